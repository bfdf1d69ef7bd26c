"""The heavy operations on a Dask cluster (``meshmill[cluster]``): ``--workers N`` starts a
``LocalCluster`` of N single-threaded worker processes on this machine, ``--scheduler ADDRESS``
joins a running one (``dask scheduler`` / ``dask worker``, dask-jobqueue, dask-kubernetes).
Without either nothing here runs and Dask is not imported.

The work is split where the kernels are already independent (pieces of a path, by ranges of
moves); what every piece needs (the part, the tool table) is held on the cluster once
(:func:`share`), and what a worker builds from it (a BVH) is kept there for the next piece
(:func:`worker_cached`). A piece whose worker dies is computed again elsewhere (Dask's retries);
the pieces come back in order, so the result is the one process's.
"""
from __future__ import annotations

import contextlib
import os
import uuid
import warnings

from . import memory
from .errors import InputError
from .progress import Meter

RETRIES = 3  # times a piece is computed again after its worker died
PIECES_PER_WORKER = 4  # pieces a worker gets on average (the slow ones then even out)
_CACHE: dict = {}  # per worker process: what it built from the shared data, by token


@contextlib.contextmanager
def connect(cluster):
    """A ``distributed.Client`` for ``cluster``: None (no cluster: yields None), a number of
    local workers, a scheduler's address (``tcp://host:8786``) or a Client already open; a local
    cluster is closed on leaving."""
    if cluster is None:
        yield None
        return
    try:
        with _sigint_blocked():  # Dask's threads, started now, keep SIGINT blocked
            from distributed import Client, LocalCluster
    except ImportError:
        raise InputError("cluster: a Dask cluster needs Dask: pip install 'meshmill[cluster]'", "cluster") from None
    if isinstance(cluster, Client):
        yield cluster
        return
    if isinstance(cluster, bool) or not isinstance(cluster, (int, str)):
        raise InputError(f"cluster must be a number of workers, a scheduler address or a Client, got {cluster!r}",
                         "cluster")
    if isinstance(cluster, int):
        if cluster < 1:
            raise InputError(f"cluster must be at least 1 worker, got {cluster}", "cluster")
        import logging

        logging.getLogger("distributed").setLevel(logging.ERROR)  # the nannies' notes of workers stopped
        _quiet_resource_tracker()
        with _python_ignoring_sigint() as python:  # Ctrl-C is the command's alone
            with _sigint_blocked(), _spawning(python):
                lc = LocalCluster(n_workers=cluster, threads_per_worker=1, processes=True,
                                  dashboard_address=None, env=worker_env(cluster), preload=[__name__])
            with lc, Client(lc) as client:
                yield client
        return
    try:
        client = Client(cluster, timeout=30)
    except (OSError, TimeoutError) as exc:
        raise InputError(f"cluster {cluster}: cannot reach the scheduler ({exc})", "cluster") from None
    with client:
        yield client


def _quiet_resource_tracker() -> None:
    """Keep multiprocessing's resource tracker (a process of its own, started with this
    environment) from warning of "leaked semaphore objects" when a run with local workers is
    interrupted and exits at once: the warning says nothing a user can act on and comes after the
    command's last line. The processes started from here ignore UserWarnings (a rule naming the
    message or the module would need ``re`` before an interpreter can import it); ours are said
    in the results, not warned."""
    rule = "ignore::UserWarning"
    have = os.environ.get("PYTHONWARNINGS", "")
    if rule not in have.split(","):
        os.environ["PYTHONWARNINGS"] = f"{have},{rule}" if have else rule


@contextlib.contextmanager
def _sigint_blocked():
    """SIGINT blocked in this thread (and so in the threads started meanwhile, which
    keep the mask), and delivered when the block ends if it came meanwhile (on the main thread).
    Processes do not keep it: a spawned Python starts with an empty mask
    (:func:`_python_ignoring_sigint`)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextlib.contextmanager
def _python_ignoring_sigint():
    """The path of a program that runs this Python with SIGINT ignored (None where none can be
    run: not POSIX, or a ``noexec`` /tmp), valid while the block lasts.

    Dask's workers start through it (:func:`_spawning`): a Ctrl-C while one imports would otherwise
    print its traceback. A spawned Python starts with an empty signal mask, so blocking SIGINT
    here does not reach it, and only an ignored disposition survives ``exec`` (a Python started
    so keeps it ignored); ignoring it here instead would lose a Ctrl-C meant for the command (any
    thread of this process may take it). So: a two-line shell script."""
    import multiprocessing.spawn
    import shlex
    import shutil
    import tempfile

    if os.name != "posix" or not os.path.exists("/bin/sh"):
        yield None
        return
    python = os.fsdecode(multiprocessing.spawn.get_executable())
    folder = tempfile.mkdtemp(prefix="meshmill-workers-")
    wrapper = os.path.join(folder, "python")
    try:
        with open(wrapper, "w") as f:
            f.write(f"#!/bin/sh\ntrap '' INT\nexec {shlex.quote(python)} \"$@\"\n")
        os.chmod(wrapper, 0o755)
        yield wrapper if os.access(wrapper, os.X_OK) else None  # not on a noexec mount
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@contextlib.contextmanager
def _spawning(python):
    """multiprocessing's spawned processes run ``python`` while the block lasts (None: as they are)."""
    import multiprocessing.spawn

    if python is None:
        yield
        return
    previous = multiprocessing.spawn.get_executable()
    multiprocessing.spawn.set_executable(python)
    try:
        yield
    finally:
        multiprocessing.spawn.set_executable(previous)


def dask_setup(worker) -> None:
    """In each local worker process (a Dask preload): Ctrl-C in the terminal reaches the whole
    process group, but only the command stops the work (and closes its cluster): the workers
    ignore SIGINT (they are born ignoring it, :func:`_python_ignoring_sigint`; this keeps one Dask
    starts again later from ignoring it too) rather than each print its
    traceback, and keep Dask's notes of the tasks cancelled then to themselves (errors show)."""
    import logging
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.getLogger("distributed").setLevel(logging.ERROR)


def worker_env(n: int) -> dict:
    """The environment of ``n`` local worker processes: numba's kernels share the cores among
    them (each its share; numba would otherwise start a thread per core in every worker)."""
    return {"NUMBA_NUM_THREADS": str(max(1, (os.cpu_count() or 1) // n))}


def workers(client) -> int:
    """How many worker threads the cluster has."""
    return max(1, sum(client.nthreads().values()))


class _Sealed:
    """``value`` carried whole in a task's arguments (Dask does not look into it for futures)."""

    def __init__(self, value):
        self.value = value


def _opened(sealed: _Sealed):
    return sealed.value


def hold(client, value):
    """``value`` held on the cluster as a task's result: a future to pass to tasks, which the
    workers fetch from each other. Should every worker holding it die, the scheduler makes it
    again from the task (data scattered to the workers could not be: Dask's memory manager
    keeps one copy of it, and a dead worker's copy was lost with the tasks waiting on it). The
    scheduler keeps the task, the value with it, until the future is released or cancelled
    (Dask's warning about a large graph is expected here: not said)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Sending large graph")
        return client.submit(_opened, _Sealed(value), pure=False, retries=RETRIES)


def share(client, shared: dict):
    """``shared`` (with a ``token`` for :func:`worker_cached`) held on the cluster (:func:`hold`)."""
    return hold(client, dict(shared, token=uuid.uuid4().hex))


def submit(client, func, *args):
    """``func(*args)`` as a task (retried where its worker dies); futures among ``args`` are the
    results of earlier tasks, which stay on the workers."""
    return client.submit(func, *args, pure=False, retries=RETRIES)


def wait(futures, progress=None, what="pieces") -> None:
    """Wait for every future, telling ``progress`` each time one completes."""
    from distributed import as_completed

    meter = Meter(progress, what, len(futures))
    for _ in as_completed(futures):
        meter.done()


def run_pieces(client, func, shared, pieces, progress=None, what="pieces") -> list:
    """``[func(shared, piece) for piece in pieces]`` on the cluster: ``shared`` held once
    (:func:`share`), the results in the pieces' order; ``progress`` is told each time a piece
    completes."""
    handle = share(client, shared)
    futures = [submit(client, func, handle, piece) for piece in pieces]
    wait(futures, progress, what)
    results = client.gather(futures)
    client.cancel([handle])
    return results


def worker_cached(shared: dict, name: str, build):
    """``build()`` once per worker process for the ``shared`` data: later pieces on the
    same worker reuse it (a BVH, kernels)."""
    key = (shared["token"], name)
    if key not in _CACHE:
        if len(_CACHE) > 16:  # earlier runs' go (this run's stay: its pieces read them again)
            for old in [k for k in _CACHE if k[0] != key[0]]:
                del _CACHE[old]
        _CACHE[key] = build()
    return _CACHE[key]


def worker_memory(client) -> int:
    """The smallest memory limit of the cluster's workers, bytes (0: none is set)."""
    limits = [w.get("memory_limit") or 0 for w in client.scheduler_info()["workers"].values()]
    limits = [x for x in limits if x > 0]
    return min(limits) if limits else 0


def check_workers(client, need: float, what: str, change: str, params=("cluster", "step")) -> None:
    """Refuse, before it starts, work whose estimate ``need`` (bytes per worker) exceeds
    :data:`~meshmill.memory.SHARE` of a worker's memory limit, in one line with the figures."""
    limit = worker_memory(client)
    if limit:
        memory.check(need, f"{what} on each worker", change, params, available=limit)
