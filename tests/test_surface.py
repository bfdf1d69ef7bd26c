"""Free-form patches (seed 002): evaluation against brute force, the seed's PCA numbers, meshes."""
import math

import numpy as np
import pytest

from meshmill.geometry.patches import (_basis, bezier, cell_samples, load_patch, make_patch, mesh_samples, mesh_surface,
                                     patch_mesh)
from meshmill.errors import InputError
from meshmill.geometry.mesh import mesh_from_arrays


def bernstein_point(points, u, v):
    """S(u, v) by the Bezier sum (eq. 1.2), term by term."""
    n, m = len(points) - 1, len(points[0]) - 1
    s = np.zeros(3)
    for i in range(n + 1):
        for j in range(m + 1):
            s += math.comb(n, i) * u**i * (1 - u) ** (n - i) * math.comb(m, j) * v**j * (1 - v) ** (m - j) * np.asarray(points[i][j])
    return s


@pytest.mark.parametrize("name", ["rubio", "choi"])
def test_bezier_matches_the_bernstein_sum_and_its_derivatives(name):
    patch = load_patch(name)
    rng = np.random.default_rng(1)
    us, vs = np.r_[0.0, rng.random(5), 1.0], np.r_[0.0, rng.random(5), 1.0]
    s, su, sv = patch.grid(us, vs)
    h = 1e-6
    for a, u in enumerate(us):
        for b, v in enumerate(vs):
            assert np.allclose(s[a, b], bernstein_point(patch.points, u, v), atol=1e-12)
            uu, vv = min(max(u, h), 1 - h), min(max(v, h), 1 - h)
            du = (bernstein_point(patch.points, uu + h, vv) - bernstein_point(patch.points, uu - h, vv)) / (2 * h)
            dv = (bernstein_point(patch.points, uu, vv + h) - bernstein_point(patch.points, uu, vv - h)) / (2 * h)
            s2, su2, sv2 = patch.grid(np.array([uu]), np.array([vv]))
            assert np.allclose(su2[0, 0], du, atol=1e-5) and np.allclose(sv2[0, 0], dv, atol=1e-5)


def test_bspline_basis_partition_of_unity_and_end_interpolation():
    knots = np.array([0, 0, 0, 0.3, 0.3, 0.7, 1, 1, 1], float)  # degree 2, 6 functions, a double knot
    t = np.linspace(0, 1, 101)
    n, dn = _basis(knots, 2, 6, t)
    assert np.allclose(n.sum(axis=1), 1.0) and np.allclose(dn.sum(axis=1), 0.0, atol=1e-9)
    assert n[0, 0] == 1.0 and n[-1, -1] == 1.0
    assert (n >= -1e-15).all()


def test_nurbs_cylinder_is_exact():
    """A quarter cylinder of radius 10 as a rational quadratic x linear patch: every point is at 10 mm."""
    w = math.sqrt(0.5)
    arc = [[10, 0], [10, 10], [0, 10]]
    points = [[[x, y, 0.0], [x, y, 50.0]] for x, y in arc]
    weights = [[1, 1], [w, w], [1, 1]]
    patch = make_patch("cyl", points, 2, 1, weights=weights)
    s, _, _ = patch.grid(np.linspace(0, 1, 17), np.linspace(0, 1, 5))
    assert np.allclose(np.hypot(s[..., 0], s[..., 1]), 10.0, atol=1e-12)


def test_seed_pca_of_the_test_surfaces():
    """Notes §0.1: 80 x 80 cell centres reproduce the thesis's eigenvalues."""
    for name, expect, area in (("rubio", (572.61, 133.23, 3.56), 3494), ("choi", (312.07, 219.02, 3.21), 3241)):
        s = cell_samples(load_patch(name), 80, 80)
        lam = np.linalg.eigvalsh(np.cov(s.points.T, bias=True))[::-1]
        assert np.allclose(lam, expect, atol=0.006)
        assert abs(s.area.sum() - area) < 1.0
    choi = cell_samples(load_patch("choi"))
    assert abs(math.degrees(choi.slope.mean()) - 23.6) < 0.05


def test_tilted_plane_samples_and_mesh():
    """A bilinear plane z = x tan 30: slope exactly 30 deg, theta 0 (normal leaning -X is the same axis)."""
    t = math.tan(math.radians(30))
    patch = bezier([[[0, 0, 0], [0, 40, 0]], [[60, 0, 60 * t], [60, 40, 60 * t]]], "plane")
    s = cell_samples(patch, 10, 8)
    assert np.allclose(s.slope, math.radians(30)) and np.allclose(s.theta, 0.0)
    assert (s.normals[:, 2] > 0).all() and s.valid.all()
    sm = patch_mesh(patch, 2.0)
    boundary = ((sm.uv == 0) | (sm.uv == 1)).any(axis=1)
    uv, usable, normals = sm.locate(sm.points)
    assert np.allclose(uv, sm.uv) and (usable == ~boundary).all() and np.allclose(normals, s.normals[0])
    # a point on a boundary edge between nodes, and one just inside
    mid = 0.5 * (sm.points[0] + sm.points[1])
    assert sm.on_free_edge(np.array([mid, mid + [1e-3, 0.0, 0.0]])).tolist() == [True, False]


def test_mesh_samples_see_the_top_and_mark_empty_cells():
    """A 20 x 10 plate at z = 3 with a 10 x 10 ramp beside it (2 x 1 cells of 10 mm): cell centres
    on shared edges still see the surface, the normal is the facet's, turned up."""
    v = np.array([[0, 0, 3], [20, 0, 3], [20, 10, 3], [0, 10, 3], [30, 0, 13], [30, 10, 13]], float)
    f = np.array([[0, 2, 1], [0, 3, 2], [1, 2, 5], [1, 5, 4]])  # wound down on purpose
    mesh = mesh_from_arrays(v, f, "plate")
    s = mesh_samples(mesh, 6, 2)
    assert s.valid.all()
    assert np.allclose(s.points[:, 2].reshape(6, 2)[:4], 3.0)
    assert np.allclose(s.slope.reshape(6, 2)[4:], math.radians(45))
    gap = mesh_from_arrays(np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0], [20, 20, 0], [19, 20, 0], [20, 19, 0]], float),
                           np.array([[0, 1, 2], [3, 4, 5]]), "two")
    s2 = mesh_samples(gap, 10, 10)
    assert 0 < s2.valid.mean() < 0.6
    # on a coarse open mesh only the boundary is a free edge, not the whole triangle
    surf = mesh_surface(gap)
    assert surf.on_free_edge(np.array([[2.0, 2.0, 0.0], [5.0, 0.0, 0.0], [5.0, 5.0, 0.0]])).tolist() == [False, True, True]


def test_patch_mesh_keeps_its_chord_tolerance():
    patch = load_patch("choi")
    coarse = patch_mesh(patch, 5.0)
    assert coarse.chord_error > 0.05
    fine = patch_mesh(patch, 5.0, chord_tol=0.0025)
    assert fine.chord_error <= 0.0025 and fine.step < 1.0
    # measured independently: random points of the patch against the triangles
    from meshmill.kernels.bvh import build_bvh
    from meshmill.kernels.backend import MeshKernels
    rng = np.random.default_rng(3)
    u, v = rng.random(300), rng.random(300)
    pts = np.array([patch.grid(np.array([a]), np.array([b]))[0][0, 0] for a, b in zip(u, v)])
    d = MeshKernels(build_bvh(fine.mesh.vertices, fine.mesh.faces)).mesh_distances(pts)
    d = d[0] if isinstance(d, tuple) else d
    assert np.max(d) <= 0.0025


@pytest.mark.parametrize("text, message", [
    ("name = 'x'\ndegree_u = 1\n", "missing 'points'"),
    ("points = [[[0,0,0],[1,0,0]],[[0,1,0],[1,1,0]]]\ndegree_u = 2\ndegree_v = 1\n", "'degree_u' must be an integer from 1 to 1"),
    ("points = [[[0,0,0],[1,0,0]],[[0,1,0],[1,1,nan]]]\ndegree_u = 1\ndegree_v = 1\n", "NaN"),
    ("points = [[[0,0,0],[1,0,0]],[[0,1,0],[1,1,0]]]\ndegree_u = 1\ndegree_v = 1\nknots_u = [0, 1]\n", "needs 4 values"),
    ("points = [[[0,0,0],[1,0,0]],[[0,1,0],[1,1,0]]]\ndegree_u = 1\ndegree_v = 1\ncolour = 1\n", "unknown key"),
    ("points = [[[0,0,0],[1,0,0]],[[0,1,0],[1,1,0]]]\ndegree_u = 1\ndegree_v = 1\nweights = [[1,1],[1,0]]\n", "positive"),
    ("this is not toml [", "not a TOML patch"),
])
def test_bad_patch_files(tmp_path, text, message):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(InputError, match=message):
        load_patch(str(p))


def test_degenerate_patch_has_no_normal():
    patch = bezier([[[0, 0, 0], [0, 0, 0]], [[1, 0, 0], [1, 0, 0]]], "line")
    with pytest.raises(InputError, match="degenerate"):
        cell_samples(patch, 4, 4)
