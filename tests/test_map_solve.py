"""The reduced solve of the hex map (seamless._Reduced): SuperLU on small
systems, PCG with an AMG V-cycle on large ones (seamless.DIRECT_MAX), and
the stiffened re-solves of integer_grid_map, preconditioned by the first
solve's factorisation or hierarchy instead of a new factorisation each.

A synthetic map system, no meshing: a jittered box of tets whose frames
turn half a turn in a ball in the middle (so the map folds and stiffening
runs), the corners' three coordinates one unknown per vertex, pinned at 0
on the faces x, y, z = 0 and an integer plane each on the faces x, y, z = 1.
"""

import numpy as np
import scipy.sparse as sp

from solver.hexmesh.quantize import greedy_round
from solver.hexmesh.seamless import DIRECT_MAX, MapSystem, _fitting_energy, _grid_map, _Reduced, integer_grid_map
from solver.linalg.multipcg import pcg_columns
from solver.linalg.rotations import exp_so3
from tests.meshes import box_mesh


def _box_system(n=8, cell=0.36, seed=0) -> MapSystem:
    mesh = box_mesh(n, jitter=0.25, seed=seed)
    # the frames of a ball in the middle turned half a turn about z: the map
    # folds around it, after rounding and after stiffening
    centre = mesh.vertices[mesh.tets].mean(axis=1)
    turn = np.zeros((len(mesh.tets), 3))
    turn[np.linalg.norm(centre - 0.5, axis=1) < 0.4, 2] = np.pi
    F = exp_so3(turn)
    nV = mesh.n_vertices
    X = mesh.vertices
    # column of scalar (v, a): a free unknown, an integer plane (on the
    # face a = 1) or -1 (pinned at 0 on the face a = 0)
    col = np.full((nV, 3), -1, dtype=np.int64)
    free = (X > 1e-9) & (X < 1 - 1e-9)
    col[free] = np.arange(int(free.sum()))
    nr = int(free.sum())
    top = X > 1 - 1e-9
    col[top] = nr + np.nonzero(top)[1]
    T = mesh.tets
    rows = (12 * np.arange(len(T))[:, None, None] + 3 * np.arange(4)[None, :, None] + np.arange(3)).reshape(-1)
    cols = col[T].reshape(-1)
    ok = cols >= 0
    Xm = sp.csr_matrix((np.ones(ok.sum()), (rows[ok], cols[ok])), shape=(12 * len(T), nr + 3))
    LX, Q, b, coef, vol = _fitting_energy(mesh, F, cell, Xm)
    integer = np.zeros(nr + 3, bool)
    integer[nr:] = True
    return MapSystem(mesh, F, cell, None, None, Xm, Q, b, integer, vol, coef, np.zeros(0), LX)


def _refactorised(ms: MapSystem, red: _Reduced, iters=6, factor=5.0):
    """integer_grid_map's stiffening as it was: a new factorisation of the
    whole stiffened energy per iteration.  Returns (best map, [(weights,
    map) per iteration, the rounded map first])."""
    w, shift = greedy_round(red.S, red.c)
    LX, weight = ms.least_squares()
    best = cur = _grid_map(ms, red.z(w))
    wts = weight.copy()
    steps = [(wts, cur)]
    nT = len(ms.tet_weight)
    for it in range(1, iters + 1):
        bad = cur.det <= 0
        if not bad.any():
            break
        wts = wts * np.repeat(np.where(bad, factor, 1.0), 9)
        Q = (LX.T @ sp.diags(wts) @ LX).tocsr()
        b = np.asarray(LX.T @ (wts * np.tile(np.eye(3).reshape(-1), nT))).ravel()
        cur = _grid_map(ms, _Reduced(Q, b, ms.integer, direct_max=np.inf).z(w), stiffening=it)
        steps.append((wts, cur))
        if cur.inverted < best.inverted or (cur.inverted == best.inverted and cur.det.min() > best.det.min()):
            best = cur
    return best, steps


def test_the_scalable_solve_and_the_factorisation_give_the_same_reduced_energy_and_maps():
    ms = _box_system()
    direct = _Reduced(ms.Q, ms.b, ms.integer)
    scalable = _Reduced(ms.Q, ms.b, ms.integer, direct_max=0)  # forced: PCG with AMG
    assert len(direct.iy) <= DIRECT_MAX
    assert direct.method == "lu" and not direct.iterations
    assert scalable.method == "amg-pcg" and 0 < scalable.iterations[0] < 200, scalable.iterations
    scale = np.abs(direct.Z).max() + np.abs(direct.y0).max()
    assert np.abs(scalable.y0 - direct.y0).max() <= 1e-10 * scale
    assert np.abs(scalable.Z - direct.Z).max() <= 1e-10 * scale
    assert np.allclose(scalable.S, direct.S, rtol=1e-10, atol=1e-10 * np.abs(direct.S).max())
    assert np.allclose(scalable.relaxed(), direct.relaxed(), rtol=0, atol=1e-10)
    w_d, _ = greedy_round(direct.S, direct.c)
    w_s, _ = greedy_round(scalable.S, scalable.c)
    assert np.array_equal(w_d, w_s)
    # the same stiffened maps as a new factorisation per stiffening, from
    # either solver's preconditioner: each iteration's solve, and the best map
    ref, steps = _refactorised(ms, direct)
    assert len(steps) == 7 and ref.stiffening >= 1, "the map should fold and be stiffened six times"
    LX, weight = ms.least_squares()
    target = np.tile(np.eye(3).reshape(-1), len(ms.tet_weight))
    for direct_max in (DIRECT_MAX, 0):
        red = _Reduced(ms.Q, ms.b, ms.integer, direct_max=direct_max)
        for (_, prev), (wts, want) in zip(steps[:-1], steps[1:]):
            rows = np.nonzero(wts != weight)[0]
            dw = wts[rows] - weight[rows]
            L = LX[rows]
            z = red.stiffened(L.T @ sp.diags(dw) @ L, L.T @ (dw * target[rows]), w_d, prev.z[red.iy])
            assert np.abs(z - want.z).max() <= 1e-10 * np.abs(want.z).max()
        # PCG, its preconditioner built again where it slowed down (this map
        # folds on a fifth of its tets: with the first factorisation alone
        # the sixth solve took 407 steps, with the first hierarchy 623;
        # 59 and 107 at most with the refreshes)
        stiff = red.iterations[1:] if red.method == "amg-pcg" else red.iterations
        assert len(stiff) == 6 and max(stiff) < (100 if red.method == "lu" else 200), (red.method, red.iterations)
        red = _Reduced(ms.Q, ms.b, ms.integer, direct_max=direct_max)
        gm = integer_grid_map(ms, red)
        assert gm.stiffening == ref.stiffening and gm.inverted == ref.inverted
        assert np.array_equal(gm.z[red.iw], ref.z[red.iw])
        assert np.abs(gm.z - ref.z).max() <= 1e-10 * np.abs(ref.z).max()
        assert np.allclose(gm.det, ref.det, rtol=0, atol=1e-10 * np.abs(ref.det).max())


def test_pcg_columns_solves_every_column_from_any_start():
    rng = np.random.default_rng(1)
    M = rng.standard_normal((60, 60))
    A = M @ M.T + 60 * np.eye(60)
    B = rng.standard_normal((60, 4))
    B[:, 2] = 0.0  # a zero column is solved by zero
    Dinv = 1.0 / np.diag(A)
    exact = np.linalg.solve(A, B)
    for X0 in (None, rng.standard_normal((60, 4))):
        r = pcg_columns(lambda X: A @ X, B, lambda R: Dinv[:, None] * R, X0=X0, rtol=1e-12)
        assert r.converged and r.X.shape == B.shape
        assert np.allclose(r.X, exact, rtol=0, atol=1e-10)
        assert np.all(r.X[:, 2] == 0.0)
    # a vector gives a vector (matvec and precond still see (n, 1) blocks)
    one = pcg_columns(lambda X: A @ X, B[:, 0], lambda R: Dinv[:, None] * R, rtol=1e-12)
    assert one.X.shape == (60,) and np.allclose(one.X, exact[:, 0], rtol=0, atol=1e-10)
