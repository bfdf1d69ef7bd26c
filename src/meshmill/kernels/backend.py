"""Which backend runs the kernels: ``cpu``, ``cuda``, or ``auto`` (CUDA when numba sees a usable
GPU, else the CPU); :class:`MeshKernels`, the kernels of one backend bound to one mesh, and
:class:`DexelKernels`, the dexel kernels of one backend. Only this package imports the backends'
modules (``cpu``, ``cpu_dexel``, ``cuda``); the CUDA module is imported only when chosen."""
from __future__ import annotations

import os
import sys

from ..errors import InputError
from .carve import BODY, RAPID, TILE  # noqa: F401  (the kinds of moves, the tiles of lines cutting runs over)
from .raycast import MAX_HITS  # noqa: F401  (crossings a line may have)

DEVICES = ("cpu", "cuda", "auto")


def _no_driver() -> bool:
    """True on a Linux machine without an NVIDIA device node (nor WSL's GPU node): no GPU can be
    there, so ``auto`` need not import numba's CUDA module (a fifth of a second) to learn it."""
    return sys.platform.startswith("linux") and not any(
        os.path.exists(p) for p in ("/dev/nvidiactl", "/dev/nvidia0", "/dev/dxg"))


def cuda_available() -> bool:
    if not _simulated() and _no_driver():
        return False
    try:
        from numba import cuda

        return bool(cuda.is_available())
    except Exception:  # numba-cuda missing or broken: no GPU for us
        return False


def _simulated() -> bool:
    import numba

    return bool(getattr(numba.config, "ENABLE_CUDASIM", 0))


def resolve(device: str) -> str:
    """``"cpu"`` or ``"cuda"`` for a ``--device`` value (raises :class:`InputError`)."""
    if device not in DEVICES:
        raise InputError(f"device must be one of {', '.join(DEVICES)}, got {device!r}", "device")
    if device == "cpu":
        return "cpu"
    if device == "auto" and _simulated():
        return "cpu"  # numba's CUDA simulator says a GPU is there: auto must not pick it (it is very slow)
    if cuda_available():
        return "cuda"
    if device == "cuda":
        raise InputError("device cuda: no usable CUDA GPU (numba.cuda.is_available() is false); use device cpu or auto",
                         "device")
    return "cpu"


def _backend(device: str, dexel: bool = False):
    """The module of the backend (``"cpu"`` or ``"cuda"``) offering its mesh kernels, or with
    ``dexel`` its dexel kernels (the CUDA module offers both)."""
    if device == "cuda":
        from . import cuda

        return cuda
    if dexel:
        from . import cpu_dexel

        return cpu_dexel
    from . import cpu

    return cpu


def _check(device: str) -> None:
    if device not in ("cpu", "cuda"):
        raise ValueError(f"device must be 'cpu' or 'cuda' (resolve '{device}' first)")


class MeshKernels:
    """The mesh kernels of one backend bound to the mesh of ``bvh`` (a
    :class:`~meshmill.kernels.bvh.BVH`) and, for the checks that tell inside from outside, to
    ``inside`` (:attr:`meshmill.geometry.solid.Solid.inside`); on CUDA their arrays are copied to
    the GPU once, here, and stay there for every call. Arguments and results are host numpy
    arrays, as documented in :mod:`meshmill.kernels.cpu`."""

    def __init__(self, bvh, device: str = "cpu", inside=None, drop_on_inside: bool = False):
        _check(device)
        self.bvh, self.device = bvh, device
        self.impl = _backend(device)
        self.mesh = self.impl.to_device(bvh) if device == "cuda" else bvh.arrays
        self.inside = None
        if inside is not None:
            self.inside = self.impl.inside_to_device(inside) if device == "cuda" else inside
        # what drops meet: with ``drop_on_inside`` (:attr:`~meshmill.geometry.solid.Solid.floor_below_sheets`)
        # the faces deciding inside (the mesh's and the caps of its holes), without the curtains and
        # floor under its sheets (a third as many triangles on a terrain; the same heights)
        self.top = self.inside[:5] if drop_on_inside and self.inside is not None else self.mesh

    def mesh_distances(self, points, cap=1e150):
        return self.impl.mesh_distances(points, self.mesh, cap)

    def largest_ball(self, cc, normals, radii, tol):
        return self.impl.largest_ball(cc, normals, radii, tol, self.mesh)

    def axis_search(self, ce, feed, side, tool, candidates, cand_tilt, slack, radius, body, offsets):
        return self.impl.axis_search(ce, feed, side, tool, candidates, cand_tilt, slack, radius, body, offsets,
                                     self.mesh)

    def _inside(self):
        if self.inside is None:
            raise ValueError("these kernels were bound without the solid's inside arrays")
        return self.inside

    def pose_penetration(self, tip, axis, tool, grow, rings, segs, base, stop=-1.0):
        return self.impl.pose_penetration(tip, axis, tool, grow, rings, segs, base, self.mesh, self._inside(), stop)

    def intervals_clear(self, tip_a, axis_a, tip_b, axis_b, tool, grow, limit, rings, segs, base):
        return self.impl.intervals_clear(tip_a, axis_a, tip_b, axis_b, tool, grow, limit, rings, segs, base,
                                         self.mesh)

    def points_inside(self, points):
        return self.impl.points_inside(points, self._inside())

    def drop_cutter(self, xy, radius, corner_radius, floor, body=None):
        return self.impl.drop_cutter(xy, radius, corner_radius, floor, self.top, body)

    @property
    def refines(self) -> bool:
        """Whether :meth:`drop_refined` is compiled here (the CPU's; elsewhere the refinement's
        rounds drop their midpoints by :meth:`drop_cutter`)."""
        return hasattr(self.impl, "drop_refined")

    def drop_refined(self, xy, radius, corner_radius, floor, grow, chord_tol, min_step, rounds, body=None):
        return self.impl.drop_refined(xy, radius, corner_radius, floor, grow, chord_tol, min_step, rounds, self.top,
                                      body)

    def touch_points(self, inside_xy, outside_xy, f_inside, f_outside, z, radius, corner_radius, floor, touch,
                     width, rounds, body=None, inside_contacts=None):
        return self.impl.touch_points(inside_xy, outside_xy, f_inside, f_outside, z, radius, corner_radius, floor,
                                      self.top, touch, width, rounds, body, inside_contacts)

    def rays_blocked(self, origins, direction, tmin):
        return self.impl.rays_blocked(origins, direction, tmin, self.mesh)


class DexelKernels:
    """The dexel kernels (seed 000) of one backend: lines cast through the mesh ``index`` (none
    needed to cut), moves binned into tiles of lines and cut from them. ``index``: ``("bvh",
    BVH.arrays)``, or on the CPU also the seed's cells and k-means partitions (``("boxes", ...)``,
    :func:`meshmill.kernels.cpu_dexel.cast_lines`); on CUDA it is copied to the GPU once, here.
    Arguments and results are host numpy arrays, as documented in :mod:`meshmill.kernels.cpu_dexel`;
    binning, and the few lines decided point by point, run on the CPU whatever the device."""

    def __init__(self, device: str = "cpu", index=None):
        _check(device)
        if device == "cuda" and index is not None and index[0] != "bvh":
            raise InputError("the cells and k-means indexes run on the CPU only: use index bvh with device cuda",
                             ("index", "device"))
        self.device = device
        self.impl = _backend(device, dexel=True)
        self.host = _backend("cpu", dexel=True)
        self.index = index
        if device == "cuda" and index is not None:
            from types import SimpleNamespace

            self.index = self.impl.to_device(SimpleNamespace(arrays=index[1]))

    def cast_lines(self, a, lu, lv, step, nu, nv, first_row=0):
        """``(dense (lines, cap, 2), count (lines,))``: the material intervals of the ``nu x nv``
        lines along axis ``a`` of the lattice from ``(lu, lv)``, ``step`` mm apart, from its row
        ``first_row`` on (a block of rows: the same lines as the whole lattice's)."""
        if self.index is None:
            raise ValueError("these dexel kernels were bound without a mesh index")
        return self.impl.cast_lines(a, lu, lv, step, nu, nv, self.index, first_row)

    def solid_lines(self, a, lines, lu, lv, step, nv, bvh, inside, first_row=0):
        """``(dense (k, cap, 2), count (k,), uneven (k,) bool)``: the material of the solid
        ``inside`` holds on the grid ``lines`` along axis ``a``, decided between the crossings of
        its check mesh (``bvh``) by its inside test (see
        :func:`meshmill.kernels.cpu_dexel.solid_lines`), on the CPU."""
        return self.host.solid_lines(a, lines, lu, lv, step, nv, bvh, inside, first_row)

    def points_inside(self, points, inside):
        """``(k,) bool``: whether each of ``points (k, 3)`` lies in the material of a
        :attr:`~meshmill.geometry.solid.Solid.inside`, on the CPU."""
        return _backend("cpu").points_inside(points, inside)

    def bin_moves(self, box, lu, lv, step, nu, nv):
        """``(tile_start, tile_moves, work)``: the moves of each tile of :data:`TILE` x TILE lines
        and the lines they cover (see :func:`meshmill.kernels.cpu_dexel.bin_moves`), on the CPU."""
        return self.host.bin_moves(box, float(lu), float(lv), float(step), int(nu), int(nv))

    def group_moves(self, ca, cb, xa, xb, sag, H, radius, limit, most):
        """``(group (k,), bound (g, 10))``: consecutive moves gathered under one bound (see
        :func:`meshmill.kernels.cpu_dexel.group_moves`), on the CPU."""
        return self.host.group_moves(ca, cb, xa, xb, sag, H, radius, float(limit), int(most))

    def move_constants(self, pa, pb, xa, xb, corner, flutes):
        """``(chord (k, 6), plane (k, 4))``: what every line a move crosses needs."""
        return self.impl.move_constants(pa, pb, xa, xb, corner, flutes)

    def cut_tiles(self, lu, lv, step, nu, nv, iv, off, count, tiles, combs, split, tile_start, tile_moves, pa, pb, xa,
                  xb, radius, corner, flutes, strips, chord, plane, box, kind, group, gbound, gbox, hit_min, hit, todo,
                  redo, row0=0, probe=None, load=None):
        """Cut the lines of the rows ``combs (mod split)`` of ``tiles`` (those set in ``todo``, or
        all when it is empty) by their moves, ``iv, count, hit, redo`` in place, a line skipping
        the moves of a group (``group (k,)``, ``gbound (g, 10)``, ``gbox (g, 6)``) where it holds no
        material in their bound (see :func:`meshmill.kernels.cpu_dexel.cut_tiles`); with ``probe
        (k, 6)`` each move's load
        gathered in ``load`` (:meth:`new_load`)."""
        if probe is None:
            import numpy as np

            probe, load = np.zeros((0, 6)), np.zeros((1, 0, 5))
        self.impl.cut_tiles(lu, lv, step, nu, nv, iv, off, count, tiles, combs, split, tile_start, tile_moves, pa, pb,
                            xa, xb, radius, corner, flutes, strips, chord, plane, box, kind, group, gbound, gbox,
                            hit_min, hit, todo, redo, row0, probe, load)

    def new_load(self, k: int) -> np.ndarray:
        """``(T, k, 5)``: what :meth:`cut_tiles` gathers each move's load in (T threads that add
        to it apart: the CPU's; one on a GPU, whose threads add atomically), empty: nothing
        removed, no extent (see :func:`meshmill.simulation.load.reduce_load`)."""
        import numba
        import numpy as np

        threads = numba.get_num_threads() if self.device == "cpu" else 1
        load = np.zeros((threads, k, 5))
        load[:, :, 1] = load[:, :, 3] = -np.inf
        load[:, :, 2] = load[:, :, 4] = np.inf
        return load


def cutter_rise(rho, radius, corner_radius) -> float:
    """Height (mm) of a cutter's profile above its tip at ``rho`` mm from its axis (flat, ball or
    bull-nose of ``radius`` and ``corner_radius``), on the host."""
    from . import cpu

    return cpu.cut.profile(rho, radius, corner_radius)


def bind(bvh_or_kernels, device: str = "cpu") -> MeshKernels:
    """``bvh_or_kernels`` itself if it is a :class:`MeshKernels`, else that BVH bound to ``device``."""
    if isinstance(bvh_or_kernels, MeshKernels):
        return bvh_or_kernels
    return MeshKernels(bvh_or_kernels, device)


def solid_kernels(mesh, device: str = "cpu", floor=None) -> MeshKernels:
    """The kernels of ``device`` bound to the solid ``mesh`` bounds (its check mesh and inside
    arrays, :meth:`meshmill.geometry.mesh.Mesh.solid`), sheets down to ``floor`` (default: the
    mesh's lowest point)."""
    from .bvh import build_bvh

    solid = mesh.solid(floor)
    return MeshKernels(build_bvh(solid.vertices, solid.faces), device, inside=solid.inside,
                       drop_on_inside=solid.floor_below_sheets)
