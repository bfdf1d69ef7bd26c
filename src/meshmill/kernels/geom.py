"""Geometric device functions, written once and compiled for every backend.

``build(jit)`` returns a namespace of scalar functions. ``jit`` is ``numba.njit(...)`` for the CPU
(called from ``prange`` loops in :mod:`meshmill.kernels.cpu`) or ``numba.cuda.jit(device=True)`` for
CUDA. The functions take plain scalars and arrays only, allocate nothing (callers hand in the
traversal ``stack``, an int32 array of ``STACK_SIZE``) and return scalars.

Mesh arrays (see :mod:`meshmill.kernels.bvh`), all in BVH order, millimetres:

- ``tris (m, 9) float64``: the three vertices of every triangle, x0 y0 z0 x1 y1 z1 x2 y2 z2;
- ``node_lo, node_hi (k, 3) float64``: node boxes;
- ``node_child (k, 2) int32``: left and right child, -1 for a leaf;
- ``node_range (k, 2) int32``: first triangle and triangle count of a leaf.

The BVH is walked by one traversal written once (:func:`bvh_search`, :func:`bvh_visit`), to
which each query hands its box test and its triangle test; a query is a tuple (its scalars, and
the work arrays its triangle test writes), a value that allocates nothing on either backend.

Distances are returned squared. A tool body is a union of coaxial cylinders given by their axial
ranges ``[t0, t1]`` and radii along the unit axis ``u`` from the tool tip.
"""
from __future__ import annotations

import math
from types import ModuleType

STACK_SIZE = 128
INF = 1.0e300
WITNESSES = 16  # points of the part found inside a blocked tool body, kept by the axis search
SEEN_SIZE = 3 * WITNESSES  # float64 work array of the axis search (a CUDA local array: a constant)
WITNESS_GRID = 8  # a blocking triangle's points looked at for a witness: barycentric steps of 1/8
WITNESS_MARGIN = 1e-9  # mm: how deep a witness must lie in a candidate's body to block it


def namespace(**functions):
    """The device functions of a ``build`` as the attributes of a module object: compiled code can
    call them through it (``dev.mesh_point_dist2(...)``), which numba does not allow through a
    SimpleNamespace."""
    ns = ModuleType("meshmill.kernels.device")
    ns.__dict__.update(functions)
    return ns


def bvh_search(jit, box_bound, leaf_dist, nearest_first=False, reach_of=None):
    """The nearest search through the BVH, compiled with ``jit``:
    ``search(q, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack) -> (best, hit)``,
    the smallest ``leaf_dist`` (mm², below cap2) of the mesh's triangles to the query ``q`` and the
    triangle that gave it (-1: none below cap2); it returns as soon as one falls below ``stop2``
    (<= cap2; 0: the exact minimum).

    ``box_bound(q, node_lo, node_hi, n, best, reach)``: a lower bound on the distance of the
    triangles under node n, or any value >= best when none can come below best;
    ``leaf_dist(q, tris, t, best, reach)``: triangle t's distance, or any value >= best when it
    cannot come below best. ``reach = reach_of(q, best)`` is what they read of best, computed again
    only when best falls (default ``sqrt(best)``, mm). Children are searched left first, or with
    ``nearest_first`` the one of the lower bound first.
    """
    if reach_of is None:
        @jit
        def reach_of(q, best):
            return math.sqrt(best)

    @jit
    def search(q, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack):
        best = cap2
        reach = reach_of(q, best)
        hit = -1
        stack[0] = 0
        sp = 1
        while sp > 0:
            sp -= 1
            n = stack[sp]
            if box_bound(q, node_lo, node_hi, n, best, reach) >= best:
                continue
            left = node_child[n, 0]
            if left < 0:
                first = node_range[n, 0]
                for t in range(first, first + node_range[n, 1]):
                    d = leaf_dist(q, tris, t, best, reach)
                    if d < best:
                        best = d
                        reach = reach_of(q, best)
                        hit = t
                        if best < stop2:
                            return best, hit
            else:
                right = node_child[n, 1]
                if nearest_first and not (box_bound(q, node_lo, node_hi, left, best, reach)
                                          < box_bound(q, node_lo, node_hi, right, best, reach)):
                    stack[sp] = left
                    stack[sp + 1] = right
                else:
                    stack[sp] = right
                    stack[sp + 1] = left
                sp += 2
        return best, hit

    return search


def bvh_visit(jit, box_meets, leaf_visit, done=None):
    """The visit of every triangle a query may meet, compiled with ``jit``:
    ``visit(q, state, node_lo, node_hi, node_child, node_range, tris, stack) -> state``, each
    triangle t under the nodes whose box meets the query (``box_meets(q, node_lo, node_hi, n)``)
    in turn: ``state = leaf_visit(q, tris, t, state)`` (a scalar or a tuple of them); it returns as
    soon as ``done(state)`` (default: never). Right children first."""
    if done is None:
        @jit
        def done(state):
            return False

    @jit
    def visit(q, state, node_lo, node_hi, node_child, node_range, tris, stack):
        stack[0] = 0
        sp = 1
        while sp > 0:
            sp -= 1
            n = stack[sp]
            if not box_meets(q, node_lo, node_hi, n):
                continue
            left = node_child[n, 0]
            if left < 0:
                first = node_range[n, 0]
                for t in range(first, first + node_range[n, 1]):
                    state = leaf_visit(q, tris, t, state)
                    if done(state):
                        return state
            else:
                stack[sp] = left
                stack[sp + 1] = node_child[n, 1]
                sp += 2
        return state

    return visit


def build(jit):
    """Compile the device functions with ``jit`` and return them in a namespace."""

    @jit
    def point_segment_offset(px, py, pz, ax, ay, az, bx, by, bz):
        """``(wx, wy, wz)``: point p less the point of segment a-b nearest it."""
        dx = bx - ax
        dy = by - ay
        dz = bz - az
        wx = px - ax
        wy = py - ay
        wz = pz - az
        dd = dx * dx + dy * dy + dz * dz
        s = 0.0
        if dd > 0.0:
            s = (wx * dx + wy * dy + wz * dz) / dd
            s = min(1.0, max(0.0, s))
        return wx - s * dx, wy - s * dy, wz - s * dz

    @jit
    def segment_tri_gap(tris, t, ax, ay, az, bx, by, bz):
        """A lower bound on the distance from triangle t to segment a-b (mm, up to rounding of
        1e-12 of the coordinates): how far the triangle's corners lie past the segment along the
        direction from the segment's point s nearest the triangle's centroid c to c (the segment
        lies wholly at or before s along it; 0 where c is on the segment)."""
        cx = (tris[t, 0] + tris[t, 3] + tris[t, 6]) / 3.0
        cy = (tris[t, 1] + tris[t, 4] + tris[t, 7]) / 3.0
        cz = (tris[t, 2] + tris[t, 5] + tris[t, 8]) / 3.0
        vx, vy, vz = point_segment_offset(cx, cy, cz, ax, ay, az, bx, by, bz)
        vn = math.sqrt(vx * vx + vy * vy + vz * vz)
        if vn <= 0.0:
            return 0.0
        sx = cx - vx
        sy = cy - vy
        sz = cz - vz
        low = INF
        for k in range(3):
            low = min(low, (tris[t, 3 * k] - sx) * vx + (tris[t, 3 * k + 1] - sy) * vy + (tris[t, 3 * k + 2] - sz) * vz)
        return low / vn

    @jit
    def point_segment_dist2(px, py, pz, ax, ay, az, bx, by, bz):
        """Squared distance from point p to segment a-b."""
        wx, wy, wz = point_segment_offset(px, py, pz, ax, ay, az, bx, by, bz)
        return wx * wx + wy * wy + wz * wz

    @jit
    def point_tri_dist2(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
        """Squared distance from point p to triangle abc.

        The plane distance where p projects inside the triangle, else the smallest edge distance.
        Robust on slivers: a wrong inside/outside call near an edge costs at most the sliver's
        width, and the plane distance never exceeds the true one. A degenerate triangle is its edges.
        """
        abx = bx - ax
        aby = by - ay
        abz = bz - az
        acx = cx - ax
        acy = cy - ay
        acz = cz - az
        nx = aby * acz - abz * acy
        ny = abz * acx - abx * acz
        nz = abx * acy - aby * acx
        nn = nx * nx + ny * ny + nz * nz
        if nn > 0.0:
            # p on the inner side of each edge (edge × (p - edge start)) · n >= 0
            ex = (aby * (pz - az) - abz * (py - ay)) * nx + (abz * (px - ax) - abx * (pz - az)) * ny \
                + (abx * (py - ay) - aby * (px - ax)) * nz
            bcx = cx - bx
            bcy = cy - by
            bcz = cz - bz
            fx = (bcy * (pz - bz) - bcz * (py - by)) * nx + (bcz * (px - bx) - bcx * (pz - bz)) * ny \
                + (bcx * (py - by) - bcy * (px - bx)) * nz
            cax = ax - cx
            cay = ay - cy
            caz = az - cz
            gx = (cay * (pz - cz) - caz * (py - cy)) * nx + (caz * (px - cx) - cax * (pz - cz)) * ny \
                + (cax * (py - cy) - cay * (px - cx)) * nz
            if ex >= 0.0 and fx >= 0.0 and gx >= 0.0:
                h = (px - ax) * nx + (py - ay) * ny + (pz - az) * nz
                return h * h / nn
        d = point_segment_dist2(px, py, pz, ax, ay, az, bx, by, bz)
        d = min(d, point_segment_dist2(px, py, pz, bx, by, bz, cx, cy, cz))
        return min(d, point_segment_dist2(px, py, pz, cx, cy, cz, ax, ay, az))

    @jit
    def point_triangle_dist2(px, py, pz, tris, t):
        """Squared distance from point p to triangle t of ``tris`` (see :func:`point_tri_dist2`)."""
        return point_tri_dist2(px, py, pz, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5],
                               tris[t, 6], tris[t, 7], tris[t, 8])

    @jit
    def line_crossing(ox, oy, oz, dx, dy, dz, ax, ay, az, bx, by, bz, cx, cy, cz, det_min, det_share):
        """Where the line o + s·d crosses triangle abc, edges included (Möller-Trumbore): s, or NaN
        where it misses, or lies in the triangle's plane: ``|det| <= det_min``, or with
        ``det_share > 0`` ``|det| <= det_share |ab| |ac|``."""
        e1x = bx - ax
        e1y = by - ay
        e1z = bz - az
        e2x = cx - ax
        e2y = cy - ay
        e2z = cz - az
        px = dy * e2z - dz * e2y
        py = dz * e2x - dx * e2z
        pz = dx * e2y - dy * e2x
        det = e1x * px + e1y * py + e1z * pz
        flat = det_min
        if det_share > 0.0:
            flat = det_share * math.sqrt((e1x * e1x + e1y * e1y + e1z * e1z) * (e2x * e2x + e2y * e2y + e2z * e2z))
        if abs(det) <= flat:
            return math.nan
        inv = 1.0 / det
        tx = ox - ax
        ty = oy - ay
        tz = oz - az
        u = (tx * px + ty * py + tz * pz) * inv
        if not (u >= 0.0 and u <= 1.0):
            return math.nan
        qx = ty * e1z - tz * e1y
        qy = tz * e1x - tx * e1z
        qz = tx * e1y - ty * e1x
        v = (dx * qx + dy * qy + dz * qz) * inv
        if not (v >= 0.0 and u + v <= 1.0):
            return math.nan
        return (e2x * qx + e2y * qy + e2z * qz) * inv

    @jit
    def across(x, y, z, ux, uy, uz):
        """The part of the vector (x, y, z) across the unit u."""
        h = x * ux + y * uy + z * uz
        return x - h * ux, y - h * uy, z - h * uz

    @jit
    def segment_line_dist2(p0x, p0y, p0z, p1x, p1y, p1z, ax, ay, az, ux, uy, uz):
        """Squared distance from segment p0-p1 to the infinite line through a along unit u."""
        wx, wy, wz = across(p0x - ax, p0y - ay, p0z - az, ux, uy, uz)
        dx, dy, dz = across(p1x - p0x, p1y - p0y, p1z - p0z, ux, uy, uz)
        dd = dx * dx + dy * dy + dz * dz
        s = 0.0
        if dd > 0.0:
            s = -(wx * dx + wy * dy + wz * dz) / dd
            if s < 0.0:
                s = 0.0
            elif s > 1.0:
                s = 1.0
        rx = wx + s * dx
        ry = wy + s * dy
        rz = wz + s * dz
        return rx * rx + ry * ry + rz * rz

    @jit
    def triangle_axis_dist2(tris, t, ax, ay, az, ux, uy, uz, t0, t1):
        """Squared distance from the line a + s·u to the part of triangle t with t0 <= s <= t1.

        Exact: the minimum lies where the line pierces the clipped triangle (0), on a triangle
        edge clipped to the slab, or on the cut of a slab plane through the triangle. Returns INF
        when the triangle misses the slab.
        """
        h0 = (tris[t, 0] - ax) * ux + (tris[t, 1] - ay) * uy + (tris[t, 2] - az) * uz
        h1 = (tris[t, 3] - ax) * ux + (tris[t, 4] - ay) * uy + (tris[t, 5] - az) * uz
        h2 = (tris[t, 6] - ax) * ux + (tris[t, 7] - ay) * uy + (tris[t, 8] - az) * uz
        if h0 < t0 and h1 < t0 and h2 < t0:
            return INF
        if h0 > t1 and h1 > t1 and h2 > t1:
            return INF
        # does the line pierce the triangle inside the slab? (not when it lies, to rounding, in the
        # triangle's plane: the edge and cut terms below are then exact, and det would be noise)
        s = line_crossing(ax, ay, az, ux, uy, uz, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4],
                          tris[t, 5], tris[t, 6], tris[t, 7], tris[t, 8], 0.0, 1e-9)
        if s >= t0 and s <= t1:
            return 0.0
        best = INF
        for k in range(3):
            i = 3 * k
            j = 3 * ((k + 1) % 3)
            px = tris[t, i]
            py = tris[t, i + 1]
            pz = tris[t, i + 2]
            qx = tris[t, j]
            qy = tris[t, j + 1]
            qz = tris[t, j + 2]
            hp = (px - ax) * ux + (py - ay) * uy + (pz - az) * uz
            hq = (qx - ax) * ux + (qy - ay) * uy + (qz - az) * uz
            # edge clipped to the slab: s in [slo, shi]
            slo = 0.0
            shi = 1.0
            dh = hq - hp
            if dh == 0.0:
                if hp < t0 or hp > t1:
                    slo = 1.0
                    shi = 0.0
            else:
                sa = (t0 - hp) / dh
                sb = (t1 - hp) / dh
                if sa > sb:
                    sa, sb = sb, sa
                if sa > slo:
                    slo = sa
                if sb < shi:
                    shi = sb
            if slo <= shi:
                d = segment_line_dist2(px + slo * (qx - px), py + slo * (qy - py), pz + slo * (qz - pz),
                                       px + shi * (qx - px), py + shi * (qy - py), pz + shi * (qz - pz),
                                       ax, ay, az, ux, uy, uz)
                if d < best:
                    best = d
        # cuts of the two slab planes through the triangle (a vertex on the plane counts: it is
        # found from both of its edges, so up to three points, any two spanning the cut)
        for c in range(2):
            tc = t0 if c == 0 else t1
            n = 0
            c0x = 0.0
            c0y = 0.0
            c0z = 0.0
            c1x = 0.0
            c1y = 0.0
            c1z = 0.0
            c2x = 0.0
            c2y = 0.0
            c2z = 0.0
            for k in range(3):
                i = 3 * k
                j = 3 * ((k + 1) % 3)
                hp = h0 if k == 0 else (h1 if k == 1 else h2)
                hq = h1 if k == 0 else (h2 if k == 1 else h0)
                if hp != hq and min(hp, hq) <= tc and tc <= max(hp, hq):
                    s = (tc - hp) / (hq - hp)
                    x = tris[t, i] + s * (tris[t, j] - tris[t, i])
                    y = tris[t, i + 1] + s * (tris[t, j + 1] - tris[t, i + 1])
                    z = tris[t, i + 2] + s * (tris[t, j + 2] - tris[t, i + 2])
                    if n == 0:
                        c0x, c0y, c0z = x, y, z
                    elif n == 1:
                        c1x, c1y, c1z = x, y, z
                    else:
                        c2x, c2y, c2z = x, y, z
                    n += 1
            if n >= 2:
                d = segment_line_dist2(c0x, c0y, c0z, c1x, c1y, c1z, ax, ay, az, ux, uy, uz)
                if d < best:
                    best = d
            if n == 3:
                d = segment_line_dist2(c1x, c1y, c1z, c2x, c2y, c2z, ax, ay, az, ux, uy, uz)
                if d < best:
                    best = d
                d = segment_line_dist2(c0x, c0y, c0z, c2x, c2y, c2z, ax, ay, az, ux, uy, uz)
                if d < best:
                    best = d
        return best

    @jit
    def box_point_dist2(node_lo, node_hi, n, px, py, pz):
        d = 0.0
        for k in range(3):
            p = px if k == 0 else (py if k == 1 else pz)
            if p < node_lo[n, k]:
                d += (node_lo[n, k] - p) ** 2
            elif p > node_hi[n, k]:
                d += (p - node_hi[n, k]) ** 2
        return d

    @jit
    def point_box(q, node_lo, node_hi, n, best, reach):
        return box_point_dist2(node_lo, node_hi, n, q[0], q[1], q[2])

    @jit
    def point_leaf(q, tris, t, best, reach):
        return point_triangle_dist2(q[0], q[1], q[2], tris, t)

    point_search = bvh_search(jit, point_box, point_leaf, nearest_first=True)

    @jit
    def mesh_point_dist2(px, py, pz, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack):
        """Squared distance from p to the mesh, capped at cap2.

        Returns early with a value below stop2 as soon as one is found (an overlap test);
        stop2 = 0 gives the exact minimum.
        """
        return point_search((px, py, pz), cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack)[0]

    @jit
    def largest_clear_ball(cx, cy, cz, nx, ny, nz, radii, tol, node_lo, node_hi, node_child, node_range, tris,
                           stack):
        """Index of the first radius in ``radii`` (sorted decreasing) whose ball tangent at c with
        outward normal n (centre c + R·n) stays out of the mesh by more than -tol; -1 if none."""
        for t in range(radii.shape[0]):
            r = radii[t]
            lim = (r - tol) * (r - tol)
            d2 = mesh_point_dist2(cx + r * nx, cy + r * ny, cz + r * nz, lim, lim,
                                  node_lo, node_hi, node_child, node_range, tris, stack)
            if d2 >= lim:
                return t
        return -1

    @jit
    def box_near_segment(node_lo, node_hi, n, ax, ay, az, bx, by, bz, ex, ey, ez, r):
        """False only when box n certainly lies farther than r from segment a-b: farther than
        (ex, ey, ez) along x, y or z from the segment's box (at most r each), or than r from the
        segment across the plane through the segment's point s nearest the box's centre c, square
        to c - s (the segment lies on the far side of that plane, the box within its extent along
        c - s of c)."""
        if node_lo[n, 0] > max(ax, bx) + ex or node_hi[n, 0] < min(ax, bx) - ex:
            return False
        if node_lo[n, 1] > max(ay, by) + ey or node_hi[n, 1] < min(ay, by) - ey:
            return False
        if node_lo[n, 2] > max(az, bz) + ez or node_hi[n, 2] < min(az, bz) - ez:
            return False
        cx = 0.5 * (node_lo[n, 0] + node_hi[n, 0])
        cy = 0.5 * (node_lo[n, 1] + node_hi[n, 1])
        cz = 0.5 * (node_lo[n, 2] + node_hi[n, 2])
        hx = 0.5 * (node_hi[n, 0] - node_lo[n, 0])
        hy = 0.5 * (node_hi[n, 1] - node_lo[n, 1])
        hz = 0.5 * (node_hi[n, 2] - node_lo[n, 2])
        wx, wy, wz = point_segment_offset(cx, cy, cz, ax, ay, az, bx, by, bz)
        dist = math.sqrt(wx * wx + wy * wy + wz * wz)
        if dist <= r:
            return True
        extent = (hx * abs(wx) + hy * abs(wy) + hz * abs(wz)) / dist
        # (rounding of coordinates this large)
        slack = 1e-12 * (1.0 + abs(cx) + abs(cy) + abs(cz) + hx + hy + hz + abs(ax) + abs(ay) + abs(az) + abs(bx)
                         + abs(by) + abs(bz))
        return dist - extent <= r + slack

    @jit
    def box_near_cylinder(node_lo, node_hi, n, p0x, p0y, p0z, p1x, p1y, p1z, ux, uy, uz, r):
        """False only when box n certainly lies farther than r from the flat-ended cylinder's
        axis p0-p1 (unit u): :func:`box_near_segment`, its end disks reaching r·sqrt(1 - u_k²)
        along coordinate axis k past the segment's box."""
        return box_near_segment(node_lo, node_hi, n, p0x, p0y, p0z, p1x, p1y, p1z,
                                r * math.sqrt(max(0.0, 1.0 - ux * ux)), r * math.sqrt(max(0.0, 1.0 - uy * uy)),
                                r * math.sqrt(max(0.0, 1.0 - uz * uz)), r)

    @jit
    def cylinder_box(q, node_lo, node_hi, n, best, reach):
        # the query: axis point a, unit u, range t0..t1 along it, and the range's ends p0, p1
        ax, ay, az, ux, uy, uz, t0, t1, p0x, p0y, p0z, p1x, p1y, p1z = q
        return 0.0 if box_near_cylinder(node_lo, node_hi, n, p0x, p0y, p0z, p1x, p1y, p1z, ux, uy, uz, reach) else best

    @jit
    def cylinder_leaf(q, tris, t, best, reach):
        ax, ay, az, ux, uy, uz, t0, t1, p0x, p0y, p0z, p1x, p1y, p1z = q
        # a triangle farther than reach from the axis segment is farther across the axis within the
        # slab (the exact test costs some ten times this bound; most triangles of the boxes met fail it)
        slack = 1e-12 * (1.0 + abs(tris[t, 0]) + abs(tris[t, 1]) + abs(tris[t, 2]) + abs(p0x) + abs(p0y) + abs(p0z)
                         + abs(p1x) + abs(p1y) + abs(p1z))
        if segment_tri_gap(tris, t, p0x, p0y, p0z, p1x, p1y, p1z) > reach + slack:
            return INF
        return triangle_axis_dist2(tris, t, ax, ay, az, ux, uy, uz, t0, t1)

    cylinder_search = bvh_search(jit, cylinder_box, cylinder_leaf)

    @jit
    def mesh_cylinder_search(ax, ay, az, ux, uy, uz, t0, t1, cap2, stop2,
                             node_lo, node_hi, node_child, node_range, tris, stack):
        """:func:`mesh_cylinder_dist2` and the triangle that gave it (-1: none under cap2)."""
        q = (ax, ay, az, ux, uy, uz, t0, t1, ax + t0 * ux, ay + t0 * uy, az + t0 * uz, ax + t1 * ux, ay + t1 * uy,
             az + t1 * uz)
        return cylinder_search(q, cap2, stop2, node_lo, node_hi, node_child, node_range, tris, stack)

    @jit
    def mesh_cylinder_dist2(ax, ay, az, ux, uy, uz, t0, t1, cap2, stop2,
                            node_lo, node_hi, node_child, node_range, tris, stack):
        """Smallest squared distance from the axis a + s·u to the mesh within t0 <= s <= t1.

        A flat-ended cylinder of radius r on that range overlaps the mesh iff this is < r².
        Capped at cap2; returns early below stop2 (stop2 = 0: exact minimum).
        """
        return mesh_cylinder_search(ax, ay, az, ux, uy, uz, t0, t1, cap2, stop2,
                                    node_lo, node_hi, node_child, node_range, tris, stack)[0]

    @jit
    def body_clear(tx, ty, tz, ux, uy, uz, seg_t0, seg_t1, seg_r, tool,
                   node_lo, node_hi, node_child, node_range, tris, stack):
        """True when no cylinder of tool body ``tool`` (rows of seg_*; radius <= 0 ends the list)
        placed with its tip at t and unit axis u overlaps the mesh."""
        return body_blocker(tx, ty, tz, ux, uy, uz, seg_t0, seg_t1, seg_r, tool,
                            node_lo, node_hi, node_child, node_range, tris, stack) < 0

    @jit
    def body_blocker(tx, ty, tz, ux, uy, uz, seg_t0, seg_t1, seg_r, tool,
                     node_lo, node_hi, node_child, node_range, tris, stack):
        """A triangle overlapping a cylinder of tool body ``tool`` placed with its tip at t and unit
        axis u, -1 when none does (:func:`body_clear`). The outer cylinders (holder) are tried
        first: they meet the part most often."""
        n = 0
        while n < seg_r.shape[1] and seg_r[tool, n] > 0.0:
            n += 1
        for j in range(n):
            k = n - 1 - j
            r2 = seg_r[tool, k] * seg_r[tool, k]
            d, hit = mesh_cylinder_search(tx, ty, tz, ux, uy, uz, seg_t0[tool, k], seg_t1[tool, k], r2, r2,
                                          node_lo, node_hi, node_child, node_range, tris, stack)
            if d < r2:
                return hit
        return -1

    @jit
    def body_depth(px, py, pz, tx, ty, tz, ux, uy, uz, seg_t0, seg_t1, seg_r, tool):
        """How deep point p lies in tool body ``tool`` placed with its tip at t and unit axis u:
        the largest margin (mm) to the side and the ends of a cylinder holding it, <= 0 if none."""
        qx = px - tx
        qy = py - ty
        qz = pz - tz
        a = qx * ux + qy * uy + qz * uz
        rx = qx - a * ux
        ry = qy - a * uy
        rz = qz - a * uz
        rad = math.sqrt(rx * rx + ry * ry + rz * rz)
        best = 0.0
        for k in range(seg_r.shape[1]):
            if seg_r[tool, k] <= 0.0:
                break
            best = max(best, min(seg_r[tool, k] - rad, min(a - seg_t0[tool, k], seg_t1[tool, k] - a)))
        return best

    @jit
    def axis_point_move(ta, ua, tb, ub, t):
        """``(cx, cy, cz, dx, dy, dz)``: the point t mm along the axis of pose a (tip ``ta``, unit
        axis ``ua``: 3-sequences) and how far it moves to pose b."""
        cx = ta[0] + t * ua[0]
        cy = ta[1] + t * ua[1]
        cz = ta[2] + t * ua[2]
        return cx, cy, cz, tb[0] + t * ub[0] - cx, tb[1] + t * ub[1] - cy, tb[2] + t * ub[2] - cz

    @jit
    def tilted_axis(fx, fy, fz, sx, sy, sz, alpha, beta):
        """Unit axis tilted by alpha toward the feed direction f and beta toward the outward side s."""
        ca = math.cos(alpha)
        sa = math.sin(alpha)
        cb = math.cos(beta)
        sb = math.sin(beta)
        ux = sa * fx + ca * sb * sx
        uy = sa * fy + ca * sb * sy
        uz = sa * fz + ca * (cb + sb * sz)
        n = math.sqrt(ux * ux + uy * uy + uz * uz)
        return ux / n, uy / n, uz / n

    @jit
    def axis_clear(i, c, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                   node_lo, node_hi, node_child, node_range, tris, stack):
        """Whether point i's tool body is clear with candidate axis c (see the CPU ``axis_search``)."""
        ux, uy, uz = tilted_axis(f[i, 0], f[i, 1], f[i, 2], s[i, 0], s[i, 1], s[i, 2], cand[c, 0], cand[c, 1])
        r = radius[tool[i]]
        return body_clear(ce[i, 0] - r * ux, ce[i, 1] - r * uy, ce[i, 2] - r * uz, ux, uy, uz,
                          seg_t0, seg_t1, seg_r, tool[i], node_lo, node_hi, node_child, node_range, tris, stack)

    @jit
    def first_clear_axis(i, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                         node_lo, node_hi, node_child, node_range, tris, stack, seen, kept):
        """The first candidate (in order of preference) clear at point i (-1 if none or no tool),
        and the witnesses kept.

        Each candidate found blocked leaves a witness: the deepest of its blocking triangle's
        corners and centroid (a point of the part inside the body). A candidate whose body holds
        one of the last ``WITNESSES`` witnesses is blocked without a search; a witness is a point
        of the part, so it serves the next points as well. ``seen``: a float64 work array of
        ``SEEN_SIZE`` holding ``kept`` witnesses (the last ``WITNESSES`` of them)."""
        t = tool[i]
        if t < 0:
            return -1, kept
        r = radius[t]
        for c in range(cand.shape[0]):
            ux, uy, uz = tilted_axis(f[i, 0], f[i, 1], f[i, 2], s[i, 0], s[i, 1], s[i, 2], cand[c, 0], cand[c, 1])
            tx = ce[i, 0] - r * ux
            ty = ce[i, 1] - r * uy
            tz = ce[i, 2] - r * uz
            held = False
            for w in range(min(kept, WITNESSES)):
                if body_depth(seen[3 * w], seen[3 * w + 1], seen[3 * w + 2], tx, ty, tz, ux, uy, uz,
                              seg_t0, seg_t1, seg_r, t) > WITNESS_MARGIN:
                    held = True
                    break
            if held:
                continue
            hit = body_blocker(tx, ty, tz, ux, uy, uz, seg_t0, seg_t1, seg_r, t,
                               node_lo, node_hi, node_child, node_range, tris, stack)
            if hit < 0:
                return c, kept
            # the deepest inside the body of the triangle's points at barycentric coordinates in
            # steps of 1 / WITNESS_GRID
            best = 0.0
            for v in range((WITNESS_GRID + 1) * (WITNESS_GRID + 2) // 2):
                ia = 0
                rest = v
                while rest > WITNESS_GRID - ia:
                    rest -= WITNESS_GRID + 1 - ia
                    ia += 1
                wa = ia / WITNESS_GRID
                wb = rest / WITNESS_GRID
                wc = 1.0 - wa - wb
                px = wa * tris[hit, 0] + wb * tris[hit, 3] + wc * tris[hit, 6]
                py = wa * tris[hit, 1] + wb * tris[hit, 4] + wc * tris[hit, 7]
                pz = wa * tris[hit, 2] + wb * tris[hit, 5] + wc * tris[hit, 8]
                depth = body_depth(px, py, pz, tx, ty, tz, ux, uy, uz, seg_t0, seg_t1, seg_r, t)
                if depth > best:
                    best = depth
                    w = kept % WITNESSES
                    seen[3 * w] = px
                    seen[3 * w + 1] = py
                    seen[3 * w + 2] = pz
            if best > 0.0:
                kept += 1
        return -1, kept

    @jit
    def keep_previous_axes(i0, i1, choice, cand_tilt, slack, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                           node_lo, node_hi, node_child, node_range, tris, stack):
        """Along the points i0..i1-1 of one contour, in order: a point takes its predecessor's
        candidate when that is clear and at most ``slack`` rad more tilted (``choice`` in place)."""
        for i in range(i0 + 1, i1):
            prev = choice[i - 1]
            c = choice[i]
            if prev < 0 or c < 0 or prev == c or cand_tilt[prev] > cand_tilt[c] + slack:
                continue
            if axis_clear(i, prev, ce, f, s, tool, cand, radius, seg_t0, seg_t1, seg_r,
                          node_lo, node_hi, node_child, node_range, tris, stack):
                choice[i] = prev

    return namespace(
        axis_point_move=axis_point_move,
        tilted_axis=tilted_axis,
        first_clear_axis=first_clear_axis,
        keep_previous_axes=keep_previous_axes,
        point_triangle_dist2=point_triangle_dist2,
        point_tri_dist2=point_tri_dist2,
        point_segment_dist2=point_segment_dist2, segment_tri_gap=segment_tri_gap,
        box_point_dist2=box_point_dist2,
        box_near_segment=box_near_segment, box_near_cylinder=box_near_cylinder,
        segment_line_dist2=segment_line_dist2,
        line_crossing=line_crossing,
        triangle_axis_dist2=triangle_axis_dist2,
        mesh_point_dist2=mesh_point_dist2,
        largest_clear_ball=largest_clear_ball,
        mesh_cylinder_search=mesh_cylinder_search,
        mesh_cylinder_dist2=mesh_cylinder_dist2,
        body_clear=body_clear,
        body_depth=body_depth,
    )
