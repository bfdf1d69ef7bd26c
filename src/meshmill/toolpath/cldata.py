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
from .decimals import fixed_rows, read_fixed, row_text
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
GOTO_DECIMALS = (6, 6, 6, 9, 9, 9)  # tip (mm), unit axis


def write_apt(path, toolpath: Toolpath, tools, partno="meshmill") -> None:
    """Write ``toolpath`` (tool indices into ``tools``) as an APT CL file: ``SPINDL/rpm`` after a
    tool's ``LOADTL`` where the table gives its speed, ``FEDRAT/f, MMPM`` where a feed move's
    programmed feed (mm/min, :attr:`Toolpath.feed`) changes. The ``GOTO`` lines are written by
    :func:`~meshmill.toolpath.decimals.fixed_rows`; only the moves that other statements
    precede are looked at one by one."""
    n = len(toolpath)
    rows = np.hstack([toolpath.tip, toolpath.axis])
    text, ends, odd = fixed_rows(rows, GOTO_DECIMALS, "GOTO/", ", ")
    tool, rapid, feed = np.asarray(toolpath.tool), np.asarray(toolpath.rapid, bool), np.asarray(toolpath.feed)
    change = np.ones(n, bool)
    change[1:] = tool[1:] != tool[:-1]
    # a FEDRAT where a fed move's feed is not the one the last FEDRAT since the tool's load set
    fed = np.nonzero(~rapid & ~np.isnan(feed))[0]
    new_feed = np.ones(len(fed), bool)
    load = np.cumsum(change)[fed]
    new_feed[1:] = (load[1:] != load[:-1]) | (feed[fed][1:] != feed[fed][:-1])
    fedrat = np.zeros(n, bool)
    fedrat[fed[new_feed]] = True
    out = [f"PARTNO/{partno}\nUNITS/MM\nMULTAX/ON\n".encode()]
    done = 0  # moves written so far
    for i in np.nonzero(change | rapid | fedrat | odd)[0].tolist():
        out.append(text[ends[done]:ends[i]])
        head = []
        if change[i]:
            t = tools[int(tool[i])]
            head += [t.apt_cutter(), f"LOADTL/{t.number}"] + ([f"SPINDL/RPM, {t.rpm:.0f}, CLW"] if t.rpm > 0 else [])
        if rapid[i]:
            head.append("RAPID")
        elif fedrat[i]:
            head.append(f"FEDRAT/{feed[i]:.1f}, MMPM")
        out.append(("\n".join(head) + "\n").encode() if head else b"")
        out.append(row_text(rows[i].tolist(), GOTO_DECIMALS, "GOTO/", ", ").encode() if odd[i] else
                   text[ends[i]:ends[i + 1]])
        done = i + 1
    out.append(text[ends[done]:ends[n]])
    out.append(b"FINI\n")
    with open(path, "wb") as fh:
        fh.write(b"".join(out))


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
        if not pending and raw.startswith("GOTO/") and "$" not in raw and not raw[-1].isspace():
            yield number, raw  # (the usual line: a statement as it stands)
            continue
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


def _goto(args, where, scale):
    """``(tip (3,), axis (3,))`` of one GOTO's ``args``: tip in mm, unit axis (z without one)."""
    v = _numbers(args, where, scale)
    if len(v) not in (3, 6):
        raise InputError(f"{where}: GOTO needs x, y, z or x, y, z, i, j, k")
    axis = [a / scale for a in v[3:]] if len(v) == 6 else [0.0, 0.0, 1.0]
    n = math.sqrt(sum(a * a for a in axis))
    if n < 1e-9:
        raise InputError(f"{where}: zero-length tool axis")
    return v[:3], [a / n for a in axis]


def _gotos_at_once(flat, counts, scales):
    """``(tips, axes)`` of :func:`_gotos` from all their numbers ``flat`` (``counts (k,)``, 3 or 6
    each), or None where some value is not finite or out of range, or an axis is zero."""
    k = len(counts)
    first = np.cumsum(counts) - counts
    six = counts == 6
    scale = np.asarray(scales, np.float64)
    vals = flat * np.repeat(scale, counts)
    tips = vals[first[:, None] + np.arange(3)]
    axes = np.zeros((k, 3))
    axes[:, 2] = 1.0
    axes[six] = vals[first[six, None] + np.arange(3, 6)] / scale[six, None]
    n = np.sqrt(axes[:, 0] * axes[:, 0] + axes[:, 1] * axes[:, 1] + axes[:, 2] * axes[:, 2])
    if np.isfinite(vals).all() and (np.abs(vals) <= MAX_COORDINATE).all() and (n >= 1e-9).all():
        return tips, axes / n[:, None]
    return None


def _gotos(args, name, lines, scales) -> tuple[np.ndarray, np.ndarray]:
    """``(tips (k, 3), axes (k, 3))`` of GOTO statements ``args`` on ``lines`` of file ``name`` in
    units of ``scales`` mm (as :func:`_goto`, the numbers read at once; when some statement reads
    otherwise, such as with an empty item or a bad number, one by one: its error)."""
    k = len(args)
    try:
        counts = np.fromiter((a.count(",") for a in args), np.int64, k) + 1
        joined = ",".join(args)
        flat = read_fixed(joined, int(counts.sum())) if k else np.zeros(0)  # (plain decimals: compiled)
        if flat is None:
            flat = np.array(joined.split(","), dtype=np.float64)
    except ValueError:
        counts = flat = None
    if flat is not None and np.isin(counts, (3, 6)).all():
        with np.errstate(over="ignore", invalid="ignore"):  # such values are read one by one below
            done = _gotos_at_once(flat, counts, scales)
        if done is not None:
            return done
    read = [_goto(a, f"{name}:{line}", scale) for a, line, scale in zip(args, lines, scales)]  # or the first error
    return np.array([t for t, _ in read], np.float64), np.array([x for _, x in read], np.float64)


def read_apt(path, tools) -> tuple[Toolpath, list[str]]:
    """Read an APT CL file; moves refer to ``tools`` by ``LOADTL/n`` or, failing that, by
    matching ``CUTTER/`` diameter and corner radius. Returns the tool path and warnings."""
    path = os.fspath(path)
    text = read_text(path, "CL", "APT CL")
    name = os.path.basename(path)
    goto, scales, rapid, tool_idx, lines = [], [], [], [], []
    warnings = []
    skipped = {}
    try:
        _read_statements(text, name, tools, goto, scales, rapid, tool_idx, lines, skipped)
    except InputError:
        _gotos(goto, name, lines, scales)  # a GOTO before the statement that failed may have failed first
        raise
    for word, count in skipped.items():
        warnings.append(f"{name}: ignored {count} {word} statement(s)")
    if not goto:
        raise InputError(f"{path}: no GOTO moves")
    tips, axes = _gotos(goto, name, lines, scales)
    tp = Toolpath(tip=tips, axis=axes, rapid=np.array(rapid, bool), tool=np.array(tool_idx, np.int64),
                  line=np.array(lines, np.int64))
    return tp, warnings


def _read_statements(text, name, tools, goto, scales, rapid, tool_idx, lines, skipped):
    """The statements of an APT CL ``text``: each GOTO's arguments, unit, whether it is rapid, its
    tool and line appended to the lists given (its numbers are read later, all at
    once); the statements ignored counted in ``skipped``."""
    current = -1
    cutter = None
    next_rapid = False
    scale = 1.0  # mm per unit of the file (UNITS/INCHES: 25.4)
    for number, stmt in _statements(text):
        if stmt.startswith("GOTO/"):  # (the usual statement: no parsing of its word)
            word, args = "GOTO", stmt[5:]
        else:
            word, slash, args = stmt.partition("/")
            word = word.strip().upper()
            if not slash and word not in ("RAPID", "FINI", "END") and not word.isalpha():
                raise InputError(f"{name}:{number}: cannot read '{stmt.strip()[:40]}' (an APT statement is WORD "
                                 "or WORD/arguments)")
        if word == "GOTO":
            if current < 0:
                where = f"{name}:{number}"
                if len(_numbers(args, where, scale)) not in (3, 6):  # its numbers' errors first
                    raise InputError(f"{where}: GOTO needs x, y, z or x, y, z, i, j, k")
                if cutter is None:
                    raise InputError(f"{where}: GOTO before any CUTTER/ or LOADTL/")
                current = _tool_for_cutter(cutter, tools, where)
            goto.append(args)
            scales.append(scale)
            rapid.append(next_rapid)
            tool_idx.append(current)
            lines.append(number)
            next_rapid = False
            continue
        where = f"{name}:{number}"
        if word == "RAPID":
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
