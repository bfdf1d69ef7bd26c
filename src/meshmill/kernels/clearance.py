"""Certified clearance of tool poses and of the tool between two poses (device functions, written
once for every backend; conventions of :mod:`meshmill.kernels.geom`).

A tool is the union of its parts along the unit axis ``u`` from the tip: the rounded end (spheres
of radius ``r`` centred on a circle of radius ``rho`` at ``t`` along the axis: a ball is rho = 0)
and flat-ended cylinders ``[t0, t1]`` of radius ``rad``. A part *penetrates by at most* ``limit``
when (sphere) its radius shrunk by ``limit`` stays out of the mesh, or (cylinder) its radius
shrunk by ``limit`` does, or its bottom raised so that it starts ``limit`` above ``base`` does (the
measure :func:`pose_depth` reports). Every part may be grown by ``grow`` (radius, and both ends of a
cylinder), for the clearance a rapid keeps from the stock.

:func:`interval_clear` decides, without sampling, that every pose between pose a and pose b of a
move (tip linear, axis by normalised linear interpolation, as verification and simulation model a
move) keeps every part within ``limit``:

- the rounded end: its circle is covered by chords (sagitta added to the radius); a chord swept
  from a to b is the bilinear patch of its four end points, within ``dev = l (1 - cos(theta/2))``
  of the true swept chord (l the chord points' distance from the tip, theta the axis turn: the
  normalised interpolation of a vector shortens it by at most that) and within a quarter of the
  patch's twist of its two triangles; so the swept end lies within ``r + slack`` of two triangles,
  whose distance to the mesh is exact (triangle-triangle distance). Chords near the mesh are halved
  until that suffices or cannot (then the caller halves the interval). A ball's chord is a point and
  its sweep a segment: a capsule, exact for a move with a fixed axis.
- a cylinder: cut into bands along its axis. A band held at the axis halfway between the two
  poses' and swept along the path of its middle lies in the prism of a stadium (the disk swept
  along the move's part across that axis) over the slab widened by the move's part along it; the
  band turns about its middle by at most theta/2, which moves its side by ``half length x
  sin(theta/2)`` across the axis and its rim by ``radius x sin(theta/2)`` along it, and the
  middle's path bows by ``t_m (1 - cos(theta/2))``: added to the radius and the slab. Bands are
  halved where their own turn is what fails. The prism's distance to a triangle is exact (the
  triangle clipped to the slab, projected across the axis, against the stadium's segment), so a
  move with a fixed axis (a waterline, a flat floor) is decided exactly.

Every test is conservative: "clear" is a proof, "not clear" only asks the caller to look closer.
"""
from __future__ import annotations

import math

from . import geom, raycast
from .geom import bvh_search, bvh_visit, namespace

INF = 1.0e300
EMPTY_BOX = (INF, INF, INF, -INF, -INF, -INF)  # (lox, loy, loz, hix, hiy, hiz) holding nothing
RING_ARCS = 8  # chords the circle of a rounded end starts with
MIN_ARC = 1e-4  # rad: a chord is not halved below this
ARC_STACK = 64  # chords waiting at once (pairs of angles in the work array)
_TRI_A = 2 * ARC_STACK  # offsets in the work array
_TRI_B = _TRI_A + 9
_POLY = _TRI_B + 9  # up to 5 clipped points (h, x, y), twice
_POLY_B = _POLY + 15
_SUB = _POLY_B + 15  # the tips of a piece of a fixed-axis interval (6)
_HULL = _TRI_A  # a tetrahedron's four faces (36) then its corners (12), over the triangles and polygons
_SHEAR = _SUB + 6  # the points of a sheared sweep's slice (up to 24, x and y) ...
_SHEAR_HULL = _SHEAR + 48  # ... and their hull's indices (up to 49)
_SHEAR_AXIS = _SHEAR_HULL + 50  # the swept segment's ends along the axis and its move along it (3)
WORK_SIZE = _SHEAR_AXIS + 3  # float64 scratch a caller hands in (the offsets above)
SPLIT_SHARE = 0.25  # a fixed-axis interval is cut so that each piece moves along the axis by at most
MAX_SPLIT = 16  # this share of the limit (at most this many pieces; see cylinder_clear)
AXIAL_TOL = 1e-7  # mm: a cylinder's axial depth is bisected to this (from above: never less than it is)


def build(jit):
    """Compile the device functions with ``jit`` and return them in a namespace."""
    g = geom.build(jit)
    ray = raycast.build(jit)
    point_tri = g.point_tri_dist2
    axis_dist = g.triangle_axis_dist2
    point_dist = g.mesh_point_dist2
    cylinder_dist = g.mesh_cylinder_dist2
    crossing = g.line_crossing
    hit = ray.hit

    @jit
    def seg_seg_dist2(p0x, p0y, p0z, p1x, p1y, p1z, q0x, q0y, q0z, q1x, q1y, q1z):
        """Squared distance between segments p0-p1 and q0-q1 (either may be a point)."""
        d1x = p1x - p0x
        d1y = p1y - p0y
        d1z = p1z - p0z
        d2x = q1x - q0x
        d2y = q1y - q0y
        d2z = q1z - q0z
        rx = p0x - q0x
        ry = p0y - q0y
        rz = p0z - q0z
        a = d1x * d1x + d1y * d1y + d1z * d1z
        e = d2x * d2x + d2y * d2y + d2z * d2z
        f = d2x * rx + d2y * ry + d2z * rz
        s = 0.0
        t = 0.0
        if a <= 1e-300 and e <= 1e-300:
            return rx * rx + ry * ry + rz * rz
        if a <= 1e-300:
            t = min(1.0, max(0.0, f / e))
        else:
            c = d1x * rx + d1y * ry + d1z * rz
            if e <= 1e-300:
                s = min(1.0, max(0.0, -c / a))
            else:
                b = d1x * d2x + d1y * d2y + d1z * d2z
                den = a * e - b * b
                if den > 0.0:
                    s = min(1.0, max(0.0, (b * f - c * e) / den))
                t = (b * s + f) / e
                if t < 0.0:
                    t = 0.0
                    s = min(1.0, max(0.0, -c / a))
                elif t > 1.0:
                    t = 1.0
                    s = min(1.0, max(0.0, (b - c) / a))
        wx = rx + s * d1x - t * d2x
        wy = ry + s * d1y - t * d2y
        wz = rz + s * d1z - t * d2z
        return wx * wx + wy * wy + wz * wz

    @jit
    def pierces(p0x, p0y, p0z, p1x, p1y, p1z, ax, ay, az, bx, by, bz, cx, cy, cz):
        """Whether segment p0-p1 crosses the plane of triangle abc inside it (a degenerate triangle
        or a segment in its plane never does: distances decide those)."""
        s = crossing(p0x, p0y, p0z, p1x - p0x, p1y - p0y, p1z - p0z, ax, ay, az, bx, by, bz, cx, cy, cz, 1e-300, 0.0)
        return s >= 0.0 and s <= 1.0

    @jit
    def tri_tri_dist2(q, o, tris, t):
        """Squared distance between the triangle ``q[o:o+9]`` (may be degenerate) and triangle t."""
        best = INF
        for i in range(3):
            i0 = o + 3 * i
            i1 = o + 3 * ((i + 1) % 3)
            for j in range(3):
                j0 = 3 * j
                j1 = 3 * ((j + 1) % 3)
                d = seg_seg_dist2(q[i0], q[i0 + 1], q[i0 + 2], q[i1], q[i1 + 1], q[i1 + 2],
                                  tris[t, j0], tris[t, j0 + 1], tris[t, j0 + 2],
                                  tris[t, j1], tris[t, j1 + 1], tris[t, j1 + 2])
                if d < best:
                    best = d
        for i in range(3):
            i0 = o + 3 * i
            d = point_tri(q[i0], q[i0 + 1], q[i0 + 2], tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4],
                          tris[t, 5], tris[t, 6], tris[t, 7], tris[t, 8])
            if d < best:
                best = d
            j0 = 3 * i
            d = point_tri(tris[t, j0], tris[t, j0 + 1], tris[t, j0 + 2], q[o], q[o + 1], q[o + 2], q[o + 3],
                          q[o + 4], q[o + 5], q[o + 6], q[o + 7], q[o + 8])
            if d < best:
                best = d
        if best > 0.0:
            for i in range(3):
                i0 = o + 3 * i
                i1 = o + 3 * ((i + 1) % 3)
                if pierces(q[i0], q[i0 + 1], q[i0 + 2], q[i1], q[i1 + 1], q[i1 + 2], tris[t, 0], tris[t, 1],
                           tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5], tris[t, 6], tris[t, 7], tris[t, 8]):
                    return 0.0
                j0 = 3 * i
                j1 = 3 * ((i + 1) % 3)
                if pierces(tris[t, j0], tris[t, j0 + 1], tris[t, j0 + 2], tris[t, j1], tris[t, j1 + 1],
                           tris[t, j1 + 2], q[o], q[o + 1], q[o + 2], q[o + 3], q[o + 4], q[o + 5], q[o + 6],
                           q[o + 7], q[o + 8]):
                    return 0.0
        return best

    @jit
    def grow_box(box, x, y, z):
        """``box`` (lox, loy, loz, hix, hiy, hiz) grown to hold the point (x, y, z)."""
        lox, loy, loz, hix, hiy, hiz = box
        return min(lox, x), min(loy, y), min(loz, z), max(hix, x), max(hiy, y), max(hiz, z)

    @jit
    def box_box_dist2(node_lo, node_hi, n, box):
        """Squared distance between node n's box and ``box`` (lox, loy, loz, hix, hiy, hiz)."""
        lox, loy, loz, hix, hiy, hiz = box
        d = 0.0
        for k in range(3):
            lo = lox if k == 0 else (loy if k == 1 else loz)
            hi = hix if k == 0 else (hiy if k == 1 else hiz)
            if node_lo[n, k] > hi:
                d += (node_lo[n, k] - hi) ** 2
            elif lo > node_hi[n, k]:
                d += (lo - node_hi[n, k]) ** 2
        return d

    @jit
    def tris_box(q, node_lo, node_hi, n, best, reach):
        # the query: the work array holding the two triangles, and their box
        w, box = q
        return box_box_dist2(node_lo, node_hi, n, box)

    @jit
    def tri_gap(w, o, tris, t):
        """A lower bound of the distance between the triangle ``w[o:o+9]`` and triangle t: their
        gap along the direction between their centroids (any direction bounds two convex sets'
        distance from below), less what rounding may take; -INF where the centroids meet."""
        vx = (tris[t, 0] + tris[t, 3] + tris[t, 6] - w[o] - w[o + 3] - w[o + 6]) / 3.0
        vy = (tris[t, 1] + tris[t, 4] + tris[t, 7] - w[o + 1] - w[o + 4] - w[o + 7]) / 3.0
        vz = (tris[t, 2] + tris[t, 5] + tris[t, 8] - w[o + 2] - w[o + 5] - w[o + 8]) / 3.0
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        if vn <= 0.0:
            return -INF
        low = INF
        top = -INF
        for k in range(3):
            low = min(low, ((tris[t, 3 * k] - w[o]) * vx + (tris[t, 3 * k + 1] - w[o + 1]) * vy
                            + (tris[t, 3 * k + 2] - w[o + 2]) * vz) / vn)
            top = max(top, ((w[o + 3 * k] - w[o]) * vx + (w[o + 3 * k + 1] - w[o + 1]) * vy
                            + (w[o + 3 * k + 2] - w[o + 2]) * vz) / vn)
        return low - top - 1e-12 * (1.0 + abs(tris[t, 0]) + abs(tris[t, 1]) + abs(tris[t, 2]) + abs(w[o])
                                    + abs(w[o + 1]) + abs(w[o + 2]))

    @jit
    def tris_leaf(q, tris, t, best, reach):
        for k in range(2):  # each triangle: its gap first, then (where that does not settle it) exactly
            o = _TRI_A + 9 * k
            g = tri_gap(q[0], o, tris, t)
            if g > 0.0 and g * g >= best:
                continue
            d = tri_tri_dist2(q[0], o, tris, t)
            if d < best:
                best = d
        return best

    tris_search = bvh_search(jit, tris_box, tris_leaf)

    @jit
    def mesh_tris_dist2(q, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack):
        """Smallest squared distance from the two triangles ``q[_TRI_A:+9]``, ``q[_TRI_B:+9]`` to the
        mesh, capped at cap2, returning early below stop2."""
        box = EMPTY_BOX
        for k in range(6):
            o = _TRI_A + 3 * k
            box = grow_box(box, q[o], q[o + 1], q[o + 2])
        return tris_search((q, box), cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack)[0]

    @jit
    def tri_normal(tris, t):
        """Triangle t's normal ``(e1 x e2)`` (its edges from the first vertex; not unit) and the
        product of its two edges' squared lengths (the normal's squared length is that times the
        squared sine of their angle)."""
        e1x = tris[t, 3] - tris[t, 0]
        e1y = tris[t, 4] - tris[t, 1]
        e1z = tris[t, 5] - tris[t, 2]
        e2x = tris[t, 6] - tris[t, 0]
        e2y = tris[t, 7] - tris[t, 1]
        e2z = tris[t, 8] - tris[t, 2]
        return (e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x,
                (e1x * e1x + e1y * e1y + e1z * e1z) * (e2x * e2x + e2y * e2y + e2z * e2z))

    @jit
    def plane_beyond(tris, t, nx, ny, nz, ax, ay, az, bx, by, bz, r, slack):
        """Whether points a and b lie on one side of triangle t's plane (normal n, known to a
        millionth: not a sliver's), both farther than ``r + slack`` from it: then every point of
        segment a-b is farther than r from the triangle. ``slack`` covers the rounding of the
        normal and of coordinates."""
        nn = math.sqrt(nx * nx + ny * ny + nz * nz)
        da = ((ax - tris[t, 0]) * nx + (ay - tris[t, 1]) * ny + (az - tris[t, 2]) * nz) / nn
        db = ((bx - tris[t, 0]) * nx + (by - tris[t, 1]) * ny + (bz - tris[t, 2]) * nz) / nn
        far = r + slack + 1e-9 * (abs(tris[t, 0]) + abs(tris[t, 1]) + abs(tris[t, 2]))
        return (da >= far and db >= far) or (da <= -far and db <= -far)

    @jit
    def capsule_reach(q, best):
        # the capsule's radius, and how near its middle a triangle must come to lower best: no point
        # of the segment is nearer a triangle than its middle less ``pad`` (half its length, and the
        # rounding of coordinates this large)
        r = math.sqrt(best)
        return r, (r * (1.0 + 1e-12) + q[13]) ** 2

    @jit
    def capsule_box(q, node_lo, node_hi, n, best, reach):
        # the query: the segment a-b, its unit direction u and length, its middle m, and pad
        ax, ay, az, bx, by, bz, ux, uy, uz, length, mx, my, mz, pad = q
        r = reach[0]
        return 0.0 if g.box_near_segment(node_lo, node_hi, n, ax, ay, az, bx, by, bz, r, r, r, r) else best

    @jit
    def segment_leaf(q, tris, t, best, reach):
        ax, ay, az, bx, by, bz, ux, uy, uz, length, mx, my, mz, pad = q
        slack = 1e-9 * (1.0 + abs(mx) + abs(my) + abs(mz) + pad)
        nx, ny, nz, ee = tri_normal(tris, t)
        sliver = not nx * nx + ny * ny + nz * nz > 1e-12 * ee  # (its normal not known to a millionth)
        if not sliver and plane_beyond(tris, t, nx, ny, nz, ax, ay, az, bx, by, bz, reach[0], slack):
            return best  # both ends farther than the reach on one side of the triangle's plane
        dm = point_tri(mx, my, mz, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5], tris[t, 6],
                       tris[t, 7], tris[t, 8])
        if dm > reach[1]:
            return best  # a cheap bound first
        da = point_tri(ax, ay, az, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5], tris[t, 6],
                       tris[t, 7], tris[t, 8])
        db = point_tri(bx, by, bz, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5], tris[t, 6],
                       tris[t, 7], tris[t, 8])
        if not sliver:
            # along the segment the distance to the triangle is convex: beyond the middle it stays
            # above the line through the middle's and the far end's (and the ends' own), so no
            # point comes nearer than the least of those (not on a sliver, whose point distances
            # may fall short of the true ones by its width)
            fa = math.sqrt(da)
            fb = math.sqrt(db)
            fm = math.sqrt(dm)
            if min(fa, fb, fm, 2.0 * fm - fa, 2.0 * fm - fb) >= reach[0] + slack:
                return best
        return min(axis_dist(tris, t, ax, ay, az, ux, uy, uz, 0.0, length), da, db)

    segment_search = bvh_search(jit, capsule_box, segment_leaf, reach_of=capsule_reach)

    @jit
    def mesh_segment_dist2(ax, ay, az, bx, by, bz, cap2, stop2, node_lo, node_hi, node_child, node_range, tris,
                           stack):
        """Smallest squared distance from segment a-b to the mesh (capped at cap2, returning early
        below stop2): per triangle the least of the segment's distance within the slab it spans
        and its two ends' distances."""
        dx = bx - ax
        dy = by - ay
        dz = bz - az
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        if length <= 1e-12:
            return point_dist(ax, ay, az, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack)
        mx = ax + 0.5 * dx
        my = ay + 0.5 * dy
        mz = az + 0.5 * dz
        pad = 0.5 * length + 1e-12 * (1.0 + abs(mx) + abs(my) + abs(mz))
        q = (ax, ay, az, bx, by, bz, dx / length, dy / length, dz / length, length, mx, my, mz, pad)
        return segment_search(q, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack)[0]

    @jit
    def seg2d_dist2(p0x, p0y, p1x, p1y, q0x, q0y, q1x, q1y):
        """Squared distance between 2-D segments p0-p1 and q0-q1 (0 when they cross)."""
        d = INF
        for k in range(4):
            if k == 0:
                ax, ay, bx, by, cx, cy = p0x, p0y, q0x, q0y, q1x, q1y
            elif k == 1:
                ax, ay, bx, by, cx, cy = p1x, p1y, q0x, q0y, q1x, q1y
            elif k == 2:
                ax, ay, bx, by, cx, cy = q0x, q0y, p0x, p0y, p1x, p1y
            else:
                ax, ay, bx, by, cx, cy = q1x, q1y, p0x, p0y, p1x, p1y
            ex = cx - bx
            ey = cy - by
            ee = ex * ex + ey * ey
            s = 0.0
            if ee > 0.0:
                s = min(1.0, max(0.0, ((ax - bx) * ex + (ay - by) * ey) / ee))
            wx = ax - bx - s * ex
            wy = ay - by - s * ey
            d = min(d, wx * wx + wy * wy)
        if d > 0.0:
            o1 = (p1x - p0x) * (q0y - p0y) - (p1y - p0y) * (q0x - p0x)
            o2 = (p1x - p0x) * (q1y - p0y) - (p1y - p0y) * (q1x - p0x)
            o3 = (q1x - q0x) * (p0y - q0y) - (q1y - q0y) * (p0x - q0x)
            o4 = (q1x - q0x) * (p1y - q0y) - (q1y - q0y) * (p1x - q0x)
            if o1 * o2 < 0.0 and o3 * o4 < 0.0:
                return 0.0
        return d

    @jit
    def clip_slab(w, src, n, dst, h0, keep_above):
        """Clip the polygon of ``n`` points (h, x, y) at ``w[src:]`` by h >= h0 (keep_above) or
        h <= h0 into ``w[dst:]``; returns its point count (at most n + 1)."""
        m = 0
        for k in range(n):
            a = src + 3 * k
            b = src + 3 * ((k + 1) % n)
            ha = w[a] - h0 if keep_above else h0 - w[a]
            hb = w[b] - h0 if keep_above else h0 - w[b]
            if ha >= 0.0:
                w[dst + 3 * m] = w[a]
                w[dst + 3 * m + 1] = w[a + 1]
                w[dst + 3 * m + 2] = w[a + 2]
                m += 1
            if (ha >= 0.0) != (hb >= 0.0):
                f = ha / (ha - hb)
                w[dst + 3 * m] = w[a] + f * (w[b] - w[a])
                w[dst + 3 * m + 1] = w[a + 1] + f * (w[b + 1] - w[a + 1])
                w[dst + 3 * m + 2] = w[a + 2] + f * (w[b + 2] - w[a + 2])
                m += 1
        return m

    @jit
    def stadium_tri_dist2(tris, t, ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, w):
        """Distance² across the axis between triangle t, clipped to s0 <= (p - a)·u <= s1, and the
        2-D segment from 0 to (vx, vy) in the frame (e1, e2); INF when the triangle misses the slab."""
        for k in range(3):
            px = tris[t, 3 * k] - ax
            py = tris[t, 3 * k + 1] - ay
            pz = tris[t, 3 * k + 2] - az
            w[_POLY + 3 * k] = px * ux + py * uy + pz * uz
            w[_POLY + 3 * k + 1] = px * e1x + py * e1y + pz * e1z
            w[_POLY + 3 * k + 2] = px * e2x + py * e2y + pz * e2z
        n = clip_slab(w, _POLY, 3, _POLY_B, s0, True)
        if n == 0:
            return INF
        n = clip_slab(w, _POLY_B, n, _POLY, s1, False)
        if n == 0:
            return INF
        best = INF
        for k in range(n):
            a = _POLY + 3 * k
            b = _POLY + 3 * ((k + 1) % n)
            d = seg2d_dist2(0.0, 0.0, vx, vy, w[a + 1], w[a + 2], w[b + 1], w[b + 2])
            if d < best:
                best = d
        if best > 0.0 and n >= 3:
            pos = False
            neg = False
            for k in range(n):
                a = _POLY + 3 * k
                b = _POLY + 3 * ((k + 1) % n)
                c = (w[b + 1] - w[a + 1]) * (0.0 - w[a + 2]) - (w[b + 2] - w[a + 2]) * (0.0 - w[a + 1])
                if c > 0.0:
                    pos = True
                elif c < 0.0:
                    neg = True
            if pos != neg:
                return 0.0
        return best

    @jit
    def prism_box(q, node_lo, node_hi, n, best, reach):
        # the query: the prism of :func:`mesh_stadium_dist2`, its box, and the work array
        ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, box, w = q
        d = box_box_dist2(node_lo, node_hi, n, box)
        if d >= best:
            return d
        # a box whose extent along the axis misses the slab holds no triangle the prism meets
        hc = (0.5 * (node_lo[n, 0] + node_hi[n, 0]) - ax) * ux + (0.5 * (node_lo[n, 1] + node_hi[n, 1]) - ay) * uy \
            + (0.5 * (node_lo[n, 2] + node_hi[n, 2]) - az) * uz
        he = 0.5 * ((node_hi[n, 0] - node_lo[n, 0]) * abs(ux) + (node_hi[n, 1] - node_lo[n, 1]) * abs(uy)
                    + (node_hi[n, 2] - node_lo[n, 2]) * abs(uz))
        # rounding (of coordinates as large as the box's or the axis point's): a vertex on a face stays in
        slack = 1e-12 * (abs(node_hi[n, 0]) + abs(node_hi[n, 1]) + abs(node_hi[n, 2]) + abs(ax) + abs(ay)
                         + abs(az) + he + abs(s0) + abs(s1)) + 1e-12
        if hc + he < s0 - slack or hc - he > s1 + slack:
            return best
        return d

    @jit
    def leaning_prism_box(q, node_lo, node_hi, n, best, reach):
        # (:func:`prism_box`, for an axis whose prism's box is much wider than the prism) a point
        # of the slab within reach across the axis of the stadium's segment lies within reach of
        # the band the axis sweeps, so within reach + |v| / 2 of the axis through the sweep's
        # middle (over [s0, s1], flat ends: the disks' extent along each coordinate axis)
        d = prism_box(q, node_lo, node_hi, n, best, reach)
        if d >= best:
            return d
        ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, box, w = q
        hv = 0.5 * math.sqrt(vx * vx + vy * vy)
        mx = ax + 0.5 * (vx * e1x + vy * e2x)
        my = ay + 0.5 * (vx * e1y + vy * e2y)
        mz = az + 0.5 * (vx * e1z + vy * e2z)
        # (rounding of coordinates this large: a triangle at the reach is never dropped)
        rr = (reach + hv) * (1.0 + 1e-12) + 1e-12 * (1.0 + abs(mx) + abs(my) + abs(mz) + abs(s0) + abs(s1))
        if not g.box_near_cylinder(node_lo, node_hi, n, mx + s0 * ux, my + s0 * uy, mz + s0 * uz, mx + s1 * ux,
                                   my + s1 * uy, mz + s1 * uz, ux, uy, uz, rr):
            return best
        return d

    @jit
    def prism_leaf(q, tris, t, best, reach):
        ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, box, w = q
        return stadium_tri_dist2(tris, t, ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, w)

    @jit
    def stadium_query(ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, w):
        """The query of the stadium prism of :func:`stadium_tri_dist2` for :func:`prism_box` and
        the leaves: its arguments with the box of its four corner points (the distance asked
        about widens it in the box test) and the work array."""
        box = EMPTY_BOX
        for k in range(4):
            h = s0 if k < 2 else s1
            f = 0.0 if k % 2 == 0 else 1.0
            box = grow_box(box, ax + h * ux + f * (vx * e1x + vy * e2x), ay + h * uy + f * (vx * e1y + vy * e2y),
                           az + h * uz + f * (vx * e1z + vy * e2z))
        return (ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, box, w)

    @jit
    def hull2d_dist2(w, n):
        """Squared distance from the origin to the convex hull of the ``n`` 2-D points (x, y) at
        ``w[_SHEAR:]`` (sorted there; the hull's indices at ``w[_SHEAR_HULL:]``): 0 inside it."""
        if n == 0:
            return INF
        for i in range(1, n):  # by x, then y
            x = w[_SHEAR + 2 * i]
            y = w[_SHEAR + 2 * i + 1]
            j = i - 1
            while j >= 0 and (w[_SHEAR + 2 * j] > x or (w[_SHEAR + 2 * j] == x and w[_SHEAR + 2 * j + 1] > y)):
                w[_SHEAR + 2 * j + 2] = w[_SHEAR + 2 * j]
                w[_SHEAR + 2 * j + 3] = w[_SHEAR + 2 * j + 1]
                j -= 1
            w[_SHEAR + 2 * j + 2] = x
            w[_SHEAR + 2 * j + 3] = y
        # Andrew's monotone chain: the lower hull left to right, the upper back, counter-clockwise,
        # the first point again at the end (m entries)
        m = 0
        m_lower = 0
        for k in range(2 * n - 1):
            if k == n:
                m_lower = m
            i = k if k < n else 2 * n - 2 - k
            low = 2 if k < n else m_lower + 1
            px = w[_SHEAR + 2 * i]
            py = w[_SHEAR + 2 * i + 1]
            while m >= low:
                a = int(w[_SHEAR_HULL + m - 2])
                b = int(w[_SHEAR_HULL + m - 1])
                qx = w[_SHEAR + 2 * a]
                qy = w[_SHEAR + 2 * a + 1]
                if (w[_SHEAR + 2 * b] - qx) * (py - qy) - (w[_SHEAR + 2 * b + 1] - qy) * (px - qx) > 0.0:
                    break
                m -= 1
            w[_SHEAR_HULL + m] = i
            m += 1
        if m == 1:
            return w[_SHEAR] * w[_SHEAR] + w[_SHEAR + 1] * w[_SHEAR + 1]
        best = INF
        inside = m >= 4  # (three corners at least)
        for k in range(m - 1):
            a = int(w[_SHEAR_HULL + k])
            b = int(w[_SHEAR_HULL + k + 1])
            ax = w[_SHEAR + 2 * a]
            ay = w[_SHEAR + 2 * a + 1]
            ex = w[_SHEAR + 2 * b] - ax
            ey = w[_SHEAR + 2 * b + 1] - ay
            if ex * (0.0 - ay) - ey * (0.0 - ax) < 0.0:
                inside = False  # the origin right of an edge
            ee = ex * ex + ey * ey
            f = 0.0
            if ee > 0.0:
                f = min(1.0, max(0.0, -(ax * ex + ay * ey) / ee))
            dx = ax + f * ex
            dy = ay + f * ey
            best = min(best, dx * dx + dy * dy)
        return 0.0 if inside else best

    @jit
    def sheared_tri_dist2(tris, t, ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, h0, h1, dh, dx, dy, w):
        """Distance² across the axis u between triangle t and the sweep of the axis segment
        a + [h0, h1]·u moved by (dh along u, (dx, dy) across it in the frame (e1, e2)): the least,
        over the poses, of the distance across the axis from the pose's segment to the part of the
        triangle level with it. The slice of the triangle less the sweep's path, {p - s·move}, level
        with [h0, h1], projected across the axis: the hull of its corners within the slab and its
        edges' crossings of the slab's faces, and its distance from the origin."""
        n = 0
        for k in range(6):  # the triangle's corners, then moved back along the move
            c = k % 3
            px = tris[t, 3 * c] - ax
            py = tris[t, 3 * c + 1] - ay
            pz = tris[t, 3 * c + 2] - az
            h = px * ux + py * uy + pz * uz
            x = px * e1x + py * e1y + pz * e1z
            y = px * e2x + py * e2y + pz * e2z
            if k >= 3:
                h -= dh
                x -= dx
                y -= dy
            w[_POLY_B + 3 * k] = h
            w[_POLY_B + 3 * k + 1] = x
            w[_POLY_B + 3 * k + 2] = y
            if h0 <= h <= h1:
                w[_SHEAR + 2 * n] = x
                w[_SHEAR + 2 * n + 1] = y
                n += 1
        for e in range(9):  # the prism's edges: the triangle's, the moved one's, and between them
            if e < 3:
                i = e
                j = (e + 1) % 3
            elif e < 6:
                i = e
                j = 3 + (e - 2) % 3
            else:
                i = e - 6
                j = e - 3
            hi_ = w[_POLY_B + 3 * i]
            hj = w[_POLY_B + 3 * j]
            for c in range(2):
                level = h0 if c == 0 else h1
                if (hi_ - level) * (hj - level) < 0.0:
                    f = (level - hi_) / (hj - hi_)
                    w[_SHEAR + 2 * n] = w[_POLY_B + 3 * i + 1] + f * (w[_POLY_B + 3 * j + 1] - w[_POLY_B + 3 * i + 1])
                    w[_SHEAR + 2 * n + 1] = w[_POLY_B + 3 * i + 2] + f * (w[_POLY_B + 3 * j + 2]
                                                                          - w[_POLY_B + 3 * i + 2])
                    n += 1
        return hull2d_dist2(w, n)

    @jit
    def sheared_leaf(q, tris, t, best, reach):
        # the prism of the sweep first (it holds the sweep: never farther), the sweep where it is near
        ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, box, w = q
        d = stadium_tri_dist2(tris, t, ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, w)
        if d >= best:
            return d
        return max(d, sheared_tri_dist2(tris, t, ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, w[_SHEAR_AXIS],
                                        w[_SHEAR_AXIS + 1], w[_SHEAR_AXIS + 2], vx, vy, w))

    prism_search = bvh_search(jit, prism_box, prism_leaf)
    leaning_prism_search = bvh_search(jit, leaning_prism_box, prism_leaf)
    sheared_search = bvh_search(jit, prism_box, sheared_leaf)

    @jit
    def sheared_clear(ta, u, tb, lo, hi, rad, node_lo, node_hi, node_child, node_range, tris, stack, w):
        """Whether the flat cylinder [lo, hi] along the fixed unit axis u, of radius rad, swept from
        tip ta to tip tb (3-arrays), keeps off the mesh: its exact sweep (:func:`sheared_tri_dist2`),
        searched within the prism that holds it (a move that climbs or sinks along the axis takes
        that prism lower and higher than any of its poses)."""
        if rad <= 0.0:
            return True
        e1x, e1y, e1z, e2x, e2y, e2z = normal_frame(u[0], u[1], u[2])
        tm = 0.5 * (lo + hi)
        ax = ta[0] + tm * u[0]
        ay = ta[1] + tm * u[1]
        az = ta[2] + tm * u[2]
        mx = tb[0] - ta[0]
        my = tb[1] - ta[1]
        mz = tb[2] - ta[2]
        dh = mx * u[0] + my * u[1] + mz * u[2]
        vx = mx * e1x + my * e1y + mz * e1z
        vy = mx * e2x + my * e2y + mz * e2z
        w[_SHEAR_AXIS] = lo - tm
        w[_SHEAR_AXIS + 1] = hi - tm
        w[_SHEAR_AXIS + 2] = dh
        q = stadium_query(ax, ay, az, u[0], u[1], u[2], e1x, e1y, e1z, e2x, e2y, e2z, lo - tm + min(0.0, dh),
                          hi - tm + max(0.0, dh), vx, vy, w)
        need2 = rad * rad
        return sheared_search(q, need2, need2, node_lo, node_hi, node_child, node_range, tris, stack)[0] >= need2

    @jit
    def mesh_stadium_dist2(ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, cap2, stop2,
                           node_lo, node_hi, node_child, node_range, tris, stack, w):
        """Smallest squared distance across the axis from the stadium prism (see
        :func:`stadium_tri_dist2`) to the mesh: a flat cylinder of radius rad over [s0, s1], swept
        across its axis by (vx, vy), overlaps the mesh iff this is below rad²."""
        q = stadium_query(ax, ay, az, ux, uy, uz, e1x, e1y, e1z, e2x, e2y, e2z, s0, s1, vx, vy, w)
        # an axis leaning off x, y and z by more than the distance asked: the prism's box is that
        # much wider than the prism, and boxes are tested against the band round its mid axis too
        if (s1 - s0) * math.sqrt(max(0.0, 1.0 - max(ux * ux, uy * uy, uz * uz))) > math.sqrt(cap2):
            return leaning_prism_search(q, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack)[0]
        return prism_search(q, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack)[0]

    @jit
    def column_box(q, node_lo, node_hi, n):
        # the query: the point p, and the kinds of the triangles
        px, py, pz, kind = q
        return not (px < node_lo[n, 0] or px > node_hi[n, 0] or py < node_lo[n, 1] or py > node_hi[n, 1]
                    or node_hi[n, 2] <= pz)

    @jit
    def winding_leaf(q, tris, t, state):
        px, py, pz, kind = q
        wind, odd = state
        side, z = hit(tris, t, 2, px, py)
        if side != 0 and z > pz:
            if kind[t] == 1:
                wind += side
            else:
                odd = not odd
        return wind, odd

    crossings_above = bvh_visit(jit, column_box, winding_leaf)

    @jit
    def inside(px, py, pz, in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor, stack):
        """Whether p lies in the material: the crossings of the line up from p with the solid
        triangles (``in_kind`` 1, signed) wind around it, or it is above ``floor`` with an odd
        number of sheet triangles (``in_kind`` 0) above it (the solid an open surface bounds below)."""
        wind, odd = crossings_above((px, py, pz, in_kind), (0, False), in_lo, in_hi, in_child, in_range, in_tris,
                                    stack)
        return wind > 0 or (odd and pz >= floor)

    @jit
    def normal_frame(ux, uy, uz):
        """Two unit vectors completing the unit u to an orthonormal frame."""
        if abs(ux) < 0.9:
            ex, ey, ez = 0.0, -uz, uy
        else:
            ex, ey, ez = uz, 0.0, -ux
        en = math.sqrt(ex * ex + ey * ey + ez * ez)
        ex /= en
        ey /= en
        ez /= en
        return ex, ey, ez, uy * ez - uz * ey, uz * ex - ux * ez, ux * ey - uy * ex

    @jit
    def turned(x, y, z, ax, ay, az, bx, by, bz):
        """Vector (x, y, z) turned by the rotation that takes unit a to unit b about a x b."""
        nx = ay * bz - az * by
        ny = az * bx - ax * bz
        nz = ax * by - ay * bx
        s = math.sqrt(nx * nx + ny * ny + nz * nz)
        c = ax * bx + ay * by + az * bz
        if s <= 1e-15:
            return x, y, z
        nx /= s
        ny /= s
        nz /= s
        d = nx * x + ny * y + nz * z
        cx = ny * z - nz * y
        cy = nz * x - nx * z
        cz = nx * y - ny * x
        return (x * c + cx * s + nx * d * (1.0 - c), y * c + cy * s + ny * d * (1.0 - c),
                z * c + cz * s + nz * d * (1.0 - c))

    @jit
    def push_halves(w, sp, a, b):
        """Push the two halves of [a, b] on the stack of ``sp`` pairs at the start of ``w``; the
        pairs on it after."""
        m = 0.5 * (a + b)
        w[2 * sp] = a
        w[2 * sp + 1] = m
        w[2 * sp + 2] = m
        w[2 * sp + 3] = b
        return sp + 2

    @jit
    def on_circle(cx, cy, cz, rho, cos, sin, e1x, e1y, e1z, e2x, e2y, e2z):
        """The point at the angle of cosine ``cos`` and sine ``sin`` on the circle of radius rho
        about c in the plane of the unit vectors e1, e2."""
        return (cx + rho * (cos * e1x + sin * e2x), cy + rho * (cos * e1y + sin * e2y),
                cz + rho * (cos * e1z + sin * e2z))

    @jit
    def put_point(w, o, px, py, pz):
        w[o] = px
        w[o + 1] = py
        w[o + 2] = pz

    @jit
    def quad_clear(w, a0x, a0y, a0z, a1x, a1y, a1z, b0x, b0y, b0z, b1x, b1y, b1z, need,
                   node_lo, node_hi, node_child, node_range, tris, stack):
        """Whether the two triangles (a0, a1, b1), (a0, b1, b0) keep ``need`` mm from the mesh."""
        if need <= 0.0:
            return True
        put_point(w, _TRI_A, a0x, a0y, a0z)
        put_point(w, _TRI_A + 3, a1x, a1y, a1z)
        put_point(w, _TRI_A + 6, b1x, b1y, b1z)
        put_point(w, _TRI_B, a0x, a0y, a0z)
        put_point(w, _TRI_B + 3, b1x, b1y, b1z)
        put_point(w, _TRI_B + 6, b0x, b0y, b0z)
        need2 = need * need
        return mesh_tris_dist2(w, need2, need2, node_lo, node_hi, node_child, node_range, tris, stack) >= need2

    @jit
    def in_tetra(px, py, pz, w, o):
        """Whether p lies in the tetrahedron of the four corners ``w[o:o+12]`` (or on its boundary;
        a flat one holds what its signed volumes, all near 0, happen to say)."""
        pos = False
        neg = False
        for k in range(4):
            # the volume with corner k replaced by p, against the others in order
            ax = px if k == 0 else w[o]
            ay = py if k == 0 else w[o + 1]
            az = pz if k == 0 else w[o + 2]
            bx = px if k == 1 else w[o + 3]
            by = py if k == 1 else w[o + 4]
            bz = pz if k == 1 else w[o + 5]
            cx = px if k == 2 else w[o + 6]
            cy = py if k == 2 else w[o + 7]
            cz = pz if k == 2 else w[o + 8]
            dx = px if k == 3 else w[o + 9]
            dy = py if k == 3 else w[o + 10]
            dz = pz if k == 3 else w[o + 11]
            ux, uy, uz = bx - ax, by - ay, bz - az
            vx, vy, vz = cx - ax, cy - ay, cz - az
            wx, wy, wz = dx - ax, dy - ay, dz - az
            v = ux * (vy * wz - vz * wy) + uy * (vz * wx - vx * wz) + uz * (vx * wy - vy * wx)
            if v > 0.0:
                pos = True
            elif v < 0.0:
                neg = True
        return not (pos and neg)

    @jit
    def hull_reach(q, best):
        # the query: the work array holding the hull, the segment a-b between the middles of its
        # two sides (a, b, unit u, length, middle m, pad: half the length and rounding) and how far
        # the hull strays from that segment (``spread``): no point of it is farther, so a triangle
        # farther than r + spread from the segment, or than that plus pad from m, is farther than r
        r = math.sqrt(best)
        rr = r * (1.0 + 1e-12) + q[15]
        return r, rr, (rr + q[14]) ** 2

    @jit
    def hull_box(q, node_lo, node_hi, n, best, reach):
        w, ax, ay, az, bx, by, bz, ux, uy, uz, length, mx, my, mz, pad, spread = q
        rr = reach[1]
        return 0.0 if g.box_near_segment(node_lo, node_hi, n, ax, ay, az, bx, by, bz, rr, rr, rr, rr) else best

    @jit
    def hull_leaf(q, tris, t, best, reach):
        w, ax, ay, az, bx, by, bz, ux, uy, uz, length, mx, my, mz, pad, spread = q
        r = reach[0]
        # the gap along the direction from the segment's point nearest the triangle's centroid to
        # the centroid, between the hull's corners and the triangle's (any direction bounds the
        # distance of two convex sets from below; this one is near the closest points' where the
        # tool moves along the surface, its corners then spread across it)
        gx = (tris[t, 0] + tris[t, 3] + tris[t, 6]) / 3.0 - mx
        gy = (tris[t, 1] + tris[t, 4] + tris[t, 7]) / 3.0 - my
        gz = (tris[t, 2] + tris[t, 5] + tris[t, 8]) / 3.0 - mz
        s = min(0.5 * length, max(-0.5 * length, gx * ux + gy * uy + gz * uz))
        vx = gx - s * ux
        vy = gy - s * uy
        vz = gz - s * uz
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        if vn > 0.0:
            low = INF  # the triangle's least reach along v, the hull's greatest
            for k in range(3):
                low = min(low, ((tris[t, 3 * k] - mx) * vx + (tris[t, 3 * k + 1] - my) * vy
                                + (tris[t, 3 * k + 2] - mz) * vz) / vn)
            top = -INF
            for k in range(4):
                o = _HULL + 36 + 3 * k
                top = max(top, ((w[o] - mx) * vx + (w[o + 1] - my) * vy + (w[o + 2] - mz) * vz) / vn)
            slack = 1e-12 * (1.0 + abs(tris[t, 0]) + abs(tris[t, 1]) + abs(tris[t, 2]) + abs(mx) + abs(my)
                             + abs(mz) + pad)
            if low - top >= r + slack:
                return best
        # the hull wholly beyond r on one side of the triangle's plane (a facet along the tool)
        nx, ny, nz, _ = tri_normal(tris, t)
        nn = math.sqrt(nx * nx + ny * ny + nz * nz)
        if nn > 0.0:
            lo = INF
            hi = -INF
            for k in range(4):
                o = _HULL + 36 + 3 * k
                sd = ((w[o] - tris[t, 0]) * nx + (w[o + 1] - tris[t, 1]) * ny + (w[o + 2] - tris[t, 2]) * nz) / nn
                lo = min(lo, sd)
                hi = max(hi, sd)
            # (rounding of coordinates this large)
            slack = 1e-12 * (1.0 + abs(tris[t, 0]) + abs(tris[t, 1]) + abs(tris[t, 2]) + abs(mx) + abs(my)
                             + abs(mz) + pad)
            if lo >= r + slack or hi <= -r - slack:
                return best
        # cheap bounds: the middle of the segment, then the segment
        if point_tri(mx, my, mz, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5], tris[t, 6],
                     tris[t, 7], tris[t, 8]) > reach[2]:
            return best
        d = axis_dist(tris, t, ax, ay, az, ux, uy, uz, 0.0, length)
        d = min(d, point_tri(ax, ay, az, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5],
                             tris[t, 6], tris[t, 7], tris[t, 8]))
        d = min(d, point_tri(bx, by, bz, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5],
                             tris[t, 6], tris[t, 7], tris[t, 8]))
        if d > reach[1] * reach[1]:
            return best
        d = best
        for f in range(4):
            d = min(d, tri_tri_dist2(w, _HULL + 9 * f, tris, t))
            if d <= 0.0:
                return 0.0
        # no face meets the triangle: it is out of the hull, or wholly in it
        if in_tetra(tris[t, 0], tris[t, 1], tris[t, 2], w, _HULL + 36):
            return 0.0
        return d

    hull_search = bvh_search(jit, hull_box, hull_leaf, reach_of=hull_reach)

    @jit
    def patch_clear(w, ta, ua, tb, ub, h0, h1, need, node_lo, node_hi, node_child, node_range, tris, stack):
        """Whether the segment [h0, h1] of the axis, swept from pose a to pose b (tips ``ta, tb``,
        unit axes ``ua, ub``: 3-arrays) as the bilinear patch of its two positions, keeps ``need``
        mm from the mesh: the patch lies in the tetrahedron of its four corners (each of its points
        a convex combination of them), whose distance to a triangle is exact (its faces, and the
        triangle wholly inside)."""
        if need <= 0.0:
            return True
        for k in range(3):
            w[_HULL + 36 + k] = ta[k] + h0 * ua[k]
            w[_HULL + 39 + k] = ta[k] + h1 * ua[k]
            w[_HULL + 42 + k] = tb[k] + h0 * ub[k]
            w[_HULL + 45 + k] = tb[k] + h1 * ub[k]
        for f in range(4):  # faces (0 1 2) (0 1 3) (0 2 3) (1 2 3): face f leaves corner 3 - f out
            for j in range(3):
                c = j + (1 if j >= 3 - f else 0)
                for k in range(3):
                    w[_HULL + 9 * f + 3 * j + k] = w[_HULL + 36 + 3 * c + k]
        # the segment between the middles of the sides a0-b0 and a1-b1; every corner lies within
        # half its side's length of it, so the hull does
        o = _HULL + 36
        ax = 0.5 * (w[o] + w[o + 6])
        ay = 0.5 * (w[o + 1] + w[o + 7])
        az = 0.5 * (w[o + 2] + w[o + 8])
        bx = 0.5 * (w[o + 3] + w[o + 9])
        by = 0.5 * (w[o + 4] + w[o + 10])
        bz = 0.5 * (w[o + 5] + w[o + 11])
        s0 = 0.5 * math.sqrt((w[o + 6] - w[o]) ** 2 + (w[o + 7] - w[o + 1]) ** 2 + (w[o + 8] - w[o + 2]) ** 2)
        s1 = 0.5 * math.sqrt((w[o + 9] - w[o + 3]) ** 2 + (w[o + 10] - w[o + 4]) ** 2 + (w[o + 11] - w[o + 5]) ** 2)
        dx = bx - ax
        dy = by - ay
        dz = bz - az
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        if length <= 1e-12:
            return False
        mx = ax + 0.5 * dx
        my = ay + 0.5 * dy
        mz = az + 0.5 * dz
        pad = 0.5 * length + 1e-12 * (1.0 + abs(mx) + abs(my) + abs(mz))
        spread = max(s0, s1) * (1.0 + 1e-12) + 1e-12 * (1.0 + abs(mx) + abs(my) + abs(mz))
        q = (w, ax, ay, az, bx, by, bz, dx / length, dy / length, dz / length, length, mx, my, mz, pad, spread)
        need2 = need * need
        return hull_search(q, need2, need2, node_lo, node_hi, node_child, node_range, tris, stack)[0] >= need2

    @jit
    def ring_clear(ta, ua, tb, ub, t_ring, rho, r, limit, node_lo, node_hi, node_child, node_range, tris, stack, w):
        """Whether the rounded end (``r`` already grown) keeps within ``limit`` between poses a and b
        (tips ``ta, tb``, unit axes ``ua, ub``: 3-arrays)."""
        cth = min(1.0, max(-1.0, ua[0] * ub[0] + ua[1] * ub[1] + ua[2] * ub[2]))
        dev = math.sqrt(t_ring * t_ring + rho * rho) * (1.0 - math.sqrt(0.5 * (1.0 + cth)))
        e1x, e1y, e1z, e2x, e2y, e2z = normal_frame(ua[0], ua[1], ua[2])
        f1x, f1y, f1z = turned(e1x, e1y, e1z, ua[0], ua[1], ua[2], ub[0], ub[1], ub[2])
        f2x, f2y, f2z = turned(e2x, e2y, e2z, ua[0], ua[1], ua[2], ub[0], ub[1], ub[2])
        cax = ta[0] + t_ring * ua[0]
        cay = ta[1] + t_ring * ua[1]
        caz = ta[2] + t_ring * ua[2]
        cbx = tb[0] + t_ring * ub[0]
        cby = tb[1] + t_ring * ub[1]
        cbz = tb[2] + t_ring * ub[2]
        arcs = 1 if rho <= 0.0 else RING_ARCS
        sp = 0
        for k in range(arcs):
            w[2 * sp] = 2.0 * math.pi * k / arcs
            w[2 * sp + 1] = 2.0 * math.pi * (k + 1) / arcs
            sp += 1
        while sp > 0:
            sp -= 1
            f0 = w[2 * sp]
            f1 = w[2 * sp + 1]
            c0 = math.cos(f0)
            s0 = math.sin(f0)
            c1 = math.cos(f1)
            s1 = math.sin(f1)
            # corners: (a, f0) (a, f1) (b, f0) (b, f1); triangles (a0, a1, b1) and (a0, b1, b0)
            a0x, a0y, a0z = on_circle(cax, cay, caz, rho, c0, s0, e1x, e1y, e1z, e2x, e2y, e2z)
            a1x, a1y, a1z = on_circle(cax, cay, caz, rho, c1, s1, e1x, e1y, e1z, e2x, e2y, e2z)
            b0x, b0y, b0z = on_circle(cbx, cby, cbz, rho, c0, s0, f1x, f1y, f1z, f2x, f2y, f2z)
            b1x, b1y, b1z = on_circle(cbx, cby, cbz, rho, c1, s1, f1x, f1y, f1z, f2x, f2y, f2z)
            tx = a0x - a1x - b0x + b1x
            ty = a0y - a1y - b0y + b1y
            tz = a0z - a1z - b0z + b1z
            twist = 0.25 * math.sqrt(tx * tx + ty * ty + tz * tz)
            sagitta = rho * (1.0 - math.cos(0.5 * (f1 - f0)))
            need = r + sagitta + dev + twist - limit
            if rho <= 0.0:  # a ball: its centre's chord
                need2 = need * need
                if need <= 0.0 or mesh_segment_dist2(a0x, a0y, a0z, b0x, b0y, b0z, need2, need2, node_lo, node_hi,
                                                     node_child, node_range, tris, stack) >= need2:
                    continue
                return False
            if quad_clear(w, a0x, a0y, a0z, a1x, a1y, a1z, b0x, b0y, b0z, b1x, b1y, b1z, need,
                          node_lo, node_hi, node_child, node_range, tris, stack):
                continue
            # halving the chord helps only while its own slack (sagitta, twist) is what fails
            if rho <= 0.0 or f1 - f0 < MIN_ARC or sagitta + twist <= 0.25 * dev or sp + 2 > ARC_STACK:
                return False
            sp = push_halves(w, sp, f0, f1)
        return True

    @jit
    def band_clear(ta, ua, tb, ub, mx, my, mz, e1x, e1y, e1z, e2x, e2y, e2z, b0, b1, s_lo, rad, shorten, chord,
                   need_extra, node_lo, node_hi, node_child, node_range, tris, stack, w):
        """Whether the band [b0, b1] of a cylinder of radius ``rad`` (its part above ``s_lo``) keeps
        ``rad + need_extra`` across the axis from the mesh between poses a and b: the prism of the
        band about its middle, along the mid axis m, the slack of its turn added (the middle's path
        bows by ``|t_m| shorten``; the band turns about it by theta/2 at most, moving its side by
        ``half · chord`` across and its rim by ``rad · chord`` along the axis, chord = sin(theta/2))."""
        tm = 0.5 * (b0 + b1)
        half = 0.5 * (b1 - b0)
        bow = abs(tm) * shorten
        across = half * chord + bow
        along = rad * chord + bow
        cax, cay, caz, vx, vy, vz = g.axis_point_move(ta, ua, tb, ub, tm)
        vu = vx * mx + vy * my + vz * mz
        v1 = vx * e1x + vy * e1y + vz * e1z
        v2 = vx * e2x + vy * e2y + vz * e2z
        lo = max(b0, s_lo) - tm - along + min(0.0, vu)
        hi = b1 - tm + along + max(0.0, vu)
        if lo >= hi:
            return True
        need = rad + need_extra + across
        if need <= 0.0:
            return True
        need2 = need * need
        return mesh_stadium_dist2(cax, cay, caz, mx, my, mz, e1x, e1y, e1z, e2x, e2y, e2z, lo, hi, v1, v2, need2,
                                  need2, node_lo, node_hi, node_child, node_range, tris, stack, w) >= need2

    @jit
    def cylinder_clear(ta, ua, tb, ub, t0, t1, rad, base, grow, limit,
                       node_lo, node_hi, node_child, node_range, tris, stack, w):
        """Whether the flat cylinder [t0, t1] of radius rad (grown by ``grow``) keeps within
        ``limit`` between poses a and b (:func:`cylinder_pass`). Where that fails on a move with a
        fixed axis that moves along it too, its exact sweep is tested radially
        (:func:`sheared_clear`), and where that fails the move is cut into pieces that move along
        the axis by at most ``SPLIT_SHARE`` of the limit (up to ``MAX_SPLIT``), each tested: a
        piece's prism holds its sweep with the bottom lowered and the top raised by that much
        only, where the whole move's takes all of it (axially too)."""
        if cylinder_pass(ta, ua, tb, ub, t0, t1, rad, base, grow, limit,
                         node_lo, node_hi, node_child, node_range, tris, stack, w):
            return True
        if ua[0] != ub[0] or ua[1] != ub[1] or ua[2] != ub[2] or limit <= 0.0:
            return False
        dx = tb[0] - ta[0]
        dy = tb[1] - ta[1]
        dz = tb[2] - ta[2]
        along = dx * ua[0] + dy * ua[1] + dz * ua[2]
        across = dx * dx + dy * dy + dz * dz - along * along
        pieces = 1  # (a move along the axis sweeps a longer cylinder: its prism is exact)
        if across > 1e-18 * (dx * dx + dy * dy + dz * dz):
            pieces = min(MAX_SPLIT, max(1, int(math.ceil(abs(along) / (SPLIT_SHARE * limit)))))
        if pieces == 1:
            return False
        # first the exact sweep, radially: the prism of cylinder_pass holds the cylinder's lowest
        # and highest places over the move at every pose, and a move that climbs or sinks with its
        # rim near the part fails it where no pose comes near
        if sheared_clear(ta, ua, tb, t0 - grow, t1 + grow, rad + grow - limit, node_lo, node_hi, node_child,
                         node_range, tris, stack, w):
            return True
        for j in range(pieces):
            f0 = j / pieces
            f1 = (j + 1) / pieces
            for k in range(3):
                w[_SUB + k] = (1.0 - f0) * ta[k] + f0 * tb[k]
                w[_SUB + 3 + k] = (1.0 - f1) * ta[k] + f1 * tb[k]
            if not cylinder_pass(w[_SUB:_SUB + 3], ua, w[_SUB + 3:_SUB + 6], ub, t0, t1, rad, base, grow, limit,
                                 node_lo, node_hi, node_child, node_range, tris, stack, w):
                return False
        return True

    @jit
    def cylinder_pass(ta, ua, tb, ub, t0, t1, rad, base, grow, limit,
                      node_lo, node_hi, node_child, node_range, tris, stack, w):
        """Whether the flat cylinder [t0, t1] of radius rad (grown by ``grow``) keeps within
        ``limit`` between poses a and b: radially (its radius shrunk by limit stays out) or else
        axially (its part from ``base + limit`` up stays out), at every pose. Bands of the cylinder
        (:func:`band_clear`) are halved where their turn's slack is what fails."""
        cth = min(1.0, max(-1.0, ua[0] * ub[0] + ua[1] * ub[1] + ua[2] * ub[2]))
        mx = ua[0] + ub[0]
        my = ua[1] + ub[1]
        mz = ua[2] + ub[2]
        mn = math.sqrt(mx * mx + my * my + mz * mz)
        if mn <= 1e-12:
            return False
        mx /= mn
        my /= mn
        mz /= mn
        e1x, e1y, e1z, e2x, e2y, e2z = normal_frame(mx, my, mz)
        shorten = 1.0 - math.sqrt(0.5 * (1.0 + cth))  # 1 - cos(theta / 2)
        chord = math.sqrt(max(0.0, 0.5 * (1.0 - cth)))  # sin(theta / 2)
        lo = t0 - grow
        hi = t1 + grow
        r = rad + grow
        for mode in range(2):  # 0: radially, 1: axially
            if mode == 1 and r * chord >= limit:
                # the rim of the turning bottom dips by r·chord past the slab of the mid axis: the
                # bottom raised by the limit still reaches what the radial test met there (a
                # conservative shortcut: the failing turns' tests took twice as long for 1 % more
                # proven; the caller halves the interval, the turn with it)
                return False
            s_lo = lo if mode == 0 else max(t0, base + limit) - grow
            extra = -limit if mode == 0 else 0.0
            if s_lo >= hi:
                return True
            ok = True
            w[0] = lo
            w[1] = hi
            sp = 1
            while sp > 0:
                sp -= 1
                b0 = w[2 * sp]
                b1 = w[2 * sp + 1]
                if band_clear(ta, ua, tb, ub, mx, my, mz, e1x, e1y, e1z, e2x, e2y, e2z, b0, b1, s_lo, r, shorten,
                              chord, extra, node_lo, node_hi, node_child, node_range, tris, stack, w):
                    continue
                # halving helps only while the band's own turn across its length is what fails
                if 0.5 * (b1 - b0) * chord <= 0.25 * (r * chord + abs(0.5 * (b0 + b1)) * shorten) + 1e-9 \
                        or b1 - b0 < 1e-6 or sp + 2 > ARC_STACK:
                    ok = False
                    break
                sp = push_halves(w, sp, b0, b1)
            if ok:
                return True
        return False

    @jit
    def interval_clear(i, tip_a, axis_a, tip_b, axis_b, tool, grow, limit, ring_t, ring_rho, ring_r,
                       seg_t0, seg_t1, seg_r, seg_base, node_lo, node_hi, node_child, node_range, tris, stack, w):
        """Whether every part of interval i's tool, grown by ``grow[i]``, keeps within ``limit[i]``
        at every pose from (tip_a[i], axis_a[i]) to (tip_b[i], axis_b[i])."""
        t = tool[i]
        g_i = grow[i]
        lim = limit[i]
        first = 0
        if g_i == 0.0 and ring_rho[t] <= 0.0 and ring_r[t] > 0.0 and seg_r[t, 0] > 0.0 \
                and seg_t0[t, 0] == ring_t[t] and seg_r[t, 0] <= ring_r[t]:
            # a turning ball and its flutes: within the ball's radius of the axis from its centre to
            # the flutes' top, swept. The point h along the axis at a pose between is the bilinear
            # patch's point at h / |(1 - s) ua + s ub|, that length at least cos(theta/2): the
            # sweep lies in the patch of the axis from the centre to t1 / cos(theta/2), exactly. A
            # fixed axis is decided exactly by the capsule and the prism below
            cth = min(1.0, max(-1.0, axis_a[i, 0] * axis_b[i, 0] + axis_a[i, 1] * axis_b[i, 1]
                               + axis_a[i, 2] * axis_b[i, 2]))
            # (a ball within the tolerance's radius proves nothing so: the ring and flutes below)
            if cth < 1.0 and ring_r[t] > lim and patch_clear(
                    w, tip_a[i], axis_a[i], tip_b[i], axis_b[i], ring_t[t], seg_t1[t, 0] / math.sqrt(0.5 * (1.0 + cth)),
                    ring_r[t] - lim, node_lo, node_hi, node_child, node_range, tris, stack):
                first = 1
        if first == 0 and ring_r[t] > 0.0:
            if not ring_clear(tip_a[i], axis_a[i], tip_b[i], axis_b[i], ring_t[t], ring_rho[t], ring_r[t] + g_i, lim,
                              node_lo, node_hi, node_child, node_range, tris, stack, w):
                return False
        for k in range(first, seg_r.shape[1]):
            r = seg_r[t, k]
            if r <= 0.0:
                break
            if not cylinder_clear(tip_a[i], axis_a[i], tip_b[i], axis_b[i], seg_t0[t, k], seg_t1[t, k], r,
                                  seg_base[t, k], g_i, lim, node_lo, node_hi, node_child, node_range, tris, stack, w):
                return False
        return True

    @jit
    def pose_depth(i, tip, axis, tool, grow, ring_t, ring_rho, ring_r, ring_n, seg_t0, seg_t1, seg_r, seg_base,
                   node_lo, node_hi, node_child, node_range, tris, in_lo, in_hi, in_child, in_range, in_tris, in_kind,
                   floor, stop, stack, ring, segs):
        """How deep pose i (every part grown by ``grow[i]``) enters the material: ``ring[i]`` for
        the rounded end (its ``ring_n`` spheres; a ball is one), ``segs[i, k]`` for each cylinder
        (the smaller of the radial and the axial depth from ``seg_base``), 0 where clear. A part
        whose reference point (sphere centre, the cylinder's top on the axis) lies in the material
        (:func:`inside`) is measured from the far side: radius plus distance. With ``stop >= 0``
        only whether each depth exceeds ``stop`` is asked: a depth is then exact up to stop, and
        past it any value past stop (searches end at the first triangle deeper than that); a
        cylinder's axial depth within AXIAL_TOL under stop is put past it, as the exact measure's
        bisection from above may: past stop wherever the exact depth is."""
        t = tool[i]
        g_i = grow[i]
        px = tip[i, 0]
        py = tip[i, 1]
        pz = tip[i, 2]
        ux = axis[i, 0]
        uy = axis[i, 1]
        uz = axis[i, 2]
        ex, ey, ez, gx, gy, gz = normal_frame(ux, uy, uz)
        r = ring_r[t] + g_i
        decide = stop >= 0.0 and r > stop  # a part this wide buried is past stop
        past = stop + max(1e-12 * stop, 1e-300)  # a depth reported past stop
        if ring_r[t] > 0.0:
            cx = px + ring_t[t] * ux
            cy = py + ring_t[t] * uy
            cz = pz + ring_t[t] * uz
            buried = inside(cx, cy, cz, in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor, stack)
            rho = ring_rho[t]
            n = ring_n[t] if rho > 0.0 else 1
            for j in range(n):
                phi = 2.0 * math.pi * j / n
                qx, qy, qz = on_circle(cx, cy, cz, rho, math.cos(phi), math.sin(phi), ex, ey, ez, gx, gy, gz)
                if buried and (rho <= 0.0 or inside(qx, qy, qz, in_lo, in_hi, in_child, in_range, in_tris, in_kind,
                                                    floor, stack)):
                    d = 0.0 if decide else math.sqrt(point_dist(qx, qy, qz, INF, 0.0, node_lo, node_hi, node_child,
                                                                node_range, tris, stack))
                    ring[i] = max(ring[i], r + d)
                    continue
                stop2 = (r - stop) ** 2 if decide else 0.0
                d2 = point_dist(qx, qy, qz, r * r, stop2, node_lo, node_hi, node_child, node_range, tris, stack)
                d = math.sqrt(d2)
                if d2 < stop2:  # (the search ended there: past stop, whatever r - d rounds to)
                    ring[i] = max(ring[i], max(r - d, past))
                elif d < r:
                    ring[i] = max(ring[i], r - d)
        for k in range(seg_r.shape[1]):
            r = seg_r[t, k]
            if r <= 0.0:
                break
            r += g_i
            t0 = seg_t0[t, k] - g_i
            t1 = seg_t1[t, k] + g_i
            r2 = r * r
            decide = stop >= 0.0 and r > stop
            stop2 = (r - stop) ** 2 if decide else 0.0
            d2 = cylinder_dist(px, py, pz, ux, uy, uz, t0, t1, r2, stop2, node_lo, node_hi, node_child, node_range,
                               tris, stack)
            qx = px + t1 * ux
            qy = py + t1 * uy
            qz = pz + t1 * uz
            if inside(qx, qy, qz, in_lo, in_hi, in_child, in_range, in_tris, in_kind, floor, stack):
                # the top of the cylinder lies in the material: as deep as it gets across the axis
                top = 0.0 if decide else math.sqrt(point_dist(qx, qy, qz, INF, 0.0, node_lo, node_hi, node_child,
                                                              node_range, tris, stack))
                segs[i, k] = r + max(top, math.sqrt(d2) if d2 < r2 and not decide else 0.0)
                continue
            if d2 >= r2:
                continue
            radial = r - math.sqrt(d2)  # (with decide and past stop: at most the radial depth)
            if d2 < stop2:  # (the search ended there: past stop, whatever r - sqrt(d2) rounds to)
                radial = max(radial, past)
            base = seg_base[t, k] - g_i
            if stop >= 0.0:
                # past stop radially; axially too where the cylinder raised by stop less AXIAL_TOL
                # still meets the mesh (the bisection from above may put a depth that far under
                # stop past it: never past stop here where it is not so there)
                if radial > stop and cylinder_dist(px, py, pz, ux, uy, uz,
                                                   min(max(t0, base + stop - AXIAL_TOL), t1 - 1e-9), t1, r2, r2,
                                                   node_lo, node_hi, node_child, node_range, tris, stack) >= r2:
                    radial = stop
                segs[i, k] = radial
                continue
            # axial depth: how far the bottom of the cylinder must rise to clear (bisection to
            # AXIAL_TOL, the upper end kept), when less than the radial depth (raised by that much,
            # the cylinder must clear)
            lo = t0
            hi = min(t1 - 1e-9, t0 + radial)
            if cylinder_dist(px, py, pz, ux, uy, uz, hi, t1, r2, r2, node_lo, node_hi, node_child, node_range,
                             tris, stack) < r2:
                segs[i, k] = radial
                continue
            for _ in range(64):  # (2^64 AXIAL_TOL: any radial depth)
                if hi - lo <= AXIAL_TOL:
                    break
                mid = 0.5 * (lo + hi)
                if cylinder_dist(px, py, pz, ux, uy, uz, mid, t1, r2, r2, node_lo, node_hi, node_child, node_range,
                                 tris, stack) < r2:
                    lo = mid
                else:
                    hi = mid
            segs[i, k] = min(radial, hi - base)

    return namespace(seg_seg_dist2=seg_seg_dist2, tri_tri_dist2=tri_tri_dist2, tri_gap=tri_gap,
                     mesh_tris_dist2=mesh_tris_dist2,
                     mesh_segment_dist2=mesh_segment_dist2, seg2d_dist2=seg2d_dist2, stadium_tri_dist2=stadium_tri_dist2,
                     sheared_tri_dist2=sheared_tri_dist2,
                     mesh_stadium_dist2=mesh_stadium_dist2, inside=inside, ring_clear=ring_clear,
                     patch_clear=patch_clear, in_tetra=in_tetra,
                     cylinder_clear=cylinder_clear, interval_clear=interval_clear, pose_depth=pose_depth)
