"""Hex meshing: a pure hexahedral mesh from a solved field, its irregular
edges the prescribed curves (docs/hexmesh.md).  The stages, in order (their
names in ``STAGE_WEIGHTS``):

- curve_edges.py: the network onto tet edges ("curves onto edges");
- transitions.py: frames per tet, transitions from omega, holonomy and the
  cut ("transitions"); ``field_on_edges`` hands them to other hex meshers;
- seamless.py: the map system with its constraints eliminated exactly ("map
  system"), the seamless map ("seamless map") and the integer-grid map
  ("integer-grid map"), rounded by quantize.py's greedy rounding;
- extract.py: hexahedra from the integer-grid map ("extraction");
- smooth.py: vertex optimisation and its policy ("smoothing");
- quality.py: measures of a hex mesh; report.py: the report and the verdict
  ("quality").

Around them: mesher.py, the driver (``hexmesh``: the stages' order and the
cell sizes tried); options.py, its settings (``HexOptions``); cellsize.py,
the automatic cell size and the refusal of one that does not fit; intake.py,
what is refused before any work; source.py, the earlier names of what it
takes (``HexInput`` is ``field.solved.SolvedField``, kept for one release);
hexes.py, what it hands back (``HexMesh``); patches.py, the
boundary patches for simulation; sizing.py, the size field of
``HexOptions.finer_near`` (``FinerNear``: smaller cells near chosen patches
and curves).
"""

from ..errors import HexMeshError
from .cellsize import default_cell_size
from .hexes import HexMesh
from .mesher import STAGE_WEIGHTS, hexmesh
from .options import DEFAULT_HEXES, MAX_HEXES, HexOptions
from .patches import BoundaryPatches
from .report import CurveMatch, HexReport
from .sizing import FinerNear
from .source import HexInput, hex_source_arrays, input_from_arrays
from .transitions import EdgeField, field_on_edges

__all__ = [
    "DEFAULT_HEXES",
    "MAX_HEXES",
    "STAGE_WEIGHTS",
    "BoundaryPatches",
    "CurveMatch",
    "EdgeField",
    "FinerNear",
    "HexInput",
    "HexMesh",
    "HexMeshError",
    "HexOptions",
    "HexReport",
    "default_cell_size",
    "field_on_edges",
    "hex_source_arrays",
    "hexmesh",
    "input_from_arrays",
]
