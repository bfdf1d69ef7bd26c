"""Certified verification against generation (issue 39): for each operation, the seconds its
path takes to make and the seconds its certificate takes, in one run on this machine.

    .venv/bin/python bench/certify.py                       # about 3 minutes
    .venv/bin/python bench/certify.py --only finish         # finish, raster, waterline, verify
    .venv/bin/python bench/certify.py --only finish --finishes impeller --repeat 5

Rows (each operation run once to load numba's cache, then ``--repeat`` times (1), timed: the row is
the run of the median verify / generation, with the ratios' range where there are several):
- ``finish``: the 5-axis finish (``scallop 0.01``, the balls and set-ups of bench/realparts.py) of
  the blade, the dolphin mould and the vase: the summary's stage seconds, generation = every
  stage but ``verify`` (index, contours, tools, axes, shallow fill, path; and what the summary's
  total holds besides: the part's loading, as the command does it, and the summary's figures). And issue 39's
  impeller (bench/standin_parts.py's stand-in, written to bench/out/parts on first use) as the
  issue ran it: ``--up +Y --scallop 0.01 --machine table-table-ac``, step-down 0.5 mm.
- ``raster``: mount_rush, B4, stepover and sample 0.1 mm (bench/whole_ops.py's row): ``drop``
  against ``verify``.
- ``waterline``: sphere_on_plate, B6, step-down 1 mm, sample 0.1 mm (whole_ops's row).
- ``verify``: ``api.verify`` of the CL files those wrote, read back as any CL file is, against
  the generation of the path.

Prints a markdown table and writes bench/out/certify.json (with the machine).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
PARTS = os.path.join(os.path.dirname(ROOT), "shared", "parts")

from finished import table  # noqa: E402
from links import _setup  # noqa: E402
from realparts import PARTS as REAL_PARTS, TOOLS  # noqa: E402
from standin_parts import written  # noqa: E402

# the finishes timed: (part file, set-up options, step-down mm, machine)
FINISHES = {name: (*REAL_PARTS[name], None) for name in ("blade", "dolphin", "vase")}
FINISHES["impeller"] = (None, ["--up", "+Y"], 0.5, "table-table-ac")
from whole_ops import B6_TABLE  # noqa: E402


def _runs(run, repeat):
    """``run()`` once (numba's cache loaded), then ``repeat`` times: those results."""
    run()
    return [run() for _ in range(repeat)]


def _median_row(label, results) -> tuple[dict, object, float]:
    """``(row, result, generation s)``: the run of ``results`` (operations' results, whose summary
    has its stages' ``seconds``) with the median verify / generation; generation = the total
    less ``verify``; with several runs, the ratios' range too."""
    secs = [r.summary["seconds"] for r in results]
    ratios = [s["verify"] / (s["total"] - s["verify"]) for s in secs]
    k = sorted(range(len(ratios)), key=ratios.__getitem__)[len(ratios) // 2]
    sec, gen = secs[k], secs[k]["total"] - secs[k]["verify"]
    row = {"operation": label, "moves": len(results[k].toolpath), "generation_s": round(gen, 2),
           "verify_s": round(sec["verify"], 2), "verify/generation": round(ratios[k], 2)}
    if len(ratios) > 1:
        row["ratio range"] = f"{min(ratios):.2f}-{max(ratios):.2f}"
    row["stages_s"] = {n: round(v, 2) for n, v in sec.items() if n not in ("total", "load")}
    return row, results[k], gen


def finish_rows(work, verify_too, repeat, finishes=tuple(FINISHES)):
    from meshmill import api
    from meshmill.toolpath.cldata import write_apt

    tools_file = os.path.join(work, "balls.toml")
    with open(tools_file, "w") as fh:
        fh.write(TOOLS)
    tools = api.load_tools(tools_file)
    rows = []
    for name in finishes:
        path, options, step_down, machine = FINISHES[name]
        part = api.load_part(path or written(name), **_setup(options))
        row, res, gen = _median_row(f"finish {name}", _runs(
            lambda: api.finish(part, tools, step_down=step_down, scallop=0.01, machine=machine), repeat))
        rows.append(row)
        if verify_too:
            cl = os.path.join(work, f"{name}.cl")
            write_apt(cl, res.toolpath, tools)
            rows.append(verify_row(f"verify {name} finish CL", part, cl, tools, gen, repeat))
    return rows


def verify_row(label, part, cl, tools, generation_s, repeat):
    from meshmill import api

    def run():
        t0 = time.perf_counter()
        r = api.verify(part, cl, tools)
        return r, time.perf_counter() - t0

    runs = _runs(run, repeat)
    r, s = runs[0][0], sorted(t for _, t in runs)[len(runs) // 2]
    return {"operation": label, "moves": r.report["moves"], "generation_s": round(generation_s, 2),
            "verify_s": round(s, 2), "verify/generation": round(s / generation_s, 2), "ok": r.report["ok"]}


def raster_rows(work, verify_too, repeat):
    from meshmill import api

    part = api.load_part(os.path.join(PARTS, "mount_rush.stl"))
    tools = api.load_tools(os.path.join(ROOT, "src", "meshmill", "data", "tools.toml"))
    row, res, gen = _median_row("raster mount_rush B4 0.1/0.1", _runs(
        lambda: api.raster(part, tools, tool="B4", stepover=0.1, sample=0.1), repeat))
    rows = [row]
    if verify_too:
        from meshmill.toolpath.cldata import write_apt

        cl = os.path.join(work, "raster.cl")
        write_apt(cl, res.toolpath, tools)
        rows.append(verify_row("verify mount_rush raster CL", part, cl, tools, gen, repeat))
    return rows


def waterline_rows(work, verify_too, repeat):
    from meshmill import api

    table_file = os.path.join(work, "b6.toml")
    with open(table_file, "w") as fh:
        fh.write(B6_TABLE)
    part = api.load_part(os.path.join(PARTS, "sphere_on_plate.stl"))
    tools = api.load_tools(table_file)
    return [_median_row("waterline sphere_on_plate B6 1/0.1", _runs(
        lambda: api.waterline(part, tools, tool="B6", step_down=1.0, sample=0.1), repeat))[0]]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="finish,raster,waterline,verify")
    ap.add_argument("--finishes", default=",".join(FINISHES), help="the parts finished (%(default)s)")
    ap.add_argument("--repeat", type=int, default=1, help="timed runs of each operation (%(default)s)")
    ap.add_argument("--out", default=os.path.join(HERE, "out", "certify.json"))
    a = ap.parse_args()
    only = a.only.split(",")
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for name, rows_of in (("finish", finish_rows), ("raster", raster_rows), ("waterline", waterline_rows)):
            if name in only:
                extra = {"finishes": a.finishes.split(",")} if name == "finish" else {}
                got = rows_of(work, "verify" in only, max(1, a.repeat), **extra)
                rows += got
                print(table([{k: v for k, v in r.items() if k != "stages_s"} for r in got]), flush=True)
    print()
    print(table([{k: v for k, v in r.items() if k != "stages_s"} for r in rows]))
    import numba

    machine = {"platform": platform.platform(), "cpus": os.cpu_count(), "numba_threads": numba.get_num_threads(),
               "python": platform.python_version()}
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as fh:
        json.dump({"machine": machine, "date": time.strftime("%Y-%m-%d %H:%M"), "rows": rows}, fh, indent=2)


if __name__ == "__main__":
    main()
