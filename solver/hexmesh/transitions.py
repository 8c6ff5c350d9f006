"""Stage 2 of hex meshing: frames per tet, transitions from omega, holonomy,
combing and the cut.

Transitions from omega (paper §5 "Meshing": matchings "should be ... even
more robust near singularities by using angle information from omega").
For an edge ij of the field's mesh, g_ij is the cube symmetry with
``E_j G[g_ij]`` nearest ``exp(omega_ij) E_i`` (Eq. 8; field.matchings.
omega_matchings): the frame at i carried across the edge by the field's own
Darboux derivative, not compared with E_j directly.  Its margin is the
integrability defect, not the turn along the edge, so it holds where the
field turns fast (next to curves, on coarse meshes).

A tet t of the split mesh (curve_edges.py) has old vertices S(t) spanning a
simplex on which the g close; its base b(t) is the first of them and its
frame the chordal mean of ``E_s G[g_bs]`` over s in S(t).  Across a face
between tets A and B sharing an old vertex s, ``F_A ~ F_B M`` with
``M = G[g_s,b(B)] G[g_b(A),s]``: the same for every shared old vertex, as
the test in ``face_transitions`` checks.  A parametrisation u with
``grad u ~ F^T / cell`` then satisfies ``u_B = M u_A + tau`` across it.

Holonomy: the product of the transitions around an interior edge is the
identity off the network and a quarter turn about the edge on a curve edge
(the pierced face's monodromy).  Combing relabels every frame along a dual
spanning tree so that tree faces carry the identity; the cut is the rest,
shrunk where a non-singular interior edge holds a single cut face (AlgoHex's
``generate_cut_surface``, CubeCover's cut to a simply connected domain).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components

from ..errors import HexMeshError
from ..field.matchings import pair_matchings
from ..field.matchings import tet_frames as matching_tet_frames
from ..linalg.rotations import CUBE_GROUP, GROUP_INVERSE, GROUP_PRODUCT, closest_symmetry
from ..mesh.tetmesh import TET_EDGE_OPPOSITE, TetMesh
from .curve_edges import CurveEdgeError, CurveEdgeMesh, curves_on_edges
from .intake import hex_input, unconverged
from .report import where

G = CUBE_GROUP
IDENTITY = 0  # CUBE_GROUP[0] is the identity
AXIS_SLACK = 60.0
"""Degrees: a singular chain edge's quarter turn is about the frame axis
nearest the curve's tangent, or one this near it (a turn about an axis
across the curve, in a field that follows the curve, is 90 degrees off)."""


def rotation_axis_angle(g: np.ndarray):
    """(axis index 0-2 or -1, quarter turns 0-3 about +axis) of cube
    symmetries given by index; -1 for rotations not about a frame axis."""
    g = np.asarray(g)
    M = G[g]
    tr = np.einsum("nii->n", M)
    axis = np.full(len(g), -1)
    quarters = np.zeros(len(g), dtype=np.int64)
    # a rotation about axis k keeps e_k: M[k, k] = 1
    for k in range(3):
        keep = np.isclose(M[:, k, k], 1.0)
        i, j = (k + 1) % 3, (k + 2) % 3
        # angle from the (i, j) block: cos = M[i,i], sin = M[j,i]
        ang = np.rint(np.arctan2(M[:, j, i], M[:, i, i]) / (0.5 * np.pi)).astype(np.int64) % 4
        sel = keep & (ang != 0)
        axis[sel] = k
        quarters[sel] = ang[sel]
    quarters[np.isclose(tr, 3.0)] = 0
    axis[np.isclose(tr, 3.0)] = -1
    return axis, quarters


@dataclass
class Transitions:
    """Per-tet frames and face transitions of a CurveEdgeMesh, combed.

    frames      : (#T, 3, 3) combed tet frames, columns the cross axes
    faces       : (k,) interior face ids of the split mesh
    tets        : (k, 2) tets (A, B) on either side (mesh.face_tets)
    transition  : (k,) CUBE_GROUP index M with u_B = G[M] u_A + tau (combed)
    cut         : (k,) bool, face lies on the cut (may carry a translation)
    edge_holonomy : dict edge id -> CUBE_GROUP index around it (cut edges)
    singular_edges : (s,) edge ids of curve edges with sigma != 0
    bad_edges   : edge ids whose holonomy is not what the network prescribes
    ambiguous_faces : faces whose shared old vertices gave different M
    """

    frames: np.ndarray
    faces: np.ndarray
    tets: np.ndarray
    transition: np.ndarray
    cut: np.ndarray
    edge_holonomy: dict
    singular_edges: np.ndarray
    bad_edges: list
    ambiguous_faces: np.ndarray


def tet_frames(cem: CurveEdgeMesh, field_mesh: TetMesh, omega, frames):
    """Base old vertex per tet (#T,) and the tet frames (#T, 3, 3): the
    chordal mean of the frame sources' frames matched to the base by omega
    (field.matchings.tet_frames with the split tets' frame sources)."""
    src = cem.frame_sources  # (#T, 4), -1 padded
    has = src >= 0
    if not has.any(axis=1).all():
        raise CurveEdgeError("internal: a split tet has no vertex of the field's mesh to take its frame from")
    base = src[np.arange(len(src)), np.argmax(has, axis=1)]
    return base, matching_tet_frames(field_mesh, frames, omega, sources=src).frames


def face_transitions(cem: CurveEdgeMesh, base: np.ndarray, field_mesh: TetMesh, omega, frames):
    """Interior faces, their tets (A, B) and M with F_A ~ F_B G[M], through
    every frame source the two tets share; faces where those disagree are
    returned too."""
    mesh = cem.mesh
    src = cem.frame_sources
    faces = np.nonzero(~mesh.is_boundary_face)[0]
    A, B = mesh.face_tets[faces, 0], mesh.face_tets[faces, 1]
    M = np.full((len(faces), 4), -1, dtype=np.int64)
    for k in range(4):
        s = src[A, k]
        ok = (s >= 0) & (src[B] == s[:, None]).any(axis=1)
        g1 = pair_matchings(field_mesh, omega, frames, np.c_[base[A[ok]], s[ok]])
        g2 = pair_matchings(field_mesh, omega, frames, np.c_[s[ok], base[B[ok]]])
        M[ok, k] = GROUP_PRODUCT[g2, g1]
    none = np.nonzero((M < 0).all(axis=1))[0]
    if len(none):
        # neighbours split from different old tets, sharing no old vertex
        # (inserted vertices only on their face): matched through their
        # base vertices' frames by the closest cube symmetry
        # (E_bB g ~ E_bA), the same relation g2 g1 gives through a source
        bA, bB = base[A[none]], base[B[none]]
        M[none, 0] = closest_symmetry(np.einsum("nji,njk->nik", frames[bA], frames[bB]))
    first = M[np.arange(len(M)), np.argmax(M >= 0, axis=1)]
    ambiguous = np.any((M >= 0) & (M != first[:, None]), axis=1)
    return faces, np.c_[A, B], first, faces[ambiguous]


def comb(n_tets: int, tets: np.ndarray, M: np.ndarray, root: int = 0):
    """Relabelling C per tet along a BFS tree of the dual graph so that the
    tree faces carry the identity; returns (C, combed M, tree-face mask)."""
    A, B = tets[:, 0], tets[:, 1]
    adj = sp.coo_matrix((np.arange(1, len(A) + 1), (A, B)), shape=(n_tets, n_tets)).tocsr()
    adj = adj + adj.T
    ncomp, _ = connected_components(adj, directed=False)
    if ncomp != 1:
        raise CurveEdgeError(f"internal: the split mesh has {ncomp} face-connected parts")
    order, pred = breadth_first_order(adj, root, directed=False, return_predecessors=True)
    # the face between each tet and its predecessor, and the transition
    # across it from the predecessor
    t = order[1:]
    p = pred[t]
    i = adj[p, t].A1 - 1
    tree = np.zeros(len(A), bool)
    tree[i] = True
    inv = GROUP_INVERSE
    step = np.full(n_tets, IDENTITY, dtype=np.int64)
    step[t] = np.where(A[i] == p, M[i], inv[M[i]])
    # C[t] = step[t] C[pred t], composed up the tree by pointer jumping:
    # C[t] = acc[t] C[up[t]], halving the distance to the root each round
    up = pred.copy()
    up[root] = root
    acc = step
    while np.any(up != root):
        acc = GROUP_PRODUCT[acc, acc[up]]
        up = up[up]
    C = acc
    combed = GROUP_PRODUCT[GROUP_PRODUCT[inv[C[B]], M], C[A]]
    return C, combed, tree


def _edge_faces(mesh: TetMesh, faces: np.ndarray):
    """CSR-like map edge -> positions in `faces` of the faces holding it."""
    fe = mesh.face_edges[faces]  # (k, 3)
    rows = fe.reshape(-1)
    cols = np.repeat(np.arange(len(faces)), 3)
    return sp.csr_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(mesh.n_edges, len(faces)))


def shrink_cut(mesh: TetMesh, faces: np.ndarray, cut: np.ndarray, keep_edges: np.ndarray) -> np.ndarray:
    """Remove cut faces hanging off an interior edge that holds no other cut
    face, until none is left; edges in keep_edges (singular, boundary) are
    never shrunk across.  (The faces removed do not depend on the order: a
    face hanging off an edge keeps hanging off it until it goes, so every
    hanging face of a round goes at once.)"""
    cut = cut.copy()
    E2F = _edge_faces(mesh, faces)
    fe = mesh.face_edges[faces]
    free = ~keep_edges
    count = np.asarray(E2F[:, np.nonzero(cut)[0]].sum(axis=1)).ravel()
    while True:
        hang = cut & ((count[fe] == 1) & free[fe]).any(axis=1)
        if not hang.any():
            return cut
        cut &= ~hang
        np.subtract.at(count, fe[hang].ravel(), 1)


def ring_walk(mesh: TetMesh, edges: np.ndarray, face_pos: np.ndarray):
    """The rings of tets around tet edges, walked all at once.  For edge
    ``edges[i]``: the tets around it in order, ``order[i, :n_order[i]]``,
    and between consecutive tets the position (into the interior-face list)
    of the face crossed, ``crossed[i, :n_crossed[i]]``.  A ring starts at
    the first tet (by id) with a boundary face at the edge, if any (an open
    fan, its first and last tets on the boundary), and leaves it through its
    first interior face holding the edge.  face_pos maps a face id to its
    interior position (-1 on the boundary).  Returns (order, crossed,
    n_order, n_crossed), the arrays padded with -1."""
    tf, ft = mesh.tet_faces, mesh.face_tets
    n = len(edges)
    slot = np.full(mesh.n_edges, -1, dtype=np.int64)
    slot[edges] = np.arange(n)
    r, c = np.nonzero(slot[mesh.tet_edges] >= 0)  # (tet, local edge) entries, by tet
    ei = slot[mesh.tet_edges[r, c]]
    srt = np.argsort(ei, kind="stable")
    r, c, ei = r[srt], c[srt], ei[srt]
    begin = np.searchsorted(ei, np.arange(n))
    count = np.diff(np.r_[begin, len(ei)])
    # the two faces of each entry's tet that hold the edge
    fa, fb = tf[r, TET_EDGE_OPPOSITE[c, 0]], tf[r, TET_EDGE_OPPOSITE[c, 1]]
    on_boundary = (face_pos[fa] < 0) | (face_pos[fb] < 0)
    first_b = np.minimum.reduceat(np.where(on_boundary, np.arange(len(ei)), len(ei)), begin) if n else begin
    start = np.where(first_b < len(ei), first_b, begin)
    key = r * max(n, 1) + ei  # an entry by (tet, edge)
    kord = np.argsort(key)
    t0, f0, f1 = r[start], fa[start], fb[start]
    f = np.where(face_pos[f0] < 0, f1, f0)
    width = int(count.max(initial=0)) + 2
    order = np.full((n, width), -1, dtype=np.int64)
    crossed = np.full((n, width), -1, dtype=np.int64)
    order[:, 0] = t0
    n_order, n_crossed = np.ones(n, dtype=np.int64), np.zeros(n, dtype=np.int64)
    cur = t0.copy()
    active = (face_pos[f0] >= 0) | (face_pos[f1] >= 0)  # not a single tet between two boundary faces
    while active.any():
        idx = np.nonzero(active)[0]
        fi = f[idx]
        crossed[idx, n_crossed[idx]] = face_pos[fi]
        n_crossed[idx] += 1
        other = np.where(ft[fi, 0] != cur[idx], ft[fi, 0], ft[fi, 1])
        closed = other == t0[idx]
        active[idx[closed]] = False
        go, other, fi = idx[~closed], other[~closed], fi[~closed]
        if np.any(n_order[go] > count[go]):
            raise CurveEdgeError("internal: an edge's ring of tets does not close")
        order[go, n_order[go]] = other
        n_order[go] += 1
        ent = kord[np.searchsorted(key, other * max(n, 1) + go, sorter=kord)]
        f[go] = np.where(fa[ent] == fi, fb[ent], fa[ent])
        cur[go] = other
        active[go[face_pos[f[go]] < 0]] = False
    return order, crossed, n_order, n_crossed


def edge_rings(mesh: TetMesh, edges: np.ndarray, face_pos: np.ndarray) -> dict:
    """For each edge id in edges: the tets around it in order and, between
    consecutive tets, the position (into the interior-face list) of the face
    crossed (``ring_walk``, as lists)."""
    order, crossed, n_order, n_crossed = ring_walk(mesh, edges, face_pos)
    return {e: (order[i, :n_order[i]].tolist(), crossed[i, :n_crossed[i]].tolist())
            for i, e in enumerate(edges.tolist())}


def ring_holonomy(order: np.ndarray, crossed: np.ndarray, n_crossed: np.ndarray, tets_ab: np.ndarray,
                  M: np.ndarray) -> np.ndarray:
    """CUBE_GROUP index of the transitions composed once around each ring
    of ``ring_walk``."""
    h = np.full(len(order), IDENTITY, dtype=np.int64)
    for i in range(int(n_crossed.max(initial=0))):
        on = np.nonzero(i < n_crossed)[0]
        p, cur = crossed[on, i], order[on, i]
        m = np.where(tets_ab[p, 0] == cur, M[p], GROUP_INVERSE[M[p]])
        h[on] = GROUP_PRODUCT[m, h[on]]
    return h


def turns_about_curve(h: int, frame: np.ndarray, tangent: np.ndarray) -> bool:
    """Whether the holonomy h (a CUBE_GROUP index) around a singular chain
    edge is a turn about the curve: a quarter (or half) turn about the axis
    of ``frame`` (3, 3; columns the axes) nearest the curve's tangent, or
    one within ``AXIS_SLACK`` of it.  Where a curve's end bends faster than
    its tets resolve, the frames lag its tangent: a tet-edge radial curve
    bent 45 degrees over its last third, at an ellipsoid's tip, had the
    turn's axis (the same in every tet of the ring) 50 degrees off its
    tangent and another axis 46, and was refused as a singularity the
    network does not ask for.  Given k holonomies, frames (k, 3, 3) and
    tangents (k, 3): a (k,) bool array."""
    one = np.ndim(h) == 0
    h = np.atleast_1d(h)
    frame, tangent = np.reshape(frame, (-1, 3, 3)), np.reshape(tangent, (-1, 3))
    axis, q = rotation_axis_angle(h)
    d = np.abs(np.einsum("nji,nj->ni", frame, tangent))  # |frame^T tangent|
    near = d[np.arange(len(d)), np.maximum(axis, 0)] >= np.cos(np.radians(AXIS_SLACK))
    ok = (q != 0) & ((axis == np.argmax(d, axis=1)) | near)
    return bool(ok[0]) if one else ok


def build_transitions(cem: CurveEdgeMesh, field_mesh: TetMesh, omega: np.ndarray, frames: np.ndarray) -> Transitions:
    """Frames per tet, transitions from omega, combing, the cut and the
    holonomy check (module docs).

    Parameters
    ----------
    cem : CurveEdgeMesh
        the split mesh (curve_edges.curves_on_edges)
    field_mesh : TetMesh
        the field's mesh; omega (#E, 3) and frames (#V, 3, 3) live on it

    Returns
    -------
    Transitions
    """
    mesh = cem.mesh
    base, F = tet_frames(cem, field_mesh, omega, frames)
    faces, ab, M, ambiguous = face_transitions(cem, base, field_mesh, omega, frames)
    C, Mc, tree = comb(mesh.n_tets, ab, M)
    F = F @ G[C]
    # singular and boundary edges block the shrinking
    sing = np.zeros(mesh.n_edges, bool)
    tangent = np.zeros((mesh.n_edges, 3))  # the curve's tangent at its chain edges
    for ch in cem.chains:
        e = mesh.edge_index(ch.vertices[:-1], ch.vertices[1:])
        if ch.sigma != 0:
            sing[e] = True
            tangent[e] = ch.tangents(mesh.vertices)
    keep = sing | mesh.is_boundary_edge
    cut = shrink_cut(mesh, faces, ~tree, keep)
    # holonomy on every interior edge touching a non-identity face, and on
    # every singular edge
    face_pos = np.full(mesh.n_faces, -1, dtype=np.int64)
    face_pos[faces] = np.arange(len(faces))
    touch = np.zeros(mesh.n_edges, bool)
    touch[mesh.face_edges[faces[Mc != IDENTITY]].reshape(-1)] = True
    check = np.nonzero((touch | sing) & ~mesh.is_boundary_edge)[0]
    order, crossed, _, n_crossed = ring_walk(mesh, check, face_pos)
    h = ring_holonomy(order, crossed, n_crossed, ab, Mc)
    hol = dict(zip(check.tolist(), h.tolist()))
    # on a singular edge a quarter turn about the frame axis along the curve
    # (its tangent, not the chain edge's own direction: a chain zig-zags),
    # elsewhere none
    on = sing[check]
    wrong = h != IDENTITY
    wrong[on] = ~turns_about_curve(h[on], F[order[on, 0]], tangent[check[on]])
    bad = check[wrong].tolist()
    return Transitions(F, faces, ab, Mc, cut, hol, np.nonzero(sing)[0], bad, ambiguous)


def checked_transitions(cem: CurveEdgeMesh, inp, report=None) -> Transitions:
    """The transitions of the split mesh (``build_transitions``), refused
    where they do not close as the network prescribes.

    Parameters
    ----------
    cem : CurveEdgeMesh
    inp : SolvedField
        the field (its mesh, omega and frames)
    report : HexReport, optional
        receives ``holonomy_bad_edges``; carried by a refusal

    Returns
    -------
    Transitions

    Raises
    ------
    HexMeshError
        kind 'field', naming how many tet edges and where
    """
    tr = build_transitions(cem, inp.mesh, inp.omega, inp.frames)
    if report is not None:
        report.holonomy_bad_edges = len(tr.bad_edges)
    if tr.bad_edges or len(tr.ambiguous_faces):
        P = cem.mesh.vertices[np.r_[cem.mesh.edges[tr.bad_edges].reshape(-1),
                                    cem.mesh.faces[tr.ambiguous_faces].reshape(-1)].astype(np.int64)]
        raise HexMeshError(
            f"the field's transitions do not close as the network prescribes around {len(tr.bad_edges)} tet "
            f"edges ({len(tr.ambiguous_faces)} faces ambiguous) near {where(P)}: the field has singularities "
            "the network does not ask for there" + unconverged(inp) + "; a field that is not hex-meshable as "
            "solved cannot give a hex mesh (solve it on a finer mesh, or check the network there)", report,
            kind="field")
    return tr


# ------------------------------------------------------------ for other hex meshers


@dataclass
class EdgeField:
    """A solved field on its tet mesh split so that the network runs along
    tet edges (curve_edges.py), one frame per tet, ready for a hex mesher
    that wants singular edges on mesh edges (CubeCover, AlgoHex).

    mesh         : TetMesh, the split mesh
    tet_frames   : (#T, 3, 3) combed per-tet frames, columns the cross axes
    faces, tets  : (k,) interior faces and (k, 2) their tets (A, B)
    transition   : (k,) CUBE_GROUP index g with F_A ~ F_B G[g]
    curve        : (#T,) the prepared curve whose chain runs along an edge of
                   the tet, -1 elsewhere
    vertex_frames: (#V, 3, 3) the field's frame at its own vertices; at the
                   inserted ones (on the curves) that of a tet around them
    chains       : the curve_edges.Chain of every prepared curve
    """

    mesh: object
    tet_frames: np.ndarray
    faces: np.ndarray
    tets: np.ndarray
    transition: np.ndarray
    curve: np.ndarray
    vertex_frames: np.ndarray
    chains: list


def field_on_edges(field) -> EdgeField:
    """A solved field on its tet mesh split so that its curves run along tet
    edges.

    Parameters
    ----------
    field : SolvedField, or a solver Result

    Returns
    -------
    EdgeField

    Raises
    ------
    HexMeshError
        where the network cannot be put onto tet edges or the field's
        transitions do not close as the network prescribes (then no hex
        mesher can use it either)
    """
    inp = hex_input(field, "field_on_edges")
    try:
        cem = curves_on_edges(inp.mesh, inp.embedding, inp.network)
    except CurveEdgeError as e:
        raise HexMeshError(f"the network cannot be put onto the tet mesh's edges: {e}", kind="map") from None
    tr = build_transitions(cem, inp.mesh, inp.omega, inp.frames)
    if tr.bad_edges or len(tr.ambiguous_faces):
        raise HexMeshError(f"the field's transitions do not close as the network prescribes around "
                           f"{len(tr.bad_edges)} tet edges" + unconverged(inp), kind="field")
    mesh = cem.mesh
    curve = np.full(mesh.n_tets, -1, dtype=np.int64)
    for ch in cem.chains:
        e = mesh.edge_index(ch.vertices[:-1], ch.vertices[1:])
        curve[np.nonzero(np.isin(mesh.tet_edges, e).any(axis=1))[0]] = ch.curve
    VF = np.zeros((mesh.n_vertices, 3, 3))
    src = cem.source_vertex
    VF[src >= 0] = inp.frames[src[src >= 0]]
    new = np.nonzero(src < 0)[0]
    if len(new):
        # the first tet around each inserted vertex
        t_of = np.full(mesh.n_vertices, -1, dtype=np.int64)
        t_of[mesh.tets.reshape(-1)[::-1]] = np.repeat(np.arange(mesh.n_tets), 4)[::-1]
        VF[new] = tr.frames[t_of[new]]
    return EdgeField(mesh, tr.frames, tr.faces, tr.tets, tr.transition, curve, VF, cem.chains)
