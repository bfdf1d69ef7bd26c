"""Loading, checking and cleaning triangle meshes.

A :class:`Mesh` is an indexed triangle mesh in mm with welded vertices and faces wound so that
their normals point out of the material. STL (ASCII and binary, also binary files whose header
starts with "solid"), OBJ and PLY are read with trimesh.
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field

import numba
import numpy as np

from ..errors import InputError
from ..tolerances import DEGENERATE_AREA, WELD_DIGITS

SUPPORTED = (".stl", ".obj", ".ply")


@dataclass
class Mesh:
    """``vertices (n, 3) float64`` mm, ``faces (m, 3) int32`` wound outward."""

    vertices: np.ndarray
    faces: np.ndarray
    closed: bool = True
    dropped_degenerate: int = 0
    flipped: bool = False
    warnings: list = field(default_factory=list)

    @property
    def face_normals(self) -> np.ndarray:
        """Unit outward normal ``(m, 3)`` of every face."""
        tri = self.vertices[self.faces]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    @property
    def bounds(self) -> np.ndarray:
        """``(2, 3)``: min and max corner, mm."""
        return np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def summary(self) -> dict:
        return {
            "vertices": int(len(self.vertices)),
            "triangles": int(len(self.faces)),
            "closed": bool(self.closed),
            "dropped_degenerate": int(self.dropped_degenerate),
            "flipped": bool(self.flipped),
            "bounds": self.bounds.round(6).tolist(),
        }


def edge_face_counts(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """How many faces share each undirected edge: ``(e,)`` counts over the unique edges."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1).astype(np.int64)
    _, counts = np.unique(e[:, 0] * n_vertices + e[:, 1], return_counts=True)
    return counts


def mesh_from_arrays(vertices, faces, name="mesh") -> Mesh:
    """Check and clean raw arrays into a :class:`Mesh` (raises :class:`InputError`)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0 or len(v) == 0:
        raise InputError(f"{name}: no triangles")
    if not np.isfinite(v).all():
        raise InputError(f"{name}: coordinates contain NaN or infinity")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{name}: face indices out of range")
    # weld identical vertices so that neighbouring faces share edges
    key = np.round(v, WELD_DIGITS)
    uniq, inverse = np.unique(key, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    first = np.full(len(uniq), -1, np.int64)
    first[inverse[::-1]] = np.arange(len(v))[::-1]
    v = v[first]
    f = inverse[f]
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    good = (area > DEGENERATE_AREA) & (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    dropped = int((~good).sum())
    f = f[good]
    if len(f) == 0:
        raise InputError(f"{name}: every triangle is degenerate")
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    v = v[used]
    f = remap[f]
    mesh = Mesh(vertices=v, faces=f.astype(np.int32), dropped_degenerate=dropped)
    if dropped:
        mesh.warnings.append(f"{name}: dropped {dropped} degenerate triangle(s)")
    counts = edge_face_counts(mesh.faces, len(v))
    mesh.closed = bool((counts == 2).all())
    _orient_outward(mesh, name)
    if not mesh.closed:
        mesh.warnings.append(f"{name}: the mesh is open (not watertight); machining it as a surface")
    return mesh


@numba.njit(cache=True)
def _winding_parity(n_faces, pair_a, pair_b, pair_same):
    """Flip flags (n_faces,) that make neighbouring faces traverse their shared edge in opposite
    directions, and a component label per face (breadth-first over manifold edges)."""
    adj_start = np.zeros(n_faces + 1, np.int64)
    for k in range(pair_a.shape[0]):
        adj_start[pair_a[k] + 1] += 1
        adj_start[pair_b[k] + 1] += 1
    for i in range(n_faces):
        adj_start[i + 1] += adj_start[i]
    fill = adj_start[:-1].copy()
    adj = np.empty(adj_start[-1], np.int64)
    same = np.empty(adj_start[-1], np.bool_)
    for k in range(pair_a.shape[0]):
        a, b = pair_a[k], pair_b[k]
        adj[fill[a]] = b
        same[fill[a]] = pair_same[k]
        fill[a] += 1
        adj[fill[b]] = a
        same[fill[b]] = pair_same[k]
        fill[b] += 1
    flip = np.zeros(n_faces, np.bool_)
    comp = np.full(n_faces, -1, np.int64)
    queue = np.empty(n_faces, np.int64)
    ncomp = 0
    for seed in range(n_faces):
        if comp[seed] >= 0:
            continue
        comp[seed] = ncomp
        head, tail = 0, 1
        queue[0] = seed
        while head < tail:
            f = queue[head]
            head += 1
            for j in range(adj_start[f], adj_start[f + 1]):
                g = adj[j]
                if comp[g] < 0:
                    comp[g] = ncomp
                    flip[g] = flip[f] ^ same[j]
                    queue[tail] = g
                    tail += 1
        ncomp += 1
    return flip, comp


def _orient_outward(mesh: Mesh, name: str) -> None:
    """Make the winding consistent across shared edges, then point every connected piece's normals
    out of the material: by its signed volume when it is closed or nearly so (its projected area
    cancels out), else (an open surface) so that its normals face up on the whole."""
    F = mesh.faces.astype(np.int64)
    nv = len(mesh.vertices)
    directed = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.minimum(directed[:, 0], directed[:, 1]) * nv + np.maximum(directed[:, 0], directed[:, 1])
    order = np.argsort(key, kind="stable")
    ks = key[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    run = np.diff(np.r_[np.nonzero(first)[0], len(ks)])
    two = np.nonzero(first)[0][run == 2]  # manifold edges: exactly two faces
    ea, eb = order[two], order[two + 1]
    pair_same = directed[ea, 0] == directed[eb, 0]
    flip, comp = _winding_parity(len(F), ea // 3, eb // 3, pair_same)
    tri = mesh.vertices[F]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    sign = np.where(flip, -1.0, 1.0)
    ncomp = comp.max() + 1
    vol = np.bincount(comp, sign * np.einsum("ij,ij->i", tri[:, 0], cross), ncomp)
    up = np.bincount(comp, sign * cross[:, 2], ncomp)
    size = np.bincount(comp, np.linalg.norm(cross, axis=1), ncomp)
    closedish = np.abs(up) <= 1e-6 * size
    comp_flip = np.where(closedish, vol < 0.0, up < 0.0)
    flip ^= comp_flip[comp]
    if flip.any():
        F[flip] = F[flip][:, ::-1]
        mesh.faces = F.astype(np.int32)
        mesh.flipped = True
        mesh.warnings.append(f"{name}: {int(flip.sum())} face(s) were wound inward or against their "
                             "neighbours; flipped them")


def load_mesh(path) -> Mesh:
    """Read STL/OBJ/PLY ``path`` into a checked :class:`Mesh` (raises :class:`InputError`)."""
    path = os.fspath(path)
    name = os.path.basename(path)
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a folder, not a mesh file")
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED:
        raise InputError(f"{path}: unsupported mesh format '{ext}' (use {', '.join(SUPPORTED)})")
    if os.path.getsize(path) == 0:
        raise InputError(f"{path}: empty file, no triangles")
    import trimesh

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise InputError(f"{path}: not a readable {ext[1:].upper()} mesh ({exc.__class__.__name__})") from None
    faces = getattr(loaded, "faces", None)
    if faces is None or len(faces) == 0:
        raise InputError(f"{path}: not a mesh or no triangles")
    return mesh_from_arrays(loaded.vertices, faces, name)
