"""The HTML report: what it shows of each kind of run, that it is self-contained, and that it loads
in a real browser (headless Chromium from the system, driven by Playwright) with its 3D traces."""
import io
import json
import os
import shutil

import numpy as np
import pytest
import trimesh

from meshmill.cli import main
from meshmill.geometry.shapes import overhang_column

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    from conftest import TOOLS_TOML

    d = tmp_path_factory.mktemp("runs")
    (d / "tools.toml").write_text(TOOLS_TOML)
    m = overhang_column()
    part = d / "part.stl"
    trimesh.Trimesh(m.vertices, m.faces, process=False).export(part)
    t = str(d / "tools.toml")
    q = ["--quiet", "--device", "cpu"]
    assert main(["finish", str(part), "--tools", t, "--step-down", "4", "--out", str(d / "finish")] + q) == 0
    assert main(["plunge", str(part), "--tools", t, "--tool", "B10", "--radial-step", "5", "--engagement", "5",
                 "--allowance", "1", "--out", str(d / "plunge")] + q) == 0
    assert main(["simulate", "--design", str(part), "--allowance", "0.5", "--toolpath", str(d / "finish" / "toolpath.cl"),
                 "--tools", t, "--step", "0.5", "--out", str(d / "sim")] + q) == 0
    assert main(["dexel", str(part), "--step", "1", "--out", str(d / "dexel" / "part.npz")] + q) == 0
    return d


@pytest.fixture(scope="module")
def report(runs):
    out = runs / "report.html"
    folders = [str(runs / k) for k in ("finish", "plunge", "sim", "dexel")]
    stdout = io.StringIO()
    import contextlib

    with contextlib.redirect_stdout(stdout):
        assert main(["report", *folders, "--out", str(out), "--json"]) == 0
    return out, json.loads(stdout.getvalue())


def test_report_shows_every_kind_of_run(report):
    out, info = report
    views = {r["kind"]: r["views"] for r in info["runs"]}
    assert set(views) == {"finish", "plunge", "simulate", "dexel"}
    assert "finish: 5-axis tool path" in views["finish"] and "finish: contours" in views["finish"]
    assert "plunge: plunge lines" in views["plunge"]
    assert "simulate: deviation" in views["simulate"] and "simulate: histogram" in views["simulate"]
    assert all(any(v.endswith("stages") for v in vs) for vs in views.values())
    assert "finish: tools" in views["finish"]
    assert info["views"] == sum(len(v) for v in views.values())


def test_report_is_self_contained(report):
    import re

    text = report[0].read_text()
    assert not re.search(r"<(script|link|img)[^>]+(src|href)=", text)  # plotly.js is inside, nothing is fetched
    assert text.count("Plotly.newPlot") == report[1]["views"]


def test_report_thins_big_paths_and_says_so(runs, tmp_path, monkeypatch):
    from meshmill import htmlreport as rep

    monkeypatch.setattr(rep, "MAX_PATH_POINTS", 50)
    info = rep.write_report([str(runs / "finish")], str(tmp_path / "r.html"))
    assert any("tool path: every" in n for n in info["runs"][0]["notes"])


def test_thinned_path_keeps_rapid_moves_apart(runs, monkeypatch):
    from meshmill import htmlreport as rep

    run = rep.read_run(str(runs / "plunge"))
    monkeypatch.setattr(rep, "MAX_PATH_POINTS", len(run.toolpath) // 5)
    import plotly.graph_objects as go

    traces = rep._path_traces(go, run, [])
    assert any(t.name == "rapid moves" for t in traces)
    for t in traces:  # plunges go down cutting and back up rapid: no thinned cutting stroke may climb
        if t.name.endswith("cutting"):
            steps = np.diff(np.asarray(t.z, float))
            assert (steps[~np.isnan(steps)] <= 1e-9).all()


def test_report_bad_input_is_one_line(runs, tmp_path, capsys):
    for argv, words in ((["report", str(tmp_path / "nope")], "no such folder"),
                        (["report", str(tmp_path)], "no summary.json"),
                        (["report", str(runs / "finish"), "--out", str(tmp_path / "no" / "r.html")], "no such folder")):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err


def test_deviation_colours_bound_the_tolerance_classes():
    from meshmill.htmlreport import deviation_colours

    scale, lim = deviation_colours(0.01)
    assert lim == pytest.approx(0.03)
    stops = [s for s, _ in scale]
    assert stops == sorted(stops) and stops[0] == 0.0 and stops[-1] == 1.0
    # ±tol sits at 1/3 and 2/3 of [-3 tol, 3 tol]: the within-tolerance band is one pale colour, and
    # the colour jumps at ±tol (a gouge never looks like a point within tolerance)
    colour = dict((round(s, 9), c) for s, c in scale)
    assert colour[round(1 / 3, 9)] == colour[round(2 / 3, 9)] == "#f7f7f7"
    assert colour[round(1 / 3 - 1e-6, 9)] != "#f7f7f7" and colour[round(2 / 3 + 1e-6, 9)] != "#f7f7f7"


@pytest.mark.skipif(not os.path.exists(CHROMIUM), reason="no system Chromium (apt-get install chromium)")
@pytest.mark.slow
def test_report_loads_in_a_real_browser(report, tmp_path):
    pw = pytest.importorskip("playwright.sync_api")
    out, info = report
    errors, fetched = [], []
    with pw.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=["--no-sandbox", "--use-gl=swiftshader",
                                                                    "--enable-unsafe-swiftshader"])
        page = browser.new_page(viewport={"width": 1200, "height": 900})
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("request", lambda r: fetched.append(r.url) if not r.url.startswith(("file:", "data:", "blob:")) else None)
        page.goto(out.as_uri())
        page.wait_for_function("document.querySelectorAll('.js-plotly-plot').length > 0", timeout=60000)
        counts = page.evaluate("Array.from(document.querySelectorAll('.js-plotly-plot')).map(d => d.data.length)")
        kinds = page.evaluate("Array.from(document.querySelectorAll('.js-plotly-plot')).map(d => d.data.map(t => t.type))")
        page.locator("#view1").scroll_into_view_if_needed()
        page.wait_for_timeout(1500)
        png = page.locator("#view1").screenshot()
        browser.close()
    assert errors == [], errors
    assert fetched == [], fetched  # no server, no internet
    assert len(counts) == info["views"] and min(counts) >= 1
    assert any("mesh3d" in k and "scatter3d" in k for k in kinds)  # a part with a path over it
    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("L"), float)
    assert img.std() > 5.0  # not blank: the part and the path are drawn
