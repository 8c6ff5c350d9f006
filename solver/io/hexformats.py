"""Hex meshes written for other tools, and the integer-grid map for HexEx.

``export_hexmesh(hex_mesh, path)`` picks the format from the extension:

``.vtu``    VTK XML UnstructuredGrid of VTK_HEXAHEDRON cells (ParaView,
            meshio) with the scaled Jacobian per cell (vtu.py's writer, the
            one a solved field's tets are written with)
``.vtk``    the same as legacy ASCII VTK (older tools, Gmsh, HexaLab)
``.mesh``   MEDIT ``Hexahedra`` (Gmsh, meshio, many FE codes), and the
            boundary ``Quadrilaterals`` with their patch id as ref
            (medit.py's writer)
``.msh``    Gmsh MSH 4.1 (ASCII), the boundary patches and the irregular
            edges as physical groups (femformats.py)
``.inp``    Abaqus / CalculiX input, C3D8, with a node set, an element set
            and a surface per boundary patch (femformats.py)
``.exo``    Exodus II, a HEX8 block and a side set per boundary patch
            (femformats.py)
``.bdf``    Nastran bulk data (also ``.nas``): GRID*, CHEXA, and per patch
            its boundary CQUAD4 with a property id of its own
            (femformats.py)
``.med``    MED (Salome, Code_Aster; HDF5, needs h5py): HE8 cells, and per
            patch its boundary QU4 in a family and group of its own
            (femformats.py)
``.ovm``    OpenVolumeMesh ASCII (HexHex, AlgoHex, the OVM tools): quad
            faces, six halffaces per cell in OpenVolumeMesh's hexahedron
            order, the patch per face and the hexahedra per edge as
            properties (ovm.py)
``.hexex``  the integer-grid map per tet corner (HexEx / libHexHex / QGP3D
            input): vertex count, ``x y z`` lines, tet count, then per tet
            its four vertex ids (positively oriented) and the 4 x 3
            parameters of its corners (the format of the HexEx paper's
            additional material)

Every file is written whole or not at all (atomic.py: a temporary name in
its folder, renamed when complete), so a failure leaves the old file or
none, never a partial one.
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import OutputError, ReadError
from .atomic import check_output_path, write_text
from .femformats import write_hex_exodus, write_hex_inp, write_hex_med, write_hex_msh, write_hex_nastran
from .medit import write_medit
from .ovm import write_hex_ovm
from .text import Tokens, format_rows
from .vtu import VTK_HEXAHEDRON, write_vtu

HEX_FORMATS = {".vtu": "VTK XML", ".vtk": "legacy VTK", ".mesh": "MEDIT", ".msh": "Gmsh MSH 4.1",
               ".inp": "Abaqus/CalculiX input", ".exo": "Exodus II", ".bdf": "Nastran bulk data",
               ".nas": "Nastran bulk data", ".med": "MED (Salome, Code_Aster)", ".ovm": "OpenVolumeMesh",
               ".hexex": "HexEx integer-grid map"}


def check_hex_path(path: str, what: str = "hex mesh") -> str:
    """Refuse, before any work, a hex-mesh output path that could not be
    written: ``atomic.check_output_path`` against ``HEX_FORMATS``, and a
    ``.med`` without h5py.

    Parameters
    ----------
    path : str
    what : str
        how the message names the path (a flag such as ``--hex``)

    Returns
    -------
    str
        the path

    Raises
    ------
    OutputError
        naming the path and the cause
    """
    check_output_path(path, what, HEX_FORMATS)
    if os.path.splitext(path)[1].lower() == ".med":
        try:
            import h5py  # noqa: F401
        except ImportError:
            raise OutputError(f"{what} {path}: MED files are HDF5, written with h5py, which is not installed (pip "
                              "install h5py); write .msh or .exo instead") from None
    return path


def write_hex_vtk(path: str, vertices: np.ndarray, hexes: np.ndarray, cell_data: dict | None = None) -> None:
    """Legacy ASCII VTK (version 4.2 DATASET UNSTRUCTURED_GRID) of hexahedra;
    cell_data: name -> (m,) float array (SCALARS)."""
    V = np.asarray(vertices, float)
    H = np.asarray(hexes, np.int64)
    m = len(H)
    out = ["# vtk DataFile Version 4.2\n", "SymFrames hex mesh\n", "ASCII\n", "DATASET UNSTRUCTURED_GRID\n",
           f"POINTS {len(V)} double\n", format_rows(V, "%.17g"),
           f"CELLS {m} {9 * m}\n", format_rows(np.c_[np.full(m, 8), H], "%d"),
           f"CELL_TYPES {m}\n", format_rows(np.full((m, 1), VTK_HEXAHEDRON), "%d")]
    if cell_data:
        out.append(f"CELL_DATA {m}\n")
        for name, a in cell_data.items():
            out += [f"SCALARS {name} double 1\n", "LOOKUP_TABLE default\n",
                    format_rows(np.asarray(a, float).reshape(-1, 1), "%.9g")]
    write_text(path, "".join(out))


def write_hex_medit(path: str, vertices: np.ndarray, hexes: np.ndarray, refs=None, quads=None,
                    quad_refs=None) -> None:
    """MEDIT ASCII mesh with a ``Hexahedra`` section (1-based, VTK's corner
    order, which MEDIT shares), refs default 0, and where given the boundary
    ``Quadrilaterals`` (k, 4) with their refs (the patch ids)."""
    if quads is not None and not len(quads):
        quads = None
    write_medit(path, vertices, None, quads=quads, quad_refs=quad_refs, hexes=hexes, hex_refs=refs)


def write_hexex(path: str, vertices: np.ndarray, tets: np.ndarray, params: np.ndarray) -> None:
    """The integer-grid map in HexEx's ``.hexex`` format (module docs).

    vertices : (n, 3); tets : (m, 4) positively oriented; params : (m, 4, 3)
    the parameter point of each tet corner (a tet soup: charts may differ
    across the cut)."""
    V = np.asarray(vertices, float)
    T = np.asarray(tets, np.int64)
    U = np.asarray(params, float).reshape(len(T), 12)
    out = [f"{len(V)}\n", format_rows(V, "%.17g"), f"{len(T)}\n",
           format_rows(np.c_[T, U], "%.17g")]  # %g writes the vertex ids as integers
    write_text(path, "".join(out))


def read_hexex(path: str):
    """Read an integer-grid map in HexEx's ``.hexex`` format.

    Parameters
    ----------
    path : str

    Returns
    -------
    vertices : (n, 3) float array
    tets : (m, 4) int array
    params : (m, 4, 3) float array
        the parameter point of each tet corner

    Raises
    ------
    ReadError
        a count the file does not hold, a value that is not a finite number,
        a vertex id that is fractional or outside 0..n-1, a tet with a
        repeated vertex, or data after the last tet; naming the file, the
        line and the value
    """
    tok = Tokens.of_file(path, ReadError, ".hexex (integer-grid map)")
    n = tok.count("vertices", 3)
    V = tok.block(n, 3, "vertex coordinates")
    m = tok.count("tets", 16)
    first = tok.pos
    rows = tok.block(m, 16, "tets")
    tok.end("the last tet")
    ids = rows[:, :4]
    line = tok.lines[first::16] if m else tok.lines[:0]
    bad = np.nonzero((ids != np.round(ids)).any(axis=1) | ((ids < 0) | (ids >= n)).any(axis=1))[0]
    if len(bad):
        shown = " ".join(f"{x:g}" for x in ids[bad[0]])
        raise ReadError(f"{tok.path}:{line[bad[0]]}: tet {bad[0]} has vertex ids {shown}: they must "
                        f"be whole numbers from 0 to {n - 1} (the file has {n} vertices; ids are 0-based)")
    T = ids.astype(np.int64)
    S = np.sort(T, axis=1)
    bad = np.nonzero((S[:, 1:] == S[:, :-1]).any(axis=1))[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{line[bad[0]]}: tet {bad[0]} {T[bad[0]].tolist()} repeats a vertex")
    return V, T, rows[:, 4:].reshape(m, 4, 3)


def export_hexmesh(hex_mesh, path: str) -> list[str]:
    """Write a HexMesh in the format its extension names (module docs).

    Parameters
    ----------
    hex_mesh : hexmesh.HexMesh
    path : str
        ``.vtu``, ``.vtk``, ``.mesh``, ``.msh``, ``.inp``, ``.exo``, ``.bdf`` / ``.nas``, ``.med``,
        ``.ovm`` or ``.hexex``

    Returns
    -------
    list of str
        the paths written

    Raises
    ------
    OutputError
        hex_mesh not a HexMesh, an unknown extension, a path that cannot be written (checked before
        anything is made: atomic.check_output_path), ``.hexex`` for a mesh
        without its map, ``.med`` without h5py, Nastran ids past 99,999,999, or a
        write that fails (the old file, or none, is left)
    """
    from ..hexmesh import HexMesh

    if not isinstance(hex_mesh, HexMesh):
        from ..checks import describe

        shown = describe(hex_mesh) if not hasattr(hex_mesh, "__dict__") else f"a {type(hex_mesh).__name__}"
        raise OutputError(f"export_hexmesh: hex_mesh = {shown}: must be a HexMesh (hexmesh(result))")
    check_hex_path(path)
    ext = os.path.splitext(path)[1].lower()
    V, H = hex_mesh.vertices, hex_mesh.hexes
    sj = np.asarray(hex_mesh.scaled_jacobian, float)
    if ext == ".vtu":
        write_vtu(path, V, H, cell_data={"scaled_jacobian": sj}, cell_type=VTK_HEXAHEDRON)
    elif ext == ".vtk":
        write_hex_vtk(path, V, H, {"scaled_jacobian": sj})
    elif ext == ".mesh":
        P = hex_mesh.patches
        write_hex_medit(path, V, H, quads=None if P is None else P.quads, quad_refs=None if P is None else P.patch)
    elif ext == ".msh":
        write_hex_msh(path, V, H, hex_mesh.patches, hex_mesh.irregular_edges, hex_mesh.irregular_valence)
    elif ext == ".exo":
        write_hex_exodus(path, V, H, hex_mesh.patches, hex_mesh.irregular_edges)
    elif ext == ".inp":
        write_hex_inp(path, V, H, hex_mesh.patches, hex_mesh.irregular_edges,
                      heading=f"SymFrames hex mesh: {len(H)} C3D8 hexahedra")
    elif ext in (".bdf", ".nas"):
        write_hex_nastran(path, V, H, hex_mesh.patches, hex_mesh.irregular_edges, hex_mesh.irregular_valence)
    elif ext == ".med":
        write_hex_med(path, V, H, hex_mesh.patches, hex_mesh.irregular_edges, hex_mesh.irregular_valence)
    elif ext == ".ovm":
        write_hex_ovm(path, V, H, hex_mesh.patches, sj)
    elif ext == ".hexex":
        gm = hex_mesh.grid_map
        if gm is None:
            raise OutputError(f"{path}: this hex mesh carries no integer-grid map to write")
        write_hexex(path, *gm)
    return [path]
