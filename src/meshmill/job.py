"""A job: one part machined from its stock to finished in one run (``meshmill job job.toml``,
:class:`Job` in Python), written as a user of the API writes it: a loop over public calls of
:mod:`meshmill.api` (an import-linter contract keeps it from reaching below).

The part is set up as every command sets it up (:func:`~meshmill.api.load_part`); the stock is a
:class:`~meshmill.simulation.stock.Stock` (a box with margins, a cylinder, a closed mesh, or the
part with an allowance), turned into the in-process stock (triple dexels) at the start; the
fixtures are solids no tool, shank or holder may enter. The operations run in order, each given
the in-process stock as ``stock=`` (its rapids, shanks and holders keep clear of it; raster and
waterline leave out the pieces of their passes that remove less than ``rest`` mm of it). Each
path is lifted to the job's plane at both ends (:meth:`~meshmill.toolpath.model.Toolpath.lifted_to`),
trimmed where it would enter a fixture (:func:`~meshmill.api.clear_fixtures`), verified against
the part (:func:`~meshmill.api.verify`), cut from the in-process stock and measured
(:func:`~meshmill.api.simulate`, whose stock after it the next operation gets: a rapid through
material or a shank or holder meeting it is an error), timed on the job's machine
(:func:`~meshmill.api.machining_time`), and written with the stock it leaves. An operation that
finds nothing to cut is skipped with a warning, or refused, as ``nothing_to_cut`` says. One
program holds every operation with its tool changes (:func:`~meshmill.api.post`).

The job's folder (:class:`JobFolder`) is checked before anything is computed, emptied of an
earlier job's results, and written whole under a temporary name that is put in place once
complete: nothing an earlier or interrupted run left can look like this run's result.

Units: mm, mm^3, seconds.
"""
from __future__ import annotations

import os
import shutil
import time
from dataclasses import dataclass, field

from . import api
from .api import InputError, NothingToCut
from .options import Params, option
from .tomlfile import read_toml

OPERATIONS = {"rough": api.rough, "plunge": api.plunge, "raster": api.raster, "waterline": api.waterline,
              "steep-shallow": api.steep_shallow, "rest-finish": api.steep_shallow, "finish": api.finish,
              "choose": api.choose}
REST_KINDS = ("raster", "waterline", "steep-shallow", "rest-finish")  # leave out what removes less than rest
TOOL_LISTS = ("finish", "choose", "rest-finish")  # take tools = [...] rather than tool
SET_BY_JOB = {"part", "tools", "stock", "fixtures", "device", "progress", "machine", "cluster", "simulate", "surface",
              "tool_pair", "flip", "material"}  # an operation's parameters the job gives it
JOB_TABLES = ("part", "stock", "fixtures", "operations")
REMOVES_NOTHING = 1e-6  # mm^3: an operation that removes less of the in-process stock cut nothing
REST_DEPTH = 0.05  # mm: the depth of stock below which a job's raster and waterline pieces are left out
LINK_CLEARANCE = 5.0  # mm: the job's safe plane above the stock and the fixtures


@dataclass(frozen=True, kw_only=True)
class JobParams(Params):
    """A job's settings: a job file's top level (``[part]`` takes :func:`~meshmill.api.load_part`'s
    options and ``file``, ``[stock]`` and ``[[fixtures]]`` :class:`~meshmill.params.StockParams`'
    and :class:`~meshmill.params.FixtureParams`', ``[[operations]]`` their API function's)."""

    name: str | None = option("text", "the job's name (default: the job file's name)", None)
    machine: object = option("object", "the machine the program is for: a shipped name or a machine file (default: "
                                       "table-table-ac when a finish runs, else generic-3axis)", None, role="machine")
    tools: object = option("object", "the tool table's file", role="tools")
    step: float = option("number", "the in-process stock's dexels", 0.5, unit="mm", above=0.0)
    rest: object = option("number", "raster and waterline leave out what removes less of the in-process stock "
                                    "(false: off)", REST_DEPTH, unit="mm", low=0.0, words=(False,))
    tolerance: float = option("number", "gouge tolerance of every path and of the final check",
                              api.finish.spec.options()["tolerance"].default, unit="mm", low=0.0)
    clearance: float = option("number", "above the stock and the fixtures: the plane the job links on",
                              LINK_CLEARANCE, unit="mm", low=0.0)
    in_process: bool = option("flag", "each operation starts from the in-process stock (false: from the part alone, "
                                      "only cut from the stock, for comparison)", True)
    nothing_to_cut: str = option("choice", "an operation that removes nothing of the stock: skip it with a warning, "
                                           "or refuse the job", "skip", choices=("skip", "refuse"))
    device: str = option("choice", "run the heavy kernels on the CPU or an NVIDIA GPU (auto: the GPU when a usable "
                                   "one is present)", "auto", choices=("cpu", "cuda", "auto"))
    material: str | None = option("text", api.simulate.spec.options()["material"].help, None)
    feeds: str = option("choice", "each move's feed: from the tool table's cutting data (table), or optimised on the load "
                                  "the in-process stock measures (optimised: meshmill feeds)", "table",
                        choices=("table", "optimised"))
    air_feed: str = option("choice", "feed moves that remove nothing of the in-process stock as it is cut (in runs of "
                                     "at least 2 mm): at the machine's largest feed (fast), or at the table's feed "
                                     "(table; optimised feeds always run them fast)", "fast", choices=("fast", "table"))


SETUP = tuple(n for n in api.load_part.spec.options() if n != "path")  # [part]'s keys besides file


def _table(value, what: str, example: str) -> dict:
    if not isinstance(value, dict):
        raise InputError(f"{what} must be a table ({example}), got {value!r}", what)
    return value


def _tables(value, what: str, example: str) -> list:
    if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
        raise InputError(f"{what} must be a list of tables ({example}), got {value!r}", what)
    return value


@dataclass
class Operation:
    """One operation of the job: ``kind`` (rough, plunge, raster, waterline, steep-shallow,
    rest-finish, finish, choose), its ``name`` and the keyword arguments of the API's function of
    that name (``tool``, ``step_down``, ..., checked against its options when made); ``rest`` mm
    (raster, waterline, steep-shallow, rest-finish): leave out what removes less of the in-process
    stock (None: cut the whole path); ``tools``: finish's and choose's cutters by name (None:
    every one), rest-finish's in the order they cut, smallest last (:meth:`expanded`)."""

    kind: str
    name: str
    params: dict = field(default_factory=dict)
    rest: float | None = REST_DEPTH
    tools: list | None = None

    @classmethod
    def from_dict(cls, d: dict, number: int, rest_default=REST_DEPTH) -> "Operation":
        """An operation of a job file's ``[[operations]]``: refused in one line where its type,
        a parameter's name, kind or range is wrong, before anything is computed."""
        _table(d, f"operation {number}", "type = ..., tool = ..., ...")
        d = {str(k).replace("-", "_"): v for k, v in d.items()}
        kind = d.pop("type", None)
        if kind not in OPERATIONS:
            raise InputError(f"operation {number}: type must be one of {', '.join(OPERATIONS)}, got {kind!r}", "type")
        name = d.pop("name", None)
        if name is not None and not (isinstance(name, str) and name.strip()):
            raise InputError(f"operation {number}: name must be text, got {name!r}", "name")
        name = name or f"{kind} {d.get('tool', '')}".strip()
        where = f"operation {number} ({name})"
        try:
            rest = JobParams.options()["rest"].check(d.pop("rest", rest_default))
            tools = d.pop("tools", None)
            if tools is not None and kind not in TOOL_LISTS:
                raise InputError("tools is finish's, choose's and rest-finish's (the cutters they use); give tool",
                                 "tools")
            if tools is not None and not (isinstance(tools, list) and tools and all(isinstance(t, str) for t in tools)):
                raise InputError(f"tools wants a list of tool names, got {tools!r}", "tools")
            if kind == "rest-finish":
                if tools is None:
                    raise InputError("rest-finish needs tools = [...]: the tools that cut what the earlier ones "
                                     "left, smallest last", "tools")
                if "tool" in d:
                    raise InputError("rest-finish takes tools = [...] (each cuts what the earlier ones left), not "
                                     "tool", "tool")
            spec = OPERATIONS[kind].spec
            unknown = sorted(set(d) - (set(spec.options()) - SET_BY_JOB - ({"tool"} if kind == "rest-finish" else
                                                                              set())))
            if unknown:
                raise InputError(f"unknown parameter{'s' * (len(unknown) > 1)} {', '.join(unknown)} for {kind} (it "
                                 f"takes {', '.join(n for n in spec.options() if n not in SET_BY_JOB)})",
                                 tuple(unknown))
            set_by_job = {k: PLACEHOLDER.get(k) for k, o in spec.options().items()
                          if k in SET_BY_JOB and (o.required or k in PLACEHOLDER)}
            spec.checked({**d, **set_by_job, **({"tool": tools[0]} if kind == "rest-finish" else {})})
        except InputError as exc:
            raise exc.within(where) from None
        return cls(kind, name, d, (None if rest is False else rest) if kind in REST_KINDS else None, tools)

    def expanded(self) -> list:
        """The operations this one runs as: itself, or for rest-finish one steep-shallow
        operation per tool in order, each cutting what the stock holds after the one before
        (rest machining from the in-process stock)."""
        if self.kind != "rest-finish":
            return [self]
        return [Operation("steep-shallow", f"{self.name} {t}", {**self.params, "tool": t}, self.rest, None)
                for t in self.tools]


PLACEHOLDER = {"tools": "the job's"}  # what stands for the job's own arguments when an operation is checked


@dataclass
class OperationResult:
    """An operation as the job ran it: ``path`` (:class:`~meshmill.results.PathResult`, its
    ``summary["job"]`` the job's figures) and ``cut`` (:class:`~meshmill.results.SimulateResult`:
    what it cut from the in-process stock, ``cut.stock`` the stock after it); ``skipped``: why it
    was left out (nothing to cut), with ``path`` and ``cut`` None."""

    operation: Operation
    path: object
    cut: object
    skipped: str = ""

    @property
    def stock(self):
        return self.cut.stock

    @property
    def ok(self) -> bool:
        return True if self.skipped else self.path.summary["job"]["ok"]


class JobFolder:
    """A job's output folder, checked before anything is computed: not a file, writable, and
    either new, empty, or an earlier job's, whose results (``job.json``, ``program.nc``,
    ``report.html`` and the ``NN-name/`` folders) are removed at once: no result of an earlier run
    stays to look like this one's. :meth:`write` writes the job there, each file under a temporary
    name put in place when complete and ``job.json`` last; a write that fails or is interrupted
    removes what it wrote."""

    RESULTS = ("job.json", "program.nc", "report.html")

    def __init__(self, path):
        self.path = os.path.abspath(os.fspath(path))
        parent = os.path.dirname(self.path)
        if os.path.exists(self.path) and not os.path.isdir(self.path):
            raise InputError(f"{path}: is a file, not a folder for the job", "out")
        try:
            os.makedirs(self.path, exist_ok=True)
        except OSError as exc:
            raise InputError(f"{path}: cannot create the job's folder ({exc.strerror})", "out") from None
        if not os.access(self.path, os.W_OK | os.X_OK) or not os.access(parent, os.X_OK):
            raise InputError(f"{path}: cannot write there (permission denied)", "out")
        entries = os.listdir(self.path)
        ours = self._results()
        if entries and not ours:
            raise InputError(f"{path}: the folder holds other files and no earlier job's: give a new or empty folder",
                             "out")
        self.clear()

    def _results(self) -> list:
        return [os.path.join(self.path, e) for e in sorted(os.listdir(self.path))
                if e in self.RESULTS or _is_operation_folder(os.path.join(self.path, e)) or e.startswith(".")
                and ".partial-" in e]

    def clear(self):
        """Remove every result of a job in the folder."""
        for target in self._results():
            try:
                shutil.rmtree(target) if os.path.isdir(target) else os.remove(target)
            except OSError as exc:
                raise InputError(f"{target}: cannot remove an earlier job's result ({exc.strerror})", "out") from None

    def write(self, fill) -> list:
        """``fill(folder)`` writes the job into the folder and returns the paths it wrote; nothing of
        it stays if it fails."""
        try:
            return fill(self.path)
        except BaseException:
            self.clear()
            raise

    def write_text(self, name, text) -> str:
        """The file ``name`` of the folder with ``text``, put in place when complete."""
        final = os.path.join(self.path, name)
        tmp = os.path.join(self.path, f".{name}.partial-{os.getpid()}")
        api.check_interrupted()
        try:
            with open(tmp, "w") as fh:
                fh.write(text)
            os.replace(tmp, final)
        except OSError as exc:
            raise InputError(f"{final}: cannot write ({exc.strerror})", "out") from None
        return final


def _is_operation_folder(path) -> bool:
    name = os.path.basename(path)
    return os.path.isdir(path) and len(name) > 3 and name[:2].isdigit() and name[2] == "-"


@dataclass
class JobResult:
    """The job's ``operations`` (:class:`OperationResult`), the program as ``posted``
    (:class:`~meshmill.results.PostResult`: its ``program`` lines and report), the ``summary``
    (job.json) and what is ``left`` on the part, where and why (:func:`~meshmill.api.what_is_left`'s
    arrays; its report is ``summary["left"]``)."""

    job: "Job"
    operations: list
    posted: object
    summary: dict
    left: dict | None = None  # what is left on the part (api.what_is_left's arrays)

    @property
    def ok(self) -> bool:
        return bool(self.summary["ok"])

    @property
    def program(self) -> list:
        """The G-code lines."""
        return self.posted.lines

    def save(self, folder, report=True, progress=None) -> list:
        """Write the job's folder (a path or a :class:`JobFolder`): per operation ``NN-name/`` (the
        operation's files and ``stock.npz``, the in-process stock after it, with ``stock/`` its
        view: machined.stl, deviation.npz, deviation.json, summary.json; the last one's also
        left.npz, what is left on the part and why), ``program.nc``, ``job.json`` (last) and, with
        ``report``, ``report.html``; whole or not at all. Returns the folders and files written."""
        target = folder if isinstance(folder, JobFolder) else JobFolder(folder)
        return target.write(lambda path: self._write(target, report, progress))

    def _write(self, folder: JobFolder, report, progress) -> list:
        import json

        written, views = [], []
        for op in self.operations:
            if op.skipped:
                continue
            sub = os.path.join(folder.path, op.path.summary["job"]["folder"])
            written += op.path.save(sub)
            op.stock.save(os.path.join(sub, "stock.npz"))
            op.cut.summary["toolpath"] = {"file": os.path.join(sub, "toolpath.cl"), "warnings": []}
            op.cut.save(os.path.join(sub, "stock"))
            views += [sub, os.path.join(sub, "stock")]
        if self.left is not None and views:
            import numpy as np

            at = os.path.join(views[-1], "left.npz")
            np.savez_compressed(at, **self.left, reasons=np.array(self.summary["left"]["reasons"]))
            written.append(at)
        written += self.posted.save(os.path.join(folder.path, "program.nc"))
        self.summary["program"] = written[-1]
        if report:
            self.summary["report"] = api.report(views, os.path.join(folder.path, "report.html"),
                                                progress=progress)["file"]
            written.append(self.summary["report"])
        written.append(folder.write_text("job.json", json.dumps(self.summary, indent=2, default=float) + "\n"))
        return written


@dataclass
class Job:
    """A part, its stock and fixtures, a tool table, a machine and operations in order. ``part``
    and ``tools`` may be given as files, ``stock`` as a Stock or a ``[stock]`` table, the
    fixtures and operations as Fixtures / Operations or tables; the other settings are
    :class:`~meshmill.params.JobParams`' (checked by :meth:`run`)."""

    part: object
    tools: object
    operations: list
    stock: object = None
    fixtures: list = field(default_factory=list)
    machine: object = None
    step: float = 0.5
    tolerance: float = JobParams.options()["tolerance"].default
    in_process: bool = True
    clearance: float = JobParams.options()["clearance"].default
    device: str = "auto"
    name: str = "job"
    nothing_to_cut: str = "skip"
    material: str | None = None
    feeds: str = "table"
    air_feed: str = "fast"

    @classmethod
    def from_toml(cls, path) -> "Job":
        """The job of a TOML file (paths in it are relative to its folder)::

            name = "vase"
            machine = "table-table-ac"   # a shipped name or a TOML file
            tools = "tools.toml"
            step = 0.5                   # the in-process stock's dexels, mm
            [part]
            file = "vase.stl"            # with units, up, origin, scale, flip as on the command line
            [stock]
            type = "box"                 # box, cylinder, mesh, offset
            margin = 2                   # and side, top, bottom; diameter; allowance; file
            [[fixtures]]
            name = "plate"
            box = [-40, -40, -10, 40, 40, -2]    # or file = "clamp.stl"
            [[operations]]
            type = "plunge"              # then the operation's parameters, as in the API
            tool = "F6"
            allowance = 1.0
        """
        path = os.fspath(path)
        d = read_toml(path, "a job file (TOML)", "job file")
        folder = os.path.dirname(os.path.abspath(path))
        known = set(JobParams.options()) | set(JOB_TABLES)
        unknown = sorted(set(d) - known)
        if unknown:
            raise InputError(f"{path}: unknown key{'s' * (len(unknown) > 1)} {', '.join(unknown)} (a job has "
                             f"{', '.join(sorted(known))})", tuple(unknown), where=path)
        try:
            settings = JobParams.checked({k: v for k, v in d.items() if k not in JOB_TABLES and k not in
                                          ("tools", "machine")} | {"tools": "file"}, "a job")
            if "part" not in d:
                raise InputError("no [part] (the part: [part] with file = ...)", "part")
            part_d = dict(_table(d["part"], "part", "[part] with file = ..."))
            if "file" not in part_d:
                raise InputError("[part] needs file", "file")
            part_file = part_d.pop("file")
            if not (isinstance(part_file, str) and part_file.strip()):
                raise InputError(f"[part] file must be a file name, got {part_file!r}", "file")
            unknown = sorted(set(part_d) - set(SETUP))
            if unknown:
                raise InputError(f"[part]: unknown key{'s' * (len(unknown) > 1)} {', '.join(unknown)} (it takes "
                                 f"file, {', '.join(SETUP)})", tuple(unknown))
            for k, v in part_d.items():
                api.load_part.spec.options()[k].check(v)
            if "tools" not in d:
                raise InputError("no tools (the tool table's file)", "tools")
            if not (isinstance(d["tools"], str) and d["tools"].strip()):
                raise InputError(f"tools must be the tool table's file name, got {d['tools']!r}", "tools")
            machine = d.get("machine")
            if machine is not None and not (isinstance(machine, str) and machine.strip()):
                raise InputError(f"machine must be a shipped name or a machine file, got {machine!r}", "machine")
            if isinstance(machine, str) and os.path.exists(os.path.join(folder, machine)):
                machine = os.path.join(folder, machine)
            ops = _tables(d.get("operations", []), "operations", "[[operations]]")
            if not ops:
                raise InputError("no [[operations]]", "operations")
            operations = [Operation.from_dict(o, k + 1, settings.rest) for k, o in enumerate(ops)]
            stock = api.Stock.from_dict(_table(d.get("stock", {}), "stock", "[stock] with type = ..."), folder)
            fixtures = [api.Fixture.from_dict(f, folder, k + 1)
                        for k, f in enumerate(_tables(d.get("fixtures", []), "fixtures", "[[fixtures]]"))]
            part = api.load_part(os.path.join(folder, part_file), **part_d)
            tools = api.load_tools(os.path.join(folder, d["tools"]))
        except InputError as exc:
            raise exc.within(path) from None
        return cls(part=part, tools=tools, operations=operations, stock=stock, fixtures=fixtures, machine=machine,
                   step=settings.step, tolerance=settings.tolerance, in_process=settings.in_process,
                   clearance=settings.clearance, device=settings.device, nothing_to_cut=settings.nothing_to_cut,
                   material=settings.material, feeds=settings.feeds, air_feed=settings.air_feed,
                   name=settings.name or os.path.splitext(os.path.basename(path))[0])

    # ------------------------------------------------------------ checks

    def _check(self):
        """Every setting checked, files read, tables made into their values; the stock holds the
        part, no fixture overlaps it. Raises :class:`InputError` before anything is computed."""
        JobParams.checked(dict(name=self.name, tools="given", step=self.step, tolerance=self.tolerance,
                               in_process=self.in_process, clearance=self.clearance, device=self.device,
                               nothing_to_cut=self.nothing_to_cut, material=self.material, feeds=self.feeds,
                               air_feed=self.air_feed), "a job")
        if isinstance(self.part, (str, os.PathLike)):
            self.part = api.load_part(self.part)
        if not (hasattr(self.part, "vertices") and hasattr(self.part, "faces")):
            raise InputError(f"part must be a Mesh (meshmill.load_part) or a mesh file, got {self.part!r}", "part")
        if isinstance(self.tools, (str, os.PathLike)):
            self.tools = api.load_tools(self.tools)
        if not isinstance(self.tools, list) or not self.tools:
            raise InputError(f"tools must be a tool table (its file, or meshmill.load_tools), got {self.tools!r}",
                             "tools")
        if not isinstance(self.operations, list) or not self.operations:
            raise InputError("a job needs at least one operation (a list of Operations or tables)", "operations")
        self.operations = [e for k, o in enumerate(self.operations)
                           for e in (o if isinstance(o, Operation) else Operation.from_dict(o, k + 1)).expanded()]
        if self.stock is None:
            self.stock = api.Stock.box()
        elif isinstance(self.stock, dict):
            self.stock = api.Stock.from_dict(self.stock)
        elif not isinstance(self.stock, api.Stock):
            raise InputError(f"stock must be a Stock (meshmill.Stock.box(...)) or a [stock] table, got {self.stock!r}",
                             "stock")
        if not isinstance(self.fixtures, (list, tuple)):
            raise InputError(f"fixtures must be a list of Fixtures or tables, got {self.fixtures!r}", "fixtures")
        self.fixtures = [f if isinstance(f, api.Fixture) else api.Fixture.from_dict(f, "", k + 1)
                         for k, f in enumerate(self.fixtures)]
        five = any(o.kind == "finish" for o in self.operations)
        if self.machine is None:
            self.machine = "table-table-ac" if five else "generic-3axis"
        if not hasattr(self.machine, "chain"):
            if not (isinstance(self.machine, (str, os.PathLike)) and os.fspath(self.machine).strip()):
                raise InputError(f"machine must be a shipped name, a machine file or a Machine, got {self.machine!r}",
                                 "machine")
            self.machine = api.load_machine(self.machine)
        self.tools = api.in_material(self.tools, self.material, self.machine)  # the speeds the program runs at
        if five and self.machine.chain.type == "3-axis":
            raise InputError(f"the finish operation is 5-axis: the machine {self.machine.name} is 3-axis", "machine")
        names = {t.name for t in self.tools}
        for k, o in enumerate(self.operations):
            for t in (o.tools or []) + ([o.params["tool"]] if "tool" in o.params else []):
                if t not in names:
                    raise InputError(f"operation {k + 1} ({o.name}): no tool '{t}' in the tool table "
                                     f"({', '.join(sorted(names))})", "tool")
        self.stock.holds(self.part)
        for name in api.Fixture.overlapping(self.part, self.fixtures):
            raise InputError(f"fixture '{name}' overlaps the part (deeper than {api.Fixture.TOUCH:g} mm): move it "
                             "or check the part's set-up (origin, up)", "fixtures")

    # ------------------------------------------------------------ running

    def run(self, progress=None, cluster=None) -> JobResult:
        """Run the operations in order from the stock; returns the :class:`JobResult`.
        ``cluster`` (local workers, a Dask scheduler's address or a Client): the operations and
        the cutting of the in-process stock split there, as each operation splits (the same job)."""
        try:
            self._check()
        except InputError as exc:
            raise exc.within(f"job '{self.name}'") from None
        with api.connect(cluster) as client:
            return self._run(progress or (lambda stage: None), client)

    def _run(self, say, client) -> JobResult:
        t_job = time.perf_counter()
        device = api.resolve_device(self.device)
        say("the in-process stock: dexels of the design and the stock")
        stock = self.stock.dexels(self.part, self.step, device=device, cluster=client)
        top = max([float(stock.state.bounds[1, 2])] + [float(f.solid(self.part).bounds[1, 2]) for f in self.fixtures])
        safe_z = top + self.clearance
        results = []
        for k, op in enumerate(self.operations):
            result = self._operation(k, op, stock, safe_z, device, say, client)
            results.append(result)
            if not result.skipped:
                stock = result.stock
        ran = [r for r in results if not r.skipped]
        if not ran:
            raise NothingToCut("nothing to cut: every operation was skipped (" +
                               "; ".join(f"{r.operation.name}: {r.skipped}" for r in results) + ")")
        return self._program(results, ran, safe_z, device, t_job, say)

    def _operation(self, k, op, stock, safe_z, device, say, client) -> OperationResult:
        """Operation ``k`` from the in-process ``stock``: its path, lifted to ``safe_z``, kept out of
        the fixtures, verified, cut from the stock and timed; or skipped (or refused) when it finds
        nothing to cut."""
        t_op = time.perf_counter()
        label = f"operation {k + 1} ({op.name})"
        say(f"{label}: {op.kind}")

        def stage(text):
            say(f"{label}: {text}")

        try:
            res = self._path(op, label, stock if self.in_process else None, device, stage, client)
        except NothingToCut as exc:
            return self._nothing(op, label, exc)
        tp, fixtures = res.toolpath.lifted_to(safe_z), None
        stage("verify against the part and the fixtures")
        if self.fixtures:
            fixtures = api.clear_fixtures(tp, self.tools, self.fixtures, safe_z=safe_z, part=self.part, device=device,
                                          label=label)
            tp = fixtures.toolpath
        check = api.verify(self.part, tp, self.tools, tolerance=self.tolerance, device=device).report
        op_s = time.perf_counter() - t_op
        stage("cut from the in-process stock")
        t_cut = time.perf_counter()
        cut = api.simulate(self.part, tp, self.tools, step=self.step, stock=stock, tolerance=self.tolerance,
                           device=device, cluster=client, material=self.material, machine=self.machine)
        cut.stock = cut.stock.named(f"stock after {op.name}")
        cut_s = time.perf_counter() - t_cut
        removed = stock.volume - cut.stock.volume
        if removed < REMOVES_NOTHING:
            return self._nothing(op, label, NothingToCut(f"nothing to cut: its path removes nothing of the stock "
                                                         f"({removed:.3g} mm^3)"))
        timed = api.machining_time(tp, self.machine, self.tools).summary
        feeds = None
        if self.feeds == "optimised" and cut.load is not None:
            table_s = timed["total"]["total_s"]
            tp.feed = api.optimised_feeds(tp, cut.load, self.tools, self.material, self.machine)
            timed = api.machining_time(tp, self.machine, self.tools).summary
            feeds = {"table_s": table_s, "optimised_s": timed["total"]["total_s"]}
        elif self.air_feed == "fast" and cut.load is not None:
            table_s = timed["total"]["total_s"]
            tp.feed = api.air_feeds(tp, cut.load.in_material, self.machine)
            timed = api.machining_time(tp, self.machine, self.tools).summary
            feeds = {"table_s": table_s, "air_fast_s": timed["total"]["total_s"]}
        s = cut.summary
        errors = list(s["errors"])
        if not check["ok"]:
            errors.append(f"the path gouges the part or collides with it ({check['gouging_moves']} gouging, "
                          f"{check['colliding_moves']} colliding moves, max gouge {check['max_gouge']:.4f} mm)")
        if fixtures is not None and not fixtures.ok:
            errors.append(f"the path enters a fixture ({fixtures.report['gouging_moves']} cutter, "
                          f"{fixtures.report['colliding_moves']} shank or holder moves)")
        res.toolpath = tp
        res.summary["verify"] = check
        res.summary["job"] = {
            "number": k + 1, "name": op.name, "folder": f"{k + 1:02d}-{_slug(op.name)}",
            "ok": not errors, "errors": errors,
            "in_process_stock": self.in_process, "rest": op.rest,
            "removed_mm3": removed,
            "left_over_design_mm3": s["volumes_mm3"]["remaining"],
            "cutting_mm": s["cutting_mm"],
            "rapid_moves_cutting": s["rapid_moves_cutting"], "colliding_moves": s["colliding_moves"],
            "fixtures": None if fixtures is None else {"trimmed_moves": fixtures.trimmed, "ok": fixtures.ok,
                                                       "max_depth": fixtures.report["max_gouge"],
                                                       "max_collision": fixtures.report["max_collision"]},
            "machining_s": timed["total"]["total_s"], "time": timed, "feeds": feeds,
            "non_cutting": non_cutting(timed["total"], air_time_share(tp, cut.load, self.machine, s["cutting_mm"])),
            "load": s.get("load"),
            "seconds": {"operation": round(op_s, 3), "cut_and_measure": round(cut_s, 3)},
        }
        return OperationResult(op, res, cut)

    def _nothing(self, op, label, exc: NothingToCut) -> OperationResult:
        """An operation that finds nothing to cut (``exc`` says why): skipped, or the job refused."""
        if self.nothing_to_cut == "refuse":
            raise NothingToCut(f"{label}: {exc} (the job's nothing_to_cut = \"skip\" would go on without it)",
                               exc.params, label)
        return OperationResult(op, None, None, skipped=str(exc))

    def _path(self, op: Operation, label, stock, device, stage, client):
        """The operation's :class:`~meshmill.results.PathResult` from the part (and the in-process
        ``stock``, or None), its tools numbered as the job's table."""
        run = OPERATIONS[op.kind]
        params = dict(op.params)
        tools = self.tools
        if op.kind in ("finish", "choose"):
            params["machine"] = self.machine
            if op.tools:
                tools = [t for t in self.tools if t.name in op.tools]
        if op.kind in REST_KINDS and stock is not None and op.rest is not None:
            params["rest"] = op.rest
        if client is not None and op.kind in ("raster", "waterline", "steep-shallow", "finish", "rough"):
            params["cluster"] = client
        if stock is not None and op.kind != "choose":  # choose links its zones over the part alone
            params["stock"] = stock
        if op.kind == "rough" and self.fixtures:  # its walks and links go round them
            params["fixtures"] = self.fixtures
        if "material" in run.spec.options():
            params["material"] = self.material
        try:
            if op.kind == "choose":
                res = run(self.part, tools=tools, device=device, progress=stage, **params)
            else:
                res = run(self.part, tools, device=device, progress=stage, **params)
        except NothingToCut:
            raise
        except InputError as exc:
            raise exc.within(label) from None
        if res.tools is not self.tools:  # the path's tools numbered as the job's table
            import numpy as np

            names = [t.name for t in self.tools]
            index = np.array([names.index(t.name) for t in res.tools])
            res.toolpath.tool = index[res.toolpath.tool]
            res.tools = self.tools
        return res

    def _program(self, results, ran, safe_z, device, t_job, say) -> JobResult:
        """The program of the operations that ran, its time, and job.json's summary."""
        say("the program")
        whole = api.Toolpath.concatenate([r.path.toolpath for r in ran])
        posted = api.post(whole, self.machine, self.tools, clearance=safe_z if self.machine.chain.type != "3-axis"
                          else None)
        timed = api.machining_time(whole, self.machine, self.tools).summary
        final = ran[-1].cut.summary
        start = ran[0].cut.stock.state.start
        summary = {
            "operation": "job", "name": self.name, "ok": all(r.ok for r in results),
            "part": api.part_entry(self.part), "tools_file": api.tools_file(self.tools),
            "machine": self.machine.summary(), "stock": {**self.stock.summary(), "volume_mm3": start.volume},
            "fixtures": [{"name": f.name, "box": f.solid(self.part).bounds.round(6).tolist()} for f in self.fixtures],
            "step": self.step, "tolerance": self.tolerance, "in_process": self.in_process, "safe_z": safe_z,
            "material": self.material, "feeds": self.feeds,
            "device": device,
            "operations": [_entry(r) for r in results],
            "final": {"design_volume_mm3": final["volumes_mm3"]["design"],
                      "left_over_design_mm3": final["volumes_mm3"]["remaining"],
                      "gouged_mm3": final["volumes_mm3"]["gouged"], **final["deviation"]},
            "program": "", "post": {kk: v for kk, v in posted.report.items() if kk not in ("program",)},
            "machining_s": timed["total"]["total_s"], "time": timed,
            "non_cutting": _program_non_cutting(timed["total"], ran),
            "seconds": {"total": round(time.perf_counter() - t_job, 3)},
        }
        skipped = [f"operation {k + 1} ({r.operation.name}) skipped: {r.skipped}" for k, r in enumerate(results)
                   if r.skipped]
        if skipped:  # (job.json has warnings where there are some)
            summary["warnings"] = skipped
        left = None
        samples = ran[-1].cut.samples
        if samples is not None and samples.get("points") is not None:
            say("what is left on the part, and why")
            import numpy as np

            used = {self.tools[int(i)].name for r in ran for i in np.unique(r.path.toolpath.tool)}
            left, summary["left"] = api.what_is_left(
                self.part, samples["points"], samples["e"], self.step, self.tools, used,
                five_axis=any(r.operation.kind == "finish" for r in ran), tolerance=self.tolerance, device=device,
                stock=ran[-1].cut.stock)
        summary["seconds"]["total"] = round(time.perf_counter() - t_job, 3)
        return JobResult(self, results, posted, summary, left)


def air_time_share(tp, load, machine, cutting_mm: dict) -> float:
    """The share of ``tp``'s feed time in air, as the in-process stock measured it (``load``, a
    :class:`~meshmill.simulation.load.MoveLoad`; None: the share of the feed length in air,
    ``cutting_mm``, a simulation's)."""
    if load is not None:
        return api.air_time_share(tp, load.in_material, machine)
    length = cutting_mm["in_material"] + cutting_mm["in_air"]
    return cutting_mm["in_air"] / length if length > 0 else 0.0


def non_cutting(total: dict, air_share: float) -> dict:
    """The machining time that cuts nothing, s: rapids, tool changes, and the feed moves through
    the air (``air_share`` of the feed time, :func:`air_time_share`); ``share`` of the ``total``
    time (a machining time's ``total``)."""
    air = total["cutting_s"] * air_share
    out = {"rapid_s": total["rapid_s"], "tool_change_s": total["tool_change_s"], "air_feed_s": air}
    out["share"] = sum(out.values()) / total["total_s"] if total["total_s"] > 0 else 0.0
    return out


def _program_non_cutting(total: dict, ran: list) -> dict:
    """:func:`non_cutting` of the whole program: its rapids and tool changes, the operations' feed
    through the air."""
    air = sum(r.path.summary["job"]["non_cutting"]["air_feed_s"] for r in ran)
    out = {"rapid_s": total["rapid_s"], "tool_change_s": total["tool_change_s"], "air_feed_s": air}
    out["share"] = sum(out.values()) / total["total_s"] if total["total_s"] > 0 else 0.0
    out["tool_change_share"] = total["tool_change_s"] / total["total_s"] if total["total_s"] > 0 else 0.0
    return out


def _entry(r: OperationResult) -> dict:
    """An operation's line in job.json."""
    if r.skipped:
        return {"name": r.operation.name, "type": r.operation.kind, "ok": True, "skipped": r.skipped}
    j = r.path.summary["job"]
    return {"name": r.operation.name, "type": r.operation.kind, "folder": j["folder"],
            **{k: j[k] for k in ("ok", "removed_mm3", "left_over_design_mm3", "cutting_mm", "machining_s", "errors",
                                 "feeds", "non_cutting")},
            "load_ok": (j["load"] or {}).get("ok", True),
            "verify_ok": r.path.summary["verify"]["ok"]}


def _slug(name: str) -> str:
    keep = "".join(c if c.isalnum() else "-" for c in name.lower())
    return "-".join(p for p in keep.split("-") if p) or "operation"
