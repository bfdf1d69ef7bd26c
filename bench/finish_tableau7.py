"""Benchmark: the shape of "Tableau 7" of seed 004 for the 5-axis Z-constant ball-end finishing.

Runs :func:`meshmill.ops.finish.finish` on :func:`meshmill.geometry.shapes.vase` (stand-in for the
thesis' model 1) with a table of six ball tools, for step-downs from 5 mm to 0.05 mm, and puts the
thesis' contour and CC-point counts and its sequential and GPU times next to ours.

    .venv/bin/python bench/finish_tableau7.py                   # all rows
    .venv/bin/python bench/finish_tableau7.py --rows 5,2.5,1    # a subset
    .venv/bin/python bench/finish_tableau7.py --out some.json

Prints a markdown table (for bench/README.md) and writes JSON (default bench/out/finish_tableau7.json).
Numba is warmed up by one untimed run of the 5 mm row before anything is timed.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import time

import numba
import numpy as np

from meshmill.geometry.shapes import vase
from meshmill.ops.finish import FinishParams, finish
from meshmill.tools.table import tool_from_entry

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_OUT = os.path.join(os.path.relpath(HERE), "out", "finish_tableau7.json")

# Six ball-end tools, R = 10 .. 1 mm (mm). Flutes 2.5 x D; gauge (tip to holder face) 60 mm for the
# big ones, 50/40 mm for the small ones; shank = D from D 6 up, 6 mm below; holder 32 x 40 mm.
TOOL_TABLE = [
    dict(name="B20", type="ball", diameter=20.0, flute_length=50.0, gauge_length=60.0, shank_diameter=20.0,
         holder_diameter=32.0, holder_length=40.0),
    dict(name="B16", type="ball", diameter=16.0, flute_length=40.0, gauge_length=60.0, shank_diameter=16.0,
         holder_diameter=32.0, holder_length=40.0),
    dict(name="B12", type="ball", diameter=12.0, flute_length=30.0, gauge_length=60.0, shank_diameter=12.0,
         holder_diameter=32.0, holder_length=40.0),
    dict(name="B8", type="ball", diameter=8.0, flute_length=20.0, gauge_length=50.0, shank_diameter=8.0,
         holder_diameter=32.0, holder_length=40.0),
    dict(name="B4", type="ball", diameter=4.0, flute_length=10.0, gauge_length=40.0, shank_diameter=6.0,
         holder_diameter=32.0, holder_length=40.0),
    dict(name="B2", type="ball", diameter=2.0, flute_length=5.0, gauge_length=40.0, shank_diameter=6.0,
         holder_diameter=32.0, holder_length=40.0),
]

STEP_DOWNS = [5.0, 2.5, 1.0, 0.5, 0.25, 0.1, 0.05]
TILT_STEP = 10.0  # degrees
MAX_TILT = 60.0  # degrees

# Seed 004, Tableau 7 (model 1: 9076 triangles, 39.93 x 39.89 x 63.11 mm): a_p (mm) ->
# (contours, CC points, sequential s, GPU s).
SEED = {
    5.0: (12, 1464, 106.28, 45.06),
    2.5: (25, 3205, 218.52, 50.38),
    1.0: (63, 7877, 513.13, 79.97),
    0.5: (126, 15864, 1047.64, 86.25),
    0.25: (252, 31640, 2249.44, 118.69),
    0.1: (631, 78963, 5628.33, 129.27),
    0.05: (1262, 157938, 10959.53, 180.01),
}

# Goals of the issue: end-to-end seconds on CPU only (this 2-core machine).
GOALS = {0.1: 30.0, 0.05: 60.0}

STAGES = ("index", "contours", "tools", "axes", "path", "verify", "total")


def parse_rows(text):
    if text is None:
        return list(STEP_DOWNS)
    rows = []
    for part in text.split(","):
        part = part.strip()
        if not part:
            continue
        try:
            v = float(part)
        except ValueError:
            raise SystemExit(f"--rows: not a number: {part!r}")
        match = [s for s in STEP_DOWNS if abs(s - v) < 1e-9]
        if not match:
            raise SystemExit(f"--rows: {part} is not a row of the table ({', '.join(f'{s:g}' for s in STEP_DOWNS)})")
        if match[0] not in rows:
            rows.append(match[0])
    if not rows:
        raise SystemExit("--rows: no row given")
    return sorted(rows, reverse=True)


def params_for(step_down):
    return FinishParams(step_down=step_down, tilt_step=TILT_STEP, max_tilt=MAX_TILT, whole_contours=True)  # the seed's rule


def git_commit():
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE, capture_output=True, text=True,
                             timeout=10)
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "src"], cwd=HERE, capture_output=True,
                               text=True, timeout=10)
        if out.returncode == 0:
            return out.stdout.strip() + ("+dirty-src" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        pass
    return None


def cpu_model():
    """The CPU's model name from /proc/cpuinfo (Linux), or None."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


def machine():
    return {
        "processor": platform.processor() or platform.machine(),
        "cpu_model": cpu_model(),
        "platform": platform.platform(),
        "cpu_count": os.cpu_count(),
        "numba_threads": numba.get_num_threads(),
        "python": platform.python_version(),
        "numba": numba.__version__,
        "numpy": np.__version__,
    }


def run_row(mesh, tools, step_down):
    t = time.perf_counter()
    _, summary, _ = finish(mesh, tools, params_for(step_down))
    wall = time.perf_counter() - t
    seed_c, seed_pts, seed_seq, seed_gpu = SEED[step_down]
    return {
        "step_down": step_down,
        "contours": summary["contours"],
        "machinable_contours": summary["machinable_contours"],
        "cc_points": summary["cc_points"],
        "points_left_out": summary["points_left_out"],
        "points_tilted": summary["points_tilted"],
        "passes": summary["passes"],
        "seconds": {k: summary["seconds"].get(k) for k in STAGES},
        "end_to_end_s": round(wall, 4),
        "verify_ok": bool(summary["verify"]["ok"]),
        "max_gouge": summary["verify"]["max_gouge"],
        "seed": {"contours": seed_c, "cc_points": seed_pts, "sequential_s": seed_seq, "gpu_s": seed_gpu},
        "speedup_vs_seed_sequential": round(seed_seq / wall, 2),
        "speedup_vs_seed_gpu": round(seed_gpu / wall, 2),
    }


def markdown(rows):
    head = ("| a_p (mm) | contours (seed) | machinable | CC points (seed) | left out | tilted "
            "| contours s | tools s | axes s | verify s | end to end s | seed seq. s | seed GPU s "
            "| seq./ours | GPU/ours | verify ok | max gouge (mm) |")
    sep = "|" + "---:|" * 15 + ":---:|---:|"
    lines = [head, sep]
    for r in rows:
        s, sd = r["seconds"], r["seed"]
        lines.append(
            f"| {r['step_down']:g} | {r['contours']} ({sd['contours']}) | {r['machinable_contours']} "
            f"| {r['cc_points']} ({sd['cc_points']}) | {r['points_left_out']} | {r['points_tilted']} "
            f"| {s['contours']:.2f} | {s['tools']:.2f} | {s['axes']:.2f} | {s['verify']:.2f} "
            f"| {r['end_to_end_s']:.2f} | {sd['sequential_s']:.2f} | {sd['gpu_s']:.2f} "
            f"| {r['speedup_vs_seed_sequential']:.1f}x | {r['speedup_vs_seed_gpu']:.1f}x "
            f"| {'yes' if r['verify_ok'] else 'NO'} | {r['max_gouge']:.2e} |")
    return "\n".join(lines)


def goals(rows):
    by = {r["step_down"]: r for r in rows}
    out = []
    for a_p, limit in GOALS.items():
        r = by.get(a_p)
        if r is None:
            out.append({"step_down": a_p, "limit_s": limit, "seconds": None, "met": None})
        else:
            out.append({"step_down": a_p, "limit_s": limit, "seconds": r["end_to_end_s"],
                        "met": bool(r["end_to_end_s"] < limit and r["verify_ok"])})
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", help="comma-separated step-downs to run, e.g. 5,2.5,1 (default: all of "
                                   + ",".join(f"{s:g}" for s in STEP_DOWNS) + ")")
    ap.add_argument("--out", default=DEFAULT_OUT, help="JSON output path (default: %(default)s)")
    args = ap.parse_args(argv)
    rows_wanted = parse_rows(args.rows)

    mesh = vase()
    tools = [tool_from_entry(e, i + 1, "bench tool table") for i, e in enumerate(TOOL_TABLE)]
    ext = mesh.bounds[1] - mesh.bounds[0]
    mach = machine()
    print(f"model: vase, {len(mesh.faces)} triangles, {ext[0]:.2f} x {ext[1]:.2f} x {ext[2]:.2f} mm "
          f"(seed model 1: 9076 triangles, 39.93 x 39.89 x 63.11 mm)", file=sys.stderr)
    print(f"machine: {mach['cpu_model'] or mach['processor']}, {mach['cpu_count']} CPUs, {mach['numba_threads']} numba threads",
          file=sys.stderr)

    print("warm-up (untimed): 5 mm row, so that numba compile/cache load is not counted ...", file=sys.stderr)
    t = time.perf_counter()
    finish(mesh, tools, params_for(5.0))
    warmup = time.perf_counter() - t
    print(f"warm-up took {warmup:.2f} s", file=sys.stderr)

    rows = []
    for a_p in rows_wanted:
        print(f"row a_p = {a_p:g} mm ...", file=sys.stderr, flush=True)
        r = run_row(mesh, tools, a_p)
        print(f"  {r['contours']} contours, {r['cc_points']} CC points, {r['end_to_end_s']:.2f} s, "
              f"verify {'ok' if r['verify_ok'] else 'FAILED'}", file=sys.stderr, flush=True)
        rows.append(r)

    goal = goals(rows)
    result = {
        "benchmark": "finish_tableau7",
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "commit": git_commit(),
        "model": {"name": "vase", "triangles": int(len(mesh.faces)),
                  "extent_mm": [round(float(v), 3) for v in ext],
                  "seed_model": {"name": "model 1", "triangles": 9076, "extent_mm": [39.93, 39.89, 63.11]}},
        "params": {"tilt_step": TILT_STEP, "max_tilt": MAX_TILT, "sample": params_for(1.0).sample,
                   "order": params_for(1.0).order},
        "tools": TOOL_TABLE,
        "machine": mach,
        "warmup": {"note": "one untimed run of the 5 mm row before timing, so numba compilation "
                           "(or loading its cache) is not counted", "seconds": round(warmup, 4)},
        "timing": "end_to_end_s is wall clock around finish(): slicing, tool choice, axis search, path "
                  "building and verification (plus BVH build); seconds are finish()'s own per-stage times",
        "rows": rows,
        "goals": goal,
    }
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump(result, fh, indent=2)
        fh.write("\n")

    print(f"Vase ({len(mesh.faces)} triangles), {len(TOOL_TABLE)} ball tools (R 10..1 mm), tilt step "
          f"{TILT_STEP:g} deg, max tilt {MAX_TILT:g} deg, sample {result['params']['sample']:g} mm; "
          f"{mach['cpu_model'] or mach['processor']}, {mach['cpu_count']} CPUs, {mach['numba_threads']} numba threads; "
          f"{result['date']}; numba warmed up before timing.")
    print()
    print(markdown(rows))
    print()
    print("Goals (CPU only, end to end):")
    for g in goal:
        if g["met"] is None:
            state = "not run"
        else:
            state = f"{g['seconds']:.2f} s -> {'MET' if g['met'] else 'NOT MET'}"
        print(f"- a_p = {g['step_down']:g} mm under {g['limit_s']:g} s: {state}")
    print()
    print(f"JSON written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
