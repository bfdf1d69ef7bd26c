"""Machine descriptions read from TOML: one table per section, units in the key names.

```toml
name = "generic 3-axis"
[motion]
feed_mm_min = 5000        # nominal cutting feed, used where the tool path gives none
rapid_mm_min = 20000
accel_mm_s2 = 6000
jerk_mm_s3 = 40000
corner_angle_deg = 5      # a sharper turn between consecutive moves stops the tool
tool_change_s = 8
reorient_s = 3            # re-orienting the rotary axes between 3+2 setups
[spindle]                 # optional: what load checks and feed optimisation keep under
power_kw = 11             # at the tool (0 or absent: not checked)
torque_nm = 70
min_rpm = 100
max_rpm = 12000           # a tool's speed above this is run at it
max_feed_mm_min = 15000   # the largest programmed feed (default: the rapid rate)
```

Each section has a reader in :data:`SECTIONS` that checks its table and returns fields of
:class:`Machine`; a new section (axis travel, kinematic chain, G-code dialect) is a new reader and
new fields with defaults. Unknown sections and keys are refused.
"""
from __future__ import annotations

import math
import os
import re
import string

from ..errors import InputError
from ..tomlfile import read_toml
from ..tools.table import MAX_RPM
from .model import CHAINS, DIALECTS, LINEAR, RAPIDS, ROTARY, Chain, GcodeFormat, Machine, MotionLimits, Spindle

SHIPPED = os.path.join(os.path.dirname(os.path.dirname(__file__)), "data", "machines")

MOTION_POSITIVE = ("feed_mm_min", "rapid_mm_min", "accel_mm_s2", "jerk_mm_s3")
MOTION_NON_NEGATIVE = ("corner_angle_deg", "tool_change_s", "reorient_s")
MOTION_OPTIONAL = {"rotary_rapid_deg_min": 3600.0}


def _number(table, key, where, positive):
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{where} '{key}' must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise InputError(f"{where} '{key}' must be > 0, got {value!r}")
    if value < 0:
        raise InputError(f"{where} '{key}' must be >= 0, got {value!r}")
    return float(value)


def _motion(table, where) -> dict:
    """``[motion]``: motion limits, corner angle, tool change and re-orientation times."""
    keys = MOTION_POSITIVE + MOTION_NON_NEGATIVE
    for key in table:
        if key not in keys and key not in MOTION_OPTIONAL:
            raise InputError(f"{where} unknown key '{key}' (known: {', '.join(keys + tuple(MOTION_OPTIONAL))})")
    for key in keys:
        if key not in table:
            raise InputError(f"{where} missing key '{key}'")
    v = {key: _number(table, key, where, key in MOTION_POSITIVE) for key in keys}
    if v["feed_mm_min"] > v["rapid_mm_min"]:
        raise InputError(f"{where} 'feed_mm_min' ({v['feed_mm_min']:g}) must not exceed 'rapid_mm_min' "
                         f"({v['rapid_mm_min']:g})")
    if v["corner_angle_deg"] >= 180.0:
        raise InputError(f"{where} 'corner_angle_deg' must be below 180, got {v['corner_angle_deg']:g}")
    motion = MotionLimits(feed=v["feed_mm_min"] / 60.0, accel=v["accel_mm_s2"], jerk=v["jerk_mm_s3"],
                          rapid=v["rapid_mm_min"] / 60.0)
    rotary = _number({**MOTION_OPTIONAL, **table}, "rotary_rapid_deg_min", where, True)
    return {"motion": motion, "corner_angle": math.radians(v["corner_angle_deg"]),
            "tool_change": v["tool_change_s"], "reorient": v["reorient_s"], "rotary_rapid": rotary / 60.0}


def _axes(table, where) -> dict:
    """``[axes]``: travel per axis letter, ``[low, high]`` (mm; degrees for A B C), or
    "continuous" for a rotary that turns freely."""
    limits = {}
    for key, value in table.items():
        if key not in LINEAR + ROTARY:
            raise InputError(f"{where} unknown axis '{key}' (known: {', '.join(LINEAR + ROTARY)})")
        if value == "continuous" and key in ROTARY:
            continue
        if (not isinstance(value, list) or len(value) != 2
                or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)
                or value[0] >= value[1]):
            also = ' or "continuous"' if key in ROTARY else ""
            raise InputError(f"{where} '{key}' must be [low, high] with low < high{also}, got {value!r}")
        limits[key] = (float(value[0]), float(value[1]))
    return {"limits": limits}


def _vector(table, key, where):
    value = table.get(key, [0.0, 0.0, 0.0])
    if (not isinstance(value, list) or len(value) != 3
            or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)):
        raise InputError(f"{where} '{key}' must be three numbers [x, y, z] in mm, got {value!r}")
    return tuple(float(x) for x in value)


def _kinematics(table, where) -> dict:
    """``[kinematics]``: the chain (see :class:`Chain`)."""
    known = ("type", "rotary", "reversed", "pivot_mm", "offset_mm", "head_length_mm", "singular_deg")
    for key in table:
        if key not in known:
            raise InputError(f"{where} unknown key '{key}' (known: {', '.join(known)})")
    kind = table.get("type", "3-axis")
    if kind not in CHAINS:
        raise InputError(f"{where} 'type' must be one of {', '.join(CHAINS)}, got {kind!r}")
    singular = table.get("singular_deg", 0.05)
    if isinstance(singular, bool) or not isinstance(singular, (int, float)) or not 0 < singular < 10:
        raise InputError(f"{where} 'singular_deg' must be between 0 and 10 degrees, got {singular!r}")
    rotary = table.get("rotary", [])
    if kind == "3-axis":
        if rotary:
            raise InputError(f"{where} a 3-axis machine has no 'rotary' axes")
        return {"chain": Chain()}
    if kind == "head-head" and isinstance(rotary, list) and len(rotary) == 2 and rotary[0] == "C":
        rotary = rotary[::-1]  # listed from the frame: C carries the tilt; kept as (tilt, C) like the others
    if (not isinstance(rotary, list) or len(rotary) != 2 or not all(r in ROTARY for r in rotary)
            or rotary[0] == rotary[1] or "C" not in rotary or rotary[0] == "C"):
        order = "C and then the tilting axis (A or B), e.g. ['C', 'A']" if kind == "head-head" else \
            "the tilting axis (A or B) and then C, e.g. ['A', 'C']"
        raise InputError(f"{where} 'rotary' must name {order}, got {table.get('rotary')!r}")
    rev = table.get("reversed", [])
    if not isinstance(rev, list) or not all(r in rotary for r in rev):
        raise InputError(f"{where} 'reversed' must list some of {rotary}, got {rev!r}")
    head = table.get("head_length_mm", 0.0)
    if kind in ("head-table", "head-head") and (isinstance(head, bool) or not isinstance(head, (int, float))
                                 or not math.isfinite(head) or head < 0):
        raise InputError(f"{where} 'head_length_mm' must be a length >= 0 mm, got {head!r}")
    return {"chain": Chain(type=kind, rotary=tuple(rotary), reversed=tuple(rev), pivot=_vector(table, "pivot_mm", where),
                           offset=_vector(table, "offset_mm", where), head_length=float(head),
                           singular=math.radians(singular))}


DIALECT_DEFAULTS = {
    "fanuc": {},
    "linuxcnc": {"start": ("%", "G21 G90 G17 G40 G49 G80 G94 G64 P0.005"), "end": ("M5", "M9", "G53 G0 Z0", "M2", "%"),
                 "comment": "({text})", "tcp": "", "retract": ("G53 G0 Z0",), "rapid": "linear"},
    "grbl": {"start": ("G21 G90 G17 G94",), "end": ("M5", "M9", "M2"), "tool_change": "", "tool_length": "",
             "comment": "; {text}", "inverse_time": False, "decimals": 3,
             "retract": ("G53 G0 Z0",), "rapid": "linear"},
}


def _gcode(table, where) -> dict:
    """``[gcode]``: the program format (see :class:`GcodeFormat`); ``dialect`` sets the defaults
    that the other keys override."""
    dialect = table.get("dialect", "fanuc")
    if dialect not in DIALECTS:
        raise InputError(f"{where} 'dialect' must be one of {', '.join(DIALECTS)}, got {dialect!r}")
    values = {**DIALECT_DEFAULTS[dialect]}
    template = GcodeFormat()
    for key, value in table.items():
        if key == "dialect":
            continue
        if not hasattr(template, key):
            raise InputError(f"{where} unknown key '{key}' (known: dialect, "
                             f"{', '.join(f for f in GcodeFormat.__dataclass_fields__ if f != 'dialect')})")
        want = type(getattr(template, key))
        if want is tuple:
            if not isinstance(value, list) or not all(isinstance(x, str) for x in value):
                raise InputError(f"{where} '{key}' must be a list of lines (strings)")
            value = tuple(value)
        elif want is bool:
            if not isinstance(value, bool):
                raise InputError(f"{where} '{key}' must be true or false, got {value!r}")
        elif want is int:
            if isinstance(value, bool) or not isinstance(value, int) or not 2 <= value <= 8:
                raise InputError(f"{where} '{key}' must be an integer from 2 to 8 (places after the point: "
                                 f"fewer round a tool path by 0.05 mm or 0.05 deg and more), got {value!r}")
        elif want is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise InputError(f"{where} '{key}' must be a positive number, got {value!r}")
            value = float(value)
            if key == "rpm" and value >= MAX_RPM:
                raise InputError(f"{where} 'rpm' must be below {MAX_RPM:g} rev/min, got {value:g}")
        elif not isinstance(value, str):
            raise InputError(f"{where} '{key}' must be a string, got {value!r}")
        elif key == "rapid" and value not in RAPIDS:
            raise InputError(f"{where} 'rapid' must be one of {', '.join(RAPIDS)}, got {value!r}")
        values[key] = value
    gcode = GcodeFormat(dialect=dialect, **values)
    for key, fields in TEMPLATE_FIELDS.items():
        _check_template(getattr(gcode, key), key, fields, where)
    return {"gcode": gcode}


# the [gcode] texts filled in per tool, and the fields each may use; the other texts (start, end,
# retract, coolant_off, tcp_off) are written as given
TOOL_FIELDS = ("number", "name", "rpm")
TEMPLATE_FIELDS = {"tool_change": TOOL_FIELDS, "tool_length": TOOL_FIELDS, "spindle": TOOL_FIELDS,
                   "coolant_on": TOOL_FIELDS, "tcp": TOOL_FIELDS, "comment": ("text",)}
SAMPLES = ({"number": 1, "name": "T1", "rpm": 1, "text": "comment"},  # the extremes a text is filled in with
           {"number": 999, "name": "a tool name of forty characters, or so..", "rpm": 999999, "text": "c" * 200})
MAX_LINE = 1000  # characters a filled-in text may have


def _check_template(text, key, fields, where):
    """InputError naming the file and key when ``text`` is not a valid format string (a lone
    brace, a format spec that does not apply) or has a field other than ``fields``."""
    known = ", ".join("{" + f + "}" for f in fields)
    try:
        names = [f for _, f, _, _ in string.Formatter().parse(text) if f is not None]
    except ValueError as exc:
        raise InputError(f"{where} '{key}' = {text!r}: {exc} (write a brace as {{{{ or }}}})") from None
    for _, name, spec, _ in string.Formatter().parse(text):
        if spec and ("{" in spec or any(int(w) > MAX_LINE for w in re.findall(r"\d+", spec))):
            raise InputError(f"{where} '{key}' = {text!r}: the format spec ':{spec}' of {{{name}}} is too wide or nested")
    bad = [f for f in names if f not in fields]
    if bad:
        raise InputError(f"{where} '{key}' = {text!r}: unknown field {{{bad[0]}}} (known here: {known})")
    for sample in SAMPLES:
        try:
            filled = text.format(**{f: sample[f] for f in fields})
        except (KeyError, IndexError, ValueError, OverflowError, MemoryError) as exc:
            raise InputError(f"{where} '{key}' = {text!r}: {exc}") from None
        if len(filled) > MAX_LINE + len(sample["text"]):
            raise InputError(f"{where} '{key}' = {text!r}: fills in to {len(filled)} characters (a format width?)")


SPINDLE_KEYS = ("power_kw", "torque_nm", "min_rpm", "max_rpm", "max_feed_mm_min")


def _spindle(table, where) -> dict:
    """``[spindle]``: power and torque at the tool, speed range and the largest feed (see
    :class:`~meshmill.machine.model.Spindle`)."""
    for key in table:
        if key not in SPINDLE_KEYS:
            raise InputError(f"{where} unknown key '{key}' (known: {', '.join(SPINDLE_KEYS)})")
    v = {key: _number(table, key, where, True) for key in table}
    low, high = v.get("min_rpm", 0.0), v.get("max_rpm", MAX_RPM - 1)
    if low >= high or high >= MAX_RPM:
        raise InputError(f"{where} 'min_rpm' must be below 'max_rpm' (below {MAX_RPM:g} rev/min)")
    return {"spindle": Spindle(power_kw=v.get("power_kw", 0.0), torque_nm=v.get("torque_nm", 0.0), min_rpm=low,
                               max_rpm=high, max_feed=v.get("max_feed_mm_min", 0.0))}


SECTIONS = {"motion": _motion, "axes": _axes, "kinematics": _kinematics, "gcode": _gcode, "spindle": _spindle}  # section -> reader
REQUIRED = ("motion",)


def shipped_machines() -> list[str]:
    """Names of the machine files shipped with meshmill (``--machine NAME`` finds them)."""
    return sorted(f[:-5] for f in os.listdir(SHIPPED) if f.endswith(".toml"))


def load_machine(path) -> Machine:
    """Read a TOML machine file, or a shipped one by name (``generic-3axis``, ``seed-002``);
    bad input raises :class:`InputError` naming the file and the key."""
    path = os.fspath(path)
    if not os.path.exists(path) and path in shipped_machines():
        path = os.path.join(SHIPPED, path + ".toml")
    if not os.path.exists(path):
        raise InputError(f"{path}: no such machine file (shipped: {', '.join(shipped_machines())})")
    data = read_toml(path, "a valid TOML machine file", "machine file")
    name = data.pop("name", os.path.splitext(os.path.basename(path))[0])
    if not isinstance(name, str) or not name.strip():
        raise InputError(f"{path}: 'name' must be a non-empty string, got {name!r}")
    fields = {}
    for section, table in data.items():
        if section not in SECTIONS:
            raise InputError(f"{path}: unknown section or key '{section}' (known: name, "
                             f"{', '.join(f'[{s}]' for s in SECTIONS)})")
        if not isinstance(table, dict):
            raise InputError(f"{path}: '{section}' must be a table ([{section}] with keys)")
        fields.update(SECTIONS[section](table, f"{path}: [{section}]"))
    for section in REQUIRED:
        if section not in data:
            raise InputError(f"{path}: missing section [{section}]")
    chain = fields.get("chain", Chain())
    for axis in fields.get("limits", {}):
        if axis in ROTARY and axis not in chain.rotary:
            raise InputError(f"{path}: [axes] '{axis}' is not a rotary axis of this machine ([kinematics] rotary)")
    spindle = fields.get("spindle")
    if spindle is not None and not spindle.max_feed:  # the drives' largest feed: the rapid rate unless given
        from dataclasses import replace

        fields["spindle"] = replace(spindle, max_feed=fields["motion"].rapid * 60.0)
    return Machine(name=name.strip(), path=path, **fields)
