"""Whole operations with ``device="cuda"`` write the CPU's paths and verify them alike."""
import os

import pytest
from parity import EXACT, close, same, same_tips

import meshmill
import meshmill.ops.finish
import meshmill.ops.plunge
import meshmill.ops.raster
import meshmill.ops.waterline
from meshmill.geometry.shapes import post_with_fillet
from meshmill.ops.finish import FinishParams, finish
from meshmill.ops.plunge import PlungeParams, plunge3
from meshmill.ops.raster import RasterParams, raster
from meshmill.ops.simulate import simulate
from meshmill.ops.waterline import WaterlineParams, waterline
from meshmill.tools.table import load_tools

RUNS = {
    "finish": lambda m, tools, dev: finish(m, tools, FinishParams(step_down=5.0, sample=4.0, tilt_step=30,
                                                                  max_tilt=60), device=dev),
    "raster": lambda m, tools, dev: raster(m, tools, "B10", RasterParams(stepover=8.0, scallop=None, angle=30.0,
                                                                         sample=5.0), device=dev),
    "waterline": lambda m, tools, dev: waterline(m, tools, "B10", WaterlineParams(step_down=6.0, sample=4.0),
                                                 device=dev),
    "plunge": lambda m, tools, dev: plunge3(m, tools, "B10", PlungeParams(radial_step=6.0, engagement=6.0,
                                                                         allowance=1.0, device=dev)),
}
# the simulator interprets every thread: finish and plunge (raster's and waterline's drop-cutter and
# touch kernels are compared in test_parity_kernels); a GPU runs all four
SIMULATOR_SKIPS = ("raster", "waterline")


@pytest.fixture(scope="module")
def setup():
    """``(part, tools)``: a small post with a fillet and the bundled tool table."""
    tools = load_tools(os.path.join(os.path.dirname(meshmill.__file__), "data", "tools.toml"))
    m = post_with_fillet(post_radius=4.0, fillet=3.0, height=10.0, plate_radius=12.0, plate_thickness=2.0,
                         arc_steps=3, segments=12)
    return m, tools


@pytest.fixture(scope="module")
def runs(setup):
    """``run(name)``: the operation's ``(cpu, cuda)`` results, each run once."""
    # the verification certifies every interval whatever the first poses' spacing: far apart, fewer
    # intervals for the simulator to interpret (the same answers, found by halving)
    with pytest.MonkeyPatch.context() as mp:
        for op in (meshmill.ops.finish, meshmill.ops.plunge, meshmill.ops.raster, meshmill.ops.waterline):
            mp.setattr(op, "DEFAULT_STEP", 20.0)
        done = {}

        def run(name):
            if name not in done:
                done[name] = tuple(RUNS[name](*setup, dev) for dev in ("cpu", "cuda"))
            return done[name]

        yield run


@pytest.mark.parametrize("name", list(RUNS))
def test_operation_matches_cpu(runs, name):
    if EXACT and name in SIMULATOR_SKIPS:
        pytest.skip("the simulator would interpret every thread of it: the kernel tests compare its kernels")
    (a, sa, *_), (b, sb, *_) = runs(name)
    assert len(a) > 20
    assert same_tips(a.tip, b.tip, sa["verify"]["tolerance"])
    for f in ("axis", "tool", "rapid"):
        assert close(getattr(a, f), getattr(b, f)), f
    va, vb = sa["verify"], sb["verify"]
    assert va.keys() == vb.keys() and va["ok"] == vb["ok"]
    assert all(close(va[k], vb[k]) for k in va if not isinstance(va[k], (list, dict, str)))


@pytest.mark.parametrize("name", ["plunge", "finish"])
def test_simulation_matches_cpu(setup, runs, name):
    # a 3-axis path, and on a GPU a turning ball-end one (the simulator would take minutes over its
    # holder's sweep; the cut test compares shank and holder moves)
    if EXACT and name == "finish":
        pytest.skip("the simulator would take minutes over the holder's sweep: the cut test compares its moves")
    m, tools = setup
    path = runs(name)[0][0]
    x, y = (simulate(m, path, tools, 2.0, device=dev) for dev in ("cpu", "cuda"))
    assert not EXACT or x[0] == y[0]
    for k in range(3):
        assert same(x[2].model.start[k], y[2].model.start[k]) and same(x[2].model.iv[k], y[2].model.iv[k]), k
