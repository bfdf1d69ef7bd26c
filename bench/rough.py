"""Adaptive clearing (meshmill rough) against FreeCAD's Adaptive2d (libarea), level by level.

    .venv/bin/python bench/rough.py                    # vase, dolphin mould, terrain, hull
    .venv/bin/python bench/rough.py --parts vase --fc /tmp/fc/x/usr/lib/freecad-python3/lib

The peer: Debian's ``libfreecad-python3-0.20`` holds ``area.so`` (FreeCAD's libarea with
``Adaptive2d``). ``apt-get download libfreecad-python3-0.20 && dpkg -x *.deb x`` and give
``--fc x/usr/lib/freecad-python3/lib`` (the folder is put on ``sys.path`` and the library path
before the import; without it the peer's rows are left out with a note). It is a benchmark
dependency only.

Each part is roughed with the F10L flat end mill (flutes 30 mm) from a box stock, 10 mm levels,
a radial width of cut (ae) of 2.5 mm (a quarter of the diameter), 0.5 mm left. On the same
levels the peer clears the same region: inside the stock's box grown by a tool diameter (and 2 mm:
the tool may go round the stock, where the stock outline given to it says there is no material),
less the part's shadow above the level (the nodes of a 0.25 mm grid where the part stands higher,
traced into polygons: holes in the region; ClearingInside), with the same tool, step-over factor, allowance and a helix of the
same diameter; its 2D paths become a 3-axis path at the level (links to the safe plane where it
says the way is not clear). Both paths are then measured the same way, by our dexel simulation:

- ``s``: compute time of the levels (ours: the clearing of each level; ``setup``: our grid of
  drop heights, shared by the levels; the peer: ``Execute`` of each level);
- ``ae max / mean``: the radial width of cut of the cutting moves at a level, measured on the
  dexel stock (the volume it removes within its layer over its length and the layer's depth),
  not by the planner; ``over`` the share of them above the set ae by more than 10 %. Every move
  is cut in order; at most 3000 of them (every k-th, ``k`` in the JSON) are measured one by one
  (the tests measure every move);
- ``air``: the share of the feed length that removes nothing from the stock as it stands;
- ``m``: feed length; ``time``: machining time on generic-3axis; ``gouge``: the deepest gouge
  of the design found by ``verify`` (certified, tolerance 0.01 mm; 0 where none);
- ``left``: the stock left over the design where a flat tool reaches (the mean and largest height
  of the stock's top above the design's over the Z lines where the tool's own drop height lies
  within the allowance plus a level of the design's top).

Prints a table and writes bench/out/rough.json.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
DATA = os.path.join(ROOT, "src", "meshmill", "data")
REAL = os.path.join(os.path.dirname(ROOT), "shared", "parts", "real")
sys.path.insert(0, os.path.join(ROOT, "src"))

PARTS = {
    "vase": dict(path=os.path.join(DATA, "vase.stl"), margin=1.0, step=0.25),
    "dolphin": dict(path=os.path.join(REAL, "mould_dolphin_tail_cavity.stl"), up="+X", origin="bottom-centre",
                    margin=0.0, top=2.0, step=0.5),
    "terrain": dict(path=os.path.join(REAL, "relief_terrain.stl"), units="m", scale=0.0002, origin="corner",
                    margin=0.0, top=2.0, step=0.5),
    "hull": dict(path=os.path.join(REAL, "ship_hull_dtc.stl"), units="m", scale=0.04, origin="bottom-centre",
                 margin=1.0, step=0.5),
}
TOOL, AE, STEP_DOWN, ALLOWANCE = "F10L", 2.5, 10.0, 0.5
MACHINE = "generic-3axis"


def load(spec):
    from meshmill import api

    part = api.load_part(spec["path"], **{k: spec[k] for k in ("up", "origin", "units", "scale") if k in spec})
    stock = api.Stock.box(spec["margin"], top=spec.get("top"))
    return part, stock


MEASURED = 3000  # cutting moves measured one by one at most (every k-th; all are cut in order)


def measure(part, stock, tools, tp, kind, summary, step):
    """The dexel measures of a 3-axis roughing path (see the module docstring)."""
    from meshmill import api
    from meshmill.ops.rough import layer_tops
    from meshmill.simulation.engagement import level_widths

    st = stock.dexels(part, step)
    cut = np.nonzero(kind == 1)[0]
    every = max(1, -(-len(cut) // MEASURED))
    cut = cut[::every]
    t = time.perf_counter()
    w = level_widths(st, tp, tools, cut, layer_tops(summary, tp.tip[cut])) if len(cut) else np.zeros(1)
    t_w = time.perf_counter() - t
    after, fig = st.cut(tp, tools)
    check = api.verify(part, tp, tools).report  # gouges against the design, certified
    timed = api.machining_time(tp, MACHINE, tools).summary
    left = stock_left(part, after, tools)
    return {"ae_max": float(w.max()), "ae_mean": float(w[w > 0.05 * AE].mean()) if (w > 0.05 * AE).any() else 0.0,
            "ae_over_10pct": float(np.mean(w > 1.1 * AE)), "air_share": fig["cutting_mm"]["air_share"],
            "feed_m": tp.cutting_length() / 1000.0, "machining_s": timed["total"]["total_s"],
            "removed_mm3": st.volume - after.volume, "rapid_cuts": fig["rapid_moves_cutting"],
            "collisions": fig["colliding_moves"], "gouging_moves": check["gouging_moves"],
            "max_gouge_mm": check["max_gouge"], **left, "measured_every": every, "measure_s": round(t_w, 1)}


def stock_left(part, after, tools):
    """Mean and largest height of the stock's top over the design's where a flat tool reaches."""
    from meshmill.kernels.backend import solid_kernels
    from meshmill.pathing.dropcutter import ToolDrop

    m = after.model
    nu, nv = m.shape(2)
    start, iv = m.start[2], m.iv[2]
    top = np.full(nu * nv, -np.inf)
    has = start[1:] > start[:-1]
    top[has] = iv[start[1:][has] - 1, 1]
    u, v = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    xy = np.column_stack([m.lo[0] + (u.ravel() + 0.5) * m.step, m.lo[1] + (v.ravel() + 0.5) * m.step])
    kern = solid_kernels(part, "cpu")
    floor = float(part.bounds[0, 2]) - 1.0
    design = kern.drop_cutter(xy, 1e-3, 0.0, floor)[0]
    tool = next(t for t in tools if t.name == TOOL)
    reach = ToolDrop(tool, kern, floor)(xy)
    on = (design > floor + 1e-6) & has & (reach <= design + ALLOWANCE + STEP_DOWN)
    e = (top - design)[on]
    return {"left_mean_mm": float(e.mean()) if len(e) else 0.0, "left_max_mm": float(e.max()) if len(e) else 0.0}


def ours(part, stock, tools):
    from meshmill import api

    t = time.perf_counter()
    res = api.rough(part, tools, tool=TOOL, engagement=AE, step_down=STEP_DOWN, allowance=ALLOWANCE, stock=stock)
    wall = time.perf_counter() - t
    s = res.summary
    levels_s = sum(lv["seconds"] for lv in s["levels"])
    return res, {"wall_s": wall, "levels_s": levels_s, "verify_s": s["seconds"]["verify"],
                 "setup_s": wall - levels_s - s["seconds"]["verify"], "ok": res.ok,
                 "per_level_s": [lv["seconds"] for lv in s["levels"]]}


def shadow_polygons(part, z, xs, ys):
    """Closed polylines (mm) around where the part stands above ``z`` (traced on the grid)."""
    from skimage.measure import find_contours

    from meshmill.kernels.backend import solid_kernels

    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    h = solid_kernels(part, "cpu").drop_cutter(np.column_stack([gx.ravel(), gy.ravel()]), 1e-3, 0.0,
                                               float(part.bounds[0, 2]) - 1.0)[0].reshape(gx.shape)
    above = np.pad((h > z + 1e-6).astype(float), 1)
    out = []
    for c in find_contours(above, 0.5):
        c = c - 1.0
        out.append([(float(xs[0] + (xs[1] - xs[0]) * i), float(ys[0] + (ys[1] - ys[0]) * j)) for i, j in c])
    return out


def peer(part, stock, tools, res, area):
    """FreeCAD's Adaptive2d on our levels: ``(toolpath, kinds, summary-like dict, figures)``."""
    from meshmill.toolpath.model import Toolpath

    s = res.summary
    tool = next(t for t in tools if t.name == TOOL)
    lo, hi = stock.solid(part).bounds
    box = [[(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]]
    h = 0.25
    xs = np.arange(lo[0] - 1.0, hi[0] + 1.0 + h, h)
    ys = np.arange(lo[1] - 1.0, hi[1] + 1.0 + h, h)
    safe = s["safe_z"]
    tips, kind, per_level = [[0.0, 0.0, safe]], [0], []
    helix = 0.75 * tool.diameter
    prev_top = s["stock_top"]
    grow = tool.diameter + 2.0  # the tool may go round the stock: the region reaches past it
    boundary = [[(lo[0] - grow, lo[1] - grow), (hi[0] + grow, lo[1] - grow), (hi[0] + grow, hi[1] + grow),
               (lo[0] - grow, hi[1] + grow)]]
    for lv in s["levels"]:
        z = lv["z"]
        paths = boundary + shadow_polygons(part, z, xs, ys)  # the shadow: holes in the region
        a2d = area.Adaptive2d()
        a2d.toolDiameter = tool.diameter
        a2d.stepOverFactor = AE / tool.diameter
        a2d.stockToLeave = ALLOWANCE
        a2d.tolerance = 0.05
        a2d.helixRampDiameter = helix
        a2d.keepToolDownDistRatio = 3.0
        a2d.opType = area.AdaptiveOperationType.ClearingInside
        t = time.perf_counter()
        out = a2d.Execute(box, paths, lambda tp: False)
        per_level.append(time.perf_counter() - t)
        for region in out:
            cx, cy = region.HelixCenterPoint
            tips += [[cx, cy, safe], [cx, cy, prev_top + 1.0]]
            kind += [0, 0]
            r = 0.5 * helix
            n = max(8, int(math.ceil((prev_top + 1.0 - z) / (2 * math.pi * r * math.tan(math.radians(3.0))) * 72)))
            for k in range(1, n + 1):  # the helix down at 3 degrees
                a = 2 * math.pi * k / 72
                tips.append([cx + r * math.cos(a), cy + r * math.sin(a), prev_top + 1.0 - (prev_top + 1.0 - z) * k / n])
                kind.append(2)
            for mtype, pts in region.AdaptivePaths:
                pts = np.asarray(pts, float)
                if not len(pts):
                    continue
                if mtype == 2:  # not clear: up, over, down
                    tips += [[tips[-1][0], tips[-1][1], safe], [pts[0, 0], pts[0, 1], safe]]
                    kind += [0, 0]
                    tips.append([pts[0, 0], pts[0, 1], z])
                    kind.append(2)
                    pts = pts[1:]
                for p in pts:
                    tips.append([p[0], p[1], z])
                    kind.append(1 if mtype == 0 else 3)
            tips.append([tips[-1][0], tips[-1][1], safe])
            kind.append(0)
        prev_top = z
    tips = np.array(tips)
    kind = np.array(kind, np.int8)
    index = [t.name for t in tools].index(TOOL)
    tp = Toolpath(tips, np.tile([0.0, 0.0, 1.0], (len(tips), 1)), kind == 0, np.full(len(tips), index, np.int64))
    return tp, kind, {"levels_s": sum(per_level), "per_level_s": per_level}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--parts", nargs="+", default=list(PARTS), choices=list(PARTS))
    ap.add_argument("--fc", default=None, help="folder holding FreeCAD's area.so (see the module docstring)")
    args = ap.parse_args()
    area = None
    note = "peer: not run (give --fc, see bench/rough.py)"
    if args.fc:
        os.environ["LD_LIBRARY_PATH"] = args.fc + os.pathsep + os.environ.get("LD_LIBRARY_PATH", "")
        sys.path.insert(0, args.fc)
        try:
            import ctypes

            ctypes.CDLL(os.path.join(args.fc, "libarea-native.so"))
            import area as area_module

            area, note = area_module, f"peer: FreeCAD 0.20 Adaptive2d from {args.fc}"
        except (ImportError, OSError) as exc:
            note = f"peer: not run ({exc})"
    from meshmill import api

    tools = api.load_tools(os.path.join(DATA, "tools.toml"))
    rows = []
    for name in args.parts:
        spec = PARTS[name]
        part, stock = load(spec)
        res, timing = ours(part, stock, tools)
        kind = res.arrays["move_kind"]
        rows.append({"part": name, "who": "meshmill", "levels": len(res.summary["levels"]), **timing,
                     **measure(part, stock, tools, res.toolpath, kind, res.summary, spec["step"])})
        print(rows[-1], flush=True)
        if area is not None:
            tp, pk, pt = peer(part, stock, tools, res, area)
            rows.append({"part": name, "who": "Adaptive2d", "levels": len(res.summary["levels"]), **pt,
                         **measure(part, stock, tools, tp, pk, res.summary, spec["step"])})
            print(rows[-1], flush=True)
    print(note)
    head = (f"{'part':8} {'who':10} {'levels':>6} {'s':>7} {'setup':>6} {'ae max':>7} {'ae mean':>7} {'over':>5} "
            f"{'air':>5} {'m':>6} {'time':>7} {'left':>11} {'gouge':>6}")
    print(head)
    for r in rows:
        print(f"{r['part']:8} {r['who']:10} {r['levels']:6d} {r['levels_s']:7.2f} {r.get('setup_s', 0):6.1f} "
              f"{r['ae_max']:7.3f} {r['ae_mean']:7.3f} {r['ae_over_10pct']:5.1%} {r['air_share']:5.1%} "
              f"{r['feed_m']:6.2f} {r['machining_s'] / 60:6.1f}' {r['left_mean_mm']:5.2f}/{r['left_max_mm']:5.2f} "
              f"{r['max_gouge_mm']:6.3f}")
    os.makedirs(os.path.join(HERE, "out"), exist_ok=True)
    with open(os.path.join(HERE, "out", "rough.json"), "w") as fh:
        json.dump({"note": note, "tool": TOOL, "ae": AE, "step_down": STEP_DOWN, "allowance": ALLOWANCE,
                   "machine": MACHINE, "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
