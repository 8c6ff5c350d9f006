"""Polycube labelling of a closed surface: a frame aligned to the solid, and one
of the six directions +-X, +-Y, +-Z per boundary triangle.

Labels are 0..5 for +X, -X, +Y, -Y, +Z, -Z: label ``2 a + s`` is axis ``a``,
sign ``+`` for ``s = 0``; ``l ^ 1`` is the opposite label.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.optimize import minimize
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

from ..surface.trisurface import TriSurface

LABEL_NAMES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
DIRECTIONS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def _alignment_energy(R: np.ndarray, N: np.ndarray, A: np.ndarray) -> float:
    """Minus the area-weighted sum of the fourth powers of the rotated
    normals' coordinates: lowest where the normals lie on the axes."""
    D = N @ R.T
    return -float(A @ np.sum(D**4, axis=1))


def align_frame(S: TriSurface) -> np.ndarray:
    """A rotation R (3 x 3, rows: the frame's axes in world coordinates) that
    puts the surface normals as near the axes as it can (the polycube
    fidelity, L4 norm of the normals), started from the world axes and
    from the principal axes of the surface; ties keep the world axes."""
    N, A = S.face_normals, S.face_areas / S.face_areas.sum()
    P = S.V[S.F].mean(axis=1)
    c = A @ P
    C = (P - c).T @ ((P - c) * A[:, None])
    _, vec = np.linalg.eigh(C)
    starts = [np.eye(3), vec.T * np.sign(np.linalg.det(vec))]
    best, best_e = np.eye(3), _alignment_energy(np.eye(3), N, A)

    def energy(r, R0):
        return _alignment_energy(Rotation.from_rotvec(r).as_matrix() @ R0, N, A)

    for R0 in starts:
        res = minimize(energy, np.zeros(3), args=(R0,), method="Nelder-Mead",
                       options={"xatol": 1e-5, "fatol": 1e-9, "maxiter": 600})
        R = Rotation.from_rotvec(res.x).as_matrix() @ R0
        if res.fun < best_e - 1e-6:
            best, best_e = R, float(res.fun)
    return best


def face_adjacency(S: TriSurface, keep: np.ndarray | None = None) -> sp.csr_matrix:
    """Face-to-face adjacency through edges weighted by edge length (only the
    edges where keep is True)."""
    ef = S.edge_faces
    E = S.edges
    w = np.linalg.norm(S.V[E[:, 1]] - S.V[E[:, 0]], axis=1)
    if keep is not None:
        ef, w = ef[keep], w[keep]
    n = len(S.F)
    return sp.coo_matrix((np.r_[w, w], (np.r_[ef[:, 0], ef[:, 1]], np.r_[ef[:, 1], ef[:, 0]])), shape=(n, n)).tocsr()


def label_scores(D: np.ndarray) -> np.ndarray:
    """(n, 6): the components of n directions (in the polycube's frame) along
    +X, -X, +Y, -Y, +Z, -Z, the labels' order."""
    return np.c_[D[:, 0], -D[:, 0], D[:, 1], -D[:, 1], D[:, 2], -D[:, 2]]


def label_faces(S: TriSurface, R: np.ndarray, sharp: np.ndarray, smoothing: float,
                position: float = 0.0, blend: bool = False, gate: float = 0.25,
                creased_position: float = 0.4) -> np.ndarray:
    """Labels 0..5 per face: fidelity to the normal in the frame R, made
    compact by diffusing the six scores over the surface (not across sharp
    edges) for a length of about ``smoothing`` before taking the best;
    ``position`` weighs in the direction of the face from the centre, scaled
    to the bounding box (a box projection; 0: the normals alone): added to
    the normals' scores, or with ``blend`` blended with them (1: the box
    projection's label where the face looks straight out from the centre),
    for the directions within acos(gate) of the normal and only on smooth
    patches no sharp crease bounds."""
    D = S.face_normals @ R.T
    normal_score = np.maximum(label_scores(D), 0.0)
    score = normal_score
    if position > 0:
        # the direction from the centre scaled to the bounding box (in R): a
        # box projection, which keeps the charts of elongated smooth solids
        # from shrinking to the tips where the normals point along an axis
        X = S.V[S.F].mean(axis=1) @ R.T
        lo, hi = X.min(axis=0), X.max(axis=0)
        Y = (X - 0.5 * (lo + hi)) / np.maximum(0.5 * (hi - lo), 1e-300)
        Y /= np.maximum(np.linalg.norm(Y, axis=1, keepdims=True), 1e-300)
        B = np.maximum(label_scores(Y), 0.0)
        # weighed by how much the face looks away from the centre (not in a
        # hole or a dent, where the direction from the centre is no guide)
        out = np.maximum(np.einsum("ij,ij->i", Y, D), 0.0)
        added = score + position * out[:, None] * B
        if blend:
            # blended, not added: at a corner of the box projection its three
            # directions score alike, so an added term cannot move a corner
            # there (a flat ellipsoid's corners stay near where its normals
            # turn); only for a direction within acos(gate) of the normal,
            # and only on smooth patches no sharp crease bounds (a cylinder's
            # wall, a bar's sides keep the added rule at creased_position)
            w = np.minimum(position * out, 0.95)[:, None]
            blended = (1.0 - w) * score + w * B * np.clip(score / gate, 0.0, 1.0)
            if np.any(sharp):
                _, comp = connected_components(face_adjacency(S, ~sharp), directed=False)
                creased = np.zeros(comp.max() + 1, bool)
                creased[comp[S.edge_faces[sharp].ravel()]] = True
                kept = score + creased_position * out[:, None] * B
                blended = np.where(creased[comp][:, None], kept, blended)
            added = blended
        score = added
    W = face_adjacency(S, ~sharp)
    deg = np.asarray(W.sum(axis=1)).ravel()
    P = sp.diags(1.0 / np.maximum(deg, 1e-300)) @ W
    # a random walk of k steps of mean length l spreads over about l sqrt(k)
    step = float(np.mean(np.linalg.norm(S.V[S.edges[:, 1]] - S.V[S.edges[:, 0]], axis=1)))
    k = int(min(400, max(0, (smoothing / max(step, 1e-300)) ** 2)))
    s = score.copy()
    for _ in range(k):
        s = 0.5 * s + 0.5 * (P @ s)
    s = np.where(deg[:, None] > 0, s, score)
    labels = np.argmax(s + 1e-9 * score, axis=1)
    return _flat_patches_whole(S, sharp, labels, normal_score)


def _flat_patches_whole(S: TriSurface, sharp: np.ndarray, labels: np.ndarray, normal_score: np.ndarray,
                        flat_deg: float = 5.0) -> np.ndarray:
    """One label per flat patch (faces between sharp edges whose normals
    stay within flat_deg of their mean): the one its normal scores best,
    so that no chart boundary crosses a flat face (a padding curve under a
    flat face would make the field turn where nothing turns)."""
    n, comp = connected_components(face_adjacency(S, ~sharp), directed=False)
    A = S.face_areas
    N = np.zeros((n, 3))
    np.add.at(N, comp, S.face_normals * A[:, None])
    N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
    dev = np.zeros(n)
    np.maximum.at(dev, comp, 1.0 - np.einsum("ij,ij->i", S.face_normals, N[comp]))
    flat = dev < 1.0 - np.cos(np.radians(flat_deg))
    best = np.zeros((n, 6))
    np.add.at(best, comp, normal_score * A[:, None])
    out = labels.copy()
    m = flat[comp]
    out[m] = np.argmax(best, axis=1)[comp[m]]
    return out


def charts_of(S: TriSurface, labels: np.ndarray) -> tuple[int, np.ndarray]:
    """Connected components of faces of one label: (count, chart per face)."""
    ef = S.edge_faces
    same = labels[ef[:, 0]] == labels[ef[:, 1]]
    return connected_components(face_adjacency(S, same), directed=False)


def merge_small_charts(S: TriSurface, labels: np.ndarray, min_area: float, rounds: int = 20) -> np.ndarray:
    """Relabel charts of area below min_area (and charts that touch a chart of
    the opposite label along a boundary shorter than their own) with the
    label of the neighbour they share most boundary with, never its
    opposite; repeated until none is left or rounds run out."""
    labels = labels.copy()
    ef = S.edge_faces
    E = S.edges
    w = np.linalg.norm(S.V[E[:, 1]] - S.V[E[:, 0]], axis=1)
    for _ in range(rounds):
        n, chart = charts_of(S, labels)
        area = np.bincount(chart, S.face_areas, n)
        ca, cb = chart[ef[:, 0]], chart[ef[:, 1]]
        cross = ca != cb
        la = np.zeros(n, int)
        la[chart] = labels
        opposite = cross & ((labels[ef[:, 0]] ^ 1) == labels[ef[:, 1]])
        bad = area < min_area
        if np.any(opposite):
            # the smaller chart of each opposite pair gives way
            i, j = ca[opposite], cb[opposite]
            bad[np.where(area[i] <= area[j], i, j)] = True
        if not np.any(bad):
            break
        # shared boundary length per (bad chart, neighbour label)
        M = np.zeros((n, 6))
        for x, y in ((ca, cb), (cb, ca)):
            m = cross & bad[x]
            np.add.at(M, (x[m], la[y[m]]), w[m])
        M[np.arange(n), la] = 0.0
        M[np.arange(n), la ^ 1] = 0.0
        # one chart per round among neighbours: the smallest bad ones first
        order = np.argsort(area)
        changed = np.zeros(n, bool)
        blocked = np.zeros(n, bool)
        Adj = sp.coo_matrix((np.ones(int(cross.sum())), (ca[cross], cb[cross])), shape=(n, n)).tocsr()
        for c in order[bad[order]]:
            if blocked[c] or M[c].max() <= 0:
                continue
            la[c] = int(np.argmax(M[c]))
            changed[c] = True
            blocked[Adj[c].indices] = True
        if not np.any(changed):
            break
        labels = la[chart]
    return labels
