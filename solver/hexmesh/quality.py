"""Stage 6 of hex meshing: quality measures of a hex mesh."""

from __future__ import annotations

import numpy as np

# corner k of a VTK hexahedron and its three neighbours, right-handed
# (Verdict's table for the corner Jacobians)
HEX_CORNER_NEIGHBOURS = np.array([[1, 3, 4], [2, 0, 5], [3, 1, 6], [0, 2, 7],
                                  [7, 5, 0], [4, 6, 1], [5, 7, 2], [6, 4, 3]])
HEX_FACES = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
"""The six faces of a VTK hexahedron, oriented outward."""
HEX_EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                      [0, 4], [1, 5], [2, 6], [3, 7]])


def det3(M: np.ndarray) -> np.ndarray:
    """Determinants of (..., 3, 3) matrices by the triple product (LAPACK's
    batched det is ~20x slower on small matrices)."""
    return np.einsum("...i,...i->...", M[..., 0, :], np.cross(M[..., 1, :], M[..., 2, :]))


def corner_jacobians(V: np.ndarray, H: np.ndarray) -> np.ndarray:
    """(m, 8) scaled Jacobian at each corner: the determinant of the three
    unit edge vectors leaving it (Verdict's corner definition)."""
    P = V[H]  # (m, 8, 3)
    E = P[:, HEX_CORNER_NEIGHBOURS] - P[:, :, None, :]  # (m, 8, 3, 3) rows: edges
    n = np.linalg.norm(E, axis=3, keepdims=True)
    E = E / np.maximum(n, 1e-300)
    return det3(E)


def scaled_jacobian(V: np.ndarray, H: np.ndarray) -> np.ndarray:
    """(m,) minimum corner scaled Jacobian per hex (1 for a cube, <= 0 inverted)."""
    if len(H) == 0:
        return np.zeros(0)
    return corner_jacobians(V, H).min(axis=1)


def boundary_quads(H: np.ndarray) -> np.ndarray:
    """(k, 4) faces held by one hex only, oriented outward; raises where a
    face is held by more than two."""
    Fq = H[:, HEX_FACES].reshape(-1, 4)
    key = np.sort(Fq, axis=1)
    _, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    return Fq[cnt[inv] == 1], int(np.sum(cnt > 2))


def edge_valences(H: np.ndarray, quads: np.ndarray):
    """(edges (k, 2), hexes around each, on the boundary) of a hex mesh."""
    E = np.sort(H[:, HEX_EDGES].reshape(-1, 2), axis=1)
    e, cnt = np.unique(E, axis=0, return_counts=True)
    if len(quads):
        QE = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
        qe = np.unique(QE, axis=0)
        n = int(max(e.max(), qe.max())) + 1
        onb = np.isin(e[:, 0] * n + e[:, 1], qe[:, 0] * n + qe[:, 1])
    else:
        onb = np.zeros(len(e), bool)
    return e, cnt, onb


def euler_characteristic(quads: np.ndarray) -> int:
    """V - E + F of a quad surface."""
    if not len(quads):
        return 0
    QE = np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1)
    return len(np.unique(quads)) - len(np.unique(QE, axis=0)) + len(quads)
