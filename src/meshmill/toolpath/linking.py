"""3-axis passes into tool paths: simplification of CL polylines and links between passes."""
from __future__ import annotations

import numba
import numpy as np

from .model import Toolpath


@numba.njit(cache=True)
def _simplify(p, tol):
    n = p.shape[0]
    keep = np.zeros(n, np.bool_)
    if n == 0:
        return keep
    keep[0] = True
    keep[n - 1] = True
    anchor = 0
    i = 2
    tol2 = tol * tol
    while i < n:
        # can the segment anchor-i stand in for every point between them?
        ax, ay, az = p[anchor, 0], p[anchor, 1], p[anchor, 2]
        dx, dy, dz = p[i, 0] - ax, p[i, 1] - ay, p[i, 2] - az
        dd = dx * dx + dy * dy + dz * dz
        ok = True
        for j in range(anchor + 1, i):
            wx, wy, wz = p[j, 0] - ax, p[j, 1] - ay, p[j, 2] - az
            s = 0.0
            if dd > 0.0:
                s = min(1.0, max(0.0, (wx * dx + wy * dy + wz * dz) / dd))
            ex, ey, ez = wx - s * dx, wy - s * dy, wz - s * dz
            if ex * ex + ey * ey + ez * ez > tol2:
                ok = False
                break
        if not ok:
            anchor = i - 1
            keep[anchor] = True
        i += 1
    return keep


def simplify_polyline(points: np.ndarray, tol: float, mask: bool = False) -> np.ndarray:
    """Drop points of ``points (k, 3)`` that lie within ``tol`` mm of the segment that replaces
    them; the end points stay. Returns the kept points (``mask``: which are kept, ``(k,) bool``)."""
    points = np.ascontiguousarray(points, np.float64)
    keep = _simplify(points, float(tol))
    return keep if mask else points[keep]


def shortest_order(passes, start=None, closed=None) -> list:
    """``passes`` (``(k, 3)`` tips each) in an order that keeps the links short: from ``start``
    (3,) (default: the first pass's start), each time the pass whose nearer end is nearest the
    last end (greedy), an open pass turned round to start at that end; ``closed[i]``: pass i is a
    loop (first point repeated), cut in its own direction, from its own start."""
    if len(passes) < 2:
        return list(passes)
    closed = np.zeros(len(passes), bool) if closed is None else np.asarray(closed, bool)
    heads = np.array([p[0] for p in passes])
    tails = np.array([p[-1] for p in passes])
    left = np.ones(len(passes), bool)
    at = heads[0] if start is None else np.asarray(start, float)
    out = []
    for _ in range(len(passes)):
        d_head = np.where(left, np.linalg.norm(heads - at, axis=1), np.inf)
        d_tail = np.where(left & ~closed, np.linalg.norm(tails - at, axis=1), np.inf)
        i, j = int(np.argmin(d_head)), int(np.argmin(d_tail))
        if d_tail[j] < d_head[i]:
            out.append(passes[j][::-1])
            left[j] = False
        else:
            out.append(passes[i])
            left[i] = False
        at = out[-1][-1]
    return out


def joined_passes(passes, gap: float) -> list:
    """Consecutive ``passes`` whose end and next start are less than ``gap`` mm apart made one
    (a straight feed move between them, which verification checks and splits again where it would
    gouge), so that the tool does not leave the part between them."""
    out = []
    for p in passes:
        if out and np.linalg.norm(p[0] - out[-1][-1]) < gap:
            out[-1] = np.vstack([out[-1], p])
        else:
            out.append(np.asarray(p))
    return out


def link_passes(passes, tool: int, safe_z: float, clear_in=None, clear_out=None, links=None) -> Toolpath:
    """Join 3-axis passes (each ``(k, 3)`` tool tips, mm) into one tool path: a rapid at the
    link's height ``links[k]`` (default: the safe plane) to above each pass, a rapid down to the
    height ``clear_in[k]`` above its first point (where the tool is clear of the stock), a feed
    down to the pass, the pass at feed, a feed up to ``clear_out[k]`` above its last point and a
    rapid up to the next link's height ``links[k + 1]`` (the last: the safe plane). Heights at or
    above the safe plane (or not given: the pass's own ends) make the whole way up and down a feed.
    The tool axis is +Z throughout; every pass has ``len(p) + 4`` moves."""
    tips, rapid = [], []
    for k, p in enumerate(passes):
        first, last = p[0], p[-1]
        z_in = safe_z if clear_in is None else min(safe_z, max(float(clear_in[k]), first[2]))
        z_out = safe_z if clear_out is None else min(safe_z, max(float(clear_out[k]), last[2]))
        over = safe_z if links is None else max(float(links[k]), z_in)
        up = safe_z if links is None else max(float(links[k + 1]), z_out)
        tips += [[first[0], first[1], over], [first[0], first[1], z_in]]
        rapid += [True, True]
        tips += list(p)
        rapid += [False] * len(p)
        tips += [[last[0], last[1], z_out], [last[0], last[1], up]]
        rapid += [False, True]
    tips = np.array(tips, np.float64).reshape(-1, 3)
    axis = np.zeros_like(tips)
    axis[:, 2] = 1.0
    return Toolpath(tips, axis, np.array(rapid, bool), np.full(len(tips), tool, np.int64))
