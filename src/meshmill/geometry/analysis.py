"""Mesh analysis shared by operations: triangle and vertex parameters, visibility and
accessibility along a direction, and an accessibility map over a hemisphere of directions.

Seed 001's definitions, with its formula errors corrected (see its notes §8): angles from
``atan2(|e1 x e2|, e1 . e2)`` (its arcsin cannot return an obtuse angle), areas from the cross
product (Heron is ill-conditioned on slivers), vertex normals normalised after weighting.

- A vertex is visible along V when its normal has ``n . V > 0``; a triangle when its facet normal
  does (the seed asks all three vertex normals, which marks facets beside a crease invisible).
- A vertex is accessible along V when it is visible and the ray from it along V meets no other
  part of the mesh; a triangle when it is visible and the rays from its three vertices and its
  centroid are all free. Rays start ``RAY_START`` mm along V so that the triangles around the
  origin do not count; they are exact (Moller-Trumbore through the BVH), not sampled.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..kernels.backend import bind
from ..kernels.bvh import build_bvh
from .mesh import Mesh

RAY_START = 1e-6  # mm, relative to the part's size: see ray_start()
WEIGHTINGS = ("area", "angle", "uniform")


def ray_start(mesh: Mesh) -> float:
    """How far along V an accessibility ray starts, mm: RAY_START times the part's size."""
    return RAY_START * max(1.0, float(np.linalg.norm(np.ptp(mesh.vertices, axis=0))))


def triangle_parameters(mesh: Mesh) -> dict:
    """Per triangle: ``area (m,)`` mm², ``angles (m, 3)`` degrees at vertices 0, 1, 2,
    ``centroid (m, 3)``, ``normal (m, 3)`` unit, ``neighbours (m, 3)`` the triangle across edges
    0-1, 1-2 and 2-0 (-1 on a boundary or a non-manifold edge)."""
    tri = mesh.vertices[mesh.faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    angles = np.empty((len(tri), 3))
    for k in range(3):
        e1 = tri[:, (k + 1) % 3] - tri[:, k]
        e2 = tri[:, (k + 2) % 3] - tri[:, k]
        angles[:, k] = np.degrees(np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=1), np.einsum("ij,ij->i", e1, e2)))
    return {"area": 0.5 * double_area, "angles": angles, "centroid": tri.mean(axis=1),
            "normal": cross / double_area[:, None], "neighbours": edge_neighbours(mesh.faces, len(mesh.vertices))}


def edge_neighbours(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """``(m, 3)``: the face across edges 0-1, 1-2, 2-0 of each face; -1 where no single one is."""
    f = faces.astype(np.int64)
    e = f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.minimum(e[:, 0], e[:, 1]) * n_vertices + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(key, kind="stable")
    ks = key[order]
    out = np.full(len(key), -1, np.int64)
    pair = np.nonzero(ks[1:] == ks[:-1])[0]
    single = np.ones(len(pair), bool)
    if len(pair) > 1:  # an edge shared by three or more faces has no single neighbour
        single[1:] &= pair[1:] != pair[:-1] + 1
        single[:-1] &= pair[:-1] + 1 != pair[1:]
    a, b = order[pair[single]], order[pair[single] + 1]
    out[a] = b // 3
    out[b] = a // 3
    return out.reshape(-1, 3)


def vertex_normals(mesh: Mesh, weighting: str = "area") -> np.ndarray:
    """Unit normal ``(n, 3)`` of every vertex: the incident facet normals weighted by facet area,
    by the facet's angle at the vertex, or uniformly, then normalised."""
    if weighting not in WEIGHTINGS:
        raise InputError(f"weighting must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}", "weighting")
    t = triangle_parameters(mesh)
    w = {"area": np.repeat(t["area"][:, None], 3, axis=1), "angle": np.radians(t["angles"]),
         "uniform": np.ones((len(mesh.faces), 3))}[weighting]
    n = np.zeros((len(mesh.vertices), 3))
    for k in range(3):
        np.add.at(n, mesh.faces[:, k], w[:, k, None] * t["normal"])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def unit_direction(direction) -> np.ndarray:
    d = np.asarray(direction, np.float64).reshape(3)
    norm = float(np.linalg.norm(d))
    if not (np.isfinite(d).all() and norm > 1e-12):
        raise InputError(f"the direction must be a non-zero vector of three finite numbers, got {list(direction)}")
    return d / norm


def visibility(mesh: Mesh, direction, weighting="area", bvh=None, device="cpu") -> dict:
    """Visibility and accessibility along ``direction (3,)``: ``visible_vertices (n,)``,
    ``accessible_vertices (n,)``, ``visible_triangles (m,)``, ``accessible_triangles (m,)`` bool.
    ``bvh``: the mesh's BVH or its :class:`~meshmill.kernels.backend.MeshKernels` (rays cast on
    ``device``)."""
    d = unit_direction(direction)
    kern = bind(bvh or build_bvh(mesh.vertices, mesh.faces), device)
    t = triangle_parameters(mesh)
    vis_v = vertex_normals(mesh, weighting) @ d > 0.0
    vis_t = t["normal"] @ d > 0.0
    start = ray_start(mesh)
    # only rays that can matter: vertices of visible triangles, and visible vertices
    need_v = vis_v.copy()
    need_v[mesh.faces[vis_t].ravel()] = True
    free_v = np.zeros(len(mesh.vertices), bool)
    idx = np.nonzero(need_v)[0]
    free_v[idx] = ~kern.rays_blocked(mesh.vertices[idx], d, start)
    free_c = np.zeros(len(mesh.faces), bool)
    tidx = np.nonzero(vis_t)[0]
    free_c[tidx] = ~kern.rays_blocked(t["centroid"][tidx], d, start)
    acc_t = vis_t & free_c & free_v[mesh.faces].all(axis=1)
    return {"visible_vertices": vis_v, "accessible_vertices": vis_v & free_v, "visible_triangles": vis_t,
            "accessible_triangles": acc_t}


def hemisphere(theta_step: float, delta_step: float) -> np.ndarray:
    """Directions ``(k, 3)`` on the upper hemisphere: theta from the pole (0) to the equator (90)
    by ``theta_step`` degrees, delta around by ``delta_step`` (one direction at the pole)."""
    for name, v in (("theta_step", theta_step), ("delta_step", delta_step)):
        if not (math.isfinite(v) and 0 < v <= 90):
            raise InputError(f"{name} must be in (0, 90] degrees, got {v}", name)
    dirs = [(0.0, 0.0, 1.0)]
    for th in np.arange(theta_step, 90.0 + 1e-9, theta_step):
        for de in np.arange(0.0, 360.0 - 1e-9, delta_step):
            t, d = math.radians(th), math.radians(de)
            dirs.append((math.sin(t) * math.cos(d), math.sin(t) * math.sin(d), math.cos(t)))
    return np.array(dirs)


def accessibility_map(mesh: Mesh, directions: np.ndarray, bvh=None, device="cpu") -> tuple[np.ndarray, np.ndarray]:
    """For each of ``directions (k, 3)``: the area share of the mesh accessible along it ``(k,)``,
    and per triangle how many of the directions reach it ``(m,) int`` (rays cast on ``device``)."""
    kern = bind(bvh or build_bvh(mesh.vertices, mesh.faces), device)
    area = triangle_parameters(mesh)["area"]
    share = np.empty(len(directions))
    reached = np.zeros(len(mesh.faces), np.int64)
    for i, d in enumerate(directions):
        acc = visibility(mesh, d, bvh=kern)["accessible_triangles"]
        share[i] = float(area[acc].sum() / area.sum())
        reached += acc
    return share, reached


def sample_surface(mesh: Mesh, spacing: float, max_samples: int = 2_000_000, faces=None):
    """Points spread over the facets ``faces`` (all by default) about one per ``spacing``² mm²
    (fewer when that would pass ``max_samples``; at least one a facet), at fixed pseudo-random
    places: ``(points (s, 3), weight (s,) mm² each stands for, face (s,))``."""
    v = mesh.vertices[mesh.faces]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    faces = np.nonzero(area > 0)[0] if faces is None else np.asarray(faces)[area[faces] > 0]
    if not len(faces):
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)
    spacing = max(spacing, math.sqrt(area[faces].sum() / max_samples))
    count = np.maximum(1, np.ceil(area[faces] / spacing ** 2)).astype(np.int64)
    face = np.repeat(faces, count)
    rng = np.random.default_rng(0)
    u, w = rng.random(len(face)), rng.random(len(face))
    over = u + w > 1.0
    u[over], w[over] = 1.0 - u[over], 1.0 - w[over]
    p = v[face, 0] + u[:, None] * (v[face, 1] - v[face, 0]) + w[:, None] * (v[face, 2] - v[face, 0])
    return p, np.repeat(area[faces] / count, count), face
