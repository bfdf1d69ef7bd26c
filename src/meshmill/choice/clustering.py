"""Partition a free-form surface into machining zones by clustering its sample points (seed 002, Ch. 3).

Every function works on a grid of nu x nv cells with one sample at each cell centre, flattened
row-major (cell i = iu * nv + iv):

- ``features (n, 4)`` = (u, v, s, theta): u, v in [0, 1]; s the slope (angle between the normal and
  +Z) in rad; theta the azimuth of the normal's XY projection in rad, an *axial* angle (theta and
  theta + pi are the same direction), normally given in [-pi/2, pi/2);
- ``points (n, 3)`` the 3D sample points, mm (PCA metric and zone statistics).

Our corrections of the seed (notes §8 items 8-11):

- theta is axial everywhere. The seed subtracts raw angles and averages them arithmetically, so cells
  at +pi/2 - 0.01 and -pi/2 + 0.01 (0.02 rad apart) look pi - 0.02 apart. Here theta enters every
  distance through the embedding (cos 2theta, sin 2theta) / 2, whose squared Euclidean distance is
  sin²(dtheta): about dtheta² for small differences, zero across the wrap. A zone's mean theta is the
  axial mean atan2(mean sin 2theta, mean cos 2theta) / 2.
- RPCL's rival is the second-nearest centre (the seed prints the winner's argmin twice).
- Mahalanobis and std metrics use whole-surface statistics, as the formulas say (not per zone); theta's
  spread there is one axial number applied to both embedding columns (see ``_metric_transform``).
- Ward is scipy's exact Ward linkage (the seed initialises with ||x_i - x_j|| instead of ½||x_i - x_j||²).
- The PCA metric's angles are taken in the XY plane and compared through sin² (pi-periodic); beta_ik is
  measured from the zone's 3D centroid, through which its principal axis passes.
"""
from __future__ import annotations

import hashlib
import numbers
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.cluster.hierarchy import cut_tree, linkage
from sklearn.cluster import KMeans

from ..errors import InputError
from ..pathing.zigzag import wrap_axial

METRICS = ("euclidean", "mahalanobis", "std", "std2", "pca")
SHAPE_FACTORS = ("ratio2", "one_minus_ratio2")


# ---------------------------------------------------------------- input checks


def _checked_features(features, grid_shape):
    """Features as a float (n, 4) array and the grid (nu, nv); InputError on a bad shape or value."""
    features = np.asarray(features, dtype=float)
    if features.ndim != 2 or features.shape[1] != 4:
        raise InputError(f"features must be an (n, 4) array of (u, v, s, theta), got shape {features.shape}")
    if not np.all(np.isfinite(features)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(features), axis=1))[0])
        raise InputError(f"features must be finite numbers; cell {bad} holds {features[bad].tolist()}")
    try:
        nu, nv = (int(m) for m in grid_shape)
    except (TypeError, ValueError):
        raise InputError(f"grid_shape must be two integers (nu, nv), got {grid_shape!r}") from None
    if nu < 1 or nv < 1 or nu * nv != len(features):
        raise InputError(f"grid {nu} x {nv} does not match {len(features)} feature rows")
    return features, (nu, nv)


def _checked_k(k, n):
    if isinstance(k, bool) or not isinstance(k, numbers.Integral):
        raise InputError(f"the number of clusters k must be an integer, got {k!r}")
    if not 1 <= k <= n:
        raise InputError(f"the number of clusters k must be between 1 and the {n} cells, got {k}")
    return int(k)


def _checked_weights(weights):
    """The seed's Ch. 4 weights omega (4,) on the squared (u, v, s, theta) terms; ones when None."""
    if weights is None:
        return np.ones(4)
    weights = np.asarray(weights, dtype=float)
    if weights.shape != (4,) or not np.all(np.isfinite(weights)) or np.any((weights < 0) | (weights > 1)):
        raise InputError(f"weights must be 4 numbers in [0, 1] for (u, v, s, theta), got {weights.tolist()}")
    return weights


def _checked_points(points, n):
    if points is None:
        raise InputError("the PCA metric needs the 3D sample points (points, shape (n, 3) in mm)")
    points = np.asarray(points, dtype=float)
    if points.shape != (n, 3) or not np.all(np.isfinite(points)):
        raise InputError(f"points must be a finite ({n}, 3) array in mm, got shape {points.shape}")
    return points


def _checked_choice(value, allowed, what):
    if value not in allowed:
        raise InputError(f"unknown {what} {value!r}; choose one of {', '.join(allowed)}")
    return value


# ---------------------------------------------------------------- axial angles and feature spaces



def embed_features(features):
    """(n, 4) (u, v, s, theta) -> (n, 5) (u, v, s, cos 2theta / 2, sin 2theta / 2): Euclidean distances
    in the last two columns are |sin dtheta|, about |dtheta| when small and 0 across the wrap."""
    features = np.asarray(features, dtype=float)
    two_theta = 2.0 * features[:, 3]
    return np.column_stack([features[:, :3], 0.5 * np.cos(two_theta), 0.5 * np.sin(two_theta)])


def _axial_angle_of_embedding(cos_sin_half):
    """(..., 2) mean of (cos 2theta, sin 2theta) / 2 -> axial mean angle (...) in [-pi/2, pi/2)."""
    return wrap_axial(0.5 * np.arctan2(cos_sin_half[..., 1], cos_sin_half[..., 0]))


def _embedded_weights(weights):
    """omega (4,) -> (5,): the theta weight applies to both embedded theta columns."""
    return np.append(weights, weights[3])


def _inverse_or_zero(spread):
    """1 / spread, 0 where the spread is zero (a constant feature differs by nothing anyway)."""
    spread = np.asarray(spread, dtype=float)
    return np.divide(1.0, spread, out=np.zeros_like(spread), where=spread > 1e-12)


def _metric_transform(embedded, metric, weights):
    """Matrix A (5, 5) with d²(x, c) = ||(e_x - e_c) A||² for the fixed quadratic-form metrics (and the
    Euclidean part of "pca"), weights omega included: A = D B with D = diag(sqrt omega).

    theta's whole-surface spread is one number, the RMS embedded deviation sqrt(Var c + Var d) (about
    the standard deviation of theta in rad), applied to both embedded columns so the wrap stays free.
    Mahalanobis uses the full covariance of (u, v, s) (pseudo-inverse: a constant feature carries no
    difference) and that spread for theta, without theta's cross-covariances: whitening the embedding
    column by column would blow up its near-constant column (cos 2theta varies only to second order
    about a dominant direction) and count cells across the wrap as far apart."""
    root_w = np.sqrt(_embedded_weights(weights))
    if metric in ("euclidean", "pca"):
        return np.diag(root_w)
    spread = embedded.std(axis=0)
    spread[3:] = np.hypot(spread[3], spread[4])
    if metric in ("std", "std2"):
        power = 0.5 if metric == "std" else 1.0
        return np.diag(root_w * _inverse_or_zero(spread) ** power)
    whitening = np.zeros((5, 5))
    variances, axes = np.linalg.eigh(np.cov(embedded[:, :3], rowvar=False, bias=True))
    keep = variances > 1e-12 * max(variances.max(), 1e-300)
    whitening[:3, : keep.sum()] = axes[:, keep] / np.sqrt(variances[keep])
    whitening[3:, 3:] = np.diag(_inverse_or_zero(spread[3:]))
    return root_w[:, None] * whitening


def initial_centres(features, grid_shape, k):
    """Eq. 3.4: k centres (k, 4) (u, v, s, theta) evenly on the circle of radius 1/4 around (1/2, 1/2):
    u_k = 1/2 + cos(2 k pi / K) / 4, v_k = 1/2 + sin(2 k pi / K) / 4 for k = 1..K, with s and theta
    of the grid cell containing (u_k, v_k) (a point on a cell border belongs to the higher cell)."""
    features, (nu, nv) = _checked_features(features, grid_shape)
    k = _checked_k(k, len(features))
    angle = 2.0 * np.pi * np.arange(1, k + 1) / k
    u = 0.5 + 0.25 * np.cos(angle)
    v = 0.5 + 0.25 * np.sin(angle)
    iu = np.clip(np.floor(np.round(u * nu, 9)).astype(int), 0, nu - 1)
    iv = np.clip(np.floor(np.round(v * nv, 9)).astype(int), 0, nv - 1)
    cell = features[iu * nv + iv]
    return np.column_stack([u, v, cell[:, 2], cell[:, 3]])


# ---------------------------------------------------------------- incremental covariance


class IncrementalCovariance:
    """Running count, mean (p,) and 1/n covariance (p, p) of a point set in any dimension p, updated
    when points are added or removed (eqs. 3.5 and 3.6 in the Welford / Chan form, which keeps the
    scatter about the mean instead of subtracting E E^T from E[x x^T])."""

    def __init__(self, dim):
        self.count = 0
        self.mean = np.zeros(dim)
        self._scatter = np.zeros((dim, dim))  # sum over members of (x - mean)(x - mean)^T

    @property
    def covariance(self):
        """(p, p) population covariance (1/n); zeros for an empty set."""
        return self._scatter / self.count if self.count else np.zeros_like(self._scatter)

    @staticmethod
    def _moments(points, dim):
        points = np.asarray(points, dtype=float).reshape(-1, dim)
        if len(points) == 0:
            return 0, None, None
        mean = points.mean(axis=0)
        centred = points - mean
        return len(points), mean, centred.T @ centred

    def add(self, points):
        """Add one point (p,) or several (m, p)."""
        m, batch_mean, batch_scatter = self._moments(points, len(self.mean))
        if m == 0:
            return
        total = self.count + m
        delta = batch_mean - self.mean
        self._scatter = self._scatter + batch_scatter + np.outer(delta, delta) * (self.count * m / total)
        self.mean = self.mean + delta * (m / total)
        self.count = total

    def remove(self, points):
        """Remove one point (p,) or several (m, p) that are members of the set."""
        m, batch_mean, batch_scatter = self._moments(points, len(self.mean))
        if m == 0:
            return
        rest = self.count - m
        if rest < 0:
            raise ValueError(f"cannot remove {m} points from a set of {self.count}")
        if rest == 0:
            self.__init__(len(self.mean))
            return
        rest_mean = (self.count * self.mean - m * batch_mean) / rest
        delta = batch_mean - rest_mean
        scatter = self._scatter - batch_scatter - np.outer(delta, delta) * (rest * m / self.count)
        self._scatter = 0.5 * (scatter + scatter.T)
        self.mean = rest_mean
        self.count = rest

    @staticmethod
    def with_point_added(count, mean, covariance, point):
        """Mean (..., p) and covariance (..., p, p) of sets (count (...), mean, covariance) after adding
        ``point`` (..., p), all broadcast (eq. 3.5, Welford form):
        Sigma' = n/(n+1) Sigma + n/(n+1)² (x - E)(x - E)^T."""
        count = np.asarray(count, dtype=float)[..., None]
        delta = np.asarray(point, dtype=float) - mean
        new_mean = mean + delta / (count + 1.0)
        share = count / (count + 1.0)
        spread = delta[..., :, None] * delta[..., None, :] / (count[..., None] + 1.0)
        new_cov = share[..., None] * (covariance + spread)
        return new_mean, new_cov


# ---------------------------------------------------------------- zone moments and the PCA metric


def _zone_point_moments(labels, k, points):
    """Count (k,), mean (k, 3) and 1/n covariance (k, 3, 3) of each zone's points (zeros when empty)."""
    count = np.bincount(labels, minlength=k).astype(float)
    safe = np.maximum(count, 1.0)
    mean = np.stack([np.bincount(labels, points[:, a], minlength=k) for a in range(3)], axis=1) / safe[:, None]
    centred = points - mean[labels]
    cov = np.empty((k, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            cov[:, a, b] = cov[:, b, a] = np.bincount(labels, centred[:, a] * centred[:, b], minlength=k) / safe
    return count, mean, cov


def _sin2_between(a, b):
    """sin² of the angle between 2D vectors a (..., 2) and b (..., 2); 0 where either is zero."""
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    norms = np.sum(a * a, axis=-1) * np.sum(b * b, axis=-1)
    return np.divide(cross * cross, norms, out=np.zeros(np.broadcast(cross, norms).shape), where=norms > 0)


def _shape_factor(eigenvalues, f):
    """f(lambda_II / lambda_I) (eq. 3.3) per zone from ascending eigenvalues (k, 3); ratio 1 (isotropic)
    when lambda_I is zero (a zone of one point)."""
    largest, second = eigenvalues[:, 2], eigenvalues[:, 1]
    ratio = np.divide(second, largest, out=np.ones_like(largest), where=largest > 0)
    return ratio**2 if f == "ratio2" else 1.0 - ratio**2


def _pca_penalty_columns(labels, k, zones, points, theta_embedded, f):
    """(n, len(zones)) shape term of eq. 3.2 for every cell i and each zone in ``zones``:
    f(lambda_II/lambda_I) [sin²(theta_I - beta_ik) + sin²(mean theta_k - theta'_I)], where theta_I is the XY
    azimuth of the zone's principal direction, beta_ik that of cell i seen from the zone's 3D centroid
    (the point the principal axis passes through), and theta'_I the principal azimuth with cell i added
    (rank-one covariance update, then one batched eigh). For the cell's own zone theta'_I = theta_I.
    Empty zones get no penalty."""
    count, mean, cov = _zone_point_moments(labels, k, points)
    count, mean, cov = count[zones], mean[zones], cov[zones]
    eigenvalues, eigenvectors = np.linalg.eigh(cov)
    shape = _shape_factor(eigenvalues, f)
    axis_xy = eigenvectors[:, :2, 2]
    off_axis = _sin2_between(axis_xy[None], points[:, None, :2] - mean[None, :, :2])

    slope_sum = np.stack([np.bincount(labels, theta_embedded[:, a], minlength=k)[zones] for a in range(2)], axis=1)
    mean_theta = _axial_angle_of_embedding(slope_sum)
    slope_xy = np.column_stack([np.cos(mean_theta), np.sin(mean_theta)])
    _, cov_added = IncrementalCovariance.with_point_added(count[None], mean[None], cov[None], points[:, None, :])
    column = np.full(k, -1)
    column[zones] = np.arange(len(zones))
    own = np.flatnonzero(column[labels] >= 0)
    cov_added[own, column[labels[own]]] = cov[column[labels[own]]]
    axis_added_xy = np.linalg.eigh(cov_added)[1][..., :2, 2]
    misaligned = _sin2_between(slope_xy[None], axis_added_xy)

    penalty = shape[None] * (off_axis + misaligned)
    penalty[:, count == 0] = 0.0
    return penalty


def _update_pca_penalty(penalty, before, labels, points, theta_embedded, f):
    """Recompute, in place, the columns of ``penalty`` (n, k) of the zones whose members changed
    between the partitions ``before`` and ``labels`` (all zones when ``before`` is None); the other
    zones' columns depend only on their unchanged members (the seed's "leave unchanged zones alone")."""
    k = penalty.shape[1]
    if before is None:
        zones = np.arange(k)
    else:
        moved = before != labels
        zones = np.unique(np.concatenate([before[moved], labels[moved]]))
    if len(zones):
        penalty[:, zones] = _pca_penalty_columns(labels, k, zones, points, theta_embedded, f)


def _squared_distances(transformed, centres):
    """(n, k) squared Euclidean distances between rows of (n, r) and (k, r)."""
    diff = transformed[:, None, :] - centres[None, :, :]
    return np.einsum("nkr,nkr->nk", diff, diff)


def _zone_means(labels, k, values):
    count = np.bincount(labels, minlength=k).astype(float)
    sums = np.stack([np.bincount(labels, values[:, a], minlength=k) for a in range(values.shape[1])], axis=1)
    return sums / np.maximum(count, 1.0)[:, None]


def _reseed_empty(labels, distances, k):
    """Give each empty zone the cell farthest from its own zone (taken from a zone of 2+ cells)."""
    labels = labels.copy()
    count = np.bincount(labels, minlength=k)
    for zone in np.flatnonzero(count == 0):
        own = distances[np.arange(len(labels)), labels].copy()
        own[count[labels] < 2] = -np.inf
        cell = int(np.argmax(own))
        if own[cell] == -np.inf:
            break
        count[labels[cell]] -= 1
        labels[cell] = zone
        count[zone] = 1
    return labels


def _kmeans_pca(transformed, start, theta_embedded, points, f, max_iter):
    """Lloyd iterations with the PCA metric: d² = ||y_i - c_k||² + shape term. The first assignment
    has no zones yet, so it is Euclidean. Stops on a fixed partition, when a partition comes back
    (the labels -> labels map is deterministic, so it would cycle; convergence is not guaranteed),
    or after max_iter assignments."""
    k = len(start)
    distances = _squared_distances(transformed, start)
    labels = _reseed_empty(np.argmin(distances, axis=1), distances, k)
    seen = {hashlib.blake2b(labels.tobytes(), digest_size=16).digest()}
    penalty = np.zeros((len(labels), k))
    before = None
    for _ in range(max_iter):
        _update_pca_penalty(penalty, before, labels, points, theta_embedded, f)
        distances = _squared_distances(transformed, _zone_means(labels, k, transformed)) + penalty
        new = _reseed_empty(np.argmin(distances, axis=1), distances, k)
        key = hashlib.blake2b(new.tobytes(), digest_size=16).digest()
        if key in seen:
            break
        seen.add(key)
        before, labels = labels, new
    return labels


# ---------------------------------------------------------------- clustering algorithms


def _prepared(features, grid_shape, k, metric, weights, points, f):
    """Checked inputs -> (embedded features (n, 5), embedded eq. 3.4 centres (k, 5), metric matrix A,
    points or None, k)."""
    features, grid = _checked_features(features, grid_shape)
    k = _checked_k(k, len(features))
    _checked_choice(metric, METRICS, "metric")
    _checked_choice(f, SHAPE_FACTORS, "shape factor f")
    weights = _checked_weights(weights)
    points = _checked_points(points, len(features)) if metric == "pca" else None
    embedded = embed_features(features)
    start = embed_features(initial_centres(features, grid, k))
    return embedded, start, _metric_transform(embedded, metric, weights), points, k


def kmeans(features, grid_shape, k, metric="euclidean", weights=None, points=None, max_iter=300, f="ratio2"):
    """K-means (Algorithm 1) from the eq. 3.4 centres -> labels (n,) int in [0, k).

    metric: "euclidean"; "mahalanobis" (whole-surface covariance of (u, v, s), axial spread of theta);
    "std" (each squared difference divided by the whole-surface standard deviation, as the seed
    prints) or "std2" (divided by the variance); "pca" (eq. 3.2, needs ``points`` (n, 3) mm, shape
    factor ``f`` = "ratio2" (lambda_II/lambda_I)² or "one_minus_ratio2" 1 - (lambda_II/lambda_I)²;
    each iteration eigen-solves a 3x3 covariance per (cell, changed zone) pair: about 1.5 s for
    80 x 80 cells and k = 3, 30 s for k = 10 on two cores).
    weights (4,) in [0, 1]: the seed's Ch. 4 omega on the squared (u, v, s, theta) terms.
    The fixed quadratic forms run scikit-learn's Lloyd K-means on linearly transformed embedded
    features; "pca" runs a numpy Lloyd loop capped at max_iter. Empty clusters are re-seeded at the
    cell farthest from its centre (scikit-learn's rule, and ours for "pca"), so all k labels are used
    unless fewer than k weighted feature vectors are distinct (scikit-learn then warns).
    """
    embedded, start, transform, points, k = _prepared(features, grid_shape, k, metric, weights, points, f)
    transformed = embedded @ transform
    start = start @ transform
    if metric == "pca":
        return _kmeans_pca(transformed, start, embedded[:, 3:], points, f, max_iter)
    model = KMeans(n_clusters=k, init=start, n_init=1, max_iter=max_iter, tol=0.0, algorithm="lloyd")
    return model.fit_predict(transformed).astype(np.intp)


def rpcl(
    features,
    grid_shape,
    k,
    metric="euclidean",
    weights=None,
    points=None,
    alpha_c=0.05,
    alpha_r=0.005,
    rate_decay=0.97,
    rate_tol=1e-3,
    samples_per_iter=128,
    max_iter=300,
    change_tol=0.01,
    seed=0,
    f="ratio2",
):
    """Rival Penalized Competitive Learning (Algorithm 2) from the eq. 3.4 centres -> labels (n,) int
    0..m-1 over the m <= k centres that still own cells, numbered in the order of their first cell.

    Each iteration t draws ``samples_per_iter`` random cells (numpy generator ``seed``; deterministic).
    For each sample x the winner c minimises gamma_j d²(x, w_j), gamma_j = n_j / sum n (n_j the
    cumulative wins, starting at 1 so that no centre begins with gamma = 0), and the rival r is the
    second-best j. Then w_c += a_c (x - w_c) and w_r -= a_r (x - w_r) with rates decaying
    geometrically per iteration, a = alpha * rate_decay**t. After the samples every cell is assigned to
    its nearest centre (the thesis's step 3; the PCA metric's shape term uses the zones of the previous
    assignment). Stops when alpha_c * rate_decay**t < rate_tol and fewer than ``change_tol`` of the
    cells changed zone, or after max_iter iterations. metric, weights, points, f: as in ``kmeans``.
    """
    embedded, start, transform, points, k = _prepared(features, grid_shape, k, metric, weights, points, f)
    if k == 1:
        return np.zeros(len(embedded), dtype=np.intp)
    transformed = embedded @ transform
    centres = start @ transform
    rng = np.random.default_rng(seed)
    n = len(transformed)
    wins = np.ones(k)
    penalty = np.zeros((n, k))
    labels = np.argmin(_squared_distances(transformed, centres), axis=1)
    before = None
    for t in range(max_iter):
        if metric == "pca":
            _update_pca_penalty(penalty, before, labels, points, embedded[:, 3:], f)
        rate_c = alpha_c * rate_decay**t
        rate_r = alpha_r * rate_decay**t
        for i in rng.integers(0, n, size=min(samples_per_iter, n)):
            x = transformed[i]
            diff = x - centres
            score = wins / wins.sum() * (np.einsum("kr,kr->k", diff, diff) + penalty[i])
            winner, rival = np.argsort(score, kind="stable")[:2]
            wins[winner] += 1.0
            centres[winner] += rate_c * diff[winner]
            centres[rival] -= rate_r * diff[rival]
        new = np.argmin(_squared_distances(transformed, centres) + penalty, axis=1)
        changed = np.mean(new != labels)
        before, labels = labels, new
        if rate_c < rate_tol and changed < change_tol:
            break
    return _first_seen_order(labels)


def ward(features, grid_shape, k=None, weights=None):
    """Agglomerative clustering with Ward linkage (Algorithm 3, scipy's exact Lance-Williams Ward on the
    embedded, omega-weighted features) -> labels (n,) int in [0, m), numbered by first cell.

    k: the number of clusters, or None for the seed's rule: keep the partition just before the
    largest jump between consecutive merge heights, over partitions of n - 1 down to 2 clusters
    (so the final merge's height counts). Heights are the dendrogram's Ward distances
    sqrt(2 delta_inertia), the usual dendrogram scale (jumps of delta_inertia itself grow with the
    square of the distances and favour the last merges). scipy holds n(n-1)/2 distances in memory
    (160 MB for 80 x 80)."""
    features, _ = _checked_features(features, grid_shape)
    n = len(features)
    if k is not None:
        k = _checked_k(k, n)
    weighted = embed_features(features) * np.sqrt(_embedded_weights(_checked_weights(weights)))
    if n == 1:
        return np.zeros(1, dtype=np.intp)
    tree = linkage(weighted, method="ward")
    if k is None:
        heights = tree[:, 2]
        # before merge j (0-based) there are n - j clusters; j = 1..n-2 keeps 2..n-1 clusters.
        k = n - (1 + int(np.argmax(np.diff(heights)))) if n > 2 else 2
    labels = cut_tree(tree, n_clusters=k)[:, 0]
    return _first_seen_order(labels)


def _first_seen_order(labels):
    """Labels renumbered 0..m-1 in the order their first cell appears (row-major)."""
    ids, first, inverse = np.unique(labels, return_index=True, return_inverse=True)
    rank = np.empty(len(ids), dtype=np.intp)
    rank[np.argsort(first)] = np.arange(len(ids))
    return rank[inverse]


def connected_zones(labels, grid_shape):
    """Split each cluster into its 4-connected components on the grid (§3.7.4) -> zone ids (n,) int
    0..Z-1, numbered in the row-major order of each zone's first cell."""
    labels = np.asarray(labels)
    try:
        nu, nv = (int(m) for m in grid_shape)
    except (TypeError, ValueError):
        raise InputError(f"grid_shape must be two integers (nu, nv), got {grid_shape!r}") from None
    if labels.ndim != 1 or len(labels) != nu * nv or not np.issubdtype(labels.dtype, np.integer):
        raise InputError(f"labels must be {nu * nv} integers for a {nu} x {nv} grid, got shape {labels.shape}")
    grid = labels.reshape(nu, nv)
    zones = np.empty((nu, nv), dtype=np.intp)
    offset = 0
    for cluster in np.unique(grid):
        components, count = ndimage.label(grid == cluster)  # default structure: 4-connectivity
        member = components > 0
        zones[member] = components[member] - 1 + offset
        offset += count
    return _first_seen_order(zones.ravel())


# ---------------------------------------------------------------- zone statistics


@dataclass(frozen=True)
class ZoneStatistics:
    """Per-zone descriptors, arrays indexed by zone id (NaN for an id without cells)."""

    count: np.ndarray  # (Z,) cells
    mean_uv: np.ndarray  # (Z, 2)
    mean_slope: np.ndarray  # (Z,) rad
    mean_theta: np.ndarray  # (Z,) rad, axial mean steepest-slope azimuth in [-pi/2, pi/2)
    eigenvalues: np.ndarray  # (Z, 3) mm², lambda_I >= lambda_II >= lambda_III of the 1/n covariance of the points
    principal_direction: np.ndarray  # (Z, 3) unit eigenvector of lambda_I; first nonzero component > 0
    principal_azimuth: np.ndarray  # (Z,) rad, axial azimuth of its XY projection in [-pi/2, pi/2); NaN when vertical
    slope_misalignment: np.ndarray  # (Z,) rad in [0, pi/2], angle between principal_azimuth and mean_theta


def axial_difference(a, b):
    """Angle rad in [0, pi/2] between axial directions a and b (broadcast)."""
    return np.abs(wrap_axial(np.asarray(a, dtype=float) - b))


def zone_statistics(zones, features, points):
    """Count, mean (u, v), mean slope, axial mean theta, PCA of the 3D points (eigenvalues, principal
    direction and its XY azimuth) and the principal-to-slope angle of each zone id 0..max(zones)."""
    zones = np.asarray(zones)
    features = np.asarray(features, dtype=float)
    points = np.asarray(points, dtype=float)
    n = len(features)
    if features.shape != (n, 4) or zones.shape != (n,) or points.shape != (n, 3):
        raise InputError(
            "zone_statistics needs zones (n,), features (n, 4) and points (n, 3); "
            f"got {zones.shape}, {features.shape}, {points.shape}"
        )
    if n == 0 or not np.issubdtype(zones.dtype, np.integer) or zones.min() < 0:
        raise InputError("zones must be non-negative integer ids, one per cell")
    k = int(zones.max()) + 1
    count, _, cov = _zone_point_moments(zones, k, points)
    means = _zone_means(zones, k, embed_features(features))
    eigenvalues, eigenvectors = np.linalg.eigh(cov)
    eigenvalues = eigenvalues[:, ::-1].copy()
    direction = eigenvectors[:, :, 2]
    leading = direction[np.arange(k), np.argmax(np.abs(direction) > 1e-12, axis=1)]
    direction = direction * np.where(leading < 0, -1.0, 1.0)[:, None]
    horizontal = np.hypot(direction[:, 0], direction[:, 1]) > 1e-9
    azimuth = np.where(horizontal, wrap_axial(np.arctan2(direction[:, 1], direction[:, 0])), np.nan)
    mean_theta = _axial_angle_of_embedding(means[:, 3:])
    empty = count == 0
    for values in (means, eigenvalues, direction, azimuth, mean_theta):
        values[empty] = np.nan
    return ZoneStatistics(
        count=count.astype(np.intp),
        mean_uv=means[:, :2],
        mean_slope=means[:, 2],
        mean_theta=mean_theta,
        eigenvalues=eigenvalues,
        principal_direction=direction,
        principal_azimuth=azimuth,
        slope_misalignment=axial_difference(azimuth, mean_theta),
    )
