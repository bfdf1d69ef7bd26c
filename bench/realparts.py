"""Real parts as a user machines them (issue 18): each part of ``../shared/parts/real/`` (and the
bundled vase) set up by meshmill's own options (units, model scale, which axis is up, work zero),
finished with ``--scallop``, simulated from a 0.5 mm allowance, and posted for two 5-axis machines.

Per part it prints and writes (JSON) the share of CC points cut and why the rest are not (no ball
fits, no free axis), the contours not cut at all, the share of the surface flatter than Z-levels
serve (left to raster), the share of the design surface within the scallop limit plus the
tolerance after the finish (``within``, simulate) against what the tools reached (``cut``), the
verification, wall times, and whether ``post`` wrote a program for ``table-table-ac`` and
``head-table-bc`` (or its one-line refusal).

    .venv/bin/python bench/realparts.py [--parts vase,dolphin] [--scallop 0.01] [--sim-step 0.3]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
REAL = os.path.join(os.path.dirname(ROOT), "shared", "parts", "real")

TOOLS = """# bench/realparts.py: finishing balls with holders (mm)
[[tools]]
name = "B10"
type = "ball"
diameter = 10.0
flute_length = 20.0
gauge_length = 50.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B6"
type = "ball"
diameter = 6.0
flute_length = 15.0
gauge_length = 45.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B2"
type = "ball"
diameter = 2.0
flute_length = 6.0
gauge_length = 35.0
shank_diameter = 6.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B1"
type = "ball"
diameter = 1.0
flute_length = 3.0
gauge_length = 30.0
shank_diameter = 4.0
holder_diameter = 25.0
holder_length = 40.0
"""

# name: (file, set-up options, step-down mm)
PARTS = {
    "vase": (os.path.join(ROOT, "src", "meshmill", "data", "vase.stl"), [], 2.0),
    "dolphin": (os.path.join(REAL, "mould_dolphin_tail_cavity.stl"), ["--up", "+X", "--origin", "corner"], 2.0),
    "terrain": (os.path.join(REAL, "relief_terrain.stl"), ["--units", "m", "--scale", "0.0002", "--origin", "corner"],
                1.0),
    "blade": (os.path.join(REAL, "blade_hpt_airfoil.stl"), ["--units", "m", "--origin", "bottom-centre"], 1.0),
    "hull": (os.path.join(REAL, "ship_hull_dtc.stl"), ["--units", "m", "--scale", "0.04", "--origin", "bottom-centre"],
             1.0),
    "car": (os.path.join(REAL, "car_body_drivaer.stl"), ["--units", "m", "--scale", "0.05", "--origin", "bottom-centre"],
            2.0),
}
MACHINES = ("table-table-ac", "head-table-bc")


def meshmill(*argv, timeout=3600):
    """``(exit code, last line of stderr, seconds)`` of a meshmill command."""
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "meshmill", *argv], capture_output=True, text=True, timeout=timeout,
                       env=dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src")))
    lines = [x for x in r.stderr.strip().splitlines() if not x.startswith(("warning", "["))]
    return r.returncode, (lines or [""])[-1], round(time.perf_counter() - t, 1)


def run_part(name, work, tools, scallop, sim_step):
    path, setup, step_down = PARTS[name]
    out = os.path.join(work, name)
    row = {"part": name, "setup": " ".join(setup), "step_down": step_down}
    rc, last, s = meshmill("finish", path, "--tools", tools, "--step-down", str(step_down), "--sample", "1.0",
                           "--tilt-step", "10", "--scallop", str(scallop), "--out", out, "--quiet", *setup)
    row.update(finish_rc=rc, finish_s=s)
    if rc not in (0, 1):
        row["error"] = last[:200]
        return row
    f = json.load(open(os.path.join(out, "summary.json")))
    n = f["cc_points"]
    row.update(cc_points=n, cut=round(f["points_cut"] / n, 4), no_ball=round(f["points_without_tool"] / n, 4),
               no_axis=round((n - f["points_without_tool"] - f["points_cut"]) / n, 4),
               contours_not_cut=len(f["unmachinable_contours"]), contours=f["contours"],
               levels=f["levels"], shallow=round(f["scallop"]["shallow_share"], 4) if f["scallop"] else None,
               verify_ok=f["verify"]["ok"], gouging=f["verify"]["gouging_moves"],
               colliding=f["verify"]["colliding_moves"])
    part_stl = os.path.join(out, "part.stl")  # the part as set up: the path's frame
    if sim_step:
        rc, last, s = meshmill("simulate", "--design", part_stl, "--allowance", "0.5", "--toolpath",
                               os.path.join(out, "toolpath.cl"), "--tools", tools, "--step", str(sim_step),
                               "--out", os.path.join(out, "sim"), "--quiet")
        row.update(sim_rc=rc, sim_s=s)
        if rc in (0, 1):
            d = json.load(open(os.path.join(out, "sim", "deviation.json")))
            row.update(within=round(d["within_tolerance"], 4), gouge_max=round(d["gouge_max"], 4))
        else:
            row["sim_error"] = last[:200]
    for m in MACHINES:
        rc, last, s = meshmill("post", os.path.join(out, "toolpath.cl"), "--machine", m, "--tools", tools,
                               "--clearance", "75", "--out", os.path.join(out, f"{m}.nc"))
        row[f"post_{m}"] = "ok" if rc == 0 else last[:200]
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--scallop", type=float, default=0.01)
    ap.add_argument("--sim-step", type=float, default=0.3, help="dexel step of the simulations, mm (0: none)")
    ap.add_argument("--work", default=os.path.join(HERE, "out", "realparts"))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    tools = os.path.join(a.work, "tools.toml")
    with open(tools, "w") as fh:
        fh.write(TOOLS)
    rows = []
    for name in a.parts.split(","):
        rows.append(run_part(name, a.work, tools, a.scallop, a.sim_step))
        print(json.dumps(rows[-1]), flush=True)
        with open(os.path.join(a.work, "realparts.json"), "w") as fh:
            json.dump({"date": datetime.date.today().isoformat(), "scallop": a.scallop, "sim_step": a.sim_step,
                       "rows": rows}, fh, indent=1)
    keys = ["cut", "no_ball", "no_axis", "contours_not_cut", "shallow", "within", "gouge_max", "verify_ok", "finish_s",
            "sim_s"]
    print("\n| part | " + " | ".join(keys) + " | " + " | ".join(MACHINES) + " |")
    print("|---" * (len(keys) + len(MACHINES) + 1) + "|")
    for r in rows:
        print(f"| {r['part']} | " + " | ".join(str(r.get(k, "-")) for k in keys) + " | "
              + " | ".join(str(r.get(f"post_{m}", r.get("error", "-")))[:60] for m in MACHINES) + " |")


if __name__ == "__main__":
    main()
