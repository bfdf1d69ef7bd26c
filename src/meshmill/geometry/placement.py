"""Where a part sits on the machine: the units of its file, which of its axes points to the
spindle, and the work zero.

A :class:`Setup` is what the user says (``units``, ``up``, ``origin``, ``scale``); placing a part's
vertices by it gives the work frame (mm, +Z toward the spindle, the work zero at the origin) in
which every operation computes and every path is written: ``work = scale * R @ p + offset``
(:class:`Placement`). It is applied to the file's coordinates before anything else, welding and
the mm tolerances included, so that a part in metres or at UTM coordinates 5e6 m away is
computed as if it had been drawn in mm near the origin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
ORIGINS = ("file", "bottom-centre", "top-centre", "corner")
AXES = {"+X": (1, 0, 0), "-X": (-1, 0, 0), "+Y": (0, 1, 0), "-Y": (0, -1, 0), "+Z": (0, 0, 1), "-Z": (0, 0, -1)}
SMALL_PART = 1.0  # mm: a part smaller than this across is more likely drawn in metres
LARGE_PART = 5000.0  # mm: larger than any machine's travel: another unit?
FAR = 1000.0  # mm: a part farther than this (and than 10 sizes) from the file's origin is far away


@dataclass(frozen=True)
class Placement:
    """``work = scale * rotation @ p + offset`` (p in the file's coordinates and units)."""

    scale: float = 1.0
    rotation: np.ndarray = None  # (3, 3), proper rotation; None: identity
    offset: np.ndarray = None  # (3,) mm; None: zero
    units: str = "mm"
    up: str = "+Z"
    origin: str = "file"
    model_scale: float = 1.0

    def apply(self, points: np.ndarray) -> np.ndarray:
        """File coordinates ``(k, 3)`` to the work frame ``(k, 3)`` (mm)."""
        p = np.asarray(points, np.float64) * self.scale
        if self.rotation is not None:
            p = p @ self.rotation.T
        return p + self.offset if self.offset is not None else p

    def summary(self) -> dict:
        r = np.eye(3) if self.rotation is None else self.rotation
        t = np.zeros(3) if self.offset is None else self.offset
        return {"units": self.units, "model_scale": self.model_scale, "scale": self.scale, "up": self.up,
                "origin": self.origin,
                "rotation": (np.round(r, 12) + 0.0).tolist(), "offset_mm": (np.round(t, 9) + 0.0).tolist()}


def _numbers(text: str, what: str) -> list[float]:
    try:
        vals = [float(x) for x in text.replace(" ", "").split(",")]
    except ValueError:
        raise InputError(f"{what} '{text}': expected numbers separated by commas", what) from None
    if not all(math.isfinite(v) for v in vals):
        raise InputError(f"{what} '{text}': the numbers must be finite", what)
    return vals


def up_rotation(up: str) -> np.ndarray:
    """The rotation ``(3, 3)`` that turns the part so that ``up`` points to +Z: an axis (``+X``,
    ``-Y``, ...: the smallest turn that takes it to +Z; -Z turns about X), three Euler angles in
    degrees ``RX,RY,RZ`` (about the fixed X, then Y, then Z axes), or nine numbers (the rows of a
    rotation matrix)."""
    key = up.strip().upper()
    if key in ("X", "Y", "Z"):
        key = "+" + key
    if key in AXES:
        a = np.array(AXES[key], float)
        z = np.array([0.0, 0.0, 1.0])
        if a[2] > 0.5:
            return np.eye(3)
        if a[2] < -0.5:
            return np.diag([1.0, -1.0, -1.0])  # half a turn about X
        k = np.cross(a, z)  # axis of the quarter turn
        kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        return np.eye(3) + kx + kx @ kx  # Rodrigues, 90 degrees
    usage = (f"up '{up}': give an axis (+X, -Y, ...), three angles RX,RY,RZ in degrees, "
             "or nine numbers (a rotation matrix by rows)")
    try:
        vals = _numbers(up, "up")
    except InputError:
        raise InputError(usage, "up") from None
    if len(vals) == 3:
        rx, ry, rz = (math.radians(v) for v in vals)
        cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
        mx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        my = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        mz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        return mz @ my @ mx
    if len(vals) == 9:
        m = np.array(vals).reshape(3, 3)
        if not (np.allclose(m @ m.T, np.eye(3), atol=1e-6) and np.linalg.det(m) > 0):
            raise InputError(f"up '{up}': the nine numbers are not a rotation (orthonormal rows, determinant +1)", "up")
        u, _, vt = np.linalg.svd(m)  # the nearest exact rotation
        return u @ vt
    raise InputError(usage, "up")


@dataclass(frozen=True)
class Setup:
    """How the part is set up: ``units`` of the file (mm, cm, m, in), ``up`` (see
    :func:`up_rotation`) and ``origin``, the work zero: ``file`` (the file's own, turned and
    scaled), ``bottom-centre`` (the centre of the bottom of the part's box), ``top-centre`` (of its
    top), ``corner`` (the box's lowest corner, x, y and z smallest), or ``X,Y,Z`` (a point in the
    file's coordinates and units); ``scale``: the model's scale (0.05: a 1:20 model of a car)."""

    units: str = "mm"
    up: str = "+Z"
    origin: str = "file"
    scale: float = 1.0

    def check(self) -> None:
        if self.units not in UNITS:
            raise InputError(f"units must be one of {', '.join(UNITS)}, got {self.units!r}", "units")
        if isinstance(self.scale, bool) or not isinstance(self.scale, (int, float)) or not (
                math.isfinite(self.scale) and self.scale > 0):
            raise InputError(f"scale must be a positive number, got {self.scale!r}", "scale")
        up_rotation(self.up)
        if self.origin not in ORIGINS and len(_numbers(self.origin, "origin")) != 3:
            raise InputError(f"origin '{self.origin}': give one of {', '.join(ORIGINS)} or a point X,Y,Z", "origin")

    def place(self, vertices: np.ndarray, name: str = "part"):
        """``(work-frame vertices (n, 3), Placement, warnings)`` of the file's ``vertices (n, 3)``."""
        self.check()
        scale = UNITS[self.units] * float(self.scale)
        rot = up_rotation(self.up)
        v = (np.asarray(vertices, np.float64) * scale) @ rot.T
        lo, hi = v.min(axis=0), v.max(axis=0)
        if self.origin == "file":
            zero = np.zeros(3)
        elif self.origin == "bottom-centre":
            zero = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2]])
        elif self.origin == "top-centre":
            zero = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), hi[2]])
        elif self.origin == "corner":
            zero = lo.copy()
        else:
            zero = rot @ (np.array(_numbers(self.origin, "origin")) * scale)
        v = v - zero
        placement = Placement(scale=scale, rotation=None if np.array_equal(rot, np.eye(3)) else rot,
                              offset=None if not zero.any() else -zero, units=self.units, up=self.up,
                              origin=self.origin, model_scale=float(self.scale))
        return v, placement, self._warnings(v, name)

    def _warnings(self, v, name) -> list[str]:
        out = []
        size = float(np.ptp(v, axis=0).max())
        if size < SMALL_PART:
            guess = "m" if self.units == "mm" else "mm"
            out.append(f"{name}: the part is only {size:.4g} mm across in {self.units}: if the file is in another unit, "
                       f"say which (units {guess}, or cm, in)")
        elif size > LARGE_PART:
            out.append(f"{name}: the part is {size:.6g} mm across in {self.units}, larger than a machine: check units")
        centre = 0.5 * (v.min(axis=0) + v.max(axis=0))
        far = float(np.linalg.norm(centre))
        if far > max(FAR, 10.0 * size):
            out.append(f"{name}: the part lies {far:.6g} mm from the work zero (slow and imprecise to compute there, "
                       "and far from any machine's travel): origin bottom-centre, top-centre, corner or a point "
                       "puts the work zero on the part")
        return out
