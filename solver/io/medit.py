"""MEDIT ASCII meshes (.mesh): written for hex meshers and FE codes, read back for a network.

``medit_text`` / ``write_medit`` write vertices, edges, triangles,
quadrilaterals, tetrahedra and hexahedra, 1-based, each entry closed by its
reference number: a solved field's tet mesh with its outward boundary
triangles (``boundary_triangles``; interchange.py), which CubeCover
(Nieser et al. 2011) reads with the ``.fra`` tet frames and ``.perm`` face
matchings beside it (cubecover.py), and a hex mesh with its boundary quads
(hexformats.py).  ``read_medit`` reads a tet mesh with tagged edges,
checking everything it reads (tetnetwork.py); meshio reads the files back
in the tests too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import NetworkError
from ..mesh.tetmesh import TetMesh
from .atomic import write_text
from .text import Tokens, format_rows


def write_medit(path: str, vertices: np.ndarray, tets: np.ndarray | None, triangles: np.ndarray | None = None,
                edges: np.ndarray | None = None, tet_refs=None, triangle_refs=None, edge_refs=None,
                vertex_refs=None, quads: np.ndarray | None = None, quad_refs=None, hexes: np.ndarray | None = None,
                hex_refs=None) -> None:
    """Write a MEDIT ASCII mesh (.mesh); the text is ``medit_text``'s (same
    parameters)."""
    write_text(path, medit_text(vertices, tets, triangles, edges, tet_refs, triangle_refs, edge_refs, vertex_refs,
                                quads, quad_refs, hexes, hex_refs))


def medit_text(vertices: np.ndarray, tets: np.ndarray | None, triangles: np.ndarray | None = None,
               edges: np.ndarray | None = None, tet_refs=None, triangle_refs=None, edge_refs=None,
               vertex_refs=None, quads: np.ndarray | None = None, quad_refs=None, hexes: np.ndarray | None = None,
               hex_refs=None) -> str:
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
        Quadrilaterals       (if given)
        k
        i j k l ref
        Tetrahedra           (if given)
        m
        i j k l ref
        Hexahedra            (if given; VTK's corner order, which MEDIT shares)
        m
        i j k l m n o p ref
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
           format_rows(np.c_[V, refs(vertex_refs, len(V))], "%.17g")]
    for name, X, r in (("Edges", edges, edge_refs), ("Triangles", triangles, triangle_refs),
                       ("Quadrilaterals", quads, quad_refs), ("Tetrahedra", tets, tet_refs),
                       ("Hexahedra", hexes, hex_refs)):
        if X is None:
            continue
        X = np.asarray(X, np.int64)
        out.append(f"{name}\n{len(X)}\n")
        out.append(format_rows(np.c_[X + 1, refs(r, len(X))], "%d"))
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
    tok = Tokens.of_file(path, error, "MEDIT mesh")
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

