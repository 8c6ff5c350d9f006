"""Measurements of a field (§5.2, §5.4): integrability, singular structure,
adaptation.  Arrays in, arrays out; ``quick_metrics`` summarises a Result."""

from __future__ import annotations

import numpy as np

from .constraints import TUBE
from .curves import CurveGeometry
from .rotations import CUBE_GROUP, closest_symmetry, exp_so3, log_so3, rotation_angle
from .tetmesh import TetMesh


def face_monodromy(mesh: TetMesh, omega: np.ndarray, faces: np.ndarray | None = None) -> np.ndarray:
    """(k, 3, 3) monodromy exp(w_ca) exp(w_bc) exp(w_ab) around faces abc (Eq. 9)."""
    faces = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
    fe = mesh.face_edges[faces]
    R = exp_so3(omega[fe.reshape(-1)]).reshape(len(faces), 3, 3, 3)
    # omega_ca = -omega_ac, so exp(w_ca) = exp(w_ac)^T
    return np.einsum("nji,njk,nkl->nil", R[:, 2], R[:, 1], R[:, 0])


def monodromy_angles(mesh: TetMesh, omega: np.ndarray, faces: np.ndarray | None = None,
                     Omega: np.ndarray | None = None) -> np.ndarray:
    """Angle (radians) by which each face fails to close (Eq. 9); with Omega
    given, measured against the prescribed rotation exp(Omega)."""
    M = face_monodromy(mesh, omega, faces)
    if Omega is not None:
        M = np.einsum("nji,njk->nik", exp_so3(Omega), M)
    return rotation_angle(M)


def structure_residual(mesh: TetMesh, omega: np.ndarray, Omega: np.ndarray,
                       faces: np.ndarray | None = None) -> np.ndarray:
    """|d omega - omega ^ omega - Omega| per face (Eq. 17)."""
    from .structure import StructureEquation

    faces = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
    se = StructureEquation(mesh.face_edges[faces], mesh.corner_weights[faces], Omega[faces], mesh.n_edges)
    return np.linalg.norm(se.residual(omega), axis=1)


def edge_matchings(frames: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Index into CUBE_GROUP of g_ij with E_j g_ij closest to E_i, per edge."""
    M = np.einsum("nji,njk->nik", frames[edges[:, 0]], frames[edges[:, 1]])
    return closest_symmetry(M)


def matched_singular_faces(mesh: TetMesh, frames: np.ndarray, faces: np.ndarray | None = None):
    """Faces where the closest-rotation matchings fail to close.

    Returns (mask over the given faces, rotation vector of the failure in the
    frame of the face's first vertex).  With g_ij the closest symmetry on each
    edge, a face abc closes when g_ca g_bc g_ab = I.
    """
    faces = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
    F = mesh.faces[faces]
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    G = CUBE_GROUP
    gab = G[edge_matchings(frames, np.c_[a, b])]
    gbc = G[edge_matchings(frames, np.c_[b, c])]
    gca = G[edge_matchings(frames, np.c_[c, a])]
    P = gca @ gbc @ gab
    sing = np.einsum("nii->n", P) < 2.5
    rot = log_so3(np.einsum("nij,njk,nlk->nil", frames[a], P, frames[a]))
    return sing, rot


def normal_adaptation(mesh: TetMesh, frames: np.ndarray, normals: np.ndarray | None = None,
                      vertices: np.ndarray | None = None) -> np.ndarray:
    """Angle (radians) between the boundary normal and the nearest frame axis,
    per boundary vertex (or the given subset)."""
    bv = mesh.boundary_vertices
    N = mesh.boundary.vertex_normals if normals is None else normals
    if vertices is not None:
        loc = np.searchsorted(bv, vertices)
        bv, N = bv[loc], N[loc]
    c = np.abs(np.einsum("nij,ni->nj", frames[bv], N)).max(axis=1)
    return np.arccos(np.clip(c, -1.0, 1.0))


def axis_alignment(frames: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Angle (radians) between each direction and the nearest axis of its frame."""
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    c = np.abs(np.einsum("nij,ni->nj", frames, d)).max(axis=1)
    return np.arccos(np.clip(c, -1.0, 1.0))


def tangent_adaptation(result) -> tuple[np.ndarray, np.ndarray]:
    """Angle between the curve tangent (at the nearest curve point) and the
    nearest frame axis at every vertex carrying a curve constraint.

    Returns (vertex ids, angles in radians).
    """
    mesh = result.mesh
    cons = result.problem.constraints
    emb = result.embedding
    verts, angs = [], []
    for ci, tr in enumerate(emb.traces):
        e = np.nonzero((cons.kind == TUBE) & (cons.tube_curve == ci))[0]
        if len(e) == 0:
            continue
        v = np.unique(mesh.edges[e])
        geo = CurveGeometry(tr.polyline, result.problem.network.curves[ci].closed)
        s, t, _ = geo.closest(mesh.vertices[v])
        verts.append(v)
        angs.append(axis_alignment(result.frames[v], geo.tangent(s, t)))
    if not verts:
        return np.zeros(0, int), np.zeros(0)
    return np.concatenate(verts), np.concatenate(angs)


def quick_metrics(result) -> dict:
    """The headline figures of a solve, in degrees where angles."""
    mesh = result.mesh
    emb = result.embedding
    net_faces = np.zeros(mesh.n_faces, bool)
    net_faces[emb.network_faces(mesh)] = True
    regular = np.nonzero(~net_faces & ~mesh.is_boundary_face)[0]
    out = {}
    if len(regular):
        ang = np.degrees(monodromy_angles(mesh, result.omega, regular))
        out["monodromy_mean_deg"] = float(ang.mean())
        out["monodromy_max_deg"] = float(ang.max())
    sing, _ = matched_singular_faces(mesh, result.frames)
    out["singular_faces"] = int(sing.sum())
    out["spurious_singular_faces"] = int((sing & ~net_faces).sum())
    pierced = emb.pierce_count > 0
    out["missing_singular_faces"] = int((pierced & ~sing & ~emb.face_excluded).sum())
    fixed = result.problem.boundary.is_feature_vertex
    na = np.degrees(normal_adaptation(mesh, result.frames))
    out["normal_adaptation_mean_deg"] = float(na[~fixed].mean()) if np.any(~fixed) else 0.0
    out["normal_adaptation_max_deg"] = float(na[~fixed].max()) if np.any(~fixed) else 0.0
    _, ta = tangent_adaptation(result)
    if len(ta):
        out["tangent_adaptation_mean_deg"] = float(np.degrees(ta).mean())
        out["tangent_adaptation_max_deg"] = float(np.degrees(ta).max())
    return out
