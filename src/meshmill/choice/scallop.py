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
