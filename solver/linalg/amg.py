"""A small smoothed-aggregation algebraic multigrid (nodal, block size b).

Only what SymFrames needs: SPD matrices whose unknowns come in blocks of b
per node (b = 3 for a rotation vector per vertex), the near-null space of
per-component constants, a V-cycle with damped block-Jacobi smoothing that
is symmetric (so it can precondition CG), and right-hand sides with several
columns.  Aggregation is a vectorised Luby maximal independent set on the
distance-2 strength graph of the nodes, so setup is numpy work rather than a
Python loop over vertices.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .parallel import parallel


def _node_matrix(A: sp.csr_matrix, b: int) -> sp.csr_matrix:
    """Frobenius norms of the b x b blocks of A."""
    if b == 1:
        return abs(A).tocsr()
    C = A.tocoo()
    n = A.shape[0] // b
    M = sp.csr_matrix((C.data**2, (C.row // b, C.col // b)), shape=(n, n))
    M.data = np.sqrt(M.data)
    return M


def _strength(N: sp.csr_matrix, theta: float) -> sp.csr_matrix:
    C = N.tocoo()
    d = np.sqrt(np.abs(N.diagonal()))
    off = C.row != C.col
    r, c, v = C.row[off], C.col[off], C.data[off]
    strong = np.abs(v) >= theta * d[r] * d[c]
    n = N.shape[0]
    return sp.csr_matrix((np.ones(strong.sum()), (r[strong], c[strong])), shape=(n, n))


def _mis(S: sp.csr_matrix, rng) -> np.ndarray:
    """Maximal independent set of the graph S (Luby, vectorised)."""
    n = S.shape[0]
    w = rng.random(n)
    state = np.zeros(n, np.int8)  # 0 undecided, 1 in set, -1 out
    rows = np.repeat(np.arange(n), np.diff(S.indptr))
    for _ in range(200):
        und = state == 0
        if not np.any(und):
            break
        vals = np.where(und[S.indices], w[S.indices], -1.0)
        nb_max = np.full(n, -1.0)
        if len(rows):
            np.maximum.at(nb_max, rows, vals)
        pick = und & (w > nb_max)
        state[pick] = 1
        hit = (S @ pick.astype(float)) > 0
        state[und & hit & ~pick] = -1
    state[state == 0] = 1
    return state == 1


def _aggregate(N: sp.csr_matrix, theta: float, rng, roots: np.ndarray | None = None):
    """Roots: a maximal independent set of the distance-2 strength graph;
    each root takes its strong neighbours; the rest join an adjacent
    aggregate.  Returns (aggregate of every node, roots).  Given roots
    (found earlier for the same strength graph) skips their search, and
    draws the same random numbers from rng as the search would."""
    n = N.shape[0]
    if roots is None:
        S = _strength(N, theta)
        S2 = (S @ S + S).tocsr()
        S2.setdiag(0)
        S2.eliminate_zeros()
        S2.data[:] = 1.0
        roots = _mis(S2, rng)
    else:
        rng.random(n)  # what _mis draws: later levels see the same stream
    agg = np.full(n, -1, dtype=np.int64)
    agg[roots] = np.arange(roots.sum())
    W = N.tocsr()
    for _ in range(10):
        left = agg < 0
        if not np.any(left):
            break
        sub = W[left].multiply((~left).astype(float)[None, :]).tocsr()
        has = np.diff(sub.indptr) > 0
        if not np.any(has):
            break
        j = _row_argmax(sub)
        idx = np.nonzero(left)[0]
        agg[idx[has]] = agg[j[has]]
    left = agg < 0
    agg[left] = agg.max() + 1 + np.arange(left.sum())
    return agg, roots


def _block_diag_inv(A: sp.csr_matrix, b: int) -> np.ndarray:
    n = A.shape[0] // b
    if b == 1:
        return (1.0 / A.diagonal()).reshape(n, 1, 1)
    C = A.tocoo()
    m = (C.row // b) == (C.col // b)
    D = np.zeros((n, b, b))
    np.add.at(D, (C.row[m] // b, C.row[m] % b, C.col[m] % b), C.data[m])
    # an unknown the operator does not see (e.g. a rotation component the
    # constraints forbid) has a zero pivot: regularise so the smoother ignores it
    tr = np.einsum("nii->n", D)
    D += (1e-10 * max(tr.max(), 1e-300) + 1e-8 * tr[:, None, None] / b) * np.eye(b)
    return inv_blocks(D)


def inv_blocks(D: np.ndarray) -> np.ndarray:
    """Inverses of a stack of square blocks (n, b, b).  3 x 3 blocks by the
    adjugate, vectorised (np.linalg.inv calls LAPACK once per block: 0.15 s
    for the ~100k blocks of a 78k-tet preconditioner, against ~10 ms)."""
    if D.shape[1:] != (3, 3):
        return np.linalg.inv(D)
    a, b, c = D[:, 0, 0], D[:, 0, 1], D[:, 0, 2]
    d, e, f = D[:, 1, 0], D[:, 1, 1], D[:, 1, 2]
    g, h, i = D[:, 2, 0], D[:, 2, 1], D[:, 2, 2]
    adj = np.empty_like(D, dtype=float)
    adj[:, 0, 0], adj[:, 0, 1], adj[:, 0, 2] = e * i - f * h, c * h - b * i, b * f - c * e
    adj[:, 1, 0], adj[:, 1, 1], adj[:, 1, 2] = f * g - d * i, a * i - c * g, c * d - a * f
    adj[:, 2, 0], adj[:, 2, 1], adj[:, 2, 2] = d * h - e * g, b * g - a * h, a * e - b * d
    det = a * adj[:, 0, 0] + b * adj[:, 1, 0] + c * adj[:, 2, 0]
    if np.any(det == 0) or not np.all(np.isfinite(det)):
        raise np.linalg.LinAlgError("Singular matrix")
    adj /= det[:, None, None]
    return adj


def _row_argmax(M: sp.csr_matrix) -> np.ndarray:
    """Column of the largest stored entry of every row (the first such
    column on ties; 0 for an empty row), without SciPy's per-row Python
    loop."""
    n = M.shape[0]
    cnt = np.diff(M.indptr)
    out = np.zeros(n, dtype=np.int64)
    if M.nnz == 0:
        return out
    rows = np.repeat(np.arange(n), cnt)
    order = np.lexsort((M.indices, -M.data, rows))  # by row, largest first, lowest column first
    has = cnt > 0
    out[has] = M.indices[order[M.indptr[:-1][has]]]
    return out


def _apply_block(Dinv: np.ndarray, x: np.ndarray) -> np.ndarray:
    n, b, _ = Dinv.shape
    if b == 1:
        return Dinv[:, 0, 0].reshape((-1,) + (1,) * (x.ndim - 1)) * x
    xs = x.reshape((n, b) + x.shape[1:])
    return np.einsum("nij,nj...->ni...", Dinv, xs).reshape(x.shape)


@dataclass
class Level:
    A: sp.csr_matrix
    P: sp.csr_matrix | None = None
    PT: sp.csr_matrix | None = None
    Dinv: np.ndarray | None = None
    omega: float = 0.6
    roots: np.ndarray | None = None  # the aggregates' roots (a mask over the nodes)
    S: sp.csr_matrix | None = None  # omega * block-diagonal inverse, as a sparse matrix
    ops: tuple = ()  # (A, P, PT, S) as applied in the V-cycle (row-split on several cores)


@dataclass
class AMG:
    """Smoothed-aggregation hierarchy for an SPD matrix with block size b."""

    levels: list = field(default_factory=list)
    coarse_solver: object = None
    coarse_inverse: np.ndarray | None = None
    block: int = 1
    seed: int = 0  # of the random weights that pick the aggregates' roots

    @classmethod
    def build(cls, A: sp.spmatrix, block: int = 1, theta: float = 0.0, max_coarse: int = 600,
              seed: int = 0, like: AMG | None = None) -> AMG:
        """theta > 0 drops connections weaker than theta * sqrt(|a_ii a_jj|)
        before aggregating.  The default aggregates by the matrix graph
        alone: with a strength filter (theta = 0.08) the denser coarse
        Galerkin operators stopped coarsening (78k-tet ball: 4,590 -> 2,703
        rows holding 4.9 M nonzeros), which made one V-cycle cost 26 ms and
        the setup 7 s, against 5 ms and 0.6 s now, for a similar number of
        CG steps (bench/RESULTS.md).

        like: an earlier hierarchy (used if built with the same seed and
        block size).  With theta = 0
        the aggregates' roots depend only on the matrix's sparsity pattern,
        so a level whose pattern is that of the same level of ``like``
        reuses its roots instead of searching the distance-2 graph again
        (0.48-0.55 -> 0.37-0.39 s per build at 98k tets).  The rest of the build,
        which reads the values, is redone, so the result is that of a
        fresh build.  (Reusing whole aggregates saved 0.1 s more, but they
        depend on the values where a node joins its strongest neighbour's
        aggregate, and aggregates from the first LM iteration's matrix cost
        up to 28% more CG steps on a 15k-tet ball.)"""
        rng = np.random.default_rng(seed)
        A = sp.csr_matrix(A)
        b = block
        amg = cls(block=b, seed=seed)
        if like is not None and (like.block, like.seed) != (b, seed):
            like = None
        while A.shape[0] > max_coarse * b and len(amg.levels) < 12:
            n = A.shape[0] // b
            Dinv = _block_diag_inv(A, b)
            k = len(amg.levels)
            prev = like.levels[k] if like is not None and k < len(like.levels) - 1 else None
            roots = prev.roots if theta == 0 and prev is not None and _same_pattern(prev.A, A) else None
            agg, roots = _aggregate(_node_matrix(A, b), theta, rng, roots)
            nagg = int(agg.max()) + 1
            if nagg >= 0.85 * n:
                break
            rows = (b * np.arange(n)[:, None] + np.arange(b)).reshape(-1)
            cols = (b * agg[:, None] + np.arange(b)).reshape(-1)
            T = sp.csr_matrix((np.ones(n * b), (rows, cols)), shape=(n * b, nagg * b))
            rho = _spectral_radius(A, Dinv, rng)
            w = 4.0 / (3.0 * rho)
            AT = (A @ T).tocsr()
            # P = (I - w D^-1 A) T, applying the block inverse column block by column block
            DAT = _block_rows(Dinv, AT)
            P = (T - w * DAT).tocsr()
            P.eliminate_zeros()
            omega = 1.0 / rho
            PT = P.T.tocsr()
            amg.levels.append(Level(A=A, P=P, PT=PT, Dinv=Dinv, omega=omega, roots=roots,
                                    S=(omega * block_diag_matrix(Dinv)).tocsr()))
            # CSR times CSR (P.T is CSC: SciPy would convert A P to CSC first
            # and the product back to CSR)
            A = PT @ (A @ P)
        amg.levels.append(Level(A=A))
        for lv in amg.levels[:-1]:
            lv.ops = tuple(parallel(M) for M in (lv.A, lv.P, lv.PT, lv.S))
        reg = 1e-13 * abs(A.diagonal()).max()
        if A.shape[0] <= 4000:
            # small enough for a dense inverse: one BLAS matvec per V-cycle
            amg.coarse_inverse = np.linalg.inv(A.toarray() + reg * np.eye(A.shape[0]))
        else:
            amg.coarse_solver = spla.splu((A + reg * sp.eye(A.shape[0])).tocsc())
        return amg

    def vcycle(self, b: np.ndarray, level: int = 0) -> np.ndarray:
        """One symmetric V-cycle for A x = b (damped block-Jacobi smoothing,
        one sweep before and after the coarse correction)."""
        L = self.levels[level]
        if level == len(self.levels) - 1:
            if self.coarse_inverse is not None:
                return self.coarse_inverse @ b
            return self.coarse_solver.solve(b)
        A, P, PT, S = L.ops
        x = S @ b
        r = b - A @ x
        x += P @ self.vcycle(PT @ r, level + 1)
        x += S @ (b - A @ x)
        return x

    @property
    def n_levels(self) -> int:
        return len(self.levels)

    @property
    def sizes(self) -> list:
        return [lv.A.shape[0] for lv in self.levels]


def _same_pattern(A: sp.csr_matrix, B: sp.csr_matrix) -> bool:
    return (A.shape == B.shape and A.nnz == B.nnz and np.array_equal(A.indptr, B.indptr)
            and np.array_equal(A.indices, B.indices))


def block_diag_matrix(D: np.ndarray) -> sp.csr_matrix:
    """Sparse block-diagonal matrix from (n, b, b) blocks."""
    n, b, _ = D.shape
    if b == 1:
        return sp.diags(D[:, 0, 0]).tocsr()
    rows = (b * np.arange(n)[:, None, None] + np.arange(b)[None, :, None])
    cols = (b * np.arange(n)[:, None, None] + np.arange(b)[None, None, :])
    return sp.csr_matrix((D.reshape(-1), (np.broadcast_to(rows, D.shape).reshape(-1),
                                          np.broadcast_to(cols, D.shape).reshape(-1))), shape=(n * b, n * b))


def _block_rows(Dinv: np.ndarray, M: sp.csr_matrix) -> sp.csr_matrix:
    """diag(Dinv) @ M for a block-diagonal Dinv (n, b, b)."""
    return block_diag_matrix(Dinv) @ M


def _spectral_radius(A, Dinv, rng, iters=12):
    x = rng.standard_normal(A.shape[0])
    lam = 1.0
    for _ in range(iters):
        y = _apply_block(Dinv, A @ x)
        lam = np.linalg.norm(y) / np.linalg.norm(x)
        x = y / np.linalg.norm(y)
    return lam * 1.05
