"""meshmill: exact, fast, verified multi-axis milling tool paths from triangle meshes."""
__version__ = "0.1.0"
