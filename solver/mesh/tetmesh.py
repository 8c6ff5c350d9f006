"""The tetrahedral mesh K (§2.1): simplices, incidence, DEC weights.

Notation follows the paper: vertices K0, edges K1, triangles K2, tets K3;
boundary simplices are those of the boundary surface dK.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from ..errors import MeshingError
from ..surface.trisurface import TriSurface, unique_rows

# local vertex pairs of the 6 tet edges, and the opposite pair for each
TET_EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])
TET_EDGE_OPPOSITE = np.array([[2, 3], [1, 3], [1, 2], [0, 3], [0, 2], [0, 1]])
# face k of a tet is the one opposite local vertex k
TET_FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


@dataclass
class TetMesh:
    """A connected, positively oriented tetrahedral mesh.

    vertices : (#V, 3) float array
    tets     : (#T, 4) int array, positive volume
    """

    vertices: np.ndarray
    tets: np.ndarray

    def __post_init__(self):
        self.vertices = np.ascontiguousarray(self.vertices, dtype=float)
        T = np.ascontiguousarray(self.tets, dtype=np.int64)
        vol = self._signed_volumes(self.vertices, T)
        flip = vol < 0
        T[flip] = T[flip][:, [1, 0, 2, 3]]
        self.tets = T

    @staticmethod
    def _signed_volumes(P, T):
        a = P[T[:, 0]]
        return np.einsum("ij,ij->i", np.cross(P[T[:, 1]] - a, P[T[:, 2]] - a), P[T[:, 3]] - a) / 6.0

    # ----------------------------------------------------------------- sizes
    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_edges(self) -> int:
        return len(self.edges)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    @property
    def n_tets(self) -> int:
        return len(self.tets)

    @cached_property
    def tet_volumes(self) -> np.ndarray:
        return self._signed_volumes(self.vertices, self.tets)

    # -------------------------------------------------------------- simplices
    @cached_property
    def _edges(self):
        te = np.sort(self.tets[:, TET_EDGES].reshape(-1, 2), axis=1)
        E, inv, _ = unique_rows(te)
        return E, inv.reshape(-1, 6)

    @property
    def edges(self) -> np.ndarray:
        """(#E, 2) vertex pairs i < j; edge orientation is i -> j."""
        return self._edges[0]

    @property
    def tet_edges(self) -> np.ndarray:
        """(#T, 6) edge ids, in the local order TET_EDGES."""
        return self._edges[1]

    @cached_property
    def _faces(self):
        tf = np.sort(self.tets[:, TET_FACES].reshape(-1, 3), axis=1)
        Fc, inv, cnt = unique_rows(tf)
        return Fc, inv.reshape(-1, 4), cnt

    @property
    def faces(self) -> np.ndarray:
        """(#F, 3) vertex triples a < b < c; orientation a -> b -> c."""
        return self._faces[0]

    @property
    def tet_faces(self) -> np.ndarray:
        """(#T, 4) face ids; face k is opposite local vertex k."""
        return self._faces[1]

    @cached_property
    def face_tets(self) -> np.ndarray:
        """(#F, 2) the tets on either side of each face (-1 on the boundary)."""
        tf = self.tet_faces.reshape(-1)
        tid = np.repeat(np.arange(self.n_tets), 4)
        order = np.argsort(tf, kind="stable")
        tf, tid = tf[order], tid[order]
        out = np.full((self.n_faces, 2), -1, dtype=np.int64)
        first = np.ones(len(tf), bool)
        first[1:] = tf[1:] != tf[:-1]
        out[tf[first], 0] = tid[first]
        out[tf[~first], 1] = tid[~first]
        if len(np.nonzero(~first)[0]) != len(tf) - self.n_faces:
            raise MeshingError("a triangle is shared by more than two tetrahedra")
        return out

    @cached_property
    def _face_edges(self):
        Fc = self.faces
        n = self.n_vertices
        keys = self.edges[:, 0] * n + self.edges[:, 1]
        fe = np.empty((len(Fc), 3), dtype=np.int64)
        for k, (u, v) in enumerate(((0, 1), (1, 2), (0, 2))):
            fe[:, k] = np.searchsorted(keys, Fc[:, u] * n + Fc[:, v])
        return fe

    @property
    def face_edges(self) -> np.ndarray:
        """(#F, 3) edge ids of (ab, bc, ac) for face abc."""
        return self._face_edges

    FACE_EDGE_SIGNS = np.array([1.0, 1.0, -1.0])
    """Orientation of (ab, bc, ac) along the face loop a -> b -> c -> a."""

    # ------------------------------------------------------------- incidence
    @cached_property
    def d0(self) -> sp.csr_matrix:
        """(#E x #V) exterior derivative on 0-forms."""
        nE = self.n_edges
        r = np.repeat(np.arange(nE), 2)
        c = self.edges.reshape(-1)
        v = np.tile([-1.0, 1.0], nE)
        return sp.csr_matrix((v, (r, c)), shape=(nE, self.n_vertices))

    @cached_property
    def d1(self) -> sp.csr_matrix:
        """(#F x #E) exterior derivative on 1-forms: (d omega)_abc = w_ab + w_bc - w_ac."""
        nF = self.n_faces
        r = np.repeat(np.arange(nF), 3)
        c = self.face_edges.reshape(-1)
        v = np.tile(self.FACE_EDGE_SIGNS, nF)
        return sp.csr_matrix((v, (r, c)), shape=(nF, self.n_edges))

    # ---------------------------------------------------------------- geometry
    @cached_property
    def edge_lengths(self) -> np.ndarray:
        P = self.vertices
        return np.linalg.norm(P[self.edges[:, 1]] - P[self.edges[:, 0]], axis=1)

    @cached_property
    def mean_edge_length(self) -> float:
        return float(self.edge_lengths.mean())

    @cached_property
    def face_normals_raw(self) -> np.ndarray:
        P = self.vertices[self.faces]
        return np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])

    @cached_property
    def face_areas(self) -> np.ndarray:
        return 0.5 * np.linalg.norm(self.face_normals_raw, axis=1)

    @cached_property
    def face_normals(self) -> np.ndarray:
        """Unit normals of the oriented faces a -> b -> c."""
        return self.face_normals_raw / (2.0 * self.face_areas[:, None])

    @cached_property
    def cotan_weights(self) -> np.ndarray:
        """Circumcentric dual area over edge length, A_ij / l_ij (§4.1).

        Per tet, edge ij receives l_kl cot(theta_kl) / 6 with theta_kl the
        dihedral angle at the opposite edge kl; the sum is the diagonal DEC
        Hodge star on 1-forms.  Negative on non-Delaunay meshes.
        """
        P = self.vertices
        X = P[self.tets]
        # outward area vectors of the face opposite each local vertex
        N = []
        for a in range(4):
            i, j, k = TET_FACES[a]
            n = 0.5 * np.cross(X[:, j] - X[:, i], X[:, k] - X[:, i])
            s = np.sign(np.einsum("ij,ij->i", n, X[:, i] - X[:, a]))
            N.append(n * s[:, None])
        w = np.zeros(self.n_edges)
        for e, (a, b) in enumerate(TET_EDGES):
            k, l_ = TET_EDGE_OPPOSITE[e]
            na, nb = N[a], N[b]
            cr = np.linalg.norm(np.cross(na, nb), axis=1)
            cot = -np.einsum("ij,ij->i", na, nb) / np.maximum(cr, 1e-300)
            lkl = np.linalg.norm(X[:, k] - X[:, l_], axis=1)
            w += np.bincount(self.tet_edges[:, e], weights=lkl * cot / 6.0, minlength=self.n_edges)
        return w

    @cached_property
    def barycentric_weights(self) -> np.ndarray:
        """Barycentric dual area over edge length: always positive."""
        # each tet gives each of its 6 edges 1/6 of its volume; a 1-form star
        # scales as volume / length^2
        vol = np.repeat(np.abs(self.tet_volumes), 6)
        le = self.edge_lengths[self.tet_edges.reshape(-1)]
        return np.bincount(self.tet_edges.reshape(-1), weights=vol / 6.0 / le**2 * 3.0, minlength=self.n_edges)

    @cached_property
    def dirichlet_weights(self) -> np.ndarray:
        """Edge weights w_ij of the smoothness energy (Eq. 16).

        Circumcentric weights A_ij / l_ij, clipped to [1/4, 4] times the
        (always positive, bounded) barycentric weight of the same edge.
        fTetWild meshes are not Delaunay: ~20% of circumcentric weights are
        negative, which would make the energy indefinite, and slivers give
        weights of 1e13 and more.  On well-shaped tets the two agree to a
        factor ~1.3, so the clip only touches degenerate geometry.
        """
        b = self.barycentric_weights
        return np.clip(self.cotan_weights, 0.25 * b, 4.0 * b)

    @cached_property
    def corner_weights(self) -> np.ndarray:
        """(#F, 3) Voronoi area fractions A_p^{qr} / A_pqr at each face corner
        (the weights of the discrete wedge product, Eq. 18).

        Unsigned circumcentric corner areas, normalised to sum to one, so the
        wedge product stays a convex combination even on obtuse triangles.
        """
        P = self.vertices[self.faces]
        A = np.empty((self.n_faces, 3))
        for p in range(3):
            q, r = (p + 1) % 3, (p + 2) % 3
            # angles at q and r
            def cot(at, u, v):
                x = P[:, u] - P[:, at]
                y = P[:, v] - P[:, at]
                return np.einsum("ij,ij->i", x, y) / np.maximum(np.linalg.norm(np.cross(x, y), axis=1), 1e-300)

            lpq2 = np.sum((P[:, q] - P[:, p]) ** 2, axis=1)
            lpr2 = np.sum((P[:, r] - P[:, p]) ** 2, axis=1)
            A[:, p] = (lpq2 * cot(r, p, q) + lpr2 * cot(q, p, r)) / 8.0
        A = np.abs(A)
        return A / A.sum(axis=1, keepdims=True)

    # ---------------------------------------------------------------- boundary
    @cached_property
    def is_boundary_face(self) -> np.ndarray:
        return self.face_tets[:, 1] < 0

    @cached_property
    def boundary_faces(self) -> np.ndarray:
        return np.nonzero(self.is_boundary_face)[0]

    @cached_property
    def boundary_vertices(self) -> np.ndarray:
        """Global ids of the vertices of dK, sorted."""
        return np.unique(self.faces[self.boundary_faces])

    @cached_property
    def is_boundary_vertex(self) -> np.ndarray:
        m = np.zeros(self.n_vertices, bool)
        m[self.boundary_vertices] = True
        return m

    @cached_property
    def is_boundary_edge(self) -> np.ndarray:
        m = np.zeros(self.n_edges, bool)
        m[self.face_edges[self.boundary_faces].reshape(-1)] = True
        return m

    @cached_property
    def boundary(self) -> TriSurface:
        """dK as a TriSurface on local vertex ids (see boundary_vertices),
        oriented outward."""
        fid = self.boundary_faces
        Fg = self.faces[fid]
        t = self.face_tets[fid, 0]
        # orient outward: the tet's fourth vertex must lie below the face
        P = self.vertices
        opp = self._opposite_vertex(t, Fg)
        n = np.cross(P[Fg[:, 1]] - P[Fg[:, 0]], P[Fg[:, 2]] - P[Fg[:, 0]])
        inward = np.einsum("ij,ij->i", n, P[opp] - P[Fg[:, 0]]) > 0
        Fg = Fg.copy()
        Fg[inward] = Fg[inward][:, [0, 2, 1]]
        local = np.full(self.n_vertices, -1, dtype=np.int64)
        local[self.boundary_vertices] = np.arange(len(self.boundary_vertices))
        return TriSurface(P[self.boundary_vertices], local[Fg])

    def _opposite_vertex(self, t, Fg):
        """The vertex of tet t[k] not on triangle Fg[k]."""
        T = self.tets[t]
        on_face = (T[:, :, None] == Fg[:, None, :]).any(axis=2)
        return T[np.arange(len(T)), np.argmin(on_face, axis=1)]

    def edge_index(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Edge ids of vertex pairs (any order); -1 where no such edge."""
        n = self.n_vertices
        keys = self.edges[:, 0] * n + self.edges[:, 1]
        lo, hi = np.minimum(i, j), np.maximum(i, j)
        q = lo.astype(np.int64) * n + hi
        pos = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
        return np.where(keys[pos] == q, pos, -1)

    def face_index(self, tri: np.ndarray) -> np.ndarray:
        """Face ids of vertex triples (k, 3), any order; -1 where absent."""
        s = np.sort(np.asarray(tri), axis=1).astype(np.int64)
        n = self.n_vertices
        keys = (self.faces[:, 0] * n + self.faces[:, 1]) * n + self.faces[:, 2]
        q = (s[:, 0] * n + s[:, 1]) * n + s[:, 2]
        pos = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
        return np.where(keys[pos] == q, pos, -1)

    @cached_property
    def vertex_adjacency(self) -> sp.csr_matrix:
        E = self.edges
        n = self.n_vertices
        A = sp.coo_matrix((np.ones(2 * len(E)), (E.reshape(-1), E[:, ::-1].reshape(-1))), shape=(n, n))
        return A.tocsr()


def edge_graph(n: int, E: np.ndarray, w: np.ndarray) -> sp.csr_matrix:
    """Symmetric n by n graph of the edges E (k, 2) with weights w (k,)."""
    return sp.coo_matrix((np.r_[w, w], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(n, n)).tocsr()


def shortest_path(G: sp.csr_matrix, a: int, b: int) -> np.ndarray | None:
    """Vertex ids of a shortest path from a to b in the graph G (Dijkstra),
    or None when b cannot be reached."""
    dist, pred = dijkstra(G, indices=a, return_predecessors=True)
    if not np.isfinite(dist[b]):
        return None
    path = [b]
    while path[-1] != a:
        path.append(int(pred[path[-1]]))
    return np.array(path[::-1])
