"""Curve ends inside the mesher's triangles, not on its vertices or edges.

A curve that passes through a tet vertex or edge pierces the faces around it
at a corner: their quarter turn is packed into a sliver of the tube, and
the structure penalty there is tens of times what the same curve scores
through the middle of the faces.  Networks that other tools export end
where *their* mesh had a boundary vertex: the singular graph of a hex mesh
ends at vertices of its boundary quads, a tet-edge chain at a vertex of its
tet mesh's boundary, and the surface that comes with such a network is that
same boundary.  fTetWild keeps the input's vertices and edges where they fit
its mesh, so the tet mesh then has a vertex exactly at the curve's end.  On a
cube-sphere ball whose surface is the hex mesh's own boundary, 5.8 of its 5.9
penalty lay within h of the 8 radial ends; meshed from the surface cleared
here, the same input scores 0.16 (the same network on an icosphere: 0.23).

``clear_curve_ends`` gives the mesher a copy of its surface in which no
vertex lies within ``CLEAR * h`` of a curve end and no edge within
``EDGE_CLEAR`` of that: the vertices near an end move away from it in the
tangent plane, by at most ``MAX_MOVE`` of their shortest edge, and
back onto the surface; the ends of an edge passing close by move it aside.
A move that would turn a triangle by more than ``MAX_TURN`` degrees or
shrink it below ``MIN_AREA`` of its area is not made; vertices on sharp
edges never move.  The input surface itself is not changed: validation,
snapping, refinement and the hex stage read it.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from ..surface.trisurface import TriSurface

CLEAR = 0.3  # no mesher vertex within this many h of a curve end ...
EDGE_CLEAR = 0.3  # ... and no mesher edge within this fraction of that
MAX_MOVE = 0.4  # a vertex moves at most this fraction of its shortest edge
MAX_TURN = 8.0  # degrees a triangle may turn when one of its vertices moves
MIN_AREA = 0.3  # ... and the fraction of its area it keeps


def clear_curve_ends(surface: TriSurface, ends: np.ndarray, h: float, fixed: np.ndarray | None = None,
                     rounds: int = 2) -> tuple[TriSurface, int]:
    """The surface the mesher gets, with the curve ends off its vertices and
    edges (module docstring).

    Parameters
    ----------
    surface : TriSurface
        The surface the mesher would get (the input, or its simplification).
    ends : (k, 3) float array
        Curve ends on the surface.
    h : float
        The mesh's edge length.
    fixed : (#V,) bool array, optional
        Vertices that never move (on sharp edges); by default those of the
        edges whose dihedral angle exceeds 30 degrees.
    rounds : int
        Passes over the ends (a move can bring another vertex closer).

    Returns
    -------
    surface : TriSurface
        ``surface`` itself where nothing moved, else a copy.
    moved : int
        The vertices moved.
    """
    ends = np.asarray(ends, float).reshape(-1, 3)
    if not len(ends):
        return surface, 0
    if fixed is None:
        fixed = np.zeros(len(surface.V), bool)
        fixed[surface.edges[np.degrees(surface.dihedral_angles) > 30.0].reshape(-1)] = True
    V = surface.V.copy()
    F = surface.F
    vf = _vertex_faces(F, len(V))
    shortest = _shortest_edges(V, F)
    moved = np.zeros(len(V), bool)
    r = CLEAR * h
    for _ in range(rounds):
        changed = False
        tree = cKDTree(V)
        for x in ends:
            _, _, nrm = _normal_at(surface, x)
            for v in tree.query_ball_point(x, r):
                if fixed[v]:
                    continue
                d = V[v] - x
                d -= (d @ nrm) * nrm
                if np.linalg.norm(d) < 1e-9 * h:
                    # the end on the vertex: away from one of its triangles, so
                    # that the end comes to lie inside that triangle
                    d = V[v] - V[F[vf[v][0]]].mean(axis=0)
                    d -= (d @ nrm) * nrm
                dist = min(r, MAX_MOVE * shortest[v] + float(np.linalg.norm(V[v] - x)))
                target = x + dist * d / max(np.linalg.norm(d), 1e-300)
                changed |= _try_move(surface, V, vf, v, target, moved)
            # an edge passing close by: its two ends step aside
            f0 = _normal_at(surface, x)[1]
            fs = np.unique(np.concatenate([vf[v] for v in F[f0]]))
            for a, b in _close_edges(V, F[fs], x, EDGE_CLEAR * r):
                if fixed[a] or fixed[b]:
                    continue
                ab = V[b] - V[a]
                foot = V[a] + np.clip((x - V[a]) @ ab / (ab @ ab), 0.0, 1.0) * ab
                w = foot - x
                w -= (w @ nrm) * nrm
                n = np.linalg.norm(w)
                if n < 1e-9 * h:
                    w = np.cross(nrm, ab)
                    n = np.linalg.norm(w)
                step = (EDGE_CLEAR * r - float(np.linalg.norm(foot - x))) * w / max(n, 1e-300)
                for p in (a, b):
                    changed |= _try_move(surface, V, vf, p, V[p] + step, moved)
        if not changed:
            break
    if not moved.any():
        return surface, 0
    return TriSurface(V, F.copy()), int(moved.sum())


def _try_move(surface: TriSurface, V: np.ndarray, vf: list, v: int, target: np.ndarray, moved: np.ndarray) -> bool:
    """Move vertex v to target, put back onto the surface, unless one of its
    triangles would turn by more than MAX_TURN or lose more than 1 - MIN_AREA
    of its area."""
    _, _, q = surface.closest_points(target[None])
    faces = surface.F[vf[v]]
    before = _normals(V, faces)
    old = V[v].copy()
    V[v] = q[0]
    after = _normals(V, faces)
    a0, a1 = np.linalg.norm(before, axis=1), np.linalg.norm(after, axis=1)
    cos = np.einsum("ij,ij->i", before, after) / np.maximum(a0 * a1, 1e-300)
    if np.any(cos < np.cos(np.radians(MAX_TURN))) or np.any(a1 < MIN_AREA * a0):
        V[v] = old
        return False
    moved[v] |= bool(np.linalg.norm(V[v] - old) > 0)
    return True


def _normals(V: np.ndarray, faces: np.ndarray) -> np.ndarray:
    P = V[faces]
    return np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])


def _normal_at(surface: TriSurface, x: np.ndarray):
    d, f, q = surface.closest_points(x[None])
    return d[0], int(f[0]), surface.face_normals[int(f[0])]


def _vertex_faces(F: np.ndarray, n: int) -> list:
    order = np.argsort(F.reshape(-1), kind="stable")
    counts = np.bincount(F.reshape(-1), minlength=n)
    faces = (order // 3).astype(np.int64)
    return np.split(faces, np.cumsum(counts)[:-1])


def _shortest_edges(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    E = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    L = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    out = np.full(len(V), np.inf)
    np.minimum.at(out, E[:, 0], L)
    np.minimum.at(out, E[:, 1], L)
    return out


def _close_edges(V: np.ndarray, faces: np.ndarray, x: np.ndarray, tol: float) -> list:
    """Edges (a, b) of the faces that pass within tol of x."""
    if not len(faces):
        return []
    E = np.unique(np.sort(np.vstack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    A, B = V[E[:, 0]], V[E[:, 1]]
    ab = B - A
    t = np.clip(np.einsum("ij,ij->i", x - A, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
    d = np.linalg.norm(A + t[:, None] * ab - x, axis=1)
    # an edge ending at a vertex near x is the vertex's business
    inner = (t > 1e-6) & (t < 1 - 1e-6)
    return [tuple(e) for e in E[(d < tol) & inner].tolist()]

