"""Runs of linear blocks that lie on a circular arc in the XY plane, for G2/G3.

A run of points ``P[i] .. P[j]`` (the blocks i+1 .. j) is one arc when the circle through its
first, middle and last points holds every point within ``tol`` mm, the points turn about its
centre one way only, by less than a whole turn, each chord between them strays from the arc by at
most ``tol`` (its sagitta), and Z is constant or linear in the angle (a helix) within ``tol``; a
run that bulges from the line through its ends by no more than ``tol`` is left as lines.
Runs are grown greedily from the first block on: an arc is as long as it can be, and at least
``MIN_BLOCKS`` blocks.
"""
from __future__ import annotations

import math

import numba
import numpy as np

MIN_BLOCKS = 3  # blocks an arc must replace
MAX_RADIUS = 5000.0  # mm: a flatter run is a line, not an arc
MAX_SWEEP = math.radians(350.0)  # an arc turns less than this (no full circles)


@numba.njit(cache=True)
def _circle(ax, ay, bx, by, cx, cy):
    """Centre and radius of the circle through three points (radius inf when collinear)."""
    d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    if abs(d) < 1e-12:
        return 0.0, 0.0, np.inf
    a2, b2, c2 = ax * ax + ay * ay, bx * bx + by * by, cx * cx + cy * cy
    ux = (a2 * (by - cy) + b2 * (cy - ay) + c2 * (ay - by)) / d
    uy = (a2 * (cx - bx) + b2 * (ax - cx) + c2 * (bx - ax)) / d
    return ux, uy, math.hypot(ax - ux, ay - uy)


@numba.njit(cache=True)
def _fits(p, i, j, tol):
    """``(ok, cx, cy, ccw)``: whether points i..j of ``p (m, 3)`` lie on one arc (module docstring)."""
    m = (i + j) // 2
    cx, cy, r = _circle(p[i, 0], p[i, 1], p[m, 0], p[m, 1], p[j, 0], p[j, 1])
    if not (r < MAX_RADIUS) or r < 10.0 * tol:
        return False, 0.0, 0.0, False
    cross = (p[m, 0] - p[i, 0]) * (p[j, 1] - p[i, 1]) - (p[m, 1] - p[i, 1]) * (p[j, 0] - p[i, 0])
    ccw = cross > 0.0  # the middle point right of the chord i-j: counter-clockwise about the centre
    sign = 1.0 if ccw else -1.0
    theta = 0.0
    thetas = np.empty(j - i + 1)
    thetas[0] = 0.0
    a0 = math.atan2(p[i, 1] - cy, p[i, 0] - cx)
    prev = a0
    for k in range(i + 1, j + 1):
        if abs(math.hypot(p[k, 0] - cx, p[k, 1] - cy) - r) > tol:
            return False, 0.0, 0.0, False
        a = math.atan2(p[k, 1] - cy, p[k, 0] - cx)
        step = sign * (a - prev)
        while step < 0.0:
            step += 2.0 * math.pi
        while step >= 2.0 * math.pi:
            step -= 2.0 * math.pi
        if step > math.pi:  # turned back (or more than half a turn in one block)
            return False, 0.0, 0.0, False
        chord = math.hypot(p[k, 0] - p[k - 1, 0], p[k, 1] - p[k - 1, 1])
        if chord < 1e-9 or r - math.sqrt(max(0.0, r * r - 0.25 * chord * chord)) > tol:
            return False, 0.0, 0.0, False
        theta += step
        thetas[k - i] = theta
        prev = a
    if theta > MAX_SWEEP:
        return False, 0.0, 0.0, False
    if theta < math.pi and r * (1.0 - math.cos(0.5 * theta)) <= tol:
        return False, 0.0, 0.0, False  # as straight as a line within the tolerance: not an arc
    dz = p[j, 2] - p[i, 2]
    for k in range(i, j + 1):  # Z constant, or linear in the angle
        if abs(p[k, 2] - (p[i, 2] + dz * thetas[k - i] / theta)) > tol:
            return False, 0.0, 0.0, False
    return True, cx, cy, ccw


@numba.njit(cache=True)
def arc_runs(p, eligible, tol):
    """Arcs among the blocks of ``p (m, 3)`` (block b goes from point b-1 to point b): ``(first
    (a,), last (a,), centre (a, 2), ccw (a,))``, the first and last block of each arc. Only blocks
    with ``eligible (m,)`` set (a feed at the same feed and rotaries as the block before) take part."""
    m = len(p)
    first, last = [], []
    cxs, cys, dirs = [], [], []
    b = 1
    while b < m:
        if not eligible[b]:
            b += 1
            continue
        e = b  # the last eligible block of the stretch from b
        while e + 1 < m and eligible[e + 1]:
            e += 1
        i = b - 1
        best = -1
        bx, by, bd = 0.0, 0.0, False
        j = i + MIN_BLOCKS
        while j <= e:
            ok, cx, cy, ccw = _fits(p, i, j, tol)
            if not ok:
                break
            best, bx, by, bd = j, cx, cy, ccw
            j += 1
        if best >= 0:
            first.append(b)
            last.append(best)
            cxs.append(bx)
            cys.append(by)
            dirs.append(bd)
            b = best + 1
        else:
            b += 1
    n = len(first)
    centre = np.empty((n, 2))
    f = np.empty(n, np.int64)
    la = np.empty(n, np.int64)
    cc = np.empty(n, np.bool_)
    for k in range(n):
        f[k], la[k], centre[k, 0], centre[k, 1], cc[k] = first[k], last[k], cxs[k], cys[k], dirs[k]
    return f, la, centre, cc
