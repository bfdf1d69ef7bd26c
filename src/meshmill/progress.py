"""The progress of a long stage: done in pieces (the same pieces a cluster's workers take), each
finished piece told as a percentage of the stage's work with an estimate of the time left.

A stage's work is split where its kernels are already independent (ranges of moves, groups of
contours, blocks of lattice rows), so doing it piece by piece gives the whole's result; the
pieces are large enough (:data:`PIECES` a stage) for the kernels' threads to stay busy.
"""
from __future__ import annotations

import contextlib
import time

PIECES = 16  # pieces a long stage is done in on one machine
QUIET_S = 1.0  # a stage is told its share only once it has run this long, and then at most this often


def ranges(n: int, pieces: int) -> list[tuple[int, int]]:
    """``pieces`` ranges ``(start, stop)`` of ``0..n`` as even as can be (none empty)."""
    pieces = max(1, min(pieces, n))
    bounds = [round(k * n / pieces) for k in range(pieces + 1)]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a]


class Meter:
    """Tells ``say`` how much of a stage ``what`` is done: ``done(amount)`` after each piece, out
    of ``total`` (moves, points, lines: what the time goes with); a stage shorter than
    :data:`QUIET_S` is not told, a longer one every :data:`QUIET_S` and at its end. The time left
    is told from the second piece on, at the pace since the first ended (a first piece pays for
    what comes once: kernels loaded, caches filled, what the later pieces then skip)."""

    def __init__(self, say, what: str, total: float):
        self.say, self.what, self.total = say, what, float(total)
        self.done_so_far, self.t0, self.told = 0.0, time.perf_counter(), None
        self.first = None  # (time, share) when the first piece ended

    def done(self, amount: float = 1.0) -> None:
        self.done_so_far += amount
        if not self.say or self.total <= 0:
            return
        share = min(1.0, self.done_so_far / self.total)
        now = time.perf_counter()
        first = self.first
        if first is None:
            self.first = (now, share)
        if now - (self.told or self.t0) < QUIET_S and not (share >= 1.0 and self.told):
            return
        self.told = now
        left = ""
        if first is not None and first[1] < share < 1.0:
            left = f", about {(now - first[0]) * (1.0 - share) / (share - first[1]):.0f} s left"
        self.say(f"{self.what}: {100.0 * share:.0f} %{left}")


class StageClock:
    """The stages of an operation in order: ``with clock("contours"):`` tells ``say`` the stage as
    it starts and puts its wall time (s) in ``seconds[key]`` (``key``: default the stage's name)."""

    def __init__(self, say=None):
        self.say = say or (lambda stage: None)
        self.seconds = {}

    @contextlib.contextmanager
    def __call__(self, stage: str, key: str | None = None):
        self.say(stage)
        t = time.perf_counter()
        yield
        self.seconds[key or stage] = time.perf_counter() - t


def in_pieces(func, cuts, say, what: str, weight=None) -> list:
    """``[func(a, b) for (a, b) in cuts]``, telling ``say`` the share done (by ``weight(a, b)``,
    default ``b - a``) and the time left after each piece."""
    weight = weight or (lambda a, b: b - a)
    meter = Meter(say, what, sum(weight(a, b) for a, b in cuts))
    out = []
    for a, b in cuts:
        out.append(func(a, b))
        meter.done(weight(a, b))
    return out
