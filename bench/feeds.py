"""The load of every move and feeds optimised on it (issue 37's measures).

    .venv/bin/python bench/feeds.py                          # vase (the demo job), dolphin, terrain
    .venv/bin/python bench/feeds.py --parts vase --materials steel-p20

Each part's job (the demo job; the dolphin mould and terrain jobs of bench/job.py) runs once per
workpiece material with the tool table's cutting data (src/meshmill/data/tools.toml: its own
values for aluminium, [[tools.cutting]] for P20), every operation cut from the in-process stock
and its moves' load measured there. Three sets of feeds are then compared on the same load
(chip and power scale with the feed):

- ``table``: each tool's feed from its cutting data (fz x flutes x rpm, plunge and ramp feeds);
- ``constant``: per tool the one feed that keeps every one of its moves within the chip load,
  the spindle's power and torque (the best a constant feed can do within the limits);
- ``optimised``: :func:`meshmill.optimised_feeds` (chip at the tool's fz, power under the
  spindle's, air at the machine's largest feed).

Per part and material: the moves over a limit (the tool's section ap x ae: feeds cannot mend
it; chip, power), the largest chip and power, and the machining time of each set on the job's
machine. Prints a table and writes bench/out/feeds.json.
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

from job import DATA, PARTS  # noqa: E402  (the jobs of bench/job.py)

MATERIALS = ("aluminium-6061", "steel-p20")


def _job(name, material):
    import meshmill

    if name == "vase":
        job = meshmill.Job.from_toml(os.path.join(DATA, "vase-job.toml"))
    else:
        spec = PARTS[name]
        part = meshmill.load_part(spec["part"]["file"], **{k: v for k, v in spec["part"].items() if k != "file"})
        job = meshmill.Job(part=part, tools=os.path.join(DATA, "tools.toml"), operations=spec["operations"],
                           stock=meshmill.Stock.from_dict(spec["stock"]), machine=spec["machine"], step=spec["step"],
                           name=name)
    job.material, job.feeds = material, "table"
    return job


def _constant(tp, load, cond, spindle):
    """Per tool the one feed within every move's chip, power and torque limits, (k,) mm/min."""
    out = np.array(load.feed, float)
    with np.errstate(invalid="ignore", divide="ignore"):
        caps = [np.where(np.isfinite(load.chip_max) & (load.chip_max > 0),
                         load.feed * np.array([c.fz or np.inf for c in cond])[tp.tool] / load.chip_max, np.inf)]
        if spindle.power_kw:
            caps.append(np.where(load.power > 0, load.feed * spindle.power_kw / load.power, np.inf))
        if spindle.torque_nm:
            caps.append(np.where(load.torque > 0, load.feed * spindle.torque_nm / load.torque, np.inf))
    cap = np.minimum.reduce(caps)
    for t in np.unique(tp.tool):
        mine = (tp.tool == t) & ~tp.rapid & np.isfinite(out)
        cut = mine & load.in_material & ~load.plunge
        if cut.any():
            scale = min(1.0, float(np.min(cap[cut] / load.feed[cut])))
            side = mine & ~load.plunge
            out[side] = out[side] * scale
    return out


def _over(load, new, cond, spindle, tp):
    """Moves over each limit with the feeds ``new`` (chip, power and torque scale with the feed),
    the largest chip over fz and the largest power."""
    from dataclasses import replace

    from meshmill.simulation.load import limits_of, over_limits

    ratio = np.where(np.isfinite(load.feed) & (load.feed > 0), new / load.feed, 1.0)
    fed = replace(load, chip_max=load.chip_max * ratio, power=load.power * ratio, torque=load.torque * ratio,
                  feed=new)
    over = over_limits(fed, limits_of(tp, cond, spindle, fed))
    fz = np.array([c.fz if c.known else np.nan for c in cond])[tp.tool]
    m = load.in_material
    with np.errstate(invalid="ignore"):
        return {**{k: int(v.sum()) for k, v in over.items()},
                "chip_max": float(np.nanmax(fed.chip_max[m] / fz[m])) if m.any() else 0.0,
                "power_max_kw": float(np.nanmax(fed.power[m])) if m.any() and np.isfinite(fed.power[m]).any() else 0.0}


def run(name, material):
    import meshmill
    from meshmill.toolpath.model import Toolpath
    from meshmill.tools.cutting import conditions

    job = _job(name, material)
    t0 = time.perf_counter()
    res = job.run()
    wall = time.perf_counter() - t0
    machine = job.machine
    spindle = machine.spindle
    rows = {k: {"s": 0.0, "section": 0, "chip": 0, "plunge": 0, "power": 0, "torque": 0, "chip_max": 0.0,
                "power_max_kw": 0.0}
            for k in ("table", "constant", "optimised")}
    for op in res.operations:
        if op.skipped or op.cut.load is None:
            continue
        tp, load = op.path.toolpath, op.cut.load
        cond = conditions(job.tools, material, spindle)
        feeds = {"table": np.array(load.feed, float), "constant": _constant(tp, load, cond, spindle),
                 "optimised": meshmill.optimised_feeds(tp, load, job.tools, material, machine)}
        for k, f in feeds.items():
            f = np.where(tp.rapid, np.nan, f)
            path = Toolpath(tp.tip, tp.axis, tp.rapid, tp.tool, tp.line, f)
            rows[k]["s"] += meshmill.machining_time(path, machine, job.tools).summary["total"]["total_s"]
            over = _over(load, f, cond, spindle, tp)
            for key in ("section", "chip", "plunge", "power", "torque"):
                rows[k][key] += over[key]
            rows[k]["chip_max"] = max(rows[k]["chip_max"], over["chip_max"])
            rows[k]["power_max_kw"] = max(rows[k]["power_max_kw"], over["power_max_kw"])
    return {"part": name, "material": material, "machine": machine.name, "job_s": round(wall, 1),
            "operations": len(res.operations), **{k: {kk: round(v, 4) if isinstance(v, float) else v
                                                     for kk, v in r.items()} for k, r in rows.items()}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--parts", nargs="+", default=["vase", "dolphin", "terrain"])
    ap.add_argument("--materials", nargs="+", default=list(MATERIALS))
    ap.add_argument("--out", default=os.path.join(HERE, "out", "feeds.json"))
    args = ap.parse_args()
    rows = []
    print(f"{'part':<9}{'material':<16}{'feeds':<11}{'time s':>9}{'section>':>9}{'chip>':>7}{'power>':>8}"
          f"{'chip/fz':>9}{'kW':>7}")
    for name in args.parts:
        for material in args.materials:
            r = run(name, material)
            rows.append(r)
            for k in ("table", "constant", "optimised"):
                e = r[k]
                print(f"{name:<9}{material:<16}{k:<11}{e['s']:>9.0f}{e['section']:>9}{e['chip']:>7}"
                      f"{e['power']:>8}{e['chip_max']:>9.2f}{e['power_max_kw']:>7.2f}", flush=True)
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump({"machine": os.uname().nodename, "cpus": os.cpu_count(), "rows": rows}, fh, indent=1)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
