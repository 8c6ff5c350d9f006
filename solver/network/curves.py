"""Geometry of one network curve: closest points, tangents and the
least-twist (rotation-minimising) reference frame E0 along it (§4.2.2)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..linalg.rotations import any_perpendicular, exp_so3, frame_from_axes, log_so3, minimal_rotation
from .network import polyline_tangents


@dataclass
class CurveGeometry:
    """P : (n, 3) polyline; closed loops repeat their first point at the end."""

    P: np.ndarray
    closed: bool = False

    @cached_property
    def tangents(self) -> np.ndarray:
        return polyline_tangents(self.P, self.closed)

    @cached_property
    def arclength(self) -> np.ndarray:
        return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(self.P, axis=0), axis=1))]

    @cached_property
    def frames(self) -> np.ndarray:
        """(n, 3, 3) rotation-minimising frames at the vertices, third column
        along the tangent.  On a closed loop the holonomy is spread evenly
        along the arc length (less its nearest quarter turn), so the frame
        closes up as a cross."""
        T = self.tangents
        n = len(T)
        x0 = any_perpendicular(T[:1])
        F = np.empty((n, 3, 3))
        F[0] = frame_from_axes(x0, T[:1])[0]
        R = exp_so3(minimal_rotation(T[:-1], T[1:]))
        for k in range(n - 1):
            F[k + 1] = R[k] @ F[k]
        if self.closed:
            # angle about T0 from the first frame to the transported last one
            M = F[0].T @ F[-1]
            beta = np.arctan2(M[1, 0], M[0, 0])
            excess = beta - np.round(beta / (np.pi / 2)) * (np.pi / 2)
            s = self.arclength / self.arclength[-1]
            twist = exp_so3(-(excess * s)[:, None] * T)
            F = twist @ F
        return F

    def closest(self, X: np.ndarray):
        """Closest curve points to X (k, 3).

        Returns (segment index (k,), fraction in [0, 1] (k,), distance (k,)).
        """
        X = np.atleast_2d(X)
        a = self.P[:-1]
        d = self.P[1:] - a
        dd = np.einsum("ij,ij->i", d, d)
        best_s = np.zeros(len(X), dtype=np.int64)
        best_t = np.zeros(len(X))
        best_d = np.full(len(X), np.inf)
        chunk = max(1, 2_000_000 // max(1, len(a)))
        for s0 in range(0, len(X), chunk):
            x = X[s0 : s0 + chunk, None, :]
            t = np.clip(np.einsum("kij,ij->ki", x - a[None], d) / dd[None], 0.0, 1.0)
            q = a[None] + t[..., None] * d[None]
            dist = np.linalg.norm(q - x, axis=2)
            j = np.argmin(dist, axis=1)
            r = np.arange(len(j))
            best_s[s0 : s0 + chunk] = j
            best_t[s0 : s0 + chunk] = t[r, j]
            best_d[s0 : s0 + chunk] = dist[r, j]
        return best_s, best_t, best_d

    def point(self, seg, t):
        return self.P[seg] + t[:, None] * (self.P[seg + 1] - self.P[seg])

    def tangent(self, seg, t):
        T = (1 - t)[:, None] * self.tangents[seg] + t[:, None] * self.tangents[seg + 1]
        return T / np.linalg.norm(T, axis=1, keepdims=True)

    def frame(self, seg, t):
        """Reference frame at curve parameters (geodesic interpolation)."""
        F0, F1 = self.frames[seg], self.frames[seg + 1]
        rel = log_so3(np.einsum("nij,nkj->nik", F1, F0))
        return exp_so3(t[:, None] * rel) @ F0
