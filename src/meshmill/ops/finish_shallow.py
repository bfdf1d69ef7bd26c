"""The shallow areas of a finish machined by raster passes of its balls (``finish --scallop``).

Z-levels dz apart lie dz / sin(slope) apart on the surface, so a scallop limit needs levels ever
closer as the surface flattens: under ``min_slope`` from the horizontal, parallel passes serve
better (the "steep and shallow" split of CAM systems). Each ball of the table, largest first,
runs parallel lines over the box of the up-facing facets flatter than ``min_slope``, their
distance the scallop limit's stepover on a surface sloped up to ``min_slope`` + ``MARGIN_DEG``
(s(R)·cos). Every point is an exact drop of the whole tool (cutter, and shank and holder out of
the material left on the part), refined where the surface leaves the chord. A point is kept
where the ball touches the part on a surface that flat (its contact normal within
``min_slope + MARGIN_DEG`` of +Z: a touch on a wall, an edge or the floor under the part is the
Z-levels' or nobody's), and no larger ball touched the part near there (within ``COVER`` of its
stepover): a smaller ball reaches only what the larger ones could not, by walls and in
hollows. The kept stretches of each line, longer than ``min_run``, are the passes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..toolpath.linking import simplify_polyline
from ..pathing.dropcutter import ToolDrop
from .finish_levels import scallop_spacing
from ..pathing.dropcutter import drop_refined

SCALLOP_MIN_SLOPE = 10.0  # deg from the horizontal: flatter surfaces are rastered, not Z-levelled (scallop)
MARGIN_DEG = 5.0  # the raster keeps contacts up to this much steeper than the shallow limit (overlap)
COVER = 0.75  # a contact within this share of a larger ball's stepover of its contacts is that ball's


@dataclass
class ShallowPasses:
    """Raster passes over the shallow areas: ``tips[i] (m, 3)`` tool tips (axis +Z) of pass i cut
    with ball ``rank[i]`` (into the finish's balls, largest first); ``contacts[i] (q, 3)`` where the
    ball touches the part along it (every dropped point, before the tips were simplified: what the
    pass stands for); ``direction (3,)`` the lines' direction; ``spacing`` the largest distance
    between neighbouring contacts (the stepover or the sample, mm); ``report``."""

    tips: list = field(default_factory=list)
    rank: list = field(default_factory=list)
    contacts: list = field(default_factory=list)
    direction: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    spacing: float = 0.0
    report: dict = field(default_factory=dict)


def shallow_facets(mesh, min_slope):
    """``(k,) bool``: the facets facing up and flatter than ``min_slope`` deg from the horizontal."""
    return mesh.face_normals[:, 2] >= math.cos(math.radians(min_slope))


def _lines(lo, hi, angle, step, sample):
    """Parallel lines at ``angle`` (rad) ``step`` apart over the box ``lo``-``hi`` (2,), points
    ``sample`` apart: a list of ``(k, 2)``, alternating in direction."""
    d = np.array([math.cos(angle), math.sin(angle)])
    n = np.array([-d[1], d[0]])
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    s0, s1 = (corners @ d).min(), (corners @ d).max()
    t0, t1 = (corners @ n).min(), (corners @ n).max()
    count = int(math.ceil((t1 - t0) / step)) + 1
    offsets = t0 + (t1 - t0) * np.arange(count) / max(count - 1, 1)
    s = np.linspace(s0, s1, int(math.ceil((s1 - s0) / sample)) + 1)
    return [(s if k % 2 == 0 else s[::-1])[:, None] * d + t * n for k, t in enumerate(offsets)]


def shallow_fill(mesh, kern, balls, height, min_slope, sample, tol, body_grow, min_run) -> ShallowPasses:
    """Raster passes of ``balls`` (:class:`~meshmill.tools.table.Tool`, largest first) over the
    shallow areas of ``mesh`` (bound to ``kern``) for the scallop limit ``height`` mm."""
    shallow = shallow_facets(mesh, min_slope)
    v = mesh.vertices[mesh.faces]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    out = ShallowPasses(report={"min_slope_deg": float(min_slope), "area_mm2": float(area[shallow].sum()),
                                "passes": 0, "cl_points": 0, "by_tool": {}})
    if not shallow.any():
        return out
    pts = v[shallow].reshape(-1, 3)
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)
    angle = 0.0 if hi[0] - lo[0] >= hi[1] - lo[1] else 0.5 * math.pi  # along the longer side
    out.direction = np.array([math.cos(angle), math.sin(angle), 0.0])
    floor = float(mesh.bounds[0, 2])
    cos_keep = math.cos(math.radians(min_slope + MARGIN_DEG))
    covered = []  # (tree of contacts, radius) of the larger balls
    for rank, tool in enumerate(balls):
        R = tool.radius
        step = float(scallop_spacing(R, height)) * cos_keep
        out.spacing = max(out.spacing, step, sample)
        drop = ToolDrop(tool, kern, floor, body_grow=body_grow)
        kept_contacts, passes, points = [], 0, 0
        for line in _lines(lo - R, hi + R, angle, step, sample):
            tips = drop_refined(line, drop, 0.5 * tol, sample / 64)
            _, contact = drop.with_contacts(tips[:, :2])
            normal_z = (tips[:, 2] + R - contact[:, 2]) / R
            keep = np.isfinite(contact[:, 2]) & (normal_z >= cos_keep) & (tips[:, 2] > floor + 1e-9)
            for tree, radius in covered:
                if keep.any():
                    sel = np.nonzero(keep)[0]
                    dist, _ = tree.query(contact[sel], distance_upper_bound=radius)
                    keep[sel[np.isfinite(dist)]] = False
            edges = np.flatnonzero(np.diff(np.r_[0, keep.astype(np.int8), 0]))
            for a, b in zip(edges[::2], edges[1::2]):
                piece = tips[a:b]
                if len(piece) < 2 or np.linalg.norm(np.diff(piece, axis=0), axis=1).sum() < min_run:
                    continue
                keep_pts = simplify_polyline(piece, 0.5 * tol, mask=True)
                out.tips.append(piece[keep_pts])
                out.contacts.append(contact[a:b])
                out.rank.append(rank)
                kept_contacts.append(contact[a:b])
                passes += 1
                points += int(keep_pts.sum())
        if kept_contacts:
            covered.append((cKDTree(np.concatenate(kept_contacts)), COVER * step))
        out.report["by_tool"][tool.name] = {"stepover": step, "passes": passes, "cl_points": points}
        out.report["passes"] += passes
        out.report["cl_points"] += points
    return out
