"""The Levenberg-Marquardt matrices of Eq. 23, assembled in x space with a
sparsity pattern fixed once per problem.

The penalty term a sum_f |r_f|^2 couples only the three edges of each face,
so its Gauss-Newton Hessian (and the second-order term that Newton adds) is
a sum of one dense 9 x 9 block Q_f per face (three so(3) values),

    H_x = P^T (sum_f E_f^T Q_f E_f) P + 2 P^T W P,

with E_f picking the face's edges from omega and P the constraint map
omega = c + P x (constraints.py).  P does not change during a solve, so
every entry of H_x is a fixed linear combination of the entries of the Q_f:
``FaceAssembly`` finds those combinations once (a sparse matrix S from the
stacked Q_f to the values of H_x in a fixed CSR pattern), and each LM
iteration then costs one batched matmul for the Q_f and one sparse product.

Why assemble at all: PCG multiplies by H a few hundred times per LM
iteration, and one product with the assembled H reads about as many bytes
as the product with J alone, where the matrix-free form reads J, J^T, the
Newton term and three vectors (bench/RESULTS.md: 5.5 ms against 10.8 ms
per product at 78k tets).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .parallel import parallel

# faces per chunk while S is built: bounds the temporary index arrays
_CHUNK = 16384


class FaceAssembly:
    """Assembles P^T (sum_f E_f^T Q_f E_f) P + C for per-face (9, 9) blocks.

    face_edges : (m, 3) edge ids; block row/column 3k + i is component i of
                 the face's k-th edge
    P          : (3 #E, n) constraint map, constant
    extra      : a constant (n, n) matrix C added to every result (the
                 smoothness term 2 P^T W P); its pattern joins H's
    pattern    : further (n, n) entries to keep in the pattern (values
                 ignored), e.g. whole diagonal blocks that are read back
    """

    def __init__(self, face_edges: np.ndarray, P: sp.spmatrix, extra: sp.spmatrix | None = None,
                 pattern: sp.spmatrix | None = None):
        P = sp.csr_matrix(P)
        P.sum_duplicates()
        P.eliminate_zeros()  # a stored zero of P adds nothing
        n = self.n = P.shape[1]
        self.m = len(face_edges)
        fe = np.ascontiguousarray(face_edges, dtype=np.int64)
        # omega dof of every row/column of every face block: (m, 9)
        dof = (3 * fe[:, :, None] + np.arange(3)).reshape(self.m, 9)
        keys, cols, vals = [], [], []
        for f0 in range(0, self.m, _CHUNK):
            xr, xc, v, t = _expand(dof[f0:f0 + _CHUNK], P)
            keys.append(xr.astype(np.int64) * n + xc)
            cols.append(t + 81 * f0)
            vals.append(v)
        n_face_keys = sum(len(k) for k in keys)
        # the pattern also holds the diagonal, the extra term and the
        # requested entries
        for M in (sp.eye(n), extra, pattern):
            if M is not None:
                C = sp.coo_matrix(M)
                keys.append(C.row.astype(np.int64) * n + C.col)
        self._keys, inv = np.unique(np.concatenate(keys), return_inverse=True)
        self.nnz = len(self._keys)
        rows = self._keys // n
        self.indices = self._keys - rows * n
        self.indptr = np.r_[0, np.cumsum(np.bincount(rows, minlength=n))]
        self.S = parallel(sp.csr_matrix((np.concatenate(vals) if vals else np.zeros(0),
                                         (inv[:n_face_keys], np.concatenate(cols) if cols else np.zeros(0, int))),
                                        shape=(self.nnz, 81 * self.m)))
        self.diagonal_positions = self.positions(np.arange(n), np.arange(n))
        self.extra_data = np.zeros(self.nnz)
        if extra is not None:
            C = sp.coo_matrix(extra)
            self.extra_data = np.bincount(self.positions(C.row, C.col), weights=C.data, minlength=self.nnz)

    def positions(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Index into the CSR values of the entries (rows, cols) of the pattern."""
        keys = np.asarray(rows, np.int64) * self.n + np.asarray(cols, np.int64)
        pos = np.searchsorted(self._keys, keys)
        if len(pos) and (pos.max() >= self.nnz or np.any(self._keys[pos] != keys)):
            raise ValueError("FaceAssembly: entry outside the sparsity pattern")
        return pos

    def data(self, Q: np.ndarray) -> np.ndarray:
        """CSR values of P^T (sum_f E_f^T Q_f E_f) P (without the extra term)."""
        return self.S @ np.ascontiguousarray(Q, dtype=float).reshape(-1)

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """A CSR matrix with the fixed pattern and these values (no copy)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


def _expand(dof: np.ndarray, P: sp.csr_matrix):
    """The x-space entries that the face-block entries of these faces feed:
    block entry (a, b) of a face (omega dofs R, C) adds Q[a, b] P[R, i] P[C, j]
    to H[i, j] for every nonzero of P's rows R and C.  Returns (i, j, P[R, i]
    P[C, j], index of the block entry among these faces' 81 per face)."""
    R = np.repeat(dof, 9, axis=1).reshape(-1)
    C = np.tile(dof, (1, 9)).reshape(-1)
    nr = np.diff(P.indptr)
    nR, nC = nr[R], nr[C]
    # most omega dofs are one unknown each (free edges): one entry apiece
    one = np.nonzero((nR == 1) & (nC == 1))[0]
    pi, qi = P.indptr[R[one]], P.indptr[C[one]]
    out = [(P.indices[pi], P.indices[qi], P.data[pi] * P.data[qi], one)]
    many = np.nonzero((nR * nC > 0) & ~((nR == 1) & (nC == 1)))[0]
    if len(many):
        cnt = nR[many] * nC[many]
        owner = np.repeat(many, cnt)
        o = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        ncol = nC[owner]
        pi = P.indptr[R[owner]] + o // ncol
        qi = P.indptr[C[owner]] + o % ncol
        out.append((P.indices[pi], P.indices[qi], P.data[pi] * P.data[qi], owner))
    return tuple(np.concatenate(z) for z in zip(*out))


def gauss_newton_blocks(Jb: np.ndarray, scale: float, out: np.ndarray | None = None) -> np.ndarray:
    """(m, 9, 9) blocks scale * J_f^T J_f from the (m, 3, 3, 3) Jacobian
    blocks d r_f / d omega_{e_k} (structure.jacobian_blocks), written into
    ``out`` if given."""
    m = len(Jb)
    B = Jb.transpose(0, 2, 1, 3).reshape(m, 3, 9)  # J_f: residual component x (edge slot, component)
    Q = np.matmul(B.transpose(0, 2, 1), B, out=out)  # batched matmul: ~9x faster than the einsum here
    Q *= scale
    return Q
