"""Runs too large for the memory refuse in one line, with the estimate and what to change; what
the garbage collector looks at while an operation runs."""
import contextlib
import os

import numpy as np
import pytest

from meshmill import memory
from meshmill.errors import InputError

DATA = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "src", "meshmill", "data")


def test_available_memory_is_read_and_a_large_estimate_refused():
    avail = memory.available_bytes()
    assert 1 << 20 < avail < 1 << 50
    memory.check(0.5 * avail, "half", "nothing")
    with pytest.raises(InputError, match=r"need about 1\.5 GB of memory, 1 GB is available: use a larger --step"):
        memory.check(1.5 * (1 << 30), "the lines", "use a larger --step", available=1 << 30)


def _block_and_move(tmp_path, tools_file, z):
    """``(part, cl)``: a 400 x 400 x 100 mm block's STL and a CL file of one 100 m move along X at
    height ``z`` from the block's corner (a billion poses 0.1 µm apart)."""
    import trimesh

    from meshmill.geometry.shapes import box
    from meshmill.toolpath.cldata import write_apt
    from meshmill.toolpath.model import Toolpath
    from meshmill.tools.table import load_tools

    b = box([0, 0, 0], [400, 400, 100])
    part = tmp_path / "block.stl"
    trimesh.Trimesh(b.vertices, b.faces, process=False).export(part)
    cl = tmp_path / "p.cl"
    tip = np.array([[0, 0, z], [100_000, 0, z]])
    write_apt(cl, Toolpath(tip, np.tile([0, 0, 1.0], (2, 1)), np.array([True, False]), np.zeros(2, int)),
              load_tools(tools_file))
    return part, cl


@pytest.mark.parametrize("argv, option", [
    (["verify", "{part}", "{cl}", "--tools", "{tools}", "--step", "0.0001"], "--step"),
    (["dexel", "{part}", "--step", "0.0005", "--out", "{out}.npz"], "--step"),
    (["raster", "{part}", "--tools", "{tools}", "--tool", "B6", "--stepover", "0.0001", "--sample", "0.001",
      "--out", "{out}"], "--stepover or --sample"),
    (["waterline", "{part}", "--tools", "{tools}", "--tool", "B6", "--step-down", "5", "--sample", "0.001",
      "--out", "{out}"], "--sample"),
])
def test_commands_refuse_runs_their_memory_cannot_hold(tmp_path, tools_file, capsys, argv, option):
    from meshmill.cli import main

    # along the block's edge, in the material: the poses of a bad move are all measured
    part, cl = _block_and_move(tmp_path, tools_file, 50.0)
    fill = dict(part=part, cl=cl, tools=tools_file, out=tmp_path / "o")
    assert main([a.format(**fill) for a in argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "of memory" in err[0] and "is available" in err[0] and option in err[0]


def test_a_clear_move_is_verified_whatever_its_length_and_the_step(tmp_path, tools_file):
    """Poses are sampled only where they are measured: a 100 m move well over a block is proven
    whole at a 0.1 µm step (a billion poses, were they sampled) and verified OK."""
    from meshmill.cli import main

    part, cl = _block_and_move(tmp_path, tools_file, 200.0)
    assert main(["verify", str(part), str(cl), "--tools", str(tools_file), "--step", "0.0001"]) == 0


def test_objects_alive_when_an_operation_starts_are_left_out_of_collections_until_it_ends():
    """memory.long_lived: inside, what was alive is frozen (a collection does not walk it), a
    cycle made inside is still collected inside; nested blocks (a job's operations) unfreeze only
    when the outermost ends; an API operation runs inside one."""
    import gc
    import weakref

    from meshmill import api, memory

    class Node:
        pass

    assert gc.get_freeze_count() == 0
    with memory.long_lived():
        frozen = gc.get_freeze_count()
        assert frozen > 0
        a, b = Node(), Node()
        a.other, b.other = b, a
        gone = weakref.ref(a)
        del a, b
        gc.collect()
        assert gone() is None  # a cycle made inside the block: collected
        with memory.long_lived():
            pass
        assert gc.get_freeze_count() >= frozen  # the inner block's end unfroze nothing
    assert gc.get_freeze_count() == 0
    seen = []
    original = memory.long_lived

    @contextlib.contextmanager
    def watched():
        with original():
            seen.append(gc.get_freeze_count())
            yield

    memory.long_lived = watched
    try:
        api.load_tools(os.path.join(DATA, "tools.toml"))  # not an operation: no block
        api.load_part(os.path.join(DATA, "vase.stl"))
    finally:
        memory.long_lived = original
    assert len(seen) == 1 and seen[0] > 0 and gc.get_freeze_count() == 0
