"""Machine kinematics: tool tip and tool axis in work coordinates <-> the program's axis values.

Units: mm and degrees. A pose is a tool tip ``(3,)`` and a unit tool axis ``(3,)`` (from the tip
towards the spindle) in work coordinates; a path of k poses is ``tip (k, 3)``, ``axis (k, 3)``.
Joints are the program's axis values ``(k, n)``, columns in ``machine.axes`` order: X Y Z, then the
rotaries by letter (A C or B C). Move i is the motion to pose i; moves are numbered from 0.

Conventions
-----------
* A rotary named A, B, C turns about +X, +Y, +Z, right-handed; the program gives its signed angle
  in degrees. An axis listed in ``chain.reversed`` counts the other way: program angle =
  -physical angle. Below, r1 (the tilt, A or B) and r2 (the turn, C) are physical angles and Rot1,
  Rot2 their rotations.
* 3-axis: X Y Z = tip; the tool axis is +Z (:func:`inverse` refuses any other).
* table-table (``chain.rotary = (R1, C)``: R1 tilts a cradle, C turns the part on it): a work point
  p is at machine coordinates M(p) = Rot1(r1) (Rot2(r2) (p - o2) + o2 - o1) + o1, with o1 =
  ``chain.pivot`` (a point of R1's axis, work coordinates at zero angles) and o2 = ``chain.pivot +
  chain.offset`` (a point of C's axis). The spindle is vertical and the control compensates the
  tool length: X Y Z = M(tip); the tool axis in work coordinates is Rot2(r2)^T Rot1(r1)^T (0, 0, 1).
* head-table (``chain.rotary = (R1, C)``: R1 tilts the spindle head, C turns the table): M(p) =
  Rot2(r2) (p - o2) + o2 with o2 = ``chain.pivot``; the tool points along d = Rot1(r1) (0, 0, 1) in
  machine coordinates and X Y Z is the head's pivot M(tip) + (head_length + tool_length) d, where
  ``tool_length`` is the tool's tip to the spindle's gauge line. The tool axis in work coordinates
  is Rot2(r2)^T d.
* head-head (``chain.rotary = (R1, C)``, listed ["C", R1] in the machine file, from the frame: C,
  nearer the machine frame, turns the head about +Z and carries R1, which tilts the spindle; the
  part stays on the fixed table, so machine and work coordinates are the same): the tool points
  along d = Rot2(r2) Rot1(r1) (0, 0, 1) and X Y Z is the head's pivot tip + (head_length +
  tool_length) d, ``tool_length`` as for head-table; ``chain.pivot`` is not used. The tool axis
  in work coordinates is d.
* TCP (``tcp=True``: the control does the kinematics, e.g. G43.4 or TRAORI): X Y Z = the tip in
  work coordinates; the rotary angles are the same as without TCP.

Every 5-axis chain puts the tool axis at polar angle abs(r1) from +Z. With r1 > 0 its azimuth
(atan2(y, x)) is ``psi + w r2``, where psi is 90 deg (table-table A), 180 (table-table B), -90
(head-table and head-head A) or 0 (head-table and head-head B), and w is -1 where C turns the
part (table-table, head-table: the tool turns the other way in work coordinates) and +1 where it
turns the head (head-head); with r1 < 0 it is ``psi + w r2 + 180``.

Inverse
-------
A tool axis at polar angle theta and azimuth phi has two solutions, (r1, r2) = (theta, w (phi - psi))
and (-theta, w (phi - psi) + 180), each repeated every 360 deg of any rotary (all of them for a rotary
without travel limits; those within its travel otherwise). The poses are solved in order; each
takes the solution nearest the previous pose's angles: the smallest abs(tilt change) + abs(turn
change) (program degrees, equal weights), ties to the smaller abs(tilt) and then to the positive
physical tilt. The first pose is measured from ``start`` (the joints before it) or, without one,
from zero angles. A rotary without travel limits is unwound: it keeps counting past +-360 deg, so
that consecutive poses never differ by a turn taken modulo 360.

* Travel: where the nearest solution is beyond a rotary's travel, the same tilt with the turn's
  equivalent within travel farthest from the end it passed is taken, as far as the pose before,
  turned by the same whole turns, stays within travel too (the post retracts there and jumps; a
  path that keeps turning one way on a [-360, 360] table or head unwinds once a turn, two turns
  only where a pose lies on the end itself); where the tilt itself is
  beyond travel, the other solution (tilt of the other sign, turn 180 deg on). Either way the
  pose is marked ``rewound``: the rotaries jump there (a finite C unwinds by a full turn, or the
  tool swings over to the other side) and the post-processor must retract the tool before that
  move. (The first pose is marked only when ``start`` is given: without it there is no motion to
  it.) Without any solution
  within travel an :class:`AxisLimitError` names the first such move. Large rotary moves that the
  geometry asks for (the azimuth swinging fast next to the pole) are not marked; see
  :func:`angle_step`.
* The pole: within ``chain.singular`` of C's axis (+Z or -Z; the table's or, head-head, the
  head's) the turn angle is undefined. It is held at the previous pose's value and the tilt
  solved for it (signed: the tilt in the plane of the held turn nearest the axis, which it
  reproduces to within ``chain.singular``), so a path through the pole flips the tilt's sign
  instead of spinning C by 180 deg. A path that starts at the pole without ``start`` holds the
  turn of its first pose off the pole.
* The linear axes X Y Z (of the machine, M(tip) or the head's pivot, with or without TCP) are
  checked against ``machine.limits`` after the rotaries are chosen, when the program's zero is
  known in machine coordinates (``origin``): the choice of solution does not depend on them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..errors import InputError
from .model import LINEAR

LIMIT_TOLERANCE = 1e-9  # mm or deg: a value this far beyond its travel still counts as inside
VERTICAL_TOLERANCE = 1e-6  # rad: a 3-axis machine takes a tool axis this close to +Z as vertical
AXIS_ZERO = 1e-9  # a tool axis shorter than this has no direction

# deg: azimuth of the tool axis in work coordinates at r1 > 0, r2 = 0, by (chain type, tilt letter)
TILT_AZIMUTH = {("table-table", "A"): 90.0, ("table-table", "B"): 180.0,
                ("head-table", "A"): -90.0, ("head-table", "B"): 0.0,
                ("head-head", "A"): -90.0, ("head-head", "B"): 0.0}
# w: deg the tool axis's azimuth (work coordinates) turns per physical degree of C, by chain type
TURN_AZIMUTH = {"table-table": -1.0, "head-table": -1.0, "head-head": 1.0}
_ROTATION_PLANE = {"A": (1, 2), "B": (2, 0), "C": (0, 1)}  # (i, j): the turn takes e_i towards e_j
_UP = np.array([0.0, 0.0, 1.0])


class AxisLimitError(InputError):
    """A move needs an axis beyond its travel. ``move`` (index), ``line`` (source line or None),
    ``axis`` (letter), ``value`` (mm or deg), ``travel`` ((low, high))."""

    def __init__(self, move, line, axis, value, travel):
        self.move, self.line, self.axis, self.value, self.travel = move, line, axis, value, travel
        super().__init__(f"{_move_name(move, line)}: {axis} {value:.3f} is beyond its travel "
                         f"[{travel[0]:g}, {travel[1]:g}]")


class JointPath(NamedTuple):
    """The result of :func:`inverse`: ``joints (k, n)`` (mm, deg; columns ``machine.axes``) and
    ``rewound (k,)`` bool: the rotaries' travel forced a re-orientation on the way to that pose
    (retract before it)."""

    joints: np.ndarray
    rewound: np.ndarray


def forward(machine, joints, tool_length=0.0, tcp=False):
    """Tool tip ``(k, 3)`` mm and unit tool axis ``(k, 3)``, work coordinates, at ``joints (k, n)``
    (mm, deg; columns ``machine.axes``). ``tool_length`` mm (tip to gauge line) matters only to a
    head-table or head-head chain without TCP; ``tcp``: X Y Z are the tip (the control does the kinematics)."""
    chain = machine.chain
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 2 or joints.shape[1] != len(machine.axes):
        raise ValueError(f"joints must be (k, {len(machine.axes)}) for axes {''.join(machine.axes)}, "
                         f"got {joints.shape}")
    xyz = joints[:, :3].copy()
    if chain.type == "3-axis":
        return xyz, np.tile(_UP, (len(joints), 1))
    tilt, turn = _physical_angles(machine, joints)
    rot1, rot2 = _rotation(chain.rotary[0], tilt), _rotation("C", turn)
    pivot = np.asarray(chain.pivot, np.float64)
    if chain.type == "table-table":
        turn_point = pivot + np.asarray(chain.offset, np.float64)
        axis = _turn_back(rot2, _turn_back(rot1, _UP))
        if not tcp:
            xyz = _turn_back(rot2, _turn_back(rot1, xyz - pivot) + pivot - turn_point) + turn_point
        return xyz, axis
    if chain.type == "head-head":
        axis = _turn(rot2, rot1[:, :, 2])  # Rot2 Rot1 (0, 0, 1): machine = work coordinates
        if not tcp:
            xyz = xyz - (chain.head_length + _per_pose(tool_length)) * axis
        return xyz, axis
    spindle = rot1[:, :, 2]  # Rot1 (0, 0, 1): the tool's direction in machine coordinates
    axis = _turn_back(rot2, spindle)
    if not tcp:
        xyz = _turn_back(rot2, xyz - (chain.head_length + _per_pose(tool_length)) * spindle - pivot) + pivot
    return xyz, axis


def inverse(machine, tip, axis, tool_length=0.0, tcp=False, start=None, lines=None, origin=None) -> JointPath:
    """Joints for a path of poses: ``tip (k, 3)`` mm and tool ``axis (k, 3)`` (normalised here),
    work coordinates -> :class:`JointPath` (``joints (k, n)`` mm and deg, columns
    ``machine.axes``; ``rewound (k,)``). The solution of each pose is chosen as the module's
    docstring says; ``start (n,)``: the joints before the first pose (None: measure from zero
    angles); ``lines (k,)``: source line of each pose, for error messages; ``tool_length`` and
    ``tcp`` as in :func:`forward`; ``origin (3,)``: where the program's zero lies in machine
    coordinates (the work offset), for checking X Y Z against their travel (None: not checked;
    the travel of the rotaries always is). Raises :class:`AxisLimitError` naming the first move
    beyond the travel, :class:`InputError` for a tool axis a 3-axis machine cannot take or one of
    zero length."""
    if lines is not None and len(lines) != len(tip):
        raise ValueError(f"lines must have one entry per pose ({len(tip)}), got {len(lines)}")
    tip, axis = _poses(tip, axis, lines)
    n = len(machine.axes)
    if start is not None:
        start = np.asarray(start, np.float64)
        if start.shape != (n,):
            raise ValueError(f"start must be ({n},) for axes {''.join(machine.axes)}, got {start.shape}")
    if machine.chain.type == "3-axis":
        _check_vertical(machine, axis, lines)
        if origin is not None:
            _check_linear(machine, tip + np.asarray(origin, np.float64), lines)
        return JointPath(tip.copy(), np.zeros(len(tip), bool))
    rotaries = _Rotaries.of(machine)
    tilt_column, turn_column = machine.axes.index(rotaries.tilt), machine.axes.index("C")
    reference = None if start is None else (float(start[tilt_column]), float(start[turn_column]))
    angles, rewound, failure = rotaries.solve_path(axis, reference, lines)
    solved = len(angles)
    tilt, turn = rotaries.tilt_sign * angles[:, 0], rotaries.turn_sign * angles[:, 1]
    xyz = _machine_xyz(machine, tip[:solved], tilt, turn, tool_length)
    if origin is not None:
        _check_linear(machine, xyz + np.asarray(origin, np.float64), lines)
    if failure is not None:
        raise failure
    joints = np.empty((len(tip), n))
    joints[:, :3] = tip if tcp else xyz
    joints[:, tilt_column], joints[:, turn_column] = angles[:, 0], angles[:, 1]
    return JointPath(joints, rewound)


def angle_step(joints, start=None):
    """The largest rotary change of each move ``(k,)`` deg: move i from ``joints[i-1]`` (or
    ``start (n,)``; without it move 0 counts 0) to ``joints[i]``, ``joints (k, n)`` with the
    rotaries after X Y Z (``machine.axes``). Zero for a 3-axis machine. For rotary speed limits
    and inverse-time feeds (G93): a move takes at least ``angle_step / machine.rotary_rapid`` s."""
    joints = np.asarray(joints, np.float64)
    if joints.ndim != 2 or joints.shape[1] < 3:
        raise ValueError(f"joints must be (k, n) with X Y Z first, got {joints.shape}")
    rotary = joints[:, 3:]
    before = rotary[:1] if start is None else np.asarray(start, np.float64)[None, 3:]
    step = np.abs(np.diff(np.concatenate([before, rotary]), axis=0))
    return step.max(axis=1, initial=0.0)


# --- rotations ------------------------------------------------------------------------------------


def _rotation(letter, degrees):
    """``(k, 3, 3)``: right-handed turns about +X, +Y or +Z (``letter`` A, B or C) by ``degrees (k,)``."""
    radians = np.radians(degrees)
    cos, sin = np.cos(radians), np.sin(radians)
    i, j = _ROTATION_PLANE[letter]
    fixed = 3 - i - j
    matrix = np.zeros((len(radians), 3, 3))
    matrix[:, fixed, fixed] = 1.0
    matrix[:, i, i] = cos
    matrix[:, j, j] = cos
    matrix[:, i, j] = -sin
    matrix[:, j, i] = sin
    return matrix


def _turn(rotation, vectors):
    """``rotation (k, 3, 3)`` applied to ``vectors (k, 3)`` or ``(3,)``: ``(k, 3)``."""
    return np.einsum("kij,kj->ki", rotation, np.broadcast_to(vectors, (len(rotation), 3)))


def _turn_back(rotation, vectors):
    """The inverse (transpose) of ``rotation (k, 3, 3)`` applied to ``vectors``: ``(k, 3)``."""
    return np.einsum("kji,kj->ki", rotation, np.broadcast_to(vectors, (len(rotation), 3)))


def machine_xyz(machine, joints, tool_length=0.0):
    """Machine X Y Z ``(k, 3)`` mm of TCP ``joints (k, n)`` (X Y Z the tool tip in work
    coordinates): where the axes stand, as the program's X Y Z would be without TCP."""
    joints = np.asarray(joints, np.float64)
    if machine.chain.type == "3-axis":
        return joints[:, :3].copy()
    return _machine_xyz(machine, joints[:, :3], *_physical_angles(machine, joints), tool_length)


def _physical_angles(machine, joints):
    """``(tilt (k,), turn (k,))`` physical degrees of the rotaries in ``joints (k, n)``."""
    tilt_letter = machine.chain.rotary[0]
    tilt = joints[:, machine.axes.index(tilt_letter)] * _sign(machine, tilt_letter)
    turn = joints[:, machine.axes.index("C")] * _sign(machine, "C")
    return tilt, turn


def _sign(machine, letter):
    """-1.0 for an axis whose control counts the other way, else 1.0."""
    return -1.0 if letter in machine.chain.reversed else 1.0


def _machine_xyz(machine, tip, tilt, turn, tool_length):
    """Machine X Y Z ``(k, 3)`` mm (the program's without TCP) for ``tip (k, 3)`` at physical
    ``tilt (k,)`` and ``turn (k,)`` deg."""
    chain = machine.chain
    rot1, rot2 = _rotation(chain.rotary[0], tilt), _rotation("C", turn)
    pivot = np.asarray(chain.pivot, np.float64)
    if chain.type == "table-table":
        turn_point = pivot + np.asarray(chain.offset, np.float64)
        return _turn(rot1, _turn(rot2, tip - turn_point) + turn_point - pivot) + pivot
    if chain.type == "head-head":
        return tip + (chain.head_length + _per_pose(tool_length)) * _turn(rot2, rot1[:, :, 2])
    return _turn(rot2, tip - pivot) + pivot + (chain.head_length + _per_pose(tool_length)) * rot1[:, :, 2]


def _per_pose(tool_length):
    """A tool length (mm) that is one number or one per pose ``(k,)``, shaped to scale ``(k, 3)``."""
    length = np.asarray(tool_length, np.float64)
    return length[..., None] if length.ndim else length


# --- choosing the rotary angles ---------------------------------------------------------------------


class _NoSolution(Exception):
    """No solution of a pose is within travel; args: the axis letter, its value and travel."""


@dataclass(frozen=True)
class _Rotaries:
    """The two rotaries of a 5-axis chain as :func:`inverse` chooses them (program degrees):
    the ``tilt`` letter (A or B), each one's sign (program = sign * physical) and travel ((low,
    high) or None: turns freely), ``azimuth`` (psi, see :data:`TILT_AZIMUTH`), ``per_turn`` (w,
    see :data:`TURN_AZIMUTH`) and ``pole`` (deg)."""

    tilt: str
    tilt_sign: float
    tilt_travel: tuple | None
    turn_sign: float
    turn_travel: tuple | None
    azimuth: float
    per_turn: float
    pole: float

    @staticmethod
    def of(machine) -> "_Rotaries":
        chain = machine.chain
        tilt = chain.rotary[0]
        return _Rotaries(tilt=tilt, tilt_sign=_sign(machine, tilt), tilt_travel=machine.limits.get(tilt),
                         turn_sign=_sign(machine, "C"), turn_travel=machine.limits.get("C"),
                         azimuth=TILT_AZIMUTH[chain.type, tilt], per_turn=TURN_AZIMUTH[chain.type],
                         pole=math.degrees(chain.singular))

    def solve_path(self, axis, reference, lines):
        """Angles pose by pose for unit ``axis (k, 3)`` from ``reference`` ((tilt, turn) program
        deg before the first pose, or None): ``(angles (m, 2), rewound (m,), failure)``, m = k and
        failure None, or m the first pose without a solution within travel and failure its
        :class:`AxisLimitError`."""
        polar = np.degrees(np.arctan2(np.hypot(axis[:, 0], axis[:, 1]), axis[:, 2]))
        azimuth = np.degrees(np.arctan2(axis[:, 1], axis[:, 0]))
        at_pole = np.minimum(polar, 180.0 - polar) < self.pole
        previous = reference if reference is not None else (0.0, self._first_turn(polar, azimuth, at_pole))
        angles, rewound = [], []
        for i, (theta, phi, on_pole, unit) in enumerate(zip(polar.tolist(), azimuth.tolist(), at_pole.tolist(),
                                                         axis.tolist())):
            try:
                tilt, turn, jumped = self.solve_pose(theta, phi, unit if on_pole else None, previous)
            except _NoSolution as beyond:
                failure = AxisLimitError(i, None if lines is None else lines[i], *beyond.args)
                return np.array(angles).reshape(-1, 2), np.array(rewound, bool), failure
            angles.append((tilt, turn))
            rewound.append(jumped and (i > 0 or reference is not None))
            previous = (tilt, turn)
        return np.array(angles).reshape(-1, 2), np.array(rewound, bool), None

    def _first_turn(self, polar, azimuth, at_pole):
        """Turn (program deg) to hold at the pole before the first pose off it: that pose's turn
        measured from zero angles (0 when no pose leaves the pole or none fits the travel)."""
        off_pole = np.flatnonzero(~at_pole)
        if not len(off_pole) or off_pole[0] == 0:
            return 0.0
        first = off_pole[0]
        try:
            return self.solve_pose(float(polar[first]), float(azimuth[first]), None, (0.0, 0.0))[1]
        except _NoSolution:
            return 0.0

    def solve_pose(self, polar, azimuth, pole_axis, previous):
        """One pose: tool axis at ``polar`` and ``azimuth`` deg (work coordinates); ``pole_axis``
        (the unit axis (3,)) when it is at the pole, else None; ``previous`` (tilt, turn) program
        deg. Returns ``(tilt, turn, rewound)`` program deg; raises :class:`_NoSolution` with the least
        violation when no solution is within travel."""
        tilt_before, turn_before = previous
        if pole_axis is not None:
            held = math.radians(self.azimuth + self.per_turn * self.turn_sign * turn_before)
            x, y, z = pole_axis
            tilt = math.degrees(math.atan2(x * math.cos(held) + y * math.sin(held), z))
            branches = [(self.tilt_sign * tilt, turn_before)]
        else:
            turn = self.per_turn * (azimuth - self.azimuth)
            branches = [(self.tilt_sign * polar, self.turn_sign * turn),
                        (-self.tilt_sign * polar, self.turn_sign * (turn + 180.0))]
        nearest = [(_nearest_turn(tilt, tilt_before), _nearest_turn(turn, turn_before)) for tilt, turn in branches]
        nearest.sort(key=lambda tt: (round(abs(tt[0] - tilt_before) + abs(tt[1] - turn_before), 9),
                                     round(abs(tt[0]), 9)))
        tilt, turn = nearest[0]
        if self._inside(tilt, turn):
            return tilt, turn, False
        # the pose before, on each solution (the other one: its turn 180 deg on, next to this turn)
        before = [turn_before if abs(tilt - tilt_before) <= abs(tilt + tilt_before) else
                  _nearest_turn(turn_before + 180.0, turn) for tilt, turn in nearest]
        within = [(_into_travel(tilt, self.tilt_travel), _into_travel(turn, self.turn_travel, prior))
                  for (tilt, turn), prior in zip(nearest, before)]
        for tilt, turn in within:
            if self._inside(tilt, turn):
                return tilt, turn, True
        tilt, turn = min(within, key=lambda tt: _beyond(tt[0], self.tilt_travel) + _beyond(tt[1], self.turn_travel))
        if _beyond(tilt, self.tilt_travel) > 0.0:
            raise _NoSolution(self.tilt, tilt, self.tilt_travel)
        raise _NoSolution("C", turn, self.turn_travel)

    def _inside(self, tilt, turn):
        return _beyond(tilt, self.tilt_travel) == 0.0 and _beyond(turn, self.turn_travel) == 0.0


def _nearest_turn(angle, reference):
    """``angle + 360 m`` (deg) nearest ``reference``."""
    return angle + 360.0 * round((reference - angle) / 360.0)


def _beyond(value, travel):
    """How far ``value`` lies beyond ``travel`` ((low, high) or None), 0 within it (tolerance
    :data:`LIMIT_TOLERANCE`)."""
    if travel is None:
        return 0.0
    excess = max(travel[0] - value, value - travel[1])
    return excess if excess > LIMIT_TOLERANCE else 0.0


def _into_travel(angle, travel, previous=None):
    """The equivalent ``angle + 360 m`` (deg) within ``travel`` ((low, high) or None) farthest
    from the end ``angle`` passed (from ``previous`` on, or beyond an end), so that a path that keeps
    turning the same way has the most travel ahead before it must unwind again; with ``previous``
    (the pose before on the same solution, deg), only whole turns ``m`` that bring it within travel
    too where there are such, so that the pose before can be solved next to this one (the post
    retracts there and jumps); the angle itself when both are inside already; where no equivalent
    is inside (travel under 360 deg), the one nearest the travel."""
    if travel is None:
        return angle
    if _beyond(angle, travel) == 0.0 and (previous is None or _beyond(previous, travel) == 0.0):
        return angle
    low, high = travel
    turns = range(math.ceil((low - angle - LIMIT_TOLERANCE) / 360.0), math.floor((high - angle + LIMIT_TOLERANCE) / 360.0) + 1)
    inside = [m for m in turns if _beyond(angle + 360.0 * m, travel) == 0.0]
    both = [m for m in inside if previous is None or _beyond(previous + 360.0 * m, travel) == 0.0]
    if both or inside:
        rising = angle > previous if previous is not None else angle > high
        m = (min if rising else max)(both or inside)  # turning up: the lowest equivalent, most travel ahead
        return angle + 360.0 * m
    near = [angle + 360.0 * m for m in range(-int(abs(angle) // 360) - 2, int(abs(angle) // 360) + 3)]
    return min(near, key=lambda a: _beyond(a, travel) if _beyond(a, travel) > 0 else math.inf)


# --- checks -------------------------------------------------------------------------------------


def _move_name(move, line):
    return f"move {move}" if line is None else f"move {move} (line {line})"


def _poses(tip, axis, lines):
    """``tip (k, 3)`` and unit ``axis (k, 3)`` float arrays; InputError for an axis of zero length
    or any non-finite value, naming the move."""
    tip, axis = np.asarray(tip, np.float64), np.asarray(axis, np.float64)
    if tip.ndim != 2 or tip.shape[1] != 3 or axis.shape != tip.shape:
        raise ValueError(f"tip and axis must both be (k, 3), got {tip.shape} and {axis.shape}")
    length = np.linalg.norm(axis, axis=1)
    bad = ~(np.isfinite(tip).all(axis=1) & np.isfinite(length) & (length > AXIS_ZERO))
    if bad.any():
        move = int(np.argmax(bad))
        raise InputError(f"{_move_name(move, None if lines is None else lines[move])}: tool tip "
                         f"{tuple(tip[move].tolist())} and axis {tuple(axis[move].tolist())} do not "
                         "make a pose (finite numbers and an axis of non-zero length needed)")
    return tip, axis / length[:, None]


def _check_vertical(machine, axis, lines):
    """InputError naming the first move whose unit ``axis (k, 3)`` is not +Z (3-axis machines)."""
    tilted = np.linalg.norm(axis - _UP, axis=1) > VERTICAL_TOLERANCE
    if tilted.any():
        move = int(np.argmax(tilted))
        x, y, z = axis[move]
        raise InputError(f"{_move_name(move, None if lines is None else lines[move])}: tool axis "
                         f"({x:.6f}, {y:.6f}, {z:.6f}) is not vertical; the 3-axis machine "
                         f"'{machine.name}' cannot tilt the tool")


def _check_linear(machine, xyz, lines):
    """AxisLimitError naming the first move (then the first of X Y Z) of ``xyz (k, 3)`` mm beyond
    the machine's travel."""
    first = None
    for column, letter in enumerate(LINEAR):
        travel = machine.limits.get(letter)
        if travel is None or not len(xyz):
            continue
        outside = (xyz[:, column] < travel[0] - LIMIT_TOLERANCE) | (xyz[:, column] > travel[1] + LIMIT_TOLERANCE)
        if outside.any() and (first is None or np.argmax(outside) < first[0]):
            first = (int(np.argmax(outside)), letter, float(xyz[np.argmax(outside), column]), travel)
    if first is not None:
        move = first[0]
        raise AxisLimitError(move, None if lines is None else lines[move], *first[1:])
