"""Set-up: units, which axis points to the spindle, the work zero; STEP and IGES parts."""
import itertools
import json
import math

import numpy as np
import pytest

from meshmill.errors import InputError
from meshmill.geometry.mesh import load_mesh, mesh_from_arrays
from meshmill.geometry.placement import AXES, Setup, up_rotation
from meshmill.geometry.shapes import box


@pytest.mark.parametrize("axis", list(AXES))
def test_each_axis_is_turned_to_the_spindle(axis):
    r = up_rotation(axis)
    assert np.allclose(r @ np.array(AXES[axis], float), [0, 0, 1], atol=1e-15)
    assert np.allclose(r @ r.T, np.eye(3), atol=1e-15) and np.linalg.det(r) == pytest.approx(1.0)


def test_rotations_as_angles_and_matrices():
    assert np.allclose(up_rotation("90,0,0") @ [0, -1, 0], [0, 0, -1], atol=1e-12)  # about X: -Y to -Z
    assert np.allclose(up_rotation("0,-90,0"), up_rotation("+X"), atol=1e-12)
    assert np.allclose(up_rotation("0,0,1, 0,1,0, -1,0,0"), up_rotation("-X"))
    with pytest.raises(InputError, match="not a rotation"):
        up_rotation("1,0,0, 0,1,0, 0,0,-1")  # a mirror
    with pytest.raises(InputError, match="give an axis"):
        up_rotation("up")
    with pytest.raises(InputError, match="^units must be one of"):
        Setup(units="ft").check()


def _utm_block():
    """A 0.12 x 0.08 x 0.03 m block at UTM-like coordinates (metres), its long side along +X."""
    b = box([0, 0, 0], [0.12, 0.08, 0.03])
    return b.vertices + np.array([512_345.0, 5_401_234.0, 812.5]), b.faces


def test_a_part_in_metres_far_away_is_set_up_in_mm_at_its_work_zero():
    v, f = _utm_block()
    raw = mesh_from_arrays(v, f, "utm", setup=Setup())  # as the file says: mm, its own zero
    assert any("0.12 mm across" in w and "units m" in w for w in raw.warnings)
    assert any("from the work zero" in w for w in raw.warnings)
    for origin, lo, hi in (("bottom-centre", [-60, -40, 0], [60, 40, 30]), ("top-centre", [-60, -40, -30], [60, 40, 0]),
                           ("corner", [0, 0, 0], [120, 80, 30])):
        m = mesh_from_arrays(v, f, "utm", setup=Setup(units="m", origin=origin))
        assert np.allclose(m.bounds, [lo, hi], atol=1e-6) and m.closed and not m.warnings
        assert m.summary()["setup"]["scale"] == 1000.0
    # a point in the file's coordinates (metres) becomes the zero
    m = mesh_from_arrays(v, f, "utm", setup=Setup(units="m", origin="512345.06,5401234.04,812.53"))
    assert np.allclose(m.bounds, [[-60, -40, -30], [60, 40, 0]], atol=1e-6)


def test_up_turns_the_part_before_anything_looks_at_it():
    # an open square sheet facing -X: set up with --up -X, it faces the spindle and no warning
    # says otherwise; left as it is, it faces sideways
    v = np.array([[0, 0, 0], [0, 10, 0], [0, 10, 10], [0, 0, 10.0]])
    f = np.array([[0, 2, 1], [0, 3, 2]])
    m = mesh_from_arrays(v, f, "sheet", setup=Setup(up="-X", origin="corner"))
    assert np.allclose(m.face_normals, [0, 0, 1]) and np.allclose(m.bounds, [[0, 0, 0], [10, 10, 0]])
    down = mesh_from_arrays(v, f, "sheet", setup=Setup(up="+X"))
    assert np.allclose(down.face_normals, [0, 0, -1]) and any("give flip" in w for w in down.warnings)
    s = m.summary()["setup"]
    assert s["up"] == "-X" and np.allclose(np.array(s["rotation"]) @ [-1, 0, 0], [0, 0, 1])


def test_the_cli_writes_the_placed_part_and_paths_in_the_work_frame(tmp_path, tools_file):
    import trimesh

    from meshmill.cli import main

    # an STL holds float32: a block in metres 2 km out, its numbers exact in float32
    b = box([0, 0, 0], [0.125, 0.0625, 0.03125])
    v, f = b.vertices + np.array([2048.0, 1024.0, 256.0]), b.faces
    part = tmp_path / "block_m.stl"
    trimesh.Trimesh(v, f, process=False).export(part)
    out = tmp_path / "r"
    setup = ["--units", "m", "--origin", "bottom-centre"]
    assert main(["raster", str(part), "--tools", str(tools_file), "--tool", "B6", "--stepover", "3",
                 "--out", str(out), "--quiet", *setup]) == 0
    s = json.loads((out / "summary.json").read_text())
    work = [[-62.5, -31.25, 0], [62.5, 31.25, 31.25]]
    assert s["part"]["setup"]["units"] == "m" and np.allclose(s["part"]["bounds"], work)
    placed = load_mesh(out / "part.stl")
    assert np.array_equal(placed.bounds, work)
    from meshmill.toolpath.cldata import read_apt
    from meshmill.tools.table import load_tools

    tp, _ = read_apt(out / "toolpath.cl", load_tools(tools_file))
    feed = tp.tip[~tp.rapid]  # over the block's top and down its sides, in mm, about the work zero
    assert feed[:, 2].max() == pytest.approx(31.25, abs=1e-6) and feed[:, 2].min() == pytest.approx(0.0, abs=1e-6)
    assert feed[:, 0].min() == pytest.approx(-66.0) and feed[:, 0].max() == pytest.approx(66.0)  # box + R + sample
    # the path verifies against the part set up the same way, and against the written part.stl
    for argv in ([str(part), *setup], [str(out / "part.stl")]):
        assert main(["verify", *argv[:1], str(out / "toolpath.cl"), "--tools", str(tools_file), "--quiet",
                     *argv[1:]]) == 0


# --- STEP: our own writer of a B-rep box (ISO 10303-21, AP214), so the reader is tested on a
# file whose every number we know


def step_box(lo, hi, unit="MILLI"):
    """The text of a STEP file holding the box ``[lo, hi]`` as a solid; ``unit`` None: metres."""
    ents = []

    def add(text):
        ents.append(text)
        return f"#{len(ents)}"

    def point(p):
        return add("CARTESIAN_POINT('',(" + ",".join(f"{c:.6f}" for c in p) + "))")

    def direction(d):
        return add("DIRECTION('',(" + ",".join(f"{c:.1f}" for c in d) + "))")

    xyz = list(zip(lo, hi))
    corner = {c: (add(f"VERTEX_POINT('',{point([xyz[n][c[n]] for n in range(3)])})"),
                  [xyz[n][c[n]] for n in range(3)]) for c in itertools.product((0, 1), repeat=3)}
    edges = {}

    def edge(a, b):
        key = tuple(sorted((a, b)))
        if key not in edges:
            (va, pa), (vb, pb) = corner[key[0]], corner[key[1]]
            d = [q - p for p, q in zip(pa, pb)]
            length = max(abs(c) for c in d)
            line = add(f"LINE('',{point(pa)},{add(f'VECTOR({chr(39)}{chr(39)},{direction([c / length for c in d])},{length:.6f})')})")
            edges[key] = add(f"EDGE_CURVE('',{va},{vb},{line},.T.)")
        return edges[key], key[0] == a

    faces = []
    for ax, side in itertools.product(range(3), (0, 1)):
        o = [a for a in range(3) if a != ax]
        cs = []
        for u, w in ((0, 0), (1, 0), (1, 1), (0, 1)):
            c = [0, 0, 0]
            c[ax], c[o[0]], c[o[1]] = side, u, w
            cs.append(tuple(c))
        if (side == 1) != (ax != 1):  # counter-clockwise seen from outside
            cs = cs[::-1]
        loop = []
        for a, b in zip(cs, cs[1:] + cs[:1]):
            e, same = edge(a, b)
            loop.append(add(f"ORIENTED_EDGE('',*,*,{e},{'.T.' if same else '.F.'})"))
        normal = [0.0] * 3
        normal[ax] = 1.0 if side else -1.0
        ref = [0.0] * 3
        ref[o[0]] = 1.0
        plane = add(f"PLANE('',{add(f'AXIS2_PLACEMENT_3D({chr(39)}{chr(39)},{point(corner[cs[0]][1])},{direction(normal)},{direction(ref)})')})")
        bound = add(f"FACE_OUTER_BOUND('',{add('EDGE_LOOP(' + chr(39) * 2 + ',(' + ','.join(loop) + '))')},.T.)")
        faces.append(add(f"ADVANCED_FACE('',({bound}),{plane},.T.)"))
    brep = add(f"MANIFOLD_SOLID_BREP('box',{add('CLOSED_SHELL(' + chr(39) * 2 + ',(' + ','.join(faces) + '))')})")
    lu = add(f"(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT({'.' + unit + '.' if unit else '$'},.METRE.))")
    au = add("(NAMED_UNIT(*)PLANE_ANGLE_UNIT()SI_UNIT($,.RADIAN.))")
    su = add("(NAMED_UNIT(*)SI_UNIT($,.STERADIAN.)SOLID_ANGLE_UNIT())")
    unc = add(f"UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-07),{lu},'distance_accuracy_value','')")
    ctx = add(f"(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT(({unc}))"
              f"GLOBAL_UNIT_ASSIGNED_CONTEXT(({lu},{au},{su}))REPRESENTATION_CONTEXT('',''))")
    place = add(f"AXIS2_PLACEMENT_3D('',{point([0, 0, 0])},{direction([0, 0, 1])},{direction([1, 0, 0])})")
    rep = add(f"ADVANCED_BREP_SHAPE_REPRESENTATION('',({place},{brep}),{ctx})")
    app = add("APPLICATION_CONTEXT('automotive design')")
    prod = add(f"PRODUCT('box','box','',({add(f'PRODUCT_CONTEXT({chr(39)}{chr(39)},{app},{chr(39)}mechanical{chr(39)})')}))")
    pd = add(f"PRODUCT_DEFINITION('design','',{add(f'PRODUCT_DEFINITION_FORMATION({chr(39)}{chr(39)},{chr(39)}{chr(39)},{prod})')},"
             f"{add(f'PRODUCT_DEFINITION_CONTEXT({chr(39)}part definition{chr(39)},{app},{chr(39)}design{chr(39)})')})")
    add(f"SHAPE_DEFINITION_REPRESENTATION({add(f'PRODUCT_DEFINITION_SHAPE({chr(39)}{chr(39)},{chr(39)}{chr(39)},{pd})')},{rep})")
    body = "\n".join(f"#{i + 1}={e};" for i, e in enumerate(ents))
    return ("ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('box.step','',(''),(''),'','','');\n"
            "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\nDATA;\n"
            f"{body}\nENDSEC;\nEND-ISO-10303-21;\n")


def test_a_step_solid_is_read_in_mm_whatever_its_unit(tmp_path):
    pytest.importorskip("cascadio")  # meshmill[step]; in the dev extra, so CI runs this
    for name, lo, hi, unit in (("mm.step", (0, 0, 0), (20, 10, 5), "MILLI"), ("m.stp", (0, 0, 0), (0.02, 0.01, 0.005), None),
                               ("off.step", (-7.5, 2.25, 1), (12.5, 12.25, 6), "MILLI")):
        (tmp_path / name).write_text(step_box(lo, hi, unit))
        m = load_mesh(tmp_path / name)
        scale = 1000.0 if unit is None else 1.0
        assert m.closed and len(m.faces) == 12 and not m.warnings
        assert np.array_equal(m.bounds, np.array([lo, hi]) * scale)  # exact: CAD dimensions come back as drawn
    m = load_mesh(tmp_path / "off.step", setup=Setup(up="+Y", origin="bottom-centre"))
    assert np.allclose(m.bounds, [[-10, -2.5, 0], [10, 2.5, 10]])
    with pytest.raises(InputError, match="states its own units"):
        load_mesh(tmp_path / "m.stp", setup=Setup(units="m"))
    (tmp_path / "bad.step").write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n")
    with pytest.raises(InputError, match="bad.step"):
        load_mesh(tmp_path / "bad.step")


def test_reading_step_without_its_extra_says_how_to_get_it(tmp_path, monkeypatch):
    import builtins

    real = builtins.__import__

    def no_cascadio(name, *a, **k):
        if name == "cascadio":
            raise ImportError(name)
        return real(name, *a, **k)

    monkeypatch.setattr(builtins, "__import__", no_cascadio)
    (tmp_path / "p.step").write_text(step_box((0, 0, 0), (1, 1, 1)))
    with pytest.raises(InputError, match=r"pip install 'meshmill\[step\]'"):
        load_mesh(tmp_path / "p.step")


def test_a_model_scale_after_the_units():
    v, f = _utm_block()
    m = mesh_from_arrays(v, f, "utm", setup=Setup(units="m", scale=0.05, origin="corner"))  # a 1:20 model
    assert np.allclose(m.bounds, [[0, 0, 0], [6, 4, 1.5]], atol=1e-6)
    assert m.summary()["setup"]["model_scale"] == 0.05 and m.summary()["setup"]["scale"] == 50.0
    with pytest.raises(InputError, match="^scale must be"):
        Setup(scale=0).check()


def test_what_the_step_reader_prints_becomes_our_warning(tmp_path, capfd):
    """OpenCASCADE prints its complaints (coloured, on the standard output) while it reads: they
    become the part's warnings, and ``--json`` stays JSON."""
    pytest.importorskip("cascadio")
    import json

    from meshmill.cli import main

    text = step_box((0, 0, 0), (20, 10, 5), "MILLI")
    text = text.replace("ENDSEC;\nEND-ISO", "#9000=PRODUCT_RELATED_PRODUCT_CATEGORY('part','',(#9999));\n"
                                            "ENDSEC;\nEND-ISO")  # a reference to nothing
    (tmp_path / "ref.step").write_text(text)
    m = load_mesh(tmp_path / "ref.step")
    said = capfd.readouterr()
    assert m.closed and len(m.faces) == 12 and not said.out and not said.err
    assert any("STEP reader says" in w for w in m.warnings), m.warnings
    assert main(["dexel", str(tmp_path / "ref.step"), "--step", "2", "--out", str(tmp_path / "d.npz"), "--json"]) == 0
    out = capfd.readouterr()
    assert json.loads(out.out)["operation"] == "dexel" and not out.err
