"""The whole 3-axis tool dropped onto a mesh: cutter, shank and holder together."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..kernels import cpu
from ..toolpath.linking import link_passes
from .verify import verify_toolpath

SAFE_ABOVE = 5.0  # mm above the part's top for rapid moves of 3-axis paths
TOUCH = 1e-6  # mm: a touch point's drop height is within this of its level ...
WALL = 1e-5  # mm: ... or within this distance of where the height jumps past it (a vertical wall)
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
    that a 3-axis position that clears the drop height clears the whole tool."""

    def __init__(self, tool, bvh, floor: float):
        self.radius, self.corner = tool.radius, tool.corner_radius
        parts = [(0.5 * tool.shank_diameter, tool.flute_length)]
        if tool.holder_diameter > 0:
            parts.append((0.5 * tool.holder_diameter, tool.gauge_length))
        self.body = (np.array([p[0] for p in parts]), np.array([p[1] for p in parts]))
        self.bvh, self.floor = bvh, floor

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        """Tip heights ``(k,)`` at ``xy (k, 2)``."""
        return cpu.drop_cutter(xy, self.radius, self.corner, self.floor, self.bvh.arrays, self.body)[0]

    def touch(self, inside_xy, outside_xy, f_inside, f_outside, z) -> np.ndarray:
        """Points ``(k, 2)`` between inside (height > z) and outside (<= z) points where the height
        reaches z from below (see :func:`meshmill.kernels.cpu.touch_points`)."""
        return cpu.touch_points(inside_xy, outside_xy, f_inside, f_outside, z, self.radius, self.corner, self.floor,
                                self.bvh.arrays, TOUCH, WALL, TOUCH_ROUNDS, self.body)


def verified_path(passes, tool_index, tools, bvh, safe_z, tol, step):
    """Link 3-axis ``passes`` (``(k, 3)`` tips each) into a tool path, verify it, and split passes at
    the feed moves that fail (the tool lifts over them) until it verifies clean. Returns
    ``(toolpath, report, passes)``; ``report["moves_left_out"]`` counts the moves given up."""
    left_out = 0
    for rnd in range(REPAIR_ROUNDS + 1):
        tp = link_passes(passes, tool_index, safe_z)
        report = verify_toolpath(bvh, tp, tools, tol, step)
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
