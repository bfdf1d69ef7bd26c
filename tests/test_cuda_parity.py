"""The CUDA build of the kernels gives the CPU's answers (tests/cudasim, which says how exactly): run
in a fresh pytest process, since numba reads NUMBA_ENABLE_CUDASIM when it is imported. The
simulator unless the environment says otherwise: on a GPU machine, NUMBA_ENABLE_CUDASIM=0 runs the
same checks on the device."""
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.slow
def test_cuda_parity_checks_pass():
    env = dict(os.environ)
    env.setdefault("NUMBA_ENABLE_CUDASIM", "1")
    r = subprocess.run([sys.executable, "-m", "pytest", "tests/cudasim", "-q", "-p", "no:cacheprovider"],
                       cwd=ROOT, capture_output=True, text=True, env=env, timeout=1800)
    assert r.returncode == 0, r.stdout[-6000:] + r.stderr[-3000:]
