"""The machined dexel model against the design: signed distance at every dexel end, ISO 25178
areal height parameters over them, volumes left and gouged.

Each dexel end of the machined model is a point of its surface. Its deviation is the exact
distance to the design mesh (through the BVH), positive where the point lies outside the design
(material left: excess) and negative inside it (gouge); inside/outside comes from the design's
own dexels on the same line. Every end counts as one sample.

A design dexel end that the cut left without material is reported apart (a wall cut through has
no machined end to measure): how many, and an upper bound of how deep each was cut, the nearer of
the machined material along its line and the nearest machined dexel end (both lie on the machined
solid). It is only a bound: where a line grazes the design, a cut within tolerance can remove a
short design dexel whole, and the bound is then up to about a lattice step.

ISO 25178-2 amplitude parameters of the deviations e: ``Sa`` mean |e|, ``Sq`` RMS, ``Sp`` highest
peak, ``Sv`` depth of the deepest pit as a positive number (0 without pits), ``Sz = Sp + Sv``. The
seed used a signed Sv and so Sz = max + min; the standard's values are used here.

A stock given as a mesh (say the ``machined.stl`` of an earlier simulation, whose marching-cubes
surface cuts the corners of convex edges by up to about half a lattice step) may lie inside the
design where the path never cuts. Such dexel ends are the stock's, not a gouge of the path: the
ends left exactly where the stock had them are told apart (:func:`measure_lines`).

Everything is measured by blocks of lines (:func:`measure_lines`, one direction's rows) and
joined (:func:`join_measures`): one process measures each direction as one block, the workers of a
cluster their own blocks, and both get the same floats (sums kept exact, extremes the first in
the lattice's order).
"""
from __future__ import annotations

import numba
import numpy as np

from ..kernels.bvh import build_bvh
from ..kernels.backend import MeshKernels
from ..progress import PIECES, Meter, ranges
from .dexel import DexelModel, line_rows, material_mesh
from .exactsum import ROOM, expansion, grow, total

DEVIATION_KEYS = ("Sa", "Sq", "Sp", "Sv", "Sz", "gouge_max", "excess_max", "within_tolerance",
                  "removed_volume", "remaining_volume")


@numba.njit(cache=True)
def _inside(start, iv, dstart, div, out_inside):
    """For every interval end of (start, iv), whether it lies strictly inside an interval of the
    design (dstart, div) on the same line; ends in order (start0, end0, start1, ...)."""
    for line in range(start.shape[0] - 1):
        for k in range(start[line], start[line + 1]):
            for e in range(2):
                w = iv[k, e]
                inside = False
                for q in range(dstart[line], dstart[line + 1]):
                    if div[q, 0] < w < div[q, 1]:
                        inside = True
                        break
                out_inside[2 * k + e] = inside


@numba.njit(cache=True)
def _cut_away(dstart, div, mstart, miv, depth):
    """For every interval end of the design (dstart, div) that no machined interval holds: how far
    along the line, into the design dexel, the nearest machined material is (the dexel's length
    when none is left in it); NaN where the end is still covered."""
    for line in range(dstart.shape[0] - 1):
        for k in range(dstart[line], dstart[line + 1]):
            s = div[k, 0]
            e = div[k, 1]
            for end in range(2):
                w = div[k, end]
                covered = False
                for q in range(mstart[line], mstart[line + 1]):
                    if miv[q, 0] <= w <= miv[q, 1]:
                        covered = True
                        break
                if covered:
                    continue
                best = e - s
                for q in range(mstart[line], mstart[line + 1]):
                    lo = max(miv[q, 0], s)
                    hi = min(miv[q, 1], e)
                    if lo <= hi:
                        best = min(best, abs(lo - w), abs(hi - w))
                depth[2 * k + end] = best


@numba.njit(cache=True)
def _difference_length(astart, aiv, bstart, biv, p):
    """Total length of (A minus B) over all lines (two sorted interval sets per line), as the
    expansion ``p`` (:mod:`~meshmill.simulation.exactsum`); returns its length."""
    m = 0
    for line in range(astart.shape[0] - 1):
        q = bstart[line]
        qe = bstart[line + 1]
        for k in range(astart[line], astart[line + 1]):
            s = aiv[k, 0]
            e = aiv[k, 1]
            while q < qe and biv[q, 1] <= s:
                q += 1
            cur = s
            r = q
            while r < qe and biv[r, 0] < e:
                if biv[r, 0] > cur:
                    m = grow(p, m, biv[r, 0] - cur)
                cur = max(cur, biv[r, 1])
                r += 1
            if cur < e:
                m = grow(p, m, e - cur)
    return m


@numba.njit(cache=True)
def _same_end(start, iv, sstart, siv, out):
    """For every interval end of (start, iv), whether the stock (sstart, siv) has an end at exactly
    that coordinate on the same line (the cut left it where it was)."""
    for line in range(start.shape[0] - 1):
        for k in range(start[line], start[line + 1]):
            for e in range(2):
                w = iv[k, e]
                for q in range(sstart[line], sstart[line + 1]):
                    if siv[q, 0] == w or siv[q, 1] == w:
                        out[2 * k + e] = True
                        break


def difference_length(a: tuple, b: tuple) -> np.ndarray:
    """The length of ``a`` minus ``b``, two CSR ``(start, iv)`` sets of the same lines, as an
    exact-sum expansion."""
    p = np.zeros(ROOM)
    return p[:_difference_length(a[0], a[1], b[0], b[1], p)].copy()


def difference_volume(a: DexelModel, b: DexelModel) -> float:
    """Volume of ``a`` minus ``b`` (same lattice), mean of the three directions, mm^3."""
    return float(np.mean([total(difference_length((a.start[k], a.iv[k]), (b.start[k], b.iv[k]))) * a.step ** 2
                          for k in range(3)]))


def end_points(lo, n, step, a: int, start, iv, first_row: int = 0) -> np.ndarray:
    """``(2m, 3)`` points of the interval ends ``(start, iv)`` (CSR) of the lines along ``a`` from
    the lattice row ``first_row`` (along the axis after ``a``) on: start, end of each dexel."""
    u, v = (a + 1) % 3, (a + 2) % 3
    nv = int(n[v])
    line = np.repeat(np.arange(len(start) - 1), np.diff(start))
    p = np.empty((2 * len(line), 3))
    p[:, u] = np.repeat(lo[u] + (first_row + line // nv + 0.5) * step, 2)
    p[:, v] = np.repeat(lo[v] + (line % nv + 0.5) * step, 2)
    p[:, a] = iv.reshape(-1)
    return p


def _uncovered(design: tuple, model: tuple) -> np.ndarray:
    """``(2m,)`` over the design's dexel ends: how far along the line the nearest material of
    ``model`` (same lines) is where no interval of it holds the end, NaN where one does."""
    depth = np.full(2 * len(design[1]), np.nan)
    _cut_away(design[0], design[1], model[0], model[1], depth)
    return depth


def _extreme(e, pts, keep, low: bool):
    """``(value, point)`` of the first smallest (``low``) or largest ``e`` among ``keep``; None
    when none is kept."""
    idx = np.nonzero(keep)[0]
    if not len(idx):
        return None
    k = idx[int(np.argmin(e[idx]) if low else np.argmax(e[idx]))]
    return float(e[k]), pts[k]


def measure_lines(lo, n, step, a: int, first_row: int, machined: tuple, stock: tuple, design: tuple, kern,
                  tolerance: float, samples: bool = True) -> dict:
    """The deviation figures of one block of lines along ``a`` (from lattice row ``first_row``):
    the ``machined``, the ``stock`` it was cut from and the ``design``, each CSR ``(start, iv)``
    over the same lines; ``kern``: :class:`~meshmill.kernels.backend.MeshKernels` of the solid
    the design bounds. Sums are exact-sum expansions and extremes the first in line order, so
    :func:`join_measures` gives the same figures however the lattice was split into blocks;
    ``samples``: keep the ends and their deviations (the block's size) for ``deviation.npz``."""
    pts = end_points(lo, n, step, a, *machined, first_row)
    inside = np.zeros(len(pts), np.bool_)
    _inside(machined[0], machined[1], design[0], design[1], inside)
    d = kern.mesh_distances(pts)
    e = np.where(inside, -d, d)
    same = np.zeros(len(pts), np.bool_)
    _same_end(machined[0], machined[1], stock[0], stock[1], same)
    short = same & (e < 0.0)  # the stock's own ends inside the design: not the path's gouges
    gone = _uncovered(design, machined)
    # design ends cut away, less those the stock never held (not the path's doing)
    away = ~np.isnan(gone) & np.isnan(_uncovered(design, stock))
    length = [expansion(iv[:, 1] - iv[:, 0]) for _, iv in (design, stock, machined)]
    return {
        "a": a, "first_row": first_row, "dexels": int(len(machined[1])), "samples": int(len(e)),
        "abs": expansion(np.abs(e)), "square": expansion(e * e),
        "low": _extreme(e, pts, np.ones(len(e), bool), True), "high": _extreme(e, pts, np.ones(len(e), bool), False),
        "path_low": _extreme(e, pts, ~short, True),
        "within": int(np.sum(np.abs(e) <= tolerance)), "excess_samples": int(np.sum(e > tolerance)),
        "gouge_samples": int(np.sum((e < -tolerance) & ~short)),
        "short": int(short.sum()), "short_low": _extreme(e, pts, short, True),
        "away_points": end_points(lo, n, step, a, *design, first_row)[away], "away_depth": gone[away],
        "design": length[0], "stock": length[1], "machined": length[2],
        "design_outside_stock": difference_length(design, stock), "remaining": difference_length(machined, design),
        "design_cut": difference_length(design, machined),
        "points": pts if samples else None, "e": e if samples else None,
    }


def nearest_end(lo, n, step, a: int, first_row: int, machined: tuple, points: np.ndarray,
                within: np.ndarray) -> np.ndarray:
    """``(j,)`` distance from each of ``points (j, 3)`` to the nearest dexel end of a block of
    machined lines along ``a`` (CSR ``(start, iv)`` from lattice row ``first_row``) where it is
    under ``within (j,)`` (the depth bound it would improve), inf where no end of the block is
    that near (the block's rows are farther, or it has no ends)."""
    from scipy.spatial import cKDTree

    out = np.full(len(points), np.inf)
    if not len(points) or not len(machined[1]):
        return out
    u, nv = (a + 1) % 3, int(n[(a + 2) % 3])
    rows = (len(machined[0]) - 1) // nv
    s0, s1 = lo[u] + (first_row + 0.5) * step, lo[u] + (first_row + rows - 0.5) * step
    near = np.nonzero(np.maximum(0.0, np.maximum(s0 - points[:, u], points[:, u] - s1)) < within)[0]
    if len(near):
        ends = end_points(lo, n, step, a, *machined, first_row)
        out[near] = cKDTree(ends).query(points[near], distance_upper_bound=float(within[near].max()))[0]
    return out


def _first(items, low: bool):
    """The first smallest (``low``) or largest of ``(value, point)`` items (None left out)."""
    best = None
    for it in items:
        if it is not None and (best is None or (it[0] < best[0] if low else it[0] > best[0])):
            best = it
    return best


def join_measures(parts: list, nearest: np.ndarray | None, step: float) -> dict:
    """The whole model's figures from the blocks' :func:`measure_lines` (in the order of the
    lattice: direction, then first row) and ``nearest``, the distance from each cut-away design
    end (in that order) to the nearest machined end where it is under the end's depth bound
    (:func:`nearest_end` over all blocks).

    Returns the ISO 25178 heights and tolerance figures of :func:`surface_parameters` (the
    gouge over the path's own ends), ``volumes`` (mm^3, mean of the three directions), the stock's
    short ends and the design ends cut away with their depth bounds (see the module notes)."""
    k = sum(p["samples"] for p in parts)
    low, high = _first([p["low"] for p in parts], True), _first([p["high"] for p in parts], False)
    path_low = _first([p["path_low"] for p in parts], True)
    short_low = _first([p["short_low"] for p in parts], True)
    sp = max(0.0, high[0]) if high else 0.0
    sv = max(0.0, -low[0]) if low else 0.0
    gouge = max(0.0, -path_low[0]) if path_low else 0.0

    def volume(key):
        return float(np.mean([total(*[p[key] for p in parts if p["a"] == a]) * step ** 2 for a in range(3)]))

    away_pts = np.concatenate([p["away_points"] for p in parts]) if parts else np.zeros((0, 3))
    away_depth = np.concatenate([p["away_depth"] for p in parts]) if parts else np.zeros(0)
    if nearest is not None and len(away_depth):
        away_depth = np.minimum(away_depth, nearest)
    return {
        "Sa": total(*[p["abs"] for p in parts]) / k if k else 0.0,
        "Sq": float(np.sqrt(total(*[p["square"] for p in parts]) / k)) if k else 0.0,
        "Sp": sp, "Sv": sv, "Sz": sp + sv,
        "gouge_max": gouge, "gouge_at": path_low[1].round(6).tolist() if gouge > 0 else None,
        "excess_max": sp, "excess_at": high[1].round(6).tolist() if sp > 0 else None,
        "within_tolerance": sum(p["within"] for p in parts) / k if k else 1.0,
        "gouge_samples": sum(p["gouge_samples"] for p in parts),
        "excess_samples": sum(p["excess_samples"] for p in parts), "samples": k,
        "short": sum(p["short"] for p in parts), "short_low": short_low,
        "away_points": away_pts, "away_depth": away_depth,
        "dexels": [sum(p["dexels"] for p in parts if p["a"] == a) for a in range(3)],
        "volumes_by_direction": [total(*[p["machined"] for p in parts if p["a"] == a]) * step ** 2 for a in range(3)],
        "volumes": {key: volume(key) for key in ("design", "stock", "machined", "design_outside_stock", "remaining",
                                                 "design_cut")},
    }


def deviations(machined: DexelModel, design_model: DexelModel, design_mesh, device="cpu"):
    """``(points (k, 3), e (k,), cut_points (j, 3), cut_depth (j,))``: every dexel end of
    ``machined`` and its signed distance to the design, mm (excess > 0, gouge < 0); and the design's
    dexel ends the cut left without material, with an upper bound of how deep they were cut (see
    the module notes). The distances run on ``device``."""
    kern = MeshKernels(build_bvh(design_mesh.vertices, design_mesh.faces), device)
    parts = [measure_lines(machined.lo, machined.n, machined.step, a, 0, (machined.start[a], machined.iv[a]),
                           (design_model.start[a], design_model.iv[a]), (design_model.start[a], design_model.iv[a]),
                           kern, 0.0) for a in range(3)]
    gone = np.concatenate([p["away_points"] for p in parts])
    depth = np.concatenate([p["away_depth"] for p in parts])
    nearest = np.min([nearest_end(machined.lo, machined.n, machined.step, a, 0, (machined.start[a], machined.iv[a]),
                                  gone, depth) for a in range(3)], axis=0) if len(gone) else None
    joined = join_measures(parts, nearest, machined.step)
    return (np.concatenate([p["points"] for p in parts]), np.concatenate([p["e"] for p in parts]),
            joined["away_points"], joined["away_depth"])


def surface_parameters(points: np.ndarray, e: np.ndarray, tolerance: float) -> dict:
    """ISO 25178 heights and the tolerance figures of deviations ``e (k,)`` at ``points (k, 3)``."""
    if len(e) == 0:
        return {"Sa": 0.0, "Sq": 0.0, "Sp": 0.0, "Sv": 0.0, "Sz": 0.0, "gouge_max": 0.0, "gouge_at": None,
                "excess_max": 0.0, "excess_at": None, "within_tolerance": 1.0, "gouge_samples": 0,
                "excess_samples": 0, "samples": 0}
    lo, hi = int(np.argmin(e)), int(np.argmax(e))
    sp = max(0.0, float(e[hi]))
    sv = max(0.0, -float(e[lo]))
    return {
        "Sa": float(np.mean(np.abs(e))),
        "Sq": float(np.sqrt(np.mean(e * e))),
        "Sp": sp,
        "Sv": sv,
        "Sz": sp + sv,
        "gouge_max": sv,
        "gouge_at": points[lo].round(6).tolist() if sv > 0 else None,
        "excess_max": sp,
        "excess_at": points[hi].round(6).tolist() if sp > 0 else None,
        "within_tolerance": float(np.mean(np.abs(e) <= tolerance)),
        "gouge_samples": int(np.sum(e < -tolerance)),
        "excess_samples": int(np.sum(e > tolerance)),
        "samples": int(len(e)),
    }


def measure(machined, start_model, design, design_model, floor, tolerance, step, device="cpu", samples=True,
            progress=None):
    """The machined dexel model against the design: ``(deviation dict, volumes dict (mm^3),
    warnings, (points (k, 3), e (k,)))`` the dexel ends and their signed deviations (mm; None
    without ``samples``). The stock's own ends inside the design (``start_model`` short of it) are
    not counted as gouges; ``floor`` is the Z an open design's solid reaches down to. Measured in
    blocks of lattice rows (the same figures), the share done told to ``progress``."""
    # an open design: deviations to the solid it bounds (its sheets, curtains and floor)
    material = material_mesh(design, floor)
    kern = MeshKernels(build_bvh(material.vertices, material.faces), device)
    lo, n = machined.lo, machined.n
    blocks = [(machined.start[a], machined.iv[a]) for a in range(3)]
    cuts = [(a, i0, i1) for a in range(3) for i0, i1 in ranges(int(n[(a + 1) % 3]), PIECES // 3)]
    meter = Meter(progress, "measuring", sum(len(m.iv[a]) for m in (machined, design_model) for a in range(3)))
    parts = []
    for a, i0, i1 in cuts:
        def rows(m):
            return line_rows(m.start[a], m.iv[a], int(n[(a + 2) % 3]), i0, i1)

        cut, design_rows = rows(machined), rows(design_model)
        parts.append(measure_lines(lo, n, step, a, i0, cut, rows(start_model), design_rows, kern, tolerance, samples))
        meter.done(len(cut[1]) + len(design_rows[1]))
    away, depth = (np.concatenate([p[k] for p in parts]) for k in ("away_points", "away_depth"))
    nearest = np.min([nearest_end(lo, n, step, a, 0, blocks[a], away, depth) for a in range(3)],
                     axis=0) if len(away) else None
    deviation, volumes, warnings = measured(join_measures(parts, nearest, step), tolerance, step)
    return deviation, volumes, warnings, ((np.concatenate([p["points"] for p in parts]),
                                           np.concatenate([p["e"] for p in parts])) if samples else (None, None))


def measured(m: dict, tolerance: float, step: float) -> tuple[dict, dict, list]:
    """``(deviation, volumes, warnings)`` of the summary from :func:`~meshmill.simulation.deviation.join_measures`."""
    warnings = []
    vol = m["volumes"]
    outside = vol["design_outside_stock"]
    if outside > 1e-6 * max(vol["design"], 1.0):
        warnings.append(f"{outside:.3f} mm^3 of the design lies outside the stock: the stock is short of the design "
                        "there (not counted as gouged by the path)")
    removed = vol["stock"] - vol["machined"]
    gouged = max(0.0, vol["design_cut"] - outside)
    deviation = {k: m[k] for k in DEVIATION_KEYS[:8]}
    deviation.update(removed_volume=removed, remaining_volume=vol["remaining"])
    cut_pts, cut_depth = m["away_points"], m["away_depth"]
    deep = int(np.argmax(cut_depth)) if len(cut_depth) else -1
    short, short_low = m["short"], m["short_low"]
    deviation.update(units="mm, mm^3", tolerance=tolerance, gouge_at=m["gouge_at"], excess_at=m["excess_at"],
                     gouged_volume=gouged, samples=m["samples"], stock_short_ends=short,
                     stock_short_max=-short_low[0] if short else 0.0,
                     stock_short_at=short_low[1].round(6).tolist() if short else None,
                     design_ends_cut_away=int(len(cut_depth)),
                     cut_away_depth_max=float(cut_depth[deep]) if deep >= 0 else 0.0,
                     cut_away_at=cut_pts[deep].round(6).tolist() if deep >= 0 else None)
    if short and -short_low[0] > tolerance:
        warnings.append(f"the stock lies inside the design at {short} dexel end(s) the path does not cut, "
                        f"up to {-short_low[0]:.3f} mm at {deviation['stock_short_at']}: the stock is short of the "
                        "design there (not a gouge of this path)")
    if deep >= 0 and cut_depth[deep] > max(tolerance, step):
        warnings.append(f"{len(cut_depth)} design dexel end(s) cut away, up to {cut_depth[deep]:.3f} mm deep at "
                        f"{cut_pts[deep].round(3).tolist()} (a bound; gouged volume {gouged:.3f} mm^3)")
    volumes = {"design": vol["design"], "stock": vol["stock"], "machined": vol["machined"],
               "removed": removed, "remaining": vol["remaining"], "gouged": gouged}
    return deviation, volumes, warnings
