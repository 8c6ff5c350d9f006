"""A dense input surface brought down to the mesh scale before fTetWild
(issue 41e).

fTetWild's time grows with its input far more than with its output: a
smooth sphere of 81,920 triangles (the ball's network, h = 0.16) had not
finished meshing after 600 s, the same sphere with 1,280 meshed in 5 s.
Blender users' sculpted or subdivided objects commonly have 1e5-1e6
triangles.  So a surface with over ``DENSE_FACTOR`` times the triangles of
an h-mesh of it (and at least ``MIN_DENSE_TRIANGLES``) is simplified first,
to about ``CELL_FRACTION`` h, by vertex clustering with quadric placement
(Lindstrom 2000, "Out-of-core simplification of large polygonal models"):
every vertex falls in a cell
of a grid of that size, each cell becomes one vertex placed where the sum
of the squared distances to the planes of its triangles is least (the
quadric error: it keeps creases and corners the cell contains, where the
mean of the vertices would round them), and triangles whose corners fall
in fewer than three cells vanish.  It is one pass of numpy, linear in the
input (1.3M triangles in seconds), and needs no compiled library.  The
clusters' triangles are then made well shaped, as fTetWild wants them:
rounds of Delaunay edge flips between nearly coplanar triangles (never
across a crease) and of smoothing of the vertices of smooth cells,
projected back onto the input.

The clustering is a simplicial map, so the result is a closed 2-chain like
the input: fTetWild (which takes triangle soups) and the winding numbers
of the inside test see the same solid.  It need not be manifold where a
part thinner than the cell collapses: then it is made again with clusters
half as large (twice at most), and else the input is meshed as it is; the
mesh's boundary is checked against the input's topology after meshing
(meshing.topology_change), as always.  Its chords may cut into curved parts: how deep is measured and
reported, and checked against the mesher's envelope (simplify_for_meshing).
The input surface stays the reference for everything else (snapping onto
sharp features, the curves, the measures).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..surface.features import FeatureGraph
from ..surface.trisurface import TriSurface, edge_keys

# simplify when the surface has this many times the triangles of an h-mesh
# of it (an h-mesh of area A has about A / (sqrt(3)/4 h^2) triangles):
# fTetWild is slow on inputs finer than its mesh even at a few thousand
# triangles -- the cylinder example (4,480 triangles, 3.3x an h-mesh at the
# default h = 0.18) meshed in 7-8 s as it is, in 2.5 s from its 2,988
# clusters, with the same field (penalty 0.002, 5 LM iterations)
DENSE_FACTOR = 2.5
# ... and has at least this many triangles (a coarse surface gains nothing)
MIN_DENSE_TRIANGLES = 2_000
# ... and from this many triangles it is clustered even where the chords
# cut deeper than the mesher's envelope (simplify_for_meshing): fTetWild on
# the input itself would take minutes (an 81,920-triangle sphere: over 600 s)
ALWAYS_TRIANGLES = 10_000
# where the clustering is not manifold, it is made again with clusters half as large, at most this many
# times, before the input is meshed as it is
MANIFOLD_TRIES = 2
# grid cell of the clustering, as a fraction of the mesh's edge length h:
# coarser meshes faster, finer keeps the field (docs/performance.md, *Clustering a dense surface*)
CELL_FRACTION = 0.6
# rounds of (Delaunay edge flips, one pass of smoothing of the smooth
# clusters projected onto the input): fTetWild takes poorly shaped input
# triangles slowly (docs/performance.md, *Clustering a dense surface*)
SMOOTH_PASSES = 5
RANK_RATIO = 0.03


@dataclass
class Simplified:
    """What ``simplify_for_meshing`` did: the surface fTetWild gets, the
    triangle counts before and after, the cell size, the relative change
    of the enclosed volume and the depth of its chords (its vertices lie on
    the input: chordal error only)."""

    surface: TriSurface
    faces_in: int
    faces_out: int
    cell: float
    volume_change: float
    deviation: float = 0.0  # the farthest input vertex from it
    envelope: float | None = None  # the mesher's

    def text(self) -> str:
        past = ("" if self.envelope is None or self.deviation <= self.envelope else
                f", past the mesher's envelope ({self.envelope:.2g}): a smaller edge length follows the input closer")
        return (f"the surface simplified from {self.faces_in:,} to {self.faces_out:,} triangles for the mesher "
                f"(clusters of {self.cell:.3g}, vertices on the input, chords within {self.deviation:.2g} of it"
                f"{past}; volume {100 * self.volume_change:+.2g}%)")


def h_mesh_faces(surface: TriSurface, h: float) -> float:
    """About how many triangles an h-mesh of the surface has."""
    return float(surface.face_areas.sum()) / (np.sqrt(3.0) / 4.0 * h * h)


def is_dense(surface: TriSurface, h: float) -> bool:
    """Whether the surface has over DENSE_FACTOR times the triangles of an
    h-mesh of it, and at least MIN_DENSE_TRIANGLES."""
    n = len(surface.F)
    return n >= MIN_DENSE_TRIANGLES and n > DENSE_FACTOR * max(h_mesh_faces(surface, h), 1.0)


def cluster_surface(V: np.ndarray, F: np.ndarray, cell: float, feature: np.ndarray | None = None,
                    corners: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertex clustering of the triangle mesh (V, F) on a grid of size cell,
    each cluster placed at the minimum of its quadric error (module
    docstring).  Returns (V', F', smooth): degenerate triangles dropped,
    pairs of the same triangle with opposite orientations cancelled, and
    smooth (#V',): the cluster's triangles span one plane (no crease or
    corner in it).

    feature : (#V,) bool, the vertices on sharp edges of the input; a
              cluster holding one is placed on the one nearest its quadric
              point, so the creases run through input vertices on them
              (a crease weak against the cell's other triangles, below
              RANK_RATIO, would otherwise be cut across)
    corners : ids of the input's sharp corners; a cluster holding one is
              placed on it
    """
    V = np.asarray(V, float)
    F = np.asarray(F, np.int64)
    lo = V.min(axis=0)
    key = np.floor((V - lo) / cell).astype(np.int64)
    _, lab = np.unique(key, axis=0, return_inverse=True)
    lab = lab.reshape(-1)
    m = int(lab.max()) + 1
    # each triangle's plane n.x = d, weighted by its area: the quadric
    # (n n^T, n d) summed into the clusters of its three corners
    P = V[F]
    cr = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    area = 0.5 * np.linalg.norm(cr, axis=1)
    n = cr / np.maximum(2.0 * area, 1e-300)[:, None]
    d = np.einsum("ij,ij->i", n, P[:, 0])
    A = area[:, None, None] * n[:, :, None] * n[:, None, :]
    b = (area * d)[:, None] * n
    QA = np.zeros((m, 3, 3))
    Qb = np.zeros((m, 3))
    for k in range(3):
        np.add.at(QA, lab[F[:, k]], A)
        np.add.at(Qb, lab[F[:, k]], b)
    cnt = np.bincount(lab, minlength=m).astype(float)
    mean = np.zeros((m, 3))
    np.add.at(mean, lab, V)
    mean /= np.maximum(cnt, 1.0)[:, None]
    # least-squares point nearest the vertices' mean: the pseudo-inverse of
    # the quadric with its small eigenvalues dropped (a flat cell has one
    # plane: the mean moves onto it only along its normal).  Two planes at
    # an angle t give eigenvalues in the ratio tan^2(t / 2): RANK_RATIO
    # keeps a crease of 19 degrees or more (sharp_angle is 30 by default),
    # and a cell of a curved smooth part (normals within ~0.2 rad) stays
    # one plane
    w, U = np.linalg.eigh(QA)
    keep = w > RANK_RATIO * np.maximum(w[:, -1:], 1e-300)
    r = Qb - np.einsum("mij,mj->mi", QA, mean)
    coef = np.einsum("mji,mj->mi", U, r) / np.where(keep, w, 1.0) * keep
    X = mean + np.einsum("mij,mj->mi", U, coef)
    # a placement outside its own cell (nearly parallel planes) falls back
    # to the mean
    far = np.linalg.norm(X - mean, axis=1) > cell
    X[far] = mean[far]
    pinned = np.zeros(m, bool)
    for ids in (None if feature is None else np.nonzero(feature)[0], corners):
        if ids is None or not len(ids):
            continue
        # per cluster, its vertex of the set nearest the placement so far
        ids = np.asarray(ids, np.int64)
        d = np.linalg.norm(V[ids] - X[lab[ids]], axis=1)
        order = np.lexsort((d, lab[ids]))
        first = order[np.r_[True, lab[ids][order][1:] != lab[ids][order][:-1]]]
        X[lab[ids[first]]] = V[ids[first]]
        pinned[lab[ids[first]]] = True
    G = lab[F]
    ok = (G[:, 0] != G[:, 1]) & (G[:, 1] != G[:, 2]) & (G[:, 0] != G[:, 2])
    G = G[ok]
    # opposite copies of one triangle cancel (a collapsed thin sheet)
    s = np.sort(G, axis=1)
    even = _orientation_parity(G)
    _, inv, counts = np.unique(s, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    net = np.zeros(len(counts))
    np.add.at(net, inv, np.where(even, 1.0, -1.0))
    first = np.full(len(counts), -1)
    order = np.argsort(inv, kind="stable")
    first[inv[order[::-1]]] = order[::-1]
    keep_f = np.zeros(len(G), bool)
    single = (counts == 1) | (np.abs(net) == counts)  # no opposite copy: keep all copies
    keep_f[single[inv]] = True
    # mixed: keep |net| copies with the sign of net
    mixed = np.nonzero(~single & (net != 0))[0]
    for j in mixed:  # rare (a few per collapsed sheet)
        rows = np.nonzero(inv == j)[0]
        want = even[rows] == (net[j] > 0)
        keep_f[rows[want][: int(abs(net[j]))]] = True
    G = G[keep_f]
    used, Gn = np.unique(G, return_inverse=True)
    return X[used], Gn.reshape(-1, 3), (keep.sum(axis=1) <= 1)[used] & ~pinned[used]


def _orientation_parity(G: np.ndarray) -> np.ndarray:
    """True where the triangle's corners are an even permutation of their
    sorted order."""
    a, b, c = G[:, 0], G[:, 1], G[:, 2]
    inversions = (a > b).astype(int) + (a > c) + (b > c)
    return inversions % 2 == 0


def _smooth_onto(surface: TriSurface, V: np.ndarray, F: np.ndarray, smooth: np.ndarray, passes: int) -> np.ndarray:
    """Umbrella smoothing of the vertices marked smooth, each pass projected
    back onto the input surface (creases and corners stay where the
    quadrics put them)."""
    E = np.r_[F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]
    deg = np.bincount(E.reshape(-1), minlength=len(V)).astype(float)
    idx = np.nonzero(smooth & (deg > 0))[0]
    for _ in range(passes):
        if not len(idx):
            break
        acc = np.zeros_like(V)
        np.add.at(acc, E[:, 0], V[E[:, 1]])
        np.add.at(acc, E[:, 1], V[E[:, 0]])
        X = 0.5 * V[idx] + 0.5 * acc[idx] / deg[idx, None]
        _, _, V[idx] = surface.closest_points(X)
    return V


def simplify_for_meshing(surface: TriSurface, h: float, say=None, features: FeatureGraph | None = None,
                         envelope: float | None = None) -> Simplified | None:
    """The surface fTetWild meshes at edge length h: None where the input
    is not dense (is_dense), else its clustering at CELL_FRACTION h
    (module docstring).  say: a function of a message, for progress.
    features: the input's sharp edges and corners, kept (cluster_surface).

    envelope: how far the mesher's surface may leave the input (fTetWild's
    own envelope, Options.epsilon of the diagonal).  Where the clustering's
    chords cut deeper (a part curved tightly for the mesh scale), a surface
    of under ALWAYS_TRIANGLES goes to fTetWild as it is (its own
    simplification keeps to the envelope, in seconds at that size); a
    larger one is meshed from the clustering all the same (fTetWild would
    take minutes), and the report says how deep the chords cut.
    """
    if not is_dense(surface, h):
        return None
    if say is not None:
        say(f"tetmesh: simplifying the surface ({len(surface.F):,} triangles, ~{h_mesh_faces(surface, h):,.0f} "
            f"at the mesh scale {h:.3g})...")
    feature = corners = None
    if features is not None and np.any(features.sharp):
        feature, corners = features.degree > 0, features.corners
    cell = CELL_FRACTION * h
    out = _clustered(surface, cell, feature, corners)
    for _ in range(MANIFOLD_TRIES):
        if _manifold(out):
            break
        # a part thinner than the cell collapsed onto itself (a collared
        # shaft at h = 0.127: 2 edges of 4 triangles, and fTetWild's
        # boundary then lost the input's topology): finer clusters, else
        # the input as it is
        cell *= 0.5
        out = _clustered(surface, cell, feature, corners)
    else:
        if say is not None:
            say(f"tetmesh: the surface kept as it is ({len(surface.F):,} triangles): clustered at the mesh scale a "
                "part thinner than the clusters collapsed")
        return None
    deviation = _deviation(surface, out)
    if envelope is not None and deviation > envelope and len(surface.F) < ALWAYS_TRIANGLES:
        if say is not None:
            say(f"tetmesh: the surface kept as it is ({len(surface.F):,} triangles): clustered at the mesh scale its "
                f"chords would cut {deviation:.3g} deep, past the mesher's envelope ({envelope:.3g})")
        return None
    v0 = float(surface.signed_volumes().sum())
    res = Simplified(out, len(surface.F), len(out.F), cell, float(out.signed_volumes().sum()) / v0 - 1.0, deviation,
                     envelope)
    if say is not None:
        say(f"tetmesh: {res.text()}")
    return res


def _manifold(surface: TriSurface) -> bool:
    """Whether every edge of the surface has exactly two triangles."""
    return bool(np.all(np.bincount(surface.face_edges.reshape(-1)) == 2))


def _clustered(surface: TriSurface, cell: float, feature, corners) -> TriSurface:
    """cluster_surface, then rounds of flips and smoothing onto the input."""
    V, F, smooth = cluster_surface(surface.V, surface.F, cell, feature, corners)
    for _ in range(SMOOTH_PASSES):
        F = flip_to_delaunay(V, F)
        V = _smooth_onto(surface, V, F, smooth, 1)
    return TriSurface(V, flip_to_delaunay(V, F))


DEVIATION_SAMPLES = 200_000


def _deviation(surface: TriSurface, out: TriSurface) -> float:
    """How far the input's vertices (up to DEVIATION_SAMPLES of them, the
    same each run) lie from the clustered surface: the depth of its chords."""
    X = surface.V[np.unique(surface.F)]
    if len(X) > DEVIATION_SAMPLES:
        X = X[np.random.default_rng(0).choice(len(X), DEVIATION_SAMPLES, replace=False)]
    return float(out.closest_points(X)[0].max())


# edge flips towards a Delaunay triangulation of the clusters: only between
# triangles whose normals are within FLIP_DIHEDRAL degrees (creases stay),
# rounds of independent flips until none is left or FLIP_ROUNDS
FLIP_DIHEDRAL = 20.0
FLIP_ROUNDS = 30


def _manifold_edges(F: np.ndarray):
    """The edges shared by exactly two triangles, in opposite directions:
    (a, b, c, d, f1, f2) with f1 = (a, b, c) and f2 = (b, a, d) up to
    rotation."""
    m = len(F)
    a = F.reshape(-1)
    b = F[:, [1, 2, 0]].reshape(-1)
    c = F[:, [2, 0, 1]].reshape(-1)
    f = np.repeat(np.arange(m), 3)
    key = edge_keys(a, b, int(F.max()) + 1)
    order = np.argsort(key, kind="stable")
    k = key[order]
    cut = np.r_[0, np.nonzero(np.diff(k))[0] + 1, len(k)]
    two = np.nonzero(np.diff(cut) == 2)[0]
    i, j = order[cut[two]], order[cut[two] + 1]
    ok = (a[i] == b[j]) & (b[i] == a[j])
    i, j = i[ok], j[ok]
    return a[i], b[i], c[i], c[j], f[i], f[j]


def flip_to_delaunay(V: np.ndarray, F: np.ndarray, dihedral: float = FLIP_DIHEDRAL,
                     rounds: int = FLIP_ROUNDS) -> np.ndarray:
    """Flip edges whose opposite angles sum to more than pi (the Delaunay
    criterion on the two triangles' hinge), between nearly coplanar
    triangles only, in rounds of flips that share no triangle.  Returns
    the new triangles (same vertices)."""
    F = F.copy()
    cos_max = np.cos(np.radians(dihedral))

    def unit(x):
        return x / np.maximum(np.linalg.norm(x, axis=-1, keepdims=True), 1e-300)

    def angle(p, q, r):  # angle at p of triangle p q r
        return np.arccos(np.clip(np.einsum("ij,ij->i", unit(q - p), unit(r - p)), -1.0, 1.0))

    for _ in range(rounds):
        a, b, c, d, f1, f2 = _manifold_edges(F)
        if not len(a):
            break
        A, B, C, D = V[a], V[b], V[c], V[d]
        n1 = unit(np.cross(B - A, C - A))
        n2 = unit(np.cross(A - B, D - B))
        excess = angle(C, A, B) + angle(D, A, B) - np.pi
        # the flipped pair: (a, d, c) and (b, c, d), facing as the old pair
        m1 = np.cross(D - A, C - A)
        m2 = np.cross(C - B, D - B)
        nm = n1 + n2
        cand = ((excess > 1e-6) & (c != d) & (np.einsum("ij,ij->i", n1, n2) > cos_max)
                & (np.einsum("ij,ij->i", m1, nm) > 0) & (np.einsum("ij,ij->i", m2, nm) > 0))
        # not where the edge (c, d) exists already
        n = int(F.max()) + 1
        have = np.unique(edge_keys(F.reshape(-1), F[:, [1, 2, 0]].reshape(-1), n))
        new = edge_keys(c, d, n)
        cand &= ~np.isin(new, have)
        idx = np.nonzero(cand)[0]
        if not len(idx):
            break
        # independent: each triangle flips with its best candidate only, and
        # no two flips make the same edge
        idx = idx[np.argsort(-excess[idx], kind="stable")]
        rank = np.arange(len(idx))
        first = np.full(len(F), len(idx))
        np.minimum.at(first, np.r_[f1[idx], f2[idx]], np.r_[rank, rank])
        win = idx[(first[f1[idx]] == rank) & (first[f2[idx]] == rank)]
        _, u = np.unique(new[win], return_index=True)
        win = win[u]
        if not len(win):
            break
        F[f1[win]] = np.stack([a[win], d[win], c[win]], axis=1)
        F[f2[win]] = np.stack([b[win], c[win], d[win]], axis=1)
    return F
