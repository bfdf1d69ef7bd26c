import numpy as np
import pytest

# numba must see NUMBA_ENABLE_CUDASIM before it is imported: test_cuda_parity.py and test_cuda_ptx.py
# run this folder in a fresh process
collect_ignore = ["cudasim"]

TOOLS_TOML = """
[[tools]]
name = "B20"
type = "ball"
diameter = 20.0
flute_length = 25.0
gauge_length = 60.0
holder_diameter = 40.0
holder_length = 40.0

[[tools]]
name = "B10"
type = "ball"
diameter = 10.0
corner_radius = 5.0
flute_length = 20.0
gauge_length = 50.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B6"
type = "ball"
diameter = 6.0
flute_length = 12.0
gauge_length = 45.0
holder_diameter = 32.0
holder_length = 40.0

[[tools]]
name = "B2"
type = "ball"
diameter = 2.0
flute_length = 5.0
gauge_length = 35.0
shank_diameter = 6.0
holder_diameter = 32.0
holder_length = 40.0
"""


@pytest.fixture
def tools_file(tmp_path):
    p = tmp_path / "tools.toml"
    p.write_text(TOOLS_TOML)
    return p


@pytest.fixture
def tools(tools_file):
    from meshmill.tools.table import load_tools

    return load_tools(tools_file)


def brute_point_triangle_dist(p, tris):
    """Independent reference: distance from p (3,) to each triangle (m, 3, 3)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    h = np.einsum("ij,ij->i", p - a, n)
    q = p - h[:, None] * n
    inside = np.ones(len(tris), bool)
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(v - u, q - u), n) >= 0
    best = np.where(inside, np.abs(h), np.inf)
    for u, v in ((a, b), (b, c), (c, a)):
        d = v - u
        s = np.clip(np.einsum("ij,ij->i", p - u, d) / np.einsum("ij,ij->i", d, d), 0, 1)
        best = np.minimum(best, np.linalg.norm(p - (u + s[:, None] * d), axis=1))
    return best


def one_line_error(capsys, argv):
    """Run the command line ``argv``: it must exit 2 with one line on stderr; returns that line."""
    from meshmill.cli import main

    rc = main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert len(err) == 1 and err[0].startswith("meshmill: error:")
    return err[0]


def propeller_like():
    """``(vertices, faces)`` of a propeller-like part, wound outward: a hub (solid of revolution)
    whose shaft ends are open, the top hole wider than the bottom one, so that the hub's boundary
    loops enclose a vector area pointing down (a rule "open pieces face up" would turn it inside
    out), and three blades around it, 3 mm off the hub."""
    from meshmill.geometry.shapes import box, revolve

    hub = revolve([0, 2, 8, 8, 3, 0], [0, 0, 0, 12, 12, 12], segments=48)
    on_axis = np.nonzero(np.abs(hub.vertices[:, :2]).sum(axis=1) < 1e-9)[0]
    parts_v, parts_f = [hub.vertices], [hub.faces[~np.isin(hub.faces, on_axis).any(axis=1)]]  # both fans: holes
    for k in range(3):
        a = 2 * np.pi * k / 3
        blade = box([11, -0.8, 3], [22, 0.8, 9])
        rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        parts_f.append(blade.faces + sum(len(p) for p in parts_v))
        parts_v.append(blade.vertices @ rot.T)
    return np.vstack(parts_v), np.vstack(parts_f)


def winding_number(points, vertices, faces, chunk=256):
    """Independent reference: the generalised winding number ``(k,)`` of a closed mesh around each
    of ``points (k, 3)`` (1 inside, 0 outside), from the solid angles of its triangles."""
    tri = vertices[faces]
    out = []
    for i in range(0, len(points), chunk):
        d = tri[None] - points[i:i + chunk, None, None, :]  # (p, m, 3, 3)
        a, b, c = d[:, :, 0], d[:, :, 1], d[:, :, 2]
        la, lb, lc = (np.linalg.norm(x, axis=-1) for x in (a, b, c))
        num = np.einsum("pmi,pmi->pm", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("pmi,pmi->pm", a, b) * lc + np.einsum("pmi,pmi->pm", b, c) * la
               + np.einsum("pmi,pmi->pm", c, a) * lb)
        out.append(2.0 * np.arctan2(num, den).sum(axis=1) / (4.0 * np.pi))
    return np.concatenate(out)


@pytest.fixture
def part(tmp_path):
    """The overhang column (:func:`meshmill.geometry.shapes.overhang_column`) as an STL file."""
    import trimesh

    from meshmill.geometry.shapes import overhang_column

    m = overhang_column()
    p = tmp_path / "part.stl"
    trimesh.Trimesh(m.vertices, m.faces, process=False).export(p)
    return p
