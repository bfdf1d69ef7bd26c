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


def mesh_grid(n) -> tuple[int, np.ndarray]:
    """``(stride, dims (3,))``: the lattice nodes the field samples (every ``stride``-th a side,
    under :data:`MAX_NODES`) and how many a side."""
    n = np.asarray(n, np.int64)
    stride = max(1, math.ceil((float(np.prod(n)) / MAX_NODES) ** (1 / 3)))
    return stride, (n + stride - 1) // stride


@numba.njit(cache=True)
def _z_field(start, iv, lo_z, step, ny, stride, i0, a0, out):
    """Field (+inside) at the sampled nodes of the coarse X rows ``a0 ..`` into ``out (k, d1 + 2,
    d2 + 2)`` (padded in Y and Z), from the Z lines of the lattice X rows ``i0 ..`` (CSR)."""
    cap = stride * step
    for a in range(out.shape[0]):
        i = (a0 + a) * stride
        for b in range(out.shape[1] - 2):
            j = b * stride
            line = (i - i0) * ny + j
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
                out[a, b + 1, c + 1] = d if inside else -max(d, 1e-6 * step)


def field_rows(lo, n, step, start, iv, first_row: int, stop_row: int) -> tuple[int, np.ndarray]:
    """``(a0, slab (k, d1 + 2, d2 + 2) float32)``: the field of :func:`machined_mesh` at the
    coarse X rows ``a0 .. a0 + k - 1`` that fall in the lattice X rows ``first_row .. stop_row - 1``,
    from their Z lines (CSR ``(start, iv)``)."""
    stride, dims = mesh_grid(n)
    a0, a1 = -(-first_row // stride), -(-stop_row // stride)
    slab = np.full((max(0, a1 - a0), int(dims[1]) + 2, int(dims[2]) + 2), -float(stride * step), np.float32)
    _z_field(start, iv, float(lo[2]), float(step), int(n[1]), stride, first_row, a0, slab)
    return a0, slab


@numba.njit(cache=True)
def _snap(verts, lo, step, stride, n, a, start, iv, line0, out, moved):
    """For every vertex on an edge along ``a`` (0: X, 1: Y) whose lattice line is one of the CSR
    lines ``line0 ..`` (``start, iv``): the single dexel end along its edge, into ``out`` and
    ``moved`` (none when there are none or several)."""
    h = stride * step
    for k in range(verts.shape[0]):
        f0 = (verts[k, 0] - lo[0]) / h - 0.5 / stride
        f1 = (verts[k, 1] - lo[1]) / h - 0.5 / stride
        f2 = (verts[k, 2] - lo[2]) / h - 0.5 / stride
        r0 = abs(f0 - round(f0)) < 1e-6
        r1 = abs(f1 - round(f1)) < 1e-6
        r2 = abs(f2 - round(f2)) < 1e-6
        if a == 0 and r1 and r2 and not r0:  # on an X edge: X line through (y, z)
            line = int(round(f1)) * stride * n[2] + int(round(f2)) * stride
            e0 = lo[0] + (math.floor(f0) * stride + 0.5) * step
        elif a == 1 and r0 and r2 and not r1:  # on a Y edge: Y line through (z, x)
            line = int(round(f2)) * stride * n[0] + int(round(f0)) * stride
            e0 = lo[1] + (math.floor(f1) * stride + 0.5) * step
        else:
            continue
        if line < line0 or line >= line0 + start.shape[0] - 1:
            continue
        e1 = e0 + h
        found = 0
        w = 0.0
        for q in range(start[line - line0], start[line - line0 + 1]):
            for e in range(2):
                if e0 < iv[q, e] < e1:
                    found += 1
                    w = iv[q, e]
        if found == 1:
            out[k] = w
            moved[k] = True


def snap_lines(verts, lo, n, step, a: int, start, iv, first_row: int) -> tuple[np.ndarray, np.ndarray]:
    """``(indices, values)``: the vertices of the marching-cubes surface ``verts (k, 3)`` on edges
    along ``a`` (0 or 1) that move to the single dexel end along their edge, and their new
    coordinate ``a``, from the lines along ``a`` of the lattice rows ``first_row ..`` (CSR)."""
    stride, _ = mesh_grid(n)
    out, moved = np.zeros(len(verts)), np.zeros(len(verts), np.bool_)
    _snap(verts, np.asarray(lo, np.float64), float(step), stride, np.asarray(n, np.int64), a, start, iv,
          first_row * int(n[(a + 2) % 3]), out, moved)
    idx = np.nonzero(moved)[0]
    return idx, out[idx]


def field_surface(field, lo, step, n) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (k, 3), faces (m, 3))`` of the field's zero level (marching cubes), before
    the snap; empty without material."""
    from skimage.measure import marching_cubes

    stride, _ = mesh_grid(n)
    if field.max() <= 0:
        return np.empty((0, 3)), np.empty((0, 3), np.int64)
    h = stride * step
    verts, faces, _, _ = marching_cubes(field, level=0.0, spacing=(h, h, h), allow_degenerate=False)
    origin = np.asarray(lo) + 0.5 * step - h  # node (0,0,0) sits after one pad layer
    return verts.astype(np.float64) + origin, faces.astype(np.int64)


def outward(verts, faces) -> np.ndarray:
    """``faces`` wound so that the closed surface encloses a positive volume."""
    if not len(faces):
        return faces
    tri = verts[faces]
    vol = np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    return faces[:, ::-1].copy() if vol < 0 else faces


def empty_field(n, step) -> np.ndarray:
    """The field of :func:`machined_mesh` before any row is filled (all outside), float32."""
    stride, dims = mesh_grid(n)
    return np.full(tuple(int(x) + 2 for x in dims), -float(stride * step), np.float32)


def machined_mesh(model: DexelModel) -> tuple[np.ndarray, np.ndarray, int]:
    """``(vertices (n, 3), faces (m, 3), stride)`` of the model's solid, wound outward; empty
    arrays when the model holds no material."""
    stride, _ = mesh_grid(model.n)
    field = empty_field(model.n, model.step)
    a0, slab = field_rows(model.lo, model.n, model.step, model.start[2], model.iv[2], 0, int(model.n[0]))
    field[a0 + 1:a0 + 1 + len(slab)] = slab
    verts, faces = field_surface(field, model.lo, model.step, model.n)
    for a in (0, 1):
        idx, w = snap_lines(verts, model.lo, model.n, model.step, a, model.start[a], model.iv[a], 0)
        verts[idx, a] = w
    return verts, outward(verts, faces), stride


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
    stride, dims = mesh_grid(n)
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
