"""The linear algebra under Levenberg-Marquardt: the nodal AMG that
preconditions the gradient space, PCG, and the row-split products that use
several cores."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from solver.linalg import parallel
from solver.linalg.amg import AMG, _row_argmax, inv_blocks
from solver.linalg.pcg import RitzRecorder, pcg
from tests.meshes import box_mesh


@pytest.fixture
def block_laplacian():
    """A vertex Laplacian of a jittered box mesh, three unknowns per vertex
    (the shape of the gradient-space operator), slightly shifted."""
    mesh = box_mesh(8, jitter=0.2)
    d0 = mesh.d0
    L = (d0.T @ d0).tocsr()
    A = sp.kron(L, np.eye(3)).tocsr() + 1e-3 * sp.eye(3 * mesh.n_vertices)
    return A.tocsr()


def test_amg_vcycle_is_symmetric_and_beats_jacobi(block_laplacian):
    A = block_laplacian
    amg = AMG.build(A, block=3, max_coarse=50)
    assert amg.n_levels >= 2
    rng = np.random.default_rng(0)
    u, v = rng.normal(size=(2, A.shape[0]))
    # a symmetric preconditioner, so CG may use it
    assert abs(u @ amg.vcycle(v) - v @ amg.vcycle(u)) <= 1e-10 * np.linalg.norm(u) * np.linalg.norm(v)
    b = rng.normal(size=A.shape[0])
    mg = pcg(lambda x: A @ x, b, amg.vcycle, rtol=1e-8, maxiter=500)
    jac = pcg(lambda x: A @ x, b, lambda r: r / A.diagonal(), rtol=1e-8, maxiter=5000)
    assert mg.converged and jac.converged
    assert np.linalg.norm(A @ mg.x - b) <= 1e-8 * np.linalg.norm(b) * 1.0001
    assert mg.iterations * 4 < jac.iterations, (mg.iterations, jac.iterations)


def test_amg_rebuilt_for_new_values_reuses_the_roots_and_equals_a_fresh_build(block_laplacian):
    """A rebuild for a matrix with the same pattern skips the search for
    the aggregates' roots, yet gives exactly the hierarchy a fresh build
    gives; a matrix with another pattern gets its own roots."""
    A = block_laplacian
    n = A.shape[0]
    rng = np.random.default_rng(7)
    s = sp.diags(rng.uniform(0.5, 2.0, n))
    B = (s @ A @ s + sp.diags(rng.uniform(0.0, 1e-2, n))).tocsr()  # new values, same pattern, SPD
    first = AMG.build(A, block=3, max_coarse=50)
    again = AMG.build(B, block=3, max_coarse=50, like=first)
    fresh = AMG.build(B, block=3, max_coarse=50)
    assert again.n_levels == fresh.n_levels >= 2
    assert again.levels[0].roots is first.levels[0].roots
    for a, f in zip(again.levels, fresh.levels):
        assert (a.A != f.A).nnz == 0
        assert a.P is None or (a.P != f.P).nnz == 0
    b = rng.normal(size=n)
    assert np.array_equal(again.vcycle(b), fresh.vcycle(b))
    C = (A + 1e-6 * sp.eye(n, k=7) + 1e-6 * sp.eye(n, k=-7)).tocsr()  # another pattern
    other = AMG.build(C, block=3, max_coarse=50, like=first)
    assert other.levels[0].roots is not first.levels[0].roots
    assert (other.levels[0].P != AMG.build(C, block=3, max_coarse=50).levels[0].P).nnz == 0
    # roots picked with other random weights are not taken over
    assert AMG.build(B, block=3, max_coarse=50, like=first, seed=1).levels[0].roots is not first.levels[0].roots


def test_block_inverses_match_lapack():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(500, 3, 3))
    D = A @ A.transpose(0, 2, 1) + np.geomspace(1e-6, 1.0, 500)[:, None, None] * np.eye(3)
    ref = np.linalg.inv(D)
    err = np.abs(inv_blocks(D) - ref).max(axis=(1, 2)) / np.abs(ref).max(axis=(1, 2))
    assert err.max() < 1e-9
    assert np.allclose(inv_blocks(D[:, :2, :2]), np.linalg.inv(D[:, :2, :2]))  # other sizes: LAPACK
    with pytest.raises(np.linalg.LinAlgError):
        inv_blocks(np.zeros((2, 3, 3)))


def test_row_argmax_matches_scipy():
    M = sp.random(300, 200, density=0.03, random_state=4, format="csr")
    M.data = np.round(M.data * 4) + 1.0  # many ties within a row
    has = np.diff(M.indptr) > 0
    assert has.sum() > 100 and (~has).any()
    assert np.array_equal(_row_argmax(M)[has], np.asarray(M.argmax(axis=1)).ravel()[has])


def test_ritz_recorder_stops_on_a_breakdown(block_laplacian):
    A = block_laplacian
    b = np.random.default_rng(5).normal(size=A.shape[0])
    calls = []

    def bad_precond(r):  # a preconditioner that once returns a non-finite vector
        calls.append(1)
        z = r / A.diagonal()
        return np.full_like(z, np.nan) if len(calls) == 3 else z

    rec = RitzRecorder(A.shape[0], nev=2, m=8)
    pcg(lambda x: A @ x, b, bad_precond, rtol=1e-8, maxiter=50, recorder=rec)
    assert rec.failed
    # and a sound run is not flagged
    rec = RitzRecorder(A.shape[0], nev=2, m=8)
    res = pcg(lambda x: A @ x, b, lambda r: r / A.diagonal(), rtol=1e-8, maxiter=2000, recorder=rec)
    assert res.converged and not rec.failed


def test_pcg_reports_negative_curvature():
    A = sp.diags([1.0, 2.0, -1.0]).tocsr()
    res = pcg(lambda x: A @ x, np.ones(3), lambda r: r, rtol=1e-12)
    assert res.negative_curvature and not res.converged
    d = res.direction  # the direction that showed it, for the LM to use
    assert d is not None and d @ (A @ d) <= 0


@pytest.mark.parametrize("cols", [None, 3])
def test_row_split_products_match_serial(block_laplacian, cols):
    A = block_laplacian
    old = parallel.threads()
    parallel.set_threads(3)
    try:
        P = parallel.RowSplitMatrix(A, 3)
        assert len(P.blocks) == 3 and P.shape == A.shape
        x = np.random.default_rng(1).normal(size=(A.shape[0],) if cols is None else (A.shape[0], cols))
        assert np.array_equal(P @ x, A @ x)
        # into a kept array: the same values, in that array
        out = np.full(x.shape, np.nan)
        assert P.matvec(x, out=out) is out and np.array_equal(out, A @ x)
        with pytest.raises(ValueError, match="out must have shape"):
            P.matvec(x, out=np.empty(x.shape, dtype=np.float32))
        # small matrices are left alone
        assert parallel.parallel(sp.eye(10, format="csr")).__class__ is not parallel.RowSplitMatrix
    finally:
        parallel.set_threads(old)


def test_tall_matrices_split_into_small_blocks_that_the_threads_share(monkeypatch):
    """A tall matrix gets more row blocks than threads (each block's result
    stays below BLOCK_BYTES), and the threads share them out; the product is
    still exactly the serial one."""
    monkeypatch.setattr(parallel, "BLOCK_BYTES", 8 * 1000)
    old = parallel.threads()
    parallel.set_threads(2)
    try:
        A = sp.random(10_000, 300, density=0.02, format="csr", random_state=2)
        P = parallel.RowSplitMatrix(A, 2)
        assert len(P.blocks) >= 10
        assert max(b.shape[0] for b in P.blocks) < 3000
        x = np.random.default_rng(3).normal(size=300)
        for _ in range(3):
            assert np.array_equal(P @ x, A @ x)
    finally:
        parallel.set_threads(old)


def test_vector_work_by_ranges_covers_every_index_once():
    old = parallel.threads()
    parallel.set_threads(2)
    try:
        for n in (7, parallel.MIN_LEN + 3):
            parts = parallel.ranges(n)
            assert len(parts) == (2 if n >= parallel.MIN_LEN else 1)
            hit = np.zeros(n, int)

            def work(i, j):
                hit[i:j] += 1
                return j - i

            assert sum(parallel.run(work, parts)) == n
            assert np.all(hit == 1)
    finally:
        parallel.set_threads(old)


def test_thread_setting_is_validated(monkeypatch):
    with pytest.raises(ValueError, match="at least 1"):
        parallel.set_threads(0)
    monkeypatch.setattr(parallel, "_threads", None)
    monkeypatch.setenv("SYMFRAMES_THREADS", "two")
    with pytest.raises(ValueError, match="SYMFRAMES_THREADS"):
        parallel.threads()
    monkeypatch.setenv("SYMFRAMES_THREADS", "1")
    assert parallel.threads() == 1
    A = sp.random(400, 400, density=0.9, format="csr", random_state=0)
    assert parallel.parallel(A) is A


def test_the_mesher_takes_symframes_thread_count_where_one_is_set(monkeypatch):
    """fTetWild's child gets SymFrames' thread count when one is asked for
    (the suite's two workers ask for one each), else 0: every core."""
    from solver.mesh.tetwild import _mesher_threads

    monkeypatch.setattr(parallel, "_threads", None)
    monkeypatch.setattr(parallel, "_asked", False)
    monkeypatch.delenv("SYMFRAMES_THREADS", raising=False)
    assert _mesher_threads() == 0
    monkeypatch.setenv("SYMFRAMES_THREADS", "1")
    assert _mesher_threads() == 1
    monkeypatch.delenv("SYMFRAMES_THREADS")
    monkeypatch.setattr(parallel, "_threads", None)
    old = parallel.threads()
    try:
        parallel.set_threads(3)
        assert _mesher_threads() == 3
    finally:
        parallel.set_threads(old)


def test_ritz_recorder_finds_the_smallest_eigenpairs_while_cg_runs():
    """eigCG: with a basis of 24 vectors, restarted many times, the recorded
    Ritz pairs of M^-1 A match the true smallest ones."""
    rng = np.random.default_rng(0)
    n = 600
    spectrum = np.r_[[1e-4, 3e-4, 1e-3, 2e-3], rng.uniform(0.1, 1.0, n - 4)]
    Q = np.linalg.qr(rng.normal(size=(n, n)))[0]
    A = (Q * spectrum) @ Q.T
    m_diag = rng.uniform(0.5, 2.0, n)  # preconditioner M = diag(m_diag)
    rec = RitzRecorder(n, nev=5, m=24)
    res = pcg(lambda v: A @ v, rng.normal(size=n), lambda r: r / m_diag, rtol=1e-10, maxiter=2000,
              recorder=rec)
    assert res.converged and res.iterations > 3 * rec.m  # several restarts happened
    lam, U = rec.vectors()
    true = np.sort(np.linalg.eigvals(A / m_diag[:, None]).real)[:4]
    assert np.allclose(lam[:4], true, rtol=1e-6)
    for i in range(4):  # A u = lambda M u, to single precision (the basis is kept in float32; |A| ~ 1)
        u = U[:, i]
        assert np.linalg.norm(A @ u - lam[i] * m_diag * u) <= 1e-5 * np.linalg.norm(u)


def test_row_split_products_work_in_a_forked_child(block_laplacian):
    """A child forked after the pool started (multiprocessing's fork, as the
    LU baseline does) gets a fresh pool instead of waiting on dead threads."""
    import multiprocessing as mp

    A = block_laplacian
    old = parallel.threads()
    parallel.set_threads(2)
    try:
        P = parallel.RowSplitMatrix(A, 2)
        x = np.ones(A.shape[0])
        P @ x  # starts the pool in this process
        ctx = mp.get_context("fork")
        with ctx.Pool(1) as pool:
            y = pool.apply_async(_product_in_child, (A, x)).get(timeout=600)  # catches a deadlock only
        assert np.array_equal(y, A @ x)
    finally:
        parallel.set_threads(old)


def _product_in_child(A, x):
    return parallel.RowSplitMatrix(A, 2) @ x


def test_pcg_stops_once_the_solution_is_known_to_be_small(block_laplacian):
    """The LM's convergence check near the minimum (volume3d.solve): CG
    stops as soon as its iterate is known to be below a bound, long before
    the residual is small, and never stops early for a bound the solution
    exceeds."""
    A = block_laplacian
    b = np.random.default_rng(2).normal(size=A.shape[0])
    jacobi = 1.0 / A.diagonal()
    full = pcg(lambda x: A @ x, b, lambda r: jacobi * r, rtol=1e-10, maxiter=5000)
    assert full.converged and not full.small_solution
    size = float(np.linalg.norm(full.x))
    early = pcg(lambda x: A @ x, b, lambda r: jacobi * r, rtol=1e-10, maxiter=5000,
                small=(np.linalg.norm, 2.0 * size, 20))
    assert early.small_solution and not early.converged
    assert 20 <= early.iterations < full.iterations
    assert np.linalg.norm(early.x) <= 2.0 * size
    for bound in (0.1 * size, 0.5 * size):
        res = pcg(lambda x: A @ x, b, lambda r: jacobi * r, rtol=1e-10, maxiter=5000,
                  small=(np.linalg.norm, bound, 20))
        assert res.converged and not res.small_solution
        assert res.iterations == full.iterations
