"""Benchmark: the CUDA backend against our CPU path, kernel by kernel and end to end (issue 6).

Sections (``--sections``, default all):

- ``t7``: seed 004's Tableau 7 sweep: :func:`meshmill.ops.finish.finish` on the vase (8960 triangles,
  stand-in for the 9076-triangle revolution part) with the six ball tools of finish_tableau7.py,
  a_p = 5 .. 0.05 mm, sample 0.5 mm, tilt step 10 deg, max tilt 60 deg.
- ``t8``: Tableau 8: the same on ``standin_parts.mould()`` (66960 triangles, 400 x 400 x 180 mm),
  a_p = 10 .. 0.25 mm, sample 1.0 mm. The seed has about one CC point per 2.5 mm of contour; at our
  0.5 mm the 400 mm part gives 2.8 million CC points at 0.25 mm, at 1.0 mm 1.4 million.
- ``dexel``: triple-dexel generation of the blade (26528 triangles, 152 x 75 x 152 mm) at 0.1 mm.
- ``sim``: :func:`meshmill.ops.simulate.simulate`: 100 000 5-axis ball moves over the wavy
  60 x 60 mm part of dexel_seed_tables.py's goal, the part with 1 mm allowance as the stock,
  dexels at 0.085 mm (about 10^6): models, cut, machined mesh and deviations.

Kernel-only: the :class:`~meshmill.kernels.backend.MeshKernels` methods are wrapped (here only) to add
up wall time per kernel (the CUDA wrappers copy their results to the host, so each call is
synchronous); line casting is ``model.info["cast_seconds"]`` and cutting ``cut()``'s own seconds.
End to end: wall clock around ``finish()``, ``dexelize()``, ``simulate()``. Before timing, each
device runs one untimed small instance of each section (numba compilation or cache load, CUDA JIT);
then every row runs ``--repeat`` times and min and median are reported.

    .venv/bin/python bench/gpu.py --quick --devices cpu        # smoke test: ~10 s (+ ~1 min cold compile)
    NUMBA_ENABLE_CUDASIM=1 .venv/bin/python bench/gpu.py --tiny --devices cpu,cuda --sections dexel,sim
    .venv/bin/python bench/gpu.py --devices cpu --out bench/out/gpu_cpu_2core.json   # 2-core reference, ~12 min
    PYTHONPATH=src python3 bench/gpu.py --cpu-rows 0.5 --cpu-reference bench/out/gpu_cpu_2core.json  # GPU machine

``--devices`` defaults to cpu,cuda where numba sees a GPU, else cpu (with a note); ``--cpu-rows``
limits the CPU's share of the two sweeps. ``--quick``: t7 row 5, t8 row 10 at a 4 mm sample, the
blade at 0.5 mm, 2000 moves at 0.5 mm. ``--tiny``: toy inputs for the CUDA simulator (which runs
every GPU thread in Python): dexel and sim take seconds there, t7 and t8 several minutes.

Prints markdown tables (for bench/README.md) to stdout, progress to stderr, and writes JSON (default
bench/out/gpu.json, rewritten after every row). ``--cpu-reference`` takes an earlier run with
``--devices cpu`` on the 2-core machine of the goals and gives each kernel's ratio against it too.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys
import time
from collections import defaultdict


HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from dexel_seed_tables import sim_job  # noqa: E402
from finish_tableau7 import MAX_TILT, SEED as SEED_T7, STEP_DOWNS as T7_ROWS, TILT_STEP, TOOL_TABLE  # noqa: E402
from finish_tableau7 import git_commit, machine  # noqa: E402
from standin_parts import blade, mould  # noqa: E402
from meshmill.errors import InputError  # noqa: E402
from meshmill.geometry.mesh import mesh_from_arrays  # noqa: E402
from meshmill.geometry.shapes import sphere, vase  # noqa: E402
from meshmill.kernels.backend import MeshKernels, cuda_available  # noqa: E402
from meshmill.ops.finish import FinishParams, finish  # noqa: E402
from meshmill.simulation.stock import Stock  # noqa: E402
from meshmill.ops.simulate import simulate  # noqa: E402
from meshmill.simulation.dexel import dexelize  # noqa: E402
from meshmill.toolpath.model import Toolpath  # noqa: E402
from meshmill.tools.table import tool_from_entry  # noqa: E402

DEFAULT_OUT = os.path.join(os.path.relpath(HERE), "out", "gpu.json")
SECTIONS = ("t7", "t8", "dexel", "sim")
DEVICES = ("cpu", "cuda")
T8_ROWS = [10.0, 5.0, 2.5, 1.0, 0.5, 0.25]
# Seed 004, Tableau 8 (about 65 000 triangles, about 400 x 400 x 180 mm): a_p (mm) ->
# (contours, CC points, sequential s, GPU s).
SEED_T8 = {
    10.0: (19, 13813, 96.59, 57.31),
    5.0: (37, 28064, 192.86, 61.44),
    2.5: (73, 56015, 378.30, 67.20),
    1.0: (181, 140241, 967.84, 107.06),
    0.5: (361, 280436, 1926.39, 171.63),
    0.25: (721, 560496, 3927.66, 322.05),
}
KERNELS = ("mesh_distances", "largest_ball", "axis_search", "pose_penetration", "intervals_clear", "points_inside",
           "drop_cutter", "touch_points", "rays_blocked")
GOAL_E2E_S, GOAL_DEXEL_S, GOAL_RATIO = 5.0, 1.0, 20.0

# Sizes of each mode: finish samples, the dexel part and step, the simulation's part and path.
# (vase: steps and segments of shapes.vase; t8_n: grid of standin_parts.mould.)
CONFIGS = {
    "full": dict(vase=(70, 64), t7_sample=0.5, t8_sample=1.0, t8_n=180, tilt_step=TILT_STEP,
                 dexel="blade", dexel_step=0.1, sim_size=60.0, sim_moves=100_000, sim_step=0.085),
    "quick": dict(vase=(70, 64), t7_sample=0.5, t8_sample=4.0, t8_n=180, tilt_step=TILT_STEP,
                  dexel="blade", dexel_step=0.5, sim_size=60.0, sim_moves=2_000, sim_step=0.5),
    "tiny": dict(vase=(8, 12), t7_sample=4.0, t8_sample=40.0, t8_n=20, tilt_step=30.0,
                 dexel="sphere", dexel_step=1.0, sim_size=10.0, sim_moves=200, sim_step=1.0),
}
ROWS = {"full": (T7_ROWS, T8_ROWS), "quick": ([5.0], [10.0]), "tiny": ([5.0], [10.0])}  # default t7, t8 rows

CLOCK = defaultdict(float)  # kernel name -> seconds since the last reset
CALLS = defaultdict(int)


def _timed(name, method):
    def wrapper(self, *args, **kwargs):
        t = time.perf_counter()
        try:
            return method(self, *args, **kwargs)
        finally:
            CLOCK[name] += time.perf_counter() - t
            CALLS[name] += 1
    wrapper.__wrapped__ = method
    return wrapper


for _name in KERNELS:  # bench only: every MeshKernels built from here on is timed per kernel
    setattr(MeshKernels, _name, _timed(_name, getattr(MeshKernels, _name)))


def say(msg):
    print(msg, file=sys.stderr, flush=True)


class ArgError(argparse.ArgumentParser):
    def error(self, message):
        print(f"gpu.py: error: {message}", file=sys.stderr)
        sys.exit(2)


def pick(text, allowed, flag):
    """Comma list of ``allowed`` values (numbers matched within 1e-9), in the order of ``allowed``."""
    if text.strip() in ("none", ""):
        return []
    chosen = set()
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        if all(isinstance(a, float) for a in allowed):
            try:
                v = float(part)
            except ValueError:
                raise InputError(f"{flag}: not a number: {part!r}")
            match = [a for a in allowed if abs(a - v) < 1e-9]
        else:
            match = [a for a in allowed if a == part]
        if not match:
            names = ", ".join(f"{a:g}" if isinstance(a, float) else a for a in allowed)
            raise InputError(f"{flag}: {part!r} is not one of {names}")
        chosen.add(match[0])
    return [a for a in allowed if a in chosen]


def stats(runs):
    return {"runs": [round(r, 4) for r in runs], "min": round(min(runs), 4),
            "median": round(statistics.median(runs), 4)}


def repeat(fn, n):
    """Run ``fn()`` ``n`` times; wall and per-kernel seconds of each run, and the last run's result."""
    walls, kern, out = [], defaultdict(list), None
    for _ in range(n):
        CLOCK.clear()
        CALLS.clear()
        t = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t)
        extra = out.pop("_kernels", {}) if isinstance(out, dict) else {}
        for k, v in list(CLOCK.items()) + list(extra.items()):
            kern[k].append(v)
        calls = dict(CALLS)
    kernels = {k: dict(stats(v), calls=calls.get(k)) for k, v in kern.items()}  # calls: None for a stage
    return stats(walls), kernels, out


def profile(fn, path):
    """One more run of ``fn()`` under cProfile; its top 45 functions by own time and by total time in ``path``."""
    import cProfile
    import io
    import pstats
    prof = cProfile.Profile()
    t = time.perf_counter()
    prof.runcall(fn)
    wall = time.perf_counter() - t
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    buf = io.StringIO()
    buf.write(f"wall under cProfile: {wall:.3f} s\n")
    for key in ("tottime", "cumulative"):
        pstats.Stats(prof, stream=buf).sort_stats(key).print_stats(45)
    with open(path, "w") as fh:
        fh.write(buf.getvalue())
    say(f"  profile: {path}")


def gpu_info():
    info = {"name": None, "numba_cuda": None, "simulator": os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"}
    try:
        from importlib.metadata import version

        info["numba_cuda"] = version("numba-cuda")
    except Exception:
        pass
    try:
        from numba import cuda

        name = cuda.get_current_device().name
        info["name"] = name.decode() if isinstance(name, bytes) else str(name)
    except Exception:
        info["name"] = "CUDA simulator" if info["simulator"] else None
    try:
        q = ["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"]
        out = subprocess.run(q, capture_output=True, text=True, timeout=20)
        if out.returncode == 0:
            info["nvidia_smi"] = out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        pass
    return info


# ---- the workloads -------------------------------------------------------------------------------------------

def finish_row(mesh, tools, a_p, sample, tilt_step, device):
    params = FinishParams(step_down=a_p, tilt_step=tilt_step, max_tilt=MAX_TILT, sample=sample)
    _, s, _ = finish(mesh, tools, params, device=device)
    return {"contours": s["contours"], "cc_points": s["cc_points"], "verify_ok": bool(s["verify"]["ok"]),
            "max_gouge": s["verify"]["max_gouge"], "stages_s": {k: round(v, 4) for k, v in s["seconds"].items()}}


def dexel_row(mesh, step, device):
    m = dexelize(mesh, step, device=device)
    return {"lines": int(sum(m.line_count(a) for a in range(3))),
            "dexels": int(sum(m.dexel_count(a) for a in range(3))), "volume": round(float(m.volume), 3),
            "_kernels": {"cast_lines": m.info["cast_seconds"]}}


def head(tp, k):
    return Toolpath(tp.tip[:k], tp.axis[:k], tp.rapid[:k], tp.tool[:k])


def sim_row(design, tp, tools, step, device):
    _, s, *_ = simulate(design, tp, tools, step, stock=Stock.offset(1.0), device=device)
    return {"moves": s["moves"], "pieces": s["pieces_cut"], "dexels": int(sum(s["lattice"]["dexels"].values())),
            "removed_mm3": round(float(s["volumes_mm3"]["removed"]), 3),
            "gouged_mm3": round(float(s["volumes_mm3"]["gouged"]), 6),
            "stages_s": s["seconds"], "_kernels": {"cut": s["seconds"]["cut"]}}


# ---- markdown ------------------------------------------------------------------------------------------------

def fmt(st):
    return "" if st is None else f"{st['min']:.3f} / {st['median']:.3f}"


def ratio(a, b):
    return None if not a or not b else a / b


def rfmt(x):
    return "" if x is None else f"{x:.1f}x"


def count(d, key):
    """A count of a row, the CPU's added in brackets where it differs from the GPU's."""
    first = (d.get("cuda") or d["cpu"])["info"][key]
    if "cuda" in d and "cpu" in d and d["cpu"]["info"][key] != first:
        return f"{first} [CPU {d['cpu']['info'][key]}]"
    return str(first)


def by_device(rows, section):
    out = defaultdict(dict)
    for r in rows:
        if r["section"] == section:
            out[r["row"]][r["device"]] = r
    return out


def finish_table(rows, section, seed):
    lines = ["| a_p (mm) | contours (seed) | CC points (seed) | CPU s min / median | CUDA s min / median "
             "| of which CUDA kernels s | CPU/CUDA | seed seq. s | seed GPU s | seed GPU / our CUDA | verify ok "
             "| max gouge (mm) |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|---:|"]
    for a_p, d in sorted(by_device(rows, section).items(), reverse=True):
        sc, sp, sseq, sgpu = seed[a_p]
        cpu, gpu = d.get("cpu"), d.get("cuda")
        med = lambda r: r["wall_s"]["median"] if r else None  # noqa: E731
        ok = all(r["info"]["verify_ok"] for r in d.values())
        gouge = max(r["info"]["max_gouge"] for r in d.values())
        kern = f"{sum(v['median'] for v in gpu['kernels'].values()):.3f}" if gpu else ""
        lines.append(f"| {a_p:g} | {count(d, 'contours')} ({sc}) | {count(d, 'cc_points')} ({sp}) "
                     f"| {fmt(cpu and cpu['wall_s'])} | {fmt(gpu and gpu['wall_s'])} "
                     f"| {kern} "
                     f"| {rfmt(ratio(med(cpu), med(gpu)))} | {sseq:.2f} | {sgpu:.2f} | {rfmt(ratio(sgpu, med(gpu)))} "
                     f"| {'yes' if ok else 'NO'} | {gouge:.2e} |")
    return "\n".join(lines)


def kernel_rows(rows, ref):
    """Per (section, row, kernel): median seconds on each device, against this run's CPU and the reference."""
    out = []
    for r in rows:
        if r["device"] != "cuda":
            continue
        cpu = next((c for c in rows if (c["section"], c["row"], c["device"]) == (r["section"], r["row"], "cpu")),
                   None)
        rcpu = ref.get((r["section"], r["row"]))
        for k, v in sorted(r["kernels"].items()):
            c = cpu["kernels"].get(k, {}).get("median") if cpu else None
            rc = rcpu["kernels"].get(k, {}).get("median") if rcpu else None
            out.append({"section": r["section"], "row": r["row"], "kernel": k, "calls": v["calls"],
                        "cuda_s": v["median"], "cpu_s": c, "ratio": ratio(c, v["median"]),
                        "ref_cpu_s": rc, "ref_ratio": ratio(rc, v["median"])})
    if not any(r["device"] == "cuda" for r in rows):  # CPU only: list the CPU's kernel seconds
        for r in rows:
            for k, v in sorted(r["kernels"].items()):
                out.append({"section": r["section"], "row": r["row"], "kernel": k, "calls": v["calls"],
                            "cuda_s": None, "cpu_s": v["median"], "ratio": None, "ref_cpu_s": None,
                            "ref_ratio": None})
    return out


def kernel_table(krows):
    lines = ["| section | row | kernel | calls | CPU s | CUDA s | CPU/CUDA | 2-core CPU s | 2-core/CUDA |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|"]
    n = lambda x: "" if x is None else f"{x:.4f}"  # noqa: E731
    for k in krows:
        lines.append(f"| {k['section']} | {k['row']:g} | {k['kernel']} | {k['calls'] or ''} | {n(k['cpu_s'])} "
                     f"| {n(k['cuda_s'])} | {rfmt(k['ratio'])} | {n(k['ref_cpu_s'])} | {rfmt(k['ref_ratio'])} |")
    return "\n".join(lines)


def goals(rows, krows, ref_note, mode):
    """The issue's goals: two end-to-end times on CUDA (full sizes only) and every kernel's ratio."""
    def cuda_row(section, row):
        if mode == "full":
            return next((r for r in rows if (r["section"], r["row"], r["device"]) == (section, row, "cuda")), None)

    out = []
    for section, row, limit, what in (("t7", 0.05, GOAL_E2E_S, "t7 a_p 0.05 mm end to end"),
                                      ("dexel", 0.1, GOAL_DEXEL_S, "dexel generation, blade (26528 triangles) "
                                                                    "at 0.1 mm, end to end")):
        r = cuda_row(section, row)
        met = None if r is None else bool(r["wall_s"]["median"] < limit and r["info"].get("verify_ok", True))
        out.append({"goal": f"{what} on CUDA under {limit:g} s", "seconds": r and r["wall_s"]["median"], "met": met})
    best = {}
    for k in krows:  # each kernel at its heaviest common row
        x, cpu_s = (k["ref_ratio"], k["ref_cpu_s"]) if ref_note else (k["ratio"], k["cpu_s"])
        if x is not None and (k["kernel"] not in best or cpu_s > best[k["kernel"]][1]):
            best[k["kernel"]] = (x, cpu_s, f"{k['section']} {k['row']:g}")
    for name, (x, _, where) in sorted(best.items()):
        out.append({"goal": f"{name}: at least {GOAL_RATIO:g}x our CPU path ({ref_note or 'this run CPU'}; {where})",
                    "ratio": round(x, 2), "met": bool(x >= GOAL_RATIO)})
    return out


def report(result):
    """Print the markdown tables of a run (or of runs merged by ``--tables``)."""
    rows, mach, gpu, cfg = result["rows"], result["machine"], result["gpu"], result["config"]
    krows, goal = result["kernel_ratios"], result["goals"]
    sections = [x for x in SECTIONS if any(r["section"] == x for r in rows)]
    tri = {x: next((r["info"]["triangles"] for r in rows if r["section"] == x), 0) for x in ("t7", "t8")}
    print(f"{result['date']}, mode {result['mode']}; CPU {mach['cpu_model'] or mach['processor']}, {mach['cpu_count']} "
          f"CPUs, {mach['numba_threads']} numba threads, numba {mach['numba']}"
          + (f"; GPU {gpu['name']}, numba-cuda {gpu['numba_cuda']}" if gpu else "; no GPU in this run")
          + f"; {result['repeat']} timed run(s) a row after an untimed warm-up; seconds are min / median.")
    if "t7" in sections:
        print(f"\n### Tableau 7: vase ({tri['t7']} triangles), sample {cfg['t7_sample']:g} mm, end to end\n")
        print(finish_table(rows, "t7", SEED_T7))
    if "t8" in sections:
        print(f"\n### Tableau 8: mould ({tri['t8']} triangles, 400 x 400 x 180 mm), "
              f"sample {cfg['t8_sample']:g} mm, end to end\n")
        print(finish_table(rows, "t8", SEED_T8))
    for section, what in (("dexel", "dexel generation"), ("sim", "simulation")):
        if section not in sections:
            continue
        print(f"\n### {what.capitalize()}, end to end\n")
        counts = ("lines", "dexels") if section == "dexel" else ("moves", "pieces", "dexels")
        print(f"| part | triangles | step mm | {' | '.join(counts)} | CPU s min / median | CUDA s min / median "
              f"| CPU/CUDA |\n|---|" + "---:|" * (len(counts) + 5))
        for row, d in by_device(rows, section).items():
            info = (d.get("cuda") or d["cpu"])["info"]
            name = info.get("part", f"wavy {info.get('part_mm', 0):g} mm")
            med = [d[x]["wall_s"]["median"] if x in d else None for x in DEVICES]
            print(f"| {name} | {info['triangles']} | {row:g} | {' | '.join(count(d, c) for c in counts)} "
                  f"| {fmt(d.get('cpu') and d['cpu']['wall_s'])} | {fmt(d.get('cuda') and d['cuda']['wall_s'])} "
                  f"| {rfmt(ratio(*med))} |")
    print("\n### Kernels (median seconds of a row)\n")
    print(kernel_table(krows))
    if goal:
        print("\nGoals of the issue (on an H100):")
        for g in goal:
            state = "not run" if g["met"] is None else ("MET" if g["met"] else "NOT MET")
            val = f"{g['seconds']:.3f} s " if g.get("seconds") is not None else ""
            val += f"{g['ratio']:.1f}x " if "ratio" in g else ""
            print(f"- {g['goal']}: {val}{state}")
    else:
        print("\nNo CUDA device in this run: the GPU figures and goals need a machine with an NVIDIA GPU.")


def merged_tables(files) -> int:
    """Print the tables of earlier runs' JSON files merged: the CUDA rows of one machine beside the
    CPU rows of another (the CPU rows are the reference of every ratio)."""
    try:
        runs = []
        for f in files:
            with open(f) as fh:
                runs.append(json.load(fh))
    except (OSError, ValueError) as e:
        print(f"gpu.py: error: --tables: {e}", file=sys.stderr)
        return 2
    rows = [r for run in runs for r in run["rows"]]
    for f, run in zip(files, runs):
        m = run["machine"]
        print(f"- {f}: {run['date']}, commit {run.get('commit')}, devices {','.join(run['devices'])}; "
              f"{m['cpu_model']}, {m['cpu_count']} CPUs, numba {m['numba']}"
              + (f"; GPU {run['gpu']['name']}, numba-cuda {run['gpu']['numba_cuda']}" if run.get("gpu") else ""))
    cpu_run = next((run for run in runs if "cuda" not in run["devices"]), None)
    ref = {(r["section"], r["row"]): r for r in rows if r["device"] == "cpu"}
    note = None
    if cpu_run:
        m = cpu_run["machine"]
        note = f"{m.get('cpu_model')}, {m.get('cpu_count')} CPUs, {cpu_run.get('date')}"
    merged = dict(next((run for run in runs if run.get("gpu")), runs[0]), rows=rows)
    merged["kernel_ratios"] = kernel_rows(rows, ref)
    merged["goals"] = goals(rows, merged["kernel_ratios"], note, merged["mode"]) if merged.get("gpu") else []
    print()
    report(merged)
    return 0


# ---- main ----------------------------------------------------------------------------------------------------

def main(argv=None):
    ap = ArgError(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sections", default=",".join(SECTIONS), help="comma list of t7,t8,dexel,sim (default all)")
    ap.add_argument("--devices", help="comma list of cpu,cuda (default: cpu,cuda with a GPU, else cpu)")
    for name, sweep in (("t7", T7_ROWS), ("t8", T8_ROWS)):
        ap.add_argument(f"--{name}-rows", help=f"step-downs of the {name} sweep (default "
                                               + ",".join(f"{s:g}" for s in sweep) + ")")
    ap.add_argument("--cpu-rows", help="step-downs that the CPU runs too, in t7 and t8 (default all; 'none')")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of each row (default 3): min and median")
    ap.add_argument("--quick", action="store_true", help="small rows for a smoke test (t7 5, t8 10 at 4 mm sample, "
                                                         "dexel 0.5 mm, 2000 moves at 0.5 mm)")
    ap.add_argument("--tiny", action="store_true", help="smallest inputs, for the CUDA simulator")
    ap.add_argument("--cpu-reference", help="gpu.json of an earlier --devices cpu run (the 2-core machine)")
    ap.add_argument("--out", default=DEFAULT_OUT, help="JSON output path (default: %(default)s)")
    ap.add_argument("--profile", metavar="DIR", help="after each section's last row, one more (untimed) run of it "
                    "under cProfile: DIR/<section>_<row>_<device>.txt, the top functions by own and by total time")
    ap.add_argument("--tables", nargs="+", metavar="JSON", help="run nothing: print the tables of earlier runs "
                    "merged (a GPU machine's --devices cuda run beside the 2-core --devices cpu run)")
    args = ap.parse_args(argv)
    if args.tables:
        return merged_tables(args.tables)
    mode = "tiny" if args.tiny else "quick" if args.quick else "full"
    cfg = CONFIGS[mode]
    try:
        sections = pick(args.sections, list(SECTIONS), "--sections")
        if args.devices is None:
            devices = ["cpu", "cuda"] if cuda_available() else ["cpu"]
        else:
            devices = pick(args.devices, list(DEVICES), "--devices")
        if "cuda" in devices and not cuda_available():
            raise InputError("--devices cuda: no usable CUDA GPU (numba.cuda.is_available() is false); "
                             "use --devices cpu here")
        t7_rows = pick(args.t7_rows, T7_ROWS, "--t7-rows") if args.t7_rows else ROWS[mode][0]
        t8_rows = pick(args.t8_rows, T8_ROWS, "--t8-rows") if args.t8_rows else ROWS[mode][1]
        both = sorted(set(T7_ROWS + T8_ROWS), reverse=True)
        cpu_rows = None if args.cpu_rows is None else pick(args.cpu_rows, both, "--cpu-rows")
        if args.repeat < 1:
            raise InputError(f"--repeat must be at least 1, got {args.repeat}")
        if not sections or not devices:
            raise InputError("no section or no device to run")
        ref, ref_note = {}, None
        if args.cpu_reference:
            try:
                with open(args.cpu_reference) as fh:
                    rj = json.load(fh)
            except (OSError, ValueError) as e:
                raise InputError(f"--cpu-reference: cannot read {args.cpu_reference}: {e}")
            ref = {(r["section"], r["row"]): r for r in rj.get("rows", []) if r["device"] == "cpu"}
            m = rj.get("machine", {})
            ref_note = f"{m.get('cpu_model')}, {m.get('cpu_count')} CPUs, {rj.get('date')}"
            if rj.get("config") != json.loads(json.dumps(cfg)):
                say(f"note: --cpu-reference ran other sizes ({rj.get('config')}): its ratios compare other work")
    except InputError as e:
        print(f"gpu.py: error: {e}", file=sys.stderr)
        return 2

    if os.environ.get("NUMBA_ENABLE_CUDASIM") == "1" and "cuda" in devices and mode != "tiny":
        say("note: NUMBA_ENABLE_CUDASIM=1 runs each GPU thread in Python: use --tiny (this takes many minutes)")
    if "cuda" not in devices:
        say("note: no CUDA device in this run (no usable GPU, or --devices cpu): CPU figures only; the GPU figures "
            "need a machine with an NVIDIA GPU and numba-cuda")
    mach = machine()
    gpu = gpu_info() if "cuda" in devices else None
    say(f"machine: {mach['cpu_model'] or mach['processor']}, {mach['cpu_count']} CPUs, {mach['numba_threads']} numba "
        f"threads; GPU: {gpu and gpu['name']}; mode {mode}; sections {','.join(sections)}; devices {','.join(devices)}")
    tools = [tool_from_entry(e, i + 1, "bench tool table") for i, e in enumerate(TOOL_TABLE)]
    rows = []

    date = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    result = {
        "benchmark": "gpu", "date": date, "commit": git_commit(), "mode": mode, "config": cfg,
        "machine": mach, "gpu": gpu, "devices": devices, "sections": sections, "repeat": args.repeat,
        "warmup": {"note": "one untimed small run of each section per device before timing (numba compile or "
                           "cache load, CUDA JIT)", "seconds": {}},
        "timing": "wall_s: wall clock around finish(), dexelize() or simulate() (min and median of the runs); "
                  "kernels: summed wall time of each MeshKernels call (results copied to the host, so "
                  "synchronous), dexel cast_seconds, cut() seconds",
        "params": {"tilt_step": cfg["tilt_step"], "max_tilt": MAX_TILT, "t7_sample": cfg["t7_sample"],
                   "t8_sample": cfg["t8_sample"], "tools": TOOL_TABLE},
        "cpu_reference": {"file": args.cpu_reference, "machine": ref_note} if args.cpu_reference else None,
        "rows": rows, "kernel_ratios": [], "goals": [],
    }

    def save():  # after every row, so that a run cut short still leaves its rows
        result["kernel_ratios"] = kernel_rows(rows, ref)
        result["goals"] = goals(rows, result["kernel_ratios"], ref_note, mode) if "cuda" in devices else []
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        with open(args.out, "w") as fh:
            json.dump(result, fh, indent=2, default=float)
            fh.write("\n")

    def run(section, row, device, fn, extra):
        say(f"{section} {row:g} on {device}: {args.repeat} run(s) ...")
        wall, kernels, info = repeat(fn, args.repeat)
        rows.append({"section": section, "row": row, "device": device, "wall_s": wall, "kernels": kernels,
                     "info": {**info, **extra}})
        save()
        say(f"  min {wall['min']:.3f} s, median {wall['median']:.3f} s; "
            + ", ".join(f"{k} {v['median']:.3f}" for k, v in sorted(kernels.items())))
        if args.profile and row == last_row[section]:
            profile(fn, os.path.join(args.profile, f"{section}_{row:g}_{device}.txt"))

    def warm(key, device, fn):
        if f"{key}/{device}" not in result["warmup"]["seconds"]:
            say(f"warm-up (untimed) for {key} on {device} ...")
            t = time.perf_counter()
            fn()
            result["warmup"]["seconds"][f"{key}/{device}"] = round(time.perf_counter() - t, 3)
            say(f"  {time.perf_counter() - t:.2f} s")

    last_row = {"t7": t7_rows[-1], "t8": t8_rows[-1], "dexel": cfg["dexel_step"], "sim": cfg["sim_step"]}
    parts = {}
    if "t7" in sections or "t8" in sections:
        parts["vase"] = vase(steps=cfg["vase"][0], segments=cfg["vase"][1])
    if "t8" in sections:
        parts["mould"] = mesh_from_arrays(*mould(cfg["t8_n"]), "mould")
    for section, part, sweep, sample in (("t7", "vase", t7_rows, cfg["t7_sample"]),
                                         ("t8", "mould", t8_rows, cfg["t8_sample"])):
        if section not in sections:
            continue
        mesh = parts[part]
        for device in devices:
            todo = [a for a in sweep if device == "cuda" or cpu_rows is None or a in cpu_rows]
            if todo:
                warm("finish", device, lambda: finish_row(parts["vase"], tools, 5.0, cfg["t7_sample"],
                                                          cfg["tilt_step"], device))
            for a_p in todo:
                run(section, a_p, device, lambda: finish_row(mesh, tools, a_p, sample, cfg["tilt_step"], device),
                    {"triangles": int(len(mesh.faces))})

    if "dexel" in sections:
        mesh = mesh_from_arrays(*blade(), "blade") if cfg["dexel"] == "blade" else sphere(5.0, rings=6, segments=10)
        for device in devices:
            warm("dexel", device, lambda: dexelize(sphere(5.0, rings=6, segments=10), 1.0, device=device))
            run("dexel", cfg["dexel_step"], device, lambda: dexel_row(mesh, cfg["dexel_step"], device),
                {"part": cfg["dexel"], "triangles": int(len(mesh.faces))})

    if "sim" in sections:
        design, tp, sim_tools = sim_job(cfg["sim_size"], cfg["sim_moves"])
        for device in devices:
            warm("sim", device, lambda: sim_row(design, head(tp, 50), sim_tools, max(cfg["sim_step"], 0.5), device))
            run("sim", cfg["sim_step"], device, lambda: sim_row(design, tp, sim_tools, cfg["sim_step"], device),
                {"part_mm": cfg["sim_size"], "triangles": int(len(design.faces))})

    save()
    report(result)
    print(f"\nJSON written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
