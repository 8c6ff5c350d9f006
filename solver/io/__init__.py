"""File formats: a surface as OBJ, a network as JSON, a result as NPZ
(formats.py); a solved field for ParaView and hex meshers (interchange.py:
what is exported, in which files), written as VTK XML (vtu.py), MEDIT
(medit.py) with CubeCover's .fra tet frames and .perm face matchings
(cubecover.py), OpenVolumeMesh (ovm.py) or AlgoHex .qtn quaternions
(qtn.py), and read back; a network read from a tet mesh with tagged edges
(tetnetwork.py); hex meshes as VTU, VTK, MEDIT, OpenVolumeMesh (ovm.py,
read back by read_hex_ovm) and the integer-grid map (hexformats.py), and for
simulation codes as Gmsh MSH, Abaqus/CalculiX, Exodus II, Nastran and MED
with their boundary patches (femformats.py); files written whole
or not at all (atomic.py), text read with line numbers and rows of numbers
written (text.py), stored fields read back (stored.py)."""

from .formats import (
    load_result,
    network_from_dict,
    network_to_dict,
    options_from_dict,
    read_network,
    read_obj,
    save_field,
    save_result,
    write_network,
    write_obj,
)
from .hexformats import HEX_FORMATS, export_hexmesh, read_hexex
from .interchange import export_field
from .ovm import read_hex_ovm
from .qtn import quaternion_frames
from .stored import load_field, load_hex_input
from .tetnetwork import TetNetworkImport, import_tet_network, read_tet_network

__all__ = [
    "HEX_FORMATS",
    "export_hexmesh",
    "load_field",
    "load_hex_input",
    "read_hexex",
    "read_hex_ovm",
    "export_field",
    "import_tet_network",
    "load_result",
    "network_from_dict",
    "network_to_dict",
    "options_from_dict",
    "quaternion_frames",
    "read_network",
    "read_obj",
    "read_tet_network",
    "save_field",
    "save_result",
    "TetNetworkImport",
    "write_network",
    "write_obj",
]
