"""Tool-path files: APT CL (tips and axes) or G-code (read through a machine's kinematics),
chosen by extension, with the feeds they program."""
from __future__ import annotations

import os

from ..errors import InputError
from .timing import programmed_feeds

TOOLPATH_APT = (".cl", ".apt", ".cls", ".aptsource")
TOOLPATH_GCODE = (".nc", ".ngc", ".gcode", ".tap", ".g", ".txt")


def read_toolpath(path, tools, tool_name=None, machine=None):
    """``(Toolpath, warnings)`` of an APT CL file or G-code, chosen by the file's extension, its
    ``feed`` (mm/min per move, NaN where none is in force), ``source`` and ``warnings`` set. ``machine``
    (:class:`~meshmill.machine.model.Machine` or None) is the one G-code is read for (5-axis
    words through its kinematics); a CL file holds tips and axes already, and is read without it
    (with a warning that it is not used)."""
    tp, warnings = _read(path, tools, tool_name, machine)
    gcode = os.path.splitext(os.fspath(path))[1].lower() in TOOLPATH_GCODE
    tp.feed, more = programmed_feeds(path, tp.line, gcode, tp.tip)
    tp.source = os.path.abspath(os.fspath(path))
    tp.warnings = warnings + more
    return tp, tp.warnings


def _read(path, tools, tool_name, machine):
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext in TOOLPATH_APT:
        from ..toolpath.cldata import read_apt

        tp, warnings = read_apt(path, tools)
        if machine is not None:
            warnings.append(f"{os.path.basename(path)}: an APT CL file gives tool tips and axes; the machine "
                            f"({machine.name}) is not used")
        return tp, warnings
    if ext in TOOLPATH_GCODE:
        from .gcode import read_gcode

        return read_gcode(path, tools, tool_name=tool_name, machine=machine)
    raise InputError(f"{path}: unknown tool-path format '{ext}' (APT CL: {', '.join(TOOLPATH_APT)}; "
                     f"G-code: {', '.join(TOOLPATH_GCODE)})")
