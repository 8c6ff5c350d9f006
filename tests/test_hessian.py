"""The assembled Levenberg-Marquardt matrices (solver/field/hessian.py) against
their definitions: P^T (sum_f E_f^T Q_f E_f) P computed densely, and the
Gauss-Newton and Newton terms of Eq. 23 from the sparse Jacobian."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from solver.field.constraints import BOUNDARY, FIXED, FREE, TUBE
from solver.field.hessian import FaceAssembly
from solver.linalg import parallel


def _dense_reference(face_edges, P, Q, extra):
    n_omega = P.shape[0]
    A = np.zeros((n_omega, n_omega))
    for f, edges in enumerate(face_edges):
        dof = (3 * np.asarray(edges)[:, None] + np.arange(3)).ravel()
        A[np.ix_(dof, dof)] += Q[f]
    return P.T.toarray() @ A @ P.toarray() + extra.toarray()


def test_face_assembly_matches_the_dense_sum_with_shared_unknowns():
    """Rows of P with several unknowns (boundary edges: the alpha of both
    ends), empty rows (fixed edges) and stored zeros all land where the
    dense product puts them."""
    rng = np.random.default_rng(3)
    n_edges, n = 7, 12
    face_edges = np.array([[0, 1, 2], [2, 3, 4], [4, 5, 6], [0, 3, 6]])
    P = sp.random(3 * n_edges, n, density=0.25, random_state=4, format="lil")
    P[3:6, :] = 0.0  # edge 1: fixed, no unknowns
    P[9, 2] = 0.0  # a stored zero
    P[:, n - 1] = 0.0  # an unknown no face sees: only its diagonal is in the pattern
    P = P.tocsr()
    assert np.any(np.diff(P.indptr) > 1) and np.any(np.diff(P.indptr) == 0)
    Q = rng.normal(size=(4, 9, 9))
    Q = Q + Q.transpose(0, 2, 1)
    extra = sp.diags(rng.uniform(1.0, 2.0, n)).tocsr()
    fa = FaceAssembly(face_edges, P, extra)
    H = fa.matrix(fa.data(Q) + fa.extra_data).toarray()
    assert np.allclose(H, _dense_reference(face_edges, P, Q, extra), rtol=0, atol=1e-12)
    assert np.array_equal(H, H.T)  # built from one triangle: exactly symmetric, as CG assumes
    # values into a kept array, with S's products split on the thread pool
    # (where its upper triangle goes into kept space too): the same values
    old = parallel.threads()
    parallel.set_threads(2)
    try:
        fb = FaceAssembly(face_edges, P, extra)
        fb.S = parallel.RowSplitMatrix(fb.S, 2)
        out = np.full(fb.nnz, np.nan)
        for scale in (1.0, 2.0):
            assert fb.data(scale * Q, out=out) is out
            assert np.array_equal(out, fa.data(scale * Q))
    finally:
        parallel.set_threads(old)
    with pytest.raises(ValueError, match="outside the sparsity pattern"):
        fa.positions(np.array([0]), np.array([n - 1]))


@pytest.fixture
def cylinder_problem(meshed):
    return meshed("cylinder", edge_length=0.3)


@pytest.mark.slow
@pytest.mark.mesher
def test_assembled_gauss_newton_and_newton_terms_match_the_jacobian(cylinder_problem):
    """On a problem with every kind of edge (free, boundary, fixed sharp,
    curve tube): the gradient, H = 2 P^T (W + a J^T J) P and the Newton term
    2 a P^T (sum_f r_f . d^2 r_f) P agree with the sparse Jacobian's."""
    p = cylinder_problem
    vp = p.volume
    kinds = set(np.unique(p.constraints.kind).tolist())
    assert {FREE, BOUNDARY, FIXED, TUBE} <= kinds
    x = np.random.default_rng(1).uniform(-0.3, 0.3, p.constraints.n_unknowns)
    om = vp.omega(x)
    g, data, (B, d) = vp.linearise(x)
    Jx = (vp.se.jacobian(om) @ vp.P).tocsr()
    r = vp.se.residual(om).reshape(-1)
    g_ref = 2 * (vp.PT @ (vp.W3 * om.reshape(-1))) + 2 * vp.a * (Jx.T @ r)
    # compared as sparse matrices: entry by entry, as dense ones would be
    # (those of this problem's ~15k unknowns took gigabytes)
    H_ref = (vp.HW + 2 * vp.a * (Jx.T @ Jx)).tocsr()
    H = vp.lm_matrix(data).tocsr()
    scale = abs(H_ref).max()
    assert np.linalg.norm(g - g_ref) <= 1e-12 * np.linalg.norm(g_ref)
    assert abs(H - H_ref).max() <= 1e-12 * scale
    # block Jacobi reads the free edges' diagonal blocks and the other diagonal entries
    nfree = len(p.constraints.free_edges)
    idx = 3 * np.arange(nfree)[:, None] + np.arange(3)
    rows, cols = (np.broadcast_to(i, (nfree, 3, 3)).ravel() for i in (idx[:, :, None], idx[:, None, :]))
    B_ref = np.asarray(H_ref[rows, cols]).reshape(nfree, 3, 3)
    assert np.allclose(B, B_ref, rtol=0, atol=1e-12 * scale)
    assert np.allclose(d, H_ref.diagonal()[3 * nfree:], rtol=0, atol=1e-12 * scale)
    K_ref = (2 * vp.a * (vp.PT @ vp.se.residual_hessian(vp.se.residual(om)) @ vp.P)).tocsr()
    K = vp.assembly.matrix(vp.second_order(x)).tocsr()
    assert abs(K - K_ref).max() <= 1e-12 * abs(K_ref).max()
    # damping adds lambda diag(H) on the diagonal only
    D = (vp.lm_matrix(data, 0.5, vp.damping_diagonal((B, d))) - H).tocsr()
    off = D - sp.diags(D.diagonal())
    assert off.nnz == 0 or abs(off).max() <= 1e-12 * scale
    assert np.allclose(D.diagonal(), 0.5 * np.r_[np.einsum("nii->ni", B).ravel(), d], atol=1e-12 * scale)


@pytest.mark.slow
@pytest.mark.mesher
def test_energy_along_a_step_is_the_exact_quartic_and_its_minimum_is_found(cylinder_problem):
    """E(x + t dx) of Eq. 23 is a quartic in t (the structure residual is
    quadratic in omega): the coefficients of VolumeProblem.energy_along
    reproduce the energy at any t, and line_minimum finds the smallest
    value on (0, t_max] that a fine grid finds, or a smaller one."""
    p = cylinder_problem
    vp = p.volume
    rng = np.random.default_rng(4)
    n = p.constraints.n_unknowns
    for scale in (0.05, 0.5):
        x = rng.uniform(-scale, scale, n)
        # a descent direction: the energy falls, then rises
        g = vp.linearise(x)[0]
        dx = -g * (scale * np.sqrt(n) / np.linalg.norm(g))
        coef = vp.energy_along(x, dx)
        for t in (-0.7, 0.0, 0.3, 1.0, 2.5):
            E = vp.energy(x + t * dx)
            assert abs(np.polyval(coef[::-1], t) - E) <= 1e-11 * max(E, 1.0), (scale, t)
        for t_max in (0.5, 4.0):
            t = vp.line_minimum(coef, t_max)
            assert 0.0 < t <= t_max
            grid = np.linspace(1e-3, t_max, 2001)
            assert vp.energy(x + t * dx) <= min(np.polyval(coef[::-1], grid)) * (1 + 1e-12)
    # (t - 1)^4: the full step is the minimum and is kept
    assert vp.line_minimum(np.array([1.0, -4.0, 6.0, -4.0, 1.0]), 4.0) == pytest.approx(1.0)
    # (t - 2)^2 (t^2 + 1): twice the step; capped at t_max
    assert vp.line_minimum(np.array([4.0, -4.0, 5.0, -4.0, 1.0]), 4.0) == pytest.approx(2.0)
    assert vp.line_minimum(np.array([4.0, -4.0, 5.0, -4.0, 1.0]), 1.5) == 1.5


@pytest.mark.slow
@pytest.mark.mesher
def test_lm_replaces_an_overshooting_step_by_the_line_minimum_and_ends_at_the_same_minimiser(cylinder_problem):
    """From a random start the Gauss-Newton step overshoots: LM takes the
    minimum along it (line_step < 1) instead of rejecting it, and ends where
    LM without the line search ends."""
    p = cylinder_problem
    vp = p.volume
    x0 = np.random.default_rng(0).uniform(-0.5, 0.5, p.constraints.n_unknowns)
    x, rep = vp.solve(x0)
    x_plain, rep_plain = vp.solve(x0, line_search=0.0)
    assert rep.converged and rep_plain.converged
    replaced = [it for it in rep.iterations[1:] if it.line_step != 1.0]
    assert replaced and all(it.accepted and 0.0 < it.line_step <= 4.0 for it in replaced)
    assert all(it.line_step == 1.0 for it in rep_plain.iterations)
    energies = [it.energy for it in rep.iterations]
    assert all(b <= a for a, b in zip(energies, energies[1:]))
    om, om_plain = vp.omega(x), vp.omega(x_plain)
    assert np.linalg.norm(om - om_plain) <= 1e-6 * np.linalg.norm(om_plain)
