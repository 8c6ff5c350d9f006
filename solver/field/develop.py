"""Field integration (§3.4, §4.3): breadth-first development of omega.

E_j = exp(omega_ij) E_i along the edges of a breadth-first tree from a root
(Eq. 8 with R_ij = I).  Path products are formed by pointer jumping, so the
work is O(#V log depth) in vectorised numpy rather than a loop over vertices.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from ..linalg.rotations import CUBE_GROUP, exp_so3, rotation_angle
from ..mesh.tetmesh import TetMesh


def _ancestors(order: np.ndarray, pred: np.ndarray):
    """Parent pointers for pointer jumping: the root points to itself, and so
    do vertices the tree does not reach (flagged in the returned mask)."""
    root = order[0]
    anc = pred.copy()
    anc[root] = root
    reached = np.zeros(len(anc), bool)
    reached[order] = True
    anc[~reached] = root
    return root, anc, reached


def accumulate_along_tree(order, pred, inc, root_value=0.0):
    """value[v] = value[pred[v]] + inc[v] over a tree; value[root] = root_value.
    Vertices the tree does not reach get NaN."""
    root, anc, reached = _ancestors(order, pred)
    S = np.asarray(inc, dtype=float).copy()
    S[root] = 0.0
    # invariant: value(v) = S[v] + value(anc[v])
    while np.any(anc != root):
        S = S + S[anc]
        anc = anc[anc]
    out = S + root_value
    out[~reached] = np.nan
    return out


def multiply_along_tree(order, pred, M, root_value):
    """E[v] = M[v] @ E[pred[v]] over a tree, E[root] = root_value.
    M : (#V, 3, 3); vertices the tree does not reach get NaN."""
    root, anc, reached = _ancestors(order, pred)
    P = np.array(M, dtype=float, copy=True)
    P[root] = np.eye(3)
    # invariant: E(v) = P[v] @ E(anc[v])
    while True:
        m = anc != root
        if not np.any(m):
            break
        P[m] = np.einsum("nij,njk->nik", P[m], P[anc[m]])
        anc = anc[anc]
    out = P @ np.asarray(root_value, dtype=float)
    out[~reached] = np.nan
    return out


def development_tree(mesh: TetMesh, root: int, avoid_edges: np.ndarray | None = None):
    """Breadth-first tree from root on the edge graph (order, predecessors).

    avoid_edges : optional (#E,) bool mask of edges to use only when nothing
    else reaches a vertex (edges inside node regions, where omega is not
    integrable).  The tree is then a shortest-path tree with those edges
    weighted heavily, which is a BFS tree on the rest.
    """
    E = mesh.edges
    n = mesh.n_vertices
    if avoid_edges is None or not np.any(avoid_edges):
        order, pred = csgraph.breadth_first_order(mesh.vertex_adjacency, int(root), directed=False,
                                                  return_predecessors=True)
    else:
        w = np.where(avoid_edges, 1e6, 1.0)
        A = sp.coo_matrix((np.r_[w, w], (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])), shape=(n, n)).tocsr()
        dist, pred = csgraph.dijkstra(A, indices=int(root), return_predecessors=True)
        pred = np.where(np.isfinite(dist), pred, -9999)
        order = np.argsort(dist, kind="stable")
        order = order[np.isfinite(dist[order])]
    if len(order) != n:
        raise ValueError("the tetrahedral mesh is not connected")
    return order, pred


def develop(mesh: TetMesh, omega: np.ndarray, root: int, E_root: np.ndarray,
            avoid_edges: np.ndarray | None = None) -> np.ndarray:
    """Frames (#V, 3, 3) developed from `root`, where the frame is E_root
    (Eq. 8 with R_ij = I, along a breadth-first tree).

    omega : (#E, 3) Darboux derivative per edge (low -> high vertex id).
    """
    order, pred = development_tree(mesh, root, avoid_edges)
    child = order[1:]
    par = pred[child]
    e = mesh.edge_index(par, child)
    sign = np.where(par < child, 1.0, -1.0)
    M = np.broadcast_to(np.eye(3), (mesh.n_vertices, 3, 3)).copy()
    M[child] = exp_so3(sign[:, None] * omega[e])
    return multiply_along_tree(order, pred, M, E_root)


def symmetric_turn(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray, axis: int,
                   skip_edges: np.ndarray | None = None, min_angle: float = np.radians(5.0)) -> float:
    """The turn theta about the frames' local axis ``axis`` that makes the
    developed field a consistent cross field (§4.2.3, Fig. 8).

    omega fixes the frames only up to one global rotation, and the boundary
    constraint (Eq. 20) leaves the rotation about the root's normal free: a
    common shift of every alpha does not change omega.  That turn is not
    arbitrary, though.  Around a singular curve the monodromy of omega is a
    quarter turn about the curve tangent, which is a symmetry of the frame
    only if the frame is adapted to the tangent; with the wrong turn, frames
    developed along different paths around a curve disagree by a rotation
    that is no cube symmetry.

    The frames E_i (developed with theta = 0) give, per edge, the mismatch
    M_ij = E_j^T exp(omega_ij) E_i: the identity on the development tree and a
    cube symmetry across its cuts when the field is consistent.  Turning
    every frame by R(theta) about its local axis conjugates M_ij by R(theta);
    we return the theta in [-pi/4, pi/4) that brings the mismatches closest to
    cube symmetries (least squares of the residual angles), or 0.0 when no
    edge constrains it (no interior singular curve: every turn is
    consistent).
    """
    E = mesh.edges
    keep = np.ones(mesh.n_edges, bool) if skip_edges is None else ~skip_edges
    M = np.einsum("nji,njk,nkl->nil", frames[E[keep, 1]], exp_so3(omega[keep]), frames[E[keep, 0]])
    M = M[rotation_angle(M) > min_angle]
    if len(M) == 0:
        return 0.0
    G = CUBE_GROUP.reshape(len(CUBE_GROUP), 9)

    def cost(theta):
        theta = np.atleast_1d(theta)
        R = exp_so3(np.outer(theta, np.eye(3)[axis]))  # (t, 3, 3)
        C = np.einsum("tji,njk,tkl->tnil", R, M, R).reshape(len(theta), len(M), 9)
        tr = (C @ G.T).max(axis=2)  # trace(C g^T), best symmetry per edge
        ang = np.arccos(np.clip((tr - 1.0) / 2.0, -1.0, 1.0))
        return np.sum(ang**2, axis=1)

    # the cost has period pi/2 in theta (quarter turns about a frame axis
    # are symmetries): scan it, then refine the best bracket by golden section
    grid = np.linspace(-np.pi / 4, np.pi / 4, 91)[:-1]
    f = np.concatenate([cost(grid[k:k + 10]) for k in range(0, len(grid), 10)])
    if f.max() - f.min() <= 1e-9 * max(f.max(), 1e-300):
        return 0.0
    k = int(np.argmin(f))
    step = grid[1] - grid[0]
    a, b = grid[k] - step, grid[k] + step
    g = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = cost(c)[0], cost(d)[0]
    for _ in range(40):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = cost(c)[0]
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = cost(d)[0]
    theta = 0.5 * (a + b)
    return float((theta + np.pi / 4) % (np.pi / 2) - np.pi / 4)
