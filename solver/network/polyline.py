"""Polylines: arc length, points at arc length, turning over a length,
merging close points (spaced, merge_close), resampling and the Hausdorff distance."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree


def arclength(P: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]


def at_arclength(P: np.ndarray, s: np.ndarray, cum: np.ndarray | None = None) -> np.ndarray:
    """Points of the polyline P at arc lengths s (clamped to the ends)."""
    cum = arclength(P) if cum is None else cum
    return np.stack([np.interp(s, cum, P[:, k]) for k in range(3)], axis=1)


def turning(P: np.ndarray, window: float, closed: bool = False) -> np.ndarray:
    """Angle (degrees) at each vertex between the chords to the points at arc
    length ``window`` behind and ahead of it (clamped at open ends): the turn
    of the curve over a length comparable to window, not across one segment."""
    cum = arclength(P)
    L = cum[-1]
    s = cum
    if closed:
        back = at_arclength(P, np.mod(s - window, L), cum)
        ahead = at_arclength(P, np.mod(s + window, L), cum)
    else:
        back = at_arclength(P, np.maximum(s - window, 0.0), cum)
        ahead = at_arclength(P, np.minimum(s + window, L), cum)
    u, v = P - back, ahead - P
    nu, nv = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
    ok = (nu > 1e-12 * max(L, 1e-300)) & (nv > 1e-12 * max(L, 1e-300))
    c = np.einsum("ij,ij->i", u, v) / np.where(ok, nu * nv, 1.0)
    out = np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))
    out[~ok] = 0.0
    return out


def spaced(P: np.ndarray, tol: float) -> list[int]:
    """Indices of the points of P kept when each is dropped that lies within
    tol of the last one kept (the first is kept)."""
    if len(P) < 2:
        return list(range(len(P)))
    gaps = np.sqrt(np.sum(np.diff(P, axis=0) ** 2, axis=1))
    if np.all(gaps > tol):  # the common case: nothing to drop
        return list(range(len(P)))
    pts = P.tolist()  # Python floats: a loop over numpy rows paid ~3 us a point in call overhead
    tol2 = tol * tol
    keep = [0]
    lx, ly, lz = pts[0]
    for i in range(1, len(pts)):
        x, y, z = pts[i]
        if (x - lx) ** 2 + (y - ly) ** 2 + (z - lz) ** 2 > tol2:
            keep.append(i)
            lx, ly, lz = x, y, z
    return keep


def merge_close(P: np.ndarray, tol: float, closed: bool) -> np.ndarray:
    """Drop points closer than tol to the last kept one (ends are kept)."""
    keep = spaced(P[:-1], tol) if len(P) > 1 else [0]
    last = len(P) - 1
    if len(keep) > 1 and np.linalg.norm(P[last] - P[keep[-1]]) <= tol:
        keep[-1] = last
    elif last > 0:
        keep.append(last)
    return P[keep]


def resample(P: np.ndarray, spacing: float) -> np.ndarray:
    """Uniform resampling by arc length (ends kept)."""
    cum = arclength(P)
    n = max(1, int(np.ceil(cum[-1] / spacing - 1e-9)))
    return at_arclength(P, np.linspace(0.0, cum[-1], n + 1), cum)


def hausdorff(A: np.ndarray, B: np.ndarray, step: float) -> float:
    """Symmetric Hausdorff distance between two polylines, sampled at step."""
    a = resample(A, step) if len(A) > 1 else A
    b = resample(B, step) if len(B) > 1 else B
    return float(max(cKDTree(b).query(a)[0].max(), cKDTree(a).query(b)[0].max()))
