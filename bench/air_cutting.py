"""Cutting length in air along a sequence of operations (issue 20's measure, before rest machining).

    .venv/bin/python bench/air_cutting.py                 # the bundled vase
    .venv/bin/python bench/air_cutting.py --step 0.3

Roughing (3-axis plunge, F6, 1 mm allowance) from the part's box, then a waterline semi-finish (B4,
1 mm step-down) and a raster (B4, 1 mm stepover), each without and with rest machining (`--rest
0.05`), and
the 5-axis finish (step-down 1 mm), each given the stock the one before left (`--stock
machined.stl` of `simulate`; the two rasters both after the waterline, the finish after the rest
raster) and simulated from it: the feed length that removes material and the length in air
(`simulate`'s `cutting_mm`), the removed volume and the machining time on table-table-ac. Prints a
table and writes bench/out/air_cutting.json.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.path.join(ROOT, "src", "meshmill", "data")
MESHMILL = os.path.join(os.path.dirname(sys.executable), "meshmill")


def run(*argv):
    t = time.perf_counter()
    subprocess.run([MESHMILL, *argv], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", default=os.path.join(DATA, "vase.stl"))
    ap.add_argument("--tools", default=os.path.join(DATA, "tools.toml"))
    ap.add_argument("--step", type=float, default=0.5, help="dexel step of the simulations, mm (0.5)")
    ap.add_argument("--out", default=os.path.join(HERE, "out", "air_cutting"))
    a = ap.parse_args()
    raster = ["raster", a.part, "--tools", a.tools, "--tool", "B4", "--stepover", "1"]
    ops = [("rough", None, ["plunge", a.part, "--tools", a.tools, "--tool", "F6", "--allowance", "1"]),
           ("waterline", "rough", ["waterline", a.part, "--tools", a.tools, "--tool", "B4", "--step-down", "1"]),
           ("waterline --rest", "rough", ["waterline", a.part, "--tools", a.tools, "--tool", "B4", "--step-down", "1",
                                          "--rest", "0.05"]),
           ("raster", "waterline", raster),
           ("raster --rest", "waterline", [*raster, "--rest", "0.05"]),
           ("finish", "raster --rest", ["finish", a.part, "--tools", a.tools, "--step-down", "1"])]
    rows = []
    for name, after, argv in ops:
        key = name.replace(" --", "-")
        folder, sim = os.path.join(a.out, key), os.path.join(a.out, f"sim-{key}")
        stock = os.path.join(a.out, f"sim-{after.replace(' --', '-')}", "machined.stl") if after else None
        given = ["--stock", stock] if stock else []
        op_s = run(*argv, *given, "--out", folder, "--quiet")
        cl = os.path.join(folder, "toolpath.cl")
        sim_s = run("simulate", "--design", a.part, *given, "--toolpath", cl, "--tools", a.tools, "--step",
                    str(a.step), "--out", sim, "--quiet")
        run("time", cl, "--machine", "table-table-ac", "--tools", a.tools, "--out", os.path.join(a.out, f"{key}-time.json"))
        s = json.load(open(os.path.join(sim, "summary.json")))
        t = json.load(open(os.path.join(a.out, f"{key}-time.json")))
        c = s["cutting_mm"]
        rows.append({"operation": name, "after": after or "box", "in_material_mm": round(c["in_material"], 1), "in_air_mm": round(c["in_air"], 1),
                     "air_share": round(c["air_share"], 4), "removed_mm3": round(s["volumes_mm3"]["removed"], 1),
                     "machining_s": round(t["total"]["total_s"], 1), "op_s": round(op_s, 1), "sim_s": round(sim_s, 1)})
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |\n|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(str(r[k]) for k in keys) + " |")
    os.makedirs(os.path.join(HERE, "out"), exist_ok=True)
    with open(os.path.join(HERE, "out", "air_cutting.json"), "w") as fh:
        json.dump({"part": os.path.basename(a.part), "step": a.step, "rows": rows}, fh, indent=2)


if __name__ == "__main__":
    main()
