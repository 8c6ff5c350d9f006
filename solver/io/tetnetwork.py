"""A singularity network read from a tet mesh whose edges carry an integer tag.

Field tools (libSCOF, AlgoHex and kin, design notes §5) export a singular
curve as a chain of tet-mesh edges with an integer per-edge index.  This module
turns such a file into the solver's input: the boundary of the tet mesh as the
domain surface, the tagged interior edges chained into ``Curve``s and the tagged
boundary edges as sharp edges.

Tag conventions (``sign``)
--------------------------
SymFrames' index σ is in turns, σ = +1/4 being the valence-3 edge of a hex mesh
(README, network.py).  A tag t != 0 on an edge means:

* ``sign=+1`` (default): t quarter turns in SymFrames' sign, σ = t / 4
  (t = +1 valence 3, t = -1 valence 5);
* ``sign=-1``: t quarter turns counted the other way, σ = -t / 4, as tools
  that give the valence-3 edge the index -1;
* ``sign="valence"``: t is the number of hexahedra around the edge,
  σ = (4 - t) / 4 (3 -> +1/4, 5 -> -1/4); t = 4 and t = 0 mean untagged.

Chains are taken as they come (zig-zag, short segments): they are broken at
vertices where the tagged interior edges do not continue as one chain (a vertex
with other than two of them, or two with different σ) and at the boundary;
chains without such a vertex are closed loops.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import NetworkError
from ..mesh.tetmesh import TetMesh
from ..network.network import Curve, Network


@dataclass
class TaggedTetMesh:
    """A tet mesh with an integer tag on some of its edges.

    vertices : (n, 3) float array
    tets     : (m, 4) int array
    edges    : (k, 2) int array, the tagged vertex pairs (any order)
    tags     : (k,) int array, nonzero
    """

    vertices: np.ndarray
    tets: np.ndarray
    edges: np.ndarray
    tags: np.ndarray


def read_tagged_tet_mesh(path: str, edge_property: str | None = None) -> TaggedTetMesh:
    """Read a tet mesh with per-edge integer tags.

    path : ``.ovm`` (OpenVolumeMesh ASCII; the tags are an integer edge
        property: ``edge_property`` by name, else the only integer/bool edge
        property, else the first one with a nonzero value) or ``.mesh`` (MEDIT;
        the tags are the reference numbers of the ``Edges`` section, 0 meaning
        untagged).
    """
    ext = os.path.splitext(path)[1].lower()
    if ext == ".ovm":
        from .interchange import read_ovm

        d = read_ovm(path)
        eprops = {k: v for k, v in d.props["edge"].items() if v.ndim == 1 and v.dtype.kind in "biu"}
        if edge_property is not None:
            if edge_property not in d.props["edge"]:
                raise NetworkError(f"{path}: no edge property {edge_property!r}; it has "
                                   f"{sorted(d.props['edge']) or 'none'}")
            tags = np.asarray(d.props["edge"][edge_property])
            if tags.ndim != 1 or tags.dtype.kind not in "biuf" or np.any(tags != np.round(tags)):
                raise NetworkError(f"{path}: edge property {edge_property!r} is not an integer per edge")
        elif len(eprops) == 1:
            tags = next(iter(eprops.values()))
        else:
            used = [k for k, v in eprops.items() if np.any(v != 0)]
            if not used:
                raise NetworkError(f"{path}: no integer edge property with a nonzero value (found "
                                   f"{sorted(d.props['edge']) or 'no edge properties'}); pass edge_property=")
            tags = eprops[used[0]]
        tags = np.asarray(tags).astype(np.int64)
        on = tags != 0
        return TaggedTetMesh(d.vertices, d.tets, d.edges[on], tags[on])
    if ext == ".mesh":
        V, T, E, ref = _read_medit(path)
        on = ref != 0
        return TaggedTetMesh(V, T, E[on], ref[on])
    raise NetworkError(f"cannot read a tagged tet mesh from {path!r}: use .ovm (OpenVolumeMesh ASCII) or .mesh "
                       "(MEDIT)")


def _read_medit(path: str):
    """(vertices, tets, edges, edge refs) of a MEDIT ASCII file; sections other
    than Vertices, Edges and Tetrahedra are skipped by their count."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        tok = []
        for line in fh:
            line = line.split("#", 1)[0].split()
            tok.extend(line)
    width = {"vertices": 4, "edges": 3, "triangles": 4, "tetrahedra": 5, "quadrilaterals": 5, "hexahedra": 9,
             "corners": 1, "ridges": 1, "requiredvertices": 1, "requirededges": 1, "requiredtriangles": 1,
             "normals": 3, "tangents": 3, "normalatvertices": 2, "tangentatedges": 2}
    out = {}
    i = 0
    while i < len(tok):
        key = tok[i].lower()
        i += 1
        if key == "end":
            break
        if key == "meshversionformatted" or key == "dimension":
            i += 1
            continue
        if key not in width:
            raise NetworkError(f"{path}: unknown MEDIT section {tok[i - 1]!r}")
        n = int(tok[i])
        w = width[key]
        out[key] = np.asarray(tok[i + 1:i + 1 + n * w], dtype=float).reshape(n, w)
        i += 1 + n * w
    if "vertices" not in out or "tetrahedra" not in out:
        raise NetworkError(f"{path}: a MEDIT tet mesh needs Vertices and Tetrahedra")
    V = out["vertices"][:, :3]
    T = out["tetrahedra"][:, :4].astype(np.int64) - 1
    Ed = out.get("edges", np.zeros((0, 3)))
    return V, T, Ed[:, :2].astype(np.int64) - 1, Ed[:, 2].astype(np.int64)


def tag_sigma(tags: np.ndarray, sign=1) -> np.ndarray:
    """σ in turns of integer edge tags under the convention ``sign`` (module docs);
    0 where the tag means untagged."""
    t = np.asarray(tags, dtype=float)
    if isinstance(sign, str):
        if sign != "valence":
            raise ValueError(f"sign must be +1, -1 or 'valence', got {sign!r}")
        return np.where(t == 0, 0.0, (4.0 - t) / 4.0)
    if sign not in (1, -1):
        raise ValueError(f"sign must be +1, -1 or 'valence', got {sign!r}")
    return sign * t / 4.0


@dataclass
class TaggedNetwork:
    """The pieces of ``network_from_tagged_edges``.

    mesh        : the TetMesh (positively oriented)
    V, F        : the boundary surface, compacted vertex ids, outward
    network     : Network
    surface_ids : (len(V),) tet-mesh vertex id of each surface vertex
    chains      : per curve, the tet-mesh vertex ids along it
    """

    mesh: TetMesh
    V: np.ndarray
    F: np.ndarray
    network: Network
    surface_ids: np.ndarray
    chains: list


def network_from_tagged_edges(tagged: TaggedTetMesh, sign=1, sharp_angle: float | None = None) -> TaggedNetwork:
    """Curves and sharp edges from the tagged edges of a tet mesh (module docs).

    Raises NetworkError naming the culprit when a tagged pair is not an edge
    of the mesh or a tag is not a multiple of a quarter turn.
    """
    mesh = TetMesh(tagged.vertices, tagged.tets)
    E = np.asarray(tagged.edges, np.int64).reshape(-1, 2)
    sig = tag_sigma(tagged.tags, sign)
    on = sig != 0
    E, sig = E[on], sig[on]
    eid = mesh.edge_index(E[:, 0], E[:, 1])
    if np.any(eid < 0):
        a, b = E[np.argmax(eid < 0)]
        raise NetworkError(f"tagged vertex pair ({a}, {b}) is not an edge of the tet mesh")
    eid, first = np.unique(eid, return_index=True)
    sig = sig[first]
    bnd = mesh.is_boundary_edge[eid]
    B = mesh.boundary
    bv = mesh.boundary_vertices
    sharp = np.searchsorted(bv, mesh.edges[eid[bnd]]) if np.any(bnd) else None
    ie, isig = mesh.edges[eid[~bnd]], sig[~bnd]
    chains, chain_sigma = chain_edges(ie, isig, mesh.is_boundary_vertex)
    curves = []
    for k, (ch, s) in enumerate(zip(chains, chain_sigma)):
        closed = len(ch) > 2 and ch[0] == ch[-1]
        curves.append(Curve(mesh.vertices[ch], sigma=s, role="singular", name=f"tagged {k} (sigma {s:+g})",
                            closed=closed))
    net = Network(curves=curves, sharp_edges=sharp, sharp_angle=sharp_angle)
    return TaggedNetwork(mesh, B.V, B.F, net, bv, chains)


def chain_edges(edges: np.ndarray, sigma: np.ndarray, stop: np.ndarray) -> tuple[list, list]:
    """Chain edges into vertex sequences.

    Parameters
    ----------
    edges : (k, 2) int array of vertex pairs
    sigma : (k,) float array; chains only continue between edges of equal sigma
    stop : (#V,) bool array, vertices where every chain ends (the boundary)

    Returns
    -------
    (chains, sigmas): per chain its vertex ids in order (closed loops repeat
    the first vertex at the end) and its sigma.

    Two edges belong to one chain when they share a vertex that is not a stop
    vertex, has exactly two of the edges and the same sigma on both.
    """
    edges = np.asarray(edges, np.int64).reshape(-1, 2)
    k = len(edges)
    if k == 0:
        return [], []
    nV = len(stop)
    inc_v = edges.reshape(-1)
    inc_e = np.repeat(np.arange(k), 2)
    deg = np.bincount(inc_v, minlength=nV)
    order = np.argsort(inc_v, kind="stable")
    v_sorted, e_sorted = inc_v[order], inc_e[order]
    start = np.searchsorted(v_sorted, np.arange(nV))
    # vertices of degree 2 with the same sigma on both edges continue a chain
    cand = np.nonzero((deg == 2) & ~np.asarray(stop, bool))[0]
    e1, e2 = e_sorted[start[cand]], e_sorted[start[cand] + 1]
    ok = sigma[e1] == sigma[e2]
    joint = np.zeros(nV, bool)
    joint[cand[ok]] = True
    A = sp.coo_matrix((np.ones(ok.sum()), (e1[ok], e2[ok])), shape=(k, k))
    ncomp, lab = connected_components(A, directed=False)
    chains, sigmas = [], []
    for c in range(ncomp):
        ce = np.nonzero(lab == c)[0]
        verts = edges[ce].reshape(-1)
        ends = np.unique(verts[~joint[verts]])
        # open chains start at an end; a loop (no end) at any vertex
        v = int(ends[0]) if len(ends) else int(edges[ce[0], 0])
        seq = [v]
        used = set()
        e = None
        while True:
            nxt = [x for x in e_sorted[start[v]:start[v] + deg[v]] if lab[x] == c and x not in used]
            if not nxt or (len(seq) > 1 and not joint[v]):
                break
            e = int(nxt[0])
            used.add(e)
            a, b = edges[e]
            v = int(b if a == v else a)
            seq.append(v)
        chains.append(np.asarray(seq, np.int64))
        sigmas.append(float(sigma[ce[0]]))
    return chains, sigmas


def read_tet_network(path: str, sign=1, edge_property: str | None = None,
                     sharp_angle: float | None = None) -> tuple[np.ndarray, np.ndarray, Network]:
    """(V, F, Network) from a tet mesh with an integer tag per edge.

    Parameters
    ----------
    path : ``.ovm`` (OpenVolumeMesh ASCII, the tag an integer edge property) or
        ``.mesh`` (MEDIT, the tag the reference number of an ``Edges`` entry)
    sign : +1, -1 or ``"valence"``: how a tag becomes σ (module docs); +1 reads
        t as quarter turns with σ = +1/4 the valence-3 edge
    edge_property : OVM only, the name of the edge property holding the tags
    sharp_angle : passed to the Network (dihedral threshold for sharp edges
        besides the tagged boundary edges)

    Returns
    -------
    V : (n, 3) float array, F : (m, 3) int array
        The boundary of the tet mesh, outward, on compacted vertex ids.
    Network
        One singular Curve per chain of tagged interior edges (module docs),
        the tagged boundary edges as ``sharp_edges`` (surface vertex ids).
    """
    tn = network_from_tagged_edges(read_tagged_tet_mesh(path, edge_property), sign, sharp_angle)
    return tn.V, tn.F, tn.network
