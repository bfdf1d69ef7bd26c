"""Removing swept volumes from dexel lines (device functions, written once for every backend).

A direction's stock is ``iv (cap, 2)``: line ``l`` holds ``count[l]`` sorted intervals (start,
end along the line, mm) in ``iv[off[l]:]``, with room up to ``off[l + 1]``. Moves are given in the
line frame (see :mod:`meshmill.kernels.sweep`): tips ``pa, pb (k, 3)``, unit axes ``xa, xb (k, 3)``,
``radius, corner, flutes (k,)``, ``strips (k,)``, and from :func:`move_constants` ``chord (k, 6)``
(a ball-end's centre chord) and ``plane (k, 4)`` (where its flutes may reach past the ball).
"""
from __future__ import annotations

import math

from . import sweep
from .geom import namespace

MIN_PIECE = 1e-9  # mm: a dexel piece shorter than this is removed
RAPID = 1  # bits of a move's kind: a rapid (it must remove nothing)
BODY = 2  # a shank or holder (it removes nothing; touching material is a collision)
TILE = 16  # lines a side of the tiles that cutting runs in parallel over


def build(jit, inline=None):
    """Compile the device functions with ``jit`` and return them in a namespace; ``inline``, if
    given, compiles :func:`cut_line` and :func:`touch_line` (called once per line and move) to be
    inlined where they are called (on the CPU: a third of the cutting time)."""
    swp = sweep.build(jit)

    @jit
    def subtract(iv, off, count, line, lo, hi):
        """Remove ``[lo, hi]`` from the sorted intervals of ``line``. Returns the length removed,
        or -1 when a split needs more room than the line has (nothing is changed then)."""
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

    @jit
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

    @jit
    def reaches(iv, off, count, line, wlo, whi):
        """Whether the intervals of ``line`` may reach into ``(wlo, whi)``: it has some, the first
        starts below whi and the last ends above wlo."""
        n = count[line]
        return n > 0 and not (iv[off[line], 0] >= whi or iv[off[line] + n - 1, 1] <= wlo)

    @jit
    def group_clear(g, line, u0, v0, iv, off, count, gbound, gbox):
        """Whether line ``line`` at (u0, v0) holds no material where the moves of group ``g`` may
        cut: within ``gbound[g]`` (the parallelogram from c ``[0:3]`` spanned by ``[3:6]`` and
        ``[6:9]``, grown by the radius ``[9]``; it holds every move's sweep) and the group's box
        ``gbox[g]`` (as a move's ``box``)."""
        wlo = gbox[g, 4]
        whi = gbox[g, 5]
        if not reaches(iv, off, count, line, wlo, whi):
            return True
        lo, hi = swp.pgram_ball(u0, v0, gbound[g, 0], gbound[g, 1], gbound[g, 2], gbound[g, 3], gbound[g, 4],
                                gbound[g, 5], gbound[g, 6], gbound[g, 7], gbound[g, 8], gbound[g, 9])
        return not material_outside(iv, off[line], count[line], max(lo, wlo), min(hi, whi), 1.0, 0.0)

    @jit
    def line_range(lo, hi, l0, step, n):
        """First and last of ``n`` lines at ``l0 + (i + 1/2) step`` within ``[lo, hi]``."""
        i0 = max(0, int(math.ceil((lo - l0) / step - 0.5)))
        i1 = min(n - 1, int(math.floor((hi - l0) / step - 0.5)))
        return i0, i1

    @jit
    def move_lines(box, m, lu, lv, step, nu, nv):
        """``(i0, i1, j0, j1)``: the lines (first and second lattice index, from ``lu, lv``) that the
        box ``box[m]`` (ulo, uhi, vlo, vhi, ...) of move m covers; none when i0 > i1 or j0 > j1."""
        i0, i1 = line_range(box[m, 0], box[m, 1], lu, step, nu)
        j0, j1 = line_range(box[m, 2], box[m, 3], lv, step, nv)
        return i0, i1, j0, j1

    @jit
    def move_constants(m, pa, pb, xa, xb, corner, flutes, chord, plane):
        """``chord[m]``: the ball centre at both ends; ``plane[m]``: the flute half-space of
        :func:`meshmill.kernels.sweep.flute_plane`."""
        cm = corner[m]
        for k in range(3):
            chord[m, k] = pa[m, k] + cm * xa[m, k]
            chord[m, 3 + k] = pb[m, k] + cm * xb[m, k]
        plane[m, 0], plane[m, 1], plane[m, 2], plane[m, 3] = swp.flute_plane(pa[m], pb[m], xa[m], xb[m], cm,
                                                                             flutes[m])

    @jit
    def material_span(iv, base, n, lo, hi):
        """``(first, last)``: where the material of the line's intervals ``iv[base:base+n]``
        within ``[lo, hi]`` starts and ends (first > last: none)."""
        first = hi
        last = lo
        for k in range(base, base + n):
            s = max(iv[k, 0], lo)
            e = min(iv[k, 1], hi)
            if s < e:
                first = min(first, s)
                last = max(last, e)
        return first, last

    @jit
    def load_extents(m, u0, v0, first, last, probe):
        """``(axial_lo, axial_hi, lateral_lo, lateral_hi)``: the extent along move m's axis and
        across its feed of the material removed from the line at (u0, v0) between ``first`` and
        ``last`` (along the line); ``probe[m]``: the axis and the unit vector across the feed (in
        the line frame)."""
        base_a = probe[m, 0] * u0 + probe[m, 1] * v0
        base_l = probe[m, 3] * u0 + probe[m, 4] * v0
        a0 = base_a + probe[m, 2] * first
        a1 = base_a + probe[m, 2] * last
        l0 = base_l + probe[m, 5] * first
        l1 = base_l + probe[m, 5] * last
        return min(a0, a1), max(a0, a1), min(l0, l1), max(l0, l1)

    @(inline or jit)
    def cut_line(m, line, u0, v0, wlo, whi, iv, off, count, pa, pb, xa, xb, radius, corner, flutes, strips,
                 chord, plane, measure):
        """Cut move m from line ``line`` at (u0, v0). Returns ``(removed, first, last)``: the length
        removed, -1 when the line ran out of room (see :func:`subtract`), and, when ``measure``,
        where the material removed starts and ends along the line (first > last: none)."""
        if not reaches(iv, off, count, line, wlo, whi):
            return 0.0, 1.0, 0.0
        n = count[line]
        base = off[line]
        cm = corner[m]
        A = (pa[m, 0], pa[m, 1], pa[m, 2])
        B = (pb[m, 0], pb[m, 1], pb[m, 2])
        XA = (xa[m, 0], xa[m, 1], xa[m, 2])
        XB = (xb[m, 0], xb[m, 1], xb[m, 2])
        turning = XA[0] != XB[0] or XA[1] != XB[1] or XA[2] != XB[2]
        if cm >= radius[m]:
            # the ball alone, unless material lies where only the flutes reach
            lo, hi = swp.capsule(u0, v0, chord[m, 0], chord[m, 1], chord[m, 2], chord[m, 3], chord[m, 4], chord[m, 5],
                                 cm)
            flo, fhi = swp.flute_range(u0, v0, plane[m, 0], plane[m, 1], plane[m, 2], plane[m, 3])
            search = material_outside(iv, base, n, max(flo, wlo), min(fhi, whi), lo, hi)
        else:
            # nothing to cut unless material lies in the sweep of the ball of radius R about the
            # axis segment (it holds the whole tool's), swept as the parallelogram of its first
            # axis along the move; a turning axis moves a point h up it off that parallelogram
            # by at most h |xb - xa|, and the normalised interpolation by (cm + h)(1 - cos(theta/2))
            H = max(0.0, flutes[m] - 2.0 * cm)
            dx = XB[0] - XA[0]
            dy = XB[1] - XA[1]
            dz = XB[2] - XA[2]
            turn = math.sqrt(dx * dx + dy * dy + dz * dz)
            grow = 0.0
            if turning:
                c = min(1.0, max(-1.0, XA[0] * XB[0] + XA[1] * XB[1] + XA[2] * XB[2]))
                grow = H * turn + (cm + H) * (1.0 - math.sqrt(0.5 * (1.0 + c)))
                grow = grow * (1.0 + 1e-9) + 1e-9
            lo, hi = swp.pgram_ball(u0, v0, chord[m, 0], chord[m, 1], chord[m, 2], chord[m, 3] - chord[m, 0],
                                    chord[m, 4] - chord[m, 1], chord[m, 5] - chord[m, 2], H * XA[0],
                                    H * XA[1], H * XA[2], radius[m] + grow)
            # and above the plane of the first tip normal to the first axis, lowered by what the
            # move takes the tip below it and the turn tilts the tool's end (a point at radius
            # R <= R |xb - xa|): every pose stands on its own tip's plane
            drop = max(0.0, -((B[0] - A[0]) * XA[0] + (B[1] - A[1]) * XA[1] + (B[2] - A[2]) * XA[2])) \
                + radius[m] * turn
            drop = drop * (1.0 + 1e-9) + 1e-9
            flo, fhi = swp.flute_range(u0, v0, XA[0], XA[1], XA[2], drop - (A[0] * XA[0] + A[1] * XA[1] + A[2] * XA[2]))
            lo = max(lo, flo)
            hi = min(hi, fhi)
            if lo >= hi or not material_outside(iv, base, n, max(lo, wlo), min(hi, whi), 1.0, 0.0):
                return 0.0, 1.0, 0.0
            search = True
        exact = search
        need_lo = True
        need_hi = True
        if search and cm < radius[m]:
            # a flat or bull-nose: its poses at the piece's ends bound the interval from inside;
            # an end is searched only where material lies between it and the bound (elsewhere
            # both remove the same): over the poses when the axis turns, else the exact sweep
            ilo = sweep.INF
            ihi = -sweep.INF
            for e in range(2):
                l, h = swp.pose_at(u0, v0, A, B, XA, XB, float(e), radius[m], cm, flutes[m], 3)
                if l <= h:
                    ilo = min(ilo, l)
                    ihi = max(ihi, h)
            need_lo = ilo > ihi or material_outside(iv, base, n, max(lo, wlo), min(ilo, whi), 1.0, 0.0)
            need_hi = ilo > ihi or material_outside(iv, base, n, max(ihi, wlo), min(hi, whi), 1.0, 0.0)
            lo = ilo
            hi = ihi
            exact = not turning and (need_lo or need_hi)
            if turning:
                for side in range(2):
                    if need_lo if side == 0 else need_hi:
                        e = swp.turning_search(u0, v0, A, B, XA, XB, radius[m], cm, flutes[m], side == 1)
                        if side == 0:
                            lo = e
                        else:
                            hi = e
                    if lo >= sweep.INF:
                        return 0.0, 1.0, 0.0
        if exact:
            elo, ehi = swp.tool_move(u0, v0, A, B, XA, XB, radius[m], cm, flutes[m], strips[m])
            if cm >= radius[m]:
                lo = elo
                hi = ehi
            else:  # the sweep holds its end poses
                if need_lo:
                    lo = min(lo, elo)
                if need_hi:
                    hi = max(hi, ehi)
        if lo >= hi:
            return 0.0, 1.0, 0.0
        first, last = 1.0, 0.0
        if measure:
            first, last = material_span(iv, base, n, lo, hi)
        return subtract(iv, off, count, line, lo, hi), first, last

    @(inline or jit)
    def touch_line(m, line, u0, v0, wlo, whi, iv, off, count, pa, pb, xa, xb, radius, corner, flutes, strips):
        """The longest piece of material (mm) of line ``line`` at (u0, v0) inside the volume move m
        sweeps; nothing is removed (a shank or holder: it collides, it does not cut)."""
        if not reaches(iv, off, count, line, wlo, whi):
            return 0.0
        n = count[line]
        base = off[line]
        if not material_outside(iv, base, n, wlo, whi, 1.0, 0.0):
            return 0.0
        R = radius[m]
        F = flutes[m]
        turn = math.sqrt((xa[m, 0] - xb[m, 0]) ** 2 + (xa[m, 1] - xb[m, 1]) ** 2 + (xa[m, 2] - xb[m, 2]) ** 2)
        XA = (xa[m, 0], xa[m, 1], xa[m, 2])
        XB = (xb[m, 0], xb[m, 1], xb[m, 2])
        # first one capsule about the cylinder's middle pose: a point s up the axis and rho off it
        # at any pose lies within half the tip's travel, s |x - xm| and rho of the capsule's axis
        # point s up (|x - xm| <= |xa - xm| along the arc, a short one)
        mu = xa[m, 0] + xb[m, 0]
        mv = xa[m, 1] + xb[m, 1]
        mw = xa[m, 2] + xb[m, 2]
        mn = math.sqrt(mu * mu + mv * mv + mw * mw)
        mu /= mn
        mv /= mn
        mw /= mn
        cu = 0.5 * (pa[m, 0] + pb[m, 0])
        cv = 0.5 * (pa[m, 1] + pb[m, 1])
        cw = 0.5 * (pa[m, 2] + pb[m, 2])
        reach = R + 0.5 * math.sqrt((pb[m, 0] - pa[m, 0]) ** 2 + (pb[m, 1] - pa[m, 1]) ** 2 + (pb[m, 2] - pa[m, 2]) ** 2) \
            + F * math.sqrt((XA[0] - mu) ** 2 + (XA[1] - mv) ** 2 + (XA[2] - mw) ** 2)
        lo, hi = swp.capsule(u0, v0, cu, cv, cw, cu + F * mu, cv + F * mv, cw + F * mw, reach * (1.0 + 1e-9) + 1e-9)
        if lo >= hi or not material_outside(iv, base, n, max(lo, wlo), min(hi, whi), 1.0, 0.0):
            return 0.0
        for stage in range(3):
            if stage == 0:
                # first the capsule about the cylinder's axis (a ball-end of its radius standing R
                # lower, swept in closed form): most lines near a shank or holder hold no material
                # in it (grown by a quarter of its ruled surface's twist, which its strips may miss)
                g = R + 0.25 * (F + 2.0 * R) * turn / strips[m] + 1e-9
                lower = g
                X0 = XA
                X1 = XB
                Rs = g
                rs = g
                Fs = F + 2.0 * g
                sub = strips[m]
            elif stage == 1:
                if turn == 0.0:
                    continue
                # a turning cylinder's sweep is searched over its poses; it lies within the
                # cylinder held at the middle axis along the move (exact in closed form), grown by
                # how far the turn moves any of its points from there: asin(turn / 2) (F + R), the
                # angle to the middle axis (half the turn's at most: the normalised interpolation
                # keeps to the arc) times the farthest point's distance from the tip
                d = math.asin(min(1.0, 0.5 * turn)) * (F + R) * (1.0 + 1e-9) + 1e-9
                lower = d
                X0 = (mu, mv, mw)
                X1 = X0
                Rs = R + d
                rs = corner[m]
                Fs = F + 2.0 * d
                sub = 1
            else:
                lower = 0.0
                X0 = XA
                X1 = XB
                Rs = R
                rs = corner[m]
                Fs = F
                sub = strips[m]
            qa = (pa[m, 0] - lower * X0[0], pa[m, 1] - lower * X0[1], pa[m, 2] - lower * X0[2])
            qb = (pb[m, 0] - lower * X1[0], pb[m, 1] - lower * X1[1], pb[m, 2] - lower * X1[2])
            lo, hi = swp.tool_move(u0, v0, qa, qb, X0, X1, Rs, rs, Fs, sub)
            if stage < 2 and (lo >= hi or not material_outside(iv, base, n, lo, hi, 1.0, 0.0)):
                return 0.0
        best = 0.0
        for k in range(base, base + n):
            s = max(iv[k, 0], lo)
            e = min(iv[k, 1], hi)
            if e - s > best:
                best = e - s
        return best

    return namespace(subtract=subtract, material_outside=material_outside, move_lines=move_lines,
                     move_constants=move_constants, group_clear=group_clear, cut_line=cut_line, touch_line=touch_line,
                     load_extents=load_extents)
