"""Seed 002's tables 2.x, 3.1-3.2 and 4.3-4.8 (tool choice, zoning, optimisation by machining
time), our figures beside the seed's, and the time each run takes.

Machine: the seed's (V 5 m/min, A 6 m/s², J 40 m/s³) with tool changes and re-orientations at
0 s, as the seed does not count them (``seed-002.toml`` has 8 s and 3 s). Tools: ball R 5,
bull-nose R 5 r 2; scallop 0.01 mm; 80 x 80 cells; patch meshes at 0.5 mm; drops every 0.5 mm.

- ``ch2``: Table 2.1 (56 x 28 mm plane at 60 deg): closed forms T1/T2 and our black box; the two
  test surfaces (§2.10): PCA, s_c, the rule, and the black box for both options; the s_c table.
- ``cross``: §4.7's counterexample, closed forms and our black box on the cross (mesh input).
- ``ch3``: Tables 3.1-3.2: K = 3, K-means and RPCL with the four metrics, Ward with the
  largest-jump rule; every zone along its steepest slope with the bull-nose, or along its principal
  direction with the better of ball and bull-nose.
- ``ch4``: Tables 4.3-4.6: per K, f0 (weights 1, bull-nose along each zone's steepest slope) and
  NOMAD's f* after ``--evals`` black-box evaluations (the seed: 1000), 3-axis and 3+2.
- ``heur``: Tables 4.7-4.8: the PCA 3+2 heuristic, f0 (tilt 0, feed along X_I) and f*.

    .venv/bin/python bench/choice_seed_tables.py [--sections ch2,cross,ch3,ch4,heur] [--ks 2,3,4,5,6] [--evals 20]

Prints markdown tables and writes ``bench/out/choice_seed_tables.json``.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import math
import os
import time

import numpy as np

from finish_tableau7 import git_commit, machine
from meshmill.choice.machining import ZonePlan
from meshmill.choice.optimise import optimise_plan
from meshmill.choice.orientation import azimuth_in_frame, heuristic_axis
from meshmill.choice.rectangle import (choose_tool, length_ball_principal, length_toric_steepest,
                                       parallel_passes_length, parallel_passes_time, pca_rectangle,
                                       critical_slope, time_ball_principal, time_toric_steepest)
from meshmill.pathing.scallop import stepover
from meshmill.geometry.patches import bezier, cell_samples, load_patch, mesh_samples, mesh_surface, patch_mesh
from meshmill.pathing.zigzag import frame_rotation
from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.machine.config import load_machine
from meshmill.ops.choose import ChooseParams, Chooser, tool_pair, zone_ids

HERE = os.path.dirname(os.path.abspath(__file__))
BALL, BULL = tool_pair("10,2")
SH = 0.01
SURFACES = ("choi", "rubio")  # Ch.4's surface 1 and surface 2
SEED_CH2 = {"rubio": {"bull": (91.3, 5606), "ball": (79.7, 5687), "s_c": 38.9, "slope": 42.34},
            "choi": {"bull": (71.8, 4725), "ball": (76.8, 5184), "s_c": 62.6, "slope": 17.13}}
# Tables 3.1, 3.2: (direction, metric) -> (K-means s, mm, RPCL s, mm); Ward: direction -> (s, mm)
SEED_CH3 = {
    "choi": {("steepest", "euclidean"): (104.7, 4763, 98.7, 4861), ("steepest", "pca"): (96.2, 4919, 95.8, 5495),
             ("steepest", "mahalanobis"): (125.2, 6179, 105.9, 5777), ("steepest", "std"): (100.1, 4800, 101.2, 4780),
             ("principal", "euclidean"): (107.8, 6230, 102.2, 6333), ("principal", "pca"): (106.5, 6190, 110.9, 6356),
             ("principal", "mahalanobis"): (108.0, 6593, 104.1, 6652), ("principal", "std"): (111.1, 6426, 110.7, 6447),
             "ward": {"steepest": (117.1, 4454), "principal": (136.8, 6302)}},
    "rubio": {("steepest", "euclidean"): (91.6, 4634, 97.0, 4726), ("steepest", "pca"): (91.5, 4626, 91.7, 4593),
              ("steepest", "mahalanobis"): (88.7, 4935, 99.8, 6277), ("steepest", "std"): (91.5, 4612, 94.3, 4966),
              ("principal", "euclidean"): (84.3, 5881, 90.7, 5940), ("principal", "pca"): (84.3, 5889, 84.1, 5869),
              ("principal", "mahalanobis"): (89.0, 5519, 85.7, 5874), ("principal", "std"): (83.0, 5808, 90.1, 6009),
              "ward": {"steepest": (96.2, 4630), "principal": (85.3, 5850)}},
}
# Tables 4.3-4.6: K -> (f0, f* no surrogate, f* S3); 4.7-4.8: K -> (f0, f*)
SEED_CH4 = {
    ("choi", "3"): {2: (96.19, 92.01, 92.01), 3: (104.77, 93.92, 92.92), 4: (147.68, 98.5, 95.92), 5: (101.90, 96.41, 96.23),
                    6: (100.1, 95.96, 98.41), 7: (103.78, 102.02, 100.06), 8: (102.4, 95.48, 91.93), 9: (153.5, 102.7, 95.29),
                    10: (143.9, 97.25, 97.91)},
    ("rubio", "3"): {2: (91.54, 90.91, 90.82), 3: (91.62, 86.83, 90.77), 4: (103.53, 78.86, 78.86), 5: (96.75, 90.06, 87.26),
                     6: (102.8, 88.49, 90.03), 7: (106.1, 89.05, 86.89), 8: (108.55, 93.61, 86.52), 9: (108.23, 88.39, 86.75),
                     10: (116.11, 88.11, 90.97)},
    ("choi", "3+2"): {2: (96.19, 85.46, 85.68), 3: (104.77, 97.24, 83.59), 4: (147.68, 100.11, 100.14), 5: (101.90, 98.42, 96.2),
                      6: (100.1, 97.19, 97.41), 7: (103.78, 96.00, 97.8), 8: (102.4, 93.48, 94.36), 9: (153.5, 108.54, 91.93),
                      10: (143.9, 99.70, 96.09)},
    ("rubio", "3+2"): {2: (91.54, 75.67, 74.96), 3: (91.62, 77.23, 73.84), 4: (103.53, 79.94, 71.95), 5: (96.75, 83.67, 82.01),
                       6: (102.8, 86.46, 85.43), 7: (106.1, 91.29, 82.23), 8: (108.55, 93.65, 84.03), 9: (108.23, 91.28, 93.91),
                       10: (116.11, 98.76, 92.04)},
}
SEED_HEUR = {"choi": {2: (121.24, 77.71), 3: (117.51, 83.15), 4: (93.49, 87.68), 5: (94.32, 84.98), 6: (91.5, 83.0),
                      7: (95.75, 86.57), 8: (93.64, 86.0), 9: (99.47, 92.61), 10: (98.47, 91.98)},
             "rubio": {2: (69.96, 65.78), 3: (65.38, 62.65), 4: (107.82, 66.11), 5: (70.83, 63.39), 6: (86.70, 64.24),
                       7: (100.74, 62.64), 8: (84.86, 60.7), 9: (101.86, 59.58), 10: (112.98, 61.34)}}


def seed_machine():
    return dataclasses.replace(load_machine("seed-002"), tool_change=0.0, reorient=0.0)


def chooser(surface, tools, axes="3", cluster="kmeans", metric="euclidean", samples=None):
    params = ChooseParams(scallop=SH, axes=axes, cluster=cluster, metric=metric)
    if samples is None:
        patch = load_patch(surface)
        samples, smesh = cell_samples(patch, 80, 80), patch_mesh(patch, 0.5)
    else:
        samples, smesh = samples
    return Chooser(samples, smesh, tools, seed_machine(), params)


def one_zone(ch, tool, theta):
    zones = np.where(ch.samples.valid, 0, -1).astype(np.intp)
    r = ch.machinist.plan(zones, {0: ZonePlan(tool, theta)})
    return r.total_s, r.toolpath.cutting_length()


def ch2_rows():
    kin = seed_machine().motion
    rows = {}
    # Table 2.1: 56 mm along Y (principal), 28 mm up a 60 deg slope in XZ
    c, s = math.cos(math.radians(60)), math.sin(math.radians(60))
    plane = bezier([[[0, 0, 0], [0, 56, 0]], [[28 * c, 0, 28 * s], [28 * c, 56, 28 * s]]], "table2.1")
    ch = chooser(None, [BALL, BULL], samples=(cell_samples(plane, 80, 80), patch_mesh(plane, 0.5)))
    t = time.perf_counter()
    bull, bull_mm = one_zone(ch, 1, 0.0)
    ball, ball_mm = one_zone(ch, 0, math.pi / 2)
    rows["table2.1"] = {"analytic_bull_s": time_toric_steepest(2, 1568, math.radians(60), 5, 2, SH, kin),
                        "analytic_ball_s": time_ball_principal(2, 1568, 5, SH, kin),
                        "analytic_bull_mm": length_toric_steepest(2, 1568, math.radians(60), 5, 2, SH),
                        "analytic_ball_mm": length_ball_principal(2, 1568, 5, SH),
                        "bull_s": bull, "bull_mm": bull_mm, "ball_s": ball, "ball_mm": ball_mm,
                        "seed_bull": (43.8, 2460), "seed_ball": (36.8, 2459), "seconds": time.perf_counter() - t}
    for name in SURFACES:
        t = time.perf_counter()
        ch = chooser(name, [BALL, BULL])
        rect = pca_rectangle(ch.samples.points, ch.samples.normals)
        rule = choose_tool(rect, 5, 2, SH, kin)
        bull, bull_mm = one_zone(ch, 1, rect.steepest_azimuth)
        ball, ball_mm = one_zone(ch, 0, rect.principal_azimuth)
        rows[name] = {"lambda": rect.variances.tolist(), "mu": rect.shape_factor, "chi": rect.size,
                      "slope_deg": math.degrees(rect.plane_slope), "s_c_deg": math.degrees(rule.critical_slope),
                      "rule": rule.tool, "predicted_bull_s": rule.time_toric_steepest,
                      "predicted_ball_s": rule.time_ball_principal, "bull_s": bull, "bull_mm": bull_mm, "ball_s": ball,
                      "ball_mm": ball_mm, "black_box": "ball" if ball < bull else "toric", "seed": SEED_CH2[name],
                      "seconds": time.perf_counter() - t}
    rows["s_c_table"] = {chi: {mu: math.degrees(critical_slope(mu, chi, 5, 2, SH, kin)) for mu in (1.25, 1.5, 2, 3, 4, 6, 9)}
                         for chi in (1568, 3315, 10000)}
    return rows


def print_ch2(rows):
    r = rows["table2.1"]
    print("\n### Table 2.1: 56 x 28 mm plane at 60 deg (time s / length mm)\n")
    print("| option | closed form | ours (black box) | seed (simulated) |\n|---|---|---|---|")
    print(f"| bull-nose along the steepest slope | {r['analytic_bull_s']:.2f} / {r['analytic_bull_mm']:.0f} | "
          f"{r['bull_s']:.2f} / {r['bull_mm']:.0f} | 43.8 / 2460 |")
    print(f"| ball along the principal direction | {r['analytic_ball_s']:.2f} / {r['analytic_ball_mm']:.0f} | "
          f"{r['ball_s']:.2f} / {r['ball_mm']:.0f} | 36.8 / 2459 |")
    print("\n### §2.10 test surfaces: the rule and the black box (time s / length mm)\n")
    print("| surface | lambda I, II | mu | chi mm² | slope deg (seed) | s_c deg (seed) | rule | predicted bull / ball s | "
          "bull-nose steepest (seed) | ball principal (seed) | black box | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name in SURFACES:
        r, sd = rows[name], SEED_CH2[name]
        print(f"| {name} | {r['lambda'][0]:.2f}, {r['lambda'][1]:.2f} | {r['mu']:.3f} | {r['chi']:.0f} | "
              f"{r['slope_deg']:.2f} ({sd['slope']}) | {r['s_c_deg']:.2f} ({sd['s_c']}) | {r['rule']} | "
              f"{r['predicted_bull_s']:.1f} / {r['predicted_ball_s']:.1f} | {r['bull_s']:.1f} / {r['bull_mm']:.0f} "
              f"({sd['bull'][0]} / {sd['bull'][1]}) | {r['ball_s']:.1f} / {r['ball_mm']:.0f} ({sd['ball'][0]} / {sd['ball'][1]}) | "
              f"{r['black_box']} | {r['seconds']:.1f} |")
    print("\n### s_c (deg), closed form (notes §2.5)\n")
    mus = (1.25, 1.5, 2, 3, 4, 6, 9)
    print("| chi mm² | " + " | ".join(f"mu {m}" for m in mus) + " |\n|---|" + "---|" * len(mus))
    for chi, row in rows["s_c_table"].items():
        print(f"| {chi} | " + " | ".join(f"{row[m]:.2f}" for m in mus) + " |")


def cross_rows():
    """The cross of Fig. 4.11: bar 80 x 30, arms 10 x 40 above and below, horizontal, ball R 5."""
    kin = seed_machine().motion
    w, h, q, p = 80.0, 30.0, 10.0, 40.0
    sod = float(stepover(SH, 5.0))
    x_t = 2 * parallel_passes_time(q, p, sod, kin) + parallel_passes_time(w, h, sod, kin)
    y_t = 2 * parallel_passes_time(h, (w - q) / 2, sod, kin) + parallel_passes_time(h + 2 * p, q, sod, kin)
    split = parallel_passes_time(w, h, sod, kin) + 2 * parallel_passes_time(p, q, sod, kin)
    lengths = (2 * parallel_passes_length(q, p, sod) + parallel_passes_length(w, h, sod),
               2 * parallel_passes_length(h, (w - q) / 2, sod) + parallel_passes_length(h + 2 * p, q, sod),
               parallel_passes_length(w, h, sod) + 2 * parallel_passes_length(p, q, sod))
    # the cross as a mesh: 1 mm squares over its outline
    xs, ys = np.arange(0, w + 1), np.arange(0, h + 2 * p + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    v = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    faces = []
    ny = len(ys)
    for i in range(len(xs) - 1):
        for j in range(len(ys) - 1):
            cx, cy = i + 0.5, j + 0.5
            if p <= cy <= p + h or (w / 2 - q / 2 <= cx <= w / 2 + q / 2):
                a, b, c, d = i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1
                faces += [[a, b, c], [a, c, d]]
    mesh = mesh_from_arrays(v, np.array(faces), "cross")
    ch = chooser(None, [BALL], samples=(mesh_samples(mesh, 80, 110), mesh_surface(mesh)))
    t = time.perf_counter()
    valid = ch.samples.valid
    one = np.where(valid, 0, -1).astype(np.intp)
    along_x = ch.machinist.plan(one, {0: ZonePlan(0, 0.0)})
    along_y = ch.machinist.plan(one, {0: ZonePlan(0, math.pi / 2)})
    yy = ch.samples.points[:, 1]
    three = np.where(~valid, -1, np.where(yy < p, 1, np.where(yy > p + h, 2, 0))).astype(np.intp)
    split_r = ch.machinist.plan(three, {0: ZonePlan(0, 0.0), 1: ZonePlan(0, math.pi / 2), 2: ZonePlan(0, math.pi / 2)})
    rect = pca_rectangle(ch.samples.points[valid])
    return {"closed_form_s": [x_t, y_t, split], "closed_form_mm": list(lengths),
            "black_box_s": [along_x.total_s, along_y.total_s, split_r.total_s],
            "black_box_mm": [r.toolpath.cutting_length() for r in (along_x, along_y, split_r)],
            "seed_s": [90.4, 82.3, 74.2], "seed_mm": [5172, 5142, 5112], "variances": rect.variances[:2].tolist(),
            "seconds": time.perf_counter() - t}


def print_cross(r):
    print("\n### §4.7 cross counterexample (ball R 5, time s / length mm)\n")
    print("| strategy | closed form (notes) | ours (black box, mesh) | seed |\n|---|---|---|---|")
    for i, name in enumerate(("along X (principal)", "along Y", "3 zones: bar along X, arms along Y")):
        print(f"| {name} | {r['closed_form_s'][i]:.2f} / {r['closed_form_mm'][i]:.0f} | {r['black_box_s'][i]:.2f} / "
              f"{r['black_box_mm'][i]:.0f} | {r['seed_s'][i]} / {r['seed_mm'][i]} |")
    print(f"\nPCA of the cross's samples: Var X {r['variances'][0]:.1f}, Var Y {r['variances'][1]:.1f} mm² "
          f"(exact 402.08, 395.83); black box {r['seconds']:.1f} s")


def plan_cost(ch, zones, plans):
    r = ch.machinist.plan(zones, plans)
    return r.total_s, r.toolpath.cutting_length(), len(r.zones)


def direction_plans(ch, zones, direction):
    plans = {}
    for z in zone_ids(zones):
        principal, steepest = ch.zone_frame(zones, z)
        if direction == "steepest":
            plans[int(z)] = ZonePlan(1, steepest)
        else:
            plans[int(z)] = min((ZonePlan(t, principal) for t in (0, 1)),
                                key=lambda c: ch.machinist.zone(zones, int(z), c).time["total_s"])
    return plans


def ch3_rows():
    rows = []
    for name in SURFACES:
        patch = load_patch(name)
        shared = (cell_samples(patch, 80, 80), patch_mesh(patch, 0.5))
        for cluster in ("kmeans", "rpcl", "ward"):
            for metric in (("euclidean", "pca", "mahalanobis", "std") if cluster != "ward" else ("euclidean",)):
                ch = chooser(name, [BALL, BULL], cluster=cluster, metric=metric, samples=shared)
                t = time.perf_counter()
                zones, _ = ch.zoning(None if cluster == "ward" else 3)
                t_zone = time.perf_counter() - t
                for direction in ("steepest", "principal"):
                    t = time.perf_counter()
                    s, mm, nz = plan_cost(ch, zones, direction_plans(ch, zones, direction))
                    if cluster == "ward":
                        seed = SEED_CH3[name]["ward"][direction]
                    else:
                        seed = SEED_CH3[name][(direction, metric)][0 if cluster == "kmeans" else 2:][:2]
                    rows.append({"surface": name, "cluster": cluster, "metric": metric, "direction": direction,
                                 "zones": nz, "time_s": s, "length_mm": mm, "seed": list(seed),
                                 "zoning_s": t_zone, "machining_s": time.perf_counter() - t})
    return rows


def print_ch3(rows):
    for name, table in zip(SURFACES, ("3.1", "3.2")):
        print(f"\n### Table {table}: {name}, K = 3 (Ward: largest jump); time s / length mm, ours (seed)\n")
        print("| direction | clustering | metric | zones | ours | seed | zoning s | machining s |\n|---|---|---|---|---|---|---|---|")
        for r in rows:
            if r["surface"] == name:
                print(f"| {r['direction']} | {r['cluster']} | {r['metric']} | {r['zones']} | {r['time_s']:.1f} / "
                      f"{r['length_mm']:.0f} | {r['seed'][0]} / {r['seed'][1]} | {r['zoning_s']:.2f} | {r['machining_s']:.1f} |")


def ch4_rows(ks, evals, axes_modes=("3", "3+2"), heuristic=False):
    rows = []
    for name in SURFACES:
        patch = load_patch(name)
        shared = (cell_samples(patch, 80, 80), patch_mesh(patch, 0.5))
        for axes in (("3+2",) if heuristic else axes_modes):
            ch = chooser(name, [BULL], axes=axes, samples=shared)
            for k in ks:
                t = time.perf_counter()
                zones, clusters = ch.zoning(k)
                if heuristic:
                    plans = {}
                    for z in zone_ids(zones):
                        inside = zones == z
                        axis, x1 = heuristic_axis(ch.samples.points[inside], ch.samples.normals[inside])
                        plans[int(z)] = ZonePlan(0, azimuth_in_frame(x1, frame_rotation(axis)), tuple(axis))
                else:
                    plans = direction_plans(ch, zones, "steepest")
                    plans = {z: ZonePlan(0, p.theta) for z, p in plans.items()}
                f0 = ch.machinist.plan(zones, plans).total_s
                opt = optimise_plan(ch, k, zones, clusters, plans, evals, heuristic=heuristic)
                seed = SEED_HEUR[name][k] if heuristic else SEED_CH4[(name, axes)].get(k)
                rows.append({"surface": name, "axes": axes, "k": k, "zones": len(zone_ids(zones)), "f0": f0,
                             "f_star": min(f0, opt.result.total_s), "gain": 1 - min(f0, opt.result.total_s) / f0,
                             "evaluations": opt.summary["black_box_evaluations"],
                             "surrogate_evaluations": opt.summary["surrogate_evaluations"], "seed": seed,
                             "seconds": time.perf_counter() - t})
    return rows


def print_ch4(rows, title):
    print(f"\n### {title} (s): ours f0 -> f*, seed f0 -> f* (none, S3)\n")
    print("| surface | axes | K | zones | f0 | f* | gain | seed f0 | seed f* | evals (surrogate) | s |\n|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        sd = r["seed"] or ()
        print(f"| {r['surface']} | {r['axes']} | {r['k']} | {r['zones']} | {r['f0']:.1f} | {r['f_star']:.1f} | "
              f"{100 * r['gain']:.1f} % | {sd[0] if sd else '-'} | {', '.join(str(v) for v in sd[1:])} | "
              f"{r['evaluations']} ({r['surrogate_evaluations']}) | {r['seconds']:.0f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", default="ch2,cross,ch3,ch4,heur")
    ap.add_argument("--ks", default="2,3,4,5,6")
    ap.add_argument("--evals", type=int, default=20, help="black-box evaluations per K (the seed: 1000)")
    ap.add_argument("--out", default=os.path.join(HERE, "out", "choice_seed_tables.json"))
    args = ap.parse_args(argv)
    sections = [s for s in args.sections.split(",") if s]
    ks = [int(k) for k in args.ks.split(",") if k]
    mach = machine()
    result = {"date": datetime.datetime.now().isoformat(timespec="seconds"), "commit": git_commit(), "machine": mach,
              "evals": args.evals}
    print(f"machine: {mach['cpu_model'] or mach['processor']}, {mach['cpu_count']} CPUs, {mach['numba_threads']} numba threads")
    if "ch2" in sections:
        result["ch2"] = ch2_rows()
        print_ch2(result["ch2"])
    if "cross" in sections:
        result["cross"] = cross_rows()
        print_cross(result["cross"])
    if "ch3" in sections:
        result["ch3"] = ch3_rows()
        print_ch3(result["ch3"])
    if "ch4" in sections:
        result["ch4"] = ch4_rows(ks, args.evals)
        print_ch4(result["ch4"], f"Tables 4.3-4.6: NOMAD with {args.evals} black-box evaluations per K")
    if "heur" in sections:
        result["heur"] = ch4_rows(ks, args.evals, heuristic=True)
        print_ch4(result["heur"], f"Tables 4.7-4.8: PCA 3+2 heuristic, NOMAD with {args.evals} evaluations per K")
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump(result, fh, indent=2, default=float)
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
