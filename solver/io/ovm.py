"""OpenVolumeMesh ASCII (.ovm): tet and hex meshes with per-entity properties.

``write_ovm`` writes a TetMesh as vertices, edges, faces of halfedges and
cells of halffaces (``ovm_halffaces``: OpenVolumeMesh's conventions), then
properties per vertex, edge, face or cell; an ``.ovm`` export
(interchange.py) carries the vertex and cell frames as quaternions, the
crossing curve per cell and the matching per face (AlgoHex, HexHex and the
OVM tools read it).  ``read_ovm`` reads a tet mesh with its numeric
properties back (a network on tagged edges: tetnetwork.py), checking
everything it reads.

``write_hex_ovm`` writes a hex mesh the same way (``hex_ovm_topology``:
quad faces, six halffaces per cell in the order of OpenVolumeMesh's
HexahedralMeshTopologyKernel), with the boundary patch of each face and
the hexahedra around each edge as properties; ``read_hex_ovm`` reads one
back.  Both kinds share the text (``_ovm_text``) and the checks of the
reader (``_read_ovm``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import NetworkError, ReadError
from ..mesh.tetmesh import TetMesh
from .atomic import write_text
from .text import Tokens, format_rows

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
    write_text(path, _ovm_text(mesh.vertices, mesh.edges, he, hf, {"vertex": vertex_props, "edge": edge_props,
                                                                   "face": face_props, "cell": cell_props}))


def _ovm_text(vertices: np.ndarray, edges: np.ndarray, face_halfedges: np.ndarray, cell_halffaces: np.ndarray,
              props: dict) -> str:
    """The text of an OpenVolumeMesh ASCII file (``write_ovm``): the four
    sections, each face and cell led by its valence (the width of its row),
    then the properties, props = {'vertex'|'edge'|'face'|'cell': {name:
    array} or None}."""
    nV, nE, nF, nC = len(vertices), len(edges), len(face_halfedges), len(cell_halffaces)
    out = ["OVM ASCII\n", f"Vertices\n{nV}\n", format_rows(vertices, "%.17g"),
           f"Edges\n{nE}\n", format_rows(edges, "%d"),
           f"Faces\n{nF}\n", format_rows(np.c_[np.full(nF, face_halfedges.shape[1]), face_halfedges], "%d"),
           f"Polyhedra\n{nC}\n", format_rows(np.c_[np.full(nC, cell_halffaces.shape[1]), cell_halffaces], "%d")]
    sizes = {"vertex": nV, "edge": nE, "face": nF, "cell": nC}
    for ent in ("vertex", "edge", "face", "cell"):
        for name, a in (props.get(ent) or {}).items():
            a = np.asarray(a)
            if len(a) != sizes[ent]:
                raise ValueError(f"{ent} property {name!r} has {len(a)} values for {sizes[ent]} {ent}s")
            if '"' in name:
                raise ValueError(f"property name {name!r} must not contain a double quote")
            t = _ovm_type(a)
            out.append(f'{_OVM_ENTITIES[ent]} {t} "{name}"\n')
            out.append(format_rows(a.astype(np.int64) if a.dtype.kind == "b" else a,
                                 "%.17g" if a.dtype.kind == "f" else "%d"))
    return "".join(out)


OVM_HEX_FACES = np.array([0, 1, 4, 2, 5, 3])
"""The local faces (``quality.HEX_FACES``) of a VTK hexahedron in the order
OpenVolumeMesh lists a hexahedron's halffaces: XF, XB, YF, YB, ZF, ZB
(``HexahedralMeshTopologyKernel::add_cell`` from its vertices 0..7, which
are VTK's 0, 3, 2, 1, 4, 5, 6, 7; ``check_halfface_ordering`` accepts this
order as it is)."""


@dataclass
class HexOVMTopology:
    """OpenVolumeMesh connectivity of a hex mesh (``hex_ovm_topology``).

    edges : (#E, 2) vertex pairs i < j, halfedge 2e from i to j, 2e + 1 back;
    face_halfedges : (#F, 4) each face's loop as the first cell holding it
    sees it from inside (outward from that cell), halfface 2f that loop and
    2f + 1 the opposite; cell_halffaces : (#H, 6) the halffaces of each cell
    in the order ``OVM_HEX_FACES``, normals into the cell; cell_faces :
    (#H, 6) the face of each local face (``quality.HEX_FACES`` order);
    edge_cells : (#E,) the hexahedra around each edge.
    """

    edges: np.ndarray
    face_halfedges: np.ndarray
    cell_halffaces: np.ndarray
    cell_faces: np.ndarray
    edge_cells: np.ndarray


def hex_ovm_topology(hexes: np.ndarray) -> HexOVMTopology:
    """Edges, quad faces of halfedges and cells of six halffaces of a hex
    mesh (VTK_HEXAHEDRON corner order), under OpenVolumeMesh's conventions
    (``HexOVMTopology``).  A cell's halfface is chosen combinatorially: the
    cell's outward loop (``quality.HEX_FACES``) runs the same way as its
    face's loop for halfface 2f, so 2f + 1 is the one into the cell, and the
    other way for 2f."""
    from ..hexmesh.quality import HEX_EDGES, HEX_FACES
    from ..surface.trisurface import unique_rows

    H = np.asarray(hexes, np.int64).reshape(-1, 8)
    m = len(H)
    Fq = H[:, HEX_FACES].reshape(-1, 4)  # outward loops, six per cell
    if not m:
        z = np.zeros((0, 2), np.int64)
        return HexOVMTopology(z, np.zeros((0, 4), np.int64), np.zeros((0, 6), np.int64),
                              np.zeros((0, 6), np.int64), np.zeros(0, np.int64))
    _, inv, _ = unique_rows(np.sort(Fq, axis=1))
    first = np.empty(inv.max() + 1, np.int64)
    first[inv[::-1]] = np.arange(len(inv))[::-1]  # each face's first listing
    loops = Fq[first]
    pairs = np.stack([loops, np.roll(loops, -1, axis=1)], axis=2).reshape(-1, 2)
    E, einv, _ = unique_rows(np.sort(pairs, axis=1))
    he = (2 * einv.reshape(-1) + (pairs[:, 0] > pairs[:, 1])).reshape(-1, 4)
    listed = loops[inv]  # each cell face's loop as listed
    start = np.argmax(Fq == listed[:, :1], axis=1)  # where the listed loop starts in the cell's loop
    same_way = Fq[np.arange(len(Fq)), (start + 1) % 4] == listed[:, 1]
    hf = (2 * inv + same_way).reshape(m, 6)[:, OVM_HEX_FACES]
    n = int(H.max()) + 1
    key = E[:, 0] * n + E[:, 1]
    CE = np.sort(H[:, HEX_EDGES].reshape(-1, 2), axis=1)
    cells = np.bincount(np.searchsorted(key, CE[:, 0] * n + CE[:, 1]), minlength=len(E))
    return HexOVMTopology(E, he, hf, inv.reshape(m, 6), cells)


def write_hex_ovm(path: str, vertices: np.ndarray, hexes: np.ndarray, patches=None,
                  scaled_jacobian: np.ndarray | None = None) -> None:
    """Write a hex mesh as OpenVolumeMesh ASCII (.ovm), as ``write_ovm``
    writes tets: quad faces of 4 halfedges, cells of 6 halffaces in the
    order XF, XB, YF, YB, ZF, ZB with normals into the cell
    (``hex_ovm_topology``), so that OpenVolumeMesh's ``HexahedralMesh``
    reads them as they are, then the properties ``EProp int "valence"``
    (the hexahedra around each edge: 4 inside and 2 on the boundary where
    the mesh is regular), ``FProp int "patch"`` (the boundary patch of each
    face, ``patches.patch``; 0 inside) and ``CProp double
    "scaled_jacobian"``, where given.

    vertices : (n, 3); hexes : (m, 8) VTK_HEXAHEDRON order; patches : a
    hexmesh.patches.BoundaryPatches or None; scaled_jacobian : (m,) or None.
    """
    V = np.asarray(vertices, float)
    t = hex_ovm_topology(hexes)
    face_props = {}
    if patches is not None:
        patch = np.zeros(len(t.face_halfedges), np.int64)
        patch[t.cell_faces[patches.cells, patches.faces]] = patches.patch
        face_props["patch"] = patch
    cell_props = {} if scaled_jacobian is None else {"scaled_jacobian": np.asarray(scaled_jacobian, float)}
    write_text(path, _ovm_text(V, t.edges, t.face_halfedges, t.cell_halffaces,
                               {"edge": {"valence": t.edge_cells}, "face": face_props, "cell": cell_props}))


@dataclass
class OVMData:
    """An OpenVolumeMesh ASCII file: tets or hexahedra rebuilt from the halffaces.

    vertices : (n, 3), edges : (#E, 2), face_halfedges : (#F, 3) (tets) or
    (#F, 4) (hexahedra), cell_halffaces : (#C, 4) or (#C, 6), tets : (#C, 4)
    vertex quadruples oriented like the file (the first halfface's loop,
    then the remaining vertex: positive when halfface normals point into the
    cells; (0, 4) for a hex mesh), props : {entity: {name: array}} with
    entity in vertex, edge, halfedge, face, halfface, cell, mesh; hexes :
    (#C, 8) for a hex mesh (``read_hex_ovm``), VTK_HEXAHEDRON corner order
    oriented like the file (the first halfface's loop, then the corners
    across from it: positive when halfface normals point into the cells).
    """

    vertices: np.ndarray
    edges: np.ndarray
    face_halfedges: np.ndarray
    cell_halffaces: np.ndarray
    tets: np.ndarray
    props: dict
    props_line: dict = field(default_factory=dict)
    hexes: np.ndarray = field(default_factory=lambda: np.zeros((0, 8), np.int64))


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
    return _read_ovm(path, error, "tet")


def read_hex_ovm(path: str, *, error=ReadError) -> OVMData:
    """Read an OpenVolumeMesh ASCII hex mesh with its properties (format in
    ``write_hex_ovm``), checking everything it reads, as ``read_ovm`` does a
    tet mesh: faces are quads of halfedges that close a loop, and each cell
    is six halffaces that are the six faces of one hexahedron, each used
    once, all facing the same way (into the cell or out of it).

    Parameters
    ----------
    path : str
    error : type
        the exception raised for a file that is not such a mesh

    Returns
    -------
    OVMData
        ``hexes`` (#C, 8) in VTK_HEXAHEDRON corner order, oriented like the
        file (positive when the halffaces point into the cells, as
        OpenVolumeMesh's do), ``tets`` empty; the properties by entity

    Raises
    ------
    ReadError
        (or ``error``) naming the file, the line and the value
    """
    return _read_ovm(path, error, "hex")


_OVM_KINDS = {"tet": (3, 4, "tetrahedral"), "hex": (4, 6, "hexahedral")}


def _read_ovm(path: str, error, kind: str) -> OVMData:
    """``read_ovm`` (kind 'tet') and ``read_hex_ovm`` (kind 'hex')."""
    face_valence, cell_valence, adjective = _OVM_KINDS[kind]
    tok = Tokens.of_file(path, error, "OpenVolumeMesh file")
    if not tok.done and tok.words[0].upper() == "OVM":
        tok.next("OVM")
        kind_ = tok.next("ASCII").upper() if not tok.done else "ASCII"
        if kind_ == "BINARY":
            tok.fail("binary OVM is not supported; save it as OVM ASCII", 1)
        if kind_ != "ASCII":
            tok.fail(f"'OVM {kind_}': expected 'OVM ASCII'", 1)

    def refuse_valence(what, k, got, valence, sub, word):
        tok.fail(f"{what} {k} has {got} {sub}; only {adjective} meshes are supported ({what}s of {valence} {sub})",
                 word)

    def section(name, width, kind, what=None, sub=None):
        i = tok.pos
        word = tok.next(f"the {name} section")
        if word.upper() != name.upper():
            tok.fail(f"{word!r} where the {name} section was expected (sections: Vertices, Edges, Faces, "
                     "Polyhedra, in this order)", i)
        if what is not None and tok.pos + 1 < len(tok):  # the first entry's valence, before its width is assumed
            count, got = tok.words[tok.pos], tok.words[tok.pos + 1]
            if count.isdigit() and int(count) > 0 and got.isdigit() and int(got) != width - 1:
                refuse_valence(what, 0, int(got), width - 1, sub, tok.pos + 1)
        n = tok.count(name.lower(), width)
        return tok.block(n, width, f"{name} section", kind), i

    V, _ = section("Vertices", 3, "float")
    E, _ = section("Edges", 2, "int")
    Fh, f0 = section("Faces", face_valence + 1, "int", "face", "halfedges")
    Ch, c0 = section("Polyhedra", cell_valence + 1, "int", "cell", "halffaces")
    nV, nE, nF = len(V), len(E), len(Fh)
    _entries_in_range(tok, E, 0, nV, 0, "edge", "vertex", f"0..{nV - 1}")
    for X, first, what, valence, sub in ((Fh, f0, "face", face_valence, "halfedges"),
                                         (Ch, c0, "cell", cell_valence, "halffaces")):
        bad = np.nonzero(X[:, 0] != valence)[0]
        if len(bad):
            refuse_valence(what, bad[0], X[bad[0], 0], valence, sub, _entry_word(tok, first, X.shape[1], bad[0]))
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
                 "before it ends)", _entry_word(tok, f0, face_valence + 1, f))
    if kind == "tet":
        T, hexes = _ovm_tets(tok, loop, hf, c0), np.zeros((0, 8), np.int64)
    else:
        T, hexes = np.zeros((0, 4), np.int64), _ovm_hexes(tok, loop, hf, c0)
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
    return OVMData(V, E, he, hf, T, props, props_line, hexes)


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



def _ovm_hexes(tok: Tokens, loop: np.ndarray, hf: np.ndarray, first: int) -> np.ndarray:
    """Corners of the cells in VTK_HEXAHEDRON order, oriented like the file:
    the first halfface's loop (corners 0..3), then across each of its
    corners the one its cell's other faces join it to (4..7); a cell whose
    six halffaces are not the six faces of that hexahedron, all facing the
    same way, is refused."""
    from ..hexmesh.quality import HEX_FACES

    if not len(hf):
        return np.zeros((0, 8), np.int64)
    m = len(hf)
    L = loop[hf // 2]  # (#C, 6, 4)
    L = np.where((hf % 2 == 1)[:, :, None], L[:, :, ::-1], L)  # the halfface's own loop
    bottom = L[:, 0]
    P = np.stack([L, np.roll(L, -1, axis=2)], axis=3).reshape(m, 24, 2)  # directed edges of the six loops
    off = ~(P[:, :, 1:2] == bottom[:, None, :]).any(axis=2)  # edge leaving the first face
    top = np.zeros((m, 4), np.int64)
    found = np.ones(m, bool)
    for i in range(4):
        hit = (P[:, :, 0] == bottom[:, i:i + 1]) & off
        found &= hit.any(axis=1)
        top[:, i] = P[np.arange(m), np.argmax(hit, axis=1), 1]
    Hx = np.c_[bottom, top]
    S = np.sort(Hx, axis=1)
    ok = found & np.all(S[:, 1:] != S[:, :-1], axis=1)
    # the six loops must be the hexahedron's six faces, each once, all into the cell

    def canonical(A):  # each loop rotated to start at its smallest corner
        r = np.argmin(A, axis=-1)[..., None]
        return np.take_along_axis(A, (r + np.arange(4)) % 4, axis=-1)

    want = canonical(Hx[:, HEX_FACES][:, :, ::-1])
    got = canonical(L)
    eq = (want[:, :, None, :] == got[:, None, :, :]).all(axis=3)
    ok &= eq.any(axis=2).all(axis=1) & eq.any(axis=1).all(axis=1)
    bad = np.nonzero(~ok)[0]
    if len(bad):
        c = bad[0]
        tok.fail(f"cell {c}: its halffaces {hf[c].tolist()} are not the six faces of one hexahedron, each once and "
                 "all facing into the cell (or all out of it)", _entry_word(tok, first, 7, c))
    return Hx
