"""Tests of solver/analysis/measures.py on fields with a known answer: a constant
field, fields built from a known rotation per vertex, and fields with one
known singular line or loop, on structured tet meshes built here.  The
measurements are checked before they judge the solver (bench/validation_report.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from solver.analysis.measures import (
    axis_alignment,
    curve_tangent_adaptation,
    darboux_derivative,
    dual_face_weights,
    edge_matchings,
    face_frame_differences,
    face_monodromy,
    group_singular_faces,
    init_independence,
    karcher_smoothing,
    loglog_slope,
    matched_singular_faces,
    monodromy_angles,
    normal_adaptation,
    omega_frame_mismatch,
    omega_singular_faces,
    pick_roots,
    root_independence,
    singular_structure,
    smoothing_check,
    smoothness,
    structure_residual,
    tet_frames,
    vertices_near_polylines,
)
from solver.field.matchings import omega_matchings
from solver.linalg.rotations import CUBE_GROUP, cross_distance, exp_so3, rotation_angle
from solver.mesh.tetmesh import TetMesh
from tests.meshes import box_mesh


# ------------------------------------------------------------------ helpers
def rz(angles):
    v = np.zeros((len(angles), 3))
    v[:, 2] = angles
    return Rotation.from_rotvec(v).as_matrix()


def rx(angles):
    v = np.zeros((len(angles), 3))
    v[:, 0] = angles
    return Rotation.from_rotvec(v).as_matrix()


def smooth_rotvec(X):
    """A smooth, non-commuting rotation field (rotation vectors, < 1 rad)."""
    x, y, z = X.T
    return 0.6 * np.c_[np.sin(1.3 * x + 0.4 * y), np.cos(0.9 * y - 0.7 * z) - 0.5, np.sin(1.1 * z + 0.8 * x * y)]


def pierced_faces(mesh: TetMesh, P: np.ndarray) -> np.ndarray:
    """Faces crossed by the polyline P (brute force, Moller-Trumbore)."""
    X = mesh.vertices[mesh.faces]
    a, e1, e2 = X[:, 0], X[:, 1] - X[:, 0], X[:, 2] - X[:, 0]
    hit = np.zeros(mesh.n_faces, bool)
    for p, q in zip(P[:-1], P[1:]):
        d = q - p
        h = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, h)
        ok = np.abs(det) > 1e-14
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = p - a
        u = inv * np.einsum("ij,ij->i", s, h)
        qv = np.cross(s, e1)
        v = inv * (qv @ d)
        t = inv * np.einsum("ij,ij->i", e2, qv)
        hit |= ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)
    return np.nonzero(hit)[0]


# Generic positions: the singular curves pass through no mesh vertex or edge.
LINE_XY = np.array([0.4137, 0.5291])
# The loop keeps 0.035 (sagitta of a diagonal chord: 0.012) from the
# vertical grid lines, so the faces it pierces are those the vertex-sampled
# field turns around.
LOOP_C, LOOP_R, LOOP_Z = np.array([0.4992, 0.5010]), 0.3159, 0.4633


def line_field(mesh):
    """E = Rz(theta / 4) around the vertical line through LINE_XY: index +1/4
    about +z (counter-clockwise seen from +z the field turns by +pi/2)."""
    d = mesh.vertices[:, :2] - LINE_XY
    theta = np.arctan2(d[:, 1], d[:, 0])
    polyline = np.array([[*LINE_XY, -0.1], [*LINE_XY, 1.1]])
    return rz(theta / 4), polyline


def loop_field(mesh):
    """E = Rz(theta / 4) with theta the polar angle around a horizontal circle
    in its meridian half-plane, atan2(z - z0, rho - R): theta jumps by 2 pi
    across the disk, so the cross makes a quarter turn about z around the
    circle (a singular loop whose axis is normal to its plane)."""
    X = mesh.vertices
    rho = np.linalg.norm(X[:, :2] - LOOP_C, axis=1)
    theta = np.arctan2(X[:, 2] - LOOP_Z, rho - LOOP_R)
    phi = np.linspace(0, 2 * np.pi, 721)
    P = np.c_[LOOP_C[0] + LOOP_R * np.cos(phi), LOOP_C[1] + LOOP_R * np.sin(phi), np.full(len(phi), LOOP_Z)]
    P[-1] = P[0]
    return rz(theta / 4), P


@pytest.fixture(scope="module")
def mesh6():
    return box_mesh(6)


@pytest.fixture(scope="module")
def mesh8():
    return box_mesh(8)


# ------------------------------------------------------------ constant field
def test_constant_field_measures_zero(mesh6):
    m = mesh6
    E = np.broadcast_to(Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix(), (m.n_vertices, 3, 3)).copy()
    om = darboux_derivative(m, E)
    assert np.abs(om).max() < 1e-12
    assert monodromy_angles(m, om).max() < 1e-12
    assert structure_residual(m, om).max() < 1e-12
    ss = singular_structure(m, E)
    assert len(ss.faces) == 0 and ss.curves == []
    roots = pick_roots(m, 2, 2)
    assert len(roots) == 4 and len(set(roots.tolist())) == 4
    ri = root_independence(m, om, E, roots)
    assert ri.max_deg < 1e-9
    phi_t, phi_h = smoothness(m, E)
    assert phi_t < 1e-6 and phi_h < 1e-6
    chk = smoothing_check(m, E, iterations=3)
    assert chk["max_change_deg"] < 1e-8


def test_adaptation_of_a_rotated_constant_field(mesh6):
    m = mesh6
    beta = 0.2
    E = rx(np.full(m.n_vertices, beta))
    bv = m.boundary_vertices
    X = m.vertices[bv]
    on_edge = (np.isclose(X, 0) | np.isclose(X, 1)).sum(axis=1) > 1
    ang = normal_adaptation(m, E)
    top = np.isclose(X[:, 2], 1) & ~on_edge
    side = np.isclose(X[:, 0], 0) & ~on_edge
    # z and y axes are tilted by beta about x; the x axis is untouched
    np.testing.assert_allclose(ang[top], beta, atol=1e-12)
    np.testing.assert_allclose(ang[side], 0.0, atol=1e-12)
    # explicit normals and a vertex subset
    v = bv[top][:3]
    np.testing.assert_allclose(normal_adaptation(m, E, np.tile([0, 0, -1.0], (len(bv), 1)), v), beta, atol=1e-12)
    # tangents: a straight line along z, then a circle with tangent-adapted frames
    pts = np.random.default_rng(0).uniform(0, 1, (20, 3))
    line = np.array([[0.5, 0.5, 0.0], [0.5, 0.5, 1.0]])
    np.testing.assert_allclose(curve_tangent_adaptation(pts, rx(np.full(20, beta)), line), beta, atol=1e-12)
    np.testing.assert_allclose(curve_tangent_adaptation(pts, rx(np.full(20, 1.0)), line), np.pi / 2 - 1.0,
                               atol=1e-12)
    phi = np.linspace(0, 2 * np.pi, 721)
    circle = np.c_[np.cos(phi), np.sin(phi), 0 * phi]
    a = np.random.default_rng(1).uniform(0, 2 * np.pi, 20)
    pts = np.c_[1.1 * np.cos(a), 1.1 * np.sin(a), 0.1 + 0 * a]
    assert curve_tangent_adaptation(pts, rz(a), circle, closed=True).max() < 1e-3  # polyline tangent error
    assert axis_alignment(np.eye(3)[None], np.array([[1.0, 1.0, 0.0]]))[0] == pytest.approx(np.pi / 4)


# --------------------------------------------- known rotation at each vertex
def test_exact_darboux_derivative_closes_and_is_root_independent(mesh6):
    m = mesh6
    E = exp_so3(smooth_rotvec(m.vertices))
    om = darboux_derivative(m, E)
    # developing omega's definition back: E_j = exp(omega_ij) E_i on every edge
    a, b = m.edges.T
    assert np.abs(exp_so3(om) @ E[a] - E[b]).max() < 1e-12
    assert monodromy_angles(m, om).max() < 1e-10
    assert len(singular_structure(m, E).faces) == 0
    roots = pick_roots(m, 3, 3)
    ri = root_independence(m, om, E, roots)
    assert ri.max_deg < 1e-8
    # the same crosses with random representatives: same world-frame omega
    g = CUBE_GROUP[np.random.default_rng(2).integers(0, 24, m.n_vertices)]
    np.testing.assert_allclose(darboux_derivative(m, E @ g), om, atol=1e-12)
    assert root_independence(m, om, E @ g, roots).max_deg < 1e-8


def test_structure_residual_of_exact_fields_is_third_order():
    res = []
    hs = []
    for n in (4, 8):
        m = box_mesh(n)
        om = darboux_derivative(m, exp_so3(smooth_rotvec(m.vertices)))
        interior = np.nonzero(~m.is_boundary_face)[0]
        r = structure_residual(m, om, None, interior)
        res.append(r.mean())
        hs.append(1.0 / n)
        # the linear part alone (d omega) is only second order: the wedge matters
        assert np.linalg.norm(m.d1 @ om, axis=1)[interior].mean() > 5 * r.mean()
    assert loglog_slope(hs, res) > 2.7


def test_commuting_field_has_exactly_zero_residual(mesh6):
    m = mesh6
    E = rz(np.sin(2.0 * m.vertices[:, 0]) + m.vertices[:, 1] ** 2)
    om = darboux_derivative(m, E)
    assert structure_residual(m, om).max() < 1e-13


def test_monodromy_against_prescribed_rotation(mesh6):
    m = mesh6
    rng = np.random.default_rng(3)
    om = 0.05 * rng.standard_normal((m.n_edges, 3))
    M = face_monodromy(m, om)
    Om = Rotation.from_matrix(M).as_rotvec()
    assert monodromy_angles(m, om, Omega=Om).max() < 1e-10
    f = np.arange(0, m.n_faces, 7)
    assert monodromy_angles(m, om, f, Om).max() < 1e-10  # Omega given for all faces
    assert monodromy_angles(m, om, f, Om[f]).max() < 1e-10  # or for the subset
    np.testing.assert_allclose(monodromy_angles(m, om, f), rotation_angle(M[f]))


# ------------------------------------------------------- known singular curves
def test_singular_line(mesh8):
    m = mesh8
    E, P = line_field(m)
    want = pierced_faces(m, P)
    ss = singular_structure(m, E, expected=want)
    np.testing.assert_array_equal(ss.faces, want)
    assert len(ss.missing) == 0 and len(ss.spurious) == 0
    np.testing.assert_allclose(ss.angle, np.pi / 2, atol=1e-9)
    np.testing.assert_allclose(np.abs(ss.axis[:, 2]), 1.0, atol=1e-9)
    # index +1/4 about +z: +1/4 about faces whose normal points up
    nz = m.face_normals[ss.faces, 2]
    np.testing.assert_allclose(ss.index, 0.25 * np.sign(nz) * np.abs(nz), atol=1e-9)
    # one open curve, from the bottom boundary to the top one
    assert len(ss.curves) == 1
    c = ss.curves[0]
    assert c.boundary_faces == 2 and c.branch_tets == 0 and c.dangling_tets == 0 and not c.closed
    # prescribed index and tangent agree with the measured ones ...
    idx = np.zeros(m.n_faces)
    idx[want] = 0.25 * np.sign(m.face_normals[want, 2])
    T = np.tile([0, 0, 1.0], (m.n_faces, 1))
    ss = singular_structure(m, E, want, None, idx, T)
    assert len(ss.wrong_index) == 0 and ss.axis_error.max() < 1e-9
    # ... and the opposite index is flagged on every face
    ss = singular_structure(m, E, want, None, -idx, T)
    np.testing.assert_array_equal(ss.wrong_index, want)
    # monodromy and residual of its Darboux derivative: a quarter turn on the
    # pierced faces (exp(Omega) with Omega = 2 pi sigma T . n / |T . n|), none elsewhere
    om = darboux_derivative(m, E)
    mono = monodromy_angles(m, om)
    np.testing.assert_allclose(mono[want], np.pi / 2, atol=1e-9)
    assert np.delete(mono, want).max() < 1e-12
    Om = np.zeros((m.n_faces, 3))
    Om[want, 2] = 2 * np.pi * 0.25 * np.sign(m.face_normals[want, 2])
    assert monodromy_angles(m, om, Omega=Om).max() < 1e-9
    assert monodromy_angles(m, om, Omega=-Om)[want].min() > np.pi - 1e-9
    r0 = structure_residual(m, om)
    np.testing.assert_allclose(r0[want], np.pi / 2, atol=1e-9)
    assert np.delete(r0, want).max() < 1e-12
    assert structure_residual(m, om, Om).max() < 1e-9
    # crosses, not frames, are compared: developing across the cut is harmless
    assert root_independence(m, om, E, pick_roots(m, 2, 2)).max_deg < 1e-8


def test_singular_loop(mesh8):
    m = mesh8
    E, P = loop_field(m)
    want = pierced_faces(m, P)
    assert len(want) > 20
    ss = singular_structure(m, E, expected=want)
    np.testing.assert_array_equal(ss.faces, want)
    np.testing.assert_allclose(ss.angle, np.pi / 2, atol=1e-9)
    np.testing.assert_allclose(np.abs(ss.axis[:, 2]), 1.0, atol=1e-9)
    assert len(ss.curves) == 1 and ss.curves[0].closed
    # every tet of the loop holds exactly two of its faces
    c = ss.curves[0]
    k = np.isin(m.tet_faces[c.tets], c.faces).sum(axis=1)
    assert np.all(k == 2)
    # singular faces missing from / added to the expected set are reported
    ss = singular_structure(m, E, expected=np.r_[want[1:], 0], allowed=None)
    np.testing.assert_array_equal(ss.missing, [0] if 0 not in want else [])
    np.testing.assert_array_equal(ss.spurious, want[:1])
    om = darboux_derivative(m, E)
    np.testing.assert_allclose(monodromy_angles(m, om)[want], np.pi / 2, atol=1e-9)
    assert root_independence(m, om, E, pick_roots(m, 2, 2)).max_deg < 1e-8


def test_grouping_separates_curves(mesh8):
    m = mesh8
    f1 = pierced_faces(m, line_field(m)[1])
    f2 = pierced_faces(m, loop_field(m)[1])
    t1, t2 = m.face_tets[f1], m.face_tets[f2]
    assert not np.intersect1d(t1[t1 >= 0], t2[t2 >= 0]).size  # the line passes inside the loop
    curves = group_singular_faces(m, np.r_[f1, f2])
    assert len(curves) == 2
    assert [len(c.faces) for c in curves] == sorted([len(f1), len(f2)], reverse=True)
    assert {c.closed for c in curves} == {True, False}
    # a branch: three faces of one tet
    t = m.n_tets // 2
    c = group_singular_faces(m, m.tet_faces[t, :3])
    assert len(c) == 1 and c[0].branch_tets == 1
    assert group_singular_faces(m, np.zeros(0, int)) == []
    near = vertices_near_polylines(m.vertices, [line_field(m)[1]], 0.1)
    d = np.linalg.norm(m.vertices[:, :2] - LINE_XY, axis=1)
    np.testing.assert_array_equal(near, d < 0.1)


# ------------------------------------------------------- root / init independence
def test_root_independence_of_a_nonintegrable_field_scales_linearly(mesh6):
    m = mesh6
    X = m.vertices
    a, b = m.edges.T
    # eta = c x dy: curl c about z, rotations commute, so developments differ
    # by c times the (signed) area between two tree paths
    eta = (0.5 * (X[a, 0] + X[b, 0]) * (X[b, 1] - X[a, 1]))[:, None] * np.array([0, 0, 1.0])
    E = np.broadcast_to(np.eye(3), (m.n_vertices, 3, 3)).copy()
    roots = pick_roots(m, 2, 2)
    from solver.field.develop import develop

    out = []
    for c in (0.01, 0.02):
        ref = develop(m, c * eta, int(roots[0]), E[0])
        out.append(root_independence(m, c * eta, ref, roots[1:]).max_deg)
    assert out[0] > 1e-4
    assert out[0] < np.degrees(0.01 * 1.0)  # at most c times the box's area
    assert out[1] == pytest.approx(2 * out[0], rel=1e-6)


def test_init_independence_reports_known_differences(mesh6):
    m = mesh6
    E = exp_so3(smooth_rotvec(m.vertices))
    om = darboux_derivative(m, E)
    d = np.zeros_like(om)
    d[5] = [0.0, 0.01, 0.0]
    F2 = E.copy()
    F2[3] = exp_so3(np.array([0.02, 0, 0])) @ E[3]
    out = init_independence({"zero": om, "random": om + d, "linear": om.copy()},
                            {"zero": E, "random": F2, "linear": E @ CUBE_GROUP[7]})
    assert out["random"]["omega_max_deg"] == pytest.approx(np.degrees(0.01))
    assert out["random"]["cross_max_deg"] == pytest.approx(np.degrees(0.02))
    assert out["linear"]["omega_max_deg"] == 0 and out["linear"]["cross_max_deg"] < 1e-6


# ---------------------------------------------------------------- smoothness
def test_tet_frames_and_smoothness_of_a_twist(mesh6):
    m = mesh6
    k = 0.5
    x = m.vertices[:, 0]
    tf = tet_frames(m, rz(k * x))
    xc = m.vertices[m.tets][:, :, 0].mean(axis=1)
    assert np.abs(cross_distance(tf, rz(k * xc))).max() < 1e-9
    f = np.nonzero(~m.is_boundary_face)[0]
    theta, dq = face_frame_differences(m, tf, f)
    ft = m.face_tets[f]
    np.testing.assert_allclose(theta, k * np.abs(xc[ft[:, 0]] - xc[ft[:, 1]]), atol=1e-9)
    np.testing.assert_allclose(dq, 2 * np.sin(theta / 4), atol=1e-9)
    w = dual_face_weights(m, f)
    pt, ph = smoothness(m, rz(k * x))
    assert pt == pytest.approx(np.sqrt(np.sum(w * theta**2)), rel=1e-9)
    assert ph == pytest.approx(np.sqrt(np.sum(w * dq**2)), rel=1e-9)
    # Dirichlet energy of the angle k x over the unit box is k^2; the
    # centroid-dual weights approximate it
    assert pt**2 == pytest.approx(k**2, rel=0.35)
    assert smoothness(m, rz(2 * k * x))[0] == pytest.approx(2 * pt, rel=1e-6)
    # invariant under the choice of representatives
    g = CUBE_GROUP[np.random.default_rng(4).integers(0, 24, m.n_vertices)]
    assert smoothness(m, rz(k * x) @ g)[0] == pytest.approx(pt, rel=1e-9)


def test_karcher_smoothing(mesh6):
    m = mesh6
    X = m.vertices
    bnd = m.is_boundary_vertex
    # a linear angle is discretely harmonic on this symmetric grid: a fixed point
    E = rz(0.6 * X[:, 0] + 0.3 * X[:, 1])
    S, hist = karcher_smoothing(m, E, iterations=5, fixed=bnd)
    assert cross_distance(E, S).max() < 1e-9
    # a quadratic angle is not: interior crosses move, boundary ones do not,
    # and phi_theta drops
    E = rz(1.5 * X[:, 0] ** 2)
    chk = smoothing_check(m, E, iterations=10, fixed=bnd)
    S = chk["frames"]
    assert chk["max_change_deg"] > 0.1
    assert cross_distance(E[bnd], S[bnd]).max() < 1e-12
    assert chk["phi_theta_after"] < chk["phi_theta_before"]
    # rotations stay about z (the field's own axis), and do not depend on
    # the representatives
    rel = np.einsum("nij,nkj->nik", S, E)
    rv = Rotation.from_matrix(rel).as_rotvec()
    assert np.abs(rv[:, :2]).max() < 1e-9
    g = CUBE_GROUP[np.random.default_rng(5).integers(0, 24, m.n_vertices)]
    S2, _ = karcher_smoothing(m, E @ g, iterations=10, fixed=bnd)
    assert cross_distance(S, S2).max() < 1e-9
    # axis constraints: a vertex restricted to rotate about x stays put
    # under a field turning about z
    axes = np.zeros((m.n_vertices, 3))
    axes[bnd] = [1.0, 0.0, 0.0]
    S3, _ = karcher_smoothing(m, E, iterations=3, axes=axes)
    assert cross_distance(E[bnd], S3[bnd]).max() < 1e-9
    assert cross_distance(E[~bnd], S3[~bnd]).max() > 1e-3


def test_loglog_slope():
    h = np.array([0.4, 0.2, 0.1, 0.05])
    assert loglog_slope(h, 3 * h**2) == pytest.approx(2.0)
    assert loglog_slope(h, 0.1 * h**1.5) == pytest.approx(1.5)
    assert np.isnan(loglog_slope([0.1], [1.0]))


def test_matched_singular_faces_keeps_its_interface(mesh6):
    m = mesh6
    E = np.broadcast_to(np.eye(3), (m.n_vertices, 3, 3))
    mask, rot = matched_singular_faces(m, E, np.arange(10))
    assert mask.shape == (10,) and rot.shape == (10, 3) and not mask.any()


def fast_field():
    """(mesh, frames, omega): a smooth field turning ~47 degrees per edge
    along x on a jittered box, with its exact (unmatched) omega."""
    m = box_mesh(6, jitter=0.2)
    E = rz(4.7 * m.vertices[:, 0])
    i, j = m.edges.T
    return m, E, Rotation.from_matrix(E[j] @ np.transpose(E[i], (0, 2, 1))).as_rotvec()


def test_omega_aware_matching_sees_through_fast_turns():
    """A smooth field turning ~45 degrees per edge: closest-rotation matching
    reads some edges as quarter-turn jumps and flags faces, the omega-aware
    matching flags none; on a real singular line both find the pierced faces."""
    m, E, om = fast_field()
    assert np.degrees(np.linalg.norm(om, axis=1)).max() > 45.0
    assert matched_singular_faces(m, E)[0].sum() > 0
    assert not omega_singular_faces(m, om, E).any()
    m8 = box_mesh(8)
    E8, P = line_field(m8)
    want = pierced_faces(m8, P)
    got = np.nonzero(omega_singular_faces(m8, darboux_derivative(m8, E8), E8))[0]
    np.testing.assert_array_equal(got, want)


def test_a_solved_field_reads_exactly_its_network_with_its_own_matchings():
    """Two straight curves of index +1/4 and -1/4 through a structured mesh
    of edge h = 1/6 (one passes 1e-4 h from a column of edge midpoints): the
    solved field turns by more than 45 degrees across edges next to both
    curves, and closest-rotation matching misreads 38 faces next to each (a
    tool reading only the frames would see singular faces off the pierced
    ones).  With each edge matched against the frame omega carries across
    it, the singular faces are exactly the pierced ones; the faces where the
    two readings differ all touch the network, and the report counts them."""
    from solver import FieldProblem
    from solver.examples import box
    from solver.network.network import Curve, Network
    from solver.pipeline import Options

    n = 6
    h = 1.0 / n
    V, F = box(lo=(0, 0, 0), hi=(1, 1, 1), n=n)
    z = np.linspace(0.0, 1.0, 5)
    near = np.c_[np.full(5, 2.5 * h), np.full(5, 3.0 * h + 1e-4 * h), z]
    other = np.c_[np.full(5, 0.21), np.full(5, 0.77), z]
    net = Network(curves=[Curve(near, sigma=0.25, name="near"), Curve(other, sigma=-0.25, name="other")],
                  sharp_angle=30.0)
    result = FieldProblem(V, F, net, Options(edge_length=h), mesh=box_mesh(n)).solve()
    assert result.report.converged
    m = result.report.metrics
    assert m["omega_spurious_singular_faces"] == 0 and m["omega_missing_singular_faces"] == 0
    mesh = result.mesh
    closest, _ = matched_singular_faces(mesh, result.frames)
    differ = closest != omega_singular_faces(mesh, result.omega, result.frames)
    assert m["max_edge_turn_deg"] > 45.0 and differ.any()
    assert m["matching_disagreements"] == differ.sum()
    on_network = np.zeros(mesh.n_vertices, bool)
    on_network[mesh.faces[result.embedding.network_faces(mesh)]] = True
    assert on_network[mesh.faces[differ]].any(axis=1).all()


def test_omega_frame_mismatch_measures_the_frames_off_omega(mesh6):
    """Zero where omega carries each cross onto the next (whatever its
    representative), the turn of a frame rotated off omega on its edges,
    and a bound on where closest-rotation and omega-aware matching differ."""
    m = mesh6
    E = exp_so3(smooth_rotvec(m.vertices))
    om = darboux_derivative(m, E)
    g = CUBE_GROUP[np.random.default_rng(5).integers(0, 24, m.n_vertices)]
    assert omega_frame_mismatch(m, om, E @ g).max() < 1e-7
    v = m.n_vertices // 2
    E2 = E.copy()
    E2[v] = exp_so3(np.radians(10.0) * np.array([[0.6, 0.0, 0.8]]))[0] @ E[v]
    mm = np.degrees(omega_frame_mismatch(m, om, E2))
    at_v = np.any(m.edges == v, axis=1)
    np.testing.assert_allclose(mm[at_v], 10.0, atol=1e-6)
    assert mm[~at_v].max() < 1e-5
    # a fast field (~47 degrees per edge along x) with frames nudged off
    # omega: the edges the two matchings read differently all reach 45
    # degrees in |omega| + mismatch
    mj, Ef, omf = fast_field()
    En = exp_so3(0.05 * np.random.default_rng(6).standard_normal((mj.n_vertices, 3))) @ Ef
    mm = omega_frame_mismatch(mj, omf, En)
    pairs = mj.edges
    differ = edge_matchings(En, pairs) != omega_matchings(mj, omf, En, pairs)
    assert differ.any()
    assert np.all(np.linalg.norm(omf, axis=1)[differ] + mm[differ] >= np.pi / 4)
