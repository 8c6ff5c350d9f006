"""VTK XML UnstructuredGrid (.vtu): a mesh of one kind of cell, for ParaView and meshio.

``write_vtu(path, points, cells, point_data, cell_data, binary, cell_type)``
writes tetrahedra (``VTK_TETRA``: a solved field on its tet mesh, vertex and
tet frames, singular-tet markers and per-tet measures; interchange.py) or
hexahedra (``VTK_HEXAHEDRON``: a hex mesh with its scaled Jacobian;
hexformats.py), each with per-point and per-cell arrays, as inline base64
binary or as ASCII.  Written by hand with numpy (no dependency beyond the
solver's); meshio reads the files back in the tests.
"""

from __future__ import annotations

import base64

import numpy as np

from .atomic import write_text
from .text import format_rows

VTK_TETRA = 10
VTK_HEXAHEDRON = 12
_CORNERS = {VTK_TETRA: 4, VTK_HEXAHEDRON: 8}  # points per cell of each VTK cell type written


def _vtu_array(name: str, a: np.ndarray, binary: bool) -> str:
    """One ``<DataArray>`` element: bool and uint8 arrays as UInt8, other
    integers as Int64, floats as Float64; (n, k) arrays with
    ``NumberOfComponents = k`` (``write_vtu``)."""
    a = np.asarray(a)
    if a.dtype.kind == "b" or a.dtype == np.uint8:
        a, vtk = a.astype(np.uint8), "UInt8"
    elif a.dtype.kind in "iu":
        a, vtk = a.astype("<i8"), "Int64"
    elif a.dtype.kind == "f":
        a, vtk = a.astype("<f8"), "Float64"
    else:
        raise TypeError(f"VTU array {name!r}: unsupported dtype {a.dtype}")
    ncomp = 1 if a.ndim == 1 else int(np.prod(a.shape[1:]))
    attrs = f'type="{vtk}" Name="{name}"' + (f' NumberOfComponents="{ncomp}"' if ncomp > 1 else "")
    if binary:
        raw = np.ascontiguousarray(a).tobytes()
        # inline binary: an UInt64 byte count, then the data, base64-encoded together
        payload = base64.b64encode(np.array(len(raw), "<u8").tobytes() + raw).decode("ascii")
        return f'<DataArray {attrs} format="binary">{payload}</DataArray>\n'
    body = format_rows(a.reshape(len(a), -1), "%.17g" if vtk == "Float64" else "%d")
    return f'<DataArray {attrs} format="ascii">\n{body}</DataArray>\n'


def write_vtu(path: str, points: np.ndarray, cells: np.ndarray, point_data: dict | None = None,
              cell_data: dict | None = None, binary: bool = True, cell_type: int = VTK_TETRA) -> None:
    """Write a mesh of one kind of cell as a VTK XML UnstructuredGrid (.vtu).

    Parameters
    ----------
    points : (n, 3) float array
    cells : (m, k) int array, the points of each cell in VTK's order for
        ``cell_type``
    point_data, cell_data : dict name -> (n,) or (n, k) array (k > 1 becomes
        a vector with NumberOfComponents = k); bool arrays are written as UInt8
    binary : inline base64 data (an UInt64 byte count followed by the raw
        little-endian values, encoded together; ``header_type="UInt64"``), else
        ASCII
    cell_type : ``VTK_TETRA`` (10; k = 4, positively oriented: the first
        three points seen from the fourth are counter-clockwise) or
        ``VTK_HEXAHEDRON`` (12; k = 8, one face, then the opposite one,
        counter-clockwise seen from outside the first)

    Format checked against VTK's "VTK File Formats" (XML UnstructuredGrid:
    Piece/Points/Cells with connectivity, offsets, types) and meshio 5.3.5's
    reader, which the tests use to read it back.
    """
    if cell_type not in _CORNERS:
        raise ValueError(f"VTU cell type {cell_type!r}: only VTK_TETRA (10) and VTK_HEXAHEDRON (12) are written")
    points = np.asarray(points, float)
    cells = np.asarray(cells, np.int64)
    m = len(cells)
    out = ['<?xml version="1.0"?>\n',
           '<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n',
           "<UnstructuredGrid>\n", f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{m}">\n',
           "<Points>\n", _vtu_array("Points", points, binary), "</Points>\n", "<Cells>\n",
           _vtu_array("connectivity", cells.reshape(-1), binary),
           _vtu_array("offsets", _CORNERS[cell_type] * np.arange(1, m + 1, dtype=np.int64), binary),
           _vtu_array("types", np.full(m, cell_type, np.uint8), binary),
           "</Cells>\n"]
    for tag, data in (("PointData", point_data), ("CellData", cell_data)):
        if data:
            out.append(f"<{tag}>\n")
            out.extend(_vtu_array(k, v, binary) for k, v in data.items())
            out.append(f"</{tag}>\n")
    out += ["</Piece>\n", "</UnstructuredGrid>\n", "</VTKFile>\n"]
    write_text(path, "".join(out))
