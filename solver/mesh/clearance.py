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

from ..surface.intersect import segments_distance
from ..surface.trisurface import TriSurface

CLEAR = 0.3  # no mesher vertex within this many h of a curve end ...
EDGE_CLEAR = 0.3  # ... and no mesher edge within this fraction of that
MAX_MOVE = 0.4  # a vertex moves at most this fraction of its shortest edge
MAX_TURN = 8.0  # degrees a triangle may turn when one of its vertices moves
MIN_AREA = 0.3  # ... and the fraction of its area it keeps


def _crease_vertices(surface: TriSurface, angle: float) -> np.ndarray:
    """(#V,) bool: the vertices of the edges whose two triangles turn by
    more than ``angle`` degrees, and of the edges not shared by exactly two
    triangles.  A clustered surface (decimate.py) need not be manifold where
    a part thinner than its cell collapsed (a collared shaft's cluster: 2
    edges of 4 triangles), and TriSurface.dihedral_angles assumes it is
    (an IndexError reached the user)."""
    fe = surface.face_edges.reshape(-1)
    count = np.bincount(fe, minlength=len(surface.edges))
    order = np.argsort(fe, kind="stable")
    faces = np.repeat(np.arange(len(surface.F)), 3)[order]
    start = np.r_[0, np.cumsum(count)[:-1]]
    two = np.nonzero(count == 2)[0]
    n = surface.face_normals
    cos = np.einsum("ij,ij->i", n[faces[start[two]]], n[faces[start[two] + 1]])
    crease = np.ones(len(count), bool)
    crease[two] = cos < np.cos(np.radians(angle))
    fixed = np.zeros(len(surface.V), bool)
    fixed[surface.edges[crease].reshape(-1)] = True
    return fixed


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
        fixed = _crease_vertices(surface, 30.0)
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



# ---------------------------------------------------------------------------
# inside the solid: the tet mesh's vertices and edges off the curves

INNER_CLEAR = 0.2  # no interior vertex within this many local edge lengths of a curve ...
INNER_EDGE_CLEAR = 0.05  # ... and no tet edge within this many (the lightest touch that clears the cases measured)
INNER_MOVE = 0.35  # a vertex moves at most this fraction of its shortest edge
KEEP_QUALITY = 0.8  # ... and its tets keep at least this fraction of their least mean-ratio quality
_DIRECTIONS = 16  # candidate directions in the plane across the curve (and as many tilted by 45 degrees)


def clear_curves(mesh, curves: list, skip: list | None = None, rounds: int = 2):
    """The tet mesh with no interior vertex within ``INNER_CLEAR`` of a
    local edge length of a curve and no edge within ``INNER_EDGE_CLEAR``.

    A curve that passes by a tet vertex or along a tet edge pierces the
    faces around it at their corners: their quarter turn is packed into a
    sliver and the edges there turn by 60-85 degrees, where the
    second-order structure equation (Eq. 17) no longer holds, so LM ends at
    a penalty above the discretisation level in a handful of faces.  Where
    a curve meets a curved surface (no tube cap, tubes.py) this is the rule
    rather than chance: the last tet sits on the end's boundary triangle
    with its apex above it, close to the curve coming in along the normal.
    (A radial curve of a cube-sphere ellipsoid passing 0.007 h from such an
    apex's edge: 95 % of the penalty 11.2 in 4 faces, above the level 8.4.)

    Each offending interior vertex moves to the best of a few candidate
    places across the curve (at most ``INNER_MOVE`` of its shortest edge):
    of those where its own clearance and its edges' are largest, the one
    where its tets are best, provided they keep their orientation and
    ``KEEP_QUALITY`` of their least quality.
    Boundary vertices never move, nor vertices within a ball of ``skip``
    (node regions: their faces carry no structure equation).

    Parameters
    ----------
    mesh : TetMesh
    curves : list of (n, 3) float arrays
        The curves' polylines.
    skip : list of (centre (3,), radius) pairs, optional
    rounds : int
        Passes (a move can bring a neighbour's edge closer).

    Returns
    -------
    mesh : TetMesh
        ``mesh`` itself where nothing moved, else a new mesh.
    moved : int
        The vertices moved.
    """
    from .tetmesh import TetMesh

    curves = [np.asarray(c, float) for c in curves if len(c) >= 2]
    if not curves:
        return mesh, 0
    A = np.vstack([c[:-1] for c in curves])
    B = np.vstack([c[1:] for c in curves])
    seg = np.linalg.norm(B - A, axis=1)
    keep = seg > 0
    A, B = A[keep], B[keep]
    seg_tree = cKDTree(0.5 * (A + B))
    half = 0.5 * float(seg[keep].max()) if keep.any() else 0.0
    X = mesh.vertices.copy()
    T = mesh.tets
    E = mesh.edges
    L = mesh.edge_lengths
    nv = len(X)
    h_loc = np.bincount(E.reshape(-1), np.repeat(L, 2), nv) / np.maximum(np.bincount(E.reshape(-1), minlength=nv), 1)
    shortest = np.full(nv, np.inf)
    np.minimum.at(shortest, E[:, 0], L)
    np.minimum.at(shortest, E[:, 1], L)
    movable = ~mesh.is_boundary_vertex
    for c, r in skip or []:
        movable &= np.linalg.norm(X - np.asarray(c, float), axis=1) > r
    vt = _incidence(T, nv)
    ve = _incidence(E, nv)
    moved = np.zeros(nv, bool)
    for _ in range(rounds):
        bad, near = _offenders(X, E, h_loc, movable, A, B, seg_tree, half)
        if not len(bad):
            break
        changed = False
        for v in bad:
            changed |= _move_vertex(X, T, E, v, vt[v], ve[v], h_loc, shortest[v], A, B, seg_tree, half, moved, near)
        if not changed:
            break
    if not moved.any():
        return mesh, 0
    return TetMesh(X, T.copy()), int(moved.sum())


def _incidence(C: np.ndarray, n: int) -> list:
    """For each of n vertices, the rows of C holding it."""
    flat = C.reshape(-1)
    order = np.argsort(flat, kind="stable")
    rows = (order // C.shape[1]).astype(np.int64)
    return np.split(rows, np.cumsum(np.bincount(flat, minlength=n))[:-1])


def _mean_ratio(X: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Signed mean-ratio quality of tets: 1 regular, 0 flat, < 0 inverted."""
    P = X[T]
    vol = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), P[:, 3] - P[:, 0]) / 6.0
    pairs = ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))
    l2 = sum(np.einsum("ij,ij->i", P[:, a] - P[:, b], P[:, a] - P[:, b]) for a, b in pairs)
    return 12.0 * (3.0 * np.abs(vol)) ** (2.0 / 3.0) / np.maximum(l2, 1e-300) * np.sign(vol)


def _near_segments(x: np.ndarray, reach: float, seg_tree, half: float) -> np.ndarray:
    return np.asarray(seg_tree.query_ball_point(x, reach + half), dtype=np.int64)


def _segments_distance(P: np.ndarray, Q: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Distance between segments P->Q (k, 3) and A->B (s, 3), all pairs: (k, s)."""
    k, n = len(P), len(A)
    d, _ = segments_distance(np.repeat(P, n, axis=0), np.repeat(Q, n, axis=0), np.tile(A, (k, 1)), np.tile(B, (k, 1)))
    return d.reshape(k, n)


def _pair_distances(P, Q, A, B, lists) -> np.ndarray:
    """For each segment P[i]->Q[i], its least distance to the segments
    A->B listed in lists[i] (cKDTree.query_ball_point's), inf where none:
    one vectorised call over all the pairs."""
    n = np.fromiter((len(x) for x in lists), np.int64, len(lists))
    out = np.full(len(lists), np.inf)
    if not n.sum():
        return out
    i = np.repeat(np.arange(len(lists)), n)
    j = np.fromiter((s for x in lists for s in x), np.int64, int(n.sum()))
    d, _ = segments_distance(P[i], Q[i], A[j], B[j])
    np.minimum.at(out, i, d)
    return out


def _offenders(X, E, h_loc, movable, A, B, seg_tree, half) -> tuple[np.ndarray, np.ndarray]:
    """Movable vertices too close to a curve, or ends of an edge that is,
    the closest first; and which vertices (any) lie too close."""
    dv = _pair_distances(X, X, A, B, seg_tree.query_ball_point(X, INNER_CLEAR * h_loc + half))
    near_curve = dv < INNER_CLEAR * h_loc
    score = np.full(len(X), np.inf)
    score[near_curve & movable] = (dv / (INNER_CLEAR * h_loc))[near_curve & movable]
    # edges with a movable end and neither end near a curve (an edge ending
    # near one is that end's business)
    ecand = np.nonzero((movable[E[:, 0]] | movable[E[:, 1]]) & ~near_curve[E[:, 0]] & ~near_curve[E[:, 1]])[0]
    a, b = X[E[ecand, 0]], X[E[ecand, 1]]
    he = 0.5 * (h_loc[E[ecand, 0]] + h_loc[E[ecand, 1]])
    reach = 0.5 * np.linalg.norm(b - a, axis=1) + INNER_EDGE_CLEAR * he + half
    de = _pair_distances(a, b, A, B, seg_tree.query_ball_point(0.5 * (a + b), reach)) / (INNER_EDGE_CLEAR * he)
    close = de < 1.0
    for end in (0, 1):
        v = E[ecand[close], end]
        m = movable[v]
        np.minimum.at(score, v[m], de[close][m])
    bad = np.nonzero(np.isfinite(score))[0]
    return bad[np.argsort(score[bad], kind="stable")], near_curve


def _clearance(X, E, v, edges, h_loc, A, B, seg_tree, half, points: np.ndarray, near: np.ndarray) -> np.ndarray:
    """For candidate positions ``points`` (c, 3) of vertex v: the least of its
    clearance from the curves and its edges', each over its bar (1 = clear);
    an edge whose other end lies near a curve is that end's business."""
    other = np.where(E[edges, 0] == v, E[edges, 1], E[edges, 0])
    reach = float(np.max(np.linalg.norm(X[other] - X[v], axis=1))) + INNER_MOVE * h_loc[v]
    other = other[~near[other]]
    segs = _near_segments(X[v], reach, seg_tree, half)
    if not len(segs):
        return np.full(len(points), np.inf)
    a, b = A[segs], B[segs]
    dv = _segments_distance(points, points, a, b).min(axis=1) / (INNER_CLEAR * h_loc[v])
    if not len(other):
        return dv
    he = 0.5 * (h_loc[v] + h_loc[other])
    P = np.repeat(points, len(other), axis=0)
    Q = np.tile(X[other], (len(points), 1))
    de = (_segments_distance(P, Q, a, b).min(axis=1) / (INNER_EDGE_CLEAR * np.tile(he, len(points))))
    return np.minimum(dv, de.reshape(len(points), len(other)).min(axis=1))


def _move_vertex(X, T, E, v, tets, edges, h_loc, shortest, A, B, seg_tree, half, moved, near) -> bool:
    """Move v to the candidate place with the best clearance (``clear_curves``)."""
    segs = _near_segments(X[v], INNER_CLEAR * h_loc[v] + 1.5 * h_loc[v], seg_tree, half)
    if not len(segs):
        return False
    # the curve's direction near v: the nearest segment's
    d = _segments_distance(X[v][None], X[v][None], A[segs], B[segs])[0]
    s = segs[int(np.argmin(d))]
    t = B[s] - A[s]
    t /= np.linalg.norm(t)
    u = np.cross(t, [1.0, 0.0, 0.0] if abs(t[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(t, u)
    ang = 2 * np.pi * np.arange(_DIRECTIONS) / _DIRECTIONS
    across = np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * w
    dirs = np.vstack([across, (across + t) / np.sqrt(2), (across - t) / np.sqrt(2)])
    step = INNER_MOVE * shortest
    pts = np.vstack([X[v][None]] + [X[v] + f * step * dirs for f in (1 / 3, 2 / 3, 1.0)])
    score = _clearance(X, E, v, edges, h_loc, A, B, seg_tree, half, pts, near)
    # each candidate's tets: oriented and keeping KEEP_QUALITY of their least
    # quality; of the clearest, the one whose tets are best
    P = X[T[tets]]
    at = (T[tets] == v)[None, :, :, None]
    Pc = np.where(at, pts[:, None, None, :], P[None])
    q = _mean_ratio(Pc.reshape(-1, 3), np.arange(4 * len(pts) * len(tets)).reshape(-1, 4)).reshape(len(pts), -1)
    qmin = q.min(axis=1)
    floor = KEEP_QUALITY * max(float(qmin[0]), 0.0)
    capped = np.minimum(score, 1.0)
    ok = (qmin > floor) & (capped > capped[0] + 1e-9)
    if not ok.any():
        return False
    cand = np.nonzero(ok)[0]
    best = int(cand[np.lexsort((-qmin[cand], -capped[cand]))[0]])
    X[v] = pts[best]
    moved[v] = True
    segs = _near_segments(X[v], INNER_CLEAR * h_loc[v], seg_tree, half)
    near[v] = bool(len(segs)) and _segments_distance(X[v][None], X[v][None], A[segs], B[segs]).min() < \
        INNER_CLEAR * h_loc[v]
    return True
