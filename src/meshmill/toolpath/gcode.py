"""3-axis G-code (RS-274 / ISO 6983) read into a :class:`Toolpath`; the tool axis is always +Z.

Read:

- ``G0`` rapid, ``G1`` linear, ``G2``/``G3`` clockwise/counter-clockwise arcs in the XY plane
  (``G17``), given by ``I J`` (centre offset from the start point; ``G91.1``, the default, or
  absolute with ``G90.1``) or by ``R`` (radius; ``R < 0`` means the arc longer than 180 degrees).
  A ``G2``/``G3`` whose end equals its start (with ``I J``) is a full circle; Z changing along an
  arc makes a helix, Z linear in the angle. Arcs become linear moves whose chord deviation
  (sagitta) is at most ``chord_tol`` mm, ending exactly at the programmed end.
- Motion is modal: a line with only coordinates repeats the last ``G0``-``G3``.
- ``G90``/``G91`` absolute/incremental coordinates, ``G20`` inch (X Y Z I J K R times 25.4),
  ``G21`` mm.
- ``T<n>`` selects the tool whose ``number`` is n for the moves that follow (``M6`` or not); a
  move before the first T word is refused. With no T word in the program: the tool named
  ``tool_name``, else the table's only tool.
- Skipped: ``F S M N O P H D Q`` words, ``%`` lines, ``( ... )`` and ``; ...`` comments, ``G4``
  (dwell; its line does not move), ``G17 G40 G43 G49 G61 G64 G80 G94``; ``G54``-``G59`` with a
  warning that work offsets are not applied.

Refused with :class:`InputError` naming ``file:line``: ``G18``/``G19`` arcs, ``G41``/``G42``
cutter compensation, canned cycles ``G81``-``G89``, ``G28``/``G30``/``G53`` (machine coordinates
are unknown), other G codes and letters, malformed or non-finite numbers, values beyond 1e6 mm.
The machine starts at an unknown place: the path starts at the first point where X, Y and Z have
all been given (absolutely, by ``G0``/``G1``, over one or more lines); an arc cannot come before it,
and a program that never gives all three has no moves.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .cldata import MAX_COORDINATE, read_text
from .model import Toolpath

MOTION = ("G0", "G1", "G2", "G3")
IGNORED_G = {"G4", "G17", "G40", "G43", "G49", "G61", "G64", "G80", "G94"}
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
LENGTH_LETTERS = "XYZIJKR"
SKIPPED_LETTERS = "FSMNOPHDQ"
KNOWN_LETTERS = set(LENGTH_LETTERS + SKIPPED_LETTERS + "T")
INCH = 25.4
FULL_CIRCLE_GAP = 1e-6  # mm: an arc ending this close to its start is a full circle
MAX_ARC_SEGMENTS = 1_000_000

_NUMBER = r"[+-]?(?:\d+\.?\d*|\.\d+)"
_WORD = re.compile(rf"([A-Z])({_NUMBER})")
_LINE = re.compile(rf"(?:[A-Z]{_NUMBER})+")
_COMMENT = re.compile(r"\([^)]*\)")


@dataclass
class _Modes:
    motion: str | None = None
    absolute: bool = True
    arc_absolute: bool = False
    scale: float = 1.0
    offsets: set = field(default_factory=set)


def _read_text(path):
    text = read_text(path, "G-code")
    if "\x00" in text:
        raise InputError(f"{path}: not a text G-code file")
    if not text.strip():
        raise InputError(f"{path}: empty G-code file")
    return text


def _parse_line(raw, where):
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
        elif letter not in KNOWN_LETTERS:
            raise InputError(f"{where}: unsupported word {letter}{text}")
        elif letter in words and letter not in SKIPPED_LETTERS:
            raise InputError(f"{where}: {letter} given twice")
        else:
            words[letter] = value
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


def _apply_g_codes(modes, gcodes, where):
    motions = [g for g in gcodes if g in MOTION]
    if len(motions) > 1:
        raise InputError(f"{where}: two motion codes ({' '.join(motions)}) on one line")
    for g in gcodes:
        if g in MOTION:
            modes.motion = g
        elif g in ("G20", "G21"):
            modes.scale = INCH if g == "G20" else 1.0
        elif g in ("G90", "G91"):
            modes.absolute = g == "G90"
        elif g in ("G90.1", "G91.1"):
            modes.arc_absolute = g == "G90.1"
        elif g in WORK_OFFSETS:
            modes.offsets.add(g)
        elif g in REFUSED_G:
            raise InputError(f"{where}: {g}: {REFUSED_G[g]}")
        elif g not in IGNORED_G:
            raise InputError(f"{where}: unknown G code {g}")


def _scaled(words, scale, where):
    out = {k: v * scale if k in LENGTH_LETTERS else v for k, v in words.items()}
    for k, v in out.items():
        if abs(v) > MAX_COORDINATE:
            raise InputError(f"{where}: {k} {v:g} is out of range (|v| <= {MAX_COORDINATE:g} mm)")
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


def _move(modes, start, words, chord_tol, where):
    """The points ``[[x, y, z], ...]`` of one programmed move from ``start`` (NaN: not known yet)."""
    end = list(start)
    for i, axis in enumerate("XYZ"):
        if axis in words:
            end[i] = words[axis] if modes.absolute else end[i] + words[axis]
    if any(math.isnan(v) for v in end):
        raise InputError(f"{where}: first move does not give X, Y and Z")
    if max(map(abs, end)) > MAX_COORDINATE:
        raise InputError(f"{where}: the move ends out of range (|v| <= {MAX_COORDINATE:g} mm)")
    if modes.motion in ("G0", "G1"):
        return [end]
    if any(math.isnan(v) for v in start):
        raise InputError(f"{where}: an arc cannot be the first move (its start is unknown)")
    ccw = modes.motion == "G3"
    start, end = np.array(start), np.array(end)
    centre = _arc_centre(start, end, words, ccw, modes.arc_absolute, where)
    return _arc_points(start, end, centre, ccw, chord_tol, where).tolist()


def read_gcode(path, tools, tool_name=None, chord_tol=0.001) -> tuple[Toolpath, list[str]]:
    """Read a 3-axis G-code file (see the module notes); moves refer to ``tools`` by ``T`` words,
    else to ``tool_name`` or the table's only tool. Returns the tool path and warnings."""
    if not chord_tol > 0:
        raise InputError(f"chord_tol must be > 0 mm, got {chord_tol}")
    path = os.fspath(path)
    text = _read_text(path)
    name = os.path.basename(path)
    modes = _Modes()
    pos = [math.nan] * 3
    tool, t_given = -1, False
    tips, rapid, tool_idx, lines = [], [], [], []
    for number, raw in enumerate(text.splitlines(), start=1):
        where = f"{name}:{number}"
        parsed = _parse_line(raw, where)
        if parsed is None:
            continue
        gcodes, words = parsed
        _apply_g_codes(modes, gcodes, where)
        words = _scaled(words, modes.scale, where)
        if "T" in words:
            tool, t_given = _tool_index(words["T"], tools, where), True
        arc_words = modes.motion in ("G2", "G3") and any(k in words for k in "IJR")
        if "G4" in gcodes or not (arc_words or any(k in words for k in "XYZ")):
            continue
        if modes.motion is None:
            raise InputError(f"{where}: coordinates without G0, G1, G2 or G3")
        if any(math.isnan(v) for v in pos) and modes.motion in ("G0", "G1"):
            # the start is unknown until X, Y and Z have all been given absolutely
            pos = [words[a] if a in words and modes.absolute else pos[i] for i, a in enumerate("XYZ")]
            if any(math.isnan(v) for v in pos):
                continue
            points = [pos]
        else:
            points = _move(modes, pos, words, chord_tol, where)
        tips += points
        rapid += [modes.motion == "G0"] * len(points)
        tool_idx += [tool] * len(points)
        lines += [number] * len(points)
        pos = points[-1]
    if not tips:
        raise InputError(f"{path}: no moves")
    warnings = []
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
    tp = Toolpath(tip=np.array(tips, np.float64), axis=np.tile([0.0, 0.0, 1.0], (len(tips), 1)),
                  rapid=np.array(rapid, bool), tool=tool_idx, line=lines)
    return tp, warnings
