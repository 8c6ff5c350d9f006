"""Solids of revolution: a closed profile in the (r, z) half-plane swept
about the z axis (a torus, a washer, a pipe, a grooved ring), as the
suggestion's ring route takes them (solver/suggest/ring.py)."""

from __future__ import annotations

import numpy as np


def revolved_surface(profile, segments: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """The closed triangle surface of the polygon ``profile`` ((k, 2) points
    (r, z), r > 0, in either orientation, not repeating its first point)
    swept about the z axis in ``segments`` steps.  Returns (V, F), oriented
    outwards."""
    P = np.asarray(profile, float)
    area = 0.5 * np.sum(P[:, 0] * np.roll(P[:, 1], -1) - np.roll(P[:, 0], -1) * P[:, 1])
    if area < 0:
        P = P[::-1]
    k = len(P)
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    V = np.concatenate([np.c_[P[:, 0] * np.cos(p), P[:, 0] * np.sin(p), P[:, 1]] for p in phi])
    i = np.arange(k)
    F = []
    for s in range(segments):
        a, b = s * k + i, ((s + 1) % segments) * k + i
        an, bn = s * k + (i + 1) % k, ((s + 1) % segments) * k + (i + 1) % k
        F.append(np.c_[a, an, bn])
        F.append(np.c_[a, bn, b])
    F = np.concatenate(F)
    # outwards: the signed volume is positive
    T = V[F]
    if np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])).sum() < 0:
        F = F[:, ::-1]
    return V, F


def polyline(points, spacing: float) -> np.ndarray:
    """The closed polygon through ``points`` with extra points so that no
    side is longer than ``spacing`` (corners kept)."""
    P = np.asarray(points, float)
    out = []
    for a, b in zip(P, np.roll(P, -1, axis=0)):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + np.linspace(0.0, 1.0, n, endpoint=False)[:, None] * (b - a))
    return np.concatenate(out)


def washer(inner: float = 0.5, outer: float = 1.0, height: float = 0.4, spacing: float = 0.1,
           segments: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """A flat ring with sharp rims: the rectangle [inner, outer] x
    [-height/2, height/2] swept."""
    h = height / 2
    return revolved_surface(polyline([(inner, -h), (outer, -h), (outer, h), (inner, h)], spacing), segments)


def rounded_ring(inner: float = 0.5, outer: float = 1.0, height: float = 0.5, fillet: float = 0.12,
                 spacing: float = 0.05, segments: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """A ring whose rectangular profile has its four corners rounded by
    ``fillet`` (quarter circles, tangent: smooth everywhere)."""
    h = height / 2
    pts = []
    for (cx, cy), start in (((outer - fillet, -h + fillet), -90), ((outer - fillet, h - fillet), 0),
                            ((inner + fillet, h - fillet), 90), ((inner + fillet, -h + fillet), 180)):
        t = np.radians(start + np.linspace(0.0, 90.0, 7))
        pts.append(np.c_[cx + fillet * np.cos(t), cy + fillet * np.sin(t)])
    return revolved_surface(polyline(np.concatenate(pts), spacing), segments)
