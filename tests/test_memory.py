"""Runs too large for the memory refuse in one line, with the estimate and what to change."""
import numpy as np
import pytest

from meshmill import memory
from meshmill.errors import InputError


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
