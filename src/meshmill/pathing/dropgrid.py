"""Drop-cutter heights on a node grid, computed only where a Z level needs them.

The grid is covered by square blocks of cells, in tiers that halve the block side down to
``FINEST`` cells. Each block can get an upper and a lower bound of the drop height over its
whole area (:meth:`ToolDrop.bounds`; a block also inherits its parent's). At a level z a block
whose upper bound is at most z is outside everywhere, one whose lower bound is above z is inside
everywhere; the others have their children bounded in turn, and the finest ones still undecided
have their nodes dropped exactly (once, kept for later levels). The inside/outside state of every
node is therefore exact, whatever the level.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from .dropcutter import ToolDrop

FINEST = 4  # cells per side of the smallest blocks; below 3 the bounds would cost more than they save


def tier_sizes(spacing: float, radius: float) -> list[int]:
    """Cells per block side, coarsest first (``[]``: drop every node). Blocks reach at most half the
    cutter radius from their centre, so the bounds (which widen the cutter by that reach) stay close
    to the drop heights."""
    most = math.floor(0.5 * radius / (spacing * math.sqrt(0.5)))
    if most < 3:
        return []
    if most < FINEST:
        return [most]
    sizes = [FINEST]
    while 2 * sizes[0] <= min(most, 16):
        sizes.insert(0, 2 * sizes[0])
    return sizes


class DropGrid:
    """Drop heights ``heights (nx, ny)`` of ``drop`` on the nodes ``xs (nx,) x ys (ny,)`` (evenly
    spaced, mm) and the mesh points touched ``contacts (nx, ny, 3)``, filled in as levels ask for
    them (NaN where not dropped yet)."""

    def __init__(self, drop: ToolDrop, xs: np.ndarray, ys: np.ndarray):
        self.drop, self.xs, self.ys = drop, xs, ys
        nx, ny = len(xs), len(ys)
        self.heights = np.full((nx, ny), np.nan)
        self.contacts = np.full((nx, ny, 3), np.nan)
        self.sizes = tier_sizes(max(xs[1] - xs[0], ys[1] - ys[0]), drop.radius)
        if not self.sizes:
            gx, gy = np.meshgrid(xs, ys, indexing="ij")
            z, cc = drop.with_contacts(np.column_stack([gx.ravel(), gy.ravel()]))
            self.heights[:] = z.reshape(nx, ny)
            self.contacts[:] = cc.reshape(nx, ny, 3)
            return
        # tier t: block b spans nodes [b·k, min((b+1)·k, n-1)] (k = sizes[t]); a node on a block
        # border lies in both blocks; block b of tier t holds blocks 2b and 2b+1 of tier t+1
        shapes = [(-(-(nx - 1) // k), -(-(ny - 1) // k)) for k in self.sizes]
        self.upper = [np.full(sh, np.inf) for sh in shapes]  # own bounds (inf / -inf: not computed)
        self.lower = [np.full(sh, -np.inf) for sh in shapes]
        self.done = np.zeros(shapes[-1], bool)  # finest blocks whose nodes are all dropped
        self._bound(0, np.ones(shapes[0], bool))

    def _bound(self, tier, which):
        """Compute the bounds of the blocks ``which`` (bool, tier's shape) of a tier."""
        k = self.sizes[tier]
        bi, bj = np.nonzero(which)
        nx, ny = len(self.xs), len(self.ys)
        xs, ys = self.xs, self.ys
        cx = 0.5 * (xs[bi * k] + xs[np.minimum(bi * k + k, nx - 1)])
        cy = 0.5 * (ys[bj * k] + ys[np.minimum(bj * k + k, ny - 1)])
        reach = 0.5 * math.hypot(k * (xs[1] - xs[0]), k * (ys[1] - ys[0])) * (1 + 1e-9)
        self.upper[tier][bi, bj], self.lower[tier][bi, bj] = self.drop.bounds(np.column_stack([cx, cy]), reach)

    @property
    def dropped(self) -> int:
        """How many nodes have been dropped so far."""
        return int(np.count_nonzero(~np.isnan(self.heights)))

    def inside(self, z: float) -> np.ndarray:
        """``(nx, ny)`` bool: where the drop height is above z (the tool would gouge); bounds the
        blocks and drops the nodes that the bounds cannot decide first."""
        if not self.sizes:
            return self.heights > z
        eps = 1e-9 * (1.0 + abs(z))
        up, lo = self.upper[0], self.lower[0]
        for t in range(len(self.sizes)):
            unsure = (up > z - eps) & (lo <= z + eps)
            if t + 1 == len(self.sizes):
                break
            shape = self.upper[t + 1].shape
            new = _to_children(unsure, shape) & np.isinf(self.upper[t + 1])  # bounds not computed yet
            if new.any():
                self._bound(t + 1, new)
            up = np.minimum(self.upper[t + 1], _to_children(up, shape))
            lo = np.maximum(self.lower[t + 1], _to_children(lo, shape))
        unsure &= ~self.done
        i, j = _nodes_to_drop(unsure, self.heights, self.sizes[-1])
        if len(i):
            self.heights[i, j], self.contacts[i, j] = self.drop.with_contacts(np.column_stack([self.xs[i], self.ys[j]]))
        self.done |= unsure
        return _inside(self.heights, lo, z + eps, z, self.sizes[-1])


def _to_children(a, shape):
    """Per-block values of a tier spread to the blocks of the next tier, ``shape``."""
    return np.repeat(np.repeat(a, 2, 0), 2, 1)[:shape[0], :shape[1]]


@numba.njit(cache=True)
def _nodes_to_drop(unsure, heights, k):
    """Row and column indices of the nodes of the ``unsure`` blocks not dropped yet, each once."""
    nx, ny = heights.shape
    taken = np.zeros((nx, ny), np.bool_)
    ii = []
    jj = []
    for bi in range(unsure.shape[0]):
        for bj in range(unsure.shape[1]):
            if not unsure[bi, bj]:
                continue
            for i in range(bi * k, min((bi + 1) * k, nx - 1) + 1):
                for j in range(bj * k, min((bj + 1) * k, ny - 1) + 1):
                    if np.isnan(heights[i, j]) and not taken[i, j]:
                        taken[i, j] = True
                        ii.append(i)
                        jj.append(j)
    return np.array(ii, np.int64), np.array(jj, np.int64)


@numba.njit(cache=True)
def _inside(heights, lower, lower_above, z, k):
    """Node states at z: the drop height where known, else the block's certificate (nodes not
    dropped lie only in blocks that the bounds decide)."""
    nx, ny = heights.shape
    out = np.empty((nx, ny), np.bool_)
    for i in range(nx):
        bi = min(i // k, lower.shape[0] - 1)
        for j in range(ny):
            h = heights[i, j]
            if np.isnan(h):
                out[i, j] = lower[bi, min(j // k, lower.shape[1] - 1)] > lower_above
            else:
                out[i, j] = h > z
    return out
