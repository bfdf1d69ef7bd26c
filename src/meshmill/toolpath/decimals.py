"""Numbers as fixed-point decimal text, many at once: the same characters as Python's
``f"{x:.{d}f}"`` (the exact binary value rounded half to even, ``-`` on every negative number,
-0.0 and those that round to zero included), written by a compiled loop.

A number is scaled by 10^d in floating point and rounded; that product is within half a unit in
its last place of the exact one, so the rounding is the exact value's unless the scaled number
lies that close to a half. A row holding such a number (or a non-finite one, or one too large
to scale exactly) is left to Python whole: :func:`fixed_rows` says which.

Read back (:func:`read_fixed`): a plain decimal of at most 15 digits is an integer over a power of
ten, both exact doubles, whose quotient is the correctly rounded value Python's ``float`` gives;
anything else is left to Python.
"""
from __future__ import annotations

import math

import numba
import numpy as np

MAX_DECIMALS = 18  # 10^d an int64
_EXACT_DIGITS = 15  # an integer of this many digits is an exact double (below 2^53)
_EXACT_POWER = 22  # 10^22 is the largest power of ten that is an exact double
_POWERS = np.array([10.0 ** k for k in range(_EXACT_POWER + 1)])  # exact doubles
_LARGEST = 2.0 ** 52  # a scaled number below this has its fraction in the double: floor(s), s - floor(s) exact


@numba.njit(cache=True)
def _write_number(x, d, powers, out, at):
    """Writes ``x`` with ``d`` decimals into ``out`` from ``at``; returns the end, or -1 where
    Python must do it (not finite, too large, or within rounding error of a half)."""
    if not math.isfinite(x):
        return -1
    s = abs(x) * powers[d]
    if s >= _LARGEST:
        return -1
    whole = math.floor(s)
    frac = s - whole  # exact
    if abs(frac - 0.5) <= 4e-16 * max(s, 1.0):  # the exact product may lie on the other side of the half
        return -1
    n = np.int64(whole) + (1 if frac > 0.5 else 0)
    if math.copysign(1.0, x) < 0:
        out[at] = 45  # '-'
        at += 1
    scale = np.int64(powers[d])
    head, tail = n // scale, n % scale
    digits = 1
    while head >= np.int64(10) ** digits:
        digits += 1
    for k in range(digits - 1, -1, -1):
        out[at + k] = 48 + head % 10
        head //= 10
    at += digits
    if d > 0:
        out[at] = 46  # '.'
        for k in range(d, 0, -1):
            out[at + k] = 48 + tail % 10
            tail //= 10
        at += d + 1
    return at


@numba.njit(cache=True)
def _fixed_rows(values, decimals, powers, prefix, sep, out, ends, odd):
    at = 0
    for i in range(values.shape[0]):
        start = at
        for c in prefix:
            out[at] = c
            at += 1
        for j in range(values.shape[1]):
            if j > 0:
                for c in sep:
                    out[at] = c
                    at += 1
            at = _write_number(values[i, j], decimals[j], powers, out, at)
            if at < 0:
                odd[i] = True
                at = start
                break
        if not odd[i]:
            out[at] = 10  # '\n'
            at += 1
        ends[i + 1] = at
    return at


def row_text(row, decimals, prefix: str, sep: str) -> str:
    """Python's line of one row (what :func:`fixed_rows` leaves to Python where ``odd``)."""
    return prefix + sep.join(f"{v:.{d}f}" for v, d in zip(row, decimals)) + "\n"


def fixed_rows(values, decimals, prefix: str, sep: str) -> tuple[bytes, np.ndarray, np.ndarray]:
    """``(text, ends, odd)``: row i of ``values (n, m)`` as the ASCII line
    ``prefix + sep.join(f"{v:.{d}f}" for v, d in zip(row, decimals)) + "\\n"`` in
    ``text[ends[i]:ends[i + 1]]`` (``ends (n + 1,)``), empty where ``odd[i]`` (``(n,)`` bool): a
    number of that row is for Python to write (:func:`row_text`). ``decimals (m,)``: 0 to
    :data:`MAX_DECIMALS`."""
    decimals = np.asarray(decimals, np.int64)
    values = np.ascontiguousarray(values, np.float64).reshape(len(values), len(decimals))
    if len(decimals) and not 0 <= decimals.min() <= decimals.max() <= MAX_DECIMALS:
        raise ValueError(f"decimals: 0 to {MAX_DECIMALS}")
    p, s = np.frombuffer(prefix.encode("ascii"), np.uint8), np.frombuffer(sep.encode("ascii"), np.uint8)
    width = len(p) + 1 + values.shape[1] * (len(s) + 18 + int(decimals.max(initial=0)))
    out = np.empty(len(values) * width, np.uint8)
    ends = np.zeros(len(values) + 1, np.int64)
    odd = np.zeros(len(values), bool)
    n = _fixed_rows(values, decimals, _POWERS, p, s, out, ends, odd)
    return out[:n].tobytes(), ends, odd


@numba.njit(cache=True)
def _read_fixed(text, powers, out):
    """The comma-separated numbers of ``text`` (ASCII bytes) into ``out``; returns how many, or
    -1 where one is not ``[spaces][-|+]digits[.digits][spaces]`` with at most 15 digits (and at
    most 22 after the point), or there are more than ``out`` holds."""
    n = 0
    i = 0
    size = text.shape[0]
    while True:
        while i < size and text[i] == 32:
            i += 1
        neg = False
        if i < size and (text[i] == 45 or text[i] == 43):
            neg = text[i] == 45
            i += 1
        m = 0
        seen = False  # a digit at all
        digits = 0  # significant ones (m's)
        decimals = 0
        point = False
        while i < size:
            c = text[i]
            if 48 <= c <= 57:
                seen = True
                if digits > 0 or c != 48:
                    digits += 1
                m = m * 10 + (c - 48)
                if point:
                    decimals += 1
            elif c == 46 and not point:
                point = True
            else:
                break
            i += 1
        while i < size and text[i] == 32:
            i += 1
        if not seen or digits > _EXACT_DIGITS or decimals > _EXACT_POWER or n >= out.shape[0]:
            return -1
        if i < size and text[i] != 44:
            return -1
        v = m / powers[decimals]  # both exact: the quotient is the decimal's correctly rounded double
        out[n] = -v if neg else v
        n += 1
        if i >= size:
            return n
        i += 1


def read_fixed(text: str, count: int):
    """``(count,)`` float64: the comma-separated numbers of ``text``, each the double Python's
    ``float`` gives, or None where one is not a plain fixed-point decimal of at most 15 digits
    (then Python must read them) or there are not ``count`` of them."""
    try:
        raw = np.frombuffer(text.encode("ascii"), np.uint8)
    except UnicodeEncodeError:
        return None
    out = np.empty(count)
    n = _read_fixed(raw, _POWERS, out)
    return out if n == count else None
