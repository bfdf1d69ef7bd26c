"""Cutting the dexel stock on the GPU gives the CPU's stock, through tiles that overflow."""
import numpy as np
from parity import same

from meshmill.geometry.shapes import box
from meshmill.simulation import cut as cutting
from meshmill.simulation.dexel import dexelize
from meshmill.tools.table import tool_from_entry
from meshmill.toolpath.model import Toolpath


class Cutter:
    """The cutting part of a tool, as ``toolpath_moves`` reads it."""

    def __init__(self, type, d, r):
        self.type, self.radius, self.corner_radius, self.flute_length, self.name = type, d / 2, r, 2.0, type


def test_cutting_matches_cpu_through_overflow(monkeypatch):
    # no spare room: the slots split lines, so tiles overflow, grow and run again
    monkeypatch.setattr(cutting, "SLACK", 0)
    model = dexelize(box((0, 0, 0), (12, 10, 6)), 1.0)
    tools = [Cutter("ball", 2.0, 1.0), Cutter("bull", 3.0, 0.5), Cutter("flat", 2.0, 0.0)]
    # ball moves (one turning), then a bull-nose and a flat end mill, each with one small turn
    tip = np.array([[2.0, 2.0, 4.0], [10.0, 2.0, 4.0], [10.0, 8.0, 3.0], [2.0, 8.0, 3.5], [2.0, 5.0, 5.0],
                    [4.0, 5.0, 5.0], [6.0, 6.0, 4.5], [8.0, 6.0, 4.5]])
    axis = np.array([[0, 0, 1.0], [0, 0, 1.0], [0.3, 0, 0.95], [0, 0, 1.0], [0, 0, 1.0], [0.05, 0, 1.0],
                     [0, 0, 1.0], [0, 0.05, 1.0]])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    rapid = np.array([True, False, False, False, True, False, True, False])
    tp = Toolpath(tip, axis, rapid, np.array([0, 0, 0, 0, 1, 1, 2, 2]))
    # the shanks (as wide as the cutters) meet the stock where the tools go deeper than their flutes
    real = [tool_from_entry(dict(name=t.type, type=t.type, diameter=2 * t.radius, corner_radius=t.corner_radius,
                                 flute_length=2.0, gauge_length=9.0), k + 1, "t") for k, t in enumerate(tools)]
    moves = cutting.Moves.merge(cutting.toolpath_moves(tp, tools), cutting.body_moves(tp, real))
    stocks, loads = [], []
    for device in ("cpu", "cuda"):
        st = cutting.stock_from_model(model)
        res = cutting.cut(st, moves, device=device, load=len(tp))
        stocks.append((st.to_model(), (res["rapid_cuts"], res["collisions"])))
        loads.append(res["load"])
    (a, ra), (b, rb) = stocks
    assert ra == rb and ra[1], (ra, rb)
    # every move's load: per thread on the CPU, by atomics on the GPU (sums in another order)
    la, lb = loads
    assert (la.volume > 0).sum() >= 4 and np.allclose(la.volume, lb.volume, rtol=1e-12, atol=1e-12)
    for f in ("height", "depth", "across"):
        assert np.array_equal(np.isnan(getattr(la, f)), np.isnan(getattr(lb, f))), f
        assert np.allclose(getattr(la, f), getattr(lb, f), rtol=0, atol=1e-12, equal_nan=True), f
    for k in range(3):
        assert same(a.start[k], b.start[k]) and same(a.iv[k], b.iv[k]), k
    assert sum(len(v) for v in a.iv) > sum(len(v) for v in model.iv)  # the slots split dexels
