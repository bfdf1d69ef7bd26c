"""G-code for a real machine from a CL tool path (``meshmill post``).

:func:`post_program` writes a :class:`~meshmill.toolpath.model.Toolpath` as the lines of an NC
program for a :class:`~meshmill.machine.model.Machine`, in the format of its ``[gcode]`` section
(:class:`~meshmill.machine.config.GcodeFormat`). Units: mm, degrees, seconds; F in mm/min (G94)
or 1/min (G93).

Three modes, by the machine's chain and ``tcp``:

- **3-axis**: the tool tip is programmed (the control adds the tool length: ``tool_length``, e.g.
  ``G43 H1``). A tilted tool axis is refused.
- **5-axis joints** (table-table or head-table, no TCP): the joints of every pose come from
  :func:`meshmill.machine.motion.inverse`. The control moves the joints linearly from block to
  block, so where the rotaries turn the tip leaves the straight CL move; feed moves are split
  (:class:`_Linearisation`) until the tip of the joint-linear motion stays within the tolerance of
  the CL segment; a program that no split keeps within it is refused (:func:`_stray_error`). A
  rapid that turns a rotary is linearised too and written as G1 at the rapid rate (pure linear
  rapids stay G0). Feeds in G93 inverse time where ``gcode.inverse_time`` (F = 1 / the block's
  minutes), else G94 with the tip's feed. table-table: the tool stays vertical, so the tool length
  is the control's (``tool_length``); head-table: the program is computed for the tool length (tip to
  the spindle's gauge line: the tool's ``gauge_length + holder_length``), said in a comment, and no
  tool-length compensation is switched on.
- **5-axis TCP** (``tcp``, or the machine's ``gcode.tcp`` text): the tool tip in work coordinates
  and the rotary angles; the control does the kinematics and the interpolation, switched on with
  ``gcode.tcp`` (in place of ``tool_length``) after each tool change and off with ``gcode.tcp_off``
  before the next one and at the end. Feeds G94 (the tip's feed); nothing is linearised.

Program layout: the ``start`` lines; a comment naming the machine; per tool: (after the first tool:
the ``retract`` lines (the tool up to the machine's Z home), ``M5``, ``coolant_off``, ``tcp_off`` in TCP mode, and ``M0`` where the machine has no
``tool_change`` text, so that the operator changes the tool), a comment with the tool, ``tool_change``,
``tool_length`` (or the TCP text, or the head-table comment), ``spindle`` (S: the tool's ``rpm``, else ``gcode.rpm``),
``coolant_on``; the first pose of each tool is reached by ``G0`` in two blocks, every axis but Z
first, then Z (the tool comes from the tool change, which leaves it high); then one block a move.
Where the control moves G0 axis by axis (``gcode.rapid = "dogleg"``), a rapid that moves more
than one axis is written as G1 at the rapid rate, so that the tool follows the straight line the
CL path was verified along (a dog-leg would cut the corner: the first positioning of a tool, from
the tool change, excepted).
``G94`` before a tool change and the ``end`` lines where G93 is on. Motion is modal: ``G0``/``G1``
and each axis word are written when their text changes (fixed decimals: ``gcode.decimals`` for X Y
Z, ``angle_decimals`` for A B C; never ``-0.000``), F when it changes (G94, one decimal) or on every
feed block (G93, as the control needs, ``decimals`` places). Blocks that move no axis (by the
written text) are left out. ``line_numbers``: N1, N2, ... on every line but ``%`` and the ``O``
number. Comments go through ``gcode.comment`` with ``(`` ``)`` turned into ``[`` ``]`` and ``%``
dropped, so that they cannot end a comment or the program early.

Feeds (mm/s per move, :func:`post_program`'s ``feed``): as given, the machine's nominal feed where
none is. The first move of each tool is a positioning ``G0`` whatever the CL says (the tool comes
from the tool change, not from the previous pose).

Limits: every written block is checked against the machine's travel (``[axes]``), in program
coordinates (the work zero at the machine's zero): the first block out of range is an
:class:`~meshmill.errors.InputError` naming the CL move and line, the axis, the value and the travel.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from ..tolerances import GOUGE_TOL
from ..toolpath.cldata import MAX_COORDINATE
from .kinematics import VERTICAL_TOLERANCE, AxisLimitError, angle_step, forward, inverse, machine_xyz

SAMPLES = 16  # points inside a block where the joint-linear tip is compared with the CL segment
MAX_DEPTH = 10  # one CL move is halved at most this deep (1024 blocks) ...
DEEPEST = 16  # ... and on to this depth where a halving still leaves no more than FALLS of the deviation
FALLS = 0.75
GROSS_STRAY = 1.0  # mm: a block that still strays this far is blamed on the pole or the rotaries' travel
POLE_REACH = 10.0  # within this many pole cones (chain.singular) a midpoint may keep C from swinging
POLE_WARNING_DEG = 2.0  # a refused move whose axis passes this near the pole is blamed on the pole
MIN_BLOCK_S = 0.006  # s: the shortest G93 block time written (F <= 10000 / min; one interpolation cycle or so)
CURVE_PIECES = 8  # the path of the flutes' top in a CL move (a curve) is checked as this many segments
SWING_SAMPLES = 65  # poses of a rotary jump checked for its lowest tip
SWING_ROUNDS = 8  # retracts raised at most this many times until the jump clears
DEVIATION_CHUNK = 8192  # blocks checked per call of forward (memory: chunk x (SAMPLES + 2) poses)
SWING_MARGIN = 5.0  # mm: a clearance suggested for a swing above a path top that no rapid travels at
TCP_HINT = 'the machine\'s [gcode] tcp text, e.g. tcp = "G43.4 H{number}"'  # how to post for TCP
SPINDLE_STOP = "M5"  # RS-274, the same in every dialect: before a tool change
OPERATOR_STOP = "M0"  # a machine without a tool changer pauses for the operator to change the tool


@dataclass
class _Run:
    """The blocks of one tool, in order. ``joints (b, n)`` the program words' values as written
    (machine.axes order, mm and degrees); ``rapid (b,)`` G0; ``feed (b,)`` the tip's feed mm/s
    (NaN for G0); ``tip_length (b,)`` mm the tip travels along the CL path in the block; ``move
    (b,)`` the CL move (0-based) the block belongs to; ``added (b,)`` inserted by linearisation;
    ``rewind (b,)`` part of a retract-unwind-return."""

    tool: int
    joints: np.ndarray
    rapid: np.ndarray
    feed: np.ndarray
    tip_length: np.ndarray
    move: np.ndarray
    added: np.ndarray
    rewind: np.ndarray


@dataclass
class _Program:
    """A program's blocks before they are written: the ``mode`` ("3-axis", "5-axis joints",
    "5-axis TCP"), one :class:`_Run` per tool, and what linearisation and the rotaries' jumps did:
    ``blocks_added``, ``largest`` mm (the largest deviation of a block from its CL move),
    ``rewinds``, ``clearance`` (the Z mm the tool stays above where the rotaries jump; None on a
    3-axis machine) and their ``warnings``."""

    mode: str
    runs: list
    blocks_added: int = 0
    largest: float = 0.0
    rewinds: int = 0
    clearance: float | None = None
    warnings: list = field(default_factory=list)

    @property
    def tcp(self) -> bool:
        return self.mode == "5-axis TCP"

    def inverse_time(self, machine) -> bool:
        """Whether feed blocks are written in G93 (5-axis joints mode, where the machine asks so)."""
        return self.mode == "5-axis joints" and machine.gcode.inverse_time


def format_number(value, decimals) -> str:
    """``value`` with ``decimals`` places, never a negative zero ("-0.0000" is "0.0000")."""
    text = f"{value:.{decimals}f}"
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text


def _clean(text):
    """``text`` on one line without the characters that would end a comment or the program early:
    ``(`` ``)`` become ``[`` ``]``, ``%`` is dropped."""
    return " ".join(text.replace("(", "[").replace(")", "]").replace("%", "").split())


def _fill(template, tool, rpm):
    """A tool's ``[gcode]`` text (checked when the machine file was read) with ``{number}``,
    ``{name}`` (:func:`_clean`, ``;`` as ``,``) and ``{rpm}`` (rev/min, an integer) filled in."""
    return template.format(number=tool.number, name=_clean(tool.name).replace(";", ","), rpm=int(round(rpm)))


def _comment(gcode, text):
    return gcode.comment.format(text=_clean(text))


def _where(tp, move):
    """``move N (CL line L)`` for error messages, N 1-based."""
    line = int(tp.line[move])
    return f"move {move + 1}" + (f" (CL line {line})" if line > 0 else "")


def _tool_runs(tool):
    """``[(tool, first, stop)]``: the stretches of ``tool (k,)`` with one tool, in order."""
    tool = np.asarray(tool)
    first = np.flatnonzero(np.r_[True, tool[1:] != tool[:-1]])
    stop = np.r_[first[1:], len(tool)]
    return [(int(tool[a]), int(a), int(b)) for a, b in zip(first, stop)]


def _move_feeds(feed, k, machine):
    """Feed (k,) mm/s per move: ``feed`` (None, a number or (k,) with NaN where none is
    programmed), the machine's nominal feed where it gives none."""
    nominal = machine.motion.feed
    if feed is None:
        return np.full(k, nominal)
    out = np.broadcast_to(np.asarray(feed, np.float64), (k,)).copy()
    given = ~np.isnan(out)
    if not (np.isfinite(out[given]).all() and (out[given] > 0).all()):
        raise InputError("feed must be a positive finite number of mm/s (or NaN: the machine's feed)", "feed")
    out[~given] = nominal
    return out


def _round_joints(joints, gcode):
    """``joints (..., n)`` rounded as the program writes them (linear ``decimals``, rotary
    ``angle_decimals``)."""
    out = np.array(joints, np.float64)
    out[..., :3] = np.round(out[..., :3], gcode.decimals)
    out[..., 3:] = np.round(out[..., 3:], gcode.angle_decimals)
    return out


def _great_circle(a0, a1, s):
    """Unit axes ``(m, 3)`` at fractions ``s (m,)`` of the great circle from ``a0 (m, 3)`` to
    ``a1 (m, 3)`` (unit vectors; not opposite)."""
    a0, a1 = np.atleast_2d(a0), np.atleast_2d(a1)
    s = np.asarray(s, np.float64).reshape(-1, 1)
    cos = np.clip(np.einsum("ij,ij->i", a0, a1), -1.0, 1.0)[:, None]
    angle = np.arccos(cos)
    small = angle < 1e-9
    sin = np.where(small, 1.0, np.sin(angle))
    w0 = np.where(small, 1.0 - s, np.sin((1.0 - s) * angle) / sin)
    w1 = np.where(small, s, np.sin(s * angle) / sin)
    out = w0 * a0 + w1 * a1
    return out / np.linalg.norm(out, axis=1, keepdims=True)


# --- 3-axis ----------------------------------------------------------------------------------------

def _three_axis_runs(tp, feed, machine):
    """One :class:`_Run` per tool: the tips as they are; a tilted axis is an InputError."""
    tilt = np.arccos(np.clip(tp.axis[:, 2], -1.0, 1.0))
    bad = np.flatnonzero(np.linalg.norm(tp.axis - (0.0, 0.0, 1.0), axis=1) > VERTICAL_TOLERANCE)
    if len(bad):
        i = int(bad[0])
        a = tp.axis[i]
        raise InputError(f"{_where(tp, i)}: the tool axis ({a[0]:.4f}, {a[1]:.4f}, {a[2]:.4f}) is tilted "
                         f"{math.degrees(tilt[i]):.3f} deg from +Z, and {machine.name} is a 3-axis machine: "
                         f"post this path for a 5-axis machine, e.g. machine table-table-ac ({len(bad)} tilted "
                         "move(s))", "machine")
    runs = []
    for tool, a, b in _tool_runs(tp.tool):
        rapid = tp.rapid[a:b].copy()
        rapid[0] = True
        tip = tp.tip[a:b]
        length = np.r_[0.0, np.linalg.norm(np.diff(tip, axis=0), axis=1)]
        zeros = np.zeros(b - a, bool)
        joints = _round_joints(tip, machine.gcode)
        straight = rapid & _dogleg_corner(joints, machine)
        rapid &= ~straight
        f = np.where(straight, machine.motion.rapid, feed[a:b])
        runs.append(_Run(tool, joints, rapid, np.where(rapid, np.nan, f), length, np.arange(a, b), zeros, zeros.copy()))
    return runs


def _dogleg_corner(joints, machine, before=None):
    """``(m,)`` bool: the moves from ``before (m, n)`` (default: the previous row; the first row
    False) to ``joints (m, n)`` that move more than one axis, where the machine's G0 is a dog-leg
    (``gcode.rapid``): written as G0 they would leave the straight line."""
    joints = np.asarray(joints)
    if machine.gcode.rapid != "dogleg":
        return np.zeros(len(joints), bool)
    before = np.r_[joints[:1], joints[:-1]] if before is None else before
    moved = joints != before  # rounded as written: any change is in the text
    return np.count_nonzero(moved, axis=1) > 1


# --- 5-axis ----------------------------------------------------------------------------------------

def _solve(machine, tp, first, tip, axis, tool_length, tcp, start, within=False):
    """:func:`~meshmill.machine.motion.inverse` of the poses ``tip (m, 3)``, ``axis (m, 3)``
    of CL moves ``first``, ``first + 1``, ... (``within``: all of them poses within CL move
    ``first``), each solved next to the one before: ``(joints (m, n) rounded as written, rewound
    (m,))``; a pose beyond the travel is an InputError naming its CL move."""
    lines = np.repeat(tp.line[first:first + 1], len(tip)) if within else tp.line[first:first + len(tip)]
    try:
        joints, rewound = inverse(machine, tip, axis, tool_length=tool_length, tcp=tcp, start=start, lines=lines)
    except AxisLimitError as exc:
        value = format_number(exc.value, machine.gcode.decimals if exc.axis in "XYZ" else machine.gcode.angle_decimals)
        raise InputError(f"{_where(tp, first if within else first + exc.move)}: {exc.axis} {value} is beyond its "
                         f"travel [{exc.travel[0]:g}, {exc.travel[1]:g}] on {machine.name}") from None
    return _round_joints(joints, machine.gcode), np.asarray(rewound, bool)


class _Linearisation:
    """Splits the feed moves of one tool until the joint-linear motion stays within ``tolerance``
    mm of the CL move at the tip and ``flutes`` mm up the tool axis (the top of the cutting part:
    where the axis strays, the flutes sweep wider than the CL move's), the CL move being the tip
    and that point each on a straight line. Joints are compared as written (rounded), so the
    measured deviation is the program's."""

    def __init__(self, machine, tp, tool_length, tcp, tolerance, flutes, rapid=False):
        self.machine, self.tp, self.rapid = machine, tp, rapid
        self.tool_length, self.tcp, self.tolerance, self.flutes = tool_length, tcp, tolerance, flutes

    def deviation(self, ja, jb, p0, p1, a0, a1, s0=None, s1=None):
        """Largest distance (m,) mm of the joint-linear motion ``ja (m, n)`` -> ``jb (m, n)`` (at
        its ends and SAMPLES points between) from the CL move: of its tip from the segments ``p0
        (m, 3)`` -> ``p1 (m, 3)``, and of its point ``flutes`` up the axis from that point's path
        in the CL move (the tip on the segment, the axis on the great circle from ``a0`` to ``a1``
        (m, 3): a curve, taken as a polyline of ``CURVE_PIECES`` between the fractions ``s0`` and
        ``s1`` (m,) of the move that the motion stands for; default the whole move)."""
        s0 = np.zeros(len(ja)) if s0 is None else np.asarray(s0, np.float64)
        s1 = np.ones(len(ja)) if s1 is None else np.asarray(s1, np.float64)
        s = np.linspace(0.0, 1.0, SAMPLES + 2)
        out = np.empty(len(ja))
        for c in range(0, len(ja), DEVIATION_CHUNK):
            a, b = ja[c:c + DEVIATION_CHUNK], jb[c:c + DEVIATION_CHUNK]
            joints = a[:, None, :] + s[None, :, None] * (b - a)[:, None, :]
            tip, axis = forward(self.machine, joints.reshape(-1, a.shape[1]), self.tool_length, self.tcp)
            tip, axis = tip.reshape(len(a), len(s), 3), axis.reshape(len(a), len(s), 3)
            q0, q1 = p0[c:c + DEVIATION_CHUNK], p1[c:c + DEVIATION_CHUNK]
            lo, hi = s0[c:c + DEVIATION_CHUNK, None], s1[c:c + DEVIATION_CHUNK, None]
            g = lo + np.linspace(0.0, 1.0, CURVE_PIECES + 1)[None, :] * (hi - lo)  # (m, pieces + 1)
            curve = (q0[:, None, :] + g[..., None] * (q1 - q0)[:, None, :]
                     + self.flutes * _great_circle_path(a0[c:c + DEVIATION_CHUNK], a1[c:c + DEVIATION_CHUNK], g))
            upper = tip + self.flutes * axis
            off = np.min([_off_segment(upper, curve[:, k], curve[:, k + 1]) for k in range(CURVE_PIECES)], axis=0)
            out[c:c + DEVIATION_CHUNK] = np.maximum(_peak(_off_segment(tip, q0, q1)), _peak(off))
        return out

    def split(self, moves, a0, a1, j0, j1, strict=False):
        """Poses inserted into the CL feed moves ``moves (r,)`` (tips ``tp.tip[move - 1]`` ->
        ``tp.tip[move]``, unit axes ``a0`` -> ``a1`` (r, 3)) whose joints ``j0`` -> ``j1`` (r, n)
        stray beyond the tolerance: per move ``(s (q,), joints (q, n), largest)`` in order, ``s``
        the fractions of the move (see :meth:`_midpoints`, ``strict`` passed on), ``largest`` mm
        the largest deviation of its blocks. Each half is split again while it strays, MAX_DEPTH
        deep, and on to DEEPEST while a halving still leaves no more than ``FALLS`` of its half's
        deviation. The halvings of all moves are measured together, one depth at a time."""
        inserted = [[] for _ in moves]
        largest = np.zeros(len(moves))
        # open intervals: (index into moves, s0, s1, joints at s0, joints at s1, deviation)
        open_ = [(k, 0.0, 1.0, j0[k], j1[k], np.inf) for k in range(len(moves))]
        for depth in range(1, DEEPEST + 1):
            if not open_:
                break
            ks = np.array([o[0] for o in open_])
            ja = np.array([o[3] for o in open_])
            jb = np.array([o[4] for o in open_])
            lo, hi = np.array([o[1] for o in open_]), np.array([o[2] for o in open_])
            mid = 0.5 * (lo + hi)
            jm = self._midpoints(moves[ks], a0[ks], a1[ks], mid, ja, jb, strict)
            p0, p1 = self.tp.tip[moves[ks] - 1], self.tp.tip[moves[ks]]
            both = self.deviation(np.r_[ja, jm], np.r_[jm, jb], np.r_[p0, p0], np.r_[p1, p1],
                                  np.r_[a0[ks], a0[ks]], np.r_[a1[ks], a1[ks]], np.r_[lo, mid], np.r_[mid, hi])
            left, right = both[:len(open_)], both[len(open_):]
            still = []
            for (k, s0, s1, ja_, jb_, whole), sm, j, dl, dr in zip(open_, mid.tolist(), jm, left, right):
                inserted[k].append((sm, j))
                for d, half in ((dl, (k, s0, sm, ja_, j, dl)), (dr, (k, sm, s1, j, jb_, dr))):
                    if d > self.tolerance and (depth < MAX_DEPTH or (depth < DEEPEST and d <= FALLS * whole)):
                        still.append(half)
                    else:
                        largest[k] = max(largest[k], d)
            open_ = still
        out = []
        for pieces, worst in zip(inserted, largest):
            pieces.sort(key=lambda sj: sj[0])
            out.append((np.array([sj[0] for sj in pieces]), np.array([sj[1] for sj in pieces]), float(worst)))
        return out

    def _midpoints(self, moves, a0, a1, sm, ja, jb, strict=False):
        """The joints (q, n) at fractions ``sm (q,)`` of CL moves ``moves (q,)`` (unit axes ``a0``
        -> ``a1`` (q, 3)), the middles of the intervals whose ends are ``ja`` and ``jb`` (q, n):
        the rotaries halfway between them and X Y Z putting the tip on the CL segment, when that
        keeps the axis within half the tolerance (at the flutes' top), or, within POLE_REACH pole
        cones of the pole and not ``strict``, within the cone's angle (``chain.singular``, the axis
        error the pole hold allows), of the great circle from ``a0`` to ``a1`` (always for a rapid,
        whose axis is free); else the pose with its axis on the great circle, solved next to ``ja``
        (near the pole of the rotaries the first keeps C from swinging where the axis hardly
        moves; ``strict`` where that left the flutes astray)."""
        p0, p1 = self.tp.tip[moves - 1], self.tp.tip[moves]
        target = p0 + sm[:, None] * (p1 - p0)
        jm = 0.5 * (ja + jb)
        tip, axis = forward(self.machine, jm, self.tool_length, self.tcp)
        jm = _retract_joints(self.machine, jm, target - tip, self.tool_length, self.tcp)
        if self.rapid:
            return jm
        want = _great_circle(a0, a1, sm)
        off = np.linalg.norm(axis - want, axis=1)  # rad, about
        singular = self.machine.chain.singular
        near_pole = np.arccos(np.minimum(1.0, np.abs(want[:, 2]))) < POLE_REACH * singular
        held = (self.flutes * off <= 0.5 * self.tolerance) | (near_pole & (not strict) & (off <= singular))
        for k in np.flatnonzero(~held):
            jm[k] = _solve(self.machine, self.tp, int(moves[k]), target[k:k + 1], want[k:k + 1], self.tool_length,
                           self.tcp, ja[k])[0][0]
        return jm


def _peak(samples):
    """The largest value (m,) of smooth functions sampled evenly, ``samples (m, q)``: the largest
    sample raised to the vertex of the parabola through it and its two neighbours, so that a peak
    between samples is not missed (what remains is third order in the spacing)."""
    rows = np.arange(len(samples))
    largest = np.argmax(samples, axis=1)
    k = np.clip(largest, 1, samples.shape[1] - 2)
    before, top, after = samples[rows, k - 1], samples[rows, k], samples[rows, k + 1]
    bend = 2.0 * top - before - after  # >= |after - before| at an inner largest sample: the rise <= bend / 8
    inner = (largest == k) & (bend > 0.0)
    rise = np.where(inner, (after - before) ** 2 / (8.0 * np.where(inner, bend, 1.0)), 0.0)
    return samples[rows, largest] + rise


def _retract_joints(machine, joints, displacement, tool_length, tcp):
    """Joints (n,) or (q, n) as written that move the tip of ``joints`` by ``displacement`` ((3,)
    or (q, 3)) mm in work coordinates with the rotaries held: for fixed rotaries the tip is affine
    in X Y Z, so one linear solve with forward's X Y Z columns is exact."""
    joints = np.asarray(joints, np.float64)
    rows = np.atleast_2d(joints)
    probe = np.repeat(rows[:, None], 4, axis=1)  # (q, 4, n)
    probe[:, 1:, :3] += np.eye(3)
    tip, _ = forward(machine, probe.reshape(-1, rows.shape[1]), tool_length, tcp)
    tip = tip.reshape(len(rows), 4, 3)
    out = rows.copy()
    step = np.atleast_2d(displacement)
    out[:, :3] += np.linalg.solve((tip[:, 1:] - tip[:, :1]).transpose(0, 2, 1), step[..., None])[..., 0]
    out = _round_joints(out, machine.gcode)
    return out if joints.ndim == 2 else out[0]


class _Blocks:
    """A :class:`_Run` being built, block by block."""

    def __init__(self, tool):
        self.tool = tool
        self.rows = []

    def add(self, joints, rapid, feed, tip_length, move, added=False, rewind=False):
        self.rows.append((joints, rapid, np.nan if rapid else feed, tip_length, move, added, rewind))

    def run(self) -> _Run:
        joints, rapid, feed, tip_length, move, added, rewind = zip(*self.rows)
        return _Run(self.tool, np.array(joints), np.array(rapid), np.array(feed), np.array(tip_length),
                    np.array(move), np.array(added), np.array(rewind))


def _great_circle_path(a0, a1, g):
    """Unit axes ``(m, q, 3)`` at fractions ``g`` ((q,), or (m, q) per row) of the great circles
    from ``a0`` to ``a1`` ``(m, 3)`` (slerp; the straight mix, normalised, where they nearly agree)."""
    cos = np.clip(np.einsum("ij,ij->i", a0, a1), -1.0, 1.0)
    angle = np.arccos(cos)[:, None]
    sin = np.sin(angle)
    safe = sin > 1e-9
    g = np.broadcast_to(g, (len(a0), np.shape(g)[-1]))
    w0 = np.where(safe, np.sin((1.0 - g) * angle) / np.where(safe, sin, 1.0), 1.0 - g)
    w1 = np.where(safe, np.sin(g * angle) / np.where(safe, sin, 1.0), g)
    out = w0[..., None] * a0[:, None, :] + w1[..., None] * a1[:, None, :]
    return out / np.linalg.norm(out, axis=2, keepdims=True)


def _off_segment(points, q0, q1):
    """Distance ``(m, s)`` of ``points (m, s, 3)`` from the segments ``q0 (m, 3)`` -> ``q1 (m, 3)``."""
    rel = points - q0[:, None, :]
    d = q1 - q0
    dd = np.einsum("ij,ij->i", d, d)
    t = np.clip(np.einsum("iqj,ij->iq", rel, d) / np.where(dd > 0.0, dd, 1.0)[:, None], 0.0, 1.0)
    return np.linalg.norm(rel - t[..., None] * d[:, None, :], axis=2)


@dataclass
class _ToolPoses:
    """One tool's CL moves ``first`` to ``stop - 1`` (m of them) as joints: ``joints (m, n)`` as
    written, ``rewound (m,)`` where the rotaries jump before the pose (never the first, reached
    from the tool change), ``before (m - 1, n)`` the joints move i starts from (``before[i - 1]``:
    pose i - 1, or where the rotaries jump, pose i - 1 solved next to pose i); ``tool_length`` mm
    the kinematics took (tip to gauge line; 0 where the control compensates it)."""

    first: int
    stop: int
    joints: np.ndarray
    rewound: np.ndarray
    before: np.ndarray
    tool_length: float


def _tool_poses(tp, machine, first, stop, tool, tcp, start) -> _ToolPoses:
    """The :class:`_ToolPoses` of ``tool``'s CL moves ``first`` to ``stop - 1`` by the inverse
    kinematics, from ``start`` (the joints before them, or None)."""
    length = tool.spindle_length if machine.chain.head_pivot else 0.0
    tip, axis = tp.tip[first:stop], tp.axis[first:stop]
    joints, rewound = _solve(machine, tp, first, tip, axis, length, tcp, start)
    rewound[0] = False  # the first pose of a tool is reached from the tool change
    before = joints[:-1].copy()
    for i in np.flatnonzero(rewound):
        before[i - 1] = _solve(machine, tp, first + i - 1, tip[i - 1:i], axis[i - 1:i], length, tcp, joints[i])[0][0]
    return _ToolPoses(first, stop, joints, rewound, before, length)


def _move_kinds(tp, poses: _ToolPoses, feed, machine, tcp):
    """``(rapid (m,), turns (m,), feed (m,))`` of one tool's CL moves: which are written G0; which
    are rapids that turn a rotary (joints mode: interpolated joint-linearly, so linearised like feed
    moves and written G1 at the rapid rate); each move's feed mm/s (the rapid rate for those, and
    for rapids that a dog-leg G0 would take off their line, written G1 along it)."""
    a, b, joints, before = poses.first, poses.stop, poses.joints, poses.before
    turned = np.r_[False, np.abs(joints[1:, 3:] - before[:, 3:]).max(axis=1) > 0.0]
    turns = tp.rapid[a:b] & turned if not tcp else np.zeros(b - a, bool)
    straight = tp.rapid[a:b] & np.r_[False, _dogleg_corner(joints[1:], machine, before)] & ~turns
    rapid = tp.rapid[a:b] & ~turns & ~straight
    return rapid, turns, np.where(turns | straight, machine.motion.rapid, feed[a:b])


@dataclass
class _Linearised:
    """One tool's CL moves as linearised: ``splits`` {i: (s (q,), joints (q, n))} the poses put
    into its move i at the fractions s; ``largest (m,)`` mm each move's largest deviation of its
    blocks from it (0 for G0); ``turn (m,)`` deg the rotaries' largest change in each move."""

    splits: dict
    largest: np.ndarray
    turn: np.ndarray


def _linearise(tp, poses: _ToolPoses, rapid, turns, machine, tcp, tolerance, flutes) -> _Linearised:
    """The :class:`_Linearised` of one tool's CL moves (joints mode; nothing is split in TCP mode):
    the moves not written G0 (``rapid``) that stray beyond ``tolerance`` mm at the tip or
    ``flutes`` mm up the axis are split (:meth:`_Linearisation.split`); a rapid that turns the
    rotaries (``turns``) keeps only its tip on the CL segment (as a feed move, where the axis's
    great circle lies between its ends' joints; where it needs the other solution of the rotaries,
    the rotaries turn joint-linearly instead). A move whose blocks still stray is split again, the
    better of the two kept: a rapid with its tip alone on the CL segment, a feed move with every
    midpoint's axis on the CL move's (``strict``)."""
    a, b, joints, before, length = poses.first, poses.stop, poses.joints, poses.before, poses.tool_length
    tip, axis = tp.tip[a:b], tp.axis[a:b]
    lin = _Linearisation(machine, tp, length, tcp, tolerance, flutes)
    cut = np.flatnonzero(~rapid[1:]) + 1 if not tcp else np.zeros(0, np.int64)
    deviation = np.zeros(b - a)
    unit = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    deviation[cut] = lin.deviation(before[cut - 1], joints[cut], tip[cut - 1], tip[cut], unit[cut - 1], unit[cut])
    lin_rapid = _Linearisation(machine, tp, length, tcp, tolerance, 0.0, rapid=True)
    linear_turn = np.zeros(b - a, bool)
    g = np.linspace(0.0, 1.0, 33)[1:]
    for i in np.flatnonzero(turns):  # follow the great circle's solutions from the start
        circle = _great_circle(np.repeat(unit[i - 1:i], len(g), axis=0), np.repeat(unit[i:i + 1], len(g), axis=0), g)
        ja = _solve(machine, tp, a + i, tip[i - 1] + g[:, None] * (tip[i] - tip[i - 1]), circle, length, tcp,
                    before[i - 1], within=True)[0][-1]
        linear_turn[i] = np.abs(ja[3:] - joints[i, 3:]).max() > 1e-3
    fast = np.flatnonzero(linear_turn)
    deviation[fast] = lin_rapid.deviation(before[fast - 1], joints[fast], tip[fast - 1], tip[fast],
                                          unit[fast - 1], unit[fast])
    splits, largest = {}, np.where(rapid, 0.0, deviation)

    def split(how, need, strict=False):  # keeps the split of each move that strays least
        found = how.split(a + need, unit[need - 1], unit[need], before[need - 1], joints[need], strict)
        for i, (s, j, worst) in zip(need.tolist(), found):
            if i not in splits or worst < largest[i]:
                splits[i], largest[i] = (s, j), worst

    for how, mask in ((lin, ~linear_turn), (lin_rapid, linear_turn)):
        split(how, np.flatnonzero(~rapid & (deviation > tolerance) & mask))
    # what still strays, again: a rapid with its tip alone on the CL segment (its axis is free), a
    # feed move with the axis of every midpoint on the CL move's
    again = np.flatnonzero(largest > tolerance)
    split(lin_rapid, again[turns[again] & ~linear_turn[again]])
    split(lin, again[~turns[again]], strict=True)
    return _Linearised(splits, largest, np.r_[0.0, np.abs(joints[1:, 3:] - before[:, 3:]).max(axis=1)])


def _tool_blocks(tp, tool_index, tool, poses: _ToolPoses, rapid, feed, lin: _Linearised, machine, clearance,
                 tcp) -> _Run:
    """The :class:`_Run` of tool ``tool_index`` (``tool``) over its CL moves: the first pose by
    G0 from the tool change, then per move its blocks: a retract-unwind-return (:func:`_rewind`)
    where the rotaries jump, then G0 (``rapid``) or G1 at ``feed (m,)`` mm/s through the poses
    ``lin`` put in."""
    a, b, joints, before = poses.first, poses.stop, poses.joints, poses.before
    step = np.r_[0.0, np.linalg.norm(np.diff(tp.tip[a:b], axis=0), axis=1)]  # mm, the tip's travel of each move
    blocks = _Blocks(tool_index)
    blocks.add(joints[0], True, np.nan, 0.0, a)
    for i in range(1, b - a):
        move, f = a + i, feed[i]
        if poses.rewound[i]:
            _rewind(blocks, tp, machine, move, joints[i - 1], before[i - 1], f, clearance, tool, poses.tool_length, tcp)
        if rapid[i]:
            blocks.add(joints[i], True, np.nan, 0.0, move)
            continue
        done = 0.0
        for sj, j in zip(*lin.splits.get(i, ((), ()))):
            blocks.add(j, False, f, (sj - done) * step[i], move, added=True)
            done = sj
        blocks.add(joints[i], False, f, (1.0 - done) * step[i], move)
    return blocks.run()


def _pole_distance(tp, move) -> float:
    """deg: how near the tool axis comes to the pole of the rotaries (+Z or -Z) in CL move
    ``move`` (its great circle from the axis before it)."""
    a0, a1 = tp.axis[move - 1], tp.axis[move]
    circle = _great_circle_path(a0[None] / np.linalg.norm(a0), a1[None] / np.linalg.norm(a1),
                                np.linspace(0.0, 1.0, 65))[0]
    return float(np.degrees(np.arccos(np.clip(np.abs(circle[:, 2]), 0.0, 1.0))).min())


def _check_gross(tp, first, lin: _Linearised):
    """InputError for the first of one tool's moves (from CL move ``first``) whose blocks stray
    more than :data:`GROSS_STRAY` from it however finely it is split: the rotaries turn where the
    tip cannot follow (near the pole, or across the end of a rotary's travel), which more blocks
    would not fix."""
    gross = np.flatnonzero(lin.largest > GROSS_STRAY)
    if not len(gross):
        return
    i = int(gross[0])
    move = first + i
    pole = _pole_distance(tp, move)
    why = (f"the tool axis passes {pole:.3f} deg from the pole of the rotaries, where C must swing: tilt the path "
           f"at least {POLE_WARNING_DEG:g} deg away from it (a lead or tilt angle) or post for TCP ({TCP_HINT})"
           if pole < POLE_WARNING_DEG else
           "check the rotaries' travel (a move across the end of a travel under two turns cannot unwind)")
    raise InputError(f"{_where(tp, move)}: the rotaries turn {lin.turn[i]:.1f} deg in this move and its joint-linear "
                     f"motion strays {lin.largest[i]:.3f} mm from it however finely it is split: {why}")


def _stray_error(tp, machine, tolerance, moves, largest) -> InputError:
    """The error for CL ``moves (k,)`` whose blocks stray up to ``largest (k,)`` mm (more than
    ``tolerance``) however finely they are split: the move that strays most, why (near the pole of
    the rotaries C is held, and the axis then off by up to ``chain.singular``), and what holds: a
    tolerance of the largest stray (rounded up), TCP, or a path tilted away from the pole."""
    worst = int(np.argmax(largest))
    move = int(moves[worst])
    holds = math.ceil(float(largest[worst]) * 1e4 - 1e-6) / 1e4  # mm: the largest stray, rounded up
    pole = _pole_distance(tp, move)
    near = (f", where the tool axis passes {pole:.3f} deg from the pole of the rotaries ({machine.name} holds C within "
            f"{math.degrees(machine.chain.singular):g} deg of it, the axis off by up to that angle)"
            if pole < POLE_WARNING_DEG else "")
    away = f", or tilt the path at least {POLE_WARNING_DEG:g} deg away from the pole (a lead or tilt angle)" \
        if pole < POLE_WARNING_DEG else ""
    return InputError(f"{len(moves)} CL move(s) stray from the path by more than the {tolerance:g} mm tolerance "
                      f"however finely they are split, the most {largest[worst]:.4f} mm at {_where(tp, move)}{near}: "
                      f"give tolerance {holds:g} (which holds), post for TCP ({TCP_HINT}){away}", "tolerance")


def _five_axis_runs(tp, tools, feed, machine, tolerance, tcp, clearance=None) -> _Program:
    """The :class:`_Program` of a 5-axis machine: one :class:`_Run` per tool from the inverse
    kinematics (:func:`_tool_poses`), moves linearised (joints mode, :func:`_linearise`), and a
    retract-unwind-return where the rotaries jump (see :func:`post_program`; ``clearance``: Z mm
    above which they do, None: the path's highest tip). A move whose blocks still stray beyond
    ``tolerance`` is an InputError (:func:`_check_gross`, :func:`_stray_error`)."""
    clearance_given = clearance is not None
    clearance = float(clearance) if clearance_given else float(tp.tip[:, 2].max())
    out = _Program("5-axis TCP" if tcp else "5-axis joints", [], clearance=clearance)
    start, strays = None, []
    for tool, a, b in _tool_runs(tp.tool):
        poses = _tool_poses(tp, machine, a, b, tools[tool], tcp, start)
        rapid, turns, f_move = _move_kinds(tp, poses, feed, machine, tcp)
        lin = _linearise(tp, poses, rapid, turns, machine, tcp, tolerance, tools[tool].flute_length)
        _check_gross(tp, a, lin)
        out.runs.append(_tool_blocks(tp, tool, tools[tool], poses, rapid, f_move, lin, machine, clearance, tcp))
        out.rewinds += int(poses.rewound.sum())
        if not clearance_given:
            out.warnings += _swing_warnings(tp, poses, machine, clearance)
        out.blocks_added += int(out.runs[-1].added.sum())
        out.largest = max(out.largest, float(lin.largest.max()))
        strays += [(a + i, lin.largest[i]) for i in np.flatnonzero(lin.largest > tolerance)]
        start = poses.joints[-1]
    if strays:
        raise _stray_error(tp, machine, tolerance, *(np.array(x) for x in zip(*strays)))
    return out


def _swing_warnings(tp, poses: _ToolPoses, machine, clearance) -> list[str]:
    """Warnings for the moves of one tool before which the tool swings over to the other side (the
    tilt changes where the rotaries jump) above ``clearance``, the path's highest tip (none was
    given), each with the clearance to give: that Z where the path's rapids travel at it (they
    clear the part where they pass), else that Z plus :data:`SWING_MARGIN`."""
    tilt = machine.axes.index(machine.chain.rotary[0])
    joints, before = poses.joints, poses.before
    if tp.rapid.any() and float(tp.tip[tp.rapid, 2].max()) >= clearance:
        advice = f"the height the path's own rapids travel at: give clearance {clearance:g}"
    else:
        advice = f"which none of the path's rapids reaches: give clearance {clearance + SWING_MARGIN:g} (that tip plus " \
                 f"{SWING_MARGIN:g} mm)"
    return [f"{_where(tp, poses.first + i)}: the tool swings over to the other side ({machine.axes[tilt]} "
            f"{format_number(joints[i - 1, tilt], 3)} -> {format_number(before[i - 1, tilt], 3)}) in one block, the "
            f"whole tool kept above Z {clearance:g}, the path's highest tip, {advice} where nothing of the part or its "
            "fixtures stands higher, else the part's top plus a margin"
            for i in np.flatnonzero(poses.rewound) if abs(before[i - 1, tilt] - joints[i - 1, tilt]) > 1e-6]


def _rewind(blocks, tp, machine, move, joints, unwound, feed, clearance, tool, tool_length, tcp):
    """The blocks before CL move ``move`` whose rotaries jump from ``joints (n,)`` (pose move-1)
    to ``unwound (n,)`` (the same pose next to pose ``move``): up the tool axis until the whole
    ``tool`` (cutter, shank, holder) is at or above Z ``clearance`` (G1 at ``feed`` mm/s), higher
    still until it stays so all through the joint-linear jump (a tilt swinging through 0 carries
    the tool in an arc), the jump (G0), down again (G1)."""
    axis = tp.axis[move - 1] / np.linalg.norm(tp.axis[move - 1])
    if axis[2] <= 0.0:
        raise InputError(f"{_where(tp, move)}: the rotaries must unwind here and the tool axis points "
                         f"{'down' if axis[2] < 0 else 'sideways'}: the tool cannot retract up to Z {clearance:g}")
    rise = max(0.0, (clearance - float(tool.lowest_z(tp.tip[move - 1], axis)[0])) / axis[2])
    for _ in range(SWING_ROUNDS):
        up = _retract_joints(machine, joints, rise * axis, tool_length, tcp)
        up_unwound = _retract_joints(machine, unwound, rise * axis, tool_length, tcp)
        if tcp:  # the control keeps the tip on the straight line between, the tool above the clearance
            break
        # without TCP the axes move linearly: a tilt swinging through 0 carries the tool in an arc
        # that may dip; go up further until the whole jump stays at or above the clearance
        s = np.linspace(0.0, 1.0, SWING_SAMPLES)
        tips, axes = forward(machine, up[None] + s[:, None] * (up_unwound - up)[None], tool_length, tcp)
        dip = clearance - float(tool.lowest_z(tips, axes).min())
        if dip <= GOUGE_TOL:  # rounding of the written joints
            break
        rise += dip / axis[2] + 0.1
    else:
        raise InputError(f"{_where(tp, move)}: the rotaries must jump here, and no retract along the tool axis keeps "
                         f"tool {tool.name} above Z {clearance:g} all through the jump (still {dip:.3f} mm below)")
    if rise > 0.0:
        blocks.add(up, False, feed, rise, move, rewind=True)
    if np.count_nonzero(up_unwound != up) > 1:  # a swing: joint-linear, as checked, at the rapid rate
        blocks.add(up_unwound, False, machine.motion.rapid, 0.0, move, rewind=True)
    else:  # C alone turns: a G0 of one axis is the same in every control
        blocks.add(up_unwound, True, np.nan, 0.0, move, rewind=True)
    if rise > 0.0:
        blocks.add(unwound, False, feed, rise, move, rewind=True)


# --- checks, feeds and text ------------------------------------------------------------------------

def _check_limits(runs, tp, machine, origin, tcp=False, tools=None):
    """InputError for the first written block beyond the machine's travel (by more than half the
    last written digit, as the kinematics' values are rounded). X Y Z are machine coordinates
    less ``origin`` (3,) (the program's zero in machine coordinates); without an origin they are
    only checked to fit: each axis's span within its travel. Returns ``{letter: [low, high]}``:
    where the program's zero may lie in machine coordinates for X Y Z to stay within travel."""
    letters = machine.axes
    if tcp:  # X Y Z are the tip: check where the axes stand
        runs = [replace(run, joints=np.column_stack([
            machine_xyz(machine, run.joints, tools[run.tool].spindle_length if machine.chain.head_pivot else 0.0),
            run.joints[:, 3:]])) for run in runs]
    joints = np.concatenate([run.joints for run in runs])
    fits = {}
    for n, letter in enumerate(letters[:3]):
        if letter in machine.limits:
            low, high = machine.limits[letter]
            lo, hi = float(joints[:, n].min()), float(joints[:, n].max())
            fits[letter] = [low - lo, high - hi]
            if origin is None and hi - lo > high - low + 1e-9:
                raise InputError(f"the program spans {hi - lo:.3f} mm in {letter} ({lo:.3f} to {hi:.3f}) but "
                                 f"{machine.name} travels {high - low:g} mm ([{low:g}, {high:g}])")
    shift = np.zeros(len(letters))
    if origin is not None:
        shift[:3] = origin
    first = None
    for r, run in enumerate(runs):
        for n, letter in enumerate(letters):
            if letter not in machine.limits or (n < 3 and origin is None):
                continue
            low, high = machine.limits[letter]
            slack = 0.5 * 10.0 ** -(machine.gcode.decimals if n < 3 else machine.gcode.angle_decimals)
            value = run.joints[:, n] + shift[n]
            out = np.flatnonzero((value < low - slack) | (value > high + slack))
            if len(out) and (first is None or (r, out[0]) < first[:2]):
                first = (r, int(out[0]), n, letter, low, high)
    if first is None:
        return fits
    r, b, n, letter, low, high = first
    run = runs[r]
    value = format_number(run.joints[b, n] + shift[n], machine.gcode.decimals if n < 3 else machine.gcode.angle_decimals)
    what = "the retract to unwind the rotaries before " if run.rewind[b] else ""
    where = " (machine coordinates, origin " + ", ".join(f"{v:g}" for v in origin) + ")" if n < 3 else ""
    raise InputError(f"{what}{_where(tp, int(run.move[b]))}: {letter} {value}{where} is beyond its travel "
                     f"[{low:g}, {high:g}] on {machine.name}")


def _rotary_limited(runs, tp, machine):
    """A warning (or None) for the feed blocks that the rotaries slow below half their feed: where
    a small tip motion needs a large turn (a small contour turned by C, or the tool axis near the
    pole of the rotaries, where C swings), the block lasts at least its turn at
    ``machine.rotary_rapid``."""
    count, worst, first = 0, 1.0, None
    for run in runs:
        cut = ~run.rapid & ~run.rewind & ~tp.rapid[run.move] & (run.tip_length > 0)  # CL feed moves
        tip_s = np.where(cut, run.tip_length / np.where(cut, run.feed, 1.0), 0.0)
        turn_s = angle_step(run.joints) / machine.rotary_rapid
        slow = cut & (turn_s > 2.0 * tip_s)
        if slow.any():
            count += int(slow.sum())
            worst = min(worst, float((tip_s[slow] / turn_s[slow]).min()))
            first = first if first is not None else int(run.move[np.argmax(slow)])
    if not count:
        return None
    return (f"{count} feed block(s) run below half their feed because the rotaries turn faster than the tip moves "
            f"(first at {_where(tp, first)}; down to {100 * worst:.2g} % of the feed, the rotaries at "
            f"{machine.rotary_rapid * 60:g} deg/min): around small contours, or where the tool axis passes near "
            "the pole of the rotaries")


def _feed_values(run, machine, inverse_time):
    """F (b,) of a run's blocks, NaN for G0: the tip's feed in mm/min (G94), or 1 / the block's
    minutes (G93): the longest of the tip at its feed along the CL path, the rotaries at
    ``machine.rotary_rapid``, the linear axes at the rapid rate, each axis on its own, and
    ``MIN_BLOCK_S`` (so F stays within what controls accept for tiny blocks)."""
    if not inverse_time:
        return np.where(run.rapid, np.nan, run.feed * 60.0)
    linear = np.abs(np.diff(run.joints[:, :3], axis=0, prepend=run.joints[:1, :3])).max(axis=1)
    seconds = np.maximum.reduce([run.tip_length / run.feed, angle_step(run.joints) / machine.rotary_rapid,
                                 linear / machine.motion.rapid, np.full(len(linear), MIN_BLOCK_S)])
    with np.errstate(divide="ignore"):
        return np.where(run.rapid, np.nan, 60.0 / seconds)


def _arcs(run, f_values, places, tolerance) -> dict:
    """{first block: (last block, centre (2,), ccw)} of the arcs among a run's feed blocks
    (:func:`~meshmill.machine.arcs.arc_runs`): blocks at the same written feed and rotaries as
    the block before, not part of a rewind."""
    from .arcs import arc_runs

    j = run.joints
    same = np.zeros(len(j), bool)
    if len(j) > 1:
        f_text = np.array([format_number(f, 1) if np.isfinite(f) else "" for f in f_values])
        same[1:] = (~run.rapid[1:] & ~run.rapid[:-1] & ~run.rewind[1:] & (f_text[1:] == f_text[:-1])
                    & np.all(np.abs(j[1:, 3:] - j[:-1, 3:]) < 10.0 ** -places, axis=1))
    first, last, centre, ccw = arc_runs(np.ascontiguousarray(j[:, :3], float), same, float(tolerance))
    return {int(a): (int(b), c, bool(d)) for a, b, c, d in zip(first, last, centre, ccw)}


def _write(runs, tools, machine, mode, inverse_time, tolerance=0.005):
    """The program's lines and the number of motion blocks among them."""
    g = machine.gcode
    letters = machine.axes
    places = [g.decimals if n < 3 else g.angle_decimals for n in range(len(letters))]
    lines = list(g.start)
    lines.append(_comment(g, f"meshmill post for {machine.name}: {mode}"))
    motion_blocks = 0
    g93 = False
    for r, run in enumerate(runs):
        tool = tools[run.tool]
        rpm = tool.rpm or g.rpm
        if r:
            lines += ["G94"] * g93 + list(g.retract) + [SPINDLE_STOP, g.coolant_off] + [g.tcp_off] * (mode == "5-axis TCP")
            g93 = False
        text = f"T{tool.number} {tool.name}: {tool.type} D{tool.diameter:g}"
        text += f" R{tool.corner_radius:g}" if tool.type == "bull" else ""
        lines.append(_comment(g, text))
        lines += [OPERATOR_STOP] if r and not g.tool_change else []
        lines.append(_fill(g.tool_change, tool, rpm))
        if mode == "5-axis TCP":
            lines.append(_fill(g.tcp, tool, rpm))
        elif mode == "5-axis joints" and machine.chain.head_pivot:
            lines.append(_comment(g, f"posted for a tool length of {tool.spindle_length:g} mm from the tip "
                                     "to the gauge line: no tool length compensation"))
        else:
            lines.append(_fill(g.tool_length, tool, rpm))
        lines += [_fill(g.spindle, tool, rpm), _fill(g.coolant_on, tool, rpm)]
        f_values = _feed_values(run, machine, inverse_time)
        arcs = _arcs(run, f_values if not inverse_time else np.where(run.rapid, np.nan, 0.0), g.angle_decimals,
                     tolerance) if g.arcs else {}
        modal = {}
        skip_to = -1
        for b in range(len(run.joints)):
            if b <= skip_to:
                continue
            if b in arcs:  # one G2/G3 from the end of block b-1 to the end of the arc's last block
                last, centre, ccw = arcs[b]
                motion = "G3" if ccw else "G2"
                end = [format_number(v, places[n]) for n, v in enumerate(run.joints[last][:3])]
                words = [motion] + [f"{letters[n]}{end[n]}" for n in range(3) if n < 2 or modal.get(letters[n]) != end[n]]
                words += [f"I{format_number(centre[0] - run.joints[b - 1][0], g.decimals)}",
                          f"J{format_number(centre[1] - run.joints[b - 1][1], g.decimals)}"]
                if inverse_time:  # F: 1 / the minutes of the blocks it replaces
                    minutes = float(np.sum(1.0 / f_values[b:last + 1]))
                    if not g93:
                        words.insert(0, "G93")
                        g93 = True
                    words.append(f"F{format_number(1.0 / minutes, g.decimals)}")
                else:
                    f_text = format_number(f_values[b], 1)
                    if modal.get("F") != f_text:
                        words.append(f"F{f_text}")
                        modal["F"] = f_text
                modal["G"] = motion
                modal.update((letters[n], end[n]) for n in range(3))
                lines.append(" ".join(words))
                motion_blocks += 1
                skip_to = last
                continue
            texts = [format_number(v, p) for v, p in zip(run.joints[b], places)]
            groups = [[n for n in range(len(letters)) if n != 2], [2]] if b == 0 else [range(len(letters))]
            for group in groups:
                words = [f"{letters[n]}{texts[n]}" for n in group if modal.get(letters[n]) != texts[n]]
                if not words:
                    continue
                motion = "G0" if run.rapid[b] else "G1"
                if not run.rapid[b]:
                    f_text = format_number(f_values[b], g.decimals if inverse_time else 1)
                    if inverse_time or modal.get("F") != f_text:
                        words.append(f"F{f_text}")
                        modal["F"] = f_text
                if modal.get("G") != motion:
                    words.insert(0, motion)
                    modal["G"] = motion
                if inverse_time and not run.rapid[b] and not g93:
                    words.insert(0, "G93")
                    g93 = True
                modal.update((letters[n], texts[n]) for n in group)
                lines.append(" ".join(words))
                motion_blocks += 1
    lines += ["G94"] * g93 + [g.tcp_off] * (mode == "5-axis TCP") + list(g.end)
    lines = [line for line in lines if line]
    if g.line_numbers:
        count = 0
        for n, line in enumerate(lines):
            if line != "%" and not (line[0] == "O" and line[1:2].isdigit()):
                count += 1
                lines[n] = f"N{count} {line}"
    return lines, motion_blocks


def _checked_arguments(toolpath, tolerance, clearance, origin):
    """The arguments of :func:`post_program` checked: ``origin`` as an array (3,) mm, or None;
    InputError for a ``tolerance`` that is no positive number of mm, a path without moves, a ``clearance`` that is no Z within the CL format's range,
    an ``origin`` that is not three finite numbers."""
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"tolerance (the linearisation's) must be a positive number of mm, got {tolerance}",
                         "tolerance")
    if len(toolpath) == 0:
        raise InputError("the tool path has no moves")
    if clearance is not None and (isinstance(clearance, bool) or not isinstance(clearance, numbers.Real)
                                  or not abs(clearance) <= MAX_COORDINATE):
        raise InputError(f"the clearance must be a Z in mm (|Z| <= {MAX_COORDINATE:g}), got {clearance}", "clearance")
    if origin is None:
        return None
    origin = np.asarray(origin, np.float64)
    if origin.shape != (3,) or not np.isfinite(origin).all():
        raise InputError(f"the origin must be three finite numbers X,Y,Z (mm), got {origin.tolist()}", "origin")
    return origin


def post_mode(machine, tcp=None) -> str:
    """How a program for ``machine`` is written: "3-axis", "5-axis joints" or, with ``tcp`` (None:
    where the machine's ``gcode.tcp`` text is not empty), "5-axis TCP"; InputError for TCP on a
    3-axis machine or without a ``gcode.tcp`` text."""
    tcp = bool(machine.gcode.tcp) if tcp is None else bool(tcp)
    if machine.chain.type == "3-axis":
        if tcp:
            raise InputError(f"TCP needs a 5-axis machine; {machine.name} is a 3-axis machine")
        return "3-axis"
    if tcp and not machine.gcode.tcp:
        raise InputError(f"{machine.name} has no [gcode] 'tcp' text to switch TCP on (e.g. \"G43.4 H{{number}}\")")
    return "5-axis TCP" if tcp else "5-axis joints"


def program_blocks(toolpath, tools, feeds, machine, mode, tolerance, clearance=None) -> _Program:
    """The :class:`_Program` of ``toolpath`` (``feeds (k,)`` mm/s per move) on ``machine`` in
    ``mode`` (:func:`post_mode`): the tips as they are (3-axis), else :func:`_five_axis_runs`."""
    if mode == "3-axis":
        return _Program(mode, _three_axis_runs(toolpath, feeds, machine))
    return _five_axis_runs(toolpath, tools, feeds, machine, tolerance, mode == "5-axis TCP", clearance)


def program_warnings(toolpath, tools, machine, program: _Program, given=None) -> list[str]:
    """The warnings about a ``program`` besides its own (the swings'): a clearance ``given`` (Z mm)
    that a 3-axis machine does not use or that lies below the path's highest tip, tools without a
    holder on a head that tilts them, joint moves fed in G94, feed blocks the rotaries slow, and
    tool changes left to the operator."""
    g, runs, warnings = machine.gcode, program.runs, []
    top = float(toolpath.tip[:, 2].max())
    joints_mode = program.mode == "5-axis joints"
    if given is not None and program.mode == "3-axis":
        warnings.append(f"the clearance (Z {given:g}) is not used on a 3-axis machine: it has no rotaries to jump")
    elif given is not None and given < top and program.rewinds:
        warnings.append(f"the clearance Z {given:g} is below the path's highest tip (Z {top:g}): where the rotaries "
                        "jump, the tool stays above it, lower than the path's own rapids")
    if joints_mode and machine.chain.head_pivot:
        warnings += [w for w in (tools[i].spindle_length_warning() for i in sorted({r.tool for r in runs})) if w]
    if joints_mode and not program.inverse_time(machine):
        warnings.append(f"{machine.name} writes 5-axis joint moves in G94: F is the tip's feed, but the control applies "
                        "it to the axes' motion, so blocks that turn the rotaries run at another speed; set "
                        f"inverse_time = true in its [gcode] (G93, F = 1 / the block's minutes) or post for TCP "
                        f"({TCP_HINT})")
    slow = _rotary_limited(runs, toolpath, machine) if joints_mode else None
    warnings += [slow] if slow else []
    if len(runs) > 1 and not g.tool_change:
        warnings.append(f"{machine.name} has no tool changer: the program stops ({OPERATOR_STOP}) at each of the "
                        f"{len(runs) - 1} tool change(s) for the operator")
    return warnings


def program_report(toolpath, tools, machine, program: _Program, lines, blocks, tolerance, origin, origin_range,
                   warnings) -> dict:
    """The report of a program (see :func:`post_program`): its ``lines`` and motion ``blocks``,
    the ``program``'s figures, the ``origin`` and the ``origin_range``, the ``warnings``."""
    joints = np.concatenate([run.joints for run in program.runs])
    return {
        "machine": machine.name, "machine_file": machine.summary()["file"], "dialect": machine.gcode.dialect,
        "kinematics": machine.chain.type, "mode": program.mode,
        "feed_mode": "G93 inverse time" if program.inverse_time(machine) else "G94 mm/min",
        "moves": len(toolpath), "blocks": blocks, "lines": len(lines),
        "linearisation": {"tolerance_mm": float(tolerance), "blocks_added": program.blocks_added,
                          "max_deviation_mm": None if program.tcp else program.largest},
        "axis_ranges": {letter: [float(joints[:, n].min()) + 0.0, float(joints[:, n].max()) + 0.0]
                        for n, letter in enumerate(machine.axes)},
        "rewinds": program.rewinds, "clearance_z_mm": program.clearance,
        "origin": None if origin is None else [float(v) for v in origin], "origin_range": origin_range,
        "tools": list(dict.fromkeys(tools[run.tool].name for run in program.runs)),
        "tool_changes": len(program.runs) - 1, "warnings": warnings,
    }


def post_program(toolpath, tools, machine, feed=None, tolerance=0.005, tcp=None, origin=None,
                 clearance=None) -> tuple[list[str], dict]:
    """The NC program of ``toolpath`` on ``machine`` (see the module's docstring for the layout).

    ``toolpath``: :class:`~meshmill.toolpath.model.Toolpath` (k moves; ``tool`` indexes
    ``tools``, the :class:`~meshmill.tools.table.Tool` list). ``origin (3,)`` mm: the program's
    zero in machine coordinates (the work offset), for the travel of X Y Z (None: each axis's span
    must fit its travel; the report's ``origin_range`` says where the zero may lie). ``feed``: None, a number or (k,)
    per move, mm/s, NaN where the machine's nominal feed applies. ``tolerance`` mm: how far the tip
    may stray from a CL feed move between blocks in 5-axis joints mode. ``tcp``: write TCP
    programs (None: where the machine's ``gcode.tcp`` is not empty). ``clearance`` mm: the Z in
    work coordinates above which the whole tool stays while the rotaries jump (None: the path's
    highest tip).

    Where the rotaries must jump (the kinematics' ``rewound`` at pose i: C unwinds, or the tilt
    swings over to its other solution), the tool never does so in the cut: at pose i-1 it retracts
    along its axis (G1, at move i's feed) until the whole tool (cutter, shank and holder as the
    tool table models them) is above ``clearance`` (no retract when already there), the rotaries
    jump in one G0 to pose i-1 solved next to pose i, the tool comes back down along its axis (G1)
    to pose i-1, and move i goes on from there. When only C unwinds (whole turns), the physical
    pose is the same and X Y Z stay: the part turns about its Z under a tool that is above it. A
    tilt swing also moves X Y Z, joint-linearly: the retract goes higher until the tool stays above
    the clearance all through the swing (checked at SWING_SAMPLES poses); where the clearance is
    the path's highest tip, which need not clear the part, a warning names the move. A tool axis
    that does not point up there cannot retract and is an InputError.

    Returns ``(lines, report)``: the program's lines (no line ends) and a dict: ``machine``,
    ``dialect``, ``kinematics``, ``mode``, ``feed_mode``, ``moves`` (in), ``blocks`` (motion
    blocks out), ``lines``, ``linearisation`` (``tolerance_mm``, ``blocks_added``,
    ``max_deviation_mm``: the largest deviation of a block from its CL move, at most the
    tolerance; None in TCP mode, where the control interpolates), ``axis_ranges`` ({letter: [low,
    high]} as written), ``rewinds`` and ``clearance_z_mm`` (what the tool stays above where the
    rotaries jump), ``tools`` (names in order of use), ``tool_changes`` (after the first tool),
    ``warnings``. Raises :class:`~meshmill.errors.InputError` for a tilted axis on a 3-axis
    machine, a block beyond the travel, a TCP program without a ``gcode.tcp`` text, or a move
    whose blocks stray beyond the tolerance however finely it is split (near the pole of the
    rotaries, where C is held; the error says the tolerance that holds).

    The stages: :func:`post_mode`, :func:`program_blocks`, the travel (:func:`_check_limits`),
    the text (:func:`_write`), :func:`program_warnings`, :func:`program_report`.
    """
    origin = _checked_arguments(toolpath, tolerance, clearance, origin)
    mode = post_mode(machine, tcp)
    program = program_blocks(toolpath, tools, _move_feeds(feed, len(toolpath), machine), machine, mode, tolerance,
                             clearance)
    origin_range = _check_limits(program.runs, toolpath, machine, origin, program.tcp, tools)
    lines, blocks = _write(program.runs, tools, machine, mode, program.inverse_time(machine), tolerance)
    warnings = program.warnings + program_warnings(toolpath, tools, machine, program, clearance)
    return lines, program_report(toolpath, tools, machine, program, lines, blocks, tolerance, origin, origin_range,
                                 warnings)
