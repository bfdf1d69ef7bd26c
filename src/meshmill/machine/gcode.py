"""G-code (RS-274 / ISO 6983) read into a :class:`Toolpath`: 3-axis, or 5-axis through a machine's
kinematics (:mod:`meshmill.machine.motion`).

Read:

- ``G0`` rapid, ``G1`` linear, ``G2``/``G3`` clockwise/counter-clockwise arcs in the XY plane
  (``G17``), given by ``I J`` (centre offset from the start point; ``G91.1``, the default, or
  absolute with ``G90.1``) or by ``R`` (radius; ``R < 0`` means the arc longer than 180 degrees).
  A ``G2``/``G3`` whose end equals its start (with ``I J``) is a full circle; Z changing along an
  arc makes a helix, Z linear in the angle. Arcs become linear moves whose chord deviation
  (sagitta) is at most ``chord_tol`` mm, ending exactly at the programmed end.
- Motion is modal: a line with only coordinates repeats the last ``G0``-``G3``.
- ``G90``/``G91`` absolute/incremental coordinates (rotary words too), ``G20`` inch (X Y Z I J K R
  times 25.4; angles stay degrees), ``G21`` mm.
- ``T<n>`` selects the tool whose ``number`` is n for the moves that follow (``M6`` or not); a
  move before the first T word is refused. With no T word in the program: the tool named
  ``tool_name``, else the table's only tool.
- Skipped: ``F S M N O H D`` words, ``P`` and ``Q`` on a ``G4`` or ``G64`` line (refused elsewhere:
  on a move they would stand for a cycle or a subprogram this reader does not run; ``K`` likewise,
  which no XY-plane move uses), ``%`` lines, ``( ... )`` and ``; ...`` comments, ``G4``
  (dwell; its line does not move), ``G17 G40 G43 G49 G61 G64 G80 G93 G94`` (``G93`` inverse-time
  and ``G94`` feeds: F words are read by :mod:`meshmill.machine.timing`; a feed move under ``G93``
  without F is refused, as a control would stop there); ``G54``-``G59`` with a warning that work offsets
  are not applied.
- A retract in machine coordinates (the final one, or before a tool change), ``G91 G28 Z0``
  (``G28`` with Z alone, its intermediate point where the tool is) or ``G53 G0 Z..`` (Z alone):
  Z becomes unknown and the path goes on from where X Y Z are all given again; read when the path has begun
  and no move follows, and left out of the tool path with a warning (the machine's Z is unknown);
  elsewhere refused.

Without a machine, or with a 3-axis one, the tool axis is always +Z and X Y Z are the tool tip.

With a 5-axis ``machine`` (table-table or head-table): its rotary words (A or B, and C) are read,
modal like X Y Z, in degrees; each block's axis values are the joints of
:func:`~meshmill.machine.motion.forward`, which gives the tool tip and axis in work coordinates
(head-table: for the tool length of the current tool, its ``gauge_length + holder_length``, as the
post-processor computes programs). The control moves the joints linearly from block to block, so
where the rotaries turn the tip leaves the straight line: such a block becomes as many equal steps
of the joints as it takes for the tip, and the point ``tool.reach`` up the tool axis, to stay
within ``chord_tol`` of the straight pieces between them (sampled at :data:`SAMPLES` points a
piece; a piece is accepted at :data:`ACCEPT` of the tolerance, the margin for the deviation between
samples). Rapids (``G0``) are taken as coordinated like ``G1``. Arcs keep the rotaries where they
are (an arc with a rotary move is refused): the tip's arc is the machine's, turned.

TCP (tool centre point control): the G code of the machine's ``gcode.tcp`` text (e.g. ``G43.4``),
and ``G43.4``/``G43.5`` on any 5-axis machine, switch it on; ``G49``, ``G43`` (the same modal group)
and the G code of ``gcode.tcp_off`` switch it off. In TCP mode X Y Z are the tool tip in work
coordinates and the rotary words give the axis; the control moves the tip on the straight line, so
nothing is split. The machine stays where it is at a switch: the modal X Y Z words are converted to
the new mode's coordinates (unknown while the machine's place is).

Refused with :class:`InputError` naming ``file:line``: ``G18``/``G19`` arcs, ``G41``/``G42``
cutter compensation, canned cycles ``G81``-``G89``, ``G28``/``G30``/``G53`` (machine coordinates
are unknown) but the final retract above, other G codes and letters, rotary words without a 5-axis
machine or not of the machine's axes, ``G43.4``/``G43.5`` without a 5-axis machine, malformed or
non-finite numbers, values beyond 1e6 mm (or degrees).
The machine starts at an unknown place: the path starts at the first point where every axis (X, Y,
Z and the rotaries) has been given (absolutely, by ``G0``/``G1``, over one or more lines); an arc
cannot come before it, and a program that never gives them all has no moves.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .kinematics import forward
from ..toolpath.cldata import MAX_COORDINATE, read_text
from ..toolpath.model import Toolpath

MOTION = ("G0", "G1", "G2", "G3")
IGNORED_G = {"G4", "G17", "G40", "G43", "G49", "G61", "G64", "G80", "G93", "G94"}
WORK_OFFSETS = {f"G{n}" for n in range(54, 60)} | {"G59.1", "G59.2", "G59.3"}
REFUSED_G = {
    "G18": "only XY-plane (G17) arcs are supported",
    "G19": "only XY-plane (G17) arcs are supported",
    "G41": "cutter radius compensation cannot be applied by this reader",
    "G42": "cutter radius compensation cannot be applied by this reader",
    "G28": "it moves in machine coordinates, which are unknown",
    "G30": "it moves in machine coordinates, which are unknown",
    "G53": "it moves in machine coordinates, which are unknown",
} | {f"G{n}": "canned cycles are not supported" for n in range(81, 90)}
END_RETRACT = ("G28", "G53")  # read as a retract of Z alone in machine coordinates
TCP_ON = {"G43.4", "G43.5"}  # tool centre point control on (Fanuc-like controls)
TCP_OFF = {"G49", "G43"}  # off: cancel, or plain tool length compensation (the same modal group)
LENGTH_LETTERS = "XYZIJR"
ROTARY_LETTERS = "ABC"
SKIPPED_LETTERS = "FSMNOHDPQ"
PARAMETER_CODES = {"G4", "G64"}  # the only lines whose P and Q words are read (and skipped)
KNOWN_LETTERS = set(LENGTH_LETTERS + SKIPPED_LETTERS + "T")
LINEAR_AXES = ("X", "Y", "Z")
INCH = 25.4
FULL_CIRCLE_GAP = 1e-6  # mm: an arc ending this close to its start is a full circle
MAX_ARC_SEGMENTS = 1_000_000  # pieces of one arc or one joint-linear block
SAMPLES = 7  # points inside a piece of a joint-linear block where the tip is compared with the piece
ACCEPT = 0.97  # a piece is accepted when its sampled deviation is within this fraction of chord_tol
POSE_CHUNK = 65536  # poses per call of forward (memory: about 200 bytes a pose)

_NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_WORD = re.compile(rf"([A-Z])({_NUMBER})")
_LINE = re.compile(rf"(?:[A-Z]{_NUMBER})+")
_COMMENT = re.compile(r"\([^)]*\)")
_G_CODE = re.compile(r"G(\d+(?:\.\d+)?)")


@dataclass
class _Modes:
    motion: str | None = None
    absolute: bool = True
    arc_absolute: bool = False
    scale: float = 1.0
    tcp: bool = False
    inverse_time: bool = False  # G93: every feed move carries its own F
    offsets: set = field(default_factory=set)


@dataclass(frozen=True)
class _Axes:
    """The program's axes for ``machine`` (None: 3-axis): ``letters`` (X Y Z and the rotaries, in
    ``machine.axes`` order: the columns of the joints), and the G codes that switch TCP on and off."""

    machine: object
    letters: tuple
    tcp_on: frozenset
    tcp_off: frozenset

    @staticmethod
    def of(machine) -> "_Axes":
        if machine is None or machine.chain.type == "3-axis":
            return _Axes(machine, LINEAR_AXES, frozenset(), frozenset())
        return _Axes(machine, tuple(machine.axes), frozenset(TCP_ON | _first_g_code(machine.gcode.tcp)),
                     frozenset(TCP_OFF | _first_g_code(machine.gcode.tcp_off)))

    @property
    def five_axis(self) -> bool:
        return len(self.letters) > 3

    def g0_rates(self):
        """Each axis's rapid rate ``(n,)`` (mm/s, deg/s) where the machine moves G0 axis by axis
        (``gcode.rapid = "dogleg"``), else None (G0 on the straight line)."""
        if self.machine is None or self.machine.gcode.rapid != "dogleg":
            return None
        m = self.machine
        return np.array([m.motion.rapid] * 3 + [m.rotary_rapid] * (len(self.letters) - 3))

    def refuse_rotary(self, word, where):
        """InputError for a rotary word that is not one of the machine's axes."""
        if self.machine is None:
            raise InputError(f"{where}: unsupported word {word}: rotary axes are read through the machine's "
                             "kinematics; give the machine (machine, e.g. table-table-ac or head-table-bc)", "machine")
        if not self.five_axis:
            raise InputError(f"{where}: unsupported word {word}: {self.machine.name} is a 3-axis machine")
        raise InputError(f"{where}: unsupported word {word}: {self.machine.name} has no {word[0]} axis "
                         f"(its rotary axes: {', '.join(self.letters[3:])})")


def _first_g_code(text):
    """The G code that a ``[gcode]`` text such as ``"G43.4 H{number}"`` starts with: ``{"G43.4"}``,
    or an empty set for a text without one."""
    found = _G_CODE.search(text.upper())
    return {f"G{float(found.group(1)):g}"} if found else set()


def _read_text(path):
    text = read_text(path, "G-code")
    if "\x00" in text:
        raise InputError(f"{path}: not a text G-code file")
    if not text.strip():
        raise InputError(f"{path}: empty G-code file")
    return text


def _parse_line(raw, where, axes):
    """``(G codes, {letter: value})`` of one line, or None for a line without words."""
    code = _COMMENT.sub("", raw).split(";", 1)[0]
    if "(" in code or ")" in code:
        raise InputError(f"{where}: unbalanced parenthesis (comment)")
    code = "".join(code.split()).upper()
    if not code or code.startswith("%"):
        return None
    if not _LINE.fullmatch(code):
        _raise_bad_word(code, where)
    gcodes, words = [], {}
    for letter, text in _WORD.findall(code):
        value = float(text)
        if letter == "G":
            gcodes.append(f"G{value:g}")
        elif letter in ROTARY_LETTERS and letter not in axes.letters:
            axes.refuse_rotary(letter + text, where)
        elif letter not in KNOWN_LETTERS and letter not in axes.letters:
            raise InputError(f"{where}: unsupported word {letter}{text}")
        elif letter in words and letter not in SKIPPED_LETTERS:
            raise InputError(f"{where}: {letter} given twice")
        else:
            words[letter] = value
    odd = [k for k in "PQ" if k in words]
    if odd and not PARAMETER_CODES.intersection(gcodes) and not REFUSED_G.keys() & set(gcodes):
        raise InputError(f"{where}: unsupported word {odd[0]}{words[odd[0]]:g} (P and Q are read only on G4 and G64 "
                         "lines; on a move they stand for a cycle or a call this reader does not run)")
    return gcodes, words


def _raise_bad_word(code, where):
    if not code[0].isalpha():
        raise InputError(f"{where}: unexpected '{code[0]}'")
    for letter, text in re.findall(r"([A-Z])(NAN|INF|[^A-Z]*)", code):
        if text in ("NAN", "INF"):
            raise InputError(f"{where}: NaN or infinite value after {letter}")
        if not re.fullmatch(_NUMBER, text):
            raise InputError(f"{where}: malformed number after {letter}: '{text}'")
    raise InputError(f"{where}: cannot read '{code}'")


def _apply_g_codes(modes, gcodes, where, axes):
    """Update ``modes`` with a line's G codes; returns the machine-coordinate code (``G28``/``G53``)
    of the line, if any, for :func:`_check_end_retract`."""
    motions = [g for g in gcodes if g in MOTION]
    if len(motions) > 1:
        raise InputError(f"{where}: two motion codes ({' '.join(motions)}) on one line")
    retract = None
    for g in gcodes:
        if g in MOTION:
            modes.motion = g
        elif g in ("G20", "G21"):
            modes.scale = INCH if g == "G20" else 1.0
        elif g in ("G90", "G91"):
            modes.absolute = g == "G90"
        elif g in ("G93", "G94"):
            modes.inverse_time = g == "G93"
        elif g in ("G90.1", "G91.1"):
            modes.arc_absolute = g == "G90.1"
        elif g in WORK_OFFSETS:
            modes.offsets.add(g)
        elif g in axes.tcp_on:
            modes.tcp = True
        elif g in axes.tcp_off:
            modes.tcp = False
        elif g in TCP_ON:
            raise InputError(f"{where}: {g} (tool centre point control) needs a 5-axis machine "
                             f"({'give it: machine' if axes.machine is None else axes.machine.name + ' has 3 axes'})", "machine")
        elif g in END_RETRACT:
            retract = g
        elif g in REFUSED_G:
            raise InputError(f"{where}: {g}: {REFUSED_G[g]}")
        elif g not in IGNORED_G:
            raise InputError(f"{where}: unknown G code {g}")
    return retract


def _check_end_retract(code, words, modes, pos, started, where):
    """Refuse a ``G28``/``G53`` line unless it is a retract of Z alone (``G28``: through an
    intermediate point where the tool already is) after the path has ``started``."""
    moved = [k for k in words if k in LENGTH_LETTERS + ROTARY_LETTERS]
    here = 0.0 if not modes.absolute else pos[2]
    if not started or moved != ["Z"] or (code == "G28" and not abs(words["Z"] - here) <= 1e-9):
        raise InputError(f"{where}: {code}: {REFUSED_G[code]} (read only as a retract of Z alone: "
                         "G91 G28 Z0 or G53 G0 Z0)")


def _scaled(words, scale, where):
    out = {k: v * scale if k in LENGTH_LETTERS else v for k, v in words.items()}
    for k, v in out.items():
        if abs(v) > MAX_COORDINATE:
            unit = "degrees" if k in ROTARY_LETTERS else "mm"
            raise InputError(f"{where}: {k} {v:g} is out of range (|v| <= {MAX_COORDINATE:g} {unit})")
    return out


def _tool_index(value, tools, where):
    for i, tool in enumerate(tools):
        if tool.number == value:
            return i
    raise InputError(f"{where}: T{value:g} is not a tool of the table (1..{len(tools)})")


def _default_tool(tools, tool_name, path):
    if tool_name is not None:
        for i, tool in enumerate(tools):
            if tool.name == tool_name:
                return i
        raise InputError(f"{path}: no tool named '{tool_name}' in the table")
    if len(tools) == 1:
        return 0
    raise InputError(f"{path}: the G-code names no tool (T word); pass the tool name")


def _arc_centre(start, end, words, ccw, arc_absolute, where):
    """XY centre of a G2/G3 arc from ``I J`` or ``R``."""
    if "R" in words:
        if "I" in words or "J" in words:
            raise InputError(f"{where}: give either R or I/J, not both")
        return _centre_from_radius(start, end, words["R"], ccw, where)
    if "I" not in words and "J" not in words:
        raise InputError(f"{where}: an arc needs I/J or R")
    if arc_absolute:
        centre = np.array([words.get("I", start[0]), words.get("J", start[1])])
    else:
        centre = start[:2] + [words.get("I", 0.0), words.get("J", 0.0)]
    r0, r1 = np.linalg.norm(start[:2] - centre), np.linalg.norm(end[:2] - centre)
    if r0 < 1e-9:
        raise InputError(f"{where}: the arc's centre is its start point")
    if abs(r1 - r0) > max(0.01, 1e-3 * r0):
        raise InputError(f"{where}: the arc's end is not on its circle (radius {r0:g} at the start, {r1:g} at the end)")
    return centre


def _centre_from_radius(start, end, r, ccw, where):
    chord = end[:2] - start[:2]
    length = float(np.linalg.norm(chord))
    if length < FULL_CIRCLE_GAP:
        raise InputError(f"{where}: an R arc cannot be a full circle; use I/J")
    if r == 0:
        raise InputError(f"{where}: R must not be 0")
    h2 = r * r - 0.25 * length * length
    if h2 < 0 and 0.5 * length - abs(r) > max(0.01, 1e-3 * abs(r)):
        raise InputError(f"{where}: R{r:g} is too small for arc ends {length:g} mm apart")
    left = np.array([-chord[1], chord[0]]) / length
    side = 1.0 if ccw == (r > 0) else -1.0  # short counter-clockwise arcs turn about a centre on the left
    return 0.5 * (start[:2] + end[:2]) + side * math.sqrt(max(h2, 0.0)) * left


def _arc_points(start, end, centre, ccw, chord_tol, where):
    """Points after ``start`` along the arc (radius and Z linear in the angle), the last = ``end``."""
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    if np.linalg.norm(end[:2] - start[:2]) < FULL_CIRCLE_GAP:
        sweep = 2 * math.pi
    else:
        sweep = (a1 - a0) % (2 * math.pi) if ccw else (a0 - a1) % (2 * math.pi)
    r0, r1 = np.linalg.norm(start[:2] - centre), np.linalg.norm(end[:2] - centre)
    step = min(2 * math.acos(max(0.0, 1 - chord_tol / max(r0, r1))), 0.5 * math.pi)
    n = max(1, math.ceil(sweep / step))
    if n > MAX_ARC_SEGMENTS:
        raise InputError(f"{where}: the arc needs over {MAX_ARC_SEGMENTS} segments at chord_tol {chord_tol:g} mm")
    t = np.arange(1, n + 1) / n
    angle = a0 + (sweep if ccw else -sweep) * t
    radius = r0 + (r1 - r0) * t
    points = np.column_stack([centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle),
                              start[2] + (end[2] - start[2]) * t])
    points[-1] = end
    return points


def _listed(letters):
    """``"X, Y and Z"``."""
    return ", ".join(letters[:-1]) + " and " + letters[-1]


def _target(modes, pos, words, letters):
    """The axis values ``[x, y, z, ...]`` (columns ``letters``) that a line's words move to from
    ``pos`` (NaN: not known; an incremental word leaves an unknown value unknown)."""
    end = list(pos)
    for i, axis in enumerate(letters):
        if axis in words:
            end[i] = words[axis] if modes.absolute else end[i] + words[axis]
    return end


def _move(modes, start, words, letters, chord_tol, where):
    """The axis values ``[[x, y, z, ...], ...]`` (columns ``letters``) of one programmed move from
    ``start`` (NaN: not known yet): its end, or the points along an arc (rotaries held)."""
    end = _target(modes, start, words, letters)
    if any(math.isnan(v) for v in end):
        raise InputError(f"{where}: first move does not give {_listed(letters)}")
    if max(map(abs, end)) > MAX_COORDINATE:
        raise InputError(f"{where}: the move ends out of range (|v| <= {MAX_COORDINATE:g} mm)")
    if modes.motion in ("G0", "G1"):
        return [end]
    if any(math.isnan(v) for v in start):
        raise InputError(f"{where}: an arc cannot be the first move (its start is unknown)")
    turned = [a for a, s, e in zip(letters[3:], start[3:], end[3:]) if s != e]
    if turned:
        raise InputError(f"{where}: an arc cannot turn a rotary axis ({', '.join(turned)}); program the rotary move "
                         "in G1 blocks")
    ccw = modes.motion == "G3"
    xyz_start, xyz_end = np.array(start[:3]), np.array(end[:3])
    centre = _arc_centre(xyz_start, xyz_end, words, ccw, modes.arc_absolute, where)
    points = _arc_points(xyz_start, xyz_end, centre, ccw, chord_tol, where)
    return np.hstack([points, np.broadcast_to(end[3:], (len(points), len(end) - 3))]).tolist()


DOGLEG_NOISE = 1e-6  # mm or deg: smaller G0 steps add no corner to the dog-leg


def _dogleg(start, end, rates):
    """The corners ``[[x, y, z, ...], ...]`` of a G0 from ``start`` to ``end`` with every axis at its
    own rate ``rates (n,)`` from the same instant: an axis stops when it is done, so the path bends
    where each shorter move ends (the last corner is ``end``)."""
    start, end = np.asarray(start, np.float64), np.asarray(end, np.float64)
    d = end - start
    done = np.abs(d) / rates  # s, when each axis arrives
    # an axis that moves less than a written digit (float noise of G91 steps) adds no corner
    corners = np.unique(done[np.abs(d) > DOGLEG_NOISE])
    points = [start + np.sign(d) * np.minimum(np.abs(d), rates * t) for t in corners]
    if not points:
        return [end.tolist()]
    points[-1] = end
    return [p.tolist() for p in points]


# --- 5-axis: joints to tool tips and axes --------------------------------------------------------


def _machine_xyz(machine, joints, tool_length):
    """The machine's X Y Z ``(3,)`` mm that put the tip where TCP words ``joints (n,)`` (tip X Y Z,
    rotaries) do: with the rotaries held the tip is affine in X Y Z, so one linear solve with
    :func:`forward`'s X Y Z columns is exact."""
    probe = np.repeat(joints[None], 4, axis=0)
    probe[:, :3] = np.vstack([np.zeros(3), np.eye(3)])
    tip, _ = forward(machine, probe, tool_length)
    return np.linalg.solve((tip[1:] - tip[0]).T, joints[:3] - tip[0])


def _switched_words(machine, pos, tcp, tool_length):
    """The modal words ``pos`` (n values, ``machine.axes``) for the pose the machine is at, once TCP
    is switched on (``tcp``: X Y Z become the tip) or off (X Y Z become the machine's); X Y Z
    unknown (NaN) while the pose is. ``tool_length`` mm as in :func:`forward`."""
    joints = np.array(pos, np.float64)
    if np.isnan(joints).any():
        joints[:3] = math.nan
    elif tcp:
        joints[:3] = forward(machine, joints[None], tool_length)[0][0]
    else:
        joints[:3] = _machine_xyz(machine, joints, tool_length)
    return joints.tolist()


def _forward_poses(machine, joints, tool_length, tcp):
    """Tip and unit axis ``(k, 3)``, work coordinates, of ``joints (k, n)`` with ``tool_length (k,)``
    mm and ``tcp (k,)`` bool per pose: :func:`forward` by groups of one length and mode."""
    tip, axis = np.empty((len(joints), 3)), np.empty((len(joints), 3))
    for length, on in set(zip(tool_length.tolist(), tcp.tolist())):
        rows = np.flatnonzero((tool_length == length) & (tcp == on))
        for c in range(0, len(rows), POSE_CHUNK):
            chunk = rows[c:c + POSE_CHUNK]
            tip[chunk], axis[chunk] = forward(machine, joints[chunk], length, on)
    return tip, axis


def _chord_distances(points):
    """Distance ``(p, m)`` mm of ``points (p, m, 3)`` from the segment between the first and the
    last point of their row."""
    a, d = points[:, :1], points[:, -1:] - points[:, :1]
    dd = np.einsum("pij,pij->pi", d, d)
    t = np.clip(np.einsum("pmj,pij->pm", points - a, d) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
    return np.linalg.norm(points - a - t[..., None] * d, axis=2)


def _piece_deviation(machine, start, end, pieces, tool_length, reach):
    """Largest distance ``(b,)`` mm, over the pieces of each block, of the tip and of the point
    ``reach (b,)`` mm up the tool axis from the straight piece between the ends of that piece, where
    the joints move linearly from ``start (b, n)`` to ``end (b, n)`` in ``pieces (b,)`` equal steps
    (joints mode, ``tool_length (b,)`` mm); sampled at :data:`SAMPLES` points inside each piece."""
    block = np.repeat(np.arange(len(start)), pieces)
    step = np.arange(len(block)) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    u = np.linspace(0.0, 1.0, SAMPLES + 2)
    out = np.zeros(len(start))
    per_chunk = max(1, POSE_CHUNK // len(u))
    for c in range(0, len(block), per_chunk):
        b, k = block[c:c + per_chunk], step[c:c + per_chunk]
        s = (k[:, None] + u) / pieces[b][:, None]
        joints = start[b][:, None, :] + s[..., None] * (end[b] - start[b])[:, None, :]
        tip, axis = _forward_poses(machine, joints.reshape(-1, start.shape[1]), np.repeat(tool_length[b], len(u)),
                                   np.zeros(len(b) * len(u), bool))
        top = tip + np.repeat(reach[b], len(u))[:, None] * axis
        shape = (len(b), len(u), 3)
        deviation = np.maximum(_chord_distances(tip.reshape(shape)), _chord_distances(top.reshape(shape)))
        np.maximum.at(out, b, deviation.max(axis=1))
    return out


def _joint_pieces(machine, start, end, tool_length, reach, chord_tol, where):
    """Equal joint steps ``(b,)`` for each joint-linear block ``start (b, n)`` -> ``end (b, n)`` that
    keep the tip and the point ``reach (b,)`` mm up the tool within ``chord_tol`` mm of the straight
    pieces (:func:`_piece_deviation`); ``where(i)`` names block i's line for errors."""
    pieces = np.ones(len(start), np.int64)
    todo = np.arange(len(start))
    target = ACCEPT * chord_tol
    while len(todo):
        deviation = _piece_deviation(machine, start[todo], end[todo], pieces[todo], tool_length[todo], reach[todo])
        over = deviation > target
        todo, deviation = todo[over], deviation[over]
        # the deviation of a smooth curve from its chords falls with the square of their number
        grown = np.ceil(1.1 * pieces[todo] * np.sqrt(deviation / target)).astype(np.int64)
        pieces[todo] = np.maximum(pieces[todo] + 1, grown)
        if len(todo) and pieces[todo].max() > MAX_ARC_SEGMENTS:
            raise InputError(f"{where(todo[np.argmax(pieces[todo])])}: the move turns the rotary axes so far that it "
                             f"needs over {MAX_ARC_SEGMENTS} pieces at chord_tol {chord_tol:g} mm")
    return pieces


def _tool_poses(axes, joints, start, tcp, tool_length, reach, chord_tol, where):
    """The tool tips and unit axes of the points read, as straight pieces: ``(tip (m, 3), axis (m,
    3), source (m,))``, ``source`` the point (row of ``joints (k, n)``) each piece ends in. A point
    is a pose reached from ``start (k, n)`` (NaN: the path's first point) with ``tcp (k,)``,
    ``tool_length (k,)`` and ``reach (k,)`` mm of its tool; ``where(i)`` is point i's file:line.
    3-axis: the tips are X Y Z and the axis +Z. 5-axis: :func:`forward`, each joints-mode block
    whose rotaries turn split in :func:`_joint_pieces` equal joint steps, the last at the point."""
    k = len(joints)
    if not axes.five_axis:
        return joints[:, :3].copy(), np.tile([0.0, 0.0, 1.0], (k, 1)), np.arange(k)
    machine = axes.machine
    tip, axis = _forward_poses(machine, joints, tool_length, tcp)
    turning = np.flatnonzero(~tcp & ~np.isnan(start).any(axis=1) & (start[:, 3:] != joints[:, 3:]).any(axis=1))
    pieces = np.ones(k, np.int64)
    pieces[turning] = _joint_pieces(machine, start[turning], joints[turning], tool_length[turning], reach[turning],
                                    chord_tol, lambda i: where(turning[i]))
    inner = pieces - 1
    block = np.repeat(np.arange(k), inner)
    s = (np.arange(len(block)) - np.repeat(np.cumsum(inner) - inner, inner) + 1) / pieces[block]
    inserted = start[block] + s[:, None] * (joints[block] - start[block])
    source = np.repeat(np.arange(k), pieces)
    at_point = np.zeros(len(source), bool)
    at_point[np.cumsum(pieces) - 1] = True
    out_tip, out_axis = np.empty((len(source), 3)), np.empty((len(source), 3))
    out_tip[at_point], out_axis[at_point] = tip, axis
    out_tip[~at_point], out_axis[~at_point] = _forward_poses(machine, inserted, tool_length[block],
                                                            np.zeros(len(block), bool))
    return out_tip, out_axis, source


def read_gcode(path, tools, tool_name=None, chord_tol=0.001, machine=None) -> tuple[Toolpath, list[str]]:
    """Read a G-code file (see the module notes); moves refer to ``tools`` by ``T`` words, else to
    ``tool_name`` or the table's only tool. ``machine``: a
    :class:`~meshmill.machine.model.Machine` whose 5-axis kinematics turn the axis words into tool
    tips and axes (None or a 3-axis machine: X Y Z are the tip, the axis +Z); ``chord_tol`` mm: how
    far arcs and the tip of joint-linear rotary moves may stray from the straight moves that stand
    for them. Returns the tool path (``tip``, ``axis (m, 3)``; ``line`` the source line of each
    point) and warnings."""
    if not chord_tol > 0:
        raise InputError(f"chord_tol must be > 0 mm, got {chord_tol}")
    path = os.fspath(path)
    text = _read_text(path)
    name = os.path.basename(path)
    axes = _Axes.of(machine)
    rates = axes.g0_rates()
    modes = _Modes()
    pos = [math.nan] * len(axes.letters)
    tool, t_given = -1, False
    ends, starts, tcp, rapid, tool_idx, lines = [], [], [], [], [], []
    warnings = []
    for number, raw in enumerate(text.splitlines(), start=1):
        where = f"{name}:{number}"
        parsed = _parse_line(raw, where, axes)
        if parsed is None:
            continue
        gcodes, words = parsed
        was_tcp = modes.tcp
        machine_code = _apply_g_codes(modes, gcodes, where, axes)
        words = _scaled(words, modes.scale, where)
        if "T" in words:
            tool, t_given = _tool_index(words["T"], tools, where), True
        if modes.tcp != was_tcp:
            length = 0.0
            if machine.chain.head_pivot and not any(math.isnan(v) for v in pos):
                length = tools[tool if tool >= 0 else _default_tool(tools, tool_name, path)].spindle_length
            pos = _switched_words(machine, pos, modes.tcp, length)
        if machine_code:
            # a Z-only retract in machine coordinates (at the end, or before a tool change): the
            # tool goes up to where we cannot say; the path goes on where X Y Z are all given again
            _check_end_retract(machine_code, words, modes, pos, bool(ends), where)
            warnings.append(f"{where}: {machine_code} Z{words['Z']:g} (a retract in machine coordinates) "
                            "is not in the tool path")
            pos = list(pos)
            pos[2] = math.nan
            continue
        arc_words = modes.motion in ("G2", "G3") and any(k in words for k in "IJR")
        if "G4" in gcodes or not (arc_words or any(k in words for k in axes.letters)):
            continue
        if modes.motion is None:
            raise InputError(f"{where}: coordinates without G0, G1, G2 or G3")
        if modes.inverse_time and modes.motion != "G0" and "F" not in words:
            raise InputError(f"{where}: {modes.motion} in inverse-time mode (G93) without F: the control stops here "
                             "(each G93 feed block needs its own F, 1 / minutes)")
        before = pos
        if any(math.isnan(v) for v in pos) and modes.motion in ("G0", "G1"):
            # the start is unknown until every axis has been given absolutely
            pos = _target(modes, pos, words, axes.letters)
            if any(math.isnan(v) for v in pos):
                continue
            points = [pos]
        else:
            points = _move(modes, pos, words, axes.letters, chord_tol, where)
            if modes.motion == "G0" and rates is not None and not modes.tcp:
                points = _dogleg(pos, points[-1], rates)
        ends += points
        starts += [before] + points[:-1]
        tcp += [modes.tcp] * len(points)
        rapid += [modes.motion == "G0"] * len(points)
        tool_idx += [tool] * len(points)
        lines += [number] * len(points)
        pos = points[-1]
    if not ends:
        missing = [a for a, v in zip(axes.letters, pos) if math.isnan(v)]
        raise InputError(f"{path}: no moves" + (f" (the path starts where {_listed(axes.letters)} have all been given "
                                                f"absolutely; never: {', '.join(missing)})" if missing else ""))
    if modes.offsets:
        warnings.append(f"{name}: work offsets ({', '.join(sorted(modes.offsets))}) are not applied; "
                        "coordinates are read as given")
    tool_idx, lines = np.array(tool_idx, np.int64), np.array(lines, np.int64)
    if t_given:
        if tool_name is not None:
            warnings.append(f"{name}: the program's T words select the tools; '{tool_name}' is not used")
        if (tool_idx < 0).any():
            raise InputError(f"{name}:{lines[np.argmax(tool_idx < 0)]}: move before the first T word")
    else:
        tool_idx[:] = _default_tool(tools, tool_name, path)
    head_table = machine is not None and machine.chain.head_pivot
    tool_length = np.array([t.spindle_length if head_table else 0.0 for t in tools])[tool_idx]
    if head_table and not np.array(tcp, bool).all():  # joint moves of a head-table program
        warnings += [w for w in (tools[i].spindle_length_warning() for i in np.unique(tool_idx)) if w]
    reach = np.array([t.reach for t in tools])[tool_idx]
    tip, axis, source = _tool_poses(axes, np.array(ends, np.float64), np.array(starts, np.float64),
                                    np.array(tcp, bool), tool_length, reach, chord_tol, lambda i: f"{name}:{lines[i]}")
    tp = Toolpath(tip=tip, axis=axis, rapid=np.array(rapid, bool)[source], tool=tool_idx[source], line=lines[source])
    return tp, warnings
