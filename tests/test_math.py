"""The discrete geometry the solver is built on, checked against known
answers: rotations and the cube group, the structure equation (Eq. 17/18)
on smooth fields, parallel transport and curvature on a surface (Eq. 4-6),
the 2D field's per-triangle condition, and development (Eq. 8)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from solver.analysis.measures import darboux_derivative
from solver.examples import icosphere
from solver.field.boundary2d import solve_boundary_field, wrap
from solver.field.develop import develop, symmetric_turn
from solver.field.structure import StructureEquation
from solver.linalg.rotations import CUBE_GROUP, cross_distance, exp_so3, hat, log_so3, rotation_angle, unwrap_rotvec
from solver.mesh.tetmesh import TetMesh
from solver.surface.features import FeatureGraph
from solver.surface.trisurface import TriSurface, first_rows, unique_rows
from tests.meshes import box_mesh


def smooth_field(X: np.ndarray) -> np.ndarray:
    """A smooth, strongly varying rotation field (one frame per point)."""
    A = np.array([[0.9, -0.4, 0.3], [0.2, 0.7, -0.8], [-0.5, 0.6, 0.4]])
    v = X @ A.T + 0.6 * np.sin(2.0 * X[:, [1, 2, 0]])
    return exp_so3(v)


def darboux(mesh: TetMesh, E: np.ndarray) -> np.ndarray:
    """omega_ij = log(E_j E_i^T) per edge (Eq. 7 with R_ij = I)."""
    i, j = mesh.edges.T
    return log_so3(E[j] @ np.transpose(E[i], (0, 2, 1)))


# ----------------------------------------------------------------- rotations
def test_exp_log_round_trip_and_hat_bracket():
    rng = np.random.default_rng(1)
    v = rng.normal(size=(200, 3))
    v *= (rng.uniform(0, 3.1, 200) / np.linalg.norm(v, axis=1))[:, None]
    assert np.allclose(log_so3(exp_so3(v)), v, atol=1e-10)
    a, b = rng.normal(size=(2, 50, 3))
    assert np.allclose(hat(a) @ hat(b) - hat(b) @ hat(a), hat(np.cross(a, b)), atol=1e-12)
    assert np.allclose(rotation_angle(exp_so3(v)), np.linalg.norm(v, axis=1), atol=1e-9)


def test_unwrap_keeps_large_rotations():
    # a 1.3-turn rotation about z is stored as its small log; unwrapping near
    # the large vector recovers it exactly
    big = np.array([[0.0, 0.0, 2.6 * np.pi]])
    small = log_so3(exp_so3(big))
    assert np.linalg.norm(small) < np.pi
    assert np.allclose(unwrap_rotvec(small, big), big, atol=1e-9)


def test_cube_group_is_the_octahedral_group():
    G = CUBE_GROUP
    assert G.shape == (24, 3, 3)
    assert np.allclose(G[0], np.eye(3))
    assert np.allclose(np.linalg.det(G), 1.0)
    # closed under products and inverses, all distinct
    keys = {tuple(np.round(g).astype(int).ravel()) for g in G}
    assert len(keys) == 24
    for a, b in itertools.product(G, G):
        assert tuple(np.round(a @ b).astype(int).ravel()) in keys


def test_cross_distance_ignores_representatives():
    rng = np.random.default_rng(2)
    E = Rotation.random(100, random_state=3).as_matrix()
    g = CUBE_GROUP[rng.integers(0, 24, 100)]
    assert np.allclose(cross_distance(E, E @ g), 0.0, atol=1e-7)
    # a small rotation about any axis moves the cross by exactly its angle
    w = rng.normal(size=(100, 3))
    w *= (np.radians(7.0) / np.linalg.norm(w, axis=1))[:, None]
    assert np.allclose(np.degrees(cross_distance(E, exp_so3(w) @ E @ g)), 7.0, atol=1e-6)
    # the largest possible distance between two crosses is below 63 degrees
    F = Rotation.random(2000, random_state=4).as_matrix()
    assert np.degrees(cross_distance(E[:1].repeat(2000, 0), F)).max() < 63.0


# ------------------------------------------------------ structure equation
@pytest.mark.parametrize("jitter", [0.0, 0.25])
def test_structure_residual_of_smooth_fields_is_third_order(jitter):
    """Darboux derivatives of smooth frame fields satisfy Eq. 17 (Omega = 0)
    up to O(h^3) per face (the wedge of Eq. 18 removes the second-order
    term), while dropping the wedge leaves O(h^2)."""
    full, lin, hs = [], [], []
    for n in (4, 8, 16):
        mesh = box_mesh(n, hi=(0.6, 0.6, 0.6), jitter=jitter)
        om = darboux(mesh, smooth_field(mesh.vertices))
        eq = StructureEquation(mesh.face_edges, mesh.corner_weights, np.zeros((mesh.n_faces, 3)), mesh.n_edges)
        full.append(np.abs(eq.residual(om)).max())
        lin.append(np.abs(eq.residual(om, linear=True)).max())
        hs.append(mesh.mean_edge_length)
    # slopes between the two finest meshes
    slope_full = np.log(full[1] / full[2]) / np.log(hs[1] / hs[2])
    slope_lin = np.log(lin[1] / lin[2]) / np.log(hs[1] / hs[2])
    assert slope_full > 2.6, (full, slope_full)
    assert 1.7 < slope_lin < 2.3, (lin, slope_lin)


def test_structure_jacobian_matches_finite_differences():
    mesh = box_mesh(2, jitter=0.2)
    rng = np.random.default_rng(5)
    om = rng.normal(scale=0.5, size=(mesh.n_edges, 3))
    eq = StructureEquation(mesh.face_edges, mesh.corner_weights, rng.normal(size=(mesh.n_faces, 3)),
                           mesh.n_edges)
    J = eq.jacobian(om).toarray()
    d = rng.normal(size=om.shape)
    eps = 1e-6
    fd = (eq.residual(om + eps * d) - eq.residual(om - eps * d)).reshape(-1) / (2 * eps)
    assert np.allclose(J @ d.reshape(-1), fd, atol=1e-7)


def test_residual_hessian_is_the_second_order_term_of_the_energy():
    """Gauss-Newton plus residual_hessian is the exact Hessian of |r|^2 / 2
    (the Newton steps of volume3d.py)."""
    mesh = box_mesh(2, jitter=0.2)
    rng = np.random.default_rng(6)
    om = rng.normal(scale=0.5, size=(mesh.n_edges, 3))
    eq = StructureEquation(mesh.face_edges, mesh.corner_weights, rng.normal(size=(mesh.n_faces, 3)),
                           mesh.n_edges)

    def grad(o):  # gradient of |r(o)|^2 / 2
        return eq.jacobian(o).T @ eq.residual(o).reshape(-1)

    J, K = eq.jacobian(om), eq.residual_hessian(eq.residual(om))
    assert abs(K - K.T).max() == 0.0
    d = rng.normal(size=om.shape)
    eps = 1e-6
    fd = (grad(om + eps * d) - grad(om - eps * d)) / (2 * eps)
    exact = J.T @ (J @ d.reshape(-1)) + K @ d.reshape(-1)
    assert np.linalg.norm(exact - fd) <= 1e-7 * np.linalg.norm(fd)
    # and the term matters: Gauss-Newton alone is off by far more
    assert np.linalg.norm(J.T @ (J @ d.reshape(-1)) - fd) > 1e-3 * np.linalg.norm(fd)


# -------------------------------------------------------------- development
def test_development_recovers_the_field():
    mesh = box_mesh(5, jitter=0.2)
    E = smooth_field(mesh.vertices)
    om = darboux(mesh, E)
    for root in (0, mesh.n_vertices // 2, mesh.n_vertices - 1):
        D = develop(mesh, om, root, E[root])
        assert np.allclose(D, E, atol=1e-10)


def test_symmetric_turn_restores_adaptation_to_a_singular_line():
    """A quarter-turn singular line along z fixes the turn of the root frame
    about x: developed from a root frame turned by 0.4 rad about x the field
    is no cross field (frames disagree across the development's cut), and
    symmetric_turn finds the turn back."""
    mesh = box_mesh(8)
    d = mesh.vertices[:, :2] - np.array([0.4137, 0.5291])
    E = Rotation.from_rotvec(np.c_[np.zeros((len(d), 2)), np.arctan2(d[:, 1], d[:, 0]) / 4]).as_matrix()
    om = darboux_derivative(mesh, E)  # matched: a quarter turn around the line
    root = 0
    turned = develop(mesh, om, root, E[root] @ exp_so3(np.array([0.4, 0.0, 0.0])))
    assert np.degrees(cross_distance(turned, E)).max() > 20.0
    theta = symmetric_turn(mesh, om, turned, axis=0)
    assert abs(theta + 0.4) < 1e-4
    fixed = turned @ exp_so3(np.array([theta, 0.0, 0.0]))
    assert np.degrees(cross_distance(fixed, E)).max() < 0.01
    # a turn about the line's own axis keeps the field consistent: nothing to fix
    about_z = develop(mesh, om, root, E[root] @ exp_so3(np.array([0.0, 0.0, 0.4])))
    assert abs(symmetric_turn(mesh, om, about_z, axis=0)) < 1e-4


def test_symmetric_turn_is_zero_without_singularities():
    mesh = box_mesh(5, jitter=0.2)
    E = smooth_field(mesh.vertices)
    om = darboux(mesh, E)
    assert symmetric_turn(mesh, om, develop(mesh, om, 0, E[0]), axis=2) == 0.0


# ------------------------------------------------------ surface, Eq. 4 - 6
def test_triangle_holonomy_equals_curvature_and_gauss_bonnet():
    """Eq. 6: parallel transport around each triangle turns by its Gaussian
    curvature (Eq. 4, angle defect form), and the total is 2 pi chi."""
    V, F = icosphere(3)
    S = TriSurface(V, F)
    # eight +1/4 singularities (the cube's corners) satisfy Poincare-Hopf
    corners = np.array(list(itertools.product((-1, 1), repeat=3))) / np.sqrt(3)
    centroids = V[F].mean(axis=1)
    sigma = np.zeros(len(F))
    sigma[np.argmax(centroids @ corners.T, axis=0)] = 0.25
    bf = solve_boundary_field(S, FeatureGraph(S, np.zeros(len(S.edges), bool)), sigma)
    # orientation of each face's edges relative to (low -> high)
    E = S.edges
    key = {tuple(e): k for k, e in enumerate(E)}
    hol = np.zeros(len(F))
    d_omega = np.zeros(len(F))
    for f, tri in enumerate(F):
        for a, b in ((tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])):
            k = key[(min(a, b), max(a, b))]
            s = 1.0 if a < b else -1.0
            hol[f] += s * bf.rho[k]
            d_omega[f] += s * bf.omega2d[k]
    assert np.allclose(wrap(hol - bf.K), 0.0, atol=1e-9)
    assert np.isclose(bf.K.sum(), 4 * np.pi, atol=1e-9)
    # Eq. 13: around every triangle the field's change cancels the
    # curvature up to the prescribed singular angle
    assert np.allclose(d_omega, -bf.K + 2 * np.pi * sigma, atol=1e-8) or np.allclose(
        d_omega, bf.K - 2 * np.pi * sigma, atol=1e-8), np.abs(d_omega + bf.K - 2 * np.pi * sigma).max()


@pytest.mark.parametrize("turns", [{}, {(0, 1): 4}, {(0, 0): 4, (0, 1): 8}])
def test_boundary_field_meets_every_triangle_condition_with_turns_added_around_generators(turns):
    """Eq. 13 on each triangle and Eq. 14 on each generator of a torus,
    also when full turns are added around its generators (the pipeline's
    parity correction does so).  The constraint solve's stabilising shift
    once left a residual that grew with the turns asked for: 1.4e-6 rad
    summed into one triangle, which failed the torus example at 50k tets."""
    from solver.examples import torus_surface

    S = TriSurface(*torus_surface())
    bf = solve_boundary_field(S, FeatureGraph(S, np.zeros(len(S.edges), bool)), np.zeros(len(S.F)),
                              generator_turns=turns)
    d_omega = np.sum(S.face_edge_signs * bf.omega2d[S.face_edges], axis=1)
    assert np.abs(d_omega + bf.K).max() < 1e-10
    assert len(bf.generators) == 2
    for _key, ids, signs in bf.generators:
        hol = np.sum(signs * (bf.rho[ids] + bf.omega2d[ids]))
        q = hol / (np.pi / 2)
        assert abs(q - round(q)) < 1e-10


@pytest.mark.parametrize("width, low, high",
                         [(2, 0, 30), (3, -40, 40), (4, 0, 3_000_000), (8, 0, 4), (3, -2**40, 2**40)])
def test_unique_rows_and_first_rows_are_numpys(width, low, high):
    """unique_rows and first_rows give np.unique(axis=0)'s arrays: one packed
    key (small ranges, negative values), two columns a key (a range whose
    fourth power passes int64) or one (a range past 3e9), any width."""
    rng = np.random.default_rng(width)
    a = rng.integers(low, high, (3000, width))
    a = np.vstack([a, a[::5], a[7:9]])  # repeated rows, some three times
    rows, first, inv, cnt = np.unique(a, axis=0, return_index=True, return_inverse=True, return_counts=True)
    u, i, c = unique_rows(a)
    assert np.array_equal(u, rows) and np.array_equal(i, inv.reshape(-1)) and np.array_equal(c, cnt)
    assert np.array_equal(first_rows(a), first)
    assert len(unique_rows(a[:0])[0]) == 0 and len(first_rows(a[:0])) == 0
