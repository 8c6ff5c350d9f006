"""Sharp features on a boundary surface (§3.3, Fig. 11).

The feature graph is read as the skeleton of an axis-aligned surface: around
each feature vertex the sectors between consecutive feature edges get a
quantised angle k * pi/2 (k >= 1), and the angle defect of that axis-aligned
surface, 2 pi - sum k pi/2, is a boundary singularity of index
``1 - sum(k) / 4`` (a cube corner: 1/4).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from ..errors import TopologyError
from .trisurface import TriSurface


def corner_fan_links(S: TriSurface) -> np.ndarray:
    """For each corner c = (f, k) (flattened 3f + k), the corner at the same
    vertex in the face across the edge (F[f,k] -> F[f,k+1]); i.e. the next
    corner clockwise around the vertex seen from outside."""
    F = S.F
    n = len(S.V)
    in_keys = (np.roll(F, 1, axis=1).astype(np.int64) * n + F).reshape(-1)
    rev = (np.roll(F, -1, axis=1).astype(np.int64) * n + F).reshape(-1)
    order = np.argsort(in_keys)
    pos = np.searchsorted(in_keys[order], rev)
    return order[pos]


@dataclass
class FeatureGraph:
    """Sharp edges of a TriSurface and what they imply for the cross field.

    S     : the surface
    sharp : (#E,) bool mask over S.edges
    quarters : optional (#sectors,) k per sector, chosen by corners.py
               (ambiguous corners, Network.corner_turns); None: rounded
    """

    S: TriSurface
    sharp: np.ndarray
    quarters: np.ndarray | None = None

    @cached_property
    def degree(self) -> np.ndarray:
        """Number of sharp edges at each vertex."""
        return np.bincount(self.S.edges[self.sharp].reshape(-1), minlength=len(self.S.V))

    @cached_property
    def sectors(self) -> tuple[int, np.ndarray]:
        """Label of the sector of each corner: corners around a vertex connected
        without crossing a sharp edge."""
        S = self.S
        nC = 3 * len(S.F)
        nxt = corner_fan_links(S)
        # the edge crossed going from corner c to nxt[c] is F[f,k] -> F[f,k+1]
        cross_edge = S.face_edges.reshape(-1)
        keep = ~self.sharp[cross_edge]
        c = np.arange(nC)[keep]
        A = sp.coo_matrix((np.ones(len(c)), (c, nxt[keep])), shape=(nC, nC))
        return csgraph.connected_components(A, directed=False)

    @cached_property
    def sector_angle(self) -> np.ndarray:
        """Real angle of each sector (sum of its corner angles)."""
        ns, lab = self.sectors
        return np.bincount(lab, weights=self.S.corner_angles.reshape(-1), minlength=ns)

    @cached_property
    def sector_vertex(self) -> np.ndarray:
        ns, lab = self.sectors
        out = np.empty(ns, dtype=np.int64)
        out[lab] = self.S.F.reshape(-1)
        return out

    @cached_property
    def sector_quarters(self) -> np.ndarray:
        """Quantised sector angle in quarter turns, k >= 1 (only meaningful at
        feature vertices)."""
        if self.quarters is not None:
            return np.asarray(self.quarters, dtype=int)
        return np.maximum(1, np.round(self.sector_angle / (np.pi / 2))).astype(int)

    @cached_property
    def vertex_index(self) -> np.ndarray:
        """Index of the axis-aligned angle defect at each vertex: 1 - sum k / 4
        at feature vertices, 0 elsewhere."""
        ns, _ = self.sectors
        sv = self.sector_vertex
        ksum = np.bincount(sv, weights=self.sector_quarters, minlength=len(self.S.V))
        idx = 1.0 - ksum / 4.0
        idx[self.degree == 0] = 0.0
        return idx

    @cached_property
    def corners(self) -> np.ndarray:
        """Feature vertices whose axis-aligned defect is nonzero."""
        return np.nonzero((self.degree > 0) & (np.abs(self.vertex_index) > 1e-9))[0]

    @cached_property
    def is_regular_feature_vertex(self) -> np.ndarray:
        """Feature vertices where a frame can follow every sharp edge."""
        m = self.degree > 0
        m[self.corners] = False
        return m

    @cached_property
    def patches(self) -> tuple[int, np.ndarray]:
        """Faces connected without crossing sharp edges."""
        S = self.S
        ef = S.edge_faces
        keep = ~self.sharp
        n = len(S.F)
        A = sp.coo_matrix((np.ones(keep.sum()), (ef[keep, 0], ef[keep, 1])), shape=(n, n))
        return csgraph.connected_components(A, directed=False)

    def corner_faces(self) -> np.ndarray:
        """One incident triangle per corner vertex, which carries its index as
        a singular triangle (Fig. 11)."""
        F = self.S.F
        first = np.full(len(self.S.V), -1)
        fl = np.repeat(np.arange(len(F)), 3)[::-1]
        first[F.reshape(-1)[::-1]] = fl
        return first[self.corners]

    def check_patches(self, face_sigma: np.ndarray, names=None) -> None:
        """Per-patch Poincare-Hopf for fields aligned with the sharp edges.

        For each patch P (cut open along sharp edges):
            sum of singularity indices inside P + sum over its feature sectors
            of (2 - k)/4  ==  chi(P).
        face_sigma : (#F,) index of the singularities carried by each face
        (curve ends).  Raises TopologyError naming the patch.
        """
        S = self.S
        npch, plab = self.patches
        ns, slab = self.sectors
        F_P = np.bincount(plab, minlength=npch)
        sec_patch = np.empty(ns, dtype=np.int64)
        sec_patch[slab] = np.repeat(plab, 3)
        V_P = np.bincount(sec_patch, minlength=npch)
        ef = S.edge_faces
        E_P = np.bincount(plab[ef[:, 0]], minlength=npch) + np.bincount(
            plab[ef[self.sharp, 1]], minlength=npch
        )
        chi = V_P - E_P + F_P
        feat_sec = self.degree[self.sector_vertex] > 0
        contrib = np.where(feat_sec, (2 - self.sector_quarters) / 4.0, 0.0)
        corner_sum = np.bincount(sec_patch, weights=contrib, minlength=npch)
        sing = np.bincount(plab, weights=face_sigma, minlength=npch)
        bad = np.nonzero(np.abs(sing + corner_sum - chi) > 1e-6)[0]
        if len(bad):
            p = bad[0]
            f = np.nonzero(plab == p)[0]
            c = S.V[S.F[f]].reshape(-1, 3).mean(axis=0)
            need = chi[p] - corner_sum[p]
            raise TopologyError(
                f"the sharp features around the surface patch near ({c[0]:.3g}, {c[1]:.3g}, {c[2]:.3g}) "
                f"({len(f)} triangles) need singularities of total index {need:g} inside the patch, but the "
                f"curves ending there sum to {sing[p]:g}; add or move singular curves so that they end in "
                "this patch, or change the sharp edges"
            )


def sharp_edges_by_angle(S: TriSurface, angle_deg: float) -> np.ndarray:
    return S.dihedral_angles > np.radians(angle_deg)


def sharp_edges_from_pairs(S: TriSurface, pairs: np.ndarray) -> np.ndarray:
    """Mask of surface edges given as vertex pairs; raises if a pair is not an edge."""
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    n = len(S.V)
    keys = S.edges[:, 0] * n + S.edges[:, 1]
    q = np.minimum(pairs[:, 0], pairs[:, 1]) * n + np.maximum(pairs[:, 0], pairs[:, 1])
    pos = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
    bad = keys[pos] != q
    if np.any(bad):
        i, j = pairs[np.nonzero(bad)[0][0]]
        raise TopologyError(f"marked sharp edge ({i}, {j}) is not an edge of the surface")
    m = np.zeros(len(S.edges), bool)
    m[pos] = True
    return m


def surface_graph(S: TriSurface, weights=None) -> sp.csr_matrix:
    E = S.edges
    n = len(S.V)
    w = np.linalg.norm(S.V[E[:, 1]] - S.V[E[:, 0]], axis=1) if weights is None else weights
    return sp.coo_matrix((np.r_[w, w], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(n, n)).tocsr()


def polyline_to_edges(S: TriSurface, P: np.ndarray, closed: bool, crease: np.ndarray | None = None) -> np.ndarray:
    """Surface edges approximating a polyline lying on S.

    Shortest paths between the vertices nearest the polyline's points; an
    edge costs its length, inflated by its distance from the polyline and
    deflated when it lies on a crease (``crease`` mask), so paths follow the
    remeshed sharp edge rather than cutting across chamfers.
    """
    E = S.edges
    le = np.linalg.norm(S.V[E[:, 1]] - S.V[E[:, 0]], axis=1)
    # route between the polyline's ends only (intermediate waypoints would add
    # spurs wherever their nearest vertex is off the crease), snapping each
    # end to a nearby crease vertex when there is one
    ends = P[[0, -1]] if not closed else P[[0, len(P) // 3, 2 * len(P) // 3, 0]]
    _, vid = cKDTree(S.V).query(ends)
    if crease is not None and np.any(crease):
        cv = np.unique(E[crease])
        d, j = cKDTree(S.V[cv]).query(ends)
        vid = np.where(d < 0.5 * le.mean(), cv[j], vid)
    dense = cKDTree(_densify(P, closed, le.mean() / 4))
    d = np.maximum.reduce([dense.query(S.V[E[:, 0]])[0], dense.query(S.V[E[:, 1]])[0],
                           dense.query(0.5 * (S.V[E[:, 0]] + S.V[E[:, 1]]))[0]])
    cost = le * (1.0 + 50.0 * (d / le.mean()) ** 2)
    if crease is not None:
        cost = np.where(crease, 0.05 * cost, cost)
    G = surface_graph(S, cost + 1e-12)
    mask = np.zeros(len(E), bool)
    n = len(S.V)
    keys = E[:, 0] * n + E[:, 1]
    for a, b in zip(vid[:-1], vid[1:]):
        if a == b:
            continue
        _, pred = csgraph.dijkstra(G, indices=a, return_predecessors=True)
        v = b
        while v != a:
            u = pred[v]
            if u < 0:
                raise TopologyError("a sharp feature curve does not lie on the surface")
            mask[np.searchsorted(keys, min(u, v) * n + max(u, v))] = True
            v = u
    return mask


def _densify(P, closed, step):
    pts = [P[0]]
    Q = np.vstack([P, P[:1]]) if closed else P
    for a, b in zip(Q[:-1], Q[1:]):
        k = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        t = np.linspace(0, 1, k + 1)[1:, None]
        pts.append(a + t * (b - a))
    return np.vstack([np.atleast_2d(p) for p in pts])


def feature_polylines(G: FeatureGraph) -> list[tuple[np.ndarray, bool]]:
    """Split the sharp edges into chains between vertices of degree != 2 (and
    corners), and closed loops.  Returns (vertex ids, closed) per chain."""
    S = G.S
    E = S.edges[G.sharp]
    if len(E) == 0:
        return []
    deg = G.degree
    stop = (deg != 2)
    stop[G.corners] = True
    adj = {}
    for a, b in E:
        adj.setdefault(int(a), []).append(int(b))
        adj.setdefault(int(b), []).append(int(a))
    used = set()
    chains = []

    def walk(a, b):
        path = [a, b]
        used.add((min(a, b), max(a, b)))
        while not stop[path[-1]]:
            cur = path[-1]
            nxt = [w for w in adj[cur] if (min(cur, w), max(cur, w)) not in used]
            if not nxt:
                break
            used.add((min(cur, nxt[0]), max(cur, nxt[0])))
            path.append(nxt[0])
            if path[-1] == path[0]:
                break
        return path

    for v in np.nonzero(stop & (deg > 0))[0]:
        for w in adj[int(v)]:
            if (min(v, w), max(v, w)) not in used:
                path = walk(int(v), w)
                chains.append((np.array(path), False))
    for a, b in E:
        if (min(a, b), max(a, b)) not in used:
            path = walk(int(a), int(b))
            chains.append((np.array(path[:-1] if path[-1] == path[0] else path), path[-1] == path[0]))
    return chains


def transfer_features(src: FeatureGraph, dst: TriSurface) -> np.ndarray:
    """Map the sharp edges of src onto the remeshed surface dst.

    Each feature chain of src becomes the cheapest path on dst between the
    dst vertices nearest to its ends, preferring creases of dst (dihedral
    above half the smallest sharp angle of src) close to the chain.
    """
    mask = np.zeros(len(dst.edges), bool)
    if not np.any(src.sharp):
        return mask
    tau = 0.5 * src.S.dihedral_angles[src.sharp].min()
    crease = dst.dihedral_angles > max(tau, np.radians(5.0))
    for verts, closed in feature_polylines(src):
        mask |= polyline_to_edges(dst, src.S.V[verts], closed and len(verts) >= 3, crease)
    return mask


def check_poincare_hopf(S: TriSurface, G: FeatureGraph, face_sigma: np.ndarray, what: str = "surface") -> None:
    """Per boundary component: sum of singular indices (curve ends and sharp
    corners) must equal the Euler characteristic (§3.2)."""
    ncomp, lab = S.face_components
    chi = S.euler_characteristics()
    ends = np.bincount(lab, weights=face_sigma, minlength=ncomp)
    vcomp = np.full(len(S.V), -1)
    vcomp[S.F.reshape(-1)] = np.repeat(lab, 3)
    corner = np.bincount(vcomp[G.corners], weights=G.vertex_index[G.corners], minlength=ncomp) if len(
        G.corners
    ) else np.zeros(ncomp)
    for c in range(ncomp):
        total = ends[c] + corner[c]
        if abs(total - chi[c]) > 1e-6:
            kind = "sphere-like" if chi[c] == 2 else f"genus {int(round((2 - chi[c]) / 2))}"
            raise TopologyError(
                f"Poincare-Hopf is violated on {what} component {c} ({kind}, Euler characteristic {chi[c]}): "
                f"curve ends contribute {ends[c]:g} and sharp corners {corner[c]:g}, total {total:g} != "
                f"{chi[c]}. Add or remove singular curves ending on this component (each end counts its "
                "index sigma), or change the sharp edges"
            )
