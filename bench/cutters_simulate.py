"""Simulate one tool path with a ball-end, a flat end and a bull-nose mill of the same diameter
(issue 23: flat and bull-nose within 3x of the ball), whole ``api.simulate`` and its cut stage.

    .venv/bin/python bench/cutters_simulate.py [--steps 0.6 0.3] [--out bench/out/cutters.json]

The path: a ball-end raster of ``sphere_on_plate.stl`` (stepover 1 mm, sampling 0.5 mm), cut
as it is by each cutter (the flat and bull-nose gouge the dome: the simulation does not care)."""
import argparse
import json
import platform
import time
from pathlib import Path

from meshmill import api
from meshmill.tools.table import Tool

PART = Path(__file__).resolve().parents[2] / "shared" / "parts" / "sphere_on_plate.stl"
TOOLS = [Tool("B6", "ball", 6.0, 3.0, 12.0, 40.0, 6.0, number=1),
         Tool("F6", "flat", 6.0, 0.0, 12.0, 40.0, 6.0, number=2),
         Tool("R6", "bull", 6.0, 1.0, 12.0, 40.0, 6.0, number=3)]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=float, nargs="+", default=[0.6, 0.3])
    ap.add_argument("--out", default="bench/out/cutters.json")
    args = ap.parse_args()
    part = api.load_part(PART)
    path = api.raster(part, TOOLS, tool="B6", stepover=1.0, sample=0.5).toolpath
    api.simulate(part, path, TOOLS, step=2.0, outputs=())  # compile
    rows = []
    print(f"{len(path.tip)} points; {platform.processor() or platform.machine()}")
    print("| step mm | cutter | simulate s | cut s | x ball (whole) | x ball (cut) |")
    print("|---:|---|---:|---:|---:|---:|")
    for step in args.steps:
        base = None
        for k, tool in enumerate(TOOLS):
            path.tool[:] = k
            t = time.perf_counter()
            res = api.simulate(part, path, TOOLS, step=step, outputs=())
            whole = time.perf_counter() - t
            cut = res.summary["seconds"]["cut"]
            base = base or (whole, cut)
            rows.append({"step": step, "cutter": tool.type, "simulate_s": whole, "cut_s": cut,
                         "machined_mm3": res.summary["volumes_mm3"]["machined"]})
            print(f"| {step} | {tool.type} | {whole:.2f} | {cut:.2f} | {whole / base[0]:.2f} | {cut / base[1]:.2f} |")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"points": len(path.tip), "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
