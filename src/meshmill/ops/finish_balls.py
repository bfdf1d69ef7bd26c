"""The largest ball of a finish at each CC point, along each run of a contour, on a whole contour.

Balls are ranks into the finish's radii, largest first (-1: none fits); a ball of radius R at a
CC point with centre direction ``d`` has its centre at CC + R·d (``d`` the outward normal times
the crease factor ``reach`` of :class:`~meshmill.geometry.slicing.Contours`). A ball fits where
its sphere does not enter the part by more than the tolerance (exact, through the part's
kernels ``kern``). Lengths in mm.
"""
from __future__ import annotations

import numpy as np

from ..geometry.slicing import MIN_HALF_COS, contour_runs
from ..kernels.backend import solid_kernels

def largest_balls(kern, points, reach, centre_dir, radii, tol):
    """``(k,)`` the largest ball (rank into ``radii``) that fits at each CC point ``points (k, 3)``
    (centre along ``centre_dir (k, 3)`` times its radius, ``reach (k,)`` the crease factor of
    the contours) and touches the part there, -1 where none does; each point on its own. In a
    concave crease the ball sits on the bisector
    touching both facets R·tan(θ/2) from the crease: where the facets end sooner (a crease sharp
    for its facets' size), or the centre's reach was capped (``MIN_HALF_COS``), that ball floats
    off the part and cuts nothing; a smaller one, nearer the crease, may touch."""
    best = kern.largest_ball(points, centre_dir, radii, tol)
    best[reach >= 1.0 / MIN_HALF_COS - 1e-9] = -1
    crease = np.nonzero((best >= 0) & (reach > 1.0 + 1e-9))[0]
    for _ in range(len(radii)):
        if not len(crease):
            break
        r = radii[best[crease]]
        floats = kern.mesh_distances(points[crease] + r[:, None] * centre_dir[crease]) > r + tol
        crease = crease[floats]
        for t in np.unique(best[crease]) + 1:
            sel = crease[best[crease] + 1 == t]
            if t >= len(radii):
                best[sel] = -1
                continue
            res = kern.largest_ball(points[sel], centre_dir[sel], radii[t:], tol)
            best[sel] = np.where(res >= 0, t + res, -1)
        crease = crease[best[crease] >= 0]
    return best


def stretch_ranks(best, s, min_run):
    """Ball ranks ``(n,)`` along a run (``best`` each point's largest ball, ``s`` arc length, mm)
    with no stretch of one ball shorter than ``min_run`` (unless the run is): the shortest such
    stretch takes the smaller ball of a neighbour when one has a smaller ball (which fits wherever
    a larger one does), else (a narrow spot) its ball spreads onto its neighbours, a point at a time
    on the nearer side, until it spans ``min_run``. Ranks only grow: no point gets a larger ball
    than its own."""
    r = best.astype(np.int64).copy()
    n = len(r)
    for _ in range(n * (int(r.max(initial=0)) + 2)):
        starts = np.r_[0, np.flatnonzero(np.diff(r)) + 1]
        if len(starts) == 1:
            break
        ends = np.r_[starts[1:], n]
        length = s[ends - 1] - s[starts]
        short = np.flatnonzero(length < min_run)
        if not len(short):
            break
        k = short[np.argmin(length[short])]
        a, b = int(starts[k]), int(ends[k])
        own = r[a]
        smaller = [r[j] for j in (a - 1, b) if 0 <= j < n and r[j] > own]
        if smaller:
            r[a:b] = min(smaller)
            continue
        while s[b - 1] - s[a] < min_run and (a > 0 or b < n):
            if b >= n or (a > 0 and s[a] - s[a - 1] <= s[b] - s[b - 1]):
                a -= 1
            else:
                b += 1
        r[a:b] = np.maximum(r[a:b], own)
    return r


def run_balls(best, con, centre_dir, radii, params, kern):
    """``(point_tool (n,), short runs, their points)``. A run is a stretch of a contour where some
    ball fits (cyclic on a closed contour); a run shorter than ``params.min_run`` mm is left out
    (-1). Along a run each point takes its largest ball, in stretches no shorter than
    ``params.min_run`` (:func:`stretch_ranks`), each re-checked as :func:`contour_balls` does."""
    pieces, ranks, short, short_points = [], [], 0, 0
    for c in range(len(con)):
        a, b = con.offsets[c], con.offsets[c + 1]
        for run in contour_runs(best[a:b] >= 0, bool(con.closed[c])):
            full = bool(con.closed[c]) and len(run) == b - a + 1
            idx = run[:-1] + a if full else run + a  # a full loop lists its first point twice
            pts = con.points[np.r_[idx, idx[:1]] if full else idx]
            seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
            if seg.sum() < params.min_run:
                short += 1
                short_points += len(idx)
                continue
            r = best[idx]
            if full and (r != r[0]).any():  # start the loop where a stretch starts
                k = int(np.flatnonzero(r != np.roll(r, 1))[0])
                idx, r, seg = np.roll(idx, -k), np.roll(r, -k), np.roll(seg, -k)
            r = stretch_ranks(r, np.r_[0.0, np.cumsum(seg[:len(idx) - 1])], params.min_run)
            cuts = np.flatnonzero(np.diff(r)) + 1
            pieces += np.split(idx, cuts)
            ranks += list(r[np.r_[0, cuts]])
    point_tool = np.full(len(best), -1, np.int64)
    if not pieces:
        return point_tool, short, short_points
    order = np.concatenate(pieces)
    offsets = np.r_[0, np.cumsum([len(p) for p in pieces])]
    piece_of = np.repeat(np.arange(len(pieces)), np.diff(offsets))
    tool = contour_balls(np.asarray(ranks)[piece_of], offsets, piece_of, con.points[order], centre_dir[order], radii,
                          params.tolerance, kern)
    point_tool[order] = tool[piece_of]
    return point_tool, short, short_points


def contour_balls(best, offsets, contour_of, points, centre_dir, radii, tol, kern):
    """Per contour the smallest of its points' largest balls (-1 if a point fits none), re-checked
    at every point: in a concave crease a smaller ball sits nearer the crease, so gouge-freeness is
    not strictly monotone in R there, and a contour moves to a smaller ball until all its points fit."""
    if len(best) == 0:
        return np.zeros(0, np.int64)
    all_fit = np.logical_and.reduceat(best >= 0, offsets[:-1])
    tool = np.where(all_fit, np.maximum.reduceat(best, offsets[:-1]), -1).astype(np.int64)
    for _ in range(len(radii)):
        pt = tool[contour_of]
        changed = False
        for t in np.unique(tool[tool >= 0]):
            sel = np.nonzero(pt == t)[0]
            res = kern.largest_ball(points[sel], centre_dir[sel], radii[t:], tol)
            worst = np.full(len(tool), 0, np.int64)
            np.maximum.at(worst, contour_of[sel], np.where(res < 0, len(radii), res))
            bad = (tool == t) & (worst > 0)
            if bad.any():
                changed = True
                tool[bad] = np.where(t + worst[bad] < len(radii), t + worst[bad], -1)
        if not changed:
            break
    return tool


def smaller_balls(point_tool, choice, con, centre_dir, side, radii, params, kern, cand, cand_tilt, slack, body):
    """Points whose ball has no collision-free axis try the smaller balls of the table in turn
    (each re-checked for gouges: the largest smaller one that fits); ``(point_tool, choice, count
    of points that found an axis on a smaller ball)``."""
    point_tool, choice = point_tool.copy(), choice.copy()
    moved = np.zeros(len(point_tool), bool)
    tried = np.zeros(len(point_tool), bool)
    for _ in range(len(radii) - 1):
        todo = np.nonzero((point_tool >= 0) & (choice < 0) & (point_tool < len(radii) - 1) & ~tried)[0]
        if not len(todo):
            break
        new = np.full(len(todo), -1, np.int64)
        for t in np.unique(point_tool[todo]) + 1:
            sel = point_tool[todo] + 1 == t
            res = kern.largest_ball(con.points[todo[sel]], centre_dir[todo[sel]], radii[t:], params.tolerance)
            new[sel] = np.where(res >= 0, t + res, -1)
        tried[todo[new < 0]] = True
        todo, new = todo[new >= 0], new[new >= 0]
        if not len(todo):
            break
        ce = con.points[todo] + radii[new][:, None] * centre_dir[todo]
        found = kern.axis_search(ce, con.feed[todo], side[todo], new, cand, cand_tilt, slack, radii, body,
                                 np.array([0, len(todo)], np.int64))
        point_tool[todo] = new
        choice[todo] = found
        moved[todo[found >= 0]] = True
    return point_tool, choice, int(moved.sum())


def balls_piece(shared: dict, piece) -> np.ndarray:
    """:func:`largest_balls` of a group of contours' points ``piece = (points, reach, centre_dir,
    offsets)`` on a worker of a cluster; ``shared``: the ``part``, the ``radii``, ``tol``, the
    ``device``."""
    from ..cluster import worker_cached

    kern = worker_cached(shared, "part", lambda: solid_kernels(shared["part"], shared["device"]))
    return largest_balls(kern, *piece[:3], shared["radii"], shared["tol"])
