"""The run folder: the files each command writes (:data:`FOLDER_OUTPUTS`), how they are written
(all or nothing, :class:`~meshmill.runfiles.RunFiles`) and read back (:func:`read_run`, for the
report). ``summary.json``'s ``operation`` names the kind of run.

A folder holds ``summary.json`` and, by kind: ``toolpath.cl`` (APT CL, mm) and ``part.stl`` (the
placed part, work frame) for finish, raster, waterline, plunge; ``contours.npz`` (finish);
``tools.toml`` and ``zones.npz`` (choose); ``deviation.json`` and, as ``--outputs`` asks,
``deviation.npz`` and ``machined.stl`` (simulate); ``analysis.npz`` (analyze). ``dexel`` writes its model file and a
``summary.json`` beside it.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field

from .errors import InputError

# the files each command writes into its folder, the summary last
FOLDER_OUTPUTS = {
    "finish": ("contours.npz", "toolpath.cl", "part.stl", "summary.json"),
    "raster": ("toolpath.cl", "part.stl", "summary.json"),
    "waterline": ("toolpath.cl", "part.stl", "summary.json"),
    "steep-shallow": ("toolpath.cl", "part.stl", "summary.json"),
    "plunge": ("toolpath.cl", "part.stl", "summary.json"),
    "rough": ("moves.npz", "toolpath.cl", "part.stl", "summary.json"),
    "simulate": ("deviation.npz", "load.npz", "machined.stl", "deviation.json", "summary.json"),
    "feeds": ("toolpath.cl", "program.nc", "load.npz", "summary.json"),
    "analyze": ("analysis.npz", "summary.json"),
    "choose": ("tools.toml", "toolpath.cl", "zones.npz", "summary.json"),
}
KINDS = (*FOLDER_OUTPUTS, "dexel")  # summary.json's "operation" in a run folder


def write_json(path, data):
    """``data`` as indented JSON (numpy numbers as floats)."""
    try:
        with open(path, "w") as fh:
            json.dump(data, fh, indent=2, default=float)
            fh.write("\n")
    except OSError as exc:
        raise InputError(f"{path}: cannot write ({exc.strerror})") from None


def write_part(path, mesh):
    """The placed part as a binary STL (mm, work frame), for any program to check a path against."""
    from .geometry.mesh import write_binary_stl

    write_binary_stl(path, mesh.vertices, mesh.faces)


@dataclass
class Run:
    """One run folder: its ``summary`` and what the views need (``None`` where absent)."""

    folder: str
    kind: str
    summary: dict
    part: object = None  # Mesh
    toolpath: object = None  # Toolpath
    tools: list = field(default_factory=list)
    contours: dict | None = None
    deviation: dict | None = None
    samples: dict | None = None  # deviation points and values
    machined: tuple | None = None  # (vertices, faces)
    zones: dict | None = None  # choose: the sampling grid's cells and their zones
    load: dict | None = None  # simulate, feeds: every move's load (load.npz)
    left: dict | None = None  # a job's last stock: what is left on the part and why (left.npz)
    notes: list = field(default_factory=list)


def read_json(path):
    try:
        with open(path) as fh:
            return json.load(fh)
    except OSError as exc:
        raise InputError(f"{path}: cannot read ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None


def summary_path(folder: str) -> str:
    """``folder``'s ``summary.json`` (raises :class:`InputError` when it is not a run folder)."""
    if not os.path.isdir(folder):
        raise InputError(f"{folder}: no such folder")
    path = os.path.join(folder, "summary.json")
    if not os.path.exists(path):
        raise InputError(f"{folder}: no summary.json (not a folder written by a meshmill command)")
    return path


def read_run(folder: str, meshes: dict | None = None) -> Run:
    """Read a run folder (raises :class:`InputError` when it is not one); ``meshes`` keeps the
    parts already loaded, by file, for runs on the same part."""
    from .geometry.mesh import SUPPORTED, load_mesh
    from .geometry.placement import Setup
    from .tools.table import load_tools
    from .toolpath.cldata import read_apt

    path = summary_path(folder)
    s = read_json(path)
    kind = s.get("operation")
    if kind not in KINDS:
        raise InputError(f"{path}: not a meshmill run summary ('operation' is {kind!r}, not one of {', '.join(KINDS)})")
    run = Run(folder=folder, kind=kind, summary=s)
    part_file = (s.get("part") or s.get("design") or s.get("surface") or {}).get("file")
    if part_file and not part_file.lower().endswith(SUPPORTED):
        part_file = None  # a patch (choose): its sampled cells stand for it
    if part_file and os.path.exists(part_file):
        meshes = {} if meshes is None else meshes
        placed = os.path.join(folder, "part.stl")  # the part as the run placed it (work frame)
        key = placed if os.path.exists(placed) else part_file
        if key not in meshes:
            entry = s.get("part") or s.get("design") or s.get("surface") or {}
            if key == placed:
                meshes[key] = load_mesh(placed)
            else:  # set up as the run did
                setup = entry.get("setup") or {}
                meshes[key] = load_mesh(part_file, flip=bool(entry.get("flipped")),
                                        setup=Setup(setup.get("units", "mm"), setup.get("up", "+Z"),
                                                    setup.get("origin", "file"), setup.get("model_scale", 1.0)))
        run.part = meshes[key]
    elif part_file:
        run.notes.append(f"the part {part_file} is gone: not shown")
    if s.get("tools_file") and os.path.exists(s["tools_file"]):
        run.tools = load_tools(s["tools_file"])
    cl = os.path.join(folder, "toolpath.cl") if kind != "simulate" else (s.get("toolpath") or {}).get("file")
    run.load = read_npz(os.path.join(folder, "load.npz"))
    if cl and os.path.exists(cl) and cl.lower().endswith((".cl", ".apt", ".cls")):
        if run.tools:
            run.toolpath, _ = read_apt(cl, run.tools)
        else:
            run.notes.append("the summary names no tool table that still exists: the tool path is not shown")
    run.zones = read_npz(os.path.join(folder, "zones.npz"))
    run.contours = read_npz(os.path.join(folder, "contours.npz"))
    if kind == "simulate":
        run.deviation = read_json(os.path.join(folder, "deviation.json"))
        run.samples = read_npz(os.path.join(folder, "deviation.npz"))
        run.left = read_npz(os.path.join(folder, "left.npz"))
        m = os.path.join(folder, "machined.stl")
        if os.path.exists(m):
            import numpy as np

            from .geometry.mesh import import_trimesh

            t = import_trimesh().load(m, force="mesh")  # processed: the STL's repeated corners merged
            run.machined = (np.asarray(t.vertices, float), np.asarray(t.faces, np.int64))
    return run


def read_npz(path):
    """The arrays of the .npz file at ``path`` by name, or None when there is none."""
    if not os.path.exists(path):
        return None
    import numpy as np

    with np.load(path) as z:
        return {k: z[k] for k in z.files}
