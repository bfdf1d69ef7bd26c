"""5-axis Z-constant ball finishing on analytic parts with known answers."""
import math

import numpy as np
import pytest

from meshmill.errors import InputError
from meshmill.geometry.shapes import overhang_column, post_with_fillet, revolve, sphere
from meshmill.ops.finish import FinishParams, finish, tilt_candidates


def test_sphere_every_tool_fits(tools):
    tp, s, d = finish(sphere(20.0, 48, 96), tools, FinishParams(step_down=4.0))
    assert s["points_without_tool"] == 0
    assert (d["best"] == 0).all() and (d["contour_tool"] == 0).all()  # the largest ball everywhere
    assert s["verify"]["ok"] and s["machinable_contours"] == s["contours"]
    # the ball centre sits exactly R off the mesh wherever the CC normal is a facet normal or in
    # the normal cone of a convex edge: no gouge beyond rounding
    from meshmill.kernels import cpu

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
    (dict(step_down=0), "step-down"),
    (dict(step_down=1, max_tilt=95), "max-tilt"),
    (dict(step_down=1, order="zigzag"), "order"),
    (dict(step_down=100), "larger than the part"),
    (dict(step_down=1, safe_z=5), "safe-z"),
])
def test_bad_parameters(tools, kw, message):
    with pytest.raises(InputError, match=message):
        finish(sphere(10.0, 8, 16), tools, FinishParams(**kw))


def test_no_ball_tool(tools):
    from meshmill.tools.table import tool_from_entry

    flat = [tool_from_entry(dict(name="F6", type="flat", diameter=6, flute_length=10, gauge_length=30), 1, "t")]
    with pytest.raises(InputError, match="no ball tool"):
        finish(sphere(10.0, 8, 16), flat, FinishParams(step_down=2))
