"""Feeds: each move's feed from its tool's cutting data, and feeds optimised on the load that
the in-process stock measures (``meshmill feeds``).

From the table (:func:`table_feeds`): a move down its tool's axis (within 10°) is a plunge, fed
at the tool's plunge feed; a ramp or helix entry (the moves an operation marks so) at its ramp
feed; every other feed move at ``fz x flutes x rpm``; a tool without a feed per tooth keeps the
machine's (NaN).

Optimised (:func:`optimise_feeds`), from each move's :class:`~meshmill.simulation.load.MoveLoad`:

- in material, the feed that brings the largest chip to the tool's feed per tooth (``fz /
  sin`` of the engagement's angle nearest 90°: chip thinning; at most ``MAX_THINNING`` times the
  table's feed), held under the spindle's power and torque (which scale with the feed), the
  plunge feed for plunges, the machine's largest feed; never faster than the table's feed where
  the move cuts a section (ap x ae) over the tool's (feeds cannot fix that);
- in air, the machine's largest feed (a move that removes nothing is still a feed move, never a
  rapid: the stock as measured is clear there, the part may not be);
- the moves are taken in runs at least ``MERGE_LENGTH`` long (never mixing moves in air, in
  material and plunging), each fed at the lowest feed of its run, so that F does not change on every short block and the control's look-ahead keeps
  its speed; feeds are rounded down to steps of
  ``FEED_STEP`` (5 %) so that a nearly steady cut keeps one F.

Air (:func:`air_feeds`, a job's default with the table's feeds): the runs of feed moves that
remove nothing of the stock as it is cut, at least ``MERGE_LENGTH`` long, at the machine's largest
feed; the others as programmed.
"""
from __future__ import annotations

import math

import numpy as np

from ..simulation.load import PLUNGE_COS, limits_of, over_limits

MAX_THINNING = 3.0  # a light cut is fed at most this many times the table's feed
FEED_STEP = 1.05  # feeds are rounded down to powers of this
MERGE_LENGTH = 2.0  # mm: a run of moves shorter than this each is given one feed
MIN_FEED_SHARE = 0.05  # the optimised feed is at least this share of the table's (a move at the limits)


def table_feeds(toolpath, conditions, entries=None) -> np.ndarray:
    """mm/min ``(k,)``: the feed of each move of ``toolpath`` from its tool's conditions
    (``conditions``: a :class:`~meshmill.tools.cutting.Cutting` per tool); NaN for rapids, for
    tools without a known feed and the first point; ``entries (k,) bool``: the ramp and helix
    moves (their ramp feed)."""
    k = len(toolpath)
    tool_of = np.asarray(toolpath.tool)
    feed = np.full(k, np.nan)
    if k < 2:
        return feed
    cut = np.array([c.feed if c.known else np.nan for c in conditions])[tool_of]
    plunge = np.array([c.plunge_feed if c.known else np.nan for c in conditions])[tool_of]
    ramp = np.array([c.ramp_feed if c.known else np.nan for c in conditions])[tool_of]
    move = np.vstack([np.zeros((1, 3)), np.diff(toolpath.tip, axis=0)])
    length = np.linalg.norm(move, axis=1)
    down = -np.einsum("ij,ij->i", move, toolpath.axis) / np.maximum(length, 1e-12)
    feed[:] = cut
    if entries is not None:
        feed[entries] = ramp[entries]
    feed[down >= PLUNGE_COS] = plunge[down >= PLUNGE_COS]  # an entry straight down is a plunge
    feed[np.asarray(toolpath.rapid, bool)] = np.nan
    feed[0] = np.nan
    return feed


def _runs(length, breaks) -> np.ndarray:
    """Run number ``(k,)`` of each move: the moves are taken in runs at least
    :data:`MERGE_LENGTH` long (a move that long is a run of its own), a ``breaks`` move
    (a rapid, a new tool, from air into material or a plunge and back) starting a new one."""
    run = np.zeros(len(length), np.int64)
    n, acc = 0, 0.0
    for i, (ln, b) in enumerate(zip(length.tolist(), breaks.tolist())):
        if b or acc >= MERGE_LENGTH:
            n, acc = n + 1, 0.0
        run[i] = n
        acc += ln
    return run


def optimise_feeds(toolpath, load, conditions, spindle, max_feed: float) -> np.ndarray:
    """mm/min ``(k,)``: the feeds of ``toolpath`` optimised on its measured ``load``
    (:class:`~meshmill.simulation.load.MoveLoad`, whose ``feed`` is what it was measured at),
    the tools' ``conditions`` and the ``spindle`` (:class:`~meshmill.machine.model.Spindle` or
    None), at most ``max_feed`` mm/min (see the module docstring). NaN for rapids."""
    k = len(toolpath)
    tool_of = np.asarray(toolpath.tool)
    rapid = np.asarray(toolpath.rapid, bool)
    table = np.array([c.feed if c.known else np.nan for c in conditions])[tool_of]
    plunge_limit = np.array([c.plunge_feed if c.known else np.nan for c in conditions])[tool_of]
    fz = np.array([c.fz for c in conditions])[tool_of]
    known = np.isfinite(table)
    measured = np.where(np.isfinite(load.feed), load.feed, np.nan)
    base = np.where(known, table, measured)  # what the move runs at without optimising
    target = np.full(k, np.nan)
    cutting = load.in_material
    # the chip: fz_programmed * sin_max = chip_max, so the feed that gives fz is feed * fz / chip_max
    with np.errstate(divide="ignore", invalid="ignore"):
        chip_feed = measured * fz / load.chip_max
    chip_feed = np.where(np.isfinite(chip_feed) & (chip_feed > 0), chip_feed, base)
    chip_feed = np.minimum(chip_feed, MAX_THINNING * base)
    target[cutting] = chip_feed[cutting]
    if spindle is not None:
        for value, limit in ((load.power, spindle.power_kw), (load.torque, spindle.torque_nm)):
            if limit:
                with np.errstate(divide="ignore", invalid="ignore"):
                    cap = measured * limit / value
                cap = np.where(np.isfinite(cap) & (value > 0), cap, np.inf)
                target = np.where(cutting, np.minimum(target, cap), target)
    plunge = cutting & load.plunge
    target[plunge] = np.where(known[plunge], plunge_limit[plunge], measured[plunge])
    over = over_limits(load, limits_of(toolpath, conditions, spindle, load))["section"]
    target[over] = np.minimum(target[over], base[over])  # a cut over its section is not sped up
    air = ~rapid & ~cutting
    target[air] = max_feed
    target = np.minimum(target, max_feed)
    target = np.maximum(target, MIN_FEED_SHARE * np.where(np.isfinite(base), base, target))
    target = FEED_STEP ** np.floor(np.log(np.maximum(target, 1e-9)) / math.log(FEED_STEP) + 1e-9)
    length = np.r_[0.0, np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)]
    kind = cutting.astype(np.int8) + load.plunge  # air, in material, plunging: runs never mix them
    breaks = rapid | np.r_[True, (tool_of[1:] != tool_of[:-1]) | (kind[1:] != kind[:-1])]
    run = _runs(length, breaks)
    lowest = np.full(run.max() + 1 if k else 0, np.inf)
    feed_moves = ~rapid & np.isfinite(target)
    np.minimum.at(lowest, run[feed_moves], target[feed_moves])
    out = np.where(feed_moves, lowest[run], np.nan)
    if k:
        out[0] = np.nan
    return out


def _air_moves(toolpath, in_material) -> np.ndarray:
    """``(k,) bool``: the feed moves that remove nothing (``in_material (k,) bool`` False)."""
    air = ~np.asarray(toolpath.rapid, bool) & ~np.asarray(in_material, bool)
    if len(air):
        air[0] = False
    return air


def air_feeds(toolpath, in_material, max_feed: float) -> np.ndarray:
    """mm/min ``(k,)``: the feeds of ``toolpath`` with its runs of feed moves in air (``in_material
    (k,) bool`` False: they remove nothing of the stock as it was cut) at ``max_feed``, where a run
    of one tool is at least :data:`MERGE_LENGTH` long; the other moves' as programmed (NaN: the
    machine's nominal feed)."""
    feed = np.asarray(toolpath.feed, np.float64).copy()
    if len(feed) < 2:
        return feed
    air = _air_moves(toolpath, in_material)
    tool_of = np.asarray(toolpath.tool)
    length = np.r_[0.0, np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)]
    start = air & ~np.r_[False, air[:-1] & (tool_of[1:] == tool_of[:-1])]
    run = np.cumsum(start) - 1
    run_length = np.bincount(run[air], weights=length[air], minlength=int(start.sum()))
    fast = air.copy()
    fast[air] = run_length[run[air]] >= MERGE_LENGTH
    feed[fast] = max_feed
    return feed


def air_time_share(toolpath, in_material, nominal_feed: float) -> float:
    """The share of the feed moves' time spent in air (``in_material (k,) bool`` False), each move
    taking its length over its feed (NaN: ``nominal_feed``, mm/min)."""
    if len(toolpath) < 2:
        return 0.0
    feed = np.where(np.isfinite(toolpath.feed), toolpath.feed, nominal_feed)
    moves = ~np.asarray(toolpath.rapid, bool)
    moves[0] = False
    seconds = np.r_[0.0, np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)] / np.maximum(feed, 1e-9)
    total = float(seconds[moves].sum())
    return float(seconds[_air_moves(toolpath, in_material)].sum()) / total if total > 0 else 0.0
