"""CPU backend: the device functions of :mod:`meshmill.kernels.geom` compiled with numba, and the
parallel loops (one independent item per ``prange`` iteration) that the operations call.

Every array argument is float64 mm unless said otherwise; ``bvh`` is ``BVH.arrays``.
"""
from __future__ import annotations

import math

import numba
import numpy as np
from numba import prange

from . import cutters
from .geom import INF, STACK_SIZE, build

dev = build(numba.njit(fastmath=False, cache=True))
cut = cutters.build(numba.njit(fastmath=False, cache=True))
_drop = cut.tool_drop
_reach = cut.contact_reach
CHUNK = 64  # points of a drop-cutter batch run in order by one thread
_point = dev.mesh_point_dist2
_ball = dev.largest_clear_ball
_cyl = dev.mesh_cylinder_dist2
_body_clear = dev.body_clear


@numba.njit(parallel=True, cache=True)
def _mesh_distances(p, cap, node_lo, node_hi, node_child, node_range, tris):
    out = np.empty(p.shape[0])
    for i in prange(p.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        d2 = _point(p[i, 0], p[i, 1], p[i, 2], cap * cap, 0.0,
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
        out[i] = _ball(cc[i, 0], cc[i, 1], cc[i, 2], nrm[i, 0], nrm[i, 1], nrm[i, 2], radii, tol,
                       node_lo, node_hi, node_child, node_range, tris, stack)
    return out


def largest_ball(cc, normals, radii, tol, bvh):
    """Index into ``radii`` (sorted decreasing, mm) of the largest ball whose sphere at
    CE = cc + R·n stays out of the mesh by more than ``-tol``; -1 where none does. ``(k,) int32``."""
    return _largest_ball(np.ascontiguousarray(cc), np.ascontiguousarray(normals),
                         np.ascontiguousarray(radii, np.float64), float(tol), *bvh)


@numba.njit(cache=True)
def candidate_axis(f, s, alpha, beta):
    """Unit axis tilted by alpha toward the feed direction f and beta toward the outward side s."""
    ca = math.cos(alpha)
    sa = math.sin(alpha)
    cb = math.cos(beta)
    sb = math.sin(beta)
    ux = sa * f[0] + ca * sb * s[0]
    uy = sa * f[1] + ca * sb * s[1]
    uz = sa * f[2] + ca * (cb + sb * s[2])
    n = math.sqrt(ux * ux + uy * uy + uz * uz)
    return ux / n, uy / n, uz / n


@numba.njit(cache=True)
def _clear_at(i, c, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
              node_lo, node_hi, node_child, node_range, tris, stack):
    ux, uy, uz = candidate_axis(f[i], s[i], cand[c, 0], cand[c, 1])
    r = radius[tool[i]]
    return _body_clear(ce[i, 0] - r * ux, ce[i, 1] - r * uy, ce[i, 2] - r * uz, ux, uy, uz,
                       seg_t0, seg_t1, seg_r, tool[i], node_lo, node_hi, node_child, node_range, tris, stack)


@numba.njit(parallel=True, cache=True)
def _axis_search(ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                 node_lo, node_hi, node_child, node_range, tris):
    out = np.full(ce.shape[0], -1, np.int32)
    for i in prange(ce.shape[0]):
        if tool[i] < 0:
            continue
        stack = np.empty(STACK_SIZE, np.int32)
        for c in range(cand.shape[0]):
            if _clear_at(i, c, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                         node_lo, node_hi, node_child, node_range, tris, stack):
                out[i] = c
                break
    return out


@numba.njit(parallel=True, cache=True)
def _keep_previous(choice, offsets, cand_tilt, slack, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                   node_lo, node_hi, node_child, node_range, tris):
    out = choice.copy()
    for k in prange(offsets.shape[0] - 1):
        stack = np.empty(STACK_SIZE, np.int32)
        for i in range(offsets[k] + 1, offsets[k + 1]):
            prev = out[i - 1]
            c = out[i]
            if prev < 0 or c < 0 or prev == c or cand_tilt[prev] > cand_tilt[c] + slack:
                continue
            if _clear_at(i, prev, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                         node_lo, node_hi, node_child, node_range, tris, stack):
                out[i] = prev
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
def _pose_penetration(tip, axis, tool, ring_t, ring_rho, ring_r, ring_n, seg_t0, seg_t1, seg_r, seg_base,
                      node_lo, node_hi, node_child, node_range, tris):
    k = tip.shape[0]
    nseg = seg_r.shape[1]
    ring = np.zeros(k)
    segs = np.zeros((k, nseg))
    for i in prange(k):
        stack = np.empty(STACK_SIZE, np.int32)
        t = tool[i]
        ux = axis[i, 0]
        uy = axis[i, 1]
        uz = axis[i, 2]
        # two unit vectors normal to the axis
        if abs(ux) < 0.9:
            ex, ey, ez = 0.0, -uz, uy
        else:
            ex, ey, ez = uz, 0.0, -ux
        en = math.sqrt(ex * ex + ey * ey + ez * ez)
        ex /= en
        ey /= en
        ez /= en
        gx = uy * ez - uz * ey
        gy = uz * ex - ux * ez
        gz = ux * ey - uy * ex
        cx = tip[i, 0] + ring_t[t] * ux
        cy = tip[i, 1] + ring_t[t] * uy
        cz = tip[i, 2] + ring_t[t] * uz
        r = ring_r[t]
        if r > 0.0:
            for j in range(ring_n[t]):
                phi = 2.0 * math.pi * j / ring_n[t]
                rx = ring_rho[t] * (math.cos(phi) * ex + math.sin(phi) * gx)
                ry = ring_rho[t] * (math.cos(phi) * ey + math.sin(phi) * gy)
                rz = ring_rho[t] * (math.cos(phi) * ez + math.sin(phi) * gz)
                d2 = _point(cx + rx, cy + ry, cz + rz, r * r, 0.0,
                            node_lo, node_hi, node_child, node_range, tris, stack)
                ring[i] = max(ring[i], r - math.sqrt(d2))
        for s in range(nseg):
            r = seg_r[t, s]
            if r <= 0.0:
                break
            t0 = seg_t0[t, s]
            t1 = seg_t1[t, s]
            d2 = _cyl(tip[i, 0], tip[i, 1], tip[i, 2], ux, uy, uz, t0, t1, r * r, 0.0,
                      node_lo, node_hi, node_child, node_range, tris, stack)
            if d2 >= r * r:
                continue
            radial = r - math.sqrt(d2)
            # axial depth: how far the bottom of the cylinder must rise to clear (bisection)
            lo = t0
            hi = t1
            if _cyl(tip[i, 0], tip[i, 1], tip[i, 2], ux, uy, uz, hi - 1e-9, t1, r * r, r * r,
                    node_lo, node_hi, node_child, node_range, tris, stack) < r * r:
                segs[i, s] = radial
                continue
            for _ in range(30):
                mid = 0.5 * (lo + hi)
                if _cyl(tip[i, 0], tip[i, 1], tip[i, 2], ux, uy, uz, mid, t1, r * r, r * r,
                        node_lo, node_hi, node_child, node_range, tris, stack) < r * r:
                    lo = mid
                else:
                    hi = mid
            segs[i, s] = min(radial, hi - seg_base[t, s])
    return ring, segs


def pose_penetration(tip, axis, tool, rings, segs, bvh, base=None):
    """How deep each tool pose enters the mesh, mm (0 where clear).

    ``tip, axis (k, 3)``; ``tool (k,)`` index into the per-tool arrays; ``rings`` is
    ``(ring_t, ring_rho, ring_r, ring_n)`` (T,): spheres of radius ring_r centred on a circle of
    radius ring_rho at ring_t along the axis (a ball: rho 0, n 1); ``segs`` is
    ``(seg_t0, seg_t1, seg_r)`` (T, K) cylinders. Returns ``ring (k,)`` and ``segs (k, K)``:
    the depth of the deepest point inside each part (radial for spheres; the smaller of the
    radial and axial depths for cylinders, the axial one measured from ``base (T, K)``, default
    the cylinders' own bottoms).
    """
    base = segs[0] if base is None else base
    return _pose_penetration(np.ascontiguousarray(tip, np.float64), np.ascontiguousarray(axis, np.float64),
                             np.ascontiguousarray(tool, np.int32), *rings, *segs, np.ascontiguousarray(base), *bvh)


@numba.njit(parallel=True, cache=True)
def _drop_cutter(xy, R, r, body_r, body_t, floor, node_lo, node_hi, node_child, node_range, tris):
    k = xy.shape[0]
    z = np.empty(k)
    cc = np.empty((k, 3))
    for c in prange((k + CHUNK - 1) // CHUNK):
        stack = np.empty(STACK_SIZE, np.int32)
        sx = sy = sz = math.nan
        for i in range(c * CHUNK, min(k, (c + 1) * CHUNK)):
            # each point starts from the previous one's contact (a neighbour's, in a grid or a pass)
            z[i], sx, sy, sz = _drop(xy[i, 0], xy[i, 1], R, r, body_r, body_t, floor, sx, sy, sz,
                                     node_lo, node_hi, node_child, node_range, tris, stack)
            cc[i, 0], cc[i, 1], cc[i, 2] = sx, sy, sz
    return z, cc


NO_BODY = (np.zeros(0), np.zeros(0))


def drop_cutter(xy, radius, corner_radius, floor, bvh, body=NO_BODY):
    """Drop a vertical cutter (radius, corner radius: flat 0, ball = radius) at each of
    ``xy (k, 2)``: tip heights ``(k,)`` (at least ``floor``) and contact points ``(k, 3)`` (NaN
    where nothing is touched above the floor). ``body = (radii, heights)``: flat-bottomed
    cylinders above the cutter (shank, holder) that must not touch either."""
    return _drop_cutter(np.ascontiguousarray(xy, np.float64), float(radius), float(corner_radius),
                        np.ascontiguousarray(body[0], np.float64), np.ascontiguousarray(body[1], np.float64),
                        float(floor), *bvh)


@numba.njit(parallel=True, cache=True)
def _touch_points(pa, pb, fa, fb, qa, z, R, r, body_r, body_t, floor, touch, width, rounds,
                  node_lo, node_hi, node_child, node_range, tris):
    out = pb.copy()
    for i in prange(pa.shape[0]):
        stack = np.empty(STACK_SIZE, np.int32)
        ax, ay, bx, by = pa[i, 0], pa[i, 1], pb[i, 0], pb[i, 1]
        fbi = fb[i]
        ga, gb = fa[i], fbi
        qx, qy, qz = qa[i, 0], qa[i, 1], qa[i, 2]
        if math.isnan(qz):
            ga, qx, qy, qz = _drop(ax, ay, R, r, body_r, body_t, floor, qx, qy, qz,
                                   node_lo, node_hi, node_child, node_range, tris, stack)
            ga -= z
        sx, sy, sz = qx, qy, qz
        side = 0
        check = 0.0
        for it in range(rounds):
            width2 = (bx - ax) ** 2 + (by - ay) ** 2
            # touching: just below z (exactly z is a flat facet at the level: go on to its edge)
            if (-touch <= fbi < 0.0) or width2 <= width * width:
                break
            # Illinois (regula falsi halving the weight of an end that stays): superlinear where the
            # height is smooth; every third round a bisection if the bracket has not halved since, so
            # it still halves where the height jumps
            w = ga / (ga - gb)
            if not (0.02 < w < 0.98):  # one end far steeper (a jump): regula falsi would creep
                w = 0.5
            contact = False
            halve = False
            if it % 3 == 0:
                halve = it > 0 and width2 > 0.25 * check  # at least one halving every three rounds
                check = width2
            if halve:
                w = 0.5
            elif it % 2 == 0:
                # contact step: the inside end's contact q alone keeps the tip above z inside a
                # disk around q, so the level set lies at or past where the segment leaves that
                # disk; try just past it. Exact in one step at a wall (the contact stays put).
                rho = _reach(qz - z, R, r, body_r, body_t)
                dx = bx - ax
                dy = by - ay
                ox = ax - qx
                oy = ay - qy
                A = dx * dx + dy * dy
                B = ox * dx + oy * dy
                C = ox * ox + oy * oy - rho * rho
                if C < 0.0:  # a inside q's disk: one exit root t > 0 of A t² + 2 B t + C
                    root = math.sqrt(B * B - A * C)
                    t_exit = -C / (B + root) if B > 0.0 else (root - B) / A
                    t = t_exit + 0.5 * width / math.sqrt(A)
                    if t < 0.98:
                        w = t
                        contact = True
            px = ax + w * (bx - ax)
            py = ay + w * (by - ay)
            f, sx, sy, sz = _drop(px, py, R, r, body_r, body_t, floor, sx, sy, sz,
                                  node_lo, node_hi, node_child, node_range, tris, stack)
            f -= z
            if f > 0.0:
                ax, ay, ga = px, py, f
                qx, qy, qz = sx, sy, sz
                if side == 1:
                    gb *= 0.5
                side = 1
            else:
                if contact:  # the disk's exit, width/2 back, is inside or on the level set
                    back = 0.5 * width / math.sqrt((bx - ax) ** 2 + (by - ay) ** 2)
                    ax += (w - back) * (bx - ax)
                    ay += (w - back) * (by - ay)
                bx, by, fbi, gb = px, py, f, f
                if side == -1:
                    ga *= 0.5
                side = -1
        out[i, 0] = bx
        out[i, 1] = by
    return out


def touch_points(inside_xy, outside_xy, f_inside, f_outside, z, radius, corner_radius, floor, bvh,
                 touch=1e-6, width=1e-4, rounds=80, body=NO_BODY, inside_contacts=None):
    """Where the drop-cutter height crosses ``z`` between each inside point (height above z by
    ``f_inside > 0``) and outside point (``f_outside <= 0``): bracketed search that keeps the
    outside end, so the result never gouges; it stops when the height is within ``touch`` mm of z
    or the bracket is ``width`` mm short (always so at a vertical wall, where the height jumps). ``inside_contacts (k, 3)``: the inside
    points' contacts from their drop (NaN rows or None: dropped again). ``(k, 2)``."""
    if inside_contacts is None:
        inside_contacts = np.full((len(inside_xy), 3), np.nan)
    return _touch_points(np.ascontiguousarray(inside_xy, np.float64), np.ascontiguousarray(outside_xy, np.float64),
                         np.ascontiguousarray(f_inside, np.float64), np.ascontiguousarray(f_outside, np.float64),
                         np.ascontiguousarray(inside_contacts, np.float64),
                         float(z), float(radius), float(corner_radius), np.ascontiguousarray(body[0], np.float64),
                         np.ascontiguousarray(body[1], np.float64), float(floor), float(touch), float(width),
                         int(rounds), *bvh)
