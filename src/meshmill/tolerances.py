"""Every named tolerance of the package, in mm unless said otherwise."""

# A tool may touch the part; entering it deeper than this is a gouge (finish and verify default).
# 10 µm is the usual finishing tolerance; it must also cover the mesh's own chordal error where
# a ball sits against a concave crease of the facets.
GOUGE_TOL = 0.01

# Shank and holder keep at least this distance from the part when finish chooses a tool axis; rapid
# moves keep it from the stock.
HOLDER_CLEARANCE = 0.5

# Material (mm) a finishing operation takes earlier operations to have left on the part, unless told:
# its rapids keep clear of it.
STOCK_ALLOWANCE = 0.5

# A STEP or IGES part is tessellated with at most this chordal deviation (mm): half the gouge
# tolerance, so that the mesh's own error stays within what finishing allows.
TESSELLATION_TOL = 0.005
TESSELLATION_ANGLE = 0.2  # rad between the normals of neighbouring facets at most

# Triangles with an area below this (mm²) are degenerate and dropped on load.
DEGENERATE_AREA = 1e-12

# Vertices closer than this are welded into one on load (exact duplicates in STL files).
WELD_DIGITS = 9

# Two CC points closer than this along a contour are the same place (arc points at an edge).
SAME_POINT = 1e-9

# What writing moves a path by: APT coordinates to 6 decimals, and a part.stl in float32 (2^-24 of
# each coordinate, three of them). finish keeps its gouges this much under the tolerance, so that the
# files it writes verify against each other within it.
WRITE_ROUNDING = 1e-6
FLOAT32_ROUNDING = 1.1e-7  # of the largest coordinate
