"""CUDA backend: the same device functions as the CPU (:mod:`meshmill.kernels.geom`,
:mod:`~meshmill.kernels.cutters`, :mod:`~meshmill.kernels.raycast`,
:mod:`~meshmill.kernels.carve`), compiled with ``numba.cuda.jit(device=True)`` and run one thread
per independent item (point, pose, contour, grid line). The functions mirror those of
:mod:`meshmill.kernels.cpu` and take and return host numpy arrays; the mesh (``bvh``) is the tuple
of device arrays from :func:`to_device`, copied once per operation and kept on the GPU.

Imported only when asked for (it needs numba's CUDA target: a GPU, or ``NUMBA_ENABLE_CUDASIM=1``,
the simulator the parity tests use). Optional dependency: ``pip install meshmill[cuda]``.
"""
from __future__ import annotations

import math

import numba
import numpy as np
from numba import cuda, float64, int32, int64

from . import carve, clearance, cutters, raycast
from .carve import BODY, TILE
from .clearance import WORK_SIZE
from .cutters import NO_BODY
from .geom import SEEN_SIZE, STACK_SIZE, build
from .raycast import MAX_HITS

numba.config.CUDA_LOW_OCCUPANCY_WARNINGS = 0  # small launches (a contour a thread, a few tiles) are expected
device = cuda.jit(device=True)
dev = build(device)
cut = cutters.build(device)
ray = raycast.build(device)
crv = carve.build(device)
clr = clearance.build(device)
THREADS = 128
CHUNK = 4  # points of a drop-cutter batch run in order by one thread (fewer than the CPU's: more threads)


def _blocks(n, threads=THREADS):
    return max(1, (n + threads - 1) // threads)


def _grid(n):
    """``(blocks, threads)`` of a launch of ``n`` threads: blocks of THREADS, or one block of whole
    warps when fewer (no idle threads for numba's simulator to interpret)."""
    threads = min(THREADS, 32 * _blocks(n, 32))
    return _blocks(n, threads), threads


class Staging:
    """Device buffers kept from call to call, one per kernel argument (``key``), dtype and shape
    past the first axis: a call copies its host arrays into them and reads its results back from
    them, with no allocation or free on the GPU (numba-cuda's frees wait for the device: 1.4 s of a
    7 s finish on an H200, its allocations 1.0 s). A buffer grows to 1.25 times what it must hold.
    Results are copied to the host before a call returns, so the next call may reuse them; one
    host thread drives the kernels."""

    def __init__(self):
        self.bufs = {}

    def empty(self, key, shape, dtype=np.float64):
        """A device array of ``shape`` and ``dtype`` (its contents left from earlier calls)."""
        shape = tuple(int(n) for n in shape)
        if not shape or shape[0] == 0:
            return cuda.device_array(shape, dtype)
        key = (key, np.dtype(dtype).str, shape[1:])
        buf = self.bufs.get(key)
        if buf is None or buf.shape[0] < shape[0]:
            buf = cuda.device_array((shape[0] + shape[0] // 4,) + shape[1:], dtype)
            self.bufs[key] = buf
        return buf[:shape[0]]

    def put(self, key, a, dtype=np.float64):
        """The host array ``a`` (as contiguous ``dtype``) in the buffer of ``key``."""
        a = np.ascontiguousarray(a, dtype)
        if a.ndim == 0 or a.shape[0] == 0:
            return cuda.to_device(a)
        view = self.empty(key, a.shape, dtype)
        view.copy_to_device(a)
        return view

    def zeros(self, key, shape, dtype=np.float64):
        return self.put(key, np.zeros(shape, dtype), dtype)


STAGE = Staging()


def _s(name, *arrays, dtype=np.float64):
    """``arrays`` staged under the keys ``name0``, ``name1``, ..."""
    return tuple(STAGE.put(f"{name}{i}", a, dtype) for i, a in enumerate(arrays))


def to_device(bvh):
    """Copy ``BVH.arrays`` to the GPU once; the result goes where ``bvh`` arrays are expected."""
    return tuple(cuda.to_device(np.ascontiguousarray(a)) for a in bvh.arrays)


def inside_to_device(inside):
    """Copy a :attr:`~meshmill.geometry.solid.Solid.inside` tuple to the GPU once (the floor stays a number)."""
    *arrays, kind, floor = inside
    return (*(cuda.to_device(np.ascontiguousarray(a)) for a in arrays), cuda.to_device(np.ascontiguousarray(kind, np.int8)),
            float(floor))


@cuda.jit
def _mesh_distances(p, cap2, node_lo, node_hi, node_child, node_range, tris, out):
    i = cuda.grid(1)
    if i < p.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        out[i] = math.sqrt(dev.mesh_point_dist2(p[i, 0], p[i, 1], p[i, 2], cap2, 0.0,
                                                node_lo, node_hi, node_child, node_range, tris, stack))


def mesh_distances(points, bvh, cap=1e150):
    """As :func:`meshmill.kernels.cpu.mesh_distances`."""
    cap = min(cap, 1e150)
    out = STAGE.empty("md.out", (len(points),))
    _mesh_distances[_grid(len(points))](*_s("md", points), cap * cap, *bvh, out)
    return out.copy_to_host()


@cuda.jit
def _largest_ball(cc, nrm, radii, tol, node_lo, node_hi, node_child, node_range, tris, out):
    i = cuda.grid(1)
    if i < cc.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        out[i] = dev.largest_clear_ball(cc[i, 0], cc[i, 1], cc[i, 2], nrm[i, 0], nrm[i, 1], nrm[i, 2], radii, tol,
                                        node_lo, node_hi, node_child, node_range, tris, stack)


def largest_ball(cc, normals, radii, tol, bvh):
    """As :func:`meshmill.kernels.cpu.largest_ball`."""
    out = STAGE.empty("lb.out", (len(cc),), np.int32)
    _largest_ball[_grid(len(cc))](*_s("lb", cc, normals, radii), float(tol), *bvh, out)
    return out.copy_to_host()


@cuda.jit
def _axis_search(ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r, node_lo, node_hi, node_child, node_range,
                 tris, out):
    i = cuda.grid(1)
    if i < ce.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        seen = cuda.local.array(SEEN_SIZE, float64)
        out[i] = dev.first_clear_axis(i, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                                      node_lo, node_hi, node_child, node_range, tris, stack, seen, 0)[0]


@cuda.jit
def _keep_previous(choice, offsets, cand_tilt, slack, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                   node_lo, node_hi, node_child, node_range, tris):
    k = cuda.grid(1)
    if k < offsets.shape[0] - 1:
        stack = cuda.local.array(STACK_SIZE, int32)
        dev.keep_previous_axes(offsets[k], offsets[k + 1], choice, cand_tilt, slack, ce, f, s, tool, cand, radius,
                               seg_t0, seg_t1, seg_r, node_lo, node_hi, node_child, node_range, tris, stack)


def axis_search(ce, feed, side, tool, candidates, cand_tilt, slack, radius, body, offsets, bvh):
    """As :func:`meshmill.kernels.cpu.axis_search`: one thread per point, then one per contour."""
    args = (*_s("as", ce, feed, side), STAGE.put("as.tool", tool, np.int32), *_s("asc", candidates, radius, *body))
    choice = STAGE.empty("as.out", (len(ce),), np.int32)
    _axis_search[_grid(len(ce))](*args, *bvh, choice)
    n_contours = len(offsets) - 1
    _keep_previous[_grid(n_contours)](choice, STAGE.put("as.off", offsets, np.int64),
                                      STAGE.put("as.tilt", cand_tilt), float(slack), *args, *bvh)
    return choice.copy_to_host()


@cuda.jit
def _pose_penetration(tip, axis, tool, grow, ring_t, ring_rho, ring_r, ring_n, seg_t0, seg_t1, seg_r, seg_base,
                      node_lo, node_hi, node_child, node_range, tris, in_lo, in_hi, in_child, in_range, in_tris,
                      in_kind, floor, stop, ring, segs):
    i = cuda.grid(1)
    if i < tip.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        clr.pose_depth(i, tip, axis, tool, grow, ring_t, ring_rho, ring_r, ring_n, seg_t0, seg_t1, seg_r, seg_base,
                       node_lo, node_hi, node_child, node_range, tris, in_lo, in_hi, in_child, in_range, in_tris,
                       in_kind, floor, stop, stack, ring, segs)


def pose_penetration(tip, axis, tool, grow, rings, segs, base, bvh, inside, stop=-1.0):
    """As :func:`meshmill.kernels.cpu.pose_penetration` (``inside`` from :func:`inside_to_device`)."""
    k = len(tip)
    ring = STAGE.zeros("pp.ring", (k,))
    depth = STAGE.zeros("pp.depth", (k, np.shape(segs[2])[1]))
    ring_t, ring_rho, ring_r, ring_n = rings
    _pose_penetration[_grid(k)](*_s("pp", tip, axis), STAGE.put("pp.tool", tool, np.int32),
                                *_s("ppg", grow, ring_t, ring_rho, ring_r),
                                STAGE.put("pp.n", ring_n, np.asarray(ring_n).dtype),
                                *_s("pps", *segs, base), *bvh, *inside, float(stop), ring, depth)
    return ring.copy_to_host(), depth.copy_to_host()


@cuda.jit
def _intervals_clear(tip_a, axis_a, tip_b, axis_b, tool, grow, limit, ring_t, ring_rho, ring_r, seg_t0, seg_t1,
                     seg_r, seg_base, node_lo, node_hi, node_child, node_range, tris, out):
    i = cuda.grid(1)
    if i < tip_a.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        work = cuda.local.array(WORK_SIZE, float64)
        out[i] = clr.interval_clear(i, tip_a, axis_a, tip_b, axis_b, tool, grow, limit, ring_t, ring_rho, ring_r,
                                    seg_t0, seg_t1, seg_r, seg_base, node_lo, node_hi, node_child, node_range, tris,
                                    stack, work)


def intervals_clear(tip_a, axis_a, tip_b, axis_b, tool, grow, limit, rings, segs, base, bvh):
    """As :func:`meshmill.kernels.cpu.intervals_clear`."""
    k = len(tip_a)
    out = STAGE.empty("ic.out", (k,), np.bool_)
    _intervals_clear[_grid(k)](*_s("ic", tip_a, axis_a, tip_b, axis_b), STAGE.put("ic.tool", tool, np.int32),
                               *_s("icg", grow, limit, *rings[:3], *segs, base), *bvh, out)
    return out.copy_to_host()


@cuda.jit
def _points_inside(p, in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor, out):
    i = cuda.grid(1)
    if i < p.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        out[i] = clr.inside(p[i, 0], p[i, 1], p[i, 2], in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor,
                            stack)


def points_inside(points, inside):
    """As :func:`meshmill.kernels.cpu.points_inside`."""
    out = STAGE.empty("pi.out", (len(points),), np.bool_)
    _points_inside[_grid(len(points))](*_s("pi", points), *inside, out)
    return out.copy_to_host()


@cuda.jit
def _drop_cutter(xy, R, r, body_r, body_t, floor, chunk, node_lo, node_hi, node_child, node_range, tris, z, cc):
    c = cuda.grid(1)
    k = xy.shape[0]
    if c * chunk < k:
        stack = cuda.local.array(STACK_SIZE, int32)
        cut.drop_run(c * chunk, min(k, (c + 1) * chunk), xy, R, r, body_r, body_t, floor,
                     node_lo, node_hi, node_child, node_range, tris, stack, z, cc)


def drop_cutter(xy, radius, corner_radius, floor, bvh, body=None, chunk=CHUNK):
    """As :func:`meshmill.kernels.cpu.drop_cutter` (``chunk`` points per thread)."""
    body = NO_BODY if body is None else body
    k = len(xy)
    z = STAGE.empty("dc.z", (k,))
    cc = STAGE.empty("dc.cc", (k, 3))
    d_xy, body_r, body_t = _s("dc", xy, *body[:2])
    _drop_cutter[_grid(_blocks(k, chunk))](d_xy, float(radius), float(corner_radius), body_r, body_t,
                                           float(floor), int(chunk), *bvh, z, cc)
    return z.copy_to_host(), cc.copy_to_host()


@cuda.jit
def _touch_points(pa, pb, fa, fb, qa, z, R, r, body_r, body_t, floor, touch, width, rounds,
                  node_lo, node_hi, node_child, node_range, tris, out):
    i = cuda.grid(1)
    if i < pa.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        cut.touch_point(i, pa, pb, fa, fb, qa, z, R, r, body_r, body_t, floor, touch, width, rounds,
                        node_lo, node_hi, node_child, node_range, tris, stack, out)


def touch_points(inside_xy, outside_xy, f_inside, f_outside, z, radius, corner_radius, floor, bvh,
                 touch=1e-6, width=1e-4, rounds=80, body=None, inside_contacts=None):
    """As :func:`meshmill.kernels.cpu.touch_points`."""
    body = NO_BODY if body is None else body
    if inside_contacts is None:
        inside_contacts = np.full((len(inside_xy), 3), np.nan)
    out = STAGE.put("tp.out", outside_xy)
    pa, pb, fa, fb, qa, body_r, body_t = _s("tp", inside_xy, outside_xy, f_inside, f_outside, inside_contacts, *body[:2])
    _touch_points[_grid(len(inside_xy))](pa, pb, fa, fb, qa, float(z), float(radius), float(corner_radius),
                                         body_r, body_t, float(floor), float(touch), float(width),
                                         int(rounds), *bvh, out)
    return out.copy_to_host()


@cuda.jit
def _rays_blocked(origins, d, tmin, node_lo, node_hi, node_child, node_range, tris, out):
    i = cuda.grid(1)
    if i < origins.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        out[i] = ray.ray_blocked(origins[i, 0], origins[i, 1], origins[i, 2], d[0], d[1], d[2], tmin,
                                 node_lo, node_hi, node_child, node_range, tris, stack)


def rays_blocked(origins, direction, tmin, bvh):
    """As :func:`meshmill.kernels.cpu.rays_blocked`."""
    out = STAGE.empty("rb.out", (len(origins),), np.uint8)
    _rays_blocked[_grid(len(origins))](*_s("rb", origins, direction), float(tmin), *bvh, out)
    return out.copy_to_host().astype(bool)


@cuda.jit
def _cast_bvh(a, line0, lu, lv, step, nu, nv, cap, node_lo, node_hi, node_child, node_range, tris, out, count):
    line = cuda.grid(1)
    if line < nu * nv:
        stack = cuda.local.array(STACK_SIZE, int32)
        hw = cuda.local.array(MAX_HITS, float64)
        hs = cuda.local.array(MAX_HITS, int64)
        count[line] = ray.cast_bvh_line(a, line, line0, lu, lv, step, nv, cap, node_lo, node_hi, node_child, node_range,
                                        tris, stack, hw, hs, out)


def cast_lines(a, lu, lv, step, nu, nv, bvh, first_row=0):
    """As :func:`meshmill.kernels.cpu_dexel.cast_lines` with the BVH index (one thread per line)."""
    n_lines = int(nu) * int(nv)
    cap = 4
    while True:
        out = cuda.device_array((n_lines, cap, 2), np.float64)
        count = cuda.device_array(n_lines, np.int64)
        _cast_bvh[_grid(n_lines)](a, int(first_row) * int(nv), float(lu), float(lv), float(step), int(nu),
                                  int(nv), cap, *bvh, out, count)
        c = count.copy_to_host()
        need = int(c.max(initial=0))
        if need <= cap:
            return out.copy_to_host(), c
        cap = need


@cuda.jit
def _move_constants(pa, pb, xa, xb, corner, flutes, chord, plane):
    m = cuda.grid(1)
    if m < pa.shape[0]:
        crv.move_constants(m, pa, pb, xa, xb, corner, flutes, chord, plane)


@cuda.jit
def _cut_tiles(lu, lv, step, nu, nv, iv, off, count, tiles, combs, split, tile_start, tile_moves, pa, pb, xa, xb,
               radius, corner, flutes, strips, chord, plane, box, kind, group, gbound, gbox, hit_min, hit, todo, redo, row0,
               probe, load):
    t = tiles[cuda.blockIdx.x]
    tv = (nv + TILE - 1) // TILE
    i = (t // tv) * TILE + cuda.threadIdx.x // TILE
    j = (t % tv) * TILE + cuda.threadIdx.x % TILE
    if i >= nu or j >= nv or i % split != combs[cuda.blockIdx.x] \
            or (todo.shape[0] > 0 and todo[(i - row0) * nv + j] == 0):
        return
    resume = tile_start[t] if todo.shape[0] == 0 else todo[(i - row0) * nv + j] - 1
    u0 = lu + (i + 0.5) * step
    v0 = lv + (j + 0.5) * step
    current = -1  # the last group tested on this line, and whether it was clear
    clear = False
    for s in range(resume, tile_start[t + 1]):
        m = tile_moves[s]
        i0, i1, j0, j1 = crv.move_lines(box, m, lu, lv, step, nu, nv)
        if i < i0 or i > i1 or j < j0 or j > j1:
            continue
        g = group[m]
        if g >= 0:
            if g != current:  # the group's first move on this line: none of its moves cuts it if clear
                current = g
                clear = crv.group_clear(g, (i - row0) * nv + j, u0, v0, iv, off, count, gbound, gbox)
            if clear:
                continue
        if kind[m] & BODY:  # a shank or holder meets material, it removes none
            if crv.touch_line(m, (i - row0) * nv + j, u0, v0, box[m, 4], box[m, 5], iv, off, count, pa, pb, xa, xb,
                              radius, corner, flutes, strips) > hit_min:
                hit[m] = 1
            continue
        measure = probe.shape[0] > 0
        removed, first, last = crv.cut_line(m, (i - row0) * nv + j, u0, v0, box[m, 4], box[m, 5], iv, off, count, pa,
                                            pb, xa, xb, radius, corner, flutes, strips, chord, plane, measure)
        if removed < 0.0:
            redo[(i - row0) * nv + j] = s + 1
            return
        if removed > hit_min:  # a rapid that cuts, or a feed move in material
            hit[m] = 1
            if measure:  # the lines of a move are cut by many threads: its load gathered atomically
                ax_lo, ax_hi, lat_lo, lat_hi = crv.load_extents(m, u0, v0, first, last, probe)
                cuda.atomic.add(load, (0, m, 0), removed)
                cuda.atomic.max(load, (0, m, 1), ax_hi)
                cuda.atomic.min(load, (0, m, 2), lat_lo)
                cuda.atomic.max(load, (0, m, 3), lat_hi)
                cuda.atomic.min(load, (0, m, 4), ax_lo)


def move_constants(pa, pb, xa, xb, corner, flutes):
    """As :func:`meshmill.kernels.cpu_dexel.move_constants` (host arrays in and out)."""
    k = len(pa)
    chord = STAGE.empty("mc.chord", (k, 6))
    plane = STAGE.empty("mc.plane", (k, 4))
    _move_constants[_grid(k)](*_s("mc", pa, pb, xa, xb, corner, flutes), chord, plane)
    return chord.copy_to_host(), plane.copy_to_host()


def cut_tiles(lu, lv, step, nu, nv, iv, off, count, tiles, combs, split, tile_start, tile_moves,
              pa, pb, xa, xb, radius, corner, flutes, strips, chord, plane, box, kind, group, gbound, gbox, hit_min, hit,
              todo, redo, row0, probe, load):
    """As :func:`meshmill.kernels.cpu_dexel.cut_tiles` (host arrays updated in place): one block per
    item, one thread per line of its tile (those off its comb idle), each line cut by the tile's
    moves in path order. A line that runs out
    of room stops and is flagged in ``redo`` (with the move it stopped at); the others go on."""
    if len(tiles) == 0:
        return
    d_iv, d_load = _s("ct.f", iv, load)
    d_count, d_off, d_tiles, d_combs, d_start, d_moves, d_strips, d_group, d_redo, d_todo = _s(
        "ct.i", count, off, tiles, combs, tile_start, tile_moves, strips, group, redo, todo, dtype=np.int64)
    d_hit, d_kind = _s("ct.b", hit, kind, dtype=np.uint8)
    _cut_tiles[len(tiles), TILE * TILE](float(lu), float(lv), float(step), int(nu), int(nv), d_iv, d_off, d_count,
                                        d_tiles, d_combs, int(split), d_start, d_moves,
                                        *_s("ct.m", pa, pb, xa, xb, radius, corner, flutes), d_strips,
                                        *_s("ct.c", chord, plane, box), d_kind, d_group,
                                        *_s("ct.g", gbound.reshape(-1, 10), gbox.reshape(-1, 6)), float(hit_min), d_hit,
                                        d_todo, d_redo,
                                        int(row0), STAGE.put("ct.probe", probe), d_load)
    load[...] = d_load.copy_to_host()
    iv[...] = d_iv.copy_to_host()
    count[...] = d_count.copy_to_host()
    hit[...] = d_hit.copy_to_host()
    redo[...] = d_redo.copy_to_host()
