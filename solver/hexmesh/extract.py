"""Stage 6 of hex meshing: hexahedra from an integer-grid map.

For a locally injective map whose boundary, curves and transitions are
integer (seamless.py), the hex mesh is the preimage of the integer grid
(HexEx, Lyon et al. 2016; HexHex, Kohler et al. 2025, which likewise
requires local injectivity).  Here:

1. The parameters are snapped to multiples of 2^-20 (HexHex's "truncate
   precision"), so that every transition u_B = M u_A + tau holds exactly in
   floating point.
2. Vertices: the integer points of every tet's image (a vectorised
   bounding-box scan and barycentric test); the same point found from
   several tets (on a shared face, edge or vertex) is one vertex, merged by
   its position in the solid.
3. Cells: the half-integer points (cell centres) of every tet's image.
   From each centre, a straight segment is traced to each of the cell's 8
   corners, tet by tet, applying the face transitions (HexEx's tracing,
   cell-centred): the segments end on singular edges but never cross one,
   since those lie on integer lines.  The corners are looked up among the
   vertices; the corner order is VTK's, in the chart of the centre's tet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..linalg.rotations import CUBE_GROUP
from ..mesh.tetmesh import TetMesh
from ..surface.trisurface import first_rows
from .transitions import GROUP_INVERSE, Transitions

SNAP = 2.0**-20
EPS = 1e-9

VTK_CORNERS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                        [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]])
"""Corner k of a VTK_HEXAHEDRON (type 12) in the unit cube."""


class ExtractionError(RuntimeError):
    """The map cannot be turned into hexahedra (it is not locally injective
    or its boundary is not on integer planes)."""


@dataclass
class RawHexes:
    """vertices (n, 3), hexes (m, 8) in VTK order, and what the tracing saw."""

    vertices: np.ndarray
    hexes: np.ndarray
    lost_corners: int
    duplicate_cells: int
    fractional: int = 0  # cut faces whose translation is not an integer vector


def snap(U: np.ndarray) -> np.ndarray:
    return np.round(U / SNAP) * SNAP


def _barycentric_frames(U: np.ndarray):
    """Per tet (#T, 3, 3) inverse of the parameter edge matrix: lambda_1..3
    of a point p are Binv @ (p - U[:, 0])."""
    Bm = np.transpose(U[:, 1:] - U[:, :1], (0, 2, 1))  # columns: edges
    return np.linalg.inv(Bm)


def _lattice_points(U: np.ndarray, Binv: np.ndarray, offset: float):
    """Points of (Z + offset)^3 in each tet's image: (tet, point, lambda)."""
    lo = np.ceil(U.min(axis=1) - offset - EPS).astype(np.int64)
    hi = np.floor(U.max(axis=1) - offset + EPS).astype(np.int64)
    n = np.maximum(hi - lo + 1, 0)
    cnt = n.prod(axis=1)
    t = np.repeat(np.arange(len(U)), cnt)
    if not len(t):
        return t, np.zeros((0, 3)), np.zeros((0, 4))
    start = np.r_[0, np.cumsum(cnt)[:-1]]
    k = np.arange(len(t)) - np.repeat(start, cnt)
    nt = n[t]
    i0 = k % nt[:, 0]
    i1 = (k // nt[:, 0]) % nt[:, 1]
    i2 = k // (nt[:, 0] * nt[:, 1])
    P = lo[t] + np.c_[i0, i1, i2] + offset
    l123 = np.einsum("tij,tj->ti", Binv[t], P - U[t, 0])
    lam = np.c_[1.0 - l123.sum(axis=1), l123]
    inside = lam.min(axis=1) >= -EPS
    return t[inside], P[inside], lam[inside]


def _face_transitions(mesh: TetMesh, faces: np.ndarray, ab: np.ndarray, M: np.ndarray, U: np.ndarray):
    """Per tet and local face: the neighbour across it (-1 on the boundary)
    and the affine transition (rotation index, translation) into it."""
    T = mesh.tets
    nT = len(T)
    nbr = np.full((nT, 4), -1, dtype=np.int64)
    rot = np.zeros((nT, 4), dtype=np.int64)
    tau = np.zeros((nT, 4, 3))
    A, B = ab[:, 0], ab[:, 1]
    Fv = mesh.faces[faces]
    # the local face index of each interior face in A and in B
    la = np.argmax(~(T[A][:, :, None] == Fv[:, None, :]).any(axis=2), axis=1)
    lb = np.argmax(~(T[B][:, :, None] == Fv[:, None, :]).any(axis=2), axis=1)
    # translation from one shared vertex: u_B(x) = G[M] u_A(x) + tau
    x = Fv[:, 0]
    ua = U[A, np.argmax(T[A] == x[:, None], axis=1)]
    ub = U[B, np.argmax(T[B] == x[:, None], axis=1)]
    G = CUBE_GROUP
    t_ab = ub - np.einsum("kij,kj->ki", G[M], ua)
    Minv = GROUP_INVERSE[M]
    nbr[A, la], rot[A, la], tau[A, la] = B, M, t_ab
    nbr[B, lb], rot[B, lb], tau[B, lb] = A, Minv, -np.einsum("kij,kj->ki", G[Minv], t_ab)
    return nbr, rot, tau


def trace(U, Binv, nbr, rot, tau, t0, p0, d, max_steps: int = 200):
    """Follow the straight parameter segments p0 -> p0 + d (k rays) from
    tets t0 across faces and transitions.  Returns (end tet, end point in
    its chart, ok mask): ok is False where a ray left through the boundary
    or did not arrive."""
    G = CUBE_GROUP
    k = len(t0)
    t = t0.copy()
    p = p0.copy()
    d = d.copy()
    rem = np.ones(k)
    done = np.zeros(k, bool)
    ok = np.ones(k, bool)
    for _ in range(max_steps):
        act = np.nonzero(~done)[0]
        if not len(act):
            break
        ta = t[act]
        lam123 = np.einsum("kij,kj->ki", Binv[ta], p[act] - U[ta, 0])
        lam = np.c_[1.0 - lam123.sum(axis=1), lam123]
        dl123 = np.einsum("kij,kj->ki", Binv[ta], d[act])
        dl = np.c_[-dl123.sum(axis=1), dl123]
        with np.errstate(divide="ignore", invalid="ignore"):
            alpha = np.where(dl < -1e-15, np.maximum(lam, 0.0) / -dl, np.inf)
        face = np.argmin(alpha, axis=1)
        a = alpha[np.arange(len(act)), face]
        arrive = a >= rem[act] - EPS
        fin = act[arrive]
        p[fin] = p[fin] + rem[fin, None] * d[fin]
        done[fin] = True
        go = act[~arrive]
        if not len(go):
            continue
        f = face[~arrive]
        a = a[~arrive]
        tg = t[go]
        nb = nbr[tg, f]
        out = nb < 0
        ok[go[out]] = False
        done[go[out]] = True
        go, f, a, tg, nb = go[~out], f[~out], a[~out], tg[~out], nb[~out]
        x = p[go] + a[:, None] * d[go]
        R = G[rot[tg, f]]
        p[go] = np.einsum("kij,kj->ki", R, x) + tau[tg, f]
        d[go] = np.einsum("kij,kj->ki", R, d[go])
        rem[go] -= a
        t[go] = nb
    ok &= done
    return t, p, ok


def extract_hexes(mesh: TetMesh, tr: Transitions, corners: np.ndarray, cell: float) -> RawHexes:
    """Hexahedra of an integer-grid map (module docs).

    Parameters
    ----------
    mesh : TetMesh
        the split mesh the map lives on
    tr : transitions.Transitions
        its interior faces, their tets (A, B) and transitions (CUBE_GROUP
        index M, u_B = G[M] u_A + tau): ``tr.faces``, ``tr.tets`` and
        ``tr.transition`` are read (an EdgeField has them too)
    corners : (#T, 4, 3) parameter points (cells) of the tet corners
    cell : the cell size (model units), for the merge tolerance

    Returns
    -------
    RawHexes
    """
    faces, ab, M = tr.faces, tr.tets, tr.transition
    U = snap(corners)
    Binv = _barycentric_frames(U)
    X = mesh.vertices[mesh.tets]  # (#T, 4, 3)
    tv, Pv, lv = _lattice_points(U, Binv, 0.0)
    xv = np.einsum("ki,kij->kj", lv, X[tv])
    tol = 1e-6 * cell
    # one vertex per position in the solid
    tree = cKDTree(xv)
    pairs = tree.query_pairs(tol, output_type="ndarray")
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(xv)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)) if len(pairs) else \
        coo_matrix((n, n))
    nv, lab = connected_components(g, directed=False)
    first = np.full(nv, -1)
    first[lab[::-1]] = np.arange(n)[::-1]
    vertices = xv[first]
    vtree = cKDTree(vertices)

    # cell centres and their 8 corners
    tc, Pc, lc = _lattice_points(U, Binv, 0.5)
    xc = np.einsum("ki,kij->kj", lc, X[tc])
    if len(xc):
        # a centre on a face between two tets is found twice
        keep = first_rows(np.round(xc / tol).astype(np.int64))
        tc, Pc = tc[keep], Pc[keep]
    nbr, rot, tau = _face_transitions(mesh, faces, ab, M, U)
    fractional = int(np.sum(np.any(np.abs(tau - np.rint(tau)) > EPS, axis=2) & (nbr >= 0)) // 2)
    m = len(tc)
    dirs = (VTK_CORNERS - 0.5).astype(float)  # (8, 3)
    t0 = np.repeat(tc, 8)
    p0 = np.repeat(Pc, 8, axis=0)
    d = np.tile(dirs, (m, 1))
    te, pe, ok = trace(U, Binv, nbr, rot, tau, t0, p0, d)
    lam123 = np.einsum("kij,kj->ki", Binv[te], pe - U[te, 0])
    lam = np.c_[1.0 - lam123.sum(axis=1), lam123]
    xe = np.einsum("ki,kij->kj", lam, X[te])
    dist, vid = vtree.query(xe) if len(xe) else (np.zeros(0), np.zeros(0, dtype=np.int64))
    ok &= dist < 1e-4 * cell
    hexes = vid.reshape(m, 8)
    good = ok.reshape(m, 8).all(axis=1)
    lost = int(np.sum(~ok))
    hexes = hexes[good]
    # the same cell from centres found in two tets
    keep = first_rows(np.sort(hexes, axis=1))
    dup = len(hexes) - len(keep)
    hexes = hexes[np.sort(keep)]
    used = np.zeros(len(vertices), bool)
    used[hexes.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    return RawHexes(vertices[used], remap[hexes], lost, dup, fractional)
