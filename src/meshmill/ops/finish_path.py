"""A finish's passes as moves: leads, links, repairs of what verification found.

:class:`PathBuilder` turns passes (dicts: ``tool``, ``idx`` into the points' arrays, ``entry`` and
``exit`` into :data:`LINKS`, ...) into a :class:`~meshmill.toolpath.model.Toolpath` and says which
pass and which part of it (``link_in``, ``approach_in``, ``lead_in``, the j-th cutting move,
``lead_out``, ``approach_out``, ``link_out``, ``direct_in``) each move is; :func:`repair_passes`
changes the passes that own failing moves. Lengths in mm.

Two passes of one tool, one after the other, are linked by a rapid straight from where the first
one's rapids may start to where the next one's may end (``direct_in``), where that rapid passes
verification, else at the lowest of :data:`LIFTS` that passes (up the first pass's way out,
across, down the next one's way in); else up to the safe plane, across and down. A direct link that verification of the
whole path still flags is not tried again for that pass.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from ..toolpath.model import Toolpath
from .finish_pole import POLE_MARGIN, POLE_STEP, gentle_turns

# Ways into and out of a pass, tried in this order: (lead along the outward side, vertical retract
# instead of one along the tool axis, feed all the way from and to the safe plane). The rapid of
# the others ends (starts) the approach distance above the lead's end, where the tool is clear of
# the stock; the approach itself is a feed.
LINKS = ((True, False, False), (True, True, False), (False, False, False), (False, True, False), (False, False, True),
         (False, True, True))
NO_LEAD = 2
LAST_RAPID_WAY = max(k for k, way in enumerate(LINKS) if not way[2])  # the last whose rapid ends above the lead
LIFTS = (0.0, 2.0, 5.0, 10.0, 20.0)  # mm: the heights a link between passes is tried at before the safe plane


@dataclass
class _Block:
    """The moves of one pass (:meth:`PathBuilder._block`): ``rows (m,)`` its points, a row of the
    builder's tips and axes (>= 0) or -1 - j for the j-th of its own ``extra``, ``axes`` (e, 3);
    ``rapid (m,)``, ``role`` (m,) of each move into them; ``ps`` the pass (held: its id keys the block)."""

    ps: dict
    rows: np.ndarray
    extra: np.ndarray
    axes: np.ndarray
    rapid: np.ndarray
    role: list

    def last(self, tip, axis) -> tuple:
        """``(tip, axis)`` of the block's last point (``tip``, ``axis``: the builder's)."""
        r = int(self.rows[-1])
        return (tip[r], axis[r]) if r >= 0 else (self.extra[-1 - r], self.axes[-1 - r])


class PathBuilder:
    """Turns passes into moves and maps verification problems back onto passes. ``approach``: the
    distance (mm) above a lead's end where the rapid stops and the feed begins. ``gentle``: the
    ``singular`` angle (rad) of a 5-axis machine whose C must turn gently (:func:`gentle_turns`), or
    None. Between passes the axis turns where the last pass left the safe plane, then travels;
    ``check``: :func:`~meshmill.pathing.verify.rapids_clear`'s call, which ways in and out
    (:meth:`_skip_blocked_ways`) and straight links are tried with (None: none tried, every
    link by the safe plane); ``direct``: whether passes are linked straight where that passes."""

    def __init__(self, tip, axis, side, safe_z, lead, approach, radius, gentle=None, reach=None, check=None,
                 direct=True):
        self.tip, self.axis, self.side, self.safe_z, self.lead = tip, axis, side, safe_z, lead
        self.approach, self.radius, self.gentle, self.reach = approach, radius, gentle, reach
        self.check, self.direct = check, direct
        self.direct_links = 0  # in the last path built
        self._known, self._known_for = {}, check  # the rapids check has passed or failed
        self._blocks = {}  # the blocks of moves of the last path built (:meth:`build`)
        self._ends = {}  # the rapid ends of its passes (:meth:`_directs`), keyed as the blocks
        self._settled = {}  # its passes' ways as :meth:`_skip_blocked_ways` left them
        self._links = {}  # its direct links (:meth:`_directs`: points, or None), keyed by the two passes
        self._changed = set()  # ids of the passes a repair build found changed (:meth:`_skip_blocked_ways`)
        self._reached = {}  # the reaches of the last path built (:meth:`_reaches`), by pass, side and way

    def _way_end(self, ps, key):
        """``(point, axis, vertical, feed)`` of pass ``ps``'s way in (``key`` ``"entry"``) or out
        (``"exit"``): where its lead begins (ends), else its first (last) point; the way's retract
        and whether it feeds all the way (:data:`LINKS`)."""
        lead, vertical, feed = LINKS[ps[key]]
        i = ps["idx"][0 if key == "entry" else -1]
        return self.tip[i] + (self.lead * self.side[i] if lead else 0.0), self.axis[i], vertical, feed

    def _reaches(self, passes):
        """Per pass, the distances ``(in, out)`` down the way to the safe plane to which a rapid
        may come where its entry (exit) feeds all the way (None: feed all the way): the stock's
        :func:`~meshmill.pathing.verify.rapid_reach`, at least the approach distance."""
        out = [[None, None] for _ in passes]
        if self.reach is None:
            return out
        pts, dirs, axes, tools, tops, where = [], [], [], [], [], []
        known, kept = self._reached, {}
        for k, ps in enumerate(passes):
            for side, key in enumerate(("entry", "exit")):
                if not LINKS[ps[key]][2] or not ps.get(("reach_in", "reach_out")[side], True):
                    continue
                memo = (id(ps), side, ps[key])
                if memo in known:  # (the same pass's way in the last path built)
                    kept[memo] = known[memo]
                    out[k][side] = kept[memo][1]
                    continue
                p, u, vertical, feed = self._way_end(ps, key)
                d = self._dir(u, vertical)
                pts.append(p)
                dirs.append(d)
                axes.append(u)
                tools.append(ps["tool"])
                tops.append(max(0.0, (self.safe_z - p[2]) / d[2]))
                where.append((k, side, memo))
        if pts:
            t = self.reach(np.array(pts), np.array(dirs), np.array(axes), np.array(tools), np.array(tops))
            for (k, side, memo), tk, top in zip(where, t, tops):
                if tk < top - self.approach:
                    out[k][side] = max(float(tk), self.approach)
                kept[memo] = (passes[k], out[k][side])
        self._reached = kept  # (holding the passes: their ids stay theirs)
        return out

    def _skip_blocked_ways(self, passes):
        """Moves each pass's ``entry`` and ``exit`` (in place) past the ways of :data:`LINKS` whose
        rapid ends where the tool itself is not clear (:attr:`check` of the pose ``approach`` above
        the lead's end: the rapid into it, or out of it, fails verification, so a round of repairs
        would take the next way), up to :data:`LAST_RAPID_WAY`: the ways that feed are left to the
        repairs, which take them only after the path's own problems have split or unmerged the
        pass (taken in the first build, 140 of the impeller's passes were dropped that the repairs
        keep). In a repair build the passes it changed are noted for :meth:`_feed_where_rapids_fail`
        (the impeller's and the dolphin's paths the same, one round fewer).
        Each rapid is asked once over the builds of a path (:meth:`_clear`'s memory), and a pass
        whose ways were settled in the last path built is not looked at again."""
        if self.check is None:
            return
        settled = self._settled
        todo = [(ps, key) for ps in passes if settled.get(id(ps), (None,))[1:] != (ps["entry"], ps["exit"])
                for key in ("entry", "exit")]
        self._changed = {id(ps) for ps, _ in todo} if settled else set()  # (a repair build's)
        while todo := [(ps, key) for ps, key in todo if ps[key] < LAST_RAPID_WAY]:
            _, above, axes, tools = self._ways_at(todo)
            ok = self._clear(above, axes, above, axes, tools)
            todo = [t for t, good in zip(todo, ok) if not good]
            for ps, key in todo:
                ps[key] += 1
        self._settled = {id(ps): (ps, ps["entry"], ps["exit"]) for ps in passes}  # (holding the passes: ids stay)

    def _feed_where_rapids_fail(self, passes, directs) -> bool:
        """(A repair build's.) Moves the ways of the passes :meth:`_skip_blocked_ways` found changed
        that stand at :data:`LAST_RAPID_WAY` to the next (feeding from the safe plane) where the
        rapid down from the safe plane into the pass (up out of it) fails :attr:`check`, as the
        next round of repairs would: only where that rapid is built, not where ``directs`` (of
        :meth:`_directs`) links the pass straight. Returns whether any way moved."""
        last = [(k, key) for k, ps in enumerate(passes) if id(ps) in self._changed for key in ("entry", "exit")
                if ps[key] == LAST_RAPID_WAY and (k if key == "entry" else k + 1) not in directs]
        if not last:
            return False
        ends, above, axes, tools = self._ways_at([(passes[k], key) for k, key in last])
        up = np.array([self._up(p, u, LINKS[LAST_RAPID_WAY][1]) for p, u in zip(ends, axes)])
        into = np.array([key == "entry" for _, key in last])[:, None]
        ok = self._clear(np.where(into, up, above), axes, np.where(into, above, up), axes, tools)
        for k, key in (t for t, good in zip(last, ok) if not good):
            passes[k][key] += 1
            self._settled[id(passes[k])] = (passes[k], passes[k]["entry"], passes[k]["exit"])
        return not ok.all()

    def _ways_at(self, todo):
        """``(ends (k, 3), above (k, 3), axes (k, 3), tools (k,))`` of the ways ``todo`` ((pass,
        ``"entry"`` or ``"exit"``) pairs): their :meth:`_way_end` and :meth:`_above` it, all at once."""
        i = np.array([ps["idx"][0 if key == "entry" else -1] for ps, key in todo], np.int64)
        lead, vertical, _ = np.array(LINKS, bool)[[ps[key] for ps, key in todo]].T
        p = np.where(lead[:, None], self.tip[i] + self.lead * self.side[i], self.tip[i])
        u = self.axis[i]
        straight = vertical | (u[:, 2] < 1e-6)
        d = np.where(straight[:, None], np.array([0.0, 0.0, 1.0]), u)
        above = p + np.minimum(self.approach, np.maximum(0.0, (self.safe_z - p[:, 2]) / d[:, 2]))[:, None] * d
        return p, above, u, np.array([ps["tool"] for ps, _ in todo], np.int64)

    def _rapid_ends(self, ps, reach):
        """Where the rapids into and out of pass ``ps`` end and start, ``(in, out)`` (each a point
        or None where the entry or exit feeds all the way from or to the safe plane)."""
        ends = []
        for key, r in zip(("entry", "exit"), reach):
            p, u, vertical, feed = self._way_end(ps, key)
            if not feed:
                ends.append(self._above(p, u, vertical))
            elif r is not None:
                ends.append(p + r * self._dir(u, vertical))
            else:
                ends.append(None)
        return ends

    def _directs(self, passes, reaches) -> dict:
        """``{pass number: (m + 1, 3) points}``: the passes reached from the pass before without the
        safe plane (:attr:`direct`), by the first of :data:`LIFTS` whose link passes
        (:meth:`_lifted`)."""
        if self.check is None or not self.direct or len(passes) < 2:
            return {}
        kept, ends = {}, []
        for ps, r in zip(passes, reaches):  # (each pass's, as in the last path built where it is the same)
            key = (id(ps), ps["entry"], ps["exit"], r[0], r[1])
            got = self._ends.get(key) or (ps, self._rapid_ends(ps, r))
            kept[key] = got
            ends.append(got[1])
        self._ends = kept  # (holding the passes: their ids stay theirs)
        ks = np.array([k for k in range(1, len(passes)) if passes[k]["tool"] == passes[k - 1]["tool"]
                       and passes[k].get("direct_in", True) and ends[k - 1][1] is not None
                       and ends[k][0] is not None], np.int64)
        # a link found (or not) in the last path built between the same two passes, the same
        keys = {int(k): (id(passes[k - 1]), passes[k - 1]["exit"], id(passes[k]), passes[k]["entry"],
                         reaches[k - 1][1], reaches[k][0]) for k in ks}
        links = {keys[k]: self._links[keys[k]] for k in keys if keys[k] in self._links}
        out = {k: links[keys[k]] for k in keys if links.get(keys[k]) is not None}
        ks = np.array([k for k in ks if keys[int(k)] not in links], np.int64)
        if len(ks):
            found = self._new_directs(passes, ends, ks)
            out.update(found)
            links.update({keys[int(k)]: found.get(int(k)) for k in ks})
        self._links = links  # (the passes are held by the ends: their ids stay theirs)
        return out

    def _new_directs(self, passes, ends, ks) -> dict:
        """:meth:`_directs` of the links into passes ``ks (j,)`` from the passes before (``ends``:
        every pass's rapid ends)."""
        a = np.array([ends[k - 1][1] for k in ks])
        b = np.array([ends[k][0] for k in ks])
        da = np.array([self._dir(self.axis[passes[k - 1]["idx"][-1]], LINKS[passes[k - 1]["exit"]][1]) for k in ks])
        db = np.array([self._dir(self.axis[passes[k]["idx"][0]], LINKS[passes[k]["entry"]][1]) for k in ks])
        xa = np.array([self.axis[passes[k - 1]["idx"][-1]] for k in ks])
        xb = np.array([self.axis[passes[k]["idx"][0]] for k in ks])
        tool = np.array([passes[k]["tool"] for k in ks])
        # a link whose ends are not clear passes at no height: their poses alone first
        live = np.nonzero(self._clear(a, xa, a, xa, tool) & self._clear(b, xb, b, xb, tool))[0]
        out = {}
        for h in LIFTS:
            ways = {i: self._lifted(a[i], da[i], b[i], db[i], h) for i in live}
            live = np.array([i for i in live if ways[i] is not None], np.int64)
            if not len(live):
                break
            m = len(ways[live[0]]) - 1  # moves per link; the axis turns on the middle one
            starts = np.concatenate([ways[i][:-1] for i in live])
            stops = np.concatenate([ways[i][1:] for i in live])
            after = np.tile(np.arange(m) > m // 2, len(live))[:, None]
            ax0 = np.where(after, np.repeat(xb[live], m, axis=0), np.repeat(xa[live], m, axis=0))
            ax1 = np.where(np.tile(np.arange(m) >= m // 2, len(live))[:, None], np.repeat(xb[live], m, axis=0), ax0)
            ok = self._clear(starts, ax0, stops, ax1, np.repeat(tool[live], m)).reshape(len(live), m).all(axis=1)
            out.update({int(ks[i]): ways[i] for i in live[ok]})
            live = live[~ok]
        return out

    def _clear(self, a, xa, b, xb, tool):
        """:attr:`check` of the rapids ``a -> b``, each asked once over the builds of one path
        (a round of repairs rebuilds the passes it did not change the same; :meth:`build` forgets
        the answers when :attr:`check` changes)."""
        rows = np.ascontiguousarray(np.column_stack([a, xa, b, xb, tool]), np.float64)
        keys = rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel().tolist()
        new = [i for i, k in enumerate(keys) if k not in self._known]
        if new:
            for i, ok in zip(new, self.check(a[new], xa[new], b[new], xb[new], tool[new])):
                self._known[keys[i]] = bool(ok)
        return np.array([self._known[k] for k in keys], bool)

    def _lifted(self, a, da, b, db, h):
        """The points ``(m + 1, 3)`` of a link from ``a`` to ``b``: straight (``h`` 0), or ``h`` mm
        up ``da`` from ``a``, across, and down ``db`` to ``b``; None where that would rise past the
        safe plane (the safe plane's link is then as short)."""
        if h == 0.0:
            return np.array([a, b])
        a2, b2 = a + h * da, b + h * db
        if max(a2[2], b2[2]) >= self.safe_z:
            return None
        return np.array([a, a2, b2, b])

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

    def _block(self, ps, reach, way, direct_out: bool, prev) -> _Block:
        """The moves of pass ``ps`` (:meth:`build`): its link in (``way``: the direct link's
        points, or None: by the safe plane, turning in place first where ``prev``, the tip and
        axis of the point before, has another axis), lead, points and lead out, and its link out
        unless ``direct_out`` (the next pass is reached directly); ``reach``: (in, out) of
        :meth:`_reaches`."""
        rows, extra, axes, rapid, role = [], [], [], [], []

        def add(p, u, is_rapid, r):
            rows.append(-1 - len(extra))
            extra.append(p)
            axes.append(u)
            rapid.append(is_rapid)
            role.append(r)

        idx = ps["idx"]
        reach_in, reach_out = reach
        t0, u0 = self.tip[idx[0]], self.axis[idx[0]]
        u1 = self.axis[idx[-1]]
        lead_in, vertical_in, feed_in = LINKS[ps["entry"]]
        lead_out, vertical_out, feed_out = LINKS[ps["exit"]]
        start = self._way_end(ps, "entry")[0]
        end = self._way_end(ps, "exit")[0]
        if way is not None:  # from where the pass before left off: straight, or lifted over what lies between
            for j, p in enumerate(way[1:]):
                add(p, u0 if j >= (len(way) - 1) // 2 else (axes[-1] if axes else prev[1]), True, "direct_in")
        else:
            if prev is not None and float(np.dot(prev[1], u0)) < 1.0 - 1e-12:  # turn in place, then travel
                add(prev[0], u0, True, "link_in")
            add(self._up(start, u0, vertical_in), u0, True, "link_in")
            if not feed_in:
                add(self._above(start, u0, vertical_in), u0, True, "link_in")
            elif reach_in is not None:  # rapid down to where the stock begins, then feed
                add(start + reach_in * self._dir(u0, vertical_in), u0, True, "link_in")
        add(start, u0, False, "approach_in")
        if lead_in:
            add(t0, u0, False, "lead_in")
        if len(idx) > 1:  # the pass's points, fed
            rows.extend(idx[1:].tolist())
            rapid.extend([False] * (len(idx) - 1))
            role.extend(range(1, len(idx)))
        if lead_out:
            add(end, u1, False, "lead_out")
        if not feed_out:
            add(self._above(end, u1, vertical_out), u1, False, "approach_out")
            if not direct_out:
                add(self._up(end, u1, vertical_out), u1, True, "link_out")
        elif reach_out is not None:  # feed out of the stock, then rapid
            add(end + reach_out * self._dir(u1, vertical_out), u1, False, "approach_out")
            if not direct_out:
                add(self._up(end, u1, vertical_out), u1, True, "link_out")
        else:
            add(self._up(end, u1, vertical_out), u1, False, "approach_out")
        return _Block(ps, np.array(rows, np.int64), np.reshape(extra, (-1, 3)), np.reshape(axes, (-1, 3)),
                      np.array(rapid, bool), role)

    def build(self, passes):
        """``(toolpath, owner, role)``: the moves of ``passes``, each move's pass (index) and part
        of it. A pass whose block of moves would come out the same as in the last path built (the
        same pass, reaches, links and point before) takes that block again: a round of repairs
        builds only the passes it changed and their neighbours."""
        if self._known_for is not self.check:  # what the last builds learnt from another check
            self._known, self._settled, self._links, self._ends, self._blocks, self._reached = {}, {}, {}, {}, {}, {}
            self._known_for = self.check
        self._skip_blocked_ways(passes)
        reaches = self._reaches(passes)
        directs = self._directs(passes, reaches)
        if self._changed and self._feed_where_rapids_fail(passes, directs):
            reaches = self._reaches(passes)
            directs = self._directs(passes, reaches)
        self.direct_links = len(directs)
        blocks, kept, prev = [], {}, None
        for k, ps in enumerate(passes):
            way, direct_out = directs.get(k), k + 1 in directs
            key = (id(ps), ps["entry"], ps["exit"], reaches[k][0], reaches[k][1],
                   None if way is None else way.tobytes(), direct_out,
                   None if prev is None else (prev[0].tobytes(), prev[1].tobytes()))
            block = self._blocks.get(key)
            if block is None:
                block = self._block(ps, reaches[k], way, direct_out, prev)
            kept[key] = block
            blocks.append(block)
            prev = block.last(self.tip, self.axis)
        self._blocks = kept  # (holding the passes: their ids stay theirs)
        # the blocks' points: rows of ``self.tip`` and ``self.axis``, then of the blocks' own (-1 - j)
        n_own = len(self.tip)
        sizes = np.array([len(b.rows) for b in blocks], np.int64)
        own = np.cumsum([0] + [len(b.extra) for b in blocks])[:-1]
        rows = np.concatenate([b.rows for b in blocks] + [np.zeros(0, np.int64)])
        rows = np.where(rows >= 0, rows, n_own + np.repeat(own, sizes) - 1 - rows)
        tip = np.concatenate([self.tip] + [b.extra for b in blocks])
        axis = np.concatenate([self.axis] + [b.axes for b in blocks])
        tp = Toolpath(tip[rows], axis[rows], np.concatenate([b.rapid for b in blocks] + [np.zeros(0, bool)]),
                      np.repeat([ps["tool"] for ps in passes], sizes).astype(np.int64))
        owner = np.repeat(np.arange(len(blocks)), sizes).tolist()
        role = [r for b in blocks for r in b.role]
        self.added = 0
        if self.gentle is not None:
            n = len(tp)
            tp, keep = gentle_turns(tp, self.radius, self.gentle)
            owner, role = [owner[k] for k in keep], [role[k] for k in keep]
            self.added = len(tp) - n
        return tp, owner, role

    def pole_report(self):
        """What :func:`gentle_turns` put into the last path built: ``margin_deg``, ``step_deg``,
        ``poses_added`` (None without a 5-axis machine)."""
        if self.gentle is None:
            return None
        return {"margin_deg": POLE_MARGIN, "step_deg": POLE_STEP, "poses_added": self.added}


def repair_passes(passes, problem_moves, owner, role):
    """New pass list after fixing the passes that own the problem moves; returns (passes, dropped).

    A failing direct link is not tried again (the pass is reached by the safe plane); a failing
    entry or exit tries the next of :data:`LINKS` (a failing lead jumps to the first option
    without one); when none is left the pass is dropped. A failing cutting move that merged points
    (:func:`merged_points`) gets them back; another splits its pass, and pieces of a single point
    are left out.
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
        if "direct_in" in roles:
            ps["direct_in"] = False
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
        # a failing move that merged points: its points back; other failing moves split the pass
        cuts = sorted(r for r in roles if isinstance(r, int))
        if "full" in ps:
            ps, cuts = _unmerged(ps, cuts)
        bounds = [0, *cuts, len(ps["idx"])]
        pieces = [ps["idx"][a:b] for a, b in zip(bounds[:-1], bounds[1:])]
        for i, piece in enumerate(pieces):
            if len(piece) < 2:
                continue
            new = dict(ps, idx=piece)
            if "full" in ps:
                new["at"] = ps["at"][bounds[i]:bounds[i + 1]]
            if i > 0:
                new["entry"] = ps["first_link"]
            if i < len(pieces) - 1:
                new["exit"] = ps["first_link"]
            out.append(new)
    return out, dropped


def _unmerged(ps, cuts):
    """``(pass, cuts)``: pass ``ps`` with the points :func:`merged_points` dropped from its failing
    moves ``cuts`` (j: the move from point j-1 to j) put back, and the failing moves that dropped
    none (to split at, renumbered)."""
    at, full = ps["at"], ps["full"]
    back = [j for j in cuts if at[j] - at[j - 1] > 1]
    if not back:
        return ps, cuts
    new_at = np.unique(np.concatenate([at] + [np.arange(at[j - 1] + 1, at[j]) for j in back]))
    split = [int(np.searchsorted(new_at, at[j])) for j in cuts if j not in back]
    return dict(ps, idx=full[new_at], at=new_at), split


def merged_points(passes, tip, axis, reach, tolerance: float) -> list:
    """The passes with the points dropped whose pose the move between the points kept either side
    passes within ``tolerance`` mm (the tip off the chord plus the axis's turn off the
    interpolated one, in radians, times the tool's ``reach (T,)`` mm), so that a smooth surface is
    not cut as a chain of short zigzags; the first and last points stay. A pass that drops points
    keeps them (``full``, the points before merging, and ``at``, where each point kept lies in
    it): :func:`repair_passes` puts them back where a merged move fails verification."""
    out = []
    for ps in passes:
        idx = np.asarray(ps["idx"])
        keep = _kept(np.ascontiguousarray(tip[idx], np.float64), np.ascontiguousarray(axis[idx], np.float64),
                      float(reach[ps["tool"]]), float(tolerance)) if len(idx) > 2 else None
        if keep is None or keep.all():
            out.append(ps)
            continue
        out.append(dict(ps, idx=idx[keep], full=idx, at=np.nonzero(keep)[0]))
    return out


@numba.njit(cache=True)
def _kept(p, u, reach: float, tol: float) -> np.ndarray:
    """``(k,) bool``: the points of one pass (tips ``p``, axes ``u`` (k, 3)) Douglas-Peucker keeps
    within ``tol`` (:func:`merged_points`)."""
    n = p.shape[0]
    keep = np.zeros(n, np.bool_)
    keep[0] = True
    keep[n - 1] = True
    stack = np.empty((max(n, 2), 2), np.int64)
    stack[0, 0] = 0
    stack[0, 1] = n - 1
    sp = 1
    while sp > 0:
        sp -= 1
        a = stack[sp, 0]
        b = stack[sp, 1]
        if b - a < 2:
            continue
        dx = p[b, 0] - p[a, 0]
        dy = p[b, 1] - p[a, 1]
        dz = p[b, 2] - p[a, 2]
        dd = dx * dx + dy * dy + dz * dz
        worst = -1.0
        k = a + 1
        for i in range(a + 1, b):
            ex = p[i, 0] - p[a, 0]
            ey = p[i, 1] - p[a, 1]
            ez = p[i, 2] - p[a, 2]
            t = 0.0
            if dd > 0.0:
                t = min(1.0, max(0.0, (ex * dx + ey * dy + ez * dz) / dd))
            ox = ex - t * dx
            oy = ey - t * dy
            oz = ez - t * dz
            mx = (1.0 - t) * u[a, 0] + t * u[b, 0]
            my = (1.0 - t) * u[a, 1] + t * u[b, 1]
            mz = (1.0 - t) * u[a, 2] + t * u[b, 2]
            mn = max(math.sqrt(mx * mx + my * my + mz * mz), 1e-12)
            c = (mx * u[i, 0] + my * u[i, 1] + mz * u[i, 2]) / mn
            err = math.sqrt(ox * ox + oy * oy + oz * oz) + reach * math.acos(min(1.0, max(-1.0, c)))
            if err > worst:
                worst = err
                k = i
        if worst > tol:
            keep[k] = True
            stack[sp, 0] = a
            stack[sp, 1] = k
            stack[sp + 1, 0] = k
            stack[sp + 1, 1] = b
            sp += 2
    return keep


def pass_points(ps) -> np.ndarray:
    """The points pass ``ps`` cuts ``(q,)``: its own, and those :func:`merged_points` dropped
    between its first and last."""
    if "full" not in ps:
        return np.asarray(ps["idx"])
    return ps["full"][ps["at"][0]:ps["at"][-1] + 1]
