"""Closed analytic solids for tests, benchmarks and the demo part: solids of revolution and boxes.

Vertices fall exactly on the profile's heights, so flat facets and rings lie exactly on the Z
planes a test chooses.
"""
from __future__ import annotations

import math

import numpy as np

from .mesh import Mesh, mesh_from_arrays


def revolve(r, z, segments: int = 64, name: str = "revolve") -> Mesh:
    """Solid of revolution about the Z axis.

    ``r, z (K,)``: the profile in the half plane r >= 0, from the axis at the bottom (r[0] = 0) up
    the outside to the axis at the top (r[-1] = 0); ``segments`` around. Returns a closed
    :class:`Mesh` with 2·segments·(K - 2) triangles.
    """
    r = np.asarray(r, np.float64)
    z = np.asarray(z, np.float64)
    if r[0] != 0 or r[-1] != 0 or (r[1:-1] <= 0).any():
        raise ValueError("profile must start and end on the axis and stay off it in between")
    theta = 2.0 * math.pi * np.arange(segments) / segments
    ring = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    k = len(r)
    verts = [np.array([[0.0, 0.0, z[0]]])]
    for i in range(1, k - 1):
        verts.append(np.column_stack([r[i] * ring, np.full(segments, z[i])]))
    verts.append(np.array([[0.0, 0.0, z[-1]]]))
    V = np.concatenate(verts)
    ring_start = lambda i: 1 + (i - 1) * segments  # noqa: E731
    j = np.arange(segments)
    jn = (j + 1) % segments
    faces = [np.column_stack([np.zeros(segments, int), ring_start(1) + jn, ring_start(1) + j])]
    for i in range(1, k - 2):
        a, b = ring_start(i), ring_start(i + 1)
        faces.append(np.column_stack([a + j, a + jn, b + jn]))
        faces.append(np.column_stack([a + j, b + jn, b + j]))
    top = len(V) - 1
    a = ring_start(k - 2)
    faces.append(np.column_stack([a + j, a + jn, np.full(segments, top)]))
    return mesh_from_arrays(V, np.concatenate(faces), name)


def sphere(radius: float, rings: int = 48, segments: int = 96, center=(0.0, 0.0, 0.0)) -> Mesh:
    """UV sphere: ``rings`` profile steps from pole to pole."""
    phi = np.linspace(-0.5 * math.pi, 0.5 * math.pi, rings + 1)
    m = revolve(radius * np.cos(phi) * (np.abs(np.cos(phi)) > 1e-12), radius * np.sin(phi), segments, "sphere")
    m.vertices = m.vertices + np.asarray(center, np.float64)
    return m


def box(lo, hi) -> Mesh:
    """Axis-aligned box between corners ``lo`` and ``hi`` (mm), 12 triangles."""
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    c = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], np.float64)
    V = lo + c * (hi - lo)
    F = [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
         [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]
    return mesh_from_arrays(V, np.array(F), "box")


def post_with_fillet(post_radius=10.0, fillet=5.0, height=30.0, plate_radius=40.0, plate_thickness=5.0,
                     arc_steps=24, segments=96) -> Mesh:
    """A round post standing on a round plate with a concave fillet of radius ``fillet`` between
    them; the plate top is at z = 0."""
    a = np.linspace(0.0, 0.5 * math.pi, arc_steps + 1)
    fr = post_radius + fillet - fillet * np.sin(a)
    fz = fillet - fillet * np.cos(a)
    r = np.r_[0.0, plate_radius, plate_radius, fr, post_radius, 0.0]
    z = np.r_[-plate_thickness, -plate_thickness, 0.0, fz, height, height]
    return revolve(r, z, segments, "post_with_fillet")


def overhang_column(radius=10.0, height=30.0, cap_radius=14.0, cap_height=5.0, segments=64) -> Mesh:
    """A column whose wall lies under a wider cap (an overhang): a vertical tool there collides."""
    r = [0.0, radius, radius, cap_radius, cap_radius, 0.0]
    z = [0.0, 0.0, height, height, height + cap_height, height + cap_height]
    return revolve(r, z, segments, "overhang_column")


def vase(height=63.11, radius=20.0, steps=70, segments=64) -> Mesh:
    """A vase-like solid of revolution about 40 x 40 x 63 mm with about 9000 triangles: a flat foot,
    a concave waist, a bulge whose underside faces down (tilting needed) and a rim, like model 1 of
    seed 004."""
    t = np.linspace(0.0, 1.0, steps)
    prof = radius * (0.62 + 0.22 * np.sin(2.0 * math.pi * (1.3 * t - 0.15)) + 0.12 * np.cos(5.0 * math.pi * t))
    prof = np.clip(prof * radius / prof.max(), 5.0, radius)
    r = np.r_[0.0, prof, 0.0]
    zz = np.r_[0.0, t * height, height]
    return revolve(r, zz, segments, "vase")
