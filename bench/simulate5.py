"""5-axis simulation at scale (issue 39): the 5-axis finish of real parts cut from their box and
measured, at two lattice steps, by this tree and by another revision in the same run.

    .venv/bin/python bench/simulate5.py                          # blade, dolphin, vase at 0.5 and 0.3 mm
    .venv/bin/python bench/simulate5.py --before 59a515b         # and that revision, side by side
    .venv/bin/python bench/simulate5.py --parts blade --steps 0.5
    .venv/bin/python bench/simulate5.py --steps 0.5 --cutters ball,bull,flat  # the same paths, other ends
    .venv/bin/python bench/simulate5.py --parts blade --steps 0.5 --cutters ball,bull,flat --points 400 --before 621bd62

Per part the finish (``finish --scallop 0.01`` with the balls of bench/realparts.py, the part's
step-down there; ``impeller``: bench/certify.py's, for table-table-ac) is made once with this
tree and written to bench/out/simulate5/<part>.cl; then
each tree simulates that file from the part's box (``api.simulate``, mode sweep: the cutters'
exact swept volumes, the shanks and holders checked against what is left, the load of every
move) in a fresh process. Reported: the moves cut, the wall time and the cut stage's, the CPU
time over the wall time (2.0: both cores busy throughout), the moves whose shank or holder meets
the stock, and the volume removed (the same figures from both trees: the result must not change).
Prints a table and writes bench/out/simulate5.json.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "src"))
sys.path.insert(0, HERE)
from finished import table  # noqa: E402
from links import _setup  # noqa: E402
from certify import FINISHES  # noqa: E402
from realparts import TOOLS  # noqa: E402
from standin_parts import written  # noqa: E402

OUT = os.path.join(HERE, "out", "simulate5")


def _tools(work):
    from meshmill import api

    path = os.path.join(work, "tools.toml")
    with open(path, "w") as fh:
        fh.write(TOOLS)
    return path, api.load_tools(path)


def cutter_tools(work, kind: str) -> str:
    """The tool table with every ball made a ``kind`` ("ball", "bull": corner radius a quarter of
    the diameter, "flat") of the same diameter and lengths: the same path cut by other ends."""
    blocks = TOOLS.split("[[tools]]")
    out = [blocks[0]]
    for b in blocks[1:]:
        d = float(b.split("diameter = ")[1].split("\n")[0])
        end = {"ball": 'type = "ball"', "bull": f'type = "bull"\ncorner_radius = {d / 4:g}', "flat": 'type = "flat"'}[kind]
        out.append(b.replace('type = "ball"', end))
    path = os.path.join(work, f"tools-{kind}.toml")
    with open(path, "w") as fh:
        fh.write("[[tools]]".join(out))
    return path


def make_path(name, tools) -> str:
    """The part's 5-axis finish as a CL file (made once)."""
    from meshmill import api

    cl = os.path.join(OUT, f"{name}.cl")
    if not os.path.exists(cl):
        path, options, step_down, machine = FINISHES[name]
        res = api.finish(api.load_part(path or written(name), **_setup(options)), tools, step_down=step_down,
                         scallop=0.01, machine=machine)
        os.makedirs(OUT, exist_ok=True)
        from meshmill.toolpath.cldata import write_apt

        write_apt(cl, res.toolpath, tools)
    return cl


def head(cl, points: int, work: str) -> str:
    """A copy of the CL file ``cl`` cut after its first ``points`` GOTO points."""
    out, n = [], 0
    with open(cl) as fh:
        for line in fh:
            if line.startswith("GOTO"):
                n += 1
                if n > points:
                    break
            out.append(line)
    path = os.path.join(work, f"{os.path.basename(cl)[:-3]}-{points}.cl")
    with open(path, "w") as fh:
        fh.writelines(out + ["FINI\n"])
    return path


def simulate_one(name, cl, tools_file, step) -> dict:
    """(In the child process.) The figures of one simulation of ``cl``."""
    import time

    from meshmill import api

    path, options, _, _ = FINISHES[name]
    part = api.load_part(path or written(name), **_setup(options))
    tools = api.load_tools(tools_file)
    t0, c0 = time.perf_counter(), time.process_time()
    res = api.simulate(part, cl, tools, step=step)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    s = res.summary
    return {"points": int(s["moves"]), "pieces_cut": int(s["pieces_cut"]), "wall_s": round(wall, 2),
            "cut_s": round(s["seconds"]["cut"], 2), "cpu_per_wall": round(cpu / wall, 2),
            "colliding_moves": int(s["colliding_moves"]), "removed_mm3": round(s["volumes_mm3"]["removed"], 3),
            "Sa_um": round(1000 * res.deviation["Sa"], 3)}


def run_in(src, name, cl, tools_file, step) -> dict:
    """:func:`simulate_one` in a fresh process with ``src`` first on the path (twice: the first run
    compiles or loads the kernels)."""
    code = (f"import sys, json; sys.path.insert(0, {src!r}); import meshmill; sys.path.insert(1, {HERE!r}); "
            f"import simulate5 as s; assert meshmill.__file__.startswith({src!r}), meshmill.__file__; "
            f"print(json.dumps(s.simulate_one({name!r}, {cl!r}, {tools_file!r}, {step!r})))")
    env = dict(os.environ, PYTHONPATH=src)
    out = None
    for _ in range(2):
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
        out = json.loads(done.stdout.strip().splitlines()[-1])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default="blade,dolphin,vase")
    ap.add_argument("--steps", default="0.5,0.3")
    ap.add_argument("--before", help="a git revision simulated beside this tree")
    ap.add_argument("--cutters", default="ball", help="the ends the same path is cut with: ball,bull,flat")
    ap.add_argument("--points", type=int, help="only the first points of each path")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as work:
        tools_file, tools = _tools(work)
        trees = [("this", os.path.join(ROOT, "src"))]
        if a.before:
            wt = os.path.join(work, "before")
            subprocess.run(["git", "-C", ROOT, "worktree", "add", "--detach", wt, a.before], check=True,
                           capture_output=True)
            trees.append((a.before, os.path.join(wt, "src")))
        try:
            for name in a.parts.split(","):
                cl = make_path(name, tools)
                if a.points:
                    cl = head(cl, a.points, work)
                for step in (float(x) for x in a.steps.split(",")):
                    for kind in a.cutters.split(","):
                        table_file = tools_file if kind == "ball" else cutter_tools(work, kind)
                        for label, src in trees:
                            row = {"part": name, "step": step, "cutter": kind, "tree": label,
                                   **run_in(src, name, cl, table_file, step)}
                            rows.append(row)
                            print(table([row]), flush=True)
        finally:
            if a.before:
                subprocess.run(["git", "-C", ROOT, "worktree", "remove", "--force", wt], capture_output=True)
    print(table(rows))
    with open(os.path.join(HERE, "out", "simulate5.json"), "w") as fh:
        json.dump({"rows": rows}, fh, indent=2)


if __name__ == "__main__":
    main()
