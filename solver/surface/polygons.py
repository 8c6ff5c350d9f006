"""Triangulating the polygons of an OBJ file.

A fan from the first vertex is only right for convex polygons without
collinear vertices: a cube face drawn as one octagon through its edge
midpoints fans into triangles of zero area (three collinear vertices), and
a non-convex polygon fans into overlapping triangles.  Polygons are
triangulated here by ear clipping in their best-fit plane (Newell's normal),
never cutting an ear with zero area or one that contains another vertex of
the polygon, so the triangles tile the polygon and keep its orientation.
Triangles pass through; quads, the common case, are split vectorised along
the diagonal that gives two triangles of positive area.
"""

from __future__ import annotations

import numpy as np


def newell_normals(P: np.ndarray) -> np.ndarray:
    """Area-weighted normals of polygons P (k, n, 3) (Newell's method; right
    for non-convex and non-planar polygons)."""
    Q = np.roll(P, -1, axis=1)
    return 0.5 * np.cross(P, Q).sum(axis=1)


def _plane_coords(P: np.ndarray, n: np.ndarray) -> np.ndarray:
    """2D coordinates of points P (m, 3) in the plane with normal n,
    oriented so that the polygon's own orientation is counter-clockwise."""
    n = n / np.linalg.norm(n)
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    u = np.cross(n, a)
    u /= np.linalg.norm(u)
    v = np.cross(n, u)
    X = P - P.mean(axis=0)
    return np.c_[X @ u, X @ v]


def ear_clip(P: np.ndarray) -> np.ndarray | None:
    """Triangles (n - 2, 3) of local indices tiling polygon P (n, 3), or None
    when the polygon has (near) zero area or could not be cut."""
    n = len(P)
    nrm = newell_normals(P[None])[0]
    scale = np.max(np.linalg.norm(P - P.mean(axis=0), axis=1))
    if not np.linalg.norm(nrm) > 1e-12 * scale**2:
        return None
    X = _plane_coords(P, nrm)
    tol = 1e-12 * scale**2
    idx = list(range(n))
    out = []
    while len(idx) > 3:
        m = len(idx)
        Y = X[idx]
        prv, nxt = np.roll(Y, 1, axis=0), np.roll(Y, -1, axis=0)
        cross = (Y[:, 0] - prv[:, 0]) * (nxt[:, 1] - prv[:, 1]) - (Y[:, 1] - prv[:, 1]) * (nxt[:, 0] - prv[:, 0])
        best, best_area = -1, 0.0
        for k in np.argsort(-cross):  # the fattest ears first: better triangles
            if cross[k] <= tol:
                break
            a, b, c = prv[k], Y[k], nxt[k]
            others = np.ones(m, bool)
            others[[(k - 1) % m, k, (k + 1) % m]] = False
            Z = Y[others]
            # reflex or collinear vertices inside the ear or on its edges block it
            e1 = (b[0] - a[0]) * (Z[:, 1] - a[1]) - (b[1] - a[1]) * (Z[:, 0] - a[0])
            e2 = (c[0] - b[0]) * (Z[:, 1] - b[1]) - (c[1] - b[1]) * (Z[:, 0] - b[0])
            e3 = (a[0] - c[0]) * (Z[:, 1] - c[1]) - (a[1] - c[1]) * (Z[:, 0] - c[0])
            inside = (e1 >= -tol) & (e2 >= -tol) & (e3 >= -tol)
            # a duplicate of an ear vertex (a polygon touching itself) is not inside
            dup = (np.linalg.norm(Z - a, axis=1) <= 1e-12 * scale) | (np.linalg.norm(Z - c, axis=1) <= 1e-12 * scale)
            if not np.any(inside & ~dup):
                best, best_area = int(k), cross[k]
                break
        if best < 0 or best_area <= tol:
            return None
        out.append((idx[(best - 1) % m], idx[best], idx[(best + 1) % m]))
        del idx[best]
    Y = X[idx]
    area = (Y[1, 0] - Y[0, 0]) * (Y[2, 1] - Y[0, 1]) - (Y[1, 1] - Y[0, 1]) * (Y[2, 0] - Y[0, 0])
    if area <= tol:
        return None
    out.append(tuple(idx))
    return np.array(out, np.int64)


def triangulate_quads(V: np.ndarray, Q: np.ndarray) -> np.ndarray:
    """(2k, 3) triangles of quads Q (k, 4): each split along the diagonal
    whose two triangles both turn the way the quad does (for a convex quad
    the shorter one)."""
    P = V[Q]
    nrm = newell_normals(P)

    def ok(i, j, k):
        return np.einsum("ij,ij->i", np.cross(P[:, j] - P[:, i], P[:, k] - P[:, i]), nrm) > 0

    good02 = ok(0, 1, 2) & ok(0, 2, 3)
    good13 = ok(1, 2, 3) & ok(1, 3, 0)
    d02 = np.linalg.norm(P[:, 2] - P[:, 0], axis=1)
    d13 = np.linalg.norm(P[:, 3] - P[:, 1], axis=1)
    use13 = good13 & (~good02 | (d13 < d02))
    A = np.where(use13[:, None], Q[:, [1, 2, 3]], Q[:, [0, 1, 2]])
    B = np.where(use13[:, None], Q[:, [1, 3, 0]], Q[:, [0, 2, 3]])
    return np.stack([A, B], axis=1).reshape(-1, 3)


def triangulate_polygons(V: np.ndarray, polygons: list[np.ndarray]):
    """Triangles of polygons (lists of vertex indices into V).

    Returns (F (m, 3) int array, source (m,) polygon index of each triangle,
    failed: indices of polygons with zero area that could not be cut).
    """
    sizes = np.array([len(p) for p in polygons], np.int64)
    tris, src, failed = [], [], []
    for size in (3, 4):
        sel = np.nonzero(sizes == size)[0]
        if len(sel):
            A = np.array([polygons[i] for i in sel], np.int64)
            tris.append(A if size == 3 else triangulate_quads(V, A))
            src.append(sel if size == 3 else np.repeat(sel, 2))
    for i in np.nonzero(sizes > 4)[0]:
        p = np.asarray(polygons[i], np.int64)
        t = ear_clip(V[p])
        if t is None:
            failed.append(int(i))
            continue
        tris.append(p[t])
        src.append(np.full(len(t), i))
    if not tris:
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64), failed
    F = np.vstack(tris)
    source = np.concatenate(src)
    order = np.argsort(source, kind="stable")  # triangles in the file's order
    return F[order], source[order], failed
