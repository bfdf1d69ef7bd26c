"""The tool axis of a finish kept from the pole of a 5-axis machine's rotaries (``finish
--machine``).

Near the pole (+Z, where C's axis and the tool axis meet) a small turn of the tool axis is a large
turn of C. Poses are put into the moves where C would turn more than ``POLE_STEP`` deg: the axis
goes round in steps, tilted at least ``POLE_MARGIN`` deg, while the ball's centre stays on its
segment. Axes are unit ``(k, 3)``, angles in degrees unless said (rad), lengths in mm.
"""
from __future__ import annotations

import math

import numpy as np

from ..toolpath.model import Toolpath

POLE_MARGIN = 2.0  # deg: for a 5-axis machine, no move swings the axis nearer its rotaries' pole than this ...
POLE_STEP = 10.0  # ... and C turns at most this much in one move (deg): the azimuth goes round in steps


def _pole_distance(a0, a1):
    """Smallest angle (rad, (k,)) between +Z and the great-circle arcs from unit ``a0`` to ``a1``
    (k, 3), and whether it is reached inside the arc (not at an end)."""
    n = np.cross(a0, a1)
    size = np.linalg.norm(n, axis=1)
    n = n / np.maximum(size, 1e-300)[:, None]
    p = np.array([0.0, 0.0, 1.0]) - n[:, 2:3] * n  # +Z projected on the arc's plane
    p /= np.maximum(np.linalg.norm(p, axis=1), 1e-300)[:, None]
    arc = np.arccos(np.clip(np.einsum("ij,ij->i", a0, a1), -1.0, 1.0))
    to_p = np.arccos(np.clip(np.einsum("ij,ij->i", a0, p), -1.0, 1.0)) + \
        np.arccos(np.clip(np.einsum("ij,ij->i", p, a1), -1.0, 1.0))
    inside = (size > 1e-12) & (to_p <= arc + 1e-9)
    ends = np.minimum(np.arccos(np.clip(a0[:, 2], -1, 1)), np.arccos(np.clip(a1[:, 2], -1, 1)))
    return np.where(inside, np.arcsin(np.clip(np.abs(n[:, 2]), 0.0, 1.0)), ends), inside


def around_pole(a0, a1, c0, c1, radius, margin=POLE_MARGIN, step=POLE_STEP, through=math.radians(0.025)):
    """Poses ``(axes (m, 3), ball centres (m, 3))`` to put between the pose (``a0``, centre ``c0``)
    and (``a1``, ``c1``) of a ball of ``radius`` where the rotaries of a 5-axis machine whose pole is
    +Z would turn C by more than ``step`` deg in the move: near the pole a small turn of the axis is
    a large turn of C (half a turn in an instant where the axis swings past the pole), which no post
    can follow within the path's tolerance. The axis turns its azimuth in steps of at most ``step``
    deg instead, its tilt going from one end's to the other's (at least ``margin`` deg where the arc
    would pass nearer the pole than that); the centre stays on its segment, so the ball cuts what it
    cut. None needed (``m = 0``) where the arc passes within ``through`` rad of the pole (the
    machine flips the tilt there: half its ``singular``) or starts or ends on it."""
    _, axes, centres = _around_poles(np.asarray(a0, float)[None], np.asarray(a1, float)[None],
                                     np.asarray(c0, float)[None], np.asarray(c1, float)[None], margin, step, through)
    return axes, centres


def _around_poles(a0, a1, c0, c1, margin, step, through):
    """:func:`around_pole` of many moves (``(k, 3)`` each): ``(count (k,), axes (m, 3), centres
    (m, 3))``, the poses of each move in turn."""
    dist, inside = _pole_distance(a0, a1)
    t0, t1 = np.arccos(np.minimum(1.0, a0[:, 2])), np.arccos(np.minimum(1.0, a1[:, 2]))
    m_rad = math.radians(margin)
    z0, z1 = np.arctan2(a0[:, 1], a0[:, 0]), np.arctan2(a1[:, 1], a1[:, 0])
    turn = (z1 - z0 + math.pi) % (2 * math.pi) - math.pi  # the shorter way round
    past = inside & (dist < m_rad)
    none = (np.minimum(t0, t1) <= np.maximum(through, np.where(past, dist + 1e-12, 0.0))) | (past & (dist < through)) \
        | (np.abs(turn) <= math.radians(step) + 1e-12)
    # (steps of a turn that is a whole number of them, to the last bit, are counted the same whatever
    # its rounding)
    count = np.where(none, 0, np.maximum(1, np.ceil(np.abs(np.degrees(turn)) / step * (1.0 - 1e-12)).astype(np.int64)
                                         - 1))
    row, s = _steps(count)
    s = s / (count[row] + 1)
    tilt = np.maximum(np.where(past[row], m_rad, 0.0), t0[row] + s * (t1 - t0)[row])
    az = z0[row] + s * turn[row]
    axes = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    return count, axes, c0[row] + s[:, None] * (c1 - c0)[row]


def _steps(count):
    """``(row, j)`` (both ``(count.sum(),)``): each row of ``count (k,)`` repeated its count times,
    and j = 1 .. count within it (float)."""
    row = np.repeat(np.arange(len(count)), count)
    return row, (np.arange(len(row)) - np.repeat(np.cumsum(count) - count, count) + 1).astype(float)


def gentle_turns(tp: Toolpath, radius, singular, margin=POLE_MARGIN, step=POLE_STEP):
    """``(toolpath, source (k',))``: ``tp`` with poses put in wherever C of a 5-axis machine whose
    pole is +Z would turn more than ``step`` deg in one move (``source``: the move of ``tp`` each
    new move belongs to). The machine holds C within ``singular`` rad of the pole; poses put in
    near it are tilted at least ``margin`` deg, and at least twice ``singular``. Off the pole,
    :func:`around_pole`'s poses. Leaving the pole, the machine still holds C where the last tilted
    pose had it: the axis tilts out at that azimuth first (to that tilt, or the move's end tilt if
    smaller), turns round at that tilt in steps of ``step`` deg, and tilts to the move's end. Tips
    follow the ball centres along their segment (``radius (T,)`` per tool index; a rapid's tip
    simply along its segment)."""
    margin = max(margin, 2.0 * math.degrees(singular))
    through = 0.5 * singular  # an arc this near the pole: the machine flips the tilt instead
    n = len(tp)
    tilt = np.arccos(np.clip(tp.axis[:, 2], -1.0, 1.0))
    az = np.arctan2(tp.axis[:, 1], tp.axis[:, 0])
    m_rad, step_rad = math.radians(margin), math.radians(step)
    off = tilt > singular
    last_off = np.maximum.accumulate(np.where(off, np.arange(n), -1))  # the last tilted pose so far
    held = np.full(n, np.nan)  # where C is held before each move
    held[1:] = np.where(last_off[:-1] >= 0, az[np.maximum(last_off[:-1], 0)], np.nan)

    def wrap(x):
        return (x + np.pi) % (2 * np.pi) - np.pi

    turned = np.zeros(n, bool)
    turned[1:] = off[1:] & np.where(off[:-1], np.abs(wrap(az[1:] - az[:-1])) > step_rad + 1e-12,
                                    np.isfinite(held[1:]) & (np.abs(wrap(az[1:] - np.nan_to_num(held[1:]))) > 1e-9))
    idx = np.flatnonzero(turned)
    if not len(idx):
        return tp, np.arange(n)
    r = np.where(tp.rapid[idx], 0.0, np.asarray(radius, float)[tp.tool[idx]])
    c0, c1 = tp.tip[idx - 1] + r[:, None] * tp.axis[idx - 1], tp.tip[idx] + r[:, None] * tp.axis[idx]
    # from a tilted pose: round the pole
    rnd = off[idx - 1]
    n_round, ax_round, ce_round = _around_poles(tp.axis[idx - 1][rnd], tp.axis[idx][rnd], c0[rnd], c1[rnd], margin,
                                                step, through)
    # from the pole: out at the held azimuth, round at that tilt (the last pose dropped where it is
    # the move's own end)
    out = np.flatnonzero(~rnd)
    i = idx[out]
    turn = wrap(az[i] - held[i])
    k = np.maximum(1, np.ceil(np.abs(turn) / step_rad * (1.0 - 1e-12)).astype(np.int64))
    t = np.minimum(m_rad, tilt[i])
    n_out = k + 1 - (t >= tilt[i] - 1e-12)
    row, j = _steps(n_out)
    zs = held[i][row] + turn[row] * (j - 1) / k[row]
    ax_out = np.column_stack([np.sin(t[row]) * np.cos(zs), np.sin(t[row]) * np.sin(zs), np.cos(t[row])])
    f = j / (n_out[row] + 1)
    ce_out = c0[out][row] + f[:, None] * (c1 - c0)[out][row]
    # each move's new poses, in the order of idx
    count = np.zeros(len(idx), np.int64)
    count[rnd], count[~rnd] = n_round, n_out
    if not count.any():
        return tp, np.arange(n)
    new_axes, centres = np.empty((count.sum(), 3)), np.empty((count.sum(), 3))
    first = np.cumsum(count) - count
    for sel, n_sel, axes_sel, centres_sel in ((rnd, n_round, ax_round, ce_round), (~rnd, n_out, ax_out, ce_out)):
        at = np.repeat(first[sel], n_sel) + _steps(n_sel)[1].astype(np.int64) - 1
        new_axes[at], centres[at] = axes_sel, centres_sel
    new_tips = centres - np.repeat(r, count)[:, None] * new_axes
    # the moves of tp, each after the poses put into it
    per = np.zeros(n, np.int64)
    per[idx] = count
    own = np.arange(n) + np.cumsum(per)
    source = np.empty(n + count.sum(), np.int64)
    source[own] = np.arange(n)
    put = np.setdiff1d(np.arange(len(source)), own, assume_unique=True)
    source[put] = np.repeat(idx, count)
    tips, axes = np.empty((len(source), 3)), np.empty((len(source), 3))
    tips[own], axes[own] = tp.tip, tp.axis
    tips[put], axes[put] = new_tips, new_axes
    return Toolpath(tips, axes, tp.rapid[source], tp.tool[source]), source
