"""Operations on triple-dexel models: build one from a part (``meshmill dexel``), and simulate
what a tool path cuts from a stock and compare it with the design (``meshmill simulate``)."""
from __future__ import annotations

import os
import time

import numpy as np

from ..errors import InputError
from ..params import OUTPUTS
from ..simulation import partition
from ..simulation.dexel import DexelModel, dexelize, lattice, uneven_lines_warning


def dexel_model(mesh, step, index="bvh", partitions=1, init="k-means++", minibatch=False, k_max=27,
                progress=None, device="cpu", cluster=None) -> tuple[DexelModel, dict]:
    """Dexel model of a part and its summary; ``partitions`` is a count or ``"auto"`` (the
    K-optimal helper over 1..k_max, whose table goes into the summary)."""
    summary = {}
    if partitions == "auto":
        lo, n = lattice(mesh.bounds, step)
        tris = mesh.vertices[mesh.faces].reshape(-1, 9)
        k, rows = partition.k_optimal(tris, lo, step, n, k_max, index, init, minibatch)
        summary["k_optimal"] = {"K": k, "table": rows}
    else:
        k = int(partitions)
    model = dexelize(mesh, step, index, k, init, minibatch, progress=progress, device=device, cluster=cluster)
    model.name = os.path.basename(mesh.source or "part")
    summary["operation"] = "dexel"
    summary.update(model.summary())
    summary["index"] = model.info
    summary["warnings"] = uneven_lines_warning(model.info.get("uneven_lines"), mesh)
    return model, summary


def _stock_bounds(design, stock) -> np.ndarray:
    """``(2, 3)``: the box of ``stock`` (a :class:`~meshmill.simulation.stock.Stock`) around ``design``."""
    if stock.kind == "dexels":
        return stock.state.bounds
    if stock.kind == "offset":
        return design.bounds + np.array([[-1.0], [1.0]]) * stock.allowance
    return stock.solid(design).bounds


def simulate(design, toolpath, tools, step, stock=None, tolerance=0.01, mode="sweep", progress=None, device="cpu",
             outputs=OUTPUTS, cluster=None, material=None, machine=None):
    """Cut ``toolpath`` from ``stock`` (a :class:`~meshmill.simulation.stock.Stock`: described, or
    in-process on a lattice of ``step`` mm) and measure the result against ``design``.

    Returns ``(deviation dict, summary dict, the stock after it, (vertices, faces) of the machined
    mesh, {"points": (k, 3), "e": (k,)} the dexel ends and their signed deviations, mm)``; the
    mesh and the ends only when ``outputs`` names ``"mesh"`` and ``"deviation"`` (else None).
    ``device``: ``"cpu"`` or ``"cuda"`` for dexel casting, cutting and distances; ``cluster``: a
    Client the cutting is split on (the whole on a cluster: :func:`meshmill.ops.simulate_blocks.simulate_on`).
    The load of every move is measured as it is cut (mode sweep): the summary's ``load``
    (:func:`~meshmill.simulation.load.load_summary`, in the workpiece ``material`` with the tools'
    cutting data, the spindle of ``machine`` and its nominal feed where none is given) and its
    overloads among the ``errors``; the :class:`~meshmill.simulation.load.MoveLoad` is the sixth
    result (None in mode points)."""
    from ..simulation.stock import Stock
    from ..tools.cutting import workpiece

    say = progress or (lambda _: None)
    t0 = time.perf_counter()
    stock = Stock.of(stock, "box")
    bounds, warnings = prepare(design, toolpath, tools, step, stock, tolerance, outputs)
    workpiece(material, tools)  # a material no table knows is refused before the work
    if stock.kind != "dexels":
        stock = stock.dexels(design, step, bounds, device)
        design_model = stock.state.design
        warnings += uneven_lines_warning(design_model.info.get("uneven_lines"), design)
        say(f"design: {sum(design_model.dexel_count(a) for a in range(3)):,} dexels")
    build_s = time.perf_counter() - t0
    after, cuts = stock.cut(toolpath, tools, tolerance, mode, device, cluster, say, load=True)
    load, load_summary = measure_load(toolpath, tools, cuts.pop("removed", None), material, machine, step)
    machined = after.model
    t2 = time.perf_counter()
    mesh = after.surface() if "mesh" in outputs else None
    mesh_s = time.perf_counter() - t2
    t1 = time.perf_counter()
    deviation, volumes, more, (pts, e) = after.measure(tolerance, "deviation" in outputs, device, say)
    deviation_s = time.perf_counter() - t1
    summary = simulate_summary(mode, step, machined.summary(), len(toolpath), cuts, volumes, deviation, mesh,
                               warnings + more, {"models": round(build_s, 4), "cut": cuts["seconds"],
                                                 "deviation": round(deviation_s, 4), "mesh": round(mesh_s, 4),
                                                 "total": round(time.perf_counter() - t0, 4)})
    add_load(summary, load_summary)
    return (deviation, summary, after, mesh[:2] if mesh else None,
            {"points": pts, "e": e} if "deviation" in outputs else None, load)


def add_load(summary: dict, load_summary: dict | None) -> None:
    """Put a :func:`measure_load` summary in a simulation's ``summary``: its ``load``, its
    overloads among the ``errors``, its warnings among the ``warnings``."""
    if load_summary is not None:
        summary["load"] = load_summary
        summary["errors"] = summary["errors"] + load_summary["errors"]
        summary["warnings"] = summary["warnings"] + load_summary.pop("warnings")


def measure_load(toolpath, tools, removed, material=None, machine=None, step=0.5):
    """``(MoveLoad, summary)`` of a path from what each move removed (``removed``, a
    :class:`~meshmill.simulation.load.RemovedByMove`; None: not measured, ``(None, None)``), in
    the workpiece ``material`` (a name) on ``machine`` (its spindle and nominal feed; None: no
    spindle limits, the generic 3-axis machine's feed where neither path nor tool gives one)."""
    from ..machine.config import load_machine
    from ..simulation.load import load_summary, move_loads
    from ..tools.cutting import conditions, workpiece

    if removed is None:
        return None, None
    kind, warnings = workpiece(material, tools)
    spindle = machine.spindle if machine is not None else None
    nominal = (machine or load_machine("generic-3axis")).motion.feed * 60.0
    cond = conditions(tools, material, spindle)
    load = move_loads(toolpath, removed, tools, cond, kind, nominal, step)
    summary = load_summary(toolpath, tools, cond, spindle, kind, load)
    summary["warnings"] = warnings
    return load, summary


def prepare(design, toolpath, tools, step, stock, tolerance, outputs) -> tuple[np.ndarray, list]:
    """``(bounds (2, 3), warnings)`` of :func:`simulate`'s arguments: the lattice's box (the
    stock's and the design's) and what the user should know of the tools and the step; refuses a
    path that never reaches the stock, a stock cut on another lattice, an empty path."""
    if not len(toolpath):
        raise InputError("the tool path has no moves", "toolpath")
    if stock.kind == "dexels" and abs(stock.model.step - step) > 1e-12 * step:
        raise InputError(f"step {step:g} mm differs from the in-process stock's {stock.model.step:g} mm", "step")
    sb = _stock_bounds(design, stock)
    bounds = np.array([np.minimum(sb[0], design.bounds[0]), np.maximum(sb[1], design.bounds[1])])
    used = sorted(set(int(t) for t in toolpath.tool))
    reach = max(tools[t].radius + tools[t].flute_length for t in used)
    path_lo, path_hi = toolpath.tip.min(axis=0) - reach, toolpath.tip.max(axis=0) + reach
    if (path_hi < sb[0]).any() or (path_lo > sb[1]).any():
        raise InputError(f"the tool path (box {np.round(path_lo, 3).tolist()} .. {np.round(path_hi, 3).tolist()} "
                         f"with the tool) never reaches the stock (box {np.round(sb[0], 3).tolist()} .. "
                         f"{np.round(sb[1], 3).tolist()}): check the units and the origin")
    warnings = []
    short = [tools[t].name for t in used if tools[t].flute_length < 2 * (tools[t].radius if tools[t].type == "ball"
                                                                         else tools[t].corner_radius)]
    if short:
        warnings.append(f"tool(s) {', '.join(short)}: flute_length below twice the corner radius; the cutter is "
                        "modelled as its whole rounded end, up to twice the corner radius")
    smallest = min(tools[t].radius for t in used)
    if step > smallest:
        warnings.append(f"step {step:g} mm is coarser than the smallest tool radius ({smallest:g} mm): "
                        "scallops and small features are not resolved")
    return bounds, warnings


def simulate_summary(mode, step, lattice, moves, cuts, volumes, deviation, mesh, warnings, seconds) -> dict:
    """``summary.json`` of a simulation: the machined model's ``lattice`` summary, the ``moves``
    count, what :func:`cut_path` found (``cuts``), the ``volumes`` and ``deviation`` of
    :func:`measure`, the machined ``mesh`` ``(vertices, faces, stride)`` (None: not made),
    ``warnings`` and ``seconds``."""
    return {
        "operation": "simulate",
        "mode": mode,
        "step": step,
        "lattice": lattice,
        "moves": moves,
        **{k: v for k, v in cuts.items() if k != "seconds"},
        "volumes_mm3": volumes,
        "deviation": deviation,
        "machined_mesh": None if mesh is None else {"vertices": int(len(mesh[0])), "triangles": int(len(mesh[1])),
                                                    "lattice_stride": int(mesh[2])},
        "warnings": warnings,
        "seconds": seconds,
    }
