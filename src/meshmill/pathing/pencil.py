"""Pencil passes: a vertical ball or bull-nose along the concave corners and fillets of a part,
where it touches two sides at once (3-axis).

The tool's drop heights on a grid ``step`` apart: where the contacts of two neighbouring nodes lie
more than :data:`JUMP` steps apart, the tool went from one side of a concave corner to the other
(over a convex edge the contact stays on the edge, and ground that curves more gently than 1.5
tool radii moves it less). Halving the grid edge finds where the contact changes side, to
:data:`SEARCH`. The crossings on the edges of each grid cell are joined, and the chains of them
are the corners' lines; points every ``sample`` mm along them are moved across the line onto the
crease the same way, and dropped. Lengths in mm.
"""
from __future__ import annotations

import numpy as np

JUMP = 3.0  # grid steps: contacts of neighbouring nodes farther apart than this straddle a corner
SEARCH = 1e-3  # mm: how close the halving puts a crease on its grid edge


def _jumps(c, step: float, ny: int, axis: int) -> np.ndarray:
    """``(k, 2)`` flat indices of the neighbouring nodes along ``axis`` (0: x, 1: y) of the grid of
    contacts ``c (nx, ny, 3)`` (NaN: none) whose contacts are more than :data:`JUMP` steps apart."""
    gap = np.linalg.norm(np.diff(c, axis=axis), axis=2)
    with np.errstate(invalid="ignore"):
        i, j = np.nonzero(gap > JUMP * step)
    first = i * ny + j
    return np.column_stack([first, first + (ny if axis == 0 else 1)])


def _creases(drop, a, b, za, zb, ca, cb):
    """``(k, 2)``: where the tool's contact goes from one side to the other between ``a`` and ``b``
    (``(k, 2)`` xy, their heights ``za, zb (k,)`` and contacts ``ca, cb (k, 3)``), by halving to
    :data:`SEARCH`: the end of the last bracket on the lower side (a V's sides meet there; at a
    wall's foot, the floor's)."""
    a, b, za, zb = a.copy(), b.copy(), za.copy(), zb.copy()
    while len(a) and np.linalg.norm(b - a, axis=1).max() > SEARCH:
        mid = 0.5 * (a + b)
        zm, cm = drop.with_contacts(mid)
        side_a = np.linalg.norm(cm - ca, axis=1) <= np.linalg.norm(cm - cb, axis=1)
        a = np.where(side_a[:, None], mid, a)
        za = np.where(side_a, zm, za)
        b = np.where(side_a[:, None], b, mid)
        zb = np.where(side_a, zb, zm)
    return np.where((za <= zb)[:, None], a, b)


def _onto_crease(drop, xy, step: float):
    """``(k, 2)``: the points ``xy`` of a corner line moved across it onto the crease (searched
    within a grid ``step`` either side; a point with no change of side there stays)."""
    if len(xy) < 2:
        return xy
    t = np.gradient(xy, axis=0)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)
    n = np.column_stack([-t[:, 1], t[:, 0]])
    a, b = xy - step * n, xy + step * n
    (za, ca), (zb, cb) = drop.with_contacts(a), drop.with_contacts(b)
    with np.errstate(invalid="ignore"):
        across = np.linalg.norm(ca - cb, axis=1) > JUMP * step
    out = xy.copy()
    if across.any():
        out[across] = _creases(drop, a[across], b[across], za[across], zb[across], ca[across], cb[across])
    return out


def crease_lines(drop, xs, ys, min_length: float) -> list:
    """``[(k, 2) xy, ...]``: the corners' lines under the tool of ``drop``
    (:class:`~meshmill.pathing.dropcutter.ToolDrop`) on the grid ``xs x ys`` (a step apart), at
    least ``min_length`` mm long."""
    nx, ny = len(xs), len(ys)
    if nx < 3 or ny < 3:
        return []
    step = float(xs[1] - xs[0])
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    xy = np.column_stack([gx.ravel(), gy.ravel()])
    z, c = drop.with_contacts(xy)
    ex, ey = (_jumps(c.reshape(nx, ny, 3), step, ny, a) for a in (0, 1))
    e = np.vstack([ex, ey])
    pts = _creases(drop, xy[e[:, 0]], xy[e[:, 1]], z[e[:, 0]], z[e[:, 1]], c[e[:, 0]], c[e[:, 1]])
    key = {}
    for k, (a, _) in enumerate(ex):  # the edge from node (i, j) to (i + 1, j)
        key[("x", int(a // ny), int(a % ny))] = k
    for k, (a, _) in enumerate(ey):  # from (i, j) to (i, j + 1)
        key[("y", int(a // ny), int(a % ny))] = len(ex) + k
    # join the crossings of each cell: (i, j) to (i + 1, j + 1), its edges x(i, j), x(i, j + 1), y(i, j), y(i + 1, j)
    cells = {}
    for (kind, i, j), k in key.items():
        for cell in (((i, j), (i, j - 1)) if kind == "x" else ((i, j), (i - 1, j))):
            cells.setdefault(cell, []).append(k)
    links = {}
    for members in cells.values():
        for a, b in _pairs(members, pts):
            links.setdefault(a, []).append(b)
            links.setdefault(b, []).append(a)
    return [pts[chain] for chain in _chains(links) if _length(pts[chain]) >= min_length]


def _pairs(members, pts):
    """The crossings of one cell joined two by two, the nearest first (a saddle's four, an odd one
    out)."""
    members = list(members)
    out = []
    while len(members) >= 2:
        best = min(((a, b) for ai, a in enumerate(members) for b in members[ai + 1:]),
                   key=lambda ab: float(np.linalg.norm(pts[ab[0]] - pts[ab[1]])))
        out.append(best)
        members = [m for m in members if m not in best]
    return out


def _chains(links) -> list:
    """The chains of a graph whose nodes have at most two neighbours: open ones from an end, then
    closed ones (their first node repeated last)."""
    seen, out = set(), []
    ends = [n for n, nb in links.items() if len(nb) == 1]
    for start in ends + list(links):
        if start in seen:
            continue
        chain, prev, cur = [start], None, start
        seen.add(start)
        while True:
            nxt = [n for n in links[cur] if n != prev and (n not in seen or (n == start and len(chain) > 2))]
            if not nxt:
                break
            prev, cur = cur, nxt[0]
            chain.append(cur)
            if cur == start:
                break
            seen.add(cur)
        if len(chain) >= 2:
            out.append(np.array(chain))
    return out


def _length(xy) -> float:
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()) if len(xy) > 1 else 0.0


def pencil_passes(drop, lo, hi, step: float, sample: float, min_length: float) -> list:
    """``[(k, 3) tips, ...]``: the pencil passes of the tool of ``drop`` over the box ``lo, hi``
    (its ``(2,)`` x, y corners, the tool's reach around the part included), the grid ``step``
    apart, points at most ``sample`` apart along each corner line at least ``min_length`` long,
    each moved across the line onto the crease."""
    xs = np.arange(lo[0], hi[0] + 0.5 * step, step)
    ys = np.arange(lo[1], hi[1] + 0.5 * step, step)
    out = []
    for xy in crease_lines(drop, xs, ys, min_length):
        seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
        at = np.r_[0.0, np.cumsum(seg)]
        s = np.linspace(0.0, at[-1], max(2, int(np.ceil(at[-1] / sample)) + 1))
        dense = np.column_stack([np.interp(s, at, xy[:, 0]), np.interp(s, at, xy[:, 1])])
        closed = np.allclose(xy[0], xy[-1])
        dense = _onto_crease(drop, dense[:-1] if closed else dense, step)
        if closed:
            dense = np.vstack([dense, dense[:1]])
        z, _ = drop.with_contacts(dense)
        out.append(np.column_stack([dense, z]))
    return out
