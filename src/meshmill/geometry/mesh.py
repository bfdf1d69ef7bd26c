"""Loading, checking and cleaning triangle meshes.

A :class:`Mesh` is an indexed triangle mesh in mm with welded vertices. Its winding is the file's:
where neighbouring faces disagree (they traverse their shared edge the same way), the faces of the
smaller share of each connected piece's area are turned to agree with the rest; a consistently
wound mesh is never turned over, closed or open, unless asked (``flip``). A closed mesh wound
inside out (negative volume) is refused, pointing to ``flip``; an open surface whose normals
face mostly away from the spindle (-Z) is named in a warning. Each piece is closed, a solid with
holes, or a sheet (:mod:`meshmill.geometry.solid`, which builds the solid the checks take as
material). Binary STL files (also those whose header starts with "solid") are read and written
here (:func:`read_binary_stl`, :func:`write_binary_stl`: importing trimesh takes longer than reading
a large part); ASCII STL, OBJ and PLY are read with trimesh.
"""
from __future__ import annotations

import contextlib
import os
import sys
import time
import warnings
from dataclasses import dataclass, field

import numba
import numpy as np

from ..errors import InputError
from ..runfiles import uninterrupted
from .placement import Placement, Setup
from .solid import CLOSED, HOLES, SHEET, bounded_solid
from ..tolerances import DEGENERATE_AREA, TESSELLATION_ANGLE, TESSELLATION_TOL, WELD_DIGITS

BREP = {".step": "step", ".stp": "step", ".iges": "iges", ".igs": "iges"}  # CAD solids, tessellated on reading
SUPPORTED = (".stl", ".obj", ".ply", *BREP)
SHEET_DEPTH = 10.0  # mm: the material below a sheet reaches at least this far below its lowest point
STRAY_SIZE = 0.01  # a separate body smaller than this share of the part across ...
STRAY_AREA = 0.001  # ... and of its area is a stray fragment, dropped


@dataclass
class Mesh:
    """``vertices (n, 3) float64`` mm, ``faces (m, 3) int32`` wound outward."""

    vertices: np.ndarray
    faces: np.ndarray
    closed: bool = True
    dropped_degenerate: int = 0
    flipped: bool = False  # turned over as a whole (asked for)
    turned_faces: int = 0  # faces turned to agree with their neighbours
    warnings: list = field(default_factory=list)
    piece: np.ndarray | None = None  # (m,) connected piece of each face (across manifold edges)
    piece_kind: np.ndarray | None = None  # (p,) int8 per piece: CLOSED, HOLES or SHEET
    loops: tuple | None = None  # the boundary loops of ``faces`` (geometry.solid.boundary_loops), found on load
    placement: Placement | None = None  # how the file was set up into the work frame (None: as read)
    source: str = ""  # the file it was read from (absolute path; "" for arrays)
    load_seconds: float = 0.0  # reading and checking it took
    _solids: dict = field(default_factory=dict, repr=False)

    @property
    def face_normals(self) -> np.ndarray:
        """Unit outward normal ``(m, 3)`` of every face."""
        tri = self.vertices[self.faces]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)

    @property
    def bounds(self) -> np.ndarray:
        """``(2, 3)``: min and max corner, mm."""
        return np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    def summary(self) -> dict:
        kinds = self.piece_kind if self.piece_kind is not None else np.zeros(0, np.int8)
        return {
            "vertices": int(len(self.vertices)),
            "triangles": int(len(self.faces)),
            "closed": bool(self.closed),
            "dropped_degenerate": int(self.dropped_degenerate),
            "flipped": bool(self.flipped),
            "turned_faces": int(self.turned_faces),
            "pieces": {"closed": int((kinds == CLOSED).sum()), "with_holes": int((kinds == HOLES).sum()),
                       "sheets": int((kinds == SHEET).sum())},
            "bounds": self.bounds.round(6).tolist(),
            "setup": (self.placement or Placement()).summary(),
        }

    def transformed(self, rotation=None, offset=None) -> "Mesh":
        """The same mesh with ``vertices @ rotation.T + offset`` (a rigid motion; its pieces and
        their kinds kept: a sheet's material then lies below it in the new frame)."""
        v = self.vertices if rotation is None else self.vertices @ np.asarray(rotation, float).T
        v = v if offset is None else v + np.asarray(offset, float)
        return Mesh(vertices=np.ascontiguousarray(v), faces=self.faces, closed=self.closed,
                    dropped_degenerate=self.dropped_degenerate, flipped=self.flipped, turned_faces=self.turned_faces,
                    piece=self.piece, piece_kind=self.piece_kind, loops=self.loops, placement=self.placement)

    def solid(self, floor: float | None = None):
        """The :class:`~meshmill.geometry.solid.Solid` this mesh bounds, sheets down to ``floor``
        (default: as deep again below the mesh's lowest point as the mesh is tall, and at least
        ``SHEET_DEPTH``: a sheet is the top of a block whose bottom is not known); built once per floor."""
        lo, hi = self.bounds[:, 2]
        floor = float(lo - max(SHEET_DEPTH, hi - lo)) if floor is None else float(floor)
        if floor not in self._solids:
            self._solids[floor] = bounded_solid(self, floor)
        return self._solids[floor]


def edge_face_counts(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """How many faces share each undirected edge: ``(e,)`` counts over the unique edges."""
    e = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1).astype(np.int64)
    _, counts = np.unique(e[:, 0] * n_vertices + e[:, 1], return_counts=True)
    return counts


def weld_index(points: np.ndarray):
    """The index of each of ``points (n, 3)`` among the distinct ones in lexicographic order
    (x, then y, then z), ``(n,) int64``, and how many there are: ``np.unique(points, axis=0,
    return_inverse=True)``'s, by one lexsort (sorting rows as records is 10x slower)."""
    order = np.lexsort((points[:, 2], points[:, 1], points[:, 0]))
    ps = points[order]
    new = np.r_[True, (ps[1:] != ps[:-1]).any(axis=1)]
    inverse = np.empty(len(points), np.int64)
    inverse[order] = np.cumsum(new) - 1
    return inverse, int(new.sum())


def closed_mesh(vertices, faces, name="mesh") -> Mesh:
    """A :class:`Mesh` of arrays known to bound closed solids, wound outward, with shared vertices
    and no degenerate triangles (what our marching cubes writes): taken as they are, unchecked
    (:func:`mesh_from_arrays` checks and repairs what users give)."""
    v = np.ascontiguousarray(vertices, np.float64).reshape(-1, 3)
    f = np.asarray(faces, np.int64).reshape(-1, 3)
    tri = v[f]
    f = f[0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1) > DEGENERATE_AREA]
    if len(f) == 0:
        raise InputError(f"{name}: no triangles")
    return Mesh(vertices=v, faces=f.astype(np.int32), closed=True, piece=np.zeros(len(f), np.int64),
                piece_kind=np.array([CLOSED], np.int8))


def mesh_from_arrays(vertices, faces, name="mesh", flip=False, setup: Setup | None = None) -> Mesh:
    """Check and clean raw arrays into a :class:`Mesh` (raises :class:`InputError`); ``flip``
    turns every face over (after making neighbours agree); ``setup`` places the vertices into the
    work frame first (units, up, work zero: :mod:`meshmill.geometry.placement`)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0 or len(v) == 0:
        raise InputError(f"{name}: no triangles")
    if not np.isfinite(v).all():
        raise InputError(f"{name}: coordinates contain NaN or infinity")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{name}: face indices out of range")
    placement, notes = None, []
    if setup is not None:
        v, placement, notes = setup.place(v, name)
    # weld identical vertices so that neighbouring faces share edges
    inverse, count = weld_index(np.round(v, WELD_DIGITS))
    first = np.full(count, -1, np.int64)
    first[inverse[::-1]] = np.arange(len(v))[::-1]
    v = v[first]
    f = inverse[f]
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    good = (area > DEGENERATE_AREA) & (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    dropped = int((~good).sum())
    f = f[good]
    if len(f) == 0:
        raise InputError(f"{name}: every triangle is degenerate")
    f, notes = _drop_strays(v, f, name, notes)
    used = np.unique(f)
    remap = np.full(len(v), -1, np.int64)
    remap[used] = np.arange(len(used))
    v = v[used]
    f = remap[f]
    mesh = Mesh(vertices=v, faces=f.astype(np.int32), dropped_degenerate=dropped, placement=placement)
    mesh.warnings += notes
    if dropped:
        mesh.warnings.append(f"{name}: dropped {dropped} degenerate triangle(s)")
    counts = edge_face_counts(mesh.faces, len(v))
    many = int((counts > 2).sum())
    if many:
        mesh.warnings.append(f"{name}: {many} non-manifold edge(s) (three or more faces on one edge): the pieces "
                             "meeting there are taken apart along them")
    _orient(mesh, name, flip)
    # closed: every piece encloses a volume (two closed bodies touching along an edge are closed)
    mesh.closed = bool((counts % 2 == 0).all() and (mesh.piece_kind == CLOSED).all())
    if not mesh.closed:
        k = mesh.piece_kind
        mesh.warnings.append(f"{name}: the mesh is open (not watertight): " + ", ".join(
            f"{n} {what}" for n, what in ((int((k == SHEET).sum()), "surface(s) with the material below them"),
                                          (int((k == HOLES).sum()), "solid(s) with holes, closed across them"),
                                          (int((k == CLOSED).sum()), "closed piece(s)")) if n))
    return mesh


@numba.njit(cache=True)
def _winding_parity(n_faces, pair_a, pair_b, pair_same):
    """Flip flags (n_faces,) that make neighbouring faces traverse their shared edge in opposite
    directions, and a component label per face (breadth-first over manifold edges)."""
    adj_start = np.zeros(n_faces + 1, np.int64)
    for k in range(pair_a.shape[0]):
        adj_start[pair_a[k] + 1] += 1
        adj_start[pair_b[k] + 1] += 1
    for i in range(n_faces):
        adj_start[i + 1] += adj_start[i]
    fill = adj_start[:-1].copy()
    adj = np.empty(adj_start[-1], np.int64)
    same = np.empty(adj_start[-1], np.bool_)
    for k in range(pair_a.shape[0]):
        a, b = pair_a[k], pair_b[k]
        adj[fill[a]] = b
        same[fill[a]] = pair_same[k]
        fill[a] += 1
        adj[fill[b]] = a
        same[fill[b]] = pair_same[k]
        fill[b] += 1
    flip = np.zeros(n_faces, np.bool_)
    comp = np.full(n_faces, -1, np.int64)
    queue = np.empty(n_faces, np.int64)
    ncomp = 0
    for seed in range(n_faces):
        if comp[seed] >= 0:
            continue
        comp[seed] = ncomp
        head, tail = 0, 1
        queue[0] = seed
        while head < tail:
            f = queue[head]
            head += 1
            for j in range(adj_start[f], adj_start[f + 1]):
                g = adj[j]
                if comp[g] < 0:
                    comp[g] = ncomp
                    flip[g] = flip[f] ^ same[j]
                    queue[tail] = g
                    tail += 1
        ncomp += 1
    return flip, comp


@numba.njit(cache=True)
def vertex_components(faces, n_vertices):
    """``(n_vertices,)`` a label per vertex, the same for vertices joined through faces'
    corners (``faces (m, 3)``): union-find, each root its smallest vertex."""
    parent = np.arange(n_vertices)
    for i in range(faces.shape[0]):
        for j in range(1, 3):
            a = faces[i, 0]
            b = faces[i, j]
            while parent[a] != a:  # path halving
                parent[a] = parent[parent[a]]
                a = parent[a]
            while parent[b] != b:
                parent[b] = parent[parent[b]]
                b = parent[b]
            if a < b:
                parent[b] = a
            elif b < a:
                parent[a] = b
    for k in range(n_vertices):  # roots are smaller than their children: one pass ends at them
        parent[k] = parent[parent[k]]
    return parent


def _drop_strays(v, f, name, notes):
    """Faces ``f`` without the stray fragments: separate bodies (faces joined by shared vertices)
    smaller than ``STRAY_SIZE`` of the part across and ``STRAY_AREA`` of its area, with a warning."""
    n, comp = np.unique(vertex_components(f, len(v))[f[:, 0]], return_inverse=True)
    n = len(n)
    if n < 2:
        return f, notes
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    comp_area = np.bincount(comp, area, n)
    lo = np.full((n, 3), np.inf)
    hi = np.full((n, 3), -np.inf)
    pts = tri.reshape(-1, 3)
    np.minimum.at(lo, np.repeat(comp, 3), pts)
    np.maximum.at(hi, np.repeat(comp, 3), pts)
    size = np.linalg.norm(hi - lo, axis=1)
    whole = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    stray = (size < STRAY_SIZE * whole) & (comp_area < STRAY_AREA * area.sum())
    if not stray.any():
        return f, notes
    keep = ~stray[comp]
    notes = notes + [f"{name}: dropped {int(stray.sum())} stray fragment(s) ({int((~keep).sum())} triangle(s), the "
                     f"largest {size[stray].max():.3g} mm across): separate bodies too small to machine or to matter"]
    return f[keep], notes


def _orient(mesh: Mesh, name: str, flip: bool) -> None:
    """Make neighbouring faces agree (per connected piece, the faces of the smaller share of its
    area turn), turn everything over when ``flip``, classify the pieces, and refuse a mesh whose
    closed pieces enclose a negative volume (wound inside out)."""
    from .solid import boundary_loops, piece_kinds

    F = mesh.faces.astype(np.int64)
    nv = len(mesh.vertices)
    directed = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = np.minimum(directed[:, 0], directed[:, 1]) * nv + np.maximum(directed[:, 0], directed[:, 1])
    order = np.argsort(key, kind="stable")
    ks = key[order]
    first = np.r_[True, ks[1:] != ks[:-1]]
    run = np.diff(np.r_[np.nonzero(first)[0], len(ks)])
    two = np.nonzero(first)[0][run == 2]  # manifold edges: exactly two faces
    ea, eb = order[two], order[two + 1]
    pair_same = directed[ea, 0] == directed[eb, 0]
    turn, comp = _winding_parity(len(F), ea // 3, eb // 3, pair_same)
    tri = mesh.vertices[F]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    ncomp = int(comp.max()) + 1
    # neighbour agreement: in each piece the larger share of the area keeps its winding
    turned_share = np.bincount(comp, area * turn, ncomp)
    majority_turned = turned_share > 0.5 * np.bincount(comp, area, ncomp)
    turn ^= majority_turned[comp]
    if turn.any():
        F[turn] = F[turn][:, ::-1]
        mesh.turned_faces = int(turn.sum())
        mesh.warnings.append(f"{name}: {mesh.turned_faces} face(s) were wound against their neighbours; turned "
                             "them to agree with the rest of their piece")
    if flip:
        F = F[:, ::-1].copy()
        mesh.flipped = True
        mesh.warnings.append(f"{name}: flip: every face turned over (normals reversed)")
    mesh.faces = F.astype(np.int32)
    mesh.piece = comp
    mesh.loops = loops, loop_piece = boundary_loops(mesh.faces, comp)
    mesh.piece_kind, volume, up, area = piece_kinds(mesh.vertices, mesh.faces, comp, loops, loop_piece)
    solid = mesh.piece_kind != SHEET
    if solid.any() and volume[solid].sum() < 0.0:
        raise InputError(f"{name}: the mesh is wound inside out (its closed pieces enclose {volume[solid].sum():.6g} "
                         "mm^3: the normals point into the material); flip turns it over", "flip")
    sheet = mesh.piece_kind == SHEET
    down = sheet & (up < 0.0)
    if down.any() and area[down].sum() > 0.05 * area.sum():  # not for a few stray fragments
        mesh.warnings.append(f"{name}: {int(down.sum())} of {int(sheet.sum())} open surface(s) "
                             f"({100 * area[down].sum() / area[sheet].sum():.0f} % of their area) face mostly away "
                             "from the spindle (-Z): the tool works on the side the normals face and the material "
                             "is what lies below; if they should face up, give flip")


def load_mesh(path, flip=False, setup: Setup | None = None) -> Mesh:
    """Read STL/OBJ/PLY ``path`` (:func:`read_mesh`) with its ``source`` and ``load_seconds``."""
    t0 = time.perf_counter()
    mesh = read_mesh(path, flip, setup)
    mesh.source = os.path.abspath(os.fspath(path))
    mesh.load_seconds = time.perf_counter() - t0
    return mesh


def read_mesh(path, flip=False, setup: Setup | None = None) -> Mesh:
    """Read STL/OBJ/PLY ``path`` into a checked :class:`Mesh` (raises :class:`InputError`);
    ``flip`` turns every face over; ``setup`` places it into the work frame (default: as the file
    is, in mm, with a warning where its size or place suggests otherwise)."""
    setup = Setup() if setup is None else setup
    path = os.fspath(path)
    name = os.path.basename(path)
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file")
    if os.path.isdir(path):
        raise InputError(f"{path}: is a folder, not a mesh file")
    ext = os.path.splitext(path)[1].lower()
    if ext not in SUPPORTED:
        raise InputError(f"{path}: unsupported mesh format '{ext}' (use {', '.join(SUPPORTED)})")
    if os.path.getsize(path) == 0:
        raise InputError(f"{path}: empty file, no triangles")
    if ext == ".stl":
        try:
            arrays = read_binary_stl(path)
        except OSError as exc:
            raise InputError(f"{path}: cannot read ({exc.strerror or exc.__class__.__name__})") from None
        if arrays is not None:
            return mesh_from_arrays(*arrays, name, flip, setup)
    trimesh = import_trimesh()

    if ext in BREP:
        if setup is not None and setup.units != "mm":
            raise InputError(f"{path}: a {BREP[ext].upper()} file states its own units (read in mm): leave units out", "units")
        vertices, faces, said = _read_brep(path, BREP[ext])
        mesh = mesh_from_arrays(vertices, faces, name, flip, setup)
        mesh.warnings[:0] = said
        return mesh
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for unreadable files
        raise InputError(f"{path}: not a readable {ext[1:].upper()} mesh ({exc.__class__.__name__})") from None
    faces = getattr(loaded, "faces", None)
    if faces is None or len(faces) == 0:
        raise InputError(f"{path}: not a mesh or no triangles")
    return mesh_from_arrays(loaded.vertices, faces, name, flip, setup)


def import_trimesh():
    """The trimesh module, imported where a Ctrl-C cannot cut its imports short
    (:func:`meshmill.runfiles.uninterrupted`)."""
    with uninterrupted():
        import trimesh
    return trimesh


STL_RECORD = np.dtype([("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("attribute", "<u2")])


def read_binary_stl(path):
    """``(vertices (3 m, 3), faces (m, 3))`` of the binary STL file ``path`` (each triangle's
    corners as written, unwelded: as trimesh gives them), or ``None`` where the file is not one:
    its length is not 84 + 50 m bytes for the m > 0 triangles its header states (ASCII files; the
    rest is trimesh's to judge). Read here because importing trimesh costs more (0.5 s) than
    reading a large part."""
    size = os.path.getsize(path)
    with open(path, "rb") as fh:
        head = fh.read(84)
        if len(head) < 84:
            return None
        count = int(np.frombuffer(head, "<u4", 1, 80)[0])
        if count == 0 or size != 84 + STL_RECORD.itemsize * count:
            return None
        records = np.fromfile(fh, STL_RECORD, count)
    corners = records["corners"].reshape(-1, 3).astype(np.float64)
    return corners, np.arange(3 * count, dtype=np.int64).reshape(-1, 3)


def write_binary_stl(path, vertices, faces):
    """Write triangles ``faces (m, 3)`` of ``vertices (n, 3)`` mm as a binary STL file (float32,
    each with its unit normal by the right-hand rule; zero for a degenerate triangle)."""
    tri = np.asarray(vertices, np.float64)[np.asarray(faces, np.int64)]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    records = np.zeros(len(tri), STL_RECORD)
    records["normal"] = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0)
    records["corners"] = tri
    with open(path, "wb") as fh:
        fh.write(b"meshmill binary STL (mm)".ljust(80, b" "))
        fh.write(np.uint32(len(tri)).astype("<u4").tobytes())
        records.tofile(fh)


def _read_brep(path, kind):
    """``(vertices (n, 3) mm, faces (m, 3), warnings)`` of a STEP or IGES file, every solid and
    surface tessellated within ``TESSELLATION_TOL`` (OpenCASCADE, through cascadio:
    ``meshmill[step]``); what OpenCASCADE prints while reading becomes ``warnings`` (one line per
    kind of message), not text on our standard output."""
    import io

    trimesh = import_trimesh()
    try:
        import cascadio
    except ImportError:
        raise InputError(f"{path}: reading {kind.upper()} needs the step extra: pip install 'meshmill[step]'") from None
    with open(path, "rb") as fh:
        data = fh.read()
    with _captured_output() as said:
        glb = cascadio.load(data, file_type=kind, tol_linear=TESSELLATION_TOL, tol_angular=TESSELLATION_ANGLE)
    if not glb:
        raise InputError(f"{path}: not a readable {kind.upper()} file (no solid or surface in it)")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loaded = trimesh.load(io.BytesIO(glb), file_type="glb", force="mesh", process=False)
    except Exception as exc:  # noqa: BLE001 (cascadio wrote something trimesh cannot read)
        raise InputError(f"{path}: its tessellation could not be read ({exc.__class__.__name__})") from None
    faces = getattr(loaded, "faces", None)
    if faces is None or len(faces) == 0:
        raise InputError(f"{path}: no solid or surface in the {kind.upper()} file")
    # glTF is in metres, in float32: back to mm, rounded to 10 nm so that a CAD dimension (20 mm, not
    # 19.99999955) and the planes it puts vertices on come back exact
    return np.round(np.asarray(loaded.vertices, np.float64) * 1000.0, 5), faces, _reader_warnings(path, kind, said)


@contextlib.contextmanager
def _captured_output():
    """What C libraries write to the standard output and error in the block, captured at the file
    descriptors (OpenCASCADE prints there): a list that holds the text when the block ends."""
    import tempfile

    said = []
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as tmp:
        try:
            os.dup2(tmp.fileno(), 1)
            os.dup2(tmp.fileno(), 2)
            yield said
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            tmp.seek(0)
            said.append(tmp.read().decode("utf-8", "replace"))


def _reader_warnings(path, kind, said) -> list[str]:
    """Our warnings of what a CAD reader printed (colour codes and star frames taken off, each
    kind of line once with its count)."""
    import re

    counts = {}
    for line in "".join(said).splitlines():
        text = re.sub(r"\x1b\[[0-9;]*m", "", line).strip().strip("*").strip()
        if text:
            counts[text] = counts.get(text, 0) + 1
    return [f"{os.path.basename(path)}: the {kind.upper()} reader says: {text}" + (f" ({n} times)" if n > 1 else "")
            for text, n in counts.items()]
