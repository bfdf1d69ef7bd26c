"""Adaptive clearing of one Z level on a node grid, with a bounded radial engagement.

The level is a grid of nodes ``h`` mm apart. ``rem (nx, ny) bool`` marks the material still to be
cleared, ``feas (nx, ny) bool`` where the tool centre may be (the part's shadow, grown by the tool
and the allowance, and the grid's border excluded). Positions are in grid units (node (i, j) is at
``(i, j)``); the tool radius ``r`` and the step ``s`` too.

The tool walks in steps of ``s``. Before each step the headings from the cleared side round to the
material side are tried (the previous heading turned by +-150 degrees): the area a step to each
would remove (the nodes of ``rem`` in the disk of radius ``r`` at its end, a step ahead of a disk
already cleared: ``ae · s`` in a straight cut of radial width ``ae``) grows as the heading turns
into the material. The step taken is the heading between the last one that removes at most
``target`` nodes and the first that removes more (or leaves the free region), found by bisection:
the removed area of every step stays at most ``target`` and close to it, in the corners as well
as along the walls, which the walk follows where the free region ends. The walk keeps the material
on its right (climb milling with a clockwise spindle; ``side = -1``: on its left, conventional) and
ends where no heading removes anything, or every one removes more than ``target``.

A walk starts from a node of the free region whose disk holds no material and lies at most a few
nodes from it (coming from the side: the region cleared so far, or the air around the stock), or,
where no such node is left, from a helix: a circle of radius ``rh`` around a free node that has
the room, descending at the ramp angle, which clears a disk of radius ``r + rh``.
"""
from __future__ import annotations

import math

import numba
import numpy as np

SCAN = 17  # headings tried before each step
TURN = math.radians(150.0)  # how far the heading may turn each way in one step
BISECT = 6  # halvings of the bracket between the last heading within the target and the first beyond it
WINDOW = 3.0  # tool radii each way about the tool where the next start is looked for first
CLEAR_SLACK = 0.75  # nodes: a node this much farther than the radius from the material holds a clear tool near it
CELL = 0.71  # nodes: how far from a node the stock it stands for reaches (half a cell's diagonal)
START_BAND = 3.0  # nodes: a walk starts at most this far outside the reach of the material
WALL_IN = 0.75  # nodes: the wall walk follows the free region's border this far inside it
WALL_GAP = 4.0  # tool radii: the longest stretch of a wall walk that removes nothing before it lifts
SLIVER = 0.5  # of a step's target: less material than this near a start is left to the walk along the walls


@numba.njit(cache=True)
def _free(feas, qi, qj):
    """Whether a node of the free region lies within one node of ``(qi, qj)`` (the free region's
    heights are those of the tool widened by a node: the tool there keeps clear of the part)."""
    nx, ny = feas.shape
    i0, j0 = int(math.floor(qi)), int(math.floor(qj))
    for i in range(i0, i0 + 2):
        for j in range(j0, j0 + 2):
            if 0 <= i < nx and 0 <= j < ny and feas[i, j] and (i - qi) ** 2 + (j - qj) ** 2 <= 1.0:
                return True
    return False


@numba.njit(cache=True)
def sweep(rem, swept, ai, aj, bi, bj, r, clear=True):
    """Clear the nodes within ``r`` of the segment a-b: ``rem`` False, ``swept`` True; returns how
    many nodes of ``rem`` it cleared (with ``clear`` False: would clear, changing nothing)."""
    nx, ny = rem.shape
    i0 = max(0, int(math.ceil(min(ai, bi) - r)))
    i1 = min(nx - 1, int(math.floor(max(ai, bi) + r)))
    j0 = max(0, int(math.ceil(min(aj, bj) - r)))
    j1 = min(ny - 1, int(math.floor(max(aj, bj) + r)))
    di, dj = bi - ai, bj - aj
    ll = di * di + dj * dj
    r2 = r * r
    n = 0
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            t = 0.0
            if ll > 0.0:
                t = min(1.0, max(0.0, ((i - ai) * di + (j - aj) * dj) / ll))
            ei, ej = i - ai - t * di, j - aj - t * dj
            if ei * ei + ej * ej <= r2:
                if rem[i, j]:
                    n += 1
                    if clear:
                        rem[i, j] = False
                if clear:
                    swept[i, j] = True
    return n


@numba.njit(cache=True)
def _step_removal(rem, feas, ai, aj, bi, bj, r):
    """Nodes of ``rem`` the step a-b would remove; -1 where its end or its middle is not free."""
    if not _free(feas, bi, bj) or not _free(feas, 0.5 * (ai + bi), 0.5 * (aj + bj)):
        return -1
    return sweep(rem, rem, ai, aj, bi, bj, r, False)


@numba.njit(cache=True)
def _near(rem, qi, qj, reach, ni, nj):
    """Gather into ``ni, nj`` the nodes of ``rem`` within ``reach`` of ``(qi, qj)``; returns how many."""
    nx, ny = rem.shape
    k = 0
    i0, i1 = max(0, int(math.ceil(qi - reach))), min(nx - 1, int(math.floor(qi + reach)))
    for i in range(i0, i1 + 1):
        w2 = reach * reach - (i - qi) * (i - qi)
        if w2 < 0.0:
            continue
        w = math.sqrt(w2)
        j0, j1 = max(0, int(math.ceil(qj - w))), min(ny - 1, int(math.floor(qj + w)))
        for j in range(j0, j1 + 1):
            if rem[i, j]:
                ni[k], nj[k] = i, j
                k += 1
    return k


@numba.njit(cache=True)
def _removal(feas, ni, nj, count, qi, qj, theta, s, r):
    """Nodes of the material near the tool (``ni, nj``, ``count`` of them) a step of ``s`` along
    ``theta`` from ``(qi, qj)`` would remove (within ``r`` of the step); -1 where its end or its
    middle leaves the free region."""
    ci, cj = math.cos(theta), math.sin(theta)
    pi, pj = qi + s * ci, qj + s * cj
    if not _free(feas, pi, pj) or not _free(feas, qi + 0.5 * s * ci, qj + 0.5 * s * cj):
        return -1
    di, dj = pi - qi, pj - qj
    ll = di * di + dj * dj
    r2 = r * r
    n = 0
    for k in range(count):
        t = min(1.0, max(0.0, ((ni[k] - qi) * di + (nj[k] - qj) * dj) / ll))
        ei, ej = ni[k] - qi - t * di, nj[k] - qj - t * dj
        if ei * ei + ej * ej <= r2:
            n += 1
    return n


@numba.njit(cache=True)
def walk(rem, feas, swept, qi, qj, theta, r, s, target, side, out, removed):
    """One walk from ``(qi, qj)`` heading ``theta`` (radians): fills ``out (m, 2)`` with its
    positions (the start first) and ``removed (m,)`` with the nodes each step cleared; returns the
    number of positions (1: no step could be taken)."""
    n = 1
    out[0, 0], out[0, 1] = qi, qj
    removed[0] = 0
    es = np.empty(SCAN)
    size = (2 * int(r + s) + 5) ** 2
    ni, nj = np.empty(size, np.int64), np.empty(size, np.int64)
    while n < out.shape[0]:
        near = _near(rem, qi, qj, r + s + 1.0, ni, nj)  # all a step may remove lies this near
        for k in range(SCAN):
            es[k] = _removal(feas, ni, nj, near, qi, qj, theta + side * (TURN - 2.0 * TURN * k / (SCAN - 1)), s, r)
        # the first pair (within the target, beyond it or not free) from the cleared side
        found = False
        pick = 0.0
        for k in range(SCAN - 1):  # the first pair (within the target, beyond it) that removes something
            if 0 <= es[k] <= target and (es[k + 1] > target or es[k + 1] < 0):
                a = TURN - 2.0 * TURN * k / (SCAN - 1)
                b = TURN - 2.0 * TURN * (k + 1) / (SCAN - 1)
                ea = es[k]
                for _ in range(BISECT):
                    m = 0.5 * (a + b)
                    e = _removal(feas, ni, nj, near, qi, qj, theta + side * m, s, r)
                    if 0 <= e <= target:
                        a, ea = m, e
                    else:
                        b = m
                if ea > 0:
                    pick = a
                    found = True
                    break
        if not found:
            best, kb = 0.0, -1
            for k in range(SCAN):
                if 0 <= es[k] <= target and es[k] > best:
                    best, kb = es[k], k
            if kb < 0:
                break  # nothing to remove within the target
            pick = TURN - 2.0 * TURN * kb / (SCAN - 1)
        th = theta + side * pick
        pi, pj = qi + s * math.cos(th), qj + s * math.sin(th)
        got = sweep(rem, swept, qi, qj, pi, pj, r)
        if got == 0:
            break
        out[n, 0], out[n, 1] = pi, pj
        removed[n] = got
        n += 1
        qi, qj, theta = pi, pj, th
    return n


@numba.njit(cache=True)
def free_along(feas, ai, aj, bi, bj):
    """Whether every node nearest to the segment a-b (sampled every half node) is free."""
    d = math.hypot(bi - ai, bj - aj)
    k = max(1, int(math.ceil(2.0 * d)))
    for t in range(k + 1):
        if not _free(feas, ai + (bi - ai) * t / k, aj + (bj - aj) * t / k):
            return False
    return True


@numba.njit(cache=True)
def clear_along(dist, ai, aj, bi, bj, r):
    """Whether the segment a-b keeps more than ``r`` from the material, ``dist (nx, ny)`` being
    each node's distance to it: every node nearest to it (sampled every half node; its ends, known
    clear, left out) lies farther than ``r`` and the way to the node from the segment."""
    nx, ny = dist.shape
    d = math.hypot(bi - ai, bj - aj)
    k = max(1, int(math.ceil(2.0 * d)))
    for t in range(1, k):
        ci = int(math.floor(ai + (bi - ai) * t / k + 0.5))
        cj = int(math.floor(aj + (bj - aj) * t / k + 0.5))
        if ci < 0 or cj < 0 or ci >= nx or cj >= ny or dist[ci, cj] <= r + CLEAR_SLACK:
            return False
    return True


def _distances(rem, pos, pad, half):
    """``(lo, hi, dist, nearest)`` over the nodes ``lo .. hi - 1``: each one's distance to the
    material ``rem`` and its nearest node there (:func:`_distance_to`), exact where it is at most
    ``pad``: over the material's box grown by ``pad``, or (``pos`` given) a window of ``half``
    nodes each way about ``pos`` within it, the nodes whose distance could be wrong (within
    ``pad`` of the window's border, inside) set to 0 (never a start, never clear)."""
    nx, ny = rem.shape
    ii, jj = np.nonzero(rem)
    lo = np.maximum([ii.min() - pad, jj.min() - pad], 0)
    hi = np.minimum([ii.max() + pad + 1, jj.max() + pad + 1], [nx, ny])
    if pos is None:
        return (lo, hi, *_distance_to(rem, lo, hi))
    c = np.floor(np.asarray(pos) + 0.5).astype(int)
    wlo = np.maximum(lo, c - int(half) - pad)
    whi = np.minimum(hi, c + int(half) + pad + 1)
    if np.any(whi <= wlo):
        return (lo, hi, *_distance_to(rem, lo, hi))
    dist, nearest = _distance_to(rem, wlo, whi)
    for a in range(2):  # a border of the window that is not the box's: its distances may be too long
        if wlo[a] > lo[a]:
            dist[(slice(None),) * a + (slice(0, pad),)] = 0.0
        if whi[a] < hi[a]:
            dist[(slice(None),) * a + (slice(dist.shape[a] - pad, None),)] = 0.0
    return wlo, whi, dist, nearest


def _distance_to(rem, lo, hi):
    """``(dist, nearest)``: over the nodes ``lo .. hi - 1`` of the grid, each one's distance to the
    nearest node of ``rem`` and that node's indices ``(2, ...)`` (full-grid indices)."""
    from scipy.ndimage import distance_transform_edt

    sub = rem[lo[0]:hi[0], lo[1]:hi[1]]
    dist, idx = distance_transform_edt(~sub, return_indices=True)
    idx[0] += lo[0]
    idx[1] += lo[1]
    return dist, idx


class LevelClearing:
    """The walks that clear one level: ``events``, each ``(entry, link, points (k, 2))`` in grid
    units: ``entry`` ``("side", None)`` or ``("helix", (centre (2,), radius))``, ``link`` None (the
    level's first walk) or how the tool comes from the previous walk's end (:meth:`_link`:
    ``("hop" | "level" | "lift", points)``); ``removed`` the nodes each walk's steps cleared; ``swept (nx, ny)`` the
    nodes the tool passed over; ``left`` the nodes of the material still there (no entry fits)."""

    def __init__(self, rem, feas, r, s, target, side, helix, pos=None, berth=0.0):
        """Clear ``rem`` (changed in place) with a tool of radius ``r`` in steps of ``s``, at most
        ``target`` nodes a step, material on the right (``side`` 1) or left (-1); ``helix``:
        ``(largest, smallest)`` helix radius; ``pos``: where the tool comes from (grid units);
        ``berth``: nodes a link or an entry keeps from the material where it can (beyond the
        tool's radius: the clearance, so that it may be a rapid)."""
        nx, ny = rem.shape
        self.events, self.removed = [], []
        self.swept = np.zeros_like(rem)
        self.feas_, self.r, self.room = feas, r, None
        self.helix_failed = 0
        tried = np.zeros_like(rem)
        out = np.empty((min(int(rem.sum()) + 2, 2_000_000), 2))
        near_i = np.empty((2 * int(r + START_BAND + s) + 5) ** 2, np.int64)
        near_j = np.empty_like(near_i)
        removed = np.empty(len(out), np.int64)
        pad = int(math.ceil(r + berth + START_BAND)) + 2
        dist = None  # the distances to the material, while no walk has removed any
        window = True
        while True:
            if dist is None:
                if not rem.any():
                    break
                # first round the tool only (distances exact within the window), then everywhere
                lo, hi, dist, nearest = _distances(rem, pos if window else None, pad, WINDOW * r)
                free = feas[lo[0]:hi[0], lo[1]:hi[1]]
                starts = []  # room to come down clear of the material first, then any
                for band in ((r + berth, r + berth + START_BAND), (r + 0.5, r + START_BAND)):
                    ci, cj = np.nonzero(free & (dist > band[0]) & (dist <= band[1]))
                    if pos is not None:
                        order = np.argsort((ci + lo[0] - pos[0]) ** 2 + (cj + lo[1] - pos[1]) ** 2, kind="stable")
                        ci, cj = ci[order], cj[order]
                    starts += list(zip(ci.tolist(), cj.tolist()))
                at = 0
            while at < len(starts) and tried[starts[at][0] + lo[0], starts[at][1] + lo[1]]:
                at += 1
            if at == len(starts) and window and pos is not None:
                window, dist = False, None  # nothing near: look everywhere
                continue
            window = True
            if at < len(starts):
                ci, cj = starts[at]
                start = np.array([ci + lo[0], cj + lo[1]], float)
                if _near(rem, start[0], start[1], r + START_BAND + s, near_i, near_j) < SLIVER * target:
                    tried[int(start[0]), int(start[1])] = True  # a sliver: left to the walk along the walls
                    continue
                g = nearest[:, ci, cj] - start
                theta = math.atan2(g[1], g[0]) + side * 0.5 * math.pi
                entry = ("side", None)
                link = None if pos is None else self._link(feas, dist, nearest, lo, pos, start, r, berth)
            else:
                if self.room is None:
                    from scipy.ndimage import distance_transform_edt

                    self.room = distance_transform_edt(feas)
                room = self.room
                fits = rem & (room >= helix[1] + 1.0)
                fi, fj = np.nonzero(fits)
                if not len(fi):
                    self.helix_failed = int(rem.sum())
                    break
                big = room[fi, fj] >= helix[0] + 1.0
                if big.any():
                    fi, fj = fi[big], fj[big]
                    k = 0 if pos is None else int(np.argmin((fi - pos[0]) ** 2 + (fj - pos[1]) ** 2))
                else:
                    k = int(np.argmax(room[fi, fj]))
                centre = np.array([fi[k], fj[k]], float)
                rh = float(min(helix[0], room[fi[k], fj[k]] - 1.0))
                link = None if pos is None else ("lift", self._away(feas, dist, lo, pos, berth))
                sweep(rem, self.swept, centre[0], centre[1], centre[0], centre[1], r + rh)
                dist = None
                start = centre + [rh, 0.0]
                theta = side * 0.5 * math.pi
                entry = ("helix", (centre, rh))
            n = walk(rem, feas, self.swept, start[0], start[1], theta, r, s, target, side, out, removed)
            if n == 1 and entry[0] == "side":
                tried[int(start[0]), int(start[1])] = True
                continue
            dist = None
            self.events.append((entry, link, out[:n].copy()))
            self.removed.append(removed[1:n].copy())
            pos = out[n - 1].copy()
        if rem.any():
            pos = self._walls(rem, feas, r, s, target, side, pos, berth)
        self.left = int(rem.sum())
        # where the tool leaves the level: away from the walls, so that it may lift at once
        self.exit = None if pos is None else self._away(feas, None, None, pos, berth)

    def _away(self, feas, dist, lo, a, want) -> np.ndarray:
        """``(2, 2)``: ``a`` and the nearest point (16 headings, up to ``want`` + 2 nodes away,
        straight through the free region) that lies ``want`` nodes beyond the tool's radius from
        the material (``dist`` over the nodes from ``lo``; None: not looked at) and ``want`` from
        what is not free, where the tool goes before it lifts (``a`` itself where none is)."""
        from scipy.ndimage import distance_transform_edt

        if self.room is None:
            self.room = distance_transform_edt(self.feas_)
        a = np.asarray(a, float)

        def ok(p):
            i, j = np.floor(p + 0.5).astype(int)
            if not (0 <= i < feas.shape[0] and 0 <= j < feas.shape[1]) or self.room[i, j] < want:
                return False
            if dist is None:
                return True
            i, j = i - lo[0], j - lo[1]
            return not (0 <= i < dist.shape[0] and 0 <= j < dist.shape[1]) or dist[i, j] >= self.r + want

        if ok(a):
            return np.array([a, a])
        for t in np.arange(1.0, want + 2.5, 1.0):
            for k in range(16):
                p = a + t * np.array([math.cos(k * math.pi / 8), math.sin(k * math.pi / 8)])
                if ok(p) and free_along(feas, a[0], a[1], p[0], p[1]):
                    return np.array([a, p])
        return np.array([a, a])

    def _link(self, feas, dist, nearest, lo, a, b, r, berth):
        """How the tool goes from ``a`` (a walk's end) to ``b`` (the next one's start), grid
        units: ``("hop", corners)`` a way the clearance over the level (away from the material,
        then round it with ``berth`` to spare), ``("level", corners)`` a way at the level round it,
        or ``("lift", (a, away))`` up over what lies between."""
        away = self._away(feas, dist, lo, a, berth)
        if berth > 0:
            hop = way_down(feas, dist, lo, away[1], b, r + berth - CLEAR_SLACK)
            if hop is not None:
                return "hop", np.vstack([away[:1], hop])
        level = way_down(feas, dist, lo, a, b, r)
        if level is not None:
            return "level", level
        return "lift", away
    def _walls(self, rem, feas, r, s, target, side, pos, berth):
        """Walk the border of the free region (``WALL_IN`` nodes inside it) where material is left
        along it, each step removing at most ``target`` per ``s``: the slivers the walks leave
        against the walls. Returns the tool's last position."""
        from scipy.ndimage import distance_transform_edt
        from skimage.measure import find_contours

        room = distance_transform_edt(feas)
        near = distance_transform_edt(~rem)  # each node's distance to the material left
        swept = self.swept
        for c in find_contours(room, WALL_IN):
            if len(c) < 2:
                continue
            ci = np.clip(np.floor(c + 0.5).astype(int), 0, np.array(rem.shape) - 1)
            if near[ci[:, 0], ci[:, 1]].min() > r + 1.0:
                continue
            t = c[1] - c[0]
            mid = 0.5 * (c[0] + c[1]) + 0.5 * np.array([t[1], -t[0]]) / max(np.hypot(*t), 1e-12)
            mi = np.clip(np.floor(mid + 0.5).astype(int), 0, np.array(rem.shape) - 1)
            wall_right = room[mi[0], mi[1]] < WALL_IN
            if wall_right != (side == 1):
                c = c[::-1]
            seg = np.hypot(*np.diff(c, axis=0).T)
            arc = np.r_[0.0, np.cumsum(seg)]
            fine = min(s, 2.0)
            n = max(2, int(math.ceil(arc[-1] / fine)) + 1)
            at = np.linspace(0.0, arc[-1], n)
            pts = np.column_stack([np.interp(at, arc, c[:, 0]), np.interp(at, arc, c[:, 1])])
            run, got, gap = [pts[0]], [0], 0.0
            for a, b in zip(pts[:-1], pts[1:]):
                step = float(np.hypot(*(b - a)))
                e = _step_removal(rem, feas, a[0], a[1], b[0], b[1], r)
                if 0 <= e <= target * fine / s and gap <= WALL_GAP * r:
                    got.append(sweep(rem, swept, a[0], a[1], b[0], b[1], r))
                    run.append(b)
                    gap = 0.0 if got[-1] else gap + step
                    continue
                pos = self._wall_run(run, got, pos, feas, berth)
                run, got, gap = [b], [0], 0.0
            pos = self._wall_run(run, got, pos, feas, berth)
        return pos

    def _wall_run(self, run, got, pos, feas, berth):
        """Keep a run of a wall walk from its first to its last step that removed anything (the
        tool comes to it from ``pos`` away from the wall first)."""
        got = np.asarray(got)
        cut = np.nonzero(got > 0)[0]
        if not len(cut):
            return pos
        a, b = max(0, cut[0] - 1), cut[-1] + 1
        pts = np.array(run[a:b])
        link = None if pos is None else ("lift", self._away(feas, None, None, pos, berth))
        self.events.append((("side", None), link, pts))
        self.removed.append(got[a + 1:b])
        return pts[-1]


def _clear_in(dist, lo, a, b, r) -> bool:
    """Whether the segment a-b (full-grid units) keeps more than ``r`` from the material, ``dist``
    being the distances over the nodes from ``lo`` (a segment leaving them is not known clear)."""
    return bool(clear_along(dist, a[0] - lo[0], a[1] - lo[1], b[0] - lo[0], b[1] - lo[1], r))


@numba.njit(cache=True)
def _way(ok, ai, aj, bi, bj, limit):
    """The shortest 8-connected way of nodes where ``ok`` from node a to node b, as ``(m, 2)``
    nodes (a first), no longer than ``limit`` steps; empty where there is none."""
    nx, ny = ok.shape
    prev = np.full(nx * ny, -1, np.int64)
    queue = np.empty(nx * ny, np.int64)
    start, goal = ai * ny + aj, bi * ny + bj
    prev[start] = start
    head, tail = 0, 1
    queue[0] = start
    depth_end, depth = 1, 0
    found = False
    while head < tail and not found:
        if head == depth_end:
            depth += 1
            depth_end = tail
            if depth > limit:
                break
        c = queue[head]
        head += 1
        ci, cj = c // ny, c % ny
        for di in range(-1, 2):
            for dj in range(-1, 2):
                i, j = ci + di, cj + dj
                if (di == 0 and dj == 0) or i < 0 or j < 0 or i >= nx or j >= ny or not ok[i, j]:
                    continue
                k = i * ny + j
                if prev[k] >= 0:
                    continue
                prev[k] = c
                queue[tail] = k
                tail += 1
                if k == goal:
                    found = True
    if not found:
        return np.empty((0, 2), np.int64)
    n, k = 1, goal
    while k != start:
        k = prev[k]
        n += 1
    out = np.empty((n, 2), np.int64)
    k = goal
    for m in range(n - 1, -1, -1):
        out[m, 0], out[m, 1] = k // ny, k % ny
        k = prev[k]
    return out


def way_down(feas, dist, lo, a, b, r) -> np.ndarray | None:
    """A way at the level from ``a`` to ``b`` (grid units) through the free region that keeps more
    than ``r`` from the material (``dist`` its distance over the nodes from ``lo``): ``(m, 2)``
    corners (a and b included), straight where it can be, or None where there is none at most
    three times the straight distance (plus the tool's diameter) long."""
    if free_along(feas, a[0], a[1], b[0], b[1]) and _clear_in(dist, lo, a, b, r):
        return np.array([a, b], float)
    sub = feas[lo[0]:lo[0] + dist.shape[0], lo[1]:lo[1] + dist.shape[1]] & (dist > r + CLEAR_SLACK)
    ai, aj = np.floor(np.asarray(a) - lo + 0.5).astype(int)
    bi, bj = np.floor(np.asarray(b) - lo + 0.5).astype(int)
    if not (0 <= ai < sub.shape[0] and 0 <= aj < sub.shape[1] and 0 <= bi < sub.shape[0] and 0 <= bj < sub.shape[1]):
        return None
    sub[ai, aj] = sub[bi, bj] = True  # the ends are clear: the walk's last disk, the next one's first
    limit = int(3 * math.hypot(bi - ai, bj - aj) + 4 * r) + 2
    nodes = _way(sub, ai, aj, bi, bj, limit)
    if not len(nodes):
        return None
    pts = np.vstack([a, nodes[1:-1] + lo, b]).astype(float)
    corners, k = [pts[0]], 0
    while k < len(pts) - 1:  # the farthest point seen straight from the last corner
        m = len(pts) - 1
        while m > k + 1 and not (free_along(feas, *pts[k], *pts[m]) and _clear_in(dist, lo, pts[k], pts[m], r)):
            m -= 1
        corners.append(pts[m])
        k = m
    return np.array(corners)


@numba.njit(cache=True)
def _tool_height(rho, radius, corner):
    """Height of a vertical cutter's end over its tip at ``rho`` mm from its axis (inf outside)."""
    if rho > radius:
        return np.inf
    flat = radius - corner
    if rho <= flat:
        return 0.0
    d = rho - flat
    return corner - math.sqrt(max(0.0, corner * corner - d * d))


@numba.njit(cache=True)
def heightmap_pass(top, part, x0, y0, h, tips, radius, corner, clearance, cuts):
    """Run a 3-axis path (vertical tool) over the stock heights ``top (nx, ny)`` (nodes ``h`` mm
    apart from ``(x0, y0)``; changed in place: lowered where a move with ``cuts[i]`` set passes).
    Returns ``(k,)``: for each move (tip i-1 to tip i) the lowest tip height at which it keeps
    ``clearance`` from the stock as the moves before it left it (the highest node within the
    tool's radius plus the clearance and a node of any point of it, plus the clearance) and from
    the part (``part (nx, ny)``: the heights above which the whole tool keeps that from it within
    a node of each node, at the nodes nearest its points every half node). A move cuts as its tool
    at its lower end if vertical, else at its higher end, and a node only where the tool covers
    the whole cell about it (never more than it does: a node stands for the stock near it)."""
    nx, ny = top.shape
    k = len(tips)
    low = np.full(k, -np.inf)
    reach = radius + clearance + h
    for i in range(1, k):
        ax, ay, az = tips[i - 1, 0], tips[i - 1, 1], tips[i - 1, 2]
        bx, by, bz = tips[i, 0], tips[i, 1], tips[i, 2]
        i0 = max(0, int(math.floor((min(ax, bx) - reach - x0) / h)))
        i1 = min(nx - 1, int(math.ceil((max(ax, bx) + reach - x0) / h)))
        j0 = max(0, int(math.floor((min(ay, by) - reach - y0) / h)))
        j1 = min(ny - 1, int(math.ceil((max(ay, by) + reach - y0) / h)))
        dx, dy = bx - ax, by - ay
        ll = dx * dx + dy * dy
        zc = min(az, bz) if ll == 0.0 else max(az, bz)  # a sloped move is taken to cut no lower than its top
        high = -np.inf
        for ii in range(i0, i1 + 1):
            for jj in range(j0, j1 + 1):
                px, py = x0 + ii * h, y0 + jj * h
                t = 0.0
                if ll > 0.0:
                    t = min(1.0, max(0.0, ((px - ax) * dx + (py - ay) * dy) / ll))
                ex, ey = px - ax - t * dx, py - ay - t * dy
                rho = math.sqrt(ex * ex + ey * ey)
                if rho <= reach and top[ii, jj] > high:
                    high = top[ii, jj]
                if cuts[i] and rho + CELL * h <= radius:  # the node's whole cell under the tool
                    z = zc + _tool_height(rho + CELL * h, radius, corner)
                    if z < top[ii, jj]:
                        top[ii, jj] = z
        d = math.hypot(bx - ax, by - ay)
        n = max(1, int(math.ceil(2.0 * d / h)))
        for t in range(n + 1):
            ci = int(math.floor((ax + (bx - ax) * t / n - x0) / h + 0.5))
            cj = int(math.floor((ay + (by - ay) * t / n - y0) / h + 0.5))
            if ci < 0 or cj < 0 or ci >= nx or cj >= ny:
                high = np.inf
            elif part[ci, cj] - clearance > high:
                high = part[ci, cj] - clearance
        low[i] = high + clearance
    return low
