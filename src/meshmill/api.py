"""meshmill as a library: every command as a function, with the command's options as keyword
arguments (same names with ``_`` for ``-``, same defaults: both come from :mod:`meshmill.params`)
and a small result object (:mod:`meshmill.results`) whose ``save`` writes exactly the files the
command writes.

```python
import meshmill
part = meshmill.load_part("part.stl", units="m", origin="bottom-centre")  # Mesh, mm, work frame
tools = meshmill.load_tools("tools.toml")
res = meshmill.finish(part, tools, step_down=1.0)
res.toolpath, res.summary   # the Toolpath and the dict summary.json holds
res.save("out/")            # contours.npz, toolpath.cl, part.stl, summary.json
```

Every function checks its arguments the same way: an unknown keyword, a missing one, a value of
the wrong type (a number given as text, a boolean as text) or out of range raises
:class:`~meshmill.errors.InputError` naming the parameter (``step_down must be a number of mm >=
0.0001, got -1``; the command line names its flags instead). A part, a tool table, a machine, a
tool path or a stock may be given as a file name. ``device`` is ``"cpu"``, ``"cuda"`` or
``"auto"`` (a usable GPU when there is one); ``progress`` is called with the name of each stage.
Units: mm, degrees for angles, mm/min for feeds.
"""
from __future__ import annotations

import functools
import inspect
import os

from . import memory
from .errors import InputError, NothingToCut
from .options import Params
from .params import (OUTPUTS, AnalyzeParams, ChooseParams, ClearFixturesParams, DexelParams, FinishParams,
                     LoadPartParams, LoadToolpathParams, PlungeParams, PostParams, RasterParams, ReportParams,
                     RoughParams, SimulateParams, SteepShallowParams, TimeParams, VerifyParams, WaterlineParams,
                     FeedsParams)
from .results import (AnalysisResult, ChooseResult, DexelResult, FixturesResult, PathResult, PostResult,
                      SimulateResult, TimeResult, VerifyResult, FeedsResult)

__all__ = ["load_part", "load_tools", "load_toolpath", "load_machine", "finish", "raster", "waterline",
           "steep_shallow", "plunge",
           "rough", "verify", "dexel", "simulate", "analyze", "choose", "post", "machining_time", "report", "clear_fixtures",
           "optimise_feeds", "optimised_feeds", "air_feeds", "air_time_share", "what_is_left", "in_material", "connect", "resolve_device", "part_entry", "tools_file", "Stock", "Fixture", "Toolpath", "PathResult",
           "VerifyResult", "DexelResult", "SimulateResult", "AnalysisResult", "ChooseResult", "PostResult",
           "TimeResult", "FixturesResult", "FeedsResult", "InputError", "NothingToCut"]
TYPES = {"Stock": "simulation.stock", "Fixture": "ops.fixtures", "Toolpath": "toolpath.model"}


def __getattr__(name):
    if name in TYPES:  # imported on first use: they bring numpy
        import importlib

        return getattr(importlib.import_module(f"{__package__}.{TYPES[name]}"), name)
    raise AttributeError(f"module 'meshmill.api' has no attribute '{name}'")


# ---------------------------------------------------------------- checking arguments


def operation(spec: type[Params], *positional: str):
    """The API function of ``body(p)``: its signature is ``spec``'s options (``positional`` first,
    the rest by keyword only, with their defaults), its docstring lists them, and a call checks
    every argument (:meth:`~meshmill.options.Params.checked`), turns objects given as file names
    into what they name (:data:`CONVERT`) and hands ``body`` the params."""
    opts = spec.options()

    def wrap(body):
        name = body.__name__
        sig = inspect.Signature(
            [inspect.Parameter(n, inspect.Parameter.POSITIONAL_OR_KEYWORD) for n in positional]
            + [inspect.Parameter(n, inspect.Parameter.KEYWORD_ONLY,
                                 default=inspect.Parameter.empty if o.required else o.default)
               for n, o in opts.items() if n not in positional],
            return_annotation=inspect.signature(body).return_annotation)
        lines = [f"    {n}: {o.help}" + (f" ({o.unit})" if o.unit else "") for n, o in opts.items()]

        @functools.wraps(body)
        def call(*args, **kwargs):
            if len(args) > len(positional):
                raise InputError(f"{name} takes {len(positional)} positional argument"
                                 f"{'s' * (len(positional) != 1)} ({', '.join(positional)}); give the others by name")
            values = dict(zip(positional, args))
            twice = sorted(set(values) & set(kwargs))
            if twice:
                raise InputError(f"{name} got {', '.join(twice)} twice", tuple(twice))
            values.update(kwargs)
            p = spec.checked(values, name)
            with memory.long_lived():
                return body(convert(p))

        call.__signature__ = sig
        call.__doc__ = f"{body.__doc__}\n\n    Parameters:\n" + "\n".join(lines)
        call.spec = spec
        return call

    return wrap


def convert(p: Params) -> Params:
    """``p`` with its objects (parts, tools, machines, tool paths, stocks...) as they are used:
    file names read, values of the wrong type refused (:class:`InputError` naming them)."""
    opts = p.options()
    values = {n: getattr(p, n) for n in opts}
    for role in ROLES:
        for n, o in opts.items():
            if o.role == role:
                values[n] = CONVERT[role](o, values[n], values)
    values.pop("machine reads", None)
    if values.get("tools") is not None and "material" in values:  # the tools' speeds in that material
        values["tools"] = in_material(values["tools"], values["material"], values.get("machine"))
    return p.replace(**values)


def _is_mesh(v) -> bool:
    return hasattr(v, "vertices") and hasattr(v, "faces") and hasattr(v, "closed")


def _is_file(v) -> bool:
    return isinstance(v, os.PathLike) or isinstance(v, str) and bool(v.strip())


def _as_path(o, v, values):
    if not _is_file(v):
        raise o.refuse(v, "a file name")
    return os.fspath(v)


def _as_part(o, v, values):
    if _is_mesh(v) or v is None and o.default is None:
        return v
    if _is_file(v):
        return load_part(v)
    raise o.refuse(v, "a Mesh (meshmill.load_part) or a mesh file")


def _as_origin(o, v, values):
    if isinstance(v, str) and v.strip():
        return v
    from .options import Option

    point = Option("numbers", "", unit="mm", name=o.name, what=o.what).check(v)
    return ",".join(repr(x) for x in point)


def _as_surface(o, v, values):
    if _is_mesh(v) or _is_file(v):
        return v
    raise o.refuse(v, "a patch file or name (rubio, choi), a mesh file or a Mesh")


def _as_tools(o, v, values):
    from .tools.table import Tool

    if v is None:
        path = values.get("toolpath")
        if o.default is None and _is_file(path):  # post, time: the tools.toml beside the tool path (choose's)
            beside = os.path.join(os.path.dirname(os.path.abspath(os.fspath(path))), "tools.toml")
            if not os.path.exists(beside):
                raise InputError(f"no tools given and no tools.toml beside {os.fspath(path)}: give the tool table",
                                 o.name)
            return load_tools(beside)
        if o.default is None and "toolpath" not in values:
            return None
        raise o.refuse(v, "a tool table: its TOML file, or the tools of meshmill.load_tools")
    if _is_file(v):
        return load_tools(v)
    if isinstance(v, (list, tuple)) and v and all(isinstance(t, Tool) for t in v):
        return v
    raise o.refuse(v, "a tool table: its TOML file, or the tools of meshmill.load_tools")


def _as_machine(o, v, values):
    from .machine.model import Machine

    values["machine reads"] = o.role == "machine"  # the machine a path is for (post, time) reads G-code only
    if v is None or isinstance(v, Machine):
        return v
    if _is_file(v):
        return load_machine(v)
    raise o.refuse(v, "a machine: a shipped name (table-table-ac, generic-3axis, ...), a machine file or a Machine")


def _as_toolpath(o, v, values):
    from .toolpath.model import Toolpath

    if isinstance(v, Toolpath):
        return v
    if not _is_file(v):
        raise o.refuse(v, "a Toolpath or a tool path file (APT CL or G-code)")
    if values.get("tools") is None:
        raise InputError("a tool path file is read with its tool table: give tools", ("tools", o.name))
    from .machine.pathfile import TOOLPATH_APT, TOOLPATH_GCODE

    ext = os.path.splitext(os.fspath(v))[1].lower()
    if o.role == "cl" and ext not in TOOLPATH_APT:
        raise InputError(f"{os.fspath(v)}: {o.name} must be an APT CL file ({', '.join(TOOLPATH_APT)}); G-code is "
                         "posted already", o.name)
    machine = values.get("machine") if values.get("machine reads", True) or ext in TOOLPATH_GCODE else None
    return load_toolpath(v, values["tools"], tool=values.get("tool"), machine=machine)


def _as_stock(o, v, values):
    from .simulation.stock import Stock

    if v is None or isinstance(v, Stock):
        return v
    if _is_mesh(v):
        return Stock.mesh(v)
    if isinstance(v, str) and v.strip().lower() == "box":
        return Stock.box()
    if isinstance(v, str) and v.strip().lower().startswith("offset:"):
        from .options import Option

        mm = Option("number", "", unit="mm", low=0.0, name=o.name)
        return Stock.offset(mm.check(mm.from_text(v.split(":", 1)[1].strip())))
    if _is_file(v):
        path = os.fspath(v)
        if path.lower().endswith(".npz"):
            return Stock.load(path, values.get("part") or values.get("design"))
        from .geometry.mesh import load_mesh

        return Stock.mesh(load_mesh(path))
    raise o.refuse(v, "a Stock (meshmill.Stock.box(), .offset(mm), .mesh(...)), a closed Mesh, a mesh file, a saved "
                      "stock (.npz), 'box' or 'offset:MM'")


def _as_cluster(o, v, values):
    if v is None or isinstance(v, str) and v.strip() or hasattr(v, "submit") and hasattr(v, "scatter"):
        return v
    if isinstance(v, int) and not isinstance(v, bool) and v >= 1:
        return v
    raise o.refuse(v, "a number of local workers (>= 1), a scheduler's address or a distributed.Client")


def _as_progress(o, v, values):
    if v is None or callable(v):
        return v
    raise o.refuse(v, "a function of one argument (the stage's text), or None")


def _as_outputs(o, v, values):
    names = [w.strip() for w in v.split(",") if w.strip()] or None if isinstance(v, str) else v
    if isinstance(names, (list, tuple)) and all(isinstance(w, str) for w in names):
        if list(names) == ["all"]:
            return OUTPUTS
        if set(names) <= {"summary", *OUTPUTS}:
            return tuple(k for k in OUTPUTS if k in names)
    raise o.refuse(v, f"a list of {', '.join(OUTPUTS)} (the command line's comma list may say summary or all)")


def _as_folders(o, v, values):
    items = [v] if _is_file(v) else v
    if isinstance(items, (list, tuple)) and items and all(_is_file(f) for f in items):
        return [os.fspath(f) for f in items]
    raise o.refuse(v, "a run folder or a list of them")


def _as_fixtures(o, v, values):
    from .ops.fixtures import Fixture

    if v is None and o.default is None:  # optional: none
        return None
    items = v if isinstance(v, (list, tuple)) else [v]
    out = []
    for k, f in enumerate(items):
        if isinstance(f, Fixture):
            out.append(f)
        elif _is_mesh(f) and f.closed:
            out.append(Fixture(f"fixture {k + 1}", mesh=f))
        elif isinstance(f, dict):
            out.append(Fixture.from_dict(f, "", k + 1))
        else:
            raise o.refuse(v, "a list of Fixtures, closed Meshes or [[fixtures]] tables")
    if not out:
        raise o.refuse(v, "a list of Fixtures, closed Meshes or [[fixtures]] tables")
    return out


CONVERT = {"cluster": _as_cluster, "progress": _as_progress, "outputs": _as_outputs, "folders": _as_folders,
           "origin": _as_origin, "path": _as_path, "part": _as_part, "surface": _as_surface, "tools": _as_tools,
           "machine": _as_machine, "target_machine": _as_machine, "toolpath": _as_toolpath, "cl": _as_toolpath,
           "stock": _as_stock, "fixtures": _as_fixtures}
ROLES = tuple(CONVERT)  # the order objects are converted in: values first, then files (a path with its tools)


def check_interrupted() -> None:
    """Raise KeyboardInterrupt where the command line was interrupted although no
    KeyboardInterrupt came through (see :data:`meshmill.runfiles.interrupted`)."""
    from .runfiles import interrupted

    if interrupted[0]():
        raise KeyboardInterrupt


def resolve_device(device) -> str:
    """``"cpu"`` or ``"cuda"`` for ``device`` (cpu, cuda, auto: the GPU when a usable one is present)."""
    from .kernels.backend import resolve

    return resolve(device)



def connect(cluster):
    """A context holding the ``distributed.Client`` of ``cluster`` (a number of local workers, a
    scheduler's address, a Client; None: no cluster, the context holds None)."""
    from .cluster import connect as open_client

    return open_client(cluster)


def part_entry(mesh) -> dict:
    """What a summary says of a part: its file and :meth:`~meshmill.geometry.mesh.Mesh.summary`."""
    return {"file": mesh.source, **mesh.summary()}


def tools_file(tools) -> str:
    """The file a tool table was read from ("" for tools made in Python)."""
    path = getattr(tools, "path", "")
    return os.path.abspath(path) if path else ""



def _path_result(operation, tp, summary, mesh, tools, device, arrays=None, material=None, entries=None):
    """The :class:`PathResult` of an operation's verified path ``tp``, each move fed as its tool's
    cutting data in ``material`` says (:func:`~meshmill.ops.feeds.table_feeds`; ``entries
    (k,) bool``: its ramp and helix moves)."""
    import numpy as np

    from .ops.feeds import table_feeds
    from .tools.cutting import conditions

    if not len(tp) or tp.rapid.all():
        raise NothingToCut(f"nothing to cut: the {operation} path has no feed move (verified: every move that would "
                           "cut was left out)")
    feeds = table_feeds(tp, conditions(tools, material), entries)
    unset = ~np.isfinite(tp.feed)
    tp.feed = np.where(unset, feeds, tp.feed)
    summary["device"] = device
    summary["tools_file"] = tools_file(tools)
    summary["part"] = part_entry(mesh)
    summary["seconds"]["load"] = round(mesh.load_seconds, 4)
    summary["seconds"]["total"] = round(summary["seconds"]["total"] + mesh.load_seconds, 4)
    return PathResult(operation, tp, summary, mesh, tools, arrays or {})


# ---------------------------------------------------------------- loading


@operation(LoadPartParams, "path")
def load_part(p):
    """The part mesh of ``path`` set up into the work frame (mm, +Z to the spindle). Returns a
    :class:`~meshmill.geometry.mesh.Mesh` (its ``warnings`` say what was repaired or looks wrong)."""
    from .geometry.mesh import load_mesh
    from .geometry.placement import Setup

    setup = Setup(units=p.units, up=p.up, origin=p.origin, scale=p.scale)
    setup.check()
    return load_mesh(p.path, flip=p.flip, setup=setup)


def load_tools(path, units="mm"):
    """The tool table of ``path``: a list of :class:`~meshmill.tools.table.Tool` (numbered from
    1) with the file's ``path`` and ``warnings``. TOML, a FreeCAD tool bit (.fctb) or library
    (.fctl), or a LinuxCNC tool table (.tbl, in ``units``: mm or inch)."""
    from .tools.table import load_tools as read

    if not _is_file(path):
        raise InputError(f"tools must be a tool table's file (TOML, .fctb, .fctl, .tbl), got {path!r}", "tools")
    if units not in ("mm", "inch"):
        raise InputError(f"units must be mm or inch, got {units!r}", "units")
    return read(path, units)


def load_machine(machine):
    """A machine: a TOML file or a shipped name (generic-3axis, table-table-ac, head-table-bc, ...)."""
    from .machine.config import load_machine as read

    if not _is_file(machine):
        raise InputError(f"machine must be a shipped name or a machine file, got {machine!r}", "machine")
    return read(machine)


@operation(LoadToolpathParams, "path", "tools")
def load_toolpath(p):
    """The :class:`~meshmill.toolpath.model.Toolpath` of an APT CL file or G-code (by extension),
    its ``feed`` (mm/min per move, NaN where the file sets none), ``source`` and ``warnings``."""
    from .machine.pathfile import read_toolpath

    return read_toolpath(p.path, p.tools, p.tool, p.machine)[0]


# ---------------------------------------------------------------- operations


@operation(FinishParams, "part", "tools")
def finish(p) -> PathResult:
    """5-axis Z-constant finishing with the ball-end tools of ``tools`` (seed 004 and beyond)."""
    import numpy as np

    from .cluster import connect
    from .ops.finish_areas import AREA_STATUS
    from .ops.finish import finish as run

    device = resolve_device(p.device)
    with connect(p.cluster) as client:
        tp, summary, detail = run(p.part, p.tools, p, progress=p.progress, device=device, machine=p.machine,
                                  cluster=client)
    con = detail["contours"]
    arrays = dict(points=con.points, offsets=con.offsets, z=con.z, closed=con.closed,
                  machinable=detail["contour_tool"] >= 0, surface_points=detail["surface_points"],
                  surface_status=detail["surface_status"], status_names=np.array(AREA_STATUS),
                  raster_from=detail["raster_from"], raster_reach=detail["raster_reach"])
    return _path_result("finish", tp, summary, p.part, p.tools, device, arrays, material=p.material)


@operation(RasterParams, "part", "tools")
def raster(p) -> PathResult:
    """3-axis zigzag finishing with the tool named ``tool``; with ``rest`` only the pieces of the
    passes that remove more than that depth of the stock (rest machining)."""
    from .cluster import connect
    from .ops.raster import raster as run

    device = resolve_device(p.device)
    with connect(p.cluster) as client:
        tp, summary = run(p.part, p.tools, p.tool, p, progress=p.progress, device=device, cluster=client)
    return _path_result("raster", tp, summary, p.part, p.tools, device, material=p.material)


@operation(WaterlineParams, "part", "tools")
def waterline(p) -> PathResult:
    """3-axis Z-level loops with the tool named ``tool``; with ``rest`` only the pieces of the
    loops that remove more than that depth of the stock."""
    from .cluster import connect
    from .ops.waterline import waterline as run

    device = resolve_device(p.device)
    with connect(p.cluster) as client:
        tp, summary, _ = run(p.part, p.tools, p.tool, p, progress=p.progress, device=device, cluster=client)
    return _path_result("waterline", tp, summary, p.part, p.tools, device, material=p.material)


@operation(SteepShallowParams, "part", "tools")
def steep_shallow(p) -> PathResult:
    """3-axis finishing to a scallop limit with the tool named ``tool``: Z levels on the ground
    steeper than ``threshold``, parallel passes on the shallower, overlapping; with ``rest`` only
    the pieces that remove more than that depth of the stock (rest finishing)."""
    from .cluster import connect
    from .ops.steep_shallow import steep_shallow as run

    device = resolve_device(p.device)
    with connect(p.cluster) as client:
        tp, summary = run(p.part, p.tools, p.tool, p, progress=p.progress, device=device, cluster=client)
    return _path_result("steep-shallow", tp, summary, p.part, p.tools, device, material=p.material)


def what_is_left(part, points, e, step, tools, used=(), five_axis=False, tolerance=0.01, device="cpu", stock=None):
    """What a stock leaves on ``part``, where and why (:mod:`meshmill.ops.left`): the design
    sampled by area, each sample given the deviation of the stock's dexel ends ``points (k, 3)``,
    ``e (k,)`` mm next to it (a lattice ``step`` mm apart: :attr:`SimulateResult.samples`) and,
    out of tolerance, the reason no tool of ``tools`` took it (``used``: the names of those the
    job ran; ``five_axis``: it had 5-axis operations). Returns ``(arrays, report)``: per sample
    ``points``, ``normals``, ``area`` mm², ``e`` mm, ``reason``; the area per reason (mm²) and
    the shares within tolerance of the whole surface and of what the table's tools reach.
    ``stock``: the in-process stock those ends are of (a :class:`Stock` of dexels): where it
    stands over the design with no end near, the sample gets a reason too, not "not measured"."""
    import numpy as np

    from .kernels.backend import solid_kernels
    from .ops.left import what_is_left as run

    kern = solid_kernels(part, resolve_device(device))
    return run(part, kern, np.asarray(points, float), np.asarray(e, float), float(step), tools, set(used),
               bool(five_axis), float(tolerance), None if stock is None else stock.model)


@operation(PlungeParams, "part", "tools")
def plunge(p) -> PathResult:
    """Plunge roughing (seed 001) with the tool named ``tool``, leaving ``allowance`` mm."""
    from .ops.plunge import plunge3, plunge5
    from .ops.simulate import simulate as cut

    if p.stock is not None and p.axes != 3:
        raise InputError("stock: 5-axis plunge roughing starts from the part's box (give axes 3)", ("stock", "axes"))
    device = resolve_device(p.device)
    run = plunge3 if p.axes == 3 else plunge5
    tp, summary = run(p.part, p.tools, p.tool, p.replace(device=device), progress=p.progress)
    if p.simulate is not None:
        dev, sim, *_ = cut(p.part, tp, p.tools, p.simulate, "box", progress=p.progress, device=device)
        v = sim["volumes_mm3"]
        summary["simulation"] = {"step": p.simulate, "stock_volume": v["stock"], "removed_volume": v["removed"],
                                 "remaining_volume": v["remaining"], "gouged_volume": v["gouged"],
                                 "gouge_max": dev["gouge_max"], "seconds": sim["seconds"]["total"]}
    return _path_result("plunge", tp, summary, p.part, p.tools, device, material=p.material)


@operation(RoughParams, "part", "tools")
def rough(p) -> PathResult:
    """Adaptive clearing from ``stock`` (default the part's box) with the tool named ``tool``: Z
    levels whose every step keeps the radial width of cut under ``engagement``, leaving
    ``allowance`` mm on the walls and ``axial_allowance`` on the floors. ``arrays["move_kind"]``
    gives each move's kind (indices into ``arrays["kinds"]``: rapid, cut, entry, link)."""
    import numpy as np

    from .ops.rough import MOVE_KINDS, rough as run

    from .cluster import connect

    device = resolve_device(p.device)
    with connect(p.cluster) as client:
        tp, summary, kind = run(p.part, p.tools, p.replace(device=device, cluster=None), progress=p.progress,
                                cluster=client)
    return _path_result("rough", tp, summary, p.part, p.tools, device,
                        dict(move_kind=kind, kinds=np.array(MOVE_KINDS)), p.material, kind == MOVE_KINDS.index("entry"))


@operation(VerifyParams, "part", "toolpath", "tools")
def verify(p) -> VerifyResult:
    """Check ``toolpath`` against the part for gouges beyond ``tolerance`` and shank or holder
    collisions, certified between poses ``step`` mm apart; rapids against ``stock``."""
    from .cluster import connect
    from .ops.verify import verify as run

    device = resolve_device(p.device)
    with connect(p.cluster) as client:
        report = run(p.part, p.toolpath, p.tools, p.tolerance, p.step, p.stock, p.worst, device, client,
                     p.progress if client is not None else None)
    problems = report.pop("problem_moves", None)
    checked = p.stock is not None and (p.stock.kind != "offset" or p.stock.allowance > 0)
    return VerifyResult(report, device, checked, problems)


@operation(DexelParams, "part")
def dexel(p) -> DexelResult:
    """Triple-dexel model of the part (seed 000) with lines ``step`` mm apart."""
    from .cluster import connect
    from .ops.simulate import dexel_model

    device = resolve_device("cpu" if p.index != "bvh" and p.device == "auto" else p.device)  # the seed's indexes: CPU
    with connect(p.cluster) as client:
        model, summary = dexel_model(p.part, p.step, p.index, p.partitions, p.init, p.minibatch, p.kmax,
                                     progress=p.progress, device=device, cluster=client)
    summary["part"] = part_entry(p.part)
    summary["device"] = device
    return DexelResult(model, summary)


@operation(SimulateParams, "design", "toolpath", "tools")
def simulate(p) -> SimulateResult:
    """Cut ``toolpath`` from ``stock`` with dexels ``step`` mm apart and measure the result
    against ``design``; ``result.stock`` is the stock after it."""
    from .cluster import connect
    from .ops.simulate import simulate as one_process
    from .ops.simulate_blocks import simulate_on

    from .simulation.stock import Stock

    device = resolve_device(p.device)
    stock = Stock.of(p.stock, "box")
    with connect(p.cluster) as client:
        if client is None or stock.cut_already:  # an in-process stock is cut here (its pieces on the cluster)
            deviation, summary, after, machined, samples, load = one_process(
                p.design, p.toolpath, p.tools, p.step, stock, p.tolerance, p.mode, p.progress, device, p.outputs,
                client, p.material, p.machine)
        else:
            deviation, summary, after, machined, samples, load = simulate_on(
                client, p.design, p.toolpath, p.tools, p.step, stock, p.tolerance, p.mode, p.progress, device,
                p.outputs, p.material, p.machine)
    summary["device"] = device
    summary["tools_file"] = tools_file(p.tools)
    summary["design"] = part_entry(p.design)
    summary["toolpath"] = {"file": p.toolpath.source, "warnings": list(p.toolpath.warnings)}
    return SimulateResult(deviation, summary, machined, samples, after, load)


@operation(AnalyzeParams, "part")
def analyze(p) -> AnalysisResult:
    """Triangle and vertex parameters, visibility and accessibility along ``direction`` (seed 001);
    with ``theta_step`` (degrees) also the accessibility map over the hemisphere."""
    from .ops.analyze import analyze as run

    summary, arrays = run(p.part, p.direction, p.weighting, p.theta_step, p.delta_step, resolve_device(p.device),
                          p.progress)
    return AnalysisResult({"part": part_entry(p.part), **summary}, arrays)


@operation(ChooseParams, "surface")
def choose(p) -> ChooseResult:
    """Tool choice, zones and directions by machining time (seed 002) on ``surface``: the
    candidates are a ``tool_pair`` "D,r" or the ball and bull-nose cutters of ``tools``."""
    import numpy as np

    from .ops.choose import choose as run
    from .ops.choose import load_surface
    from .ops.choose import tool_pair as pair

    tools = pair(p.tool_pair) if p.tool_pair is not None else p.tools
    device = resolve_device(p.device)
    loaded = load_surface(p.surface, p, flip=p.flip)
    tp, summary, cells, chooser = run(loaded, tools, p.machine, p, progress=p.progress, device=device)
    s = chooser.samples
    zone_arrays = dict(grid_shape=np.array(s.grid_shape), zones=cells, points=s.points, normals=s.normals,
                       valid=s.valid)
    name = p.surface.source or "part" if _is_mesh(p.surface) else os.fspath(p.surface)
    return ChooseResult("choose", tp, summary, name, chooser.tools, zones=zone_arrays, machine=p.machine,
                        device=device)


@operation(PostParams, "toolpath", "machine", "tools")
def post(p) -> PostResult:
    """G-code of ``toolpath`` (an APT CL file or a Toolpath) for ``machine``."""
    from .machine.post import post_program

    toolpath = p.toolpath
    if p.progress:
        p.progress("inverse kinematics and blocks")
    per_s, note, _ = _feeds(toolpath, p.feed, p.machine)
    lines, report = post_program(toolpath, p.tools, p.machine, feed=per_s, tolerance=p.tolerance, origin=p.origin,
                                 clearance=p.clearance)
    report = {"operation": "post", "toolpath": toolpath.source, "program": "",
              "tools_file": tools_file(p.tools), "feeds": note, **report}
    report["warnings"] = list(toolpath.warnings) + report["warnings"]
    return PostResult(lines, report)


def _feeds(toolpath, feed, machine):
    """Feeds per move, mm/s (NaN on rapids where unset) with those the path lacks filled by
    ``feed`` mm/min (else left to the machine's), and the note that says which."""
    import numpy as np

    per_s = np.asarray(toolpath.feed, float) / 60.0
    feed_move = ~toolpath.rapid
    unset = feed_move & np.isnan(per_s)
    nominal = f"the machine's {machine.motion.feed * 60.0:g} mm/min"
    fill = f"feed {feed:g} mm/min" if feed is not None else nominal
    if feed is not None:
        per_s[unset] = feed / 60.0
    if not unset.any():
        note = "feeds as programmed"
    elif unset.sum() == feed_move.sum():
        note = f"no feed programmed: {fill}"
    else:
        note = f"{unset.sum()} of {feed_move.sum()} feed moves without a programmed feed: {fill}"
    return per_s, note, unset


@operation(TimeParams, "toolpath", "machine", "tools")
def machining_time(p) -> TimeResult:
    """Machining time of ``toolpath`` on ``machine`` with jerk-limited motion (seed 002 §1.6.2):
    ``feed`` mm/min on every feed move (default: as programmed, else the machine's)."""
    from .machine.timing import path_times

    if p.progress:
        p.progress("timing")
    summary, notes = path_times(p.toolpath, p.machine, p.tools, p.feed)
    summary = {"operation": "time", "toolpath": p.toolpath.source, "moves": len(p.toolpath),
               "machine": p.machine.summary(), "tools_file": tools_file(p.tools), "notes": notes, **summary}
    return TimeResult(summary, list(p.toolpath.warnings))


def in_material(tools, material=None, machine=None):
    """``tools`` with each one's spindle speed that of its cutting data in ``material``, within
    ``machine``'s spindle (:func:`~meshmill.tools.cutting.in_material`)."""
    from .tools.cutting import in_material as resolve

    return resolve(tools, material, getattr(machine, "spindle", None))


def optimised_feeds(toolpath, load, tools, material=None, machine=None):
    """mm/min ``(k,)``: the feeds of ``toolpath`` optimised on its measured ``load`` (a
    :class:`~meshmill.simulation.load.MoveLoad`, :attr:`SimulateResult.load`) for ``tools`` in
    ``material`` on ``machine`` (its spindle and largest feed; None: generic-3axis)
    (:func:`~meshmill.ops.feeds.optimise_feeds`)."""
    from .ops.feeds import optimise_feeds as optimise
    from .tools.cutting import conditions

    machine = load_machine(machine or "generic-3axis") if not hasattr(machine, "spindle") else machine
    return optimise(toolpath, load, conditions(tools, material, machine.spindle), machine.spindle,
                    machine.spindle.max_feed)


def air_feeds(toolpath, in_material, machine=None):
    """mm/min ``(k,)``: the feeds of ``toolpath`` with its runs of moves in air (``in_material
    (k,) bool`` False, as the in-process stock measured them: :attr:`SimulateResult.load`'s) at the
    largest feed of ``machine`` (None: generic-3axis) (:func:`~meshmill.ops.feeds.air_feeds`)."""
    from .ops.feeds import air_feeds as fast

    machine = load_machine(machine or "generic-3axis") if not hasattr(machine, "spindle") else machine
    return fast(toolpath, in_material, machine.spindle.max_feed)


def air_time_share(toolpath, in_material, machine=None) -> float:
    """The share of ``toolpath``'s feed time in air (``in_material (k,) bool`` False), each move
    at its feed (NaN: the nominal feed of ``machine``, None: generic-3axis)
    (:func:`~meshmill.ops.feeds.air_time_share`)."""
    from .ops.feeds import air_time_share as share

    machine = load_machine(machine or "generic-3axis") if not hasattr(machine, "motion") else machine
    return share(toolpath, in_material, machine.motion.feed * 60.0)


@operation(FeedsParams, "design", "toolpath", "tools")
def optimise_feeds(p) -> FeedsResult:
    """Each move of ``toolpath`` fed so that its chip stays at its tool's feed per tooth and the
    spindle's power and torque are not exceeded, in light cuts and in air faster, within the
    machine's largest feed: the load measured by cutting the path from ``stock``
    (:func:`simulate`), the feeds optimised (:func:`optimised_feeds`), the machining time with
    the feeds as programmed (else the table's, else the machine's) and optimised, and the
    program posted for ``machine``."""
    from .toolpath.model import Toolpath
    from .ops.feeds import table_feeds
    from .tools.cutting import conditions

    import numpy as np

    sim = simulate(p.design, p.toolpath, p.tools, step=p.step, stock=p.stock, tolerance=p.tolerance, device=p.device,
                   progress=p.progress, material=p.material, machine=p.machine, outputs=())
    tp = p.toolpath
    before = tp.feed.copy()
    unset = ~np.isfinite(before)
    before[unset] = table_feeds(tp, conditions(p.tools, p.material, p.machine.spindle))[unset]
    given = Toolpath(tp.tip, tp.axis, tp.rapid, tp.tool, tp.line, before, tp.source)
    new = optimised_feeds(tp, sim.load, p.tools, p.material, p.machine)
    out = Toolpath(tp.tip, tp.axis, tp.rapid, tp.tool, tp.line, new, tp.source)
    t0 = machining_time(given, p.machine, p.tools).summary
    t1 = machining_time(out, p.machine, p.tools).summary
    posted = post(out, p.machine, p.tools)
    load = sim.summary.get("load") or {}
    moved = ~tp.rapid & np.isfinite(new)
    summary = {"operation": "feeds", "toolpath": tp.source, "moves": len(tp), "material": p.material,
               "design": part_entry(p.design),
               "machine": p.machine.summary(), "tools_file": tools_file(p.tools),
               "time_s": {"before": t0["total"]["total_s"], "optimised": t1["total"]["total_s"]},
               "time": {"before": t0, "optimised": t1},
               "feed_mm_min": {"lowest": float(np.nanmin(new[moved])) if moved.any() else None,
                               "highest": float(np.nanmax(new[moved])) if moved.any() else None,
                               "changes": int((np.diff(new[moved]) != 0).sum()) if moved.any() else 0},
               "load_before": load, "errors": load.get("errors", []),
               "warnings": sim.summary["warnings"] + posted.report["warnings"],
               "seconds": sim.summary["seconds"]}
    return FeedsResult(out, summary, sim.load, posted, p.tools)


@operation(ReportParams, "folders", "out")
def report(p) -> dict:
    """One self-contained HTML file ``out`` with 3D views and tables of the run ``folders``;
    returns what it holds (runs, views, bytes, notes)."""
    from .htmlreport import write_report
    from .runfiles import RunFiles

    folder = os.path.dirname(os.path.abspath(p.out))
    if not os.path.isdir(folder):
        raise InputError(f"{folder}: no such folder for out", "out")
    run = RunFiles([p.out])
    try:
        info = write_report(list(p.folders), run.tmp(p.out), progress=p.progress)
        run.commit()
    finally:
        if not run.done:
            run.abort()
    info["file"] = os.path.abspath(p.out)
    return info


@operation(ClearFixturesParams, "toolpath", "tools", "fixtures")
def clear_fixtures(p) -> FixturesResult:
    """``toolpath`` kept out of the ``fixtures`` (solids no cutter, shank or holder may enter): the
    moves that would enter one left out, each stretch left out linked over at ``safe_z`` (up the
    tool axis, across, down at feed), and the path checked against them again."""
    from .ops.fixtures import clear_fixtures as run
    from .ops.fixtures import union

    solid = union([f.solid(p.part) for f in p.fixtures])
    tp, trimmed, report = run(p.toolpath, p.tools, solid, p.safe_z, resolve_device(p.device), p.label)
    return FixturesResult(tp, trimmed, report)
