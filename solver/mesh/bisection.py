"""Local refinement of a tet mesh by longest-edge bisection (Rivara), to
grade it towards a sizing field (resolution.py) after meshing.

Why after meshing: fTetWild (pytetwild 0.2.3) takes one global edge length
and no sizing field, so a network that needs edges of 0.01 somewhere made it
mesh everything at 0.01 (1.5M tets in 15 minutes, issue 27).  Here fTetWild
meshes the bulk and the tets that are too long for the sizing field at their
centroid are split, a few numpy passes per round.

Each round marks the longest edge of every tet to split; the closure (a tet
holding a marked edge marks its own longest edge, until nothing changes)
makes every marked edge the longest of some tet; every tet holding a marked
edge is then cut in two at its longest edge, and rounds repeat until no
marked edge is left.  A triangle is always cut first at its own longest edge,
from whichever side, so the result is conforming; ties in length are broken
by the vertex ids, the same on both sides.  Longest-edge bisection produces
a bounded number of shapes, so quality does not decay with the depth.

Midpoints of boundary edges on smooth parts of the boundary are moved onto
the input surface (as refine.py does), unless that would flatten a tet.
"""

from __future__ import annotations

import numpy as np

from ..surface.trisurface import TriSurface
from .refine import project_onto_surface
from .tetmesh import TET_EDGES, TetMesh


def _longest(P, T):
    """(T,) local index (0-5, TET_EDGES order) of each tet's longest edge,
    ties broken by the sorted vertex pair, so that every tet holding an edge
    ranks it the same against the others."""
    a, b = T[:, TET_EDGES[:, 0]], T[:, TET_EDGES[:, 1]]
    L = np.sum((P[a] - P[b]) ** 2, axis=2)
    key = np.lexsort((np.maximum(a, b).ravel(), np.minimum(a, b).ravel(), L.ravel()))
    rank = np.empty(key.size, np.int64)
    rank[key] = np.arange(key.size)
    return np.argmax(rank.reshape(-1, 6), axis=1)


_BIG = np.int64(1) << 31  # vertex-pair keys lo * _BIG + hi


def _edge_keys(T):
    a, b = T[:, TET_EDGES[:, 0]], T[:, TET_EDGES[:, 1]]
    return np.minimum(a, b).astype(np.int64) * _BIG + np.maximum(a, b)


def bisect(mesh: TetMesh, mark: np.ndarray, surface: TriSurface | None = None, crease_deg: float = 25.0,
           min_volume_ratio: float = 0.25) -> TetMesh:
    """Refine ``mesh`` conformingly so that every tet in ``mark`` (bool
    (#T,) or ids) is cut at least once.

    surface : the input boundary; new midpoints of boundary edges whose
              dihedral angle is below crease_deg are moved onto it (undone
              where a tet would keep less than min_volume_ratio of its
              volume)
    """
    P = mesh.vertices
    T = mesh.tets
    m = np.zeros(len(T), bool)
    m[mark] = True
    if not np.any(m):
        return mesh
    nv0 = len(P)
    smooth = _smooth_boundary_keys(mesh, crease_deg) if surface is not None else np.zeros(0, np.int64)
    marked = np.unique(_edge_keys(T[m])[np.arange(int(m.sum())), _longest(P, T[m])])
    mid_keys = np.zeros(0, np.int64)  # sorted keys of cut edges
    mid_ids = np.zeros(0, np.int64)  # their midpoints
    while len(marked):
        keys = _edge_keys(T)
        lg = _longest(P, T)
        lkey = keys[np.arange(len(T)), lg]
        # closure: a tet holding a marked edge marks its own longest edge
        # (on the round's edge ids: one sort, then boolean passes)
        ukeys, eid = np.unique(keys, return_inverse=True)
        eid = eid.reshape(keys.shape)
        leid = eid[np.arange(len(T)), lg]
        on = np.isin(ukeys, marked, assume_unique=True)
        while True:
            has = on[eid].any(axis=1)
            new = leid[has][~on[leid[has]]]
            if len(new) == 0:
                break
            on[new] = True
        marked = ukeys[on]
        cut = np.unique(lkey[has])
        fresh = np.setdiff1d(cut, mid_keys)
        a, b = fresh // _BIG, fresh % _BIG
        ids = len(P) + np.arange(len(fresh))
        P = np.vstack([P, 0.5 * (P[a] + P[b])])
        if len(smooth):
            # the halves of a smooth boundary edge are smooth boundary edges
            on = np.isin(fresh, smooth)
            ka = np.minimum(a[on], ids[on]) * _BIG + np.maximum(a[on], ids[on])
            kb = np.minimum(b[on], ids[on]) * _BIG + np.maximum(b[on], ids[on])
            smooth = np.union1d(smooth, np.r_[ka, kb])
        order = np.argsort(np.r_[mid_keys, fresh], kind="stable")
        mid_keys, mid_ids = np.r_[mid_keys, fresh][order], np.r_[mid_ids, ids][order]
        S, loc = T[has], lg[has]
        mids = mid_ids[np.searchsorted(mid_keys, lkey[has])]
        r = np.arange(len(S))
        c1, c2 = S.copy(), S.copy()
        c1[r, TET_EDGES[loc, 0]] = mids
        c2[r, TET_EDGES[loc, 1]] = mids
        T = np.vstack([T[~has], c1, c2])
        # an edge cut in one tet may still be whole in another (cut there
        # at its own longest edge first): it stays marked until gone
        marked = np.intersect1d(marked, _edge_keys(T))
    if len(smooth) and len(P) > nv0:
        P = _project(P, T, nv0, smooth, surface, min_volume_ratio)
    return TetMesh(P, T)


def _smooth_boundary_keys(mesh: TetMesh, crease_deg: float) -> np.ndarray:
    B = mesh.boundary
    e = mesh.boundary_vertices[B.edges[B.dihedral_angles < np.deg2rad(crease_deg)]]
    return np.unique(np.minimum(e[:, 0], e[:, 1]).astype(np.int64) * _BIG + np.maximum(e[:, 0], e[:, 1]))


def _project(P, T, nv0, smooth, surface, min_ratio):
    """Move the new vertices (ids >= nv0) that are midpoints of smooth
    boundary edges onto the surface, undoing moves that would leave a tet
    below min_ratio of its volume."""
    ends = np.unique(np.r_[smooth // _BIG, smooth % _BIG])
    ids = ends[ends >= nv0]
    if len(ids) == 0:
        return P
    return project_onto_surface(P, T, ids, surface, min_ratio)
