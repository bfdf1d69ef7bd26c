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
    a0, a1 = np.asarray(a0, float), np.asarray(a1, float)
    dist, inside = _pole_distance(a0[None], a1[None])
    t0, t1 = math.acos(min(1.0, a0[2])), math.acos(min(1.0, a1[2]))
    m_rad = math.radians(margin)
    z0, z1 = math.atan2(a0[1], a0[0]), math.atan2(a1[1], a1[0])
    turn = (z1 - z0 + math.pi) % (2 * math.pi) - math.pi  # the shorter way round
    past = bool(inside[0]) and dist[0] < m_rad
    if min(t0, t1) <= max(through, dist[0] + 1e-12 if past else 0.0) or (past and dist[0] < through) or \
            abs(turn) <= math.radians(step) + 1e-12:
        return np.empty((0, 3)), np.empty((0, 3))
    k = max(1, int(math.ceil(abs(math.degrees(turn)) / step)) - 1)
    s = np.arange(1, k + 1) / (k + 1)
    tilt = np.maximum(m_rad if past else 0.0, t0 + s * (t1 - t0))
    az = z0 + s * turn
    axes = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    centres = np.asarray(c0, float) + s[:, None] * (np.asarray(c1, float) - np.asarray(c0, float))
    return axes, centres


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
    inserts = {}
    for i in np.flatnonzero(turned):
        r = 0.0 if tp.rapid[i] else float(radius[tp.tool[i]])
        c0, c1 = tp.tip[i - 1] + r * tp.axis[i - 1], tp.tip[i] + r * tp.axis[i]
        if off[i - 1]:
            new_axes, centres = around_pole(tp.axis[i - 1], tp.axis[i], c0, c1, r, margin, step, through)
        else:
            turn = float(wrap(az[i] - held[i]))
            k = max(1, int(math.ceil(abs(turn) / step_rad)))
            t = min(m_rad, tilt[i])
            zs = held[i] + turn * np.arange(0, k + 1) / k
            new_axes = np.column_stack([np.sin(t) * np.cos(zs), np.sin(t) * np.sin(zs), np.full(k + 1, np.cos(t))])
            if t >= tilt[i] - 1e-12:
                new_axes = new_axes[:-1]  # the last is the move's own end
            f = np.arange(1, len(new_axes) + 1) / (len(new_axes) + 1)
            centres = c0 + f[:, None] * (c1 - c0)
        if len(new_axes):
            inserts[int(i)] = (centres - r * new_axes, new_axes)
    if not inserts:
        return tp, np.arange(n)
    at = sorted(inserts)
    pieces = np.split(np.arange(n), at)
    tips, axes, source = [tp.tip[pieces[0]]], [tp.axis[pieces[0]]], [pieces[0]]
    for j, piece in zip(at, pieces[1:]):
        t_new, a_new = inserts[j]
        tips += [t_new, tp.tip[piece]]
        axes += [a_new, tp.axis[piece]]
        source += [np.full(len(t_new), j), piece]
    source = np.concatenate(source)
    return Toolpath(np.vstack(tips), np.vstack(axes), tp.rapid[source], tp.tool[source]), source
