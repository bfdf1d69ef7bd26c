"""Free-form surfaces for tool choice and zoning (seed 002): B-spline / Bezier / NURBS patches read
from TOML, sampled at the centres of a regular (u, v) grid of cells, and triangulated for the
3-axis kernels.

Patch file (TOML; lengths in mm)::

    name = "rubio"
    degree_u = 2
    degree_v = 2
    points = [[[x, y, z], ...], ...]   # points[i][j] = P_ij, i along u, j along v
    knots_u = [...]                    # optional: clamped, non-decreasing; default Bezier
    knots_v = [...]
    weights = [[...], ...]             # optional: NURBS weights, positive

``rubio`` and ``choi`` name the seed's two test surfaces (shipped in ``meshmill/data/surfaces``).
The surface's normal is oriented so that its mean points up (+Z, towards a 3-axis spindle).
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numba
import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from .. import memory
from ..errors import InputError
from .mesh import Mesh, mesh_from_arrays
from ..tomlfile import read_toml

DATA = os.path.join(os.path.dirname(os.path.dirname(__file__)), "data", "surfaces")
BUILTIN = ("rubio", "choi")
KEYS = {"name", "degree_u", "degree_v", "points", "knots_u", "knots_v", "weights"}

NODE_BYTES = 160  # one node of a patch's grid: points, normals, the triangles it spans


def _basis(knots, degree, count, t):
    """B-spline basis values and first derivatives ``(m, count), (m, count)`` at ``t (m,)``."""
    lo, hi = knots[degree], knots[count]
    t = np.clip(np.asarray(t, float), lo, hi)
    span = np.clip(np.searchsorted(knots, t, side="right") - 1, degree, count - 1)
    n = np.zeros((len(t), len(knots) - 1))
    n[np.arange(len(t)), span] = 1.0
    dn = np.zeros((len(t), count))
    for k in range(1, degree + 1):
        nk = np.zeros((len(t), len(knots) - 1 - k))
        for i in range(len(knots) - 1 - k):
            d1, d2 = knots[i + k] - knots[i], knots[i + k + 1] - knots[i + 1]
            if d1 > 0:
                nk[:, i] += (t - knots[i]) / d1 * n[:, i]
                if k == degree and i < count:
                    dn[:, i] += k / d1 * n[:, i]
            if d2 > 0:
                nk[:, i] += (knots[i + k + 1] - t) / d2 * n[:, i + 1]
                if k == degree and i < count:
                    dn[:, i] -= k / d2 * n[:, i + 1]
        n = nk
    return n[:, :count], dn


@dataclass(frozen=True)
class Patch:
    """A tensor-product NURBS patch: ``points (mu, mv, 3)`` mm, ``weights (mu, mv)``, clamped
    ``knots_u (mu + degree_u + 1,)`` and ``knots_v``."""

    name: str
    points: np.ndarray
    weights: np.ndarray
    degree_u: int
    degree_v: int
    knots_u: np.ndarray
    knots_v: np.ndarray

    @property
    def domain(self) -> np.ndarray:
        """``(2, 2)``: [[u0, u1], [v0, v1]]."""
        mu, mv = self.points.shape[:2]
        return np.array([[self.knots_u[self.degree_u], self.knots_u[mu]],
                         [self.knots_v[self.degree_v], self.knots_v[mv]]])

    def grid(self, us, vs):
        """Points, d/du and d/dv ``(a, b, 3)`` each at every (us[i], vs[j])."""
        mu, mv = self.points.shape[:2]
        nu, dnu = _basis(self.knots_u, self.degree_u, mu, us)
        nv, dnv = _basis(self.knots_v, self.degree_v, mv, vs)
        pw = self.points * self.weights[..., None]
        a = np.einsum("ai,ijc,bj->abc", nu, pw, nv)
        a_u = np.einsum("ai,ijc,bj->abc", dnu, pw, nv)
        a_v = np.einsum("ai,ijc,bj->abc", nu, pw, dnv)
        w = np.einsum("ai,ij,bj->ab", nu, self.weights, nv)[..., None]
        w_u = np.einsum("ai,ij,bj->ab", dnu, self.weights, nv)[..., None]
        w_v = np.einsum("ai,ij,bj->ab", nu, self.weights, dnv)[..., None]
        s = a / w
        return s, (a_u - s * w_u) / w, (a_v - s * w_v) / w

    def upward(self) -> float:
        """+1 if S_u x S_v points up on average, else -1 (the sign that orients normals up)."""
        us = np.linspace(*self.domain[0], 21)
        vs = np.linspace(*self.domain[1], 21)
        _, su, sv = self.grid(us, vs)
        return 1.0 if np.cross(su, sv)[..., 2].sum() >= 0 else -1.0


def bezier(points, name="bezier") -> Patch:
    """The Bezier patch of control points ``(mu, mv, 3)``."""
    return make_patch(name, points, len(points) - 1, len(points[0]) - 1)


def make_patch(name, points, degree_u, degree_v, knots_u=None, knots_v=None, weights=None) -> Patch:
    """Check and build a :class:`Patch` (raises :class:`InputError`)."""
    try:
        p = np.asarray(points, float)
    except (TypeError, ValueError):
        raise InputError(f"{name}: 'points' must be a grid of [x, y, z] triples") from None
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[0] < 2 or p.shape[1] < 2:
        raise InputError(f"{name}: 'points' must be a grid of at least 2 x 2 [x, y, z] triples, got shape {p.shape}")
    if not np.isfinite(p).all():
        raise InputError(f"{name}: control points contain NaN or infinity")
    mu, mv = p.shape[:2]
    for deg, m, key in ((degree_u, mu, "degree_u"), (degree_v, mv, "degree_v")):
        if not isinstance(deg, int) or isinstance(deg, bool) or not 1 <= deg < m:
            raise InputError(f"{name}: '{key}' must be an integer from 1 to {m - 1} (control points minus one), got {deg}")
    knots = []
    for kn, deg, m, key in ((knots_u, degree_u, mu, "knots_u"), (knots_v, degree_v, mv, "knots_v")):
        if kn is None:
            inner = max(m - deg - 1, 0)
            kn = [0.0] * (deg + 1) + [(i + 1) / (inner + 1) for i in range(inner)] + [1.0] * (deg + 1)
        try:
            kn = np.asarray(kn, float)
        except (TypeError, ValueError):
            raise InputError(f"{name}: '{key}' must be a list of numbers") from None
        if kn.shape != (m + deg + 1,):
            raise InputError(f"{name}: '{key}' needs {m + deg + 1} values (control points + degree + 1), got {kn.size}")
        if not np.isfinite(kn).all() or np.any(np.diff(kn) < 0) or kn[deg] >= kn[m]:
            raise InputError(f"{name}: '{key}' must be finite, non-decreasing and span a non-empty domain")
        knots.append(kn)
    w = np.ones((mu, mv)) if weights is None else np.asarray(weights, float)
    if w.shape != (mu, mv) or not np.isfinite(w).all() or (w <= 0).any():
        raise InputError(f"{name}: 'weights' must be {mu} x {mv} positive numbers")
    return Patch(name, p, w, degree_u, degree_v, knots[0], knots[1])


def load_patch(path_or_name: str) -> Patch:
    """A patch from a TOML file, or one of the built-in names ``rubio``/``choi``."""
    path = os.path.join(DATA, f"{path_or_name}.toml") if path_or_name in BUILTIN and not os.path.exists(path_or_name) \
        else path_or_name
    if not os.path.isfile(path):
        raise InputError(f"{path}: no such file (a surface is an STL mesh, a patch .toml, or one of {', '.join(BUILTIN)})")
    doc = read_toml(path, "a TOML patch file", "patch file")
    unknown = set(doc) - KEYS
    if unknown:
        raise InputError(f"{path}: unknown key(s) {', '.join(sorted(unknown))} (allowed: {', '.join(sorted(KEYS))})")
    for key in ("points", "degree_u", "degree_v"):
        if key not in doc:
            raise InputError(f"{path}: missing '{key}'")
    return make_patch(str(doc.get("name", os.path.basename(path))), doc["points"], doc["degree_u"], doc["degree_v"],
                      doc.get("knots_u"), doc.get("knots_v"), doc.get("weights"))


@dataclass
class Samples:
    """One sample per cell of an ``nu x nv`` grid, flattened row-major (i = iu * nv + iv):
    ``uv (n, 2)``, ``points (n, 3)`` mm, unit ``normals (n, 3)`` (up on average), ``slope (n,)``
    = arccos|n_z| rad, ``theta (n,)`` azimuth of the normal's XY projection, axial in
    [-pi/2, pi/2), ``area (n,)`` mm² of each cell; ``valid (n,)``: the cell holds surface (a
    mesh's grid may overhang it; invalid cells carry their nearest valid cell's values)."""

    grid_shape: tuple
    uv: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    slope: np.ndarray
    theta: np.ndarray
    area: np.ndarray
    valid: np.ndarray

    @property
    def features(self) -> np.ndarray:
        """``(n, 4)``: (u, v, s, theta), u and v scaled to [0, 1]."""
        return np.column_stack([self.uv, self.slope, self.theta])


def slope_and_azimuth(normals):
    """``slope (n,)`` = arccos|n_z| and the axial azimuth ``theta (n,)`` in [-pi/2, pi/2) of
    ``normals (n, 3)`` (0 where the normal is vertical)."""
    slope = np.arccos(np.clip(np.abs(normals[:, 2]), 0.0, 1.0))
    theta = np.mod(np.arctan2(normals[:, 1], normals[:, 0]) + 0.5 * np.pi, np.pi) - 0.5 * np.pi
    return slope, np.where(np.hypot(normals[:, 0], normals[:, 1]) > 1e-12, theta, 0.0)


def cell_samples(patch: Patch, nu: int = 80, nv: int = 80) -> Samples:
    """Samples at the centres of an ``nu x nv`` grid of equal (u, v) cells (seed 002 §2.8)."""
    if nu < 1 or nv < 1:
        raise InputError(f"the sampling grid must have at least 1 x 1 cells, got {nu} x {nv}")
    (u0, u1), (v0, v1) = patch.domain
    fu, fv = (np.arange(nu) + 0.5) / nu, (np.arange(nv) + 0.5) / nv
    s, su, sv = patch.grid(u0 + (u1 - u0) * fu, v0 + (v1 - v0) * fv)
    cross = np.cross(su, sv).reshape(-1, 3) * patch.upward()
    length = np.linalg.norm(cross, axis=1)
    if (length < 1e-12).any():
        raise InputError(f"{patch.name}: the surface is degenerate (no normal) somewhere on the sampling grid")
    normals = cross / length[:, None]
    slope, theta = slope_and_azimuth(normals)
    uu, vv = np.meshgrid(fu, fv, indexing="ij")
    area = length * (u1 - u0) * (v1 - v0) / (nu * nv)
    return Samples((nu, nv), np.column_stack([uu.ravel(), vv.ravel()]), s.reshape(-1, 3), normals, slope, theta, area,
                   np.ones(nu * nv, bool))


EDGE_TOL = 1e-5  # mm: a contact this close to a free edge is on it (the tool rolls over the edge)
TOP_TOL = 0.01  # mm: a mesh contact this far below the top at its XY is on a wall or underside


@dataclass
class SurfaceMesh:
    """A surface's triangles: the :class:`Mesh`, and per node ``uv (k, 2)`` in [0, 1]²,
    ``points (k, 3)`` mm and unit ``normals (k, 3)`` (up on average). A mesh (``xy_box (2, 2)``
    given) is located by XY in that box and its top seen from +Z; a patch by its nearest node."""

    mesh: Mesh
    uv: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    xy_box: np.ndarray | None = None

    def __post_init__(self):
        self.chord_error, self.step = 0.0, None  # a patch's triangulation: deviation from it, node spacing (mm)
        self._tree = cKDTree(self.points)
        f = self.mesh.faces
        e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1).astype(np.int64)
        keys, counts = np.unique(e[:, 0] * len(self.mesh.vertices) + e[:, 1], return_counts=True)
        free = keys[counts == 1]
        v = self.mesh.vertices
        self._free = (v[free // len(v)], v[free % len(v)])
        self._free_tree = cKDTree(0.5 * (self._free[0] + self._free[1])) if len(free) else None
        self._top = None

    def on_free_edge(self, points) -> np.ndarray:
        """``(k,)``: each of ``points (k, 3)`` lies on a free (boundary) edge, within ``EDGE_TOL``
        (exact distances to the nearest edges)."""
        if self._free_tree is None or len(points) == 0:
            return np.zeros(len(points), bool)
        a, b = self._free
        k = min(16, len(a))
        idx = self._free_tree.query(points, k=k)[1].reshape(len(points), k)
        pa, ab = points[:, None, :] - a[idx], b[idx] - a[idx]
        t = np.clip(np.einsum("ijk,ijk->ij", pa, ab) / np.maximum(np.einsum("ijk,ijk->ij", ab, ab), 1e-300), 0, 1)
        gap = np.linalg.norm(pa - t[..., None] * ab, axis=2).min(axis=1)
        return gap <= EDGE_TOL

    def locate(self, points):
        """For surface points ``(k, 3)`` (part frame): ``uv (k, 2)``, ``usable (k,)`` (not on a
        free edge, and for a mesh on its top seen from +Z) and the surface normal ``(k, 3)`` at
        the nearest node (patches) or None (meshes: take the cell's)."""
        usable = ~self.on_free_edge(points)
        if self.xy_box is None:
            node = self._tree.query(points)[1]
            return self.uv[node], usable, self.normals[node]
        lo, hi = self.xy_box
        uv = np.clip((points[:, :2] - lo) / np.maximum(hi - lo, 1e-12), 0.0, 1.0)
        return uv, usable & (points[:, 2] >= self.top_height(points[:, :2]) - TOP_TOL), None

    def top_height(self, xy) -> np.ndarray:
        """Height ``(k,)`` of the mesh's top over ``xy (k, 2)`` (a 1 µm ball dropped on it)."""
        from ..kernels.bvh import build_bvh
        from ..kernels.backend import MeshKernels

        if self._top is None:
            self._top = MeshKernels(build_bvh(self.mesh.vertices, self.mesh.faces), "cpu")
        floor = float(self.mesh.vertices[:, 2].min()) - 1.0
        return self._top.drop_cutter(np.ascontiguousarray(xy, float), 1e-3, 1e-3, floor)[0]


def patch_mesh(patch: Patch, step: float = 0.5, chord_tol: float | None = None) -> SurfaceMesh:
    """Triangulate ``patch`` with node spacing about ``step`` mm along both parameter directions
    (two triangles per grid quad); with ``chord_tol``, the step shrinks until the triangles
    leave the patch by at most that much at the quads' centres and edge midpoints. The mesh's
    ``chord_error`` (mm, measured there) and ``step`` are kept on it."""
    if not (math.isfinite(step) and step > 0):
        raise InputError(f"the mesh step must be a positive number, got {step}")
    (u0, u1), (v0, v1) = patch.domain
    probe, _, _ = patch.grid(np.linspace(u0, u1, 33), np.linspace(v0, v1, 33))
    len_u = np.linalg.norm(np.diff(probe, axis=0), axis=2).sum(axis=0).max()
    len_v = np.linalg.norm(np.diff(probe, axis=1), axis=2).sum(axis=1).max()
    for _ in range(8):
        nu, nv = int(math.ceil(len_u / step)) + 1, int(math.ceil(len_v / step)) + 1
        memory.check(NODE_BYTES * float(nu) * nv, f"a mesh step of {step:g} mm: {nu * nv:,} patch nodes",
                     "use a larger mesh_step", ("mesh_step",))
        fu, fv = np.linspace(0.0, 1.0, nu), np.linspace(0.0, 1.0, nv)
        su_, sv_ = u0 + (u1 - u0) * fu, v0 + (v1 - v0) * fv
        s, su, sv = patch.grid(su_, sv_)
        mu_, mv_ = 0.5 * (su_[1:] + su_[:-1]), 0.5 * (sv_[1:] + sv_[:-1])
        centre = patch.grid(mu_, mv_)[0]
        chord = max(np.linalg.norm(centre - 0.5 * (s[:-1, :-1] + s[1:, 1:]), axis=2).max(),
                    np.linalg.norm(patch.grid(mu_, sv_)[0] - 0.5 * (s[:-1] + s[1:]), axis=2).max(),
                    np.linalg.norm(patch.grid(su_, mv_)[0] - 0.5 * (s[:, :-1] + s[:, 1:]), axis=2).max())
        if chord_tol is None or chord <= chord_tol:
            break
        step *= 0.9 * math.sqrt(chord_tol / chord)  # the chord error grows with the square of the step
    else:
        raise InputError(f"{patch.name}: could not triangulate within {chord_tol:g} mm of the patch")
    cross = np.cross(su, sv) * patch.upward()
    norm = np.linalg.norm(cross, axis=2, keepdims=True)
    normals = np.divide(cross, norm, out=np.zeros_like(cross), where=norm > 1e-12).reshape(-1, 3)
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    uu, vv = np.meshgrid(fu, fv, indexing="ij")
    points = s.reshape(-1, 3)
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    out = SurfaceMesh(mesh_from_arrays(points, faces, patch.name), uv, points, normals)
    out.chord_error, out.step = float(chord), float(step)
    return out


@numba.njit(cache=True)
def _top_hits(vertices, faces, x0, y0, dx, dy, nu, nv):
    """Highest triangle over each cell centre of an ``nu x nv`` XY grid: ``z (nu*nv,)`` (-inf:
    none) and the face index ``(nu*nv,)`` (-1)."""
    z = np.full(nu * nv, -np.inf)
    face = np.full(nu * nv, -1, np.int64)
    for f in range(faces.shape[0]):
        a, b, c = vertices[faces[f, 0]], vertices[faces[f, 1]], vertices[faces[f, 2]]
        det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
        if abs(det) < 1e-15:
            continue  # vertical facet: seen edge-on from above
        lo_x, hi_x = min(a[0], b[0], c[0]), max(a[0], b[0], c[0])
        lo_y, hi_y = min(a[1], b[1], c[1]), max(a[1], b[1], c[1])
        i0, i1 = max(0, int(np.ceil((lo_x - x0) / dx - 0.5))), min(nu - 1, int(np.floor((hi_x - x0) / dx - 0.5)))
        j0, j1 = max(0, int(np.ceil((lo_y - y0) / dy - 0.5))), min(nv - 1, int(np.floor((hi_y - y0) / dy - 0.5)))
        for i in range(i0, i1 + 1):
            px = x0 + (i + 0.5) * dx
            for j in range(j0, j1 + 1):
                py = y0 + (j + 0.5) * dy
                l1 = ((px - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (py - a[1])) / det
                l2 = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / det
                if l1 < -1e-12 or l2 < -1e-12 or l1 + l2 > 1.0 + 1e-12:
                    continue
                h = a[2] + l1 * (b[2] - a[2]) + l2 * (c[2] - a[2])
                k = i * nv + j
                if h > z[k]:
                    z[k] = h
                    face[k] = f
    return z, face


def mesh_samples(mesh: Mesh, nu: int = 80, nv: int = 80) -> Samples:
    """Samples of a mesh's top surface (seen from +Z) at the centres of an ``nu x nv`` grid over
    its XY box: u along X, v along Y; the normal is the facet's, turned up."""
    lo, hi = mesh.bounds
    dx, dy = (hi[0] - lo[0]) / nu, (hi[1] - lo[1]) / nv
    if dx <= 0 or dy <= 0:
        raise InputError("the surface has no extent in X or Y: nothing to machine from above")
    z, face = _top_hits(mesh.vertices, mesh.faces.astype(np.int64), lo[0], lo[1], dx, dy, nu, nv)
    valid = face >= 0
    if valid.sum() < 3:
        raise InputError("fewer than 3 cells of the sampling grid see the surface from above: use a finer grid", "grid")
    iu, iv = np.divmod(np.arange(nu * nv), nv)
    uv = np.column_stack([(iu + 0.5) / nu, (iv + 0.5) / nv])
    normals = mesh.face_normals[np.maximum(face, 0)]
    normals *= np.where(normals[:, 2] < 0, -1.0, 1.0)[:, None]
    points = np.column_stack([lo[0] + uv[:, 0] * (hi[0] - lo[0]), lo[1] + uv[:, 1] * (hi[1] - lo[1]), z])
    area = dx * dy / np.maximum(normals[:, 2], 1e-3)
    # cells off the surface take their nearest valid cell's values (the clustering needs a full grid)
    nearest = ndimage.distance_transform_edt(~valid.reshape(nu, nv), return_distances=False, return_indices=True)
    src = (nearest[0] * nv + nearest[1]).ravel()
    points, normals, area = points[src], normals[src], np.where(valid, area, 0.0)
    slope, theta = slope_and_azimuth(normals)
    return Samples((nu, nv), uv, points, normals, slope, theta, area, valid)


def mesh_surface(mesh: Mesh) -> SurfaceMesh:
    """A mesh as a :class:`SurfaceMesh`: uv = position in its XY box, area-weighted vertex
    normals turned up."""
    lo, hi = mesh.bounds
    v, f = mesh.vertices, mesh.faces
    uv = (v[:, :2] - lo[:2]) / np.maximum(hi[:2] - lo[:2], 1e-12)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    cross *= np.where(cross[:, 2] < 0, -1.0, 1.0)[:, None]
    normals = np.zeros_like(v)
    for k in range(3):
        np.add.at(normals, f[:, k], cross)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    return SurfaceMesh(mesh, uv, v, normals, np.array([lo[:2], hi[:2]]))
