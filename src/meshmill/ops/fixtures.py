"""Fixtures: solids no cutter, shank or holder may enter (a vice, a base plate, clamps). A path
is kept clear of them by leaving out the moves that would enter one and linking over each
stretch left out (:func:`clear_fixtures`), then checked against them again."""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..params import FixtureParams


@dataclass(frozen=True)
class Fixture:
    """A named solid: a box ``(2, 3)`` in the work frame, or a closed mesh ``file`` (in the part
    file's frame with ``frame = "part"``, placed as the part was) or a loaded ``mesh``."""

    name: str
    box: tuple | None = None
    file: str = ""
    frame: str = "part"
    mesh: object = None

    TOUCH = 1e-3  # mm: a fixture may touch the part (it sits on a plate, in a vice): deeper is an overlap

    @staticmethod
    def overlapping(part, fixtures) -> list[str]:
        """The names of ``fixtures`` whose solids overlap ``part`` (:func:`overlapping`)."""
        return overlapping(part, fixtures)

    @classmethod
    def from_dict(cls, d: dict, folder: str = "", number: int = 1) -> "Fixture":
        """The fixture of a job file's ``[[fixtures]]`` table (:class:`~meshmill.params.FixtureParams`;
        ``file`` relative to ``folder``)."""
        if not isinstance(d, dict):
            raise InputError(f"fixture {number} must be a table (name, box or file), got {d!r}", "fixtures")
        name = d.get("name") if isinstance(d.get("name"), str) else None
        try:
            p = FixtureParams.checked(d, "a fixture")
        except InputError as exc:
            raise exc.within(f"fixture '{name}'" if name else f"fixture {number}") from None
        return cls(p.name or f"fixture {number}", p.box, os.path.join(folder, p.file) if p.file else "", p.frame)

    def solid(self, part):
        """The closed mesh in the work frame (``part``: the part it is placed with)."""
        from ..geometry import shapes
        from ..simulation.stock import placed_solid

        if self.mesh is not None:
            return self.mesh
        if self.box is not None:
            return shapes.box(np.array(self.box[:3], float), np.array(self.box[3:], float))
        return placed_solid(self.file, part, self.frame, f"fixture '{self.name}'")


def union(meshes):
    """One mesh of ``meshes`` (closed solids apart from each other)."""
    from ..geometry.mesh import mesh_from_arrays

    verts, faces, base = [], [], 0
    for m in meshes:
        verts.append(m.vertices)
        faces.append(m.faces + base)
        base += len(m.vertices)
    return mesh_from_arrays(np.vstack(verts), np.vstack(faces), "fixtures")


TOUCH = Fixture.TOUCH


def overlapping(part, fixtures) -> list[str]:
    """The names of the ``fixtures`` (:class:`Fixture`) whose solid overlaps the part's by more than
    :data:`TOUCH`: a vertex, or a point a tenth along an edge, of either deeper inside the other."""
    from ..kernels.backend import solid_kernels

    found = []
    part_kern = solid_kernels(part, "cpu")
    for f in fixtures:
        solid = f.solid(part)
        if _inside(_edge_points(solid), part_kern) or _inside(_edge_points(part), solid_kernels(solid, "cpu")):
            found.append(f.name)
    return found


def _edge_points(mesh) -> np.ndarray:
    """``(k, 3)``: the vertices of ``mesh`` and the points a tenth apart along its edges."""
    tri = mesh.vertices[mesh.faces]
    ends = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    f = np.linspace(0.1, 0.9, 9)
    points = ends[:, 0, None, :] + f[None, :, None] * (ends[:, 1, None, :] - ends[:, 0, None, :])
    return np.vstack([mesh.vertices, points.reshape(-1, 3)])


def _inside(points, kern) -> bool:
    """Whether one of ``points (k, 3)`` lies inside the solid of ``kern`` deeper than :data:`TOUCH`."""
    inside = np.asarray(kern.points_inside(points), bool)
    return bool(inside.any() and (kern.mesh_distances(points[inside]) > TOUCH).any())


def clear_fixtures(tp, tools, fixtures_mesh, safe_z: float, device: str = "cpu", label: str = ""):
    """``(toolpath, trimmed moves, its check against the fixtures)``: ``tp`` with the moves that
    bring a cutter, shank or holder into the solid ``fixtures_mesh`` left out; each stretch left
    out is linked over (a rapid up the tool axis to ``safe_z``, across, and down to the next point
    kept at feed). Raises :class:`InputError` when the links themselves enter a fixture."""
    from ..kernels.backend import solid_kernels
    from ..pathing.verify import verify_toolpath
    from ..toolpath.model import Toolpath, lift

    where = f"{label}: " if label else ""
    fix_kern = solid_kernels(fixtures_mesh, device)
    report = verify_toolpath(fix_kern, tp, tools, 0.0)
    bad = np.zeros(len(tp), bool)
    bad[report.pop("problem_moves")] = True  # the move into point i
    if not bad.any():
        return tp, 0, report
    # a point is kept when neither move at it enters a fixture
    keep = ~bad & ~np.r_[bad[1:], False]
    tips, axes, rapid, tool, feed = [], [], [], [], []
    prev = None
    for i in np.nonzero(keep)[0]:
        if prev is not None and i != prev + 1:  # a stretch left out: link over it
            a, b = lift(tp.tip[prev], tp.axis[prev], safe_z), lift(tp.tip[i], tp.axis[i], safe_z)
            tips += [a, b]
            axes += [tp.axis[prev], tp.axis[i]]
            rapid += [True, True]
            tool += [tp.tool[prev], tp.tool[i]]
            feed += [np.nan, np.nan]
            tips.append(tp.tip[i])  # down at feed: the stretch below was not cut
            axes.append(tp.axis[i])
            rapid.append(False)
        else:
            tips.append(tp.tip[i])
            axes.append(tp.axis[i])
            rapid.append(bool(tp.rapid[i]) if prev is not None else True)
        tool.append(tp.tool[i])
        feed.append(tp.feed[i])
        prev = i
    if not tips:
        raise InputError(f"{where}every move enters a fixture")
    out = Toolpath(np.array(tips), np.array(axes), np.array(rapid), np.array(tool, np.int64), None,
                   np.array(feed, float), tp.source, list(tp.warnings))
    again = verify_toolpath(fix_kern, out, tools, 0.0)
    again.pop("problem_moves")
    if not again["ok"]:
        raise InputError(f"{where}the path cannot be linked clear of the fixtures ({again['worst'][0]}): raise the "
                         "job's clearance or move the fixture", "clearance")
    return out, int(bad.sum()), again
