"""Which backend runs the kernels: ``cpu``, ``cuda``, or ``auto`` (CUDA when numba sees a usable
GPU, else the CPU). The CUDA module is imported only when chosen."""
from __future__ import annotations

from ..errors import InputError

DEVICES = ("cpu", "cuda", "auto")


def cuda_available() -> bool:
    try:
        from numba import cuda

        return bool(cuda.is_available())
    except Exception:  # numba-cuda missing or broken: no GPU for us
        return False


def resolve(device: str) -> str:
    """``"cpu"`` or ``"cuda"`` for a ``--device`` value (raises :class:`InputError`)."""
    if device not in DEVICES:
        raise InputError(f"--device must be one of {', '.join(DEVICES)}, got '{device}'")
    if device == "cpu":
        return "cpu"
    if cuda_available():
        return "cuda"
    if device == "cuda":
        raise InputError("--device cuda: no usable CUDA GPU (numba.cuda.is_available() is false); "
                         "use --device cpu or auto")
    return "cpu"
