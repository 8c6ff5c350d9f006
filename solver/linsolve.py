"""Preconditioned conjugate gradients for the Levenberg-Marquardt systems.

Sparse LU of the ~3|E| x 3|E| normal equations does not scale on these
meshes (design notes §3: 312 s and 428 M nonzeros at 71k edges), so every LM
step is solved by PCG with a two-part preconditioner:

* a block-Jacobi smoother: the exact 3x3 diagonal block of each free edge
  and the diagonal of the adaptation parameters;
* a gradient-space correction.  The penalty a |d omega|^2 vanishes on
  omega = d phi, where only the small smoothness term acts, so those modes
  are what Jacobi-PCG is slow on (design notes: ~1,100 iterations).  We add
  G A_g^-1 G^T with G = d0 (per so(3) component, interior vertices) and A_g
  the vertex Laplacian of the smoothness weights, inverted by one V-cycle of
  a smoothed-aggregation AMG (amg.py).  This is the gradient half of the
  Hiptmair-Xu auxiliary space preconditioner for H(curl) problems.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PCGResult:
    x: np.ndarray
    iterations: int
    converged: bool
    relative_residual: float
    negative_curvature: bool = False  # stopped at a direction p with p^T A p <= 0


def pcg(matvec, b, precond, x0=None, rtol=1e-8, maxiter=2000) -> PCGResult:
    """Solve A x = b for SPD A given as a matvec, preconditioner as a function.
    Stops early, flagging negative_curvature, if A turns out not to be
    positive definite."""
    x = np.zeros_like(b) if x0 is None else x0.copy()
    r = b - matvec(x) if x0 is not None else b.copy()
    nb = np.linalg.norm(b)
    if nb == 0:
        return PCGResult(np.zeros_like(b), 0, True, 0.0)
    z = precond(r)
    p = z.copy()
    rz = r @ z
    it = 0
    res = np.linalg.norm(r) / nb
    while res > rtol and it < maxiter:
        Ap = matvec(p)
        pAp = p @ Ap
        if pAp <= 0:
            return PCGResult(x, it, False, res, True)
        alpha = rz / pAp
        x += alpha * p
        r -= alpha * Ap
        it += 1
        res = np.linalg.norm(r) / nb
        if res <= rtol:
            break
        z = precond(r)
        rz_new = r @ z
        p = z + (rz_new / rz) * p
        rz = rz_new
    return PCGResult(x, it, res <= rtol, res)
