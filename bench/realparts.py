"""Real parts as a user machines them (issue 18): each part of ``../shared/parts/real/`` (and the
bundled vase) set up by meshmill's own options (units, model scale, which axis is up, work zero),
finished with ``--scallop``, simulated from a 0.5 mm allowance, and posted for two 5-axis machines.

Per part it prints and writes (JSON) the shares of the design's surface area that the finish cut
and why the rest was not (no ball of the table fits there, no collision-free axis, facing down
beyond --max-tilt), the contours not cut at all, the share of the surface within the scallop limit
plus the tolerance after the finish (simulate) of what the tools reach and of the whole,
``meshmill verify`` of the written path, wall times, and whether ``post`` (``--clearance``: 10 mm
over the finish's safe plane) wrote a program for ``table-table-ac`` and ``head-table-bc`` (with
its warnings) or its one-line refusal. The finish is
made for ``table-table-ac`` (``--machine``: both machines have their pole at +Z).

    .venv/bin/python bench/realparts.py [--parts vase,dolphin] [--scallop 0.01] [--sim-step 0.3]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
REAL = os.path.join(os.path.dirname(ROOT), "shared", "parts", "real")

TOOLS = """# bench/realparts.py: finishing balls with holders (mm)
[[tools]]
name = "B10"
type = "ball"
diameter = 10.0
flute_length = 20.0
gauge_length = 50.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B6"
type = "ball"
diameter = 6.0
flute_length = 15.0
gauge_length = 45.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B2"
type = "ball"
diameter = 2.0
flute_length = 6.0
gauge_length = 35.0
shank_diameter = 6.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B1"
type = "ball"
diameter = 1.0
flute_length = 3.0
gauge_length = 30.0
shank_diameter = 4.0
holder_diameter = 25.0
holder_length = 40.0
"""

# name: (file, set-up options, step-down mm)
PARTS = {
    "vase": (os.path.join(ROOT, "src", "meshmill", "data", "vase.stl"), [], 2.0),
    "dolphin": (os.path.join(REAL, "mould_dolphin_tail_cavity.stl"), ["--up", "+X", "--origin", "bottom-centre"], 2.0),
    "terrain": (os.path.join(REAL, "relief_terrain.stl"), ["--units", "m", "--scale", "0.0002", "--origin", "corner"],
                1.0),
    "blade": (os.path.join(REAL, "blade_hpt_airfoil.stl"), ["--units", "m", "--origin", "bottom-centre"], 1.0),
    "hull": (os.path.join(REAL, "ship_hull_dtc.stl"), ["--units", "m", "--scale", "0.04", "--origin", "bottom-centre"],
             1.0),
    "car": (os.path.join(REAL, "car_body_drivaer.stl"), ["--units", "m", "--scale", "0.05", "--origin", "bottom-centre"],
            2.0),
}
MACHINES = ("table-table-ac", "head-table-bc")


def band_shares(out, sim, tools_file, scallop, tol, max_tilt, spacing):
    """Shares of the design's surface area, from points spread over it (``spacing`` mm apart),
    each taking the deviation of the nearest dexel end of the simulation and its status
    (:func:`meshmill.ops.finish_areas.surface_status`: facing down beyond ``max_tilt``, no ball of the
    table fits there, else the finish's status of the nearest CC point or raster contact):
    ``reachable`` (cut, or left out in short runs or by the repair, or flat and not reached by the
    raster: a ball gets there), ``no_ball``, ``no_axis``, ``facing_down``, and ``within`` (deviation in
    [-tol, scallop + tol]) of the whole and of what is reachable."""
    import numpy as np
    from scipy.spatial import cKDTree

    sys.path.insert(0, os.path.join(ROOT, "src"))
    from meshmill.geometry.analysis import sample_surface
    from meshmill.geometry.mesh import load_mesh
    from meshmill.kernels.backend import solid_kernels
    from meshmill.ops.finish_areas import AREA_STATUS, surface_status
    from meshmill.tools.table import load_tools

    mesh = load_mesh(os.path.join(out, "part.stl"))
    radii = np.array(sorted((t.radius for t in load_tools(tools_file) if t.type == "ball"), reverse=True))
    p, w, face = sample_surface(mesh, spacing)
    c = np.load(os.path.join(out, "contours.npz"))
    status = surface_status(mesh, solid_kernels(mesh, "cpu"), radii, tol, max_tilt, p, face, c["surface_points"],
                            c["surface_status"], int(c["raster_from"]), float(c["raster_reach"]))
    d = np.load(os.path.join(sim, "deviation.npz"))
    e = d["e"][cKDTree(d["points"]).query(p)[1]]
    reach = np.isin(status, [AREA_STATUS.index(k) for k in ("cut", "short_runs", "left_out", "shallow")])
    band = (e >= -tol) & (e <= scallop + tol)
    total = w.sum()
    out = {k: round(float(w[status == AREA_STATUS.index(k)].sum() / total), 4) for k in ("no_ball", "no_axis",
                                                                                         "facing_down", "shallow")}
    return {**out, "reachable": round(float(w[reach].sum() / total), 4),
            "within_all": round(float(w[band].sum() / total), 4),
            "within_reachable": round(float(w[band & reach].sum() / max(w[reach].sum(), 1e-300)), 4)}


def meshmill(*argv, timeout=3600, warnings=False):
    """``(exit code, last line of stderr, seconds)`` of a meshmill command (``warnings``: its
    warnings instead, joined, when it succeeds)."""
    t = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "meshmill", *argv], capture_output=True, text=True, timeout=timeout,
                       env=dict(os.environ, PYTHONPATH=os.path.join(ROOT, "src")))
    said = r.stderr.strip().splitlines()
    lines = [x for x in said if not x.startswith(("warning", "["))]
    if warnings and r.returncode == 0:
        lines = ["; ".join(x[len("warning: "):] for x in said if x.startswith("warning"))]
    return r.returncode, (lines or [""])[-1], round(time.perf_counter() - t, 1)


def run_part(name, work, tools, scallop, sim_step):
    path, setup, step_down = PARTS[name]
    out = os.path.join(work, name)
    row = {"part": name, "setup": " ".join(setup), "step_down": step_down}
    rc, last, s = meshmill("finish", path, "--tools", tools, "--step-down", str(step_down), "--sample", "1.0",
                           "--tilt-step", "10", "--scallop", str(scallop), "--machine", MACHINES[0], "--out", out,
                           "--quiet", *setup)
    row.update(finish_rc=rc, finish_s=s)
    if rc not in (0, 1):
        row["error"] = last[:200]
        return row
    f = json.load(open(os.path.join(out, "summary.json")))
    a = f["area_mm2"]
    row.update(cc_points=f["cc_points"], raster_points=f["raster_points"], levels=f["levels"],
               contours=f["contours"], contours_not_cut=len(f["unmachinable_contours"]),
               # a contour is never dropped for one point: those not cut fit no ball, or only in runs under --min-run
               contours_not_cut_short=sum(c["points_without_tool"] < c["cc_points"] for c in f["unmachinable_contours"]),
               area_mm2=round(a["total"], 1), **{f"area_{k}": round(a[k] / a["total"], 4) for k in
                                                 ("cut", "no_ball", "no_axis", "facing_down", "short_runs", "left_out")},
               verify_ok=f["verify"]["ok"], moves=f["moves"])
    part_stl = os.path.join(out, "part.stl")  # the part as set up: the path's frame
    rc, last, s = meshmill("verify", part_stl, os.path.join(out, "toolpath.cl"), "--tools", tools, "--out",
                           os.path.join(out, "verify.json"))
    v = json.load(open(os.path.join(out, "verify.json"))) if rc in (0, 1) else {}
    row.update(verify_rc=rc, verify_s=s, gouging=v.get("gouging_moves"), colliding=v.get("colliding_moves"),
               rapid_touching=v.get("rapid_moves_touching"))
    if sim_step:
        rc, last, s = meshmill("simulate", "--design", part_stl, "--allowance", "0.5", "--toolpath",
                               os.path.join(out, "toolpath.cl"), "--tools", tools, "--step", str(sim_step),
                               "--out", os.path.join(out, "sim"), "--quiet")
        row.update(sim_rc=rc, sim_s=s)
        if rc in (0, 1):
            d = json.load(open(os.path.join(out, "sim", "deviation.json")))
            row.update(gouge_max=round(d["gouge_max"], 4),
                       **band_shares(out, os.path.join(out, "sim"), tools, scallop, 0.01, 60.0, sim_step))
        else:
            row["sim_error"] = last[:200]
    clearance = f"{f['safe_z'] + 10.0:.1f}"  # where the rotaries may swing: 10 mm over the path's rapids
    row["post_clearance"] = float(clearance)
    for m in MACHINES:
        rc, last, s = meshmill("post", os.path.join(out, "toolpath.cl"), "--machine", m, "--tools", tools,
                               "--clearance", clearance, "--out", os.path.join(out, f"{m}.nc"), warnings=True)
        row[f"post_{m}"] = (f"ok ({last[:200]})" if last else "ok") if rc == 0 else "refused: " + last[:200]
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--parts", default=",".join(PARTS))
    ap.add_argument("--scallop", type=float, default=0.01)
    ap.add_argument("--sim-step", type=float, default=0.3, help="dexel step of the simulations, mm (0: none)")
    ap.add_argument("--work", default=os.path.join(HERE, "out", "realparts"))
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    tools = os.path.join(a.work, "tools.toml")
    with open(tools, "w") as fh:
        fh.write(TOOLS)
    rows = []
    for name in a.parts.split(","):
        rows.append(run_part(name, a.work, tools, a.scallop, a.sim_step))
        print(json.dumps(rows[-1]), flush=True)
        with open(os.path.join(a.work, "realparts.json"), "w") as fh:
            json.dump({"date": datetime.date.today().isoformat(), "scallop": a.scallop, "sim_step": a.sim_step,
                       "rows": rows}, fh, indent=1)
    keys = ["area_cut", "no_ball", "no_axis", "facing_down", "reachable", "within_reachable", "within_all",
            "contours_not_cut", "gouging", "colliding", "gouge_max", "finish_s", "sim_s"]
    print("\n| part | " + " | ".join(keys) + " | " + " | ".join(MACHINES) + " |")
    print("|---" * (len(keys) + len(MACHINES) + 1) + "|")
    for r in rows:
        print(f"| {r['part']} | " + " | ".join(str(r.get(k, "-")) for k in keys) + " | "
              + " | ".join(str(r.get(f"post_{m}", r.get("error", "-")))[:60] for m in MACHINES) + " |")


if __name__ == "__main__":
    main()
