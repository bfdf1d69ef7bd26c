"""What each API call returns (:mod:`meshmill.api`): a small object with the figures of the run
(``summary`` or ``report``), what it made (a tool path, a model, a program) and ``save``, which
writes exactly the files the command writes, all or nothing (:class:`~meshmill.runfiles.RunFiles`)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field

from .errors import InputError
from .runfolder import FOLDER_OUTPUTS, write_json, write_part


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

    def _save_folder(self, folder, kind, write):
        """The files of a ``kind`` of run folder (:data:`~meshmill.runfolder.FOLDER_OUTPUTS`) into
        ``folder``: ``write(at)`` writes each to ``at(name)``."""
        return self._save([os.path.join(folder, n) for n in FOLDER_OUTPUTS[kind]],
                          lambda run: write(lambda name: run.tmp(os.path.join(folder, name))))


@dataclass
class PathResult(_Saved):
    """A tool path and its summary: finish, raster, waterline, plunge, rough. ``arrays``: finish's
    contours and surface status (contours.npz), rough's kind of every move (moves.npz)."""

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

        def write(at):
            import numpy as np

            if self.arrays:
                np.savez_compressed(at("moves.npz" if self.operation == "rough" else "contours.npz"), **self.arrays)
            write_apt(at("toolpath.cl"), self.toolpath, self.tools, partno=os.path.basename(self.part.source or "part"))
            write_part(at("part.stl"), self.part)
            write_json(at("summary.json"), self.summary)

        return self._save_folder(folder, self.operation, write)


@dataclass
class VerifyResult(_Saved):
    """``report``: what verify found (moves, gouging and colliding moves, worst cases, ok);
    ``problem_moves``: the moves that fail."""

    report: dict
    device: str
    stock_checked: bool
    problem_moves: object = None  # (k,) the moves that fail: the index of the point each ends at

    @property
    def ok(self) -> bool:
        return bool(self.report["ok"])

    def save(self, path) -> list:
        """Write the report as JSON to ``path``."""
        return self._save([path], lambda run: write_json(run.tmp(path), self.report))


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


@dataclass
class SimulateResult(_Saved):
    """``deviation`` (ISO 25178 parameters, gouge and excess), ``summary``, the ``machined``
    surface ``(vertices, faces)``, the deviation ``samples`` (points, e) and the ``stock`` after
    the path (:class:`~meshmill.simulation.stock.Stock`, to cut on or save)."""

    deviation: dict
    summary: dict
    machined: tuple
    samples: dict
    stock: object = None  # the stock after the path (a Stock; None when cut on a cluster's workers)
    load: object = None  # the load of every move (a MoveLoad; None when not measured)

    @property
    def ok(self) -> bool:
        """No rapid cut material, no shank or holder hit it, no move over its tool's or the
        spindle's limits."""
        return not (self.summary["rapid_moves_cutting"] or self.summary["colliding_moves"]
                    or not self.summary.get("load", {}).get("ok", True))

    def save(self, folder) -> list:
        """Write deviation.json, summary.json and, where the run kept them, deviation.npz,
        load.npz (every move's load) and machined.stl into ``folder`` (an earlier run's files there are removed)."""
        import numpy as np

        def write(at):
            if self.samples is not None:
                np.savez_compressed(at("deviation.npz"), points=self.samples["points"], e=self.samples["e"])
            if self.load is not None:
                np.savez_compressed(at("load.npz"), **self.load.arrays())
            if self.machined is not None and len(self.machined[1]):
                from .geometry.mesh import write_binary_stl

                write_binary_stl(at("machined.stl"), *self.machined)
            write_json(at("deviation.json"), self.deviation)
            write_json(at("summary.json"), self.summary)

        return self._save_folder(folder, "simulate", write)


@dataclass
class AnalysisResult(_Saved):
    """``summary`` and the per-triangle and per-vertex ``arrays`` (analysis.npz)."""

    summary: dict
    arrays: dict

    def save(self, folder) -> list:
        import numpy as np

        def write(at):
            np.savez_compressed(at("analysis.npz"), **self.arrays)
            write_json(at("summary.json"), self.summary)

        return self._save_folder(folder, "analyze", write)


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

        def write(at):
            self.summary["tools_file"] = os.path.abspath(os.path.join(folder, "tools.toml"))
            write_tools(at("tools.toml"), self.tools)
            write_apt(at("toolpath.cl"), self.toolpath, self.tools, partno=os.path.basename(self.part))
            np.savez_compressed(at("zones.npz"), **self.zones)
            write_json(at("summary.json"), self.summary)

        return self._save_folder(folder, "choose", write)


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


@dataclass
class FeedsResult(_Saved):
    """``toolpath`` with its optimised feeds, ``summary`` (machining time before and after, the
    load as measured, its errors), the ``load`` of every move (a MoveLoad, at the feeds before),
    the ``program`` (a :class:`PostResult`) and the ``tools``."""

    toolpath: object
    summary: dict
    load: object
    program: object
    tools: list

    @property
    def ok(self) -> bool:
        """No move over its tool's or the spindle's limits as measured (a section over the tool's, which feeds cannot mend)."""
        return not self.summary["errors"]

    def save(self, folder) -> list:
        """Write toolpath.cl (FEDRAT per move), program.nc, load.npz and summary.json."""
        import numpy as np

        from .toolpath.cldata import write_apt

        def write(at):
            write_apt(at("toolpath.cl"), self.toolpath, self.tools)
            with open(at("program.nc"), "w") as fh:
                fh.write("\n".join(self.program.lines) + "\n")
            if self.load is not None:
                np.savez_compressed(at("load.npz"), **self.load.arrays())
            write_json(at("summary.json"), self.summary)

        return self._save_folder(folder, "feeds", write)


@dataclass
class TimeResult(_Saved):
    """``summary``: machining time per tool and in total (cutting, rapid, tool changes, stops)."""

    summary: dict
    warnings: list

    def save(self, path) -> list:
        return self._save([path], lambda run: write_json(run.tmp(path), self.summary))


@dataclass
class FixturesResult:
    """A path kept out of the fixtures: the ``toolpath``, how many moves were ``trimmed`` (left
    out and linked over) and the ``report`` of its check against them (``ok``)."""

    toolpath: object
    trimmed: int
    report: dict

    @property
    def ok(self) -> bool:
        return bool(self.report["ok"])
