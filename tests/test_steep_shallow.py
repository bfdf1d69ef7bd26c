"""Steep-and-shallow finishing to a scallop limit and rest finishing from the in-process stock:
the scallop a simulation of the cut leaves, per slope, against the analytic one; no seam at the
threshold; rest passes only where the stock stands above the design."""
import json
import math
import os
import subprocess
import sys

import numpy as np
import pytest

import meshmill
from meshmill import api
from meshmill.errors import InputError
from meshmill.geometry.shapes import box, revolve, sphere
from meshmill.job import Job, Operation
from meshmill.pathing.slope import contact_slopes, level_distance, raster_stepover
from meshmill.pathing.scallop import stepover
from meshmill.tools.table import tool_from_entry

SCALLOP = 0.01


@pytest.fixture(scope="module")
def balls():
    entry = dict(type="ball", flute_length=15, gauge_length=45, holder_diameter=32, holder_length=40)
    return [tool_from_entry(dict(entry, name="B6", diameter=6), 1, "t"),
            tool_from_entry(dict(entry, name="B4", diameter=4), 2, "t"),
            tool_from_entry(dict(entry, name="B2", diameter=2, shank_diameter=2), 3, "t"),
            tool_from_entry(dict(entry, name="B1", diameter=1, shank_diameter=1), 4, "t"),
            tool_from_entry(dict(entry, name="R6", type="bull", diameter=6, corner_radius=1), 5, "t"),
            tool_from_entry(dict(entry, name="F6", type="flat", diameter=6), 6, "t")]


def scallop_of(spacing, radius):
    """The cusp a ball of ``radius`` leaves between passes ``spacing`` apart on a plane."""
    return radius - math.sqrt(radius * radius - 0.25 * spacing * spacing)


def test_levels_and_stepover_follow_the_ground_they_cut(balls):
    b4, r6 = balls[1], balls[4]
    sod = stepover(SCALLOP, 2.0)
    assert level_distance(SCALLOP, b4, 40.0) == pytest.approx(sod * math.sin(math.radians(40.0)))
    assert raster_stepover(SCALLOP, b4, 50.0) == pytest.approx(sod * math.cos(math.radians(50.0)))
    assert raster_stepover(SCALLOP, b4, None) == pytest.approx(sod)  # flat ground: seed 002's stepover
    assert level_distance(SCALLOP, r6, None) == pytest.approx(stepover(SCALLOP, 1.0))  # the corner's radius


def test_contact_slopes_of_ball_and_bull_nose(balls):
    b4, r6, f6 = balls[1], balls[4], balls[5]
    tips = np.zeros((3, 3))
    for theta in (0.0, 30.0, 60.0, 90.0):
        t = math.radians(theta)
        # a ball touching a plane sloped theta: the contact is R from the centre, along -n
        contact = np.array([[-2 * math.sin(t), 0.0, 2 - 2 * math.cos(t)]])
        assert contact_slopes(tips[:1], contact, b4)[0] == pytest.approx(theta, abs=1e-9)
        # a bull-nose: the contact is r from its ring point, along -n
        ring = np.array([-2.0, 0.0, 1.0])
        c = ring + np.array([-math.sin(t), 0.0, -math.cos(t)])
        assert contact_slopes(tips[:1], c[None], r6)[0] == pytest.approx(theta, abs=1e-9)
    assert contact_slopes(tips[:1], np.array([[1.0, 0.0, 0.0]]), f6)[0] == 0.0  # on its flat bottom
    assert contact_slopes(tips[:1], np.array([[3.0, 0.0, 0.5]]), f6)[0] == 90.0  # its rim: a wall or an edge
    assert np.isnan(contact_slopes(tips[:1], np.full((1, 3), np.nan), b4)[0])  # on the floor: no ground


@pytest.fixture(scope="module")
def dome_cut(balls):
    """A hemisphere of radius 10 finished with a 4 mm ball at a 0.01 mm scallop, simulated on 0.05 mm
    dexels: ``(path result, sample points, deviations)``."""
    part = sphere(10.0, 96, 192)
    res = meshmill.steep_shallow(part, balls, tool="B4", scallop=SCALLOP, stock="offset:0.3", device="cpu")
    sim = meshmill.simulate(part, res.toolpath, balls, step=0.05, stock="offset:0.3", device="cpu")
    return res, sim.samples["points"], sim.samples["e"]


@pytest.mark.parametrize("band", [(2, 12), (15, 25), (28, 38), (40, 50), (52, 62), (65, 75)])
def test_the_scallop_at_every_slope_is_the_analytic_one(dome_cut, band):
    """The deviation a simulation of the cut leaves on the dome at each slope is the scallop the
    passes' spacing leaves there (the levels' dz / sin, the raster's stepover / cos at worst),
    under the limit; both sides of the 45 deg threshold cut the 40-50 band: no seam."""
    res, p, e = dome_cut
    s = res.summary
    assert s["verify"]["ok"] and s["steep"]["levels"] > 10 and s["shallow"]["passes"] > 10
    n = p / np.linalg.norm(p, axis=1)[:, None]
    slope = np.degrees(np.arccos(np.clip(n[:, 2], -1.0, 1.0)))
    at = (slope >= band[0]) & (slope < band[1]) & (p[:, 2] > 0.2)
    assert at.sum() > 1000
    lo, hi = np.radians(band)
    dz, step = s["steep"]["step_down"], s["shallow"]["stepover_used"]
    spacing = []
    if band[1] > s["steep"]["min_slope"]:
        spacing.append(dz / math.sin(lo) if band[0] >= s["steep"]["min_slope"] else np.inf)
    if band[0] < s["shallow"]["max_slope"]:
        spacing.append(step / math.cos(hi) if band[1] <= s["shallow"]["max_slope"] else np.inf)
    analytic = scallop_of(min(spacing), 2.0)
    assert analytic <= SCALLOP + 1e-9
    worst = float(e[at].max())
    # the cusp as measured: no more than the analytic one, the facets' chords (the sphere's 96
    # rings) and the path's chord tolerance (half the 0.01 mm); and the cusps are there to see
    facets = 10.0 * (1 - math.cos(math.pi / 192))
    assert worst <= analytic + facets + 0.005 + 1e-4, (band, worst, analytic)
    assert worst >= 0.3 * scallop_of(min(spacing) * math.cos(lo) if band[1] <= 50 else min(spacing), 2.0) - facets


def pocket():
    """A 40 mm block, z 0-10, with a round pocket 16 mm across down to z 2 and a 1 mm fillet
    between its wall and floor."""
    a = np.linspace(0.0, 0.5 * math.pi, 9)
    r = np.r_[0.0, 20.0, 20.0, 8.0, (7.0 + np.sin(a))[::-1], 0.0]
    z = np.r_[0.0, 0.0, 10.0, 10.0, (3.0 - np.cos(a))[::-1], 2.0]
    return revolve(r, z, 96, "pocket")


def in_fillet(p):
    r = np.hypot(p[:, 0], p[:, 1])
    return (r > 6.9) & (r < 8.05) & (p[:, 2] > 1.95) & (p[:, 2] < 3.1)


def left_by_b6(p, grow=0.0):
    """Where a 6 mm ball leaves material on the pocket part: the pocket's corner (the ball sits on
    the floor and against the wall: r 5-8, z 2-5) and the foot of the block's outside wall (a
    ball's tip stays above the part's bottom: z < 3)."""
    r = np.hypot(p[:, 0], p[:, 1])
    corner = (r > 5.0 - grow) & (r < 8.05 + grow) & (p[:, 2] > 1.95 - grow) & (p[:, 2] < 5.0 + grow)
    foot = (r > 19.95 - grow) & (p[:, 2] < 3.0 + grow)
    return corner | foot


@pytest.fixture(scope="module")
def pocket_job(balls):
    ops = [{"type": "steep-shallow", "name": "finish", "tool": "B6", "scallop": SCALLOP},
           {"type": "rest-finish", "tools": ["B2", "B1"], "scallop": SCALLOP, "rest": 0.015}]
    job = Job(part=pocket(), tools=balls, operations=[Operation.from_dict(o, k + 1) for k, o in enumerate(ops)],
              stock=api.Stock.from_dict({"type": "offset", "allowance": 0.2}), machine="generic-3axis", step=0.25,
              device="cpu")
    return job.run()


def test_rest_finishing_cuts_only_what_the_larger_ball_left(pocket_job):
    """A 6 mm ball leaves the 1 mm fillet uncut (and the corner 3 mm up the wall and out on the
    floor); the 2 mm and then the 1 mm ball cut only where it left material (their passes where
    the stock stands more than rest above the design, measured on the in-process stock) and the
    simulated deviation in the fillet ends within the scallop limit and the tolerance."""
    ops = pocket_job.operations
    assert [o.operation.name for o in ops] == ["finish", "rest-finish B2", "rest-finish B1"]
    assert pocket_job.ok and all(not o.skipped for o in ops)
    p, e = ops[0].cut.samples["points"], ops[0].cut.samples["e"]
    assert e[in_fillet(p)].max() > 0.15  # the 6 mm ball does not fit the 1 mm fillet
    for o in ops[1:]:
        s = o.path.summary
        assert s["rest"]["min_depth"] == 0.015 and s["rest"]["points_left"] > 0
        assert s["pencil"]["lines"] >= 1
        tp = o.path.toolpath
        a, b = tp.tip[:-1], tp.tip[1:]
        length = np.linalg.norm(b - a, axis=1)
        feed = ~tp.rapid[1:] & (np.abs(b[:, 2] - a[:, 2]) < 0.9 * length)  # not the entries and exits
        a, b, length = a[feed], b[feed], length[feed]
        ball = next(t for t in o.path.tools if t.name == s["tool"])
        # the ball of each feed move along the part: where the 6 mm ball left material, grown by
        # the overlap, the lattice step the stock is measured on and the ball
        centre = 0.5 * (a + b) + [0.0, 0.0, ball.radius]
        near = left_by_b6(centre, grow=s["overlap"] + 0.25 + 2 * ball.radius)
        assert length[near].sum() > 0.97 * length.sum(), (s["tool"], length[~near].sum(), length.sum())
    p, e = ops[-1].cut.samples["points"], ops[-1].cut.samples["e"]
    assert e[in_fillet(p)].max() <= SCALLOP + 0.01  # the limit and the tolerance
    assert e[left_by_b6(p) & (p[:, 2] > 1.95)].max() <= SCALLOP + 0.01
    final = pocket_job.summary["final"]
    assert final["gouge_max"] <= 0.01
    # the time that cuts nothing: rapids, tool changes (two here), feed through the air
    nc = pocket_job.summary["non_cutting"]
    total = pocket_job.summary["time"]["total"]
    assert nc["tool_change_s"] == total["tool_change_s"] > 0 and 0 < nc["share"] < 1
    assert nc["share"] * total["total_s"] == pytest.approx(nc["rapid_s"] + nc["tool_change_s"] + nc["air_feed_s"])
    assert all(0 <= o["non_cutting"]["share"] < 1 for o in pocket_job.summary["operations"])


def test_steep_shallow_refuses_what_it_cannot_do(balls):
    part = box([0, 0, 0], [20, 20, 5])
    with pytest.raises(InputError, match="flat"):
        meshmill.steep_shallow(part, balls, tool="F6", scallop=SCALLOP)
    with pytest.raises(InputError, match="threshold"):
        meshmill.steep_shallow(part, balls, tool="B4", scallop=SCALLOP, threshold=89.0)
    with pytest.raises(InputError, match="scallop"):
        meshmill.steep_shallow(part, balls, tool="B4")
    with pytest.raises(InputError, match="min_slope"):
        meshmill.raster(part, balls, tool="B4", stepover=1.0, min_slope=50.0, max_slope=40.0)
    with pytest.raises(InputError, match="step_down"):
        meshmill.waterline(part, balls, tool="B4", step_down=1.0, scallop=SCALLOP)
    with pytest.raises(InputError, match="rest-finish needs tools"):
        Operation.from_dict({"type": "rest-finish", "scallop": SCALLOP}, 1)
    with pytest.raises(InputError, match="not tool"):
        Operation.from_dict({"type": "rest-finish", "tools": ["B2"], "tool": "B2", "scallop": SCALLOP}, 1)


def test_waterline_and_raster_keep_to_their_ground(balls):
    """On a box (walls at 90 deg, a top at 0) the levels with min_slope 45 keep the walls, the
    raster with max_slope 45 the top."""
    part = box([0, 0, 0], [20, 20, 5])
    w = meshmill.waterline(part, balls, tool="B4", scallop=SCALLOP, min_slope=45.0, device="cpu")
    r = meshmill.raster(part, balls, tool="B4", scallop=SCALLOP, max_slope=45.0, device="cpu")
    assert w.summary["step_down"] == pytest.approx(level_distance(SCALLOP, balls[1], 45.0))
    wt, rt = w.toolpath.tip[~w.toolpath.rapid], r.toolpath.tip[~r.toolpath.rapid]
    a, b = w.toolpath.tip[:-1], w.toolpath.tip[1:]
    level = ~w.toolpath.rapid[1:] & (np.abs(a[:, 2] - b[:, 2]) < 1e-9)
    assert level.sum() > 100 and a[level, 2].max() < 5.0 - 1e-9  # no level on the top face
    a, b = r.toolpath.tip[:-1], r.toolpath.tip[1:]
    feed = ~r.toolpath.rapid[1:]
    length = np.linalg.norm(b - a, axis=1)
    on_top = feed & (a[:, 2] >= 5.0 - 1e-9) & (b[:, 2] >= 5.0 - 1e-9)
    assert length[on_top].sum() > 0.55 * length[feed].sum()  # the rest: rolling over the edges, entries
    # the raster stops where the ball rolls over the edge past 45 deg (R sin 45 out), plus the
    # overlap and a sample
    out = 2.0 * math.sin(math.radians(45.0)) + 1.0 + 0.5 + 1e-6
    assert np.all((rt[:, 0] >= -out) & (rt[:, 0] <= 20.0 + out) & (rt[:, 1] >= -out) & (rt[:, 1] <= 20.0 + out))


def test_the_command_line(tmp_path, balls):
    import trimesh

    stl = tmp_path / "dome.stl"
    m = sphere(8.0, 48, 96)
    trimesh.Trimesh(m.vertices, m.faces, process=False).export(str(stl))
    tools = os.path.join(os.path.dirname(meshmill.__file__), "data", "tools.toml")
    run = [sys.executable, "-m", "meshmill", "steep-shallow", str(stl), "--tools", tools, "--tool", "B4"]
    out = subprocess.run([*run, "--scallop", "0.02", "--out", str(tmp_path / "o"), "--device", "cpu"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    s = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert s["operation"] == "steep-shallow" and s["verify"]["ok"]
    bad = subprocess.run([*run, "--scallop", "-1"], capture_output=True, text=True)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_what_is_left_and_why(pocket_job, balls):
    """After the 6 mm ball alone, the pocket's corner is left: no tool of a table of 6 mm balls
    fits it, a tool the job does not use takes it from a table with smaller ones, and it is the
    job's to take when it runs them; the block's bottom is below a 3-axis shadow (in 5 axes: no
    axis within 60 deg reaches it). Areas are the design's, exact in sum."""
    part = pocket()
    v = part.vertices[part.faces]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum()
    after_b6 = pocket_job.operations[0].cut.samples
    corner = None
    for tools, used, five, expect in (([balls[0]], {"B6"}, False, "no tool of the table fits"),
                                      (balls, {"B6"}, False, "a tool the job does not use"),
                                      (balls, {"B6", "B2", "B1"}, False, "left by the job"),
                                      (balls, {"B6", "B2", "B1"}, True, "left by the job")):
        arrays, report = meshmill.what_is_left(part, after_b6["points"], after_b6["e"], 0.25, tools, used,
                                               five_axis=five, tolerance=0.01, device="cpu")
        assert report["area_mm2"] == pytest.approx(area, rel=1e-9)
        assert sum(report["by_reason_mm2"].values()) == pytest.approx(area, rel=1e-9)
        names = np.array(report["reasons"])[arrays["reason"]]
        p, n = arrays["points"], arrays["normals"]
        corner = in_fillet(p)
        assert np.mean(names[corner] == expect) > 0.9, (expect, np.unique(names[corner], return_counts=True))
        bottom = n[:, 2] < -0.99
        assert np.all(names[bottom] == ("no collision-free axis" if five else "below a 3-axis shadow"))
        assert report["by_reason_mm2"]["not measured"] < 0.01 * area
    final = pocket_job.summary["left"]
    assert final["reachable_within_tolerance"] >= 0.95
    assert final["by_reason_mm2"]["below a 3-axis shadow"] == pytest.approx(math.pi * 400, rel=0.05)  # the bottom
    assert final["within_tolerance"] == pytest.approx(final["by_reason_mm2"]["within tolerance"] / final["area_mm2"])


def test_passes_in_a_short_order_joined_and_linked_low(balls):
    """Passes are taken nearest end first (open ones turned round), close ones joined; a link
    between passes travels at the lowest height clear of what stands between them, not at the
    safe plane, and the path still verifies."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.dropcutter import StockClearance, link_heights
    from meshmill.pathing.verify import StockCheck
    from meshmill.toolpath.linking import joined_passes, shortest_order

    line = lambda x0, x1: np.array([[x0, 0.0, 0.0], [x1, 0.0, 0.0]])  # noqa: E731
    order = shortest_order([line(0, 1), line(10, 11), line(4, 2)])
    assert [tuple(p[:, 0]) for p in order] == [(0, 1), (2, 4), (10, 11)]
    joined = joined_passes(order, 2.0)
    assert len(joined) == 2 and len(joined[0]) == 4
    # a 10 mm wall between two passes on the floor: the link clears it, under the safe plane
    part = box([-2, -20, 0], [2, 20, 10])
    kern = solid_kernels(part, "cpu")
    b4 = balls[1]
    clear = StockClearance(b4, kern, -1.0, StockCheck(clearance=0.5), widen=0.5 * b4.radius + 1e-6)
    ends = np.array([[-10.0, 0.0, -8.0, 0.0], [8.0, 0.0, 10.0, 0.0]])
    z = link_heights(ends, np.zeros(2), np.zeros(2), 30.0, clear, b4.radius)
    assert z[0] == 30.0 and z[2] == 30.0 and 10.0 + 0.5 - 1e-9 <= z[1] < 12.0
    far = link_heights(ends, np.zeros(2), np.zeros(2), 30.0, clear, b4.radius, high={(-8.0, 0.0)})
    assert far[1] == 30.0  # verification found it too close: at the safe plane
    r = meshmill.steep_shallow(part, balls, tool="B4", scallop=0.02, device="cpu")
    tp = r.toolpath
    assert r.summary["verify"]["ok"] and tp.tip[tp.rapid, 2].min() < r.summary["safe_z"] - 1.0


def test_a_wall_under_an_overhang_is_a_3_axis_shadow_and_reached_in_5_axes(balls):
    from meshmill.geometry.shapes import overhang_column
    from meshmill.kernels.backend import solid_kernels
    from meshmill.ops.left import _fans, reach

    part = overhang_column(radius=10.0, height=30.0, cap_radius=14.0, cap_height=5.0)
    kern = solid_kernels(part, "cpu")
    foot, normal = np.array([[10.0, 0.0, 10.0]]), np.array([[1.0, 0.0, 0.0]])
    b2 = [balls[2]]
    fits, reaches = reach(foot, normal, b2, kern, 0.0, five_axis=False, tol=0.01)
    assert fits.all() and not reaches.any()  # the shank meets the cap straight above
    fits, reaches = reach(foot, normal, b2, kern, 0.0, five_axis=True, tol=0.01)
    assert reaches.all()  # tilted out from the wall
    fans = _fans(np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]), 60.0)
    assert np.allclose(np.linalg.norm(fans, axis=2), 1.0) and (fans[:, :, 2] >= 0.5 - 1e-12).all()


def test_a_ball_reaches_a_floor_by_a_wall_where_its_shank_clears_the_wall_exactly():
    """A 4 mm ball on a 6 mm shank 10 mm above its tip, on a floor beside a wall 15 mm high: the
    vertical tool reaches a point of the floor only where the shank clears the wall (3 mm from
    it), though the ball fits from 2 mm; beside a wall 8 mm high, from 2 mm."""
    from meshmill.geometry.shapes import box
    from meshmill.kernels.backend import solid_kernels
    from meshmill.ops.left import reach

    b4 = tool_from_entry(dict(type="ball", name="B4", diameter=4, flute_length=10, gauge_length=40, shank_diameter=6,
                              holder_diameter=32, holder_length=40), 1, "t")
    gap = np.array([1.9, 2.1, 2.9, 3.1, 5.0])
    for height, first in ((15.0, 3), (8.0, 1)):
        part = box([0, -10, 0], [30, 10, 5])  # the floor at z 5, the wall's face at x 10
        wall = box([0, -10, 5], [10, 10, 5 + height])
        from meshmill.geometry.mesh import mesh_from_arrays
        both = mesh_from_arrays(np.vstack([part.vertices, wall.vertices]),
                                np.vstack([part.faces, wall.faces + len(part.vertices)]), "step")
        kern = solid_kernels(both, "cpu")
        feet = np.c_[10.0 + gap, np.zeros(len(gap)), np.full(len(gap), 5.0)]
        fits, reaches = reach(feet, np.tile([0.0, 0.0, 1.0], (len(gap), 1)), [b4], kern, 0.0, False, 0.01)
        assert fits[:, 0].tolist() == [False, True, True, True, True]
        assert reaches[:, 0].tolist() == [k >= first for k in range(len(gap))], (height, reaches[:, 0])


def test_stock_thicker_than_the_lattice_over_the_design_is_left_not_unmeasured(balls):
    """A block with a slot 3 mm wide and 8 mm deep under 1 mm of a box stock that nothing cut:
    the slot is full of stock and no dexel end's foot lies within 1.5 steps of its walls and
    floor (the ends nearest them are over the block's top), yet the stock stands on them: they are
    the 2 and 1 mm balls' to cut, not "not measured"."""
    from meshmill.geometry.mesh import mesh_from_arrays

    ring = np.array([(0, 0), (20, 0), (20, 10), (11.5, 10), (11.5, 2), (8.5, 2), (8.5, 10), (0, 10)], float)  # (x, z)
    tri = np.array([(1, 2, 3), (1, 3, 4), (5, 6, 7), (5, 7, 0), (0, 1, 4), (0, 4, 5)])
    n = len(ring)
    v = np.vstack([np.c_[ring[:, 0], np.zeros(n), ring[:, 1]], np.c_[ring[:, 0], np.full(n, 20.0), ring[:, 1]]])
    faces = np.vstack([tri, tri[:, ::-1] + n] + [[(k, (k + 1) % n, n + (k + 1) % n), (k, n + (k + 1) % n, n + k)]
                                                 for k in range(n)])
    part = mesh_from_arrays(v, faces[:, ::-1], "slot")  # wound outward
    stock = api.Stock.box(1.0).dexels(part, 0.5)
    _, _, _, (points, e) = stock.measure(0.01, samples=True)
    walls = 2 * 8 * 20 + 3 * 20  # mm²: the slot's walls and floor
    arrays, alone = meshmill.what_is_left(part, points, e, 0.5, balls, {"B6"}, tolerance=0.01)
    p = arrays["points"]
    slot = (p[:, 0] > 8.5 - 1e-6) & (p[:, 0] < 11.5 + 1e-6) & (p[:, 2] > 1.0) & (p[:, 2] < 9.0) \
        & (np.abs(arrays["normals"][:, 1]) < 0.5)
    a = arrays["area"][slot]
    assert a.sum() > 0.75 * walls

    def share(names, reason):
        return a[names[slot] == reason].sum() / a.sum()

    assert share(np.array(alone["reasons"])[arrays["reason"]], "not measured") > 0.9
    for used, expect in (({"B6"}, "a tool the job does not use"), ({"B6", "B2", "B1"}, "left by the job")):
        arrays, report = meshmill.what_is_left(part, points, e, 0.5, balls, used, tolerance=0.01, stock=stock)
        names = np.array(report["reasons"])[arrays["reason"]]
        # the rest: the floor's corners, which no ball fits
        assert share(names, expect) > 0.8 and share(names, expect) + share(names, "no tool of the table fits") == pytest.approx(1.0)
        assert report["by_reason_mm2"]["not measured"] < 0.05 * walls
        thick = a[np.isnan(arrays["e"][slot])].sum()
        assert thick > 0.9 * a.sum() and report["thick_mm2"] >= thick - 1e-9


def v_groove(width=8.0, depth=4.0, length=20.0):
    """A 20 x ``length`` x 10 mm block with a 90 deg V-groove along Y down the middle of its top
    (``width`` across at the top, its bottom line at x = 10, z = 10 - ``depth``)."""
    from meshmill.geometry.mesh import mesh_from_arrays

    h = 0.5 * width
    ring = np.array([(0, 0), (10, 0), (20, 0), (20, 10), (10 + h, 10), (10, 10 - depth), (10 - h, 10), (0, 10)],
                    float)  # (x, z), round the section
    n = len(ring)
    v = np.vstack([np.c_[ring[:, 0], np.zeros(n), ring[:, 1]], np.c_[ring[:, 0], np.full(n, length), ring[:, 1]]])
    front = [(1, k + 1, k) for k in range(2, n - 1)] + [(1, 0, n - 1)]
    faces = front + [(n + a, n + c, n + b) for a, b, c in front]
    faces += [f for k in range(n) for f in ((k, (k + 1) % n, n + (k + 1) % n), (k, n + (k + 1) % n, n + k))]
    return mesh_from_arrays(v, np.array(faces)[:, ::-1], "groove")


def pencil_lines(part, tool):
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.dropcutter import ToolDrop
    from meshmill.pathing.pencil import pencil_passes

    drop = ToolDrop(tool, solid_kernels(part), float(part.bounds[0, 2]) - 1.0)
    reach = tool.radius
    return pencil_passes(drop, part.bounds[0, :2] - reach, part.bounds[1, :2] + reach, 0.5 * tool.radius, 0.5,
                         tool.diameter)


def test_pencil_passes_run_along_the_corners_the_ball_touches_twice(balls):
    """A 90 deg V-groove: one pass along its bottom line, the ball touching both walls (tip
    r (sqrt 2 - 1) above the line, exact: the walls are planes). The pocket: B6 sits on the floor
    against the wall (a circle r 5 at the floor), B2 fits the 1 mm fillet (r 7); nothing on a
    sphere, which has no concave corner."""
    b4, b6, b2 = balls[1], balls[0], balls[2]
    (line,) = pencil_lines(v_groove(), b4)
    inside = (line[:, 1] > 2.0) & (line[:, 1] < 18.0)  # off the groove's open ends
    assert np.abs(line[inside, 0] - 10.0).max() < 2e-3
    assert np.abs(line[inside, 2] - (6.0 + 2.0 * (math.sqrt(2.0) - 1.0))).max() < 2e-3
    assert np.ptp(line[:, 1]) > 15.0
    facets = 8.0 * (1.0 - math.cos(math.pi / 96))  # the pocket's wall: a polygon of 96 sides
    for tool, radius, z, tol in ((b6, 5.0, 2.0, facets + 2e-3), (b2, 7.0, 2.0, 0.05)):
        (ring,) = pencil_lines(pocket(), tool)
        assert np.allclose(ring[0], ring[-1])  # a closed line round the pocket
        assert np.abs(np.hypot(ring[:, 0], ring[:, 1]) - radius).max() < tol
        assert np.abs(ring[:, 2] - z).max() < 0.05
    assert pencil_lines(sphere(10.0), b4) == []
