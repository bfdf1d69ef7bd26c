"""Command line: argument parsing, progress and error messages; no geometry here.

Every command's options are its API function's (:mod:`meshmill.params`): the parser is made from
them (``step_down`` is ``--step-down``, the same defaults, help and checks), and the values given
are handed to the API as they are, after turning the text into the option's kind. Bad input ends
with one line on stderr and exit code 2 (the API's :class:`InputError`, its parameters spelled as
flags); an interrupt, at any moment, with ``meshmill: interrupted`` and exit code 130; ``verify``
exits 1 when it finds problems.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time

from . import __version__, memory, runfiles
from .errors import InputError
from .options import Option
from .runfiles import RunFiles
from .runfolder import FOLDER_OUTPUTS


class _Parser(argparse.ArgumentParser):
    def error(self, message):
        self.exit(2, f"meshmill: error: {message}\n")


_status_line = [False]  # a progress line is open on the terminal (to be ended before other text)
_run = [None]  # the result files of the command running (RunFiles): earlier results go at once
_interrupted = [False]  # SIGINT came: whatever exception follows is the interrupt's
_finished = [False]  # the command has ended (its result written, or its error said): SIGINT has nothing to stop


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
        if _interrupted[0]:  # a Ctrl-C that a library swallowed (trimesh's imports catch BaseException)
            raise KeyboardInterrupt
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


def _mm(x) -> str:
    """A length as the command line prints it (to a tenth of a micrometre)."""
    return f"{x:.4f}"


def _verified(v, tol) -> str:
    """What an operation's certified check found, as the command line says it: OK means every pose
    of every move within the tolerance; the depth is the deepest of the poses measured (the moves'
    ends and the middles of the intervals halved), not a bound between them."""
    return (f"{'OK' if v['ok'] else 'PROBLEMS'} (deepest pose measured {_mm(v['max_gouge'])} mm; every pose "
            f"{'within' if v['ok'] else 'checked against'} the tolerance {tol:g} mm)")


def _load_part(args, path):
    """The part ``path`` placed into the work frame by the set-up options (``--units``, ``--up``,
    ``--scale``, ``--origin``, ``--flip``), its warnings said."""
    from . import api
    from .params import SETUP

    mesh = api.load_part(path, **{k: args.options.pop(k) for k in SETUP if k in args.options})
    for w in mesh.warnings:
        _say(args, f"warning: {w}")
    return mesh


def _results(paths) -> RunFiles:
    """The result files of this run: earlier results under their names are removed now, whatever
    fails next; the new ones appear when the command saves them."""
    _run[0] = RunFiles(paths)
    return _run[0]


def _default_out(command):
    return {"finish": "out", "raster": "out", "waterline": "out", "steep-shallow": "out", "plunge": "out", "rough": "out",
            "simulate": "sim",
            "analyze": "analysis", "choose": "choose", "feeds": "feeds"}[command]


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


def cmd_finish(args):
    from . import api

    mesh = _load_part(args, args.options.pop("part"))
    res = api.finish(mesh, progress=_progress(args), **args.options)
    res.save(args.out)
    summary = res.summary
    v = summary["verify"]
    _say(args, f"contours {summary['contours']} (machinable {summary['machinable_contours']}), "
               f"CC points {summary['cc_points']}, left out {summary['points_left_out']}, "
               f"tilted {summary['points_tilted']}, passes {summary['passes']}")
    for name, entry in summary["tools_used"].items():
        _say(args, f"  {name}: {entry['contours']} contour(s), {entry['cc_points']} CC points")
    _say(args, f"verify ({v['poses_checked']} poses): {_verified(v, summary['tolerance'])}")
    _say(args, f"wrote {os.path.join(args.out, 'toolpath.cl')} and summary.json in {summary['seconds']['total']:.1f} s "
               f"(device {summary['device']})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def cmd_rough(args):
    from . import api

    mesh = _load_part(args, args.options.pop("part"))
    res = api.rough(mesh, progress=_progress(args), **args.options)
    res.save(args.out)
    summary = res.summary
    v, w, length = summary["verify"], summary["planned_width_mm"], summary["length_mm"]
    for warning in summary["warnings"]:
        _say(args, f"warning: {warning}")
    _say(args, f"{len(summary['levels'])} levels, {sum(lv['walks'] for lv in summary['levels'])} walks; "
               f"cut {length['cut'] / 1000:.2f} m, links {length['link'] / 1000:.2f} m at feed; radial width "
               f"max {w['max']:.3f} mean {w['mean']:.3f} (set {w['set']:g}) mm; left {summary['left_mm2']:.1f} mm^2")
    _say(args, f"{summary['moves']} moves; verify: {_verified(v, v['tolerance'])}")
    _say(args, f"wrote {os.path.join(args.out, 'toolpath.cl')}, moves.npz and summary.json in "
               f"{summary['seconds']['total']:.1f} s (device {summary['device']})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def _three_axis(args):
    """raster, waterline, steep-shallow and plunge: load, run the API's function, save, say."""
    from . import api

    mesh = _load_part(args, args.options.pop("part"))
    res = getattr(api, args.command.replace("-", "_"))(mesh, progress=_progress(args), **args.options)
    res.save(args.out)
    summary = res.summary
    if "simulation" in summary:
        s = summary["simulation"]
        _say(args, f"simulated at {s['step']:g} mm: removed {s['removed_volume']:.1f} of {s['stock_volume']:.1f} mm^3, "
                   f"{s['remaining_volume']:.1f} mm^3 left over the part")
    v = summary["verify"]
    _say(args, f"{summary['cl_points']} CL points, {summary['moves']} moves; verify: {_verified(v, v['tolerance'])}")
    _say(args, f"wrote {os.path.join(args.out, 'toolpath.cl')} and summary.json in {summary['seconds']['total']:.1f} s "
               f"(device {summary['device']})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def cmd_verify(args):
    from . import api

    if args.out:
        _results([args.out])
    o = args.options
    mesh = _load_part(args, o.pop("part"))
    tp = api.load_toolpath(o.pop("toolpath"), o["tools"], machine=o.get("machine"))
    for w in tp.warnings:
        _say(args, f"warning: {w}")
    res = api.verify(mesh, tp, progress=_progress(args) if o.get("cluster") is not None else None, **o)
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
          f"the deepest poses measured: gouge {_mm(report['max_gouge'])} mm, "
          f"collision {_mm(report['max_collision'])} mm (tolerance {report['tolerance']:g} mm; device {res.device})")
    for line in report["worst"]:
        print("  " + line)
    print("OK" if res.ok else "PROBLEMS FOUND")
    return 0 if res.ok else 1


def cmd_dexel(args):
    from . import api

    part = args.options.pop("part")
    out = args.out or os.path.splitext(os.path.basename(part))[0] + ".dexel.npz"
    if not out.lower().endswith((".td", ".npz")):
        out += ".npz"
    _results([out, os.path.join(os.path.dirname(os.path.abspath(out)), "summary.json")])
    mesh = _load_part(args, part)
    res = api.dexel(mesh, progress=_progress(args), **args.options)
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


def cmd_simulate(args):
    from . import api

    o = args.options
    design = _load_part(args, o.pop("design"))
    tp = api.load_toolpath(o.pop("toolpath"), o["tools"], tool=o.get("tool"), machine=o.get("machine"))
    for w in tp.warnings:
        _say(args, f"warning: {w}")
    res = api.simulate(design, tp, progress=_progress(args), **o)
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
               f"Sz {deviation['Sz']:.4f} mm; within ±{deviation['tolerance']:g} mm: "
               f"{100 * deviation['within_tolerance']:.1f} %")
    _say(args, f"gouge max {_mm(deviation['gouge_max'])} mm at {deviation['gouge_at']}; excess max "
               f"{deviation['excess_max']:.4f} mm; removed {deviation['removed_volume']:.1f} mm^3, remaining "
               f"{deviation['remaining_volume']:.1f} mm^3")
    c = summary["cutting_mm"]
    _say(args, f"feed moves: {c['in_material']:.1f} mm in material, {c['in_air']:.1f} mm in air "
               f"({100 * c['air_share']:.1f} %)")
    for line in load_lines(summary.get("load")):
        _say(args, line)
    _say(args, f"wrote {written} in {args.out} ({summary['seconds']['total']:.1f} s, device {summary['device']})")
    _finish_json(args, summary)
    return 0 if res.ok else 1


def cmd_feeds(args):
    from . import api

    o = args.options
    design = _load_part(args, o.pop("design"))
    res = api.optimise_feeds(design, progress=_progress(args), **o)
    written = ", ".join(os.path.basename(p) for p in res.save(args.out))
    s = res.summary
    for w in s["warnings"]:
        _say(args, f"warning: {w}")
    _end_status()
    for e in s["errors"][:10]:
        print(f"error: {e}", file=sys.stderr)
    for line in load_lines(s["load_before"]):
        _say(args, line)
    f = s["feed_mm_min"]
    _say(args, f"feeds {f['lowest']:.0f} to {f['highest']:.0f} mm/min ({f['changes']} changes); machining time "
               f"{_clock(s['time_s']['before'])} as programmed, {_clock(s['time_s']['optimised'])} optimised")
    _say(args, f"wrote {written} in {args.out}")
    _finish_json(args, s)
    return 0 if res.ok else 1


def load_lines(load) -> list:
    """One line per tool of a summary's ``load``: the largest depth, width, chip and power."""
    if not load:
        return []

    def top(entry, key, fmt):
        v = entry.get(key)
        return "-" if v is None else format(v["max"], fmt)

    return [f"load {t['tool']}: {t['moves_in_material']} moves in material, ap up to {top(t, 'ap_mm', '.2f')} mm, "
            f"ae {top(t, 'ae_mm', '.2f')} mm, engagement {top(t, 'engagement_deg', '.0f')} deg, chip "
            f"{top(t, 'chip_max_mm', '.4f')} mm, {top(t, 'rate_mm3_min', '.0f')} mm^3/min, "
            f"{top(t, 'power_kw', '.2f')} kW" for t in load["tools"]]


def cmd_analyze(args):
    from . import api

    mesh = _load_part(args, args.options.pop("part"))
    res = api.analyze(mesh, progress=_progress(args), **args.options)
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
    from .job import Job, JobFolder

    job = Job.from_toml(args.options["jobfile"])
    if "device" in args.options:
        job.device = args.options["device"]
    folder = JobFolder(args.out)  # checked and cleared before anything is computed
    for w in job.part.warnings:
        _say(args, f"warning: {w}")
    res = job.run(progress=_progress(args), cluster=args.options.get("cluster"))
    res.save(folder, report=not args.no_report, progress=_progress(args))
    s = res.summary
    for w in s.get("warnings", []):
        _say(args, f"warning: {w}")
    for op in s["operations"]:
        if op.get("skipped"):
            continue
        c = op["cutting_mm"]
        _say(args, f"{op['folder']}: {'OK' if op['ok'] else 'PROBLEMS'}, removed {op['removed_mm3']:.0f} mm^3, "
                   f"{op['left_over_design_mm3']:.0f} mm^3 left over the part; cutting {c['in_material']:.0f} mm in "
                   f"material, {c['in_air']:.0f} mm in air ({100 * c['air_share']:.1f} %); "
                   f"{_clock(op['machining_s'])} on the machine"
                   + (f" ({_clock(op['feeds']['table_s'])} at the table's feeds)" if op.get("feeds") else ""))
        for e in op["errors"][:5]:
            _say(args, f"  error: {e}")
    f = s["final"]
    _say(args, f"final: {100 * f['within_tolerance']:.1f} % of the dexel ends within ±{f['tolerance']:g} mm, "
               f"{f['left_over_design_mm3']:.0f} mm^3 left over the part, max gouge {_mm(f['gouge_max'])} mm")
    if s.get("left"):
        left = s["left"]
        out = ", ".join(f"{k} {v:.0f} mm^2" for k, v in left["by_reason_mm2"].items()
                        if k != "within tolerance" and v >= 0.5)
        _say(args, f"left: {100 * left['within_tolerance']:.1f} % of the surface within ±{f['tolerance']:g} mm, "
                   f"{100 * left['reachable_within_tolerance']:.1f} % of what the table's balls reach"
                   + (f"; out of it: {out}" if out else ""))
    if s.get("non_cutting"):
        nc = s["non_cutting"]
        _say(args, f"time cutting nothing: {100 * nc['share']:.0f} % (rapids {_clock(nc['rapid_s'])}, tool changes "
                   f"{_clock(nc['tool_change_s'])}, feed through the air {_clock(nc['air_feed_s'])})")
    _say(args, f"wrote {args.out}/ (program.nc: {s['post']['blocks']} blocks, {_clock(s['machining_s'])} on "
               f"{s['machine']['name']}; job.json{'' if args.no_report else ', report.html'}) in "
               f"{s['seconds']['total']:.1f} s")
    _finish_json(args, s)
    return 0 if res.ok else 1


def cmd_report(args):
    from . import api

    info = api.report(progress=_progress(args), **args.options)
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
    machine = api.load_machine(args.options.pop("machine"))
    res = api.machining_time(machine=machine, **args.options)
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

    out = args.out or os.path.join(os.path.dirname(os.path.abspath(args.options["toolpath"])), "program.nc")
    _results([out])
    machine = api.load_machine(args.options.pop("machine"))
    res = api.post(machine=machine, **args.options)
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

    res = api.choose(progress=_progress(args), **args.options)
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
    _say(args, f"verify: {_verified(v, v['tolerance'])}")
    _say(args, f"wrote {os.path.join(args.out, 'toolpath.cl')}, tools.toml, zones.npz and summary.json in "
               f"{summary['seconds']['total']:.1f} s (device {res.device})")
    _finish_json(args, summary)
    return 0 if res.ok else 1




# ---------------------------------------------------------------- the parser, made from the API's options


def _spec(command):
    """The API function and options of ``command``."""
    from . import api

    return {"finish": api.finish, "raster": api.raster, "waterline": api.waterline,
            "steep-shallow": api.steep_shallow, "plunge": api.plunge,
            "rough": api.rough, "verify": api.verify, "dexel": api.dexel, "simulate": api.simulate, "analyze": api.analyze,
            "choose": api.choose, "post": api.post, "time": api.machining_time, "report": api.report,
            "feeds": api.optimise_feeds}[command].spec


def _add_options(parser, spec, skip=()):
    """An argument for every option of ``spec`` the command line has: a positional for a
    positional one, ``--flag`` (``store_true`` for a flag) otherwise, with its aliases in a group;
    none has a default here (the API's applies)."""
    for name, o in spec.options().items():
        if not o.cli or name in skip:
            continue
        if o.positional:
            parser.add_argument(name, nargs="+" if o.role == "folders" else None, help=o.help_text())
            continue
        if o.kind == "flag":
            on = o.default is True  # a flag on by default is turned off by --no-...
            parser.add_argument(o.flag, action=argparse.BooleanOptionalAction if on else "store_true",
                                default=argparse.SUPPRESS, help=o.help_text())
            continue
        target = parser.add_mutually_exclusive_group(required=o.required) if o.aliases else parser
        metavar = o.metavar or (o.unit.upper().replace("/", "_PER_") if o.unit else None)
        target.add_argument(o.flag, dest=name, default=argparse.SUPPRESS, metavar=metavar,
                            required=o.required and not o.aliases,
                            choices=[str(c) for c in o.choices] or None, help=o.help_text())
        for flag, prefix in o.aliases:
            target.add_argument(flag, dest=f"{name}|{prefix}", default=argparse.SUPPRESS, metavar="MM",
                                help=f"the same as {o.flag} {prefix}MM")


def _add_cluster(parser):
    """``--workers N`` / ``--scheduler ADDRESS``: the API's ``cluster`` (meshmill[cluster])."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--workers", dest="cluster", type=int, default=argparse.SUPPRESS, metavar="N",
                   help="split the work over N worker processes on this machine (a Dask LocalCluster; needs "
                        "meshmill[cluster]); the result is the same")
    g.add_argument("--scheduler", dest="cluster", default=argparse.SUPPRESS, metavar="ADDRESS",
                   help="split the work over a running Dask cluster (tcp://host:8786); the result is the same")


def _add_setup(parser):
    """``--units``, ``--up``, ``--scale``, ``--origin``, ``--flip``: load_part's options, how the
    part file is set up on the machine."""
    from .params import LoadPartParams

    g = parser.add_argument_group("set-up (the part file into the work frame: mm, +Z to the spindle)")
    _add_options(g, LoadPartParams, skip=("path",))


def _options_given(args, spec) -> dict:
    """The options given on the command line, in the kinds of ``spec`` (text turned into numbers,
    choices, points; an alias's value with its prefix)."""
    from .params import LoadPartParams

    opts = {**LoadPartParams.options(), **spec.options()}
    out = {}
    for key, text in vars(args).items():
        name, _, prefix = key.partition("|")
        if name not in opts:
            continue
        o = opts[name]
        if name == "cluster" or o.kind == "flag" or o.positional:
            out[name] = text
        elif prefix:  # an alias's value: a number of mm, checked under the alias's own name
            flag = next(f for f, pre in o.aliases if pre == prefix)
            alias = Option("number", "", unit="mm", low=0.0, name=flag[2:].replace("-", "_"))
            out[name] = f"{prefix}{alias.check(alias.from_text(text)):g}"
        else:
            out[name] = o.from_text(text)
    return out


def build_parser():
    from .job import JobParams

    p = _Parser(prog="meshmill", description="Exact, verified multi-axis milling tool paths from triangle meshes.")
    p.add_argument("--version", action="version", version=f"meshmill {__version__}")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    def command(name, help, func, out=None, out_help=None, setup=True, cluster=False, json=True, quiet=True):
        sp = sub.add_parser(name, help=help)
        spec = _spec(name) if name != "job" else None
        if spec is not None:
            _add_options(sp, spec)
        if setup:
            _add_setup(sp)
        if cluster:
            _add_cluster(sp)
        if out_help:
            sp.add_argument("--out", default=out, help=out_help)
        if quiet:
            sp.add_argument("--quiet", action="store_true", help="print nothing but errors")
        if json:
            sp.add_argument("--json", action="store_true", help="print the summary as JSON on stdout (and nothing on "
                                                                "stderr)")
        sp.set_defaults(func=func, spec=spec)
        return sp

    folder = "output folder (out)"
    command("finish", "5-axis Z-constant finishing with ball-end tools", cmd_finish, "out", folder, cluster=True)
    command("raster", "3-axis zigzag finishing (flat, ball or bull-nose)", _three_axis, "out", folder, cluster=True)
    command("waterline", "3-axis Z-level loops (flat, ball or bull-nose)", _three_axis, "out", folder, cluster=True)
    command("steep-shallow", "3-axis finishing to a scallop limit: Z levels on steep ground, parallel passes on shallow",
            _three_axis, "out", folder, cluster=True)
    command("plunge", "3- or 5-axis plunge roughing (tréflage)", _three_axis, "out", folder)
    command("rough", "adaptive clearing from the stock: Z levels with a bounded radial engagement", cmd_rough, "out",
            folder, cluster=True)
    command("verify", "check an APT CL file or G-code for gouges and collisions", cmd_verify, None,
            "write the report as JSON to this file", cluster=True, json=False)
    command("dexel", "triple-dexel model of a closed part", cmd_dexel, None,
            "model file: .npz (compact binary) or .td (seed's ASCII) (PART.dexel.npz)", cluster=True)
    command("simulate", "cut a tool path from a stock and measure it against the design", cmd_simulate, "sim",
            "output folder (sim)", cluster=True)
    command("feeds", "each move's feed optimised on the load measured by cutting the path from its stock", cmd_feeds,
            "feeds", "output folder (feeds)")
    command("analyze", "triangle and vertex parameters, visibility and accessibility", cmd_analyze, "analysis",
            "output folder (analysis)", json=False)
    command("choose", "tool choice, zones and directions by machining time (3-axis or 3+2)", cmd_choose, "choose",
            "output folder (choose)", setup=False)
    jb = command("job", "machine a part from its stock in one run: operations in order, rest machining, one program "
                        "and one report", cmd_job, "job", "output folder (job): checked before anything is "
                        "computed, written whole when the job completes", setup=False, cluster=True)
    jb.add_argument("jobfile", help="the job's TOML file ([part], [stock], [[fixtures]], [[operations]], tools, "
                                    "machine)")
    jb.add_argument("--no-report", action="store_true", help="do not write report.html")
    jb.add_argument("--device", choices=JobParams.options()["device"].choices, default=argparse.SUPPRESS,
                    help="run the heavy kernels on the CPU or an NVIDIA GPU (default: the job file's, else auto)")
    command("report", "one self-contained HTML file with 3D views and tables of run folders", cmd_report,
            setup=False)
    command("time", "machining time of a tool path on a jerk-limited machine", cmd_time, None,
            "write the summary as JSON to this file", setup=False, quiet=False, json=False).add_argument(
        "--json", action="store_true", help="print the summary as JSON on stdout")
    command("post", "G-code for a machine from an APT CL file (3- and 5-axis)", cmd_post, None,
            "program file to write (program.nc beside the tool path)", setup=False, quiet=False, json=False
            ).add_argument("--json", action="store_true", help="print the report as JSON on stdout (and nothing on "
                                                               "stderr)")
    return p


def _spelled(argv, parser) -> list:
    """``argv`` with the value of an option that starts with a dash joined to it (``--up -Z`` is
    ``--up=-Z``; argparse would take ``-Z`` for an option), where it is not itself an option."""
    if not argv or argv[0] not in parser._subparsers._group_actions[0].choices:
        return argv
    sp = parser._subparsers._group_actions[0].choices[argv[0]]
    takes = {s for a in sp._actions if a.option_strings and a.nargs != 0 for s in a.option_strings}
    known = {s for a in sp._actions for s in a.option_strings}
    out, i = [argv[0]], 1
    while i < len(argv):
        a = argv[i]
        if a in takes and i + 1 < len(argv) and argv[i + 1].startswith("-") and argv[i + 1] not in known \
                and argv[i + 1] != "--":
            out.append(f"{a}={argv[i + 1]}")
            i += 2
            continue
        out.append(a)
        i += 1
    return out


def _flags_of(parser, command):
    """``spell(name)``: a parameter's flag on ``command``'s command line (``step_down`` is
    ``--step-down``; ``cluster`` is ``--workers/--scheduler``), the name itself where the command
    has no such flag (a job file's key)."""
    sp = parser._subparsers._group_actions[0].choices[command]
    flags = {}
    for a in sp._actions:
        if not a.option_strings:
            flags[a.dest] = [a.dest]
        elif "|" in a.dest:  # an alias (--stock-allowance): errors of its value name it
            flags[a.option_strings[0][2:].replace("-", "_")] = [a.option_strings[0]]
        else:
            flags.setdefault(a.dest, []).append(a.option_strings[0])

    def spell(name):
        return "/".join(f for f in flags.get(name, [name]) if f.startswith("--") or f == name)

    return spell


def _on_interrupt(signum, frame):
    """SIGINT: remember it (whatever exception it leaves, a numba kernel's included, is the
    interrupt's) and stop the Python code running; once the command has ended, nothing. Where
    Python would print an exception with its traceback and drop it (:func:`_in_callback`) it is
    only remembered: the next stage of the command raises it (:func:`_progress`)."""
    if _finished[0]:
        return
    _interrupted[0] = True
    if not runfiles.held[0] and not _in_callback(frame):
        raise KeyboardInterrupt


def _in_callback(frame) -> bool:
    """Whether ``frame`` or a frame it was called from is code whose exceptions Python prints and
    drops ("Exception ignored in ..."): llvmlite's (numba compiling a kernel, whose object cache
    calls back into Python from native code), a ``__del__``, a weak reference's callback (the
    import system's module locks, ``weakref.finalize``)."""
    while frame is not None:
        code = frame.f_code
        if f"{os.sep}llvmlite{os.sep}" in code.co_filename or code.co_name == "__del__" \
                or (code.co_filename.startswith("<frozen importlib") and code.co_name == "cb") \
                or (code.co_filename.endswith(f"{os.sep}weakref.py") and code.co_name == "__call__"):
            return True
        frame = frame.f_back
    return False


def _quiet_interrupts(hook):
    """``sys.unraisablehook`` while a command runs: a KeyboardInterrupt of our Ctrl-C that Python
    drops where it cannot raise it (a callback, a finaliser: the places :func:`_in_callback` does
    not know) is not printed (it is remembered: the next stage raises it); anything else goes to
    ``hook``."""
    def unraisable(info):
        if not (_interrupted[0] and info.exc_type is not None and issubclass(info.exc_type, KeyboardInterrupt)):
            hook(info)

    return unraisable


def _caused_by_interrupt(exc) -> bool:
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def main(argv=None) -> int:
    _status_line[0] = False
    _run[0] = None
    _interrupted[0] = _finished[0] = False
    runfiles.held[0] = 0
    previous = signal.signal(signal.SIGINT, _on_interrupt) if _main_thread() else None
    hook = sys.unraisablehook
    sys.unraisablehook = _quiet_interrupts(hook)
    runfiles.interrupted[0] = lambda: _interrupted[0]
    try:
        return _main(argv)
    except BaseException as exc:  # an interrupt, however it surfaces (in a numba kernel: a SystemError)
        if _interrupted[0] or _caused_by_interrupt(exc):
            _end_status()
            print("meshmill: interrupted", file=sys.stderr)
            return 130
        raise
    finally:
        if _run[0] is not None and not _run[0].done:
            _run[0].abort()  # a run that did not complete leaves no result behind
        _finished[0] = True
        runfiles.interrupted[0] = lambda: False
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook


def _main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


def _main(argv) -> int:
    parser = build_parser()
    argv = _spelled(sys.argv[1:] if argv is None else list(argv), parser)
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
        args.options = _options_given(args, args.spec) if args.spec is not None else \
            {k: v for k, v in vars(args).items() if k in ("jobfile", "device", "cluster")}
        return args.func(args)
    except InputError as exc:
        _end_status()
        print(f"meshmill: error: {exc.text(_flags_of(parser, args.command))}", file=sys.stderr)
        return 2
    except MemoryError:  # an estimate fell short: still one line, and nothing written
        _end_status()
        print(f"meshmill: error: out of memory ({memory.size(memory.available_bytes())} available): use a coarser "
              "step, sample or step-down", file=sys.stderr)
        return 2


def entry():
    """The ``meshmill`` command: :func:`main`, then out at once. A finished run exits without
    waiting on anything (numba's thread pools, Dask's) and a Ctrl-C after its result is written
    does not turn it into an interrupted one."""
    signal.signal(signal.SIGINT, _on_interrupt)  # from the start (main puts back this one when it ends)
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    entry()
