"""verify: gouges, shank collisions and rapids into the part, with their depth and place."""
import numpy as np
import pytest

from meshmill.geometry.shapes import box, sphere
from meshmill.pathing.verify import verify_toolpath
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


def _ridge():
    """A sharp ridge along Y (apex at x = 0, z = 10, flanks at 45 degrees) on a block."""
    from meshmill.geometry.mesh import mesh_from_arrays

    v = np.array([[-10, -10, 0], [10, -10, 0], [0, -10, 10], [-10, 10, 0], [10, 10, 0], [0, 10, 10]], float)
    f = np.array([[0, 2, 1], [3, 4, 5], [0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4], [2, 0, 3], [2, 3, 5]])
    return mesh_from_arrays(v, f[:, ::-1], "ridge")


def test_a_ball_crossing_a_sharp_apex_between_its_poses_is_found():
    # a 1 mm ball crosses the apex in a 0.5 mm move, 0.05 mm too low: both ends are clear (the
    # apex lies between them), so poses 0.5 mm apart see nothing; the certified check finds it
    ball = tool_from_entry(dict(name="B1", type="ball", diameter=1, flute_length=4, gauge_length=30), 1, "t")
    z = 10.0 - 0.05
    tp = _path([[-0.25, 0, z], [0.25, 0, z]])
    ends = verify_toolpath(_ridge(), _path([[-0.25, 0, z]]), [ball])
    assert ends["ok"]
    r = verify_toolpath(_ridge(), tp, [ball], step=0.5)
    assert not r["ok"] and r["gouging_moves"] == 1
    assert r["max_gouge"] == pytest.approx(0.05, abs=1e-3) and r["poses_refined"] > 0


def test_a_shallow_dip_is_measured_at_its_depth_whatever_the_step():
    # a 4 mm ball dipping 0.025 mm into a flat top between two 0.5 mm poses
    ball = tool_from_entry(dict(name="B4", type="ball", diameter=4, flute_length=10, gauge_length=30), 1, "t")
    tp = _path([[0, 0, 10.0], [0.25, 0, 10 - 0.025], [0.5, 0, 10.0]])
    for step in (0.5, 2.0):
        r = verify_toolpath(box([-10, -10, 0], [10, 10, 10]), tp, [ball], step=step)
        assert not r["ok"] and r["max_gouge"] == pytest.approx(0.025, abs=1e-9)


def test_a_tool_buried_in_the_part_is_a_gouge(tools):
    # the B2 deep inside a block: no part of it crosses the surface
    m = box([-50, -50, -50], [50, 50, 50])
    r = verify_toolpath(m, _path([[0, 0, -30], [1, 0, -30]], tool=3), tools)
    assert not r["ok"] and r["gouging_moves"] == 2 and r["max_gouge"] > 1.0


def test_rapids_keep_clear_of_the_stock(tools):
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck

    part = box([0, 0, 0], [20, 20, 10])
    # B10 passes at rapid 0.3 mm over the top: clear of the part, inside a 0.5 mm allowance
    tp = _path([[-10, 10, 10.3], [30, 10, 10.3]], rapid=[True, True], tool=1)
    assert verify_toolpath(part, tp, tools)["ok"]
    r = verify_toolpath(part, tp, tools, stock=StockCheck(allowance=0.5))
    assert r["rapid_moves_touching"] == 1 and "into the stock" in r["worst"][0]
    assert "0.2000 mm" in r["worst"][0]
    # 0.3 mm over the allowance: out of the stock, but not the clearance away
    over = _path([[-10, 10, 10.8], [30, 10, 10.8]], rapid=[True, True], tool=1)
    r = verify_toolpath(part, over, tools, stock=StockCheck(allowance=0.5, clearance=0.5))
    assert r["rapid_moves_touching"] == 1 and "0.3000 mm from the stock (less than the clearance)" in r["worst"][0]
    # a stock mesh: the rapid crosses a blank 5 mm above the part
    blank = box([-5, -5, 0], [25, 25, 15])
    r = verify_toolpath(part, tp, tools, stock=StockCheck(kern=solid_kernels(blank)))
    assert r["rapid_moves_touching"] == 1
    high = _path([[-10, 10, 16], [30, 10, 16]], rapid=[True, True], tool=1)
    assert verify_toolpath(part, high, tools, stock=StockCheck(kern=solid_kernels(blank), clearance=0.5))["ok"]
    assert not verify_toolpath(part, high, tools, stock=StockCheck(kern=solid_kernels(blank), clearance=1.5))["ok"]


def test_an_open_sheet_has_material_below_it(tools):
    from meshmill.geometry.mesh import mesh_from_arrays

    # a flat sheet at z = 10 over [0, 20]^2, facing up; its lowest point is the floor
    sheet = mesh_from_arrays(np.array([[0, 0, 10], [20, 0, 10], [20, 20, 10], [0, 20, 10.0]]),
                             np.array([[0, 1, 2], [0, 2, 3]]), "sheet")
    above = _path([[5, 5, 10], [15, 5, 10]], tool=1)
    assert verify_toolpath(sheet, above, tools)["ok"]
    # the B10 (R 5) beside the edge, its ball's centre level with the sheet: the tool dips under
    # the sheet's edge (the curtain below it), which the sheet's triangles alone never see
    side = _path([[24.9, 10, 5.0], [24.9, 12, 5.0]], tool=1)
    r = verify_toolpath(sheet, side, tools)
    assert not r["ok"] and r["max_gouge"] == pytest.approx(0.1, abs=1e-6)
    # a tool under the sheet, clear of its triangles, is in the material (down to the floor, as
    # deep again below the sheet as it is tall and at least 10 mm)
    assert not verify_toolpath(sheet, _path([[10, 10, 2.0], [11, 10, 2.0]], tool=3), tools)["ok"]


def test_shank_and_holder_of_feed_moves_stay_out_of_the_stock(tools):
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck

    m = box([0, 0, 0], [10, 10, 100])
    # B6's holder (radius 16 from 45 mm up) runs 0.3 mm from the wall x = 0, the ball far from it:
    # clear of the design, 0.2 mm into a 0.5 mm allowance, between poses as much as at them
    tp = _path([[-16.3, -20, 5], [-16.3, 30, 5]], tool=2)
    assert verify_toolpath(m, tp, tools)["ok"]
    for step in (0.5, 100.0):
        r = verify_toolpath(m, tp, tools, step=step, stock=StockCheck(allowance=0.5))
        assert r["colliding_moves"] == 1 and r["gouging_moves"] == 0
        assert r["max_collision"] == pytest.approx(0.2, abs=1e-9)
        assert "holder (in the stock) 0.2000 mm" in r["worst"][0]
    # a stock mesh the holder enters at both points; the cutting end in it is what a cut is for
    blank = box([-17, -30, 0], [20, 40, 60])
    r = verify_toolpath(m, tp, tools, stock=StockCheck(kern=solid_kernels(blank)))
    assert r["colliding_moves"] == 2 and r["gouging_moves"] == 0 and "holder (in the stock)" in r["worst"][0]
    low = box([-30, -30, 0], [20, 40, 16])  # below the shank (12 mm over the tip): only the cutter in it
    assert verify_toolpath(m, tp, tools, stock=StockCheck(kern=solid_kernels(low)))["ok"]


@pytest.mark.parametrize("pieces", [False, True])
def test_a_changed_path_reverified_reports_as_a_whole_check(tools, pieces):
    """Repair rounds check only the moves a path's new version does not share with the last
    (the same two points, axes, tool and kind): the report equals a check of the whole new path,
    problems, counts and figures, whatever was kept, moved, added or removed."""
    from meshmill.pathing.reverify import Reverify
    from meshmill.pathing.verify import StockCheck, check_parts, verify_toolpath
    from meshmill.kernels.backend import solid_kernels

    kern = solid_kernels(box([0, 0, 0], [20, 20, 10]), "cpu")
    stock = StockCheck(allowance=0.5, clearance=0.5)
    rng = np.random.default_rng(2)
    n = 60
    pts = np.column_stack([np.linspace(-5, 25, n), np.full(n, 10.0), np.full(n, 10.0)])
    pts[rng.choice(n, 6, replace=False), 2] -= rng.uniform(0.05, 0.5, 6)  # dips into the top
    rapid = np.zeros(n, bool)
    rapid[[0, 30]] = True
    tp = _path(pts, rapid=rapid, tool=1)
    progress = (lambda *a: None) if pieces else None
    check = Reverify(lambda path, only: check_parts(kern, path, tools, 0.01, 0.5, stock, only, progress), 0.01, 0.5,
                     stock.summary())
    first = check(tp)
    assert first == verify_toolpath(kern, tp, tools, 0.01, 0.5, stock=stock) and not first["ok"]
    assert check.checked == n
    # repair: lift the dips, drop two points, add a rapid up and back, tilt one point
    fixed = pts.copy()
    fixed[:, 2] = np.maximum(fixed[:, 2], 10.0)
    keep = np.ones(n, bool)
    keep[[12, 40]] = False
    new = np.vstack([fixed[keep][:20], [[fixed[keep][19, 0], 10.0, 30.0]], fixed[keep][20:]])
    axes = np.tile(UP, (len(new), 1))
    axes[45] = [0.0, np.sin(0.1), np.cos(0.1)]
    new_rapid = np.r_[rapid[keep][:20], True, rapid[keep][20:]]
    tp2 = _path(new, axes=axes, rapid=new_rapid, tool=1)
    again = check(tp2)
    assert again == verify_toolpath(kern, tp2, tools, 0.01, 0.5, stock=stock)
    assert 0 < check.checked < len(tp2) // 2
    # unchanged: nothing checked, the same report
    assert check(tp2) == again and check.checked == 0


def test_a_moves_key_is_its_point_before_its_point_tool_kind_and_whether_it_is_first():
    from meshmill.pathing.reverify import move_keys

    rng = np.random.default_rng(4)
    for n in (0, 1, 2, 7):
        tp = _path(rng.random((n, 3)), axes=rng.random((n, 3)), rapid=rng.random(n) < 0.5, tool=1)
        prev = np.maximum(np.arange(n) - 1, 0)
        want = np.column_stack([tp.tip[prev], tp.axis[prev], tp.tip, tp.axis, tp.tool, tp.rapid,
                                np.arange(n) == 0]).astype(float).reshape(n, 15)
        assert np.array_equal(move_keys(tp), want)


def test_the_first_point_is_proven_and_never_taken_for_a_move_of_length_zero():
    """A needle's tip 0.05 mm inside a bull-nose's rounded corner, between the spheres its pose
    measure samples: the first point of a path is proven like every interval (not certified
    there), and a later move of length zero at the same place, whose interval is checked, is
    never given the first point's figures by a re-verification."""
    import math

    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.reverify import Reverify
    from meshmill.pathing.verify import StockCheck, check_parts
    from meshmill.tools.table import Tool

    bull = Tool(name="R5", type="bull", diameter=10.0, corner_radius=1.0, flute_length=10.0, gauge_length=30.0,
                shank_diameter=10.0)
    a = math.radians(5)  # midway between two of the measure's spheres
    centre = np.array([4 * math.cos(a), 4 * math.sin(a), 1.0])
    d = np.array([math.cos(a) * math.cos(math.pi / 4), math.sin(a) * math.cos(math.pi / 4), -math.sin(math.pi / 4)])
    apex = centre + 0.95 * d
    e1 = np.cross(d, [0, 0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(d, e1)
    base = apex + 6 * d
    v = np.array([apex, base + 0.05 * e1, base + 0.05 * (-0.5 * e1 + 0.866 * e2), base + 0.05 * (-0.5 * e1 - 0.866 * e2)])
    needle = mesh_from_arrays(v, np.array([[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]]), "needle", flip=True)
    kern = solid_kernels(needle, "cpu", floor=float(v[:, 2].min()) - 50)
    stock = StockCheck()
    check = Reverify(lambda path, only: check_parts(kern, path, [bull], 0.01, 0.5, stock, only), 0.01, 0.5,
                     stock.summary())
    for points in ([[0, 0, 0]], [[0, 0, 0], [-3, 0, 0]], [[0, 0, 0], [0, 0, 0]]):
        tp = _path(points, tool=0)
        whole = verify_toolpath(kern, tp, [bull], 0.01, 0.5, stock=stock)
        assert not whole["ok"] and "not certified" in whole["worst"][0]
        assert check(tp) == whole


def test_a_move_is_certified_in_one_test_and_still_halved_where_it_must():
    """A straight move with a fixed axis is proven whole (one certified interval, its last pose
    alone measured: the proof bounds the 100 poses between); a ridge under it that none of its
    poses see is found all the same (the whole test fails, its poses are measured and it is
    halved); a move whose axis turns is proven whole too."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, verify_moves

    ball = tool_from_entry(dict(name="B1", type="ball", diameter=1, flute_length=4, gauge_length=30), 1, "t")
    kern = solid_kernels(_ridge())
    high = _path([[-5, 0, 10.5], [5, 0, 10.5]])
    fig = verify_moves(kern, high, [ball], 0.001, 0.1, StockCheck())["figures"]
    assert fig["certified"][list(fig["move"]).index(1)] == 1 and fig["poses"][list(fig["move"]).index(1)] == 1
    # poses 0.1 mm apart at x = +-0.05, +-0.15, ... : the ball 0.001 mm into the apex at x = 0
    low = _path([[-5.05, 0, 10 - 0.001 * np.sqrt(2) - 0.0004], [4.95, 0, 10 - 0.001 * np.sqrt(2) - 0.0004]])
    r = verify_toolpath(_ridge(), low, [ball], tol=0.0005, step=0.1)
    assert not r["ok"] and r["gouging_moves"] == 1 and r["poses_refined"] > 0
    assert verify_moves(kern, low, [ball], 0.0005, 0.1, StockCheck())["figures"]["poses"][1] > 100
    # a turning axis too: proven whole where that holds, and between its poses where it does not
    turn = np.array([0.0, np.sin(0.01), np.cos(0.01)])
    tilted = _path([[-5, 0, 10.5], [5, 0, 10.5]], axes=[UP, turn])
    fig = verify_moves(kern, tilted, [ball], 0.001, 0.1, StockCheck())["figures"]
    assert fig["certified"][list(fig["move"]).index(1)] == 1
    low_turn = _path([[-5.05, 0, 10 - 0.001 * np.sqrt(2) - 0.0004], [4.95, 0, 10 - 0.001 * np.sqrt(2) - 0.0004]],
                     axes=[UP, turn])
    r = verify_toolpath(_ridge(), low_turn, [ball], tol=0.0005, step=0.1)
    assert not r["ok"] and r["gouging_moves"] == 1
    near = _path([[-5.05, 0, 10.02], [4.95, 0, 10.02]], axes=[UP, turn])  # the ball 0.02 mm over the apex
    fig = verify_moves(kern, near, [ball], 0.001, 0.1, StockCheck())["figures"]
    assert fig["certified"][list(fig["move"]).index(1)] >= 1


def test_pieces_of_a_move_whose_tool_was_proven_whole_are_tested_for_the_shank_alone():
    """_Measure.clear's ``proven``: intervals whose tool is known proven against the design (the
    pieces of a move proven whole, its shank failing) are not tested against it again: a move
    over the ridge's apex 0.0004 mm too low fails its proof, and passes it given as proven; the
    rest of the report (``tool_ok``) says which intervals the design proved."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, _Measure

    ball = tool_from_entry(dict(name="B1", type="ball", diameter=1, flute_length=4, gauge_length=30), 1, "t")
    meas = _Measure(solid_kernels(_ridge()), [ball], 0.0005, StockCheck())
    z = 10 - 0.001 * np.sqrt(2) - 0.0004
    ta, tb = np.array([[-5.05, 0, z], [-5.05, 0, 12.0]]), np.array([[4.95, 0, z], [4.95, 0, 12.0]])
    up, tool, feed = np.tile(UP, (2, 1)), np.zeros(2, np.int64), np.zeros(2, bool)
    ok, tool_ok = meas.clear(ta, up, tb, up, tool, feed)
    assert ok.tolist() == [False, True] and tool_ok.tolist() == [False, True]
    ok, tool_ok = meas.clear(ta, up, tb, up, tool, feed, proven=np.array([True, False]))
    assert ok.tolist() == [True, True] and tool_ok.tolist() == [True, True]


def test_a_tool_thinner_than_the_tolerance_through_the_material_is_found():
    """A part whose radius is within the tolerance is proven of nothing (its sweep shrunk by the
    tolerance is empty): a 0.016 mm ball fed through a block between two clean poses outside it
    is found by its poses, all measured (a review found the lazy poses missing it)."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, verify_moves

    thin = tool_from_entry(dict(name="B0.016", type="ball", diameter=0.016, flute_length=0.1, gauge_length=30,
                                shank_diameter=0.016), 1, "t")
    kern = solid_kernels(box([-5, -5, 0], [5, 5, 10]))
    r = verify_moves(kern, _path([[-20, 0, 1.0], [20, 0, 1.0]]), [thin], 0.01, 0.5, StockCheck())
    assert [p.kind for p in r["problems"]] == ["gouge"] and r["problems"][0].depth > 1.0
    assert r["figures"]["poses"][1] == 80


def test_without_bad_depths_the_same_moves_fail_at_no_more_than_their_depth():
    """Repairs ask only which moves fail (``bad_depths=False``): on random moves over the ridge,
    turning and not, feed and rapid, the problems are on the same moves, of the same kinds, no
    deeper than the full measure says (a gouge deeper than the tolerance); fewer poses are
    measured."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, verify_moves

    ball = tool_from_entry(dict(name="B1", type="ball", diameter=1, flute_length=4, gauge_length=30), 1, "t")
    kern = solid_kernels(_ridge())
    rng = np.random.default_rng(3)
    n = 120
    pts = np.column_stack([rng.uniform(-4, 4, n), rng.uniform(-4, 4, n), rng.uniform(9.3, 10.8, n)])
    tilt, az = rng.uniform(0, 0.3, n) * (rng.random(n) < 0.5), rng.uniform(-np.pi, np.pi, n)
    axes = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    tp = _path(pts, axes, rng.random(n) < 0.2)
    stock = StockCheck(allowance=0.2, clearance=0.1)
    full = verify_moves(kern, tp, [ball], 0.01, 0.25, stock)
    lazy = verify_moves(kern, tp, [ball], 0.01, 0.25, stock, bad_depths=False)
    deepest = {}
    for p in full["problems"]:
        deepest[p.move, p.kind] = max(deepest.get((p.move, p.kind), 0.0), p.depth)
    found = {}
    for p in lazy["problems"]:
        found[p.move, p.kind] = max(found.get((p.move, p.kind), 0.0), p.depth)
    assert len(deepest) > 20 and set(found) == set(deepest)
    assert all(d <= deepest[k] + 1e-12 for k, d in found.items())
    assert all(d > 0.01 for (_, kind), d in found.items() if kind == "gouge")
    assert lazy["figures"]["poses"].sum() < full["figures"]["poses"].sum()


@pytest.mark.parametrize("move, ua, ub, q", [
    # (tip move, axis at the start, at the end, a 0.01 mm cube's centre): a review's cases
    ([14.510442788367692, -0.8939600422294134, -0.11099841928567467], [0.3916845491900154, 0.33428702566531193,
     0.8572254069949475], [-0.6722213898033749, -0.4916938794155183, 0.5534939313453554],
     [8.281367845811326, 1.3546558734108651, 10.273173443775432]),
    ([4.439998360545827, 3.918481682041161, 5.175517773865839], [-0.3148246858979567, -0.008334144963559975,
     0.9491132488681102], [0.8278191376654517, -0.43921470195267137, 0.3490070499337425],
     [10.81930013257224, -4.411432610527445, 9.6366263360848]),
])
def test_a_turning_move_over_a_speck_is_found_where_its_halves_would_miss_it(move, ua, ub, q):
    """A move turning 86-87 degrees past a 0.01 mm cube, 0.05 mm deep at its deepest (10^5 poses).
    Its halves joined by the normalised interpolation of their own end axes are other poses than
    the move's (the same tip, an axis off by millimetres at the flutes): proven so, the move
    passed. It is found."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, _Measure, move_poses

    ball = tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=12, gauge_length=30,
                                shank_diameter=2), 1, "t")
    ua, ub, q = (np.asarray(v) / (np.linalg.norm(v) if i < 2 else 1.0) for i, v in enumerate((ua, ub, q)))
    kern = solid_kernels(box(q - 0.005, q + 0.005))
    tp = Toolpath(np.array([np.zeros(3), move]), np.array([ua, ub]), np.zeros(2, bool), np.zeros(2, np.int64))
    s = np.linspace(0.0, 1.0, 100001)
    tip, axis = move_poses(tp, np.ones(len(s), np.int64), s)
    deepest = _Measure(kern, [ball], 0.01, StockCheck()).depths(tip, axis, np.zeros(len(s), np.int64),
                                                                np.zeros(len(s), bool))[0].max()
    assert deepest > 0.05
    r = verify_toolpath(kern, tp, [ball], tol=0.01, step=0.5)
    assert not r["ok"] and r["gouging_moves"] == 1


def test_a_ball_thinner_than_the_tolerance_turning_into_a_sphere_is_found():
    """A 0.02 mm ball (its radius within the 0.01 mm tolerance: its proof shrunk by the tolerance
    is of nothing) turning 1 degree on a move shorter than the step, 0.1 mm into a sphere between
    its clean end and its start: the ring's proof still sees it (a review found the swept axis's
    test claiming it, the ball's radius less the tolerance being 0)."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, verify_moves

    tool = tool_from_entry(dict(name="B002", type="ball", diameter=0.02, flute_length=1, gauge_length=30,
                                shank_diameter=3), 1, "t")
    kern = solid_kernels(sphere(20.0, rings=24, segments=48))
    tip = np.array([[12.230503, -1.76482, 15.554818], [12.434104, -2.035544, 15.496109]])
    ax = np.array([[0.5921832795249493, -0.0854500232396179, 0.8012597936870566],
                   [0.5990393599197689, -0.0980666727349294, 0.7946916213007496]])
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    tp = Toolpath(tip, ax, np.array([True, False]), np.zeros(2, np.int64))
    r = verify_moves(kern, tp, [tool], 0.01, 0.5, StockCheck(), only=np.array([False, True]))
    assert [p.kind for p in r["problems"]] == ["gouge"] and r["problems"][0].move == 1


def test_the_pairing_slack_bounds_how_far_a_piece_of_a_turning_move_is_from_its_proof():
    """A piece of a move between the fractions fa and fb, proven between its end poses: the
    kernels' interpolation meets each of the move's axes with the tip of another place along the
    piece. On random moves (turns up to 170 degrees) and pieces, each of 2001 poses of the move
    lies within ``pairing_slack`` of the pose of the proof's interpolation with the same axis
    (found by bisection along the arc, independently of the slack's formula); the bound is met
    within 10 % on a 30 degree turn's first half; a whole move and a fixed axis have none."""
    from meshmill.pathing.verify import move_poses, pairing_slack

    def off_and_slack(tp, fa, fb):
        slack = pairing_slack(tp, np.ones(1, np.int64), np.array([fa]), np.array([fb]))[0]
        (ta, tb), (xa, xb) = move_poses(tp, np.ones(2, np.int64), np.array([fa, fb]))
        s = np.linspace(fa, fb, 2001)
        tip, axis = move_poses(tp, np.ones(len(s), np.int64), s)
        want = np.arccos(np.clip(axis @ xa, -1.0, 1.0))  # each axis's place along the arc from xa
        lo, hi = np.zeros(len(s)), np.ones(len(s))
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            v = (1.0 - mid)[:, None] * xa + mid[:, None] * xb
            got = np.arccos(np.clip((v / np.linalg.norm(v, axis=1, keepdims=True)) @ xa, -1.0, 1.0))
            lo, hi = np.where(got < want, mid, lo), np.where(got < want, hi, mid)
        return np.linalg.norm(ta + lo[:, None] * (tb - ta) - tip, axis=1).max(), slack

    def move(ua, turn, travel):
        side = np.cross(ua, [0.3, -0.5, 0.8])
        side /= np.linalg.norm(side)
        ub = np.cos(turn) * ua + np.sin(turn) * side
        return Toolpath(np.array([np.zeros(3), travel]), np.array([ua, ub]), np.zeros(2, bool), np.zeros(2, np.int64))

    rng = np.random.default_rng(11)
    for _ in range(60):
        ua = rng.normal(size=3)
        tp = move(ua / np.linalg.norm(ua), rng.uniform(0.0, np.radians(170.0)), rng.normal(size=3) * 20.0)
        off, slack = off_and_slack(tp, *np.sort(rng.uniform(0.0, 1.0, 2)))
        assert off <= slack * (1.0 + 1e-6) + 1e-9
    off, slack = off_and_slack(move(np.array(UP), np.radians(30.0), np.array([10.0, 3.0, 1.0])), 0.0, 0.5)
    assert 0.9 * slack < off <= slack
    still = Toolpath(np.array([np.zeros(3), np.ones(3)]), np.array([UP, UP]), np.zeros(2, bool), np.zeros(2, np.int64))
    assert pairing_slack(still, np.ones(1, np.int64), np.array([0.2]), np.array([0.7]))[0] == 0.0
    assert pairing_slack(tp, np.ones(1, np.int64), np.array([0.0]), np.array([1.0]))[0] == 0.0


def test_a_piece_whose_pairing_slack_passes_the_tolerance_is_not_certified():
    """A move turning 140 degrees over 22 mm whose shank passes through a 0.1 mm cube (0.32 mm
    deep, 10^5 poses): its first quarter, proven between its end poses, is clear, but its pairing
    slack (1.0 mm) is more than the tolerance, and the kernels do not prove negative limits (a
    review found the quarter certified so). The collision is found, for a feed and a rapid."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, rapids_clear

    b6 = tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=12, gauge_length=30,
                              shank_diameter=4, holder_diameter=20, holder_length=20), 1, "t")
    kern = solid_kernels(box([-0.05] * 3, [0.05] * 3))
    tip = np.array([[-5.462710742945467, 13.728857149270889, -13.198372724034854],
                    [16.228679250688796, 18.690428025802397, -12.99561112230176]])
    axis = np.array([[0.15393118142275738, -0.7014090884819554, 0.6959385619296483],
                     [-0.7433644422599551, 0.39507538112308555, -0.5397450779895956]])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    for rapid in (False, True):
        r = verify_toolpath(kern, Toolpath(tip, axis, np.array([rapid, rapid]), np.zeros(2, np.int64)), [b6],
                            tol=0.01, step=0.5)
        assert not r["ok"] and "shank" in r["worst"][0]
        assert r["colliding_moves" if not rapid else "rapid_moves_touching"] == 1
    assert not rapids_clear(kern, [b6], 0.01, StockCheck(), tip[:1], axis[:1], tip[1:], axis[1:],
                            np.zeros(1, np.int64))[0]


def test_rapids_asked_only_whether_they_pass_are_judged_as_verification_judges_them():
    """rapids_clear measures poses only as deep as the tolerance (the kernels' ``stop``): on 400
    random rapids over and into a sphere, with an allowance and a clearance, its answers are
    those of the whole check of each rapid as a path, both ways."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, rapids_clear, verify_moves

    b6 = tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=12, gauge_length=30,
                              shank_diameter=4, holder_diameter=20, holder_length=20), 1, "t")
    kern = solid_kernels(sphere(10.0, 16, 32))
    stock = StockCheck(allowance=0.5, clearance=1.0)
    rng = np.random.default_rng(3)
    n = 400
    a = rng.uniform(-14, 14, (n, 3)) + [0, 0, 6]
    b = a + rng.normal(size=(n, 3)) * rng.uniform(0.1, 8, (n, 1))
    xa = np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), np.ones(n)])
    xa /= np.linalg.norm(xa, axis=1, keepdims=True)
    xb = np.where(rng.random((n, 1)) < 0.5, xa, xa + rng.normal(scale=0.2, size=(n, 3)))
    xb /= np.linalg.norm(xb, axis=1, keepdims=True)
    got = rapids_clear(kern, [b6], 0.01, stock, a, xa, b, xb, np.zeros(n, np.int64))
    tp = Toolpath(np.stack([a, b], 1).reshape(-1, 3), np.stack([xa, xb], 1).reshape(-1, 3), np.ones(2 * n, bool),
                  np.zeros(2 * n, np.int64))
    only = np.zeros(2 * n, bool)
    only[1::2] = True
    found = verify_moves(kern, tp, [b6], 0.01, 0.5, stock, only=only)
    ref = np.ones(n, bool)
    ref[[p.move // 2 for p in found["problems"]]] = False
    ref[[m // 2 for m in found["unresolved"]]] = False
    assert np.array_equal(got, ref)
    assert 40 < got.sum() < n - 40
