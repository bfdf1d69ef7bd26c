"""Jobs from stock to finished part, with and without the in-process stock (issue 20's measures).

    .venv/bin/python bench/job.py                     # vase, dolphin mould, terrain
    .venv/bin/python bench/job.py --parts vase

Each part runs as one job (``meshmill.Job``) three times: ``stock+rest``, the operations given
the in-process stock (rapids, shanks and holders keep clear of it) with rest machining (raster and
waterline cut only where it holds more than 0.05 mm); ``stock``, the same without rest machining;
``alone``, each operation computed from the part alone, as run on its own (its rapids may cut
the stock: the job reports them). All are cut from the in-process stock to measure them. Per operation: the share of the feed length that cuts air
(removes nothing from the stock as it stands then), the volume removed, the machining time on
the job's machine, the seconds the operation took; per job: the final share of the design's
surface within the tolerance, the machining time, and the wall time against the operations'
own seconds (the rest is the job's: the in-process stock, its meshes, the checks, the program).
Prints a table and writes bench/out/job.json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.path.join(ROOT, "src", "meshmill", "data")
REAL = os.path.join(os.path.dirname(ROOT), "shared", "parts", "real")
sys.path.insert(0, os.path.join(ROOT, "src"))

ROUGH = {"type": "plunge", "name": "rough", "tool": "F10L", "allowance": 1.0, "radial_step": 4.0, "engagement": 4.0}
PARTS = {
    # the demo job
    "vase": dict(part={"file": os.path.join(DATA, "vase.stl")}, machine="table-table-ac", step=0.5,
                 stock={"type": "box", "margin": 1.0},
                 operations=[ROUGH,
                             {"type": "waterline", "name": "semi-finish", "tool": "B4", "step_down": 1.0,
                              "allowance": 0.3},
                             {"type": "raster", "name": "top", "tool": "B4", "stepover": 1.0, "allowance": 0.3},
                             {"type": "finish", "name": "finish", "step_down": 1.0}]),
    # a mould cavity: deep walls, concave corners (../shared/parts/real/, turned to face +Z)
    "dolphin": dict(part={"file": os.path.join(REAL, "mould_dolphin_tail_cavity.stl"), "up": "+X",
                          "origin": "bottom-centre"}, machine="generic-3axis", step=0.75,
                    stock={"type": "box", "margin": 0.0, "top": 2.0},
                    operations=[ROUGH,
                                {"type": "waterline", "name": "semi-finish", "tool": "B10", "step_down": 2.0,
                                 "allowance": 0.3},
                                {"type": "raster", "name": "finish B4", "tool": "B4", "stepover": 1.0}]),
    # a terrain relief in metres, an open sheet
    "terrain": dict(part={"file": os.path.join(REAL, "relief_terrain.stl"), "units": "m", "scale": 0.0002,
                          "origin": "corner"}, machine="generic-3axis", step=1.0,
                    stock={"type": "box", "margin": 0.0, "top": 2.0},
                    operations=[ROUGH,
                                {"type": "raster", "name": "semi-finish B10", "tool": "B10", "stepover": 2.0,
                                 "allowance": 0.3},
                                {"type": "raster", "name": "finish B4", "tool": "B4", "stepover": 1.0}]),
}


VARIANTS = (("stock+rest", True, 0.05), ("stock", True, False), ("alone", False, False))


def run(name, spec, variant, in_process, rest):
    from meshmill import api
    from meshmill.job import Job, Operation

    part = api.load_part(**{k if k != "file" else "path": v for k, v in spec["part"].items()})
    tools = api.load_tools(os.path.join(DATA, "tools.toml"))
    ops = [Operation.from_dict(o, k + 1, rest) for k, o in enumerate(spec["operations"])]
    job = Job(part=part, tools=tools, operations=ops, stock=api.Stock.from_dict(spec["stock"]), machine=spec["machine"],
              step=spec["step"], in_process=in_process, name=name)
    t = time.perf_counter()
    res = job.run()
    wall = time.perf_counter() - t
    rows = []
    for op in res.operations:
        if op.skipped:
            continue
        j = op.path.summary["job"]
        rows.append({"part": name, "variant": variant, "operation": op.operation.name,
                     "air_share": round(j["cutting_mm"]["air_share"], 4),
                     "in_material_mm": round(j["cutting_mm"]["in_material"], 1),
                     "in_air_mm": round(j["cutting_mm"]["in_air"], 1), "removed_mm3": round(j["removed_mm3"], 1),
                     "machining_s": round(j["machining_s"], 1), "op_s": j["seconds"]["operation"],
                     "cut_s": j["seconds"]["cut_and_measure"], "ok": j["ok"]})
    f = res.summary["final"]
    total = {"part": name, "variant": variant, "within_tolerance": round(f["within_tolerance"], 4),
             "left_over_design_mm3": round(f["left_over_design_mm3"], 1),
             "machining_s": round(res.summary["machining_s"], 1), "wall_s": round(wall, 1),
             "ops_s": round(sum(r["op_s"] for r in rows), 1), "ok": res.ok}
    return rows, total


def table(rows):
    keys = list(rows[0])
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(str(r[k]) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(PARTS))
    a = ap.parse_args()
    rows, totals = [], []
    for name in a.parts.split(","):
        for variant, in_process, rest in VARIANTS:
            r, t = run(name, PARTS[name], variant, in_process, rest)
            rows += r
            totals.append(t)
            print(table(r), "\n", table([t]), "\n", flush=True)
    print(table(rows))
    print()
    print(table(totals))
    os.makedirs(os.path.join(HERE, "out"), exist_ok=True)
    with open(os.path.join(HERE, "out", "job.json"), "w") as fh:
        json.dump({"operations": rows, "jobs": totals}, fh, indent=2)


if __name__ == "__main__":
    main()
