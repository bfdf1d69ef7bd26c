"""3-axis waterline (Z-level) finishing and roughing loops for flat, ball and bull-nose cutters.

A tool at tip height z and position (x, y) gouges (or its shank or holder collides) exactly when
the drop height of the whole tool there is above z, so the waterline loops at z are the level set
``drop(x, y) = z``. The drop-cutter heights live on one grid over the part (``sample`` apart, like
the fibres of other programs, widened by the tool's reach) shared by every level, and are computed
only in the blocks of the grid where bounds of the drop height cannot tell inside from outside
(:mod:`meshmill.pathing.dropgrid`). Per level, marching squares (the cell centre deciding saddles) gives the
crossings, which are moved onto the level set by a bracketed search with the exact drop-cutter:
each loop point keeps ``drop <= z`` (no gouge) and either its height is within 1e-6 mm of z or the
level set lies within 1e-4 mm of it toward the material (always so at a vertical wall, where the
height jumps).
A point counts as inside when ``drop > z`` strictly, so a flat facet lying exactly at z gives no
loop of its own. Loops are chained by grid-edge identity, closed, and run clockwise around material
seen from +Z (climb milling with a clockwise spindle).

With ``scallop`` the levels are as far apart as the scallop limit allows on ground as steep as
``min_slope`` (sod sin(min_slope)); with ``min_slope``/``max_slope`` only the pieces of the loops
on ground that steep are cut (:mod:`meshmill.pathing.slope`: the steep half of steep and shallow).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numba
import numpy as np

from ..progress import Meter, StageClock
from .. import memory
from ..errors import InputError, NothingToCut
from ..kernels.backend import solid_kernels
from ..geometry.mesh import Mesh
from ..geometry.slicing import z_levels
from ..toolpath.linking import simplify_polyline
from ..params import WaterlineParams
from ..pathing.dropcutter import ToolDrop, pick_tool, stock_for, verified_path
from ..pathing.rest import REST_JOIN, REST_LEAD, densify, in_material, loop_runs
from ..pathing.dropgrid import DropGrid
from ..pathing.slope import level_distance, scallop_radius, slope_pieces
from ..pathing.verify import DEFAULT_STEP

REFINE_ROUNDS = 8  # chord refinement rounds of a loop
NODE_BYTES = 64  # one node of the drop grid: heights, contacts, bounds and the level masks
PROBES = np.array([0.5, 0.25, 0.75, 0.125, 0.375, 0.625, 0.875])  # where chords are checked


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


def _crossings(grid: DropGrid, z, edge_ids, drop: ToolDrop):
    """The point on each grid edge where the drop height reaches z, never above it; ``(k, 2)``."""
    i0, j0, i1, j1 = _edge_nodes(edge_ids, len(grid.ys))
    swap = grid.heights[i0, j0] <= z  # a: the inside end (height > z), b: the outside end
    ia, ja = np.where(swap, i1, i0), np.where(swap, j1, j0)
    ib, jb = np.where(swap, i0, i1), np.where(swap, j0, j1)
    pa = np.column_stack([grid.xs[ia], grid.ys[ja]])
    pb = np.column_stack([grid.xs[ib], grid.ys[jb]])
    return drop.touch(pa, pb, grid.heights[ia, ja] - z, grid.heights[ib, jb] - z, z, grid.contacts[ia, ja])


def _chord_intrusion(loop, z, reach, drop: ToolDrop, pairs=False):
    """How deep each chord of the clockwise ``loop (k, 2)`` runs into the material side of the level
    set, ``(k-1,)`` mm, and the touch point that would fix it ``(k-1, 2)``. Probed at eighths; a probe
    whose drop height is above z is inside by the smaller of that excess and its distance to the
    level set outward (to the left of the chord), so a chord grazing a vertical wall counts by how
    far it enters the wall, not by the wall's height. Chords that find no way out within ``reach``
    come back as infinitely deep. With ``pairs``, ``loop (2c, 2)`` holds c separate chords."""
    a, b = (loop[0::2], loop[1::2]) if pairs else (loop[:-1], loop[1:])
    probe = a[:, None, :] + PROBES[None, :, None] * (b - a)[:, None, :]
    zp, cp = drop.with_contacts(probe.reshape(-1, 2))
    fp = (zp - z).reshape(len(a), -1)
    worst = np.argmax(fp, axis=1)
    rows = np.arange(len(a))
    f, mid = fp[rows, worst], probe[rows, worst]
    contact = cp.reshape(len(a), -1, 3)[rows, worst]
    depth = np.maximum(f, 0.0)
    touch = np.full_like(mid, np.nan)
    idx = np.nonzero(f > 0.0)[0]
    if len(idx):
        d = b[idx] - a[idx]
        length = np.linalg.norm(d, axis=1, keepdims=True)
        left = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(length, 1e-12)
        # look for the outside a little way out first, then further
        push = np.full((len(idx), 1), 0.25 * reach)
        outer = mid[idx] + left * push
        fo = drop(outer) - z
        for _ in range(2):
            far = np.nonzero(fo > 0.0)[0]
            if len(far) == 0:
                break
            push[far] *= 4.0
            outer[far] = mid[idx][far] + left[far] * push[far]
            fo[far] = drop(outer[far]) - z
        ok = fo <= 0.0
        depth[idx[~ok]] = np.inf
        j = idx[ok]
        if len(j):
            touch[j] = drop.touch(mid[j], outer[ok], f[j], fo[ok], z, contact[j])
            depth[j] = np.minimum(f[j], np.linalg.norm(touch[j] - mid[j], axis=1))
    return depth, touch


def _refine_loop(loop, z, chord_tol, reach, drop: ToolDrop):
    """Passes ``[(m, 2)]`` along the clockwise ``loop (k, 2)``: where a chord runs into the material
    by more than ``chord_tol``, its touch point is added (and only the two new chords are checked
    again); chords that still do after a few rounds are left out (the pass is split there)."""
    depth, touch = _chord_intrusion(loop, z, reach, drop)
    for _ in range(REFINE_ROUNDS):
        bad = np.nonzero((depth > chord_tol) & np.isfinite(depth))[0]
        if len(bad) == 0:
            break
        loop = np.insert(loop, bad + 1, touch[bad], axis=0)
        # chord i of the old loop becomes chords i + n and i + n + 1 (n: insertions before it)
        new = bad + np.arange(len(bad))
        fresh = np.concatenate([new, new + 1])
        pairs = np.stack([loop[fresh], loop[fresh + 1]], axis=1)  # (f, 2, 2): each new chord alone
        d_new, t_new = _chord_intrusion(pairs.reshape(-1, 2), z, reach, drop, pairs=True)
        old_idx = np.delete(np.arange(len(depth) + len(bad)), fresh)
        depth2 = np.empty(len(depth) + len(bad))
        touch2 = np.empty((len(depth) + len(bad), 2))
        depth2[old_idx] = np.delete(depth, bad)
        touch2[old_idx] = np.delete(touch, bad, axis=0)
        depth2[fresh], touch2[fresh] = d_new, t_new
        depth, touch = depth2, touch2
    cuts = np.nonzero(depth > chord_tol)[0]
    if len(cuts) == 0:
        return [loop]
    # piece i ends at the start of a bad chord; the next begins at its end
    return [p for p in np.split(loop, cuts + 1) if len(p) >= 2]


def _level_loops(z, grid, drop, cx, cy, centre_cache, tol, spacing):
    """``([(z, (k, 3) loop or piece), ...], seconds in the grid)``: the loops of level ``z`` of the
    drop grid, refined within ``tol``; ``centre_cache`` keeps the cell centres dropped for saddles."""
    found, grid_s = [], 0.0
    t = time.perf_counter()
    inside = grid.inside(z)
    grid_s += time.perf_counter() - t
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
            zc = drop(pts)
            centre_cache.update(zip(missing, zc))
        centre_inside[si, sj] = np.array([centre_cache[(a, b)] for a, b in zip(si, sj)]) > z
    segs = _cell_segments(inside, centre_inside)
    if len(segs) == 0:
        return found, grid_s
    edge_loops = _chain_loops(segs)
    all_edges = np.concatenate(edge_loops)
    pts = _crossings(grid, z, all_edges, drop)
    start = 0
    for el in edge_loops:
        p = pts[start:start + len(el)]
        start += len(el)
        if len(p) < 3:
            continue
        loop = np.column_stack([p, np.full(len(p), z)])[::-1]  # clockwise: climb milling
        loop = simplify_polyline(np.vstack([loop, loop[:1]]), 0.25 * tol)
        for piece in _refine_loop(loop[:, :2], z, 0.5 * tol, spacing, drop):
            found.append((float(z), np.column_stack([piece, np.full(len(piece), z)])))
    return found, grid_s


def level_piece(shared: dict, levels) -> list:
    """The loops of a group of ``levels`` on a worker of a cluster (:func:`meshmill.cluster.run_pieces`);
    ``shared``: the ``part``, the ``tool`` and its drop (``floor``, ``grow``, ``body_grow``), the
    grid ``xs, ys``, ``tol``, ``spacing``, ``device``. The drop grid is built once per worker."""
    from ..cluster import worker_cached

    def build():
        kern = solid_kernels(shared["part"], shared["device"])
        drop = ToolDrop(shared["tool"], kern, shared["floor"], grow=shared["grow"], body_grow=shared["body_grow"])
        return drop, DropGrid(drop, shared["xs"], shared["ys"]), {}

    drop, grid, centres = worker_cached(shared, "grid", build)
    xs, ys = shared["xs"], shared["ys"]
    cx, cy = 0.5 * (xs[:-1] + xs[1:]), 0.5 * (ys[:-1] + ys[1:])
    found = []
    for z in levels:
        found += _level_loops(z, grid, drop, cx, cy, centres, shared["tol"], shared["spacing"])[0]
    return found


@dataclass
class WaterlineSetup:
    """What a waterline works with: ``params`` as kept (the clearance plus the stock's margin);
    ``rapid_stock`` (what rapids keep clear of), ``grow`` mm (how far the shank and holder keep
    from the design), ``safe_z`` mm and ``rest_kern`` (what ``rest`` depths are measured from, or
    None), as :func:`~meshmill.pathing.dropcutter.stock_for` gives them; the ``tool`` and its
    ``index`` in the table; ``levels (L,)`` Z mm from the top down; the drop grid's nodes ``xs
    (nx,)`` x ``ys (ny,)`` mm, ``sample`` apart over the part widened by the tool's reach."""

    params: WaterlineParams
    rapid_stock: object
    grow: float
    safe_z: float
    rest_kern: object
    index: int
    tool: object
    levels: np.ndarray
    xs: np.ndarray
    ys: np.ndarray


def waterline_setup(mesh: Mesh, tools, tool_name: str, params: WaterlineParams, device: str = "cpu",
                    stock=None) -> WaterlineSetup:
    """The :class:`WaterlineSetup` of ``mesh`` with the tool ``tool_name`` of ``tools``:
    InputError for a tool not in the table or a grid larger than the memory (``sample``);
    NothingToCut where ``step_down`` leaves no level. ``stock``: ``params.stock`` as
    :func:`~meshmill.pathing.dropcutter.stock_for` gives it, where already made (its params aside)."""
    if stock is None:
        params, rapid_stock, grow, safe_z, rest_kern = stock_for(mesh, params, device)
    else:
        rapid_stock, grow, safe_z, rest_kern = stock
    index, tool = pick_tool(tools, tool_name)
    reach = max(tool.radius, 0.5 * tool.shank_diameter, 0.5 * tool.holder_diameter)  # outside it: no contact
    bounds = mesh.bounds
    if params.step_down is None:  # the levels the scallop limit needs on ground as steep as min_slope
        if scallop_radius(tool) is None:
            raise InputError(f"tool '{tool.name}' is flat: its scallop height is not defined, give step_down instead "
                             "of scallop", ("step_down", "scallop"))
        params = replace(params, step_down=level_distance(params.scallop, tool, params.min_slope))
    levels = z_levels(bounds[0, 2], bounds[1, 2], params.step_down)
    if len(levels) == 0:
        raise NothingToCut(f"step_down {params.step_down:g} is larger than the part height "
                           f"{bounds[1, 2] - bounds[0, 2]:g} mm: no level", "step_down")
    spacing = params.sample
    lo = bounds[0, :2] - reach - 2 * spacing
    hi = bounds[1, :2] + reach + 2 * spacing
    nx = int(math.ceil((hi[0] - lo[0]) / spacing)) + 1
    ny = int(math.ceil((hi[1] - lo[1]) / spacing)) + 1
    memory.check(NODE_BYTES * float(nx) * ny, f"{nx:,} x {ny:,} grid points", "use a larger sample", ("sample",))
    xs = lo[0] + (hi[0] - lo[0]) * np.arange(nx) / (nx - 1)
    ys = lo[1] + (hi[1] - lo[1]) * np.arange(ny) / (ny - 1)
    return WaterlineSetup(params, rapid_stock, grow, safe_z, rest_kern, index, tool, levels, xs, ys)


def drop_grid(mesh: Mesh, kern, setup: WaterlineSetup) -> tuple[ToolDrop, DropGrid]:
    """``(drop, grid)``: the drop-cutter of the whole tool over the part (bound to ``kern``; never
    below the part's bottom less 1 mm; the cutter grown by ``allowance``, shank and holder by
    ``setup.grow``) and its heights on the nodes ``setup.xs x setup.ys``, bounded per block and
    dropped as the levels need them (:class:`~meshmill.pathing.dropgrid.DropGrid`)."""
    drop = ToolDrop(setup.tool, kern, float(mesh.bounds[0, 2]) - 1.0, grow=setup.params.allowance,
                    body_grow=setup.grow)
    return drop, DropGrid(drop, setup.xs, setup.ys)


def level_loops(setup: WaterlineSetup, drop: ToolDrop, grid: DropGrid, part=None, device="cpu", cluster=None,
                say=None):
    """``([(z, (k, 3) loop or piece), ...], seconds in the grid)``: the loops of every level of
    ``setup.levels`` from the top down (:func:`_level_loops`, refined within the tolerance), or with
    ``cluster`` (a ``distributed.Client``) groups of levels found on its workers, which drop
    ``part`` on ``device`` themselves (the same loops)."""
    params = setup.params
    xs, ys = setup.xs, setup.ys
    loops, grid_s = [], 0.0
    if cluster is not None:
        from ..cluster import PIECES_PER_WORKER, run_pieces, workers
        from ..progress import ranges

        shared = dict(part=part, device=device, tool=setup.tool, floor=drop.floor, grow=params.allowance,
                      body_grow=setup.grow, xs=xs, ys=ys, tol=params.tolerance, spacing=params.sample)
        groups = [setup.levels[a:b] for a, b in ranges(len(setup.levels), PIECES_PER_WORKER * workers(cluster))]
        for found in run_pieces(cluster, level_piece, shared, groups, say, "levels"):
            loops += found
        return loops, grid_s
    cx, cy = 0.5 * (xs[:-1] + xs[1:]), 0.5 * (ys[:-1] + ys[1:])
    centre_cache = {}
    meter = Meter(say, "levels", len(setup.levels))
    for z in setup.levels:
        found, s = _level_loops(z, grid, drop, cx, cy, centre_cache, params.tolerance, params.sample)
        loops += found
        grid_s += s
        meter.done()
    return loops, grid_s


def rest_pieces(loops, setup: WaterlineSetup):
    """``(loops, report)``: the pieces of ``loops`` (``[(z, (k, 3))]``) that remove more than
    ``rest`` mm of the stock (tested at ``sample`` spacing against ``setup.rest_kern``), with a
    lead of :data:`~meshmill.pathing.rest.REST_LEAD` samples on each side; a loop whole in the
    material stays as it was."""
    params, tool = setup.params, setup.tool
    dense = [densify(p, params.sample) for _, p in loops]
    sizes = np.cumsum([len(d) for d in dense])[:-1]
    inside = np.split(in_material(np.vstack(dense), tool, setup.rest_kern, params.rest), sizes) if dense else []
    n_in, n_all = int(sum(i.sum() for i in inside)), int(sum(len(d) for d in dense))
    pieces = []
    for (z, p), d, i in zip(loops, dense, inside):  # one drop onto the stock for every loop
        if i.all():
            pieces.append((z, p))  # as it was: whole in material
        else:
            pieces += [(z, simplify_polyline(r, 0.25 * params.tolerance))
                       for r in loop_runs(d, i, REST_LEAD * params.sample, REST_JOIN * tool.diameter)]
    return pieces, {"min_depth": params.rest, "points_in_material": n_in, "points_tested": n_all, "runs": len(pieces),
                    "loops_before": len(loops)}


def cut_pieces(loops, setup: WaterlineSetup, drop: ToolDrop, near=None):
    """``(loops, rest report, slope report)``: the pieces of ``loops`` (``[(z, (k, 3))]``) that
    remove more than ``rest`` of the stock (:func:`rest_pieces`) and lie on ground within
    ``min_slope``-``max_slope`` (:func:`~meshmill.pathing.slope.slope_pieces`, with ``near`` only
    where the tool touches near those points); the reports None where not asked."""
    params, rest, slopes = setup.params, None, None
    if params.rest is not None:  # the pieces of the loops in the stock's material, at sample spacing
        loops, rest = rest_pieces(loops, setup)
    if loops and (params.min_slope is not None or params.max_slope is not None or near is not None):
        pieces, slopes = slope_pieces([p for _, p in loops], drop, setup.tool, params.min_slope, params.max_slope,
                                      params.overlap, params.sample, closed=True, near=near)
        loops = [(float(p[0, 2]), simplify_polyline(p, 0.25 * params.tolerance)) for p in pieces]
    return loops, rest, slopes


def waterline_summary(setup: WaterlineSetup, grid: DropGrid, loops, tp, report: dict, rest, slopes=None) -> dict:
    """The summary of a waterline (timing aside): its parameters, the grid and how much of it was
    dropped, the ``loops`` cut (``[(z, (k, 3))]``), the path ``tp``, the ``rest`` report (or
    None) and the verification ``report``."""
    params = setup.params
    return {
        "operation": "waterline",
        "tool": setup.tool.name,
        "step_down": params.step_down,
        "sample": params.sample,
        "grid_spacing": params.sample,
        "tolerance": params.tolerance,
        "allowance": params.allowance,
        "safe_z": setup.safe_z,
        "stock": setup.rapid_stock.summary(),
        "levels": int(len(setup.levels)),
        "passes": len(loops),
        "closed_loops": int(sum(np.array_equal(p[0], p[-1]) for _, p in loops)),
        "grid": [len(setup.xs), len(setup.ys)],
        "grid_points_dropped": grid.dropped,
        "cl_points": int(sum(len(p) for _, p in loops)),
        "moves": int(len(tp)),
        "cutting_length": tp.cutting_length(),
        **({"rest": rest} if rest is not None else {}),
        **({"slopes": slopes} if slopes is not None else {}),
        "verify": report,
    }


def waterline(mesh: Mesh, tools, tool_name: str, params: WaterlineParams, progress=None, device: str = "cpu",
              cluster=None):
    """Run the operation on ``device`` (``"cpu"`` or ``"cuda"``); returns ``(toolpath, summary, passes)`` with ``passes`` a list of
    ``(z, (k, 3) array)`` from the top level down: closed loops (first point repeated at the end),
    or pieces of loops where a stretch could not be cut without gouging. ``params.stock``: the
    material it starts from (:func:`~meshmill.pathing.dropcutter.stock_for`), which rapids keep
    ``params.clearance`` from; with ``params.rest`` only the pieces of the loops that remove more
    than that depth of it are cut (:mod:`meshmill.pathing.rest`), with a lead of 1.5 samples on
    each side, measured from its surface; ``cluster``: a ``distributed.Client`` groups of levels
    are found on (the same loops). The stages: :func:`waterline_setup`, :func:`drop_grid`,
    :func:`level_loops`, :func:`rest_pieces` (with ``rest``), the verified path
    (:func:`~meshmill.pathing.dropcutter.verified_path`), :func:`waterline_summary`."""
    setup = waterline_setup(mesh, tools, tool_name, params, device)
    params = setup.params
    clock = StageClock(progress)
    t_all = time.perf_counter()
    with clock("index"):
        kern = solid_kernels(mesh, device)  # the solid the part bounds, on the device from here on
    with clock("drop-cutter bounds", "bounds"):
        drop, grid = drop_grid(mesh, kern, setup)
    with clock("levels"):
        loops, grid_s = level_loops(setup, drop, grid, mesh, device, cluster, clock.say)
    clock.seconds.update(grid=grid_s, levels=clock.seconds.pop("levels") - grid_s)
    loops, rest, slopes = cut_pieces(loops, setup, drop)
    if not loops:
        why = f"removes more than rest {params.rest:g} mm of the stock" if params.rest is not None else \
            "meets the part at any level"
        if slopes is not None:
            why = "lies on ground that steep" if rest is None else why + " on ground that steep"
        raise NothingToCut(f"nothing to cut: no loop {why}", "rest" if params.rest is not None else ())
    with clock("verify"):
        tp, report, kept = verified_path([p for _, p in loops], setup.index, tools, kern, setup.safe_z,
                                         params.tolerance, DEFAULT_STEP, setup.rapid_stock, clock.say)
    loops = [(float(p[0, 2]), p) for p in kept]
    summary = waterline_summary(setup, grid, loops, tp, report, rest, slopes)
    clock.seconds["total"] = time.perf_counter() - t_all
    summary["seconds"] = {k: round(v, 4) for k, v in clock.seconds.items()}
    return tp, summary, loops
