"""Measurements of a field (§5.2, §5.4): integrability, singular structure,
adaptation, root and initialisation independence, smoothness.

Arrays in, arrays out: every function takes a TetMesh and plain arrays (or a
solved Result where it needs the network), so each can be checked on fields
with a known answer (``tests/test_analysis.py``) before it judges the solver.
``quick_metrics`` summarises a Result; ``bench/validation_report.py`` runs them all.

Conventions
-----------
* frames : (#V, 3, 3) rotations, columns are the cross axes (§2.2).
* omega  : (#E, 3) rotation vectors on the edges low -> high vertex id,
  E_j = exp(omega_ij) E_i (Eq. 8 with R_ij = I).
* A face abc (a < b < c, mesh.faces) is traversed a -> b -> c -> a; its
  monodromy M maps E_a to M E_a after one loop (Eq. 9), and its normal
  follows the right-hand rule.  A curve of index sigma with tangent T
  piercing the face gives M = exp(2 pi sigma T) when T . n > 0 (the sign
  convention of network.py).
* Angles are radians unless a name ends in ``_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

from .. import checks
from ..errors import OptionsError
from ..field.develop import develop
from ..field.matchings import omega_matchings
from ..field.matchings import tet_frames as matching_tet_frames
from ..field.solved import as_field
from ..linalg.rotations import CUBE_GROUP, closest_symmetry, cross_distance, exp_so3, log_so3, match_to, rotation_angle
from ..mesh.tetmesh import TetMesh
from ..network.curves import CurveGeometry

# ============================================================ integrability


def face_monodromy(mesh: TetMesh, omega: np.ndarray, faces: np.ndarray | None = None) -> np.ndarray:
    """(k, 3, 3) monodromy exp(w_ca) exp(w_bc) exp(w_ab) around faces abc (Eq. 9)."""
    faces = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
    fe = mesh.face_edges[faces]
    R = exp_so3(omega[fe.reshape(-1)]).reshape(len(faces), 3, 3, 3)
    # omega_ca = -omega_ac, so exp(w_ca) = exp(w_ac)^T
    return np.einsum("nji,njk,nkl->nil", R[:, 2], R[:, 1], R[:, 0])


def monodromy_angles(mesh: TetMesh, omega: np.ndarray, faces: np.ndarray | None = None,
                     Omega: np.ndarray | None = None) -> np.ndarray:
    """Angle by which omega fails to close around each face (Eq. 9).

    Parameters
    ----------
    mesh : TetMesh
    omega : (#E, 3) float array
        Rotation vectors on ``mesh.edges``, E_j = exp(omega_ij) E_i.
    faces : (k,) int array, optional
        Face ids; default every face of the mesh.
    Omega : (#F, 3) or (k, 3) float array, optional
        The prescribed rotation of each face (Eq. 19); the angle is then
        measured against exp(Omega) instead of the identity.

    Returns
    -------
    (k,) float array
        Angles in radians, 0 where omega is integrable around the face.
    """
    checks.instance("mesh", mesh, TetMesh, OptionsError)
    omega = checks.array("omega", omega, OptionsError, shape=(mesh.n_edges, 3))
    if faces is not None:
        faces = checks.array("faces", faces, OptionsError, shape=(None,), kind="i")
        if len(faces) and (faces.min() < 0 or faces.max() >= mesh.n_faces):
            raise OptionsError(f"faces: ids run from 0 to {mesh.n_faces - 1}, found {faces.min()}..{faces.max()}")
    if Omega is not None:
        Omega = checks.array("Omega", Omega, OptionsError, shape=(None, 3))
        if len(Omega) not in (mesh.n_faces, mesh.n_faces if faces is None else len(faces)):
            raise OptionsError(f"Omega has {len(Omega)} rows: one per face ({mesh.n_faces}) or per face given")
    M = face_monodromy(mesh, omega, faces)
    if Omega is not None:
        faces_ = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
        Om = Omega if len(Omega) == len(M) else Omega[faces_]
        M = np.einsum("nji,njk->nik", exp_so3(Om), M)
    return rotation_angle(M)


def structure_residual(mesh: TetMesh, omega: np.ndarray, Omega: np.ndarray | None = None,
                       faces: np.ndarray | None = None) -> np.ndarray:
    """|d omega - omega ^ omega - Omega| per face (Eq. 17), in the BCH-consistent
    form of structure.py.  Omega : (#F, 3) or None for zero."""
    from ..field.structure import StructureEquation

    faces = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
    Om = np.zeros((len(faces), 3)) if Omega is None else np.asarray(Omega)[faces]
    se = StructureEquation(mesh.face_edges[faces], mesh.corner_weights[faces], Om, mesh.n_edges)
    return np.linalg.norm(se.residual(omega), axis=1)


def darboux_derivative(mesh: TetMesh, frames: np.ndarray) -> np.ndarray:
    """omega_ij = log(E_j E_i^T) per edge (Eq. 7, R_ij = I), with E_j the
    representative of its cross closest to E_i."""
    a, b = mesh.edges[:, 0], mesh.edges[:, 1]
    Ej = match_to(frames[b], frames[a])
    return log_so3(np.einsum("nij,nkj->nik", Ej, frames[a]))


# ======================================================= singular structure


def edge_matchings(frames: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Index into CUBE_GROUP of g_ij with E_j g_ij closest to E_i, per edge."""
    M = np.einsum("nji,njk->nik", frames[edges[:, 0]], frames[edges[:, 1]])
    return closest_symmetry(M)


def matched_singular_faces(mesh: TetMesh, frames: np.ndarray, faces: np.ndarray | None = None):
    """Faces where the closest-rotation matchings fail to close.

    Returns (mask over the given faces, rotation vector of the failure in
    world coordinates).  With g_ij the closest symmetry on each edge, a face
    abc closes when g_ca g_bc g_ab = I; otherwise developing the matched
    frames around a -> b -> c -> a maps E_a to exp(rot) E_a, a quarter, half
    or third turn about an axis of the cross at a.
    """
    faces = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
    a, P = _loop_matching(mesh, faces, lambda pairs: edge_matchings(frames, pairs))
    sing = np.einsum("nii->n", P) < 2.5
    rot = log_so3(np.einsum("nij,njk,nlk->nil", frames[a], P, frames[a]))
    return sing, rot


def omega_frame_mismatch(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Per edge ij (i < j), the angle (radians) between the cross at j and
    the cross at i carried across the edge by omega (Eq. 8).  Zero on the
    edges of the development tree; elsewhere the monodromy omega leaves
    around the cycle the edge closes.  It bounds how far closest-rotation
    matching can be from the omega-aware one: the two differ on an edge only
    if |omega_ij| + mismatch_ij >= 45 degrees (distinct cube symmetries are at
    least 90 degrees apart)."""
    E = mesh.edges
    return cross_distance(exp_so3(omega) @ frames[E[:, 0]], frames[E[:, 1]])


def omega_singular_faces(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray,
                         faces: np.ndarray | None = None) -> np.ndarray:
    """Faces where the omega-aware matchings fail to close (mask over faces).

    Closest-rotation matching (matched_singular_faces) reads an edge whose
    frames turn by more than 45 degrees as a quarter-turn jump, so a smooth
    but fast-turning field (the twisted field of a solid torus on a coarse
    mesh) shows faces that are not singular.  Here each edge is matched
    against the frame omega carries across it instead; with omega the field's
    Darboux derivative this finds the faces whose monodromy is a nontrivial
    cube symmetry, whatever the turn per edge."""
    faces = np.arange(mesh.n_faces) if faces is None else np.asarray(faces)
    _, P = _loop_matching(mesh, faces, lambda pairs: omega_matchings(mesh, omega, frames, pairs))
    return np.einsum("nii->n", P) < 2.5


def _loop_matching(mesh: TetMesh, faces: np.ndarray, match):
    """(first vertex a of each face abc, g_ca g_bc g_ab) for edge matchings
    match(ordered pairs) -> CUBE_GROUP indices; the identity where the
    matchings close around the face."""
    F = mesh.faces[faces]
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    G = CUBE_GROUP
    return a, G[match(np.c_[c, a])] @ G[match(np.c_[b, c])] @ G[match(np.c_[a, b])]


@dataclass
class SingularFaces:
    """The singular faces of a field (§5.2) and how they sit on the network.

    Attributes
    ----------
    singular : (#F,) bool array
        Faces where the matchings omega carries across each edge fail to
        close (``omega_singular_faces``): the field's own singular faces,
        the ones the exports write.
    closest : (#F,) bool array
        The same read with closest-rotation matchings
        (``matched_singular_faces``), as a tool that sees only the frames
        would; it misreads faces around an edge that turns by ~45 degrees.
    network : (#F,) bool array
        Faces the network passes through (pierced faces, node regions,
        faces where curves end).
    """

    singular: np.ndarray
    closest: np.ndarray
    network: np.ndarray

    @property
    def spurious(self) -> np.ndarray:
        """(#F,) bool array: singular faces off the network, which a good field does not have."""
        return self.singular & ~self.network

    @property
    def closest_spurious(self) -> np.ndarray:
        """(#F,) bool array: the same for the closest-rotation reading."""
        return self.closest & ~self.network

    @property
    def disagreements(self) -> int:
        """Faces the two readings disagree on."""
        return int((self.singular != self.closest).sum())


def singular_faces(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray, network_faces: np.ndarray) -> SingularFaces:
    """The singular faces of a field, read both ways, against the network.

    Parameters
    ----------
    mesh : TetMesh
    omega : (#E, 3) float array
        The field's Darboux derivative on ``mesh.edges`` (Eq. 8).
    frames : (#V, 3, 3) float array
        Vertex frames, columns the cross axes.
    network_faces : (k,) int array
        Ids of the faces the network passes through
        (``Result.embedding.network_faces(mesh)``, or the stored ones).

    Returns
    -------
    SingularFaces
    """
    checks.instance("mesh", mesh, TetMesh, OptionsError)
    omega = checks.array("omega", omega, OptionsError, shape=(mesh.n_edges, 3))
    frames = checks.array("frames", frames, OptionsError, shape=(mesh.n_vertices, 3, 3))
    network_faces = _face_ids(mesh, network_faces)
    network = np.zeros(mesh.n_faces, bool)
    network[np.asarray(network_faces, dtype=np.int64)] = True
    return SingularFaces(singular=omega_singular_faces(mesh, omega, frames),
                         closest=matched_singular_faces(mesh, frames)[0], network=network)


@dataclass
class SingularCurve:
    """A connected set of singular faces (faces joined through shared tets).

    faces          : face ids
    tets           : tets holding at least one of them
    boundary_faces : how many of the faces lie on the domain boundary (ends)
    branch_tets    : tets holding three or more of the faces (nodes)
    dangling_tets  : interior tets holding exactly one (a curve stopping
                     inside the solid: impossible for a consistent field
                     unless a face's matching is ambiguous)
    closed         : a loop: every tet holds exactly two, no boundary face
    """

    faces: np.ndarray
    tets: np.ndarray
    boundary_faces: int
    branch_tets: int
    dangling_tets: int

    @property
    def closed(self) -> bool:
        return self.boundary_faces == 0 and self.branch_tets == 0 and self.dangling_tets == 0


def group_singular_faces(mesh: TetMesh, faces: np.ndarray) -> list[SingularCurve]:
    """Group faces into curves: two faces belong together when they share a
    tet.  A singular curve crossing the mesh enters and leaves each tet it
    visits through two of its faces, so each curve (or network component)
    becomes one group.  Largest group first."""
    faces = np.unique(np.asarray(faces, dtype=np.int64))
    if len(faces) == 0:
        return []
    ft = mesh.face_tets[faces]  # (k, 2), -1 on the boundary
    rows = np.repeat(np.arange(len(faces)), 2)
    cols = ft.reshape(-1)
    ok = cols >= 0
    A = sp.csr_matrix((np.ones(ok.sum()), (rows[ok], cols[ok])), shape=(len(faces), mesh.n_tets))
    n, lab = connected_components(A @ A.T, directed=False)
    out = []
    for k in range(n):
        m = lab == k
        sub = ft[m]
        t = sub[sub >= 0]
        ut, cnt = np.unique(t, return_counts=True)
        nb = int((sub[:, 1] < 0).sum())
        out.append(SingularCurve(faces=faces[m], tets=ut, boundary_faces=nb, branch_tets=int((cnt >= 3).sum()),
                                 dangling_tets=int((cnt == 1).sum())))
    out.sort(key=lambda c: -len(c.faces))
    return out


@dataclass
class SingularStructure:
    """The singular faces of a field compared with the prescribed network.

    faces          : singular face ids (matched frames fail to close)
    axis           : (k, 3) unit rotation axis of each singular face's failure
    angle          : (k,) its angle (pi/2 for a quarter turn)
    index          : (k,) signed turns about the face normal, rot . n / 2 pi
                     (+-1/4 around a curve of index +-1/4, see module docs)
    curves         : the faces grouped into curves
    expected       : faces the network pierces (None if not compared)
    missing        : expected faces that are not singular
    spurious       : singular faces outside the allowed set (the network's
                     faces, node regions and curve ends)
    wrong_index    : expected faces found singular with another index than
                     prescribed (needs ``prescribed_index``)
    axis_error     : (len(expected & singular),) angle between the failure's
                     axis and the curve tangent, where tangents are given
    """

    faces: np.ndarray
    axis: np.ndarray
    angle: np.ndarray
    index: np.ndarray
    curves: list[SingularCurve]
    expected: np.ndarray | None = None
    missing: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    spurious: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    wrong_index: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    axis_error: np.ndarray = field(default_factory=lambda: np.zeros(0))


def singular_structure(mesh: TetMesh, frames: np.ndarray, expected: np.ndarray | None = None,
                       allowed: np.ndarray | None = None, prescribed_index: np.ndarray | None = None,
                       tangents: np.ndarray | None = None) -> SingularStructure:
    """Singular faces of ``frames`` (closest rotation over the 24 cube
    symmetries), with axis and angle, grouped into curves, and compared with
    the prescribed network.

    expected         : face ids the network pierces (must be singular)
    allowed          : face ids where singular faces are not spurious
                       (defaults to ``expected``)
    prescribed_index : (#F,) index in turns about the face normal on the
                       expected faces (Omega . n / 2 pi)
    tangents         : (#F, 3) curve tangent on the expected faces
    """
    sing, rot = matched_singular_faces(mesh, frames)
    fid = np.nonzero(sing)[0]
    r = rot[fid]
    ang = np.linalg.norm(r, axis=1)
    axis = r / np.maximum(ang, 1e-300)[:, None]
    index = np.einsum("ij,ij->i", r, mesh.face_normals[fid]) / (2 * np.pi)
    out = SingularStructure(faces=fid, axis=axis, angle=ang, index=index, curves=group_singular_faces(mesh, fid))
    if expected is None:
        return out
    expected = np.unique(np.asarray(expected, dtype=np.int64))
    allowed = expected if allowed is None else np.union1d(expected, allowed)
    out.expected = expected
    out.missing = expected[~sing[expected]]
    out.spurious = np.setdiff1d(fid, allowed)
    found = expected[sing[expected]]
    loc = np.searchsorted(fid, found)
    if prescribed_index is not None:
        want = np.round(4 * np.asarray(prescribed_index)[found]) / 4
        got = np.round(4 * index[loc]) / 4
        out.wrong_index = found[np.abs(want - got) > 1e-6]
    if tangents is not None:
        T = np.asarray(tangents)[found]
        T = T / np.maximum(np.linalg.norm(T, axis=1, keepdims=True), 1e-300)
        c = np.abs(np.einsum("ij,ij->i", axis[loc], T))
        out.axis_error = np.arccos(np.clip(c, -1.0, 1.0))
    return out


def network_singular_structure(field) -> SingularStructure:
    """singular_structure of a solved field (SolvedField or Result) against
    its network: expected
    are the faces where the field must be singular
    (Embedding.prescribed_singular); allowed also the node regions and the
    boundary faces where curves end."""
    result = as_field(field, "network_singular_structure")
    mesh, emb = result.mesh, result.embedding
    n = mesh.face_normals
    idx = np.einsum("ij,ij->i", emb.face_omega, n) / (2 * np.pi)
    expected = np.nonzero(emb.prescribed_singular())[0]
    Om = emb.face_omega
    tang = Om / np.maximum(np.linalg.norm(Om, axis=1, keepdims=True), 1e-300)
    return singular_structure(mesh, result.frames, expected, emb.network_faces(mesh), idx, tang)


# ================================================== root / init independence


def pick_roots(mesh: TetMesh, n_boundary: int = 3, n_interior: int = 3, exclude: np.ndarray | None = None,
               start: int | None = None) -> np.ndarray:
    """Spread-out development roots: farthest-point samples among boundary
    vertices and among interior vertices not in ``exclude`` (a vertex mask,
    e.g. vertices near the network).  ``start`` (if given) comes first."""
    X = mesh.vertices
    bnd = mesh.is_boundary_vertex
    ok_int = ~bnd if exclude is None else ~bnd & ~np.asarray(exclude, bool)
    chosen = [] if start is None else [int(start)]

    def fps(cand, k):
        cand = np.nonzero(cand)[0]
        if len(cand) == 0 or k <= 0:
            return
        if chosen:
            d = np.min(np.linalg.norm(X[cand, None] - X[chosen][None], axis=2), axis=1)
        else:
            d = np.linalg.norm(X[cand] - X.mean(axis=0), axis=1)
        for _ in range(k):
            i = int(np.argmax(d))
            if d[i] <= 0:
                break
            chosen.append(int(cand[i]))
            d = np.minimum(d, np.linalg.norm(X[cand] - X[cand[i]], axis=1))

    fps(bnd, n_boundary)
    fps(ok_int, n_interior)
    return np.array(chosen, dtype=np.int64)


@dataclass
class RootIndependence:
    """Largest change of any cross when omega is developed from other roots.

    roots      : the roots tried
    max_change : (len(roots),) max over vertices of the cross distance to
                 the reference frames (radians)
    worst_vertex : (len(roots),) where it occurs
    change     : (#V,) max over roots, per vertex
    """

    roots: np.ndarray
    max_change: np.ndarray
    worst_vertex: np.ndarray
    change: np.ndarray

    @property
    def max_deg(self) -> float:
        return float(np.degrees(self.max_change.max())) if len(self.max_change) else 0.0


def root_independence(mesh: TetMesh, omega: np.ndarray, frames: np.ndarray, roots,
                      avoid_edges: np.ndarray | None = None) -> RootIndependence:
    """Develop omega from each root (§4.3, Fig. 16), starting from the
    reference frame at that root, and measure how far every cross moves from
    the reference ``frames`` (normally the development from the default
    root).  Exactly integrable omega gives zero for every root."""
    roots = np.asarray(roots, dtype=np.int64)
    change = np.zeros(mesh.n_vertices)
    mx, worst = [], []
    for r in roots:
        E = develop(mesh, omega, int(r), frames[r], avoid_edges)
        d = cross_distance(frames, E)
        mx.append(float(d.max()))
        worst.append(int(np.argmax(d)))
        change = np.maximum(change, d)
    return RootIndependence(roots, np.array(mx), np.array(worst, dtype=np.int64), change)


def init_independence(omegas: dict, frames: dict | None = None, reference: str | None = None) -> dict:
    """Distance between solutions from different initialisations (Fig. 17).

    omegas : {init name: (#E, 3) omega}; frames : {init name: (#V, 3, 3)}
    Returns {name: {"omega_max_deg": max_e |omega_e - omega_ref_e|,
    "omega_rel": ||omega - omega_ref|| / ||omega_ref||, "cross_max_deg": max
    cross distance between the developed frames}} for every name but the
    reference (default: the first).
    """
    names = list(omegas)
    ref = reference or names[0]
    o0 = omegas[ref]
    out = {}
    for k in names:
        if k == ref:
            continue
        d = np.linalg.norm(omegas[k] - o0, axis=1)
        row = {"omega_max_deg": float(np.degrees(d.max())),
               "omega_rel": float(np.linalg.norm(omegas[k] - o0) / max(np.linalg.norm(o0), 1e-300))}
        if frames is not None:
            row["cross_max_deg"] = float(np.degrees(cross_distance(frames[ref], frames[k]).max()))
        out[k] = row
    return out


# ================================================================ adaptation


def normal_adaptation(mesh: TetMesh, frames: np.ndarray, normals: np.ndarray | None = None,
                      vertices: np.ndarray | None = None) -> np.ndarray:
    """Angle (radians) between the boundary normal and the nearest frame axis,
    per boundary vertex (or the given subset).  ``normals`` is indexed like
    mesh.boundary_vertices (one per boundary vertex)."""
    bv = mesh.boundary_vertices
    N = mesh.boundary.vertex_normals if normals is None else normals
    if vertices is not None:
        loc = np.searchsorted(bv, vertices)
        bv, N = bv[loc], N[loc]
    return axis_alignment(frames[bv], N)


def vertex_normal_adaptation(field) -> np.ndarray:
    """Normal adaptation of a solved field at every vertex where it is measured.

    The frames of sharp-feature vertices are fixed to the feature (§3.3), so
    only the other boundary vertices measure how well the field follows the
    surface.

    Parameters
    ----------
    field : SolvedField, or a solver Result

    Returns
    -------
    (#V,) float array
        Angle (radians) between the surface normal and the nearest frame
        axis at each boundary vertex off the sharp features; -1 at interior
        and sharp-feature vertices.
    """
    f = as_field(field, "vertex_normal_adaptation")
    mesh = f.mesh
    out = np.full(mesh.n_vertices, -1.0)
    free = ~f.feature_vertices[mesh.boundary_vertices]
    out[mesh.boundary_vertices[free]] = normal_adaptation(mesh, f.frames)[free]
    return out


def axis_alignment(frames: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Angle (radians) between each direction and the nearest axis of its frame."""
    d = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    c = np.abs(np.einsum("nij,ni->nj", frames, d)).max(axis=1)
    return np.arccos(np.clip(c, -1.0, 1.0))


def curve_tangent_adaptation(points: np.ndarray, frames: np.ndarray, polyline: np.ndarray,
                             closed: bool = False) -> np.ndarray:
    """Angle (radians) between the curve tangent at the point of the polyline
    nearest to each point and the nearest axis of the point's frame."""
    geo = CurveGeometry(np.asarray(polyline, float), closed)
    s, t, _ = geo.closest(points)
    return axis_alignment(frames, geo.tangent(s, t))


def tangent_adaptation(field) -> tuple[np.ndarray, np.ndarray]:
    """Angle between the curve tangent (at the nearest curve point) and the
    nearest frame axis at every vertex carrying a curve constraint, of a
    solved field (SolvedField or Result).

    Returns (vertex ids, angles in radians).
    """
    f = as_field(field, "tangent_adaptation")
    verts, angs = [], []
    for ci, tr in enumerate(f.embedding.traces):
        v = f.curve_vertices(ci)
        if len(v) == 0:
            continue
        verts.append(v)
        angs.append(curve_tangent_adaptation(f.mesh.vertices[v], f.frames[v], tr.polyline,
                                             f.network.curves[ci].closed))
    if not verts:
        return np.zeros(0, int), np.zeros(0)
    return np.concatenate(verts), np.concatenate(angs)


# ================================================================ smoothness


def tet_frames(mesh: TetMesh, frames: np.ndarray) -> np.ndarray:
    """(#T, 3, 3) one frame per tet: the Karcher mean of its four vertex
    frames matched to the first vertex by the closest rotation, as for
    CubeCover in §5.5 (field.matchings.tet_frames without omega)."""
    from .streamlines import barycentric_karcher_mean

    def karcher(matched, weights):
        return barycentric_karcher_mean(matched, weights, iterations=8)

    return matching_tet_frames(mesh, frames, mean=karcher).frames


def dual_face_weights(mesh: TetMesh, faces: np.ndarray) -> np.ndarray:
    """Face area over dual edge length for interior faces (§5.4's w_ijk).

    The dual edge joins the two tets' centroids: circumcentres, as in the
    paper, coincide or swap order on non-Delaunay (fTetWild) and structured
    meshes, which gives infinite or negative weights."""
    ft = mesh.face_tets[faces]
    C = mesh.vertices[mesh.tets].mean(axis=1)
    ell = np.linalg.norm(C[ft[:, 0]] - C[ft[:, 1]], axis=1)
    return mesh.face_areas[faces] / np.maximum(ell, 1e-300)


def _quat(R):
    return Rotation.from_matrix(R).as_quat()  # x y z w, sign arbitrary


def face_frame_differences(mesh: TetMesh, tframes: np.ndarray, faces: np.ndarray):
    """Per interior face: (theta, |q_a - q_b|) between the frames of its two
    tets, the second matched to the first (closest cube symmetry) and its
    quaternion sign chosen nearest."""
    ft = mesh.face_tets[faces]
    Ea, Eb = tframes[ft[:, 0]], tframes[ft[:, 1]]
    theta = cross_distance(Ea, Eb)
    qa, qb = _quat(Ea), _quat(match_to(Eb, Ea))
    qb = np.where((np.einsum("ij,ij->i", qa, qb) < 0)[:, None], -qb, qb)
    return theta, np.linalg.norm(qa - qb, axis=1)


def smoothness(mesh: TetMesh, frames: np.ndarray, faces: np.ndarray | None = None,
               tframes: np.ndarray | None = None) -> tuple[float, float]:
    """(phi_theta, phi_H) of §5.4 over interior faces (or the given ones):

        phi_H     = (sum_f w_f |q_fa - q_fb|^2)^(1/2)
        phi_theta = (sum_f w_f theta_f^2)^(1/2)

    with frames per tet from the vertex frames (tet_frames) and w_f the face
    area over the dual edge length (dual_face_weights)."""
    if faces is None:
        faces = np.nonzero(~mesh.is_boundary_face)[0]
    tf = tet_frames(mesh, frames) if tframes is None else tframes
    theta, dq = face_frame_differences(mesh, tf, faces)
    w = dual_face_weights(mesh, faces)
    return float(np.sqrt(np.sum(w * theta**2))), float(np.sqrt(np.sum(w * dq**2)))


# ============================================================ local smoothing


def karcher_smoothing(mesh: TetMesh, frames: np.ndarray, iterations: int = 20, fixed: np.ndarray | None = None,
                      axes: np.ndarray | None = None, weights: np.ndarray | None = None, inner: int = 2):
    """Local smoothing of §5.2 (Fig. 18): each sweep replaces every free
    frame E_i by the weighted Karcher mean of its neighbours, the minimiser
    of sum_j w_ij d(E_i, E_j)^2 with E_j the representative closest to E_i
    (Jacobi sweeps; ``inner`` fixed-point steps E_i <- E_i exp(mean log(E_i^T E_j))).

    fixed   : (#V,) bool, frames that do not move
    axes    : (#V, 3), nonzero rows restrict that vertex to rotations about
              the given world axis (boundary vertices about their normal)
    weights : (#E,) w_ij, default mesh.dirichlet_weights (Eq. 16)
    Returns (smoothed frames, (iterations,) max cross change per sweep).
    """
    E = np.array(frames, dtype=float, copy=True)
    nV = mesh.n_vertices
    a, b = mesh.edges[:, 0], mesh.edges[:, 1]
    w = mesh.dirichlet_weights if weights is None else np.asarray(weights, float)
    wsum = np.bincount(a, w, nV) + np.bincount(b, w, nV)
    free = np.ones(nV, bool) if fixed is None else ~np.asarray(fixed, bool)
    free &= wsum > 0
    if axes is not None:
        ax = np.asarray(axes, float)
        has_ax = np.linalg.norm(ax, axis=1) > 0
        ax = np.where(has_ax[:, None], ax / np.maximum(np.linalg.norm(ax, axis=1, keepdims=True), 1e-300), 0.0)
    history = []
    for _ in range(iterations):
        E0 = E
        X = E.copy()
        for _ in range(inner):
            # body-frame logs towards the matched neighbours, both directions
            vab = log_so3(np.einsum("nji,njk->nik", X[a], match_to(E0[b], X[a])))
            vba = log_so3(np.einsum("nji,njk->nik", X[b], match_to(E0[a], X[b])))
            s = np.zeros((nV, 3))
            for k in range(3):
                s[:, k] = np.bincount(a, w * vab[:, k], nV) + np.bincount(b, w * vba[:, k], nV)
            s /= np.maximum(wsum, 1e-300)[:, None]
            if axes is not None:
                sw = np.einsum("nij,nj->ni", X, s)  # world coordinates
                sw = np.where(has_ax[:, None], np.einsum("ni,ni->n", sw, ax)[:, None] * ax, sw)
                s = np.einsum("nji,nj->ni", X, sw)
            s[~free] = 0.0
            X = X @ exp_so3(s)
        E = X
        history.append(float(cross_distance(E0, E).max()))
    return E, np.array(history)


def smoothing_check(mesh: TetMesh, frames: np.ndarray, iterations: int = 20, fixed: np.ndarray | None = None,
                    axes: np.ndarray | None = None, faces: np.ndarray | None = None) -> dict:
    """How far local Karcher smoothing moves the crosses and how much it
    lowers phi_theta (§5.2, Fig. 18).  Degrees for the changes."""
    S, hist = karcher_smoothing(mesh, frames, iterations, fixed, axes)
    d = np.degrees(cross_distance(frames, S))
    free = np.ones(mesh.n_vertices, bool) if fixed is None else ~np.asarray(fixed, bool)
    p0, h0 = smoothness(mesh, frames, faces)
    p1, h1 = smoothness(mesh, S, faces)
    return {
        "iterations": iterations,
        "max_change_deg": float(d.max()),
        "mean_change_deg": float(d[free].mean()) if np.any(free) else 0.0,
        "p99_change_deg": float(np.percentile(d[free], 99)) if np.any(free) else 0.0,
        "last_sweep_deg": float(np.degrees(hist[-1])) if len(hist) else 0.0,
        "phi_theta_before": p0,
        "phi_theta_after": p1,
        "phi_theta_drop_pct": 100.0 * (p0 - p1) / p0 if p0 > 0 else 0.0,
        "phi_H_before": h0,
        "phi_H_after": h1,
        "frames": S,
    }


# ================================================================ refinement


def loglog_slope(h, values) -> float:
    """Least-squares slope of log(values) against log(h)."""
    h, v = np.asarray(h, float), np.asarray(values, float)
    ok = (h > 0) & (v > 0) & np.isfinite(v)
    if ok.sum() < 2:
        return float("nan")
    return float(np.polyfit(np.log(h[ok]), np.log(v[ok]), 1)[0])


def vertices_near_polylines(X: np.ndarray, polylines, distance: float) -> np.ndarray:
    """(len(X),) bool: within ``distance`` of any of the polylines."""
    near = np.zeros(len(X), bool)
    for P in polylines:
        if len(P) >= 2:
            near |= CurveGeometry(np.asarray(P, float)).closest(X)[2] < distance
    return near


def _face_ids(mesh: TetMesh, faces) -> np.ndarray:
    faces = checks.array("network_faces", faces, OptionsError, shape=(None,), kind="i")
    if len(faces) and (faces.min() < 0 or faces.max() >= mesh.n_faces):
        raise OptionsError(f"network_faces: face ids run from 0 to {mesh.n_faces - 1}, found "
                           f"{faces.min()}..{faces.max()}")
    return faces


def regular_face_mask(mesh: TetMesh, network_faces: np.ndarray) -> np.ndarray:
    """The faces whose monodromy should vanish: interior faces the network
    does not pass through.

    Parameters
    ----------
    mesh : TetMesh
    network_faces : (k,) int array
        Ids of the faces the network passes through (pierced faces, node
        regions, faces where curves end).

    Returns
    -------
    (#F,) bool array
    """
    checks.instance("mesh", mesh, TetMesh, OptionsError)
    network_faces = _face_ids(mesh, network_faces)
    mask = ~mesh.is_boundary_face
    mask[np.asarray(network_faces, dtype=np.int64)] = False
    return mask


def regular_faces(field) -> np.ndarray:
    """Ids of the regular faces (regular_face_mask) of a solved field
    (SolvedField or Result) where the structure equation is imposed (not
    Embedding.face_excluded)."""
    f = as_field(field, "regular_faces")
    mesh, emb = f.mesh, f.embedding
    return np.nonzero(regular_face_mask(mesh, emb.network_faces(mesh)) & ~emb.face_excluded)[0]


def subdomain_faces(field, away: float) -> np.ndarray:
    """Regular faces whose three vertices all lie at least ``away`` from
    every network curve (a fixed subdomain for a refinement study)."""
    field = as_field(field, "subdomain_faces")
    mesh = field.mesh
    f = regular_faces(field)
    curves = [c.points for c in field.network.curves]
    if not curves or away <= 0:
        return f
    near = vertices_near_polylines(mesh.vertices, curves, away)
    return f[~near[mesh.faces[f]].any(axis=1)]


# ================================================================ summaries


def quick_metrics(field) -> dict:
    """The headline figures of a solved field (SolvedField or Result), in
    degrees where angles."""
    result = as_field(field, "quick_metrics")
    mesh = result.mesh
    emb = result.embedding
    net_faces = emb.network_faces(mesh)
    regular = np.nonzero(regular_face_mask(mesh, net_faces))[0]
    out = {}
    if len(regular):
        ang = np.degrees(monodromy_angles(mesh, result.omega, regular))
        out["monodromy_mean_deg"] = float(ang.mean())
        out["monodromy_max_deg"] = float(ang.max())
    sf = singular_faces(mesh, result.omega, result.frames, net_faces)
    out["singular_faces"] = int(sf.closest.sum())
    out["spurious_singular_faces"] = int(sf.closest_spurious.sum())
    # faces the singular curves pierce (a feature curve's faces are regular)
    must = emb.prescribed_singular()
    out["missing_singular_faces"] = int((must & ~sf.closest).sum())
    # the same with omega-aware matchings (the field's own, which the exports
    # write), and the largest turn of an edge.  Closest-rotation matching is
    # ambiguous where an edge turns by ~45 degrees: an edge the curve passes
    # close to (the plate at h = 0.2: 2-4 faces around such an edge flagged on
    # 5 of 202 meshes -- one edge 4e-4 from the curve turned 46.4 degrees --
    # while the omega-aware structure was exactly the network's)
    out["omega_singular_faces"] = int(sf.singular.sum())
    out["omega_spurious_singular_faces"] = int(sf.spurious.sum())
    out["omega_missing_singular_faces"] = int((must & ~sf.singular).sum())
    out["matching_disagreements"] = sf.disagreements
    out["max_edge_turn_deg"] = float(np.degrees(np.linalg.norm(result.omega, axis=1).max()))
    na = vertex_normal_adaptation(result)
    na = np.degrees(na[na >= 0])
    out["normal_adaptation_mean_deg"] = float(na.mean()) if len(na) else 0.0
    out["normal_adaptation_max_deg"] = float(na.max()) if len(na) else 0.0
    _, ta = tangent_adaptation(result)
    if len(ta):
        out["tangent_adaptation_mean_deg"] = float(np.degrees(ta).mean())
        out["tangent_adaptation_max_deg"] = float(np.degrees(ta).max())
    return out
