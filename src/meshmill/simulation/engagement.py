"""The material each move of a path removes, measured on the in-process dexel stock.

The path is cut in order (the Z dexels alone: the others are not summed); before and after each
move of interest the volume held by the stock's Z dexels is summed (``step²`` times the lengths of their intervals), so the difference is what
that move removed, at the resolution of the dexels and independent of how the path was planned.
For a 3-axis move at one height, its volume over its length and the axial depth of its layer is
the mean radial width of cut (ae) of the move.
"""
from __future__ import annotations

import numba
import numpy as np

MOVE_FIELDS = ("pa", "pb", "xa", "xb", "radius", "corner", "flutes", "strips", "rapid", "source", "body")


@numba.njit(cache=True)
def _line_volume(iv, off, count, step, z0, z1):
    total = 0.0
    for i in range(len(count)):
        for k in range(off[i], off[i] + count[i]):
            total += max(0.0, min(iv[k, 1], z1) - max(iv[k, 0], z0))
    return total * step * step


def z_volume(st, band=(-np.inf, np.inf)) -> float:
    """mm³ the Z dexels of a cutting stock (:class:`~meshmill.simulation.cut.Stock`) hold between
    the heights ``band`` (mm)."""
    return float(_line_volume(st.iv[2], st.off[2], st.count[2], st.step, band[0], band[1]))


def _subset(moves, sel):
    from .cut import Moves

    return Moves(**{f: getattr(moves, f)[sel] for f in MOVE_FIELDS})


def _cut_z(st, moves, kern) -> None:
    """Cut the Z lines of the cutting stock ``st`` by the cutter moves of ``moves`` (the only lines
    whose volume is summed here)."""
    from . import cut as cutting

    keep = ~moves.body
    if not keep.any():
        return
    moves = _subset(moves, keep)
    hit = np.zeros(len(moves), np.uint8)
    cutting._cut_direction(st, 2, moves, cutting._boxes(moves), kern, hit)


def removed_per_move(stock, toolpath, tools, which, bands=None, device: str = "cpu") -> np.ndarray:
    """mm³ ``(len(which),)`` removed by each move ``which`` (indices of tool-path points: the move
    ends there) of ``toolpath`` from ``stock`` (an in-process :class:`~meshmill.simulation.stock.
    Stock`, left as it was), the path cut in order; with ``bands (len(which), 2)`` only what lay
    between those heights (mm)."""
    from . import cut as cutting
    from .stock import copy_cutting

    from ..kernels.backend import DexelKernels

    st = copy_cutting(stock.state.cutting)
    moves = cutting.toolpath_moves(toolpath, tools)
    kern = DexelKernels(device)
    which = np.asarray(which, np.int64)
    out = np.zeros(len(which))
    done = -1  # moves up to this point index are cut
    for n, j in enumerate(which):
        before = (moves.source > done) & (moves.source < j)
        if before.any():
            _cut_z(st, _subset(moves, before), kern)
        band = (-np.inf, np.inf) if bands is None else np.asarray(bands[n], float)
        v0 = z_volume(st, band)
        this = moves.source == j
        if this.any():
            _cut_z(st, _subset(moves, this), kern)
        out[n] = v0 - z_volume(st, band)
        done = j
    return out


def level_widths(stock, toolpath, tools, which, layer_top, device: str = "cpu") -> np.ndarray:
    """The mean radial width of cut (mm) ``(len(which),)`` of the level moves ``which`` of
    ``toolpath``: what each removes from ``stock`` (:func:`removed_per_move`) between its height
    and ``layer_top (len(which),)``, over its length and that depth."""
    which = np.asarray(which, np.int64)
    bands = np.column_stack([toolpath.tip[which, 2], layer_top])
    volume = removed_per_move(stock, toolpath, tools, which, bands, device)
    length = np.linalg.norm(toolpath.tip[which] - toolpath.tip[which - 1], axis=1)
    depth = np.asarray(layer_top, float) - toolpath.tip[which, 2]
    return volume / np.maximum(length * depth, 1e-12)
