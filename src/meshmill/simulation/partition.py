"""The seed's spatial partitions of a mesh's triangles (kept to reproduce its tables):
uniform cells and k-means on triangle centroids, their envelopes and overlap, and a K-optimal
helper.

Every triangle belongs to exactly one partition (the cell holding its centroid, or its k-means
cluster); a partition's envelope is the box of its triangles, so envelopes may overlap. The
overlap criterion is the sum over pairs of the volume of the boxes' intersection (the robust
form of the seed's formula, which miscounts nested boxes).
"""
from __future__ import annotations

import itertools
import math
import time

import numpy as np

from ..errors import InputError


def cell_counts(k: int, extent) -> tuple[int, int, int]:
    """Factor ``k`` cells into ``nx*ny*nz == k`` with cells as cube-like as possible over a box of
    size ``extent (3,)`` mm (the seed's 2 -> 2x1x1, 8 -> 2x2x2, 12 -> 3x2x2 along the long axes)."""
    ext = np.maximum(np.asarray(extent, float), 1e-9)
    best, score = (k, 1, 1), math.inf
    for nx in range(1, k + 1):
        if k % nx:
            continue
        for ny in range(1, k // nx + 1):
            if (k // nx) % ny:
                continue
            nz = k // (nx * ny)
            cell = ext / np.array([nx, ny, nz])
            s = cell.max() / cell.min()
            if s < score - 1e-12:
                best, score = (nx, ny, nz), s
    return best


def cell_labels(centroids: np.ndarray, k: int) -> np.ndarray:
    """Cell index ``(m,)`` of each centroid ``(m, 3)`` over a uniform grid of k cells on their box."""
    lo, hi = centroids.min(axis=0), centroids.max(axis=0)
    counts = np.array(cell_counts(k, hi - lo))
    size = np.where(hi > lo, (hi - lo) / counts, 1.0)
    idx = np.minimum(((centroids - lo) / size).astype(np.int64), counts - 1)
    return (idx[:, 0] * counts[1] + idx[:, 1]) * counts[2] + idx[:, 2]


def kmeans_labels(centroids: np.ndarray, k: int, init="k-means++", minibatch=False, seed=0) -> np.ndarray:
    """k-means cluster ``(m,)`` of each centroid with scikit-learn (tolerance 1e-6 as in the seed)."""
    from sklearn.cluster import KMeans, MiniBatchKMeans

    if k > len(centroids):
        raise InputError(f"partitions {k} is more than the {len(centroids)} triangles", "partitions")
    if minibatch:
        km = MiniBatchKMeans(n_clusters=k, init=init, n_init=1, random_state=seed, tol=1e-6,
                             batch_size=1024, max_iter=300)
    else:
        km = KMeans(n_clusters=k, init=init, n_init=1, random_state=seed, tol=1e-6, max_iter=300)
    return km.fit_predict(centroids).astype(np.int64)


def partition_index(tris: np.ndarray, labels: np.ndarray):
    """Group ``tris (m, 9)`` by label. Returns ``(box_lo (K, 3), box_hi (K, 3), box_start (K+1,),
    tris (m, 9) in partition order)``; empty partitions are dropped."""
    order = np.argsort(labels, kind="stable")
    lab = labels[order]
    uniq, first = np.unique(lab, return_index=True)
    start = np.r_[first, len(lab)].astype(np.int64)
    t = np.ascontiguousarray(tris[order])
    pts = t.reshape(-1, 3, 3)
    lo = np.minimum.reduceat(pts.min(axis=1), first, axis=0)
    hi = np.maximum.reduceat(pts.max(axis=1), first, axis=0)
    return lo, hi, start, t


def total_overlap(box_lo: np.ndarray, box_hi: np.ndarray) -> float:
    """Sum over pairs of boxes of their intersection volume, mm^3."""
    total = 0.0
    for i, j in itertools.combinations(range(len(box_lo)), 2):
        d = np.minimum(box_hi[i], box_hi[j]) - np.maximum(box_lo[i], box_lo[j])
        if (d > 0).all():
            total += float(np.prod(d))
    return total


def line_tests(box_lo, box_hi, box_start, lo, step, n) -> float:
    """Expected line-triangle tests of casting the three grids through the partitions: for each
    direction, the lines crossing each box times its triangles, plus one box test per line and box."""
    tests = 0.0
    for a in range(3):
        u, v = (a + 1) % 3, (a + 2) % 3
        lines_u = np.clip(np.floor((box_hi[:, u] - lo[u]) / step - 0.5) - np.ceil((box_lo[:, u] - lo[u]) / step - 0.5) + 1, 0, None)
        lines_v = np.clip(np.floor((box_hi[:, v] - lo[v]) / step - 0.5) - np.ceil((box_lo[:, v] - lo[v]) / step - 0.5) + 1, 0, None)
        tests += float((lines_u * lines_v * np.diff(box_start)).sum()) + n[u] * n[v] * len(box_lo)
    return tests


def k_optimal(tris, lo, step, n, k_max, method="kmeans", init="k-means++", minibatch=False):
    """Partition for K = 1..k_max; rows ``{K, overlap_mm3, line_tests, seconds}`` and the best K.

    The seed ranks K by overlap alone, which always picks K = 1 (overlap 0, see its notes §11.11);
    we pick the K with the fewest expected line-triangle tests (:func:`line_tests`), which counts
    the redundancy that overlap measures and the work that partitions save.
    """
    rows = []
    cent = tris.reshape(-1, 3, 3).mean(axis=1)
    for k in range(1, k_max + 1):
        t0 = time.perf_counter()
        if method == "kmeans":
            labels = kmeans_labels(cent, k, init, minibatch)
        else:
            labels = cell_labels(cent, k)
        blo, bhi, bstart, _ = partition_index(tris, labels)
        seconds = time.perf_counter() - t0
        rows.append({"K": k, "overlap_mm3": round(total_overlap(blo, bhi), 3),
                     "line_tests": int(line_tests(blo, bhi, bstart, lo, step, n)), "seconds": round(seconds, 4)})
    best = min(rows, key=lambda r: r["line_tests"])["K"]
    return best, rows
