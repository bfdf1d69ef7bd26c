"""Casting dexels on the GPU gives the CPU's dexels."""
import numpy as np
import pytest
from parity import same

from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.geometry.shapes import box, sphere
from meshmill.simulation.dexel import dexelize


def shifted_sphere():
    """A coarse sphere off the dexel grid."""
    s = sphere(5.0, rings=6, segments=10)
    return mesh_from_arrays(s.vertices + np.random.default_rng(2).uniform(-1, 1, 3), s.faces, "s")


@pytest.mark.parametrize("make", [lambda: box((0, 0, 0), (4, 3, 2)), shifted_sphere], ids=["box", "sphere"])
def test_dexel_casting_matches_cpu(make):
    m = make()
    a = dexelize(m, 1.0)
    b = dexelize(m, 1.0, device="cuda")
    for k in range(3):
        assert same(a.start[k], b.start[k]), k
        assert same(a.iv[k], b.iv[k]), k
