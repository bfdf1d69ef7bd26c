"""The whole 3-axis tool dropped onto a mesh: cutter, shank and holder together."""
from __future__ import annotations


import numpy as np

from ..progress import PIECES, in_pieces, ranges
from ..errors import InputError
from ..kernels.backend import bind, cutter_rise, solid_kernels
from ..toolpath.linking import link_passes
from .reverify import Reverify
from .verify import StockCheck, check_parts

SAFE_ABOVE = 5.0  # mm above the part's top for rapid moves of 3-axis paths
TOUCH = 1e-6  # mm: a touch point's drop height is within this of its level ...
WALL = 1e-4  # mm: ... or the level set is within this distance of it (so always at a vertical wall)
TOUCH_ROUNDS = 80
REPAIR_ROUNDS = 3


def stock_check(solid, allowance: float, clearance: float, device) -> StockCheck:
    """What the rapids of an operation keep clear of: the ``solid`` stock mesh if given (with the
    design itself), else the design with ``allowance`` mm on it; ``clearance`` mm away."""
    if solid is not None:
        return StockCheck(allowance=0.0, kern=solid_kernels(solid, device), clearance=clearance)
    return StockCheck(allowance=allowance, clearance=clearance)


def body_grow(solid, allowance: float, tolerance: float) -> float:
    """How far a 3-axis operation's shank and holder keep from the design: out of the material
    ``allowance`` mm on it (a ``solid`` stock mesh is left to the check and repair of
    :func:`verified_path`), and half the ``tolerance`` more. The check lets them into the stock
    by the tolerance; kept out by half of it, a shank that rests on the stock between two points
    of a pass (the chord within half the tolerance of its drop) is proven clear at once, where one
    just touching had its moves halved until the chord came within the tolerance (the raster of
    bench/whole_ops.py: poses refined 7 294 -> 2 479, its verification 1.16 -> 0.99 s)."""
    return (0.0 if solid is not None else float(allowance)) + 0.5 * float(tolerance)


def safe_height(mesh, solid, allowance: float, clearance: float) -> float:
    """The plane of a 3-axis operation's rapids: ``SAFE_ABOVE`` over the part, and at least the
    clearance and 1 mm over the stock (``solid``, else the part with ``allowance`` on it)."""
    top = max(mesh.bounds[1, 2], solid.bounds[1, 2]) if solid is not None else mesh.bounds[1, 2] + allowance
    return float(max(mesh.bounds[1, 2] + SAFE_ABOVE, top + clearance + 1.0))


def stock_for(mesh, params, device):
    """A 3-axis operation's ``params.stock`` (a :class:`~meshmill.simulation.stock.Stock`, default
    the part with ``STOCK_ALLOWANCE`` on it) as it uses it: ``(params with the clearance grown by
    the stock's margin, what rapids keep clear of (StockCheck), how far the shank and holder keep
    from the design, the safe plane, the kernels ``params.rest`` depths are measured from or None)``."""
    from dataclasses import replace

    from ..simulation.stock import Stock

    stock = Stock.of(params.stock, "offset")
    solid, allowance, margin = stock.material(mesh)
    params = replace(params, clearance=params.clearance + margin)
    check = stock_check(solid, allowance, params.clearance, device)
    rest_kern = None
    if params.rest is not None:
        surface = stock.rest_surface(mesh)
        if surface is None:
            raise InputError("rest needs a stock to measure depths from: a mesh, a box, or a saved or in-process stock "
                             "(not the part offset)", ("rest", "stock"))
        rest_kern = check.kern if surface is solid else solid_kernels(surface, device)
    return (params, check, body_grow(solid, allowance, params.tolerance),
            safe_height(mesh, solid, allowance, params.clearance), rest_kern)


def pick_tool(tools, name):
    """``(index, tool)`` of the tool called ``name`` in the table."""
    for i, t in enumerate(tools):
        if t.name == name:
            return i, t
    raise InputError(f"tool: no tool named '{name}' in the table (have: {', '.join(t.name for t in tools)})", "tool")


class ToolDrop:
    """Drop-cutter heights of a vertical tool over the mesh of ``bvh``, never below ``floor``:
    the cutter's exact contact, and the shank and holder as flat-bottomed cylinders above it, so
    that a 3-axis position that clears the drop height clears the whole tool. ``bvh``: a BVH (run
    on ``device``) or :class:`~meshmill.kernels.backend.MeshKernels`.

    With ``grow`` the whole tool is grown by a ball of that radius (the Minkowski sum of a flat or
    bull-nose cutter with a ball of radius g is a bull-nose of radius R + g and corner r + g whose
    tip is g below the real one; shank and holder g wider): the heights are the real tip's, the
    tool kept ``grow`` mm from the mesh. With ``square`` the cylinders are grown as verification
    grows them (radius and both ends by g: a little more than the Minkowski sum): a flat end stays
    flat, and the flutes above a rounded end start g below its equator. ``body_grow`` grows the
    shank and holder alone (radius and bottom by b): the cutter may touch the mesh, the rest stays
    out of the material ``b`` mm on it (the stock allowance an operation starts from). ``widen``
    grows the whole (grown) tool sideways by a disk of that radius (a cutter of radius R + w and
    the same corner, body cylinders w wider): a height clear there keeps the tool clear anywhere
    within w mm of the point at that height."""

    def __init__(self, tool, bvh, floor: float, device: str = "cpu", grow: float = 0.0, square: bool = False,
                 body_grow: float = 0.0, widen: float = 0.0):
        g, b, w = float(grow), float(body_grow), float(widen)
        square_flat = square and tool.type == "flat"  # a flat end grown as a cylinder: a wider flat end
        self.radius, self.corner, self.grow = tool.radius + g + w, tool.corner_radius + (0.0 if square_flat else g), g
        parts = [(0.5 * tool.shank_diameter + g + b + w, max(0.0, tool.flute_length - b))]
        if tool.holder_diameter > 0:
            parts.append((0.5 * tool.holder_diameter + g + b + w, max(0.0, tool.gauge_length - b)))
        self.body = (np.array([p[0] for p in parts]), np.array([p[1] for p in parts]))
        # flat disks (radius, height over the grown tip) the kernel's body cylinders cannot stand
        # for (no wider than the cutter): the grown flutes, and a bull-nose's grown flat bottom
        self.disks = []
        if square and g > 0 and tool.type != "flat":
            self.disks.append((tool.radius + g, tool.corner_radius))
            if tool.type == "bull":
                self.disks.append((tool.radius - tool.corner_radius + g, 0.0))
        self.kern, self.floor = bind(bvh, device), floor

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """Tip heights ``(k,)`` at ``xy (k, 2)``."""
        return self.with_contacts(xy)[0]

    def with_contacts(self, xy: np.ndarray):
        """Tip heights ``(k,)`` at ``xy (k, 2)`` and the mesh points touched ``(k, 3)`` (NaN: none)."""
        z, contact = self.kern.drop_cutter(xy, self.radius, self.corner, self.floor - self.grow, self.body)
        for radius, height in self.disks:
            zd, cd = self.kern.drop_cutter(xy, radius, 0.0, self.floor - self.grow + height)
            higher = zd - height > z
            z = np.where(higher, zd - height, z)
            contact[higher] = cd[higher]
        return z + self.grow, contact

    def refined(self, xy: np.ndarray, chord_tol: float, min_step: float, rounds: int):
        """:func:`drop_refined` in one compiled pass where the kernels offer it and no disk is
        dropped besides the cutter (else None): the tips ``(m, 3)``."""
        if self.disks or not self.kern.refines:
            return None
        z, rows = self.kern.drop_refined(xy, self.radius, self.corner, self.floor - self.grow, self.grow, chord_tol,
                                         min_step, rounds, self.body)
        rows = rows[np.lexsort((rows[:, 1], rows[:, 0]))]
        at = rows[:, 0].astype(np.int64) + 1
        return np.column_stack([np.insert(xy, at, rows[:, 3:5], axis=0), np.insert(z, at, rows[:, 2])])

    def bounds(self, xy: np.ndarray, delta: float):
        """(For ``grow`` 0.) Upper and lower bounds ``(k,), (k,)`` of the drop height anywhere within ``delta`` mm of
        each of ``xy (k, 2)``.

        Upper: the contact a point q offers the tool at p rises at most to what it offers a tool
        whose profile is the original pushed out by delta (h(max(0, rho - delta))) at the centre, which
        is the cutter with radius R + delta and the same corner radius, and body cylinders delta wider.
        Lower: any mesh point within rho0 - delta of the centre lies within rho0 of p and holds
        the tool tip at most h(rho0) below itself, so a flat cutter of radius rho0 - delta at the
        centre, lowered by h(rho0), stays below the drop height (best of a few rho0)."""
        R, r = self.radius, self.corner
        upper = self.kern.drop_cutter(xy, R + delta, r, self.floor, (self.body[0] + delta, self.body[1]))[0]
        lower = np.full(len(xy), self.floor)
        if delta < R:
            flat = R - r  # the flat bottom's radius: no rise inside it
            for rho0 in {max(flat, delta + 0.4 * (R - delta)), max(flat, delta + 0.75 * (R - delta))}:
                rise = cutter_rise(rho0, R, r)
                lower = np.maximum(lower, self.kern.drop_cutter(xy, rho0 - delta, 0.0, self.floor + rise)[0] - rise)
        return upper, lower

    def touch(self, inside_xy, outside_xy, f_inside, f_outside, z, inside_contacts=None) -> np.ndarray:
        """(For ``grow`` 0.) Points ``(k, 2)`` between inside (height > z) and outside (<= z) points where the height
        reaches z from below (see :func:`meshmill.kernels.cpu.touch_points`)."""
        return self.kern.touch_points(inside_xy, outside_xy, f_inside, f_outside, z, self.radius, self.corner,
                                      self.floor, TOUCH, WALL, TOUCH_ROUNDS, self.body, inside_contacts)


class StockClearance:
    """Where a vertical tool is clear of the stock: the height ``(k,)`` over ``xy (k, 2)`` above
    which the whole tool keeps ``stock.clearance`` mm from the stock (the design grown by
    ``stock.allowance``, and the stock mesh when given), never below ``floor``; with ``widen``,
    anywhere within that distance of the point at that height."""

    def __init__(self, tool, kern, floor: float, stock: StockCheck, widen: float = 0.0):
        self.drops = [ToolDrop(tool, kern, floor, grow=stock.allowance + stock.clearance, square=True, widen=widen)]
        if stock.kern is not None:
            self.drops.append(ToolDrop(tool, stock.kern, floor, grow=stock.clearance, square=True, widen=widen))

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, np.float64).reshape(-1, 2)
        return np.max([d(xy) for d in self.drops], axis=0)


def verified_path(passes, tool_index, tools, kern, safe_z, tol, step, stock: StockCheck | None = None,
                  progress=None):
    """Link 3-axis ``passes`` (``(k, 3)`` tips each) into a tool path, verify it against the solid
    of ``kern`` (:class:`~meshmill.kernels.backend.MeshKernels`, :func:`solid_kernels`), and split
    passes at the feed moves that fail (the tool lifts over them) until it verifies clean. Each
    pass is entered and left vertically: rapid down to where the tool is clear of the stock
    (:class:`StockClearance`), feed the rest, and back; from one pass to the next the tool
    travels at the lowest height clear of the stock along the way (:func:`link_heights`), at the
    safe plane where verification finds that link too close. Returns ``(toolpath, report, passes)``;
    ``report["moves_left_out"]`` counts the moves given up; ``progress`` is told the share of each
    round's check done."""
    stock = stock or StockCheck()
    tool = tools[tool_index]
    floor = float(kern.bvh.node_lo[0, 2]) - 1.0
    clear = StockClearance(tool, kern, floor, stock)
    spacing = max(tool.radius, 0.5)
    clear_wide = StockClearance(tool, kern, floor, stock, widen=0.5 * spacing + 1e-6)
    high = set()  # links verification found too close: at the safe plane
    # each round of repairs checks only the moves it changed
    check = Reverify(lambda path, only: check_parts(kern, path, tools, tol, step, stock, only, progress), tol, step,
                     stock.summary())
    left_out = 0
    for rnd in range(REPAIR_ROUNDS + 1):
        ends = np.array([[p[0, 0], p[0, 1], p[-1, 0], p[-1, 1]] for p in passes]).reshape(-1, 4)
        z_in = clear(ends[:, :2]) if len(passes) else None
        z_out = clear(ends[:, 2:]) if len(passes) else None
        links = link_heights(ends, z_in, z_out, safe_z, clear_wide, spacing, high)
        tp = link_passes(passes, tool_index, safe_z, z_in, z_out, links)
        report = check(tp)
        bad = report.pop("problem_moves")
        if report["ok"] or rnd == REPAIR_ROUNDS:
            break
        # move m of pass k's block: rapid across, rapid down, feed to p[0], ..., p[-1], feed up, rapid up
        owner, point = [], []
        for k, p in enumerate(passes):
            owner += [k] * (len(p) + 4)
            point += [-2, -1] + list(range(len(p))) + [-1, -3]
        splits, raised = {}, set()
        for m in bad:
            if point[m] > 0:
                splits.setdefault(owner[m], []).append(point[m])
            elif point[m] in (-2, -3):  # a link into pass k (across) or out of it (up): at the safe plane
                raised.add((ends[owner[m], 0], ends[owner[m], 1]) if point[m] == -2 else
                           (ends[owner[m], 2], ends[owner[m], 3]))
        if raised - high:
            high |= raised
            continue
        if not splits:
            break
        new = []
        for k, p in enumerate(passes):
            cuts = sorted(set(splits.get(k, [])))
            left_out += len(cuts)
            new += [q for q in np.split(p, cuts) if len(q) >= 2]
        passes = new
    report["moves_left_out"] = left_out
    return tp, report, passes


def link_heights(ends, z_in, z_out, safe_z: float, clear, spacing: float, high=frozenset()) -> np.ndarray:
    """``(n + 1,)`` the heights of the links into each of n passes (``ends (n, 4)``: each pass's
    first and last XY; ``z_in``, ``z_out`` where the tool is clear of the stock above them) and
    out of the last: the first and last at ``safe_z``, each other the highest of the two ends'
    and of ``clear`` (a :class:`StockClearance` widened by half ``spacing``) at points ``spacing``
    apart on the straight way between them, so that the whole way is clear; at ``safe_z`` where
    the link's start or end XY is in ``high``."""
    n = len(ends)
    out = np.full(n + 1, float(safe_z))
    if n < 2:
        return out
    a, b = ends[:-1, 2:], ends[1:, :2]
    count = np.maximum(2, np.ceil(np.linalg.norm(b - a, axis=1) / spacing).astype(np.int64) + 1)
    owner = np.repeat(np.arange(n - 1), count)
    f = (np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)) / np.repeat(count - 1, count)
    z = clear(a[owner] + f[:, None] * (b - a)[owner])
    top = np.full(n - 1, -np.inf)
    np.maximum.at(top, owner, z)
    links = np.minimum(safe_z, np.maximum.reduce([top, np.asarray(z_out[:-1]), np.asarray(z_in[1:])]))
    for k in range(n - 1):
        if (a[k, 0], a[k, 1]) in high or (b[k, 0], b[k, 1]) in high:
            links[k] = safe_z
    out[1:-1] = links
    return out


REFINE_ROUNDS = 6  # each halves the spacing where the chord leaves the surface


def drop_piece(shared: dict, piece) -> np.ndarray:
    """:func:`drop_refined` of one piece ``xy (k, 2)`` of a polyline on a worker of a cluster
    (:func:`meshmill.cluster.run_pieces`); ``shared``: the ``part``, the ``tool`` and the
    :class:`ToolDrop` arguments (``floor``, ``grow``, ``body_grow``), ``chord_tol``, ``min_step``,
    ``device``. The part's kernels are built once per worker."""
    from ..cluster import worker_cached

    kern = worker_cached(shared, "part", lambda: solid_kernels(shared["part"], shared["device"]))
    drop = ToolDrop(shared["tool"], kern, shared["floor"], grow=shared["grow"], body_grow=shared["body_grow"])
    return drop_refined(piece, drop, shared["chord_tol"], shared["min_step"])


def drop_refined_on(client, xy, shared: dict, progress=None) -> np.ndarray:
    """:func:`drop_refined` of the polyline ``xy (k, 2)`` in pieces on ``client``'s workers (see
    :func:`drop_piece` for ``shared``): pieces share their end points, and each segment is refined
    on its own, so the tips are the one process's."""
    from ..cluster import PIECES_PER_WORKER, run_pieces, workers

    pieces = [xy[a:b + 1] for a, b in _polyline_pieces(len(xy), PIECES_PER_WORKER * workers(client))]
    return _joined(run_pieces(client, drop_piece, shared, pieces, progress, "drop-cutter"))


def _polyline_pieces(k: int, count: int) -> list[tuple[int, int]]:
    """``(a, b)``: pieces ``a .. b`` (both ends in) of a polyline of ``k`` points, each sharing its
    first point with the piece before."""
    return ranges(k - 1, count) if k > 1 else [(0, 0)]


def _joined(tips: list) -> np.ndarray:
    """The tips of consecutive pieces of a polyline (sharing their end points) as one."""
    return np.concatenate([tips[0]] + [t[1:] for t in tips[1:]])


def drop_refined_pieces(xy, drop: "ToolDrop", chord_tol, min_step, progress=None) -> np.ndarray:
    """:func:`drop_refined` of the polyline ``xy (k, 2)`` piece by piece (each segment is refined
    on its own: the same tips), the share done and the time left told to ``progress``."""
    cuts = _polyline_pieces(len(xy), PIECES)
    return _joined(in_pieces(lambda a, b: drop_refined(xy[a:b + 1], drop, chord_tol, min_step), cuts, progress,
                             "drop-cutter"))


def drop_refined(xy, drop: ToolDrop, chord_tol, min_step):
    """Drop the tool along the polyline ``xy (k, 2)``, adding midpoints where the tip height
    leaves the chord by more than ``chord_tol``; returns tips ``(m, 3)``. Each round drops only
    the midpoints of the segments the round before split (the others' were within the chord).
    A :class:`ToolDrop` does it all in one compiled pass where it can (:meth:`ToolDrop.refined`:
    the same tips); ``drop`` may be any function of ``xy`` giving heights."""
    if isinstance(drop, ToolDrop):
        tips = drop.refined(np.asarray(xy, np.float64), chord_tol, min_step, REFINE_ROUNDS)
        if tips is not None:
            return tips
    z = drop(xy)
    fresh = np.ones(max(len(xy) - 1, 0), bool)  # segments whose midpoint is not dropped yet
    for _ in range(REFINE_ROUNDS):
        if len(xy) < 2:
            break
        idx = np.nonzero(fresh & (np.linalg.norm(xy[1:] - xy[:-1], axis=1) > min_step))[0]
        if len(idx) == 0:
            break
        mid = 0.5 * (xy[idx] + xy[idx + 1])
        zm = drop(mid)
        off = np.abs(zm - 0.5 * (z[idx] + z[idx + 1])) > chord_tol
        if not off.any():
            break
        ins = idx[off]
        xy = np.insert(xy, ins + 1, mid[off], axis=0)
        z = np.insert(z, ins + 1, zm[off])
        split = np.zeros(len(fresh), bool)
        split[ins] = True
        fresh = np.repeat(split, np.where(split, 2, 1))  # a split segment's two halves are new
    return np.column_stack([xy, z])
