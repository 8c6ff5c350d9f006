"""A solved field exported for ParaView and hex meshers: what is written, and in which files.

``export_field(field, path)`` picks the format from the extension; each
format's writer is in its own module:

``.vtu``   VTK XML UnstructuredGrid (ParaView, meshio; vtu.py): tets, vertex
           frames, tet frames, singular-tet markers and per-tet error measures
           (``vtu_field_data``).
``.mesh``  MEDIT mesh (medit.py) + ``.fra`` tet frames + ``.perm`` face
           matchings next to it (cubecover.py): the three files CubeCover
           (Nieser et al. 2011) reads.
``.ovm``   OpenVolumeMesh ASCII with per-cell and per-vertex frame properties
           (AlgoHex, HexHex and OVM tools read it; ovm.py).
``.qtn``   one quaternion per tet in cell order (AlgoHex
           ``--cell-quaternion-in-path``; qtn.py).

What they carry is computed once per field (``field_export``, a
``FieldExport``): the field's tet frames and face matchings
(field/matchings.py, paper §5.5) and per-tet measures, on the field's own
tet mesh or on its split along the curves (``edge_field_export``), which
hex meshers need.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from ..analysis.measures import matched_singular_faces, monodromy_angles, omega_singular_faces
from ..errors import OutputError
from ..field.matchings import FaceMatchings, TetFrames, face_matchings, omega_tet_frames
from ..mesh.tetmesh import TetMesh
from .atomic import check_output_path, write_files
from .cubecover import fra_text, perm_text, signed_permutation
from .medit import boundary_triangles, medit_text
from .ovm import write_ovm
from .qtn import write_qtn
from .vtu import write_vtu

# ============================================================ per-tet measures


@dataclass
class FieldExport:
    """Everything the writers need of a solved field, computed once.

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


def field_export(field) -> FieldExport:
    """Tet frames, face matchings, markers and per-tet measures of a solved
    field (a SolvedField, or a Result: its ``.field``).

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
    from ..field.solved import as_field

    fd = as_field(field, "field_export")
    mesh = fd.mesh
    tf = omega_tet_frames(mesh, fd.omega, fd.frames)
    fm = face_matchings(mesh, tf)
    mono = np.degrees(monodromy_angles(mesh, fd.omega, None, fd.embedding.face_omega))
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


def edge_field_export(field) -> FieldExport:
    """The FieldExport of a solved field (or a Result) on its tet mesh split
    so that every curve runs along tet edges (hexmesh.field_on_edges): the
    per-tet field's singular edges are then the curves' chains, not
    staircases of tet edges around them, which is what CubeCover's and
    AlgoHex's parametrisations need.  Raises HexMeshError where that is not
    possible."""
    from ..hexmesh import field_on_edges

    ef = field_on_edges(field)
    nT = ef.mesh.n_tets
    tf = TetFrames(ef.tet_frames, np.zeros((nT, 4), np.int64), np.zeros(nT))
    fm = FaceMatchings(ef.faces, ef.tets, ef.transition, np.ones(len(ef.faces), bool), ef.transition)
    return FieldExport(ef.mesh, ef.vertex_frames, tf, fm, ef.curve, np.zeros(nT, bool), {})


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


# ============================================================ export dispatch

FORMATS = {".vtu": "vtu", ".mesh": "medit", ".ovm": "ovm", ".qtn": "qtn"}
MEDIT_SIDE_FILES = (".fra", ".perm")  # written beside a .mesh export


def export_field(field, path: str, fmt: str | None = None, binary: bool = True,
                 all_faces: bool = False, data: FieldExport | None = None,
                 on_edges: bool | None = None) -> list[str]:
    """Write a solved field for ParaView or a hex mesher.

    Parameters
    ----------
    field : SolvedField (``Result.field``, ``io.load_field(path)``), or a
        solver Result
    path : output file; its extension picks the format unless ``fmt`` is given
    fmt : 'vtu', 'medit' (writes path.mesh + .fra + .perm), 'ovm' or 'qtn'
    binary : VTU only, base64 inline data instead of ASCII
    all_faces : .perm only, list identity matchings too
    data : ``field_export(field)`` or ``edge_field_export(field)`` if
        already computed (the one this call would make: see on_edges)
    on_edges : write the field on its tet mesh split so that the curves run
        along tet edges (``edge_field_export``), for hex meshers; default:
        yes for 'medit', 'ovm' and 'qtn', no for 'vtu' (which shows the
        field as solved, with its vertex frames and measures)

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

    What is written (tet order = ``field.mesh.tets`` everywhere, so a ``.qtn``
    matches the ``.ovm``/``.mesh``/``.vtu`` of the same field):

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
    from ..field.solved import as_field

    field = as_field(field, "export_field")
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
        on_edges = fmt != "vtu"
    if data is not None:
        fe = data
    elif on_edges:
        fe = edge_field_export(field)
    else:
        fe = field_export(field)
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
