"""Command line: argument parsing, progress and error messages; no geometry here.

Bad input ends with one line on stderr and exit code 2; ``verify`` exits 1 when it finds problems.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

from . import __version__, memory
from .errors import InputError
from .runfiles import RunFiles
from .runfolder import FOLDER_OUTPUTS
from .tolerances import GOUGE_TOL, HOLDER_CLEARANCE


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(2, f"meshmill: error: {message}\n")


_status_line = [False]  # a progress line is open on the terminal (to be ended before other text)
_run = [None]  # the result files of the command running (RunFiles): earlier results go at once


def _quiet(args):
    return getattr(args, "quiet", False) or getattr(args, "json", False)


def _end_status():
    """End an open progress line, so that what follows starts on a line of its own."""
    if _status_line[0]:
        print(file=sys.stderr)
        _status_line[0] = False


def _say(args, text):
    if not _quiet(args):
        _end_status()
        print(text, file=sys.stderr, flush=True)


def _progress(args):
    """A callback for the stages of a long command: on a terminal one line that updates in place
    (elapsed time, stage number and name); elsewhere a plain line a stage."""
    start = time.perf_counter()
    count = [0]
    tty = sys.stderr.isatty()

    def stage(name):
        if _quiet(args):
            return
        count[0] += 1
        text = f"[{time.perf_counter() - start:7.2f} s] {name}"
        if tty:
            width = max(20, os.get_terminal_size(sys.stderr.fileno()).columns - 1)
            bar = "#" * min(count[0], 20)
            sys.stderr.write("\r\033[K" + f"{bar:<20} {text}"[:width])
            sys.stderr.flush()
            _status_line[0] = True
        else:
            print(text, file=sys.stderr, flush=True)

    return stage


def _finish_json(args, summary):
    """With ``--json``: the summary on stdout, for scripts."""
    if getattr(args, "json", False):
        json.dump(summary, sys.stdout, indent=2, default=float)
        sys.stdout.write("\n")


def _add_setup(parser):
    """``--units``, ``--up``, ``--origin``: how the part file is set up on the machine."""
    from .geometry.placement import ORIGINS, UNITS

    g = parser.add_argument_group("set-up (the part file into the work frame: mm, +Z to the spindle)")
    g.add_argument("--units", choices=tuple(UNITS), default="mm", help="units of the part file (mm)")
    g.add_argument("--up", default="+Z",
                   help="the part's axis that points to the spindle (+X, -Y, ...), or a rotation: RX,RY,RZ degrees "
                        "about X, then Y, then Z, or nine numbers, a matrix by rows (+Z)")
    g.add_argument("--scale", type=float, default=1.0,
                   help="the model's scale, after --units (0.05: a 1:20 model) (1)")
    g.add_argument("--origin", default="file",
                   help=f"the work zero: {', '.join(ORIGINS)} (of the part's box, after --up) or a point X,Y,Z "
                        "in the file's coordinates (file: the file's own zero)")


def _add_cluster(parser):
    """``--workers N`` / ``--scheduler ADDRESS``: the heavy work on a Dask cluster (meshmill[cluster])."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--workers", type=int, default=None, metavar="N",
                   help="split the work over N worker processes on this machine (a Dask LocalCluster; "
                        "needs meshmill[cluster]); the result is the same")
    g.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="split the work over a running Dask cluster (tcp://host:8786); the result is the same")


def _cluster(args):
    return args.workers if args.workers is not None else args.scheduler


def _add_device(parser):
    parser.add_argument("--device", choices=("cpu", "cuda", "auto"), default="auto",
                        help="run the heavy kernels on the CPU or an NVIDIA GPU (needs meshmill[cuda]); "
                             "auto: the GPU when a usable one is present (auto)")


def _load_part(args, path, placed=True):
    """The part ``path`` placed into the work frame by ``--units``, ``--up``, ``--scale``,
    ``--origin`` and ``--flip`` (``placed=False``: a file already in the work frame, a stock),
    its warnings said."""
    from . import api

    if placed:
        mesh = api.load_part(path, units=args.units, up=args.up, origin=args.origin, scale=args.scale,
                             flip=getattr(args, "flip", False))
    else:
        mesh = api.load_part(path)
    for w in mesh.warnings:
        _say(args, f"warning: {w}")
    return mesh


def _stock(args):
    """The stock mesh of ``--stock FILE`` (its warnings said), or None."""
    path = getattr(args, "stock", None)
    return None if path in (None, "box") else _load_part(args, path, placed=False)


def _add_stock(parser, allowance_flag="--stock-allowance", default=None):
    """``--stock FILE`` or ``--stock-allowance MM``: the material rapid moves must keep clear of."""
    from .tolerances import STOCK_ALLOWANCE

    g = parser.add_mutually_exclusive_group()
    g.add_argument("--stock", default=None, metavar="FILE",
                   help="closed mesh of the material the operation starts from (a machined.stl of simulate, a "
                        "blank): rapid moves keep the clearance from it")
    default = STOCK_ALLOWANCE if default is None else default
    g.add_argument(allowance_flag, type=float, default=default, metavar="MM", dest="stock_allowance",
                   help=f"instead of --stock: material earlier operations left on the part, mm ({default:g}); rapid "
                        "moves keep the clearance from it")


def _tools_beside(args):
    """The tool table of ``--tools``, else the ``tools.toml`` beside ``args.toolpath`` (as choose
    writes it)."""
    from . import api

    path = args.tools
    if path is None:
        path = os.path.join(os.path.dirname(os.path.abspath(args.toolpath)), "tools.toml")
        if not os.path.exists(path):
            raise InputError(f"no --tools given and no tools.toml beside {args.toolpath}: give the tool table")
    return api.load_tools(path)


def _results(paths) -> RunFiles:
    """The result files of this run: earlier results under their names are removed now, whatever
    fails next; the new ones appear when the command saves them."""
    _run[0] = RunFiles(paths)
    return _run[0]


def _default_out(command):
    return {"finish": "out", "raster": "out", "waterline": "out", "plunge": "out", "simulate": "sim",
            "analyze": "analysis", "choose": "choose"}[command]


def _clear_after_usage_error(argv):
    """A command refused by the parser still must not leave an earlier run's files looking like its
    own: remove the results in the folder its ``--out`` names (or the default folder)."""
    if not argv or argv[0] not in FOLDER_OUTPUTS:
        return
    out = _default_out(argv[0])
    for i, a in enumerate(argv):
        if a == "--out" and i + 1 < len(argv):
            out = argv[i + 1]
        elif a.startswith("--out="):
            out = a[len("--out="):]
    if os.path.isdir(out):
        try:
            RunFiles([os.path.join(out, name) for name in FOLDER_OUTPUTS[argv[0]]])
        except InputError:
            pass


def _options(args, *names):
    """``{name: args.name}``: the API's keyword arguments of the same names as the options."""
    return {n: getattr(args, n) for n in names}


def cmd_finish(args):
    from . import api

    tools = api.load_tools(args.tools)
    mesh = _load_part(args, args.part)
    res = api.finish(mesh, tools, stock=_stock(args), progress=_progress(args), cluster=_cluster(args),
                     **_options(args, "step_down", "sample", "max_tilt", "tilt_step", "order", "safe_z", "tolerance",
                                "clearance", "lead", "machine", "scallop", "min_run", "whole_contours",
                                "stock_allowance", "device"))
    res.save(args.out)
    summary = res.summary
    v = summary["verify"]
    _say(args, f"contours {summary['contours']} (machinable {summary['machinable_contours']}), "
               f"CC points {summary['cc_points']}, left out {summary['points_left_out']}, "
               f"tilted {summary['points_tilted']}, passes {summary['passes']}")
    for name, entry in summary["tools_used"].items():
        _say(args, f"  {name}: {entry['contours']} contour(s), {entry['cc_points']} CC points")
    _say(args, f"verify: {'OK' if v['ok'] else 'PROBLEMS'} ({v['poses_checked']} poses, max gouge "
               f"{v['max_gouge']:.4f} mm, tolerance {v['tolerance']} mm)")
    _say(args, f"wrote {os.path.join(args.out, 'toolpath.cl')} and summary.json in {summary['seconds']['total']:.1f} s "
               f"(device {summary['device']})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def _three_axis(args, run, **options):
    """raster, waterline and plunge: load, run ``run`` (the API's function), save, say."""
    from . import api

    tools = api.load_tools(args.tools)
    mesh = _load_part(args, args.part)
    res = run(mesh, tools, tool=args.tool, device=args.device, progress=_progress(args), **options)
    res.save(args.out)
    summary = res.summary
    if "simulation" in summary:
        s = summary["simulation"]
        _say(args, f"simulated at {s['step']:g} mm: removed {s['removed_volume']:.1f} of {s['stock_volume']:.1f} mm^3, "
                   f"{s['remaining_volume']:.1f} mm^3 left over the part")
    v = summary["verify"]
    _say(args, f"{summary['cl_points']} CL points, {summary['moves']} moves; verify: {'OK' if v['ok'] else 'PROBLEMS'} "
               f"(max gouge {v['max_gouge']:.4f} mm, tolerance {v['tolerance']} mm)")
    _say(args, f"wrote {os.path.join(args.out, 'toolpath.cl')} and summary.json in {summary['seconds']['total']:.1f} s "
               f"(device {summary['device']})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def cmd_raster(args):
    from . import api

    return _three_axis(args, api.raster, stock=_stock(args), cluster=_cluster(args),
                       **_options(args, "stepover", "scallop", "angle", "sample", "tolerance", "clearance",
                                  "stock_allowance", "allowance", "rest"))


def cmd_waterline(args):
    from . import api

    return _three_axis(args, api.waterline, stock=_stock(args), cluster=_cluster(args),
                       **_options(args, "step_down", "sample", "tolerance", "clearance", "stock_allowance", "allowance",
                                                    "rest"))


def cmd_plunge(args):
    from . import api

    return _three_axis(args, api.plunge, stock=_stock(args), **_options(args, "allowance", "axes", "radial_step", "engagement",
                                                      "theta_step", "delta_step", "regions", "clearance", "simulate"))


def cmd_verify(args):
    from . import api

    if args.out:
        _results([args.out])
    tools = api.load_tools(args.tools)
    mesh = _load_part(args, args.part)
    stock = _stock(args)
    tp = api.load_toolpath(args.toolpath, tools, machine=args.machine)
    for w in tp.warnings:
        _say(args, f"warning: {w}")
    cluster = _cluster(args)
    res = api.verify(mesh, tp, tools, stock=stock, allowance=args.stock_allowance, cluster=cluster,
                     progress=_progress(args) if cluster is not None else None,
                     **_options(args, "tolerance", "step", "worst", "device"))
    if args.out:
        res.save(args.out)
    report = res.report
    pieces = 0 < report["lines"] < report["moves"]  # G-code: arcs and rotary blocks are read as several moves

    def count(n, kind):
        lines = report["problem_lines"][kind]
        return f"{n}" + (f" (on {lines} line{'s' * (lines != 1)})" if pieces and n else "")

    print(f"{report['moves']} moves" + (f" from {report['lines']} program lines" if pieces else "")
          + f", {report['poses_checked']} poses checked: "
          f"{count(report['gouging_moves'], 'gouge')} gouging, {count(report['colliding_moves'], 'collision')} colliding, "
          f"{count(report['rapid_moves_touching'], 'rapid')} rapid into the {'stock' if res.stock_checked else 'part'}; "
          f"max gouge {report['max_gouge']:.4f} mm, "
          f"max collision {report['max_collision']:.4f} mm (tolerance {report['tolerance']} mm; device {res.device})")
    for line in report["worst"]:
        print("  " + line)
    print("OK" if res.ok else "PROBLEMS FOUND")
    return 0 if res.ok else 1


def cmd_dexel(args):
    from . import api

    out = args.out or os.path.splitext(os.path.basename(args.part))[0] + ".dexel.npz"
    if not out.lower().endswith((".td", ".npz")):
        out += ".npz"
    _results([out, os.path.join(os.path.dirname(os.path.abspath(out)), "summary.json")])
    mesh = _load_part(args, args.part)
    res = api.dexel(mesh, progress=_progress(args), cluster=_cluster(args),
                    **_options(args, "step", "index", "partitions", "kmax", "init", "minibatch", "device"))
    res.save(out)
    summary = res.summary
    for w in summary["warnings"]:
        _say(args, f"warning: {w}")
    d = summary["dexels"]
    _say(args, f"dexels X {d['X']:,}, Y {d['Y']:,}, Z {d['Z']:,}; volume {summary['volume_mm3']:.3f} mm^3 "
               f"(mesh {_mesh_volume(mesh):.3f}); cast in {res.model.info['cast_seconds']:.2f} s with "
               f"{res.model.info['index']}")
    _say(args, f"wrote {out} and {os.path.join(os.path.dirname(os.path.abspath(out)), 'summary.json')} "
               f"(device {summary['device']})")
    _finish_json(args, summary)
    return 0


def _mesh_volume(mesh):
    import numpy as np

    tri = mesh.vertices[mesh.faces]
    return float(np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0)


def _outputs(text: str) -> tuple:
    """``--outputs`` of simulate: a comma list of summary, deviation, mesh (or all)."""
    names = {w.strip() for w in text.split(",") if w.strip()}
    if names == {"all"}:
        return ("deviation", "mesh")
    unknown = names - {"summary", "deviation", "mesh"}
    if unknown or not names:
        raise InputError(f"--outputs: give a comma list of summary, deviation, mesh (or all), got '{text}'")
    return tuple(k for k in ("deviation", "mesh") if k in names)


def cmd_simulate(args):
    from . import api

    tools = api.load_tools(args.tools)
    design = _load_part(args, args.design)
    stock = _stock(args)
    tp = api.load_toolpath(args.toolpath, tools, tool=args.tool, machine=args.machine)
    for w in tp.warnings:
        _say(args, f"warning: {w}")
    res = api.simulate(design, tp, tools, stock="box" if stock is None else stock, progress=_progress(args),
                       cluster=_cluster(args), outputs=_outputs(args.outputs),
                       **_options(args, "step", "allowance", "tolerance", "mode", "device"))
    written = ", ".join(os.path.basename(p) for p in res.save(args.out))
    summary, deviation = res.summary, res.deviation
    for w in summary["warnings"]:
        _say(args, f"warning: {w}")
    _end_status()
    for e in summary["errors"][:10]:
        print(f"error: {e}", file=sys.stderr)
    if len(summary["errors"]) > 10:
        print(f"error: ... {len(summary['errors']) - 10} more in summary.json", file=sys.stderr)
    _say(args, f"Sa {deviation['Sa']:.4f}  Sq {deviation['Sq']:.4f}  Sp {deviation['Sp']:.4f}  Sv {deviation['Sv']:.4f}  "
               f"Sz {deviation['Sz']:.4f} mm; within ±{args.tolerance:g} mm: {100 * deviation['within_tolerance']:.1f} %")
    _say(args, f"gouge max {deviation['gouge_max']:.4f} mm at {deviation['gouge_at']}; excess max "
               f"{deviation['excess_max']:.4f} mm; removed {deviation['removed_volume']:.1f} mm^3, remaining "
               f"{deviation['remaining_volume']:.1f} mm^3")
    c = summary["cutting_mm"]
    _say(args, f"feed moves: {c['in_material']:.1f} mm in material, {c['in_air']:.1f} mm in air "
               f"({100 * c['air_share']:.1f} %)")
    _say(args, f"wrote {written} in {args.out} ({summary['seconds']['total']:.1f} s, device {summary['device']})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def cmd_analyze(args):
    from . import api

    mesh = _load_part(args, args.part)
    res = api.analyze(mesh, progress=_progress(args),
                      **_options(args, "direction", "weighting", "theta_step", "delta_step", "device"))
    res.save(args.out)
    summary, seconds = res.summary, res.summary["seconds"]
    _say(args, f"{summary['visible_triangles']} of {len(mesh.faces)} triangles visible along {summary['direction']}, "
               f"{summary['accessible_triangles']} accessible; {summary['accessible_vertices']} of {len(mesh.vertices)} "
               f"vertices accessible ({seconds['visibility']:.2f} s)")
    if "map" in summary:
        m = summary["map"]
        _say(args, f"map over {m['directions']} directions: best {m['best_direction']} reaches {100 * m['best_share']:.1f} % "
                   f"of the area; {m['never_reached_triangles']} triangles reached by none")
    _say(args, f"wrote analysis.npz and summary.json in {args.out}")
    return 0


def cmd_job(args):
    from .job import Job

    job = Job.from_toml(args.jobfile)
    if args.device is not None:
        job.device = args.device
    for w in job.part.warnings:
        _say(args, f"warning: {w}")
    res = job.run(progress=_progress(args), cluster=_cluster(args))
    res.save(args.out, report=not args.no_report, progress=_progress(args))
    s = res.summary
    for op in s["operations"]:
        c = op["cutting_mm"]
        _say(args, f"{op['folder']}: {'OK' if op['ok'] else 'PROBLEMS'}, removed {op['removed_mm3']:.0f} mm^3, "
                   f"{op['left_over_design_mm3']:.0f} mm^3 left over the part; cutting {c['in_material']:.0f} mm in "
                   f"material, {c['in_air']:.0f} mm in air ({100 * c['air_share']:.1f} %); "
                   f"{_clock(op['machining_s'])} on the machine")
        for e in op["errors"][:5]:
            _say(args, f"  error: {e}")
    f = s["final"]
    _say(args, f"final: {100 * f['within_tolerance']:.1f} % of the surface within ±{f['tolerance']:g} mm, "
               f"{f['left_over_design_mm3']:.0f} mm^3 left over the part, max gouge {f['gouge_max']:.4f} mm")
    _say(args, f"wrote {args.out}/ (program.nc: {s['post']['blocks']} blocks, {_clock(s['machining_s'])} on "
               f"{s['machine']['name']}; job.json{'' if args.no_report else ', report.html'}) in "
               f"{s['seconds']['total']:.1f} s")
    _finish_json(args, s)
    return 0 if res.ok else 1


def cmd_report(args):
    from . import api

    info = api.report(args.folders, args.out, progress=_progress(args))
    for r in info["runs"]:
        for n in r["notes"]:
            _say(args, f"note: {r['folder']}: {n}")
    _say(args, f"wrote {info['file']} ({info['bytes'] / 1e6:.1f} MB, {info['views']} views of {len(info['runs'])} "
               "run(s)); open it in any browser")
    _finish_json(args, info)
    return 0


def _clock(seconds):
    minutes, s = divmod(round(seconds), 60)
    return f"{minutes // 60}:{minutes % 60:02d}:{s:02d}"


def cmd_time(args):
    from . import api

    if args.out:
        _results([args.out])
    machine = api.load_machine(args.machine)
    res = api.machining_time(args.toolpath, machine, _tools_beside(args), feed=args.feed, tool=args.tool)
    if args.out:
        res.save(args.out)
    summary = res.summary
    for w in res.warnings:
        _say(args, f"warning: {w}")
    if args.json:
        _finish_json(args, summary)
        return 0
    print(f"machine: {machine.name}; {'; '.join(summary['notes'])}")
    print(f"{'tool':<12}{'cutting s':>11}{'rapid s':>10}{'changes':>8}{'change s':>10}{'total s':>11}"
          f"{'cutting mm':>13}{'rapid mm':>11}{'stops':>9}")
    for name, e in [*summary["tools"].items(), ("total", summary["total"])]:
        print(f"{name:<12}{e['cutting_s']:>11.1f}{e['rapid_s']:>10.1f}{e['tool_changes']:>8}{e['tool_change_s']:>10.1f}"
              f"{e['total_s']:>11.1f}{e['cutting_mm']:>13.1f}{e['rapid_mm']:>11.1f}{e['stops']:>9}")
    print(f"machining time {_clock(summary['total']['total_s'])} (h:mm:ss)")
    return 0


def cmd_post(args):
    from . import api

    out = args.out or os.path.join(os.path.dirname(os.path.abspath(args.toolpath)), "program.nc")
    _results([out])
    machine = api.load_machine(args.machine)
    res = api.post(args.toolpath, machine, _tools_beside(args),
                   **_options(args, "feed", "tolerance", "origin", "clearance"))
    res.save(out)
    report = res.report
    for w in report["warnings"]:
        _say(args, f"warning: {w}")
    if args.json:
        _finish_json(args, report)
        return 0
    lin = report["linearisation"]
    if lin["max_deviation_mm"] is None:
        shape = "the control interpolates (TCP)"
    elif report["mode"] == "3-axis":
        shape = "straight moves"
    else:
        shape = (f"linearisation within {lin['tolerance_mm']:g} mm added {lin['blocks_added']} blocks (largest tip "
                 f"deviation {lin['max_deviation_mm']:.4f} mm)")
    ranges = ", ".join(f"{a} {lo:.3f}..{hi:.3f}" for a, (lo, hi) in report["axis_ranges"].items())
    rewinds = (f"; {report['rewinds']} rewind(s) of the rotaries, the whole tool above Z {report['clearance_z_mm']:g}"
               if report["rewinds"] else "")
    print(f"wrote {out}: {report['blocks']} blocks for {report['moves']} CL moves on {machine.name} "
          f"({report['dialect']}, {report['mode']}, {report['feed_mode']}); {shape}; axes {ranges}{rewinds}; "
          f"tools {', '.join(report['tools'])}, {report['tool_changes']} tool change(s); {report['feeds']}.")
    return 0


def cmd_choose(args):
    from . import api

    res = api.choose(args.surface, progress=_progress(args),
                     **_options(args, "scallop", "tool_pair", "tools", "zones", "k_max", "axes", "optimise", "machine",
                                "cluster", "metric", "grid", "mesh_step", "sample", "min_zone", "seed", "flip",
                                "device"))
    res.save(args.out)
    summary = res.summary
    v = summary["verify"]
    if not _quiet(args):
        _end_status()
        for pair in (summary["rule"] or {}).get("pairs", []):
            print(f"rule (whole surface, seed 002): {pair['choice']} along the {pair['direction']} "
                  f"(slope {pair['slope_deg']:.2f} deg, critical slope {pair['critical_slope_deg']:.2f} deg; "
                  f"predicted ball {pair['predicted_ball_principal_s']:.1f} s, bull {pair['predicted_bull_steepest_s']:.1f} s)")
        print(f"{'zone':>4}{'cells':>7}{'tool':>12}{'azimuth':>9}{'tilt':>7}{'predicted s':>13}{'measured s':>12}"
              f"{'cut mm':>9}{'planes':>8}{'coverage':>10}")
        for z in summary["zones"]:
            print(f"{z['zone']:>4}{z['cells']:>7}{z['tool']:>12}{z['azimuth_deg']:>9.1f}{z['tilt_deg']:>7.1f}"
                  f"{z['predicted_s']:>13.1f}{z['measured_s']:>12.1f}{z['cutting_mm']:>9.0f}{z['planes']:>8}"
                  f"{z['coverage']:>10.3f}")
        print(f"K = {summary['k']} ({len(summary['zones'])} zones), total {summary['total_s']:.1f} s with "
              f"{summary['tool_changes']} tool change(s) and {summary['reorientations']} re-orientation(s) on "
              f"{res.machine.name}")
        if summary["optimisation"]:
            o = summary["optimisation"]
            print(f"NOMAD: rule-based {o['rule_s']:.1f} s -> {o['optimum_s']:.1f} s after {o['black_box_evaluations']} "
                  f"black-box and {o['surrogate_evaluations']} surrogate evaluations")
    for z in summary["zones"]:
        if not z["machined"]:
            _say(args, f"warning: zone {z['zone']} ({z['cells']} cells) is not machined: no candidate covers it "
                       f"(best {100 * z['coverage']:.0f} % of its cells{', no passes' if not z['planes'] else ''})")
    _say(args, f"verify: {'OK' if v['ok'] else 'PROBLEMS'} (max gouge {v['max_gouge']:.4f} mm, tolerance {v['tolerance']} mm)")
    _say(args, f"wrote {os.path.join(args.out, 'toolpath.cl')}, tools.toml, zones.npz and summary.json in "
               f"{summary['seconds']['total']:.1f} s (device {res.device})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def build_parser():
    p = _Parser(prog="meshmill", description="Exact, verified multi-axis milling tool paths from triangle meshes.")
    p.add_argument("--version", action="version", version=f"meshmill {__version__}")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    f = sub.add_parser("finish", help="5-axis Z-constant finishing with ball-end tools")
    f.add_argument("part", help="part mesh (STL, OBJ, PLY), mm")
    f.add_argument("--tools", required=True, help="TOML tool table")
    f.add_argument("--step-down", type=float, required=True, help="distance between Z planes, mm")
    f.add_argument("--sample", type=float, default=0.5, help="largest distance between CC points, mm (0.5)")
    f.add_argument("--max-tilt", type=float, default=60.0, help="largest tool tilt from vertical, degrees (60)")
    f.add_argument("--tilt-step", type=float, default=5.0, help="tilt search step, degrees (5)")
    f.add_argument("--order", choices=("contour", "tool"), default="contour",
                   help="contour by contour from the top, or grouped by tool (contour)")
    f.add_argument("--safe-z", type=float, default=None, help="safe plane for rapid moves, mm (part top + 5 + ...)")
    f.add_argument("--tolerance", type=float, default=GOUGE_TOL, help=f"gouge tolerance, mm ({GOUGE_TOL})")
    f.add_argument("--clearance", type=float, default=HOLDER_CLEARANCE,
                   help=f"shank and holder clearance from the part, and rapids' from the stock, mm ({HOLDER_CLEARANCE})")
    f.add_argument("--lead", type=float, default=2.0, help="lead-in/out distance, mm (2)")
    f.add_argument("--machine", default=None,
                   help="the 5-axis machine the path is for (TOML file or shipped name): no move swings the tool axis "
                        "past the pole of its rotaries (it goes round it)")
    f.add_argument("--scallop", type=float, default=None,
                   help="add levels where the surface is shallow so that the scallop between passes stays under MM "
                        "(surfaces flatter than 10 deg are reported, for raster) (off)")
    f.add_argument("--min-run", type=float, default=1.0,
                   help="a stretch of a contour that a ball fits, shorter than this, is left out, mm (1)")
    f.add_argument("--whole-contours", action="store_true",
                   help="seed 004's rule: one ball per contour, and a contour with a point that no ball fits is not "
                        "cut (default: every run of a contour that a ball fits is cut, with its own ball)")
    _add_stock(f)
    f.add_argument("--out", default="out", help="output folder (out)")
    _add_cluster(f)
    _add_device(f)
    f.add_argument("--quiet", action="store_true", help="print nothing but errors")
    f.set_defaults(func=cmd_finish)

    r = sub.add_parser("raster", help="3-axis zigzag finishing (flat, ball or bull-nose)")
    r.add_argument("part", help="part mesh (STL, OBJ, PLY), mm")
    r.add_argument("--tools", required=True, help="TOML tool table")
    r.add_argument("--tool", required=True, help="name of the tool in the table")
    g = r.add_mutually_exclusive_group(required=True)
    g.add_argument("--stepover", type=float, help="distance between passes, mm")
    g.add_argument("--scallop", type=float, help="scallop height that sets the stepover, mm")
    r.add_argument("--angle", type=float, default=0.0, help="machining direction from X, degrees (0)")
    r.add_argument("--sample", type=float, default=0.5, help="largest distance between CL points along a pass, mm (0.5)")
    r.add_argument("--tolerance", type=float, default=GOUGE_TOL, help=f"gouge and chord tolerance, mm ({GOUGE_TOL})")
    r.add_argument("--clearance", type=float, default=HOLDER_CLEARANCE,
                   help=f"distance rapid moves keep from the stock, mm ({HOLDER_CLEARANCE})")
    _add_stock(r)
    r.add_argument("--allowance", type=float, default=0.0, metavar="MM",
                   help="material left on the part, mm: the tool kept that far from it (semi-finishing) (0)")
    r.add_argument("--rest", type=float, default=None, metavar="MM",
                   help="rest machining: with --stock, cut only the pieces of the passes that remove more than MM of it "
                        "(1.5 samples of pass kept on each side); the passes through air are left out (off)")
    r.add_argument("--out", default="out", help="output folder (out)")
    _add_device(r)
    _add_cluster(r)
    r.add_argument("--quiet", action="store_true", help="print nothing but errors")
    r.set_defaults(func=cmd_raster)

    w = sub.add_parser("waterline", help="3-axis Z-level loops (flat, ball or bull-nose)")
    w.add_argument("part", help="part mesh (STL, OBJ, PLY), mm")
    w.add_argument("--tools", required=True, help="TOML tool table")
    w.add_argument("--tool", required=True, help="name of the tool in the table")
    w.add_argument("--step-down", type=float, required=True, help="distance between Z levels, mm")
    w.add_argument("--sample", type=float, default=0.5, help="grid spacing of the loop search, mm (0.5)")
    w.add_argument("--tolerance", type=float, default=GOUGE_TOL, help=f"gouge and chord tolerance, mm ({GOUGE_TOL})")
    w.add_argument("--clearance", type=float, default=HOLDER_CLEARANCE,
                   help=f"distance rapid moves keep from the stock, mm ({HOLDER_CLEARANCE})")
    _add_stock(w)
    w.add_argument("--allowance", type=float, default=0.0, metavar="MM",
                   help="material left on the part, mm: the tool kept that far from it (semi-finishing) (0)")
    w.add_argument("--rest", type=float, default=None, metavar="MM",
                   help="rest machining: with --stock, cut only the pieces of the loops that remove more than MM of it "
                        "(1.5 samples of loop kept on each side) (off)")
    w.add_argument("--out", default="out", help="output folder (out)")
    _add_cluster(w)
    _add_device(w)
    w.add_argument("--quiet", action="store_true", help="print nothing but errors")
    w.set_defaults(func=cmd_waterline)

    pl = sub.add_parser("plunge", help="3- or 5-axis plunge roughing (tréflage)")
    pl.add_argument("part", help="part mesh (STL, OBJ, PLY), mm")
    pl.add_argument("--tools", required=True, help="TOML tool table")
    pl.add_argument("--tool", required=True, help="name of the tool in the table")
    pl.add_argument("--axes", type=int, choices=(3, 5), default=3, help="3: nested contours; 5: hemisphere (3)")
    pl.add_argument("--radial-step", type=float, default=5.0, help="3-axis: distance between plunges along a contour, mm (5)")
    pl.add_argument("--engagement", type=float, default=5.0, help="3-axis: radial engagement between contours, mm (5)")
    pl.add_argument("--theta-step", type=float, default=15.0, help="5-axis: tilt step of the directions, degrees (15)")
    pl.add_argument("--delta-step", type=float, default=30.0, help="5-axis: azimuth step, degrees (30)")
    pl.add_argument("--regions", type=int, default=0,
                    help="5-axis: split the part into K regions, each plunged from its best direction (0: the seed's "
                         "one plunge a direction through the stock centre)")
    pl.add_argument("--allowance", type=float, required=True, help="material left on the part, mm")
    pl.add_argument("--clearance", type=float, default=5.0, help="clearance plane above the stock, mm (5)")
    pl.add_argument("--stock", default=None,
                    help="3-axis: a closed stock mesh (work frame) holding the part: the plunges cover its box "
                         "(default: the part's box)")
    pl.add_argument("--simulate", type=float, default=None,
                    help="also cut the path from the part's box with dexels of this step, mm, and report the volumes")
    pl.add_argument("--out", default="out", help="output folder (out)")
    _add_device(pl)
    pl.add_argument("--quiet", action="store_true", help="print nothing but errors")
    pl.set_defaults(func=cmd_plunge)

    v = sub.add_parser("verify", help="check an APT CL file or G-code for gouges and collisions")
    v.add_argument("part", help="part mesh (STL, OBJ, PLY), mm")
    v.add_argument("toolpath", help="APT CL file (.cl) or G-code (.nc, .ngc, .gcode, .tap)")
    v.add_argument("--tools", required=True, help="TOML tool table")
    v.add_argument("--machine", default=None,
                   help="G-code's machine (TOML file or shipped name): 5-axis words are read through its kinematics")
    v.add_argument("--tolerance", type=float, default=GOUGE_TOL, help=f"gouge tolerance, mm ({GOUGE_TOL})")
    v.add_argument("--step", type=float, default=0.5,
                   help="distance between the poses first measured along a move, mm (every interval between them is "
                        "then certified or halved: the result does not depend on it, its speed does) (0.5)")
    _add_stock(v, "--allowance", default=0.0)
    v.add_argument("--worst", type=int, default=10, help="how many worst cases to print (10)")
    v.add_argument("--out", default=None, help="write the report as JSON to this file")
    _add_device(v)
    _add_cluster(v)
    v.add_argument("--quiet", action="store_true", help="no warnings")
    v.set_defaults(func=cmd_verify)

    d = sub.add_parser("dexel", help="triple-dexel model of a closed part")
    d.add_argument("part", help="part mesh (STL, OBJ, PLY), mm; must be closed")
    d.add_argument("--step", type=float, required=True, help="distance between grid lines, mm")
    d.add_argument("--index", choices=("bvh", "cells", "kmeans"), default="bvh",
                   help="how lines find their triangles: BVH, or the seed's cells or k-means partitions (bvh)")
    d.add_argument("--partitions", default="1", help="number of cells or clusters, or 'auto' (K-optimal helper) (1)")
    d.add_argument("--kmax", type=int, default=27, help="largest K the K-optimal helper tries (27)")
    d.add_argument("--init", choices=("k-means++", "random"), default="k-means++", help="k-means initialisation")
    d.add_argument("--minibatch", action="store_true", help="mini-batch k-means")
    _add_device(d)
    _add_cluster(d)
    d.add_argument("--out", default=None, help="model file: .npz (compact binary) or .td (seed's ASCII) (PART.dexel.npz)")
    d.add_argument("--quiet", action="store_true", help="print nothing but errors")
    d.set_defaults(func=cmd_dexel)

    s = sub.add_parser("simulate", help="cut a tool path from a stock and measure it against the design")
    s.add_argument("--design", required=True, help="design part mesh (STL, OBJ, PLY), mm; closed")
    g = s.add_mutually_exclusive_group()
    g.add_argument("--stock", default=None, help="'box' (the design's box, default) or a closed stock mesh")
    g.add_argument("--allowance", type=float, default=None, help="stock = design dexels lengthened by MM at both ends")
    s.add_argument("--toolpath", required=True,
                   help="APT CL file (.cl) or G-code (.nc, .ngc, .gcode, .tap; 5-axis with --machine)")
    s.add_argument("--tools", required=True, help="TOML tool table")
    s.add_argument("--tool", default=None, help="tool name for G-code without T words")
    s.add_argument("--machine", default=None,
                   help="G-code's machine (TOML file or shipped name): 5-axis words are read through its kinematics")
    s.add_argument("--step", type=float, required=True, help="dexel grid step, mm")
    s.add_argument("--tolerance", type=float, default=GOUGE_TOL, help=f"deviation tolerance band ±MM ({GOUGE_TOL})")
    s.add_argument("--mode", choices=("sweep", "points"), default="sweep",
                   help="exact swept volume of every move, or the tool at the points only (seed) (sweep)")
    s.add_argument("--out", default="sim", help="output folder (sim)")
    s.add_argument("--outputs", default="all",
                   help="what to write beside summary.json and deviation.json: a comma list of summary (those alone), "
                        "deviation (deviation.npz: every dexel end), mesh (machined.stl), or all (all)")
    _add_device(s)
    _add_cluster(s)
    s.add_argument("--quiet", action="store_true", help="print nothing but errors")
    s.set_defaults(func=cmd_simulate)

    n = sub.add_parser("analyze", help="triangle and vertex parameters, visibility and accessibility")
    n.add_argument("part", help="part mesh (STL, OBJ, PLY), mm")
    n.add_argument("--direction", default="0,0,1", help="direction X,Y,Z (0,0,1)")
    n.add_argument("--weighting", choices=("area", "angle", "uniform"), default="area", help="vertex normals (area)")
    n.add_argument("--theta-step", type=float, default=None, help="also map accessibility over the hemisphere, degrees")
    n.add_argument("--delta-step", type=float, default=10.0, help="azimuth step of the map, degrees (10)")
    n.add_argument("--out", default="analysis", help="output folder (analysis)")
    _add_device(n)
    n.add_argument("--quiet", action="store_true", help="print nothing but errors")
    n.set_defaults(func=cmd_analyze)

    jb = sub.add_parser("job", help="machine a part from its stock in one run: operations in order, rest machining, "
                                    "one program and one report")
    jb.add_argument("jobfile", help="the job's TOML file ([part], [stock], [[fixtures]], [[operations]], tools, machine)")
    jb.add_argument("--out", default="job", help="output folder (job)")
    jb.add_argument("--no-report", action="store_true", help="do not write report.html")
    jb.add_argument("--device", choices=("cpu", "cuda", "auto"), default=None,
                    help="run the heavy kernels on the CPU or an NVIDIA GPU (default: the job file's, else auto)")
    _add_cluster(jb)
    jb.add_argument("--quiet", action="store_true", help="print nothing but errors")
    jb.add_argument("--json", action="store_true", help="print job.json on stdout (and nothing on stderr)")
    jb.set_defaults(func=cmd_job)

    rp = sub.add_parser("report", help="one self-contained HTML file with 3D views and tables of run folders")
    rp.add_argument("folders", nargs="+", help="folders written by finish, raster, waterline, plunge, dexel or simulate")
    rp.add_argument("--out", default="report.html", help="HTML file to write (report.html)")
    rp.add_argument("--quiet", action="store_true", help="print nothing but errors")
    rp.set_defaults(func=cmd_report)

    tm = sub.add_parser("time", help="machining time of a tool path on a jerk-limited machine")
    tm.add_argument("toolpath", help="APT CL file (.cl) or G-code (.nc, .ngc, .gcode, .tap; 5-axis on a 5-axis --machine)")
    tm.add_argument("--machine", required=True,
                    help="TOML machine file, or a shipped one: generic-3axis, seed-002")
    tm.add_argument("--tools", default=None,
                    help="TOML tool table (default: tools.toml beside the tool path, as choose writes it)")
    tm.add_argument("--tool", default=None, help="tool name for G-code without T words")
    tm.add_argument("--feed", type=float, default=None,
                    help="cutting feed for every feed move, mm/min (default: as programmed, else the machine's)")
    tm.add_argument("--out", default=None, help="write the summary as JSON to this file")
    tm.set_defaults(func=cmd_time)
    po = sub.add_parser("post", help="G-code for a machine from an APT CL file (3- and 5-axis)")
    po.add_argument("toolpath", help="APT CL file")
    po.add_argument("--machine", required=True,
                    help="TOML machine file, or a shipped one: generic-3axis, linuxcnc-3axis, grbl-3axis, "
                         "table-table-ac, head-table-bc, head-head-ca")
    po.add_argument("--tools", default=None,
                    help="TOML tool table (default: tools.toml beside the tool path, as choose writes it)")
    po.add_argument("--out", default=None, help="program file to write (program.nc beside the tool path)")
    po.add_argument("--origin", default=None, metavar="X,Y,Z",
                    help="the program's zero in machine coordinates (work offset), for the travel of X Y Z "
                         "(default: each axis's span must fit its travel)")
    po.add_argument("--clearance", type=float, default=None, metavar="Z",
                    help="5-axis: Z (work coordinates, mm) above which the whole tool stays while the rotaries "
                         "unwind or swing over; the part's top plus a margin (default: the path's highest tip)")
    po.add_argument("--tolerance", type=float, default=0.005,
                    help="5-axis: largest tip deviation from a CL move between blocks, mm (0.005)")
    po.add_argument("--feed", type=float, default=None,
                    help="feed for the moves the CL file gives none, mm/min (default: the machine's)")
    po.add_argument("--json", action="store_true", help="print the report as JSON on stdout (and nothing on stderr)")
    po.set_defaults(func=cmd_post)
    ch = sub.add_parser("choose", help="tool choice, zones and directions by machining time (3-axis or 3+2)")
    ch.add_argument("surface", help="surface: patch TOML (Bezier/B-spline/NURBS), 'rubio' or 'choi', or a mesh (STL, OBJ, PLY)")
    ch.add_argument("--tool-pair", default=None, metavar="D,r",
                    help="a ball of diameter D and a bull-nose D with corner radius r, mm (e.g. 10,2)")
    ch.add_argument("--tools", default=None, help="TOML tool table: its ball and bull-nose cutters are the candidates")
    ch.add_argument("--scallop", type=float, required=True, help="largest scallop height, mm")
    ch.add_argument("--zones", default="auto", help="number of clusters K, or auto (best of 1..--k-max) (auto)")
    ch.add_argument("--k-max", type=int, default=6, help="largest K tried by --zones auto (6)")
    ch.add_argument("--axes", choices=("3", "3+2"), default="3", help="3-axis or 3+2-axis (3)")
    ch.add_argument("--optimise", type=int, default=0, metavar="EVALS",
                    help="NOMAD black-box evaluations for the weights, directions, tools (and tilts) (0: none)")
    ch.add_argument("--machine", default="generic-3axis",
                    help="TOML machine file, or a shipped one: generic-3axis, seed-002 (generic-3axis)")
    ch.add_argument("--cluster", choices=("kmeans", "rpcl", "ward"), default="kmeans", help="clustering (kmeans)")
    ch.add_argument("--metric", choices=("euclidean", "mahalanobis", "std", "std2", "pca"), default="euclidean",
                    help="clustering metric (euclidean)")
    ch.add_argument("--grid", type=int, default=80, help="sampling grid, cells a side (80)")
    ch.add_argument("--mesh-step", type=float, default=0.5, help="triangle size of a patch's mesh, mm (0.5)")
    ch.add_argument("--sample", type=float, default=0.5, help="drop-cutter spacing along a pass, mm (0.5)")
    ch.add_argument("--min-zone", type=float, default=0.01,
                    help="zones under this fraction of the cells join a neighbour (0.01)")
    ch.add_argument("--seed", type=int, default=0, help="random seed of RPCL and NOMAD (0)")
    ch.add_argument("--out", default="choose", help="output folder (choose)")
    ch.add_argument("--quiet", action="store_true", help="print nothing but errors")
    _add_device(ch)
    ch.set_defaults(func=cmd_choose)
    for sp in (f, r, w, pl, v, d, s, n, ch):
        sp.add_argument("--flip", action="store_true",
                        help="turn every face of the part over (reverse its normals): for a part wound inside out, "
                             "or an open surface that faces away from the spindle")
    for sp in (f, r, w, pl, v, d, s, n):
        _add_setup(sp)
    for sp in (f, r, w, pl, d, s, rp, tm, ch):
        sp.add_argument("--json", action="store_true", help="print the summary as JSON on stdout (and nothing on stderr)")
    return p


def _flags(exc) -> str:
    """An error's message with the parameters it names as this command's flags (``step_down`` ->
    ``--step-down``: the API's keyword arguments are the options' names)."""
    return getattr(exc, "flags_message", None) or str(exc)


def main(argv=None) -> int:
    _status_line[0] = False
    _run[0] = None
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # usage errors (2), --help and --version (0)
        if exc.code:
            _clear_after_usage_error(argv)
        return int(exc.code or 0)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    try:
        if args.command in FOLDER_OUTPUTS:
            _results([os.path.join(args.out, n) for n in FOLDER_OUTPUTS[args.command]])  # earlier results go now
        return args.func(args)
    except InputError as exc:
        _end_status()
        print(f"meshmill: error: {_flags(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        _end_status()
        print("meshmill: interrupted", file=sys.stderr)
        return 130
    except MemoryError:  # an estimate fell short: still one line, and nothing written
        _end_status()
        print(f"meshmill: error: out of memory ({memory.size(memory.available_bytes())} available): use a coarser "
              "step, sample or step-down", file=sys.stderr)
        return 2
    finally:
        if _run[0] is not None and not _run[0].done:
            _run[0].abort()  # a run that did not complete leaves no result behind


if __name__ == "__main__":
    sys.exit(main())
