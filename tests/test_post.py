"""meshmill post: G-code for 3-axis (Fanuc, LinuxCNC, grbl) and 5-axis (table-table, head-table,
TCP) machines, checked by reading the program back."""
import json
from dataclasses import replace
import re

import numpy as np
import pytest

from meshmill.cli import main
from conftest import one_line_error
from meshmill.errors import InputError
from meshmill.machine.config import SHIPPED, load_machine
from meshmill.machine.kinematics import forward
from meshmill.machine.post import format_number, post_program
from meshmill.tools.table import Tool, load_tools, write_tools
from meshmill.toolpath.cldata import read_apt, write_apt
from meshmill.toolpath.model import Toolpath

WORD = re.compile(r"([A-Z])(-?\d+(?:\.\d*)?)")
UP = (0.0, 0.0, 1.0)


def _cl(tmp_path, tools, tp, name="job.cl"):
    """Write ``tp`` as a CL file with tools.toml beside it; read it back (moves carry CL lines)."""
    write_tools(tmp_path / "tools.toml", tools)
    write_apt(tmp_path / name, tp, tools)
    return read_apt(tmp_path / name, tools)[0]


def _square():
    """A 50 mm square at Z -20 with tool 2 (B10), then a slot with tool 3 (B6); rapids between."""
    tip = np.array([[10, 10, -5], [10, 10, -20], [60, 10, -20], [60, 60, -20], [10, 60, -20], [10, 10, -20],
                    [10, 10, -5], [20, 20, -5], [20, 20, -10], [40, 20, -10], [40, 20, -5]], float)
    rapid = np.zeros(len(tip), bool)
    rapid[[0, 6, 7, 10]] = True
    tool = np.array([1] * 7 + [2] * 4)
    return Toolpath(tip, np.tile(UP, (len(tip), 1)), rapid, tool)


def _blocks(lines, machine):
    """The motion blocks of a program (its start and end lines left out): ``[((motion, G93 on),
    joints (n,) in machine.axes order with the modal values filled in, F or None, tool number)]``."""
    letters = machine.axes
    state = dict.fromkeys(letters, np.nan)
    motion, inverse_time, tool, out = None, False, None, []
    for line in lines:
        if line in machine.gcode.start + machine.gcode.end + machine.gcode.retract:
            continue
        line = re.sub(r"\(.*?\)|;.*$", "", line).strip()
        words = WORD.findall(line)
        if not words:
            continue
        codes = [(a, float(v)) for a, v in words]
        if ("M", 6.0) in codes:
            tool = int(dict(codes)["T"])
            continue
        moves = {a: v for a, v in codes if a in letters}
        for a, v in codes:
            if a == "G" and v in (0.0, 1.0):
                motion = int(v)
            elif a == "G" and v in (93.0, 94.0):
                inverse_time = v == 93.0
        if not moves:
            continue
        state.update(moves)
        f = dict(codes).get("F")
        out.append(((motion, inverse_time), np.array([state[a] for a in letters]), f, tool))
    return out


def _machine_file(tmp_path, shipped, extra):
    """A copy of a shipped machine file with ``extra`` keys added to its [gcode] table (the last)."""
    text = open(f"{SHIPPED}/{shipped}.toml").read()
    assert text.split("\n[")[-1].startswith("gcode]")
    path = tmp_path / f"{shipped}-custom.toml"
    path.write_text(text.rstrip() + "\n" + extra + "\n")
    return load_machine(path)


# --- 3-axis -------------------------------------------------------------------------------------

FANUC = """%
O1000
G21 G90 G17 G40 G49 G80 G94
(meshmill post for generic 3-axis VMC [Fanuc-like]: 3-axis)
(T2 B10: ball D10)
T2 M6
G43 H2
S10000 M3
M8
G0 X10.0000 Y10.0000
Z-5.0000
G1 Z-20.0000 F4000.0
X60.0000
Y60.0000
X10.0000
Y10.0000
G0 Z-5.0000
G91 G28 Z0
G90
M5
M9
(T3 B6: ball D6)
T3 M6
G43 H3
S10000 M3
M8
G0 X20.0000 Y20.0000
Z-5.0000
G1 Z-10.0000 F4000.0
X40.0000
G0 Z-5.0000
M5
M9
G91 G28 Z0
G90
M30
%""".splitlines()


def test_fanuc_program_is_the_golden_one(tmp_path, tools):
    tp = _cl(tmp_path, tools, _square())
    lines, report = post_program(tp, tools, load_machine("generic-3axis"))
    assert lines == FANUC
    assert report["blocks"] == 13 and report["moves"] == 11 and report["tool_changes"] == 1
    assert report["tools"] == ["B10", "B6"] and report["dialect"] == "fanuc" and report["mode"] == "3-axis"
    assert report["axis_ranges"] == {"X": [10.0, 60.0], "Y": [10.0, 60.0], "Z": [-20.0, -5.0]}
    assert report["linearisation"]["blocks_added"] == 0 and report["feed_mode"] == "G94 mm/min"


def test_linuxcnc_and_grbl_key_lines(tmp_path, tools):
    tp = _cl(tmp_path, tools, _square())
    lines, _ = post_program(tp, tools, load_machine("linuxcnc-3axis"))
    assert lines[:11] == ["%", "G21 G90 G17 G40 G49 G80 G94 G64 P0.005",
                          "(meshmill post for LinuxCNC 3-axis mill: 3-axis)", "(T2 B10: ball D10)", "T2 M6", "G43 H2",
                          "S10000 M3", "M8", "G0 X10.0000 Y10.0000", "Z-5.0000", "G1 Z-20.0000 F3000.0"]
    change = lines.index("(T3 B6: ball D6)")
    assert lines[change - 3:change + 6] == ["G53 G0 Z0", "M5", "M9", "(T3 B6: ball D6)", "T3 M6", "G43 H3", "S10000 M3", "M8",
                                            "G0 X20.0000 Y20.0000"]
    assert lines[-6:] == ["G0 Z-5.0000", "M5", "M9", "G53 G0 Z0", "M2", "%"]

    lines, report = post_program(tp, tools, load_machine("grbl-3axis"))
    assert lines[:8] == ["G21 G90 G17 G94", "; meshmill post for grbl 3-axis router: 3-axis", "; T2 B10: ball D10",
                         "S10000 M3", "M8", "G0 X10.000 Y10.000", "Z-5.000", "G1 Z-20.000 F1500.0"]
    change = lines.index("; T3 B6: ball D6")
    # no tool changer: spindle and coolant off, the tool named, then a pause for the operator
    assert lines[change - 3:change + 5] == ["G53 G0 Z0", "M5", "M9", "; T3 B6: ball D6", "M0", "S10000 M3", "M8",
                                            "G0 X20.000 Y20.000"]
    assert lines[-4:] == ["G0 Z-5.000", "M5", "M9", "M2"]
    assert not any("M6" in line or "G43" in line for line in lines)
    assert "no tool changer" in report["warnings"][0]


@pytest.mark.parametrize("name, retract", [("generic-3axis", ["G91 G28 Z0", "G90"]),
                                           ("linuxcnc-3axis", ["G53 G0 Z0"]), ("grbl-3axis", ["G53 G0 Z0"])])
def test_tool_change_retracts_before_the_spindle_stop(tmp_path, tools, name, retract):
    machine = load_machine(name)
    assert list(machine.gcode.retract) == retract
    lines, _ = post_program(_cl(tmp_path, tools, _square()), tools, machine)
    stops = [n for n, line in enumerate(lines) if line == "M5"]
    change, end = stops[0], stops[-1]
    assert len(stops) == 2 and lines[change - len(retract):change] == retract
    # the new tool comes down only after X Y at the retracted height
    first = next(n for n in range(change, end) if lines[n].startswith("G0"))
    assert lines[first].startswith("G0 X") and "Z" not in lines[first] and lines[first + 1].startswith("Z")


@pytest.mark.parametrize("name", ["generic-3axis", "linuxcnc-3axis", "grbl-3axis"])
def test_modal_words_decimals_and_the_path_read_back(tmp_path, tools, name):
    tp = _square()
    tp.tip[2, 0] -= 0.00004  # rounds to 60.0000 / 60.000: no new X word
    tp.tip[:, 1] += np.where(tp.tip[:, 1] == 10, -9.99996, 0.0)  # Y 0.00004: written as Y0.0000, never negative
    tp.tip[5, 1] = -0.00004
    tp = _cl(tmp_path, tools, tp)
    machine = load_machine(name)
    lines, _ = post_program(tp, tools, machine)
    places = machine.gcode.decimals
    assert not re.search(r"[A-Z]-0\.0*(\s|$)", "\n".join(lines))
    modal = {}
    for line in lines:
        if line.startswith(("T", "M5")):
            modal.clear()  # a tool change writes every word again
        if line.startswith(("(", ";")) or line in machine.gcode.start + machine.gcode.end + machine.gcode.retract:
            continue
        for letter, value in WORD.findall(line):
            if letter in "XYZ":
                assert len(value.split(".")[1]) == places, line
                assert modal.get(letter) != value, f"{line}: {letter} repeats its modal value"
                modal[letter] = value
            elif letter == "F":
                assert modal.get("F") != value, line
                modal["F"] = value
            elif letter == "G" and value in ("0", "1"):
                assert modal.get("G") != value, f"{line}: G{value} repeats"
                modal["G"] = value
    blocks = _blocks(lines, machine)
    ends = np.array([b[1] for b in blocks])
    # every CL move ends where a block ends, in order (the first of each tool in two blocks: XY then Z)
    expected = np.round(tp.tip, places)
    at = 0
    for p in expected:
        at += int(np.flatnonzero(np.abs(ends[at:] - p).max(axis=1) < 1e-9)[0])
    assert [b[0][0] for b in blocks] == [0, 0, 1, 1, 1, 1, 1, 0, 0, 0, 1, 1, 0]


def test_line_numbers(tmp_path, tools):
    machine = _machine_file(tmp_path, "generic-3axis", "line_numbers = true")
    lines, _ = post_program(_square(), tools, machine)
    assert lines[:4] == ["%", "O1000", "N1 G21 G90 G17 G40 G49 G80 G94",
                         "N2 (meshmill post for generic 3-axis VMC [Fanuc-like]: 3-axis)"]
    assert lines[-1] == "%" and lines[-2] == f"N{len(lines) - 3} M30"


def test_limit_error_names_the_first_move_and_axis(tmp_path, tools):
    tp = _square()
    tp.tip[3] = [60, 450, -20]  # Y beyond [0, 400] at move 4
    tp.tip[4] = [700, 450, -20]  # X beyond [0, 600] at move 5, too
    tp = _cl(tmp_path, tools, tp)
    with pytest.raises(InputError) as err:
        post_program(tp, tools, load_machine("linuxcnc-3axis"), origin=(0.0, 0.0, 0.0))
    assert str(err.value) == (f"move 4 (CL line {tp.line[3]}): Y 450.0000 (machine coordinates, origin 0, 0, 0) is "
                              "beyond its travel [0, 400] on LinuxCNC 3-axis mill")
    # without the work offset: each axis's span must fit, and the report says where the zero may lie
    with pytest.raises(InputError, match=r"^the program spans 690\.000 mm in X \(10\.000 to 700\.000\) but "
                                         r"LinuxCNC 3-axis mill travels 600 mm"):
        post_program(tp, tools, load_machine("linuxcnc-3axis"))
    fine = _cl(tmp_path, tools, _square())
    _, report = post_program(fine, tools, load_machine("linuxcnc-3axis"))
    xs = fine.tip[:, 0]
    assert report["origin_range"]["X"] == pytest.approx([0.0 - xs.min(), 600.0 - xs.max()])
    with pytest.raises(InputError, match=r"X -90\.0000 \(machine coordinates, origin -100, 0, -50\)"):
        post_program(fine, tools, load_machine("linuxcnc-3axis"), origin=(-100.0, 0.0, -50.0))


def test_tilted_axis_on_a_3_axis_machine_is_refused(tmp_path, tools):
    tp = _square()
    tp.axis[8] = [0.0, np.sin(0.2), np.cos(0.2)]
    tp = _cl(tmp_path, tools, tp)
    with pytest.raises(InputError) as err:
        post_program(tp, tools, load_machine("generic-3axis"))
    text = str(err.value)
    assert text.startswith(f"move 9 (CL line {tp.line[8]}): the tool axis") and "11.459 deg" in text
    assert "3-axis machine" in text and "1 tilted move" in text
    with pytest.raises(InputError, match="TCP needs a 5-axis machine"):
        post_program(_square(), tools, load_machine("generic-3axis"), tcp=True)


def test_feeds_per_move(tools):
    tp = _square()
    feed = np.full(len(tp), np.nan)
    feed[3:] = 20.0  # mm/s: 1200 mm/min from move 4 on
    lines, _ = post_program(tp, tools, load_machine("generic-3axis"), feed=feed)
    assert "G1 Z-20.0000 F4000.0" in lines and "Y60.0000 F1200.0" in lines and "G1 Z-10.0000 F1200.0" in lines
    with pytest.raises(InputError, match="feed"):
        post_program(tp, tools, load_machine("generic-3axis"), feed=-1.0)


def test_format_number_has_no_negative_zero():
    assert format_number(-0.00004, 4) == "0.0000" and format_number(-0.0, 3) == "0.000"
    assert format_number(-0.4, 0) == "0" and format_number(-0.00006, 4) == "-0.0001"
    assert format_number(12.5, 1) == "12.5"


# --- 5-axis -------------------------------------------------------------------------------------

def _five_axis_path():
    """Around a 30 mm circle, the tool tilted outwards from 10 to 40 deg while its azimuth turns
    from -60 to 420 deg (through C's 0/360 wrap), going down; tool 2 (B10) for the first part,
    tool 3 (B6) for the rest; rapids in and out of each."""
    def arc(start, stop, tilt0, tilt1, z0, z1, count):
        phi = np.radians(np.linspace(start, stop, count))
        tilt = np.radians(np.linspace(tilt0, tilt1, count))
        tip = np.c_[30 * np.cos(phi), 30 * np.sin(phi), np.linspace(z0, z1, count)]
        axis = np.c_[np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.cos(tilt)]
        return np.r_[tip[:1] + [0, 0, 30], tip, tip[-1:] + [0, 0, 30]], np.r_[axis[:1], axis, axis[-1:]]

    tip1, axis1 = arc(-60, 200, 10, 30, -5, -10, 27)
    tip2, axis2 = arc(200, 420, 30, 40, -10, -15, 23)
    tip, axis = np.r_[tip1, tip2], np.r_[axis1, axis2]
    rapid = np.zeros(len(tip), bool)
    rapid[[0, 28, 29, len(tip) - 1]] = True
    tool = np.array([1] * len(tip1) + [2] * len(tip2))
    return Toolpath(tip, axis, rapid, tool)


def _segment_distance(points, p0, p1):
    """Distance (m, s) from ``points (m, 3)`` to each segment ``p0 (s, 3)`` -> ``p1 (s, 3)``."""
    d = p1 - p0
    rel = points[:, None, :] - p0[None]
    t = np.clip(np.einsum("msj,sj->ms", rel, d) / np.maximum(np.einsum("sj,sj->s", d, d), 1e-300), 0, 1)
    return np.linalg.norm(rel - t[..., None] * d[None], axis=2)


@pytest.mark.parametrize("name", ["table-table-ac", "head-table-bc", "head-head-ca"])
def test_five_axis_blocks_stay_on_the_cl_path(tmp_path, tools, name):
    machine = load_machine(name)
    tp = _cl(tmp_path, tools, _five_axis_path())
    tolerance = 0.005
    lines, report = post_program(tp, tools, machine, feed=50.0, tolerance=tolerance)
    letters = machine.axes
    blocks = _blocks(lines, machine)
    numbers = {t.number: t for t in tools}
    clearance = tp.tip[:, 2].max()

    def length(number):
        return numbers[number].spindle_length if machine.chain.head_pivot else 0.0

    cut = ~tp.rapid
    cut[[0, 29]] = False  # the first move of each tool is a positioning G0
    seg0, seg1 = tp.tip[np.flatnonzero(cut) - 1], tp.tip[np.flatnonzero(cut)]
    moving = np.flatnonzero(tp.rapid[1:]) + 1
    up0, up1 = tp.tip[moving - 1], tp.tip[moving]

    def distance_to_path(point):
        return _segment_distance(point[None], seg0, seg1).min()

    s = np.linspace(0.0, 1.0, 201)
    worst, off_path, unwinds = 0.0, [], []
    for b in range(1, len(blocks)):
        (motion, inverse_time), joints, f, number = blocks[b]
        before = blocks[b - 1][1]
        if motion == 0:
            if np.abs(joints[:3] - before[:3]).max() == 0 and blocks[b - 1][0][0] == 1 and blocks[b - 1][3] == number:
                unwinds.append(b)  # rotaries only, after a feed block of the same tool: the unwind
            continue
        dense = before + s[:, None] * (joints - before)
        tip, axis = forward(machine, dense, length(number))
        distance = _segment_distance(tip, seg0, seg1).min(axis=1)
        if (distance[0] > tolerance or distance[-1] > tolerance) and _segment_distance(tip, up0, up1).min(axis=1).max() <= tolerance:
            continue  # a CL rapid that G0 would not keep straight (Z with X or Y on a dog-leg control): G1 along it
        if distance[0] > tolerance or distance[-1] > tolerance:
            off_path.append((b, tip, axis))
            continue
        worst = max(worst, distance.max())
        assert inverse_time == machine.gcode.inverse_time
    assert worst <= tolerance
    assert report["linearisation"]["max_deviation_mm"] <= tolerance
    assert report["linearisation"]["blocks_added"] > 0
    # every CL pose is a block's end
    ends = np.array([forward(machine, b[1][None], length(b[3]))[0][0] for b in blocks])
    for i in np.flatnonzero(cut):
        assert np.nanmin(np.linalg.norm(ends - tp.tip[i], axis=1)) < 1e-3
    # C turns through its 0/360 wrap: a continuous C just goes on, C in [-360, 360] unwinds once by two turns
    # (retract, turn, return) and never in the cut
    c = np.array([b[1][letters.index("C")] for b in blocks])
    assert np.floor(c.min() / 360.0) < np.floor(c.max() / 360.0)  # a whole turn lies between
    if "C" in machine.limits:
        assert report["rewinds"] == len(unwinds) == 1 and c.min() == pytest.approx(-360.0, abs=1.0)
    else:
        assert report["rewinds"] == len(unwinds) == 0 and np.ptp(c) > 360.0
    assert sorted(b for b, _, _ in off_path) == sorted(b for u in unwinds for b in (u - 1, u + 1))
    for u in unwinds:
        turn = blocks[u][1] - blocks[u - 1][1]
        # to the far end of C's travel: two turns, so that the next unwind is two turns away
        assert np.abs(turn[:-1]).max() == 0 and abs(turn[-1]) == pytest.approx(720.0, abs=1e-3)
    for b, tip, axis in off_path:  # up and down the tool axis, until the whole tool is at the clearance height
        assert np.abs(np.cross(tip[-1] - tip[0], axis[0])).max() < 1e-3 and np.ptp(axis, axis=0).max() < 1e-9
        up = tip[0] if tip[0, 2] > tip[-1, 2] else tip[-1]
        assert numbers[blocks[b][3]].lowest_z(up, axis[0])[0] == pytest.approx(clearance, abs=1e-3)
        assert min(distance_to_path(tip[0]), distance_to_path(tip[-1])) < tolerance
    assert report["axis_ranges"]["C"] == pytest.approx([c.min(), c.max()])


@pytest.mark.parametrize("name", ["table-table-ac", "head-table-bc", "head-head-ca"])
def test_inverse_time_feeds(tools, name):
    machine = load_machine(name)
    tp = _five_axis_path()
    lines, report = post_program(tp, tools, machine, feed=50.0)
    assert report["feed_mode"] == "G93 inverse time"
    blocks = _blocks(lines, machine)
    numbers = {t.number: t for t in tools}
    checked = 0
    for b in range(1, len(blocks)):
        (motion, inverse_time), joints, f, number = blocks[b]
        if motion != 1:
            continue
        assert inverse_time and f is not None  # G93 wants F on every feed block
        before = blocks[b - 1][1]
        length = numbers[number].spindle_length if machine.chain.head_pivot else 0.0
        tips = forward(machine, np.stack([before, joints]), length)[0]
        # the cut at 3000 mm/min; the rapids that turn the rotaries are G1 at the rapid rate
        minutes = [max(np.linalg.norm(tips[1] - tips[0]) / tip_feed,
                       np.abs(joints[3:] - before[3:]).max() / (machine.rotary_rapid * 60.0),
                       np.abs(joints[:3] - before[:3]).max() / (machine.motion.rapid * 60.0))
                   for tip_feed in (3000.0, machine.motion.rapid * 60.0)]
        assert any(f == pytest.approx(1.0 / m, rel=2e-3, abs=1e-4) for m in minutes)
        checked += 1
    assert checked > 100
    assert lines.count("G94") == 2  # back to G94 before the tool change and before the end


def test_linearisation_only_where_the_rotaries_turn(tools):
    """A straight cut with a fixed tilted axis: joint-linear motion is straight, nothing added."""
    tip = np.array([[0, 0, 20], [0, 0, 0], [40, 10, -5], [40, 10, 20]], float)
    axis = np.tile([0.3, -0.2, 0.9], (4, 1)) / np.linalg.norm([0.3, -0.2, 0.9])
    tp = Toolpath(tip, axis, np.array([True, False, False, True]), np.ones(4, int))
    for name in ("table-table-ac", "head-table-bc"):
        lines, report = post_program(tp, tools, load_machine(name))
        assert report["linearisation"]["blocks_added"] == 0 and report["blocks"] == 5
        assert report["linearisation"]["max_deviation_mm"] < 1e-3


def test_tcp_writes_the_tool_tip(tmp_path, tools):
    machine = _machine_file(tmp_path, "table-table-ac", 'tcp = "G43.4 H{number}"')
    tp = _five_axis_path()
    lines, report = post_program(tp, tools, machine, feed=50.0)
    assert report["mode"] == "5-axis TCP" and report["feed_mode"] == "G94 mm/min"
    assert report["linearisation"]["max_deviation_mm"] is None and report["linearisation"]["blocks_added"] == 0
    assert "G43.4 H2" in lines and "G43.4 H3" in lines and not any(line.startswith("G43 H") for line in lines)
    assert not any("G93" in line for line in lines)
    assert lines[lines.index("T3 M6") - 4:lines.index("T3 M6") - 1] == ["M5", "M9", "G49"]
    assert lines[-7:] == ["G49", "M5", "M9", "G91 G28 Z0", "G90", "M30", "%"]
    blocks = _blocks(lines, machine)
    assert all(b[2] in (None, 3000.0) for b in blocks)
    ends = np.array([b[1] for b in blocks])
    for i in range(len(tp)):
        hit = np.flatnonzero(np.abs(ends[:, :3] - tp.tip[i]).max(axis=1) < 1e-4)
        assert len(hit), f"pose {i} not written"
        _, axis = forward(machine, ends[hit[:1]], tcp=True)
        assert np.abs(axis[0] - tp.axis[i] / np.linalg.norm(tp.axis[i])).max() < 1e-5
    assert report["blocks"] == len(tp) + 2  # one block a move, the first of each tool in two
    # the shipped machine has no TCP text: asking for TCP there is refused
    with pytest.raises(InputError, match="no \\[gcode\\] 'tcp' text"):
        post_program(tp, tools, load_machine("table-table-ac"), tcp=True)


# --- command line -------------------------------------------------------------------------------

def test_post_command(tmp_path, tools, capsys):
    _cl(tmp_path, tools, _five_axis_path())
    cl = tmp_path / "job.cl"
    rc = main(["post", str(cl), "--machine", "head-table-bc"])
    out = capsys.readouterr().out
    assert rc == 0 and (tmp_path / "program.nc").exists()
    assert out.startswith(f"wrote {tmp_path / 'program.nc'}: ") and "linearisation within 0.005 mm added" in out
    assert "C -" in out and "1 rewind(s)" in out and "no feed programmed: the machine's 5000 mm/min" in out
    assert (tmp_path / "program.nc").read_text().startswith("%\nO1000\n")
    assert main(["post", str(cl), "--machine", "head-table-bc", "--clearance", "80"]) == 0
    assert "1 rewind(s) of the rotaries, the whole tool above Z 80" in capsys.readouterr().out

    # FEDRAT is honoured; --feed fills the moves before it
    text = cl.read_text().splitlines()
    text.insert(text.index(next(t for t in text if t.startswith("GOTO"))) + 2, "FEDRAT/1200, MMPM")
    cl.write_text("\n".join(text) + "\n")
    rc = main(["post", str(cl), "--machine", "table-table-ac", "--json", "--out", str(tmp_path / "nc" / "p.nc"),
               "--tolerance", "0.01", "--feed", "900"])
    captured = capsys.readouterr()
    report = json.loads(captured.out)
    assert rc == 0 and not captured.err and (tmp_path / "nc" / "p.nc").exists()
    assert report["feeds"].startswith("1 of ") and "feed 900 mm/min" in report["feeds"]
    assert report["linearisation"]["tolerance_mm"] == 0.01 and report["machine"].startswith("5-axis trunnion")
    assert set(report["axis_ranges"]) == {"X", "Y", "Z", "A", "C"} and report["rewinds"] == 0

    square = tmp_path / "sq"
    square.mkdir()
    _cl(square, tools, _square())
    lines = (square / "job.cl").read_text().splitlines()
    lines.insert(5, "FEDRAT/600")
    (square / "job.cl").write_text("\n".join(lines) + "\n")
    assert main(["post", str(square / "job.cl"), "--machine", "grbl-3axis"]) == 0
    assert "feeds as programmed" in capsys.readouterr().out
    assert "G1 Z-20.000 F600.0" in (square / "program.nc").read_text()


def test_post_command_bad_input(tmp_path, tools, capsys):
    _cl(tmp_path, tools, _square())
    cl = str(tmp_path / "job.cl")
    assert "no such CL file" in one_line_error(capsys, ["post", str(tmp_path / "x.cl"), "--machine", "grbl-3axis"])
    assert "no such machine file" in one_line_error(capsys, ["post", cl, "--machine", "nope"])
    assert "--tolerance" in one_line_error(capsys, ["post", cl, "--machine", "grbl-3axis", "--tolerance", "0"])
    assert "--feed" in one_line_error(capsys, ["post", cl, "--machine", "grbl-3axis", "--feed", "-3"])
    assert "--clearance" in one_line_error(capsys, ["post", cl, "--machine", "grbl-3axis", "--clearance", "nan"])
    far = _square()
    far.tip[2, 0] = 400.0
    _cl(tmp_path, tools, far, "far.cl")
    line = one_line_error(capsys, ["post", str(tmp_path / "far.cl"), "--machine", "grbl-3axis"])
    assert "spans 390.000 mm in X" in line and "travels 300 mm" in line
    line = one_line_error(capsys, ["post", str(tmp_path / "far.cl"), "--machine", "grbl-3axis", "--origin", "0,0,0"])
    assert "move 3 (CL line" in line and "X 400.000 (machine coordinates, origin 0, 0, 0) is beyond its travel [0, 300]" in line
    assert "--origin" in one_line_error(capsys, ["post", cl, "--machine", "grbl-3axis", "--origin", "1,2"])
    alone = tmp_path / "alone"
    alone.mkdir()
    (alone / "job.cl").write_text((tmp_path / "job.cl").read_text())
    assert "no --tools given" in one_line_error(capsys, ["post", str(alone / "job.cl"), "--machine", "grbl-3axis"])
    one_line_error(capsys, ["post", cl])  # no --machine


def test_a_rapid_that_turns_the_rotaries_is_linearised(tools):
    """A CL rapid turning B from 30 to -50 deg (through the other solution of the rotaries): G1 at the
    rapid rate, its joint-linear tips within the tolerance of the CL segment."""
    def ax(tilt, az):
        t, a = np.radians(tilt), np.radians(az)
        return [np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)]
    tip = np.array([[35, 0, 40], [35, 0, 20], [30, 0, 20], [-30, 10, 20], [-35, 10, 20], [-35, 10, 40]], float)
    axis = np.array([ax(30, 0)] * 3 + [ax(50, 200)] * 3)
    tp = Toolpath(tip, axis, np.array([1, 0, 0, 1, 0, 1], bool), np.ones(6, int))
    machine = load_machine("head-table-bc")
    tolerance = 0.005
    lines, report = post_program(tp, tools, machine, tolerance=tolerance)
    assert report["linearisation"]["max_deviation_mm"] <= tolerance
    blocks = _blocks(lines, machine)
    length = tools[1].spindle_length
    tips = forward(machine, np.array([b[1] for b in blocks]), length)[0]
    start = int(np.flatnonzero(np.linalg.norm(tips - tip[2], axis=1) < 1e-3)[0])
    stop = int(np.flatnonzero(np.linalg.norm(tips - tip[3], axis=1) < 1e-3)[0])
    assert stop - start > 2 and all(blocks[b][0][0] == 1 for b in range(start + 1, stop + 1))
    s = np.linspace(0.0, 1.0, 33)[:, None]
    for b in range(start, stop):
        j0, j1 = blocks[b][1], blocks[b + 1][1]
        path = forward(machine, j0 + s * (j1 - j0), length)[0]
        assert _segment_distance(path, tip[2:3], tip[3:4]).max() <= tolerance + 1e-4
    assert blocks[-1][0][0] == 0  # the last rapid turns nothing: G0


def test_tcp_travel_is_checked_where_the_axes_stand(tmp_path):
    """With TCP the program's X Y Z are the tip, but the head's pivot is what travels: a tip at
    Z 450 puts head-table-bc's pivot at 450 + 150 + the tool's length, beyond Z's 500."""
    machine = load_machine("head-table-bc")
    tcp_machine = replace(machine, gcode=replace(machine.gcode, tcp="G43.4 H{number}"))
    tools = [Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1)]
    tip = np.array([[0.0, 0.0, 450.0], [10.0, 0.0, 450.0]])
    axis = np.tile([0.0, 0.0, 1.0], (2, 1))
    tp = Toolpath(tip=tip, axis=axis, rapid=np.array([True, False]), tool=np.zeros(2, np.int64))
    for m in (machine, tcp_machine):
        with pytest.raises(InputError, match=r"Z 640\.0+ \(machine coordinates, origin 0, 0, 0\) is beyond its travel"):
            post_program(tp, tools, m, origin=(0.0, 0.0, 0.0))


def test_g94_joint_programs_warn_that_f_is_not_the_tips():
    machine = load_machine("table-table-ac")
    g94 = replace(machine, gcode=replace(machine.gcode, inverse_time=False))
    tools = [Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1)]
    tilt = np.radians([10.0, 20.0, 30.0])
    axis = np.column_stack([np.sin(tilt), np.zeros(3), np.cos(tilt)])
    tp = Toolpath(tip=np.array([[0.0, 0, 5], [5.0, 0, 0], [10.0, 0, 0]]), axis=axis,
                  rapid=np.array([True, False, False]), tool=np.zeros(3, np.int64))
    _, report = post_program(tp, tools, g94)
    assert report["feed_mode"].startswith("G94") and any(
        "set inverse_time = true in its [gcode]" in w and 'tcp = "G43.4 H{number}"' in w for w in report["warnings"])
    _, report = post_program(tp, tools, machine)
    assert not any("G94" in w for w in report["warnings"])


def _joint_poses(lines, letters="XYZAC"):
    """Every pose (p, 5) a program's lines reach once all of ``letters`` were given."""
    state, poses = {}, []
    for line in lines:
        w = dict(re.findall(f"([{letters}])(-?[\\d.]+)", line))
        if w:
            state.update({k: float(v) for k, v in w.items()})
            if len(state) == len(letters):
                poses.append([state[k] for k in letters])
    return np.array(poses)


@pytest.mark.parametrize("clearance", [None, 60.0])
def test_a_tilt_swing_keeps_the_whole_tool_above_the_clearance(clearance):
    """A path that needs A beyond +30 on the trunnion swings to the other solution; the G0 of the
    swing passes the tilt through 0 with the axes moving linearly: every pose of it keeps the whole
    tool, holder included, at or above the clearance (the path's highest tip, or --clearance)."""
    machine = load_machine("table-table-ac")
    tool = Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, holder_diameter=30.0, holder_length=40.0, number=1)
    # tilts in the plane where A must be positive, then beyond its +30 travel
    tilt = np.radians([20.0, 25.0, 35.0, 40.0])
    axis = np.column_stack([np.zeros(4), np.sin(tilt), np.cos(tilt)])  # A +20, +25, then -35 at C 180
    # off the A axis: retracted only to the clearance, the swing's G0 would carry the tip 22.8 mm below it
    x0, y0, z0 = -45.086, -56.602, 10.237
    tip = np.array([[x0, y0, z0 + 20], [x0, y0, z0], [x0 + 5, y0, z0], [x0 + 10, y0, z0]])
    tp = Toolpath(tip=tip, axis=axis, rapid=np.array([True, False, False, False]), tool=np.zeros(4, np.int64))
    lines, report = post_program(tp, [tool], machine, clearance=clearance)
    assert report["clearance_z_mm"] == (clearance or z0 + 20)
    assert report["rewinds"] >= 1 and any("swings over" in w for w in report["warnings"]) == (clearance is None)
    poses = _joint_poses(lines)
    jumps = [k for k in range(1, len(poses)) if abs(poses[k, 3] - poses[k - 1, 3]) > 30]
    assert jumps
    s = np.linspace(0, 1, 201)[:, None]
    for k in jumps:
        tips, axes = forward(machine, poses[k - 1] + s * (poses[k] - poses[k - 1]))
        low = tool.lowest_z(tips, axes)
        assert low.min() >= report["clearance_z_mm"] - 1e-3
        assert (tips[:, 2] - low).max() > 0.2  # tilted, the ball reaches lower than the tip
    for bad in (float("nan"), 1e308):
        with pytest.raises(InputError, match="clearance must be a Z"):
            post_program(tp, [tool], machine, clearance=bad)
    _, report = post_program(tp, [tool], machine, clearance=np.float32(20.0))
    assert any("below the path's highest tip" in w for w in report["warnings"])


def test_a_rapid_whose_great_circle_needs_a_tilt_beyond_travel_is_refused_at_its_move():
    """A rapid turning the rotaries follows the great circle between its axes, pose by pose from
    the start: both ends 118 deg from +Z (within A's -120), the circle between them dips to 126.9
    deg, which no tilt of the trunnion reaches: one line naming that rapid (CL move 3), not a pose
    of the circle counted as a move of its own."""
    machine = load_machine("table-table-ac")
    tool = Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, holder_diameter=30.0, holder_length=40.0, number=1)
    s, c = np.sin(np.radians(118.0)), np.cos(np.radians(118.0))
    axis = np.array([[s, 0, c], [s, 0, c], [0, s, c], [0, s, c]])
    tip = np.array([[0.0, 0, 50], [0, 0, 40], [0, 0, 60], [0, 5, 40]])
    tp = Toolpath(tip=tip, axis=axis, rapid=np.array([True, False, True, False]), tool=np.zeros(4, np.int64))
    with pytest.raises(InputError, match=r"^move 3: A -120\.8664 is beyond its travel \[-120, 30\]"):
        post_program(tp, [tool], machine)


def test_a_head_table_tool_without_holder_is_warned():
    machine = load_machine("head-table-bc")
    tp = Toolpath(np.array([[0.0, 0, 5], [5.0, 0, 0]]), np.tile(UP, (2, 1)), np.array([True, False]), np.zeros(2, int))
    bare = Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1)
    _, report = post_program(tp, [bare], machine)
    assert any("no holder in the tool table" in w and "gauge_length = 40 mm" in w for w in report["warnings"])
    held = replace(bare, holder_diameter=30.0, holder_length=50.0)
    _, report = post_program(tp, [held], machine)
    assert not any("no holder" in w for w in report["warnings"])
    _, report = post_program(tp, [bare], load_machine("table-table-ac"))  # the table turns: the length does not enter
    assert not any("no holder" in w for w in report["warnings"])


def test_gcode_texts_filled_in_or_written_as_given(tmp_path, tools):
    machine = _machine_file(tmp_path, "generic-3axis",
                            'start = ["%", "(JOB {A})"]\nspindle = "S{rpm:05d} M3"\ncomment = ";{text}"')
    lines, _ = post_program(_square(), tools, machine)
    assert lines[1] == "(JOB {A})" and "S10000 M3" in lines and lines[2].startswith(";meshmill post for")


def test_each_tool_its_own_spindle_speed(tmp_path, tools):
    fast = [replace(tools[0], rpm=18000.0), *tools[1:]]
    write_tools(tmp_path / "t.toml", fast)
    assert [t.rpm for t in load_tools(tmp_path / "t.toml")] == [t.rpm for t in fast]
    tp = _square()
    tp.tool[:3] = 0
    lines, report = post_program(tp, fast, load_machine("generic-3axis"), clearance=50.0)
    assert [line for line in lines if line.startswith("S")] == ["S18000 M3", "S10000 M3", "S10000 M3"]
    assert any("not used on a 3-axis machine" in w for w in report["warnings"])


def test_rotaries_slowing_a_feed_near_the_pole_are_warned():
    """Tilted 0.5 deg, the axis's azimuth turns 90 deg over 1 mm: C swings 90 deg in a block the
    tip would cut in 12 ms at 5000 mm/min; the block lasts C's turn and a warning says so."""
    machine = load_machine("table-table-ac")
    tools = [Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1)]
    t = np.radians(0.5)
    axis = np.array([[np.sin(t), 0, np.cos(t)], [np.sin(t), 0, np.cos(t)], [0, np.sin(t), np.cos(t)]])
    tp = Toolpath(np.array([[0.0, 0, 5], [0.0, 0, 0], [1.0, 0, 0]]), axis, np.array([True, False, False]), np.zeros(3, int))
    _, report = post_program(tp, tools, machine)
    slow = [w for w in report["warnings"] if "rotaries turn fast" in w]
    assert len(slow) == 1 and "first at move 3" in slow[0] and "near the pole" in slow[0]
    tilted = np.radians(40.0)
    tp.axis[:] = [np.sin(tilted), 0, np.cos(tilted)]
    tp.axis[2] = [np.sin(tilted) * np.cos(0.01), np.sin(tilted) * np.sin(0.01), np.cos(tilted)]
    _, report = post_program(tp, tools, machine)
    assert not any("rotaries turn fast" in w for w in report["warnings"])


def test_a_feed_move_that_turns_the_rotaries_keeps_its_feed():
    """100 mm at 10 mm/s with A turning 10 -> 12 deg: 10 s (G93 F6), 600 mm/min in G94; never the rapid rate."""
    machine = load_machine("table-table-ac")
    tools = [Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1)]
    t = np.radians([10.0, 10.0, 12.0])
    axis = np.c_[np.zeros(3), np.sin(t), np.cos(t)]
    tp = Toolpath(np.array([[0, 0, 5], [0, 0, 0], [100, 0, 0.0]]), axis, np.array([1, 0, 0], bool), np.zeros(3, int))
    for m, want in ((machine, "F6.0000"), (replace(machine, gcode=replace(machine.gcode, inverse_time=False)), "F600.0")):
        lines, _ = post_program(tp, tools, m, feed=10.0)
        cut = [line for line in lines if "X100" in line]
        feeds = set(re.findall(r"F[\d.]+", "\n".join(lines)))
        assert len(cut) == 1 and (cut[0].endswith(want) if m.gcode.inverse_time else feeds == {want})


@pytest.mark.parametrize("noise", [6.8e-8, -6.8e-8])
def test_an_unwind_at_the_end_of_travel_leaves_room_for_the_pose_before(tools, noise):
    """C turning the negative way on head-table-bc (C within +-360) with a pose a hair past -360
    (a CL's rounding): unwinding two turns to +360 would leave the pose before it at +362.8, beyond
    travel, and the cut between would turn C 717 deg; the unwind takes one turn instead."""
    steps = np.arange(0, 300)
    phi = -np.radians(2.8125) * steps
    tilt = np.radians(20.0)
    axis = np.column_stack([np.sin(tilt) * np.cos(phi), np.sin(tilt) * np.sin(phi), np.full(len(phi), np.cos(tilt))])
    axis[128] = [np.sin(tilt), noise, np.cos(tilt)]  # -360 deg, off by the CL's last digit
    tip = np.column_stack([20 * np.cos(phi), 20 * np.sin(phi), np.zeros(len(phi))])
    tip = np.r_[tip[:1] + [0, 0, 10], tip]
    axis = np.r_[axis[:1], axis]
    rapid = np.zeros(len(tip), bool)
    rapid[0] = True
    tp = Toolpath(tip, axis, rapid, np.ones(len(tip), int))
    lines, report = post_program(tp, tools, load_machine("head-table-bc"))
    assert report["rewinds"] >= 1 and report["linearisation"]["max_deviation_mm"] <= 0.005


def _ax(tilt, azimuth):
    t, a = np.radians(tilt), np.radians(azimuth)
    return np.c_[np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)]


def test_long_flutes_are_measured_against_the_curve_of_each_half():
    """A 10 -> 30 deg tilt over 50 mm with 50 mm flutes: each half is compared with the flutes'
    path over its own part of the move (a polyline over the whole move would leave its chord
    error, 0.0118 mm, above the tolerance however often the move is halved)."""
    tool = Tool("B6", "ball", 6.0, 3.0, 50.0, 60.0, 6.0, number=1)
    tp = Toolpath(np.array([[0.0, 0, 10], [0.0, 0, 0], [50.0, 0, 0]]), _ax([10, 10, 30], [0, 0, 0]),
                  np.array([True, False, False]), np.zeros(3, int))
    for name in ("table-table-ac", "head-table-bc"):
        _, report = post_program(tp, [tool], load_machine(name))
        lin = report["linearisation"]
        assert lin["max_deviation_mm"] <= 0.005 and lin["blocks_added"] < 200


@pytest.mark.parametrize("name", ["table-table-ac", "head-table-bc", "head-head-ca"])
@pytest.mark.parametrize("first", [0.0, 0.02, 0.04])
def test_leaving_the_pole_does_not_swing_c_in_the_cut(name, first):
    """From vertical, through a pose `first` deg off the pole (inside the 0.05 deg cone, C held), to
    2, 4, 6 deg at azimuth 90 with the tip 150 mm off C's axis: the blocks keep C from swinging
    where the axis hardly moves, and stay within the tolerance."""
    tool = Tool("B6", "ball", 6.0, 3.0, 6.0, 30.0, 6.0, holder_diameter=30, holder_length=40, number=1)
    tip = np.c_[np.full(6, 150.0), np.arange(6) * 2.0, np.r_[10, 0, 0, 0, 0, 0]]
    tp = Toolpath(tip, _ax([0, 0, first, 2, 4, 6], [0, 0, 0, 90, 90, 90]), np.array([1, 0, 0, 0, 0, 0], bool),
                  np.zeros(6, int))
    _, report = post_program(tp, [tool], load_machine(name), feed=10.0)
    assert report["linearisation"]["max_deviation_mm"] <= 0.005 and report["linearisation"]["blocks_added"] < 40


def test_a_swing_to_the_other_solution_leaves_the_pose_before_within_travel():
    """head-table-bc with C in [-200, 400] and B in [-120, 30]: beyond B +30 the tool swings over
    (C + 180); C -198.3 would leave the pose before at -200.2, beyond travel; C 161.7 does not."""
    base = load_machine("head-table-bc")
    machine = replace(base, limits={**base.limits, "B": (-120.0, 30.0), "C": (-200.0, 400.0)})
    tool = Tool("B6", "ball", 6.0, 3.0, 6.0, 30.0, 6.0, holder_diameter=30, holder_length=40, number=1)
    axis = _ax([28, 29.2, 30.48, 32], [21, 20.234, 18.3, 17])
    tip = np.c_[np.linspace(0, 10, 4), np.zeros(4), np.zeros(4)]
    tp = Toolpath(np.r_[tip[:1] + [0, 0, 20], tip], np.r_[axis[:1], axis], np.array([1, 0, 0, 0, 0], bool),
                  np.zeros(5, int))
    _, report = post_program(tp, [tool], machine, feed=10.0)
    assert report["rewinds"] == 1 and report["linearisation"]["max_deviation_mm"] <= 0.005


def test_a_turn_across_the_end_of_a_one_turn_travel_is_refused(tools):
    """C in [0, 360] cannot unwind: a path turning through its end is refused, naming the move."""
    base = load_machine("head-table-bc")
    machine = replace(base, limits={**base.limits, "C": (0.0, 360.0)})
    phi = np.arange(-341.0, -420.0, -5.0)  # C = -azimuth on the head-table: 341 up past 360 (no pose on it)
    axis = _ax(np.full(len(phi), 30.0), phi)
    tip = np.c_[30 * np.cos(np.radians(phi)), 30 * np.sin(np.radians(phi)), np.zeros(len(phi))]
    tp = Toolpath(np.r_[tip[:1] + [0, 0, 20], tip], np.r_[axis[:1], axis], np.r_[True, np.zeros(len(phi), bool)],
                  np.ones(len(phi) + 1, int))
    with pytest.raises(InputError, match=r"move \d+: the rotaries turn 35\d\.\d deg .* check the rotaries' travel"):
        post_program(tp, tools, machine)


def _near_pole_path(first):
    """From vertical, through a pose ``first`` deg off the pole (at azimuth 0), to 2, 4, 6 deg at
    azimuth 90, the tip 150 mm off C's axis, fed 2 mm a move."""
    tip = np.c_[np.full(6, 150.0), np.arange(6) * 2.0, np.r_[10, 0, 0, 0, 0, 0]]
    return Toolpath(tip, _ax([0, 0, first, 2, 4, 6], [0, 0, 0, 90, 90, 90]), np.array([1, 0, 0, 0, 0, 0], bool),
                    np.zeros(6, int))


def _read_back_stray(lines, machine, tool, tp):
    """mm: how far the program's joint-linear feed blocks (65 poses each) leave the CL feed moves
    of ``tp``, at the tip (from the segments) and ``tool.flute_length`` up the axis (from the
    flutes' top on the CL moves: the tip on its segment, the axis on the great circle, 400 pieces a
    move), read back through the kinematics."""
    length = tool.spindle_length if machine.chain.head_pivot else 0.0
    feed = np.flatnonzero(~tp.rapid[1:]) + 1
    g = np.linspace(0.0, 1.0, 401)[:, None]
    tops = []
    for i in feed:
        a0, a1 = tp.axis[i - 1], tp.axis[i]
        angle = np.arccos(np.clip(a0 @ a1, -1, 1))
        w0, w1 = (np.sin((1 - g) * angle) / np.sin(angle), np.sin(g * angle) / np.sin(angle)) if angle > 1e-12 \
            else (1 - g, g)
        axes = w0 * a0 + w1 * a1
        tops.append(tp.tip[i - 1] + g * (tp.tip[i] - tp.tip[i - 1]) + tool.flute_length * axes)
    s = np.linspace(0.0, 1.0, 65)[:, None]
    blocks = _blocks(lines, machine)
    worst = 0.0
    for b in range(1, len(blocks)):
        if blocks[b][0][0] != 1:
            continue
        tip, axis = forward(machine, blocks[b - 1][1] + s * (blocks[b][1] - blocks[b - 1][1]), length)
        off_tip = _segment_distance(tip, tp.tip[feed - 1], tp.tip[feed]).min(axis=1)
        off_top = np.min([_segment_distance(tip + tool.flute_length * axis, c[:-1], c[1:]).min(axis=1) for c in tops],
                         axis=0)
        worst = max(worst, off_tip.max(), off_top.max())
    return worst


@pytest.mark.parametrize("name", ["table-table-ac", "head-table-bc", "head-head-ca"])
@pytest.mark.parametrize("first", [0.1, 0.3])
def test_a_cut_near_the_pole_is_split_until_it_holds_the_tolerance(name, first):
    """`first` deg off the pole, outside its 0.05 deg cone, with 20 mm flutes: midpoints that kept C
    from swinging left the axis up to 0.05 deg off, and blocks 0.0065 (0.1 deg) and 0.0092 mm (0.3
    deg) off the CL path however often they were halved (written, with a warning); such moves are
    now split again with the axis of every midpoint on the CL move's: the program read back holds
    the 0.005 mm tolerance."""
    machine = load_machine(name)
    tool = Tool("B6", "ball", 6.0, 3.0, 20.0, 60.0, 6.0, holder_diameter=30, holder_length=40, number=1)
    tp = _near_pole_path(first)
    lines, report = post_program(tp, [tool], machine, feed=10.0)
    assert report["linearisation"]["max_deviation_mm"] <= 0.005
    assert _read_back_stray(lines, machine, tool, tp) <= 0.005 + 1e-5


@pytest.mark.parametrize("name", ["table-table-ac", "head-table-bc", "head-head-ca"])
def test_a_pose_the_pole_hold_leaves_beyond_the_tolerance_is_refused(name):
    """0.04 deg off the pole, inside its 0.05 deg cone, where the machine holds C: the pose's own
    axis is off by 0.04 deg, 0.014 mm at the top of 20 mm flutes, which no split mends (it was
    written with a warning, 0.0140 mm over a 0.005 mm tolerance). The post refuses it, naming the
    move and what holds; at the tolerance it gives, the program read back holds it."""
    machine = load_machine(name)
    tool = Tool("B6", "ball", 6.0, 3.0, 20.0, 60.0, 6.0, holder_diameter=30, holder_length=40, number=1)
    tp = _near_pole_path(0.04)
    with pytest.raises(InputError) as refused:
        post_program(tp, [tool], machine, feed=10.0)
    message = str(refused.value)
    assert "the most 0.0140 mm at move 4" in message and "0.040 deg from the pole" in message
    assert "give tolerance 0.014 (which holds)" in message and "TCP" in message and "2 deg away from the pole" in message
    assert refused.value.params == ("tolerance",)
    lines, report = post_program(tp, [tool], machine, feed=10.0, tolerance=0.014)
    assert report["linearisation"]["max_deviation_mm"] <= 0.014
    assert _read_back_stray(lines, machine, tool, tp) <= 0.014 + 1e-5
    if machine.gcode.tcp:
        return
    tcp = replace(machine, gcode=replace(machine.gcode, tcp="G43.4 H{number}"))
    assert post_program(tp, [tool], tcp, feed=10.0)[1]["mode"] == "5-axis TCP"


def test_a_swing_warning_says_what_clearance_to_give():
    """Without a clearance the tool swings over above the path's highest tip; the warning names
    the parameter and the Z to give: that tip where the path's rapids travel there, else that tip
    plus 5 mm."""
    machine = load_machine("table-table-ac")
    tool = Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, holder_diameter=30.0, holder_length=40.0, number=1)
    tilt = np.radians([20.0, 25.0, 35.0, 40.0])
    axis = np.column_stack([np.zeros(4), np.sin(tilt), np.cos(tilt)])  # A beyond +30: the other solution
    tip = np.array([[-45.0, -56.6, 30.2], [-45.0, -56.6, 10.2], [-40.0, -56.6, 10.2], [-35.0, -56.6, 10.2]])
    for rapid, give in (([True, False, False, False], "give clearance 30.2 where nothing"),
                        ([False] * 4, "give clearance 35.2 (that tip plus 5 mm) where nothing")):
        tp = Toolpath(tip=tip, axis=axis, rapid=np.array(rapid), tool=np.zeros(4, np.int64))
        swing = [w for w in post_program(tp, [tool], machine)[1]["warnings"] if "swings over" in w]
        assert len(swing) == 1 and give in swing[0] and "--clearance" not in swing[0], swing


def test_the_program_stages_alone():
    """post_mode says how a machine is posted for; program_blocks gives the blocks before their
    text: on a 5-axis machine, a cut whose axis turns is split, one whose axis stays is not."""
    from meshmill.machine.post import post_mode, program_blocks

    trunnion = load_machine("table-table-ac")
    assert post_mode(load_machine("generic-3axis")) == "3-axis" and post_mode(trunnion) == "5-axis joints"
    with pytest.raises(InputError, match="no \\[gcode\\] 'tcp' text"):
        post_mode(trunnion, tcp=True)
    tool = Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1)
    tip = np.array([[0.0, 0, 20], [0, 0, 0], [40, 0, 0], [80, 0, 0]])
    tp = Toolpath(tip, _ax([10, 10, 10, 30], [0, 0, 0, 0]), np.array([1, 0, 0, 0], bool), np.zeros(4, int))
    program = program_blocks(tp, [tool], np.full(4, 10.0), trunnion, "5-axis joints", 0.005)
    (run,) = program.runs
    assert program.rewinds == 0 and 0 < program.largest <= 0.005 and program.blocks_added == run.added.sum() > 0
    assert set(run.move[run.added]) == {3}  # only the move whose axis turns
