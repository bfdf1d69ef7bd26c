"""Machine kinematics (meshmill.machine.kinematics): forward and inverse transforms of the 3-axis,
table-table, head-table and head-head chains, the choice of solution along a path, travel limits."""
import dataclasses
import math
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from meshmill.errors import InputError
from meshmill.machine.config import load_machine, shipped_machines
from meshmill.machine.kinematics import AxisLimitError, angle_step, forward, inverse

FIVE_AXIS = ["table-table-ac", "head-table-bc", "head-head-ca"]
THREE_AXIS = ["generic-3axis", "linuxcnc-3axis", "grbl-3axis"]
TOOL_LENGTH = 50.0


def variant(name, limits=None, **chain):
    """A shipped machine with some of its chain's fields (and its limits) replaced."""
    machine = load_machine(name)
    return dataclasses.replace(machine, chain=dataclasses.replace(machine.chain, **chain),
                               limits=machine.limits if limits is None else limits)


def unit(polar_deg, azimuth_deg):
    """Unit vectors ``(k, 3)`` at polar angles from +Z and azimuths (deg)."""
    polar, azimuth = np.radians(polar_deg), np.radians(azimuth_deg)
    return np.stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)], axis=-1)


def angle_between(a, b):
    """Angle (rad) between rows of unit vectors ``a`` and ``b`` ``(k, 3)``."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))


def assert_within_travel(machine, joints):
    for column, letter in enumerate(machine.axes):
        if letter in machine.limits:
            low, high = machine.limits[letter]
            assert (joints[:, column] >= low - 1e-9).all() and (joints[:, column] <= high + 1e-9).all(), letter


def reachable_poses(machine, k, rng):
    """k random poses: tips in a ball that every orientation keeps within travel, axes within the
    tilt's travel (both signs) and off the pole."""
    tilt_low, tilt_high = machine.limits[machine.chain.rotary[0]]
    reach = min(-tilt_low, tilt_high) if machine.chain.type != "table-table" else max(-tilt_low, tilt_high)
    cos_polar = rng.uniform(math.cos(math.radians(reach)), math.cos(math.radians(0.2)), k)
    axis = unit(np.degrees(np.arccos(cos_polar)), rng.uniform(-180.0, 180.0, k))
    direction = rng.normal(size=(k, 3))
    tip = direction / np.linalg.norm(direction, axis=1)[:, None] * rng.uniform(0.0, 100.0, k)[:, None]
    return tip, axis


def test_every_shipped_five_axis_machine_is_tested():
    shipped = {name for name in shipped_machines() if load_machine(name).chain.type != "3-axis"}
    assert shipped == set(FIVE_AXIS)
    assert {load_machine(name).chain.type for name in FIVE_AXIS} == {"table-table", "head-table", "head-head"}


# --- round trips ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", FIVE_AXIS)
def test_forward_of_inverse_gives_the_poses_back(name):
    machine = load_machine(name)
    tip, axis = reachable_poses(machine, 2000, np.random.default_rng(7))
    path = inverse(machine, tip, axis, tool_length=TOOL_LENGTH)
    assert path.joints.shape == (2000, 5) and path.rewound.shape == (2000,)
    assert_within_travel(machine, path.joints)
    back_tip, back_axis = forward(machine, path.joints, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(back_tip, tip, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back_axis, axis, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", FIVE_AXIS)
def test_inverse_of_forward_gives_the_joints_or_the_other_solution(name):
    machine = load_machine(name)
    rng = np.random.default_rng(11)
    k = 2000
    travel = machine.limits
    tilt_letter = machine.chain.rotary[0]
    tilt = rng.uniform(*travel[tilt_letter], k)
    tilt = np.where(np.abs(tilt) < 0.2, 0.2, tilt)  # off the pole
    turn = rng.uniform(*travel.get("C", (-720.0, 720.0)), k)
    xyz = rng.uniform(-150.0, 150.0, (k, 3))
    joints = np.column_stack([xyz, tilt, turn])
    tip, axis = forward(machine, joints, tool_length=TOOL_LENGTH)
    path = inverse(machine, tip, axis, tool_length=TOOL_LENGTH)
    solved_tilt, solved_turn = path.joints[:, 3], path.joints[:, 4]
    same = np.isclose(solved_tilt, tilt, atol=1e-9) & np.isclose((solved_turn - turn + 180.0) % 360.0, 180.0, atol=1e-9)
    other = np.isclose(solved_tilt, -tilt, atol=1e-9) & np.isclose((solved_turn - turn) % 360.0, 180.0, atol=1e-9)
    assert (same | other).all()
    assert same.any() and other.any()
    np.testing.assert_allclose(path.joints[same, :3], xyz[same], rtol=0, atol=1e-9)
    back_tip, back_axis = forward(machine, path.joints, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(back_tip, tip, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back_axis, axis, rtol=0, atol=1e-12)
    # each pose alone, measured from its own joints, gives those joints back
    for i in range(0, k, 97):
        alone = inverse(machine, tip[i:i + 1], axis[i:i + 1], tool_length=TOOL_LENGTH, start=joints[i])
        np.testing.assert_allclose(alone.joints[0], joints[i], rtol=0, atol=1e-9)


chains = st.tuples(st.sampled_from(["table-table", "head-table", "head-head"]), st.sampled_from(["A", "B"]))
vectors = st.tuples(*[st.floats(-300.0, 300.0)] * 3)


@settings(max_examples=150, deadline=None)
@given(chain=chains, reversed_tilt=st.booleans(), reversed_turn=st.booleans(), pivot=vectors, offset=vectors,
       head_length=st.floats(0.0, 400.0), tool_length=st.floats(0.0, 200.0), tcp=st.booleans(),
       xyz=vectors, tilt=st.floats(0.2, 170.0), tilt_sign=st.sampled_from([-1.0, 1.0]),
       turn=st.floats(-720.0, 720.0))
def test_every_chain_round_trips(chain, reversed_tilt, reversed_turn, pivot, offset, head_length, tool_length,
                                 tcp, xyz, tilt, tilt_sign, turn):
    kind, tilt_letter = chain
    reversed_axes = tuple(letter for letter, flag in ((tilt_letter, reversed_tilt), ("C", reversed_turn)) if flag)
    machine = variant("table-table-ac", limits={}, type=kind, rotary=(tilt_letter, "C"), reversed=reversed_axes,
                      pivot=pivot, offset=offset if kind == "table-table" else (0.0, 0.0, 0.0),
                      head_length=head_length)
    assert machine.axes == ("X", "Y", "Z", *sorted((tilt_letter, "C")))
    joints = np.array([[*xyz, tilt_sign * tilt, turn]])
    tip, axis = forward(machine, joints, tool_length=tool_length, tcp=tcp)
    assert abs(np.linalg.norm(axis) - 1.0) < 1e-12
    assert abs(math.degrees(math.acos(min(1.0, axis[0, 2]))) - tilt) < 1e-6
    alone = inverse(machine, tip, axis, tool_length=tool_length, tcp=tcp, start=joints[0])
    np.testing.assert_allclose(alone.joints, joints, rtol=0, atol=1e-9)
    fresh = inverse(machine, tip, axis, tool_length=tool_length, tcp=tcp)
    back_tip, back_axis = forward(machine, fresh.joints, tool_length=tool_length, tcp=tcp)
    np.testing.assert_allclose(back_tip, tip, rtol=0, atol=1e-9)
    np.testing.assert_allclose(back_axis, axis, rtol=0, atol=1e-12)


# --- hand computations -------------------------------------------------------------------------------


def test_table_table_with_pivot_and_offset_against_a_hand_computation():
    # o1 = (10, -20, 30), o2 = (15, -13, -10); p = (1, 2, 3) at A = 90, C = 90:
    # Rz(90) (p - o2) = Rz(90) (-14, 15, 13) = (-15, -14, 13); + o2 - o1 = (-10, -7, -27);
    # Rx(90) -> (-10, 27, -7); + o1 = (0, 7, 23). Tool axis: Rz(-90) Rx(-90) z = Rz(-90) (0, 1, 0) = (1, 0, 0).
    machine = variant("table-table-ac", pivot=(10.0, -20.0, 30.0), offset=(5.0, 7.0, -40.0), limits={})
    tip, axis = forward(machine, [[0.0, 7.0, 23.0, 90.0, 90.0]])
    np.testing.assert_allclose(tip, [[1.0, 2.0, 3.0]], atol=1e-12)
    np.testing.assert_allclose(axis, [[1.0, 0.0, 0.0]], atol=1e-15)
    path = inverse(machine, [[1.0, 2.0, 3.0]], [[1.0, 0.0, 0.0]], start=[0.0, 0.0, 0.0, 80.0, 80.0])
    np.testing.assert_allclose(path.joints, [[0.0, 7.0, 23.0, 90.0, 90.0]], atol=1e-12)


def test_head_table_with_pivot_against_a_hand_computation():
    # o2 = (3, -4, 0); p = (1, 2, 3) at B = 90, C = 90: Rz(90) (-2, 6, 3) + o2 = (-3, -6, 3); the tool
    # points along Ry(90) z = (1, 0, 0), 150 + 50 mm to the head's pivot: (197, -6, 3).
    # Tool axis in work coordinates: Rz(-90) (1, 0, 0) = (0, -1, 0).
    machine = variant("head-table-bc", pivot=(3.0, -4.0, 0.0))
    tip, axis = forward(machine, [[197.0, -6.0, 3.0, 90.0, 90.0]], tool_length=50.0)
    np.testing.assert_allclose(tip, [[1.0, 2.0, 3.0]], atol=1e-12)
    np.testing.assert_allclose(axis, [[0.0, -1.0, 0.0]], atol=1e-15)
    path = inverse(machine, [[1.0, 2.0, 3.0]], [[0.0, -1.0, 0.0]], tool_length=50.0)
    np.testing.assert_allclose(path.joints, [[197.0, -6.0, 3.0, 90.0, 90.0]], atol=1e-12)
    # a longer tool moves the head's pivot up the tool axis
    longer = inverse(machine, [[1.0, 2.0, 3.0]], [[0.0, -1.0, 0.0]], tool_length=80.0)
    np.testing.assert_allclose(longer.joints[0, :3], [227.0, -6.0, 3.0], atol=1e-12)


def test_head_head_against_a_hand_computation():
    # A = 90 turns the spindle (+Z) towards -Y: (0, -1, 0); C = 90 turns that about +Z to (1, 0, 0).
    # The head's pivot (200, 5, 7) lies 200 + 50 mm up the tool from the tip: tip (-50, 5, 7).
    machine = load_machine("head-head-ca")
    assert machine.chain.head_length == 200.0
    tip, axis = forward(machine, [[200.0, 5.0, 7.0, 90.0, 90.0]], tool_length=50.0)
    np.testing.assert_allclose(tip, [[-50.0, 5.0, 7.0]], atol=1e-12)
    np.testing.assert_allclose(axis, [[1.0, 0.0, 0.0]], atol=1e-15)
    path = inverse(machine, [[-50.0, 5.0, 7.0]], [[1.0, 0.0, 0.0]], tool_length=50.0, start=[0.0, 0.0, 0.0, 80.0, 80.0])
    np.testing.assert_allclose(path.joints, [[200.0, 5.0, 7.0, 90.0, 90.0]], atol=1e-12)
    # A 30, C -45: Rz(-45) (0, -1/2, sqrt(3)/2) = (-sqrt(2)/4, -sqrt(2)/4, sqrt(3)/2); the pivot 250 mm up it
    d = np.array([-math.sqrt(2.0) / 4.0, -math.sqrt(2.0) / 4.0, math.sqrt(3.0) / 2.0])
    tip, axis = forward(machine, [[10.0, 20.0, 300.0, 30.0, -45.0]], tool_length=50.0)
    np.testing.assert_allclose(axis, [d], atol=1e-15)
    np.testing.assert_allclose(tip, [[10.0, 20.0, 300.0] - 250.0 * d], atol=1e-12)
    # B head: B 90 turns the spindle towards +X, C 90 that towards +Y; the pivot is not used
    b_head = variant("head-head-ca", rotary=("B", "C"), pivot=(3.0, -4.0, 9.0), head_length=100.0, limits={})
    assert b_head.axes == ("X", "Y", "Z", "B", "C")
    tip, axis = forward(b_head, [[0.0, 0.0, 0.0, 90.0, 90.0]], tool_length=20.0)
    np.testing.assert_allclose(axis, [[0.0, 1.0, 0.0]], atol=1e-15)
    np.testing.assert_allclose(tip, [[0.0, -120.0, 0.0]], atol=1e-12)
    # TCP: X Y Z are the tip
    tip, _ = forward(machine, [[10.0, 20.0, 300.0, 30.0, -45.0]], tool_length=50.0, tcp=True)
    np.testing.assert_allclose(tip, [[10.0, 20.0, 300.0]], atol=0)


def test_head_head_part_stays_put_and_c_turns_the_tool_with_it():
    machine = load_machine("head-head-ca")
    rng = np.random.default_rng(4)
    joints = np.column_stack([rng.uniform(-500.0, 500.0, (50, 3)), rng.uniform(-110.0, 110.0, 50),
                              rng.uniform(-360.0, 360.0, 50)])
    tip, axis = forward(machine, joints, tool_length=TOOL_LENGTH)
    # X Y Z move the head and nothing else: the tip moves with them, the tool axis does not change
    moved = joints + np.array([7.0, -3.0, 11.0, 0.0, 0.0])
    moved_tip, moved_axis = forward(machine, moved, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(moved_tip - tip, np.tile([7.0, -3.0, 11.0], (50, 1)), atol=1e-9)
    np.testing.assert_allclose(moved_axis, axis, atol=0)
    # C turns the tool axis's azimuth the same way (head-table: the table, so the other way)
    turned = joints + np.array([0.0, 0.0, 0.0, 0.0, 25.0])
    _, turned_axis = forward(machine, turned, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(turned_axis, unit_turn(axis, 25.0), atol=1e-12)
    table = load_machine("head-table-bc")
    table_joints = np.column_stack([np.zeros((50, 3)), np.clip(joints[:, 3], -110, 110), joints[:, 4]])
    _, before = forward(table, table_joints)
    _, after = forward(table, table_joints + np.array([0.0, 0.0, 0.0, 0.0, 25.0]))
    np.testing.assert_allclose(after, unit_turn(before, -25.0), atol=1e-12)


def unit_turn(vectors, degrees):
    """``vectors (k, 3)`` turned right-handed about +Z by ``degrees``."""
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return vectors @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def test_right_handed_turns_and_zero_angles():
    table = load_machine("table-table-ac")
    # A = +90 turns the table's +Y face up: the tool, vertical in the machine, comes along work +Y
    _, axis = forward(table, [[0.0, 0.0, 0.0, 90.0, 0.0], [0.0, 0.0, 0.0, 0.0, 0.0]])
    np.testing.assert_allclose(axis, [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], atol=1e-15)
    head = load_machine("head-table-bc")
    # B = +90 turns the head's tool (+Z) towards +X; the head's pivot sits head_length + tool above the tip
    tip, axis = forward(head, [[0.0, 0.0, 200.0, 0.0, 0.0], [0.0, 0.0, 0.0, 90.0, 0.0]], tool_length=50.0)
    np.testing.assert_allclose(tip, [[0.0, 0.0, 0.0], [-200.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(axis, [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]], atol=1e-15)
    fork = load_machine("head-head-ca")
    # A = +90 turns the spindle (+Z) towards -Y; C = +90 turns the head, -Y towards +X
    tip, axis = forward(fork, [[0.0, 0.0, 250.0, 0.0, 0.0], [0.0, 0.0, 0.0, 90.0, 0.0], [0.0, 0.0, 0.0, 90.0, 90.0]],
                        tool_length=50.0)
    np.testing.assert_allclose(tip, [[0.0, 0.0, 0.0], [0.0, 250.0, 0.0], [-250.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(axis, [[0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [1.0, 0.0, 0.0]], atol=1e-15)


@pytest.mark.parametrize("name", FIVE_AXIS)
def test_tcp_writes_the_tip_and_the_same_angles(name):
    machine = load_machine(name)
    tip, axis = reachable_poses(machine, 300, np.random.default_rng(3))
    plain = inverse(machine, tip, axis, tool_length=TOOL_LENGTH)
    tcp = inverse(machine, tip, axis, tool_length=TOOL_LENGTH, tcp=True)
    assert np.array_equal(tcp.joints[:, :3], tip)
    assert np.array_equal(tcp.joints[:, 3:], plain.joints[:, 3:])
    back_tip, back_axis = forward(machine, tcp.joints, tool_length=TOOL_LENGTH, tcp=True)
    assert np.array_equal(back_tip, tip)
    np.testing.assert_allclose(back_axis, axis, rtol=0, atol=1e-12)


# --- reversed axes ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", FIVE_AXIS)
@pytest.mark.parametrize("flipped", [("tilt",), ("C",), ("tilt", "C")])
def test_reversed_axes_count_the_other_way(name, flipped):
    machine = load_machine(name)
    letters = tuple(machine.chain.rotary[0] if f == "tilt" else f for f in flipped)
    columns = [machine.axes.index(letter) for letter in letters]
    mirrored = {a: ((-t[1], -t[0]) if a in letters else t) for a, t in machine.limits.items()}
    reversed_machine = variant(name, reversed=letters, limits=mirrored)
    sign = np.ones(5)
    sign[columns] = -1.0
    tip, axis = reachable_poses(machine, 500, np.random.default_rng(5))
    plain = inverse(machine, tip, axis, tool_length=TOOL_LENGTH)
    flipped_path = inverse(reversed_machine, tip, axis, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(flipped_path.joints, plain.joints * sign, rtol=0, atol=1e-12)
    assert np.array_equal(flipped_path.rewound, plain.rewound)
    reversed_pose = forward(reversed_machine, plain.joints * sign, TOOL_LENGTH)
    for a, b in zip(reversed_pose, forward(machine, plain.joints, TOOL_LENGTH)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)


# --- continuity, rewinding, the pole -------------------------------------------------------------------


def spiral(polar=40.0, turns=3.3, step=5.0, direction=1.0):
    """Tool axes at a fixed polar angle whose azimuth turns through 0/360 several times."""
    azimuth = 10.0 + direction * np.arange(0.0, turns * 360.0, step)
    axis = unit(np.full_like(azimuth, polar), azimuth)
    tip = np.column_stack([30.0 * np.cos(np.radians(azimuth)), 30.0 * np.sin(np.radians(azimuth)),
                           np.zeros_like(azimuth)])
    return tip, axis


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_continuous_turn_stays_continuous(direction):
    machine = load_machine("table-table-ac")
    assert "C" not in machine.limits
    tip, axis = spiral(direction=direction)
    path = inverse(machine, tip, axis)
    turn = path.joints[:, 4]
    assert np.abs(np.diff(turn)).max() <= 5.0 + 1e-9
    assert np.ptp(turn) > 3.0 * 360.0
    np.testing.assert_allclose(path.joints[:, 3], -40.0, atol=1e-9)  # A's travel [-120, 30] takes -40 only
    assert not path.rewound.any()
    assert angle_step(path.joints).max() <= 5.0 + 1e-9


@pytest.mark.parametrize("direction", [1.0, -1.0])
@pytest.mark.parametrize("name, tilt", [("head-table-bc", 40.0), ("head-head-ca", -40.0)])
def test_finite_turn_rewinds_within_travel_and_marks_it(direction, name, tilt):
    # head-head-ca from zero angles, azimuth 10 at 40 deg: (A 40, C 100) costs 140, (A -40, C -80) 120
    machine = load_machine(name)
    assert machine.limits["C"] == (-360.0, 360.0)
    tip, axis = spiral(direction=direction)
    path = inverse(machine, tip, axis, tool_length=TOOL_LENGTH)
    assert_within_travel(machine, path.joints)
    turn_step = np.abs(np.diff(path.joints[:, 4]))
    jumps = np.flatnonzero(turn_step > 5.0 + 1e-9) + 1
    assert len(jumps) >= 2
    assert np.array_equal(np.flatnonzero(path.rewound), jumps)
    # the equivalent farthest from the end it passed: a jump of two turns less 5 deg, every two turns
    np.testing.assert_allclose(turn_step[jumps - 1], 715.0, atol=1e-9)
    np.testing.assert_allclose(path.joints[:, 3], tilt, atol=1e-9)  # the tilt keeps its side
    # head-head: C follows the azimuth, head-table: it turns against it
    sense = 1.0 if machine.chain.type == "head-head" else -1.0
    steady = np.setdiff1d(np.arange(len(turn_step)), jumps - 1)
    assert (np.diff(path.joints[:, 4])[steady] * sense * direction > 0).all()
    back_tip, back_axis = forward(machine, path.joints, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(back_tip, tip, atol=1e-9)
    np.testing.assert_allclose(back_axis, axis, atol=1e-12)


@pytest.mark.parametrize("name, azimuth", [("head-table-bc", -5.0),  # B 30 at C 5 (+ 360 m)
                                           ("head-head-ca", -85.0)])  # A 30 at C = -85 + 90 = 5 (+ 360 m)
def test_a_start_near_the_end_of_the_travel_rewinds_the_first_move(name, azimuth):
    machine = load_machine(name)
    tip, axis = np.zeros((1, 3)), unit([30.0], [azimuth])
    from_start = inverse(machine, tip, axis, tool_length=TOOL_LENGTH, start=[0.0, 0.0, 0.0, 30.0, 359.0])
    # 365 unwound one turn, not to the far end (-355): the start unwound with it (-1) stays within travel,
    # so that the post can retract there and jump (359 - 720 would be beyond)
    np.testing.assert_allclose(from_start.joints[0, 3:], [30.0, 5.0], atol=1e-9)
    assert from_start.rewound.tolist() == [True]
    from_edge = inverse(machine, tip, axis, tool_length=TOOL_LENGTH, start=[0.0, 0.0, 0.0, 30.0, 360.0])
    np.testing.assert_allclose(from_edge.joints[0, 3:], [30.0, -355.0], atol=1e-9)  # 360 - 720 is within: two turns
    other_end = inverse(machine, tip, axis, tool_length=TOOL_LENGTH, start=[0.0, 0.0, 0.0, 30.0, -350.0])
    np.testing.assert_allclose(other_end.joints[0, 3:], [30.0, -355.0], atol=1e-9)
    assert other_end.rewound.tolist() == [False]
    alone = inverse(machine, tip, axis, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(alone.joints[0, 3:], [30.0, 5.0], atol=1e-9)
    assert alone.rewound.tolist() == [False]
    back_tip, back_axis = forward(machine, from_start.joints, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(back_tip, tip, atol=1e-9)
    np.testing.assert_allclose(back_axis, axis, atol=1e-12)


def test_tilt_beyond_the_travel_takes_the_other_side_and_marks_it():
    machine = load_machine("table-table-ac")  # A in [-120, 30]
    polar = np.array([20.0, 25.0, 30.0, 35.0, 40.0])
    path = inverse(machine, np.zeros((5, 3)), unit(polar, np.full(5, 90.0)))
    np.testing.assert_allclose(path.joints[:, 3], [20.0, 25.0, 30.0, -35.0, -40.0], atol=1e-9)
    np.testing.assert_allclose(path.joints[:, 4] % 360.0, [0.0, 0.0, 0.0, 180.0, 180.0], atol=1e-9)
    assert path.rewound.tolist() == [False, False, False, True, False]
    # head-head with A in [-110, 30]: A > 0 points the tool at azimuth C - 90, so azimuth -90 is C 0
    fork = variant("head-head-ca", limits={"A": (-110.0, 30.0), "C": (-360.0, 360.0)})
    path = inverse(fork, np.zeros((5, 3)), unit(polar, np.full(5, -90.0)), tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(path.joints[:, 3], [20.0, 25.0, 30.0, -35.0, -40.0], atol=1e-9)
    np.testing.assert_allclose(path.joints[:, 4] % 360.0, [0.0, 0.0, 0.0, 180.0, 180.0], atol=1e-9)
    assert path.rewound.tolist() == [False, False, False, True, False]


@pytest.mark.parametrize("name", FIVE_AXIS)
@pytest.mark.parametrize("plane", [0.0, 30.0, 90.0, 135.0, -100.0])
@pytest.mark.parametrize("reversed_axes", [False, True])
def test_path_through_the_pole_holds_the_turn_and_flips_the_tilt(name, plane, reversed_axes):
    machine = load_machine(name)
    if reversed_axes:
        machine = variant(name, reversed=machine.chain.rotary,
                          limits={a: (-t[1], -t[0]) if a in "ABC" else t for a, t in machine.limits.items()})
    singular = math.degrees(machine.chain.singular)
    tilt = np.concatenate([np.arange(10.0, 0.0, -0.5), [0.4 * singular, 0.0, -0.4 * singular],
                           np.arange(-0.5, -10.01, -0.5)])
    axis = unit(np.abs(tilt), np.where(tilt >= 0.0, plane, plane + 180.0))
    tip = np.zeros_like(axis)
    path = inverse(machine, tip, axis, tool_length=TOOL_LENGTH)
    turn, tilt_angle = path.joints[:, 4], path.joints[:, 3]
    assert np.ptp(turn) < 1e-9
    assert abs(tilt_angle[0]) == pytest.approx(10.0) and tilt_angle[-1] == pytest.approx(-tilt_angle[0])
    assert np.all(np.diff(tilt_angle) * np.sign(tilt_angle[-1]) > 0.0)  # through zero, monotonic
    assert not path.rewound.any()
    assert angle_step(path.joints).max() <= 0.5 + 1e-9
    back_tip, back_axis = forward(machine, path.joints, tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(back_tip, tip, atol=1e-9)
    assert angle_between(back_axis, axis).max() <= machine.chain.singular
    off = np.abs(tilt) > singular
    np.testing.assert_allclose(back_axis[off], axis[off], atol=1e-12)


@pytest.mark.parametrize("name", FIVE_AXIS)
def test_at_the_pole_the_turn_is_held_and_the_axis_kept_within_the_singular_angle(name):
    machine = load_machine(name)
    near = unit([0.03, 0.03, 179.99], [70.0, -20.0, 0.0])[:2]
    path = inverse(machine, np.zeros((2, 3)), near, tool_length=TOOL_LENGTH, start=[0.0, 0.0, 0.0, 0.0, 123.0])
    np.testing.assert_allclose(path.joints[:, 4], 123.0, atol=0)
    _, back_axis = forward(machine, path.joints, tool_length=TOOL_LENGTH)
    assert angle_between(back_axis, near).max() <= machine.chain.singular


@pytest.mark.parametrize("name", FIVE_AXIS)
def test_a_path_leaving_the_pole_holds_its_first_tilted_turn_from_the_start(name):
    machine = load_machine(name)
    tilt = np.array([0.0, 0.0, 0.0, 1.0, 2.0, 3.0])
    axis = unit(tilt, np.full(6, 45.0))
    path = inverse(machine, np.zeros((6, 3)), axis, tool_length=TOOL_LENGTH)
    assert np.ptp(path.joints[:, 4]) < 1e-9
    assert angle_step(path.joints).max() <= 1.0 + 1e-9


def test_ties_go_to_the_smaller_tilt_then_to_the_positive_tilt():
    machine = variant("table-table-ac", limits={})  # A and C turn freely
    # from zero angles, azimuth 0 at 20 deg: (A 20, C 90) and (A -20, C -90) cost the same
    path = inverse(machine, np.zeros((1, 3)), unit([20.0], [0.0]))
    np.testing.assert_allclose(path.joints[0, 3:], [20.0, 90.0], atol=1e-9)
    # from A 180: (A 170, C 90) and (A 190, C -90) cost the same; the smaller tilt wins
    path = inverse(machine, np.zeros((1, 3)), unit([170.0], [0.0]), start=[0.0, 0.0, 0.0, 180.0, 0.0])
    np.testing.assert_allclose(path.joints[0, 3:], [170.0, 90.0], atol=1e-9)


@pytest.mark.parametrize("name", FIVE_AXIS + THREE_AXIS)
def test_an_empty_path_has_no_joints(name):
    machine = load_machine(name)
    path = inverse(machine, np.zeros((0, 3)), np.zeros((0, 3)))
    assert path.joints.shape == (0, len(machine.axes)) and path.rewound.shape == (0,)
    assert angle_step(path.joints).shape == (0,)
    assert forward(machine, path.joints)[0].shape == (0, 3)


# --- travel limits --------------------------------------------------------------------------------------


def test_axis_limit_error_names_the_first_move_the_axis_the_value_and_the_travel():
    machine = load_machine("table-table-ac")
    polar = np.concatenate([np.full(12, 100.0), [131.2], np.full(7, 140.0)])
    axis = unit(polar, np.full(20, 30.0))
    tip = np.zeros((20, 3))
    with pytest.raises(AxisLimitError) as error:
        inverse(machine, tip, axis, lines=list(range(28, 48)))
    assert str(error.value) == "move 12 (line 40): A -131.200 is beyond its travel [-120, 30]"
    assert isinstance(error.value, InputError)
    assert (error.value.move, error.value.line, error.value.axis) == (12, 40, "A")
    assert error.value.value == pytest.approx(-131.2) and error.value.travel == (-120.0, 30.0)
    with pytest.raises(AxisLimitError, match=r"^move 12: A -131\.200 is beyond its travel \[-120, 30\]$"):
        inverse(machine, tip, axis)


def test_linear_limits_are_checked_and_the_first_move_named():
    machine = load_machine("table-table-ac")
    tip = np.zeros((8, 3))
    tip[3] = [400.0, 0.0, 0.0]
    tip[5] = [0.0, 0.0, -250.0]
    axis = np.tile([0.0, 0.0, 1.0], (8, 1))
    inverse(machine, tip, axis)  # the program's zero in machine coordinates unknown: X Y Z not checked
    zero = (0.0, 0.0, 0.0)
    with pytest.raises(AxisLimitError, match=r"^move 3: X 400\.000 is beyond its travel \[-300, 300\]$"):
        inverse(machine, tip, axis, origin=zero)
    inverse(machine, tip, axis, origin=(-150.0, 0.0, 100.0))  # moved by the work offset: within travel
    # a rotary beyond its travel after a linear one: the linear one is named
    axis[6] = unit([150.0], [0.0])[0]
    with pytest.raises(AxisLimitError, match=r"^move 3: X"):
        inverse(machine, tip, axis, origin=zero)
    # before it: the rotary one
    axis[2] = unit([150.0], [0.0])[0]
    with pytest.raises(AxisLimitError, match=r"^move 2: A -150\.000"):
        inverse(machine, tip, axis, origin=zero)
    # machine coordinates are checked, with or without TCP: a tip within X's travel that the
    # tilted table carries beyond Z's
    tilted = inverse(machine, [[0.0, 200.0, 0.0]], unit([90.0], [-90.0]), tcp=True, start=[0.0] * 5, origin=zero)
    assert tilted.joints[0, 3] == pytest.approx(-90.0)
    with pytest.raises(AxisLimitError, match=r"^move 0: Z -300\.000"):
        inverse(machine, [[0.0, 300.0, 0.0]], unit([90.0], [-90.0]), tcp=True, origin=zero)


def test_a_turn_with_short_travel_is_named():
    machine = variant("head-table-bc", limits={"B": (-110.0, 110.0), "C": (-60.0, 60.0)})
    # azimuth -90: C = 90 (B 30) or -90 (B -30), both beyond C's travel
    axis = unit([30.0, 30.0], [-30.0, -90.0])
    path = inverse(machine, np.zeros((1, 3)), axis[:1], tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(path.joints[0, 3:], [30.0, 30.0], atol=1e-9)
    with pytest.raises(AxisLimitError, match=r"^move 1: C 90\.000 is beyond its travel \[-60, 60\]$"):
        inverse(machine, np.zeros((2, 3)), axis, tool_length=TOOL_LENGTH)


def test_a_head_head_turn_with_short_travel_is_named():
    machine = variant("head-head-ca", limits={"A": (-110.0, 110.0), "C": (-60.0, 60.0)})
    # azimuth 0: C = 90 (A 30) or -90 (A -30), both beyond C's travel
    axis = unit([30.0, 30.0], [-60.0, 0.0])
    path = inverse(machine, np.zeros((1, 3)), axis[:1], tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(path.joints[0, 3:], [30.0, 30.0], atol=1e-9)
    with pytest.raises(AxisLimitError, match=r"^move 1: C 90\.000 is beyond its travel \[-60, 60\]$"):
        inverse(machine, np.zeros((2, 3)), axis, tool_length=TOOL_LENGTH)


def test_head_head_linear_travel_is_the_head_pivots():
    machine = load_machine("head-head-ca")  # Z in [-250, 750], head 200 mm
    tip, axis = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    inverse(machine, tip, axis, tool_length=500.0, origin=(0.0, 0.0, 0.0))  # pivot at Z 700
    with pytest.raises(AxisLimitError, match=r"^move 0: Z 800\.000 is beyond its travel \[-250, 750\]$"):
        inverse(machine, tip, axis, tool_length=600.0, origin=(0.0, 0.0, 0.0))
    # tilted 90 deg to +X (A -90 at C 90, or A 90 at C -90): the pivot 250 mm along X, Z at the tip's
    path = inverse(machine, [[0.0, 0.0, -200.0]], [[1.0, 0.0, 0.0]], tool_length=TOOL_LENGTH, origin=(0.0, 0.0, 0.0))
    np.testing.assert_allclose(path.joints[0, :3], [250.0, 0.0, -200.0], atol=1e-9)


# --- machine files ----------------------------------------------------------------------------------------


def machine_file(tmp_path, kinematics, axes=""):
    """A machine file with the [motion] of seed-002 and the given [kinematics] (and [axes]) lines."""
    path = tmp_path / "m.toml"
    motion = (pathlib.Path(load_machine("seed-002").path)).read_text()
    path.write_text(motion + "[kinematics]\n" + kinematics + ("\n[axes]\n" + axes if axes else "") + "\n")
    return path


def test_head_head_lists_its_rotaries_from_the_frame(tmp_path):
    shipped = load_machine("head-head-ca")
    assert shipped.chain.type == "head-head" and shipped.chain.rotary == ("A", "C")
    assert shipped.axes == ("X", "Y", "Z", "A", "C")
    assert shipped.limits["C"] == (-360.0, 360.0) and shipped.limits["A"] == (-110.0, 110.0)
    for rotary in ('["C", "B"]', '["B", "C"]'):
        machine = load_machine(machine_file(tmp_path, f'type = "head-head"\nrotary = {rotary}\nreversed = ["C"]\n'
                                                      'head_length_mm = 120', 'B = [-90, 90]\nC = "continuous"'))
        assert machine.chain.rotary == ("B", "C") and machine.chain.reversed == ("C",)
        assert machine.axes == ("X", "Y", "Z", "B", "C") and machine.chain.head_length == 120.0
    for bad in ('["C", "C"]', '["A", "B"]', '["C"]', '"CA"'):
        with pytest.raises(InputError, match=r"'rotary' must name C and then the tilting axis"):
            load_machine(machine_file(tmp_path, f'type = "head-head"\nrotary = {bad}'))
    with pytest.raises(InputError, match=r"'rotary' must name the tilting axis \(A or B\) and then C"):
        load_machine(machine_file(tmp_path, 'type = "head-table"\nrotary = ["C", "A"]'))
    with pytest.raises(InputError, match=r"'head_length_mm' must be a length >= 0 mm"):
        load_machine(machine_file(tmp_path, 'type = "head-head"\nrotary = ["C", "A"]\nhead_length_mm = -1'))


# --- 3-axis machines ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", THREE_AXIS)
def test_three_axis_machines_pass_vertical_poses_through(name):
    machine = load_machine(name)
    assert machine.axes == ("X", "Y", "Z")
    rng = np.random.default_rng(2)
    low = [machine.limits[a][0] for a in "XYZ"]
    high = [machine.limits[a][1] for a in "XYZ"]
    tip = rng.uniform(low, high, (100, 3))
    axis = np.tile([0.0, 0.0, 1.0], (100, 1))
    path = inverse(machine, tip, axis)
    assert np.array_equal(path.joints, tip) and not path.rewound.any()
    back_tip, back_axis = forward(machine, path.joints)
    assert np.array_equal(back_tip, tip) and np.array_equal(back_axis, axis)
    assert not angle_step(path.joints).any()


@pytest.mark.parametrize("name", THREE_AXIS)
def test_three_axis_machines_refuse_a_tilted_tool(name):
    machine = load_machine(name)
    tip = np.tile([[machine.limits["X"][0] + 1.0, machine.limits["Y"][0] + 1.0, machine.limits["Z"][1] - 1.0]], (4, 1))
    axis = np.tile([0.0, 0.0, 1.0], (4, 1))
    axis[2] = unit([5.0], [0.0])[0]
    with pytest.raises(InputError, match=r"^move 2 \(line 7\): tool axis \(0\.087156, 0\.000000, 0\.996195\) is "
                                         r"not vertical; the 3-axis machine '.+' cannot tilt the tool$"):
        inverse(machine, tip, axis, lines=[5, 6, 7, 8])


def test_bad_poses_are_refused():
    machine = load_machine("head-table-bc")
    with pytest.raises(InputError, match=r"^move 1: tool tip .* do not make a pose"):
        inverse(machine, np.zeros((2, 3)), [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]])
    with pytest.raises(InputError, match=r"^move 0 \(line 3\): tool tip"):
        inverse(machine, [[np.nan, 0.0, 0.0]], [[0.0, 0.0, 1.0]], lines=[3])
    with pytest.raises(ValueError):
        inverse(machine, np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(ValueError):
        forward(machine, np.zeros((2, 3)))
    # an axis that is not quite of unit length is normalised
    path = inverse(machine, np.zeros((1, 3)), [[0.0, 0.0, 2.0]], tool_length=TOOL_LENGTH)
    np.testing.assert_allclose(path.joints, [[0.0, 0.0, 200.0, 0.0, 0.0]], atol=1e-12)


def test_angle_step_is_the_largest_rotary_change_per_move():
    joints = np.array([[0.0, 0.0, 0.0, 10.0, 100.0],
                       [5.0, 0.0, 0.0, 12.0, 95.0],
                       [5.0, 0.0, 0.0, 2.0, 96.0]])
    np.testing.assert_allclose(angle_step(joints), [0.0, 5.0, 10.0])
    np.testing.assert_allclose(angle_step(joints, start=[0.0, 0.0, 0.0, 0.0, 70.0]), [30.0, 5.0, 10.0])
