"""The job file, the API and the command line used as a hostile but realistic user uses them:
wrong types (numbers and booleans as text, tables where a number is wanted), wrong shapes, unknown
keys, empty and huge values, nothing to cut, a stock smaller than the part, a fixture inside it.
Every one ends in :class:`meshmill.InputError` naming what is wrong (the API) or one line on
stderr and exit code 2 (the command line), never in a traceback, and before anything heavy is
computed where the input alone says it is wrong."""
import os
import re

import numpy as np
import pytest
import trimesh

import meshmill
from meshmill.cli import main
from meshmill.geometry import shapes

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "src", "meshmill", "data")

BASE = """name = "h"
tools = "tools.toml"
step = 2.0
{top}
[part]
file = "part.stl"
{part}
[stock]
type = "box"
margin = 1
{stock}
{fixtures}
[[operations]]
type = "raster"
tool = "B4"
stepover = 6.0
sample = 2.0
{op}
"""


def job(folder, top="", part="", stock="", fixtures="", op="", text=None):
    """A small job file in ``folder`` (a post with a fillet, 30 mm across, a box stock; one raster)
    with the given lines added to its sections, or ``text`` whole."""
    post = shapes.post_with_fillet(post_radius=6.0, fillet=3.0, height=12.0, plate_radius=15.0, plate_thickness=3.0,
                                   segments=32)
    trimesh.Trimesh(post.vertices, post.faces).export(os.path.join(folder, "part.stl"))
    small = shapes.box((-3, -3, 0), (3, 3, 5))
    trimesh.Trimesh(small.vertices, small.faces).export(os.path.join(folder, "small.stl"))
    with open(os.path.join(DATA, "tools.toml")) as src, open(os.path.join(folder, "tools.toml"), "w") as dst:
        dst.write(src.read())
    path = os.path.join(folder, "job.toml")
    with open(path, "w") as fh:
        fh.write(text if text is not None else BASE.format(top=top, part=part, stock=stock, fixtures=fixtures, op=op))
    return path


def one_line(capsys, argv, code=2):
    """Run the command line; assert the exit code and a single ``meshmill: error:`` line."""
    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    err = [e for e in err if not e.startswith(("[", "warning:"))]  # progress and warnings aside
    assert rc == code and len(err) == 1 and err[0].startswith("meshmill: error: "), (rc, err)
    return err[0]


# ---------------------------------------------------------------- job files

JOB_FILES = [
    # (what, the job file's change, what the error says)
    ("TOML that does not parse", dict(text="name = \n"), "not a job file (TOML)"),
    ("an empty file", dict(text=""), "no [part]"),
    ("the part as a file name", dict(text='tools = "tools.toml"\npart = "part.stl"\n[[operations]]\ntype = "raster"\n'),
     "part must be a table"),
    ("operations as numbers", dict(text='tools = "tools.toml"\noperations = [1, 2]\n[part]\nfile = "part.stl"\n'),
     "operations must be a list of tables"),
    ("operations as text", dict(text='tools = "tools.toml"\noperations = "raster"\n[part]\nfile = "part.stl"\n'),
     "operations must be a list of tables"),
    ("one operation as a table", dict(text='tools = "tools.toml"\n[part]\nfile = "part.stl"\n[operations]\ntype = "raster"\n'),
     "operations must be a list of tables"),
    ("no operations", dict(text='tools = "tools.toml"\n[part]\nfile = "part.stl"\n'), "no [[operations]]"),
    ("an unknown key", dict(top='colour = "red"'), "unknown key colour"),
    ("a misspelt key", dict(top="stepp = 1"), "unknown key stepp"),
    ("the name as a number", dict(top="name2 = 1"), "unknown key name2"),
    ("the step as text", dict(text=BASE.replace("step = 2.0", 'step = "2"').format(top="", part="", stock="",
                                                                                  fixtures="", op="")),
     "step must be a positive number of mm, got '2' (text: a number is written without quotes)"),
    ("a negative step", dict(text=BASE.replace("step = 2.0", "step = -1").format(top="", part="", stock="", fixtures="",
                                                                                op="")), "step must be a positive"),
    ("a zero step", dict(text=BASE.replace("step = 2.0", "step = 0").format(top="", part="", stock="", fixtures="",
                                                                           op="")), "step must be a positive"),
    ("a step of nan", dict(text=BASE.replace("step = 2.0", "step = nan").format(top="", part="", stock="",
                                                                               fixtures="", op="")), "got nan"),
    ("a step of inf", dict(text=BASE.replace("step = 2.0", "step = inf").format(top="", part="", stock="",
                                                                               fixtures="", op="")), "got inf"),
    ("a huge step count", dict(text=BASE.replace("step = 2.0", "step = 1e-6").format(top="", part="", stock="",
                                                                                    fixtures="", op="")),
     "of memory"),
    ("the tolerance as text", dict(top='tolerance = "0.01"'), "tolerance must be a number of mm >= 0, got '0.01'"),
    ("a negative tolerance", dict(top="tolerance = -1"), "tolerance must be a number of mm >= 0, got -1"),
    ("the clearance as a list", dict(top="clearance = [1]"), "clearance must be a number of mm >= 0, got [1]"),
    ("rest as the text false", dict(top='rest = "false"'), "rest must be a number of mm >= 0 or False, got 'false'"),
    ("a negative rest", dict(top="rest = -0.1"), "rest must be"),
    ("in_process as text", dict(top='in_process = "false"'),
     "in_process must be true or false, got 'false' (text: true and false are written without quotes)"),
    ("in_process as a number", dict(top="in_process = 0"), "in_process must be true or false, got 0"),
    ("an unknown nothing_to_cut", dict(top='nothing_to_cut = "maybe"'), "nothing_to_cut must be one of skip, refuse"),
    ("an unknown device", dict(top='device = "gpu"'), "device must be one of cpu, cuda, auto, got 'gpu'"),
    ("the device as a number", dict(top="device = 1"), "device must be one of cpu, cuda, auto, got 1"),
    ("no tools", dict(text=BASE.replace('tools = "tools.toml"\n', "").format(top="", part="", stock="", fixtures="",
                                                                            op="")), "no tools"),
    ("the tools as a number", dict(text=BASE.replace('tools = "tools.toml"', "tools = 5").format(
        top="", part="", stock="", fixtures="", op="")), "tools must be the tool table's file name, got 5"),
    ("a missing tool table", dict(text=BASE.replace('tools = "tools.toml"', 'tools = "nope.toml"').format(
        top="", part="", stock="", fixtures="", op="")), "nope.toml"),
    ("the machine as a number", dict(top="machine = 5"), "machine must be a shipped name or a machine file, got 5"),
    ("an unknown machine", dict(top='machine = "no-such-machine"'), "no-such-machine"),
    ("a 3-axis machine for a finish", dict(top='machine = "generic-3axis"', op='[[operations]]\ntype = "finish"\n'
                                                                            'step_down = 2.0'), "is 3-axis"),
    ("[part] without its file", dict(text=BASE.replace('file = "part.stl"', 'units = "mm"').format(
        top="", part="", stock="", fixtures="", op="")), "[part] needs file"),
    ("[part] file as a number", dict(text=BASE.replace('file = "part.stl"', "file = 5").format(
        top="", part="", stock="", fixtures="", op="")), "[part] file must be a file name, got 5"),
    ("[part] file missing", dict(text=BASE.replace('file = "part.stl"', 'file = "gone.stl"').format(
        top="", part="", stock="", fixtures="", op="")), "gone.stl"),
    ("[part] up as a number", dict(part="up = 5"), "up must be an axis"),
    ("[part] up as a vector", dict(part="up = [0, 0, 1]"), "up must be an axis"),
    ("[part] up unknown", dict(part='up = "sideways"'), "up 'sideways': give an axis"),
    ("[part] origin of two numbers", dict(part="origin = [0, 0]"), "origin must be"),
    ("[part] origin unknown", dict(part='origin = "middle"'), "origin 'middle'"),
    ("[part] units unknown", dict(part='units = "furlong"'), "units must be one of mm, cm, m, in, got 'furlong'"),
    ("[part] scale as text", dict(part='scale = "2"'), "scale must be a positive number, got '2'"),
    ("[part] scale zero", dict(part="scale = 0"), "scale must be a positive number, got 0"),
    ("[part] flip as text", dict(part='flip = "no"'), "flip must be true or false, got 'no'"),
    ("[part] an unknown key", dict(part='colour = "red"'), "[part]: unknown key colour"),
    ("the stock as text", dict(text=BASE.replace("[stock]\ntype = \"box\"\nmargin = 1\n", "").replace(
        'tools = "tools.toml"', 'tools = "tools.toml"\nstock = "box"').format(top="", part="", stock="", fixtures="",
                                                                             op="")), "stock must be a table"),
    ("[stock] an unknown type", dict(text=BASE.replace('type = "box"', 'type = "sphere"').format(
        top="", part="", stock="", fixtures="", op="")), "[stock]: type must be one of box, cylinder, mesh, offset"),
    ("[stock] margin as text", dict(text=BASE.replace("margin = 1", 'margin = "1"').format(
        top="", part="", stock="", fixtures="", op="")), "[stock]: margin must be a number of mm >= 0, got '1'"),
    ("[stock] a negative margin", dict(text=BASE.replace("margin = 1", "margin = -1").format(
        top="", part="", stock="", fixtures="", op="")), "[stock]: margin must be a number of mm >= 0, got -1"),
    ("[stock] a mesh without a file", dict(text=BASE.replace('type = "box"', 'type = "mesh"').format(
        top="", part="", stock="", fixtures="", op="")), "type 'mesh' needs file"),
    ("[stock] a mesh file missing", dict(text=BASE.replace('type = "box"', 'type = "mesh"\nfile = "gone.stl"').format(
        top="", part="", stock="", fixtures="", op="")), "gone.stl"),
    ("[stock] a file for a box", dict(stock='file = "small.stl"'), "file is for type 'mesh', not 'box'"),
    ("[stock] a zero diameter", dict(text=BASE.replace('type = "box"', 'type = "cylinder"\ndiameter = 0').format(
        top="", part="", stock="", fixtures="", op="")), "diameter must be a positive number of mm, got 0"),
    ("[stock] a bar narrower than the part", dict(text=BASE.replace('type = "box"', 'type = "cylinder"\ndiameter = 10')
                                                  .format(top="", part="", stock="", fixtures="", op="")),
     "is narrower than the part"),
    ("[stock] a stock mesh smaller than the part", dict(text=BASE.replace(
        'type = "box"', 'type = "mesh"\nfile = "small.stl"').format(top="", part="", stock="", fixtures="", op="")),
     "the stock mesh does not hold the part"),
    ("[stock] an unknown frame", dict(stock='frame = "world"'), "[stock]: frame must be one of part, work"),
    ("fixtures as a table", dict(fixtures='[fixtures]\nname = "plate"'), "fixtures must be a list of tables"),
    ("a fixture box of two numbers", dict(fixtures="[[fixtures]]\nbox = [0, 0]"),
     "fixture 1: box must be 6 numbers"),
    ("a fixture box as text", dict(fixtures='[[fixtures]]\nbox = "0,0,0,1,1,1"'), "fixture 1: box must be 6 numbers"),
    ("a fixture box inside out", dict(fixtures="[[fixtures]]\nbox = [30, 30, -5, 20, 20, -1]"),
     "box's second corner must lie above the first"),
    ("a fixture with a file and a box", dict(fixtures='[[fixtures]]\nfile = "small.stl"\nbox = [20, 20, -5, 30, 30, -1]'),
     "give exactly one of file and box"),
    ("a fixture with neither", dict(fixtures='[[fixtures]]\nname = "plate"'), "fixture 'plate': give exactly one"),
    ("a fixture inside the part", dict(fixtures='[[fixtures]]\nname = "clamp"\nbox = [-3, -3, 2, 3, 3, 8]'),
     "fixture 'clamp' overlaps the part"),
    ("a fixture with an unknown key", dict(fixtures="[[fixtures]]\nbox = [20, 20, -5, 30, 30, -1]\ncolour = 1"),
     "unknown parameter colour"),
    ("an operation without a type", dict(text=BASE.replace('type = "raster"\n', "").format(
        top="", part="", stock="", fixtures="", op="")), "operation 1: type must be one of rough, plunge, raster"),
    ("an unknown operation", dict(text=BASE.replace('type = "raster"', 'type = "drill"').format(
        top="", part="", stock="", fixtures="", op="")), "type must be one of rough, plunge, raster, waterline, steep-shallow, rest-finish, finish"),
    ("the tool as a number", dict(text=BASE.replace('tool = "B4"', "tool = 5").format(
        top="", part="", stock="", fixtures="", op="")), "tool must be text, got 5"),
    ("a tool not in the table", dict(text=BASE.replace('tool = "B4"', 'tool = "B3"').format(
        top="", part="", stock="", fixtures="", op="")), "no tool 'B3' in the tool table"),
    ("no tool", dict(text=BASE.replace('tool = "B4"\n', "").format(top="", part="", stock="", fixtures="", op="")),
     "tool is required"),
    ("the stepover as text", dict(text=BASE.replace("stepover = 6.0", 'stepover = "6"').format(
        top="", part="", stock="", fixtures="", op="")), "operation 1 (raster B4): stepover must be a positive number"),
    ("a negative stepover", dict(text=BASE.replace("stepover = 6.0", "stepover = -6").format(
        top="", part="", stock="", fixtures="", op="")), "stepover must be a positive number of mm, got -6"),
    ("neither stepover nor scallop", dict(text=BASE.replace("stepover = 6.0\n", "").format(
        top="", part="", stock="", fixtures="", op="")), "give exactly one of stepover and scallop"),
    ("both stepover and scallop", dict(op="scallop = 0.01"), "give exactly one of stepover and scallop"),
    ("an unknown parameter", dict(op="wobble = 1"), "unknown parameter wobble for raster"),
    ("the angle as text", dict(op='angle = "45"'), "angle must be a number of deg, got '45'"),
    ("a zero sample", dict(text=BASE.replace("sample = 2.0", "sample = 0").format(
        top="", part="", stock="", fixtures="", op="")), "sample must be a number of mm >= 0.001, got 0"),
    ("the allowance as text", dict(op='allowance = "0.3"'), "allowance must be a number of mm >= 0, got '0.3'"),
    ("the stock set in an operation", dict(op='stock = "box"'), "unknown parameter stock for raster"),
    ("a device set in an operation", dict(op='device = "cpu"'), "unknown parameter device for raster"),
    ("a list of tools for a raster", dict(op='tools = ["B4"]'), "tools is finish's, choose's and rest-finish's"),
    ("a finish's tools as text", dict(op='[[operations]]\ntype = "finish"\nstep_down = 2.0\ntools = "B4"'),
     "tools wants a list of tool names"),
    ("a finish without step_down", dict(op='[[operations]]\ntype = "finish"'), "step_down is required"),
    ("a finish's unknown order", dict(op='[[operations]]\ntype = "finish"\nstep_down = 2.0\norder = "zigzag"'),
     "order must be one of tool, contour, got 'zigzag'"),
    ("a finish tilted past 90", dict(op='[[operations]]\ntype = "finish"\nstep_down = 2.0\nmax_tilt = 95'),
     "max_tilt must be a number of deg from 0 to below 90, got 95"),
    ("a waterline's step_down as a list", dict(op='[[operations]]\ntype = "waterline"\ntool = "B4"\nstep_down = []'),
     "step_down must be a number of mm >= 0.0001, got []"),
    ("a plunge on 4 axes", dict(op='[[operations]]\ntype = "plunge"\ntool = "F10L"\nallowance = 1\naxes = 4'),
     "axes must be one of 3, 5, got 4"),
    ("a plunge without its allowance", dict(op='[[operations]]\ntype = "plunge"\ntool = "F10L"'),
     "allowance is required"),
    ("a choose's zones as text", dict(op='[[operations]]\ntype = "choose"\nscallop = 0.05\nzones = "2"'),
     "zones must be a whole number from 1 to 50 or 'auto', got '2'"),
    ("an operation's name as a number", dict(op='[[operations]]\ntype = "raster"\nname = 5\ntool = "B4"\nstepover = 6'),
     "operation 2: name must be text, got 5"),
    ("an operation's rest as text", dict(op='rest = "no"'), "rest must be a number of mm >= 0 or False, got 'no'"),
]


@pytest.mark.parametrize("what, change, says", JOB_FILES, ids=[c[0] for c in JOB_FILES])
def test_a_hostile_job_file_is_one_line_and_exit_2(tmp_path, capsys, what, change, says):
    path = job(str(tmp_path), **change)
    err = one_line(capsys, ["job", path, "--out", str(tmp_path / "out")])
    assert says in err, err
    assert not os.path.exists(tmp_path / "out" / "job.json")


def test_the_same_mistakes_in_python_raise_input_error(tmp_path):
    path = job(str(tmp_path), top='in_process = "false"')
    with pytest.raises(meshmill.InputError, match="in_process must be true or false, got 'false'") as e:
        meshmill.Job.from_toml(path).run()
    assert e.value.params == ("in_process",)


@pytest.mark.slow
def test_an_operation_with_nothing_to_cut_is_skipped_or_refused(tmp_path, capsys):
    nothing = 'allowance = 1e9\n[[operations]]\ntype = "raster"\ntool = "B4"\nstepover = 3.0\nsample = 1.0'
    path = job(str(tmp_path), op=nothing)
    assert main(["job", path, "--out", str(tmp_path / "out"), "--no-report"]) in (0, 1)
    err = capsys.readouterr().err
    assert "warning: operation 1 (raster B4) skipped: nothing to cut" in err
    done = __import__("json").load(open(tmp_path / "out" / "job.json"))
    assert done["operations"][0]["skipped"].startswith("nothing to cut") and done["operations"][1]["removed_mm3"] > 0
    assert sorted(os.listdir(tmp_path / "out")) == ["02-raster-b4", "job.json", "program.nc"]
    refuse = job(str(tmp_path), top='nothing_to_cut = "refuse"', op=nothing)
    err = one_line(capsys, ["job", refuse, "--out", str(tmp_path / "out2")])
    assert "operation 1 (raster B4): nothing to cut" in err and not os.path.exists(tmp_path / "out2" / "job.json")
    alone = job(str(tmp_path), op="allowance = 1e9")
    assert "every operation was skipped" in one_line(capsys, ["job", alone, "--out", str(tmp_path / "out3")])


def test_a_job_folder_is_checked_before_anything_is_computed(tmp_path, capsys):
    path = job(str(tmp_path))
    (tmp_path / "afile").write_text("x")
    assert "is a file, not a folder" in one_line(capsys, ["job", path, "--out", str(tmp_path / "afile")])
    assert "cannot create" in one_line(capsys, ["job", path, "--out", str(tmp_path / "afile" / "sub")])
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "thesis.tex").write_text("x")
    assert "holds other files" in one_line(capsys, ["job", path, "--out", str(tmp_path / "mine")])
    assert (tmp_path / "mine" / "thesis.tex").exists()


@pytest.mark.slow
def test_a_shorter_job_leaves_none_of_a_longer_ones_folders(tmp_path, capsys):
    two = job(str(tmp_path), op='[[operations]]\ntype = "raster"\ntool = "B4"\nstepover = 4.0\nsample = 2.0\n'
                                 'angle = 90\nrest = false')
    out = str(tmp_path / "out")
    assert main(["job", two, "--out", out, "--no-report", "--quiet"]) in (0, 1)
    assert sorted(os.listdir(out)) == ["01-raster-b4", "02-raster-b4", "job.json", "program.nc"]
    one = job(str(tmp_path))
    assert main(["job", one, "--out", out, "--no-report", "--quiet"]) in (0, 1)
    assert sorted(os.listdir(out)) == ["01-raster-b4", "job.json", "program.nc"]


# ---------------------------------------------------------------- the API


@pytest.fixture(scope="module")
def kit(tmp_path_factory):
    """A small part, the tools, a short path on it, and a folder for files."""
    folder = tmp_path_factory.mktemp("api")
    part = shapes.box((0, 0, 0), (10, 10, 5))
    tools = meshmill.load_tools(os.path.join(DATA, "tools.toml"))
    tp = meshmill.Toolpath(np.array([[-8.0, 5, 20], [-8.0, 5, 10], [18.0, 5, 10]]), np.tile([0.0, 0, 1], (3, 1)),
                           np.array([True, True, False]), np.zeros(3, np.int64))
    return part, tools, tp, folder


def _calls(part, tools, tp, folder):
    """``(name, call)``: calls a user makes by mistake."""
    m = meshmill
    job = dict(part=part, tools=tools, operations=[{"type": "raster", "tool": "B4", "stepover": 3}])
    return [
        ("raster stepover as text", lambda: m.raster(part, tools, tool="B4", stepover="3"), "stepover"),
        ("waterline step_down as text", lambda: m.waterline(part, tools, tool="B4", step_down="1"), "step_down"),
        ("finish step_down as text", lambda: m.finish(part, tools, step_down="1"), "step_down"),
        ("dexel step as text", lambda: m.dexel(part, step="1"), "step"),
        ("raster progress as a number", lambda: m.raster(part, tools, tool="B4", stepover=3, progress=5), "progress"),
        ("an unknown keyword", lambda: m.raster(part, tools, tool="B4", stepover=3, stepovr=3), "stepovr"),
        ("a keyword given twice", lambda: m.raster(part, tools, tool="B4", stepover=3, part=part), "part"),
        ("too many positional arguments", lambda: m.raster(part, tools, "B4", 3), ()),
        ("a missing required keyword", lambda: m.waterline(part, tools, tool="B4"), "step_down"),
        ("post's machine as a number", lambda: m.post(tp, 5, tools), "machine"),
        ("post's origin of two numbers", lambda: m.post(tp, "generic-3axis", tools, origin=(0, 0)), "origin"),
        ("post's clearance as text", lambda: m.post(tp, "table-table-ac", tools, clearance="75"), "clearance"),
        ("post's negative feed", lambda: m.post(tp, "generic-3axis", tools, feed=-1), "feed"),
        ("post of G-code", lambda: m.post(str(folder / "p.nc"), "generic-3axis", tools), "toolpath"),
        ("time's feed as text", lambda: m.machining_time(tp, "generic-3axis", tools, feed="fast"), "feed"),
        ("load_part up as a vector", lambda: m.load_part(os.path.join(DATA, "vase.stl"), up=[0, 0, 1]), "up"),
        ("load_part origin of two numbers", lambda: m.load_part(os.path.join(DATA, "vase.stl"), origin=[0, 0]),
         "origin"),
        ("load_part units unknown", lambda: m.load_part(os.path.join(DATA, "vase.stl"), units="ft"), "units"),
        ("load_part a number for the file", lambda: m.load_part(5), "path"),
        ("load_part a missing file", lambda: m.load_part(str(folder / "gone.stl")), ()),
        ("load_part flip as text", lambda: m.load_part(os.path.join(DATA, "vase.stl"), flip="no"), "flip"),
        ("load_tools a number", lambda: m.load_tools(5), "tools"),
        ("load_tools a missing file", lambda: m.load_tools(str(folder / "gone.toml")), ()),
        ("load_machine a number", lambda: m.load_machine(5), "machine"),
        ("load_machine an unknown name", lambda: m.load_machine("no-such-machine"), ()),
        ("finish without a part", lambda: m.finish(None, tools, step_down=1), "part"),
        ("finish tools as None", lambda: m.finish(part, None, step_down=1), "tools"),
        ("finish tools as numbers", lambda: m.finish(part, [1, 2], step_down=1), "tools"),
        ("finish a missing tool table", lambda: m.finish(part, str(folder / "gone.toml"), step_down=1), ()),
        ("finish machine as a number", lambda: m.finish(part, tools, step_down=1, machine=5), "machine"),
        ("finish stock as a number", lambda: m.finish(part, tools, step_down=1, stock=0.5), "stock"),
        ("finish stock offset of text", lambda: m.finish(part, tools, step_down=1, stock="offset:abc"), "stock"),
        ("finish stock offset negative", lambda: m.finish(part, tools, step_down=1, stock="offset:-1"), "stock"),
        ("finish an open stock mesh", lambda: m.finish(part, tools, step_down=1, stock=m.load_part(
            str(folder / "sheet.stl"))), "stock"),
        ("raster cluster of 1.5 workers", lambda: m.raster(part, tools, tool="B4", stepover=3, cluster=1.5), "cluster"),
        ("raster cluster of 0 workers", lambda: m.raster(part, tools, tool="B4", stepover=3, cluster=0), "cluster"),
        ("raster an unknown device", lambda: m.raster(part, tools, tool="B4", stepover=3, device="gpu"), "device"),
        ("raster device None", lambda: m.raster(part, tools, tool="B4", stepover=3, device=None), "device"),
        ("raster a tool not in the table", lambda: m.raster(part, tools, tool="B3", stepover=3), "tool"),
        ("raster rest without a stock", lambda: m.raster(part, tools, tool="B4", stepover=3, rest=0.1), "rest"),
        ("simulate a negative step", lambda: m.simulate(part, tp, tools, step=-1), "step"),
        ("simulate outputs unknown", lambda: m.simulate(part, tp, tools, step=1, outputs="bogus"), "outputs"),
        ("simulate outputs as a number", lambda: m.simulate(part, tp, tools, step=1, outputs=5), "outputs"),
        ("simulate an allowance keyword", lambda: m.simulate(part, tp, tools, step=1, allowance=0.5), "allowance"),
        ("verify a number for the path", lambda: m.verify(part, 5, tools), "toolpath"),
        ("verify a missing path file", lambda: m.verify(part, str(folder / "gone.cl"), tools), ()),
        ("verify worst as text", lambda: m.verify(part, tp, tools, worst="3"), "worst"),
        ("analyze direction of two numbers", lambda: m.analyze(part, direction=(0, 0)), "direction"),
        ("analyze direction as text", lambda: m.analyze(part, direction="0,0,1"), "direction"),
        ("analyze a zero direction", lambda: m.analyze(part, direction=(0, 0, 0)), "direction"),
        ("choose with neither tools nor a pair", lambda: m.choose("rubio", scallop=0.01), ("tool_pair", "tools")),
        ("choose a pair as a tuple", lambda: m.choose("rubio", scallop=0.01, tool_pair=(10, 2)), "tool_pair"),
        ("choose a number for the surface", lambda: m.choose(5, scallop=0.01, tool_pair="10,2"), "surface"),
        ("choose zones as text", lambda: m.choose("rubio", scallop=0.01, tool_pair="10,2", zones="2"), "zones"),
        ("dexel partitions as a word", lambda: m.dexel(part, step=1, partitions="many"), "partitions"),
        ("dexel zero partitions", lambda: m.dexel(part, step=1, partitions=0), "partitions"),
        ("dexel an unknown index", lambda: m.dexel(part, step=1, index="octree"), "index"),
        ("plunge axes as text", lambda: m.plunge(part, tools, tool="F10L", allowance=1, axes="3"), "axes"),
        ("report of no folders", lambda: m.report([]), "folders"),
        ("report of a number", lambda: m.report(5), "folders"),
        ("report of a missing folder", lambda: m.report([str(folder / "gone")], str(folder / "r.html")), ()),
        ("a box stock's margin as text", lambda: m.Stock.box(margin="1"), "margin"),
        ("a negative box margin", lambda: m.Stock.box(-1), "margin"),
        ("an offset as text", lambda: m.Stock.offset("0.5"), "allowance"),
        ("a stock mesh of a number", lambda: m.Stock.mesh(5), "stock"),
        ("a stock from text", lambda: m.Stock.from_dict("box"), "stock"),
        ("a job without operations", lambda: m.Job(part=part, tools=tools, operations=[]).run(), "operations"),
        ("a job's operation as a number", lambda: m.Job(part=part, tools=tools, operations=[1]).run(), ()),
        ("a job's stock as text", lambda: m.Job(**job, stock="box").run(), "stock"),
        ("a job's fixtures as text", lambda: m.Job(**job, fixtures="x").run(), "fixtures"),
        ("a job's machine as a number", lambda: m.Job(**job, machine=5).run(), "machine"),
        ("a job's step as text", lambda: m.Job(**job, step="1").run(), "step"),
        ("a job's in_process as text", lambda: m.Job(**job, in_process="false").run(), "in_process"),
        ("a job's part as a number", lambda: m.Job(part=5, tools=tools, operations=job["operations"]).run(), "part"),
        ("a job's tools as a number", lambda: m.Job(part=part, tools=5, operations=job["operations"]).run(), "tools"),
        ("clear_fixtures of a number", lambda: m.clear_fixtures(tp, tools, 5, safe_z=10), "fixtures"),
        ("clear_fixtures without safe_z", lambda: m.clear_fixtures(tp, tools, [m.Fixture("f", box=(0, 0, 0, 1, 1, 1))]),
         "safe_z"),
    ]


def test_hostile_api_calls_raise_input_error_naming_the_parameter(kit):
    part, tools, tp, folder = kit
    (folder / "p.nc").write_text("G0 X0 Y0 Z0\n")
    sheet = shapes.box((0, 0, 0), (1, 1, 1))
    trimesh.Trimesh(sheet.vertices, sheet.faces[:-2]).export(folder / "sheet.stl")
    calls = _calls(part, tools, tp, folder)
    assert len(calls) >= 70
    for name, call, params in calls:
        try:
            call()
        except meshmill.InputError as exc:
            wanted = (params,) if isinstance(params, str) else params
            assert set(wanted) <= set(exc.params), (name, str(exc), exc.params)
            assert "\n" not in str(exc), name
            continue
        except Exception as exc:  # noqa: BLE001 (the point: nothing else may come out)
            pytest.fail(f"{name}: {exc.__class__.__name__}: {exc}")
        pytest.fail(f"{name}: no error")


def test_a_job_takes_its_tool_table_as_a_file_name(tmp_path):
    """As the README says: a tool table (and a part) may be given as a file name."""
    j = meshmill.Job(part=os.path.join(DATA, "vase.stl"), tools=os.path.join(DATA, "tools.toml"),
                     operations=[{"type": "raster", "tool": "B4", "stepover": 8.0, "sample": 2.0}], step=2.0)
    j._check()
    assert j.tools[0].name and j.part.closed


# ---------------------------------------------------------------- the command line


@pytest.mark.parametrize("argv, says", [
    (["raster", "{part}", "--tools", "{tools}", "--tool", "B4", "--stepover", "abc"],
     "--stepover must be a positive number of mm, got 'abc'"),
    (["raster", "{part}", "--tools", "{tools}", "--tool", "B4", "--stepover", "1", "--scallop", "0.1"],
     "give exactly one of --stepover and --scallop"),
    (["raster", "{part}", "--tools", "{tools}", "--tool", "B4", "--stepover", "1", "--workers", "0"],
     "--workers/--scheduler must be a number of local workers (>= 1)"),
    (["finish", "{part}", "--tools", "{tools}", "--step-down", "-1"], "--step-down must be a number of mm >= 0.0001"),
    (["finish", "{part}", "--tools", "{tools}", "--step-down", "1", "--stock-allowance", "-1"],
     "--stock-allowance must be a number of mm >= 0, got -1"),
    (["finish", "{part}", "--tools", "{tools}", "--step-down", "1", "--stock", "offset:x"], "--stock must be"),
    (["simulate", "--design", "{part}", "--toolpath", "{cl}", "--tools", "{tools}", "--step", "1", "--outputs",
      "bogus"], "--outputs must be"),
    (["dexel", "{part}", "--step", "1", "--partitions", "many"], "--partitions must be a whole number"),
    (["dexel", "{part}", "--step", "1", "--up", "sideways"], "--up 'sideways': give an axis"),
    (["analyze", "{part}", "--direction", "1,2"], "--direction must be 3 numbers"),
    (["raster", "{part}", "--tools", "{tools}", "--tool", "B4", "--stepover", "1", "--device", "gpu"],
     "invalid choice: 'gpu'"),
    (["post", "{part}", "--machine", "generic-3axis", "--tools", "{tools}"], "toolpath must be an APT CL file"),
])
def test_hostile_command_lines_are_one_line(tmp_path, capsys, kit, argv, says):
    from meshmill.toolpath.cldata import write_apt

    _, tools, tp, _ = kit
    write_apt(str(tmp_path / "p.cl"), tp, tools)
    argv = [a.format(part=os.path.join(DATA, "vase.stl"), tools=os.path.join(DATA, "tools.toml"),
                     cl=str(tmp_path / "p.cl")) for a in argv]
    assert says in one_line(capsys, [*argv, "--out", str(tmp_path / "o")] if argv[0] != "post" else argv)


def test_an_option_whose_value_starts_with_a_dash(tmp_path, capsys):
    """``--up -Z`` as the README writes it (argparse alone takes -Z for an option)."""
    out = str(tmp_path / "d.npz")
    assert main(["dexel", os.path.join(DATA, "vase.stl"), "--step", "2", "--up", "-Z", "--out", out, "--quiet"]) == 0
    summary = __import__("json").load(open(tmp_path / "summary.json"))
    assert summary["part"]["setup"]["up"] == "-Z"
    assert re.search(r"origin.*-10,0,0", "origin -10,0,0")  # a negative point is a value too
    assert main(["dexel", os.path.join(DATA, "vase.stl"), "--step", "2", "--origin", "-10,0,0", "--out", out,
                 "--quiet"]) == 0
