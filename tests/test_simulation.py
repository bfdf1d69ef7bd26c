"""Material-removal simulation: swept volumes against sampled references, analytic removed
volumes, scallops, gouges, rapid moves, the machined mesh and the command line."""
import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
import trimesh

from meshmill.cli import main
from meshmill.geometry.shapes import box
from meshmill.kernels.cpu_dexel import swp
from meshmill.ops.simulate import simulate
from meshmill.simulation.stock import Stock
from meshmill.simulation.cut import SWEEP_TOL, cut, split_turns, stock_from_model, toolpath_moves, turn_pieces, twist_strips
from meshmill.simulation.dexel import dexelize
from meshmill.simulation.exactsum import expansion, total
from meshmill.simulation.surface import machined_mesh
from meshmill.toolpath.model import Toolpath
from meshmill.tools.table import Tool

BALL = Tool("B6", "ball", 6.0, 3.0, 12.0, 40.0, 6.0)
FLAT = Tool("F6", "flat", 6.0, 0.0, 12.0, 40.0, 6.0)
BULL = Tool("R6", "bull", 6.0, 1.0, 12.0, 40.0, 6.0)


def tool_gap(p, tip, x, R, r, F, axes=None):
    """Reference: how far points p (k, 3) lie outside the cutter model at one pose (inside: minus
    how deep, within the core's depth); with ``axes (k, 3)`` one pose per point instead."""
    q = p - tip
    a = q @ x if axes is None else np.einsum("ij,ij->i", q, axes)
    x = x if axes is None else axes
    rad = np.linalg.norm(q - a[:, None] * x, axis=1)
    H = max(0.0, F - 2 * r)
    ax = a - r
    gap = np.maximum(0, np.maximum(-ax, ax - H))
    # inside the core (the disk swept up H), minus how deep: a signed distance for flat ends too
    depth = np.maximum(0, np.minimum(np.minimum((R - r) - rad, ax), H - ax))
    return np.sqrt(np.maximum(0, rad - (R - r)) ** 2 + gap ** 2) - depth - r


def inside_tool(p, tip, x, R, r, F):
    return tool_gap(p, tip, x, R, r, F) <= 1e-12


@pytest.mark.parametrize("tool", [BALL, FLAT, BULL])
@pytest.mark.parametrize("turn", [0.0, 0.01])
@pytest.mark.slow
def test_swept_interval_matches_dense_sampling(tool, turn):
    """Line against the swept volume of a move (split as the simulation splits turning moves)
    equals the union of densely sampled poses, within the sampling and SWEEP_TOL."""
    rng = np.random.default_rng(7)
    R, r, F = tool.radius, (tool.radius if tool.type == "ball" else tool.corner_radius), tool.flute_length
    w = np.linspace(-20, 20, 2001)
    for _ in range(15):
        pa = rng.uniform(-2, 2, 3)
        pb = pa + rng.normal(size=3) * rng.choice([0.0, 0.3, 3.0])
        xa = np.array([0.0, 0.0, 1.0]) if rng.random() < 0.5 else rng.normal(size=3)
        xa /= np.linalg.norm(xa)
        k = np.cross(xa, rng.normal(size=3))
        k /= np.linalg.norm(k)
        xb = xa * math.cos(turn) + k * math.sin(turn)
        one = (pa[None], pb[None], xa[None], xb[None])
        _, p0, p1, x0, x1 = split_turns(*one, turn_pieces(*one, np.array([R]), np.array([r]), np.array([F])))
        strips = twist_strips(p0, p1, x0, x1, np.full(len(p0), r), np.full(len(p0), F))
        dense = np.linspace(0, 1, 101)
        for _ in range(4):
            u0, v0 = rng.uniform(-5, 5, 2)
            lo, hi = math.inf, -math.inf
            for j in range(len(p0)):
                a, b = swp.tool_move(u0, v0, p0[j], p1[j], x0[j], x1[j], R, r, F, int(strips[j]))
                lo, hi = min(lo, a), max(hi, b)
            pts = np.column_stack([np.full_like(w, u0), np.full_like(w, v0), w])
            hit = np.zeros(len(w), bool)
            for t in dense:
                x = xa + t * (xb - xa)
                hit |= inside_tool(pts, pa + t * (pb - pa), x / np.linalg.norm(x), R, r, F)
            if not hit.any():
                assert lo > hi or hi - lo < 0.1
                continue
            # every sampled point lies in the interval (up to SWEEP_TOL), and its ends lie on the
            # swept volume (distance to the nearest of 4001 poses, which are at most |D|/4000 apart)
            assert lo - SWEEP_TOL <= w[hit].min() and w[hit].max() <= hi + SWEEP_TOL
            fine = np.linspace(0, 1, 4001)[:, None]
            x = xa + fine * (xb - xa)
            x /= np.linalg.norm(x, axis=1, keepdims=True)
            tips = pa + fine * (pb - pa)
            gap = [min(tool_gap(np.array([[u0, v0, e]]) - tips + 0.0, np.zeros(3), None, R, r, F, x)) for e in (lo, hi)]
            gap = np.array(gap)
            assert (gap <= SWEEP_TOL + np.linalg.norm(pb - pa) / 4000 + 1e-6).all()


def test_the_floor_of_a_convex_function_from_four_values_is_never_above_its_minimum():
    """The golden search of a line point's distance to a bull-nose's swept core stops once the
    chords of its four values prove the minimum beyond the radius (the bisection asks only that):
    that floor is never above the true minimum, on smooth, kinked and tilted convex functions."""
    rng = np.random.default_rng(1)
    gaps = []
    for _ in range(3000):
        k, p, s0, m = rng.uniform(0.1, 5), rng.choice([1.0, 1.5, 2.0, 4.0]), rng.uniform(-0.5, 1.5), rng.normal()
        a, b = np.sort(rng.uniform(0, 1, 2))
        s1, s2 = b - 0.6180339887498949 * (b - a), a + 0.6180339887498949 * (b - a)
        f = lambda s: k * np.abs(s - s0) ** p + m * s  # noqa: E731
        floor = swp.convex_floor(a, s1, s2, b, f(a), f(s1), f(s2), f(b))
        true = f(np.linspace(a, b, 4001)).min()
        assert floor <= true + 1e-9 * (1 + abs(true))
        gaps.append(true - floor)
    assert np.median(gaps) < 0.05  # and it is a useful bound


def _tool_boxes(tips, x, R, r, F):
    """Boxes ``(k, 2, 3)`` (lowest, highest corner) of a cutter's surface at ``k`` poses (tips and
    unit axes ``(k, 3)``): its corner torus at the bottom and its rounded top at F (the model of
    ``tool_gap``) as 13 circles around the axis, each circle's box exact."""
    x = np.atleast_2d(x)
    tips = np.atleast_2d(tips)
    alpha = np.linspace(0.0, math.pi, 13)
    rad = (R - r) + r * np.sin(alpha)
    h = np.where(alpha <= math.pi / 2, r, max(r, F - r)) - r * np.cos(alpha)
    centre = tips[:, None] + h[None, :, None] * x[:, None]  # (k, 13, 3)
    half = rad[None, :, None] * np.sqrt(np.maximum(0.0, 1.0 - x * x))[:, None]  # a circle's reach along each axis
    return np.stack([(centre - half).min(axis=1), (centre + half).max(axis=1)], axis=1)


@pytest.mark.parametrize("degrees", [60.0, 120.0, 170.0])
def test_a_move_turning_far_is_cut_in_pieces_of_equal_turns_within_their_boxes(degrees):
    """A move whose axis turns far is split in pieces of equal turns whose ends are poses of the
    move; the tool at 2001 poses of the move (tip linear, axis by the normalised interpolation)
    lies in the box of one of its pieces, and at 101 poses of each piece in that piece's box
    (shanks and holders too, within their own tolerance). Equal steps of the interpolation instead turn the middle pieces
    up to 2 tan(θ/2)/θ times more, and their tool leaves their boxes."""
    from meshmill.simulation import cut as cutting
    from meshmill.tools.table import tool_from_entry

    rng = np.random.default_rng(int(degrees))
    holder = tool_from_entry(dict(name="B6h", type="ball", diameter=6.0, flute_length=12.0, gauge_length=40.0,
                                  holder_diameter=32.0, holder_length=40.0), 1, "t")
    tools = [BALL, BULL, FLAT, holder]
    for case in range(8):
        xa = rng.normal(size=3)
        xa /= np.linalg.norm(xa)
        k = np.cross(xa, rng.normal(size=3))
        k /= np.linalg.norm(k)
        theta = math.radians(degrees)
        xb = xa * math.cos(theta) + k * math.sin(theta)
        ti = case % len(tools)
        tp = Toolpath(np.array([[0.0, 0.0, 0.0], rng.normal(size=3)]), np.array([xa, xb]), np.zeros(2, bool),
                      np.array([ti, ti]))
        moves = toolpath_moves(tp, tools)
        if ti == 3:
            moves = cutting.body_moves(tp, tools)
        keep = (moves.source == 1) & (moves.radius == moves.radius.max())  # the holder of the bodies
        moves = cutting.Moves(*(getattr(moves, f)[keep] for f in (
            "pa", "pb", "xa", "xb", "radius", "corner", "flutes", "strips", "rapid", "source", "body")))
        boxes = cutting._boxes(moves)
        turns = np.arccos(np.clip(np.einsum("ij,ij->i", moves.xa, moves.xb), -1, 1))
        assert len(moves) > 3 and np.allclose(turns, theta / len(moves), rtol=1e-6)
        assert np.array_equal(moves.pb[:-1], moves.pa[1:]) and np.array_equal(moves.xb[:-1], moves.xa[1:])
        R, r, F = moves.radius[0], moves.corner[0], moves.flutes[0]
        lift = float((moves.pa[0] - tp.tip[0]) @ xa)  # a body's cylinder starts up the axis
        delta = theta / len(moves)
        reach, H = math.hypot(lift + F, R), max(0.0, lift + F - 2 * r)
        ts = np.linspace(0, 1, 2001)
        xs = xa + ts[:, None] * (xb - xa)
        xs /= np.linalg.norm(xs, axis=1, keepdims=True)
        poses = _tool_boxes(tp.tip[0] + ts[:, None] * (tp.tip[1] - tp.tip[0]) + lift * xs, xs, R, r, F)
        for t, x, pose in zip(ts, xs, poses):
            inside = np.all((pose[0] >= boxes[:, 0] - 1e-9) & (pose[1] <= boxes[:, 1] + 1e-9), axis=1)
            assert inside.any(), (degrees, ti, t)
            # the piece holding this axis, at the same tip: its axis is near enough that the tool's
            # farthest point is within its tolerance of here, less the piece's chord sag
            j = min(len(moves) - 1, int(math.acos(min(1.0, x @ xa)) / delta))
            foot = moves.pa[j] - lift * moves.xa[j], moves.pb[j] - lift * moves.xb[j]
            d = foot[1] - foot[0]
            s = (tp.tip[0] + t * (tp.tip[1] - tp.tip[0]) - foot[0]) @ d / (d @ d)
            y = moves.xa[j] + s * (moves.xb[j] - moves.xa[j])
            off = math.acos(min(1.0, x @ y / np.linalg.norm(y)))
            tol = cutting.BODY_SWEEP_TOL if ti == 3 else SWEEP_TOL
            assert reach * off + (R + H) * delta ** 2 / 8 <= tol * (1 + 1e-6), (degrees, ti, t)
        ss = np.linspace(0, 1, 101)[:, None]
        for m in range(len(moves)):
            x = moves.xa[m] + ss * (moves.xb[m] - moves.xa[m])
            x /= np.linalg.norm(x, axis=1, keepdims=True)
            pose = _tool_boxes(moves.pa[m] + ss * (moves.pb[m] - moves.pa[m]), x, R, r, F)
            assert np.all(pose[:, 0] >= boxes[m, 0] - 1e-9) and np.all(pose[:, 1] <= boxes[m, 1] + 1e-9), (degrees, ti, m)


def test_a_pose_of_a_flat_or_bull_nose_meets_a_line_where_its_points_are():
    """One pose of a flat end or bull-nose against a line (:func:`sweep.stand`, closed form but
    for the rims): the interval holds every point of the line inside the tool and its ends lie on
    the tool's boundary; axes along the line and across it, and lines exactly on the side, the
    rim and the end face's edge, included."""
    rng = np.random.default_rng(11)
    w = np.linspace(-30.0, 30.0, 60001)
    met = 0
    for case in range(400):
        R = float(rng.choice([2.0, 3.0, 5.0]))
        r = float(rng.choice([0.0, 0.5, 1.0, R / 2]))
        F = float(rng.choice([10.0, 16.0]))
        x = np.zeros(3)
        if case % 4 == 0:
            x[2] = rng.choice([-1.0, 1.0])
        elif case % 4 == 1:
            x[rng.integers(0, 2)] = rng.choice([-1.0, 1.0])
        else:
            x = rng.normal(size=3)
            x /= np.linalg.norm(x)
        tip = np.round(rng.uniform(-2, 2, 3), 1)
        if case % 4 == 0:  # on the side (R), the rim's start (R - r) or the axis, exactly
            off = float(rng.choice([R, R - r, 0.0, R + 0.5]))
            u0, v0 = tip[0] + off, tip[1]
        else:
            u0, v0 = tip[:2] + rng.uniform(-R - 1, R + 1, 2)
        H = max(0.0, F - 2 * r)
        c = tip + r * x
        lo, hi = swp.stand(u0, v0, *c, *x, H, R - r, r, 3)
        pts = np.column_stack([np.full_like(w, u0), np.full_like(w, v0), w])
        gap = tool_gap(pts, tip, x, R, r, F)
        inside = gap <= 0.0
        if lo > hi:
            assert not (gap < -1e-6).any(), case
            continue
        met += 1
        assert (w[gap < -1e-9] >= lo - 1e-6).all() and (w[gap < -1e-9] <= hi + 1e-6).all(), case
        if inside.any():
            assert w[inside].min() <= lo + 1e-3 + 1e-6 and w[inside].max() >= hi - 1e-3 - 1e-6, case
        ends = tool_gap(np.array([[u0, v0, lo], [u0, v0, hi]]), tip, x, R, r, F)
        assert (np.abs(ends) <= 1e-8).all(), (case, ends)
    assert met > 150


def test_a_line_grazing_a_bull_nose_meets_it_where_it_touches():
    """Lines that only touch a bull-nose: along its side with the axis along the line (the
    3-axis case against dexels along the axis), and tangent to its rounded rim at a point whose
    normal is across the line, with tilted axes. The ends lie within 1e-7 mm of where they touch
    (the distance is flat along such a line: float64's resolution of it allows some 3e-8 mm along
    the line; stopping on the distance within 1e-13 alone left 5e-7 mm)."""
    lo, hi = swp.stand(3.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 8.0, 2.0, 1.0, 3)
    assert lo == pytest.approx(1.0, abs=1e-12) and hi == pytest.approx(9.0, abs=1e-12)
    rng = np.random.default_rng(4)
    w = np.array([0.0, 0.0, 1.0])
    checked = 0
    for _ in range(300):
        x = rng.normal(size=3) + [0.0, 0.0, 2.0]
        x /= np.linalg.norm(x)
        rho, r, H = rng.uniform(0.5, 3.0), rng.uniform(0.2, 2.0), rng.uniform(0.0, 10.0)
        c = rng.uniform(-2, 2, 3)
        e1 = np.cross(x, [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(x, e1)
        phi = rng.uniform(0, 2 * np.pi)
        e = math.cos(phi) * e1 + math.sin(phi) * e2  # radial direction
        # on the lower rim, normal cos(psi) e - sin(psi) x, across the line: tan(psi) = e_w / x_w
        psi = math.atan2(e @ w, x @ w)
        if not 0.0 < psi < np.pi / 2:
            continue
        p = c + rho * e + r * (math.cos(psi) * e - math.sin(psi) * x)
        lo, hi = swp.stand(p[0], p[1], *c, *x, H, rho, r, 3)
        if lo <= hi:
            assert abs(lo - p[2]) <= 1e-7 and abs(hi - p[2]) <= 1e-7, (lo, hi, p[2])
            checked += 1
    assert checked > 50


@pytest.mark.parametrize("k", [0, 1, 2])
def test_aligned_sweep_matches_the_bisection_and_the_poses(k):
    """A flat or bull-nose tool whose axis lies along a line-frame axis (3-axis against every dexel
    direction) is cut in closed form per pose: the same interval as the general bisection on the
    distance to the core, and every end is reached by a pose (the ends of dense poses bracket
    it); lines placed exactly on the tool's edges and moves along the axes included."""
    rng = np.random.default_rng(5 + k)
    checked = 0
    for i in range(240):
        sgn = 1.0 if i % 2 else -1.0
        x = np.zeros(3)
        x[k] = sgn
        R, r, H = (3.0, 0.0, 6.0) if i % 3 == 0 else (5.0, 1.0, 6.0) if i % 3 == 1 else (4.0, 2.0, 0.0)
        c = np.round(rng.uniform(-2, 2, 3), 1)
        D = np.round(rng.normal(size=3) * rng.choice([0.0, 0.5, 3.0]), 1)
        if i % 4 == 0:
            D[rng.integers(0, 3)] = 0.0
        u0, v0 = (c[0] + R, c[1]) if i % 7 == 0 else (c[0], c[1] - R + r) if i % 7 == 1 else rng.uniform(-7, 7, 2)
        lo, hi = swp.aligned_sweep(u0, v0, *c, *D, k, sgn, H, R - r, r)
        blo, bhi = swp.rounded_sweep(u0, v0, *c, *D, *x, H, R - r, r)
        if lo > hi or blo > bhi:  # both miss, or one grazes (an interval shorter than 1e-6 mm)
            assert (lo > hi or hi - lo < 1e-6) and (blo > bhi or bhi - blo < 1e-6)
            continue
        # the bisection accepts points 1e-9 mm off the tool: where the line grazes a curved edge
        # its interval is up to sqrt(2 R 1e-9) longer
        assert blo - 1e-7 <= lo <= blo + 2e-4 and bhi - 2e-4 <= hi <= bhi + 1e-7
        s0, s1 = swp.aligned_poses(u0, v0, *c, *D, k, sgn, H, R - r, r)
        ss = np.linspace(s0, s1, 501)
        assert lo <= min(swp.aligned_at(s, u0, v0, *c, *D, k, sgn, H, R - r, r, False) for s in ss) + 1e-12
        assert hi >= -min(swp.aligned_at(s, u0, v0, *c, *D, k, sgn, H, R - r, r, True) for s in ss) - 1e-12
        # both ends lie on the tool at some pose (the reference distance, over 4001 poses)
        tips = c - r * x + np.linspace(0, 1, 4001)[:, None] * D
        for e in (lo, hi):
            gap = tool_gap(np.array([[u0, v0, e]]) - tips, np.zeros(3), x, R, r, H + 2 * r)
            assert gap.min() <= 1e-9 + np.linalg.norm(D) / 4000
        checked += 1
    assert checked > 60


@pytest.mark.parametrize("corner", [0.0, 0.5])
def test_a_flat_or_bull_nose_swept_with_a_fixed_axis_meets_a_line_where_its_poses_do(corner):
    """A flat end mill or a shank (``Disk + Parallelogram``, in closed form) and a bull-nose (the
    same thickened by its corner radius, by bisection on the distance to that core) swept along a
    move with a fixed axis, against a line: both ends lie
    on the tool at some pose, and every point of the line that some pose holds lies between them
    (the reference signed distance of 1001 poses); axes along the line, across it and tilted, moves
    along the axis, none, short and long (whose sides the line may cross between the poses), tools
    of no height, and lines exactly through the rim."""
    rng = np.random.default_rng(11)
    checked = 0
    for i in range(120):
        x = rng.normal(size=3)
        if i % 5 == 0:
            x = np.zeros(3)
            x[rng.integers(0, 3)] = rng.choice([-1.0, 1.0])
        elif i % 5 == 1:
            x[rng.integers(0, 3)] = 0.0
        x /= np.linalg.norm(x)
        R, H = rng.choice([1.0, 3.0, 12.5]), rng.choice([0.0, 2.0, 30.0])
        r = corner * R
        c = np.round(rng.uniform(-2, 2, 3), 1)
        D = np.round(rng.normal(size=3) * rng.choice([0.0, 0.5, 3.0, 12.0]), 1) if i % 7 else rng.uniform(-3, 3) * x
        if i % 3 == 0:  # through the rim of the first pose's bottom
            e = np.cross(x, rng.normal(size=3))
            u0, v0 = (c + (R - r) * e / np.linalg.norm(e))[:2]
        else:
            u0, v0 = c[:2] + rng.uniform(-R - 4, R + 4, 2)
        if r > 0.0:
            lo, hi = swp.rounded_sweep(u0, v0, *c, *D, *x, H, R - r, r)
        else:
            lo, hi = swp.flat_sweep(u0, v0, *c, *D, *x, H, R)
        tips = c - r * x + np.linspace(0, 1, 1001)[:, None] * D
        w = np.linspace(-64, 64, 6401)
        line = np.column_stack([np.full(len(w), u0), np.full(len(w), v0), w])
        held = np.zeros(len(w), bool)
        for tip in tips[::25]:
            held |= tool_gap(line, tip, x, R, r, H + 2 * r) < -1e-6
        if lo > hi:
            assert not held.any(), i
            continue
        assert (w[held] >= lo - 1e-9).all() and (w[held] <= hi + 1e-9).all(), (i, lo, hi)
        for end in (lo, hi):
            gap = tool_gap(np.array([[u0, v0, end]]) - tips, np.zeros(3), x, R, r, H + 2 * r)
            assert -1e-9 <= gap.min() <= 2e-9 + np.linalg.norm(D) / 2000, (i, end, gap.min())  # on the surface
        checked += 1
    assert checked > 40


def slot_removed(tool, depth, step=0.1):
    d = dexelize(box((0, 0, 0), (40, 20, 10)), step)
    tip = np.array([[-10, 10, 10 - depth], [50, 10, 10 - depth]], float)
    tp = Toolpath(tip, np.tile([0, 0, 1.0], (2, 1)), np.zeros(2, bool), np.zeros(2, int))
    st = stock_from_model(d)
    cut(st, toolpath_moves(tp, [tool]))
    return d.volume - st.to_model().volume


def test_slots_remove_the_analytic_volume():
    R, h = 3.0, 2.0
    ball = R * R * math.acos((R - h) / R) - (R - h) * math.sqrt(2 * R * h - h * h)
    assert slot_removed(BALL, h) == pytest.approx(40 * ball, rel=0.01)
    assert slot_removed(FLAT, h) == pytest.approx(40 * 2 * R * h, rel=0.01)
    r = 1.0
    bull = 2 * R * (h - r) + 2 * (R - r) * r + math.pi * r * r / 2
    assert slot_removed(BULL, h) == pytest.approx(40 * bull, rel=0.01)


def test_points_mode_cuts_only_at_the_points():
    d = dexelize(box((0, 0, 0), (40, 20, 10)), 0.2)
    tip = np.array([[0, 10, 8.0], [20, 10, 8.0], [40, 10, 8.0]])
    tp = Toolpath(tip, np.tile([0, 0, 1.0], (3, 1)), np.zeros(3, bool), np.zeros(3, int))
    removed = {}
    for mode in ("sweep", "points"):
        st = stock_from_model(d)
        cut(st, toolpath_moves(tp, [BALL], mode))
        removed[mode] = d.volume - st.to_model().volume
    cap = math.pi * 2 ** 2 * (3 * 3 - 2) / 3  # spherical cap of height 2
    assert removed["points"] == pytest.approx(cap * 2, rel=0.01)  # half, whole, half a cap
    assert removed["sweep"] > 5 * removed["points"]


def grid_positions(model, axis):
    return model.lo[axis] + (np.arange(model.n[axis]) + 0.5) * model.step


def test_parallel_passes_leave_the_scallop_height(tmp_path):
    """Ball passes along X, stepover s on a plane: Sp is the scallop h = R - sqrt(R^2 - s^2/4)."""
    design = box((0, 0, 0), (10, 10, 5))
    stock = box((0, 0, 0), (10, 10, 6))
    step, R, s = 0.05, 3.0, 1.5
    ref = dexelize(design, step, bounds=np.array([[0, 0, 0], [10, 10, 6]]))
    cusp = grid_positions(ref, 1)[np.argmin(np.abs(grid_positions(ref, 1) - 5.0))]  # a Z line on a cusp
    ys = cusp + s / 2 + s * np.arange(-6, 6)
    pts = []
    for k, y in enumerate(ys):
        xs = (-5.0, 15.0) if k % 2 == 0 else (15.0, -5.0)
        pts += [(xs[0], y, 5.0), (xs[1], y, 5.0)]
    pts = np.array([(-5.0, ys[0], 9.0)] + pts + [(pts[-1][0], ys[-1], 9.0)])
    rapid = np.zeros(len(pts), bool)
    rapid[[1, -1]] = True
    tp = Toolpath(pts, np.tile([0, 0, 1.0], (len(pts), 1)), rapid, np.zeros(len(pts), int))
    dev, summary, machined, (v, f), _, _ = simulate(design, tp, [BALL], step, stock=stock, tolerance=0.01)
    h = R - math.sqrt(R * R - s * s / 4)
    assert dev["Sp"] == pytest.approx(h, rel=0.05)
    assert dev["gouge_max"] < 1e-6 and summary["rapid_moves_cutting"] == 0
    assert dev["removed_volume"] == pytest.approx(100.0 - dev["remaining_volume"], rel=0.01)
    assert trimesh.Trimesh(v, f).is_watertight


def _dip(design, step, depth):
    """A ball pass along the middle of a 40 x 20 x 10 box's top that dips ``depth`` on a grid line
    at its centre: the path and the dip's place."""
    ref = dexelize(design, step)
    x0 = grid_positions(ref, 0)[np.argmin(np.abs(grid_positions(ref, 0) - 20.0))]
    y0 = grid_positions(ref, 1)[np.argmin(np.abs(grid_positions(ref, 1) - 10.0))]
    pts = np.array([[-5, y0, 10.0], [x0, y0, 10.0 - depth], [45, y0, 10.0]])
    return Toolpath(pts, np.tile([0, 0, 1.0], (3, 1)), np.zeros(3, bool), np.zeros(3, int)), (x0, y0)


def test_a_dip_into_the_design_is_reported_where_it_is():
    design = box((0, 0, 0), (40, 20, 10))
    step = 0.1
    tp, (x0, y0) = _dip(design, step, 0.2)
    dev, *_ = simulate(design, tp, [BALL], step, stock=Stock.offset(0.5))
    assert dev["gouge_max"] == pytest.approx(0.2, abs=2e-3)
    np.testing.assert_allclose(dev["gouge_at"], [x0, y0, 9.8], atol=step)
    assert dev["excess_max"] == pytest.approx(0.5, abs=1e-6)  # the allowance left elsewhere


def test_a_stock_short_of_the_design_is_not_a_gouge_of_the_path():
    # a stock mesh 0.2 mm short of the design's top (as a machined.stl whose marching cubes cut a
    # corner), and a path that dips 0.3 mm into one place of the top: only that is the path's
    design = box((0, 0, 0), (40, 20, 10))
    stock = box((-1, -1, -1), (41, 21, 9.8))
    step = 0.1
    tp, (x0, y0) = _dip(design, step, 0.3)
    dev, summary, *_ = simulate(design, tp, [BALL], step, stock=stock)
    assert dev["gouge_max"] == pytest.approx(0.3, abs=2e-3)  # the dip, not the stock's shortfall
    np.testing.assert_allclose(dev["gouge_at"], [x0, y0, 9.7], atol=step)
    assert dev["stock_short_max"] == pytest.approx(0.2, abs=1e-6) and dev["stock_short_ends"] > 1000
    assert dev["Sv"] == pytest.approx(0.3, abs=2e-3)
    assert any("short of the design" in w for w in summary["warnings"])
    nothing = Toolpath(np.array([[-5, 10, 20.0], [45, 10, 20.0]]), np.tile([0, 0, 1.0], (2, 1)), np.ones(2, bool),
                       np.zeros(2, int))
    dev, summary, *_ = simulate(design, nothing, [BALL], step, stock=stock)
    assert dev["gouge_max"] == 0.0 and dev["gouged_volume"] == pytest.approx(0.0, abs=1e-6)


def test_rapid_move_through_material_is_reported():
    design = box((0, 0, 0), (20, 20, 10))
    pts = np.array([[-5, 10, 20.0], [-5, 10, 5.0], [25, 10, 5.0]])
    tp = Toolpath(pts, np.tile([0, 0, 1.0], (3, 1)), np.array([True, True, True]), np.zeros(3, int))
    _, summary, *_ = simulate(design, tp, [BALL], 0.25)
    assert summary["rapid_cutting_points"] == [2]


def test_cutting_length_in_air_and_in_material():
    """A feed pass over the stock, a plunge beside it and a pass through its top: the first two cut
    air, the last material (each move counts whole: it removes material or it does not)."""
    design = box((0, 0, 0), (20, 20, 10))
    stock = box((-1, -1, -1), (21, 21, 12))
    pts = np.array([[-5, 10, 20.0], [25, 10, 20.0], [25, 10, 11.0], [-5, 10, 11.0]])
    tp = Toolpath(pts, np.tile([0, 0, 1.0], (4, 1)), np.array([True, False, False, False]), np.zeros(4, int))
    _, summary, *_ = simulate(design, tp, [BALL], 0.25, stock=stock)
    c = summary["cutting_mm"]
    assert c["in_air"] == pytest.approx(39.0) and c["in_material"] == pytest.approx(30.0)
    assert c["air_share"] == pytest.approx(39.0 / 69.0) and summary["rapid_moves_cutting"] == 0


def test_five_axis_turning_tool_cuts_a_block():
    """A ball tool tilting from vertical to 30 degrees along one move removes what the same motion
    cut as 3000 short moves removes."""
    d = dexelize(box((0, 0, 0), (30, 20, 10)), 0.1)
    n = 2
    tips = np.array([[0.0, 10, 8.5], [30.0, 10, 8.5]])
    ang = np.radians([0.0, 30.0])
    axes = np.column_stack([np.sin(ang), np.zeros(n), np.cos(ang)])
    tp = Toolpath(tips, axes, np.zeros(n, bool), np.zeros(n, int))
    st = stock_from_model(d)
    moves = toolpath_moves(tp, [BALL])
    assert len(moves) > 10  # split where the axis turns
    cut(st, moves)
    swept = d.volume - st.to_model().volume
    t = np.linspace(0, 1, 3001)
    x = np.column_stack([(1 - t) * axes[0, 0] + t * axes[1, 0], np.zeros_like(t), (1 - t) * axes[0, 2] + t * axes[1, 2]])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    dense = Toolpath(tips[0] + t[:, None] * (tips[1] - tips[0]), x, np.zeros(len(t), bool), np.zeros(len(t), int))
    st2 = stock_from_model(d)
    cut(st2, toolpath_moves(dense, [BALL]))
    assert swept == pytest.approx(d.volume - st2.to_model().volume, rel=1e-3)


def test_the_cut_does_not_depend_on_combs_of_rows_or_on_lines_running_out_of_room(monkeypatch):
    """A few tiles are cut in combs of rows over the threads, and a line that runs out of room is
    grown and cut again alone: the stock, the hits and the loads are those of whole tiles with
    room to spare."""
    from meshmill.kernels import cpu_dexel
    from meshmill.simulation import cut as cutting

    d = dexelize(box((0, 0, 0), (30, 20, 10)), 0.25)
    tips = np.array([[0.0, 10, 8.5], [30.0, 10, 8.5], [30.0, 4, 7.0], [0.0, 16, 9.5], [15.0, 10, 6.0]])
    ang = np.radians([0.0, 30.0, 10.0, 0.0, 20.0])
    axes = np.column_stack([np.sin(ang), np.zeros(5), np.cos(ang)])
    tp = Toolpath(tips, axes, np.array([True, False, False, False, False]), np.zeros(5, int))
    moves = toolpath_moves(tp, [BALL])
    runs = []
    for spread, slack in ((0, 2), (10 ** 6, 2), (0, 0), (10 ** 6, 0)):
        monkeypatch.setattr(cpu_dexel, "SPREAD", spread)  # 0: whole tiles; huge: combs of single rows
        monkeypatch.setattr(cutting, "SLACK", slack)  # 0: every line that gains an interval overflows
        st = stock_from_model(d)
        res = cut(st, moves, load=len(tp))
        runs.append((st.to_model(), res))
    (m0, r0) = runs[0]
    for m, r in runs[1:]:
        assert r["in_material"].tolist() == r0["in_material"].tolist() and r["rapid_cuts"] == r0["rapid_cuts"]
        assert np.allclose(r["load"].volume, r0["load"].volume, rtol=1e-12, atol=1e-12)
        for k in range(3):
            assert np.array_equal(m.start[k], m0.start[k]) and np.array_equal(m.iv[k], m0.iv[k]), k
    assert sum(len(v) for v in m0.iv) > sum(len(v) for v in d.iv)  # the moves split dexels: lines grew


def test_machined_mesh_is_watertight_and_keeps_the_volume():
    d = dexelize(box((0, 0, 0), (20, 10, 10)), 0.2)
    pts = np.array([[-5, 5, 7.0], [25, 5, 7.0]])
    tp = Toolpath(pts, np.tile([0, 0, 1.0], (2, 1)), np.zeros(2, bool), np.zeros(2, int))
    st = stock_from_model(d)
    cut(st, toolpath_moves(tp, [BALL]))
    m = st.to_model()
    v, f, stride = machined_mesh(m)
    tm = trimesh.Trimesh(v, f)
    assert stride == 1 and tm.is_watertight and tm.volume == pytest.approx(m.volume, rel=0.01)


def test_simulate_command(tmp_path, capsys):
    b = box((0, 0, 0), (30, 20, 10))
    trimesh.Trimesh(b.vertices, b.faces).export(tmp_path / "part.stl")
    (tmp_path / "tools.toml").write_text('[[tools]]\nname="B6"\ntype="ball"\ndiameter=6\nflute_length=12\n'
                                         'gauge_length=40\n')
    (tmp_path / "p.cl").write_text("CUTTER/6, 3\nRAPID\nGOTO/-5, 10, 20\nGOTO/-5, 10, 9\nGOTO/35, 10, 9\nFINI\n")
    (tmp_path / "p.nc").write_text("T1 M6\nG0 X-5 Y10 Z20\nG1 Z9\nG1 X35\nM30\n")
    for path in ("p.cl", "p.nc"):
        out = tmp_path / ("sim_" + path)
        rc = main(["simulate", "--design", str(tmp_path / "part.stl"), "--toolpath", str(tmp_path / path),
                   "--tools", str(tmp_path / "tools.toml"), "--step", "0.25", "--allowance", "1", "--out", str(out),
                   "--quiet"])
        assert rc == 0
        dev = json.loads((out / "deviation.json").read_text())
        assert set(["Sa", "Sq", "Sp", "Sv", "Sz", "gouge_max", "excess_max", "within_tolerance", "removed_volume",
                    "remaining_volume"]) <= set(dev)
        assert dev["gouge_max"] == pytest.approx(1.0, abs=0.01)
        assert trimesh.load(out / "machined.stl").is_watertight
    bad = [
        (["--toolpath", str(tmp_path / "missing.cl")], "no such CL file"),
        (["--toolpath", str(tmp_path / "tools.toml")], "unknown tool-path format"),
        (["--toolpath", str(tmp_path / "p.cl"), "--step", "-1"], "--step"),
        (["--toolpath", str(tmp_path / "p.cl"), "--allowance", "nan"], "--allowance"),
    ]
    for extra, message in bad:
        argv = ["simulate", "--design", str(tmp_path / "part.stl"), "--tools", str(tmp_path / "tools.toml"),
                "--step", "0.5", "--out", str(tmp_path / "x")] + extra
        capsys.readouterr()
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and message in err[0]
    # a path in inches against a part in mm never reaches the stock
    (tmp_path / "far.cl").write_text("CUTTER/6, 3\nGOTO/500, 500, 500\nGOTO/600, 500, 500\nFINI\n")
    capsys.readouterr()
    assert main(["simulate", "--design", str(tmp_path / "part.stl"), "--toolpath", str(tmp_path / "far.cl"),
                 "--tools", str(tmp_path / "tools.toml"), "--step", "0.5", "--out", str(tmp_path / "y")]) == 2
    assert "never reaches the stock" in capsys.readouterr().err


def test_dexel_command(tmp_path, capsys):
    b = box((0, 0, 0), (3, 2, 1))
    trimesh.Trimesh(b.vertices, b.faces).export(tmp_path / "b.stl")
    assert main(["dexel", str(tmp_path / "b.stl"), "--step", "0.25", "--index", "kmeans", "--partitions", "3",
                 "--out", str(tmp_path / "o" / "b.npz"), "--quiet"]) == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["volume_mm3"] == pytest.approx(6.0) and s["index"]["partitions"] == 3
    assert main(["dexel", str(tmp_path / "b.stl"), "--step", "0.25", "--out", str(tmp_path / "b.td"), "--quiet"]) == 0
    assert (tmp_path / "b.td").read_text().startswith("# TD v1")
    open_box = trimesh.Trimesh(b.vertices, b.faces[:-1])
    open_box.export(tmp_path / "open.stl")
    capsys.readouterr()  # an open box: the solid it bounds, closed across its hole
    assert main(["dexel", str(tmp_path / "open.stl"), "--step", "0.25", "--out", str(tmp_path / "open.npz")]) == 0
    assert "open" in capsys.readouterr().err and json.loads((tmp_path / "summary.json").read_text())[
        "volume_mm3"] == pytest.approx(6.0)
    assert main(["dexel", str(tmp_path / "b.stl"), "--step", "0"]) == 2
    from meshmill.kernels.backend import cuda_available

    if not cuda_available():  # no GPU: auto runs on the CPU, cuda is one clear line
        assert main(["dexel", str(tmp_path / "b.stl"), "--step", "0.5", "--out", str(tmp_path / "c.npz"),
                     "--quiet"]) == 0
        assert json.loads((tmp_path / "summary.json").read_text())["index"]["device"] == "cpu"
        capsys.readouterr()
        assert main(["dexel", str(tmp_path / "b.stl"), "--step", "0.5", "--device", "cuda"]) == 2
        assert "no usable CUDA GPU" in capsys.readouterr().err


@pytest.mark.slow
def test_ball_fast_path_cuts_what_the_whole_tool_cuts():
    """Ball-end moves are cut with the ball alone unless material lies where only the flutes
    reach: on random lines with random material, both give the same material left."""
    from meshmill.kernels.cpu_dexel import material_outside

    rng = np.random.default_rng(11)
    R, F = 3.0, 12.0
    checked = 0
    for _ in range(400):
        pa = rng.uniform(-2, 2, 3)
        pb = pa + rng.normal(size=3) * rng.choice([0.0, 0.5, 3.0])
        xa = rng.normal(size=3)
        xa /= np.linalg.norm(xa)
        xb = xa if rng.random() < 0.5 else xa + 0.01 * rng.normal(size=3)
        xb = xb / np.linalg.norm(xb)
        u0, v0 = rng.uniform(-4, 4, 2)
        lo, hi = swp.tool_move(u0, v0, pa, pb, xa, xb, R, R, F, 3)
        blo, bhi = swp.capsule(u0, v0, *(pa + R * xa), *(pb + R * xb), R)
        flo, fhi = swp.flute_range(u0, v0, *swp.flute_plane(pa, pb, xa, xb, R, F))
        ends = np.sort(rng.uniform(-20, 20, 2 * rng.integers(1, 4)))
        iv = ends.reshape(-1, 2)
        if not material_outside(iv, 0, len(iv), max(flo, -30.0), min(fhi, 30.0), blo, bhi):
            full = [(max(s, -30), min(e, lo)) for s, e in iv] + [(max(s, hi), e) for s, e in iv]
            fast = [(max(s, -30), min(e, blo)) for s, e in iv] + [(max(s, bhi), e) for s, e in iv]
            left = lambda parts: sum(max(0.0, e - s) for s, e in parts)  # noqa: E731
            if lo <= hi:
                assert left(fast) == pytest.approx(left(full), abs=1e-9)
            checked += 1
    assert checked > 100


def test_subtract_cases_and_growing_room():
    from meshmill.kernels.cpu_dexel import subtract
    from meshmill.simulation.cut import _grow

    def run(intervals, lo, hi, room=4):
        iv = np.zeros((room, 2))
        iv[:len(intervals)] = intervals
        count = np.array([len(intervals)])
        removed = subtract(iv, np.array([0, room]), count, 0, lo, hi)
        return removed, iv[:count[0]].tolist()

    assert run([[0, 10]], 12, 15) == (0.0, [[0, 10]])  # miss
    assert run([[0, 10]], -1, 11) == (10.0, [])  # whole
    assert run([[0, 10]], 8, 12) == (2.0, [[0, 8]])  # end
    assert run([[0, 10]], -2, 3) == (3.0, [[3, 10]])  # start
    assert run([[0, 10]], 4, 6) == (2.0, [[0, 4], [6, 10]])  # split
    assert run([[0, 2], [3, 5], [6, 9]], 1, 7) == (4.0, [[0, 1], [7, 9]])  # across three
    assert run([[0, 10]], 4, 6, room=1) == (-1.0, [[0, 10]])  # no room: unchanged
    st = stock_from_model(dexelize(box((0, 0, 0), (2, 2, 2)), 0.5))
    before = st.to_model()
    full = np.nonzero(st.count[2])[0]
    room = np.diff(st.off[2])[full]
    _grow(st, 2, full)
    assert (room >= 1 + 2).all() and (np.diff(st.off[2])[full] == 2 * room).all()
    np.testing.assert_array_equal(st.to_model().iv[2], before.iv[2])


@pytest.mark.slow
def test_review_cases_turning_flat_empty_stock_and_bad_axes():
    # a flat cutter whose axis turns by 1e-6 rad along a long move cuts the whole slot
    d = dexelize(box((0, 0, 0), (40, 20, 10)), 0.2)
    tip = np.array([[-10, 10, 8.0], [50, 10, 8.0]])
    for axes in (np.array([[0, 0, 1.0], [0, 0, 1.0]]), np.array([[0, 0, 1.0], [1e-6, 0, 1.0]]),
                 np.array([[0, 0, 1.0], [1e-3, 0, 1.0]])):
        axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
        st = stock_from_model(d)
        cut(st, toolpath_moves(Toolpath(tip, axes, np.zeros(2, bool), np.zeros(2, int)), [FLAT]))
        removed = d.volumes() - st.to_model().volumes()
        assert removed[2] == pytest.approx(40 * 6 * 2, rel=0.01)
    # a path that removes the whole design reports it as gouged, without a traceback
    design = box((0, 0, 0), (10, 10, 5))
    big = Tool("F40", "flat", 40.0, 0.0, 30.0, 60.0, 40.0)
    tp = Toolpath(np.array([[-30, 5, -1.0], [40, 5, -1.0]]), np.tile([0, 0, 1.0], (2, 1)), np.zeros(2, bool),
                  np.zeros(2, int))
    dev, summary, *_ = simulate(design, tp, [big], 0.5)
    assert summary["volumes_mm3"]["machined"] == 0 and dev["samples"] == 0
    assert summary["volumes_mm3"]["gouged"] == pytest.approx(500.0) and dev["cut_away_depth_max"] >= 5.0
    assert dev["design_ends_cut_away"] > 0 and any("cut away" in w for w in summary["warnings"])
    # opposite axes in one move: a clear error
    tp = Toolpath(np.array([[0, 0, 20.0], [1, 0, 20.0]]), np.array([[1, 0, 0.0], [-1, 0, 0.0]]), np.zeros(2, bool),
                  np.zeros(2, int))
    with pytest.raises(Exception, match="turns by 180"):
        toolpath_moves(tp, [BALL])


def test_an_open_surface_is_simulated_as_the_solid_below_it(tools):
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.ops.raster import RasterParams, raster
    from meshmill.toolpath.model import Toolpath

    # a wavy open sheet (a terrain), no solid of its own: raster it, then cut the path from the
    # sheet with 0.5 mm on it
    x, y = np.meshgrid(np.linspace(0, 30, 31), np.linspace(0, 20, 21), indexing="ij")
    z = 5 + 2 * np.sin(x / 5) * np.cos(y / 5)
    v = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    i = np.arange(30)[:, None] * 21 + np.arange(20)[None, :]
    f = np.concatenate([np.stack([i, i + 21, i + 22], -1).reshape(-1, 3), np.stack([i, i + 22, i + 1], -1).reshape(-1, 3)])
    sheet = mesh_from_arrays(v, f, "terrain")
    assert not sheet.closed
    tp, s = raster(sheet, tools, "B6", RasterParams(stepover=1.0, sample=0.5))
    assert s["verify"]["ok"]
    dev, sim, *_ = simulate(sheet, tp, tools, 0.5, stock=Stock.offset(0.5))
    assert dev["gouge_max"] <= 0.0101 and sim["colliding_moves"] == 0 and sim["rapid_moves_cutting"] == 0
    # the material is there: the same path 0.2 mm lower gouges it by that much
    low = Toolpath(tp.tip - np.where(tp.rapid, 0.0, 0.2)[:, None] * [0, 0, 1], tp.axis, tp.rapid, tp.tool)
    dev, *_ = simulate(sheet, low, tools, 0.5, stock=Stock.offset(0.5))
    assert dev["gouge_max"] == pytest.approx(0.2, abs=0.012)


@given(st.lists(st.floats(-1e12, 1e12, allow_nan=False).filter(lambda x: x == 0 or abs(x) > 1e-300), max_size=60),
       st.integers(1, 7))
def test_exact_sums_do_not_depend_on_the_grouping(values, size):
    x = np.array(values, float)
    groups = [expansion(x[i:i + size]) for i in range(0, len(x), size)]
    assert total(*groups) == total(expansion(x)) == math.fsum(values)


def test_blocks_of_lines_measure_and_mesh_as_the_whole_model():
    """What a cluster's workers compute per block of lines, joined, is the whole model's: the
    deviation figures, the cut-away depths, the mesh's field and its snapped vertices (split at
    rows that need not be tiles)."""
    from meshmill.geometry.shapes import post_with_fillet, sphere
    from meshmill.kernels.backend import MeshKernels
    from meshmill.kernels.bvh import build_bvh
    from meshmill.simulation.deviation import join_measures, measure_lines, nearest_end
    from meshmill.simulation.surface import empty_field, field_rows, field_surface, snap_lines

    design = post_with_fillet(segments=32)
    bounds = design.bounds + np.array([[-2.0], [2.0]])
    step = 0.9
    dm = dexelize(design, step, bounds=bounds)
    stock = dexelize(box(design.bounds[0] - 1.0, design.bounds[1] + 1.0), step, bounds=bounds)
    machined = dexelize(sphere(30.0, center=(6.0, 0.0, -5.0)), step, bounds=bounds)  # gouges and leaves excess
    kern = MeshKernels(build_bvh(design.vertices, design.faces), "cpu")
    lo, n = dm.lo, dm.n

    def rows(m, a, i0, i1):
        nv = int(n[(a + 2) % 3])
        s = m.start[a][i0 * nv:i1 * nv + 1]
        return s - s[0], m.iv[a][s[0]:s[-1]]

    def measured(cuts):
        parts, blocks = [], []
        for a in range(3):
            edges = [0, *cuts, int(n[(a + 1) % 3])]
            for i0, i1 in zip(edges[:-1], edges[1:]):
                blocks.append((a, i0, i1))
                parts.append(measure_lines(lo, n, step, a, i0, rows(machined, a, i0, i1), rows(stock, a, i0, i1),
                                           rows(dm, a, i0, i1), kern, 0.05))
        away, depth = (np.concatenate([p[k] for p in parts]) for k in ("away_points", "away_depth"))
        near = np.min([nearest_end(lo, n, step, a, i0, rows(machined, a, i0, i1), away, depth)
                       for a, i0, i1 in blocks], axis=0)
        return join_measures(parts, near, step), parts

    whole, wp = measured([])
    split, sp = measured([1, 7, 8, 30])
    # the depth bounds against every machined end's distance (no pruning by rows or bounds)
    from scipy.spatial import cKDTree

    from meshmill.simulation.deviation import end_points

    ends = np.concatenate([end_points(lo, n, step, a, machined.start[a], machined.iv[a]) for a in range(3)])
    line_depth = np.concatenate([p["away_depth"] for p in wp])
    brute = np.minimum(line_depth, cKDTree(ends).query(whole["away_points"])[0])
    assert np.array_equal(whole["away_depth"], brute) and (brute < line_depth).any()
    assert whole["samples"] and len(whole["away_depth"]) and whole["gouge_max"] > 0 and whole["excess_max"] > 0
    for k, v in whole.items():
        assert np.array_equal(v, split[k]) if isinstance(v, np.ndarray) else v == split[k], k
    assert np.array_equal(np.concatenate([p["e"] for p in wp]), np.concatenate([p["e"] for p in sp]))

    field = empty_field(n, step)
    for i0, i1 in ((0, 5), (5, 6), (6, int(n[0]))):
        a0, slab = field_rows(lo, n, step, *rows(machined, 2, i0, i1), i0, i1)
        field[a0 + 1:a0 + 1 + len(slab)] = slab
    verts, faces = field_surface(field, lo, step, n)
    whole_v, whole_f, _ = machined_mesh(machined)
    for a in (0, 1):
        for i0, i1 in ((0, 9), (9, int(n[(a + 1) % 3]))):
            idx, w = snap_lines(verts, lo, n, step, a, *rows(machined, a, i0, i1), i0)
            verts[idx, a] = w
    assert np.array_equal(verts, whole_v) and len(faces) == len(whole_f)


def _turning_move(rng, max_turn):
    """A random move: tips ``pa, pb`` (still, short or long) and unit axes ``xa, xb`` near +Z, the
    second turned from the first by up to ``max_turn`` rad about a random direction."""
    pa = rng.uniform(-3, 3, 3)
    pb = pa + rng.normal(size=3) * rng.choice([0.0, 0.5, 3.0])
    xa = rng.normal(size=3) + [0.0, 0.0, 2.0]
    xa /= np.linalg.norm(xa)
    k = np.cross(xa, rng.normal(size=3))
    k /= np.linalg.norm(k)
    turn = rng.uniform(0.0, max_turn)
    return pa, pb, xa, xa * math.cos(turn) + k * math.sin(turn)


def test_the_search_over_poses_keeps_the_side_where_they_meet_the_line():
    """A turning flat end whose poses meet the line only near the end of the move: the search
    keeps that side when neither of its inner poses meets the line (it dropped it: 8.5e-3 mm
    short), against 20 001 poses."""
    u0, v0 = -7.5099953442920935, -4.518850807074838
    pa = np.array([0.5227418980606336, -2.1561971701336424, -0.12300733668968067])
    pb = np.array([0.5593924289308024, -2.0327324665080955, -0.4777064253669372])
    xa = np.array([-0.3664659225362628, -0.20658644653853087, 0.9072071250415907])
    xb = np.array([-0.36377842278623934, -0.1884806956712764, 0.9122172364488778])
    R, F = 2.1070545924563864, 16.99782466826192
    lo, hi = swp.tool_move(u0, v0, pa, pb, xa, xb, R, 0.0, F, 1)
    best = -math.inf
    for t in np.linspace(0.0, 1.0, 20001):
        x = xa + t * (xb - xa)
        x /= np.linalg.norm(x)
        a, b = swp.pose_at(u0, v0, pa, pb, xa, xb, t, R, 0.0, F, 2)
        if a <= b:
            best = max(best, b)
    assert best > 14.43 and hi >= best - 1e-6


def test_a_turning_flat_or_bull_nose_cuts_what_its_exact_sweep_holds():
    """A flat end or bull-nose cutting a line, its axis turning or fixed: the closed-form bounds that
    spare the search over its poses or the exact fixed sweep (balls about its axis swept along the
    move at the first axis, grown by what the turn moves, above the first tip's plane lowered by
    what the move and turn take the tool below it) and the poses at the ends that spare it where no
    material lies beyond them never hide material its exact sweep holds: the length removed is the
    exact sweep's, on lines through material in random pieces near the tool's top and its tip."""
    from meshmill.kernels.cpu_dexel import crv

    rng = np.random.default_rng(5)
    checked = cut_some = 0
    for case in range(400):
        R, F = rng.uniform(1.0, 8.0), rng.uniform(8.0, 60.0)
        cm = R * rng.choice([0.0, 0.25, 0.5])  # flat or bull-nose
        pa, pb, xa, xb = _turning_move(rng, 0.3)
        if case % 3 == 0:  # a fixed axis, some along the line
            xb = xa = np.array([0.0, 0.0, 1.0]) if case % 9 == 0 else xa
        # lines near the tool's top at the end of the move, where the turn moves it the most, or
        # near its tip, where the tip's plane bounds it
        near = pb + (F - cm) * xb if case % 2 else (pa if case % 4 == 0 else pb)
        u0, v0 = near[:2] + rng.uniform(-R - 2, R + 2, 2)
        ends = np.sort(rng.uniform(-60, 60, 2 * rng.integers(1, 4)))
        iv = np.zeros((8, 2))
        iv[:len(ends) // 2] = ends.reshape(-1, 2)
        off, count = np.array([0, 8]), np.array([len(ends) // 2])
        chord = np.concatenate([pa + cm * xa, pb + cm * xb])[None]
        arrays = [a[None] for a in (pa, pb, xa, xb)] + [np.array([R]), np.array([cm]), np.array([F]),
                                                         np.array([1], np.int64), chord, np.zeros((1, 4))]
        before = iv[:count[0]].copy()
        got, _, _ = crv.cut_line(0, 0, u0, v0, -100.0, 100.0, iv, off, count, *arrays, False)
        lo, hi = swp.tool_move(u0, v0, pa, pb, xa, xb, R, cm, F, 1)
        exact = sum(max(0.0, min(b, hi) - max(a, lo)) for a, b in before) if lo < hi else 0.0
        assert got == pytest.approx(exact, abs=1e-8), (case, got, exact)  # two methods, each to 1e-9
        checked += 1
        cut_some += exact > 0
    assert cut_some > 50 and checked - cut_some > 50  # both kinds of lines were tried


def test_a_turning_shank_is_found_in_material_wherever_its_exact_sweep_is():
    """A turning cylinder (a shank or holder: flat, on its tip) against a line: the closed-form
    bound that spares the search over its poses (the cylinder held at its middle axis, grown by
    what half the turn moves) never hides material its exact sweep holds: the longest piece found
    is the exact sweep's, on lines through material in random pieces."""
    from meshmill.kernels.cpu_dexel import crv

    rng = np.random.default_rng(3)
    checked = found = 0
    for _ in range(400):
        R, F = rng.uniform(2.0, 16.0), rng.uniform(10.0, 40.0)
        pa, pb, xa, xb = _turning_move(rng, 0.2)
        # one line along w at (u0, v0) near the cylinder, material in a few random pieces
        u0, v0 = pa[:2] + rng.uniform(-R - 8, R + 8, 2)
        ends = np.sort(rng.uniform(-60, 60, 2 * rng.integers(1, 4)))
        iv = ends.reshape(-1, 2).copy()
        off, count = np.array([0, len(iv)]), np.array([len(iv)])
        arrays = [a[None] for a in (pa, pb, xa, xb)] + [np.array([R]), np.array([0.0]), np.array([F]),
                                                         np.array([1], np.int64)]
        got = crv.touch_line(0, 0, u0, v0, -100.0, 100.0, iv, off, count, *arrays)
        lo, hi = swp.tool_move(u0, v0, pa, pb, xa, xb, R, 0.0, F, 1)
        exact = max([0.0] + [min(b, hi) - max(a, lo) for a, b in iv]) if lo < hi else 0.0
        assert got == pytest.approx(exact, abs=1e-12), (got, exact)
        checked += 1
        found += exact > 0
    assert found > 50 and checked - found > 50  # both kinds of lines were tried


def test_a_turning_shank_is_found_by_the_far_rim_of_its_first_pose():
    """The bound a turning cylinder is first tested with (held at the middle axis, grown by what
    half the turn moves its points) holds its first pose's rim on the side the axis turns away
    from, where the turn moves it out of that cylinder the most: material in 2e-4 mm of a line
    just inside that rim is met (with half the growth it was not)."""
    from meshmill.kernels.cpu_dexel import crv

    R, F = 5.0, 40.0
    for turn in (0.05, 0.2):
        for k in range(8):
            phi = 2 * math.pi * k / 8  # the direction the axis turns in, about the still tip
            side = np.array([math.cos(phi), math.sin(phi), 0.0])
            xa = math.cos(turn / 2) * np.array([0.0, 0.0, 1.0]) - math.sin(turn / 2) * side
            xb = math.cos(turn / 2) * np.array([0.0, 0.0, 1.0]) + math.sin(turn / 2) * side
            out = -side - (-side @ xa) * xa  # across xa, away from the middle axis
            p = 1e-3 * xa + (F - 2e-3) * xa + (R - 1e-3) * out / np.linalg.norm(out)
            iv = np.array([[p[2] - 1e-4, p[2] + 1e-4]])
            arrays = [a[None] for a in (np.zeros(3), np.zeros(3), xa, xb)] + [
                np.array([R]), np.array([0.0]), np.array([F]), np.array([1], np.int64)]
            got = crv.touch_line(0, 0, p[0], p[1], -100.0, 100.0, iv, np.array([0, 1]), np.array([1]), *arrays)
            assert got == pytest.approx(2e-4, abs=1e-12), (turn, k, got)


def _wavy_path(rng, n, tool_of):
    """A 5-axis path of ``n`` points winding over a 30 x 20 x 10 mm box: the tip on a wave, the
    axis tilting and swinging by up to 40 degrees (pieces of moves turn), a rapid now and then."""
    t = np.linspace(0.0, 1.0, n)
    tips = np.column_stack([2 + 26 * t, 10 + 6 * np.sin(9 * t + rng.uniform(0, 6)), 7.5 + 2 * np.cos(13 * t)])
    tips += rng.normal(scale=0.05, size=tips.shape)
    tilt = np.radians(40) * np.sin(5 * t + rng.uniform(0, 6)) ** 2
    swing = 7 * t + rng.uniform(0, 6)
    axes = np.column_stack([np.sin(tilt) * np.cos(swing), np.sin(tilt) * np.sin(swing), np.cos(tilt)])
    return Toolpath(tips, axes, rng.random(n) < 0.05, tool_of)


def _point_to_pgram(p, c, D, E):
    """Distance (mm) from points ``p (k, 3)`` to the parallelogram ``c + s D + h E``, s, h in [0, 1]."""
    n = np.cross(D, E)
    if np.linalg.norm(n) < 1e-12:  # degenerate: the distance to its outline
        segs = [(c, D), (c, E), (c + D, E), (c + E, D)]
    else:
        M = np.column_stack([D, E, n / np.linalg.norm(n)])
        s, h, z = np.linalg.solve(M, (p - c).T)
        inside = (s >= 0) & (s <= 1) & (h >= 0) & (h <= 1)
        segs = [(c, D), (c, E), (c + D, E), (c + E, D)]
    out = np.full(len(p), np.inf)
    for a, d in segs:
        dd = max(d @ d, 1e-300)
        f = np.clip((p - a) @ d / dd, 0, 1)
        out = np.minimum(out, np.linalg.norm(p - a - f[:, None] * d, axis=1))
    if np.linalg.norm(n) >= 1e-12:
        out = np.where(inside, np.abs(z), out)
    return out


def test_a_group_of_moves_bounds_every_pose_of_its_moves():
    """A group of consecutive moves (``move_groups``) is skipped on a line with no material in its
    bound: every point of every member's tool axis, at 41 poses a move (the tip interpolated, the
    axis by the normalised interpolation), lies within the bound's growth (less the sweep's
    tolerance) of its parallelogram; its box holds its members'."""
    from meshmill.simulation import cut as cutting

    rng = np.random.default_rng(7)
    tested, groups = 0, {}
    for tools in ([BALL], [BULL, FLAT]):
        tp = _wavy_path(rng, 120, np.repeat(np.arange(len(tools)), 120 // len(tools)))
        moves = toolpath_moves(tp, tools)
        boxes = cutting._boxes(moves)
        for limit in (0.1, 0.3, 2.0):
            cutting.GROUP_GROW, keep = limit, cutting.GROUP_GROW
            try:
                group, bound, gboxes = cutting.move_groups(moves, boxes)
            finally:
                cutting.GROUP_GROW = keep
            groups[limit] = groups.get(limit, 0) + len(bound)
            for m in np.nonzero(group >= 0)[0]:
                g = group[m]
                f = np.linspace(0, 1, 41)[:, None]
                tip = moves.pa[m] + f * (moves.pb[m] - moves.pa[m])
                x = moves.xa[m] + f * (moves.xb[m] - moves.xa[m])
                x /= np.linalg.norm(x, axis=1, keepdims=True)
                H = max(0.0, moves.flutes[m] - 2 * moves.corner[m])
                h = np.linspace(0, H, 11)
                pts = (tip[:, None] + (moves.corner[m] + h[None, :, None]) * x[:, None]).reshape(-1, 3)
                c, D, E, rad = bound[g, :3], bound[g, 3:6], bound[g, 6:9], bound[g, 9]
                assert _point_to_pgram(pts, c, D, E).max() <= rad - moves.radius[m] - SWEEP_TOL + 1e-9
                assert np.all(gboxes[g, 0] <= boxes[m, 0]) and np.all(gboxes[g, 1] >= boxes[m, 1])
                tested += 1
    assert tested > 500 and min(groups.values()) > 3, groups


@pytest.mark.slow
def test_groups_of_moves_cut_what_the_moves_cut_one_by_one(monkeypatch):
    """Lines with no material in a group's bound skip its moves: the stock, the hits (rapids,
    collisions of shanks and holders, feeds in material) and each move's load are those of the
    moves cut one by one, for balls, bull-noses and flat ends turning along a winding path, with
    lines running out of room."""
    from meshmill.simulation import cut as cutting
    from meshmill.simulation.cut import body_moves
    from meshmill.tools.table import tool_from_entry

    d = dexelize(box((0, 0, 0), (30, 20, 10)), 0.25)
    tools = [tool_from_entry(dict(name=n, type=k, diameter=6.0, corner_radius=r, flute_length=6.0, gauge_length=12.0),
                             i + 1, "t") for i, (n, k, r) in enumerate((("B6", "ball", 3.0), ("R6", "bull", 1.0),
                                                                         ("F6", "flat", 0.0)))]
    rng = np.random.default_rng(11)
    tp = _wavy_path(rng, 150, np.repeat(np.arange(3), 50))
    moves = cutting.Moves.merge(toolpath_moves(tp, tools), body_moves(tp, tools))
    runs = []
    for limit, slack in ((0.0, 2), (0.3, 2), (2.0, 2), (0.3, 0)):
        monkeypatch.setattr(cutting, "GROUP_GROW", limit)  # 0: no groups
        monkeypatch.setattr(cutting, "SLACK", slack)
        st = stock_from_model(d)
        runs.append((st, cut(st, moves, load=len(tp))))
        if limit:
            group = cutting.move_groups(moves, cutting._boxes(moves))[0]
            assert (group >= 0).sum() > len(tp) and (group[moves.body] < 0).all()
    s0, r0 = runs[0]
    m0 = s0.to_model()
    assert r0["collisions"] and len(r0["in_material"]) > 50
    for s, r in runs[1:]:
        m = s.to_model()
        assert r["in_material"].tolist() == r0["in_material"].tolist()
        assert r["rapid_cuts"] == r0["rapid_cuts"] and r["collisions"] == r0["collisions"]
        # (the threads add each move's load in their own order)
        assert np.allclose(r["load"].volume, r0["load"].volume, rtol=1e-12, atol=1e-12)
        for k in range(3):
            assert np.array_equal(m.start[k], m0.start[k]) and np.array_equal(m.iv[k], m0.iv[k]), k
