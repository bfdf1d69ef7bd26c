"""Tool libraries people already have, read into the ``[[tools]]`` entries of a meshmill tool table
(dicts that :func:`meshmill.tools.table.tool_from_entry` checks; lengths in mm).

- FreeCAD tool bits (``.fctb``, JSON ``"version": 2``) and tool libraries (``.fctl``) of the
  Path/CAM workbench: end mills, ball ends and bull noses; other shapes have no meshmill type.
- LinuxCNC tool tables (``tool.tbl``): lines ``T1 P1 D6.0 Z+42.5 ;6mm flat end mill``. They give
  no flute length, no shank and no type; what is assumed is returned as warnings.
"""
from __future__ import annotations

import json
import math
import os
import re

from ..errors import InputError

MM_PER_UNIT = {"": 1.0, "mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4, "inch": 25.4, "inches": 25.4, '"': 25.4}
FREECAD_TYPES = {"endmill": "flat", "ballend": "ball", "bullnose": "bull", "torus": "bull"}
LINUXCNC_FIELDS = "TPXYZABCUVWDIJQ"  # T tool, P pocket, X..W offsets, D diameter, I J Q lathe angles/orientation
_QUANTITY = re.compile(r'\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:e[+-]?\d+)?)(?:\s*/\s*([1-9]\d*))?\s*([a-z]*|")\s*',
                       re.IGNORECASE)
_CORNER = re.compile(r'\b(?:c?r|rc)=?(\d+(?:\.\d*)?|\.\d+)(mm|in|")?(?![\w.])', re.IGNORECASE)


def _read_json(path: str, what: str):
    try:
        with open(path, encoding="utf-8-sig") as fh:
            return json.load(fh)
    except FileNotFoundError:
        raise InputError(f"{path}: no such {what}") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read the {what} ({e.strerror})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a {what} (not UTF-8 text)") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not a {what}: invalid JSON at line {e.lineno} ({e.msg})") from None


def _length(value, key: str, where: str, positive: bool = True) -> float:
    """A FreeCAD length (``"6.00 mm"``, ``"0.25 in"``, ``"1/4 in"``, ``6``: mm) in mm."""
    mm = None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        mm = float(value)
    elif isinstance(value, str):
        text = value.replace(",", ".") if "." not in value else value  # a decimal comma of some locales
        m = _QUANTITY.fullmatch(text)
        if m and m.group(3).lower() in MM_PER_UNIT:
            number = float(m.group(1)) / (float(m.group(2)) if m.group(2) else 1.0)
            mm = number * MM_PER_UNIT[m.group(3).lower()]
    if mm is None or not math.isfinite(mm) or mm < 0 or (positive and mm == 0):
        raise InputError(f"{where}: '{key}' must be a length {'> 0' if positive else '>= 0'} "
                         f"(such as '6 mm' or '0.25 in'), got {value!r}")
    return mm


def read_fctb(path) -> dict:
    """A FreeCAD tool bit (.fctb) as a tool table entry, in mm.

    ``endmill`` -> flat, ``ballend`` -> ball, ``bullnose``/``torus`` -> bull (corner radius from
    ``CornerRadius``, ``TorusRadius``, or ``Diameter/2 - FlatRadius``; a corner radius of 0 or
    ``Diameter/2`` gives a flat or ball tool). flute_length = ``CuttingEdgeHeight``, gauge_length =
    ``Length`` (FreeCAD's overall length: it includes the part in the holder), shank_diameter =
    ``ShankDiameter`` (default: the diameter); ``Flutes`` -> flutes and ``Chipload`` -> fz (mm)
    when given and not 0. Any other shape raises :class:`InputError`.
    """
    path = os.fspath(path)
    data = _read_json(path, "FreeCAD tool bit")
    if not isinstance(data, dict) or not isinstance(data.get("parameter"), dict):
        raise InputError(f"{path}: not a FreeCAD tool bit (a JSON object with 'shape' and 'parameter')")
    shape = data.get("shape") or data.get("shape-type")
    if not isinstance(shape, str):
        raise InputError(f"{path}: FreeCAD tool bit has no 'shape'")
    # FreeCAD 1.1 names the shape's kind in 'shape-type' (the shape file may be a user's own)
    kind = str(data.get("shape-type") or os.path.splitext(os.path.basename(shape))[0]).lower()
    if kind not in FREECAD_TYPES:
        raise InputError(f"{path}: FreeCAD tool bit shape '{shape}' has no meshmill tool type (ball, flat, bull)")
    kind = FREECAD_TYPES[kind]
    p = data["parameter"]
    attributes = data.get("attribute") if isinstance(data.get("attribute"), dict) else {}
    for key in ("Diameter", "CuttingEdgeHeight", "Length"):
        if key not in p:
            raise InputError(f"{path}: FreeCAD tool bit has no parameter '{key}'")
    d = _length(p["Diameter"], "Diameter", path)
    flute = _length(p["CuttingEdgeHeight"], "CuttingEdgeHeight", path)
    gauge = _length(p["Length"], "Length", path)
    shank = _length(p["ShankDiameter"], "ShankDiameter", path) if "ShankDiameter" in p else d
    if gauge < flute:
        raise InputError(f"{path}: 'Length' ({gauge:g} mm) is shorter than 'CuttingEdgeHeight' ({flute:g} mm)")
    entry = {"name": str(data.get("name") or os.path.splitext(os.path.basename(path))[0]), "type": kind,
             "diameter": d}
    if kind == "bull":
        R = 0.5 * d
        if "CornerRadius" in p or "TorusRadius" in p:
            key = "CornerRadius" if "CornerRadius" in p else "TorusRadius"
            rc = _length(p[key], key, path, positive=False)
        elif "FlatRadius" in p:
            rc = R - _length(p["FlatRadius"], "FlatRadius", path, positive=False)
        else:
            raise InputError(f"{path}: FreeCAD bull-nose bit has no 'CornerRadius' (or 'FlatRadius')")
        if not 0.0 <= rc <= R * (1 + 1e-9):
            raise InputError(f"{path}: corner radius {rc:g} mm must be from 0 to Diameter/2 = {R:g} mm")
        if rc == 0.0:
            entry["type"] = "flat"
        elif rc >= R * (1 - 1e-9):
            entry["type"] = "ball"
        else:
            entry["corner_radius"] = rc
    entry.update(flute_length=flute, gauge_length=gauge, shank_diameter=shank)
    flutes = p.get("Flutes", attributes.get("Flutes", 0))
    if isinstance(flutes, str) and flutes.strip().isdigit():
        flutes = int(flutes)
    if (isinstance(flutes, bool) or not isinstance(flutes, (int, float))
            or not (math.isfinite(flutes) and flutes >= 0 and flutes == int(flutes))):
        raise InputError(f"{path}: 'Flutes' must be a whole number, got {flutes!r}")
    if flutes:
        entry["flutes"] = int(flutes)
    chipload = p.get("Chipload", attributes.get("Chipload", 0))
    fz = _length(chipload, "Chipload", path, positive=False)
    if fz > 0:
        entry["fz"] = fz
    return entry


def _find_bit(library_dir: str, name: str):
    """The .fctb file ``name`` of a library: beside the library, or in the ``Bit`` folder beside its
    folder (FreeCAD's ``Tools/Library`` and ``Tools/Bit``), with or without ``.fctb``."""
    name = name.replace("\\", "/")
    bits = os.path.join(os.path.dirname(library_dir), "Bit")
    stem = os.path.splitext(os.path.basename(name))[0]
    for candidate in (os.path.join(library_dir, name), os.path.join(bits, name), os.path.join(bits, stem + ".fctb")):
        if os.path.isfile(candidate):
            return candidate
    return None


def _unique_names(entries, numbers) -> None:
    """Suffix `` T<number>`` to every name that more than one entry has."""
    names = [e["name"] for e in entries]
    for entry, number in zip(entries, numbers):
        if names.count(entry["name"]) > 1:
            entry["name"] = f"{entry['name']} T{number}"


def read_fctl(path) -> tuple[list[dict], list[int]]:
    """A FreeCAD tool library (.fctl) as ``(entries, numbers)``: its bits read by :func:`read_fctb`
    in the library's order, and their tool numbers (``nr``). Clashing names get `` T<nr>``."""
    path = os.fspath(path)
    data = _read_json(path, "FreeCAD tool library")
    tools = data.get("tools") if isinstance(data, dict) else None
    if not isinstance(tools, list) or not tools:
        raise InputError(f"{path}: not a FreeCAD tool library (a JSON object with a non-empty 'tools' list)")
    here = os.path.dirname(os.path.abspath(path))
    entries, numbers = [], []
    for i, item in enumerate(tools, 1):
        nr = item.get("nr") if isinstance(item, dict) else None
        if isinstance(nr, str) and nr.strip().isdigit():
            nr = int(nr)
        if isinstance(nr, bool) or not isinstance(nr, int) or not isinstance(item.get("path"), str):
            raise InputError(f"{path}: tools entry {i} needs a tool number 'nr' and a bit 'path'")
        if nr in numbers:
            raise InputError(f"{path}: tool number {nr} is given twice")
        bit = _find_bit(here, item["path"])
        if bit is None:
            raise InputError(f"{path}: tool {nr}: no tool bit '{item['path']}' beside the library or in its "
                             "sibling Bit folder")
        try:
            entries.append(read_fctb(bit))
        except InputError as e:
            raise InputError(f"{path}: tool {nr}: {e.message}") from None
        numbers.append(nr)
    _unique_names(entries, numbers)
    return entries, numbers


def _type_from_comment(comment: str, scale: float, d: float, where: str):
    """``(type, corner_radius, named)`` of a LinuxCNC tool from its comment (mm; corner radius
    ``R1``/``R0.5mm`` for a bull nose, in the table's units unless it says mm or in)."""
    text = comment.lower()
    if re.search(r"\bbull|\btor(?:us|oid)", text):
        m = _CORNER.search(text)
        if m is None:
            raise InputError(f"{where}: a bull-nose cutter by its comment needs its corner radius there "
                             "(such as R1)")
        rc = float(m.group(1)) * (MM_PER_UNIT[m.group(2)] if m.group(2) else scale)
        if not 0.0 < rc < 0.5 * d:
            raise InputError(f"{where}: corner radius {rc:g} mm must be > 0 and < D/2 = {0.5 * d:g} mm")
        return "bull", rc, True
    if re.search(r"\bball", text):
        return "ball", 0.5 * d, True
    return "flat", 0.0, re.search(r"\bflat|\bsquare|\bend ?mill", text) is not None


def read_linuxcnc_tbl(path, units: str = "mm") -> tuple[list[dict], list[str], list[int]]:
    """A LinuxCNC tool table as ``(entries, warnings, tool numbers)``, in file order, in mm.

    Values are in machine ``units`` ("mm" or "inch"). Type from the comment (ball; bull/torus with
    a corner radius R1; else flat). Assumed, one warning line per tool: flute_length =
    min(3 x D, gauge_length); gauge_length = the Z offset when it is at least D (a shorter one is
    taken as an offset from a master tool, not a length), else 4 x D; shank_diameter = D. Name: the
    comment, else ``T<n>``; names that clash get `` T<n>``.
    """
    path = os.fspath(path)
    if units not in ("mm", "inch"):
        raise InputError(f"units must be 'mm' or 'inch', got {units!r}", "units")
    scale = 25.4 if units == "inch" else 1.0
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            lines = fh.read().splitlines()
    except FileNotFoundError:
        raise InputError(f"{path}: no such LinuxCNC tool table") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read the LinuxCNC tool table ({e.strerror})") from None
    entries, warnings, numbers, first_line = [], [], [], {}
    for line_no, line in enumerate(lines, 1):
        fields, _, comment = line.partition(";")
        if not fields.strip():
            continue  # blank or comment line
        where = f"{path}: line {line_no}"
        values = {}
        for token in fields.split():
            letter = token[0].upper()
            if letter not in LINUXCNC_FIELDS:
                raise InputError(f"{where}: unknown field '{token}' (LinuxCNC tool table fields: "
                                 f"{' '.join(LINUXCNC_FIELDS)})")
            if letter in values:
                raise InputError(f"{where}: field {letter} is given twice")
            try:
                values[letter] = int(token[1:]) if letter in "TPQ" else float(token[1:])
            except ValueError:
                values[letter] = math.nan
            if not math.isfinite(values[letter]):
                whole = "whole " if letter in "TPQ" else ""
                raise InputError(f"{where}: '{token}' needs a {whole}number after {letter}")
        t = values.get("T")
        if t is None or t < 1:
            raise InputError(f"{where}: needs a tool number T1 or above")
        if t in first_line:
            raise InputError(f"{where}: tool T{t} is listed again (first on line {first_line[t]})")
        first_line[t] = line_no
        if values.get("D", 0.0) <= 0:
            raise InputError(f"{where}: tool T{t} needs a diameter D > 0")
        d = values["D"] * scale
        z = values.get("Z", 0.0) * scale
        kind, rc, named = _type_from_comment(comment, scale, d, where)
        gauge = z if z >= d else 4.0 * d
        flute = min(3.0 * d, gauge)
        entry = {"name": comment.strip() or f"T{t}", "type": kind, "diameter": d}
        if kind == "bull":
            entry["corner_radius"] = rc
        entry.update(flute_length=flute, gauge_length=gauge, shank_diameter=d)
        said = [f"LinuxCNC tables give no flute length; taken as {flute:g} mm "
                f"({'3 x D' if flute == 3.0 * d else 'the gauge length'})",
                f"gauge_length taken as the Z offset, {gauge:g} mm, with no holder" if z >= d else
                f"no Z offset of at least D; gauge_length taken as {gauge:g} mm (4 x D)",
                "shank_diameter taken as D"]
        if not named:
            said.append("the comment names no ball, bull or flat cutter; taken as flat")
        entries.append(entry)
        numbers.append(t)
        warnings.append(f"T{t}: " + "; ".join(said))
    if not entries:
        raise InputError(f"{path}: no tools in this LinuxCNC tool table")
    _unique_names(entries, numbers)
    return entries, warnings, numbers
