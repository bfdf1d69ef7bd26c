"""Drop-height bounds and the lazily filled drop grid of the waterline: exact against dropping every node."""
import numpy as np
import pytest

from meshmill.kernels.bvh import build_bvh
from meshmill.geometry.mesh import Mesh
from meshmill.geometry.shapes import box, revolve
from meshmill.pathing.dropcutter import ToolDrop
from meshmill.pathing.dropgrid import DropGrid, tier_sizes
from meshmill.tools.table import tool_from_entry

TOOLS = {
    "flat": dict(name="F6", type="flat", diameter=6, flute_length=12, gauge_length=30),
    "ball": dict(name="B6", type="ball", diameter=6, flute_length=12, gauge_length=30),
    "bull": dict(name="R6", type="bull", diameter=6, corner_radius=1, flute_length=12, gauge_length=30,
                 holder_diameter=20, holder_length=20),
}


def _part():
    """A stepped cylinder (flat ring at z = 10) beside a box whose top lies at z = 10 too: vertical
    walls, flat facets on a level, and a holder that reaches the box before the cutter does."""
    step = revolve([0, 12, 12, 6, 6, 0], [0, 0, 10, 10, 18, 18], 40)
    blk = box((16.0, -8.0, 0.0), (24.0, 8.0, 10.0))
    v = np.vstack([step.vertices, blk.vertices])
    f = np.vstack([step.faces, blk.faces + len(step.vertices)])
    return Mesh(vertices=v, faces=f.astype(np.int32))


@pytest.mark.parametrize("kind", ["flat", "ball", "bull"])
def test_bounds_hold_around_each_centre(kind):
    m = _part()
    drop = ToolDrop(tool_from_entry(TOOLS[kind], 1, "t"), build_bvh(m.vertices, m.faces), -1.0)
    rng = np.random.default_rng(3)
    centres = rng.uniform([-20, -20], [30, 20], (300, 2))
    for delta in (0.3, 1.2):
        upper, lower = drop.bounds(centres, delta)
        ang = rng.uniform(0, 2 * np.pi, (300, 24))
        rad = delta * np.sqrt(rng.uniform(0, 1, (300, 24)))
        pts = centres[:, None, :] + rad[..., None] * np.stack([np.cos(ang), np.sin(ang)], -1)
        h = drop(pts.reshape(-1, 2)).reshape(300, 24)
        assert np.all(h <= upper[:, None] + 1e-9) and np.all(h >= lower[:, None] - 1e-9)
        assert np.all(lower <= drop(centres) + 1e-9)


@pytest.mark.parametrize("kind", ["flat", "ball", "bull"])
def test_grid_states_equal_dropping_every_node(kind):
    m = _part()
    drop = ToolDrop(tool_from_entry(TOOLS[kind], 1, "t"), build_bvh(m.vertices, m.faces), -1.0)
    xs = np.linspace(-25.0, 35.0, 301)  # 0.2 mm: nodes on x = 16, 24 (the box walls) and on 0
    ys = np.linspace(-20.0, 20.0, 201)
    grid = DropGrid(drop, xs, ys)
    assert len(grid.sizes) == 2  # tiers of 8 and 4 cells: bounds at work
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    full = drop(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape)
    for z in (17.0, 10.0, 9.999, 10.001, 6.0, 0.5, 14.0):  # the flat ring and the box top at 10
        inside = grid.inside(z)
        # a contact on the rim of the cutter, where its side is vertical, moves the height by 1e-8
        # for 1e-16 in xy: only there may two exact computations disagree
        clear = np.abs(full - z) > 1e-6
        assert np.array_equal(inside[clear], full[clear] > z), z
        if z == 10.0:  # resting exactly on a flat facet at z is not inside
            on_flat = full == z
            assert on_flat.sum() > 1000 and not inside[on_flat].any()
    assert grid.dropped < full.size  # the bounds decided some blocks
    known = ~np.isnan(grid.heights)
    assert np.allclose(grid.heights[known], full[known], rtol=0, atol=1e-6)


def test_tier_sizes():
    assert tier_sizes(0.5, 3.0) == [4]
    assert tier_sizes(0.1, 3.0) == [16, 8, 4]
    assert tier_sizes(1.0, 3.0) == []


@pytest.mark.parametrize("kind", ["flat", "ball", "bull"])
def test_touch_points_converge_on_long_brackets(kind):
    # levels just under flat tops (the inside end barely above z, the outside end far below) and
    # brackets up to 4 mm long: the search must still end on the outside within 1e-4 mm of the level set
    m = _part()
    tool = tool_from_entry(TOOLS[kind], 1, "t")
    drop = ToolDrop(tool, build_bvh(m.vertices, m.faces), -1.0)
    rng = np.random.default_rng(5)
    for length in (0.5, 4.0):
        for z in (18 - 1e-9, 10 - 1e-7, 6.0):
            a = rng.uniform([-18, -18], [30, 18], (4000, 2))
            ang = rng.uniform(0, 2 * np.pi, len(a))
            u = np.column_stack([np.cos(ang), np.sin(ang)])
            b = a + length * u
            fa, fb = drop(a) - z, drop(b) - z
            ok = (fa > 0) & (fb <= 0)
            a, b, u, fa, fb = a[ok], b[ok], u[ok], fa[ok], fb[ok]
            out = drop.touch(a, b, fa, fb, z)
            fo = drop(out) - z
            assert np.all(fo <= 0.0)
            back = np.linspace(0.0, 1.0001e-4, 40)
            fv = drop((out[:, None] - back[None, :, None] * u[:, None]).reshape(-1, 2)).reshape(len(a), -1) - z
            assert np.all((fo >= -1e-6) | (fv > 0).any(axis=1)), (length, z)
