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
stacked Q_f to the values of H_x's upper triangle in a fixed CSR pattern),
and each LM iteration then costs one batched matmul for the Q_f, one sparse
product and a gather that fills in the lower triangle.

Why assemble at all: PCG multiplies by H a few hundred times per LM
iteration, and one product with the assembled H reads about as many bytes
as the product with J alone, where the matrix-free form reads J, J^T, the
Newton term and three vectors (bench/RESULTS.md: 5.5 ms against 10.8 ms
per product at 78k tets).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from ..linalg.parallel import RowSplitMatrix, parallel

# faces per chunk while S is built: bounds the temporary index arrays
_CHUNK = 16384


class FaceAssembly:
    """Assembles P^T (sum_f E_f^T Q_f E_f) P + C for symmetric per-face
    (9, 9) blocks.

    face_edges : (m, 3) edge ids; block row/column 3k + i is component i of
                 the face's k-th edge
    P          : (3 #E, n) constraint map, constant
    extra      : a constant symmetric (n, n) matrix C added to every result
                 (the smoothness term 2 P^T W P); its pattern joins H's
    pattern    : further (n, n) entries to keep in the pattern (values
                 ignored), e.g. whole diagonal blocks that are read back

    H is symmetric, so S holds only its upper triangle (i <= j), fed by the
    block entries a <= b (45 of the 81 per face), and ``data`` copies each
    value to its mirror entry (so H is exactly symmetric).  Building S is a
    sort of these keys, and what that costs is mostly first touches of new
    memory (this VM faults pages in at ~3 ms per MB): with half the keys, S
    built as CSR straight from the sorted keys (no inverse index, no COO
    conversion) and few other new arrays, the volume problem's setup at 98k
    tets went from 5.6 to 2.8 s (bench/RESULTS.md).
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
            k, t, v = _upper_entries(dof[f0:f0 + _CHUNK], P)
            keys.append(k)
            cols.append((t + 81 * f0).astype(np.int32 if 81 * self.m < 2**31 else np.int64))
            vals.append(v)
        keys = np.concatenate(keys) if keys else np.zeros(0, np.int64)
        # sorted by key, the face entries are S's rows in order: S is built
        # as CSR directly (no inverse index, no COO conversion)
        order = np.argsort(keys)
        keys = keys[order]
        first = np.r_[True, keys[1:] != keys[:-1]] if len(keys) else np.zeros(0, bool)
        starts = np.flatnonzero(first)
        ukeys = keys[starts]
        counts = np.diff(np.r_[starts, len(keys)])
        del keys, first
        # the pattern also holds the diagonal, the extra term and the
        # requested entries (their upper-triangle keys), merged into the
        # sorted face keys
        more = [np.arange(n, dtype=np.int64) * (n + 1)]
        for M in (extra, pattern):
            if M is not None:
                C = sp.coo_matrix(M)
                lo, hi = np.minimum(C.row, C.col).astype(np.int64), np.maximum(C.row, C.col).astype(np.int64)
                more.append(lo * n + hi)
        more = np.unique(np.concatenate(more))
        pos = np.searchsorted(ukeys, more)
        inside = pos < len(ukeys)
        missing = np.ones(len(more), bool)
        missing[inside] = ukeys[pos[inside]] != more[inside]
        if np.any(missing):
            up_keys = np.insert(ukeys, pos[missing], more[missing])
            # the row of S of every face key: shifted by the keys inserted before it
            row_counts = np.zeros(len(up_keys), np.int64)
            k = np.arange(len(ukeys))
            row_counts[k + np.searchsorted(pos[missing], k, side="right")] = counts
        else:
            up_keys, row_counts = ukeys, counts
        n_up = len(up_keys)
        cols = np.concatenate(cols) if cols else np.zeros(0, np.int32)
        vals = np.concatenate(vals) if vals else np.zeros(0)
        self._up = None  # kept space for S's products (see data)
        self.S = parallel(sp.csr_matrix((vals[order], cols[order], np.r_[0, np.cumsum(row_counts)]),
                                        shape=(n_up, 81 * self.m)))
        del order, cols, vals
        # the full pattern: the upper triangle and its mirror image, merged
        # row by row by SciPy (the two strict triangles do not overlap); the
        # values carry each entry's upper-triangle index + 1
        # (fresh memory is what costs here, so few new arrays: int64
        # values, offsets made in place)
        ur = up_keys // n
        U = sp.csr_matrix((np.arange(1, n_up + 1, dtype=np.int64), up_keys - ur * n,
                           np.r_[0, np.cumsum(np.bincount(ur, minlength=n))]), shape=(n, n))
        del ur, up_keys
        H = (U + sp.triu(U, k=1).T.tocsr()).tocsr()
        H.sort_indices()
        self.indices, self.indptr = H.indices, H.indptr
        self.nnz = H.nnz
        self._mirror = H.data
        self._mirror -= 1
        self._keys = np.repeat(np.arange(n, dtype=np.int64) * n, np.diff(self.indptr))
        self._keys += self.indices
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

    def data(self, Q: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """CSR values of P^T (sum_f E_f^T Q_f E_f) P (without the extra
        term) for symmetric Q_f (their upper triangles are read), written
        into ``out`` (nnz values) if given.

        Both the upper triangle and the values are written into kept
        arrays where they can be: a fresh array of this size is new pages
        each time (glibc maps it anew), and faulting them in cost more than
        the products (196k tets: the gather 0.24 s into a new array)."""
        q = np.ascontiguousarray(Q, dtype=float).reshape(-1)
        if isinstance(self.S, RowSplitMatrix):
            if self._up is None:
                self._up = np.empty(self.S.shape[0])
            up = self.S.matvec(q, out=self._up)
        else:
            up = self.S @ q
        if out is None:
            out = np.empty(self.nnz)
        # (a plain gather; by index ranges on the thread pool, or with
        # int32 indices, it was slower.  mode="clip" skips the index check,
        # with which np.take buffers its output)
        return np.take(up, self._mirror, out=out, mode="clip")

    def matrix(self, data: np.ndarray) -> sp.csr_matrix:
        """A CSR matrix with the fixed pattern and these values (no copy)."""
        return sp.csr_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))


# the 45 entries a <= b of a symmetric 9 x 9 block, their flat index 9a + b,
# and whether they lie on its diagonal
_IA, _IB = np.triu_indices(9)
_FLAT = 9 * _IA + _IB
_ON_DIAG = _IA == _IB


def _upper_entries(dof: np.ndarray, P: sp.csr_matrix):
    """The upper-triangle x-space entries that these faces' blocks feed.

    Block entry (a, b) of a face (omega dofs R, C) adds Q[a, b] P[R, i]
    P[C, j] to H[i, j] for every nonzero of P's rows R and C; for a < b the
    mirror entry (b, a) adds the same value to H[j, i].  So the upper
    triangle takes, from each a < b, the one of (i, j), (j, i) with row <=
    column (both when i = j: twice the value), and from each a = b the
    entries with i <= j.  Returns the keys i n + j (i <= j), the index of
    the block entry among these faces' 81 per face, and the factor
    P[R, i] P[C, j] (doubled where due)."""
    n = P.shape[1]
    R = dof[:, _IA].reshape(-1)
    C = dof[:, _IB].reshape(-1)
    nr = np.diff(P.indptr)
    nR, nC = nr[R], nr[C]
    # most omega dofs are one unknown each (free edges): one entry apiece
    single = (nR == 1) & (nC == 1)
    one = np.flatnonzero(single)
    pi, qi = P.indptr[R[one]], P.indptr[C[one]]
    parts = [(P.indices[pi], P.indices[qi], P.data[pi] * P.data[qi], one)]
    many = np.flatnonzero((nR * nC > 0) & ~single)
    if len(many):
        cnt = nR[many] * nC[many]
        owner = np.repeat(many, cnt)
        o = np.arange(int(cnt.sum())) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        ncol = nC[owner]
        pi = P.indptr[R[owner]] + o // ncol
        qi = P.indptr[C[owner]] + o % ncol
        parts.append((P.indices[pi], P.indices[qi], P.data[pi] * P.data[qi], owner))
    i, j, v, src = (np.concatenate(z) for z in zip(*parts))
    slot = src % 45
    on_diag = _ON_DIAG[slot]
    keep = ~on_diag | (i <= j)
    i, j, v, src, slot, on_diag = i[keep], j[keep], v[keep], src[keep], slot[keep], on_diag[keep]
    v = np.where(~on_diag & (i == j), 2.0 * v, v)
    lo, hi = np.minimum(i, j).astype(np.int64), np.maximum(i, j).astype(np.int64)
    return lo * n + hi, (src // 45) * 81 + _FLAT[slot], v


def gauss_newton_blocks(Jb: np.ndarray, scale: float, out: np.ndarray | None = None) -> np.ndarray:
    """(m, 9, 9) blocks scale * J_f^T J_f from the (m, 3, 3, 3) Jacobian
    blocks d r_f / d omega_{e_k} (structure.jacobian_blocks), written into
    ``out`` if given."""
    m = len(Jb)
    B = Jb.transpose(0, 2, 1, 3).reshape(m, 3, 9)  # J_f: residual component x (edge slot, component)
    Q = np.matmul(B.transpose(0, 2, 1), B, out=out)  # batched matmul: ~9x faster than the einsum here
    Q *= scale
    return Q
