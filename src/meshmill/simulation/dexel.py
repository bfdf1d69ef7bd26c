"""Triple-dexel model of a solid: three grids of lines along X, Y and Z, and on every line the
intervals that lie inside the material.

The three grids share one lattice: cells of ``step`` mm from the corner ``lo``, ``n (3,)`` cells a
side; a line along axis ``a`` runs through the centres of the cells in the other two axes
(``u = (a+1) % 3``, ``v = (a+2) % 3``), so every lattice node ``lo + (i + 1/2) step`` lies on one
line of each direction. Intervals are stored per direction as CSR: ``start[a] (nu*nv + 1,)``
offsets and ``iv[a] (m, 2)`` sorted, disjoint ``(from, to)`` coordinates along ``a``, mm.

Lines are cast through the mesh exactly (:mod:`meshmill.kernels.raycast`); the index that finds
the triangles a line may cross is the package's BVH, or the seed's cells or k-means partitions.
"""
from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field

import numba
import numpy as np

from .. import memory
from ..errors import InputError
from ..kernels.backend import MAX_HITS, DexelKernels
from ..kernels.bvh import build_bvh
from . import partition
from .exactsum import expansion, total

LINE_BYTES = 200  # one line while casting (its dense rows, count and CSR share) and its intervals after
FORMAT = "meshmill-dexel-1"
MAX_PARTITIONS = 4096  # the seed used up to 37; every line tests every partition box


@dataclass
class DexelModel:
    """Triple-dexel model: ``lo (3,)`` lattice corner and ``step`` mm, ``n (3,)`` cells a side,
    per direction ``start[a]`` and ``iv[a]`` (see the module docstring)."""

    lo: np.ndarray
    step: float
    n: np.ndarray
    start: list
    iv: list
    name: str = ""
    info: dict = field(default_factory=dict)

    def shape(self, a: int) -> tuple[int, int]:
        """``(nu, nv)``: lines of the grid along axis ``a``."""
        return int(self.n[(a + 1) % 3]), int(self.n[(a + 2) % 3])

    def line_count(self, a: int) -> int:
        nu, nv = self.shape(a)
        return nu * nv

    def dexel_count(self, a: int) -> int:
        return int(len(self.iv[a]))

    def volumes(self) -> np.ndarray:
        """``(3,)`` volume measured by each direction's dexels, mm^3 (exact sums: the same
        however the lines are grouped)."""
        return np.array([total(expansion(self.iv[a][:, 1] - self.iv[a][:, 0])) * self.step ** 2 for a in range(3)])

    @property
    def volume(self) -> float:
        """Mean of the three directions' volumes, mm^3."""
        return float(self.volumes().mean())

    def summary(self) -> dict:
        return lattice_summary(self.lo, self.step, self.n, [self.dexel_count(a) for a in range(3)], self.volumes())


def lattice_summary(lo, step, n, dexels, volumes) -> dict:
    """A model's summary from its lattice, its dexel count and volume (mm^3) per direction."""
    names = "XYZ"
    return {
        "step": step,
        "lattice_corner": [round(float(x), 9) for x in lo],
        "cells": [int(x) for x in n],
        "lines": {names[a]: int(n[(a + 1) % 3]) * int(n[(a + 2) % 3]) for a in range(3)},
        "dexels": {names[a]: int(dexels[a]) for a in range(3)},
        "volume_mm3": round(float(np.mean(volumes)), 6),
        "volume_by_direction_mm3": {names[a]: round(float(v), 6) for a, v in enumerate(volumes)},
    }


def lattice(bounds: np.ndarray, step: float, pad: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """``(lo (3,), n (3,))``: a lattice of ``step`` cells centred on ``bounds (2, 3)`` with ``pad``
    empty cells on every side."""
    if not (math.isfinite(step) and step > 0):
        raise InputError(f"step must be a positive number of mm, got {step}", "step")
    bounds = np.asarray(bounds, float)
    ext = bounds[1] - bounds[0]
    n = np.ceil(ext / step).astype(np.int64) + 2 * pad
    n = np.maximum(n, 1)
    lo = 0.5 * (bounds[0] + bounds[1]) - 0.5 * n * step
    lines = int(n[1] * n[2] + n[2] * n[0] + n[0] * n[1])
    memory.check(LINE_BYTES * float(lines), f"step {step:g} mm: {lines:,} dexel lines over a {ext[0]:.1f} x "
                 f"{ext[1]:.1f} x {ext[2]:.1f} mm box", "use a larger step", ("step",))
    return lo, n


@numba.njit(cache=True)
def compact_lines(iv, off, count):
    """CSR ``(start, iv)`` of per-line intervals stored with room: line i's ``count[i]``
    intervals at ``iv[off[i]:]``."""
    start = np.zeros(count.shape[0] + 1, np.int64)
    for i in range(count.shape[0]):
        start[i + 1] = start[i] + count[i]
    out = np.empty((start[-1], 2))
    for i in range(count.shape[0]):
        for k in range(count[i]):
            out[start[i] + k, 0] = iv[off[i] + k, 0]
            out[start[i] + k, 1] = iv[off[i] + k, 1]
    return start, out


def compact(dense: np.ndarray, count: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(start, iv)`` of dense per-line intervals ``(n_lines, cap, 2)`` with ``count (n_lines,)``
    (negative counts, lines in error, hold nothing)."""
    cap = dense.shape[1]
    return compact_lines(dense.reshape(-1, 2), np.arange(len(count) + 1, dtype=np.int64) * cap,
                         np.maximum(count, 0).astype(np.int64))


def mesh_index(mesh, index="bvh", partitions=1, init="k-means++", minibatch=False):
    """The triangle index the lines are cast through, and what it is: ``(index, info)``."""
    tris = mesh.vertices[mesh.faces].reshape(-1, 9)
    if index == "bvh":
        bvh = build_bvh(mesh.vertices, mesh.faces)
        return ("bvh", bvh.arrays), {"index": "bvh", "nodes": int(len(bvh.node_lo))}
    if index not in ("cells", "kmeans"):
        raise InputError(f"index must be bvh, cells or kmeans, got {index!r}", "index")
    if not (isinstance(partitions, int) and 1 <= partitions <= MAX_PARTITIONS):
        raise InputError(f"partitions must be a whole number from 1 to {MAX_PARTITIONS}, got {partitions}", "partitions")
    cent = tris.reshape(-1, 3, 3).mean(axis=1)
    if index == "cells":
        labels = partition.cell_labels(cent, partitions)
        info = {"index": "cells", "cells": list(partition.cell_counts(partitions, np.ptp(cent, axis=0)))}
    else:
        labels = partition.kmeans_labels(cent, partitions, init, minibatch)
        info = {"index": "kmeans", "init": init, "minibatch": bool(minibatch)}
    lo, hi, start, t = partition.partition_index(tris, labels)
    info.update(partitions=int(len(lo)), overlap_mm3=round(partition.total_overlap(lo, hi), 6))
    return ("boxes", (lo, hi, start, t)), info


def material_mesh(mesh, floor=None):
    """``mesh`` if closed, else the closed surface of the solid it bounds as a mesh: its holes
    capped, its sheets down to ``floor`` mm (default: the solid's, see
    :meth:`~meshmill.geometry.mesh.Mesh.solid`) by curtains under their edges and a floor under
    them (:mod:`meshmill.geometry.solid`). What a dexel model of an open part holds, and what
    deviations are measured to."""
    if mesh.closed:
        return mesh
    from ..geometry.mesh import Mesh

    s = mesh.solid(floor)
    return Mesh(vertices=s.vertices, faces=s.faces.astype(np.int32), closed=True, flipped=mesh.flipped,
                placement=mesh.placement)


def uneven_lines_warning(odd: dict | None, mesh) -> list[str]:
    """The one-line warning of a model of ``mesh`` whose lines crossed its surface an odd number of
    times (``odd``: how many along each axis, its ``info["uneven_lines"]``): only where every piece
    of the mesh is closed, where it means shells that intersect or overlap (an open sheet's solid
    is decided point by point by construction: its lines graze the curtains under its edges)."""
    if not odd or not mesh.closed:
        return []
    lines = ", ".join(f"{k} along {axis}" for axis, k in odd.items())
    return [f"{lines} grid line(s) cross the surface an odd number of times (self-intersecting or overlapping "
            "shells): their material was decided point by point, by the winding of the solid"]


def parity_may_differ(source) -> bool:
    """Whether the winding of a line's crossings of ``source``'s check mesh may tell its solid's
    material wrongly where they balance: where it has two sheets or more. The solid is the union
    of its closed (and capped) pieces, which winding counts, and of the points under an odd number
    of sheet faces (so a nose's underside sheet takes away what its top sheet holds), which the
    winding of the sheets' curtained volumes counts twice: a line along X through mount_rush.stl
    took 2 mm of air under its sheets for material, and simulate reported a 7.2 mm gouge there."""
    from ..geometry.solid import SHEET

    kinds = source.piece_kind
    return kinds is not None and int((kinds == SHEET).sum()) > 1


LINE_BYTES = 112  # a line being cast on a worker: its room for crossings, count, and the compacted result
TRIANGLE_BYTES = 400  # a triangle on a worker: the mesh, the solid, its BVH


def _cast(kern, a, lo, n, step, mesh, bvh, source, rows=None):
    """``(start, iv, uneven lines)`` of the lines along ``a`` of the lattice ``lo, n`` (of its rows
    ``rows = (i0, i1)`` along the axis after ``a``, default all): the material of the solid
    ``source`` bounds, whose surface ``mesh`` is (:func:`material_mesh`). One closed piece is cast
    by the winding of its crossings (on the kernels' device), the lines whose crossings do not
    balance decided point by point; any other part has every line decided point by point
    (:func:`parity_may_differ`)."""
    u, v = (a + 1) % 3, (a + 2) % 3
    i0, i1 = rows if rows is not None else (0, int(n[u]))
    lines = np.arange((i1 - i0) * int(n[v]))
    if parity_may_differ(source):
        dense, count = np.zeros((len(lines), 0, 2)), np.zeros(len(lines), np.int64)
    else:
        dense, count = kern.cast_lines(a, lo[u], lo[v], step, i1 - i0, n[v], i0)
        lines = np.nonzero(count == -1)[0]
    uneven = 0
    if len(lines):  # decided point by point
        if bvh is None:  # the cells and k-means indexes hold no BVH: one for these lines
            bvh = build_bvh(mesh.vertices, mesh.faces).arrays
        inside = source.solid(float(mesh.bounds[0, 2])).inside
        got, got_count, odd = kern.solid_lines(a, lines, lo[u], lo[v], step, n[v], bvh, inside, i0)
        if got.shape[1] > dense.shape[1]:
            dense = np.concatenate([dense, np.zeros((len(dense), got.shape[1] - dense.shape[1], 2))], axis=1)
        dense[lines, :got.shape[1]] = got
        count[lines] = got_count
        uneven = int(odd.sum())
    if (count == -2).any():
        raise InputError(f"{int((count == -2).sum())} line(s) along {'XYZ'[a]} cross the surface more than "
                         f"{MAX_HITS} times: the mesh is too intricate for one line (or has many stacked shells)")
    s, iv = compact(dense, count)
    return s, iv, uneven


def cast_rows(shared: dict, key: str, a: int, rows) -> tuple:
    """``(start, iv, uneven lines)`` of the lines along ``a`` of the lattice rows ``rows = (i0,
    i1)`` cast on a worker of a cluster: ``shared[key]`` is ``(material mesh, source part)`` (its
    index and kernels built once per worker), ``shared`` also holds the lattice ``lo, n, step``
    and the ``device``."""
    from ..cluster import worker_cached

    mesh, source = shared[key]
    idx, _ = worker_cached(shared, f"{key} index", lambda: mesh_index(mesh))
    kern = worker_cached(shared, f"{key} kernels", lambda: DexelKernels(shared["device"], idx))
    return _cast(kern, a, shared["lo"], shared["n"], shared["step"], mesh, idx[1], source, rows)


def cast_block(shared: dict, piece) -> tuple:
    """One block of lines on a worker of a cluster (:func:`meshmill.cluster.run_pieces`): the
    lines along ``a`` whose first lattice index (along the axis after ``a``) is in ``i0 .. i1 - 1``,
    as :func:`dexelize` casts them (:func:`cast_rows` of ``shared["mesh"]``), and the index's info."""
    from ..cluster import worker_cached

    a, i0, i1 = piece
    start, iv, bad = cast_rows(shared, "mesh", a, (i0, i1))
    return start, iv, bad, worker_cached(shared, "mesh index", lambda: mesh_index(shared["mesh"][0]))[1]


def line_rows(start, iv, nv: int, i0: int, i1: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR ``(start, iv)`` of the lattice rows ``i0 .. i1 - 1`` (``nv`` lines a row) of the lines
    ``(start, iv)``."""
    s = start[i0 * nv:i1 * nv + 1]
    return s - s[0], iv[s[0]:s[-1]]


def join_lines(blocks):
    """The CSR ``(start, iv)`` of consecutive blocks of lines, each ``(start, iv, ...)``."""
    starts, ivs, base = [np.zeros(1, np.int64)], [], 0
    for s, iv, *_ in blocks:
        starts.append(s[1:] + base)
        ivs.append(iv)
        base += len(iv)
    return np.concatenate(starts), np.concatenate(ivs) if ivs else np.zeros((0, 2))


def dexelize(mesh, step: float, index="bvh", partitions=1, init="k-means++", minibatch=False,
             bounds=None, progress=None, device="cpu", cluster=None) -> DexelModel:
    """Triple-dexel model of the solid ``mesh`` bounds at ``step`` mm over ``bounds (2, 3)``
    (default: the solid's box with one empty cell around; an open mesh's sheets reach down to the
    bottom of ``bounds``, see :func:`material_mesh`). ``device``: ``"cpu"`` or ``"cuda"`` (BVH
    index only). ``cluster``: a ``distributed.Client``: blocks of lines cast on its workers (BVH
    index only; the same model). Timings, the index and the device go to ``model.info``."""
    source = mesh
    mesh = material_mesh(mesh, None if bounds is None else float(np.asarray(bounds, float)[0, 2]))
    lo, n = lattice(mesh.bounds if bounds is None else bounds, step)
    if cluster is not None:
        return _dexelize_on(cluster, mesh, source, lo, n, float(step), index, progress, device)
    odd = {}
    t0 = time.perf_counter()
    idx, info = mesh_index(mesh, index, partitions, init, minibatch)
    bvh = idx[1] if idx[0] == "bvh" else None
    info["index_seconds"] = round(time.perf_counter() - t0, 4)
    info["device"] = device
    kern = DexelKernels(device, idx)
    starts, ivs = [], []
    t1 = time.perf_counter()
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        s, iv, bad = _cast(kern, a, lo, n, step, mesh, bvh, source)
        if bad:
            odd["XYZ"[a]] = bad
        starts.append(s)
        ivs.append(iv)
        if progress:
            progress(f"lines along {'XYZ'[a]}: {n[u] * n[v]:,}, dexels {len(iv):,}")
    info["cast_seconds"] = round(time.perf_counter() - t1, 4)
    if odd:
        info["uneven_lines"] = odd
    return DexelModel(lo=lo, step=float(step), n=n, start=starts, iv=ivs, info=info)


def _dexelize_on(client, mesh, source, lo, n, step, index, progress, device) -> DexelModel:
    """:func:`dexelize` with blocks of lines cast on the workers of ``client``."""
    from ..cluster import PIECES_PER_WORKER, check_workers, run_pieces, workers
    from ..progress import ranges

    if index != "bvh":
        raise InputError("a cluster casts lines through the BVH index only (leave index out)", ("cluster", "index"))
    t1 = time.perf_counter()
    count = PIECES_PER_WORKER * workers(client)
    pieces = [(a, i0, i1) for a in range(3) for i0, i1 in ranges(int(n[(a + 1) % 3]), count)]
    # a worker holds the mesh and its BVH, and a block's lines with room for four crossing pairs
    block = max((i1 - i0) * int(n[(a + 2) % 3]) for a, i0, i1 in pieces)
    check_workers(client, LINE_BYTES * block + TRIANGLE_BYTES * len(mesh.faces),
                  f"casting {sum(int(n[(a + 1) % 3] * n[(a + 2) % 3]) for a in range(3)):,} dexel lines in blocks",
                  "use more workers, or a coarser step")
    shared = dict(mesh=(mesh, source), lo=lo, n=n, step=step, device=device)
    blocks = run_pieces(client, cast_block, shared, pieces, progress, "dexel lines")
    starts, ivs, odd = [], [], {}
    for a in range(3):
        mine = [b for (d, _, _), b in zip(pieces, blocks) if d == a]
        s, iv = join_lines(mine)
        starts.append(s)
        ivs.append(iv)
        if sum(b[2] for b in mine):
            odd["XYZ"[a]] = sum(b[2] for b in mine)
    info = {**blocks[0][3], "device": device, "workers": workers(client), "pieces": len(pieces),
            "cast_seconds": round(time.perf_counter() - t1, 4)}
    if odd:
        info["uneven_lines"] = odd
    return DexelModel(lo=lo, step=float(step), n=n, start=starts, iv=ivs, info=info)


def save_npz(path, model: DexelModel) -> None:
    """Write the compact binary format (numpy ``.npz``, compressed)."""
    arrays = {"format": np.array(FORMAT), "lo": model.lo, "step": np.array(model.step), "n": model.n,
              "name": np.array(model.name)}
    for a in range(3):
        arrays[f"start{a}"] = model.start[a]
        arrays[f"iv{a}"] = model.iv[a]
    try:
        np.savez_compressed(path, **arrays)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror})") from None


def load_npz(path) -> DexelModel:
    """Read a model written by :func:`save_npz`."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise InputError(f"{path}: no such dexel file")
    try:
        with np.load(path, allow_pickle=False) as f:
            if str(f["format"]) != FORMAT:
                raise InputError(f"{path}: not a meshmill dexel file")
            return DexelModel(lo=f["lo"], step=float(f["step"]), n=f["n"],
                              start=[f[f"start{a}"] for a in range(3)], iv=[f[f"iv{a}"] for a in range(3)],
                              name=str(f["name"]))
    except (ValueError, KeyError, OSError):
        raise InputError(f"{path}: not a meshmill dexel file") from None


def export_td(path, model: DexelModel) -> None:
    """Write the seed's ASCII layout (its notes §6.2): header, then one dexel a line,
    ``<X|Y|Z> <i> <j> <x0> <y0> <z0> <x1> <y1> <z1> material``."""
    hi = model.lo + model.n * model.step
    head = ["# TD v1", f"name {model.name}", f"step {model.step:.9g} {model.step:.9g} {model.step:.9g}",
            "envelope_min " + " ".join(f"{x:.9g}" for x in model.lo),
            "envelope_max " + " ".join(f"{x:.9g}" for x in hi),
            "grid " + " ".join(str(int(x)) for x in model.n),
            f"dexels {sum(model.dexel_count(a) for a in range(3))}"]
    try:
        with open(path, "w") as fh:
            fh.write("\n".join(head) + "\n")
            for a in range(3):
                u, v = (a + 1) % 3, (a + 2) % 3
                nu, nv = model.shape(a)
                per_line = np.diff(model.start[a])
                line = np.repeat(np.arange(nu * nv), per_line)
                i, j = line // nv, line % nv
                p0 = np.empty((len(line), 3))
                p0[:, u] = model.lo[u] + (i + 0.5) * model.step
                p0[:, v] = model.lo[v] + (j + 0.5) * model.step
                p1 = p0.copy()
                p0[:, a] = model.iv[a][:, 0]
                p1[:, a] = model.iv[a][:, 1]
                rows = np.column_stack([i, j, p0, p1])
                fmt = "XYZ"[a] + " %d %d %.6f %.6f %.6f %.6f %.6f %.6f material"
                np.savetxt(fh, rows, fmt=fmt)
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror})") from None
