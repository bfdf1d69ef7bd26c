"""Links between the 5-axis finish's passes: by the safe plane, or straight where verified clear
(issue 38).

    .venv/bin/python bench/links.py                      # vase, blade, dolphin (about 3 min)
    .venv/bin/python bench/links.py --parts vase

Per part, the 5-axis finish (`finish`, the tools of bench/realparts.py, `--order tool`, the
part's step-down there, `--scallop 0.01` on the vase) run twice in the same process, with
``links = "safe"`` (every link up to the safe plane, across and down) and ``links = "direct"``
(a rapid straight from one pass to the next of the same tool where it passes verification, else
the safe plane). Reported: the links of each kind, the rapid and feed length, the moves and the stops the machine makes
(turns sharper than its corner angle), the machining time
on table-table-ac and its non-cutting share (rapids and tool changes over the total, and each
alone), the CC
points cut, whether the path verified, and the finish's wall time. Prints a table and writes
bench/out/links.json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "src"))
sys.path.insert(0, HERE)
from finished import table  # noqa: E402
from realparts import PARTS as REAL_PARTS, TOOLS  # noqa: E402

SETUPS = {
    "vase": dict(step_down=1.0, scallop=0.01),
    "blade": dict(step_down=1.0),
    "dolphin": dict(step_down=2.0),
}


def _setup(options):
    """load_part's keywords from realparts' command-line set-up options."""
    out = {}
    for k in range(0, len(options), 2):
        key, value = options[k].lstrip("-"), options[k + 1]
        out[key] = float(value) if key == "scale" else value
    return out


def run(name, tools, machine, links):
    from meshmill import api

    path, options, _ = REAL_PARTS[name]
    part = api.load_part(path, **_setup(options))
    t = time.perf_counter()
    res = api.finish(part, tools, order="tool", sample=1.0, tilt_step=10.0, machine=machine, links=links,
                     device="cpu", **SETUPS[name])
    wall = time.perf_counter() - t
    tp, s = res.toolpath, res.summary
    seg = np.r_[0.0, np.linalg.norm(np.diff(tp.tip, axis=0), axis=1)]
    total = api.machining_time(tp, machine, tools).summary["total"]
    return {"part": name, "links": links, "direct_links": s["links"]["direct"],
            "safe_plane_links": s["links"]["safe_plane"],
            "rapid_m": round(float(seg[tp.rapid].sum()) / 1000, 2), "feed_m": round(float(seg[~tp.rapid].sum()) / 1000, 2),
            "moves": int(len(tp)), "stops": int(total["stops"]), "machining_min": round(total["total_s"] / 60, 1),
            "non_cutting": round((total["rapid_s"] + total["tool_change_s"]) / total["total_s"], 3),
            "rapids_share": round(total["rapid_s"] / total["total_s"], 3),
            "tool_change_share": round(total["tool_change_s"] / total["total_s"], 3),
            "points_cut": s["points_cut"], "verified": s["verify"]["ok"], "finish_s": round(wall, 1)}


def main():
    from meshmill import api

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--parts", default=",".join(SETUPS))
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as work:
        tools_file = os.path.join(work, "tools.toml")
        with open(tools_file, "w") as fh:
            fh.write(TOOLS)
        tools = api.load_tools(tools_file)
    machine = api.load_machine("table-table-ac")
    run("vase", tools, machine, "safe")  # compiles the kernels before anything is timed
    rows = []
    for name in a.parts.split(","):
        for links in ("safe", "direct"):
            rows.append(run(name, tools, machine, links))
            print(table(rows[-1:]), flush=True)
    print(table(rows))
    os.makedirs(os.path.join(HERE, "out"), exist_ok=True)
    with open(os.path.join(HERE, "out", "links.json"), "w") as fh:
        json.dump({"rows": rows}, fh, indent=2)


if __name__ == "__main__":
    main()
