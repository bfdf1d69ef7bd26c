"""Every CUDA kernel compiles for a real GPU (PTX for an H100, sm_90), with the argument types its
wrapper launches it with. The CUDA simulator of the parity tests runs the device functions as
Python, so it cannot catch what only the CUDA compiler refuses; this can, without a GPU: it needs
NVIDIA's compiler library, which ``pip install -e '.[cuda]'`` brings (skipped without it), and
NUMBA_ENABLE_CUDASIM=0 (tests/test_cuda_ptx.py runs it so)."""
import os
from types import SimpleNamespace

import numpy as np
import pytest

from meshmill.geometry.shapes import post_with_fillet
from meshmill.kernels.bvh import build_bvh


MAX_PTX = 1_500_000  # bytes of PTX a kernel may take (the largest, the cut kernel, takes about 0.9 MB)


class Host(np.ndarray):
    """Stands in for a device array."""

    def copy_to_host(self):
        return np.asarray(self).copy()

    def copy_to_device(self, a):
        self[...] = a


class Compile:
    """Stands in for a kernel launch: compiles the kernel with the launch's argument types."""

    def __init__(self, name, fn, compiled):
        self.name, self.fn, self.compiled = name, fn, compiled

    def __getitem__(self, launch):
        import numba
        from numba import cuda

        def run(*args):
            sig = tuple(numba.typeof(np.asarray(a) if isinstance(a, np.ndarray) else a) for a in args)
            if self.name not in self.compiled:
                ptx, _ = cuda.compile_ptx(self.fn, sig, cc=(9, 0))
                # the driver compiles the PTX at the first launch: 3.9 MB of it (every call of the
                # large device functions inlined anew) took NVIDIA's ptxas over 2 minutes and 5 GB
                assert len(ptx) < MAX_PTX, f"{self.name}: {len(ptx)} bytes of PTX"
                self.compiled.append(self.name)
        return run


def test_every_cuda_kernel_compiles_for_a_gpu(monkeypatch):
    pytest.importorskip("numba_cuda", reason="the CUDA extra is not installed (pip install -e '.[cuda]')")
    if os.environ.get("NUMBA_ENABLE_CUDASIM") != "0":
        pytest.skip("compiles for a real GPU: NUMBA_ENABLE_CUDASIM=0")
    import numba.cuda.dispatcher as dispatcher
    from numba.cuda.cudadrv import nvvm

    try:
        nvvm.NVVM()
    except Exception as exc:  # noqa: BLE001 - not found, or not loadable: numba-cuda's versions differ
        pytest.skip(f"NVIDIA's NVVM library is not usable: {exc}")
    monkeypatch.setattr(dispatcher, "get_current_device",
                        lambda: SimpleNamespace(compute_capability=(9, 0)))  # no GPU: an H100
    import meshmill.kernels.cuda as mod

    compiled = []
    for name in dir(mod):
        k = getattr(mod, name)
        if type(k).__name__ == "CUDADispatcher" and not k.targetoptions.get("device", False):
            monkeypatch.setattr(mod, name, Compile(name, k.py_func, compiled))
    monkeypatch.setattr(mod.cuda, "to_device", lambda a: np.ascontiguousarray(a).view(Host))
    monkeypatch.setattr(mod.cuda, "device_array", lambda shape, dtype: np.zeros(shape, dtype).view(Host))

    m = post_with_fillet(arc_steps=4, segments=12)
    b = mod.to_device(build_bvh(m.vertices, m.faces))
    k = 8
    p = np.random.default_rng(0).uniform(-5, 5, (k, 3))
    body = (np.zeros((2, 3)), np.ones((2, 3)), np.ones((2, 3)))
    mod.mesh_distances(p, b)
    mod.largest_ball(p, p, np.array([3.0, 1.0]), 0.01, b)
    mod.axis_search(p, p, p, np.zeros(k, np.int64), np.zeros((3, 2)), np.zeros(3), 0.1, np.ones(2), body,
                    np.array([0, 4, 8]), b)
    rings = (np.zeros(2), np.zeros(2), np.ones(2), np.ones(2, np.int64))
    inside = mod.inside_to_device((*build_bvh(m.vertices, m.faces).arrays, np.ones(len(m.faces), np.int8), -5.0))
    mod.pose_penetration(p, p, np.zeros(k, np.int32), np.zeros(k), rings, body, body[0], b, inside)
    mod.intervals_clear(p, p, p, p, np.zeros(k, np.int32), np.zeros(k), np.ones(k), rings, body, body[0], b)
    mod.points_inside(p, inside)
    mod.drop_cutter(p[:, :2], 3.0, 1.0, -5.0, b, (np.ones(2), np.ones(2)))
    mod.touch_points(p[:, :2], p[:, :2], np.ones(k), -np.ones(k), 1.0, 3.0, 1.0, -5.0, b)
    mod.rays_blocked(p, np.array([0, 0, 1.0]), 1e-6, b)
    mod.cast_lines(0, 0.0, 0.0, 1.0, 2, 2, b)
    mv = (p, p, p, p, np.ones(k), np.ones(k), np.ones(k) * 4)
    mod.move_constants(p, p, p, p, np.ones(k), np.ones(k))
    mod.cut_tiles(0.0, 0.0, 1.0, 4, 4, np.zeros((10, 2)), np.arange(17), np.zeros(16, np.int64), np.array([0]),
                  np.array([0]), 1, np.array([0, 1]), np.array([0]), *mv, np.ones(k, np.int64), np.zeros((k, 6)), np.zeros((k, 4)),
                  np.zeros((k, 6)), np.zeros(k, np.uint8), np.zeros(k, np.int64) - 1, np.zeros((0, 10)), np.zeros((0, 6)),
                  1e-3, np.zeros(k, np.uint8), np.zeros(0, np.int64),
                  np.zeros(16, np.int64), 0,
                  np.zeros((k, 6)), np.zeros((1, k, 5)))
    kernels = sorted(n for n in dir(mod) if isinstance(getattr(mod, n), Compile))
    assert sorted(compiled) == kernels, set(kernels) - set(compiled)
    assert len(compiled) == 13, compiled
