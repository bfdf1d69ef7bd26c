"""Plunge roughing (tréflage, seed 001): the tool feeds along its own axis into the stock, one
plunge at a time, down to the lowest position that keeps ``allowance`` mm from the part.

3-axis: the stock is the part's box; plunge points lie on nested rectangles shrunk from its
outline by ``k * engagement`` (k = 0, 1, ...) while they enclose anything, ``radial_step`` mm apart
along each perimeter. The depth at a point is exact: the drop-cutter of the 3-axis kernels with
the whole tool grown by the allowance (the Minkowski sum of the cutter with a ball of radius
``allowance`` is a bull-nose of radius R + a and corner r + a whose tip is a below the real one;
shank and holder grown likewise), never below the stock bottom. Plunges whose depth is not below
the stock top remove nothing and are skipped. A plunge cuts with its end and flutes only: the shank
and holder, where wider than the hole the cutter makes less the clearance, keep
``HOLDER_CLEARANCE`` from the stock at every depth (the plunge stops where they would not: the
material below is left and counted), and a plunge deeper than the flutes (a necked tool) is cut in
layers of the flute length, every plunge of a layer before the next. Each plunge: rapid to the
clearance plane above the point, rapid down to where the tool clears the stock, feed down, feed
back up there, rapid to the plane; contours from the outside in. The path is verified like every
path we write (gouge and shank/holder collision along every move, rapids out of the stock).

5-axis (seed 001's half-sphere): directions U over the upper hemisphere (theta from the pole by
``theta_step``, around by ``delta_step``); the tool starts at PI = C + r U outside the stock (C its
centre, r its half-diagonal plus the clearance) with axis U and plunges along -U toward C. The
depth is exact as in 3-axis, in the tool frame (T1, T2, U), T1 = y x U normalised (x x U when
U is along y), T2 = U x T1: the part turned into that frame and the grown tool dropped on it,
shank and holder included, never past the point where the axis leaves the stock, and limited by
the shank and holder as in 3-axis (the stock's box turned into the frame). A plunge is kept when its
tip gets past the point where the axis enters the stock (it removes stock). Between plunges the tool
moves along the sphere (chords of at most ``ARC_STEP``), which stays outside the stock.

The seed's own depths (the nearest sampled surface point in a square around the point, no
allowance; in 5-axis a test that can never be true and an allowance added the wrong way) can
gouge; see its notes §4.9-4.10.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from ..errors import InputError, NothingToCut
from ..geometry.shapes import box
from ..kernels.backend import resolve, solid_kernels
from ..params import PlungeParams
from ..tolerances import GOUGE_TOL, HOLDER_CLEARANCE
from ..toolpath.model import Toolpath
from ..pathing.dropcutter import pick_tool
from ..pathing.verify import DEFAULT_STEP, StockCheck, verify_toolpath

ARC_STEP = math.radians(5.0)  # largest angle of a chord of the 5-axis linking moves
REACH_SAMPLES = 64  # positions along a plunge line looked at before the first contact is bisected


def tool_frame(u) -> tuple[np.ndarray, np.ndarray]:
    """``(T1, T2)`` completing the unit axis ``u`` (3,) to a right-handed frame: T1 = y x u
    normalised (x x u when u is along y), T2 = u x T1 (seed 001's frame)."""
    t1 = np.cross([0.0, 1.0, 0.0], u)
    if np.linalg.norm(t1) < 1e-9:
        t1 = np.cross([1.0, 0.0, 0.0], u)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(u, t1)


def rectangle_points(x0, y0, x1, y1, step) -> np.ndarray:
    """``(k, 2)`` points every ``step`` mm along the perimeter of the rectangle, from (x0, y0)
    up the side x = x0 first; a degenerate rectangle (a segment or a point) is walked once."""
    w, h = x1 - x0, y1 - y0
    if w <= 0 and h <= 0:
        return np.array([[x0, y0]])
    if w <= 0 or h <= 0:
        length = max(w, h)
        s = np.arange(0.0, length + 1e-9, step)
        return np.column_stack([x0 + s * (w > 0), y0 + s * (h > 0)])
    s = np.arange(0.0, 2 * (w + h) - 1e-9, step)
    x = np.select([s < h, s < h + w, s < 2 * h + w], [np.full_like(s, x0), x0 + (s - h), np.full_like(s, x1)],
                  x1 - (s - 2 * h - w))
    y = np.select([s < h, s < h + w, s < 2 * h + w], [y0 + s, np.full_like(s, y1), y1 - (s - h - w)], np.full_like(s, y0))
    return np.column_stack([x, y])


def contours(bounds, engagement, step) -> list[np.ndarray]:
    """Plunge points of the nested rectangles, outermost first."""
    (x0, y0, _), (x1, y1, _) = bounds
    out = []
    k = 0
    while x0 + k * engagement <= x1 - k * engagement + 1e-9 and y0 + k * engagement <= y1 - k * engagement + 1e-9:
        e = k * engagement
        out.append(rectangle_points(x0 + e, y0 + e, max(x0 + e, x1 - e), max(y0 + e, y1 - e), step))
        k += 1
    return out


def grown_tool_drop(tool, allowance, kern, floor):
    """Drop heights of the real tip of ``tool`` kept ``allowance`` mm from the solid of ``kern``
    (:class:`~meshmill.kernels.backend.MeshKernels`): a callable
    ``xy (k, 2) -> (tip (k,), contact (k, 3))``, tips never below ``floor``, contacts the mesh
    points touched (NaN where none is)."""
    a = allowance
    body_r = [0.5 * tool.shank_diameter + a]
    body_t = [tool.flute_length]
    if tool.holder_diameter > 0:
        body_r.append(0.5 * tool.holder_diameter + a)
        body_t.append(tool.gauge_length)
    body = (np.array(body_r), np.array(body_t))

    def drop(xy):
        z, contact = kern.drop_cutter(xy, tool.radius + a, tool.corner_radius + a, floor - a, body)
        return z + a, contact

    return drop


class BoxStock:
    """The stock of a plunge operation (the part's box) and how far a tool plunging along -u into it
    may go: the lowest position where the parts that do not follow the cutter into its hole (shank
    and holder wider than the cutter less the clearance) keep ``HOLDER_CLEARANCE`` from it
    (:meth:`reach`), and the lowest where the whole tool does (:meth:`approach`: a rapid may come
    that far)."""

    def __init__(self, bounds, tool, device):
        lo, hi = bounds
        self.mesh = box(lo, hi)
        self.kern = solid_kernels(self.mesh, device)
        self.tool = tool
        cyl = tool.cylinders()
        t, rho, r, _ = tool.ring()
        self.whole = self._parts([(a, b, rad) for a, b, rad, _ in cyl], (t, rho, r))
        wide = [(a, b, rad) for a, b, rad, cut in cyl if not cut and rad + HOLDER_CLEARANCE > tool.radius]
        self.wide = self._parts(wide, None) if wide else None

    @staticmethod
    def _parts(cylinders, ring):
        t0 = np.array([[c[0] for c in cylinders] or [0.0]])
        t1 = np.array([[c[1] for c in cylinders] or [0.0]])
        r = np.array([[c[2] for c in cylinders] or [0.0]])
        t, rho, rr = ring if ring is not None else (0.0, 0.0, 0.0)
        rings = (np.array([t]), np.array([rho]), np.array([rr]), np.array([1 if rho == 0 else 36]))
        return rings, (t0, t1, r), t0

    def _lowest(self, parts, origin, u, t_lo, t_hi):
        """Per line ``origin (k, 3) + t u``: the lowest t in [t_lo, t_hi] (k,) above which the
        ``parts``, grown by the clearance, stay out of the stock, coming down from t_hi."""
        rings, segs, base = parts
        k = len(origin)
        t_lo = np.broadcast_to(np.asarray(t_lo, float), (k,)).copy()
        t_hi = np.broadcast_to(np.asarray(t_hi, float), (k,)).copy()
        if k == 0:
            return t_lo
        axis = np.tile(u, (k, 1))

        def clear(t):
            ring, seg = self.kern.pose_penetration(origin + t[:, None] * u, axis, np.zeros(k, np.int32),
                                                   np.full(k, HOLDER_CLEARANCE), rings, segs, base)
            return (ring <= 0.0) & (seg.max(axis=1) <= 0.0)

        above = t_hi.copy()  # the lowest position known clear, all the way from t_hi
        below = t_lo.copy()
        found = np.zeros(k, bool)
        for j in range(1, REACH_SAMPLES + 1):  # the first contact, coming down
            t = t_hi + (t_lo - t_hi) * j / REACH_SAMPLES
            ok = clear(t)
            hit = ~ok & ~found
            below[hit] = t[hit]
            found |= hit
            above[~found] = t[~found]
        for _ in range(50):
            mid = 0.5 * (above + below)
            ok = clear(mid)
            above = np.where(found & ok, mid, above)
            below = np.where(found & ~ok, mid, below)
        return np.where(found, above, t_lo)

    def reach(self, origin, u, t_lo, t_hi):
        """How low (k,) the tip may plunge: where the wide shank and holder would come too near."""
        return self._lowest(self.wide, origin, u, t_lo, t_hi) if self.wide else np.asarray(t_lo, float)

    def approach(self, origin, u, t_lo, t_hi):
        """Where (k,) a rapid along -u must stop: the whole tool clear of the stock by the clearance."""
        return self._lowest(self.whole, origin, u, t_lo, t_hi)


def layers(entry, end, flute_length):
    """The bottoms ``(j,)`` of the layers of one plunge from ``entry`` down to ``end`` (along its
    axis): each at most the flute length deeper than the one before."""
    depth = entry - end
    n = max(1, int(math.ceil(depth / flute_length - 1e-9)))
    return np.maximum(end, entry - flute_length * np.arange(1, n + 1))


def plunge_moves(origin, u, clear, approach, bottoms):
    """``(tips (m, 3), rapid (m,))`` of one plunge along -u from the line ``origin + t u``: rapid to
    ``clear`` (already there, or the way there is the caller's), down to ``approach``, feed to each
    bottom and back up to ``approach``, rapid back to ``clear``."""
    tips, rapid = [origin + clear * u, origin + approach * u], [True, True]
    for b in bottoms:
        tips += [origin + b * u, origin + approach * u]
        rapid += [False, False]
    tips.append(origin + clear * u)
    rapid.append(True)
    return tips, rapid


def _verified(mesh, tools, index, tips, axes, rapid, say, device, stock: BoxStock):
    """The tool path of the plunges and its verification report (a clear error when empty): rapids
    keep out of the stock's box."""
    if not tips:
        raise NothingToCut("nothing to cut: no plunge removes stock (the part fills its box, or the allowance is too "
                          "large)", "allowance")
    tp = Toolpath(np.array(tips, np.float64), np.array(axes, np.float64), np.array(rapid),
                  np.full(len(tips), index, np.int64))
    say("verify")
    report = verify_toolpath(solid_kernels(mesh, device), tp, tools, GOUGE_TOL, DEFAULT_STEP,
                             stock=StockCheck(kern=stock.kern, feed_body=False))  # layers make room for the shank
    report.pop("problem_moves")
    return tp, report


def _summary(axes, tool, bounds, tp, report, depths, t0, params, fields, left=(), n_layers=(), **extra):
    """``summary.json`` of a plunge operation: the common figures, ``extra``, then the parameters.
    ``depths (k,)`` of the plunges, ``left (k,)`` the depth each leaves uncut for the shank and
    holder, ``n_layers (k,)`` their layers."""
    depths = np.asarray(depths)
    left = np.asarray(left, float).reshape(-1)
    n_layers = np.asarray(n_layers, int).reshape(-1)
    return {
        "operation": "plunge",
        "axes": axes,
        "tool": tool.name,
        "stock": np.round(bounds, 6).tolist(),
        **extra,
        "valid_plunges": int(len(depths)),
        "depth_mm": {"min": float(depths.min()), "max": float(depths.max()), "mean": float(depths.mean())},
        "flute_length": tool.flute_length,
        "plunges_in_layers": int((n_layers > 1).sum()),
        "layers_max": int(n_layers.max(initial=1)),
        "plunges_short_of_the_part": int((left > 1e-9).sum()),
        "left_by_shank_and_holder_mm": float(left.max(initial=0.0)),
        "cl_points": len(tp),
        "moves": len(tp),
        "cutting_length": tp.cutting_length(),
        "verify": report,
        "seconds": {"total": round(time.perf_counter() - t0, 4)},
        **{k: getattr(params, k) for k in fields},
    }


def _turned_drop(mesh, tool, allowance, centre, u, floor, device):
    """``(frame (3, 3), drop)``: the tool frame of axis u (rows T1, T2, U) and the grown-tool drop
    over the part turned into it, about ``centre``, never below ``floor`` along u."""
    frame = np.stack([*tool_frame(u), u])
    turned = mesh.transformed(frame, -centre @ frame.T)
    lo, hi = mesh.bounds
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    bottom = float(((corners - centre) @ u).min())  # the stock's floor seen along u: sheets reach down to it
    return frame, grown_tool_drop(tool, allowance, solid_kernels(turned, device, bottom), floor)


def stock_box(stock, mesh) -> np.ndarray:
    """``(2, 3)``: the box of ``stock`` (a :class:`~meshmill.simulation.stock.Stock`, a closed
    mesh, or None: the part's box) around ``mesh``."""
    from ..simulation.stock import Stock

    stock = Stock.of(stock)
    if stock is None:
        return mesh.bounds
    solid, allowance, _ = stock.material(mesh)
    return solid.bounds if solid is not None else mesh.bounds + np.array([[-1.0], [1.0]]) * allowance


def plunge3(mesh, tools, tool_name, params: PlungeParams, progress=None):
    """3-axis plunge roughing of ``mesh`` from the box of ``params.stock`` (default: the part's
    box; plunges cover its XY and start at its top). Returns ``(toolpath, summary)``."""
    say = progress or (lambda stage: None)
    params = replace(params, device=resolve(params.device))
    index, tool = pick_tool(tools, tool_name)
    t0 = time.perf_counter()
    bounds = stock_box(params.stock, mesh)
    z_min, z_max = float(mesh.bounds[0, 2]), float(bounds[1, 2])
    if params.engagement > 2 * tool.radius:
        raise InputError(f"engagement {params.engagement:g} mm is wider than the tool ({tool.diameter:g} mm): "
                         "stock would be left between the contours", "engagement")
    rings = contours(bounds, params.engagement, params.radial_step)
    n_points = sum(len(r) for r in rings)
    if n_points > 5_000_000:
        raise InputError(f"{n_points:,} plunge points: use a larger radial_step or engagement",
                         ("radial_step", "engagement"))
    say(f"{len(rings)} contours, {n_points} plunge points")
    drop = grown_tool_drop(tool, params.allowance, solid_kernels(mesh, params.device), z_min)
    stock = BoxStock(bounds, tool, params.device)
    clear_z = z_max + params.clearance
    up = np.array([0.0, 0.0, 1.0])
    plunges = []  # per kept point: origin, approach, bottoms (one per layer)
    depths, left, n_layers, contour_of = [], [], [], []
    for k, xy in enumerate(rings):
        z = drop(xy)[0]
        keep = z < z_max - 1e-9
        xy, z = xy[keep], z[keep]
        origin = np.column_stack([xy, np.zeros(len(xy))])
        reach = stock.reach(origin, up, z, clear_z)
        end = np.maximum(z, reach)
        approach = stock.approach(origin, up, z_max, clear_z)
        for o, e, zz, a in zip(origin, end, z, approach):
            if e >= z_max - 1e-9:
                continue  # the shank or holder keeps it from the stock
            bottoms = layers(z_max, e, tool.flute_length)
            plunges.append((o, a, bottoms))
            depths.append(z_max - e)
            left.append(e - zz)
            n_layers.append(len(bottoms))
            contour_of.append(k)
    tips, rapid = [], []
    for layer in range(max(n_layers, default=0)):  # every plunge of a layer before the next
        for o, a, bottoms in plunges:
            if layer < len(bottoms):
                t, r = plunge_moves(o, up, clear_z, a, bottoms[layer:layer + 1])
                tips += t
                rapid += r
    tp, report = _verified(mesh, tools, index, tips, np.tile(up, (len(tips), 1)), rapid, say, params.device, stock)
    return tp, _summary(3, tool, bounds, tp, report, depths, t0, params,
                        ("radial_step", "engagement", "allowance", "clearance"), left, n_layers, contours=len(rings),
                        plunges=int(n_points), valid_per_contour=np.bincount(contour_of, minlength=len(rings)).tolist(),
                        clearance_z=clear_z)


def _slab(c, u, lo, hi):
    """``(t_in, t_out)``: the line c + t u against the box [lo, hi] (c inside)."""
    with np.errstate(divide="ignore"):
        a = (lo - c) / u
        b = (hi - c) / u
    return float(np.max(np.minimum(a, b))), float(np.min(np.maximum(a, b)))


def _arc(a, b, centre, radius):
    """Points after ``a`` up to ``b`` along the great circle of the sphere through both."""
    ua, ub = (a - centre) / radius, (b - centre) / radius
    angle = math.acos(max(-1.0, min(1.0, float(ua @ ub))))
    n = max(1, math.ceil(angle / ARC_STEP))
    if angle < 1e-12:
        return [b]
    out = []
    for k in range(1, n + 1):
        t = k / n
        w = (math.sin((1 - t) * angle) * ua + math.sin(t * angle) * ub) / math.sin(angle)
        out.append(centre + radius * w)
    return out


def plunge5(mesh, tools, tool_name, params: PlungeParams, progress=None):
    """5-axis plunge roughing from the hemisphere of directions. Returns ``(toolpath, summary)``."""
    from ..geometry.analysis import hemisphere

    say = progress or (lambda stage: None)
    params = replace(params, device=resolve(params.device))
    index, tool = pick_tool(tools, tool_name)
    t0 = time.perf_counter()
    lo, hi = mesh.bounds
    centre = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(hi - centre)) + params.clearance + tool.radius
    dirs = hemisphere(params.theta_step, params.delta_step)
    say(f"{len(dirs)} plunge directions")
    stock = BoxStock(mesh.bounds, tool, params.device)
    if params.regions:
        return _plunge_regions(mesh, tools, index, tool, params, dirs, centre, radius, say, t0, stock)
    tips, axes, rapid, depths, left, n_layers = [], [], [], [], [], []
    last = None
    for u in dirs:
        t_in, t_out = _slab(centre, u, lo, hi)  # along u from the centre: exit behind (t_in < 0), entry ahead
        _, drop = _turned_drop(mesh, tool, params.allowance, centre, u, t_in, params.device)
        h = float(drop(np.zeros((1, 2)))[0][0])
        end = max(h, float(stock.reach(centre[None], u, h, radius)[0]))
        if end >= t_out - 1e-9:
            continue  # the tip never gets into the stock
        approach = float(stock.approach(centre[None], u, t_out, radius)[0])
        start = centre + radius * u
        if last is not None:
            for p in _arc(last, start, centre, radius):
                tips.append(p)
                axes.append((p - centre) / radius)
                rapid.append(True)
        bottoms = layers(t_out, end, tool.flute_length)
        t, r = plunge_moves(centre, u, radius, approach, bottoms)
        if last is not None:
            t, r = t[1:], r[1:]  # the arc ends where the plunge starts
        tips += t
        axes += [u] * len(t)
        rapid += r
        depths.append(t_out - end)
        left.append(end - h)
        n_layers.append(len(bottoms))
        last = start
    tp, report = _verified(mesh, tools, index, tips, axes, rapid, say, params.device, stock)
    return tp, _summary(5, tool, mesh.bounds, tp, report, depths, t0, params, ("allowance", "clearance", "theta_step",
                                                                         "delta_step"), left, n_layers,
                        sphere={"centre": centre.round(6).tolist(), "radius": radius}, plunges=len(dirs))


def _direction_plunges(mesh, tool, params, u, centre, lo, hi, stock, radius):
    """Plunges along -u on a grid of ``radial_step`` over the stock's shadow: ``(xy (k, 2) in the
    tool frame, tip (k,) and entry (k,) along u from the centre, contact (k, 3) world, NaN: none,
    left (k,) the depth the shank and holder leave)``, only those that get into the stock."""
    t1, t2 = tool_frame(u)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    shadow = (corners - centre) @ np.stack([t1, t2]).T
    a = np.arange(shadow[:, 0].min(), shadow[:, 0].max() + 1e-9, params.radial_step)
    b = np.arange(shadow[:, 1].min(), shadow[:, 1].max() + 1e-9, params.radial_step)
    X, Y = np.meshgrid(a, b, indexing="ij")
    Y[1::2] = Y[1::2, ::-1]  # serpentine: short moves between neighbours
    xy = np.column_stack([X.ravel(), Y.ravel()])
    origin = centre + xy[:, :1] * t1 + xy[:, 1:] * t2
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (lo - origin) / u
        tb = (hi - origin) / u
    t_exit = np.max(np.where(u != 0, np.minimum(ta, tb), -np.inf), axis=1)
    t_entry = np.min(np.where(u != 0, np.maximum(ta, tb), np.inf), axis=1)
    inside_slab = np.all((u != 0) | ((origin >= lo) & (origin <= hi)), axis=1)
    crosses = inside_slab & (t_exit < t_entry)
    xy, t_exit, t_entry = xy[crosses], t_exit[crosses], t_entry[crosses]
    if not len(xy):
        return xy, t_exit, t_entry, np.empty((0, 3)), t_exit
    frame, drop = _turned_drop(mesh, tool, params.allowance, centre, u, float(t_exit.min()), params.device)
    z, contact = drop(xy)
    tip = np.maximum(z, t_exit)
    contact = np.where(np.isnan(contact), np.nan, centre + contact @ frame)
    contact[tip <= t_exit + 1e-12] = np.nan  # resting on the stock's far side, not on the part
    t1, t2 = tool_frame(u)
    reach = stock.reach(centre + xy[:, :1] * t1 + xy[:, 1:] * t2, u, tip, radius)
    end = np.maximum(tip, reach)
    keep = end < t_entry - 1e-9
    return xy[keep], end[keep], t_entry[keep], contact[keep], (end - tip)[keep]


def _plunge_regions(mesh, tools, index, tool, params, dirs, centre, radius, say, t0, stock):
    """Region mode: the part's triangles in ``params.regions`` k-means regions; every direction
    plunges a grid over the stock's shadow; each region keeps the direction whose plunges resting
    on it remove the most stock (axial length in the stock); plunges touching no part go with the
    direction that has the most of them."""
    from scipy.spatial import cKDTree

    from ..simulation.partition import kmeans_labels

    lo, hi = mesh.bounds
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    k = min(params.regions, len(cent))
    labels = kmeans_labels(cent, k)
    tree = cKDTree(cent)
    per_dir = []
    gain = np.zeros((len(dirs), k + 1))  # last column: plunges resting on no part
    for d, u in enumerate(dirs):
        xy, tip, entry, contact, short = _direction_plunges(mesh, tool, params, u, centre, lo, hi, stock, radius)
        region = np.full(len(xy), k)
        touched = ~np.isnan(contact[:, 0])
        if touched.any():
            region[touched] = labels[tree.query(contact[touched])[1]]
        np.add.at(gain[d], region, entry - tip)
        per_dir.append((xy, tip, entry, region, short))
    best = np.argmax(gain, axis=0)
    say(f"{k} regions; {len(set(best.tolist()))} directions chosen")
    tips, axes, rapid, depths, left, n_layers = [], [], [], [], [], []
    last = None
    for d, u in enumerate(dirs):
        xy, tip, entry, region, short = per_dir[d]
        chosen = np.isin(region, np.nonzero(best == d)[0]) & (gain[d, region] > 0)
        if not chosen.any():
            continue
        t1, t2 = tool_frame(u)
        pole = centre + radius * u
        if last is not None:  # across the last plane to its pole, along the sphere, then in this plane
            tips.append(last[0])
            axes.append(last[1])
            rapid.append(True)
            for p in _arc(last[0], pole, centre, radius):
                tips.append(p)
                axes.append((p - centre) / radius)
                rapid.append(True)
        origin = centre + xy[chosen, :1] * t1 + xy[chosen, 1:] * t2
        approach = stock.approach(origin, u, entry[chosen], radius)
        plunges = [(o, a, layers(e, h, tool.flute_length)) for o, a, e, h in
                   zip(origin, approach, entry[chosen], tip[chosen])]
        for layer in range(max(len(p[2]) for p in plunges)):
            for o, a, bottoms in plunges:
                if layer < len(bottoms):
                    t, r = plunge_moves(o, u, radius, a, bottoms[layer:layer + 1])
                    tips += t
                    axes += [u] * len(t)
                    rapid += r
        depths += list(entry[chosen] - tip[chosen])
        left += list(short[chosen])
        n_layers += [len(p[2]) for p in plunges]
        last = (pole, u)
    tp, report = _verified(mesh, tools, index, tips, axes, rapid, say, params.device, stock)
    return tp, _summary(5, tool, mesh.bounds, tp, report, depths, t0, params,
                        ("radial_step", "allowance", "clearance", "theta_step", "delta_step"), left, n_layers,
                        mode="regions",
                        regions=k, directions=len(dirs),
                        region_directions=[dirs[b].round(6).tolist() if gain[b, j] > 0 else None
                                           for j, b in enumerate(best[:k])],
                        plunges=int(sum(len(p[0]) for p in per_dir)))
