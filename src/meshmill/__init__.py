"""meshmill: exact, fast, verified multi-axis milling tool paths from triangle meshes.

The operations are functions of :mod:`meshmill.api`, reachable from here (``meshmill.finish``,
``meshmill.load_part``, ``meshmill.Stock``, ...); they are imported on first use, so ``import
meshmill`` is quick.
"""
__version__ = "0.1.0"

API = ("load_part", "load_tools", "load_toolpath", "load_machine", "finish", "raster", "waterline",
       "steep_shallow", "plunge",
       "rough", "verify", "dexel", "simulate", "analyze", "choose", "post", "machining_time", "report", "clear_fixtures",
       "optimise_feeds", "optimised_feeds", "air_feeds", "air_time_share", "what_is_left",
       "Stock", "Fixture", "Toolpath")
__all__ = [*API, "Job", "InputError", "NothingToCut", "__version__"]


def __getattr__(name):
    if name in API:
        from . import api

        return getattr(api, name)
    if name == "Job":
        from .job import Job

        return Job
    if name in ("InputError", "NothingToCut"):
        from . import errors

        return getattr(errors, name)
    raise AttributeError(f"module 'meshmill' has no attribute '{name}'")


def __dir__():
    return sorted(set(globals()) | set(__all__))
