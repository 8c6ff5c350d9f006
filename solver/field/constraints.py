"""The linear constraints of Eq. 23, as an affine parametrisation
omega = c + P x of the so(3) value on every edge.

Edge kinds, in order of priority:

* boundary edges (Eq. 20): omega = omega0 + (alpha_j - alpha_i) (N_i + N_j)/2,
  with alpha = 0 at sharp-feature vertices, whose frames are fully fixed;
  an edge with both ends on sharp features is fixed, omega = omega0 (§4.2.2);
* tube edges -- interior edges of the tets a curve crosses (see embed.py):
  free torsion (Eq. 21): omega = omega0 + beta_e T_e with beta_e free;
  fixed torsion (Eq. 22): omega = omega0 + (gamma_j - gamma_i + sigma theta_ij) T_e,
  with theta_ij the change of the polar angle around the curve, so the
  prescribed winding is carried and the total torsion is that of E0;
* all other edges are free: three unknowns each.

x is laid out as [3 per free edge | alpha | beta | gamma].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..linalg.rotations import exp_so3, log_so3
from ..mesh.embed import Embedding
from ..mesh.tetmesh import TetMesh
from ..network.curves import CurveGeometry
from ..network.network import PreparedNetwork, Torsion
from ..network.polyline import resample
from .boundary2d import BoundaryField, wrap
from .structure import StructureEquation

FREE, BOUNDARY, FIXED, TUBE = 0, 1, 2, 3

END_FREE = 1.5
"""Tube edges whose midpoint lies within this many edge lengths (of the
boundary triangle where the curve ends) of a singular curve's end on the
boundary are left free.  There the boundary frames are adapted to the surface
normals (Eq. 20) and the tube's to the curve tangent (Eq. 21), which differ
by the curve's remaining bend and by the surface's curvature across the
end's triangles; constrained to both, the faces of the last tets cannot
close (Eq. 17): on the cube-sphere network of an ellipsoid, radial curves
0.25 long and 22 degrees off the normal in the input, LM ended with the
structure penalty 17-71 against the discretisation level 8-11, 90 % of it
within an edge of the ends; with these edges free, 1.5-6.3 (3 meshes), and
the hex mesh valid with the curves exactly the irregular edges.  The curve
still winds as prescribed (its pierced faces carry Omega, §4.2.2) and
meets the surface along the normal (the intake bends it so).  A feature
curve (sigma = 0) keeps its adaptation to the end: no quarter turn of the
boundary field is packed around its end, and following it is its point."""


@dataclass
class AffineOmega:
    """omega (#E, 3) = c + (P @ x).reshape(#E, 3).

    kind        : (#E,) FREE / BOUNDARY / FIXED / TUBE
    free_edges  : edges with three unknowns, in the order of x
    alpha_vertices : global vertex ids carrying alpha (Eq. 20)
    tube_curve  : (#E,) curve id of tube edges, -1 elsewhere
    tube_tangent: (#E, 3) T_e on tube edges
    tube_reference : (#E, 3) on tube edges, omega of the reference field
                  adapted to the curve and winding around it as prescribed:
                  omega0 + sigma theta T_e (tube_curvature)
    n_alpha, n_beta, n_gamma : sizes of the parameter blocks
    """

    c: np.ndarray
    P: sp.csr_matrix
    kind: np.ndarray
    free_edges: np.ndarray
    alpha_vertices: np.ndarray
    tube_curve: np.ndarray
    tube_tangent: np.ndarray
    tube_reference: np.ndarray
    n_alpha: int
    beta_edges: np.ndarray  # tube edges with free torsion, in the order of the beta block
    n_beta: int
    n_gamma: int
    fixed_frame_vertices: np.ndarray  # global ids whose frame is E0 exactly
    gauge_vertices: np.ndarray  # global ids of free boundary vertices whose alpha is fixed to 0
    alpha_group: np.ndarray  # (#bV,) local id of the representative of each boundary vertex's alpha
    alpha_column: np.ndarray  # (#bV,) column of x holding each boundary vertex's alpha, -1 if none

    @property
    def n_unknowns(self) -> int:
        return self.P.shape[1]

    def omega(self, x: np.ndarray) -> np.ndarray:
        return self.c + (self.P @ x).reshape(-1, 3)

    def x_from_omega(self, omega: np.ndarray) -> np.ndarray:
        """Least-squares x for a given omega (exact on free edges); used to
        start from an arbitrary field."""
        A = self.P.T @ self.P
        rhs = self.P.T @ (omega - self.c).reshape(-1)
        d = A.diagonal()
        # P has orthogonal column blocks except alpha/gamma couplings: a few
        # Jacobi-preconditioned CG steps give the projection
        from scipy.sparse.linalg import cg

        x, _ = cg(A + 1e-12 * sp.eye(A.shape[0]), rhs, M=sp.diags(1.0 / np.maximum(d, 1e-30)), rtol=1e-12,
                  maxiter=2000)
        return x


def build_constraints(
    mesh: TetMesh,
    net: PreparedNetwork,
    emb: Embedding,
    bfield: BoundaryField,
) -> AffineOmega:
    """omega = c + P x: the boundary edges (Eq. 20), the curve tubes' edges
    (Eq. 21, 22) and the free edges parametrised by the unknowns x.

    Parameters
    ----------
    mesh : TetMesh
    net : PreparedNetwork
        The curves' indices and torsion modes.
    emb : Embedding
        The network traced through the mesh (tubes, curve ends).
    bfield : BoundaryField
        The boundary data: E0, omega0 and the normals of Eq. 20.

    Returns
    -------
    AffineOmega
    """
    nE = mesh.n_edges
    kind = np.full(nE, FREE, dtype=np.int8)
    c = np.zeros((nE, 3))
    entries = []  # (rows, columns, values) blocks of P, in column order
    # ---------------------------------------------------------- boundary (Eq. 20)
    bv = mesh.boundary_vertices
    B = mesh.boundary
    ge = mesh.edge_index(bv[B.edges[:, 0]], bv[B.edges[:, 1]])
    assert np.all(ge >= 0)
    fixed_v_local = bfield.is_feature_vertex
    both_fixed = fixed_v_local[B.edges[:, 0]] & fixed_v_local[B.edges[:, 1]]
    kind[ge] = np.where(both_fixed, FIXED, BOUNDARY)
    c[ge] = bfield.omega0
    # alpha unknowns at boundary vertices that are not on sharp features.  The
    # three vertices of the triangle where a curve ends share one alpha: the
    # 2D field splits the quarter turn evenly over that triangle's edges, and
    # the volume solve may rotate that local structure but not unbalance it
    # (an uneven split makes edges turn by ~45 degrees, where closest-rotation
    # matching of the crosses becomes ambiguous).
    free_local = ~fixed_v_local
    group = _alpha_groups(B, free_local, [np.searchsorted(mesh.boundary_faces, f) for f, _ in emb.boundary_end_faces])
    alpha_local = _alpha_after_gauge(B, free_local, group)
    # ------------------------------------------------------------------ tubes
    tube_curve, tube_T, tube_omega0, tube_theta, turns = _tube_edges(mesh, net, emb, kind, bfield.normals)
    is_tube = tube_curve >= 0
    kind[is_tube] = TUBE
    c[is_tube] = tube_omega0[is_tube]
    # sigma per edge (0 off the tubes; the appended 0 is what tube_curve = -1 picks)
    sigma_e = np.where(is_tube, np.array([cv.sigma for cv in net.curves] + [0.0], float)[tube_curve], 0.0)
    sig_e = sigma_e[is_tube]
    tube_ref = np.zeros((nE, 3))
    tube_ref[is_tube] = tube_omega0[is_tube] + (sig_e * tube_theta[is_tube])[:, None] * tube_T[is_tube]
    _settle_windings(mesh, emb, tube_curve, sigma_e, tube_T, tube_theta, turns, tube_ref)
    # -------------------------------------------------------------- free edges
    free_edges = np.nonzero(kind == FREE)[0]
    nfree = len(free_edges)
    for k in range(3):
        entries.append((3 * free_edges + k, 3 * np.arange(nfree) + k, np.ones(nfree)))
    col = 3 * nfree
    alpha_col_local, reps = _alpha_columns(B, ge, both_fixed, bfield.edge_normals, group, alpha_local, col, entries)
    col += len(reps)
    beta_edges, n_gamma, col = _tube_columns(net, mesh.edges, np.nonzero(is_tube)[0], tube_curve, tube_T,
                                             tube_theta, c, col, entries)
    rows, cols, vals = zip(*entries)
    P = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(3 * nE, col)
    )
    return AffineOmega(
        c=c,
        P=P,
        kind=kind,
        free_edges=free_edges,
        alpha_vertices=bv[reps],  # representative of each alpha group
        tube_curve=tube_curve,
        tube_tangent=tube_T,
        tube_reference=tube_ref,
        n_alpha=len(reps),
        beta_edges=beta_edges,
        n_beta=len(beta_edges),
        n_gamma=n_gamma,
        fixed_frame_vertices=bv[fixed_v_local],
        gauge_vertices=bv[free_local & (alpha_col_local < 0)],
        alpha_group=group,
        alpha_column=alpha_col_local,
    )


def _alpha_columns(B, ge, both_fixed, edge_normals, group, alpha_local, col: int, entries: list):
    """The alpha columns of P from column ``col`` on (Eq. 20), one per alpha
    group that keeps its unknown, appended to entries.  Returns (the column
    of each boundary vertex's alpha, -1 if none; the groups' representative
    vertices)."""
    reps = np.unique(group[alpha_local])
    rep_col = np.full(len(B.V), -1)
    rep_col[reps] = col + np.arange(len(reps))
    alpha_col_local = np.where(alpha_local, rep_col[group], -1)
    bnd = np.nonzero(~both_fixed)[0]
    nrm = 0.5 * (edge_normals[bnd, 0] + edge_normals[bnd, 1])
    for end, sign in ((0, -1.0), (1, 1.0)):
        v = B.edges[bnd, end]
        cc = alpha_col_local[v]
        ok = cc >= 0
        for k in range(3):
            entries.append((3 * ge[bnd[ok]] + k, cc[ok], sign * nrm[ok, k]))
    return alpha_col_local, reps


def _tube_columns(net: PreparedNetwork, E, tube_edges, tube_curve, tube_T, tube_theta, c, col: int, entries: list):
    """The tube columns of P from column ``col`` on, appended to entries:
    one beta per edge of a curve with free torsion (Eq. 21), one gamma per
    (curve, vertex) of a curve with fixed torsion (Eq. 22), whose winding
    goes into c.  Returns (the edges with a beta, in column order; the
    number of gammas; the next free column)."""
    beta_edges = np.zeros(0, dtype=np.int64)
    n_gamma = 0
    if not len(tube_edges):
        return beta_edges, n_gamma, col
    fixed_t = np.array([net.curves[tube_curve[e]].torsion == Torsion.FIXED for e in tube_edges], bool)
    # free torsion: one beta per edge (Eq. 21)
    beta_edges = tube_edges[~fixed_t]
    for k in range(3):
        entries.append((3 * beta_edges + k, col + np.arange(len(beta_edges)), tube_T[beta_edges, k]))
    col += len(beta_edges)
    # fixed torsion: gamma per (curve, vertex) (Eq. 22), winding in c
    xe = tube_edges[fixed_t]
    if len(xe):
        sig = np.array([net.curves[tube_curve[e]].sigma for e in xe])
        c[xe] += (sig * tube_theta[xe])[:, None] * tube_T[xe]
        key = np.stack([np.repeat(tube_curve[xe], 2), E[xe].reshape(-1)], axis=1)
        uk, inv = np.unique(key, axis=0, return_inverse=True)
        inv = inv.reshape(-1, 2)
        # one gauge per curve: drop the first gamma of each curve
        first = np.r_[True, uk[1:, 0] != uk[:-1, 0]]
        gcol = np.cumsum(~first) - 1
        gcol[first] = -1
        n_gamma = int((~first).sum())
        for end, sign in ((0, -1.0), (1, 1.0)):
            cc = gcol[inv[:, end]]
            ok = cc >= 0
            for k in range(3):
                entries.append((3 * xe[ok] + k, col + cc[ok], sign * tube_T[xe[ok], k]))
        col += n_gamma
    return beta_edges, n_gamma, col


def _alpha_groups(B, free_local, cap_faces) -> np.ndarray:
    """Representative vertex of each vertex's alpha: the free vertices of a
    curve-end triangle are merged."""
    n = len(B.V)
    parent = np.arange(n)

    def find(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    for f in cap_faces:
        tri = [v for v in B.F[f] if free_local[v]]
        for v in tri[1:]:
            a, b = find(tri[0]), find(v)
            if a != b:
                parent[max(a, b)] = min(a, b)
    return np.array([find(v) for v in range(n)])


def _alpha_after_gauge(B, free_local, group):
    """Which free boundary vertices keep an alpha unknown: all of them.

    Adding a constant to alpha on a component without sharp features does
    not change omega (Eq. 20 uses differences), an exact null direction of
    the LM systems.  Pinning one vertex would remove it but leave the nearly
    null "constant except at one vertex" mode that stalls PCG; the damped
    systems are regular and PCG ignores the null direction, so we keep it.
    """
    return free_local.copy()


def _polar_angle(X: np.ndarray, C: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Polar angle of points X around curve points C, in the reference
    frames F (n, 3, 3) there (first two columns across the curve)."""
    r = X - C
    return np.arctan2(np.einsum("ij,ij->i", r, F[:, :, 1]), np.einsum("ij,ij->i", r, F[:, :, 0]))


def _edge_winding(geo: CurveGeometry, XA: np.ndarray, XB: np.ndarray, samples: int = 9) -> np.ndarray:
    """The angle (wrapped) by which edges XA -> XB wind around the curve,
    seen from the curve's point Q nearest to each edge: A and B projected
    along the tangent at Q, in the reference frame there.

    _tube_edges measures theta per vertex (each end in the frame of its own
    nearest curve point), so that it comes from one reference field and the
    windings of a face's three edges add up to a whole number of turns --
    but not always the right one: where the curve crosses an oblique face
    close to one of its edges, the ends' nearest points lie apart along the
    curve and the face wound 0 times where the curve pierces it.  Seen from
    Q, an edge the curve passes close to subtends nearly half a turn on the
    side where the curve passes.  Used alone this angle is not one field's
    (its face sums are not whole turns), so it only proposes another branch
    for the per-vertex angle (_settle_windings).  On a straight curve both
    agree exactly."""
    u = np.linspace(0.0, 1.0, samples)
    P = XA[:, None, :] + u[None, :, None] * (XB - XA)[:, None, :]
    seg, t, d = geo.closest(P.reshape(-1, 3))
    k = np.argmin(d.reshape(len(XA), samples), axis=1) + samples * np.arange(len(XA))
    Q, F = geo.point(seg[k], t[k]), geo.frame(seg[k], t[k])
    return wrap(_polar_angle(XB, Q, F) - _polar_angle(XA, Q, F))


def _tube_edges(mesh: TetMesh, net: PreparedNetwork, emb: Embedding, kind, bnormals):
    """Curve, tangent, reference derivative and winding angle per tube edge."""
    nE = mesh.n_edges
    E = mesh.edges
    X = mesh.vertices
    tube_curve = np.full(nE, -1, dtype=np.int64)
    tube_T = np.zeros((nE, 3))
    omega0 = np.zeros((nE, 3))
    theta = np.zeros(nE)
    turns = np.zeros(nE)
    best = np.full(nE, np.inf)
    node_tets = emb.node_region_tets
    node_verts = np.unique(mesh.tets[node_tets]) if len(node_tets) else np.zeros(0, int)
    excluded_v = np.zeros(mesh.n_vertices, bool)
    excluded_v[node_verts] = True
    is_bnd = mesh.is_boundary_vertex
    normals = np.zeros((mesh.n_vertices, 3))
    normals[mesh.boundary_vertices] = bnormals
    for ci, (curve, tr) in enumerate(zip(net.curves, emb.traces)):
        tets = np.setdiff1d(tr.tets, node_tets)
        if len(tets) == 0:
            continue
        edges = np.unique(mesh.tet_edges[tets].reshape(-1))
        edges = edges[(kind[edges] == FREE) & ~excluded_v[E[edges, 0]] & ~excluded_v[E[edges, 1]]]
        if len(edges) == 0:
            continue
        geo = CurveGeometry(tr.polyline, curve.closed)
        mid = 0.5 * (X[E[edges, 0]] + X[E[edges, 1]])
        s, t, d = geo.closest(mid)
        # A boundary vertex's frame is adapted to its normal N (Eq. 20).  Where
        # the tangent is neither along N nor across it (a curve ending on a
        # curved surface: N and T differ by ~ tube radius / curvature radius),
        # both adaptations cannot hold, so such edges are left free.
        Tm = geo.tangent(s, t)
        ok = np.ones(len(edges), bool)
        for end in range(2):
            v = E[edges, end]
            b = is_bnd[v]
            if np.any(b):
                c = np.abs(np.einsum("ij,ij->i", Tm[b], normals[v[b]]))
                compatible = (c > np.cos(np.radians(1.0))) | (c < np.sin(np.radians(1.0)))
                ok[np.nonzero(b)[0][~compatible]] = False
        # ... and so are those near a singular curve's ends on the boundary
        # (END_FREE): the surface, whose frames are adapted to its normals,
        # takes over the curve's adaptation there
        for f, k in ((tr.start_face, 0), (tr.end_face, -1)):
            if f >= 0 and curve.sigma != 0:
                h_end = float(np.mean(mesh.edge_lengths[mesh.face_edges[f]]))
                ok &= np.linalg.norm(mid - tr.polyline[k], axis=1) > END_FREE * h_end
        edges, s, t, d = edges[ok], s[ok], t[ok], d[ok]
        better = d < best[edges]
        edges, s, t, d = edges[better], s[better], t[better], d[better]
        if len(edges) == 0:
            continue
        best[edges] = d
        tube_curve[edges] = ci
        tube_T[edges] = geo.tangent(s, t)
        si, ti, _ = geo.closest(X[E[edges, 0]])
        sj, tj, _ = geo.closest(X[E[edges, 1]])
        Fi, Fj = geo.frame(si, ti), geo.frame(sj, tj)
        omega0[edges] = log_so3(np.einsum("nij,nkj->nik", Fj, Fi))
        # polar angle of each end around the curve, in its own reference frame
        th = wrap(_polar_angle(X[E[edges, 1]], geo.point(sj, tj), Fj)
                  - _polar_angle(X[E[edges, 0]], geo.point(si, ti), Fi))
        theta[edges] = th
        # the whole turns by which the edge winds otherwise seen from the curve
        # (_edge_winding): a candidate for _settle_windings
        turns[edges] = np.round((_edge_winding(geo, X[E[edges, 0]], X[E[edges, 1]]) - th) / (2.0 * np.pi))
    return tube_curve, tube_T, omega0, theta, turns


def _settle_windings(mesh: TetMesh, emb: Embedding, tube_curve, sigma_e, tube_T, theta, turns, ref) -> int:
    """Add the whole turns of _edge_winding to the tube edges where that
    makes the curve wind around the tube faces as it pierces them.

    theta (per vertex) winds a whole number of times around every face, and
    the reference field's structure residual on a tube face (all three
    edges on one curve's tube) is 2 pi sigma T times that number less the
    pierce count: ~pi/2 off for a quarter-turn curve that pierces the face
    but winds 0 times around it.  An edge where the two measures of theta
    disagree takes the other branch if that lowers the summed mismatch of
    its tube faces by at least a quarter of 2 pi sigma.  Edges the curve
    passes within round-off of (the embedding's perturbation) disagree too,
    and there the pierces decide.  theta and ref are updated in place;
    returns the number of edges changed.

    Measured on meshes graded towards bent curves (a sizing field of a
    third of the radius of curvature, not the default): the 2 x 1 x 0.6
    ellipsoid of tube_curvature had 50 of its 851 tube faces winding wrong
    (30 of them pierced; penalty 275-278, not converged), 6 after this
    (penalty 5.3 and 47 on two meshes); the bowed ball 3 of 244, then 0.
    On the same networks' default (ungraded) meshes no face winds wrong."""
    cand = np.nonzero((tube_curve >= 0) & (turns != 0) & (sigma_e != 0))[0]
    if len(cand) == 0:
        return 0
    fe = mesh.face_edges
    tc = tube_curve[fe]
    tf = np.nonzero((tc[:, 0] >= 0) & (tc[:, 0] == tc[:, 1]) & (tc[:, 1] == tc[:, 2]) & ~emb.face_excluded)[0]
    fe_t = fe[tf]
    changed = 0
    for e in cand:
        F = tf[(fe_t == e).any(axis=1)]
        if len(F) == 0:
            continue
        se = StructureEquation(fe[F], mesh.corner_weights[F], emb.face_omega[F], mesh.n_edges)
        before = np.linalg.norm(se.residual(ref), axis=1).sum()
        old = ref[e].copy()
        ref[e] = old + (sigma_e[e] * 2.0 * np.pi * turns[e]) * tube_T[e]
        after = np.linalg.norm(se.residual(ref), axis=1).sum()
        if after < before - 0.25 * abs(2.0 * np.pi * sigma_e[e]):
            theta[e] += 2.0 * np.pi * turns[e]
            changed += 1
        else:
            ref[e] = old
    return changed


RING_RADIUS = 1.5  # tube_curvature: vertices at most this many edge lengths (around the tube) from their curve


def tube_curvature(mesh: TetMesh, cons: AffineOmega, emb: Embedding, net: PreparedNetwork) -> np.ndarray:
    """(#F, 3) Omega_f of the structure equation (Eq. 17/19) on every face.

    emb.face_omega prescribes 2 pi sigma T on the faces a curve pierces and
    0 elsewhere (§4.2.2).  Next to a bent singular curve that is not what
    the discrete equation asks of a field adapted to it.  On a tube face,
    omega is omega0 + beta T_e on each edge (Eq. 21/22); T_e differs between
    the edges by ~kappa h while beta winds by up to a quarter turn around the
    curve, these rotations do not commute, and the wedge of Eq. 18 (exact
    for commuting rotations: a straight curve) is off by O(beta^2 kappa h).
    The faces around the tube see the same winding and the same error.
    So no field adapted to a bent curve satisfies the equation there, and
    LM paid for it on every face near the curve.

    Here Omega_f near each curve is the value of Eq. 17 (with Omega = 0)
    of the curve's reference field: on tube edges cons.tube_reference
    (omega0 + sigma theta T_e, inside the constraints), on the other edges
    of the tets around the tube the exact rotation between the frames
    E^0 exp(sigma phi) at the vertices' nearest curve points (phi the polar
    angle around the curve).  This covers faces whose three edges belong to
    one curve, between vertices nearer to it than to any other curve, within
    RING_RADIUS edge lengths of it, off the node regions, the boundary and the
    curve's ends.  The equation then holds exactly for the reference field,
    and on a straight curve, where it turns about one axis, this is
    face_omega itself.  A face where the two differ by more than an eighth
    of a turn (a polar angle wrapped the other way across the curve) keeps
    face_omega.  Measured (default options, limitations.md): the
    cube-sphere ball with its radial curves bowed by 0.45 scored 13.4 (9.9
    on tube faces), 3.5 with tube faces alone corrected, 1.6 with the ring
    around them; the network stretched into a 2 x 1 x 0.6 ellipsoid, its
    radial curves bent onto the normal from 50 degrees off, 160-172 and 33."""
    Om = emb.face_omega.copy()
    E, X = mesh.edges, mesh.vertices
    tube = cons.kind == TUBE
    owner = np.where(tube, cons.tube_curve, -1)
    ref = cons.tube_reference.copy()
    node_tets = emb.node_region_tets
    off = mesh.is_boundary_vertex.copy()
    if len(node_tets):
        off[mesh.tets[node_tets].reshape(-1)] = True
    # the nearest curve of a vertex, from points every quarter edge along each
    step = 0.25 * float(np.median(mesh.edge_lengths))
    lines = [resample(tr.polyline, step) for tr in emb.traces]
    if lines:
        nearest_tree = cKDTree(np.vstack(lines))
        nearest_label = np.concatenate([np.full(len(P), ci) for ci, P in enumerate(lines)])
    for ci, tr in enumerate(emb.traces):
        own = np.nonzero(owner == ci)[0]
        tets = np.setdiff1d(tr.tets, node_tets)
        if len(own) == 0 or len(tets) == 0:
            continue
        near_tube = np.zeros(mesh.n_vertices, bool)
        near_tube[mesh.tets[tets].reshape(-1)] = True
        ring = np.setdiff1d(np.nonzero(near_tube[mesh.tets].any(axis=1))[0], node_tets)
        edges = np.unique(mesh.tet_edges[ring].reshape(-1))
        reach = RING_RADIUS * float(np.median(mesh.edge_lengths[edges]))
        edges = edges[(owner[edges] < 0) & (cons.kind[edges] == FREE)]
        verts = np.unique(E[edges].reshape(-1))
        verts = verts[~off[verts]]
        if len(edges) == 0 or len(verts) == 0:
            continue
        geo = CurveGeometry(tr.polyline, net.curves[ci].closed)
        seg, t, d = geo.closest(X[verts])
        at_end = ((seg == 0) & (t <= 0.0)) | ((seg == len(geo.P) - 2) & (t >= 1.0))
        if net.curves[ci].closed:
            at_end[:] = False
        ok = (d < reach) & ~at_end & (nearest_label[nearest_tree.query(X[verts])[1]] == ci)
        good = np.zeros(mesh.n_vertices, bool)
        good[verts[ok]] = True
        edges = edges[good[E[edges, 0]] & good[E[edges, 1]]]
        if len(edges) == 0:
            continue
        si, ti, _ = geo.closest(X[E[edges, 0]])
        sj, tj, _ = geo.closest(X[E[edges, 1]])
        Fi, Fj = geo.frame(si, ti), geo.frame(sj, tj)

        turn = net.curves[ci].sigma * wrap(_polar_angle(X[E[edges, 1]], geo.point(sj, tj), Fj)
                                           - _polar_angle(X[E[edges, 0]], geo.point(si, ti), Fi))
        z = np.zeros((len(edges), 3))
        z[:, 2] = turn
        # E_j E_i^T for E = F exp(sigma phi e_z) E0
        ref[edges] = log_so3(np.einsum("nij,njk,nlk->nil", Fj, exp_so3(z), Fi))
        owner[edges] = ci
    fe = mesh.face_edges
    o = owner[fe]
    faces = np.nonzero((o[:, 0] >= 0) & (o[:, 0] == o[:, 1]) & (o[:, 1] == o[:, 2]) & ~emb.face_excluded)[0]
    if len(faces) == 0:
        return Om
    se = StructureEquation(fe[faces], mesh.corner_weights[faces], np.zeros((len(faces), 3)), mesh.n_edges)
    r = se.residual(ref)
    keep = np.linalg.norm(r - Om[faces], axis=1) < np.pi / 8
    Om[faces[keep]] = r[keep]
    return Om
