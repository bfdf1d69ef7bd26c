"""Tool libraries of other programs read into tool table entries: FreeCAD .fctb/.fctl, LinuxCNC .tbl."""
import json

import pytest

from meshmill.errors import InputError
from meshmill.tools.foreign import read_fctb, read_fctl, read_linuxcnc_tbl
from meshmill.tools.table import KEYS, tool_from_entry


def _tool(entry, number=1):
    # the cutting-data keys (flutes, fz, ...) are being added to the table's KEYS: drop what this
    # version of tool_from_entry does not know yet, so that the shape is still checked
    return tool_from_entry({k: v for k, v in entry.items() if k in KEYS}, number, "x")


def _bit(folder, filename, shape, parameter, attribute=None, **extra):
    path = folder / filename
    path.write_text(json.dumps({"version": 2, "name": filename.split(".")[0], "shape": shape,
                                "parameter": parameter, "attribute": attribute or {}, **extra}))
    return path


def _error(call, *args, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        call(*args, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_fctb_endmill(tmp_path):
    path = _bit(tmp_path, "5mm_Endmill.fctb", "endmill.fcstd",
                {"CuttingEdgeHeight": "30.0000 mm", "Diameter": "5.0000 mm", "Length": "50.0000 mm",
                 "ShankDiameter": "3.0000 mm"}, {"Flutes": 2, "Material": "Carbide"})
    entry = read_fctb(path)
    assert entry == {"name": "5mm_Endmill", "type": "flat", "diameter": 5.0, "flute_length": 30.0,
                     "gauge_length": 50.0, "shank_diameter": 3.0, "flutes": 2}
    tool = _tool(entry)
    assert (tool.type, tool.diameter, tool.corner_radius, tool.gauge_length) == ("flat", 5.0, 0.0, 50.0)


def test_fctb_ballend_freecad_1_1(tmp_path):
    # FreeCAD 1.1: 'shape-type', Flutes and Chipload among the parameters, no ShankDiameter here
    path = _bit(tmp_path, "6mm_Ball_End.fctb", "ballend.fcstd",
                {"CuttingEdgeHeight": "40.0000 mm", "Diameter": "6.0000 mm", "Length": "50.0000 mm",
                 "Flutes": "2", "Chipload": "0.05 mm", "Units": "Metric"}, **{"shape-type": "Ballend"})
    entry = read_fctb(path)
    assert entry == {"name": "6mm_Ball_End", "type": "ball", "diameter": 6.0, "flute_length": 40.0,
                     "gauge_length": 50.0, "shank_diameter": 6.0, "flutes": 2, "fz": 0.05}
    assert _tool(entry).corner_radius == 3.0


@pytest.mark.parametrize("radius, expected", [({"FlatRadius": "1.5000 mm"}, 1.5),  # FreeCAD <= 1.0
                                              ({"CornerRadius": "1.0 mm"}, 1.0),  # FreeCAD 1.1
                                              ({"TorusRadius": "0.5 mm"}, 0.5)])
def test_fctb_bullnose(tmp_path, radius, expected):
    path = _bit(tmp_path, "6mm_Bullnose.fctb", "bullnose.fcstd",
                {"CuttingEdgeHeight": "40.0000 mm", "Diameter": "6.0000 mm", "Length": "50.0000 mm",
                 "ShankDiameter": "3.0000 mm", **radius})
    entry = read_fctb(path)
    assert entry == {"name": "6mm_Bullnose", "type": "bull", "diameter": 6.0, "corner_radius": expected,
                     "flute_length": 40.0, "gauge_length": 50.0, "shank_diameter": 3.0}
    assert _tool(entry).corner_radius == expected


def test_fctb_bullnose_limits_are_flat_or_ball(tmp_path):
    base = {"CuttingEdgeHeight": "20 mm", "Diameter": "8 mm", "Length": "60 mm"}
    flat = read_fctb(_bit(tmp_path, "a.fctb", "bullnose.fcstd", {**base, "CornerRadius": "0 mm"}))
    ball = read_fctb(_bit(tmp_path, "b.fctb", "torus.fcstd", {**base, "FlatRadius": "0 mm"}))
    assert (flat["type"], ball["type"]) == ("flat", "ball") and "corner_radius" not in flat | ball
    _tool(flat), _tool(ball)


def test_fctb_units(tmp_path):
    path = _bit(tmp_path, "quarter.fctb", "endmill.fcstd",
                {"Diameter": "0.25 in", "CuttingEdgeHeight": '3/4"', "Length": "2 inch",
                 "ShankDiameter": "1/4 in"})
    entry = read_fctb(path)
    assert entry["diameter"] == pytest.approx(6.35) and entry["shank_diameter"] == pytest.approx(6.35)
    assert entry["flute_length"] == pytest.approx(19.05) and entry["gauge_length"] == pytest.approx(50.8)
    path = _bit(tmp_path, "metric.fctb", "endmill.fcstd",
                {"Diameter": 6, "CuttingEdgeHeight": "1.8 cm", "Length": "0.05 m", "ShankDiameter": "6,00 mm"})
    entry = read_fctb(path)
    assert (entry["diameter"], entry["shank_diameter"]) == (6.0, 6.0)
    assert entry["flute_length"] == pytest.approx(18.0) and entry["gauge_length"] == pytest.approx(50.0)
    _tool(entry)


@pytest.mark.parametrize("shape", ["v-bit.fcstd", "drill.fcstd", "chamfer.fcstd", "thread-mill.fcstd",
                                   "slittingsaw.fcstd", "probe.fcstd"])
def test_fctb_other_shapes(tmp_path, shape):
    path = _bit(tmp_path, "bit.fctb", shape, {"Diameter": "5 mm", "Length": "50 mm"})
    assert _error(read_fctb, path) == (f"{path}: FreeCAD tool bit shape '{shape}' has no meshmill tool type "
                                       "(ball, flat, bull)")


def test_fctb_errors(tmp_path):
    good = {"CuttingEdgeHeight": "30 mm", "Diameter": "5 mm", "Length": "50 mm"}
    cases = {
        "missing.fctb": None,
        "bad.fctb": "{ not json",
        "list.fctb": "[1, 2]",
        "noshape.fctb": json.dumps({"version": 2, "name": "x", "parameter": good}),
    }
    for name, text in cases.items():
        if text is not None:
            (tmp_path / name).write_text(text)
        assert _error(read_fctb, tmp_path / name).startswith(f"{tmp_path / name}: ")
    no_d = _bit(tmp_path, "nod.fctb", "endmill.fcstd", {"CuttingEdgeHeight": "30 mm", "Length": "50 mm"})
    assert _error(read_fctb, no_d) == f"{no_d}: FreeCAD tool bit has no parameter 'Diameter'"
    furlong = _bit(tmp_path, "unit.fctb", "endmill.fcstd", {**good, "Diameter": "5 furlong"})
    assert "'Diameter' must be a length" in _error(read_fctb, furlong)
    short = _bit(tmp_path, "short.fctb", "endmill.fcstd", {**good, "Length": "20 mm"})
    assert _error(read_fctb, short) == f"{short}: 'Length' (20 mm) is shorter than 'CuttingEdgeHeight' (30 mm)"
    no_radius = _bit(tmp_path, "bull.fctb", "bullnose.fcstd", good)
    assert "CornerRadius" in _error(read_fctb, no_radius)
    big = _bit(tmp_path, "big.fctb", "bullnose.fcstd", {**good, "CornerRadius": "3 mm"})
    assert "corner radius 3 mm" in _error(read_fctb, big)
    flutes = _bit(tmp_path, "flutes.fctb", "endmill.fcstd", good, {"Flutes": "two"})
    assert "'Flutes' must be a whole number" in _error(read_fctb, flutes)


def test_fctl_library(tmp_path):
    (tmp_path / "Bit").mkdir()
    (tmp_path / "Library").mkdir()
    end = {"CuttingEdgeHeight": "30 mm", "Diameter": "5 mm", "Length": "50 mm"}
    _bit(tmp_path / "Bit", "5mm_Endmill.fctb", "endmill.fcstd", end)
    _bit(tmp_path / "Bit", "6mm_Ball_End.fctb", "ballend.fcstd", {**end, "Diameter": "6 mm"})
    (tmp_path / "Library" / "near.fctb").write_text(  # beside the library, named like the end mill
        json.dumps({"version": 2, "name": "5mm_Endmill", "shape": "endmill.fcstd", "parameter": end}))
    library = tmp_path / "Library" / "Mill.fctl"
    library.write_text(json.dumps({"version": 1, "tools": [
        {"nr": 3, "path": "5mm_Endmill.fctb"}, {"nr": "1", "path": "6mm_Ball_End"}, {"nr": 7, "path": "near.fctb"}]}))
    entries, numbers = read_fctl(library)
    assert numbers == [3, 1, 7]
    assert [(e["name"], e["type"], e["diameter"]) for e in entries] == [
        ("5mm_Endmill T3", "flat", 5.0), ("6mm_Ball_End", "ball", 6.0), ("5mm_Endmill T7", "flat", 5.0)]
    for number, entry in zip(numbers, entries):
        _tool(entry, number)

    _bit(tmp_path / "Bit", "60degree_Vbit.fctb", "v-bit.fcstd", {"Diameter": "10 mm", "Length": "50 mm"})
    library.write_text(json.dumps({"version": 1, "tools": [{"nr": 5, "path": "60degree_Vbit.fctb"}]}))
    message = _error(read_fctl, library)
    assert message.startswith(f"{library}: tool 5: ") and "60degree_Vbit.fctb" in message and "'v-bit.fcstd'" in message
    library.write_text(json.dumps({"version": 1, "tools": [{"nr": 2, "path": "gone.fctb"}]}))
    assert _error(read_fctl, library) == (f"{library}: tool 2: no tool bit 'gone.fctb' beside the library or "
                                          "in its sibling Bit folder")
    library.write_text(json.dumps({"version": 1, "tools": [{"nr": 1, "path": "5mm_Endmill.fctb"},
                                                           {"nr": 1, "path": "6mm_Ball_End.fctb"}]}))
    assert _error(read_fctl, library) == f"{library}: tool number 1 is given twice"
    library.write_text(json.dumps({"version": 1, "tools": []}))
    assert _error(read_fctl, library).startswith(f"{library}: not a FreeCAD tool library")


TBL = """\
; tool table of the mill
T1 P1 D6.0 Z+45.0 ;6mm flat end mill

t2 p2 d10 z+60.5 ;10mm Ball Nose
T3 P3 D12.0 Z+70 ;bull nose R1.5
T4 P4 X0 Y0 D8.0 Z-1.25
T5 P5 D3.0 Z+7.5 ;#7 tap drill
T6 P6 D6.0 Z+45 ;6mm flat end mill
"""


def test_linuxcnc_table(tmp_path):
    path = tmp_path / "tool.tbl"
    path.write_text(TBL)
    entries, warnings, numbers = read_linuxcnc_tbl(path)
    assert entries == [
        {"name": "6mm flat end mill T1", "type": "flat", "diameter": 6.0, "flute_length": 18.0,
         "gauge_length": 45.0, "shank_diameter": 6.0},
        {"name": "10mm Ball Nose", "type": "ball", "diameter": 10.0, "flute_length": 30.0,
         "gauge_length": 60.5, "shank_diameter": 10.0},
        {"name": "bull nose R1.5", "type": "bull", "diameter": 12.0, "corner_radius": 1.5,
         "flute_length": 36.0, "gauge_length": 70.0, "shank_diameter": 12.0},
        {"name": "T4", "type": "flat", "diameter": 8.0, "flute_length": 24.0, "gauge_length": 32.0,
         "shank_diameter": 8.0},
        {"name": "#7 tap drill", "type": "flat", "diameter": 3.0, "flute_length": 7.5, "gauge_length": 7.5,
         "shank_diameter": 3.0},
        {"name": "6mm flat end mill T6", "type": "flat", "diameter": 6.0, "flute_length": 18.0,
         "gauge_length": 45.0, "shank_diameter": 6.0},
    ]
    assert warnings[0] == ("T1: LinuxCNC tables give no flute length; taken as 18 mm (3 x D); gauge_length taken "
                           "as the Z offset, 45 mm, with no holder; shank_diameter taken as D")
    assert warnings[3] == ("T4: LinuxCNC tables give no flute length; taken as 24 mm (3 x D); no Z offset of at "
                           "least D; gauge_length taken as 32 mm (4 x D); shank_diameter taken as D; the comment "
                           "names no ball, bull or flat cutter; taken as flat")
    assert "taken as 7.5 mm (the gauge length)" in warnings[4]
    assert len(warnings) == len(entries)
    tools = [_tool(e, i + 1) for i, e in enumerate(entries)]
    assert tools[2].corner_radius == 1.5 and tools[1].corner_radius == 5.0


def test_linuxcnc_table_inch(tmp_path):
    path = tmp_path / "tool.tbl"
    path.write_text("T1 P1 D0.25 Z+2.0 ;1/4 bull R.03\nT2 P2 D0.125 Z+0.1 ;1/8 end mill\n")
    (bull, flat), _, _ = read_linuxcnc_tbl(path, units="inch")
    assert bull["diameter"] == pytest.approx(6.35) and bull["gauge_length"] == pytest.approx(50.8)
    assert bull["corner_radius"] == pytest.approx(0.762) and bull["flute_length"] == pytest.approx(19.05)
    assert flat["diameter"] == pytest.approx(3.175) and flat["gauge_length"] == pytest.approx(12.7)
    _tool(bull), _tool(flat)
    path.write_text("T1 P1 D0.25 ;bull R0.5mm\n")
    assert read_linuxcnc_tbl(path, units="inch")[0][0]["corner_radius"] == 0.5


@pytest.mark.parametrize("text, message", [
    ("T1 P1 Z+40 ;no diameter\n", "line 1: tool T1 needs a diameter D > 0"),
    ("\nT2 P2 D0 Z+40\n", "line 2: tool T2 needs a diameter D > 0"),
    ("T1 P1 D6 K3\n", "line 1: unknown field 'K3'"),
    ("T1 P1 D6\nT1 P2 D8\n", "line 2: tool T1 is listed again (first on line 1)"),
    ("P1 D6\n", "line 1: needs a tool number T1 or above"),
    ("T1 P1 Dsix\n", "line 1: 'Dsix' needs a number after D"),
    ("T1 P1 D6 ;bull nose\n", "line 1: a bull-nose cutter by its comment needs its corner radius"),
    ("; only a comment\n\n", "no tools in this LinuxCNC tool table"),
])
def test_linuxcnc_table_errors(tmp_path, text, message):
    path = tmp_path / "tool.tbl"
    path.write_text(text)
    assert _error(read_linuxcnc_tbl, path).startswith(f"{path}: {message}")


def test_linuxcnc_table_units_and_missing_file(tmp_path):
    assert "units must be 'mm' or 'inch'" in _error(read_linuxcnc_tbl, tmp_path / "tool.tbl", units="cm")
    assert _error(read_linuxcnc_tbl, tmp_path / "tool.tbl") == f"{tmp_path / 'tool.tbl'}: no such LinuxCNC tool table"
