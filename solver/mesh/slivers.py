"""Flat tetrahedra in the mesher's output, and their repair.

fTetWild works in exact rational arithmetic and rounds its vertices to
doubles at the end.  The rounding can leave a tet whose four vertices are
coplanar to working precision (volume ~1e-34; ball at the 270k-tet target:
1-3 flat tets in 5 of 7 coarse meshes; bench/RESULTS.md).  Red refinement
(refine.py) gives such a tet eight flat children, where the midpoints of
two opposite edges can coincide and leave an edge of zero length, and the
DEC weights there (tetmesh.py: volume / length^2, cotangents of degenerate
triangles) become ratios of round-off.

The repair moves one vertex of each flat tet off the plane of the other
three, to whichever of a few candidate positions gives the best worst tet
around the vertex, and only if that is better than before.  It never moves a
boundary vertex (those lie on the input surface), so the solid's shape is
unchanged; interior vertices are free (the curve tubes only guide the
mesher: curves are traced through the finished mesh, embed.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .tetmesh import TetMesh

# a tet of quality below this is flat: the regular tet has quality 1, and
# fTetWild's optimised meshes stay above ~1e-2 apart from rounding accidents
FLAT_QUALITY = 1e-3
# candidate moves of a vertex: along the direction that raises the flat
# tet's volume, by these fractions of its mean edge length, and towards the
# centroid of the vertex's neighbours, by these fractions of the way
_NORMAL_STEPS = (0.05, 0.1, 0.2, 0.3)
_SMOOTH_STEPS = (0.25, 0.5, 1.0)


def tet_quality(P: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Signed volume over the cube of the rms edge length, scaled to 1 for the
    regular tet: 0 for a flat tet, negative for an inverted one."""
    X = P[T]
    E = X[:, [1, 2, 3, 2, 3, 3]] - X[:, [0, 0, 0, 1, 1, 2]]
    rms = np.sqrt(np.einsum("ijk,ijk->i", E, E) / 6.0)
    return 6.0 * np.sqrt(2.0) * TetMesh._signed_volumes(P, T) / np.maximum(rms, 1e-300) ** 3


def orient_flat(P: np.ndarray, T: np.ndarray, flat: np.ndarray, face_tets: np.ndarray,
                tet_faces: np.ndarray) -> np.ndarray:
    """T with each flat tet ordered consistently with its neighbours.

    A flat tet's volume has the sign of round-off, so sorting it by that sign
    (as TetMesh does) orients it at random.  Across a shared face, the two
    tets' fourth vertices lie on opposite sides in a valid mesh: replacing
    the flat tet's vertex opposite the face by the neighbour's must give a
    negative volume.  Flat tets whose neighbours are all flat take their
    orientation from those oriented before them (rounds over the face graph).
    """
    T = T.copy()
    todo = np.zeros(len(T), bool)
    todo[flat] = True
    while np.any(todo):
        t = np.flatnonzero(todo)
        nb = face_tets[tet_faces[t]]  # (k, 4, 2)
        other = np.where(nb[..., 0] == t[:, None], nb[..., 1], nb[..., 0])  # (k, 4) neighbour across face j
        ok = (other >= 0) & ~todo[np.maximum(other, 0)]
        has = ok.any(axis=1)
        if not np.any(has):
            break  # a cluster of flat tets without oriented neighbours: left as they are
        t, ok, other = t[has], ok[has], other[has]
        j = np.argmax(ok, axis=1)  # the first face with an oriented neighbour
        u = other[np.arange(len(t)), j]
        # each tet's vertex off the shared face (found by value, so the
        # local order of the face ids does not matter), the tet's replaced
        # by the neighbour's
        mine, theirs = T[t], T[u]
        q = theirs[~(theirs[:, :, None] == mine[:, None, :]).any(axis=2)]
        swapped = np.where((mine[:, :, None] == theirs[:, None, :]).any(axis=2), mine, q[:, None])
        # (the neighbour's volume has the sign of its orientation)
        flip = np.sign(TetMesh._signed_volumes(P, swapped)) == np.sign(TetMesh._signed_volumes(P, T[u]))
        T[t[flip]] = T[t[flip]][:, [1, 0, 2, 3]]
        todo[t] = False
    return T


@dataclass(frozen=True)
class FlatRepair:
    """What ``repair_flat_tets`` did.

    Parameters
    ----------
    flat_tets : int
        Tets that were flat.
    moved_vertices : int
        Interior vertices moved off a flat tet's plane.
    flat_tets_left : int
        Tets still flat after the repair.
    """

    flat_tets: int = 0
    moved_vertices: int = 0
    flat_tets_left: int = 0


def repair_flat_tets(P: np.ndarray, T: np.ndarray, boundary: np.ndarray, face_tets: np.ndarray,
                     tet_faces: np.ndarray, rounds: int = 5) -> tuple[np.ndarray, np.ndarray, FlatRepair]:
    """Move interior vertices of flat tets (quality < FLAT_QUALITY) so that
    every tet has positive quality.

    P, T         : vertices and tets (non-flat tets positively oriented)
    boundary     : (#V,) bool, vertices that must not move
    face_tets, tet_faces : the mesh's face adjacency (TetMesh)

    Returns new vertices, the tets consistently oriented (flat ones by
    orient_flat) and a FlatRepair: how many tets were flat, how many
    vertices moved and how many flat tets remain."""
    q = tet_quality(P, T)
    flat0 = np.flatnonzero(np.abs(q) < FLAT_QUALITY)
    if len(flat0) == 0:
        return P, T, FlatRepair()
    T = orient_flat(P, T, flat0, face_tets, tet_faces)
    P = P.copy()
    nV = len(P)
    # tets around each vertex, and each vertex's neighbours
    inc = sp.csr_matrix((np.ones(T.size), (T.reshape(-1), np.repeat(np.arange(len(T)), 4))), shape=(nV, len(T)))
    adj = (inc @ inc.T).tocsr()
    moved = np.zeros(nV, bool)
    for _ in range(rounds):
        q = tet_quality(P, T)
        flat = np.flatnonzero(q < FLAT_QUALITY)
        if len(flat) == 0:
            break
        improved = False
        for t in flat:  # a handful of tets per mesh: the loop is not over the mesh
            if tet_quality(P, T[t:t + 1])[0] >= FLAT_QUALITY:
                continue  # fixed by an earlier move this round
            # the tet's mean edge length (the 4 x 4 distances hold 12 edges and 4 zeros)
            L = np.mean(np.linalg.norm(P[T[t]][:, None] - P[T[t]][None], axis=2)) * 16.0 / 12.0
            best = None
            for v in T[t]:
                if boundary[v]:
                    continue
                star = inc.indices[inc.indptr[v]:inc.indptr[v + 1]]
                nbrs = adj.indices[adj.indptr[v]:adj.indptr[v + 1]]
                nbrs = nbrs[nbrs != v]
                now = tet_quality(P, T[star]).min()
                cands = [P[v] + s * (P[nbrs].mean(axis=0) - P[v]) for s in _SMOOTH_STEPS]
                g = _volume_gradient(P, T[t], v, L)
                if np.linalg.norm(g) > 0:
                    n = g / np.linalg.norm(g)
                    cands += [P[v] + s * L * n for s in _NORMAL_STEPS]
                keep = P[v].copy()
                for c in cands:
                    P[v] = c
                    worst = tet_quality(P, T[star]).min()
                    if worst > now and (best is None or worst > best[0]):
                        best = (worst, v, c.copy())
                P[v] = keep
            if best is not None:
                P[best[1]] = best[2]
                moved[best[1]] = True
                improved = True
        if not improved:
            break
    left = int(np.sum(tet_quality(P, T) < FLAT_QUALITY))
    return P, T, FlatRepair(int(len(flat0)), int(moved.sum()), left)


def _volume_gradient(P: np.ndarray, tet: np.ndarray, v: int, L: float) -> np.ndarray:
    """d volume / d P[v] of the (ordered) tet: the volume is linear in each
    vertex, so differences over a step L are exact up to rounding."""
    k = int(np.flatnonzero(tet == v)[0])
    X = np.repeat(P[tet][None], 4, axis=0)  # the tet, then with P[v] moved by L along x, y, z
    X[np.arange(1, 4), k, np.arange(3)] += L
    vol = TetMesh._signed_volumes(X.reshape(-1, 3), np.arange(16).reshape(4, 4))
    return (vol[1:] - vol[0]) / L
