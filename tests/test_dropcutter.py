"""Drop-cutter for flat, ball and bull-nose cutters: analytic cases, brute force, OpenCAMLib."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshmill.kernels.bvh import build_bvh
from meshmill.geometry.mesh import load_mesh
from meshmill.geometry.shapes import box, revolve, sphere
from meshmill.kernels import cpu

PARTS = __import__("pathlib").Path(__file__).resolve().parents[2] / "shared" / "parts"
CUTTERS = {"flat": (3.0, 0.0), "ball": (3.0, 3.0), "bull": (3.0, 1.0)}


def _bvh(m):
    return build_bvh(m.vertices, m.faces).arrays


@pytest.mark.parametrize("kind", CUTTERS)
def test_on_a_plane(kind):
    R, r = CUTTERS[kind]
    b = _bvh(box([0, 0, 0], [20, 20, 10]))
    xy = np.array([[10, 10], [0, 0], [20, 5], [3, 17.5], [10, 0]], np.float64)  # corners and edges too
    z, cc = cpu.drop_cutter(xy, R, r, -100, b)
    assert np.all(z == 10.0)
    assert np.all(cc[:, 2] == 10.0)


def _profile(rho, R, r):
    a = R - r
    return 0.0 if rho <= a else r - math.sqrt(max(0.0, r * r - (rho - a) ** 2))


@pytest.mark.parametrize("kind", CUTTERS)
def test_beside_a_box_edge(kind):
    R, r = CUTTERS[kind]
    b = _bvh(box([0, 0, 0], [20, 20, 10]))
    for e in np.linspace(0.1, 2.99, 9):  # axis e mm outside the face x = 20
        z, _ = cpu.drop_cutter(np.array([[20 + e, 10.0]]), R, r, -100, b)
        assert abs(z[0] - (10.0 - _profile(e, R, r))) < 1e-12


def test_ball_on_a_sphere():
    Rs, R = 20.0, 3.0
    m = sphere(Rs, 96, 192)
    b = _bvh(m)
    xy = np.array([[0, 0], [5, 3], [-9, 4], [12, -7]], np.float64)
    z, _ = cpu.drop_cutter(xy, R, R, -100, b)
    exact = np.sqrt((Rs + R) ** 2 - (xy ** 2).sum(1)) - R
    chord = Rs * (1 - math.cos(math.pi / 96))  # the facets lie inside the sphere by at most this
    assert np.all(z <= exact + 1e-12) and np.all(z >= exact - chord)


def test_ball_resting_on_the_rim_of_a_hole():
    # a block with a round hole of radius 2 (48-gon): a ball of radius 3 rests on the rim's edges
    n, rh, top = 48, 2.0, 10.0
    prof_r = [0, 15, 15, rh, rh, 0]  # revolve: outer wall, top face, the hole's wall, its floor
    prof_z = [0, 0, top, top, 4, 4]
    m = revolve(prof_r, prof_z, n)
    b = _bvh(m)
    z, _ = cpu.drop_cutter(np.array([[0.0, 0.0]]), 3.0, 3.0, -100, b)
    d = rh * math.cos(math.pi / n)  # the rim edges' distance from the axis
    assert abs(z[0] - (top + math.sqrt(9.0 - d * d) - 3.0)) < 1e-12
    z, _ = cpu.drop_cutter(np.array([[0.0, 0.0]]), 1.5, 1.5, -100, b)  # a small ball reaches the floor
    assert z[0] == 4.0


coord = st.one_of(st.floats(-4, 4, allow_nan=False), st.integers(-2, 2).map(float))


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(coord, coord, coord), min_size=3, max_size=3), st.tuples(coord, coord),
       st.sampled_from(list(CUTTERS)))
@pytest.mark.slow
def test_triangle_drop_against_dense_samples(pts, xy, kind):
    R, r = CUTTERS[kind]
    tri = np.array(pts, np.float64)
    if np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0])) < 1e-2:
        return
    z, cx, cy, cz = cpu.cut.triangle_drop(tri.reshape(1, 9), 0, xy[0], xy[1], R, r, -1e300)
    n = 150
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    w1, w2 = i[keep] / n, j[keep] / n
    p = tri[0] + w1[:, None] * (tri[1] - tri[0]) + w2[:, None] * (tri[2] - tri[0])
    rho = np.hypot(p[:, 0] - xy[0], p[:, 1] - xy[1])
    ok = rho <= R
    if not ok.any():
        assert z < -1e299 or z <= p[:, 2].max()
        return
    sampled = max(pz - _profile(rh, R, r) for pz, rh in zip(p[ok, 2], rho[ok]))
    assert z >= sampled - 1e-9  # never below any point of the triangle: no gouge
    span = np.ptp(tri, axis=0).max()
    # and touches it, within the sampling's resolution; where the cutter only grazes the triangle
    # (rho = R exactly along a vertical facet) the contact lies between samples just beyond R
    near = rho <= R + 2 * span / n
    reach = max(pz - _profile(min(rh, R), R, r) for pz, rh in zip(p[near, 2], rho[near]))
    assert z <= reach + 3 * span / n * 4
    # the contact point is on the triangle and under the cutter at that height
    assert abs(math.hypot(cx - xy[0], cy - xy[1])) <= R + 1e-9
    assert abs(cz - _profile(math.hypot(cx - xy[0], cy - xy[1]), R, r) - z) < 1e-6


def _drop_above(tri, xy, R, r, best):
    return cpu.cut.triangle_drop(np.asarray(tri, np.float64).reshape(1, 9), 0, xy[0], xy[1], R, r, best)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(coord, coord, coord), min_size=3, max_size=3), st.tuples(coord, coord),
       st.sampled_from(list(CUTTERS)), st.sampled_from([-1.0, -1e-3, -1e-8, 0.0, 1e-8, 1e-3, 1.0]))
def test_a_triangle_gives_its_drop_above_any_bound_and_nothing_below_it(pts, xy, kind, shift):
    # the searches pass the best height so far: a triangle must give its own drop when that is
    # above it, whatever it skips (a ball's sphere test, the plane's), and nothing otherwise
    R, r = CUTTERS[kind]
    tri = np.array(pts, np.float64)
    if np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0])) < 1e-2:
        return  # (the loader drops degenerate triangles)
    alone = _drop_above(tri, xy, R, r, -1e300)
    if alone[0] < -1e299:
        return
    got = _drop_above(tri, xy, R, r, alone[0] + shift)
    if shift < 0.0:
        assert got == alone
    else:
        assert got[0] < -1e299


def test_a_ball_meets_a_wall_above_its_centre_that_its_sphere_misses():
    # the tool is the sphere only below its centre: above it, the flutes' column; a steep triangle
    # rising past the centre beside the axis lifts the ball though the sphere about the centre
    # (at the bound's height) is farther than R from it
    R = 3.0
    wall = [[2.5, -5.0, 0.0], [2.5, 5.0, 0.0], [2.9, 0.0, 20.0]]
    alone = _drop_above(wall, (0.0, 0.0), R, R, -1e300)
    assert alone[0] > 10.0
    assert _drop_above(wall, (0.0, 0.0), R, R, alone[0] - 1e-6) == alone


def test_a_ball_resting_exactly_on_an_edge_keeps_it_at_the_bound_and_below():
    # a horizontal edge 2 mm beside the axis at z 5: the ball's tip rests at 5 - (3 - sqrt(5));
    # the edge is exactly R from the centre there, on the sphere test's boundary
    R = 3.0
    tri = [[2.0, -4.0, 5.0], [2.0, 4.0, 5.0], [6.0, 0.0, 1.0]]
    z = 5.0 - (R - math.sqrt(R * R - 4.0))
    alone = _drop_above(tri, (0.0, 0.0), R, R, -1e300)
    assert abs(alone[0] - z) < 1e-12
    assert _drop_above(tri, (0.0, 0.0), R, R, z - 1e-12) == alone
    assert _drop_above(tri, (0.0, 0.0), R, R, alone[0])[0] < -1e299


ocl = pytest.importorskip("opencamlib", reason="OpenCAMLib is a test-only peer")


@pytest.mark.parametrize("part", ["pycam-textbox", "beet_mm", "mount_rush", "sphere_on_plate"])
@pytest.mark.slow
def test_equals_opencamlib_batch_drop_cutter(part):
    path = PARTS / f"{part}.stl"
    if not path.exists():
        pytest.skip("shared parts not present")
    m = load_mesh(path, flip=part == "beet_mm")  # beet_mm is wound inside out
    b = _bvh(m)
    surf = ocl.STLSurf()
    ocl.STLReader(str(path), surf)
    lo, hi = m.bounds
    rng = np.random.default_rng(7)
    xy = rng.uniform(lo[:2] - 1, hi[:2] + 1, (3000, 2))
    # and points on the grid lines through vertices, where programs break
    v = m.vertices[rng.choice(len(m.vertices), 500)]
    xy = np.vstack([xy, v[:, :2], np.column_stack([v[:, 0], rng.uniform(lo[1], hi[1], 500)])])
    floor = lo[2] - 10
    for kind, cutter in [("flat", ocl.CylCutter(6, 30)), ("ball", ocl.BallCutter(6, 30)),
                         ("bull", ocl.BullCutter(6, 1, 30))]:
        R, r = CUTTERS[kind]
        bdc = ocl.BatchDropCutter()
        bdc.setSTL(surf)
        bdc.setCutter(cutter)
        for x, y in xy:
            bdc.appendPoint(ocl.CLPoint(float(x), float(y), floor))
        bdc.run()
        theirs = np.array([p.z for p in bdc.getCLPoints()])
        ours, _ = cpu.drop_cutter(xy, R, r, floor, b)
        assert np.abs(ours - theirs).max() < 1e-3, kind


def test_a_wider_body_that_touches_nothing_keeps_the_cutters_contact():
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.dropcutter import ToolDrop
    from meshmill.tools.table import tool_from_entry

    # a plane rising at 30 deg; the shank (grown wider than the ball) starts far above what it
    # passes over: the floor it is dropped from, less its height, rounds above the tip at some
    # points, which once wiped the ball's contact (NaN) though the height stayed the ball's
    t = math.tan(math.radians(30))
    plane = mesh_from_arrays(np.array([[0, 0, 0], [60, 0, 60 * t], [60, 40, 60 * t], [0, 40, 0.0]]),
                             np.array([[0, 1, 2], [0, 2, 3]]), "plane")
    ball = tool_from_entry(dict(name="B10", type="ball", diameter=10, flute_length=30, gauge_length=50), 1, "t")
    xy = np.column_stack([np.linspace(0, 60, 601), np.full(601, 20.0)])
    kern = solid_kernels(plane)
    z0, c0 = ToolDrop(ball, kern, -1.0).with_contacts(xy)
    z1, c1 = ToolDrop(ball, kern, -1.0, body_grow=0.5).with_contacts(xy)
    assert np.array_equal(z0, z1) and np.isfinite(c0[:, 0]).all()
    assert np.array_equal(c0, c1)


@pytest.mark.parametrize("kind", CUTTERS)
def test_a_point_drops_the_same_alone_in_another_order_or_with_others(kind):
    """Each point starts from its neighbour's contact (a first lower bound that prunes the
    search), yet its height and contact are a triangle's, whatever came before it: points 0.05 mm
    apart along lines over a faceted sphere and a box's edge, dropped in one call, reversed,
    shuffled and one by one, give the same bits (a waterline's levels or a raster's pieces spread
    over a cluster's workers then give the one process's path)."""
    R, r = CUTTERS[kind]
    s, b = sphere(20.0, 24, 48), box([25, -5, 0], [35, 5, 12])
    b = _bvh(type(s)(vertices=np.vstack([s.vertices, b.vertices]), faces=np.vstack([s.faces, b.faces + len(s.vertices)])))
    t = np.arange(-30.0, 40.0, 0.05)
    xy = np.vstack([np.column_stack([t, np.full(len(t), y)]) for y in (0.0, 3.3, 11.7)])
    z, cc = cpu.drop_cutter(xy, R, r, -100, b)
    order = np.random.default_rng(1).permutation(len(xy))
    for again in (slice(None, None, -1), order):
        z2, cc2 = cpu.drop_cutter(xy[again], R, r, -100, b)
        assert np.array_equal(z2, z[again]) and np.array_equal(cc2, cc[again], equal_nan=True)
    alone = [cpu.drop_cutter(xy[i:i + 1], R, r, -100, b) for i in range(0, len(xy), 11)]
    assert np.array_equal(np.concatenate([a[0] for a in alone]), z[::11])
    assert np.array_equal(np.concatenate([a[1] for a in alone]), cc[::11], equal_nan=True)


def test_a_start_point_that_no_triangle_beats_falls_back_to_the_floor():
    """mesh_drop given a start point above everything (not the mesh's: no triangle lifts the
    tool to its bound) searches again from the floor: the height and contact of no start."""
    from meshmill.kernels.cpu import STACK_SIZE, cut

    b = _bvh(sphere(10.0, 12, 24))
    stack = np.empty(STACK_SIZE, np.int32)
    for x, y in ((0.0, 0.0), (4.0, 3.0), (20.0, 0.0)):
        plain = cut.mesh_drop(x, y, 3.0, 3.0, -100.0, math.nan, math.nan, math.nan, *b, stack)
        high = cut.mesh_drop(x, y, 3.0, 3.0, -100.0, x, y, 50.0, *b, stack)
        assert plain == high or (math.isnan(plain[1]) and plain[0] == high[0] and math.isnan(high[1]))


def test_refinement_drops_only_the_new_segments_midpoints():
    """Each round tests the halves of the segments split the round before: the tips are those of
    testing every segment every round, from fewer drops."""
    from meshmill.geometry import shapes
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.dropcutter import REFINE_ROUNDS, ToolDrop, drop_refined
    from meshmill.tools.table import Tool

    part = shapes.post_with_fillet(segments=48)
    tool = Tool(name="B6", type="ball", diameter=6.0, corner_radius=3.0, flute_length=12.0, gauge_length=40.0,
                shank_diameter=6.0, holder_diameter=30.0, holder_length=40.0, number=1)
    drop = ToolDrop(tool, solid_kernels(part, "cpu"), float(part.bounds[0, 2]))
    counted = []

    def counting(xy):
        counted.append(len(xy))
        return drop(xy)

    xy = np.column_stack([np.linspace(-45.0, 45.0, 91), np.full(91, 3.0)])  # over the fillets and the post's edge
    tips = drop_refined(xy, counting, 0.001, 0.01)
    ref_xy, z, every = xy, drop(xy), len(xy)  # every segment's midpoint, every round
    for _ in range(REFINE_ROUNDS):
        mid = 0.5 * (ref_xy[:-1] + ref_xy[1:])
        idx = np.nonzero(np.linalg.norm(ref_xy[1:] - ref_xy[:-1], axis=1) > 0.01)[0]
        zm = drop(mid[idx])
        every += len(idx)
        off = np.abs(zm - 0.5 * (z[idx] + z[idx + 1])) > 0.001
        if not off.any():
            break
        ref_xy = np.insert(ref_xy, idx[off] + 1, mid[idx[off]], axis=0)
        z = np.insert(z, idx[off] + 1, zm[off])
    assert np.array_equal(tips, np.column_stack([ref_xy, z])) and len(tips) > len(xy) + 10
    assert sum(counted) < every


@pytest.mark.parametrize("kind", ["ball", "bull", "flat"])
def test_the_compiled_refinement_gives_the_rounds_tips(kind):
    """ToolDrop.refined (one compiled pass, each segment refined on its own, depth first) gives the
    tips of drop_refined's rounds over a plain drop function, bit for bit: lines crossing a post's
    fillets, its edge and a box whose corners and top lie on the grid, with a shank and holder and
    a grown tool; polylines of 0-3 points; rows that run out of room (made room for, the same)."""
    from meshmill.geometry import shapes
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.dropcutter import REFINE_ROUNDS, ToolDrop, drop_refined
    from meshmill.tools.table import Tool

    post, b = shapes.post_with_fillet(segments=48), box([20.0, -5.0, 5.0], [30.0, 5.0, 12.0])
    part = type(post)(vertices=np.vstack([post.vertices, b.vertices]),
                      faces=np.vstack([post.faces, b.faces + len(post.vertices)]))
    R, r = CUTTERS[kind]
    tool = Tool(name="T", type=kind, diameter=2 * R, corner_radius=r, flute_length=8.0, gauge_length=40.0,
                shank_diameter=2 * R, holder_diameter=30.0, holder_length=40.0, number=1)
    kern = solid_kernels(part, "cpu")
    for grow, body_grow in ((0.0, 0.0), (0.5, 1.0)):
        drop = ToolDrop(tool, kern, float(part.bounds[0, 2]), grow=grow, body_grow=body_grow)
        for y in (0.0, 3.0, 5.0):
            xy = np.column_stack([np.linspace(-45.0, 45.0, 91), np.full(91, y)])  # x on whole mm
            fast = drop.refined(xy, 0.001, 0.01, REFINE_ROUNDS)
            slow = drop_refined(xy, lambda p: drop(p), 0.001, 0.01)
            assert np.array_equal(fast, slow) and len(fast) > len(xy)
            assert np.array_equal(drop_refined(xy, drop, 0.001, 0.01), fast)
        for k in range(4):
            assert np.array_equal(drop.refined(xy[:k], 0.001, 0.01, REFINE_ROUNDS),
                                  drop_refined(xy[:k], lambda p: drop(p), 0.001, 0.01))
    z, rows = cpu.drop_refined(xy, drop.radius, drop.corner, drop.floor - drop.grow, drop.grow, 0.001, 0.01,
                               REFINE_ROUNDS, kern.top, drop.body, chunk=4, cap=1)
    z2, rows2 = cpu.drop_refined(xy, drop.radius, drop.corner, drop.floor - drop.grow, drop.grow, 0.001, 0.01,
                                 REFINE_ROUNDS, kern.top, drop.body)
    order, order2 = np.lexsort((rows[:, 1], rows[:, 0])), np.lexsort((rows2[:, 1], rows2[:, 0]))
    assert np.array_equal(z, z2) and np.array_equal(rows[order], rows2[order2]) and len(rows) > 10


@pytest.mark.parametrize("kind", CUTTERS)
def test_the_drop_meets_the_top_faces_as_it_meets_the_whole_solid(kind):
    """Solid kernels drop onto the faces deciding inside (the mesh's, the caps'), not onto the
    curtains and floor under a sheet: the heights of the whole check mesh, to rounding, on a bumpy
    open sheet whose vertices lie on the grid the points are dropped at, and along its edges (unless
    the floor is above part of the sheet)."""
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.kernels.backend import solid_kernels

    n = 12
    gx, gy = np.meshgrid(np.arange(n + 1, dtype=float), np.arange(n + 1, dtype=float), indexing="ij")
    gz = 2.0 * np.sin(gx / 2.0) * np.cos(gy / 3.0) + np.where((gx + gy) % 5 == 0, 1.5, 0.0)  # spikes
    v = np.column_stack([gx.ravel(), gy.ravel(), gz.ravel()])
    k = np.arange(n * (n + 1)).reshape(n, n + 1)[:, :n].ravel()
    f = np.vstack([np.column_stack([k, k + n + 1, k + n + 2]), np.column_stack([k, k + n + 2, k + 1])])
    kern = solid_kernels(mesh_from_arrays(v, f, "sheet"))
    assert len(kern.top[4]) == len(f) < len(kern.bvh.tris)  # the curtains and floor left out
    xs = np.arange(-40, 4 * n + 41) / 4.0  # grid lines, the edges and beyond them
    xy = np.vstack([np.column_stack([xs, np.full(len(xs), y)]) for y in (-2.0, 0.0, 3.0, 6.25, n, n + 1.5)])
    xy = np.vstack([xy, xy[:, ::-1]])
    R, r = CUTTERS[kind]
    floor = kern.inside[-1]
    body = (np.array([4.5]), np.array([3.0]))
    ours, _ = kern.drop_cutter(xy, R, r, floor, body)
    whole, _ = cpu.drop_cutter(xy, R, r, floor, kern.mesh, body)
    assert np.abs(ours - whole).max() < 1e-9 and (ours > floor).any()
    # a floor above part of the sheet stands above it there: then the drop meets the whole solid
    high = solid_kernels(mesh_from_arrays(v, f, "sheet"), floor=0.0)
    assert high.top is high.mesh
    z, _ = high.drop_cutter(xy, R, r, -5.0, body)
    assert np.array_equal(z, cpu.drop_cutter(xy, R, r, -5.0, high.mesh, body)[0])
