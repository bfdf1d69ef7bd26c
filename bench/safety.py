"""Safety of the written paths on the bundled and the real parts (issue 17), measured the same way
for any version of meshmill.

Every part is set up as a user would in another program (metres to mm, turned so that it is
machined from +Z, moved to the origin: ``setup``), then ``finish``, ``waterline``, ``raster`` and
``plunge`` are run by the command line of the version under test (``--src``: its ``src`` folder,
default this checkout's). Each written path is then measured by this checkout's checks:

- ``rapid_in_stock``: rapid moves that come within the clearance (0.5 mm) of the stock the
  operation starts from (the part with 0.5 mm on it; plunge: the part's box), certified verify;
- ``gouging`` / ``colliding``: feed moves whose cutting part enters the solid the part bounds (an
  open surface: the solid below it) deeper than 0.01 mm, or whose shank or holder does, certified
  verify (not blind between poses);
- ``plunge_past_flutes``: plunges deeper into the stock than the flute length;
- ``sim_rapid_cuts`` / ``sim_collisions``: the dexel simulation from that stock (at ``--sim-step``):
  rapid moves that cut material, moves whose shank or holder meets the stock as it is cut.

Goal: zero of each. A run that fails prints its one-line error instead.

    .venv/bin/python bench/safety.py [--src /path/to/other/src] [--parts vase,blade] [--out bench/out/safety.json]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import subprocess
import sys
import time

import numpy as np
import trimesh

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
SHARED = os.path.join(os.path.dirname(ROOT), "shared", "parts")
sys.path.insert(0, os.path.join(ROOT, "src"))

from meshmill.geometry.mesh import load_mesh  # noqa: E402
from meshmill.geometry.shapes import box  # noqa: E402
from meshmill.kernels.backend import solid_kernels  # noqa: E402
from meshmill.machine.pathfile import read_toolpath  # noqa: E402
from meshmill.ops.simulate import simulate  # noqa: E402
from meshmill.pathing.verify import StockCheck, verify_toolpath  # noqa: E402
from meshmill.simulation.stock import Stock  # noqa: E402
from meshmill.tools.table import load_tools  # noqa: E402

TOOLS = """# bench/safety.py: a roughing end mill, balls and a bull-nose, with holders (mm)
[[tools]]
name = "F10"
type = "flat"
diameter = 10.0
flute_length = 25.0
gauge_length = 60.0
holder_diameter = 40.0
holder_length = 40.0

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
"""
ALLOWANCE = 0.5  # mm the finishing operations are taken to start from
CLEARANCE = 0.5  # mm rapids keep from the stock


def _turn_x_up(v):
    """+X to +Z (a mould cavity that opens toward +X)."""
    return np.column_stack([-v[:, 2], v[:, 1], v[:, 0]])


# name: (file, scale to mm, turn, largest extent wanted or None)
PARTS = {
    "vase": (os.path.join(ROOT, "src", "meshmill", "data", "vase.stl"), 1.0, None, None),
    "ktoolcav": (os.path.join(SHARED, "ktoolcav.stl"), 25.4, None, None),  # inches
    "blade": (os.path.join(SHARED, "real", "blade_hpt_airfoil.stl"), 1000.0, None, None),
    "dolphin": (os.path.join(SHARED, "real", "mould_dolphin_tail_cavity.stl"), 1.0, _turn_x_up, None),
    "terrain": (os.path.join(SHARED, "real", "relief_terrain.stl"), 1.0, None, 150.0),
    "hull": (os.path.join(SHARED, "real", "ship_hull_dtc.stl"), 1000.0, None, 200.0),
    "car": (os.path.join(SHARED, "real", "car_body_drivaer.stl"), 1000.0, None, 200.0),
}


def setup(name, folder):
    """The part set up for machining from +Z, its lowest corner at the origin: an STL in mm."""
    path, scale, turn, extent = PARTS[name]
    m = trimesh.load(path, force="mesh", process=False)
    v = np.asarray(m.vertices, float) * scale
    if turn is not None:
        v = turn(v)
    v -= v.min(axis=0)
    if extent is not None:
        v *= extent / np.ptp(v, axis=0).max()
    out = os.path.join(folder, f"{name}.stl")
    trimesh.Trimesh(v, m.faces, process=False).export(out)
    return out


def operations(part_file):
    """``(name, argv after the part, tool)`` of the operations run on a part of this height."""
    lo, hi = trimesh.load(part_file).bounds
    h = hi[2] - lo[2]
    step = max(0.5, round(h / 8, 1))
    return [
        ("finish", ["--step-down", str(step), "--sample", "1.0", "--tilt-step", "10"], None),
        ("waterline", ["--tool", "B6", "--step-down", str(max(1.0, round(h / 6, 1))), "--sample", "1.0"], "B6"),
        ("raster", ["--tool", "B6", "--stepover", "2", "--sample", "0.5"], "B6"),
        ("plunge", ["--tool", "F10", "--radial-step", "6", "--engagement", "8", "--allowance", "1"], "F10"),
    ]


def run_op(src, op, part_file, args, tools_file, out):
    env = dict(os.environ, PYTHONPATH=src)
    cmd = [sys.executable, "-m", "meshmill", op, part_file, "--tools", tools_file, "--out", out, "--quiet", *args]
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
    return r.returncode, (r.stderr.strip().splitlines() or [""])[-1], time.perf_counter() - t


def plunges_past_flutes(tp, tools, lo, hi):
    """Feed moves down the tool axis that end deeper in the stock box than the flute length."""
    count = 0
    for i in range(1, len(tp)):
        if tp.rapid[i]:
            continue
        d = tp.tip[i] - tp.tip[i - 1]
        u = tp.axis[i]
        if np.dot(d, u) >= -1e-9 or np.linalg.norm(np.cross(d, u)) > 1e-6:
            continue  # not a plunge down its axis
        p = tp.tip[i]
        with np.errstate(divide="ignore", invalid="ignore"):
            a, b = (lo - p) / u, (hi - p) / u
        entry = np.min(np.where(u != 0, np.maximum(a, b), np.inf))  # where the axis leaves the box upward
        if entry > tools[tp.tool[i]].flute_length + 1e-6:
            count += 1
    return count


def measure(part_file, op, cl, tools, sim_step):
    part = load_mesh(part_file)
    kern = solid_kernels(part)
    tp, _ = read_toolpath(cl, tools)
    lo, hi = part.bounds
    if op == "plunge":
        stock = StockCheck(kern=solid_kernels(box(lo, hi)), clearance=CLEARANCE, feed_body=False)  # roughing
    else:
        stock = StockCheck(allowance=ALLOWANCE, clearance=CLEARANCE)
    t = time.perf_counter()
    v = verify_toolpath(kern, tp, tools, 0.01, 0.5, stock=stock)
    row = {"moves": len(tp), "rapid_in_stock": v["rapid_moves_touching"], "gouging": v["gouging_moves"],
           "colliding": v["colliding_moves"], "max_gouge": round(v["max_gouge"], 4),
           "verify_s": round(time.perf_counter() - t, 1)}
    if op == "plunge":
        row["plunge_past_flutes"] = plunges_past_flutes(tp, tools, lo, hi)
    if sim_step:  # (an open part: the solid it bounds, as simulate models it)
        t = time.perf_counter()
        try:
            stock = Stock.of("box") if op == "plunge" else Stock.offset(ALLOWANCE)
            _, sim, *_ = simulate(part, tp, tools, sim_step, stock)
            row.update(sim_rapid_cuts=sim["rapid_moves_cutting"], sim_collisions=sim["colliding_moves"],
                       sim_s=round(time.perf_counter() - t, 1))
        except Exception as exc:  # noqa: BLE001
            row["sim_error"] = str(exc)[:120]
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--src", default=os.path.join(ROOT, "src"), help="src folder of the meshmill that writes the paths")
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--ops", default="finish,waterline,raster,plunge")
    ap.add_argument("--sim-step", type=float, default=0.5, help="dexel step of the simulations, mm (0: none)")
    ap.add_argument("--work", default=os.path.join(HERE, "out", "safety"))
    ap.add_argument("--out", default=None, help="JSON file (default: WORK/safety.json)")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    tools_file = os.path.join(a.work, "tools.toml")
    with open(tools_file, "w") as fh:
        fh.write(TOOLS)
    tools = load_tools(tools_file)
    rows = []
    for name in a.parts.split(","):
        part_file = setup(name, a.work)
        for op, args, _ in operations(part_file):
            if op not in a.ops.split(","):
                continue
            out = os.path.join(a.work, f"{name}-{op}")
            rc, last, seconds = run_op(a.src, op, part_file, args, tools_file, out)
            row = {"part": name, "op": op, "rc": rc, "seconds": round(seconds, 1)}
            cl = os.path.join(out, "toolpath.cl")
            if rc in (0, 1) and os.path.exists(cl):
                row.update(measure(part_file, op, cl, tools, a.sim_step))
            else:
                row["error"] = last[:160]
            rows.append(row)
            print(json.dumps(row), flush=True)
    result = {"date": datetime.date.today().isoformat(), "src": os.path.abspath(a.src), "rows": rows}
    out = a.out or os.path.join(a.work, "safety.json")
    os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
    with open(out, "w") as fh:
        json.dump(result, fh, indent=1)
    keys = ["rapid_in_stock", "gouging", "colliding", "plunge_past_flutes", "sim_rapid_cuts", "sim_collisions"]
    print(f"\n{'part':<10}{'op':<11}{'rc':>3}{'s':>7}" + "".join(f"{k:>20}" for k in keys))
    for r in rows:
        print(f"{r['part']:<10}{r['op']:<11}{r['rc']:>3}{r['seconds']:>7.0f}"
              + "".join(f"{str(r.get(k, '-')):>20}" for k in keys) + (f"  {r['error']}" if "error" in r else ""))


if __name__ == "__main__":
    main()
