"""Embedding the curve network in an arbitrary tet mesh ("dual paths").

Design choice (docs/how-it-works.md, *Embedding the network*).  The paper sweeps a prism tube along each
curve and asks TetGen to conform to it; that sweeping self-intersects on
complicated networks (§6).  fTetWild does not keep a prescribed tet structure
anyway, so we never build tubes.  Instead each curve is traced through the
finished mesh as a walk from tet to tet:

* the faces it pierces play the role of the tube cross-sections S2^A and carry
  the curvature Omega_f = 2 pi sigma T (T the curve tangent, §4.2.2), signed
  along the face normal the way the walk crosses the face;
* the tets it crosses form its tube; their interior edges carry the
  curve-adaptation constraints (Eq. 21/22) -- the analogue of S1 -- with T
  and the reference frame taken at the nearest point of the curve;
* a node is a small ball of tets around it (the paper joins tubes with one
  tet); its faces carry no structure equation (like S2^B): the field has a
  point singularity there, with O(1) rotations across every ring of faces,
  which the second-order equation cannot represent.

Nothing can self-intersect, any curve shape and any node geometry work, and
the mesh resolution alone controls accuracy.  Degenerate walks (a curve
through a mesh edge or vertex) are resolved by a deterministic perturbation of
the curve far below the mesh size.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..errors import MeshingError, NetworkError
from ..network.network import PreparedNetwork, polyline_tangents
from .tetmesh import TetMesh


@dataclass
class CurveTrace:
    """The walk of one prepared curve through the mesh.

    tets     : (k,) tets visited, in order
    faces    : (k-1,) + ends: interior faces pierced between consecutive tets
    tangents : (len(faces), 3) unit curve tangent at each pierce (vertex tangents interpolated)
    points   : (len(faces), 3) pierce points
    start_face, end_face : boundary face ids where the curve starts / ends
                           (-1 if it starts / ends at a node or is a loop)
    polyline : (n, 3) the (possibly perturbed, boundary-projected) polyline traced
    """

    tets: np.ndarray
    faces: np.ndarray
    tangents: np.ndarray
    points: np.ndarray
    start_face: int
    end_face: int
    polyline: np.ndarray


@dataclass
class Embedding:
    """The network as seen by the tet mesh.

    traces        : one CurveTrace per prepared curve
    node_tets     : (n_nodes,) tet containing each node
    node_region   : per node, array of tets whose faces carry no structure
                    equation
    face_omega    : (#F, 3) prescribed curvature Omega_f in R^3 (Eq. 17)
    face_excluded : (#F,) bool, True for faces left out of R(omega) (Eq. 19)
    pierce_count  : (#F,) number of curve crossings of each face

    The structure equation's Omega_f is face_omega corrected inside the
    curve tubes (field.constraints.tube_curvature).
    """

    traces: list[CurveTrace]
    node_tets: np.ndarray
    node_region: list[np.ndarray]
    face_omega: np.ndarray
    face_excluded: np.ndarray
    pierce_count: np.ndarray
    boundary_end_faces: list = field(default_factory=list)  # (face id, sigma)

    @property
    def node_region_tets(self) -> np.ndarray:
        if not self.node_region:
            return np.zeros(0, dtype=np.int64)
        return np.unique(np.concatenate(self.node_region))

    def prescribed_singular(self) -> np.ndarray:
        """(#F,) bool: the faces where the field must be singular -- a
        structure equation whose Omega_f is not a whole number of turns.
        Faces that only feature curves (sigma = 0) pierce are not among
        them, nor faces two opposite curves pierce."""
        quarters = np.rint(np.linalg.norm(self.face_omega, axis=1) / (0.5 * np.pi)).astype(np.int64)
        return (quarters % 4 != 0) & ~self.face_excluded

    def network_faces(self, mesh: TetMesh) -> np.ndarray:
        """Faces the network passes through: pierced faces, the faces of node
        regions and the boundary faces where curves end."""
        m = self.pierce_count > 0
        nr = self.node_region_tets
        if len(nr):
            m[mesh.tet_faces[nr].reshape(-1)] = True
        for f, _ in self.boundary_end_faces:
            m[f] = True
        return np.nonzero(m)[0]


def _unit(T: np.ndarray) -> np.ndarray:
    return T / np.maximum(np.linalg.norm(T, axis=1, keepdims=True), 1e-300)


class _Degenerate(Exception):
    pass


class TetLocator:
    """Point location in a tet mesh (KD-tree on centroids + barycentric test)."""

    def __init__(self, mesh: TetMesh):
        self.mesh = mesh
        X = mesh.vertices[mesh.tets]
        self.centroids = X.mean(axis=1)
        self.tree = cKDTree(self.centroids)
        # inverse of the barycentric map per tet
        A = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=2)
        # a tet flat to round-off (fTetWild once returned one, volume
        # 2.5e-34, in the coarse mesh of a ~270k-tet ball) has no inverse:
        # it gets the pseudo-inverse (so a walk can still step through it),
        # and locate prefers the neighbours, which hold all its points
        L = np.linalg.norm(A, axis=1).max(axis=1)
        self.flat = np.abs(np.linalg.det(A)) <= 1e-14 * L**3
        self.Ainv = np.empty_like(A)
        self.Ainv[~self.flat] = np.linalg.inv(A[~self.flat])
        if self.flat.any():
            self.Ainv[self.flat] = np.linalg.pinv(A[self.flat])
        self.origin = X[:, 0]

    def barycentric(self, t, p) -> np.ndarray:
        """Barycentric coordinates of point(s) p in tet(s) t."""
        t = np.asarray(t)
        p = np.asarray(p, float)
        y = np.einsum("...ij,...j->...i", self.Ainv[t], p - self.origin[t])
        return np.concatenate([1.0 - y.sum(axis=-1, keepdims=True), y], axis=-1)

    def locate(self, P: np.ndarray, k: int = 24) -> np.ndarray:
        """Tet containing each point (k,3), -1 if none is found (outside)."""
        P = np.atleast_2d(P)
        k = min(k, len(self.centroids))
        _, idx = self.tree.query(P, k=k)
        idx = idx.reshape(len(P), k)
        lam = self.barycentric(idx, P[:, None, :])  # (n, k, 4)
        score = np.where(self.flat[idx], -np.inf, lam.min(axis=2))
        best = np.argmax(score, axis=1)
        ok = score[np.arange(len(P)), best] > -1e-9
        out = np.where(ok, idx[np.arange(len(P)), best], -1)
        # a sliver's centroid can be far from its points: walk from the best guess
        for i in np.nonzero(~ok)[0]:
            out[i] = self.walk(int(idx[i, best[i]]), P[i])
        return out

    def walk(self, t: int, p: np.ndarray, max_steps: int = 100000) -> int:
        """Visibility walk towards p; -1 if it leaves the mesh."""
        tf, ft = self.mesh.tet_faces, self.mesh.face_tets
        for _ in range(max_steps):
            lam = self.barycentric(t, p)
            k = int(np.argmin(lam))
            if lam[k] > -1e-9:
                return t
            f = tf[t, k]
            nb = ft[f, 0] if ft[f, 0] != t else ft[f, 1]
            if nb < 0:
                return -1
            t = int(nb)
        return -1


def _project_to_boundary(mesh: TetMesh, x: np.ndarray):
    """Closest point of the tet boundary to x, and the boundary face id."""
    S = mesh.boundary
    d, f_local, q = S.closest_points(x[None])
    return mesh.boundary_faces[f_local[0]], q[0], d[0]


GRAZING = 0.3  # a last segment closer than acos(0.3) = 73 degrees to the boundary face's normal overshoots along it


def _outward_normal(mesh: TetMesh, f: int) -> np.ndarray:
    """Unit outward normal of boundary face f (a face id of the mesh)."""
    t = mesh.face_tets[f, 0] if mesh.face_tets[f, 0] >= 0 else mesh.face_tets[f, 1]
    a, b, c = mesh.vertices[mesh.faces[f]]
    n = np.cross(b - a, c - a)
    inside = mesh.vertices[mesh.tets[t]].mean(axis=0)
    if n @ (inside - a) > 0:
        n = -n
    return n / max(np.linalg.norm(n), 1e-300)


def trace_curve(mesh: TetMesh, loc: TetLocator, P: np.ndarray, start_tet: int, start_face: int,
                end_at_boundary: bool, label: str, tol: float, strict: bool = True,
                closed: bool = False) -> CurveTrace:
    """Walk the polyline P through the mesh starting in start_tet.

    start_face : boundary face the curve enters through (or -1)
    end_at_boundary : the last segment must leave the mesh through a boundary face
    strict : raise _Degenerate where the walk leaves a tet through (or within
             tol of) an edge; otherwise leave through the first face hit.
             Either face continues a chain of face-adjacent tets, which is
             all the discretisation needs (the curve is moved by < tol).
    """
    tet_faces = mesh.tet_faces
    face_tets = mesh.face_tets
    t = int(start_tet)
    entry = int(start_face)
    p = P[0].copy()
    tets = [t]
    faces, tangents, points = [], [], []
    end_face = -1
    nseg = len(P) - 1
    max_steps = 50 * mesh.n_tets + 1000
    # the tangent at a pierce is the curve's smooth tangent there (vertex
    # tangents interpolated, as for the tube edges' T_e in constraints.py),
    # not its segment's direction: on a curve of curvature k sampled at
    # spacing ds the two differ by ~ k ds / 2, and every degree of error in
    # the axis of Omega_f costs 1.6 degrees of residual on a quarter-turn
    # face, which no field can remove (Eq. 19)
    Tv = polyline_tangents(P, closed) if len(P) > 1 else np.zeros((len(P), 3))
    steps = 0
    for s in range(nseg):
        q = P[s + 1]
        seglen = np.linalg.norm(q - P[s])
        if seglen == 0:
            continue
        last = s == nseg - 1
        while True:
            steps += 1
            if steps > max_steps:
                raise MeshingError(f"curve {label}: tracing through the mesh did not terminate")
            seg = q - p
            l0 = loc.barycentric(t, p)
            l1 = loc.barycentric(t, q)
            # faces we may leave through: those whose coordinate becomes negative
            cand = []
            for k in range(4):
                f = tet_faces[t, k]
                if f == entry:
                    continue
                if l1[k] < -1e-12:
                    den = l0[k] - l1[k]
                    sk = l0[k] / den if den > 0 else 0.0
                    cand.append((max(sk, 0.0), k))
            if not cand:
                break  # q lies in t
            cand.sort()
            s_exit, k = cand[0]
            if strict and len(cand) > 1 and (cand[1][0] - s_exit) * np.linalg.norm(seg) < tol:
                raise _Degenerate()
            x = p + s_exit * seg
            f = int(tet_faces[t, k])
            nb = face_tets[f, 0] if face_tets[f, 0] != t else face_tets[f, 1]
            if nb < 0:
                if last and end_at_boundary:
                    end_face = f
                    break
                raise NetworkError(
                    f"curve {label} leaves the solid near ({x[0]:.4g}, {x[1]:.4g}, {x[2]:.4g}); keep curves "
                    "inside the domain mesh and end them on its boundary or at a node"
                )
            faces.append(f)
            u = min(max(np.linalg.norm(x - P[s]) / seglen, 0.0), 1.0)
            tangents.append((1.0 - u) * Tv[s] + u * Tv[s + 1])
            points.append(x)
            entry = f
            t = int(nb)
            tets.append(t)
            p = x
        if end_face >= 0:
            break
        p = q.copy()
    if end_at_boundary and end_face < 0:
        raise NetworkError(f"curve {label}: its end did not reach the boundary of the mesh")
    return CurveTrace(
        tets=np.array(tets, dtype=np.int64),
        faces=np.array(faces, dtype=np.int64),
        tangents=_unit(np.array(tangents).reshape(-1, 3)),
        points=np.array(points).reshape(-1, 3),
        start_face=int(start_face),
        end_face=int(end_face),
        polyline=P,
    )


def embed_network(mesh: TetMesh, net: PreparedNetwork, node_radius: float, max_attempts: int = 6) -> Embedding:
    """Trace every prepared curve and assemble Omega and the node regions.

    node_radius : tets whose centroid lies this close to a node form its node
    region (faces without a structure equation, no curve constraints).
    """
    loc = TetLocator(mesh)
    h = mesh.mean_edge_length
    rng = np.random.default_rng(12345)
    for attempt in range(max_attempts):
        amp = 0.0 if attempt == 0 else 1e-6 * h * 10 ** attempt
        try:
            return _embed_once(mesh, net, loc, rng, amp, node_radius)
        except _Degenerate:
            continue
    # a curve still meets an edge under every jitter (seen once, on a
    # ~115k-tet fTetWild ball that could not be kept to find out why; flat
    # slivers, whose near-coplanar faces the walk cannot tell apart, are the
    # likely cause): leave through the first face hit, which keeps the chain
    # of tets face-connected
    return _embed_once(mesh, net, loc, rng, 0.0, node_radius, strict=False)


def _embed_once(mesh, net: PreparedNetwork, loc: TetLocator, rng, amp: float, node_radius: float,
                strict: bool = True) -> Embedding:
    h = mesh.mean_edge_length
    tol = 1e-9 * h
    node_pos = [nd.position + (amp * rng.standard_normal(3) if amp else 0.0) for nd in net.nodes]
    node_tets = loc.locate(np.array(node_pos).reshape(-1, 3)) if node_pos else np.zeros(0, int)
    for k, t in enumerate(node_tets):
        if t < 0:
            raise NetworkError(f"node {k} at {np.round(node_pos[k], 4)} lies outside the meshed solid")
    node_of_end = {}
    for k, nd in enumerate(net.nodes):
        for e in nd.ends:
            node_of_end[e] = k
    traces = []
    for ci, c in enumerate(net.curves):
        P = c.points.copy()
        label = f"{ci} '{c.name}'" if c.name else str(ci)
        skind, ekind = net.start_kind[ci], net.end_kind[ci]
        if amp:
            # nodes move with node_pos; loops and boundary ends move here
            movable = np.ones(len(P), bool)
            movable[0] = skind != "node"
            movable[-1] = ekind != "node"
            P[movable] += amp * rng.standard_normal(P[movable].shape)
        if c.closed:
            P[-1] = P[0]
            t0 = loc.locate(P[:1])[0]
            if t0 < 0:
                raise NetworkError(f"closed curve {label} starts outside the meshed solid")
            start_face = -1
        elif skind == "node":
            k = node_of_end[(ci, 0)]
            P[0] = node_pos[k]
            t0 = node_tets[k]
            start_face = -1
        else:
            f, x, _ = _project_to_boundary(mesh, P[0])
            P[0] = x
            t0 = mesh.face_tets[f, 0]
            start_face = f
        if ekind == "node":
            P[-1] = node_pos[node_of_end[(ci, 1)]]
        elif ekind == "boundary":
            f, x, _ = _project_to_boundary(mesh, P[-1])
            # overshoot slightly so the walk leaves through the boundary:
            # along the last segment, or, where it grazes the boundary face,
            # along the face's outward normal (a grazing overshoot can stay
            # inside, and the walk then ends short of the boundary)
            d = x - P[-2]
            d /= max(np.linalg.norm(d), 1e-300)
            n = _outward_normal(mesh, f)
            if d @ n < GRAZING:
                d = n
            P[-1] = x + 1e-3 * h * d
        tr = trace_curve(mesh, loc, P, t0, start_face, ekind == "boundary", label, tol, strict, c.closed)
        if c.closed and tr.tets[-1] != tr.tets[0]:
            if strict:
                # its start (and end) within rounding of a face of its start
                # tet: the walk came back to the neighbour; jitter and retry
                raise _Degenerate()
            raise MeshingError(f"closed curve {label} did not return to its start tet")
        traces.append(tr)
    return _assemble(mesh, net, traces, node_tets, node_radius)


def _assemble(mesh: TetMesh, net: PreparedNetwork, traces, node_tets, node_radius: float) -> Embedding:
    nF = mesh.n_faces
    omega = np.zeros((nF, 3))
    count = np.zeros(nF, dtype=np.int64)
    n = mesh.face_normals
    cen = mesh.vertices[mesh.tets].mean(axis=1)
    for c, tr in zip(net.curves, traces):
        if len(tr.faces) == 0:
            continue
        # Omega_f = 2 pi sigma T, oriented along the face normal (§4.2.2).
        # Which way the curve crosses face k is which way the walk goes,
        # from tets[k] into tets[k + 1] (their centroids lie strictly on
        # either side), not the sign of n . T: where the curve grazes a
        # face, T (interpolated between vertex tangents) can lie in the
        # face's plane or just past it, and that sign then flipped the
        # quarter turn (a radial curve of the cube-sphere network through
        # a face at 0.000 of the normal: penalty 4.5e3, 1 run in 3)
        cross = cen[tr.tets[1:len(tr.faces) + 1]] - cen[tr.tets[:len(tr.faces)]]
        s = np.where(np.einsum("ij,ij->i", n[tr.faces], cross) >= 0.0, 1.0, -1.0)
        np.add.at(omega, tr.faces, 2 * np.pi * c.sigma * s[:, None] * tr.tangents)
        np.add.at(count, tr.faces, 1)
    # node regions (§2.1.1 joins tubes at one tet; see the module docstring):
    # the tets within node_radius of the node, the tet containing it, and any
    # tet two of its curves still share on their way out.  A node is a point
    # singularity: the field turns by O(1) across every ring of faces around
    # it, at any scale, so the second-order structure equation cannot hold
    # there and is left out.
    regions = []
    for k, nd in enumerate(net.nodes):
        ball = np.nonzero(np.linalg.norm(cen - nd.position, axis=1) < node_radius)[0]
        region = set(ball.tolist()) | {int(node_tets[k])}
        seqs = []
        for ci, s in nd.ends:
            tets = traces[ci].tets
            seqs.append(set((tets if s == 0 else tets[::-1]).tolist()))
        for a in range(len(seqs)):
            for b in range(a + 1, len(seqs)):
                region |= {t for t in seqs[a] & seqs[b] if np.linalg.norm(cen[t] - nd.position) < 3 * node_radius}
        regions.append(np.array(sorted(region), dtype=np.int64))
    excluded = mesh.is_boundary_face.copy()
    for r in regions:
        excluded[mesh.tet_faces[r].reshape(-1)] = True
    ends = []
    for c, tr in zip(net.curves, traces):
        for f in (tr.start_face, tr.end_face):
            if f >= 0:
                ends.append((int(f), c.sigma))
    return Embedding(traces, np.asarray(node_tets, dtype=np.int64), regions, omega, excluded, count, ends)
