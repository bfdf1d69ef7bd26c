"""Cutting data: how fast a tool may cut a material, how deep and how wide, and the materials'
specific cutting force.

A tool of the table may give, beside its shape (mm, rev/min, m/min, mm/min):

```toml
[[tools]]
name = "F10"
type = "flat"
diameter = 10.0
flute_length = 30.0
gauge_length = 60.0
flutes = 3
vc = 250.0           # cutting speed, m/min (or rpm = ...)
fz = 0.05            # feed per tooth, mm: the largest chip thickness it is made for
ap_ratio = 1.0       # largest axial depth, x diameter (or ap = mm; default: the flute length)
ae_ratio = 0.5       # largest radial width, x diameter (or ae = mm; default: the diameter)
plunge_feed = 300    # mm/min along the axis into material (default: a third of the feed)
ramp_feed = 800      # mm/min of a helix or ramp entry (default: half the feed)

[[tools.cutting]]    # the tool maker's data for one workpiece material (what it gives replaces the above)
material = "steel-p20"
vc = 120.0
fz = 0.04
ae_ratio = 0.25
```

A job (or ``--material``) names the workpiece material; :meth:`Cutting.of` resolves a tool's
data for it. :data:`MATERIALS` holds the specific cutting force of common materials (Kienzle:
``kc = kc1 * h^-mc`` N/mm², h the mean chip thickness in mm; power = kc x removal rate; typical handbook values for
planning: the tool maker's or the machine's data win where they differ).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

from ..errors import InputError

CUTTING_KEYS = ("vc", "fz", "ap", "ae", "ap_ratio", "ae_ratio", "plunge_feed", "ramp_feed")
MATERIAL_KEYS = ("material", "rpm") + CUTTING_KEYS
MAX_VC = 10000.0  # m/min: cutting speeds are below this
MAX_FZ = 10.0  # mm per tooth
PLUNGE_SHARE = 1.0 / 3.0  # plunge feed, of the cutting feed, where the table gives none
RAMP_SHARE = 0.5  # ramp feed, of the cutting feed, where the table gives none


@dataclass(frozen=True)
class Material:
    """A workpiece material: ``kc1`` N/mm² (specific cutting force at a 1 mm chip) and ``mc``."""

    name: str
    kc1: float
    mc: float
    note: str

    def specific_energy(self, h):
        """N/mm² (times a removal rate in mm³/s: mW) to cut chips of mean thickness ``h`` mm (array or number; below
        :data:`MIN_CHIP` it is taken at that chip: Kienzle's law is not measured lower)."""
        import numpy as np

        return self.kc1 * np.maximum(np.asarray(h, float), MIN_CHIP) ** -self.mc


MIN_CHIP = 0.005  # mm: thinner chips are costed as this thick
MATERIALS = {m.name: m for m in (
    Material("aluminium-6061", 700.0, 0.25, "wrought aluminium alloy, aged (6061-T6)"),
    Material("aluminium-7075", 850.0, 0.25, "high-strength wrought aluminium alloy (7075-T6)"),
    Material("steel-1045", 1700.0, 0.25, "medium-carbon steel, annealed (C45)"),
    Material("steel-p20", 2100.0, 0.25, "pre-hardened mould steel, about 30 HRC (1.2311/1.2738)"),
    Material("stainless-304", 2000.0, 0.21, "austenitic stainless steel"),
    Material("titanium-6al4v", 1400.0, 0.23, "titanium alloy Ti-6Al-4V, annealed"),
    Material("cast-iron", 1100.0, 0.28, "grey cast iron (GG25)"),
    Material("brass", 780.0, 0.18, "free-cutting brass"),
    Material("plastic", 150.0, 0.2, "engineering plastics (POM, PA)"),
)}


def workpiece(name: str | None, tools) -> tuple[Material | None, list]:
    """``(material, warnings)``: the shipped :class:`Material` called ``name`` (None: none
    named, or a material only the tool table's ``[[tools.cutting]]`` names: no power then, and
    a warning says so); any other name is an :class:`InputError` listing the known ones."""
    if name is None:
        return None, []
    if name in MATERIALS:
        return MATERIALS[name], []
    named = sorted({d.material for t in tools for d in t.data[1:]})
    if name in named:
        return None, [f"material '{name}' is not among the shipped materials ({', '.join(MATERIALS)}): its specific "
                      "cutting force is unknown, so no power or torque is computed"]
    raise InputError(f"material must be one of {', '.join(tuple(MATERIALS) + tuple(named))}, got {name!r}", "material")


def conditions(tools, material: str | None = None, spindle=None) -> list:
    """Each tool's :class:`Cutting` in ``material``, its speed held within the ``spindle``'s
    (:class:`~meshmill.machine.model.Spindle`, None: any)."""
    top = spindle.max_rpm if spindle is not None else math.inf
    return [Cutting.of(t, material, top) for t in tools]


@dataclass(frozen=True)
class CuttingData:
    """What a tool table gives for one material (``material`` "": the tool's own data); 0 where
    it gives nothing."""

    material: str = ""
    rpm: float = 0.0
    vc: float = 0.0
    fz: float = 0.0
    ap: float = 0.0
    ae: float = 0.0
    ap_ratio: float = 0.0
    ae_ratio: float = 0.0
    plunge_feed: float = 0.0
    ramp_feed: float = 0.0

    def given(self) -> dict:
        """The values it gives (not 0), as a tool table writes them (``material`` aside)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "material" and getattr(self, f.name)}


def _data(entry: dict, where: str, keys) -> CuttingData:
    values = {}
    for key in keys:
        if key not in entry or key == "material":
            continue
        v = entry[key]
        high = {"vc": MAX_VC, "fz": MAX_FZ, "rpm": 1e6}.get(key, math.inf)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 < v < high:
            unit = {"vc": "m/min", "rpm": "rev/min", "plunge_feed": "mm/min", "ramp_feed": "mm/min",
                    "ap_ratio": "x diameter", "ae_ratio": "x diameter"}.get(key, "mm")
            raise InputError(f"{where}: '{key}' must be a number of {unit} > 0"
                             + (f" and below {high:g}" if high < math.inf else "") + f", got {v!r}")
        values[key] = float(v)
    for a, b in (("ap", "ap_ratio"), ("ae", "ae_ratio"), ("rpm", "vc")):
        if a in values and b in values:
            raise InputError(f"{where}: give '{a}' or '{b}', not both")
    return CuttingData(material=str(entry.get("material", "")), **values)


def cutting_entries(entry: dict, where: str) -> tuple:
    """The :class:`CuttingData` of a ``[[tools]]`` entry: its own (material "") and those of its
    ``[[tools.cutting]]`` tables, checked (raises :class:`InputError`)."""
    own = _data(entry, where, CUTTING_KEYS)
    out = [own]
    tables = entry.get("cutting", [])
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise InputError(f"{where}: 'cutting' must be [[tools.cutting]] tables, one per material")
    for t in tables:
        for key in t:
            if key not in MATERIAL_KEYS:
                raise InputError(f"{where}: [[tools.cutting]] unknown key '{key}' (known: {', '.join(MATERIAL_KEYS)})")
        name = t.get("material")
        if not isinstance(name, str) or not name:
            raise InputError(f"{where}: every [[tools.cutting]] table needs material = \"a name\"")
        if name in [d.material for d in out[1:]]:
            raise InputError(f"{where}: [[tools.cutting]] material '{name}' is given twice")
        out.append(_data(t, f"{where}, material '{name}'", MATERIAL_KEYS))
    return tuple(out) if len(out) > 1 or own.given() else ()


@dataclass(frozen=True)
class Cutting:
    """A tool's conditions in one material: ``rpm`` rev/min (0: the machine's), ``fz`` mm per
    tooth and ``flutes`` (0: not given), the largest ``ap`` and ``ae`` mm, ``plunge_feed`` and
    ``ramp_feed`` mm/min (0 where no feed is known), ``material`` ("" : the tool's own data),
    ``known``: the table gives a feed per tooth and flutes (a feed is then the tool's, and its chip
    load can be judged)."""

    rpm: float
    fz: float
    flutes: int
    ap: float
    ae: float
    plunge_feed: float
    ramp_feed: float
    material: str = ""

    @property
    def known(self) -> bool:
        return self.fz > 0 and self.flutes > 0 and self.rpm > 0

    @property
    def feed(self) -> float:
        """mm/min: ``fz * flutes * rpm`` (0 when not :attr:`known`)."""
        return self.fz * self.flutes * self.rpm if self.known else 0.0

    @staticmethod
    def of(tool, material: str | None = None, max_rpm: float = math.inf) -> "Cutting":
        """``tool``'s conditions in ``material``: the ``[[tools.cutting]]`` table of that material
        over the tool's own values; the spindle speed from ``rpm`` or ``vc`` (at the full
        diameter), at most ``max_rpm``."""
        own = tool.data[0] if tool.data else CuttingData()
        mine = next((d for d in tool.data[1:] if d.material == material), None) if material else None

        def pick(key):
            return getattr(mine, key) if mine is not None and getattr(mine, key) else getattr(own, key)

        rpm = (mine.rpm if mine is not None and mine.rpm else 0.0) or tool.rpm
        vc = pick("vc")
        if mine is not None and mine.vc:
            rpm = 0.0  # the material's cutting speed over the tool's own rpm
        if not rpm and vc:
            rpm = vc * 1000.0 / (math.pi * tool.diameter)
        rpm = min(rpm, max_rpm)
        D = tool.diameter
        ap = pick("ap") or pick("ap_ratio") * D or tool.flute_length
        ae = pick("ae") or pick("ae_ratio") * D or D
        fz = pick("fz")
        feed = fz * tool.flutes * rpm
        return Cutting(rpm=rpm, fz=fz, flutes=tool.flutes, ap=ap, ae=min(ae, D),
                       plunge_feed=pick("plunge_feed") or PLUNGE_SHARE * feed,
                       ramp_feed=pick("ramp_feed") or RAMP_SHARE * feed,
                       material=material if mine is not None else "")


def in_material(tools, material: str | None = None, spindle=None):
    """``tools`` with each one's spindle speed (``rpm``) that of its cutting data in ``material``
    (from ``vc`` where the table gives a cutting speed; within the ``spindle``'s), so that tool
    paths, programs and timings use it; the same object where nothing changes. An unknown
    material is an :class:`InputError`."""
    from dataclasses import replace

    workpiece(material, tools)
    out = [replace(t, rpm=c.rpm) if c.rpm and c.rpm != t.rpm else t
           for t, c in zip(tools, conditions(tools, material, spindle))]
    if all(a is b for a, b in zip(out, tools)):
        return tools
    if hasattr(tools, "path"):
        return type(tools)(out, tools.path)
    return out
