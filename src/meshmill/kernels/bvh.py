"""Flat bounding-volume hierarchy over the triangles of a mesh.

The tree is a set of arrays that every backend can traverse with an explicit stack (see
:mod:`meshmill.kernels.geom`): node boxes, child indices and leaf triangle ranges, with the
triangles copied in leaf order. Built on the CPU by binned surface-area splits (each node split
at the plane, among 15 per axis, that least weighs each side's triangles by its box's area), at
the median along the longest axis of the centroids' box below :data:`SAH_DEPTH` levels or where
no plane splits. Every search returns the same distances whatever the tree: it prunes only what
cannot come below the best.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

LEAF_SIZE = 4


@dataclass(frozen=True)
class BVH:
    """``tris (m, 9)`` triangle vertices in leaf order; ``order (m,)`` original face index of each;
    ``node_lo/node_hi (k, 3)`` boxes; ``node_child (k, 2)`` children (-1: leaf);
    ``node_range (k, 2)`` first triangle and count of each leaf."""

    tris: np.ndarray
    order: np.ndarray
    node_lo: np.ndarray
    node_hi: np.ndarray
    node_child: np.ndarray
    node_range: np.ndarray

    @property
    def arrays(self):
        """The arrays in the argument order of the device functions."""
        return self.node_lo, self.node_hi, self.node_child, self.node_range, self.tris


SAH_BINS = 16  # candidate split planes per axis, at the edges of equal bins of the centroids' box
SAH_DEPTH = 48  # below this depth nodes split at the median (the traversal's stack holds 128)


@numba.njit(cache=True)
def _half_area(lo, hi):
    dx = max(0.0, hi[0] - lo[0])
    dy = max(0.0, hi[1] - lo[1])
    dz = max(0.0, hi[2] - lo[2])
    return dx * dy + dy * dz + dz * dx


@numba.njit(cache=True)
def _bin_of(c, lo, ext):
    """The bin (of :data:`SAH_BINS` over ``[lo, lo + ext]``) that centroid coordinate ``c`` falls in."""
    return min(SAH_BINS - 1, int(SAH_BINS * (c - lo) / ext))


@numba.njit(cache=True)
def _sah_split(tri_lo, tri_hi, cent, order, s, e, clo, chi, blo, bhi, count, right_area, right_count):
    """The axis and bin of the split of ``order[s:e]`` with the least surface-area cost
    (triangles times box area on each side), among the :data:`SAH_BINS` - 1 planes per axis;
    (-1, -1) where none leaves triangles on both sides."""
    best, best_axis, best_bin = np.inf, -1, -1
    for k in range(3):
        ext = chi[k] - clo[k]
        if ext <= 0.0:
            continue
        for b in range(SAH_BINS):
            count[b] = 0
            for j in range(3):
                blo[b, j] = np.inf
                bhi[b, j] = -np.inf
        for i in range(s, e):
            t = order[i]
            b = _bin_of(cent[t, k], clo[k], ext)
            count[b] += 1
            for j in range(3):
                blo[b, j] = min(blo[b, j], tri_lo[t, j])
                bhi[b, j] = max(bhi[b, j], tri_hi[t, j])
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        c = 0
        for b in range(SAH_BINS - 1, 0, -1):  # the boxes and counts right of each plane
            c += count[b]
            for j in range(3):
                lo[j] = min(lo[j], blo[b, j])
                hi[j] = max(hi[j], bhi[b, j])
            right_count[b] = c
            right_area[b] = _half_area(lo, hi)
        lo[:] = np.inf
        hi[:] = -np.inf
        c = 0
        for b in range(SAH_BINS - 1):
            c += count[b]
            for j in range(3):
                lo[j] = min(lo[j], blo[b, j])
                hi[j] = max(hi[j], bhi[b, j])
            if c == 0 or right_count[b + 1] == 0:
                continue
            cost = c * _half_area(lo, hi) + right_count[b + 1] * right_area[b + 1]
            if cost < best:
                best, best_axis, best_bin = cost, k, b
    return best_axis, best_bin


@numba.njit(cache=True)
def _build(tri_lo, tri_hi, cent, leaf_size):
    m = cent.shape[0]
    cap = 2 * m + 1  # every leaf holds a triangle: at most 2m - 1 nodes
    node_lo = np.empty((cap, 3))
    node_hi = np.empty((cap, 3))
    node_child = np.full((cap, 2), -1, np.int32)
    node_range = np.zeros((cap, 2), np.int32)
    order = np.arange(m)
    work = np.empty((cap, 4), np.int64)  # node, start, end, depth
    work[0, :] = 0
    work[0, 2] = m
    nwork = 1
    count = 1
    clo = np.empty(3)
    chi = np.empty(3)
    blo = np.empty((SAH_BINS, 3))
    bhi = np.empty((SAH_BINS, 3))
    bins = np.zeros(SAH_BINS, np.int64)
    right_area = np.empty(SAH_BINS)
    right_count = np.zeros(SAH_BINS, np.int64)
    while nwork > 0:
        nwork -= 1
        n = work[nwork, 0]
        s = work[nwork, 1]
        e = work[nwork, 2]
        depth = work[nwork, 3]
        for k in range(3):
            lo = np.inf
            hi = -np.inf
            for i in range(s, e):
                t = order[i]
                lo = min(lo, tri_lo[t, k])
                hi = max(hi, tri_hi[t, k])
            node_lo[n, k] = lo
            node_hi[n, k] = hi
        if e - s <= leaf_size:
            node_range[n, 0] = s
            node_range[n, 1] = e - s
            continue
        for k in range(3):
            clo[k] = np.inf
            chi[k] = -np.inf
            for i in range(s, e):
                c = cent[order[i], k]
                clo[k] = min(clo[k], c)
                chi[k] = max(chi[k], c)
        axis, split = -1, -1
        if depth < SAH_DEPTH:
            axis, split = _sah_split(tri_lo, tri_hi, cent, order, s, e, clo, chi, blo, bhi, bins, right_area,
                                     right_count)
        if axis >= 0:  # the triangles of the bins up to ``split`` first
            ext = chi[axis] - clo[axis]
            i = s
            j = e - 1
            while i <= j:
                t = order[i]
                if _bin_of(cent[t, axis], clo[axis], ext) <= split:
                    i += 1
                else:
                    order[i] = order[j]
                    order[j] = t
                    j -= 1
            mid = i
        else:  # the median along the longest axis of the centroids' box
            axis = 0
            for k in range(3):
                if chi[k] - clo[k] > chi[axis] - clo[axis]:
                    axis = k
            sub = order[s:e].copy()
            keys = np.empty(e - s)
            for i in range(e - s):
                keys[i] = cent[sub[i], axis]
            idx = np.argsort(keys, kind="mergesort")
            for i in range(e - s):
                order[s + i] = sub[idx[i]]
            mid = (s + e) // 2
        left = count
        count += 2
        node_child[n, 0] = left
        node_child[n, 1] = left + 1
        for c in range(2):
            work[nwork + c, 0] = left + c
            work[nwork + c, 1] = s if c == 0 else mid
            work[nwork + c, 2] = mid if c == 0 else e
            work[nwork + c, 3] = depth + 1
        nwork += 2
    return order, node_lo[:count], node_hi[:count], node_child[:count], node_range[:count]


def build_bvh(vertices: np.ndarray, faces: np.ndarray) -> BVH:
    """Build the BVH of a mesh: ``vertices (n, 3) float64`` mm, ``faces (m, 3) int``, m >= 1."""
    tri = vertices[faces]  # (m, 3, 3)
    order, lo, hi, child, rng = _build(tri.min(axis=1), tri.max(axis=1), tri.mean(axis=1), LEAF_SIZE)
    tris = np.ascontiguousarray(tri[order].reshape(-1, 9))
    return BVH(tris=tris, order=order, node_lo=lo, node_hi=hi, node_child=child, node_range=rng)
