"""5-axis Z-constant finishing with ball-end tools (the method of seed 004, exact).

1. Contours: planes from the top down every ``step_down``; CC points with outward normals
   (:mod:`meshmill.geometry.slicing`).
2. Gouge-free tool: per CC point the largest ball of the table whose sphere at CE = CC + R·n does not
   enter the mesh by more than ``tol`` (exact point-to-triangle distances through the BVH). Each
   *run* of a contour (the points between those that no ball fits) takes the smallest of its
   points' tools, and runs shorter than ``min_run`` are left out: all of a contour that a tool
   reaches is cut. With ``whole_contours`` (seed 004's rule) a contour takes one tool, and a
   contour with a point that no tool fits is reported and not cut.
3. Collision-free axis: candidates tilted by alpha toward the feed direction and beta toward the
   outward side, in order of increasing tilt up to ``max_tilt``; a point keeps its predecessor's
   choice when that is free and no more than one step more tilted. The flutes must not gouge and the
   shank and holder keep ``clearance``. Points without a free axis are left out with a lift.
4. Passes with lead-in/out along the outward side and retracts along the tool axis (or vertically)
   to the safe plane, ordered by contour or grouped by tool.
5. The finished path is verified (:mod:`meshmill.pathing.verify`); moves that fail are repaired by
   splitting passes or changing the link, and whatever cannot be repaired is left out. The path
   written is the verified one.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import time
import numpy as np
from scipy.spatial import cKDTree

from ..progress import PIECES, Meter, ranges
from ..errors import InputError, NothingToCut
from ..geometry.analysis import sample_surface
from ..geometry.mesh import Mesh
from ..geometry.slicing import MIN_HALF_COS, concat_contours, contour_runs, slice_contours, z_levels
from ..kernels.backend import solid_kernels
from ..params import FinishParams
from ..simulation.stock import Stock
from ..tolerances import FLOAT32_ROUNDING, WRITE_ROUNDING
from ..tools.table import pack_cylinders
from ..toolpath.model import Toolpath
from .finish_levels import added_contours
from .finish_shallow import shallow_facets, shallow_fill
from ..pathing.reverify import Reverify
from ..pathing.verify import DEFAULT_STEP, StockCheck, check_parts, path_pieces, rapid_reach, verify_piece

REPAIR_ROUNDS = 7
# Ways into and out of a pass, tried in this order: (lead along the outward side, vertical retract
# instead of one along the tool axis, feed all the way from and to the safe plane). The rapid of
# the others ends (starts) the approach distance above the lead's end, where the tool is clear of
# the stock; the approach itself is a feed.
LINKS = ((True, False, False), (True, True, False), (False, False, False), (False, True, False), (False, False, True),
         (False, True, True))
NO_LEAD = 2
SCALLOP_MIN_SLOPE = 10.0  # deg from the horizontal: flatter surfaces are rastered, not Z-levelled (scallop)
AREA_SAMPLES = 2_000_000  # most points sampled on the design to say what each status of the CC points stands for
POLE_MARGIN = 2.0  # deg: for a 5-axis machine, no move swings the axis nearer its rotaries' pole than this ...
POLE_STEP = 10.0  # ... and C turns at most this much in one move (deg): the azimuth goes round in steps
MAX_ARC_STEP = math.radians(5.0)  # largest turn of the normal between CC points at a convex edge


def tilt_candidates(max_tilt_deg: float, step_deg: float):
    """Candidate (alpha, beta) in rad, ordered by tilt from +Z in rings of one step, then by a
    preference for tilting sideways (beta) over tilting along the feed, so that neighbouring points
    pick the same candidate; ``(c, 2)`` and their tilts ``(c,)``."""
    n = int(math.floor(max_tilt_deg / step_deg + 1e-9))
    steps = np.arange(-n, n + 1) * math.radians(step_deg)
    a, b = np.meshgrid(steps, steps[steps >= 0], indexing="ij")
    a, b = a.ravel(), b.ravel()
    tilt = np.arccos(np.clip(np.cos(a) * np.cos(b), -1, 1))
    keep = tilt <= math.radians(max_tilt_deg) + 1e-9
    a, b, tilt = a[keep], b[keep], tilt[keep]
    ring = np.ceil(tilt / math.radians(step_deg) - 1e-6)
    order = np.lexsort((a < 0, np.round(tilt, 9), np.abs(a), ring))
    return np.stack([a[order], b[order]], axis=1), tilt[order]


def _axes(cand, idx, feed, side):
    """World axes ``(k, 3)`` of candidate ``idx (k,)`` in the local frames."""
    al = cand[idx, 0][:, None]
    be = cand[idx, 1][:, None]
    up = np.array([0.0, 0.0, 1.0])
    u = np.sin(al) * feed + np.cos(al) * (np.cos(be) * up + np.sin(be) * side)
    return u / np.linalg.norm(u, axis=1, keepdims=True)


class _PathBuilder:
    """Turns passes into moves and maps verification problems back onto passes. ``approach``: the
    distance (mm) above a lead's end where the rapid stops and the feed begins. ``gentle``: the
    ``singular`` angle (rad) of a 5-axis machine whose C must turn gently (:func:`gentle_turns`), or
    None. Between passes the axis turns where the last pass left the safe plane, then travels."""

    def __init__(self, tip, axis, side, safe_z, lead, approach, radius, gentle=None, reach=None):
        self.tip, self.axis, self.side, self.safe_z, self.lead = tip, axis, side, safe_z, lead
        self.approach, self.radius, self.gentle, self.reach = approach, radius, gentle, reach

    def _reaches(self, passes):
        """Per pass, the distances ``(in, out)`` down the way to the safe plane to which a rapid
        may come where its entry (exit) feeds all the way (None: feed all the way): the stock's
        :func:`~meshmill.pathing.verify.rapid_reach`, at least the approach distance."""
        out = [[None, None] for _ in passes]
        if self.reach is None:
            return out
        pts, dirs, axes, tools, tops, where = [], [], [], [], [], []
        for k, ps in enumerate(passes):
            for side, key, end in ((0, "entry", 0), (1, "exit", -1)):
                lead, vertical, feed = LINKS[ps[key]]
                if not feed or not ps.get(("reach_in", "reach_out")[side], True):
                    continue
                i = ps["idx"][end]
                p = self.tip[i] + (self.lead * self.side[i] if lead else 0.0)
                u = self.axis[i]
                d = np.array([0.0, 0.0, 1.0]) if vertical or u[2] < 1e-6 else u
                pts.append(p)
                dirs.append(d)
                axes.append(u)
                tools.append(ps["tool"])
                tops.append(max(0.0, (self.safe_z - p[2]) / d[2]))
                where.append((k, side))
        if pts:
            t = self.reach(np.array(pts), np.array(dirs), np.array(axes), np.array(tools), np.array(tops))
            for (k, side), tk, top in zip(where, t, tops):
                if tk < top - self.approach:
                    out[k][side] = max(float(tk), self.approach)
        return out

    def _up(self, p, u, vertical):
        if vertical or u[2] < 1e-6:
            return np.array([p[0], p[1], self.safe_z])
        return p + (self.safe_z - p[2]) / u[2] * u

    @staticmethod
    def _dir(u, vertical):
        return np.array([0.0, 0.0, 1.0]) if vertical or u[2] < 1e-6 else u

    def _above(self, p, u, vertical):
        """``approach`` mm up the way to the safe plane (never past it)."""
        d = self._dir(u, vertical)
        return p + min(self.approach, max(0.0, (self.safe_z - p[2]) / d[2])) * d

    def build(self, passes):
        tips, axes, rapid, tools, owner, role = [], [], [], [], [], []

        def add(p, u, is_rapid, tool, k, r):
            tips.append(p)
            axes.append(u)
            rapid.append(is_rapid)
            tools.append(tool)
            owner.append(k)
            role.append(r)

        reaches = self._reaches(passes)
        for k, ps in enumerate(passes):
            idx, tool = ps["idx"], ps["tool"]
            reach_in, reach_out = reaches[k]
            t0, u0 = self.tip[idx[0]], self.axis[idx[0]]
            t1, u1 = self.tip[idx[-1]], self.axis[idx[-1]]
            lead_in, vertical_in, feed_in = LINKS[ps["entry"]]
            lead_out, vertical_out, feed_out = LINKS[ps["exit"]]
            start = t0 + (self.lead * self.side[idx[0]] if lead_in else 0.0)
            end = t1 + (self.lead * self.side[idx[-1]] if lead_out else 0.0)
            if tips and float(np.dot(axes[-1], u0)) < 1.0 - 1e-12:  # turn in place, then travel
                add(tips[-1], u0, True, tool, k, "link_in")
            add(self._up(start, u0, vertical_in), u0, True, tool, k, "link_in")
            if not feed_in:
                add(self._above(start, u0, vertical_in), u0, True, tool, k, "link_in")
            elif reach_in is not None:  # rapid down to where the stock begins, then feed
                add(start + reach_in * self._dir(u0, vertical_in), u0, True, tool, k, "link_in")
            add(start, u0, False, tool, k, "approach_in")
            if lead_in:
                add(t0, u0, False, tool, k, "lead_in")
            for j in range(1, len(idx)):
                add(self.tip[idx[j]], self.axis[idx[j]], False, tool, k, j)
            if lead_out:
                add(end, u1, False, tool, k, "lead_out")
            if not feed_out:
                add(self._above(end, u1, vertical_out), u1, False, tool, k, "approach_out")
                add(self._up(end, u1, vertical_out), u1, True, tool, k, "link_out")
            elif reach_out is not None:  # feed out of the stock, then rapid
                add(end + reach_out * self._dir(u1, vertical_out), u1, False, tool, k, "approach_out")
                add(self._up(end, u1, vertical_out), u1, True, tool, k, "link_out")
            else:
                add(self._up(end, u1, vertical_out), u1, False, tool, k, "approach_out")
        tp = Toolpath(np.array(tips).reshape(-1, 3), np.array(axes).reshape(-1, 3), np.array(rapid, bool),
                      np.array(tools, np.int64))
        self.added = 0
        if self.gentle is not None:
            n = len(tp)
            tp, keep = gentle_turns(tp, self.radius, self.gentle)
            owner, role = [owner[k] for k in keep], [role[k] for k in keep]
            self.added = len(tp) - n
        return tp, owner, role


def _repair(passes, problem_moves, owner, role):
    """New pass list after fixing the passes that own the problem moves; returns (passes, dropped).

    A failing entry or exit tries the next of :data:`LINKS` (a failing lead jumps to the first
    option without one); when none is left the pass is dropped. A failing cutting move splits its
    pass, and pieces of a single point are left out.
    """
    fixes = {}
    for m in problem_moves:
        fixes.setdefault(owner[m], set()).add(role[m])
    out, dropped = [], 0
    for k, ps in enumerate(passes):
        if k not in fixes:
            out.append(ps)
            continue
        ps = dict(ps)
        roles = fixes[k]
        if "lead_in" in roles:
            ps["entry"] = max(ps["entry"] + 1, NO_LEAD)
        elif "link_in" in roles and LINKS[ps["entry"]][2] and ps.get("reach_in", True):
            ps["reach_in"] = False  # the rapid down to the stock failed: feed all the way
        elif "link_in" in roles or "approach_in" in roles:
            ps["entry"] += 1
        if "lead_out" in roles:
            ps["exit"] = max(ps["exit"] + 1, NO_LEAD)
        elif "link_out" in roles and LINKS[ps["exit"]][2] and ps.get("reach_out", True):
            ps["reach_out"] = False
        elif "link_out" in roles or "approach_out" in roles:
            ps["exit"] += 1
        if ps["entry"] >= len(LINKS) or ps["exit"] >= len(LINKS):
            dropped += 1
            continue
        # split at cutting moves that failed: the move from point j-1 to j is not cut
        cuts = sorted(r for r in roles if isinstance(r, int))
        bounds = [0, *cuts, len(ps["idx"])]
        pieces = [ps["idx"][a:b] for a, b in zip(bounds[:-1], bounds[1:])]
        for i, piece in enumerate(pieces):
            if len(piece) < 2:
                continue
            new = dict(ps, idx=piece)
            if i > 0:
                new["entry"] = ps["first_link"]
            if i < len(pieces) - 1:
                new["exit"] = ps["first_link"]
            out.append(new)
    return out, dropped


def _pole_distance(a0, a1):
    """Smallest angle (rad, (k,)) between +Z and the great-circle arcs from unit ``a0`` to ``a1``
    (k, 3), and whether it is reached inside the arc (not at an end)."""
    n = np.cross(a0, a1)
    size = np.linalg.norm(n, axis=1)
    n = n / np.maximum(size, 1e-300)[:, None]
    p = np.array([0.0, 0.0, 1.0]) - n[:, 2:3] * n  # +Z projected on the arc's plane
    p /= np.maximum(np.linalg.norm(p, axis=1), 1e-300)[:, None]
    arc = np.arccos(np.clip(np.einsum("ij,ij->i", a0, a1), -1.0, 1.0))
    to_p = np.arccos(np.clip(np.einsum("ij,ij->i", a0, p), -1.0, 1.0)) + \
        np.arccos(np.clip(np.einsum("ij,ij->i", p, a1), -1.0, 1.0))
    inside = (size > 1e-12) & (to_p <= arc + 1e-9)
    ends = np.minimum(np.arccos(np.clip(a0[:, 2], -1, 1)), np.arccos(np.clip(a1[:, 2], -1, 1)))
    return np.where(inside, np.arcsin(np.clip(np.abs(n[:, 2]), 0.0, 1.0)), ends), inside


def around_pole(a0, a1, c0, c1, radius, margin=POLE_MARGIN, step=POLE_STEP, through=math.radians(0.025)):
    """Poses ``(axes (m, 3), ball centres (m, 3))`` to put between the pose (``a0``, centre ``c0``)
    and (``a1``, ``c1``) of a ball of ``radius`` where the rotaries of a 5-axis machine whose pole is
    +Z would turn C by more than ``step`` deg in the move: near the pole a small turn of the axis is
    a large turn of C (half a turn in an instant where the axis swings past the pole), which no post
    can follow within the path's tolerance. The axis turns its azimuth in steps of at most ``step``
    deg instead, its tilt going from one end's to the other's (at least ``margin`` deg where the arc
    would pass nearer the pole than that); the centre stays on its segment, so the ball cuts what it
    cut. None needed (``m = 0``) where the arc passes within ``through`` rad of the pole (the
    machine flips the tilt there: half its ``singular``) or starts or ends on it."""
    a0, a1 = np.asarray(a0, float), np.asarray(a1, float)
    dist, inside = _pole_distance(a0[None], a1[None])
    t0, t1 = math.acos(min(1.0, a0[2])), math.acos(min(1.0, a1[2]))
    m_rad = math.radians(margin)
    z0, z1 = math.atan2(a0[1], a0[0]), math.atan2(a1[1], a1[0])
    turn = (z1 - z0 + math.pi) % (2 * math.pi) - math.pi  # the shorter way round
    past = bool(inside[0]) and dist[0] < m_rad
    if min(t0, t1) <= max(through, dist[0] + 1e-12 if past else 0.0) or (past and dist[0] < through) or \
            abs(turn) <= math.radians(step) + 1e-12:
        return np.empty((0, 3)), np.empty((0, 3))
    k = max(1, int(math.ceil(abs(math.degrees(turn)) / step)) - 1)
    s = np.arange(1, k + 1) / (k + 1)
    tilt = np.maximum(m_rad if past else 0.0, t0 + s * (t1 - t0))
    az = z0 + s * turn
    axes = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    centres = np.asarray(c0, float) + s[:, None] * (np.asarray(c1, float) - np.asarray(c0, float))
    return axes, centres


def gentle_turns(tp: Toolpath, radius, singular, margin=POLE_MARGIN, step=POLE_STEP):
    """``(toolpath, source (k',))``: ``tp`` with poses put in wherever C of a 5-axis machine whose
    pole is +Z would turn more than ``step`` deg in one move (``source``: the move of ``tp`` each
    new move belongs to). The machine holds C within ``singular`` rad of the pole; poses put in
    near it are tilted at least ``margin`` deg, and at least twice ``singular``. Off the pole,
    :func:`around_pole`'s poses. Leaving the pole, the machine still holds C where the last tilted
    pose had it: the axis tilts out at that azimuth first (to that tilt, or the move's end tilt if
    smaller), turns round at that tilt in steps of ``step`` deg, and tilts to the move's end. Tips
    follow the ball centres along their segment (``radius (T,)`` per tool index; a rapid's tip
    simply along its segment)."""
    margin = max(margin, 2.0 * math.degrees(singular))
    through = 0.5 * singular  # an arc this near the pole: the machine flips the tilt instead
    n = len(tp)
    tilt = np.arccos(np.clip(tp.axis[:, 2], -1.0, 1.0))
    az = np.arctan2(tp.axis[:, 1], tp.axis[:, 0])
    m_rad, step_rad = math.radians(margin), math.radians(step)
    off = tilt > singular
    last_off = np.maximum.accumulate(np.where(off, np.arange(n), -1))  # the last tilted pose so far
    held = np.full(n, np.nan)  # where C is held before each move
    held[1:] = np.where(last_off[:-1] >= 0, az[np.maximum(last_off[:-1], 0)], np.nan)

    def wrap(x):
        return (x + np.pi) % (2 * np.pi) - np.pi

    turned = np.zeros(n, bool)
    turned[1:] = off[1:] & np.where(off[:-1], np.abs(wrap(az[1:] - az[:-1])) > step_rad + 1e-12,
                                    np.isfinite(held[1:]) & (np.abs(wrap(az[1:] - np.nan_to_num(held[1:]))) > 1e-9))
    inserts = {}
    for i in np.flatnonzero(turned):
        r = 0.0 if tp.rapid[i] else float(radius[tp.tool[i]])
        c0, c1 = tp.tip[i - 1] + r * tp.axis[i - 1], tp.tip[i] + r * tp.axis[i]
        if off[i - 1]:
            new_axes, centres = around_pole(tp.axis[i - 1], tp.axis[i], c0, c1, r, margin, step, through)
        else:
            turn = float(wrap(az[i] - held[i]))
            k = max(1, int(math.ceil(abs(turn) / step_rad)))
            t = min(m_rad, tilt[i])
            zs = held[i] + turn * np.arange(0, k + 1) / k
            new_axes = np.column_stack([np.sin(t) * np.cos(zs), np.sin(t) * np.sin(zs), np.full(k + 1, np.cos(t))])
            if t >= tilt[i] - 1e-12:
                new_axes = new_axes[:-1]  # the last is the move's own end
            f = np.arange(1, len(new_axes) + 1) / (len(new_axes) + 1)
            centres = c0 + f[:, None] * (c1 - c0)
        if len(new_axes):
            inserts[int(i)] = (centres - r * new_axes, new_axes)
    if not inserts:
        return tp, np.arange(n)
    at = sorted(inserts)
    pieces = np.split(np.arange(n), at)
    tips, axes, source = [tp.tip[pieces[0]]], [tp.axis[pieces[0]]], [pieces[0]]
    for j, piece in zip(at, pieces[1:]):
        t_new, a_new = inserts[j]
        tips += [t_new, tp.tip[piece]]
        axes += [a_new, tp.axis[piece]]
        source += [np.full(len(t_new), j), piece]
    source = np.concatenate(source)
    return Toolpath(np.vstack(tips), np.vstack(axes), tp.rapid[source], tp.tool[source]), source


def _largest_balls(kern, con, centre_dir, radii, tol):
    """``(k,)`` the largest ball (rank into ``radii``) that fits at each CC point of ``con`` and
    touches the part there, -1 where none does (:func:`largest_balls` of its points)."""
    return largest_balls(kern, con.points, con.reach, centre_dir, radii, tol)


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


def _stretch_ranks(best, s, min_run):
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


def _run_tools(best, con, centre_dir, radii, params, kern):
    """``(point_tool (n,), short runs, their points)``. A run is a stretch of a contour where some
    ball fits (cyclic on a closed contour); a run shorter than ``params.min_run`` mm is left out
    (-1). Along a run each point takes its largest ball, in stretches no shorter than
    ``params.min_run`` (:func:`_stretch_ranks`), each re-checked as :func:`_contour_tools` does."""
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
            r = _stretch_ranks(r, np.r_[0.0, np.cumsum(seg[:len(idx) - 1])], params.min_run)
            cuts = np.flatnonzero(np.diff(r)) + 1
            pieces += np.split(idx, cuts)
            ranks += list(r[np.r_[0, cuts]])
    point_tool = np.full(len(best), -1, np.int64)
    if not pieces:
        return point_tool, short, short_points
    order = np.concatenate(pieces)
    offsets = np.r_[0, np.cumsum([len(p) for p in pieces])]
    piece_of = np.repeat(np.arange(len(pieces)), np.diff(offsets))
    tool = _contour_tools(np.asarray(ranks)[piece_of], offsets, piece_of, con.points[order], centre_dir[order], radii,
                          params.tolerance, kern)
    point_tool[order] = tool[piece_of]
    return point_tool, short, short_points


def _contour_tools(best, offsets, contour_of, points, centre_dir, radii, tol, kern):
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


def _smaller_balls(point_tool, choice, con, centre_dir, side, radii, params, kern, cand, cand_tilt, slack, body):
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


AREA_STATUS = ("cut", "no_ball", "no_axis", "short_runs", "left_out", "facing_down", "shallow")


def surface_status(mesh, kern, radii, tol, max_tilt, p, face, points, status, raster_from=None, raster_reach=0.0):
    """``(s,)`` index into ``AREA_STATUS`` of each point ``p (s, 3)`` of the design (on facets
    ``face (s,)``): ``facing_down`` on facets no ball within ``max_tilt`` touches (:func:`facing_down`);
    ``no_ball`` where no ball of ``radii`` touches the facet there without entering the part by more
    than ``tol`` (exact, through ``kern``); on facets facing up flatter than ``SCALLOP_MIN_SLOPE``,
    the status of the nearest raster contact (``points[raster_from:]``) within ``raster_reach`` mm,
    else ``shallow`` (no raster, or none of its passes reached there); elsewhere the status of the
    nearest of ``points (k, 3)`` (CC points, then raster contacts; ``status (k,)``)."""
    out = np.full(len(p), AREA_STATUS.index("facing_down"), np.int64)
    flat = shallow_facets(mesh, SCALLOP_MIN_SLOPE)[face]
    out[flat] = AREA_STATUS.index("shallow")
    up = np.nonzero(~facing_down(mesh, max_tilt)[face] & ~flat)[0]
    if len(up) and len(points):
        out[up] = status[cKDTree(points).query(p[up])[1]]
    flat = np.nonzero(flat)[0]
    if raster_from is not None and len(flat) and len(points) > raster_from:
        dist, near = cKDTree(points[raster_from:]).query(p[flat], distance_upper_bound=raster_reach)
        hit = np.isfinite(dist)
        out[flat[hit]] = status[raster_from:][near[hit]]
    checked = np.nonzero(out != AREA_STATUS.index("facing_down"))[0]
    if len(checked):
        fits = kern.largest_ball(p[checked], mesh.face_normals[face[checked]], radii, tol) >= 0
        out[checked[~fits]] = AREA_STATUS.index("no_ball")
    return out


def surface_areas(mesh, kern, radii, tol, max_tilt, spacing, points, status, raster_from=None, raster_reach=0.0):
    """mm² of the design surface by why it was or was not cut (:func:`surface_status` of points
    spread over it about ``spacing`` apart, :func:`~meshmill.geometry.analysis.sample_surface`)."""
    p, weight, face = sample_surface(mesh, spacing, AREA_SAMPLES)
    by = np.bincount(surface_status(mesh, kern, radii, tol, max_tilt, p, face, points, status, raster_from,
                                    raster_reach), weights=weight, minlength=len(AREA_STATUS))
    return {**{name: float(by[k]) for k, name in enumerate(AREA_STATUS)}, "total": float(weight.sum()),
            "why": "points spread over the design: facing_down where no ball within --max-tilt touches it, no_ball "
                   "where no ball of the table touches it there, shallow where it faces up flatter than 10 deg and no "
                   "raster pass (--scallop) reached it, else the status of the nearest CC point (or raster contact)"}


def facing_down(mesh, max_tilt):
    """``(m,) bool``: facets facing down more steeply than a ball whose axis is tilted at most
    ``max_tilt`` deg from +Z can touch (its cutting half faces down the axis; the flutes square to it)."""
    return mesh.face_normals[:, 2] < -math.sin(math.radians(max_tilt)) - 1e-9

def axis_piece(shared: dict, piece) -> np.ndarray:
    """The axis search of a group of contours on a worker of a cluster
    (:func:`meshmill.cluster.run_pieces`): ``piece = (centres, feed, side, tool, offsets)`` of its
    contours; ``shared``: the ``part``, the candidates and the tools as the search takes them,
    the ``device``. The part's kernels are built once per worker."""
    from ..cluster import worker_cached

    kern = worker_cached(shared, "part", lambda: solid_kernels(shared["part"], shared["device"]))
    ce, feed, side, tool, offsets = piece
    return kern.axis_search(ce, feed, side, tool, shared["cand"], shared["cand_tilt"], shared["slack"],
                            shared["radii"], shared["body"], offsets)


def _contour_groups(offsets, count: int, *arrays) -> list[tuple]:
    """``count`` groups of contours (``offsets (c + 1,)`` of their points) as pieces: every
    per-point array of ``arrays`` sliced to the group's points, and the group's offsets from 0."""
    return [(*(x[offsets[a]:offsets[b]] for x in arrays), offsets[a:b + 1] - offsets[a])
            for a, b in ranges(len(offsets) - 1, count)]


def _by_contours(cluster, offsets, arrays, local, remote, shared, say, what) -> np.ndarray:
    """``(k,) int64`` of a per-point search done by groups of contours (each point or contour on its
    own: the same result however grouped): ``local(piece)`` here, the share done told, or
    ``remote(shared, piece)`` on the workers of ``cluster``; pieces of :func:`_contour_groups`."""
    if cluster is not None:
        from ..cluster import PIECES_PER_WORKER, run_pieces, workers

        out = run_pieces(cluster, remote, shared, _contour_groups(offsets, PIECES_PER_WORKER * workers(cluster),
                                                                  *arrays), say, what)
    else:
        meter, out = Meter(say, what, offsets[-1]), []
        for piece in _contour_groups(offsets, PIECES, *arrays):
            out.append(local(piece))
            meter.done(len(piece[0]))
    return np.concatenate([np.zeros(0, np.int64), *out])


def balls_piece(shared: dict, piece) -> np.ndarray:
    """:func:`largest_balls` of a group of contours' points ``piece = (points, reach, centre_dir,
    offsets)`` on a worker of a cluster; ``shared``: the ``part``, the ``radii``, ``tol``, the
    ``device``."""
    from ..cluster import worker_cached

    kern = worker_cached(shared, "part", lambda: solid_kernels(shared["part"], shared["device"]))
    return largest_balls(kern, *piece[:3], shared["radii"], shared["tol"])


class _ClusterCheck:
    """:func:`~meshmill.pathing.verify.check_parts` of finish's paths in ranges of moves on a
    cluster's workers: the part (and stock) scattered and their kernels built once for every round
    of repairs; the reports are the one process's."""

    def __init__(self, client, mesh, stock, check: StockCheck, tools, tol, step, device, say):
        from ..cluster import share

        self.client, self.say, self.check = client, say, check
        self.tol, self.step = tol, step
        self.handle = share(client, dict(part=mesh, floor=None, stock=stock, allowance=check.allowance,
                                         clearance=check.clearance, tools=list(tools), tol=tol, step=step,
                                         device=device))

    def __call__(self, tp, only):
        from ..cluster import PIECES_PER_WORKER, submit, wait, workers

        pieces = path_pieces(tp, PIECES_PER_WORKER * workers(self.client), only)
        futures = [submit(self.client, verify_piece, self.handle, p) for p in pieces]
        wait(futures, self.say, "verify")
        return self.client.gather(futures)


def finish(mesh: Mesh, tools, params: FinishParams, progress=None, device: str = "cpu", machine=None, cluster=None):
    """Run the operation on ``device`` (``"cpu"`` or ``"cuda"``); returns ``(toolpath, summary, detail)``.

    ``tools``: the whole tool table (ball tools are used); ``progress(stage)`` is called as each
    stage starts; ``params.stock``: the material the finish starts from (a
    :class:`~meshmill.simulation.stock.Stock`; default the part with ``STOCK_ALLOWANCE`` on it),
    which rapids keep ``params.clearance`` from. ``detail`` holds per-point arrays for reports and
    tests. ``machine``: the 5-axis :class:`~meshmill.machine.model.Machine` the path is for: no
    move swings the axis past the pole of its rotaries (:func:`around_pole`).
    """
    stock, allowance, margin = Stock.of(params.stock, "offset").material(mesh)
    # kept under the tolerance by what writing the path and the part moves them (the files verify)
    tolerance = params.tolerance
    params = dataclasses.replace(params, tolerance=max(0.0, tolerance - WRITE_ROUNDING - FLOAT32_ROUNDING *
                                                       float(np.abs(mesh.bounds).max())),
                                 clearance=params.clearance + margin)
    say = progress or (lambda stage: None)
    seconds = {}
    t_all = time.perf_counter()
    balls = sorted((t for t in tools if t.type == "ball"), key=lambda t: (-t.radius, t.number))
    if not balls:
        raise InputError("the tool table has no ball tool: finish needs ball-end tools")
    radii = np.array([t.radius for t in balls])
    zmin, zmax = mesh.bounds[:, 2]
    top = max(zmax, stock.bounds[1, 2]) if stock is not None else zmax + allowance
    lowest_ball = radii.max() * (1.0 - math.cos(math.radians(params.max_tilt)))
    if params.safe_z is None:
        safe_z = max(zmax + 5.0, top + params.clearance + 1.0) + lowest_ball
    else:
        safe_z = params.safe_z
        if safe_z <= top + params.clearance + lowest_ball:
            raise InputError(f"safe_z {safe_z:g} is too low: it must be above {top + params.clearance + lowest_ball:.3f} "
                             "mm (the stock's top, the clearance, and what a tilted ball hangs below its tip)", "safe_z")
    levels = z_levels(zmin, zmax, params.step_down)
    if len(levels) == 0:
        raise NothingToCut(f"step_down {params.step_down:g} is larger than the part height {zmax - zmin:g} mm: no contour",
                         "step_down")

    say("index")
    t = time.perf_counter()
    kern = solid_kernels(mesh, device)  # the solid the part bounds, on the device for every stage
    rapid_stock = StockCheck(allowance=0.0 if stock is not None else allowance,
                             kern=solid_kernels(stock, device) if stock is not None else None,
                             clearance=params.clearance)
    seconds["index"] = time.perf_counter() - t

    say("contours")
    t = time.perf_counter()
    arc_step = min(params.sample / radii.max(), MAX_ARC_STEP)
    con = slice_contours(mesh, levels, params.sample, arc_step)
    scallop = None
    if params.scallop is not None:
        def piece_tools(c):
            cd = c.normals * c.reach[:, None]
            return _run_tools(_largest_balls(kern, c, cd, radii, params.tolerance), c, cd, radii, params, kern)[0]

        added, scallop = added_contours(mesh, levels, zmin, zmax, radii, params.scallop, params.sample, arc_step,
                                        piece_tools, SCALLOP_MIN_SLOPE)
        con = concat_contours([con, *added])
    seconds["contours"] = time.perf_counter() - t
    npts = len(con.points)
    contour_of = con.contour_of

    say("tools")
    t = time.perf_counter()
    centre_dir = con.normals * con.reach[:, None]  # ball centre = CC + R·centre_dir
    best = _by_contours(cluster, con.offsets, (con.points, con.reach, centre_dir),
                        lambda p: largest_balls(kern, *p[:3], radii, params.tolerance), balls_piece,
                        dict(part=mesh, device=device, radii=radii, tol=params.tolerance), say, "tools")
    fits = best >= 0
    if params.whole_contours:
        contour_tool = _contour_tools(best, con.offsets, contour_of, con.points, centre_dir, radii, params.tolerance, kern)
        point_tool = contour_tool[contour_of]
        short_runs = short_points = 0
    else:
        point_tool, short_runs, short_points = _run_tools(best, con, centre_dir, radii, params, kern)
    seconds["tools"] = time.perf_counter() - t

    say("axes")
    t = time.perf_counter()
    side = np.cross(con.feed, [0.0, 0.0, 1.0])
    cand, cand_tilt = tilt_candidates(params.max_tilt, params.tilt_step)
    # shank and holder keep the clearance from the part, and stay out of the allowance on it
    body, _ = pack_cylinders(balls, params.tolerance, max(params.clearance, rapid_stock.allowance))
    slack = math.radians(params.tilt_step) + 1e-9
    centres = con.points + radii[np.maximum(point_tool, 0)][:, None] * centre_dir
    choice = _by_contours(cluster, con.offsets, (centres, con.feed, side, point_tool),
                          lambda p: kern.axis_search(*p[:4], cand, cand_tilt, slack, radii, body, p[4]), axis_piece,
                          dict(part=mesh, device=device, cand=cand, cand_tilt=cand_tilt, slack=slack, radii=radii,
                               body=body), say, "axes")
    fallback = 0
    if not params.whole_contours:  # no free axis for the run's ball: a smaller one, with a thinner shank
        point_tool, choice, fallback = _smaller_balls(point_tool, choice, con, centre_dir, side, radii, params, kern,
                                                      cand, cand_tilt, slack, body)
    contour_tool = np.full(len(con), -1, np.int64)
    if npts:
        np.maximum.at(contour_tool, contour_of, point_tool)  # the smallest ball on it
    has_axis = choice >= 0
    ce = con.points + radii[np.maximum(point_tool, 0)][:, None] * centre_dir
    axis = np.zeros_like(ce)
    axis[has_axis] = _axes(cand, choice[has_axis], con.feed[has_axis], side[has_axis])
    tip = ce - radii[np.maximum(point_tool, 0)][:, None] * axis
    seconds["axes"] = time.perf_counter() - t

    table_index = {tool.number: i for i, tool in enumerate(tools)}
    shallow = None
    if params.scallop is not None:
        say("shallow areas")
        t = time.perf_counter()
        shallow = shallow_fill(mesh, kern, balls, params.scallop, SCALLOP_MIN_SLOPE, params.sample, params.tolerance,
                               max(params.clearance, rapid_stock.allowance), params.min_run)
        seconds["shallow"] = time.perf_counter() - t

    say("path")
    t = time.perf_counter()
    passes, bridge = [], []  # bridge: (CC point, axis, rank) of points put in where a pass meets a larger ball's
    for c in range(len(con)):
        a, b = con.offsets[c], con.offsets[c + 1]
        for run in contour_runs(has_axis[a:b] & (point_tool[a:b] >= 0), bool(con.closed[c])):
            # one ball a pass: where the ball changes the pass ends, and the smaller ball's pass takes
            # in the larger one's neighbouring point (a smaller ball fits where a larger one does), so
            # that the stretch between them is cut
            pieces = np.split(run + a, np.nonzero(np.diff(point_tool[a + run]))[0] + 1)
            for j, piece in enumerate(pieces):
                rank = int(point_tool[piece[0]])
                ends = []
                for k, nb, at in ((j - 1, -1, 0), (j + 1, 0, -1)):
                    if 0 <= k < len(pieces) and point_tool[pieces[k][nb]] < rank:
                        ends.append(len(tip) + len(bridge))
                        bridge.append((pieces[k][nb], axis[piece[at]], rank))
                    else:
                        ends.append(None)
                idx = np.r_[[ends[0]] * (ends[0] is not None), piece, [ends[1]] * (ends[1] is not None)]
                if len(idx) < 2:
                    continue
                link = 0 if params.lead > 0 else NO_LEAD
                passes.append(dict(contour=c, tool=table_index[balls[rank].number], rank=rank,
                                   idx=idx.astype(np.int64), entry=link, exit=link, first_link=link, shallow=False))
    if bridge:
        cc, ax, rk = (np.array(x) for x in zip(*bridge))
        r = radii[rk][:, None]
        bce = con.points[cc] + r * centre_dir[cc]
        tip, axis, ce, side = np.vstack([tip, bce - r * ax]), np.vstack([axis, ax]), np.vstack([ce, bce]), \
            np.vstack([side, side[cc]])
    n_raster, raster_first = 0, len(tip)
    if shallow is not None and shallow.tips:
        # the raster's tips follow the CC points' in the arrays: vertical axes, the outward side square to the lines
        first = len(tip)
        sizes = [len(p) for p in shallow.tips]
        rtip = np.concatenate(shallow.tips)
        n_raster = len(rtip)
        rank = np.repeat(shallow.rank, sizes)
        raxis = np.tile([0.0, 0.0, 1.0], (n_raster, 1))
        tip, axis = np.vstack([tip, rtip]), np.vstack([axis, raxis])
        ce = np.vstack([ce, rtip + radii[rank][:, None] * raxis])
        side = np.vstack([side, np.tile(np.cross(shallow.direction, [0.0, 0.0, 1.0]), (n_raster, 1))])
        for k, (size, r) in enumerate(zip(sizes, shallow.rank)):
            passes.append(dict(contour=len(con) + k, tool=table_index[balls[r].number], rank=r,
                               idx=first + np.arange(size), entry=NO_LEAD, exit=NO_LEAD, first_link=NO_LEAD,
                               shallow=True))
            first += size
    if not passes:
        smallest = min(radii)
        raise NothingToCut(f"nothing to cut: of {len(con)} contour(s), {int((contour_tool >= 0).sum())} fit a ball of "
                         f"the table (smallest R {smallest:g} mm) and none has a collision-free axis within "
                         f"max_tilt {params.max_tilt:g}; add smaller or longer tools", "max_tilt")
    if params.order == "tool":
        passes.sort(key=lambda p: (p["rank"], p["shallow"], p["contour"]))
    gentle = None
    if machine is not None and machine.chain.type != "3-axis":
        gentle = machine.chain.singular
    builder = _PathBuilder(tip, axis, side, safe_z, params.lead,
                           approach=rapid_stock.allowance + rapid_stock.clearance + params.tolerance,
                           radius=np.array([t.radius for t in tools]), gentle=gentle,
                           reach=None if stock is None else functools.partial(
                               rapid_reach, kern, tools, params.tolerance, rapid_stock))
    seconds["path"] = time.perf_counter() - t

    say("verify")
    t = time.perf_counter()
    step = min(DEFAULT_STEP, params.sample)
    if cluster is not None:  # ranges of moves on the workers: the same reports
        parts = _ClusterCheck(cluster, mesh, stock, rapid_stock, tools, params.tolerance, step, device, say)
    else:
        def parts(path, only):
            return check_parts(kern, path, tools, params.tolerance, step, rapid_stock, only, progress=say)
    # each round of repairs checks only the moves it changed
    check = Reverify(parts, params.tolerance, step, rapid_stock.summary())
    dropped = 0
    for rnd in range(REPAIR_ROUNDS + 1):
        tp, owner, role = builder.build(passes)
        report = check(tp)
        if report["ok"] or not passes:
            break
        if rnd == REPAIR_ROUNDS:  # give up on what still fails
            bad = {owner[m] for m in report["problem_moves"]}
            dropped += len(bad)
            passes = [p for k, p in enumerate(passes) if k not in bad]
            tp, owner, role = builder.build(passes)
            report = check(tp)
            break
        passes, lost = _repair(passes, report["problem_moves"], owner, role)
        dropped += lost
    report.pop("problem_moves")
    report["repair_rounds"] = rnd
    if not passes:
        raise NothingToCut("nothing left to cut: every pass failed verification (try lead 0, a larger max_tilt or "
                         "other tools)", ("lead", "max_tilt"))
    seconds["verify"] = time.perf_counter() - t

    cut_all = np.zeros(len(tip), bool)
    for ps in passes:
        cut_all[ps["idx"]] = True
    cut = cut_all[:npts]  # (the bridges and the raster's tips are no CC points)
    raster_cut = cut_all[raster_first:raster_first + n_raster]
    machinable = contour_tool >= 0
    tools_used = {}
    for ps in passes:
        name = tools[ps["tool"]].name
        entry = tools_used.setdefault(name, {"passes": 0, "cc_points": 0, "contours": set(), "raster_points": 0})
        entry["passes"] += 1
        if ps["shallow"]:
            entry["raster_points"] += int(len(ps["idx"]))
        else:
            entry["cc_points"] += int(len(np.unique(ps["idx"][ps["idx"] < npts])))
            entry["contours"].add(ps["contour"])
    for entry in tools_used.values():
        entry["contours"] = len(entry["contours"])
    tilt = np.degrees(np.arccos(np.clip(axis[:npts][cut, 2], -1, 1))) if cut.any() else np.zeros(0)
    feed_move = ~tp.rapid[1:] & (tp.tool[1:] == tp.tool[:-1])
    turn = np.einsum("ij,ij->i", tp.axis[1:], tp.axis[:-1])[feed_move]
    max_turn = float(np.degrees(np.arccos(np.clip(turn.min(), -1, 1)))) if len(turn) else 0.0
    status = np.select([cut, ~fits, point_tool < 0, ~has_axis], [0, 1, 3, 2], 4)
    if n_raster:  # every contact of a raster pass takes the pass's status
        contacts = np.concatenate(shallow.contacts)
        pass_cut = np.add.reduceat(raster_cut, np.r_[0, np.cumsum([len(t) for t in shallow.tips])[:-1]]) > 0
        contact_status = np.repeat(np.where(pass_cut, 0, 4), [len(c) for c in shallow.contacts])
    else:
        contacts, contact_status = np.zeros((0, 3)), np.zeros(0, np.int64)
    point_status = np.r_[status, contact_status].astype(np.int64)
    raster_reach = shallow.spacing if shallow is not None else 0.0
    areas = surface_areas(mesh, kern, radii, params.tolerance, params.max_tilt, params.sample,
                          np.vstack([con.points, contacts]), point_status, npts if shallow is not None else None,
                          raster_reach)
    if scallop is not None:
        scallop = {**scallop, "shallow": shallow.report}
    seconds["total"] = time.perf_counter() - t_all
    summary = {
        "operation": "finish",
        "step_down": params.step_down,
        "sample": params.sample,
        "max_tilt": params.max_tilt,
        "tilt_step": params.tilt_step,
        "order": params.order,
        "safe_z": safe_z,
        "tolerance": tolerance,
        "tolerance_kept": params.tolerance,
        "clearance": params.clearance,
        "stock": rapid_stock.summary(),
        "levels": int(len(np.unique(con.z))),
        "scallop": scallop,
        "pole": None if gentle is None else {"margin_deg": POLE_MARGIN, "step_deg": POLE_STEP,
                                             "poses_added": builder.added},
        "contours": int(len(con)),
        "machinable_contours": int(machinable.sum()),
        "unmachinable_contours": [
            {"z": float(con.z[c]), "cc_points": int(con.offsets[c + 1] - con.offsets[c]),
             "points_without_tool": int((~fits[con.offsets[c]:con.offsets[c + 1]]).sum())}
            for c in np.nonzero(~machinable)[0]
        ],
        "cc_points": int(npts),
        "points_without_tool": int((~fits).sum()),
        "whole_contours": bool(params.whole_contours),
        "partly_cut_contours": int((machinable & (np.add.reduceat(point_tool < 0, con.offsets[:-1]) > 0)).sum())
        if npts else 0,
        "runs_too_short": int(short_runs),
        "points_in_short_runs": int(short_points),
        "points_on_smaller_balls": int(fallback),
        "points_left_out": int((point_tool >= 0).sum() - cut[point_tool >= 0].sum()),
        "points_cut": int(cut.sum()),
        "raster_points": int(n_raster),
        "raster_points_cut": int(raster_cut.sum()),
        "area_mm2": areas,
        "points_tilted": int((tilt > 1e-6).sum()),
        "max_tilt_used": float(tilt.max()) if len(tilt) else 0.0,
        "max_axis_change": max_turn,
        "passes": len(passes),
        "passes_dropped": dropped,
        "moves": int(len(tp)),
        "cutting_length": tp.cutting_length(),
        "tools_used": tools_used,
        "verify": report,
        "seconds": {k: round(v, 4) for k, v in seconds.items()},
    }
    detail = dict(surface_points=np.vstack([con.points, contacts]), surface_status=point_status,
                  raster_from=npts if shallow is not None else -1, raster_reach=raster_reach,
                  contours=con, best=best, contour_tool=contour_tool, point_tool=point_tool, choice=choice,
                  axis=axis[:npts], tip=tip[:npts], ce=ce[:npts], cut=cut, balls=balls, kern=kern, shallow=shallow)
    return tp, summary, detail
