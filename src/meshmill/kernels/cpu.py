"""CPU backend: the device functions of :mod:`meshmill.kernels.geom` compiled with numba, and the
parallel loops (one independent item per ``prange`` iteration) that the operations call.

Every array argument is float64 mm unless said otherwise; ``bvh`` is ``BVH.arrays``.
"""
from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

from . import clearance, cutters, raycast
from .clearance import WORK_SIZE
from .cutters import NO_BODY
from .geom import INF, SEEN_SIZE, STACK_SIZE, build

# device functions allocate nothing and keep no array they are handed, so they are compiled without
# reference counting (else every call passing arrays counts references, atomically, in the innermost
# loops); the parallel loops below allocate, and count
device = numba.njit(fastmath=False, cache=True, _nrt=False)
dev = build(device)
cut = cutters.build(device)
clr = clearance.build(device)
ray = raycast.build(device)
CHUNK = 64  # points of a drop-cutter batch run in order by one thread
RAY_CHUNK = 256  # rays tested in order by one thread


@numba.njit(parallel=True, cache=True)
def _mesh_distances(p, cap, node_lo, node_hi, node_child, node_range, tris):
    out = np.empty(p.shape[0])
    for i in prange(p.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        d2 = dev.mesh_point_dist2(p[i, 0], p[i, 1], p[i, 2], cap * cap, 0.0,
                                  node_lo, node_hi, node_child, node_range, tris, stack)
        out[i] = math.sqrt(d2)
    return out


def mesh_distances(points, bvh, cap=INF):
    """Exact distance ``(k,)`` from each of ``points (k, 3)`` to the mesh (values above cap: cap)."""
    cap = min(cap, 1e150)
    return _mesh_distances(np.ascontiguousarray(points, np.float64), cap, *bvh)


@numba.njit(parallel=True, cache=True)
def _largest_ball(cc, nrm, radii, tol, node_lo, node_hi, node_child, node_range, tris):
    out = np.empty(cc.shape[0], np.int32)
    for i in prange(cc.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        out[i] = dev.largest_clear_ball(cc[i, 0], cc[i, 1], cc[i, 2], nrm[i, 0], nrm[i, 1], nrm[i, 2], radii, tol,
                                        node_lo, node_hi, node_child, node_range, tris, stack)
    return out


def largest_ball(cc, normals, radii, tol, bvh):
    """Index into ``radii`` (sorted decreasing, mm) of the largest ball whose sphere at
    CE = cc + R·n stays out of the mesh by more than ``-tol``; -1 where none does. ``(k,) int32``."""
    return _largest_ball(np.ascontiguousarray(cc), np.ascontiguousarray(normals),
                         np.ascontiguousarray(radii, np.float64), float(tol), *bvh)


@numba.njit(parallel=True, cache=True)
def _axis_search(ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                 node_lo, node_hi, node_child, node_range, tris):
    out = np.empty(ce.shape[0], np.int32)
    for c in prange((ce.shape[0] + CHUNK - 1) // CHUNK):  # neighbouring points share their witnesses
        stack = np.empty(STACK_SIZE, np.int32)
        seen = np.empty(SEEN_SIZE)
        kept = 0
        for i in range(c * CHUNK, min(ce.shape[0], (c + 1) * CHUNK)):
            out[i], kept = dev.first_clear_axis(i, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                                                node_lo, node_hi, node_child, node_range, tris, stack, seen, kept)
    return out


@numba.njit(parallel=True, cache=True)
def _keep_previous(choice, offsets, cand_tilt, slack, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                   node_lo, node_hi, node_child, node_range, tris):
    out = choice.copy()
    for k in prange(offsets.shape[0] - 1):
        stack = np.empty(STACK_SIZE, np.int32)
        dev.keep_previous_axes(offsets[k], offsets[k + 1], out, cand_tilt, slack, ce, f, s, tool, cand, radius,
                               seg_t0, seg_t1, seg_r, node_lo, node_hi, node_child, node_range, tris, stack)
    return out


def axis_search(ce, feed, side, tool, candidates, cand_tilt, slack, radius, body, offsets, bvh):
    """Collision-free tool axis per point.

    ``ce (k, 3)`` ball centres, ``feed/side (k, 3)`` unit feed and outward side directions,
    ``tool (k,)`` tool index (-1: skip), ``candidates (c, 2)`` (alpha, beta) rad in order of
    preference, ``cand_tilt (c,)`` their tilt from +Z, ``radius (T,)`` ball radii, ``body`` the
    ``(seg_t0, seg_t1, seg_r)`` arrays (T, K) of the parts that must stay clear, ``offsets (p+1,)``
    point ranges of the contours. A point keeps its predecessor's candidate when that is clear and
    at most ``slack`` rad more tilted. Returns ``(k,) int32`` candidate index, -1 where none is clear.
    """
    args = (np.ascontiguousarray(ce), np.ascontiguousarray(feed), np.ascontiguousarray(side),
            np.ascontiguousarray(tool, np.int32), np.ascontiguousarray(candidates, np.float64),
            np.ascontiguousarray(radius, np.float64), *body)
    first = _axis_search(*args, *bvh)
    return _keep_previous(first, np.ascontiguousarray(offsets, np.int64),
                          np.ascontiguousarray(cand_tilt, np.float64), float(slack), *args, *bvh)


@numba.njit(parallel=True, cache=True)
def _pose_penetration(tip, axis, tool, grow, ring_t, ring_rho, ring_r, ring_n, seg_t0, seg_t1, seg_r, seg_base,
                      node_lo, node_hi, node_child, node_range, tris, in_lo, in_hi, in_child, in_range, in_tris,
                      in_kind, floor, stop):
    ring = np.zeros(tip.shape[0])
    segs = np.zeros((tip.shape[0], seg_r.shape[1]))
    for i in prange(tip.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        clr.pose_depth(i, tip, axis, tool, grow, ring_t, ring_rho, ring_r, ring_n, seg_t0, seg_t1, seg_r, seg_base,
                       node_lo, node_hi, node_child, node_range, tris, in_lo, in_hi, in_child, in_range, in_tris,
                       in_kind, floor, stop, stack, ring, segs)
    return ring, segs


def _f(a):
    return np.ascontiguousarray(a, np.float64)


def pose_penetration(tip, axis, tool, grow, rings, segs, base, bvh, inside, stop=-1.0):
    """How deep each tool pose enters the material, mm (0 where clear).

    ``tip, axis (k, 3)``; ``tool (k,)`` index into the per-tool arrays; ``grow (k,)`` mm every part
    is grown by; ``rings`` is ``(ring_t, ring_rho, ring_r, ring_n)`` (T,): spheres of radius
    ring_r centred on a circle of radius ring_rho at ring_t along the axis (a ball: rho 0);
    ``segs`` is ``(seg_t0, seg_t1, seg_r)`` (T, K) cylinders and ``base (T, K)`` where their axial
    depth is measured from; ``bvh`` the check mesh's arrays, ``inside`` the
    :attr:`~meshmill.geometry.solid.Solid.inside` arrays. Returns ``ring (k,)`` and ``segs (k, K)``
    (see :func:`meshmill.kernels.clearance.build`'s ``pose_depth``). ``stop`` >= 0: only whether
    each depth exceeds it is asked (exact up to it, any value past it beyond).
    """
    *in_bvh, kind, floor = inside
    return _pose_penetration(_f(tip), _f(axis), np.ascontiguousarray(tool, np.int32), _f(grow), *rings, *segs,
                             _f(base), *bvh, *in_bvh, np.ascontiguousarray(kind, np.int8), float(floor), float(stop))


@numba.njit(parallel=True, cache=True)
def _intervals_clear(tip_a, axis_a, tip_b, axis_b, tool, grow, limit, ring_t, ring_rho, ring_r, seg_t0, seg_t1,
                     seg_r, seg_base, node_lo, node_hi, node_child, node_range, tris):
    out = np.zeros(tip_a.shape[0], np.bool_)
    for i in prange(tip_a.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        work = np.empty(WORK_SIZE)
        out[i] = clr.interval_clear(i, tip_a, axis_a, tip_b, axis_b, tool, grow, limit, ring_t, ring_rho, ring_r,
                                    seg_t0, seg_t1, seg_r, seg_base, node_lo, node_hi, node_child, node_range, tris,
                                    stack, work)
    return out


def intervals_clear(tip_a, axis_a, tip_b, axis_b, tool, grow, limit, rings, segs, base, bvh):
    """``(k,) bool``: whether the tool of each interval, every part grown by ``grow (k,)``, stays
    within ``limit (k,)`` mm of the mesh at every pose from (tip_a, axis_a) to (tip_b, axis_b)
    (``(k, 3)`` each; the move's interpolation: tip linear, axis normalised linear). True is a
    proof; False means: look closer (see :mod:`meshmill.kernels.clearance`)."""
    return _intervals_clear(_f(tip_a), _f(axis_a), _f(tip_b), _f(axis_b), np.ascontiguousarray(tool, np.int32),
                            _f(grow), _f(limit), *rings[:3], *segs, _f(base), *bvh)


@numba.njit(parallel=True, cache=True)
def _points_inside(p, in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor):
    out = np.zeros(p.shape[0], np.bool_)
    for i in prange(p.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        out[i] = clr.inside(p[i, 0], p[i, 1], p[i, 2], in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor, stack)
    return out


def points_inside(points, inside):
    """``(k,) bool``: whether each of ``points (k, 3)`` lies in the material of a
    :attr:`~meshmill.geometry.solid.Solid.inside`."""
    *in_bvh, kind, floor = inside
    return _points_inside(_f(points), *in_bvh, np.ascontiguousarray(kind, np.int8), float(floor))


@numba.njit(parallel=True, cache=True)
def _drop_cutter(xy, R, r, body_r, body_t, floor, chunk, threads, node_lo, node_hi, node_child, node_range, tris):
    # numba gives each thread one run of a prange's iterations: the chunks dealt to the
    # ``threads`` lanes in turn (lane j: chunks j, j + threads, ...) spread each thread's share
    # over the whole batch, in order, where runs of chunks left one thread the steep half of a
    # part and the other waiting (a raster's grid 0.46 -> 0.42 s on 2 threads)
    k = xy.shape[0]
    z = np.empty(k)
    cc = np.empty((k, 3))
    n_chunks = (k + chunk - 1) // chunk
    lanes = max(1, min(threads, n_chunks))
    for j in prange(lanes):
        stack = np.empty(STACK_SIZE, np.int32)
        for c in range(j, n_chunks, lanes):
            cut.drop_run(c * chunk, min(k, (c + 1) * chunk), xy, R, r, body_r, body_t, floor,
                         node_lo, node_hi, node_child, node_range, tris, stack, z, cc)
    return z, cc


def drop_cutter(xy, radius, corner_radius, floor, bvh, body=None, chunk=CHUNK):
    """Drop a vertical cutter (radius, corner radius: flat 0, ball = radius) at each of
    ``xy (k, 2)``: tip heights ``(k,)`` (at least ``floor``) and contact points ``(k, 3)`` (NaN
    where nothing is touched above the floor). ``body = (radii, heights)``: flat-bottomed
    cylinders above the cutter (shank, holder) that must not touch either. ``chunk``: points
    dropped in order by one thread."""
    body = NO_BODY if body is None else body
    return _drop_cutter(np.ascontiguousarray(xy, np.float64), float(radius), float(corner_radius),
                        np.ascontiguousarray(body[0], np.float64), np.ascontiguousarray(body[1], np.float64),
                        float(floor), int(chunk), numba.get_num_threads(), *bvh)


@numba.njit(parallel=True, cache=True)
def _drop_refined(xy, R, r, body_r, body_t, floor, grow, chord_tol, min_step, rounds, chunk, threads, cap,
                  node_lo, node_hi, node_child, node_range, tris):
    k = xy.shape[0]
    z = np.empty(k)
    n_chunks = max(1, (k - 1 + chunk - 1) // chunk)  # chunks of segments (one of the lone point)
    lanes = max(1, min(threads, n_chunks))  # dealt to the threads in turn, as in _drop_cutter
    rows = np.empty((lanes, cap, 5))
    count = np.zeros(lanes, np.int64)
    for j in prange(lanes):
        stack = np.empty(STACK_SIZE, np.int32)
        pend = np.empty((rounds + 1, 9))
        for c in range(j, n_chunks, lanes):
            s1 = min(k - 1, (c + 1) * chunk)
            count[j] = cut.refine_run(c * chunk, s1, s1 == k - 1, xy, R, r, body_r, body_t, floor, grow, chord_tol,
                                      min_step, rounds, node_lo, node_hi, node_child, node_range, tris, stack, pend,
                                      z, rows[j], count[j])
            if count[j] < 0:
                break
    return z, rows, count


def drop_refined(xy, radius, corner_radius, floor, grow, chord_tol, min_step, rounds, bvh, body=None, chunk=CHUNK,
                 cap=None):
    """Drop a vertical cutter (as :func:`drop_cutter`; heights raised by ``grow``, floor before it)
    at each of ``xy (k, 2)``, a polyline, and refine each of its segments on its own: its midpoint
    dropped where it is longer than ``min_step``, kept where its height leaves the chord by more
    than ``chord_tol``, its halves refined so in turn, ``rounds`` levels deep. Returns the heights
    ``(k,)`` and the midpoints kept ``(m, 5)``: segment, place along it (0-1), height, x, y, in
    no particular order. ``cap``: rows a thread holds at first (more are made room for)."""
    body = NO_BODY if body is None else body
    xy = np.ascontiguousarray(xy, np.float64)
    if len(xy) == 0:
        return np.zeros(0), np.zeros((0, 5))
    cap = cap or max(1024, len(xy) // max(1, numba.get_num_threads()))
    while True:
        z, rows, count = _drop_refined(xy, float(radius), float(corner_radius),
                                       np.ascontiguousarray(body[0], np.float64),
                                       np.ascontiguousarray(body[1], np.float64), float(floor), float(grow),
                                       float(chord_tol), float(min_step), int(rounds), int(chunk),
                                       numba.get_num_threads(), cap, *bvh)
        if (count >= 0).all():
            return z, np.concatenate([rows[j, :count[j]] for j in range(len(count))])
        cap *= 4  # (a thread's rows ran out: again with room for more)


@numba.njit(parallel=True, cache=True)
def _touch_points(pa, pb, fa, fb, qa, z, R, r, body_r, body_t, floor, touch, width, rounds,
                  node_lo, node_hi, node_child, node_range, tris):
    out = pb.copy()
    for i in prange(pa.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        cut.touch_point(i, pa, pb, fa, fb, qa, z, R, r, body_r, body_t, floor, touch, width, rounds,
                        node_lo, node_hi, node_child, node_range, tris, stack, out)
    return out


def touch_points(inside_xy, outside_xy, f_inside, f_outside, z, radius, corner_radius, floor, bvh,
                 touch=1e-6, width=1e-4, rounds=80, body=None, inside_contacts=None):
    """Where the drop-cutter height crosses ``z`` between each inside point (height above z by
    ``f_inside > 0``) and outside point (``f_outside <= 0``): bracketed search that keeps the
    outside end, so the result never gouges; it stops when the height is within ``touch`` mm of z
    or the bracket is ``width`` mm short (always so at a vertical wall, where the height jumps). ``inside_contacts (k, 3)``: the inside
    points' contacts from their drop (NaN rows or None: dropped again). ``(k, 2)``."""
    body = NO_BODY if body is None else body
    if inside_contacts is None:
        inside_contacts = np.full((len(inside_xy), 3), np.nan)
    return _touch_points(np.ascontiguousarray(inside_xy, np.float64), np.ascontiguousarray(outside_xy, np.float64),
                         np.ascontiguousarray(f_inside, np.float64), np.ascontiguousarray(f_outside, np.float64),
                         np.ascontiguousarray(inside_contacts, np.float64),
                         float(z), float(radius), float(corner_radius), np.ascontiguousarray(body[0], np.float64),
                         np.ascontiguousarray(body[1], np.float64), float(floor), float(touch), float(width),
                         int(rounds), *bvh)


@numba.njit(parallel=True, cache=True)
def _rays_blocked(origins, d, tmin, node_lo, node_hi, node_child, node_range, tris):
    out = np.zeros(origins.shape[0], np.bool_)
    for c in prange((origins.shape[0] + RAY_CHUNK - 1) // RAY_CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        for i in range(c * RAY_CHUNK, min(origins.shape[0], (c + 1) * RAY_CHUNK)):
            out[i] = ray.ray_blocked(origins[i, 0], origins[i, 1], origins[i, 2], d[0], d[1], d[2], tmin,
                                     node_lo, node_hi, node_child, node_range, tris, stack)
    return out


def rays_blocked(origins, direction, tmin, bvh):
    """``(k,) bool``: whether the ray from each of ``origins (k, 3)`` along the unit ``direction``
    meets the mesh beyond ``tmin`` mm."""
    return _rays_blocked(np.ascontiguousarray(origins, np.float64), np.asarray(direction, np.float64),
                         float(tmin), *bvh)
