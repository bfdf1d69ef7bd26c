"""Every operation's options, each defined once (:mod:`meshmill.options`): the API's keyword
arguments in the order of its signature, the command's flags, a job file's keys.

A class per API function; the fields shared by several (tolerance, clearance, device, ...) are
made by one function each, so that their name, unit, default and help are written once. Objects
(a part, a tool table, a stock, a machine) are options of kind ``object`` whose ``role`` names
the API's converter (a file name is read, a value of the wrong type refused). Units: mm, degrees,
mm/min.
"""
from __future__ import annotations

from dataclasses import dataclass

from .errors import InputError
from .options import REQUIRED, Params, option
from .tolerances import GOUGE_TOL, HOLDER_CLEARANCE, STOCK_ALLOWANCE

MESH_FORMATS = "STL, OBJ, PLY; STEP, IGES with meshmill[step]"
DEVICES = ("cpu", "cuda", "auto")
MAX_COORDINATE = 1e6  # mm: a kilometre is no machine's travel
MAX_PARTITIONS = 4096  # cells or k-means clusters of a dexel model (every line tests every partition box)
WEIGHTINGS = ("area", "angle", "uniform")
CLUSTERINGS = ("kmeans", "rpcl", "ward")
METRICS = ("euclidean", "mahalanobis", "std", "std2", "pca")
OUTPUTS = ("deviation", "mesh")  # what simulate may keep beyond the summary


# ---------------------------------------------------------------- shared options


def _part(what="part"):
    return option("object", f"{what} mesh ({MESH_FORMATS}), mm; in Python a loaded Mesh or a file name",
                  role="part", positional=True)


def _tools(default=REQUIRED, more=""):
    return option("object", f"TOML tool table (a file name, or the tools of load_tools){more}", default,
                  role="tools", metavar="FILE")


def _tool():
    return option("text", "name of the tool in the table")


def _toolpath():
    return option("object", "APT CL file (.cl) or G-code (.nc, .ngc, .gcode, .tap); in Python also a Toolpath",
                  role="toolpath", positional=True)


def _machine(default=None, help="the machine: a TOML file or a shipped name (table-table-ac, head-table-bc, "
                                "generic-3axis, ...)", role="machine"):
    return option("object", help, default, role=role, metavar="NAME|FILE")


def _stock(help, aliases=()):
    return option("object", help, None, role="stock", metavar="STOCK", aliases=aliases)


def _tolerance(default=GOUGE_TOL, help="gouge tolerance", positive=False):
    return option("number", help, default, unit="mm", **({"above": 0.0} if positive else {"low": 0.0}))


def _clearance(default=HOLDER_CLEARANCE, help="distance rapid moves keep from the stock"):
    return option("number", help, default, unit="mm", low=0.0)


def _allowance():
    return option("number", "material left on the part: the tool kept that far from it (semi-finishing)", 0.0,
                  unit="mm", low=0.0)


def _rest(what="passes"):
    return option("number", f"rest machining: with a stock, cut only the pieces of the {what} that remove more than "
                            f"this depth of it (1.5 samples kept on each side)", None, unit="mm", low=0.0)


def _slope(which: str, default=None):
    bound = {"min": "at least", "max": "at most"}[which]
    return option("number", f"cut only the pieces of the passes where the surface the tool touches is {bound} this "
                            "steep, from the horizontal (steep and shallow finishing)", default, unit="deg", low=0.0,
                  high=90.0)


def _overlap():
    return option("number", "with min_slope or max_slope: each piece kept this far beyond its ground along the pass, "
                            "so that the steep and the shallow passes overlap (no seam)", 1.0, unit="mm", low=0.0)


def _design():
    return option("object", f"design part mesh ({MESH_FORMATS}), mm; closed", role="part")


def _material():
    return option("text", "the workpiece material: the tools' [[tools.cutting]] of that name and its specific cutting "
                          "force (aluminium-6061, aluminium-7075, steel-1045, steel-p20, stainless-304, titanium-6al4v, "
                          "cast-iron, brass, plastic)", None)


def _device():
    return option("choice", "run the heavy kernels on the CPU or an NVIDIA GPU (meshmill[cuda]); auto: the GPU when "
                            "a usable one is present", "auto", choices=DEVICES)


def _cluster():
    return option("object", "the heavy work on a Dask cluster (meshmill[cluster]): a number of local worker "
                            "processes, a scheduler's address (tcp://host:8786) or a distributed.Client; the same "
                            "result", None, role="cluster", cli=False)


def _progress():
    return option("object", "called with the name of each stage, and in a long stage with its share done", None,
                  role="progress", cli=False)


_STOCK_ALLOWANCE = (("--stock-allowance", "offset:"),)
_STOCK_HELP = ("the material the operation starts from: a closed mesh file (a machined.stl of simulate, a blank), a "
               "saved stock (stock.npz), 'box' (the part's box) or 'offset:MM' (the part with MM left on it); "
               "rapid moves keep the clearance from it, the shank and holder stay out of it; in Python a Stock "
               f"(default: the part with {STOCK_ALLOWANCE:g} mm left on it; --stock-allowance MM: offset:MM)")


# ---------------------------------------------------------------- loading


@dataclass(frozen=True, kw_only=True)
class LoadPartParams(Params):
    """load_part: the part file into the work frame (mm, +Z to the spindle)."""

    path: object = option("object", f"part mesh file ({MESH_FORMATS})", role="path", positional=True)
    units: str = option("choice", "units of the part file", "mm", choices=("mm", "cm", "m", "in"))
    up: str = option("text", "the part's axis that points to the spindle (+X, -Y, ...), or a rotation: 'RX,RY,RZ' "
                             "degrees about X, then Y, then Z, or nine numbers, a matrix by rows", "+Z",
                     what="an axis (+X, -Y, ...) or a rotation ('RX,RY,RZ' degrees, or nine numbers) as text")
    origin: object = option("object", "the work zero: file (the file's own zero), bottom-centre, top-centre, corner "
                                      "(of the part's box, after up), or a point X,Y,Z in the file's coordinates",
                            "file", role="origin",
                            what="file, bottom-centre, top-centre, corner, or a point X,Y,Z (text or three numbers)")
    scale: float = option("number", "the model's scale, after units (0.05: a 1:20 model)", 1.0, above=0.0)
    flip: bool = option("flag", "turn every face of the part over (reverse its normals): for a part wound inside "
                                "out, or an open surface that faces away from the spindle", False)


SETUP = ("units", "up", "origin", "scale", "flip")  # load_part's options that set a part up


@dataclass(frozen=True, kw_only=True)
class LoadToolpathParams(Params):
    """load_toolpath: an APT CL file or G-code."""

    path: object = option("object", "APT CL file (.cl) or G-code (.nc, .ngc, .gcode, .tap)", role="path",
                          positional=True)
    tools: object = _tools()
    tool: str | None = option("text", "tool name for G-code without T words", None)
    machine: object = _machine(help="the machine whose kinematics read 5-axis G-code (a TOML file or shipped name)")


# ---------------------------------------------------------------- path operations


@dataclass(frozen=True, kw_only=True)
class FinishParams(Params):
    """finish: 5-axis Z-constant ball-end finishing."""

    part: object = _part()
    tools: object = _tools(more="; its ball tools are used")
    step_down: float = option("number", "distance between Z planes, from the top of the part down", unit="mm",
                              low=1e-4)
    sample: float = option("number", "largest distance between CC points along a contour", 0.5, unit="mm", low=1e-4)
    max_tilt: float = option("number", "largest tool tilt from vertical", 60.0, unit="deg", low=0.0, below=90.0)
    tilt_step: float = option("number", "tilt search step", 5.0, unit="deg", above=0.0)
    order: str = option("choice", "grouped by tool, largest first (each tool cuts all it should before the next is "
                                  "loaded), or contour by contour from the top (seed 004's order: a tool change "
                                  "wherever the ball changes)", "tool", choices=("tool", "contour"))
    links: str = option("choice", "between two passes of one tool: a rapid straight from one to the next where it "
                                  "passes verification, else by the safe plane (direct), or always by the safe "
                                  "plane (safe)", "direct", choices=("direct", "safe"))
    safe_z: float | None = option("number", "plane for rapid moves between passes (default: the part's top + 5 + "
                                            "what a tilted ball hangs below its tip)", None, unit="mm",
                                  low=-MAX_COORDINATE, high=MAX_COORDINATE)
    tolerance: float = _tolerance(help="how deep the cutting part may enter the mesh")
    clearance: float = _clearance(help="distance the shank and holder keep from the part, and rapid moves from the "
                                       "stock")
    lead: float = option("number", "lead-in/out distance along the outward side of the contour", 2.0, unit="mm",
                         low=0.0)
    machine: object = _machine(help="the 5-axis machine the path is for (TOML file or shipped name): no move swings "
                                    "the tool axis past the pole of its rotaries (it goes round it)")
    scallop: float | None = option("number", "keep the scallop between passes under this: levels added where the "
                                             "surface is shallow, flatter surfaces rastered", None, unit="mm",
                                   above=0.0)
    min_run: float = option("number", "a stretch of a contour that a ball fits, shorter than this, is left out", 1.0,
                            unit="mm", low=0.0)
    whole_contours: bool = option("flag", "seed 004's rule: one ball per contour, and a contour with a point that no "
                                          "ball fits is not cut", False)
    stock: object = _stock(_STOCK_HELP, _STOCK_ALLOWANCE)
    material: str | None = _material()
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class RasterParams(Params):
    """raster: 3-axis zigzag finishing (flat, ball or bull-nose)."""

    part: object = _part()
    tools: object = _tools()
    tool: str = _tool()
    stepover: float | None = option("number", "distance between passes (or give scallop)", None, unit="mm",
                                    above=0.0)
    scallop: float | None = option("number", "scallop height that sets the stepover (or give stepover): on ground as "
                                             "steep as max_slope, else on flat ground", None, unit="mm", above=0.0)
    angle: float = option("number", "machining direction from X", 0.0, unit="deg")
    min_slope: float | None = _slope("min")
    max_slope: float | None = _slope("max")
    overlap: float = _overlap()
    sample: float = option("number", "largest distance between CL points along a pass", 0.5, unit="mm", low=1e-3)
    tolerance: float = _tolerance(help="gouge and chord tolerance", positive=True)
    clearance: float = _clearance()
    stock: object = _stock(_STOCK_HELP, _STOCK_ALLOWANCE)
    allowance: float = _allowance()
    rest: float | None = _rest()
    material: str | None = _material()
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()

    def check(self):
        if (self.stepover is None) == (self.scallop is None):
            raise InputError("give exactly one of stepover and scallop", ("stepover", "scallop"))
        _check_slopes(self)


@dataclass(frozen=True, kw_only=True)
class WaterlineParams(Params):
    """waterline: 3-axis Z-level loops (flat, ball or bull-nose)."""

    part: object = _part()
    tools: object = _tools()
    tool: str = _tool()
    step_down: float | None = option("number", "distance between Z levels (or give scallop)", None, unit="mm",
                                     low=1e-4)
    scallop: float | None = option("number", "scallop height that sets the levels' distance (or give step_down): on "
                                             "ground as steep as min_slope, else on walls", None, unit="mm", above=0.0)
    sample: float = option("number", "grid spacing of the loop search", 0.5, unit="mm", low=1e-3)
    min_slope: float | None = _slope("min")
    max_slope: float | None = _slope("max")
    overlap: float = _overlap()
    tolerance: float = _tolerance(help="gouge and chord tolerance", positive=True)
    clearance: float = _clearance()
    stock: object = _stock(_STOCK_HELP, _STOCK_ALLOWANCE)
    allowance: float = _allowance()
    rest: float | None = _rest("loops")
    material: str | None = _material()
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()


    def check(self):
        if (self.step_down is None) == (self.scallop is None):
            raise InputError("give exactly one of step_down and scallop", ("step_down", "scallop"))
        _check_slopes(self)


def _check_slopes(p):
    if p.min_slope is not None and p.max_slope is not None and p.min_slope > p.max_slope:
        raise InputError(f"min_slope {p.min_slope:g} is steeper than max_slope {p.max_slope:g}: no ground between",
                         ("min_slope", "max_slope"))


@dataclass(frozen=True, kw_only=True)
class SteepShallowParams(Params):
    """steep-shallow: 3-axis finishing to a scallop limit, Z levels on the steep ground and
    parallel passes on the shallow (ball or bull-nose)."""

    part: object = _part()
    tools: object = _tools()
    tool: str = _tool()
    scallop: float = option("number", "largest scallop height left between passes, on every slope", unit="mm",
                            above=0.0)
    threshold: float = option("number", "ground steeper than this is cut by Z levels, shallower by parallel passes",
                              45.0, unit="deg", above=5.0, below=85.0)
    overlap: float = option("number", "each side's passes go this far into the other's ground (and 5 deg of "
                                      "slope), so no seam is left", 1.0, unit="mm", low=0.0)
    angle: float = option("number", "the parallel passes' direction from X", 0.0, unit="deg")
    sample: float = option("number", "largest distance between CL points along a pass, and the levels' grid", 0.5,
                           unit="mm", low=1e-3)
    pencil: bool = option("flag", "also pencil passes along the concave corners and fillets, where the tool touches "
                                  "two sides at once (first, before the levels and the parallel passes)", True)
    tolerance: float = _tolerance(help="gouge and chord tolerance", positive=True)
    clearance: float = _clearance()
    stock: object = _stock(_STOCK_HELP, _STOCK_ALLOWANCE)
    allowance: float = _allowance()
    rest: float | None = _rest()
    material: str | None = _material()
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class PlungeParams(Params):
    """plunge: 3- or 5-axis plunge roughing (seed 001)."""

    part: object = _part()
    tools: object = _tools()
    tool: str = _tool()
    allowance: float = option("number", "material left on the part", unit="mm", low=0.0)
    axes: int = option("choice", "3: nested contours; 5: plunges over the hemisphere of directions", 3, choices=(3, 5))
    radial_step: float = option("number", "3-axis: distance between plunges along a contour", 5.0, unit="mm",
                                low=1e-3)
    engagement: float = option("number", "3-axis: radial engagement between contours", 5.0, unit="mm", low=1e-3)
    theta_step: float = option("number", "5-axis: tilt step of the directions", 15.0, unit="deg", above=0.0,
                               high=90.0)
    delta_step: float = option("number", "5-axis: azimuth step", 30.0, unit="deg", above=0.0, high=90.0)
    regions: int = option("integer", "5-axis: split the part into K regions, each plunged from its best direction "
                                     "(0: the seed's one plunge a direction through the stock centre)", 0, low=0)
    clearance: float = _clearance(5.0, "clearance plane above the stock")
    stock: object = _stock("3-axis: the material the plunges start from, whose box they cover: a closed mesh file, "
                           "a saved stock (stock.npz), 'box'; in Python a Stock (default: the part's box)")
    simulate: float | None = option("number", "also cut the path from the part's box with dexels of this step and "
                                              "report the volumes", None, unit="mm", above=0.0)
    material: str | None = _material()
    device: str = _device()
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class RoughParams(Params):
    """rough: adaptive clearing from the stock, Z levels with a bounded radial engagement."""

    part: object = _part()
    tools: object = _tools()
    tool: str = _tool()
    engagement: float | None = option("number", "largest radial width of cut (ae) of every step; the path keeps "
                                                "close to it (default: a quarter of the tool diameter)", None,
                                      unit="mm", above=0.0)
    step_down: float | None = option("number", "largest depth between levels (default: the flute length)", None,
                                     unit="mm", above=0.0)
    stair: float | None = option("number", "step-up levels where a level leaves a stair higher than this above the "
                                           "part (shallow areas)", None, unit="mm", above=0.0)
    allowance: float = option("number", "material left on the part's walls (radial)", 0.5, unit="mm", low=0.0)
    axial_allowance: float | None = option("number", "material left on floors (default: the allowance)", None,
                                           unit="mm", low=0.0)
    direction: str = option("choice", "climb (the material on the tool's right, clockwise spindle) or conventional",
                            "climb", choices=("climb", "conventional"))
    axis: str = option("text", "the tool axis (spindle side) for indexed 3+2 roughing: +Z (3-axis), an axis (+X, -Y, "
                               "...) or three numbers x,y,z; the same clearing in that direction, from the stock as "
                               "it is", "+Z")
    helix_diameter: float | None = option("number", "diameter of the helix entering closed material (default: "
                                                    "three quarters of the tool diameter; smaller where the room "
                                                    "is short)", None, unit="mm", above=0.0)
    ramp_angle: float = option("number", "descent angle of the helix", 3.0, unit="deg", above=0.0, high=45.0)
    sample: float | None = option("number", "grid spacing of the clearing (default: a tenth of the engagement, at "
                                            "most a sixteenth of the tool radius)", None, unit="mm", above=0.0)
    clearance: float = _clearance()
    stock: object = _stock("the material to clear: a closed mesh file, a saved stock (stock.npz), 'box'; in Python "
                           "a Stock (default: the part's box)")
    fixtures: object = option("object", "solids the tool keeps the clearance from (in Python Fixtures or closed "
                                        "Meshes; a job gives its own)", None, role="fixtures", cli=False)
    material: str | None = _material()
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()


# ---------------------------------------------------------------- checks and models


@dataclass(frozen=True, kw_only=True)
class VerifyParams(Params):
    """verify: gouges, shank and holder collisions and rapids into the stock of any tool path."""

    part: object = _part()
    toolpath: object = _toolpath()
    tools: object = _tools()
    tolerance: float = _tolerance()
    step: float = option("number", "distance between the poses measured along a move found bad (for its depth) or "
                                   "made with a tool too thin to prove (each move is certified whole or halved: "
                                   "whether it passes does not depend on it)", 0.5, unit="mm", low=1e-4)
    stock: object = _stock("the material rapids must keep clear of: a closed mesh file, a saved stock (stock.npz), "
                           "'offset:MM' (the part with MM left on it); in Python a Stock (default: the part alone; "
                           "--allowance MM: offset:MM)", (("--allowance", "offset:"),))
    worst: int = option("integer", "how many worst cases to report", 10, low=0)
    machine: object = _machine(help="G-code's machine (TOML file or shipped name): 5-axis words are read through its "
                                     "kinematics")
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class DexelParams(Params):
    """dexel: the triple-dexel model of a closed part (seed 000)."""

    part: object = _part()
    step: float = option("number", "distance between grid lines", unit="mm", above=0.0)
    index: str = option("choice", "how lines find their triangles: BVH, or the seed's cells or k-means partitions",
                        "bvh", choices=("bvh", "cells", "kmeans"))
    partitions: object = option("integer", "number of cells or clusters, or 'auto' (the K-optimal helper)", 1, low=1,
                                high=MAX_PARTITIONS, words=("auto",))
    kmax: int = option("integer", "largest K the K-optimal helper tries", 27, low=1, high=MAX_PARTITIONS)
    init: str = option("choice", "k-means initialisation", "k-means++", choices=("k-means++", "random"))
    minibatch: bool = option("flag", "mini-batch k-means", False)
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()

    def check(self):
        if self.partitions == "auto" and self.index == "bvh":
            raise InputError("partitions auto needs index cells or kmeans", ("partitions", "index"))


@dataclass(frozen=True, kw_only=True)
class SimulateParams(Params):
    """simulate: cut a tool path from a stock and measure it against the design."""

    design: object = _design()
    toolpath: object = option("object", "APT CL file (.cl) or G-code (.nc, .ngc, .gcode, .tap; 5-axis with machine); "
                                        "in Python also a Toolpath", role="toolpath")
    tools: object = _tools()
    step: float = option("number", "dexel grid step", unit="mm", above=0.0)
    stock: object = _stock("the stock the path cuts: 'box' (the design's box), a closed mesh file, a saved stock "
                           "(stock.npz: go on from it), 'offset:MM' (the design's dexels lengthened by MM at both "
                           "ends); in Python a Stock (default: box; --allowance MM: offset:MM)",
                           (("--allowance", "offset:"),))
    tolerance: float = _tolerance(help="deviation tolerance band ±")
    mode: str = option("choice", "exact swept volume of every move, or the tool at the points only (seed)", "sweep",
                       choices=("sweep", "points"))
    tool: str | None = option("text", "tool name for G-code without T words", None)
    machine: object = _machine(help="G-code's machine (TOML file or shipped name): 5-axis words are read through its "
                                    "kinematics; its spindle's power and torque bound every move's load")
    material: str | None = _material()
    outputs: object = option("object", "what to keep beside the summary: deviation (every dexel end's deviation, "
                                       "deviation.npz), mesh (machined.stl); the command line's comma list may say "
                                       "summary (those alone) or all", OUTPUTS, role="outputs")
    device: str = _device()
    cluster: object = _cluster()
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class AnalyzeParams(Params):
    """analyze: triangle and vertex parameters, visibility and accessibility (seed 001)."""

    part: object = _part()
    direction: tuple = option("numbers", "direction of visibility and accessibility", (0.0, 0.0, 1.0))
    weighting: str = option("choice", "vertex normals", "area", choices=WEIGHTINGS)
    theta_step: float | None = option("number", "also map accessibility over the hemisphere, this tilt step", None,
                                      unit="deg", above=0.0, high=90.0)
    delta_step: float = option("number", "azimuth step of the map", 10.0, unit="deg", above=0.0, high=90.0)
    device: str = _device()
    progress: object = _progress()

    def check(self):
        if sum(x * x for x in self.direction) < 1e-24:
            raise InputError(f"direction must not be zero, got {','.join(f'{x:g}' for x in self.direction)}",
                             "direction")


@dataclass(frozen=True, kw_only=True)
class ChooseParams(Params):
    """choose: tool choice, zones and directions by machining time (seed 002)."""

    surface: object = option("object", "surface: patch TOML (Bezier/B-spline/NURBS), 'rubio' or 'choi', or a mesh "
                                       f"({MESH_FORMATS}); in Python also a loaded Mesh", role="surface",
                             positional=True)
    scallop: float = option("number", "largest scallop height", unit="mm", above=0.0)
    tool_pair: str | None = option("text", "a ball of diameter D and a bull-nose D with corner radius r, 'D,r' in mm "
                                           "(e.g. 10,2)", None, metavar="D,r")
    tools: object = _tools(None, "; its ball and bull-nose cutters are the candidates")
    zones: object = option("integer", "number of clusters K, or auto (best of 1..k_max)", "auto", low=1, high=50,
                           words=("auto",))
    k_max: int = option("integer", "largest K tried by zones auto", 6, low=1, high=20)
    axes: str = option("choice", "3-axis or 3+2-axis", "3", choices=("3", "3+2"))
    optimise: int = option("integer", "NOMAD black-box evaluations for the weights, directions, tools (and tilts) "
                                      "(0: none)", 0, low=0, metavar="EVALS")
    machine: object = _machine("generic-3axis", "TOML machine file, or a shipped one: generic-3axis, seed-002")
    cluster: str = option("choice", "clustering", "kmeans", choices=CLUSTERINGS)
    metric: str = option("choice", "clustering metric", "euclidean", choices=METRICS)
    grid: int = option("integer", "sampling grid, cells a side", 80, low=4, high=400)
    mesh_step: float = option("number", "triangle size of a patch's mesh", 0.5, unit="mm", low=0.01, high=50.0)
    sample: float = option("number", "drop-cutter spacing along a pass", 0.5, unit="mm", low=0.01, high=50.0)
    min_zone: float = option("number", "zones under this fraction of the cells join a neighbour", 0.01, low=0.0,
                             below=1.0)
    seed: int = option("integer", "random seed of RPCL and NOMAD", 0, low=0)
    flip: bool = option("flag", "turn every face of the surface over (reverse its normals)", False)
    device: str = _device()
    progress: object = _progress()

    def check(self):
        if (self.tool_pair is None) == (self.tools is None):
            raise InputError("give exactly one of tool_pair and tools", ("tool_pair", "tools"))


# ---------------------------------------------------------------- programs and reports


@dataclass(frozen=True, kw_only=True)
class PostParams(Params):
    """post: G-code for a machine from a tool path (3- and 5-axis)."""

    toolpath: object = option("object", "APT CL file (.cl); in Python also a Toolpath", role="cl", positional=True)
    machine: object = _machine(REQUIRED, "TOML machine file, or a shipped one: generic-3axis, linuxcnc-3axis, "
                                         "grbl-3axis, table-table-ac, head-table-bc, head-head-ca", "target_machine")
    tools: object = _tools(None, " (default: the tools.toml beside the tool path, as choose writes it)")
    feed: float | None = option("number", "feed for the moves the path gives none (default: the machine's)", None,
                                unit="mm/min", above=0.0)
    tolerance: float = option("number", "5-axis: largest tip deviation from a CL move between blocks", 0.005,
                              unit="mm", above=0.0)
    origin: tuple | None = option("numbers", "the program's zero in machine coordinates (work offset), for the travel "
                                           "of X Y Z (default: each axis's span must fit its travel)", None, unit="mm",
                                  metavar="X,Y,Z")
    clearance: float | None = option("number", "5-axis: Z (work coordinates) above which the whole tool stays while "
                                               "the rotaries unwind or swing over; the part's top plus a margin "
                                               "(default: the path's highest tip)", None, unit="mm",
                                     low=-MAX_COORDINATE, high=MAX_COORDINATE, metavar="Z")
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class TimeParams(Params):
    """machining_time: the time of a tool path on a jerk-limited machine."""

    toolpath: object = _toolpath()
    machine: object = _machine(REQUIRED, "TOML machine file, or a shipped one: generic-3axis, seed-002",
                               "target_machine")
    tools: object = _tools(None, " (default: the tools.toml beside the tool path, as choose writes it)")
    feed: float | None = option("number", "cutting feed for every feed move (default: as programmed, else the "
                                          "machine's)", None, unit="mm/min", above=0.0)
    tool: str | None = option("text", "tool name for G-code without T words", None)
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class FeedsParams(Params):
    """feeds: each move's feed optimised on the load measured by cutting the path from its stock."""

    design: object = _design()
    toolpath: object = option("object", "APT CL file (.cl) or G-code (.nc, .ngc, .gcode, .tap); in Python also a "
                                        "Toolpath", role="toolpath")
    tools: object = _tools()
    machine: object = _machine("generic-3axis", "the machine (TOML file or shipped name): its spindle's power, torque "
                                                "and speeds, its largest feed, the program's dialect", "target_machine")
    material: str | None = _material()
    step: float = option("number", "dexel grid step of the stock the load is measured on", 0.5, unit="mm", above=0.0)
    stock: object = _stock("the stock the path cuts: 'box' (the design's box), a closed mesh file, a saved stock "
                           "(stock.npz), 'offset:MM'; in Python a Stock (default: box)")
    tool: str | None = option("text", "tool name for G-code without T words", None)
    tolerance: float = _tolerance(help="the shank and holder's clearance in the cut")
    device: str = _device()
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class ReportParams(Params):
    """report: one self-contained HTML file with 3D views and tables of run folders."""

    folders: object = option("object", "folders written by finish, raster, waterline, plunge, dexel, simulate or a "
                                       "job's operations", role="folders", positional=True)
    out: str = option("text", "HTML file to write", "report.html")
    progress: object = _progress()


@dataclass(frozen=True, kw_only=True)
class ClearFixturesParams(Params):
    """clear_fixtures: a tool path kept out of solids no cutter, shank or holder may enter."""

    toolpath: object = _toolpath()
    tools: object = _tools()
    fixtures: object = option("object", "the fixtures: Fixtures, closed Meshes or [[fixtures]] tables",
                              role="fixtures")
    safe_z: float = option("number", "the plane the stretches left out are linked over at", unit="mm",
                           low=-MAX_COORDINATE, high=MAX_COORDINATE)
    part: object = option("object", "the part the fixtures given in its file's frame are placed with", None,
                          role="part")
    label: str = option("text", "what the errors say the path is", "", cli=False)
    device: str = _device()


# ---------------------------------------------------------------- a job's stock and fixtures


@dataclass(frozen=True, kw_only=True)
class StockParams(Params):
    """A stock as the job file's ``[stock]`` table (and :meth:`~meshmill.simulation.stock.Stock.from_dict`)."""

    type: str = option("choice", "box (the part's box grown by the margins), cylinder (about Z), mesh (a closed "
                                 "file), offset (the part with allowance on every dexel end)", "box",
                       choices=("box", "cylinder", "mesh", "offset"))
    margin: float = option("number", "box and cylinder: margin on every side", 0.0, unit="mm", low=0.0)
    side: float | None = option("number", "margin on the sides (default: margin)", None, unit="mm", low=0.0)
    top: float | None = option("number", "margin on top (default: margin)", None, unit="mm", low=0.0)
    bottom: float | None = option("number", "margin below (default: margin)", None, unit="mm", low=0.0)
    diameter: float | None = option("number", "cylinder: its diameter (default: the part's widest radius plus the "
                                              "side margin, doubled)", None, unit="mm", above=0.0)
    allowance: float = option("number", "offset: material on the part", 1.0, unit="mm", low=0.0)
    file: str | None = option("text", "mesh: the closed stock mesh (relative to the job file)", None)
    frame: str = option("choice", "mesh: in the part file's frame (placed as the part) or the work frame", "part",
                        choices=("part", "work"))

    def check(self):
        if self.type == "mesh" and self.file is None:
            raise InputError("type 'mesh' needs file", ("type", "file"))
        if self.type != "mesh" and self.file is not None:
            raise InputError(f"file is for type 'mesh', not {self.type!r}", ("file", "type"))


@dataclass(frozen=True, kw_only=True)
class FixtureParams(Params):
    """A solid no cutter, shank or holder may enter: a job file's ``[[fixtures]]`` table."""

    name: str | None = option("text", "its name (default: fixture N)", None)
    box: tuple | None = option("numbers", "a box [x0, y0, z0, x1, y1, z1] in the work frame", None, unit="mm", count=6)
    file: str | None = option("text", "a closed mesh file (relative to the job file)", None)
    frame: str = option("choice", "file: in the part file's frame (placed as the part) or the work frame", "part",
                        choices=("part", "work"))

    def check(self):
        if (self.box is None) == (self.file is None):
            raise InputError("give exactly one of file and box", ("file", "box"))
        if self.box is not None and not all(self.box[k + 3] > self.box[k] for k in range(3)):
            raise InputError("box's second corner must lie above the first on every axis", "box")
