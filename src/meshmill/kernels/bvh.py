"""Flat bounding-volume hierarchy over the triangles of a mesh.

The tree is a set of arrays that every backend can traverse with an explicit stack (see
:mod:`meshmill.kernels.geom`): node boxes, child indices and leaf triangle ranges, with the
triangles copied in leaf order. Built on the CPU by median splits along the longest axis of the
centroids' box.
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


@numba.njit(cache=True)
def _build(tri_lo, tri_hi, cent, leaf_size):
    m = cent.shape[0]
    cap = 2 * m + 1  # median splits leave >= 2 triangles a leaf: at most m + 1 nodes
    node_lo = np.empty((cap, 3))
    node_hi = np.empty((cap, 3))
    node_child = np.full((cap, 2), -1, np.int32)
    node_range = np.zeros((cap, 2), np.int32)
    order = np.arange(m)
    work = np.empty((cap, 3), np.int64)  # node, start, end
    work[0, 0] = 0
    work[0, 1] = 0
    work[0, 2] = m
    nwork = 1
    count = 1
    while nwork > 0:
        nwork -= 1
        n = work[nwork, 0]
        s = work[nwork, 1]
        e = work[nwork, 2]
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
        axis = 0
        ext = -1.0
        for k in range(3):
            lo = np.inf
            hi = -np.inf
            for i in range(s, e):
                c = cent[order[i], k]
                lo = min(lo, c)
                hi = max(hi, c)
            if hi - lo > ext:
                ext = hi - lo
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
        work[nwork, 0] = left
        work[nwork, 1] = s
        work[nwork, 2] = mid
        work[nwork + 1, 0] = left + 1
        work[nwork + 1, 1] = mid
        work[nwork + 1, 2] = e
        nwork += 2
    return order, node_lo[:count], node_hi[:count], node_child[:count], node_range[:count]


def build_bvh(vertices: np.ndarray, faces: np.ndarray) -> BVH:
    """Build the BVH of a mesh: ``vertices (n, 3) float64`` mm, ``faces (m, 3) int``, m >= 1."""
    tri = vertices[faces]  # (m, 3, 3)
    order, lo, hi, child, rng = _build(tri.min(axis=1), tri.max(axis=1), tri.mean(axis=1), LEAF_SIZE)
    tris = np.ascontiguousarray(tri[order].reshape(-1, 9))
    return BVH(tris=tris, order=order, node_lo=lo, node_hi=hi, node_child=child, node_range=rng)
