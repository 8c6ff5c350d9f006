"""Preconditioned conjugate gradients for the Levenberg-Marquardt systems.

Sparse LU of the ~3|E| x 3|E| normal equations does not scale on these
meshes (docs/performance.md, *Against a sparse-LU LM*: 312 s and 428 M nonzeros at 71k edges), so every LM
step is solved by PCG with a two-part preconditioner:

* a block-Jacobi smoother: the exact 3x3 diagonal block of each free edge
  and the diagonal of the adaptation parameters;
* a gradient-space correction.  The penalty a |d omega|^2 vanishes on
  omega = d phi, where only the small smoothness term acts, so those modes
  are what Jacobi-PCG is slow on (~1,100 iterations: docs/performance.md, *Against a sparse-LU LM*).  We add
  G A_g^-1 G^T with G = d0 (per so(3) component, interior vertices) and A_g
  the vertex Laplacian of the smoothness weights, inverted by one V-cycle of
  a smoothed-aggregation AMG (amg.py).  This is the gradient half of the
  Hiptmair-Xu auxiliary space preconditioner for H(curl) problems.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .parallel import ranges, run


@dataclass
class PCGResult:
    x: np.ndarray
    iterations: int
    converged: bool
    relative_residual: float
    negative_curvature: bool = False  # stopped at a direction p with p^T A p <= 0
    direction: np.ndarray | None = None  # that direction p (when negative_curvature)
    small_solution: bool = False  # stopped once the solution was known to be small (see pcg)


def pcg(matvec, b, precond, x0=None, rtol=1e-8, maxiter=2000, recorder=None, small=None) -> PCGResult:
    """Solve A x = b for SPD A given as a matvec, preconditioner as a function.
    Stops early, flagging negative_curvature, if A turns out not to be
    positive definite, and returns the direction p with p^T A p <= 0 that
    showed it.  A RitzRecorder, if given, collects approximate
    eigenvectors of the smallest eigenvalues on the way.

    small = (size, bound, steps), if given, also stops CG, flagging
    small_solution, once size(x) <= bound after at least ``steps`` steps
    and size(x) grew by less than 2% over the last ten (tested every tenth
    step).  From x0 = 0 the iterates grow towards the solution (their norm
    in the preconditioner's metric increases monotonically, Steihaug 1983),
    and on the LM systems they come close to its size long before the
    residual is small: ball, 98k tets, a Newton system whose solution is
    2.3e-6 of omega: 2.16e-6 after 25 steps and 2.24e-6 after 100, while the
    residual first reached 1e-5 after 1,378.  The LM uses this to confirm
    convergence without solving a system whose solution it does not need.
    It is a heuristic: with a weak preconditioner the iterates can stall
    well below the solution's size."""
    # vectors are updated in place through one scratch array, by index
    # ranges on all cores (parallel.run): a CG step on these systems is
    # memory-bound.  (Not with BLAS axpy: OpenBLAS threads spin after each
    # call and slow down the products on the other core.)
    x = np.zeros_like(b) if x0 is None else x0.astype(float, copy=True)
    r = b - matvec(x) if x0 is not None else b.astype(float, copy=True)
    parts = ranges(len(b))

    def pdot(u, v):
        # u . v by einsum, not BLAS: OpenBLAS runs long dot products on
        # several threads, which then spin for a while and slow down the
        # sparse products on the other cores (with BLAS dots the product
        # with the LM matrix took 6.5 ms per CG step at 78k tets, without
        # them 5.5 ms; bench/RESULTS.md)
        return float(sum(run(lambda i, j: np.einsum("i,i->", u[i:j], v[i:j]), parts)))

    nb = np.sqrt(pdot(b, b))
    if nb == 0:
        return PCGResult(np.zeros_like(b), 0, True, 0.0)
    z = precond(r)
    p = z.copy()
    tmp = np.empty_like(p)
    rz = pdot(r, z)
    if recorder is not None:
        recorder.start(z, rz)
    it = 0
    size_before = 0.0

    # the range workers read alpha, Ap, beta and z of the current step
    def update(i, j):
        # x += alpha p, r -= alpha Ap; returns this range's r . r
        xs, rs, ts = x[i:j], r[i:j], tmp[i:j]
        xs += np.multiply(p[i:j], alpha, out=ts)
        rs -= np.multiply(Ap[i:j], alpha, out=ts)
        return np.einsum("i,i->", rs, rs)

    def direction(i, j):
        # p = z + beta p
        ps = p[i:j]
        ps *= beta
        ps += z[i:j]

    res = np.sqrt(pdot(r, r)) / nb
    while res > rtol and it < maxiter:
        Ap = matvec(p)
        pAp = pdot(p, Ap)
        if pAp <= 0:
            return PCGResult(x, it, False, res, True, direction=p)
        alpha = rz / pAp
        if recorder is not None:
            recorder.add_alpha(alpha)
        rr = float(sum(run(update, parts)))
        it += 1
        res = np.sqrt(rr) / nb
        if res <= rtol:
            break
        if small is not None and it % 10 == 0:
            size = small[0](x)
            if it >= small[2] and size <= small[1] and size - size_before <= 0.02 * size:
                return PCGResult(x, it, False, res, small_solution=True)
            size_before = size
        z = precond(r)
        rz_new = pdot(r, z)
        beta = rz_new / rz
        if recorder is not None:
            recorder.add_vector(beta, z, rz_new)
        run(direction, parts)
        rz = rz_new
    return PCGResult(x, it, res <= rtol, res)


class RitzRecorder:
    """Approximate eigenvectors of the smallest eigenvalues of M^-1 A,
    gathered while PCG runs, without further products with A (eigCG,
    Stathopoulos & Orginos 2010).

    PCG is a Lanczos process: v_k = (-1)^k z_k / sqrt(r_k . z_k) are its
    vectors and T (tridiagonal, from CG's alpha and beta) is V^T A V.  We keep
    at most m of them; when the basis is full it is restarted with the Ritz
    vectors of the nev smallest Ritz values of T_m and of T_(m-1) (2 nev
    vectors), and the Lanczos recurrence continues unchanged."""

    def __init__(self, n: int, nev: int = 8, m: int = 48):
        if not 0 < 2 * nev < m:
            raise ValueError(f"need 0 < 2 nev < m, got nev={nev}, m={m}")
        self.nev, self.m = nev, m
        self.V = np.empty((m, n), dtype=np.float32)  # a Lanczos vector per row; single precision is
        # plenty for a preconditioner and halves the restarts' memory traffic
        self.T = np.zeros((m, m))
        self.cur = 0
        self.failed = False

    def start(self, z, rz):
        # failed: the recurrence broke down (a non-finite coefficient or an
        # eigensolver that did not converge); the recorder then stops and
        # offers no vectors, since deflation only speeds CG up
        self.failed = not (np.isfinite(rz) and rz > 0)
        if self.failed:
            return
        self.T[:] = 0.0
        self.V[0] = z / np.sqrt(rz)
        self.cur, self.sign = 1, 1.0
        self.alpha_prev = self.beta_prev = None
        self.complete = False

    def add_alpha(self, alpha):
        if self.failed:
            return
        if not (np.isfinite(alpha) and alpha > 0):
            self.failed = True
            return
        j = self.cur - 1  # the diagonal of the newest vector is now complete
        self.T[j, j] += 1.0 / alpha + (self.beta_prev / self.alpha_prev if self.alpha_prev is not None else 0.0)
        self.alpha_prev = alpha
        self.complete = True

    def add_vector(self, beta, z, rz):
        if self.failed:
            return
        if not (np.isfinite(beta) and beta >= 0 and np.isfinite(rz) and rz > 0):
            self.failed = True
            return
        t = np.sqrt(beta) / self.alpha_prev  # coupling of the newest and the next vector
        self.sign = -self.sign
        if self.cur == self.m:
            try:
                W = self._restart()
            except np.linalg.LinAlgError:
                self.failed = True
                return
            k = self.cur
            self.T[:k, k] = self.T[k, :k] = t * W[-1]
        else:
            k = self.cur
            self.T[k - 1, k] = self.T[k, k - 1] = t
        np.multiply(z, self.sign / np.sqrt(rz), out=self.V[k])
        self.cur = k + 1
        self.beta_prev = beta
        self.complete = False

    def _restart(self):
        m, nev = self.m, self.nev
        Tm = self.T.copy()
        Y = np.linalg.eigh(Tm)[1][:, :nev]
        Y1 = np.zeros((m, nev))
        Y1[:-1] = np.linalg.eigh(Tm[:-1, :-1])[1][:, :nev]
        Q = np.linalg.qr(np.hstack([Y, Y1]))[0]
        lam, Z = np.linalg.eigh(Q.T @ Tm @ Q)
        W = Q @ Z
        self.V[:2 * nev] = W.T.astype(np.float32) @ self.V
        self.T[:] = 0.0
        self.T[np.arange(2 * nev), np.arange(2 * nev)] = lam
        self.cur = 2 * nev
        return W

    def vectors(self) -> tuple[np.ndarray, np.ndarray]:
        """(Ritz values, Ritz vectors as columns) of the nev smallest."""
        k = self.cur if self.complete else self.cur - 1  # T's last diagonal needs one more alpha
        lam, Y = np.linalg.eigh(self.T[:k, :k])
        return lam[:self.nev], (Y[:, :self.nev].T.astype(np.float32) @ self.V[:k]).T.astype(np.float64)
