"""raster and waterline operations: paths that touch without gouging, robust Z levels, peers."""
import math

import numpy as np
import pytest

from meshmill.errors import InputError, NothingToCut
from meshmill.kernels.bvh import build_bvh
from meshmill.geometry.mesh import load_mesh
from meshmill.geometry.shapes import box, revolve, sphere
from meshmill.pathing.dropcutter import ToolDrop
from meshmill.ops.raster import RasterParams, raster
from meshmill.pathing.scallop import stepover as stepover_for_scallop
from meshmill.ops.waterline import WaterlineParams, waterline
from meshmill.simulation.stock import Stock
from meshmill.tools.table import tool_from_entry

PARTS = __import__("pathlib").Path(__file__).resolve().parents[2] / "shared" / "parts"


@pytest.fixture
def cutters():
    return [tool_from_entry(dict(name="F6", type="flat", diameter=6, flute_length=20, gauge_length=40), 1, "t"),
            tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=20, gauge_length=40), 2, "t"),
            tool_from_entry(dict(name="R6", type="bull", diameter=6, corner_radius=1, flute_length=20,
                                 gauge_length=40, holder_diameter=30, holder_length=30), 3, "t")]


def test_scallop_stepover():
    # seed 002's numbers: ball R 5, scallop 0.01 mm -> 0.6321 mm
    assert abs(stepover_for_scallop(0.01, 5.0) - 0.6321) < 1e-4


@pytest.mark.parametrize("name", ["F6", "B6", "R6"])
def test_raster_on_a_block(cutters, name):
    m = box([0, 0, 0], [30, 20, 10])
    tp, s = raster(m, cutters, name, RasterParams(stepover=2.0, angle=30.0))
    assert s["verify"]["ok"]
    cut = tp.tip[~tp.rapid]
    tool = next(t for t in cutters if t.name == name)
    drop = ToolDrop(tool, build_bvh(m.vertices, m.faces), 0.0)
    assert np.abs(drop(cut[:, :2]) - cut[:, 2]).max() < 1e-12  # every CL point is a dropped position
    assert cut[:, 2].max() == 10.0 and cut[:, 2].min() == 0.0  # on the top, and down to the bottom
    assert s["cl_points"] < s["cl_points_dropped"]  # collinear points removed


def test_raster_with_scallop_on_a_sphere(cutters):
    m = sphere(15.0, 48, 96)
    tp, s = raster(m, cutters, "B6", RasterParams(scallop=0.01))
    assert abs(s["stepover"] - stepover_for_scallop(0.01, 3.0)) < 1e-12 and s["stepover_used"] <= s["stepover"]
    assert s["verify"]["ok"]


def test_bad_raster_parameters(cutters):
    m = box([0, 0, 0], [10, 10, 10])
    with pytest.raises(InputError, match="flat"):
        raster(m, cutters, "F6", RasterParams(scallop=0.01))
    with pytest.raises(InputError, match="no tool named"):
        raster(m, cutters, "X", RasterParams(stepover=1))
    with pytest.raises(InputError, match="exactly one"):
        RasterParams.checked(dict(part=m, tools=cutters, tool="B6", stepover=1, scallop=0.1))


def _touching(drop, passes, tol=1e-6, wall=1e-4):
    """Every pass point keeps the drop height at or below its level, and touches: the height is within
    tol of z, or a step of `wall` mm toward the material rises above z (a vertical wall)."""
    for z, p in passes:
        h = drop(p[:, :2])
        assert np.all(h <= z + 1e-9)
        loose = np.nonzero(h < z - tol)[0]
        if len(loose):
            q = p[loose, :2]
            # probe around each loose point: some direction within `wall` must gouge
            ang = np.linspace(0, 2 * np.pi, 16, endpoint=False)
            probes = (q[:, None, :] + wall * np.stack([np.cos(ang), np.sin(ang)], 1)[None]).reshape(-1, 2)
            hp = drop(probes).reshape(len(q), -1)
            assert np.all(hp.max(axis=1) > z), (z, q[hp.max(axis=1) <= z][:3])


@pytest.mark.parametrize("name", ["F6", "B6", "R6"])
def test_waterline_loops_touch_without_gouging(cutters, name):
    m = revolve([0, 12, 12, 6, 4, 4, 0], [0, 0, 4, 8, 12, 16, 16], 48)  # foot, cone, post
    tp, s, passes = waterline(m, cutters, name, WaterlineParams(step_down=2.0, sample=0.4))
    assert s["verify"]["ok"] and s["closed_loops"] == s["passes"] == s["levels"]
    tool = next(t for t in cutters if t.name == name)
    _touching(ToolDrop(tool, build_bvh(m.vertices, m.faces), -1.0), passes)
    # one loop per level around the axis, its radius as the geometry says: at z = 14 the centre of
    # B6 is 1 mm above the post's top edge (radius 4, a 48-gon), which it touches sqrt(9 - 1) out
    if name == "B6":
        z, p = passes[0]
        assert z == 14.0
        assert np.allclose(np.hypot(p[:, 0], p[:, 1]), 4 * math.cos(math.pi / 48) + math.sqrt(8), atol=0.02)


def test_waterline_at_a_flat_facet_is_clean(cutters):
    # the step face of a stepped cylinder lies exactly on a level
    m = revolve([0, 20, 20, 10, 10, 0], [0, 0, 10, 10, 20, 20], 48)
    tp, s, passes = waterline(m, cutters, "F6", WaterlineParams(step_down=5.0, sample=0.5))
    assert [z for z, _ in passes] == [15.0, 10.0, 5.0]
    assert all(len(p) > 20 for _, p in passes) and s["verify"]["ok"]
    r = [np.hypot(p[:, 0], p[:, 1]).mean() for _, p in passes]
    assert abs(r[0] - 13.0) < 0.05 and abs(r[1] - 13.0) < 0.05 and abs(r[2] - 23.0) < 0.05


def test_waterline_again_in_one_process(cutters):
    m = sphere(10.0, 24, 48)
    runs = [waterline(m, cutters, "B6", WaterlineParams(step_down=3.0, sample=0.5))[2] for _ in range(3)]
    for other in runs[1:]:
        assert len(other) == len(runs[0])
        assert all(np.array_equal(a[1], b[1]) for a, b in zip(runs[0], other))


ocl = pytest.importorskip("opencamlib", reason="OpenCAMLib is a test-only peer")


@pytest.mark.parametrize("part, frac", [("pycam-textbox", 0.7), ("sphere_on_plate", 0.37), ("beet_mm", 0.45)])
@pytest.mark.slow
def test_waterline_near_opencamlib(cutters, part, frac):
    path = PARTS / f"{part}.stl"
    if not path.exists():
        pytest.skip("shared parts not present")
    m = load_mesh(path, flip=part == "beet_mm")  # beet_mm is wound inside out
    lo, hi = m.bounds[:, 2]
    z = float(np.round(lo + frac * (hi - lo), 3))
    sampling = 0.2
    surf = ocl.STLSurf()
    ocl.STLReader(str(path), surf)
    ball = ocl.BallCutter(6, 40)  # kept alive: OpenCAMLib holds a bare pointer to it
    wl = ocl.Waterline()
    wl.setSTL(surf)
    wl.setCutter(ball)
    wl.setZ(z)
    wl.setSampling(sampling)
    wl.run()
    theirs = np.array([[p.x, p.y] for loop in wl.getLoops() if len(loop) > 10 for p in loop])
    # our level set at z: a step-down that puts a level exactly at z
    tp, s, passes = waterline(m, cutters, "B6", WaterlineParams(step_down=hi - z, sample=sampling))
    from scipy.spatial import cKDTree

    def dense(p, step=0.02):  # our simplified polylines, resampled to compare with their points
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        t = np.concatenate([[0], np.cumsum(seg)])
        s = np.linspace(0, t[-1], max(2, int(t[-1] / step) + 1))
        return np.column_stack([np.interp(s, t, p[:, 0]), np.interp(s, t, p[:, 1])])

    ours = np.vstack([dense(p[:, :2]) for lz, p in passes if abs(lz - z) < 1e-9])

    d_ours = cKDTree(theirs).query(ours)[0]
    d_theirs = cKDTree(ours).query(theirs)[0]
    # each of our points lies near their loops and theirs near ours, within the sampling distance
    assert np.percentile(d_ours, 99) < sampling and np.percentile(d_theirs, 99) < sampling


def _box_distance_xy(xy, lo, hi):
    """Horizontal distance from points ``(k, 2)`` to the box ``[lo, hi]`` (xy)."""
    d = np.maximum(np.maximum(lo - xy, xy - hi), 0.0)
    return np.hypot(d[:, 0], d[:, 1])


def test_raster_keeps_the_holder_out_of_the_allowance(cutters):
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.pathing.verify import StockCheck, verify_toolpath

    # a plate with a tower much taller than R6's gauge length (holder radius 15 from 40 mm up)
    plate, tower = box([0, 0, 0], [60, 40, 2]), box([25, 15, 0], [35, 25, 70])
    m = mesh_from_arrays(np.vstack([plate.vertices, tower.vertices]),
                         np.vstack([plate.faces, tower.faces + len(plate.vertices)]), "plate and tower")
    lo, hi = np.array([25.0, 15.0]), np.array([35.0, 25.0])
    near = {}
    for allowance in (0.0, 0.5):
        tp, s = raster(m, cutters, "R6", RasterParams(stepover=2.0, sample=0.25, stock=Stock.offset(allowance)))
        assert s["verify"]["ok"]
        low = tp.tip[~tp.rapid & (tp.tip[:, 2] < 70 - 40 - 1e-6)]
        near[allowance] = _box_distance_xy(low[:, :2], lo, hi).min()
        r = verify_toolpath(m, tp, cutters, stock=StockCheck(allowance=0.5, clearance=0.5))
        assert (r["colliding_moves"] == 0) == (allowance == 0.5)
        if allowance == 0.0:
            assert "holder (in the stock)" in " ".join(r["worst"])
    # the holder (radius 15) keeps out of the allowance, and half the tolerance (0.01) more
    assert 15.005 - 1e-9 <= near[0.0] < 15.5 and 15.505 - 1e-9 <= near[0.5]


def test_rest_raster_cuts_only_where_the_stock_has_material(cutters):
    """A box whose stock holds material above it only over a 10 mm square: with --rest the raster
    keeps the pieces of its passes near the square, and removes from the stock what the whole
    raster removes (simulated: an independent check that no piece in material was left out)."""
    from meshmill.ops.simulate import simulate

    design = box((0, 0, 0), (40, 40, 10))
    stock = box((10, 10, 0), (20, 20, 13))
    tools = [cutters[1]]
    full, _ = raster(design, tools, "B6", RasterParams(stepover=1.0, sample=0.5, stock=stock))
    rest, summary = raster(design, tools, "B6", RasterParams(stepover=1.0, sample=0.5, rest=0.05, stock=stock))
    assert summary["verify"]["ok"] and summary["rest"]["runs"] > 5
    feed = rest.tip[~rest.rapid]
    reach = 3.0 + 3.0 + 0.5 + 1e-9  # the cutter's radius, the margin, a sample
    assert (feed[:, :2] >= 10 - reach).all() and (feed[:, :2] <= 20 + reach).all()
    assert rest.cutting_length() < 0.2 * full.cutting_length()
    _, s_full, *_ = simulate(design, full, tools, 0.5, stock=stock)
    _, s_rest, *_ = simulate(design, rest, tools, 0.5, stock=stock)
    assert s_rest["volumes_mm3"]["removed"] == pytest.approx(s_full["volumes_mm3"]["removed"], rel=1e-9, abs=1e-6)
    assert s_rest["cutting_mm"]["air_share"] < s_full["cutting_mm"]["air_share"]
    with pytest.raises(InputError, match="rest needs a stock"):
        raster(design, tools, "B6", RasterParams(stepover=1.0, rest=0.05))
    with pytest.raises(NothingToCut, match="no piece of the passes removes more than rest 5 mm"):
        raster(design, tools, "B6", RasterParams(stepover=1.0, sample=0.5, rest=5.0, stock=stock))


def test_rest_waterline_cuts_only_the_loops_in_the_stock(cutters):
    """Stock only along one wall of a box: with --rest the loops are cut there (and a tool radius
    round the corners), and remove from the stock what the whole loops remove (simulated)."""
    from meshmill.ops.simulate import simulate

    design = box((0, 0, 0), (40, 40, 10))
    stock = box((-5, -5, 0), (45, 2, 10))
    tools = [cutters[1]]
    params = dict(step_down=2.5, sample=0.5)
    full, _, _ = waterline(design, tools, "B6", WaterlineParams(**params, stock=stock))
    rest, summary, loops = waterline(design, tools, "B6", WaterlineParams(**params, rest=0.05, stock=stock))
    assert summary["verify"]["ok"] and summary["rest"]["runs"] == summary["rest"]["loops_before"] >= 3  # one run a loop
    feed = rest.tip[~rest.rapid]
    assert len(feed) and (feed[:, 1] <= 2 + 3.0 + 3.0 + 0.5).all()  # the stock, its reach, the margin, a sample
    assert rest.cutting_length() < 0.5 * full.cutting_length()
    _, s_full, *_ = simulate(design, full, tools, 0.5, stock=stock)
    _, s_rest, *_ = simulate(design, rest, tools, 0.5, stock=stock)
    assert s_rest["volumes_mm3"]["removed"] == pytest.approx(s_full["volumes_mm3"]["removed"], rel=1e-9, abs=1e-6)


def test_the_waterline_stages_alone_on_a_sphere(cutters):
    """waterline_setup, drop_grid and level_loops on a sphere of radius 10: at level z the tip of a
    ball of radius 3 touching it runs on the circle of radius sqrt(13² - (z + 3)²), or 13 where its
    centre is below the equator (from above, the ball's side meets the equator first), one closed
    loop a level, never inside it (the facets lie inside the sphere: at most their chordal error
    of the sphere's radius, and the loop's own chords, inside the circle) and at most 1e-4 mm
    outside it (how closely a crossing is found where the drop height jumps at the equator)."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.ops.waterline import drop_grid, level_loops, waterline_setup

    m = sphere(10.0, rings=96, segments=192)
    setup = waterline_setup(m, cutters, "B6", WaterlineParams(step_down=4.0, sample=0.5))
    assert np.allclose(setup.levels, [6.0, 2.0, -2.0, -6.0])
    drop, grid = drop_grid(m, solid_kernels(m), setup)
    loops, _ = level_loops(setup, drop, grid)
    assert [z for z, _ in loops] == list(setup.levels)
    chord = 10.0 * (1.0 - math.cos(math.pi / 96)) + setup.params.tolerance
    for z, loop in loops:
        assert np.array_equal(loop[0], loop[-1]) and np.allclose(loop[:, 2], z)
        r = np.hypot(loop[:, 0], loop[:, 1])
        want = math.sqrt(13.0 ** 2 - max(z + 3.0, 0.0) ** 2)
        assert r.max() <= want + 1e-4 and r.min() >= want - chord
