"""The optional extras: without plotly (meshmill[report]) or PyNomadBBO (meshmill[optimise]) the
commands that need them fail with one line naming the extra; nothing else imports them."""
import subprocess
import sys

import pytest

from meshmill.errors import InputError

REPORT = "the HTML report needs plotly: pip install 'meshmill[report]'"
OPTIMISE = "optimise needs PyNomadBBO: pip install 'meshmill[optimise]'"


@pytest.fixture
def no_plotly(monkeypatch):
    for name in ("plotly", "plotly.graph_objects", "plotly.offline"):
        monkeypatch.setitem(sys.modules, name, None)


@pytest.fixture
def no_nomad(monkeypatch):
    monkeypatch.setitem(sys.modules, "PyNomad", None)


def test_report_without_plotly(no_plotly, tmp_path):
    from meshmill.htmlreport import write_report

    with pytest.raises(InputError) as exc:
        write_report([str(tmp_path)], str(tmp_path / "report.html"))
    assert str(exc.value) == REPORT


def test_report_command_without_plotly(no_plotly, tmp_path, capsys):
    from meshmill.cli import main

    assert main(["report", str(tmp_path), "--out", str(tmp_path / "report.html")]) == 2
    assert capsys.readouterr().err.strip() == f"meshmill: error: {REPORT}"
    assert not (tmp_path / "report.html").exists()


def test_optimise_without_nomad(no_nomad):
    from meshmill.choice.optimise import _mads

    with pytest.raises(InputError) as exc:
        _mads(lambda x: x[0] ** 2, [1.0], [-2.0], [2.0], ["R"], 4, False, 0, [])
    assert str(exc.value) == OPTIMISE


def test_choose_command_without_nomad(no_nomad, tmp_path, capsys):
    from meshmill.cli import main

    argv = ["choose", "rubio", "--tool-pair", "10,2", "--scallop", "0.01", "--zones", "1", "--grid", "10",
            "--mesh-step", "2", "--sample", "2", "--optimise", "2", "--quiet", "--out", str(tmp_path / "c")]
    assert main(argv) == 2
    assert capsys.readouterr().err.strip() == f"meshmill: error: --{OPTIMISE}"


def test_extras_are_imported_only_when_needed():
    code = ("import sys, meshmill.cli, meshmill.htmlreport, meshmill.choice.optimise; "
            "print(sorted(m for m in ('plotly', 'PyNomad') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_kernel_runs_without_importing_scipy_linalg_and_blas_still_works():
    """numba's BLAS probe (scipy.linalg, 0.15 s of every command) is skipped: a cached kernel loads
    without it, and afterwards scipy.linalg imports and np.dot compiles against its BLAS."""
    code = ("import sys, numpy as np, numba\n"
            "from meshmill.simulation.dexel import dexelize\nfrom meshmill.geometry.shapes import box\n"
            "dexelize(box((0, 0, 0), (1, 1, 1)), 0.25)\nprint('scipy.linalg' in sys.modules)\n"
            "import scipy.linalg\nprint(scipy.linalg.solve(np.eye(2), np.ones(2)).tolist())\n"
            "print(numba.njit(lambda a, b: np.dot(a, b))(np.arange(3.0), np.arange(3.0)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "[1.0,", "1.0]", "5.0"]
