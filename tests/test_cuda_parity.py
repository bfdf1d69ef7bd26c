"""The CUDA build of the kernels gives the CPU's answers, bit for bit: numba's CUDA simulator runs
the same device functions on any machine. Inputs are small: the simulator interprets every thread
in Python. On a GPU machine, NUMBA_ENABLE_CUDASIM=0 runs the same checks on the device; there NVVM
fuses multiply-adds and libdevice's sin/cos may differ in the last bit, so coordinates are compared
within 1e-6 mm (discrete answers, such as which ball fits, must still agree)."""
import os
import subprocess
import sys
import textwrap

SAME = textwrap.dedent("""
    import os
    import numpy as np

    EXACT = os.environ.get("NUMBA_ENABLE_CUDASIM", "1") != "0"


    def same(a, b):
        a, b = np.asarray(a), np.asarray(b)
        if EXACT or a.dtype.kind in "biu":
            return np.array_equal(a, b, equal_nan=True)
        return a.shape == b.shape and np.allclose(a, b, rtol=0.0, atol=1e-6, equal_nan=True)


    def close(a, b):
        # as same, but floats within 1e-12 mm in the simulator: a drop-cutter run in other chunks
        # (the GPU's are smaller) may take an equal-height contact from the other triangle of an
        # edge, a last-bit difference
        a, b = np.asarray(a), np.asarray(b)
        if a.dtype.kind in "biu" or not EXACT:
            return same(a, b)
        return a.shape == b.shape and np.allclose(a, b, rtol=0.0, atol=1e-12, equal_nan=True)
""")

KERNELS = SAME + textwrap.dedent("""
    import numpy as np
    from meshmill.geometry.bvh import build_bvh
    from meshmill.geometry.shapes import post_with_fillet
    from meshmill.geometry.slicing import slice_contours
    from meshmill.kernels import cpu, cuda
    from meshmill.kernels.backend import MeshKernels

    m = post_with_fillet(arc_steps=6, segments=24)
    bvh = build_bvh(m.vertices, m.faces)
    c, g = MeshKernels(bvh, "cpu"), MeshKernels(bvh, "cuda")
    con = slice_contours(m, np.array([0.0, 2.0, 8.0]), 2.0, 0.3)  # z = 0: exactly on the plate's flat top
    radii = np.array([10.0, 5.0, 3.0, 1.0])
    assert np.array_equal(c.largest_ball(con.points, con.normals, radii, 0.01),
                          g.largest_ball(con.points, con.normals, radii, 0.01))
    rng = np.random.default_rng(0)
    p = rng.uniform(-45, 45, (64, 3))
    assert same(c.mesh_distances(p), g.mesh_distances(p))
    # drop-cutter on grid lines through the axis and the plate's edge (x = 0, y = 40), a bull-nose with body
    xs = np.linspace(-45, 45, 19)
    xy = np.array([(x, y) for x in xs for y in (0.0, 40.0, 13.7)])
    body = (np.array([8.0, 16.0]), np.array([20.0, 40.0]))
    for R, r in ((3.0, 1.0), (4.0, 4.0), (5.0, 0.0)):
        zc, cc = c.drop_cutter(xy, R, r, -10.0, body)
        zg, cg = cuda.drop_cutter(xy, R, r, -10.0, g.mesh, body, chunk=cpu.CHUNK)
        assert same(zc, zg) and same(cc, cg), (R, r)
        assert same(zc, g.drop_cutter(xy, R, r, -10.0, body)[0])  # the GPU's own chunks
    # touch points between points above and below z = 10 (the post's wall is at radius 10)
    inside = np.column_stack([np.zeros(12), np.linspace(-9, 9, 12)])
    ang = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    outside = 30.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    fi = c.drop_cutter(inside, 3.0, 1.0, -10.0)[0] - 10.0
    fo = c.drop_cutter(outside, 3.0, 1.0, -10.0)[0] - 10.0
    args = (inside, outside, fi, fo, 10.0, 3.0, 1.0, -10.0, 1e-6, 1e-4, 80)
    assert same(c.touch_points(*args), g.touch_points(*args))
    # rays: from every vertex (some on the plate's top, some under the post) straight up
    for d in ((0.0, 0.0, 1.0), (0.6, 0.0, 0.8)):
        assert np.array_equal(c.rays_blocked(m.vertices, np.array(d), 1e-6), g.rays_blocked(m.vertices, np.array(d), 1e-6))
    # the certified checks: poses measured, intervals certified, points inside the solid
    from meshmill.kernels.backend import solid_kernels
    from meshmill.tools.table import pack_cylinders, pack_rings, tool_from_entry
    sc, sg = solid_kernels(m, "cpu"), solid_kernels(m, "cuda")
    tools = [tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=10, gauge_length=30,
                                  holder_diameter=20, holder_length=20), 1, "t"),
             tool_from_entry(dict(name="R8", type="bull", diameter=8, corner_radius=2, flute_length=10,
                                  gauge_length=30), 2, "t")]
    (t0, t1, r), _ = pack_cylinders(tools)
    rings = pack_rings(tools)
    n = 48
    ta = np.column_stack([rng.uniform(-15, 15, (n, 2)), rng.uniform(-1, 12, n)])
    tb = ta + rng.normal(scale=0.7, size=(n, 3))
    xa = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), np.ones(n)])
    xa /= np.linalg.norm(xa, axis=1, keepdims=True)
    xb = xa + rng.normal(scale=0.03, size=(n, 3))
    xb /= np.linalg.norm(xb, axis=1, keepdims=True)
    tool = rng.integers(0, 2, n)
    grow = np.where(rng.random(n) < 0.3, 0.5, 0.0)
    ra, sa = sc.pose_penetration(ta, xa, tool, grow, rings, (t0, t1, r), t0)
    rb, sb = sg.pose_penetration(ta, xa, tool, grow, rings, (t0, t1, r), t0)
    assert same(ra, rb) and same(sa, sb)
    lim = np.full(n, 0.01)
    ca = sc.intervals_clear(ta, xa, tb, xb, tool, grow, lim, rings, (t0, t1, r), t0)
    assert np.array_equal(ca, sg.intervals_clear(ta, xa, tb, xb, tool, grow, lim, rings, (t0, t1, r), t0))
    assert ca.any() and (~ca).any()
    assert np.array_equal(sc.points_inside(ta), sg.points_inside(ta))
    print("kernel parity")
""")

CUT = SAME + textwrap.dedent("""
    import numpy as np
    from meshmill.geometry.shapes import box
    from meshmill.simulation import cut as cutting
    from meshmill.simulation.dexel import dexelize
    from meshmill.toolpath.model import Toolpath

    # no spare room: the slots split lines, so tiles overflow, grow and run again
    cutting.SLACK = 0
    model = dexelize(box((0, 0, 0), (12, 10, 6)), 1.0)

    class T:
        def __init__(self, type, d, r):
            self.type, self.radius, self.corner_radius, self.flute_length, self.name = type, d / 2, r, 8.0, type

    tools = [T("ball", 2.0, 1.0), T("bull", 3.0, 0.5), T("flat", 2.0, 0.0)]
    # ball moves (one turning), then a bull-nose and a flat end mill, each with one small turn
    tip = np.array([[2.0, 2.0, 4.0], [10.0, 2.0, 4.0], [10.0, 8.0, 3.0], [2.0, 8.0, 3.5], [2.0, 5.0, 5.0],
                    [4.0, 5.0, 5.0], [6.0, 6.0, 4.5], [8.0, 6.0, 4.5]])
    axis = np.array([[0, 0, 1.0], [0, 0, 1.0], [0.3, 0, 0.95], [0, 0, 1.0], [0, 0, 1.0], [0.05, 0, 1.0],
                     [0, 0, 1.0], [0, 0.05, 1.0]])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    rapid = np.array([True, False, False, False, True, False, True, False])
    tp = Toolpath(tip, axis, rapid, np.array([0, 0, 0, 0, 1, 1, 2, 2]))
    from meshmill.tools.table import tool_from_entry
    # the shanks (as wide as the cutters) meet the stock where the tools go deep
    real = [tool_from_entry(dict(name=t.type, type=t.type, diameter=2 * t.radius, corner_radius=t.corner_radius,
                                 flute_length=2.0, gauge_length=9.0), k + 1, "t") for k, t in enumerate(tools)]
    moves = cutting.Moves.merge(cutting.toolpath_moves(tp, tools), cutting.body_moves(tp, real))
    stocks = []
    for device in ("cpu", "cuda"):
        st = cutting.stock_from_model(model)
        res = cutting.cut(st, moves, device=device)
        stocks.append((st.to_model(), (res["rapid_cuts"], res["collisions"])))
    (a, ra), (b, rb) = stocks
    assert ra == rb and ra[1], (ra, rb)
    for k in range(3):
        assert same(a.start[k], b.start[k]) and same(a.iv[k], b.iv[k]), k
    assert sum(len(v) for v in a.iv) > sum(len(v) for v in model.iv)  # the slots split dexels
    print("cut parity", len(moves), "moves")
""")

DEXEL = SAME + textwrap.dedent("""
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
            assert same(a.start[k], b.start[k]), k
            assert same(a.iv[k], b.iv[k]), k
    print("dexel parity", sum(len(v) for v in a.iv), "dexels")
""")

OPERATIONS = SAME + textwrap.dedent("""
    import os
    import numpy as np
    import meshmill
    from meshmill.geometry.shapes import post_with_fillet
    from meshmill.tools.table import load_tools
    from meshmill.ops.finish import FinishParams, finish
    from meshmill.ops.raster import RasterParams, raster
    from meshmill.ops.waterline import WaterlineParams, waterline
    from meshmill.ops.plunge import PlungeParams, plunge3
    from meshmill.ops.simulate import simulate

    import meshmill.ops.finish, meshmill.ops.plunge, meshmill.ops.raster, meshmill.ops.waterline
    tools = load_tools(os.path.join(os.path.dirname(meshmill.__file__), "data", "tools.toml"))
    m = post_with_fillet(post_radius=4.0, fillet=3.0, height=10.0, plate_radius=12.0, plate_thickness=2.0,
                         arc_steps=3, segments=12)
    # the verification certifies every interval whatever the first poses' spacing: far apart, fewer
    # intervals for the simulator to interpret (the same answers, found by halving)
    for op in (meshmill.ops.finish, meshmill.ops.plunge, meshmill.ops.raster, meshmill.ops.waterline):
        op.DEFAULT_STEP = 20.0
    runs = {
        "finish": lambda dev: finish(m, tools, FinishParams(step_down=5.0, sample=4.0, tilt_step=30, max_tilt=60),
                                     device=dev),
        "raster": lambda dev: raster(m, tools, "B10", RasterParams(stepover=8.0, scallop=None, angle=30.0, sample=5.0),
                                     device=dev),
        "waterline": lambda dev: waterline(m, tools, "B10", WaterlineParams(step_down=6.0, sample=4.0), device=dev),
        "plunge": lambda dev: plunge3(m, tools, "B10", PlungeParams(radial_step=6.0, engagement=6.0, allowance=1.0,
                                                                   device=dev)),
    }
    if EXACT:  # the simulator interprets every thread: finish and plunge (raster's and waterline's
        # drop-cutter and touch kernels are compared in the kernel test); a GPU runs all four
        runs = {k: runs[k] for k in ("finish", "plunge")}
    paths = {}
    for name, run in runs.items():
        (a, sa, *_), (b, sb, *_) = run("cpu"), run("cuda")
        assert len(a) > 20, name
        for f in ("tip", "axis", "tool", "rapid"):
            assert close(getattr(a, f), getattr(b, f)), (name, f)
        va, vb = sa["verify"], sb["verify"]
        assert va.keys() == vb.keys() and va["ok"] == vb["ok"], name
        assert all(close(va[k], vb[k]) for k in va if not isinstance(va[k], (list, dict, str))), name
        paths[name] = a
    # a 3-axis path, and on a GPU a turning ball-end one (the simulator would take minutes over its
    # holder's sweep; the cut test compares shank and holder moves)
    for name in ("plunge",) if EXACT else ("finish", "plunge"):
        x, y = (simulate(m, paths[name], tools, 2.0, device=dev) for dev in ("cpu", "cuda"))
        assert not EXACT or x[0] == y[0], name
        for k in range(3):
            assert same(x[2].start[k], y[2].start[k]) and same(x[2].iv[k], y[2].iv[k]), name
    print("operation parity")
""")


def run_cuda(script, marker):
    """Run ``script`` in a fresh interpreter with numba's CUDA target (the simulator unless the
    environment says otherwise) and check it printed ``marker``."""
    env = dict(os.environ)
    env.setdefault("NUMBA_ENABLE_CUDASIM", "1")
    r = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    assert marker in r.stdout


def test_cuda_kernels_match_cpu():
    run_cuda(KERNELS, "kernel parity")


def test_cuda_cutting_matches_cpu_through_overflow():
    run_cuda(CUT, "cut parity")


def test_cuda_dexel_casting_matches_cpu():
    run_cuda(DEXEL, "dexel parity")


def test_cuda_operations_match_cpu():
    run_cuda(OPERATIONS, "operation parity")
