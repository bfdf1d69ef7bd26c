"""Hot loops: device functions written once (geom, cutters) and their backends (cpu, cuda).

numba's on-disk cache checks only the source file of each cached function, not the device
functions it calls from other files, so a changed ``geom.py`` would leave stale machine code behind
``cpu.py``. The cache therefore lives in a folder named after a hash of this package's sources
(unless ``NUMBA_CACHE_DIR`` is set).
"""
import hashlib
import os
import sys

import numba


def _cache_dir():
    here = os.path.dirname(os.path.abspath(__file__))
    digest = hashlib.sha256()
    for name in sorted(os.listdir(here)):
        if name.endswith(".py"):
            with open(os.path.join(here, name), "rb") as fh:
                digest.update(name.encode() + fh.read())
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "meshmill", "numba-" + digest.hexdigest()[:16])


if not os.environ.get("NUMBA_CACHE_DIR"):
    numba.config.CACHE_DIR = _cache_dir()

# The threading layer of the parallel loops, pinned: GNU OpenMP where it loads, else numba's own
# workqueue; never the system's TBB, whose pool can keep a finished process from exiting (a core
# at 100 % after the result is written; numba #10556). An explicit NUMBA_THREADING_LAYER wins.
if not os.environ.get("NUMBA_THREADING_LAYER") and not os.environ.get("NUMBA_THREADING_LAYER_PRIORITY"):
    numba.config.THREADING_LAYER_PRIORITY = ["omp", "workqueue", "tbb"]


def _arraymath_without_blas_probe():
    """Import numba's array functions without their BLAS probe. When numba first compiles or
    loads a function it imports ``numba.np.arraymath``, which imports ``scipy.linalg`` only to
    learn whether ``np.correlate`` may call BLAS: 0.15 s of every command (5 % of a raster), for
    a function no kernel here calls. The probe finds no BLAS (that one function then loops
    itself); ``scipy.linalg`` stays importable, and ``np.dot`` and the like, which ask for BLAS
    when they are compiled, still find it."""
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return  # probed already, or scipy.linalg already paid for
    sys.modules["scipy.linalg.cython_blas"] = None  # an import of it raises ImportError
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        del sys.modules["scipy.linalg.cython_blas"]


_arraymath_without_blas_probe()
