"""Parallel-plane zigzag over one zone of a surface, dropped with the exact 3-axis drop-cutter
(seed 002's black box, §4.1, on our kernels).

In the machining frame (the part turned so that the tool axis is +Z; the identity in 3-axis), the
passes are vertical planes at azimuth ``theta``. The tool is dropped every ``sample`` mm along a
plane; a sample belongs to the zone when the point it touches lies in one of the zone's cells.
A sample whose contact is on the surface's edge (the tool rolling over it) machines nothing. The
distance to the next plane is the smallest, over the pass's contacts, of the stepover that keeps
the scallop (eq. 2.3 with R_eff of eq. 1.5 at the contact's slope and feed angle, capped by the
flat bottom), measured on the surface square to the pass, projected on the horizontal, so the scallop limit holds at the
pass's worst point (§4.2). Consecutive pieces closer than ``link`` mm are joined by a feed move
dropped on the surface; farther ones by a retract and a rapid.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.bvh import build_bvh
from ..kernels.backend import MeshKernels
from ..ops.dropcutter import ToolDrop
from .scallop import effective_radius, stepover
from .surface import SurfaceMesh

SMOOTH = math.radians(20.0)  # a contact whose normal is farther from its cell's is on an edge
LINK_STEPOVERS = 4.0  # pieces this many largest stepovers apart (or closer) are linked at feed


def frame_rotation(axis) -> np.ndarray:
    """``(3, 3)`` rotation taking the unit tool ``axis (3,)`` to +Z (part frame -> machining
    frame): the shortest rotation, so a vertical axis gives the identity."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    z = np.array([0.0, 0.0, 1.0])
    c = float(a @ z)
    v = np.cross(a, z)
    s = float(np.linalg.norm(v))
    if s < 1e-15:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = v / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


@dataclass
class ZonePasses:
    """The passes of one zone in the machining frame: ``passes`` list of ``(k, 3)`` tool tips
    (links at feed included), the plane ``spacings (p,)`` mm used, the stepover-limiting R_eff
    ``(p,)`` of each plane, the ``contacts (m, 3)`` of the samples that machine the zone and the
    drop spacing ``sample`` mm."""

    passes: list
    spacings: np.ndarray
    r_eff: np.ndarray
    contacts: np.ndarray
    sample: float

    def coverage(self, points) -> float:
        """Fraction of the zone's cell centres ``points (n, 3)`` (machining frame) lying within
        one plane spacing or one drop spacing (the larger) of a contact (1 for an empty zone)."""
        if len(points) == 0:
            return 1.0
        if len(self.contacts) == 0:
            return 0.0
        gap = cKDTree(self.contacts).query(points)[0]
        return float(np.mean(gap <= max(self.spacings.max(), self.sample)))


class SurfaceSetup:
    """One surface in one machining frame with one cutter: the mesh kernels, and the cell of
    every mesh node for zone membership. ``rotation (3, 3)`` part -> machining frame."""

    def __init__(self, smesh: SurfaceMesh, grid_shape, tool, rotation=None, device="cpu"):
        self.rotation = np.eye(3) if rotation is None else np.asarray(rotation, float)
        self.tool = tool
        verts = smesh.mesh.vertices @ self.rotation.T
        self.kern = MeshKernels(build_bvh(verts, smesh.mesh.faces), device)
        self.floor = float(verts[:, 2].min()) - 1.0  # below the lowest point: a flat bottom resting there touches
        self.top = float(verts[:, 2].max())
        self.drop = ToolDrop(tool, self.kern, self.floor)
        self.smesh = smesh
        self.grid_shape = grid_shape

    def contact_cells(self, contacts):
        """Grid cell ``(k,)`` of each contact ``(k, 3)`` (machining frame), -1 where there is
        none or it lies on the surface's free edge."""
        ok = np.isfinite(contacts[:, 0])
        cell = np.full(len(contacts), -1, np.int64)
        if ok.any():
            uv, edge = self.smesh.locate(contacts[ok] @ self.rotation)
            nu, nv = self.grid_shape
            iu = np.clip((uv[:, 0] * nu).astype(np.int64), 0, nu - 1)
            iv = np.clip((uv[:, 1] * nv).astype(np.int64), 0, nv - 1)
            cell[ok] = np.where(edge, -1, iu * nv + iv)
        return cell

    def contact_normals(self, tips, contacts):
        """The cutter's unit normal ``(k, 3)`` at each contact (machining frame), which is the
        surface's wherever the contact is smooth: from the contact towards the centre of the
        corner circle through it (straight up on a bull-nose's flat bottom)."""
        R, r = self.tool.radius, self.tool.corner_radius
        h = contacts[:, :2] - tips[:, :2]
        rho = np.linalg.norm(h, axis=1)
        ring = np.where(rho > 1e-12, np.minimum(rho, R - r) / np.maximum(rho, 1e-12), 0.0)
        centre = np.column_stack([tips[:, :2] + ring[:, None] * h, tips[:, 2] + r])
        n = centre - contacts
        length = np.linalg.norm(n, axis=1, keepdims=True)
        up = np.zeros_like(n)
        up[:, 2] = 1.0
        return np.where(length > 1e-9 * max(r, 1e-9), n / np.maximum(length, 1e-300), up)

    def zone_passes(self, in_zone, points, normals, theta, scallop, sample=0.5) -> ZonePasses:
        """Zigzag over the cells where ``in_zone (n_cells,) bool`` holds, whose sample ``points
        (n_cells, 3)`` (part frame) bound it; planes at azimuth ``theta`` rad (machining frame).
        The stepover looks at the contacts where the cutter's normal is within ``SMOOTH`` of the
        cell's sample normal ``normals (n_cells, 3)`` (all, if none is): a tool rolling over an
        edge or a crease does not set the scallop of the faces beside it."""
        cell_normals = normals @ self.rotation.T
        R, r = self.tool.radius, self.tool.corner_radius
        d = np.array([math.cos(theta), math.sin(theta)])
        across = np.array([-math.sin(theta), math.cos(theta)])
        pts = (points[in_zone] @ self.rotation.T)[:, :2]
        s_lo, s_hi = (pts @ d).min() - R - sample, (pts @ d).max() + R + sample
        t_lo, t_hi = (pts @ across).min() - R, (pts @ across).max() + R
        n_s = int(math.ceil((s_hi - s_lo) / sample)) + 1
        s = np.linspace(s_lo, s_hi, n_s)
        probe = float(stepover(scallop, min(R, r) if r > 0 else R))  # step while no contact is in the zone
        passes, spacings, r_effs, touched = [], [], [], []
        t, k = t_lo, 0
        while t <= t_hi:
            xy = s[:, None] * d + t * across
            tips, contacts = self.drop.with_contacts(xy)
            cell = self.contact_cells(contacts)
            inside = (cell >= 0) & in_zone[np.maximum(cell, 0)]
            if not inside.any():
                t += probe
                continue
            n = self.contact_normals(np.column_stack([xy, tips])[inside], contacts[inside])
            smooth = np.einsum("ij,ij->i", n, cell_normals[cell[inside]]) >= math.cos(SMOOTH)
            if smooth.any():
                n = n[smooth]
            slope = np.arccos(np.clip(np.abs(n[:, 2]), 0.0, 1.0))
            alpha = theta - np.arctan2(n[:, 1], n[:, 0])
            r_eff = effective_radius(R, r, slope, alpha)
            sod = stepover(scallop, r_eff, R, r)
            # sod is measured on the surface square to the pass: sqrt(1 - (n . across)²) of it is horizontal
            spacing = sod * np.sqrt(np.maximum(1.0 - (n[:, :2] @ across) ** 2, 0.0))
            worst = int(np.argmin(spacing))
            cl = np.column_stack([xy, tips])
            pieces = _runs(cl, inside)
            if k % 2:
                pieces = [p[::-1] for p in pieces[::-1]]
            passes += pieces
            touched.append(contacts[inside])
            spacings.append(spacing[worst])
            r_effs.append(r_eff[worst])
            t += spacing[worst]
            k += 1
        link = LINK_STEPOVERS * (max(spacings) if spacings else probe)
        return ZonePasses(self.linked(passes, link, sample), np.array(spacings), np.array(r_effs),
                          np.concatenate(touched) if touched else np.empty((0, 3)), sample)

    def linked(self, pieces, link, sample):
        """Join consecutive ``pieces`` whose gap is at most ``link`` mm by a feed move dropped on
        the surface every ``sample`` mm; returns the joined passes."""
        out = []
        for p in pieces:
            if out and np.linalg.norm(p[0, :2] - out[-1][-1, :2]) <= link:
                a, b = out[-1][-1, :2], p[0, :2]
                m = max(2, int(math.ceil(np.linalg.norm(b - a) / sample)) + 1)
                xy = a + np.linspace(0.0, 1.0, m)[1:-1, None] * (b - a)
                mid = np.column_stack([xy, self.drop(xy)]) if len(xy) else np.empty((0, 3))
                out[-1] = np.concatenate([out[-1], mid, p])
            else:
                out.append(p)
        return out


def _runs(cl, mask):
    """Maximal runs of consecutive rows of ``cl (k, 3)`` where ``mask (k,)`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [cl[a:b] for a, b in zip(edges[::2], edges[1::2])]
