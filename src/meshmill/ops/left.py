"""What a job leaves on the part, where, and why: the design's surface, sampled by area, each
sample given the deviation the in-process stock's dexel ends measure next to it and, where that
is more than the tolerance, the reason no tool took it.

The surface: points on a barycentric grid of every facet, about a lattice step apart, each
standing for an equal share of its facet's area (mm², exact in sum) with the facet's normal. The
deviation: the stock's dexel ends (their exact distance to the design, positive where material
stands on it) carried down to the design along the distance's gradient (central differences),
and each surface point given the nearest such foot within 1.5 lattice steps. A point with no
foot that near but the stock's material a step out from it carries more than that of stock (its
deviation unknown, its reason tested like any other out of tolerance); else it is "not measured":
no end of any direction near it and no stock on it, which a lattice step finer than the part's
thin features avoids.

The reasons, for a point with more than the tolerance on it, tried in order with the balls of the
table (a ball of radius R touches the point from its centre R out along the normal; bull-noses
and flat end mills are left out of this test):

- no tool of the table fits: no ball's centre there keeps its radius from the part (a concave
  corner or fillet tighter than the smallest ball, or a gap narrower than it);
- below a 3-axis shadow (a 3-axis job) / no collision-free axis (a job with 5-axis operations): no
  ball that fits reaches it with its tip no lower than the part's bottom (the part stands on it)
  along the vertical axis (the whole tool dropped over the ball's centre, exactly, stops no higher
  than the ball touching the point) nor, in 5 axes, along any of a fan of axes within
  ``max_tilt`` of the vertical (flutes, shank and holder sampled along the axis, each keeping its
  radius from the part);
- a tool the job does not use: only balls of the table that no operation of the job ran reach it;
- left by the job: a tool the job uses reaches it (scallops over the limit, material a rest pass
  did not take, an operation left out).

This is a map for a user, not a certificate: the reach is tested at the points, the axes on a fan.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from ..pathing.dropcutter import ToolDrop


REASONS = ("within tolerance", "gouged", "left by the job", "a tool the job does not use",
           "below a 3-axis shadow", "no collision-free axis", "no tool of the table fits", "not measured")
WITHIN, GOUGED, LEFT, UNUSED, SHADOW, NO_AXIS, NO_FIT, UNMEASURED = range(len(REASONS))
NEAR_STEPS = 1.5  # lattice steps: how far a surface point looks for an end's foot
TILTS = (0.0, 20.0, 40.0, 60.0)  # deg: the fan of 5-axis axes tried (and the normal, tilted no further)
AZIMUTHS = 8


def surface_samples(mesh, spacing: float):
    """``(points (m, 3), normals (m, 3), area (m,))``: points on every facet of ``mesh`` about
    ``spacing`` mm apart (a barycentric grid of n x n sub-triangles' centroids, n from the
    facet's longest edge), each with its facet's unit normal and an equal share of its area."""
    v = mesh.vertices[mesh.faces]  # (f, 3, 3)
    cross = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / np.maximum(2.0 * area, 1e-300)[:, None]
    edge = np.max(np.linalg.norm(v - np.roll(v, 1, axis=1), axis=2), axis=1)
    n = np.clip(np.ceil(edge / spacing), 1, 64).astype(np.int64)
    points, normals, areas = [], [], []
    for k in np.unique(n):
        faces = np.nonzero(n == k)[0]
        # the centroids of the k^2 sub-triangles of a k-grid, in barycentric coordinates
        i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
        up = (i + j) < k
        bary = [np.column_stack([(i[up] + 1 / 3), (j[up] + 1 / 3)]) / k]
        down = (i + j) < k - 1
        bary.append(np.column_stack([(i[down] + 2 / 3), (j[down] + 2 / 3)]) / k)
        b = np.vstack(bary)  # (k^2, 2)
        w = np.column_stack([1.0 - b.sum(axis=1), b])  # (k^2, 3)
        pts = np.einsum("sv,fvc->fsc", w, v[faces]).reshape(-1, 3)
        points.append(pts)
        normals.append(np.repeat(normal[faces], len(w), axis=0))
        areas.append(np.repeat(area[faces] / len(w), len(w)))
    return np.vstack(points), np.vstack(normals), np.concatenate(areas)


def design_feet(points, e, kern, near: float = 0.02, normals: bool = False):
    """``(k, 3)``: ``points`` moved their distance ``e (k,)`` to the design of ``kern`` (bound
    kernels) down the distance's gradient (central differences); those within ``near`` mm of it
    stay where they are. With ``normals``, also ``(k, 3)`` the unit gradient (from the design out
    to the point; zero where not moved)."""
    points = np.asarray(points, float)
    feet = points.copy()
    out = np.zeros_like(feet)
    far = np.abs(e) > near
    if not far.any():
        return (feet, out) if normals else feet
    p, d0 = points[far], np.abs(e[far])
    h = np.minimum(0.05, 0.25 * d0)[:, None, None] * np.eye(3)[None]
    probes = np.concatenate([(p[:, None] + h).reshape(-1, 3), (p[:, None] - h).reshape(-1, 3)])
    d = kern.mesh_distances(probes).reshape(2, len(p), 3)
    grad = (d[0] - d[1]) / (2.0 * h[:, 0, 0])[:, None]
    grad /= np.maximum(np.linalg.norm(grad, axis=1), 1e-12)[:, None]
    feet[far] = p - d0[:, None] * grad
    out[far] = grad
    return (feet, out) if normals else feet


def stock_over(model, kern, points, normals, step: float) -> np.ndarray:
    """``(k,) bool``: whether the stock's dexel ``model`` holds material a lattice ``step`` out from
    each of ``points (k, 3)`` along its unit normal: on the nearest line of some direction, at a
    point outside the design of ``kern`` (so the material there is stock left on the part, not the
    part)."""
    points = np.asarray(points, float)
    out = np.zeros(len(points), bool)
    if not len(points):
        return out
    q = points + step * np.asarray(normals, float)
    lo, h, n = np.asarray(model.lo, float), float(model.step), np.asarray(model.n, np.int64)
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        iu = np.clip(np.floor((q[:, u] - lo[u]) / h).astype(np.int64), 0, n[u] - 1)
        iv = np.clip(np.floor((q[:, v] - lo[v]) / h).astype(np.int64), 0, n[v] - 1)
        at = q.copy()
        at[:, u] = lo[u] + (iu + 0.5) * h
        at[:, v] = lo[v] + (iv + 0.5) * h
        hit = np.nonzero(~out & _in_lines(model.start[a], model.iv[a], iu * n[v] + iv, at[:, a]))[0]
        if len(hit):
            out[hit] = ~np.asarray(kern.points_inside(at[hit]), bool)
    return out


def _in_lines(start, iv, line, t) -> np.ndarray:
    """``(k,) bool``: ``t (k,)`` lies within an interval of line ``line (k,)`` (CSR ``start``, ``iv``)."""
    s0, s1 = start[line], start[line + 1]
    inside = np.zeros(len(t), bool)
    left = s0.copy()  # binary search: the first interval of the line ending at or after t
    right = s1.copy()
    while (left < right).any():
        go = left < right
        mid = (left + right) // 2
        ends = np.where(go, iv[np.minimum(mid, len(iv) - 1), 1], np.inf) if len(iv) else np.full(len(t), np.inf)
        before = go & (ends < t)
        left = np.where(before, mid + 1, left)
        right = np.where(go & ~before, mid, right)
    has = left < s1
    inside[has] = iv[left[has], 0] <= t[has]
    return inside


def _fans(normals, max_tilt: float) -> np.ndarray:
    """``(k, a, 3)`` unit axes: the fan of :data:`TILTS` x :data:`AZIMUTHS` within ``max_tilt``,
    and each point's normal tilted no further than ``max_tilt``."""
    fan = [np.array([0.0, 0.0, 1.0])]
    for t in TILTS[1:]:
        if t > max_tilt + 1e-9:
            break
        for a in range(AZIMUTHS):
            phi = 2 * math.pi * a / AZIMUTHS
            fan.append(np.array([math.sin(math.radians(t)) * math.cos(phi),
                                 math.sin(math.radians(t)) * math.sin(phi), math.cos(math.radians(t))]))
    fan = np.repeat(np.array(fan)[None], len(normals), axis=0)
    n = np.asarray(normals, float)
    horiz = np.hypot(n[:, 0], n[:, 1])
    tilt = np.arctan2(horiz, n[:, 2])
    t = np.minimum(tilt, math.radians(max_tilt))
    az = np.where((horiz > 1e-12)[:, None], n[:, :2] / np.maximum(horiz, 1e-12)[:, None], [1.0, 0.0])
    own = np.column_stack([np.sin(t)[:, None] * az, np.cos(t)])
    return np.concatenate([fan, own[:, None]], axis=1)


def _clear_along(centre, axes, tool, kern, tol: float) -> np.ndarray:
    """``(k,) bool``: some axis of ``axes (k, a, 3)`` keeps the ball ``tool`` at ``centre (k, 3)``
    and its flutes, shank and holder (radii sampled about a radius apart along the axis) clear of
    the part; the axes tried in turn, each only for the points no axis before cleared."""
    R = tool.radius
    heights, radii = [], []
    for top, radius in ((tool.flute_length, R), (tool.gauge_length, 0.5 * tool.shank_diameter),
                        (tool.gauge_length + tool.holder_length, 0.5 * tool.holder_diameter)):
        start = heights[-1] if heights else R
        if radius <= 0 or top <= start:
            continue
        count = max(2, int(math.ceil((top - start) / max(radius, 0.25))) + 1)
        heights += list(np.linspace(start, top, count))
        radii += [radius] * count
    h, r = np.array(heights), np.array(radii)
    ok = np.zeros(len(centre), bool)
    for a in range(axes.shape[1]):
        at = np.nonzero(~ok)[0]
        if not len(at):
            break
        pts = centre[at, None] + axes[at, a, None] * h[None, :, None]  # (q, s, 3)
        d = kern.mesh_distances(pts.reshape(-1, 3)).reshape(len(at), len(h))
        ok[at] = (d >= r[None] - tol).all(axis=1)
    return ok


def reach(feet, normals, balls, kern, floor: float, five_axis: bool, tol: float, max_tilt: float = 60.0,
          skip=None):
    """``(fits (k, b), reaches (k, b))`` bool: whether each ball of ``balls`` fits at each of
    ``feet (k, 3)`` (its centre a radius out along ``normals`` keeps that from the part of
    ``kern``), and fits and reaches it, its tip no lower than ``floor`` (the part's bottom) and the
    whole tool clear along the vertical axis (dropped over the centre: :class:`ToolDrop`), or with
    ``five_axis`` along one of a fan of axes (:func:`_clear_along`). ``skip (k,) bool``: points whose
    reach need not be tested (left False)."""
    k = len(feet)
    fits = np.zeros((k, len(balls)), bool)
    reaches = np.zeros((k, len(balls)), bool)
    done = np.zeros(k, bool) if skip is None else np.asarray(skip, bool).copy()
    for j, tool in enumerate(balls):
        centre = feet + tool.radius * normals
        fits[:, j] = kern.mesh_distances(centre) >= tool.radius - tol
        above = centre[:, 2] - tool.radius >= floor - tol  # a tip never goes below the part's bottom
        at = np.nonzero(fits[:, j] & above & ~done)[0]
        if not len(at):
            continue
        # the vertical tool dropped over the centre (moved the tolerance off the point, so that a
        # ball touching a wall slides down it) stops no higher than the ball touching the point
        off = centre[at] + tol * normals[at]
        ok = ToolDrop(tool, kern, floor)(off[:, :2]) <= off[:, 2] - tool.radius + tol
        if five_axis and (~ok).any():
            rest = at[~ok]
            ok[~ok] = _clear_along(centre[rest], _fans(normals[rest], max_tilt), tool, kern, tol)
        reaches[at, j] = ok
        done[at[ok]] = True  # one ball that reaches is enough
    return fits, reaches


def what_is_left(mesh, kern, points, e, step: float, tools, used: set, five_axis: bool, tolerance: float,
                 stock=None):
    """``(arrays, report)``: the design ``mesh`` (bound to ``kern``) sampled by area
    (:func:`surface_samples`), each sample's deviation from the nearest foot of the stock's dexel
    ends ``points (k, 3)``, ``e (k,)`` (lattice ``step`` mm), and its reason (:data:`REASONS`)
    with the ``tools`` of the table (``used``: the names the job's operations ran). ``arrays``:
    ``points``, ``normals``, ``area`` mm², ``e`` mm (NaN: not measured), ``reason`` (index into
    ``reasons``). ``report``: area per reason (mm²), the shares within tolerance of the whole
    surface and of the surface some tool of the table reaches. ``stock``: the stock's dexel model:
    a sample with no end near it but stock over it (:func:`stock_over`) has more than
    :data:`NEAR_STEPS` steps of material left on it (``e`` NaN) and is given its reason, not
    "not measured"."""
    sp, sn, sa = surface_samples(mesh, step)
    dev = np.full(len(sp), np.nan)
    if len(points):
        feet = design_feet(points, e, kern)
        dist, idx = cKDTree(feet).query(sp, distance_upper_bound=NEAR_STEPS * step)
        found = np.isfinite(dist)
        dev[found] = np.asarray(e)[idx[found]]
    reason = np.full(len(sp), UNMEASURED, np.int8)
    reason[np.abs(dev) <= tolerance] = WITHIN
    reason[dev < -tolerance] = GOUGED
    thick = np.zeros(len(sp), bool)
    if stock is not None:
        unmeasured = np.nonzero(np.isnan(dev))[0]
        thick[unmeasured] = stock_over(stock, kern, sp[unmeasured], sn[unmeasured], step)
    left = np.nonzero((dev > tolerance) | thick)[0]
    balls = sorted([t for t in tools if t.type == "ball"], key=lambda t: t.radius)
    if len(left):
        if not balls:
            reason[left] = NO_FIT
        else:  # the job's balls first (smallest first): one that reaches settles it
            floor = float(mesh.bounds[0, 2])
            mine = [t for t in balls if t.name in used]
            others = [t for t in balls if t.name not in used]
            fits_m, reach_m = reach(sp[left], sn[left], mine, kern, floor, five_axis, tolerance)
            by_job = reach_m.any(axis=1)
            fits_o, reach_o = reach(sp[left], sn[left], others, kern, floor, five_axis, tolerance, skip=by_job)
            r = np.full(len(left), LEFT, np.int8)
            r[~by_job] = UNUSED
            r[~(by_job | reach_o.any(axis=1))] = NO_AXIS if five_axis else SHADOW
            r[~(fits_m.any(axis=1) | fits_o.any(axis=1))] = NO_FIT
            reason[left] = r
    area = {name: float(sa[reason == k].sum()) for k, name in enumerate(REASONS)}
    total = float(sa.sum())
    reachable = area["within tolerance"] + area["gouged"] + area["left by the job"] + area["a tool the job does not use"]
    report = {
        "area_mm2": total,
        "by_reason_mm2": area,
        "within_tolerance": area["within tolerance"] / total if total else 0.0,
        "reachable_mm2": reachable,
        "reachable_within_tolerance": area["within tolerance"] / reachable if reachable else 1.0,
        "unreachable_mm2": total - reachable - area["not measured"],
        "thick_mm2": float(sa[thick].sum()),  # of those out of tolerance: more than NEAR_STEPS steps of stock on it
        "tolerance": tolerance, "step": step, "five_axis": five_axis,
        "balls": [t.name for t in balls], "used": sorted(used),
        "reasons": list(REASONS),
    }
    return {"points": sp, "normals": sn, "area": sa, "e": dev, "reason": reason}, report
