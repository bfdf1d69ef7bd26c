"""A job: one part machined from its stock to finished in one run (``meshmill job job.toml``,
:class:`Job` in Python).

The part is set up as every command sets it up; the stock is a box with margins, a cylinder, a
closed mesh, or the part with an allowance; the fixtures are solids no tool, shank or holder may
enter. The operations run in order, each from the in-process stock: a triple-dexel model of the
stock, cut by each operation's path exactly as ``simulate`` cuts it and handed to the next one,
which receives it as a closed mesh around every dexel (:func:`~meshmill.simulation.surface.stock_hull`:
rapids, shanks and holders keep clear of it; raster and waterline leave out the
pieces of their passes that remove less than ``rest`` mm of it). Each path is trimmed where it
would enter a fixture (the stretch is left uncut and linked over: up along the tool axis to the
job's safe plane, across, and down at feed), verified against the part and the fixtures, cut from
the in-process stock (rapids through material and shanks or holders meeting it are errors), timed
on the job's machine, and written with the stock it leaves. One program holds every operation
with its tool changes; the last stock is measured against the design.

Units: mm, mm^3, seconds.
"""
from __future__ import annotations

import inspect
import math
import os
import time
from dataclasses import dataclass, field

import numpy as np

from . import api
from .errors import InputError
from .runfolder import write_json
from .tolerances import GOUGE_TOL, HOLDER_CLEARANCE
from .tomlfile import read_toml

OPERATIONS = {"plunge": api.plunge, "raster": api.raster, "waterline": api.waterline, "finish": api.finish,
              "choose": api.choose}
STOCK_KINDS = ("box", "cylinder", "mesh", "offset")
REST_DEPTH = 0.05  # mm: the depth of stock below which raster and waterline pieces are left out
LINK_CLEARANCE = 5.0  # mm: the job's safe plane above the stock and the fixtures
CYLINDER_SEGMENTS = 128
_JOB_KEYS = {"name", "machine", "tools", "step", "tolerance", "rest", "in_process", "device", "clearance", "part",
             "stock", "fixtures", "operations"}
_SET_BY_JOB = {"part", "tools", "stock", "rest", "rest_stock", "device", "progress", "machine", "simulate", "surface",
               "tool_pair", "flip", "cluster"}


def _number(value, what, low=None, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{what} must be a number of mm, got {value!r}")
    if positive and value <= 0 or low is not None and value < low:
        raise InputError(f"{what} must be {'a positive number of mm' if positive else f'at least {low:g} mm'}, "
                         f"got {value:g}")
    return float(value)


@dataclass
class Stock:
    """What the job starts from: ``kind`` box (the part's box grown by the margins), cylinder
    (about Z through the box's centre, its ``diameter`` or the part's widest radius plus the side
    margin), mesh (a closed ``file``, in the part file's frame or ``frame = "work"``), offset
    (the part with ``allowance`` mm on every dexel end). ``side``, ``top``, ``bottom``: margins, mm."""

    kind: str = "box"
    side: float = 0.0
    top: float = 0.0
    bottom: float = 0.0
    diameter: float | None = None
    allowance: float = 1.0
    file: str = ""
    frame: str = "part"

    @classmethod
    def from_dict(cls, d: dict, folder: str = "") -> "Stock":
        d = dict(d)
        kind = d.pop("type", d.pop("kind", "box"))
        if kind not in STOCK_KINDS:
            raise InputError(f"[stock] type must be one of {', '.join(STOCK_KINDS)}, got {kind!r}")
        margin = _number(d.pop("margin", 0.0), "[stock] margin", low=0.0)
        s = cls(kind=kind, side=margin, top=margin, bottom=margin)
        for key in ("side", "top", "bottom"):
            if key in d:
                setattr(s, key, _number(d.pop(key), f"[stock] {key}", low=0.0))
        if "diameter" in d:
            s.diameter = _number(d.pop("diameter"), "[stock] diameter", positive=True)
        if "allowance" in d:
            s.allowance = _number(d.pop("allowance"), "[stock] allowance", low=0.0)
        if "file" in d:
            s.file = os.path.join(folder, str(d.pop("file")))
        s.frame = str(d.pop("frame", "part"))
        if d:
            raise InputError(f"[stock]: unknown key(s) {', '.join(sorted(d))}")
        if s.frame not in ("part", "work"):
            raise InputError(f"[stock] frame must be 'part' or 'work', got {s.frame!r}")
        if kind == "mesh" and not s.file:
            raise InputError("[stock] type 'mesh' needs file")
        return s

    def solid(self, part):
        """The closed stock :class:`~meshmill.geometry.mesh.Mesh` in the work frame (None for an
        offset stock, which is the part's dexels lengthened)."""
        from .geometry import shapes

        lo, hi = part.bounds
        if self.kind == "box":
            return shapes.box(lo - [self.side, self.side, self.bottom], hi + [self.side, self.side, self.top])
        if self.kind == "cylinder":
            centre = 0.5 * (lo + hi)
            widest = float(np.hypot(*(part.vertices[:, :2] - centre[:2]).T).max())
            radius = 0.5 * self.diameter if self.diameter else widest + self.side
            if radius < widest - 1e-9:
                raise InputError(f"[stock] diameter {2 * radius:g} mm is narrower than the part ({2 * widest:.3f} mm)")
            ring = radius / math.cos(math.pi / CYLINDER_SEGMENTS)  # the polygon holds the round bar
            z0, z1 = lo[2] - self.bottom, hi[2] + self.top
            m = shapes.revolve([0.0, ring, ring, 0.0], [z0, z0, z1, z1], CYLINDER_SEGMENTS, "cylinder stock")
            m.vertices[:, :2] += centre[:2]
            return m
        if self.kind == "mesh":
            return _placed(self.file, part, self.frame, "stock")
        return None

    def summary(self) -> dict:
        d = {"type": self.kind}
        if self.kind in ("box", "cylinder"):
            d.update(side=self.side, top=self.top, bottom=self.bottom)
        if self.kind == "cylinder" and self.diameter:
            d["diameter"] = self.diameter
        if self.kind == "offset":
            d["allowance"] = self.allowance
        if self.kind == "mesh":
            d.update(file=os.path.abspath(self.file), frame=self.frame)
        return d


def _placed(path, part, frame, what):
    """The closed mesh of ``path`` in the work frame: placed as the part was (``frame`` "part")
    or as it is ("work")."""
    from .geometry.mesh import load_mesh, mesh_from_arrays

    mesh = load_mesh(path)
    if frame == "part" and part.placement is not None:
        mesh = mesh_from_arrays(part.placement.apply(mesh.vertices), mesh.faces, os.path.basename(path))
        mesh.source = os.path.abspath(path)
    if not mesh.closed:
        raise InputError(f"{path}: the {what} mesh is open (not watertight)")
    return mesh


@dataclass
class Fixture:
    """A solid no tool, shank or holder may enter: a closed ``mesh`` in the work frame."""

    name: str
    mesh: object

    @classmethod
    def from_dict(cls, d: dict, part, folder: str = "", number: int = 1) -> "Fixture":
        from .geometry import shapes

        d = dict(d)
        name = str(d.pop("name", f"fixture {number}"))
        frame = str(d.pop("frame", "part"))
        if ("file" in d) == ("box" in d):
            raise InputError(f"fixture '{name}': give exactly one of file and box")
        if "box" in d:
            b = d.pop("box")
            if not (isinstance(b, list) and len(b) == 6):
                raise InputError(f"fixture '{name}': box wants six numbers [x0, y0, z0, x1, y1, z1] (work frame, mm)")
            lo = np.array([_number(v, f"fixture '{name}' box") for v in b[:3]])
            hi = np.array([_number(v, f"fixture '{name}' box") for v in b[3:]])
            if (hi <= lo).any():
                raise InputError(f"fixture '{name}': box's second corner must lie above the first on every axis")
            mesh = shapes.box(lo, hi)
        else:
            if frame not in ("part", "work"):
                raise InputError(f"fixture '{name}': frame must be 'part' or 'work', got {frame!r}")
            mesh = _placed(os.path.join(folder, str(d.pop("file"))), part, frame, f"fixture '{name}'")
        if d:
            raise InputError(f"fixture '{name}': unknown key(s) {', '.join(sorted(d))}")
        return cls(name, mesh)


@dataclass
class Operation:
    """One operation of the job: ``kind`` (plunge, raster, waterline, finish), its ``name`` and
    the keyword arguments of the API's function of that name (``tool``, ``step_down``, ...);
    ``rest`` mm (raster, waterline): leave out what removes less of the in-process stock (None:
    cut the whole path); ``tools``: finish's ball cutters by name (None: every one)."""

    kind: str
    name: str
    params: dict = field(default_factory=dict)
    rest: float | None = REST_DEPTH
    tools: list | None = None

    @classmethod
    def from_dict(cls, d: dict, number: int, rest_default) -> "Operation":
        d = {k.replace("-", "_"): v for k, v in d.items()}
        kind = d.pop("type", None)
        if kind not in OPERATIONS:
            raise InputError(f"operation {number}: type must be one of {', '.join(OPERATIONS)}, got {kind!r}")
        name = str(d.pop("name", f"{kind} {d.get('tool', '')}".strip()))
        rest = d.pop("rest", rest_default)
        if rest is False:
            rest = None
        elif rest is not None:
            rest = _number(rest, f"operation {number} ({name}): rest", low=0.0)
        tools = d.pop("tools", None)
        if tools is not None and kind not in ("finish", "choose"):
            raise InputError(f"operation {number} ({name}): tools is finish's and choose's (the cutters they "
                             "choose from); give tool")
        if tools is not None and not (isinstance(tools, list) and tools and all(isinstance(t, str) for t in tools)):
            raise InputError(f"operation {number} ({name}): tools wants a list of tool names")
        allowed = set(inspect.signature(OPERATIONS[kind]).parameters) - _SET_BY_JOB
        unknown = sorted(set(d) - allowed)
        if unknown:
            raise InputError(f"operation {number} ({name}): unknown parameter(s) {', '.join(unknown)} for {kind} "
                             f"(it takes {', '.join(sorted(allowed))})")
        return cls(kind, name, d, rest if kind in ("raster", "waterline") else None, tools)


@dataclass
class OperationResult:
    """An operation as the job ran it: ``path`` (:class:`~meshmill.api.PathResult`, its
    ``summary["job"]`` the job's figures), the ``stock`` after it (DexelModel), the stock's
    ``machined`` surface ``(vertices, faces)``, its deviation ``samples`` and ``stock_summary``."""

    operation: Operation
    path: object
    stock: object
    machined: tuple
    samples: dict
    stock_summary: dict

    @property
    def ok(self) -> bool:
        return self.path.summary["job"]["ok"]


@dataclass
class JobResult:
    """The job's ``operations`` (:class:`OperationResult`), the G-code ``program`` (lines) and its
    post ``post_report``, and the ``summary`` (job.json)."""

    job: "Job"
    operations: list
    program: list
    post_report: dict
    summary: dict

    @property
    def ok(self) -> bool:
        return bool(self.summary["ok"])

    def save(self, folder, report=True, progress=None) -> list:
        """Write the job's folder: per operation ``NN-name/`` (the operation's files and
        ``stock.npz``, the in-process stock after it, with ``stock/`` its view: machined.stl,
        deviation.npz, deviation.json, summary.json), ``program.nc``, ``job.json`` and, with
        ``report``, ``report.html``. Returns the folders and files written."""
        from .simulation.dexel import save_npz

        os.makedirs(folder, exist_ok=True)
        written, views = [], []
        for k, op in enumerate(self.operations):
            sub = os.path.join(folder, op.path.summary["job"]["folder"])
            written += op.path.save(sub)
            save_npz(os.path.join(sub, "stock.npz"), op.stock)
            res = api.SimulateResult(op.stock_summary["deviation"], op.stock_summary, op.machined, op.samples)
            op.stock_summary["toolpath"] = {"file": os.path.abspath(os.path.join(sub, "toolpath.cl")), "warnings": []}
            res.save(os.path.join(sub, "stock"))
            views += [sub, os.path.join(sub, "stock")]
        program = os.path.join(folder, "program.nc")
        with open(program, "w") as fh:
            fh.write("\n".join(self.program) + "\n")
        self.summary["program"] = os.path.abspath(program)
        written.append(program)
        if report:
            info = api.report(views, os.path.join(folder, "report.html"), progress=progress)
            self.summary["report"] = info["file"]
            written.append(info["file"])
        write_json(os.path.join(folder, "job.json"), self.summary)
        written.append(os.path.join(folder, "job.json"))
        return written


@dataclass
class Job:
    """A part, its stock and fixtures, a tool table, a machine and operations in order.

    ``step``: the in-process stock's dexel spacing (mm); ``tolerance``: the gouge tolerance of
    the paths and of the final check (mm); ``in_process``: the operations are given the
    in-process stock (False: each is computed from the part alone, as run on its own, and only
    simulated on the stock, for comparison); ``clearance``: mm above the stock and fixtures for
    the links between operations."""

    part: object
    tools: list
    operations: list
    stock: Stock = field(default_factory=Stock)
    fixtures: list = field(default_factory=list)
    machine: object = None
    step: float = 0.5
    tolerance: float = GOUGE_TOL
    in_process: bool = True
    clearance: float = LINK_CLEARANCE
    device: str = "auto"
    name: str = "job"

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
        unknown = sorted(set(d) - _JOB_KEYS)
        if unknown:
            raise InputError(f"{path}: unknown key(s) {', '.join(unknown)} (a job has {', '.join(sorted(_JOB_KEYS))})")
        part_d = dict(d.get("part") or {})
        if "file" not in part_d:
            raise InputError(f"{path}: [part] needs file")
        part_file = os.path.join(folder, str(part_d.pop("file")))
        setup = {k: part_d.pop(k) for k in ("units", "up", "origin", "scale", "flip") if k in part_d}
        if part_d:
            raise InputError(f"[part]: unknown key(s) {', '.join(sorted(part_d))}")
        part = api.load_part(part_file, **setup)
        if "tools" not in d:
            raise InputError(f"{path}: no tools (the tool table's file)")
        tools = api.load_tools(os.path.join(folder, str(d["tools"])))
        machine = d.get("machine")
        if isinstance(machine, str) and os.path.exists(os.path.join(folder, machine)):
            machine = os.path.join(folder, machine)
        rest = d.get("rest", REST_DEPTH)
        ops = d.get("operations") or []
        if not ops:
            raise InputError(f"{path}: no [[operations]]")
        return cls(part=part, tools=tools,
                   operations=[Operation.from_dict(o, k + 1, rest) for k, o in enumerate(ops)],
                   stock=Stock.from_dict(d.get("stock") or {}, folder),
                   fixtures=[Fixture.from_dict(f, part, folder, k + 1) for k, f in enumerate(d.get("fixtures") or [])],
                   machine=machine, step=d.get("step", 0.5), tolerance=d.get("tolerance", GOUGE_TOL),
                   in_process=bool(d.get("in_process", True)), clearance=d.get("clearance", LINK_CLEARANCE),
                   device=d.get("device", "auto"), name=str(d.get("name", os.path.splitext(os.path.basename(path))[0])))

    # ------------------------------------------------------------ checks

    def _check(self):
        _number(self.step, "step", positive=True)
        _number(self.tolerance, "tolerance", low=0.0)
        _number(self.clearance, "clearance", low=0.0)
        if not self.operations:
            raise InputError("a job needs at least one operation")
        if not isinstance(self.stock, Stock):
            self.stock = Stock.from_dict(self.stock)
        self.operations = [o if isinstance(o, Operation) else Operation.from_dict(o, k + 1, REST_DEPTH)
                           for k, o in enumerate(self.operations)]
        self.fixtures = [f if isinstance(f, Fixture) else Fixture.from_dict(f, self.part, "", k + 1)
                         for k, f in enumerate(self.fixtures)]
        five = any(o.kind == "finish" for o in self.operations)
        if self.machine is None:
            self.machine = "table-table-ac" if five else "generic-3axis"
        if isinstance(self.machine, (str, os.PathLike)):
            self.machine = api.load_machine(self.machine)
        if five and self.machine.chain.type == "3-axis":
            raise InputError(f"the finish operation is 5-axis: the machine {self.machine.name} is 3-axis")
        names = {t.name for t in self.tools}
        for k, o in enumerate(self.operations):
            for t in (o.tools or []) + ([o.params["tool"]] if "tool" in o.params else []):
                if t not in names:
                    raise InputError(f"operation {k + 1} ({o.name}): no tool '{t}' in the tool table "
                                     f"({', '.join(sorted(names))})")

    # ------------------------------------------------------------ running

    def run(self, progress=None, cluster=None) -> JobResult:
        """Run the operations in order from the stock; returns the :class:`JobResult`.
        ``cluster`` (local workers, a Dask scheduler's address or a Client): the operations and
        the cutting of the in-process stock split there, as each operation splits (the same job)."""
        from .cluster import connect

        with connect(cluster) as client:
            return self._run(progress, client)

    def _run(self, progress, client) -> JobResult:
        from .geometry.mesh import closed_mesh
        from .kernels.backend import solid_kernels
        from .ops.simulate import cut_path, measure, simulate_summary
        from .pathing.verify import verify_toolpath
        from .simulation import cut as cutting
        from .simulation.dexel import dexelize
        from .simulation.surface import machined_mesh, stock_hull
        from .toolpath.model import Toolpath

        say = progress or (lambda stage: None)
        t_job = time.perf_counter()
        self._check()
        device = api._device(self.device)
        part = self.part
        stock_mesh = self.stock.solid(part)
        fix_mesh = _union([f.mesh for f in self.fixtures]) if self.fixtures else None
        if stock_mesh is not None:
            bounds = np.array([np.minimum(stock_mesh.bounds[0], part.bounds[0]),
                               np.maximum(stock_mesh.bounds[1], part.bounds[1])])
        else:
            pad = self.stock.allowance + self.step
            bounds = part.bounds + np.array([[-pad], [pad]])
        say("the in-process stock: dexels of the design and the stock")
        design_model = dexelize(part, self.step, bounds=bounds, device=device, cluster=client)
        if stock_mesh is None:
            st = cutting.stock_from_model(design_model, self.stock.allowance)
        else:
            st = cutting.stock_from_model(dexelize(stock_mesh, self.step, bounds=bounds, device=device, cluster=client))
        start_model = st.to_model("stock")
        floor = float(bounds[0, 2])
        top = float(bounds[1, 2])
        if fix_mesh is not None:
            top = max(top, float(fix_mesh.bounds[1, 2]))
        safe_z = top + self.clearance
        surface = stock_mesh or closed_mesh(*machined_mesh(start_model)[:2], "stock")
        if stock_mesh is None:
            stock_mesh = closed_mesh(*stock_hull(start_model), "stock")
        fix_kern = solid_kernels(fix_mesh, device) if fix_mesh is not None else None
        part_kern = solid_kernels(part, device)  # every path verified against it
        results = []
        # the in-process stock for the next operation: a hull around every dexel (what rapids,
        # shanks and holders keep clear of) and its surface (what rest depths are measured from)
        current = stock_mesh
        for k, op in enumerate(self.operations):
            t_op = time.perf_counter()
            label = f"operation {k + 1} ({op.name})"
            say(f"{label}: {op.kind}")

            def stage(text, label=label):
                say(f"{label}: {text}")

            res = self._path(op, label, current if self.in_process else None, surface if self.in_process else None,
                             device, stage, client)
            tp, trimmed, fixture_check = _linked(res.toolpath, safe_z), 0, None
            stage("verify against the part and the fixtures")
            if fix_kern is not None:
                tp, trimmed, fixture_check = _clear_fixtures(tp, self.tools, fix_kern, safe_z, label)
            check = verify_toolpath(part_kern, tp, self.tools, self.tolerance)
            check.pop("problem_moves")
            op_s = time.perf_counter() - t_op
            before = start_model.volume if not results else results[-1].stock.volume
            stage("cut from the in-process stock")
            t_cut = time.perf_counter()
            cuts = cut_path(st, tp, self.tools, self.tolerance, "sweep", None, device, client)
            machined = st.to_model(f"stock after {op.name}")
            verts, faces, stride = machined_mesh(machined)
            deviation, volumes, warnings, (pts, e) = measure(machined, start_model, part, design_model, floor,
                                                             self.tolerance, self.step, device)
            cut_s = time.perf_counter() - t_cut
            timed = api.machining_time(tp, self.machine, self.tools).summary
            errors = list(cuts["errors"])
            if not check["ok"]:
                errors.append(f"the path gouges the part or collides with it ({check['gouging_moves']} gouging, "
                              f"{check['colliding_moves']} colliding moves, max gouge {check['max_gouge']:.4f} mm)")
            if fixture_check is not None and not fixture_check["ok"]:
                errors.append(f"the path enters a fixture ({fixture_check['gouging_moves']} cutter, "
                              f"{fixture_check['colliding_moves']} shank or holder moves)")
            res.toolpath = tp
            res.summary["verify"] = check
            res.summary["job"] = {
                "number": k + 1, "name": op.name, "folder": f"{k + 1:02d}-{_slug(op.name)}",
                "ok": not errors, "errors": errors,
                "in_process_stock": self.in_process, "rest": op.rest,
                "removed_mm3": before - machined.volume,
                "left_over_design_mm3": volumes["remaining"],
                "cutting_mm": cuts["cutting_mm"],
                "rapid_moves_cutting": cuts["rapid_moves_cutting"], "colliding_moves": cuts["colliding_moves"],
                "fixtures": None if fixture_check is None else {"trimmed_moves": trimmed, "ok": fixture_check["ok"],
                                                                 "max_depth": fixture_check["max_gouge"],
                                                                 "max_collision": fixture_check["max_collision"]},
                "machining_s": timed["total"]["total_s"], "time": timed,
                "seconds": {"operation": round(op_s, 3), "cut_and_measure": round(cut_s, 3)},
            }
            stock_summary = simulate_summary("sweep", self.step, machined.summary(), len(tp), cuts, volumes, deviation,
                                             (verts, faces, stride), warnings,
                                             {"cut": cuts["seconds"], "total": round(cut_s, 3)})
            stock_summary.update(design=api._part_entry(part), tools_file=api._tools_file(self.tools), device=device)
            results.append(OperationResult(op, res, machined, (verts, faces), {"points": pts, "e": e}, stock_summary))
            current = closed_mesh(*stock_hull(machined), f"stock after {op.name}")
            surface = closed_mesh(verts, faces, f"stock after {op.name}")
        say("the program")
        whole = Toolpath.concatenate([r.path.toolpath for r in results])
        posted = api.post(whole, self.machine, self.tools, clearance=safe_z if self.machine.chain.type != "3-axis"
                          else None)
        timed = api.machining_time(whole, self.machine, self.tools).summary
        final = results[-1].stock_summary
        summary = {
            "operation": "job", "name": self.name, "ok": all(r.ok for r in results),
            "part": api._part_entry(part), "tools_file": api._tools_file(self.tools),
            "machine": self.machine.summary(), "stock": {**self.stock.summary(), "volume_mm3": start_model.volume},
            "fixtures": [{"name": f.name, "box": f.mesh.bounds.round(6).tolist()} for f in self.fixtures],
            "step": self.step, "tolerance": self.tolerance, "in_process": self.in_process, "safe_z": safe_z,
            "device": device,
            "operations": [{"name": r.operation.name, "type": r.operation.kind, "folder": r.path.summary["job"]["folder"],
                            **{kk: r.path.summary["job"][kk] for kk in ("ok", "removed_mm3", "left_over_design_mm3",
                                                                          "cutting_mm", "machining_s", "errors")},
                            "verify_ok": r.path.summary["verify"]["ok"]} for r in results],
            "final": {"design_volume_mm3": final["volumes_mm3"]["design"],
                      "left_over_design_mm3": final["volumes_mm3"]["remaining"],
                      "gouged_mm3": final["volumes_mm3"]["gouged"], **final["deviation"]},
            "program": "", "post": {kk: v for kk, v in posted.report.items() if kk not in ("program",)},
            "machining_s": timed["total"]["total_s"], "time": timed,
            "seconds": {"total": round(time.perf_counter() - t_job, 3)},
        }
        return JobResult(self, results, posted.lines, posted.report, summary)

    def _path(self, op: Operation, label, stock, surface, device, stage, client=None):
        """The operation's :class:`~meshmill.api.PathResult` from the part (and the in-process
        stock: its hull ``stock`` and its ``surface``, or None), its tools numbered as the job's
        table."""
        run = OPERATIONS[op.kind]
        params = dict(op.params)
        tools = self.tools
        if op.kind in ("finish", "choose"):
            params["machine"] = self.machine
            if op.tools:
                tools = [t for t in self.tools if t.name in op.tools]
        if op.kind in ("raster", "waterline") and stock is not None and op.rest is not None:
            params["rest"] = op.rest
            params["rest_stock"] = surface
        if client is not None and op.kind in ("raster", "waterline", "finish"):
            params["cluster"] = client
        if stock is not None and op.kind != "choose":  # choose links its zones over the part alone
            params["stock"] = stock
            if op.kind != "plunge":  # the hull's corners are cut by up to half a cell: rapids keep that too
                params["clearance"] = params.get("clearance", HOLDER_CLEARANCE) + 0.5 * self.step
        try:
            if op.kind == "choose":
                res = run(self.part, tools=tools, device=device, progress=stage, **params)
            else:
                res = run(self.part, tools, device=device, progress=stage, **params)
        except InputError as exc:
            raise InputError(f"{label}: {exc}") from None
        if res.tools is not self.tools:  # the path's tools numbered as the job's table
            names = [t.name for t in self.tools]
            index = np.array([names.index(t.name) for t in res.tools])
            res.toolpath.tool = index[res.toolpath.tool]
            res.tools = self.tools
        return res


def _union(meshes):
    from .geometry.mesh import mesh_from_arrays

    verts, faces, base = [], [], 0
    for m in meshes:
        verts.append(m.vertices)
        faces.append(m.faces + base)
        base += len(m.vertices)
    return mesh_from_arrays(np.vstack(verts), np.vstack(faces), "fixtures")


def _slug(name: str) -> str:
    keep = "".join(c if c.isalnum() else "-" for c in name.lower())
    return "-".join(p for p in keep.split("-") if p) or "operation"


def _lift(tip, axis, z):
    """The tip moved along ``axis`` up to height ``z`` (or straight up where the axis is flat)."""
    if tip[2] >= z:
        return tip.copy()
    return tip + axis * ((z - tip[2]) / axis[2]) if axis[2] > 1e-6 else np.array([tip[0], tip[1], z])


def _linked(tp, safe_z):
    """``tp`` starting and ending on the job's safe plane: a rapid down from above its first
    point, a rapid up from its last (along the tool axis)."""
    from .toolpath.model import Toolpath

    if not len(tp):
        return tp
    first, last = _lift(tp.tip[0], tp.axis[0], safe_z), _lift(tp.tip[-1], tp.axis[-1], safe_z)
    return Toolpath(np.vstack([first, tp.tip, last]), np.vstack([tp.axis[:1], tp.axis, tp.axis[-1:]]),
                    np.r_[True, tp.rapid, True], np.r_[tp.tool[:1], tp.tool, tp.tool[-1:]],
                    np.r_[0, tp.line, 0], np.r_[np.nan, tp.feed, np.nan], tp.source, list(tp.warnings))


def _clear_fixtures(tp, tools, fix_kern, safe_z, label):
    """``(toolpath, trimmed moves, its check against the fixtures)``: ``tp`` with the moves that
    bring a cutter, shank or holder into a fixture left out; each stretch left out is linked over
    (a rapid up the tool axis to ``safe_z``, across, and down to the next point kept at feed).
    Raises :class:`InputError` when the links themselves enter a fixture."""
    from .pathing.verify import verify_toolpath
    from .toolpath.model import Toolpath

    report = verify_toolpath(fix_kern, tp, tools, 0.0)
    bad = np.zeros(len(tp), bool)
    bad[report.pop("problem_moves")] = True  # the move into point i
    if not bad.any():
        return tp, 0, report
    # a point is kept when neither move at it enters a fixture
    keep = ~bad & ~np.r_[bad[1:], False]
    tips, axes, rapid, tool, feed = [], [], [], [], []
    prev = None
    for i in np.nonzero(keep)[0]:
        if prev is not None and i != prev + 1:  # a stretch left out: link over it
            a, b = _lift(tp.tip[prev], tp.axis[prev], safe_z), _lift(tp.tip[i], tp.axis[i], safe_z)
            tips += [a, b]
            axes += [tp.axis[prev], tp.axis[i]]
            rapid += [True, True]
            tool += [tp.tool[prev], tp.tool[i]]
            feed += [np.nan, np.nan]
            tips.append(tp.tip[i])  # down at feed: the stretch below was not cut
            axes.append(tp.axis[i])
            rapid.append(False)
        else:
            tips.append(tp.tip[i])
            axes.append(tp.axis[i])
            rapid.append(bool(tp.rapid[i]) if prev is not None else True)
        tool.append(tp.tool[i])
        feed.append(tp.feed[i])
        prev = i
    if not tips:
        raise InputError(f"{label}: every move enters a fixture")
    out = Toolpath(np.array(tips), np.array(axes), np.array(rapid), np.array(tool, np.int64), None,
                   np.array(feed, float), tp.source, list(tp.warnings))
    again = verify_toolpath(fix_kern, out, tools, 0.0)
    again.pop("problem_moves")
    if not again["ok"]:
        raise InputError(f"{label}: the path cannot be linked clear of the fixtures ({again['worst'][0]}): raise the "
                         "job's clearance or move the fixture")
    return out, int(bad.sum()), again
