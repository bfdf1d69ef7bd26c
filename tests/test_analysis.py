"""Mesh analysis: triangle parameters, vertex normals, visibility and accessibility."""
import json

import numpy as np
import pytest
import trimesh

from meshmill.cli import main
from meshmill.errors import InputError
from meshmill.geometry import analysis
from meshmill.geometry.mesh import mesh_from_arrays
from meshmill.geometry.shapes import box, revolve, sphere


def test_seed_example_facet():
    """Seed 001's facet (closed into a tetrahedron): area 2.11797 mm², its normal, and an obtuse
    angle the seed's arcsin missed (its angles summed to 154.13 degrees)."""
    v = np.array([[1.836, 0, 29.100], [3.673, 1.836, 27.127], [1.836, 1.836, 28.092], [2.5, 1.0, 0.0]])
    m = mesh_from_arrays(v, np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]]), "tet")
    t = analysis.triangle_parameters(m)
    k = int(np.argmin(np.abs(t["area"] - 2.11797)))
    assert t["area"][k] == pytest.approx(2.11797, abs=5e-6)
    assert sorted(t["angles"][k]) == pytest.approx([38.321, 38.747, 102.933], abs=1e-3)
    assert t["angles"].sum(axis=1) == pytest.approx(np.full(4, 180.0))
    assert np.abs(t["normal"][k]) == pytest.approx([0.4183, 0.4371, 0.7962], abs=1e-4)  # file: 0.418 0.436 0.796
    assert (t["neighbours"] >= 0).all()


def test_vertex_normals_on_a_box_corner():
    m = box((0, 0, 0), (1, 1, 1))
    for w in analysis.WEIGHTINGS:
        n = analysis.vertex_normals(m, w)
        assert np.allclose(np.linalg.norm(n, axis=1), 1)
        corner = np.argmin(np.linalg.norm(m.vertices - [1, 1, 1], axis=1))
        assert (n[corner] > 0).all()  # points out of the corner
    with pytest.raises(InputError):
        analysis.vertex_normals(m, "cotan")


def test_sphere_visible_is_accessible():
    m = sphere(10.0, rings=24, segments=48)
    f = analysis.visibility(m, [0, 0, 1])
    t = analysis.triangle_parameters(m)
    np.testing.assert_array_equal(f["visible_triangles"], t["normal"][:, 2] > 0)
    np.testing.assert_array_equal(f["accessible_triangles"], f["visible_triangles"])  # convex: nothing hides
    assert f["accessible_vertices"].sum() == f["visible_vertices"].sum() > 0


def mushroom():
    """Plate r 20 (top at z 5, rings at r 15, 10, 5), column r 5, cap r 14 from z 25 to 30."""
    r = [0, 20, 20, 15, 10, 5, 5, 14, 14, 0]
    z = [0, 0, 5, 5, 5, 5, 25, 25, 30, 30]
    return revolve(r, z, 48, "mushroom")


def test_overhang_hides_the_plate_under_the_cap():
    m = mushroom()
    f = analysis.visibility(m, [0, 0, 1])
    t = analysis.triangle_parameters(m)
    c = t["centroid"]
    rad = np.hypot(c[:, 0], c[:, 1])
    plate = np.isclose(c[:, 2], 5) & (t["normal"][:, 2] > 0.99)
    assert f["visible_triangles"][plate].all()
    np.testing.assert_array_equal(f["accessible_triangles"][plate], rad[plate] > 15)
    cap_top = np.isclose(c[:, 2], 30)
    assert f["accessible_triangles"][cap_top].all()
    assert not f["visible_triangles"][np.isclose(t["normal"][:, 2], 0)].any()  # walls
    # from the side, the plate's top is not visible; the cap's rim faces are
    side = analysis.visibility(m, [1, 0, 0])
    assert not side["visible_triangles"][plate].any()
    # the hemisphere map reaches the plate under the cap from fewer directions than outside it
    dirs = analysis.hemisphere(30, 45)
    assert len(dirs) == 1 + 3 * 8
    share, reached = analysis.accessibility_map(m, dirs)
    assert 0 < share.min() and share.max() < 1
    assert (reached[plate & (rad < 10)] < reached[plate & (rad > 15)].min()).all()


def test_analyze_command(tmp_path, capsys):
    m = mushroom()
    trimesh.Trimesh(m.vertices, m.faces).export(tmp_path / "m.stl")
    assert main(["analyze", str(tmp_path / "m.stl"), "--direction", "0,0,2", "--theta-step", "45",
                 "--delta-step", "90", "--out", str(tmp_path / "a"), "--quiet"]) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["direction"] == [0, 0, 1] and s["accessible_triangles"] < s["visible_triangles"]
    assert s["map"]["directions"] == 1 + 2 * 4
    with np.load(tmp_path / "a" / "analysis.npz") as z:
        assert z["accessible_triangles"].sum() == s["accessible_triangles"]
    capsys.readouterr()
    assert main(["analyze", str(tmp_path / "m.stl"), "--direction", "0,0,0", "--out", str(tmp_path / "b")]) == 2
    assert "--direction must not be zero" in capsys.readouterr().err
    assert main(["analyze", str(tmp_path / "m.stl"), "--direction", "1,2", "--out", str(tmp_path / "b")]) == 2
