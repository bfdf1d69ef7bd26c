"""Z-constant contours of a mesh: cutter-contact (CC) points with outward normals.

Robustness comes from a symbolic rule, not from epsilons: a vertex at or above the plane counts
as above it. A triangle is cut only when it has vertices strictly below and at-or-above, so a
vertex or a flat facet lying exactly on a plane is handled as if the plane were an infinitesimal
distance lower, and every cut edge is shared by exactly two cut triangles of a closed mesh.

Each cut triangle gives one segment, oriented so that the material is on its left seen from +Z
(outer boundaries run counter-clockwise): it starts on the edge that goes from above to below in
the face's winding and ends on the edge that goes from below to above. Segments are chained by the
identity of the mesh edge they share, never by comparing coordinates.

Normals make the ball tangent to the faceted surface: a CC point inside a facet takes the facet
normal; at a convex edge the normal turns from one facet's to the next in steps (several CC points
at one place, so that the ball centre moves along the exact offset of the edge); at a concave edge
the point takes the bisector and the ball centre moves out along it by R / cos(θ/2) (θ the turn
between the facets), to where the ball touches both facets instead of entering them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from .. import memory
from ..errors import InputError
from ..tolerances import SAME_POINT
from .mesh import Mesh

POINT_BYTES = 240  # the arrays of one CC point through finish (points, normals, feed, centres, tips, axes, ...)
CUT_BYTES = 120  # one triangle cut while slicing (indices, segment ends)
MIN_HALF_COS = 0.1  # cap of the centre's reach in a crease sharper than about 170 degrees


@dataclass
class Contours:
    """CC points of all contours, concatenated.

    ``points, normals, feed (k, 3)``: CC point (mm), unit outward normal, unit horizontal feed
    direction; ``reach (k,)``: a ball of radius R sits at centre ``point + R·reach·normal``
    (1, or 1/cos(θ/2) in a concave crease); ``offsets (c + 1,)``: contour i holds points offsets[i]:offsets[i+1];
    ``closed (c,) bool``; ``z (c,)`` the contour's plane height (mm)."""

    points: np.ndarray
    normals: np.ndarray
    feed: np.ndarray
    reach: np.ndarray
    offsets: np.ndarray
    closed: np.ndarray
    z: np.ndarray

    def __len__(self):
        return len(self.closed)

    @property
    def contour_of(self) -> np.ndarray:
        """``(k,)`` the contour of each point."""
        return np.repeat(np.arange(len(self)), np.diff(self.offsets))

    def take(self, keep: np.ndarray) -> "Contours":
        """The runs of points where ``keep (k,) bool`` as contours of their own (open, but a
        closed contour kept whole), with their normals and feed directions as they were."""
        pieces, closed, z = [], [], []
        for c in range(len(self)):
            a, b = self.offsets[c], self.offsets[c + 1]
            whole = bool(self.closed[c]) and bool(keep[a:b].all())
            for run in contour_runs(keep[a:b], bool(self.closed[c])):
                pieces.append(a + (run[:-1] if whole else run))
                closed.append(whole)
                z.append(self.z[c])
        idx = np.concatenate(pieces) if pieces else np.zeros(0, np.int64)
        return Contours(points=self.points[idx], normals=self.normals[idx], feed=self.feed[idx],
                        reach=self.reach[idx], offsets=np.r_[0, np.cumsum([len(p) for p in pieces])].astype(np.int64),
                        closed=np.array(closed, bool), z=np.array(z, float))


def contour_runs(ok: np.ndarray, closed: bool) -> list:
    """Index runs of consecutive True in ``ok`` (cyclic when closed; a full loop ends where it began)."""
    n = len(ok)
    if closed and n and ok.all():
        return [np.r_[np.arange(n), 0]]
    if closed and n:
        start = int(np.nonzero(~ok)[0][0]) + 1
        order = (np.arange(n) + start) % n
    else:
        order = np.arange(n)
    runs, cur = [], []
    for i in order:
        if ok[i]:
            cur.append(i)
        elif cur:
            runs.append(np.array(cur))
            cur = []
    if cur:
        runs.append(np.array(cur))
    return runs


def concat_contours(parts) -> Contours:
    """The contours of ``parts`` (a list of :class:`Contours`) in one, from the top plane down
    (in their order within a plane)."""
    sizes = np.concatenate([np.diff(p.offsets) for p in parts])
    z = np.concatenate([p.z for p in parts])
    first = np.concatenate([p.offsets[:-1] + base for p, base in
                            zip(parts, np.cumsum([0] + [len(p.points) for p in parts[:-1]]))])
    order = np.argsort(-z, kind="stable")
    idx = np.concatenate([np.arange(first[c], first[c] + sizes[c]) for c in order]) if len(order) else \
        np.zeros(0, np.int64)
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) for k in ("points", "normals", "feed", "reach")}
    return Contours(points=cat["points"][idx], normals=cat["normals"][idx], feed=cat["feed"][idx],
                    reach=cat["reach"][idx], offsets=np.r_[0, np.cumsum(sizes[order])].astype(np.int64),
                    closed=np.concatenate([p.closed for p in parts])[order], z=z[order])


def z_levels(zmin: float, zmax: float, step: float) -> np.ndarray:
    """Planes from the top down: ``zmax - k·step`` for k = 1, 2, ... while above ``zmin``."""
    n = int(math.floor((zmax - zmin) / step + 1e-9))
    z = zmax - step * np.arange(1, n + 1)
    return z[z > zmin]


@numba.njit(cache=True)
def _segments(V, F, tri_idx, lvl_idx, levels):
    n = tri_idx.shape[0]
    nv = V.shape[0]
    start_key = np.empty(n, np.int64)
    end_key = np.empty(n, np.int64)
    start_edge = np.empty((n, 2), np.int64)
    p0 = np.empty((n, 3))
    p1 = np.empty((n, 3))
    for s in range(n):
        t = tri_idx[s]
        z = levels[lvl_idx[s]]
        for k in range(3):
            a = F[t, k]
            b = F[t, (k + 1) % 3]
            above_a = V[a, 2] >= z
            above_b = V[b, 2] >= z
            if above_a == above_b:
                continue
            lo = min(a, b)
            hi = max(a, b)
            f = (z - V[lo, 2]) / (V[hi, 2] - V[lo, 2])
            x = V[lo, 0] + f * (V[hi, 0] - V[lo, 0])
            y = V[lo, 1] + f * (V[hi, 1] - V[lo, 1])
            key = (lvl_idx[s] * nv + lo) * nv + hi
            if above_a:  # from above to below: the segment starts here
                start_key[s] = key
                start_edge[s, 0] = lo
                start_edge[s, 1] = hi
                p0[s, 0] = x
                p0[s, 1] = y
                p0[s, 2] = z
            else:
                end_key[s] = key
                p1[s, 0] = x
                p1[s, 1] = y
                p1[s, 2] = z
    return start_key, end_key, start_edge, p0, p1


@numba.njit(cache=True)
def _chain(nxt, has_prev):
    n = nxt.shape[0]
    visited = np.zeros(n, np.bool_)
    order = np.empty(n, np.int64)
    offsets = [0]
    closed = []
    pos = 0
    for rnd in range(2):
        for s0 in range(n):
            if visited[s0] or (rnd == 0 and has_prev[s0]):
                continue
            s = s0
            is_closed = False
            while True:
                visited[s] = True
                order[pos] = s
                pos += 1
                s = nxt[s]
                if s < 0:
                    break
                if visited[s]:
                    is_closed = s == s0
                    break
            offsets.append(pos)
            closed.append(is_closed)
    return order, np.array(offsets, np.int64), np.array(closed, np.bool_)


@numba.njit(cache=True)
def _emit(fill, V, F, FN, tri_of, start_edge, p0, p1, order, offsets, closed, sample, arc_step,
          out_p, out_n, out_r):
    """Walk the chains and write CC points (when fill) or only count them; returns counts."""
    nchain = offsets.shape[0] - 1
    counts = np.zeros(nchain, np.int64)
    k = 0
    for c in range(nchain):
        first = offsets[c]
        last = offsets[c + 1]
        m = last - first
        k0 = k
        for j in range(m):
            seg = order[first + j]
            tb = tri_of[seg]
            nbx = FN[tb, 0]
            nby = FN[tb, 1]
            nbz = FN[tb, 2]
            # the point where this segment enters its facet
            if j == 0 and not closed[c]:
                if fill:
                    out_p[k, :] = p0[seg]
                    out_n[k, 0] = nbx
                    out_n[k, 1] = nby
                    out_n[k, 2] = nbz
                k += 1
            else:
                prev = order[first + (j - 1 if j > 0 else m - 1)]
                ta = tri_of[prev]
                nax = FN[ta, 0]
                nay = FN[ta, 1]
                naz = FN[ta, 2]
                cosang = min(1.0, max(-1.0, nax * nbx + nay * nby + naz * nbz))
                lo = start_edge[seg, 0]
                hi = start_edge[seg, 1]
                third = F[tb, 0]
                for q in range(3):
                    if F[tb, q] != lo and F[tb, q] != hi:
                        third = F[tb, q]
                side = ((V[third, 0] - V[lo, 0]) * nax + (V[third, 1] - V[lo, 1]) * nay
                        + (V[third, 2] - V[lo, 2]) * naz)
                if cosang > 1.0 - 1e-12:
                    steps = 0  # flat: one point, facet normal
                elif side < 0.0:
                    ang = math.acos(cosang)
                    steps = int(math.ceil(ang / arc_step))  # convex: turn the normal
                else:
                    steps = -1  # concave: bisector
                if steps <= 0:
                    if fill:
                        out_p[k, :] = p0[seg]
                        if steps == 0:
                            out_n[k, 0] = nbx
                            out_n[k, 1] = nby
                            out_n[k, 2] = nbz
                        else:
                            bx = nax + nbx
                            by = nay + nby
                            bz = naz + nbz
                            bn = math.sqrt(bx * bx + by * by + bz * bz)
                            if bn < 1e-9:
                                bx, by, bz, bn = nbx, nby, nbz, 1.0
                            out_n[k, 0] = bx / bn
                            out_n[k, 1] = by / bn
                            out_n[k, 2] = bz / bn
                            out_r[k] = 1.0 / max(math.sqrt(0.5 * (1.0 + cosang)), MIN_HALF_COS)
                    k += 1
                else:
                    ang = math.acos(cosang)
                    sa = math.sin(ang)
                    for q in range(steps + 1):
                        if fill:
                            f = q / steps
                            wa = math.sin((1.0 - f) * ang) / sa
                            wb = math.sin(f * ang) / sa
                            x = wa * nax + wb * nbx
                            y = wa * nay + wb * nby
                            z = wa * naz + wb * nbz
                            nn = math.sqrt(x * x + y * y + z * z)
                            out_p[k, :] = p0[seg]
                            out_n[k, 0] = x / nn
                            out_n[k, 1] = y / nn
                            out_n[k, 2] = z / nn
                        k += 1
            # points inside the facet, at most `sample` apart
            dx = p1[seg, 0] - p0[seg, 0]
            dy = p1[seg, 1] - p0[seg, 1]
            length = math.sqrt(dx * dx + dy * dy)
            inner = int(math.ceil(length / sample)) - 1
            for q in range(1, inner + 1):
                if fill:
                    f = q / (inner + 1)
                    out_p[k, 0] = p0[seg, 0] + f * dx
                    out_p[k, 1] = p0[seg, 1] + f * dy
                    out_p[k, 2] = p0[seg, 2]
                    out_n[k, 0] = nbx
                    out_n[k, 1] = nby
                    out_n[k, 2] = nbz
                k += 1
            if j == m - 1 and not closed[c]:
                if fill:
                    out_p[k, :] = p1[seg]
                    out_n[k, 0] = nbx
                    out_n[k, 1] = nby
                    out_n[k, 2] = nbz
                k += 1
        counts[c] = k - k0
    return counts


@numba.njit(cache=True)
def _feed_directions(points, offsets, closed):
    """Unit horizontal tangent at each point from its nearest distinct neighbours."""
    out = np.zeros_like(points)
    for c in range(offsets.shape[0] - 1):
        a = offsets[c]
        b = offsets[c + 1]
        m = b - a
        for i in range(a, b):
            fx = 0.0
            fy = 0.0
            for direction in (1, -1):
                j = i
                for _ in range(m):
                    j += direction
                    if j >= b or j < a:
                        if not closed[c]:
                            j = -1
                            break
                        j = a + (j - a) % m
                    dx = points[j, 0] - points[i, 0]
                    dy = points[j, 1] - points[i, 1]
                    if dx * dx + dy * dy > SAME_POINT * SAME_POINT:
                        break
                if j >= 0:
                    dx = points[j, 0] - points[i, 0]
                    dy = points[j, 1] - points[i, 1]
                    d = math.sqrt(dx * dx + dy * dy)
                    if d > 0.0:
                        fx += direction * dx / d
                        fy += direction * dy / d
            d = math.sqrt(fx * fx + fy * fy)
            if d > 0.0:
                out[i, 0] = fx / d
                out[i, 1] = fy / d
            else:
                out[i, 0] = 1.0
    return out


def slice_contours(mesh: Mesh, levels: np.ndarray, sample: float, arc_step: float) -> Contours:
    """Contours of ``mesh`` at heights ``levels (L,)`` mm, ordered from the top plane down.

    ``sample``: largest distance between neighbouring CC points (mm); ``arc_step``: largest turn
    of the normal between neighbouring CC points at a convex edge (rad).
    """
    V = mesh.vertices
    F = mesh.faces.astype(np.int64)
    FN = mesh.face_normals
    levels = np.asarray(levels, np.float64)
    asc = np.sort(levels)
    tz = V[F][:, :, 2]
    lo = np.searchsorted(asc, tz.min(axis=1), side="right")
    hi = np.searchsorted(asc, tz.max(axis=1), side="right")
    cnt = hi - lo
    memory.check(CUT_BYTES * float(cnt.sum()), f"{int(cnt.sum()):,} triangle cuts", "use a larger step_down", ("step_down",))
    tri_idx = np.repeat(np.arange(len(F)), cnt)
    lvl_idx = (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt) + np.repeat(lo, cnt))
    if len(V) ** 2 * max(1, len(asc)) >= 2 ** 62:
        raise InputError("mesh and plane count too large for one run")
    sk, ek, start_edge, p0, p1 = _segments(V, F, tri_idx, lvl_idx.astype(np.int64), asc)
    srt = np.argsort(sk, kind="stable")
    pos = np.searchsorted(sk[srt], ek)
    pos = np.minimum(pos, max(len(sk) - 1, 0))
    nxt = np.where((len(sk) > 0) & (sk[srt][pos] == ek), srt[pos], -1) if len(sk) else np.empty(0, np.int64)
    has_prev = np.zeros(len(sk), bool)
    has_prev[nxt[nxt >= 0]] = True
    order, offsets, closed = _chain(nxt.astype(np.int64), has_prev)
    # contours from the top plane down, then by their first segment for determinism
    chain_lvl = lvl_idx[order[offsets[:-1]]] if len(closed) else np.empty(0, np.int64)
    chain_key = np.lexsort((np.arange(len(closed)), -chain_lvl))
    order = np.concatenate([order[offsets[c]:offsets[c + 1]] for c in chain_key]) if len(closed) else order
    sizes = np.diff(offsets)[chain_key]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    closed = closed[chain_key]
    chain_lvl = chain_lvl[chain_key]
    args = (V, F, FN, tri_idx, start_edge, p0, p1, order, offsets, closed, float(sample), float(arc_step))
    empty = np.empty((0, 3))
    counts = _emit(False, *args, empty, empty, np.empty(0))
    total = int(counts.sum())
    memory.check(POINT_BYTES * float(total), f"{total:,} CC points", "use a larger step_down or sample", ("step_down", "sample"))
    out_p = np.empty((total, 3))
    out_n = np.empty((total, 3))
    out_r = np.ones(total)
    _emit(True, *args, out_p, out_n, out_r)
    pt_offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    feed = _feed_directions(out_p, pt_offsets, closed)
    keep = counts > 0
    return Contours(points=out_p, normals=out_n, feed=feed, reach=out_r, offsets=pt_offsets if keep.all() else
                    np.concatenate([[0], np.cumsum(counts[keep])]).astype(np.int64),
                    closed=closed[keep], z=asc[chain_lvl][keep])
