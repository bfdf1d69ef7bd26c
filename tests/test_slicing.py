"""Z-constant contours: exact on analytic solids, robust on planes through vertices and facets."""
import math

import numpy as np

from meshmill.kernels.bvh import build_bvh
from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.geometry.shapes import box, revolve, sphere
from meshmill.geometry.slicing import slice_contours, z_levels
from meshmill.kernels import cpu


def test_levels_from_the_top_down():
    np.testing.assert_allclose(z_levels(0.0, 10.0, 2.5), [7.5, 5.0, 2.5])
    assert len(z_levels(0.0, 63.11, 5.0)) == 12  # as Tableau 7 of seed 004
    assert len(z_levels(0.0, 1.0, 2.0)) == 0


def test_sphere_contours_lie_on_the_mesh_and_run_counter_clockwise():
    m = sphere(20.0, 32, 64)
    levels = z_levels(-20, 20, 3.0)
    c = slice_contours(m, levels, 0.5, math.radians(5))
    assert len(c) == len(levels) and c.closed.all()
    np.testing.assert_allclose(np.sort(c.z)[::-1], levels)
    bvh = build_bvh(m.vertices, m.faces)
    assert cpu.mesh_distances(c.points, bvh.arrays).max() < 1e-9
    np.testing.assert_allclose(np.linalg.norm(c.normals, axis=1), 1.0)
    for i in range(len(c)):
        pts = c.points[c.offsets[i]:c.offsets[i + 1]]
        assert np.all(pts[:, 2] == c.z[i])
        x, y = pts[:, 0], pts[:, 1]
        area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        assert area > 0  # counter-clockwise seen from +Z around the material
        gaps = np.linalg.norm(np.diff(np.vstack([pts, pts[:1]]), axis=0), axis=1)
        assert gaps.max() <= 0.5 + 1e-9
    side = np.cross(c.feed, [0, 0, 1.0])
    assert (np.einsum("ij,ij->i", side, c.normals) > 0).all()


def test_flat_facet_exactly_on_a_plane():
    # stepped cylinder: the step face lies exactly on z = 10, and whole vertex rings lie on the planes
    m = revolve([0, 20, 20, 10, 10, 0], [0, 0, 10, 10, 20, 20], 48)
    c = slice_contours(m, np.array([15.0, 10.0, 5.0]), 0.5, math.radians(5))
    assert len(c) == 3 and c.closed.all()
    radii = [np.hypot(*c.points[c.offsets[i]:c.offsets[i + 1], :2].T) for i in range(3)]
    # a plane on the step face machines the wall below it: the facet counts as above the plane
    np.testing.assert_allclose([r.max() for r in radii], [10, 20, 20], rtol=1e-12)
    assert all(np.all(c.points[c.offsets[i]:c.offsets[i + 1], 2] == c.z[i]) for i in range(3))


def test_plane_through_box_vertices_gives_one_loop():
    m = box([0, 0, 0], [10, 10, 10])
    c = slice_contours(m, np.array([10.0 - 1e-12, 5.0, 0.0 + 1e-12]), 1.0, math.radians(5))
    assert len(c) == 3 and c.closed.all()
    # a plane exactly through the bottom face's vertices gives nothing (all of it counts as above)
    c0 = slice_contours(m, np.array([0.0]), 1.0, math.radians(5))
    assert len(c0) == 0


def test_convex_edge_gets_a_fan_of_normals():
    m = box([0, 0, 0], [10, 10, 10])
    c = slice_contours(m, np.array([5.0]), 1.0, math.radians(5))
    # at each of the four vertical edges the normal turns 90 degrees in 5-degree steps
    at_corner = np.all(np.isin(np.round(c.points[:, :2], 9), [0.0, 10.0]), axis=1)
    assert at_corner.sum() == 4 * 19
    assert np.abs(np.linalg.norm(c.normals, axis=1) - 1).max() < 1e-12


def test_open_surface_gives_open_chains():
    s = sphere(10.0, 16, 32)
    keep = s.vertices[s.faces][:, :, 2].min(axis=1) >= -1e-9  # the upper half only
    m = mesh_from_arrays(s.vertices, s.faces[keep])
    assert not m.closed
    c = slice_contours(m, np.array([5.0]), 0.5, math.radians(5))
    assert len(c) == 1 and c.closed.all()  # a full ring is still closed
    half = mesh_from_arrays(m.vertices, m.faces[m.vertices[m.faces][:, :, 1].min(axis=1) >= -1e-9])
    c = slice_contours(half, np.array([5.0]), 0.5, math.radians(5))
    assert len(c) == 1 and not c.closed[0]
