"""The CUDA build of the kernels gives the CPU's answers, bit for bit: numba's CUDA simulator runs
the same device functions on any machine. Inputs are small: the simulator interprets every thread
in Python. On a GPU machine, NUMBA_ENABLE_CUDASIM=0 runs the same checks on the device; there NVVM
fuses multiply-adds and libdevice's sin/cos may differ in the last bit, so coordinates are compared
within 1e-6 mm (discrete answers, such as which ball fits, must still agree)."""
import os

import numpy as np

EXACT = os.environ.get("NUMBA_ENABLE_CUDASIM", "1") != "0"


def same(a, b):
    """``a`` and ``b`` agree: bit for bit in the simulator, floats within 1e-6 mm on a GPU."""
    a, b = np.asarray(a), np.asarray(b)
    if EXACT or a.dtype.kind in "biu":
        return np.array_equal(a, b, equal_nan=True)
    return a.shape == b.shape and np.allclose(a, b, rtol=0.0, atol=1e-6, equal_nan=True)


def close(a, b):
    """As :func:`same`, but floats within 1e-12 mm in the simulator: a drop-cutter run in other
    chunks (the GPU's are smaller) may take an equal-height contact from the other triangle of an
    edge, a last-bit difference."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind in "biu" or not EXACT:
        return same(a, b)
    return a.shape == b.shape and np.allclose(a, b, rtol=0.0, atol=1e-12, equal_nan=True)


def polyline_gap(a, b):
    """The largest distance (mm) from a point of ``a (n, 3)`` to the polyline through ``b (m, 3)``."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if len(b) < 2:
        b = np.concatenate([b, b])  # one point: a segment of length zero
    p, q = b[:-1], b[1:]
    d = q - p
    t = np.einsum("ijk,jk->ij", a[:, None, :] - p[None], d) / np.maximum(np.einsum("jk,jk->j", d, d), 1e-300)
    foot = p[None] + np.clip(t, 0.0, 1.0)[..., None] * d[None]
    return float(np.linalg.norm(a[:, None, :] - foot, axis=2).min(axis=1).max())


def same_tips(a, b, tol):
    """The tips of two paths agree: as :func:`close` in the simulator; on a GPU, where a last-bit
    difference may break a tie of the host's refinement otherwise (other vertices on the same
    curve: seen on a real H200 in a waterline, 2.6e-3 mm apart), each path's tips lie within
    ``tol`` mm (the operation's tolerance) of the other's polyline. The kernels themselves are
    compared within 1e-6 mm (test_parity_kernels)."""
    if close(a, b):
        return True
    return not EXACT and max(polyline_gap(a, b), polyline_gap(b, a)) <= tol
