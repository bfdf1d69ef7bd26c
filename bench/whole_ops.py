"""Issue 23's measures: whole commands as a user waits for them, against OpenCAMLib in the same run.

    .venv/bin/python bench/whole_ops.py [--only raster,waterline,finish,simulate] [--out bench/out/whole_ops.json]

- raster: ``meshmill raster mount_rush.stl --tool B4 --stepover 0.1 --sample 0.1`` (a new process,
  start-up, loading, drop, refinement, certified verification and writing included) against
  ``BatchDropCutter`` (BallCutter 4 mm) on the same grid points, the best of 3 runs against the best
  of 2 (the VM's speed drifts); goal 10x;
- waterline: ``meshmill waterline sphere_on_plate.stl --step-down 1 --sample 0.1`` with a 6 mm ball
  against ``Waterline`` (sampling 0.1) at the same levels; goal: keep 20x;
- finish: the dolphin mould of ``../shared/parts/real/`` turned to face +Z, as bench/realparts.py
  finishes it; goal under 60 s;
- simulate: one raster cut with a ball, a flat and a bull-nose mill of 6 mm (bench/cutters_simulate.py,
  0.3 mm dexels); goal: flat and bull within 3x of the ball.

(about 5 minutes on 2 cores)"""
import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PARTS = os.path.join(os.path.dirname(ROOT), "shared", "parts")
MESHMILL = os.path.join(os.path.dirname(sys.executable), "meshmill")
sys.path.insert(0, HERE)

B6_TABLE = """[[tools]]
name = "B6"
type = "ball"
diameter = 6.0
flute_length = 30.0
gauge_length = 30.0
"""


def command(*args) -> float:
    """Wall seconds of ``meshmill args`` in a new process (it must succeed)."""
    t = time.perf_counter()
    subprocess.run([MESHMILL, *args, "--quiet"], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def bench_raster(work):
    import opencamlib as ocl

    from meshmill import api
    from meshmill.ops.raster import raster_lines

    path = os.path.join(PARTS, "mount_rush.stl")
    tools = os.path.join(ROOT, "src", "meshmill", "data", "tools.toml")
    args = ("raster", path, "--tools", tools, "--tool", "B4", "--stepover", "0.1", "--sample", "0.1")
    # the package's bytecode, as an installed package has it (this machine's PYTHONDONTWRITEBYTECODE
    # leaves an editable install without: 0.1 s of every command), and numba's cache
    subprocess.run([sys.executable, "-m", "compileall", "-q", os.path.join(ROOT, "src", "meshmill")], check=True)
    command(*args, "--stepover", "2", "--sample", "1", "--out", os.path.join(work, "warm"))
    ours = min(command(*args, "--out", os.path.join(work, "raster")) for _ in range(3))
    part = api.load_part(path)
    xy = np.concatenate(raster_lines(part.bounds, 2.0, 0.1, 0.0, 0.1)[0])
    surf = ocl.STLSurf()
    ocl.STLReader(path, surf)
    cutter = ocl.BallCutter(4.0, 30.0)
    floor = float(part.bounds[0, 2] - 10)
    theirs = []
    for _ in range(2):  # a fresh batch each time: its points start at the floor again
        bdc = ocl.BatchDropCutter()
        bdc.setSTL(surf)
        bdc.setCutter(cutter)
        for x, y in xy:
            bdc.appendPoint(ocl.CLPoint(float(x), float(y), floor))
        t = time.perf_counter()
        bdc.run()
        theirs.append(time.perf_counter() - t)
    theirs = min(theirs)
    return {"row": "raster mount_rush B4 0.1/0.1", "ours_s": ours, "peer": "BatchDropCutter", "peer_s": theirs,
            "points": int(len(xy)), "ratio": theirs / ours, "goal": ">= 10x"}


def bench_waterline(work):
    import opencamlib as ocl
    from three_axis_vs_ocl import ocl_loops, ocl_surface

    from meshmill import api
    from meshmill.geometry.slicing import z_levels

    path = os.path.join(PARTS, "sphere_on_plate.stl")
    table = os.path.join(work, "b6.toml")
    with open(table, "w") as f:
        f.write(B6_TABLE)
    args = ("waterline", path, "--tools", table, "--tool", "B6", "--step-down", "1", "--sample", "0.1")
    command("waterline", path, "--tools", table, "--tool", "B6", "--step-down", "10", "--out",
            os.path.join(work, "warm"))
    ours = command(*args, "--out", os.path.join(work, "waterline"))
    bounds = api.load_part(path).bounds
    levels = z_levels(bounds[0, 2], bounds[1, 2], 1.0)
    surf = ocl_surface(path)
    cutter = ocl.BallCutter(6.0, 30.0)
    t = time.perf_counter()
    for z in levels:
        ocl_loops(ocl.Waterline, surf, cutter, z, 0.1)
    theirs = time.perf_counter() - t
    return {"row": "waterline sphere_on_plate B6 1/0.1", "ours_s": ours, "peer": "Waterline", "peer_s": theirs,
            "levels": int(len(levels)), "ratio": theirs / ours, "goal": ">= 20x"}


def bench_finish(work):
    import realparts

    table = os.path.join(work, "finish.toml")
    with open(table, "w") as f:
        f.write(realparts.TOOLS)
    path, setup, step_down = realparts.PARTS["dolphin"]
    ours = command("finish", path, "--tools", table, "--step-down", str(step_down), "--sample", "1.0",
                   "--tilt-step", "10", "--scallop", "0.01", "--machine", realparts.MACHINES[0], "--out",
                   os.path.join(work, "finish"), *setup)
    return {"row": "finish dolphin mould (bench/realparts.py)", "ours_s": ours, "goal": "< 60 s"}


def bench_simulate(work):
    from cutters_simulate import TOOLS, PART

    from meshmill import api

    part = api.load_part(PART)
    path = api.raster(part, TOOLS, tool="B6", stepover=1.0, sample=0.5).toolpath
    api.simulate(part, path, TOOLS, step=2.0, outputs=())
    times = {}
    for k, tool in enumerate(TOOLS):
        path.tool[:] = k
        t = time.perf_counter()
        api.simulate(part, path, TOOLS, step=0.3, outputs=())
        times[tool.type] = time.perf_counter() - t
    return {"row": "simulate sphere_on_plate raster, 0.3 mm dexels", "ours_s": times["ball"],
            "flat_s": times["flat"], "bull_s": times["bull"],
            "ratio": max(times["flat"], times["bull"]) / times["ball"], "goal": "flat, bull <= 3x ball"}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", default="raster,waterline,finish,simulate")
    ap.add_argument("--out", default=os.path.join(HERE, "out", "whole_ops.json"))
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as work:
        for name in args.only.split(","):
            rows.append(globals()["bench_" + name](work))
            print(json.dumps(rows[-1]), file=sys.stderr)
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs")
    print("| measure | ours s | peer | peer s | ratio | goal |")
    print("|---|---:|---|---:|---:|---|")
    for r in rows:
        peer = r.get("peer", "")
        peer_s = f"{r['peer_s']:.1f}" if "peer_s" in r else ""
        extra = f" (flat {r['flat_s']:.2f}, bull {r['bull_s']:.2f})" if "flat_s" in r else ""
        ratio = f"{r['ratio']:.2f}" if "ratio" in r else ""
        print(f"| {r['row']}{extra} | {r['ours_s']:.2f} | {peer} | {peer_s} | {ratio} | {r['goal']} |")
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        json.dump({"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(), "rows": rows}, f,
                  indent=1)


if __name__ == "__main__":
    main()
