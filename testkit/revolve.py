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


def revolved_solid(profile, segments: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """The closed surface of a solid the axis passes through: ``profile``
    ((k, 2) points (r, z)) runs from a point on the axis (r = 0) to another,
    r > 0 between; each end becomes a pole.  Returns (V, F), outwards."""
    P = np.asarray(profile, float)
    if P[0, 0] != 0.0 or P[-1, 0] != 0.0 or np.any(P[1:-1, 0] <= 0):
        raise ValueError("the profile must run from the axis to the axis, off it between")
    mid = P[1:-1]
    k = len(mid)
    phi = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.concatenate([np.c_[mid[:, 0] * np.cos(p), mid[:, 0] * np.sin(p), mid[:, 1]] for p in phi])
    V = np.vstack([ring, [[0.0, 0.0, P[0, 1]], [0.0, 0.0, P[-1, 1]]]])
    south, north = len(ring), len(ring) + 1
    i = np.arange(k - 1)
    F = []
    for s in range(segments):
        a, b = s * k, ((s + 1) % segments) * k
        F.append(np.c_[a + i, a + i + 1, b + i + 1])
        F.append(np.c_[a + i, b + i + 1, b + i])
        F.append([[south, a, b]])
        F.append([[north, b + k - 1, a + k - 1]])
    F = np.concatenate(F).astype(np.int64)
    T = V[F]
    if np.einsum("ij,ij->i", T[:, 0], np.cross(T[:, 1], T[:, 2])).sum() < 0:
        F = F[:, ::-1]
    return V, F


def stepped_shaft(spacing: float = 0.1, segments: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """A cylinder of radius 1 and height 1 with a boss of radius 0.5 and
    height 0.6 on its top face: sharp rims."""
    pts = polyline([(0.0, -0.5), (1.0, -0.5), (1.0, 0.5), (0.5, 0.5), (0.5, 1.1), (0.0, 1.1)], spacing)
    pts = np.vstack([pts, [(0.0, 1.1)]])
    # polyline closes the loop back to the start: drop the closing side along the axis
    keep = np.r_[True, pts[1:-1, 0] > 0, True]
    return revolved_solid(pts[keep], segments)


def collared_shaft(fillet: float = 0.1, spacing: float = 0.05, segments: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """A shaft of radius 0.4 and height 2 with a collar of radius 1 and
    height 0.4 round its middle, the collar's outer rims rounded by
    ``fillet`` (smooth) and the other rims sharp."""
    t = np.radians(np.linspace(0.0, 90.0, 7))
    low = np.c_[1.0 - fillet + fillet * np.sin(t), -0.2 + fillet - fillet * np.cos(t)]
    high = np.c_[1.0 - fillet + fillet * np.cos(t), 0.2 - fillet + fillet * np.sin(t)]
    pts = np.vstack([[(0.0, -1.0), (0.4, -1.0), (0.4, -0.2)], low, high, [(0.4, 0.2), (0.4, 1.0), (0.0, 1.0)]])
    dense = polyline(pts, spacing)
    dense = dense[: np.nonzero(np.all(np.isclose(dense, [0.0, 1.0]), axis=1))[0][0] + 1]
    return revolved_solid(dense, segments)
