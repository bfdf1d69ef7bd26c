"""5-axis G-code read through the machine's kinematics, and round trips through the post-processor."""
import dataclasses
import math

import numpy as np
import pytest
import trimesh

from meshmill.cli import main
from meshmill.errors import InputError
from meshmill.geometry.shapes import box
from meshmill.machine.config import load_machine
from meshmill.machine.kinematics import forward
from meshmill.machine.post import post_program
from meshmill.machine.pathfile import read_toolpath
from meshmill.toolpath.cldata import write_apt
from meshmill.machine.gcode import read_gcode
from meshmill.toolpath.model import Toolpath

CHORD = 0.001  # mm, the reader's chord_tol
POST_TOL = 0.005  # mm, the post-processor's linearisation tolerance
FIVE_AXIS = ("table-table-ac", "head-table-bc", "head-head-ca")


def read(tmp_path, tools, body, machine=None, **kw):
    p = tmp_path / "p.nc"
    p.write_text(body)
    return read_gcode(p, tools, machine=None if machine is None else load_machine(machine), **kw)


def tool_length(machine, tool):
    """The head-table program's tool length (tip to gauge line), mm; 0 where forward ignores it."""
    return tool.spindle_length if machine.chain.head_pivot else 0.0


def with_tcp(machine, text="G43.4 H{number}"):
    return dataclasses.replace(machine, gcode=dataclasses.replace(machine.gcode, tcp=text))


def segment_distances(points, polyline):
    """Distance (p,) of ``points (p, 3)`` from the polyline ``(q, 3)``, the segment (p,) each is
    nearest and the fraction (p,) along it."""
    a, d = polyline[:-1], np.diff(polyline, axis=0)
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    t = np.clip(np.einsum("pij,ij->pi", points[:, None] - a[None], d) / dd, 0.0, 1.0)
    dist = np.linalg.norm(a[None] + t[..., None] * d[None] - points[:, None], axis=2)
    seg = dist.argmin(axis=1)
    rows = np.arange(len(points))
    return dist[rows, seg], seg, t[rows, seg]


def great_circle(a0, a1, s):
    """Unit axes (m, 3) at fractions ``s (m,)`` of the great circles from ``a0`` to ``a1`` (m, 3)."""
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", a0, a1), -1.0, 1.0))[:, None]
    s = s[:, None]
    sin = np.where(angle > 1e-9, np.sin(angle), 1.0)
    w0 = np.where(angle > 1e-9, np.sin((1 - s) * angle) / sin, 1 - s)
    w1 = np.where(angle > 1e-9, np.sin(s * angle) / sin, s)
    out = w0 * a0 + w1 * a1
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def angles_deg(a, b):
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))


def joint_motion_tips(machine, j0, j1, length, samples):
    """Tips (samples, 3) at equal steps of the joints moving linearly from ``j0`` to ``j1`` (n,)."""
    s = np.linspace(0.0, 1.0, samples)[:, None]
    return forward(machine, j0 + s * (j1 - j0), length)[0]


# --- hand-written programs --------------------------------------------------------------------


@pytest.mark.parametrize("name, start", [("table-table-ac", "X40 Y0 Z10 A-30 C0"),
                                         ("head-table-bc", "X40 Y0 Z200 B30 C0")])
def test_pure_c_turn_traces_an_arc_about_the_c_axis(tmp_path, tools, name, start):
    tp, warnings = read(tmp_path, tools, f"T1 M6\nG0 {start}\nG1 C90 F1000\n", name, chord_tol=CHORD)
    machine = load_machine(name)
    length = tool_length(machine, tools[0])
    j0 = np.array([float(w[1:]) for w in start.split()])
    j1 = j0.copy()
    j1[4] = 90.0
    ends, end_axes = forward(machine, np.stack([j0, j1]), length)
    assert not warnings and list(tp.line[:1]) == [2] and (tp.line[1:] == 3).all()
    np.testing.assert_allclose(tp.tip[[0, -1]], ends, atol=1e-12)
    np.testing.assert_allclose(tp.axis[[0, -1]], end_axes, atol=1e-12)
    # the table turns under the tool: the tip circles the C axis (work Z through the origin) by 90 deg
    radius = np.hypot(tp.tip[:, 0], tp.tip[:, 1])
    np.testing.assert_allclose(radius, radius[0], atol=1e-9)
    np.testing.assert_allclose(tp.tip[:, 2], tp.tip[0, 2], atol=1e-9)
    swept = np.unwrap(np.arctan2(tp.tip[:, 1], tp.tip[:, 0]))
    assert abs(swept[-1] - swept[0]) == pytest.approx(0.5 * math.pi)
    assert np.all(np.diff(swept) * np.sign(swept[-1] - swept[0]) > 0)
    chord = np.linalg.norm(np.diff(tp.tip[:, :2], axis=0), axis=1)
    sagitta = radius[0] - np.sqrt(radius[0] ** 2 - 0.25 * chord ** 2)
    assert sagitta.max() <= CHORD and len(tp) > 3
    # the axis keeps its 30 deg tilt all the way round
    np.testing.assert_allclose(np.degrees(np.arccos(tp.axis[:, 2])), 30.0, atol=1e-9)


@pytest.mark.parametrize("name", FIVE_AXIS)
def test_joint_linear_move_is_followed_within_chord_tol(tmp_path, tools, name):
    """Every point of the true motion (joints linear) is within chord_tol of the read pieces, and the
    pieces' ends are on it."""
    machine = load_machine(name)
    tilt = machine.chain.rotary[0]
    sign = -1 if name == "table-table-ac" else 1
    j0 = np.array([-20.0, 15.0, 30.0, 5.0 * sign, 10.0])
    j1 = np.array([35.0, -10.0, 20.0, 55.0 * sign, -200.0])
    body = (f"T2 M6\nG0 X{j0[0]} Y{j0[1]} Z{j0[2]} {tilt}{j0[3]} C{j0[4]}\n"
            f"G93 G1 X{j1[0]} Y{j1[1]} Z{j1[2]} {tilt}{j1[3]} C{j1[4]} F10\nG94\n")
    tp, _ = read(tmp_path, tools, body, name, chord_tol=CHORD)
    length = tool_length(machine, tools[1])
    assert segment_distances(joint_motion_tips(machine, j0, j1, length, 5001), tp.tip)[0].max() <= CHORD
    # the pieces end on the motion, at equal steps of the joints
    np.testing.assert_allclose(tp.tip, joint_motion_tips(machine, j0, j1, length, len(tp)), atol=1e-9)
    assert (tp.tool == 1).all() and tp.rapid[0] and not tp.rapid[1:].any()


def test_axis_turning_about_a_still_tip_is_split(tmp_path, tools):
    """The tip on the C axis stays; the tool swings round a cone, split so that the point
    ``reach`` up the tool stays within chord_tol of the pieces."""
    y, z = 10 * math.sin(math.radians(30)), 10 * math.cos(math.radians(30))  # the tip (0, 0, 10) tilted by A-30
    tp, _ = read(tmp_path, tools, f"T1\nG0 X0 Y{y!r} Z{z!r} A-30 C0\nG1 C360\n", "table-table-ac", chord_tol=CHORD)
    np.testing.assert_allclose(tp.tip, np.tile([0, 0, 10], (len(tp), 1)), atol=1e-9)
    top = tp.tip + tools[0].reach * tp.axis
    radius = tools[0].reach * math.sin(math.radians(30))
    chord = np.linalg.norm(np.diff(top, axis=0), axis=1)
    assert (radius - np.sqrt(radius ** 2 - 0.25 * chord ** 2)).max() <= CHORD
    assert np.ptp(np.unwrap(np.arctan2(tp.axis[:, 1], tp.axis[:, 0]))) == pytest.approx(2 * math.pi)


def test_rapid_rotary_move_is_split_too(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X50 Y0 Z10 A-20 C0\nC180\n", "table-table-ac")
    assert len(tp) > 10 and tp.rapid.all()


def test_head_table_tip_depends_on_the_tool(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X0 Y0 Z300 B0 C0\nT2\nZ300.0001\n", "head-table-bc")
    lengths = [t.spindle_length for t in tools[:2]]
    np.testing.assert_allclose(tp.tip[:, 2], [300 - 150 - lengths[0], 300.0001 - 150 - lengths[1]])



def test_modal_and_incremental_rotary_words(tmp_path, tools):
    body = "T1\nG0 X10 Y0 Z20 A-20 C10\nG1 X15\nC30\nG91 C-5 A-5\nG90 Y3\n"
    tp, _ = read(tmp_path, tools, body, "table-table-ac")
    expected = np.array([[10, 0, 20, -20, 10], [15, 0, 20, -20, 10], [15, 0, 20, -20, 30], [15, 0, 20, -25, 25],
                         [15, 3, 20, -25, 25]], float)
    tips, axes = forward(load_machine("table-table-ac"), expected)
    last = [int(np.flatnonzero(tp.line == n)[-1]) for n in range(2, 7)]
    np.testing.assert_allclose(tp.tip[last], tips, atol=1e-12)
    np.testing.assert_allclose(tp.axis[last], axes, atol=1e-12)
    assert list(np.unique(tp.line)) == [2, 3, 4, 5, 6]


def test_path_starts_once_every_axis_is_given(tmp_path, tools):
    tp, _ = read(tmp_path, tools, "T1\nG0 X0 Y0 Z50\nG0 A-10\nG0 C5\nG1 X1\n", "table-table-ac")
    assert list(tp.line) == [4, 5]
    with pytest.raises(InputError, match="no moves .*never: A, C"):
        read(tmp_path, tools, "T1\nG0 X0 Y0 Z50\nG1 X1\n", "table-table-ac")


def test_arc_with_rotaries_held(tmp_path, tools):
    machine = load_machine("head-table-bc")
    tp, _ = read(tmp_path, tools, "T1\nG0 X10 Y0 Z200 B20 C30\nG3 X0 Y10 I-10 J0\n", "head-table-bc",
                 chord_tol=CHORD)
    xy = np.array([[10, 0]] + [[10 * math.cos(a), 10 * math.sin(a)] for a in np.linspace(0, 0.5 * math.pi, 50)])
    joints = np.column_stack([xy, np.full(len(xy), 200.0), np.full(len(xy), 20.0), np.full(len(xy), 30.0)])
    dense = forward(machine, joints, tool_length(machine, tools[0]))[0]
    assert segment_distances(dense, tp.tip)[0].max() <= CHORD + 1e-9
    assert (tp.axis == tp.axis[0]).all()


@pytest.mark.parametrize("name", FIVE_AXIS)
@pytest.mark.parametrize("switch", ["G43.4 H1", "G43.5 H1"])
def test_tcp_tips_as_given(tmp_path, tools, name, switch):
    machine = load_machine(name)
    tilt = machine.chain.rotary[0]
    body = (f"T1 M6\n{switch}\nG0 X10 Y5 Z20 {tilt}-30 C0\nG1 X12 C90\n{tilt}-10\nG1 Z15 C-200\nG49\n"
            "G91 G28 Z0\nG90\nM30\n")
    tp, warnings = read(tmp_path, tools, body, name)
    joints = np.array([[10, 5, 20, -30, 0], [12, 5, 20, -30, 90], [12, 5, 20, -10, 90], [12, 5, 15, -10, -200]], float)
    tips, axes = forward(machine, joints, tcp=True)
    np.testing.assert_array_equal(tp.tip, tips)
    np.testing.assert_allclose(tp.axis, axes, atol=1e-15)
    np.testing.assert_array_equal(tp.tip, joints[:, :3])
    assert list(tp.line) == [3, 4, 5, 6]
    assert warnings == ["p.nc:8: G28 Z0 (a retract in machine coordinates) is not in the tool path"]


def test_the_machines_own_tcp_code(tmp_path, tools):
    machine = with_tcp(load_machine("table-table-ac"), "G234 H{number}")  # a Haas-like TCPC code
    (tmp_path / "p.nc").write_text("T1\nG234 H1\nG0 X10 Y5 Z20 A-30 C45\nG1 C90\n")
    tp, _ = read_gcode(tmp_path / "p.nc", tools, machine=machine)
    np.testing.assert_array_equal(tp.tip, [[10, 5, 20], [10, 5, 20]])
    with pytest.raises(InputError, match="p.nc:2: unknown G code G234"):
        read(tmp_path, tools, "T1\nG234 H1\nG0 X10 Y5 Z20 A-30 C45\n", "table-table-ac")


@pytest.mark.parametrize("name", FIVE_AXIS)
def test_tcp_switch_leaves_the_machine_where_it_is(tmp_path, tools, name):
    """X Y Z not given after a switch keep the pose: the words are converted to the new mode."""
    machine = load_machine(name)
    tilt = machine.chain.rotary[0]
    z = 10 if name == "table-table-ac" else 200
    body = (f"T1\nG0 X30 Y-5 Z{z} {tilt}-25 C40\nG43.4 H1\nG1 X31\nG49\nG1 C40\nG43.4 H1\nG1 Y-4\nG43 H1\n"
            "C40\n")
    tp, _ = read(tmp_path, tools, body, name)
    before = forward(machine, np.array([[30, -5, z, -25, 40]], float), tool_length(machine, tools[0]))[0][0]
    assert list(tp.line) == [2, 4, 6, 8, 10]
    np.testing.assert_allclose(tp.tip[0], before, atol=1e-12)
    np.testing.assert_allclose(tp.tip[1], [31, before[1], before[2]], atol=1e-9)
    np.testing.assert_allclose(tp.tip[2], tp.tip[1], atol=1e-9)  # off again (G49): the same place
    np.testing.assert_allclose(tp.tip[3], [31, -4, before[2]], atol=1e-9)
    np.testing.assert_allclose(tp.tip[4], tp.tip[3], atol=1e-9)  # off again (G43)


@pytest.mark.parametrize("end", ["G91 G28 Z0\nG90\nM30\n", "G53 G0 Z0\nM2\n", "G28 Z-1\n"])
@pytest.mark.parametrize("name", [None, "generic-3axis", "table-table-ac"])
def test_final_retract_in_machine_coordinates(tmp_path, tools, end, name):
    rotaries = " A0 C0" if name == "table-table-ac" else ""
    tp, warnings = read(tmp_path, tools, f"T1\nG0 X0 Y0 Z5{rotaries}\nG1 Z-1\n{end}", name)
    assert len(tp) == 2 and len(warnings) == 1
    assert warnings[0].startswith("p.nc:4: G") and "not in the tool path" in warnings[0]


@pytest.mark.parametrize("name, body, message", [
    (None, "G0 X0 Y0 Z0 A90\n", "p.nc:2: unsupported word A90: .*give the machine \\(machine,"),
    (None, "G0 X0 Y0 Z0\nG1 C10\n", "p.nc:3: unsupported word C10: .*give the machine \\(machine,"),
    ("generic-3axis", "G0 X0 Y0 Z0 B5\n", "p.nc:2: unsupported word B5: .*3-axis machine"),
    ("table-table-ac", "G0 X0 Y0 Z0 A0 C0\nG1 B10\n", "p.nc:3: unsupported word B10: .*no B axis .*A, C"),
    ("head-table-bc", "G0 X0 Y0 Z0 A10 C0\n", "p.nc:2: unsupported word A10: .*no A axis .*B, C"),
    (None, "G43.4 H1\n", "p.nc:2: G43.4 .*needs a 5-axis machine"),
    ("grbl-3axis", "G43.5\n", "p.nc:2: G43.5 .*needs a 5-axis machine"),
    ("table-table-ac", "G0 X10 Y0 Z0 A-10 C0\nG2 X0 Y10 I-10 C30\n",
     "p.nc:3: an arc cannot turn a rotary axis \\(C\\)"),
    ("table-table-ac", "G0 X10 Y0 Z0 A-10 C0\nG1 A10000000\n", "p.nc:3: A 1e\\+07 is out of range .*degrees"),
    ("table-table-ac", "G0 X0 Y0 Z0 A0 C0\nG28 X0 Y0\n", "p.nc:3: G28: .*machine coordinates.*Z alone"),
    ("table-table-ac", "G0 X0 Y0 Z0 A0 C0\nG53 G0 Z0 C0\n", "p.nc:3: G53: .*retract of Z alone"),
    (None, "G0 X0 Y0 Z0\nG90 G28 Z5\n", "p.nc:3: G28: .*retract of Z alone"),
    (None, "G53 G0 Z0\nG0 X0 Y0 Z0\n", "p.nc:2: G53: .*retract of Z alone"),
])
def test_bad_5axis_gcode(tmp_path, tools, name, body, message):
    with pytest.raises(InputError, match=message):
        read(tmp_path, tools, "T1\n" + body, name)


# --- round trips: CL -> post_program -> read_gcode -------------------------------------------------


def smooth(rng, t, scale):
    """A random smooth function (k,) of ``t (k,)`` in [0, 1], about +-scale."""
    return sum(scale * rng.uniform(-1, 1) / (j + 1) * np.sin((j + 1) * math.pi * t + rng.uniform(0, 2 * math.pi))
               for j in range(3))


def random_cl_path(machine, rng, k=150):
    """A smooth 5-axis CL path for ``machine``: tilt 5..60 deg, C turning 300 deg from 20..40 deg on
    one side of 0 through 0 (= 360) to the other; built from the rotary angles, so that the inverse
    kinematics keeps to one tilt sign within the travel (no rewinds)."""
    t = np.linspace(0.0, 1.0, k)
    joints = np.zeros((k, 5))
    joints[:, :3] = np.column_stack([-30 + 60 * t + smooth(rng, t, 8), smooth(rng, t, 20), -5 + smooth(rng, t, 4)])
    tilt = np.clip(32 + smooth(rng, t, 40), 5, 60)
    joints[:, 3] = -tilt if machine.chain.type == "table-table" else tilt  # A travel [-120, 30]
    side = rng.choice([-1, 1])
    joints[:, 4] = side * (rng.uniform(20, 40) - 300 * t + smooth(rng, t, 20) * t * (1 - t))
    tip, axis = forward(machine, joints, tcp=True)
    rapid = np.zeros(k, bool)
    rapid[0] = True
    return Toolpath(tip, axis, rapid, np.full(k, 1, np.int64))


@pytest.mark.parametrize("tcp", [False, True])
@pytest.mark.parametrize("name", FIVE_AXIS)
@pytest.mark.parametrize("seed", [0, 1])
def test_round_trip_5axis(tmp_path, tools, name, tcp, seed):
    machine = load_machine(name)
    if tcp:
        machine = with_tcp(machine)
    cl = random_cl_path(machine, np.random.default_rng(seed))
    lines, report = post_program(cl, tools, machine, tolerance=POST_TOL, tcp=tcp)
    assert report["rewinds"] == 0 and report["mode"] == ("5-axis TCP" if tcp else "5-axis joints")
    c_low, c_high = report["axis_ranges"]["C"]
    assert c_low < -200 and 20 < c_high < 40 or c_high > 200 and -40 < c_low < -20
    (tmp_path / "p.nc").write_text("\n".join(lines) + "\n")
    tp, warnings = read_gcode(tmp_path / "p.nc", tools, machine=machine, chord_tol=CHORD)
    assert len(warnings) == 1 and "retract in machine coordinates" in warnings[0]
    assert (tp.tool == 1).all() and tp.rapid[0] and not tp.rapid[1:].any()
    # every CL tip is on the read path, every read point within the tolerances of the CL path
    assert segment_distances(cl.tip, tp.tip)[0].max() <= POST_TOL + CHORD
    dist, seg, frac = segment_distances(tp.tip, cl.tip)
    assert dist.max() <= POST_TOL + CHORD
    np.testing.assert_allclose(tp.tip[0], cl.tip[0], atol=1e-3)
    np.testing.assert_allclose(tp.tip[-1], cl.tip[-1], atol=1e-3)
    # the axes: within a small angle of the CL axis (on its great circle) where the tip is
    assert angles_deg(tp.axis, great_circle(cl.axis[seg], cl.axis[seg + 1], frac)).max() < 0.1
    if tcp:
        assert len(tp) == len(cl)  # the control interpolates: one point a block
        assert angles_deg(tp.axis, cl.axis).max() < 1e-3


@pytest.mark.parametrize("name", ["generic-3axis", "linuxcnc-3axis", "grbl-3axis"])
def test_round_trip_3axis(tmp_path, tools, name):
    machine = load_machine(name)
    machine = dataclasses.replace(machine, gcode=dataclasses.replace(machine.gcode, arcs=False))  # G1 for G1
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 1.0, 80)
    tip = np.column_stack([50 + 40 * t + smooth(rng, t, 10), 50 + smooth(rng, t, 30), -20 + smooth(rng, t, 8)])
    rapid = np.zeros(len(t), bool)
    rapid[[0, 40]] = True
    cl = Toolpath(tip, np.tile([0.0, 0.0, 1.0], (len(t), 1)), rapid, np.full(len(t), 2, np.int64))
    lines, _ = post_program(cl, tools, machine)
    (tmp_path / "p.nc").write_text("\n".join(lines) + "\n")
    half_digit = 0.5 * 10.0 ** -machine.gcode.decimals
    for reader_machine in (machine, None):
        tp, warnings = read_gcode(tmp_path / "p.nc", tools, tool_name="B6", machine=reader_machine)
        assert len(tp) == len(cl) and np.abs(tp.tip - cl.tip).max() <= half_digit
        # a rapid moving Z with X or Y is G1 at the rapid rate where G0 is a dog-leg (Fanuc)
        straight = cl.rapid[40] if machine.gcode.rapid == "linear" else False
        assert (tp.axis == [0, 0, 1]).all() and list(tp.rapid) == [True] + [False] * 39 + [straight] + [False] * 39
        assert (tp.tool == 2).all()  # T3 (B6), or grbl's program without T words and the tool named
        assert any("'B6' is not used" in w for w in warnings) == bool(machine.gcode.tool_change)
        retracts = [w for w in warnings if "retract in machine coordinates" in w]
        assert len(retracts) == (name != "grbl-3axis")


# --- simulate / verify ----------------------------------------------------------------------------


def test_read_toolpath_passes_the_machine(tmp_path, tools):
    (tmp_path / "p.nc").write_text("T1\nG43.4\nG0 X1 Y2 Z3 A-10 C20\n")
    tp, _ = read_toolpath(tmp_path / "p.nc", tools, machine=load_machine("table-table-ac"))
    np.testing.assert_array_equal(tp.tip, [[1, 2, 3]])
    cl = Toolpath(np.array([[0.0, 0, 5]]), np.array([[0.0, 0, 1]]), np.array([True]), np.array([0]))
    write_apt(tmp_path / "p.cl", cl, tools)
    _, warnings = read_toolpath(tmp_path / "p.cl", tools, machine=load_machine("table-table-ac"))
    assert any("not used" in w for w in warnings)


def tilted_ball_path(gap, k=60):
    """B10 (tool 2, radius 5) over the top face z = 0 of a box: the ball's centre ``gap`` mm above
    touching (negative: into the part), the tool tilted 10..45 deg, its azimuth turning."""
    t = np.linspace(0.0, 1.0, k)
    tilt, azimuth = np.radians(10 + 35 * t), np.radians(-60 + 240 * t)
    axis = np.column_stack([np.sin(tilt) * np.cos(azimuth), np.sin(tilt) * np.sin(azimuth), np.cos(tilt)])
    centre = np.column_stack([-30 + 60 * t, 20 * np.sin(3 * t), np.full(k, 5.0 + gap)])
    rapid = np.zeros(k, bool)
    rapid[0] = True
    return Toolpath(centre - 5.0 * axis, axis, rapid, np.full(k, 1, np.int64))


@pytest.mark.parametrize("gap, verdict", [(0.5, 0), (-0.3, 1)])
@pytest.mark.parametrize("name", FIVE_AXIS)
def test_verify_posted_program_as_the_cl_file(tmp_path, tools, tools_file, capsys, name, gap, verdict):
    m = box((-60, -60, -30), (60, 60, 0))
    part = tmp_path / "part.stl"
    trimesh.Trimesh(m.vertices, m.faces, process=False).export(part)
    cl = tilted_ball_path(gap)
    write_apt(tmp_path / "p.cl", cl, tools)
    lines, _ = post_program(cl, tools, load_machine(name))
    (tmp_path / "p.nc").write_text("\n".join(lines) + "\n")
    common = ["--tools", str(tools_file), "--device", "cpu", "--quiet"]
    assert main(["verify", str(part), str(tmp_path / "p.cl"), *common]) == verdict
    from_cl = capsys.readouterr().out.splitlines()[-1]
    assert main(["verify", str(part), str(tmp_path / "p.nc"), "--machine", name, *common]) == verdict
    from_nc = capsys.readouterr().out.splitlines()[-1]
    assert from_cl == from_nc == ("OK" if verdict == 0 else "PROBLEMS FOUND")


def test_dogleg_rapids(tmp_path, tools):
    """Fanuc's G0 moves each axis at its own rate (generic-3axis: X Y Z alike), so the path bends
    where the shorter moves end; LinuxCNC's is straight; without a machine, straight."""
    body = "T3\nG0 X0 Y0 Z5\nG0 X10 Y4 Z-2\nG1 X12\n"
    tp, _ = read(tmp_path, tools, body, "generic-3axis")
    np.testing.assert_allclose(tp.tip, [[0, 0, 5], [4, 4, 1], [7, 4, -2], [10, 4, -2], [12, 4, -2]])
    assert tp.rapid.tolist() == [True] * 4 + [False] and tp.line.tolist() == [2, 3, 3, 3, 4]
    for machine in ("linuxcnc-3axis", None):
        tp, _ = read(tmp_path, tools, body, machine)
        np.testing.assert_allclose(tp.tip, [[0, 0, 5], [10, 4, -2], [12, 4, -2]])
    # G91 steps that return to a coordinate in float noise add no corner
    tp, _ = read(tmp_path, tools, "T3\nG0 X0 Y0 Z5\nG91 G0 X0.1\nX0.2\nG90 X0.3 Y5 Z6\n", "generic-3axis")
    np.testing.assert_allclose(tp.tip[-2:], [[0.3, 1, 6], [0.3, 5, 6]])
    assert len(tp) == 5 and np.linalg.norm(np.diff(tp.tip, axis=0), axis=1).min() > 0.09
    # five axes: the rotaries at rotary_rapid_deg_min (9000 deg/min = 150 deg/s), X Y Z at 30 m/min = 500 mm/s
    tp, _ = read(tmp_path, tools, "T3\nG0 X0 Y0 Z50 A0 C0\nG0 X50 C300\n", "table-table-ac")
    machine = load_machine("table-table-ac")
    corner = forward(machine, np.array([[50.0, 0, 50, 0, 15.0]]))[0][0]  # X done after 0.1 s, C at 15 deg
    assert tp.rapid.all() and np.linalg.norm(tp.tip - corner, axis=1).min() < 1e-9


@pytest.mark.parametrize("name, verdict", [("generic-3axis", 1), ("linuxcnc-3axis", 0)])
def test_verify_sees_the_dogleg_of_a_rapid(tmp_path, tools_file, capsys, name, verdict):
    """A steep rapid up past a box's edge clears it on the straight line; moving X and Z at the
    same rate, the ball first climbs at 45 deg and clips the edge."""
    m = box((0, -10, -20), (20, 10, 0))
    part = tmp_path / "part.stl"
    trimesh.Trimesh(m.vertices, m.faces, process=False).export(part)
    (tmp_path / "p.nc").write_text("T3\nG0 X-10 Y0 Z-10\nG0 X5 Z30\n")
    rc = main(["verify", str(part), str(tmp_path / "p.nc"), "--machine", name, "--tools", str(tools_file), "--quiet"])
    out = capsys.readouterr().out
    assert rc == verdict and ("1 (on 1 line) rapid into the part" in out) == bool(verdict)


def one_line_error(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("meshmill: error:")
    return err[0]


def test_cli_bad_input(tmp_path, tools_file, capsys):
    m = box((-60, -60, -30), (60, 60, 0))
    part = tmp_path / "part.stl"
    trimesh.Trimesh(m.vertices, m.faces, process=False).export(part)
    (tmp_path / "p.nc").write_text("T1\nG0 X0 Y0 Z50 A-10 C0\n")
    t = str(tools_file)
    assert "p.nc:2: unsupported word A-10" in one_line_error(capsys, ["verify", str(part), str(tmp_path / "p.nc"),
                                                                      "--tools", t])
    assert "no such machine file" in one_line_error(capsys, ["verify", str(part), str(tmp_path / "p.nc"), "--tools", t,
                                                             "--machine", "no-such-machine"])
    assert "no A axis" in one_line_error(capsys, ["verify", str(part), str(tmp_path / "p.nc"), "--tools", t,
                                                  "--machine", "head-table-bc"])
    assert "p.nc:2: unsupported word A-10" in one_line_error(
        capsys, ["simulate", "--design", str(part), "--toolpath", str(tmp_path / "p.nc"), "--tools", t, "--step", "1",
                 "--out", str(tmp_path / "sim")])
    assert "3-axis machine" in one_line_error(
        capsys, ["simulate", "--design", str(part), "--toolpath", str(tmp_path / "p.nc"), "--tools", t, "--step", "1",
                 "--machine", "generic-3axis", "--out", str(tmp_path / "sim")])


def test_a_retract_before_a_tool_change_leaves_z_unknown_until_given(tmp_path):
    """G91 G28 Z0 before a tool change: the moves after it join the path once Z is given again."""
    from meshmill.machine.gcode import read_gcode
    from meshmill.tools.table import Tool

    tools = [Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1), Tool("B4", "ball", 4.0, 2.0, 10.0, 30.0, 4.0, number=2)]
    p = tmp_path / "p.nc"
    p.write_text("T1 M6\nG0 X0 Y0 Z5\nG1 Z-1 F500\nX10\nG91 G28 Z0\nG90\nT2 M6\nG0 X20 Y0\nZ5\nG1 Z-1\n")
    tp, warnings = read_gcode(str(p), tools)
    assert len(warnings) == 1 and "retract in machine coordinates" in warnings[0]
    after = tp.tip[tp.tool == 1]
    assert np.allclose(after[0], [20, 0, 5]) and np.allclose(after[-1], [20, 0, -1])
    assert not np.any(np.isnan(tp.tip))


@pytest.mark.parametrize("name", ["generic-3axis", "linuxcnc-3axis", "table-table-ac"])
def test_arcs_are_written_where_moves_lie_on_one_and_read_back_within_the_tolerance(tmp_path, tools, name):
    # a circle of 120 moves at one height, a descending helix, then a zigzag (no arc), on an exact grid
    t = np.linspace(0.0, 2 * np.pi * 0.9, 120)
    circle = np.column_stack([20 + 10 * np.cos(t), 10 * np.sin(t), np.full(len(t), -5.0)])
    u = np.linspace(0.0, -4 * np.pi, 150)
    helix = np.column_stack([3 * np.cos(u), 3 * np.sin(u), -6.0 + u / (4 * np.pi)])
    zig = np.column_stack([np.arange(10.0), 20 + (np.arange(10) % 2) * 2.0, np.full(10, -5.0)])
    tip = np.vstack([[30.0, 0.0, 10.0], circle, [3.0, 0.0, 10.0], helix, zig])
    rapid = np.zeros(len(tip), bool)
    rapid[[0, 1 + len(circle)]] = True
    cl = Toolpath(tip, np.tile([0.0, 0.0, 1.0], (len(tip), 1)), rapid, np.full(len(tip), 2, np.int64))
    machine = load_machine(name)
    lines, report = post_program(cl, tools, machine)
    def arcs(lines):
        return [w for ln in lines for w in ln.split() if w in ("G2", "G3")]

    g2 = arcs(lines)
    assert len(g2) >= 2 and report["blocks"] < len(tip) - 200  # the circle and the helix are arcs
    assert "G3" in g2 and "G2" in g2  # each way round
    (tmp_path / "p.nc").write_text("\n".join(lines) + "\n")
    back, _ = read_gcode(tmp_path / "p.nc", tools, tool_name="B6", machine=machine)
    feed = ~back.rapid
    dist, _, _ = segment_distances(back.tip[feed], cl.tip)
    assert dist.max() <= POST_TOL + CHORD  # the arcs keep to the CL moves within the post's tolerance
    assert np.abs(back.tip[-1] - cl.tip[-1]).max() < 1e-3
    off = dataclasses.replace(machine, gcode=dataclasses.replace(machine.gcode, arcs=False))
    assert not arcs(post_program(cl, tools, off)[0])
