"""The solid a part mesh bounds: what every gouge and collision check takes as material.

Each connected piece of the mesh (faces joined across edges shared by two faces) is one of:

- closed: the volume it encloses;
- a solid with holes (open, but its boundary loops enclose less than ``SHEET_SHARE`` of its area,
  e.g. a propeller whose shaft ends are open): closed by a fan of triangles across each hole, from
  the hole's centroid;
- a sheet (an open surface, e.g. a terrain or a skull cap): the material is what lies below it as
  seen from the spindle (+Z), down to the floor (the floor of the stock): the points with an odd
  number of the sheet's faces above them. Its boundary is the sheet, vertical curtains from the
  sheet's boundary edges down to the floor, and the floor under the sheet (the sheet projected).

A :class:`Solid` holds the check mesh (the faces, caps, curtains and floor: every point of the
solid's boundary lies on it, so distances to it are distances to the solid's boundary) and the
faces that decide inside from outside (:func:`meshmill.kernels.clearance.inside`: the winding of
the closed pieces and caps, the parity of the sheets).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..tolerances import DEGENERATE_AREA
from ..kernels.bvh import build_bvh

CLOSED, HOLES, SHEET = 0, 1, 2  # kinds of connected pieces
# an open piece is a sheet (a surface with material behind it) when its boundary loops enclose at
# least this share of its area (its vector area: zero for a closed piece, the projected area of a
# flat sheet); below it, a solid with holes
SHEET_SHARE = 0.2


@dataclass
class Solid:
    """``vertices (n, 3), faces (m, 3)``: the check mesh, mm; ``inside_bvh`` the BVH of the faces
    deciding inside (the mesh's and the caps') with ``inside_kind (k,) int8`` in its order (1: a
    closed piece's or cap's face, wound; 0: a sheet's face); ``floor`` mm; counts of what was added."""

    vertices: np.ndarray
    faces: np.ndarray
    inside_bvh: object
    inside_kind: np.ndarray
    floor: float
    caps: int = 0
    curtains: int = 0

    @property
    def inside(self):
        """``(node_lo, node_hi, node_child, node_range, tris, kind, floor)`` for the kernels."""
        return (*self.inside_bvh.arrays, self.inside_kind, self.floor)

    @property
    def floor_below_sheets(self) -> bool:
        """Whether the floor lies at or below every vertex (of the sheets, the caps, the pieces):
        then the curtains and floor lie below the sheets' faces and edges, and a tool lowered
        from above meets the faces deciding inside first (:attr:`inside`'s BVH)."""
        return self.floor <= float(self.vertices[:, 2].min())


def boundary_edges(faces: np.ndarray, piece: np.ndarray, odd: bool = False):
    """Edges used by one face of their piece (``odd``: by an odd number of them, once each):
    ``(k, 2)`` vertex pairs in the direction that face (the first of them) traverses them, and the
    piece of each ``(k,)``."""
    F = faces.astype(np.int64)
    directed = F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    face_piece = np.repeat(piece, 3)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    # (piece, edge) as one integer key (np.unique over rows sorts 10x slower)
    _, edge = np.unique(lo * (int(hi.max()) + 1) + hi, return_inverse=True)
    _, first, inv, counts = np.unique(face_piece.astype(np.int64) * (int(edge.max()) + 1) + edge.reshape(-1),
                                      return_index=True, return_inverse=True, return_counts=True)
    if odd:
        keep = first[counts % 2 == 1]
        return directed[keep], face_piece[keep]
    single = counts[inv.reshape(-1)] == 1
    return directed[single], face_piece[single]


def boundary_loops(faces: np.ndarray, piece: np.ndarray):
    """Chains of boundary edges (:func:`boundary_edges`), each ``(k,)`` vertex indices in the
    direction the faces traverse them (closed but where a non-manifold boundary leaves a chain
    open), and the piece of each."""
    edges, edge_piece = boundary_edges(faces, piece)
    if len(edges) == 0:
        return [], np.zeros(0, np.int64)
    nxt = {}
    for k, a in enumerate(edges[:, 0].tolist()):
        nxt.setdefault(a, []).append(k)
    used = np.zeros(len(edges), bool)
    loops, loop_piece = [], []
    for k0 in range(len(edges)):
        if used[k0]:
            continue
        used[k0] = True
        start, cur = int(edges[k0, 0]), int(edges[k0, 1])
        loop = [start]
        while cur != start:
            loop.append(cur)
            options = [k for k in nxt.get(cur, ()) if not used[k]]
            if not options:
                break
            used[options[0]] = True
            cur = int(edges[options[0], 1])
        loops.append(np.array(loop, np.int64))
        loop_piece.append(int(edge_piece[k0]))
    return loops, np.array(loop_piece, np.int64)


def _cap_faces(vertices, loops):
    """Fans across ``loops``: new vertices (their centroids), faces ``(c, b, a)`` for each loop
    edge a -> b (so that a cap meets its piece's faces the other way round: the winding stays
    consistent), and the loop of each face."""
    centres, faces, owner = [], [], []
    n = len(vertices)
    for k, loop in enumerate(loops):
        if len(loop) < 3:
            continue
        c = n + len(centres)
        centres.append(vertices[loop].mean(axis=0))
        faces.append(np.column_stack([np.full(len(loop), c), np.roll(loop, -1), loop]))
        owner.append(np.full(len(loop), k))
    if not centres:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    return np.array(centres), np.concatenate(faces), np.concatenate(owner)


def piece_kinds(vertices, faces, piece, loops, loop_piece):
    """Per piece ``(p,)``: its kind (CLOSED, HOLES, SHEET), volume (closed across its holes; sheets
    0), the vertical component of its vector area (< 0: it faces mostly down) and its area."""
    n_pieces = int(piece.max()) + 1
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.bincount(piece, np.linalg.norm(cross, axis=1), n_pieces)
    vec = np.stack([0.5 * np.bincount(piece, cross[:, k], n_pieces) for k in range(3)], axis=1)
    kind = np.full(n_pieces, CLOSED, np.int8)
    open_piece = np.zeros(n_pieces, bool)
    open_piece[loop_piece] = True
    sheet = open_piece & (np.linalg.norm(vec, axis=1) >= SHEET_SHARE * area)
    kind[open_piece] = HOLES
    kind[sheet] = SHEET
    # volumes with the holes closed by their caps (about the vertices' centroid, for rounding)
    centre = vertices.mean(axis=0)
    vol = np.bincount(piece, np.einsum("ij,ij->i", tri[:, 0] - centre, np.cross(tri[:, 1] - centre,
                                                                               tri[:, 2] - centre)), n_pieces) / 6.0
    hole = np.nonzero(kind[loop_piece] == HOLES)[0]
    cap_v, cap_f, owner = _cap_faces(vertices, [loops[k] for k in hole])
    if len(cap_f):
        ct = np.vstack([vertices, cap_v])[cap_f] - centre
        vol += np.bincount(loop_piece[hole][owner], np.einsum("ij,ij->i", ct[:, 0], np.cross(ct[:, 1], ct[:, 2])),
                           n_pieces) / 6.0
    vol[kind == SHEET] = 0.0
    return kind, vol, vec[:, 2], area


def bounded_solid(mesh, floor: float) -> Solid:
    """The :class:`Solid` of ``mesh`` (a :class:`~meshmill.geometry.mesh.Mesh`), its sheets
    reaching down to ``floor`` mm."""
    V, F = mesh.vertices, mesh.faces.astype(np.int64)
    piece = mesh.piece if mesh.piece is not None else np.zeros(len(F), np.int64)
    kind = mesh.piece_kind if mesh.piece_kind is not None else np.zeros(1, np.int8)
    face_kind = kind[piece]
    if mesh.closed:
        loops, loop_piece = [], np.zeros(0, np.int64)
    else:
        loops, loop_piece = mesh.loops if mesh.loops is not None else boundary_loops(F, piece)
    cap_v, cap_f, _ = _cap_faces(V, [loop for loop, p in zip(loops, loop_piece) if kind[p] == HOLES])
    Vc = np.vstack([V, cap_v]) if len(cap_v) else V
    inside_faces = np.vstack([F, cap_f]) if len(cap_f) else F
    inside_kind = np.r_[(face_kind != SHEET).astype(np.int8), np.ones(len(cap_f), np.int8)]
    check_v, check_f = [Vc], [inside_faces]
    n_curtain = 0
    if (kind == SHEET).any():
        n = len(Vc)
        low = V.copy()
        low[:, 2] = floor  # vertex i dropped to the floor is vertex n + i
        # under every edge where the count of a sheet's faces above changes: used by one face of
        # it, or by three (a non-manifold edge its piece kept: mount_rush.stl has them)
        edges, edge_piece = boundary_edges(F, piece, odd=True)
        edges = edges[kind[edge_piece] == SHEET]
        curtain = np.concatenate([np.column_stack([edges[:, 0], edges[:, 1], edges[:, 1] + n]),
                                  np.column_stack([edges[:, 0], edges[:, 1] + n, edges[:, 0] + n])])
        check_v.append(low)
        check_f += [curtain, F[face_kind == SHEET][:, ::-1] + n]
        n_curtain = len(edges)
    verts = np.vstack(check_v)
    faces = np.vstack(check_f)
    tri = verts[faces]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    faces = faces[area > DEGENERATE_AREA]
    in_bvh = build_bvh(Vc, inside_faces)
    return Solid(vertices=verts, faces=faces.astype(np.int64), inside_bvh=in_bvh,
                 inside_kind=np.ascontiguousarray(inside_kind[in_bvh.order]), floor=float(floor),
                 caps=int(len(cap_f)), curtains=n_curtain)
