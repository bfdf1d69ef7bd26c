"""Each CUDA kernel against the CPU's, on a post with a fillet on a plate."""
import numpy as np
import pytest
from parity import same

from meshmill.geometry.shapes import post_with_fillet
from meshmill.geometry.slicing import slice_contours
from meshmill.kernels import cpu, cuda
from meshmill.kernels.backend import MeshKernels, solid_kernels
from meshmill.kernels.bvh import build_bvh
from meshmill.tools.table import pack_cylinders, pack_rings, tool_from_entry


@pytest.fixture(scope="module")
def part():
    return post_with_fillet(arc_steps=6, segments=24)


@pytest.fixture(scope="module")
def kernels(part):
    """``(cpu, cuda)`` mesh kernels of the part."""
    bvh = build_bvh(part.vertices, part.faces)
    return MeshKernels(bvh, "cpu"), MeshKernels(bvh, "cuda")


@pytest.fixture(scope="module")
def solids(part):
    """``(cpu, cuda)`` solid kernels of the part: the certified checks (poses measured, intervals
    certified, points inside the solid)."""
    return solid_kernels(part, "cpu"), solid_kernels(part, "cuda")


@pytest.fixture(scope="module")
def samples():
    """Random points, then pose pairs ``(ta, xa, tb, xb, tool, grow)``, from one generator."""
    rng = np.random.default_rng(0)
    points = rng.uniform(-45, 45, (64, 3))
    n = 48
    ta = np.column_stack([rng.uniform(-15, 15, (n, 2)), rng.uniform(-1, 12, n)])
    tb = ta + rng.normal(scale=0.7, size=(n, 3))
    xa = np.column_stack([rng.uniform(-0.3, 0.3, (n, 2)), np.ones(n)])
    xa /= np.linalg.norm(xa, axis=1, keepdims=True)
    xb = xa + rng.normal(scale=0.03, size=(n, 3))
    xb /= np.linalg.norm(xb, axis=1, keepdims=True)
    tool = rng.integers(0, 2, n)
    grow = np.where(rng.random(n) < 0.3, 0.5, 0.0)
    return points, (ta, xa, tb, xb, tool, grow)


@pytest.fixture(scope="module")
def shapes():
    """``(rings, cylinders)`` of a ball with a holder and a bull-nose without."""
    tools = [tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=10, gauge_length=30,
                                  holder_diameter=20, holder_length=20), 1, "t"),
             tool_from_entry(dict(name="R8", type="bull", diameter=8, corner_radius=2, flute_length=10,
                                  gauge_length=30), 2, "t")]
    (t0, t1, r), _ = pack_cylinders(tools)
    return pack_rings(tools), (t0, t1, r)


def test_largest_ball(part, kernels):
    c, g = kernels
    con = slice_contours(part, np.array([0.0, 2.0, 8.0]), 2.0, 0.3)  # z = 0: exactly on the plate's flat top
    radii = np.array([10.0, 5.0, 3.0, 1.0])
    assert np.array_equal(c.largest_ball(con.points, con.normals, radii, 0.01),
                          g.largest_ball(con.points, con.normals, radii, 0.01))


def test_mesh_distances(kernels, samples):
    c, g = kernels
    p = samples[0]
    assert same(c.mesh_distances(p), g.mesh_distances(p))


@pytest.mark.parametrize("R, r", [(3.0, 1.0), (4.0, 4.0), (5.0, 0.0)])
def test_drop_cutter(kernels, R, r):
    # grid lines through the axis and the plate's edge (x = 0, y = 40), a bull-nose with body
    c, g = kernels
    xs = np.linspace(-45, 45, 19)
    xy = np.array([(x, y) for x in xs for y in (0.0, 40.0, 13.7)])
    body = (np.array([8.0, 16.0]), np.array([20.0, 40.0]))
    zc, cc = c.drop_cutter(xy, R, r, -10.0, body)
    zg, cg = cuda.drop_cutter(xy, R, r, -10.0, g.mesh, body, chunk=cpu.CHUNK)
    assert same(zc, zg) and same(cc, cg)
    assert same(zc, g.drop_cutter(xy, R, r, -10.0, body)[0])  # the GPU's own chunks


def test_touch_points(kernels):
    # between points above and below z = 10 (the post's wall is at radius 10)
    c, g = kernels
    inside = np.column_stack([np.zeros(12), np.linspace(-9, 9, 12)])
    ang = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    outside = 30.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    fi = c.drop_cutter(inside, 3.0, 1.0, -10.0)[0] - 10.0
    fo = c.drop_cutter(outside, 3.0, 1.0, -10.0)[0] - 10.0
    args = (inside, outside, fi, fo, 10.0, 3.0, 1.0, -10.0, 1e-6, 1e-4, 80)
    assert same(c.touch_points(*args), g.touch_points(*args))


@pytest.mark.parametrize("direction", [(0.0, 0.0, 1.0), (0.6, 0.0, 0.8)])
def test_rays_blocked(part, kernels, direction):
    # from every vertex (some on the plate's top, some under the post)
    c, g = kernels
    d = np.array(direction)
    assert np.array_equal(c.rays_blocked(part.vertices, d, 1e-6), g.rays_blocked(part.vertices, d, 1e-6))


def test_pose_penetration(solids, samples, shapes):
    sc, sg = solids
    ta, xa, _, _, tool, grow = samples[1]
    rings, cyl = shapes
    ra, sa = sc.pose_penetration(ta, xa, tool, grow, rings, cyl, cyl[0])
    rb, sb = sg.pose_penetration(ta, xa, tool, grow, rings, cyl, cyl[0])
    assert same(ra, rb) and same(sa, sb)


def test_intervals_clear(solids, samples, shapes):
    sc, sg = solids
    ta, xa, tb, xb, tool, grow = samples[1]
    rings, cyl = shapes
    lim = np.full(len(ta), 0.01)
    ca = sc.intervals_clear(ta, xa, tb, xb, tool, grow, lim, rings, cyl, cyl[0])
    assert np.array_equal(ca, sg.intervals_clear(ta, xa, tb, xb, tool, grow, lim, rings, cyl, cyl[0]))
    assert ca.any() and (~ca).any()


def test_points_inside(solids, samples):
    sc, sg = solids
    ta = samples[1][0]
    assert np.array_equal(sc.points_inside(ta), sg.points_inside(ta))


def test_staged_buffers_are_reused_and_hold_each_call_alone(kernels, samples):
    # calls of one kernel, larger then smaller then larger again: each gives the CPU's answers
    # (no values left from the call before), and the second and third reuse the first's buffers
    a, b = kernels
    p = samples[0]
    for k, n in enumerate((len(p), len(p) // 3, len(p))):
        assert same(a.mesh_distances(p[:n]), b.mesh_distances(p[:n]))
        if k == 0:
            held = dict(cuda.STAGE.bufs)
    assert all(cuda.STAGE.bufs[key] is buf for key, buf in held.items())
    small = cuda.STAGE.put("test", np.arange(4.0))
    assert same(small.copy_to_host(), np.arange(4.0)) and same(cuda.STAGE.put("test", [7.0]).copy_to_host(), [7.0])
