"""Mesh input: formats, cleaning and bad files."""
import struct

import numpy as np
import pytest
import trimesh

from meshmill.errors import InputError
from meshmill.geometry.mesh import load_mesh, mesh_from_arrays
from meshmill.geometry.shapes import box, sphere

from conftest import propeller_like

PARTS = __import__("pathlib").Path(__file__).resolve().parents[2] / "shared" / "parts"


def _export(mesh, path):
    trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).export(path)
    return path


@pytest.mark.parametrize("ext", ["stl", "obj", "ply"])
def test_formats_load_the_same_solid(tmp_path, ext):
    s = sphere(5.0, 12, 24)
    m = load_mesh(_export(s, tmp_path / f"s.{ext}"))
    assert m.closed and len(m.faces) == len(s.faces)
    np.testing.assert_allclose(m.bounds, s.bounds, atol=1e-5)


def test_ascii_stl(tmp_path):
    p = tmp_path / "a.stl"
    p.write_bytes(trimesh.exchange.stl.export_stl_ascii(trimesh.Trimesh(box([0, 0, 0], [1, 2, 3]).vertices,
                                                                         box([0, 0, 0], [1, 2, 3]).faces)).encode())
    m = load_mesh(p)
    assert len(m.faces) == 12 and m.closed


@pytest.mark.skipif(not (PARTS / "ktoolcav.stl").exists(), reason="shared parts not present")
def test_binary_stl_whose_header_starts_with_solid():
    assert (PARTS / "ktoolcav.stl").read_bytes()[:5] == b"solid"
    m = load_mesh(PARTS / "ktoolcav.stl")
    assert len(m.faces) == 4090 and m.closed


def test_degenerate_triangles_are_dropped_and_counted():
    b = box([0, 0, 0], [1, 1, 1])
    V = np.vstack([b.vertices, [[5, 5, 5], [6, 6, 6], [7, 7, 7]]])
    F = np.vstack([b.faces, [[8, 9, 10], [0, 0, 1]]])
    m = mesh_from_arrays(V, F)
    assert m.dropped_degenerate == 2 and len(m.faces) == 12 and m.closed
    assert any("degenerate" in w for w in m.warnings)


def test_inside_out_closed_mesh_is_refused_and_flip_turns_it():
    b = box([0, 0, 0], [1, 1, 1])
    with pytest.raises(InputError, match="inside out.*flip turns it over"):
        mesh_from_arrays(b.vertices, b.faces[:, ::-1])
    m = mesh_from_arrays(b.vertices, b.faces[:, ::-1], flip=True)
    assert m.flipped and m.turned_faces == 0
    assert np.allclose(m.face_normals, b.face_normals)
    assert any("flip: every face turned over" in w for w in m.warnings)


def test_open_mesh_warns():
    b = box([0, 0, 0], [1, 1, 1])
    m = mesh_from_arrays(b.vertices, b.faces[2:])
    assert not m.closed and any("open" in w for w in m.warnings)


def test_unwelded_stl_triangles_are_welded(tmp_path):
    s = sphere(5.0, 8, 16)
    soup = s.vertices[s.faces].reshape(-1, 3)
    m = mesh_from_arrays(soup, np.arange(len(soup)).reshape(-1, 3))
    assert m.closed and len(m.vertices) == len(s.vertices)


@pytest.mark.parametrize("content, message", [
    (None, "no such file"),
    (b"", "empty"),
    (b"hello, this is not a mesh\n", "not"),
    (b"solid x\nendsolid x\n", "no triangles"),
])
def test_bad_files(tmp_path, content, message):
    p = tmp_path / "bad.stl"
    if content is not None:
        p.write_bytes(content)
    with pytest.raises(InputError, match=message):
        load_mesh(p)


def test_nan_coordinates(tmp_path):
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, float("nan"), 0]], np.float32)
    data = b"\0" * 80 + struct.pack("<I", 1) + struct.pack("<3f", 0, 0, 1) + tri.tobytes() + b"\0\0"
    p = tmp_path / "nan.stl"
    p.write_bytes(data)
    with pytest.raises(InputError, match="NaN"):
        load_mesh(p)


def test_unsupported_extension(tmp_path):
    p = tmp_path / "part.step"
    p.write_text("ISO-10303-21;")
    with pytest.raises(InputError, match="unsupported"):
        load_mesh(p)


def test_scrambled_winding_is_made_consistent_by_neighbour_agreement():
    s = sphere(5.0, 12, 24)
    F = s.faces.copy()
    rng = np.random.default_rng(3)
    bad = rng.random(len(F)) < 0.4
    F[bad] = F[bad][:, ::-1]
    m = mesh_from_arrays(s.vertices, F)
    assert m.closed and not m.flipped and m.turned_faces == bad.sum()
    centre = m.vertices[m.faces].mean(axis=1)
    assert (np.einsum("ij,ij->i", m.face_normals, centre) > 0).all()
    assert any("against their neighbours" in w for w in m.warnings)


def test_consistently_wound_open_part_keeps_its_winding():
    v, f = propeller_like()
    m = mesh_from_arrays(v, f, "propeller")
    assert not m.flipped and m.turned_faces == 0
    assert m.summary()["pieces"] == {"closed": 3, "with_holes": 1, "sheets": 0}
    hub = m.piece == m.piece[0]
    centre = m.vertices[m.faces[hub]].mean(axis=1) - [0, 0, 6]
    assert (np.einsum("ij,ij->i", m.face_normals[hub], centre) > 0).all()  # still facing out of the hub
    s = m.solid()
    assert s.caps == 2 * 48 and s.curtains == 0
    # the hub is material right up to its open ends, which are capped
    from meshmill.kernels.backend import solid_kernels
    inside = solid_kernels(m).points_inside(np.array([[0.0, 0, 6], [0, 0, 11.99], [0, 0, 12.01], [8.5, 0, 1]]))
    assert inside.tolist() == [True, True, False, False]
    # the boundary loops found on load are the faces' (the solid takes them, moved with the mesh)
    from meshmill.geometry.solid import boundary_loops

    for mesh in (m, m.transformed(offset=[1.0, 2.0, 3.0])):
        loops, loop_piece = boundary_loops(mesh.faces, mesh.piece)
        assert len(loops) == len(mesh.loops[0]) == 2 and np.array_equal(loop_piece, mesh.loops[1])
        assert all(np.array_equal(a, b) for a, b in zip(loops, mesh.loops[0]))


def test_open_surface_facing_down_is_named_and_flip_turns_it():
    v = np.array([[0, 0, 0], [10, 0, 0], [10, 10, 1], [0, 10, 1]], float)
    down = np.array([[0, 2, 1], [0, 3, 2]])
    m = mesh_from_arrays(v, down, "sheet")
    assert not m.flipped and m.summary()["pieces"]["sheets"] == 1
    assert any("away from the spindle" in w and "give flip" in w for w in m.warnings)
    up = mesh_from_arrays(v, down, "sheet", flip=True)
    assert up.face_normals[:, 2].min() > 0 and not any("away from" in w for w in up.warnings)


@pytest.mark.skipif(not (PARTS / "beet_mm.stl").exists(), reason="shared parts not present")
def test_inward_wound_part_with_a_slit_is_refused_then_turned_by_flip():
    # beet_mm is wound inward and one sliver triangle leaves a slit when dropped
    with pytest.raises(InputError, match="inside out"):
        load_mesh(PARTS / "beet_mm.stl")
    m = load_mesh(PARTS / "beet_mm.stl", flip=True)
    assert m.dropped_degenerate == 1 and m.flipped
    top = m.vertices[m.faces][:, :, 2].min(axis=1) > m.bounds[1, 2] - 1.0
    assert (m.face_normals[top, 2] > 0).mean() > 0.95


def test_stray_fragments_and_non_manifold_edges_are_said_and_handled():
    from meshmill.geometry.mesh import mesh_from_arrays
    from meshmill.geometry.shapes import box

    # two blocks touching along an edge (four faces on it), and a 0.05 mm chip floating beside them
    a, b, chip = box([0, 0, 0], [10, 10, 10]), box([10, 10, 0], [20, 20, 10]), box([30, 30, 30], [30.05, 30.05, 30.05])
    v = np.vstack([a.vertices, b.vertices, chip.vertices])
    f = np.vstack([a.faces, b.faces + 8, chip.faces + 16])
    m = mesh_from_arrays(v, f, "parts")
    assert len(m.faces) == 24 and m.bounds[1].tolist() == [20, 20, 10]
    assert m.closed and m.summary()["pieces"] == {"closed": 2, "with_holes": 0, "sheets": 0}
    said = " ".join(m.warnings)
    assert "dropped 1 stray fragment(s) (12 triangle(s)" in said and "1 non-manifold edge(s)" in said
    # the same chip next to a part of its own size is no stray
    small = mesh_from_arrays(np.vstack([chip.vertices, chip.vertices + 0.1]), np.vstack([chip.faces, chip.faces + 8]),
                             "chips")
    assert len(small.faces) == 24


def test_welding_indexes_points_as_unique_rows_do():
    """The vertex weld's index equals np.unique over rows (the lexicographic order of the distinct
    points), with repeats, grid values, and -0.0 beside 0.0."""
    from meshmill.geometry.mesh import weld_index

    rng = np.random.default_rng(5)
    pts = np.round(rng.integers(-3, 4, (2000, 3)) * 0.5, 6)
    pts[::7] = -0.0 * pts[::7]
    pts[::11, 1] = -0.0
    inverse, count = weld_index(pts)
    uniq, ref = np.unique(pts, axis=0, return_inverse=True)
    assert count == len(uniq) and np.array_equal(inverse, ref.reshape(-1))
    assert np.array_equal(uniq[inverse], pts)


def test_binary_stl_files_are_read_as_trimesh_reads_them(tmp_path):
    """Binary STL files are read here (not with trimesh, whose import takes longer than reading a
    large part): the same corners in the same order, as float64 of the file's float32; ASCII files
    (and binary ones whose length does not match their count) are left to trimesh."""
    from meshmill.geometry.mesh import read_binary_stl

    stls = sorted(PARTS.glob("*.stl"))
    if not stls:
        pytest.skip("shared parts not present")
    binary = 0
    for path in stls:
        got = read_binary_stl(path)
        theirs = trimesh.load(path, force="mesh", process=False)
        if got is None:  # an ASCII file
            assert path.read_bytes()[:5].lower() == b"solid"
            continue
        binary += 1
        assert got[0].dtype == np.float64 and np.array_equal(got[0], theirs.vertices), path.name
        assert np.array_equal(got[1], theirs.faces), path.name
    assert binary >= 3
    solid_header = PARTS / "ktoolcav.stl"  # binary, its header starting with "solid"
    assert read_binary_stl(solid_header) is not None
    truncated = tmp_path / "truncated.stl"  # one record short of its count
    truncated.write_bytes(solid_header.read_bytes()[:-50])
    assert read_binary_stl(truncated) is None


def test_binary_stl_written_here_reads_back_with_its_normals(tmp_path):
    from meshmill.geometry.mesh import read_binary_stl, write_binary_stl

    s = sphere(5.0, 12, 24)
    v = np.vstack([s.vertices, [[0, 0, 9], [1, 0, 9], [2, 0, 9]]])  # with a degenerate triangle (a line)
    f = np.vstack([s.faces, [[len(s.vertices), len(s.vertices) + 1, len(s.vertices) + 2]]])
    path = tmp_path / "s.stl"
    write_binary_stl(path, v, f)
    assert path.stat().st_size == 84 + 50 * len(f)
    corners, faces = read_binary_stl(path)
    assert np.array_equal(corners, v[f].reshape(-1, 3).astype(np.float32).astype(np.float64))
    theirs = trimesh.load(path, force="mesh", process=False)
    assert np.array_equal(theirs.vertices, corners) and np.array_equal(theirs.faces, faces)
    stored = np.frombuffer(path.read_bytes()[84:], np.dtype([("n", "<f4", 3), ("c", "<f4", 9), ("a", "<u2")]))["n"]
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    np.testing.assert_allclose(stored[:-1], normal[:-1] / np.linalg.norm(normal[:-1], axis=1)[:, None], atol=1e-6)
    assert np.all(stored[-1] == 0)
    again = load_mesh(path)  # the degenerate triangle dropped: the sphere, closed
    assert again.closed and len(again.faces) == len(s.faces) and again.dropped_degenerate == 1


def test_vertex_components_join_what_faces_join():
    """Union-find labels against a breadth-first search over the faces' corners (random soups,
    repeated corners, vertices no face uses)."""
    from meshmill.geometry.mesh import vertex_components

    rng = np.random.default_rng(3)
    for _ in range(200):
        nv = int(rng.integers(1, 40))
        faces = rng.integers(0, nv, (int(rng.integers(1, 25)), 3))
        label = vertex_components(faces, nv)
        neighbours = [set() for _ in range(nv)]
        for a, b, c in faces:
            neighbours[a] |= {b, c}
            neighbours[b] |= {a, c}
            neighbours[c] |= {a, b}
        for start in range(nv):
            seen, todo = {start}, [start]
            while todo:
                for n in neighbours[todo.pop()] - seen:
                    seen.add(n)
                    todo.append(n)
            assert {k for k in range(nv) if label[k] == label[start]} == seen


def test_a_stl_file_that_cannot_be_read_is_one_clear_error(tmp_path, monkeypatch):
    import meshmill.geometry.mesh as mesh_module

    def refused(path):
        raise PermissionError(13, "Permission denied", str(path))

    p = _export(box([0, 0, 0], [1, 1, 1]), tmp_path / "locked.stl")
    monkeypatch.setattr(mesh_module, "read_binary_stl", refused)
    with pytest.raises(InputError, match="locked.stl: cannot read \\(Permission denied\\)"):
        load_mesh(p)


def test_a_sheet_edge_three_of_its_faces_share_hangs_a_curtain():
    """A sheet whose piece kept an edge of three faces (a flap folded over, as mount_rush.stl has):
    the count of its faces above a point changes by one across that edge, so its material ends
    there. The check mesh must hold that wall (distances to the solid's boundary are taken to it),
    as it holds the curtain under an edge of one face."""
    from meshmill.geometry.mesh import Mesh
    from meshmill.geometry.solid import SHEET, boundary_edges
    from meshmill.kernels.backend import solid_kernels

    v = np.array([[0, 0, 5], [0, 2, 5], [-2, 1, 5], [2, 1, 5], [1.5, 1, 6.0]])  # e0, e1, left, right, flap
    f = np.array([[0, 1, 2], [0, 3, 1], [0, 1, 4]], np.int32)
    m = Mesh(vertices=v, faces=f, closed=False, piece=np.zeros(3, np.int64), piece_kind=np.array([SHEET], np.int8))
    edges, _ = boundary_edges(f, m.piece, odd=True)
    assert {tuple(sorted(e)) for e in edges.tolist()} == {(0, 1), (0, 2), (1, 2), (0, 3), (1, 3), (0, 4), (1, 4)}
    kern = solid_kernels(m, "cpu", 0.0)
    left, right = np.array([[-0.05, 1.0, 3.0]]), np.array([[0.05, 1.0, 3.0]])
    assert kern.points_inside(left)[0] and not kern.points_inside(right)[0]  # one face above, then two
    assert kern.mesh_distances(right)[0] == pytest.approx(0.05, abs=1e-9)
    assert kern.mesh_distances(left)[0] == pytest.approx(0.05, abs=1e-9)
