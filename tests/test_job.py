"""Jobs: operations in order from the stock, the in-process stock handed on, fixtures, one program."""
import json
import os
import re

import numpy as np
import pytest
import trimesh

from meshmill import api
from meshmill.cli import main
from meshmill.errors import InputError
from meshmill.geometry import shapes
from meshmill.job import Job

TOOLS = """
[[tools]]
name = "F6"
type = "flat"
diameter = 6.0
flute_length = 20.0
gauge_length = 40.0
holder_diameter = 30.0
holder_length = 40.0

[[tools]]
name = "B6"
type = "ball"
diameter = 6.0
flute_length = 15.0
gauge_length = 40.0
holder_diameter = 30.0
holder_length = 40.0

[[tools]]
name = "B4"
type = "ball"
diameter = 4.0
flute_length = 12.0
gauge_length = 40.0
holder_diameter = 30.0
holder_length = 40.0
"""

# the jaw of a vice against the stock's +X face (the stock is the part's box and 1 mm)
JAW = [16.0, -10.0, -4.0, 20.0, 10.0, 4.0]


def job_toml(folder, rest="0.05", extra=""):
    part = shapes.post_with_fillet(post_radius=6.0, fillet=3.0, height=12.0, plate_radius=15.0, plate_thickness=3.0,
                                   segments=48)
    trimesh.Trimesh(part.vertices, part.faces).export(os.path.join(folder, "part.stl"))
    with open(os.path.join(folder, "tools.toml"), "w") as fh:
        fh.write(TOOLS)
    text = f"""
name = "post"
machine = "generic-3axis"
tools = "tools.toml"
step = 0.5
{extra}
[part]
file = "part.stl"

[stock]
type = "box"
margin = 1

[[fixtures]]
name = "jaw"
box = {JAW}

[[operations]]
name = "rough"
type = "plunge"
tool = "F6"
allowance = 0.5
radial_step = 3.0
engagement = 3.0

[[operations]]
name = "semi"
type = "raster"
tool = "B6"
stepover = 2.0
allowance = 0.2
rest = false

[[operations]]
name = "rest B4"
type = "raster"
tool = "B4"
stepover = 1.0
rest = {rest}
"""
    path = os.path.join(folder, "job.toml")
    with open(path, "w") as fh:
        fh.write(text)
    return path


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    folder = str(tmp_path_factory.mktemp("job"))
    path = job_toml(folder)
    job = Job.from_toml(path)
    res = job.run()
    out = os.path.join(folder, "out")
    res.save(out, report=False)
    return job, res, out


def test_operations_run_in_order_each_from_the_stock_the_last_left(ran):
    job, res, out = ran
    assert res.ok, [o.path.summary["job"]["errors"] for o in res.operations]
    volumes = [res.summary["stock"]["volume_mm3"]] + [o.stock.volume for o in res.operations]
    removed = [o.path.summary["job"]["removed_mm3"] for o in res.operations]
    assert all(r > 0 for r in removed)
    assert np.allclose(np.diff(volumes), -np.array(removed))
    # an independent check of the hand-over: the whole program's path cut at once from the stock
    # removes what the operations removed one after another
    from meshmill.ops.simulate import simulate

    whole = api.load_toolpath(os.path.join(out, "01-rough", "toolpath.cl"), job.tools)
    paths = [api.load_toolpath(os.path.join(out, o.path.summary["job"]["folder"], "toolpath.cl"), job.tools)
             for o in res.operations]
    from meshmill.toolpath.model import Toolpath

    whole = Toolpath.concatenate(paths)
    stock = shapes.box(job.part.bounds[0] - 1.0, job.part.bounds[1] + 1.0)
    _, summary, machined, *_ = simulate(job.part, whole, job.tools, job.step, stock=stock)
    assert machined.volume == pytest.approx(res.operations[-1].stock.volume, rel=2e-3)
    # the final check is the last stock against the design: nothing gouged
    assert res.summary["final"]["gouge_max"] <= job.tolerance + 1e-9


def test_each_folder_holds_the_path_and_the_stock_after_it(ran):
    job, res, out = ran
    for o in res.operations:
        sub = os.path.join(out, o.path.summary["job"]["folder"])
        for name in ("toolpath.cl", "summary.json", "part.stl", "stock.npz", os.path.join("stock", "machined.stl"),
                     os.path.join("stock", "summary.json")):
            assert os.path.exists(os.path.join(sub, name)), name
    summary = json.load(open(os.path.join(out, "job.json")))
    assert [o["name"] for o in summary["operations"]] == ["rough", "semi", "rest B4"]
    assert summary["machining_s"] > sum(o["machining_s"] for o in summary["operations"]) * 0.99


def test_one_program_changes_tools_between_operations(ran):
    job, res, out = ran
    program = open(os.path.join(out, "program.nc")).read().splitlines()
    changes = [ln for ln in program if "M6" in ln.split()]
    assert len(changes) == 3
    assert res.summary["post"]["tool_changes"] == 2 or len(res.summary["post"]["tools"]) == 3


def test_no_path_enters_a_fixture(ran):
    job, res, out = ran
    jaw = shapes.box(JAW[:3], JAW[3:])
    trimmed = 0
    for o in res.operations:
        j = o.path.summary["job"]
        assert j["fixtures"]["ok"]
        trimmed += j["fixtures"]["trimmed_moves"]
        # a second, independent check: the written file against the jaw as a part
        tp = api.load_toolpath(os.path.join(out, j["folder"], "toolpath.cl"), job.tools)
        assert api.verify(jaw, tp, job.tools, tolerance=0.0, device="cpu").ok
    assert trimmed > 0  # the passes over the jaw were cut


def test_rest_machining_cuts_less_air_than_the_whole_path(ran, tmp_path):
    job, res, out = ran
    whole = Job.from_toml(job_toml(str(tmp_path), rest="false")).run()
    # the same stock before the last operation
    assert whole.operations[-2].stock.volume == pytest.approx(res.operations[-2].stock.volume)
    rest = res.operations[-1].path.summary["job"]
    every = whole.operations[-1].path.summary["job"]
    assert rest["cutting_mm"]["in_material"] + rest["cutting_mm"]["in_air"] < every["cutting_mm"]["in_material"] + every["cutting_mm"]["in_air"]
    # what rest machining leaves is within its depth of what the whole path leaves: a bound on the
    # volume, the depth over the area of the stock's top
    area = np.prod(job.part.bounds[1, :2] - job.part.bounds[0, :2] + 2.0)
    assert rest["left_over_design_mm3"] <= every["left_over_design_mm3"] + 0.05 * area


def test_moves_through_the_air_run_at_the_largest_feed(ran):
    """The job's runs of feed moves that cut nothing of the in-process stock are fed at the
    machine's largest feed (written G1, so the path stays the one verified): each operation is
    shorter than at the table's feeds, and the air is where the stock measured it."""
    job, res, out = ran
    fast = job.machine.spindle.max_feed
    for o in res.operations:
        j = o.path.summary["job"]
        assert j["feeds"]["air_fast_s"] <= j["feeds"]["table_s"]
        tp, inside = o.path.toolpath, o.cut.load.in_material
        sped = np.isclose(tp.feed, fast)
        assert not (sped & inside).any() and not (sped & tp.rapid).any()
    assert any(np.isclose(o.path.toolpath.feed, fast).any() for o in res.operations)
    program = open(os.path.join(out, "program.nc")).read()
    assert re.search(rf"G1\b[^\n]*F{fast:.0f}\b", program)


def test_job_file_errors_are_one_line(tmp_path, capsys):
    path = job_toml(str(tmp_path), extra='colour = "red"')
    assert main(["job", path, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown key colour" in err[0]
    text = open(job_toml(str(tmp_path))).read()
    for bad, says in ((text.replace('stepover = 2.0', 'stepover = 2.0\nwobble = 1'), "unknown parameter wobble"),
                      (text.replace('tool = "B4"', 'tool = "B3"'), "no tool 'B3'"),
                      (text.replace('type = "box"\nmargin = 1', 'type = "sphere"'), "[stock]: type must be one of box, cylinder, mesh, offset, got 'sphere'"),
                      (text.replace('stepover = 1.0', 'stepover = -1.0'), "operation 3 (rest B4): stepover must be a positive number")):
        with open(tmp_path / "bad.toml", "w") as fh:
            fh.write(bad)
        with pytest.raises(InputError, match=re.escape(says)):
            Job.from_toml(tmp_path / "bad.toml").run()


def test_the_package_exports_the_job():
    import meshmill

    assert meshmill.Job is Job


@pytest.mark.parametrize("kind", ["box", "cylinder"])
def test_stock_kinds_hold_the_part(kind):
    from meshmill import Stock

    part = shapes.post_with_fillet(segments=32)
    solid = Stock.from_dict({"type": kind, "margin": 2.0}).solid(part)
    assert solid.closed
    assert (solid.bounds[0] <= part.bounds[0] - 2.0 + 1e-9).all() and (solid.bounds[1] >= part.bounds[1] + 2.0 - 1e-9).all()
    if kind == "cylinder":  # the round bar's polygon holds the circle of the part's widest radius plus the margin
        r = np.hypot(*solid.vertices[:, :2].T)
        assert r.max() >= 42.0 - 1e-9


def test_choose_runs_as_an_operation_of_the_job(tmp_path):
    text = open(job_toml(str(tmp_path))).read()
    text = text[:text.index('[[operations]]\nname = "semi"')] + """[[operations]]
name = "semi"
type = "raster"
tool = "B6"
stepover = 2.0
allowance = 0.2

[[operations]]
name = "zones"
type = "choose"
scallop = 0.05
zones = 1
grid = 30
tools = ["B4", "B6"]
"""
    path = tmp_path / "choose.toml"
    path.write_text(text)
    job = Job.from_toml(path)
    res = job.run()
    op = res.operations[-1]
    assert op.ok, op.path.summary["job"]["errors"]
    assert op.path.summary["job"]["removed_mm3"] > 0
    # the chosen cutters are numbered as the job's table in the one program
    used = {job.tools[int(t)].name for t in op.path.toolpath.tool}
    assert used <= {"B4", "B6"}
    res.save(tmp_path / "out", report=False)
    assert os.path.exists(tmp_path / "out" / "03-zones" / "zones.npz")


@pytest.mark.parametrize("stock", ['type = "offset"\nallowance = 1.0', 'type = "cylinder"\nmargin = 1.0',
                                   'type = "mesh"\nfile = "blank.stl"'])
def test_every_kind_of_stock_is_cut_by_the_job(tmp_path, stock):
    part = job_toml(str(tmp_path))
    blank = shapes.box([-17.0, -17.0, -4.0], [17.0, 17.0, 13.0])
    trimesh.Trimesh(blank.vertices, blank.faces).export(tmp_path / "blank.stl")
    text = open(part).read().replace('type = "box"\nmargin = 1', stock)
    text = text[:text.index('[[operations]]\nname = "semi"')]  # the roughing alone
    path = tmp_path / "stock.toml"
    path.write_text(text)
    res = Job.from_toml(path).run()
    assert res.ok, res.operations[0].path.summary["job"]["errors"]
    start = res.summary["stock"]["volume_mm3"]
    assert start > res.summary["final"]["design_volume_mm3"]
    assert 0 < res.operations[0].path.summary["job"]["removed_mm3"] < start
