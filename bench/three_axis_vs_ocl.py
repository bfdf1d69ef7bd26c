"""3-axis kernels against OpenCAMLib, same machine, same run, same thread count.

Drop-cutter: CL points per second on a grid over each part (default 1000 x 1000), ours
(``meshmill.kernels.cpu.drop_cutter``) against OpenCAMLib's ``BatchDropCutter``, for flat, ball and
bull-nose cutters, with the largest height difference between the two.

Waterline: seconds per Z level, ours (``meshmill.ops.waterline.waterline``, the whole operation:
bounds, grid, loops, refinement and the verification of the path) against ``Waterline`` and
``AdaptiveWaterline`` at sampling = span/500, over 10 levels and for a single level; the loops'
quality (how deep the ball enters the part at the points and along the chords, exact distances);
and the loop counts at levels lying exactly on flat facets.

    .venv/bin/python bench/three_axis_vs_ocl.py [--grid 1000] [--parts ...] [--wl-parts ...] [--flat part:z:z]

(an empty ``--parts`` / ``--wl-parts`` / ``--flat`` skips that part of the run)
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

from meshmill.kernels.bvh import build_bvh
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


B6 = tool_from_entry(dict(name="B6", type="ball", diameter=6, flute_length=30, gauge_length=30), 1, "bench")


def ocl_loops(cls, surf, cutter, z, sampling):
    """OpenCAMLib's ``Waterline`` or ``AdaptiveWaterline`` (min sampling a tenth) loops at z."""
    wl = cls()
    wl.setSTL(surf)
    wl.setCutter(cutter)
    wl.setZ(float(z))
    wl.setSampling(sampling)
    if cls is ocl.AdaptiveWaterline:
        wl.setMinSampling(sampling / 10)
    wl.run()
    return wl.getLoops()


def bench_drop(part, n):
    path = os.path.join(PARTS, part + ".stl")
    mesh = load_mesh(path, flip=os.path.basename(str(path)) == "beet_mm.stl")  # beet_mm is wound inside out
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
    mesh = load_mesh(path, flip=os.path.basename(str(path)) == "beet_mm.stl")  # beet_mm is wound inside out
    surf = ocl_surface(path)
    lo, hi = mesh.bounds
    sampling = float((hi[:2] - lo[:2]).max() / 500)
    step = float((hi[2] - lo[2]) / (levels + 1))
    zs = hi[2] - step * np.arange(1, levels + 1)
    tools = [B6]
    one = WaterlineParams(step_down=float(hi[2] - lo[2]) * 0.6, sample=sampling)  # a single level, at z_one
    z_one = float(hi[2] - one.step_down)
    waterline(mesh, tools, "B6", one)  # compiled (or loaded from numba's cache) before timing
    t = time.perf_counter()
    waterline(mesh, tools, "B6", one)
    t_one = time.perf_counter() - t
    t = time.perf_counter()
    _, s_all, passes = waterline(mesh, tools, "B6", WaterlineParams(step_down=step, sample=sampling))
    t_all = time.perf_counter() - t
    res = {}
    cutter = ocl.BallCutter(6.0, 30.0)  # kept alive: OpenCAMLib holds a bare pointer to it

    def run_ocl(cls, z):
        return ocl_loops(cls, surf, cutter, z, sampling)

    bvh = build_bvh(mesh.vertices, mesh.faces)

    def quality(loops):
        """For the points of ``loops [(z, (k, 2+))]`` (tool tips at level z, each loop closed): the deepest
        the ball enters the part at a point and along the chords between points (sampled at eighths;
        mm, exact distance from its centre to the mesh), and the share of points where it stays more
        than 1 µm away (the loop does not touch the part there)."""
        def centres(z, xy):
            return np.column_stack([xy, np.full(len(xy), z + 3.0)])

        pts = np.vstack([centres(z, p[:, :2]) for z, p in loops])
        frac = np.arange(1, 8) / 8.0
        chords = []
        for z, p in loops:
            a = p[:, :2]
            b = np.roll(a, -1, axis=0)
            chords.append(centres(z, (a[:, None, :] + frac[None, :, None] * (b - a)[:, None, :]).reshape(-1, 2)))
        d = cpu.mesh_distances(pts, bvh.arrays)
        dc = cpu.mesh_distances(np.vstack(chords), bvh.arrays)
        return dict(points=len(d), max_gouge=float(max(0.0, 3.0 - d.min())),
                    max_chord_gouge=float(max(0.0, 3.0 - dc.min())), not_touching=float(np.mean(d > 3.0 + 1e-3)))

    for name, cls in (("Waterline", ocl.Waterline), ("AdaptiveWaterline", ocl.AdaptiveWaterline)):
        t = time.perf_counter()
        got = [run_ocl(cls, z) for z in zs]
        seconds = (time.perf_counter() - t) / len(zs)
        loops = [g for level in got for g in level]
        pts = [(z, np.array([[q.x, q.y] for q in g])) for z, level in zip(zs, got) for g in level if len(g)]
        res[name] = dict(seconds_per_level=seconds, loops=len(loops), loops_under_5_points=sum(len(g) < 5 for g in loops),
                         **quality(pts))
    t = time.perf_counter()
    run_ocl(ocl.Waterline, z_one)
    res["Waterline"]["one_level_s"] = time.perf_counter() - t
    row = dict(part=part, sampling=sampling, levels=int(s_all["levels"]), z_one=z_one, ours_one_level_s=t_one,
               ours_quality=quality(passes),
               ours_per_level_s=t_all / s_all["levels"], ours_passes=s_all["passes"],
               ours_closed_loops=s_all["closed_loops"], ours_verify_ok=s_all["verify"]["ok"],
               ours_seconds=s_all["seconds"], grid=s_all["grid"], grid_points_dropped=s_all["grid_points_dropped"],
               ocl=res)
    row["ratio_waterline"] = res["Waterline"]["seconds_per_level"] / row["ours_per_level_s"]
    row["ratio_adaptive"] = res["AdaptiveWaterline"]["seconds_per_level"] / row["ours_per_level_s"]
    row["ratio_one_level"] = res["Waterline"]["one_level_s"] / t_one
    print(f"  waterline {part:14s}: ours {row['ours_per_level_s']:.3f} s/level ({t_one:.3f} s for one), "
          f"Waterline {res['Waterline']['seconds_per_level']:.3f} ({res['Waterline']['one_level_s']:.3f} for one), Adaptive "
          f"{res['AdaptiveWaterline']['seconds_per_level']:.3f}", file=sys.stderr)
    return row


def bench_flat_levels(part, levels):
    """Loop counts at levels that lie exactly on flat facets of the part: ours and ``Waterline``'s."""
    path = os.path.join(PARTS, part + ".stl")
    mesh = load_mesh(path, flip=os.path.basename(str(path)) == "beet_mm.stl")  # beet_mm is wound inside out
    surf = ocl_surface(path)
    sampling = float((mesh.bounds[1, :2] - mesh.bounds[0, :2]).max() / 500)
    cutter = ocl.BallCutter(6.0, 30.0)  # kept alive: OpenCAMLib holds a bare pointer to it
    rows = []
    for z in levels:
        theirs = ocl_loops(ocl.Waterline, surf, cutter, z, sampling)
        _, _, passes = waterline(mesh, [B6], "B6", WaterlineParams(step_down=float(mesh.bounds[1, 2] - z), sample=sampling))
        rows.append(dict(part=part, z=z, ours=sum(1 for zz, _ in passes if zz == z), ocl=len(theirs),
                         ocl_under_5_points=sum(len(g) < 5 for g in theirs)))
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--grid", type=int, default=1000)
    ap.add_argument("--parts", default="pycam-textbox,beet_mm,mount_rush")
    ap.add_argument("--wl-parts", default="pycam-textbox,beet_mm,mount_rush,sphere_on_plate")
    ap.add_argument("--levels", type=int, default=10)
    ap.add_argument("--flat", default="pycam-textbox:-5:-2.05", help="part:z:z... levels on flat facets")
    ap.add_argument("--out", default=os.path.join("bench", "out", "three_axis_vs_ocl.json"))
    a = ap.parse_args()
    threads = numba.get_num_threads()
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs, numba threads {threads}, "
          f"OpenCAMLib threads {ocl.max_threads()}", file=sys.stderr)
    drop = [r for p in a.parts.split(",") if p for r in bench_drop(p, a.grid)]
    wl = [bench_waterline(p, a.levels) for p in a.wl_parts.split(",") if p]
    part, *zs = a.flat.split(":") if a.flat else [None]
    flat = bench_flat_levels(part, [float(z) for z in zs]) if part else []
    print(f"\n### Drop-cutter, {a.grid} x {a.grid} grid over each part, diameter 6 mm cutters\n")
    print("| part | cutter | ours CL pts/s | OpenCAMLib pts/s | ratio | max abs dz (mm) |")
    print("|---|---|---:|---:|---:|---:|")
    for r in drop:
        print(f"| {r['part']} | {r['cutter']} | {r['ours_pts_per_s']:,.0f} | {r['ocl_pts_per_s']:,.0f} | "
              f"{r['ratio']:.1f}x | {r['max_abs_diff']:.1e} |")
    print(f"\n### Waterline, ball 6 mm, sampling span/500, {a.levels} levels\n")
    print("| part | sampling (mm) | ours s/level | Waterline s/level | AdaptiveWaterline s/level | ratio vs Waterline "
          "| ratio vs Adaptive | one level: ours s | one level: Waterline s | ratio | our passes (closed) "
          "| OCL loops (< 5 points) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in wl:
        o = r["ocl"]
        print(f"| {r['part']} | {r['sampling']:.3f} | {r['ours_per_level_s']:.3f} | "
              f"{o['Waterline']['seconds_per_level']:.3f} | {o['AdaptiveWaterline']['seconds_per_level']:.3f} | "
              f"{r['ratio_waterline']:.1f}x | {r['ratio_adaptive']:.1f}x | {r['ours_one_level_s']:.3f} | "
              f"{o['Waterline']['one_level_s']:.3f} | {r['ratio_one_level']:.1f}x | "
              f"{r['ours_passes']} ({r['ours_closed_loops']}) | {o['Waterline']['loops']} "
              f"({o['Waterline']['loops_under_5_points']}) |")
    print("\nLoop quality, all levels: how deep the ball enters the part at a loop point (exact distance from its "
          "centre to the mesh) and along the chords between them, and the share of points where it stays more "
          "than 1 µm away:\n")
    print("| part | ours: points | gouge at points / chords (mm) | not touching | Waterline: points "
          "| gouge at points / chords (mm) | not touching | Adaptive: points | gouge at points / chords (mm) | not touching |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for r in wl:
        cells = [r["ours_quality"], r["ocl"]["Waterline"], r["ocl"]["AdaptiveWaterline"]]
        print(f"| {r['part']} | " + " | ".join(f"{c['points']} | {c['max_gouge']:.1e} / {c['max_chord_gouge']:.1e} | {100 * c['not_touching']:.1f}%"
                                             for c in cells) + " |")
    print("\nLevels exactly on flat facets (the tool at z rests on them):\n")
    print("| part | z (mm) | our loops | Waterline loops (< 5 points) |")
    print("|---|---:|---:|---:|")
    for r in flat:
        print(f"| {r['part']} | {r['z']:g} | {r['ours']} | {r['ocl']} ({r['ocl_under_5_points']}) |")
    os.makedirs(os.path.dirname(a.out), exist_ok=True)
    with open(a.out, "w") as fh:
        json.dump(dict(date=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                       machine=dict(cpus=os.cpu_count(), numba_threads=threads, ocl_threads=ocl.max_threads(),
                                    python=platform.python_version(), numba=numba.__version__,
                                    numpy=np.__version__, opencamlib=getattr(ocl, "version", lambda: "?")()),
                       drop=drop, waterline=wl, flat_levels=flat), fh, indent=2)
    print(f"\nJSON written to {a.out}")


if __name__ == "__main__":
    main()
