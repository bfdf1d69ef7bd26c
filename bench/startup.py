"""Start-up time of the command line and the package (issue 19): wall time of fresh processes, best
of ``--repeat`` each, for ``meshmill --help``, ``import meshmill``, ``import meshmill.api`` and a
small waterline and finish of the bundled vase (coarse step-down); for those two, also how much of
the process is imports (``python -X importtime``: the top-level imports' cumulative time, those
made during the run included). The first run of an operation may compile numba kernels into the
cache: ``first s`` shows it, ``best s`` the warm start. Goal: --help and import under 0.3 s.

    .venv/bin/python bench/startup.py            # or: make bench-startup
"""
import argparse
import importlib.util
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "src", "meshmill", "data")
GOAL_S = 0.3


def commands(out):
    """``[(name, argv, profile imports)]`` to time; ``out``: a scratch folder for the runs' files."""
    meshmill = os.path.join(os.path.dirname(sys.executable), "meshmill")
    part, tools = os.path.join(DATA, "vase.stl"), os.path.join(DATA, "tools.toml")
    runs = [("meshmill --help", [meshmill, "--help"], False),
            ("import meshmill", [sys.executable, "-c", "import meshmill"], False)]
    if importlib.util.find_spec("meshmill.api") is not None:
        runs.append(("import meshmill.api", [sys.executable, "-c", "import meshmill.api"], False))
    else:
        print("note: meshmill.api does not exist in this version: not timed")
    runs += [("meshmill waterline (vase, B4, step-down 10)",
              [meshmill, "waterline", part, "--tools", tools, "--tool", "B4", "--step-down", "10", "--quiet",
               "--out", os.path.join(out, "waterline")], True),
             ("meshmill finish (vase, step-down 10)",
              [meshmill, "finish", part, "--tools", tools, "--step-down", "10", "--quiet",
               "--out", os.path.join(out, "finish")], True)]
    return runs


def wall(argv):
    """Seconds ``argv`` takes in a fresh process (raises when it fails)."""
    t0 = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    return time.perf_counter() - t0


def imports(argv):
    """``(seconds, {module: seconds} of the 4 largest)`` of the top-level imports in the process
    ``argv`` (a ``meshmill`` command, run as ``python -m``)."""
    r = subprocess.run([sys.executable, "-X", "importtime", "-m", "meshmill", *argv[1:]], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    top = {}
    for line in r.stderr.splitlines():
        parts = line.split("|")
        if line.startswith("import time:") and len(parts) == 3 and parts[1].strip().isdigit():
            if not parts[2][1:].startswith(" "):  # a top-level import: its cumulative time counts
                top[parts[2].strip()] = int(parts[1]) / 1e6
    largest = dict(sorted(top.items(), key=lambda kv: -kv[1])[:4])
    return sum(top.values()), largest


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="fresh processes per command (5)")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "out", "startup.json"), help="JSON written")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, argv, profile in commands(tmp):
            times = [wall(argv) for _ in range(args.repeat)]
            row = {"command": name, "argv": argv, "first_s": times[0], "best_s": min(times),
                   "median_s": statistics.median(times)}
            if profile:
                row["imports_s"], row["largest_imports_s"] = imports(argv)
                row["imports_share"] = row["imports_s"] / row["best_s"]
            rows.append(row)
            print(f"{name}: best {row['best_s']:.3f} s", file=sys.stderr)
    print(f"\nbest of {args.repeat} fresh processes; goal: --help and import under {GOAL_S} s\n")
    print("| command | best s | median s | first s | imports s | imports share |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in rows:
        imp = f"{r['imports_s']:.2f} | {100 * r['imports_share']:.0f} %" if "imports_s" in r else "- | -"
        print(f"| {r['command']} | {r['best_s']:.3f} | {r['median_s']:.3f} | {r['first_s']:.3f} | {imp} |")
    for r in rows:
        if "largest_imports_s" in r:
            print(f"\n{r['command']}, largest imports: "
                  + ", ".join(f"{m} {s:.2f} s" for m, s in r["largest_imports_s"].items()))
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    with open(args.out, "w") as fh:
        json.dump({"repeat": args.repeat, "python": sys.version.split()[0], "machine": platform.processor()
                   or platform.machine(), "cpus": os.cpu_count(), "goal_s": GOAL_S, "runs": rows}, fh, indent=1)
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
