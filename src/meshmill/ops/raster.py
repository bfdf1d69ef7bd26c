"""3-axis parallel-plane (raster, zigzag) finishing with a flat, ball or bull-nose cutter.

Lines at ``angle`` from X cover the part's box widened by the cutter radius, ``stepover`` apart
(or the stepover that leaves a scallop of ``scallop`` mm: sod = 2·sqrt(2·h·R_eff - h²), seed 002,
times cos(max_slope) where the passes keep to ground at most that steep).
Every line, and the link to the next one, is dropped onto the mesh with the exact drop-cutter
(cutter, shank and holder: :class:`meshmill.pathing.dropcutter.ToolDrop`) at
``sample`` spacing, refined where the surface leaves the chord by more than half the tolerance,
and simplified where points are collinear within half the tolerance. The tool tip never goes
below the part's lowest point. The path is verified like any other.
"""
from __future__ import annotations

import math
import time

import numpy as np

from .. import memory
from ..errors import InputError, NothingToCut
from ..kernels.backend import solid_kernels
from ..geometry.mesh import Mesh
from ..toolpath.linking import simplify_polyline
from ..pathing.slope import raster_stepover, slope_pieces
from ..params import RasterParams
from ..pathing.dropcutter import ToolDrop, drop_refined_on, drop_refined_pieces, pick_tool, stock_for, verified_path
from ..pathing.rest import REST_JOIN, REST_LEAD, in_material, material_runs
from ..pathing.verify import DEFAULT_STEP

CL_BYTES = 200  # one dropped point of a pass, its contact and its share of the tool path and verification


def effective_radius(tool) -> float:
    """Radius that sets the scallop between neighbouring passes (seed 002): R for a ball; the corner
    radius r for a bull-nose, its worst case (passes across the slope)."""
    if tool.type == "ball":
        return tool.radius
    if tool.type == "bull":
        return tool.corner_radius
    raise InputError(f"tool '{tool.name}' is flat: its scallop height is not defined, give stepover instead of scallop",
                     ("stepover", "scallop"))


def raster_lines(bounds, radius, stepover, angle_deg, sample):
    """XY points of the zigzag: a list of ``(k, 2)`` arrays, lines and links alternating."""
    a = math.radians(angle_deg)
    d = np.array([math.cos(a), math.sin(a)])
    n = np.array([-math.sin(a), math.cos(a)])
    lo = bounds[0, :2] - radius - sample
    hi = bounds[1, :2] + radius + sample
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    s0, s1 = (corners @ d).min(), (corners @ d).max()
    t0, t1 = (corners @ n).min(), (corners @ n).max()
    n_lines = int(math.ceil((t1 - t0) / stepover)) + 1
    offsets = t0 + (t1 - t0) * np.arange(n_lines) / max(n_lines - 1, 1)
    n_pts = int(math.ceil((s1 - s0) / sample)) + 1
    s = s0 + (s1 - s0) * np.arange(n_pts) / (n_pts - 1)
    pieces = []
    for k, t in enumerate(offsets):
        line = s[:, None] * d + t * n
        if k % 2:
            line = line[::-1]
        if pieces:
            a_end, b_start = pieces[-1][-1], line[0]
            m = max(2, int(math.ceil(np.linalg.norm(b_start - a_end) / sample)) + 1)
            f = np.linspace(0.0, 1.0, m)[1:-1, None]
            pieces.append(a_end + f * (b_start - a_end))
        pieces.append(line)
    return pieces, n_lines, float((t1 - t0) / max(n_lines - 1, 1))


def raster_passes(mesh: Mesh, kern, tool, params: RasterParams, grow: float, rest_kern, say, device="cpu",
                  cluster=None, near=None):
    """``(passes, report)``: the zigzag over ``mesh`` (bound to ``kern``) dropped with ``tool``
    (shank and holder grown by ``grow``), cut into the pieces that remove more than ``params.rest``
    of the stock of ``rest_kern`` and that lie on ground within ``params.min_slope``-``max_slope``,
    simplified within half the tolerance: ``(k, 3)`` tips each, not yet verified; ``near``: only
    where the tool touches near those points (:func:`~meshmill.pathing.slope.slope_pieces`).
    ``report``: the stepover, the lines, the points dropped and kept, the rest and slope reports."""
    stepover = checked_stepover(mesh, tool, params)
    bounds = mesh.bounds
    say("drop-cutter")
    pieces, n_lines, spacing = raster_lines(bounds, tool.radius, stepover, params.angle, params.sample)
    xy = np.concatenate(pieces)
    drop = ToolDrop(tool, kern, float(bounds[0, 2]), grow=params.allowance, body_grow=grow)
    if cluster is not None:  # pieces of the passes dropped on the workers: the same tips
        shared = dict(part=mesh, tool=tool, floor=float(bounds[0, 2]), grow=params.allowance,
                      body_grow=grow, chord_tol=0.5 * params.tolerance, min_step=params.sample / 64,
                      device=device)
        tips = drop_refined_on(cluster, xy, shared, say)
    else:
        tips = drop_refined_pieces(xy, drop, 0.5 * params.tolerance, params.sample / 64, say)
    dropped = len(tips)
    passes, rest, slopes = [tips], None, None
    if params.rest is not None:
        inside = in_material(tips, tool, rest_kern, params.rest)
        passes = material_runs(tips, inside, REST_LEAD * params.sample, REST_JOIN * tool.diameter)
        kept = sum(len(p) for p in passes)
        rest = {"min_depth": params.rest, "points_in_material": int(inside.sum()), "points_left_out": int(dropped - kept),
                "runs": len(passes)}
        if not passes:
            raise NothingToCut(f"nothing to cut: no piece of the passes removes more than rest {params.rest:g} mm of the "
                               "stock", "rest")
    if params.min_slope is not None or params.max_slope is not None or near is not None:
        passes, slopes = slope_pieces(passes, drop, tool, params.min_slope, params.max_slope, params.overlap,
                                      params.sample, near=near)
        if not passes:
            raise NothingToCut(f"nothing to cut: no piece of the passes lies on ground "
                               f"{_slopes_text(params.min_slope, params.max_slope)}", ("min_slope", "max_slope"))
    passes = [simplify_polyline(p, 0.5 * params.tolerance) for p in passes]
    report = {"stepover": stepover, "stepover_used": spacing, "lines": n_lines, "cl_points_dropped": int(dropped),
              **({"rest": rest} if rest is not None else {}), **({"slopes": slopes} if slopes is not None else {})}
    return passes, report


def checked_stepover(mesh: Mesh, tool, params: RasterParams) -> float:
    """The distance between passes (given, or from the scallop on ground up to ``max_slope``),
    refused where its points would not fit in memory."""
    stepover = params.stepover if params.stepover is not None else raster_stepover(params.scallop, tool,
                                                                                   params.max_slope)
    bounds = mesh.bounds
    extent = bounds[1, :2] - bounds[0, :2] + 2 * tool.radius
    estimate = (extent.max() * 1.5 / stepover + 1) * (extent.max() * 1.5 / params.sample + 1)
    memory.check(CL_BYTES * estimate, f"about {estimate:.3g} CL points", "use a larger stepover or sample",
                 ("stepover", "sample"))
    return stepover


def _slopes_text(lo, hi) -> str:
    """"between 10 and 45 deg", "at least 45 deg steep", ..."""
    if lo is None and hi is None:
        return "near what is left"
    if lo is not None and hi is not None:
        return f"between {lo:g} and {hi:g} deg steep"
    return f"at least {lo:g} deg steep" if lo is not None else f"at most {hi:g} deg steep"


def raster(mesh: Mesh, tools, tool_name: str, params: RasterParams, progress=None, device: str = "cpu", cluster=None):
    """Run the operation on ``device`` (``"cpu"`` or ``"cuda"``); returns ``(toolpath, summary)``.
    ``params.stock``: the material it starts from (:func:`~meshmill.pathing.dropcutter.stock_for`),
    which rapids keep ``params.clearance`` from; with
    ``params.rest`` only the pieces of the passes that remove more than that depth of it are cut
    (:mod:`meshmill.pathing.rest`), with a lead of 1.5 samples on each side; with
    ``params.min_slope``/``max_slope`` only those on ground that steep (:mod:`meshmill.pathing.slope`);
    ``cluster``: a ``distributed.Client`` the passes are dropped on in pieces (the same path); the
    depths are measured from the stock's surface."""
    params, rapid_stock, grow, safe_z, rest_kern = stock_for(mesh, params, device)
    say = progress or (lambda stage: None)
    index, tool = pick_tool(tools, tool_name)
    seconds = {}
    t_all = time.perf_counter()
    if params.scallop is not None:
        effective_radius(tool)  # a flat end mill has no scallop: refused
    checked_stepover(mesh, tool, params)  # before anything is computed
    say("index")
    t = time.perf_counter()
    kern = solid_kernels(mesh, device)  # the solid the part bounds, on the device from here on
    seconds["index"] = time.perf_counter() - t
    t = time.perf_counter()
    passes, built = raster_passes(mesh, kern, tool, params, grow, rest_kern, say, device, cluster)
    seconds["drop"] = time.perf_counter() - t
    say("verify")
    t = time.perf_counter()
    tp, report, passes = verified_path(passes, index, tools, kern, safe_z, params.tolerance, DEFAULT_STEP, rapid_stock,
                                       say)
    seconds["verify"] = time.perf_counter() - t
    seconds["total"] = time.perf_counter() - t_all
    summary = {
        "operation": "raster",
        "tool": tool.name,
        "angle": params.angle,
        "stepover": built["stepover"],
        "stepover_used": built["stepover_used"],
        "scallop": params.scallop,
        "sample": params.sample,
        "tolerance": params.tolerance,
        "allowance": params.allowance,
        "safe_z": safe_z,
        "stock": rapid_stock.summary(),
        "lines": built["lines"],
        "cl_points_dropped": built["cl_points_dropped"],
        "cl_points": int(sum(len(p) for p in passes)),
        "moves_left_out": report["moves_left_out"],
        "moves": int(len(tp)),
        "cutting_length": tp.cutting_length(),
        **{k: built[k] for k in ("rest", "slopes") if k in built},
        "verify": report,
        "seconds": {k: round(v, 4) for k, v in seconds.items()},
    }
    return tp, summary
