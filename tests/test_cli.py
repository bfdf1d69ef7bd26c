"""The command line: outputs, exit codes and one-line errors."""
import json
import subprocess
import sys

import numpy as np
import trimesh

from meshmill.cli import main
from conftest import one_line_error


def test_finish_then_verify(tmp_path, part, tools_file, capsys):
    out = tmp_path / "out"
    rc = main(["finish", str(part), "--tools", str(tools_file), "--step-down", "2", "--out", str(out), "--quiet"])
    assert rc == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("contours", "machinable_contours", "cc_points", "points_left_out", "tools_used", "seconds"):
        assert key in summary
    assert summary["verify"]["ok"] and summary["seconds"]["total"] > 0
    cl = (out / "toolpath.cl").read_text().splitlines()
    assert cl[-1] == "FINI" and any(l.startswith("LOADTL/") for l in cl) and "RAPID" in cl
    rc = main(["verify", str(part), str(out / "toolpath.cl"), "--tools", str(tools_file)])
    assert rc == 0 and "OK" in capsys.readouterr().out


def test_verify_finds_a_gouge(tmp_path, part, tools_file, capsys):
    (tmp_path / "g.cl").write_text("LOADTL/2\nGOTO/0, 0, 34.5, 0, 0, 1\nGOTO/1, 0, 34.5, 0, 0, 1\nFINI\n")
    rc = main(["verify", str(part), str(tmp_path / "g.cl"), "--tools", str(tools_file)])
    out = capsys.readouterr().out
    assert rc == 1 and "PROBLEMS" in out and "gouge" in out and "line 2" in out


def test_verify_of_a_program_counts_its_lines(tmp_path, part, tools_file, capsys):
    """An arc is read as many moves; the problems are also counted on the program's lines."""
    (tmp_path / "g.nc").write_text("T2\nG0 X0 Y0 Z40\nG1 Z34.5 F100\nG2 X0 Y0 I1 J0\nG0 Z40\n")
    rc = main(["verify", str(part), str(tmp_path / "g.nc"), "--tools", str(tools_file), "--out", str(tmp_path / "v.json")])
    out = capsys.readouterr().out
    report = json.loads((tmp_path / "v.json").read_text())
    assert rc == 1 and report["lines"] == 4 and report["moves"] > 10
    assert report["gouging_moves"] > 2 and report["problem_lines"]["gouge"] == 2
    assert f"{report['moves']} moves from 4 program lines" in out and f"{report['gouging_moves']} (on 2 lines) gouging" in out


def test_bad_inputs_give_one_line_and_exit_2(tmp_path, part, tools_file, capsys):
    t = str(tools_file)
    assert "no such file" in one_line_error(capsys, ["finish", str(tmp_path / "missing.stl"), "--tools", t, "--step-down", "1"])
    (tmp_path / "empty.stl").write_bytes(b"")
    assert "empty" in one_line_error(capsys, ["finish", str(tmp_path / "empty.stl"), "--tools", t, "--step-down", "1"])
    (tmp_path / "junk.stl").write_text("this is no mesh at all")
    one_line_error(capsys, ["finish", str(tmp_path / "junk.stl"), "--tools", t, "--step-down", "1"])
    m = trimesh.Trimesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, np.nan]]), [[0, 1, 2]], process=False)
    m.export(tmp_path / "nan.stl")
    assert "NaN" in one_line_error(capsys, ["finish", str(tmp_path / "nan.stl"), "--tools", t, "--step-down", "1"])
    assert "tool table" in one_line_error(capsys, ["finish", str(part), "--tools", str(tmp_path / "no.toml"), "--step-down", "1"])
    assert "larger than the part" in one_line_error(capsys, ["finish", str(part), "--tools", t, "--step-down", "500"])
    assert "step" in one_line_error(capsys, ["finish", str(part), "--tools", t, "--step-down", "-1"])
    assert "no such CL file" in one_line_error(capsys, ["verify", str(part), str(tmp_path / "x.cl"), "--tools", t])
    one_line_error(capsys, ["finish", str(part), "--tools", t])  # missing --step-down


def test_entry_point_exit_code(tmp_path):
    r = subprocess.run([sys.executable, "-m", "meshmill", "finish", str(tmp_path / "nope.stl"), "--tools", "x.toml",
                        "--step-down", "1"], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr


def test_more_bad_inputs(tmp_path, part, tools_file, capsys):
    t = str(tools_file)
    for opt in (["--safe-z", "nan"], ["--clearance", "nan"], ["--tolerance", "inf"], ["--sample", "1e-9"]):
        one_line_error(capsys, ["finish", str(part), "--tools", t, "--step-down", "2", *opt])
    (tmp_path / "c.cl").write_text("LOADTL/1\nGOTO/1e308, 0, 100\n")
    assert "out of range" in one_line_error(capsys, ["verify", str(part), str(tmp_path / "c.cl"), "--tools", t])
    (tmp_path / "ok.cl").write_text("LOADTL/1\nGOTO/0, 0, 100\n")
    one_line_error(capsys, ["verify", str(part), str(tmp_path / "ok.cl"), "--tools", t, "--tolerance", "nan"])
    one_line_error(capsys, ["verify", str(part), str(tmp_path / "ok.cl"), "--tools", t, "--step", "nan"])
    one_line_error(capsys, ["verify", str(part), str(tmp_path / "ok.cl"), "--tools", t, "--out", str(tmp_path)])
    one_line_error(capsys, ["verify", str(part), str(tmp_path), "--tools", t])
    one_line_error(capsys, ["finish", str(part), "--tools", str(tmp_path), "--step-down", "2"])
    (tmp_path / "list.toml").write_text("tools = [1, 2]\n")
    one_line_error(capsys, ["finish", str(part), "--tools", str(tmp_path / "list.toml"), "--step-down", "2"])


def test_latin1_ascii_stl(tmp_path):
    from meshmill.geometry.mesh import load_mesh

    body = "solid caf\xe9\n" + "".join(
        f"facet normal 0 0 1\nouter loop\nvertex {a}\nvertex {b}\nvertex {c}\nendloop\nendfacet\n"
        for a, b, c in [("0 0 0", "1 0 0", "0 1 0"), ("1 0 0", "1 1 0", "0 1 0")]) + "endsolid caf\xe9\n"
    (tmp_path / "l.stl").write_bytes(body.encode("latin-1"))
    assert len(load_mesh(tmp_path / "l.stl").faces) == 2


def test_a_failed_run_leaves_no_result_behind(tmp_path, part, tools_file, capsys, monkeypatch):
    out = tmp_path / "out"
    args = ["raster", str(part), "--tools", str(tools_file), "--tool", "B6", "--stepover", "3", "--out", str(out),
            "--quiet"]
    assert main(args) == 0 and (out / "summary.json").exists() and (out / "toolpath.cl").exists()
    # a bad value, then a usage error: the earlier run's files must not pass for this run's
    assert main(args[:-3] + ["--sample", "-1", "--out", str(out)]) == 2
    assert not (out / "summary.json").exists() and not (out / "toolpath.cl").exists()
    assert main(args) == 0
    assert main(args[:-3] + ["--sample", "abc", "--out", str(out)]) == 2
    assert not (out / "summary.json").exists() and not (out / "toolpath.cl").exists()
    # interrupted while writing: nothing final, nothing partial
    assert main(args) == 0
    import meshmill.toolpath.cldata as cldata

    def half_written(path, *a, **k):
        with open(path, "w") as fh:
            fh.write("PARTNO/x\nGOTO/1")
        raise KeyboardInterrupt

    monkeypatch.setattr(cldata, "write_apt", half_written)
    assert main(args) == 130
    assert sorted(p.name for p in out.iterdir()) == []
    capsys.readouterr()


def test_verify_with_an_allowance_and_a_stock(tmp_path, part, tools_file, capsys):
    # a rapid 0.3 mm over the column's top: clear of the part, not of a 0.5 mm allowance
    top = trimesh.load(part).bounds[1, 2]
    (tmp_path / "p.cl").write_text(f"LOADTL/3\nRAPID\nGOTO/-30, 0, {top + 0.3}\nRAPID\nGOTO/30, 0, {top + 0.3}\nFINI\n")
    base = ["verify", str(part), str(tmp_path / "p.cl"), "--tools", str(tools_file)]
    assert main(base) == 0
    assert main(base + ["--allowance", "0.5"]) == 1
    assert "rapid into the stock" in capsys.readouterr().out
    blank = trimesh.creation.box(bounds=[[-40, -40, -5], [40, 40, top + 10]])
    blank.export(tmp_path / "blank.stl")
    assert main(base + ["--stock", str(tmp_path / "blank.stl")]) == 1
    assert one_line_error(capsys, base + ["--allowance", "-1"]).endswith("--allowance must be a number of mm >= 0, got -1")
