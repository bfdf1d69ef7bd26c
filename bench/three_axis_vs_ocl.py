"""3-axis kernels against OpenCAMLib, same machine, same run, same thread count.

Drop-cutter: CL points per second on a grid over each part (default 1000 x 1000), ours
(``meshmill.kernels.cpu.drop_cutter``) against OpenCAMLib's ``BatchDropCutter``, for flat, ball and
bull-nose cutters, with the largest height difference between the two.

Waterline: seconds per Z level, ours (``meshmill.ops.waterline.waterline``, which computes one
drop-cutter grid for all levels, refines and verifies) against ``Waterline`` and
``AdaptiveWaterline`` at sampling = span/500, for one level and for all levels of a step-down.

    .venv/bin/python bench/three_axis_vs_ocl.py [--grid 1000] [--parts pycam-textbox,beet_mm,mount_rush]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time

import numba
import numpy as np

from meshmill.geometry.bvh import build_bvh
from meshmill.geometry.mesh import load_mesh
from meshmill.kernels import cpu
from meshmill.ops.waterline import WaterlineParams, waterline
from meshmill.tools.table import tool_from_entry

# numba's OpenMP threads must start before OpenCAMLib loads its own libgomp, or the process crashes
cpu.drop_cutter(np.zeros((4, 2)), 1.0, 0.0, 0.0, build_bvh(np.eye(3), np.array([[0, 1, 2]])).arrays)
import opencamlib as ocl  # noqa: E402

PARTS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "parts")
CUTTERS = {  # diameter 6 mm, bull corner radius 1 mm, 30 mm long
    "flat": (3.0, 0.0, lambda: ocl.CylCutter(6.0, 30.0)),
    "ball": (3.0, 3.0, lambda: ocl.BallCutter(6.0, 30.0)),
    "bull": (3.0, 1.0, lambda: ocl.BullCutter(6.0, 1.0, 30.0)),
}


def ocl_surface(path):
    s = ocl.STLSurf()
    ocl.STLReader(path, s)
    return s


def bench_drop(part, n):
    path = os.path.join(PARTS, part + ".stl")
    mesh = load_mesh(path)
    bvh = build_bvh(mesh.vertices, mesh.faces)
    surf = ocl_surface(path)
    lo, hi = mesh.bounds
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n), indexing="ij")
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    floor = float(lo[2] - 10)
    rows = []
    for kind, (R, r, make) in CUTTERS.items():
        cpu.drop_cutter(xy[:100], R, r, floor, bvh.arrays)  # compiled before timing
        t = time.perf_counter()
        ours, _ = cpu.drop_cutter(xy, R, r, floor, bvh.arrays)
        t_ours = time.perf_counter() - t
        cutter = make()  # OpenCAMLib keeps a bare pointer: the object must outlive the run
        bdc = ocl.BatchDropCutter()
        bdc.setSTL(surf)
        bdc.setCutter(cutter)
        for x, y in xy:
            bdc.appendPoint(ocl.CLPoint(float(x), float(y), floor))
        t = time.perf_counter()
        bdc.run()
        t_ocl = time.perf_counter() - t
        theirs = np.array([p.z for p in bdc.getCLPoints()])
        rows.append(dict(part=part, cutter=kind, points=len(xy), ours_s=t_ours, ocl_s=t_ocl,
                         ours_pts_per_s=len(xy) / t_ours, ocl_pts_per_s=len(xy) / t_ocl, ratio=t_ocl / t_ours,
                         max_abs_diff=float(np.abs(ours - theirs).max())))
        print(f"  drop {part:14s} {kind:4s}: ours {len(xy) / t_ours:10.0f}/s, OCL {len(xy) / t_ocl:9.0f}/s, "
              f"{t_ocl / t_ours:5.1f}x, max |dz| {rows[-1]['max_abs_diff']:.2e} mm", file=sys.stderr)
    return rows


def bench_waterline(part, levels):
    path = os.path.join(PARTS, part + ".stl")
    mesh = load_mesh(path)
    surf = ocl_surface(path)
    lo, hi = mesh.bounds
    sampling = float((hi[:2] - lo[:2]).max() / 500)
    step = float((hi[2] - lo[2]) / (levels + 1))
    zs = hi[2] - step * np.arange(1, levels + 1)
    tools = [tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=30, gauge_length=30), 1, "b")]
    waterline(mesh, tools, "B6", WaterlineParams(step_down=float(hi[2] - lo[2]) * 0.6, sample=sampling))  # warm
    t = time.perf_counter()
    _, one, _ = waterline(mesh, tools, "B6", WaterlineParams(step_down=float(hi[2] - zs[0]), sample=sampling))
    t_one = time.perf_counter() - t
    t = time.perf_counter()
    _, s_all, passes = waterline(mesh, tools, "B6", WaterlineParams(step_down=step, sample=sampling))
    t_all = time.perf_counter() - t
    res = {}
    cutter = ocl.BallCutter(6.0, 30.0)  # kept alive: OpenCAMLib holds a bare pointer to it
    for name, cls in (("Waterline", ocl.Waterline), ("AdaptiveWaterline", ocl.AdaptiveWaterline)):
        t = time.perf_counter()
        loops = 0
        tiny = 0
        for z in zs:
            wl = cls()
            wl.setSTL(surf)
            wl.setCutter(cutter)
            wl.setZ(float(z))
            wl.setSampling(sampling)
            if name == "AdaptiveWaterline":
                wl.setMinSampling(sampling / 10)
            wl.run()
            got = wl.getLoops()
            loops += len(got)
            tiny += sum(len(g) < 5 for g in got)
        res[name] = dict(seconds_per_level=(time.perf_counter() - t) / len(zs), loops=loops, loops_under_5_points=tiny)
    row = dict(part=part, sampling=sampling, levels=int(s_all["levels"]), ours_one_level_s=t_one,
               ours_per_level_s=t_all / s_all["levels"], ours_passes=s_all["passes"],
               ours_closed_loops=s_all["closed_loops"], ours_verify_ok=s_all["verify"]["ok"],
               ours_grid_s=s_all["seconds"]["grid"], ocl=res)
    row["ratio_waterline"] = res["Waterline"]["seconds_per_level"] / row["ours_per_level_s"]
    row["ratio_adaptive"] = res["AdaptiveWaterline"]["seconds_per_level"] / row["ours_per_level_s"]
    row["ratio_one_level"] = res["Waterline"]["seconds_per_level"] / t_one
    print(f"  waterline {part:14s}: ours {row['ours_per_level_s']:.3f} s/level ({t_one:.3f} s for one), "
          f"Waterline {res['Waterline']['seconds_per_level']:.3f}, Adaptive "
          f"{res['AdaptiveWaterline']['seconds_per_level']:.3f}", file=sys.stderr)
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--grid", type=int, default=1000)
    ap.add_argument("--parts", default="pycam-textbox,beet_mm,mount_rush")
    ap.add_argument("--wl-parts", default="pycam-textbox,beet_mm,mount_rush,sphere_on_plate")
    ap.add_argument("--levels", type=int, default=10)
    ap.add_argument("--out", default=os.path.join("bench", "out", "three_axis_vs_ocl.json"))
    a = ap.parse_args()
    threads = numba.get_num_threads()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, numba threads {threads}, "
          f"OpenCAMLib threads {ocl.max_threads()}", file=sys.stderr)
    drop = [r for p in a.parts.split(",") for r in bench_drop(p, a.grid)]
    wl = [bench_waterline(p, a.levels) for p in a.wl_parts.split(",")]
    print(f"\n### Drop-cutter, {a.grid} x {a.grid} grid over each part, diameter 6 mm cutters\n")
    print("| part | cutter | ours CL pts/s | OpenCAMLib pts/s | ratio | max abs dz (mm) |")
    print("|---|---|---:|---:|---:|---:|")
    for r in drop:
        print(f"| {r['part']} | {r['cutter']} | {r['ours_pts_per_s']:,.0f} | {r['ocl_pts_per_s']:,.0f} | "
              f"{r['ratio']:.1f}x | {r['max_abs_diff']:.1e} |")
    print(f"\n### Waterline, ball 6 mm, sampling span/500, {a.levels} levels\n")
    print("| part | ours s/level (all levels) | ours s (one level) | Waterline s/level | AdaptiveWaterline s/level "
          "| ratio vs Waterline (all / one) | ratio vs Adaptive | our passes (closed) | OCL loops (< 5 points) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in wl:
        o = r["ocl"]
        print(f"| {r['part']} | {r['ours_per_level_s']:.3f} | {r['ours_one_level_s']:.3f} | "
              f"{o['Waterline']['seconds_per_level']:.3f} | {o['AdaptiveWaterline']['seconds_per_level']:.3f} | "
              f"{r['ratio_waterline']:.1f}x / {r['ratio_one_level']:.1f}x | {r['ratio_adaptive']:.1f}x | "
              f"{r['ours_passes']} ({r['ours_closed_loops']}) | {o['Waterline']['loops']} "
              f"({o['Waterline']['loops_under_5_points']}) |")
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as fh:
        json.dump(dict(date=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                       machine=dict(cpus=os.cpu_count(), numba_threads=threads, ocl_threads=ocl.max_threads(),
                                    python=platform.python_version(), numba=numba.__version__,
                                    numpy=np.__version__, opencamlib=getattr(ocl, "version", lambda: "?")()),
                       drop=drop, waterline=wl), fh, indent=2)
    print(f"\nJSON written to {a.out}")


if __name__ == "__main__":
    main()
