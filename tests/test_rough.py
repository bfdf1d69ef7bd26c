"""Adaptive clearing (meshmill rough): pockets with vertical walls and sharp inner corners, an
island, a slot narrower than two tool diameters, a floor at an exact level, a stock cut before;
the radial width of cut of every move measured by the dexel simulation, not the planner."""
import subprocess
import sys

import numpy as np
import pytest

import meshmill
from meshmill.geometry.mesh import closed_mesh
from meshmill.ops.rough import MOVE_KINDS, flat_heights, layer_tops, rough_levels
from meshmill.simulation.engagement import level_widths
from meshmill.tools.table import load_tools

TOOLS = """
[[tools]]
name = "F6"
type = "flat"
diameter = 6.0
flute_length = 12.0
gauge_length = 40.0
holder_diameter = 30.0
holder_length = 30.0

[[tools]]
name = "F3"
type = "flat"
diameter = 3.0
flute_length = 12.0
gauge_length = 40.0
shank_diameter = 3.0
holder_diameter = 30.0
holder_length = 30.0
"""


def boxes(*spans):
    """One closed mesh of axis-aligned boxes ``(x0, y0, z0, x1, y1, z1)`` (touching, not merged)."""
    vs, fs = [], []
    for s in spans:
        lo, hi = np.array(s[:3], float), np.array(s[3:], float)
        v = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])])
        f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                      [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
        fs.append(f + 8 * len(vs))
        vs.append(v)
    return closed_mesh(np.vstack(vs), np.vstack(fs), "boxes")


@pytest.fixture(scope="module")
def tools(tmp_path_factory):
    p = tmp_path_factory.mktemp("tools") / "tools.toml"
    p.write_text(TOOLS)
    return load_tools(str(p))


def pocket_part():
    """A 40 x 34 x 12 block with a closed 32 x 26 pocket 8 deep (floor at z = 4, exactly on a
    level), sharp inner corners, and a 6 x 6 island standing 8 high in it."""
    return boxes((0, 0, 0, 40, 34, 4),                      # the floor
                 (0, 0, 4, 40, 4, 12), (0, 30, 4, 40, 34, 12),  # the walls
                 (0, 4, 4, 4, 30, 12), (36, 4, 4, 40, 30, 12),
                 (17, 14, 4, 23, 20, 12))                   # the island


def measured_widths(part, res, stock, step=0.15):
    kind = res.arrays["move_kind"]
    cut = np.nonzero(kind == MOVE_KINDS.index("cut"))[0]
    st = meshmill.Stock.of(stock).dexels(part, step)
    return level_widths(st, res.toolpath, res.tools, cut, layer_tops(res.summary, res.toolpath.tip[cut]))


def test_closed_pocket_with_an_island_is_cleared_by_helices_within_the_engagement(tools):
    part = pocket_part()
    res = meshmill.rough(part, tools, tool="F6", engagement=1.5, step_down=4.0, allowance=0.3, axial_allowance=0.0,
                         stock="box")
    s = res.summary
    assert res.ok and s["verify"]["gouging_moves"] == 0
    levels = [lv["z"] for lv in s["levels"] if lv["walks"]]
    assert levels == [8.0, 4.0]  # the floor at 4 is a level (no stair left on it); nothing to reach under it
    assert all(lv["helices"] >= 1 for lv in s["levels"] if lv["walks"])  # closed: entered by helices
    assert s["left_mm2"] < 2.0  # specks of a few nodes in the sharp corners at most
    assert s["planned_width_mm"]["max"] <= 1.5
    w = measured_widths(part, res, "box")
    assert w.max() <= 1.1 * 1.5, w.max()
    assert np.average(w, weights=w) > 0.7 * 1.5  # most material is cut close to the engagement, not in a trickle
    # what is left in the pocket after the path: the stock simulated, the floor and walls measured
    after, figures = meshmill.Stock.of("box").dexels(part, 0.2).cut(res.toolpath, tools)
    assert figures["rapid_moves_cutting"] == 0 and figures["colliding_moves"] == 0
    # the pocket (32 x 26 x 8 less the island) is gone but for the allowance on its walls and corners
    pocket = 32 * 26 * 8 - 6 * 6 * 8
    left = after.volume - (40 * 34 * 12 - pocket)
    walls = (2 * (32 + 26) + 4 * 6) * 8 * 0.3
    corners = 8 * (4 - np.pi) * 3.3 ** 2 * 8 / 4  # the round of the tool in the 8 sharp inner corners
    assert left < walls + corners + 0.05 * pocket, (left, walls, corners)


def test_slot_narrower_than_two_diameters_and_open_sides(tools):
    # a 9 mm slot through a block, open at both ends: entered from the side, no helix needed
    part = boxes((0, 0, 0, 30, 10, 10), (0, 19, 0, 30, 29, 10), (0, 10, 0, 30, 19, 3))
    res = meshmill.rough(part, tools, tool="F6", engagement=1.5, allowance=0.0, stock="box")
    s = res.summary
    assert res.ok
    assert sum(lv["helices"] for lv in s["levels"]) == 0
    assert s["left_mm2"] < 1.0
    w = measured_widths(part, res, "box")
    assert w.max() <= 1.1 * 1.5
    tip = res.toolpath.tip[res.arrays["move_kind"] == 1]
    tip = tip[(tip[:, 0] > 3) & (tip[:, 0] < 27)]  # over the block (outside it the tool goes round)
    assert tip[:, 1].min() >= 10 + 3 - 1e-6 and tip[:, 1].max() <= 19 - 3 + 1e-6  # the centre stays in the slot
    assert np.isclose(tip[:, 2].min(), 3.0)  # down to the slot's floor


def test_rest_roughing_from_the_stock_a_larger_tool_left(tools):
    part = pocket_part()
    first = meshmill.rough(part, tools, tool="F6", engagement=2.0, step_down=8.0, allowance=0.3, stock="box")
    stock = meshmill.Stock.of("box").dexels(part, 0.2).cut(first.toolpath, tools)[0]
    second = meshmill.rough(part, tools, tool="F3", engagement=1.0, step_down=8.0, allowance=0.3, stock=stock)
    assert second.ok
    # the smaller tool clears only the corners the larger one left: a fraction of its path
    assert second.summary["length_mm"]["cut"] < 0.5 * first.summary["length_mm"]["cut"]
    w = measured_widths(part, second, stock)
    assert w.max() <= 1.1 * 1.0 + 0.1  # the in-process stock's surface is known to half a dexel
    # the same from that stock as a closed mesh (its surface, as a user would save it)
    mesh_stock = meshmill.Stock.mesh(stock.surface_mesh())
    third = meshmill.rough(part, tools, tool="F3", engagement=1.0, step_down=8.0, allowance=0.3, stock=mesh_stock)
    assert third.ok and third.summary["length_mm"]["cut"] < 0.5 * first.summary["length_mm"]["cut"]
    after, figures = stock.cut(third.toolpath, tools)
    assert figures["rapid_moves_cutting"] == 0 and figures["colliding_moves"] == 0


def test_levels_and_flats():
    assert rough_levels(10.0, 0.0, 4.0, [5.0], None) == [(6.0, "level"), (5.0, "level"), (2.0, "level"),
                                                          (0.0, "level")]
    lv = rough_levels(10.0, 0.0, 4.0, [], 1.5)
    assert lv[:3] == [(6.0, "level"), (7.5, "stair"), (9.0, "stair")]
    assert np.allclose(flat_heights(pocket_part(), 1.0), [4.0, 12.0])
    assert np.allclose(flat_heights(pocket_part(), 1000.0), [4.0])  # the tops at 12 add up to less


@pytest.mark.parametrize("kw, word", [(dict(engagement=7.0), "engagement"), (dict(step_down=13.0), "step_down"),
                                      (dict(stock=meshmill.Stock.offset(1.0)), "stock"), (dict(axis="0,0,0"), "axis"),
                                      (dict(axis="up"), "axis"), (dict(engagement=-1.0), "engagement"),
                                      (dict(direction="sideways"), "direction")])
def test_bad_settings_are_refused(tools, kw, word):
    with pytest.raises(meshmill.InputError, match=word):
        meshmill.rough(pocket_part(), tools, tool="F6", **kw)


def test_cli_rough_and_a_clear_error(tmp_path, tools):
    part = tmp_path / "pocket.stl"
    import trimesh

    m = pocket_part()
    trimesh.Trimesh(m.vertices, m.faces).export(part)
    (tmp_path / "tools.toml").write_text(TOOLS)
    run = [sys.executable, "-m", "meshmill", "rough", str(part), "--tools", str(tmp_path / "tools.toml"),
           "--tool", "F6", "--out", str(tmp_path / "out"), "--quiet"]
    assert subprocess.run(run, capture_output=True, text=True).returncode == 0
    assert (tmp_path / "out" / "moves.npz").exists()
    bad = subprocess.run(run + ["--engagement", "9"], capture_output=True, text=True)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "engagement" in bad.stderr


def test_a_closed_pocket_no_helix_fits_is_a_clear_error(tools):
    # a closed pocket 6.4 mm wide for a 6 mm tool: its centre has 0.2 mm each way, no helix fits
    part = boxes((0, 0, 0, 20, 30, 2), (0, 0, 2, 20, 5, 8), (0, 25, 2, 20, 30, 8), (0, 5, 2, 6.8, 25, 8),
                 (13.2, 5, 2, 20, 25, 8))
    with pytest.raises(meshmill.InputError, match="no entry fits"):
        meshmill.rough(part, tools, tool="F6", allowance=0.0, stock="box")
