"""The CUDA build of the device functions gives the CPU's answers (numba's CUDA simulator, so it
runs on any machine; on a GPU machine the same check runs on the device)."""
import os
import subprocess
import sys
import textwrap

SCRIPT = textwrap.dedent("""
    import numpy as np
    from meshmill.geometry.bvh import build_bvh
    from meshmill.geometry.shapes import post_with_fillet
    from meshmill.geometry.slicing import slice_contours
    from meshmill.kernels import cpu, cuda as gpu

    m = post_with_fillet(arc_steps=6, segments=24)
    bvh = build_bvh(m.vertices, m.faces)
    con = slice_contours(m, np.array([2.0, 8.0]), 2.0, 0.3)
    radii = np.array([10.0, 5.0, 3.0, 1.0])
    dev = gpu.to_device(bvh)
    a = cpu.largest_ball(con.points, con.normals, radii, 0.01, bvh.arrays)
    b = gpu.largest_ball(con.points, con.normals, radii, 0.01, dev)
    assert (a == b).all(), (a, b)
    p = np.random.default_rng(0).uniform(-45, 45, (64, 3))
    d = np.abs(cpu.mesh_distances(p, bvh.arrays) - gpu.mesh_distances(p, dev)).max()
    assert d < 1e-12, d
    print("parity", len(a), "points")
""")


def run_cuda(script, marker):
    """Run ``script`` in a fresh interpreter with numba's CUDA target (the simulator unless the
    environment says otherwise) and check it printed ``marker``."""
    env = dict(os.environ)
    env.setdefault("NUMBA_ENABLE_CUDASIM", "1")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert marker in r.stdout


def test_cuda_build_matches_cpu():
    run_cuda(SCRIPT, "parity")


DEXEL_SCRIPT = textwrap.dedent("""
    import numpy as np
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box, sphere
    from meshmill.simulation.dexel import dexelize

    rng = np.random.default_rng(2)
    s = sphere(5.0, rings=6, segments=10)
    parts = [box((0, 0, 0), (4, 3, 2)), mesh_from_arrays(s.vertices + rng.uniform(-1, 1, 3), s.faces, "s")]
    for m in parts:
        a = dexelize(m, 1.0)
        b = dexelize(m, 1.0, device="cuda")
        for k in range(3):
            assert np.array_equal(a.start[k], b.start[k]), k
            assert np.array_equal(a.iv[k], b.iv[k]), k
    print("dexel parity", sum(len(v) for v in a.iv), "dexels")
""")


def test_cuda_dexel_casting_matches_cpu():
    run_cuda(DEXEL_SCRIPT, "dexel parity")
