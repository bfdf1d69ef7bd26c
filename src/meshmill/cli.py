"""Command line: argument parsing, progress and error messages; no geometry here.

Bad input ends with one line on stderr and exit code 2; ``verify`` exits 1 when it finds problems.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

from . import __version__, memory
from .errors import InputError
from .runfiles import RunFiles
from .tolerances import GOUGE_TOL, HOLDER_CLEARANCE


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(2, f"meshmill: error: {message}\n")


_status_line = [False]  # a progress line is open on the terminal (to be ended before other text)
_run = [None]  # the result files of the command running (RunFiles), committed when it succeeds

# the files each command writes into its --out folder, the summary last
FOLDER_OUTPUTS = {
    "finish": ("contours.npz", "toolpath.cl", "part.stl", "summary.json"),
    "raster": ("toolpath.cl", "part.stl", "summary.json"),
    "waterline": ("toolpath.cl", "part.stl", "summary.json"),
    "plunge": ("toolpath.cl", "part.stl", "summary.json"),
    "simulate": ("deviation.npz", "machined.stl", "deviation.json", "summary.json"),
    "analyze": ("analysis.npz", "summary.json"),
    "choose": ("tools.toml", "toolpath.cl", "zones.npz", "summary.json"),
}


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


def _device(args):
    """The backend for ``--device`` (auto: CUDA when a usable GPU is present); the commands say it
    with their results."""
    from .kernels.backend import resolve

    return resolve(args.device)


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


def _add_device(parser):
    parser.add_argument("--device", choices=("cpu", "cuda", "auto"), default="auto",
                        help="run the heavy kernels on the CPU or an NVIDIA GPU (needs meshmill[cuda]); "
                             "auto: the GPU when a usable one is present (auto)")


def _setup(args):
    """The :class:`~meshmill.geometry.placement.Setup` of ``--units``, ``--up`` and ``--origin``."""
    from .geometry.placement import Setup

    setup = Setup(units=getattr(args, "units", "mm"), up=getattr(args, "up", "+Z"),
                  origin=getattr(args, "origin", "file"), scale=getattr(args, "scale", 1.0))
    setup.check()
    return setup


def _load_part(args, path, flip=None, placed=True):
    """The part ``path`` (its faces turned over with ``--flip``) placed into the work frame by
    ``--units``, ``--up`` and ``--origin`` (``placed=False``: a file already in the work frame, a
    stock), its warnings said."""
    from .geometry.mesh import load_mesh

    mesh = load_mesh(path, flip=getattr(args, "flip", False) if flip is None else flip,
                     setup=_setup(args) if placed else None)
    for w in mesh.warnings:
        _say(args, f"warning: {w}")
    return mesh


def _write_part(path, mesh):
    """The placed part as a binary STL (mm, work frame), for any program to check a path against."""
    import trimesh

    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(path, file_type="stl")


def _stock_mesh(args):
    """The closed stock mesh of ``--stock FILE``, or None."""
    path = getattr(args, "stock", None)
    if path in (None, "box"):
        return None
    stock = _load_part(args, path, flip=False, placed=False)
    if not stock.closed:
        raise InputError(f"{path}: the stock mesh is open (not watertight)")
    return stock


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
    writes it); sets ``args.tools`` to the file read."""
    from .tools.table import load_tools

    if args.tools is None:
        beside = os.path.join(os.path.dirname(os.path.abspath(args.toolpath)), "tools.toml")
        if not os.path.exists(beside):
            raise InputError(f"no --tools given and no tools.toml beside {args.toolpath}: give the tool table")
        args.tools = beside
    return load_tools(args.tools)


def _write_json(path, data):
    try:
        with open(path, "w") as fh:
            json.dump(data, fh, indent=2, default=float)
            fh.write("\n")
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror})") from None


def _results(paths) -> RunFiles:
    """The result files of this run (earlier results under their names are removed now; the new
    ones appear when the command succeeds)."""
    _run[0] = RunFiles(paths)
    return _run[0]


def _folder_results(command, out) -> tuple[str, RunFiles]:
    """``(folder, RunFiles)`` of a command that writes :data:`FOLDER_OUTPUTS` into ``out`` (made
    once a run, by :func:`main` before the command checks its options)."""
    paths = [os.path.abspath(os.path.join(out, name)) for name in FOLDER_OUTPUTS[command]]
    if _run[0] is not None and _run[0].paths == paths:
        return out, _run[0]
    return out, _results(paths)


def _clear_after_usage_error(argv):
    """A command refused by the parser still must not leave an earlier run's files looking like its
    own: remove the results in the folder its ``--out`` names (or the default folder)."""
    if not argv or argv[0] not in FOLDER_OUTPUTS:
        return
    out = {"finish": "out", "raster": "out", "waterline": "out", "plunge": "out", "simulate": "sim",
           "analyze": "analysis", "choose": "choose"}[argv[0]]
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


def cmd_finish(args):
    import numpy as np

    from .ops.finish import FinishParams, finish
    from .tools.table import load_tools
    from .toolpath.cldata import write_apt

    out, run = _folder_results("finish", args.out)
    t0 = time.perf_counter()
    tools = load_tools(args.tools)
    mesh = _load_part(args, args.part)
    load_s = time.perf_counter() - t0
    params = FinishParams(step_down=args.step_down, sample=args.sample, max_tilt=args.max_tilt,
                          tilt_step=args.tilt_step, order=args.order, safe_z=args.safe_z, tol=args.tolerance,
                          clearance=args.clearance, lead=args.lead, stock_allowance=args.stock_allowance,
                          min_run=args.min_run, whole_contours=args.whole_contours, scallop=args.scallop)
    params.check()
    stock = _stock_mesh(args)
    device = _device(args)
    machine = None
    if args.machine:
        from .machine.config import load_machine

        machine = load_machine(args.machine)
    tp, summary, detail = finish(mesh, tools, params, progress=_progress(args), device=device, stock=stock,
                                 machine=machine)
    summary["device"] = device
    summary["tools_file"] = os.path.abspath(args.tools)
    con = detail["contours"]
    from .ops.finish import AREA_STATUS

    np.savez_compressed(run.tmp(os.path.join(out, "contours.npz")), points=con.points, offsets=con.offsets, z=con.z,
                        closed=con.closed, machinable=detail["contour_tool"] >= 0,
                        surface_points=detail["surface_points"], surface_status=detail["surface_status"],
                        status_names=np.array(AREA_STATUS), raster_from=detail["raster_from"],
                        raster_reach=detail["raster_reach"])
    summary["part"] = {"file": os.path.abspath(args.part), **mesh.summary()}
    summary["seconds"]["load"] = round(load_s, 4)
    summary["seconds"]["total"] = round(summary["seconds"]["total"] + load_s, 4)
    write_apt(run.tmp(os.path.join(out, "toolpath.cl")), tp, tools, partno=os.path.basename(args.part))
    _write_part(run.tmp(os.path.join(out, "part.stl")), mesh)
    _write_json(run.tmp(os.path.join(out, "summary.json")), summary)
    run.commit()
    v = summary["verify"]
    _say(args, f"contours {summary['contours']} (machinable {summary['machinable_contours']}), "
               f"CC points {summary['cc_points']}, left out {summary['points_left_out']}, "
               f"tilted {summary['points_tilted']}, passes {summary['passes']}")
    for name, entry in summary["tools_used"].items():
        _say(args, f"  {name}: {entry['contours']} contour(s), {entry['cc_points']} CC points")
    _say(args, f"verify: {'OK' if v['ok'] else 'PROBLEMS'} ({v['poses_checked']} poses, max gouge "
               f"{v['max_gouge']:.4f} mm, tolerance {v['tolerance']} mm)")
    _say(args, f"wrote {os.path.join(out, 'toolpath.cl')} and summary.json in {summary['seconds']['total']:.1f} s "
               f"(device {summary['device']})")
    _finish_json(args, summary)
    return 0 if v["ok"] else 1


def _three_axis(args, run):
    """Shared tail of raster, waterline and plunge: load, run, write toolpath.cl and summary.json."""
    from .tools.table import load_tools
    from .toolpath.cldata import write_apt

    out, files = _folder_results(args.command, args.out)
    t0 = time.perf_counter()
    tools = load_tools(args.tools)
    mesh = _load_part(args, args.part)
    load_s = time.perf_counter() - t0
    device = _device(args)
    tp, summary = run(mesh, tools, device)
    summary["device"] = device
    summary["tools_file"] = os.path.abspath(args.tools)
    summary["part"] = {"file": os.path.abspath(args.part), **mesh.summary()}
    summary["seconds"]["load"] = round(load_s, 4)
    summary["seconds"]["total"] = round(summary["seconds"]["total"] + load_s, 4)
    write_apt(files.tmp(os.path.join(out, "toolpath.cl")), tp, tools, partno=os.path.basename(args.part))
    _write_part(files.tmp(os.path.join(out, "part.stl")), mesh)
    _write_json(files.tmp(os.path.join(out, "summary.json")), summary)
    files.commit()
    v = summary["verify"]
    _say(args, f"{summary['cl_points']} CL points, {summary['moves']} moves; verify: {'OK' if v['ok'] else 'PROBLEMS'} "
               f"(max gouge {v['max_gouge']:.4f} mm, tolerance {v['tolerance']} mm)")
    _say(args, f"wrote {os.path.join(out, 'toolpath.cl')} and summary.json in {summary['seconds']['total']:.1f} s "
               f"(device {summary['device']})")
    _finish_json(args, summary)
    return 0 if v["ok"] else 1


def cmd_raster(args):
    from .ops.raster import RasterParams, raster

    params = RasterParams(stepover=args.stepover, scallop=args.scallop, angle=args.angle, sample=args.sample,
                          tol=args.tolerance, stock_allowance=args.stock_allowance, clearance=args.clearance)
    params.check()
    return _three_axis(args, lambda mesh, tools, device: raster(mesh, tools, args.tool, params, progress=_progress(args),
                                                                 device=device, stock=_stock_mesh(args)))


def cmd_waterline(args):
    from .ops.waterline import WaterlineParams, waterline

    params = WaterlineParams(step_down=args.step_down, sample=args.sample, tol=args.tolerance,
                             stock_allowance=args.stock_allowance, clearance=args.clearance)
    params.check()

    def run(mesh, tools, device):
        tp, summary, _ = waterline(mesh, tools, args.tool, params, progress=_progress(args), device=device,
                                   stock=_stock_mesh(args))
        return tp, summary

    return _three_axis(args, run)


def cmd_plunge(args):
    from .ops.plunge import PlungeParams, plunge3, plunge5

    params = PlungeParams(radial_step=args.radial_step, engagement=args.engagement, allowance=args.allowance,
                          clearance=args.clearance, theta_step=args.theta_step, delta_step=args.delta_step,
                          regions=args.regions)
    run = plunge3 if args.axes == 3 else plunge5
    if args.simulate is not None and not (math.isfinite(args.simulate) and args.simulate > 0):
        raise InputError(f"--simulate must be a positive dexel step in mm, got {args.simulate}")

    def plunge_and_simulate(mesh, tools, device):
        params.device = device
        tp, summary = run(mesh, tools, args.tool, params, progress=_progress(args))
        if args.simulate is not None:
            from .ops.simulate import simulate

            dev, sim, *_ = simulate(mesh, tp, tools, args.simulate, stock="box", progress=_progress(args),
                                    device=device)
            v = sim["volumes_mm3"]
            summary["simulation"] = {"step": args.simulate, "stock_volume": v["stock"], "removed_volume": v["removed"],
                                     "remaining_volume": v["remaining"], "gouged_volume": v["gouged"],
                                     "gouge_max": dev["gouge_max"], "seconds": sim["seconds"]["total"]}
            _say(args, f"simulated at {args.simulate:g} mm: removed {v['removed']:.1f} of {v['stock']:.1f} mm^3, "
                       f"{v['remaining']:.1f} mm^3 left over the part")
        return tp, summary

    return _three_axis(args, plunge_and_simulate)


def cmd_verify(args):
    from .kernels.backend import solid_kernels
    from .machine.config import load_machine
    from .ops.simulate import read_toolpath
    from .ops.verify import StockCheck, verify_toolpath
    from .tools.table import load_tools

    run = _results([args.out]) if args.out else None
    if not (math.isfinite(args.step) and args.step >= 1e-4):
        raise InputError(f"--step must be a finite number of at least 0.0001 mm, got {args.step}")
    if not (math.isfinite(args.tolerance) and args.tolerance >= 0):
        raise InputError(f"--tolerance must be a finite number >= 0, got {args.tolerance}")
    if not (math.isfinite(args.stock_allowance) and args.stock_allowance >= 0):
        raise InputError(f"--allowance must be a number of mm >= 0, got {args.stock_allowance}")
    tools = load_tools(args.tools)
    machine = load_machine(args.machine) if args.machine else None
    mesh = _load_part(args, args.part)
    stock = _stock_mesh(args)
    tp, warnings = read_toolpath(args.toolpath, tools, machine=machine)
    for w in warnings:
        _say(args, f"warning: {w}")
    device = _device(args)
    floor = min(mesh.bounds[0, 2], stock.bounds[0, 2]) if stock is not None else None
    check = StockCheck(allowance=0.0 if stock is not None else args.stock_allowance,
                       kern=solid_kernels(stock, device) if stock is not None else None)
    report = verify_toolpath(solid_kernels(mesh, device, floor), tp, tools, args.tolerance, args.step,
                             worst=args.worst, stock=check)
    report.pop("problem_moves")
    if run:
        _write_json(run.tmp(args.out), report)
        run.commit()
    pieces = 0 < report["lines"] < report["moves"]  # G-code: arcs and rotary blocks are read as several moves

    def count(n, kind):
        lines = report["problem_lines"][kind]
        return f"{n}" + (f" (on {lines} line{'s' * (lines != 1)})" if pieces and n else "")

    print(f"{report['moves']} moves" + (f" from {report['lines']} program lines" if pieces else "")
          + f", {report['poses_checked']} poses checked: "
          f"{count(report['gouging_moves'], 'gouge')} gouging, {count(report['colliding_moves'], 'collision')} colliding, "
          f"{count(report['rapid_moves_touching'], 'rapid')} rapid into the {'stock' if stock is not None or args.stock_allowance else 'part'}; max gouge {report['max_gouge']:.4f} mm, "
          f"max collision {report['max_collision']:.4f} mm (tolerance {report['tolerance']} mm; device {device})")
    for line in report["worst"]:
        print("  " + line)
    print("OK" if report["ok"] else "PROBLEMS FOUND")
    return 0 if report["ok"] else 1


def cmd_dexel(args):
    from .ops.simulate import dexel_model
    from .simulation.dexel import export_td, save_npz

    if args.index != "bvh" and args.device == "auto":
        args.device = "cpu"  # the seed's indexes run on the CPU only
    out = args.out or os.path.splitext(os.path.basename(args.part))[0] + ".dexel.npz"
    if not out.lower().endswith((".td", ".npz")):
        out += ".npz"
    folder = os.path.dirname(os.path.abspath(out))
    run = _results([out, os.path.join(folder, "summary.json")])
    mesh = _load_part(args, args.part)
    device = _device(args)
    model, summary = dexel_model(mesh, args.step, args.index, args.partitions, args.init, args.minibatch,
                                 args.kmax, progress=_progress(args), device=device)
    model.name = os.path.basename(args.part)
    if out.lower().endswith(".td"):
        export_td(run.tmp(out), model)
    else:
        save_npz(run.tmp(out), model)
    summary["part"] = {"file": os.path.abspath(args.part), **mesh.summary()}
    summary["file"] = os.path.abspath(out)
    _write_json(run.tmp(os.path.join(folder, "summary.json")), summary)
    run.commit()
    for w in summary["warnings"]:
        _say(args, f"warning: {w}")
    d = summary["dexels"]
    _say(args, f"dexels X {d['X']:,}, Y {d['Y']:,}, Z {d['Z']:,}; volume {summary['volume_mm3']:.3f} mm^3 "
               f"(mesh {_mesh_volume(mesh):.3f}); cast in {model.info['cast_seconds']:.2f} s with {model.info['index']}")
    _say(args, f"wrote {out} and {os.path.join(folder, 'summary.json')} (device {device})")
    _finish_json(args, summary)
    return 0


def _mesh_volume(mesh):
    import numpy as np

    tri = mesh.vertices[mesh.faces]
    return float(np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0)


def cmd_simulate(args):
    import numpy as np

    from .machine.config import load_machine
    from .ops.simulate import read_toolpath, simulate
    from .tools.table import load_tools

    out, run = _folder_results("simulate", args.out)
    if not (math.isfinite(args.step) and args.step > 0):
        raise InputError(f"--step must be a positive number of mm, got {args.step}")
    tools = load_tools(args.tools)
    design = _load_part(args, args.design)
    stock = "box"
    if args.stock not in (None, "box"):
        stock = _load_part(args, args.stock, flip=False, placed=False)
        if not stock.closed:
            raise InputError(f"{args.stock}: the stock mesh is open (not watertight)")
    machine = load_machine(args.machine) if args.machine else None
    tp, warnings = read_toolpath(args.toolpath, tools, args.tool, machine)
    for w in warnings:
        _say(args, f"warning: {w}")
    device = _device(args)
    deviation, summary, _, (verts, faces), samples = simulate(
        design, tp, tools, args.step, stock=stock, allowance=args.allowance, tolerance=args.tolerance,
        mode=args.mode, progress=_progress(args), device=device)
    summary["device"] = device
    summary["tools_file"] = os.path.abspath(args.tools)
    np.savez_compressed(run.tmp(os.path.join(out, "deviation.npz")), points=samples["points"], e=samples["e"])
    summary["design"] = {"file": os.path.abspath(args.design), **design.summary()}
    summary["toolpath"] = {"file": os.path.abspath(args.toolpath), "warnings": warnings}
    if len(faces):
        import trimesh

        trimesh.Trimesh(verts, faces, process=False).export(run.tmp(os.path.join(out, "machined.stl")))
    _write_json(run.tmp(os.path.join(out, "deviation.json")), deviation)
    _write_json(run.tmp(os.path.join(out, "summary.json")), summary)
    run.commit()
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
    _say(args, f"wrote deviation.json, summary.json, machined.stl in {out} ({summary['seconds']['total']:.1f} s, "
               f"device {device})")
    _finish_json(args, summary)
    return 1 if summary["rapid_moves_cutting"] or summary["colliding_moves"] else 0


def cmd_analyze(args):
    import numpy as np

    from .geometry import analysis
    from .geometry.bvh import build_bvh

    out, run = _folder_results("analyze", args.out)
    try:
        direction = [float(v) for v in args.direction.split(",")]
    except ValueError:
        raise InputError(f"--direction must be three numbers X,Y,Z, got '{args.direction}'") from None
    if len(direction) != 3:
        raise InputError(f"--direction must be three numbers X,Y,Z, got '{args.direction}'")
    mesh = _load_part(args, args.part)
    t0 = time.perf_counter()
    bvh = build_bvh(mesh.vertices, mesh.faces)
    tri = analysis.triangle_parameters(mesh)
    normals = analysis.vertex_normals(mesh, args.weighting)
    flags = analysis.visibility(mesh, direction, args.weighting, bvh)
    seconds = {"visibility": round(time.perf_counter() - t0, 4)}
    summary = {
        "part": {"file": os.path.abspath(args.part), **mesh.summary()},
        "direction": analysis.unit_direction(direction).round(9).tolist(),
        "weighting": args.weighting,
        "area_mm2": {"total": float(tri["area"].sum()), "min": float(tri["area"].min()), "max": float(tri["area"].max())},
        "boundary_edges": int((tri["neighbours"] < 0).sum()),
        **{k: int(v.sum()) for k, v in flags.items()},
    }
    arrays = {"vertex_normals": normals, **tri, **flags}
    if args.theta_step is not None:
        t1 = time.perf_counter()
        dirs = analysis.hemisphere(args.theta_step, args.delta_step)
        share, reached = analysis.accessibility_map(mesh, dirs, bvh)
        seconds["map"] = round(time.perf_counter() - t1, 4)
        summary["map"] = {"directions": len(dirs), "best_direction": dirs[int(np.argmax(share))].round(9).tolist(),
                          "best_share": float(share.max()), "never_reached_triangles": int((reached == 0).sum())}
        arrays.update(map_directions=dirs, map_share=share, triangles_reached=reached)
    summary["seconds"] = seconds
    np.savez_compressed(run.tmp(os.path.join(out, "analysis.npz")), **arrays)
    _write_json(run.tmp(os.path.join(out, "summary.json")), summary)
    run.commit()
    _say(args, f"{summary['visible_triangles']} of {len(mesh.faces)} triangles visible along {summary['direction']}, "
               f"{summary['accessible_triangles']} accessible; {summary['accessible_vertices']} of {len(mesh.vertices)} "
               f"vertices accessible ({seconds['visibility']:.2f} s)")
    if "map" in summary:
        m = summary["map"]
        _say(args, f"map over {m['directions']} directions: best {m['best_direction']} reaches {100 * m['best_share']:.1f} % "
                   f"of the area; {m['never_reached_triangles']} triangles reached by none")
    _say(args, f"wrote analysis.npz and summary.json in {out}")
    return 0


def cmd_report(args):
    from .report import write_report

    out = args.out
    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        raise InputError(f"{folder}: no such folder for --out")
    run = _results([out])
    info = write_report(args.folders, run.tmp(out), progress=_progress(args))
    run.commit()
    info["file"] = os.path.abspath(out)
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
    import numpy as np

    from .machine.config import load_machine
    from .machine.timing import programmed_feeds, rotary_seconds, tool_times
    from .ops.simulate import TOOLPATH_GCODE, read_toolpath

    run = _results([args.out]) if args.out else None
    if args.feed is not None and not (math.isfinite(args.feed) and args.feed > 0):
        raise InputError(f"--feed must be a positive number of mm/min, got {args.feed}")
    machine = load_machine(args.machine)
    tools = _tools_beside(args)
    is_gcode = os.path.splitext(args.toolpath)[1].lower() in TOOLPATH_GCODE
    tp, warnings = read_toolpath(args.toolpath, tools, args.tool, machine if is_gcode else None)
    feed_move = ~tp.rapid[1:]
    nominal = f"the machine's {machine.kinematics.feed * 60.0:g} mm/min"
    if args.feed is not None:
        feed, unset = np.full(len(tp), args.feed / 60.0), 0
        notes = [f"feed {args.feed:g} mm/min (--feed) on every feed move"]
    else:
        feed, more = programmed_feeds(args.toolpath, tp.line, is_gcode, tp.tip)
        warnings += more
        unset = int((feed_move & np.isnan(feed[1:])).sum())
        if not unset:
            notes = ["feeds as programmed"]
        elif unset == feed_move.sum():
            notes = [f"no feed programmed: every feed move at {nominal}"]
        else:
            notes = [f"{unset} of {feed_move.sum()} feed moves without a programmed feed: {nominal}"]
    rotary = None
    if np.ptp(tp.axis, axis=0).max() > 1e-9:
        if machine.chain.type == "3-axis":
            notes.append("the tool axis turns along the path: rotary-axis motion is not timed on a 3-axis machine")
        else:
            try:
                rotary = rotary_seconds(machine, tp.tip, tp.axis, tools, tp.tool)
                notes.append(f"rotary axes at {machine.rotary_rapid * 60.0:g} deg/min bound each move's time")
            except InputError as exc:
                notes.append(f"rotary-axis motion is not timed ({exc})")
    times = tool_times(tp.tip, tp.rapid, tp.tool, machine, feed, rotary)
    summary = {"operation": "time", "toolpath": os.path.abspath(args.toolpath), "moves": len(tp),
               "machine": machine.summary(), "tools_file": os.path.abspath(args.tools), "notes": notes,
               "feed_moves": int(feed_move.sum()), "feed_moves_at_machine_feed": unset,
               "tools": {tools[t].name: entry for t, entry in times["tools"].items()}, "total": times["total"]}
    if run:
        _write_json(run.tmp(args.out), summary)
        run.commit()
    for w in warnings:
        _say(args, f"warning: {w}")
    if args.json:
        _finish_json(args, summary)
        return 0
    print(f"machine: {machine.name}; {'; '.join(notes)}")
    print(f"{'tool':<12}{'cutting s':>11}{'rapid s':>10}{'changes':>8}{'change s':>10}{'total s':>11}"
          f"{'cutting mm':>13}{'rapid mm':>11}{'stops':>9}")
    for name, e in [*summary["tools"].items(), ("total", summary["total"])]:
        print(f"{name:<12}{e['cutting_s']:>11.1f}{e['rapid_s']:>10.1f}{e['tool_changes']:>8}{e['tool_change_s']:>10.1f}"
              f"{e['total_s']:>11.1f}{e['cutting_mm']:>13.1f}{e['rapid_mm']:>11.1f}{e['stops']:>9}")
    print(f"machining time {_clock(summary['total']['total_s'])} (h:mm:ss)")
    return 0


def cmd_post(args):
    import numpy as np

    from .machine.config import load_machine
    from .machine.post import post_program
    from .machine.timing import programmed_feeds
    from .toolpath.cldata import MAX_COORDINATE, read_apt

    out = args.out or os.path.join(os.path.dirname(os.path.abspath(args.toolpath)), "program.nc")
    run = _results([out])
    if args.feed is not None and not (math.isfinite(args.feed) and args.feed > 0):
        raise InputError(f"--feed must be a positive number of mm/min, got {args.feed}")
    if not (math.isfinite(args.tolerance) and args.tolerance > 0):
        raise InputError(f"--tolerance must be a positive number of mm, got {args.tolerance}")
    machine = load_machine(args.machine)
    tools = _tools_beside(args)
    tp, warnings = read_apt(args.toolpath, tools)
    feed, more = programmed_feeds(args.toolpath, tp.line, False)
    warnings += more
    unset = ~tp.rapid & np.isnan(feed)
    fill = (f"--feed {args.feed:g} mm/min" if args.feed is not None
            else f"the machine's {machine.kinematics.feed * 60.0:g} mm/min")
    if args.feed is not None:
        feed[unset] = args.feed / 60.0
    if not unset.any():
        feeds = "feeds as programmed"
    elif unset.sum() == (~tp.rapid).sum():
        feeds = f"no feed programmed: {fill}"
    else:
        feeds = f"{unset.sum()} of {(~tp.rapid).sum()} feed moves without a programmed feed: {fill}"
    origin = None
    if args.origin is not None:
        try:
            origin = [float(v) for v in args.origin.split(",")]
        except ValueError:
            origin = []
        if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
            raise InputError(f"--origin wants X,Y,Z in mm (the program's zero in machine coordinates), got '{args.origin}'")
    if args.clearance is not None and not abs(args.clearance) <= MAX_COORDINATE:
        raise InputError(f"--clearance must be a Z in mm (|Z| <= {MAX_COORDINATE:g}), got {args.clearance}")
    lines, report = post_program(tp, tools, machine, feed=feed, tolerance=args.tolerance, origin=origin,
                                 clearance=args.clearance)
    try:
        with open(run.tmp(out), "w") as fh:
            fh.write("\n".join(lines) + "\n")
    except OSError as exc:
        raise InputError(f"{out}: cannot write ({exc.strerror})") from None
    run.commit()
    report = {"operation": "post", "toolpath": os.path.abspath(args.toolpath), "program": os.path.abspath(out),
              "tools_file": os.path.abspath(args.tools), "feeds": feeds, **report}
    report["warnings"] = warnings + report["warnings"]
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
          f"tools {', '.join(report['tools'])}, {report['tool_changes']} tool change(s); {feeds}.")
    return 0


def cmd_choose(args):
    import numpy as np

    from .machine.config import load_machine
    from .ops.choose import ChooseParams, choose, load_surface, tool_pair
    from .tools.table import load_tools, write_tools
    from .toolpath.cldata import write_apt

    out, run = _folder_results("choose", args.out)
    if (args.tool_pair is None) == (args.tools is None):
        raise InputError("give exactly one of --tool-pair and --tools")
    if args.zones == "auto":
        zones = None
    else:
        try:
            zones = int(args.zones)
        except ValueError:
            raise InputError(f"--zones must be 'auto' or an integer, got '{args.zones}'") from None
    params = ChooseParams(scallop=args.scallop, zones=zones, axes=args.axes, optimise=args.optimise, grid=args.grid,
                          mesh_step=args.mesh_step, sample=args.sample, cluster=args.cluster, metric=args.metric,
                          k_max=args.k_max, min_zone=args.min_zone, seed=args.seed)
    params.check()
    tools = tool_pair(args.tool_pair) if args.tool_pair else load_tools(args.tools)
    machine = load_machine(args.machine)
    device = _device(args)
    surface = load_surface(args.surface, params, flip=args.flip)
    tp, summary, zones, chooser = choose(surface, tools, machine, params, progress=_progress(args), device=device)
    summary["tools_file"] = os.path.abspath(os.path.join(out, "tools.toml"))
    write_tools(run.tmp(os.path.join(out, "tools.toml")), chooser.tools)
    write_apt(run.tmp(os.path.join(out, "toolpath.cl")), tp, chooser.tools, partno=os.path.basename(args.surface))
    s = chooser.samples
    np.savez_compressed(run.tmp(os.path.join(out, "zones.npz")), grid_shape=np.array(s.grid_shape), zones=zones,
                        points=s.points, normals=s.normals, valid=s.valid)
    _write_json(run.tmp(os.path.join(out, "summary.json")), summary)
    run.commit()
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
              f"{summary['tool_changes']} tool change(s) and {summary['reorientations']} re-orientation(s) on {machine.name}")
        if summary["optimisation"]:
            o = summary["optimisation"]
            print(f"NOMAD: rule-based {o['rule_s']:.1f} s -> {o['optimum_s']:.1f} s after {o['black_box_evaluations']} "
                  f"black-box and {o['surrogate_evaluations']} surrogate evaluations")
    for z in summary["zones"]:
        if not z["machined"]:
            _say(args, f"warning: zone {z['zone']} ({z['cells']} cells) is not machined: no candidate covers it "
                       f"(best {100 * z['coverage']:.0f} % of its cells{', no passes' if not z['planes'] else ''})")
    _say(args, f"verify: {'OK' if v['ok'] else 'PROBLEMS'} (max gouge {v['max_gouge']:.4f} mm, tolerance {v['tolerance']} mm)")
    _say(args, f"wrote {os.path.join(out, 'toolpath.cl')}, tools.toml, zones.npz and summary.json in "
               f"{summary['seconds']['total']:.1f} s (device {device})")
    _finish_json(args, summary)
    return 0 if v["ok"] and not summary["incomplete_zones"] else 1


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
    r.add_argument("--out", default="out", help="output folder (out)")
    _add_device(r)
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
    w.add_argument("--out", default="out", help="output folder (out)")
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
    _add_device(s)
    s.add_argument("--quiet", action="store_true", help="print nothing but errors")
    s.set_defaults(func=cmd_simulate)

    n = sub.add_parser("analyze", help="triangle and vertex parameters, visibility and accessibility")
    n.add_argument("part", help="part mesh (STL, OBJ, PLY), mm")
    n.add_argument("--direction", default="0,0,1", help="direction X,Y,Z (0,0,1)")
    n.add_argument("--weighting", choices=("area", "angle", "uniform"), default="area", help="vertex normals (area)")
    n.add_argument("--theta-step", type=float, default=None, help="also map accessibility over the hemisphere, degrees")
    n.add_argument("--delta-step", type=float, default=10.0, help="azimuth step of the map, degrees (10)")
    n.add_argument("--out", default="analysis", help="output folder (analysis)")
    n.add_argument("--quiet", action="store_true", help="print nothing but errors")
    n.set_defaults(func=cmd_analyze)

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
            _folder_results(args.command, args.out)  # earlier results go now, whatever fails next
        return args.func(args)
    except InputError as exc:
        _end_status()
        print(f"meshmill: error: {exc}", file=sys.stderr)
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
