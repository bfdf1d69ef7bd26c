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
   choice when that is free and no more than one step more tilted. The flutes keep within half the
   tolerance (verification lets them in by all of it between poses) and the shank and holder keep
   ``clearance``; from a stock, a point whose shank or holder enters it takes
   the first candidate free of the stock too (:func:`stock_free_axes`). Points without a free
   axis are left out with a lift.
4. Passes with lead-in/out along the outward side and retracts along the tool axis (or vertically)
   to the safe plane, ordered by contour or grouped by tool.
5. The finished path is verified (:mod:`meshmill.pathing.verify`); moves that fail are repaired by
   splitting passes or changing the link, and whatever cannot be repaired is left out. The path
   written is the verified one.

:func:`finish` runs these as stages, each a function here that takes and returns explicit state
(lengths in mm): :func:`finish_setup` (the balls, the safe plane, the levels), :func:`contours`
(1), :func:`point_balls` (2, with :mod:`~meshmill.ops.finish_balls`), :func:`tool_axes` and
:func:`stock_free_axes` (3),
:func:`~meshmill.ops.finish_shallow.shallow_fill` (``scallop``'s flat areas),
:func:`cutting_passes` (4, moves by :class:`~meshmill.ops.finish_path.PathBuilder`, kept from the
rotaries' pole by :mod:`~meshmill.ops.finish_pole`), :func:`verify_and_repair` (5) and
:func:`finish_summary` (the surface cut and why not, :mod:`~meshmill.ops.finish_areas`).
"""
from __future__ import annotations

import dataclasses
import functools
import math
import time
from dataclasses import dataclass

import numba
import numpy as np

from ..progress import PIECES, Meter, StageClock, ranges
from ..errors import InputError, NothingToCut
from ..geometry.mesh import Mesh
from ..geometry.slicing import concat_contours, contour_runs, slice_contours, z_levels
from ..kernels.backend import solid_kernels
from ..params import FinishParams
from ..simulation.stock import Stock
from ..tolerances import FLOAT32_ROUNDING, WRITE_ROUNDING
from ..tools.table import pack_cylinders
from ..toolpath.model import Toolpath
from .finish_areas import surface_areas
from .finish_balls import balls_piece, contour_balls, largest_balls, run_balls, smaller_balls
from .finish_levels import added_contours
from .finish_path import NO_LEAD, PathBuilder, merged_points, pass_points, repair_passes
from .finish_shallow import SCALLOP_MIN_SLOPE, shallow_fill
from ..pathing.reverify import Reverify
from ..pathing.verify import (DEFAULT_STEP, StockCheck, body_in_stock, check_parts, path_pieces, rapid_reach,
                              rapids_clear, verify_piece)

REPAIR_ROUNDS = 7
MERGE_SHARE = 0.5  # a pass's points are merged where the move between the ones kept passes within this share of the tolerance
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


@dataclass
class ContourWork:
    """Where the per-point searches of the contours run: here through the part's kernels ``kern``
    (``part`` bound to them), or, with a ``cluster`` (a ``distributed.Client``), on its workers,
    which bind ``part`` on ``device`` themselves; ``say`` is told the share done."""

    kern: object
    part: Mesh
    device: str = "cpu"
    cluster: object = None
    say: object = None

    def by_contours(self, offsets, arrays, local, remote, shared: dict, what: str) -> np.ndarray:
        """``(k,) int64`` of a per-point search done by groups of contours (each point or contour
        on its own: the same result however grouped): ``local(piece)`` here, or ``remote(shared +
        part and device, piece)`` on the cluster's workers; pieces of :func:`_contour_groups`."""
        say = self.say or (lambda stage: None)
        if self.cluster is not None:
            from ..cluster import PIECES_PER_WORKER, run_pieces, workers

            pieces = _contour_groups(offsets, PIECES_PER_WORKER * workers(self.cluster), *arrays)
            out = run_pieces(self.cluster, remote, dict(part=self.part, device=self.device, **shared), pieces, say,
                             what)
        else:
            meter, out = Meter(say, what, offsets[-1]), []
            for piece in _contour_groups(offsets, PIECES, *arrays):
                out.append(local(piece))
                meter.done(len(piece[0]))
        return np.concatenate([np.zeros(0, np.int64), *out])


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
                                         device=device, bad_depths=False))

    def __call__(self, tp, only):
        from ..cluster import PIECES_PER_WORKER, submit, wait, workers

        pieces = path_pieces(tp, PIECES_PER_WORKER * workers(self.client), only)
        futures = [submit(self.client, verify_piece, self.handle, p) for p in pieces]
        wait(futures, self.say, "verify")
        return self.client.gather(futures)


# --- the stages ------------------------------------------------------------------------------------

@dataclass
class FinishSetup:
    """What a finish works with: ``params`` as kept (the tolerance less what writing the path and
    the part's float32 vertices move points, the clearance plus the stock's margin; ``tolerance``
    mm: the one asked); ``stock`` (a closed mesh the finish starts from, or None) and
    ``allowance`` mm on the design otherwise; ``balls`` the ball tools, largest first, and their
    ``radii (b,)`` mm; ``levels (L,)`` the contours' Z mm from the top down; ``safe_z`` mm; the
    part's ``zmin``, ``zmax`` mm."""

    params: FinishParams
    tolerance: float
    stock: Mesh | None
    allowance: float
    balls: list
    radii: np.ndarray
    levels: np.ndarray
    safe_z: float
    zmin: float
    zmax: float

    @property
    def stock_allowance(self) -> float:
        """mm of material on the design that the finish starts from (0 where a stock mesh is given)."""
        return 0.0 if self.stock is not None else self.allowance

    @property
    def body_clearance(self) -> float:
        """mm the shank and holder keep from the part: the clearance, and out of the allowance."""
        return max(self.params.clearance, self.stock_allowance)

    def stock_check(self, device: str = "cpu") -> StockCheck:
        """What rapids keep the clearance from (and shanks and holders stay out of): the stock
        mesh, bound on ``device``, and the allowance."""
        kern = solid_kernels(self.stock, device) if self.stock is not None else None
        return StockCheck(allowance=self.stock_allowance, kern=kern, clearance=self.params.clearance)


def finish_setup(mesh: Mesh, tools, params: FinishParams) -> FinishSetup:
    """The :class:`FinishSetup` of ``mesh`` with the tool table ``tools``: InputError without a
    ball tool or with a ``safe_z`` that a tilted ball under the stock's top would not clear;
    NothingToCut where ``step_down`` leaves no level."""
    stock, allowance, margin = Stock.of(params.stock, "offset").material(mesh)
    # kept under the tolerance by what writing the path and the part moves them (the files verify)
    tolerance = params.tolerance
    params = dataclasses.replace(params, tolerance=max(0.0, tolerance - WRITE_ROUNDING - FLOAT32_ROUNDING *
                                                       float(np.abs(mesh.bounds).max())),
                                 clearance=params.clearance + margin)
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
    return FinishSetup(params, tolerance, stock, allowance, balls, radii, levels, safe_z, zmin, zmax)


def contours(mesh: Mesh, kern, setup: FinishSetup):
    """``(contours, scallop)``: the CC points (:class:`~meshmill.geometry.slicing.Contours`: ``(n,
    3)`` mm points, outward normals, feed directions) of the planes ``setup.levels``, ``sample``
    mm apart and the normal turning at most :data:`MAX_ARC_STEP` (and a sample over the largest
    radius) between them at a convex edge; with ``scallop``, the levels put in between where the
    slope needs them (:func:`~meshmill.ops.finish_levels.added_contours`, ``scallop`` its report;
    else None)."""
    params, radii = setup.params, setup.radii
    arc_step = min(params.sample / radii.max(), MAX_ARC_STEP)
    con = slice_contours(mesh, setup.levels, params.sample, arc_step)
    if params.scallop is None:
        return con, None

    def piece_tools(c):
        cd = c.normals * c.reach[:, None]
        return run_balls(largest_balls(kern, c.points, c.reach, cd, radii, params.tolerance), c, cd, radii, params,
                         kern)[0]

    added, scallop = added_contours(mesh, setup.levels, setup.zmin, setup.zmax, radii, params.scallop, params.sample,
                                    arc_step, piece_tools, SCALLOP_MIN_SLOPE)
    return concat_contours([con, *added]), scallop


@dataclass
class Balls:
    """The ball of each of n CC points: ``centre_dir (n, 3)`` (the ball's centre is CC + R
    centre_dir), ``best (n,)`` the largest ball that fits at the point alone and ``point_tool
    (n,)`` the one its run (or, ``whole_contours``, its contour) takes (ranks into the radii,
    largest first; -1: none); ``short_runs`` runs left out as shorter than ``min_run``, holding
    ``short_points`` points."""

    centre_dir: np.ndarray
    best: np.ndarray
    point_tool: np.ndarray
    short_runs: int = 0
    short_points: int = 0


def point_balls(con, setup: FinishSetup, work: ContourWork) -> Balls:
    """The :class:`Balls` of the CC points ``con``: per point the largest ball of ``setup.radii``
    whose sphere does not enter the part by more than the tolerance (:func:`largest_balls`), then
    per run the balls of :func:`run_balls` (``whole_contours``: per contour,
    :func:`contour_balls`)."""
    params, radii, kern = setup.params, setup.radii, work.kern
    centre_dir = con.normals * con.reach[:, None]  # ball centre = CC + R·centre_dir
    best = work.by_contours(con.offsets, (con.points, con.reach, centre_dir),
                            lambda p: largest_balls(kern, *p[:3], radii, params.tolerance), balls_piece,
                            dict(radii=radii, tol=params.tolerance), "tools")
    if params.whole_contours:
        contour_tool = contour_balls(best, con.offsets, con.contour_of, con.points, centre_dir, radii,
                                      params.tolerance, kern)
        return Balls(centre_dir, best, contour_tool[con.contour_of])
    return Balls(centre_dir, best, *run_balls(best, con, centre_dir, radii, params, kern))


@dataclass
class Poses:
    """The tool at each of n CC points (c contours): ``point_tool (n,)`` its ball (rank; -1: not
    cut), ``choice (n,)`` its axis candidate (:func:`tilt_candidates`; -1: no free axis),
    ``contour_tool (c,)`` the smallest ball on each contour (-1: none), ``side (n, 3)`` the unit
    outward side (feed x +Z), and the ball's centre ``ce``, unit ``axis`` and ``tip`` (n, 3) mm;
    ``fallback``: points that found an axis on a smaller ball than their run's; ``out_of_stock``:
    points tilted again to keep the shank and holder out of the stock (:func:`stock_free_axes`)."""

    point_tool: np.ndarray
    choice: np.ndarray
    contour_tool: np.ndarray
    side: np.ndarray
    ce: np.ndarray
    axis: np.ndarray
    tip: np.ndarray
    fallback: int
    out_of_stock: int = 0  # points whose axis was tilted again to keep shank and holder out of the stock

    @property
    def has_axis(self) -> np.ndarray:
        return self.choice >= 0


def axis_cylinders(setup: FinishSetup) -> tuple:
    """The ``(t0, t1, r)`` (T, K) arrays of the parts an axis must keep clear for the balls of
    ``setup``: the flutes within half the tolerance (radius R - tol/2), the shank and holder
    ``setup.body_clearance`` from the part. Verification lets the flutes in by the tolerance
    between two poses; a pass whose poses put them in by almost all of it (the least tilted
    candidate free, kept along the contour while free) has its turning moves halved until the turn
    comes within what is left (the impeller of bench/certify.py: poses refined 78 230 -> 47 589,
    its verification 9.2 -> 8.1 s; the same surface cut)."""
    return pack_cylinders(setup.balls, 0.5 * setup.params.tolerance, setup.body_clearance)[0]


def tool_axes(con, balls: Balls, setup: FinishSetup, work: ContourWork) -> Poses:
    """The :class:`Poses` of the CC points ``con`` with their ``balls``: per point the first
    collision-free axis of :func:`tilt_candidates` (:func:`axis_cylinders`: the flutes within half
    the tolerance, shank and holder ``setup.body_clearance`` from the part; the predecessor's when
    free and at most a step more tilted); a point without one tries the smaller balls (not with
    ``whole_contours``)."""
    params, radii, kern = setup.params, setup.radii, work.kern
    side = np.cross(con.feed, [0.0, 0.0, 1.0])
    cand, cand_tilt = tilt_candidates(params.max_tilt, params.tilt_step)
    body = axis_cylinders(setup)
    slack = math.radians(params.tilt_step) + 1e-9
    point_tool = balls.point_tool
    centres = con.points + radii[np.maximum(point_tool, 0)][:, None] * balls.centre_dir
    choice = work.by_contours(con.offsets, (centres, con.feed, side, point_tool),
                              lambda p: kern.axis_search(*p[:4], cand, cand_tilt, slack, radii, body, p[4]), axis_piece,
                              dict(cand=cand, cand_tilt=cand_tilt, slack=slack, radii=radii, body=body), "axes")
    fallback = 0
    if not params.whole_contours:  # no free axis for the run's ball: a smaller one, with a thinner shank
        point_tool, choice, fallback = smaller_balls(point_tool, choice, con, balls.centre_dir, side, radii, params,
                                                      kern, cand, cand_tilt, slack, body)
    contour_tool = np.full(len(con), -1, np.int64)
    if len(con.points):
        np.maximum.at(contour_tool, con.contour_of, point_tool)  # the smallest ball on it
    has_axis = choice >= 0
    ce = con.points + radii[np.maximum(point_tool, 0)][:, None] * balls.centre_dir
    axis = np.zeros_like(ce)
    axis[has_axis] = _axes(cand, choice[has_axis], con.feed[has_axis], side[has_axis])
    tip = ce - radii[np.maximum(point_tool, 0)][:, None] * axis
    return Poses(point_tool, choice, contour_tool, side, ce, axis, tip, fallback)


def stock_free_axes(con, poses: Poses, setup: FinishSetup, kern, tools, stock: StockCheck) -> int:
    """Points whose axis (of :func:`tool_axes`, free of the part) puts the shank or holder into the
    stock the finish starts from (as verification measures it,
    :func:`~meshmill.pathing.verify.body_in_stock`) take the first candidate of
    :func:`tilt_candidates` that is free of both (the part as :func:`tool_axes` tests it); ``poses``
    is changed in place. Returns how many points changed. Without it, the passes of a finish
    from an in-process stock lose those points in verification."""
    params, radii = setup.params, setup.radii
    table_index = {tool.number: i for i, tool in enumerate(tools)}
    rank_tool = np.array([table_index[b.number] for b in setup.balls])
    at = np.nonzero(poses.has_axis & (poses.point_tool >= 0))[0]
    if not len(at):
        return 0
    deep = body_in_stock(kern, tools, params.tolerance, stock, poses.tip[at], poses.axis[at],
                         rank_tool[poses.point_tool[at]]) > 0.0
    bad = at[deep]
    if not len(bad):
        return 0
    cand, cand_tilt = tilt_candidates(params.max_tilt, params.tilt_step)
    body = axis_cylinders(setup)
    side, rank, ce = poses.side[bad], poses.point_tool[bad], poses.ce[bad]
    found = np.full(len(bad), -1, np.int64)
    for c in range(len(cand)):
        todo = np.nonzero(found < 0)[0]
        if not len(todo):
            break
        free = kern.axis_search(ce[todo], con.feed[bad[todo]], side[todo], rank[todo], cand[c:c + 1],
                                cand_tilt[c:c + 1], 0.0, radii, body, np.array([0, len(todo)])) >= 0
        todo = todo[free]
        if not len(todo):
            continue
        axis = _axes(cand, np.full(len(todo), c), con.feed[bad[todo]], side[todo])
        tip = ce[todo] - radii[rank[todo]][:, None] * axis
        out = body_in_stock(kern, tools, params.tolerance, stock, tip, axis, rank_tool[rank[todo]]) <= 0.0
        found[todo[out]] = c
    moved = bad[found >= 0]
    c = found[found >= 0]
    poses.choice[moved] = c
    poses.axis[moved] = _axes(cand, c, con.feed[moved], poses.side[moved])
    poses.tip[moved] = poses.ce[moved] - radii[poses.point_tool[moved]][:, None] * poses.axis[moved]
    return len(moved)


@dataclass
class Passes:
    """The passes of a finish and the points they index. ``passes``: dicts with ``contour``, the
    ``tool`` (index into the tool table) and its ``rank``, ``idx`` (the pass's points in order),
    ``entry``, ``exit`` and ``first_link`` (into :data:`~meshmill.ops.finish_path.LINKS`), ``shallow`` (a raster pass);
    ``tip``, ``axis``, ``ce``, ``side`` (m, 3) mm: the n CC points' poses, then the points put in
    where a pass meets a larger ball's, then ``n_raster`` raster tips from ``raster_first``."""

    passes: list
    tip: np.ndarray
    axis: np.ndarray
    ce: np.ndarray
    side: np.ndarray
    raster_first: int
    n_raster: int


def cutting_passes(con, balls: Balls, poses: Poses, shallow, setup: FinishSetup, tools) -> Passes:
    """The :class:`Passes` along the runs of each contour that have a ball and an axis, one ball a
    pass (where the ball changes, the smaller ball's pass takes in the larger one's neighbouring
    point, so that the stretch between them is cut), then the raster passes of ``shallow``
    (:class:`~meshmill.ops.finish_shallow.ShallowPasses` or None), ordered by contour or, with
    ``order = "tool"``, by ball; NothingToCut where there is none."""
    params, radii = setup.params, setup.radii
    table_index = {tool.number: i for i, tool in enumerate(tools)}
    point_tool, has_axis = poses.point_tool, poses.has_axis
    tip, axis, ce, side = poses.tip, poses.axis, poses.ce, poses.side
    passes, bridge = [], []  # bridge: (CC point, axis, rank) of points put in where a pass meets a larger ball's
    for c in range(len(con)):
        a, b = con.offsets[c], con.offsets[c + 1]
        for run in contour_runs(has_axis[a:b] & (point_tool[a:b] >= 0), bool(con.closed[c])):
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
                passes.append(dict(contour=c, tool=table_index[setup.balls[rank].number], rank=rank,
                                   idx=idx.astype(np.int64), entry=link, exit=link, first_link=link, shallow=False))
    if bridge:
        cc, ax, rk = (np.array(x) for x in zip(*bridge))
        r = radii[rk][:, None]
        bce = con.points[cc] + r * balls.centre_dir[cc]
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
            passes.append(dict(contour=len(con) + k, tool=table_index[setup.balls[r].number], rank=r,
                               idx=first + np.arange(size), entry=NO_LEAD, exit=NO_LEAD, first_link=NO_LEAD,
                               shallow=True))
            first += size
    if not passes:
        raise NothingToCut(f"nothing to cut: of {len(con)} contour(s), {int((poses.contour_tool >= 0).sum())} fit a "
                           f"ball of the table (smallest R {min(radii):g} mm) and none has a collision-free axis "
                           f"within max_tilt {params.max_tilt:g}; add smaller or longer tools", "max_tilt")
    reach = np.array([t.reach for t in tools])
    if params.order == "tool":
        passes.sort(key=lambda p: (p["rank"], p["shallow"], p["contour"]))
        passes = short_order(passes, tip, axis, reach)
    near_starts(passes, tip)
    passes = merged_points(passes, tip, axis, reach, MERGE_SHARE * params.tolerance)
    return Passes(passes, tip, axis, ce, side, raster_first, n_raster)


LOOP_SAMPLES = 32  # points of a closed contour the next pass's start is looked for among


def short_order(passes: list, tip, axis, reach) -> list:
    """``passes`` (sorted by tool, raster or not, then contour) with each tool's contour passes
    taken in a short order: from the first, always the pass whose start lies nearest the end of
    the one before (a closed contour anywhere along it, as :func:`near_starts` then starts it),
    the distance being the tip's plus the tool's ``reach (T,)`` times the axis's turn (rad) from
    ``tip``, ``axis (n, 3)``. Passes on both sides of a thin wall are then taken side by side,
    level after level, not crossing over at every level. Where that walk is no shorter in sum,
    the contour order stays. Raster passes keep their order."""
    out, k = [], 0
    while k < len(passes):
        j = k
        while j < len(passes) and (passes[j]["tool"], passes[j]["shallow"]) == (passes[k]["tool"], passes[k]["shallow"]):
            j += 1
        group = passes[k:j]
        k = j
        if group[0]["shallow"] or len(group) < 3:
            out += group
            continue
        pts, owner = [], []
        for g, ps in enumerate(group):
            idx = ps["idx"]
            if len(idx) >= 3 and idx[0] == idx[-1]:  # a whole closed contour: any of its points
                idx = idx[:-1][np.linspace(0, len(idx) - 2, min(LOOP_SAMPLES, len(idx) - 1)).astype(np.int64)]
            else:
                idx = idx[:1]
            pts.append(idx)
            owner.append(np.full(len(idx), g))
        pts, owner = np.concatenate(pts), np.concatenate(owner)
        ends = np.array([ps["idx"][-1] for ps in group])
        order, total, before = _greedy_walk(tip[pts], axis[pts], owner, tip[ends], axis[ends],
                                            float(reach[group[0]["tool"]]))
        # the contour order where it is as short (the greedy walk is not always shorter)
        out += [group[g] for g in order] if total < before else group
    return out


@numba.njit(cache=True)
def _greedy_walk(at_tip, at_axis, owner, end_tip, end_axis, r):
    """The walk of :func:`short_order` over one tool's passes: ``(order (G,), its cost, the cost of
    the contour order)``. ``at_tip``, ``at_axis (P, 3)``: the points a pass may start at, of pass
    ``owner (P,)``; ``end_tip``, ``end_axis (G, 3)``: each pass's last point; the cost of a link is
    the tip's distance plus ``r`` times the axis's turn (rad). The turn is worked out only where the
    distance alone is below the best so far (it only adds)."""
    n = len(end_tip)
    left = np.ones(n, np.bool_)
    left[0] = False
    order = np.zeros(n, np.int64)
    g, total = 0, 0.0
    for step in range(1, n):
        best, at = np.inf, -1
        for p in range(len(owner)):
            if not left[owner[p]]:
                continue
            cost = _link_cost(at_tip[p], at_axis[p], end_tip[g], end_axis[g], r, best)
            if cost < best:
                best, at = cost, p
        total += best
        g = owner[at]
        left[g] = False
        order[step] = g
    before = 0.0
    for g in range(n - 1):
        best = np.inf
        for p in range(len(owner)):
            if owner[p] == g + 1:
                best = min(best, _link_cost(at_tip[p], at_axis[p], end_tip[g], end_axis[g], r, best))
        before += best
    return order, total, before


@numba.njit(cache=True, inline="always")
def _link_cost(p, a, q, b, r, best):
    """The distance from tip ``q`` to ``p`` plus ``r`` times the angle between axes ``a`` and ``b``;
    any value at or above ``best`` once the distance alone reaches it."""
    d = math.sqrt((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2)
    if d >= best:
        return d
    c = min(1.0, max(-1.0, a[0] * b[0] + a[1] * b[1] + a[2] * b[2]))
    return d + r * math.acos(c)


def near_starts(passes: list, tip) -> None:
    """Each pass that is a whole closed contour (its first point repeated last) starts, in place,
    at its point nearest the end of the pass before of the same tool (``tip (n, 3)``): the link
    between them is short."""
    for before, ps in zip(passes[:-1], passes[1:]):
        idx = ps["idx"]
        if ps["tool"] != before["tool"] or len(idx) < 3 or idx[0] != idx[-1]:
            continue
        loop = idx[:-1]
        s = int(np.argmin(np.linalg.norm(tip[loop] - tip[before["idx"][-1]], axis=1)))
        ps["idx"] = np.r_[loop[s:], loop[:s + 1]]


def path_builder(cut: Passes, setup: FinishSetup, tools, kern, rapid_stock: StockCheck, machine=None) -> PathBuilder:
    """The :class:`~meshmill.ops.finish_path.PathBuilder` of the points of ``cut``: rapids stop the
    allowance, clearance and tolerance above a lead's end (with a stock mesh, where the stock
    begins: :func:`~meshmill.pathing.verify.rapid_reach` through the part's ``kern``); for a 5-axis
    ``machine``, C turns gently near the pole of its rotaries."""
    params = setup.params
    gentle = machine.chain.singular if machine is not None and machine.chain.type != "3-axis" else None
    reach = None if setup.stock is None else functools.partial(rapid_reach, kern, tools, params.tolerance, rapid_stock)
    check = functools.partial(rapids_clear, kern, tools, params.tolerance, rapid_stock,
                              step=min(DEFAULT_STEP, params.sample))
    return PathBuilder(cut.tip, cut.axis, cut.side, setup.safe_z, params.lead,
                       approach=rapid_stock.allowance + rapid_stock.clearance + params.tolerance,
                       radius=np.array([t.radius for t in tools]), gentle=gentle, reach=reach, check=check,
                       direct=params.links != "safe")


def path_check(mesh: Mesh, kern, setup: FinishSetup, tools, rapid_stock: StockCheck, device="cpu", cluster=None,
               say=None) -> Reverify:
    """The check of each version of a finish's path (:class:`~meshmill.pathing.reverify.Reverify`:
    a round of repairs checks only the moves it changed) within the kept tolerance, poses at most
    :data:`~meshmill.pathing.verify.DEFAULT_STEP` and ``sample`` apart, rapids against
    ``rapid_stock``: here through ``kern``, or in ranges of moves on the workers of ``cluster``
    (the same reports). A move found bad is not measured further (``bad_depths``): the repairs
    need only which moves fail, and a path left with problems reports each at the depth that
    found it, at least."""
    params = setup.params
    step = min(DEFAULT_STEP, params.sample)
    if cluster is not None:
        parts = _ClusterCheck(cluster, mesh, setup.stock, rapid_stock, tools, params.tolerance, step, device, say)
    else:
        def parts(path, only):
            return check_parts(kern, path, tools, params.tolerance, step, rapid_stock, only, progress=say,
                               bad_depths=False)
    return Reverify(parts, params.tolerance, step, rapid_stock.summary())


@dataclass
class Verified:
    """The verified finish: its ``path``, the verification ``report`` (with ``repair_rounds``),
    the ``passes`` kept (as repaired) and how many were ``dropped``."""

    path: Toolpath
    report: dict
    passes: list
    dropped: int


def verify_and_repair(passes: list, build, check, built=None) -> Verified:
    """The path of ``passes`` that passes its verification: ``build(passes)`` gives ``(toolpath,
    owner (k,), role (k,))`` (each move's pass and part in it, :meth:`PathBuilder.build`;
    ``built``: that of ``passes``, already built),
    ``check(toolpath)`` its report (:func:`~meshmill.pathing.verify.merge_reports`, with
    ``problem_moves``). Up to :data:`REPAIR_ROUNDS` rounds of :func:`repair_passes` change the passes
    that own the failing moves; then the passes that still fail are left out. NothingToCut when
    no pass is left."""
    dropped = 0
    for rnd in range(REPAIR_ROUNDS + 1):
        tp, owner, role = built if rnd == 0 and built is not None else build(passes)
        report = check(tp)
        if report["ok"] or not passes:
            break
        if rnd == REPAIR_ROUNDS:  # give up on what still fails
            bad = {owner[m] for m in report["problem_moves"]}
            dropped += len(bad)
            passes = [p for k, p in enumerate(passes) if k not in bad]
            tp, owner, role = build(passes)
            report = check(tp)
            break
        passes, lost = repair_passes(passes, report["problem_moves"], owner, role)
        dropped += lost
    report.pop("problem_moves")
    report["repair_rounds"] = rnd
    if not passes:
        raise NothingToCut("nothing left to cut: every pass failed verification (try lead 0, a larger max_tilt or "
                           "other tools)", ("lead", "max_tilt"))
    return Verified(tp, report, passes, dropped)


def _point_status(con, balls: Balls, poses: Poses, cut: Passes, shallow, passes: list):
    """``(cut (n,), raster_cut (n_raster,), points (s, 3), status (s,))``: which CC points and
    raster tips the ``passes`` cut, and the status (index into
    :data:`~meshmill.ops.finish_areas.AREA_STATUS`) of the CC points, then of the raster's contacts
    (each its pass's: cut, or left out)."""
    npts = len(con.points)
    cut_all = np.zeros(len(cut.tip), bool)
    for ps in passes:
        cut_all[pass_points(ps)] = True
    point_cut = cut_all[:npts]  # (the bridges and the raster's tips are no CC points)
    raster_cut = cut_all[cut.raster_first:cut.raster_first + cut.n_raster]
    status = np.select([point_cut, balls.best < 0, poses.point_tool < 0, ~poses.has_axis], [0, 1, 3, 2], 4)
    if cut.n_raster:  # every contact of a raster pass takes the pass's status
        contacts = np.concatenate(shallow.contacts)
        pass_cut = np.add.reduceat(raster_cut, np.r_[0, np.cumsum([len(t) for t in shallow.tips])[:-1]]) > 0
        contact_status = np.repeat(np.where(pass_cut, 0, 4), [len(c) for c in shallow.contacts])
    else:
        contacts, contact_status = np.zeros((0, 3)), np.zeros(0, np.int64)
    return point_cut, raster_cut, np.vstack([con.points, contacts]), np.r_[status, contact_status].astype(np.int64)


def _tools_used(tools, passes: list, npts: int) -> dict:
    """Per tool name: its ``passes``, the CC points (``cc_points``) and ``contours`` they cut, and
    its ``raster_points``."""
    used = {}
    for ps in passes:
        points = pass_points(ps)
        entry = used.setdefault(tools[ps["tool"]].name, {"passes": 0, "cc_points": 0, "contours": set(),
                                                         "raster_points": 0})
        entry["passes"] += 1
        if ps["shallow"]:
            entry["raster_points"] += int(len(points))
        else:
            entry["cc_points"] += int(len(np.unique(points[points < npts])))
            entry["contours"].add(ps["contour"])
    for entry in used.values():
        entry["contours"] = len(entry["contours"])
    return used


def finish_summary(mesh: Mesh, kern, tools, setup: FinishSetup, con, scallop, balls: Balls, poses: Poses,
                   shallow, cut: Passes, done: Verified, stock: dict, pole) -> tuple[dict, dict]:
    """``(summary, detail)`` of a finish from its stages' results: the summary's figures (the
    surface's mm² by why it was or was not cut, :func:`surface_areas`), and per-point arrays for
    reports and tests. ``stock``: the rapids' :class:`~meshmill.pathing.verify.StockCheck` summary;
    ``pole``: what :func:`~meshmill.ops.finish_pole.gentle_turns` did (None without a 5-axis machine)."""
    params, radii, tp = setup.params, setup.radii, done.path
    npts = len(con.points)
    point_tool, fits = poses.point_tool, balls.best >= 0
    point_cut, raster_cut, points, point_status = _point_status(con, balls, poses, cut, shallow, done.passes)
    machinable = poses.contour_tool >= 0
    tilt = np.degrees(np.arccos(np.clip(cut.axis[:npts][point_cut, 2], -1, 1))) if point_cut.any() else np.zeros(0)
    feed_move = ~tp.rapid[1:] & (tp.tool[1:] == tp.tool[:-1])
    turn = np.einsum("ij,ij->i", tp.axis[1:], tp.axis[:-1])[feed_move]
    max_turn = float(np.degrees(np.arccos(np.clip(turn.min(), -1, 1)))) if len(turn) else 0.0
    raster_reach = shallow.spacing if shallow is not None else 0.0
    areas = surface_areas(mesh, kern, radii, params.tolerance, params.max_tilt, params.sample, points, point_status,
                          npts if shallow is not None else None, raster_reach)
    summary = {
        "operation": "finish",
        "step_down": params.step_down,
        "sample": params.sample,
        "max_tilt": params.max_tilt,
        "tilt_step": params.tilt_step,
        "order": params.order,
        "safe_z": setup.safe_z,
        "tolerance": setup.tolerance,
        "tolerance_kept": params.tolerance,
        "clearance": params.clearance,
        "stock": stock,
        "levels": int(len(np.unique(con.z))),
        "scallop": None if scallop is None else {**scallop, "shallow": shallow.report},
        "pole": pole,
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
        "runs_too_short": int(balls.short_runs),
        "points_in_short_runs": int(balls.short_points),
        "points_on_smaller_balls": int(poses.fallback),
        "points_tilted_out_of_stock": int(poses.out_of_stock),
        "points_left_out": int((point_tool >= 0).sum() - point_cut[point_tool >= 0].sum()),
        "points_cut": int(point_cut.sum()),
        "raster_points": int(cut.n_raster),
        "raster_points_cut": int(raster_cut.sum()),
        "area_mm2": areas,
        "points_tilted": int((tilt > 1e-6).sum()),
        "max_tilt_used": float(tilt.max()) if len(tilt) else 0.0,
        "max_axis_change": max_turn,
        "passes": len(done.passes),
        "passes_dropped": done.dropped,
        "moves": int(len(tp)),
        "cutting_length": tp.cutting_length(),
        "tools_used": _tools_used(tools, done.passes, npts),
        "verify": done.report,
    }
    detail = dict(surface_points=points, surface_status=point_status, raster_from=npts if shallow is not None else -1,
                  raster_reach=raster_reach, contours=con, best=balls.best, contour_tool=poses.contour_tool,
                  point_tool=point_tool, choice=poses.choice, axis=cut.axis[:npts], tip=cut.tip[:npts],
                  ce=cut.ce[:npts], cut=point_cut, balls=setup.balls, kern=kern, shallow=shallow)
    return summary, detail


def finish(mesh: Mesh, tools, params: FinishParams, progress=None, device: str = "cpu", machine=None, cluster=None):
    """Run the operation on ``device`` (``"cpu"`` or ``"cuda"``); returns ``(toolpath, summary, detail)``.

    ``tools``: the whole tool table (ball tools are used); ``progress(stage)`` is called as each
    stage starts; ``params.stock``: the material the finish starts from (a
    :class:`~meshmill.simulation.stock.Stock`; default the part with ``STOCK_ALLOWANCE`` on it),
    which rapids keep ``params.clearance`` from. ``detail`` holds per-point arrays for reports and
    tests. ``machine``: the 5-axis :class:`~meshmill.machine.model.Machine` the path is for: no
    move swings the axis past the pole of its rotaries
    (:func:`~meshmill.ops.finish_pole.gentle_turns`). The stages are the module's.
    """
    setup = finish_setup(mesh, tools, params)
    params = setup.params
    clock = StageClock(progress)
    t_all = time.perf_counter()
    with clock("index"):
        kern = solid_kernels(mesh, device)  # the solid the part bounds, on the device for every stage
        rapid_stock = setup.stock_check(device)
    work = ContourWork(kern, mesh, device, cluster, clock.say)
    with clock("contours"):
        con, scallop = contours(mesh, kern, setup)
    with clock("tools"):
        balls = point_balls(con, setup, work)
    with clock("axes"):
        poses = tool_axes(con, balls, setup, work)
        poses.out_of_stock = stock_free_axes(con, poses, setup, kern, tools, rapid_stock)
    shallow = None
    if params.scallop is not None:
        with clock("shallow areas", "shallow"):
            shallow = shallow_fill(mesh, kern, setup.balls, params.scallop, SCALLOP_MIN_SLOPE, params.sample,
                                   params.tolerance, setup.body_clearance, params.min_run)
    with clock("path"):
        cut = cutting_passes(con, balls, poses, shallow, setup, tools)
        builder = path_builder(cut, setup, tools, kern, rapid_stock, machine)
        built = builder.build(cut.passes)
    with clock("verify"):
        done = verify_and_repair(cut.passes, builder.build,
                                 path_check(mesh, kern, setup, tools, rapid_stock, device, cluster, clock.say), built)
    summary, detail = finish_summary(mesh, kern, tools, setup, con, scallop, balls, poses, shallow, cut, done,
                                     rapid_stock.summary(), builder.pole_report())
    summary["links"] = {"way": params.links, "direct": builder.direct_links,
                        "safe_plane": max(0, len(done.passes) - 1 - builder.direct_links)}
    clock.seconds["total"] = time.perf_counter() - t_all
    summary["seconds"] = {k: round(v, 4) for k, v in clock.seconds.items()}
    return done.path, summary, detail
