"""Jerk-limited machining time (seed 002 §1.6.2): straight segments from rest to rest.

Units: mm, s. A segment of length L with feed limit V, acceleration limit A and jerk limit J takes
L/v + T_acc(v), where v <= V is the highest speed it reaches and T_acc(v) the time of one
S-curve speed-up to v: v/A + A/J when A is reached (v >= A²/J), 2 sqrt(v/J) otherwise. This is the
seed's eqs. 1.13-1.15 (case 1: V and A reached, case 2: V only, case 3: neither, t = 4 ∛(L/(2J)))
plus the fourth case (A reached, V not) that the seed's parameters never meet.

A tool path is timed as such segments (:func:`path_time`, :func:`tool_times`): it comes to rest
where rapid and feed moves meet, at tool changes and at turns sharper than the machine's corner
angle, and runs straight through the gentler turns between. :func:`programmed_feeds` reads the
feed rates of APT and G-code files.
"""
from __future__ import annotations

import os
import re

import numpy as np

from ..toolpath.cldata import read_text


def segment_time(length, v_max, accel, jerk):
    """Time ``(...)`` s to travel ``length (...)`` mm on a straight line from rest to rest."""
    L = np.maximum(np.asarray(length, float), 0.0)
    v_a = accel * accel / jerk  # the speed gained while the jerk ramps the acceleration up and down
    # highest speed the length allows: v T_acc(v) = L
    v_jerk = np.cbrt(L * L * jerk / 4.0)  # A not reached: v · 2 sqrt(v/J) = L
    b = accel / jerk
    v_acc = 0.5 * accel * (-b + np.sqrt(b * b + 4.0 * L / accel))  # A reached: v²/A + v A/J = L
    v_len = np.where(v_jerk <= v_a, v_jerk, v_acc)
    v = np.minimum(v_len, v_max)
    t_acc = np.where(v >= v_a, v / accel + accel / jerk, 2.0 * np.sqrt(v / jerk))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(L > 0.0, L / v + t_acc, 0.0)
    return t if t.ndim else float(t)


# --- tool paths -----------------------------------------------------------------------------------

MIN_MOVE = 1e-6  # mm: a shorter move has no direction; it takes no time and never stops the tool


def _limits(machine, corner_angle):
    """``(MotionLimits, corner angle rad)`` of a Machine or of bare MotionLimits and an angle."""
    motion = getattr(machine, "motion", machine)
    if corner_angle is None:
        if motion is machine:
            raise ValueError("corner_angle is needed with bare MotionLimits")
        corner_angle = machine.corner_angle
    return motion, float(corner_angle)


def _runs(tip, rapid, motion, corner_angle, feed=None, tool=None, rotary_s=None):
    """The path's rest-to-rest runs: ``(length (r,) mm, seconds (r,), rapid (r,) bool, tool (r,)
    or None)``.

    Move i goes from ``tip[i-1]`` to ``tip[i]``; ``rapid[i]``, ``feed[i]`` (mm/s, NaN: the nominal
    feed) and ``tool[i]`` describe it. A run ends where rapid and feed moves meet, where the tool
    changes and where the direction turns by more than ``corner_angle``. Its time is that of one
    straight segment of its length whose cruise time is that of its moves at their own speeds
    (the speed limit of the segment is the length-weighted harmonic mean of theirs), and at least
    the sum of its moves' ``rotary_s (k,)`` (the seconds the rotary axes need for each move).
    """
    tip = np.asarray(tip, np.float64)
    step = np.diff(tip, axis=0)
    length = np.sqrt(np.einsum("ij,ij->i", step, step))
    end = np.flatnonzero(length > MIN_MOVE) + 1  # the vertex each kept move ends at
    if not len(end):
        return np.zeros(0), np.zeros(0), np.zeros(0, bool), None if tool is None else np.zeros(0, np.int64)
    length = length[end - 1]
    direction = step[end - 1] / length[:, None]
    is_rapid = np.asarray(rapid, bool)[end]
    speed = np.where(is_rapid, motion.rapid, motion.feed)
    if feed is not None:
        programmed = np.asarray(feed, np.float64)[end]
        given = ~np.isnan(programmed)
        if (programmed[given] <= 0).any() or np.isinf(programmed).any():
            raise ValueError("feed must be a positive finite number of mm/s (or NaN)")
        speed = np.where(given & ~is_rapid, np.minimum(programmed, motion.rapid), speed)
    cross = np.cross(direction[1:], direction[:-1])
    turn = np.arctan2(np.sqrt(np.einsum("ij,ij->i", cross, cross)),
                      np.einsum("ij,ij->i", direction[1:], direction[:-1]))
    starts = np.ones(len(end), bool)
    starts[1:] = (is_rapid[1:] != is_rapid[:-1]) | (turn > corner_angle)
    move_tool = None if tool is None else np.asarray(tool)[end]
    if move_tool is not None:
        starts[1:] |= move_tool[1:] != move_tool[:-1]
    first = np.flatnonzero(starts)
    run_length = np.add.reduceat(length, first)
    cruise = np.add.reduceat(length / speed, first)
    seconds = segment_time(run_length, run_length / cruise, motion.accel, motion.jerk)
    if rotary_s is not None:
        # the rotaries' moves that the linear axes' (kept) moves carry, run by run
        rot = np.asarray(rotary_s, np.float64)
        owner = np.searchsorted(end, np.arange(1, len(rot)), side="left")  # kept move that ends at or after each move
        per_kept = np.bincount(np.minimum(owner, len(end) - 1), weights=rot[1:], minlength=len(end))
        seconds = np.maximum(seconds, np.add.reduceat(per_kept, first))
    return run_length, seconds, is_rapid[first], None if move_tool is None else move_tool[first]


def _totals(length, seconds, rapid) -> dict:
    """Sums over runs ``(r,)``: seconds, lengths (mm) and stops (every run ends at rest)."""
    cutting_s, rapid_s = float(seconds[~rapid].sum()), float(seconds[rapid].sum())
    return {"total_s": cutting_s + rapid_s, "cutting_s": cutting_s, "rapid_s": rapid_s,
            "cutting_mm": float(length[~rapid].sum()), "rapid_mm": float(length[rapid].sum()),
            "stops": int(len(length))}


def path_time(tip, rapid, machine, corner_angle=None, feed=None, rotary_s=None) -> dict:
    """Machining time of a tool path, rest-to-rest run by run (see :func:`_runs`).

    ``tip (k, 3)`` mm, ``rapid (k,) bool`` (move i ends at ``tip[i]``), ``machine`` a
    :class:`~meshmill.machine.model.Machine` or :class:`~meshmill.machine.model.MotionLimits`, ``corner_angle`` radians
    (default: the machine's), ``feed (k,)`` mm/s per feed move (NaN: the machine's feed; capped at
    the rapid rate), ``rotary_s (k,)`` the least seconds the rotary axes need for each move (see
    :func:`rotary_seconds`). Returns ``total_s``, ``cutting_s``, ``rapid_s``, ``cutting_mm``,
    ``rapid_mm`` and ``stops`` (rest-to-rest runs, each ending at rest).
    """
    motion, corner_angle = _limits(machine, corner_angle)
    length, seconds, is_rapid, _ = _runs(tip, rapid, motion, corner_angle, feed, rotary_s=rotary_s)
    return _totals(length, seconds, is_rapid)


def tool_times(tip, rapid, tool, machine, feed=None, rotary_s=None) -> dict:
    """:func:`path_time` per tool: ``{"tools": {tool: dict}, "total": dict}``, tools in the order
    of first use; runs also end at tool changes. ``tool (k,) int``; each change of tool between
    consecutive moves adds ``machine.tool_change`` seconds to the incoming tool (``tool_changes``,
    ``tool_change_s``, included in ``total_s``); the first tool is in the spindle at the start."""
    tool = np.asarray(tool)
    motion, corner_angle = _limits(machine, None)
    length, seconds, is_rapid, run_tool = _runs(tip, rapid, motion, corner_angle, feed, tool, rotary_s)
    changed_to = tool[1:][tool[1:] != tool[:-1]]
    used, first = np.unique(tool, return_index=True)
    tools = {}
    for t in used[np.argsort(first)]:
        mine = run_tool == t
        entry = _totals(length[mine], seconds[mine], is_rapid[mine])
        changes = int((changed_to == t).sum())
        entry.update(tool_changes=changes, tool_change_s=changes * machine.tool_change)
        entry["total_s"] += entry["tool_change_s"]
        tools[t.item()] = entry
    total = _totals(length, seconds, is_rapid)
    total.update(tool_changes=len(changed_to), tool_change_s=len(changed_to) * machine.tool_change)
    total["total_s"] += total["tool_change_s"]
    return {"tools": tools, "total": total}


def rotary_seconds(machine, tip, axis, tools=None, tool=None):
    """Least seconds ``(k,)`` the rotary axes of a 5-axis ``machine`` need for each move of a
    tool path (``tip``, ``axis (k, 3)``): the largest joint change of the move (from
    :func:`meshmill.machine.kinematics.inverse`, the post's own choice of solutions) at
    ``machine.rotary_rapid``. None on a 3-axis machine. ``tools``/``tool (k,)``: the tool lengths
    that a head-table machine needs (the move's tool's gauge plus holder length)."""
    if machine.chain.type == "3-axis":
        return None
    from .kinematics import angle_step, inverse

    length = 0.0
    if tools is not None and tool is not None:
        lengths = np.array([t.spindle_length for t in tools])
        length = lengths[np.asarray(tool)]
    joints, _ = inverse(machine, tip, axis, tool_length=length)
    return angle_step(joints) / machine.rotary_rapid


# --- feed rates programmed in tool-path files -----------------------------------------------------

INCH = 25.4
APT_FEED_UNITS = {"MMPM": 1.0, "IPM": INCH}  # per minute; per revolution (MMPR, IPR) needs the spindle speed
_GCODE_COMMENT = re.compile(r"\([^)]*\)")
_GCODE_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")


def _apt_feeds(text):
    """``[(line, mm/min or None)]`` of the FEDRAT statements (None: not a feed per minute): the
    lines ``FEDRAT/...``, spaces or tabs before the word and the slash allowed, any case."""
    # (found with str.find, the words read upper-case: a multi-line regex took 0.06 s over a
    # 100 k-line file)
    up = text.upper()
    out, number, pos = [], 1, 0
    at = up.find("FEDRAT")
    while at >= 0:
        start = up.rfind("\n", 0, at) + 1
        end = up.find("\n", at)
        end = len(up) if end < 0 else end
        line = up[start:end].lstrip(" \t")
        at = up.find("FEDRAT", end)  # (the word must start its line: one a line)
        rest = line[6:].lstrip(" \t")
        if not line.startswith("FEDRAT") or not rest.startswith("/"):
            continue
        number += up.count("\n", pos, start)
        pos = start
        words = [w.strip() for w in rest[1:].split("$$")[0].split(",") if w.strip()]
        values, units = [], []
        for w in words:
            try:
                values.append(float(w))
            except ValueError:
                units.append(w)
        scale = APT_FEED_UNITS.get(units[0] if units else "MMPM") if len(units) <= 1 else None
        ok = len(values) == 1 and scale is not None and 0 < values[0] < float("inf")
        out.append((number, values[0] * scale if ok else None))
    return out


def _gcode_feeds(text):
    """``[(line, value or None, kind)]`` of the lines with F words: kind "feed" (mm/min; inch/min
    under G20), "inverse" (G93: 1 / the block's minutes, that block only) or "reset" (a G93 line
    with no F, or G94 after G93: no feed per minute in force); None: F <= 0."""
    out, scale, inverse = [], 1.0, False
    for number, raw in enumerate(text.splitlines(), start=1):
        code = "".join(_GCODE_COMMENT.sub("", raw).split(";", 1)[0].split()).upper()
        if "F" not in code and "G2" not in code and "G9" not in code:
            continue
        feed, switched = None, False
        for letter, value in _GCODE_WORD.findall(code):
            if letter == "G" and float(value) in (20.0, 21.0):
                scale = INCH if float(value) == 20.0 else 1.0
            elif letter == "G" and float(value) in (93.0, 94.0):
                switched = inverse != (float(value) == 93.0)
                inverse = float(value) == 93.0
            elif letter == "F":
                feed = float(value)
        if switched:  # no feed per minute in force from here (G93), or until the next F (G94)
            out.append((number, None, "reset"))
        if feed is not None:
            value = (feed if inverse else feed * scale) if feed > 0 else None
            out.append((number, value, "inverse" if inverse else "feed"))
    return out


def programmed_feeds(path, line, gcode, tip=None) -> tuple[np.ndarray, list[str]]:
    """Feed rates ``(k,)`` mm/min that a tool-path file programs for its moves, NaN where none is in
    force. ``line (k,)``: the source line of each move (:attr:`Toolpath.line`); ``gcode``: the
    file is G-code (``F`` words, mm/min or inch/min under G20; under G93 1 / the block's minutes,
    turned into the block's tip length per that time with ``tip (k, 3)``) rather than APT
    (``FEDRAT/f`` with ``MMPM`` or ``IPM``, mm/min without). Feeds per minute are modal from their
    line on; feeds per revolution and non-positive ones are not honoured (NaN from there on, and
    a warning)."""
    path = os.fspath(path)
    found = _gcode_feeds(read_text(path, "tool-path")) if gcode else \
        [(n, f, "feed") for n, f in _apt_feeds(read_text(path, "tool-path"))]
    line = np.asarray(line)
    modal = [(n, f) for n, f, kind in found if kind != "inverse"]
    lines = np.array([0] + [n for n, _ in modal], np.int64)
    values = np.array([np.nan] + [np.nan if f is None else f for _, f in modal])
    feed = values[np.searchsorted(lines, line, side="right") - 1]
    bad = [n for n, f, kind in found if f is None and kind != "reset"]
    warnings = []
    blocks = [(n, f) for n, f, kind in found if kind == "inverse" and f is not None]
    if blocks and tip is None:
        warnings.append(f"{os.path.basename(path)}: inverse-time (G93) feeds need the path's moves; the machine's feed there")
    elif blocks:
        step = np.concatenate([[0.0], np.linalg.norm(np.diff(np.asarray(tip, np.float64), axis=0), axis=1)])
        for n, f in blocks:
            mine = line == n
            feed[mine] = step[mine].sum() * f if step[mine].sum() > 0 else np.nan
    word = "F word" if gcode else "FEDRAT"
    if bad:
        warnings.append(f"{os.path.basename(path)}: {len(bad)} {word}(s) not honoured (first at line {bad[0]}): "
                        "not a positive feed per minute; the machine's feed there")
    return feed, warnings


def path_times(tp, machine, tools, feed=None) -> tuple[dict, list[str]]:
    """``(figures, notes)``: the machining time of Toolpath ``tp`` on ``machine`` per tool and in
    total (:func:`tool_times`), ``feed`` mm/min on every feed move (default: as programmed, else
    the machine's); the rotaries bound a move's time where the axis turns on a 5-axis machine."""
    from ..errors import InputError

    feed_move = ~tp.rapid[1:]
    if feed is not None:
        per_s, unset = np.full(len(tp), feed / 60.0), 0
        notes = [f"feed {feed:g} mm/min on every feed move (as given)"]
    else:
        per_s = np.asarray(tp.feed, float) / 60.0
        unset = int((feed_move & np.isnan(per_s[1:])).sum())
        nominal = f"the machine's {machine.motion.feed * 60.0:g} mm/min"
        if not unset:
            notes = ["feeds as programmed"]
        elif unset == feed_move.sum():
            notes = [f"no feed programmed: every feed move at {nominal}"]
        else:
            notes = [f"{unset} of {feed_move.sum()} feed moves without a programmed feed: {nominal}"]
    rotary = None
    if len(tp) and np.ptp(tp.axis, axis=0).max() > 1e-9:
        if machine.chain.type == "3-axis":
            notes.append("the tool axis turns along the path: rotary-axis motion is not timed on a 3-axis machine")
        else:
            try:
                rotary = rotary_seconds(machine, tp.tip, tp.axis, tools, tp.tool)
                notes.append(f"rotary axes at {machine.rotary_rapid * 60.0:g} deg/min bound each move's time")
            except InputError as exc:
                notes.append(f"rotary-axis motion is not timed ({exc})")
    times = tool_times(tp.tip, tp.rapid, tp.tool, machine, per_s, rotary)
    return {"feed_moves": int(feed_move.sum()), "feed_moves_at_machine_feed": unset,
            "tools": {tools[t].name: entry for t, entry in times["tools"].items()}, "total": times["total"]}, notes
