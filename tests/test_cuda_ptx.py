"""Every CUDA kernel compiles for a real GPU (tests/cudasim/test_ptx.py, which says why and what it
needs): run in a fresh pytest process with NUMBA_ENABLE_CUDASIM=0, since numba reads it when it is
imported."""
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.slow
def test_every_cuda_kernel_compiles_for_a_gpu():
    pytest.importorskip("numba_cuda", reason="the CUDA extra is not installed (pip install -e '.[cuda]')")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="0")
    r = subprocess.run([sys.executable, "-m", "pytest", "tests/cudasim/test_ptx.py", "-q", "-rs", "-p",
                        "no:cacheprovider"], cwd=ROOT, capture_output=True, text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stdout[-6000:] + r.stderr[-3000:]
    skipped = [line for line in r.stdout.splitlines() if line.startswith("SKIPPED")]
    if skipped:
        pytest.skip(skipped[0].split(": ", 1)[-1])
