"""Tool choice, zoning and machining directions by machining time (seed 002), 3-axis or 3+2-axis.

1. The whole surface's PCA rectangle gives the seed's closed-form rule: a ball along the principal
   direction or a bull-nose along the steepest slope (s_c(mu) against the slope).
2. The surface is split into zones: clustering of (u, v, s, theta) over the sample grid
   (K-means, RPCL or Ward; Euclidean, Mahalanobis, std or PCA metric), then every 4-connected
   component its own zone; components under ``min_zone`` of the cells join the neighbour they
   share most border with (a zone costs a retract, a rapid and often a tool change).
3. Each zone is machined (the zigzag black box, :mod:`meshmill.choice.machining`) with every
   candidate: each cutter along the zone's principal and steepest directions, and in 3+2-axis also
   on the PCA heuristic's tool axes; the plan keeps the fastest candidate that machines each zone,
   or one cutter for all, or (3+2) all on the vertical axis, whichever is fastest as a whole.
4. ``optimise`` > 0 runs NOMAD (MADS) on the weights, per-cluster feed offsets, cutters and axes
   (:mod:`meshmill.choice.optimise`).
``zones=None`` (auto) does 2-4 for K = 1..k_max and keeps the best K. Plans compare by
:attr:`~meshmill.choice.machining.PlanResult.score`. Predicted times are the seed's surrogate 3
(analytic PCA-rectangle time, annex E) per zone.
"""
from __future__ import annotations

import math
import os
import time

import numpy as np

from ..errors import InputError
from ..kernels.backend import solid_kernels
from ..machine.timing import path_time
from ..params import ChooseParams
from ..tolerances import GOUGE_TOL
from ..tools.table import Tool
from ..choice import clustering
from ..choice.machining import UP, Machinist, ZonePlan
from ..choice.orientation import accessible, azimuth_in_frame, heuristic_axis
from ..choice.rectangle import choose_tool, pca_rectangle, zone_time_surrogate
from ..geometry.patches import cell_samples, load_patch, mesh_samples, mesh_surface, patch_mesh
from ..geometry.mesh import SUPPORTED, Mesh, load_mesh
from ..pathing.zigzag import frame_rotation
from ..pathing.verify import DEFAULT_STEP, verify_toolpath

HEURISTIC_TILTS = (0.0, 15.0, -15.0, 30.0, -30.0)  # degrees about X_II tried in 3+2
CHORD_SHARE = 0.25  # a patch's triangles stay within this share of the gouge tolerance of it


def tool_pair(spec: str) -> list[Tool]:
    """``"D,r"`` -> a ball of diameter D and a bull-nose of diameter D and corner radius r (mm),
    fluted 3 D, shank D, gauge 5 D, no holder."""
    try:
        d, r = (float(x) for x in spec.split(","))
    except ValueError:
        raise InputError(f"tool_pair wants 'DIAMETER,CORNER_RADIUS' in mm (e.g. 10,2), got '{spec}'", "tool_pair") \
            from None
    if not (math.isfinite(d) and math.isfinite(r) and d > 0 and 0 < r < d / 2):
        raise InputError(f"tool_pair {spec}: need a diameter > 0 and 0 < corner radius < diameter/2", "tool_pair")
    body = dict(diameter=d, flute_length=3 * d, gauge_length=5 * d, shank_diameter=d)
    return [Tool(name=f"BALL{d:g}", type="ball", corner_radius=d / 2, number=1, **body),
            Tool(name=f"BULL{d:g}R{r:g}", type="bull", corner_radius=r, number=2, **body)]


def candidate_tools(tools) -> list[Tool]:
    """The ball and bull-nose cutters of a table (a flat end leaves no defined scallop)."""
    out = [t for t in tools if t.type in ("ball", "bull")]
    if not out:
        raise InputError("the tool table has no ball or bull-nose cutter to choose from")
    return out


def merge_small(zones, grid_shape, min_cells):
    """Zones ``(n,)`` (-1: no surface) with every zone under ``min_cells`` cells given, smallest
    first, to the 4-neighbour zone it shares most edges with (a zone with no neighbour stays),
    renumbered 0..Z-1 by first cell."""
    nu, nv = grid_shape
    zones = zones.copy()
    isolated = set()
    while True:
        ids, counts = np.unique(zones[zones >= 0], return_counts=True)
        small = [(c, z) for z, c in zip(ids, counts) if c < min_cells and z not in isolated]
        if not small or len(ids) == 1:
            break
        z = int(min(small)[1])
        g = zones.reshape(nu, nv)
        pairs = np.concatenate([np.column_stack([g[:-1].ravel(), g[1:].ravel()]),
                                np.column_stack([g[:, :-1].ravel(), g[:, 1:].ravel()])])
        pairs = np.concatenate([pairs, pairs[:, ::-1]])
        border = pairs[(pairs[:, 0] == z) & (pairs[:, 1] != z) & (pairs[:, 1] >= 0), 1]
        if len(border) == 0:
            isolated.add(z)
            continue
        zones[zones == z] = np.bincount(border).argmax()
    out = np.full(len(zones), -1, np.intp)
    out[zones >= 0] = _first_seen(zones[zones >= 0])
    return out


def _first_seen(labels):
    """Labels ``(n,)`` renumbered 0..m-1 in the order their first element appears."""
    ids, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(ids), np.intp)
    rank[np.argsort(first)] = np.arange(len(ids))
    return rank[inverse]


def zone_ids(zones):
    """The zone ids ``(Z,)`` of ``zones (n,)`` (without -1, the cells off the surface)."""
    return np.unique(zones[zones >= 0])


def axial_mean(theta):
    """Axial mean (rad, in [-pi/2, pi/2)) of axial angles ``theta (n,)``."""
    return 0.5 * math.atan2(np.sin(2 * theta).mean(), np.cos(2 * theta).mean())


class Chooser:
    """Zoning, candidate plans and their evaluation for one surface; see the module docstring."""

    def __init__(self, samples, smesh, tools, machine, params: ChooseParams, device="cpu", say=None):
        smallest = min(tools, key=lambda t: t.corner_radius)
        if params.scallop >= smallest.corner_radius:
            raise InputError(f"scallop {params.scallop:g} mm is not smaller than {smallest.name}'s corner radius "
                             f"{smallest.corner_radius:g} mm: no stepover leaves it", "scallop")
        self.params, self.machine, self.tools = params, machine, tools
        self.say = say or (lambda stage: None)
        self.samples, self.smesh = samples, smesh
        self.machinist = Machinist(self.smesh, self.samples, tools, params.scallop, machine, params.sample, device)

    # -- zoning ----------------------------------------------------------------------------
    def zoning(self, k, weights=None):
        """``(zones (n,), clusters (n,))`` for K = ``k`` clusters (Ward: None keeps the partition
        before the largest merge jump)."""
        p, s = self.params, self.samples
        if k == 1:
            clusters = np.zeros(len(s.points), np.intp)
        elif p.cluster == "kmeans":
            clusters = clustering.kmeans(s.features, s.grid_shape, k, p.metric, weights, s.points)
        elif p.cluster == "rpcl":
            clusters = clustering.rpcl(s.features, s.grid_shape, k, p.metric, weights, s.points, seed=p.seed)
        else:
            clusters = clustering.ward(s.features, s.grid_shape, k, weights)
        clusters = np.where(s.valid, clusters, -1)
        zones = clustering.connected_zones(clusters, s.grid_shape)
        zones[~s.valid] = -1
        zones = merge_small(zones, s.grid_shape, max(1, int(p.min_zone * s.valid.sum())))
        return zones, clusters

    def zone_frame(self, zones, z):
        """``(principal azimuth, steepest azimuth)`` of zone ``z`` (rad): the PCA rectangle's
        principal direction (the steepest slope where it has none: too few cells, or vertical)
        and the axial mean of the cells' steepest-slope azimuths."""
        inside = zones == z
        steepest = axial_mean(self.samples.theta[inside])
        try:
            principal = pca_rectangle(self.samples.points[inside], self.samples.normals[inside]).principal_azimuth
        except InputError:
            principal = steepest
        return (principal if math.isfinite(principal) else steepest), steepest

    # -- candidates ------------------------------------------------------------------------
    def candidates(self, zones, z) -> list[ZonePlan]:
        """Every cutter along the zone's principal and steepest directions (3-axis), and in 3+2
        every cutter on the accessible PCA-heuristic axes along the zone's X_I."""
        principal, steepest = self.zone_frame(zones, z)
        out = []
        for t in range(len(self.tools)):
            out += [ZonePlan(t, principal), ZonePlan(t, steepest)]
        if self.params.axes == "3+2":
            inside = zones == z
            normals = self.samples.normals[inside]
            if inside.sum() < 3:
                return out
            for zeta in HEURISTIC_TILTS:
                axis, x1 = heuristic_axis(self.samples.points[inside], normals, math.radians(zeta))
                if not accessible(normals, axis):
                    continue
                theta = azimuth_in_frame(x1, frame_rotation(axis))
                out += [ZonePlan(t, theta, tuple(float(c) for c in axis)) for t in range(len(self.tools))]
        return out

    def best_plans(self, zones):
        """``(plans, tried)``: each zone's fastest candidate among those that machine it (see
        :attr:`~meshmill.choice.machining.ZoneResult.ok`; the best-covering one where none
        does), or with one cutter for all zones, or (3+2) all on the vertical axis, whichever
        plan is fastest as a whole (tool changes and re-orientations counted); and each zone's
        candidates with their results."""
        tried = {int(z): [(c, self.machinist.zone(zones, int(z), c)) for c in self.candidates(zones, z)]
                 for z in zone_ids(zones)}

        def pick(options):
            good = [x for x in options if x[1].ok]
            if good:
                return min(good, key=lambda x: x[1].time["total_s"])[0]
            return max(options, key=lambda x: (x[1].coverage, -x[1].time["total_s"]))[0]

        filters = [lambda c: True] + [lambda c, t=t: c.tool == t for t in range(len(self.tools))]
        if self.params.axes == "3+2":
            filters += [lambda c, f=f: f(c) and c.axis == UP for f in list(filters)]
        options = []
        for keep in filters:
            chosen = {z: [x for x in c if keep(x[0])] for z, c in tried.items()}
            if all(chosen.values()):
                options.append({z: pick(c) for z, c in chosen.items()})
        best = min(options, key=lambda plans: self.machinist.plan(zones, plans).score)
        return best, tried

    def predicted(self, zones, z, plan) -> float:
        """Surrogate 3 (annex E) for zone ``z`` with ``plan``, in the plan's machining frame."""
        inside = zones == z
        rot = frame_rotation(plan.axis)
        try:
            rect = pca_rectangle(self.samples.points[inside] @ rot.T, self.samples.normals[inside] @ rot.T)
        except InputError:  # too few cells for a rectangle
            return math.inf
        tool = self.tools[plan.tool]
        try:
            return float(zone_time_surrogate(rect, plan.theta, tool.radius, tool.corner_radius, self.params.scallop,
                                             self.machine.motion))
        except InputError:  # a vertical plane: no feed direction in XY lies in it
            return math.inf

    # -- the whole run ---------------------------------------------------------------------
    def run(self):
        """``(PlanResult, zones (n,), clusters (n,), summary dict)``: for each K (``zones``, or
        1..``k_max``) the rule-based plan, optimised when ``optimise`` > 0 (as the seed: K fixed,
        MADS per K); the best by :attr:`~meshmill.choice.machining.PlanResult.score`."""
        from ..choice.optimise import optimise_plan

        p = self.params
        runs = []
        for k in ([p.zones] if p.zones not in (None, "auto") else range(1, p.k_max + 1)):
            self.say(f"zoning K={k}")
            zones, clusters = self.zoning(k)
            plans, tried = self.best_plans(zones)
            result, optimisation = self.machinist.plan(zones, plans), None
            if p.optimise > 0:
                self.say(f"optimising K={k} ({p.optimise} evaluations)")
                opt = optimise_plan(self, k, zones, clusters, plans, p.optimise, seed=p.seed)
                optimisation = opt.summary
                if opt.result.score < result.score:
                    zones, clusters, plans, result, tried = opt.zones, opt.clusters, opt.plans, opt.result, {}
            runs.append({"k": k, "zones": zones, "clusters": clusters, "tried": tried, "result": result,
                         "optimisation": optimisation})
        best = min(runs, key=lambda r: r["result"].score)
        by_k = {int(r["k"]): round(r["result"].total_s, 3) for r in runs}
        optimisation = best["optimisation"]
        if optimisation is not None and len(runs) > 1:
            optimisation = {**optimisation, "by_k": {int(r["k"]): r["optimisation"] for r in runs}}
        return best["result"], best["zones"], best["clusters"], self.summary(
            best["result"], best["zones"], best["clusters"], best["tried"], by_k, optimisation)

    def rule(self):
        """The seed's closed-form choice on the whole surface, for each bull-nose cutter against
        a ball of its diameter (the table's, if it has one); None when the surface has no PCA
        rectangle (vertical)."""
        valid = self.samples.valid
        try:
            rect = pca_rectangle(self.samples.points[valid], self.samples.normals[valid])
        except InputError:
            return None
        balls = [t for t in self.tools if t.type == "ball"]
        out = []
        for bull in (t for t in self.tools if t.type == "bull"):
            ball = next((b for b in balls if b.diameter == bull.diameter), None)
            choice = choose_tool(rect, bull.radius, bull.corner_radius, self.params.scallop, self.machine.motion)
            out.append({
                "ball": ball.name if ball else None, "bull": bull.name,
                "choice": (ball.name if ball else f"a ball of diameter {bull.diameter:g} (not in the table)")
                if choice.tool == "ball" else bull.name,
                "direction": "principal" if choice.tool == "ball" else "steepest slope",
                "azimuth_deg": math.degrees(choice.azimuth),
                "slope_deg": math.degrees(choice.slope), "critical_slope_deg": math.degrees(choice.critical_slope),
                "shape_factor": choice.shape_factor, "critical_shape_factor": choice.critical_shape_factor,
                "predicted_ball_principal_s": choice.time_ball_principal,
                "predicted_bull_steepest_s": choice.time_toric_steepest,
                "warnings": list(choice.warnings)})
        return {"shape_factor": rect.shape_factor, "characteristic_size_mm2": rect.size,
                "eigenvalues_mm2": rect.variances.tolist(), "plane_slope_deg": math.degrees(rect.plane_slope),
                "principal_azimuth_deg": math.degrees(rect.principal_azimuth),
                "steepest_azimuth_deg": math.degrees(rect.steepest_azimuth), "pairs": out}

    def zone_row(self, r, zones, clusters):
        """Summary of one :class:`~meshmill.choice.machining.ZoneResult`."""
        s = self.samples
        inside = zones == r.zone
        return {
            "zone": r.zone, "cells": int(inside.sum()), "area_mm2": float(s.area[inside].sum()),
            "cluster": int(np.bincount(clusters[inside]).argmax()),
            "tool": self.tools[r.plan.tool].name, "azimuth_deg": math.degrees(r.plan.theta),
            "axis": list(r.plan.axis), "tilt_deg": _tilt_deg(r.plan.axis),
            "mean_slope_deg": math.degrees(float(s.slope[inside].mean())),
            "predicted_s": self.predicted(zones, r.zone, r.plan), "measured_s": r.time["total_s"],
            "cutting_mm": r.time["cutting_mm"], "planes": r.planes, "coverage": r.coverage,
            "machined": r.ok, "moves_left_out": r.moves_left_out,
        }

    def summary(self, result, zones, clusters, tried, by_k, optimisation):
        rows = []
        for r in result.zones:
            row = self.zone_row(r, zones, clusters)
            if r.zone in tried:
                row["tried"] = [{"tool": self.tools[c.tool].name, "azimuth_deg": math.degrees(c.theta),
                                 "tilt_deg": _tilt_deg(c.axis), "measured_s": x.time["total_s"],
                                 "coverage": x.coverage, "planes": x.planes} for c, x in tried[r.zone]]
            rows.append(row)
        return {
            "operation": "choose", "axes": self.params.axes, "scallop": self.params.scallop,
            "grid": list(self.samples.grid_shape), "cluster": self.params.cluster, "metric": self.params.metric,
            "tools": [t.name for t in self.tools], "machine": self.machine.summary(),
            "rule": self.rule(), "k": int(np.unique(clusters[clusters >= 0]).size), "zones": rows,
            "total_s": result.total_s, "tool_changes": result.tool_changes, "reorientations": result.reorientations,
            "covered": result.covered, "incomplete_zones": [r.zone for r in result.incomplete],
            "predicted_zones_s": float(sum(z["predicted_s"] for z in rows)),
            "total_by_k": by_k, "optimisation": optimisation, "zone_runs": self.machinist.runs,
        }


def _tilt_deg(axis) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, axis[2]))))


def load_surface(path, params: ChooseParams, flip=False):
    """``(samples, surface mesh, description)`` of an STL/OBJ/PLY mesh (its top, seen from +Z; its
    faces turned over with ``flip``), a :class:`~meshmill.geometry.mesh.Mesh` already loaded, or a
    patch (TOML file or a built-in name)."""
    if isinstance(path, Mesh):
        return mesh_samples(path, params.grid, params.grid), mesh_surface(path), {"file": path.source,
                                                                                  **path.summary()}
    if os.path.splitext(path)[1].lower() in SUPPORTED:
        mesh = load_mesh(path, flip=flip)
        return mesh_samples(mesh, params.grid, params.grid), mesh_surface(mesh), {"file": os.path.abspath(path),
                                                                                 **mesh.summary()}
    patch = load_patch(path)
    smesh = patch_mesh(patch, params.mesh_step, CHORD_SHARE * GOUGE_TOL)
    return (cell_samples(patch, params.grid, params.grid), smesh,
            {"patch": patch.name, "degrees": [patch.degree_u, patch.degree_v],
             "control_points": list(patch.points.shape[:2]), "file": os.path.abspath(path) if os.path.exists(path) else "",
             "mesh_step": smesh.step, "chord_error": smesh.chord_error, "triangles": int(len(smesh.mesh.faces))})


def choose(surface, tools, machine, params: ChooseParams, progress=None, device="cpu"):
    """Run the whole choice (module docstring) on ``surface`` (a path, or what
    :func:`load_surface` returned); returns ``(toolpath, summary, zones (n,), chooser)``, the
    tool path verified against the surface."""
    say = progress or (lambda stage: None)
    t_all = time.perf_counter()
    samples, smesh, described = load_surface(surface, params) if isinstance(surface, str) else surface
    chooser = Chooser(samples, smesh, candidate_tools(tools), machine, params, device, say)
    result, zones, clusters, summary = chooser.run()
    say("refine")
    plans = {r.zone: r.plan for r in result.zones}
    result = chooser.machinist.plan(zones, plans, GOUGE_TOL)
    summary.update({"total_s": result.total_s, "tool_changes": result.tool_changes,
                    "reorientations": result.reorientations, "covered": result.covered,
                    "incomplete_zones": [r.zone for r in result.incomplete]})
    final = {r.zone: r for r in result.zones}
    for row in summary["zones"]:
        r = final[row["zone"]]
        row.update({"measured_s": r.time["total_s"], "cutting_mm": r.time["cutting_mm"], "coverage": r.coverage,
                    "machined": r.ok, "moves_left_out": r.moves_left_out})
    say("verify")
    t = time.perf_counter()
    kern = solid_kernels(chooser.smesh.mesh, device, float(chooser.smesh.mesh.vertices[:, 2].min()) - 1.0)
    report = verify_toolpath(kern, result.toolpath, chooser.tools, GOUGE_TOL, DEFAULT_STEP)
    report.pop("problem_moves")
    whole = path_time(result.toolpath.tip, result.toolpath.rapid, machine)
    summary.update({
        "verify": report, "moves": int(len(result.toolpath)), "cutting_length": result.toolpath.cutting_length(),
        "path_time": whole, "device": device, "surface": described,
        "seconds": {"verify": round(time.perf_counter() - t, 4), "total": round(time.perf_counter() - t_all, 4)},
    })
    return result.toolpath, summary, zones, chooser
