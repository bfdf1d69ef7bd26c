"""Interrupts and exits, as a user meets them: Ctrl-C (SIGINT to the whole process group, as a
terminal sends it) at any moment of a command, a job or a run on a cluster ends with one line,
``meshmill: interrupted``, exit code 130 and no result left that could pass for this run's; a
run that has written its result exits at once."""
import os
import signal
import subprocess
import sys
import time

import pytest

import meshmill

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(ROOT, "src", "meshmill", "data")
MESHMILL = [sys.executable, "-c", "from meshmill.cli import entry; entry()"]


@pytest.fixture(scope="module")
def path(tmp_path_factory):
    """A raster of the vase written as a CL file (what simulate cuts)."""
    folder = tmp_path_factory.mktemp("path")
    part, tools = meshmill.load_part(os.path.join(DATA, "vase.stl")), meshmill.load_tools(os.path.join(DATA, "tools.toml"))
    meshmill.raster(part, tools, tool="B4", stepover=1.0, device="cpu").save(folder)
    return str(folder / "toolpath.cl")


def interrupted(argv, when, env=None):
    """Run ``meshmill argv`` in a session of its own, send SIGINT to its process group ``when``
    (seconds after the start, or the text of a progress line after which to send it), and
    return ``(returncode, stderr lines, whether the signal was sent)``."""
    p = subprocess.Popen([*MESHMILL, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True, env={**os.environ, **(env or {})})
    sent, lines = False, []
    if isinstance(when, str):
        for line in p.stderr:  # progress lines, as they come
            lines.append(line.rstrip("\n"))
            if when in line:
                os.killpg(p.pid, signal.SIGINT)
                sent = True
                break
    else:
        try:
            p.wait(timeout=when)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGINT)
            sent = True
    _, err = p.communicate(timeout=120)
    return p.returncode, lines + err.splitlines(), sent


def ends_interrupted(rc, lines, sent):
    """Interrupted cleanly: 130 and one line of ours (no traceback), or finished before the signal."""
    text = "\n".join(lines)
    assert "Traceback" not in text and "Error" not in text.replace("meshmill: error", ""), text[-3000:]
    if sent and rc != 0:
        assert rc == 130 and lines[-1] == "meshmill: interrupted", (rc, text[-2000:])
    return rc == 130


@pytest.mark.slow
def test_ctrl_c_at_any_moment_of_a_command(path, tmp_path):
    out = tmp_path / "sim"
    argv = ["simulate", "--design", os.path.join(DATA, "vase.stl"), "--toolpath", path, "--tools",
            os.path.join(DATA, "tools.toml"), "--step", "0.2", "--out", str(out)]
    # a complete earlier result, which must not survive as this run's
    assert subprocess.run([*MESHMILL, *argv, "--quiet"], capture_output=True).returncode in (0, 1)
    assert (out / "summary.json").exists()
    stopped = 0
    # while starting (imports: trimesh's catch BaseException), loading, and inside the numba kernels
    for when in (0.3, 0.9, 1.6, "design: ", "cutting ", 2.5):
        rc, lines, sent = interrupted(argv, when)
        stopped += ends_interrupted(rc, lines, sent)
        if rc == 130:
            assert not any(os.path.exists(out / n) for n in ("summary.json", "deviation.json", "machined.stl")), when
    assert stopped >= 5
    # into folders that were not there: they go again with the run
    rc, lines, sent = interrupted([*argv[:-1], str(tmp_path / "new" / "sim")], "cutting ")
    assert sent and ends_interrupted(rc, lines, sent) and not (tmp_path / "new").exists()


def test_a_run_that_fails_leaves_no_folder_it_made(tmp_path):
    from meshmill.cli import main

    bad = tmp_path / "bad.cl"
    bad.write_text("GOTO/abc\n")  # refused once the run has begun (its output folder made)
    out = tmp_path / "new" / "sim"
    argv = ["simulate", "--design", os.path.join(DATA, "vase.stl"), "--toolpath", str(bad), "--tools",
            os.path.join(DATA, "tools.toml"), "--step", "0.5", "--out", str(out)]
    assert main(argv) == 2
    assert not (tmp_path / "new").exists()
    out.mkdir(parents=True)
    (out / "notes.txt").write_text("mine")  # a folder that was there, with a file of the user's, stays
    assert main(argv) == 2
    assert os.listdir(out) == ["notes.txt"]


@pytest.mark.slow
def test_ctrl_c_stops_a_job_and_leaves_none_of_its_files(tmp_path):
    out = tmp_path / "job"
    argv = ["job", os.path.join(DATA, "vase-job.toml"), "--out", str(out), "--no-report"]
    (out / "01-rough").mkdir(parents=True)  # an earlier job's results
    for name in ("job.json", "program.nc"):
        (out / name).write_text("{}")
    (out / "01-rough" / "summary.json").write_text("{}")
    for when in ("the in-process stock", "operation 1 (rough): verify", "operation 6 (semi-finish): waterline"):
        rc, lines, sent = interrupted(argv, when)
        assert sent and ends_interrupted(rc, lines, sent)
        assert sorted(os.listdir(out)) == [], when  # the earlier job's went at the start; nothing of this one


@pytest.mark.slow
def test_ctrl_c_on_a_cluster_is_one_line_too(path, tmp_path):
    pytest.importorskip("distributed")
    argv = ["simulate", "--design", os.path.join(DATA, "vase.stl"), "--toolpath", path, "--tools",
            os.path.join(DATA, "tools.toml"), "--step", "0.5", "--workers", "2", "--out", str(tmp_path / "sim")]
    for when in (1.2, "cutting "):  # while the workers start (born ignoring SIGINT), and while they cut
        rc, lines, sent = interrupted(argv, when)
        assert ends_interrupted(rc, lines, sent) or not sent


def test_a_finished_run_exits_at_once(path, tmp_path):
    """The result written, the process is gone: no thread pool (numba's, Dask's) keeps it alive."""
    argv = ["simulate", "--design", os.path.join(DATA, "vase.stl"), "--toolpath", path, "--tools",
            os.path.join(DATA, "tools.toml"), "--step", "1.0", "--outputs", "summary", "--out", str(tmp_path / "s")]
    for _ in range(3):
        p = subprocess.Popen([*MESHMILL, *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for line in p.stderr:
            if line.startswith("wrote "):
                t = time.perf_counter()
                break
        p.wait(timeout=60)
        assert p.returncode in (0, 1) and time.perf_counter() - t < 2.0


def test_the_threading_layer_is_pinned_to_one_that_shuts_down():
    code = ("import numpy as np, numba\nimport meshmill.kernels\n"
            "from meshmill.simulation.dexel import dexelize\nfrom meshmill.geometry.shapes import box\n"
            "dexelize(box((0, 0, 0), (1, 1, 1)), 0.25)\nprint(numba.threading_layer())")
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_THREADING_LAYER")}
    layer = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout
    assert layer.strip() in ("omp", "workqueue")


def _sigint_at_start(queue):
    queue.put(signal.getsignal(signal.SIGINT))


def test_the_cluster_workers_are_born_ignoring_sigint():
    """A worker cannot be interrupted while it imports (and print its traceback): a spawned
    Python starts with an empty signal mask, so blocking SIGINT here would not reach it."""
    import multiprocessing

    from meshmill import cluster

    ctx = multiprocessing.get_context("spawn")
    queue = ctx.Queue()
    python = multiprocessing.spawn.get_executable()
    with cluster._python_ignoring_sigint() as wrapper:
        assert wrapper is not None
        with cluster._spawning(wrapper):
            child = ctx.Process(target=_sigint_at_start, args=(queue,))
            child.start()
        assert queue.get(timeout=60) == signal.SIG_IGN
        child.join(timeout=60)
    assert child.exitcode == 0 and multiprocessing.spawn.get_executable() == python
    assert signal.getsignal(signal.SIGINT) is not signal.SIG_IGN  # this process keeps its own


def test_blocks_that_must_not_be_cut_short_nest_and_raise_once_the_last_ends():
    import threading

    from meshmill import runfiles

    said, before = [False], runfiles.interrupted[0]
    runfiles.interrupted[0] = lambda: said[0]
    try:
        with pytest.raises(KeyboardInterrupt):
            with runfiles.uninterrupted():
                with runfiles.uninterrupted():
                    said[0] = True  # a Ctrl-C came while both were held
                assert runfiles.held[0] == 1  # the inner block's end raises nothing: the outer still holds
            raise AssertionError("not reached")
        assert runfiles.held[0] == 0
        raised = []

        def other():  # another thread's block never raises the main thread's interrupt
            try:
                with runfiles.uninterrupted():
                    pass
            except KeyboardInterrupt:
                raised.append(True)

        t = threading.Thread(target=other)
        t.start()
        t.join()
        assert not raised and runfiles.held[0] == 0
    finally:
        runfiles.interrupted[0] = before


def test_a_ctrl_c_where_python_would_drop_the_exception_is_remembered_for_the_next_stage():
    """A SIGINT that lands in a ``__del__``, a weak reference's callback (the import system's
    module locks: CI saw "Exception ignored in: <function _get_module_lock.<locals>.cb>" and a
    traceback) or a finaliser raises nothing there (it would be printed and dropped) but is kept."""
    import gc
    import weakref

    from meshmill import cli

    namespace = {"signal": signal}
    # the import system's callback, as Python's frozen module names it
    exec(compile("def cb(ref):\n    signal.raise_signal(signal.SIGINT)\n    sum(range(10))\n",
                 "<frozen importlib._bootstrap>", "exec"), namespace)

    class Dying:
        def __del__(self):
            signal.raise_signal(signal.SIGINT)
            sum(range(10))  # the handler runs between bytecodes: here at the latest

    class Target:
        pass

    def by_del():
        Dying()

    def by_weakref_callback():
        t, kept = Target(), []
        kept.append(weakref.ref(t, namespace["cb"]))  # the reference outlives t: its callback runs
        del t

    def by_finalizer():
        t = Target()
        weakref.finalize(t, lambda: (signal.raise_signal(signal.SIGINT), sum(range(10))))
        del t

    dropped, hook, state = [], sys.unraisablehook, (cli._interrupted[0], cli._finished[0])
    previous = signal.signal(signal.SIGINT, cli._on_interrupt)
    sys.unraisablehook = dropped.append
    try:
        for how in (by_del, by_weakref_callback, by_finalizer):
            cli._interrupted[0] = cli._finished[0] = False
            how()
            gc.collect()
            assert cli._interrupted[0], how.__name__
            assert not dropped, (how.__name__, [d.exc_type for d in dropped])
        cli._interrupted[0] = False
        with pytest.raises(KeyboardInterrupt):  # anywhere else, at once
            signal.raise_signal(signal.SIGINT)
            sum(range(10))
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook
        cli._interrupted[0], cli._finished[0] = state


def test_a_ctrl_c_that_python_drops_anywhere_else_is_not_printed_and_still_remembered():
    """Where :func:`cli._in_callback` does not know the place (any weak reference's callback of
    ours, here), the handler raises, Python drops the KeyboardInterrupt through
    ``sys.unraisablehook``: the command's hook keeps it quiet (it is remembered); other dropped
    exceptions, and a KeyboardInterrupt that is not a Ctrl-C of the command, are still told."""
    import gc
    import weakref

    from meshmill import cli

    class Target:
        pass

    class Failing:
        def __del__(self):
            raise ValueError("not an interrupt")

    def on_gone(ref):
        signal.raise_signal(signal.SIGINT)
        sum(range(10))

    told, hook, state = [], sys.unraisablehook, (cli._interrupted[0], cli._finished[0])
    previous = signal.signal(signal.SIGINT, cli._on_interrupt)
    sys.unraisablehook = cli._quiet_interrupts(told.append)
    try:
        cli._interrupted[0] = cli._finished[0] = False
        t, kept = Target(), []
        kept.append(weakref.ref(t, on_gone))
        del t
        gc.collect()
        assert cli._interrupted[0] and not told
        Failing()
        gc.collect()
        assert [d.exc_type for d in told] == [ValueError]
        cli._interrupted[0] = False

        class Interrupting:
            def __del__(self):
                raise KeyboardInterrupt

        Interrupting()
        gc.collect()
        assert [d.exc_type for d in told] == [ValueError, KeyboardInterrupt]
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook
        cli._interrupted[0], cli._finished[0] = state
