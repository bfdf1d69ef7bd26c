"""Triangle and vertex parameters, visibility and accessibility of a part (seed 001:
``meshmill analyze``)."""
from __future__ import annotations

import time

import numpy as np

from ..geometry import analysis
from ..kernels.backend import MeshKernels
from ..kernels.bvh import build_bvh


def analyze(part, direction, weighting="area", theta_step=None, delta_step=10.0, device="cpu", progress=None):
    """``(summary, arrays)``: per triangle and vertex the parameters and the visibility and
    accessibility flags along ``direction (3,)``; with ``theta_step`` (degrees) also the share of
    the area each direction of the hemisphere reaches (``delta_step`` around)."""
    say = progress or (lambda stage: None)
    t0 = time.perf_counter()
    say("visibility")
    kern = MeshKernels(build_bvh(part.vertices, part.faces), device)
    tri = analysis.triangle_parameters(part)
    normals = analysis.vertex_normals(part, weighting)
    flags = analysis.visibility(part, direction, weighting, kern)
    seconds = {"visibility": round(time.perf_counter() - t0, 4)}
    summary = {
        "direction": analysis.unit_direction(direction).round(9).tolist(),
        "weighting": weighting,
        "area_mm2": {"total": float(tri["area"].sum()), "min": float(tri["area"].min()), "max": float(tri["area"].max())},
        "boundary_edges": int((tri["neighbours"] < 0).sum()),
        **{k: int(v.sum()) for k, v in flags.items()},
    }
    arrays = {"vertex_normals": normals, **tri, **flags}
    if theta_step is not None:
        say("accessibility map")
        t1 = time.perf_counter()
        dirs = analysis.hemisphere(theta_step, delta_step)
        share, reached = analysis.accessibility_map(part, dirs, kern)
        seconds["map"] = round(time.perf_counter() - t1, 4)
        summary["map"] = {"directions": len(dirs), "best_direction": dirs[int(np.argmax(share))].round(9).tolist(),
                          "best_share": float(share.max()), "never_reached_triangles": int((reached == 0).sum())}
        arrays.update(map_directions=dirs, map_share=share, triangles_reached=reached)
    summary["seconds"] = seconds
    return summary, arrays
