"""Prism tubes, node tetrahedra and end caps: internal surfaces handed to
fTetWild so that the tet mesh has the paper's tube structure (§2.1.1, §5.1)
wherever the mesher keeps it.

Each curve gets a tube of triangular prisms whose cross-sections are
equilateral triangles centred on the curve; tubes stop at a distance
``node_radius`` from a node (the node region of embed.py).  A curve ending
on the boundary where the surface is flat ends in a cap triangle lying on
it; elsewhere its tube stops one cross-section spacing short of the surface
and the curve crosses its last stretch through ordinary tets.  (A cap on a
curved surface lies within fTetWild's envelope of it without lying on it:
meshing both made folded boundary triangles, up to 95 degrees off the
surface normal, on which the 3D lift of the boundary cross field got
spurious quarter turns -- the ball failed at h = 0.21-0.25 in most runs.
Tube walls reaching a curved surface did the same, less often.)  Cross-sections
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

from ..network.curves import CurveGeometry
from ..network.network import PreparedNetwork
from ..surface.trisurface import TriSurface

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
    flat_tol: float = 0.0,
) -> TubeSurfaces:
    """Tube soup for every prepared interior curve.

    radius      : circumradius of the cross-section triangles
    spacing     : target distance between cross-sections along a curve; also
                  the gap left between a tube and the boundary
    node_radius : tubes stop this far from a node
    flat_tol    : a curve ending on the boundary keeps its cap triangle on
                  the surface if the cap lies within flat_tol of it
    """
    geos = [CurveGeometry(c.points, c.closed) for c in net.curves]
    # the caps of curves ending on the boundary, and whether each is flat
    ends = [(ci, k) for ci, c in enumerate(net.curves) if not c.closed
            for k, kind in ((0, net.start_kind[ci]), (1, net.end_kind[ci])) if kind == "boundary"]
    caps = {}
    if ends:
        rings = np.array([_rings(geos[ci], np.array([k * geos[ci].arclength[-1]]), False, radius)[0]
                          for ci, k in ends])
        Q = surface.closest_points(rings.reshape(-1, 3))[2].reshape(-1, 3, 3)
        probe = np.concatenate([Q.mean(axis=1, keepdims=True), 0.5 * (Q + np.roll(Q, 1, axis=1))], axis=1)
        off = surface.closest_points(probe.reshape(-1, 3))[0].reshape(len(ends), -1).max(axis=1)
        caps = {e: q for e, q, d in zip(ends, Q, off) if d <= flat_tol}
    # where curves ending on the boundary without a cap get `spacing` away
    # from it (one closest-point query for all of them)
    dense = np.linspace(0.0, 1.0, 400)
    samples = [g.point(*_locate(g, dense * g.arclength[-1])) for g in geos]
    d_dense = _distances(surface, samples, spacing)
    layout = []
    for ci, (c, geo) in enumerate(zip(net.curves, geos)):
        L = geo.arclength[-1]
        s0, s1 = 0.0, L
        far = np.nonzero(d_dense[ci] >= spacing)[0]
        if net.start_kind[ci] == "node":
            s0 = _arclength_at_distance(geo, node_radius, from_start=True)
        elif net.start_kind[ci] == "boundary" and (ci, 0) not in caps:
            s0 = dense[far[0]] * L if len(far) else L
        if net.end_kind[ci] == "node":
            s1 = _arclength_at_distance(geo, node_radius, from_start=False)
        elif net.end_kind[ci] == "boundary" and (ci, 1) not in caps:
            s1 = dense[far[-1]] * L if len(far) else 0.0
        if s1 - s0 < spacing:
            continue
        m = max(1, int(np.ceil((s1 - s0) / spacing)))
        s = np.linspace(0.0, L, m, endpoint=False) if c.closed else np.linspace(s0, s1, m + 1)
        layout.append((ci, s))
    centres = [geos[ci].point(*_locate(geos[ci], s)) for ci, s in layout]
    d_st = _distances(surface, centres, spacing)
    V: list[np.ndarray] = []
    F: list[np.ndarray] = []
    nv = 0
    k2 = (np.arange(3) + 1) % 3
    for (ci, s), dist in zip(layout, d_st):
        closed = net.curves[ci].closed
        ring = _rings(geos[ci], s, closed, radius)
        # a curve that runs close to the boundary gets no tube there; flat
        # caps stay on the surface
        keep = dist >= 0.5 * spacing
        for k, pos in ((0, 0), (1, -1)):
            if (ci, k) in caps:
                ring[pos] = caps[(ci, k)]
                keep[pos] = True
        for run in _runs(keep, closed):
            ids = nv + np.arange(3 * len(run)).reshape(-1, 3)
            V.append(ring[run].reshape(-1, 3))
            nv += 3 * len(run)
            if closed and len(run) == len(keep):
                a, b = ids, np.roll(ids, -1, axis=0)
            else:
                a, b = ids[:-1], ids[1:]
            # two triangles per prism side, and the cross-sections (the
            # paper's S2^A)
            F.append(np.stack([a, a[:, k2], b[:, k2]], axis=2).reshape(-1, 3))
            F.append(np.stack([a, b[:, k2], b], axis=2).reshape(-1, 3))
            F.append(ids)
    Vall = np.vstack(V) if V else np.zeros((0, 3))
    # Each triangle is given once: tetmesh.py decides inside/outside by the
    # domain surface alone, so the tubes' orientation does not matter.  (Given
    # twice, in both orientations, fTetWild sometimes failed to reach its
    # quality target and refined pass after pass: 75k tets in 235 s for the
    # ball at h = 0.25, against 5k tets in 4 s once.)
    Fall = np.vstack(F).astype(np.int64) if F else np.zeros((0, 3), np.int64)
    return TubeSurfaces(Vall, Fall)


def _distances(surface: TriSurface, groups: list[np.ndarray], within: float) -> list[np.ndarray]:
    """Distance to the surface of every point in each group, in one query;
    inf beyond within (only nearness is asked: cheap on a dense surface)."""
    if not groups:
        return []
    d = surface.closest_points(np.vstack(groups), within=within)[0]
    return np.split(d, np.cumsum([len(g) for g in groups])[:-1])


def _rings(geo: CurveGeometry, s: np.ndarray, closed: bool, radius: float) -> np.ndarray:
    """(len(s), 3, 3) cross-section triangles at arc lengths s."""
    seg, t = _locate(geo, s)
    C = geo.point(seg, t)
    Fr = _frames_mod_third(geo, seg, t, closed)
    return C[:, None, :] + radius * (
        np.cos(_ANG)[None, :, None] * Fr[:, None, :, 0] + np.sin(_ANG)[None, :, None] * Fr[:, None, :, 1]
    )


def _runs(keep: np.ndarray, closed: bool) -> list[np.ndarray]:
    """Maximal runs of consecutive True stations (index arrays); on a loop a
    run may wrap around, and a loop kept whole is one run of every station."""
    n = len(keep)
    if keep.all():
        return [np.arange(n)]
    idx = np.arange(n)
    if closed:
        # start just after a dropped station, so no run wraps
        first = int(np.nonzero(~keep)[0][0])
        idx = np.roll(idx, -(first + 1))
    k = keep[idx]
    edges = np.diff(np.r_[0, k.astype(np.int8), 0])
    starts, stops = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    return [idx[a:b] for a, b in zip(starts, stops)]


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
