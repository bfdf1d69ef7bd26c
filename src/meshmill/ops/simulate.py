"""Operations on triple-dexel models: build one from a part (``meshmill dexel``), and simulate
what a tool path cuts from a stock and compare it with the design (``meshmill simulate``)."""
from __future__ import annotations

import time

import numpy as np

from ..errors import InputError
from ..geometry import shapes
from ..simulation import cut as cutting
from ..simulation import partition
from ..kernels.backend import MeshKernels
from ..kernels.bvh import build_bvh
from ..simulation.deviation import join_measures, measure_lines, nearest_end
from ..progress import PIECES, Meter, ranges
from ..simulation.dexel import (MAX_PARTITIONS, DexelModel, dexelize, lattice, line_rows, material_mesh,
                                uneven_lines_warning)
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
    summary["warnings"] = uneven_lines_warning(model.info.get("uneven_lines"))
    return model, summary


def _stock_bounds(design, stock, allowance):
    if allowance is not None:
        return design.bounds + np.array([[-1.0], [1.0]]) * allowance
    if stock == "box":
        return design.bounds
    return stock.bounds


OUTPUTS = ("deviation", "mesh")  # what simulate may keep beyond the summary: the ends' deviations, the machined mesh


def simulate(design, toolpath, tools, step, stock="box", allowance=None, tolerance=0.01, mode="sweep",
             progress=None, device="cpu", outputs=OUTPUTS):
    """Cut ``toolpath`` from the stock (``"box"``: the design's box; a Mesh; or the design with
    ``allowance`` mm on both ends of every dexel) and measure the result against ``design``.

    Returns ``(deviation dict, summary dict, machined DexelModel, (vertices, faces) of the machined
    mesh, {"points": (k, 3), "e": (k,)} the dexel ends and their signed deviations, mm)``; the
    mesh and the ends only when ``outputs`` names ``"mesh"`` and ``"deviation"`` (else None).
    ``device``: ``"cpu"`` or ``"cuda"`` for dexel casting, cutting and distances (on a cluster:
    :func:`meshmill.ops.simulate_blocks.simulate_on`)."""
    say = progress or (lambda _: None)
    t0 = time.perf_counter()
    bounds, warnings = prepare(design, toolpath, tools, step, stock, allowance, tolerance, outputs)
    design_model = dexelize(design, step, bounds=bounds, device=device)
    warnings += uneven_lines_warning(design_model.info.get("uneven_lines"))
    say(f"design: {sum(design_model.dexel_count(a) for a in range(3)):,} dexels")
    if allowance is not None:
        stock_model = design_model
    elif stock == "box":
        stock_model = dexelize(shapes.box(*design.bounds), step, bounds=bounds, device=device)
    else:
        stock_model = dexelize(stock, step, bounds=bounds, device=device)
    st = cutting.stock_from_model(stock_model, allowance or 0.0)
    start_model = st.to_model()
    build_s = time.perf_counter() - t0
    cuts = cut_path(st, toolpath, tools, tolerance, mode, say, device)
    machined = st.to_model()
    t2 = time.perf_counter()
    mesh = machined_mesh(machined) if "mesh" in outputs else None
    mesh_s = time.perf_counter() - t2
    t1 = time.perf_counter()
    deviation, volumes, more, (pts, e) = measure(machined, start_model, design, design_model, float(bounds[0, 2]),
                                                 tolerance, step, device, "deviation" in outputs, say)
    deviation_s = time.perf_counter() - t1
    summary = simulate_summary(mode, step, machined.summary(), len(toolpath), cuts, volumes, deviation, mesh,
                               warnings + more, {"models": round(build_s, 4), "cut": cuts["seconds"],
                                                 "deviation": round(deviation_s, 4), "mesh": round(mesh_s, 4),
                                                 "total": round(time.perf_counter() - t0, 4)})
    return (deviation, summary, machined, mesh[:2] if mesh else None,
            {"points": pts, "e": e} if "deviation" in outputs else None)


def prepare(design, toolpath, tools, step, stock, allowance, tolerance, outputs) -> tuple[np.ndarray, list]:
    """``(bounds (2, 3), warnings)`` of :func:`simulate`'s arguments: the lattice's box (the
    stock's and the design's) and what the user should know of the tools and the step; refuses a
    path that never reaches the stock, unknown ``outputs``."""
    unknown = set(outputs) - set(OUTPUTS)
    if unknown:
        raise InputError(f"--outputs: unknown {', '.join(sorted(unknown))} (choose from summary, {', '.join(OUTPUTS)})")
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


def cut_path(st, toolpath, tools, tolerance=0.01, mode="sweep", progress=None, device="cpu", cluster=None) -> dict:
    """Cut ``toolpath`` from the stock ``st`` (:class:`~meshmill.simulation.cut.Stock`, in place):
    its cutters remove material, its shanks and holders (grown by ``tolerance`` less) collide
    with what is left. Returns :func:`cut_figures`."""
    moves = path_moves(toolpath, tools, tolerance, mode)
    if progress:
        progress(f"cutting {len(moves):,} moves ({len(toolpath):,} points, mode {mode})")
    return cut_figures(toolpath, len(moves), cutting.cut(st, moves, progress=progress, device=device, cluster=cluster))


def path_moves(toolpath, tools, tolerance=0.01, mode="sweep") -> cutting.Moves:
    """The pieces a path cuts (``mode`` sweep: with its shanks and holders, grown by ``tolerance``
    less, checked against the stock they pass; points: the tool at the points, the seed's)."""
    moves = cutting.toolpath_moves(toolpath, tools, mode)
    if mode == "sweep":
        moves = cutting.Moves.merge(moves, cutting.body_moves(toolpath, tools, tolerance))
    return moves


def cut_figures(toolpath, pieces: int, result: dict) -> dict:
    """The summary's figures of a cut (``result`` of :func:`~meshmill.simulation.cut.cut` with
    ``pieces`` moves): ``pieces_cut``, the rapid moves that cut and the moves that collide
    (counts, tool-path point indices, ``errors`` lines), ``cutting_mm`` (feed length in material
    and in air) and ``seconds``."""
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
    return {"pieces_cut": pieces,
            "rapid_moves_cutting": len(result["rapid_cuts"]),
            "rapid_cutting_points": result["rapid_cuts"][:1000],
            "colliding_moves": len(result["collisions"]),
            "colliding_points": result["collisions"][:1000],
            "errors": errors,
            "cutting_mm": {"in_material": material_mm, "in_air": air_mm,
                           "air_share": air_mm / (air_mm + material_mm) if air_mm + material_mm > 0 else 0.0},
            "seconds": result["seconds"]}


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
