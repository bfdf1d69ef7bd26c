"""Adaptive clearing (3-axis and indexed roughing from the stock) with a bounded radial engagement.

Levels: from the stock's top down, ``step_down`` apart (default the flute length), the part's
bottom, its top, and every height where its flat upward facets add up to the area of the tool's
end (plus the axial allowance: a floor is cut at its height, not left as a step); with
``stair``, step-up levels between two levels where the one below left a stair higher than that,
cut after it, bottom up.

Everything lives on one grid of nodes ``sample`` mm apart over the stock and the part, widened so
the tool can go round the stock (:func:`grid_heights`):

- ``top (nx, ny)``: the stock's height at each node (its surface mesh dropped on with a flat disk
  of half a node: a mesh or in-process stock with overhangs counts as full below its top, which
  can only overstate the material), lowered to the level wherever a level's tool passed;
- ``drop (nx, ny)``: the drop-cutter height of the whole tool (cutter, shank, holder) grown by the
  radial allowance and widened sideways by one node, so that the tool centre anywhere within a
  node of a free node keeps the allowance from the part: the free region of a level at z is
  ``drop + (axial - radial allowance) <= z``, less where the stock standing beyond the part would
  meet the shank above the flutes or the holder (:func:`_body_free`).

The material of a level is the nodes whose stock top is above it within the tool's reach from
the free region; :class:`~meshmill.pathing.clearing.LevelClearing` clears it in walks whose every
step removes at most ``engagement · step`` mm² (the radial width of cut), entered from the side
where the stock is open or cleared, else by a helix at ``ramp_angle``. Walks are joined at the
level, or a clearance over it, round the material where a way keeps clear of it, else over what
lies between (the highest stock top within the tool's reach along the way, plus the clearance);
every link and entry is a rapid where the stock as the path leaves it, the part and the
fixtures keep the clearance from the tool (:class:`PathBuilder`). Indexed: the part, the stock
and the fixtures turned so that ``axis`` is +Z (:func:`rough`). The path is verified like every
path: gouges against the design, shank and holder against the part, rapids against the part.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from .. import memory
from ..errors import InputError, NothingToCut
from ..kernels.backend import resolve, solid_kernels
from ..params import RoughParams
from ..pathing.clearing import LevelClearing, heightmap_pass
from ..pathing.dropcutter import ToolDrop, pick_tool, stock_check
from ..pathing.verify import DEFAULT_STEP, verify_toolpath
from ..progress import Meter
from ..tolerances import GOUGE_TOL
from ..toolpath.model import Toolpath

NODE_BYTES = 200  # per grid node: its heights, and a level's masks, distances and nearest nodes
FLAT_NORMAL = 1.0 - 1e-6  # a facet this close to facing +Z is flat
HELIX_SMALLEST = 0.1  # of the tool diameter: the smallest helix tried where the room is short
HELIX_POINTS = 72  # points per turn of a helix (chords within 0.005 mm of it up to 6 mm radius: posted as arcs)
MOVE_KINDS = ("rapid", "cut", "entry", "link")
MANY_NODES = 100  # material left for want of an entry is warned about from this many nodes on
NODE_SLACK = 1.5  # nodes: the width of cut a step is planned at stays this far under the engagement


@dataclass
class RoughSetup:
    """What the levels share: ``params``, the ``tool`` (``index`` in the table), the grid ``xs
    (nx,)``, ``ys (ny,)`` (``h`` mm apart), the stock ``top`` and the tool ``drop`` heights ``(nx,
    ny)``, the ``levels`` (top down, step-up levels after the one below them), the stock's solid
    (what rapids keep clear of), its top ``stock_top``, the plane of the rapids ``safe_z`` and the
    fixtures' heights ``obstacle``, the stock's heights ``beyond`` the part and its allowance, and
    ``part_clear``, the heights above which the tool keeps the clearance from the part (its
    allowance included) and the fixtures."""

    params: RoughParams
    index: int
    tool: object
    xs: np.ndarray
    ys: np.ndarray
    h: float
    top: np.ndarray
    drop: np.ndarray
    levels: list
    solid: object
    stock_top: float
    safe_z: float
    obstacle: np.ndarray  # (nx, ny) the fixtures' heights over the nodes (-inf where none)
    beyond: np.ndarray  # (nx, ny) the stock's heights where it rises above the part and its allowance (else -inf)
    part_clear: np.ndarray  # (nx, ny) above which the tool keeps the clearance from the part and its allowance


def flat_heights(mesh, least: float) -> np.ndarray:
    """Heights ``(k,)`` of the part's flat upward facets, at least ``least`` mm² of them at each."""
    tri = mesh.vertices[mesh.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(cross, axis=1)
    up = cross[:, 2] >= FLAT_NORMAL * np.maximum(area2, 1e-300)
    if not up.any():
        return np.empty(0)
    z = np.round(tri[up][:, :, 2].mean(axis=1), 6)
    heights, inv = np.unique(z, return_inverse=True)
    area = np.bincount(inv, weights=0.5 * area2[up])
    return heights[area >= least]


def rough_levels(top: float, bottom: float, step: float, flats, stair) -> list:
    """``[(z, kind)]``: the main levels from ``top`` down (``step`` apart, the last at ``bottom``,
    the ``flats`` between them), each followed by its step-up levels (kind "stair": ``stair`` mm
    apart above it, below the level before, bottom up)."""
    main = list(np.arange(top - step, bottom + 1e-9, -step))
    if not main or main[-1] > bottom + 1e-6:
        main.append(bottom)
    main = sorted({round(float(z), 6) for z in main + [f for f in flats if bottom - 1e-9 <= f < top - 1e-6]},
                  reverse=True)
    out, above = [], top
    for z in main:
        out.append((z, "level"))
        if stair:
            ups = np.arange(z + stair, above - 1e-6, stair)
            out += [(round(float(u), 6), "stair") for u in ups]
        above = z
    return out


def rough_stock(value):
    """``value`` as the :class:`~meshmill.simulation.stock.Stock` a roughing starts from
    (default the part's box); the part offset is refused."""
    from ..simulation.stock import Stock

    stock = Stock.of(value, "box")
    if stock.kind == "offset":
        raise InputError("stock: roughing starts from a stock that holds material around the part: box, cylinder, "
                         "a mesh, or an in-process stock (not the part offset)", "stock")
    return stock


def layer_tops(summary: dict, tips) -> np.ndarray:
    """The top ``(k,)`` of the layer each of ``tips (k, 3)`` cuts, from a roughing's ``summary``:
    the main level above the nearest one (the stock's top above the first)."""
    main = [lv["z"] for lv in summary["levels"] if lv["kind"] == "level"]
    tops = [summary["stock_top"]] + main
    return np.array([tops[int(np.argmin([abs(q - z) for q in main]))] for z in np.asarray(tips)[:, 2]])


def rough_setup(mesh, tools, params: RoughParams, device: str, cluster=None) -> RoughSetup:
    """The :class:`RoughSetup` of ``mesh``: InputError for a tool not in the table, an engagement
    wider than the tool, a step-down deeper than its flutes, a stock that is the part offset, a
    grid larger than the memory. ``cluster``: a ``distributed.Client`` whose workers compute the
    grid's heights in pieces of rows (the same heights)."""
    index, tool = pick_tool(tools, params.tool)
    stock = rough_stock(params.stock)
    solid, _, margin = stock.material(mesh)
    ae = params.engagement if params.engagement is not None else 0.25 * tool.diameter
    if ae > tool.diameter:
        raise InputError(f"engagement {ae:g} mm is wider than the tool ({tool.diameter:g} mm)", "engagement")
    step_down = params.step_down if params.step_down is not None else tool.flute_length
    if step_down > tool.flute_length + 1e-9:
        raise InputError(f"step_down {step_down:g} mm is deeper than {tool.name}'s flutes "
                         f"({tool.flute_length:g} mm): the shank would cut", "step_down")
    h = params.sample if params.sample is not None else min(ae / 10.0, tool.radius / 16.0)
    a_r = params.allowance
    a_a = params.axial_allowance if params.axial_allowance is not None else a_r
    params = replace(params, engagement=ae, step_down=step_down, sample=h, axial_allowance=a_a,
                     clearance=params.clearance + margin)
    lo = np.minimum(solid.bounds[0], mesh.bounds[0])
    hi = np.maximum(solid.bounds[1], mesh.bounds[1])
    pad = tool.radius + params.clearance + 4 * h  # room to go round the stock
    nx = int(math.ceil((hi[0] - lo[0] + 2 * pad) / h)) + 1
    ny = int(math.ceil((hi[1] - lo[1] + 2 * pad) / h)) + 1
    memory.check(NODE_BYTES * float(nx) * ny, f"{nx:,} x {ny:,} grid nodes", "use a larger sample", ("sample",))
    xs = lo[0] - pad + h * np.arange(nx)
    ys = lo[1] - pad + h * np.arange(ny)
    surface = stock.rest_surface(mesh)
    if cluster is None:
        heights = grid_heights(mesh, surface, tool, params, xs, ys, device)
    else:
        from ..cluster import PIECES_PER_WORKER, run_pieces, workers
        from ..progress import ranges

        fixtures = [f if hasattr(f, "vertices") else f.solid(mesh) for f in params.fixtures or ()]
        shared = dict(part=mesh, surface=surface, tool=tool, xs=xs, ys=ys, device=device,
                      params=replace(params, part=None, tools=None, stock=None, progress=None,
                                     fixtures=fixtures or None))
        parts = run_pieces(cluster, heights_piece, shared, ranges(nx, PIECES_PER_WORKER * workers(cluster)),
                           params.progress, "grid heights")
        heights = {k: np.concatenate([q[k] for q in parts]) for k in parts[0]}
    top, obstacle = heights["top"], heights["obstacle"]
    stock_top = float(top.max())
    bottom = float(mesh.bounds[0, 2]) + a_a
    if stock_top <= bottom + 1e-6:
        raise NothingToCut("nothing to cut: the stock does not rise above the part's bottom", "stock")
    # the flats, and the part's top: the stock over it is faced, not left as a cap
    # (a floor smaller than the tool's end is no floor it could be cut at)
    flats = np.r_[flat_heights(mesh, math.pi * tool.radius ** 2), mesh.bounds[1, 2]] + a_a
    levels = rough_levels(stock_top, bottom, step_down, flats, params.stair)
    safe_z = float(max(stock_top, mesh.bounds[1, 2], obstacle.max()) + params.clearance + 1.0)
    return RoughSetup(params, index, tool, xs, ys, h, top, heights["drop"], levels, solid, stock_top, safe_z, obstacle,
                      heights["beyond"], heights["part_clear"])


def heights_piece(shared: dict, rows) -> dict:
    """:func:`grid_heights` of the rows ``rows = (a, b)`` of the grid, on a worker of a cluster
    (:func:`meshmill.cluster.run_pieces`)."""
    a, b = rows
    return grid_heights(shared["part"], shared["surface"], shared["tool"], shared["params"], shared["xs"][a:b],
                        shared["ys"], shared["device"])


def grid_heights(mesh, surface, tool, params: RoughParams, xs, ys, device: str) -> dict:
    """The heights ``(nx, ny)`` over the nodes ``xs x ys`` (see :class:`RoughSetup`): ``top``
    (the stock's ``surface`` dropped on with a flat disk of half a node), ``drop`` (the whole tool
    grown by the radial allowance and widened by a node, the axial allowance's difference added;
    the fixtures kept the clearance from), ``obstacle`` (the fixtures' heights), ``beyond`` (the
    stock where it rises over the part and its allowance) and ``part_clear`` (above which the tool
    keeps the clearance from the part, its allowance and the fixtures)."""
    h = params.sample
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    shape = (len(xs), len(ys))
    floor = float(min(surface.bounds[0, 2], mesh.bounds[0, 2])) - 1.0
    a_r, a_a, c = params.allowance, params.axial_allowance, params.clearance
    kern = solid_kernels(mesh, device)

    def tool_drop(k, grow):
        return ToolDrop(tool, k, floor, grow=grow, widen=h)(xy).reshape(shape)

    def disk_drop(k):
        return k.drop_cutter(xy, 0.5 * h, 0.0, floor)[0].reshape(shape)

    top = disk_drop(solid_kernels(surface, device))
    drop = tool_drop(kern, a_r) + (a_a - a_r)
    part_clear = tool_drop(kern, max(a_r, a_a) + c)
    obstacle = np.full(shape, -np.inf)
    if params.fixtures:
        from .fixtures import union

        fix = solid_kernels(union([f if hasattr(f, "vertices") else f.solid(mesh) for f in params.fixtures]), device)
        clear = tool_drop(fix, c)  # the tool keeps the clearance from them; links and rapids pass over them
        drop, part_clear = np.maximum(drop, clear), np.maximum(part_clear, clear)
        obstacle = disk_drop(fix)
        obstacle[obstacle <= floor + 1e-9] = -np.inf
    beyond = np.where(top > disk_drop(kern) + min(a_r, a_a) + 1e-6, top, -np.inf)
    return {"top": top, "drop": drop, "obstacle": obstacle, "beyond": beyond, "part_clear": part_clear}


def _dilated(mask, radius) -> np.ndarray:
    """``mask`` grown by ``radius`` nodes (Euclidean)."""
    from scipy.ndimage import distance_transform_edt

    return distance_transform_edt(~mask) <= radius


def _max_near(top, radius) -> np.ndarray:
    """The highest of ``top`` within ``radius`` nodes of each node: the disk as rows, each row a
    running maximum along Y, shifted along X (work in rows times the radius, not its square)."""
    from scipy.ndimage import maximum_filter1d

    k = int(math.floor(radius))
    out = np.full_like(top, -np.inf)
    rows = {}
    nx = top.shape[0]
    for di in range(-k, k + 1):
        w = int(math.floor(math.sqrt(max(0.0, radius * radius - di * di))))
        if w not in rows:
            rows[w] = maximum_filter1d(top, 2 * w + 1, axis=1, mode="nearest")
        src = rows[w]
        if di >= 0:
            np.maximum(out[:nx - di], src[di:], out=out[:nx - di])
        else:
            np.maximum(out[-di:], src[:nx + di], out=out[-di:])
    return out


class PathBuilder:
    """The moves of a roughing path (tips mm, kinds of :data:`MOVE_KINDS`): every move but the
    walks' steps is first a link or an entry at feed; :meth:`toolpath` makes rapids of those the
    stock as the path leaves it lets be (:func:`~meshmill.pathing.clearing.heightmap_pass`)."""

    def __init__(self, setup: RoughSetup):
        self.s = setup
        self.tips, self.kind = [], []
        self.at = None

    def xy(self, g) -> np.ndarray:
        """Grid units ``(..., 2)`` to mm."""
        g = np.asarray(g, float)
        return np.stack([self.s.xs[0] + self.s.h * g[..., 0], self.s.ys[0] + self.s.h * g[..., 1]], axis=-1)

    def add(self, p, kind):
        p = np.asarray(p, float)
        if self.at is not None and np.all(np.abs(p - self.at) < 1e-9):
            return
        self.tips.append(p)
        self.kind.append(kind)
        self.at = p

    def over(self, b, z_cross, z_to):
        """Up to ``z_cross``, across to above ``b`` and down to ``z_to`` (from the safe plane at
        the start of the path)."""
        if self.at is None:
            self.add([b[0], b[1], self.s.safe_z], "rapid")
        else:
            z_cross = max(z_cross, self.at[2])
            self.add([self.at[0], self.at[1], z_cross], "link")
            self.add([b[0], b[1], z_cross], "link")
        self.add([b[0], b[1], z_to], "entry")

    def helix(self, centre, rh, z_from, z_to, side):
        """A helix about ``centre`` (mm) of radius ``rh`` mm from ``z_from`` down to ``z_to`` at
        the ramp angle, then a whole turn at ``z_to``; it starts and ends at angle 0."""
        pitch = 2 * math.pi * rh * math.tan(math.radians(self.s.params.ramp_angle))
        turns = max(1e-9, z_from - z_to) / pitch
        n = max(1, int(math.ceil(turns * HELIX_POINTS)))
        ang = side * 2 * math.pi * turns * np.arange(1, n + 1) / n
        for a, z in zip(ang, z_from - (z_from - z_to) * np.arange(1, n + 1) / n):
            self.add([centre[0] + rh * math.cos(a), centre[1] + rh * math.sin(a), z], "entry")
        a0 = ang[-1]
        for k in range(1, HELIX_POINTS + 1):
            a = a0 + side * 2 * math.pi * k / HELIX_POINTS
            self.add([centre[0] + rh * math.cos(a), centre[1] + rh * math.sin(a), z_to], "entry")
        self.add([centre[0] + rh, centre[1], z_to], "entry")

    def toolpath(self) -> tuple[Toolpath, np.ndarray]:
        """The path and its moves' kinds ``(k,) int8``: a link or entry clear of the stock as the
        moves before it left it (by the clearance) is a rapid; a vertical one clear above some
        height is split there (rapid above, feed below)."""
        s = self.s
        tips = np.array(self.tips)
        kind = np.array([MOVE_KINDS.index(k) for k in self.kind], np.int8)
        tool = s.tool
        low = heightmap_pass(np.maximum(s.beyond, s.obstacle), s.part_clear, s.xs[0], s.ys[0], s.h, tips, tool.radius,
                             tool.corner_radius, s.params.clearance, kind != 0)
        out_t, out_k = [tips[0]], [kind[0]]
        for i in range(1, len(tips)):
            a, b, k = tips[i - 1], tips[i], kind[i]
            if k in (2, 3):
                vertical = abs(a[0] - b[0]) < 1e-12 and abs(a[1] - b[1]) < 1e-12
                if low[i] <= min(a[2], b[2]):
                    k = 0
                elif vertical and low[i] < max(a[2], b[2]):
                    split = [b[0], b[1], low[i]]
                    out_t.append(np.array(split))
                    out_k.append(0 if b[2] < a[2] else k)
                    if b[2] > a[2]:
                        k = 0
            out_t.append(b)
            out_k.append(k)
        tips, kind = np.array(out_t), np.array(out_k, np.int8)
        axis = np.zeros_like(tips)
        axis[:, 2] = 1.0
        return Toolpath(tips, axis, kind == 0, np.full(len(tips), s.index, np.int64)), kind


def _crossing(setup: RoughSetup, high, a, b) -> float:
    """The height a link from ``a`` to ``b`` (grid units) crosses at: the highest of ``high``
    (the stock top near each node) along it plus the clearance, at most the safe plane."""
    d = float(np.hypot(*(np.asarray(b) - a)))
    t = np.linspace(0.0, 1.0, max(2, int(math.ceil(2 * d)) + 1))
    p = np.asarray(a)[None] + t[:, None] * (np.asarray(b) - a)[None]
    i = np.clip(np.floor(p[:, 0] + 0.5).astype(int), 0, high.shape[0] - 1)
    j = np.clip(np.floor(p[:, 1] + 0.5).astype(int), 0, high.shape[1] - 1)
    return float(min(setup.safe_z, high[i, j].max() + setup.params.clearance))


def _body_free(setup: RoughSetup, top, z) -> np.ndarray:
    """``(nx, ny) bool``: where the tool at ``z`` keeps its shank above the stock ``top`` where
    it rises beyond the part and its allowance (what stands within its radius rises at most to the
    flutes' end; the part itself is the drop heights') and its holder the clearance over it (a
    square around the holder: the filter is fast). The tool may stand a node from a free
    node, and a node's height stands for the stock within 0.71 nodes of it: the radii grow by 2
    nodes."""
    from scipy.ndimage import maximum_filter

    t, h = setup.tool, setup.h
    top = np.where(np.isfinite(setup.beyond), top, -np.inf)
    ok = _max_near(top, max(t.radius, 0.5 * t.shank_diameter) / h + 2.0) <= z + t.flute_length + 1e-9
    if t.holder_diameter > 0:
        k = int(math.ceil(0.5 * t.holder_diameter / h)) + 2
        ok &= maximum_filter(top, size=2 * k + 1, mode="nearest") <= z + t.gauge_length - setup.params.clearance
    return ok


def rough_level(setup: RoughSetup, z: float, top: np.ndarray, pos):
    """Clear the level at ``z`` from the stock heights ``top`` (lowered in place where the tool
    passes): ``(LevelClearing, high, step)``, ``high`` the stock top within the tool's reach at
    the level's start, ``step`` the walks' step (nodes)."""
    p, t = setup.params, setup.tool
    r = t.radius / setup.h
    feas = (setup.drop <= z + 1e-9) & _body_free(setup, top, z)
    feas[0, :] = feas[-1, :] = feas[:, 0] = feas[:, -1] = False
    material = top > z + 1e-6
    reach = _dilated(feas, r)
    rem = material & reach
    high = _max_near(np.maximum(top, setup.obstacle), r + 1.5)
    s = max(2.0, 0.25 * r)  # the step, nodes
    target = (p.engagement / setup.h - NODE_SLACK) * s  # the cleared border is known to a node
    side = 1 if p.direction == "climb" else -1
    helix = (0.5 * p.helix_diameter / setup.h if p.helix_diameter is not None else 0.375 * t.diameter / setup.h,
             HELIX_SMALLEST * t.radius / setup.h)
    level = LevelClearing(rem, feas, r, s, target, side, helix, pos, p.clearance / setup.h + 1.5)
    level.material = int(material.sum())
    level.unreachable = int((material & ~reach).sum())
    top[level.swept] = np.minimum(top[level.swept], z)
    return level, high, s


def tool_axis(text: str) -> np.ndarray:
    """The unit vector ``(3,)`` of an axis option: +X, -Y, ... or three numbers ``x,y,z``."""
    from ..geometry.placement import AXES

    key = text.strip().upper()
    if key in ("X", "Y", "Z"):
        key = "+" + key
    if key in AXES:
        return np.array(AXES[key], float)
    try:
        v = np.array([float(t) for t in text.replace(" ", "").split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise InputError(f"axis '{text}': give an axis (+X, -Y, ...) or three numbers x,y,z (not all zero)", "axis")
    return v / np.linalg.norm(v)


def rough(mesh, tools, params: RoughParams, progress=None, cluster=None):
    """Adaptive clearing of ``mesh`` from ``params.stock`` (default its box) with the tool
    ``params.tool``, along ``params.axis`` (indexed: the part and the stock turned so that it is
    +Z, the path turned back). Returns ``(toolpath, summary, move_kind (k,) int8)`` (indices into
    :data:`MOVE_KINDS`)."""
    u = tool_axis(params.axis)
    if u[2] > 1 - 1e-12:
        return _rough(mesh, tools, params, progress, cluster)
    from ..simulation.stock import Stock
    from .plunge import tool_frame

    frame = np.stack([*tool_frame(u), u])  # rows: the tool frame's axes in the work frame
    stock = rough_stock(params.stock)
    surface = stock.rest_surface(mesh)
    margin = stock.material(mesh)[2]
    turned = Stock.mesh(surface.transformed(frame))
    fixtures = [(f if hasattr(f, "vertices") else f.solid(mesh)).transformed(frame) for f in params.fixtures or ()]
    tp, summary, kind = _rough(mesh.transformed(frame), tools, replace(params, stock=turned, axis="+Z",
                                                                        clearance=params.clearance + margin,
                                                                        fixtures=fixtures or None), progress,
                                  cluster)
    tp = Toolpath(tp.tip @ frame, np.tile(u, (len(tp), 1)), tp.rapid, tp.tool)
    summary.update(axes="3+2", axis=u.round(9).tolist(), frame=frame.round(9).tolist())
    return tp, summary, kind


def _rough(mesh, tools, params: RoughParams, progress=None, cluster=None):
    """:func:`rough` along +Z."""
    say = progress or (lambda stage: None)
    t0 = time.perf_counter()
    device = resolve(params.device)
    setup = rough_setup(mesh, tools, replace(params, device=device), device, cluster)
    p = setup.params
    say(f"{len(setup.levels)} levels on {len(setup.xs):,} x {len(setup.ys):,} nodes")
    top = setup.top.copy()
    build = PathBuilder(setup)
    side = 1 if p.direction == "climb" else -1
    meter = Meter(say, "levels", len(setup.levels))
    per_level, removed, pos, step = [], [], None, 2.0
    t_levels = time.perf_counter()
    for z, kind in setup.levels:
        t_level = time.perf_counter()
        level, high, step = rough_level(setup, z, top, pos)
        t_level = time.perf_counter() - t_level
        for (entry, link, pts), got in zip(level.events, level.removed):
            start = build.xy(pts[0])
            how, way = link if link is not None else ("lift", None)
            at_level = build.at is not None and abs(build.at[2] - z) < 1e-9
            if how == "hop" and at_level:  # away from the material, up the clearance, round, down
                corners = build.xy(way)
                build.add([corners[1][0], corners[1][1], z], "link")
                for q in corners[1:]:
                    build.add([q[0], q[1], z + p.clearance], "link")
                build.add([start[0], start[1], z], "entry")
            elif how == "level" and at_level:
                for q in build.xy(way[1:]):
                    build.add([q[0], q[1], z], "link")
            else:
                if way is not None and at_level:
                    away = build.xy(way[1])
                    build.add([away[0], away[1], z], "link")
                    pos = way[1]
                cross = _crossing(setup, high, pos, pts[0]) if pos is not None else setup.safe_z
                if entry[0] == "helix":
                    (ci, cj), rh = entry[1][0], entry[1][1]
                    centre = build.xy(entry[1][0])
                    z_from = min(float(high[int(ci), int(cj)]) + p.clearance, setup.safe_z)
                    build.over([centre[0] + rh * setup.h, centre[1]], cross, z_from)
                    build.helix(centre, rh * setup.h, z_from, z, side)
                else:
                    build.over(start, cross, z)
            for q in build.xy(pts[1:]):
                build.add([q[0], q[1], z], "cut")
            removed.append(got)
            pos = pts[-1]
        if level.exit is not None and build.at is not None and abs(build.at[2] - z) < 1e-9:
            away = build.xy(level.exit[1])
            build.add([away[0], away[1], z], "link")
            pos = level.exit[1]
        per_level.append({"z": z, "kind": kind, "walks": len(level.events),
                          "helices": sum(e[0][0] == "helix" for e in level.events),
                          "material_mm2": round(level.material * setup.h ** 2, 3),
                          "left_mm2": round(level.left * setup.h ** 2, 3),
                          "unreachable_mm2": round(level.unreachable * setup.h ** 2, 3),
                          "seconds": round(t_level, 4)})
        if level.helix_failed and level.left:
            per_level[-1]["no_entry_mm2"] = per_level[-1]["left_mm2"]  # left where no helix fits
        meter.done()
    t_levels = time.perf_counter() - t_levels
    no_entry = [lv for lv in per_level if lv.get("no_entry_mm2")]
    helix = p.helix_diameter if p.helix_diameter is not None else 0.75 * setup.tool.diameter
    if build.at is None and no_entry:
        raise InputError(f"no entry fits: the material at {len(no_entry)} level(s) is closed and has no room for a "
                         f"helix of {HELIX_SMALLEST * setup.tool.diameter:g} to {helix:g} mm (a smaller tool, or a "
                         "stock open at the side)", ("helix_diameter", "tool"))
    if build.at is None:
        raise NothingToCut("nothing to cut: the stock holds no material the tool can reach at any level", "stock")
    build.over(build.at[:2], setup.safe_z, setup.safe_z)
    tp, kind = build.toolpath()
    say("verify")
    t_verify = time.perf_counter()
    # rapids keep clear of the design here, and of the stock as the path leaves it by construction
    # (heightmap_pass); the walks make room for the shank, which rough_level keeps out of the stock
    check = replace(stock_check(None, 0.0, p.clearance, device), feed_body=False)
    report = verify_toolpath(solid_kernels(mesh, device), tp, tools, GOUGE_TOL, DEFAULT_STEP, stock=check)
    report.pop("problem_moves")
    t_verify = time.perf_counter() - t_verify
    summary = rough_summary(setup, tp, kind, per_level, removed, step, report)
    summary["warnings"] = [f"level {lv['z']:g}: {lv['no_entry_mm2']:g} mm^2 of closed material left, no helix fits "
                           f"(at most {helix:g} mm)" for lv in no_entry if lv["no_entry_mm2"] > MANY_NODES * setup.h ** 2]
    summary["seconds"] = {"levels": round(t_levels, 4), "verify": round(t_verify, 4),
                          "total": round(time.perf_counter() - t0, 4)}
    return tp, summary, kind


def rough_summary(setup: RoughSetup, tp, kind, per_level, removed, step, report) -> dict:
    """``summary.json`` of a roughing: levels, lengths by kind of move, the engagement the
    planner held (the radial width of each step: its removed area over its length), the verify
    report, then the parameters."""
    p, t = setup.params, setup.tool
    seg = np.linalg.norm(np.diff(tp.tip, axis=0), axis=1)
    length = {k: round(float(seg[kind[1:] == i].sum()), 3) for i, k in enumerate(MOVE_KINDS)}
    widths = np.concatenate(removed) * setup.h ** 2 / (step * setup.h) if removed else np.zeros(1)
    feed = length["cut"] + length["entry"] + length["link"]
    return {
        "operation": "rough",
        "axes": 3,
        "axis": [0.0, 0.0, 1.0],
        "tool": t.name,
        "levels": per_level,
        "grid": {"sample": setup.h, "nodes": [len(setup.xs), len(setup.ys)]},
        "length_mm": length,
        "feed_not_cutting_share": round((length["link"]) / feed, 4) if feed else 0.0,
        "planned_width_mm": {"max": round(float(widths.max()), 4), "mean": round(float(widths.mean()), 4),
                             "set": p.engagement},
        "left_mm2": round(sum(lv["left_mm2"] for lv in per_level), 3),
        "moves": len(tp),
        "cutting_length": tp.cutting_length(),
        "stock_top": setup.stock_top,
        "safe_z": setup.safe_z,
        "verify": report,
        **{k: getattr(p, k) for k in ("engagement", "step_down", "allowance", "axial_allowance", "stair",
                                      "direction", "helix_diameter", "ramp_angle", "sample", "clearance")},
    }
