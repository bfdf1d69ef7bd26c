"""The files one command writes, all or nothing.

A command names its result files before it computes anything; the results of an earlier run under
those names are removed at once, so that neither a failure nor an interruption leaves a file that
claims to be this run's result. Every file is written under a temporary name beside its final one
(``.NAME.partial-PID.EXT``, the extension kept for writers that choose the format by it) and
renamed into place by :meth:`RunFiles.commit` once all are complete, the summary last. A run that
does not commit leaves nothing behind (:meth:`RunFiles.abort`).
"""
from __future__ import annotations

import contextlib
import os
import threading

from .errors import InputError

# Whether the run was interrupted although no KeyboardInterrupt reached here (a library that
# catches BaseException while it imports can swallow one): the command line sets it; no result
# of an interrupted run is committed.
interrupted = [lambda: False]
# How many blocks a Ctrl-C must not cut short (:func:`uninterrupted`) are running: while any is,
# the command line's SIGINT handler only remembers it.
held = [0]
_holding = threading.Lock()


@contextlib.contextmanager
def uninterrupted():
    """A block a Ctrl-C must not cut short (raised when the last such block ends, in the main
    thread): importing trimesh, whose imports catch BaseException, so that a KeyboardInterrupt
    inside an extension module's initialisation would leave that module half made (and a crash
    when trimesh touches it). Blocks may nest or run in several threads at once."""
    with _holding:
        held[0] += 1
    try:
        yield
    finally:
        with _holding:
            held[0] -= 1
            last = held[0] == 0
    if last and interrupted[0]() and threading.current_thread() is threading.main_thread():
        raise KeyboardInterrupt


class RunFiles:
    """Result files ``paths`` (the summary, if any, last) of one run."""

    def __init__(self, paths):
        self.paths = [os.path.abspath(os.fspath(p)) for p in paths]
        self.partial = {}
        self.done = False
        self.created = []  # the folders this run made (abort removes them while empty)
        for p in self.paths:
            folder = os.path.dirname(p)
            missing = []
            up = folder
            while not os.path.isdir(up) and os.path.dirname(up) != up:
                missing.append(up)
                up = os.path.dirname(up)
            try:
                os.makedirs(folder, exist_ok=True)
            except OSError as exc:
                raise InputError(f"{folder}: cannot create the output folder ({exc.strerror})") from None
            self.created += missing
            if os.path.isdir(p):
                raise InputError(f"{p}: is a folder, not a file to write")
        self.clear()

    def clear(self):
        """Remove what an earlier run left under the final names."""
        for p in self.paths:
            try:
                if os.path.lexists(p):
                    os.remove(p)
            except OSError as exc:
                raise InputError(f"{p}: cannot replace an earlier result ({exc.strerror})") from None

    def tmp(self, path) -> str:
        """The temporary name to write final ``path`` (one of :attr:`paths`) under."""
        final = os.path.abspath(os.fspath(path))
        if final not in self.paths:
            raise ValueError(f"{final} is not a result file of this run")
        folder, name = os.path.split(final)
        stem, ext = os.path.splitext(name)
        part = os.path.join(folder, f".{stem}.partial-{os.getpid()}{ext}")
        self.partial[final] = part
        return part

    def commit(self):
        """Rename every written file into place, in the order of :attr:`paths` (summary last)."""
        if interrupted[0]():
            raise KeyboardInterrupt
        for p in self.paths:
            part = self.partial.get(p)
            if part is not None and os.path.exists(part):
                try:
                    os.replace(part, p)
                except OSError as exc:
                    raise InputError(f"{p}: cannot write ({exc.strerror})") from None
        self.done = True

    def abort(self):
        """Remove the temporary files of a run that did not complete, and the folders it made for
        them where they hold nothing else."""
        for part in self.partial.values():
            try:
                if os.path.exists(part):
                    os.remove(part)
            except OSError:
                pass
        self.partial.clear()
        for folder in sorted(self.created, key=len, reverse=True):  # the deepest first
            try:
                os.rmdir(folder)
            except OSError:  # not empty (or gone)
                pass
