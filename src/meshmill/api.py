"""meshmill as a library: every command as a function, with the command's options as keyword
arguments (same names with ``_`` for ``-``, same defaults) and a small result object whose
``save`` writes exactly the files the command writes.

```python
import meshmill
part = meshmill.load_part("part.stl", units="m", origin="bottom-centre")  # Mesh, mm, work frame
tools = meshmill.load_tools("tools.toml")
res = meshmill.finish(part, tools, step_down=1.0)
res.toolpath, res.summary   # the Toolpath and the dict summary.json holds
res.save("out/")            # contours.npz, toolpath.cl, part.stl, summary.json
```

Bad input raises :class:`~meshmill.errors.InputError` naming the parameter (``step_down must be
at least 0.0001 mm``; the command line names its flags instead). ``device`` is ``"cpu"``,
``"cuda"`` or ``"auto"`` (a usable GPU when there is one); ``progress`` is called with the name of
each stage. Units: mm, degrees for angles, mm/min for feeds.
"""
from __future__ import annotations

import functools
import inspect
import math
import os
import re
import time
from dataclasses import dataclass, field

from .errors import InputError
from .runfolder import FOLDER_OUTPUTS, write_json, write_part
from .tolerances import GOUGE_TOL, HOLDER_CLEARANCE, STOCK_ALLOWANCE

_FLAG = re.compile(r"--([a-z][a-z0-9]*(?:-[a-z0-9]+)*)")


def _named_errors(func):
    """Errors of ``func`` name its parameters (``step_down``) where the lower layers wrote the
    command's flag (``--step-down``); ``InputError.params`` lists the names so replaced and
    ``flags_message`` keeps the flags' wording for the command line."""
    names = set(inspect.signature(func).parameters)

    @functools.wraps(func)
    def call(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except InputError as exc:
            found = []

            def name(m):
                key = m.group(1).replace("-", "_")
                if key not in names:
                    return m.group(0)
                found.append(key)
                return key

            text = _FLAG.sub(name, str(exc))
            if not found:
                raise
            err = InputError(text)
            err.params = tuple(dict.fromkeys(found))
            err.flags_message = str(exc)  # as the command line says it
            raise err from None

    return call


def _finite(v):
    return isinstance(v, (int, float)) and math.isfinite(v)


# ---------------------------------------------------------------- loading


@_named_errors
def load_part(path, *, units="mm", up="+Z", origin="file", scale=1.0, flip=False):
    """The part mesh of ``path`` (STL, OBJ, PLY; STEP and IGES with ``meshmill[step]``) set up
    into the work frame (mm, +Z to the spindle): ``units`` of the file (mm, cm, m, in), ``up`` the
    part's axis to the spindle (+X, -Y, ..., "RX,RY,RZ" degrees or nine numbers), ``scale`` the
    model's scale, ``origin`` the work zero (bottom-centre, top-centre, corner, file, or "X,Y,Z");
    ``flip`` turns every face over. Returns a :class:`~meshmill.geometry.mesh.Mesh` (its
    ``warnings`` say what was repaired or looks wrong)."""
    from .geometry.mesh import load_mesh
    from .geometry.placement import Setup

    setup = Setup(units=units, up=up, origin=origin, scale=scale)
    setup.check()
    return load_mesh(path, flip=flip, setup=setup)


def _load_stock(stock):
    """The closed stock :class:`Mesh` of ``stock`` (a mesh, a file already in the work frame, or
    None)."""
    if stock is None:
        return None
    if isinstance(stock, (str, os.PathLike)):
        from .geometry.mesh import load_mesh

        stock = load_mesh(stock)
    if not stock.closed:
        raise InputError(f"{stock.source or 'the stock'}: the stock mesh is open (not watertight)")
    return stock


@_named_errors
def load_tools(path):
    """The tool table of TOML file ``path``: a list of :class:`~meshmill.tools.table.Tool`
    (numbered from 1) with the file's ``path``."""
    from .tools.table import load_tools as read

    return read(path)


@_named_errors
def load_machine(machine):
    """A machine: a TOML file or a shipped name (generic-3axis, table-table-ac, head-table-bc, ...)."""
    from .machine.config import load_machine as read

    return read(machine)


@_named_errors
def load_toolpath(path, tools, *, tool=None, machine=None):
    """The :class:`~meshmill.toolpath.model.Toolpath` of an APT CL file or G-code (by extension),
    its ``feed`` (mm/min per move, NaN where the file sets none), ``source`` and ``warnings``.
    ``tool``: the tool of G-code without T words; ``machine`` (a Machine or a name): the one
    whose kinematics read 5-axis G-code."""
    from .machine.pathfile import read_toolpath

    if isinstance(machine, (str, os.PathLike)):
        machine = load_machine(machine)
    return read_toolpath(path, tools, tool, machine)[0]


def _device(device):
    from .kernels.backend import resolve

    return resolve(device)


def _part_entry(mesh):
    return {"file": mesh.source, **mesh.summary()}


def _tools_file(tools):
    path = getattr(tools, "path", "")
    return os.path.abspath(path) if path else ""


def _loaded(summary, mesh):
    """Add the part's loading time to the summary's ``seconds``."""
    load_s = mesh.load_seconds
    summary["seconds"]["load"] = round(load_s, 4)
    summary["seconds"]["total"] = round(summary["seconds"]["total"] + load_s, 4)


# ---------------------------------------------------------------- results


class _Saved:
    """Writes a result's files all or nothing (:class:`~meshmill.runfiles.RunFiles`)."""

    def _save(self, paths, write):
        from .runfiles import RunFiles

        run = RunFiles(paths)
        try:
            write(run)
            run.commit()
        finally:
            if not run.done:
                run.abort()
        return [p for p in run.paths if os.path.exists(p)]


@dataclass
class PathResult(_Saved):
    """A tool path and its summary: finish, raster, waterline, plunge. ``arrays``: finish's
    contours and surface status (contours.npz)."""

    operation: str
    toolpath: object
    summary: dict
    part: object
    tools: list
    arrays: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        """The written path verified free of gouges and collisions."""
        return bool(self.summary["verify"]["ok"])

    def save(self, folder) -> list:
        """Write the command's files into ``folder``; returns their paths."""
        from .toolpath.cldata import write_apt

        def write(run):
            import numpy as np

            if self.arrays:
                np.savez_compressed(run.tmp(os.path.join(folder, "contours.npz")), **self.arrays)
            partno = os.path.basename(self.part.source or "part")
            write_apt(run.tmp(os.path.join(folder, "toolpath.cl")), self.toolpath, self.tools, partno=partno)
            write_part(run.tmp(os.path.join(folder, "part.stl")), self.part)
            write_json(run.tmp(os.path.join(folder, "summary.json")), self.summary)

        return self._save([os.path.join(folder, n) for n in FOLDER_OUTPUTS[self.operation]], write)


def _path_result(operation, tp, summary, mesh, tools, device, arrays=None):
    summary["device"] = device
    summary["tools_file"] = _tools_file(tools)
    summary["part"] = _part_entry(mesh)
    _loaded(summary, mesh)
    return PathResult(operation, tp, summary, mesh, tools, arrays or {})


# ---------------------------------------------------------------- operations


@_named_errors
def finish(part, tools, *, step_down, sample=0.5, max_tilt=60.0, tilt_step=5.0, order="contour", safe_z=None,
           tolerance=GOUGE_TOL, clearance=HOLDER_CLEARANCE, lead=2.0, machine=None, scallop=None, min_run=1.0,
           whole_contours=False, stock=None, stock_allowance=STOCK_ALLOWANCE, device="auto", cluster=None,
           progress=None) -> PathResult:
    """5-axis Z-constant finishing with the ball-end tools of ``tools`` (seed 004 and beyond):
    ``step_down`` mm between levels, ``machine`` the 5-axis machine the axes are for, ``scallop``
    mm adds levels where the surface is shallow, ``stock`` the material rapids keep clear of (a
    closed mesh or file; else ``stock_allowance`` on the part); ``cluster``: the axis search in
    groups of contours there (the same path)."""
    import numpy as np

    from .ops.finish import AREA_STATUS, FinishParams
    from .ops.finish import finish as run

    params = FinishParams(step_down=step_down, sample=sample, max_tilt=max_tilt, tilt_step=tilt_step, order=order,
                          safe_z=safe_z, tol=tolerance, clearance=clearance, lead=lead,
                          stock_allowance=stock_allowance, min_run=min_run, whole_contours=whole_contours,
                          scallop=scallop)
    params.check()
    stock = _load_stock(stock)
    device = _device(device)
    if isinstance(machine, (str, os.PathLike)):
        machine = load_machine(machine)
    from .cluster import connect

    with connect(cluster) as client:
        tp, summary, detail = run(part, tools, params, progress=progress, device=device, stock=stock,
                                  machine=machine, cluster=client)
    con = detail["contours"]
    arrays = dict(points=con.points, offsets=con.offsets, z=con.z, closed=con.closed,
                  machinable=detail["contour_tool"] >= 0, surface_points=detail["surface_points"],
                  surface_status=detail["surface_status"], status_names=np.array(AREA_STATUS),
                  raster_from=detail["raster_from"], raster_reach=detail["raster_reach"])
    return _path_result("finish", tp, summary, part, tools, device, arrays)


@_named_errors
def raster(part, tools, *, tool, stepover=None, scallop=None, angle=0.0, sample=0.5, tolerance=GOUGE_TOL,
           clearance=HOLDER_CLEARANCE, stock=None, stock_allowance=STOCK_ALLOWANCE, allowance=0.0, rest=None,
           rest_stock=None, device="auto", cluster=None, progress=None) -> PathResult:
    """3-axis zigzag finishing with the tool named ``tool``: ``stepover`` mm between passes, or
    the one a ``scallop`` height gives; ``angle`` degrees from X; ``allowance`` mm of material
    left on the part (semi-finishing); ``cluster``: the passes dropped in pieces there (the same
    path); ``rest`` mm: with a ``stock`` (and ``rest_stock``, the surface the depths are measured
    from where it is not the stock),
    only the pieces of the passes that remove more than that depth of it (rest machining)."""
    from .ops.raster import RasterParams
    from .ops.raster import raster as run

    if (stepover is None) == (scallop is None):
        raise InputError("give exactly one of --stepover and --scallop")
    params = RasterParams(stepover=stepover, scallop=scallop, angle=angle, sample=sample, tol=tolerance,
                          stock_allowance=stock_allowance, clearance=clearance, allowance=allowance, rest=rest)
    params.check()
    device = _device(device)
    from .cluster import connect

    with connect(cluster) as client:
        tp, summary = run(part, tools, tool, params, progress=progress, device=device, stock=_load_stock(stock),
                          rest_stock=_load_stock(rest_stock), cluster=client)
    return _path_result("raster", tp, summary, part, tools, device)


@_named_errors
def waterline(part, tools, *, tool, step_down, sample=0.5, tolerance=GOUGE_TOL, clearance=HOLDER_CLEARANCE,
              stock=None, stock_allowance=STOCK_ALLOWANCE, allowance=0.0, rest=None, rest_stock=None,
              device="auto", cluster=None, progress=None) -> PathResult:
    """3-axis Z-level loops with the tool named ``tool``, ``step_down`` mm apart, ``allowance`` mm
    of material left on the part; ``cluster``: groups of levels found there (the same path);
    ``rest`` mm:
    with a ``stock``, only the pieces of the loops that remove more than that depth of it."""
    from .ops.waterline import WaterlineParams
    from .ops.waterline import waterline as run

    params = WaterlineParams(step_down=step_down, sample=sample, tol=tolerance, stock_allowance=stock_allowance,
                             clearance=clearance, allowance=allowance, rest=rest)
    params.check()
    device = _device(device)
    from .cluster import connect

    with connect(cluster) as client:
        tp, summary, _ = run(part, tools, tool, params, progress=progress, device=device, stock=_load_stock(stock),
                             rest_stock=_load_stock(rest_stock), cluster=client)
    return _path_result("waterline", tp, summary, part, tools, device)


@_named_errors
def plunge(part, tools, *, tool, allowance, axes=3, radial_step=5.0, engagement=5.0, theta_step=15.0,
           delta_step=30.0, regions=0, clearance=5.0, stock=None, simulate=None, device="auto",
           progress=None) -> PathResult:
    """Plunge roughing (seed 001) from the part's box with the tool named ``tool``, leaving
    ``allowance`` mm: ``axes`` 3 (nested contours) or 5 (hemisphere of directions); 3-axis from
    the box of ``stock`` (a closed mesh or file holding the part) where given. ``simulate`` (a
    dexel step, mm) also cuts the path from the box and reports the volumes."""
    from .ops.plunge import PlungeParams, plunge3, plunge5

    if axes not in (3, 5):
        raise InputError(f"--axes must be 3 or 5, got {axes}")
    params = PlungeParams(radial_step=radial_step, engagement=engagement, allowance=allowance, clearance=clearance,
                          theta_step=theta_step, delta_step=delta_step, regions=regions)
    if simulate is not None and not (_finite(simulate) and simulate > 0):
        raise InputError(f"--simulate must be a positive dexel step in mm, got {simulate}")
    stock = _load_stock(stock)
    if stock is not None and axes != 3:
        raise InputError("--stock: 5-axis plunge roughing starts from the part's box (give --axes 3)")
    device = _device(device)
    params.device = device
    if axes == 3:
        tp, summary = plunge3(part, tools, tool, params, progress=progress,
                              stock_box=None if stock is None else stock.bounds)
    else:
        tp, summary = plunge5(part, tools, tool, params, progress=progress)
    if simulate is not None:
        from .ops.simulate import simulate as cut

        dev, sim, *_ = cut(part, tp, tools, simulate, stock="box", progress=progress, device=device)
        v = sim["volumes_mm3"]
        summary["simulation"] = {"step": simulate, "stock_volume": v["stock"], "removed_volume": v["removed"],
                                 "remaining_volume": v["remaining"], "gouged_volume": v["gouged"],
                                 "gouge_max": dev["gouge_max"], "seconds": sim["seconds"]["total"]}
    return _path_result("plunge", tp, summary, part, tools, device)


@dataclass
class VerifyResult(_Saved):
    """``report``: what verify found (moves, gouging and colliding moves, worst cases, ok)."""

    report: dict
    device: str
    stock_checked: bool

    @property
    def ok(self) -> bool:
        return bool(self.report["ok"])

    def save(self, path) -> list:
        """Write the report as JSON to ``path``."""
        return self._save([path], lambda run: write_json(run.tmp(path), self.report))


@_named_errors
def verify(part, toolpath, tools, *, tolerance=GOUGE_TOL, step=0.5, stock=None, allowance=0.0, worst=10,
           machine=None, device="auto", cluster=None, progress=None) -> VerifyResult:
    """Check ``toolpath`` (a Toolpath, or an APT CL / G-code file read for ``machine``) against the
    part for gouges beyond ``tolerance`` and shank or holder collisions, certified between poses
    ``step`` mm apart; rapids against ``stock`` (a closed mesh or file) or ``allowance`` mm on
    the part. ``cluster``: a number of local worker processes, a Dask scheduler's address or a
    ``distributed.Client``: ranges of moves verified there (the same report)."""
    from .kernels.backend import solid_kernels
    from .pathing.verify import StockCheck, verify_toolpath

    if not (_finite(step) and step >= 1e-4):
        raise InputError(f"--step must be a finite number of at least 0.0001 mm, got {step}")
    if not (_finite(tolerance) and tolerance >= 0):
        raise InputError(f"--tolerance must be a finite number >= 0, got {tolerance}")
    if not (_finite(allowance) and allowance >= 0):
        raise InputError(f"--allowance must be a number of mm >= 0, got {allowance}")
    stock = _load_stock(stock)
    if isinstance(toolpath, (str, os.PathLike)):
        toolpath = load_toolpath(toolpath, tools, machine=machine)
    device = _device(device)
    say = progress or (lambda stage: None)
    floor = min(part.bounds[0, 2], stock.bounds[0, 2]) if stock is not None else None
    allowance = 0.0 if stock is not None else allowance
    if cluster is not None:
        from .cluster import PIECES_PER_WORKER, connect, run_pieces, workers
        from .pathing.verify import merge_reports, path_pieces, verify_piece

        with connect(cluster) as client:
            pieces = path_pieces(toolpath, PIECES_PER_WORKER * workers(client))
            shared = dict(part=part, floor=floor, stock=stock, allowance=allowance, tools=list(tools), tol=tolerance,
                          step=step, device=device)
            parts = run_pieces(client, verify_piece, shared, pieces, say, "certified check of every move")
        report = merge_reports(toolpath, parts, tolerance, step,
                               {**StockCheck(allowance=allowance).summary(), "mesh": stock is not None}, worst)
    else:
        say("index")
        check = StockCheck(allowance=allowance, kern=solid_kernels(stock, device) if stock is not None else None)
        kern = solid_kernels(part, device, floor)
        say("certified check of every move")
        report = verify_toolpath(kern, toolpath, tools, tolerance, step, worst=worst, stock=check, progress=say)
    report.pop("problem_moves")
    return VerifyResult(report, device, stock is not None or bool(allowance))


@dataclass
class DexelResult(_Saved):
    """``model``: the :class:`~meshmill.simulation.dexel.DexelModel`; ``summary``."""

    model: object
    summary: dict

    def save(self, path) -> list:
        """Write the model to ``path`` (.npz compact binary, .td the seed's ASCII) and
        ``summary.json`` beside it."""
        from .simulation.dexel import export_td, save_npz

        path = os.fspath(path)
        folder = os.path.dirname(os.path.abspath(path))

        def write(run):
            (export_td if path.lower().endswith(".td") else save_npz)(run.tmp(path), self.model)
            self.summary["file"] = os.path.abspath(path)
            write_json(run.tmp(os.path.join(folder, "summary.json")), self.summary)

        return self._save([path, os.path.join(folder, "summary.json")], write)


@_named_errors
def dexel(part, *, step, index="bvh", partitions="1", kmax=27, init="k-means++", minibatch=False, device="auto",
          cluster=None, progress=None) -> DexelResult:
    """Triple-dexel model of the part (seed 000) with lines ``step`` mm apart; ``index``: bvh, or the
    seed's cells or kmeans partitions (``partitions`` a count or "auto"); ``cluster`` (local
    workers, a scheduler's address or a Client): blocks of lines cast there (the same model)."""
    from .ops.simulate import dexel_model

    if index != "bvh" and device == "auto":
        device = "cpu"  # the seed's indexes run on the CPU only
    device = _device(device)
    from .cluster import connect

    with connect(cluster) as client:
        model, summary = dexel_model(part, step, index, str(partitions), init, minibatch, kmax, progress=progress,
                                     device=device, cluster=client)
    model.name = os.path.basename(part.source or "part")
    summary["part"] = _part_entry(part)
    summary["device"] = device
    return DexelResult(model, summary)


@dataclass
class SimulateResult(_Saved):
    """``deviation`` (ISO 25178 parameters, gouge and excess), ``summary``, the ``machined``
    surface ``(vertices, faces)`` and the deviation ``samples`` (points, e)."""

    deviation: dict
    summary: dict
    machined: tuple
    samples: dict

    @property
    def ok(self) -> bool:
        """No rapid cut material and no shank or holder hit it."""
        return not (self.summary["rapid_moves_cutting"] or self.summary["colliding_moves"])

    def save(self, folder) -> list:
        """Write deviation.json, summary.json and, where the run kept them, deviation.npz and
        machined.stl into ``folder`` (an earlier run's files there are removed)."""
        import numpy as np

        def write(run):
            if self.samples is not None:
                np.savez_compressed(run.tmp(os.path.join(folder, "deviation.npz")), points=self.samples["points"],
                                    e=self.samples["e"])
            if self.machined is not None and len(self.machined[1]):
                import trimesh

                trimesh.Trimesh(*self.machined, process=False).export(run.tmp(os.path.join(folder, "machined.stl")))
            write_json(run.tmp(os.path.join(folder, "deviation.json")), self.deviation)
            write_json(run.tmp(os.path.join(folder, "summary.json")), self.summary)

        return self._save([os.path.join(folder, n) for n in FOLDER_OUTPUTS["simulate"]], write)


@_named_errors
def simulate(design, toolpath, tools, *, step, stock="box", allowance=None, tolerance=GOUGE_TOL, mode="sweep",
             tool=None, machine=None, device="auto", cluster=None, outputs=("deviation", "mesh"),
             progress=None) -> SimulateResult:
    """Cut ``toolpath`` (a Toolpath or a file, read for ``machine`` and ``tool``) from the stock
    with dexels ``step`` mm apart and measure the result against ``design``: ``stock`` "box",
    a closed mesh or file, or ``allowance`` mm on the design; ``mode`` sweep (exact swept volumes)
    or points (the seed's); ``cluster``: blocks of dexel lines cast, cut and measured there (the
    same result; this process never holds the models); ``outputs``: what is kept beyond the
    summary and deviation figures, ``"deviation"`` (every dexel end's deviation, ``samples``)
    and ``"mesh"`` (the machined surface); a run without them is faster and smaller."""
    from .ops.simulate import simulate as one_process
    from .ops.simulate_blocks import simulate_on

    if not (_finite(step) and step > 0):
        raise InputError(f"--step must be a positive number of mm, got {step}")
    if allowance is not None and stock not in (None, "box"):
        raise InputError("give --stock or --allowance, not both")
    stock = "box" if stock in (None, "box") else _load_stock(stock)
    if isinstance(toolpath, (str, os.PathLike)):
        if isinstance(machine, (str, os.PathLike)):
            machine = load_machine(machine)
        toolpath = load_toolpath(toolpath, tools, tool=tool, machine=machine)
    device = _device(device)
    from .cluster import connect

    with connect(cluster) as client:
        run = one_process if client is None else functools.partial(simulate_on, client)
        deviation, summary, _, machined, samples = run(design, toolpath, tools, step, stock=stock,
                                                       allowance=allowance, tolerance=tolerance, mode=mode,
                                                       progress=progress, device=device, outputs=tuple(outputs))
    summary["device"] = device
    summary["tools_file"] = _tools_file(tools)
    summary["design"] = _part_entry(design)
    summary["toolpath"] = {"file": toolpath.source, "warnings": list(toolpath.warnings)}
    return SimulateResult(deviation, summary, machined, samples)


@dataclass
class AnalysisResult(_Saved):
    """``summary`` and the per-triangle and per-vertex ``arrays`` (analysis.npz)."""

    summary: dict
    arrays: dict

    def save(self, folder) -> list:
        import numpy as np

        def write(run):
            np.savez_compressed(run.tmp(os.path.join(folder, "analysis.npz")), **self.arrays)
            write_json(run.tmp(os.path.join(folder, "summary.json")), self.summary)

        return self._save([os.path.join(folder, n) for n in FOLDER_OUTPUTS["analyze"]], write)


@_named_errors
def analyze(part, *, direction=(0.0, 0.0, 1.0), weighting="area", theta_step=None, delta_step=10.0, device="auto",
            progress=None) -> AnalysisResult:
    """Triangle and vertex parameters, visibility and accessibility along ``direction`` (seed 001);
    with ``theta_step`` (degrees) also the accessibility map over the hemisphere."""
    import numpy as np

    from .geometry import analysis
    from .kernels.backend import MeshKernels
    from .kernels.bvh import build_bvh

    if isinstance(direction, str):
        try:
            direction = [float(v) for v in direction.split(",")]
        except ValueError:
            raise InputError(f"--direction must be three numbers X,Y,Z, got '{direction}'") from None
    if len(direction) != 3:
        raise InputError(f"--direction must be three numbers X,Y,Z, got '{','.join(map(str, direction))}'")
    say = progress or (lambda stage: None)
    device = _device(device)
    t0 = time.perf_counter()
    say("visibility")
    kern = MeshKernels(build_bvh(part.vertices, part.faces), device)
    tri = analysis.triangle_parameters(part)
    normals = analysis.vertex_normals(part, weighting)
    flags = analysis.visibility(part, direction, weighting, kern)
    seconds = {"visibility": round(time.perf_counter() - t0, 4)}
    summary = {
        "part": _part_entry(part),
        "direction": analysis.unit_direction(direction).round(9).tolist(),
        "weighting": weighting,
        "area_mm2": {"total": float(tri["area"].sum()), "min": float(tri["area"].min()), "max": float(tri["area"].max())},
        "boundary_edges": int((tri["neighbours"] < 0).sum()),
        **{k: int(v.sum()) for k, v in flags.items()},
    }
    arrays = {"vertex_normals": normals, **tri, **flags}
    if theta_step is not None:
        say("accessibility map")
        t1 = time.perf_counter()
        dirs = analysis.hemisphere(theta_step, delta_step)
        share, reached = analysis.accessibility_map(part, dirs, kern)
        seconds["map"] = round(time.perf_counter() - t1, 4)
        summary["map"] = {"directions": len(dirs), "best_direction": dirs[int(np.argmax(share))].round(9).tolist(),
                          "best_share": float(share.max()), "never_reached_triangles": int((reached == 0).sum())}
        arrays.update(map_directions=dirs, map_share=share, triangles_reached=reached)
    summary["seconds"] = seconds
    return AnalysisResult(summary, arrays)


@dataclass
class ChooseResult(PathResult):
    """choose: the path, the chosen ``tools`` (written as tools.toml), the ``zones`` arrays
    (zones.npz), the ``machine`` it was timed on and the ``device`` it ran on; ``part`` is the
    surface's name."""

    zones: dict = field(default_factory=dict)
    machine: object = None
    device: str = "cpu"

    @property
    def ok(self) -> bool:
        return bool(self.summary["verify"]["ok"]) and not self.summary["incomplete_zones"]

    def save(self, folder) -> list:
        import numpy as np

        from .tools.table import write_tools
        from .toolpath.cldata import write_apt

        def write(run):
            self.summary["tools_file"] = os.path.abspath(os.path.join(folder, "tools.toml"))
            write_tools(run.tmp(os.path.join(folder, "tools.toml")), self.tools)
            write_apt(run.tmp(os.path.join(folder, "toolpath.cl")), self.toolpath, self.tools,
                      partno=os.path.basename(self.part))
            np.savez_compressed(run.tmp(os.path.join(folder, "zones.npz")), **self.zones)
            write_json(run.tmp(os.path.join(folder, "summary.json")), self.summary)

        return self._save([os.path.join(folder, n) for n in FOLDER_OUTPUTS["choose"]], write)


@_named_errors
def choose(surface, *, scallop, tool_pair=None, tools=None, zones="auto", k_max=6, axes="3", optimise=0,
           machine="generic-3axis", cluster="kmeans", metric="euclidean", grid=80, mesh_step=0.5, sample=0.5,
           min_zone=0.01, seed=0, flip=False, device="auto", progress=None) -> ChooseResult:
    """Tool choice, zones and directions by machining time (seed 002) on ``surface`` (a patch TOML,
    "rubio" or "choi", a mesh file or a loaded part): the candidates are a ``tool_pair`` "D,r" or the ball and
    bull-nose cutters of ``tools`` (a table or its file)."""
    import numpy as np

    from .ops.choose import ChooseParams, load_surface
    from .ops.choose import choose as run
    from .ops.choose import tool_pair as pair

    if (tool_pair is None) == (tools is None):
        raise InputError("give exactly one of --tool-pair and --tools")
    if zones == "auto":
        zones = None
    else:
        try:
            zones = int(zones)
        except (TypeError, ValueError):
            raise InputError(f"--zones must be 'auto' or an integer, got '{zones}'") from None
    params = ChooseParams(scallop=scallop, zones=zones, axes=axes, optimise=optimise, grid=grid, mesh_step=mesh_step,
                          sample=sample, cluster=cluster, metric=metric, k_max=k_max, min_zone=min_zone, seed=seed)
    params.check()
    if tool_pair is not None:
        tools = pair(tool_pair)
    elif isinstance(tools, (str, os.PathLike)):
        tools = load_tools(tools)
    if isinstance(machine, (str, os.PathLike)):
        machine = load_machine(machine)
    device = _device(device)
    loaded = load_surface(surface, params, flip=flip)
    tp, summary, cells, chooser = run(loaded, tools, machine, params, progress=progress, device=device)
    s = chooser.samples
    zone_arrays = dict(grid_shape=np.array(s.grid_shape), zones=cells, points=s.points, normals=s.normals,
                       valid=s.valid)
    name = surface.source or "part" if hasattr(surface, "vertices") else os.fspath(surface)
    return ChooseResult("choose", tp, summary, name, chooser.tools, zones=zone_arrays, machine=machine, device=device)


@dataclass
class PostResult(_Saved):
    """``lines``: the G-code program; ``report``: what the post did (blocks, axis ranges, warnings)."""

    lines: list
    report: dict

    def save(self, path) -> list:
        """Write the program to ``path``."""
        def write(run):
            try:
                with open(run.tmp(path), "w") as fh:
                    fh.write("\n".join(self.lines) + "\n")
            except OSError as exc:
                raise InputError(f"{path}: cannot write ({exc.strerror})") from None
            self.report["program"] = os.path.abspath(path)

        return self._save([path], write)


def _feeds(toolpath, feed, machine):
    """Feeds per move, mm/s (NaN on rapids where unset) with those the path lacks filled by
    ``feed`` mm/min (else left to the machine's), and the note that says which."""
    import numpy as np

    per_s = np.asarray(toolpath.feed, float) / 60.0
    feed_move = ~toolpath.rapid
    unset = feed_move & np.isnan(per_s)
    nominal = f"the machine's {machine.motion.feed * 60.0:g} mm/min"
    fill = f"--feed {feed:g} mm/min" if feed is not None else nominal
    if feed is not None:
        per_s[unset] = feed / 60.0
    if not unset.any():
        note = "feeds as programmed"
    elif unset.sum() == feed_move.sum():
        note = f"no feed programmed: {fill}"
    else:
        note = f"{unset.sum()} of {feed_move.sum()} feed moves without a programmed feed: {fill}"
    return per_s, note, unset


@_named_errors
def post(toolpath, machine, tools, *, feed=None, tolerance=0.005, origin=None, clearance=None,
         progress=None) -> PostResult:
    """G-code of ``toolpath`` (a Toolpath or an APT CL file) for ``machine`` (a Machine or a name):
    ``feed`` mm/min where the path sets none; ``tolerance`` mm, the largest tip deviation between
    5-axis blocks; ``origin`` (X, Y, Z) the program's zero in machine coordinates; ``clearance``
    the Z above which the whole tool stays while the rotaries unwind."""
    from .machine.post import post_program
    from .toolpath.cldata import MAX_COORDINATE

    if feed is not None and not (_finite(feed) and feed > 0):
        raise InputError(f"--feed must be a positive number of mm/min, got {feed}")
    if not (_finite(tolerance) and tolerance > 0):
        raise InputError(f"--tolerance must be a positive number of mm, got {tolerance}")
    if isinstance(origin, str):
        try:
            origin = [float(v) for v in origin.split(",")]
        except ValueError:
            origin = []
    if origin is not None and (len(origin) != 3 or not all(_finite(v) for v in origin)):
        raise InputError(f"--origin wants X,Y,Z in mm (the program's zero in machine coordinates), got '{origin}'")
    if clearance is not None and not abs(clearance) <= MAX_COORDINATE:
        raise InputError(f"--clearance must be a Z in mm (|Z| <= {MAX_COORDINATE:g}), got {clearance}")
    if isinstance(machine, (str, os.PathLike)):
        machine = load_machine(machine)
    if isinstance(toolpath, (str, os.PathLike)):
        from .machine.pathfile import TOOLPATH_APT
        from .toolpath.cldata import read_apt

        if os.path.splitext(os.fspath(toolpath))[1].lower() not in TOOLPATH_APT:
            read_apt(toolpath, tools)  # refuses what is not an APT CL file
        toolpath = load_toolpath(toolpath, tools)
    per_s, note, _ = _feeds(toolpath, feed, machine)
    (progress or (lambda stage: None))("inverse kinematics and blocks")
    lines, report = post_program(toolpath, tools, machine, feed=per_s, tolerance=tolerance, origin=origin,
                                 clearance=clearance)
    report = {"operation": "post", "toolpath": toolpath.source, "program": "",
              "tools_file": _tools_file(tools), "feeds": note, **report}
    report["warnings"] = list(toolpath.warnings) + report["warnings"]
    return PostResult(lines, report)


@dataclass
class TimeResult(_Saved):
    """``summary``: machining time per tool and in total (cutting, rapid, tool changes, stops)."""

    summary: dict
    warnings: list

    def save(self, path) -> list:
        return self._save([path], lambda run: write_json(run.tmp(path), self.summary))


@_named_errors
def machining_time(toolpath, machine, tools, *, feed=None, tool=None, progress=None) -> TimeResult:
    """Machining time of ``toolpath`` (a Toolpath or an APT CL / G-code file) on ``machine`` with
    jerk-limited motion (seed 002 §1.6.2): ``feed`` mm/min on every feed move (default: as
    programmed, else the machine's)."""
    import numpy as np

    from .machine.timing import rotary_seconds, tool_times
    from .machine.pathfile import TOOLPATH_GCODE

    if feed is not None and not (_finite(feed) and feed > 0):
        raise InputError(f"--feed must be a positive number of mm/min, got {feed}")
    if isinstance(machine, (str, os.PathLike)):
        machine = load_machine(machine)
    if isinstance(toolpath, (str, os.PathLike)):
        is_gcode = os.path.splitext(os.fspath(toolpath))[1].lower() in TOOLPATH_GCODE
        toolpath = load_toolpath(toolpath, tools, tool=tool, machine=machine if is_gcode else None)
    tp = toolpath
    (progress or (lambda stage: None))("timing")
    feed_move = ~tp.rapid[1:]
    if feed is not None:
        per_s, unset = np.full(len(tp), feed / 60.0), 0
        notes = [f"feed {feed:g} mm/min (--feed) on every feed move"]
    else:
        per_s = np.asarray(tp.feed, float) / 60.0
        unset = int((feed_move & np.isnan(per_s[1:])).sum())
        nominal = f"the machine's {machine.motion.feed * 60.0:g} mm/min"
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
    times = tool_times(tp.tip, tp.rapid, tp.tool, machine, per_s, rotary)
    summary = {"operation": "time", "toolpath": tp.source, "moves": len(tp),
               "machine": machine.summary(), "tools_file": _tools_file(tools), "notes": notes,
               "feed_moves": int(feed_move.sum()), "feed_moves_at_machine_feed": unset,
               "tools": {tools[t].name: entry for t, entry in times["tools"].items()}, "total": times["total"]}
    return TimeResult(summary, list(tp.warnings))


@_named_errors
def report(folders, out="report.html", *, progress=None) -> dict:
    """One self-contained HTML file ``out`` with 3D views and tables of the run ``folders``;
    returns what it holds (runs, views, bytes, notes)."""
    from .htmlreport import write_report
    from .runfiles import RunFiles

    folder = os.path.dirname(os.path.abspath(out))
    if not os.path.isdir(folder):
        raise InputError(f"{folder}: no such folder for --out")
    run = RunFiles([out])
    try:
        info = write_report(list(folders), run.tmp(out), progress=progress)
        run.commit()
    finally:
        if not run.done:
            run.abort()
    info["file"] = os.path.abspath(out)
    return info
