"""Tool tables and APT CL files."""
import numpy as np
import pytest

from meshmill.errors import InputError
from meshmill.toolpath.cldata import read_apt, write_apt
from meshmill.toolpath.model import Toolpath
from meshmill.tools.table import Tool, load_tools


def test_tool_table_defaults(tools):
    b10 = tools[1]
    assert b10.number == 2 and b10.corner_radius == 5.0 and b10.shank_diameter == 10.0
    assert tools[3].shank_diameter == 6.0 and tools[3].holder_length == 40.0
    kinds = [c[3] for c in tools[0].cylinders()]
    assert kinds == [True, False, False]  # flutes, shank, holder


def _surface_points(tool, n=120):
    """Points (p, 3) on the tool's surface with its tip at 0 and its axis +Z: the rims of every
    cylinder and the spheres of the rounded end, densely (brute-force reference)."""
    phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    ring = np.column_stack([np.cos(phi), np.sin(phi), np.zeros(n)])
    points = []
    for t0, t1, radius, _ in tool.cylinders():
        for t in (t0, t1):
            points.append(radius * ring + [0.0, 0.0, t])
    t, rho, r, _ = tool.ring()
    if r > 0:
        u, v = np.meshgrid(phi, np.linspace(0.0, np.pi, n // 2))
        sphere = r * np.column_stack([(np.sin(v) * np.cos(u)).ravel(), (np.sin(v) * np.sin(u)).ravel(), np.cos(v).ravel()])
        for centre in rho * ring[:: max(1, n // 24)] + [0.0, 0.0, t]:
            points.append(sphere + centre)
    return np.concatenate(points)


@pytest.mark.parametrize("index", [0, 1, 2, 3, 4])
def test_lowest_z_of_the_tool_is_its_lowest_surface_point(tools, index):
    shapes = [*tools[:3], Tool("F8", "flat", 8.0, 0.0, 15.0, 40.0, 8.0, 30.0, 35.0),
              Tool("R10", "bull", 10.0, 2.0, 15.0, 40.0, 8.0, 30.0, 35.0)]
    tool = shapes[index]
    body = _surface_points(tool)
    rng = np.random.default_rng(index)
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        tip = rng.uniform(-50, 50, 3)
        # a rotation taking +Z to axis
        z = np.array([0.0, 0.0, 1.0])
        v, c = np.cross(z, axis), float(axis[2])
        k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        rot = np.eye(3) + k + k @ k / (1.0 + c)
        brute = (body @ rot.T + tip)[:, 2].min()
        low = tool.lowest_z(tip, axis)[0]
        assert low <= brute + 1e-9 and brute - low < 0.02 * tool.reach


@pytest.mark.parametrize("body, message", [
    ("", "no \\[\\[tools\\]\\]"),
    ("[[tools]]\nname='x'\ntype='drill'\ndiameter=3\nflute_length=5\ngauge_length=9\n", "type"),
    ("[[tools]]\ntype='ball'\ndiameter=-3\nflute_length=5\ngauge_length=9\n", "diameter"),
    ("[[tools]]\ntype='ball'\ndiameter=6\ncorner_radius=2\nflute_length=5\ngauge_length=9\n", "corner_radius"),
    ("[[tools]]\ntype='bull'\ndiameter=6\nflute_length=5\ngauge_length=9\n", "corner_radius"),
    ("[[tools]]\ntype='ball'\ndiameter=6\nflute_length=5\n", "gauge_length"),
    ("[[tools]]\ntype='ball'\ndiameter=6\nflute_length=10\ngauge_length=5\n", "gauge_length"),
    ("[[tools]]\ntype='ball'\ndiameter='six'\nflute_length=10\ngauge_length=5\n", "number"),
    ("[[tools\n", "not a valid TOML"),
    ("[[tools]]\ntype='ball'\ndiameter=6\nflute_length=10\ngauge_length=20\nrpm=-5\n", "rpm"),
    # a misspelt key would drop the holder: refused, with the key and the tool named
    ("[[tools]]\nname='B6'\ntype='ball'\ndiameter=6\nflute_length=10\ngauge_length=20\nholder_diamter=32\n"
     "holder_length=40\n", "tool 1 \\('B6'\\): unknown key 'holder_diamter'"),
])
def test_bad_tool_tables(tmp_path, body, message):
    p = tmp_path / "t.toml"
    p.write_text(body)
    with pytest.raises(InputError, match=message):
        load_tools(p)


def test_cl_round_trip(tmp_path, tools):
    rng = np.random.default_rng(1)
    axis = rng.normal(size=(6, 3))
    axis[:, 2] = np.abs(axis[:, 2])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    tp = Toolpath(rng.uniform(-50, 50, (6, 3)), axis, np.array([1, 0, 0, 1, 0, 0], bool), np.array([0, 0, 0, 2, 2, 2]))
    write_apt(tmp_path / "p.cl", tp, tools)
    text = (tmp_path / "p.cl").read_text().splitlines()
    assert text[-1] == "FINI" and "CUTTER/20.000000, 10.000000" in text and "LOADTL/3" in text
    back, warnings = read_apt(tmp_path / "p.cl", tools)
    assert not warnings
    np.testing.assert_allclose(back.tip, tp.tip, atol=1e-6)
    np.testing.assert_allclose(back.axis, tp.axis, atol=1e-8)
    assert (back.rapid == tp.rapid).all() and (back.tool == tp.tool).all()


def test_cl_from_another_cam_system(tmp_path, tools):
    (tmp_path / "cam.cl").write_text(
        "$$ made elsewhere\nPARTNO/TEST\nCUTTER/10, 5\nFEDRAT/1200\nROTABL/90\nRAPID\nGOTO/0, 0, 50\n"
        "GOTO/1.0, 2.0, $\n 3.0\nGOTO/1, 2, 3, 0, 0, 2\nFINI\n")
    tp, warnings = read_apt(tmp_path / "cam.cl", tools)
    assert len(tp) == 3 and (tp.tool == 1).all() and list(tp.rapid) == [True, False, False]
    np.testing.assert_allclose(tp.tip[1], [1, 2, 3])
    np.testing.assert_allclose(tp.axis[2], [0, 0, 1])
    assert tp.line[1] == 8 and any("ROTABL" in w for w in warnings)


@pytest.mark.parametrize("body, message", [
    ("GOTO/1,2,3\n", "before any CUTTER"),
    ("CUTTER/7, 0\nGOTO/1,2,3\n", "matches no tool"),
    ("LOADTL/9\n", "not a tool of the table"),
    ("LOADTL/1\nGOTO/1,2\n", "GOTO needs"),
    ("LOADTL/1\nGOTO/1,2,nan\n", "NaN"),
    ("LOADTL/1\nGOTO/1,2,x\n", "expected numbers"),
    ("LOADTL/1\nGOTO/0,0,1,0,0,0\n", "bad.cl:2: zero-length tool axis"),
    ("GOTO/1, 2, 3, 0, 0, 0\n", "bad.cl:1: GOTO before any CUTTER"),
    ("CUTTER/7\nGOTO/1,2,3,0,0,0\n", "bad.cl:2: CUTTER/7, 0 matches no tool"),
    ("LOADTL/1\nGOTO/0,0,1\nGOTO/0,0,1e9\n", "bad.cl:3: value 1e\\+09 is out of range"),
    # the GOTOs' numbers are read at the end, all at once: a bad one still comes before a later error
    ("LOADTL/1\nGOTO/0,0,1\nGOTO/1,2,x\nGOTO/0,0,2\nWHATEVER/1\n", "bad.cl:3: expected numbers"),
    ("LOADTL/1\nGOTO/0,0,1\nGOTO/1,2,3,4\nWHATEVER/1\n", "bad.cl:3: GOTO needs"),
    ("PARTNO/X\nFINI\n", "no GOTO"),
    # what looks like a move but is not one, and statements that change the moves, are refused
    ("LOADTL/1\nGOTO/0,0,50\nGOTO 0, 0, 15, 0, 0, 1\n", "bad.cl:3: cannot read 'GOTO 0, 0, 15"),
    ("LOADTL/1\nGOTO/0,0,50\nG0TO/0,0,15\n", "bad.cl:3: unknown statement 'G0TO'"),
    ("LOADTL/1\nGOTO/0,0,50\nhello there\n", "bad.cl:3: cannot read"),
    ("LOADTL/1\nGOTO/0,0,50\nWHATEVER/1\n", "bad.cl:3: unknown statement 'WHATEVER'"),
    ("LOADTL/1\nCIRCLE/0,0,0,0,0,1,5\nGOTO/5,0,0\n", "bad.cl:2: CIRCLE"),
    ("LOADTL/1\nGODLTA/0,0,-5\n", "GODLTA"),
    ("UNITS/FEET\nLOADTL/1\nGOTO/0,0,1\n", "UNITS/FEET"),
])
def test_bad_cl_files(tmp_path, tools, body, message):
    (tmp_path / "bad.cl").write_text(body)
    with pytest.raises(InputError, match=message):
        read_apt(tmp_path / "bad.cl", tools)


def test_gotos_of_three_and_six_numbers_with_spaces_and_a_trailing_comma(tmp_path, tools):
    (tmp_path / "g.cl").write_text("LOADTL/1\nGOTO / 1, 2 ,3\nGOTO/4,5,6, 0,3,4\nRAPID\nGOTO/7,8,9,\n"
                                   "UNITS/INCHES\nGOTO/1,0,0,0,0,2\nFINI\n")
    tp, _ = read_apt(tmp_path / "g.cl", tools)
    np.testing.assert_array_equal(tp.tip, [[1, 2, 3], [4, 5, 6], [7, 8, 9], [25.4, 0, 0]])
    np.testing.assert_array_equal(tp.axis, [[0, 0, 1], [0, 0.6, 0.8], [0, 0, 1], [0, 0, 1]])
    assert list(tp.rapid) == [False, False, True, False] and list(tp.line) == [2, 3, 5, 7]


def test_cl_in_inches_is_read_in_mm(tmp_path, tools):
    (tmp_path / "in.cl").write_text("UNITS/INCHES\nCUTTER/0.787402, 0.393701\nGOTO/1, 2, 0.5, 0, 0, 1\n"
                                    "UNITS/MM\nGOTO/1, 2, 3\nFINI\n")
    tp, _ = read_apt(tmp_path / "in.cl", tools)
    np.testing.assert_allclose(tp.tip, [[25.4, 50.8, 12.7], [1, 2, 3]])
    assert (tp.tool == 0).all()  # CUTTER/0.787402, 0.393701 (inches): the 20 mm ball
