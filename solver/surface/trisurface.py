"""Triangle-surface topology and checks: closed, manifold, oriented, simple.

Used twice: on the user's input surface (validation before any heavy work)
and on the boundary of the tetrahedral mesh (the domain of the 2D problem).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from ..errors import SurfaceError

# winding numbers of surfaces over this many triangles count far groups of
# about WINDING_GROUP_FACES triangles by their dipole (TriSurface._winding_fast):
# validating the ball's network on an 81,920-triangle sphere spent 11 of
# its 19.5 s in exact winding numbers
FAST_WINDING_FACES = 20_000
WINDING_GROUP_FACES = 64
WINDING_FAR = 3.0


CLOSEST_CHUNK = 65_536
"""Points ``TriSurface.closest_points`` answers at once (its memory is a
few KB per point of a chunk)."""
CLOSEST_PAIRS = 262_144
"""Point-triangle pairs its exhaustive fallback measures at once (~150 MB)."""
SIZE_CLASS_SPREAD = 8.0
SIZE_CLASS_RATIO = 4.0
"""closest_points searches the triangles in classes of radii within a
factor SIZE_CLASS_RATIO where the largest radius exceeds SIZE_CLASS_SPREAD
times the median (TriSurface._size_classes)."""


def unique_rows(a: np.ndarray):
    """np.unique(axis=0) for non-negative int rows of width 2 or 3, in
    lexicographic order, via a combined int64 key (much faster).

    Returns (unique rows, inverse, counts).
    """
    a = np.asarray(a, dtype=np.int64)
    n = int(a.max()) + 1 if a.size else 1
    key = a[:, 0]
    for k in range(1, a.shape[1]):
        key = key * n + a[:, k]
    _, idx, inv, cnt = np.unique(key, return_index=True, return_inverse=True, return_counts=True)
    return a[idx], inv.reshape(-1), cnt


def edge_keys(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    lo = np.minimum(a, b).astype(np.int64)
    hi = np.maximum(a, b).astype(np.int64)
    return lo * n + hi


@dataclass
class TriSurface:
    """A closed oriented triangle surface.

    V : (n, 3) float array of vertex positions
    F : (m, 3) int array, counter-clockwise seen from outside the solid
    """

    V: np.ndarray
    F: np.ndarray

    # ---------------------------------------------------------------- topology
    @cached_property
    def edges(self) -> np.ndarray:
        """(#E, 2) sorted vertex pairs."""
        return self._edge_data[0]

    @cached_property
    def face_edges(self) -> np.ndarray:
        """(#F, 3) edge ids of face edges (F0F1, F1F2, F2F0)."""
        return self._edge_data[1]

    @cached_property
    def face_edge_signs(self) -> np.ndarray:
        """(#F, 3) +1 where the face traverses the edge from low to high id."""
        F = self.F
        nxt = np.roll(F, -1, axis=1)
        return np.where(F < nxt, 1.0, -1.0)

    @cached_property
    def _edge_data(self):
        F = self.F
        a = F.reshape(-1)
        b = np.roll(F, -1, axis=1).reshape(-1)
        keys = edge_keys(a, b, len(self.V))
        uk, inv, cnt = np.unique(keys, return_inverse=True, return_counts=True)
        edges = np.stack([uk // len(self.V), uk % len(self.V)], axis=1)
        return edges, inv.reshape(-1, 3), cnt

    @cached_property
    def _edge_key_sorted(self) -> np.ndarray:
        return edge_keys(self.edges[:, 0], self.edges[:, 1], len(self.V))

    def edge_index(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Edge ids of existing edges between vertices i and j (any order)."""
        return np.searchsorted(self._edge_key_sorted, edge_keys(np.asarray(i), np.asarray(j), len(self.V)))

    @cached_property
    def edge_faces(self) -> np.ndarray:
        """(#E, 2) the two faces of each edge (closed manifold surfaces only)."""
        fe = self.face_edges.reshape(-1)
        order = np.argsort(fe, kind="stable")
        faces = np.repeat(np.arange(len(self.F)), 3)[order]
        return faces.reshape(-1, 2)

    @cached_property
    def face_areas(self) -> np.ndarray:
        return 0.5 * np.linalg.norm(self.face_normals_raw, axis=1)

    @cached_property
    def face_normals_raw(self) -> np.ndarray:
        P = self.V[self.F]
        return np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])

    @cached_property
    def face_normals(self) -> np.ndarray:
        n = self.face_normals_raw
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)

    @cached_property
    def vertex_normals(self) -> np.ndarray:
        """Unit area-weighted vertex normals N_i (§2.1)."""
        N = np.zeros_like(self.V)
        for k in range(3):
            np.add.at(N, self.F[:, k], self.face_normals_raw)
        return N / np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)

    @cached_property
    def corner_angles(self) -> np.ndarray:
        """(#F, 3) interior angle at each corner."""
        P = self.V[self.F]
        out = np.empty(self.F.shape)
        for k in range(3):
            u = P[:, (k + 1) % 3] - P[:, k]
            v = P[:, (k + 2) % 3] - P[:, k]
            out[:, k] = np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.einsum("ij,ij->i", u, v))
        return out

    @cached_property
    def dihedral_angles(self) -> np.ndarray:
        """(#E,) angle in radians between the normals of the two faces of each edge
        (0 = flat)."""
        f0, f1 = self.edge_faces.T
        c = np.einsum("ij,ij->i", self.face_normals[f0], self.face_normals[f1])
        return np.arccos(np.clip(c, -1.0, 1.0))

    @cached_property
    def face_components(self) -> tuple[int, np.ndarray]:
        """Connected components of faces through shared edges."""
        ef = self.edge_faces
        n = len(self.F)
        A = sp.coo_matrix((np.ones(len(ef)), (ef[:, 0], ef[:, 1])), shape=(n, n))
        return csgraph.connected_components(A, directed=False)

    @property
    def n_components(self) -> int:
        return self.face_components[0]

    def component_of_faces(self) -> np.ndarray:
        return self.face_components[1]

    def euler_characteristics(self) -> np.ndarray:
        """Euler characteristic V - E + F of each component."""
        ncomp, lab = self.face_components
        Fc = np.bincount(lab, minlength=ncomp)
        Ec = np.bincount(lab[self.edge_faces[:, 0]], minlength=ncomp)
        vlab = np.full(len(self.V), -1)
        vlab[self.F.reshape(-1)] = np.repeat(lab, 3)
        used = vlab >= 0
        Vc = np.bincount(vlab[used], minlength=ncomp)
        return Vc - Ec + Fc

    def signed_volumes(self) -> np.ndarray:
        """Signed volume enclosed by each component (> 0: outward oriented)."""
        ncomp, lab = self.face_components
        P = self.V[self.F]
        vol = np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])) / 6.0
        return np.bincount(lab, weights=vol, minlength=ncomp)

    @cached_property
    def bbox_diagonal(self) -> float:
        used = self.V[np.unique(self.F)]
        return float(np.linalg.norm(used.max(0) - used.min(0)))

    # ------------------------------------------------------------------ queries
    def winding_number(self, X: np.ndarray, chunk: int = 2_000_000) -> np.ndarray:
        """Generalised winding number of points X (k, 3): ~1 inside, ~0 outside.

        Sum of signed solid angles of all triangles (Van Oosterom-Strackee).
        On surfaces of over FAST_WINDING_FACES triangles, groups of
        triangles far from a point count by their dipole (issue 41e:
        _winding_fast); many points (a dense curve) on a closed surface
        share sums (``_shared_winding``).
        """
        X = np.atleast_2d(np.asarray(X, float))
        if len(X) > 256 and self._closed and np.all(np.isfinite(X)):
            return self._shared_winding(X, chunk)
        return self._winding(X, chunk)

    @cached_property
    def _closed(self) -> bool:
        """Every edge has exactly two faces (the winding number is then an
        integer, constant between the sheets of the surface)."""
        E = np.sort(self.F[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        _, cnt = np.unique(E, axis=0, return_counts=True)
        return bool(len(cnt)) and bool(np.all(cnt == 2))

    def _shared_winding(self, X: np.ndarray, chunk: int, batch: int = 256) -> np.ndarray:
        """The winding number of a closed surface is constant in the ball of
        radius d(x) (the distance to the surface) around x, so it is summed
        over all triangles only at a few representatives, farthest from the
        surface first, in rounds of 1, 2, 4, ... up to ``batch`` of the points
        left, and copied to the points left in their balls: linear in the
        points, not in points x triangles, for a dense curve."""
        r = (1.0 - 1e-9) * self._distance_below(X)
        out = np.full(len(X), np.nan)
        todo = np.argsort(-r, kind="stable")
        tree, ids = cKDTree(X), np.arange(len(X))
        n = 1
        while len(todo):
            reps = todo[:n]
            out[reps] = self._winding(X[reps], chunk)
            balls = tree.query_ball_point(X[reps], r[reps], return_sorted=False)
            size = np.fromiter((len(b) for b in balls), np.int64, len(balls))
            if size.sum():
                inside = ids[np.concatenate([np.asarray(b, np.int64) for b in balls if len(b)])]
                src = np.repeat(reps, size)
                new = np.isnan(out[inside])
                out[inside[new]] = out[src[new]]
            todo = todo[np.isnan(out[todo])]
            if len(todo) < len(ids) // 2:  # search only the points left
                tree, ids = cKDTree(X[todo]), todo.copy()
            n = min(2 * n, batch)
        return out

    def _distance_below(self, X: np.ndarray) -> np.ndarray:
        """A lower bound of the distance from each of X (k, 3) to the surface:
        the closest of the triangles of the 16 nearest centroids, or less
        when a farther triangle may be closer (closest_points without its
        exact per-point fallback)."""
        P, cent, rad, tree = self.face_tree
        kq = min(len(self.F), 16)
        dc, idx = tree.query(X, k=kq)
        dc, idx = dc.reshape(len(X), kq), idx.reshape(len(X), kq)
        best = np.full(len(X), np.inf)
        for j in range(kq):
            best = np.minimum(best, np.linalg.norm(closest_point_on_triangles(X, P[idx[:, j]]) - X, axis=1))
        return np.clip(np.minimum(best, dc[:, -1] - rad.max()), 0.0, None)

    def _winding(self, X: np.ndarray, chunk: int) -> np.ndarray:
        """The winding number summed over all triangles (Van Oosterom-Strackee),
        far groups by their dipole on large surfaces (_winding_fast)."""
        if len(self.F) > FAST_WINDING_FACES and len(X):
            return self._winding_fast(X, chunk)
        return _solid_angle_sum(self.V[self.F], X, chunk)

    @cached_property
    def _winding_groups(self):
        """Triangles grouped by a grid of cells (about WINDING_GROUP_FACES
        per group): (face order, group starts, centres (g, 3), radii (g,),
        dipoles (g, 3): the sum of area x unit normal)."""
        P = self.V[self.F]
        cen = P.mean(axis=1)
        lo, hi = cen.min(axis=0), cen.max(axis=0)
        n_cells = max(1.0, len(self.F) / WINDING_GROUP_FACES)
        # cells of a surface: their number grows like (extent / size)^2
        size = float(np.linalg.norm(hi - lo)) / max(np.sqrt(n_cells), 1.0)
        key = np.floor((cen - lo) / max(size, 1e-300)).astype(np.int64)
        _, lab = np.unique(key, axis=0, return_inverse=True)
        lab = lab.reshape(-1)
        order = np.argsort(lab, kind="stable")
        starts = np.r_[0, np.nonzero(np.diff(lab[order]))[0] + 1, len(order)]
        g = len(starts) - 1
        an = 0.5 * np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])  # area x unit normal
        area = np.linalg.norm(an, axis=1)
        w = np.bincount(lab, weights=area, minlength=g)
        c = np.stack([np.bincount(lab, weights=area * cen[:, k], minlength=g) for k in range(3)], axis=1)
        c /= np.maximum(w, 1e-300)[:, None]
        rad = np.zeros(g)
        np.maximum.at(rad, lab, np.max(np.linalg.norm(P - c[lab][:, None], axis=2), axis=1))
        dip = np.stack([np.bincount(lab, weights=an[:, k], minlength=g) for k in range(3)], axis=1)
        return order, starts, c, rad, dip

    def _winding_fast(self, X: np.ndarray, chunk: int) -> np.ndarray:
        """Winding numbers with far groups as dipoles (Barill et al. 2018,
        "Fast winding numbers for soups and clouds", first order): a group
        whose centre is over WINDING_FAR times its radius from the point
        adds D.(c - x) / (4 pi |c - x|^3); nearer groups count exactly.
        Every use thresholds at 0.5; the first-order error at that distance
        is ~1e-3 of a group's solid angle."""
        order, starts, c, rad, dip = self._winding_groups
        P = self.face_tree[0]
        out = np.zeros(len(X))
        step = max(1, chunk // max(1, len(c)))
        near_pairs = []
        for s in range(0, len(X), step):
            x = X[s : s + step]
            d = c[None] - x[:, None]
            r = np.linalg.norm(d, axis=2)
            far = r > WINDING_FAR * rad[None]
            contrib = np.einsum("kgi,gi->kg", d, dip) / np.maximum(r, 1e-300) ** 3
            out[s : s + step] = np.where(far, contrib, 0.0).sum(axis=1) / (4 * np.pi)
            qi, gi = np.nonzero(~far)
            near_pairs.append((qi + s, gi))
        qi = np.concatenate([q for q, _ in near_pairs]) if near_pairs else np.zeros(0, np.int64)
        gi = np.concatenate([g for _, g in near_pairs]) if near_pairs else np.zeros(0, np.int64)
        if len(qi):
            by = np.argsort(gi, kind="stable")
            qi, gi = qi[by], gi[by]
            cuts = np.r_[0, np.nonzero(np.diff(gi))[0] + 1, len(gi)]
            for a, b in zip(cuts[:-1], cuts[1:]):
                g = gi[a]
                faces = order[starts[g] : starts[g + 1]]
                out[qi[a:b]] += _solid_angle_sum(P[faces], X[qi[a:b]], chunk)
        return out


    @cached_property
    def face_tree(self):
        """(triangle corners, centroids, radii, k-d tree of the centroids)
        for closest_points, built once per surface."""
        P = self.V[self.F]
        cent = P.mean(axis=1)
        rad = np.max(np.linalg.norm(P - cent[:, None], axis=2), axis=1)
        return P, cent, rad, cKDTree(cent)

    @cached_property
    def _size_classes(self):
        """None where the triangles are of about one size; else
        [(face ids, TriSurface of those faces)], the faces grouped by radius
        in classes spanning a factor SIZE_CLASS_RATIO each, for
        closest_points.  (One k-d tree over all centroids must search as far
        as the largest triangle's radius around every point: a dense region
        beside a few large triangles then gave each point tens of thousands
        of candidates.)"""
        rad = self.face_tree[2]
        if not len(rad) or rad.max() <= SIZE_CLASS_SPREAD * max(float(np.median(rad)), 1e-300):
            return None
        lo = max(float(rad[rad > 0].min()) if np.any(rad > 0) else 1.0, 1e-300)
        cls = np.floor(np.log(np.maximum(rad, lo) / lo) / np.log(SIZE_CLASS_RATIO)).astype(np.int64)
        out = []
        for c in np.unique(cls):
            ids = np.nonzero(cls == c)[0]
            out.append((ids, TriSurface(self.V, self.F[ids])))
        return out

    def closest_points(self, X: np.ndarray, within: float | None = None):
        """Closest surface point to each of X (k, 3).

        within: only points at most this far from the surface are wanted;
        the others come back with distance inf, face -1 and point nan, at
        little cost (a dense surface seen from deep inside the solid).

        Returns (distance (k,), face index (k,), closest point (k, 3)).
        """
        X = np.atleast_2d(np.asarray(X, float))
        if len(X) > CLOSEST_CHUNK:  # bounded memory: each point's answer is its own
            parts = [self.closest_points(X[s:s + CLOSEST_CHUNK], within) for s in range(0, len(X), CLOSEST_CHUNK)]
            return tuple(np.concatenate(p) for p in zip(*parts))
        classes = self._size_classes
        if classes is not None:  # triangles of very different sizes: each class searched alone
            best_d, best_f, best_p = np.full(len(X), np.inf), np.full(len(X), -1), np.full((len(X), 3), np.nan)
            for ids, sub in classes:
                d, f, q = sub.closest_points(X, within)
                better = d < best_d
                best_d[better], best_f[better], best_p[better] = d[better], ids[f[better]], q[better]
            return best_d, best_f, best_p
        P, cent, rad, tree = self.face_tree
        nf, rmax = len(self.F), float(rad.max())
        kq = min(nf, 16)
        bound = np.inf if within is None else float(within) + rmax
        dc, idx = tree.query(X, k=kq, distance_upper_bound=bound)
        dc = np.asarray(dc, float).reshape(len(X), kq)
        idx = np.asarray(idx).reshape(len(X), kq)
        best_d = np.full(len(X), np.inf)
        best_f = np.full(len(X), -1)
        best_p = np.full((len(X), 3), np.nan)
        for j in range(kq):
            has = idx[:, j] < nf
            if not has.any():
                break
            rows = np.nonzero(has)[0]
            f = idx[rows, j]
            q = closest_point_on_triangles(X[rows], P[f])
            d = np.linalg.norm(q - X[rows], axis=1)
            better = d < best_d[rows]
            r = rows[better]
            best_d[r], best_f[r], best_p[r] = d[better], f[better], q[better]
        # a face beyond the kq nearest centroids may still be closer (large
        # triangles, or a point far from a dense surface): every face whose
        # centroid lies within the best distance + its own radius is
        # checked, for all such points at once.  With kq faces found, no
        # other lies nearer than dc[:, -1] - rmax
        reach = np.minimum(best_d, bound - rmax)
        unsure = np.nonzero((dc[:, -1] - rmax < reach) & np.isfinite(dc[:, -1]))[0]
        if len(unsure):
            self._closest_exhaustive(X, unsure, reach[unsure] + rmax, best_d, best_f, best_p)
        if within is not None:
            far = best_d > within
            best_d[far], best_f[far], best_p[far] = np.inf, -1, np.nan
        return best_d, best_f, best_p

    def _closest_exhaustive(self, X, rows, radius, best_d, best_f, best_p, pairs_per_chunk: int = CLOSEST_PAIRS):
        """closest_points for the points X[rows] over every face with its
        centroid within radius of the point (improving best_* in place)."""
        P, cent, rad, tree = self.face_tree
        radius = np.broadcast_to(np.asarray(radius, float), (len(rows),))
        # the counts first, the candidate lists a bounded batch at a time
        counts = np.asarray(tree.query_ball_point(X[rows], radius, return_length=True), np.int64).reshape(-1)
        start = 0
        while start < len(rows):
            stop = start + 1 + int(np.searchsorted(np.cumsum(counts[start:]), pairs_per_chunk))
            stop = min(stop, len(rows))
            part = tree.query_ball_point(X[rows[start:stop]], radius[start:stop], return_sorted=False)
            f = np.fromiter(itertools.chain.from_iterable(part), np.int64, int(counts[start:stop].sum()))
            k = np.repeat(rows[start:stop], counts[start:stop])
            # a face cannot be nearer than its centroid's distance less its radius
            lb = np.linalg.norm(cent[f] - X[k], axis=1) - rad[f]
            keep = lb < best_d[k]
            f, k = f[keep], k[keep]
            if len(f):
                q = closest_point_on_triangles(X[k], P[f])
                d = np.linalg.norm(q - X[k], axis=1)
                order = np.lexsort((d, k))
                k, f, q, d = k[order], f[order], q[order], d[order]
                first = np.r_[True, k[1:] != k[:-1]]
                k, f, q, d = k[first], f[first], q[first], d[first]
                better = d < best_d[k]
                r = k[better]
                best_d[r], best_f[r], best_p[r] = d[better], f[better], q[better]
            start = stop


def _solid_angle_sum(P: np.ndarray, X: np.ndarray, chunk: int = 2_000_000) -> np.ndarray:
    """Sum over the triangles P (f, 3, 3) of their signed solid angles at
    each of X (k, 3), over 4 pi (Van Oosterom-Strackee)."""
    out = np.zeros(len(X))
    step = max(1, chunk // max(1, len(P)))
    for s in range(0, len(X), step):
        x = X[s : s + step, None, :]
        a = P[None, :, 0] - x
        b = P[None, :, 1] - x
        c = P[None, :, 2] - x
        la = np.linalg.norm(a, axis=2)
        lb = np.linalg.norm(b, axis=2)
        lc = np.linalg.norm(c, axis=2)
        det = np.einsum("kfi,kfi->kf", a, np.cross(b, c))
        den = (
            la * lb * lc
            + np.einsum("kfi,kfi->kf", a, b) * lc
            + np.einsum("kfi,kfi->kf", b, c) * la
            + np.einsum("kfi,kfi->kf", c, a) * lb
        )
        out[s : s + step] = 2.0 * np.arctan2(det, den).sum(axis=1) / (4 * np.pi)
    return out


def closest_point_on_triangles(X: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Closest point on triangle T[k] (k, 3, 3) to point X[k] (k, 3) (Ericson)."""
    a, b, c = T[:, 0], T[:, 1], T[:, 2]
    ab, ac, ap = b - a, c - a, X - a
    d1 = np.einsum("ij,ij->i", ab, ap)
    d2 = np.einsum("ij,ij->i", ac, ap)
    bp = X - b
    d3 = np.einsum("ij,ij->i", ab, bp)
    d4 = np.einsum("ij,ij->i", ac, bp)
    cp = X - c
    d5 = np.einsum("ij,ij->i", ab, cp)
    d6 = np.einsum("ij,ij->i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = vb / denom
        w = vc / denom
    out = a + v[:, None] * ab + w[:, None] * ac
    # edge regions
    with np.errstate(divide="ignore", invalid="ignore"):
        m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        t = d1 / (d1 - d3)
        out = np.where(m[:, None], a + t[:, None] * ab, out)
        m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        t = d2 / (d2 - d6)
        out = np.where(m[:, None], a + t[:, None] * ac, out)
        m = (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0)
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        out = np.where(m[:, None], b + t[:, None] * (c - b), out)
    # vertex regions
    out = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, out)
    out = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, out)
    out = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, out)
    return out


def _fmt(p) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in p) + ")"


def validate_surface(V: np.ndarray, F: np.ndarray, check_intersections: bool = True) -> TriSurface:
    """Check that (V, F) bounds a solid; raise SurfaceError saying what to fix.

    Checks, in order: array shapes and finiteness, index range, degenerate
    triangles, every edge shared by exactly two triangles, consistent
    orientation, manifold vertices, self-intersections and outward
    orientation (cavities inward).

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    check_intersections : bool
        Look for triangles that cross or touch (the slowest check).

    Returns
    -------
    TriSurface

    Raises
    ------
    SurfaceError
        Naming the first problem found, where it is and how to fix it.
    """
    V, F = _surface_arrays(V, F)
    _check_size(V, F)
    S = TriSurface(V, F)
    _check_degenerate(S)
    _check_closed(S)
    _check_orientation(S)
    _check_manifold_vertices(S)
    # intersections first: nesting below is only meaningful without them
    if check_intersections:
        _check_intersections(S)
    _check_nesting(S)
    return S


def _is_complex(V) -> bool:
    """Complex vertex coordinates (an array, or lists holding complex numbers)."""
    if isinstance(V, np.ndarray):
        return np.iscomplexobj(V)
    if isinstance(V, (list, tuple)):
        return any(isinstance(x, (complex, np.complexfloating)) for row in V if isinstance(row, (list, tuple))
                   for x in row)
    return False


# coordinates beyond this overflow squared distances and volumes (1e200**2 = inf)
MAX_COORDINATE = 1e100


MIN_EXTENT = 1e-50
"""A surface smaller than this across underflows the geometry: a small
triangle's area (a product of two lengths) or a tet's volume (of three)
rounds to 0 long before the double range ends (1e-308)."""


FLAT_RATIO = 1e-9
"""A surface thinner than this fraction of its size along an axis is flat:
no tet mesh or field fits in it."""


def _check_size(V: np.ndarray, F: np.ndarray) -> None:
    """Refuse a surface of no size or too small for floating-point geometry,
    saying its size and the scale that would fix it."""
    P = V[np.unique(F)]
    ext = float(np.ptp(P, axis=0).max())
    if ext == 0:
        raise SurfaceError(f"the surface has no size: all its {len(P)} vertices are at {P[0].tolist()}; give the "
                           "surface of a solid")
    ptp = np.ptp(P, axis=0)
    flat = np.nonzero(ptp <= FLAT_RATIO * ext)[0]
    if len(flat):
        axes = " and ".join("xyz"[i] for i in flat)
        raise SurfaceError(f"the surface is flat: {ext:.4g} across but {float(ptp[flat[0]]):.3g} along {axes}, so it "
                           "bounds (almost) no volume (an object scaled to 0 along an axis, e.g. Blender scale "
                           "(1, 1, 0)?); give the surface of a solid: a non-zero scale on every axis")
    if ext < MIN_EXTENT:
        k = int(np.ceil(-np.log10(ext)))
        raise SurfaceError(f"the surface is only {ext:.3g} across (its largest extent), too small for SymFrames' "
                           f"double-precision geometry (below {MIN_EXTENT:g} across, areas and volumes round to 0); "
                           f"a model in the wrong units: scale it up (e.g. by 1e{k}, to about 1 across)")


def _surface_arrays(V, F) -> tuple[np.ndarray, np.ndarray]:
    """(V, F) as float and int64 arrays of the right shapes, finite, with
    indices in range."""
    if V is None or F is None:
        raise SurfaceError(f"surface {'vertices' if V is None else 'faces'} = None: give the vertices as an (n, 3) "
                           "array of numbers and the faces as an (m, 3) array of vertex indices")
    if _is_complex(V):
        raise SurfaceError("surface vertices are complex numbers; give real coordinates (an (n, 3) float array; "
                           "the imaginary part is not dropped silently)")
    try:
        V = np.asarray(V, dtype=float)
        F = np.asarray(F)
    except (TypeError, ValueError, OverflowError) as e:
        raise SurfaceError(f"surface vertices must be an (n, 3) array of numbers and faces an (m, 3) array of "
                           f"vertex indices ({e})") from None
    if V.ndim != 2 or V.shape[1] != 3 or len(V) < 4:
        raise SurfaceError(f"surface vertices must be an (n, 3) array with n >= 4, got shape {V.shape}")
    if F.ndim == 2 and F.shape[1] == 3 and len(F) < 4:
        raise SurfaceError(f"the surface has {len(F)} triangle(s): a closed surface bounding a solid has at least 4 "
                           "(an open plane or sheet bounds no volume); give the closed surface of the solid")
    if F.ndim != 2 or F.shape[1] != 3:
        raise SurfaceError(
            f"surface faces must be an (m, 3) array of triangles with m >= 4, got shape {F.shape}; "
            "triangulate quads and n-gons first"
        )
    if not np.all(np.isfinite(V)):
        bad = np.nonzero(~np.all(np.isfinite(V), axis=1))[0][0]
        raise SurfaceError(f"surface vertex {bad} has a non-finite coordinate")
    far = np.nonzero(np.any(np.abs(V) > MAX_COORDINATE, axis=1))[0]
    if len(far):
        raise SurfaceError(f"surface vertex {far[0]} at {V[far[0]].tolist()} is beyond +-{MAX_COORDINATE:g}: "
                           f"{len(far)} such vertex/vertices; a stray vertex (delete it) or a model in the wrong "
                           "units (scale it)")
    if not np.issubdtype(F.dtype, np.integer):
        raise SurfaceError("surface faces must hold integer vertex indices")
    F = F.astype(np.int64)
    if F.min() < 0 or F.max() >= len(V):
        raise SurfaceError(f"surface face indices must lie in [0, {len(V) - 1}], found {F.min()}..{F.max()}")
    return V, F


def _check_degenerate(S: TriSurface) -> None:
    """Refuse triangles with repeated vertices or (near) zero area."""
    V, F, diag = S.V, S.F, S.bbox_diagonal
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    P = V[F]
    longest = np.max(np.linalg.norm(P - np.roll(P, 1, axis=1), axis=2), axis=1)
    thin = S.face_areas <= 1e-10 * np.maximum(longest, 1e-300) ** 2
    bad = np.nonzero(rep | thin | (longest < 1e-12 * diag))[0]
    if len(bad):
        f = bad[0]
        raise SurfaceError(
            f"{len(bad)} degenerate triangle(s) (zero area), e.g. triangle {f} at {_fmt(P[f].mean(0))}; "
            "merge duplicate vertices and dissolve degenerate faces (Blender: Mesh > Clean Up > Merge by "
            "Distance, Degenerate Dissolve)"
        )


def _check_closed(S: TriSurface) -> None:
    """Refuse edges not shared by exactly two triangles (and say so when the
    triangles are an unmerged soup)."""
    V = S.V
    _, _, cnt = S._edge_data
    if np.any(cnt == 1):
        soup = _unmerged_vertices(S, np.unique(S.edges[cnt == 1]))
        if soup is not None:
            n_open, n_twin, (i, j) = soup
            raise SurfaceError(
                f"surface triangles are not connected: {n_open} open edges, and {n_twin} of their vertices sit at the "
                f"same position as another vertex (e.g. vertices {i} and {j} at {_fmt(V[i])}) -- a triangle soup "
                "as STL files store it. Merge vertices by distance (Blender: Mesh > Clean Up > Merge by Distance; "
                "trimesh: merge_vertices())"
            )
    if np.any(cnt != 2):
        e = np.nonzero(cnt != 2)[0][0]
        i, j = S.edges[e]
        kind = "an open boundary (hole)" if cnt[e] == 1 else f"a non-manifold edge shared by {cnt[e]} faces"
        raise SurfaceError(
            f"surface is not closed and manifold: edge ({i}, {j}) at {_fmt(V[[i, j]].mean(0))} is {kind}; "
            f"{int(np.sum(cnt == 1))} open and {int(np.sum(cnt > 2))} non-manifold edges in total. "
            "Fill holes and separate touching parts (Blender: Select > All by Trait > Non Manifold)"
        )


def _check_orientation(S: TriSurface) -> None:
    """Refuse neighbouring triangles that list their shared edge in the same
    direction: each directed edge is used once."""
    V, F = S.V, S.F
    a = F.reshape(-1)
    b = np.roll(F, -1, axis=1).reshape(-1)
    dkeys = a.astype(np.int64) * len(V) + b
    ud, dc = np.unique(dkeys, return_counts=True)
    if np.any(dc > 1):
        k = ud[np.nonzero(dc > 1)[0][0]]
        i, j = k // len(V), k % len(V)
        raise SurfaceError(
            f"surface orientation is inconsistent at edge ({i}, {j}) near {_fmt(V[[i, j]].mean(0))}: two "
            "neighbouring triangles list it in the same direction. Recalculate normals "
            "(Blender: Mesh > Normals > Recalculate Outside)"
        )


def _check_manifold_vertices(S: TriSurface) -> None:
    """Refuse vertices where two parts of the surface touch: the corners
    around each vertex form a single fan."""
    V, F = S.V, S.F
    nF = len(F)
    corner = np.arange(3 * nF).reshape(nF, 3)
    # corner (f,k) at vertex F[f,k]; its outgoing edge (F[f,k] -> F[f,k+1]) is
    # the incoming edge of the neighbouring corner around the same vertex
    in_keys = np.roll(F, 1, axis=1).astype(np.int64) * len(V) + F  # prev -> vertex
    # neighbour of corner (f,k) around vertex v: the corner whose incoming edge is
    # the reverse of (v -> next)
    rev = np.roll(F, -1, axis=1).astype(np.int64) * len(V) + F
    order = np.argsort(in_keys.reshape(-1))
    pos = np.searchsorted(in_keys.reshape(-1)[order], rev.reshape(-1))
    nb = order[np.clip(pos, 0, len(order) - 1)]
    A = sp.coo_matrix((np.ones(3 * nF), (corner.reshape(-1), nb)), shape=(3 * nF, 3 * nF))
    ncc, lab = csgraph.connected_components(A, directed=False)
    used = np.unique(F)
    if ncc != len(used):
        per_vertex = np.zeros(len(V), int)
        first = np.full(ncc, -1)
        verts = F.reshape(-1)
        first[lab] = verts
        np.add.at(per_vertex, first, 1)
        v = np.nonzero(per_vertex > 1)[0][0]
        raise SurfaceError(
            f"surface vertex {v} at {_fmt(V[v])} is non-manifold (two parts of the surface touch only there); "
            "split it or move the parts apart"
        )


def _check_intersections(S: TriSurface) -> None:
    """Refuse triangles that cross, or that touch without sharing vertices."""
    P = S.V[S.F]
    hit = find_crossing_or_contact(S)
    if hit is not None and hit[0] == "cross":
        f, g = hit[1:3]
        raise SurfaceError(
            f"surface intersects itself: triangles {f} and {g} cross near {_fmt(P[f].mean(0))}; "
            "remove the intersection (Blender: 3D-Print Toolbox > Intersections, or a Boolean union)"
        )
    if hit is not None:
        f, g, x = hit[1:]
        cf, cg = S.component_of_faces()[[f, g]]
        what = (f"surface components {cf} and {cg} touch or overlap" if cf != cg else
                f"surface component {cf} touches itself")
        raise SurfaceError(
            f"{what}: triangles {f} and {g} meet at {_fmt(x)} without sharing vertices -- solids touching face "
            "to face or along an edge, overlapping with coincident faces, or a surface folded onto itself. "
            "Move the parts apart and solve each solid separately, or join them into one solid (a Boolean "
            "union)"
        )


def _check_nesting(S: TriSurface) -> None:
    """One solid, its outer surface outward and its cavities inward."""
    V, F = S.V, S.F
    vols = S.signed_volumes()
    ncomp, lab = S.face_components
    if ncomp > 1:
        comp_vertex = np.array([F[np.nonzero(lab == c)[0][0], 0] for c in range(ncomp)])
        depth = np.zeros(ncomp, int)
        for c in range(ncomp):
            others = [d for d in range(ncomp) if d != c]
            for d in others:
                sub = TriSurface(V, F[lab == d])
                if abs(sub.winding_number(V[comp_vertex[c]][None])[0]) > 0.5:
                    depth[c] += 1
    else:
        depth = np.zeros(1, int)
    _check_one_solid(S, depth)
    for c in range(ncomp):
        want_positive = depth[c] % 2 == 0
        if (vols[c] > 0) != want_positive:
            what = "an outer surface" if want_positive else "a cavity"
            fix = "outward" if want_positive else "into the cavity (towards the solid's outside)"
            raise SurfaceError(
                f"surface component {c} ({int(np.sum(lab == c))} triangles, {what}) is oriented the wrong "
                f"way; its normals must point {fix} (Blender: Mesh > Normals > Recalculate Outside)"
            )


def _check_one_solid(S: TriSurface, depth: np.ndarray) -> None:
    """One solid per solve: exactly one outer component (depth 0, inside no
    other); every other component is a cavity directly inside it (depth 1).
    A second outer component is a separate solid (the tet mesh would not be
    connected); a component inside a cavity is a solid floating in it."""
    ncomp, lab = S.face_components
    outer = np.nonzero(depth == 0)[0]
    sizes = np.bincount(lab, minlength=ncomp)
    if len(outer) > 1:
        where = ", ".join(f"component {c} ({sizes[c]} triangles) near {_fmt(S.V[S.F[lab == c]].mean(axis=(0, 1)))}"
                          for c in outer[:4])
        raise SurfaceError(
            f"the surface bounds {len(outer)} separate solids ({where}{', ...' if len(outer) > 4 else ''}); a solve "
            "takes one solid, possibly with cavities inside it. Solve each solid separately (Blender: Mesh > "
            "Separate > By Loose Parts), or join them into one (a Boolean union)"
        )
    inner = np.nonzero(depth >= 2)[0]
    if len(inner):
        c = inner[0]
        raise SurfaceError(
            f"surface component {c} ({sizes[c]} triangles) near {_fmt(S.V[S.F[lab == c]].mean(axis=(0, 1)))} is a "
            "solid inside a cavity of another; a solve takes one solid. Solve it separately (Blender: Mesh > "
            "Separate > By Loose Parts)"
        )


def _unmerged_vertices(S: TriSurface, open_vertices: np.ndarray):
    """(open edge count, vertices of open edges with a geometric twin, one
    such pair) when most open-edge vertices coincide with another vertex --
    the surface is an unmerged triangle soup -- else None."""
    tree = cKDTree(S.V)
    d, j = tree.query(S.V[open_vertices], k=2)
    twin = d[:, 1] <= 1e-9 * S.bbox_diagonal
    if twin.sum() < max(3, 0.5 * len(open_vertices)):
        return None
    k = int(np.argmax(twin))
    n_open = int(np.sum(S._edge_data[2] == 1))
    v = int(open_vertices[k])
    return n_open, int(twin.sum()), (v, int(j[k, 1] if j[k, 0] == v else j[k, 0]))


def candidate_pairs(S: TriSurface, pad: float = 0.0, chunk: int = 500_000):
    """Pairs of triangles (f < g) that may come within pad of each other, in
    chunks of at most ``chunk`` pairs: their bounding boxes do, and pieces of
    them (below) have bounding spheres that do.

    One search radius for all triangles (twice the largest) made this
    quadratic when a few large triangles sit among many small ones (a cube
    with a 0.1 grid on five faces and the sixth cut into long triangles:
    13,102 faces, 49 s).  Here every triangle searches with a radius of its
    own (the larger of a pair finds the smaller: |c_f - c_g| <= r_f + r_g
    <= 2 r_f), and triangles much larger than the median are first bisected
    along their longest edge into pieces of at most ``cap``, so that a long
    thin triangle searches along itself instead of a ball of its length.
    """
    V, F = S.V, S.F
    n = len(F)
    P = V[F]
    rad = np.max(np.linalg.norm(P - P.mean(axis=1)[:, None], axis=2), axis=1)
    cap = 4.0 * float(np.median(rad))
    while np.sum(np.maximum(1.0, 2.0 * (rad / cap) ** 2)) > 8 * n + 64:
        cap *= 2.0  # bounded work for surfaces made mostly of large triangles
    Q, owner = _bisect_to_radius(P, cap)
    qc = Q.mean(axis=1)
    qr = np.max(np.linalg.norm(Q - qc[:, None], axis=2), axis=1)
    rank = np.empty(len(Q), np.int64)
    rank[np.lexsort((np.arange(len(Q)), qr))] = np.arange(len(Q))
    tree = cKDTree(qc)
    keys = []
    step = 8192
    for s0 in range(0, len(Q), step):
        ids = np.arange(s0, min(s0 + step, len(Q)))
        hits = tree.query_ball_point(qc[ids], 2.0 * qr[ids] + pad, return_sorted=False)
        lens = np.fromiter((len(h) for h in hits), np.int64, len(hits))
        b = np.fromiter(itertools.chain.from_iterable(hits), np.int64, int(lens.sum()))
        a = np.repeat(ids, lens)
        keep = (rank[b] < rank[a]) & (owner[a] != owner[b])
        a, b = a[keep], b[keep]
        keep = np.linalg.norm(qc[a] - qc[b], axis=1) <= qr[a] + qr[b] + pad
        f, g = owner[a[keep]], owner[b[keep]]
        keys.append(np.unique(np.minimum(f, g) * n + np.maximum(f, g)))
    key = np.unique(np.concatenate(keys)) if keys else np.zeros(0, np.int64)
    f, g = key // n, key % n
    lo, hi = P.min(axis=1) - pad, P.max(axis=1) + pad
    keep = np.all((lo[f] <= hi[g]) & (lo[g] <= hi[f]), axis=1)
    f, g = f[keep], g[keep]
    for c0 in range(0, len(f), chunk):
        yield f[c0:c0 + chunk], g[c0:c0 + chunk]


def _bisect_to_radius(P: np.ndarray, cap: float):
    """Split triangles P (k, 3, 3) by bisecting their longest edge until every
    piece's centroid-to-corner radius is at most cap.  Returns the pieces and
    the index of the triangle each comes from."""
    owner = np.arange(len(P))
    out, own = [], []
    while len(P):
        c = P.mean(axis=1)
        done = np.max(np.linalg.norm(P - c[:, None], axis=2), axis=1) <= cap
        out.append(P[done])
        own.append(owner[done])
        P, owner = P[~done], owner[~done]
        if not len(P):
            break
        k = np.argmax(np.linalg.norm(np.roll(P, -1, axis=1) - P, axis=2), axis=1)  # edge k -> k + 1
        i = np.arange(len(P))
        a, b, c = P[i, k], P[i, (k + 1) % 3], P[i, (k + 2) % 3]
        m = 0.5 * (a + b)
        P = np.concatenate([np.stack([a, m, c], axis=1), np.stack([m, b, c], axis=1)])
        owner = np.concatenate([owner, owner])
    return np.concatenate(out), np.concatenate(own)


def find_self_intersection(S: TriSurface):
    """Return one pair of crossing triangles (f, g), or None.

    Broad phase: candidate_pairs (per-triangle search radius); narrow phase:
    an edge of one triangle properly crossing the other, for pairs that share
    no vertex, and the edge opposite the shared vertex for pairs that share
    one.
    """
    for f, g in candidate_pairs(S):
        hit = _crossing(S, f, g)
        if hit is not None:
            return hit
    return None


def _crossing(S: TriSurface, f, g):
    V, F = S.V, S.F
    P = S.face_tree[0]
    tol = 1e-9 * S.bbox_diagonal
    same = F[f][:, :, None] == F[g][:, None, :]
    keep = same.sum(axis=(1, 2)) <= 1
    f, g, same = f[keep], g[keep], same[keep]
    # no proper crossing where the corners of one triangle not shared with
    # the other lie strictly on one side of the other's plane (as
    # segment_crosses_triangle decides sides): most pairs of a smooth
    # surface, dropped before the six edge tests
    apart = np.zeros(len(f), bool)
    for A, B, shared in ((f, g, same.any(axis=2)), (g, f, same.any(axis=1))):
        a, b, c = P[B, 0], P[B, 1], P[B, 2]
        n = np.cross(b - a, c - a)
        scale = np.linalg.norm(n, axis=1) * tol
        d = np.einsum("ikj,ij->ik", P[A] - a[:, None], n)
        apart |= np.all((d > scale[:, None]) | shared, axis=1) | np.all((d < -scale[:, None]) | shared, axis=1)
    f, g = f[~apart], g[~apart]
    hits = np.zeros(len(f), bool)
    for A, B in ((f, g), (g, f)):
        for k in range(3):
            s0 = V[F[A, k]]
            s1 = V[F[A, (k + 1) % 3]]
            # skip edges touching a shared vertex
            touches = (F[A, k][:, None] == F[B]).any(1) | (F[A, (k + 1) % 3][:, None] == F[B]).any(1)
            crossing = segment_crosses_triangle(s0, s1, P[B], tol)
            hits |= crossing & ~touches
    if np.any(hits):
        i = np.nonzero(hits)[0][0]
        return int(f[i]), int(g[i])
    return None


CONTACT_TOLERANCE = 1e-6  # of the bounding-box diagonal: float32 coordinates (Blender) touch to ~1e-7


def find_contact(S: TriSurface):
    """One pair of triangles that share no vertex but touch -- a vertex or
    an edge of one within tolerance of the other -- and the contact point,
    or None.

    Catches what find_self_intersection cannot: two solids touching face to
    face, overlapping with coincident faces, or meeting along an edge, where
    nothing crosses properly.  The tolerance is CONTACT_TOLERANCE of the
    diagonal, and at most a hundredth of the two triangles' shortest edge so
    that fine meshes are not flagged; far below fTetWild's envelope (1e-3),
    which would merge such surfaces anyway.
    """
    for f, g in candidate_pairs(S, pad=CONTACT_TOLERANCE * S.bbox_diagonal):
        hit = _contact(S, f, g)
        if hit is not None:
            return hit
    return None


def find_crossing_or_contact(S: TriSurface):
    """find_self_intersection and find_contact in one broad phase: (kind,
    f, g, point) with kind 'cross' or 'touch', or None.  Crossings anywhere
    are reported before contacts."""
    touch = None
    for f, g in candidate_pairs(S, pad=CONTACT_TOLERANCE * S.bbox_diagonal):
        hit = _crossing(S, f, g)
        if hit is not None:
            return "cross", hit[0], hit[1], S.V[S.F[hit[0]]].mean(axis=0)
        if touch is None:
            touch = _contact(S, f, g)
    return None if touch is None else ("touch", *touch)


def _contact(S: TriSurface, f, g):
    V, F = S.V, S.F
    P = V[F]
    shared = (F[f][:, :, None] == F[g][:, None, :]).any(axis=(1, 2))
    f, g = f[~shared], g[~shared]
    if not len(f):
        return None
    L = np.minimum(np.linalg.norm(P[f] - np.roll(P[f], 1, axis=1), axis=2).min(axis=1),
                   np.linalg.norm(P[g] - np.roll(P[g], 1, axis=1), axis=2).min(axis=1))
    tol = np.minimum(CONTACT_TOLERANCE * S.bbox_diagonal, 0.01 * L)
    best = np.full(len(f), np.inf)
    where = np.zeros((len(f), 3))
    for A, B in ((f, g), (g, f)):
        for k in range(3):
            x = V[F[A, k]]
            d = np.linalg.norm(closest_point_on_triangles(x, P[B]) - x, axis=1)
            better = d < best
            best[better], where[better] = d[better], x[better]
    for i in range(3):
        for j in range(3):
            d, x = segments_distance(P[f, i], P[f, (i + 1) % 3], P[g, j], P[g, (j + 1) % 3])
            better = d < best
            best[better], where[better] = d[better], x[better]
    hit = np.nonzero(best <= tol)[0]
    if len(hit):
        i = hit[0]
        return int(f[i]), int(g[i]), where[i]
    return None


def segments_distance(p0, p1, q0, q1):
    """Distance between segments p0-p1 and q0-q1 (k, 3) each, and the
    midpoint of the closest pair (Ericson, clamped)."""
    u, v, w = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("ij,ij->i", u, u)
    b = np.einsum("ij,ij->i", u, v)
    c = np.einsum("ij,ij->i", v, v)
    d = np.einsum("ij,ij->i", u, w)
    e = np.einsum("ij,ij->i", v, w)
    den = a * c - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip(np.where(den > 1e-300, (b * e - c * d) / den, 0.0), 0, 1)
        t = np.clip(np.where(c > 1e-300, (b * s + e) / c, 0.0), 0, 1)
        s = np.clip(np.where(a > 1e-300, (b * t - d) / a, 0.0), 0, 1)
    x = p0 + s[:, None] * u
    y = q0 + t[:, None] * v
    return np.linalg.norm(x - y, axis=1), 0.5 * (x + y)


def segment_crosses_triangle(s0, s1, T, tol=0.0):
    """Does segment s0-s1 (k,3) properly cross triangle T (k,3,3)?"""
    a, b, c = T[:, 0], T[:, 1], T[:, 2]

    def vol(p, q, r, s):
        return np.einsum("ij,ij->i", q - p, np.cross(r - p, s - p))

    d0 = vol(a, b, c, s0)
    d1 = vol(a, b, c, s1)
    scale = np.linalg.norm(np.cross(b - a, c - a), axis=1) * tol
    straddle = ((d0 > scale) & (d1 < -scale)) | ((d0 < -scale) & (d1 > scale))
    u = vol(s0, s1, a, b)
    v = vol(s0, s1, b, c)
    w = vol(s0, s1, c, a)
    inside = ((u > 0) & (v > 0) & (w > 0)) | ((u < 0) & (v < 0) & (w < 0))
    return straddle & inside
