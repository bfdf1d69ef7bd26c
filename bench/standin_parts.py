"""Stand-ins for the three parts of the thesis benchmark (the original models are unavailable), the
part of seed 004's Tableau 8, and the compressor impeller of issue 39.

Each function returns ``(vertices (n, 3) float64, faces (m, 3) int64)`` in mm: a closed, watertight,
outward-wound triangle mesh with no degenerate triangles, deterministic, its bounding box starting at
the origin and scaled to the thesis' size (X x Y x Z).

- :func:`double_wave` "an extrusion of a free-form ruled surface built from two different guide
  curves": 86.5 x 57.8 x 96.7 mm, 4096 triangles (thesis: about 4070). A tall block whose top is the
  ruled surface between two different sine waves, one on y = 0 and one on y = 57.8.
- :func:`handle` "a surface of revolution with strong curvature": 40.08 x 40.04 x 62.11 mm,
  9072 triangles (thesis: about 9076). A bulbous knob on a waisted neck, revolved about Z, flat caps.
- :func:`blade` "a turbine blade": 152 x 75 x 152 mm, 26528 triangles (thesis: about 26512).
  A cambered NACA-like section swept along Z with chord shrinking and twist growing along the span,
  closed by flat airfoil caps.
- :func:`mould` seed 004's Tableau 8 part (about 400 x 400 x 180 mm, 65 000 triangles; not shown in
  the thesis): 400 x 400 x 180 mm, 66960 triangles. A block whose top is a smooth free-form height
  field (a dome with two ridges on its flanks and a valley running out to one side, 60 to 180 mm
  high) over vertical walls and a flat bottom; every horizontal section is one closed contour, as
  the seed's counts (one contour per level) suggest.
- :func:`impeller` issue 39's "real 25k-triangle compressor impeller" (not published): 80 x 33 x
  80 mm, its axis along +Y as in the issue (``--up +Y``), 29 808 triangles. A trumpet hub on a
  backplate with 8 full blades and 8 splitters, 1.2 mm thick, wrapped 45 degrees at the inlet and
  radial at the exit; the union of the hub and the blades is manifold3d's (a bench dependency).

    .venv/bin/python bench/standin_parts.py [FOLDER]    # writes FOLDER/{name}.stl (default bench/out/parts)
"""
from __future__ import annotations

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_OUT = os.path.join(os.path.relpath(HERE), "out", "parts")


def _loft(rings, cap, fan=False):
    """Close a stack of rings (k, m, 3) into a solid.

    Consecutive rings are joined by quads. ``cap`` is a triangulation of one ring as (t, 3) ring
    indices, wound in the ring's own order; with ``fan`` it is ignored and each end gets a fan to the
    ring's centroid instead. The result is flipped if needed so that its signed volume is positive.
    """
    rings = np.asarray(rings, dtype=np.float64)
    k, m, _ = rings.shape
    verts = rings.reshape(-1, 3)
    i = np.arange(m)
    j = (i + 1) % m
    faces = []
    for r in range(k - 1):
        a, b = r * m + i, (r + 1) * m + i
        c, d = r * m + j, (r + 1) * m + j
        faces += [np.c_[a, c, d], np.c_[a, d, b]]
    if fan:
        verts = np.vstack([verts, rings[0].mean(0), rings[-1].mean(0)])
        cap = np.c_[i, j, np.full(m, m)]
        bottom = np.where(cap == m, k * m, cap)
        top = np.where(cap == m, k * m + 1, cap + (k - 1) * m)
    else:
        bottom, top = np.asarray(cap), np.asarray(cap) + (k - 1) * m
    faces = np.vstack(faces + [bottom[:, ::-1], top]).astype(np.int64)
    if _signed_volume(verts, faces) < 0:
        faces = faces[:, ::-1].copy()
    return verts, faces


def _signed_volume(v, f):
    return np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6.0


def _fit(v, size):
    """Scale each axis so that the bounding box is [0, size]."""
    lo, hi = v.min(0), v.max(0)
    return (v - lo) / (hi - lo) * np.asarray(size, dtype=np.float64)


def _strip_cap(n):
    """Quads across a ring laid out as side A (0..n-1) then side B backwards (n..2n-1)."""
    i = np.arange(n - 1)
    a0, a1, b1, b0 = i, i + 1, 2 * n - 2 - i, 2 * n - 1 - i
    return np.vstack([np.c_[a0, a1, b1], np.c_[a0, b1, b0]])


def double_wave(nx=40, ny=24):
    """86.5 x 57.8 x 96.7 mm block topped by a ruled surface between two different waves (4096 tris)."""
    L, W = 86.5, 57.8
    x = np.linspace(0.0, L, nx + 1)
    y = np.linspace(0.0, W, ny + 1)
    u = x / L
    wave0 = 80.0 + 10.0 * np.sin(2 * np.pi * 1.5 * u)                    # guide curve on y = 0
    wave1 = 78.0 + 14.0 * np.sin(2 * np.pi * 1.0 * u + 1.2) + 2.0 * u     # guide curve on y = W
    rings = []
    for xi, z0, z1 in zip(x, wave0, wave1):
        ztop = z0 + (z1 - z0) * y / W                                      # straight rulings across y
        bottom = np.c_[np.full_like(y, xi), y, np.zeros_like(y)]
        top = np.c_[np.full_like(y, xi), y, ztop][::-1]
        rings.append(np.vstack([bottom, top]))                             # section in the YZ plane
    v, f = _loft(rings, _strip_cap(ny + 1))
    return _fit(v, (L, W, 96.7)), f


def handle(n_theta=72, n_z=63):
    """40.08 x 40.04 x 62.11 mm knob on a waisted neck, revolved about Z (9072 triangles)."""
    t = np.linspace(0.0, 1.0, n_z)
    z = 62.11 * t
    # base flange (r 14) -> neck (r ~6) -> bulb (r 20) -> rounded top (r ~5)
    r = (6.0 + 8.0 * np.exp(-((t - 0.0) / 0.12) ** 2)
         + 14.0 * np.exp(-((t - 0.72) / 0.15) ** 2) - 3.0 * t)
    r[-1] = max(r[-1], 3.0)
    th = np.linspace(0.0, 2 * np.pi, n_theta, endpoint=False)
    rings = [np.c_[ri * np.cos(th), ri * np.sin(th), np.full_like(th, zi)] for ri, zi in zip(r, z)]
    v, f = _loft(rings, None, fan=True)
    return _fit(v, (40.08, 40.04, 62.11)), f


def blade(n_chord=100, n_span=66):
    """152 x 75 x 152 mm twisted, cambered airfoil swept along Z (26528 triangles)."""
    n = n_chord
    x = 0.5 * (1 - np.cos(np.linspace(0.0, np.pi, n + 1)))[1:]            # cosine spacing, LE excluded
    thick = 5 * 0.14 * (0.2969 * np.sqrt(x) - 0.126 * x - 0.3516 * x**2 + 0.2843 * x**3 - 0.1015 * x**4)
    thick += 0.004 * x                                                     # blunt trailing edge
    p, mc = 0.4, 0.06                                                      # NACA 4-digit camber line
    camber = np.where(x < p, mc / p**2 * (2 * p * x - x**2), mc / (1 - p) ** 2 * (1 - 2 * p + 2 * p * x - x**2))
    sec = np.vstack([[0.0, 0.0], np.c_[x, camber + thick], np.c_[x, camber - thick][::-1]])  # LE, upper, lower
    sec -= [0.35, 0.0]                                                     # stack about 35 % chord
    rings = []
    for s in np.linspace(0.0, 1.0, n_span):
        chord = 130.0 * (1 - 0.35 * s)
        a = np.radians(15.0 + 30.0 * s)                                    # twist along the span
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        xy = chord * sec @ rot.T
        rings.append(np.c_[xy, np.full(len(xy), 152.0 * s)])
    ring_len = 2 * n + 1
    le = np.array([[ring_len - 1, 0, 1]])                                  # nose triangle, then quads
    i = np.arange(1, n)
    quads = np.vstack([np.c_[i, i + 1, ring_len - 1 - i], np.c_[i, ring_len - 1 - i, ring_len - i]])
    v, f = _loft(rings, np.vstack([le, quads]))
    return _fit(v, (152.0, 75.0, 152.0)), f


def mould(n=180):
    """400 x 400 x 180 mm block under a free-form height field (2 n^2 + 12 n triangles: 66960)."""
    L, H, low = 400.0, 180.0, 60.0
    x = np.linspace(0.0, L, n + 1)
    X, Y = np.meshgrid(x, x, indexing="ij")
    u, v = X / L, Y / L

    def bump(cu, cv, su, sv):
        return np.exp(-(((u - cu) / su) ** 2) - ((v - cv) / sv) ** 2)

    valley = np.exp(-(((v - 0.45 - 0.5 * (u - 0.45)) / 0.09) ** 2)) * np.clip(u - 0.45, 0.0, None)
    f = bump(0.45, 0.45, 0.35, 0.32) + 0.12 * bump(0.45, 0.78, 0.12, 0.25) + 0.10 * bump(0.15, 0.30, 0.25, 0.10) \
        - 0.45 * valley
    z = low + (H - low) * (f - f.min()) / (f.max() - f.min())
    top = np.column_stack([X.ravel(), Y.ravel(), z.ravel()])
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = [np.c_[a, b, c], np.c_[a, c, d]]                               # top, normals up
    ring = np.concatenate([idx[:, 0], idx[-1, 1:], idx[::-1, -1][1:], idx[0, ::-1][1:-1]])  # CCW from above
    m, base = len(ring), len(top)
    k = np.arange(m)
    pt, qt, pb, qb = ring, np.roll(ring, -1), base + k, base + (k + 1) % m
    centre = base + m
    faces += [np.c_[pt, pb, qb], np.c_[pt, qb, qt], np.c_[np.full(m, centre), qb, pb]]  # walls, bottom fan
    v = np.vstack([top, top[ring] * [1.0, 1.0, 0.0], [[L / 2, L / 2, 0.0]]])
    return v, np.vstack(faces).astype(np.int64)


def impeller(blades=8, n_theta=120, n_prof=36, n_t=40, n_s=6, wrap=45.0, thick=1.2):
    """80 x 33 x 80 mm compressor impeller, axis +Y (29 808 triangles; mm).

    The hub is a revolved profile: a 40 mm radius backplate 3 mm thick, a trumpet (a quarter
    ellipse) rising to a 10 mm radius at 30 mm, a nose to 33 mm. Each blade is a thin solid between
    the hub (sunk 1 mm into it) and the shroud line, radial-element: at a meridional station t
    (0 inlet, 1 exit) its section is a straight line at the angle ``wrap (1 - t)^2`` plus its place,
    thickened ``thick`` along the circle. Splitters start at t = 0.35. The pieces overlap and are
    united by manifold3d; the result is turned so that the axis (Z while built) is +Y.
    """
    import trimesh  # here only, with manifold3d: the bench scripts import the parts without them

    phi = np.linspace(0.0, np.pi / 2, n_prof)
    prof = np.vstack([[40.0, 0.0], np.c_[40 - 30 * np.cos(phi), 3 + 27 * (1 - np.sin(phi))][::-1], [10.0, 33.0]])
    th = np.linspace(0.0, 2 * np.pi, n_theta, endpoint=False)
    rings = [np.c_[r * np.cos(th), r * np.sin(th), np.full_like(th, z)] for r, z in prof]
    pieces = [trimesh.Trimesh(*_loft(rings, None, fan=True), process=False)]

    def one_blade(t0, place):
        t = np.linspace(t0, 1.0, n_t)
        p = t * np.pi / 2
        inward = np.c_[27 * np.cos(p), 30 * np.sin(p)]
        inward /= np.linalg.norm(inward, axis=1)[:, None]
        hub = np.c_[40 - 30 * np.cos(p), 3 + 27 * (1 - np.sin(p))] - inward
        shroud = np.c_[40 - 14 * np.cos(p), 10 + 20 * (1 - np.sin(p))]
        angle = np.radians(wrap) * (1 - t) ** 2 + 2 * np.pi * place / blades
        s = np.linspace(0.0, 1.0, n_s)[:, None]
        sections = []
        for i in range(n_t):
            rz = (1 - s) * hub[i] + s * shroud[i]
            a = np.r_[angle[i] + thick / 2 / rz[:, 0], angle[i] - thick / 2 / rz[::-1, 0]]
            r, z = np.r_[rz[:, 0], rz[::-1, 0]], np.r_[rz[:, 1], rz[::-1, 1]]
            sections.append(np.c_[r * np.cos(a), r * np.sin(a), z])
        return trimesh.Trimesh(*_loft(sections, None, fan=True), process=False)

    for k in range(blades):
        pieces += [one_blade(0.0, k), one_blade(0.35, k + 0.5)]
    whole = trimesh.boolean.union(pieces, engine="manifold")
    v = np.asarray(whole.vertices, dtype=np.float64) @ np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    return v - v.min(0), np.asarray(whole.faces, dtype=np.int64)


PARTS = {"double_wave": double_wave, "handle": handle, "blade": blade, "mould": mould, "impeller": impeller}


def written(name: str, folder: str = DEFAULT_OUT) -> str:
    """The path of ``folder/{name}.stl``, written first if it is not there (trimesh; the impeller
    also needs manifold3d)."""
    import trimesh

    path = os.path.join(folder, f"{name}.stl")
    if not os.path.exists(path):
        os.makedirs(folder, exist_ok=True)
        trimesh.Trimesh(*PARTS[name](), process=False).export(path)
    return path


def main(argv=None):
    import trimesh  # here only: the bench scripts import the parts on machines without trimesh

    argv = sys.argv[1:] if argv is None else argv
    out = argv[0] if argv else DEFAULT_OUT
    os.makedirs(out, exist_ok=True)
    ok = True
    for name, make in PARTS.items():
        v, f = make()
        mesh = trimesh.Trimesh(v, f, process=False)
        min_area = mesh.area_faces.min()
        good = mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0 and min_area >= 1e-9
        ok &= bool(good)
        path = os.path.join(out, f"{name}.stl")
        mesh.export(path)
        size = " x ".join(f"{s:.2f}" for s in mesh.extents)
        print(f"{name:12s} {len(f):6d} tris  {size} mm  volume {mesh.volume:10.1f} mm^3  "
              f"watertight={mesh.is_watertight} winding_consistent={mesh.is_winding_consistent} "
              f"min_area={min_area:.3g}  -> {path}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
