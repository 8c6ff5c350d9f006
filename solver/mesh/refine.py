"""Uniform red refinement of a tet mesh (each tet into eight; Bey 1995).

Why: fTetWild's time grows much faster than its output (docs/how-it-works.md, *Tubes and tet mesh*;
bench/RESULTS.md: 8 s at 19k tets, 91 s at 48k, 171 s at 133k), while
splitting every tet into eight is a few numpy passes.  So a large mesh is
made by meshing at twice (or four times) the target edge length and refining.
Refinement keeps everything the rest of the pipeline relies on -- a
conforming, positively oriented mesh; the dual-path embedding (embed.py)
traces curves through any mesh -- and Bey's rule (cut the inner octahedron
along its shortest diagonal) keeps the shape quality of the coarse tets.

New vertices are edge midpoints.  Midpoints of boundary edges on smooth parts
of the boundary are moved to the closest point of the input surface, so the
refined boundary approximates the solid as well as a direct mesh would
(a chord of length 2h sags by h^2/(2R)); a move that would invert or badly
flatten a tet is undone.  Midpoints on sharp creases stay on the crease.

The nested meshes also give a prolongation for 1-forms (Whitney
interpolation), computed on demand.  It is not used by the solver: as a
coarse space for the Levenberg-Marquardt systems it cut CG steps about 4x
(refined 58k-tet ball, one system) but needed an exact coarse solve that
cost more than it saved, and as a start for the fine LM (the coarse
solution, prolonged) it saved nothing, because the singular flux lands on
the coarse faces the curves pierce, not on the fine ones (ball, 77k tets:
11 fine iterations from it, as from zero).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..surface.trisurface import TriSurface
from .tetmesh import TET_EDGES, TetMesh

# the three diagonals of the inner octahedron, given by the local edge ids of
# their end midpoints (TET_EDGES order 01 02 03 12 13 23), each with the
# cycle of the four other midpoints around it
_DIAGONALS = (
    ((0, 5), (1, 2, 4, 3)),  # m01-m23, around m02 m03 m13 m12
    ((1, 4), (0, 2, 5, 3)),  # m02-m13, around m01 m03 m23 m12
    ((2, 3), (0, 1, 5, 4)),  # m03-m12, around m01 m02 m23 m13
)


@dataclass
class Refinement:
    """A coarse mesh and its red refinement.

    fine        : the refined TetMesh (fine tet k lies in coarse tet k // 8)
    coarse      : the mesh it was made from
    edge_parent : (#E_fine,) coarse edge a fine edge halves, -1 for edges
                  inside coarse faces and tets
    whitney     : (#E_fine, #E_coarse) sparse prolongation of edge values
                  (1-form cochains) by Whitney interpolation; exact for
                  constant 1-forms
    """

    fine: TetMesh
    coarse: TetMesh

    @cached_property
    def _prolongation(self):
        return _whitney_prolongation(self.coarse, self.fine)

    @property
    def edge_parent(self) -> np.ndarray:
        return self._prolongation[0]

    @property
    def whitney(self) -> sp.csr_matrix:
        return self._prolongation[1]


def red_refine(coarse: TetMesh, surface: TriSurface | None = None, crease_deg: float = 25.0,
               min_volume_ratio: float = 0.25) -> Refinement:
    """Split every tet of ``coarse`` into eight.

    surface : the input boundary; when given, midpoints of boundary edges
              whose dihedral angle is below ``crease_deg`` are moved onto it
              (undone where a tet would keep less than ``min_volume_ratio`` of
              its volume before the move).  The coarse boundary must then
              be manifold (ValueError otherwise).
    """
    P = coarse.vertices
    T = coarse.tets
    E = coarse.edges
    nV = len(P)
    te = coarse.tet_edges
    m = nV + te  # (T, 6) midpoint vertex ids
    Pf = np.vstack([P, 0.5 * (P[E[:, 0]] + P[E[:, 1]])])
    corners = np.stack([
        np.stack([T[:, 0], m[:, 0], m[:, 1], m[:, 2]], 1),
        np.stack([m[:, 0], T[:, 1], m[:, 3], m[:, 4]], 1),
        np.stack([m[:, 1], m[:, 3], T[:, 2], m[:, 5]], 1),
        np.stack([m[:, 2], m[:, 4], m[:, 5], T[:, 3]], 1),
    ], 1)
    # inner octahedron: the shortest of its three diagonals (Bey)
    lens = np.stack([np.linalg.norm(Pf[m[:, a]] - Pf[m[:, b]], axis=1) for (a, b), _ in _DIAGONALS], 1)
    pick = np.argmin(lens, axis=1)
    inner = np.empty((len(T), 4, 4), dtype=np.int64)
    for k, ((a, b), cyc) in enumerate(_DIAGONALS):
        sel = pick == k
        mm = m[sel]
        for j in range(4):
            inner[sel, j] = np.stack([mm[:, a], mm[:, b], mm[:, cyc[j]], mm[:, cyc[(j + 1) % 4]]], 1)
    Tf = np.concatenate([corners, inner], axis=1).reshape(-1, 4)
    if surface is not None:
        Pf = _project_boundary_midpoints(coarse, Pf, Tf, surface, crease_deg, min_volume_ratio)
    return Refinement(fine=TetMesh(Pf, Tf), coarse=coarse)


def _project_boundary_midpoints(coarse, Pf, Tf, surface, crease_deg, min_ratio):
    B = coarse.boundary
    bv = coarse.boundary_vertices
    if np.any(B._edge_data[2] != 2):
        raise ValueError("red_refine: the coarse mesh's boundary is not manifold, so its midpoints cannot be "
                         "projected; mesh finer, or pass surface=None to refine without projection")
    smooth = B.dihedral_angles < np.deg2rad(crease_deg)
    be = bv[B.edges[smooth]]
    mids = len(coarse.vertices) + coarse.edge_index(be[:, 0], be[:, 1])
    if len(mids) == 0:
        return Pf
    return project_onto_surface(Pf, Tf, mids, surface, min_ratio)


def project_onto_surface(P: np.ndarray, T: np.ndarray, ids: np.ndarray, surface: TriSurface,
                         min_ratio: float) -> np.ndarray:
    """P with the vertices ids moved onto their closest points of surface,
    undoing moves that would leave a tet of T below min_ratio of its signed
    volume (T need not be oriented: volumes are compared before and after)."""
    _, _, q = surface.closest_points(P[ids])
    vol0 = TetMesh._signed_volumes(P, T)
    Pn = P.copy()
    Pn[ids] = q
    moved = np.zeros(len(P), bool)
    moved[ids] = True
    for _ in range(5):
        bad = TetMesh._signed_volumes(Pn, T) * np.sign(vol0) < min_ratio * np.abs(vol0)
        bad &= moved[T].any(axis=1)
        if not np.any(bad):
            break
        undo = np.unique(T[bad])
        undo = undo[moved[undo]]
        Pn[undo] = P[undo]
        moved[undo] = False
    return Pn


def _whitney_prolongation(coarse: TetMesh, fine: TetMesh):
    """Fine-edge values of the Whitney 1-form interpolating coarse edge values.

    Each fine edge runs between two points of one coarse tet with barycentric
    coordinates l(s) = p + s (q - p); the integral of the Whitney form
    W_ij = l_i dl_j - l_j dl_i along it is (p_i + q_i)/2 (q_j - p_j) -
    (p_j + q_j)/2 (q_i - p_i), exact for the linear path.
    """
    nVc = coarse.n_vertices
    Ec = coarse.edges
    # the barycentric coordinates of every fine vertex in one coarse tet that
    # contains it: a coarse vertex is its own corner, a midpoint is half-half;
    # fine tet k came from coarse tet k // 8
    parent_tet = np.arange(fine.n_tets) // 8
    Ef = fine.edges
    tet_of_edge = np.empty(fine.n_edges, dtype=np.int64)
    tet_of_edge[fine.tet_edges.reshape(-1)] = np.repeat(parent_tet, 6)
    Tc = coarse.tets[tet_of_edge]  # (Ef, 4) coarse vertices
    te = coarse.tet_edges[tet_of_edge]  # (Ef, 6)

    def bary(v):
        lam = np.zeros((len(v), 4))
        is_vert = v < nVc
        lam[is_vert] = (Tc[is_vert] == v[is_vert, None]).astype(float)
        mid = ~is_vert
        e = v[mid] - nVc
        loc = np.argmax(te[mid] == e[:, None], axis=1)
        pairs = TET_EDGES[loc]
        r = np.nonzero(mid)[0]
        lam[r, pairs[:, 0]] = 0.5
        lam[r, pairs[:, 1]] = 0.5
        return lam

    p, q = bary(Ef[:, 0]), bary(Ef[:, 1])
    cols, vals = [], []
    for k, (i, j) in enumerate(TET_EDGES):
        w = 0.5 * (p[:, i] + q[:, i]) * (q[:, j] - p[:, j]) - 0.5 * (p[:, j] + q[:, j]) * (q[:, i] - p[:, i])
        # the coarse edge (Tc_i, Tc_j) is oriented min -> max
        sign = np.where(Tc[:, i] < Tc[:, j], 1.0, -1.0)
        cols.append(te[:, k])
        vals.append(w * sign)
    rows = np.tile(np.arange(fine.n_edges), 6)
    W = sp.csr_matrix((np.concatenate(vals), (rows, np.concatenate(cols))), shape=(fine.n_edges, coarse.n_edges))
    W.eliminate_zeros()
    W.data[np.abs(W.data) < 1e-14] = 0.0
    W.eliminate_zeros()
    # fine edges that halve a coarse edge: one end a coarse vertex, the other
    # the midpoint of a coarse edge through it
    a, b = Ef[:, 0], Ef[:, 1]
    parent = np.full(fine.n_edges, -1, dtype=np.int64)
    half = (a < nVc) & (b >= nVc)
    e = b[half] - nVc
    on = (Ec[e] == a[half, None]).any(axis=1)
    idx = np.nonzero(half)[0][on]
    parent[idx] = e[on]
    return parent, W
