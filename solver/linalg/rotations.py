"""Rotations, so(3) and the cube symmetry group.

Conventions used everywhere in SymFrames
----------------------------------------
* An element of so(3) is stored as a 3-vector ``v``; its matrix is ``hat(v)``
  (paper Eq. 2), so ``[hat(a), hat(b)] = hat(a x b)``.
* A frame is a rotation matrix ``E`` whose *columns* are the cross axes (§2.2).
* Two frames represent the same cross iff ``E2 = E1 @ g`` for a cube symmetry
  ``g`` in ``CUBE_GROUP`` (App. A.3, right action).
* The discrete Darboux derivative of an edge ``ij`` is ``omega_ij`` with
  ``E_j = exp(omega_ij) @ E_i`` (Eq. 7/8 with ``R_ij = I``).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial.transform import Rotation


def hat(v: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrices of vectors (Eq. 2).

    v : (..., 3) float array  ->  (..., 3, 3) float array
    """
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def exp_so3(v: np.ndarray) -> np.ndarray:
    """Rodrigues' formula, vectorised: (..., 3) rotation vectors -> (..., 3, 3)."""
    v = np.asarray(v, dtype=float)
    shape = v.shape[:-1]
    flat = v.reshape(-1, 3)
    mats = Rotation.from_rotvec(flat).as_matrix()
    return mats.reshape(shape + (3, 3))


def log_so3(R: np.ndarray) -> np.ndarray:
    """Smallest rotation vector of rotation matrices: (..., 3, 3) -> (..., 3)."""
    R = np.asarray(R, dtype=float)
    shape = R.shape[:-2]
    vec = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_rotvec()
    return vec.reshape(shape + (3,))


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Angle in radians of rotation matrices (..., 3, 3), robust near 0 and pi."""
    tr = np.trace(R, axis1=-2, axis2=-1)
    c = np.clip((tr - 1.0) / 2.0, -1.0, 1.0)
    # arccos loses precision near 0; use the skew part there
    skew = np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
        axis=-1,
    )
    s = 0.5 * np.linalg.norm(skew, axis=-1)
    return np.arctan2(s, c)


def unwrap_rotvec(v: np.ndarray, near: np.ndarray) -> np.ndarray:
    """Among the rotation vectors ``v + 2*pi*k*v_hat`` (same rotation), pick the
    one closest to ``near``.  Lets an edge carry rotations larger than pi
    (Fig. 9) while staying exact.  v, near : (n, 3).
    """
    v = np.asarray(v, dtype=float)
    near = np.asarray(near, dtype=float)
    ang = np.linalg.norm(v, axis=-1)
    axis = np.where(ang[:, None] > 1e-12, v / np.maximum(ang, 1e-300)[:, None], 0.0)
    # the near vector's component along the axis decides the number of turns
    t = np.einsum("ij,ij->i", near, axis)
    k = np.round((t - ang) / (2 * np.pi))
    cand = v + (2 * np.pi * k)[:, None] * axis
    # at angle ~pi the axis sign is ambiguous; also try the antipodal form
    alt_axis = -axis
    t2 = np.einsum("ij,ij->i", near, alt_axis)
    ang2 = 2 * np.pi - ang
    k2 = np.round((t2 - ang2) / (2 * np.pi))
    cand2 = (ang2 + 2 * np.pi * k2)[:, None] * alt_axis
    d1 = np.linalg.norm(cand - near, axis=-1)
    d2 = np.linalg.norm(cand2 - near, axis=-1)
    return np.where((d2 < d1)[:, None], cand2, cand)


def _cube_group() -> np.ndarray:
    mats = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            g = np.zeros((3, 3))
            for r, c in enumerate(perm):
                g[r, c] = signs[r]
            if np.linalg.det(g) > 0:
                mats.append(g)
    group = np.array(mats)
    # identity first, so that argmax ties resolve to "no symmetry"
    ident = np.argmax(np.einsum("kii->k", group))
    order = [ident] + [k for k in range(len(group)) if k != ident]
    return group[order]


CUBE_GROUP: np.ndarray = _cube_group()
"""(24, 3, 3) rotational symmetries of the cube, identity first."""
_GROUP_T = np.ascontiguousarray(CUBE_GROUP.transpose(0, 2, 1).reshape(24, 9).T)  # (9, 24): g^T, flattened


def closest_symmetry(M: np.ndarray) -> np.ndarray:
    """Index into CUBE_GROUP of the g minimising the angle of ``M @ g``.

    M : (n, 3, 3) rotations  ->  (n,) int
    The angle of a rotation decreases with its trace, so we maximise
    ``trace(M g) = sum_ij M_ij g_ji``.
    """
    M = np.asarray(M)
    traces = M.reshape(-1, 9) @ _GROUP_T  # a product of (n, 9) and (9, 24): no einsum loop
    return np.argmax(traces, axis=1)


def _group_tables():
    G = CUBE_GROUP
    prod = np.einsum("aij,bjk->abik", G, G).reshape(-1, 9)
    idx = np.argmax(prod @ G.reshape(24, 9).T, axis=1).reshape(24, 24)  # exact: entries are 0, +-1
    inv = np.argmax(np.einsum("aij,bji->ab", G, G), axis=1)  # trace(G[a] G[b]) = 3 iff G[b] = G[a]^T
    return idx, inv


GROUP_PRODUCT, GROUP_INVERSE = _group_tables()
"""(24, 24) index of G[a] @ G[b], and (24,) index of G[a]^T, into CUBE_GROUP."""


def symmetry_index(M: np.ndarray) -> np.ndarray:
    """Index into CUBE_GROUP of (n, 3, 3) signed permutation matrices; -1 for
    matrices that are not rotations of the cube (e.g. reflections)."""
    M = np.asarray(M, dtype=float).reshape(-1, 9)
    score = M @ CUBE_GROUP.reshape(24, 9).T
    k = np.argmax(score, axis=1)
    return np.where(np.isclose(score[np.arange(len(k)), k], 3.0), k, -1)


def polar_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation nearest each (n, 3, 3) matrix in the Frobenius norm (the
    orthogonal polar factor with its determinant forced to +1)."""
    U, _, Vt = np.linalg.svd(M)
    d = np.sign(np.linalg.det(U @ Vt))
    d[d == 0] = 1.0
    U[:, :, 2] *= d[:, None]
    return U @ Vt


def cross_distance(E1: np.ndarray, E2: np.ndarray) -> np.ndarray:
    """Angle (radians) between the crosses of frames E1, E2 : (n, 3, 3).

    The smallest rotation angle taking E1 to any representative of E2's cross.
    """
    M = np.einsum("nji,njk->nik", E1, E2)  # E1^T E2
    g = CUBE_GROUP[closest_symmetry(M)]
    return rotation_angle(M @ g)


def match_to(E: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Representative of each cross E (n,3,3) closest to the frames ref (n,3,3)."""
    M = np.einsum("nji,njk->nik", ref, E)  # ref^T E
    g = CUBE_GROUP[closest_symmetry(M)]
    return E @ g


def frame_from_axes(x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Orthonormal frames with third column along z and first column the part
    of x orthogonal to z.  x, z : (n, 3)  ->  (n, 3, 3)."""
    z = z / np.linalg.norm(z, axis=1, keepdims=True)
    x = x - np.einsum("ij,ij->i", x, z)[:, None] * z
    x = x / np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=2)


def any_perpendicular(z: np.ndarray) -> np.ndarray:
    """A unit vector perpendicular to each row of z (n, 3)."""
    z = np.asarray(z, dtype=float)
    pick = np.where(np.abs(z[:, [0]]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    x = np.cross(z, pick)
    return x / np.linalg.norm(x, axis=1, keepdims=True)


def minimal_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation vector of the smallest rotation taking unit vectors a to b (n,3)."""
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=1)
    c = np.einsum("ij,ij->i", a, b)
    ang = np.arctan2(s, c)
    safe = s > 1e-12
    out = np.zeros_like(a)
    out[safe] = axis[safe] / s[safe, None] * ang[safe, None]
    anti = (~safe) & (c < 0)
    if np.any(anti):
        out[anti] = any_perpendicular(a[anti]) * np.pi
    return out


def best_adapted_frame(directions: list[np.ndarray], weights=None, init=None, iters: int = 20):
    """The rotation whose axes are closest to a set of unit directions.

    Minimises sum_k w_k * min_axis |E e_axis -/+ d_k|^2 by alternating axis
    assignment and orthogonal Procrustes.  Used for frames at sharp corners and
    feature vertices (§3.3, §4.2.2: "the cross field best adapted to the curve
    tangent and the boundary normals").

    directions : list of (3,) unit vectors;  returns (3, 3).
    """
    D = np.asarray(directions, dtype=float)
    D = D / np.linalg.norm(D, axis=1, keepdims=True)
    w = np.ones(len(D)) if weights is None else np.asarray(weights, float)
    if init is None:
        z = D[0]
        x = D[1] if len(D) > 1 and abs(D[1] @ z) < 0.99 else any_perpendicular(z[None])[0]
        E = frame_from_axes(x[None], z[None])[0]
    else:
        E = np.asarray(init, float)
    for _ in range(iters):
        proj = D @ E  # (k, 3): coordinates of each direction in the frame
        ax = np.argmax(np.abs(proj), axis=1)
        sgn = np.sign(proj[np.arange(len(D)), ax])
        # target: E @ (sgn * e_ax) ~ d  ->  Procrustes on B = sum w d (sgn e_ax)^T
        B = np.zeros((3, 3))
        for k in range(len(D)):
            e = np.zeros(3)
            e[ax[k]] = sgn[k]
            B += w[k] * np.outer(D[k], e)
        # fill unconstrained axes so the SVD is well posed
        U, _, Vt = np.linalg.svd(B + 1e-9 * E)
        S = np.eye(3)
        S[2, 2] = np.sign(np.linalg.det(U @ Vt))
        E_new = U @ S @ Vt
        if np.allclose(E_new, E, atol=1e-13):
            break
        E = E_new
    return E

