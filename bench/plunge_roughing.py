"""Plunge roughing (seed 001) on the stand-in parts, and accessibility speed.

For the double wave and the handle (``standin_parts.py``), a flat end mill of 10 mm: 3-axis
plunging (radial step 3 mm, engagement 6 mm) and 5-axis half-sphere plunging (15° / 30°; the
seed's one plunge a direction, and 8 regions each from its best direction), 1 mm allowance;
plunge counts, seconds, and what the dexel simulation (0.5 mm) says is left of the stock box over
the design. Then visibility and accessibility along three directions of the blade
(26 528 triangles) and of a 30 000-triangle sphere, timed end to end.

    .venv/bin/python bench/plunge_roughing.py [--out bench/out/plunge_roughing.json]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import time

from finish_tableau7 import git_commit, machine
from standin_parts import blade, double_wave, handle
from meshmill.geometry import analysis
from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.geometry.shapes import sphere
from meshmill.ops.plunge import PlungeParams, plunge3, plunge5
from meshmill.ops.simulate import simulate
from meshmill.tools.table import Tool

HERE = os.path.dirname(os.path.abspath(__file__))
FLAT = Tool("F10", "flat", 10.0, 0.0, 60.0, 90.0, 10.0)


def roughing_rows(step=0.5):
    rows = []
    for name, make in (("double_wave", double_wave), ("handle", handle)):
        m = mesh_from_arrays(*make(), name)
        for axes, run, regions in ((3, plunge3, 0), (5, plunge5, 0), (5, plunge5, 8)):
            params = PlungeParams(radial_step=3.0, engagement=6.0, allowance=1.0, theta_step=15.0, delta_step=30.0,
                                  regions=regions)
            t = time.perf_counter()
            tp, s = run(m, [FLAT], "F10", params)
            seconds = time.perf_counter() - t
            dev, sim, *_ = simulate(m, tp, [FLAT], step, stock="box")
            rows.append({"part": name, "axes": axes, "regions": regions, "plunges": s["plunges"], "valid": s["valid_plunges"],
                         "seconds": seconds, "verify_ok": s["verify"]["ok"], "stock_mm3": sim["volumes_mm3"]["stock"],
                         "left_mm3": dev["remaining_volume"], "gouged_mm3": sim["volumes_mm3"]["gouged"],
                         "simulate_s": sim["seconds"]["total"]})
            r = rows[-1]
            print(f"  {name} {axes}-axis regions {regions}: {r['valid']}/{r['plunges']} plunges, {r['seconds']:.2f} s",
                  flush=True)
    return rows


def access_rows():
    rows = []
    parts = [("blade", mesh_from_arrays(*blade(), "blade")), ("sphere", sphere(20.0, rings=100, segments=150))]
    for name, m in parts:
        analysis.visibility(m, [0, 0, 1])  # compile / load caches
        for d in ([0, 0, 1], [1, 0, 0], [0.3, 0.4, 0.8]):
            t = time.perf_counter()
            f = analysis.visibility(m, d)
            rows.append({"part": name, "triangles": int(len(m.faces)), "direction": d,
                         "seconds": time.perf_counter() - t, "visible": int(f["visible_triangles"].sum()),
                         "accessible": int(f["accessible_triangles"].sum())})
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(HERE, "out", "plunge_roughing.json"))
    args = ap.parse_args(argv)
    mach = machine()
    print(f"machine: {mach['cpu_model'] or mach['processor']}, {mach['cpu_count']} CPUs, {mach['numba_threads']} numba threads")
    rough = roughing_rows()
    print("\n| part | axes | regions | plunges (valid / all) | seconds | verify | stock mm³ | left over the design mm³ | gouged mm³ |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rough:
        print(f"| {r['part']} | {r['axes']} | {r['regions'] or 'seed'} | {r['valid']} / {r['plunges']} | {r['seconds']:.2f} | "
              f"{'ok' if r['verify_ok'] else 'PROBLEMS'} | {r['stock_mm3']:.0f} | {r['left_mm3']:.0f} | {r['gouged_mm3']:.2f} |")
    access = access_rows()
    print("\n| part | triangles | direction | visible | accessible | seconds |")
    print("|---|---|---|---|---|---|")
    for r in access:
        print(f"| {r['part']} | {r['triangles']} | {r['direction']} | {r['visible']} | {r['accessible']} | {r['seconds']:.3f} |")
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump({"date": datetime.datetime.now().isoformat(timespec="seconds"), "commit": git_commit(),
                   "machine": mach, "roughing": rough, "accessibility": access}, fh, indent=2, default=float)
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
