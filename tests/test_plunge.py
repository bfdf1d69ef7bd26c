"""3-axis plunge roughing: exact depths with the allowance, contours, the command."""
import json

import numpy as np
import pytest
import trimesh

from meshmill.cli import main
from meshmill.errors import InputError
from meshmill.kernels.bvh import build_bvh
from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.geometry.shapes import box, sphere
from meshmill.kernels.cpu import mesh_distances
from meshmill.ops.plunge import PlungeParams, contours, plunge3, rectangle_points
from meshmill.tools.table import Tool

FLAT = Tool("F6", "flat", 6.0, 0.0, 40.0, 60.0, 6.0)
BULL = Tool("R8", "bull", 8.0, 1.0, 40.0, 60.0, 8.0)


def stepped_block():
    """Steps of 10 mm: z 10 for x in [40, 60], 20 for [20, 40], 30 for [0, 20]; y in [0, 30]."""
    parts = [box((0, 0, 0), (60, 30, 10)), box((0, 0, 10), (40, 30, 20)), box((0, 0, 20), (20, 30, 30))]
    v = np.concatenate([p.vertices for p in parts])
    f = np.concatenate([p.faces + 8 * i for i, p in enumerate(parts)])
    return mesh_from_arrays(v, f, "steps")


def plunges(tp):
    """(x, y, z) of every plunge bottom (a feed move followed by the feed back up)."""
    return tp.tip[:-1][~tp.rapid[:-1] & ~tp.rapid[1:]]


@pytest.mark.parametrize("allowance", [0.0, 0.5])
def test_depths_on_a_stepped_block_equal_the_steps(allowance):
    m = stepped_block()
    tp, s = plunge3(m, [FLAT], "F6", PlungeParams(radial_step=2.0, engagement=5.0, allowance=allowance))
    bottoms = plunges(tp)
    x = bottoms[:, 0]
    reach = FLAT.radius + allowance
    over_a = x > 40 + reach + 1e-9
    over_b = (x > 20 + reach + 1e-9) & (x < 40 - reach - 1e-9)
    assert over_a.sum() > 10 and over_b.sum() > 10
    np.testing.assert_allclose(bottoms[over_a, 2], 10 + allowance, atol=1e-9)
    np.testing.assert_allclose(bottoms[over_b, 2], 20 + allowance, atol=1e-9)
    assert (x >= 20 - reach - 1e-9).all()  # over the top step nothing is removed: skipped
    assert s["verify"]["ok"] and s["valid_plunges"] == len(bottoms) < s["plunges"]
    # every plunge: rapid on the clearance plane, rapid down to where the tool clears the stock by
    # the holder clearance, feed down, feed back up there, rapid up to the plane
    assert set(np.round(tp.tip[tp.rapid][:, 2], 9)) == {35.0, 30.5} and len(tp) == 5 * len(bottoms)
    assert s["plunges_short_of_the_part"] == 0 and s["layers_max"] == 1


def tool_points(tip, R, n_ring=720, spacing=0.1, height=10.0):
    """Points on the boundary of a flat cylinder standing at tip: the bottom disc and the side."""
    g = np.arange(-R, R + 1e-9, spacing)
    X, Y = np.meshgrid(g, g)
    inside = X ** 2 + Y ** 2 <= R * R
    disc = np.column_stack([X[inside], Y[inside], np.zeros(inside.sum())])
    a = np.linspace(0, 2 * np.pi, n_ring, endpoint=False)
    side = [np.column_stack([R * np.cos(a), R * np.sin(a), np.full_like(a, h)]) for h in np.arange(0, height, 0.25)]
    return np.concatenate([disc] + side) + tip


@pytest.mark.slow
def test_no_plunge_comes_closer_than_the_allowance():
    m = sphere(20.0, rings=24, segments=48, center=(0, 0, 0))
    allowance = 1.0
    tp, s = plunge3(m, [FLAT], "F6", PlungeParams(radial_step=4.0, engagement=4.0, allowance=allowance))
    bvh = build_bvh(m.vertices, m.faces).arrays
    # the shank (as wide as the cutter) keeps 0.5 mm above the stock: no plunge deeper than the
    # flutes less that, and those are no nearer the part than the allowance
    floor = max(m.bounds[0, 2], m.bounds[1, 2] - (FLAT.flute_length - 0.5))
    assert s["plunges_short_of_the_part"] > 0 and plunges(tp)[:, 2].min() >= floor - 1e-6
    for tip in plunges(tp):
        d = mesh_distances(tool_points(tip, FLAT.radius), bvh).min()
        assert d >= allowance - 1e-6
        if tip[2] > floor + 1e-6:  # resting on the grown tool's contact: exactly the allowance away
            assert d <= allowance + 0.02


def test_bull_nose_and_bad_values():
    m = sphere(20.0, rings=24, segments=48)
    tp, s = plunge3(m, [BULL], "R8", PlungeParams(radial_step=5.0, engagement=6.0, allowance=0.5))
    assert s["verify"]["ok"] and s["valid_plunges"] > 0
    with pytest.raises(Exception, match="wider than the tool"):
        plunge3(m, [BULL], "R8", PlungeParams(radial_step=5.0, engagement=9.0, allowance=0.5))
    with pytest.raises(InputError, match="^radial_step must be a number of mm >= 0.001, got 0$"):
        PlungeParams.checked(dict(part=m, tools=[BULL], tool="R8", radial_step=0.0, engagement=6.0, allowance=0.5))


def test_contours_and_perimeter_points():
    pts = rectangle_points(0, 0, 4, 2, 1.0)
    assert len(pts) == 12 and pts[0].tolist() == [0, 0] and pts[2].tolist() == [0, 2] and pts[6].tolist() == [4, 2]
    rings = contours(np.array([[0, 0, 0], [10, 4, 1]]), 1.5, 1.0)
    assert len(rings) == 2 and rings[1][0].tolist() == [1.5, 1.5]  # 2nd: 7 x 1 mm; a 3rd would be empty
    assert len(rectangle_points(1, 1, 1, 1, 0.5)) == 1


def test_plunge_command(tmp_path, tools_file):
    m = stepped_block()
    trimesh.Trimesh(m.vertices, m.faces).export(tmp_path / "steps.stl")
    rc = main(["plunge", str(tmp_path / "steps.stl"), "--tools", str(tools_file), "--tool", "B6", "--radial-step", "3",
               "--engagement", "4", "--allowance", "0.5", "--out", str(tmp_path / "o"), "--quiet"])
    assert rc == 0
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["valid_plunges"] > 0 and (tmp_path / "o" / "toolpath.cl").read_text().count("GOTO") == s["moves"]
    ball = sphere(15.0, rings=24, segments=48)
    trimesh.Trimesh(ball.vertices, ball.faces).export(tmp_path / "ball.stl")
    assert main(["plunge", str(tmp_path / "ball.stl"), "--tools", str(tools_file), "--tool", "B6", "--radial-step", "3",
                 "--engagement", "4", "--allowance", "0.5", "--simulate", "0.5", "--out", str(tmp_path / "s"),
                 "--quiet"]) == 0
    sim = json.loads((tmp_path / "s" / "summary.json").read_text())["simulation"]
    assert 0 < sim["removed_volume"] < sim["stock_volume"] and sim["gouged_volume"] < 1e-6
    assert main(["plunge", str(tmp_path / "steps.stl"), "--tools", str(tools_file), "--tool", "B6", "--radial-step",
                 "3", "--engagement", "4", "--allowance", "-1", "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert main(["plunge", str(tmp_path / "steps.stl"), "--tools", str(tools_file), "--tool", "B6", "--axes", "5",
                 "--theta-step", "45", "--delta-step", "90", "--allowance", "0.5", "--out", str(tmp_path / "o5"),
                 "--quiet"]) == 0
    s5 = json.loads((tmp_path / "o5" / "summary.json").read_text())
    assert s5["axes"] == 5 and s5["plunges"] == 9 and s5["verify"]["ok"]


def test_seed_tool_frame():
    from meshmill.ops.plunge import tool_frame

    t1, t2 = tool_frame(np.array([0.25, 0.433, 0.866]) / np.linalg.norm([0.25, 0.433, 0.866]))
    np.testing.assert_allclose(t1, [0.961, 0.000, -0.277], atol=1e-3)
    np.testing.assert_allclose(t2, [-0.120, 0.901, -0.416], atol=1e-3)
    t1, t2 = tool_frame(np.array([0.0, 1.0, 0.0]))  # along y: the fallback
    assert np.isclose(np.linalg.norm(t1), 1) and np.isclose(t1 @ [0, 1, 0], 0) and np.isclose(t2 @ t1, 0)


def tool_points_along(tip, u, R, height=10.0):
    from meshmill.ops.plunge import tool_frame

    t1, t2 = tool_frame(u)
    local = tool_points(np.zeros(3), R, n_ring=360, spacing=0.2, height=height)
    return tip + local[:, :1] * t1 + local[:, 1:2] * t2 + local[:, 2:] * u


def test_five_axis_plunges_keep_the_allowance():
    from meshmill.ops.plunge import plunge5

    m = sphere(15.0, rings=24, segments=48)
    allowance = 1.0
    tp, s = plunge5(m, [FLAT], "F6", PlungeParams(radial_step=1, engagement=1, allowance=allowance, theta_step=30,
                                                   delta_step=60))
    assert s["plunges"] == 1 + 3 * 6 and 0 < s["valid_plunges"] <= s["plunges"] and s["verify"]["ok"]
    bvh = build_bvh(m.vertices, m.faces).arrays
    bottom = ~tp.rapid[:-1] & ~tp.rapid[1:]
    for tip, u in zip(tp.tip[:-1][bottom], tp.axis[:-1][bottom]):
        d = mesh_distances(tool_points_along(tip, u, FLAT.radius), bvh).min()
        assert allowance - 1e-6 <= d <= allowance + 0.05  # a sphere always stops the tool
    # rapid moves stay out of the stock box by the holder clearance
    lo, hi = m.bounds
    rap = tp.tip[tp.rapid]
    assert (np.linalg.norm(np.maximum(np.maximum(lo - rap, rap - hi), 0.0), axis=1) >= 0.5 - 1e-6).all()


@pytest.mark.slow
def test_region_mode_reaches_under_an_overhang_and_removes_more():
    from meshmill.ops.plunge import plunge5
    from meshmill.ops.simulate import simulate
    from test_analysis import mushroom

    m = mushroom()
    allowance = 0.5
    base = dict(radial_step=3.0, engagement=3.0, allowance=allowance, theta_step=30, delta_step=45)
    tp_r, s_r = plunge5(m, [FLAT], "F6", PlungeParams(**base, regions=6))
    tp_s, s_s = plunge5(m, [FLAT], "F6", PlungeParams(**base))
    assert s_r["verify"]["ok"] and s_r["regions"] == 6 and s_r["valid_plunges"] > s_s["valid_plunges"]
    bvh = build_bvh(m.vertices, m.faces).arrays
    feed = np.r_[~tp_r.rapid[:-1] & ~tp_r.rapid[1:], False]  # the plunges' bottoms
    for tip, u in zip(tp_r.tip[feed], tp_r.axis[feed]):
        assert mesh_distances(tool_points_along(tip, u, FLAT.radius, height=6.0), bvh).min() >= allowance - 1e-6
    # some plunge ends under the cap (r < 14, below z 25), which no vertical plunge can reach
    under = (np.hypot(tp_r.tip[feed, 0], tp_r.tip[feed, 1]) < 13) & (tp_r.tip[feed, 2] < 20)
    assert under.any() and (tp_r.axis[feed][under, 2] < 0.99).all()
    left = {}
    for name, tp in (("regions", tp_r), ("seed", tp_s)):
        dev, *_ = simulate(m, tp, [FLAT], 0.5, stock="box")
        left[name] = dev["remaining_volume"]
        assert dev["gouge_max"] < 0.05
    assert left["regions"] < left["seed"]


def tower():
    """A 20 x 20 tower 60 mm tall on a 60 x 60 x 5 plate: plunges around it go 60 mm deep."""
    parts = [box((0, 0, 0), (60, 60, 5)), box((20, 20, 5), (40, 40, 65))]
    v = np.concatenate([p.vertices for p in parts])
    f = np.concatenate([p.faces + 8 * i for i, p in enumerate(parts)])
    return mesh_from_arrays(v, f, "tower")


def test_plunges_cut_with_their_flutes_only():
    from meshmill.ops.simulate import simulate

    m = tower()
    short = Tool("F10", "flat", 10.0, 0.0, 20.0, 40.0, 10.0, 32.0, 40.0)  # shank as wide as the cutter
    tp, s = plunge3(m, [short], "F10", PlungeParams(radial_step=6.0, engagement=8.0, allowance=0.5))
    bottoms = plunges(tp)
    assert s["verify"]["ok"] and len(bottoms) > 20
    # the shank keeps 0.5 mm above the stock: no plunge deeper than the flutes less that
    assert bottoms[:, 2].min() == pytest.approx(65 - 19.5, abs=1e-6)
    assert s["plunges_short_of_the_part"] > 0 and s["left_by_shank_and_holder_mm"] > 30
    # independent: the dexel simulation checks shank and holder against the stock as it is cut
    dev, sim, *_ = simulate(m, tp, [short], 1.0, stock="box")
    assert sim["colliding_moves"] == 0 and sim["rapid_moves_cutting"] == 0
    # a necked tool (shank 6 mm, cutter 10): deeper, in layers of its flute length, down to where
    # the holder keeps its clearance
    necked = Tool("N10", "flat", 10.0, 0.0, 20.0, 50.0, 6.0, 32.0, 40.0)
    tp, s = plunge3(m, [necked], "N10", PlungeParams(radial_step=6.0, engagement=8.0, allowance=0.5))
    bottoms = plunges(tp)
    assert s["verify"]["ok"] and s["layers_max"] == 3 and s["plunges_in_layers"] > 0
    assert bottoms[:, 2].min() == pytest.approx(65 - 49.5, abs=1e-6)
    x, y, z = bottoms.T
    for px, py in set(zip(np.round(x, 6), np.round(y, 6))):
        depth = np.sort(z[(np.round(x, 6) == px) & (np.round(y, 6) == py)])[::-1]
        assert np.all(-np.diff(np.r_[65.0, depth]) <= 20.0 + 1e-9)  # each layer cuts at most the flutes
    dev, sim, *_ = simulate(m, tp, [necked], 1.0, stock="box")
    assert sim["colliding_moves"] == 0 and sim["rapid_moves_cutting"] == 0


def test_simulate_reports_a_holder_in_the_stock():
    from meshmill.ops.simulate import simulate
    from meshmill.toolpath.model import Toolpath

    m = tower()
    short = Tool("F10", "flat", 10.0, 0.0, 20.0, 40.0, 10.0, 32.0, 40.0)
    # one plunge 50 mm straight down beside the tower: the shank and then the holder enter the stock
    tip = np.array([[5.0, 5, 70], [5.0, 5, 15], [5.0, 5, 70]])
    tp = Toolpath(tip, np.tile([0, 0, 1.0], (3, 1)), np.array([True, False, True]), np.zeros(3, int))
    dev, sim, *_ = simulate(m, tp, [short], 1.0, stock="box")
    assert sim["colliding_moves"] == 2 and sim["colliding_points"] == [1, 2]  # down and back up
    assert any("shank or holder" in e for e in sim["errors"])
