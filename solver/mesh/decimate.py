"""A dense input surface brought down to the mesh scale before fTetWild
(issue 41e).

fTetWild's time grows with its input far more than with its output: a
smooth sphere of 81,920 triangles (the ball's network, h = 0.16) had not
finished meshing after 600 s, the same sphere with 1,280 meshed in 5 s.
Blender users' sculpted or subdivided objects commonly have 1e5-1e6
triangles.  So a surface with over ``DENSE_FACTOR`` times the triangles of
an h-mesh of it (and at least ``MIN_DENSE_TRIANGLES``) is simplified first, to about ``CELL_FRACTION`` h, by
vertex clustering with quadric placement (Lindstrom 2000, "Out-of-core
simplification of large polygonal models"): every vertex falls in a cell
of a grid of that size, each cell becomes one vertex placed where the sum
of the squared distances to the planes of its triangles is least (the
quadric error: it keeps creases and corners the cell contains, where the
mean of the vertices would round them), and triangles whose corners fall
in fewer than three cells vanish.  It is one pass of numpy, linear in the
input (1.3M triangles in seconds), and needs no compiled library.

The clustering is a simplicial map, so the result is a closed 2-chain like
the input: fTetWild (which takes triangle soups) and the winding numbers
of the inside test see the same solid.  It need not be manifold where a
part thinner than the cell collapses; the mesh's boundary is checked
against the input's topology after meshing (meshing.topology_change), as
always.  The input surface stays the reference for everything else
(snapping onto sharp features, the curves, the measures).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..surface.trisurface import TriSurface

# simplify when the surface has this many times the triangles of an h-mesh
# of it (an h-mesh of area A has about A / (sqrt(3)/4 h^2) triangles);
# below it fTetWild's own simplification (tetwild.wants_simplify) does
DENSE_FACTOR = 8.0
# ... and has at least this many triangles: below it fTetWild meshes the
# input as it is in seconds (the 4,480-triangle cylinder 5 s, a
# 5,120-triangle sphere 24 s), and the boundary keeps the input's own
# vertices (a clustering at h/2 leaves chords: the cylinder at h = 0.4 lost
# 0.5% of its radius at the polygon's extremes)
MIN_DENSE_TRIANGLES = 10_000
# grid cell of the clustering, as a fraction of the mesh's edge length h.
# fTetWild's time grows with the input's triangles and falls with their
# quality, and the field suffers from a boundary of coarse chords: the
# ball's network on the 81,920-triangle sphere at h = 0.161 (one run each,
# 2 cores, another job running),
#   cell h:     1,350 triangles, meshing 10-14 s, penalty 5.4-13 (bound ~6.7)
#   cell 0.6 h: 3,738 triangles, meshing 68 s,    penalty 3.98
#   cell 0.5 h: 5,256 triangles, meshing 46 s,    penalty 1.48, converged
# against 0.20 for an unsimplified 5,120-triangle sphere (24 s) and 0.23
# for the 1,280-triangle example: h / 2, the field first
CELL_FRACTION = 0.5
# passes of tangential smoothing of the smooth clusters (onto the input):
# fTetWild takes poorly shaped input triangles slowly (the 81,920-triangle
# sphere clustered at h into 1,404 triangles: 15.5 s raw, 7.8 s smoothed,
# minimum triangle quality 0.08 -> 0.23; 0.7 h: 2,772 triangles, 24.6 -> 13.1 s)
SMOOTH_PASSES = 5
RANK_RATIO = 0.03


@dataclass
class Simplified:
    """What ``simplify_for_meshing`` did: the surface fTetWild gets, the
    triangle counts before and after, the cell size and the relative
    change of the enclosed volume (its vertices lie on the input: chordal
    error only)."""

    surface: TriSurface
    faces_in: int
    faces_out: int
    cell: float
    volume_change: float

    def text(self) -> str:
        return (f"the surface simplified from {self.faces_in:,} to {self.faces_out:,} triangles for the mesher "
                f"(clusters of {self.cell:.3g}, vertices on the input; volume {100 * self.volume_change:+.2g}%)")


def h_mesh_faces(surface: TriSurface, h: float) -> float:
    """About how many triangles an h-mesh of the surface has."""
    return float(surface.face_areas.sum()) / (np.sqrt(3.0) / 4.0 * h * h)


def is_dense(surface: TriSurface, h: float) -> bool:
    """Whether the surface has over DENSE_FACTOR times the triangles of an
    h-mesh of it, and at least MIN_DENSE_TRIANGLES."""
    n = len(surface.F)
    return n >= MIN_DENSE_TRIANGLES and n > DENSE_FACTOR * max(h_mesh_faces(surface, h), 1.0)


def cluster_surface(V: np.ndarray, F: np.ndarray, cell: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertex clustering of the triangle mesh (V, F) on a grid of size cell,
    each cluster placed at the minimum of its quadric error (module
    docstring).  Returns (V', F', smooth): degenerate triangles dropped,
    pairs of the same triangle with opposite orientations cancelled, and
    smooth (#V',): the cluster's triangles span one plane (no crease or
    corner in it)."""
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
    return X[used], Gn.reshape(-1, 3), keep.sum(axis=1)[used] <= 1


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


def simplify_for_meshing(surface: TriSurface, h: float, say=None) -> Simplified | None:
    """The surface fTetWild meshes at edge length h: None where the input
    is not dense (is_dense), else its clustering at CELL_FRACTION h
    (module docstring).  say: a function of a message, for progress."""
    if not is_dense(surface, h):
        return None
    cell = CELL_FRACTION * h
    if say is not None:
        say(f"tetmesh: simplifying the surface ({len(surface.F):,} triangles, ~{h_mesh_faces(surface, h):,.0f} "
            f"at the mesh scale {h:.3g})...")
    V, F, smooth = cluster_surface(surface.V, surface.F, cell)
    V = _smooth_onto(surface, V, F, smooth, SMOOTH_PASSES)
    out = TriSurface(V, F)
    v0 = float(surface.signed_volumes().sum())
    res = Simplified(out, len(surface.F), len(F), cell, float(out.signed_volumes().sum()) / v0 - 1.0)
    if say is not None:
        say(f"tetmesh: {res.text()}")
    return res
