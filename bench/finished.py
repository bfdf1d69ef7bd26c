"""A finished part (issue 38): jobs that end with steep-and-shallow finishing to a 0.01 mm scallop
and rest finishing from the in-process stock, and what they leave on the part and why.

    .venv/bin/python bench/finished.py                      # vase, dolphin, terrain, hull, car
    .venv/bin/python bench/finished.py --parts dolphin

Per part one job (``meshmill.Job``): the roughing and semi-finishing of bench/job.py (the hull
and the car: adaptive clearing from their box rather than plunges, as every CAM roughs), then
``steep-shallow`` with B10 at ``scallop = 0.01`` and ``rest-finish`` with B4 then B1, as a mould
shop finishes with the largest ball and rests with smaller ones (the vase: roughed as
the demo job roughs it, from the top and the four sides, then its 5-axis finish with ``scallop =
0.01``, then the same 3-axis finishing from the top). Reported: the share of the design's surface
(by area, :func:`meshmill.api.what_is_left`) within ±0.01 and ±0.02 mm, of the whole and of the
surface some ball of the table reaches; the area per reason of what is left; the machining time
and its non-cutting share (rapids, tool changes, feed through the air); the wall time of the
finishing operations (5-axis finish, steep-shallow and rest-finish) and of the job. Prints a table and writes
bench/out/finished.json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "src"))
sys.path.insert(0, HERE)
from job import DATA, PARTS as JOB_PARTS, REAL, ROUGH  # noqa: E402

SCALLOP = 0.01
FINISH = [{"type": "steep-shallow", "name": "finish B10", "tool": "B10", "scallop": SCALLOP},
          {"type": "rest-finish", "name": "rest", "tools": ["B4", "B1"], "scallop": SCALLOP}]
SIDES = [{"type": "rough", "name": f"rough {axis}", "tool": "F10L", "allowance": 0.5, "engagement": 2.5,
          "step_down": 10.0, **({"axis": axis} if axis != "top" else {})} for axis in ("top", "+X", "+Y", "-X", "-Y")]
CLEAR = {"type": "rough", "name": "rough", "tool": "F10L", "allowance": 0.5, "engagement": 2.5, "step_down": 10.0}
SEMI = {"type": "waterline", "name": "semi-finish", "tool": "B10", "step_down": 2.0, "allowance": 0.3}
PARTS = {
    # the demo part: its 5-axis finish to the scallop limit too
    # roughed as the demo job roughs it: adaptive clearing from the top, then under the bulge from
    # the four sides (3+2)
    "vase": dict(JOB_PARTS["vase"], operations=SIDES + JOB_PARTS["vase"]["operations"][1:3]
                 + [{"type": "finish", "name": "finish", "step_down": 1.0, "scallop": SCALLOP}] + FINISH),
    "dolphin": dict(JOB_PARTS["dolphin"], operations=JOB_PARTS["dolphin"]["operations"][:2] + FINISH),
    "terrain": dict(JOB_PARTS["terrain"], operations=JOB_PARTS["terrain"]["operations"][:2] + FINISH),
    # real designs as published: a ship's hull (metres) and a car body, 3-axis from the top
    "hull": dict(part={"file": os.path.join(REAL, "ship_hull_dtc.stl"), "units": "m", "scale": 0.04,
                       "origin": "bottom-centre"}, machine="generic-3axis", step=0.75,
                 stock={"type": "box", "margin": 0.0, "top": 2.0}, operations=[CLEAR, SEMI] + FINISH),
    "car": dict(part={"file": os.path.join(REAL, "car_body_drivaer.stl"), "units": "m", "scale": 0.05,
                      "origin": "bottom-centre"}, machine="generic-3axis", step=0.75,
                stock={"type": "box", "margin": 0.0, "top": 2.0}, operations=[CLEAR, SEMI] + FINISH),
}


def run(name, spec):
    from meshmill import api
    from meshmill.job import Job, Operation

    part = api.load_part(**{k if k != "file" else "path": v for k, v in spec["part"].items()})
    tools = api.load_tools(os.path.join(DATA, "tools.toml"))
    ops = [Operation.from_dict(o, k + 1) for k, o in enumerate(spec["operations"])]
    job = Job(part=part, tools=tools, operations=ops, stock=api.Stock.from_dict(spec["stock"]), machine=spec["machine"],
              step=spec["step"], name=name)
    t = time.perf_counter()
    res = job.run(progress=lambda s: print(f"  [{time.perf_counter() - t:7.1f} s] {s}", flush=True))
    wall = time.perf_counter() - t
    left, arrays = res.summary["left"], res.left
    area, e, reason = arrays["area"], arrays["e"], arrays["reason"]
    names = left["reasons"]
    reachable = np.isin(reason, [names.index(n) for n in ("within tolerance", "gouged", "left by the job",
                                                          "a tool the job does not use")])

    def share(tol, where):
        a = area[where]
        return float(a[np.abs(e[where]) <= tol].sum() / a.sum()) if a.sum() else 0.0

    finishing = [o for o in res.operations if not o.skipped and o.operation.kind in ("steep-shallow", "finish")]
    nc = res.summary["non_cutting"]
    row = {"part": name, "ok": res.ok,
           "within_0.01": round(share(0.01, np.isfinite(e) | True), 4),
           "within_0.02": round(share(0.02, np.isfinite(e) | True), 4),
           "reachable_within_0.01": round(share(0.01, reachable), 4),
           "reachable_within_0.02": round(share(0.02, reachable), 4),
           "reachable_mm2": round(left["reachable_mm2"], 1), "area_mm2": round(left["area_mm2"], 1),
           "machining_min": round(res.summary["machining_s"] / 60, 1),
           "non_cutting_share": round(nc["share"], 3), "tool_change_share": round(nc["tool_change_share"], 4),
           "finishing_wall_s": round(sum(o.path.summary["job"]["seconds"]["operation"] for o in finishing), 1),
           "job_wall_s": round(wall, 1)}
    reasons = {"part": name, **{k: round(v, 1) for k, v in left["by_reason_mm2"].items()}}
    ops = [{"part": name, "operation": o.operation.name, "skipped": bool(o.skipped),
            **({} if o.skipped else {
                "machining_min": round(o.path.summary["job"]["machining_s"] / 60, 2),
                "non_cutting_share": round(o.path.summary["job"]["non_cutting"]["share"], 3),
                "air_share": round(o.path.summary["job"]["cutting_mm"]["air_share"], 3),
                "op_s": o.path.summary["job"]["seconds"]["operation"]})} for o in res.operations]
    return row, reasons, ops


def table(rows):
    keys = list(dict.fromkeys(k for r in rows for k in r))
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(str(r.get(k, "")) for k in keys) + " |" for r in rows]
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(PARTS))
    a = ap.parse_args()
    rows, reasons, ops = [], [], []
    for name in a.parts.split(","):
        print(name, flush=True)
        r, why, o = run(name, PARTS[name])
        rows.append(r)
        reasons.append(why)
        ops += o
        print(table([r]), "\n", table([why]), "\n", table(o), "\n", flush=True)
    print(table(rows), "\n\n", table(reasons), "\n\n", table(ops))
    os.makedirs(os.path.join(HERE, "out"), exist_ok=True)
    with open(os.path.join(HERE, "out", "finished.json"), "w") as fh:
        json.dump({"jobs": rows, "left_mm2": reasons, "operations": ops}, fh, indent=2)


if __name__ == "__main__":
    main()
