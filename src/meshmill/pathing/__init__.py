"""Building blocks of tool paths shared by the operations (``ops``) and the tool choice
(``choice``): the verified drop of the whole tool, drop grids, verification of a path, stepover
from a scallop height, zigzag passes."""
