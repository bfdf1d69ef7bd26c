"""APT cutter-location (CL) files: one statement a line.

Written: ``PARTNO``, ``UNITS/MM``, ``MULTAX/ON``, ``CUTTER/diameter, corner_radius`` and
``LOADTL/n`` at each tool change (n: the tool's 1-based position in the table), ``RAPID`` before
each rapid ``GOTO``, ``GOTO/x, y, z, i, j, k`` (tool tip and unit tool axis), ``FINI``.

Read: the same, plus what other CAM systems write: ``$$`` comments, ``$`` continuation lines,
``GOTO/x, y, z`` without an axis (vertical), ``CUTTER/`` with up to seven parameters,
``UNITS/INCHES`` (every length after it times 25.4), and the statements of :data:`HARMLESS`
(feeds, spindle, coolant, comments, tolerances...), which do not move the tool and are skipped.
``ROTABL``, ``TLAXIS`` and the others of :data:`IGNORED_WITH_WARNING` are skipped with a warning.
Every other statement is refused with ``file:line``: a move we cannot read (``CIRCLE``, ``GODLTA``,
``CYCLE``, ``ORIGIN``, a ``GOTO`` without its slash, a garbled word) would otherwise vanish from
the path, and the path would be checked, simulated and posted without it.
"""
from __future__ import annotations

import math
import os

import numpy as np

from ..errors import InputError
from .model import Toolpath

MAX_COORDINATE = 1e6  # mm: a kilometre is no machine's travel
IGNORED_WITH_WARNING = ("ROTABL", "TLAXIS", "INDIRV", "TLON", "TLLFT", "TLRGT", "INSERT", "PPFUN")
# statements that neither move the tool nor change how the moves are read
HARMLESS = ("PARTNO", "MULTAX", "MACHIN", "FEDRAT", "SPINDL", "COOLNT", "SELCTL", "PPRINT", "DISPLY", "TOLER",
            "INTOL", "OUTTOL", "CLRSRF", "CLEARP", "OPSTOP", "STOP", "OPSKIP", "DELAY", "AUTOPS", "NOPOST",
            "TITLES", "REMARK", "SEQNO", "END", "LEADER", "OPNAME", "TPRINT", "MCHTOL")
REFUSED = {
    "CIRCLE": "circular moves (CIRCLE/ before a GOTO) are not read: output linear moves",
    "GODLTA": "incremental moves (GODLTA) are not read: output GOTO",
    "CYCLE": "canned cycles are not read: output the moves",
    "ORIGIN": "ORIGIN shifts the coordinates, which this reader does not apply",
    "TRANS": "TRANS shifts the coordinates, which this reader does not apply",
    "FROM": "FROM (the start position) is not read: output it as RAPID and GOTO",
    "GOFWD": "drive-surface motion (GOFWD, GOLFT, ...) is not read: output GOTO",
    "GOLFT": "drive-surface motion (GOFWD, GOLFT, ...) is not read: output GOTO",
    "GORGT": "drive-surface motion (GOFWD, GOLFT, ...) is not read: output GOTO",
    "GOBACK": "drive-surface motion (GOFWD, GOLFT, ...) is not read: output GOTO",
    "GOUP": "drive-surface motion (GOFWD, GOLFT, ...) is not read: output GOTO",
    "GODOWN": "drive-surface motion (GOFWD, GOLFT, ...) is not read: output GOTO",
    "CUTCOM": "cutter compensation changes the moves, which this reader does not apply",
    "TRACUT": "TRACUT transforms the moves, which this reader does not apply",
    "COPY": "COPY repeats moves, which this reader does not apply",
}
INCH = 25.4  # mm


def write_apt(path, toolpath: Toolpath, tools, partno="meshmill") -> None:
    """Write ``toolpath`` (tool indices into ``tools``) as an APT CL file: ``SPINDL/rpm`` after a
    tool's ``LOADTL`` where the table gives its speed, ``FEDRAT/f, MMPM`` where a feed move's
    programmed feed (mm/min, :attr:`Toolpath.feed`) changes."""
    lines = [f"PARTNO/{partno}", "UNITS/MM", "MULTAX/ON"]
    current = -1
    goto = "GOTO/%.6f, %.6f, %.6f, %.9f, %.9f, %.9f"
    rows = np.hstack([toolpath.tip, toolpath.axis]).tolist()  # python floats: formatted fast
    fed = np.nan
    for t, rapid, row, f in zip(toolpath.tool.tolist(), toolpath.rapid.tolist(), rows, toolpath.feed.tolist()):
        if t != current:
            lines.append(tools[t].apt_cutter())
            lines.append(f"LOADTL/{tools[t].number}")
            if tools[t].rpm > 0:
                lines.append(f"SPINDL/RPM, {tools[t].rpm:.0f}, CLW")
            current = t
            fed = np.nan
        if rapid:
            lines.append("RAPID")
        elif f == f and f != fed:  # (f == f: not NaN)
            lines.append(f"FEDRAT/{f:.1f}, MMPM")
            fed = f
        lines.append(goto % tuple(row))
    lines.append("FINI")
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")


def read_text(path, kind, text_kind=None) -> str:
    """The UTF-8 text of a tool-path file; a missing, unreadable or binary file is an
    :class:`InputError` naming it as a ``kind`` file (``text_kind`` in the binary case)."""
    if not os.path.exists(path):
        raise InputError(f"{path}: no such {kind} file")
    try:
        with open(path, encoding="utf-8", errors="strict") as fh:
            return fh.read()
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text {text_kind or kind} file") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None


def _statements(text):
    """Yield ``(line_number, statement)`` with comments removed and continuations joined."""
    pending = ""
    start = 0
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("$$"):
            continue
        if "$$" in line:
            line = line[: line.index("$$")].strip()
        if not pending:
            start = number
        if line.endswith("$"):
            pending += line[:-1]
            continue
        yield start, pending + line
        pending = ""
    if pending:
        yield start, pending


def _numbers(args, where, scale=1.0):
    """The comma-separated numbers of ``args`` times ``scale`` (a unit's mm); range-checked in mm."""
    out = []
    for a in args.split(","):
        a = a.strip()
        if not a:
            continue
        try:
            v = float(a)
        except ValueError:
            raise InputError(f"{where}: expected numbers, got '{a}'") from None
        if not math.isfinite(v):
            raise InputError(f"{where}: NaN or infinite value")
        v *= scale
        if abs(v) > MAX_COORDINATE:
            raise InputError(f"{where}: value {v:g} is out of range (|v| <= {MAX_COORDINATE:g} mm)")
        out.append(v)
    return out


def _tool_for_cutter(values, tools, where):
    d = values[0]
    r = values[1] if len(values) > 1 else 0.0
    for i, tool in enumerate(tools):  # within 0.1 µm: a size written in inches to 6 decimals matches
        if abs(tool.diameter - d) <= 1e-4 and abs(tool.corner_radius - r) <= 1e-4:
            return i
    raise InputError(f"{where}: CUTTER/{d:g}, {r:g} matches no tool in the table")


def read_apt(path, tools) -> tuple[Toolpath, list[str]]:
    """Read an APT CL file; moves refer to ``tools`` by ``LOADTL/n`` or, failing that, by
    matching ``CUTTER/`` diameter and corner radius. Returns the tool path and warnings."""
    path = os.fspath(path)
    text = read_text(path, "CL", "APT CL")
    name = os.path.basename(path)
    tips, axes, rapid, tool_idx, lines = [], [], [], [], []
    warnings = []
    skipped = {}
    current = -1
    cutter = None
    next_rapid = False
    scale = 1.0  # mm per unit of the file (UNITS/INCHES: 25.4)
    for number, stmt in _statements(text):
        where = f"{name}:{number}"
        word, slash, args = stmt.partition("/")
        word = word.strip().upper()
        if not slash and word not in ("RAPID", "FINI", "END") and not word.isalpha():
            raise InputError(f"{where}: cannot read '{stmt.strip()[:40]}' (an APT statement is WORD or WORD/arguments)")
        if word == "GOTO":
            v = _numbers(args, where, scale)
            if len(v) not in (3, 6):
                raise InputError(f"{where}: GOTO needs x, y, z or x, y, z, i, j, k")
            if current < 0:
                if cutter is None:
                    raise InputError(f"{where}: GOTO before any CUTTER/ or LOADTL/")
                current = _tool_for_cutter(cutter, tools, where)
            axis = [a / scale for a in v[3:]] if len(v) == 6 else [0.0, 0.0, 1.0]
            n = math.sqrt(sum(a * a for a in axis))
            if n < 1e-9:
                raise InputError(f"{where}: zero-length tool axis")
            tips.append(v[:3])
            axes.append([a / n for a in axis])
            rapid.append(next_rapid)
            tool_idx.append(current)
            lines.append(number)
            next_rapid = False
        elif word == "RAPID":
            next_rapid = True
        elif word == "UNITS":
            unit = args.strip().upper()
            if unit in ("MM", "MILLIMETERS", "MILLIMETRES"):
                scale = 1.0
            elif unit in ("INCHES", "INCH", "IN"):
                scale = INCH
            else:
                raise InputError(f"{where}: UNITS/{args.strip()}: only UNITS/MM and UNITS/INCHES are known")
        elif word == "CUTTER":
            cutter = _numbers(args, where, scale)
            if not cutter or cutter[0] <= 0:
                raise InputError(f"{where}: CUTTER needs a positive diameter")
            current = -1
        elif word == "LOADTL":
            v = _numbers(args, where)
            if not v or int(v[0]) != v[0] or not 1 <= int(v[0]) <= len(tools):
                raise InputError(f"{where}: LOADTL/{args.strip()} is not a tool of the table (1..{len(tools)})")
            current = int(v[0]) - 1
        elif word == "FINI":
            break
        elif word in IGNORED_WITH_WARNING:
            skipped[word] = skipped.get(word, 0) + 1
        elif word in REFUSED:
            raise InputError(f"{where}: {word}: {REFUSED[word]}")
        elif word not in HARMLESS:
            shown = word if len(word) <= 20 else word[:20] + "..."
            raise InputError(f"{where}: unknown statement '{shown}' (refused: a move it stands for would be lost)")
    for word, count in skipped.items():
        warnings.append(f"{name}: ignored {count} {word} statement(s)")
    if not tips:
        raise InputError(f"{path}: no GOTO moves")
    tp = Toolpath(tip=np.array(tips, np.float64), axis=np.array(axes, np.float64), rapid=np.array(rapid, bool),
                  tool=np.array(tool_idx, np.int64), line=np.array(lines, np.int64))
    return tp, warnings
