"""The stock: the material a part is machined from, as one value (:class:`Stock`).

Made from a box around the part, a cylinder, a closed mesh, or the part itself with an allowance
on it; given to any operation as ``stock=`` (its rapids keep clear of it, its shank and holder
stay out of it, rest machining measures depths from its surface). Cut by a tool path it becomes
the in-process stock: triple dexels (:mod:`meshmill.simulation.cut`) on a lattice of ``step`` mm,
whose :meth:`Stock.cut` returns the stock after the path and what the cut found, and whose hull
(a closed mesh around every dexel) and surface stand for it in the next operation. Saved and
loaded as a dexel model (``stock.npz``). Units: mm, mm^3.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import InputError
from ..params import StockParams

CYLINDER_SEGMENTS = 128
KINDS = ("box", "cylinder", "mesh", "offset", "dexels")


@dataclass(frozen=True)
class Stock:
    """The stock. Describe it with :meth:`box`, :meth:`cylinder`, :meth:`mesh`, :meth:`offset` (or
    :meth:`from_dict`, a job file's ``[stock]``); :meth:`dexels` turns it into the in-process
    stock of a part, which :meth:`cut` cuts and :meth:`save` / :meth:`load` keep."""

    kind: str = "box"
    side: float = 0.0
    top: float = 0.0
    bottom: float = 0.0
    diameter: float | None = None
    allowance: float = 0.0
    file: str = ""
    frame: str = "work"
    given: object = None  # mesh: the closed Mesh given (else read from ``file``)
    state: object = field(default=None, repr=False, compare=False)  # dexels: the _Dexels

    # ------------------------------------------------------------ descriptions

    @classmethod
    def box(cls, margin: float = 0.0, *, side=None, top=None, bottom=None) -> "Stock":
        """The part's box grown by ``margin`` mm (``side``, ``top``, ``bottom`` each, if given)."""
        return cls.from_dict(dict(type="box", margin=margin, side=side, top=top, bottom=bottom))

    @classmethod
    def cylinder(cls, diameter=None, *, margin: float = 0.0, side=None, top=None, bottom=None) -> "Stock":
        """A round bar about Z through the part's box centre: ``diameter`` mm, or the part's widest
        radius plus the side margin; ``top`` and ``bottom`` margins."""
        return cls.from_dict(dict(type="cylinder", diameter=diameter, margin=margin, side=side, top=top,
                                  bottom=bottom))

    @classmethod
    def mesh(cls, mesh, frame: str = "work") -> "Stock":
        """A closed mesh: a loaded Mesh (in the work frame), or a file in the work frame or, with
        ``frame = "part"``, in the part file's frame (placed as the part was)."""
        if hasattr(mesh, "vertices"):
            if not mesh.closed:
                raise InputError(f"{mesh.source or 'the stock'}: the stock mesh is open (not watertight)", "stock")
            return cls(kind="mesh", given=mesh, file=mesh.source or "", frame="work")
        if not isinstance(mesh, (str, os.PathLike)):
            raise InputError(f"stock must be a closed mesh file or a Mesh, got {mesh!r}", "stock")
        return cls.from_dict(dict(type="mesh", file=os.fspath(mesh), frame=frame))

    @classmethod
    def offset(cls, allowance: float) -> "Stock":
        """The part with ``allowance`` mm of material on it (on every dexel end, once cut)."""
        return cls.from_dict(dict(type="offset", allowance=allowance))

    @classmethod
    def of(cls, value, default: str | None = None):
        """``value`` as a Stock: a Stock, a closed Mesh, ``"box"``; None is ``default`` (``"box"``,
        ``"offset"``: the part with :data:`~meshmill.tolerances.STOCK_ALLOWANCE` on it, or None)."""
        from ..tolerances import STOCK_ALLOWANCE

        if value is None:
            value = default
        if value is None or isinstance(value, cls):
            return value
        if value == "box":
            return cls.box()
        if value == "offset":
            return cls.offset(STOCK_ALLOWANCE)
        return cls.mesh(value)

    @classmethod
    def from_dict(cls, d: dict, folder: str = "") -> "Stock":
        """The stock of a job file's ``[stock]`` table (:class:`~meshmill.params.StockParams`;
        ``file`` relative to ``folder``)."""
        if not isinstance(d, dict):
            raise InputError(f"stock must be a table (type, margin, ...), got {d!r}", "stock")
        try:
            p = StockParams.checked({k: v for k, v in d.items() if v is not None}, "a stock")
        except InputError as exc:
            raise exc.within("[stock]") from None
        side, top, bottom = (p.margin if v is None else v for v in (p.side, p.top, p.bottom))
        return cls(kind=p.type, side=side, top=top, bottom=bottom, diameter=p.diameter,
                   allowance=p.allowance if p.type == "offset" else 0.0,
                   file=os.path.join(folder, p.file) if p.file else "", frame=p.frame)

    @classmethod
    def load(cls, path, part=None) -> "Stock":
        """The in-process stock saved by :meth:`save` (a dexel model, ``stock.npz``), of ``part``."""
        from .cut import stock_from_model
        from .dexel import load_npz

        model = load_npz(path)
        inner = model.lo + model.step  # the bounds whose lattice (one empty cell around) is the model's
        bounds = np.array([inner, inner + (model.n - 2) * model.step * (1.0 - 1e-12)])
        return cls(kind="dexels", state=_Dexels(part, model, stock_from_model(model), model, None, None, bounds))

    # ------------------------------------------------------------ as an operation sees it

    @property
    def cut_already(self) -> bool:
        """An in-process stock: triple dexels (:meth:`dexels`, :meth:`load`)."""
        return self.kind == "dexels"

    def solid(self, part):
        """The closed stock :class:`~meshmill.geometry.mesh.Mesh` in the work frame, or None for an
        offset stock (the part's dexels lengthened) and an in-process one (see :meth:`material`)."""
        from ..geometry import shapes

        if self.kind == "dexels":
            return self.state.solid
        lo, hi = part.bounds
        if self.kind == "box":
            return shapes.box(lo - [self.side, self.side, self.bottom], hi + [self.side, self.side, self.top])
        if self.kind == "cylinder":
            centre = 0.5 * (lo + hi)
            widest = float(np.hypot(*(part.vertices[:, :2] - centre[:2]).T).max())
            radius = 0.5 * self.diameter if self.diameter else widest + self.side
            if radius < widest - 1e-9:
                raise InputError(f"diameter {2 * radius:g} mm is narrower than the part ({2 * widest:.3f} mm)",
                                 "diameter")
            ring = radius / math.cos(math.pi / CYLINDER_SEGMENTS)  # the polygon holds the round bar
            z0, z1 = lo[2] - self.bottom, hi[2] + self.top
            m = shapes.revolve([0.0, ring, ring, 0.0], [z0, z0, z1, z1], CYLINDER_SEGMENTS, "cylinder stock")
            m.vertices[:, :2] += centre[:2]
            return m
        if self.kind == "mesh":
            return self.given if self.given is not None else placed_solid(self.file, part, self.frame, "stock")
        return None

    def material(self, part):
        """``(mesh or None, allowance mm, margin mm)``: what rapids keep clear of and shanks and
        holders stay out of, a closed mesh or the part grown by ``allowance``; ``margin``: how far
        the mesh may lie inside the material (half a dexel cell for an in-process stock), which
        clearances from it add."""
        if self.kind == "offset":
            return None, self.allowance, 0.0
        if self.kind == "dexels":
            s = self.state
            return (s.solid if s.solid is not None and not s.cut else self.hull(), 0.0, 0.5 * s.model.step)
        return self.solid(part), 0.0, 0.0

    def rest_surface(self, part):
        """The surface rest machining measures depths from (None: an offset stock not yet cut)."""
        if self.kind == "offset":
            return None
        if self.kind == "dexels":
            s = self.state
            return s.solid if s.solid is not None and not s.cut else self.surface_mesh()
        return self.solid(part)

    # ------------------------------------------------------------ the in-process stock

    def dexels(self, part, step: float, bounds=None, device: str = "cpu", cluster=None) -> "Stock":
        """This stock around ``part`` as triple dexels ``step`` mm apart, ready to :meth:`cut`:
        on a lattice over ``bounds (2, 3)`` (default: the stock's and the part's box; an offset
        stock's, the part's box grown by the allowance and a step)."""
        from .cut import stock_from_model
        from .dexel import dexelize

        if self.kind == "dexels":
            return self
        solid = self.solid(part)
        if bounds is None:
            if solid is not None:
                bounds = np.array([np.minimum(solid.bounds[0], part.bounds[0]),
                                   np.maximum(solid.bounds[1], part.bounds[1])])
            else:
                pad = self.allowance + step
                bounds = part.bounds + np.array([[-pad], [pad]])
        design = dexelize(part, step, bounds=bounds, device=device, cluster=cluster)
        start = design if solid is None else dexelize(solid, step, bounds=bounds, device=device, cluster=cluster)
        cutting = stock_from_model(start, self.allowance)
        model = cutting.to_model("stock")
        return replace(self, kind="dexels", state=_Dexels(part, model, cutting, model, design, solid,
                                                          np.asarray(bounds, float), description=self))

    def cut(self, toolpath, tools, tolerance: float = 0.01, mode: str = "sweep", device: str = "cpu", cluster=None,
            progress=None, name: str = "machined", load: bool = False) -> tuple["Stock", dict]:
        """``(the stock after toolpath, what the cut found)``: its cutters remove material, its
        shanks and holders (grown by ``tolerance`` less) collide with what is left; the figures of
        :func:`cut_figures` (rapids that cut, collisions, feed in material and in air) and, with
        ``load``, ``"removed"``: what each move removed, how deep and how wide
        (:class:`~meshmill.simulation.load.RemovedByMove`)."""
        from . import cut as cutting

        if self.kind != "dexels":
            raise InputError("the stock is not cut yet: make its dexels first (Stock.dexels(part, step))", "stock")
        s = self.state
        st = copy_cutting(s.cutting)
        moves = path_moves(toolpath, tools, tolerance, mode)
        if progress:
            progress(f"cutting {len(moves):,} moves ({len(toolpath):,} points, mode {mode})")
        result = cutting.cut(st, moves, progress=progress, device=device, cluster=cluster,
                             load=len(toolpath) if load and mode == "sweep" else 0)
        figures = cut_figures(toolpath, len(moves), result)
        if "load" in result:
            figures["removed"] = result["load"]
        after = _Dexels(s.part, st.to_model(name), st, s.start, s.design, s.solid, s.bounds, cut=True,
                        description=s.description)
        return replace(self, state=after), figures

    def named(self, name: str) -> "Stock":
        """The same in-process stock, its model called ``name`` (as :meth:`save` writes it)."""
        s = self.state
        return replace(self, state=replace(s, model=replace(s.model, name=name)))

    def holds(self, part) -> None:
        """Raise :class:`InputError` where the stock does not hold ``part``: a mesh stock that some
        of the part's vertices lie outside of (by more than a micrometre)."""
        from ..kernels.backend import solid_kernels

        if self.kind != "mesh":
            return
        solid = self.solid(part)
        kern = solid_kernels(solid, "cpu")
        out = ~np.asarray(kern.points_inside(part.vertices), bool)
        if out.any():
            far = kern.mesh_distances(part.vertices[out])
            if far.max() > 1e-3:
                raise InputError(f"the stock mesh does not hold the part: {int((far > 1e-3).sum())} of its vertices lie "
                                 f"outside it, up to {far.max():.3f} mm (check the stock's frame and the part's set-up)",
                                 "stock")

    @property
    def model(self):
        """The :class:`~meshmill.simulation.dexel.DexelModel` of an in-process stock."""
        if self.kind != "dexels":
            raise InputError("the stock is not cut yet: make its dexels first (Stock.dexels(part, step))", "stock")
        return self.state.model

    @property
    def volume(self) -> float:
        """mm^3 of an in-process stock."""
        return self.model.volume

    def hull(self):
        """A closed mesh around every dexel of the in-process stock
        (:func:`~meshmill.simulation.surface.stock_hull`)."""
        from ..geometry.mesh import closed_mesh
        from .surface import stock_hull

        s = self.state
        if s.hull is None:
            s.hull = closed_mesh(*stock_hull(self.model), self.model.name)
        return s.hull

    def surface(self) -> tuple:
        """``(vertices, faces, stride)``: the in-process stock's surface
        (:func:`~meshmill.simulation.surface.machined_mesh`)."""
        from .surface import machined_mesh

        s = self.state
        if s.surface is None:
            s.surface = machined_mesh(self.model)
        return s.surface

    def surface_mesh(self):
        """:meth:`surface` as a closed :class:`~meshmill.geometry.mesh.Mesh` (what rest depths are
        measured from)."""
        from ..geometry.mesh import closed_mesh

        v, f, _ = self.surface()
        return closed_mesh(v, f, self.model.name)

    def measure(self, tolerance: float, samples: bool = True, device: str = "cpu", progress=None):
        """The in-process stock against its part: ``(deviation, volumes, warnings, (points, e))``
        (:func:`~meshmill.simulation.deviation.measure`)."""
        from .deviation import measure
        from .dexel import dexelize

        s = self.state
        if s.part is None:
            raise InputError("the stock has no part to be measured against (Stock.load(path, part))", "stock")
        if s.design is None:
            s.design = dexelize(s.part, s.model.step, bounds=s.bounds, device=device)
        return measure(s.model, s.start, s.part, s.design, float(s.bounds[0, 2]), tolerance, s.model.step, device,
                       samples, progress)

    def save(self, path) -> None:
        """Write the in-process stock as a dexel model (``.npz``, :func:`~meshmill.simulation.dexel.save_npz`)."""
        from .dexel import save_npz

        save_npz(path, self.model)

    def summary(self) -> dict:
        """What the stock is, as job.json says it."""
        d = self.state.description if self.kind == "dexels" and self.state.description else self
        out = {"type": d.kind}
        if d.kind in ("box", "cylinder"):
            out.update(side=d.side, top=d.top, bottom=d.bottom)
        if d.kind == "cylinder" and d.diameter:
            out["diameter"] = d.diameter
        if d.kind == "offset":
            out["allowance"] = d.allowance
        if d.kind == "mesh":
            out.update(file=os.path.abspath(d.file) if d.file else "", frame=d.frame)
        return out


@dataclass
class _Dexels:
    """An in-process stock: its ``part``, ``model`` (DexelModel) and mutable ``cutting`` dexels, the
    ``start`` model (the stock before any cut) and the part's ``design`` model on the same lattice,
    the ``solid`` it was made from (None: an offset or a loaded stock), the ``bounds (2, 3)`` its
    lattice was made over, whether it was ``cut``, its ``description`` and the hull and surface
    once made."""

    part: object
    model: object
    cutting: object
    start: object
    design: object
    solid: object
    bounds: np.ndarray
    cut: bool = False
    description: object = None
    hull: object = None
    surface: object = None


def placed_solid(path, part, frame: str, what: str):
    """The closed mesh of file ``path`` in the work frame: placed as ``part`` was (``frame``
    "part") or as it is ("work")."""
    from ..geometry.mesh import load_mesh, mesh_from_arrays

    mesh = load_mesh(path)
    if frame == "part" and part is not None and part.placement is not None:
        mesh = mesh_from_arrays(part.placement.apply(mesh.vertices), mesh.faces, os.path.basename(path))
        mesh.source = os.path.abspath(path)
    if not mesh.closed:
        raise InputError(f"{path}: the {what} mesh is open (not watertight)", what if what == "stock" else ())
    return mesh


# ---------------------------------------------------------------- cutting a path


def copy_cutting(st):
    """A copy of the mutable dexels ``st`` (:class:`~meshmill.simulation.cut.Stock`) to cut on."""
    return replace(st, iv=[x.copy() for x in st.iv], off=[x.copy() for x in st.off], count=[x.copy() for x in st.count])


def path_moves(toolpath, tools, tolerance=0.01, mode="sweep"):
    """The pieces a path cuts (``mode`` sweep: with its shanks and holders, grown by ``tolerance``
    less, checked against the stock they pass; points: the tool at the points, the seed's)."""
    from . import cut as cutting

    moves = cutting.toolpath_moves(toolpath, tools, mode)
    if mode == "sweep":
        moves = cutting.Moves.merge(moves, cutting.body_moves(toolpath, tools, tolerance))
    return moves


def cut_figures(toolpath, pieces: int, result: dict) -> dict:
    """The summary's figures of a cut (``result`` of :func:`~meshmill.simulation.cut.cut` with
    ``pieces`` moves): ``pieces_cut``, the rapid moves that cut and the moves that collide
    (counts, tool-path point indices, ``errors`` lines), ``cutting_mm`` (feed length in material
    and in air) and ``seconds``."""
    errors = [f"rapid move to point {i} (source line {int(toolpath.line[i])}) cuts material"
              for i in result["rapid_cuts"][:1000]]
    errors += [f"move to point {i} (source line {int(toolpath.line[i])}): the shank or holder meets the stock"
               for i in result["collisions"][:1000]]
    step_mm = np.r_[0.0, np.linalg.norm(np.diff(toolpath.tip, axis=0), axis=1)]
    feed = ~np.asarray(toolpath.rapid, bool)
    if len(feed):
        feed[0] = False
    in_material = np.zeros(len(toolpath), bool)
    in_material[result["in_material"]] = True
    material_mm = float(step_mm[feed & in_material].sum())
    air_mm = float(step_mm[feed & ~in_material].sum())
    return {"pieces_cut": pieces,
            "rapid_moves_cutting": len(result["rapid_cuts"]),
            "rapid_cutting_points": result["rapid_cuts"][:1000],
            "colliding_moves": len(result["collisions"]),
            "colliding_points": result["collisions"][:1000],
            "errors": errors,
            "cutting_mm": {"in_material": material_mm, "in_air": air_mm,
                           "air_share": air_mm / (air_mm + material_mm) if air_mm + material_mm > 0 else 0.0},
            "seconds": result["seconds"]}
