"""Stage 1 of hex meshing: the network onto tet edges.

A parametrisation needs its singularities on mesh edges and one frame per
tet (CubeCover, AlgoHex's Parametrization3DT).  The field's embedding
(mesh/embed.py) is dual instead: a curve pierces faces and crosses the tets
of its tube, and a node is a ball of tets with no structure equation.  The
paper re-ran TetGen with the singular faces' barycentres inserted (§5
"Meshing"); here the field's own mesh is changed locally, so that the field
(frames per vertex, omega per edge) carries over unchanged:

* every face a curve pierces is split 1 -> 3 at its pierce point, and so
  are the boundary faces where curves end.  A crossed tet has two split
  faces (entry and exit); splitting the entry face makes three children,
  and the one holding the exit face is split again, so the segment between
  the two pierce points becomes an edge (5 children, each the parent with
  one or two face vertices replaced by a point of that face: positive by
  construction);
* each node's ball (its node region grown by a layer of tets, so that its
  skin is made of faces that do carry the structure equation, and grown
  further until every skin face sees the node) is re-tetrahedralised as a
  cone from the node over its skin.  A curve leaving the node pierces the
  skin once; that skin face is split like the others, giving the edge from
  the node to the pierce point.

Every new tet lies inside one old tet (or one ball), and none holds all
three vertices of a pierced face: its old vertices span a simplex on which
omega's matchings close, so frames per tet and transitions between them
follow from omega alone (transitions.py), and the holonomy around every
edge of the new mesh is the monodromy of an old face: the pierced face's
quarter turn around a curve edge, the identity elsewhere.

A pierce point close to an edge of its face would make near-flat children:
its barycentric coordinates are clamped to >= ``LAMBDA_MIN`` (the chain
then passes within a fraction of an edge of the curve; the hex mesh's
irregular edges are only asked to lie within one cell of it).

Inputs this does not handle (two curves through one tet or one face, a
curve entering a tet twice, node balls that touch another node or curve)
raise ``CurveEdgeError`` naming the curves and the place; a finer field
mesh separates them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import MeshingError
from ..mesh.tetmesh import TET_FACES, TetMesh

LAMBDA_MIN = 0.1
"""Smallest barycentric coordinate of a split point on its face: children
keep at least this fraction of their parent's volume."""

VERTEX_ROUTE = 0.2
"""A curve passing closer than this fraction of the local edge length to a
vertex of the field's mesh is routed through the vertex: clamping the pierce
points of the faces around it would make the chain zig-zag backwards.  Not
through a vertex of a face another curve pierces (``_piercing_curves``)."""

CONE_HEIGHT_MIN = 0.15
"""A node ball's skin face must be seen from the node at a height of at
least this fraction of the face's size (sqrt of twice its area)."""


class CurveEdgeError(MeshingError):
    """The network cannot be put onto tet edges by local splits."""


@dataclass
class Chain:
    """One curve as a chain of edges of the new mesh.

    vertices : (k,) vertex ids in curve order (closed loops repeat the first)
    curve    : index of the prepared curve
    sigma    : index in turns (0 for feature curves)
    polyline : (n, 3) the curve the chain follows (its tangent, not the
               chain's zig-zag, says which parameter axis the chain runs along)
    """

    vertices: np.ndarray
    curve: int
    sigma: float
    closed: bool = False
    polyline: np.ndarray | None = None

    def tangents(self, X: np.ndarray) -> np.ndarray:
        """(k-1, 3) unit tangent of the curve at each chain edge's midpoint:
        the direction of the polyline segment nearest to it."""
        mid = 0.5 * (X[self.vertices[:-1]] + X[self.vertices[1:]])
        if self.polyline is None or len(self.polyline) < 2:
            d = X[self.vertices[1:]] - X[self.vertices[:-1]]
            return d / np.linalg.norm(d, axis=1, keepdims=True)
        P = self.polyline
        a, d = P[:-1], P[1:] - P[:-1]
        dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
        s = np.clip(np.einsum("kij,ij->ki", mid[:, None] - a[None], d) / dd, 0.0, 1.0)
        dist = np.linalg.norm(mid[:, None] - (a[None] + s[..., None] * d[None]), axis=2)
        seg = d[np.argmin(dist, axis=1)]
        return seg / np.linalg.norm(seg, axis=1, keepdims=True)

    @property
    def edges(self) -> np.ndarray:
        """(k-1, 2) consecutive vertex pairs."""
        return np.c_[self.vertices[:-1], self.vertices[1:]]


@dataclass
class CurveEdgeMesh:
    """The field's tet mesh with the network on its edges.

    mesh          : TetMesh, positively oriented
    frame_sources : (#T, 4) vertices of the field's mesh (-1 padded) whose
                    frames make each tet's frame: its own old vertices, or
                    for a node ball's tets the skin triangle's
    source_vertex : (#V,) vertex of the field's mesh each vertex is, -1 for
                    inserted points (pierce points, curve ends, nodes)
    parent        : (#T,) tet of the field's mesh each new tet lies in (for
                    a node ball's cone tets: the ball tet the skin face was a
                    face of)
    chains        : one Chain per prepared curve
    node_vertices : (#nodes,) vertex id of each node
    stats         : counts of what was split and coned
    """

    mesh: TetMesh
    source_vertex: np.ndarray
    parent: np.ndarray
    chains: list[Chain]
    node_vertices: np.ndarray
    stats: dict = field(default_factory=dict)
    frame_sources: np.ndarray | None = None


def _clamp_to_face(P: np.ndarray, X: np.ndarray, lam_min: float = LAMBDA_MIN) -> np.ndarray:
    """The points P (k, 3) moved into their triangles X (k, 3, 3) so that
    every barycentric coordinate is >= lam_min (least-squares coordinates,
    so a point slightly off the face's plane lands on it)."""
    A = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]], axis=2)  # (k, 3, 2)
    AtA = np.einsum("kia,kib->kab", A, A)
    Atb = np.einsum("kia,ki->ka", A, P - X[:, 0])
    uv = np.linalg.solve(AtA, Atb[..., None])[..., 0]
    lam = np.c_[1.0 - uv.sum(axis=1), uv]
    lam = np.maximum(lam, lam_min)
    lam /= lam.sum(axis=1, keepdims=True)
    return np.einsum("ka,kai->ki", lam, X)


def _tet_face_local(T: np.ndarray, tet_faces: np.ndarray, t: int, f: int) -> int:
    """Local index (0-3, the opposite vertex) of face f in tet t."""
    loc = np.nonzero(tet_faces[t] == f)[0]
    if len(loc) != 1:
        raise CurveEdgeError(f"internal: face {f} is not a face of tet {t}")
    return int(loc[0])


class _Builder:
    """Collects the splits of one field mesh, then builds the new mesh."""

    def __init__(self, mesh: TetMesh, labels: list[str]):
        self.mesh = mesh
        self.labels = labels
        self.points: list[np.ndarray] = []  # inserted vertices
        self.face_point: dict[int, int] = {}  # split face -> inserted vertex id
        self.face_curve: dict[int, int] = {}
        self.tet_splits: dict[int, list] = {}  # crossed tet -> [(entry face, exit face, curve)]

    def new_point(self, x: np.ndarray) -> int:
        self.points.append(np.asarray(x, float))
        return self.mesh.n_vertices + len(self.points) - 1

    def split_face(self, f: int, x: np.ndarray, curve: int) -> int:
        if f in self.face_point:
            other = self.face_curve[f]
            c = self.mesh.vertices[self.mesh.faces[f]].mean(axis=0)
            who = (f"curves {self.labels[other]} and {self.labels[curve]} both pass" if other != curve
                   else f"curve {self.labels[curve]} passes twice")
            raise CurveEdgeError(
                f"{who} through one face of the field's tet mesh near ({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g}); "
                "solve the field on a finer mesh (a smaller edge length) so that they are at least one tet apart")
        X = self.mesh.vertices[self.mesh.faces[f]]
        p = _clamp_to_face(np.asarray(x, float)[None], X[None])[0]
        v = self.new_point(p)
        self.face_point[f] = v
        self.face_curve[f] = curve
        return v

    def cross(self, t: int, f_in: int | None, f_out: int | None, curve: int) -> None:
        """Tet t is crossed from face f_in to face f_out; None where the curve
        enters or leaves through a vertex of t instead."""
        self.tet_splits.setdefault(int(t), []).append((f_in, f_out, curve))

    def keep(self, t: int) -> None:
        """Tet t is crossed between two of its vertices' faces: left whole."""
        self.tet_splits.setdefault(int(t), []).append((None, None, -1))


def _skin(T: np.ndarray, tet_faces: np.ndarray, face_tets: np.ndarray, region: np.ndarray, inside: np.ndarray):
    """Skin faces of a set of tets: (tet, local face, face id, tet across or -1)."""
    tf = tet_faces[region]  # (k, 4)
    ft = face_tets[tf]  # (k, 4, 2)
    other = np.where(ft[..., 0] == region[:, None], ft[..., 1], ft[..., 0])
    out = (other < 0) | ~inside[np.maximum(other, 0)]
    r, l = np.nonzero(out)
    return region[r], l, tf[r, l], other[r, l]


def _cone_heights(X: np.ndarray, T: np.ndarray, tets: np.ndarray, local: np.ndarray, apex: np.ndarray):
    """Signed height of the apex over each skin face, relative to the face's
    size: > 0 where the face is seen from inside."""
    F = T[tets][np.arange(len(tets))[:, None], TET_FACES[local]]  # (k, 3)
    a, b, c = X[F[:, 0]], X[F[:, 1]], X[F[:, 2]]
    n = np.cross(b - a, c - a)
    area2 = np.linalg.norm(n, axis=1)
    opp = X[T[tets, local]]
    side = np.sign(np.einsum("ij,ij->i", n, opp - a))  # the tet's own vertex is inside
    h = side * np.einsum("ij,ij->i", n, apex - a) / np.maximum(area2, 1e-300)
    return h / np.sqrt(np.maximum(area2, 1e-300))


def _node_ball(mesh: TetMesh, seed: np.ndarray, apex: np.ndarray, label: str, max_grow: int = 8) -> np.ndarray:
    """The node region grown by one layer, then until the node sees every
    skin face from a height >= CONE_HEIGHT_MIN (module docs)."""
    T, X = mesh.tets, mesh.vertices
    tf, ft = mesh.tet_faces, mesh.face_tets
    inside = np.zeros(mesh.n_tets, bool)
    inside[seed] = True
    # one layer: the skin of the node region has no structure equation
    _, _, _, other = _skin(T, tf, ft, np.nonzero(inside)[0], inside)
    inside[other[other >= 0]] = True
    for _ in range(max_grow):
        region = np.nonzero(inside)[0]
        tets, local, faces, other = _skin(T, tf, ft, region, inside)
        h = _cone_heights(X, T, tets, local, apex)
        bad = h < CONE_HEIGHT_MIN
        if not bad.any():
            return region
        if np.any(bad & (other < 0)):
            break  # the ball reaches the solid's surface where the node cannot see it
        inside[other[bad]] = True
    raise CurveEdgeError(
        f"node {label} at ({apex[0]:.4g}, {apex[1]:.4g}, {apex[2]:.4g}): its ball of tets cannot be made "
        "star-shaped from the node (it is too close to the surface or its tets are too distorted); solve the "
        "field on a finer mesh or move the node further from the surface")


def curves_on_edges(mesh: TetMesh, embedding, network) -> CurveEdgeMesh:
    """Split the field's tet mesh so that every prepared curve is a chain of
    edges and every node a vertex (module docs).

    Parameters
    ----------
    mesh : TetMesh
        the field's tet mesh
    embedding : mesh.embed.Embedding
        the curves traced through it (pierced faces and points, node regions)
    network : network.network.PreparedNetwork
        the prepared curves and nodes the embedding traced

    Returns
    -------
    CurveEdgeMesh

    Raises
    ------
    CurveEdgeError
        where two curves share a tet or a face, or a node's ball cannot be
        coned, naming the curves or the node and where.
    """
    labels = [f"{network.source[i]}" + (f" '{c.name}'" if c.name else "") for i, c in enumerate(network.curves)]
    b = _Builder(mesh, labels)
    node_vertex, ball_of, balls = _node_balls(mesh, embedding, network, b)
    end_node = {e: k for k, nd in enumerate(network.nodes) for e in nd.ends}
    chains = []
    routed: set[int] = set()  # field-mesh vertices a chain passes through
    piercer = _piercing_curves(mesh, embedding)
    for ci, (c, tr) in enumerate(zip(network.curves, embedding.traces)):
        tets, faces, pts = np.asarray(tr.tets), np.asarray(tr.faces), np.asarray(tr.points)
        n = len(tets)
        lo, hi = 0, n - 1  # crossed tets tets[lo..hi] lie outside the node balls
        start_v = end_v = -1
        if network.start_kind[ci] == "node":
            k = end_node[(ci, 0)]
            while lo < n and ball_of[tets[lo]] == k:
                lo += 1
            start_v = int(node_vertex[k])
        if network.end_kind[ci] == "node":
            k = end_node[(ci, 1)]
            while hi >= 0 and ball_of[tets[hi]] == k:
                hi -= 1
            end_v = int(node_vertex[k])
        polyline = np.asarray(tr.polyline, float)
        if lo == hi + 1 and start_v >= 0 and end_v >= 0 and 0 < lo < n:
            # a node-to-node curve that passes from one node's ball straight
            # into the other's: the face between them is split, both cones
            # reach the pierce point
            p = b.split_face(int(faces[lo - 1]), pts[lo - 1], ci)
            chains.append(Chain(np.array([start_v, p, end_v], dtype=np.int64), ci, float(c.sigma), False, polyline))
            continue
        if lo > hi and (start_v >= 0) != (end_v >= 0):
            # a curve from a node to the surface inside the node's ball (a
            # short radial curve): where the ball holds the boundary face
            # it ends on, the face is split there and the cone reaches it
            k, f = (end_node[(ci, 0)], int(tr.end_face)) if start_v >= 0 else (end_node[(ci, 1)], int(tr.start_face))
            if f >= 0 and ball_of[int(np.max(mesh.face_tets[f]))] == k:
                x = _end_point(mesh, f, polyline) if start_v >= 0 else polyline[0]
                p = b.split_face(f, x, ci)
                chains.append(Chain(np.array([start_v, p] if start_v >= 0 else [p, end_v], dtype=np.int64), ci,
                                    float(c.sigma), False, polyline))
                continue
        if lo > hi:
            raise CurveEdgeError(
                f"curve {labels[ci]} lies inside its nodes' balls of tets (it is shorter than about two tets of "
                "the field's mesh); solve the field on a finer mesh (a smaller edge length)")
        inner = tets[lo:hi + 1]
        if np.any(ball_of[inner] >= 0):
            k = int(ball_of[inner][ball_of[inner] >= 0][0])
            raise CurveEdgeError(
                f"curve {labels[ci]} passes through the ball of tets around node {k}, which it does not end at; "
                "solve the field on a finer mesh (a smaller edge length) so that it passes further from the node")
        if network.start_kind[ci] == "loop":
            # the loop starts inside tets[0] == tets[-1]: that tet is entered
            # through the last face and left through the first
            seq_faces = np.r_[faces, faces[:1]]
            verts = [b.split_face(int(f), x, ci) for f, x in zip(faces, pts)]
            for j in range(len(faces)):
                b.cross(tets[j + 1] if j + 1 < n else tets[0], seq_faces[j], seq_faces[j + 1], ci)
            chains.append(Chain(np.array(verts + verts[:1], dtype=np.int64), ci, float(c.sigma), True, polyline))
            continue
        # entry face of tets[lo] and exit face of tets[hi]; the start and end
        # points (a node, or where the curve meets the surface)
        start_node, end_node_ = network.start_kind[ci] == "node", network.end_kind[ci] == "node"
        f0 = int(faces[lo - 1]) if start_node else int(tr.start_face)
        f1 = int(faces[hi]) if end_node_ else int(tr.end_face)
        x0 = pts[lo - 1] if start_node else polyline[0]
        x1 = pts[hi] if end_node_ else _end_point(mesh, f1, polyline)
        seq = [f0, *faces[lo:hi].tolist(), f1]  # entry face of inner[j] is seq[j], its exit seq[j + 1]
        xs = [x0, *pts[lo:hi], x1]
        # a vertex of a face another curve pierces keeps its frame: the tets
        # around that curve's chain need it to wind around the curve
        runs = _vertex_runs(mesh, inner, seq, polyline, routed, boundary_ok=(not start_node, not end_node_),
                            keep=(piercer != ci) & (piercer != -1))
        chain = _open_chain(mesh, b, ci, inner, seq, xs, runs, routed)
        chain = ([start_v] if start_node else []) + chain + ([end_v] if end_node_ else [])
        chains.append(Chain(np.array(chain, dtype=np.int64), ci, float(c.sigma), False, polyline))
    return _build(mesh, b, balls, node_vertex, chains, mesh.vertices, routed)


def _piercing_curves(mesh: TetMesh, embedding) -> np.ndarray:
    """Per vertex of the field's mesh, the curve whose pierced faces (and
    surface end faces) hold it: -1 none, -2 more than one.  A chain routed
    through a vertex takes away its frame from every tet around it
    (``_build``), so it must not pass through a vertex of a face another
    curve pierces: the split tets around that curve would keep the frames
    of only two of the face's vertices, and their transitions could no
    longer wind around it."""
    owner = np.full(mesh.n_vertices, -1, dtype=np.int64)
    for ci, tr in enumerate(embedding.traces):
        f = [int(x) for x in np.asarray(tr.faces, dtype=np.int64).tolist()]
        f += [int(x) for x in (tr.start_face, tr.end_face) if x is not None and int(x) >= 0]
        v = np.unique(mesh.faces[np.asarray(f, dtype=np.int64)]) if f else np.zeros(0, dtype=np.int64)
        o = owner[v]
        owner[v] = np.where((o == -1) | (o == ci), ci, -2)
    return owner


def _node_balls(mesh: TetMesh, embedding, network, b: _Builder):
    """Per node: its inserted vertex, and its ball of tets (the node region,
    the curves' first tets, grown to star-shaped: _node_ball); (node
    vertices, ball id per tet or -1, balls)."""
    node_vertex = np.array([b.new_point(np.asarray(nd.position, float)) for nd in network.nodes], dtype=np.int64)
    ball_of = np.full(mesh.n_tets, -1, dtype=np.int64)
    balls = []
    for k, nd in enumerate(network.nodes):
        seed = [np.asarray(embedding.node_region[k], dtype=np.int64), [int(embedding.node_tets[k])]]
        # the curves' first tets, up to their last one in the region: a curve
        # leaves the ball through one skin face only
        region = set(np.concatenate(seed).tolist())
        for ci, s in nd.ends:
            tets = embedding.traces[ci].tets
            seq = tets if s == 0 else tets[::-1]
            inreg = np.nonzero(np.isin(seq, list(region)))[0]
            if len(inreg):
                seed.append(seq[: inreg[-1] + 1])
        ball = _node_ball(mesh, np.unique(np.concatenate(seed)), np.asarray(nd.position, float), str(k))
        clash = ball_of[ball]
        if np.any(clash >= 0):
            raise CurveEdgeError(
                f"nodes {int(clash[clash >= 0][0])} and {k} are too close for the field's mesh (their balls of "
                "tets overlap); solve the field on a finer mesh (a smaller edge length)")
        ball_of[ball] = k
        balls.append(ball)
    return node_vertex, ball_of, balls


def _open_chain(mesh: TetMesh, b: _Builder, ci: int, inner, seq: list, xs: list, runs: dict, routed: set) -> list:
    """The chain of a curve crossing the tets inner (entry face of inner[j]
    seq[j], exit seq[j + 1], pierce points xs), through the vertices of
    runs; records the splits in b.  Returns the vertex ids, start to end
    (without the nodes)."""
    Fv = mesh.faces
    chain = []
    j = 0
    while j < len(inner):
        run = runs.get(j)
        if run is None:
            # a plain crossing: the entry face split (the start's is split here)
            if j == 0:
                chain.append(b.split_face(seq[0], xs[0], ci))
            b.cross(int(inner[j]), seq[j], seq[j + 1], ci)
            chain.append(b.split_face(seq[j + 1], xs[j + 1], ci))
            j += 1
            continue
        v, k = run  # inner[j..k] all hold v: the chain goes through v
        entry_has_v = v in Fv[seq[j]]
        exit_has_v = v in Fv[seq[k + 1]]
        if not entry_has_v:
            if j == 0:
                chain.append(b.split_face(seq[0], xs[0], ci))
            b.cross(int(inner[j]), seq[j], None, ci)
        chain.append(int(v))
        routed.add(int(v))
        if not exit_has_v:
            b.cross(int(inner[k]), None, seq[k + 1], ci)
            chain.append(b.split_face(seq[k + 1], xs[k + 1], ci))
        for m in range(j, k + 1):
            if (m != j or entry_has_v) and (m != k or exit_has_v):
                b.keep(int(inner[m]))  # crossed inside the star of v: left whole
        j = k + 1
    return chain


def _polyline_distance(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Distance from points X (k, 3) to the polyline P (n, 3)."""
    a, d = P[:-1], P[1:] - P[:-1]
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    t = np.clip(np.einsum("kij,ij->ki", X[:, None] - a[None], d) / dd, 0.0, 1.0)
    return np.linalg.norm(X[:, None] - (a[None] + t[..., None] * d[None]), axis=2).min(axis=1)


def _vertex_runs(mesh: TetMesh, inner: np.ndarray, seq: list, polyline: np.ndarray, routed: set,
                 boundary_ok: tuple, keep: np.ndarray) -> dict:
    """Where the chain goes through a vertex of the field's mesh instead of
    piercing the faces around it: {first crossed tet j: (vertex v, last tet
    k)}, the tets inner[j..k] all holding v.  A vertex qualifies when the
    curve passes within VERTEX_ROUTE of an edge length of it, it is inside
    the solid (or the curve ends at it on the surface), no other chain goes
    through it and ``keep`` (a mask over the vertices: those of faces other
    curves pierce, ``_piercing_curves``) does not hold it."""
    T, X = mesh.tets, mesh.vertices
    n = len(inner)
    V = T[inner]
    d = _polyline_distance(polyline, X[V.reshape(-1)]).reshape(n, 4)
    E = X[V[:, [0, 0, 0, 1, 1, 2]]] - X[V[:, [1, 2, 3, 2, 3, 3]]]
    h = np.linalg.norm(E, axis=2).mean(axis=1)
    onb = mesh.is_boundary_vertex
    Fv = mesh.faces
    runs, used, j = {}, set(), 0
    while j < n:
        best = None
        for c in range(4):
            v = int(V[j, c])
            if d[j, c] > VERTEX_ROUTE * h[j] or v in routed or v in used or keep[v]:
                continue
            if j > 0 and v in V[j - 1]:
                continue  # the block of tets around v starts earlier
            k = j
            while k + 1 < n and v in V[k + 1]:
                k += 1
            at_start = j == 0 and v in Fv[seq[0]]
            at_end = k == n - 1 and v in Fv[seq[n]]
            if onb[v] and not ((at_start and boundary_ok[0]) or (at_end and boundary_ok[1])):
                continue  # a singular curve must not touch the surface on its way
            if best is None or d[j, c] < best[0]:
                best = (d[j, c], v, k)
        if best is None:
            j += 1
            continue
        _, v, k = best
        runs[j] = (v, k)
        used.add(v)
        j = k + 1
    return runs


def _end_point(mesh: TetMesh, f: int, polyline: np.ndarray) -> np.ndarray:
    """Where the polyline's last segment crosses boundary face f's plane."""
    a, bb, c = mesh.vertices[mesh.faces[f]]
    n = np.cross(bb - a, c - a)
    p, q = polyline[-2], polyline[-1]
    den = float(n @ (q - p))
    s = float(n @ (a - p)) / den if abs(den) > 1e-300 else 1.0
    return p + np.clip(s, 0.0, 1.0) * (q - p)


def _build(mesh: TetMesh, b: _Builder, balls, node_vertex, chains, X, routed: set) -> CurveEdgeMesh:
    """The split mesh from the splits b recorded (module docs)."""
    T, tf, ft = mesh.tets, mesh.tet_faces, mesh.face_tets
    nV = mesh.n_vertices
    P = np.vstack([X, np.array(b.points).reshape(-1, 3)])
    in_ball = np.zeros(mesh.n_tets, bool)
    for ball in balls:
        in_ball[ball] = True
    new_tets, parent = _split_crossed(mesh, b)
    crossed = np.zeros(mesh.n_tets, bool)
    crossed[list(b.tet_splits)] = True
    if np.any(crossed & in_ball):
        raise CurveEdgeError("internal: a crossed tet lies in a node ball")
    shell_points, cone_src = _cone_balls(mesh, b, balls, node_vertex, chains, P, new_tets, parent)
    # the rest: unchanged; split faces must belong to crossed tets or node skins
    kept = [t for t, sp in b.tet_splits.items() if sp[0][0] is None and sp[0][1] is None]
    if kept and np.isin(tf[kept], list(b.face_point)).any():
        raise CurveEdgeError("internal: a tet left whole around a curve's vertex has a split face")
    keep = np.nonzero(~crossed & ~in_ball)[0]
    for f in b.face_point:
        for t in ft[f]:
            if t >= 0 and not crossed[t] and not in_ball[t]:
                c = b.face_curve[f]
                x = X[mesh.faces[f]].mean(axis=0)
                raise CurveEdgeError(
                    f"curve {b.labels[c]} ends or turns inside a tet near ({x[0]:.4g}, {x[1]:.4g}, {x[2]:.4g}) "
                    "in a way the local splits cannot follow; solve the field on a finer mesh")
    if shell_points:
        P = np.vstack([P, np.array(shell_points)])
    NT = np.array(new_tets, dtype=np.int64).reshape(-1, 4)
    neg = TetMesh._signed_volumes(P, NT) < 0
    NT[neg] = NT[neg][:, [1, 0, 2, 3]]
    Tn = np.vstack([T[keep], NT])
    par = np.r_[keep, np.array(parent, dtype=np.int64)]
    # the field-mesh vertices each tet takes its frame from: its own, or for
    # a node ball's tets those of the skin triangle it stands on
    fsrc = np.where(Tn < nV, Tn, -1)
    for i, sv in cone_src:
        fsrc[len(keep) + i] = np.r_[sv, -1]
    # a vertex a chain goes through has no frame of its own (the field turns
    # around it): the tets around it take theirs from their other vertices
    if routed:
        fsrc[np.isin(fsrc, list(routed))] = -1
        if np.any((fsrc < 0).all(axis=1)):
            raise CurveEdgeError("internal: a tet around a curve's vertex has no other vertex to take a frame from")
    # drop the vertices the cones removed and renumber
    used = np.zeros(len(P), bool)
    used[Tn.reshape(-1)] = True
    new_id = np.cumsum(used) - 1
    source = np.r_[np.arange(nV), np.full(len(P) - nV, -1)][used]
    vol = TetMesh._signed_volumes(P, Tn)
    if np.any(vol <= 0):
        raise CurveEdgeError(f"internal: {int(np.sum(vol <= 0))} split tets are not positive")
    out_mesh = TetMesh(P[used], new_id[Tn])
    for ch in chains:
        ch.vertices = new_id[ch.vertices]
    stats = {"split_faces": len(b.face_point), "crossed_tets": int(crossed.sum()),
             "cone_tets": int(sum(len(x) for x in balls)), "removed_vertices": int(nV - used[:nV].sum()),
             "tets": out_mesh.n_tets, "routed_vertices": len(routed),
             "min_volume_ratio": float(np.min(vol / TetMesh._signed_volumes(X, T)[par]))}
    return CurveEdgeMesh(out_mesh, source, par, chains, new_id[node_vertex], stats, fsrc)


def _split_crossed(mesh: TetMesh, b: _Builder):
    """The children of every crossed tet: five (entry and exit faces split),
    three where the chain enters or leaves through a vertex, the tet itself
    between two; (tets, parents)."""
    T, tf, X = mesh.tets, mesh.tet_faces, mesh.vertices
    new_tets, parent = [], []
    for t, splits in b.tet_splits.items():
        if len(splits) != 1:
            curves = sorted({b.labels[c] for *_, c in splits if c >= 0})
            x = X[T[t]].mean(axis=0)
            raise CurveEdgeError(
                f"curve(s) {', '.join(curves)} cross one tet of the field's mesh {len(splits)} times near "
                f"({x[0]:.4g}, {x[1]:.4g}, {x[2]:.4g}); solve the field on a finer mesh (a smaller edge length)")
        f_in, f_out, _ = splits[0]
        if f_in is None and f_out is None:
            new_tets.append(T[t].copy())
            parent.append(t)
            continue
        if f_in is None or f_out is None:
            f = f_in if f_out is None else f_out
            l1 = _tet_face_local(T, tf, t, int(f))
            p = b.face_point[int(f)]
            for i in range(4):
                if i != l1:
                    child = T[t].copy()
                    child[i] = p
                    new_tets.append(child)
                    parent.append(t)
            continue
        l1, l2 = _tet_face_local(T, tf, t, int(f_in)), _tet_face_local(T, tf, t, int(f_out))
        p, q = b.face_point[int(f_in)], b.face_point[int(f_out)]
        for i in range(4):
            if i not in (l1, l2):
                child = T[t].copy()
                child[i] = p
                new_tets.append(child)
        half = T[t].copy()
        half[l2] = p
        for i in range(4):
            if i != l2:
                child = half.copy()
                child[i] = q
                new_tets.append(child)
        parent += [t] * 5
    return new_tets, parent


def _cone_balls(mesh: TetMesh, b: _Builder, balls, node_vertex, chains, P, new_tets: list, parent: list):
    """Each node's ball as a cone from the node over its skin (split skin
    faces in three), in shells so that the map has vertices inside the ball;
    appends to new_tets / parent, extends the chains from the node through
    the shells.  Returns (the shells' points, (new tet index, the skin
    triangle's field-mesh vertices) per cone tet)."""
    T, tf, ft = mesh.tets, mesh.tet_faces, mesh.face_tets
    nV = mesh.n_vertices
    shell_points: list[np.ndarray] = []
    cone_src = []
    for k, ball in enumerate(balls):
        inside = np.zeros(mesh.n_tets, bool)
        inside[ball] = True
        tets, local, faces, _ = _skin(T, tf, ft, ball, inside)
        hit = [int(f) for f in faces if int(f) in b.face_point]
        if len(set(hit)) != len(hit):
            raise CurveEdgeError(f"internal: a skin face of node {k} is split twice")
        tris, owner = [], []
        for t, l, f in zip(tets, local, faces):
            tri = T[t][TET_FACES[l]]
            if int(f) in b.face_point:
                for i in range(3):
                    sub = tri.copy()
                    sub[i] = b.face_point[int(f)]
                    tris.append(sub)
                    owner.append(t)
            else:
                tris.append(tri)
                owner.append(t)
        tris = np.array(tris, dtype=np.int64)
        apex = int(node_vertex[k])
        skin_v = np.unique(tris)
        R = float(np.mean(np.linalg.norm(P[skin_v] - P[apex], axis=1)))
        e = np.r_[tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]
        hs = float(np.mean(np.linalg.norm(P[e[:, 0]] - P[e[:, 1]], axis=1)))
        n_sh = int(max(1, min(6, round(R / max(hs, 1e-300)))))
        # shell j (1..n_sh-1) of skin vertex v at N + (v - N) j / n_sh
        base = len(P) + len(shell_points)
        layer = {n_sh: {int(v): int(v) for v in skin_v}}
        for j in range(1, n_sh):
            layer[j] = {int(v): base + (j - 1) * len(skin_v) + i for i, v in enumerate(skin_v.tolist())}
            shell_points.extend(P[apex] + (P[skin_v] - P[apex]) * (j / n_sh))
        for tri, t, sv in zip(tris, owner, np.where(tris < nV, tris, -1)):
            a, bb, c = (int(x) for x in tri)
            inner = [layer[1][a], layer[1][bb], layer[1][c]] if n_sh > 1 else [a, bb, c]
            new_tets.append(np.array([apex, *inner]))
            parent.append(t)
            cone_src.append((len(new_tets) - 1, sv))
            for j in range(1, n_sh):
                lo = [layer[j][a], layer[j][bb], layer[j][c]]
                hi = [layer[j + 1][a], layer[j + 1][bb], layer[j + 1][c]]
                for tet in _prism_tets(lo, hi):
                    new_tets.append(np.array(tet))
                    parent.append(t)
                    cone_src.append((len(new_tets) - 1, sv))
        # the curves from this node: through the shells to their skin points
        for ch in chains:
            for end in (0, -1):
                if ch.vertices[end] != apex or len(ch.vertices) < 2:
                    continue
                q = int(ch.vertices[1 if end == 0 else -2])
                mids = [layer[j][q] for j in range(1, n_sh)]
                v = ch.vertices.tolist()
                v = [apex, *mids, *v[1:]] if end == 0 else [*v[:-1], *mids[::-1], apex]
                ch.vertices = np.array(v, dtype=np.int64)
    return shell_points, cone_src


def split_edges(cem: CurveEdgeMesh, edges: np.ndarray) -> CurveEdgeMesh:
    """Split each edge (k, 2) of cem.mesh at its midpoint (every tet around it
    in two).  The new vertices are inserted points (source -1); chains and
    nodes keep their vertex ids.  Edges that share no tet are split together
    (vectorised rounds: in each, an edge goes when it is the first remaining
    edge of every tet around it): the same tets as splitting them one after
    another in the order given, up to the numbering of the new vertices."""
    E = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    V = cem.mesh.vertices
    parent = cem.parent.copy()
    Tcur = cem.mesh.tets.copy()
    fs = cem.frame_sources.copy()
    new_points: list[np.ndarray] = []
    pending = np.arange(len(E))
    loc = np.array([(i, j) for i in range(4) for j in range(i + 1, 4)])
    while len(pending):
        lo, hi = np.minimum(E[pending, 0], E[pending, 1]), np.maximum(E[pending, 0], E[pending, 1])
        base = int(max(Tcur.max(), hi.max())) + 1
        want = lo * base + hi
        order = np.argsort(want, kind="stable")  # of equal edges, the first given is the one split
        a, b = Tcur[:, loc[:, 0]], Tcur[:, loc[:, 1]]
        key = np.minimum(a, b) * base + np.maximum(a, b)  # (#T, 6)
        pos = np.clip(np.searchsorted(want[order], key), 0, len(want) - 1)
        hit = want[order][pos] == key
        t, _ = np.nonzero(hit)
        j = order[pos[hit]]  # index into pending of the edge tet t holds
        if not len(t):
            break  # no remaining edge has a tet around it
        first = np.full(len(Tcur), len(pending))
        np.minimum.at(first, t, j)
        ok = np.ones(len(pending), bool)
        ok[j[first[t] != j]] = False  # wait: a tet around it holds an earlier edge
        held = np.zeros(len(pending), bool)
        held[j] = True
        go = ok & held
        # new vertices in the order of the edges
        m = np.full(len(pending), -1)
        Vall = np.vstack([V] + new_points) if new_points else V
        m[go] = len(Vall) + np.arange(int(go.sum()))
        ea, eb = E[pending[go], 0], E[pending[go], 1]
        new_points.append(0.5 * (Vall[ea] + Vall[eb]))
        split = go[j] & (first[t] == j)
        ts, js = t[split], j[split]
        rows = Tcur[ts]
        ga, gb, gm = E[pending[js], 0][:, None], E[pending[js], 1][:, None], m[js][:, None]
        c1 = np.where(rows == ga, gm, rows)
        c2 = np.where(rows == gb, gm, rows)
        keep = np.ones(len(Tcur), bool)
        keep[ts] = False
        Tcur = np.vstack([Tcur[keep], c1, c2])
        parent = np.r_[parent[keep], parent[ts], parent[ts]]
        fs = np.vstack([fs[keep], fs[ts], fs[ts]])
        pending = pending[~go & held]
    extra = np.vstack(new_points) if new_points else np.zeros((0, 3))
    if not len(extra):
        return cem
    V = np.vstack([V, extra])
    vol = TetMesh._signed_volumes(V, Tcur)
    if np.any(vol <= 0):
        raise CurveEdgeError("internal: an edge split made a tet that is not positive")
    mesh = TetMesh(V, Tcur)
    source = np.r_[cem.source_vertex, np.full(len(extra), -1)]
    stats = dict(cem.stats)
    stats["split_edges"] = stats.get("split_edges", 0) + len(extra)
    stats["tets"] = mesh.n_tets
    return CurveEdgeMesh(mesh, source, parent, cem.chains, cem.node_vertices, stats, fs)


def _prism_tets(lo: list, hi: list) -> list:
    """Three tets filling the prism lo (a, b, c) -> hi (A, B, C), its quad
    sides cut by the diagonal from their smallest vertex id, so that
    neighbouring prisms agree (Dompierre et al. 1999)."""
    v = list(lo) + list(hi)  # 0 1 2 | 3 4 5, vertical edges i -> i + 3
    m = int(np.argmin(v))
    # rotate so that the smallest vertex is v0 (bottom) or V0 (top, mirrored)
    r = m % 3
    bottom = [lo[(r + i) % 3] for i in range(3)]
    top = [hi[(r + i) % 3] for i in range(3)]
    if m >= 3:
        bottom, top = top, bottom
    v0, v1, v2 = bottom
    V0, V1, V2 = top
    if min(v1, V2) < min(v2, V1):
        return [(v0, v1, v2, V2), (v0, v1, V2, V1), (v0, V1, V2, V0)]
    return [(v0, v1, v2, V1), (v0, V1, v2, V2), (v0, V1, V2, V0)]
