"""CUDA backend: the same device functions as the CPU (:mod:`meshmill.kernels.geom`), compiled
with ``numba.cuda.jit(device=True)`` and run one thread per item.

Imported only when asked for (it needs numba's CUDA target: a GPU, or ``NUMBA_ENABLE_CUDASIM=1``,
the simulator the tests use). So far the point-distance and largest-ball queries; the rest of the
operations move here with the GPU issue.
"""
from __future__ import annotations

import math

import numpy as np
from numba import cuda, int32

from .geom import STACK_SIZE, build

dev = build(cuda.jit(device=True))
_point = dev.mesh_point_dist2
_ball = dev.largest_clear_ball
THREADS = 128


@cuda.jit
def _mesh_distances(p, cap2, node_lo, node_hi, node_child, node_range, tris, out):
    i = cuda.grid(1)
    if i < p.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        out[i] = math.sqrt(_point(p[i, 0], p[i, 1], p[i, 2], cap2, 0.0,
                                  node_lo, node_hi, node_child, node_range, tris, stack))


@cuda.jit
def _largest_ball(cc, nrm, radii, tol, node_lo, node_hi, node_child, node_range, tris, out):
    i = cuda.grid(1)
    if i < cc.shape[0]:
        stack = cuda.local.array(STACK_SIZE, int32)
        out[i] = _ball(cc[i, 0], cc[i, 1], cc[i, 2], nrm[i, 0], nrm[i, 1], nrm[i, 2], radii, tol,
                       node_lo, node_hi, node_child, node_range, tris, stack)


def _blocks(n):
    return max(1, (n + THREADS - 1) // THREADS)


def to_device(bvh):
    """Copy ``BVH.arrays`` to the GPU once; the result goes where ``bvh`` arrays are expected."""
    return tuple(cuda.to_device(np.ascontiguousarray(a)) for a in bvh.arrays)


def mesh_distances(points, bvh_dev, cap=1e150):
    """As :func:`meshmill.kernels.cpu.mesh_distances`, on the GPU."""
    p = cuda.to_device(np.ascontiguousarray(points, np.float64))
    out = cuda.device_array(len(points), np.float64)
    _mesh_distances[_blocks(len(points)), THREADS](p, cap * cap, *bvh_dev, out)
    return out.copy_to_host()


def largest_ball(cc, normals, radii, tol, bvh_dev):
    """As :func:`meshmill.kernels.cpu.largest_ball`, on the GPU."""
    out = cuda.device_array(len(cc), np.int32)
    _largest_ball[_blocks(len(cc)), THREADS](cuda.to_device(np.ascontiguousarray(cc, np.float64)),
                                              cuda.to_device(np.ascontiguousarray(normals, np.float64)),
                                              cuda.to_device(np.ascontiguousarray(radii, np.float64)),
                                              float(tol), *bvh_dev, out)
    return out.copy_to_host()
