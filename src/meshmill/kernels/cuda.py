"""CUDA backend: the same device functions as the CPU (:mod:`meshmill.kernels.geom`), compiled
with ``numba.cuda.jit(device=True)`` and run one thread per item.

Imported only when asked for (it needs numba's CUDA target: a GPU, or ``NUMBA_ENABLE_CUDASIM=1``,
the simulator the tests use). So far the point-distance and largest-ball queries and the casting of
dexel lines; the rest of the operations move here with the GPU issue.
"""
from __future__ import annotations

import math

import numpy as np
from numba import cuda, float64, int32, int64

from . import raycast
from .geom import STACK_SIZE, build
from .raycast import MAX_HITS

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


ray = raycast.build(cuda.jit(device=True))
_cast_bvh_line = ray.cast_bvh_line


@cuda.jit
def _cast_bvh(a, lu, lv, step, nu, nv, cap, node_lo, node_hi, node_child, node_range, tris, out, count):
    line = cuda.grid(1)
    if line < nu * nv:
        stack = cuda.local.array(STACK_SIZE, int32)
        hw = cuda.local.array(MAX_HITS, float64)
        hs = cuda.local.array(MAX_HITS, int64)
        count[line] = _cast_bvh_line(a, line, lu, lv, step, nv, cap, node_lo, node_hi, node_child, node_range, tris,
                                     stack, hw, hs, out)


def cast_lines(a, lu, lv, step, nu, nv, bvh_dev):
    """As :func:`meshmill.kernels.cpu_dexel.cast_lines` with the BVH index, on the GPU (the BVH
    arrays from :func:`to_device`)."""
    n_lines = int(nu) * int(nv)
    cap = 4
    while True:
        out = cuda.device_array((n_lines, cap, 2), np.float64)
        count = cuda.device_array(n_lines, np.int64)
        _cast_bvh[_blocks(n_lines), THREADS](a, float(lu), float(lv), float(step), int(nu), int(nv), cap,
                                            *bvh_dev, out, count)
        c = count.copy_to_host()
        need = int(c.max(initial=0))
        if need <= cap:
            return out.copy_to_host(), c
        cap = need
