"""Gouge and collision check of any tool path against the solid a mesh bounds, certified between
its poses.

A move goes from one point to the next with the tip linear and the axis interpolated linearly and
normalised, as a controller would. Each move's point (its last pose) is measured exactly (distances
to the triangles, and whether a part lies in the material, :mod:`meshmill.kernels.clearance`).
Then each move is *certified* whole, from the point before to its own: a test that cannot miss (the
end swept as a capsule or chord patches, the cylinders as stadium prisms, with the slack the
turning axis adds) shows that no pose in between enters the material by more than the tolerance.
Where it does not, the move is halved: the middle pose measured, each half certified, and so on
until the test passes, a pose is found too deep, or the piece is shorter than ``MIN_INTERVAL``
(then the move is reported with the bound). A piece of a turning move is certified between its two
end poses, whose interpolation meets the move's axes with tips a little further along the piece:
the test takes what that moves the tool off the tolerance (:func:`pairing_slack`). The poses
``step`` apart are measured only for tools too thin to prove and for the depths of moves found
bad. So "OK" means that no point of the modelled tool enters the part deeper than the tolerance
anywhere along any feed move, and that no rapid move touches the stock at all, whatever ``step``
was.

A feed move **gouges** when the cutting part (end and flutes) enters the part by more than ``tol``;
it **collides** when the shank or holder does, or enters the stock (the part grown by the
stock's allowance, and a stock mesh when one is given: they must never rub on material the
operation expects to find; with an allowance the shank and holder are measured against the grown
part alone, which holds the part). A **rapid** move must keep every part of the tool
out of the stock: the part grown by the stock's allowance (material the path expects to find on
the design) plus the clearance a rapid keeps, and, when one is given, out of a stock mesh by the
clearance. For an open surface the material is the solid below it (:mod:`meshmill.geometry.solid`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..progress import PIECES, Meter, ranges
from .. import memory
from ..kernels.backend import MeshKernels, solid_kernels
from ..tolerances import GOUGE_TOL
from ..tools.table import pack_cylinders, pack_rings
from ..toolpath.model import Toolpath

DEFAULT_STEP = 0.5  # mm between the poses measured along a bad move (its depth) or with a thin tool
MIN_INTERVAL = 1e-5  # mm: an interval this short that cannot be certified is reported with its bound
MAX_ROUNDS = 40  # halvings of an interval (0.5 mm / 2^40: far below MIN_INTERVAL)
POSE_BYTES = 400  # a pose measured and its intervals (tips, axes, depths of every part, the interval ends)


@dataclass
class Problem:
    kind: str  # gouge | collision | rapid
    move: int  # 0-based move index
    line: int  # source line (0: not from a file)
    part: str
    depth: float  # mm
    tip: tuple

    def describe(self) -> str:
        where = f"line {self.line}" if self.line else f"move {self.move + 1}"
        x, y, z = self.tip
        if self.kind == "rapid" and self.depth < 0:  # clear of the stock, but within the clearance
            depth = f"{-self.depth:.4f} mm from the stock (less than the clearance)"
        else:
            depth = f"{self.depth:.4f} mm{' into the stock' if self.kind == 'rapid' else ''} deep"
        return f"{self.kind}: {self.part} {depth} at {where}, tip ({x:.3f}, {y:.3f}, {z:.3f})"


@dataclass
class StockCheck:
    """The material a path starts from besides the design: ``allowance`` mm of material on the
    design (every part grown by it), a stock mesh's kernels (``kern``, or None). Rapid moves keep
    the ``clearance`` mm from both; the shank and holder of feed moves stay out of both (unless
    ``feed_body`` is False)."""

    allowance: float = 0.0
    kern: MeshKernels | None = None
    clearance: float = 0.0
    # False for roughing, whose own cuts make room for its shank: simulate checks that shank and
    # holder against the stock as it is cut
    feed_body: bool = True

    def summary(self) -> dict:
        return {"allowance": float(self.allowance), "mesh": self.kern is not None, "clearance": float(self.clearance),
                "shank_and_holder": bool(self.feed_body)}


REACH_STEP_MIN = 1.0 / 16.0  # mm: the shortest interval the descent of a rapid halves down to


def rapid_reach(kern, tools, tol: float, stock: StockCheck, points, dirs, axes, tool, top, step: float = 1.0):
    """How far a rapid may come down each line ``points + t dirs`` (``(k, 3)`` each, unit
    ``dirs``) from ``t = top (k,)`` towards ``t = 0``, the tool ``tool (k,)`` held at ``axes (k,
    3)``: the smallest t (k,) reached by a descent that certifies every interval on its way as
    verification certifies a rapid (out of the part and the stock, grown as ``stock`` grows them,
    within ``tol``), in intervals of ``step`` mm halved where one is not certified (down to
    :data:`REACH_STEP_MIN`) and doubled again after each certified one."""
    points, dirs, axes = (np.asarray(a, np.float64).reshape(-1, 3) for a in (points, dirs, axes))
    t = np.asarray(top, np.float64).reshape(-1).copy()
    tool = np.asarray(tool, np.int64).reshape(-1)
    if not len(points):
        return t
    meas = _Measure(kern, tools, tol, stock)
    s = np.full(len(t), float(step))
    live = t > 0.0
    while live.any():
        i = np.nonzero(live)[0]
        lo = np.maximum(0.0, t[i] - s[i])
        ok = meas.clear(points[i] + t[i, None] * dirs[i], axes[i], points[i] + lo[:, None] * dirs[i], axes[i],
                        tool[i], np.ones(len(i), bool))[0]
        t[i[ok]] = lo[ok]
        s[i[ok]] = np.minimum(step, 2.0 * s[i[ok]])
        s[i[~ok]] *= 0.5
        live[i[~ok & (s[i] < REACH_STEP_MIN)]] = False
        live &= t > 0.0
    return t


def rapids_clear(kern, tools, tol: float, stock: StockCheck, starts, start_axes, ends, end_axes, tool,
                 step: float = DEFAULT_STEP) -> np.ndarray:
    """``(k,) bool``: whether a rapid from each of ``starts`` to ``ends`` (``(k, 3)`` tips, the
    tool ``tool (k,)`` turning from ``start_axes`` to ``end_axes``) passes verification as a move
    of a path would (:func:`verify_moves`: both ends and every interval, out of the part and the
    stock as ``stock`` grows them)."""
    k = len(starts)
    if not k:
        return np.zeros(0, bool)
    tips = np.stack([starts, ends], axis=1).reshape(-1, 3)
    axes = np.stack([start_axes, end_axes], axis=1).reshape(-1, 3)
    tp = Toolpath(tips, axes, np.ones(2 * k, bool), np.repeat(np.asarray(tool, np.int64), 2))
    only = np.zeros(2 * k, bool)
    only[1::2] = True
    found = verify_moves(kern, tp, tools, tol, step, stock, only=only, bad_depths=False, decide=True)
    ok = np.ones(k, bool)
    ok[[p.move // 2 for p in found["problems"]]] = False
    ok[[m // 2 for m in found["unresolved"]]] = False
    return ok


def body_in_stock(kern, tools, tol: float, stock: StockCheck, tips, axes, tool) -> np.ndarray:
    """``(k,)`` mm: how deep the shank and holder of the feed poses ``tips``, ``axes`` (``(k, 3)``,
    tool ``tool (k,)``) enter the stock, as verification measures them (the design grown by
    ``stock.allowance``, and ``stock``'s mesh); 0 where they keep out of it."""
    tips = np.asarray(tips, np.float64).reshape(-1, 3)
    if not len(tips):
        return np.zeros(0)
    meas = _Measure(kern, tools, tol, stock)
    if not meas.body_stocks:
        return np.zeros(len(tips))
    return meas._body_stock_depth(tips, np.asarray(axes, np.float64).reshape(-1, 3),
                                  np.asarray(tool, np.int64).reshape(-1)).max(axis=1)


def sample_moves(tp: Toolpath, tools, step: float, moves=None):
    """Poses along the path (of its ``moves``, indices in order, where given): ``tip, axis (s,
    3)``, ``tool, move (s,)``, ``frac (s,)`` (the pose's place along its move, 0 at the point
    before, 1 at the move's point), ``rapid (s,) bool``."""
    k = len(tp)
    if k == 0 or (moves is not None and len(moves) == 0):
        e3, e = np.empty((0, 3)), np.empty(0, np.int64)
        return e3, e3, e, e, np.empty(0), np.empty(0, bool)
    # the poses of each move asked: its tip's travel or its reach's turn over the step (move 0, the
    # path's first point, one pose)
    which = np.arange(k) if moves is None else np.asarray(moves, np.int64)
    prev = np.maximum(which - 1, 0)
    dtip = np.linalg.norm(tp.tip[which] - tp.tip[prev], axis=1)
    cosang = np.clip(np.einsum("ij,ij->i", tp.axis[which], tp.axis[prev]), -1.0, 1.0)
    dang = np.arccos(cosang) * np.array([t.reach for t in tools])[tp.tool[which]]
    n = np.where(which == 0, 1.0, np.maximum(1, np.ceil(np.maximum(dtip, dang) / step)))
    memory.check(POSE_BYTES * float(n.sum()), f"{n.sum():,.0f} poses {step:g} mm apart", "use a larger step", ("step",))
    n = n.astype(np.int64)
    move = np.repeat(which, n)
    first = np.cumsum(n) - n
    j = np.arange(n.sum()) - np.repeat(first, n) + 1
    frac = j / np.repeat(n, n)
    frac[move == 0] = 1.0
    tip, axis = move_poses(tp, move, frac)
    return tip, axis, tp.tool[move], move, frac, tp.rapid[move]


def move_poses(tp: Toolpath, move, frac):
    """Tips and unit axes ``(s, 3)`` at ``frac (s,)`` along ``move (s,)`` (from point move-1)."""
    prev = np.maximum(move - 1, 0)
    f = frac[:, None]
    # (1 - f) a + f b: the move's point itself at f = 1, whatever the point before
    tip = (1.0 - f) * tp.tip[prev] + f * tp.tip[move]
    axis = (1.0 - f) * tp.axis[prev] + f * tp.axis[move]
    norm = np.linalg.norm(axis, axis=1, keepdims=True)
    axis = np.where(norm > 1e-9, axis / np.maximum(norm, 1e-300), tp.axis[move])
    return tip, axis


def pairing_slack(tp: Toolpath, move, fa, fb) -> np.ndarray:
    """``(k,)`` mm: how far the poses of ``move (k,)`` between the fractions ``fa`` and ``fb``
    (k,) of it lie at most from those of the interval between its poses there, as the kernels
    prove it (tip linear, the two unit axes joined by their normalised interpolation): the same
    axes, each met with the tip of another place along the piece. With the move's unnormalised
    axes V = (1 - f) a + f b at the two ends, of lengths n0 and n1, that place is off by
    λ(1 - λ)|n0 - n1| / ((1 - λ) n0 + λ n1) <= |n0 - n1| / (4 min(n0, n1)) of the piece, so every
    pose of the move is a pose of the interval moved by at most that share of the piece's tip
    travel (0 for a fixed axis, and for the whole move). A proof within a limit bounds how deep
    any point of the tool lies in the material; moving the tool by d deepens that by d at most."""
    prev = np.maximum(move - 1, 0)
    a, b = tp.axis[prev], tp.axis[move]
    n0 = np.linalg.norm((1.0 - fa)[:, None] * a + fa[:, None] * b, axis=1)
    n1 = np.linalg.norm((1.0 - fb)[:, None] * a + fb[:, None] * b, axis=1)
    travel = np.abs(fb - fa) * np.linalg.norm(tp.tip[move] - tp.tip[prev], axis=1)
    return 0.25 * np.abs(n0 - n1) / np.maximum(np.minimum(n0, n1), 1e-300) * travel


def _part_names(tools, k):
    names = []
    for tool in tools:
        row = []
        for t0, t1, r, cut in tool.cylinders():
            if cut:
                row.append("end" if t0 == 0.0 else "flutes")
            else:
                row.append("shank" if abs(t0 - tool.flute_length) < 1e-12 and t1 == tool.gauge_length else "holder")
        names.append(row + [""] * (k - len(row)))
    return names


class _Measure:
    """The tool geometry and the solids a path is measured against."""

    def __init__(self, kern, tools, tol, stock: StockCheck):
        (t0, t1, r), self.cutting = pack_cylinders(tools)
        # a flat bottom resting exactly on a facet touches it: the slab of a cutting cylinder that
        # starts at the tip starts tol above it
        self.segs = (np.where(self.cutting & (t0 == 0.0), tol, t0), t1, r)
        self.base = t0
        self.rings = pack_rings(tools)
        self.reach = np.array([t.reach for t in tools])
        self.kern, self.tol, self.stock = kern, tol, stock
        # shank and holder alone (no end, no flutes), for feed moves against the stock: ``body_col``
        # (T, Kb) is the column of each of their cylinders in the full packing
        cols = [np.nonzero(~self.cutting[i] & (r[i] > 0))[0] for i in range(len(tools))]
        kb = max([1] + [len(c) for c in cols])
        packed = [np.zeros((len(tools), kb)) for _ in range(3)]
        self.body_col = np.zeros((len(tools), kb), np.int64)
        for i, c in enumerate(cols):
            for a, src in zip(packed, (t0, t1, r)):
                a[i, :len(c)] = src[i, c]
            self.body_col[i, :len(c)] = c
        self.body_segs = tuple(packed)
        self.no_rings = self.rings[:2] + (np.zeros_like(self.rings[2]), self.rings[3])
        # what the shank and holder of feed moves stay out of: (kernels, grown by) per solid
        self.body_stocks = [] if not stock.feed_body else (
            [(kern, float(stock.allowance))] * (stock.allowance > 0) + [(stock.kern, 0.0)] * (stock.kern is not None))
        # (T,): a tool with a part whose radius the tolerance swallows is proven of nothing (its
        # sweep shrunk by the tolerance is empty): every pose of its moves is measured
        radii = np.column_stack([self.rings[2], r])
        self.thin = ((radii > 0.0) & (radii <= tol)).any(axis=1)
        # tools T..2T-1: the cutting parts alone (a prefix of each tool's cylinders). Where the
        # shank and holder of a feed move keep out of the design grown by the allowance, they keep
        # out of the design (a part grown holds the part), so feed moves meet the design with these
        self.count = len(tools)
        self.cut_only = bool(stock.feed_body and stock.allowance > 0)
        if self.cut_only:
            t0, t1, r = self.segs
            self.segs = (np.concatenate([t0, t0]), np.concatenate([t1, t1]),
                         np.concatenate([r, np.where(self.cutting, r, 0.0)]))
            self.base = np.concatenate([self.base, self.base])
            self.rings = tuple(np.concatenate([a, a]) for a in self.rings)

    def _design_tool(self, tool, rapid):
        """The tool numbers poses meet the design with: feed poses without shank and holder where
        :attr:`body_stocks` holds the design grown by the allowance."""
        return np.where(rapid, tool, tool + self.count) if self.cut_only else tool

    def _grow(self, rapid, on_stock):
        c = self.stock.clearance
        return np.where(rapid, c if on_stock else self.stock.allowance + c, 0.0)

    def _body_stock_depth(self, tip, axis, tool, stop=-1.0):
        """``(f, Kb)``: how deep the shank and holder of feed poses enter the stock (the design
        grown by the allowance, and the stock mesh)."""
        depth = np.zeros((len(tip), self.body_col.shape[1]))
        for kern, grow in self.body_stocks:
            depth = np.maximum(depth, kern.pose_penetration(tip, axis, tool, np.full(len(tip), grow), self.no_rings,
                                                            self.body_segs, self.body_segs[0], stop)[1])
        return depth

    def depths(self, tip, axis, tool, rapid, stop=-1.0):
        """``(end (s,), body (s,), ring (s,), segs (s, K), stock (s,))``: how deep each pose enters;
        rapid poses are measured against the stock (grown) and reported as depth into it; the
        shank and holder of feed poses also against the stock (``stock``: that depth alone). With
        ``stop`` >= 0 only whether each depth exceeds it is asked (the kernels' ``stop``)."""
        ring, segs = self.kern.pose_penetration(tip, axis, self._design_tool(tool, rapid), self._grow(rapid, False),
                                                self.rings, self.segs, self.base, stop)
        if self.stock.kern is not None and rapid.any():
            r2, s2 = self.stock.kern.pose_penetration(tip[rapid], axis[rapid], tool[rapid],
                                                      self._grow(rapid[rapid], True), self.rings, self.segs,
                                                      self.base, stop)
            ring[rapid] = np.maximum(ring[rapid], r2)
            segs[rapid] = np.maximum(segs[rapid], s2)
        in_stock = np.zeros(len(tip))
        feed = np.nonzero(~rapid)[0]
        if self.body_stocks and len(feed):
            sb = self._body_stock_depth(tip[feed], axis[feed], tool[feed], stop)
            in_stock[feed] = sb.max(axis=1)
            cols = self.body_col[tool[feed]]
            used = self.body_segs[2][tool[feed]] > 0
            for j in range(sb.shape[1]):
                rows, c = feed[used[:, j]], cols[used[:, j], j]
                segs[rows, c] = np.maximum(segs[rows, c], sb[used[:, j], j])
        cut = self.cutting[tool]
        end = np.maximum(ring, np.where(cut, segs, 0.0).max(axis=1))
        body = np.where(~cut, segs, 0.0).max(axis=1)
        return end, body, ring, segs, in_stock

    def clear(self, ta, xa, tb, xb, tool, rapid, slack=None, proven=None):
        """``(ok, tool_ok)``, (k,) bool each: intervals certified within the tolerance (rapids: out
        of the stock; the shank and holder of feed moves: out of the stock too), less ``slack (k,)``
        mm where given (:func:`pairing_slack`; the kernels prove limits of 0 and more only: an
        interval whose slack reaches the tolerance is not certified); and those whose tool is
        certified against the design (rapids: and the stock), the feed moves' shank and holder
        against the stock left. ``proven (k,) bool``: intervals whose tool is known to be so (the
        pieces of a move whose proof covered it whole: their poses are the move's), not tested
        again."""
        if slack is not None and (slack >= self.tol).any():
            ok = np.zeros(len(ta), bool)
            part = np.zeros(len(ta), bool) if proven is None else proven.copy()
            sel = np.nonzero(slack < self.tol)[0]
            if len(sel):
                ok[sel], part[sel] = self.clear(ta[sel], xa[sel], tb[sel], xb[sel], tool[sel], rapid[sel], slack[sel],
                                                None if proven is None else proven[sel])
            return ok, part
        lim = np.full(len(ta), self.tol) if slack is None else self.tol - slack
        fresh = np.ones(len(ta), bool) if proven is None else ~proven
        ok = np.zeros(len(ta), bool) if proven is None else proven.copy()
        sel = slice(None) if proven is None else np.nonzero(fresh)[0]  # (all: views, no copies)
        if fresh.any():
            ok[sel] = self.kern.intervals_clear(ta[sel], xa[sel], tb[sel], xb[sel],
                                                self._design_tool(tool[sel], rapid[sel]), self._grow(rapid[sel], False),
                                                lim[sel], self.rings, self.segs, self.base)
        if self.stock.kern is not None and (ok & rapid & fresh).any():
            sel = np.nonzero(ok & rapid & fresh)[0]
            ok[sel] = self.stock.kern.intervals_clear(ta[sel], xa[sel], tb[sel], xb[sel], tool[sel],
                                                      self._grow(rapid[sel], True), lim[sel], self.rings, self.segs,
                                                      self.base)
        part = ok.copy()
        for kern, grow in self.body_stocks:
            sel = np.nonzero(ok & ~rapid)[0]
            if len(sel):
                ok[sel] = kern.intervals_clear(ta[sel], xa[sel], tb[sel], xb[sel], tool[sel], np.full(len(sel), grow),
                                               lim[sel], self.no_rings, self.body_segs, self.body_segs[0])
        return ok, part


def verify_toolpath(kern, tp: Toolpath, tools, tol: float = GOUGE_TOL, step: float = DEFAULT_STEP,
                    worst: int = 10, device: str = "cpu", stock: StockCheck | None = None, progress=None) -> dict:
    """Check ``tp`` against the solid of ``kern`` (:class:`~meshmill.kernels.backend.MeshKernels`
    bound to it, :func:`~meshmill.kernels.backend.solid_kernels`; or a
    :class:`~meshmill.geometry.mesh.Mesh`, bound here on ``device``); returns a JSON-ready report
    with the counts of moves that gouge, collide or rapid into the stock, and the ``worst`` cases.
    Where the moves come from a file, ``lines`` counts its lines with moves and ``problem_lines``
    its lines with a problem of each kind (a G-code arc or rotary block is read as several moves).
    With ``progress`` the moves are checked in ranges (:func:`verify_moves`, the same report), the
    share done and the time left told after each."""
    stock = stock or StockCheck()
    if not isinstance(kern, MeshKernels):
        kern = solid_kernels(kern, device)
    return merge_reports(tp, check_parts(kern, tp, tools, tol, step, stock, progress=progress), tol, step,
                         stock.summary(), worst)


def check_parts(kern, tp: Toolpath, tools, tol: float, step: float, stock: StockCheck, only=None,
                progress=None, bad_depths: bool = True) -> list[dict]:
    """What :func:`verify_moves` finds on ``tp`` (its moves where ``only (k,) bool`` is set, else
    all), in :data:`~meshmill.progress.PIECES` ranges when ``progress`` is given (the share done
    and the time left told after each); :func:`merge_reports` makes the report."""
    if progress is None:
        return [verify_moves(kern, tp, tools, tol, step, stock, only=only, bad_depths=bad_depths)]
    what = "every move" if only is None or np.all(only) else f"the {int(np.count_nonzero(only)):,} moves changed"
    meter, parts = Meter(progress, f"certified check of {what}", len(tp)), []
    for first, piece, piece_only in path_pieces(tp, PIECES, only):
        parts.append(verify_moves(kern, piece, tools, tol, step, stock, first, piece_only, bad_depths))
        meter.done(len(piece))
    return parts


def path_pieces(tp: Toolpath, count: int, only=None) -> list[tuple]:
    """``count`` pieces ``(first, piece, only)`` of ``tp`` for :func:`verify_moves`: each from the
    point before its range of moves (``first``), so that every move is in exactly one piece;
    ``only``: the moves of the whole path to check (None: all), sliced to the piece's."""
    return [(max(0, a - 1), tp.points(max(0, a - 1), b), None if only is None else only[max(0, a - 1):b])
            for a, b in ranges(len(tp), count)]


def verify_moves(kern, tp: Toolpath, tools, tol: float, step: float, stock: StockCheck, first: int = 0,
                 only=None, bad_depths: bool = True, decide: bool = False) -> dict:
    """What :func:`verify_toolpath` finds on the moves into points ``first + 1 ..`` of ``tp``, whose
    point 0 is the point ``first`` of a whole path (its pose is checked with the move into it, in
    the piece before), or on those where ``only (len(tp),) bool`` is set: counts, the deepest feed
    poses, and the problems with their moves numbered as the whole path's; ``figures``: the same
    per move checked (``move`` numbered as the whole path's, ``poses``, ``refined``, ``certified``,
    ``max_gouge``, ``max_collision``). Pieces of a path verified apart (:func:`merge_reports`) give
    the whole path's report. A move's figures depend on its two points alone. Without
    ``bad_depths`` a move found bad is not measured further: its depth is that of the poses that
    found it, at least (for repairs, which need only which moves fail). With ``decide`` only
    which moves fail is asked: a pose's depth is exact up to ``tol`` and past it any depth past
    ``tol`` (past it wherever the exact depth is: the searches end at the first triangle deeper
    than that)."""
    checked = np.ones(len(tp), bool) if only is None else np.asarray(only, bool).copy()
    if first > 0:
        checked[0] = False
    if not checked.any():
        return {"poses": 0, "certified": 0, "refined": 0, "max_gouge": 0.0, "max_collision": 0.0, "problems": [],
                "unresolved": [], "figures": _figures(first, np.zeros(0, np.int64), *[np.zeros(0)] * 5)}
    meas = _Measure(kern, tools, tol, stock)
    bad_move = np.zeros(len(tp), bool)
    poses = []  # (tip, tool, move, rapid, end, body, ring, segs, in_stock) of the poses measured

    def measure(tip, axis, tool, move, rapid):  # a move with a pose beyond the tolerance is bad
        got = meas.depths(tip, axis, tool, rapid, tol if decide else -1.0)
        poses.append((tip, tool, move, rapid, *got))
        bad_move[move[(got[0] > tol) | (got[1] > tol)]] = True

    def measure_samples(moves):  # every pose ``step`` apart of ``moves``, but their last (measured first)
        tip, axis, tool, move, frac, rapid = sample_moves(tp, tools, step, moves)
        inner = frac < 1.0
        if inner.any():
            measure(tip[inner], axis[inner], tool[inner], move[inner], rapid[inner])

    # Each move's last pose (its point) is measured first; a tool too thin to prove (``thin``) has
    # every pose ``step`` apart measured. Every move is then proven whole, from the point before
    # to its own (a proof holds at any length: it bounds every pose between), unless it already
    # failed; the path's first point, a move of length zero, is proven at its pose as one too (its
    # measure samples a rounded end's circle, the proof covers it). A move whose proof fails is
    # halved: each half's middle pose measured, each half proven (less its pairing slack), and
    # so on where a proof fails, until a pose is found beyond the tolerance or the intervals left
    # are too short to halve. The poses between a move's ends are measured only where the move is
    # found bad, for the depths reported (``bad_depths``).
    mv = np.nonzero(checked)[0]
    measure(tp.tip[mv], tp.axis[mv], tp.tool[mv], mv, tp.rapid[mv])
    measure_samples(mv[meas.thin[tp.tool[mv]]])
    last = mv[~bad_move[mv]]
    before = np.maximum(last - 1, 0)
    certified = np.zeros(len(tp), np.int64)
    ok, part = meas.clear(tp.tip[before], tp.axis[before], tp.tip[last], tp.axis[last], tp.tool[last], tp.rapid[last])
    certified += np.bincount(last[ok], minlength=len(tp))
    im = last[~ok]
    ta, xa, tb, xb = tp.tip[before[~ok]], tp.axis[before[~ok]], tp.tip[im], tp.axis[im]
    fa, fb = np.zeros(len(im)), np.ones(len(im))
    it, ir = tp.tool[im], tp.rapid[im]
    iw = part[~ok]  # the tool proven against the design over the whole move: its pieces' too
    unresolved = []  # (move, tip, bound) of intervals too short to halve that stay unproven
    refined = []  # the moves of the poses measured in halving
    for _ in range(MAX_ROUNDS):  # the intervals here failed their proof, their moves not found bad
        if len(im) == 0:
            break
        turn = np.arccos(np.clip(np.einsum("ij,ij->i", xa, xb), -1.0, 1.0))
        span = np.linalg.norm(tb - ta, axis=1) + meas.reach[it] * turn
        short = span < MIN_INTERVAL
        for k in np.nonzero(short)[0]:
            unresolved.append((int(im[k]), ta[k], float(span[k])))
            bad_move[im[k]] = True
        live = ~short
        ta, xa, fa, tb, xb, fb, im, it, ir, iw = (a[live] for a in (ta, xa, fa, tb, xb, fb, im, it, ir, iw))
        memory.check(2 * POSE_BYTES * len(im), f"{2 * len(im):,} pieces of moves halved", "use a larger tolerance",
                     ("tolerance",))
        fm = 0.5 * (fa + fb)
        tm, xm = move_poses(tp, im, fm)
        refined.append(im)
        measure(tm, xm, it, im, ir)
        ta, xa, fa, tb, xb, fb, im, it, ir, iw = (np.concatenate([a, b]) for a, b in
                                                  ((ta, tm), (xa, xm), (fa, fm), (tm, tb), (xm, xb), (fm, fb),
                                                   (im, im), (it, it), (ir, ir), (iw, iw)))
        alive = ~bad_move[im]
        ta, xa, fa, tb, xb, fb, im, it, ir, iw = (a[alive] for a in (ta, xa, fa, tb, xb, fb, im, it, ir, iw))
        ok, part = meas.clear(ta, xa, tb, xb, it, ir, pairing_slack(tp, im, fa, fb), iw)
        certified += np.bincount(im[ok], minlength=len(tp))
        todo = ~ok
        ta, xa, fa, tb, xb, fb, im, it, ir, iw = (a[todo] for a in (ta, xa, fa, tb, xb, fb, im, it, ir, part))
    else:
        for k in range(len(im)):
            unresolved.append((int(im[k]), ta[k], float(np.linalg.norm(tb[k] - ta[k]))))
    if bad_depths:
        measure_samples(mv[bad_move[mv] & ~meas.thin[tp.tool[mv]]])
    refined = np.bincount(np.concatenate(refined + [np.zeros(0, np.int64)]), minlength=len(tp))
    tip, tool, move, rapid, end, body, ring, segs, in_stock = (np.concatenate(a) for a in zip(*poses))
    part = _found(tp, tools, tip, tool, move, rapid, end, body, ring, segs, in_stock, meas, unresolved)
    feed = ~rapid
    gouge = np.zeros(len(tp))
    np.maximum.at(gouge, move[feed], end[feed])
    collision = np.zeros(len(tp))
    np.maximum.at(collision, move[feed], body[feed])
    part.update(certified=int(certified.sum()), refined=int(refined.sum()),
                figures=_figures(first, mv, np.bincount(move, minlength=len(tp))[mv], refined[mv], certified[mv],
                                 gouge[mv], collision[mv]))
    if first:
        for p in part["problems"]:
            p.move += first
        part["unresolved"] = [m + first for m in part["unresolved"]]
    return part


def _figures(first, moves, poses, refined, certified, max_gouge, max_collision) -> dict:
    """:func:`verify_moves`'s ``figures`` of the ``moves (n,)`` of a piece starting at point
    ``first`` of the whole path."""
    return {"move": moves + first, "poses": poses.astype(np.int64), "refined": refined.astype(np.int64),
            "certified": certified.astype(np.int64), "max_gouge": max_gouge.astype(float),
            "max_collision": max_collision.astype(float)}


def _found(tp, tools, tip, tool, move, rapid, end_depth, body_depth, ring_depth, seg_depth, stock_depth, meas,
           unresolved) -> dict:
    """The problems of the checked poses (moves numbered as in ``tp``) and their figures."""
    tol = meas.tol
    cut_mask = meas.cutting[tool]
    seg_cut = np.where(cut_mask, seg_depth, 0.0)
    seg_body = np.where(~cut_mask, seg_depth, 0.0)
    names = _part_names(tools, seg_depth.shape[1])
    problems = []
    clearance = meas.stock.clearance

    def collect(kind, mask, depth, part, shift=0.0):
        idx = np.nonzero(mask)[0]
        if len(idx) == 0:
            return set()
        # the deepest pose of each offending move
        order = np.lexsort((-depth[idx], move[idx]))
        idx = idx[order]
        firsts = idx[np.r_[True, move[idx][1:] != move[idx][:-1]]]
        parts = part(firsts)
        for m, line, d, at, name in zip(move[firsts].tolist(), tp.line[move[firsts]].tolist(),
                                        (depth[firsts] - shift).tolist(), tip[firsts].tolist(), parts):
            problems.append(Problem(kind, m, line, name, d, tuple(at)))
        return set(move[firsts].tolist())

    def named(i, seg):  # the part of each pose i whose column of ``seg`` is deepest
        return [names[t][c] for t, c in zip(tool[i].tolist(), np.argmax(seg[i], axis=1).tolist())]

    def end_part(i):
        ring_wins = ring_depth[i] >= seg_cut[i].max(axis=1)
        cyl = named(i, seg_cut)
        return [tools[t].type + " end" if w else c for t, w, c in zip(tool[i].tolist(), ring_wins.tolist(), cyl)]

    def body_part(i):
        where = (stock_depth[i] >= body_depth[i]) & (body_depth[i] > 0.0)
        return [c + " (in the stock)" if w else c for w, c in zip(where.tolist(), named(i, seg_body))]

    def any_part(i):
        end_wins = end_depth[i] >= body_depth[i]
        return [e if w else b for w, e, b in zip(end_wins.tolist(), end_part(i), body_part(i))]

    gouge = collect("gouge", ~rapid & (end_depth > tol), end_depth, end_part)
    coll = collect("collision", ~rapid & (body_depth > tol), body_depth, body_part)
    worst_any = np.maximum(end_depth, body_depth)
    rap = collect("rapid", rapid & (worst_any > tol), worst_any, any_part, clearance)
    unresolved_moves = set()
    for m, at, span in unresolved:
        unresolved_moves.add(m)
        if m in gouge or m in coll or m in rap:
            continue
        kind = "rapid" if tp.rapid[m] else "gouge"
        (rap if kind == "rapid" else gouge).add(m)
        problems.append(Problem(kind, m, int(tp.line[m]), "tool (not certified within the tolerance)",
                                float(tol + span), tuple(float(v) for v in at)))
    feed = ~rapid
    return {"poses": int(len(tip)), "max_gouge": float(end_depth[feed].max()) if feed.any() else 0.0,
            "max_collision": float(body_depth[feed].max()) if feed.any() else 0.0, "problems": problems,
            "unresolved": sorted(unresolved_moves)}


def verify_piece(shared: dict, piece) -> dict:
    """:func:`verify_moves` of one piece ``(first, toolpath, only)`` of a path on a worker of a cluster
    (:func:`meshmill.cluster.run_pieces`); ``shared``: the part, its ``floor``, the ``stock`` mesh
    (or None), ``allowance`` and ``clearance`` (rapids keep it from both; default 0), the ``tools``,
    ``tol``, ``step``, ``device`` (and ``bad_depths``, default True). The kernels are built once
    per worker."""
    from ..cluster import worker_cached

    first, tp, only = piece
    kern = worker_cached(shared, "part", lambda: solid_kernels(shared["part"], shared["device"], shared["floor"]))
    stock_kern = None
    if shared["stock"] is not None:
        stock_kern = worker_cached(shared, "stock", lambda: solid_kernels(shared["stock"], shared["device"]))
    check = StockCheck(allowance=shared["allowance"], kern=stock_kern, clearance=shared.get("clearance", 0.0))
    return verify_moves(kern, tp, shared["tools"], shared["tol"], shared["step"], check, first, only,
                        shared.get("bad_depths", True))


KINDS = ("gouge", "collision", "rapid")


def merge_reports(tp: Toolpath, parts: list, tol: float, step: float, stock: dict, worst: int = 10) -> dict:
    """The JSON-ready report of ``tp`` from what :func:`verify_moves` found on its pieces;
    ``stock``: the :meth:`StockCheck.summary` they were checked with."""
    problems = sorted((p for part in parts for p in part["problems"]),
                      key=lambda p: (-p.depth, KINDS.index(p.kind), p.move))
    moves = {kind: {p.move for p in problems if p.kind == kind} for kind in KINDS}
    lines = {kind: len({p.line for p in problems if p.kind == kind and p.line > 0}) for kind in KINDS}
    return {
        "moves": int(len(tp)), "step": float(step), "tolerance": float(tol), "stock": stock,
        "poses_checked": sum(p["poses"] for p in parts),
        "poses_refined": sum(p["refined"] for p in parts),
        "intervals_certified": sum(p["certified"] for p in parts),
        "gouging_moves": len(moves["gouge"]),
        "colliding_moves": len(moves["collision"]),
        "rapid_moves_touching": len(moves["rapid"]),
        "unresolved_moves": len({m for p in parts for m in p["unresolved"]}),
        "max_gouge": max([p["max_gouge"] for p in parts], default=0.0),
        "max_collision": max([p["max_collision"] for p in parts], default=0.0),
        "ok": not problems,
        "worst": [p.describe() for p in problems[:worst]],
        "problem_moves": sorted({p.move for p in problems}),
        "lines": int(len(np.unique(tp.line[tp.line > 0]))),
        "problem_lines": lines,
    }
