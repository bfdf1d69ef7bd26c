"""Black-box optimisation of a zoning and its plans with NOMAD's MADS (seed 002 Ch. 4, PyNomadBBO).

For a fixed number of clusters K the variables are the clustering weights omega (4, in [0, 1]) and,
per cluster, the feed offset delta (degrees, [-90, 90]) from the zone's base direction and the
cutter (integer); in 3+2-axis also a mode (integer: 0 vertical axis, 1 the PCA heuristic's axis)
and two tilts of that axis, zeta about X_II (the seed's) and eta about X_I (degrees, [-45, 45]
each), which together reach every axis within 45 degrees of X_III: the seed's (Phi_k, Psi_k)
measured from the zone's own best-fit normal instead of from +Z. Every connected zone of a cluster uses its
cluster's variables on its own base direction (the steepest slope for a vertical axis, X_I on a
heuristic axis), so the dimension stays fixed while omega changes the zones (the seed's
variable-dimension gap, notes §8.17). An inaccessible axis (eq. 4.1) fails the evaluation.

PyNomad takes one Python black box, so the seed's static surrogate (surrogate 3, the analytic
PCA-rectangle time) is used as a first phase: MADS on the surrogate, then MADS on the black box
(the plan's score: time raised for unmachined cells) from whichever of the start and the
surrogate's optimum the black box finds better. Options as the seed: ORTHO 2N directions; the
quadratic-model search only in 3-axis. Errors inside the black box are raised after MADS returns
(PyNomad would swallow them); an :class:`InputError` there fails that evaluation only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .machining import UP, ZonePlan
from ..pathing.zigzag import wrap_axial
from .orientation import accessible, azimuth_in_frame, heuristic_axis, heuristic_tilts
from ..pathing.zigzag import frame_rotation

SURROGATE_FACTOR = 4  # surrogate evaluations per black-box evaluation of the budget
TRANSIT_S = 2.0  # s: the surrogate's cost of a zone (retract, rapid, approach)


@dataclass
class Optimised:
    zones: np.ndarray
    clusters: np.ndarray
    plans: dict
    result: object
    summary: dict


class Problem:
    """The decoded variables of :mod:`meshmill.choice.optimise` for one chooser and K."""

    def __init__(self, chooser, k):
        self.chooser, self.k = chooser, k
        self.axes32 = chooser.params.axes == "3+2"
        self.per_cluster = 5 if self.axes32 else 2
        self._zoning = {}

    @property
    def dimension(self):
        return 4 + self.k * self.per_cluster

    def bounds(self):
        n_tools = len(self.chooser.tools)
        lo, hi, kinds = [0.0] * 4, [1.0] * 4, ["R"] * 4
        for _ in range(self.k):
            lo += [-90.0, 0]
            hi += [90.0, n_tools - 1]
            kinds += ["R", "I"]
            if self.axes32:
                lo += [0, -45.0, -45.0]
                hi += [1, 45.0, 45.0]
                kinds += ["I", "R", "R"]
        return lo, hi, kinds

    def zoning(self, weights):
        key = tuple(np.round(weights, 6))
        if key not in self._zoning:
            if len(self._zoning) > 256:
                self._zoning.clear()
            self._zoning[key] = self.chooser.zoning(self.k, np.asarray(key) if any(w != 1 for w in key) else None)
        return self._zoning[key]

    def decode(self, x):
        """``(zones, clusters, plans)`` for the variables ``x``, or None when an axis is not
        accessible or the weights are all zero."""
        x = list(x)
        if max(x[:4]) <= 0:
            return None
        zones, clusters = self.zoning(x[:4])
        s = self.chooser.samples
        plans = {}
        for z in np.unique(zones[zones >= 0]):
            inside = zones == z
            c = int(np.bincount(clusters[inside]).argmax())
            v = x[4 + c * self.per_cluster: 4 + (c + 1) * self.per_cluster] if c < self.k else [0.0, 0]
            delta, tool = math.radians(v[0]), int(round(v[1]))
            if self.axes32 and int(round(v[2])) == 1:
                axis, x1 = heuristic_axis(s.points[inside], s.normals[inside], math.radians(v[3]), math.radians(v[4]))
                if not accessible(s.normals[inside], axis):
                    return None
                base = azimuth_in_frame(x1, frame_rotation(axis))
                plans[int(z)] = ZonePlan(tool, base + delta, tuple(float(a) for a in axis))
            else:
                _, steepest = self.chooser.zone_frame(zones, z)
                plans[int(z)] = ZonePlan(tool, steepest + delta, UP)
        return zones, clusters, plans

    def encode(self, zones, clusters, plans):
        """Variables reproducing ``plans`` as far as the cluster-level encoding allows: each
        cluster takes the plan of its largest zone."""
        s = self.chooser.samples
        x = [1.0, 1.0, 1.0, 1.0]
        for c in range(self.k):
            members = [z for z in plans if np.bincount(clusters[zones == z]).argmax() == c]
            if not members:
                x += [0.0, 0] + ([0, 0.0, 0.0] if self.axes32 else [])
                continue
            z = max(members, key=lambda z: int((zones == z).sum()))
            plan, inside = plans[z], zones == z
            if np.allclose(plan.axis, UP):
                base, mode, zeta, eta = self.chooser.zone_frame(zones, z)[1], 0, 0.0, 0.0
            else:
                mode = 1
                zeta, eta = heuristic_tilts(plan.axis, s.points[inside], s.normals[inside])
                axis, x1 = heuristic_axis(s.points[inside], s.normals[inside], zeta, eta)
                base = azimuth_in_frame(x1, frame_rotation(axis))
                zeta, eta = math.degrees(zeta), math.degrees(eta)
            delta = math.degrees(wrap_axial(plan.theta - base))
            x += [delta, plan.tool] + ([mode, zeta, eta] if self.axes32 else [])
        return x

    def black_box(self, x):
        """The plan's :attr:`~meshmill.choice.machining.PlanResult.score`; None when it does not
        decode."""
        decoded = self.decode(x)
        if decoded is None:
            return None
        zones, _, plans = decoded
        return self.chooser.machinist.plan(zones, plans).score

    def surrogate(self, x):
        decoded = self.decode(x)
        if decoded is None:
            return None
        zones, _, plans = decoded
        ch = self.chooser
        tools = sorted({p.tool for p in plans.values()})
        axes = {tuple(np.round(p.axis, 9)) for p in plans.values()}
        return (sum(ch.predicted(zones, z, p) for z, p in plans.items()) + TRANSIT_S * len(plans)
                + (len(tools) - 1) * ch.machine.tool_change + (len(axes) - 1) * ch.machine.reorient)


def _mads(f, x0, lo, hi, kinds, evals, quad, seed, history):
    """Minimise ``f`` (None: failed) with PyNomad from ``x0``; returns ``(x, f)``."""
    try:
        import PyNomad
    except ImportError:
        raise InputError("optimise needs PyNomadBBO: pip install 'meshmill[optimise]'", "optimise") from None

    failure = []

    def bb(point):
        if failure:
            return 0
        try:
            value = f([point.get_coord(i) for i in range(point.size())])
        except InputError:  # this point cannot be machined (e.g. a zone too small or vertical)
            return 0
        except BaseException as exc:  # noqa: BLE001 - re-raised below, PyNomad would swallow it
            failure.append(exc)
            return 0
        if value is None or not math.isfinite(value):
            return 0
        history.append(value)
        point.setBBO(str(value).encode("UTF-8"))
        return 1

    params = ["BB_OUTPUT_TYPE OBJ", f"MAX_BB_EVAL {int(evals)}", "DIRECTION_TYPE ORTHO 2N", "DISPLAY_DEGREE 0",
              f"BB_INPUT_TYPE ( {' '.join(kinds)} )", f"SEED {int(seed)}",
              f"QUAD_MODEL_SEARCH {'yes' if quad else 'no'}", "NM_SEARCH no"]
    x0 = [min(max(v, a), b) for v, a, b in zip(x0, lo, hi)]
    if not x0:
        return x0, None
    out = PyNomad.optimize(bb, x0, lo, hi, params)
    if failure:
        raise failure[0]
    if out["x_best_feas"] is None or not len(out["x_best_feas"]):
        return x0, None
    return list(out["x_best_feas"][0] if isinstance(out["x_best_feas"][0], (list, tuple)) else out["x_best_feas"]), \
        float(out["f_single_best"])


def _free(f, x0, free):
    """``f`` of the full variables as a function of the ``free (m,)`` indices only, and back."""
    def g(y):
        x = list(x0)
        for i, v in zip(free, y):
            x[i] = v
        return f(x)

    return g


def optimise_plan(chooser, k, zones, clusters, plans, evals, seed=0, heuristic=False) -> Optimised:
    """MADS over :class:`Problem` from ``plans`` (the rule-based plan on ``zones``) with
    ``evals`` black-box evaluations. With ``heuristic`` (3+2 only; the seed's eq. 4.6): the
    weights stay 1 and every zone stays on its PCA-heuristic axis, only the offsets, cutters and
    tilts move. The result is never worse than ``plans``: that plan is kept when MADS finds no
    better one."""
    problem = Problem(chooser, k)
    lo, hi, kinds = problem.bounds()
    rule = chooser.machinist.plan(zones, plans)
    f_rule = rule.score
    x0 = problem.encode(zones, clusters, plans)
    free = list(range(len(x0)))
    if k == 1:
        free = free[4:]  # the weights of a single cluster change nothing
    if heuristic:
        if not problem.axes32:
            raise InputError("the PCA heuristic is a 3+2-axis method (axes 3+2)", "axes")
        x0[:4] = [1.0] * 4
        modes = [4 + c * problem.per_cluster + 2 for c in range(k)]
        for i in modes:
            if x0[i] != 1:  # a vertical cluster starts on its heuristic axis, untilted, along X_I
                x0[i], x0[i - 2], x0[i + 1] = 1, 0.0, 0.0
            x0[i + 2] = 0.0  # eq. 4.6 tilts about X_II only
        free = [i for i in free if i >= 4 and i not in modes and i - 2 not in modes]
    free = [i for i in free if lo[i] < hi[i]]
    sub = lambda v: [v[i] for i in free]  # noqa: E731
    quad = not problem.axes32
    surrogate_history, history = [], []
    ys, fs = _mads(_free(problem.surrogate, x0, free), sub(x0), sub(lo), sub(hi), sub(kinds),
                   SURROGATE_FACTOR * evals, quad, seed, surrogate_history)
    xs = list(x0)
    for i, v in zip(free, ys):
        xs[i] = v
    # start from the better of the encoded plan and the surrogate's optimum
    starts = [(problem.black_box(x), x) for x in ([x0, xs] if xs != x0 else [x0])]
    starts = [(f, x) for f, x in starts if f is not None]
    summary = {"k": k, "variables": len(free), "rule_s": rule.total_s, "surrogate_evaluations": len(surrogate_history),
               "surrogate_optimum_predicted_s": fs}
    if not starts:  # neither decodes (a zone's axis is not accessible): keep the rule-based plan
        summary.update({"black_box_evaluations": 2, "optimum_s": rule.total_s, "gain": 0.0, "best_so_far_s": [],
                        "started_from": "nothing: the rule-based plan does not encode"})
        return Optimised(zones, clusters, plans, rule, summary)
    f_start, start = min(starts, key=lambda t: t[0])
    y, f = _mads(_free(problem.black_box, start, free), sub(start), sub(lo), sub(hi), sub(kinds),
                 max(1, evals - len(starts)), quad, seed, history)
    x = list(start)
    if f is not None:
        for i, v in zip(free, y):
            x[i] = v
    best_f = min([f_start] + history)
    if best_f < f_rule:
        zones_o, clusters_o, plans_o = problem.decode(x) if f is not None and f <= f_start else problem.decode(start)
        result = chooser.machinist.plan(zones_o, plans_o)
    else:
        zones_o, clusters_o, plans_o, result = zones, clusters, plans, rule
    summary.update({
        "black_box_evaluations": len(history) + len(starts),
        "started_from": "surrogate optimum" if start is xs and xs != x0 else "rule-based plan (encoded)",
        "start_s": f_start, "optimum_s": result.total_s, "gain": (rule.total_s - result.total_s) / rule.total_s,
        "weights": [float(w) for w in x[:4]], "x": [float(v) for v in x],
        "best_so_far_s": np.minimum.accumulate([f_start] + history).tolist(),
    })
    return Optimised(zones_o, clusters_o, plans_o, result, summary)
