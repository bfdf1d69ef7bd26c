"""A watertight triangle mesh of a triple-dexel model (the machined part).

Marching cubes (scikit-image) over the lattice nodes, which all lie on Z lines: a node is inside
when its Z line holds material there, and the field is the distance along Z to the nearest dexel
end (clamped to one cell), so surface points on Z edges fall exactly on the Z dexels' ends. A
surface point on an X or Y edge is then moved to the end of the X or Y dexel along that edge when
there is exactly one, so the mesh passes through the ends of all three directions. The lattice
is padded with empty nodes, so the surface is closed. Large lattices are sampled every ``stride``
nodes to keep the field under ``MAX_NODES``.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .dexel import DexelModel

MAX_NODES = 40_000_000


@numba.njit(cache=True)
def _z_field(start, iv, lo_z, step, nx, ny, nz, stride, out):
    """Field at the sampled nodes (+inside); out shape (nx//stride.., ...) padded by one."""
    cap = stride * step
    for a in range(out.shape[0] - 2):
        i = a * stride
        for b in range(out.shape[1] - 2):
            j = b * stride
            line = i * ny + j
            s0 = start[line]
            s1 = start[line + 1]
            q = s0
            for c in range(out.shape[2] - 2):
                z = lo_z + (c * stride + 0.5) * step
                while q < s1 and iv[q, 1] < z:
                    q += 1
                inside = q < s1 and iv[q, 0] <= z
                d = cap
                for k in range(max(s0, q - 1), min(s1, q + 2)):
                    d = min(d, abs(z - iv[k, 0]), abs(z - iv[k, 1]))
                out[a + 1, b + 1, c + 1] = d if inside else -max(d, 1e-6 * step)


@numba.njit(cache=True)
def _snap(verts, lo, step, stride, n, start0, iv0, start1, iv1):
    """Move vertices on X or Y edges to the single X or Y dexel end along their edge."""
    h = stride * step
    for k in range(verts.shape[0]):
        f0 = (verts[k, 0] - lo[0]) / h - 0.5 / stride
        f1 = (verts[k, 1] - lo[1]) / h - 0.5 / stride
        f2 = (verts[k, 2] - lo[2]) / h - 0.5 / stride
        r0 = abs(f0 - round(f0)) < 1e-6
        r1 = abs(f1 - round(f1)) < 1e-6
        r2 = abs(f2 - round(f2)) < 1e-6
        if r1 and r2 and not r0:  # on an X edge: X line through (y, z)
            a = 0
            line = int(round(f1)) * stride * n[2] + int(round(f2)) * stride
            start = start0
            iv = iv0
            e0 = lo[0] + (math.floor(f0) * stride + 0.5) * step
        elif r0 and r2 and not r1:  # on a Y edge: Y line through (z, x)
            a = 1
            line = int(round(f2)) * stride * n[0] + int(round(f0)) * stride
            start = start1
            iv = iv1
            e0 = lo[1] + (math.floor(f1) * stride + 0.5) * step
        else:
            continue
        e1 = e0 + h
        found = 0
        w = 0.0
        for q in range(start[line], start[line + 1]):
            for e in range(2):
                if e0 < iv[q, e] < e1:
                    found += 1
                    w = iv[q, e]
        if found == 1:
            verts[k, a] = w


def machined_mesh(model: DexelModel) -> tuple[np.ndarray, np.ndarray, int]:
    """``(vertices (n, 3), faces (m, 3), stride)`` of the model's solid, wound outward; empty
    arrays when the model holds no material."""
    from skimage.measure import marching_cubes

    n = model.n.astype(np.int64)
    stride = max(1, math.ceil((float(np.prod(n)) / MAX_NODES) ** (1 / 3)))
    dims = (n + stride - 1) // stride
    field = np.full(tuple(int(x) + 2 for x in dims), -float(stride * model.step), np.float32)
    _z_field(model.start[2], model.iv[2], float(model.lo[2]), model.step, int(n[0]), int(n[1]), int(n[2]),
             stride, field)
    if field.max() <= 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64), stride
    h = stride * model.step
    verts, faces, _, _ = marching_cubes(field, level=0.0, spacing=(h, h, h), allow_degenerate=False)
    origin = model.lo + 0.5 * model.step - h  # node (0,0,0) sits after one pad layer
    verts = verts.astype(np.float64) + origin
    _snap(verts, model.lo.astype(np.float64), model.step, stride, n, model.start[0], model.iv[0],
          model.start[1], model.iv[1])
    faces = faces.astype(np.int64)
    tri = verts[faces]
    vol = np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    if vol < 0:
        faces = faces[:, ::-1].copy()
    return verts, faces, stride


@numba.njit(cache=True)
def _mark_cells(start, iv, a, lo, step, n, stride, out):
    """Mark in ``out`` (coarse cells, padded by one) every cell of ``stride``-sized blocks that a
    dexel of direction ``a`` passes through (the lattice's cell of a line point holds it)."""
    u = (a + 1) % 3
    v = (a + 2) % 3
    idx = np.zeros(3, np.int64)
    for line in range(start.shape[0] - 1):
        if start[line + 1] == start[line]:
            continue
        idx[u] = (line // n[v]) // stride + 1
        idx[v] = (line % n[v]) // stride + 1
        for q in range(start[line], start[line + 1]):
            c0 = max(0, min(n[a] - 1, int(math.floor((iv[q, 0] - lo[a]) / step))))
            c1 = max(0, min(n[a] - 1, int(math.floor((iv[q, 1] - lo[a]) / step))))
            for c in range(c0 // stride, c1 // stride + 1):
                idx[a] = c + 1
                out[idx[0], idx[1], idx[2]] = 1.0


def stock_hull(model: DexelModel) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (n, 3), faces (m, 3))``: a closed mesh, wound outward, around every dexel of
    the model in all three directions: the boundary of the lattice cells (of ``stride`` cells a
    side, as :func:`machined_mesh` samples) that any dexel passes through, with the corners cut
    as marching cubes cuts them (at most half a cell). Unlike :func:`machined_mesh` it loses no
    material thinner than a cell (a skin left on a wall): the in-process stock an operation keeps
    its rapids, shank and holder clear of."""
    from skimage.measure import marching_cubes

    n = model.n.astype(np.int64)
    stride = max(1, math.ceil((float(np.prod(n)) / MAX_NODES) ** (1 / 3)))
    dims = (n + stride - 1) // stride
    field = np.zeros(tuple(int(x) + 2 for x in dims), np.float32)
    lo = model.lo.astype(np.float64)
    for a in range(3):
        _mark_cells(model.start[a], model.iv[a], a, lo, float(model.step), n, stride, field)
    if field.max() <= 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64)
    h = stride * model.step
    verts, faces, _, _ = marching_cubes(field, level=0.5, spacing=(h, h, h), allow_degenerate=False)
    verts = verts.astype(np.float64) + (lo + 0.5 * h - h)  # the centre of coarse cell 0 after the pad
    faces = faces.astype(np.int64)
    tri = verts[faces]
    if np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) < 0:
        faces = faces[:, ::-1].copy()
    return verts, faces
