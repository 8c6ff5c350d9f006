"""Prism tubes, node tetrahedra and end caps: internal surfaces handed to
fTetWild so that the tet mesh has the paper's tube structure (§2.1.1, §5.1)
wherever the mesher keeps it.

Each curve gets a tube of triangular prisms whose cross-sections are
equilateral triangles centred on the curve; a curve ending on the boundary
ends in a cap triangle lying on the surface; tubes stop at a distance
``node_radius`` from a node (the node region of embed.py).  Cross-sections
are part of the input, so the curve pierces each of them at its centroid and
every tube edge turns about the tangent by about a third of the curve's
winding; the paper's S2^A faces then carry rotations about T only, where the
second-order structure equation is exact.

fTetWild treats the input as a triangle soup within an envelope, so tubes
that touch each other or the boundary never make meshing fail (the failure
the paper reports for TetGen, §6); where structure is lost, embed.py still
traces the curve through whatever tets are there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .curves import CurveGeometry
from .network import PreparedNetwork
from .trisurface import TriSurface

_ANG = np.array([0.0, 2 * np.pi / 3, 4 * np.pi / 3])


@dataclass
class TubeSurfaces:
    """Triangles to add to the domain surface before tetrahedralisation.

    V, F : the soup (vertex ids local to V)
    """

    V: np.ndarray
    F: np.ndarray


def build_tubes(
    net: PreparedNetwork,
    surface: TriSurface,
    radius: float,
    spacing: float,
    node_radius: float,
) -> TubeSurfaces:
    """Tube soup for every prepared interior curve.

    radius      : circumradius of the cross-section triangles
    spacing     : target distance between cross-sections along a curve
    node_radius : tubes stop this far from a node
    """
    V: list[np.ndarray] = []
    F: list[np.ndarray] = []
    nv = 0

    def add(P):
        nonlocal nv
        ids = nv + np.arange(len(P))
        V.append(np.asarray(P, float))
        nv += len(P)
        return ids

    for ci, c in enumerate(net.curves):
        geo = CurveGeometry(c.points, c.closed)
        L = geo.arclength[-1]
        s0 = 0.0
        s1 = L
        if net.start_kind[ci] == "node":
            s0 = _arclength_at_distance(geo, node_radius, from_start=True)
        if net.end_kind[ci] == "node":
            s1 = _arclength_at_distance(geo, node_radius, from_start=False)
        if s1 - s0 < spacing:
            continue
        m = max(1, int(np.ceil((s1 - s0) / spacing)))
        if c.closed:
            s = np.linspace(0.0, L, m, endpoint=False)
        else:
            s = np.linspace(s0, s1, m + 1)
        seg, t = _locate(geo, s)
        C = geo.point(seg, t)
        Fr = _frames_mod_third(geo, seg, t, c.closed)
        ring = C[:, None, :] + radius * (
            np.cos(_ANG)[None, :, None] * Fr[:, None, :, 0] + np.sin(_ANG)[None, :, None] * Fr[:, None, :, 1]
        )
        if not c.closed:
            # ends on the boundary: put the cap triangle on the surface
            if net.start_kind[ci] == "boundary":
                ring[0] = surface.closest_points(ring[0])[2]
            if net.end_kind[ci] == "boundary":
                ring[-1] = surface.closest_points(ring[-1])[2]
        ids = add(ring.reshape(-1, 3)).reshape(-1, 3)
        stations = [ids[k] for k in range(len(ids))]
        if c.closed:
            stations = stations + [stations[0]]
        for a, b in zip(stations[:-1], stations[1:]):
            for k in range(3):
                k2 = (k + 1) % 3
                F.append(np.array([a[k], a[k2], b[k2]]))
                F.append(np.array([a[k], b[k2], b[k]]))
        # every cross-section is an input triangle (the paper's S2^A)
        for st in stations[:-1] if c.closed else stations:
            F.append(np.asarray(st))
    Vall = np.vstack(V) if V else np.zeros((0, 3))
    Fall = np.array(F, dtype=np.int64).reshape(-1, 3)
    # Each triangle is given in both orientations: fTetWild still embeds it,
    # but its contributions to the generalised winding number that decides
    # inside/outside cancel, so tubes that cross each other or the boundary
    # cannot carve cavities or add material.
    Fall = np.vstack([Fall, Fall[:, [0, 2, 1]]])
    return TubeSurfaces(Vall, Fall)



def _locate(geo: CurveGeometry, s: np.ndarray):
    """Segment and fraction of arc-length positions s."""
    L = geo.arclength
    seg = np.clip(np.searchsorted(L, s, side="right") - 1, 0, len(L) - 2)
    t = (s - L[seg]) / np.maximum(L[seg + 1] - L[seg], 1e-300)
    return seg, np.clip(t, 0.0, 1.0)


def _frames_mod_third(geo: CurveGeometry, seg, t, closed):
    """Rotation-minimising frames; on a loop the holonomy is spread so the
    triangular cross-sections close up (mod 120 degrees)."""
    F = geo.frame(seg, t)
    if closed and len(F) > 1:
        # geo.frames closes up mod 90 degrees; redo mod 120
        raw = CurveGeometry(geo.P, False).frames
        M = raw[0].T @ raw[-1]
        beta = np.arctan2(M[1, 0], M[0, 0])
        excess = beta - np.round(beta / (2 * np.pi / 3)) * (2 * np.pi / 3)
        frac = (geo.arclength[seg] + t * (geo.arclength[seg + 1] - geo.arclength[seg])) / geo.arclength[-1]
        rawF = CurveGeometry(geo.P, False).frame(seg, t)
        ang = -excess * frac
        c, s = np.cos(ang), np.sin(ang)
        x = c[:, None] * rawF[:, :, 0] + s[:, None] * rawF[:, :, 1]
        y = -s[:, None] * rawF[:, :, 0] + c[:, None] * rawF[:, :, 1]
        F = np.stack([x, y, rawF[:, :, 2]], axis=2)
    return F


def _arclength_at_distance(geo: CurveGeometry, d: float, from_start: bool) -> float:
    """Arc length of the first curve point at straight-line distance d from
    the start (or the last such point before the end)."""
    P = geo.P
    ref = P[0] if from_start else P[-1]
    # densify to find the crossing
    s = np.linspace(0.0, geo.arclength[-1], 400)
    seg, t = _locate(geo, s)
    dist = np.linalg.norm(geo.point(seg, t) - ref, axis=1)
    if from_start:
        k = np.nonzero(dist >= d)[0]
        return float(s[k[0]]) if len(k) else float(s[-1])
    k = np.nonzero(dist >= d)[0]
    return float(s[k[-1]]) if len(k) else float(s[0])
