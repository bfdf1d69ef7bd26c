"""Z-levels added where the surface needs them, so that the scallop between neighbouring
passes stays under a limit (``finish --scallop``).

Two passes dz apart lie dz / sin(slope) apart on a surface sloped ``slope`` from the horizontal,
and a ball of radius R leaves a scallop under h while that is at most
s(R) = 2 sqrt(2 R h - h²). A point of a wall therefore needs levels at most s(R)·sin(slope)
apart, R being the ball that cuts it. Levels are added by halving bands, locally: each band
between two levels is halved, the plane at its middle is sliced, and only the stretches of it
whose points need it (the band wider than their s(R)·sin(slope), R the largest ball that fits the
whole stretch) are kept, a little beyond where they need it; bands halve again only where the
halves were kept. Near a point needing levels dz apart every level of that depth is therefore
present (spacing at most dz, at least half of it), and steep walls elsewhere keep the step-down's
levels. The part's top and bottom are no passes: the surface between them and the nearest level
is cut from one side only, and its band counts twice its width. Surfaces flatter than
``min_slope`` would need ever more levels (dz -> 0): they are left to the shallow-area raster
(:mod:`meshmill.ops.finish_shallow`).
"""
from __future__ import annotations

import math

import numpy as np

from ..geometry.slicing import Contours, slice_contours

MAX_DEPTH = 12  # halvings of a step-down band (1 mm -> 0.24 um)
MIN_BAND = 1e-3  # mm: no band narrower than this is halved


def scallop_spacing(radius, height):
    """Largest distance (mm) between neighbouring passes of a ball of ``radius`` (array or number)
    that leaves a scallop under ``height``: 2 sqrt(2 R h - h²), h at most R."""
    r = np.asarray(radius, float)
    h = np.minimum(height, r)
    return 2.0 * np.sqrt(np.maximum(2.0 * r * h - h * h, 0.0))


def _sin_slope(normals):
    return np.sqrt(np.clip(1.0 - normals[:, 2] ** 2, 0.0, 1.0))


def _grow_along(con: Contours, mask, margin):
    """``mask`` widened along each contour to the points within ``margin`` mm (of arc length) of
    a True point (cyclic on closed contours)."""
    out = mask.copy()
    for c in range(len(con)):
        a, b = con.offsets[c], con.offsets[c + 1]
        m = mask[a:b]
        if m.all() or not m.any():
            continue
        p = con.points[a:b]
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        s = np.r_[0.0, np.cumsum(seg)]
        at = s[m]
        if con.closed[c]:
            total = s[-1] + float(np.linalg.norm(p[-1] - p[0]))
            at = np.r_[at - total, at, at + total]
        j = np.clip(np.searchsorted(at, s), 1, len(at) - 1)
        near = np.minimum(np.abs(s - at[j - 1]), np.abs(at[j] - s))
        out[a:b] |= near <= margin
    return out


def added_contours(mesh, levels, zmin, zmax, radii, height, sample, arc_step, piece_tools, min_slope):
    """``(contours, report)``: the stretches of added planes that the scallop limit ``height``
    needs between ``levels`` (from the top down; the part's top ``zmax`` and bottom ``zmin`` bound
    the first and last band). ``radii (T,)`` the balls, largest first; ``piece_tools(contours)``
    the ball (rank into ``radii``, -1: none) that would cut each point of those contours;
    ``min_slope`` deg: flatter points never need a level."""
    # bands (upper z, lower z, open above, open below): the part's top and bottom are no passes, so
    # the surface between them and the nearest level is cut from one side only and counts double
    bands = [(a, b, k == 0, k == len(levels)) for k, (a, b) in enumerate(zip(np.r_[zmax, levels],
                                                                           np.r_[levels, zmin]))]
    s_max = float(scallop_spacing(radii.max(), height))
    sin_min = math.sin(math.radians(min_slope))
    kept, planes, deepest = [], 0, 0
    for depth in range(1, MAX_DEPTH + 1):
        bands = [band for band in bands if band[0] - band[1] >= 2 * MIN_BAND]
        if not bands:
            break
        mids = np.array([0.5 * (a + b) for a, b, _, _ in bands])
        width = np.array([(a - b) * (2.0 if up or down else 1.0) for a, b, up, down in bands])
        con = slice_contours(mesh, mids, sample, arc_step)
        if len(con.points) == 0:
            break
        order = np.argsort(mids)

        def band_width(c):  # (k,) the width of the band each point of contours c lies in
            return np.repeat(width[order[np.searchsorted(mids[order], c.z)]], np.diff(c.offsets))

        sin = _sin_slope(con.normals)
        steep = sin >= sin_min
        # where even the largest ball needs the plane, with a margin to find the stretch's ball
        maybe = steep & (band_width(con) > s_max * sin)
        if not maybe.any():
            break
        sub = con.take(_grow_along(con, maybe, 2.0 * sample))
        tool = piece_tools(sub)
        sin = _sin_slope(sub.normals)
        need = (tool >= 0) & (sin >= sin_min) & (band_width(sub) > scallop_spacing(radii[np.maximum(tool, 0)], height) * sin)
        keep = _grow_along(sub, need, sample) & (tool >= 0)
        if not keep.any():
            break
        piece = sub.take(keep)
        kept.append(piece)
        deepest = depth
        used = np.unique(piece.z)
        planes += len(used)
        bands = [half for (a, b, up, down) in bands if np.any(np.abs(used - 0.5 * (a + b)) < 1e-12)
                 for half in ((a, 0.5 * (a + b), up, False), (0.5 * (a + b), b, False, down))]
    report = {"height": float(height), "radii": [float(r) for r in radii], "planes_added": int(planes),
              "depth": int(deepest), "min_slope_deg": float(min_slope),
              "cc_points_added": int(sum(len(k.points) for k in kept))}
    return kept, report
