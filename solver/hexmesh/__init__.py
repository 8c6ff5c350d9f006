"""Hex meshing: a pure hexahedral mesh from a solved field, its irregular
edges the prescribed curves (docs/hexmesh.md; the stages in mesher.py), and
its boundary patches for simulation (patches.py)."""

from ..errors import HexMeshError
from .arrays import input_from_arrays
from .mesher import STAGE_WEIGHTS, EdgeField, HexMesh, default_cell_size, field_on_edges, hexmesh
from .patches import BoundaryPatches
from .report import CurveMatch, HexReport
from .source import HexInput, hex_source_arrays

__all__ = [
    "STAGE_WEIGHTS",
    "BoundaryPatches",
    "CurveMatch",
    "EdgeField",
    "HexInput",
    "HexMesh",
    "HexMeshError",
    "HexReport",
    "default_cell_size",
    "field_on_edges",
    "hex_source_arrays",
    "hexmesh",
    "input_from_arrays",
]
