"""Post-processing speed and accuracy: the demo's 5-axis vase finish posted for every shipped
5-axis machine at two tolerances, then read back.

    .venv/bin/python bench/post_programs.py [--cl demo-out/toolpath.cl] [--out bench/out/post_programs.json]

Without --cl the path is made first (``meshmill finish`` on the shipped vase, step-down 1 mm, as
``make demo`` does; not timed). Per machine and tolerance: the seconds of ``post_program`` (CL
already read), the blocks written and added by linearisation, the largest tip deviation, the
rewinds, and the seconds to read the program back (``read_gcode`` through the machine's
kinematics, which splits joint-linear blocks within 1 um) with the moves it gives.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import tempfile
import time

from finish_tableau7 import git_commit, machine as machine_info
from meshmill.machine.config import load_machine
from meshmill.machine.post import post_program
from meshmill.tools.table import load_tools
from meshmill.toolpath.cldata import read_apt
from meshmill.machine.gcode import read_gcode

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.path.join(HERE, "..", "src", "meshmill", "data")
RUNS = (("table-table-ac", 0.005), ("table-table-ac", 0.001), ("head-table-bc", 0.005), ("head-table-bc", 0.001),
        ("head-head-ca", 0.005))  # (machine, tolerance mm)
CLEARANCE = 75.0  # mm: the vase's top is at 63.11, the path's highest tip at 73.11


def _make_cl(folder):
    from meshmill.cli import main

    if main(["finish", os.path.join(DATA, "vase.stl"), "--tools", os.path.join(DATA, "tools.toml"),
             "--step-down", "1", "--out", folder, "--quiet"]) != 0:
        sys.exit("finish failed")
    return os.path.join(folder, "toolpath.cl")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cl", default=None, help="APT CL file (default: make the demo's vase finish)")
    ap.add_argument("--out", default=os.path.join(HERE, "out", "post_programs.json"))
    args = ap.parse_args(argv)
    tools = load_tools(os.path.join(DATA, "tools.toml"))
    with tempfile.TemporaryDirectory() as tmp:
        cl_path = args.cl or _make_cl(os.path.join(tmp, "finish"))
        tp, _ = read_apt(cl_path, tools)
        rows = []
        for name, tol in RUNS:
            m = load_machine(name)
            t0 = time.perf_counter()
            lines, report = post_program(tp, tools, m, tolerance=tol, clearance=CLEARANCE)
            post_s = time.perf_counter() - t0
            nc = os.path.join(tmp, f"{name}.nc")
            with open(nc, "w") as fh:
                fh.write("\n".join(lines) + "\n")
            t0 = time.perf_counter()
            back, _ = read_gcode(nc, tools, machine=m)
            read_s = time.perf_counter() - t0
            rows.append({"machine": name, "tolerance_mm": tol, "moves": len(tp), "post_s": post_s,
                         "blocks": report["blocks"], "added": report["linearisation"]["blocks_added"],
                         "max_deviation_mm": report["linearisation"]["max_deviation_mm"],
                         "rewinds": report["rewinds"], "read_s": read_s, "read_moves": len(back)})
            r = rows[-1]
            print(f"{name} tol {tol:g}: post {post_s:.2f} s, {r['blocks']} blocks (+{r['added']}), "
                  f"max dev {r['max_deviation_mm']:.4f} mm, read back {read_s:.2f} s", file=sys.stderr)
    print("| machine | tol mm | CL moves | post s | blocks | added | max dev mm | rewinds | read s | read moves |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['machine']} | {r['tolerance_mm']:g} | {r['moves']} | {r['post_s']:.2f} | {r['blocks']} | "
              f"{r['added']} | {r['max_deviation_mm']:.4f} | {r['rewinds']} | {r['read_s']:.2f} | "
              f"{r['read_moves']} |")
    mach = machine_info()
    print(f"machine: {mach['cpu_model'] or mach['processor']}, {mach['cpu_count']} CPUs")
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump({"rows": rows, "cl": os.path.abspath(cl_path) if args.cl else "vase finish, step-down 1 mm",
                   "machine": mach, "commit": git_commit(),
                   "date": datetime.datetime.now().isoformat(timespec="seconds")}, fh, indent=1)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
