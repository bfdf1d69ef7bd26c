"""``simulate`` on a Dask cluster without this process ever holding a dexel model.

The lattice's lines are split, per direction, into blocks of tile rows (the cutting kernel's
tiles, so a block's lines are cut by the moves whose swept boxes touch its tiles). A block lives
on a worker from start to end: its design and stock lines are cast there (the meshes and their
BVHs held once on the cluster, built once per worker), cut there, measured there. This process receives only each
block's figures (exact-sum expansions and first extremes, :mod:`meshmill.simulation.deviation`),
the design ends cut away (to bound their depth by the nearest machined end of any block), the
marching-cubes field's rows (at most :data:`~meshmill.simulation.surface.MAX_NODES`) and the
vertices the X and Y lines snap; the ends' deviations only when ``deviation`` is among the
outputs. The figures, the mesh and the samples are those of the one process's run.

A block is kept on its worker as a Dask future; a worker that dies loses its blocks, which Dask
computes again from their tasks (casting, cutting) elsewhere.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import memory
from ..cluster import PIECES_PER_WORKER, check_workers, hold, share, submit, wait, worker_cached, workers
from ..progress import ranges
from ..kernels.backend import TILE, MeshKernels
from ..kernels.bvh import build_bvh
from ..simulation import cut as cutting
from ..params import OUTPUTS
from ..simulation.deviation import join_measures, measure_lines, measured, nearest_end
from ..simulation.dexel import LINE_BYTES, TRIANGLE_BYTES, cast_rows, lattice, lattice_summary, material_mesh, \
    uneven_lines_warning
from ..simulation.surface import empty_field, field_rows, field_surface, mesh_grid, outward, snap_lines
from ..simulation.stock import cut_figures, path_moves
from ..simulation.load import RemovedByMove, merge_loads, move_probe
from ..kernels.backend import DexelKernels
from .simulate import add_load, measure_load, prepare, simulate_summary

HELD_LINE_BYTES = 200  # a line kept on a worker: its design, stock and cut dexels (CSR, about two each)
SAMPLE_BYTES = 64  # a machined dexel gathered for deviation.npz: its two ends (points and deviations)


@dataclass
class Block:
    """One block of lines along ``a``: lattice rows ``first_row .. stop_row - 1`` (tile rows
    ``rows``), the design's and the stock's lines (CSR ``(start, iv)``), lines cast unevenly."""

    a: int
    rows: tuple
    first_row: int
    stop_row: int
    design: tuple
    stock: tuple
    uneven: int


def block_models(shared: dict, piece) -> Block:
    """The design's and the stock's lines of one block, cast on a worker; the stock's dexels
    lengthened by the ``allowance`` (its own: the design's)."""
    a, rows = piece
    nu = int(shared["n"][(a + 1) % 3])
    i0, i1 = rows[0] * TILE, min(nu, rows[1] * TILE)
    ds, div, bad = cast_rows(shared, "design", a, (i0, i1))
    if shared["allowance"] is not None:
        stock = cutting.widened(ds, div, shared["allowance"])
    else:
        ss, siv, _ = cast_rows(shared, "stock", a, (i0, i1))
        stock = cutting.widened(ss, siv)
    return Block(a, rows, i0, i1, (ds, div), stock, bad)


def block_info(block: Block) -> tuple:
    """``(a, design dexels, uneven lines, (lo, hi) of the stock's material along a or None)``."""
    start, iv = block.stock
    full = np.diff(start) > 0
    span = (float(iv[start[:-1][full], 0].min()), float(iv[start[1:][full] - 1, 1].max())) if full.any() else None
    return block.a, len(block.design[1]), block.uneven, span


def cut_block(shared: dict, block: Block) -> tuple:
    """``(start, iv, hit indices, load)``: the block's stock cut by the moves
    (:func:`~meshmill.simulation.cut.cut_lines`) and, where ``shared`` has a ``probe``, the load
    of the moves that removed some of it (their indices and rows of
    :func:`~meshmill.simulation.load.reduce_load`; None otherwise)."""
    start, iv, hit, load = cutting.cut_lines(shared, block.a, block.rows, *block.stock)
    if load is not None:
        some = np.nonzero(load[:, 0] > 0)[0]
        load = (some, load[some])
    return start, iv, np.nonzero(hit)[0], load


def cut_info(cut: tuple) -> tuple:
    """``(machined dexels, indices of the moves that hit, load)`` of a cut block."""
    return len(cut[1]), cut[2], cut[3]


def _kernels(shared):
    mesh = shared["design"][0]
    return worker_cached(shared, "measure", lambda: MeshKernels(build_bvh(mesh.vertices, mesh.faces), shared["device"]))


def measure_block(shared: dict, block: Block, cut: tuple, tolerance: float, samples: bool) -> dict:
    """:func:`~meshmill.simulation.deviation.measure_lines` of a cut block."""
    return measure_lines(shared["lo"], shared["n"], shared["step"], block.a, block.first_row, cut[:2], block.stock,
                         block.design, _kernels(shared), tolerance, samples)


def nearest_block(shared: dict, block: Block, cut: tuple, points) -> np.ndarray:
    """Distance from each of ``points = (points, depth bounds)`` to the nearest machined dexel end
    of the block, where under its bound (:func:`~meshmill.simulation.deviation.nearest_end`)."""
    return nearest_end(shared["lo"], shared["n"], shared["step"], block.a, block.first_row, cut[:2], *points)


def field_block(shared: dict, block: Block, cut: tuple) -> tuple:
    """The machined mesh's field rows of a block of Z lines (:func:`~meshmill.simulation.surface.field_rows`)."""
    return field_rows(shared["lo"], shared["n"], shared["step"], *cut[:2], block.first_row, block.stop_row)


def snap_block(shared: dict, block: Block, cut: tuple, verts) -> tuple:
    """The surface's vertices on edges along the block's X or Y lines, moved to their dexel end."""
    return snap_lines(verts, shared["lo"], shared["n"], shared["step"], block.a, *cut[:2], block.first_row)


def simulate_on(client, design, toolpath, tools, step, stock, tolerance=0.01, mode="sweep", progress=None,
                device="cpu", outputs=OUTPUTS, material=None, machine=None):
    """:func:`meshmill.ops.simulate.simulate` by blocks of lines on the workers of ``client`` (a
    ``distributed.Client``) from a described ``stock``: the same arguments and results, but the
    stock after it is None (this process never holds it)."""
    say = progress or (lambda _: None)
    t0 = time.perf_counter()
    workpiece_material = material  # (material below: the design's mesh for casting)
    bounds, warnings = prepare(design, toolpath, tools, step, stock, tolerance, outputs)
    floor = float(bounds[0, 2])
    lo, n = lattice(bounds, step)
    material = material_mesh(design, floor)
    allowance = stock.allowance if stock.kind == "offset" else None
    stock_part = stock.solid(design)
    stock_mesh = None if stock_part is None else material_mesh(stock_part, floor)
    count = PIECES_PER_WORKER * workers(client)
    pieces = [(a, rows) for a in range(3) for rows in ranges(-(-int(n[(a + 1) % 3]) // TILE), count)]
    moves = path_moves(toolpath, tools, tolerance, mode)
    lines = sum(int(n[(a + 1) % 3] * n[(a + 2) % 3]) for a in range(3))
    block = max(min(int(n[(a + 1) % 3]), (r1 - r0) * TILE) * int(n[(a + 2) % 3]) for a, (r0, r1) in pieces)
    triangles = len(material.faces) + (0 if stock_mesh is None else len(stock_mesh.faces))
    # a worker keeps its share of every direction's blocks (half as much again where Dask places
    # unevenly), casts one block at a time, and holds the meshes, their BVHs and the moves
    check_workers(client, 1.5 * HELD_LINE_BYTES * lines / workers(client) + LINE_BYTES * block
                  + TRIANGLE_BYTES * triangles + cutting.MOVE_BYTES * len(moves),
                  f"simulating {len(moves):,} moves over {lines:,} dexel lines in blocks",
                  "use more workers, or a coarser step")
    handle = share(client, dict(design=(material, design), stock=None if stock_part is None else (stock_mesh, stock_part),
                                allowance=allowance, lo=lo, n=n, step=float(step), device=device))
    blocks = [submit(client, block_models, handle, p) for p in pieces]
    wait(blocks, say, "design and stock lines")
    infos = client.gather([submit(client, block_info, b) for b in blocks])
    odd = {"XYZ"[a]: sum(i[2] for i in infos if i[0] == a) for a in range(3)}
    warnings = warnings + uneven_lines_warning({k: v for k, v in odd.items() if v}, design)
    say(f"design: {sum(i[1] for i in infos):,} dexels")
    mlo, mhi = np.full(3, np.inf), np.full(3, -np.inf)
    for a, _, _, span in infos:
        if span is not None:
            mlo[a], mhi[a] = min(mlo[a], span[0]), max(mhi[a], span[1])
    build_s = time.perf_counter() - t0

    t1 = time.perf_counter()
    say(f"cutting {len(moves):,} moves ({len(toolpath):,} points, mode {mode})")
    near, boxes = cutting.near_moves(moves, mlo, mhi)
    probe = move_probe(near) if mode == "sweep" else None
    moved = share(client, dict(moves=near, boxes=boxes, lo=lo, n=n, step=float(step), device=device, probe=probe))
    cuts = [submit(client, cut_block, moved, b) for b in blocks]
    wait(cuts, say, "cutting")
    done = client.gather([submit(client, cut_info, c) for c in cuts])
    hit = np.zeros(len(near), np.uint8)
    for _, idx, _ in done:
        hit[idx] = 1
    cut_s = round(time.perf_counter() - t1, 4)
    figures = cut_figures(toolpath, len(moves), {**cutting.hits(near, hit), "seconds": cut_s})
    load = load_summary = None
    if probe is not None:
        per_direction = [DexelKernels().new_load(len(near))[0] for _ in range(3)]
        for p, (_, _, (some, rows)) in zip(pieces, done):
            per_direction[p[0]][some] = merge_loads([per_direction[p[0]][some], rows])
        removed = RemovedByMove.of(near, per_direction, float(step), len(toolpath), probe)
        load, load_summary = measure_load(toolpath, tools, removed, workpiece_material, machine, float(step))

    t2 = time.perf_counter()
    samples = "deviation" in outputs
    if samples:
        memory.check(SAMPLE_BYTES * sum(d for d, _, _ in done), "gathering the deviation of every machined dexel end",
                     "leave deviation out of outputs (say outputs summary,mesh)", ("outputs",))
    parts = [submit(client, measure_block, handle, b, c, tolerance, samples) for b, c in zip(blocks, cuts)]
    wait(parts, say, "measuring")
    parts = client.gather(parts)
    away, depth = (np.concatenate([p[k] for p in parts]) for k in ("away_points", "away_depth"))
    nearest = None
    if len(away):
        points = hold(client, (away, depth))
        nearest = np.min(client.gather([submit(client, nearest_block, handle, b, c, points)
                                        for b, c in zip(blocks, cuts)]), axis=0)
    m = join_measures(parts, nearest, step)
    deviation, volumes, more = measured(m, tolerance, step)
    deviation_s = time.perf_counter() - t2

    t3 = time.perf_counter()
    mesh = None
    if "mesh" in outputs:
        field = empty_field(n, step)
        for a0, slab in client.gather([submit(client, field_block, handle, b, c)
                                       for p, b, c in zip(pieces, blocks, cuts) if p[0] == 2]):
            field[a0 + 1:a0 + 1 + len(slab)] = slab
        verts, faces = field_surface(field, lo, step, n)
        if len(verts):
            shared_verts = hold(client, verts)
            snaps = client.gather([submit(client, snap_block, handle, b, c, shared_verts)
                                   for p, b, c in zip(pieces, blocks, cuts) if p[0] < 2])
            for (idx, w), p in zip(snaps, [p for p in pieces if p[0] < 2]):
                verts[idx, p[0]] = w
        mesh = (verts, outward(verts, faces), mesh_grid(n)[0])
    mesh_s = time.perf_counter() - t3
    client.cancel(blocks + cuts + [handle, moved])  # (cancelling a future cancels what was made from it)
    summary = simulate_summary(mode, step, lattice_summary(lo, float(step), n, m["dexels"], m["volumes_by_direction"]),
                               len(toolpath), figures, volumes, deviation, mesh, warnings + more,
                               {"models": round(build_s, 4), "cut": cut_s, "deviation": round(deviation_s, 4),
                                "mesh": round(mesh_s, 4), "total": round(time.perf_counter() - t0, 4)})
    sampled = None
    if samples:
        sampled = {"points": np.concatenate([p["points"] for p in parts]), "e": np.concatenate([p["e"] for p in parts])}
    add_load(summary, load_summary)
    return deviation, summary, None, mesh[:2] if mesh else None, sampled, load
