"""Gouge and collision check of any tool path against a mesh.

Every pose of the path is checked exactly (distances to the triangles, not to sampled points), and
each move is checked at intermediate poses no more than ``step`` apart (tip, and axis motion at the
far end of the tool), with the tip and the axis interpolated linearly as a controller would.

A feed move gouges when the cutting part (end and flutes) enters the part by more than ``tol``; it
collides when the shank or holder does. Any rapid move that touches the part is reported too.
Bull-nose ends are checked as 36 spheres along their torus (the rest exactly).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels.backend import bind
from ..tolerances import GOUGE_TOL
from ..tools.table import pack_cylinders, pack_rings
from ..toolpath.model import Toolpath

DEFAULT_STEP = 0.5  # mm between checked poses along a move


@dataclass
class Problem:
    kind: str  # gouge | collision | rapid
    move: int  # 0-based move index
    line: int  # source line (0: not from a file)
    part: str
    depth: float  # mm
    tip: tuple

    def describe(self) -> str:
        where = f"line {self.line}" if self.line else f"move {self.move + 1}"
        x, y, z = self.tip
        return f"{self.kind}: {self.part} {self.depth:.4f} mm deep at {where}, tip ({x:.3f}, {y:.3f}, {z:.3f})"


def sample_moves(tp: Toolpath, tools, step: float):
    """Poses along the path: ``tip, axis (s, 3)``, ``tool, move (s,)``, ``rapid (s,) bool``."""
    k = len(tp)
    if k == 0:
        e3, e = np.empty((0, 3)), np.empty(0, np.int64)
        return e3, e3, e, e, np.empty(0, bool)
    reach = np.array([t.reach for t in tools])[tp.tool]
    dtip = np.zeros(k)
    dang = np.zeros(k)
    if k > 1:
        dtip[1:] = np.linalg.norm(np.diff(tp.tip, axis=0), axis=1)
        cosang = np.clip(np.einsum("ij,ij->i", tp.axis[1:], tp.axis[:-1]), -1.0, 1.0)
        dang[1:] = np.arccos(cosang) * reach[1:]
    n = np.maximum(1, np.ceil(np.maximum(dtip, dang) / step)).astype(np.int64)
    n[0] = 1  # a move after a tool change is checked along its way with the new tool
    move = np.repeat(np.arange(k), n)
    first = np.cumsum(n) - n
    j = np.arange(n.sum()) - np.repeat(first, n) + 1
    frac = j / np.repeat(n, n)
    prev = np.maximum(move - 1, 0)
    frac[move == 0] = 1.0
    tip = tp.tip[prev] + frac[:, None] * (tp.tip[move] - tp.tip[prev])
    axis = tp.axis[prev] + frac[:, None] * (tp.axis[move] - tp.axis[prev])
    norm = np.linalg.norm(axis, axis=1, keepdims=True)
    axis = np.where(norm > 1e-9, axis / np.maximum(norm, 1e-300), tp.axis[move])
    return tip, axis, tp.tool[move], move, tp.rapid[move]


def _part_names(tools, k):
    names = []
    for tool in tools:
        row = []
        for t0, t1, r, cut in tool.cylinders():
            if cut:
                row.append("end" if t0 == 0.0 else "flutes")
            else:
                row.append("shank" if abs(t0 - tool.flute_length) < 1e-12 and t1 == tool.gauge_length else "holder")
        names.append(row + [""] * (k - len(row)))
    return names


def verify_toolpath(bvh, tp: Toolpath, tools, tol: float = GOUGE_TOL, step: float = DEFAULT_STEP,
                    worst: int = 10, device: str = "cpu") -> dict:
    """Check ``tp`` against the mesh of ``bvh`` (a BVH run on ``device``, or
    :class:`~meshmill.kernels.backend.MeshKernels`); returns a JSON-ready report with the counts of
    moves that gouge, collide or rapid into the part, and the ``worst`` cases. Where the moves come
    from a file, ``lines`` counts its lines with moves and ``problem_lines`` its lines with a
    problem of each kind (a G-code arc or rotary block is read as several moves)."""
    tip, axis, tool, move, rapid = sample_moves(tp, tools, step)
    (t0, t1, r), cutting = pack_cylinders(tools)
    # a flat bottom resting exactly on a facet touches it: the slab of a cutting cylinder that
    # starts at the tip starts tol above it
    segs = (np.where(cutting & (t0 == 0.0), tol, t0), t1, r)
    if len(tip) == 0:
        return {"moves": 0, "poses_checked": 0, "step": float(step), "tolerance": float(tol), "gouging_moves": 0,
                "colliding_moves": 0, "rapid_moves_touching": 0, "max_gouge": 0.0, "max_collision": 0.0,
                "ok": True, "worst": [], "problem_moves": [], "lines": 0,
                "problem_lines": {"gouge": 0, "collision": 0, "rapid": 0}}
    ring_depth, seg_depth = bind(bvh, device).pose_penetration(tip, axis, tool, pack_rings(tools), segs, base=t0)
    cut_mask = cutting[tool]
    seg_cut = np.where(cut_mask, seg_depth, 0.0)
    seg_body = np.where(~cut_mask, seg_depth, 0.0)
    end_depth = np.maximum(ring_depth, seg_cut.max(axis=1))
    body_depth = seg_body.max(axis=1)
    names = _part_names(tools, seg_depth.shape[1])
    problems = []

    def collect(kind, mask, depth, part_of):
        idx = np.nonzero(mask)[0]
        if len(idx) == 0:
            return 0
        # the deepest sample of each offending move
        order = np.lexsort((-depth[idx], move[idx]))
        idx = idx[order]
        firsts = idx[np.r_[True, move[idx][1:] != move[idx][:-1]]]
        for i in firsts:
            problems.append(Problem(kind, int(move[i]), int(tp.line[move[i]]), part_of(i), float(depth[i]),
                                    tuple(float(v) for v in tip[i])))
        return len(firsts)

    def end_part(i):
        if ring_depth[i] >= seg_cut[i].max():
            return tools[tool[i]].type + " end"
        return names[tool[i]][int(np.argmax(seg_cut[i]))]

    def body_part(i):
        return names[tool[i]][int(np.argmax(seg_body[i]))]

    def any_part(i):
        return end_part(i) if end_depth[i] >= body_depth[i] else body_part(i)

    n_gouge = collect("gouge", ~rapid & (end_depth > tol), end_depth, end_part)
    n_coll = collect("collision", ~rapid & (body_depth > tol), body_depth, body_part)
    worst_any = np.maximum(end_depth, body_depth)
    n_rapid = collect("rapid", rapid & (worst_any > tol), worst_any, any_part)
    problems.sort(key=lambda p: -p.depth)
    lines = {kind: len({p.line for p in problems if p.kind == kind and p.line > 0})
             for kind in ("gouge", "collision", "rapid")}
    return {
        "moves": int(len(tp)),
        "poses_checked": int(len(tip)),
        "step": float(step),
        "tolerance": float(tol),
        "gouging_moves": n_gouge,
        "colliding_moves": n_coll,
        "rapid_moves_touching": n_rapid,
        "max_gouge": float(end_depth[~rapid].max()) if (~rapid).any() else 0.0,
        "max_collision": float(body_depth[~rapid].max()) if (~rapid).any() else 0.0,
        "ok": n_gouge == 0 and n_coll == 0 and n_rapid == 0,
        "worst": [p.describe() for p in problems[:worst]],
        "problem_moves": sorted({p.move for p in problems}),
        "lines": int(len(np.unique(tp.line[tp.line > 0]))),
        "problem_lines": lines,
    }
