"""3-axis G-code reader."""
import math

import numpy as np
import pytest

from meshmill.errors import InputError
from meshmill.machine.gcode import read_gcode

TOL = 0.001


def read(tmp_path, tools, body, **kw):
    p = tmp_path / "p.nc"
    p.write_text(body)
    return read_gcode(p, tools, **kw)


def sagittas(tip, centre, r):
    """Chord deviation of each segment of an arc of radius r about ``centre`` (XY)."""
    chord = np.linalg.norm(np.diff(tip[:, :2], axis=0), axis=1)
    return r - np.sqrt(r * r - 0.25 * chord * chord)


def check_arc(tip, centre, r, end):
    np.testing.assert_allclose(np.linalg.norm(tip[:, :2] - centre, axis=1), r, rtol=0, atol=1e-9)
    assert sagittas(tip, centre, r).max() <= TOL + 1e-12
    assert tuple(tip[-1]) == tuple(end)


def swept(tip, centre):
    """Signed angle swept along the points (counter-clockwise positive)."""
    a = np.unwrap(np.arctan2(tip[:, 1] - centre[1], tip[:, 0] - centre[0]))
    return a[-1] - a[0]


def test_square(tmp_path, tools):
    tp, warnings = read(tmp_path, tools, "T1 M6\nG0 X0 Y0 Z5\nG1 Z-1\nG1 X10\nG1 Y10\nG1 X0\nG1 Y0\nG0 Z5\n")
    assert not warnings
    np.testing.assert_array_equal(tp.tip, [[0, 0, 5], [0, 0, -1], [10, 0, -1], [10, 10, -1], [0, 10, -1],
                                           [0, 0, -1], [0, 0, 5]])
    assert list(tp.rapid) == [True, False, False, False, False, False, True]
    assert (tp.axis == [0, 0, 1]).all() and (tp.tool == 0).all()
    assert list(tp.line) == [2, 3, 4, 5, 6, 7, 8]


def test_modal_motion(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X0 Y0 Z5\nX1\nG1 Z0\nX2\nY3 F200\n")
    np.testing.assert_array_equal(tp.tip, [[0, 0, 5], [1, 0, 5], [1, 0, 0], [2, 0, 0], [2, 3, 0]])
    assert list(tp.rapid) == [True, True, False, False, False]


def test_incremental(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X1 Y2 Z3\nG91 G1 X1\nY-2 Z0.5\nG90 X0\n")
    np.testing.assert_allclose(tp.tip, [[1, 2, 3], [2, 2, 3], [2, 0, 3.5], [0, 0, 3.5]])


def test_inch(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG20 G0 X1 Y2 Z0.5\nG2 X1 Y0 I-0.5 J-1\nG21 G1 X0\n")
    np.testing.assert_allclose(tp.tip[0], [25.4, 50.8, 12.7])
    check_arc(tp.tip[1:-1], np.array([12.7, 25.4]), 0.5 * math.hypot(25.4, 50.8), tuple(tp.tip[-2]))
    np.testing.assert_allclose(tp.tip[-2], [25.4, 0, 12.7])
    np.testing.assert_array_equal(tp.tip[-1], [0, 0, 12.7])


@pytest.mark.parametrize("arc", ["G2 X10 Y0 I-10 J0", "G2 I-10"])
def test_full_circle(tmp_path, tools, arc):
    tp, _ = read(tmp_path, tools, f"T1\nG0 X10 Y0 Z0\n{arc}\n", chord_tol=TOL)
    check_arc(tp.tip, np.zeros(2), 10.0, (10.0, 0.0, 0.0))
    assert swept(tp.tip, np.zeros(2)) == pytest.approx(-2 * math.pi)
    assert (tp.tip[:, 2] == 0).all() and tp.rapid[0] and not tp.rapid[1:].any() and (tp.line[1:] == 3).all()


@pytest.mark.parametrize("arc", ["G3 X0 Y10 I-10 J0", "G90.1 G3 X0 Y10 I0 J0", "G3 X0 Y10 I-10"])
def test_quarter_arc(tmp_path, tools, arc):
    tp, _ = read(tmp_path, tools, f"T1\nG0 X10 Y0 Z0\n{arc}\n", chord_tol=TOL)
    check_arc(tp.tip, np.zeros(2), 10.0, (0.0, 10.0, 0.0))
    assert swept(tp.tip, np.zeros(2)) == pytest.approx(0.5 * math.pi)


@pytest.mark.parametrize("arc, centre, sweep", [
    ("G3 X0 Y10 R10", (0, 0), 0.5 * math.pi),
    ("G3 X0 Y10 R-10", (10, 10), 1.5 * math.pi),
    ("G2 X0 Y10 R10", (10, 10), -0.5 * math.pi),
    ("G2 X0 Y10 R-10", (0, 0), -1.5 * math.pi),
])
def test_radius_arcs(tmp_path, tools, arc, centre, sweep):
    tp, _ = read(tmp_path, tools, f"T1\nG0 X10 Y0 Z0\n{arc}\n", chord_tol=TOL)
    check_arc(tp.tip, np.array(centre, float), 10.0, (0.0, 10.0, 0.0))
    assert swept(tp.tip, np.array(centre, float)) == pytest.approx(sweep)


def test_helix(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X10 Y0 Z0\nG3 X10 Y0 Z-2 I-10 J0\n", chord_tol=TOL)
    check_arc(tp.tip, np.zeros(2), 10.0, (10.0, 0.0, -2.0))
    a = np.unwrap(np.arctan2(tp.tip[:, 1], tp.tip[:, 0]))
    np.testing.assert_allclose(tp.tip[:, 2], -2 * (a - a[0]) / (2 * math.pi), atol=1e-9)


def test_tool_selection(tmp_path, tools):
    body = "T2 M6\nG0 X0 Y0 Z5\nT3\nM6\nG1 Z0\n"
    tp, warnings = read(tmp_path, tools, body)
    assert list(tp.tool) == [1, 2] and not warnings
    tp, warnings = read(tmp_path, tools, body, tool_name="B20")
    assert list(tp.tool) == [1, 2] and "T words" in warnings[0]
    tp, _ = read(tmp_path, tools, "G0 X0 Y0 Z5\n", tool_name="B6")
    assert list(tp.tool) == [2]
    tp, _ = read(tmp_path, tools[:1], "G0 X0 Y0 Z5\n")
    assert list(tp.tool) == [0]


@pytest.mark.parametrize("body, kw, message", [
    ("T9 M6\nG0 X0 Y0 Z5\n", {}, "p.nc:1: T9 is not a tool"),
    ("G0 X0 Y0 Z5\n", {}, "names no tool"),
    ("G0 X0 Y0 Z5\n", {"tool_name": "B99"}, "no tool named 'B99'"),
    ("G0 X0 Y0 Z5\nT1\nG1 Z0\n", {}, "p.nc:1: move before the first T word"),
])
def test_tool_selection_errors(tmp_path, tools, body, kw, message):
    with pytest.raises(InputError, match=message):
        read(tmp_path, tools, body, **kw)


@pytest.mark.parametrize("body, message", [
    ("G18\n", "p.nc:2: G18"),
    ("G19 G2 X0 Y0 Z0 I1\n", "p.nc:2: G19"),
    ("G41 D1\n", "p.nc:2: G41: cutter radius compensation"),
    ("G42\n", "p.nc:2: G42"),
    ("G81 X0 Y0 Z-3 R2\n", "p.nc:2: G81: canned cycles"),
    ("G83 X0 Y0 Z-3 R2 Q1\n", "p.nc:2: G83: canned cycles"),
    ("G28 Z0\n", "p.nc:2: G28: .*machine coordinates"),
    ("G53 G0 Z0\n", "p.nc:2: G53: .*machine coordinates"),
    ("G92 X0\n", "p.nc:2: unknown G code G92"),
    ("G0 X1.2.3 Y0 Z0\n", "p.nc:2: malformed number"),
    ("G0 Xabc\n", "p.nc:2: malformed number"),
    ("G0 X0 Y0 Z nan\n", "p.nc:2: NaN"),
    ("G0 X2000000 Y0 Z0\n", "p.nc:2: X 2e\\+06 is out of range"),
    ("G20 G0 X50000 Y0 Z0\n", "p.nc:2: X 1.27e\\+06 is out of range"),
    ("G0 X0 Y0\n", "no moves"),
    ("G91 G0 X0 Y0 Z5\n", "no moves"),
    ("G2 X0 Y0 Z0 I1\n", "p.nc:2: an arc cannot be the first move"),
    ("X0 Y0 Z0\n", "p.nc:2: coordinates without G0"),
    ("G0 X0 Y0 Z0\nG2 X5 Y0 I1\n", "p.nc:3: .*not on its circle"),
    ("G0 X0 Y0 Z0\nG2 X5 Y0 R1\n", "p.nc:3: R1 is too small"),
    ("G0 X0 Y0 Z0\nG2 X0 Y0 R1\n", "p.nc:3: an R arc cannot be a full circle"),
    ("G0 X0 Y0 Z0\nG2 X5 Y0\n", "p.nc:3: an arc needs I/J or R"),
    ("G0 X0 Y0 Z0 A90\n", "p.nc:2: unsupported word A90"),
    # words of cycles and calls on a move: refused like other unsupported words
    ("G0 X0 Y0 Z0\nG1 X5 Q2\n", "p.nc:3: unsupported word Q2"),
    ("G0 X0 Y0 Z0\nG1 X5 P1\n", "p.nc:3: unsupported word P1"),
    ("G0 X0 Y0 Z0\nG1 X5 K1\n", "p.nc:3: unsupported word K1"),
    ("G0 X0 Y0 Z0\nM98 P100\n", "p.nc:3: unsupported word P100"),
    ("G0 X0 X1 Y0 Z0\n", "p.nc:2: X given twice"),
    ("G0 G1 X0 Y0 Z0\n", "p.nc:2: two motion codes"),
    ("G0 X0 Y0 Z0 (open\n", "p.nc:2: unbalanced parenthesis"),
    ("G21 G90\nM30\n", "no moves"),
    ("G0 X0 Y0 Z0\nG93 G1 X5 F100\nX10\n", "p.nc:4: G1 in inverse-time mode \\(G93\\) without F"),
    ("G0 X0 Y0 Z0\nG93 G1 X5 F100\nG0 Z5\nG2 X15 Z5 I5\n", "p.nc:5: G2 in inverse-time mode"),
])
def test_bad_gcode(tmp_path, tools, body, message):
    with pytest.raises(InputError, match=message):
        read(tmp_path, tools, "T1\n" + body)


@pytest.mark.parametrize("content, message", [
    (None, "no such G-code file"),
    ("folder", "cannot read"),
    (b"\xff\xfe\x00G0", "not a text G-code file"),
    (b"G0 X0\x00", "not a text G-code file"),
    (b"  \n\n", "empty G-code file"),
])
def test_bad_files(tmp_path, tools, content, message):
    p = tmp_path / "p.nc"
    if content == "folder":
        p.mkdir()
    elif content is not None:
        p.write_bytes(content)
    with pytest.raises(InputError, match=message):
        read_gcode(p, tools)


def test_comments_line_numbers_and_ignored_codes(tmp_path, tools):
    body = ("%\nO1000 (program 1000)\nN10 G21 (mm) G90 G17 G40 G49 G80 G94 G64 ; absolute\n"
            "N20 T1 M6 S12000 M3 (SPINDLE; ON)\nN30 G54 G43 H1 g0 x1 y2 z3 F500 ; rapid\n"
            "N40 G4 P1.5\nN50 G61 G1 X 4 . 5 M8\nM30\n%\n")
    tp, warnings = read(tmp_path, tools, body)
    np.testing.assert_array_equal(tp.tip, [[1, 2, 3], [4.5, 2, 3]])
    assert list(tp.line) == [5, 7] and list(tp.rapid) == [True, False]
    assert len(warnings) == 1 and "G54" in warnings[0] and "not applied" in warnings[0]


def test_chord_tol_must_be_positive(tmp_path, tools):
    with pytest.raises(InputError, match="chord_tol"):
        read(tmp_path, tools, "T1\nG0 X0 Y0 Z0\n", chord_tol=0.0)


def test_inverse_time_blocks_each_with_f(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X0 Y0 Z0\nG93 G1 X5 F100\nX10 F50\nG0 Z5\nG94 G1 X0\n")
    assert len(tp) == 5 and tp.tip[-1].tolist() == [0.0, 0.0, 5.0]


def test_dwell_does_not_move(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X0 Y0 Z5\nG4 X2\nG1 Z0\n")
    np.testing.assert_array_equal(tp.tip, [[0, 0, 5], [0, 0, 0]])


def test_start_known_once_x_y_and_z_are_given(tmp_path, tools):
    from meshmill.machine.gcode import read_gcode

    (tmp_path / "p.nc").write_text("G21 G90\nT1 M6\nG0 Z5\nG0 X1 Y2\nG1 Z-1\nG1 X4\n")
    tp, _ = read_gcode(tmp_path / "p.nc", tools)
    np.testing.assert_allclose(tp.tip, [[1, 2, 5], [1, 2, -1], [4, 2, -1]])
    assert list(tp.rapid) == [True, False, False] and list(tp.line) == [4, 5, 6]
