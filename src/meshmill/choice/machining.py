"""The black box of seed 002 on our kernels: a zoning plus, per zone, a cutter, a feed azimuth
and a tool axis -> the zigzag tool paths and their machining time on a machine.

Zones are machined one after the other, grouped by cutter and then by tool axis (fewest tool
changes and re-orientations); each zone's passes are linked with retracts to its own safe plane
(``SAFE_ABOVE`` over the part in the zone's machining frame). The time is that of
:func:`meshmill.machine.timing.path_time` on the machining-frame moves, plus the machine's tool
change and re-orientation times.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..machine.timing import path_time
from ..pathing.dropcutter import SAFE_ABOVE, StockClearance, verified_path
from ..pathing.dropcutter import drop_refined
from ..pathing.verify import DEFAULT_STEP, StockCheck
from ..tolerances import HOLDER_CLEARANCE, STOCK_ALLOWANCE
from ..toolpath.linking import link_passes, simplify_polyline
from ..toolpath.model import Toolpath
from ..pathing.zigzag import SurfaceSetup, frame_rotation

UP = (0.0, 0.0, 1.0)
MIN_COVERAGE = 0.9  # a zone machined over less than this fraction of its cells is not machined
KEEP_COVERAGE = 0.5  # ... and below this fraction its passes are left out of the tool path
UNCOVERED_PENALTY = 10.0  # plans compare by their time raised by this times the share of cells not machined
# what the zones' rapids keep clear of: the finishing allowance earlier operations left
STOCK = StockCheck(allowance=STOCK_ALLOWANCE, clearance=HOLDER_CLEARANCE)


@dataclass(frozen=True)
class ZonePlan:
    """How one zone is machined: cutter index, feed azimuth ``theta`` (rad, in the machining
    frame's XY) and unit tool ``axis (3,)`` in the part frame (+Z: 3-axis)."""

    tool: int
    theta: float
    axis: tuple = UP


@dataclass
class ZoneResult:
    """One machined zone: its ``plan``, ``toolpath`` (part frame, linked), times from
    :func:`path_time` (``time``), ``planes``, ``coverage`` (see
    :meth:`~meshmill.pathing.zigzag.ZonePasses.coverage`) and the feed moves left out."""

    zone: int
    plan: ZonePlan
    toolpath: Toolpath
    time: dict
    planes: int
    coverage: float
    moves_left_out: int = 0

    @property
    def ok(self) -> bool:
        """The zone is machined: it has passes and ``MIN_COVERAGE`` of its cells."""
        return self.planes > 0 and self.coverage >= MIN_COVERAGE  # feed moves dropped because they failed verification (tool lifts over)


@dataclass
class PlanResult:
    """All zones in machining order, the whole tool path (zones joined by rapid transits; zones
    whose passes reach under ``KEEP_COVERAGE`` of their cells are not in it), ``total_s``: the
    path's time plus the tool changes and re-orientations, and ``covered``: the fraction of the
    zones' cells machined (each zone's coverage weighted by its cells)."""

    zones: list
    toolpath: Toolpath
    total_s: float
    tool_changes: int
    reorientations: int
    covered: float

    @property
    def score(self) -> float:
        """What plans are compared by: ``total_s`` raised by ``UNCOVERED_PENALTY`` times the
        share of cells left unmachined, so no plan trades surface for time."""
        return self.total_s * (1.0 + UNCOVERED_PENALTY * (1.0 - self.covered))

    @property
    def incomplete(self) -> list:
        """Zones that are not machined (see :attr:`ZoneResult.ok`)."""
        return [r for r in self.zones if not r.ok]


class Machinist:
    """Evaluates plans on one surface: ``smesh`` (:class:`~meshmill.geometry.patches.SurfaceMesh`),
    ``samples`` (:class:`~meshmill.geometry.patches.Samples`, the zoning grid), candidate
    ``tools``, ``scallop`` mm, ``machine`` (:class:`~meshmill.machine.model.Machine`), drop
    spacing ``sample`` mm. Setups (BVH per cutter and axis) are cached."""

    def __init__(self, smesh, samples, tools, scallop, machine, sample=0.5, device="cpu"):
        self.smesh, self.samples, self.tools = smesh, samples, tools
        self.scallop, self.machine, self.sample, self.device = scallop, machine, sample, device
        self._setups, self._zones = {}, {}
        self.runs = 0  # zone zigzags computed (cache misses)
        # cells reach this far beyond their sample: half the longest cell side
        g = samples.points.reshape(*samples.grid_shape, 3)
        sides = [np.linalg.norm(np.diff(g, axis=a), axis=2).max() for a in (0, 1) if g.shape[a] > 1]
        self.cell_margin = 0.5 * max(sides, default=0.0)
        lo, hi = smesh.mesh.bounds
        reach = max(t.reach for t in tools)
        # 3+2 transits run outside this sphere, where no pose of any tool reaches the part
        self.centre = 0.5 * (lo + hi)
        self.clear_radius = 0.5 * float(np.linalg.norm(hi - lo)) + SAFE_ABOVE + reach

    def setup(self, tool: int, axis) -> SurfaceSetup:
        key = (tool, tuple(np.round(axis, 12)))
        if key not in self._setups:
            if len(self._setups) > 64:
                self._setups.clear()
            self._setups[key] = SurfaceSetup(self.smesh, self.samples.grid_shape, self.tools[tool],
                                             frame_rotation(axis), self.device)
        return self._setups[key]

    def zone(self, zones, zone: int, plan: ZonePlan) -> ZoneResult:
        """Machine zone ``zone`` of ``zones (n_cells,)`` with ``plan`` (results are cached)."""
        key = (hash(zones.tobytes()), zone, plan)
        if key not in self._zones:
            if len(self._zones) > 512:
                self._zones.clear()
            self._zones[key] = self._zone(zones, zone, plan)
        return self._zones[key]

    def _zone(self, zones, zone, plan, tol=None):
        st = self.setup(plan.tool, plan.axis)
        inside = zones == zone
        self.runs += 1
        zp = st.zone_passes(inside, self.samples.points, self.samples.normals, plan.theta, self.scallop, self.sample,
                            self.cell_margin)
        passes = zp.passes
        if tol is not None and passes:
            # chords between drops leave the surface by at most tol/2; moves that still gouge (steep
            # walls) are left out, the tool lifting over them
            passes = [simplify_polyline(drop_refined(p[:, :2], st.drop, 0.5 * tol, self.sample / 64), 0.5 * tol)
                      for p in passes]
            tp, report, passes = verified_path(passes, plan.tool, self.tools, st.kern, st.top + SAFE_ABOVE, tol,
                                               DEFAULT_STEP, STOCK)
            left_out = report["moves_left_out"]
        elif passes:
            left_out = 0
            clear = StockClearance(self.tools[plan.tool], st.kern, st.floor, STOCK)
            tp = link_passes(passes, plan.tool, st.top + SAFE_ABOVE, clear(np.array([p[0, :2] for p in passes])),
                             clear(np.array([p[-1, :2] for p in passes])))
        else:
            left_out = 0
            tp = Toolpath.concatenate([])
        time = path_time(tp.tip, tp.rapid, self.machine)
        coverage = zp.coverage(self.samples.points[inside] @ st.rotation.T)
        # back to the part frame
        tp = Toolpath(tp.tip @ st.rotation, np.tile(np.asarray(plan.axis, float), (len(tp), 1)), tp.rapid, tp.tool)
        return ZoneResult(zone, plan, tp, time, len(zp.spacings), coverage, left_out)

    def plan(self, zones, plans: dict, tol=None) -> PlanResult:
        """Machine every zone ``z: ZonePlan`` of ``plans`` on ``zones (n_cells,)``; with ``tol``
        (mm), the passes are refined where the chord between drops leaves the surface by more
        than tol/2 (the tool path to write; not cached)."""
        order = sorted(plans, key=lambda z: (plans[z].tool, tuple(np.round(plans[z].axis, 9)), z))
        results = [self.zone(zones, z, plans[z]) if tol is None else self._zone(zones, z, plans[z], tol)
                   for z in order]
        cut = [r for r in results if len(r.toolpath) and r.coverage >= KEEP_COVERAGE]
        cells = np.array([int((zones == r.zone).sum()) for r in results], float)
        covered = float((cells * [r.coverage if r in cut else 0.0 for r in results]).sum() / max(cells.sum(), 1.0))
        changes = sum(a.plan.tool != b.plan.tool for a, b in zip(cut, cut[1:]))
        turns = sum(not np.allclose(a.plan.axis, b.plan.axis) for a, b in zip(cut, cut[1:]))
        parts = [r.toolpath for r in cut[:1]]
        for a, b in zip(cut, cut[1:]):
            parts += [self.transit(a.toolpath, b.toolpath), b.toolpath]
        tp = Toolpath.concatenate(parts)
        total = path_time(tp.tip, tp.rapid, self.machine)["total_s"] if len(tp) else 0.0
        total += changes * self.machine.tool_change + turns * self.machine.reorient
        return PlanResult(results, tp, total, changes, turns, covered)

    def transit(self, a: Toolpath, b: Toolpath) -> Toolpath:
        """Rapid moves from the end of ``a`` to the start of ``b`` (both begin and end retracted):
        straight when the tool axis stays; else out along a's axis to the plane that touches the
        clearance sphere from above, across that plane (the axis turning), and in along b's axis.
        Every pose off the straight case is outside the sphere, where no tool reaches the part.
        The first row repeats the end of ``a`` (a zero move, so that the rows time as moves)."""
        p, q, ax, bx = a.tip[-1], b.tip[0], a.axis[-1], b.axis[0]
        if np.allclose(ax, bx):
            tips, axes = [p, q], [ax, bx]
        else:
            tips = [p, self._out(p, ax), self._out(q, bx), q]
            axes = [ax, ax, bx, bx]
        n = len(tips)
        return Toolpath(np.array(tips), np.array(axes), np.ones(n, bool), np.full(n, b.tool[0], np.int64))

    def _out(self, point, axis):
        """From ``point`` along ``axis`` (pointing up: a 3+2 axis is accessible from above) to
        the plane over the clearance sphere; past the sphere, then straight up, when the axis is
        nearly horizontal."""
        top = self.centre[2] + self.clear_radius
        d = point - self.centre
        b = float(d @ axis)
        leave = point + max(-b + np.sqrt(max(b * b - (d @ d - self.clear_radius**2), 0.0)), 0.0) * axis
        if axis[2] > 0.05:
            return point + max((top - point[2]) / axis[2], float((leave - point) @ axis)) * axis
        return np.array([leave[0], leave[1], max(top, leave[2])])
