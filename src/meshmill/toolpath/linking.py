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


def link_passes(passes, tool: int, safe_z: float, clear_in=None, clear_out=None) -> Toolpath:
    """Join 3-axis passes (each ``(k, 3)`` tool tips, mm) into one tool path: a rapid to the safe
    plane above each pass, a rapid down to the height ``clear_in[k]`` above its first point (where
    the tool is clear of the stock), a feed down to the pass, the pass at feed, a feed up to
    ``clear_out[k]`` above its last point and a rapid back up to the safe plane. Heights at or
    above the safe plane (or not given: the pass's own ends) make the whole way up and down a feed.
    The tool axis is +Z throughout; every pass has ``len(p) + 4`` moves."""
    tips, rapid = [], []
    for k, p in enumerate(passes):
        first, last = p[0], p[-1]
        z_in = safe_z if clear_in is None else min(safe_z, max(float(clear_in[k]), first[2]))
        z_out = safe_z if clear_out is None else min(safe_z, max(float(clear_out[k]), last[2]))
        tips += [[first[0], first[1], safe_z], [first[0], first[1], z_in]]
        rapid += [True, True]
        tips += list(p)
        rapid += [False] * len(p)
        tips += [[last[0], last[1], z_out], [last[0], last[1], safe_z]]
        rapid += [False, True]
    tips = np.array(tips, np.float64).reshape(-1, 3)
    axis = np.zeros_like(tips)
    axis[:, 2] = 1.0
    return Toolpath(tips, axis, np.array(rapid, bool), np.full(len(tips), tool, np.int64))
