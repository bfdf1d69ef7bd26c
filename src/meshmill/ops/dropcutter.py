"""The whole 3-axis tool dropped onto a mesh: cutter, shank and holder together."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kernels import cpu
from ..kernels.backend import bind
from ..toolpath.linking import link_passes
from .verify import verify_toolpath

SAFE_ABOVE = 5.0  # mm above the part's top for rapid moves of 3-axis paths
TOUCH = 1e-6  # mm: a touch point's drop height is within this of its level ...
WALL = 1e-4  # mm: ... or the level set is within this distance of it (so always at a vertical wall)
TOUCH_ROUNDS = 80
REPAIR_ROUNDS = 3


def pick_tool(tools, name):
    """``(index, tool)`` of the tool called ``name`` in the table."""
    for i, t in enumerate(tools):
        if t.name == name:
            return i, t
    raise InputError(f"no tool named '{name}' in the table (have: {', '.join(t.name for t in tools)})")


class ToolDrop:
    """Drop-cutter heights of a vertical tool over the mesh of ``bvh``, never below ``floor``:
    the cutter's exact contact, and the shank and holder as flat-bottomed cylinders above it, so
    that a 3-axis position that clears the drop height clears the whole tool. ``bvh``: a BVH (run
    on ``device``) or :class:`~meshmill.kernels.backend.MeshKernels`."""

    def __init__(self, tool, bvh, floor: float, device: str = "cpu"):
        self.radius, self.corner = tool.radius, tool.corner_radius
        parts = [(0.5 * tool.shank_diameter, tool.flute_length)]
        if tool.holder_diameter > 0:
            parts.append((0.5 * tool.holder_diameter, tool.gauge_length))
        self.body = (np.array([p[0] for p in parts]), np.array([p[1] for p in parts]))
        self.kern, self.floor = bind(bvh, device), floor

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """Tip heights ``(k,)`` at ``xy (k, 2)``."""
        return self.with_contacts(xy)[0]

    def with_contacts(self, xy: np.ndarray):
        """Tip heights ``(k,)`` at ``xy (k, 2)`` and the mesh points touched ``(k, 3)`` (NaN: none)."""
        return self.kern.drop_cutter(xy, self.radius, self.corner, self.floor, self.body)

    def bounds(self, xy: np.ndarray, delta: float):
        """Upper and lower bounds ``(k,), (k,)`` of the drop height anywhere within ``delta`` mm of
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
                rise = cpu.cut.profile(rho0, R, r)
                lower = np.maximum(lower, self.kern.drop_cutter(xy, rho0 - delta, 0.0, self.floor + rise)[0] - rise)
        return upper, lower

    def touch(self, inside_xy, outside_xy, f_inside, f_outside, z, inside_contacts=None) -> np.ndarray:
        """Points ``(k, 2)`` between inside (height > z) and outside (<= z) points where the height
        reaches z from below (see :func:`meshmill.kernels.cpu.touch_points`)."""
        return self.kern.touch_points(inside_xy, outside_xy, f_inside, f_outside, z, self.radius, self.corner,
                                      self.floor, TOUCH, WALL, TOUCH_ROUNDS, self.body, inside_contacts)


def verified_path(passes, tool_index, tools, kern, safe_z, tol, step):
    """Link 3-axis ``passes`` (``(k, 3)`` tips each) into a tool path, verify it against the mesh of
    ``kern`` (:class:`~meshmill.kernels.backend.MeshKernels`), and split passes at
    the feed moves that fail (the tool lifts over them) until it verifies clean. Returns
    ``(toolpath, report, passes)``; ``report["moves_left_out"]`` counts the moves given up."""
    left_out = 0
    for rnd in range(REPAIR_ROUNDS + 1):
        tp = link_passes(passes, tool_index, safe_z)
        report = verify_toolpath(kern, tp, tools, tol, step)
        bad = report.pop("problem_moves")
        if report["ok"] or rnd == REPAIR_ROUNDS:
            break
        # move m of pass k's block [start, start + 2 + len(p) + 1): rapid, rapid, feed to p[0], ..., rapid
        owner, point = [], []
        for k, p in enumerate(passes):
            owner += [k] * (len(p) + 3)
            point += [-1, -1] + list(range(len(p))) + [-1]
        splits = {}
        for m in bad:
            if point[m] > 0:
                splits.setdefault(owner[m], []).append(point[m])
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
