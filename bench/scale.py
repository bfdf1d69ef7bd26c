"""The heavy operations on a Dask cluster against one process, on this machine (issue 21).

    .venv/bin/python bench/scale.py               # about 3 minutes on 2 cores
    .venv/bin/python bench/scale.py --step 0.05 --finish-step 0.05 --only simulate,finish --repeat 1
                                                  # the issue's sizes, about 15 minutes

Per operation: one process (no Dask), a LocalCluster of 1 worker x 2 threads and one of 2
workers x 1 thread (started before the clock; its start-up is given apart): wall seconds (best
of ``--repeat``), the overhead against one process, and whether the result is the one
process's (tool path tips, report or summary, dexel model). Operations: ``simulate`` of the
100 000-move 5-axis ball path over the wavy 60 x 60 mm part (seed 000's goal job,
``bench/dexel_seed_tables.py``) at ``--step``, ``dexel`` of that part, ``verify`` of the same path,
``raster`` of the vase (B4, stepover 0.25, sample 0.1), ``finish`` (Tableau 7's row at
``--finish-step``: the vase, its six balls, bench/finish_tableau7.py). ``simulate`` on a cluster
keeps every block of lines on its worker and gathers only figures (and here the mesh and the
ends' deviations, compared too). Prints a table and writes bench/out/scale.json (or ``--out``).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "src"))
sys.path.insert(0, HERE)


def best(fn, repeat):
    out, times = None, []
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main():
    import numpy as np
    from distributed import Client, LocalCluster

    from dexel_seed_tables import sim_job
    from finish_tableau7 import TOOL_TABLE, params_for
    from meshmill import api
    from meshmill.cluster import worker_env
    from meshmill.geometry.shapes import vase as vase_shape
    from meshmill.ops.finish import finish as finish_op
    from meshmill.tools.table import tool_from_entry

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=float, default=0.2, help="dexel step of simulate and dexel, mm (0.2)")
    ap.add_argument("--finish-step", type=float, default=0.5, help="step-down of the finish row, mm (0.5)")
    ap.add_argument("--only", default="simulate,dexel,verify,raster,finish", help="operations, comma list")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(HERE, "out", "scale.json"))
    a = ap.parse_args()
    finish_tools = [tool_from_entry(e, k + 1, "bench tool table") for k, e in enumerate(TOOL_TABLE)]
    model1 = vase_shape()
    design, tp, tools = sim_job(60.0, 100_000, 3.0)
    vase = api.load_part(os.path.join(ROOT, "src", "meshmill", "data", "vase.stl"))
    table = api.load_tools(os.path.join(ROOT, "src", "meshmill", "data", "tools.toml"))

    stages = {}

    def simulate(cluster, warm=False):
        r = api.simulate(design, tp, tools, step=1.0 if warm else a.step, device="cpu", cluster=cluster)
        stages["cluster" if cluster else "one_process"] = {
            "seconds": r.summary.pop("seconds"), "lines": r.summary["lattice"]["lines"],
            "machined_dexels": r.summary["lattice"]["dexels"], "ends_measured": r.deviation["samples"],
            "pieces_cut": r.summary["pieces_cut"]}
        return [r.summary, r.deviation, *r.machined, r.samples["points"], r.samples["e"]]

    def finish(cluster, warm=False):
        path, summary, _ = finish_op(model1, finish_tools, params_for(5.0 if warm else a.finish_step), cluster=cluster)
        return [path.tip, path.axis, summary["verify"]]

    def dexel(cluster, warm=False):
        m = api.dexel(design, step=a.step, device="cpu", cluster=cluster).model
        return [np.concatenate([m.iv[d].ravel() for d in range(3)]), [m.start[d] for d in range(3)]]

    def verify(cluster, warm=False):
        return api.verify(design, tp, tools, device="cpu", cluster=cluster).report

    def raster(cluster, warm=False):
        return api.raster(vase, table, tool="B4", stepover=0.25, sample=0.1, device="cpu", cluster=cluster).toolpath.tip

    def same(x, y):
        if isinstance(x, np.ndarray):
            return np.array_equal(x, y)
        if isinstance(x, list):
            return all(same(p, q) for p, q in zip(x, y))
        return x == y

    ops = {name: fn for name, fn in (("simulate", simulate), ("dexel", dexel), ("verify", verify), ("raster", raster),
                                     ("finish", finish)) if name in a.only.split(",")}
    for fn in ops.values():  # compile and load everything once (simulate and finish on small sizes)
        fn(None, warm=True)
    rows = []
    base = {name: best(lambda: fn(None), a.repeat) for name, fn in ops.items()}
    for workers, threads in ((1, 2), (2, 1)):
        t = time.perf_counter()
        with LocalCluster(n_workers=workers, threads_per_worker=threads, processes=True, dashboard_address=None,
                          env=worker_env(workers * threads)) as lc, \
                Client(lc) as client:
            start_s = time.perf_counter() - t
            for name, fn in ops.items():
                fn(client, warm=True)  # the workers compile / load once
                s, out = best(lambda: fn(client), a.repeat)
                rows.append({"operation": name, "cluster": f"{workers} x {threads}", "one_process_s": round(base[name][0], 2),
                             "cluster_s": round(s, 2), "overhead": round(s / base[name][0] - 1.0, 3),
                             "same_result": bool(same(base[name][1], out)), "cluster_start_s": round(start_s, 2)})
                print(rows[-1], flush=True)
    keys = list(rows[0])
    print("| " + " | ".join(keys) + " |\n|" + "---|" * len(keys))
    for r in rows:
        print("| " + " | ".join(str(r[k]) for k in keys) + " |")
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    with open(a.out, "w") as fh:
        json.dump({"step": a.step, "finish_step": a.finish_step, "moves": len(tp), "rows": rows,
                   "simulate_stages": stages}, fh, indent=2)


if __name__ == "__main__":
    main()
