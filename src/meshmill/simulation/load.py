"""The load of every move: what it removes from the in-process stock, how deep and how wide,
the chip it makes and the power it takes.

While a path is cut from the dexel stock (:func:`meshmill.simulation.cut.cut` with ``load``),
each line a move cuts reports the length it removed and where that material began and ended;
from these the move's volume (the mean of the three directions' dexels, ``step²`` per mm), the
extent of the material it removed along its axis (the axial depth ``ap``: the engaged length of
the flutes; and its top above the lowest tip, ``height``, which sets the diameter at work) and
across its feed (the radial width ``ae``, measured from the tool's centre line: which side it
engaged) are gathered exactly on the dexels: the X and Y lines give the extents across a
vertical tool's feed where they end, the Z lines the heights.

From these and the tool's cutting data (:class:`~meshmill.tools.cutting.Cutting`) follow, per
move (mm, mm/min, s, kW):

- the effective diameter at the top of the cut (h above the tip): a ball ``2 sqrt(h (D - h))``,
  a bull-nose ``D - 2 rc + 2 sqrt(h (2 rc - h))`` while h is under the corner;
- the engagement angle from the extent across the feed (w from the centre line: the tooth is
  in the material from ``acos(w_hi / R)`` to ``acos(w_lo / R)``; a side cut of width ae gives
  ``acos(1 - 2 ae / D)``, a slot 180°); a move down the axis (a plunge) engages the whole tool;
- the chip: feed per tooth ``fz = F / (z n)``, its largest thickness ``fz sin`` of the angle
  nearest 90° in the engagement (chip thinning at small widths) and its mean ``fz (w_hi - w_lo)
  / (R phi)``;
- the removal rate: volume over time, over a window of the path about one diameter long (a
  single move's volume is counted on dexels ``step`` apart);
- the power: removal rate times the material's specific cutting energy at that mean chip
  (:class:`~meshmill.tools.cutting.Material`), and the torque at the spindle speed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

LOAD_SLACK = 0.05  # share a measured depth, width or chip may exceed the tool's limit (dexel resolution)
PLUNGE_COS = math.cos(math.radians(10.0))  # a move within 10° of down its axis is a plunge (engages the whole tool)
DEFAULT_CHIP = 0.05  # mm: the mean chip costed where the tool gives no feed per tooth


def move_probe(moves) -> np.ndarray:
    """``(k, 6)``: each move's unit axis (at its end) and unit vector across its feed (axis x
    motion; zero for a move along its axis or of no length), world frame."""
    x = np.asarray(moves.xb, float)
    across = np.cross(x, np.asarray(moves.pb, float) - np.asarray(moves.pa, float))
    size = np.linalg.norm(across, axis=1, keepdims=True)
    across = np.divide(across, size, out=np.zeros_like(across), where=size > 1e-9)
    probe = np.hstack([x, across])
    probe[np.asarray(moves.body, bool)] = 0.0
    return np.ascontiguousarray(probe)


def reduce_load(load: np.ndarray) -> np.ndarray:
    """``(k, 5)``: the threads' load ``(T, k, 5)`` of :meth:`~meshmill.kernels.backend.
    DexelKernels.new_load` in one (length removed summed; the extents' highest along the axis,
    lowest and highest across the feed, lowest along the axis)."""
    return merge_loads(list(load))


def merge_loads(loads: list) -> np.ndarray:
    """``(k, 5)``: loads of the same moves over different lines in one."""
    out = loads[0].copy()
    for ld in loads[1:]:
        out[:, 0] += ld[:, 0]
        out[:, 1] = np.maximum(out[:, 1], ld[:, 1])
        out[:, 2] = np.minimum(out[:, 2], ld[:, 2])
        out[:, 3] = np.maximum(out[:, 3], ld[:, 3])
        out[:, 4] = np.minimum(out[:, 4], ld[:, 4])
    return out


@dataclass
class RemovedByMove:
    """What each tool-path point's move removed (k points): ``volume (k,)`` mm³, ``height (k,)``
    mm the top of it along the axis above the move's lowest tip, ``depth (k,)`` mm its extent
    along the axis, ``across (k, 2)`` mm its extent across the feed from the tool's centre line
    (NaN where it removed nothing; ``across`` also for a move along its axis)."""

    volume: np.ndarray
    height: np.ndarray
    depth: np.ndarray
    across: np.ndarray

    @staticmethod
    def of(moves, per_direction: list, step: float, points: int, probe) -> "RemovedByMove":
        """From the cutter moves ``moves`` (pieces of ``points`` tool-path points), each
        direction's ``(k, 5)`` gathered load (:func:`reduce_load`) and the moves' ``probe``
        (:func:`move_probe`) it was gathered with."""
        g = np.stack(per_direction)  # (3, k, 5)
        volume = g[:, :, 0].mean(axis=0) * step * step
        top, bottom = g[:, :, 1].max(axis=0), g[:, :, 4].min(axis=0)
        lo, hi = g[:, :, 2].min(axis=0), g[:, :, 3].max(axis=0)
        x, n = probe[:, :3], probe[:, 3:]
        pa, pb = np.asarray(moves.pa, float), np.asarray(moves.pb, float)
        low = np.minimum(np.einsum("ij,ij->i", pa, x), np.einsum("ij,ij->i", pb, x))
        centre = np.einsum("ij,ij->i", pb, n)
        cut = ~np.asarray(moves.body, bool) & (volume > 0) & np.isfinite(top)
        side = cut & (np.abs(n).sum(axis=1) > 0) & np.isfinite(lo)
        src = np.asarray(moves.source)
        out_v = np.zeros(points)
        np.add.at(out_v, src[cut], volume[cut])
        height, depth = np.full(points, -np.inf), np.full(points, -np.inf)
        np.maximum.at(height, src[cut], top[cut] - low[cut])
        np.maximum.at(depth, src[cut], top[cut] - bottom[cut])  # per piece: a turning move's axes differ
        w_lo, w_hi = np.full(points, np.inf), np.full(points, -np.inf)
        np.minimum.at(w_lo, src[side], lo[side] - centre[side])
        np.maximum.at(w_hi, src[side], hi[side] - centre[side])
        height[~np.isfinite(height)] = np.nan
        depth[~np.isfinite(depth)] = np.nan
        across = np.column_stack([w_lo, w_hi])
        across[~np.isfinite(across)] = np.nan
        return RemovedByMove(out_v, np.maximum(height, 0.0), np.maximum(depth, 0.0), across)


def effective_diameter(tool, height):
    """mm ``(k,)``: the diameter of ``tool`` (:class:`~meshmill.tools.table.Tool`) at ``height
    (k,)`` mm above its tip."""
    ap = np.maximum(np.asarray(height, float), 0.0)
    D, rc = tool.diameter, tool.corner_radius
    if tool.type == "flat" or rc <= 0:
        return np.full(ap.shape, D)
    a = np.minimum(ap, rc)
    return D - 2 * rc + 2 * np.sqrt(a * (2 * rc - a))


@dataclass
class MoveLoad:
    """The load of each tool-path point's move (k points; NaN where not a feed move in material):
    ``volume`` mm³, ``ap`` (the engaged length along the axis), ``height`` (the top of the cut
    above the tip), ``ae``, ``diameter`` (effective, at that height) mm, ``angle`` degrees of
    engagement, ``fz`` mm per tooth as programmed, ``chip_max`` and ``chip_mean`` mm, ``rate``
    mm³/min (windowed), ``power`` kW, ``torque`` Nm, ``feed`` mm/min, ``plunge (k,) bool``,
    ``in_material (k,) bool``."""

    volume: np.ndarray
    ap: np.ndarray
    height: np.ndarray
    ae: np.ndarray
    diameter: np.ndarray
    angle: np.ndarray
    fz: np.ndarray
    chip_max: np.ndarray
    chip_mean: np.ndarray
    rate: np.ndarray
    power: np.ndarray
    torque: np.ndarray
    feed: np.ndarray
    plunge: np.ndarray
    in_material: np.ndarray

    def arrays(self) -> dict:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def move_feeds(toolpath, conditions, nominal: float) -> np.ndarray:
    """mm/min ``(k,)`` each move is fed at: as programmed, else its tool's cutting feed
    (``conditions``: a :class:`~meshmill.tools.cutting.Cutting` per tool), else ``nominal``."""
    feed = np.asarray(toolpath.feed, float).copy()
    tool_feed = np.array([c.feed or nominal for c in conditions])
    unset = ~np.isfinite(feed) | (feed <= 0)
    feed[unset] = tool_feed[np.asarray(toolpath.tool)[unset]]
    return feed


def _windowed_rate(volume, seconds, length, tool_of, window) -> np.ndarray:
    """mm³/min ``(k,)``: volume over time of the moves within ``window (k,)`` mm of path around
    each move, among the consecutive moves of one tool."""
    k = len(volume)
    rate = np.zeros(k)
    change = np.r_[0, np.nonzero(np.diff(tool_of))[0] + 1, k]
    for a, b in zip(change[:-1], change[1:]):
        cl = np.r_[0.0, np.cumsum(length[a:b])]
        cv = np.r_[0.0, np.cumsum(volume[a:b])]
        ct = np.r_[0.0, np.cumsum(seconds[a:b])]
        mid = 0.5 * (cl[:-1] + cl[1:])
        half = 0.5 * np.maximum(window[a:b], length[a:b])
        i0 = np.searchsorted(cl, mid - half, side="right") - 1
        i1 = np.searchsorted(cl, mid + half, side="left")
        i0, i1 = np.clip(i0, 0, b - a), np.clip(i1, 0, b - a)
        t = ct[i1] - ct[i0]
        rate[a:b] = np.divide(cv[i1] - cv[i0], t, out=np.zeros(b - a), where=t > 0) * 60.0
    return rate


def move_loads(toolpath, removed: RemovedByMove, tools, conditions, material, nominal_feed: float,
               step: float) -> MoveLoad:
    """The :class:`MoveLoad` of ``toolpath``'s moves from what they removed (``removed``), the
    tools' ``conditions`` (a :class:`~meshmill.tools.cutting.Cutting` per tool), the workpiece
    ``material`` (:class:`~meshmill.tools.cutting.Material` or None: no power), the feed where
    neither the path nor the tool gives one (``nominal_feed`` mm/min) and the dexels' ``step``."""
    with np.errstate(invalid="ignore", divide="ignore"):  # NaN where a move is not in material
        return _move_loads(toolpath, removed, tools, conditions, material, nominal_feed, step)


def _move_loads(toolpath, removed, tools, conditions, material, nominal_feed, step) -> MoveLoad:
    k = len(toolpath)
    tip = np.asarray(toolpath.tip, float)
    axis = np.asarray(toolpath.axis, float)
    tool_of = np.asarray(toolpath.tool)
    rapid = np.asarray(toolpath.rapid, bool)
    move = np.vstack([np.zeros((1, 3)), np.diff(tip, axis=0)])
    length = np.linalg.norm(move, axis=1)
    feed = move_feeds(toolpath, conditions, nominal_feed)
    feed[rapid] = np.nan
    seconds = np.where(rapid | (length == 0), 0.0, 60.0 * length / np.where(np.isfinite(feed), feed, 1.0))
    in_material = ~rapid & (removed.volume > 0) & np.isfinite(removed.height)
    down = -np.einsum("ij,ij->i", move, axis) / np.maximum(length, 1e-12)
    plunge = in_material & (down >= PLUNGE_COS)
    nan = np.full(k, np.nan)
    ap = np.where(in_material, removed.depth, np.nan)
    height = np.where(in_material, removed.height, np.nan)
    D = nan.copy()
    for t in np.unique(tool_of[in_material]):
        mine = in_material & (tool_of == t)
        D[mine] = effective_diameter(tools[int(t)], height[mine])
    R = 0.5 * D
    w_lo = np.clip(removed.across[:, 0], -R, R)
    w_hi = np.clip(removed.across[:, 1], -R, R)
    full = plunge | ~np.isfinite(w_lo)
    w_lo, w_hi = np.where(full, -R, w_lo), np.where(full, R, w_hi)
    psi_s = np.arccos(np.clip(w_hi / R, -1.0, 1.0))
    psi_e = np.arccos(np.clip(w_lo / R, -1.0, 1.0))
    phi = np.maximum(psi_e - psi_s, 0.0)
    ae = w_hi - w_lo
    rpm = np.array([c.rpm for c in conditions])[tool_of]
    z = np.array([c.flutes for c in conditions])[tool_of]
    known = in_material & (rpm > 0) & (z > 0)
    fz = np.where(known, feed / np.where(known, rpm * z, 1.0), np.nan)
    sin_max = np.where((psi_s <= 0.5 * np.pi) & (psi_e >= 0.5 * np.pi), 1.0,
                       np.maximum(np.sin(psi_s), np.sin(psi_e)))
    chip_max = fz * sin_max
    chip_mean = np.where(phi > 0, fz * ae / np.where(phi > 0, R * phi, 1.0), 0.0)
    window = np.where(np.isfinite(D), np.maximum(D, 2 * step), 2 * step)
    rate = np.where(in_material, _windowed_rate(np.where(in_material, removed.volume, 0.0), seconds, length, tool_of,
                                                window), np.nan)
    power = torque = nan
    if material is not None:
        chip = np.where(np.isfinite(chip_mean) & (chip_mean > 0), chip_mean, DEFAULT_CHIP)
        power = material.specific_energy(chip) * rate / 60.0 / 1e6  # N/mm² * mm³/s = mW
        torque = np.where(rpm > 0, power * 1000.0 / (2 * np.pi * np.maximum(rpm, 1e-9) / 60.0), np.nan)
    out = MoveLoad(volume=np.where(in_material, removed.volume, 0.0), ap=ap, height=height,
                   ae=np.where(in_material, ae, np.nan),
                   diameter=D, angle=np.where(in_material, np.degrees(phi), np.nan), fz=fz,
                   chip_max=np.where(in_material, chip_max, np.nan), chip_mean=np.where(in_material, chip_mean, np.nan),
                   rate=rate, power=np.where(in_material, power, np.nan), torque=np.where(in_material, torque, np.nan),
                   feed=feed, plunge=plunge, in_material=in_material)
    return out


LIMITS = (  # (figure, what it is, unit); the flutes' length is the cut's own check (a shank meeting the stock)
    ("section", "cut section ap x ae", "mm²"), ("chip", "chip load", "mm"),
    ("plunge", "plunge feed", "mm/min"), ("power", "spindle power", "kW"), ("torque", "spindle torque", "Nm"))


def _values(load: MoveLoad) -> dict:
    """``{figure: (k,) value}`` of each move, as :data:`LIMITS` names them."""
    return {"section": load.ap * load.ae, "chip": load.chip_max, "plunge": load.feed,
            "power": load.power, "torque": load.torque}


def limits_of(toolpath, conditions, spindle, load: MoveLoad) -> dict:
    """``{figure: (k,) limit}`` each move is held to (inf where none applies). The tool's largest
    depth and width are taken as the section it is rated for, ``ap x ae``: a cut may trade one
    for the other (deep and light, shallow and wide) but not load the tool more."""
    tool_of = np.asarray(toolpath.tool)
    k = len(tool_of)
    inf = np.full(k, np.inf)
    by = lambda f: np.array([f(c) for c in conditions], float)[tool_of]  # noqa: E731
    side = ~load.plunge
    return {
        "section": np.where(side, by(lambda c: c.ap * c.ae), np.inf),
        "chip": np.where(side, by(lambda c: c.fz if c.known else np.inf), np.inf),
        "plunge": np.where(load.plunge, by(lambda c: c.plunge_feed if c.known else np.inf), np.inf),
        "power": inf if spindle is None or not spindle.power_kw else np.full(k, spindle.power_kw),
        "torque": inf if spindle is None or not spindle.torque_nm else np.full(k, spindle.torque_nm),
    }


def over_limits(load: MoveLoad, limits: dict) -> dict:
    """``{figure: (k,) bool}``: the moves in material over each of ``limits`` (:func:`limits_of`)
    by more than :data:`LOAD_SLACK`."""
    with np.errstate(invalid="ignore"):
        return {figure: load.in_material & np.isfinite(value) & (value > limits[figure] * (1 + LOAD_SLACK))
                for figure, value in _values(load).items()}


def overloads(toolpath, tools, load: MoveLoad, limits: dict, over: dict) -> list:
    """One line per tool and limit its moves are ``over`` (:func:`over_limits`), with how many,
    the worst and where."""
    values = _values(load)
    tool_of = np.asarray(toolpath.tool)
    errors = []
    for figure, what, unit in LIMITS:
        value = values[figure]
        for t in np.unique(tool_of[over[figure]]):
            mine = np.nonzero(over[figure] & (tool_of == t))[0]
            worst = mine[np.argmax(value[mine] / limits[figure][mine])]
            tool = tools[int(t)]
            shown = (f"{load.ap[worst]:.3g} x {load.ae[worst]:.3g} mm" if figure == "section"
                     else f"{value[worst]:.4g} {unit}")
            errors.append(f"{len(mine)} move(s) of T{tool.number} '{tool.name}' over its {what} of "
                          f"{limits[figure][worst]:.4g} {unit}: up to {shown} at move {int(worst)} "
                          f"({', '.join(f'{c:.3f}' for c in toolpath.tip[worst])})")
    return errors


def _spread(values) -> dict | None:
    values = np.asarray(values, float)
    values = values[np.isfinite(values)]
    if not len(values):
        return None
    q = np.percentile(values, [50, 95])
    return {"median": round(float(q[0]), 6), "p95": round(float(q[1]), 6), "max": round(float(values.max()), 6)}


def load_summary(toolpath, tools, conditions, spindle, material, load: MoveLoad) -> dict:
    """summary.json's ``load``: per tool its limits and the distributions of its moves in
    material (depth, width, engagement, chip, removal rate, power), the moves over a limit, and
    the errors (:func:`overloads`)."""
    limits = limits_of(toolpath, conditions, spindle, load)
    over = over_limits(load, limits)
    errors = overloads(toolpath, tools, load, limits, over)
    tool_of = np.asarray(toolpath.tool)
    per_tool = []
    for t in np.unique(tool_of[~np.asarray(toolpath.rapid, bool)]):
        mine = (tool_of == t) & load.in_material
        c = conditions[int(t)]
        feed_moves = (tool_of == t) & ~np.asarray(toolpath.rapid, bool)
        entry = {
            "tool": tools[int(t)].name, "material": c.material or None,
            "cutting": {"rpm": round(c.rpm, 1), "fz_mm": c.fz or None, "flutes": c.flutes or None,
                        "feed_mm_min": round(c.feed, 1) or None, "ap_mm": c.ap, "ae_mm": c.ae,
                        "plunge_feed_mm_min": round(c.plunge_feed, 1) or None},
            "feed_moves": int(feed_moves.sum()), "moves_in_material": int(mine.sum()),
            "removed_mm3": round(float(load.volume[mine].sum()), 3),
            **{name: _spread(getattr(load, field)[mine]) for name, field in (
                ("ap_mm", "ap"), ("ae_mm", "ae"), ("engagement_deg", "angle"), ("chip_max_mm", "chip_max"),
                ("chip_mean_mm", "chip_mean"), ("rate_mm3_min", "rate"), ("power_kw", "power"),
                ("torque_nm", "torque"))},
            "over": {figure: int((mine & over[figure]).sum()) for figure, _, _ in LIMITS},
        }
        per_tool.append(entry)
    return {"material": None if material is None else material.name,
            "spindle": None if spindle is None else spindle.summary(),
            "slack": LOAD_SLACK, "tools": per_tool, "errors": errors, "ok": not errors}
