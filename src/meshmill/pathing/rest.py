"""Rest machining: the pieces of a 3-axis pass where the tool removes material from the stock an
operation starts from (the in-process stock), so that the passes through air are left out.

A point of a pass is in material when its tip lies more than ``min_depth`` below the height at
which the same cutter, dropped from above, first touches the stock (the exact drop-cutter onto the
stock mesh: the cutter's whole width counts); a run keeps :data:`REST_LEAD` samples of the pass on
each side of its points in material, so that the moves where the cutter enters and leaves the
material are cut. The test is made at the pass's points (``sample`` apart before
simplification): material between two points in air is left for the next operation, which its
simulation reports; nothing is cut that the full pass would not cut.
"""
from __future__ import annotations

import numpy as np

REST_LEAD = 1.5  # samples of a pass kept before and after its points in material
REST_JOIN = 2.0  # tool diameters: runs of a pass closer than this are cut as one (no retract between)


def in_material(tips, tool, stock_kern, min_depth: float) -> np.ndarray:
    """``(k,) bool``: whether the cutter at each of ``tips (k, 3)`` (vertical axis) lies more
    than ``min_depth`` mm inside the stock of ``stock_kern``
    (:class:`~meshmill.kernels.backend.MeshKernels`)."""
    floor = float(stock_kern.bvh.node_lo[0, 2]) - 1.0
    top = stock_kern.drop_cutter(np.ascontiguousarray(tips[:, :2]), tool.radius, tool.corner_radius, floor)[0]
    return tips[:, 2] < top - min_depth


def material_runs(tips, inside, margin: float, join: float = 0.0) -> list:
    """The runs ``[(m, 3), ...]`` of the polyline ``tips (k, 3)`` around its points ``inside
    (k,) bool``, each widened by ``margin`` mm of the polyline on both sides; runs less than
    ``join`` mm apart along it are one run (the tool cuts through the gap rather than leaving and
    entering the material again)."""
    if not inside.any():
        return []
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(tips, axis=0), axis=1))]
    at = s[inside]
    # the nearest point in material before and after each point, along the polyline
    before = np.searchsorted(at, s, side="right") - 1
    after = np.minimum(before + 1, len(at) - 1)
    near = np.minimum(np.where(before >= 0, s - at[np.maximum(before, 0)], np.inf), np.abs(at[after] - s))
    keep = near <= margin
    edges = np.diff(np.r_[0, keep.astype(np.int8), 0])
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    if join > 0 and len(starts) > 1:
        gap = s[starts[1:]] - s[ends[:-1] - 1]
        close = gap < join
        starts = np.r_[starts[:1], starts[1:][~close]]
        ends = np.r_[ends[:-1][~close], ends[-1:]]
    return [tips[a:b] for a, b in zip(starts, ends) if b - a >= 2]


def densify(polyline, spacing: float) -> np.ndarray:
    """``polyline (k, 3)`` with points added on its segments so that none is longer than
    ``spacing`` mm (the same path)."""
    seg = np.linalg.norm(np.diff(polyline, axis=0), axis=1)
    n = np.maximum(1, np.ceil(seg / spacing).astype(np.int64))
    i = np.repeat(np.arange(len(seg)), n)
    k = np.arange(len(i)) - np.repeat(np.cumsum(n) - n, n) + 1  # 1..n along each segment
    f = (k / n[i])[:, None]
    return np.vstack([polyline[:1], polyline[i] + f * (polyline[i + 1] - polyline[i])])


def loop_runs(loop, inside, margin: float, join: float = 0.0) -> list:
    """As :func:`material_runs` for a closed ``loop (k, 3)`` (first point repeated at the end):
    a run through its start is not cut in two."""
    if inside.all():
        return [loop]
    if np.array_equal(loop[0], loop[-1]) and inside[0]:
        k = int(np.argmin(inside))  # a point in air: the loop starts there
        loop = np.vstack([loop[k:-1], loop[:k + 1]])
        inside = np.r_[inside[k:-1], inside[:k + 1]]
    return material_runs(loop, inside, margin, join)
