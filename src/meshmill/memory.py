"""What a run may hold in memory: the machine's (or its container's) available memory, and a
one-line refusal of a run whose estimate does not fit, instead of a numpy MemoryError or a fixed
count; what Python's cyclic garbage collector looks at while a run goes (:func:`long_lived`).

Every operation estimates its largest arrays from its sizes before it makes them (bytes per item
times items, the figures are beside each call) and calls :func:`check`.
"""
from __future__ import annotations

import contextlib
import gc
import os
import threading

from .errors import InputError

SHARE = 0.8  # of the available memory a run may plan to take
_frozen = [0]  # how many :func:`long_lived` blocks are running
_freezing = threading.Lock()


def available_bytes() -> int:
    """The memory this process can still take, bytes: the kernel's MemAvailable, no more than a
    cgroup's limit less its use, else the physical memory."""
    avail = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            avail = 1 << 34
    for limit_file, usage_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            with open(limit_file) as fh:
                text = fh.read().strip()
            if text == "max":
                continue
            with open(usage_file) as fh:
                used = int(fh.read().strip())
            avail = min(avail, max(0, int(text) - used))
        except (OSError, ValueError):
            continue
    return int(avail)


def size(n: float) -> str:
    """``n`` bytes for a person to read."""
    for unit, k in (("GB", 1 << 30), ("MB", 1 << 20), ("kB", 1 << 10)):
        if n >= k:
            return f"{n / k:.3g} {unit}"
    return f"{n:.0f} B"


def check(need: float, what: str, change: str, params=(), available: int | None = None) -> None:
    """Refuse (``InputError``) a run whose estimate ``need`` (bytes) exceeds ``SHARE`` of the
    available memory, in one line: ``what`` needs it, ``change`` says which options (``params``,
    by name) to change."""
    avail = available_bytes() if available is None else available
    if need > SHARE * avail:
        raise InputError(f"{what} need about {size(need)} of memory, {size(avail)} is available: {change}", params)


@contextlib.contextmanager
def long_lived():
    """A block (an operation) during which the objects alive when it starts are left out of the
    cyclic garbage collector's passes (``gc.freeze``; put back when the outermost such block
    ends). Each full collection walked every object there is: numba's type registries, the part,
    the passes and their caches, hundreds of thousands, a tenth of a second each time, and an
    operation makes millions of short-lived objects: the impeller's finish 1.1 s faster to
    generate, 0.3 s to verify. Objects the block frees are freed as before (by their counts;
    a cycle among the frozen ones waits for the block's end). Blocks may nest or run in several
    threads at once."""
    with _freezing:
        _frozen[0] += 1
        if _frozen[0] == 1:
            gc.freeze()
    try:
        yield
    finally:
        with _freezing:
            _frozen[0] -= 1
            if _frozen[0] == 0:
                gc.unfreeze()
