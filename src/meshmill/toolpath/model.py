"""The tool-path model shared by every operation: a sequence of moves."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Toolpath:
    """Moves in order. ``tip (k, 3)`` tool tip (mm), ``axis (k, 3)`` unit tool axis (tip to
    spindle), ``rapid (k,) bool``, ``tool (k,) int`` 0-based index into the tool table;
    ``line (k,) int`` source line of each move when read from a file (0 otherwise); ``feed (k,)``
    mm/min, the feed each move is programmed at (NaN where unset: the machine's, or the post's
    ``feed``); ``source``: the file it was read from ("" otherwise), ``warnings``: what its reader noticed."""

    tip: np.ndarray
    axis: np.ndarray
    rapid: np.ndarray
    tool: np.ndarray
    line: np.ndarray | None = None
    feed: np.ndarray | None = None
    source: str = ""
    warnings: list = field(default_factory=list)

    def __post_init__(self):
        if self.line is None:
            self.line = np.zeros(len(self.tip), np.int64)
        if self.feed is None:
            self.feed = np.full(len(self.tip), np.nan)

    def __len__(self):
        return len(self.tip)

    @staticmethod
    def concatenate(parts: list["Toolpath"]) -> "Toolpath":
        if not parts:
            return Toolpath(np.empty((0, 3)), np.empty((0, 3)), np.empty(0, bool), np.empty(0, np.int64))
        return Toolpath(
            tip=np.concatenate([p.tip for p in parts]),
            axis=np.concatenate([p.axis for p in parts]),
            rapid=np.concatenate([p.rapid for p in parts]),
            tool=np.concatenate([p.tool for p in parts]),
            line=np.concatenate([p.line for p in parts]),
            feed=np.concatenate([p.feed for p in parts]),
        )

    def points(self, start: int, stop: int) -> "Toolpath":
        """Points ``start .. stop - 1`` as a Toolpath (the same source)."""
        return Toolpath(self.tip[start:stop], self.axis[start:stop], self.rapid[start:stop], self.tool[start:stop],
                        self.line[start:stop], self.feed[start:stop], self.source)

    def lifted_to(self, z: float) -> "Toolpath":
        """The path starting and ending on the plane ``z``: a rapid down from above its first point
        and a rapid up from its last, along the tool axis (:func:`lift`)."""
        if not len(self):
            return self
        first, last = lift(self.tip[0], self.axis[0], z), lift(self.tip[-1], self.axis[-1], z)
        return Toolpath(np.vstack([first, self.tip, last]), np.vstack([self.axis[:1], self.axis, self.axis[-1:]]),
                        np.r_[True, self.rapid, True], np.r_[self.tool[:1], self.tool, self.tool[-1:]],
                        np.r_[0, self.line, 0], np.r_[np.nan, self.feed, np.nan], self.source, list(self.warnings))

    def cutting_length(self) -> float:
        """Length of the feed moves, mm."""
        if len(self) < 2:
            return 0.0
        seg = np.linalg.norm(np.diff(self.tip, axis=0), axis=1)
        return float(seg[~self.rapid[1:]].sum())


def lift(tip, axis, z):
    """The tip ``(3,)`` moved along ``axis`` up to height ``z`` (or straight up where the axis is flat)."""
    if tip[2] >= z:
        return tip.copy()
    return tip + axis * ((z - tip[2]) / axis[2]) if axis[2] > 1e-6 else np.array([tip[0], tip[1], z])
