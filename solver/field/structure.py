"""The discrete structure equation (Eq. 17) and its Jacobian.

For a face abc with edges (ab, bc, ac) and omega_ca = -omega_ac, write
A = omega_ab, B = omega_bc, C = omega_ca.  The residual is

    r = A + B + C - (omega ^ omega)_abc - Omega_abc                 (Eq. 17/19)

with the primal-primal wedge of discrete exterior calculus (Eq. 18)

    (omega ^ omega)_abc = 1/2 (w_b [A, B] + w_c [B, C] + w_a [C, A]),

where w_p are the Voronoi area fractions at the corners and [x^, y^] = (x cross y)^.

Note on Eq. 18 as printed: its prefactor 1/(6 A_ijk) and bracket order give
-1/3 of this value.  The form above is the one whose zero set agrees with the
monodromy exp(C) exp(B) exp(A) = exp(Omega) to second order (BCH, averaged
over the three base points) under our development convention
E_j = exp(omega_ij) E_i; ``tests/test_structure.py`` checks that residuals of
smooth frame fields vanish to third order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..linalg.rotations import hat

_cross_mat = hat  # [v]_x for v (n, 3) -> (n, 3, 3)


@dataclass
class StructureEquation:
    """Residuals of Eq. 17 on a set of faces.

    face_edges : (m, 3) edge ids (ab, bc, ac)
    weights    : (m, 3) corner weights (w_a, w_b, w_c)
    Omega      : (m, 3) prescribed curvature
    n_edges    : total number of edges
    """

    face_edges: np.ndarray
    weights: np.ndarray
    Omega: np.ndarray
    n_edges: int

    def _abc(self, omega):
        fe = self.face_edges
        return omega[fe[:, 0]], omega[fe[:, 1]], -omega[fe[:, 2]]

    def wedge(self, omega: np.ndarray) -> np.ndarray:
        A, B, C = self._abc(omega)
        wa, wb, wc = (self.weights[:, k, None] for k in range(3))
        return 0.5 * (wb * np.cross(A, B) + wc * np.cross(B, C) + wa * np.cross(C, A))

    def residual(self, omega: np.ndarray, linear: bool = False) -> np.ndarray:
        """(m, 3) residual; ``linear`` drops the wedge term (the linear
        initialisation of §5.2)."""
        A, B, C = self._abc(omega)
        r = A + B + C - self.Omega
        if not linear:
            r = r - self.wedge(omega)
        return r

    def jacobian_blocks(self, omega: np.ndarray, linear: bool = False) -> np.ndarray:
        """(m, 3, 3, 3): d r_f / d omega_{e_k} for the k-th edge of each face."""
        m = len(self.face_edges)
        I = np.broadcast_to(np.eye(3), (m, 3, 3))
        if linear:
            J = np.stack([I, I, -I], axis=1)
            return np.ascontiguousarray(J)
        A, B, C = self._abc(omega)
        wa, wb, wc = (self.weights[:, k, None, None] for k in range(3))
        XA, XB, XC = _cross_mat(A), _cross_mat(B), _cross_mat(C)
        JA = I + 0.5 * wb * XB - 0.5 * wa * XC
        JB = I - 0.5 * wb * XA + 0.5 * wc * XC
        JC = I - 0.5 * wc * XB + 0.5 * wa * XA
        return np.stack([JA, JB, -JC], axis=1)

    def jacobian(self, omega: np.ndarray, linear: bool = False) -> sp.csr_matrix:
        """Sparse (3m x 3 n_edges) Jacobian."""
        return self.assemble(self.jacobian_blocks(omega, linear))

    def residual_hessian(self, mu: np.ndarray) -> sp.csr_matrix:
        """The (3 n_edges)^2 Hessian of sum_f mu_f . r_f(omega) for fixed
        weights mu (m, 3): the second-order term that Gauss-Newton drops
        (assembled from residual_hessian_blocks)."""
        return self.assemble_blocks(self.residual_hessian_blocks(mu))

    def residual_hessian_blocks(self, mu: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """(m, 9, 9) per-face blocks of residual_hessian (row/column 3k + i:
        component i of the face's k-th edge).  r is quadratic in omega (the
        wedge of Eq. 18), so they do not depend on omega.  With [mu] the
        cross-product matrix, the face term -1/2 w_b mu . (A x B) =
        1/2 w_b A^T [mu] B couples A and B by 1/2 w_b [mu] (and B, A by its
        transpose), likewise (B, C) with w_c and (C, A) with w_a; C = -omega_ac
        flips the sign of the blocks that touch the third edge.  Written into
        ``out`` (m, 9, 9) if given."""
        m = len(self.face_edges)
        wa, wb, wc = (self.weights[:, k, None, None] for k in range(3))
        M = 0.5 * _cross_mat(mu)
        # (face, row slot, component, column slot, component)
        Q = np.zeros((m, 3, 3, 3, 3)) if out is None else out.reshape(m, 3, 3, 3, 3)
        if out is not None:
            Q[:, 0, :, 0, :] = Q[:, 1, :, 1, :] = Q[:, 2, :, 2, :] = 0.0  # the blocks set below cover the rest
        for p, q, blk in ((0, 1, wb * M), (1, 2, -wc * M), (2, 0, -wa * M)):
            Q[:, p, :, q, :] = blk
            Q[:, q, :, p, :] = np.swapaxes(blk, 1, 2)
        return Q.reshape(m, 9, 9)

    def assemble_blocks(self, Q: np.ndarray) -> sp.csr_matrix:
        """The (3 n_edges)^2 sparse matrix sum_f E_f^T Q_f E_f of per-face
        (m, 9, 9) blocks."""
        dof = (3 * self.face_edges[:, :, None] + np.arange(3)).reshape(-1, 9)
        rows = np.broadcast_to(dof[:, :, None], Q.shape).reshape(-1)
        cols = np.broadcast_to(dof[:, None, :], Q.shape).reshape(-1)
        n = 3 * self.n_edges
        return sp.csr_matrix((Q.reshape(-1), (rows, cols)), shape=(n, n))

    def jacobian_transpose_product(self, Jb: np.ndarray, r: np.ndarray) -> np.ndarray:
        """J^T r as (n_edges, 3), from jacobian_blocks Jb and residuals r (m, 3)."""
        JTr = np.einsum("mkij,mi->mkj", Jb, r)
        fe = self.face_edges.reshape(-1)
        return np.stack([np.bincount(fe, weights=JTr[:, :, c].reshape(-1), minlength=self.n_edges)
                         for c in range(3)], axis=1)

    def assemble(self, Jb: np.ndarray) -> sp.csr_matrix:
        """Sparse Jacobian from jacobian_blocks."""
        m = len(self.face_edges)
        rows = (3 * np.arange(m)[:, None, None, None] + np.arange(3)[None, None, :, None])
        cols = (3 * self.face_edges[:, :, None, None] + np.arange(3)[None, None, None, :])
        rows = np.broadcast_to(rows, Jb.shape).reshape(-1)
        cols = np.broadcast_to(cols, Jb.shape).reshape(-1)
        return sp.csr_matrix((Jb.reshape(-1), (rows, cols)), shape=(3 * m, 3 * self.n_edges))
