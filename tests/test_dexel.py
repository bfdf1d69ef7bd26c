"""Triple-dexel models: volumes of analytic solids, exact lines through edges and vertices, the
seed's partitions against the BVH, files."""
import math

import numpy as np
import pytest

from meshmill.errors import InputError
from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.geometry.shapes import box, sphere
from meshmill.kernels.cpu_dexel import cast_lines
from meshmill.simulation import partition
from meshmill.simulation.dexel import dexelize, export_td, load_npz, save_npz


def torus(R, r, n_major=360, n_minor=180):
    """Closed torus about Z, wound outward."""
    a = 2 * np.pi * np.arange(n_major) / n_major
    b = 2 * np.pi * np.arange(n_minor) / n_minor
    A, B = np.meshgrid(a, b, indexing="ij")
    V = np.stack([(R + r * np.cos(B)) * np.cos(A), (R + r * np.cos(B)) * np.sin(A), r * np.sin(B)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_major), np.arange(n_minor), indexing="ij")
    p = i * n_minor + j
    q = ((i + 1) % n_major) * n_minor + j
    pn = i * n_minor + (j + 1) % n_minor
    qn = ((i + 1) % n_major) * n_minor + (j + 1) % n_minor
    F = np.concatenate([np.stack([p, q, qn], -1).reshape(-1, 3), np.stack([p, qn, pn], -1).reshape(-1, 3)])
    return mesh_from_arrays(V, F, "torus")


def mesh_volume(m):
    tri = m.vertices[m.faces]
    return np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6


@pytest.mark.slow
def test_sphere_and_torus_volumes_at_0_3mm():
    s = dexelize(sphere(10.0, rings=180, segments=360), 0.3)
    exact = 4 / 3 * math.pi * 1000
    assert abs(s.volume / exact - 1) < 3e-3
    assert np.all(np.abs(s.volumes() / exact - 1) < 3e-3)
    t = torus(12.0, 4.0)
    d = dexelize(t, 0.3)
    exact = 2 * math.pi ** 2 * 12.0 * 16.0
    assert abs(d.volume / exact - 1) < 3e-3
    assert np.all(np.abs(d.volumes() / exact - 1) < 3e-3)
    # converges to the mesh's own volume as the step shrinks
    assert abs(dexelize(t, 0.1).volume / mesh_volume(t) - 1) < 5e-4


def fan_cube():
    """Cube [0,10]^3 whose top is a fan of 4 triangles around (5, 5, 10) and whose other faces are
    split along a diagonal."""
    V = [[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0], [0, 0, 10], [10, 0, 10], [10, 10, 10], [0, 10, 10],
         [5, 5, 10]]
    F = [[0, 2, 1], [0, 3, 2],  # bottom
         [4, 5, 8], [5, 6, 8], [6, 7, 8], [7, 4, 8],  # top fan
         [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]
    return mesh_from_arrays(np.array(V, float), np.array(F), "cube")


@pytest.mark.parametrize("step", [1.0, 0.5, 2.5])
def test_lines_through_vertices_edges_and_faces(step):
    m = fan_cube()
    tris = np.ascontiguousarray(m.vertices[m.faces].reshape(-1, 9))
    lo, hi, start, t = partition.partition_index(tris, np.zeros(len(tris), np.int64))
    # lines at -step, 0, step, ..., 10 + step: through the vertices, the fan's and the faces'
    # diagonals and the cube's edges and side faces
    n = int(round(10 / step)) + 3
    for a in range(3):
        dense, count = cast_lines(a, -1.5 * step, -1.5 * step, step, n, n, ("boxes", (lo, hi, start, t)))
        assert (count >= 0).all()
        c = (np.arange(n) - 1) * step
        U, W = np.meshgrid(c, c, indexing="ij")
        inside = (U > 0) & (U < 10) & (W > 0) & (W < 10)
        border = ((U == 0) | (U == 10)) & (W >= 0) & (W <= 10) | ((W == 0) | (W == 10)) & (U >= 0) & (U <= 10)
        cnt = count.reshape(n, n)
        assert (cnt[inside] == 1).all()
        got = dense.reshape(n, n, -1, 2)[inside][:, 0]
        np.testing.assert_array_equal(got, np.tile([0.0, 10.0], (len(got), 1)))
        assert (cnt[~inside & ~border] == 0).all()
        # a line in the plane of a side face is in or out as a whole, never cut short
        full = dense.reshape(n, n, -1, 2)[border & (cnt == 1)][:, 0]
        np.testing.assert_array_equal(full, np.tile([0.0, 10.0], (len(full), 1)))
        assert (cnt[border] <= 1).all()


def brute_intervals(tris, a, u0, v0):
    """Reference: Moller-Trumbore with a tolerance for one line in general position."""
    d = np.zeros(3)
    d[a] = 1.0
    o = np.zeros(3)
    o[(a + 1) % 3], o[(a + 2) % 3] = u0, v0
    o[a] = -1e3
    v0_, v1, v2 = tris[:, 0:3], tris[:, 3:6], tris[:, 6:9]
    e1, e2 = v1 - v0_, v2 - v0_
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-15
    inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
    tv = o - v0_
    u = np.einsum("ij,ij->i", tv, p) * inv
    q = np.cross(tv, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1)
    w = np.sort(t[hit] + o[a])
    return w.reshape(-1, 2)


def test_bvh_matches_brute_force_in_general_position():
    rng = np.random.default_rng(3)
    m = sphere(7.0, rings=12, segments=17)
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    m = mesh_from_arrays(m.vertices @ rot.T + [0.3, -0.2, 0.1], m.faces, "tilted")
    d = dexelize(m, 0.37)
    tris = m.vertices[m.faces].reshape(-1, 9)
    for a in range(3):
        nu, nv = d.shape(a)
        for line in rng.choice(nu * nv, 200, replace=False):
            u0 = d.lo[(a + 1) % 3] + (line // nv + 0.5) * d.step
            v0 = d.lo[(a + 2) % 3] + (line % nv + 0.5) * d.step
            ref = brute_intervals(tris, a, u0, v0)
            got = d.iv[a][d.start[a][line]:d.start[a][line + 1]]
            np.testing.assert_allclose(got, ref, atol=1e-9)


@pytest.mark.parametrize("index, k", [("cells", 1), ("cells", 8), ("cells", 12), ("kmeans", 5), ("kmeans", 27)])
def test_partitions_give_the_bvh_model(index, k):
    m = sphere(6.0, rings=20, segments=40)
    ref = dexelize(m, 0.25)
    d = dexelize(m, 0.25, index=index, partitions=k)
    for a in range(3):
        np.testing.assert_array_equal(d.start[a], ref.start[a])
        np.testing.assert_array_equal(d.iv[a], ref.iv[a])
    assert d.info["partitions"] == k


def test_overlap_and_cell_layout():
    lo = np.array([[0, 0, 0], [5, 0, 0], [20, 20, 20]], float)
    hi = np.array([[10, 10, 10], [8, 2, 3], [21, 21, 21]], float)
    assert partition.total_overlap(lo, hi) == pytest.approx(3 * 2 * 3)  # nested box counted exactly
    assert partition.cell_counts(12, [40, 20, 20]) == (3, 2, 2)
    assert partition.cell_counts(8, [1, 1, 1]) == (2, 2, 2)
    assert partition.cell_counts(2, [1, 5, 1]) == (1, 2, 1)


def test_k_optimal_table():
    m = sphere(6.0, rings=20, segments=40)
    tris = m.vertices[m.faces].reshape(-1, 9)
    d = dexelize(m, 0.5)
    k, rows = partition.k_optimal(tris, d.lo, d.step, d.n, 6)
    assert [r["K"] for r in rows] == list(range(1, 7)) and rows[0]["overlap_mm3"] == 0
    assert k == min(rows, key=lambda r: r["line_tests"])["K"] and k > 1


def test_open_and_inconsistent_meshes_hold_the_solid_they_bound():
    from meshmill.simulation.dexel import uneven_lines_warning

    # a box with a triangle missing: a solid with a hole, closed across it
    b = box((0, 0, 0), (1, 1, 1))
    open_box = mesh_from_arrays(b.vertices, b.faces[:-1], "open")
    holed = dexelize(open_box, 0.1)
    assert np.allclose(holed.volumes(), 1.0, atol=1e-9)
    assert not uneven_lines_warning(holed.info.get("uneven_lines"), open_box)
    # an open sheet: what lies below it down to the bottom of the bounds (here 2 mm under it)
    sheet = mesh_from_arrays(np.array([[0, 0, 5], [4, 0, 5], [4, 3, 5], [0, 3, 5.0]]), np.array([[0, 1, 2], [0, 2, 3]]),
                             "sheet")
    d = dexelize(sheet, 0.25, bounds=np.array([[0, 0, 3.0], [4, 3, 5]]))
    assert np.allclose(d.volumes(), 4 * 3 * 2, atol=1e-9)
    assert not uneven_lines_warning(d.info.get("uneven_lines") or {"X": 1}, sheet)  # a sheet's lines graze by design
    # a closed box and, poking out of it, a small one wound inside out (it takes material away,
    # as its winding says): lines through it do not balance, and are decided point by point
    small = box((8, 4, 4), (12, 6, 6))
    a = box((0, 0, 0), (10, 10, 10))
    m = mesh_from_arrays(np.vstack([a.vertices, small.vertices]), np.vstack([a.faces, small.faces[:, ::-1] + 8]),
                         "inverted")
    d = dexelize(m, 0.5)
    assert d.info["uneven_lines"]["X"] > 0
    assert "self-intersecting or overlapping" in uneven_lines_warning(d.info.get("uneven_lines"), m)[0]
    assert np.allclose(d.volumes(), 1000 - 8, atol=1e-9)


def test_sheets_over_sheets_hold_the_material_verification_takes():
    """A sheet over a smaller one (a nose's top and its underside, taken apart): the solid holds
    the points under an odd number of sheet faces, so the lower sheet takes away what lies under
    it. The volumes the sheets' curtains enclose, counted by winding, hold it twice: every line
    must count it once, as the solid's inside test does (a line through it along X took it for
    material, and simulate reported a gouge of 7 mm on mount_rush.stl there)."""
    from meshmill.kernels.backend import solid_kernels

    quad = np.array([[0, 1, 2], [0, 2, 3]])
    top = np.array([[0, 0, 5], [4, 0, 5], [4, 3, 5], [0, 3, 5.0]])
    under = np.array([[1, 0, 3], [3, 0, 3], [3, 3, 3], [1, 3, 3.0]])
    m = mesh_from_arrays(np.vstack([top, under]), np.vstack([quad, quad + 4]), "two sheets")
    d = dexelize(m, 0.25, bounds=np.array([[0, 0, 0.0], [4, 3, 5]]))
    assert np.allclose(d.volumes(), 4 * 3 * 5 - 2 * 3 * 3, atol=1e-9)
    kern = solid_kernels(m, "cpu", 0.0)
    assert not kern.points_inside(np.array([[2.0, 1.5, 2.0]]))[0] and kern.points_inside(np.array([[2.0, 1.5, 4.0]]))[0]


def test_files_round_trip(tmp_path):
    d = dexelize(box((0, 0, 0), (3, 2, 1)), 0.5)
    d.name = "blk"
    save_npz(tmp_path / "m.npz", d)
    back = load_npz(tmp_path / "m.npz")
    assert back.name == "blk" and back.step == 0.5
    for a in range(3):
        np.testing.assert_array_equal(back.iv[a], d.iv[a])
    export_td(tmp_path / "m.td", d)
    lines = (tmp_path / "m.td").read_text().splitlines()
    assert lines[0] == "# TD v1" and lines[6] == f"dexels {sum(len(v) for v in d.iv)}"
    assert len(lines) == 7 + sum(len(v) for v in d.iv) and lines[7].startswith("X ")
    (tmp_path / "bad.npz").write_bytes(b"nope")
    with pytest.raises(InputError, match="not a meshmill dexel file"):
        load_npz(tmp_path / "bad.npz")
