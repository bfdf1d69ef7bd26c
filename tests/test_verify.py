"""verify: gouges, shank collisions and rapids into the part, with their depth and place."""
import numpy as np

from meshmill.geometry.shapes import box
from meshmill.ops.verify import verify_toolpath
from meshmill.toolpath.model import Toolpath
from meshmill.tools.table import tool_from_entry

UP = (0.0, 0.0, 1.0)


def _path(points, axes=None, rapid=None, tool=0):
    points = np.array(points, np.float64)
    axes = np.tile(UP, (len(points), 1)) if axes is None else np.array(axes, np.float64)
    rapid = np.zeros(len(points), bool) if rapid is None else np.array(rapid, bool)
    return Toolpath(points, axes, rapid, np.full(len(points), tool))


def test_ball_dipping_into_a_block_reports_the_depth_and_place(tools):
    bvh = box([0, 0, 0], [20, 20, 10])
    # B10 (index 1) runs along the top at tip z = 10, dips 0.2 mm at x = 10, comes back up
    tp = _path([[2, 10, 10], [10, 10, 9.8], [18, 10, 10]], tool=1)
    r = verify_toolpath(bvh, tp, tools, tol=0.01, step=0.1)
    assert r["gouging_moves"] == 2 and not r["ok"]
    assert abs(r["max_gouge"] - 0.2) < 1e-9
    assert "0.2000 mm" in r["worst"][0] and "(10.000, 10.000, 9.800)" in r["worst"][0]


def test_clean_path_on_top_of_a_block(tools):
    bvh = box([0, 0, 0], [20, 20, 10])
    tp = _path([[2, 10, 20], [2, 10, 10], [18, 10, 10], [18, 10, 20]], rapid=[True, True, False, True], tool=1)
    r = verify_toolpath(bvh, tp, tools)
    assert r["ok"] and r["max_gouge"] < 1e-12


def test_shank_collision_against_a_wall(tools):
    m = box([0, 0, 0], [10, 10, 30])
    bvh = m
    # B2 (R 1, shank 6 mm from 5 mm up) with its ball touching the wall x = 0: the shank enters 2 mm
    tp = _path([[-1.0, 5, 5], [-1.0, 6, 5]], tool=3)
    r = verify_toolpath(bvh, tp, tools)
    assert r["colliding_moves"] == 2 and r["gouging_moves"] == 0
    assert abs(r["max_collision"] - 2.0) < 1e-9
    assert "shank" in r["worst"][0]


def test_holder_collision(tools):
    m = box([0, 0, 0], [10, 10, 100])
    bvh = m
    # B6: R 3, shank 6 mm, holder 32 mm from 45 mm up; ball 1 mm off the wall
    tp = _path([[-4.0, 5, 5], [-4.0, 6, 5]], tool=2)
    r = verify_toolpath(bvh, tp, tools)
    assert r["colliding_moves"] == 2 and "holder" in r["worst"][0]
    assert abs(r["max_collision"] - 12.0) < 1e-9


def test_rapid_through_the_part(tools):
    bvh = box([0, 0, 0], [20, 20, 10])
    tp = _path([[-15, 10, 5], [35, 10, 5]], rapid=[True, True], tool=1)
    r = verify_toolpath(bvh, tp, tools)
    assert r["rapid_moves_touching"] == 1 and not r["ok"]


def test_interpolated_axis_is_checked_between_poses(tools):
    # both end poses are clear, the swing of the axis in between sweeps the holder through a post
    post = box([-2, 30, 0], [2, 34, 60])
    bvh = post
    a = np.array([0.0, np.sin(0.6), np.cos(0.6)])
    b = np.array([0.0, -np.sin(0.6), np.cos(0.6)])
    tp = _path([[0, 0, 0], [0, 0, 0]], axes=[b, a], tool=1)
    single = verify_toolpath(bvh, _path([[0, 0, 0]], axes=[b], tool=1), tools)
    assert single["ok"]
    r = verify_toolpath(bvh, tp, tools)
    assert not r["ok"]


def test_bull_nose_and_flat_are_checked(tools):
    bull = tool_from_entry(dict(name="R6", type="bull", diameter=12, corner_radius=2, flute_length=20,
                                gauge_length=40), 1, "t")
    flat = tool_from_entry(dict(name="F6", type="flat", diameter=6, flute_length=20, gauge_length=40), 2, "t")
    bvh = box([0, 0, 0], [20, 20, 10])
    ok = verify_toolpath(bvh, _path([[10, 10, 10], [12, 10, 10]], tool=0), [bull, flat])
    assert ok["ok"]  # resting flat on the top face is no gouge
    bad = verify_toolpath(bvh, _path([[10, 10, 9.7], [12, 10, 9.7]], tool=1), [bull, flat])
    assert not bad["ok"] and abs(bad["max_gouge"] - 0.3) < 1e-6


def test_move_after_a_tool_change_is_checked_along_its_way(tools):
    bvh = box([0, 0, 0], [20, 20, 10])
    tp = Toolpath(np.array([[-15.0, 10, 5], [35.0, 10, 5]]), np.tile(UP, (2, 1)), np.array([True, False]),
                  np.array([0, 1]))
    r = verify_toolpath(bvh, tp, tools)
    assert r["gouging_moves"] == 1 and r["poses_checked"] > 50
