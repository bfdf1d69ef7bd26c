"""Effective cutting radius and the stepover that leaves a given scallop height (seed 002, §1.2-1.3).

Angles in radians, lengths in mm. ``slope`` s is the angle between the surface normal and +Z
(arccos|n_z|, the seed's corrected definition); ``alpha`` is the angle between the XY projections
of the feed direction and of the steepest-slope direction (the convention under which eq. 1.5 is
exact, see the notes §1.2).
"""
from __future__ import annotations

import numpy as np

from ..errors import InputError


def effective_radius(radius, corner, slope, alpha):
    """R_eff ``(...)`` of a vertical ball (corner == radius) or bull-nose cutter (eq. 1.5):
    (R - r) cos²α / (sin s (1 - sin²α sin²s)) + r; infinite on a horizontal surface (s = 0)
    when R > r and the feed is not across the slope."""
    slope, alpha = np.broadcast_arrays(np.asarray(slope, float), np.asarray(alpha, float))
    flat = radius - corner
    if flat <= 0.0:
        return np.full(slope.shape, float(radius))
    sin_s, sin_a, cos_a = np.sin(slope), np.sin(alpha), np.cos(alpha)
    den = sin_s * (1.0 - sin_a**2 * sin_s**2)
    num = flat * cos_a**2
    with np.errstate(divide="ignore", invalid="ignore"):
        r_eff = np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), np.inf) + corner
    return np.where(num <= 0.0, float(corner), r_eff)


def flat_bottom_stepover(radius, corner, scallop):
    """Largest stepover on a horizontal plane, mm: the flat bottom plus the two corner arcs
    2(R - r) + 2 sqrt(r² - (r - h)²) (seed 002 §2.2.2.1; 6.4 mm for R 5, r 2, h 0.01)."""
    h = min(scallop, corner)
    return 2.0 * (radius - corner) + 2.0 * np.sqrt(corner**2 - (corner - h) ** 2)


def stepover(scallop, r_eff, radius=None, corner=None):
    """sod = 2 sqrt(2 h R_eff - h²) ``(...)`` mm, the distance on the surface between passes that
    leaves a scallop of ``h``; capped by the flat-bottom stepover when ``radius``/``corner`` are given."""
    r_eff = np.asarray(r_eff, float)
    if not (np.isfinite(scallop) and scallop > 0):
        raise InputError(f"the scallop height must be a positive number, got {scallop}")
    if np.any(scallop >= r_eff):
        raise InputError(f"scallop height {scallop:g} mm is not smaller than the effective radius {float(np.min(r_eff)):g} mm")
    with np.errstate(invalid="ignore", over="ignore"):
        sod = 2.0 * np.sqrt(2.0 * scallop * r_eff - scallop * scallop)
    if radius is not None:
        sod = np.minimum(sod, flat_bottom_stepover(radius, corner, scallop))
    return sod


RING_SAMPLES = 720  # points of the torus's centre circle in the exact stepover


def stepover_exact(scallop, radius, corner, normals, feeds, samples=RING_SAMPLES):
    """Exact stepover ``(k,)`` mm of a vertical ball or bull-nose cutter on a locally plane surface:
    the distance, on the surface and square to the feed, between two passes whose cusp is
    ``scallop`` high. ``normals (k, 3)`` unit surface normals, ``feeds (k, 3)`` unit feed
    directions tangent to the surface (machining frame, tool axis +Z).

    Seen along the feed, the cutter (its corner circle swept by a ball of radius r) is the union of
    the discs of radius r centred on the projected centre circle, an ellipse E; the surface is a
    line. A pass leaves the lower outline of that shape; two passes d apart leave a cusp h high
    exactly when d is the width of the shape h above its lowest point. So the stepover is
    max(x_E + w) - min(x_E - w) over the circle, w = sqrt(r² - (y_E - y_min - h - r)²) the
    half-chord of each disc at that height. For a ball this is 2 sqrt(2 h R - h²) (eq. 2.3); on a
    horizontal surface 2(R - r) + 2 sqrt(2 h r - h²), the flat bottom; at a slope it tends to eq.
    1.5's circle as h -> 0, but unlike eq. 1.5 it sees that a bull-nose fed along the contour of a
    gentle slope (alpha near 90 deg) leaves the flat bottom's tilt, not its corner radius, as the
    scallop on one side: the step grows as the slope vanishes instead of dropping to the corner's."""
    normals = np.asarray(normals, float).reshape(-1, 3)
    feeds = np.asarray(feeds, float).reshape(-1, 3)
    if not (np.isfinite(scallop) and scallop > 0):
        raise InputError(f"the scallop height must be a positive number, got {scallop}")
    r, flat = float(corner), float(radius - corner)
    if scallop >= r:
        raise InputError(f"scallop height {scallop:g} mm is not smaller than the corner radius {r:g} mm")
    ball = 2.0 * np.sqrt(2.0 * scallop * r - scallop * scallop)
    if flat <= 0.0 or len(normals) == 0:
        return np.full(len(normals), ball)
    across = np.cross(normals, feeds)
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    psi = np.linspace(0.0, 2.0 * np.pi, samples, endpoint=False)
    c, s = np.cos(psi), np.sin(psi)
    # the centre circle (flat * (cos, sin, 0)) in (across, normal) coordinates, per contact
    x = flat * (np.outer(across[:, 0], c) + np.outer(across[:, 1], s))
    y = flat * (np.outer(normals[:, 0], c) + np.outer(normals[:, 1], s))
    lowest = -flat * np.hypot(normals[:, 0], normals[:, 1])  # min of y, exact
    rise = y - lowest[:, None]  # >= 0: how far each disc's centre sits above the lowest one's
    w2 = r * r - (r + rise - scallop) ** 2
    reach = w2 >= 0.0
    w = np.sqrt(np.where(reach, w2, 0.0))
    right = np.where(reach, x + w, -np.inf).max(axis=1)
    left = np.where(reach, x - w, np.inf).min(axis=1)
    # sampling the circle may miss the lowest disc by a hair: never below the ball's chord
    return np.maximum(right - left, ball)
