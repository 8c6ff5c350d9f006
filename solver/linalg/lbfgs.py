"""Limited-memory BFGS in plain numpy.

scipy's L-BFGS-B makes many tiny BLAS calls per iteration; with a threaded
BLAS on a busy machine they cost ~100x their work (12k unknowns: 2.1 s per
100 iterations with OpenBLAS's default threads under load, 0.12 s with one
thread).  The two-loop recursion below uses a handful of vector operations
per iteration and no BLAS threads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class LBFGSResult:
    x: np.ndarray
    fun: float
    iterations: int
    converged: bool


def lbfgs(fun, x0: np.ndarray, max_iterations: int = 200, memory: int = 8, gtol: float = 1e-8,
          ftol: float = 1e-10, callback=None) -> LBFGSResult:
    """Minimise fun(x) -> (value, gradient) from x0 (Nocedal & Wright,
    Alg. 7.4/7.5) with a backtracking (Armijo) line search.

    Stops when the gradient's max norm falls below gtol times max(1, |f|),
    the relative decrease of f over an iteration below ftol, or after
    max_iterations.  callback(iteration, f), if given, is called after each
    iteration (it may raise to stop, e.g. errors.Cancelled)."""
    x = np.asarray(x0, float).copy()
    f, g = fun(x)
    S, Y, R = [], [], []
    it = 0
    for it in range(1, max_iterations + 1):
        if np.max(np.abs(g)) <= gtol * max(1.0, abs(f)):
            return LBFGSResult(x, f, it - 1, True)
        # two-loop recursion: d = -H g
        q = g.copy()
        alpha = []
        for s, y, r in zip(reversed(S), reversed(Y), reversed(R)):
            a = r * float(s @ q)
            alpha.append(a)
            q -= a * y
        if S:
            q *= float(S[-1] @ Y[-1]) / float(Y[-1] @ Y[-1])
        else:
            q /= max(np.linalg.norm(g), 1e-300)
        for (s, y, r), a in zip(zip(S, Y, R), reversed(alpha)):
            b = r * float(y @ q)
            q += (a - b) * s
        d = -q
        slope = float(g @ d)
        if slope >= 0:  # not a descent direction: restart along -g
            S.clear(), Y.clear(), R.clear()
            d = -g / max(np.linalg.norm(g), 1e-300)
            slope = float(g @ d)
        t = 1.0
        while True:
            xn = x + t * d
            fn, gn = fun(xn)
            if np.isfinite(fn) and fn <= f + 1e-4 * t * slope:
                break
            t *= 0.5
            if t < 1e-12:
                return LBFGSResult(x, f, it, False)
        s, y = xn - x, gn - g
        sy = float(s @ y)
        if sy > 1e-12 * float(y @ y):
            S.append(s)
            Y.append(y)
            R.append(1.0 / sy)
            if len(S) > memory:
                S.pop(0), Y.pop(0), R.pop(0)
        done = abs(f - fn) <= ftol * max(1.0, abs(f))
        x, f, g = xn, fn, gn
        if callback is not None:
            callback(it, f)
        if done:
            return LBFGSResult(x, f, it, True)
    return LBFGSResult(x, f, it, False)
