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
ends left exactly where the stock had them are told apart (:func:`uncut_ends`).
"""
from __future__ import annotations

import numba
import numpy as np

from ..kernels.bvh import build_bvh
from ..kernels.backend import MeshKernels
from .dexel import DexelModel


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
def _difference_length(astart, aiv, bstart, biv):
    """Total length of (A minus B) over all lines, two sorted interval sets per line."""
    total = 0.0
    for line in range(astart.shape[0] - 1):
        q = bstart[line]
        qe = bstart[line + 1]
        for k in range(astart[line], astart[line + 1]):
            s = aiv[k, 0]
            e = aiv[k, 1]
            while q < qe and biv[q, 1] <= s:
                q += 1
            cur = s
            p = q
            while p < qe and biv[p, 0] < e:
                if biv[p, 0] > cur:
                    total += biv[p, 0] - cur
                cur = max(cur, biv[p, 1])
                p += 1
            if cur < e:
                total += e - cur
    return total


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


def uncut_ends(machined: DexelModel, stock: DexelModel) -> np.ndarray:
    """``(k,) bool`` over the dexel ends of ``machined`` in the order of :func:`deviations`: those
    the cut left exactly where the ``stock`` (same lattice) had them."""
    out = []
    for a in range(3):
        same = np.zeros(2 * len(machined.iv[a]), np.bool_)
        _same_end(machined.start[a], machined.iv[a], stock.start[a], stock.iv[a], same)
        out.append(same)
    return np.concatenate(out)


def difference_volume(a: DexelModel, b: DexelModel) -> float:
    """Volume of ``a`` minus ``b`` (same lattice), mean of the three directions, mm^3."""
    vols = [_difference_length(a.start[k], a.iv[k], b.start[k], b.iv[k]) * a.step ** 2 for k in range(3)]
    return float(np.mean(vols))


def end_points(model: DexelModel, a: int) -> np.ndarray:
    """``(2m, 3)`` points of the interval ends of direction ``a`` (start, end of each dexel)."""
    u, v = (a + 1) % 3, (a + 2) % 3
    nu, nv = model.shape(a)
    line = np.repeat(np.arange(nu * nv), np.diff(model.start[a]))
    p = np.empty((2 * len(line), 3))
    p[:, u] = np.repeat(model.lo[u] + (line // nv + 0.5) * model.step, 2)
    p[:, v] = np.repeat(model.lo[v] + (line % nv + 0.5) * model.step, 2)
    p[:, a] = model.iv[a].reshape(-1)
    return p


def deviations(machined: DexelModel, design_model: DexelModel, design_mesh, device="cpu"):
    """``(points (k, 3), e (k,), cut_points (j, 3), cut_depth (j,))``: every dexel end of
    ``machined`` and its signed distance to the design, mm (excess > 0, gouge < 0); and the design's
    dexel ends the cut left without material, with an upper bound of how deep they were cut (see
    the module notes). The distances run on ``device``."""
    from scipy.spatial import cKDTree

    kern = MeshKernels(build_bvh(design_mesh.vertices, design_mesh.faces), device)
    pts, devs, gone_pts, gone_depth = [], [], [], []
    for a in range(3):
        p = end_points(machined, a)
        inside = np.zeros(len(p), np.bool_)
        _inside(machined.start[a], machined.iv[a], design_model.start[a], design_model.iv[a], inside)
        d = kern.mesh_distances(p)
        pts.append(p)
        devs.append(np.where(inside, -d, d))
    machined_pts = np.concatenate(pts)
    gone_pts, gone_depth = uncovered_ends(design_model, machined)
    if len(gone_pts) and len(machined_pts):
        # nearer than the material along the line: the nearest machined dexel end (on its surface)
        gone_depth = np.minimum(gone_depth, cKDTree(machined_pts).query(gone_pts)[0])
    return machined_pts, np.concatenate(devs), gone_pts, gone_depth


def uncovered_ends(design_model: DexelModel, model: DexelModel):
    """``(points (j, 3), depth (j,))``: the design's dexel ends that no interval of ``model`` (same
    lattice) holds, and how far along the line the nearest material of ``model`` is (a wall cut
    through leaves no machined end to measure)."""
    pts, depths = [], []
    for a in range(3):
        q = end_points(design_model, a)
        depth = np.full(len(q), np.nan)
        _cut_away(design_model.start[a], design_model.iv[a], model.start[a], model.iv[a], depth)
        gone = ~np.isnan(depth)
        pts.append(q[gone])
        depths.append(depth[gone])
    return np.concatenate(pts), np.concatenate(depths)


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
