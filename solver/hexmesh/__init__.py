"""Hex meshing: a pure hexahedral mesh from a solved field, its irregular
edges the prescribed curves (docs/hexmesh.md; the stages in mesher.py)."""

from ..errors import HexMeshError
from .mesher import STAGE_WEIGHTS, HexMesh, default_cell_size, hexmesh
from .report import CurveMatch, HexReport
from .source import HexInput, hex_source_arrays, input_from_arrays, input_from_check

__all__ = ["STAGE_WEIGHTS", "CurveMatch", "HexInput", "HexMesh", "HexMeshError", "HexReport", "default_cell_size",
           "hex_source_arrays", "hexmesh", "input_from_arrays", "input_from_check"]
