"""A singularity network read from a tet mesh whose edges carry an integer tag.

Field tools (libSCOF, AlgoHex and kin; docs/usage.md, *Import a network from a
tet mesh with tagged edges*) export a singular
curve as a chain of tet-mesh edges with an integer per-edge index.  This module
turns such a file into the solver's input: the boundary of the tet mesh as the
domain surface, the tagged interior edges chained into ``Curve``s and the tagged
boundary edges as sharp edges.

Tag conventions
---------------
SymFrames' index σ is in turns, σ = +1/4 being the valence-3 edge of a hex mesh
(README, network.py).  A tag t != 0 on an edge means, by convention:

* ``index``: t quarter turns in SymFrames' sign, σ = t / 4 (t = +1 valence 3,
  t = -1 valence 5);
* ``negated``: t quarter turns counted the other way, σ = -t / 4, as tools
  that give the valence-3 edge the index -1;
* ``valence``: t is the number of hexahedra around the edge, σ = (4 - t) / 4
  (3 -> +1/4, 5 -> -1/4); t = 4 and t = 0 mean untagged.

A tag must read as a σ from -1 to +3/4: an edge of a hex mesh has 1 to 8
hexahedra around it (``SIGMA_RANGE``).  Files do not say which convention
they use, and the same tags read the wrong way give a network no field has
(the sum of the indices at the ends on a boundary component no longer
matches its Euler characteristic).  So when no convention is given, each is
tried and the one under which the network satisfies Poincaré–Hopf and the
node rules (``network.topology.check_topology``) is kept; none, or more
than one, is refused with what each reading gave.  A convention that is
given but under which the network fails those rules is refused, naming the
one that fits if one does.

Chains are taken as they come (zig-zag, short segments): they are broken at
vertices where the tagged interior edges do not continue as one chain (a vertex
with other than two of them, or two with different σ) and at the boundary;
chains without such a vertex are closed loops.

Every value read is checked (medit.read_medit, ovm.read_ovm,
``check_tets``): a refusal names the file, the line and the value.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import NetworkError, SurfaceError, TopologyError
from ..mesh.tetmesh import TetMesh
from ..network.network import Curve, Network
from ..network.topology import check_topology
from ..surface.validation import validate_surface

# the conventions (module docs): name -> how sigma follows from a tag t
CONVENTIONS = {"index": "sigma = t/4", "negated": "sigma = -t/4", "valence": "sigma = (4 - t)/4"}
SIGMA_RANGE = (-1.0, 0.75)  # an edge of a hex mesh has 1..8 hexahedra around it
_SIGNS = {1: "index", -1: "negated"}  # the older sign= values


def convention_name(sign) -> str:
    """'index', 'negated' or 'valence' from a convention's name or the older
    ``sign`` (+1, -1, 'valence'); NetworkError otherwise."""
    if isinstance(sign, str) and sign in CONVENTIONS:
        return sign
    if isinstance(sign, (int, np.integer)) and not isinstance(sign, (bool, np.bool_)) and int(sign) in _SIGNS:
        return _SIGNS[int(sign)]
    raise NetworkError(f"tag convention {sign!r}: must be one of {', '.join(map(repr, CONVENTIONS))} (or None to "
                       "detect it)")


@dataclass
class TaggedTetMesh:
    """A tet mesh with an integer tag on some of its edges.

    vertices : (n, 3) float array
    tets     : (m, 4) int array
    edges    : (k, 2) int array, the tagged vertex pairs (any order)
    tags     : (k,) int array, nonzero
    path     : the file read ('' when built in memory)
    lines    : (k,) int array, the line of each tag in the file (or None)
    source   : where the tags were found, for messages
    """

    vertices: np.ndarray
    tets: np.ndarray
    edges: np.ndarray
    tags: np.ndarray
    path: str = ""
    lines: np.ndarray | None = None
    source: str = "tags"

    def where(self, k: int) -> str:
        """'path:line' of tag k, or a description of it."""
        if self.path and self.lines is not None:
            return f"{self.path}:{int(self.lines[k])}"
        return f"{self.path or self.source}: tagged edge {k}"


def read_tagged_tet_mesh(path: str, edge_property: str | None = None) -> TaggedTetMesh:
    """Read a tet mesh with per-edge integer tags, checking every value.

    path : ``.ovm`` (OpenVolumeMesh ASCII; the tags are an integer edge
        property: ``edge_property`` by name, else the only integer/bool edge
        property, else the only one with a nonzero value; several such are
        refused, naming them) or ``.mesh`` (MEDIT; the tags are the reference
        numbers of the ``Edges`` section, 0 meaning
        untagged).

    Raises NetworkError naming the file, the line and the value of anything
    it cannot read (ovm.read_ovm / medit.read_medit, ``check_tets``).
    """
    from .medit import read_medit
    from .ovm import read_ovm

    if not isinstance(path, (str, os.PathLike)):
        raise NetworkError(f"tet mesh path {path!r}: must be a file path (a string)")
    path = os.fspath(path)
    if edge_property is not None and not isinstance(edge_property, str):
        raise NetworkError(f"edge property {edge_property!r}: must be a property name (a string)")
    ext = os.path.splitext(path)[1].lower()
    if ext == ".ovm":
        d = read_ovm(path, NetworkError)
        check_tets(d.vertices, d.tets, path)
        eprops = {k: v for k, v in d.props["edge"].items() if v.ndim == 1 and v.dtype.kind in "biu"}
        if edge_property is not None:
            if edge_property not in d.props["edge"]:
                raise NetworkError(f"{path}: no edge property {edge_property!r}; it has "
                                   f"{sorted(d.props['edge']) or 'none'}")
            name = edge_property
            tags = np.asarray(d.props["edge"][name])
            if tags.ndim != 1:
                raise NetworkError(f"{path}: edge property {name!r} holds vectors, not one integer per edge")
            if tags.dtype.kind == "f":
                bad = np.nonzero(tags != np.round(tags))[0]
                if len(bad):
                    line = d.props_line["edge"][name] + bad[0]
                    raise NetworkError(f"{path}:{line}: edge property {name!r} has {tags[bad[0]]:g} on edge "
                                       f"{bad[0]}; tags must be whole numbers")
                if np.any(np.abs(tags) > 2.0**62):
                    k = int(np.argmax(np.abs(tags)))
                    raise NetworkError(f"{path}:{d.props_line['edge'][name] + k}: edge property {name!r} has "
                                       f"{tags[k]:g} on edge {k}: out of range for a tag")
        elif len(eprops) == 1:
            name = next(iter(eprops))
            tags = eprops[name]
        else:
            used = [k for k, v in eprops.items() if np.any(v != 0)]
            if not used:
                raise NetworkError(f"{path}: no integer edge property with a nonzero value (found "
                                   f"{sorted(d.props['edge']) or 'no edge properties'}); name the one holding "
                                   "the tags (--tag-property NAME, Python: edge_property=)")
            if len(used) > 1:
                counts = ", ".join(f"{k!r} ({int(np.count_nonzero(eprops[k])):,} nonzero edges)" for k in used)
                raise NetworkError(f"{path}: {len(used)} integer edge properties could hold the tags: {counts}; "
                                   "SymFrames does not guess which: name it (--tag-property NAME, Python: "
                                   f"edge_property={used[0]!r})")
            name = used[0]
            tags = eprops[name]
        tags = np.asarray(tags).astype(np.int64)
        on = np.nonzero(tags != 0)[0]
        return TaggedTetMesh(d.vertices, d.tets, d.edges[on], tags[on], path,
                             d.props_line["edge"].get(name, 0) + on, f"edge property {name!r}")
    if ext == ".mesh":
        m = read_medit(path, NetworkError)
        check_tets(m.vertices, m.tets, path, m.tet_lines)
        on = np.nonzero(m.edge_refs != 0)[0]
        return TaggedTetMesh(m.vertices, m.tets, m.edges[on], m.edge_refs[on], path, m.edge_lines[on],
                             "reference numbers of the Edges")
    raise NetworkError(f"cannot read a tagged tet mesh from {path!r}: use .ovm (OpenVolumeMesh ASCII) or .mesh "
                       "(MEDIT)")


def check_tets(V: np.ndarray, T: np.ndarray, path: str, lines: np.ndarray | None = None) -> None:
    """Refuse a tet mesh that is not one: no tets, a tet with a repeated
    vertex or no volume, a tet listed twice (it would read as a hole), a
    triangle shared by more than two tets.  Messages name the tets (and
    their lines when known)."""
    def at(k):
        return f"{path}:{int(lines[k])}" if lines is not None else f"{path}: tet {k}"

    if len(T) == 0:
        raise NetworkError(f"{path}: no tetrahedra; a tet mesh is needed")
    Ts = np.sort(T, axis=1)
    rep = np.nonzero(np.any(Ts[:, 1:] == Ts[:, :-1], axis=1))[0]
    if len(rep):
        raise NetworkError(f"{at(rep[0])}: tet {rep[0]} has a repeated vertex {T[rep[0]].tolist()}")
    _, first, inv, cnt = np.unique(Ts, axis=0, return_index=True, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    dup = np.nonzero(cnt[inv] > 1)[0]
    if len(dup):
        k = dup[np.nonzero(dup != first[inv[dup]])[0][0]]
        j = first[inv[k]]
        raise NetworkError(f"{at(k)}: tet {k} {T[k].tolist()} repeats tet {j} ({at(j)}); remove the duplicate")
    P = V[T]
    vol = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), P[:, 3] - P[:, 0])
    scale = np.max(np.linalg.norm(P - P[:, :1], axis=2), axis=1) ** 3
    flat = np.nonzero(np.abs(vol) <= 1e-14 * scale)[0]
    if len(flat):
        raise NetworkError(f"{at(flat[0])}: tet {flat[0]} {T[flat[0]].tolist()} has no volume (its four vertices "
                           "lie in one plane)")
    faces = np.sort(T[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    uf, finv, fcnt = np.unique(faces, axis=0, return_inverse=True, return_counts=True)
    if np.any(fcnt > 2):
        f = int(np.argmax(fcnt))
        owners = np.nonzero(finv.reshape(-1) == f)[0] // 4
        raise NetworkError(f"{at(owners[0])}: the triangle {uf[f].tolist()} is a face of {fcnt[f]} tets "
                           f"({', '.join(map(str, owners))}); a tet mesh shares a triangle between at most two")


def tag_sigma(tags: np.ndarray, sign=1) -> np.ndarray:
    """σ in turns of integer edge tags under a convention ('index',
    'negated', 'valence', or the older +1, -1, 'valence'); 0 where the tag
    means untagged.  The range is not checked here (``convention_sigma``)."""
    t = np.asarray(tags, dtype=float)
    name = convention_name(sign)
    if name == "valence":
        return np.where((t == 0) | (t == 4), 0.0, (4.0 - t) / 4.0)
    return (1.0 if name == "index" else -1.0) * t / 4.0


def convention_sigma(tagged: TaggedTetMesh, convention) -> np.ndarray:
    """σ of each tag under the convention, refusing (NetworkError, naming
    the file, the line and the tag) a tag outside ``SIGMA_RANGE``."""
    name = convention_name(convention)
    t = np.asarray(tagged.tags, np.int64)
    sig = tag_sigma(t, name)
    lo, hi = SIGMA_RANGE
    if name == "valence":
        bad = np.nonzero((t != 0) & (t != 4) & ((sig < lo) | (sig > hi)))[0]
        valid = "0..8, hexahedra around the edge (0 and 4: untagged)"
    else:
        bad = np.nonzero((sig < lo) | (sig > hi))[0]
        valid = "-4..3" if name == "index" else "-3..4"
        valid += f" ({CONVENTIONS[name]} from -1 to +3/4)"
    if len(bad):
        k = bad[0]
        a, b = np.asarray(tagged.edges)[k]
        raise NetworkError(f"{tagged.where(k)}: tag {t[k]} on the edge ({a}, {b}) is out of the range of the "
                           f"'{name}' convention, {valid}: an edge of a hex mesh has 1 to 8 hexahedra around it")
    return sig


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


def network_from_tagged_edges(tagged: TaggedTetMesh, sign=1, sharp_angle: float | None = None,
                              mesh: TetMesh | None = None) -> TaggedNetwork:
    """Curves and sharp edges from the tagged edges of a tet mesh (module docs).

    sign : the convention ('index', 'negated', 'valence'; or +1, -1)
    mesh : the TetMesh of tagged.vertices / tagged.tets, if already made

    Raises NetworkError naming the culprit (and its line) when a tag is out
    of the convention's range, a tagged pair is not an edge of the mesh, or
    one edge carries two different tags.
    """
    mesh = TetMesh(tagged.vertices, tagged.tets) if mesh is None else mesh
    E = np.asarray(tagged.edges, np.int64).reshape(-1, 2)
    sig = convention_sigma(tagged, sign)
    on = np.nonzero(sig != 0)[0]
    E, sig = E[on], sig[on]
    eid = mesh.edge_index(E[:, 0], E[:, 1])
    if np.any(eid < 0):
        k = int(np.argmax(eid < 0))
        a, b = E[k]
        why = "joins a vertex to itself" if a == b else "is not an edge of the tet mesh"
        raise NetworkError(f"{tagged.where(on[k])}: the tagged vertex pair ({a}, {b}) {why}")
    order = np.argsort(eid, kind="stable")
    same = np.nonzero((eid[order][1:] == eid[order][:-1]) & (sig[order][1:] != sig[order][:-1]))[0]
    if len(same):
        i, j = order[same[0]], order[same[0] + 1]
        a, b = E[i]
        raise NetworkError(f"{tagged.where(on[j])}: the edge ({a}, {b}) is tagged again with another tag (first at "
                           f"{tagged.where(on[i])}); tag each edge once")
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


@dataclass
class TetNetworkImport:
    """A network imported from a tagged tet mesh, and how its tags were read.

    Attributes
    ----------
    V : (n, 3) float array
        The tet mesh's boundary vertices.
    F : (m, 3) int array
        Its triangles, outward.
    network : Network
    convention : str
        ``'index'``, ``'negated'`` or ``'valence'``: how the tags were read.
    detected : bool
        True when the convention was detected, not given.
    results : dict
        ``{convention: 'fits' or why the network fails under it}`` for the
        conventions tried.
    tagged : TaggedNetwork or None
        The tet mesh and the tagged edges' chains.
    """

    V: np.ndarray
    F: np.ndarray
    network: Network
    convention: str
    detected: bool
    results: dict = field(default_factory=dict)
    tagged: TaggedNetwork | None = None

    def describe(self) -> str:
        """How the tags were read, in a line."""
        s = f"tags read by the '{self.convention}' convention ({CONVENTIONS[self.convention]})"
        if not self.detected:
            return s + ", as given"
        others = [f"{k}: {why}" for k, why in self.results.items() if k != self.convention]
        return s + ", detected: the only one under which the network satisfies Poincare-Hopf and the node rules" + (
            " (" + "; ".join(others) + ")" if others else "")


def _reading(tagged: TaggedTetMesh, mesh: TetMesh, S, convention: str, sharp_angle):
    """(TaggedNetwork, None) when the network under this convention passes
    check_topology, else (None, why)."""
    try:
        tn = network_from_tagged_edges(tagged, convention, sharp_angle, mesh=mesh)
        check_topology(S, tn.network)
    except (NetworkError, TopologyError) as e:
        return None, str(e)
    return tn, None


def import_tet_network(path: str, convention=None, edge_property: str | None = None,
                       sharp_angle: float | None = None) -> TetNetworkImport:
    """The domain and network of a tagged tet mesh, its tag convention
    detected or checked (module docs).

    Parameters
    ----------
    path : ``.ovm`` or ``.mesh`` (``read_tagged_tet_mesh``)
    convention : 'index', 'negated', 'valence' (or +1, -1), or None to detect it
    edge_property : OVM only, the edge property holding the tags
    sharp_angle : dihedral threshold for sharp edges besides the tagged
        boundary edges

    Returns
    -------
    TetNetworkImport

    Raises
    ------
    NetworkError
        A value of the file cannot be read (file, line and value named); no
        convention gives a network satisfying Poincare-Hopf and the node
        rules, or several do (each reading's result named); or the given one
        does not (naming the one that fits, if any).
    SurfaceError
        The tet mesh's boundary does not bound one solid.
    """
    if convention is not None:
        convention = convention_name(convention)
    tagged = read_tagged_tet_mesh(path, edge_property)
    sharp_angle = Network(sharp_angle=sharp_angle).sharp_angle  # checked as a Network checks it
    mesh = TetMesh(tagged.vertices, tagged.tets)
    B = mesh.boundary
    try:
        S = validate_surface(B.V, B.F)
    except SurfaceError as e:
        raise SurfaceError(f"{path}: the boundary of its tets does not bound one solid (a tet missing or extra?): "
                           f"{e}") from None
    tried = [convention] if convention is not None else list(CONVENTIONS)
    results, fits = {}, {}
    for name in tried:
        tn, why = _reading(tagged, mesh, S, name, sharp_angle)
        results[name] = why or "fits"
        if tn is not None:
            fits[name] = tn
    if convention is not None and convention not in fits:
        for name in CONVENTIONS:
            if name != convention:
                tn, why = _reading(tagged, mesh, S, name, sharp_angle)
                results[name] = why or "fits"
                if tn is not None:
                    fits[name] = tn
        if fits:
            name = next(iter(fits))
            raise NetworkError(
                f"{path}: read by the '{convention}' tag convention ({CONVENTIONS[convention]}) the network fails: "
                f"{results[convention]} -- but the '{name}' convention ({CONVENTIONS[name]}) satisfies Poincare-Hopf "
                f"and the node rules: the file's tags are read that way. Use --tag-convention {name} (Python: "
                f"convention='{name}'), or leave the convention out to detect it")
    if not fits:
        raise NetworkError(f"{path}: the {tagged.source} fit no tag convention; read by each, the network fails: "
                           + "; ".join(f"'{k}' ({CONVENTIONS[k]}): {why}" for k, why in results.items())
                           + ". Check that these are the file's singularity tags"
                           + (" (--tag-property NAME names another edge property)" if path.lower().endswith(".ovm")
                              else ""))
    if len(fits) > 1:
        raise NetworkError(f"{path}: the {tagged.source} fit more than one tag convention ("
                           + ", ".join(f"'{k}' ({CONVENTIONS[k]})" for k in fits)
                           + "): under each the network satisfies Poincare-Hopf and the node rules (curves that end "
                           "on the boundary in pairs of opposite indices, or none, cannot tell the sign). Give the "
                           "convention the file was written with: --tag-convention NAME (Python: convention=)")
    name, tn = next(iter(fits.items()))
    return TetNetworkImport(tn.V, tn.F, tn.network, name, convention is None, results, tn)


def read_tet_network(path: str, sign=None, edge_property: str | None = None,
                     sharp_angle: float | None = None) -> tuple[np.ndarray, np.ndarray, Network]:
    """(V, F, Network) from a tet mesh with an integer tag per edge.

    Parameters
    ----------
    path : ``.ovm`` (OpenVolumeMesh ASCII, the tag an integer edge property) or
        ``.mesh`` (MEDIT, the tag the reference number of an ``Edges`` entry)
    sign : the tag convention, 'index', 'negated' or 'valence' (or +1, -1),
        or None (the default) to detect it (module docs, ``import_tet_network``)
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
    imp = import_tet_network(path, sign, edge_property, sharp_angle)
    return imp.V, imp.F, imp.network

