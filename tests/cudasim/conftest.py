"""The CUDA checks: numba reads NUMBA_ENABLE_CUDASIM (1: its CUDA simulator, 0: a GPU) when it is
imported, so the main run leaves this folder out (tests/conftest.py) and tests/test_cuda_parity.py
and tests/test_cuda_ptx.py run it in a fresh process with the variable set."""
import os

import pytest


@pytest.fixture(autouse=True)
def _cuda_target():
    if "NUMBA_ENABLE_CUDASIM" not in os.environ:
        pytest.skip("set NUMBA_ENABLE_CUDASIM (1: numba's CUDA simulator, 0: a GPU) before numba is imported")
