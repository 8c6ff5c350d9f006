"""Preconditioned conjugate gradients on several right-hand sides at once.

The columns of B are independent CG runs (each its own step lengths) made
in lockstep, so that every step reads the matrix and the preconditioner's
operators once for all the columns: a sparse product with an (n, k) block
costs far less than k products with vectors.  This is not block CG (the
columns do not share a Krylov space); it is what the hex map's reduced
solve needs (seamless.py: one right-hand side per integer unknown plus
one), where the columns converge in nearly the same number of steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class ColumnsResult:
    X: np.ndarray  # (n, k) the solutions
    iterations: int  # steps of the slowest column
    converged: bool  # every column reached rtol
    relative_residual: np.ndarray  # (k,) ||b - A x|| / ||b|| per column (as updated by CG)


def pcg_columns(matvec, B: np.ndarray, precond, X0: np.ndarray | None = None, rtol: float = 1e-10,
                maxiter: int = 1000) -> ColumnsResult:
    """Solve A X = B for SPD A, column by column, in lockstep.

    Parameters
    ----------
    matvec : callable
        (n, m) -> (n, m), the product with A of a block of columns
    B : (n, k) or (n,) array
    precond : callable
        (n, m) -> (n, m), a symmetric positive definite preconditioner
        (an AMG V-cycle, a factorisation's solve)
    X0 : array like B, optional
        the starting guess (zero if None)
    rtol : float
        stop a column once ||b - A x|| <= rtol ||b||; a zero column is
        solved by zero
    maxiter : int

    Returns
    -------
    ColumnsResult (X of B's shape)

    A column whose curvature p'Ap is not positive (A not SPD to working
    precision) stops there, unconverged.
    """
    vec = B.ndim == 1
    B = B.reshape(len(B), -1).astype(float)
    k = B.shape[1]
    if X0 is None:
        X = np.zeros_like(B)
        R = B.copy()
    else:
        X = np.array(X0, dtype=float).reshape(B.shape)
        R = B - matvec(X)
    nb = np.linalg.norm(B, axis=0)
    nb_safe = np.where(nb > 0, nb, 1.0)
    res = np.linalg.norm(R, axis=0) / nb_safe
    res[nb == 0] = 0.0
    if X0 is not None:
        X[:, nb == 0] = 0.0
        R[:, nb == 0] = 0.0
    act = np.nonzero(res > rtol)[0]  # the columns still running
    broken = np.zeros(k, bool)
    it = 0
    if len(act):
        Zc = precond(R[:, act])
        P = Zc.copy()
        rz = np.einsum("ij,ij->j", R[:, act], Zc)
    while len(act) and it < maxiter:
        AP = matvec(P)
        pAp = np.einsum("ij,ij->j", P, AP)
        ok = pAp > 0
        alpha = np.where(ok, rz / np.where(ok, pAp, 1.0), 0.0)
        X[:, act] += P * alpha
        Ra = R[:, act] - AP * alpha
        R[:, act] = Ra
        it += 1
        res[act] = np.linalg.norm(Ra, axis=0) / nb_safe[act]
        broken[act[~ok]] = True
        keep = ok & (res[act] > rtol)
        if not keep.any():
            break
        if not keep.all():
            # drop the finished columns from the running block
            act, Ra, P, rz = act[keep], Ra[:, keep], P[:, keep], rz[keep]
        Zc = precond(Ra)
        rz_new = np.einsum("ij,ij->j", Ra, Zc)
        P = Zc + P * (rz_new / rz)
        rz = rz_new
    X = X[:, 0] if vec else X
    return ColumnsResult(X, it, bool(np.all(res <= rtol) and not broken.any()), res)
