"""Verification of the successive versions of a path (the repair rounds of finish, raster and
waterline): a move the version before had as well (the same two points, axes, tool and kind,
compared exactly) keeps what was found on it, and only the other moves are checked.

A move's figures depend on its two points alone (:func:`meshmill.pathing.verify.verify_moves`),
so the report is the one a check of the whole path gives, at the cost of the moves that changed.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..toolpath.model import Toolpath
from .verify import merge_reports

_FIGURES = ("poses", "refined", "certified", "max_gouge", "max_collision")


def move_keys(tp: Toolpath) -> np.ndarray:
    """``(k, 15)`` float64: what decides each move's check (the point before and the move's point,
    tips and axes, its tool, whether it is rapid, and whether it is the path's first: move 0 is
    checked from its own point, unlike a later move of length zero)."""
    k = len(tp)
    keys = np.empty((k, 15))
    if not k:
        return keys
    keys[1:, 0:3], keys[1:, 3:6] = tp.tip[:-1], tp.axis[:-1]
    keys[0, 0:3], keys[0, 3:6] = tp.tip[0], tp.axis[0]
    keys[:, 6:9], keys[:, 9:12], keys[:, 12], keys[:, 13] = tp.tip, tp.axis, tp.tool, tp.rapid
    keys[:, 14] = 0.0
    keys[0, 14] = 1.0
    return keys


def _rows(keys: np.ndarray) -> np.ndarray:
    """``(k,)``: each row of ``keys`` as one opaque value (its bytes), compared at once."""
    keys = np.ascontiguousarray(keys)
    return keys.view(np.dtype((np.void, keys.dtype.itemsize * keys.shape[1]))).reshape(-1)


def _hashes(keys: np.ndarray) -> np.ndarray:
    """A 64-bit hash of each row of ``keys`` (matches are compared in full afterwards)."""
    words = np.ascontiguousarray(keys).view(np.uint64)
    h = np.full(len(keys), 1469598103934665603, np.uint64)
    with np.errstate(over="ignore"):
        for j in range(words.shape[1]):
            h = (h ^ words[:, j]) * np.uint64(1099511628211)
            h ^= h >> np.uint64(29)
    return h


class Reverify:
    """Call with each version of a path: ``check(tp, only)`` returns the
    :func:`~meshmill.pathing.verify.verify_moves` parts of the moves where ``only (k,) bool`` is
    set; the report of the whole path is :func:`~meshmill.pathing.verify.merge_reports`'s
    (``tol``, ``step``, ``stock`` summary, ``worst``). ``checked`` counts the moves checked in the
    last call."""

    def __init__(self, check, tol: float, step: float, stock: dict, worst: int = 10):
        self.check, self.tol, self.step, self.stock, self.worst = check, tol, step, stock, worst
        self.keys = self.hashes = None
        self.checked = 0

    def _known(self, keys):
        """For each move of ``keys``, the index of the same move in the last version (-1: new);
        this version's hashes are kept for the next."""
        found = np.full(len(keys), -1, np.int64)
        new_h = _hashes(keys)
        old_h, self.hashes = self.hashes, new_h
        if self.keys is None or not len(self.keys) or not len(keys):
            return found
        order = np.argsort(old_h, kind="stable")
        at = np.minimum(np.searchsorted(old_h[order], new_h), len(order) - 1)
        cand = order[at]
        # the same bytes (stricter than equal floats: -0.0 is not 0.0 here, so checked again)
        same = (old_h[cand] == new_h) & (_rows(self.keys)[cand] == _rows(keys))
        found[same] = cand[same]
        return found

    def __call__(self, tp: Toolpath) -> dict:
        keys = move_keys(tp)
        known = self._known(keys)
        only = known < 0
        self.checked = int(only.sum())
        parts = self.check(tp, only) if only.any() else []
        # the figures of every move of this version: the new ones' from the parts, the others' kept
        fig = {name: np.zeros(len(tp), np.int64 if name in ("poses", "refined", "certified") else float)
               for name in _FIGURES}
        problems, unresolved = {}, set()
        for part in parts:
            f = part["figures"]
            for name in _FIGURES:
                fig[name][f["move"]] = f[name]
            for p in part["problems"]:
                problems.setdefault(p.move, []).append(p)
            unresolved.update(part["unresolved"])
        kept = np.nonzero(~only)[0]
        if len(kept):
            src = known[kept]
            for name in _FIGURES:
                fig[name][kept] = self.figures[name][src]
            flagged = np.array(sorted(set(self.problems) | self.unresolved), np.int64)
            for m, s in zip(kept[np.isin(src, flagged)].tolist(), src[np.isin(src, flagged)].tolist()):
                for p in self.problems.get(s, ()):
                    problems.setdefault(m, []).append(dataclasses.replace(p, move=m, line=int(tp.line[m])))
                if s in self.unresolved:
                    unresolved.add(m)
        self.keys, self.figures, self.problems, self.unresolved = keys, fig, problems, unresolved
        whole = {"poses": int(fig["poses"].sum()), "refined": int(fig["refined"].sum()),
                 "certified": int(fig["certified"].sum()), "max_gouge": float(fig["max_gouge"].max(initial=0.0)),
                 "max_collision": float(fig["max_collision"].max(initial=0.0)),
                 "problems": [p for ps in problems.values() for p in ps], "unresolved": sorted(unresolved)}
        return merge_reports(tp, [whole], self.tol, self.step, self.stock, self.worst)
