"""The certified clearance kernels against independent references: dense sampling of triangles,
and of the poses of a move (each pose measured exactly, 1 µm apart) for every "clear" claim."""
import numpy as np
import pytest

from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.geometry.shapes import box, sphere
from meshmill.kernels import cpu
from meshmill.kernels.backend import solid_kernels
from meshmill.pathing.verify import move_poses
from meshmill.toolpath.model import Toolpath
from meshmill.tools.table import pack_cylinders, pack_rings, tool_from_entry


def _tri_samples(tri, n=40):
    a, b = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    keep = a + b <= 1 + 1e-12
    a, b = a[keep], b[keep]
    return tri[0] + a[:, None] * (tri[1] - tri[0]) + b[:, None] * (tri[2] - tri[0])


def test_triangle_triangle_distance_matches_dense_sampling():
    rng = np.random.default_rng(1)
    for case in range(40):
        A = rng.uniform(-1, 1, (3, 3))
        B = rng.uniform(-1, 1, (3, 3)) + rng.uniform(-1.5, 1.5, 3) * (case % 3 != 0)
        if case % 5 == 0:
            A[2] = A[1]  # a degenerate triangle: a segment
        q = np.zeros(cpu.WORK_SIZE)
        q[:9] = A.ravel()
        got = np.sqrt(cpu.clr.tri_tri_dist2(q, 0, B.reshape(1, 9).copy(), 0))
        pa, pb = _tri_samples(A), _tri_samples(B)
        ref = min(np.linalg.norm(pa[i:i + 64, None] - pb[None], axis=2).min() for i in range(0, len(pa), 64))
        step = max(np.linalg.norm(T[i] - T[j]) for T in (A, B) for i in range(3) for j in range(3)) / 40
        assert got <= ref + 1e-9, case
        assert got >= ref - 2 * step, case


def _tools():
    ball = tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=12, gauge_length=30,
                                holder_diameter=20, holder_length=20), 1, "t")
    bull = tool_from_entry(dict(name="R8", type="bull", diameter=8, corner_radius=2, flute_length=12,
                                gauge_length=30), 2, "t")
    flat = tool_from_entry(dict(name="F6", type="flat", diameter=6, flute_length=12, gauge_length=30,
                                holder_diameter=16, holder_length=20), 3, "t")
    return [ball, bull, flat]


def _ridge():
    """A sharp ridge along Y (apex at x = 0, z = 10) on a block: a closed prism."""
    v = np.array([[-10, -10, 0], [10, -10, 0], [0, -10, 10], [-10, 10, 0], [10, 10, 0], [0, 10, 10]], float)
    f = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]])
    return mesh_from_arrays(v, f[:, ::-1], "ridge")



def _part_and_tools(part, tol):
    """``(mesh, kernels, t0, segs, rings)``: a box, the ridge or a sphere, and :func:`_tools`
    packed as verification packs them (a flat bottom's slab starting ``tol`` above the tip)."""
    mesh = {"box": box([-10, -10, 0], [10, 10, 10]), "ridge": _ridge(), "sphere": sphere(8.0, 12, 24)}[part]
    (t0, t1, r), cutting = pack_cylinders(_tools())
    return mesh, solid_kernels(mesh), t0, (np.where(cutting & (t0 == 0.0), tol, t0), t1, r), pack_rings(_tools())


def test_the_gap_between_triangles_along_their_centroids_never_exceeds_their_distance():
    # the cheap bound mesh_tris_dist2 prunes with: below the exact distance for any pair (near,
    # far, long and thin, touching), and near it for a far pair (so it prunes)
    rng = np.random.default_rng(5)
    close = 0
    for case in range(400):
        A = rng.uniform(-1, 1, (3, 3)) * rng.uniform(0.01, 3, 3)
        B = rng.uniform(-1, 1, (3, 3)) + rng.normal(size=3) * rng.uniform(0, 6)
        q = np.zeros(cpu.WORK_SIZE)
        q[9:18] = A.ravel()
        tri = B.reshape(1, 9).copy()
        exact = np.sqrt(cpu.clr.tri_tri_dist2(q, 9, tri, 0))
        gap = cpu.clr.tri_gap(q, 9, tri, 0)
        assert gap <= exact + 1e-12, (case, gap, exact)
        close += exact > 3.0 and gap > 0.5 * exact
    assert close > 20, close

@pytest.mark.parametrize("part", ["box", "sphere"])
def test_the_prism_search_finds_the_nearest_triangle_of_the_whole_mesh(part):
    # long tilted stadium prisms (a shank's band swept across its axis) against every triangle
    # one by one: the BVH's pruning (the prism's box, its slab, the band round the mid axis)
    # never drops the nearest; slab ends put exactly on the box's faces and vertices
    mesh = {"box": box([-10, -10, 0], [10, 10, 10]), "sphere": sphere(8.0, 16, 32)}[part]
    kern = solid_kernels(mesh)
    tris = kern.mesh[-1]
    rng = np.random.default_rng(11)
    stack, w = np.empty(cpu.STACK_SIZE, np.int32), np.zeros(cpu.WORK_SIZE)
    near = 0
    for case in range(300):
        u = rng.normal(size=3) if case % 4 else np.array([0.0, 0.0, 1.0])
        u /= np.linalg.norm(u)
        e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        (e1x, e1y, e1z), (e2x, e2y, e2z) = e1, np.cross(u, e1)
        a = rng.uniform(-12, 12, 3)
        if case % 4 == 0:  # the slab's ends on the top face (z = 10) or through a corner's height
            a[2] = 0.0
        s0, s1 = sorted(rng.uniform(-25, 25, 2))
        if case % 4 == 0:
            s0, s1 = (10.0, s1 + 20) if case % 8 == 0 else (s0 - 20, 10.0)
        v = rng.normal(size=2) * rng.uniform(0, 2)
        ref = min(cpu.clr.stadium_tri_dist2(tris, t, *a, *u, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, v[0], v[1], w)
                  for t in range(len(tris)))
        for cap in (1e300, max(4.0 * ref, 1.0) if ref < 1e200 else 1e300):  # (a finite cap: a leaning axis's test)
            got = cpu.clr.mesh_stadium_dist2(*a, *u, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, v[0], v[1], cap, 0.0,
                                             *kern.mesh, stack, w)
            assert got == ref, (case, got, ref)
        for radius in (np.sqrt(ref) * 1.001, np.sqrt(ref) * 0.999)[:2 * (ref < 1e200)]:  # capped there: found or not
            cap = radius * radius
            capped = cpu.clr.mesh_stadium_dist2(*a, *u, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, v[0], v[1], cap, cap,
                                                *kern.mesh, stack, w)
            assert (capped < cap) == (ref < cap), (case, radius)
        near += 0.0 < ref < 4.0
    assert near > 30, near


def _decide_as_exact(ring, seg, ring_d, seg_d, stop):
    """Depths measured with ``stop`` decide as the exact ones: past stop wherever those are, and
    past it only where those are too, but for the rounding of r - d at stop (ends) and a
    cylinder's axial depth within AXIAL_TOL under stop (the exact bisection may put it past)."""
    from meshmill.kernels.clearance import AXIAL_TOL
    assert (ring_d[ring > stop] > stop).all() and (seg_d[seg > stop] > stop).all()
    assert (ring[ring_d > stop] > stop - 1e-12).all() and (seg[seg_d > stop] > stop - AXIAL_TOL - 1e-12).all()
    assert np.array_equal(ring[ring_d <= stop], ring_d[ring_d <= stop])


@pytest.mark.parametrize("stop", [0.01, 0.001])
def test_a_ball_a_few_ulps_from_stop_deep_is_decided_past_it_where_it_is(stop):
    # (a review's case) a search that ends at the first triangle nearer than r - stop reported r -
    # d, which rounds to stop or under it: balls at (r - stop)(1 +- 8 ulps) from facets of a
    # sphere, mostly over their edges
    mesh = sphere(8.0, 12, 24)
    kern = solid_kernels(mesh)
    tri = mesh.vertices[mesh.faces]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    rng = np.random.default_rng(1)
    n = 20000
    for radius in (3.0, 1.3):
        rings = (np.array([radius]), np.zeros(1), np.array([radius]), np.ones(1, np.int64))
        segs = (np.zeros((1, 1)),) * 3
        f = rng.integers(0, len(tri), n)
        a = rng.random(n)
        b = np.where(rng.random(n) < 0.7, 1 - a, rng.random(n) * (1 - a))
        p = tri[f, 0] + a[:, None] * (tri[f, 1] - tri[f, 0]) + b[:, None] * (tri[f, 2] - tri[f, 0])
        up = np.tile([0.0, 0.0, 1.0], (n, 1))
        tip = p + ((radius - stop) * (1 + rng.integers(-8, 9, n) * 2.2e-16))[:, None] * nrm[f] - radius * up
        args = (tip, up, np.zeros(n, np.int64), np.zeros(n), rings, segs, segs[0])
        (ring, seg), (ring_d, seg_d) = kern.pose_penetration(*args), kern.pose_penetration(*args, stop=stop)
        _decide_as_exact(ring, seg, ring_d, seg_d, stop)
        assert (ring > stop).sum() > 100 and (ring <= stop).sum() > 100


@pytest.mark.parametrize("part", ["box", "ridge", "sphere"])
def test_a_depth_asked_only_past_a_stop_decides_as_the_exact_one(part):
    # poses above, grazing, in and buried in the part, every tool, grown or not: with ``stop``
    # each depth is past stop exactly where the exact one is, equal to it at or below stop (the
    # rounded ends) or between it and stop (the cylinders: the radial depth, or stop itself)
    stop = 0.01
    mesh, kern, t0, segs, rings = _part_and_tools(part, stop)
    top = mesh.bounds[1, 2]
    rng = np.random.default_rng(7)
    n = 3000
    tip = np.column_stack([rng.uniform(-14, 14, n), rng.uniform(-14, 14, n), top + rng.uniform(-12, 4, n)])
    axis = np.column_stack([rng.uniform(-0.6, 0.6, (n, 2)) * (rng.random((n, 1)) < 0.6), np.ones(n)])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    tool = rng.integers(0, 3, n)
    # two thirds on the surface: the tip on an upward facet, a few hundredths off it
    tri = mesh.vertices[mesh.faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    up = np.nonzero(normal[:, 2] > 0.3 * np.linalg.norm(normal, axis=1))[0]
    on = rng.random(n) < 0.67
    f = rng.choice(up, on.sum())
    a, b = rng.random((2, on.sum()))
    a, b = np.where(a + b > 1, 1 - a, a), np.where(a + b > 1, 1 - b, b)
    tip[on] = tri[f, 0] + a[:, None] * (tri[f, 1] - tri[f, 0]) + b[:, None] * (tri[f, 2] - tri[f, 0])
    nrm = normal[f] / np.linalg.norm(normal[f], axis=1, keepdims=True)
    axis[on] = nrm
    tip[on] += rng.uniform(-0.02, 0.01, (on.sum(), 1)) * nrm
    # a third of those on their side: the first cylinder's middle alongside the facet, radially
    # a few hundredths into it
    idx = np.nonzero(on)[0]
    side = rng.random(len(idx)) < 0.33
    k = idx[side]
    tan = np.cross(nrm[side], rng.normal(size=(len(k), 3)))
    tan /= np.linalg.norm(tan, axis=1, keepdims=True)
    reach = segs[2][tool[k], 0] - rng.uniform(-0.01, 0.02, len(k))
    mid = 0.5 * (segs[0][tool[k], 0] + segs[1][tool[k], 0])
    axis[k] = tan
    tip[k] += reach[:, None] * nrm[side] - mid[:, None] * tan
    grow = np.where(rng.random(n) < 0.3, 0.5, 0.0)
    ring, seg = kern.pose_penetration(tip, axis, tool, grow, rings, segs, t0)
    # half the poses in contact raised along their axis to about stop deep, either side of it
    deep = np.maximum(ring, seg.max(axis=1))
    lift = (deep > 0) & (deep < 1.0) & (rng.random(n) < 0.6)
    tip[lift] += (deep[lift] - rng.uniform(0.0, 2 * stop, lift.sum()))[:, None] * axis[lift]
    ring, seg = kern.pose_penetration(tip, axis, tool, grow, rings, segs, t0)
    ring_d, seg_d = kern.pose_penetration(tip, axis, tool, grow, rings, segs, t0, stop=stop)
    _decide_as_exact(ring, seg, ring_d, seg_d, stop)
    low = ring <= stop
    assert np.array_equal(ring[low], ring_d[low])
    low = seg <= stop
    assert (seg[low] <= seg_d[low] + 1e-15).all() and (seg_d[low] <= stop).all()
    # the cases are there: both sides of stop, for ends and cylinders, and buried poses
    assert 50 < (ring > stop).sum() < n - 50 and 50 < (seg > stop).any(axis=1).sum() < n - 50
    assert ((ring > 0) & (ring <= stop)).sum() > 10 and ((seg > 0) & (seg <= stop)).sum() > 5
    assert (ring > 1.0).sum() > 50


@pytest.mark.parametrize("part", ["box", "ridge", "sphere"])
@pytest.mark.slow
def test_every_clear_interval_is_clear_at_every_pose(part):
    tol = 0.01
    mesh, kern, t0, segs, rings = _part_and_tools(part, tol)
    top = mesh.bounds[1, 2]
    fine = (rings[0], rings[1], rings[2], np.full(3, 720))  # the torus densely sampled for the reference
    rng = np.random.default_rng({"box": 2, "ridge": 3, "sphere": 4}[part])
    n = 240
    tool = rng.integers(0, 3, n)
    ta = np.column_stack([rng.uniform(-8, 8, n), rng.uniform(-8, 8, n), top + rng.uniform(-0.3, 0.6, n)])
    move = rng.normal(size=(n, 3)) * rng.uniform(0.0, 1.5, (n, 1))
    tb = ta + move
    tilt = lambda k: np.column_stack([rng.uniform(-0.4, 0.4, (k, 2)), np.ones(k)])  # noqa: E731
    xa = tilt(n)
    xa /= np.linalg.norm(xa, axis=1, keepdims=True)
    xb = np.where(rng.random((n, 1)) < 0.5, xa, xa + rng.normal(scale=0.05, size=(n, 3)))
    xb /= np.linalg.norm(xb, axis=1, keepdims=True)
    grow = np.where(rng.random(n) < 0.2, 0.5, 0.0)
    ok = kern.intervals_clear(ta, xa, tb, xb, tool, grow, np.full(n, tol), rings, segs, t0)
    tp = Toolpath(np.stack([ta, tb], 1).reshape(-1, 3), np.stack([xa, xb], 1).reshape(-1, 3),
                  np.zeros(2 * n, bool), np.repeat(tool, 2))
    s = np.linspace(0.0, 1.0, 801)
    worst = np.zeros(n)
    for i in range(n):
        m = np.full(len(s), 2 * i + 1)
        tip, axis = move_poses(tp, m, s)
        ring, seg = kern.pose_penetration(tip, axis, np.full(len(s), tool[i]), np.full(len(s), grow[i]), fine,
                                          segs, t0)
        worst[i] = max(ring.max(), seg.max())
    # a "clear" interval is clear at every pose, within what 800 poses can miss (the moves are
    # at most a few mm long and turn a few degrees: the poses are a few µm apart)
    assert (worst[ok] <= tol + 2e-4).all(), (worst[ok].max(), np.nonzero(ok & (worst > tol + 2e-4))[0])
    # and the test is not idle: most intervals well clear of the part are proven so
    free = worst <= 0.0
    assert ok[free].mean() > 0.8
    assert ok.any() and (~ok).any()


def test_points_inside_a_closed_solid_a_void_and_under_a_sheet():
    outer = box([0, 0, 0], [10, 10, 10])
    inner = box([3, 3, 3], [7, 7, 7])
    v = np.vstack([outer.vertices, inner.vertices])
    f = np.vstack([outer.faces, inner.faces[:, ::-1] + len(outer.vertices)])  # the void faces inward
    hollow = mesh_from_arrays(v, f, "hollow")
    k = solid_kernels(hollow)
    pts = np.array([[1, 1, 1], [5, 5, 5], [5, 5, 8], [5, 5, 11], [-1, 5, 5], [5, 5, 2]], float)
    assert k.points_inside(pts).tolist() == [True, False, True, False, False, True]
    # a sheet: a tilted quad; the material is below it
    sheet = mesh_from_arrays(np.array([[0, 0, 0], [10, 0, 2], [10, 10, 2], [0, 10, 0]], float),
                             np.array([[0, 1, 2], [0, 2, 3]]), "sheet")
    k = solid_kernels(sheet)
    # (down to the floor: as deep again below the sheet's lowest point as it is tall, at least 10 mm)
    pts = np.array([[5, 5, 0.5], [5, 5, 1.5], [5, 5, -0.5], [5, 5, -10.5], [11, 5, 0.5], [5, 5, 1.0]], float)
    assert sheet.solid().floor == -10.0
    assert k.points_inside(pts).tolist() == [True, False, True, False, False, False]


@pytest.mark.parametrize("limit, clear", [(0.012, True), (0.008, False)])
def test_a_fixed_axis_step_up_past_an_edge_is_decided_in_pieces(limit, clear):
    """A flat cylinder whose side touches a block's wall at the start and whose bottom reaches the
    block's top at the end, moving up and away by 0.02 mm: every pose enters by at most 0.01 mm
    (the smaller of the side's and the bottom's depth), which the prism of the whole move (its
    bottom 0.02 mm low all along) cannot show; cut in pieces along the axis it is proven within
    0.012, and never within 0.008 (dense poses, measured exactly, are the reference)."""
    kern = solid_kernels(box([-20, -10, -10], [1, 10, 0]))
    t0 = np.array([[0.0]])
    segs = (t0, np.array([[10.0]]), np.array([[1.0]]))
    rings = (np.zeros(1), np.zeros(1), np.zeros(1), np.ones(1, np.int64))
    ta, tb = np.array([[2.0, 0.0, -0.02]]), np.array([[1.98, 0.0, 0.0]])
    up = np.array([[0.0, 0.0, 1.0]])
    one = np.zeros(1, np.int64)
    ok = kern.intervals_clear(ta, up, tb, up, one, np.zeros(1), np.full(1, limit), rings, segs, t0)
    assert ok[0] == clear
    s = np.linspace(0.0, 1.0, 2001)[:, None]
    _, seg = kern.pose_penetration(ta + s * (tb - ta), np.repeat(up, len(s), 0), np.zeros(len(s), np.int64),
                                   np.zeros(len(s)), rings, segs, t0)
    assert seg.max() == pytest.approx(0.01, abs=1e-6)


@pytest.mark.slow
def test_a_climbing_cylinders_sweep_is_the_least_distance_of_its_poses():
    """The sweep of an axis segment moved along and across a fixed axis, against a triangle: never
    farther than any of its poses (each pose's distance across the axis to the part of the
    triangle level with it: the prism test of that pose alone), and no nearer than the nearest of
    801 poses less their spacing. Corners and edges on the slab's faces and grid values included."""
    rng = np.random.default_rng(11)
    w = np.zeros(cpu.WORK_SIZE)
    over = under = 0.0
    for k in range(600):
        u = np.array([0.0, 0.0, 1.0]) if k % 3 == 0 else rng.normal(size=3)
        u /= np.linalg.norm(u)
        e1 = np.cross(u, [1.0, 0.0, 0.0] if abs(u[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(u, e1)
        a = rng.normal(size=3)
        h0 = rng.uniform(-1, 1)
        h1 = h0 + rng.uniform(0.01, 3)
        dh, dx, dy = rng.normal(size=3) * rng.choice([0.1, 1.0])
        tri = rng.normal(size=(3, 3)) * 1.5 + a
        if k % 5 == 0:  # corners on the slab's faces
            tri = a + np.round((tri - a) * 2) / 2
            h0, h1 = np.floor(h0 * 2) / 2, np.ceil(h1 * 2) / 2
        tris = tri.reshape(1, 9).copy()
        got = cpu.clr.sheared_tri_dist2(tris, 0, *a, *u, *e1, *e2, h0, h1, dh, dx, dy, w)
        poses = [cpu.clr.stadium_tri_dist2(tris, 0, *(a + s * (dh * u + dx * e1 + dy * e2)), *u, *e1, *e2, h0, h1, 0.0,
                                           0.0, w) for s in np.linspace(0.0, 1.0, 801)]
        near = min(poses)
        if near >= 1e299:
            assert got >= 1e299 or got <= 4.0  # (a crossing between poses: only near them)
            continue
        over = max(over, np.sqrt(got) - np.sqrt(near))
        under = max(under, np.sqrt(near) - np.sqrt(got))
    assert over <= 1e-12  # never farther than a pose: a sweep found clear is clear at every pose
    assert under <= 0.01  # and as near as the poses, to their spacing (moves of up to ~5 mm, 801 poses)


def test_a_cylinder_sinking_away_from_a_ledge_is_proven_in_one_sweep():
    """A flat cylinder (radius 1) whose rim leaves a block's top edge while it sinks 4 mm beside it:
    the prism of the whole move reaches down to its lowest pose's bottom all along, and that of
    each of its 16 pieces 0.25 mm below its own (0.02 mm into the block where the rim leaves it);
    the exact sweep keeps 0.1 mm above the block there (dense poses, measured exactly, are the
    reference). The same move 0.2 mm lower enters it."""
    kern = solid_kernels(box([-20, -10, -10], [1, 10, 0]))
    t0 = np.array([[0.0]])
    segs = (t0, np.array([[10.0]]), np.array([[1.0]]))
    rings = (np.zeros(1), np.zeros(1), np.zeros(1), np.ones(1, np.int64))
    up = np.array([[0.0, 0.0, 1.0]])
    s = np.linspace(0.0, 1.0, 2001)[:, None]
    for lower, clear in ((0.0, True), (0.2, False)):
        ta, tb = np.array([[1.53, 0.0, 1.98 - lower]]), np.array([[2.53, 0.0, -2.02 - lower]])
        ok = kern.intervals_clear(ta, up, tb, up, np.zeros(1, np.int64), np.zeros(1), np.full(1, 0.01), rings, segs,
                                  t0)
        _, seg = kern.pose_penetration(ta + s * (tb - ta), np.repeat(up, len(s), 0), np.zeros(len(s), np.int64),
                                       np.zeros(len(s)), rings, segs, t0)
        assert ok[0] == clear and (seg.max() == 0.0) == clear


@pytest.mark.parametrize("depth", [3e-8, 4e-6, 0.0123, 0.4])
def test_a_cylinders_axial_depth_is_never_less_than_it_is(depth):
    """A cylinder of radius 1 whose bottom lies ``depth`` into a block's top, its axis 0.5 mm in
    from the block's side (radially 1.5 deep) and tilted a little: its depth is the axial one,
    bisected from above to within AXIAL_TOL (never less than the true depth)."""
    from meshmill.kernels.clearance import AXIAL_TOL
    kern = solid_kernels(box([-0.5, -10, -10], [20, 10, 0]))
    tilt = np.radians(0.3)
    axis = np.array([[np.sin(tilt), 0.0, np.cos(tilt)]])
    # the bottom's lowest point (its rim towards -x) lies ``depth`` below z = 0
    tip = np.array([[0.0, 0.0, -depth + np.sin(tilt) * 1.0]])
    t0 = np.array([[0.0]])
    segs = (t0, np.array([[10.0]]), np.array([[1.0]]))
    rings = (np.zeros(1), np.zeros(1), np.zeros(1), np.ones(1, np.int64))
    _, seg = kern.pose_penetration(tip, axis, np.zeros(1, np.int64), np.zeros(1), rings, segs, t0)
    # the rim point (-cos, 0, sin) of the bottom disk is the lowest: depth / cos(tilt) along the axis
    true = depth / np.cos(tilt)
    assert true <= seg[0, 0] <= true + AXIAL_TOL + 1e-12, (seg[0, 0], true)


@pytest.mark.parametrize("drop, limit, clear", [(0.0, 0.0, False), (0.0, 0.01, True), (1e-9, 0.0, True)])
def test_a_shank_bottom_exactly_on_a_face_is_seen(drop, limit, clear):
    """A shank wider than the ball passes over a block's edge with its flat bottom exactly at the
    block's top (its vertices and face on the slab's plane, where the prism's boxes are pruned):
    touching it is 0 deep, so not clear within a limit of 0, clear within 0.01; a nanometre higher
    it is clear at any limit."""
    kern = solid_kernels(box([2.5, -10, -10], [20, 10, 10]))
    ball = tool_from_entry(dict(name="B4", type="ball", diameter=4, flute_length=10, gauge_length=30,
                                shank_diameter=6), 1, "t")
    (t0, t1, r), cutting = pack_cylinders([ball])
    rings = pack_rings([ball])
    up = np.array([[0.0, 0.0, 1.0]])
    ta, tb = np.array([[0.0, -5.0, drop]]), np.array([[0.0, 5.0, drop]])
    ok = kern.intervals_clear(ta, up, tb, up, np.zeros(1, np.int64), np.zeros(1), np.full(1, limit), rings,
                              (t0, t1, r), t0)
    assert ok[0] == clear


def _patch_call():
    import numba

    @numba.njit
    def call(ta, ua, tb, ub, h0, h1, need, node_lo, node_hi, node_child, node_range, tris):
        w = np.empty(cpu.WORK_SIZE)
        stack = np.empty(128, np.int32)
        return cpu.clr.patch_clear(w, ta, ua, tb, ub, h0, h1, need, node_lo, node_hi, node_child, node_range, tris,
                                   stack)
    return call


def test_a_swept_axis_segment_is_proven_clear_only_where_every_point_of_its_patch_is():
    """The tetrahedron test of a segment of the axis swept between two poses against the bilinear
    patch it bounds, sampled densely (the patch's distance is what a ball and its flutes sweep),
    on soups of random triangles."""
    from meshmill.kernels.bvh import build_bvh

    call = _patch_call()
    rng = np.random.default_rng(7)
    s = np.linspace(0.0, 1.0, 81)
    proven = doubted = 0
    for case in range(80):
        v = rng.uniform(-6, 6, (12, 3))
        f = np.array([rng.permutation(12)[:3] for _ in range(8)])
        bvh = build_bvh(v, f).arrays
        ta = rng.uniform(-3, 3, 3)
        tb = ta + rng.normal(scale=1.0, size=3)
        ua = rng.normal(size=3)
        ua /= np.linalg.norm(ua)
        ub = ua + rng.normal(scale=0.4, size=3) * (case % 2)
        ub /= np.linalg.norm(ub)
        h0, h1 = 1.0, rng.uniform(2, 8)
        # the patch, densely: (1 - t)(ta + h ua) + t (tb + h ub)
        tt, hh = np.meshgrid(s, h0 + s * (h1 - h0), indexing="ij")
        pts = ((1 - tt)[..., None] * (ta + hh[..., None] * ua) + tt[..., None] * (tb + hh[..., None] * ub))
        ref = cpu.mesh_distances(pts.reshape(-1, 3), bvh).min()
        step = (np.linalg.norm(tb - ta) + (h1 - h0) * (1 + np.linalg.norm(ub - ua))) / 80
        for need in (0.5 * ref, ref - step, ref + 0.05, 2 * ref + 0.1):
            if need <= 0:
                continue
            ok = call(ta, ua, tb, ub, h0, h1, need, *bvh)
            assert not ok or ref >= need - 1e-9, (case, need, ref)
            proven += ok
            doubted += not ok
            if need <= ref - step and case % 2 == 0:
                assert ok, (case, need, ref)  # a fixed axis: the patch is its own hull, the test exact
    assert proven > 60 and doubted > 60, (proven, doubted)


def test_a_triangle_wholly_inside_the_swept_hull_is_found():
    from meshmill.kernels.bvh import build_bvh

    call = _patch_call()
    ta, tb = np.zeros(3), np.array([4.0, 0, 0])
    ua, ub = np.array([0, 0, 1.0]), np.array([0, 1.0, 0])  # a quarter turn: a fat tetrahedron
    corners = np.array([ta + ua, ta + 6 * ua, tb + ub, tb + 6 * ub])
    tri = corners.mean(axis=0) + 0.05 * np.eye(3)
    assert not call(ta, ua, tb, ub, 1.0, 6.0, 0.01, *build_bvh(tri, np.array([[0, 1, 2]])).arrays)
    far = tri + np.array([0, 0, 40.0])
    assert call(ta, ua, tb, ub, 1.0, 6.0, 0.01, *build_bvh(far, np.array([[0, 1, 2]])).arrays)


def test_a_turning_ball_leaning_over_an_edge_is_proven_to_its_depth():
    """A ball with long flutes leaning over the ridge's apex, turning up to 20 degrees a move: each
    move set to reach 5 to 30 µm into the part (its depth found on 2001 poses); no move is proven
    within a limit 2 µm under that depth, and nearly all within 5 µm over it (the sweep of the
    axis lies in the patch of the axis lengthened by 1 / cos(theta/2): no slack across it)."""
    ball = tool_from_entry(dict(name="B2", type="ball", diameter=2, flute_length=20, gauge_length=40), 1, "t")
    kern = solid_kernels(_ridge())
    (t0, t1, r), _ = pack_cylinders([ball])
    segs, rings = (t0, t1, r), pack_rings([ball])
    rng = np.random.default_rng(5)
    n = 120
    ta = np.column_stack([rng.uniform(-6, -1, n), rng.uniform(-3, 3, n), rng.uniform(2, 9, n)])
    tb = ta + rng.normal(scale=0.3, size=(n, 3))

    def axis(th, ph):
        return np.column_stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])

    th, ph = rng.uniform(0.2, 0.9, n), rng.uniform(-0.6, 0.6, n)
    xa, xb = axis(th, ph), axis(th + rng.uniform(-0.35, 0.35, n), ph + rng.uniform(-0.35, 0.35, n))
    s = np.linspace(0.0, 1.0, 2001)
    flank = np.array([-1.0, 0.0, 1.0]) / np.sqrt(2)

    def depth(ta, tb):
        tp = Toolpath(np.stack([ta, tb], 1).reshape(-1, 3), np.stack([xa, xb], 1).reshape(-1, 3),
                      np.zeros(2 * n, bool), np.zeros(2 * n, np.int64))
        out = np.zeros(n)
        for i in range(n):
            tip, ax = move_poses(tp, np.full(len(s), 2 * i + 1), s)
            ring, seg = kern.pose_penetration(tip, ax, np.zeros(len(s), np.int64), np.zeros(len(s)), rings, segs, t0)
            out[i] = max(ring.max(), seg.max())
        return out

    target = rng.uniform(0.005, 0.03, n)
    for _ in range(3):  # moved along the flank's normal to the depth aimed at
        d = depth(ta, tb)
        shift = np.where(d > 0.0, d - target, -1.0)[:, None] * flank
        ta, tb = ta + shift, tb + shift
    d = depth(ta, tb)
    sel = (d > 0.004) & (d < 0.05)
    assert sel.sum() > 90
    zero, tool = np.zeros(sel.sum()), np.zeros(sel.sum(), np.int64)
    under = kern.intervals_clear(ta[sel], xa[sel], tb[sel], xb[sel], tool, zero, d[sel] - 0.002, rings, segs, t0)
    assert not under.any()
    over = kern.intervals_clear(ta[sel], xa[sel], tb[sel], xb[sel], tool, zero, d[sel] + 0.005, rings, segs, t0)
    assert over.mean() > 0.9


def test_the_rim_of_a_turning_balls_flutes_is_held_where_the_axis_bulges():
    """A ball turning 40 degrees about its fixed tip: half-way, the flutes' top rim lies t1 (1 -
    cos 20 deg) = 1.2 mm above the chord of the axis's ends. A small triangle 0.02 mm inside the
    rim there is found (the axis's patch is lengthened to t1 / cos(theta/2)); one 0.05 mm outside
    the tool at every pose is proven clear."""
    from meshmill.kernels.bvh import build_bvh

    ball = tool_from_entry(dict(name="B2", type="ball", diameter=2, flute_length=20, gauge_length=20), 1, "t")
    (t0, t1, r), _ = pack_cylinders([ball])
    rings = pack_rings([ball])
    half = np.radians(20.0)
    xa, xb = np.array([[-np.sin(half), 0, np.cos(half)]]), np.array([[np.sin(half), 0, np.cos(half)]])
    tip = np.zeros((1, 3))
    for q, clear in (([0.0, 0.99, 19.98], False), ([0.0, 1.05, 19.9], True)):
        tri = np.asarray(q) + 1e-3 * np.array([[0, 0, 0], [1.0, 0, 0], [0, 0, 1.0]])
        bvh = build_bvh(tri, np.array([[0, 1, 2]])).arrays
        ok = cpu.intervals_clear(tip, xa, tip, xb, np.zeros(1, np.int64), np.zeros(1), np.full(1, 0.002), rings,
                                 (t0, t1, r), t0, bvh)
        assert ok[0] == clear, q
