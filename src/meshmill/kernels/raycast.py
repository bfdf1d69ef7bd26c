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

from types import SimpleNamespace

from .geom import STACK_SIZE  # noqa: F401  (callers size their traversal stacks with it)

MAX_HITS = 512  # crossings a line may have (callers' buffers); more is reported as an error


def build(jit):
    """Compile the device functions with ``jit`` and return them in a namespace."""

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
    def intervals_from_hits(hw, hs, n, out, row, cap):
        """Sort the ``n`` hits ``hw (w), hs (side)`` along the line and write the material
        intervals (depth > 0) into ``out[row, :cap, 2]``. Entries sort before exits at equal w, so
        touching pieces merge. Returns the interval count (may exceed cap: only cap are written),
        or -1 when the crossings do not balance (the mesh is not closed along this line)."""
        for i in range(1, n):  # insertion sort: few hits a line
            w = hw[i]
            s = hs[i]
            j = i - 1
            while j >= 0 and (hw[j] > w or (hw[j] == w and hs[j] > s)):
                hw[j + 1] = hw[j]
                hs[j + 1] = hs[j]
                j -= 1
            hw[j + 1] = w
            hs[j + 1] = s
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
    def bvh_line_hits(a, u0, v0, node_lo, node_hi, node_child, node_range, tris, stack, hw, hs):
        """Every crossing of the line with the mesh, through the BVH; returns the hit count
        (may exceed ``len(hw)``: only that many are stored)."""
        u = (a + 1) % 3
        v = (a + 2) % 3
        n = 0
        stack[0] = 0
        sp = 1
        while sp > 0:
            sp -= 1
            k = stack[sp]
            if u0 < node_lo[k, u] or u0 > node_hi[k, u] or v0 < node_lo[k, v] or v0 > node_hi[k, v]:
                continue
            left = node_child[k, 0]
            if left < 0:
                first = node_range[k, 0]
                # written out here and in box_line_hits: the innermost loop of line casting stays call-free
                for t in range(first, first + node_range[k, 1]):
                    side, w = hit(tris, t, a, u0, v0)
                    if side != 0:
                        if n < hw.shape[0]:
                            hw[n] = w
                            hs[n] = side
                        n += 1
            else:
                stack[sp] = left
                stack[sp + 1] = node_child[k, 1]
                sp += 2
        return n

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
        u = (a + 1) % 3
        v = (a + 2) % 3
        n = 0
        for k in range(box_lo.shape[0]):
            if u0 < box_lo[k, u] or u0 > box_hi[k, u] or v0 < box_lo[k, v] or v0 > box_hi[k, v]:
                continue
            for t in range(box_start[k], box_start[k + 1]):
                side, w = hit(tris, t, a, u0, v0)
                if side != 0:
                    if n < hw.shape[0]:
                        hw[n] = w
                        hs[n] = side
                    n += 1
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
    def ray_blocked(ox, oy, oz, dx, dy, dz, tmin, node_lo, node_hi, node_child, node_range, tris, stack):
        """Whether the ray o + t d, t > tmin, meets a triangle (Moller-Trumbore, both faces,
        edges included); an any-hit query through the BVH."""
        stack[0] = 0
        sp = 1
        while sp > 0:
            sp -= 1
            k = stack[sp]
            t0 = tmin
            t1 = 1e300
            for c in range(3):
                o = ox if c == 0 else (oy if c == 1 else oz)
                d = dx if c == 0 else (dy if c == 1 else dz)
                if d == 0.0:
                    if o < node_lo[k, c] or o > node_hi[k, c]:
                        t0 = 1.0
                        t1 = 0.0
                else:
                    a = (node_lo[k, c] - o) / d
                    b = (node_hi[k, c] - o) / d
                    t0 = max(t0, min(a, b))
                    t1 = min(t1, max(a, b))
            if t0 > t1:
                continue
            left = node_child[k, 0]
            if left >= 0:
                stack[sp] = left
                stack[sp + 1] = node_child[k, 1]
                sp += 2
                continue
            first = node_range[k, 0]
            for t in range(first, first + node_range[k, 1]):
                e1x = tris[t, 3] - tris[t, 0]
                e1y = tris[t, 4] - tris[t, 1]
                e1z = tris[t, 5] - tris[t, 2]
                e2x = tris[t, 6] - tris[t, 0]
                e2y = tris[t, 7] - tris[t, 1]
                e2z = tris[t, 8] - tris[t, 2]
                px = dy * e2z - dz * e2y
                py = dz * e2x - dx * e2z
                pz = dx * e2y - dy * e2x
                det = e1x * px + e1y * py + e1z * pz
                if abs(det) < 1e-300:
                    continue
                inv = 1.0 / det
                tx = ox - tris[t, 0]
                ty = oy - tris[t, 1]
                tz = oz - tris[t, 2]
                u = (tx * px + ty * py + tz * pz) * inv
                if u < 0.0 or u > 1.0:
                    continue
                qx = ty * e1z - tz * e1y
                qy = tz * e1x - tx * e1z
                qz = tx * e1y - ty * e1x
                v = (dx * qx + dy * qy + dz * qz) * inv
                if v < 0.0 or u + v > 1.0:
                    continue
                if (e2x * qx + e2y * qy + e2z * qz) * inv > tmin:
                    return True
        return False

    return SimpleNamespace(edge_side=edge_side, hit=hit, intervals_from_hits=intervals_from_hits,
                           bvh_line_hits=bvh_line_hits, cast_bvh_line=cast_bvh_line, box_line_hits=box_line_hits,
                           cast_box_line=cast_box_line,
                           ray_blocked=ray_blocked)
