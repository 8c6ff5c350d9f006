"""The triangle surface: ``TriSurface``, its topology (edges, faces of an
edge, components, Euler characteristics), geometry (normals, angles,
volumes) and queries (winding numbers, closest points).

Used twice: on the user's input surface (checked by validation.py before any
heavy work) and on the boundary of the tetrahedral mesh (the domain of the
2D problem).  Whether a surface bounds a solid is validation.py's question;
which of its triangles cross or touch, intersect.py's.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

# winding numbers of surfaces over this many triangles count far groups of
# about WINDING_GROUP_FACES triangles by their dipole (TriSurface._winding_fast):
# validating the ball's network on an 81,920-triangle sphere spent 11 of
# its 19.5 s in exact winding numbers
FAST_WINDING_FACES = 20_000
WINDING_GROUP_FACES = 64
WINDING_FAR = 3.0


CLOSEST_CHUNK = 8_192
"""Points ``TriSurface.closest_points`` answers at once (its memory is
about 12 KB per point of a chunk: 16 candidate triangles each)."""
CLOSEST_PAIRS = 262_144
"""Point-triangle pairs its exhaustive fallback measures at once (~150 MB)."""
SIZE_CLASS_SPREAD = 8.0
SIZE_CLASS_RATIO = 4.0
"""closest_points searches the triangles in classes of radii within a
factor SIZE_CLASS_RATIO where the largest radius exceeds SIZE_CLASS_SPREAD
times the median (TriSurface._size_classes)."""


def _row_groups(a: np.ndarray):
    """(order, new) of int rows a (k, w): the permutation sorting them in
    lexicographic order (stable where rows tie: ``np.lexsort``, or a stable
    sort of one key), and which sorted rows start a run of equal rows.  The
    columns are packed into one int64 key where their range allows, else
    two columns a key (a range up to 3e9), else one."""
    a = a - min(int(a.min()), 0)
    n = int(a.max()) + 1
    width = a.shape[1]
    if n ** width < 2**63:  # (python ints: no overflow in the test)
        keys = [a[:, 0]]
        for k in range(1, width):
            keys[0] = keys[0] * n + a[:, k]
    elif n * n < 2**63:
        keys = [a[:, k] * n + a[:, k + 1] if k + 1 < width else a[:, k] for k in range(0, width, 2)]
    else:
        keys = list(a.T)
    order = np.lexsort(keys[::-1]) if len(keys) > 1 else np.argsort(keys[0], kind="stable")
    new = np.zeros(len(a), bool)
    new[0] = True
    for key in keys:
        s = key[order]
        new[1:] |= s[1:] != s[:-1]
    return order, new


def unique_rows(a: np.ndarray):
    """np.unique(a, axis=0, return_inverse=True, return_counts=True) for int
    rows of any width, the same arrays, on int64 keys (``_row_groups``).
    numpy's own compares the rows as records: on the 1.4M faces of a
    227k-hex grid it took 3.3 s, this 0.64 s.

    Returns (unique rows, inverse, counts).
    """
    a = np.asarray(a, dtype=np.int64)
    if not len(a):
        return a, np.zeros(0, np.int64), np.zeros(0, np.int64)
    order, new = _row_groups(a)
    inv = np.empty(len(a), np.int64)
    inv[order] = np.cumsum(new) - 1
    starts = np.nonzero(new)[0]
    return a[order[starts]], inv, np.diff(np.r_[starts, len(a)])


def first_rows(a: np.ndarray) -> np.ndarray:
    """np.unique(a, axis=0, return_index=True)[1] for int rows: the index of
    each distinct row's first occurrence, in the rows' lexicographic order."""
    a = np.asarray(a, dtype=np.int64)
    if not len(a):
        return np.zeros(0, np.int64)
    order, new = _row_groups(a)
    return order[new]  # a stable sort puts each run's first occurrence first


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
        # every (point, candidate) pair in one call: with few points per
        # call (the intake asks a handful at a time), one call per candidate
        # rank cost more in numpy's per-call overhead than in arithmetic
        rows, js = np.nonzero(idx < nf)
        D = np.full((len(X), kq), np.inf)
        Q = np.full((len(X), kq, 3), np.nan)
        if len(rows):
            q = closest_point_on_triangles(X[rows], P[idx[rows, js]])
            d = np.linalg.norm(q - X[rows], axis=1)
            D[rows, js] = np.where(np.isnan(d), np.inf, d)
            Q[rows, js] = q
        jb = np.argmin(D, axis=1)  # the first of equals, as candidates come nearest first
        at = np.arange(len(X))
        best_d = D[at, jb]
        found = np.isfinite(best_d)
        best_f = np.where(found, idx[at, jb], -1)
        best_p = np.where(found[:, None], Q[at, jb], np.nan)
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
