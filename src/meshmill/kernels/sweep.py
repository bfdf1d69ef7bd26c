"""Where an axis-aligned line crosses the volume a cutter sweeps along a linear move (device
functions, written once for every backend).

Coordinates are in the line's frame: the line is ``(u0, v0, w)``, w free (see
:mod:`meshmill.kernels.raycast` for the axis order); every point handed in is already permuted
to that frame. An interval is ``(lo, hi)``; ``lo > hi`` means empty.

The cutter is the rounded-cylinder family ``Disk(rho) + Segment(H) + Ball(r)`` (Minkowski sums,
the disk perpendicular to the axis): a ball-end mill of radius R is rho = 0, r = R; a flat end
mill is r = 0, rho = R; a bull-nose is rho = R - r. Its end is exact; its flutes are the full
radius up to ``flute_length - r`` and rounded like the end above that, so the flute top never
cuts more than the real tool. Swept along a move with a fixed axis it becomes
``Disk(rho) + Parallelogram(D, H u) + Ball(r)``, convex, so a line meets it in one interval:

- ball (rho = 0): the parallelogram thickened by r is a slab-clipped parallelepiped plus four
  capsules on the edges; all closed form (:func:`pgram_ball`);
- flat and bull-nose with the axis along a coordinate axis of the line frame (a 3-axis tool
  against every dexel direction): the line meets the tool at each pose in closed form, and the
  ends of the sweep's interval are a convex (lower) and a concave (upper) function of the pose,
  searched by golden section over the poses that meet the line (:func:`aligned_sweep`);
- other flat and bull-nose moves: the distance from a line point to ``Disk + Parallelogram`` is
  convex along the line; its level set ``<= r`` is bracketed by the ball sweep of radius rho + r
  and found by bisection to ``BISECT_TOL`` (:func:`rounded_sweep`).

When the axis turns during a move (5-axis), see :func:`tool_move`: the callers split such moves
into pieces short enough for the stated sweep tolerance. A flat or bull-nose cutter's turning sweep
is searched over its poses, each in closed form but where the line passes through a rounded rim
(:func:`stand`).
"""
from __future__ import annotations

import math

from . import geom
from .geom import namespace

INF = 1.0e300
BISECT_TOL = 1e-9  # mm along the line
FACE_SLACK = 1e-12  # mm: a line this near a flat end's plane and along it lies in it
GOLDEN = 0.6180339887498949
SEARCH_SAMPLES = 16  # poses sampled along a turning piece before the golden-section search
SEARCH_TOL = 1e-6  # mm: the golden-section search stops when its poses differ by this at most
NEWTON_STEPS = 12  # Newton's steps to a rounded rim before regula falsi takes over
SEARCH_STEPS = 60  # poses the golden-section search evaluates at most (0.618^60 of the bracket)


def build(jit):
    """Compile the device functions with ``jit`` and return them in a namespace."""
    g = geom.build(jit)

    @jit
    def golden_step(a, b, s1, s2, f1, f2):
        """One step of a golden-section search for a minimum in ``[a, b]`` (``s1 < s2`` inside,
        their values ``f1, f2``): the new bracket and inner points, the value kept, and whether
        the new point to evaluate is ``s1`` (else ``s2``)."""
        if f1 <= f2:
            b = s2
            return a, b, b - GOLDEN * (b - a), s1, f1, f1, True
        a = s1
        return a, b, s2, a + GOLDEN * (b - a), f2, f2, False

    @jit
    def sphere(u0, v0, cu, cv, cw, R):
        """Line against the ball of radius R at c."""
        q = R * R - (u0 - cu) ** 2 - (v0 - cv) ** 2
        if q < 0.0:
            return INF, -INF
        h = math.sqrt(q)
        return cw - h, cw + h

    @jit
    def capsule(u0, v0, au, av, aw, bu, bv, bw, R):
        """Line against the capsule of radius R around segment a-b."""
        lo, hi = sphere(u0, v0, au, av, aw, R)
        l2, h2 = sphere(u0, v0, bu, bv, bw, R)
        lo = min(lo, l2)
        hi = max(hi, h2)
        du = bu - au
        dv = bv - av
        dw = bw - aw
        dd = du * du + dv * dv + dw * dw
        if dd <= 1e-24:
            return lo, hi
        pu = u0 - au
        pv = v0 - av
        # k(z) = (pu, pv, z); t(z) = (s0 + z dw)/dd; |k|^2 - (k.d)^2/dd <= R^2
        s0 = pu * du + pv * dv
        A = 1.0 - dw * dw / dd
        B = -2.0 * s0 * dw / dd
        C = pu * pu + pv * pv - s0 * s0 / dd - R * R
        if A <= 1e-14:  # segment along the line: constant distance
            if C > 0.0:
                return lo, hi
            z0, z1 = -INF, INF
        else:
            disc = B * B - 4.0 * A * C
            if disc < 0.0:
                return lo, hi
            sq = math.sqrt(disc)
            z0 = (-B - sq) / (2.0 * A)
            z1 = (-B + sq) / (2.0 * A)
        # clip to 0 <= t <= 1
        if dw > 0.0:
            z0 = max(z0, -s0 / dw)
            z1 = min(z1, (dd - s0) / dw)
        elif dw < 0.0:
            z0 = max(z0, (dd - s0) / dw)
            z1 = min(z1, -s0 / dw)
        elif s0 < 0.0 or s0 > dd:
            return lo, hi
        if z0 <= z1:
            lo = min(lo, z0 + aw)
            hi = max(hi, z1 + aw)
        return lo, hi

    @jit
    def pgram_ball(u0, v0, cu, cv, cw, Du, Dv, Dw, Eu, Ev, Ew, R, tri=False):
        """Line against ``Parallelogram(c; D, E) + Ball(R)``, or with ``tri`` the triangle
        ``(c, c + D, c + E) + Ball(R)``."""
        nu = Dv * Ew - Dw * Ev
        nv = Dw * Eu - Du * Ew
        nw = Du * Ev - Dv * Eu
        area = math.sqrt(nu * nu + nv * nv + nw * nw)
        dd = Du * Du + Dv * Dv + Dw * Dw
        ee = Eu * Eu + Ev * Ev + Ew * Ew
        if area <= 1e-12 * max(dd + ee, 1e-300):
            # degenerate: the four corners lie on one line; a capsule over the extreme two
            if dd >= ee:
                xu, xv, xw, xx = Du, Dv, Dw, dd
            else:
                xu, xv, xw, xx = Eu, Ev, Ew, ee
            if xx <= 1e-24:
                return sphere(u0, v0, cu, cv, cw, R)
            tmin = min(0.0, min((Du * xu + Dv * xv + Dw * xw) / xx, (Eu * xu + Ev * xv + Ew * xw) / xx))
            tmax = max(0.0, max((Du * xu + Dv * xv + Dw * xw) / xx, (Eu * xu + Ev * xv + Ew * xw) / xx))
            if not tri:
                tmin = min(tmin, ((Du + Eu) * xu + (Dv + Ev) * xv + (Dw + Ew) * xw) / xx)
                tmax = max(tmax, ((Du + Eu) * xu + (Dv + Ev) * xv + (Dw + Ew) * xw) / xx)
            return capsule(u0, v0, cu + tmin * xu, cv + tmin * xv, cw + tmin * xw,
                           cu + tmax * xu, cv + tmax * xv, cw + tmax * xw, R)
        nu /= area
        nv /= area
        nw /= area
        lo, hi = capsule(u0, v0, cu, cv, cw, cu + Du, cv + Dv, cw + Dw, R)
        l2, h2 = capsule(u0, v0, cu, cv, cw, cu + Eu, cv + Ev, cw + Ew, R)
        lo = min(lo, l2)
        hi = max(hi, h2)
        if tri:
            l2, h2 = capsule(u0, v0, cu + Du, cv + Dv, cw + Dw, cu + Eu, cv + Ev, cw + Ew, R)
            lo = min(lo, l2)
            hi = max(hi, h2)
        else:
            l2, h2 = capsule(u0, v0, cu + Eu, cv + Ev, cw + Ew, cu + Eu + Du, cv + Ev + Dv, cw + Ew + Dw, R)
            lo = min(lo, l2)
            hi = max(hi, h2)
            l2, h2 = capsule(u0, v0, cu + Du, cv + Dv, cw + Dw, cu + Du + Eu, cv + Dv + Ev, cw + Dw + Ew, R)
            lo = min(lo, l2)
            hi = max(hi, h2)
        # the slab part: p - c = s D + h E + t n, 0 <= s, h <= 1, |t| <= R; rows of the inverse
        # are (E x n)/area, (n x D)/area, n (det = area)
        r0u = (Ev * nw - Ew * nv) / area
        r0v = (Ew * nu - Eu * nw) / area
        r0w = (Eu * nv - Ev * nu) / area
        r1u = (nv * Dw - nw * Dv) / area
        r1v = (nw * Du - nu * Dw) / area
        r1w = (nu * Dv - nv * Du) / area
        pu = u0 - cu
        pv = v0 - cv
        z0 = -INF
        z1 = INF
        for k in range(4 if tri else 3):
            if k == 0:
                a0 = r0u * pu + r0v * pv - r0w * cw
                b0 = r0w
                lim0, lim1 = 0.0, 1.0
            elif k == 1:
                a0 = r1u * pu + r1v * pv - r1w * cw
                b0 = r1w
                lim0, lim1 = 0.0, 1.0
            elif k == 2:
                a0 = nu * pu + nv * pv - nw * cw
                b0 = nw
                lim0, lim1 = -R, R
            else:  # triangle: s + h <= 1
                a0 = (r0u + r1u) * pu + (r0v + r1v) * pv - (r0w + r1w) * cw
                b0 = r0w + r1w
                lim0, lim1 = -INF, 1.0
            # coordinate = a0 + w b0 must lie in [lim0, lim1]
            if b0 == 0.0:
                if a0 < lim0 or a0 > lim1:
                    return lo, hi
            else:
                t0 = (lim0 - a0) / b0
                t1 = (lim1 - a0) / b0
                if t0 > t1:
                    t0, t1 = t1, t0
                z0 = max(z0, t0)
                z1 = min(z1, t1)
        if z0 <= z1:
            lo = min(lo, z0)
            hi = max(hi, z1)
        return lo, hi

    @jit
    def convex_floor(a, s1, s2, b, fa, f1, f2, fb):
        """A lower bound of a convex function on ``[a, b]`` from its values at ``a < s1 < s2 < b``:
        each piece lies above the chords of its neighbours extended (-INF where points coincide)."""
        if not (a < s1 < s2 < b):
            return -INF
        m12 = (f2 - f1) / (s2 - s1)
        m01 = (f1 - fa) / (s1 - a)
        m23 = (fb - f2) / (b - s2)
        # [a, s1] and [s2, b]: above the middle chord extended, least at their ends
        low = min(min(f1, f2), min(f1 + m12 * (a - s1), f2 + m12 * (b - s2)))
        # [s1, s2]: above both outer chords; the least of their maximum at an end or where they cross
        mid = min(max(f1, f2 + m23 * (s1 - s2)), max(f1 + m01 * (s2 - s1), f2))
        if m01 < m23:
            x = (f2 - f1 + m01 * s1 - m23 * s2) / (m01 - m23)
            if s1 < x < s2:
                mid = min(mid, f1 + m01 * (x - s1))
        return min(low, mid)

    @jit
    def offset_dist2(s, su, sv, sw, eu, ev, ew, qa, Da, H, rho):
        """Squared distance of :func:`core_dist2` to the core placed at fraction s of the move
        (``su..`` the point's part normal to the axis, ``eu..`` the move's, ``qa, Da`` along it)."""
        du = su - s * eu
        dv = sv - s * ev
        dw = sw - s * ew
        radial = max(0.0, math.sqrt(du * du + dv * dv + dw * dw) - rho)
        ax = qa - s * Da
        gap = max(0.0, max(-ax, ax - H))
        return radial * radial + gap * gap

    @jit
    def core_dist2(pu, pv, pw, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, enough, prove):
        """Squared distance from p to ``Disk(rho) + Parallelogram(c; D, H x)``, x the unit axis,
        the disk perpendicular to x; or any value <= ``enough`` once one is found (the callers
        only ask whether p lies within a distance); with ``prove``, any value > ``enough`` once
        the distance is proven to exceed it (for callers that ask only that)."""
        qu = pu - cu
        qv = pv - cv
        qw = pw - cw
        qa = qu * xu + qv * xv + qw * xw
        Da = Du * xu + Dv * xv + Dw * xw
        # perpendicular parts
        su = qu - qa * xu
        sv = qv - qa * xv
        sw = qw - qa * xw
        eu = Du - Da * xu
        ev = Dv - Da * xv
        ew = Dw - Da * xw
        ee = eu * eu + ev * ev + ew * ew
        dscale = Du * Du + Dv * Dv + Dw * Dw
        if ee <= 1e-20 * max(dscale, 1e-300):
            # move along the axis: radial term constant, axial term over an interval
            radial = max(0.0, math.sqrt(su * su + sv * sv + sw * sw) - rho)
            a0 = qa - max(Da, 0.0)
            a1 = qa - min(Da, 0.0)
            gap = max(0.0, max(-a1, a0 - H))
            return radial * radial + gap * gap
        if abs(Da) <= 1e-10 * math.sqrt(dscale):
            s = min(1.0, max(0.0, (su * eu + sv * ev + sw * ew) / ee))
            du = su - s * eu
            dv = sv - s * ev
            dw = sw - s * ew
            radial = max(0.0, math.sqrt(du * du + dv * dv + dw * dw) - rho)
            gap = max(0.0, max(-qa, qa - H))
            return radial * radial + gap * gap
        # general: convex in s; the ends, then a golden-section search on [0, 1]
        fa = offset_dist2(0.0, su, sv, sw, eu, ev, ew, qa, Da, H, rho)
        fb = offset_dist2(1.0, su, sv, sw, eu, ev, ew, qa, Da, H, rho)
        best = min(fa, fb)
        a = 0.0
        b = 1.0
        s1 = b - GOLDEN
        s2 = GOLDEN
        f1 = offset_dist2(s1, su, sv, sw, eu, ev, ew, qa, Da, H, rho)
        f2 = offset_dist2(s2, su, sv, sw, eu, ev, ew, qa, Da, H, rho)
        while b - a > 1e-12 and best > enough:
            best = min(best, min(f1, f2))
            if prove and best > enough and convex_floor(a, s1, s2, b, fa, f1, f2, fb) \
                    > enough + 1e-12 * (1.0 + max(max(fa, fb), max(f1, f2))):
                return best  # the whole bracket proven beyond enough
            if f1 <= f2:
                fb = f2
            else:
                fa = f1
            a, b, s1, s2, f1, f2, left = golden_step(a, b, s1, s2, f1, f2)
            if left:
                f1 = offset_dist2(s1, su, sv, sw, eu, ev, ew, qa, Da, H, rho)
            else:
                f2 = offset_dist2(s2, su, sv, sw, eu, ev, ew, qa, Da, H, rho)
        return min(best, min(f1, f2))

    @jit
    def level_edge(w_out, w_in, u0, v0, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r2):
        """Bisect between a line point outside (``w_out``) and one inside (``w_in``) the set
        ``core_dist2 <= r2``; returns the inside end, within ``BISECT_TOL`` of the boundary."""
        while abs(w_in - w_out) > BISECT_TOL:
            m = 0.5 * (w_out + w_in)
            if core_dist2(u0, v0, m, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r2, True) <= r2:
                w_in = m
            else:
                w_out = m
        return w_in

    @jit
    def rounded_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r):
        """Line against ``Disk(rho) + Parallelogram(c; D, H x) + Ball(r)`` (rho > 0)."""
        olo, ohi = pgram_ball(u0, v0, cu, cv, cw, Du, Dv, Dw, H * xu, H * xv, H * xw, rho + r)
        if olo > ohi:
            return INF, -INF
        r2 = r * r + 1e-18
        ilo, ihi = pgram_ball(u0, v0, cu, cv, cw, Du, Dv, Dw, H * xu, H * xv, H * xw, r)
        if ilo <= ihi:
            inside = 0.5 * (ilo + ihi)
        else:
            # find a point inside: golden-section on the convex distance over the outer interval
            a = olo
            b = ohi
            inside = INF
            m = 0.5 * (a + b)
            if core_dist2(u0, v0, m, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r2, False) <= r2:
                inside = m
            else:
                for _ in range(80):
                    w1 = b - GOLDEN * (b - a)
                    w2 = a + GOLDEN * (b - a)
                    f1 = core_dist2(u0, v0, w1, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r2, False)
                    if f1 <= r2:
                        inside = w1
                        break
                    f2 = core_dist2(u0, v0, w2, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r2, False)
                    if f2 <= r2:
                        inside = w2
                        break
                    if f1 <= f2:
                        b = w2
                    else:
                        a = w1
                    if b - a < BISECT_TOL:
                        break
            if inside == INF:
                return INF, -INF
            ilo = inside
            ihi = inside
        # bisection for both ends of the level set
        lo = level_edge(olo, ilo, u0, v0, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r2)
        return lo, level_edge(ohi, ihi, u0, v0, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r2)

    @jit
    def near_range(pu, pv, pw, qu, qv, qw, rho):
        """``(lo, hi)``: the t where ``|p + t q| <= rho`` (q may be 0: all t or none)."""
        qq = qu * qu + qv * qv + qw * qw
        pq = pu * qu + pv * qv + pw * qw
        c = pu * pu + pv * pv + pw * pw - rho * rho
        if qq <= 1e-24:
            if c <= 0.0:
                return -INF, INF
            return INF, -INF
        disc = pq * pq - qq * c
        if disc < 0.0:
            # a line that touches (in exact arithmetic) touches: rounding may leave it 1e-12 short
            if disc < -1e-12 * max(pq * pq, qq * rho * rho * qq):
                return INF, -INF
            disc = 0.0
        k = -(pq + math.copysign(math.sqrt(disc), pq))
        if k == 0.0:
            return 0.0, 0.0
        t0 = k / qq
        t1 = c / k
        return min(t0, t1), max(t0, t1)

    @jit
    def flat_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho):
        """Line against ``Disk(rho) + Parallelogram(c; D, H x)`` (a flat end mill or a shank swept
        with a fixed axis), in closed form. A line point at w is in it where some
        ``alpha, s in [0, 1] x [0, H]`` along D and up x leave it within rho of the axis: with
        ``s = (q - c).x - alpha D.x``, the (w, alpha) that do form an ellipse (the distance
        across x, quadratic) cut by two strips (alpha and s), convex; its lowest and highest w
        lie where an edge of the strips crosses the ellipse or at the ellipse's own extremes."""
        # q(w) - c = d + w e, e the line's direction; across x: a + w b + alpha g (g: -D across x)
        du = u0 - cu
        dv = v0 - cv
        dw = -cw
        dx = du * xu + dv * xv + dw * xw
        Dx = Du * xu + Dv * xv + Dw * xw
        au = du - dx * xu
        av = dv - dx * xv
        aw = dw - dx * xw
        bu = -xw * xu
        bv = -xw * xv
        bw = 1.0 - xw * xw
        gu = -(Du - Dx * xu)
        gv = -(Dv - Dx * xv)
        gw = -(Dw - Dx * xw)
        along = abs(xw) > 1e-12  # s changes along the line
        lo = INF
        hi = -INF
        for edge in range(2):  # the edges alpha = 0, 1: w within the ellipse and the strip of s
            alpha = float(edge)
            w0, w1 = near_range(au + alpha * gu, av + alpha * gv, aw + alpha * gw, bu, bv, bw, rho)
            s = dx - alpha * Dx  # s at w = 0
            if along:
                z0 = -s / xw
                z1 = (H - s) / xw
                w0 = max(w0, min(z0, z1))
                w1 = min(w1, max(z0, z1))
            elif s < -FACE_SLACK or s > H + FACE_SLACK:  # a line in the end's plane meets it
                continue
            if w0 <= w1:
                lo = min(lo, w0)
                hi = max(hi, w1)
        for edge in range(2):  # the edges s = 0, H: alpha within [0, 1] and the ellipse
            top = H * edge
            if along:
                # w = w0 + alpha wa
                w0 = (top - dx) / xw
                wa = Dx / xw
                t0, t1 = near_range(au + w0 * bu, av + w0 * bv, aw + w0 * bw, gu + wa * bu, gv + wa * bv,
                                    gw + wa * bw, rho)
                t0 = max(t0, 0.0)
                t1 = min(t1, 1.0)
                if t0 <= t1:
                    lo = min(lo, w0 + min(t0 * wa, t1 * wa))
                    hi = max(hi, w0 + max(t0 * wa, t1 * wa))
            elif abs(Dx) > 1e-12:
                alpha = (dx - top) / Dx
                if 0.0 <= alpha <= 1.0:
                    w0, w1 = near_range(au + alpha * gu, av + alpha * gv, aw + alpha * gw, bu, bv, bw, rho)
                    if w0 <= w1:
                        lo = min(lo, w0)
                        hi = max(hi, w1)
        # the ellipse's own lowest and highest w, where the alpha nearest them lies in the strips
        gg = gu * gu + gv * gv + gw * gw
        if gg > 1e-24:
            ka = (au * gu + av * gv + aw * gw) / gg
            kb = (bu * gu + bv * gv + bw * gw) / gg
            w0, w1 = near_range(au - ka * gu, av - ka * gv, aw - ka * gw, bu - kb * gu, bv - kb * gv, bw - kb * gw,
                                rho)
            if w0 <= w1 and w1 < INF:
                for end in range(2):
                    w = w1 if end else w0
                    alpha = -(ka + w * kb)
                    s = dx + w * xw - alpha * Dx
                    if 0.0 <= alpha <= 1.0 and 0.0 <= s <= H:
                        lo = min(lo, w)
                        hi = max(hi, w)
        if lo > hi:
            return INF, -INF
        return lo, hi

    @jit
    def aligned_at(s, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper):
        """:func:`aligned_sweep`'s function of the pose s (the line meets the tool there): the
        lower end of the line's interval with the tool at s (``upper``: minus the upper end)."""
        bu = u0 - cu - s * Du
        bv = v0 - cv - s * Dv
        w = cw + s * Dw
        if k == 2:  # axis along the line: radial distance d, core from w to w + sgn H
            t = max(0.0, math.sqrt(bu * bu + bv * bv) - rho)
            g = math.sqrt(max(0.0, r * r - t * t))
            if upper:
                return -(w + max(0.0, sgn * H) + g)
            return w + min(0.0, sgn * H) - g
        # axis across the line, along u (k = 0) or v (k = 1): axial a, offset b
        a = sgn * (bu if k == 0 else bv)
        b = bv if k == 0 else bu
        gap = max(0.0, max(-a, a - H))
        reach = rho + math.sqrt(max(0.0, r * r - gap * gap))
        h = math.sqrt(max(0.0, reach * reach - b * b))
        return -(w + h) if upper else w - h

    @jit
    def slab_range(p, dp, lo, hi, s0, s1):
        """``[s0, s1]`` clipped to where ``lo <= p + s dp <= hi``."""
        if dp == 0.0:
            if p < lo or p > hi:
                return 1.0, 0.0
            return s0, s1
        t0 = (lo - p) / dp
        t1 = (hi - p) / dp
        return max(s0, min(t0, t1)), min(s1, max(t0, t1))

    @jit
    def disk_range(pa, pb, da, db, R):
        """Where ``|(pa, pb) + s (da, db)| <= R`` over s in [0, 1] (empty: first > second)."""
        A = da * da + db * db
        B = pa * da + pb * db
        C = pa * pa + pb * pb - R * R
        if A <= 1e-300:
            return (0.0, 1.0) if C <= 0.0 else (1.0, 0.0)
        disc = B * B - A * C
        if disc < 0.0:
            return 1.0, 0.0
        q = math.sqrt(disc)
        return max(0.0, (-B - q) / A), min(1.0, (-B + q) / A)

    @jit
    def aligned_poses(u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r):
        """The poses s in [0, 1] at which the line meets the tool of :func:`aligned_sweep`: an
        interval (the set is convex), ``(1, 0)`` when none."""
        bu = u0 - cu
        bv = v0 - cv
        if k == 2:
            return disk_range(bu, bv, -Du, -Dv, rho + r)
        # the section of the tool by the plane of the line and the axis: the rectangle
        # [0, H] x [-rho, rho] (axial, offset) grown by r; the union of two rectangles and four disks
        a0 = sgn * (bu if k == 0 else bv)
        da = -sgn * (Du if k == 0 else Dv)
        b0 = bv if k == 0 else bu
        db = -(Dv if k == 0 else Du)
        lo, hi = slab_range(a0, da, -r, H + r, 0.0, 1.0)
        lo, hi = slab_range(b0, db, -rho, rho, lo, hi)
        l2, h2 = slab_range(a0, da, 0.0, H, 0.0, 1.0)
        l2, h2 = slab_range(b0, db, -rho - r, rho + r, l2, h2)
        if l2 <= h2:
            if lo <= hi:
                lo, hi = min(lo, l2), max(hi, h2)
            else:
                lo, hi = l2, h2
        if r > 0.0:
            for corner in range(4):
                ca = 0.0 if corner < 2 else H
                cb = rho if corner % 2 == 0 else -rho
                l2, h2 = disk_range(a0 - ca, b0 - cb, da, db, r)
                if l2 <= h2:
                    if lo <= hi:
                        lo, hi = min(lo, l2), max(hi, h2)
                    else:
                        lo, hi = l2, h2
        return lo, hi

    @jit
    def aligned_extreme(s0, s1, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper):
        """Lowest start (``upper`` False) or minus the highest end of the line in the tool over
        the poses ``s0 <= s <= s1`` (those meeting the line) of :func:`aligned_sweep`: each is
        convex in s (the set of (s, w) with the line point w in the tool at pose s is convex), so
        a golden-section search to 1e-12 in s, with both ends evaluated."""
        best = min(aligned_at(s0, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper),
                   aligned_at(s1, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper))
        a = s0
        b = s1
        s1 = b - GOLDEN * (b - a)
        s2 = a + GOLDEN * (b - a)
        f1 = aligned_at(s1, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper)
        f2 = aligned_at(s2, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper)
        while b - a > 1e-12:
            best = min(best, min(f1, f2))
            a, b, s1, s2, f1, f2, left = golden_step(a, b, s1, s2, f1, f2)
            if left:
                f1 = aligned_at(s1, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper)
            else:
                f2 = aligned_at(s2, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, upper)
        return min(best, min(f1, f2))

    @jit
    def aligned_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r):
        """Line against ``Disk(rho) + Parallelogram(c; D, H x) + Ball(r)`` when the axis x is
        ``sgn`` times coordinate axis k of the line frame (k = 2: along the line; a 3-axis tool
        against every dexel direction): the line meets the tool at each pose in closed form, and
        the sweep's interval is the union over the poses (see :func:`aligned_extreme`)."""
        s0, s1 = aligned_poses(u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r)
        if s0 > s1:
            return INF, -INF
        return (aligned_extreme(s0, s1, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, False),
                -aligned_extreme(s0, s1, u0, v0, cu, cv, cw, Du, Dv, Dw, k, sgn, H, rho, r, True))

    @jit
    def fixed_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r):
        """Line against ``Disk(rho) + Parallelogram(c; D, H x) + Ball(r)`` (rho > 0): in closed
        form when r = 0 (a flat end), or per pose when x lies along a coordinate axis of the line
        frame, else by bisection."""
        if r <= 0.0:
            # grown by the distance the bisection took points within on every side (a side the
            # line touches along the move is met along the touch, as one exactly in the plane of
            # an end), within the ball sweep of radius rho that holds the tool
            t = BISECT_TOL
            lo, hi = flat_sweep(u0, v0, cu - t * xu, cv - t * xv, cw - t * xw, Du, Dv, Dw, xu, xv, xw, H + 2.0 * t,
                                rho + t)
            olo, ohi = pgram_ball(u0, v0, cu, cv, cw, Du, Dv, Dw, H * xu, H * xv, H * xw, rho)
            lo = max(lo, olo)
            hi = min(hi, ohi)
            if lo > hi:
                return INF, -INF
            return lo, hi
        if xu == 0.0 and xv == 0.0:
            return aligned_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, 2, 1.0 if xw > 0.0 else -1.0, H, rho, r)
        if xw == 0.0 and (xu == 0.0 or xv == 0.0):
            k = 0 if xv == 0.0 else 1
            return aligned_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, k, 1.0 if xu + xv > 0.0 else -1.0, H, rho, r)
        return rounded_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, xu, xv, xw, H, rho, r)

    @jit
    def cylinder_line(pu, pv, pw, xu, xv, xw, a_lo, a_hi, R):
        """``(lo, hi)`` of the line through ``(pu, pv, 0)`` along w (coordinates relative to a
        point c on the axis, unit axis x) inside the solid cylinder ``a_lo <= (p - c).x <= a_hi``,
        radius R (empty: lo > hi); ``pw`` is c's w, added back."""
        e = pu * xu + pv * xv  # the axial coordinate at w = pw is e, and grows by xw along w
        lo = -INF
        hi = INF
        if xw == 0.0:
            if e < a_lo or e > a_hi:
                return INF, -INF
        else:
            z0 = (a_lo - e) / xw
            z1 = (a_hi - e) / xw
            lo = min(z0, z1)
            hi = max(z0, z1)
        # radial distance squared: A z^2 + 2 B z + C0 (z = w - pw)
        A = xu * xu + xv * xv
        B = -e * xw
        C = pu * pu + pv * pv - e * e - R * R
        if A <= 1e-24:
            if C > 0.0:
                return INF, -INF
        else:
            disc = B * B - A * C
            if disc < 0.0:
                return INF, -INF
            q = -(B + math.copysign(math.sqrt(disc), B))
            if q == 0.0:  # B = 0 and disc = 0: the line grazes the cylinder at z = 0
                z0 = 0.0
                z1 = 0.0
            else:
                z0 = q / A
                z1 = C / q
            lo = max(lo, min(z0, z1))
            hi = min(hi, max(z0, z1))
        if lo > hi:
            return INF, -INF
        return pw + lo, pw + hi

    @jit
    def stand_distance(w, pu, pv, pw, xu, xv, xw, H, rho):
        """``(d2, slope)``: the squared distance from the line point at w to
        ``Disk(rho) + Segment(c, c + H x)`` and the derivative of the distance along the line."""
        z = w - pw
        a = pu * xu + pv * xv + z * xw
        s2 = max(0.0, pu * pu + pv * pv + z * z - a * a)
        rad = math.sqrt(s2)
        radial = max(0.0, rad - rho)
        gap = max(0.0, max(-a, a - H))
        d2 = radial * radial + gap * gap
        if d2 <= 0.0:
            return 0.0, 0.0
        slope = 0.0
        if radial > 0.0:
            slope += radial * (z - a * xw) / rad
        if gap > 0.0:
            slope += gap * (-xw if a < 0.0 else xw)
        return d2, slope / math.sqrt(d2)

    @jit
    def stand(u0, v0, cu, cv, cw, xu, xv, xw, H, rho, r, ends):
        """Line against ``Disk(rho) + Segment(c, c + H x) + Ball(r)`` (one pose, rho > 0): the
        cylinder of radius rho + r that holds it in closed form, which is exact where the line
        meets that beside the segment or within rho of the axis; where it meets it by a rounded
        rim (r > 0), root-finding on the distance to the core.
        ``ends``: 1 finds the lower end only, 2 the upper only, 3 both (the other is then only
        a bound: the line meets the tool when lo <= hi all the same)."""
        pu = u0 - cu
        pv = v0 - cv
        if xu == 0.0 and xv == 0.0:  # the axis along the line: the radial distance is the line's
            t = max(0.0, math.sqrt(pu * pu + pv * pv) - rho)
            if t > r:
                return INF, -INF
            g = math.sqrt(max(0.0, r * r - t * t))
            return (cw - g, cw + H + g) if xw > 0.0 else (cw - H - g, cw + g)
        olo, ohi = cylinder_line(pu, pv, cw, xu, xv, xw, -r, H + r, rho + r)
        if olo > ohi or r <= 0.0:
            return olo, ohi
        # an end of the outer cylinder beside the segment or within rho of the axis is the tool's
        rims = 0
        for side in range(2):
            if ends & (1 << side):
                z = (olo if side == 0 else ohi) - cw
                a = pu * xu + pv * xv + z * xw
                if (a < 0.0 or a > H) and pu * pu + pv * pv + z * z - a * a > rho * rho:
                    rims |= 1 << side
        if rims == 0:
            return olo, ohi
        # Newton's steps from outside: the distance is convex along the line, so they stay
        # outside and converge, or pass the line's closest point (the line misses the tool)
        lo = olo
        hi = ohi
        slow = 0
        for side in range(2):
            if not rims & (1 << side):
                continue
            w = olo if side == 0 else ohi
            inward = 1.0 if side == 0 else -1.0
            d2, slope = stand_distance(w, pu, pv, cw, xu, xv, xw, H, rho)
            d = math.sqrt(d2)
            for _ in range(NEWTON_STEPS):
                if d - r <= 1e-13:
                    break
                if slope * inward >= 0.0:
                    return INF, -INF
                w -= (d - r) / slope
                d2, slope = stand_distance(w, pu, pv, cw, xu, xv, xw, H, rho)
                d = math.sqrt(d2)
            # done where a point BISECT_TOL further in is inside (a line grazing a rim meets it
            # where the distance is flat: within 1e-13 of r there may still be far along it)
            further = stand_distance(w + inward * BISECT_TOL, pu, pv, cw, xu, xv, xw, H, rho)[0]
            if d - r > 0.0 and math.sqrt(further) > r:
                slow |= 1 << side
            if side == 0:
                lo = w
            else:
                hi = w
        if slow == 0:
            return lo, hi
        # where Newton is slow: regula falsi (Illinois' variant) to BISECT_TOL between that point
        # and one inside the tool (on the cylinders of radius rho + r over the segment or rho
        # over it lengthened by r, or else the line's point closest to the rims)
        l1, h1 = cylinder_line(pu, pv, cw, xu, xv, xw, 0.0, H, rho + r)
        l2, h2 = cylinder_line(pu, pv, cw, xu, xv, xw, -r, H + r, rho)
        ilo = min(l1, l2)
        ihi = max(h1, h2)
        r2 = r * r + 1e-18
        if ilo > ihi:
            a = lo
            b = hi
            inside = INF
            w1 = b - GOLDEN * (b - a)
            w2 = a + GOLDEN * (b - a)
            f1 = stand_distance(w1, pu, pv, cw, xu, xv, xw, H, rho)[0]
            f2 = stand_distance(w2, pu, pv, cw, xu, xv, xw, H, rho)[0]
            for _ in range(90):
                if f1 <= r2:
                    inside = w1
                    break
                if f2 <= r2:
                    inside = w2
                    break
                if b - a < BISECT_TOL:
                    break
                a, b, w1, w2, f1, f2, left = golden_step(a, b, w1, w2, f1, f2)
                if left:
                    f1 = stand_distance(w1, pu, pv, cw, xu, xv, xw, H, rho)[0]
                else:
                    f2 = stand_distance(w2, pu, pv, cw, xu, xv, xw, H, rho)[0]
            if inside == INF:
                return INF, -INF
            ilo = inside
            ihi = inside
        for side in range(2):
            if not slow & (1 << side):
                continue
            w_out = lo if side == 0 else hi
            w_in = ilo if side == 0 else ihi
            f_out = math.sqrt(stand_distance(w_out, pu, pv, cw, xu, xv, xw, H, rho)[0]) - r
            f_in = math.sqrt(stand_distance(w_in, pu, pv, cw, xu, xv, xw, H, rho)[0]) - r
            kept = 0
            for _ in range(200):
                if abs(w_in - w_out) <= BISECT_TOL or f_out <= 0.0:
                    break
                w = w_in + f_in * (w_out - w_in) / (f_in - f_out) if f_in < f_out else 0.5 * (w_in + w_out)
                if not (min(w_in, w_out) < w < max(w_in, w_out)):
                    w = 0.5 * (w_in + w_out)
                f = math.sqrt(stand_distance(w, pu, pv, cw, xu, xv, xw, H, rho)[0]) - r
                if f <= 0.0:
                    w_in = w
                    f_in = f
                    if kept == -1:
                        f_out *= 0.5
                    kept = -1
                else:
                    w_out = w
                    f_out = f
                    if kept == 1:
                        f_in *= 0.5
                    kept = 1
            if f_out <= 0.0:
                w_in = w_out
            if side == 0:
                lo = w_in
            else:
                hi = w_in
        return lo, hi

    @jit
    def pose(u0, v0, tu, tv, tw, xu, xv, xw, R, r, F, ends):
        """Line against the cutter standing at tip t with unit axis x (``ends``: see :func:`stand`)."""
        H = max(0.0, F - 2.0 * r)
        cu = tu + r * xu
        cv = tv + r * xv
        cw = tw + r * xw
        if R - r <= 1e-12:
            return capsule(u0, v0, cu, cv, cw, cu + H * xu, cv + H * xv, cw + H * xw, r)
        return stand(u0, v0, cu, cv, cw, xu, xv, xw, H, R - r, r, ends)

    @jit
    def pose_at(u0, v0, pa, pb, xa, xb, t, R, r, F, ends):
        """:func:`pose` at fraction t of a move (tip linear, axis normalised linear)."""
        xu = xa[0] + t * (xb[0] - xa[0])
        xv = xa[1] + t * (xb[1] - xa[1])
        xw = xa[2] + t * (xb[2] - xa[2])
        n = math.sqrt(xu * xu + xv * xv + xw * xw)
        return pose(u0, v0, pa[0] + t * (pb[0] - pa[0]), pa[1] + t * (pb[1] - pa[1]), pa[2] + t * (pb[2] - pa[2]),
                    xu / n, xv / n, xw / n, R, r, F, ends)

    @jit
    def turning_search(u0, v0, pa, pb, xa, xb, R, r, F, upper):
        """Lowest start (``upper`` False) or highest end of the pose intervals over the move: the
        best of ``SEARCH_SAMPLES + 1`` poses, then Brent's search around it (parabolas through
        the best three poses where they fit, golden sections where not; the pieces moves are
        split into turn little, so the extreme is unimodal there), one pose a step, until the
        best pose lies within ``SEARCH_TOL`` of both ends of the bracket at any point of the
        tool."""
        # how fast any point of the tool moves with t (the normalised axis turns at most
        # |xb - xa| / cos(turn / 2), under 1.01 |xb - xa| for the turns of a piece)
        speed = math.sqrt((pb[0] - pa[0]) ** 2 + (pb[1] - pa[1]) ** 2 + (pb[2] - pa[2]) ** 2) + 1.01 * (F + R) * \
            math.sqrt((xb[0] - xa[0]) ** 2 + (xb[1] - xa[1]) ** 2 + (xb[2] - xa[2]) ** 2)
        width = SEARCH_TOL / max(speed, SEARCH_TOL)
        best = INF
        tbest = -1.0
        for k in range(SEARCH_SAMPLES + 1):
            t = k / SEARCH_SAMPLES
            lo, hi = pose_at(u0, v0, pa, pb, xa, xb, t, R, r, F, 2 if upper else 1)
            f = (-hi if upper else lo) if lo <= hi else INF
            if f < best:
                best = f
                tbest = t
        if tbest < 0.0:
            return -INF if upper else INF
        a = max(0.0, tbest - 1.0 / SEARCH_SAMPLES)
        b = min(1.0, tbest + 1.0 / SEARCH_SAMPLES)
        # x the best pose so far, w the second best, v the one before (their values fx, fw, fv);
        # d the last step, e the one before it
        x = tbest
        w = tbest
        v = tbest
        fx = best
        fw = best
        fv = best
        d = 0.0
        e = 0.0
        step = 0.5 * width  # the least step
        for _ in range(SEARCH_STEPS):
            if max(x - a, b - x) <= width:
                break
            mid = 0.5 * (a + b)
            golden = True
            if abs(e) > step and fx < INF and fw < INF and fv < INF:
                # the parabola through (v, fv), (w, fw), (x, fx): its vertex at x + p / q
                rr = (x - w) * (fx - fv)
                q = (x - v) * (fx - fw)
                p = (x - v) * q - (x - w) * rr
                q = 2.0 * (q - rr)
                if q > 0.0:
                    p = -p
                q = abs(q)
                before = e
                e = d
                if abs(p) < abs(0.5 * q * before) and p > q * (a - x) and p < q * (b - x):
                    d = p / q
                    golden = False
                    if x + d - a < 2.0 * step or b - x - d < 2.0 * step:
                        d = step if mid >= x else -step
            if golden:
                e = (a - x) if x >= mid else (b - x)
                d = (1.0 - GOLDEN) * e
            u = min(b, max(a, x + d if abs(d) >= step else x + (step if d > 0.0 else -step)))
            lo, hi = pose_at(u0, v0, pa, pb, xa, xb, u, R, r, F, 2 if upper else 1)
            fu = (-hi if upper else lo) if lo <= hi else INF
            if fu <= fx:
                if u >= x:
                    a = x
                else:
                    b = x
                v = w
                fv = fw
                w = x
                fw = fx
                x = u
                fx = fu
            else:
                if u < x:
                    a = u
                else:
                    b = u
                if fu <= fw or w == x:
                    v = w
                    fv = fw
                    w = u
                    fw = fu
                elif fu <= fv or v == x or v == w:
                    v = u
                    fv = fu
        return -fx if upper else fx

    @jit
    def flute_plane(pa, pb, xa, xb, r, F):
        """Where a ball-end mill's flutes may cut beyond its ball, for every line of a move: the
        flutes lie on the shank side of the plane through the ball centre normal to the axis, for
        every pose; over a move that is the half-space ``(p - c_a).x_a >= -m`` (m covers the
        move and its turn). Returns ``(xu, xv, xw, k)``: the line at (u0, v0) is in the
        half-space where ``u0 xu + v0 xv + w xw + k >= 0``."""
        cu, cv, cw, du, dv, dw = g.axis_point_move(pa, xa, pb, xb, r)  # the ball centre's chord
        dist = math.sqrt(du * du + dv * dv + dw * dw)
        turn = math.sqrt((xb[0] - xa[0]) ** 2 + (xb[1] - xa[1]) ** 2 + (xb[2] - xa[2]) ** 2)
        m = max(0.0, -(du * xa[0] + dv * xa[1] + dw * xa[2])) if turn == 0.0 else dist + (dist + F + r) * turn
        m += 1e-9
        return xa[0], xa[1], xa[2], m - cu * xa[0] - cv * xa[1] - cw * xa[2]

    @jit
    def flute_range(u0, v0, xu, xv, xw, k):
        """``(lo, hi)`` of the line inside the half-space of :func:`flute_plane` (may be infinite
        or empty)."""
        a0 = u0 * xu + v0 * xv + k
        if xw > 1e-12:
            return -a0 / xw, INF
        if xw < -1e-12:
            return -INF, -a0 / xw
        if a0 >= 0.0:
            return -INF, INF
        return INF, -INF

    @jit
    def tool_move(u0, v0, pa, pb, xa, xb, R, r, F, sub):
        """Line against the volume a cutter (radius R, corner radius r, flute length F) sweeps
        from tip pa with axis xa to tip pb with axis xb (arrays (3,) in the line frame).

        Fixed axis: exact (see the module docstring). Turning axis (callers split moves so that
        each piece turns little, see :mod:`meshmill.simulation.cut`): a ball-end mill sweeps the
        ruled surface of its axis segment, taken in ``sub`` strips of two triangles each,
        thickened by R; other cutters take the lowest start and highest end of their poses."""
        rho = R - r
        H = max(0.0, F - 2.0 * r)
        cu, cv, cw, Du, Dv, Dw = g.axis_point_move(pa, xa, pb, xb, r)
        if xa[0] == xb[0] and xa[1] == xb[1] and xa[2] == xb[2]:
            if rho <= 1e-12:
                return pgram_ball(u0, v0, cu, cv, cw, Du, Dv, Dw, H * xa[0], H * xa[1], H * xa[2], r)
            return fixed_sweep(u0, v0, cu, cv, cw, Du, Dv, Dw, xa[0], xa[1], xa[2], H, rho, r)
        if rho > 1e-12:  # other cutters: the extreme ends over the poses
            lo = INF
            hi = -INF
            for side in range(2):
                e = turning_search(u0, v0, pa, pb, xa, xb, R, r, F, side == 1)
                if side == 0:
                    if e >= INF:
                        break
                    lo = e
                else:
                    hi = e
            return lo, hi
        # ball: per strip, the quad c_a, c_b, c_b + H x_b, c_a + H x_a split along its diagonal
        lo = INF
        hi = -INF
        for k in range(sub):
            ha = H * k / sub
            hb = H * (k + 1) / sub
            au = cu + ha * xa[0]
            av = cv + ha * xa[1]
            aw = cw + ha * xa[2]
            bu = cu + Du + ha * xb[0]
            bv = cv + Dv + ha * xb[1]
            bw = cw + Dw + ha * xb[2]
            Gu = cu + Du + hb * xb[0] - au
            Gv = cv + Dv + hb * xb[1] - av
            Gw = cw + Dw + hb * xb[2] - aw
            l1, h1 = pgram_ball(u0, v0, au, av, aw, bu - au, bv - av, bw - aw, Gu, Gv, Gw, r, True)
            l2, h2 = pgram_ball(u0, v0, au, av, aw, Gu, Gv, Gw, (hb - ha) * xa[0], (hb - ha) * xa[1],
                                (hb - ha) * xa[2], r, True)
            lo = min(lo, min(l1, l2))
            hi = max(hi, max(h1, h2))
        return lo, hi

    return namespace(sphere=sphere, capsule=capsule, pgram_ball=pgram_ball, core_dist2=core_dist2,
                     convex_floor=convex_floor, rounded_sweep=rounded_sweep, flat_sweep=flat_sweep,
                     aligned_sweep=aligned_sweep, aligned_poses=aligned_poses,
                     aligned_at=aligned_at, fixed_sweep=fixed_sweep, pose=pose, flute_plane=flute_plane,
                     flute_range=flute_range, pose_at=pose_at, stand=stand,
                     turning_search=turning_search, tool_move=tool_move)
