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

from ..kernels.backend import solid_kernels
from .dropcutter import ToolDrop
from ..tolerances import STOCK_ALLOWANCE
from .scallop import stepover, stepover_exact
from ..geometry.patches import SurfaceMesh

SMOOTH = math.radians(20.0)  # a contact whose normal is farther from its cell's is on an edge
LINK_STEPOVERS = 4.0  # pieces this many largest stepovers apart (or closer) are linked at feed
ON_SURFACE = 1e-6  # mm: a point this close to the triangles is on them


def wrap_axial(theta):
    """Axial angle(s) rad reduced to [-pi/2, pi/2)."""
    return (np.asarray(theta, dtype=float) + np.pi / 2) % np.pi - np.pi / 2


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
    (links at feed included), the plane ``spacings (p,)`` mm used (horizontal), and the
    ``contacts (m, 3)`` of the samples that machine the zone with the ``reach (m,)`` of each on the
    surface (half its plane's spacing there, square to the pass, plus half the way to its
    neighbours along the pass)."""

    passes: list
    spacings: np.ndarray
    contacts: np.ndarray
    reach: np.ndarray

    def coverage(self, points) -> float:
        """Fraction of ``points (n, 3)`` (the zone's cell centres, machining frame) within the
        reach of their nearest contact (1 for no points)."""
        if len(points) == 0:
            return 1.0
        if len(self.contacts) == 0:
            return 0.0
        gap, idx = cKDTree(self.contacts).query(np.asarray(points))
        return float(np.mean(gap <= self.reach[idx] + 1e-9))


class SurfaceSetup:
    """One surface in one machining frame with one cutter: the mesh kernels and the drop-cutter.
    ``rotation (3, 3)`` part -> machining frame."""

    def __init__(self, smesh: SurfaceMesh, grid_shape, tool, rotation=None, device="cpu"):
        self.rotation = np.eye(3) if rotation is None else np.asarray(rotation, float)
        self.tool = tool
        turned = smesh.mesh.transformed(self.rotation)
        self.floor = float(turned.vertices[:, 2].min()) - 1.0  # below the lowest point: a flat bottom resting there touches
        self.kern = solid_kernels(turned, device, self.floor)  # the solid, sheets down to the floor
        verts = turned.vertices
        self.top = float(verts[:, 2].max())
        self.drop = ToolDrop(tool, self.kern, self.floor, body_grow=STOCK_ALLOWANCE)  # shank, holder out of the stock
        self.smesh = smesh
        self.grid_shape = grid_shape

    def contact_cells(self, contacts):
        """Grid cell ``(k,)`` of each contact ``(k, 3)`` (machining frame; -1 for none),
        whether it is usable ``(k,)`` (not on the surface's free edge, and on a mesh's top), and
        the surface normal ``(k, 3)`` there (machining frame; NaN where unknown: take the cell's)."""
        ok = np.isfinite(contacts[:, 0])
        cell = np.full(len(contacts), -1, np.int64)
        usable = np.zeros(len(contacts), bool)
        normal = np.full((len(contacts), 3), np.nan)
        if ok.any():
            uv, usable[ok], n = self.smesh.locate(contacts[ok] @ self.rotation)
            nu, nv = self.grid_shape
            iu = np.clip((uv[:, 0] * nu).astype(np.int64), 0, nu - 1)
            iv = np.clip((uv[:, 1] * nv).astype(np.int64), 0, nv - 1)
            cell[ok] = iu * nv + iv
            if n is not None:
                normal[ok] = n @ self.rotation.T
        return cell, usable, normal

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

    def zone_passes(self, in_zone, points, normals, theta, scallop, sample=0.5, margin=0.0) -> ZonePasses:
        """Zigzag over the cells where ``in_zone (n_cells,) bool`` holds, whose sample ``points
        (n_cells, 3)`` (part frame; cells reach ``margin`` mm beyond them) bound it; planes at
        the axial azimuth ``theta`` rad (machining frame; theta and theta + pi are one
        direction). The stepover is :func:`~meshmill.pathing.scallop.stepover_exact` at the
        contacts where the cutter's normal is within ``SMOOTH`` of the surface's (the nearest
        node's, or the cell's sample normal ``normals (n_cells, 3)``; all contacts if none is):
        a tool rolling over an edge or a crease does not set the scallop of the faces beside it."""
        theta = float(wrap_axial(theta))
        cell_normals = normals @ self.rotation.T
        R, r = self.tool.radius, self.tool.corner_radius
        d = np.array([math.cos(theta), math.sin(theta)])
        across = np.array([-math.sin(theta), math.cos(theta)])
        across3 = np.array([across[0], across[1], 0.0])
        pts = (points[in_zone] @ self.rotation.T)[:, :2]
        s_lo, s_hi = (pts @ d).min() - R - sample - margin, (pts @ d).max() + R + sample + margin
        t_lo, t_hi = (pts @ across).min() - R - margin, (pts @ across).max() + R + margin
        n_s = int(math.ceil((s_hi - s_lo) / sample)) + 1
        s = np.linspace(s_lo, s_hi, n_s)
        probe = float(stepover(scallop, r))  # step while no contact is in the zone: the smallest stepover
        passes, spacings, touched, touched_spacing = [], [], [], []
        t, k = t_lo, 0
        while t <= t_hi:
            xy = s[:, None] * d + t * across
            tips, contacts = self.drop.with_contacts(xy)
            # a flat bottom resting on a flat of the surface machines a band centred on the axis,
            # wherever the drop-cutter reports its contact (often a vertex or an edge of the
            # flat): then the point under the axis, on the surface, stands for it
            flat = np.hypot(contacts[:, 0] - xy[:, 0], contacts[:, 1] - xy[:, 1]) <= R - r
            if flat.any():
                f = np.flatnonzero(flat)
                under = np.column_stack([xy[f], tips[f]])
                on = self.kern.mesh_distances(under, 1.0) <= ON_SURFACE
                contacts[f[on]] = under[on]
            cell, usable, surface_n = self.contact_cells(contacts)
            ref_n = np.where(np.isnan(surface_n), cell_normals[np.maximum(cell, 0)], surface_n)
            # a flat bottom on the free edge of a horizontal surface overhangs it and machines it
            # (within the scallop height over the flat's width)
            usable |= flat & (ref_n[:, 2] >= math.cos(scallop / max(R - r, scallop)))
            inside = (cell >= 0) & usable & in_zone[np.maximum(cell, 0)]
            if not inside.any():
                t += probe
                continue
            n_all = self.contact_normals(np.column_stack([xy, tips])[inside], contacts[inside])
            smooth = np.einsum("ij,ij->i", n_all, ref_n[inside]) >= math.cos(SMOOTH)
            n = n_all[smooth] if smooth.any() else n_all
            feed = np.cross(across3, n)  # tangent to the surface in the pass's vertical plane
            feed /= np.maximum(np.linalg.norm(feed, axis=1, keepdims=True), 1e-300)
            sod = stepover_exact(scallop, R, r, n, feed)
            # sod is measured on the surface square to the pass: sqrt(1 - (n . across)²) of it is horizontal
            spacing = float((sod * np.sqrt(np.maximum(1.0 - (n @ across3) ** 2, 0.0))).min())
            pieces = _runs(np.column_stack([xy, tips]), inside)
            if k % 2:
                pieces = [p[::-1] for p in pieces[::-1]]
            passes += pieces
            touched.append(contacts[inside])
            # how far each contact's machining reaches on the surface: half the plane spacing
            # there (square to the pass) and half the way to its neighbours along the pass
            square = np.sqrt(np.maximum(1.0 - (n_all @ across3) ** 2, 0.0025))
            touched_spacing.append(0.5 * spacing / square + 0.5 * _along_gaps(contacts, inside))
            spacings.append(spacing)
            t += spacing
            k += 1
        link = LINK_STEPOVERS * (max(spacings) if spacings else probe)
        return ZonePasses(self.linked(passes, link, sample), np.array(spacings),
                          np.concatenate(touched) if touched else np.empty((0, 3)),
                          np.concatenate(touched_spacing) if touched else np.empty(0))

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


def _along_gaps(points, mask):
    """For each ``mask``ed row of ``points (k, 3)``: the distance to its farther masked
    neighbour along the rows (the nearer one's at a run's ends; 0 for a lone row)."""
    idx = np.flatnonzero(mask)
    gap = np.linalg.norm(np.diff(points[idx], axis=0), axis=1)
    joined = np.diff(idx) == 1  # neighbours in the same run
    prev = np.concatenate([[0.0], np.where(joined, gap, 0.0)])
    nxt = np.concatenate([np.where(joined, gap, 0.0), [0.0]])
    return np.maximum(prev, nxt)


def _runs(cl, mask):
    """Maximal runs of consecutive rows of ``cl (k, 3)`` where ``mask (k,)`` holds."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [cl[a:b] for a, b in zip(edges[::2], edges[1::2])]
