"""Tool axes for 3+2-axis zones (seed 002 §4.1 and the PCA heuristic of §4.5).

The seed's two rotations of a zone become one tool axis here: the first turns the zone's PCA
normal X_III onto the spindle (the best-fit plane becomes horizontal); the second turns it by
``zeta`` about X_II, so that the plane slopes along X_I by |zeta| and its steepest-slope direction is
the principal direction. The rotation centre does not matter for a tool axis (the seed leaves it
unstated). A tool axis is accessible when every sample normal of the zone is within 90 degrees
of it (eq. 4.1: n . a >= 0; the drop-cutter then keeps the whole cutter, shank and holder clear
of the surface).
"""
from __future__ import annotations

import math

import numpy as np


def rotate(v, axis, angle):
    """``v (3,)`` turned by ``angle`` rad about the unit ``axis (3,)`` (right hand)."""
    k = np.asarray(axis, float)
    return v * math.cos(angle) + np.cross(k, v) * math.sin(angle) + k * (k @ v) * (1 - math.cos(angle))


def pca_frame(points, normals=None):
    """``X_I, X_II, X_III (3,)`` of ``points (n, 3)``: eigenvectors of their 1/n covariance by
    decreasing eigenvalue, X_III on the side of the mean of ``normals (n, 3)`` (else up), the
    frame right-handed."""
    w, v = np.linalg.eigh(np.cov(np.asarray(points, float).T, bias=True))
    x1, x2, x3 = v[:, 2], v[:, 1], v[:, 0]
    side = np.asarray(normals, float).sum(axis=0) if normals is not None else np.array([0.0, 0.0, 1.0])
    if x3 @ side < 0:
        x3 = -x3
    if np.cross(x1, x2) @ x3 < 0:
        x2 = -x2
    return x1, x2, x3


def heuristic_axis(points, normals, zeta=0.0, eta=0.0):
    """The PCA heuristic's tool axis ``(3,)`` for a zone of ``points (n, 3)`` with ``normals
    (n, 3)``, tilted by ``zeta`` rad about X_II (the seed's second rotation) and then by ``eta``
    about X_I (our addition, so that the two angles reach every axis near X_III), and the
    principal direction X_I ``(3,)``: sin(zeta) X_I - cos(zeta) sin(eta) X_II + cos(zeta) cos(eta) X_III."""
    x1, x2, x3 = pca_frame(points, normals)
    return math.sin(zeta) * x1 - math.cos(zeta) * math.sin(eta) * x2 + math.cos(zeta) * math.cos(eta) * x3, x1


def heuristic_tilts(axis, points, normals):
    """``(zeta, eta)`` rad with :func:`heuristic_axis` = ``axis (3,)`` for this zone."""
    x1, x2, x3 = pca_frame(points, normals)
    a = np.asarray(axis, float)
    return math.asin(max(-1.0, min(1.0, float(a @ x1)))), math.atan2(-float(a @ x2), float(a @ x3))


def accessible(normals, axis, margin=0.0) -> bool:
    """Eq. 4.1: every ``normals (n, 3)`` of the zone has n . axis >= ``margin``."""
    return bool(len(normals) == 0 or (normals @ np.asarray(axis, float)).min() >= margin)


def azimuth_in_frame(direction, rotation) -> float:
    """Azimuth (rad) in the machining frame of ``direction (3,)`` (part frame) for the frame
    ``rotation (3, 3)`` (part -> machining)."""
    d = rotation @ np.asarray(direction, float)
    return math.atan2(d[1], d[0])
