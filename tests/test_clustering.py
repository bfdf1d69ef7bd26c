"""Partitioning a surface into machining zones by clustering (seed 002, Ch. 3), on small synthetic grids
whose right answer is known."""
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from sklearn.exceptions import ConvergenceWarning

from meshmill.choice import clustering as cl
from meshmill.errors import InputError

NU = NV = 20
GRID = (NU, NV)


def cell_uv(nu=NU, nv=NV):
    """Cell-centre (u, v) of a row-major nu x nv grid."""
    iu, iv = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    return ((iu + 0.5) / nu).ravel(), ((iv + 0.5) / nv).ravel()


def surface_samples(height, size=100.0):
    """Features (n, 4) and points (n, 3) mm of z = height(x, y) on a size x size mm square, x = size u, y = size v."""
    u, v = cell_uv()
    x, y = size * u, size * v
    step = 1e-4
    gx = (height(x + step, y) - height(x - step, y)) / (2 * step)
    gy = (height(x, y + step) - height(x, y - step)) / (2 * step)
    normal = np.column_stack([-gx, -gy, np.ones_like(gx)])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    slope = np.arccos(np.abs(normal[:, 2]))
    theta = cl.wrap_axial(np.arctan2(normal[:, 1], normal[:, 0]))
    return np.column_stack([u, v, slope, theta]), np.column_stack([x, y, height(x, y)])


def flat_points(features):
    """3D points of a flat 100 x 100 mm square for features whose s, theta are set by hand."""
    return np.column_stack([100 * features[:, 0], 100 * features[:, 1], np.zeros(len(features))])


def same_partition(a, b):
    """True when the labellings a and b are equal up to renaming the labels."""
    pairs = set(zip(np.asarray(a).tolist(), np.asarray(b).tolist()))
    return len(pairs) == len(set(a.tolist())) == len(set(b.tolist()))


def halves():
    """Two regions u < 1/2 and u >= 1/2 with clearly different slope and slope direction."""
    u, v = cell_uv()
    region = (u >= 0.5).astype(int)
    return np.column_stack([u, v, np.where(region, 1.2, 0.3), np.where(region, 1.0, -0.5)]), region


def four_triangles():
    """Four regions cut by the diagonals (the Voronoi cells of the eq. 3.4 centres for k = 4), with
    slope directions pi/4 apart, neighbours also differing in slope (uncorrelated with u and v)."""
    u, v = cell_uv()
    region = np.argmax(np.column_stack([u - 0.5, v - 0.5, 0.5 - u, 0.5 - v]), axis=1)
    theta = np.array([-3, -1, 1, 3]) * np.pi / 8
    slope = np.array([0.3, 1.1, 0.3, 1.1])
    return np.column_stack([u, v, slope[region], theta[region]]), region


def three_sectors():
    """Three 120 degree sectors around the centre holding the eq. 3.4 centres for k = 3, with slope
    directions pi/3 apart (equidistant in the axial embedding) and equal slopes."""
    u, v = cell_uv()
    angle = np.arctan2(v - 0.5, u - 0.5)
    region = np.floor(((angle - np.pi / 3) % (2 * np.pi)) / (2 * np.pi / 3)).astype(int)
    theta = np.array([-1, 0, 1]) * np.pi / 3
    return np.column_stack([u, v, np.full_like(u, 0.6), theta[region]]), region


QUADRATIC_METRICS = ("euclidean", "mahalanobis", "std", "std2")


@pytest.mark.parametrize("make", [halves, four_triangles])
def test_kmeans_finds_the_regions_with_every_metric(make):
    features, region = make()
    k = region.max() + 1
    for metric in QUADRATIC_METRICS:
        labels = cl.kmeans(features, GRID, k, metric=metric)
        assert labels.shape == region.shape and labels.min() >= 0 and labels.max() < k
        assert same_partition(labels, region), metric
    for f in cl.SHAPE_FACTORS:
        assert same_partition(cl.kmeans(features, GRID, k, metric="pca", points=flat_points(features), f=f), region), f


@pytest.mark.parametrize("make", [halves, four_triangles])
def test_rpcl_and_ward_find_the_regions(make):
    features, region = make()
    k = region.max() + 1
    for metric in ("euclidean", "mahalanobis", "std"):
        assert same_partition(cl.rpcl(features, GRID, k, metric=metric), region), metric
    assert same_partition(cl.rpcl(features, GRID, k, metric="pca", points=flat_points(features)), region)
    assert same_partition(cl.ward(features, GRID, k), region)


def test_theta_wraps_at_plus_minus_half_pi():
    """Cells at +pi/2 - 0.01 and -pi/2 + 0.01 are 0.02 rad apart: one zone, not two (the seed's raw
    difference would call them pi - 0.02 apart)."""
    rng = np.random.default_rng(3)
    u, v = cell_uv()
    right = u >= 0.5
    theta = np.where(right, rng.choice([np.pi / 2 - 0.01, -np.pi / 2 + 0.01], size=u.size), 0.0)
    features = np.column_stack([u, v, np.full_like(u, 0.5), theta])
    pair = cl.embed_features(np.array([[0, 0, 0, np.pi / 2 - 0.01], [0, 0, 0, -np.pi / 2 + 0.01]]))
    assert np.linalg.norm(pair[0] - pair[1]) == pytest.approx(np.sin(0.02))
    for metric in QUADRATIC_METRICS:
        assert same_partition(cl.kmeans(features, GRID, 2, metric=metric), right), metric
    assert same_partition(cl.kmeans(features, GRID, 2, metric="pca", points=flat_points(features)), right)
    assert same_partition(cl.rpcl(features, GRID, 2), right)
    assert same_partition(cl.ward(features, GRID), right)
    stats = cl.zone_statistics(right.astype(int), features, flat_points(features))
    assert abs(abs(stats.mean_theta[1]) - np.pi / 2) < 0.01  # axial mean near the wrap, not near 0


def test_zero_position_weights_ignore_where_cells_are():
    """omega = (0, 0, 1, 1): cells scattered at random over the grid group by slope direction alone."""
    rng = np.random.default_rng(7)
    u, v = cell_uv()
    group = rng.integers(0, 2, size=u.size)
    features = np.column_stack([u, v, np.full_like(u, 0.4), np.where(group, 0.1, -0.1)])
    assert not same_partition(cl.kmeans(features, GRID, 2), group)
    for metric in QUADRATIC_METRICS:
        assert same_partition(cl.kmeans(features, GRID, 2, metric=metric, weights=[0, 0, 1, 1]), group), metric
    assert same_partition(cl.rpcl(features, GRID, 2, weights=[0, 0, 1, 1]), group)
    assert same_partition(cl.ward(features, GRID, 2, weights=[0, 0, 1, 1]), group)


def test_pca_metric_aligns_zones_with_their_slope():
    """A roof z = 0.3 |x - 40| + 0.1 y: both faces slope mostly along X, but the faces are long along Y.
    Euclidean K-means (k = 4) cuts zones long across the slope; the PCA metric (either f) stretches
    zones along their steepest-slope direction, so the cell-weighted angle between each zone's
    principal direction and its mean slope direction drops (the seed's Table 3.3 claim)."""
    features, points = surface_samples(lambda x, y: 0.3 * np.abs(x - 40) + 0.1 * y)

    def misalignment(labels):
        stats = cl.zone_statistics(cl.connected_zones(labels, GRID), features, points)
        return np.degrees(stats.count @ stats.slope_misalignment / stats.count.sum())

    euclidean = cl.kmeans(features, GRID, 4)
    assert misalignment(euclidean) > 50
    for f in cl.SHAPE_FACTORS:
        pca = cl.kmeans(features, GRID, 4, metric="pca", points=points, f=f)
        assert not same_partition(pca, euclidean)
        assert misalignment(pca) < misalignment(euclidean) - 20, f


def test_rpcl_drops_surplus_clusters():
    features, region = halves()
    labels = cl.rpcl(features, GRID, 3)
    assert same_partition(labels, region) and set(labels.tolist()) == {0, 1}
    features, region = three_sectors()
    labels = cl.rpcl(features, GRID, 4)
    assert same_partition(labels, region) and set(labels.tolist()) == {0, 1, 2}
    assert np.array_equal(labels, cl.rpcl(features, GRID, 4))  # deterministic for a seed


@pytest.mark.parametrize("make", [halves, three_sectors])
def test_ward_without_k_finds_the_number_of_regions(make):
    features, region = make()
    assert same_partition(cl.ward(features, GRID), region)


@settings(max_examples=40, deadline=None)
@given(data=st.data(), dim=st.integers(1, 4), size=st.integers(2, 25))
def test_incremental_covariance_matches_numpy(data, dim, size):
    elements = st.floats(-1e3, 1e3, allow_nan=False, allow_subnormal=False)
    values = data.draw(arrays(float, (size, dim), elements=elements))
    running = cl.IncrementalCovariance(dim)
    for m, point in enumerate(values, start=1):
        running.add(point)
        assert running.count == m
        np.testing.assert_allclose(running.mean, values[:m].mean(axis=0), rtol=1e-9, atol=1e-9)
        expected = np.atleast_2d(np.cov(values[:m].T, bias=True))
        np.testing.assert_allclose(running.covariance, expected, rtol=1e-7, atol=1e-6)
    gone = data.draw(st.integers(1, size - 1))
    running.remove(values[0])  # one point, eq. 3.6
    running.remove(values[1:gone])  # then a batch (empty when gone == 1)
    rest = values[gone:]
    np.testing.assert_allclose(running.mean, rest.mean(axis=0), rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(running.covariance, np.atleast_2d(np.cov(rest.T, bias=True)), rtol=1e-6, atol=1e-4)

    head_cov = np.atleast_2d(np.cov(values[:-1].T, bias=True))
    mean, cov = cl.IncrementalCovariance.with_point_added(size - 1, values[:-1].mean(axis=0), head_cov, values[-1])
    np.testing.assert_allclose(cov, np.atleast_2d(np.cov(values.T, bias=True)), rtol=1e-7, atol=1e-6)
    np.testing.assert_allclose(mean, values.mean(axis=0), rtol=1e-9, atol=1e-9)


def test_incremental_covariance_batch_and_empty():
    rng = np.random.default_rng(0)
    values = rng.normal(size=(50, 3)) * [100, 10, 1] + 1e4
    running = cl.IncrementalCovariance(3)
    running.add(values[:30])
    running.add(values[30:])
    np.testing.assert_allclose(running.covariance, np.cov(values.T, bias=True), rtol=1e-9)
    running.remove(values)
    assert running.count == 0 and not running.covariance.any()
    with pytest.raises(ValueError):
        running.remove(values[0])


def test_connected_zones_split_separated_blobs():
    labels = np.zeros(GRID, dtype=int)
    labels[2:6, 2:6] = 1
    labels[12:16, 10:18] = 1  # cluster 1 is two blobs
    labels[8, 8] = 2
    labels[9, 9] = 2  # only diagonal neighbours: two zones under 4-connectivity
    zones = cl.connected_zones(labels.ravel(), GRID).reshape(GRID)
    assert zones.max() + 1 == 5
    assert zones[0, 0] == 0 and zones[2, 2] == 1 and zones[8, 8] == 2 and zones[9, 9] == 3 and zones[12, 10] == 4
    for zone in range(5):  # every zone lies inside one cluster
        assert len(np.unique(labels[zones == zone])) == 1


def test_initial_centres_follow_eq_3_4():
    u, v = cell_uv()
    iu = np.floor(u * NU)
    features = np.column_stack([u, v, iu / 100, (v * NV) / 100 - 0.1])
    centres = cl.initial_centres(features, GRID, 4)
    np.testing.assert_allclose(centres[:, :2], [[0.5, 0.75], [0.25, 0.5], [0.5, 0.25], [0.75, 0.5]], atol=1e-12)
    cells = [(10, 15), (5, 10), (10, 5), (15, 10)]  # the cells containing those (u, v)
    np.testing.assert_allclose(centres[:, 2:], [features[a * NV + b, 2:] for a, b in cells])


def test_zone_statistics_of_a_tilted_strip():
    features, points = surface_samples(lambda x, y: 0.5 * x)
    zones = (features[:, 1] >= 0.5).astype(int)  # two strips 100 mm along X, 50 mm along Y
    stats = cl.zone_statistics(zones, features, points)
    assert stats.count.tolist() == [200, 200]
    np.testing.assert_allclose(stats.mean_uv, [[0.5, 0.25], [0.5, 0.75]])
    np.testing.assert_allclose(stats.mean_slope, np.arctan(0.5))
    np.testing.assert_allclose(stats.mean_theta, 0, atol=1e-9)
    for zone in range(2):
        expected = np.linalg.eigvalsh(np.cov(points[zones == zone].T, bias=True))[::-1]
        np.testing.assert_allclose(stats.eigenvalues[zone], expected)
    np.testing.assert_allclose(stats.principal_direction, [[2, 0, 1], [2, 0, 1]] / np.sqrt(5), atol=1e-12)
    np.testing.assert_allclose(stats.principal_azimuth, 0, atol=1e-12)
    np.testing.assert_allclose(stats.slope_misalignment, 0, atol=1e-9)


def test_empty_clusters_do_not_crash():
    """Two distinct feature values and k = 3: scikit-learn and the PCA loop re-seed the empty zone."""
    features, region = halves()
    weights = [0, 0, 1, 1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # "fewer distinct clusters than k"
        labels = cl.kmeans(features, GRID, 3, weights=weights)
    assert labels.min() >= 0 and labels.max() < 3
    labels = cl.kmeans(features, GRID, 5, metric="pca", points=flat_points(features), weights=weights)
    assert labels.min() >= 0 and labels.max() < 5
    constant = features.copy()
    constant[:, 3] = 0.2  # zero variance: Mahalanobis falls back on the pseudo-inverse
    assert same_partition(cl.kmeans(constant, GRID, 2, metric="mahalanobis"), region)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda f: cl.kmeans(f, GRID, NU * NV + 1), "between 1 and the 400 cells"),
        (lambda f: cl.kmeans(f, GRID, 0), "between 1 and the 400 cells"),
        (lambda f: cl.rpcl(f, GRID, 2.5), "must be an integer"),
        (lambda f: cl.ward(f, GRID, 401), "between 1 and the 400 cells"),
        (lambda f: cl.kmeans(f, (10, 10), 2), "does not match"),
        (lambda f: cl.kmeans(f, GRID, 2, metric="cosine"), "unknown metric"),
        (lambda f: cl.kmeans(f, GRID, 2, metric="pca"), "needs the 3D sample points"),
        (lambda f: cl.kmeans(f, GRID, 2, weights=[1, 1, 2, 1]), "weights"),
        (lambda f: cl.kmeans(f, GRID, 2, metric="pca", points=flat_points(f), f="ratio"), "shape factor"),
        (lambda f: cl.initial_centres(f[:, :3], GRID, 2), r"\(n, 4\)"),
    ],
)
def test_bad_input_raises_input_error(call, message):
    features, _ = halves()
    with pytest.raises(InputError, match=message):
        call(features)


def test_nan_features_raise_input_error():
    features, _ = halves()
    features[37, 2] = np.nan
    for call in (cl.kmeans, cl.rpcl, cl.ward):
        with pytest.raises(InputError, match="finite numbers; cell 37"):
            call(features, GRID, 2)
    with pytest.raises(InputError, match="finite"):
        cl.kmeans(halves()[0], GRID, 2, metric="pca", points=np.full((NU * NV, 3), np.nan))
