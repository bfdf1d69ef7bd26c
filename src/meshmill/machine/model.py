"""The machine tool as data, read by :mod:`~meshmill.machine.config` from TOML: motion limits,
kinematic chain, axis travel, G-code format. No imports from the rest of the package: every other
module of ``machine`` (kinematics, timing, post, G-code reader) reads this one.

Units: mm, s, radians (``corner_angle``, ``chain.singular``), deg/s (``rotary_rapid``).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

LINEAR = ("X", "Y", "Z")
ROTARY = ("A", "B", "C")  # about X, Y, Z
CHAINS = ("3-axis", "table-table", "head-table", "head-head")
DIALECTS = ("fanuc", "linuxcnc", "grbl")
RAPIDS = ("linear", "dogleg")  # [gcode] rapid: how G0 moves


@dataclass(frozen=True)
class Chain:
    """The kinematic chain (``[kinematics]``). ``type``: "3-axis", "table-table" (both rotaries
    carry the part: ``rotary[0]`` tilts the table, ``rotary[1]`` turns the part on it),
    "head-table" (``rotary[0]`` tilts the spindle head, ``rotary[1]`` turns the table) or
    "head-head" (both rotaries move the spindle head, the part stays on the fixed table: C, nearer
    the machine frame, turns the head about Z and carries ``rotary[0]``, which tilts the spindle).
    ``rotary`` is always (tilt, "C"); a head-head file lists the rotaries from the frame, ["C", "A"]
    or ["C", "B"] (["A", "C"] is taken as well). A rotary
    named A, B or C turns about X, Y or Z (right hand, positive angle turns the table or the head
    by that angle; ``reversed`` names the axes whose controller counts the other way).
    ``pivot`` (3,) mm: a point of the first rotary's axis in work coordinates at zero angles
    (table-table); ``offset`` (3,) mm: from there to a point of the second rotary's axis
    (table-table, zero when the axes meet); ``head_length`` mm: from the head's pivot to the
    spindle's gauge line along the tool (head-table, head-head). ``singular`` rad: within this of
    the pole (tool axis on C's axis, +Z or -Z) the turning angle is held."""

    type: str = "3-axis"
    rotary: tuple = ()
    reversed: tuple = ()
    pivot: tuple = (0.0, 0.0, 0.0)
    offset: tuple = (0.0, 0.0, 0.0)
    head_length: float = 0.0
    singular: float = math.radians(0.05)

    @property
    def head_pivot(self) -> bool:
        """The head tilts the tool (head-table, head-head): the control programs the head's pivot,
        so the tool's length (tip to gauge line) enters the joints."""
        return self.type in ("head-table", "head-head")


@dataclass(frozen=True)
class GcodeFormat:
    """How programs are written (``[gcode]``); the tool's texts (``tool_change``, ``tool_length``,
    ``spindle``, ``coolant_on``, ``tcp``) may use ``{number}`` (tool number), ``{name}`` and
    ``{rpm}``, ``comment`` uses ``{text}``, the others are written as given. ``inverse_time``: 5-axis feed moves in G93 (F =
    1 / minutes), else G94 mm/min; ``tcp``: the control does the kinematics (tool tip in work
    coordinates and the rotary angles are written), its switch-on text (e.g. "G43.4 H{number}");
    ``retract``: the lines that raise the tool to the machine's Z home before each tool change's
    spindle stop (after the first tool); ``rapid``: how the control moves in G0, "linear" (all axes
    on the straight line, as LinuxCNC and grbl) or "dogleg" (each axis at its own rapid rate, so
    the path bends where the shorter moves end: Fanuc's default, parameter 1401 LRP = 0); ``arcs``:
    a run of feed blocks on an arc in the XY plane (within the post's tolerance) written as one
    G2/G3 with I J (incremental centre; a helix where Z changes with the angle)."""

    dialect: str = "fanuc"
    decimals: int = 4
    angle_decimals: int = 4
    start: tuple = ("%", "O1000", "G21 G90 G17 G40 G49 G80 G94")
    end: tuple = ("M5", "M9", "G91 G28 Z0", "G90", "M30", "%")
    retract: tuple = ("G91 G28 Z0", "G90")
    tool_change: str = "T{number} M6"
    tool_length: str = "G43 H{number}"
    spindle: str = "S{rpm} M3"
    rpm: float = 10000.0
    coolant_on: str = "M8"
    coolant_off: str = "M9"
    comment: str = "({text})"
    inverse_time: bool = True
    rapid: str = "dogleg"
    tcp: str = ""
    tcp_off: str = "G49"
    line_numbers: bool = False
    arcs: bool = True


@dataclass(frozen=True)
class Machine:
    """A machine tool: linear-axis limits (``motion``, mm and s), ``corner_angle`` (radians:
    a sharper turn between moves stops the tool), ``tool_change`` and ``reorient`` (s), the axis
    travel ``limits`` ({letter: (low, high)} mm or degrees; a rotary absent or "continuous" turns
    freely), the kinematic ``chain``, the G-code ``gcode`` format, the rotary axes' speed
    ``rotary_rapid`` (deg/s) and the ``path`` of the file it was read from."""

    name: str
    motion: MotionLimits
    corner_angle: float
    tool_change: float
    reorient: float
    limits: dict = field(default_factory=dict)
    chain: Chain = Chain()
    gcode: GcodeFormat = GcodeFormat()
    rotary_rapid: float = 60.0
    path: str = ""
    spindle: "Spindle" = None

    def __post_init__(self):
        if self.spindle is None:
            object.__setattr__(self, "spindle", Spindle(max_feed=self.motion.rapid * 60.0))

    @property
    def axes(self) -> tuple:
        """The machine's axis letters in program order: X Y Z and its rotaries."""
        return LINEAR + tuple(sorted(self.chain.rotary))

    def summary(self) -> dict:
        """The machine in the file's units, for summary JSON files."""
        k = self.motion
        return {"name": self.name, "file": os.path.abspath(self.path) if self.path else "",
                "feed_mm_min": k.feed * 60.0, "rapid_mm_min": k.rapid * 60.0, "accel_mm_s2": k.accel,
                "jerk_mm_s3": k.jerk, "corner_angle_deg": math.degrees(self.corner_angle),
                "tool_change_s": self.tool_change, "reorient_s": self.reorient,
                "rotary_rapid_deg_min": self.rotary_rapid * 60.0, "kinematics": self.chain.type,
                "rotary": list(self.chain.rotary), "limits": {a: list(v) for a, v in self.limits.items()},
                "dialect": self.gcode.dialect, "spindle": self.spindle.summary()}


@dataclass(frozen=True)
class Spindle:
    """What the spindle and the feed drives allow: ``power_kw`` and ``torque_nm`` at the tool (0:
    not given, not checked), speeds ``min_rpm``..``max_rpm`` rev/min, and the largest programmed
    feed ``max_feed`` mm/min (default: the rapid rate)."""

    power_kw: float = 0.0
    torque_nm: float = 0.0
    min_rpm: float = 0.0
    max_rpm: float = 1e6
    max_feed: float = 0.0

    def summary(self) -> dict:
        return {"power_kw": self.power_kw, "torque_nm": self.torque_nm, "min_rpm": self.min_rpm,
                "max_rpm": self.max_rpm, "max_feed_mm_min": self.max_feed}


@dataclass(frozen=True)
class MotionLimits:
    """Limits of the machine's linear motion: ``feed`` and ``rapid`` in mm/s, ``accel`` mm/s²,
    ``jerk`` mm/s³."""

    feed: float
    accel: float
    jerk: float
    rapid: float

    @staticmethod
    def seed() -> "MotionLimits":
        """The seed's standard machine: V = 5 m/min, A = 6 m/s², J = 40 m/s³ (rapid 20 m/min)."""
        return MotionLimits(feed=5000.0 / 60.0, accel=6000.0, jerk=40000.0, rapid=20000.0 / 60.0)
