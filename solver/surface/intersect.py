"""Which triangles of a surface cross or touch: ``find_crossing_or_contact``
(what validation.py asks), ``find_self_intersection`` and ``find_contact``;
the spatial pruning they share (``candidate_pairs``: pairs whose bounding
boxes and bisected pieces come near), the narrow phases (``_crossing``: an
edge of one triangle properly through the other; ``_contact``: triangles
within a tolerance without sharing a vertex) and the segment predicates
they use (``segment_crosses_triangle``, ``segments_distance``).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import cKDTree

from .trisurface import TriSurface, closest_point_on_triangles


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
