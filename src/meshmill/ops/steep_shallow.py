"""3-axis steep-and-shallow finishing to a scallop limit (ball or bull-nose).

Z levels dz apart lie dz / sin(slope) apart on the surface, and parallel passes s apart up to
s / cos(slope): each serves one kind of ground. The steep ground (steeper than ``threshold`` less
:data:`SLOPE_MARGIN`) is cut by waterline loops whose levels are as far apart as the scallop
limit allows at that slope, the shallow ground (up to ``threshold`` plus the margin) by a
raster whose stepover is what the limit allows at that slope; each keeps the pieces of its passes
on its own ground (the contact normal of the tool at every ``sample``,
:mod:`meshmill.pathing.slope`) widened by ``overlap`` mm along the pass, so the two overlap by
the margin's band of slopes and no seam is left. Levels and stepover are the limit's on the
ground each cuts, not on the whole part's shallowest slope. Both kinds of passes are linked and
verified as one path, each kind in an order that keeps the links short and passes closer than
:data:`JOIN` tool diameters joined by a feed along the part (verification splits them again where
that would gouge).

With ``rest`` only the pieces that remove more than that of the stock are cut (rest finishing,
``type = "rest-finish"`` in a job). From an in-process stock (triple dexels) that is measured,
not guessed from a reference tool: the stock's dexel ends that stand more than ``rest`` above the
design (their exact distance to it, :meth:`~meshmill.simulation.stock.Stock.measure`) are what
is left (where a vertical tool could touch it), and the passes are kept where the tool touches
the design within a lattice step of one of them (:func:`left_points`); from a mesh or box stock, by the depth below its surface
(:mod:`meshmill.pathing.rest`).
"""
from __future__ import annotations

import time

import numpy as np
from scipy.spatial import cKDTree

from ..errors import InputError, NothingToCut
from ..geometry.mesh import Mesh
from ..kernels.backend import solid_kernels
from ..params import RasterParams, SteepShallowParams, WaterlineParams
from ..pathing.dropcutter import ToolDrop, pick_tool, stock_for, verified_path
from ..pathing.pencil import pencil_passes
from ..pathing.slope import scallop_radius, slope_pieces
from ..pathing.verify import DEFAULT_STEP
from ..progress import StageClock
from ..toolpath.linking import joined_passes, shortest_order
from .left import design_feet
from .raster import raster_passes
from .waterline import cut_pieces, drop_grid, level_loops, waterline_setup

SLOPE_MARGIN = 5.0  # deg: the band of slopes both kinds of passes cut, about the threshold
SHADOW_NZ = 0.05  # what is left on ground facing down more than this (normal's z) no vertical tool touches
JOIN = 2.0  # tool diameters: passes whose end and next start are closer are joined by a feed along the part


def left_points(stock, kern, depth: float, tolerance: float, tool, device="cpu"):
    """``((q, 3) points, reach)``: the points of the design under the dexel ends of the in-process
    ``stock`` (:class:`~meshmill.simulation.stock.Stock` of kind dexels) that stand more than
    ``depth`` mm above it (:func:`~meshmill.ops.left.design_feet`, onto the design of ``kern``)
    and that a vertical ``tool`` could touch (not facing down, nor so low on a wall that its tip
    would go below the part's bottom), and how near a tool contact must come to one to cut it
    (the lattice step: every piece of surface has an end of some direction within it)."""
    _, _, _, (points, e) = stock.measure(tolerance, samples=True, device=device)
    more = e > depth
    feet, normal = design_feet(points[more], e[more], kern, near=0.0, normals=True)
    r = tool.corner_radius
    floor = float(kern.bvh.node_lo[0, 2])
    touchable = (normal[:, 2] >= -SHADOW_NZ) & (feet[:, 2] + r * normal[:, 2] - r >= floor - tolerance)
    return feet[touchable], float(stock.model.step)


def steep_shallow(mesh: Mesh, tools, tool_name: str, params: SteepShallowParams, progress=None, device: str = "cpu",
                  cluster=None):
    """Run the operation on ``device``; returns ``(toolpath, summary)``. ``params.stock``: the
    material it starts from (:func:`~meshmill.pathing.dropcutter.stock_for`), which rapids keep
    ``params.clearance`` from and ``params.rest`` depths are measured from; ``cluster``: a
    ``distributed.Client`` the levels and the passes are found on in pieces (the same path)."""
    from dataclasses import replace

    from ..simulation.stock import Stock

    index, tool = pick_tool(tools, tool_name)
    if scallop_radius(tool) is None:
        raise InputError(f"tool '{tool.name}' is flat: steep-shallow keeps a scallop limit, which needs a ball or "
                         "bull-nose", "tool")
    clock = StageClock(progress)
    t_all = time.perf_counter()
    with clock("index"):
        kern = solid_kernels(mesh, device)  # the solid the part bounds, on the device from here on
    near, left = None, None
    if params.rest is not None and Stock.of(params.stock, "offset").kind == "dexels":  # what is left, measured
        with clock("what is left on the part", "left"):
            points, reach = left_points(params.stock, kern, params.rest, params.tolerance, tool, device)
        left = {"min_depth": params.rest, "points_left": int(len(points)), "reach": reach}
        if not len(points):
            raise NothingToCut(f"nothing to cut: the stock stands nowhere more than rest {params.rest:g} mm above the "
                               "part", "rest")
        near = (cKDTree(points), reach)
        params = replace(params, rest=None)
    params, rapid_stock, grow, safe_z, rest_kern = stock_for(mesh, params, device)
    common = dict(tool=tool_name, sample=params.sample, tolerance=params.tolerance, clearance=params.clearance,
                  allowance=params.allowance, rest=params.rest, overlap=params.overlap)
    steep_from = max(0.0, params.threshold - SLOPE_MARGIN)
    shallow_to = min(90.0, params.threshold + SLOPE_MARGIN)
    wp = WaterlineParams(scallop=params.scallop, min_slope=steep_from, **common)
    steep, levels, steep_report, step_down = [], 0, None, None
    with clock("steep: levels", "steep"):
        try:
            setup = waterline_setup(mesh, tools, tool_name, wp, device, stock=(rapid_stock, grow, safe_z, rest_kern))
            step_down, levels = setup.params.step_down, len(setup.levels)
            drop, grid = drop_grid(mesh, kern, setup)
            loops, _ = level_loops(setup, drop, grid, mesh, device, cluster, clock.say)
            loops, _, steep_report = cut_pieces(loops, setup, drop, near)
            steep = [p for _, p in loops]
        except NothingToCut:  # no level in the part's height
            pass
    pencil, lines = [], 0
    if params.pencil:
        with clock("pencil: corners", "pencil"):
            drop = ToolDrop(tool, kern, float(mesh.bounds[0, 2]) - 1.0, grow=params.allowance, body_grow=grow)
            reach = tool.radius + params.allowance
            found = pencil_passes(drop, mesh.bounds[0, :2] - reach, mesh.bounds[1, :2] + reach,
                                  min(params.sample, 0.5 * tool.radius), params.sample, tool.diameter)
            lines = len(found)
            pencil = slope_pieces(found, drop, tool, None, None, params.overlap, params.sample, near=near)[0] \
                if near is not None else found
    rp = RasterParams(scallop=params.scallop, max_slope=shallow_to, angle=params.angle, **common)
    shallow, built = [], {}
    with clock("shallow: parallel passes", "shallow"):
        try:
            shallow, built = raster_passes(mesh, kern, tool, rp, grow, rest_kern, clock.say, device, cluster, near)
        except NothingToCut:  # no shallow ground (or none in the stock's material)
            pass
    if not steep and not shallow and not pencil:
        depth = params.rest if params.rest is not None else (left or {}).get("min_depth")
        why = f" that removes more than rest {depth:g} mm of the stock" if depth is not None else ""
        raise NothingToCut(f"nothing to cut: no pass{why} on the part's ground", "rest" if depth is not None else ())
    # each kind in an order that keeps links short, passes close to each other joined along the part
    passes = joined_passes(shortest_order(pencil, closed=[np.array_equal(p[0], p[-1]) for p in pencil]),
                           JOIN * tool.diameter)
    passes += joined_passes(shortest_order(steep, start=passes[-1][-1] if passes else None,
                                           closed=[np.array_equal(p[0], p[-1]) for p in steep]), JOIN * tool.diameter)
    passes += joined_passes(shortest_order(shallow, start=passes[-1][-1] if passes else None), JOIN * tool.diameter)
    with clock("verify"):
        tp, report, kept = verified_path(passes, index, tools, kern, safe_z, params.tolerance, DEFAULT_STEP,
                                         rapid_stock, clock.say)
    clock.seconds["total"] = time.perf_counter() - t_all
    summary = {
        "operation": "steep-shallow",
        "tool": tool.name,
        "scallop": params.scallop,
        "threshold": params.threshold,
        "overlap": params.overlap,
        "steep": {"min_slope": steep_from, "step_down": step_down, "levels": levels, "passes": len(steep),
                  **({"slopes": steep_report} if steep_report else {})},
        "pencil": {"lines": lines, "passes": len(pencil)} if params.pencil else None,
        "shallow": {"max_slope": shallow_to, "angle": params.angle, "passes": len(shallow),
                    **{k: built[k] for k in ("stepover", "stepover_used", "lines", "slopes") if k in built}},
        "sample": params.sample,
        "tolerance": params.tolerance,
        "allowance": params.allowance,
        "safe_z": safe_z,
        "stock": rapid_stock.summary(),
        **({"rest": {"min_depth": params.rest}} if params.rest is not None else {}),
        **({"rest": left} if left is not None else {}),
        "cl_points": int(sum(len(p) for p in kept)),
        "moves_left_out": report["moves_left_out"],
        "moves": int(len(tp)),
        "cutting_length": tp.cutting_length(),
        "verify": report,
        "seconds": {k: round(v, 4) for k, v in clock.seconds.items()},
    }
    return tp, summary
