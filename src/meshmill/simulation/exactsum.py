"""Sums whose result does not depend on how the terms were grouped: a dexel model's volume, the
mean deviation over its ends, summed over one whole model or over blocks of its lines on the
workers of a cluster, give the same float.

A sum is kept exactly as an *expansion* (Shewchuk, "Adaptive precision floating-point arithmetic",
1997): a few non-overlapping floats whose exact sum is the sum of the terms. Expansions of blocks
are joined by concatenation, and :func:`total` rounds the exact sum once (``math.fsum``).
"""
from __future__ import annotations

import math

import numba
import numpy as np

ROOM = 64  # floats an expansion may need (non-overlapping doubles: about 40 at most)


@numba.njit(cache=True)
def grow(p, n, x):
    """Add ``x`` to the expansion ``p[:n]`` in place; returns its new length."""
    i = 0
    for j in range(n):
        y = p[j]
        if abs(x) < abs(y):
            x, y = y, x
        hi = x + y
        lo = y - (hi - x)
        if lo != 0.0:
            p[i] = lo
            i += 1
        x = hi
    p[i] = x
    return i + 1


@numba.njit(cache=True)
def _expansion(x, p):
    n = 0
    for k in range(x.shape[0]):
        n = grow(p, n, x[k])
    return n


def expansion(x: np.ndarray) -> np.ndarray:
    """The exact sum of ``x (k,)`` as an expansion (a few floats)."""
    p = np.zeros(ROOM)
    return p[:_expansion(np.ascontiguousarray(x, dtype=np.float64), p)].copy()


def total(*expansions) -> float:
    """The exact sum of the given expansions, rounded once."""
    return math.fsum(float(v) for e in expansions for v in e)
