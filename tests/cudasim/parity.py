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
