"""Cutters with shank and holder, and their cutting data, read from a TOML tool table (or a
FreeCAD tool bit or library, or a LinuxCNC tool table: :mod:`meshmill.tools.foreign`).

Every tool is modelled along its axis from the tip (t = 0), in mm:

- cutting part: the ball/torus end (a ring of spheres), then the flutes up to ``flute_length``;
- shank: radius ``shank_diameter/2`` from ``flute_length`` to ``gauge_length`` (tip to holder face);
- holder (optional): radius ``holder_diameter/2`` from ``gauge_length`` for ``holder_length``.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..tomlfile import read_toml
from .cutting import CUTTING_KEYS, Cutting, cutting_entries

TYPES = ("ball", "flat", "bull")
KEYS = ("name", "type", "diameter", "corner_radius", "flute_length", "gauge_length", "shank_diameter",
        "holder_diameter", "holder_length", "rpm") + CUTTING_KEYS + ("flutes", "cutting")
MAX_RPM = 1e6  # rev/min: spindle speeds are below this (tool tables and machines)
RING_POINTS = 36  # spheres along the torus of a bull-nose cutter in verification


@dataclass(frozen=True)
class Tool:
    """One cutter of the table; ``number`` is its 1-based position (APT ``LOADTL/number``)."""

    name: str
    type: str
    diameter: float
    corner_radius: float
    flute_length: float
    gauge_length: float
    shank_diameter: float
    holder_diameter: float = 0.0
    holder_length: float = 0.0
    number: int = 1
    rpm: float = 0.0  # spindle speed, rev/min; 0: the machine's ([gcode] rpm)
    flutes: int = 0  # teeth; 0: not given (no feed per tooth, no chip load)
    data: tuple = ()  # the cutting data: CuttingData, the tool's own first (material ""), then per material

    def cutting(self, material: str | None = None, max_rpm: float = math.inf) -> Cutting:
        """The cutting conditions of this tool in ``material`` (the tool's own data where the
        table gives none for it), at most ``max_rpm``: :class:`~meshmill.tools.cutting.Cutting`."""
        return Cutting.of(self, material, max_rpm)

    @property
    def radius(self) -> float:
        return 0.5 * self.diameter

    def cylinders(self):
        """``[(t0, t1, radius, cutting)]`` coaxial cylinders of the tool, from the tip up."""
        R, rc = self.radius, self.corner_radius
        out = []
        if self.type == "ball":
            out.append((R, self.flute_length, R, True))
        elif self.type == "flat":
            out.append((0.0, self.flute_length, R, True))
        else:
            out.append((0.0, rc, R - rc, True))
            out.append((rc, self.flute_length, R, True))
        if self.gauge_length > self.flute_length:
            out.append((self.flute_length, self.gauge_length, 0.5 * self.shank_diameter, False))
        if self.holder_diameter > 0.0:
            out.append((self.gauge_length, self.gauge_length + self.holder_length, 0.5 * self.holder_diameter, False))
        return out

    def ring(self):
        """``(t, rho, r, n)``: the rounded end as n spheres of radius r on a circle of radius rho
        at height t (ball: one sphere; flat: none, r = 0)."""
        R, rc = self.radius, self.corner_radius
        if self.type == "ball":
            return R, 0.0, R, 1
        if self.type == "flat":
            return 0.0, 0.0, 0.0, 0
        return rc, R - rc, rc, RING_POINTS

    @property
    def spindle_length(self) -> float:
        """Tip to the spindle's gauge line, mm: ``gauge_length`` (tip to holder face) plus
        ``holder_length``; what a head that tilts the tool is programmed for."""
        return self.gauge_length + self.holder_length

    def lowest_z(self, tip, axis):
        """Lowest Z (m,) mm of the modelled tool (cutter, shank, holder: :meth:`cylinders` and
        :meth:`ring`) with its tip at ``tip (m, 3)`` and its axis along the unit ``axis (m, 3)``."""
        tip, axis = np.atleast_2d(tip), np.atleast_2d(axis)
        az = axis[:, 2]
        across = np.sqrt(np.maximum(0.0, 1.0 - az * az))  # a disc of radius r reaches r * across below its centre
        t, rho, r, _ = self.ring()
        low = tip[:, 2] + t * az - rho * across - r
        for t0, t1, radius, _ in self.cylinders():
            low = np.minimum(low, tip[:, 2] + np.minimum(t0 * az, t1 * az) - radius * across)
        return low

    def spindle_length_warning(self) -> str | None:
        """A warning when :attr:`spindle_length` is only the gauge length (no holder in the table),
        so that a machine whose head tilts the tool would be programmed for too short a tool."""
        if self.holder_length > 0:
            return None
        return (f"tool T{self.number} '{self.name}' has no holder in the tool table: its length to the spindle's "
                f"gauge line is taken as gauge_length = {self.gauge_length:g} mm; a head that tilts the tool needs "
                "the real length: give holder_diameter and holder_length")

    @property
    def reach(self) -> float:
        """Length of the modelled tool from its tip, mm."""
        return self.gauge_length + (self.holder_length if self.holder_diameter > 0 else 0.0)

    def apt_cutter(self) -> str:
        return f"CUTTER/{self.diameter:.6f}, {self.corner_radius:.6f}"


def pack_rings(tools):
    """Per-tool ring arrays ``(t, rho, r, n)`` for :func:`meshmill.kernels.cpu.pose_penetration`."""
    rings = [tool.ring() for tool in tools]
    return (np.array([r[0] for r in rings], np.float64), np.array([r[1] for r in rings], np.float64),
            np.array([r[2] for r in rings], np.float64), np.array([r[3] for r in rings], np.int64))


def pack_cylinders(tools, tol=0.0, clearance=0.0):
    """Per-tool cylinder arrays ``(t0, t1, r)`` (T, K) and ``cutting (T, K) bool``.

    Cutting cylinders shrink by ``tol`` (and a cylinder starting at the tip starts ``tol`` higher,
    so that a flat bottom may rest on a facet); shank and holder grow by ``clearance`` in radius and
    at both ends (a flat-ended cylinder holding all points within ``clearance`` of the real one, as
    verification grows them: a shank bottom hovering over the part is kept ``clearance`` off it too).
    Unused slots have radius 0.
    """
    cyl = [tool.cylinders() for tool in tools]
    k = max(len(c) for c in cyl)
    t0 = np.zeros((len(tools), k))
    t1 = np.zeros((len(tools), k))
    r = np.zeros((len(tools), k))
    cutting = np.zeros((len(tools), k), bool)
    for i, parts in enumerate(cyl):
        for j, (a, b, rad, cut) in enumerate(parts):
            t0[i, j] = a + (tol if (cut and a == 0.0) else 0.0) if cut else max(0.0, a - clearance)
            t1[i, j] = b if cut else b + clearance
            r[i, j] = rad - tol if cut else rad + clearance
            cutting[i, j] = cut
    return (t0, t1, r), cutting


def _number(entry, key, where, default=None, required=True):
    if key not in entry:
        if required and default is None:
            raise InputError(f"{where}: missing key '{key}'")
        return default
    value = entry[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where}: '{key}' must be a number (mm), got {value!r}")
    return float(value)


def tool_from_entry(entry: dict, number: int, where: str) -> Tool:
    """Check one ``[[tools]]`` table into a :class:`Tool` (raises :class:`InputError`)."""
    name = str(entry.get("name", f"T{number}"))
    where = f"{where}: tool {number} ('{name}')"
    for key in entry:
        if key not in KEYS:
            # a misspelt key (holder_diamter) would silently drop what it meant to give
            raise InputError(f"{where}: unknown key '{key}' (known: {', '.join(KEYS)})")
    kind = entry.get("type")
    if kind not in TYPES:
        raise InputError(f"{where}: 'type' must be one of {', '.join(TYPES)}, got {kind!r}")
    d = _number(entry, "diameter", where)
    if d <= 0:
        raise InputError(f"{where}: diameter must be > 0 mm")
    R = 0.5 * d
    if kind == "ball":
        rc = _number(entry, "corner_radius", where, default=R)
        if abs(rc - R) > 1e-9 * max(1.0, R):
            raise InputError(f"{where}: a ball tool's corner_radius must be diameter/2 = {R:g}")
        rc = R
    elif kind == "flat":
        rc = _number(entry, "corner_radius", where, default=0.0)
        if rc != 0.0:
            raise InputError(f"{where}: a flat tool's corner_radius must be 0")
    else:
        rc = _number(entry, "corner_radius", where)
        if not 0.0 < rc < R:
            raise InputError(f"{where}: a bull tool needs 0 < corner_radius < diameter/2 = {R:g}")
    flute = _number(entry, "flute_length", where)
    gauge = _number(entry, "gauge_length", where)
    if flute < rc or flute <= 0:
        raise InputError(f"{where}: flute_length must be at least the corner radius and > 0")
    if gauge < flute:
        raise InputError(f"{where}: gauge_length ({gauge:g}) must be at least flute_length ({flute:g})")
    shank = _number(entry, "shank_diameter", where, default=d)
    if shank <= 0:
        raise InputError(f"{where}: shank_diameter must be > 0 mm")
    holder_d = _number(entry, "holder_diameter", where, default=0.0, required=False)
    holder_l = _number(entry, "holder_length", where, default=holder_d, required=False)
    if holder_d < 0 or holder_l < 0 or (holder_d > 0 and holder_l <= 0):
        raise InputError(f"{where}: holder_diameter and holder_length must be > 0 mm")
    rpm = entry.get("rpm", 0)
    if "rpm" in entry and (isinstance(rpm, bool) or not isinstance(rpm, (int, float)) or not 1 <= rpm < MAX_RPM):
        raise InputError(f"{where}: 'rpm' must be a spindle speed from 1 to {MAX_RPM - 1:g} rev/min "
                         f"(or left out for the machine's), got {rpm!r}")
    if "rpm" in entry and "vc" in entry:
        raise InputError(f"{where}: give 'rpm' or 'vc', not both")
    flutes = entry.get("flutes", 0)
    if "flutes" in entry and (isinstance(flutes, bool) or not isinstance(flutes, int) or not 1 <= flutes <= 100):
        raise InputError(f"{where}: 'flutes' must be a whole number of teeth from 1 to 100, got {flutes!r}")
    data = cutting_entries(entry, where)
    return Tool(name=name, type=kind, diameter=d, corner_radius=rc, flute_length=flute, gauge_length=gauge,
                shank_diameter=shank, holder_diameter=holder_d, holder_length=holder_l if holder_d > 0 else 0.0,
                number=number, rpm=float(rpm), flutes=int(flutes), data=data)


class ToolTable(list):
    """The tools of a table file, in order (a list of :class:`Tool`), and the file's ``path``."""

    def __init__(self, tools=(), path=""):
        super().__init__(tools)
        self.path = os.path.abspath(path) if path else ""
        self.warnings = []  # what reading it assumed (a LinuxCNC table's flute lengths, ...)


def load_tools(path, units: str = "mm") -> ToolTable:
    """Read a tool table into tools numbered from 1 in its order: TOML (``[[tools]]`` entries),
    a FreeCAD tool bit (``.fctb``) or library (``.fctl``), or a LinuxCNC tool table (``.tbl``,
    in ``units`` mm or inch; what it does not say is assumed and said in the table's
    ``warnings``), see :mod:`meshmill.tools.foreign`."""
    from . import foreign

    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"{path}: no such tool table")
    ext = os.path.splitext(path)[1].lower()
    warnings = []
    if ext in (".fctb", ".fctl", ".tbl"):
        if ext == ".fctb":
            entries, numbers = [foreign.read_fctb(path)], [1]
        elif ext == ".fctl":
            entries, numbers = foreign.read_fctl(path)
        else:
            entries, warnings, numbers = foreign.read_linuxcnc_tbl(path, units)
        table = ToolTable([tool_from_entry(e, i + 1, path) for i, e in enumerate(entries)], path)
        moved = [f"T{n} is tool {i + 1}" for i, n in enumerate(numbers) if n != i + 1]
        if moved:
            warnings.append(f"{os.path.basename(path)}: meshmill numbers tools by their order in the table, so "
                            f"{', '.join(moved[:5])}{' ...' if len(moved) > 5 else ''}: programs call them so")
        table.warnings = warnings
        return table
    data = read_toml(path, "a valid TOML tool table", "tool table")
    entries = data.get("tools")
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: no [[tools]] entries")
    if not all(isinstance(e, dict) for e in entries):
        raise InputError(f"{path}: every tools entry must be a table ([[tools]] with keys)")
    tools = [tool_from_entry(e, i + 1, path) for i, e in enumerate(entries)]
    names = [t.name for t in tools]
    if len(set(names)) != len(names):
        raise InputError(f"{path}: tool names must be unique")
    return ToolTable(tools, path)


def write_tools(path, tools) -> None:
    """Write ``tools`` as a TOML tool table that :func:`load_tools` reads back (same order)."""
    lines = ["# tool table written by meshmill (mm)"]
    for t in tools:
        lines += ["", "[[tools]]", f'name = "{t.name}"', f'type = "{t.type}"', f"diameter = {t.diameter!r}"]
        if t.type == "bull":
            lines.append(f"corner_radius = {t.corner_radius!r}")
        lines += [f"flute_length = {t.flute_length!r}", f"gauge_length = {t.gauge_length!r}",
                  f"shank_diameter = {t.shank_diameter!r}"]
        if t.holder_diameter > 0:
            lines += [f"holder_diameter = {t.holder_diameter!r}", f"holder_length = {t.holder_length!r}"]
        if t.rpm > 0:
            lines.append(f"rpm = {t.rpm!r}")
        if t.flutes:
            lines.append(f"flutes = {t.flutes}")
        lines += [f"{k} = {v!r}" for k, v in t.data[0].given().items()] if t.data else []
        for d in t.data[1:]:
            lines += ["", "[[tools.cutting]]", f'material = "{d.material}"'] + \
                [f"{k} = {v!r}" for k, v in d.given().items()]
    with open(path, "w") as fh:
        fh.write("\n".join(lines) + "\n")
