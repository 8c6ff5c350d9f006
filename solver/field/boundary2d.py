"""The 2D boundary cross field (§3) and its extrinsic lift (§3.4).

Input: the boundary surface dK (outward), its sharp-feature graph, and the
singular triangles (curve ends, sharp corners).  Output: a 2D Darboux
derivative omega (one angle per boundary edge), the developed field, and the
3D data the volume problem needs: a reference frame E0_i per boundary vertex
(third axis = normal) and omega0_ij per boundary edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse import csgraph

from ..errors import TopologyError
from ..linalg.rotations import (
    CUBE_GROUP,
    best_adapted_frame,
    exp_so3,
    frame_from_axes,
    log_so3,
    minimal_rotation,
    unwrap_rotvec,
)
from ..surface.features import FeatureGraph, corner_fan_links
from ..surface.trisurface import TriSurface
from .develop import accumulate_along_tree


def wrap(x, period=2 * np.pi):
    """Map angles to (-period/2, period/2]."""
    return x - period * np.round(x / period)


@dataclass
class VertexCoordinates:
    """Local polar coordinates at every vertex (§2.3, Knöppel et al. 2013).

    phi_corner : (#F, 3) angle at F[f,k] of the edge F[f,k] -> F[f,k+1]
    theta_tilde: (#F, 3) normalised interior angles 2 pi theta / Theta_i
    Theta      : (#V,) angle sum at each vertex
    ref_corner : (#V,) corner (3f + k) whose outgoing edge has angle 0
    """

    phi_corner: np.ndarray
    theta_tilde: np.ndarray
    Theta: np.ndarray
    ref_corner: np.ndarray


def vertex_coordinates(S: TriSurface) -> VertexCoordinates:
    F = S.F
    nV = len(S.V)
    theta = S.corner_angles
    Theta = np.bincount(F.reshape(-1), weights=theta.reshape(-1), minlength=nV)
    tt = 2 * np.pi * theta / Theta[F]
    cw = corner_fan_links(S)  # clockwise neighbour
    ccw = np.empty_like(cw)
    ccw[cw] = np.arange(len(cw))  # counter-clockwise neighbour
    # reference corner: the first corner of each vertex
    flatv = F.reshape(-1)
    ref = np.full(nV, -1, dtype=np.int64)
    ref[flatv[::-1]] = np.arange(len(flatv))[::-1]
    phi = np.full(len(flatv), np.nan)
    used = ref >= 0
    cur = ref[used]
    phi[cur] = 0.0
    ttf = tt.reshape(-1)
    for _ in range(64):
        nxt = ccw[cur]
        fresh = np.isnan(phi[nxt])
        if not np.any(fresh):
            break
        phi[nxt[fresh]] = phi[cur[fresh]] + ttf[cur[fresh]]
        cur = nxt[fresh]
    if np.any(np.isnan(phi)):
        raise TopologyError("a boundary vertex has more than 64 neighbours; refine the surface more evenly")
    return VertexCoordinates(phi.reshape(-1, 3), tt, Theta, ref)


@dataclass
class BoundaryField:
    """Result of the 2D stage.

    omega2d  : (#bE,) 2D Darboux derivative per boundary edge (low -> high id)
    phi      : (#bV,) developed field angle at each vertex (normalised coords)
    rho      : (#bE,) parallel transport angle (Eq. 5)
    K        : (#bF,) Gaussian curvature per triangle (Eq. 4)
    Omega    : (#bF,) prescribed singular angle per triangle
    E0       : (#bV, 3, 3) extrinsic reference frames (third axis: normal)
    omega0   : (#bE, 3) Darboux derivative of E0 (exact, large rotations kept)
    normals  : (#bV, 3) vertex normals used
    edge_normals : (#bE, 2, 3) normal used at each end of each edge in Eq. 20
    is_feature_vertex : (#bV,) frames fully fixed there (sharp features)
    features : FeatureGraph on the boundary
    generators : list of ((component, k), edge ids, signs) loops used in Eq. 14
    generator_null_values : (#generators, m) change of each generator's
        holonomy along m random null vectors of the face and alignment rows
        (zero for the combinations these rows fix)
    uncorrected : BoundaryField or None
        where field/handles.py corrected the generators' turns, the
        smoothest field before the correction (FieldProblem.solve falls
        back to it where the corrected one leaves LM far from a solution)
    """

    omega2d: np.ndarray
    phi: np.ndarray
    rho: np.ndarray
    K: np.ndarray
    Omega: np.ndarray
    E0: np.ndarray
    omega0: np.ndarray
    normals: np.ndarray
    edge_normals: np.ndarray
    is_feature_vertex: np.ndarray
    features: FeatureGraph
    generators: list
    constraint_residual: float
    generator_null_values: np.ndarray | None = None
    uncorrected: BoundaryField | None = None


def edge_angles(S: TriSurface, vc: VertexCoordinates):
    """phi_ij and phi_ji (§2.3) for every edge i<j of S."""
    F = S.F
    nV = len(S.V)
    a = F.reshape(-1)
    b = np.roll(F, -1, axis=1).reshape(-1)
    keys = a.astype(np.int64) * nV + b
    order = np.argsort(keys)
    E = S.edges
    phi = vc.phi_corner.reshape(-1)
    fwd = order[np.searchsorted(keys[order], E[:, 0] * nV + E[:, 1])]
    bwd = order[np.searchsorted(keys[order], E[:, 1] * nV + E[:, 0])]
    return phi[fwd], phi[bwd]


def tree_cotree_generators(S: TriSurface, comp_faces: np.ndarray, root: int):
    """Homology generators of one component as primal edge loops.

    Returns a list of (edge ids, signs) where signs orient each edge along
    the loop.
    """
    E = S.edges
    nV = len(S.V)
    fmask = np.zeros(len(S.F), bool)
    fmask[comp_faces] = True
    emask = np.zeros(len(E), bool)
    emask[S.face_edges[comp_faces].reshape(-1)] = True
    eids = np.nonzero(emask)[0]
    A = sp.coo_matrix((np.ones(len(eids)), (E[eids, 0], E[eids, 1])), shape=(nV, nV))
    A = (A + A.T).tocsr()
    _, pred = csgraph.breadth_first_order(A, root, directed=False, return_predecessors=True)
    in_tree = np.zeros(len(E), bool)
    child = np.nonzero(pred >= 0)[0]
    n = nV
    keys = E[:, 0] * n + E[:, 1]
    tkeys = np.minimum(child, pred[child]) * n + np.maximum(child, pred[child])
    in_tree[np.searchsorted(keys, tkeys)] = True
    # dual tree on faces through edges not in the primal tree
    ef = S.edge_faces
    dual = emask & ~in_tree
    nF = len(S.F)
    D = sp.coo_matrix((np.ones(dual.sum()), (ef[dual, 0], ef[dual, 1])), shape=(nF, nF))
    D = (D + D.T).tocsr()
    froot = comp_faces[0]
    _, fpred = csgraph.breadth_first_order(D, froot, directed=False, return_predecessors=True)
    in_cotree = np.zeros(len(E), bool)
    fchild = np.nonzero(fpred >= 0)[0]
    # the edge shared by a face and its dual parent
    fe = S.face_edges
    par = fpred[fchild]
    same = (fe[fchild][:, :, None] == fe[par][:, None, :]).any(axis=2) & dual[fe[fchild]]
    in_cotree[fe[fchild][np.arange(len(fchild)), np.argmax(same, axis=1)]] = True
    left = np.nonzero(emask & ~in_tree & ~in_cotree)[0]
    loops = []
    for e in left:
        u, v = E[e]
        pu = _path_to_root(pred, u)
        pv = _path_to_root(pred, v)
        # trim the common tail
        while len(pu) > 1 and len(pv) > 1 and pu[-2] == pv[-2]:
            pu.pop()
            pv.pop()
        # loop: u -> v (edge e), v -> ... -> lca, lca -> ... -> u
        verts = [u] + pv + pu[::-1][1:]
        ids, signs = [], []
        for x, y in zip(verts[:-1], verts[1:]):
            k = np.searchsorted(keys, min(x, y) * n + max(x, y))
            ids.append(k)
            signs.append(1.0 if x < y else -1.0)
        loops.append((np.array(ids), np.array(signs)))
    return loops


def _sector_rows(S: TriSurface, G: FeatureGraph, vc: VertexCoordinates, beta, rho, reg):
    """Alignment across the sectors of sharp corners (§3.3, Fig. 11).

    Fixed omega on sharp edges keeps the field aligned along a chain of
    regular feature vertices, but nothing carried the alignment past a
    corner: the smoothest field could turn by any angle from one chain to the
    next (12 degrees on the holes of a genus-1 block, 45 with a singular pair
    through it), and the frames adapted at the sharp edges then disagreed with
    the 2D field by up to half a quarter turn.  For each sector s of a corner
    c, from sharp edge (a1, c) to (c, a2) counter-clockwise, the field carried
    a1 -> c -> a2 must arrive aligned with the second edge:

        omega_a1c + omega_ca2 = theta~_s - k_s pi/2  (- Omega_c in the sector
                                                      of c's singular triangle)

    where theta~_s is the sector's normalised angle and k_s its quantised
    angle in quarter turns; the real target is the value congruent (mod pi/2)
    to exact alignment at a1 and a2 (their beta) nearest to that ideal.
    Around c the targets sum to zero, so when every sector of c has regular
    feature vertices at both ends the singular sector's row is implied and
    left out.  Returns (rows as (sector, edge, sign) triplets, rhs, links
    (a1, a2) per row).
    """
    F = S.F
    ns, slab = G.sectors
    nV = len(S.V)
    corners = G.corners
    if len(corners) == 0:
        return np.zeros((0, 3), np.int64), np.zeros(0), np.zeros((0, 2), np.int64)
    sv = G.sector_vertex
    is_corner = np.zeros(nV, bool)
    is_corner[corners] = True
    fe = S.face_edges
    sharp = G.sharp
    flat = np.arange(3 * len(F))
    f, k = flat // 3, flat % 3
    cv = F[f, k]
    at = is_corner[cv]
    # the sector's first corner starts at a sharp edge (c, F[f,k+1]); its
    # last corner ends at a sharp edge (c, F[f,k+2])
    first = at & sharp[fe[f, k]]
    last = at & sharp[fe[f, (k + 2) % 3]]
    a1 = np.full(ns, -1)
    a2 = np.full(ns, -1)
    a1[slab[first]] = F[f[first], (k[first] + 1) % 3]
    a2[slab[last]] = F[f[last], (k[last] + 2) % 3]
    tt = np.bincount(slab, weights=vc.theta_tilde.reshape(-1), minlength=ns)
    sing = np.zeros(ns, bool)
    cf = G.corner_faces()
    ck = np.argmax(F[cf] == corners[:, None], axis=1)
    sing[slab[3 * cf + ck]] = True
    Omega_c = np.zeros(nV)
    Omega_c[corners] = 2 * np.pi * G.vertex_index[corners]
    secs = np.nonzero(is_corner[sv] & (a1 >= 0) & (a2 >= 0))[0]
    secs = secs[(a1[secs] != a2[secs])]
    valid = reg[a1[secs]] & reg[a2[secs]]
    # every sector of the corner valid: its singular sector's row is implied
    n_sec = np.bincount(sv[secs], minlength=nV)
    n_val = np.bincount(sv[secs[valid]], minlength=nV)
    all_valid = (n_sec == np.bincount(sv, minlength=nV)) & (n_val == n_sec)
    keep = valid & ~(sing[secs] & all_valid[sv[secs]])
    secs = secs[keep]
    c, p, q = sv[secs], a1[secs], a2[secs]
    ideal = tt[secs] - G.sector_quarters[secs] * np.pi / 2 - np.where(sing[secs], Omega_c[c], 0.0)
    e1 = S.edge_index(p, c)
    e2 = S.edge_index(c, q)
    s1 = np.where(p < c, 1.0, -1.0)
    s2 = np.where(c < q, 1.0, -1.0)
    # alignment at a1 and a2: phi_a2 - phi_a1 = rho + omega along a1 -> c -> a2
    resid = beta[q] - beta[p] - s1 * rho[e1] - s2 * rho[e2]
    rhs = ideal + wrap(resid - ideal, np.pi / 2)
    n = len(secs)
    trip = np.stack([np.r_[np.arange(n), np.arange(n)], np.r_[e1, e2], np.r_[s1, s2]], axis=1)
    return trip, rhs, np.stack([p, q], axis=1)


def _unlinked_chain_paths(S: TriSurface, fixed, links, reg):
    """Sharp chains not linked to their component's development root.

    Chains of regular feature vertices are joined by fixed sharp edges and by
    the corner sectors of _sector_rows; the groups this leaves in a surface
    component other than the root's (the root is the first regular feature
    vertex, as in _develop_angles) each get the breadth-first tree path from
    the root to their first vertex.  Returns [(root, vertex, edge ids,
    signs)].
    """
    E = S.edges
    nV = len(S.V)
    if not np.any(reg):
        return []
    pairs = np.r_[E[fixed], links.reshape(-1, 2)]
    A = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(nV, nV))
    _, glab = csgraph.connected_components(A, directed=False)
    Aall = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(nV, nV))
    Aall = (Aall + Aall.T).tocsr()
    ncomp, vlab = csgraph.connected_components(Aall, directed=False)
    out = []
    for c in range(ncomp):
        feat = np.nonzero((vlab == c) & reg)[0]
        if len(feat) == 0:
            continue
        root = int(feat[0])
        _, first = np.unique(glab[feat], return_index=True)
        others = [int(v) for v in feat[first] if glab[v] != glab[root]]
        if not others:
            continue
        _, pred = csgraph.breadth_first_order(Aall, root, directed=False, return_predecessors=True)
        for v in others:
            path = _path_to_root(pred, v)[::-1]  # root -> v
            a, b = np.array(path[:-1]), np.array(path[1:])
            out.append((root, v, S.edge_index(a, b), np.where(a < b, 1.0, -1.0)))
    return out


def _path_to_root(pred, v):
    path = [int(v)]
    while pred[path[-1]] >= 0:
        path.append(int(pred[path[-1]]))
    return path


def solve_boundary_field(
    S: TriSurface,
    features: FeatureGraph,
    face_sigma: np.ndarray,
    generator_turns: dict | None = None,
    normal_override: dict | None = None,
) -> BoundaryField:
    """Solve Eq. 15 with feature alignment, develop it, and lift it to 3D.

    Parameters
    ----------
    S : TriSurface
        The boundary surface, #bV vertices, #bE edges, #bF triangles.
    features : FeatureGraph
        Its sharp edges and corners.
    face_sigma : (#bF,) float array
        Index of the curve ends per boundary triangle.
    generator_turns : dict or None
        {(component, k): quarter turns} added to the holonomy target of
        generator k of a component (Eq. 14).
    normal_override : dict or None
        {vertex: unit vector} replacing the vertex normal the 3D frame is
        adapted to (the curve tangent at curve ends).

    Returns
    -------
    BoundaryField

    Raises
    ------
    TopologyError
        When no field satisfies the singularities and the sharp features
        together.
    """
    E = S.edges
    vc = vertex_coordinates(S)
    phi_ij, phi_ji = edge_angles(S, vc)
    rho = wrap(phi_ji + np.pi - phi_ij)  # Eq. 5
    K = vc.theta_tilde.sum(axis=1) - np.pi  # Eq. 4
    # singular triangles: curve ends and sharp corners (Fig. 11)
    Omega = 2 * np.pi * np.asarray(face_sigma, dtype=float).copy()
    np.add.at(Omega, features.corner_faces(), 2 * np.pi * features.vertex_index[features.corners])
    # feature alignment: fixed omega on sharp edges between regular feature vertices
    reg = features.is_regular_feature_vertex
    beta = np.zeros(len(S.V))
    if np.any(features.sharp):
        se = np.nonzero(features.sharp)[0]
        z = np.zeros(len(S.V), complex)
        np.add.at(z, E[se, 0], np.exp(4j * phi_ij[se]))
        np.add.at(z, E[se, 1], np.exp(4j * phi_ji[se]))
        beta = np.angle(z) / 4.0
    fixed = features.sharp & reg[E[:, 0]] & reg[E[:, 1]]
    ls = _LeastNorm(_cotan_weights(S), fixed, wrap(beta[E[:, 1]] - beta[E[:, 0]] - rho, np.pi / 2))
    # constraint rows: one per triangle (Eq. 13), minus one per component,
    # then the alignment carried across the sectors of sharp corners
    C, b, keep = _triangle_rows(S, K, Omega)
    trip, srhs, links = _sector_rows(S, features, vc, beta, rho, reg)
    Csec = sp.csr_matrix((trip[:, 2], (trip[:, 0].astype(np.int64), trip[:, 1].astype(np.int64))),
                         shape=(len(srhs), len(E)))
    Call = sp.vstack([C[keep], Csec]).tocsr()
    ball = np.r_[b[keep], srhs]
    generators = _generators(S)
    null_values = np.zeros((0, 0))
    if generators:
        Call, ball, null_values = _add_generator_rows(ls, Call, ball, rho, generators, generator_turns)
    Call, ball = _add_chain_rows(S, ls, Call, ball, rho, beta, links, reg)
    omega = ls.solve(Call, ball)
    res = np.abs(Call @ omega - ball)
    worst = float(res.max()) if len(res) else 0.0
    if worst > 1e-6:
        f = int(np.argmax(np.abs(C @ omega - b)))
        c = S.V[S.F[f]].mean(axis=0)
        raise TopologyError(
            "the boundary cross field cannot satisfy the singularities and sharp features together "
            f"(worst mismatch {np.degrees(worst):.3g} degrees near ({c[0]:.3g}, {c[1]:.3g}, {c[2]:.3g})); "
            "check that every patch bounded by sharp edges holds the singular curves it needs"
        )
    # develop the 2D field (§3.4): phi_j = phi_i + rho_ij + omega_ij
    phi = _develop_angles(S, rho + omega, beta, reg, S.face_components[1])
    E0, omega0, N, edge_normals = _lift(S, features, vc, phi, omega, normal_override)
    return BoundaryField(
        omega2d=omega,
        phi=phi,
        rho=rho,
        K=K,
        Omega=Omega,
        E0=E0,
        omega0=omega0,
        normals=N,
        edge_normals=edge_normals,
        is_feature_vertex=features.degree > 0,
        features=features,
        generators=[(key, ids, signs) for key, (ids, signs) in generators],
        constraint_residual=worst,
        generator_null_values=null_values,
    )


def _cotan_weights(S: TriSurface) -> np.ndarray:
    """(#bE,) cotan weights of Eq. 12, floored: the 2D energy must stay
    positive."""
    cot = 1.0 / np.tan(S.corner_angles)
    w = np.zeros(len(S.edges))
    for k in range(3):
        # corner k is opposite the edge (k+1, k+2) = face_edges[:, (k+1) % 3]
        np.add.at(w, S.face_edges[:, (k + 1) % 3], 0.5 * cot[:, k])
    return np.maximum(w, 0.05 * np.abs(w).mean())


def _triangle_rows(S: TriSurface, K: np.ndarray, Omega: np.ndarray):
    """The holonomy rows of Eq. 13, one per triangle: (C, right-hand side,
    mask of the rows kept: one per component is left out, as the rows of a
    closed component sum to zero)."""
    ncomp, flab = S.face_components
    nF = len(S.F)
    rows = np.repeat(np.arange(nF), 3)
    C = sp.csr_matrix((S.face_edge_signs.reshape(-1), (rows, S.face_edges.reshape(-1))), shape=(nF, len(S.edges)))
    keep = np.ones(nF, bool)
    for c in range(ncomp):
        keep[np.nonzero(flab == c)[0][0]] = False
    return C, -K + Omega, keep


def _generators(S: TriSurface) -> list:
    """((component, k), (edge ids, signs)) of the homology generators of the
    components of positive genus (Eq. 14)."""
    ncomp, flab = S.face_components
    chi = S.euler_characteristics()
    generators = []
    for c in range(ncomp):
        if chi[c] >= 2:
            continue
        comp_faces = np.nonzero(flab == c)[0]
        root = S.F[comp_faces[0], 0]
        for k, loop in enumerate(tree_cotree_generators(S, comp_faces, root)):
            generators.append(((c, k), loop))
    return generators


class _LeastNorm:
    """Smallest weighted-norm 2D omega under linear rows, with the omega of
    the fixed (aligned sharp) edges given."""

    def __init__(self, w: np.ndarray, fixed: np.ndarray, omega_fixed: np.ndarray):
        self.w, self.fixed, self.free, self.omega_fixed = w, fixed, ~fixed, omega_fixed

    def _least_norm(self, rows):
        """(Cf, apply): apply(r) is the smallest weighted-norm x on the free
        edges with Cf x = r (r a vector or columns), by the normal equations
        of the constraints."""
        Cf = rows[:, self.free].tocsr()
        Winv = sp.diags(1.0 / self.w[self.free])
        Sys = (Cf @ Winv @ Cf.T).tocsc()
        lu = spla.splu(Sys + 1e-12 * Sys.diagonal().mean() * sp.eye(Sys.shape[0]), permc_spec="MMD_AT_PLUS_A")

        def apply(r):
            y = lu.solve(r)
            # the shift guards against dependent rows but leaves a residual
            # of shift * y in every row, and these add up in the triangle
            # left out of each component (its row is minus the sum of the
            # others): the torus example at 50k tets, with a full turn added
            # around a generator, missed it by 1.4e-6 rad on 4 of 4 meshes,
            # above the tolerance of solve_boundary_field.  Iterative
            # refinement against the unshifted system removes it (along a
            # null vector of Sys, y may grow, but Cf^T maps that direction
            # to zero)
            for _ in range(3):
                y += lu.solve(r - Sys @ y)
            return Winv @ (Cf.T @ y)

        return Cf, apply

    def solve(self, rows, rhs) -> np.ndarray:
        """Smallest-norm omega with rows @ omega = rhs (fixed edges moved to
        the right-hand side)."""
        _, apply = self._least_norm(rows)
        out = np.zeros(len(self.w))
        out[self.free] = apply(rhs - rows[:, self.fixed] @ self.omega_fixed[self.fixed])
        out[self.fixed] = self.omega_fixed[self.fixed]
        return out

    def null_vectors(self, rows, m: int) -> np.ndarray:
        """m random vectors on the free edges that the rows map to zero."""
        Cf, apply = self._least_norm(rows)
        R = np.random.default_rng(0).normal(size=(int(self.free.sum()), m))
        out = np.zeros((len(self.w), m))
        out[self.free] = R - apply(Cf @ R)
        return out


def _add_generator_rows(ls: _LeastNorm, Call, ball, rho, generators: list, generator_turns: dict | None):
    """The rows with the generators' holonomy rows added (Eq. 14), and how
    the generators' holonomies move along the null space of the rows before
    them: (rows, right-hand side, null values)."""
    nE = len(rho)
    # Eq. 14 fixes the holonomy of the cross field along each generator to
    # a multiple of a quarter turn; take the multiple nearest to the
    # smoothest field without generator constraints (plus any requested
    # extra turns, e.g. the parity correction of the pipeline)
    omega1 = ls.solve(Call, ball)
    # a combination homologous to sharp outlines (a hole's rim) does not
    # move, the alignment rows fix it, and turns added to it would
    # contradict them (the pipeline keeps its corrections off these
    # combinations)
    N = ls.null_vectors(Call, len(generators) + 2)
    null_values = np.array([signs @ N[ids] for _key, (ids, signs) in generators])
    null_values /= np.linalg.norm(N, axis=0)[None, :]  # one scale per vector: integer combinations stay so
    gen_rows, gen_rhs = [], []
    for key, (ids, signs) in generators:
        Phi0 = np.sum(signs * rho[ids])
        H1 = Phi0 + np.sum(signs * omega1[ids])
        turns = int(np.round(H1 / (np.pi / 2)))
        if generator_turns is not None:
            turns += generator_turns.get(key, 0)
        row = np.zeros(nE)
        np.add.at(row, ids, signs)
        gen_rows.append(row)
        gen_rhs.append(-Phi0 + turns * np.pi / 2)
    return sp.vstack([Call, sp.csr_matrix(np.array(gen_rows))]).tocsr(), np.r_[ball, gen_rhs], null_values


def _add_chain_rows(S: TriSurface, ls: _LeastNorm, Call, ball, rho, beta, links, reg):
    """The rows with the sharp chains that the corners do not link to the
    development root (the rims of a hole, apart from the outline) aligned
    with the root: each group by the quarter turn nearest to the smoothest
    field (a free choice, like a generator's turns; it sets how the field
    turns across the annulus between them), one at a time: the next group's
    quarter turn is read from the field that already has the previous ones
    (two rims of a round hole, rounded independently, could contradict the
    meridian's turns between them)."""
    nE = len(rho)
    for root, rep, ids, signs in _unlinked_chain_paths(S, ls.fixed, links, reg):
        omega2 = ls.solve(Call, ball)
        Phi0 = np.sum(signs * rho[ids])
        d = beta[rep] - beta[root]
        val = Phi0 + np.sum(signs * omega2[ids])
        row = sp.csr_matrix((signs, (np.zeros(len(ids), np.int64), ids)), shape=(1, nE))
        Call = sp.vstack([Call, row]).tocsr()
        ball = np.r_[ball, d + np.round((val - d) / (np.pi / 2)) * np.pi / 2 - Phi0]
    return Call, ball


def _lift(S: TriSurface, features: FeatureGraph, vc: VertexCoordinates, phi, omega, normal_override: dict | None):
    """The extrinsic lift (§3.4) of the developed 2D field: (E0, omega0, the
    vertex normals used, the normals at each edge end)."""
    F, E = S.F, S.edges
    N = S.vertex_normals.copy()
    if normal_override:
        idx = np.fromiter(normal_override.keys(), dtype=np.int64)
        N[idx] = np.array([normal_override[int(i)] for i in idx])
    is_feat = features.degree > 0
    ref_next = np.roll(F, -1, axis=1).reshape(-1)[vc.ref_corner]
    r = S.V[ref_next] - S.V
    real = phi * vc.Theta / (2 * np.pi)
    E_ref = frame_from_axes(r, N)
    u = np.cos(real)[:, None] * E_ref[:, :, 0] + np.sin(real)[:, None] * E_ref[:, :, 1]
    E0 = frame_from_axes(u, N)
    # normals per edge end: at feature vertices use the normal of the sector the
    # edge lies in (the triangle normal, as in Fig. 11)
    edge_normals = np.stack([N[E[:, 0]], N[E[:, 1]]], axis=1)
    fn = S.face_normals
    ef = S.edge_faces
    side_normal = fn[ef[:, 0]] * S.face_areas[ef[:, 0], None] + fn[ef[:, 1]] * S.face_areas[ef[:, 1], None]
    side_normal /= np.linalg.norm(side_normal, axis=1, keepdims=True)
    for end in range(2):
        m = is_feat[E[:, end]] & ~features.sharp
        edge_normals[m, end] = side_normal[m]
    # fully adapted frames at feature vertices: normals of every sector plus
    # the sharp edge directions
    _adapt_feature_frames(S, features, E0)
    omega0 = _extrinsic_omega(S, features, E0, omega, edge_normals)
    _walk_corner_fans(S, features, E0, omega0)
    return E0, omega0, N, edge_normals


def lift_mismatch(S: TriSurface, bf: BoundaryField) -> np.ndarray:
    """(#F,) angle by which the lifted omega0 misses the holonomy the 2D
    field prescribes around each triangle, (K + Omega) N to first order
    (Eq. 4, 13).  It is a few hundredths of a radian on a sound mesh; a
    quarter turn where closest-rotation matching in the lift picked the
    wrong representative, as on folded boundary triangles.  Triangles at
    sharp-feature vertices (fully fixed frames, large rotations) read 0."""
    hol = np.einsum("fk,fkj->fj", S.face_edge_signs, bf.omega0[S.face_edges])
    d = np.linalg.norm(hol - (bf.K + bf.Omega)[:, None] * S.face_normals, axis=1)
    d[bf.is_feature_vertex[S.F].any(axis=1)] = 0.0
    return d


def _develop_angles(S, step, beta, reg, flab):
    """Breadth-first development of angles: phi_j = phi_i + step_ij."""
    E = S.edges
    nV = len(S.V)
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(nV, nV))
    A = (A + A.T).tocsr()
    ncomp, vlab = csgraph.connected_components(A, directed=False)
    phi = np.zeros(nV)
    keys = E[:, 0].astype(np.int64) * nV + E[:, 1]
    for c in range(ncomp):
        verts = np.nonzero(vlab == c)[0]
        feat = verts[reg[verts]]
        root = int(feat[0]) if len(feat) else int(verts[0])
        order, pred = csgraph.breadth_first_order(A, root, directed=False, return_predecessors=True)
        phi[root] = beta[root] if len(feat) else 0.0
        child = order[1:]
        par = pred[child]
        eid = np.searchsorted(keys, np.minimum(child, par) * nV + np.maximum(child, par))
        inc = np.zeros(nV)
        inc[child] = np.where(par < child, step[eid], -step[eid])
        acc = accumulate_along_tree(order, pred, inc, root_value=phi[root])
        phi[verts] = acc[verts]
    return phi


def _adapt_feature_frames(S: TriSurface, G: FeatureGraph, E0: np.ndarray) -> None:
    """Replace E0 at feature vertices by the frame best adapted to all the
    sector normals and sharp edge directions (§4.2.2 'best adapted'), choosing
    the representative closest to the lifted 2D frame."""
    feat = np.nonzero(G.degree > 0)[0]
    if len(feat) == 0:
        return
    ns, slab = G.sectors
    fn = S.face_normals_raw  # area weighted
    sec_normal = np.zeros((ns, 3))
    np.add.at(sec_normal, slab, np.repeat(fn, 3, axis=0))
    sv = G.sector_vertex
    E = S.edges[G.sharp]
    dirs_by_v: dict[int, list] = {}
    for s in range(ns):
        v = sv[s]
        if G.degree[v] > 0:
            dirs_by_v.setdefault(int(v), []).append(sec_normal[s] / np.linalg.norm(sec_normal[s]))
    for a, b in E:
        d = S.V[b] - S.V[a]
        d /= np.linalg.norm(d)
        dirs_by_v[int(a)].append(d)
        dirs_by_v[int(b)].append(-d)
    for v in feat:
        # initialise from the data (a sector normal and the next direction):
        # starting from the averaged vertex normal would sit halfway between
        # two face normals of a sharp edge, a saddle of the fit
        Ea = None
        if G.degree[v] == 2:
            Ea = _acute_crease_frame(dirs_by_v[int(v)])
        elif G.degree[v] == 3 and np.all(G.sector_quarters[sv == v] == 1):
            Ea = _cube_corner_frame(dirs_by_v[int(v)])
        if Ea is None:
            Ea = best_adapted_frame(dirs_by_v[int(v)])
        M = E0[v].T @ Ea
        tr = np.einsum("ij,kji->k", M, CUBE_GROUP)
        E0[v] = Ea @ CUBE_GROUP[np.argmax(tr)]


def _acute_crease_frame(dirs: list) -> np.ndarray | None:
    """The frame at a vertex inside a crease whose walls meet at less than 45
    degrees (their normals n1, n2 more than 135 apart), or None for other
    creases.  ``dirs``: the two sector normals, then the two edge
    directions out of the vertex.  The crease is one cell corner (a sector
    of one quarter, corners.py), so n1 and n2 go to perpendicular axes:
    the frame has the crease as an axis and n1 turned towards n2 by half
    their excess over 90 degrees as another, each normal (angle - 90) / 2
    off.  The free fit (``best_adapted_frame``) would put them on one axis
    there, the closer fit of a flat crease, which contradicts the corner's
    quarter: a triangular prism with a 40-degree corner, split into three
    quads, ended LM at its cap (penalty 6e3) with 45 degrees converging."""
    if len(dirs) != 4:
        return None
    n1, n2, e1, e2 = (np.asarray(x, float) for x in dirs)
    d = e1 - e2
    if np.linalg.norm(d) < 1e-12:
        return None
    d /= np.linalg.norm(d)
    p1, p2 = n1 - (n1 @ d) * d, n2 - (n2 @ d) * d
    if min(np.linalg.norm(p1), np.linalg.norm(p2)) < 1e-9:
        return None
    p1, p2 = p1 / np.linalg.norm(p1), p2 / np.linalg.norm(p2)
    beta = float(np.arccos(np.clip(p1 @ p2, -1.0, 1.0)))
    if beta <= 0.75 * np.pi:
        return None
    axis = np.cross(p1, p2)
    axis /= np.linalg.norm(axis)
    t = 0.5 * (beta - 0.5 * np.pi)
    x = np.cos(t) * p1 + np.sin(t) * np.cross(axis, p1)
    return frame_from_axes(x[None], d[None])[0]


def _cube_corner_frame(dirs: list) -> np.ndarray | None:
    """The frame at a convex corner of three sharp edges, each sector one
    quarter: the rotation taking the three axes to the three edges (out of
    the vertex) and each sector normal to minus the axis of the edge it
    does not touch, in the least-squares sense (orthogonal Procrustes with
    that assignment).  ``dirs``: the three sector normals, then the three
    edge directions.  The free fit may pair an acute corner's edges with one
    axis (the flat reading), which contradicts its quarters (the
    triangular prism of ``_acute_crease_frame``)."""
    if len(dirs) != 6:
        return None
    D = np.asarray(dirs, float)
    N, Ed = D[:3], D[3:]
    # the edges to x, y and z, right-handed
    T = np.eye(3)[[0, 1, 2] if np.linalg.det(Ed) > 0 else [1, 0, 2]]  # the target axis of each edge
    # a sector's normal is perpendicular to its two edges: minus the third's axis
    side = np.argmax(np.abs(N @ Ed.T), axis=1)
    if len(set(side.tolist())) != 3:
        return None
    Tn = -T[side]
    B = Ed.T @ T + N.T @ Tn
    U, _, Vt = np.linalg.svd(B)
    R = U @ Vt
    if np.linalg.det(R) < 0:
        U[:, -1] *= -1
        R = U @ Vt
    return R


def _extrinsic_omega(S, G: FeatureGraph, E0, omega2d, edge_normals):
    """omega0_ij: the exact rotation between E0_i and the representative of
    E0_j closest to the prediction log(Q_ij) + omega_ij N_i (§3.4).

    Q_ij is the smallest rotation between the normals used at i and j; on
    sharp edges and edges at sharp corners the prediction is the plain
    smallest rotation (no 2D angle), since there the 2D coordinates are
    distorted by the angle normalisation.
    """
    E = S.edges
    Ni, Nj = edge_normals[:, 0], edge_normals[:, 1]
    logQ = minimal_rotation(Ni, Nj)
    pred = logQ + omega2d[:, None] * Ni
    at_corner = np.zeros(len(S.V), bool)
    at_corner[G.corners] = True
    plain = at_corner[E[:, 0]] | at_corner[E[:, 1]]
    pred[plain] = logQ[plain]
    # along a sharp edge both frames are fully adapted: take the smallest turn
    pred[G.sharp] = 0.0
    Ei, Ej = E0[E[:, 0]], E0[E[:, 1]]
    # candidates R_g = E_j g E_i^T for the 24 symmetries
    R = np.einsum("nij,gjk,nlk->ngil", Ej, CUBE_GROUP, Ei)
    P = exp_so3(pred)
    # distance between R_g and the prediction: angle of R_g P^T, via traces
    tr = np.einsum("ngij,nij->ng", R, P)
    best = np.argmax(tr, axis=1)
    Rb = R[np.arange(len(E)), best]
    return unwrap_rotvec(log_so3(Rb), pred)


def _walk_corner_fans(S: TriSurface, G: FeatureGraph, E0, omega0) -> None:
    """Choose omega0 on the smooth spokes of sharp corners by walking each
    sector's fan from its first sharp edge, so that every triangle of the
    fan closes (in place).

    _extrinsic_omega predicts a corner spoke by the smallest rotation alone:
    the corner's 2D coordinates are rescaled, so omega_ij says little there.
    Where the 2D field turns fast next to a corner (a concave corner of a
    hole, with a singular pair through the solid twisting the field across
    the arm) the nearest representative was then a quarter turn off on a
    triangle by the corner, and LM ended at its cap with a penalty of 1e4.
    Across the fan's outer edges and along sharp edges omega0 is reliable;
    the spoke c -> b of triangle (c, a, b) is the representative of E0_b
    nearest to R_ab R_ca.
    """
    corners = G.corners
    if len(corners) == 0:
        return
    F = S.F
    nV = len(S.V)
    fe = S.face_edges
    sharp = G.sharp
    is_corner = np.zeros(nV, bool)
    is_corner[corners] = True
    cw = corner_fan_links(S)
    ccw = np.empty_like(cw)
    ccw[cw] = np.arange(len(cw))

    def rot(i, j):
        e = S.edge_index(i, j)
        R = exp_so3(omega0[e])
        return np.where((i < j)[:, None, None], R, np.transpose(R, (0, 2, 1)))

    flat = np.arange(3 * len(F))
    cur = flat[is_corner[F.reshape(-1)] & sharp[fe.reshape(-1)]]
    for _ in range(64):
        f, k = cur // 3, cur % 3
        go = ~sharp[fe[f, (k + 2) % 3]]
        cur, f, k = cur[go], f[go], k[go]
        if len(cur) == 0:
            break
        # a spoke to another corner keeps its smallest rotation (both frames
        # are fully adapted); the walk goes on past it
        own = ~is_corner[F[f, (k + 2) % 3]]
        c, a, b = F[f[own], k[own]], F[f[own], (k[own] + 1) % 3], F[f[own], (k[own] + 2) % 3]
        pred = rot(a, b) @ rot(c, a)
        cand = np.einsum("nij,gjk,nlk->ngil", E0[b], CUBE_GROUP, E0[c])
        best = np.argmax(np.einsum("ngij,nij->ng", cand, pred), axis=1)
        Rcb = cand[np.arange(len(c)), best]
        R = np.where((c < b)[:, None, None], Rcb, np.transpose(Rcb, (0, 2, 1)))
        e = S.edge_index(c, b)
        omega0[e] = unwrap_rotvec(log_so3(R), omega0[e])
        cur = ccw[cur]

