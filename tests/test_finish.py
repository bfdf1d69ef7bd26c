"""5-axis Z-constant ball finishing on analytic parts with known answers."""
import math

import numpy as np
import pytest

from meshmill.errors import InputError
from meshmill.geometry.shapes import overhang_column, post_with_fillet, revolve, sphere
from meshmill.ops.finish import FinishParams, finish, tilt_candidates
from meshmill.simulation.stock import Stock


def test_sphere_every_tool_fits(tools):
    tp, s, d = finish(sphere(20.0, 48, 96), tools, FinishParams(step_down=4.0))
    assert s["points_without_tool"] == 0
    assert (d["best"] == 0).all() and (d["contour_tool"] == 0).all()  # the largest ball everywhere
    assert s["verify"]["ok"] and s["machinable_contours"] == s["contours"]
    # the ball centre sits exactly R off the mesh wherever the CC normal is a facet normal or in
    # the normal cone of a convex edge: no gouge beyond rounding
    dist = d["kern"].mesh_distances(d["ce"])
    assert np.abs(dist - 10.0).max() < 1e-9


def test_concave_fillet_rejects_tools_larger_than_its_radius(tools):
    fillet = 4.0
    m = post_with_fillet(post_radius=10.0, fillet=fillet, height=30.0)
    tp, s, d = finish(m, tools, FinishParams(step_down=1.0))
    con = d["contours"]
    radii = np.array([t.radius for t in d["balls"]])
    band = (con.z > 0.05) & (con.z < fillet - 0.05)
    assert band.sum() >= 3
    for c in np.nonzero(band)[0]:
        best = d["best"][con.offsets[c]:con.offsets[c + 1]]
        # R 10 and 5 gouge the fillet; R 3 is the largest that fits, at every point
        assert (radii[best] == 3.0).all()
    assert s["verify"]["ok"]


def test_wall_under_an_overhang_needs_a_tilt(tools):
    m = overhang_column(radius=10.0, height=30.0, cap_radius=14.0, cap_height=5.0, segments=64)
    tp, s, d = finish(m, tools, FinishParams(step_down=2.0, max_tilt=60, tilt_step=5))
    con = d["contours"]
    wall = (con.z < 30.0) & (con.z > 10.0)
    idx = np.concatenate([np.arange(con.offsets[c], con.offsets[c + 1]) for c in np.nonzero(wall)[0]])
    cut = idx[d["cut"][idx]]
    assert len(cut) > 0
    tilt = np.degrees(np.arccos(d["axis"][cut, 2]))
    assert tilt.min() > 0  # a vertical holder would hit the cap
    radial = con.points[cut, :2] / np.linalg.norm(con.points[cut, :2], axis=1, keepdims=True)
    assert (np.einsum("ij,ij->i", d["axis"][cut, :2], radial) > 0).all()  # leaning away from the part
    assert s["verify"]["ok"] and s["points_tilted"] > 0


def test_no_tilt_allowed_leaves_points_out_instead_of_colliding(tools):
    m = overhang_column()
    tp, s, d = finish(m, tools, FinishParams(step_down=2.0, max_tilt=0.0))
    assert s["points_left_out"] > 0 and s["points_tilted"] == 0
    assert s["verify"]["ok"] and s["verify"]["colliding_moves"] == 0


def test_flat_facet_on_a_plane_is_machined_cleanly(tools):
    m = revolve([0, 20, 20, 10, 10, 0], [0, 0, 10, 10, 20, 20], 48)
    tp, s, d = finish(m, tools, FinishParams(step_down=5.0))
    assert s["contours"] == 3 and s["verify"]["ok"]


def test_summary_and_order_by_tool(tools):
    m = post_with_fillet()
    _, s1, _ = finish(m, tools, FinishParams(step_down=2.0, order="contour"))
    tp, s2, _ = finish(m, tools, FinishParams(step_down=2.0, order="tool"))
    for key in ("contours", "machinable_contours", "cc_points", "points_left_out", "tools_used", "seconds", "verify"):
        assert key in s2
    assert s2["verify"]["ok"]
    changes = int((np.diff(tp.tool) != 0).sum())
    assert changes == len(s2["tools_used"]) - 1  # each tool loaded once
    assert s1["cc_points"] == s2["cc_points"] and s1["points_cut"] == s2["points_cut"]


def test_deterministic(tools, tmp_path):
    from meshmill.toolpath.cldata import write_apt

    m = post_with_fillet()
    for name in ("a.cl", "b.cl"):
        tp, _, _ = finish(m, tools, FinishParams(step_down=3.0))
        write_apt(tmp_path / name, tp, tools)
    assert (tmp_path / "a.cl").read_text() == (tmp_path / "b.cl").read_text()


def test_unmachinable_contour_is_reported_not_cut(tools):
    # a narrow slot between two columns is too thin for the smallest ball: revolve a groove of
    # width 1 mm (radius 0.5) on a cylinder; the B2 ball (R 1) cannot enter it
    r = [0, 10, 10, 9, 9, 10, 10, 0]
    z = [0, 0, 10, 10, 10.5, 10.5, 20, 20]
    m = revolve(r, z, 64)
    tp, s, d = finish(m, tools, FinishParams(step_down=0.25))
    con = d["contours"]
    slot = (con.z > 10.0) & (con.z <= 10.5)  # a plane on the upper face machines the slot wall below it
    assert slot.any()
    assert (d["contour_tool"][slot] == -1).all()
    assert s["machinable_contours"] == s["contours"] - slot.sum()
    assert len(s["unmachinable_contours"]) == slot.sum()
    assert not d["cut"][np.concatenate([np.arange(con.offsets[c], con.offsets[c + 1]) for c in np.nonzero(slot)[0]])].any()
    assert s["verify"]["ok"]


def test_candidates_start_vertical_and_stay_within_max_tilt():
    cand, tilt = tilt_candidates(60, 5)
    assert tuple(cand[0]) == (0.0, 0.0)
    assert tilt.max() <= math.radians(60) + 1e-9
    assert (np.diff(np.ceil(tilt / math.radians(5) - 1e-6)) >= 0).all()


@pytest.mark.parametrize("kw, message", [
    (dict(step_down=0), "^step_down must be a number of mm >= 0.0001, got 0$"),
    (dict(step_down=1, max_tilt=95), "^max_tilt must be a number of deg from 0 to below 90, got 95$"),
    (dict(step_down=1, order="zigzag"), "^order must be one of tool, contour, got 'zigzag'$"),
    (dict(step_down=100), "larger than the part"),
    (dict(step_down=1, safe_z=5), "^safe_z 5 is too low"),
])
def test_bad_parameters(tools, kw, message):
    with pytest.raises(InputError, match=message) as e:
        finish(sphere(10.0, 8, 16), tools, FinishParams.checked(dict(part=None, tools=tools, **kw)))
    assert e.value.params[0] == (next(iter(kw)) if len(kw) == 1 else list(kw)[-1])


def test_no_ball_tool(tools):
    from meshmill.tools.table import tool_from_entry

    flat = [tool_from_entry(dict(name="F6", type="flat", diameter=6, flute_length=10, gauge_length=30), 1, "t")]
    with pytest.raises(InputError, match="no ball tool"):
        finish(sphere(10.0, 8, 16), flat, FinishParams(step_down=2))


def _ball_centres(tp, tools):
    """Ball centres ``(k, 3)`` and radii ``(k,)`` of the feed moves' points."""
    feed = ~tp.rapid
    R = np.array([tools[t].radius for t in tp.tool[feed]])
    return tp.tip[feed] + R[:, None] * tp.axis[feed], R


def test_a_wound_open_propeller_keeps_every_ball_centre_outside_its_solid(tools):
    from conftest import propeller_like, winding_number
    from meshmill.kernels.bvh import build_bvh
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box
    from meshmill.kernels import cpu

    v, f = propeller_like()
    part = mesh_from_arrays(v, f, "propeller")
    assert not part.flipped and part.turned_faces == 0
    tp, s, d = finish(part, tools, FinishParams(step_down=3.0, sample=1.0, tilt_step=10))
    assert s["verify"]["ok"] and s["points_cut"] > 200
    centre, R = _ball_centres(tp, tools)
    # independent: the closed bodies the part is made of (the hub with its ends closed): winding
    # numbers from solid angles, and distances to each body
    hub = revolve([0, 2, 8, 8, 3, 0], [0, 0, 0, 12, 12, 12], segments=48)
    bodies = [hub]
    for k in range(3):
        a = 2 * np.pi * k / 3
        b = box([11, -0.8, 3], [22, 0.8, 9])
        rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        bodies.append(mesh_from_arrays(b.vertices @ rot.T, b.faces, "blade"))
    for body in bodies:
        assert (winding_number(centre, body.vertices, body.faces) < 0.5).all()
        gap = cpu.mesh_distances(centre, build_bvh(body.vertices, body.faces).arrays)
        assert (gap >= R - s["tolerance"] - 1e-6).all()


def _dome(radius=20.0, rings=16, segments=48):
    """An open hemispherical sheet (a skull cap), facing out, its rim at z = 0."""
    t = np.linspace(0.0, 0.5 * np.pi, rings + 1)
    cap = revolve(np.r_[0.0, radius * np.cos(t[:-1]), 0.0], np.r_[0.0, radius * np.sin(t[:-1]), radius], segments)
    bottom = np.isclose(cap.vertices[cap.faces][:, :, 2], 0.0).all(axis=1)
    from meshmill.geometry.mesh import mesh_from_arrays

    return mesh_from_arrays(cap.vertices, cap.faces[~bottom], "dome")


def test_an_open_sheet_is_finished_without_dipping_under_its_edge(tools):
    from conftest import winding_number
    from meshmill.ops.simulate import simulate

    dome = _dome()
    assert dome.summary()["pieces"]["sheets"] == 1
    tp, s, d = finish(dome, tools, FinishParams(step_down=4.0, sample=1.0, tilt_step=10))
    assert s["verify"]["ok"] and s["points_cut"] > 100
    # independent: the solid the sheet bounds from below, built as a closed mesh (the dome on a
    # cylinder down to the floor), simulated with dexels from a 0.5 mm allowance
    floor = dome.solid().floor
    t = np.linspace(0.0, 0.5 * np.pi, 17)
    block = revolve(np.r_[0.0, 20.0, 20.0 * np.cos(t[1:-1]), 0.0], np.r_[floor, floor, 20.0 * np.sin(t[1:-1]), 20.0],
                    48)
    centre, R = _ball_centres(tp, tools)
    assert (winding_number(centre, block.vertices, block.faces) < 0.5).all()
    dev, summary, *_ = simulate(block, tp, tools, 0.5, stock=Stock.offset(0.5))
    assert dev["gouge_max"] < 0.05 and summary["rapid_moves_cutting"] == 0 and summary["colliding_moves"] == 0


@pytest.mark.slow
def test_rapids_keep_clear_of_the_stock_the_finish_starts_from(tools):
    from meshmill.ops.simulate import simulate

    m = overhang_column()
    tp, s, d = finish(m, tools, FinishParams(step_down=2.0))
    assert s["verify"]["ok"] and s["stock"] == {"allowance": 0.5, "mesh": False, "clearance": 0.5, "shank_and_holder": True}
    # independent: the dexel simulation from the stock the finish assumes (0.5 mm on the part)
    dev, summary, *_ = simulate(m, tp, tools, 0.25, stock=Stock.offset(0.5))
    assert summary["rapid_moves_cutting"] == 0 and summary["colliding_moves"] == 0
    # and every rapid keeps the ball's centre the radius, the allowance and the clearance off the part
    rapid = np.nonzero(tp.rapid)[0]
    f = np.linspace(0, 1, 41)[:, None]
    pts, radii = [], []
    for i in rapid[rapid > 0]:
        R = tools[tp.tool[i]].radius
        a = tp.tip[i - 1] + R * tp.axis[i - 1]
        b = tp.tip[i] + R * tp.axis[i]
        pts.append(a + f * (b - a))
        radii.append(np.full(len(f), R))
    gap = d["kern"].mesh_distances(np.concatenate(pts)) - np.concatenate(radii)
    assert gap.min() >= 1.0 - 1e-6


def test_every_run_of_a_contour_that_a_ball_fits_is_cut(tools):
    from conftest import brute_point_triangle_dist

    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box

    # two towers on a base with a 1 mm gap between them: no ball of the table (smallest R 1) fits
    # the gap's walls, every other point of the towers' contours fits one
    parts = [box([0, 0, 0], [40, 20, 5]), box([0, 0, 0], [19.5, 20, 20]), box([20.5, 0, 0], [40, 20, 20])]
    m = mesh_from_arrays(np.vstack([p.vertices for p in parts]),
                         np.vstack([p.faces + 8 * i for i, p in enumerate(parts)]), "towers")
    whole = finish(m, tools, FinishParams(step_down=3.0, whole_contours=True))
    runs = finish(m, tools, FinishParams(step_down=3.0))
    for tp, s, d in (whole, runs):
        assert s["verify"]["ok"]
        con = d["contours"]
        tower = np.repeat(con.z > 5.0, np.diff(con.offsets))
        x, nx = con.points[:, 0], con.normals[:, 0]
        in_gap = tower & (((np.abs(x - 19.5) < 1e-9) & (nx > 0.5)) | ((np.abs(x - 20.5) < 1e-9) & (nx < -0.5)))
        assert in_gap.any() and not d["cut"][in_gap].any()
        if s["whole_contours"]:
            assert not d["cut"][tower].any()  # seed 004: a contour with one unfit point is not cut
        else:
            assert d["cut"][tower & ~in_gap].mean() > 0.8 and s["partly_cut_contours"] > 0  # the corners by the gap: no ball
            # independent: every cut ball centre keeps its radius from the triangles, less the tolerance
            cut = np.nonzero(d["cut"])[0]
            r = np.array([b.radius for b in d["balls"]])[d["point_tool"][cut]]
            tris = m.vertices[m.faces]
            dist = np.array([brute_point_triangle_dist(p, tris).min() for p in d["ce"][cut]])
            assert (dist >= r - 0.01 - 1e-9).all()


def _frustum_column(segments=64):
    """A frustum rising at 30 deg from r 20 to r 10, a vertical column r 10 above it and a flat top:
    ``(mesh, height of the frustum's top, of the part)``."""
    t = 10 * math.tan(math.radians(30))
    return revolve([0, 20, 10, 10, 0], [0, 0, t, t + 10, t + 10], segments), t, t + 10


def test_scallop_adds_levels_only_where_the_slope_needs_them_and_rasters_the_flats(tools):
    from meshmill.ops.finish_levels import scallop_spacing

    m, t, top = _frustum_column()
    h, step = 0.05, 1.5
    tp, s, d = finish(m, tools, FinishParams(step_down=step, scallop=h, sample=1.0))
    assert s["verify"]["ok"]
    con, cut = d["contours"], d["cut"]
    z = np.repeat(con.z, np.diff(con.offsets))
    radius = np.array([b.radius for b in d["balls"]])[d["point_tool"]]
    nz = con.normals[:, 2]
    # the column: a 20 mm ball leaves 0.028 mm between levels 1.5 mm apart: the step-down's alone
    column = cut & (np.abs(nz) < 1e-9) & (z > t + 1e-6)
    assert column.sum() > 100
    k = (top - z[column]) / step
    assert np.abs(k - np.round(k))[k > 1].max() < 1e-9
    assert np.all(np.abs(k[k < 1] - 0.5) < 1e-9)  # the top and the first level: one-sided, one level between
    # the 30 deg frustum, cut by the 20 mm ball but by its concave edge: levels close enough for that
    # ball (dz / sin 30 on the surface), the lowest within half that of the bottom (no pass there)
    frustum = cut & (np.abs(nz - math.cos(math.radians(30))) < 0.01) & (radius == 10.0)
    levels = np.unique(z[frustum])
    gap = np.diff(levels)
    dz_max = float(scallop_spacing(10.0, h)) * math.sin(math.radians(30))
    assert len(levels) >= 3 and gap.max() <= dz_max + 1e-9 and levels[0] <= 0.5 * dz_max + 1e-9
    # the flat top: raster passes, not levels; its area reported
    sh = s["scallop"]["shallow"]
    assert sh["passes"] > 0 and s["raster_points_cut"] > 0
    assert sh["area_mm2"] == pytest.approx(0.5 * 64 * 100 * math.sin(2 * math.pi / 64), rel=1e-9)
    assert s["scallop"]["planes_added"] > 0 and s["levels"] > len(np.unique(np.round((top - z) / step)))


def test_scallop_is_met_on_the_surface_the_balls_reach_by_simulation(tools):
    """Independent check: cut the finish out of the part with 0.5 mm on it (exact dexel
    simulation) and measure the surface: within [-tol, scallop + tol] nearly everywhere but the
    part's underside, which no tool reaches."""
    from scipy.spatial import cKDTree

    from meshmill.geometry.analysis import sample_surface
    from meshmill.ops.finish_areas import AREA_STATUS, surface_status
    from meshmill.ops.simulate import simulate

    m, t, top = _frustum_column(32)
    h = 0.05
    tp, s, d = finish(m, tools, FinishParams(step_down=2.0, scallop=h, sample=1.0))
    radii = np.array([b.radius for b in d["balls"]])
    assert s["verify"]["ok"]
    dev, summary, _, _, ends, _ = simulate(m, tp, tools, 0.25, stock=Stock.offset(0.5))
    p, w, face = sample_surface(m, 0.25)
    e = ends["e"][cKDTree(ends["points"]).query(p)[1]]
    # reached: not the underside, and the nearest CC point or raster contact fits a ball (the
    # column's foot, in the concave edge, fits none of the table)
    status = surface_status(m, d["kern"], radii, 0.01, 60.0, p, face, d["surface_points"], d["surface_status"],
                            d["raster_from"], d["raster_reach"])
    reached = status == AREA_STATUS.index("cut")
    band = (e >= -0.01) & (e <= h + 0.01)
    assert w[band & reached].sum() / w[reached].sum() > 0.97
    assert dev["gouge_max"] <= 0.01 + 1e-6
    a = s["area_mm2"]
    assert a["facing_down"] == pytest.approx(w[m.face_normals[face, 2] < -0.5].sum(), rel=1e-9)
    assert a["cut"] + a["facing_down"] + a["no_ball"] == pytest.approx(a["total"], rel=1e-6)
    assert 0 < a["no_ball"] < 0.05 * a["total"]


def test_a_run_takes_the_largest_ball_stretch_by_stretch(tools):
    from meshmill.ops.finish_balls import stretch_ranks

    s = np.arange(12) * 0.5
    # a long stretch of ball 0, a narrow spot (one point) for ball 2, a long stretch of ball 1
    best = np.array([0, 0, 0, 0, 0, 2, 1, 1, 1, 1, 1, 1])
    r = stretch_ranks(best, s, 1.0)
    assert (r >= best).all()  # never a larger ball than fits
    assert r[0] == 0 and r[-1] == 1 and r[5] == 2
    two = np.flatnonzero(r == 2)  # the narrow spot's ball spreads to one stretch of 1 mm
    assert (np.diff(two) == 1).all() and 5 in two and s[two[-1]] - s[two[0]] >= 1.0 - 1e-12
    # every stretch spans min_run, and never a larger ball than fits, on random runs
    rng = np.random.default_rng(1)
    for _ in range(100):
        n = int(rng.integers(2, 60))
        s_ = np.cumsum(rng.uniform(0.01, 0.8, n))
        b = rng.integers(0, 4, n)
        r = stretch_ranks(b, s_, 1.0)
        starts = np.r_[0, np.flatnonzero(np.diff(r)) + 1]
        ends = np.r_[starts[1:], n]
        assert (r >= b).all()
        assert len(starts) == 1 or (s_[ends - 1] - s_[starts] >= 1.0 - 1e-12).all()
    # a short stretch of a larger ball between smaller ones takes theirs
    assert (stretch_ranks(np.array([1, 1, 1, 1, 0, 1, 1, 1]), s[:8], 1.0) == 1).all()
    assert (stretch_ranks(np.array([0, 0, 0, 0]), s[:4], 1.0) == 0).all()


def test_axis_search_keeps_a_shank_bottom_hovering_over_the_part_out_of_the_allowance():
    """The shank's flat bottom 0.3 mm above a step's top, within its radius: the allowance (0.5 mm)
    on the step reaches it. The axis search must see it as verification does (the cylinders grown
    at their ends too), or every such pose fails verification and is left out."""
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.verify import StockCheck, _Measure
    from meshmill.tools.table import Tool, pack_cylinders

    parts = [box([-10, -10, -5], [1, 10, 0]), box([1, -10, -5], [10, 10, 2.7])]
    m = mesh_from_arrays(np.vstack([p.vertices for p in parts]), np.vstack([p.faces + 8 * i for i, p in
                                                                            enumerate(parts)]), "step")
    kern = solid_kernels(m, "cpu")
    ball = Tool(name="B1", type="ball", diameter=1.0, corner_radius=0.5, flute_length=3.0, gauge_length=30.0,
                shank_diameter=4.0, holder_diameter=25.0, holder_length=40.0, number=1)
    ce = np.array([[0.4, 0.0, 0.5]])  # the ball on the floor, 0.1 mm from the step's wall
    args = (ce, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]), np.array([0]), np.zeros((1, 2)),
            np.zeros(1), 0.0, np.array([0.5]))
    grown, _ = pack_cylinders([ball], 0.01, 0.5)
    bare, _ = pack_cylinders([ball], 0.01, 0.0)
    assert kern.axis_search(*args, grown, np.array([0, 1]))[0] == -1
    assert kern.axis_search(*args, bare, np.array([0, 1]))[0] == 0
    meas = _Measure(kern, [ball], 0.01, StockCheck(allowance=0.5))
    *_, in_stock = meas.depths(ce - [0, 0, 0.5], np.array([[0.0, 0, 1]]), np.array([0]), np.array([False]))
    assert in_stock[0] == pytest.approx(0.2, abs=1e-6)


@pytest.mark.parametrize("into, vertical", [(0.008, False), (0.004, True)])
def test_an_axis_keeps_the_flutes_within_half_the_tolerance(into, vertical):
    """A ball on a floor, a wall beside it from 1 mm above its centre, ``into`` mm nearer the axis
    than the flutes' radius: the vertical axis puts the flutes into the wall by that much. The
    axis search (:func:`axis_cylinders`) takes it only within half the tolerance (the moves between
    poses may take the rest); else the chosen axis keeps them so, as verification's exact measure
    of the pose says."""
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box
    from meshmill.kernels.backend import solid_kernels
    from meshmill.kernels.cpu import dev
    from meshmill.ops.finish import axis_cylinders, finish_setup
    from meshmill.pathing.verify import StockCheck, _Measure
    from meshmill.tools.table import Tool

    parts = [box([-20, -20, -5], [20, 20, 0]), box([3.0 - into, -20, 4], [20, 20, 11])]
    m = mesh_from_arrays(np.vstack([p.vertices for p in parts]), np.vstack([p.faces + 8 * i for i, p in
                                                                            enumerate(parts)]), "wall")
    kern = solid_kernels(m, "cpu")
    ball = Tool(name="B6", type="ball", diameter=6.0, corner_radius=3.0, flute_length=15.0, gauge_length=40.0,
                shank_diameter=6.0, holder_diameter=25.0, holder_length=30.0, number=1)
    setup = finish_setup(m, [ball], FinishParams(tolerance=0.01, step_down=1.0))
    cand, tilt = tilt_candidates(30.0, 5.0)
    feed, side = np.array([[0.0, -1.0, 0.0]]), np.array([[-1.0, 0.0, 0.0]])  # the outward side away from the wall
    ce = np.array([[0.0, 0.0, 3.0]])
    found = kern.axis_search(ce, feed, side, np.array([0]), cand, tilt, 0.0, np.array([3.0]), axis_cylinders(setup),
                             np.array([0, 1]))[0]
    assert (found == 0) == vertical and found >= 0
    meas = _Measure(kern, [ball], 0.01, StockCheck())
    axes = np.array([[0.0, 0.0, 1.0], dev.tilted_axis(*feed[0], *side[0], *cand[found])])
    end, *_ = meas.depths(ce - 3.0 * axes, axes, np.zeros(2, np.int64), np.zeros(2, bool))
    assert end[0] == pytest.approx(into, abs=1e-9)  # the vertical axis: the flutes that deep
    assert end[1] <= 0.005 + 1e-12


def test_no_move_swings_the_axis_past_the_pole_of_the_machine(tmp_path, tools_file, capsys):
    from meshmill.cli import main
    from meshmill.ops.finish_pole import POLE_MARGIN, POLE_STEP, _pole_distance, around_pole
    from meshmill.toolpath.cldata import write_apt
    from meshmill.toolpath.model import Toolpath
    from meshmill.tools.table import load_tools

    tools = load_tools(tools_file)
    t = math.radians(10)
    a0 = np.array([math.sin(t), 0, math.cos(t)])
    a1 = np.array([math.sin(t) * math.cos(math.radians(179)), math.sin(t) * math.sin(math.radians(179)), math.cos(t)])
    c0, c1 = np.array([0, 0, 13.0]), np.array([10, 0, 13.0])  # B6: centres 3 mm over the tips
    axes, centres = around_pole(a0, a1, c0, c1, 3.0)
    chain = np.vstack([a0, axes, a1])
    dist, _ = _pole_distance(chain[:-1], chain[1:])
    assert len(axes) >= 179 / POLE_STEP - 1 and dist.min() >= math.radians(POLE_MARGIN) - 1e-9
    assert np.allclose(np.linalg.norm(axes, axis=1), 1.0)
    assert np.allclose(np.cross(centres - c0, c1 - c0), 0.0) and np.all(np.diff(centres[:, 0]) > 0)  # on the segment
    # through the pole exactly, or from and to it, nothing is needed
    assert len(around_pole(a0, a0 * [-1, 1, 1], c0, c1, 3.0)[0]) == 0
    assert len(around_pole(a0, np.array([0, 0, 1.0]), c0, c1, 3.0)[0]) == 0

    def program(axes_between, centres_between):
        ax = np.vstack([a0, a0, axes_between, a1, a1])
        ce = np.vstack([c0 + [0, 0, 40], c0, centres_between, c1, c1 + [0, 0, 40]])
        tp = Toolpath(ce - 3.0 * ax, ax, np.r_[True, True, np.zeros(len(axes_between) + 1, bool), True],
                      np.full(len(ax), 2))
        write_apt(tmp_path / "p.cl", tp, tools)
        return main(["post", str(tmp_path / "p.cl"), "--machine", "table-table-ac", "--tools", str(tools_file),
                     "--clearance", "75", "--out", str(tmp_path / "p.nc")])

    capsys.readouterr()
    assert program(np.empty((0, 3)), np.empty((0, 3))) == 2 and "pole" in capsys.readouterr().err
    assert program(axes, centres) == 0


def test_the_summary_says_how_much_surface_was_cut_and_why_the_rest_was_not(tools):
    # a 48-gon column 20 mm tall: its walls cut, its flat top left to a raster (no --scallop), its
    # underside facing down
    m = revolve([0, 10, 10, 0], [0, 0, 20, 20], 48)
    tp, s, d = finish(m, tools, FinishParams(step_down=2.0))
    perimeter = 2 * 48 * 10 * math.sin(math.pi / 48)
    disc = 0.5 * 48 * 100 * math.sin(2 * math.pi / 48)
    a = s["area_mm2"]
    assert a["cut"] == pytest.approx(20 * perimeter, rel=1e-9)
    assert a["shallow"] == pytest.approx(disc, rel=1e-9) and a["facing_down"] == pytest.approx(disc, rel=1e-9)
    assert a["no_ball"] == a["no_axis"] == a["short_runs"] == a["left_out"] == 0
    # with --scallop the top is rastered: cut
    tp, s, d = finish(m, tools, FinishParams(step_down=2.0, scallop=0.05))
    assert s["area_mm2"]["cut"] == pytest.approx(20 * perimeter + disc, rel=1e-9)
    # the towers with a 1 mm gap: the gap's walls fit no ball, and say so
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box

    parts = [box([0, 0, 0], [40, 20, 5]), box([0, 0, 0], [19.5, 20, 20]), box([20.5, 0, 0], [40, 20, 20])]
    m = mesh_from_arrays(np.vstack([p.vertices for p in parts]),
                         np.vstack([p.faces + 8 * i for i, p in enumerate(parts)]), "towers")
    tp, s, d = finish(m, tools, FinishParams(step_down=3.0))
    wall = 20 * (20 - 5)  # each gap wall above the base, 20 mm wide
    assert s["area_mm2"]["no_ball"] >= 2 * wall * 0.8


def test_leaving_the_pole_the_axis_tilts_out_where_c_is_held_and_turns_gently(tmp_path, tools_file, capsys):
    from meshmill.cli import main
    from meshmill.ops.finish_pole import POLE_STEP, gentle_turns
    from meshmill.toolpath.cldata import write_apt
    from meshmill.toolpath.model import Toolpath
    from meshmill.tools.table import load_tools

    tools = load_tools(tools_file)
    t = math.radians(10)

    def tilted(az):
        return [math.sin(t) * math.cos(math.radians(az)), math.sin(t) * math.sin(math.radians(az)), math.cos(t)]

    # B6 (index 2) feeding along X: tilted at azimuth 0, vertical, then tilted at azimuth 135
    ax = np.array([tilted(0), tilted(0), [0, 0, 1.0], tilted(135), tilted(135)])
    ce = np.array([[0, 0, 53.0], [0, 0, 13.0], [5, 0, 13.0], [10, 0, 13.0], [10, 0, 53.0]])
    tp = Toolpath(ce - 3.0 * ax, ax, np.array([True, True, False, False, True]), np.full(5, 2))
    radius = np.array([tool.radius for tool in tools])
    out, source = gentle_turns(tp, radius, math.radians(0.05))
    assert (np.diff(source) >= 0).all() and len(np.unique(source)) == len(tp)
    tilt = np.degrees(np.arccos(np.clip(out.axis[:, 2], -1, 1)))
    az = np.degrees(np.arctan2(out.axis[:, 1], out.axis[:, 0]))
    off = tilt > 1e-6
    both = off[1:] & off[:-1]
    turn = np.abs((np.diff(az) + 180) % 360 - 180)
    assert turn[both].max() <= POLE_STEP + 1e-9
    first_off = np.flatnonzero(off & (np.arange(len(off)) > 2))[0]  # the first tilted pose after the vertical one
    assert abs(az[first_off]) < 1e-9  # tilts out where C was held (azimuth 0)
    # the ball centres stay on their segments
    centre = out.tip + 3.0 * out.axis
    feed = ~out.rapid
    assert np.allclose(centre[feed][:, 1:], [0.0, 13.0])
    for path, ok in ((tp, False), (out, True)):
        write_apt(tmp_path / "p.cl", path, tools)
        capsys.readouterr()
        rc = main(["post", str(tmp_path / "p.cl"), "--machine", "table-table-ac", "--tools", str(tools_file),
                   "--clearance", "75", "--out", str(tmp_path / "p.nc")])
        err = capsys.readouterr().err
        assert (rc == 0 and "stray" not in err) if ok else (rc == 2 or "stray" in err)


def test_a_crease_too_sharp_for_any_ball_to_touch_is_not_cut(tools):
    """Two facets folding back on each other (a 178 deg concave crease): the ball touching both
    would sit far out along the bisector, beyond the slicer's cap; such a ball touches nothing and
    its point fits no ball (no passes floating 10 R away from the part)."""
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.slicing import MIN_HALF_COS

    # a block whose top has a slit 0.1 mm wide at the top, 10 mm deep (walls 0.3 deg off vertical)
    v = np.array([[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0],
                  [-10, -10, 20], [-0.05, -10, 20], [0, -10, 10], [0.05, -10, 20], [10, -10, 20],
                  [-10, 10, 20], [-0.05, 10, 20], [0, 10, 10], [0.05, 10, 20], [10, 10, 20]], float)
    f = [[0, 2, 1], [0, 3, 2],  # bottom
         [0, 1, 8], [0, 8, 7], [0, 7, 6], [0, 6, 5], [0, 5, 4],  # front (y = -10)
         [3, 9, 10], [3, 10, 11], [3, 11, 12], [3, 12, 13], [3, 13, 2],  # back (y = 10)
         [0, 4, 9], [0, 9, 3], [1, 2, 13], [1, 13, 8],  # sides
         [4, 5, 10], [4, 10, 9], [7, 8, 13], [7, 13, 12],  # top, either side of the slit
         [5, 6, 11], [5, 11, 10], [6, 7, 12], [6, 12, 11]]  # the slit's walls
    m = mesh_from_arrays(v, np.array(f), "slit")
    tp, s, d = finish(m, tools, FinishParams(step_down=2.0))
    con = d["contours"]
    capped = con.reach >= 1.0 / MIN_HALF_COS - 1e-9
    assert capped.any() and (d["best"][capped] < 0).all() and not d["cut"][capped].any()
    # every ball cut touches the part: none floats off it
    cut = np.nonzero(d["cut"])[0]
    radius = np.array([b.radius for b in d["balls"]])[d["point_tool"][cut]]
    assert np.abs(d["kern"].mesh_distances(d["ce"][cut]) - radius).max() <= 0.01 + 1e-9
    assert s["verify"]["ok"]


def test_axis_search_with_witnesses_finds_the_first_clear_candidate():
    """The search skips candidates whose body holds a point of the part found inside an earlier
    candidate's (or an earlier point's): on points along the walls and floor of a pocket, in
    chunks that share their witnesses, it returns exactly the first candidate whose body clears
    the part when each is searched on its own."""
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box
    from meshmill.kernels.backend import solid_kernels
    from meshmill.kernels.cpu import dev
    from meshmill.ops.finish import tilt_candidates
    from meshmill.tools.table import Tool, pack_cylinders

    walls = [box([-20, -20, 0], [20, 20, 5]), box([-20, -20, 5], [-12, 20, 30]), box([12, -20, 5], [20, 20, 30]),
             box([-12, -20, 5], [12, -12, 30]), box([-12, 12, 5], [12, 20, 18])]
    m = mesh_from_arrays(np.vstack([p.vertices for p in walls]),
                         np.vstack([p.faces + 8 * i for i, p in enumerate(walls)]), "pocket")
    kern = solid_kernels(m, "cpu")
    ball = Tool(name="B2", type="ball", diameter=2.0, corner_radius=1.0, flute_length=6.0, gauge_length=35.0,
                shank_diameter=6.0, holder_diameter=32.0, holder_length=40.0, number=1)
    body, _ = pack_cylinders([ball], 0.01, 0.5)
    cand, tilt = tilt_candidates(60.0, 5.0)
    rng = np.random.default_rng(3)
    k = 160
    # ball centres 1 mm off a wall (x = -12 or y = 12) or on the floor, at z on the grid and off it
    x = np.where(rng.random(k) < 0.5, -11.0, rng.uniform(-11, 11, k))
    y = np.where(x == -11.0, rng.uniform(-11, 11, k), 11.0)
    z = np.where(rng.random(k) < 0.3, 6.0, np.round(rng.uniform(6, 29, k), 0))
    ce = np.column_stack([x, y, z])
    feed = np.tile([0.0, 1.0, 0.0], (k, 1))
    side = np.cross(feed, [0.0, 0.0, 1.0])
    tool = np.zeros(k, np.int64)
    found = kern.axis_search(ce, feed, side, tool, cand, tilt, 0.0, np.array([1.0]), body, np.array([0, 1]))
    arrays = kern.mesh
    for i in range(k):
        first = -1
        for c in range(len(cand)):
            u = dev.tilted_axis(*feed[i], *side[i], *cand[c])
            if dev.body_clear(*(ce[i] - np.array(u)), *u, *body, 0, *arrays, np.empty(128, np.int32)):
                first = c
                break
        assert found[i] == first
    assert (found > 0).sum() > 20 and (found < 0).sum() > 5 and (found == 0).sum() > 5


# --- the stages alone ------------------------------------------------------------------------------

def _stage_setup(mesh, tools, **kw):
    from meshmill.kernels.backend import solid_kernels
    from meshmill.ops.finish import ContourWork, finish_setup

    setup = finish_setup(mesh, tools, FinishParams(**kw))
    kern = solid_kernels(mesh)
    return setup, kern, ContourWork(kern, mesh)


def test_the_contours_stage_slices_a_sphere(tools):
    """CC points of a sphere of radius 10 every 2 mm from the top: on the sphere (within its facets'
    chordal error), outward normals along the radius, one closed contour per level at the level's
    height, the points at most a sample apart."""
    from meshmill.ops.finish import contours

    m = sphere(10.0, rings=96, segments=192)
    setup, kern, _ = _stage_setup(m, tools, step_down=2.0, sample=0.5)
    con, scallop = contours(m, kern, setup)
    assert scallop is None and len(con) == len(setup.levels) and con.closed.all()
    assert np.array_equal(np.sort(con.z)[::-1], setup.levels)
    r = np.linalg.norm(con.points, axis=1)
    assert np.all(r <= 10.0 + 1e-9) and np.all(r >= 10.0 * math.cos(math.pi / 96) - 1e-9)
    assert np.all(np.einsum("ij,ij->i", con.normals, con.points / r[:, None]) > math.cos(math.radians(3.0)))
    assert np.allclose(con.points[:, 2], np.repeat(con.z, np.diff(con.offsets)))
    for c in range(len(con)):
        p = con.points[con.offsets[c]:con.offsets[c + 1]]
        assert np.linalg.norm(np.diff(np.r_[p, p[:1]], axis=0), axis=1).max() <= 0.5 + 1e-9


def test_the_balls_stage_takes_a_smaller_ball_in_a_slot(tools):
    """Two blocks 8 mm apart: on the walls of the slot between them no ball wider than the slot
    fits (B20 and B10 would reach the other wall), B6 does; on the outer walls B20 does. Each run
    takes its points' balls."""
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box
    from meshmill.ops.finish import contours, point_balls

    a, b = box([0, 0, 0], [20, 30, 20]), box([28, 0, 0], [48, 30, 20])
    m = mesh_from_arrays(np.r_[a.vertices, b.vertices], np.r_[a.faces, b.faces + len(a.vertices)], "slot")
    setup, kern, work = _stage_setup(m, tools, step_down=5.0, sample=1.0)
    assert [t.name for t in setup.balls] == ["B20", "B10", "B6", "B2"]
    con, _ = contours(m, kern, setup)
    balls = point_balls(con, setup, work)
    x, y = con.points[:, 0], con.points[:, 1]
    in_slot = (np.isclose(x, 20.0) | np.isclose(x, 28.0)) & (y > 3.0) & (y < 27.0)  # 3 mm off the slot's ends
    outside = (np.isclose(x, 0.0) | np.isclose(x, 48.0)) & (y > 10.0) & (y < 20.0)
    assert in_slot.sum() > 50 and outside.sum() > 20
    assert (balls.best[in_slot] == 2).all() and (balls.best[outside] == 0).all()
    assert (balls.point_tool[in_slot] == 2).all() and (balls.point_tool[outside] == 0).all()
    assert (balls.point_tool >= balls.best).all()  # a run never takes a larger ball than a point's own


def test_the_verify_and_repair_stage_splits_a_pass_at_a_bad_move(tools):
    """A pass over a block's top whose middle point dips 1 mm into it: the two moves to and from
    that point gouge; one round of repairs splits the pass around them, and the path of the two
    pieces verifies clean."""
    from meshmill.geometry.shapes import box
    from meshmill.ops.finish import Passes, path_builder, path_check, verify_and_repair

    m = box([0, 0, 0], [40, 20, 10])
    setup, kern, _ = _stage_setup(m, tools, step_down=5.0, lead=0.0)
    tip = np.c_[np.linspace(10, 30, 7), np.full(7, 10.0), np.full(7, 10.0)]
    tip[3, 2] = 9.0  # the known bad point
    up = np.tile([0.0, 0.0, 1.0], (7, 1))
    b6 = next(i for i, t in enumerate(tools) if t.name == "B6")
    passes = [dict(contour=0, tool=b6, rank=2, idx=np.arange(7), entry=2, exit=2, first_link=2, shallow=False)]
    cut = Passes(passes, tip, up, tip + 3.0 * up, np.tile([0.0, -1.0, 0.0], (7, 1)), 7, 0)
    rapid_stock = setup.stock_check()
    build = path_builder(cut, setup, tools, kern, rapid_stock).build
    first = path_check(m, kern, setup, tools, rapid_stock)(build(passes)[0])
    assert not first["ok"] and len(first["problem_moves"]) == 2
    done = verify_and_repair(passes, build, path_check(m, kern, setup, tools, rapid_stock))
    assert done.report["ok"] and done.report["repair_rounds"] == 1 and done.dropped == 0
    assert [list(p["idx"]) for p in done.passes] == [[0, 1, 2], [4, 5, 6]]
    assert done.path.tip[:, 2].min() >= 10.0 - 1e-9


def test_passes_are_linked_straight_where_the_rapid_is_clear_else_by_the_safe_plane(tools):
    """Two passes over a block's top 4 mm apart, then one beside the far wall: the first link is
    one rapid straight between the passes (nothing at the safe plane), the second, whose chord
    would cross the block, goes by the safe plane. The path verifies; every rapid keeps the ball
    the allowance and the clearance off the block (exact distances). A direct link that
    verification flags is not tried again."""
    from meshmill.geometry.shapes import box
    from meshmill.ops.finish import Passes, path_builder, path_check
    from meshmill.ops.finish_path import repair_passes

    m = box([0, 0, 0], [40, 20, 10])
    setup, kern, _ = _stage_setup(m, tools, step_down=5.0, lead=0.0)
    b6 = next(i for i, t in enumerate(tools) if t.name == "B6")
    x = np.linspace(10, 30, 5)
    top = [np.c_[x, np.full(5, y), np.full(5, 10.0)] for y in (8.0, 12.0)]
    wall = np.c_[np.full(5, 44.5), np.linspace(5, 15, 5), np.full(5, 2.0)]  # B6 1.5 mm off the wall x = 40
    tip = np.vstack(top + [wall])
    up = np.tile([0.0, 0.0, 1.0], (15, 1))
    side = np.vstack([np.tile([0.0, 1.0, 0.0], (10, 1)), np.tile([1.0, 0.0, 0.0], (5, 1))])
    passes = [dict(contour=c, tool=b6, rank=2, idx=np.arange(5 * c, 5 * c + 5), entry=2, exit=2, first_link=2,
                   shallow=False) for c in range(3)]
    cut = Passes(passes, tip, up, tip + 3.0 * up, side, 15, 0)
    rapid_stock = setup.stock_check()
    builder = path_builder(cut, setup, tools, kern, rapid_stock)
    tp, owner, role = builder.build(passes)
    at_safe = np.isclose(tp.tip[:, 2], setup.safe_z)
    owner, role = np.array(owner), np.array(role, object)
    assert list(role).count("direct_in") == 1 and owner[list(role).index("direct_in")] == 1
    between = (owner == 0) & (role != "link_in") | (owner == 1) & (role != "link_out")
    assert not at_safe[between].any() and at_safe[(owner == 2) & (role == "link_in")].any()
    report = path_check(m, kern, setup, tools, rapid_stock)(tp)
    assert report["ok"], report["worst"]
    # independent: the ball's centre along every rapid, R + allowance + clearance off the block
    f = np.linspace(0, 1, 81)[:, None]
    rapid = np.nonzero(tp.rapid)[0]
    centres = np.concatenate([tp.tip[i - 1] + 3.0 * tp.axis[i - 1] + f * (tp.tip[i] - tp.tip[i - 1])
                              for i in rapid[rapid > 0]])
    gap = kern.mesh_distances(centres) - 3.0
    assert gap.min() >= rapid_stock.allowance + rapid_stock.clearance - setup.params.tolerance
    # a direct link flagged by verification: that pass is reached by the safe plane from then on
    moved = list(role).index("direct_in")
    again, dropped = repair_passes(passes, [moved], list(owner), list(role))
    assert dropped == 0 and again[1]["direct_in"] is False and again[1]["entry"] == passes[1]["entry"]
    tp2, owner2, role2 = builder.build(again)
    assert "direct_in" not in role2 and np.isclose(tp2.tip[np.array(owner2) == 1, 2], setup.safe_z).any()


def test_a_round_of_repairs_builds_again_only_the_passes_it_changed(tools):
    """Eight passes over a block's top, linked directly, with leads: after repairs that split one
    pass, send another by the safe plane and take a third's lead away, the builder makes the
    blocks of moves of the changed passes and of the pass before the one by the safe plane again
    (its way out changes), takes the others' as they were, and gives exactly the path, owners
    and roles of a fresh builder."""
    from meshmill.geometry.shapes import box
    from meshmill.ops.finish import Passes, path_builder
    from meshmill.ops.finish_path import PathBuilder, repair_passes

    m = box([0, 0, 0], [60, 40, 10])
    setup, kern, _ = _stage_setup(m, tools, step_down=5.0, lead=1.0)
    b6 = next(i for i, t in enumerate(tools) if t.name == "B6")
    x = np.linspace(10, 50, 9)
    tip = np.vstack([np.c_[x, np.full(9, y), np.full(9, 10.0)] for y in 5.0 + 4.0 * np.arange(8)])
    up = np.tile([0.0, 0.0, 1.0], (len(tip), 1))
    side = np.tile([0.0, -1.0, 0.0], (len(tip), 1))
    passes = [dict(contour=c, tool=b6, rank=2, idx=np.arange(9 * c, 9 * c + 9), entry=0, exit=0, first_link=0,
                   shallow=False) for c in range(8)]
    cut = Passes(passes, tip, up, tip + 3.0 * up, side, len(tip), 0)
    rapid_stock = setup.stock_check()
    builder = path_builder(cut, setup, tools, kern, rapid_stock)
    tp, owner, role = builder.build(passes)
    assert builder.direct_links >= 5
    made = []
    block = PathBuilder._block

    def counted(self, ps, *a):
        made.append(ps["contour"])
        return block(self, ps, *a)

    PathBuilder._block = counted
    try:
        owner, role = np.array(owner), np.array(role, object)
        bad = [int(np.nonzero((owner == 2) & (role == 4))[0][0]),  # a cutting move of pass 2: split there
               int(np.nonzero((owner == 5) & (role == "direct_in"))[0][0]),  # pass 5: by the safe plane
               int(np.nonzero((owner == 6) & (role == "lead_in"))[0][0])]  # pass 6: no lead in
        again, dropped = repair_passes(passes, bad, list(owner), list(role))
        got = builder.build(again)
    finally:
        PathBuilder._block = block
    fresh = path_builder(cut, setup, tools, kern, rapid_stock).build(again)
    assert dropped == 0 and len(again) == 9
    assert np.array_equal(got[0].tip, fresh[0].tip) and np.array_equal(got[0].axis, fresh[0].axis)
    assert np.array_equal(got[0].rapid, fresh[0].rapid) and np.array_equal(got[0].tool, fresh[0].tool)
    assert got[1] == fresh[1] and got[2] == fresh[2]
    # made again: pass 2's two pieces, pass 4 (its way out: up, now that 5 is reached by the safe
    # plane), 5 and 6 (pass 3 and 7 follow the same points as before)
    assert sorted(made) == [2, 2, 4, 5, 6]


def test_a_link_the_straight_rapid_fails_is_lifted_by_the_lowest_height_that_passes():
    """PathBuilder with a stand-in check that refuses any move across lower than z = 16: the link
    between two passes at z = 10 goes 10 mm up the first pass's axis, across (the axis turning
    there), and down the next one's; with the check refusing everything, by the safe plane."""
    from meshmill.ops.finish_path import LIFTS, PathBuilder

    tip = np.array([[0.0, 0, 10], [10, 0, 10], [0, 5, 10], [10, 5, 10]])
    tilted = np.array([0.0, math.sin(0.2), math.cos(0.2)])
    axis = np.array([[0.0, 0, 1], [0, 0, 1], tilted, tilted])
    side = np.tile([0.0, -1.0, 0.0], (4, 1))
    passes = [dict(tool=0, idx=np.array([0, 1]), entry=2, exit=2), dict(tool=0, idx=np.array([2, 3]), entry=2, exit=2)]

    def high(a, xa, b, xb, tool):
        across = np.linalg.norm((b - a)[:, :2], axis=1) > 2.0  # not a leg up or down
        return ~across | (np.minimum(a[:, 2], b[:, 2]) >= 16.0 - 1e-9)

    builder = PathBuilder(tip, axis, side, safe_z=50.0, lead=0.0, approach=1.0, radius=np.array([3.0]), check=high)
    tp, owner, role = builder.build(passes)
    way = [i for i, r in enumerate(role) if r == "direct_in"]
    assert len(way) == 3 and builder.direct_links == 1 and LIFTS[:4] == (0.0, 2.0, 5.0, 10.0)
    assert np.allclose(tp.tip[way[0]], tp.tip[way[0] - 1] + 10.0 * axis[1])  # up the first pass's axis
    assert np.allclose(tp.tip[way[1]], tip[2] + 11.0 * tilted)  # across, down the next one's (5 mm: 15.8 < 16)
    assert np.allclose(tp.axis[way[0]], axis[1]) and np.allclose(tp.axis[way[1]], tilted)
    assert np.allclose(tp.tip[way[2]], tip[2] + 1.0 * tilted) and tp.rapid[way].all()
    assert not np.isclose(tp.tip[:, 2], 50.0)[way[0] - 1:way[2] + 1].any()
    builder.check = lambda a, xa, b, xb, tool: np.zeros(len(a), bool)
    tp, owner, role = builder.build(passes)
    assert "direct_in" not in role and np.isclose(tp.tip[:, 2], 50.0).sum() >= 2


def test_ways_whose_rapid_ends_in_the_way_are_skipped_before_the_path_is_built():
    """PathBuilder with a stand-in check that refuses the tool's pose left of x = -0.1 and around
    x = 10: a pass at x = 0 whose axis leans left takes the vertical retract (its rapid along the
    axis would end at x = -0.3), a pass at x = 10 gives up its rapids' ways only as far as the
    last one (feeding all the way is left to the repairs, which may first split the pass), and
    no pose is asked twice over two builds."""
    from meshmill.ops.finish_path import LAST_RAPID_WAY, LINKS, PathBuilder

    lean = np.array([-math.sin(0.3), 0.0, math.cos(0.3)])
    tip = np.array([[0.0, 0, 10], [0, 5, 10], [10, 0, 10], [10, 5, 10]])
    axis = np.array([lean, lean, [0, 0, 1], [0, 0, 1]])
    side = np.tile([0.0, -1.0, 0.0], (4, 1))
    passes = [dict(tool=0, idx=np.array([0, 1]), entry=0, exit=0), dict(tool=0, idx=np.array([2, 3]), entry=0, exit=0)]
    asked = []

    def check(a, xa, b, xb, tool):
        asked.append(len(a))
        pose = np.all(a == b, axis=1)
        blocked = (a[:, 0] < -0.1) | (np.abs(a[:, 0] - 10.0) < 1.0)
        return ~(pose & blocked)

    builder = PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]), check=check,
                          direct=False)
    tp, owner, role = builder.build(passes)
    assert (passes[0]["entry"], passes[0]["exit"]) == (1, 1) and LINKS[1] == (True, True, False)
    assert (passes[1]["entry"], passes[1]["exit"]) == (LAST_RAPID_WAY, LAST_RAPID_WAY) and not LINKS[LAST_RAPID_WAY][2]
    into = [i for i, r in enumerate(role) if r == "link_in" and owner[i] == 0][-1]
    assert np.allclose(tp.tip[into], tip[0] + [0.0, -2.0, 1.0]) and tp.rapid[into]  # vertical, above the lead
    n = sum(asked)
    builder.build(passes)
    assert sum(asked) == n


def test_a_repair_build_sends_a_changed_pass_whose_rapid_down_fails_to_feed_at_once():
    """PathBuilder with a stand-in check that refuses every pose around x = 10 and the rapids
    down to it: the first build leaves the pass there at the last way with a rapid (the repairs
    may first split it); a rebuild with that pass changed (as repairs make it) sends its ways
    to the next, which feed from the safe plane, as the next round of repairs would, and asks the
    rapid down of the way in and the rapid up of the way out; an unchanged pass is left alone."""
    from meshmill.ops.finish_path import LAST_RAPID_WAY, LINKS, PathBuilder

    tip = np.array([[0.0, 0, 10], [0, 5, 10], [10, 0, 10], [10, 5, 10]])
    axis = np.tile([0.0, 0.0, 1.0], (4, 1))
    side = np.tile([0.0, -1.0, 0.0], (4, 1))
    passes = [dict(tool=0, idx=np.array([0, 1]), entry=0, exit=0), dict(tool=0, idx=np.array([2, 3]), entry=0, exit=0)]
    rapids = []

    def check(a, xa, b, xb, tool):
        pose = np.all(a == b, axis=1)
        near = (np.abs(a[:, 0] - 10.0) < 1.0) | (np.abs(b[:, 0] - 10.0) < 1.0)
        rapids.extend((tuple(p), tuple(q)) for p, q, n in zip(a.tolist(), b.tolist(), pose) if not n)
        return ~near

    builder = PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]), check=check,
                          direct=False)
    builder.build(passes)
    assert [(ps["entry"], ps["exit"]) for ps in passes] == [(0, 0), (LAST_RAPID_WAY, LAST_RAPID_WAY)]
    assert not rapids
    passes[1] = dict(passes[1])
    tp, owner, role = builder.build(passes)
    assert (passes[1]["entry"], passes[1]["exit"]) == (LAST_RAPID_WAY + 1, LAST_RAPID_WAY + 1)
    assert LINKS[LAST_RAPID_WAY + 1][2] and passes[0]["entry"] == passes[0]["exit"] == 0
    assert sorted(rapids) == sorted([((10.0, 0.0, 50.0), (10.0, 0.0, 11.0)), ((10.0, 5.0, 11.0), (10.0, 5.0, 50.0))])
    fed = [r for i, r in enumerate(role) if owner[i] == 1]
    assert "approach_in" in fed and not any(tp.rapid[i] and tp.tip[i, 2] < 50.0 for i in range(len(tp)) if owner[i] == 1)


def test_a_repair_build_keeps_a_pass_reached_straight_at_its_way():
    """As above with straight links allowed, a tilted axis and every rapid touching the safe plane
    refused: pass 1 is reached straight from pass 0, so its rapid down is never built: its way
    in stays (and the link with it); its way out, whose rapid up is built, feeds instead."""
    from meshmill.ops.finish_path import LAST_RAPID_WAY, PathBuilder

    tip = np.array([[0.0, 0, 10], [0, 5, 10], [3, 0, 10], [3, 5, 10]])
    tilt = np.array([0.3, 0.0, 1.0]) / math.hypot(0.3, 1.0)
    axis = np.tile(tilt, (4, 1))
    side = np.tile([-1.0, 0.0, 0.0], (4, 1))
    above_tips = {(0.0, 0.0), (0.0, 5.0), (3.0, 0.0), (3.0, 5.0)}

    def check(a, xa, b, xb, tool):
        pose = np.all(a == b, axis=1)
        at_tip = np.array([(x, y) in above_tips for x, y in a[:, :2].tolist()])
        return np.where(pose, at_tip, np.maximum(a[:, 2], b[:, 2]) < 49.9)

    passes = [dict(tool=0, idx=np.array([0, 1]), entry=0, exit=0), dict(tool=0, idx=np.array([2, 3]), entry=0, exit=0)]
    builder = PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]), check=check)
    builder.build(passes)
    assert [(ps["entry"], ps["exit"]) for ps in passes] == [(LAST_RAPID_WAY, LAST_RAPID_WAY)] * 2
    assert builder.direct_links == 1
    passes[1] = dict(passes[1])
    tp, owner, role = builder.build(passes)
    assert (passes[1]["entry"], passes[1]["exit"]) == (LAST_RAPID_WAY, LAST_RAPID_WAY + 1)
    assert builder.direct_links == 1 and "direct_in" in role and "link_out" not in role[owner.index(1):]
    again = PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]),
                        check=check).build([dict(ps) for ps in passes])
    assert np.array_equal(tp.tip, again[0].tip) and role == again[2]  # what a new builder makes of the same ways


def test_a_rebuild_looks_again_only_at_the_ways_and_links_of_the_passes_it_changed():
    """PathBuilder over five passes along y, linked straight: a second build of the same passes
    computes no way and no link again; with pass 2 replaced by a copy (as a round of repairs makes
    one), only its two ways and the two links into and out of it; the paths equal a new
    builder's; and a changed check forgets what the last builds learnt (their blocks included:
    a pass whose way the new check moves on is built anew)."""
    from meshmill.ops.finish_path import NO_LEAD, PathBuilder

    tip = np.array([[10.0 * (k // 2), 5.0 * (k % 2), 10.0] for k in range(10)])
    axis = np.tile([0.0, 0.0, 1.0], (10, 1))
    side = np.tile([-1.0, 0.0, 0.0], (10, 1))

    def passes():
        return [dict(tool=0, idx=np.array([2 * k, 2 * k + 1]), entry=0, exit=0) for k in range(5)]

    def clear(a, xa, b, xb, tool):
        return np.ones(len(a), bool)

    builder = PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]), check=clear)
    ways, links = [], []
    ways_at, new_directs = builder._ways_at, builder._new_directs
    builder._ways_at = lambda todo: ways.append(len(todo)) or ways_at(todo)
    builder._new_directs = lambda ps, ends, ks: links.append(len(ks)) or new_directs(ps, ends, ks)
    ours = passes()
    first = builder.build(ours)
    assert ways == [10] and links == [4] and builder.direct_links == 4
    again = builder.build(ours)
    assert ways == [10] and links == [4]
    ours[2] = dict(ours[2])
    changed = builder.build(ours)
    assert ways == [10, 2] and links == [4, 2]
    fresh = PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]),
                        check=clear).build(passes())
    for tp, owner, role in (first, again, changed):
        assert np.array_equal(tp.tip, fresh[0].tip) and np.array_equal(tp.rapid, fresh[0].rapid)
        assert owner == fresh[1] and role == fresh[2]


    def blocked(a, xa, b, xb, tool):  # the pose above pass 2's lead-in is not clear
        return ~((np.abs(a[:, 0] - 18.0) < 1e-9) & (np.abs(a[:, 1]) < 1e-9))

    builder.check = blocked
    tp, owner, role = builder.build(ours)
    assert ways[2] == 10 and links[2] == 4 and ours[2]["entry"] == NO_LEAD  # both ways with a lead blocked
    fresh = PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]),
                        check=blocked).build(passes())
    assert np.array_equal(tp.tip, fresh[0].tip) and owner == fresh[1] and role == fresh[2]


def test_a_rebuild_asks_the_stock_reach_only_of_the_passes_it_changed():
    """PathBuilder whose passes feed from the safe plane (way 4) with a stand-in stock reach (the
    rapid may come down to 3 mm above each pass end): a second build of the same passes asks no
    reach again, one with pass 1 replaced by a copy asks its two ways only, and the paths equal
    a new builder's."""
    from meshmill.ops.finish_path import LINKS, PathBuilder

    tip = np.array([[10.0 * (k // 2), 5.0 * (k % 2), 10.0] for k in range(6)])
    axis = np.tile([0.0, 0.0, 1.0], (6, 1))
    side = np.tile([-1.0, 0.0, 0.0], (6, 1))
    asked = []

    def reach(p, d, u, tool, top):
        asked.append(len(p))
        return np.full(len(p), 3.0)

    def passes():
        return [dict(tool=0, idx=np.array([2 * k, 2 * k + 1]), entry=4, exit=4) for k in range(3)]

    assert LINKS[4][2]

    def builder():
        return PathBuilder(tip, axis, side, safe_z=50.0, lead=2.0, approach=1.0, radius=np.array([3.0]), reach=reach)

    b, ours = builder(), passes()
    first = b.build(ours)
    assert asked == [6]
    again = b.build(ours)
    ours[1] = dict(ours[1])
    changed = b.build(ours)
    assert asked == [6, 2]
    fresh = builder().build(passes())
    for tp, owner, role in (first, again, changed):
        assert np.array_equal(tp.tip, fresh[0].tip) and np.array_equal(tp.rapid, fresh[0].rapid) and role == fresh[2]
    assert np.isclose(fresh[0].tip[:, 2], 13.0).any()  # the rapid down stops where the stock begins


def test_points_within_the_tolerance_of_a_move_are_merged_and_put_back_where_it_fails():
    """A pass along a line with 0.002 mm of zigzag and one 0.05 mm bump: merged to its two ends and
    the bump (the zigzag is within half the tolerance, the bump is not), every point still counted
    as cut; where verification flags a merged move, repair puts its points back instead of
    splitting the pass; where the axis starts to turn, the point stays."""
    from meshmill.ops.finish_path import merged_points, pass_points, repair_passes

    x = np.linspace(0.0, 20.0, 101)
    tip = np.c_[x, 0.002 * (np.arange(101) % 2), np.zeros(101)]
    tip[50, 1] = 0.05
    axis = np.tile([0.0, 0.0, 1.0], (101, 1))
    ps = dict(tool=0, idx=np.arange(101), entry=0, exit=0, first_link=2)
    (m,) = merged_points([ps], tip, axis, np.array([40.0]), 0.005)
    kept = set(m["idx"].tolist())
    assert {0, 50, 100} <= kept and kept - {0, 100} <= set(range(47, 54))  # the spike and its flanks
    assert np.array_equal(pass_points(m), np.arange(101))
    j = list(m["idx"]).index(100)  # the move into the last point fails verification
    (back,), dropped = repair_passes([m], [j], [0] * (j + 1), list(range(j + 1)))
    assert dropped == 0 and back["idx"][0] == 0 and back["idx"][-1] == 100
    assert set(range(m["idx"][j - 1], 101)) <= set(back["idx"]) and np.array_equal(pass_points(back), np.arange(101))
    # a move that merged nothing splits the pass as before
    k = list(back["idx"]).index(60)  # the move 59 -> 60, which merged nothing
    pieces, _ = repair_passes([back], [k], [0] * (k + 1), list(range(k + 1)))
    assert len(pieces) == 2 and pieces[0]["idx"][-1] == back["idx"][k - 1] and pieces[1]["idx"][0] == back["idx"][k]
    assert len(np.intersect1d(pass_points(pieces[0]), pass_points(pieces[1]))) == 0
    # the axis held, then turning 1 deg evenly: the point where it starts to turn stays (0.35 mm off
    # the axis interpolated from end to end at a reach of 40 mm), the even turn is the interpolation
    turn = np.radians(np.r_[np.zeros(50), np.linspace(0, 1, 51)])
    bent = np.c_[np.sin(turn), np.zeros(101), np.cos(turn)]
    (t,) = merged_points([ps], np.c_[x, np.zeros(101), np.zeros(101)], bent, np.array([40.0]), 0.005)
    assert list(t["idx"]) == [0, 50, 100]


def test_a_finish_from_a_stock_tilts_the_shank_out_of_what_stands_above_the_wall(tmp_path):
    from meshmill.ops.simulate import simulate
    from meshmill.tools.table import load_tools

    # one ball whose shank is as wide as it is, 5 mm of flutes
    (tmp_path / "t.toml").write_text('[[tools]]\nname = "B4"\ntype = "ball"\ndiameter = 4.0\nflute_length = 5.0\n'
                                     'gauge_length = 40.0\nholder_diameter = 20.0\nholder_length = 20.0\n')
    tools = load_tools(tmp_path / "t.toml")
    part = revolve([0, 10, 10, 0], [0, 0, 20, 20])
    # what the roughing left: 0.3 mm on the wall and a collar 4 mm wide round its top 6 mm
    collar = revolve([0, 10.3, 10.3, 14, 14, 0], [-0.3, -0.3, 14, 14, 20.3, 20.3])
    alone = finish(part, tools, FinishParams(step_down=2.0))[2]
    tp, s, d = finish(part, tools, FinishParams(step_down=2.0, stock=Stock.mesh(collar)))
    assert s["verify"]["ok"] and s["points_tilted_out_of_stock"] > 0
    con = d["contours"]
    low = con.points[:, 2] <= 8.0  # the shank of a vertical ball there runs into the collar
    tilt = np.degrees(np.arccos(np.clip(d["axis"][:, 2], -1, 1)))
    assert low.sum() > 100 and np.degrees(np.arccos(alone["axis"][low, 2].min())) < 16.0  # from the part alone
    assert d["cut"][low].all() and tilt[low].min() > 19.0
    # independent: the dexel simulation from that stock finds no shank or holder in it
    _, summary, *_ = simulate(part, tp, tools, 0.25, stock=Stock.mesh(collar))
    assert summary["colliding_moves"] == 0


def test_passes_of_one_tool_on_both_sides_of_a_wall_are_taken_side_by_side():
    """Open passes at three levels on both sides of a thin wall, sorted by contour (A B A B A B):
    the short order takes one side top-down, crosses once, and takes the other bottom-up; a
    closed contour is entered anywhere along it; raster passes keep their order."""
    from meshmill.ops.finish import short_order

    tip, axis, passes = [], [], []
    for level, z in enumerate((5.0, 4.0, 3.0)):
        for side in (-1.0, 1.0):
            first = len(tip)
            tip += [[side, -10.0, z], [side, 10.0, z]] if side < 0 else [[side, 10.0, z], [side, -10.0, z]]
            axis += [[0.5 * side, 0.0, math.sqrt(0.75)]] * 2
            passes.append(dict(contour=2 * level + (side > 0), tool=0, rank=0, shallow=False,
                               idx=np.array([first, first + 1])))
    tip, axis = np.array(tip), np.array(axis)
    order = short_order(passes, tip, axis, np.array([40.0]))
    assert [p["contour"] for p in order] == [0, 2, 4, 5, 3, 1]
    # a closed loop near the end of the last pass goes before an open pass whose start is far
    loop = len(tip) + np.r_[np.arange(8), 0]
    ring = np.c_[np.cos(np.arange(8) * math.pi / 4), np.sin(np.arange(8) * math.pi / 4), np.zeros(8)]
    tip2 = np.vstack([tip, ring + [0.0, 12.0, 5.0]])
    axis2 = np.vstack([axis, np.tile([0.0, 0.0, 1.0], (8, 1))])
    mixed = [passes[0], passes[5], dict(contour=9, tool=0, rank=0, shallow=False, idx=loop)]
    assert [p["contour"] for p in short_order(mixed, tip2, axis2, np.array([0.0]))] == [0, 9, 5]
    raster = [dict(p, shallow=True) for p in passes]
    assert short_order(raster, tip, axis, np.array([40.0])) == raster


def test_gentle_turns_puts_each_moves_poses_in_its_place():
    """On random paths about the pole (rapid and feed moves, four tools), the poses put into a move
    from a tilted pose are :func:`around_pole`'s for that move alone, in the move's place, and turn
    C by at most the step; the path's own poses are kept."""
    from meshmill.ops.finish_pole import POLE_MARGIN, POLE_STEP, around_pole, gentle_turns
    from meshmill.toolpath.model import Toolpath

    rng = np.random.default_rng(7)
    radius = np.array([5.0, 3.0, 1.0, 0.5])
    singular = math.radians(0.05)
    for _ in range(60):
        n = int(rng.integers(2, 25))
        tilt = np.abs(rng.normal(0.0, 0.3, n)) * (rng.random(n) < 0.8)
        az = rng.uniform(-np.pi, np.pi, n)
        axis = np.column_stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
        tp = Toolpath(rng.normal(0.0, 5.0, (n, 3)), axis, rng.random(n) < 0.3, rng.integers(0, 4, n))
        out, source = gentle_turns(tp, radius, singular)
        own = np.r_[source[1:] != source[:-1], True]  # the last of each move's rows is its own pose
        assert (np.diff(source) >= 0).all() and (source[own] == np.arange(n)).all()
        assert (out.tip[own] == tp.tip).all() and (out.axis[own] == tp.axis).all()
        for i in range(1, n):
            if tilt[i - 1] <= singular or tilt[i] <= singular:
                continue
            r = 0.0 if tp.rapid[i] else radius[tp.tool[i]]
            c0, c1 = tp.tip[i - 1] + r * tp.axis[i - 1], tp.tip[i] + r * tp.axis[i]
            axes, centres = around_pole(tp.axis[i - 1], tp.axis[i], c0, c1, r, POLE_MARGIN, POLE_STEP,
                                        0.5 * singular)
            put = (source == i) & ~own
            assert np.allclose(out.axis[put], axes, atol=1e-12) and np.allclose(out.tip[put], centres - r * axes,
                                                                                atol=1e-9)
            if len(axes):  # C turns by at most the step along the move's poses
                chain = np.vstack([tp.axis[i - 1], axes, tp.axis[i]])
                turn = np.diff(np.degrees(np.arctan2(chain[:, 1], chain[:, 0])))
                assert (np.abs((turn + 180) % 360 - 180) <= POLE_STEP + 1e-6).all()
