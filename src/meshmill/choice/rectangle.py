"""PCA rectangle of a surface, the ball-or-bull-nose choice and the rectangle time surrogate
(seed 002, Herraz 2021: Ch.2 and annex E, with the misprints of the notes §8 corrected).

A surface (or a zone of it) is replaced by the rectangle that has the same second moments as its
sample points: w = sqrt(12 λ_I) along the principal direction S_I, h = sqrt(12 λ_II) along S_II,
shape factor μ = w/h and characteristic size χ = w h. Machining it with parallel zigzag passes
gives closed-form times: a toric tool fed along the steepest slope (T1, eq. 2.4) against a ball
fed along the principal direction (T2, eq. 2.5), the slope s_c(μ) where they are equal (eq. 2.10)
and the shape factor μ_c(s) where they are equal (annex A eq. 8).

Timing model (notes §1.8): every pass and every connection is a straight segment from rest to
rest. The closed forms take passes in case 2 (V reached, A not: l/V + 2 sqrt(V/J)) and
connections in case 3 (neither: 4 ∛(l/(2J))); ``choose_tool`` says when that does not hold.
Pass counts are not rounded (width/stepover), as in the seed.

Units: mm, s, radians. Azimuths are angles in XY from +X; axial ones lie in (-pi/2, pi/2].
Slopes are arccos|n·Z| (0 for a horizontal plane).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..machine.model import MotionLimits
from ..machine.timing import segment_time
from ..pathing.scallop import effective_radius, flat_bottom_stepover, stepover

# |XY part| of a unit vector below which it counts as vertical (no azimuth)
_VERTICAL = 1e-12
# λ_II/λ_I below which the samples count as collinear
_COLLINEAR = 1e-12


def _scalar_or_array(x):
    x = np.asarray(x, float)
    return float(x) if x.ndim == 0 else x


def _axial(angle):
    """Fold an azimuth of a line (defined mod pi) into (-pi/2, pi/2]."""
    return np.pi / 2 - np.mod(np.pi / 2 - angle, np.pi)


def _azimuth(v) -> float:
    """Axial azimuth of a 3D direction's XY projection; NaN when the direction is vertical."""
    if np.hypot(v[0], v[1]) <= _VERTICAL:
        return float("nan")
    return float(_axial(np.arctan2(v[1], v[0])))


# ---------------------------------------------------------------------------------------------
# PCA rectangle (§2.3)


@dataclass(frozen=True, eq=False)
class PcaRectangle:
    """Rectangle with the second moments of a set of surface samples.

    ``centre`` (3,) mm; ``axes`` (3, 3) rows S_I, S_II, S_III (unit; S_III = S_I × S_II points up,
    the best-fit plane's normal); ``variances`` (3,) λ_I ≥ λ_II ≥ λ_III mm² (1/n covariance);
    ``plane_slope`` rad (eq. 2.16 corrected: arccos|S_III·Z|); ``mean_slope`` rad, mean of the
    pointwise slopes (eq. 2.15) or None without normals; ``principal_azimuth`` of S_I and
    ``steepest_azimuth`` of the XY projection of the normal, axial in (-pi/2, pi/2], NaN when
    undefined (S_I vertical; horizontal plane)."""

    centre: np.ndarray
    axes: np.ndarray
    variances: np.ndarray
    plane_slope: float
    mean_slope: float | None
    principal_azimuth: float
    steepest_azimuth: float

    @property
    def normal(self) -> np.ndarray:
        """Unit normal of the best-fit plane, z ≥ 0, (3,)."""
        return self.axes[2]

    @property
    def width(self) -> float:
        """w = sqrt(12 λ_I), mm: the side along S_I."""
        return float(np.sqrt(12.0 * self.variances[0]))

    @property
    def height(self) -> float:
        """h = sqrt(12 λ_II), mm: the side along S_II."""
        return float(np.sqrt(12.0 * self.variances[1]))

    @property
    def shape_factor(self) -> float:
        """μ = sqrt(λ_I/λ_II) = w/h ≥ 1 (eq. 2.13)."""
        return float(np.sqrt(self.variances[0] / self.variances[1]))

    @property
    def size(self) -> float:
        """χ = 12 sqrt(λ_I λ_II) = w h, mm² (eq. 2.14)."""
        return float(12.0 * np.sqrt(self.variances[0] * self.variances[1]))


def pca_rectangle(points, normals=None) -> PcaRectangle:
    """PCA rectangle of surface samples ``points`` (n, 3) mm, n ≥ 3, unweighted (the seed uses the
    centres of a uniform (u, v) grid of cells); ``normals`` (n, 3), of any non-zero length, give
    the mean pointwise slope."""
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"surface samples must be an (n, 3) array, got shape {pts.shape}")
    if len(pts) < 3:
        raise InputError(f"a PCA rectangle needs at least 3 surface samples, got {len(pts)}")
    if not np.all(np.isfinite(pts)):
        raise InputError("surface samples contain NaN or infinite coordinates")
    centre = pts.mean(axis=0)
    d = pts - centre
    lam, vec = np.linalg.eigh(d.T @ d / len(pts))
    lam, vec = np.clip(lam[::-1], 0.0, None), vec[:, ::-1]
    if not lam[1] > _COLLINEAR * lam[0]:
        raise InputError("surface samples are collinear or coincident: they span no plane")
    s1, s2 = vec[:, 0], vec[:, 1]
    n = np.cross(s1, s2)
    n /= np.linalg.norm(n)
    if n[2] < 0.0:
        n, s2 = -n, -s2
    mean_slope = None
    if normals is not None:
        nrm = np.asarray(normals, float)
        if nrm.shape != pts.shape:
            raise InputError(f"normals must have the samples' shape {pts.shape}, got {nrm.shape}")
        length = np.linalg.norm(nrm, axis=1)
        if not np.all(np.isfinite(length)) or np.any(length <= 0.0):
            raise InputError("normals contain NaN, infinite or zero-length vectors")
        mean_slope = float(np.mean(np.arccos(np.clip(np.abs(nrm[:, 2]) / length, 0.0, 1.0))))
    return PcaRectangle(
        centre=centre,
        axes=np.stack([s1, s2, n]),
        variances=lam,
        plane_slope=float(np.arccos(min(abs(n[2]), 1.0))),
        mean_slope=mean_slope,
        principal_azimuth=_azimuth(s1),
        steepest_azimuth=_azimuth(n),
    )


# ---------------------------------------------------------------------------------------------
# Parallel passes over a rectangle (§1.6.2, §2.2)


def pass_time(length, kin: MotionLimits):
    """Time ``(...)`` s of a pass of ``length`` mm that reaches the feed V (case 2, eq. 1.14):
    length/V + 2 sqrt(V/J)."""
    return length / kin.feed + 2.0 * np.sqrt(kin.feed / kin.jerk)


def connection_time(length, kin: MotionLimits):
    """Time ``(...)`` s of a connection of ``length`` mm that reaches neither V nor A
    (case 3, eq. 1.15): 4 ∛(length/(2J))."""
    return 4.0 * np.cbrt(np.asarray(length, float) / (2.0 * kin.jerk))


def parallel_passes_time(length_along, width_across, sod, kin: MotionLimits):
    """Closed-form zigzag time ``(...)`` s: (width/sod) passes of ``length_along`` mm, each followed
    by a connection of ``sod`` mm, passes in case 2 and connections in case 3:
    (width/sod)(length/V + 2 sqrt(V/J) + 4 ∛(sod/(2J))). The pass count is not rounded."""
    return _scalar_or_array(width_across / sod * (pass_time(length_along, kin) + connection_time(sod, kin)))


def parallel_passes_segment_time(length_along, width_across, sod, kin: MotionLimits):
    """As ``parallel_passes_time`` ``(...)`` s, with each pass and connection timed by the exact
    rest-to-rest segment time, right in every kinematic case (short passes, long connections,
    A reached)."""
    t_pass = segment_time(length_along, kin.feed, kin.accel, kin.jerk)
    t_conn = segment_time(sod, kin.feed, kin.accel, kin.jerk)
    return _scalar_or_array(width_across / sod * (np.asarray(t_pass) + t_conn))


def parallel_passes_length(length_along, width_across, sod):
    """Path length ``(...)`` mm of the same zigzag: (width/sod)(length + sod)."""
    return _scalar_or_array(width_across / sod * (length_along + sod))


# ---------------------------------------------------------------------------------------------
# Ball along the principal direction against torus along the steepest slope (§2.2, annex A)


def _check_tool(radius, corner, scallop):
    for name, value in (("tool radius", radius), ("corner radius", corner), ("scallop height", scallop)):
        if not (np.isfinite(value) and value > 0.0):
            raise InputError(f"the {name} must be a positive number, got {value}")
    if corner > radius:
        raise InputError(f"corner radius {corner:g} mm is larger than the tool radius {radius:g} mm")
    if scallop >= radius:
        raise InputError(f"scallop height {scallop:g} mm is not smaller than the tool radius {radius:g} mm")


def _sides(mu, chi):
    """w = sqrt(μχ), h = sqrt(χ/μ) of a rectangle with μ ≥ 1 and χ > 0 (arrays broadcast)."""
    mu, chi = np.asarray(mu, float), np.asarray(chi, float)
    if not np.all(np.isfinite(mu) & (mu >= 1.0)):
        raise InputError(f"the shape factor μ = w/h must be a number ≥ 1, got {mu}")
    if not np.all(np.isfinite(chi) & (chi > 0.0)):
        raise InputError(f"the characteristic size χ = w h must be a positive number, got {chi}")
    return np.sqrt(mu * chi), np.sqrt(chi / mu)


def _check_slope(slope):
    slope = np.asarray(slope, float)
    if not np.all(np.isfinite(slope) & (slope >= 0.0) & (slope <= np.pi / 2)):
        raise InputError(f"the slope must be an angle in [0, pi/2] rad, got {slope}")
    return slope


def stepover_toric_steepest(slope, radius, corner, scallop):
    """sod1 ``(...)`` mm of a bull-nose tool fed along the steepest slope: eq. 2.3 with
    R_eff = (R - r)/sin s + r (eq. 2.2), capped by the flat-bottom stepover (infinite R_eff at s = 0)."""
    _check_tool(radius, corner, scallop)
    r_eff = effective_radius(radius, corner, _check_slope(slope), 0.0)
    return _scalar_or_array(stepover(scallop, r_eff, radius, corner))


def stepover_ball(radius, scallop):
    """sod2 mm of a ball tool: 2 sqrt(2 sh R - sh²)."""
    _check_tool(radius, radius, scallop)
    return float(stepover(scallop, radius))


def time_toric_steepest(mu, chi, slope, radius, corner, scallop, kin: MotionLimits):
    """T1 ``(...)`` s (eq. 2.4): torus fed along the steepest slope, w/sod1 passes of length h."""
    w, h = _sides(mu, chi)
    return parallel_passes_time(h, w, stepover_toric_steepest(slope, radius, corner, scallop), kin)


def length_toric_steepest(mu, chi, slope, radius, corner, scallop):
    """L1 ``(...)`` mm = χ/sod1 + sqrt(μχ) (the notes' corrected form)."""
    w, h = _sides(mu, chi)
    return parallel_passes_length(h, w, stepover_toric_steepest(slope, radius, corner, scallop))


def time_ball_principal(mu, chi, radius, scallop, kin: MotionLimits):
    """T2 ``(...)`` s (eq. 2.5): ball fed along the principal direction, h/sod2 passes of length w."""
    w, h = _sides(mu, chi)
    return parallel_passes_time(w, h, stepover_ball(radius, scallop), kin)


def length_ball_principal(mu, chi, radius, scallop):
    """L2 ``(...)`` mm = (h/sod2)(sqrt(χμ) + sod2) (the notes' corrected form)."""
    w, h = _sides(mu, chi)
    return parallel_passes_length(w, h, stepover_ball(radius, scallop))


def critical_slope(mu, chi, radius, corner, scallop, kin: MotionLimits):
    """s_c ``(...)`` rad where T1 = T2 (eqs. 2.6-2.10): below it the torus along the steepest slope
    is faster, above it the ball along the principal direction.

    z = ∛sod1 is the positive root of z³ - p z - q = 0 (Cardano with the corrected sign, or the
    trigonometric form when Δ = 4p³ - 27q² ≥ 0; there is exactly one positive root either way).
    When that sod1 is not above the ball's (arcsin argument ≥ 1), the torus wins at every slope:
    pi/2. When it is not below the flat-bottom stepover, the torus loses at every slope: 0."""
    _check_tool(radius, corner, scallop)
    w, h = _sides(mu, chi)
    t2 = np.asarray(time_ball_principal(mu, chi, radius, scallop, kin))
    p = 4.0 * w / (t2 * np.cbrt(2.0 * kin.jerk))
    q = w * pass_time(h, kin) / t2
    disc = 4.0 * p**3 - 27.0 * q**2
    root = np.sqrt(np.abs(disc) / 108.0)
    cardano = np.cbrt(q / 2.0 + root) + np.cbrt(q / 2.0 - root)
    trig = 2.0 * np.sqrt(p / 3.0) * np.cos(np.arccos(np.clip(1.5 * q / p * np.sqrt(3.0 / p), -1.0, 1.0)) / 3.0)
    z = np.where(disc < 0.0, cardano, trig)
    sod1 = z**3
    with np.errstate(divide="ignore"):
        arg = 8.0 * scallop * (radius - corner) / (z**6 + 4.0 * scallop**2 - 8.0 * scallop * corner)
        s_c = np.arcsin(np.clip(arg, 0.0, 1.0))
    s_c = np.where(sod1 >= flat_bottom_stepover(radius, corner, scallop), 0.0, s_c)
    return _scalar_or_array(np.where(sod1 <= stepover_ball(radius, scallop), np.pi / 2, s_c))


def critical_shape_factor(slope, chi, radius, corner, scallop, kin: MotionLimits):
    """μ_c ``(...)`` where T1 = T2 at this slope (annex A eq. 8): above it the ball along the
    principal direction is faster. sod1 is capped by the flat bottom as in T1."""
    chi = np.asarray(chi, float)
    if not np.all(np.isfinite(chi) & (chi > 0.0)):
        raise InputError(f"the characteristic size χ = w h must be a positive number, got {chi}")
    sod1 = np.asarray(stepover_toric_steepest(slope, radius, corner, scallop))
    sod2 = stepover_ball(radius, scallop)
    rho = sod2 / sod1
    k = np.sqrt(kin.feed / kin.jerk)
    a1 = k + 2.0 * np.cbrt(sod1 / (2.0 * kin.jerk))
    a2 = k + 2.0 * np.cbrt(sod2 / (2.0 * kin.jerk))
    b = np.sqrt(chi) / kin.feed * (1.0 - rho)
    return _scalar_or_array(((b + np.sqrt(b * b + 16.0 * rho * a1 * a2)) / (4.0 * rho * a1)) ** 2)


@dataclass(frozen=True)
class ToolChoice:
    """Decision of ``choose_tool``. ``tool`` is "ball" or "toric"; ``azimuth`` rad is the feed
    direction in XY (axial); times s and lengths mm are the closed-form predictions of both
    options; ``slope``, ``critical_slope`` rad and ``shape_factor``, ``critical_shape_factor`` are
    the quantities compared; ``warnings`` lists where the closed forms' assumptions fail."""

    tool: str
    azimuth: float
    time_ball_principal: float
    time_toric_steepest: float
    length_ball_principal: float
    length_toric_steepest: float
    ball_azimuth: float
    toric_azimuth: float
    slope: float
    critical_slope: float
    shape_factor: float
    critical_shape_factor: float
    warnings: list[str]


def choose_tool(rect: PcaRectangle, radius, corner, scallop, kin: MotionLimits) -> ToolChoice:
    """Ball tool (radius R) along the principal direction or bull-nose tool (R, corner r) along the
    steepest slope for the PCA rectangle ``rect`` (§2.4.1): ball when the plane's slope is above
    s_c(μ̃) at χ̃ (a tie goes to the torus). Scallop height ``scallop`` mm."""
    mu, chi, slope = rect.shape_factor, rect.size, rect.plane_slope
    s_c = critical_slope(mu, chi, radius, corner, scallop, kin)
    sod1 = stepover_toric_steepest(slope, radius, corner, scallop)
    warnings = []
    v, a, j = kin.feed, kin.accel, kin.jerk
    threshold = 2.0 * np.sqrt(v**3 / j)  # segment length above which V is reached
    if v > a * a / j:
        warnings.append(
            f"the feed {v:g} mm/s is above A²/J = {a * a / j:g} mm/s: speed-ups reach A_max (case 1), "
            "which the closed forms ignore; time with parallel_passes_segment_time instead"
        )
    if rect.height <= threshold:
        warnings.append(
            f"the rectangle's height {rect.height:.3g} mm is not above 2 sqrt(V³/J) = {threshold:.3g} mm: "
            "passes do not reach the feed (case 2 assumed)"
        )
    if sod1 >= threshold:
        warnings.append(
            f"the toric stepover {sod1:.3g} mm is not below 2 sqrt(V³/J) = {threshold:.3g} mm: "
            "connections reach the feed (case 3 assumed)"
        )
    if sod1 >= flat_bottom_stepover(radius, corner, scallop):
        warnings.append(f"the toric stepover is capped by the flat bottom at {sod1:.4g} mm (eq. 2.3 is unbounded here)")
    if rect.mean_slope is not None and (rect.mean_slope > s_c) != (slope > s_c):
        warnings.append(
            f"the mean pointwise slope {np.degrees(rect.mean_slope):.2f}° and the plane's slope "
            f"{np.degrees(slope):.2f}° lie on both sides of s_c = {np.degrees(s_c):.2f}°: the choice is uncertain"
        )
    toric_azimuth = rect.steepest_azimuth
    if np.isnan(toric_azimuth):
        toric_azimuth = rect.principal_azimuth
        warnings.append(
            "the plane is horizontal: the toric tool has its flat-bottom stepover in every direction, "
            "so it is fed along the principal direction, at most as long as the predicted T1"
        )
    # s_c = 0: the torus loses even on a horizontal plane; s_c = pi/2: it wins even on a vertical one
    tool = "ball" if slope > s_c or s_c == 0.0 else "toric"
    return ToolChoice(
        tool=tool,
        azimuth=rect.principal_azimuth if tool == "ball" else toric_azimuth,
        time_ball_principal=time_ball_principal(mu, chi, radius, scallop, kin),
        time_toric_steepest=time_toric_steepest(mu, chi, slope, radius, corner, scallop, kin),
        length_ball_principal=length_ball_principal(mu, chi, radius, scallop),
        length_toric_steepest=length_toric_steepest(mu, chi, slope, radius, corner, scallop),
        ball_azimuth=rect.principal_azimuth,
        toric_azimuth=toric_azimuth,
        slope=slope,
        critical_slope=s_c,
        shape_factor=mu,
        critical_shape_factor=critical_shape_factor(slope, chi, radius, corner, scallop, kin),
        warnings=warnings,
    )


# ---------------------------------------------------------------------------------------------
# Annex E: zigzag at any angle over a rectangle (surrogate 3)


def rectangle_time(width, height, alpha, p, kin: MotionLimits):
    """Zigzag time ``(...)`` s over a ``width`` × ``height`` mm rectangle, passes at angle ``alpha``
    rad to the width side and ``p`` mm apart (annex E). Passes in case 2, connections along the
    sides in case 3, pass counts not rounded.

    α is folded into [0, pi/2] (the time is the same for α, -α and pi - α). Case tan α ≥ h/w is
    case tan α ≤ h/w with the sides swapped and α -> pi/2 - α, so one formula serves both: a
    central band of (cos α/p)(h - w tan α) full passes of length w/cos α with connections
    p/cos α, and two corner triangles of w sin α/p passes each, whose connections alternate between
    p/cos α and p/sin α. The corner passes' lengths i p/(sin α cos α), i = 1..m, are summed as
    m² p/(2 sin α cos α) = (triangle area)/p, like the central band (area/p), so that a
    non-integer m needs no rounding and the time is continuous in α; the literal
    m(m + 1)/2 would add a full diagonal pass per corner and jump by w/V at α = 0. Every term is
    written without dividing by sin α, so α = 0 and pi/2 give exactly the parallel-pass forms."""
    w, h, p = (np.asarray(x, float) for x in (width, height, p))
    alpha = np.asarray(alpha, float)
    for name, x in (("width", w), ("height", h), ("stepover", p)):
        if not np.all(np.isfinite(x) & (x > 0.0)):
            raise InputError(f"the rectangle's {name} must be positive, got {x}")
    if not np.all(np.isfinite(alpha)):
        raise InputError(f"the pass angle must be finite, got {alpha}")
    a = np.mod(alpha, np.pi)
    a = np.where(a > np.pi / 2, np.pi - a, a)
    swap = a > np.arctan2(h, w)
    w, h, a = np.where(swap, h, w), np.where(swap, w, h), np.where(swap, np.pi / 2 - a, a)
    cos_a, sin_a, tan_a = np.cos(a), np.sin(a), np.tan(a)
    speed_up = 2.0 * np.sqrt(kin.feed / kin.jerk)
    side_step = p / cos_a  # connection along the sides the full passes end on
    n_full = np.maximum(cos_a / p * (h - w * tan_a), 0.0)
    central = n_full * (pass_time(w / cos_a, kin) + connection_time(side_step, kin))
    m = w * sin_a / p  # passes in one corner triangle
    corner = (
        w * w * tan_a / (2.0 * p * kin.feed)  # Σ pass lengths / V
        + m * (speed_up + connection_time(side_step, kin) / 2.0)
        + 2.0 * (w / p) * np.cbrt(sin_a * sin_a * p / (2.0 * kin.jerk))  # m · 2 ∛((p/sin α)/(2J))
    )
    return _scalar_or_array(central + 2.0 * corner)


def zone_time_surrogate(rect: PcaRectangle, theta, radius, corner, scallop, kin: MotionLimits):
    """Surrogate 3 ``(...)`` s: zigzag time over ``rect`` with the feed azimuth ``theta (...)`` rad
    in XY. The feed is lifted into the PCA plane (F_p normalised) and α = angle(F_p, S_I); the
    stepover p is eq. 2.3 with R_eff (eq. 1.5) at the plane's slope and the XY angle between theta
    and the plane's steepest azimuth (any on a horizontal plane), capped by the flat bottom."""
    _check_tool(radius, corner, scallop)
    theta = np.asarray(theta, float)
    if not np.all(np.isfinite(theta)):
        raise InputError(f"the feed azimuth must be finite, got {theta}")
    n = rect.normal
    if n[2] <= _VERTICAL:
        raise InputError("the PCA plane is vertical: a feed direction in XY cannot be lifted into it")
    c, s = np.cos(theta), np.sin(theta)
    feed = np.stack([c, s, -(n[0] * c + n[1] * s) / n[2]], axis=-1)
    feed /= np.linalg.norm(feed, axis=-1, keepdims=True)
    # arctan2 of |sin| and |cos| stays accurate where arccos of a cosine near 1 does not
    alpha = np.arctan2(np.linalg.norm(np.cross(feed, rect.axes[0]), axis=-1), np.abs(feed @ rect.axes[0]))
    # on a horizontal plane every direction is "along the slope": R_eff is infinite (capped below)
    to_steepest = np.zeros_like(theta) if np.isnan(rect.steepest_azimuth) else theta - rect.steepest_azimuth
    r_eff = effective_radius(radius, corner, rect.plane_slope, to_steepest)
    p = stepover(scallop, r_eff, radius, corner)
    return rectangle_time(rect.width, rect.height, alpha, p, kin)
