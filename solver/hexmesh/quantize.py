"""Stage 4 of hex meshing: the integer-grid map.

The integer unknowns of the reduced system (seamless.py) are plain
coordinates of z: the translations across the cut, the boundary planes and
the curve lines, each an integer in an integer-grid map.  Their energy, with
every other unknown at its optimum, is a small dense quadratic: with z split
into continuous y and integer w,

    y(w) = Q_yy^-1 (b_y - Q_yw w),
    E(w) = 1/2 w' S w - c' w,   S = Q_ww - Q_wy Q_yy^-1 Q_yw,

one sparse factorisation and one solve per integer unknown give S exactly.
Greedy rounding (MIQ / CoMISo, as CubeCover and AlgoHex use) then fixes the
unknown nearest an integer and moves the others to their conditional
optimum, an O(m^2) update of S^-1, until all are fixed; no re-solve of the
large system is needed between roundings.

Inverted tets left by the rounding are then stiffened (MIQ; AlgoHex's
``update_cell_weights``): their weight grows and the continuous unknowns
are solved again, keeping the best map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .quality import det3
from .seamless import MapSystem


@dataclass
class GridMap:
    """An integer-grid map (or its relaxed seamless version).

    z        : (nz,) the reduced unknowns; z[system.integer] are integers
    corners  : (#T, 4, 3) parameter points of the tet corners (cells)
    det      : (#T,) det of cell * grad(u) F per tet (> 0: not inverted)
    energy   : the frame-fitting energy
    rounded  : how many integer unknowns were rounded
    max_shift: largest move of an integer unknown off its relaxed value
    stiffening : stiffening iterations used
    """

    z: np.ndarray
    corners: np.ndarray
    det: np.ndarray
    energy: float
    rounded: int = 0
    max_shift: float = 0.0
    stiffening: int = 0

    @property
    def inverted(self) -> int:
        return int(np.sum(self.det <= 0))


def _jacobian_det(ms: MapSystem, z: np.ndarray):
    U = ms.corners(z)
    J = np.einsum("tca,tcj->taj", U, ms.grad)
    return U, det3(J)


def _grid_map(ms: MapSystem, z: np.ndarray, **kw) -> GridMap:
    U, det = _jacobian_det(ms, z)
    return GridMap(z, U, det, ms.energy(z), **kw)


class _Reduced:
    """The energy as a function of the integer unknowns (module docs)."""

    def __init__(self, Q: sp.csr_matrix, b: np.ndarray, integer: np.ndarray):
        self.iw = np.nonzero(integer)[0]
        self.iy = np.nonzero(~integer)[0]
        Q = Q.tocsc()
        Qyy = Q[self.iy][:, self.iy]
        Qyw = Q[self.iy][:, self.iw].toarray()
        Qww = Q[self.iw][:, self.iw].toarray()
        # SPD: symmetric mode with a symmetric ordering is several times
        # faster than SuperLU's default (COLAMD, partial pivoting)
        self.lu = spla.splu(Qyy.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                            options={"SymmetricMode": True})
        self.y0 = self.lu.solve(b[self.iy])
        self.Z = self.lu.solve(Qyw) if len(self.iw) else np.zeros((len(self.iy), 0))
        self.S = Qww - Qyw.T @ self.Z
        self.c = b[self.iw] - Qyw.T @ self.y0
        self.n = len(b)

    def z(self, w: np.ndarray) -> np.ndarray:
        out = np.empty(self.n)
        out[self.iw] = w
        out[self.iy] = self.y0 - self.Z @ w
        return out

    def relaxed(self) -> np.ndarray:
        if not len(self.iw):
            return np.zeros(0)
        return np.linalg.solve(self.S + 1e-12 * np.eye(len(self.S)) * np.trace(self.S), self.c)


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


def seamless_map(ms: MapSystem) -> tuple[GridMap, _Reduced]:
    """The relaxed (real-valued) seamless map and its reduced energy."""
    red = _Reduced(ms.Q, ms.b, ms.integer)
    z = red.z(red.relaxed())
    return _grid_map(ms, z), red


def integer_grid_map(ms: MapSystem, red: _Reduced | None = None, stiffen_iters: int = 6,
                     stiffen_factor: float = 5.0) -> GridMap:
    """Round the integer unknowns greedily and stiffen inverted tets.

    Parameters
    ----------
    ms : MapSystem
    red : the reduced energy of ms (seamless_map's), computed if None
    stiffen_iters : at most this many re-solves with inverted tets' weights
        multiplied by stiffen_factor

    Returns
    -------
    GridMap  (the least inverted of the maps tried)
    """
    red = red or _Reduced(ms.Q, ms.b, ms.integer)
    w, shift = greedy_round(red.S, red.c)
    best = _grid_map(ms, red.z(w), rounded=len(w), max_shift=shift)
    if best.inverted == 0 or stiffen_iters == 0:
        return best
    # stiffening: the integer unknowns stay, the continuous ones move
    LX, weight = ms.least_squares()
    wts = weight.copy()
    nT = len(ms.tet_weight)
    cur = best
    for it in range(1, stiffen_iters + 1):
        bad = cur.det <= 0
        if not bad.any():
            break
        scale = np.ones(nT)
        scale[bad] = stiffen_factor
        wts = wts * np.repeat(scale, 9)
        Q = (LX.T @ sp.diags(wts) @ LX).tocsr()
        b = LX.T @ (wts * np.tile(np.eye(3).reshape(-1), nT))
        red_s = _Reduced(Q, np.asarray(b).ravel(), ms.integer)
        cur = _grid_map(ms, red_s.z(w), rounded=len(w), max_shift=shift, stiffening=it)
        if cur.inverted < best.inverted or (cur.inverted == best.inverted and cur.det.min() > best.det.min()):
            best = cur
    return best


def optimise_map(ms: MapSystem, gm: GridMap, mu: float = 10.0, lam: float = 0.0, iters: int = 300,
                 rounds: int = 4, callback=None) -> GridMap:
    """Lower the map's distortion with its integers fixed, untangling
    inverted tets on the way: minimise, over the continuous unknowns,

        sum_t V_t ( ||J_t - I||^2 + mu f(J_t) ),   J_t = cell grad(u_t) F_t,

    f the foldover-free energy of smooth.py (mean-ratio shape plus volume,
    finite while eps > 0 so an inverted start is allowed, a barrier as eps
    -> 0).  The first term keeps the map aligned with the field (f alone is
    blind to rotation).  AlgoHex likewise follows its linear solve with a
    locally injective optimisation under the same constraints.
    """
    from ..linalg.lbfgs import lbfgs
    from .smooth import foldover_free

    iy = np.nonzero(~ms.integer)[0]
    z = gm.z.copy()
    w = ms.tet_weight / ms.tet_weight.sum()
    X = ms.X
    Xy = X[:, iy].tocsc()
    base = X @ z - Xy @ z[iy]  # the integer part of the corners, fixed
    coef = ms.grad
    eye = np.eye(3)
    best = gm
    for _ in range(rounds):
        U = ms.corners(z)
        J = np.einsum("tca,tcj->taj", U, coef)
        Dmin = float(det3(J).min())
        eps = 1e-3 if Dmin > 1e-2 else float(np.sqrt(1e-6 + 0.04 * Dmin * Dmin))

        def fun(y):
            U = (base + Xy @ y).reshape(-1, 4, 3)
            J = np.einsum("tca,tcj->taj", U, coef)
            f, dJ = foldover_free(J, eps, lam)
            R = J - eye
            e = float(np.sum(w * (np.einsum("tij,tij->t", R, R) + mu * f)))
            dJ = w[:, None, None] * (2.0 * R + mu * dJ)
            dU = np.einsum("taj,tcj->tca", dJ, coef)
            return e, Xy.T @ dU.reshape(-1)

        res = lbfgs(fun, z[iy], max_iterations=iters, callback=callback)
        z[iy] = res.x
        cur = _grid_map(ms, z.copy(), rounded=gm.rounded, max_shift=gm.max_shift, stiffening=gm.stiffening)
        if cur.inverted <= best.inverted:
            best = cur
        if cur.inverted == 0 and Dmin > 1e-2:
            break
    return best
