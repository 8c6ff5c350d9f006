"""Greedy rounding of the integer-grid map's integer unknowns.

The integer unknowns of the reduced map system (seamless.py) have a small
dense quadratic energy E(w) = 1/2 w' S w - c' w once every other unknown is
at its optimum (seamless.py's ``_Reduced``).  Greedy rounding (MIQ /
CoMISo, as CubeCover and AlgoHex use) fixes the unknown nearest an integer
and moves the others to their conditional optimum, an O(m^2) update of
S^-1, until all are fixed.
"""

from __future__ import annotations

import numpy as np


def greedy_round(S: np.ndarray, c: np.ndarray, batch_tol: float = 1e-3) -> tuple[np.ndarray, float]:
    """Integer w (approximately) minimising 1/2 w'Sw - c'w by greedy
    rounding: fix the unknown nearest an integer (all within batch_tol of
    one at once), update the rest to their conditional optimum, repeat.
    Returns (w, largest distance an unknown was moved when rounded)."""
    m = len(c)
    if m == 0:
        return np.zeros(0), 0.0
    reg = 1e-12 * max(np.trace(S) / m, 1e-300)
    K = np.linalg.inv(S + reg * np.eye(m))  # conditional covariance of the free unknowns
    w = K @ c
    free = np.ones(m, bool)
    shift = 0.0
    while free.any():
        idx = np.nonzero(free)[0]
        dist = np.abs(w[idx] - np.rint(w[idx]))
        pick = idx[dist <= max(batch_tol, dist.min())]
        for i in pick.tolist():
            v = float(np.rint(w[i]))
            shift = max(shift, abs(v - w[i]))
            d = v - w[i]
            kii = K[i, i]
            if kii > 1e-300:
                w += K[:, i] * (d / kii)
                K -= np.outer(K[:, i], K[i, :]) / kii
            w[i] = v
            K[i, :] = 0.0
            K[:, i] = 0.0
            free[i] = False
    return np.rint(w), shift
