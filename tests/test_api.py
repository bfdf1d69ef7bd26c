"""The Python API (meshmill.api, reachable as meshmill.*): each operation through the API writes the
files the command line writes (timing aside), errors name the parameters, and the README's example
runs."""
import os
import re
import shutil
import subprocess
import sys

import pytest

import meshmill
from meshmill.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "bench"))
from compare_runs import same  # noqa: E402


def _tree(folder):
    return sorted(os.path.relpath(os.path.join(d, f), folder) for d, _, fs in os.walk(folder) for f in fs)


def _both(tmp_path, cli_argv, api_run, name="out"):
    """Run the command into ``name``, move it aside, run the API into the same ``name`` (summaries
    hold their own paths), and assert the two wrote the same files."""
    out = tmp_path / name
    assert main([*cli_argv, "--out", str(out)]) in (0, 1)
    cli = tmp_path / f"{name}-cli"
    shutil.move(out, cli)
    os.makedirs(out.parent, exist_ok=True)
    api_run(str(out))
    if os.path.isdir(cli):
        assert _tree(cli) == _tree(out)
        for rel in _tree(cli):
            assert same(os.path.join(cli, rel), os.path.join(out, rel)) == "", rel
    else:
        assert same(str(cli), str(out)) == ""


@pytest.mark.slow
def test_path_operations_write_what_the_commands_write(tmp_path, part, tools_file):
    t = str(tools_file)
    mesh, tools = meshmill.load_part(part), meshmill.load_tools(t)
    _both(tmp_path, ["finish", str(part), "--tools", t, "--step-down", "3", "--scallop", "0.05", "--quiet"],
          lambda out: meshmill.finish(mesh, tools, step_down=3, scallop=0.05).save(out), "finish")
    _both(tmp_path, ["raster", str(part), "--tools", t, "--tool", "B6", "--stepover", "3", "--angle", "30", "--quiet"],
          lambda out: meshmill.raster(mesh, tools, tool="B6", stepover=3, angle=30).save(out), "raster")
    _both(tmp_path, ["waterline", str(part), "--tools", t, "--tool", "B6", "--step-down", "5", "--quiet"],
          lambda out: meshmill.waterline(mesh, tools, tool="B6", step_down=5).save(out), "waterline")
    _both(tmp_path, ["plunge", str(part), "--tools", t, "--tool", "B10", "--allowance", "1", "--simulate", "2",
                     "--quiet"],
          lambda out: meshmill.plunge(mesh, tools, tool="B10", allowance=1, simulate=2).save(out), "plunge")


def test_checks_and_programs_write_what_the_commands_write(tmp_path, part, tools_file):
    t = str(tools_file)
    mesh, tools = meshmill.load_part(part), meshmill.load_tools(t)
    res = meshmill.finish(mesh, tools, step_down=4)
    assert res.ok and len(res.toolpath) == res.summary["moves"]
    res.save(tmp_path / "f")
    cl = str(tmp_path / "f" / "toolpath.cl")
    tp = meshmill.load_toolpath(cl, tools)
    assert tp.source == os.path.abspath(cl) and len(tp) == len(res.toolpath)
    _both(tmp_path, ["verify", str(part), cl, "--tools", t], lambda out: meshmill.verify(mesh, tp, tools).save(out),
          "verify.json")
    _both(tmp_path, ["simulate", "--design", str(part), "--toolpath", cl, "--tools", t, "--step", "2", "--allowance",
                     "0.5", "--quiet"],
          lambda out: meshmill.simulate(mesh, tp, tools, step=2, stock=meshmill.Stock.offset(0.5)).save(out), "sim")
    _both(tmp_path, ["post", cl, "--machine", "table-table-ac", "--tools", t, "--clearance", "60"],
          lambda out: meshmill.post(tp, "table-table-ac", tools, clearance=60).save(out), "program.nc")
    _both(tmp_path, ["time", cl, "--machine", "table-table-ac", "--tools", t],
          lambda out: meshmill.machining_time(tp, "table-table-ac", tools).save(out), "time.json")
    _both(tmp_path, ["dexel", str(part), "--step", "2", "--quiet"],
          lambda out: meshmill.dexel(mesh, step=2).save(out), "part.dexel.npz")
    _both(tmp_path, ["analyze", str(part), "--direction", "0,1,1", "--theta-step", "30", "--quiet"],
          lambda out: meshmill.analyze(mesh, direction=(0, 1, 1), theta_step=30).save(out), "analysis")
    _both(tmp_path, ["report", str(tmp_path / "f"), str(tmp_path / "sim"), "--quiet"],
          lambda out: meshmill.report([tmp_path / "f", tmp_path / "sim"], out), "report.html")


@pytest.mark.slow
def test_choose_writes_what_the_command_writes(tmp_path):
    options = dict(tool_pair="10,2", scallop=0.05, zones=2, grid=16, sample=2.0, mesh_step=2.0)
    argv = ["choose", "rubio", "--quiet"]
    for k, v in options.items():
        argv += [f"--{k.replace('_', '-')}", str(v)]
    _both(tmp_path, argv, lambda out: meshmill.choose("rubio", **options).save(out), "choose")


def test_errors_name_the_parameter_and_the_command_its_flag(part, tools_file, capsys):
    mesh, tools = meshmill.load_part(part), meshmill.load_tools(tools_file)
    with pytest.raises(meshmill.InputError) as e:
        meshmill.finish(mesh, tools, step_down=-1)
    assert str(e.value).startswith("step_down ") and e.value.params == ("step_down",)
    with pytest.raises(meshmill.InputError, match="^max_tilt must"):
        meshmill.finish(mesh, tools, step_down=1, max_tilt=95)
    with pytest.raises(meshmill.InputError, match="^units"):
        meshmill.load_part(part, units="furlong")
    assert main(["finish", str(part), "--tools", str(tools_file), "--step-down", "-1"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("meshmill: error: --step-down ") and err.count("\n") == 1


def test_results_are_typed_objects_and_import_is_lazy():
    code = ("import sys, meshmill; heavy = [m for m in ('numpy', 'numba', 'trimesh', 'scipy') if m in sys.modules];"
            "print(heavy, meshmill.__version__, callable(meshmill.finish))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.startswith("[] ") and "True" in out
    assert set(meshmill.API) <= set(dir(meshmill))


def test_the_readme_example_runs(tmp_path, monkeypatch):
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    example = [b for b in blocks if "meshmill.finish(" in b]
    assert example, "the README has a Python example of the API"
    monkeypatch.chdir(tmp_path)
    exec(compile(example[0], "README.md", "exec"), {})
    assert (tmp_path / "out" / "toolpath.cl").exists()
