"""Exact distance kernels and the BVH against brute force."""
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import brute_point_triangle_dist
from meshmill.kernels.bvh import build_bvh
from meshmill.geometry.shapes import sphere
from meshmill.kernels import cpu
from meshmill.kernels.geom import STACK_SIZE

# half the coordinates on a coarse grid, so that vertices, edges and slab planes coincide exactly
coord = st.one_of(st.floats(-10, 10, allow_nan=False, allow_infinity=False), st.integers(-3, 3).map(float))
point = st.tuples(coord, coord, coord)


def _tris(*pts):
    return np.array([np.ravel(pts)], np.float64)


@settings(max_examples=300, deadline=None)
@given(point, point, point, point)
def test_point_triangle_distance_matches_reference(a, b, c, p):
    tri = np.array([a, b, c], np.float64)
    area = np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0]))
    if area < 1e-3:
        return
    d = math.sqrt(cpu.dev.point_triangle_dist2(*p, tri.reshape(1, 9), 0))
    ref = brute_point_triangle_dist(np.array(p), tri[None])[0]
    assert abs(d - ref) < 1e-9 * max(1.0, ref)


def _sampled_axis_dist(tri, a, u, t0, t1, n=120):
    """Smallest distance to the axis over a dense barycentric grid of the triangle within the slab."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    w1, w2 = i[keep] / n, j[keep] / n
    pts = tri[0] + w1[:, None] * (tri[1] - tri[0]) + w2[:, None] * (tri[2] - tri[0])
    h = (pts - a) @ u
    # a sample within rounding of a slab end is not known to be inside (a triangle touching the
    # plane t0 = 1e-194 from outside samples at h = 1e-17)
    inside = (h >= t0 + 1e-12) & (h <= t1 - 1e-12)
    pts, h = pts[inside], h[inside]
    if len(pts) == 0:
        return np.inf, 0.0
    r = np.linalg.norm(pts - a - h[:, None] * u, axis=1)
    span = max(np.linalg.norm(tri[1] - tri[0]), np.linalg.norm(tri[2] - tri[0]), np.linalg.norm(tri[2] - tri[1]))
    return r.min(), 2 * span / n


@settings(max_examples=150, deadline=None)
@given(point, point, point, point, point, st.floats(0, 5), st.floats(0.5, 10))
def test_triangle_axis_distance_bounded_by_samples(a, b, c, base, direction, t0, length):
    tri = np.array([a, b, c], np.float64)
    u = np.array(direction, np.float64)
    if np.linalg.norm(u) < 1e-3 or np.linalg.norm(np.cross(tri[1] - tri[0], tri[2] - tri[0])) < 1e-2:
        return
    u /= np.linalg.norm(u)
    base = np.array(base, np.float64)
    d2 = cpu.dev.triangle_axis_dist2(tri.reshape(1, 9), 0, *base, *u, t0, t0 + length)
    sampled, res = _sampled_axis_dist(tri, base, u, t0, t0 + length)
    if sampled == np.inf:
        # the grid may miss a thin sliver of the triangle inside the slab; the exact value can't be
        # smaller than nothing, but must then come from that sliver: nothing to compare
        return
    exact = math.sqrt(d2)
    assert exact <= sampled + 1e-9
    assert exact >= sampled - res - 1e-9


def test_cylinder_distance_on_a_flat_square():
    # unit square in z = 0 as two triangles; axis vertical through (0.5, 0.5)
    sq = np.array([[0, 0, 0, 1, 0, 0, 1, 1, 0], [0, 0, 0, 1, 1, 0, 0, 1, 0]], np.float64)
    up = (0.0, 0.0, 1.0)
    assert cpu.dev.triangle_axis_dist2(sq, 0, 0.6, 0.2, -1.0, *up, 0.0, 2.0) == 0.0  # pierces
    assert cpu.dev.triangle_axis_dist2(sq, 0, 0.5, 0.5, 0.5, *up, 0.0, 2.0) >= 1e300  # slab above the square
    # the slab starts exactly on the square's plane: touching counts, distance 0
    assert cpu.dev.triangle_axis_dist2(sq, 0, 0.6, 0.2, 0.0, *up, 0.0, 2.0) == 0.0
    # axis outside the square: distance to the nearest edge
    d2 = cpu.dev.triangle_axis_dist2(sq, 0, 3.0, 0.5, -1.0, *up, 0.0, 2.0)
    assert abs(math.sqrt(d2) - 2.0) < 1e-12


def _random_mesh(seed, m=60):
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-10, 10, (m, 1, 3))
    V = (centers + rng.normal(0, 2, (m, 3, 3))).reshape(-1, 3)
    F = np.arange(3 * m).reshape(m, 3)
    return V, F


def _bvh_depth_and_leaves(bvh):
    depth, leaves, todo = 0, [], [(0, 1)]
    while todo:
        n, d = todo.pop()
        depth = max(depth, d)
        if bvh.node_child[n, 0] < 0:
            leaves.append(n)
        else:
            todo += [(int(bvh.node_child[n, 0]), d + 1), (int(bvh.node_child[n, 1]), d + 1)]
    return depth, leaves


def test_the_bvh_holds_every_triangle_once_in_boxes_that_hold_it_and_stays_shallow():
    # surface-area splits on meshes that tempt them to peel one triangle a level (sizes growing
    # geometrically, all on one line), on a grid mesh, and on identical triangles (no plane splits)
    rng = np.random.default_rng(3)
    size = 2.0 ** np.arange(300.0)  # (a split per triangle: the median takes over at SAH_DEPTH)
    peel = np.stack([np.c_[size, 0 * size, 0 * size], np.c_[1.5 * size, 0 * size, 0 * size],
                     np.c_[size, 0.5 * size, 0 * size]], axis=1)
    same = np.tile([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]], (300, 1, 1))
    V, F = _grid_mesh(2, 200)
    for tri in (peel, same, V[F], rng.uniform(-50, 50, (3000, 3, 3))):
        bvh = build_bvh(tri.reshape(-1, 3), np.arange(3 * len(tri)).reshape(-1, 3))
        depth, leaves = _bvh_depth_and_leaves(bvh)
        assert depth < STACK_SIZE // 2
        held = np.concatenate([np.arange(bvh.node_range[n, 0], bvh.node_range[n, 0] + bvh.node_range[n, 1])
                               for n in leaves])
        assert np.array_equal(np.sort(held), np.arange(len(tri)))  # every triangle in one leaf
        assert np.array_equal(np.sort(bvh.order), np.arange(len(tri)))
        np.testing.assert_array_equal(bvh.tris, tri[bvh.order].reshape(-1, 9))
        for n in range(len(bvh.node_lo)):  # each box holds the boxes (and so the triangles) below it
            for c in bvh.node_child[n]:
                if c >= 0:
                    assert (bvh.node_lo[n] <= bvh.node_lo[c]).all() and (bvh.node_hi[c] <= bvh.node_hi[n]).all()
        for n in leaves:
            a, m = bvh.node_range[n]
            pts = bvh.tris[a:a + m].reshape(-1, 3)
            assert m >= 1 and (bvh.node_lo[n] <= pts.min(axis=0)).all() and (pts.max(axis=0) <= bvh.node_hi[n]).all()


def test_bvh_point_distance_equals_brute_force():
    for seed in range(5):
        V, F = _random_mesh(seed)
        bvh = build_bvh(V, F)
        pts = np.random.default_rng(100 + seed).uniform(-14, 14, (300, 3))
        d = cpu.mesh_distances(pts, bvh.arrays)
        ref = np.array([brute_point_triangle_dist(p, V[F]).min() for p in pts])
        np.testing.assert_allclose(d, ref, rtol=0, atol=1e-10)


def test_bvh_cylinder_distance_equals_brute_force():
    for seed in range(5):
        V, F = _random_mesh(seed)
        bvh = build_bvh(V, F)
        rng = np.random.default_rng(200 + seed)
        stack = np.empty(STACK_SIZE, np.int32)
        for _ in range(100):
            a = rng.uniform(-12, 12, 3)
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            t0, t1 = 0.0, rng.uniform(1, 15)
            d = cpu.dev.mesh_cylinder_dist2(*a, *u, t0, t1, 1e300, 0.0, *bvh.arrays, stack)
            ref = min(cpu.dev.triangle_axis_dist2(bvh.tris, k, *a, *u, t0, t1) for k in range(len(F)))
            assert d == ref


def test_early_exit_reports_an_overlap():
    m = sphere(10.0, 16, 32)
    bvh = build_bvh(m.vertices, m.faces)
    stack = np.empty(STACK_SIZE, np.int32)
    # a ball of radius 3 centred 2 mm outside the sphere overlaps it
    d2 = cpu.dev.mesh_point_dist2(12.0, 0.0, 0.0, 9.0, 9.0, *bvh.arrays, stack)
    assert d2 < 9.0
    # one 4 mm outside does not: the query returns the cap
    d2 = cpu.dev.mesh_point_dist2(14.5, 0.0, 0.0, 9.0, 9.0, *bvh.arrays, stack)
    assert d2 == 9.0


def test_slab_plane_through_a_vertex():
    # found by hypothesis: the slab's lower plane passes exactly through vertex b
    tri = np.array([[0, 0, 0, 0, 1, 1, 1, 2, 0]], np.float64)
    d2 = cpu.dev.triangle_axis_dist2(tri, 0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0)
    assert abs(d2 - 0.2) < 1e-15


def test_sliver_triangle_distance():
    # found in review: a 1e-11 mm high sliver; the nearest feature is edge AB at 3.262 mm
    tri = np.array([[0, 0, 0, 100, 0, 0, 37.3, 1e-11, 0]], np.float64)
    p = (66.013, 0.006, -3.262)
    d = math.sqrt(cpu.dev.point_triangle_dist2(*p, tri, 0))
    assert abs(d - math.hypot(0.006, 3.262)) < 1e-9
    collinear = np.array([[0, 0, 0, 1, 0, 0, 2, 0, 0]], np.float64)
    assert cpu.dev.point_triangle_dist2(0.5, 1.0, 0.0, collinear, 0) == 1.0


def test_axis_in_the_plane_of_the_triangle():
    # found in review: rounding noise in det made the pierce test report 0 for an in-plane axis
    rng = np.random.default_rng(5)
    tri = np.array([[0, 0, 0], [10, 0, 0], [10, 0, 10]], np.float64)
    base, u = np.array([2.0, 0, 5.0]), np.array([0, 0, 1.0])
    for _ in range(2000):
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        d2 = cpu.dev.triangle_axis_dist2((tri @ q.T).reshape(1, 9), 0, *(q @ base), *(q @ u), 0.0, 30.0)
        assert abs(d2 - 9.0) < 1e-9


def _grid_mesh(seed, m=40):
    """Triangles with corners on the integer grid of [-3, 3]³: queries on their vertices, edges and
    planes are exact in floating point, and many boxes touch."""
    rng = np.random.default_rng(seed)
    V = rng.integers(-3, 4, (3 * m, 3)).astype(np.float64)
    F = np.arange(3 * m).reshape(m, 3)
    keep = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1) > 0
    return V, F[keep]


def _queries(V, F, rng, k=30):
    """Points on the vertices, the edges' middles and quarter points of the faces (exact for grid
    meshes), and random points around them."""
    tri = V[F]
    on = np.concatenate([V[:k], 0.5 * (tri[:k, 0] + tri[:k, 1]), 0.25 * tri[:k, 0] + 0.25 * tri[:k, 1]
                         + 0.5 * tri[:k, 2]])
    return np.concatenate([on, rng.uniform(V.min() - 2, V.max() + 2, (k, 3))])


def _meshes():
    return [_grid_mesh(0), _grid_mesh(1), _random_mesh(0, 40)]


def _segment_triangle_dist2(a, b, tris, t):
    """Exact squared distance from segment a-b to triangle t: 0 where it pierces, else the least
    of its ends' distances to the triangle and of the triangle's edges' to it."""
    tri = tris[t].reshape(3, 3)
    m = np.column_stack([b - a, tri[0] - tri[1], tri[0] - tri[2]])
    if abs(np.linalg.det(m)) > 1e-12:  # (parallel or in its plane: the terms below are exact)
        s, beta, gamma = np.linalg.solve(m, tri[0] - a)
        if 0.0 <= s <= 1.0 and beta >= 0.0 and gamma >= 0.0 and beta + gamma <= 1.0:
            return 0.0
    d = min(cpu.dev.point_triangle_dist2(*a, tris, t), cpu.dev.point_triangle_dist2(*b, tris, t))
    for k in range(3):
        d = min(d, cpu.clr.seg_seg_dist2(*a, *b, *tri[k], *tri[(k + 1) % 3]))
    return d


def test_the_segment_gap_never_exceeds_the_distance():
    # segment_tri_gap prunes the cylinder searches' triangles: a lower bound on the distance from
    # a segment (or a point) to a triangle, on grid meshes whose queries lie on vertices, edges
    # and faces, segments along them, of length zero, and random ones
    checked = 0
    for V, F in _meshes():
        bvh = build_bvh(V, F)
        rng = np.random.default_rng(7 + len(F))
        pts = _queries(V, F, rng)
        pairs = [(a, b) for a, b in zip(pts[::2], pts[1::2])] + [(p, p) for p in pts[:20]]
        pairs += [(V[f[0]], V[f[1]]) for f in F[:20]]  # along an edge of the mesh
        for a, b in pairs:
            for t in range(len(bvh.tris)):
                gap = cpu.dev.segment_tri_gap(bvh.tris, t, *a, *b)
                assert gap <= math.sqrt(_segment_triangle_dist2(a, b, bvh.tris, t)) + 1e-12
                checked += 1
    assert checked > 10000


def test_capped_cylinder_searches_find_every_triangle_within_the_cap():
    # the pose measures ask a cylinder's distance capped at its radius: with the triangles
    # pruned by the gap, it is still exactly the least of the exact test below the cap
    stack = np.empty(STACK_SIZE, np.int32)
    for V, F in _meshes():
        bvh = build_bvh(V, F)
        rng = np.random.default_rng(11 + len(F))
        pts = _queries(V, F, rng)
        tris = range(len(bvh.tris))
        for a, b in zip(pts[::2], pts[1::2]):
            if np.linalg.norm(b - a) == 0.0:
                continue
            u = (b - a) / np.linalg.norm(b - a)
            ref = min(cpu.dev.triangle_axis_dist2(bvh.tris, t, *a, *u, 0.5, 3.0) for t in tris)
            for r in (0.25, 1.0, 2.0, 3.0):
                d = cpu.dev.mesh_cylinder_dist2(*a, *u, 0.5, 3.0, r * r, 0.0, *bvh.arrays, stack)
                assert d == ref if ref < r * r else d >= r * r


def test_every_bvh_search_is_the_minimum_of_its_triangle_test():
    # the traversal written once prunes only what cannot come below the best, so each search
    # returns exactly the least of its triangle test over all triangles, and a triangle giving it
    stack = np.empty(STACK_SIZE, np.int32)
    for V, F in _meshes():
        bvh = build_bvh(V, F)
        rng = np.random.default_rng(len(F))
        pts = _queries(V, F, rng)
        tris = range(len(bvh.tris))
        for p in pts:
            d = cpu.dev.mesh_point_dist2(*p, 1e300, 0.0, *bvh.arrays, stack)
            assert d == min(cpu.dev.point_triangle_dist2(*p, bvh.tris, t) for t in tris)
        for a, b in zip(pts[::2], pts[1::2]):
            if np.linalg.norm(b - a) == 0.0:
                continue
            u = (b - a) / np.linalg.norm(b - a)
            d, hit = cpu.dev.mesh_cylinder_search(*a, *u, 0.0, 2.5, 1e300, 0.0, *bvh.arrays, stack)
            ref = [cpu.dev.triangle_axis_dist2(bvh.tris, t, *a, *u, 0.0, 2.5) for t in tris]
            assert d == min(ref) and ref[hit] == d
            d = cpu.clr.mesh_segment_dist2(*a, *b, 1e300, 0.0, *bvh.arrays, stack)
            (dx, dy, dz), length = b - a, math.sqrt(sum((b - a) ** 2))  # as the kernel rounds them
            su = (dx / length, dy / length, dz / length)
            assert d == min(min(cpu.dev.triangle_axis_dist2(bvh.tris, t, *a, *su, 0.0, length),
                                cpu.dev.point_triangle_dist2(*a, bvh.tris, t),
                                cpu.dev.point_triangle_dist2(*b, bvh.tris, t)) for t in tris)
        w = np.zeros(cpu.WORK_SIZE)
        for a, b, c in zip(pts[::3], pts[1::3], pts[2::3]):
            w[cpu.clearance._TRI_A:cpu.clearance._TRI_A + 9] = np.r_[a, b, c]
            w[cpu.clearance._TRI_B:cpu.clearance._TRI_B + 9] = np.r_[a, c, c + 0.5]
            d = cpu.clr.mesh_tris_dist2(w, 1e300, 0.0, *bvh.arrays, stack)
            assert d == min(min(cpu.clr.tri_tri_dist2(w, cpu.clearance._TRI_A, bvh.tris, t),
                                cpu.clr.tri_tri_dist2(w, cpu.clearance._TRI_B, bvh.tris, t)) for t in tris)
            e1 = (b - a) / max(np.linalg.norm(b - a), 1e-300)
            e2 = np.cross(u := np.array([0.0, 0.0, 1.0]), e1)
            if np.linalg.norm(e2) < 1e-9:
                continue
            e2 /= np.linalg.norm(e2)
            e1 = np.cross(e2, u)
            args = (*a, *u, *e1, *e2, -1.0, 1.5, 0.75, -0.25)
            d = cpu.clr.mesh_stadium_dist2(*args, 1e300, 0.0, *bvh.arrays, stack, w)
            assert d == min(cpu.clr.stadium_tri_dist2(bvh.tris, t, *args, w) for t in tris)


def test_a_search_stops_below_stop2_and_caps_at_cap2():
    stack = np.empty(STACK_SIZE, np.int32)
    V, F = _grid_mesh(7)
    bvh = build_bvh(V, F)
    for p in _queries(V, F, np.random.default_rng(7)):
        exact = cpu.dev.mesh_point_dist2(*p, 1e300, 0.0, *bvh.arrays, stack)
        for lim in (0.25, 1.0, 4.0):
            d = cpu.dev.mesh_point_dist2(*p, lim, lim, *bvh.arrays, stack)
            assert exact <= d < lim if exact < lim else d == lim


def test_the_visits_see_every_crossing():
    # inside, line hits and ray blocking through the BVH against the same triangle test over all
    # triangles, for lines through vertices and edges (ties decided once, by the triangle test)
    stack = np.empty(STACK_SIZE, np.int32)
    V, F = _grid_mesh(11, 80)
    bvh = build_bvh(V, F)
    tris = range(len(bvh.tris))
    kind = np.ones(len(bvh.tris), np.int8)
    kind[::3] = 0
    pts = _queries(V, F, np.random.default_rng(3))
    hw, hs = np.empty(512), np.empty(512, np.int64)
    all_lo, all_hi = bvh.node_lo[:1], bvh.node_hi[:1]
    for p in pts:
        wind, odd = 0, False
        for t in tris:
            side, z = cpu.ray.hit(bvh.tris, t, 2, p[0], p[1])
            if side != 0 and z > p[2]:
                wind, odd = (wind + side, odd) if kind[t] == 1 else (wind, not odd)
        assert cpu.clr.inside(*p, *bvh.arrays, kind, 0.0, stack) == (wind > 0 or (odd and p[2] >= 0.0))
        for a in range(3):
            u0, v0 = p[(a + 1) % 3], p[(a + 2) % 3]
            n = cpu.ray.bvh_line_hits(a, u0, v0, *bvh.arrays, stack, hw, hs)
            got = sorted(zip(hw[:n], hs[:n]))
            n = cpu.ray.box_line_hits(a, u0, v0, all_lo, all_hi, np.array([0, len(bvh.tris)]), bvh.tris, hw, hs)
            assert got == sorted(zip(hw[:n], hs[:n]))
        d = np.array([0.3, -0.5, 0.8])
        blocked = any(cpu.dev.line_crossing(*p, *d, *bvh.tris[t], 1e-300, 0.0) > 1e-6 for t in tris)
        assert cpu.ray.ray_blocked(*p, *d, 1e-6, *bvh.arrays, stack) == blocked
