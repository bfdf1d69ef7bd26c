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
```

Each section has a reader in :data:`SECTIONS` that checks its table and returns fields of
:class:`Machine`; a new section (axis travel, kinematic chain, G-code dialect) is a new reader and
new fields with defaults. Unknown sections and keys are refused.
"""
from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass

from ..errors import InputError
from .timing import Kinematics

SHIPPED = os.path.join(os.path.dirname(os.path.dirname(__file__)), "data", "machines")

MOTION_POSITIVE = ("feed_mm_min", "rapid_mm_min", "accel_mm_s2", "jerk_mm_s3")
MOTION_NON_NEGATIVE = ("corner_angle_deg", "tool_change_s", "reorient_s")


@dataclass(frozen=True)
class Machine:
    """A machine tool: linear-axis limits (``kinematics``, mm and s), ``corner_angle`` (radians:
    a sharper turn between moves stops the tool), ``tool_change`` and ``reorient`` (s), and the
    ``path`` of the file it was read from."""

    name: str
    kinematics: Kinematics
    corner_angle: float
    tool_change: float
    reorient: float
    path: str = ""

    def summary(self) -> dict:
        """The machine in the file's units, for summary JSON files."""
        k = self.kinematics
        return {"name": self.name, "file": os.path.abspath(self.path) if self.path else "",
                "feed_mm_min": k.feed * 60.0, "rapid_mm_min": k.rapid * 60.0, "accel_mm_s2": k.accel,
                "jerk_mm_s3": k.jerk, "corner_angle_deg": math.degrees(self.corner_angle),
                "tool_change_s": self.tool_change, "reorient_s": self.reorient}


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
    """``[motion]``: kinematics, corner angle, tool change and re-orientation times."""
    keys = MOTION_POSITIVE + MOTION_NON_NEGATIVE
    for key in table:
        if key not in keys:
            raise InputError(f"{where} unknown key '{key}' (known: {', '.join(keys)})")
    for key in keys:
        if key not in table:
            raise InputError(f"{where} missing key '{key}'")
    v = {key: _number(table, key, where, key in MOTION_POSITIVE) for key in keys}
    if v["feed_mm_min"] > v["rapid_mm_min"]:
        raise InputError(f"{where} 'feed_mm_min' ({v['feed_mm_min']:g}) must not exceed 'rapid_mm_min' "
                         f"({v['rapid_mm_min']:g})")
    if v["corner_angle_deg"] >= 180.0:
        raise InputError(f"{where} 'corner_angle_deg' must be below 180, got {v['corner_angle_deg']:g}")
    kinematics = Kinematics(feed=v["feed_mm_min"] / 60.0, accel=v["accel_mm_s2"], jerk=v["jerk_mm_s3"],
                            rapid=v["rapid_mm_min"] / 60.0)
    return {"kinematics": kinematics, "corner_angle": math.radians(v["corner_angle_deg"]),
            "tool_change": v["tool_change_s"], "reorient": v["reorient_s"]}


SECTIONS = {"motion": _motion}  # section -> reader of its table into Machine fields
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
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: not a valid TOML machine file ({exc})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot read the machine file ({exc.strerror})") from None
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
    return Machine(name=name.strip(), path=path, **fields)
