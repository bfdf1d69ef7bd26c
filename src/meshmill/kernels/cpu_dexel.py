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

from . import raycast, sweep
from .geom import STACK_SIZE
from .raycast import MAX_HITS

ray = raycast.build(numba.njit(fastmath=False, cache=True))
_cast_bvh_line = ray.cast_bvh_line
_cast_box_line = ray.cast_box_line
_ray_blocked = ray.ray_blocked
LINE_CHUNK = 256


@numba.njit(parallel=True, cache=True)
def _cast_bvh(a, lu, lv, step, nu, nv, cap, node_lo, node_hi, node_child, node_range, tris):
    n_lines = nu * nv
    out = np.zeros((n_lines, cap, 2))
    count = np.zeros(n_lines, np.int64)
    n_chunks = (n_lines + LINE_CHUNK - 1) // LINE_CHUNK
    for c in prange(n_chunks):
        stack = np.empty(STACK_SIZE, np.int32)
        hw = np.empty(MAX_HITS)
        hs = np.empty(MAX_HITS, np.int64)
        for line in range(c * LINE_CHUNK, min(n_lines, (c + 1) * LINE_CHUNK)):
            count[line] = _cast_bvh_line(a, line, lu, lv, step, nv, cap, node_lo, node_hi, node_child, node_range,
                                         tris, stack, hw, hs, out)
    return out, count


@numba.njit(parallel=True, cache=True)
def _cast_boxes(a, lu, lv, step, nu, nv, cap, box_lo, box_hi, box_start, tris):
    n_lines = nu * nv
    out = np.zeros((n_lines, cap, 2))
    count = np.zeros(n_lines, np.int64)
    n_chunks = (n_lines + LINE_CHUNK - 1) // LINE_CHUNK
    for c in prange(n_chunks):
        hw = np.empty(MAX_HITS)
        hs = np.empty(MAX_HITS, np.int64)
        for line in range(c * LINE_CHUNK, min(n_lines, (c + 1) * LINE_CHUNK)):
            count[line] = _cast_box_line(a, line, lu, lv, step, nv, cap, box_lo, box_hi, box_start, tris, hw, hs,
                                         out)
    return out, count


@numba.njit(parallel=True, cache=True)
def _rays_blocked(origins, d, tmin, node_lo, node_hi, node_child, node_range, tris):
    out = np.zeros(origins.shape[0], np.bool_)
    n_chunks = (origins.shape[0] + LINE_CHUNK - 1) // LINE_CHUNK
    for c in prange(n_chunks):
        stack = np.empty(STACK_SIZE, np.int32)
        for i in range(c * LINE_CHUNK, min(origins.shape[0], (c + 1) * LINE_CHUNK)):
            out[i] = _ray_blocked(origins[i, 0], origins[i, 1], origins[i, 2], d[0], d[1], d[2], tmin,
                                  node_lo, node_hi, node_child, node_range, tris, stack)
    return out


def rays_blocked(origins, direction, tmin, bvh):
    """``(k,) bool``: whether the ray from each of ``origins (k, 3)`` along the unit ``direction``
    meets the mesh beyond ``tmin`` mm (``bvh`` is ``BVH.arrays``)."""
    return _rays_blocked(np.ascontiguousarray(origins, np.float64), np.asarray(direction, np.float64),
                         float(tmin), *bvh)


def cast_lines(a, lu, lv, step, nu, nv, index):
    """Material intervals of the ``nu x nv`` lines along axis ``a``.

    ``index`` is ``("bvh", BVH.arrays)`` or ``("boxes", (box_lo, box_hi, box_start, tris))``.
    Returns ``(dense (n_lines, cap, 2), count (n_lines,))``; a negative count marks a line whose
    crossings do not balance (-1) or are too many (-2).
    """
    kind, arrays = index
    fn = _cast_bvh if kind == "bvh" else _cast_boxes
    cap = 4
    while True:
        out, count = fn(a, float(lu), float(lv), float(step), int(nu), int(nv), cap, *arrays)
        need = int(count.max(initial=0))
        if need <= cap:
            return out, count
        cap = need


swp = sweep.build(numba.njit(fastmath=False, cache=True))
_tool_move = swp.tool_move
_capsule = swp.capsule
_flute_plane = swp.flute_plane
_flute_range = swp.flute_range
TILE = 16  # lines a side of the tiles that cutting runs in parallel over
MIN_PIECE = 1e-9  # mm: a dexel piece shorter than this is removed


@numba.njit(cache=True)
def subtract(iv, off, count, line, lo, hi):
    """Remove ``[lo, hi]`` from the sorted intervals of ``line`` (stored in ``iv[off[line]:]``,
    ``count[line]`` of them, room for ``off[line+1] - off[line]``). Returns the length removed, or
    -1 when a split needs more room than the line has (nothing is changed then)."""
    base = off[line]
    n = count[line]
    k = 0
    while k < n and iv[base + k, 1] <= lo:
        k += 1
    if k == n or iv[base + k, 0] >= hi:
        return 0.0
    s = iv[base + k, 0]
    e = iv[base + k, 1]
    if s < lo and e > hi:  # split in two
        if n == off[line + 1] - base:
            return -1.0
        for m in range(n, k + 1, -1):
            iv[base + m, 0] = iv[base + m - 1, 0]
            iv[base + m, 1] = iv[base + m - 1, 1]
        iv[base + k, 1] = lo
        iv[base + k + 1, 0] = hi
        iv[base + k + 1, 1] = e
        count[line] = n + 1
        return hi - lo
    removed = 0.0
    keep = k
    trimmed = s < lo
    if trimmed:
        removed += e - lo
        iv[base + k, 1] = lo
        keep = k + 1
        k += 1
    j = k
    while j < n and iv[base + j, 1] <= hi:
        removed += iv[base + j, 1] - iv[base + j, 0]
        j += 1
    if j < n and iv[base + j, 0] < hi:
        removed += hi - iv[base + j, 0]
        iv[base + j, 0] = hi
    # drop slivers at the cut, then close the gap
    if trimmed and iv[base + keep - 1, 1] - iv[base + keep - 1, 0] < MIN_PIECE:
        removed += iv[base + keep - 1, 1] - iv[base + keep - 1, 0]
        keep -= 1
    if j < n and iv[base + j, 1] - iv[base + j, 0] < MIN_PIECE:
        removed += iv[base + j, 1] - iv[base + j, 0]
        j += 1
    shift = j - keep
    if shift > 0:
        for m in range(j, n):
            iv[base + m - shift, 0] = iv[base + m, 0]
            iv[base + m - shift, 1] = iv[base + m, 1]
        count[line] = n - shift
    return removed


@numba.njit(cache=True)
def material_outside(iv, base, n, a, b, lo, hi):
    """Whether the line's intervals ``iv[base:base+n]`` hold material in ``[a, b]`` outside
    ``[lo, hi]`` (an empty ``[lo, hi]``, lo > hi, excludes nothing)."""
    if a > b:
        return False
    for k in range(base, base + n):
        s = max(iv[k, 0], a)
        e = min(iv[k, 1], b)
        if s >= e:
            continue
        if lo > hi or s < lo or e > hi:
            return True
    return False


@numba.njit(cache=True)
def _line_range(lo, hi, l0, step, n):
    i0 = max(0, int(math.ceil((lo - l0) / step - 0.5)))
    i1 = min(n - 1, int(math.floor((hi - l0) / step - 0.5)))
    return i0, i1


@numba.njit(cache=True)
def bin_moves(box, lu, lv, step, nu, nv):
    """Tiles of ``TILE x TILE`` lines and, per tile, the moves whose box ``(k, 6)`` (ulo, uhi,
    vlo, vhi, wlo, whi) covers one of its lines, in move order: ``(tile_start, tile_moves)``."""
    tu = (nu + TILE - 1) // TILE
    tv = (nv + TILE - 1) // TILE
    cnt = np.zeros(tu * tv + 1, np.int64)
    for m in range(box.shape[0]):
        i0, i1 = _line_range(box[m, 0], box[m, 1], lu, step, nu)
        j0, j1 = _line_range(box[m, 2], box[m, 3], lv, step, nv)
        if i0 > i1 or j0 > j1:
            continue
        for ti in range(i0 // TILE, i1 // TILE + 1):
            for tj in range(j0 // TILE, j1 // TILE + 1):
                cnt[ti * tv + tj + 1] += 1
    for t in range(tu * tv):
        cnt[t + 1] += cnt[t]
    fill = cnt[:-1].copy()
    moves = np.empty(cnt[-1], np.int64)
    for m in range(box.shape[0]):
        i0, i1 = _line_range(box[m, 0], box[m, 1], lu, step, nu)
        j0, j1 = _line_range(box[m, 2], box[m, 3], lv, step, nv)
        if i0 > i1 or j0 > j1:
            continue
        for ti in range(i0 // TILE, i1 // TILE + 1):
            for tj in range(j0 // TILE, j1 // TILE + 1):
                t = ti * tv + tj
                moves[fill[t]] = m
                fill[t] += 1
    return cnt, moves


@numba.njit(parallel=True, cache=True)
def cut_tiles(lu, lv, step, nu, nv, iv, off, count, tiles, tile_start, tile_moves,
              pa, pb, xa, xb, radius, corner, flutes, strips, box, rapid, rapid_min, rapid_hit, overflow):
    """Cut the lines of the given ``tiles`` with their moves, in move order within each line.

    Moves ``pa, pb, xa, xb (k, 3)`` tips and unit axes in the line frame, ``radius, corner,
    flutes (k,)`` the cutter, ``strips (k,)`` how finely a turning ball-end's flutes are swept, ``box (k, 6)`` bounds. Sets ``rapid_hit[m]`` when a rapid move
    removes more than ``rapid_min`` mm of a dexel, and ``overflow[t]`` when a line of tile t ran out
    of room: the tile stops there, so rerunning it after growing the line is exact (removal is
    idempotent, and moves before the stop saw the material in path order)."""
    tv = (nv + TILE - 1) // TILE
    for q in prange(tiles.shape[0]):
        t = tiles[q]
        ti = t // tv
        tj = t % tv
        for s in range(tile_start[t], tile_start[t + 1]):
            if overflow[t]:
                break  # the tile stops at the move that overflowed; it is run again with more room
            m = tile_moves[s]
            i0, i1 = _line_range(box[m, 0], box[m, 1], lu, step, nu)
            j0, j1 = _line_range(box[m, 2], box[m, 3], lv, step, nv)
            i0 = max(i0, ti * TILE)
            i1 = min(i1, ti * TILE + TILE - 1)
            j0 = max(j0, tj * TILE)
            j1 = min(j1, tj * TILE + TILE - 1)
            wlo = box[m, 4]
            whi = box[m, 5]
            pam = pa[m]
            pbm = pb[m]
            xam = xa[m]
            xbm = xb[m]
            rm = radius[m]
            cm = corner[m]
            fm = flutes[m]
            sm = strips[m]
            ball = cm >= rm
            # ball-end: the ball's centre chord, and the plane that bounds where the flutes reach
            cau = pam[0] + cm * xam[0]
            cav = pam[1] + cm * xam[1]
            caw = pam[2] + cm * xam[2]
            cbu = pbm[0] + cm * xbm[0]
            cbv = pbm[1] + cm * xbm[1]
            cbw = pbm[2] + cm * xbm[2]
            f_u, f_v, f_w, f_k = _flute_plane(pam, pbm, xam, xbm, cm, fm)
            for i in range(i0, i1 + 1):
                u0 = lu + (i + 0.5) * step
                for j in range(j0, j1 + 1):
                    line = i * nv + j
                    n = count[line]
                    if n == 0:
                        continue
                    base = off[line]
                    if iv[base, 0] >= whi or iv[base + n - 1, 1] <= wlo:
                        continue
                    v0 = lv + (j + 0.5) * step
                    if ball:
                        # the ball alone, unless material lies where only the flutes reach
                        lo, hi = _capsule(u0, v0, cau, cav, caw, cbu, cbv, cbw, cm)
                        flo, fhi = _flute_range(u0, v0, f_u, f_v, f_w, f_k)
                        if material_outside(iv, base, n, max(flo, wlo), min(fhi, whi), lo, hi):
                            lo, hi = _tool_move(u0, v0, pam, pbm, xam, xbm, rm, cm, fm, sm)
                    else:
                        lo, hi = _tool_move(u0, v0, pam, pbm, xam, xbm, rm, cm, fm, sm)
                    if lo >= hi:
                        continue
                    removed = subtract(iv, off, count, line, lo, hi)
                    if removed < 0.0:
                        overflow[t] = 1
                        break
                    elif removed > rapid_min and rapid[m]:
                        rapid_hit[m] = 1
