"""3-axis waterline (Z-level) finishing and roughing loops for flat, ball and bull-nose cutters.

A cutter at tip height z and position (x, y) gouges exactly when the drop-cutter height there is
above z, so the waterline loops at z are the level set ``drop(x, y) = z``. The drop-cutter heights
are computed once on a grid over the part (``sample`` apart, widened by the cutter radius) and serve
every level. Per level, marching squares (with the cell centre deciding the saddles) gives the
crossings, which are moved onto the level set by a bracketed search with the exact drop-cutter:
each loop point keeps ``drop <= z`` (no gouge) and its height is within 1e-6 mm of z, or (at a
vertical wall, where the height jumps) it is within 1e-5 mm of the jump.
A point counts as inside when ``drop > z`` strictly, so a flat facet lying exactly at z gives no
loop of its own. Loops are chained by grid-edge identity, closed, and run clockwise around material
seen from +Z (climb milling with a clockwise spindle).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numba
import numpy as np

from ..errors import InputError
from ..geometry.bvh import build_bvh
from ..geometry.mesh import Mesh
from ..geometry.slicing import z_levels
from ..kernels import cpu
from ..tolerances import GOUGE_TOL
from ..toolpath.linking import link_passes, simplify_polyline
from .raster import SAFE_ABOVE, pick_tool
from .verify import verify_toolpath

SECANT_ROUNDS = 80
TOUCH = 1e-6  # mm: a loop point's drop-cutter height is within this of its level ...
WALL = 1e-5  # mm: ... or within this distance of where it jumps past it (a vertical wall)


@dataclass
class WaterlineParams:
    step_down: float
    sample: float = 0.5
    tol: float = GOUGE_TOL

    def check(self):
        for name in ("step_down", "sample", "tol"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise InputError(f"--{name.replace('_', '-').replace('tol', 'tolerance')} must be a positive number, got {v}")
        if self.sample < 1e-3 or self.step_down < 1e-4:
            raise InputError("--sample must be at least 0.001 mm and --step-down at least 0.0001 mm")


@numba.njit(cache=True)
def _cell_segments(inside, centre_inside):
    """Marching squares over the node grid ``inside (nx, ny)``: segments as pairs of edge ids,
    from the edge where the cell's counter-clockwise boundary leaves the inside to the edge where
    it enters it (inside on the left). Edge ids: 2·(i·ny + j) for the edge (i,j)-(i+1,j), 2·(i·ny
    + j) + 1 for (i,j)-(i,j+1). ``centre_inside (nx-1, ny-1)`` decides the saddles."""
    nx, ny = inside.shape
    out = []
    for i in range(nx - 1):
        for j in range(ny - 1):
            c0 = inside[i, j]
            c1 = inside[i + 1, j]
            c2 = inside[i + 1, j + 1]
            c3 = inside[i, j + 1]
            if c0 == c1 and c1 == c2 and c2 == c3:
                continue
            e = (2 * (i * ny + j), 2 * ((i + 1) * ny + j) + 1, 2 * (i * ny + j + 1), 2 * (i * ny + j) + 1)
            cs = (c0, c1, c2, c3)
            leave = [k for k in range(4) if cs[k] and not cs[(k + 1) % 4]]
            enter = [k for k in range(4) if not cs[k] and cs[(k + 1) % 4]]
            if len(leave) == 1:
                out.append((e[leave[0]], e[enter[0]]))
            else:  # saddle: two leaving and two entering edges
                a, b = leave[0], leave[1]
                if centre_inside[i, j]:
                    # inside corners joined through the centre: each leaving edge meets the entering
                    # edge that follows it counter-clockwise
                    out.append((e[a], e[(a + 1) % 4]))
                    out.append((e[b], e[(b + 1) % 4]))
                else:
                    out.append((e[a], e[(a + 3) % 4]))
                    out.append((e[b], e[(b + 3) % 4]))
    res = np.empty((len(out), 2), np.int64)
    for k in range(len(out)):
        res[k, 0] = out[k][0]
        res[k, 1] = out[k][1]
    return res


@numba.njit(cache=True)
def _chain_loops(segs):
    """Follow segments end edge -> start edge into closed loops of edge ids."""
    n = segs.shape[0]
    order = np.argsort(segs[:, 0])
    starts = segs[order, 0]
    used = np.zeros(n, np.bool_)
    loops = []
    for s0 in range(n):
        if used[s0]:
            continue
        loop = []
        s = s0
        while not used[s]:
            used[s] = True
            loop.append(segs[s, 0])
            k = np.searchsorted(starts, segs[s, 1])
            if k >= n or starts[k] != segs[s, 1]:
                break
            s = order[k]
        loops.append(np.array(loop, np.int64))
    return loops


def _edge_nodes(edge_ids, ny):
    node = edge_ids // 2
    i, j = node // ny, node % ny
    vertical = edge_ids % 2 == 1
    return i, j, np.where(vertical, i, i + 1), np.where(vertical, j + 1, j)


def _crossings(xs, ys, drop, z, edge_ids, radius, corner, floor, bvh):
    """The point on each grid edge where the drop-cutter height reaches z, never above it; ``(k, 2)``."""
    i0, j0, i1, j1 = _edge_nodes(edge_ids, len(ys))
    pa = np.column_stack([xs[i0], ys[j0]])
    pb = np.column_stack([xs[i1], ys[j1]])
    fa = drop[i0, j0] - z
    fb = drop[i1, j1] - z
    swap = fa <= 0  # a: the inside end (f > 0), b: the outside end (f <= 0)
    pa[swap], pb[swap] = pb[swap].copy(), pa[swap].copy()
    fa[swap], fb[swap] = fb[swap].copy(), fa[swap].copy()
    return cpu.touch_points(pa, pb, fa, fb, z, radius, corner, floor, bvh, TOUCH, WALL, SECANT_ROUNDS)


def waterline(mesh: Mesh, tools, tool_name: str, params: WaterlineParams, progress=None):
    """Run the operation; returns ``(toolpath, summary, loops)`` with ``loops`` a list of
    ``(z, (k, 3) array)`` from the top level down."""
    params.check()
    say = progress or (lambda stage: None)
    index, tool = pick_tool(tools, tool_name)
    R, rc = tool.radius, tool.corner_radius
    bounds = mesh.bounds
    levels = z_levels(bounds[0, 2], bounds[1, 2], params.step_down)
    if len(levels) == 0:
        raise InputError(f"--step-down {params.step_down:g} is larger than the part height "
                         f"{bounds[1, 2] - bounds[0, 2]:g} mm: no level")
    lo = bounds[0, :2] - R - 2 * params.sample
    hi = bounds[1, :2] + R + 2 * params.sample
    nx = int(math.ceil((hi[0] - lo[0]) / params.sample)) + 1
    ny = int(math.ceil((hi[1] - lo[1]) / params.sample)) + 1
    if nx * ny > 50_000_000:
        raise InputError(f"{nx} x {ny} grid points: use a larger --sample")
    seconds = {}
    t_all = time.perf_counter()
    say("index")
    t = time.perf_counter()
    bvh = build_bvh(mesh.vertices, mesh.faces)
    seconds["index"] = time.perf_counter() - t
    say("drop-cutter grid")
    t = time.perf_counter()
    xs = lo[0] + (hi[0] - lo[0]) * np.arange(nx) / (nx - 1)
    ys = lo[1] + (hi[1] - lo[1]) * np.arange(ny) / (ny - 1)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    floor = float(bounds[0, 2]) - 1.0
    drop = cpu.drop_cutter(np.column_stack([gx.ravel(), gy.ravel()]), R, rc, floor, bvh.arrays)[0].reshape(nx, ny)
    cx = 0.5 * (xs[:-1] + xs[1:])
    cy = 0.5 * (ys[:-1] + ys[1:])
    seconds["grid"] = time.perf_counter() - t
    say("levels")
    t = time.perf_counter()
    loops = []
    centre_cache = {}
    for z in levels:
        inside = drop > z
        mixed = (inside[:-1, :-1] != inside[1:, :-1]) | (inside[:-1, :-1] != inside[:-1, 1:]) | \
            (inside[:-1, :-1] != inside[1:, 1:])
        saddle = mixed & (inside[:-1, :-1] == inside[1:, 1:]) & (inside[1:, :-1] == inside[:-1, 1:]) & \
            (inside[:-1, :-1] != inside[1:, :-1])
        centre_inside = np.zeros_like(mixed)
        si, sj = np.nonzero(saddle)
        if len(si):
            missing = [(a, b) for a, b in zip(si, sj) if (a, b) not in centre_cache]
            if missing:
                pts = np.array([[cx[a], cy[b]] for a, b in missing])
                zc = cpu.drop_cutter(pts, R, rc, floor, bvh.arrays)[0]
                centre_cache.update(zip(missing, zc))
            centre_inside[si, sj] = np.array([centre_cache[(a, b)] for a, b in zip(si, sj)]) > z
        segs = _cell_segments(inside, centre_inside)
        if len(segs) == 0:
            continue
        edge_loops = _chain_loops(segs)
        all_edges = np.concatenate(edge_loops)
        pts = _crossings(xs, ys, drop, z, all_edges, R, rc, floor, bvh.arrays)
        start = 0
        for el in edge_loops:
            p = pts[start:start + len(el)]
            start += len(el)
            if len(p) < 3:
                continue
            loop = np.column_stack([p, np.full(len(p), z)])[::-1]  # clockwise: climb milling
            loop = np.vstack([loop, loop[:1]])
            loops.append((float(z), simplify_polyline(loop, 0.5 * params.tol)))
    seconds["levels"] = time.perf_counter() - t
    safe_z = float(bounds[1, 2] + SAFE_ABOVE)
    tp = link_passes([p for _, p in loops], index, safe_z)
    say("verify")
    t = time.perf_counter()
    report = verify_toolpath(bvh, tp, tools, params.tol, params.sample)
    report.pop("problem_moves")
    seconds["verify"] = time.perf_counter() - t
    seconds["total"] = time.perf_counter() - t_all
    summary = {
        "operation": "waterline",
        "tool": tool.name,
        "step_down": params.step_down,
        "sample": params.sample,
        "tolerance": params.tol,
        "safe_z": safe_z,
        "levels": int(len(levels)),
        "loops": len(loops),
        "grid": [nx, ny],
        "cl_points": int(sum(len(p) for _, p in loops)),
        "moves": int(len(tp)),
        "cutting_length": tp.cutting_length(),
        "verify": report,
        "seconds": {k: round(v, 4) for k, v in seconds.items()},
    }
    return tp, summary, loops
