"""Drop-cutter device functions for vertical flat, ball and bull-nose (torus) cutters, written once
for every backend (see :mod:`meshmill.kernels.geom` for the conventions).

A cutter is given by its radius ``R`` and corner radius ``r`` (flat: r = 0, ball: r = R, bull:
0 < r < R). Its lower surface rises ``h(rho)`` above the tip at distance ``rho`` from the axis:
0 on the flat bottom (rho <= R - r), then the torus arc ``r - sqrt(r² - (rho - R + r)²)``.

Dropping the cutter at (x, y) onto a triangle gives the highest tip z at which it touches:
the best of the vertex contacts (``z_v - h(rho_v)``), the facet contact (the torus point whose
normal is the facet's, when it falls inside the triangle), and the edge contacts: along an edge the
tip height ``g(w) = z(w) - h(rho(w))`` is concave in the edge parameter w (a linear height minus a
convex function of a convex distance), so its maximum over the reachable part of the edge is an
end point or the single root of ``g'`` (closed form for a ball, safeguarded Newton to machine
precision for a torus). This replaces the offset-ellipse solve of other programs with an exact 1-D maximisation.
"""
from __future__ import annotations

import math

from . import geom
from .geom import namespace

NEG = -1.0e300
NO_BODY = ((), ())  # no shank or holder cylinders: ``body`` of the drop-cutter wrappers
PLANE_BOUND_NZ = 1e-6  # facets at least this far from vertical bound their triangle's contact by their plane's
BISECTIONS = 60
WARM_SLACK = 1e-9  # a neighbour's contact bounds the drop from below less this share of its height (+1 mm)
SPHERE_SLACK = 1e-9  # a ball passes over a triangle farther than its radius and this share of the centre's coordinates


def build(jit):
    """Compile the drop-cutter device functions with ``jit``."""
    point_triangle = geom.build(jit).point_triangle_dist2

    @jit
    def profile(rho, R, r):
        """Height of the cutter's lower surface above its tip at distance rho from the axis."""
        a = R - r
        if rho <= a:
            return 0.0
        q = rho - a
        v = r * r - q * q
        return r - math.sqrt(v) if v > 0.0 else r

    @jit
    def profile_slope(rho, R, r):
        a = R - r
        if rho <= a:
            return 0.0
        q = rho - a
        v = r * r - q * q
        return q / math.sqrt(v) if v > 0.0 else 1.0e300

    @jit
    def edge_drop(px, py, pz, qx, qy, qz, x, y, R, r, best):
        """Highest tip z touching segment p-q (NEG if out of reach or surely not above ``best``)
        and the contact parameter t."""
        ex = qx - px
        ey = qy - py
        L = math.sqrt(ex * ex + ey * ey)
        if L <= 1e-12 * (1.0 + abs(px) + abs(py)):
            return NEG, 0.0  # vertical edge: its top vertex is the contact
        ex /= L
        ey /= L
        uc = (x - px) * ex + (y - py) * ey
        d = abs((x - px) * ey - (y - py) * ex)
        if d > R or max(pz, qz) - profile(d, R, r) <= best:
            return NEG, 0.0
        s = math.sqrt(max(0.0, R * R - d * d))
        wa = max(-s, -uc)
        wb = min(s, L - uc)
        if wa > wb:
            return NEG, 0.0
        m = (qz - pz) / L
        ra = math.sqrt(d * d + wa * wa)
        rb = math.sqrt(d * d + wb * wb)
        ga = m - (profile_slope(ra, R, r) * wa / ra if ra > 0.0 else 0.0)
        gb = m - (profile_slope(rb, R, r) * wb / rb if rb > 0.0 else 0.0)
        if ga <= 0.0:
            w = wa
        elif gb >= 0.0:
            w = wb
        elif r == R:
            w = m * s / math.sqrt(1.0 + m * m)  # ball: closed form
            w = min(wb, max(wa, w))
        else:
            # torus: safeguarded Newton on the decreasing g' within the bracket [lo, hi]
            lo = wa
            hi = wb
            w = min(hi, max(lo, m * s / math.sqrt(1.0 + m * m)))  # start from the ball's answer
            a = R - r
            for _ in range(BISECTIONS):
                rm = math.sqrt(d * d + w * w)
                q = rm - a
                v = r * r - q * q
                if rm <= a or v <= 0.0 or rm == 0.0:
                    gm = m if rm <= a else -math.copysign(1.0e300, w)
                    step_ok = False
                    gpp = 0.0
                else:
                    sv = math.sqrt(v)
                    h1 = q / sv
                    h2 = r * r / (v * sv)
                    gm = m - h1 * w / rm
                    gpp = -(h2 * (w / rm) ** 2 + h1 * d * d / (rm * rm * rm))
                    step_ok = gpp < 0.0
                if gm > 0.0:
                    lo = w
                else:
                    hi = w
                nw = w - gm / gpp if step_ok else 0.5 * (lo + hi)
                if not (lo < nw < hi):
                    nw = 0.5 * (lo + hi)
                # g is flat at its maximum: 1e-10 mm in w is far below 1e-12 mm in height
                if abs(nw - w) <= 1e-10 * (R + abs(w)) or hi - lo <= 1e-10 * (R + abs(w)):
                    w = nw
                    break
                w = nw
        rho = min(R, math.sqrt(d * d + w * w))
        u = uc + w
        return pz + m * u - profile(rho, R, r), u / L

    @jit
    def facet_drop(tris, t, x, y, R, r):
        """Tip z of the cutter at (x, y) resting on the plane of triangle t: the cutter point whose
        normal is the plane's upward normal touches it; no point of the plane within the cutter's
        reach holds the tip higher. Returns that z (NEG for a vertical plane), the contact point,
        whether the contact falls inside the triangle (then it is the triangle's contact) and the
        z component of the plane's unit normal."""
        ax = tris[t, 0]
        ay = tris[t, 1]
        az = tris[t, 2]
        abx = tris[t, 3] - ax
        aby = tris[t, 4] - ay
        abz = tris[t, 5] - az
        acx = tris[t, 6] - ax
        acy = tris[t, 7] - ay
        acz = tris[t, 8] - az
        nx = aby * acz - abz * acy
        ny = abz * acx - abx * acz
        nz = abx * acy - aby * acx
        if nz < 0.0:
            nx, ny, nz = -nx, -ny, -nz
        nn = math.sqrt(nx * nx + ny * ny + nz * nz)
        if nz <= 1e-12 * nn:
            return NEG, 0.0, 0.0, 0.0, False, 0.0
        nx /= nn
        ny /= nn
        nz /= nn
        nh = math.sqrt(nx * nx + ny * ny)
        px = x
        py = y
        if nh > 0.0:
            px -= (R - r) * nx / nh + r * nx
            py -= (R - r) * ny / nh + r * ny
        # the plane's height at the contact, and whether it is inside the triangle's projection
        det = abx * acy - aby * acx
        wx = px - ax
        wy = py - ay
        b1 = (wx * acy - wy * acx) / det
        b2 = (abx * wy - aby * wx) / det
        zp = az + b1 * abz + b2 * acz
        return zp - r * (1.0 - nz), px, py, zp, b1 >= 0.0 and b2 >= 0.0 and b1 + b2 <= 1.0, nz

    @jit
    def triangle_drop(tris, t, x, y, R, r, best):
        """Highest tip z of the cutter at (x, y) touching triangle t if above ``best`` (else NEG),
        and the contact point. A contact never rises above the point touched, so a feature (the
        triangle, an edge, a vertex) lower than best is skipped."""
        zmax = max(tris[t, 2], tris[t, 5], tris[t, 8])
        if zmax <= best:
            return NEG, 0.0, 0.0, 0.0
        dx = max(min(tris[t, 0], tris[t, 3], tris[t, 6]) - x, 0.0, x - max(tris[t, 0], tris[t, 3], tris[t, 6]))
        dy = max(min(tris[t, 1], tris[t, 4], tris[t, 7]) - y, 0.0, y - max(tris[t, 1], tris[t, 4], tris[t, 7]))
        d2 = dx * dx + dy * dy
        if d2 > R * R or zmax - profile(math.sqrt(d2), R, r) <= best:
            return NEG, 0.0, 0.0, 0.0
        cz = best + R
        if r == R and zmax <= cz:
            # a ball with its tip at best is, below its centre, the sphere about it: a triangle wholly
            # below the centre and farther from it than R (and a slack far above the rounding of
            # the tests below) cannot hold the tip at best, so none of its features needs a test
            far = R + SPHERE_SLACK * (1.0 + abs(x) + abs(y) + abs(cz))
            if point_triangle(x, y, cz, tris, t) >= far * far:
                return NEG, 0.0, 0.0, 0.0
        top = best
        cx = 0.0
        cy = 0.0
        cz = 0.0
        z, px, py, pz, inside, nz = facet_drop(tris, t, x, y, R, r)
        if nz > PLANE_BOUND_NZ:  # not so steep that the plane's height is ill-conditioned
            if z <= best:  # every point of the triangle lies on that plane: none does better
                return NEG, 0.0, 0.0, 0.0
            if inside:  # the plane's best point is the triangle's
                return z, px, py, pz
        elif inside and z > top:
            top = z
            cx, cy, cz = px, py, pz
        for k in range(3):
            vz = tris[t, 3 * k + 2]
            if vz <= top:
                continue
            vx = tris[t, 3 * k]
            vy = tris[t, 3 * k + 1]
            rho = math.sqrt((vx - x) ** 2 + (vy - y) ** 2)
            if rho <= R:
                z = vz - profile(rho, R, r)
                if z > top:
                    top = z
                    cx, cy, cz = vx, vy, vz
        for k in range(3):
            j = (k + 1) % 3
            pz = tris[t, 3 * k + 2]
            qz = tris[t, 3 * j + 2]
            if max(pz, qz) <= top:
                continue
            px = tris[t, 3 * k]
            py = tris[t, 3 * k + 1]
            qx = tris[t, 3 * j]
            qy = tris[t, 3 * j + 1]
            z, f = edge_drop(px, py, pz, qx, qy, qz, x, y, R, r, top)
            if z > top:
                top = z
                cx = px + f * (qx - px)
                cy = py + f * (qy - py)
                cz = pz + f * (qz - pz)
        if top > best:
            return top, cx, cy, cz
        return NEG, 0.0, 0.0, 0.0

    @jit
    def mesh_drop(x, y, R, r, floor, sx, sy, sz, node_lo, node_hi, node_child, node_range, tris, stack):
        """Drop the cutter at (x, y) onto the mesh: the highest touching tip z (at least floor) and
        the contact point (NaN when the floor wins). ``(sx, sy, sz)``: a point of the mesh (NaN for
        none), usually a neighbour's contact: the tip height it gives (less ``WARM_SLACK``) is a
        first lower bound, so the search prunes what lies below it from the start. The height
        and contact are always a triangle's (the one that point lies on lifts the tool at least
        as high), so they do not depend on the point given: a point dropped alone, in another
        order or with other points comes out the same, bit for bit."""
        warm = floor
        rho = math.sqrt((sx - x) ** 2 + (sy - y) ** 2)
        if rho <= R:  # False for NaN
            z = sz - profile(rho, R, r)
            warm = max(floor, z - WARM_SLACK * (1.0 + abs(z)))
        best = warm
        cx = math.nan
        cy = math.nan
        cz = math.nan
        while True:
            stack[0] = 0
            sp = 1
            while sp > 0:
                sp -= 1
                n = stack[sp]
                if node_hi[n, 2] <= best:
                    continue
                dx = max(node_lo[n, 0] - x, 0.0, x - node_hi[n, 0])
                dy = max(node_lo[n, 1] - y, 0.0, y - node_hi[n, 1])
                d2 = dx * dx + dy * dy
                if d2 > R * R:
                    continue
                # no point of the box can lift the tip above its top less the cutter's rise there
                if node_hi[n, 2] - profile(math.sqrt(d2), R, r) <= best:
                    continue
                left = node_child[n, 0]
                if left < 0:
                    first = node_range[n, 0]
                    for k in range(first, first + node_range[n, 1]):
                        z, px, py, pz = triangle_drop(tris, k, x, y, R, r, best)
                        if z > best:
                            best = z
                            cx, cy, cz = px, py, pz
                else:
                    right = node_child[n, 1]
                    if node_hi[left, 2] > node_hi[right, 2]:  # higher child first
                        stack[sp] = right
                        stack[sp + 1] = left
                    else:
                        stack[sp] = left
                        stack[sp + 1] = right
                    sp += 2
            if not math.isnan(cx) or warm == floor:
                break
            best = warm = floor  # (no triangle came above the warm bound: again from the floor)
        return best, cx, cy, cz

    @jit
    def tool_drop(x, y, R, r, body_r, body_t, floor, sx, sy, sz, node_lo, node_hi, node_child, node_range, tris,
                  stack):
        """As mesh_drop for the whole tool: the cutter, and above it the flat-bottomed cylinders of
        radius body_r[k] starting body_t[k] above the tip (shank, holder; those no wider than the
        cutter are covered by it)."""
        best, cx, cy, cz = mesh_drop(x, y, R, r, floor, sx, sy, sz, node_lo, node_hi, node_child, node_range, tris,
                                     stack)
        for k in range(body_r.shape[0]):
            if body_r[k] > R:
                z, px, py, pz = mesh_drop(x, y, body_r[k], 0.0, best + body_t[k], sx, sy, sz,
                                          node_lo, node_hi, node_child, node_range, tris, stack)
                # (nothing touched: z is the floor given, which less body_t may round above best)
                if not math.isnan(px) and z - body_t[k] > best:
                    best = z - body_t[k]
                    cx, cy, cz = px, py, pz
        return best, cx, cy, cz

    @jit
    def contact_reach(rise, R, r, body_r, body_t):
        """How far from a mesh point the whole tool's axis can be while that point holds the tip
        more than ``rise`` mm below it (-1 if nowhere): the tool's lower envelope (cutter profile,
        then the flat bottoms of the wider body cylinders) stays under ``rise`` up to there."""
        rho = -1.0
        if rise > 0.0:
            rho = R if rise >= r else R - r + math.sqrt(rise * (2.0 * r - rise))
        for k in range(body_r.shape[0]):
            if body_r[k] > R and body_t[k] < rise:
                rho = max(rho, body_r[k])
        return rho

    @jit
    def drop_run(i0, i1, xy, R, r, body_r, body_t, floor, node_lo, node_hi, node_child, node_range, tris, stack,
                 z, cc):
        """Drop the tool at points i0..i1-1 of ``xy`` in order, each starting from the previous
        one's contact (a neighbour's, in a grid or a pass): ``z[i]``, ``cc[i, :]``."""
        sx = math.nan
        sy = math.nan
        sz = math.nan
        for i in range(i0, i1):
            z[i], sx, sy, sz = tool_drop(xy[i, 0], xy[i, 1], R, r, body_r, body_t, floor, sx, sy, sz,
                                         node_lo, node_hi, node_child, node_range, tris, stack)
            cc[i, 0] = sx
            cc[i, 1] = sy
            cc[i, 2] = sz

    @jit
    def refine_run(s0, s1, last, xy, R, r, body_r, body_t, floor, grow, chord_tol, min_step, rounds,
                   node_lo, node_hi, node_child, node_range, tris, stack, pend, z, rows, n):
        """Drop the tool (its heights raised by ``grow``) at points s0..s1 of the polyline ``xy``
        in order, into ``z[s0:s1]`` (and ``z[s1]`` where ``last``), and refine each segment s-s+1
        between them on its own: its midpoint is dropped where it is longer than ``min_step``, and
        kept where its height leaves the chord by more than ``chord_tol``, its halves refined so in
        turn, ``rounds`` levels deep. A kept midpoint is the row ``(s, t, z, x, y)`` of ``rows``
        (t: its place along the segment, 0-1), appended at ``n``; returns the rows' count, -1 where
        ``rows`` is full. ``pend (rounds + 1, 9)``: the halves waiting."""
        sx = math.nan
        sy = math.nan
        sz = math.nan
        zb, sx, sy, sz = tool_drop(xy[s0, 0], xy[s0, 1], R, r, body_r, body_t, floor, sx, sy, sz,
                                   node_lo, node_hi, node_child, node_range, tris, stack)
        zb += grow
        z[s0] = zb
        for s in range(s0, s1):
            za = zb
            zb, sx, sy, sz = tool_drop(xy[s + 1, 0], xy[s + 1, 1], R, r, body_r, body_t, floor, sx, sy, sz,
                                       node_lo, node_hi, node_child, node_range, tris, stack)
            zb += grow
            if s + 1 < s1 or last:
                z[s + 1] = zb
            # (a, b): x, y, z, t of each end, and the depth
            pend[0, 0] = xy[s, 0]
            pend[0, 1] = xy[s, 1]
            pend[0, 2] = za
            pend[0, 3] = 0.0
            pend[0, 4] = xy[s + 1, 0]
            pend[0, 5] = xy[s + 1, 1]
            pend[0, 6] = zb
            pend[0, 7] = 1.0
            pend[0, 8] = 0.0
            top = 1
            while top > 0:
                top -= 1
                ax = pend[top, 0]
                ay = pend[top, 1]
                bx = pend[top, 4]
                by = pend[top, 5]
                dx = bx - ax
                dy = by - ay
                if not math.sqrt(dx * dx + dy * dy) > min_step:
                    continue
                mx = 0.5 * (ax + bx)
                my = 0.5 * (ay + by)
                zm, sx, sy, sz = tool_drop(mx, my, R, r, body_r, body_t, floor, sx, sy, sz,
                                           node_lo, node_hi, node_child, node_range, tris, stack)
                zm += grow
                if not abs(zm - 0.5 * (pend[top, 2] + pend[top, 6])) > chord_tol:
                    continue
                if n >= rows.shape[0]:
                    return -1
                tm = 0.5 * (pend[top, 3] + pend[top, 7])
                rows[n, 0] = s
                rows[n, 1] = tm
                rows[n, 2] = zm
                rows[n, 3] = mx
                rows[n, 4] = my
                n += 1
                depth = pend[top, 8] + 1.0
                if depth >= rounds:
                    continue
                # its halves: (a, m) where it was, (m, b) above it
                for k in range(4):
                    pend[top + 1, 4 + k] = pend[top, 4 + k]
                pend[top + 1, 8] = depth
                pend[top, 4] = mx
                pend[top, 5] = my
                pend[top, 6] = zm
                pend[top, 7] = tm
                pend[top, 8] = depth
                pend[top + 1, 0] = mx
                pend[top + 1, 1] = my
                pend[top + 1, 2] = zm
                pend[top + 1, 3] = tm
                top += 2
        return n

    @jit
    def touch_point(i, pa, pb, fa, fb, qa, z, R, r, body_r, body_t, floor, touch, width, rounds,
                    node_lo, node_hi, node_child, node_range, tris, stack, out):
        """Where the drop height crosses z between inside point ``pa[i]`` and outside point
        ``pb[i]``: ``out[i, :]`` (see the CPU ``touch_points``)."""
        ax = pa[i, 0]
        ay = pa[i, 1]
        bx = pb[i, 0]
        by = pb[i, 1]
        fbi = fb[i]
        ga = fa[i]
        gb = fbi
        qx = qa[i, 0]
        qy = qa[i, 1]
        qz = qa[i, 2]
        if math.isnan(qz):
            ga, qx, qy, qz = tool_drop(ax, ay, R, r, body_r, body_t, floor, qx, qy, qz,
                                       node_lo, node_hi, node_child, node_range, tris, stack)
            ga -= z
        sx = qx
        sy = qy
        sz = qz
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
                rho = contact_reach(qz - z, R, r, body_r, body_t)
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
            f, sx, sy, sz = tool_drop(px, py, R, r, body_r, body_t, floor, sx, sy, sz,
                                      node_lo, node_hi, node_child, node_range, tris, stack)
            f -= z
            if f > 0.0:
                ax = px
                ay = py
                ga = f
                qx = sx
                qy = sy
                qz = sz
                if side == 1:
                    gb *= 0.5
                side = 1
            else:
                if contact:  # the disk's exit, width/2 back, is inside or on the level set
                    back = 0.5 * width / math.sqrt((bx - ax) ** 2 + (by - ay) ** 2)
                    ax += (w - back) * (bx - ax)
                    ay += (w - back) * (by - ay)
                bx = px
                by = py
                fbi = f
                gb = f
                if side == -1:
                    ga *= 0.5
                side = -1
        out[i, 0] = bx
        out[i, 1] = by

    return namespace(profile=profile, contact_reach=contact_reach, edge_drop=edge_drop, triangle_drop=triangle_drop,
                     mesh_drop=mesh_drop, tool_drop=tool_drop, drop_run=drop_run, refine_run=refine_run,
                     touch_point=touch_point)
