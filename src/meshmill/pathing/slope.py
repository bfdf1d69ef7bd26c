"""Steep and shallow: the slope of the surface a vertical tool touches along a 3-axis pass, the
pieces of a pass on ground in a range of slopes, and the level distance and stepover that keep a
scallop limit on that ground (steep-and-shallow finishing).

Slopes are in degrees from the horizontal, of the surface at the point the tool touches (its
contact normal, exact for a ball or bull-nose: the contact lies on the corner torus, whose ring
point above it gives the normal). Z levels ``dz`` apart lie ``dz / sin(slope)`` apart on the
surface, raster passes ``s`` apart at most ``s / cos(slope)`` (the slope across the passes): so
levels serve the steep ground and parallel passes the shallow, each at the distance the scallop
limit allows on the least favourable slope of its ground (:func:`level_distance`,
:func:`raster_stepover`), not the part's.
"""
from __future__ import annotations

import math

import numpy as np

from .rest import densify, loop_runs, material_runs
from .scallop import stepover


def scallop_radius(tool) -> float:
    """The radius that leaves the scallop between neighbouring passes: R for a ball, the corner
    for a bull-nose (its worst case, passes across the slope); None for a flat end mill."""
    return {"ball": tool.radius, "bull": tool.corner_radius}.get(tool.type)


def level_distance(scallop: float, tool, min_slope: float | None) -> float:
    """Distance between Z levels, mm, that keeps the scallop under ``scallop`` on ground at
    least ``min_slope`` deg steep (None: walls): sod(R) sin(min_slope)."""
    theta = 90.0 if min_slope is None else min_slope
    return float(stepover(scallop, scallop_radius(tool))) * math.sin(math.radians(max(theta, 1.0)))


def raster_stepover(scallop: float, tool, max_slope: float | None) -> float:
    """Distance between raster passes, mm, that keeps the scallop under ``scallop`` on ground at
    most ``max_slope`` deg steep (None: flat ground only, the stepover of seed 002): sod(R)
    cos(max_slope)."""
    theta = 0.0 if max_slope is None else min(max_slope, 89.0)
    return float(stepover(scallop, scallop_radius(tool))) * math.cos(math.radians(theta))


def contact_slopes(tips, contacts, tool, grow: float = 0.0) -> np.ndarray:
    """``(k,)`` deg: the slope of the surface where the vertical ``tool`` (grown by ``grow``, the
    allowance) with its tip at ``tips (k, 3)`` touches the mesh at ``contacts (k, 3)`` (NaN where
    it touches nothing: on the floor). A flat end mill touching with its rim above its tip: 90 (a
    wall or an edge); with its bottom: 0."""
    tips, contacts = np.asarray(tips, float), np.asarray(contacts, float)
    r, flat = tool.corner_radius + grow, tool.radius - tool.corner_radius
    d = contacts[:, :2] - tips[:, :2]
    rho = np.hypot(d[:, 0], d[:, 1])
    bottom = rho <= flat + 1e-9
    if r <= 0:  # a flat end mill: its bottom, or its rim above the tip (a wall, an edge)
        nz = np.where((rho < flat - 1e-9) | (contacts[:, 2] <= tips[:, 2] + 1e-9), 1.0, 0.0)
    else:
        unit = d / np.where(rho > 0, rho, 1.0)[:, None]
        ring = np.column_stack([tips[:, :2] + flat * unit, tips[:, 2] + tool.corner_radius])
        n = ring - contacts
        nz = n[:, 2] / np.maximum(np.linalg.norm(n, axis=1), 1e-12)
        nz = np.where(bottom, 1.0, nz)
    slope = np.degrees(np.arccos(np.clip(nz, -1.0, 1.0)))
    return np.where(np.isfinite(contacts[:, 2]), slope, np.nan)


RING = 16  # points of a bull-nose's corner ring tried for the nearest contact at a level


def level_slopes(tips, tool, kern, grow: float = 0.0):
    """``((k,) deg, (k, 3) contacts)``: the slope of the surface where the vertical ``tool`` (grown by ``grow``) with
    its tip at ``tips (k, 3)`` touches the mesh of ``kern`` (bound kernels), found from the
    mesh's distance rather than a drop (a waterline point on a vertical wall is where the drop
    height jumps): the gradient of the distance (central differences) at the corner's centre (a
    ball) or the point of its ring nearest the mesh (a bull-nose), which points from the contact
    along its normal, and the point it touches, that far down the gradient. A flat end mill
    touches at a level with its rim: 90, at its tip."""
    tips = np.asarray(tips, float)
    if tool.corner_radius + grow <= 0:
        return np.full(len(tips), 90.0), tips
    flat = tool.radius - tool.corner_radius
    lift = np.array([0.0, 0.0, tool.corner_radius])
    if flat > 0:
        a = 2.0 * np.pi * np.arange(RING) / RING
        ring = np.column_stack([flat * np.cos(a), flat * np.sin(a), np.zeros(RING)]) + lift
        cand = (tips[:, None] + ring[None]).reshape(-1, 3)
        d = kern.mesh_distances(cand).reshape(len(tips), RING)
        centre = cand.reshape(len(tips), RING, 3)[np.arange(len(tips)), np.argmin(d, axis=1)]
    else:
        centre = tips + lift
    h = min(0.05, 0.25 * (tool.corner_radius + grow))
    offsets = h * np.vstack([np.eye(3), -np.eye(3)])
    d = kern.mesh_distances((centre[:, None] + offsets[None]).reshape(-1, 3)).reshape(len(tips), 6)
    grad = d[:, :3] - d[:, 3:]
    grad /= np.maximum(np.linalg.norm(grad, axis=1), 1e-300)[:, None]
    contacts = centre - (tool.corner_radius + grow) * grad
    return np.degrees(np.arccos(np.clip(grad[:, 2], -1.0, 1.0))), contacts


def on_slopes(slopes, min_slope, max_slope) -> np.ndarray:
    """``(k,) bool``: the slopes within ``[min_slope, max_slope]`` (None: open); a tool that
    touches nothing (on the floor beside the part) is on no ground."""
    s = np.where(np.isfinite(slopes), slopes, -1.0)
    keep = np.isfinite(slopes)
    if min_slope is not None:
        keep &= s >= min_slope
    if max_slope is not None:
        keep &= s <= max_slope
    return keep


def slope_pieces(passes, drop, tool, min_slope, max_slope, overlap: float, sample: float, closed=False, near=None):
    """``(pieces, report)``: the pieces of ``passes`` (``(k, 3)`` tips; ``closed``: loops, first
    point repeated: a level's, :func:`level_slopes`) where the tool of ``drop``
    (:class:`~meshmill.pathing.dropcutter.ToolDrop`) touches ground within the slopes (None, None:
    any ground; else :func:`contact_slopes`), tested every ``sample`` mm, each
    piece widened by ``overlap`` mm along its pass on both sides (the seam with the other
    ground's passes) and pieces less than a tool diameter apart joined. ``near``: ``(tree,
    reach)``, also only where the tool touches within ``reach`` mm of a point of the
    ``scipy.spatial.cKDTree`` (the stock left on the part: rest finishing). A pass whole on that
    ground stays as it was."""
    runs = material_runs if not closed else loop_runs
    pieces, tested, kept = [], 0, 0
    for p in passes:
        dense = densify(p, sample)
        if closed:  # a level's loop: the tool touches sideways, at the level
            slopes, contact = level_slopes(dense, tool, drop.kern, drop.grow)
        else:
            z, contact = drop.with_contacts(dense[:, :2])
            slopes = contact_slopes(np.column_stack([dense[:, :2], z]), contact, tool, drop.grow)
        keep = on_slopes(slopes, min_slope, max_slope)
        if near is not None and keep.any():
            tree, reach = near
            at = np.nonzero(keep)[0]
            dist, _ = tree.query(contact[at], distance_upper_bound=reach)
            keep[at[~np.isfinite(dist)]] = False
        tested += len(dense)
        kept += int(keep.sum())
        if keep.all():
            pieces.append(p)
        elif keep.any():
            pieces += runs(dense, keep, overlap + sample, tool.diameter)
    return pieces, {"min_slope": min_slope, "max_slope": max_slope, "overlap": overlap, "points_tested": tested,
                    "points_kept": kept, "passes_before": len(passes), "pieces": len(pieces)}
