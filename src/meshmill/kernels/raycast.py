"""Axis-aligned lines against triangles: exact, watertight multi-hit casting (device functions).

A line runs along axis ``a`` (0: X, 1: Y, 2: Z) through ``(u0, v0)`` in the plane of the two
other axes ``u = (a+1) % 3``, ``v = (a+2) % 3`` (so u, v, a is right-handed). A triangle is hit when
``(u0, v0)`` lies inside its projection on that plane. The inside test uses edge functions
computed the same way for both triangles that share an edge (from the lexicographically smaller
end), and a point lying exactly on an edge or a vertex is decided as if it were moved by
``(eps, eps^2)`` (simulation of simplicity). So a line through an edge or a vertex of a closed
mesh crosses exactly one of the triangles around it on each sheet: no hit is lost or counted
twice, with no tolerance to tune. Triangles parallel to the line (zero projected area) are never
hit. The hit's coordinate along the line is a convex combination of the vertices' coordinates.

``hit`` returns +1 where the triangle's normal points along +a (the line leaves the material
when the mesh is wound outward), -1 where it enters, 0 for no hit.
"""
from __future__ import annotations

from . import geom
from .geom import bvh_visit, namespace

MAX_HITS = 512  # crossings a line may have (callers' buffers); more is reported as an error


def build(jit):
    """Compile the device functions with ``jit`` and return them in a namespace."""
    crossing = geom.build(jit).line_crossing

    @jit
    def edge_side(pu, pv, qu, qv, u0, v0):
        """``(sign, value)`` of the edge function of p->q at (u0, v0): > 0 left of the edge.
        ``sign`` is never 0 for a non-degenerate edge (ties broken by the perturbation)."""
        flip = 1.0
        if qu < pu or (qu == pu and qv < pv):
            pu, pv, qu, qv = qu, qv, pu, pv
            flip = -1.0
        du = qu - pu
        dv = qv - pv
        e = du * (v0 - pv) - dv * (u0 - pu)
        if e > 0.0:
            s = 1.0
        elif e < 0.0:
            s = -1.0
        elif dv != 0.0:  # moved by (eps, eps^2): e -> -dv*eps + du*eps^2
            s = -1.0 if dv > 0.0 else 1.0
        elif du != 0.0:
            s = 1.0  # canonical order makes du > 0 here
        else:
            s = 0.0
        return s * flip, e * flip

    @jit
    def hit(tris, t, a, u0, v0):
        """``(side, w)``: whether the line along axis a at (u0, v0) crosses triangle t of
        ``tris (m, 9)``, and where along a."""
        u = (a + 1) % 3
        v = (a + 2) % 3
        p0u = tris[t, u]
        p0v = tris[t, v]
        p1u = tris[t, 3 + u]
        p1v = tris[t, 3 + v]
        p2u = tris[t, 6 + u]
        p2v = tris[t, 6 + v]
        s2, e2 = edge_side(p0u, p0v, p1u, p1v, u0, v0)  # opposite vertex 2
        if s2 == 0.0:
            return 0, 0.0
        s0, e0 = edge_side(p1u, p1v, p2u, p2v, u0, v0)
        if s0 != s2:
            return 0, 0.0
        s1, e1 = edge_side(p2u, p2v, p0u, p0v, u0, v0)
        if s1 != s2:
            return 0, 0.0
        total = e0 + e1 + e2
        w0 = tris[t, a]
        w1 = tris[t, 3 + a]
        w2 = tris[t, 6 + a]
        if total == 0.0:
            w = (w0 + w1 + w2) / 3.0
        else:
            w = (e0 * w0 + e1 * w1 + e2 * w2) / total
            w = min(max(w, min(w0, min(w1, w2))), max(w0, max(w1, w2)))
        return (1 if s2 > 0.0 else -1), w

    @jit
    def sort_hits(hw, hs, n):
        """Sort the ``n`` hits ``hw (w), hs (side)`` along the line, entries before exits at equal
        w (insertion sort: few hits a line)."""
        for i in range(1, n):
            w = hw[i]
            s = hs[i]
            j = i - 1
            while j >= 0 and (hw[j] > w or (hw[j] == w and hs[j] > s)):
                hw[j + 1] = hw[j]
                hs[j + 1] = hs[j]
                j -= 1
            hw[j + 1] = w
            hs[j + 1] = s

    @jit
    def intervals_from_hits(hw, hs, n, out, row, cap):
        """Sort the ``n`` hits ``hw (w), hs (side)`` along the line and write the material
        intervals (depth > 0) into ``out[row, :cap, 2]``. Entries sort before exits at equal w, so
        touching pieces merge. Returns the interval count (may exceed cap: only cap are written),
        or -1 when the crossings do not balance (the mesh is not closed along this line)."""
        sort_hits(hw, hs, n)
        depth = 0
        count = 0
        start = 0.0
        for i in range(n):
            if hs[i] < 0:
                depth += 1
                if depth == 1:
                    start = hw[i]
            else:
                depth -= 1
                if depth < 0:
                    return -1
                if depth == 0 and hw[i] > start:
                    if count > 0 and count <= cap and start <= out[row, count - 1, 1]:
                        out[row, count - 1, 1] = hw[i]
                    else:
                        if count < cap:
                            out[row, count, 0] = start
                            out[row, count, 1] = hw[i]
                        count += 1
        if depth != 0:
            return -1
        return count

    @jit
    def line_box(q, node_lo, node_hi, n):
        # the query: the line along a at (u0, v0) (axes u, v), and where its hits go
        a, u, v, u0, v0, hw, hs = q
        return not (u0 < node_lo[n, u] or u0 > node_hi[n, u] or v0 < node_lo[n, v] or v0 > node_hi[n, v])

    @jit
    def keep_hit(q, tris, t, n):
        """The ``n`` hits found so far and triangle t's, if the line crosses it (stored in ``hw, hs``
        while they have room)."""
        a, u, v, u0, v0, hw, hs = q
        side, w = hit(tris, t, a, u0, v0)
        if side != 0:
            if n < hw.shape[0]:
                hw[n] = w
                hs[n] = side
            n += 1
        return n

    line_visit = bvh_visit(jit, line_box, keep_hit)

    @jit
    def bvh_line_hits(a, u0, v0, node_lo, node_hi, node_child, node_range, tris, stack, hw, hs):
        """Every crossing of the line with the mesh, through the BVH; returns the hit count
        (may exceed ``len(hw)``: only that many are stored)."""
        return line_visit((a, (a + 1) % 3, (a + 2) % 3, u0, v0, hw, hs), 0, node_lo, node_hi, node_child, node_range,
                          tris, stack)

    @jit
    def cast_bvh_line(a, line, line0, lu, lv, step, nv, cap, node_lo, node_hi, node_child, node_range, tris, stack,
                      hw, hs, out):
        """Cast grid line ``line0 + line`` (id i*nv + j) along axis a through the BVH into
        ``out[line]``; returns its interval count, -1 (unbalanced crossings) or -2 (more than the
        buffers hold)."""
        u0 = lu + ((line0 + line) // nv + 0.5) * step
        v0 = lv + ((line0 + line) % nv + 0.5) * step
        n = bvh_line_hits(a, u0, v0, node_lo, node_hi, node_child, node_range, tris, stack, hw, hs)
        if n > hw.shape[0]:
            return -2
        return intervals_from_hits(hw, hs, n, out, line, cap)

    @jit
    def box_line_hits(a, u0, v0, box_lo, box_hi, box_start, tris, hw, hs):
        """Every crossing of the line with the mesh, through a flat list of partition boxes
        (``box_start (K+1,)`` triangle ranges of ``tris`` in partition order)."""
        q = (a, (a + 1) % 3, (a + 2) % 3, u0, v0, hw, hs)
        n = 0
        for k in range(box_lo.shape[0]):
            if line_box(q, box_lo, box_hi, k):
                for t in range(box_start[k], box_start[k + 1]):
                    n = keep_hit(q, tris, t, n)
        return n

    @jit
    def cast_box_line(a, line, line0, lu, lv, step, nv, cap, box_lo, box_hi, box_start, tris, hw, hs, out):
        """As :func:`cast_bvh_line`, through partition boxes (see :func:`box_line_hits`)."""
        u0 = lu + ((line0 + line) // nv + 0.5) * step
        v0 = lv + ((line0 + line) % nv + 0.5) * step
        n = box_line_hits(a, u0, v0, box_lo, box_hi, box_start, tris, hw, hs)
        if n > hw.shape[0]:
            return -2
        return intervals_from_hits(hw, hs, n, out, line, cap)

    @jit
    def slab_box(q, node_lo, node_hi, n):
        # the query: the ray o + t d, t > tmin
        ox, oy, oz, dx, dy, dz, tmin = q
        t0 = tmin
        t1 = 1e300
        for c in range(3):
            o = ox if c == 0 else (oy if c == 1 else oz)
            d = dx if c == 0 else (dy if c == 1 else dz)
            if d == 0.0:
                if o < node_lo[n, c] or o > node_hi[n, c]:
                    t0 = 1.0
                    t1 = 0.0
            else:
                a = (node_lo[n, c] - o) / d
                b = (node_hi[n, c] - o) / d
                t0 = max(t0, min(a, b))
                t1 = min(t1, max(a, b))
        return not (t0 > t1)

    @jit
    def ray_leaf(q, tris, t, blocked):
        ox, oy, oz, dx, dy, dz, tmin = q
        return crossing(ox, oy, oz, dx, dy, dz, tris[t, 0], tris[t, 1], tris[t, 2], tris[t, 3], tris[t, 4], tris[t, 5],
                        tris[t, 6], tris[t, 7], tris[t, 8], 1e-300, 0.0) > tmin

    @jit
    def blocked(state):
        return state

    any_hit = bvh_visit(jit, slab_box, ray_leaf, blocked)

    @jit
    def ray_blocked(ox, oy, oz, dx, dy, dz, tmin, node_lo, node_hi, node_child, node_range, tris, stack):
        """Whether the ray o + t d, t > tmin, meets a triangle (Moller-Trumbore, both faces,
        edges included); an any-hit query through the BVH."""
        return any_hit((ox, oy, oz, dx, dy, dz, tmin), False, node_lo, node_hi, node_child, node_range, tris, stack)

    return namespace(edge_side=edge_side, hit=hit, sort_hits=sort_hits, intervals_from_hits=intervals_from_hits,
                     bvh_line_hits=bvh_line_hits, cast_bvh_line=cast_bvh_line, box_line_hits=box_line_hits,
                     cast_box_line=cast_box_line, ray_blocked=ray_blocked)
