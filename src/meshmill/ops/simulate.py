"""Operations on triple-dexel models: build one from a part (``meshmill dexel``), and simulate
what a tool path cuts from a stock and compare it with the design (``meshmill simulate``)."""
from __future__ import annotations

import time

import numpy as np

from ..errors import InputError
from ..geometry import shapes
from ..simulation import cut as cutting
from ..simulation import partition
from ..simulation.deviation import deviations, difference_volume, surface_parameters, uncovered_ends, uncut_ends
from ..simulation.dexel import MAX_PARTITIONS, DexelModel, dexelize, lattice, material_mesh, uneven_lines_warning
from ..simulation.surface import machined_mesh

DEVIATION_KEYS = ("Sa", "Sq", "Sp", "Sv", "Sz", "gouge_max", "excess_max", "within_tolerance",
                  "removed_volume", "remaining_volume")


def dexel_model(mesh, step, index="bvh", partitions="1", init="k-means++", minibatch=False, k_max=27,
                progress=None, device="cpu", cluster=None) -> tuple[DexelModel, dict]:
    """Dexel model of a part and its summary; ``partitions`` is a count or ``"auto"`` (the
    K-optimal helper over 1..k_max, whose table goes into the summary)."""
    summary = {}
    if partitions == "auto":
        if index == "bvh":
            raise InputError("--partitions auto needs --index cells or kmeans")
        if not 1 <= k_max <= MAX_PARTITIONS:
            raise InputError(f"--kmax must be a whole number from 1 to {MAX_PARTITIONS}, got {k_max}")
        lo, n = lattice(mesh.bounds, step)
        tris = mesh.vertices[mesh.faces].reshape(-1, 9)
        k, rows = partition.k_optimal(tris, lo, step, n, k_max, index, init, minibatch)
        summary["k_optimal"] = {"K": k, "table": rows}
    else:
        try:
            k = int(partitions)
        except ValueError:
            raise InputError(f"--partitions must be a whole number or 'auto', got '{partitions}'") from None
        if k < 1:
            raise InputError(f"--partitions must be at least 1, got {k}")
    model = dexelize(mesh, step, index, k, init, minibatch, progress=progress, device=device, cluster=cluster)
    summary["operation"] = "dexel"
    summary.update(model.summary())
    summary["index"] = model.info
    summary["warnings"] = uneven_lines_warning(model)
    return model, summary


def _stock_bounds(design, stock, allowance):
    if allowance is not None:
        return design.bounds + np.array([[-1.0], [1.0]]) * allowance
    if stock == "box":
        return design.bounds
    return stock.bounds


def simulate(design, toolpath, tools, step, stock="box", allowance=None, tolerance=0.01, mode="sweep",
             progress=None, device="cpu", cluster=None):
    """Cut ``toolpath`` from the stock (``"box"``: the design's box; a Mesh; or the design with
    ``allowance`` mm on both ends of every dexel) and measure the result against ``design``.

    Returns ``(deviation dict, summary dict, machined DexelModel, (vertices, faces) of the machined
    mesh, {"points": (k, 3), "e": (k,)} the dexel ends and their signed deviations, mm)``. ``device``: ``"cpu"`` or ``"cuda"`` for dexel casting, cutting and distances;
    ``cluster``: a ``distributed.Client`` the dexel lines are cast and cut on (the measures run
    here)."""
    say = progress or (lambda _: None)
    t0 = time.perf_counter()
    if allowance is not None and not (np.isfinite(allowance) and allowance >= 0):
        raise InputError(f"--allowance must be a number of mm >= 0, got {allowance}")
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise InputError(f"--tolerance must be a number of mm >= 0, got {tolerance}")
    sb = _stock_bounds(design, stock, allowance)
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
        warnings.append(f"--step {step:g} mm is coarser than the smallest tool radius ({smallest:g} mm): "
                        "scallops and small features are not resolved")
    design_model = dexelize(design, step, bounds=bounds, device=device, cluster=cluster)
    warnings += uneven_lines_warning(design_model)
    say(f"design: {sum(design_model.dexel_count(a) for a in range(3)):,} dexels")
    if allowance is not None:
        stock_model = design_model
    elif stock == "box":
        stock_model = dexelize(shapes.box(*design.bounds), step, bounds=bounds, device=device, cluster=cluster)
    else:
        stock_model = dexelize(stock, step, bounds=bounds, device=device, cluster=cluster)
    st = cutting.stock_from_model(stock_model, allowance or 0.0)
    start_model = st.to_model()
    outside = difference_volume(design_model, start_model)
    if outside > 1e-6 * max(design_model.volume, 1.0):
        warnings.append(f"{outside:.3f} mm^3 of the design lies outside the stock: the stock is short of the design "
                        "there (not counted as gouged by the path)")
    build_s = time.perf_counter() - t0
    cuts = cut_path(st, toolpath, tools, tolerance, mode, say, device, cluster)
    machined = st.to_model()
    t2 = time.perf_counter()
    verts, faces, stride = machined_mesh(machined)
    mesh_s = time.perf_counter() - t2
    t1 = time.perf_counter()
    deviation, volumes, more, (pts, e) = measure(machined, start_model, design, design_model, float(bounds[0, 2]),
                                                 tolerance, step, device)
    warnings += more
    deviation_s = time.perf_counter() - t1
    summary = simulate_summary(mode, step, machined, len(toolpath), cuts, volumes, deviation, (verts, faces, stride),
                               warnings, {"models": round(build_s, 4), "cut": cuts["seconds"],
                                          "deviation": round(deviation_s, 4), "mesh": round(mesh_s, 4),
                                          "total": round(time.perf_counter() - t0, 4)})
    return deviation, summary, machined, (verts, faces), {"points": pts, "e": e}


def simulate_summary(mode, step, machined, moves, cuts, volumes, deviation, mesh, warnings, seconds) -> dict:
    """``summary.json`` of a simulation: the ``machined`` model, the ``moves`` count, what
    :func:`cut_path` found (``cuts``), the ``volumes`` and ``deviation`` of :func:`measure`, the
    machined ``mesh`` ``(vertices, faces, stride)``, ``warnings`` and ``seconds``."""
    verts, faces, stride = mesh
    return {
        "operation": "simulate",
        "mode": mode,
        "step": step,
        "lattice": machined.summary(),
        "moves": moves,
        **{k: v for k, v in cuts.items() if k != "seconds"},
        "volumes_mm3": volumes,
        "deviation": deviation,
        "machined_mesh": {"vertices": int(len(verts)), "triangles": int(len(faces)), "lattice_stride": int(stride)},
        "warnings": warnings,
        "seconds": seconds,
    }


def cut_path(st, toolpath, tools, tolerance=0.01, mode="sweep", progress=None, device="cpu", cluster=None) -> dict:
    """Cut ``toolpath`` from the stock ``st`` (:class:`~meshmill.simulation.cut.Stock`, in place):
    its cutters remove material, its shanks and holders (grown by ``tolerance`` less) collide
    with what is left. Returns the summary's figures: ``pieces_cut``, the rapid moves that cut
    and the moves that collide (counts, tool-path point indices, ``errors`` lines),
    ``cutting_mm`` (feed length in material and in air) and ``seconds``."""
    moves = cutting.toolpath_moves(toolpath, tools, mode)
    if mode == "sweep":  # the shank and holder, checked against the stock they pass (beyond the tolerance)
        moves = cutting.Moves.merge(moves, cutting.body_moves(toolpath, tools, tolerance))
    if progress:
        progress(f"cutting {len(moves):,} moves ({len(toolpath):,} points, mode {mode})")
    result = cutting.cut(st, moves, progress=progress, device=device, cluster=cluster)
    errors = [f"rapid move to point {i} (source line {int(toolpath.line[i])}) cuts material"
              for i in result["rapid_cuts"][:1000]]
    errors += [f"move to point {i} (source line {int(toolpath.line[i])}): the shank or holder meets the stock"
               for i in result["collisions"][:1000]]
    step_mm = np.r_[0.0, np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)]
    feed = ~np.asarray(toolpath.rapid, bool)
    feed[0] = False
    in_material = np.zeros(len(toolpath), bool)
    in_material[result["in_material"]] = True
    material_mm = float(step_mm[feed & in_material].sum())
    air_mm = float(step_mm[feed & ~in_material].sum())
    return {"pieces_cut": len(moves),
            "rapid_moves_cutting": len(result["rapid_cuts"]),
            "rapid_cutting_points": result["rapid_cuts"][:1000],
            "colliding_moves": len(result["collisions"]),
            "colliding_points": result["collisions"][:1000],
            "errors": errors,
            "cutting_mm": {"in_material": material_mm, "in_air": air_mm,
                           "air_share": air_mm / (air_mm + material_mm) if air_mm + material_mm > 0 else 0.0},
            "seconds": result["seconds"]}


def measure(machined, start_model, design, design_model, floor, tolerance, step, device="cpu"):
    """The machined dexel model against the design: ``(deviation dict, volumes dict (mm^3),
    warnings, (points (k, 3), e (k,)))`` the dexel ends and their signed deviations (mm). The
    stock's own ends inside the design (``start_model`` short of it) are not counted as gouges;
    ``floor`` is the Z an open design's solid reaches down to."""
    warnings = []
    outside = difference_volume(design_model, start_model)
    # an open design: deviations to the solid it bounds (its sheets, curtains and floor)
    pts, e, cut_pts, cut_depth = deviations(machined, design_model, material_mesh(design, floor), device)
    params = surface_parameters(pts, e, tolerance)
    # the stock's own ends inside the design (a stock short of the design) are not the path's gouges
    short = uncut_ends(machined, start_model) & (e < 0.0)
    path = surface_parameters(pts[~short], e[~short], tolerance)
    params.update(gouge_max=path["gouge_max"], gouge_at=path["gouge_at"], gouge_samples=path["gouge_samples"])
    if len(cut_pts) and outside > 0.0:  # design ends the stock never held were not cut away by the path
        never = uncovered_ends(design_model, start_model)[0]
        if len(never):
            from scipy.spatial import cKDTree

            was = cKDTree(never).query(cut_pts)[0] < 1e-9
            cut_pts, cut_depth = cut_pts[~was], cut_depth[~was]
    stock_volume = start_model.volume
    removed = stock_volume - machined.volume
    remaining = difference_volume(machined, design_model)
    gouged = max(0.0, difference_volume(design_model, machined) - outside)
    deviation = {k: params[k] for k in DEVIATION_KEYS if k in params}
    deviation.update(removed_volume=removed, remaining_volume=remaining)
    deviation = {k: deviation[k] for k in DEVIATION_KEYS}
    deep = int(np.argmax(cut_depth)) if len(cut_depth) else -1
    deviation.update(units="mm, mm^3", tolerance=tolerance, gouge_at=params["gouge_at"],
                     excess_at=params["excess_at"], gouged_volume=gouged, samples=params["samples"],
                     stock_short_ends=int(short.sum()), stock_short_max=float(-e[short].min()) if short.any() else 0.0,
                     stock_short_at=pts[short][int(np.argmin(e[short]))].round(6).tolist() if short.any() else None,
                     design_ends_cut_away=int(len(cut_depth)),
                     cut_away_depth_max=float(cut_depth[deep]) if deep >= 0 else 0.0,
                     cut_away_at=cut_pts[deep].round(6).tolist() if deep >= 0 else None)
    if short.any() and -e[short].min() > tolerance:
        warnings.append(f"the stock lies inside the design at {int(short.sum())} dexel end(s) the path does not cut, "
                        f"up to {-e[short].min():.3f} mm at {deviation['stock_short_at']}: the stock is short of the "
                        "design there (not a gouge of this path)")
    if deep >= 0 and cut_depth[deep] > max(tolerance, step):
        warnings.append(f"{len(cut_depth)} design dexel end(s) cut away, up to {cut_depth[deep]:.3f} mm deep at "
                        f"{cut_pts[deep].round(3).tolist()} (a bound; gouged volume {gouged:.3f} mm^3)")
    volumes = {"design": design_model.volume, "stock": stock_volume, "machined": machined.volume,
               "removed": removed, "remaining": remaining, "gouged": gouged}
    return deviation, volumes, warnings, (pts, e)
