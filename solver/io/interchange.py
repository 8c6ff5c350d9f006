"""Hex-meshing interchange: a solved field written for other tools, and read back.

``export_field(result, path)`` picks the format from the extension:

``.vtu``   VTK XML UnstructuredGrid (ParaView, meshio): tets, vertex frames,
           tet frames, singular-tet markers and per-tet error measures.
``.mesh``  MEDIT mesh + ``.fra`` tet frames + ``.perm`` face matchings next to
           it: the three files CubeCover (Nieser et al. 2011) reads.
``.ovm``   OpenVolumeMesh ASCII with per-cell and per-vertex frame properties
           (AlgoHex, HexHex and OVM tools read it).
``.qtn``   one quaternion per tet in cell order (AlgoHex ``--cell-quaternion-in-path``).

The formats are written by hand with numpy (no dependency beyond the solver's);
each writer's docstring states the format and the source it was checked
against.  Readers for ``.ovm``, ``.fra``, ``.perm`` and ``.qtn`` are here too;
VTU and MEDIT are read by meshio in the tests.

The tet frames and face matchings the formats carry are the field's
(field/matchings.py, paper §5.5); CubeCover's signed-permutation encoding of
the matchings is here (``signed_permutation``).
"""

from __future__ import annotations

import base64
import os
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..analysis.measures import matched_singular_faces, monodromy_angles, omega_singular_faces
from ..errors import NetworkError, OutputError, ReadError
from ..field.matchings import FaceMatchings, TetFrames, face_matchings, omega_tet_frames
from ..linalg.rotations import CUBE_GROUP
from ..mesh.tetmesh import TetMesh
from .atomic import check_output_path, write_files, write_text
from .text import Tokens, read_text

# ================================================================ signed permutations


def signed_permutation(g: np.ndarray) -> np.ndarray:
    """CubeCover's encoding of cube symmetries: (n,) CUBE_GROUP indices ->
    (n, 3) int, entry i = s * (j + 1) when axis i of the first frame maps to
    s times axis j of the second (the column i of G[g] has s in row j)."""
    M = CUBE_GROUP[np.asarray(g)]
    j = np.argmax(np.abs(M), axis=1)  # (n, 3): row of the nonzero per column
    s = np.take_along_axis(M, j[:, None, :], axis=1)[:, 0, :]
    return (s * (j + 1)).astype(np.int64)


def permutation_matrix(p: np.ndarray) -> np.ndarray:
    """Inverse of ``signed_permutation``: (n, 3) entries +-(1..3) -> (n, 3, 3)."""
    p = np.asarray(p, dtype=np.int64).reshape(-1, 3)
    if np.any((np.abs(p) < 1) | (np.abs(p) > 3)) or np.any(np.sort(np.abs(p), axis=1) != [1, 2, 3]):
        raise ValueError("a permutation row must hold +-1, +-2, +-3, each magnitude once")
    M = np.zeros((len(p), 3, 3))
    n = np.arange(len(p))[:, None]
    M[n, np.abs(p) - 1, np.arange(3)[None, :]] = np.sign(p)
    return M


# ============================================================ per-tet measures


@dataclass
class FieldExport:
    """Everything the writers need from a Result, computed once.

    mesh, vertex_frames (#V, 3, 3), tet : TetFrames, matchings : FaceMatchings
    curve       : (#T,) index of the prepared curve crossing each tet, -1 if none
    node_region : (#T,) bool, tets of node regions (no structure equation)
    measures    : per-tet float/int arrays (see ``field_export``)
    """

    mesh: TetMesh
    vertex_frames: np.ndarray
    tet: TetFrames
    matchings: FaceMatchings
    curve: np.ndarray
    node_region: np.ndarray
    measures: dict = field(default_factory=dict)

    @property
    def tet_quaternions(self) -> np.ndarray:
        """(#T, 4) unit quaternions w, x, y, z of the tet frames, w >= 0."""
        return _quaternions(self.tet.frames)

    @property
    def vertex_quaternions(self) -> np.ndarray:
        return _quaternions(self.vertex_frames)


def _quaternions(R: np.ndarray) -> np.ndarray:
    q = Rotation.from_matrix(R).as_quat(scalar_first=True)
    return np.where(q[:, :1] < 0, -q, q)


def _per_tet_max(mesh: TetMesh, face_values: np.ndarray) -> np.ndarray:
    return face_values[mesh.tet_faces].max(axis=1)


@dataclass
class FieldData:
    """What an export needs of a solved field: a Result's, or one stored
    elsewhere (the add-on keeps it in the .blend).

    Attributes
    ----------
    mesh : TetMesh
    frames : (#V, 3, 3) float array
        Vertex frames, columns the cross axes.
    omega : (#E, 3) float array
        The Darboux derivative on ``mesh.edges`` (Eq. 8).
    curve : (#T,) int array
        The curve crossing each tet, -1 elsewhere.
    node_region : (#T,) bool array
        Tets of node regions (no structure equation).
    face_omega : (#F, 3) float array or None
        The prescribed Omega of pierced faces (Eq. 19), zero elsewhere;
        None if unknown (monodromy is then measured against the identity
        everywhere).
    """

    mesh: TetMesh
    frames: np.ndarray
    omega: np.ndarray
    curve: np.ndarray
    node_region: np.ndarray
    face_omega: np.ndarray | None = None


def field_data(result) -> FieldData:
    """The FieldData of a solver Result.

    Parameters
    ----------
    result : solver.Result, or a hexmesh.HexInput (a stored field: its
        prescribed Omega is not kept, ``face_omega`` is None)

    Returns
    -------
    FieldData
        The result's mesh, frames and omega, the curve crossing each tet,
        the node-region tets and the prescribed Omega per face.
    """
    from .. import checks
    from ..errors import OptionsError
    from ..hexmesh import HexInput
    from ..pipeline import Result

    checks.instance("field_data: result", result, (Result, HexInput), OptionsError, "the Result of solve(...)")
    mesh, emb = result.mesh, result.embedding
    curve = np.full(mesh.n_tets, -1, dtype=np.int64)
    for i, tr in enumerate(emb.traces):
        curve[tr.tets] = i
    node = np.zeros(mesh.n_tets, bool)
    node[emb.node_region_tets] = True
    from ..hexmesh import HexInput

    # a stored field keeps no prescribed Omega: unknown
    face_omega = None if isinstance(result, HexInput) else emb.face_omega
    return FieldData(mesh, np.asarray(result.frames), np.asarray(result.omega), curve, node, face_omega)


def field_export(result) -> FieldExport:
    """Tet frames, face matchings, markers and per-tet measures of a Result
    (or a FieldData).

    measures (all (#T,)):
      ``monodromy_deg``       largest failure to close (Eq. 9) over the tet's
                              faces, against the prescribed exp(Omega) on
                              pierced faces (meaningless in node regions)
      ``omega_singular``      faces of the tet where omega-aware matchings do
                              not close (normally 2 where a curve passes
                              through the tet, 0 off the network)
      ``closest_singular``    the same with closest-rotation matchings
      ``spread_deg``          tet.spread in degrees
      ``matching_disagree``   faces of the tet where the omega matching and
                              the closest-rotation matching of tet frames differ
      ``matching_ambiguous``  faces of the tet whose three vertices disagreed
    """
    fd = result if isinstance(result, FieldData) else field_data(result)
    mesh = fd.mesh
    tf = omega_tet_frames(mesh, fd.omega, fd.frames)
    fm = face_matchings(mesh, tf)
    mono = np.degrees(monodromy_angles(mesh, fd.omega, None, fd.face_omega))
    osing = omega_singular_faces(mesh, fd.omega, fd.frames).astype(np.int64)
    csing = matched_singular_faces(mesh, fd.frames)[0].astype(np.int64)
    dis = np.zeros(mesh.n_faces, np.int64)
    dis[fm.faces] = fm.symmetry != fm.closest
    amb = np.zeros(mesh.n_faces, np.int64)
    amb[fm.faces] = ~fm.agree
    tfc = mesh.tet_faces
    measures = {
        "monodromy_deg": _per_tet_max(mesh, mono),
        "omega_singular": osing[tfc].sum(axis=1),
        "closest_singular": csing[tfc].sum(axis=1),
        "spread_deg": np.degrees(tf.spread),
        "matching_disagree": dis[tfc].sum(axis=1),
        "matching_ambiguous": amb[tfc].sum(axis=1),
    }
    return FieldExport(mesh, np.asarray(fd.frames), tf, fm, fd.curve, fd.node_region, measures)


def edge_field_export(result) -> FieldExport:
    """The FieldExport of a Result (or hexmesh.HexInput) on its tet mesh split
    so that every curve runs along tet edges (hexmesh.field_on_edges): the
    per-tet field's singular edges are then the curves' chains, not
    staircases of tet edges around them, which is what CubeCover's and
    AlgoHex's parametrisations need.  Raises HexMeshError where that is not
    possible."""
    from ..hexmesh import field_on_edges

    ef = field_on_edges(result)
    nT = ef.mesh.n_tets
    tf = TetFrames(ef.tet_frames, np.zeros((nT, 4), np.int64), np.zeros(nT))
    fm = FaceMatchings(ef.faces, ef.tets, ef.transition, np.ones(len(ef.faces), bool), ef.transition)
    return FieldExport(ef.mesh, ef.vertex_frames, tf, fm, ef.curve, np.zeros(nT, bool), {})


# ======================================================================= VTU

_VTK_TETRA = 10


def _vtu_array(name: str, a: np.ndarray, binary: bool) -> str:
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
    body = _fmt_rows(a.reshape(len(a), -1), "%.17g" if vtk == "Float64" else "%d")
    return f'<DataArray {attrs} format="ascii">\n{body}</DataArray>\n'


def _fmt_rows(a: np.ndarray, fmt: str) -> str:
    """Rows of a 2D array as text lines (C-level formatting, no Python loop per row)."""
    a = np.asarray(a)
    if len(a) == 0:
        return ""
    a = a.reshape(len(a), -1)
    line = " ".join([fmt] * a.shape[1]) + "\n"
    return (line * len(a)) % tuple(a.reshape(-1).tolist())


def write_vtu(path: str, points: np.ndarray, tets: np.ndarray, point_data: dict | None = None,
              cell_data: dict | None = None, binary: bool = True) -> None:
    """Write a tet mesh as a VTK XML UnstructuredGrid (.vtu).

    Parameters
    ----------
    points : (n, 3) float array
    tets : (m, 4) int array, positively oriented (VTK_TETRA, type 10: the
        first three points seen from the fourth are counter-clockwise)
    point_data, cell_data : dict name -> (n,) or (n, k) array (k > 1 becomes
        a vector with NumberOfComponents = k); bool arrays are written as UInt8
    binary : inline base64 data (an UInt64 byte count followed by the raw
        little-endian values, encoded together; ``header_type="UInt64"``), else
        ASCII

    Format checked against VTK's "VTK File Formats" (XML UnstructuredGrid:
    Piece/Points/Cells with connectivity, offsets, types) and meshio 5.3.5's
    reader, which the tests use to read it back.
    """
    points = np.asarray(points, float)
    tets = np.asarray(tets, np.int64)
    m = len(tets)
    out = ['<?xml version="1.0"?>\n',
           '<VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n',
           "<UnstructuredGrid>\n", f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{m}">\n',
           "<Points>\n", _vtu_array("Points", points, binary), "</Points>\n", "<Cells>\n",
           _vtu_array("connectivity", tets.reshape(-1), binary),
           _vtu_array("offsets", 4 * np.arange(1, m + 1, dtype=np.int64), binary),
           _vtu_array("types", np.full(m, _VTK_TETRA, np.uint8), binary),
           "</Cells>\n"]
    for tag, data in (("PointData", point_data), ("CellData", cell_data)):
        if data:
            out.append(f"<{tag}>\n")
            out.extend(_vtu_array(k, v, binary) for k, v in data.items())
            out.append(f"</{tag}>\n")
    out += ["</Piece>\n", "</UnstructuredGrid>\n", "</VTKFile>\n"]
    write_text(path, "".join(out))


def vtu_field_data(fe: FieldExport) -> tuple[dict, dict]:
    """(point_data, cell_data) of a FieldExport as written to VTU.

    point data: ``axis0``, ``axis1``, ``axis2`` (#V, 3) the vertex frame's
    columns; ``boundary`` (#V,) UInt8.
    cell data: ``tet_axis0..2`` (#T, 3) the tet frame's columns; ``curve``
    (#T,) crossing curve or -1; ``singular`` (#T,) UInt8, crossed by a curve;
    ``node_region`` UInt8; and the measures of ``field_export``.
    """
    pd = {f"axis{k}": fe.vertex_frames[:, :, k] for k in range(3)}
    pd["boundary"] = fe.mesh.is_boundary_vertex
    cd = {f"tet_axis{k}": fe.tet.frames[:, :, k] for k in range(3)}
    cd["curve"] = fe.curve
    cd["singular"] = fe.curve >= 0
    cd["node_region"] = fe.node_region
    cd.update(fe.measures)
    return pd, cd


# ===================================================================== MEDIT


def write_medit(path: str, vertices: np.ndarray, tets: np.ndarray, triangles: np.ndarray | None = None,
                edges: np.ndarray | None = None, tet_refs=None, triangle_refs=None, edge_refs=None,
                vertex_refs=None) -> None:
    """Write a MEDIT ASCII mesh (.mesh); the text is ``medit_text``'s (same
    parameters)."""
    write_text(path, medit_text(vertices, tets, triangles, edges, tet_refs, triangle_refs, edge_refs, vertex_refs))


def medit_text(vertices: np.ndarray, tets: np.ndarray, triangles: np.ndarray | None = None,
               edges: np.ndarray | None = None, tet_refs=None, triangle_refs=None, edge_refs=None,
               vertex_refs=None) -> str:
    """A MEDIT ASCII mesh (.mesh), 1-based indices::

        MeshVersionFormatted 2
        Dimension 3
        Vertices
        n
        x y z ref            (n lines)
        Edges                (if given)
        k
        i j ref
        Triangles            (if given)
        k
        i j k ref
        Tetrahedra
        m
        i j k l ref
        End

    Checked against CubeCover's reader (evouga/CubeCover src/readMeshFixed.h:
    version 1 or 2, ``Dimension 3``, a count after each keyword, a reference
    number closing every entity line, ``End``) and meshio's MEDIT reader.
    Refs default to 0.
    """
    def refs(r, n):
        return np.zeros(n, np.int64) if r is None else np.broadcast_to(np.asarray(r, np.int64), (n,))

    V = np.asarray(vertices, float)
    out = ["MeshVersionFormatted 2\n", "Dimension 3\n", f"Vertices\n{len(V)}\n",
           _fmt_rows(np.c_[V, refs(vertex_refs, len(V))], "%.17g")]
    for name, X, r in (("Edges", edges, edge_refs), ("Triangles", triangles, triangle_refs),
                       ("Tetrahedra", tets, tet_refs)):
        if X is None:
            continue
        X = np.asarray(X, np.int64)
        out.append(f"{name}\n{len(X)}\n")
        out.append(_fmt_rows(np.c_[X + 1, refs(r, len(X))], "%d"))
    out.append("End\n")
    return "".join(out)


# MEDIT sections: values per entry (Dimension 3); the element sections end in a reference number
MEDIT_SECTIONS = {"vertices": 4, "edges": 3, "triangles": 4, "quadrilaterals": 5, "tetrahedra": 5, "prisms": 7,
                  "pyramids": 6, "hexahedra": 9, "corners": 1, "ridges": 1, "requiredvertices": 1,
                  "requirededges": 1, "requiredtriangles": 1, "requiredquadrilaterals": 1,
                  "requiredtetrahedra": 1, "requiredhexahedra": 1, "normals": 3, "tangents": 3,
                  "normalatvertices": 2, "tangentatedges": 2, "normalattrianglevertices": 3,
                  "normalatquadrilateralvertices": 3, "tangentatvertices": 2}
# sections of vertex indices (1-based), by the number of them per entry
MEDIT_INDEXED = {"edges": 2, "triangles": 3, "quadrilaterals": 4, "tetrahedra": 4, "prisms": 6, "pyramids": 5,
                 "hexahedra": 8, "corners": 1, "requiredvertices": 1}


@dataclass
class MeditData:
    """A MEDIT ASCII mesh as ``read_medit`` reads it.

    vertices : (n, 3); tets : (m, 4) 0-based; edges : (k, 2) 0-based;
    edge_refs : (k,) int, the reference number of each edge;
    tet_lines, edge_lines : the line of each entry in the file
    """

    vertices: np.ndarray
    tets: np.ndarray
    edges: np.ndarray
    edge_refs: np.ndarray
    tet_lines: np.ndarray
    edge_lines: np.ndarray


def read_medit(path: str, error=NetworkError) -> MeditData:
    """Read a MEDIT ASCII mesh (format in ``write_medit``), checking
    everything it reads.

    Keywords are case-insensitive; ``#`` starts a comment.  Sections other
    than Vertices, Edges and Tetrahedra are read by their counts and
    checked, then left out.  ``error`` is raised naming the file, the line
    and the value of: an unknown keyword, a Dimension other than 3, a count
    that is not a whole number or more entries than the file holds, a
    coordinate that is not a finite number, a vertex index or reference
    number that is not a whole number, an index outside 1..#vertices
    (MEDIT counts from 1), a missing Vertices or Tetrahedra section.
    ``MeshVersionFormatted`` 1 and 2 are read; ``End`` ends the file.
    """
    tok = Tokens(read_text(path, error, "MEDIT mesh"), path, error)
    out, first = {}, {}
    while not tok.done:
        i = tok.pos
        word = tok.next("a keyword")
        key = word.lower()
        if key == "end":
            break
        if key in ("meshversionformatted", "dimension"):
            v = tok.next(f"the value of {word}")
            if key == "dimension" and v != "3":
                tok.fail(f"Dimension {v!r}: only 3D meshes (Dimension 3) are read", i + 1)
            if key == "meshversionformatted" and v not in ("1", "2", "3", "4"):
                tok.fail(f"MeshVersionFormatted {v!r}: expected 1 or 2 (an ASCII MEDIT file; a binary .meshb is "
                         "not read)", i + 1)
            continue
        if key not in MEDIT_SECTIONS:
            tok.fail(f"{word!r} is no MEDIT keyword" + (" (a number here means the count of the section before is "
                                                        "too small)" if word[:1].isdigit() or word[:1] in "+-."
                                                        else f"; the sections read are "
                                                        f"{', '.join(k.title() for k in MEDIT_SECTIONS)}"), i)
        if key in out:
            tok.fail(f"a second {word} section (the first at line {tok.line(first[key])})", i)
        w = MEDIT_SECTIONS[key]
        n = tok.count(f"entries of the {word} section", w)
        start = tok.pos
        kind = "float" if key in ("vertices", "normals", "tangents") else "int"
        out[key] = tok.block(n, w, f"{word} section", kind)
        first[key] = start
        if key in MEDIT_INDEXED:
            out[key + "_lines"] = tok.lines[start:tok.pos:w] if n else np.zeros(0, np.int64)
    for key in ("vertices", "tetrahedra"):
        if key not in out:
            raise error(f"{path}: no {key.title()} section; a MEDIT tet mesh needs Vertices and Tetrahedra")
    nV = len(out["vertices"])
    for key, k in MEDIT_INDEXED.items():
        if key not in out or not len(out[key]):
            continue
        idx = out[key][:, :k]
        bad = np.nonzero(np.any((idx < 1) | (idx > nV), axis=1))[0]
        if len(bad):
            r = bad[0]
            v = idx[r][(idx[r] < 1) | (idx[r] > nV)][0]
            hint = " (0: the indices look 0-based; MEDIT counts vertices from 1)" if v == 0 else ""
            raise error(f"{path}:{out[key + '_lines'][r]}: {key.title()} entry {r + 1} refers to vertex {v}, but the "
                        f"file has {nV:,} vertices (valid: 1..{nV}){hint}")
    E = out.get("edges", np.zeros((0, 3), np.int64))
    return MeditData(out["vertices"][:, :3], out["tetrahedra"][:, :4] - 1, E[:, :2] - 1, E[:, 2],
                     out["tetrahedra_lines"], out.get("edges_lines", np.zeros(0, np.int64)))


def boundary_triangles(mesh: TetMesh) -> np.ndarray:
    """(k, 3) boundary triangles of the tet mesh in global vertex ids,
    oriented outward."""
    return mesh.boundary_vertices[mesh.boundary.F]


def write_fra(path: str, frames: np.ndarray) -> None:
    """Write per-tet frames as ``fra_text`` makes them."""
    write_text(path, fra_text(frames))


def fra_text(frames: np.ndarray) -> str:
    """Per-tet frames in CubeCover's ``.fra`` format::

        FRA 1
        ntets 3 1
        a0x a0y a0z          (3 lines per tet, in tet order: the frame's
        a1x a1y a1z           three axes, i.e. the columns of E)
        a2x a2y a2z

    The header line after ``FRA 1`` is ``#frames vectors-per-frame type``;
    CubeCover reads the type and ignores it, and its own writer puts 1.
    Checked against evouga/CubeCover src/ReadFrameField.cpp and
    src/WriteFrameFIeld.cpp.

    frames : (#T, 3, 3) float array, columns are the cross axes
    """
    F = np.asarray(frames, float)
    rows = np.transpose(F, (0, 2, 1)).reshape(-1, 3)  # axis k of tet t on row 3t + k
    return f"FRA 1\n{len(F)} 3 1\n" + _fmt_rows(rows, "%.17g")


def read_fra(path: str) -> np.ndarray:
    """Per-tet frames of a ``.fra`` file with 3 vectors per tet -> (#T, 3, 3),
    the vectors as columns.

    Raises
    ------
    ReadError
        not a version-1 ``.fra``, a count that the file does not hold, a
        value that is not a finite number, or data after the last frame;
        naming the file, the line and the value
    """
    tok = _text_tokens(path, ".fra (CubeCover frames)")
    if tok.next("'FRA'") != "FRA" or tok.next("the version") != "1":
        tok.fail("not a version-1 .fra file (it must start with 'FRA 1')", 0)
    n = tok.count("frames", 9)
    vpt = tok.count("vectors per frame", 0)
    if vpt != 3:
        tok.fail(f"{vpt} vectors per frame; only frames of 3 vectors are read", tok.pos - 1)
    tok.next("the frame type")
    vals = tok.block(3 * n, 3, "frame vectors")
    _end(tok, "the last frame")
    return np.transpose(vals.reshape(n, 3, 3), (0, 2, 1))


def _text_tokens(path, what: str) -> Tokens:
    """The words of an interchange text file, with their lines (ReadError)."""
    return Tokens(read_text(path, ReadError, what), os.fspath(path), ReadError)


def _end(tok: Tokens, what: str) -> None:
    if not tok.done:
        tok.fail(f"{tok.words[tok.pos]!r} after {what}: the count in the header is smaller than the data (or the "
                 "file has extra data)")


def write_perm(path: str, n_tets: int, tets: np.ndarray, perms: np.ndarray, keep_identity: bool = False) -> None:
    """Write face matchings as ``perm_text`` makes them."""
    write_text(path, perm_text(n_tets, tets, perms, keep_identity))


def perm_text(n_tets: int, tets: np.ndarray, perms: np.ndarray, keep_identity: bool = False) -> str:
    """Face matchings in CubeCover's ``.perm`` format::

        PERM 1
        ntets nfaces 3
        t0 t1 p0 p1 p2       (one line per listed interior face)

    t0, t1 are 0-based tets sharing the face; p_i = s * (j + 1) says that
    axis i of t0's frame corresponds to s times axis j of t1's frame
    (CubeCover's AssignmentGroup: ``to.row(j) ~ s * from.row(i)``).  Faces not
    listed have the identity matching; like CubeCover's own writer only
    non-identity faces are written unless ``keep_identity``.  CubeCover inverts
    the permutation itself when t0, t1 come in the other order than in its face
    table.  Checked against evouga/CubeCover src/ReadFrameField.cpp,
    src/FrameField.cpp (fromFramesAndAssignments), src/AssignmentGroup.cpp
    (parseFromPerm, operator*) and src/WriteFrameFIeld.cpp.

    tets : (k, 2) int, perms : (k, 3) int (``signed_permutation``)
    """
    tets = np.asarray(tets, np.int64).reshape(-1, 2)
    perms = np.asarray(perms, np.int64).reshape(-1, 3)
    if not keep_identity:
        keep = np.any(perms != [1, 2, 3], axis=1)
        tets, perms = tets[keep], perms[keep]
    return f"PERM 1\n{int(n_tets)} {len(tets)} 3\n" + _fmt_rows(np.c_[tets, perms], "%d")


def read_perm(path: str) -> tuple[int, np.ndarray, np.ndarray]:
    """(#tets, (k, 2) tet pairs, (k, 3) signed permutations) of a ``.perm`` file.

    Raises
    ------
    ReadError
        not a version-1 ``.perm``, a count the file does not hold, a tet id
        outside 0..#tets-1, a face of a tet with itself, or a permutation
        that is not a signed permutation of 1, 2, 3; naming the file, the line
        and the value
    """
    tok = _text_tokens(path, ".perm (CubeCover face matchings)")
    if tok.next("'PERM'") != "PERM" or tok.next("the version") != "1":
        tok.fail("not a version-1 .perm file (it must start with 'PERM 1')", 0)
    nt = tok.count("tets", 0)
    nf = tok.count("face lines", 5)
    nv = tok.count("assignments per face", 0)
    if nv != 3:
        tok.fail(f"{nv} assignments per face; only 3 are read", tok.pos - 1)
    first = tok.pos
    vals = tok.block(nf, 5, "face lines", "int")
    _end(tok, "the last face line")
    T, P = vals[:, :2], vals[:, 2:]
    line = tok.lines[first::5] if nf else tok.lines[:0]
    bad = np.nonzero(((T < 0) | (T >= nt)).any(axis=1))[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{line[bad[0]]}: face line {T[bad[0]].tolist()} names a tet outside 0..{nt - 1} "
                        f"(the header says {nt} tets; ids are 0-based)")
    bad = np.nonzero(T[:, 0] == T[:, 1])[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{line[bad[0]]}: face line {T[bad[0]].tolist()} matches a tet with itself")
    bad = np.nonzero(np.any(np.sort(np.abs(P), axis=1) != [1, 2, 3], axis=1))[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{line[bad[0]]}: the permutation {P[bad[0]].tolist()} is not a signed "
                        "permutation of 1, 2, 3 (each of +-1, +-2, +-3 once)")
    return nt, T, P


# ======================================================================= QTN


def write_qtn(path: str, quaternions: np.ndarray) -> None:
    """Write AlgoHex's ``.qtn``: one unit quaternion ``w x y z`` per cell, in
    cell order, no header (AlgoHex reads whitespace-separated numbers, four per
    cell: cgg-bern/AlgoHex demo/HexMeshing/HexMeshing.cc load_cell_quaternions
    and src/AlgoHex/SingularGraphExtractionT_impl.hh).  AlgoHex's frame axis i
    is ``q * e_i``, the i-th column of the rotation matrix, as here.  The cell
    order is the tet order of the ``.ovm``/``.mesh``/``.vtu`` written with it."""
    write_text(path, _fmt_rows(np.asarray(quaternions, float), "%.17g"))


def read_qtn(path: str) -> np.ndarray:
    """(n, 4) quaternions w, x, y, z of a ``.qtn`` file.

    Raises
    ------
    ReadError
        a value that is not a finite number, a count that is not four per
        cell, or a quaternion of zero length; naming the file, line and value
    """
    tok = _text_tokens(path, ".qtn (AlgoHex quaternions)")
    if len(tok) % 4:
        raise ReadError(f"{tok.path}: {len(tok)} numbers is not four per cell (w x y z); the file is truncated or "
                        f"has extra data (line {tok.line(len(tok) - 1)})")
    q = tok.block(len(tok) // 4, 4, "quaternions")
    norm = np.linalg.norm(q, axis=1)
    bad = np.nonzero(norm < 1e-9)[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{tok.lines[4 * bad[0]]}: quaternion {bad[0]} is {q[bad[0]].tolist()}: of zero "
                        "length, no rotation")
    return q


def quaternion_frames(q: np.ndarray) -> np.ndarray:
    """Frames of quaternions, as ``.qtn`` files and the add-on store them.

    Parameters
    ----------
    q : (n, 4) float array
        Quaternions w, x, y, z; normalised here, so any nonzero length will do.

    Returns
    -------
    (n, 3, 3) float array
        Rotation matrices, columns the cross axes.

    Raises
    ------
    OptionsError
        q not (n, 4) finite numbers, or a quaternion of zero length
    """
    from .. import checks
    from ..errors import OptionsError

    q = checks.array("quaternions", q, OptionsError, shape=(None, 4))
    zero = np.nonzero(np.linalg.norm(q, axis=1) < 1e-12)[0]
    if len(zero):
        raise OptionsError(f"quaternion {zero[0]} is {q[zero[0]].tolist()}: of zero length, no rotation")
    return Rotation.from_quat(np.asarray(q, float), scalar_first=True).as_matrix()


# ======================================================================= OVM

_OVM_ENTITIES = {"vertex": "VProp", "edge": "EProp", "halfedge": "HEProp", "face": "FProp",
                 "halfface": "HFProp", "cell": "CProp", "mesh": "MProp"}
_OVM_READ_ENTITIES = {"vprop": "vertex", "eprop": "edge", "heprop": "halfedge", "fprop": "face",
                      "hfprop": "halfface", "cprop": "cell", "mprop": "mesh",
                      # the older long names (OpenVolumeMesh documentation/examples)
                      "vertex_property": "vertex", "edge_property": "edge", "halfedge_property": "halfedge",
                      "face_property": "face", "halfface_property": "halfface", "polyhedron_property": "cell",
                      "cell_property": "cell", "mesh_property": "mesh"}
_OVM_SCALARS = {"int": np.int64, "uint": np.int64, "short": np.int64, "long": np.int64, "ulong": np.int64,
                "char": np.int64, "uchar": np.int64, "bool": bool, "float": float, "double": float}


def _ovm_type(a: np.ndarray) -> str:
    k = a.dtype.kind
    if a.ndim == 1:
        return {"b": "bool", "i": "int", "u": "uint", "f": "double"}[k]
    n = a.shape[1]
    if a.ndim != 2 or n not in (2, 3, 4):
        raise ValueError("OVM property arrays must be (n,) or (n, 2|3|4)")
    return f"vec{n}" + {"i": "i", "u": "ui", "f": "d", "b": "i"}[k]


def ovm_halffaces(mesh: TetMesh) -> tuple[np.ndarray, np.ndarray]:
    """OpenVolumeMesh connectivity of a TetMesh.

    Returns (face_halfedges (#F, 3), cell_halffaces (#T, 4)).  Edge e is
    ``mesh.edges[e]`` from its first to its second vertex; halfedge 2e runs that
    way, 2e + 1 back.  Face f = a < b < c (``mesh.faces``) is the loop
    a -> b -> c -> a: halfedges (2 e_ab, 2 e_bc, 2 e_ac + 1).  Halfface 2f has
    that loop's right-hand normal, 2f + 1 the opposite one.  A cell lists, for
    its faces opposite local vertices 0..3, the halfface whose normal points
    into the cell (OpenVolumeMesh's convention; TetrahedralMeshTopologyKernel
    builds cells so from positively oriented vertex quadruples).  Chosen
    combinatorially: the face (a, b, c) seen with the opposite vertex v is
    inward-facing iff (a, b, c, v) is an even permutation of the positively
    oriented tet.
    """
    fe = mesh.face_edges
    he = np.stack([2 * fe[:, 0], 2 * fe[:, 1], 2 * fe[:, 2] + 1], axis=1)
    T = mesh.tets
    tf = mesh.tet_faces
    Fv = mesh.faces[tf]  # (#T, 4, 3)
    seq = np.concatenate([Fv, T[:, :, None]], axis=2)  # (#T, 4, 4): a, b, c, opposite
    pos = np.argmax(seq[..., :, None] == T[:, None, None, :], axis=3)  # positions in the tet
    inv = np.zeros(pos.shape[:2], np.int64)
    for i in range(4):
        for j in range(i + 1, 4):
            inv += pos[..., i] > pos[..., j]
    hf = 2 * tf + (inv % 2)
    return he, hf


def write_ovm(path: str, mesh: TetMesh, vertex_props: dict | None = None, edge_props: dict | None = None,
              face_props: dict | None = None, cell_props: dict | None = None) -> None:
    """Write a tet mesh as OpenVolumeMesh ASCII (.ovm)::

        OVM ASCII
        Vertices
        n
        x y z
        Edges
        #E
        i j                  (mesh.edges order)
        Faces
        #F
        3 h0 h1 h2           (halfedge indices, ovm_halffaces)
        Polyhedra
        #T
        4 f0 f1 f2 f3        (halfface indices, normals into the cell)
        CProp vec4d "name"   (then one value per line, per cell)
        ...

    Properties come after the topology as ``<VProp|EProp|FProp|CProp> <type>
    "<name>"`` followed by one line per entity; types ``int``, ``uint``,
    ``bool``, ``double``, ``vec{2,3,4}{d,i}``.  Checked against
    OpenVolumeMesh/OpenVolumeMesh src/OpenVolumeMesh/FileManager
    (FileManagerT_impl.hh readStream/writeStream/readProperty, TypeNames.cc) and
    Core/TopologyKernel.cc, Mesh/TetrahedralMeshTopologyKernel.cc for the
    halfedge/halfface conventions.

    Property dicts map name -> (n,) or (n, k) arrays indexed like the mesh's
    vertices / edges / faces / tets.
    """
    he, hf = ovm_halffaces(mesh)
    out = ["OVM ASCII\n", f"Vertices\n{mesh.n_vertices}\n", _fmt_rows(mesh.vertices, "%.17g"),
           f"Edges\n{mesh.n_edges}\n", _fmt_rows(mesh.edges, "%d"),
           f"Faces\n{mesh.n_faces}\n", _fmt_rows(np.c_[np.full(mesh.n_faces, 3), he], "%d"),
           f"Polyhedra\n{mesh.n_tets}\n", _fmt_rows(np.c_[np.full(mesh.n_tets, 4), hf], "%d")]
    sizes = {"vertex": mesh.n_vertices, "edge": mesh.n_edges, "face": mesh.n_faces, "cell": mesh.n_tets}
    for ent, props in (("vertex", vertex_props), ("edge", edge_props), ("face", face_props), ("cell", cell_props)):
        for name, a in (props or {}).items():
            a = np.asarray(a)
            if len(a) != sizes[ent]:
                raise ValueError(f"{ent} property {name!r} has {len(a)} values for {sizes[ent]} {ent}s")
            if '"' in name:
                raise ValueError(f"property name {name!r} must not contain a double quote")
            t = _ovm_type(a)
            out.append(f'{_OVM_ENTITIES[ent]} {t} "{name}"\n')
            out.append(_fmt_rows(a.astype(np.int64) if a.dtype.kind == "b" else a,
                                 "%.17g" if a.dtype.kind == "f" else "%d"))
    write_text(path, "".join(out))


@dataclass
class OVMData:
    """An OpenVolumeMesh ASCII file: tets rebuilt from the halffaces.

    vertices : (n, 3), edges : (#E, 2), face_halfedges : (#F, 3),
    cell_halffaces : (#C, 4), tets : (#C, 4) vertex quadruples oriented like
    the file (the first halfface's loop, then the remaining vertex: positive
    when halfface normals point into the cells), props : {entity: {name: array}}
    with entity in vertex, edge, halfedge, face, halfface, cell, mesh.
    """

    vertices: np.ndarray
    edges: np.ndarray
    face_halfedges: np.ndarray
    cell_halffaces: np.ndarray
    tets: np.ndarray
    props: dict
    props_line: dict = field(default_factory=dict)


def read_ovm(path: str, error=NetworkError) -> OVMData:
    """Read an OpenVolumeMesh ASCII tet mesh with its properties (format in
    ``write_ovm``), checking everything it reads.

    Comments (#) and blank lines are skipped, keywords are case-insensitive.
    Numeric properties (``int``, ``uint``, ``short``, ``long``, ``char``,
    ``bool``, ``float``, ``double`` and ``vec{2,3,4}{d,f,i,ui}``) are read;
    others are skipped, one line per entity.  Every count, index and value
    is checked (``error`` is raised naming the file, the line and the value):
    counts are whole numbers the file holds that many entries for, vertices
    finite, faces triangles of halfedges that close a loop, cells
    tetrahedra of four halffaces that close one, integer properties whole
    numbers.  ``props_line[entity][name]`` is the line of a property's first
    value (one entity per line, as OpenVolumeMesh writes them).
    """
    tok = Tokens(read_text(path, error, "OpenVolumeMesh file"), path, error)
    if not tok.done and tok.words[0].upper() == "OVM":
        tok.next("OVM")
        kind = tok.next("ASCII").upper() if not tok.done else "ASCII"
        if kind == "BINARY":
            tok.fail("binary OVM is not supported; save it as OVM ASCII", 1)
        if kind != "ASCII":
            tok.fail(f"'OVM {kind}': expected 'OVM ASCII'", 1)

    def section(name, width, kind):
        i = tok.pos
        word = tok.next(f"the {name} section")
        if word.upper() != name.upper():
            tok.fail(f"{word!r} where the {name} section was expected (sections: Vertices, Edges, Faces, "
                     "Polyhedra, in this order)", i)
        n = tok.count(name.lower(), width)
        return tok.block(n, width, f"{name} section", kind), i

    V, _ = section("Vertices", 3, "float")
    E, _ = section("Edges", 2, "int")
    Fh, f0 = section("Faces", 4, "int")
    Ch, c0 = section("Polyhedra", 5, "int")
    nV, nE, nF = len(V), len(E), len(Fh)
    _entries_in_range(tok, E, 0, nV, 0, "edge", "vertex", f"0..{nV - 1}")
    for X, first, what, valence, sub in ((Fh, f0, "face", 3, "halfedges"), (Ch, c0, "cell", 4, "halffaces")):
        bad = np.nonzero(X[:, 0] != valence)[0]
        if len(bad):
            tok.fail(f"{what} {bad[0]} has {X[bad[0], 0]} {sub}; only tetrahedral meshes are supported ({what}s of "
                     f"{valence} {sub})", _entry_word(tok, first, X.shape[1], bad[0]))
    _entries_in_range(tok, Fh, f0, 2 * nE, 1, "face", "halfedge", f"0..{2 * nE - 1}")
    _entries_in_range(tok, Ch, c0, 2 * nF, 1, "cell", "halfface", f"0..{2 * nF - 1}")
    he, hf = Fh[:, 1:], Ch[:, 1:]
    loose = np.nonzero(E[:, 0] == E[:, 1])[0]
    if len(loose):
        tok.fail(f"edge {loose[0]} joins vertex {E[loose[0], 0]} to itself", _entry_word(tok, 0, 2, loose[0]))
    # halfedge h runs from hv[h]; a face's halfedges must close a loop
    hv = E.reshape(-1)
    hv_to = E[:, ::-1].reshape(-1)
    loop = hv[he]
    open_ = np.nonzero(np.any(hv_to[he] != np.roll(loop, -1, axis=1), axis=1))[0]
    if len(open_):
        f = open_[0]
        tok.fail(f"face {f}: its halfedges {he[f].tolist()} do not close a loop (each must start where the one "
                 "before it ends)", _entry_word(tok, f0, 4, f))
    T = _ovm_tets(tok, loop, hf, c0)
    counts = {"vertex": nV, "edge": nE, "halfedge": 2 * nE, "face": nF, "halfface": 2 * nF, "cell": len(hf), "mesh": 1}
    props: dict = {k: {} for k in counts}
    props_line: dict = {k: {} for k in counts}
    while not tok.done:
        i = tok.pos
        line = tok.line(i)
        ent = _OVM_READ_ENTITIES.get(tok.words[i].lower())
        if ent is None:
            tok.fail(f"{tok.words[i]!r} where a property (VProp, EProp, FProp, CProp, ... type \"name\") or the "
                     "end of the file was expected", i)
        head = tok.raw_line(line)
        while not tok.done and tok.line() == line:
            tok.pos += 1
        parts = head.split()
        if len(parts) < 2:
            tok.fail(f"property line {head.strip()!r}: expected '{parts[0]} <type> \"<name>\"'", i)
        typ = parts[1].lower()
        name = head[head.find('"') + 1:head.rfind('"')] if head.count('"') >= 2 else ""
        n = counts[ent]
        what = f"{ent} property {name!r}"
        if typ in _OVM_SCALARS or (typ.startswith("vec") and typ[3:4] in ("2", "3", "4")
                                   and typ[4:] in ("d", "f", "i", "ui")):
            k = 1 if typ in _OVM_SCALARS else int(typ[3])
            if n * k > len(tok) - tok.pos:
                tok.fail(f"{what} ({typ}) needs {n:,} values of {k} number(s), one per {ent}, but the file holds "
                         f"only {len(tok) - tok.pos:,} more values (truncated?)", i)
            props_line[ent][name] = tok.line()
            integer = typ in _OVM_SCALARS and _OVM_SCALARS[typ] is not float or typ[4:] in ("i", "ui")
            if typ == "bool":
                words = tok.words[tok.pos:tok.pos + n]
                tok.words[tok.pos:tok.pos + n] = [{"true": "1", "false": "0"}.get(w.lower(), w) for w in words]
            vals = tok.block(n, k, f"values of the {what}", "int" if integer else "float")
            props[ent][name] = vals[:, 0] if k == 1 else vals
            if typ == "bool":
                if np.any((vals != 0) & (vals != 1)):
                    j = int(np.argmax(((vals != 0) & (vals != 1))[:, 0]))
                    tok.fail(f"{what} (bool): value {vals[j, 0]} for {ent} {j}; must be 0 or 1",
                             tok.pos - n + j)
                props[ent][name] = vals[:, 0].astype(bool)
        else:
            # an unknown type: its values take one line per entity
            while not tok.done and tok.line() <= line + n:
                tok.pos += 1
    return OVMData(V, E, he, hf, T, props, props_line)


def _entry_word(tok: Tokens, first: int, width: int, k: int) -> int:
    """Index of the first word of entry k of a section whose keyword is word
    ``first`` (then its count, then the entries)."""
    return first + 2 + k * width


def _entries_in_range(tok: Tokens, X: np.ndarray, first: int, n: int, skip: int, what: str, sub: str,
                      valid: str) -> None:
    """Refuse an index outside [0, n) in the columns of X after ``skip``."""
    A = X[:, skip:]
    bad = np.nonzero(np.any((A < 0) | (A >= n), axis=1))[0]
    if len(bad):
        k = bad[0]
        v = A[k][(A[k] < 0) | (A[k] >= n)][0]
        tok.fail(f"{what} {k} refers to {sub} {v}, but the file has {n:,} {sub}s (valid: {valid}; indices are "
                 "0-based)", _entry_word(tok, first, X.shape[1], k))


def _ovm_tets(tok: Tokens, loop: np.ndarray, hf: np.ndarray, first: int) -> np.ndarray:
    """Vertex quadruples of the cells, oriented like the file (the first
    halfface's loop, then the remaining vertex); a cell whose four
    halffaces are not the four faces of one tetrahedron is refused."""
    if not len(hf):
        return np.zeros((0, 4), np.int64)
    f = hf // 2
    tris = loop[f]  # (#C, 4, 3)
    tri = np.where((hf[:, 0] % 2 == 1)[:, None], tris[:, 0, ::-1], tris[:, 0])
    other = tris[:, 1]
    on_tri = (other[:, :, None] == tri[:, None, :]).any(axis=2)
    fourth = other[np.arange(len(other)), np.argmin(on_tri, axis=1)]
    T = np.c_[tri, fourth]
    # each of the four faces: three distinct vertices of T; the faces distinct
    in_T = (tris[:, :, :, None] == T[:, None, None, :]).any(axis=3).all(axis=2)
    Ts = np.sort(T, axis=1)
    distinct = np.all(Ts[:, 1:] != Ts[:, :-1], axis=1)
    fs = np.sort(f, axis=1)
    faces_distinct = np.all(fs[:, 1:] != fs[:, :-1], axis=1)
    bad = np.nonzero(~(in_T.all(axis=1) & distinct & faces_distinct))[0]
    if len(bad):
        c = bad[0]
        tok.fail(f"cell {c}: its halffaces {hf[c].tolist()} are not the four faces of one tetrahedron",
                 _entry_word(tok, first, 5, c))
    return T


# ============================================================ export dispatch

FORMATS = {".vtu": "vtu", ".mesh": "medit", ".ovm": "ovm", ".qtn": "qtn"}
MEDIT_SIDE_FILES = (".fra", ".perm")  # written beside a .mesh export


def export_field(result, path: str, fmt: str | None = None, binary: bool = True,
                 all_faces: bool = False, data: FieldExport | None = None,
                 on_edges: bool | None = None) -> list[str]:
    """Write a solved field for ParaView or a hex mesher.

    Parameters
    ----------
    result : solver.Result, or a FieldData
    path : output file; its extension picks the format unless ``fmt`` is given
    fmt : 'vtu', 'medit' (writes path.mesh + .fra + .perm), 'ovm' or 'qtn'
    binary : VTU only, base64 inline data instead of ASCII
    all_faces : .perm only, list identity matchings too
    data : ``field_export(result)`` or ``edge_field_export(result)`` if
        already computed (the one this call would make: see on_edges)
    on_edges : write the field on its tet mesh split so that the curves run
        along tet edges (``edge_field_export``), for hex meshers; default:
        yes for 'medit', 'ovm' and 'qtn' when result is a Result (or a
        HexInput), no for 'vtu' (which shows the field as solved, with its
        vertex frames and measures) and for a FieldData (no network)

    Returns
    -------
    list of str
        The files written.

    Raises
    ------
    OutputError
        An unknown format or extension, or a path that cannot be written
        (checked before any work, ``atomic.check_output_path``), or a write
        that fails: every file is written whole or not at all, MEDIT's three
        together (``atomic.write_files``).

    What is written (tet order = ``result.mesh.tets`` everywhere, so a ``.qtn``
    matches the ``.ovm``/``.mesh``/``.vtu`` of the same result):

    * vtu: ``vtu_field_data``;
    * medit: ``.mesh`` with Vertices (ref 0), the outward boundary Triangles
      (ref 1) and Tetrahedra (ref = 1 + index of the curve crossing the tet,
      0 elsewhere: the tets a mesher may want to skip), ``.fra`` with the tet
      frames, ``.perm`` with the omega-derived face matchings (module docs);
    * ovm: topology as in ``write_ovm`` with properties VProp vec4d
      ``vertex_frame_wxyz``, CProp vec4d ``cell_frame_wxyz`` (both unit
      quaternions w, x, y, z), CProp vec3d ``cell_axis0..2``, CProp int
      ``curve`` (-1 or the crossing curve), FProp int ``matching`` (the
      CUBE_GROUP index g of the face from face_tets[f, 0] to face_tets[f, 1],
      0 on the boundary);
    * qtn: the tet quaternions w, x, y, z.
    """
    from .. import checks
    from ..errors import OptionsError
    from ..hexmesh import HexInput
    from ..pipeline import Result

    checks.instance("export_field: result", result, (Result, HexInput, FieldData), OptionsError,
                    "the Result of solve(...), a stored field (io.load_hex_input) or a FieldData")
    binary = checks.boolean("binary", binary, OptionsError)
    all_faces = checks.boolean("all_faces", all_faces, OptionsError)
    if on_edges is not None:
        on_edges = checks.boolean("on_edges", on_edges, OptionsError)
    if fmt is None:
        ext = os.path.splitext(os.fspath(path))[1].lower() if isinstance(path, (str, os.PathLike)) else ""
        if ext not in FORMATS:
            check_output_path(path, "export", FORMATS)  # refuses, naming the extension
        fmt = FORMATS[ext]
    elif fmt not in FORMATS.values():
        raise OutputError(f"export {path}: unknown format {fmt!r}; choose one of {', '.join(FORMATS.values())}")
    if fmt == "medit":
        path = os.path.splitext(path)[0] + ".mesh"
    check_output_path(path, "export", suffix_files=MEDIT_SIDE_FILES if fmt == "medit" else ())
    if on_edges is None:
        on_edges = fmt != "vtu" and not isinstance(result, FieldData)
    if data is not None:
        fe = data
    elif on_edges:
        fe = edge_field_export(result)
    else:
        fe = field_export(result)
    mesh = fe.mesh
    if fmt == "vtu":
        pd, cd = vtu_field_data(fe)
        write_vtu(path, mesh.vertices, mesh.tets, pd, cd, binary)
        return [path]
    if fmt == "qtn":
        write_qtn(path, fe.tet_quaternions)
        return [path]
    if fmt == "ovm":
        g = np.zeros(mesh.n_faces, np.int64)
        g[fe.matchings.faces] = fe.matchings.symmetry
        cell = {"cell_frame_wxyz": fe.tet_quaternions, "curve": fe.curve}
        cell.update({f"cell_axis{k}": fe.tet.frames[:, :, k] for k in range(3)})
        write_ovm(path, mesh, vertex_props={"vertex_frame_wxyz": fe.vertex_quaternions},
                  face_props={"matching": g}, cell_props=cell)
        return [path]
    stem = os.path.splitext(path)[0]
    fm = fe.matchings
    # the three files go together: all are written or none
    return write_files({
        stem + ".mesh": medit_text(mesh.vertices, mesh.tets, boundary_triangles(mesh), tet_refs=fe.curve + 1,
                                   triangle_refs=1),
        stem + ".fra": fra_text(fe.tet.frames),
        stem + ".perm": perm_text(mesh.n_tets, fm.tets, signed_permutation(fm.symmetry), keep_identity=all_faces),
    }, f"export {path}")
