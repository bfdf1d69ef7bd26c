"""How much of the design surface a finish cut, and why the rest was not (its summary's ``area_mm2``).

Points spread over the design (:func:`~meshmill.geometry.analysis.sample_surface`) take a status
of :data:`AREA_STATUS`: from the facet they lie on (facing down, shallow) or from the nearest CC
point or raster contact; their weights are mm².
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from ..geometry.analysis import sample_surface
from .finish_shallow import SCALLOP_MIN_SLOPE, shallow_facets

AREA_SAMPLES = 2_000_000  # most points sampled on the design to say what each status of the CC points stands for

AREA_STATUS = ("cut", "no_ball", "no_axis", "short_runs", "left_out", "facing_down", "shallow")


def surface_status(mesh, kern, radii, tol, max_tilt, p, face, points, status, raster_from=None, raster_reach=0.0):
    """``(s,)`` index into ``AREA_STATUS`` of each point ``p (s, 3)`` of the design (on facets
    ``face (s,)``): ``facing_down`` on facets no ball within ``max_tilt`` touches (:func:`facing_down`);
    ``no_ball`` where no ball of ``radii`` touches the facet there without entering the part by more
    than ``tol`` (exact, through ``kern``); on facets facing up flatter than ``SCALLOP_MIN_SLOPE``,
    the status of the nearest raster contact (``points[raster_from:]``) within ``raster_reach`` mm,
    else ``shallow`` (no raster, or none of its passes reached there); elsewhere the status of the
    nearest of ``points (k, 3)`` (CC points, then raster contacts; ``status (k,)``)."""
    out = np.full(len(p), AREA_STATUS.index("facing_down"), np.int64)
    flat = shallow_facets(mesh, SCALLOP_MIN_SLOPE)[face]
    out[flat] = AREA_STATUS.index("shallow")
    up = np.nonzero(~facing_down(mesh, max_tilt)[face] & ~flat)[0]
    if len(up) and len(points):
        out[up] = status[cKDTree(points).query(p[up])[1]]
    flat = np.nonzero(flat)[0]
    if raster_from is not None and len(flat) and len(points) > raster_from:
        dist, near = cKDTree(points[raster_from:]).query(p[flat], distance_upper_bound=raster_reach)
        hit = np.isfinite(dist)
        out[flat[hit]] = status[raster_from:][near[hit]]
    checked = np.nonzero(out != AREA_STATUS.index("facing_down"))[0]
    if len(checked):
        fits = kern.largest_ball(p[checked], mesh.face_normals[face[checked]], radii, tol) >= 0
        out[checked[~fits]] = AREA_STATUS.index("no_ball")
    return out


def surface_areas(mesh, kern, radii, tol, max_tilt, spacing, points, status, raster_from=None, raster_reach=0.0):
    """mm² of the design surface by why it was or was not cut (:func:`surface_status` of points
    spread over it about ``spacing`` apart, :func:`~meshmill.geometry.analysis.sample_surface`)."""
    p, weight, face = sample_surface(mesh, spacing, AREA_SAMPLES)
    by = np.bincount(surface_status(mesh, kern, radii, tol, max_tilt, p, face, points, status, raster_from,
                                    raster_reach), weights=weight, minlength=len(AREA_STATUS))
    return {**{name: float(by[k]) for k, name in enumerate(AREA_STATUS)}, "total": float(weight.sum()),
            "why": "points spread over the design: facing_down where no ball within --max-tilt touches it, no_ball "
                   "where no ball of the table touches it there, shallow where it faces up flatter than 10 deg and no "
                   "raster pass (--scallop) reached it, else the status of the nearest CC point (or raster contact)"}


def facing_down(mesh, max_tilt):
    """``(m,) bool``: facets facing down more steeply than a ball whose axis is tilted at most
    ``max_tilt`` deg from +Z can touch (its cutting half faces down the axis; the flutes square to it)."""
    return mesh.face_normals[:, 2] < -math.sin(math.radians(max_tilt)) - 1e-9
