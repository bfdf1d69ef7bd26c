"""PCA rectangle, ball-or-torus choice and the rectangle time surrogate against the numbers of seed
002 (Herraz 2021, notes §2 and §4.3, §4.7). Tolerances are half a unit of the printed last digit."""
from math import comb

import numpy as np
import pytest

from meshmill.choice.rectangle import (
    PcaRectangle,
    choose_tool,
    connection_time,
    critical_shape_factor,
    critical_slope,
    length_ball_principal,
    length_toric_steepest,
    parallel_passes_length,
    parallel_passes_segment_time,
    parallel_passes_time,
    pass_time,
    pca_rectangle,
    rectangle_time,
    stepover_ball,
    stepover_toric_steepest,
    time_ball_principal,
    time_toric_steepest,
    zone_time_surrogate,
)
from meshmill.pathing.scallop import effective_radius
from meshmill.errors import InputError
from meshmill.machine.model import MotionLimits

KIN = MotionLimits.seed()
R, CORNER, SH = 5.0, 2.0, 0.01
TOOL = (R, CORNER, SH)
deg = np.radians


def axial_gap(a, b):
    """Angle between two lines given by azimuths, in [0, pi/2]."""
    return abs((a - b + np.pi / 2) % np.pi - np.pi / 2)


def planar_rectangle(width, height, slope, steepest_azimuth, principal_azimuth, cells=(12, 7)):
    """Samples of a planar width × height rectangle (width side's XY azimuth ``principal_azimuth``)
    in the plane of slope ``slope`` whose normal points along ``steepest_azimuth`` in XY, centred
    at (3, -2, 7). Two Gauss nodes per cell along each side make the 1/n second moments exactly
    w²/12 and h²/12."""
    n = np.array([np.sin(slope) * np.cos(steepest_azimuth), np.sin(slope) * np.sin(steepest_azimuth), np.cos(slope)])
    c, s = np.cos(principal_azimuth), np.sin(principal_azimuth)
    e1 = np.array([c, s, -(n[0] * c + n[1] * s) / n[2]])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    gauss = np.array([-1.0, 1.0]) / (2.0 * np.sqrt(3.0))

    def nodes(length, k):
        centres = (np.arange(k) + 0.5) / k - 0.5
        return ((centres[:, None] + gauss[None, :] / k) * length).ravel()

    u, v = np.meshgrid(nodes(width, cells[0]), nodes(height, cells[1]), indexing="ij")
    pts = np.array([3.0, -2.0, 7.0]) + u.ravel()[:, None] * e1 + v.ravel()[:, None] * e2
    return pts, np.tile(n, (len(pts), 1))


def bezier(control, cells=80):
    """Points and normals at the centres of a cells × cells uniform (u, v) grid of a Bézier patch
    with control points (n+1, m+1, 3)."""
    ctrl = np.asarray(control, float)
    t = (np.arange(cells) + 0.5) / cells

    def bernstein(n, i):
        return comb(n, i) * t**i * (1 - t) ** (n - i) if 0 <= i <= n else 0 * t

    def basis(n):  # B_i,n(t) and its derivative n (B_i-1,n-1 - B_i,n-1), (n+1, cells)
        b = np.array([bernstein(n, i) for i in range(n + 1)])
        return b, np.array([n * (bernstein(n - 1, i - 1) - bernstein(n - 1, i)) for i in range(n + 1)])

    bu, dbu = basis(ctrl.shape[0] - 1)
    bv, dbv = basis(ctrl.shape[1] - 1)
    pts = np.einsum("iu,jv,ijk->uvk", bu, bv, ctrl).reshape(-1, 3)
    su = np.einsum("iu,jv,ijk->uvk", dbu, bv, ctrl).reshape(-1, 3)
    sv = np.einsum("iu,jv,ijk->uvk", bu, dbv, ctrl).reshape(-1, 3)
    return pts, np.cross(su, sv)


RUBIO = [  # test surface 1 (Table 2.2), rows i (u), columns j (v)
    [(0.0, -15.32, -12.85), (0.0, -6.42, 7.66), (0.0, 15.32, 12.85)],
    [(40.0, -18.53, -9.02), (40.0, -9.64, 11.49), (40.0, 12.10, 16.68)],
    [(80.0, -28.17, 2.46), (80.0, -22.49, 26.81), (80.0, 2.46, 28.17)],
]
CHOI = [  # test surface 2 (Table 2.4)
    [(7.92, 0.0, 37.26), (6.33, 20.4, 29.81), (6.33, 40.8, 29.81), (7.92, 61.2, 37.26)],
    [(23.72, 0.0, 26.11), (22.14, 20.4, 18.66), (22.14, 40.8, 18.66), (23.72, 61.2, 26.11)],
    [(42.70, 0.0, 29.87), (41.12, 20.4, 22.42), (41.12, 40.8, 22.42), (42.70, 61.2, 29.87)],
    [(56.02, 0.0, 19.25), (54.44, 20.4, 11.79), (54.44, 40.8, 11.79), (56.02, 61.2, 19.25)],
]


# --- PCA rectangle -------------------------------------------------------------------------------


@pytest.mark.parametrize("principal, steepest", [(deg(90.0), 0.0), (deg(-9.74), deg(66.97)), (deg(35.0), deg(-80.0))])
def test_pca_of_a_planar_tilted_rectangle_is_exact(principal, steepest):
    slope = deg(60.0)
    pts, normals = planar_rectangle(56.0, 28.0, slope, steepest, principal)
    rect = pca_rectangle(pts, normals)
    assert rect.width == pytest.approx(56.0, rel=1e-12)
    assert rect.height == pytest.approx(28.0, rel=1e-12)
    assert rect.shape_factor == pytest.approx(2.0, rel=1e-12)
    assert rect.size == pytest.approx(1568.0, rel=1e-12)
    assert rect.plane_slope == pytest.approx(slope, abs=1e-12)
    assert rect.mean_slope == pytest.approx(slope, abs=1e-12)
    assert axial_gap(rect.principal_azimuth, principal) < 1e-10
    assert axial_gap(rect.steepest_azimuth, steepest) < 1e-10
    assert -np.pi / 2 < rect.principal_azimuth <= np.pi / 2 and -np.pi / 2 < rect.steepest_azimuth <= np.pi / 2
    assert rect.centre == pytest.approx([3.0, -2.0, 7.0], abs=1e-12)
    assert rect.normal[2] > 0 and np.cross(rect.axes[0], rect.axes[1]) == pytest.approx(rect.normal, abs=1e-12)
    assert rect.axes @ rect.axes.T == pytest.approx(np.eye(3), abs=1e-12)


def test_pca_of_a_horizontal_plane_has_no_steepest_direction():
    pts, _ = planar_rectangle(40.0, 10.0, 0.0, 0.0, deg(20.0))
    rect = pca_rectangle(pts)
    assert rect.plane_slope == 0.0 and rect.mean_slope is None
    assert np.isnan(rect.steepest_azimuth)
    assert rect.principal_azimuth == pytest.approx(deg(20.0), abs=1e-12)


def test_pca_of_the_test_surfaces_matches_the_notes():
    """80×80 cell centres of the two Bézier patches (notes §0.1 [my check] values)."""
    rubio = pca_rectangle(*bezier(RUBIO))
    assert rubio.variances[:2] == pytest.approx([572.61, 133.23], abs=0.005)
    assert np.degrees(rubio.plane_slope) == pytest.approx(42.35, abs=0.005)
    assert np.degrees(rubio.principal_azimuth) == pytest.approx(-9.94, abs=0.005)
    assert np.degrees(axial_gap(rubio.steepest_azimuth, deg(67.0))) < 0.05
    choi = pca_rectangle(*bezier(CHOI))
    assert choi.variances[:2] == pytest.approx([312.07, 219.02], abs=0.005)
    assert np.degrees(choi.plane_slope) == pytest.approx(17.18, abs=0.005)
    assert np.degrees(choi.mean_slope) == pytest.approx(23.6, abs=0.05)
    assert np.degrees(axial_gap(choi.principal_azimuth, deg(90.0))) < 1e-6
    assert np.degrees(axial_gap(choi.steepest_azimuth, 0.0)) < 1e-6
    # the decisions of §2.10 (test case 1: ball; test case 2: torus), from the surfaces themselves
    assert choose_tool(rubio, *TOOL, KIN).tool == "ball"
    assert choose_tool(choi, *TOOL, KIN).tool == "toric"


CROSS_W, CROSS_H, CROSS_Q, CROSS_P = 80.0, 30.0, 10.0, 40.0


def test_pca_of_the_cross_counterexample():
    """§4.7: Var(Sx) = 402.08, Var(Sy) = 395.83 mm² from cell centres of a fine grid over the cross."""
    d = 0.1
    x, y = np.meshgrid(np.arange(-40.0 + d / 2, 40.0, d), np.arange(-55.0 + d / 2, 55.0, d), indexing="ij")
    inside = (np.abs(y) < CROSS_H / 2) | (np.abs(x) < CROSS_Q / 2)
    pts = np.column_stack([x[inside], y[inside], np.zeros(inside.sum())])
    rect = pca_rectangle(pts)
    assert rect.variances[:2] == pytest.approx([402.08, 395.83], abs=0.005)
    assert rect.principal_azimuth == pytest.approx(0.0, abs=1e-9)  # the principal direction is X


@pytest.mark.parametrize(
    "points, normals, message",
    [
        (np.zeros((2, 3)), None, "at least 3"),
        (np.zeros((5, 2)), None, r"\(n, 3\)"),
        ([[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]], None, "collinear"),
        (np.ones((4, 3)), None, "collinear"),
        ([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]], None, "NaN"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1], [0, 0, 1], [0, 0, 0]], "zero-length"),
        ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1]], "shape"),
    ],
)
def test_pca_rejects_degenerate_samples(points, normals, message):
    with pytest.raises(InputError, match=message):
        pca_rectangle(points, normals)


# --- closed forms of Ch.2 ----------------------------------------------------------------------------


def test_table_2_1_rectangle():
    """56 × 28 mm at 60°: R_eff 5.464, sod 0.6609 / 0.6321, T1 43.06 s, T2 37.34 s."""
    assert float(effective_radius(R, CORNER, deg(60.0), 0.0)) == pytest.approx(5.464, abs=0.0005)
    assert stepover_toric_steepest(deg(60.0), *TOOL) == pytest.approx(0.6609, abs=0.00005)
    assert stepover_ball(R, SH) == pytest.approx(0.6321, abs=0.00005)
    assert time_toric_steepest(2.0, 1568.0, deg(60.0), *TOOL, KIN) == pytest.approx(43.06, abs=0.005)
    assert time_ball_principal(2.0, 1568.0, R, SH, KIN) == pytest.approx(37.34, abs=0.005)
    # L2 = (h/sod2)(w + sod2) ≈ 2508 mm. L1 = χ/sod1 + sqrt(μχ) gives 2428.7 mm, not the notes' "≈ 2452"
    assert length_ball_principal(2.0, 1568.0, R, SH) == pytest.approx(2508.0, abs=0.5)
    assert length_toric_steepest(2.0, 1568.0, deg(60.0), *TOOL) == pytest.approx(1568.0 / 0.660854 + 56.0, abs=0.05)


def test_closed_forms_are_the_parallel_pass_terms():
    w, h, sod = 56.0, 28.0, 0.6321392251711644
    n = h / sod
    expected = n * (w / KIN.feed + 2 * np.sqrt(KIN.feed / KIN.jerk) + 4 * np.cbrt(sod / (2 * KIN.jerk)))
    assert parallel_passes_time(w, h, sod, KIN) == pytest.approx(expected, rel=1e-14)
    assert time_ball_principal(2.0, 1568.0, R, SH, KIN) == pytest.approx(expected, rel=1e-14)
    assert parallel_passes_length(w, h, sod) == pytest.approx(n * (w + sod), rel=1e-14)
    # where passes are case 2 and connections case 3, the exact segment times agree
    assert parallel_passes_segment_time(w, h, sod, KIN) == pytest.approx(expected, rel=1e-12)
    assert pass_time(w, KIN) + connection_time(sod, KIN) == pytest.approx(expected / n, rel=1e-14)


def test_segment_timed_passes_stay_right_outside_the_closed_forms_cases():
    sod, n = 0.6321, 28.0 / 0.6321
    conn = 4 * np.cbrt(sod / (2 * KIN.jerk))
    # short passes (3 mm < 2 sqrt(V³/J) = 7.6 mm) never reach V: case 3 (eq. 1.15), not case 2
    short = n * (4 * np.cbrt(3.0 / (2 * KIN.jerk)) + conn)
    assert parallel_passes_segment_time(3.0, 28.0, sod, KIN) == pytest.approx(short, rel=1e-12)
    # V > A²/J and long passes: A and V reached, case 1 (eq. 1.13)
    fast = MotionLimits(feed=1000.0, accel=6000.0, jerk=40000.0, rapid=1000.0)
    v, a, j = fast.feed, fast.accel, fast.jerk
    expected = n * (2000.0 / v + a / j + v / a + 4 * np.cbrt(sod / (2 * j)))
    assert parallel_passes_segment_time(2000.0, 28.0, sod, fast) == pytest.approx(expected, rel=1e-12)
    assert parallel_passes_time(2000.0, 28.0, sod, fast) < expected  # the case-2 form misses the A limit


@pytest.mark.parametrize(
    "chi, expected",
    [
        (1568.0, [55.10, 44.68, 33.86, 23.96, 18.99, 13.75, 9.93]),
        (3315.0, [59.55, 50.09, 39.90, 30.07, 24.86, 19.08, 14.58]),
        (10000.0, [65.66, 57.74, 48.84, 39.71, 34.56, 28.46, 23.32]),
    ],
)
def test_critical_slope_reference_table(chi, expected):
    mu = np.array([1.25, 1.5, 2.0, 3.0, 4.0, 6.0, 9.0])
    assert np.degrees(critical_slope(mu, chi, *TOOL, KIN)) == pytest.approx(expected, abs=0.005)


@pytest.mark.parametrize("mu, chi", [(2.0, 1568.0), (1.25, 3315.0), (6.0, 10000.0), (1.19, 3137.0)])
def test_times_are_equal_at_the_critical_slope(mu, chi):
    s_c = critical_slope(mu, chi, *TOOL, KIN)
    t2 = time_ball_principal(mu, chi, R, SH, KIN)
    assert time_toric_steepest(mu, chi, s_c, *TOOL, KIN) == pytest.approx(t2, rel=1e-12)
    lo, hi = 1e-6, np.pi / 2  # bisection on T1(s) - T2, increasing in s
    for _ in range(100):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if time_toric_steepest(mu, chi, mid, *TOOL, KIN) < t2 else (lo, mid)
    assert s_c == pytest.approx(lo, abs=1e-10)
    assert critical_shape_factor(s_c, chi, *TOOL, KIN) == pytest.approx(mu, rel=1e-10)


def test_critical_slope_when_the_cubic_has_three_real_roots():
    """Δ = 4p³ - 27q² ≥ 0 needs h below about the stepover (here V = 10 mm/s, χ = 0.01 mm²):
    the trigonometric form still gives the one positive root."""
    slow = MotionLimits(feed=10.0, accel=6000.0, jerk=40000.0, rapid=10.0)
    s_c = critical_slope(4.0, 0.01, *TOOL, slow)
    assert 0.0 < s_c < np.pi / 2
    t2 = time_ball_principal(4.0, 0.01, R, SH, slow)
    assert time_toric_steepest(4.0, 0.01, s_c, *TOOL, slow) == pytest.approx(t2, rel=1e-12)


def test_critical_shape_factor():
    assert critical_shape_factor(deg(33.86), 1568.0, *TOOL, KIN) == pytest.approx(2.000, abs=0.0005)
    slopes = deg(np.array([10, 20, 30, 40, 50, 60, 70, 80, 89.0]))
    expected = [8.92, 3.75, 2.29, 1.67, 1.35, 1.17, 1.07, 1.02, 1.00]
    assert critical_shape_factor(slopes, 1568.0, *TOOL, KIN) == pytest.approx(expected, abs=0.005)
    assert critical_shape_factor(deg(42.34), 3315.0, *TOOL, KIN) == pytest.approx(1.85, abs=0.005)
    assert critical_shape_factor(deg(17.13), 3137.0, *TOOL, KIN) == pytest.approx(6.82, abs=0.005)


def test_critical_slope_of_the_test_surfaces():
    """The printed 38.90° and 62.61° come from the rounded μ̃ 2.07 and 1.19; the unrounded
    sqrt(λI/λII) give 38.87° and 62.39°. The decisions do not change."""
    assert np.degrees(critical_slope(2.07, 3315.47, *TOOL, KIN)) == pytest.approx(38.90, abs=0.005)
    assert np.degrees(critical_slope(1.19, 3137.0, *TOOL, KIN)) == pytest.approx(62.61, abs=0.005)
    assert np.degrees(critical_slope(np.sqrt(572.62 / 133.31), 3315.47, *TOOL, KIN)) == pytest.approx(38.87, abs=0.005)
    assert np.degrees(critical_slope(np.sqrt(312.07 / 219.02), 3137.0, *TOOL, KIN)) == pytest.approx(62.39, abs=0.005)


def test_critical_slope_limits():
    # a square: the torus is at least as fast at every slope; a very long strip: never
    assert critical_slope(1.0, 1568.0, *TOOL, KIN) == pytest.approx(np.pi / 2, abs=1e-6)
    assert critical_slope(1000.0, 1568.0, *TOOL, KIN) == 0.0
    assert time_toric_steepest(1000.0, 1568.0, 0.0, *TOOL, KIN) > time_ball_principal(1000.0, 1568.0, R, SH, KIN)


def planar_choice(lam1, lam2, slope, steepest, principal):
    pts, normals = planar_rectangle(np.sqrt(12 * lam1), np.sqrt(12 * lam2), slope, steepest, principal)
    return pca_rectangle(pts, normals)


def test_choice_on_the_table_2_1_rectangle():
    rect = planar_choice(56.0**2 / 12, 28.0**2 / 12, deg(60.0), 0.0, deg(90.0))
    choice = choose_tool(rect, *TOOL, KIN)
    assert choice.tool == "ball" and choice.warnings == []
    assert choice.azimuth == pytest.approx(np.pi / 2, abs=1e-9) and choice.toric_azimuth == pytest.approx(0.0, abs=1e-9)
    assert choice.time_ball_principal == pytest.approx(37.34, abs=0.005)
    assert choice.time_toric_steepest == pytest.approx(43.06, abs=0.005)
    assert np.degrees(choice.critical_slope) == pytest.approx(33.86, abs=0.005)
    assert choice.critical_shape_factor < choice.shape_factor


@pytest.mark.parametrize(
    "lam1, lam2, slope, steepest, principal, tool, mu_c",
    [
        (572.62, 133.31, 42.34, 66.97, -9.74, "ball", 1.85),  # test case 1
        (312.07, 219.02, 17.13, 0.0, 90.0, "toric", 6.82),  # test case 2
    ],
)
def test_choice_on_the_test_cases(lam1, lam2, slope, steepest, principal, tool, mu_c):
    choice = choose_tool(planar_choice(lam1, lam2, deg(slope), deg(steepest), deg(principal)), *TOOL, KIN)
    assert choice.tool == tool and choice.warnings == []
    assert choice.critical_shape_factor == pytest.approx(mu_c, abs=0.01)  # χ̃ here is 3315.47 and 3137.25
    assert (choice.time_ball_principal < choice.time_toric_steepest) == (tool == "ball")
    expected_azimuth = principal if tool == "ball" else steepest
    assert np.degrees(axial_gap(choice.azimuth, deg(expected_azimuth))) < 1e-8


def test_choice_warns_where_the_closed_forms_do_not_hold():
    small = choose_tool(planar_choice(20.0**2 / 12, 5.0**2 / 12, deg(30.0), 0.0, deg(90.0)), *TOOL, KIN)
    assert any("passes do not reach the feed" in w for w in small.warnings)
    flat = choose_tool(planar_choice(56.0**2 / 12, 28.0**2 / 12, 0.0, 0.0, deg(30.0)), *TOOL, KIN)
    assert flat.tool == "toric" and flat.azimuth == pytest.approx(deg(30.0), abs=1e-9)
    assert any("horizontal" in w for w in flat.warnings) and any("flat bottom" in w for w in flat.warnings)
    fast = MotionLimits(feed=1000.0, accel=6000.0, jerk=40000.0, rapid=1000.0)
    rect = planar_choice(56.0**2 / 12, 28.0**2 / 12, deg(60.0), 0.0, deg(90.0))
    assert any("A_max" in w for w in choose_tool(rect, *TOOL, fast).warnings)
    # the mean pointwise slope and the plane's slope straddle s_c: the choice is flagged
    bent = PcaRectangle(rect.centre, rect.axes, rect.variances, deg(30.0), deg(40.0), rect.principal_azimuth, 0.0)
    assert any("uncertain" in w for w in choose_tool(bent, *TOOL, KIN).warnings)


@pytest.mark.parametrize(
    "call",
    [
        lambda: time_ball_principal(2.0, 1568.0, 5.0, 5.0, KIN),  # sh = R
        lambda: time_toric_steepest(2.0, 1568.0, deg(60.0), 5.0, 2.0, 6.0, KIN),  # sh > R
        lambda: critical_slope(2.0, 1568.0, 5.0, 6.0, 0.01, KIN),  # r > R
        lambda: critical_slope(np.nan, 1568.0, *TOOL, KIN),
        lambda: critical_slope(0.5, 1568.0, *TOOL, KIN),  # μ < 1
        lambda: critical_shape_factor(deg(30.0), -1.0, *TOOL, KIN),
        lambda: time_toric_steepest(2.0, 1568.0, deg(100.0), *TOOL, KIN),
        lambda: rectangle_time(56.0, 28.0, np.nan, 0.6, KIN),
        lambda: rectangle_time(56.0, 0.0, 0.1, 0.6, KIN),
    ],
)
def test_closed_forms_reject_bad_input(call):
    with pytest.raises(InputError):
        call()


# --- cross counterexample (§4.7) ---------------------------------------------------------------------


def test_cross_counterexample():
    sod = stepover_ball(R, SH)
    w, h, q, p = CROSS_W, CROSS_H, CROSS_Q, CROSS_P
    along_x = 2 * parallel_passes_time(q, p, sod, KIN) + parallel_passes_time(w, h, sod, KIN)
    along_y = 2 * parallel_passes_time(h, (w - q) / 2, sod, KIN) + parallel_passes_time(h + 2 * p, q, sod, KIN)
    three_zones = parallel_passes_time(w, h, sod, KIN) + 2 * parallel_passes_time(p, q, sod, KIN)
    assert [along_x, along_y, three_zones] == pytest.approx([90.49, 82.38, 74.27], abs=0.005)
    lengths = [
        2 * parallel_passes_length(q, p, sod) + parallel_passes_length(w, h, sod),
        2 * parallel_passes_length(h, (w - q) / 2, sod) + parallel_passes_length(h + 2 * p, q, sod),
        parallel_passes_length(w, h, sod) + 2 * parallel_passes_length(p, q, sod),
    ]
    assert lengths == pytest.approx([5172, 5142, 5112], abs=0.5)


# --- annex E -----------------------------------------------------------------------------------------


def zigzag_time(w, h, alpha, p, kin):
    """Brute force: lines at angle alpha (0 < alpha < pi/2) to the width side, p apart measured
    perpendicular to them (the first and last half a step in from the rectangle's extreme corners),
    clipped to [0, w] × [0, h]; a zigzag with a straight connection between consecutive line ends.
    Passes and connections timed with the same case 2 / case 3 terms."""
    d = np.array([np.cos(alpha), np.sin(alpha)])
    nrm = np.array([-np.sin(alpha), np.cos(alpha)])
    e_lo, e_hi = -w * np.sin(alpha), h * np.cos(alpha)
    ends = []
    for e in np.arange(e_lo + p / 2, e_hi, p):
        base = e * nrm  # the line is base + t d; keep 0 <= x <= w, 0 <= y <= h
        t_lo, t_hi = -np.inf, np.inf
        for k, top in ((0, w), (1, h)):
            a, b = (0 - base[k]) / d[k], (top - base[k]) / d[k]
            t_lo, t_hi = max(t_lo, min(a, b)), min(t_hi, max(a, b))
        ends.append((base + t_lo * d, base + t_hi * d))
    passes = [np.linalg.norm(b - a) for a, b in ends]
    conns = [np.linalg.norm(ends[i][1 - i % 2] - ends[i + 1][1 - i % 2]) for i in range(len(ends) - 1)]
    return sum(pass_time(x, kin) for x in passes) + sum(connection_time(x, kin) for x in conns)


@pytest.mark.parametrize("alpha_deg", [0.5, 3.0, 10.0, 17.0, 26.0, 26.6, 40.0, 63.43, 75.0, 89.0, 89.5])
@pytest.mark.parametrize("p", [0.6321, 2.3, 5.0])
def test_rectangle_time_matches_a_brute_force_zigzag(alpha_deg, p):
    """Both cases of annex E (tan α = h/w at 26.57°). The brute force has whole lines; the model
    counts (h cos α + w sin α)/p passes and as many connections, a fractional number in the central
    band and in each corner, where connections average the two legs p/cos α and p/sin α. The two
    differ by at most one longest pass with its fixed terms and one connection along the longer leg."""
    w, h, alpha = 56.0, 28.0, deg(alpha_deg)
    brute = zigzag_time(w, h, alpha, p, KIN)
    model = rectangle_time(w, h, alpha, p, KIN)
    longest_pass = min(w / np.cos(alpha), h / np.sin(alpha))
    tolerance = pass_time(longest_pass, KIN) + connection_time(p / min(np.sin(alpha), np.cos(alpha)), KIN)
    assert abs(model - brute) <= tolerance


def test_rectangle_time_special_angles_and_symmetry():
    w, h, p = 56.0, 28.0, 0.6321
    assert rectangle_time(w, h, 0.0, p, KIN) == pytest.approx(parallel_passes_time(w, h, p, KIN), rel=1e-14)
    assert rectangle_time(w, h, np.pi / 2, p, KIN) == pytest.approx(parallel_passes_time(h, w, p, KIN), rel=1e-14)
    # α = 0 is the T2 form of Ch.2 at the ball's stepover
    assert rectangle_time(w, h, 0.0, stepover_ball(R, SH), KIN) == pytest.approx(
        time_ball_principal(2.0, 1568.0, R, SH, KIN), rel=1e-14
    )
    alpha = np.array([0.3, 1.1])
    assert rectangle_time(w, h, -alpha, p, KIN) == pytest.approx(rectangle_time(w, h, alpha, p, KIN), rel=1e-14)
    assert rectangle_time(w, h, np.pi - alpha, p, KIN) == pytest.approx(rectangle_time(w, h, alpha, p, KIN), rel=1e-14)
    swapped = rectangle_time(h, w, np.pi / 2 - alpha, p, KIN)
    assert swapped == pytest.approx(rectangle_time(w, h, alpha, p, KIN), rel=1e-14)
    # continuous at 0, at the change of case tan α = h/w and at pi/2
    for a in (0.0, np.arctan2(h, w), np.pi / 2):
        left, right = rectangle_time(w, h, [a - 1e-9, a + 1e-9], p, KIN)
        assert left == pytest.approx(right, rel=1e-6)
        assert rectangle_time(w, h, a, p, KIN) == pytest.approx(left, rel=1e-6)


def test_zone_surrogate_reduces_to_t1_and_t2():
    rect = planar_choice(56.0**2 / 12, 28.0**2 / 12, deg(60.0), 0.0, deg(90.0))
    t2 = time_ball_principal(2.0, 1568.0, R, SH, KIN)
    t1 = time_toric_steepest(2.0, 1568.0, deg(60.0), *TOOL, KIN)
    assert zone_time_surrogate(rect, np.pi / 2, R, R, SH, KIN) == pytest.approx(t2, rel=1e-9)
    assert zone_time_surrogate(rect, 0.0, *TOOL, KIN) == pytest.approx(t1, rel=1e-9)
    theta = np.linspace(-np.pi / 2, np.pi / 2, 7)
    times = zone_time_surrogate(rect, theta, *TOOL, KIN)
    assert times.shape == (7,)
    assert times == pytest.approx([zone_time_surrogate(rect, t, *TOOL, KIN) for t in theta], rel=1e-14)
    # a ball's stepover does not depend on the direction: only α changes
    ball = zone_time_surrogate(rect, theta, R, R, SH, KIN)
    assert ball.min() == pytest.approx(t2, rel=1e-9)


def test_zone_surrogate_on_an_oblique_plane_and_a_flat_one():
    rect = planar_choice(572.62, 133.31, deg(42.34), deg(66.97), deg(-9.74))
    theta = deg(20.0)
    # the lifted feed's angle to S_I, and R_eff from the XY angle to the steepest azimuth
    n = rect.normal
    f = np.array([np.cos(theta), np.sin(theta), -(n[0] * np.cos(theta) + n[1] * np.sin(theta)) / n[2]])
    alpha = np.arccos(abs(f @ rect.axes[0]) / np.linalg.norm(f))
    r_eff = float(effective_radius(R, CORNER, deg(42.34), theta - deg(66.97)))
    p = 2 * np.sqrt(2 * SH * r_eff - SH**2)
    expected = rectangle_time(rect.width, rect.height, alpha, p, KIN)
    assert zone_time_surrogate(rect, theta, *TOOL, KIN) == pytest.approx(expected, rel=1e-12)
    flat = planar_choice(400.0, 100.0, 0.0, 0.0, deg(10.0))
    cap = 2 * (R - CORNER) + 2 * np.sqrt(CORNER**2 - (CORNER - SH) ** 2)
    # every direction gets the flat-bottom stepover, across the principal direction too
    assert zone_time_surrogate(flat, deg([10.0, 100.0]), *TOOL, KIN) == pytest.approx(
        [parallel_passes_time(flat.width, flat.height, cap, KIN),
         parallel_passes_time(flat.height, flat.width, cap, KIN)],
        rel=1e-9,
    )


def test_zone_surrogate_rejects_a_vertical_plane():
    pts, _ = planar_rectangle(40.0, 10.0, deg(60.0), 0.0, deg(90.0))
    rect = pca_rectangle(pts)
    vertical = PcaRectangle(rect.centre, np.array([[0, 1.0, 0], [0, 0, 1.0], [1.0, 0, 0]]), rect.variances,
                            np.pi / 2, None, np.pi / 2, 0.0)
    with pytest.raises(InputError, match="vertical"):
        zone_time_surrogate(vertical, 0.3, *TOOL, KIN)
