"""Material removal: a stock held as triple dexels, cut by the volume each move of a tool path
sweeps (exact per move, :mod:`meshmill.kernels.sweep`), or by the tool at the path's points only
(the seed's mode, kept for comparison). The shank and holder do not cut: where the volume they
sweep meets material left in the stock at that point of the path, the move collides.

A move goes from one CL point to the next, tip interpolated linearly and the tool axis by the
normalised linear interpolation of the two axes (a 5-axis controller's interpolation of its
rotary joints differs from this by less than the path tolerance for the small angle steps of a
finishing path). A move whose axis turns is split into pieces of equal turns (:func:`turn_pieces`,
:func:`split_turns`) over which the cut stays within ``SWEEP_TOL`` of the swept volume.

Consecutive cutting moves are gathered in groups under one bound (:func:`move_groups`): a line
with no material in a group's bound skips all its moves, which would remove nothing from it (on
a finish most lines a move crosses were emptied by the moves just before). The result is that of
the moves cut one by one.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from ..progress import Meter, ranges
from ..errors import InputError
from ..kernels.backend import BODY, RAPID, TILE, DexelKernels
from ..kernels.sweep import SEARCH_SAMPLES
from .dexel import DexelModel, compact_lines, join_lines

SWEEP_TOL = 1e-3  # mm: largest gap between the cut and the true swept volume of a turning tool
BODY_SWEEP_TOL = 5e-3  # mm: the same for a shank or holder, which cuts nothing (each also that much thinner)
MAX_TURN = 0.05  # rad: largest turn of a piece of a flat or bull-nose move (searched over poses)
SAME_AXIS = 1e-9  # rad: axes closer than this are one axis (the move is cut with a fixed axis)
MAX_MOVE_TURN = 179.0  # degrees: a larger turn in one move has no interpolation (the axis passes 0)
RAPID_CUT = 1e-3  # mm of a dexel a rapid move must remove (or a shank or holder meet) to count as cutting
SLACK = 8  # spare interval slots a line with material starts with, at most (a line out of room is cut again)
SLACK_BYTES = 256e6  # bytes the spare slots of a direction may take (with at least 2 a line)
CUT_PIECES = 8  # pieces the tiles are cut in on one machine (each alike: a share of every direction's tiles)
PIECE_COMBS = 4  # combs of rows a tile is dealt out to the pieces in (a power of two up to TILE)
GROUP_MOVES = 16  # moves a group holds at most (see move_groups)
GROUP_GROW = 0.3  # mm: how far a group's bound may reach past its moves' tools
MOVE_BYTES = 1200  # a move on a worker of a cluster: its arrays, and per direction its frame, constants, box, tiles


@dataclass
class Stock:
    """Mutable triple dexels on a model's lattice: per direction ``iv (cap, 2)`` with the room of
    line ``i`` at ``off[i]:off[i+1]`` and ``count (n_lines,)`` intervals in use."""

    lo: np.ndarray
    step: float
    n: np.ndarray
    iv: list
    off: list
    count: list

    def to_model(self, name="machined") -> DexelModel:
        starts, ivs = [], []
        for a in range(3):
            s, v = compact_lines(self.iv[a], self.off[a], self.count[a])
            starts.append(s)
            ivs.append(v)
        return DexelModel(lo=self.lo.copy(), step=self.step, n=self.n.copy(), start=starts, iv=ivs, name=name)


def slack(counts) -> int:
    """Spare interval slots for each line with material among lines of ``counts (lines,)``
    intervals: :data:`SLACK`, fewer (down to 2) where they would take more than
    :data:`SLACK_BYTES`."""
    lines = max(1, int(np.count_nonzero(counts)))
    return int(min(SLACK, max(2, SLACK_BYTES // (16 * lines))))


@numba.njit(cache=True)
def _spread(start, src, allowance, slack):
    """Per-line room ``count + slack`` (lines with intervals) and the intervals widened by
    ``allowance`` at both ends (merged where they then overlap)."""
    n = start.shape[0] - 1
    off = np.zeros(n + 1, np.int64)
    for i in range(n):
        c = start[i + 1] - start[i]
        off[i + 1] = off[i] + c + (slack if c > 0 else 0)
    iv = np.zeros((off[n], 2))
    count = np.zeros(n, np.int64)
    for i in range(n):
        c = 0
        for k in range(start[i], start[i + 1]):
            s = src[k, 0] - allowance
            e = src[k, 1] + allowance
            if c > 0 and s <= iv[off[i] + c - 1, 1]:
                iv[off[i] + c - 1, 1] = max(e, iv[off[i] + c - 1, 1])
            else:
                iv[off[i] + c, 0] = s
                iv[off[i] + c, 1] = e
                c += 1
        count[i] = c
    return iv, off, count


def stock_from_model(model: DexelModel, allowance: float = 0.0) -> Stock:
    """A stock from a dexel model, every dexel lengthened by ``allowance`` mm at both ends (the
    seed's "both ends" stock allowance: an offset of ``allowance * |n.a|`` of a surface)."""
    ivs, offs, counts = [], [], []
    for a in range(3):
        iv, off, count = _spread(model.start[a], model.iv[a], float(allowance), slack(np.diff(model.start[a])))
        ivs.append(iv)
        offs.append(off)
        counts.append(count)
    return Stock(lo=model.lo.copy(), step=model.step, n=model.n.copy(), iv=ivs, off=offs, count=counts)


def widened(start, iv, allowance: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(start, iv)`` of the lines ``(start, iv)`` as :func:`stock_from_model` makes them
    (every dexel lengthened by ``allowance`` mm at both ends, those then touching merged)."""
    return compact_lines(*_spread(start, iv, float(allowance), 0))


def _grow(stock: Stock, a: int, lines: np.ndarray) -> None:
    """Double the room of the given lines of direction ``a``."""
    room = np.diff(stock.off[a])
    room[lines] *= 2
    off = np.zeros(len(room) + 1, np.int64)
    np.cumsum(room, out=off[1:])
    counts = stock.count[a]
    within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    iv = np.zeros((off[-1], 2))
    iv[np.repeat(off[:-1], counts) + within] = stock.iv[a][np.repeat(stock.off[a][:-1], counts) + within]
    stock.iv[a] = iv
    stock.off[a] = off


@dataclass
class Moves:
    """Linear moves of one cutter each: tips ``pa, pb (k, 3)``, unit axes ``xa, xb (k, 3)``,
    ``radius, corner, flutes (k,)`` mm, ``strips (k,)`` (see :func:`twist_strips`), ``rapid (k,)
    bool``, ``source (k,)`` index of the tool-path point each move ends at; ``body (k,) bool``: a
    shank or holder (a flat cylinder standing at the tip given), which removes nothing."""

    pa: np.ndarray
    pb: np.ndarray
    xa: np.ndarray
    xb: np.ndarray
    radius: np.ndarray
    corner: np.ndarray
    flutes: np.ndarray
    strips: np.ndarray
    rapid: np.ndarray
    source: np.ndarray
    body: np.ndarray | None = None

    def __post_init__(self):
        if self.body is None:
            self.body = np.zeros(len(self.pa), bool)

    def __len__(self):
        return len(self.pa)

    @staticmethod
    def merge(*parts: "Moves") -> "Moves":
        """The ``parts`` in path order (by source point; for one point, in the order given)."""
        fields = ("pa", "pb", "xa", "xb", "radius", "corner", "flutes", "strips", "rapid", "source", "body")
        order = np.argsort(np.concatenate([p.source for p in parts]), kind="stable")
        return Moves(**{f: np.concatenate([getattr(p, f) for p in parts])[order] for f in fields})


def toolpath_moves(toolpath, tools, mode="sweep") -> Moves:
    """The moves to cut for a :class:`~meshmill.toolpath.model.Toolpath`.

    ``mode="sweep"``: every move from point k-1 to point k with the tool of point k (the first
    point is a move of length zero), split where the axis turns (see the module docstring).
    ``mode="points"``: the tool placed at each point only; a ball-end mill is then its sphere only,
    as in the seed."""
    tip = np.asarray(toolpath.tip, float)
    axis = np.asarray(toolpath.axis, float)
    k = len(tip)
    R = np.array([tools[t].radius for t in toolpath.tool])
    r = np.array([tools[t].radius if tools[t].type == "ball" else tools[t].corner_radius for t in toolpath.tool])
    F = np.array([max(tools[t].flute_length, 2 * r_) for t, r_ in zip(toolpath.tool, r)])
    if mode == "points":
        F = np.where(r >= R, 2 * R, F)
        return Moves(tip, tip.copy(), axis, axis.copy(), R, r, F, np.ones(k, np.int64), toolpath.rapid.astype(bool),
                     np.arange(k))
    pa = np.vstack([tip[:1], tip[:-1]])
    xa = np.vstack([axis[:1], axis[:-1]])
    axis = axis.copy()
    cos = np.einsum("ij,ij->i", xa, axis)
    flip = np.nonzero(cos < math.cos(math.radians(MAX_MOVE_TURN)))[0]
    if len(flip):
        i = int(flip[0])
        raise InputError(f"the tool axis turns by {math.degrees(math.acos(max(-1.0, cos[i]))):.1f} degrees in the move to "
                         f"point {i} (source line {int(toolpath.line[i])}): no interpolation of the axis is defined there")
    same = cos > math.cos(SAME_AXIS)  # numerically the same axis: cut as a fixed-axis move, exactly
    axis[same] = xa[same]
    pieces = turn_pieces(pa, tip, xa, axis, R, r, F)
    if (pieces == 1).all():
        return Moves(pa, tip, xa, axis.copy(), R, r, F, twist_strips(pa, tip, xa, axis, r, F),
                     toolpath.rapid.astype(bool), np.arange(k))
    src, p0, p1, x0, x1 = split_turns(pa, tip, xa, axis, pieces)
    return Moves(p0, p1, x0, x1, R[src], r[src], F[src], twist_strips(p0, p1, x0, x1, r[src], F[src]),
                 toolpath.rapid[src].astype(bool), src)


def body_moves(toolpath, tools, shrink: float = 0.0) -> Moves:
    """The shank and holder of every move of ``toolpath`` (each a flat cylinder, from its start up
    the axis), split where the axis turns as a flat cutter reaching up to the cylinder's top would
    be, so that their sweep stays within ``BODY_SWEEP_TOL`` of the true one (a collision test
    needs no more: they cut nothing). ``shrink`` (mm): each cylinder thinner by it and starting
    that much higher (what meets the stock is then deeper in it than ``shrink``, as verification
    counts a collision beyond its tolerance), and by ``BODY_SWEEP_TOL`` more: a cylinder that meets
    the stock goes deeper in it than ``shrink``, and one that goes deeper than ``shrink + 2
    BODY_SWEEP_TOL`` meets it."""
    tip = np.asarray(toolpath.tip, float)
    axis = np.asarray(toolpath.axis, float)
    pa = np.vstack([tip[:1], tip[:-1]])
    xa = np.vstack([axis[:1], axis[:-1]])
    out = []
    for t0, t1, rad, idx in _body_cylinders(toolpath.tool, tools):
        t0, rad = t0 + shrink + BODY_SWEEP_TOL, rad - shrink - BODY_SWEEP_TOL
        if len(idx) == 0 or rad <= 0 or t1 <= t0:
            continue
        R = np.full(len(idx), rad)
        # as a flat end reaching up to the cylinder's top: the chord of its foot, t0 up the axis, is
        # within t0 δ²/8 of the foot's arc, which the cylinder's own chord term (R + t1 - t0) δ²/8
        # leaves in the budget of F = t1
        pieces = turn_pieces(pa[idx], tip[idx], xa[idx], axis[idx], R, np.zeros(len(idx)), np.full(len(idx), t1),
                             BODY_SWEEP_TOL)
        src, p0, p1, x0, x1 = split_turns(pa[idx], tip[idx], xa[idx], axis[idx], pieces)
        src = idx[src]
        p0, p1 = p0 + t0 * x0, p1 + t0 * x1
        same = np.all(x0 == x1, axis=1) | (np.einsum("ij,ij->i", x0, x1) > math.cos(SAME_AXIS))
        x1[same] = x0[same]
        out.append(Moves(p0, p1, x0, x1, np.full(len(src), rad), np.zeros(len(src)), np.full(len(src), t1 - t0),
                         np.ones(len(src), np.int64), toolpath.rapid[src].astype(bool), src, np.ones(len(src), bool)))
    if not out:
        e3 = np.empty((0, 3))
        e = np.empty(0)
        return Moves(e3, e3, e3, e3, e, e, e, np.empty(0, np.int64), np.empty(0, bool), np.empty(0, np.int64),
                     np.empty(0, bool))
    return Moves.merge(*out)


def _body_cylinders(tool_of, tools):
    """``(t0, t1, radius, moves)`` for each shank and holder cylinder of the tools in use, with the
    indices of the moves ``(m,)`` made with that tool."""
    tool_of = np.asarray(tool_of)
    for t in np.unique(tool_of):
        idx = np.nonzero(tool_of == t)[0]
        for a, b, rad, cutting in tools[int(t)].cylinders():
            if not cutting and b > a:
                yield a, b, rad, idx


def turn_pieces(pa, pb, xa, xb, R, r, F, tol: float = SWEEP_TOL) -> np.ndarray:
    """How many pieces ``(k,)`` to split moves in (:func:`split_turns`, equal turns) so that a
    turning tool's cut stays within ``tol`` mm of its swept volume. A piece turning by δ of a
    move turning by θ: the ball centre's arc against its chord ((R + H) δ²/8), and the piece's own
    interpolation against the move's (the same axes, paired with the tips a little differently:
    at most D tan(θ/2) tan(δ/2) δ/2 at the tool's farthest point, D = hypot(F, R), from the tip;
    see :func:`split_turns`), at most δ = 0.5 rad; for flat and bull-nose cutters (searched over
    their poses) also the turn to ``MAX_TURN`` and the distance between sampled poses."""
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", xa, xb), -1.0, 1.0))
    angle[np.all(xa == xb, axis=1)] = 0.0  # arccos of a unit vector's square can be 1e-8
    H = np.maximum(0.0, F - 2 * r)
    # tan(δ/2)/δ <= 0.52 for δ <= 0.5
    pairing = np.hypot(F, R) * np.tan(0.5 * np.minimum(angle, math.radians(MAX_MOVE_TURN))) * 0.26
    chord = np.maximum(angle * np.sqrt(((R + H) / 8 + pairing) / tol), 2.0 * angle)
    # flat and bull-nose: the poses sampled along a piece are at most sqrt(8 R tol) apart, so a
    # line the search misses lies within tol of the side of the swept volume
    spacing = np.linalg.norm(pb - pa, axis=1) / (SEARCH_SAMPLES * np.sqrt(8 * R * tol))
    other = np.where(angle > 0, np.maximum(np.maximum(chord, angle / MAX_TURN), spacing), 1.0)
    return np.maximum(1, np.ceil(np.where(r >= R, chord, other) - 1e-9)).astype(np.int64)


def split_turns(pa, pb, xa, xb, pieces) -> tuple:
    """Moves ``pa -> pb (k, 3)``, axes ``xa -> xb (k, 3)`` (tip linear, axis by the normalised
    interpolation) split in ``pieces (k,)`` of equal turns: ``(source (n,), p0, p1, x0, x1 (n, 3))``.
    The piece ends are poses of the move: the axis at angle φ from ``xa`` of the move's θ is
    reached at t = sin φ / (sin φ + sin(θ - φ)) (where the normalised interpolation turns
    fastest, in the middle of a large turn, the pieces are shortest). A piece's own interpolation
    pairs the same axes with the tips a little differently: the move's weights on the piece's
    end axes are in the ratio q of the lengths of the interpolated (unnormalised) axes there, so
    it reaches the piece's fraction s where the piece is at s' (|s' - s| <= tanh(|ln q| / 4)),
    and |d ln length / dφ| = |tan(φ - θ/2)| <= tan(θ/2)."""
    src = np.repeat(np.arange(len(pa)), pieces)
    j = np.arange(len(src)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    n = pieces[src]
    theta = np.arccos(np.clip(np.einsum("ij,ij->i", xa[src], xb[src]), -1.0, 1.0))

    def at(f):
        phi = f * theta
        sa, sb = np.sin(phi), np.sin(theta - phi)
        t = np.where(theta > 1e-12, sa / np.where(sa + sb > 0, sa + sb, 1.0), f)
        t = np.where(f >= 1.0, 1.0, t)[:, None]
        x = xa[src] + t * (xb[src] - xa[src])
        return pa[src] + t * (pb[src] - pa[src]), x / np.linalg.norm(x, axis=1, keepdims=True)

    p0, x0 = at(j / n)
    p1, x1 = at((j + 1) / n)
    return src, p0, p1, x0, x1


def twist_strips(pa, pb, xa, xb, r, F) -> np.ndarray:
    """``(k,)`` strips for each move's ruled surface (the axis segment of a ball-end swept over the
    move), so that its twist (H θ⊥/4, θ⊥ the turn out of the plane of the centre's motion) stays
    within ``SWEEP_TOL`` a strip."""
    H = np.maximum(0.0, F - 2 * r)
    centre_move = (pb + r[:, None] * xb) - (pa + r[:, None] * xa)
    normal = np.cross(centre_move, xa)
    size = np.linalg.norm(normal, axis=1)
    normal = np.divide(normal, size[:, None], out=np.zeros_like(normal), where=size[:, None] > 1e-12)
    twist = H * np.abs(np.einsum("ij,ij->i", xb - xa, normal)) / (4 * SWEEP_TOL)
    return np.maximum(1, np.ceil(twist - 1e-9)).astype(np.int64)


def _boxes(m: Moves) -> np.ndarray:
    """``(k, 2, 3)`` boxes holding each move's swept volume: the hull of the core segment's ends
    (from c = tip + r x up H = F - 2r) widened by the disk and the corner radius, plus SWEEP_TOL
    (a shank's or holder's BODY_SWEEP_TOL)."""
    return _move_boxes(m.pa, m.pb, m.xa, m.xb, m.radius, m.corner, m.flutes,
                       np.where(m.body, BODY_SWEEP_TOL, SWEEP_TOL))


@numba.njit(cache=True)
def _move_boxes(pa, pb, xa, xb, radius, corner, flutes, tol):
    out = np.empty((pa.shape[0], 2, 3))
    for k in range(pa.shape[0]):
        r = corner[k]
        H = max(0.0, flutes[k] - 2.0 * r)
        for d in range(3):
            ca = pa[k, d] + r * xa[k, d]
            cb = pb[k, d] + r * xb[k, d]
            lo = min(ca, cb, ca + H * xa[k, d], cb + H * xb[k, d], ca + H * xb[k, d], cb + H * xa[k, d])
            hi = max(ca, cb, ca + H * xa[k, d], cb + H * xb[k, d], ca + H * xb[k, d], cb + H * xa[k, d])
            disk = (radius[k] - r) * max(math.sqrt(min(1.0, max(0.0, 1.0 - xa[k, d] ** 2))),
                                         math.sqrt(min(1.0, max(0.0, 1.0 - xb[k, d] ** 2))))
            ext = disk + r + tol[k]
            out[k, 0, d] = lo - ext
            out[k, 1, d] = hi + ext
    return out


def material_bounds(stock: Stock):
    """``(lo (3,), hi (3,))``: the box of the stock's material, mm (from the dexels along each axis;
    an empty stock gives lo > hi)."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for a in range(3):
        counts = stock.count[a]
        if counts.sum() == 0:
            continue
        first = stock.iv[a][stock.off[a][:-1][counts > 0]]
        last = stock.iv[a][stock.off[a][:-1][counts > 0] + counts[counts > 0] - 1]
        lo[a] = min(lo[a], first[:, 0].min())
        hi[a] = max(hi[a], last[:, 1].max())
    return lo, hi


def near_moves(moves: Moves, lo, hi):
    """``(moves, boxes)``: the moves less the shanks and holders that never come near the box
    ``lo, hi (3,)`` of the stock's material (they cannot meet it), and their boxes."""
    boxes = _boxes(moves)
    near = np.all((boxes[:, 0] <= hi) & (boxes[:, 1] >= lo), axis=1)
    if (moves.body & ~near).any():
        keep = ~moves.body | near
        moves = Moves(**{f: getattr(moves, f)[keep] for f in ("pa", "pb", "xa", "xb", "radius", "corner", "flutes",
                                                               "strips", "rapid", "source", "body")})
        boxes = boxes[keep]
    return moves, boxes


def move_groups(moves: Moves, boxes, kern=None) -> tuple:
    """``(group (k,), bound (g, 10), gboxes (g, 2, 3))``: consecutive cutting moves of one tool
    gathered under one bound (:func:`~meshmill.kernels.cpu_dexel.group_moves`, at most
    :data:`GROUP_MOVES` moves whose bound reaches at most :data:`GROUP_GROW` mm past their
    tools): each move's group (-1: none), each group's bound and box (world frame). (Shanks and
    holders are not grouped: their lines mostly end at the first test, and groups of them were
    no faster.) ``kern``: the :class:`~meshmill.kernels.backend.DexelKernels` (default the CPU's)."""
    kern = kern or DexelKernels("cpu")
    group = np.full(len(moves), -1, np.int64)
    bounds, gboxes, g0 = [np.empty((0, 10))], [np.empty((0, 2, 3))], 0
    cutting = np.nonzero(~moves.body)[0]
    tool = np.column_stack([moves.radius[cutting], moves.corner[cutting], moves.flutes[cutting]])
    change = np.r_[0, np.nonzero(np.any(tool[1:] != tool[:-1], axis=1))[0] + 1, len(cutting)]
    for start, stop in zip(change[:-1], change[1:]):  # the runs of one tool
        of = cutting[start:stop]
        if len(of) < 2:
            continue
        r = moves.corner[of][:, None]
        xa, xb = moves.xa[of], moves.xb[of]
        ca, cb = moves.pa[of] + r * xa, moves.pb[of] + r * xb
        H = np.maximum(0.0, moves.flutes[of] - 2 * moves.corner[of])
        # the ball centre off its chord (the normalised interpolation of the axes), and what a
        # cut may take past the tool's sweep
        cos = np.clip(np.einsum("ij,ij->i", xa, xb), -1.0, 1.0)
        sag = r[:, 0] * (1 - np.sqrt(0.5 * (1 + cos))) + SWEEP_TOL
        g, bound = kern.group_moves(ca, cb, xa, xb, sag, H, moves.radius[of], GROUP_GROW, GROUP_MOVES)
        inside = g >= 0
        if not inside.any():
            continue
        group[of[inside]] = g[inside] + g0
        first = np.r_[0, np.nonzero(np.diff(g[inside]))[0] + 1]
        b = boxes[of[inside]]
        gboxes.append(np.stack([np.minimum.reduceat(b[:, 0], first), np.maximum.reduceat(b[:, 1], first)], axis=1))
        bounds.append(bound)
        g0 += len(bound)
    return group, np.concatenate(bounds), np.concatenate(gboxes)


class DirectionMoves(NamedTuple):
    """What cutting the lines along one direction needs of the moves (``k`` of them, ``g`` groups),
    in the direction's frame (u, v, then the lines' axis): their ``kind (k,)`` bits, ``box (k, 6)``,
    ends ``pa, pb`` and axes ``xa, xb (k, 3)``, the ``chord (k, 6)`` and ``plane (k, 4)`` of
    :mod:`~meshmill.kernels.carve`, the moves of each tile (``tile_start``, ``tile_moves``), each
    move's ``group (k,)`` with the groups' ``gbound (g, 10)`` and ``gbox (g, 6)``, ``work
    (tiles,)`` the lines each tile's moves cover, added over them, and the moves' ``probe (k, 6)``
    where their load is gathered (:func:`~meshmill.simulation.load.move_probe`; else None)."""

    kind: np.ndarray
    box: np.ndarray
    pa: np.ndarray
    pb: np.ndarray
    xa: np.ndarray
    xb: np.ndarray
    chord: np.ndarray
    plane: np.ndarray
    tile_start: np.ndarray
    tile_moves: np.ndarray
    group: np.ndarray
    gbound: np.ndarray
    gbox: np.ndarray
    work: np.ndarray
    probe: np.ndarray | None = None


def _direction_moves(lo, n, step, a: int, moves: Moves, boxes, kern, groups=None, probe=None) -> DirectionMoves:
    """The moves as cutting the lines along ``a`` needs them, with the groups of
    :func:`move_groups` (``groups``, else made here) and ``probe (k, 6)`` (world frame; None: no
    load gathered)."""
    kind = (moves.rapid.astype(np.uint8) * RAPID) | (moves.body.astype(np.uint8) * BODY)
    u, v = (a + 1) % 3, (a + 2) % 3
    perm = [u, v, a]

    def in_frame(b):
        return np.ascontiguousarray(np.column_stack([b[:, 0, u], b[:, 1, u], b[:, 0, v], b[:, 1, v], b[:, 0, a],
                                                     b[:, 1, a]]))

    box = in_frame(boxes)
    pa, pb = np.ascontiguousarray(moves.pa[:, perm]), np.ascontiguousarray(moves.pb[:, perm])
    xa, xb = np.ascontiguousarray(moves.xa[:, perm]), np.ascontiguousarray(moves.xb[:, perm])
    chord, plane = kern.move_constants(pa, pb, xa, xb, moves.corner, moves.flutes)
    tile_start, tile_moves, work = kern.bin_moves(box, lo[u], lo[v], step, n[u], n[v])
    group, bound, gboxes = groups if groups is not None else move_groups(moves, boxes, kern)
    gbound = np.ascontiguousarray(bound[:, [u, v, a, 3 + u, 3 + v, 3 + a, 6 + u, 6 + v, 6 + a, 9]])
    if probe is not None:
        probe = np.ascontiguousarray(probe[:, [u, v, a, 3 + u, 3 + v, 3 + a]])
    return DirectionMoves(kind, box, pa, pb, xa, xb, chord, plane, tile_start, tile_moves, group, gbound,
                          in_frame(gboxes), work, probe)


def dealt(work, pieces: int) -> np.ndarray:
    """``(tiles,)``: the piece of each tile (-1: no work), dealt from the most ``work`` to the
    least, back and forth over the ``pieces``."""
    out = np.full(len(work), -1)
    busy = np.nonzero(work > 0)[0]
    order = busy[np.argsort(-work[busy], kind="stable")]
    pos = np.arange(len(order))
    turn, at = pos // pieces, pos % pieces
    out[order] = np.where(turn % 2 == 0, at, pieces - 1 - at)
    return out


def _cut_direction(stock: Stock, a: int, moves: Moves, boxes, kern, hit, rows=None, prepared=None,
                   alone: bool = True, load=None, tiles=None) -> None:
    """Cut the lines along ``a`` (those of the tile rows ``rows = (first, stop)`` along the axis
    after ``a``, which ``stock`` then holds ``alone`` for that direction, else among all its lines;
    or those of ``tiles = (tiles, combs, split)``, the rows ``combs (mod split)`` of each tile;
    default all) by the moves, in place; ``hit (k,)`` marks the moves that hit; ``prepared``: what
    :func:`_direction_moves` gives (else made here); where it has a probe, each move's load
    gathered in ``load`` (:meth:`~meshmill.kernels.backend.DexelKernels.new_load`)."""
    u, v = (a + 1) % 3, (a + 2) % 3
    nu, nv = int(stock.n[u]), int(stock.n[v])
    lu, lv = float(stock.lo[u]), float(stock.lo[v])
    kind, box, pa, pb, xa, xb, chord, plane, tile_start, tile_moves, group, gbound, gbox, _, probe = (
        prepared or _direction_moves(stock.lo, stock.n, stock.step, a, moves, boxes, kern))
    if tiles is None:
        busy = np.nonzero(np.diff(tile_start))[0]
        tiles = busy, np.zeros(len(busy), np.int64), 1
    tiles, combs, split = tiles
    tv = (nv + TILE - 1) // TILE
    row0 = 0
    if rows is not None:
        inside = (tiles // tv >= rows[0]) & (tiles // tv < rows[1])
        tiles, combs = tiles[inside], combs[inside]
        row0 = rows[0] * TILE if alone else 0
    spread = np.random.default_rng(0).permutation(len(tiles))  # the busy tiles over the threads
    tiles, combs = tiles[spread], combs[spread]
    todo = np.zeros(0, np.int64)  # every line of the tiles, then the lines that ran out of room (from where)
    while len(tiles):
        redo = np.zeros(len(stock.count[a]), np.int64)
        kern.cut_tiles(lu, lv, stock.step, nu, nv, stock.iv[a], stock.off[a], stock.count[a], tiles, combs, split,
                       tile_start, tile_moves, pa, pb, xa, xb, moves.radius, moves.corner, moves.flutes, moves.strips,
                       chord, plane, box, kind, group, gbound, gbox, RAPID_CUT, hit, todo, redo, row0, probe, load)
        full = np.nonzero(redo)[0]
        if len(full):
            _grow(stock, a, full)
        tiles = np.unique(((full // nv + row0) // TILE) * tv + (full % nv) // TILE)
        combs, split, todo = np.zeros(len(tiles), np.int64), 1, redo


def hits(moves: Moves, hit) -> dict:
    """The tool-path points whose moves ``hit (k,)``: rapids cutting, bodies colliding, feeds in material."""
    rapid_cuts = np.unique(moves.source[(hit == 1) & ~moves.body & moves.rapid])
    collisions = np.unique(moves.source[(hit == 1) & moves.body])
    in_material = np.unique(moves.source[(hit == 1) & ~moves.body & ~moves.rapid])
    return {"rapid_cuts": [int(i) for i in rapid_cuts], "collisions": [int(i) for i in collisions],
            "in_material": in_material}


def cut(stock: Stock, moves: Moves, progress=None, device="cpu", cluster=None, load: int = 0) -> dict:
    """Remove every move's swept volume from ``stock`` (in place) on ``device`` (``"cpu"`` or
    ``"cuda"``); body moves (shank, holder) remove nothing. Returns ``{"rapid_cuts": sorted
    tool-path point indices whose rapid move cut material, "collisions": those whose shank or
    holder met material, "in_material": those whose feed move removed material (more than
    :data:`RAPID_CUT` of some dexel; the others cut air), "seconds": ...}``. ``cluster``: a
    ``distributed.Client`` whose workers cut blocks of tile rows of each direction (the same
    result). ``load``: the number of tool-path points whose moves' load is also gathered (what
    each removed, how deep and how wide: ``"load"``, the :class:`~meshmill.simulation.load.
    RemovedByMove` of those points; 0: not gathered)."""
    from .load import RemovedByMove, move_probe, reduce_load

    t0 = time.perf_counter()
    moves, boxes = near_moves(moves, *material_bounds(stock))
    hit = np.zeros(len(moves), np.uint8)
    probe = move_probe(moves) if load else None
    gathered = []
    if cluster is not None:
        gathered = _cut_on(cluster, stock, moves, boxes, hit, progress, device, probe)
    else:
        kern = DexelKernels(device)
        groups = move_groups(moves, boxes, kern)
        prepared = [_direction_moves(stock.lo, stock.n, stock.step, a, moves, boxes, kern, groups, probe)
                    for a in range(3)]
        # the tiles (independent) in CUT_PIECES pieces alike, so that the time the first pieces
        # take tells the time left: each tile in PIECE_COMBS combs of its rows, dealt out from the
        # most lines their moves cover to the least, back and forth (a heavy tile's combs go to
        # pieces one after the other); the share done by those lines
        work = [np.repeat(p.work, PIECE_COMBS) / PIECE_COMBS for p in prepared]
        piece = [dealt(w, CUT_PIECES) for w in work]
        meter = Meter(progress, "cutting lines along X, Y and Z", sum(float(w.sum()) for w in work))
        per = [kern.new_load(len(moves)) if load else None for _ in range(3)]
        for k in range(CUT_PIECES):
            for a in range(3):
                some = np.nonzero(piece[a] == k)[0]  # (tile, comb) = divmod(unit, PIECE_COMBS)
                if len(some):
                    _cut_direction(stock, a, moves, boxes, kern, hit, None, prepared[a], False, per[a],
                                   (some // PIECE_COMBS, some % PIECE_COMBS, PIECE_COMBS))
            meter.done(sum(float(work[a][piece[a] == k].sum()) for a in range(3)))
        if load:
            gathered = [reduce_load(p) for p in per]
    out = {**hits(moves, hit), "seconds": round(time.perf_counter() - t0, 4)}
    if load:
        out["load"] = RemovedByMove.of(moves, gathered, stock.step, load, probe)
    return out


def cut_rows(shared: dict, piece):
    """One block of tile rows of one direction cut on a worker (:func:`meshmill.cluster.run_pieces`):
    ``piece = (a, (first, stop) tile rows, start, iv)`` the block's lines (CSR); ``shared``: the
    ``moves``, their ``boxes``, the lattice ``lo, n, step``, the ``device``. Returns the block's
    lines cut (CSR) and the moves' hits."""
    a, rows, start, iv = piece
    return cut_lines(shared, a, rows, start, iv)


def cut_lines(shared: dict, a: int, rows, start, iv):
    """``(start, iv, hit)``: the lines along ``a`` of the tile rows ``rows = (first, stop)`` (CSR
    ``start, iv``) cut by the ``moves`` of ``shared`` (with their ``boxes``, the lattice ``lo, n,
    step`` and the ``device``; scattered to a worker, whose moves in each direction's frame are
    made once, :func:`meshmill.cluster.worker_cached`), and ``hit (k,)`` the moves that hit."""
    from ..cluster import worker_cached

    from .load import reduce_load

    moves, boxes = shared["moves"], shared["boxes"]
    n = shared["n"]
    stock = Stock(lo=shared["lo"], step=shared["step"], n=n, iv=[None] * 3, off=[None] * 3, count=[None] * 3)
    stock.iv[a], stock.off[a], stock.count[a] = _with_room(start, iv)  # the block's lines alone
    hit = np.zeros(len(moves), np.uint8)
    kern = DexelKernels(shared["device"])
    groups = worker_cached(shared, "groups", lambda: move_groups(moves, boxes, kern))  # once for the 3 directions
    probe = shared.get("probe")
    prepared = worker_cached(shared, f"moves {a}", lambda: _direction_moves(shared["lo"], n, shared["step"], a, moves,
                                                                          boxes, kern, groups, probe))
    load = kern.new_load(len(moves)) if probe is not None else None
    _cut_direction(stock, a, moves, boxes, kern, hit, rows, prepared, load=load)
    s, out = compact_lines(stock.iv[a], stock.off[a], stock.count[a])
    return s, out, hit, None if load is None else reduce_load(load)


def _with_room(start, iv):
    """``(iv, off, count)`` of CSR lines ``(start, iv)`` with :func:`slack` spare slots a line
    with material (the intervals as they are)."""
    count = np.diff(start).astype(np.int64)
    off = np.zeros(len(count) + 1, np.int64)
    np.cumsum(count + np.where(count > 0, slack(count), 0), out=off[1:])
    out = np.zeros((off[-1], 2))
    out[np.repeat(off[:-1], count) + (np.arange(len(iv)) - np.repeat(start[:-1], count))] = iv
    return out, off, count


def _cut_on(client, stock: Stock, moves: Moves, boxes, hit, progress, device, probe=None) -> list:
    """:func:`cut` of ``stock`` (replaced in place) by blocks of tile rows on ``client``'s workers;
    with ``probe``, each direction's load of the moves (:func:`~meshmill.simulation.load.reduce_load`)."""
    from .load import merge_loads

    from ..cluster import PIECES_PER_WORKER, check_workers, run_pieces, workers

    pieces, peak = [], 0.0
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        nv = int(stock.n[v])
        tile_rows = (int(stock.n[u]) + TILE - 1) // TILE
        for r0, r1 in ranges(tile_rows, PIECES_PER_WORKER * workers(client)):
            l0, l1 = r0 * TILE * nv, min(int(stock.n[u]), r1 * TILE) * nv
            start, iv = compact_lines(stock.iv[a], stock.off[a][l0:l1 + 1], stock.count[a][l0:l1])
            pieces.append((a, (r0, r1), start, iv))
            # a worker holds the block's lines: offsets and counts, intervals with room (doubled while
            # a line grows), and what it returns
            c = stock.count[a][l0:l1]
            peak = max(peak, 16.0 * (l1 - l0) + 2 * 16.0 * (len(iv) + slack(c) * np.count_nonzero(c)) + 24.0 * len(iv))
    # and the moves with, per direction it cuts, their frame, constants, boxes and tiles
    check_workers(client, peak + MOVE_BYTES * len(moves), f"cutting {len(moves):,} moves in blocks of dexel lines",
                  "use more workers, or a coarser step")
    pieces.sort(key=lambda p: -len(p[3]))  # the largest blocks first: the slow ones do not come last
    shared = dict(moves=moves, boxes=boxes, lo=stock.lo, n=stock.n, step=stock.step, device=device, probe=probe)
    done = run_pieces(client, cut_rows, shared, pieces, progress, "cutting")
    for a in range(3):
        blocks = sorted((rows, s, iv) for (d, rows, *_), (s, iv, _, _) in zip(pieces, done) if d == a)
        stock.iv[a], stock.off[a], stock.count[a] = _with_room(*join_lines([(s, iv) for _, s, iv in blocks]))
    for _, _, h, _ in done:
        hit |= h
    if probe is None:
        return []
    return [merge_loads([ld for (d, *_), (*_, ld) in zip(pieces, done) if d == a]) for a in range(3)]
