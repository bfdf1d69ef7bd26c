"""Cutting data, the load of every move measured on the dexel stock, overloads refused and feeds
optimised: a full-width slot, a 10 % side cut, a ball at a known depth, a move in air, all with
their answers in closed form; the tool table's cutting data, FreeCAD and LinuxCNC tables."""
import json
import math
import subprocess
import sys

import numpy as np
import pytest

import meshmill
from meshmill.errors import InputError
from meshmill.geometry.mesh import closed_mesh
from meshmill.machine.config import load_machine
from meshmill.simulation.load import effective_diameter
from meshmill.ops.feeds import MAX_THINNING, MERGE_LENGTH, air_feeds, air_time_share, table_feeds
from meshmill.toolpath.model import Toolpath
from meshmill.tools.cutting import MATERIALS, conditions
from meshmill.tools.table import load_tools, tool_from_entry

F10 = dict(name="F10", type="flat", diameter=10.0, flute_length=30.0, gauge_length=60.0, flutes=3, rpm=8000.0,
           fz=0.05, ae_ratio=0.5, ap=8.0, plunge_feed=300.0)
B10 = dict(name="B10", type="ball", diameter=10.0, flute_length=20.0, gauge_length=60.0, flutes=2, rpm=10000.0,
           fz=0.05)


def block(x1=60.0, y1=40.0, z1=20.0):
    """A closed box from the origin, its faces on the dexel lattice's planes."""
    v = np.array([[x, y, z] for z in (0.0, z1) for y in (0.0, y1) for x in (0.0, x1)])
    f = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                  [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    return closed_mesh(v, f, "block")


def straight(points, rapid_first=True, step=1.0):
    """A path through ``points`` (their first a rapid), its feed moves split every ``step`` mm."""
    pts, rapid = [np.asarray(points[0], float)], [True]
    for a, b in zip(points[:-1], points[1:]):
        a, b = np.asarray(a, float), np.asarray(b, float)
        n = max(1, int(math.ceil(np.linalg.norm(b - a) / step)))
        for k in range(1, n + 1):
            pts.append(a + (b - a) * k / n)
            rapid.append(False)
    pts = np.array(pts)
    return Toolpath(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), np.array(rapid), np.zeros(len(pts), np.int64))


def cut(part, tp, entry, step=0.5, **kw):
    tools = [tool_from_entry(entry, 1, "test")]
    return meshmill.simulate(part, tp, tools, step=step, stock="box", outputs=(), **kw), tools


def test_a_full_width_slot_removes_width_times_depth_times_feed():
    # a 10 mm flat, 5 mm deep, along X across a 60 mm block, at fz 0.05 x 3 x 8000 = 1200 mm/min
    tp = straight([(-10, 20, 30), (-10, 20, 15), (70, 20, 15)])
    tp.feed[:] = 1200.0
    res, _ = cut(block(), tp, F10)
    load = res.load
    middle = np.nonzero(load.in_material & (tp.tip[:, 0] > 15) & (tp.tip[:, 0] < 45))[0]
    assert len(middle) > 20
    assert np.allclose(load.rate[middle], 10 * 5 * 1200, rtol=0.03)
    assert np.allclose(load.ap[middle], 5.0, atol=1e-9) and np.allclose(load.ae[middle], 10.0, atol=1e-9)
    assert np.allclose(load.angle[middle], 180.0) and np.allclose(load.chip_max[middle], 0.05)
    assert load.volume.sum() == pytest.approx(10 * 5 * 60, rel=1e-6)
    # 5 x 10 mm is more section than the tool's 8 x 5 mm (ap x 0.5 D): an overload, said with where
    assert not res.ok and any("cut section ap x ae of 40 mm²: up to 5 x 10 mm" in e for e in res.summary["errors"])
    over = res.summary["load"]["tools"][0]["over"]
    assert over["section"] > 0 and over["chip"] == 0


def test_a_ten_percent_side_cut_engages_acos_one_minus_two_ae_over_d():
    # the tool's centre 4 mm outside the block's side at y = 40: 1 mm of its 10 mm engaged, 5 deep
    tp = straight([(-10, 44, 30), (-10, 44, 15), (70, 44, 15)])
    tp.feed[:] = 1200.0
    res, _ = cut(block(), tp, F10, material="aluminium-6061", machine="generic-3axis")
    load = res.load
    mid = np.nonzero(load.in_material & (tp.tip[:, 0] > 15) & (tp.tip[:, 0] < 45))[0]
    assert np.allclose(load.ae[mid], 1.0, atol=1e-9)
    phi = math.degrees(math.acos(1 - 2 * 1.0 / 10.0))
    assert np.allclose(load.angle[mid], phi, atol=1e-6)
    assert np.allclose(load.chip_max[mid], 0.05 * math.sin(math.radians(phi)))  # chip thinning
    assert np.allclose(load.chip_mean[mid], 0.05 * 1.0 / (5.0 * math.radians(phi)))
    assert np.allclose(load.rate[mid], 1 * 5 * 1200, rtol=0.03)
    kc = MATERIALS["aluminium-6061"].specific_energy(load.chip_mean[mid])
    assert np.allclose(load.power[mid], kc * load.rate[mid] / 60e6)
    assert np.allclose(load.torque[mid], load.power[mid] * 1e3 / (2 * math.pi * 8000 / 60))
    assert res.ok and res.summary["load"]["ok"]


def test_a_ball_at_a_known_depth_cuts_at_its_effective_diameter():
    # a 10 mm ball 2 mm into the flat top: a groove 2 sqrt(2 x 8) = 8 mm wide
    tp = straight([(-10, 20, 30), (-10, 20, 18), (70, 20, 18)])
    res, tools = cut(block(), tp, B10, step=0.25)
    load = res.load
    mid = np.nonzero(load.in_material & (tp.tip[:, 0] > 15) & (tp.tip[:, 0] < 45))[0]
    assert np.allclose(load.height[mid], 2.0, atol=1e-9)  # the top of the cut: the block's top, exactly
    assert np.allclose(load.ap[mid], 2.0, atol=0.01)  # its bottom: the lowest dexel end the ball reaches
    assert np.allclose(load.diameter[mid], 8.0) and effective_diameter(tools[0], [2.0, 7.0])[1] == 10.0
    assert np.all(load.ae[mid] <= 8.0 + 1e-9) and np.all(load.ae[mid] >= 8.0 - 0.25)
    area = 25 * math.acos(3 / 5) - 3 * 4  # the circular segment the ball's section cuts
    assert load.volume[mid].sum() / (tp.tip[mid[-1], 0] - tp.tip[mid[0] - 1, 0]) == pytest.approx(area, rel=0.03)


def test_a_move_in_air_has_no_load_and_is_not_an_error():
    tp = straight([(-10, 20, 30), (-10, 20, 25), (70, 20, 25)])
    res, _ = cut(block(), tp, F10)
    assert not res.load.in_material.any() and res.load.volume.sum() == 0.0
    assert np.isnan(res.load.ap).all() and res.summary["load"]["tools"][0]["moves_in_material"] == 0
    assert res.summary["errors"] == []


def test_power_over_the_spindle_is_refused():
    weak = tmp_machine = load_machine("generic-3axis")
    from dataclasses import replace
    weak = replace(tmp_machine, spindle=replace(tmp_machine.spindle, power_kw=0.05))
    tp = straight([(-10, 44, 30), (-10, 44, 15), (70, 44, 15)])
    res, _ = cut(block(), tp, F10, material="steel-p20", machine=weak)
    assert not res.ok and any("spindle power of 0.05 kW" in e for e in res.summary["errors"])


def test_feeds_from_the_table_are_written_as_fedrat_and_spindl_and_f_and_s(tmp_path):
    tools = [tool_from_entry(F10, 1, "t")]
    tp = straight([(-10, 44, 30), (-10, 44, 15), (70, 44, 15), (70, 44, 30)], step=100)
    feeds = table_feeds(tp, conditions(tools))
    assert np.isnan(feeds[0]) and feeds[1] == 300.0 and feeds[2] == pytest.approx(1200.0)  # plunge, then cut
    assert feeds[3] == pytest.approx(1200.0)  # up: not a plunge
    tp.feed = feeds
    from meshmill.toolpath.cldata import write_apt

    write_apt(tmp_path / "p.cl", tp, tools)
    text = (tmp_path / "p.cl").read_text()
    assert "SPINDL/RPM, 8000, CLW" in text and "FEDRAT/300.0, MMPM" in text and "FEDRAT/1200.0, MMPM" in text
    back = meshmill.load_toolpath(str(tmp_path / "p.cl"), tools)
    assert np.allclose(back.feed[1:], feeds[1:])
    program = meshmill.post(back, "generic-3axis", tools)
    assert any("S8000" in line for line in program.lines)
    assert any("F300" in line for line in program.lines) and any("F1200" in line for line in program.lines)


def test_operations_write_each_tools_feed_and_speed_in_the_material():
    table = [dict(F10, rpm=None, vc=250.0)]
    table[0].pop("rpm")
    table[0]["cutting"] = [{"material": "steel-p20", "vc": 100.0, "fz": 0.03}]
    tools = [tool_from_entry(table[0], 1, "t")]
    part = block(40, 30, 10)
    res = meshmill.raster(part, tools, tool="F10", stepover=8.0, material="steel-p20", device="cpu")
    rpm = 100.0 * 1000 / (math.pi * 10)
    assert res.tools[0].rpm == pytest.approx(rpm)
    feed = res.toolpath.feed[~res.toolpath.rapid][1:]
    assert np.isclose(feed, 0.03 * 3 * rpm).mean() > 0.5  # fz x flutes x rpm
    assert set(np.round(feed[~np.isclose(feed, 0.03 * 3 * rpm)], 6)) <= {300.0}  # and the plunges' feed
    with pytest.raises(InputError, match="material must be one of"):
        meshmill.raster(part, tools, tool="F10", stepover=8.0, material="unobtainium", device="cpu")


def test_feed_optimisation_speeds_light_cuts_and_air_and_keeps_every_move_within_limits():
    tools = [tool_from_entry(dict(F10, ae_ratio=1.0), 1, "t")]
    # a side cut of 1 mm, then through air, then a full slot
    tp = straight([(-10, 44, 30), (-10, 44, 15), (70, 44, 15), (70, 60, 15), (-10, 60, 15), (-10, 20, 15),
                   (70, 20, 15)])
    tp.feed = table_feeds(tp, conditions(tools))
    machine = load_machine("generic-3axis")
    res = meshmill.simulate(block(), tp, tools, step=0.5, stock="box", outputs=(), material="aluminium-6061",
                            machine=machine)
    new = meshmill.optimised_feeds(tp, res.load, tools, "aluminium-6061", machine)
    load = res.load
    side = load.in_material & (np.abs(tp.tip[:, 1] - 44) < 1e-9) & (tp.tip[:, 0] > 15) & (tp.tip[:, 0] < 45)
    slot = load.in_material & (np.abs(tp.tip[:, 1] - 20) < 1e-9) & (tp.tip[:, 0] > 15) & (tp.tip[:, 0] < 45)
    air = ~tp.rapid & ~load.in_material
    air[0] = False
    # the side cut's chip is thinned to 0.6 fz: fed up to fz again (within 5 %), the slot at the table's feed
    assert np.all(new[side] <= 1200 / 0.6 + 1e-6) and np.all(new[side] >= 1200 / 0.6 / 1.05 - 1e-6)
    assert np.all(new[slot] <= 1200 + 1e-6) and np.all(new[slot] >= 1200 / 1.05 - 1e-6)
    assert np.all(new[air & (tp.tip[:, 1] > 50)] > 10000)  # through air at the machine's largest feed, still G1
    assert np.all(new[~tp.rapid][1:] <= machine.spindle.max_feed + 1e-6)
    assert np.all(new[side] / 1200 <= MAX_THINNING)
    # the new feeds cut within the limits: the chip at most fz, the power under the spindle's
    again = Toolpath(tp.tip, tp.axis, tp.rapid, tp.tool, tp.line, new)
    res2 = meshmill.simulate(block(), again, tools, step=0.5, stock="box", outputs=(), material="aluminium-6061",
                             machine=machine)
    assert res2.ok and np.nanmax(res2.load.chip_max) <= 0.05 * 1.0001
    t0 = meshmill.machining_time(tp, machine, tools).summary["total"]["total_s"]
    t1 = meshmill.machining_time(again, machine, tools).summary["total"]["total_s"]
    assert t1 < 0.8 * t0


def test_runs_in_air_are_fed_at_the_largest_feed_and_the_cuts_keep_theirs():
    """A slot, a 0.5 mm hop up in it, the slot on, a 25 mm move through the air: the long run in
    air at the machine's largest feed, the hop and the cuts as programmed; cut again with the new
    feeds, the air is still air and the time is shorter."""
    tools = [tool_from_entry(dict(F10, ae_ratio=1.0), 1, "t")]
    tp = straight([(-10, 20, 30), (-10, 20, 15), (20, 20, 15), (20, 20, 15.5), (30, 20, 15.5), (30, 20, 25),
                   (30, 0.0, 25), (30, 0.0, 15)])
    tp.feed = table_feeds(tp, conditions(tools))
    machine = load_machine("generic-3axis")
    res = meshmill.simulate(block(), tp, tools, step=0.5, stock="box", outputs=())
    inside = res.load.in_material
    new = meshmill.air_feeds(tp, inside, machine)
    air = ~tp.rapid & ~inside
    air[0] = False
    lifted = air & (tp.tip[:, 2] > 20)  # up out of the slot, over and down to the stock: 25 mm in air
    assert lifted.sum() >= 20 and np.all(new[lifted] == machine.spindle.max_feed)
    assert np.array_equal(new[~air], tp.feed[~air], equal_nan=True)  # cuts and rapids untouched
    # every fast move lies in a run in air at least MERGE_LENGTH long; the others keep their feed
    hop = air & (np.abs(tp.tip[:, 2] - 15.5) < 1e-9) & (np.abs(tp.tip[:, 0] - 20) < 1e-9)
    assert hop.any() and np.array_equal(new[hop], tp.feed[hop], equal_nan=True)
    again = Toolpath(tp.tip, tp.axis, tp.rapid, tp.tool, tp.line, new)
    res2 = meshmill.simulate(block(), again, tools, step=0.5, stock="box", outputs=())
    assert np.array_equal(res2.load.in_material, inside) and res2.ok
    nominal = machine.motion.feed * 60.0
    assert air_time_share(again, inside, nominal) < air_time_share(tp, inside, nominal)
    t0 = meshmill.machining_time(tp, machine, tools).summary["total"]["cutting_s"]
    t1 = meshmill.machining_time(again, machine, tools).summary["total"]["cutting_s"]
    assert t1 < t0
    assert MERGE_LENGTH > 1.0  # the hop is shorter than a run the feed changes for


def test_meshmill_feeds_writes_the_path_the_program_and_the_times(tmp_path):
    part = block(40, 30, 10)
    (tmp_path / "part.stl").write_bytes(b"")
    part_file = tmp_path / "part.stl"
    import trimesh

    trimesh.Trimesh(part.vertices, part.faces).export(part_file)
    tools_file = tmp_path / "tools.toml"
    tools_file.write_text('[[tools]]\nname = "F10"\ntype = "flat"\ndiameter = 10.0\nflute_length = 30.0\n'
                          'gauge_length = 60.0\nflutes = 3\nvc = 250.0\nfz = 0.05\n')
    tools = load_tools(str(tools_file))
    path = meshmill.raster(part, tools, tool="F10", stepover=3.0, device="cpu", material="aluminium-6061")
    path.save(str(tmp_path / "r"))
    out = tmp_path / "feeds"
    run = subprocess.run([sys.executable, "-m", "meshmill", "feeds", "--design", str(part_file), "--toolpath",
                          str(tmp_path / "r/toolpath.cl"),
                          "--tools", str(tools_file), "--material", "aluminium-6061", "--stock", "offset:1",
                          "--out", str(out), "--json"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    s = json.loads((out / "summary.json").read_text())
    assert s["time_s"]["optimised"] < s["time_s"]["before"]
    assert "FEDRAT/" in (out / "toolpath.cl").read_text() and "F" in (out / "program.nc").read_text()
    bad = subprocess.run([sys.executable, "-m", "meshmill", "feeds", "--design", str(part_file), "--toolpath",
                          str(tmp_path / "r/toolpath.cl"),
                          "--tools", str(tools_file), "--material", "cheese", "--out", str(out)],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and len(bad.stderr.strip().splitlines()) == 1 and "material" in bad.stderr


@pytest.mark.parametrize("entry, message", [
    (dict(F10, fz=-1.0), "'fz' must be a number of mm > 0"),
    (dict(F10, flutes=2.5), "'flutes' must be a whole number"),
    (dict(F10, ap=3.0, ap_ratio=0.5), "give 'ap' or 'ap_ratio', not both"),
    (dict(F10, cutting=[{"vc": 100.0}]), "needs material"),
    (dict(F10, cutting=[{"material": "x", "flutes": 2}]), "unknown key 'flutes'"),
    ({**{k: v for k, v in F10.items() if k != "rpm"}, "vc": "fast"}, "'vc' must be a number of m/min"),
    (dict(F10, vc=200.0), "give 'rpm' or 'vc', not both"),
])
def test_bad_cutting_data_is_one_line(entry, message):
    with pytest.raises(InputError, match=message) as exc:
        tool_from_entry(entry, 1, "table.toml")
    assert "\n" not in str(exc.value)


def test_the_material_overrides_the_tools_own_data_and_the_spindle_holds_the_speed():
    t = tool_from_entry(dict(F10, cutting=[{"material": "steel-p20", "rpm": 30000.0, "ae": 1.0}]), 1, "t")
    own, steel = t.cutting(), t.cutting("steel-p20", max_rpm=12000.0)
    assert own.rpm == 8000.0 and own.ae == 5.0 and own.feed == pytest.approx(1200.0)
    assert steel.rpm == 12000.0 and steel.ae == 1.0 and steel.fz == 0.05 and steel.ap == 8.0
    assert steel.plunge_feed == 300.0 and steel.material == "steel-p20"


def test_cutting_data_is_written_back_as_read(tmp_path):
    from meshmill.tools.table import write_tools

    t = tool_from_entry(dict(F10, cutting=[{"material": "steel-p20", "rpm": 3000.0, "ae_ratio": 0.1}]), 1, "t")
    write_tools(tmp_path / "t.toml", [t])
    [back] = load_tools(str(tmp_path / "t.toml"))
    assert back.data == t.data and back.flutes == 3 and back.cutting("steel-p20") == t.cutting("steel-p20")


def test_the_machines_spindle_section_is_read_and_checked(tmp_path):
    m = load_machine("generic-3axis")
    assert m.spindle.power_kw == 11 and m.spindle.max_rpm == 12000 and m.spindle.max_feed == 15000
    p = tmp_path / "m.toml"
    base = ("[motion]\nfeed_mm_min = 1000\nrapid_mm_min = 5000\naccel_mm_s2 = 100\njerk_mm_s3 = 1000\n"
            "corner_angle_deg = 5\ntool_change_s = 5\nreorient_s = 0\n")
    p.write_text(base + "[spindle]\npower_kw = 2\n")
    assert load_machine(str(p)).spindle.max_feed == 5000  # the rapid rate where not given
    p.write_text(base + "[spindle]\npower = 2\n")
    with pytest.raises(InputError, match="unknown key 'power'"):
        load_machine(str(p))


def test_freecad_and_linuxcnc_tables_load_as_tool_tables(tmp_path):
    bit = tmp_path / "6mm_Endmill.fctb"
    bit.write_text(json.dumps({"version": 2, "name": "6 mm end mill", "shape": "endmill.fcstd",
                               "parameter": {"Diameter": "6.00 mm", "CuttingEdgeHeight": "18.00 mm",
                                             "Length": "50.00 mm", "ShankDiameter": "6.00 mm"},
                               "attribute": {"Flutes": 3}}))
    [t] = meshmill.load_tools(str(bit))
    assert (t.type, t.diameter, t.flute_length, t.gauge_length, t.flutes) == ("flat", 6.0, 18.0, 50.0, 3)
    tbl = tmp_path / "tool.tbl"
    tbl.write_text("T1 P1 D6.0 Z+40.0 ;6 mm flat end mill\nT5 P2 D0.25 Z+2.0 ;quarter inch ball\n")
    tools = meshmill.load_tools(str(tbl))
    assert [t.type for t in tools] == ["flat", "ball"] and tools[1].diameter == 0.25
    assert any("T5 is tool 2" in w for w in tools.warnings)
    inch = meshmill.load_tools(str(tbl), units="inch")
    assert inch[1].diameter == pytest.approx(6.35)


def test_a_job_whose_finishing_ball_runs_in_full_material_is_refused():
    ball = dict(B10, ap_ratio=0.2, ae_ratio=0.5)  # rated for 2 x 5 mm
    tools = [tool_from_entry(ball, 1, "t")]
    job = meshmill.Job(part=block(30, 20, 10), tools=tools, stock=meshmill.Stock.box(3.0), machine="generic-3axis",
                       operations=[{"type": "raster", "tool": "B10", "stepover": 2.0}], material="aluminium-6061",
                       step=0.5)
    res = job.run()
    op = res.operations[0]
    assert not res.ok and not op.ok and res.summary["operations"][0]["load_ok"] is False
    assert any("cut section ap x ae of 10 mm²" in e for e in op.path.summary["job"]["errors"])
