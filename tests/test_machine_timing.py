"""Machine time: jerk-limited segments, tool paths, machine files and ``meshmill time``."""
import json
import math

import numpy as np
import pytest

from meshmill.cli import main
from conftest import one_line_error
from meshmill.errors import InputError
from meshmill.machine.config import load_machine, shipped_machines
from meshmill.machine.model import Machine
from meshmill.machine.model import MotionLimits
from meshmill.machine.timing import path_time, programmed_feeds, segment_time, tool_times
from meshmill.toolpath.cldata import write_apt
from meshmill.toolpath.model import Toolpath

SEED = MotionLimits.seed()  # V 83.3 mm/s, A 6000 mm/s², J 40000 mm/s³: A²/J = 900 > V
FAST = MotionLimits(feed=500.0, accel=4000.0, jerk=50000.0, rapid=500.0)  # A²/J = 320 < V


# --- segment_time -----------------------------------------------------------------------------------

def test_segment_time_matches_the_seeds_closed_forms_in_each_case():
    V, A, J = FAST.feed, FAST.accel, FAST.jerk
    L = 300.0  # case 1, V and A reached: L >= V (V/A + A/J) = 102.5
    assert segment_time(L, V, A, J) == pytest.approx(L / V + V / A + A / J, rel=1e-12)
    L = 80.0  # A reached, V not: 2 A³/J² = 51.2 < L < 102.5
    assert segment_time(L, V, A, J) == pytest.approx(A / J + math.sqrt((A / J) ** 2 + 4 * L / A), rel=1e-12)
    V, A, J = SEED.feed, SEED.accel, SEED.jerk
    L = 50.0  # case 2, V reached, A not: L >= 2 V sqrt(V/J) = 7.6
    assert segment_time(L, V, A, J) == pytest.approx(L / V + 2 * math.sqrt(V / J), rel=1e-12)
    L = 1.0  # case 3, neither: peak speed cbrt(L² J / 4) = 21.5 < V
    assert segment_time(L, V, A, J) == pytest.approx(4 * np.cbrt(L / (2 * J)), rel=1e-12)
    lengths = np.array([0.0, 1.0, 50.0])
    assert np.allclose(segment_time(lengths, V, A, J), [segment_time(x, V, A, J) for x in lengths], rtol=1e-15)


@pytest.mark.parametrize("kin", [FAST, SEED], ids=["A-reached", "seed"])
def test_segment_time_is_continuous_and_increasing(kin):
    V, A, J = kin.feed, kin.accel, kin.jerk
    v_a = A * A / J
    if V >= v_a:  # case 1 | A reached, V not | case 3
        bounds = [V * (V / A + A / J), 2 * v_a * math.sqrt(v_a / J)]
    else:  # case 2 | case 3
        bounds = [2 * V * math.sqrt(V / J)]
    for b in bounds:
        below, above = segment_time(b * (1 - 1e-9), V, A, J), segment_time(b * (1 + 1e-9), V, A, J)
        assert abs(above - below) < 1e-8 * above
    t = segment_time(np.geomspace(1e-4, 1e4, 2001), V, A, J)
    assert (np.diff(t) > 0).all()
    # continuous in V across A²/J too
    assert segment_time(100.0, v_a * (1 - 1e-9), A, J) == pytest.approx(segment_time(100.0, v_a * (1 + 1e-9), A, J),
                                                                        rel=1e-8)


def _speed_up(v_peak, A, J, steps=2000):
    """Time and distance to speed up from rest to ``v_peak`` by simulating the S-curve: jerk +J
    until the acceleration reaches A, then 0, then -J from the moment that ramping the acceleration
    down (which gains a²/2J) reaches v_peak, until the acceleration is 0. The motion is exact within
    a time step; the switch from +J to -J falls on a step (``steps`` in the shortest jerk phase)."""
    dt = min(A / J, math.sqrt(v_peak / J)) / steps
    t = x = v = a = 0.0
    down = False
    while True:
        down = down or v + a * a / (2 * J) >= v_peak
        if down:
            h = min(dt, a / J)
            x, v, t = x + v * h + a * h * h / 2 - J * h ** 3 / 6, v + a * h - J * h * h / 2, t + h
            if h == a / J:
                return t, x
            a -= J * h
        elif a >= A:  # hold A until ramping down from A reaches v_peak
            h = (v_peak - A * A / (2 * J) - v) / A
            x, v, t, down = x + v * h + A * h * h / 2, v + A * h, t + h, True
        else:
            h = min(dt, (A - a) / J)
            x, v, t = x + v * h + a * h * h / 2 + J * h ** 3 / 6, v + a * h + J * h * h / 2, t + h
            a = min(a + J * h, A)


def _brute_segment_time(L, V, A, J):
    """Rest to rest: speed up to the highest v <= V whose speed-up and (mirrored) slow-down fit in
    L, cruise over the rest."""
    t, x = _speed_up(V, A, J)
    if 2 * x <= L:
        return 2 * t + (L - 2 * x) / V
    lo, hi = 0.0, V
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if 2 * _speed_up(mid, A, J)[1] <= L else (lo, mid)
    return 2 * _speed_up(lo, A, J)[0]


def test_segment_time_against_a_simulated_s_curve():
    rng = np.random.default_rng(2)
    cases = [(L, k.feed, k.accel, k.jerk) for L, k in ((300.0, FAST), (80.0, FAST), (50.0, SEED), (1.0, SEED))]
    for _ in range(10):
        cases.append((10 ** rng.uniform(-2, 2.7), rng.uniform(20, 600), rng.uniform(500, 10000),
                      10 ** rng.uniform(3.7, 5.3)))
    for L, V, A, J in cases:
        assert segment_time(L, V, A, J) == pytest.approx(_brute_segment_time(L, V, A, J), rel=2e-3), (L, V, A, J)


# --- path_time ----------------------------------------------------------------------------------------

def seed_machine(corner_deg=5.0, tool_change=8.0):
    return Machine(name="seed", motion=SEED, corner_angle=math.radians(corner_deg), tool_change=tool_change,
                   reorient=3.0)


def test_square_stops_at_its_four_corners():
    tip = np.array([[0, 0, 0], [50, 0, 0], [50, 50, 0], [0, 50, 0], [0, 0, 0]], float)
    r = path_time(tip, np.zeros(5, bool), seed_machine())
    assert r["stops"] == 4 and r["cutting_mm"] == pytest.approx(200) and r["rapid_mm"] == 0 and r["rapid_s"] == 0
    assert r["cutting_s"] == pytest.approx(4 * segment_time(50.0, SEED.feed, SEED.accel, SEED.jerk), rel=1e-12)
    assert r["total_s"] == r["cutting_s"]
    # the same square in 1 mm steps: straight steps run through, the corners still stop
    fine = np.concatenate([np.linspace(tip[i], tip[i + 1], 51)[:-1] for i in range(4)] + [tip[-1:]])
    assert path_time(fine, np.zeros(len(fine), bool), seed_machine()) == pytest.approx(r, rel=1e-12)


def test_fine_arc_is_one_run_below_the_corner_angle():
    angle = np.linspace(0, 0.75 * math.pi, 1001)  # 0.135° a step
    tip = np.column_stack([40 * np.cos(angle), 40 * np.sin(angle), np.zeros_like(angle)])
    r = path_time(tip, np.zeros(len(tip), bool), seed_machine())
    chords = np.linalg.norm(np.diff(tip, axis=0), axis=1).sum()
    assert r["stops"] == 1 and r["cutting_mm"] == pytest.approx(chords, rel=1e-12)
    assert r["cutting_s"] == pytest.approx(segment_time(chords, SEED.feed, SEED.accel, SEED.jerk), rel=1e-12)
    # with a corner angle under the step, every vertex stops
    coarse = path_time(tip, np.zeros(len(tip), bool), SEED, corner_angle=math.radians(0.1))
    assert coarse["stops"] == 1000 and coarse["total_s"] > 10 * r["total_s"]


def test_rapids_and_feeds_are_separate_runs():
    tip = np.array([[0, 0, 50], [0, 0, 2], [0, 0, 0], [100, 0, 0], [100, 0, 50], [0, 0, 50]], float)
    rapid = np.array([False, True, False, False, True, True])
    r = path_time(tip, rapid, seed_machine())
    seg = lambda L, v: segment_time(L, v, SEED.accel, SEED.jerk)  # noqa: E731
    # rapid down 48; feed 2 down then 100 across (a 90° corner); rapid up 50, then back 100 (90° corner)
    assert r["stops"] == 5
    assert r["rapid_mm"] == pytest.approx(198) and r["cutting_mm"] == pytest.approx(102)
    assert r["cutting_s"] == pytest.approx(seg(2, SEED.feed) + seg(100, SEED.feed), rel=1e-12)
    assert r["rapid_s"] == pytest.approx(seg(48, SEED.rapid) + seg(50, SEED.rapid) + seg(100, SEED.rapid), rel=1e-12)
    # collinear rapid then feed: still two runs
    line = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0]], float)
    assert path_time(line, np.array([False, True, False]), seed_machine())["stops"] == 2


def test_zero_length_moves_neither_stop_nor_give_nan():
    tip = np.array([[0, 0, 0], [50, 0, 0], [50, 50, 0], [0, 50, 0], [0, 0, 0]], float)
    repeated = np.repeat(tip, 3, axis=0)
    r = path_time(tip, np.zeros(5, bool), seed_machine())
    assert path_time(repeated, np.zeros(15, bool), seed_machine()) == pytest.approx(r, rel=1e-12)
    # a zero-length move flagged rapid between feeds changes nothing either
    rapid = np.zeros(15, bool)
    rapid[4] = True
    assert path_time(repeated, rapid, seed_machine()) == pytest.approx(r, rel=1e-12)
    for still in (np.zeros((4, 3)), np.zeros((1, 3)), np.zeros((0, 3))):
        r0 = path_time(still, np.zeros(len(still), bool), seed_machine())
        assert r0 == {"total_s": 0.0, "cutting_s": 0.0, "rapid_s": 0.0, "cutting_mm": 0.0, "rapid_mm": 0.0, "stops": 0}


def test_per_move_feed():
    line = np.array([[0, 0, 0], [30, 0, 0], [100, 0, 0]], float)
    rapid = np.zeros(3, bool)
    m = seed_machine()
    nominal = path_time(line, rapid, m)
    assert path_time(line, rapid, m, feed=np.full(3, np.nan)) == pytest.approx(nominal, rel=1e-15)
    assert path_time(line, rapid, m, feed=np.full(3, SEED.feed)) == pytest.approx(nominal, rel=1e-12)
    # two feeds on one straight run: one run whose cruise time is that of each move at its feed
    slow = path_time(line, rapid, m, feed=np.array([np.nan, 10.0, 50.0]))
    v = 100.0 / (30 / 10.0 + 70 / 50.0)
    assert slow["stops"] == 1
    assert slow["cutting_s"] == pytest.approx(segment_time(100.0, v, SEED.accel, SEED.jerk), rel=1e-12)
    # faster than the rapid rate is capped at it; rapids ignore the feed
    assert path_time(line, rapid, m, feed=np.full(3, 1e6))["cutting_s"] == pytest.approx(
        segment_time(100.0, SEED.rapid, SEED.accel, SEED.jerk), rel=1e-12)
    assert path_time(line, ~rapid, m, feed=np.full(3, 1.0))["rapid_s"] == pytest.approx(
        segment_time(100.0, SEED.rapid, SEED.accel, SEED.jerk), rel=1e-12)
    with pytest.raises(ValueError):
        path_time(line, rapid, m, feed=np.array([1.0, -1.0, 1.0]))
    with pytest.raises(ValueError):
        path_time(line, rapid, SEED)  # bare MotionLimits need a corner angle


def test_tool_times_add_tool_changes():
    sq = np.array([[0, 0, 0], [50, 0, 0], [50, 50, 0], [0, 50, 0], [0, 0, 0]], float)
    tip = np.concatenate([sq, sq + [0, 0, -1], sq])
    tool = np.repeat([2, 0, 2], 5)
    rapid = np.zeros(15, bool)
    rapid[[5, 10]] = True  # each tool's first move is a rapid (0.. -1 mm down, then up)
    m = seed_machine(tool_change=7.5)
    r = tool_times(tip, rapid, tool, m)
    assert list(r["tools"]) == [2, 0]
    t2, t0, total = r["tools"][2], r["tools"][0], r["total"]
    assert t2["tool_changes"] == 1 and t0["tool_changes"] == 1 and total["tool_changes"] == 2
    assert total["tool_change_s"] == 15.0 and t0["tool_change_s"] == 7.5
    assert t2["stops"] == 4 + 1 + 4 and t0["stops"] == 4 + 1
    for key in ("cutting_s", "rapid_s", "cutting_mm", "rapid_mm", "stops", "total_s"):
        assert total[key] == pytest.approx(t2[key] + t0[key], rel=1e-12)
    assert total["total_s"] == pytest.approx(total["cutting_s"] + total["rapid_s"] + 15.0, rel=1e-12)
    assert total["cutting_s"] == pytest.approx(3 * path_time(sq, np.zeros(5, bool), m)["cutting_s"], rel=1e-12)


def test_path_time_is_vectorised():
    angle = np.linspace(0, 400 * math.pi, 1_000_001)
    tip = np.column_stack([40 * np.cos(angle), 40 * np.sin(angle), np.linspace(0, -20, len(angle))])
    rapid = np.zeros(len(tip), bool)
    rapid[::1000] = True
    tool = np.searchsorted([250_500, 500_500, 750_500], np.arange(len(tip)), side="right")
    r = tool_times(tip, rapid, tool, seed_machine())
    # 1000 rapid moves (every 1000th), the feed runs between them, three of those split by a tool change
    assert r["total"]["stops"] == 2000 + 3 and r["total"]["tool_changes"] == 3
    assert r["total"]["cutting_mm"] + r["total"]["rapid_mm"] == pytest.approx(
        np.linalg.norm(np.diff(tip, axis=0), axis=1).sum(), rel=1e-12)


# --- machine files -----------------------------------------------------------------------------------

MACHINE_TOML = """name = "test VMC"
[motion]
feed_mm_min = 5000
rapid_mm_min = 20000
accel_mm_s2 = 6000
jerk_mm_s3 = 40000
corner_angle_deg = 5
tool_change_s = 8
reorient_s = 3
"""


def test_machine_files_load():
    assert {"generic-3axis", "seed-002"} <= set(shipped_machines())
    seed = load_machine("seed-002")
    assert seed.motion == MotionLimits.seed()
    assert seed.corner_angle == pytest.approx(math.radians(5)) and seed.tool_change == 8 and seed.reorient == 3
    generic = load_machine("generic-3axis")
    assert generic.motion.rapid > generic.motion.feed and generic.path.endswith("generic-3axis.toml")
    assert generic.summary()["feed_mm_min"] == pytest.approx(4000)


@pytest.mark.parametrize("text, words", [
    (None, ["no such machine file"]),
    ("name = 'x'\n[motion\nfeed_mm_min = 1", ["not a valid TOML"]),
    (MACHINE_TOML.replace("jerk_mm_s3 = 40000", "jerk_mm_s3 = -40000"), ["[motion]", "jerk_mm_s3", "> 0"]),
    (MACHINE_TOML.replace("jerk_mm_s3 = 40000", "jerk_mm_s3 = 0"), ["jerk_mm_s3", "> 0"]),
    (MACHINE_TOML.replace("jerk_mm_s3 = 40000", "jerk_mm_s3 = nan"), ["jerk_mm_s3", "finite"]),
    (MACHINE_TOML.replace("accel_mm_s2 = 6000", "accel_mm_s2 = '6000'"), ["accel_mm_s2", "number"]),
    (MACHINE_TOML.replace("accel_mm_s2 = 6000", "accel_mm_s2 = true"), ["accel_mm_s2", "number"]),
    (MACHINE_TOML.replace("jerk_mm_s3", "jerk"), ["unknown key 'jerk'"]),
    (MACHINE_TOML.replace("reorient_s = 3\n", ""), ["missing key 'reorient_s'"]),
    (MACHINE_TOML + "[coolant]\nflood = true\n", ["unknown section", "coolant"]),
    (MACHINE_TOML + "[spindle]\nmax_rpm = 500\nmin_rpm = 600\n", ["[spindle]", "'min_rpm' must be below 'max_rpm'"]),
    (MACHINE_TOML + "[spindle]\npower_kw = -3\n", ["[spindle]", "power_kw", "> 0"]),
    (MACHINE_TOML + "[axes]\nx_mm = 500\n", ["unknown axis", "x_mm"]),
    (MACHINE_TOML.replace('name = "test VMC"', "colour = 'red'"), ["unknown", "colour"]),
    (MACHINE_TOML.replace('name = "test VMC"', "name = 3"), ["'name'"]),
    ('name = "x"\n', ["missing section [motion]"]),
    ('name = "x"\nmotion = 5\n', ["'motion' must be a table"]),
    (MACHINE_TOML.replace("feed_mm_min = 5000", "feed_mm_min = 50000"), ["feed_mm_min", "rapid_mm_min"]),
    (MACHINE_TOML.replace("corner_angle_deg = 5", "corner_angle_deg = 180"), ["corner_angle_deg", "180"]),
    # [axes], [kinematics], [gcode]
    (MACHINE_TOML + "[axes]\nX = [5, -5]\n", ["'X'", "low < high"]),
    (MACHINE_TOML + "[axes]\nX = [0, nan]\n", ["'X'"]),
    (MACHINE_TOML + "[axes]\nQ = [0, 1]\n", ["unknown axis 'Q'"]),
    (MACHINE_TOML + "[axes]\nA = [0, 90]\n", ["'A' is not a rotary axis of this machine"]),
    (MACHINE_TOML + "[kinematics]\ntype = 'robot'\n", ["'type'", "robot"]),
    (MACHINE_TOML + "[kinematics]\ntype = 'table-table'\nrotary = ['C', 'A']\n", ["'rotary'"]),
    (MACHINE_TOML + "[kinematics]\ntype = 'table-table'\nrotary = ['A', 'B']\n", ["'rotary'"]),
    (MACHINE_TOML + "[kinematics]\ntype = 'head-table'\nrotary = ['B', 'C']\nhead_length_mm = -5\n", ["'head_length_mm'"]),
    (MACHINE_TOML + "[kinematics]\ntype = 'table-table'\nrotary = ['A', 'C']\npivot_mm = [0, 0]\n", ["'pivot_mm'"]),
    (MACHINE_TOML + "[kinematics]\ntype = 'table-table'\nrotary = ['A', 'C']\nreversed = ['B']\n", ["'reversed'"]),
    (MACHINE_TOML + "[kinematics]\ntype = '3-axis'\nrotary = ['A', 'C']\n", ["3-axis machine has no 'rotary'"]),
    (MACHINE_TOML + "[kinematics]\nsingular_deg = 45\n", ["'singular_deg'"]),
    (MACHINE_TOML + "[gcode]\ndialect = 'heidenhain'\n", ["'dialect'"]),
    (MACHINE_TOML + "[gcode]\ndecimals = 12\n", ["'decimals'"]),
    (MACHINE_TOML + "[gcode]\nangle_decimals = 0\n", ["'angle_decimals'", "from 2 to 8"]),
    (MACHINE_TOML + "[gcode]\ninverse_time = 'yes'\n", ["'inverse_time'"]),
    (MACHINE_TOML + "[gcode]\nstart = 'G21'\n", ["'start'"]),
    (MACHINE_TOML + "[gcode]\nbeep = 1\n", ["unknown key 'beep'"]),
    (MACHINE_TOML + "[gcode]\ntool_change = 'T{num} M6'\n", ["'tool_change'", "unknown field {num}", "{number}"]),
    (MACHINE_TOML + "[gcode]\nrapid = 'fast'\n", ["'rapid' must be one of linear, dogleg"]),
    (MACHINE_TOML + "[gcode]\ncomment = '({text)'\n", ["'comment'", "expected '}'"]),
    (MACHINE_TOML + "[gcode]\ncomment = '({text} {number})'\n", ["'comment'", "unknown field {number}", "{text}"]),
    (MACHINE_TOML + "[gcode]\nspindle = 'S{rpm:s} M3'\n", ["'spindle'", "format code 's'"]),
    (MACHINE_TOML + "[gcode]\ntool_change = 'T{number:>2000000000} M6'\n", ["'tool_change'", "too wide"]),
    (MACHINE_TOML + "[gcode]\nspindle = 'S{rpm:>{rpm}}'\n", ["'spindle'", "nested"]),
    (MACHINE_TOML + "[gcode]\nrpm = 2000000\n", ["'rpm' must be below"]),
    (MACHINE_TOML + "[motion]\n", []),  # a second [motion] table is a TOML error
])
def test_bad_machine_files(tmp_path, text, words):
    p = tmp_path / "m.toml"
    if text is not None:
        p.write_text(text)
    with pytest.raises(InputError) as e:
        load_machine(p)
    message = str(e.value)
    assert str(p) in message and "\n" not in message
    for w in words:
        assert w in message


def test_machine_file_values(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text(MACHINE_TOML.replace("tool_change_s = 8", "tool_change_s = 0"))
    m = load_machine(p)
    assert m.name == "test VMC" and m.tool_change == 0.0 and m.motion.feed == pytest.approx(5000 / 60)
    p.write_text(MACHINE_TOML.replace('name = "test VMC"\n', ""))
    assert load_machine(p).name == "m"


# --- programmed feeds ----------------------------------------------------------------------------------

def test_programmed_feeds(tmp_path):
    cl = tmp_path / "f.cl"
    cl.write_text("LOADTL/1\nRAPID\nGOTO/0,0,10\nGOTO/0,0,5\nFEDRAT/600\nGOTO/0,0,0\n$$ FEDRAT/1\n"
                  "FEDRAT/ IPM, 10 $$ inch\nGOTO/1,0,0\nFEDRAT/MMPR, 0.1\nGOTO/2,0,0\nFINI\n")
    feed, warnings = programmed_feeds(cl, np.array([3, 4, 6, 9, 11]), gcode=False)
    assert np.isnan(feed[[0, 1, 4]]).all() and feed[2] == pytest.approx(600.0) and feed[3] == pytest.approx(254.0)
    assert len(warnings) == 1 and "line 10" in warnings[0]
    nc = tmp_path / "f.nc"
    nc.write_text("G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F300 (FAST)\nX10\nG20\nX1 F10 ; inch\nG0 Z1\n")
    feed, warnings = programmed_feeds(nc, np.array([2, 3, 4, 6, 7]), gcode=True)
    assert np.isnan(feed[0]) and np.allclose(feed[1:], [300.0, 300.0, 254.0, 254.0]) and not warnings


def test_feed_statements_are_found_at_the_start_of_their_lines_in_any_case(tmp_path):
    # spaces or tabs before the word and the slash, any case, a comment after: read; a word that
    # only contains FEDRAT, one after a comment or after another word on its line, or without
    # its slash: not a feed statement (a lone CR ends a line, as the file is read)
    cl = tmp_path / "w.cl"
    cl.write_text("LOADTL/1\n  fedrat / 200, ipm $$ inch\r\nGOTO/0,0,0\n\tFedRat\t/ 5,MMPR\nGOTO/1,0,0\n"
                  "XFEDRAT/3\nFEDRATE/4\n$$ FEDRAT/5\nGOTO FEDRAT/6\nFEDRAT 7\nGOTO/1,1,0\n"
                  "FEDRAT/1e3, MMPM\rGOTO/9,9,9\nGOTO/2,0,0\nFEDRAT/300\nGOTO/3,0,0\n", newline="")
    feed, warnings = programmed_feeds(cl, np.array([3, 5, 11, 13, 14, 16]), gcode=False)
    assert feed[0] == pytest.approx(5080.0) and np.isnan(feed[1:3]).all()
    assert feed[3] == feed[4] == pytest.approx(1000.0) and feed[5] == pytest.approx(300.0)
    assert len(warnings) == 1 and "line 4" in warnings[0]


# --- meshmill time -------------------------------------------------------------------------------------

def _cl(tmp_path, tools):
    sq = np.array([[0, 0, 0], [50, 0, 0], [50, 50, 0], [0, 50, 0], [0, 0, 0]], float)
    tip = np.concatenate([[[0, 0, 20]], sq, [[0, 0, 20], [100, 0, 20]], sq + [100, 0, 0], [[100, 0, 20]]])
    rapid = np.zeros(len(tip), bool)
    rapid[[0, 6, 7, 8, 13]] = True
    tool = np.array([1] * 7 + [3] * 7)
    tp = Toolpath(tip=tip, axis=np.tile([0.0, 0.0, 1.0], (len(tip), 1)), rapid=rapid, tool=tool)
    path = tmp_path / "job.cl"
    write_apt(path, tp, tools)
    return path, tp


def test_time_command(tmp_path, tools, tools_file, capsys):
    cl, tp = _cl(tmp_path, tools)
    out = tmp_path / "time.json"
    rc = main(["time", str(cl), "--machine", "seed-002", "--tools", str(tools_file), "--out", str(out)])
    text = capsys.readouterr().out
    assert rc == 0
    assert "no feed programmed" in text and "5000 mm/min" in text and "B10" in text and "B2" in text
    summary = json.loads(out.read_text())
    expected = tool_times(tp.tip, tp.rapid, tp.tool, load_machine("seed-002"))
    assert summary["total"] == pytest.approx(expected["total"], rel=1e-9)
    assert summary["tools"]["B2"] == pytest.approx(expected["tools"][3], rel=1e-9)
    assert summary["total"]["tool_changes"] == 1 and summary["total"]["cutting_mm"] == pytest.approx(420)  # 20 mm plunge
    assert summary["feed_moves_at_machine_feed"] == summary["feed_moves"] == 9
    assert f"{summary['total']['total_s']:.1f}" in text
    rc = main(["time", str(cl), "--machine", "seed-002", "--tools", str(tools_file), "--json", "--feed", "2500"])
    captured = capsys.readouterr()
    assert rc == 0 and not captured.err
    fast = json.loads(captured.out)
    assert fast["total"]["cutting_s"] > summary["total"]["cutting_s"] and "2500 mm/min on every feed move" in fast["notes"][0]


def test_time_command_reads_gcode_feeds(tmp_path, tools_file, capsys):
    nc = tmp_path / "job.nc"
    nc.write_text("T2 M6\nG0 X0 Y0 Z5\nG1 Z0 F600\nX50\nY50\nX0\nY0\nG0 Z5\n")
    rc = main(["time", str(nc), "--machine", "seed-002", "--tools", str(tools_file), "--json"])
    summary = json.loads(capsys.readouterr().out)
    assert rc == 0 and summary["notes"] == ["feeds as programmed"] and summary["tools"]["B10"]["stops"] == 6
    seg = segment_time(50.0, 10.0, SEED.accel, SEED.jerk)
    assert summary["total"]["cutting_s"] == pytest.approx(segment_time(5.0, 10.0, SEED.accel, SEED.jerk) + 4 * seg)


def test_time_command_bad_input(tmp_path, tools, tools_file, capsys):
    cl, _ = _cl(tmp_path, tools)
    t = str(tools_file)
    bad = tmp_path / "bad.toml"
    bad.write_text(MACHINE_TOML.replace("jerk_mm_s3 = 40000", "jerk_mm_s3 = -1"))
    assert "jerk_mm_s3" in one_line_error(capsys, ["time", str(cl), "--machine", str(bad), "--tools", t])
    assert "no such machine file" in one_line_error(capsys, ["time", str(cl), "--machine", "nope.toml", "--tools", t])
    assert "--feed" in one_line_error(capsys, ["time", str(cl), "--machine", "seed-002", "--tools", t, "--feed", "-5"])
    assert "no such CL file" in one_line_error(capsys, ["time", str(tmp_path / "x.cl"), "--machine", "seed-002",
                                                         "--tools", t])
    one_line_error(capsys, ["time", str(cl), "--tools", t])  # no --machine
    # no --tools: the tools.toml beside the path, else one line
    assert main(["time", str(cl), "--machine", "seed-002", "--json"]) == (0 if (cl.parent / "tools.toml").exists() else 2)
    capsys.readouterr()
    alone = tmp_path / "alone"
    alone.mkdir()
    (alone / "job.cl").write_text(cl.read_text())
    assert "no --tools given" in one_line_error(capsys, ["time", str(alone / "job.cl"), "--machine", "seed-002"])


def test_rotary_axes_bound_the_time_of_a_5axis_path():
    """The tool axis circling at 30 deg tilt with the tip nearly still: C turns 360 deg, which at
    the trunnion's 9000 deg/min takes 2.4 s, far longer than the 1 mm of linear motion."""
    from meshmill.machine.config import load_machine
    from meshmill.machine.timing import rotary_seconds

    m = load_machine("table-table-ac")
    t = np.linspace(0.0, 2 * np.pi, 73)
    axis = np.column_stack([0.5 * np.cos(t), 0.5 * np.sin(t), np.full(len(t), np.sqrt(0.75))])
    tip = np.column_stack([np.linspace(0, 1, len(t)), np.zeros(len(t)), np.zeros(len(t))])
    rapid = np.zeros(len(t), bool)
    rot = rotary_seconds(m, tip, axis)
    assert rot.sum() == pytest.approx(360.0 / 150.0, rel=1e-9)
    assert path_time(tip, rapid, m)["total_s"] < 0.2
    assert path_time(tip, rapid, m, rotary_s=rot)["total_s"] == pytest.approx(2.4, rel=1e-9)
    assert rotary_seconds(load_machine("generic-3axis"), tip, axis) is None


def test_time_of_a_posted_5axis_program_matches_its_cl(tmp_path, capsys):
    """CL -> post (G93 inverse-time feeds) -> time: the program's time (its F words read back as
    block times) agrees with the CL file's at the machine's feed, rotaries included."""
    from meshmill.machine.config import load_machine
    from meshmill.machine.post import post_program
    from meshmill.tools.table import Tool, write_tools

    tools = [Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1)]
    k = 60
    t = np.linspace(0.0, 1.0, k)
    tilt, turn = np.radians(10 + 30 * t), np.radians(-40 + 160 * t)
    axis = np.column_stack([np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn), np.cos(tilt)])
    tip = np.column_stack([30 * np.cos(2 * np.pi * t), 30 * np.sin(2 * np.pi * t), 5 * t])
    tip = np.concatenate([[tip[0] + [0, 0, 20]], tip, [tip[-1] + [0, 0, 20]]])
    axis = np.concatenate([axis[:1], axis, axis[-1:]])
    rapid = np.zeros(k + 2, bool)
    rapid[[0, -1]] = True
    tp = Toolpath(tip=tip, axis=axis, rapid=rapid, tool=np.zeros(k + 2, np.int64))
    write_apt(tmp_path / "job.cl", tp, tools)
    write_tools(tmp_path / "tools.toml", tools)
    machine = load_machine("table-table-ac")
    lines, report = post_program(tp, tools, machine, tolerance=0.005)
    (tmp_path / "job.nc").write_text("\n".join(lines) + "\n")
    assert report["feed_mode"].startswith("G93")
    times = {}
    for name in ("job.cl", "job.nc"):
        assert main(["time", str(tmp_path / name), "--machine", "table-table-ac", "--json"]) == 0
        times[name] = json.loads(capsys.readouterr().out)["total"]
    # the final 20 mm rapid moves X Y and Z of the trunnion: G1 at the rapid rate (Fanuc's G0 is a dog-leg)
    assert times["job.nc"]["cutting_mm"] == pytest.approx(times["job.cl"]["cutting_mm"] + 20.0, rel=1e-3)
    assert times["job.nc"]["total_s"] == pytest.approx(times["job.cl"]["total_s"], rel=0.05)


def test_g93_does_not_inherit_the_feed_per_minute(tmp_path):
    """After G93 a block with no F has no feed (NaN: the machine's), not the G94 feed before it;
    a G93 F is 1 / the block's minutes."""
    from meshmill.machine.timing import programmed_feeds

    nc = tmp_path / "p.nc"
    nc.write_text("G94 G1 X10 F600\nG93 G1 X20 F30\nX30\nG94 X40 F1200\n")
    tip = np.array([[0, 0, 0], [10, 0, 0], [20, 0, 0], [30, 0, 0], [40, 0, 0]], float)
    feed, _ = programmed_feeds(nc, [0, 1, 2, 3, 4], True, tip)
    assert feed[1] == pytest.approx(600.0)  # mm/min
    assert feed[2] == pytest.approx(10.0 * 30)  # 10 mm in 1/30 min
    assert np.isnan(feed[3]) and feed[4] == pytest.approx(1200.0)


def test_time_on_a_head_table_machine(tmp_path, capsys):
    """Tool lengths per move (head-table) reach the kinematics without a crash."""
    from meshmill.tools.table import Tool, write_tools

    tools = [Tool("B6", "ball", 6.0, 3.0, 20.0, 40.0, 6.0, number=1), Tool("B4", "ball", 4.0, 2.0, 10.0, 30.0, 4.0, number=2)]
    k = 20
    t = np.linspace(0, 1, k)
    axis = np.column_stack([np.sin(0.5 * t), np.zeros(k), np.cos(0.5 * t)])
    tip = np.column_stack([20 * t, np.zeros(k), np.zeros(k)])
    tp = Toolpath(tip=tip, axis=axis, rapid=np.zeros(k, bool), tool=(t > 0.5).astype(np.int64))
    write_apt(tmp_path / "job.cl", tp, tools)
    write_tools(tmp_path / "tools.toml", tools)
    assert main(["time", str(tmp_path / "job.cl"), "--machine", "head-table-bc", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["total"]["tool_changes"] == 1 and out["total"]["total_s"] > 0
