"""Per-tet frames and the cube symmetries across faces (paper §5.5): the
field's output for hex meshing, which the exporters (io/interchange.py)
write and a hex-meshing stage reads.

CubeCover and AlgoHex want one frame per tet; the solver has one per vertex.
The paper took "the Karcher mean of frames at vertices" and matched tets by
the closest rotation, noting that "in principle we should be able to make
this step even more robust near singularities by using angle information
from omega" (§5.5).  Here both steps use omega:

* in tet t with reference vertex r (its first vertex) every other vertex k is
  matched to r along the tet edge rk by the cube symmetry h_k that omega's
  transport says: ``E_k G[h_k]`` is the representative of k's cross closest
  to ``exp(omega_rk) E_r`` (Eq. 8 with R_ij = I); h_r = identity;
* the tet frame is the chordal mean of the four matched frames projected back
  to SO(3): ``F_t = polar(sum_k E_k G[h_k])``, the rotation nearest (in the
  Frobenius norm) to their sum, i.e. the minimiser of
  ``sum_k ||F - E_k G[h_k]||_F^2`` over SO(3) (via an SVD);
* across an interior face shared by tets A and B, each face vertex p appears
  in both means, as ``E_p G[h_A(p)]`` and ``E_p G[h_B(p)]``, so
  ``F_A ~ F_B g`` with ``g = G[h_B(p)]^T G[h_A(p)]``: an exact cube symmetry
  taken from omega, not from comparing F_A with F_B.  The three face vertices
  vote (they agree unless a singular curve runs through the tets).

G is ``rotations.CUBE_GROUP`` (identity first), frames have the cross axes as
columns (rotations.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..linalg.rotations import (
    CUBE_GROUP,
    GROUP_INVERSE,
    GROUP_PRODUCT,
    closest_symmetry,
    exp_so3,
    polar_rotation,
    rotation_angle,
)
from ..mesh.tetmesh import TetMesh


def omega_matchings(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """The cube symmetry g_ij with E_j g_ij closest to exp(omega_ij) E_i: the
    frame at i carried to j by omega (Eq. 8), per ordered vertex pair.

    Parameters
    ----------
    mesh : TetMesh
    omega : (#E, 3) float array
        E_j = exp(omega_ij) E_i on the edges i < j.
    frames : (#V, 3, 3) float array
        Columns are the cross axes.
    pairs : (k, 2) int array
        Ordered vertex pairs (i, j), each an edge of the mesh.

    Returns
    -------
    (k,) int array
        Indices into CUBE_GROUP.
    """
    pairs = np.asarray(pairs)
    e = mesh.edge_index(pairs[:, 0], pairs[:, 1])
    sign = np.where(pairs[:, 0] < pairs[:, 1], 1.0, -1.0)
    carried = exp_so3(sign[:, None] * omega[e]) @ frames[pairs[:, 0]]
    return closest_symmetry(np.einsum("nji,njk->nik", carried, frames[pairs[:, 1]]))


@dataclass
class TetFrames:
    """One frame per tet from the vertex frames (``tet_frames``; module docs,
    §5.5).

    Parameters
    ----------
    frames : (#T, 3, 3) float array
        Rotations, columns are the cross axes.
    matching : (#T, 4) int array
        CUBE_GROUP index h_k per local vertex k: E_{tets[t, k]} @ G[h_k] is
        the representative averaged (identity, 0, at the reference vertex
        k = 0; per source where the tets take their frames from sources).
    spread : (#T,) float array
        Largest angle (radians) between F_t and a matched vertex frame.
    """

    frames: np.ndarray
    matching: np.ndarray
    spread: np.ndarray


def pair_matchings(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``omega_matchings`` of ordered vertex pairs, computed once per edge
    (on (i, j) with i < j) and inverted for (j, i), so that g_ji = g_ij^-1
    exactly; the identity where i == j.

    Parameters
    ----------
    mesh, omega, frames
        As ``omega_matchings``.
    pairs : (k, 2) int array
        Ordered vertex pairs (i, j), each an edge of the mesh or i == j.

    Returns
    -------
    (k,) int array
        Indices into CUBE_GROUP.

    Raises
    ------
    ValueError
        A pair of two vertices that no edge joins.
    """
    pairs = np.asarray(pairs)
    out = np.zeros(len(pairs), dtype=np.int64)
    diff = pairs[:, 0] != pairs[:, 1]
    if not diff.any():
        return out
    lo = np.minimum(pairs[diff, 0], pairs[diff, 1])
    hi = np.maximum(pairs[diff, 0], pairs[diff, 1])
    e = mesh.edge_index(lo, hi)
    if np.any(e < 0):
        raise ValueError("internal: two vertices of a pair to match are not joined by an edge")
    ue, inv = np.unique(e, return_inverse=True)
    g = omega_matchings(mesh, omega, frames, mesh.edges[ue])[inv]
    fwd = pairs[diff, 0] < pairs[diff, 1]
    out[diff] = np.where(fwd, g, GROUP_INVERSE[g])
    return out


def tet_frames(mesh: TetMesh, frames: np.ndarray, omega: np.ndarray | None = None, *,
               sources: np.ndarray | None = None, mean=None) -> TetFrames:
    """One frame per tet from the frames at its vertices (module docs, §5.5).

    Each tet averages the frames of its sources (its four vertices by
    default); the first is its reference r, and every other source s is
    matched to it, ``E_s G[h_s]``: by omega's transport along the edge rs
    (``pair_matchings``, Eq. 8, the §5.5 remark) when omega is given, else
    by the closest rotation (as the paper did).  The matched frames are then
    averaged: by default their chordal mean projected to SO(3),
    ``polar(sum_s E_s G[h_s])``.

    The field's exports (``omega_tet_frames``), the hex mesher's split mesh
    (hexmesh/transitions.py: omega, its tets' old vertices as sources) and
    the §5.4 smoothness measure (analysis.tet_frames: closest rotation, the
    Karcher mean) all take their tet frames here.

    Parameters
    ----------
    mesh : TetMesh
        The mesh the frames (and omega) live on.
    frames : (#V, 3, 3) float array
        Columns are the cross axes.
    omega : (#E, 3) float array, optional
        As ``omega_matchings``; None matches by the closest rotation.
    sources : (#T, 4) int array, optional
        Per tet, the vertices of ``mesh`` whose frames it averages, -1
        padded (a padded entry counts the reference once more; every row
        needs one vertex).  Default ``mesh.tets``; a mesh split from
        ``mesh`` passes the old vertices of its tets.
    mean : callable(matched, weights) -> (#T, 3, 3) float array, optional
        The average of the matched frames (#T, 4, 3, 3) with weights
        (#T, 4); default the chordal mean projected to SO(3).

    Returns
    -------
    TetFrames
        ``matching`` is h per source (the identity at the reference and at
        padded entries), ``spread`` the largest angle between the tet frame
        and a matched frame.
    """
    src = mesh.tets if sources is None else np.asarray(sources)
    n = len(src)
    has = src >= 0
    ref = src[np.arange(n), np.argmax(has, axis=1)]
    S = np.where(has, src, ref[:, None])
    R = np.repeat(ref, 4)
    if omega is not None:
        h = pair_matchings(mesh, omega, frames, np.c_[R, S.reshape(-1)]).reshape(n, 4)
    else:
        h = closest_symmetry(np.einsum("nji,njk->nik", frames[R], frames[S.reshape(-1)])).reshape(n, 4)
    matched = frames[S] @ CUBE_GROUP[h]  # (#T, 4, 3, 3)
    F = polar_rotation(matched.sum(axis=1)) if mean is None else mean(matched, np.full((n, 4), 0.25))
    rel = np.swapaxes(F, 1, 2)[:, None] @ matched
    spread = rotation_angle(rel).max(axis=1)
    return TetFrames(F, h, spread)


def omega_tet_frames(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray) -> TetFrames:
    """Per-tet frames: the chordal mean, projected to SO(3), of the four vertex
    frames matched to the tet's first vertex by omega's transport (§5.5 remark,
    Eq. 8): ``tet_frames(mesh, frames, omega)``.  (``analysis.tet_frames`` is
    the Karcher mean with closest-rotation matching, as the paper did; the two
    agree wherever no tet edge turns by 45 degrees or more.)

    Parameters
    ----------
    mesh, omega, frames
        As ``omega_matchings``.

    Returns
    -------
    TetFrames
    """
    return tet_frames(mesh, frames, omega)


@dataclass
class FaceMatchings:
    """Cube symmetries across the interior faces (module docs, §5.5).

    Parameters
    ----------
    faces : (k,) int array
        Interior face ids.
    tets : (k, 2) int array
        The tets (A, B) on either side (mesh.face_tets).
    symmetry : (k,) int array
        CUBE_GROUP index g with F_A ~ F_B @ G[g], from omega.
    agree : (k,) bool array
        The three face vertices gave the same g.
    closest : (k,) int array
        CUBE_GROUP index of the closest-rotation matching of the two tet
        frames (what §5.5 used), for comparison.
    """

    faces: np.ndarray
    tets: np.ndarray
    symmetry: np.ndarray
    agree: np.ndarray
    closest: np.ndarray


def _local_index(tets: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """Position of each of verts (k, m) in its tet (k, 4)."""
    return np.argmax(tets[:, None, :] == verts[:, :, None], axis=2)


def face_matchings(mesh: TetMesh, tf: TetFrames) -> FaceMatchings:
    """Omega-derived matchings across every interior face.

    For face f between tets A and B and each face vertex p,
    g_p = G[h_B(p)]^T G[h_A(p)] (module docs); the majority of the three is
    kept, and where all three differ the one whose F_B G[g] is nearest F_A.

    Parameters
    ----------
    mesh : TetMesh
    tf : TetFrames
        The tet frames of ``omega_tet_frames`` on this mesh.

    Returns
    -------
    FaceMatchings
    """
    faces = np.nonzero(~mesh.is_boundary_face)[0]
    ft = mesh.face_tets[faces]
    A, B = ft[:, 0], ft[:, 1]
    Fv = mesh.faces[faces]
    hA = np.take_along_axis(tf.matching[A], _local_index(mesh.tets[A], Fv), axis=1)
    hB = np.take_along_axis(tf.matching[B], _local_index(mesh.tets[B], Fv), axis=1)
    cand = GROUP_PRODUCT[GROUP_INVERSE[hB], hA]  # (k, 3)
    FA, FB = tf.frames[A], tf.frames[B]
    M = np.swapaxes(FB, 1, 2) @ FA  # F_B^T F_A, ~ G[g]
    # trace(G[c]^T M) = <G[c], M>: larger is nearer
    score = M.reshape(-1, 9) @ CUBE_GROUP.reshape(24, 9).T  # (k, 24)
    fit = np.take_along_axis(score, cand, axis=1)
    c0, c1, c2 = cand.T
    best = cand[np.arange(len(cand)), np.argmax(fit, axis=1)]
    g = np.where((c0 == c1) | (c0 == c2), c0, np.where(c1 == c2, c1, best))
    agree = (c0 == c1) & (c1 == c2)
    closest = np.argmax(score, axis=1)
    return FaceMatchings(faces, ft, g, agree, closest)
