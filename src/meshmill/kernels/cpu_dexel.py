"""CPU backend of the dexel kernels: casting grid lines through a mesh, cutting dexels with
swept tools. Parallel over lines (``prange`` over chunks of lines, one thread a chunk).

A grid of lines along axis ``a`` has ``nu x nv`` lines; line ``(i, j)`` (id ``i*nv + j``) passes
through ``u = lo_u + (i + 1/2) step``, ``v = lo_v + (j + 1/2) step`` (u, v as in
:mod:`meshmill.kernels.raycast`). Intervals are ``(start, end)`` coordinates along ``a``, mm.
"""
from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

from . import carve, raycast, sweep
from .carve import BODY, TILE
from .cpu import clr, device
from .geom import STACK_SIZE
from .raycast import MAX_HITS

ray = raycast.build(device)
swp = sweep.build(device)
crv = carve.build(device, numba.njit(fastmath=False, cache=True, inline="always"))
subtract = crv.subtract
material_outside = crv.material_outside
LINE_CHUNK = 256  # lines cast in order by one thread
SOLID_CHUNK = 8  # lines decided point by point in order by one thread (a few cost most)
SOLID_ROOM = 1 << 24  # bytes of intervals those lines start with (a line with more is decided again)


@numba.njit(parallel=True, cache=True)
def _solid_lines(a, lines, line0, lu, lv, step, nv, cap, node_lo, node_hi, node_child, node_range, tris,
                 in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor):
    k = lines.shape[0]
    out = np.zeros((k, cap, 2))
    count = np.zeros(k, np.int64)
    uneven = np.zeros(k, np.bool_)
    u, v = (a + 1) % 3, (a + 2) % 3
    for c in prange((k + SOLID_CHUNK - 1) // SOLID_CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        hw = np.empty(MAX_HITS)
        hs = np.empty(MAX_HITS, np.int64)
        p = np.empty(3)
        for i in range(c * SOLID_CHUNK, min(k, (c + 1) * SOLID_CHUNK)):
            p[u] = lu + ((line0 + lines[i]) // nv + 0.5) * step
            p[v] = lv + ((line0 + lines[i]) % nv + 0.5) * step
            m = ray.bvh_line_hits(a, p[u], p[v], node_lo, node_hi, node_child, node_range, tris, stack, hw, hs)
            if m > MAX_HITS:
                count[i] = -2
                continue
            ray.sort_hits(hw, hs, m)
            depth = 0
            for j in range(m):
                depth -= hs[j]
                if depth < 0:
                    uneven[i] = True
            uneven[i] = uneven[i] or depth != 0
            d = 0  # the distinct crossings, kept at the front of hw
            for j in range(m):
                if d == 0 or hw[j] - hw[d - 1] > 1e-9:  # (else the same crossing: an edge or vertex of two faces)
                    hw[d] = hw[j]
                    d += 1
            for j in range(d - 1):  # the material between two crossings, where it cannot change
                p[a] = 0.5 * (hw[j] + hw[j + 1])
                hs[j] = clr.inside(p[0], p[1], p[2], in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor, stack)
            n = 0
            j = 0
            while j < d - 1:
                if hs[j] == 0:
                    j += 1
                    continue
                e = j
                while e + 1 < d - 1 and hs[e + 1] != 0:
                    e += 1
                if n < cap:
                    out[i, n, 0] = hw[j]
                    out[i, n, 1] = hw[e + 1]
                n += 1
                j = e + 1
            count[i] = n
    return out, count, uneven


def solid_lines(a, lines, lu, lv, step, nv, bvh, inside, first_row=0):
    """The material of the solid ``inside`` holds (a :attr:`~meshmill.geometry.solid.Solid.inside`:
    the winding of its closed pieces and caps, the parity of its sheets) on the grid ``lines``
    (ids ``i*nv + j`` from the lattice row ``first_row``) along axis ``a``: decided between every
    two crossings of its check mesh (``bvh``: its BVH arrays), where it cannot change, by the
    inside test at their middle. ``(dense (k, cap, 2), count (k,), uneven (k,) bool)``: the
    intervals, their count (-2: more crossings than a line holds), and the lines whose crossings
    do not balance by the mesh's winding (shells that intersect or are wound inside out)."""
    in_bvh, kind, floor = inside[:5], inside[5], inside[6]
    lines = np.ascontiguousarray(lines, np.int64)

    def run(which, cap):
        return _solid_lines(int(a), which, int(first_row) * int(nv), float(lu), float(lv), float(step), int(nv), cap,
                            *bvh, *in_bvh, np.ascontiguousarray(kind, np.int8), float(floor))

    cap = max(4, min(32, SOLID_ROOM // (16 * max(1, len(lines)))))
    out, count, uneven = run(lines, cap)
    over = np.nonzero(count > cap)[0]  # lines with more intervals than that: again, with room for them
    if len(over):
        more, count[over], _ = run(lines[over], int(count[over].max()))
        out = np.concatenate([out, np.zeros((len(out), more.shape[1] - cap, 2))], axis=1)
        out[over] = more
    return out, count, uneven


@numba.njit(parallel=True, cache=True)
def _cast_bvh(a, line0, lu, lv, step, nu, nv, cap, node_lo, node_hi, node_child, node_range, tris):
    n_lines = nu * nv
    out = np.zeros((n_lines, cap, 2))
    count = np.zeros(n_lines, np.int64)
    n_chunks = (n_lines + LINE_CHUNK - 1) // LINE_CHUNK
    for c in prange(n_chunks):
        stack = np.empty(STACK_SIZE, np.int32)
        hw = np.empty(MAX_HITS)
        hs = np.empty(MAX_HITS, np.int64)
        for line in range(c * LINE_CHUNK, min(n_lines, (c + 1) * LINE_CHUNK)):
            count[line] = ray.cast_bvh_line(a, line, line0, lu, lv, step, nv, cap, node_lo, node_hi, node_child,
                                            node_range, tris, stack, hw, hs, out)
    return out, count


@numba.njit(parallel=True, cache=True)
def _cast_boxes(a, line0, lu, lv, step, nu, nv, cap, box_lo, box_hi, box_start, tris):
    n_lines = nu * nv
    out = np.zeros((n_lines, cap, 2))
    count = np.zeros(n_lines, np.int64)
    n_chunks = (n_lines + LINE_CHUNK - 1) // LINE_CHUNK
    for c in prange(n_chunks):
        hw = np.empty(MAX_HITS)
        hs = np.empty(MAX_HITS, np.int64)
        for line in range(c * LINE_CHUNK, min(n_lines, (c + 1) * LINE_CHUNK)):
            count[line] = ray.cast_box_line(a, line, line0, lu, lv, step, nv, cap, box_lo, box_hi, box_start, tris,
                                            hw, hs, out)
    return out, count


def cast_lines(a, lu, lv, step, nu, nv, index, first_row=0):
    """Material intervals of the ``nu x nv`` lines along axis ``a``, from the row ``first_row``
    of a lattice from ``(lu, lv)`` (a block of its rows, cast as the whole lattice casts them).

    ``index`` is ``("bvh", BVH.arrays)`` or ``("boxes", (box_lo, box_hi, box_start, tris))``.
    Returns ``(dense (n_lines, cap, 2), count (n_lines,))``; a negative count marks a line whose
    crossings do not balance (-1) or are too many (-2).
    """
    kind, arrays = index
    fn = _cast_bvh if kind == "bvh" else _cast_boxes
    cap = 4
    while True:
        out, count = fn(a, int(first_row) * int(nv), float(lu), float(lv), float(step), int(nu), int(nv), cap, *arrays)
        need = int(count.max(initial=0))
        if need <= cap:
            return out, count
        cap = need


@numba.njit(cache=True)
def bin_moves(box, lu, lv, step, nu, nv):
    """Tiles of ``TILE x TILE`` lines and, per tile, the moves whose box ``(k, 6)`` (ulo, uhi,
    vlo, vhi, wlo, whi) covers one of its lines, in move order: ``(tile_start, tile_moves,
    work)``, ``work (tiles,)`` the lines of the tile its moves' boxes cover, added over the moves
    (what cutting the tile costs, roughly)."""
    tu = (nu + TILE - 1) // TILE
    tv = (nv + TILE - 1) // TILE
    cnt = np.zeros(tu * tv + 1, np.int64)
    for m in range(box.shape[0]):
        i0, i1, j0, j1 = crv.move_lines(box, m, lu, lv, step, nu, nv)
        if i0 > i1 or j0 > j1:
            continue
        for ti in range(i0 // TILE, i1 // TILE + 1):
            for tj in range(j0 // TILE, j1 // TILE + 1):
                cnt[ti * tv + tj + 1] += 1
    for t in range(tu * tv):
        cnt[t + 1] += cnt[t]
    fill = cnt[:-1].copy()
    moves = np.empty(cnt[-1], np.int64)
    work = np.zeros(tu * tv)
    for m in range(box.shape[0]):
        i0, i1, j0, j1 = crv.move_lines(box, m, lu, lv, step, nu, nv)
        if i0 > i1 or j0 > j1:
            continue
        for ti in range(i0 // TILE, i1 // TILE + 1):
            rows = min(i1, ti * TILE + TILE - 1) - max(i0, ti * TILE) + 1
            for tj in range(j0 // TILE, j1 // TILE + 1):
                t = ti * tv + tj
                moves[fill[t]] = m
                fill[t] += 1
                work[t] += rows * (min(j1, tj * TILE + TILE - 1) - max(j0, tj * TILE) + 1)
    return cnt, moves, work


@numba.njit(cache=True)
def _dist(p, q):
    """Distance between points ``p, q (3,)``."""
    return math.sqrt((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2)


@numba.njit(cache=True)
def _seg_dist(p, a, b):
    """Distance (mm) from point ``p (3,)`` to the segment a-b."""
    d0, d1, d2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    q0, q1, q2 = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    dd = d0 * d0 + d1 * d1 + d2 * d2
    t = 0.0 if dd <= 0.0 else min(1.0, max(0.0, (q0 * d0 + q1 * d1 + q2 * d2) / dd))
    return math.sqrt((q0 - t * d0) ** 2 + (q1 - t * d1) ** 2 + (q2 - t * d2) ** 2)


@numba.njit(cache=True)
def _group_bound(ca, cb, xa, xb, sag, H, first, last):
    """The axis (unit, the mean of moves ``first..last``'s) and how far past the parallelogram
    from their first chord end to the last's second, spanned by H times that axis, any point of
    their tools' axes lies (see :func:`group_moves`)."""
    X = np.zeros(3)
    for m in range(first, last + 1):
        X += xa[m] + xb[m]
    X /= math.sqrt(X[0] ** 2 + X[1] ** 2 + X[2] ** 2)
    dev = 0.0
    tilt = 0.0
    for m in range(first, last + 1):
        dev = max(dev, max(_seg_dist(ca[m], ca[first], cb[last]), _seg_dist(cb[m], ca[first], cb[last])) + sag[m])
        far = max(_dist(xa[m], X), _dist(xb[m], X))
        if far >= math.sqrt(2.0):  # past 90 degrees from X: the arc between may reach farther
            far += _dist(xa[m], xb[m])
        tilt = max(tilt, far)
    return X, dev + H[first] * tilt


@numba.njit(cache=True)
def group_moves(ca, cb, xa, xb, sag, H, radius, limit, most):
    """Consecutive moves gathered in groups whose cuts one bound holds, so that a line with no
    material in it skips them all. Move m's tool at each pose lies within ``radius[m]`` of its
    axis from the ball centre up ``H[m]``; the centre lies within ``sag[m]`` of the chord ``ca[m]
    -> cb[m] (3,)`` and the axis between ``xa[m]`` and ``xb[m]`` (unit). A group's parallelogram
    runs from its first ``ca`` to its last ``cb``, spanned by H times its mean axis X: a point h up
    an axis lies within its centre's distance to the group's chord plus ``h |x - X|`` of it (the
    axes of a move on the arc between its two, no farther from X than those where they lie within
    90 degrees of X: such a cap is convex; else farther by the chord between them at most). A
    group takes the most moves from its first, up to ``most`` and halving, whose growth stays
    within ``limit`` mm. Returns ``(group (k,), bound (g, 10))``:
    each move's group (-1: alone) and each group's corner, spans and radius (the tool's plus the
    growth; as :func:`meshmill.kernels.carve.group_clear` reads them)."""
    k = ca.shape[0]
    group = np.full(k, -1, np.int64)
    bound = np.empty((k, 10))
    g = 0
    i = 0
    while i < k:
        # the most moves from i on that keep within the limit, halving from ``most``
        size = min(most, k - i)
        X = np.zeros(3)
        gr = 0.0
        while size > 1:
            X, gr = _group_bound(ca, cb, xa, xb, sag, H, i, i + size - 1)
            if gr <= limit:
                break
            size //= 2
        if size > 1:
            j = i + size - 1
            group[i:j + 1] = g
            for c in range(3):
                bound[g, c] = ca[i, c]
                bound[g, 3 + c] = cb[j, c] - ca[i, c]
                bound[g, 6 + c] = H[i] * X[c]
            bound[g, 9] = radius[i] + gr * (1.0 + 1e-9) + 1e-9
            g += 1
        i += size
    return group, bound[:g].copy()


@numba.njit(parallel=True, cache=True)
def move_constants(pa, pb, xa, xb, corner, flutes):
    """Per move, what every line it crosses needs: ``chord (k, 6)``, ``plane (k, 4)`` (see
    :mod:`meshmill.kernels.carve`)."""
    k = pa.shape[0]
    chord = np.empty((k, 6))
    plane = np.empty((k, 4))
    for m in prange(k):
        crv.move_constants(m, pa, pb, xa, xb, corner, flutes, chord, plane)
    return chord, plane


@numba.njit(cache=True)
def _tile_lines(box, m, lu, lv, step, nu, nv, ti, tj, comb, split):
    """``(i0, i1, j0, j1)``: the lines of tile (ti, tj) on rows ``comb (mod split)`` that
    ``box[m]`` covers (the rows from i0 by ``split``)."""
    i0, i1, j0, j1 = crv.move_lines(box, m, lu, lv, step, nu, nv)
    i0 = max(i0, ti * TILE)
    i0 += (comb - i0) % split
    return i0, min(i1, ti * TILE + TILE - 1), max(j0, tj * TILE), min(j1, tj * TILE + TILE - 1)


SPREAD = 64  # work items a thread is given at least: a call with fewer cuts them in finer combs of rows


def cut_tiles(lu, lv, step, nu, nv, iv, off, count, tiles, combs, split, tile_start, tile_moves,
              pa, pb, xa, xb, radius, corner, flutes, strips, chord, plane, box, kind, group, gbound, gbox,
              hit_min, hit, todo, redo, row0, probe, load):
    """Cut the lines of the given items, each the rows ``i = combs[q] (mod split)`` of tile
    ``tiles[q]`` (``split`` a power of two up to :data:`~meshmill.kernels.carve.TILE`; 1: whole
    tiles), with their moves, in move order within each line.

    Moves as in :mod:`meshmill.kernels.carve`, ``box (k, 6)`` their bounds, ``kind (k,)`` bits
    :data:`~meshmill.kernels.carve.RAPID` and :data:`~meshmill.kernels.carve.BODY`. Sets ``hit[m]``
    when a move removes more than ``hit_min`` mm of a dexel (a rapid that cuts; a feed move in
    material, not in air) or a body move (shank, holder: it removes nothing) meets that much
    material, and ``redo[line] = s + 1`` when a line ran out of room at the tile's move ``s`` (an
    index of ``tile_moves``): the line stops there (the others go on), so cutting it again from
    that move after growing it is exact (the moves before the stop saw the material in path
    order). ``group (k,)``: each move's group (-1: none; see
    :func:`group_moves`; the moves of a group follow one another among those cutting),
    ``gbound (g, 10)`` and ``gbox (g, 6)`` their bounds in the line frame: a
    line with no material in a group's bound (:func:`meshmill.kernels.carve.group_clear`) skips
    its moves (they would remove nothing). ``todo (lines,) int64``: the lines to cut (those
    set, from the tile's move ``todo - 1`` on: a ``redo`` of before; empty: every line of the
    items, from the first move). ``iv, off, count`` may hold the lines from row ``row0``
    on only (a block of rows: the tiles given must lie in it; ``todo`` and ``redo`` are
    numbered as ``count``). With ``probe (k, 6)`` (each move's axis and unit vector across its
    feed in the line frame; ``(0, 6)``: not measured), ``load (T, k, 5)`` gathers per thread and
    move the length removed from these lines, the highest point along the axis, the extent
    across the feed and the lowest point along the axis of what it removed (see
    :mod:`meshmill.simulation.load`). A few items are cut in finer combs (each line still in one,
    its moves in order), so that every thread has work to the end."""
    f = 1
    while split * f < TILE and len(tiles) * f < SPREAD * numba.get_num_threads():
        f *= 2
    # item (t, c) of split s -> (t, c + s r) of split s f, r < f; the copies of an item apart in the range
    tiles_f = np.tile(np.asarray(tiles, np.int64), f)
    combs_f = np.tile(np.asarray(combs, np.int64), f) + split * np.repeat(np.arange(f, dtype=np.int64), len(tiles))
    _cut_tiles(lu, lv, step, nu, nv, iv, off, count, tiles_f, combs_f, split * f, tile_start, tile_moves, pa, pb, xa,
               xb, radius, corner, flutes, strips, chord, plane, box, kind, group, gbound, gbox, hit_min, hit, todo,
               redo, row0, probe, load)


@numba.njit(cache=True, inline="always")
def _line_extent(iv, off, count, line):
    """``(start, end)`` of the material of ``line`` (its first interval's start, its last's end;
    inf, -inf: none)."""
    n = count[line]
    if n == 0:
        return np.inf, -np.inf
    return iv[off[line], 0], iv[off[line] + n - 1, 1]


@numba.njit(parallel=True, cache=True)
def _cut_tiles(lu, lv, step, nu, nv, iv, off, count, tiles, combs, split, tile_start, tile_moves,
               pa, pb, xa, xb, radius, corner, flutes, strips, chord, plane, box, kind, group, gbound, gbox,
               hit_min, hit, todo, redo, row0, probe, load):
    tv = (nv + TILE - 1) // TILE
    measure = probe.shape[0] > 0
    some = todo.shape[0] > 0
    for q in prange(tiles.shape[0]):
        me = numba.get_thread_id() if measure else 0
        t = tiles[q]
        ti = t // tv
        tj = t % tv
        comb = combs[q]  # the rows i = comb (mod split)
        # per line of the tile, the last group tested on it and whether it was clear (material only
        # goes, so the line stays so for the group's later moves)
        tested = np.full(TILE * TILE, -1, np.int64)
        clear_at = np.zeros(TILE * TILE, np.bool_)
        # where the material of each line of the item starts and ends (kept as the item's moves
        # cut it; material only goes, so a value not yet updated holds it still), and of each
        # row's lines together (made when a move first needs it, and again after one of its lines
        # was cut): a move skips the rows and lines whose material lies outside its box along the
        # lines (most of those a shank or holder covers), which
        # :func:`~meshmill.kernels.carve.cut_line` and ``touch_line`` would find at their first
        # test, reading the line's intervals
        ext_lo = np.full(TILE * TILE, np.inf)
        ext_hi = np.full(TILE * TILE, -np.inf)
        row_lo = np.empty(TILE)
        row_hi = np.empty(TILE)
        stale = np.ones(TILE, np.bool_)
        for i in range(ti * TILE + (comb - ti * TILE) % split, min(nu, ti * TILE + TILE), split):
            for j in range(tj * TILE, min(nv, tj * TILE + TILE)):
                at = (i - ti * TILE) * TILE + j - tj * TILE
                ext_lo[at], ext_hi[at] = _line_extent(iv, off, count, (i - row0) * nv + j)
        for s in range(tile_start[t], tile_start[t + 1]):
            m = tile_moves[s]
            g = group[m]
            body = kind[m] & BODY
            if body and hit[m]:
                continue
            wlo = box[m, 4]
            whi = box[m, 5]
            i0, i1, j0, j1 = _tile_lines(box, m, lu, lv, step, nu, nv, ti, tj, comb, split)
            for i in range(i0, i1 + 1, split):
                r = i - ti * TILE
                if stale[r]:
                    stale[r] = False
                    row_lo[r] = np.inf
                    row_hi[r] = -np.inf
                    for at in range(r * TILE, r * TILE + TILE):
                        row_lo[r] = min(row_lo[r], ext_lo[at])
                        row_hi[r] = max(row_hi[r], ext_hi[at])
                if row_lo[r] >= whi or row_hi[r] <= wlo:
                    continue
                u0 = lu + (i + 0.5) * step
                for j in range(j0, j1 + 1):
                    line = (i - row0) * nv + j
                    if redo[line] > 0 or (some and (todo[line] == 0 or s < todo[line] - 1)):
                        continue
                    at = r * TILE + j - tj * TILE
                    if ext_lo[at] >= whi or ext_hi[at] <= wlo:
                        continue
                    v0 = lv + (j + 0.5) * step
                    if g >= 0:
                        if tested[at] != g:
                            tested[at] = g
                            clear_at[at] = crv.group_clear(g, line, u0, v0, iv, off, count, gbound, gbox)
                        if clear_at[at]:
                            continue
                    if body:
                        if crv.touch_line(m, line, u0, v0, wlo, whi, iv, off, count, pa, pb, xa, xb, radius, corner,
                                          flutes, strips) > hit_min:
                            hit[m] = 1
                            break
                        continue
                    removed, first, last = crv.cut_line(m, line, u0, v0, wlo, whi, iv, off, count,
                                                        pa, pb, xa, xb, radius, corner, flutes, strips, chord, plane,
                                                        measure)
                    if removed < 0.0:
                        redo[line] = s + 1
                    elif removed > 0.0:
                        ext_lo[at], ext_hi[at] = _line_extent(iv, off, count, line)
                        stale[r] = True
                        if removed > hit_min:
                            hit[m] = 1
                            if measure:
                                ax_lo, ax_hi, lat_lo, lat_hi = crv.load_extents(m, u0, v0, first, last, probe)
                                load[me, m, 0] += removed
                                load[me, m, 1] = max(load[me, m, 1], ax_hi)
                                load[me, m, 2] = min(load[me, m, 2], lat_lo)
                                load[me, m, 3] = max(load[me, m, 3], lat_hi)
                                load[me, m, 4] = min(load[me, m, 4], ax_lo)
                if body and hit[m]:
                    break
