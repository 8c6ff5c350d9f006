"""The hex-meshing stage's parts on inputs with known answers (no meshing)."""

import itertools
from types import SimpleNamespace

import numpy as np
import pytest

from solver.examples import icosphere
from solver.hexmesh import smooth
from solver.hexmesh.curve_edges import CurveEdgeMesh, _prism_tets, split_edges
from solver.hexmesh.extract import extract_hexes
from solver.hexmesh.quality import (
    HEX_CORNER_NEIGHBOURS,
    boundary_quads,
    cell_sizes,
    edge_valences,
    euler_characteristic,
    hausdorff_distance,
    scaled_jacobian,
    surface_left,
)
from solver.hexmesh.quantize import greedy_round
from solver.hexmesh.seamless import AffineUnionFind, IntegerSpace
from solver.hexmesh.smooth import (
    BoundaryMotion,
    CornerEnergy,
    active_vertices,
    foldover_free,
    local_order,
    optimise,
    surface_lost,
)
from solver.linalg.rotations import CUBE_GROUP
from solver.mesh.tetmesh import TetMesh
from solver.surface.trisurface import TriSurface, closest_point_on_triangles

CUBE = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)


def grid_tets(nx, ny, nz, h=1.0):
    """A box of nx x ny x nz cubes, six Kuhn tets each (conforming)."""
    idx = np.arange((nx + 1) * (ny + 1) * (nz + 1)).reshape(nx + 1, ny + 1, nz + 1)
    V = np.stack(np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij"), -1)
    V = V.reshape(-1, 3) * h
    T = []
    for i, j, k in itertools.product(range(nx), range(ny), range(nz)):
        c = [idx[i + a, j + b, k + d] for a, b, d in itertools.product((0, 1), repeat=3)]  # bit order a b d
        for perm in itertools.permutations(range(3)):
            path = [0]
            cur = 0
            for ax in perm:
                cur |= 1 << (2 - ax)
                path.append(cur)
            T.append([c[p] for p in path])
    return TetMesh(V.astype(float), np.array(T))


def test_split_edges_together_is_splitting_them_one_after_another():
    """split_edges splits the edges that share no tet in one vectorised round,
    then the rest: the same tets as splitting each edge in the order given
    (every tet around it in two at its midpoint), duplicates and edges that
    share tets included, up to the numbering of the new vertices."""
    mesh = grid_tets(3, 3, 2)
    n = mesh.n_vertices
    cem = CurveEdgeMesh(mesh, np.arange(n), np.arange(mesh.n_tets), [], np.zeros(0, np.int64),
                        {}, np.c_[mesh.tets, np.full(mesh.n_tets, -1)])
    rng = np.random.default_rng(3)
    T = mesh.tets[rng.choice(mesh.n_tets, 40)]
    E = np.r_[T[:, [0, 1]], T[:, [1, 2]], T[:, [0, 1]][:5]]  # neighbours in a tet, and repeats

    X, tets, parent = mesh.vertices.copy(), mesh.tets.copy(), np.arange(mesh.n_tets)
    for a, b in E.tolist():  # the reference: one edge after another
        around = np.nonzero((tets == a).any(axis=1) & (tets == b).any(axis=1))[0]
        if not len(around):
            continue
        m = len(X)
        X = np.vstack([X, 0.5 * (X[a] + X[b])])
        c1, c2 = tets[around].copy(), tets[around].copy()
        c1[c1 == a], c2[c2 == b] = m, m
        keep = np.ones(len(tets), bool)
        keep[around] = False
        tets, parent = np.vstack([tets[keep], c1, c2]), np.r_[parent[keep], parent[around], parent[around]]

    def cells(V, Tt, P):
        return sorted(tuple(sorted(map(tuple, np.round(V[t], 12).tolist()))) + (int(p),) for t, p in zip(Tt, P))

    out = split_edges(cem, E)
    assert out.mesh.n_vertices == len(X) > n and out.stats["split_edges"] == len(X) - n
    assert cells(out.mesh.vertices, out.mesh.tets, out.parent) == cells(X, tets, parent)
    assert np.all(TetMesh._signed_volumes(out.mesh.vertices, out.mesh.tets) > 0)


# ------------------------------------------------------------------ quality


def test_scaled_jacobian_is_one_for_a_cube_and_negative_when_inverted():
    H = np.arange(8)[None]
    assert scaled_jacobian(CUBE, H)[0] == pytest.approx(1.0)
    sheared = CUBE.copy()
    sheared[4:, 0] += 1.0  # top face shifted by one edge length: corners at 45 degrees
    assert scaled_jacobian(sheared, H)[0] == pytest.approx(np.sqrt(0.5))
    flipped = CUBE.copy()
    flipped[4:, 2] = -1.0
    assert scaled_jacobian(flipped, H)[0] < 0


def test_cell_sizes_are_the_mean_edge_lengths():
    H = np.arange(8)[None]
    assert cell_sizes(CUBE, H) == pytest.approx([1.0])
    # stretched by 2 along x: four edges of 2, eight of 1
    assert cell_sizes(CUBE * [2.0, 1.0, 1.0], H) == pytest.approx([16.0 / 12.0])
    assert cell_sizes(CUBE * 0.25, H) == pytest.approx([0.25])


def test_boundary_quads_valences_and_euler_characteristic_of_a_block():
    n = 3
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    V = np.stack(np.meshgrid(*[np.arange(n + 1)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
    H = np.array([[idx[i + a, j + b, k + c] for a, b, c in CUBE.astype(int)]
                  for i, j, k in itertools.product(range(n), repeat=3)])
    q, over = boundary_quads(H)
    assert over == 0 and len(q) == 6 * n * n
    assert euler_characteristic(q) == 2
    e, val, onb = edge_valences(H, q)
    assert set(val[~onb]) == {4}
    # outward orientation: the quads' normals point away from the centre
    P = V[q]
    nrm = np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 1])
    assert np.all(np.einsum("ij,ij->i", nrm, P.mean(axis=1) - n / 2) > 0)


def _hex_block(n: int, jitter: float, seed: int = 0):
    """(V, H) of [-1, 1]^3 as n^3 hexahedra, the vertices moved randomly by
    up to jitter of a cell."""
    g = np.linspace(-1.0, 1.0, n + 1)
    V = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    V = V + jitter * (2.0 / n) * np.random.default_rng(seed).uniform(-1, 1, V.shape)
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    H = np.array([[idx[i + a, j + b, k + c] for a, b, c in CUBE.astype(int)]
                  for i, j, k in itertools.product(range(n), repeat=3)])
    return V, H


def _distances_brute(X, V, F):
    """Exact distance from each point of X to the triangles (V, F): every pair."""
    T = V[F]
    out = np.empty(len(X))
    for s in range(0, len(X), 64):
        Y = X[s:s + 64]
        C = closest_point_on_triangles(np.repeat(Y, len(T), axis=0), np.tile(T, (len(Y), 1, 1)))
        out[s:s + 64] = np.linalg.norm(C - np.repeat(Y, len(T), axis=0), axis=1).reshape(len(Y), -1).min(axis=1)
    return out


def _hausdorff_before(S, V, q):
    """The quality stage's measure before it was bounded in memory: every
    surface sample against its 16 nearest boundary triangles, at once."""
    from scipy.spatial import cKDTree

    P = V[q]
    samples = np.vstack([V[np.unique(q)], P.mean(axis=1), 0.5 * (P + np.roll(P, -1, axis=1)).reshape(-1, 3)])
    d1 = S.closest_points(samples)[0]
    T = V[np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])]
    Y = np.vstack([S.V, S.V[S.F].mean(axis=1)])
    k = min(16, len(T))
    _, idx = cKDTree(T.mean(axis=1)).query(Y, k=k)
    C = closest_point_on_triangles(np.repeat(Y, k, axis=0), T[idx.reshape(-1)])
    d2 = np.linalg.norm(C - np.repeat(Y, k, axis=0), axis=1).reshape(len(Y), k).min(axis=1)
    return float(max(d1.max(), d2.max()))


@pytest.mark.parametrize("radius, spike", [(1.2, 0.0), (1.9, 0.0), (1.1, 1.5)])
def test_hausdorff_distance_in_chunks_is_the_exact_one(radius, spike):
    """The chunked, pruned measure equals the exhaustive one (every sample
    against every triangle, both ways) and the measure before it, to 1e-12
    of the diagonal, whichever side is the farther (radius 1.2: the block's
    corners; 1.9: the sphere; a spike: one surface vertex), in one chunk or
    in chunks of 5 samples."""
    V, H = _hex_block(4, 0.15)
    q, _ = boundary_quads(H)
    Vs, Fs = icosphere(2, radius)
    Vs[0] *= 1.0 + spike
    S = TriSurface(Vs, Fs)
    P = V[q]
    samples = np.vstack([V[np.unique(q)], P.mean(axis=1), 0.5 * (P + np.roll(P, -1, axis=1)).reshape(-1, 3)])
    tri = np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    d1 = _distances_brute(samples, Vs, Fs).max()
    d2 = _distances_brute(np.vstack([Vs, Vs[Fs].mean(axis=1)]), V, tri).max()
    exact = max(d1, d2)
    assert (d2 > d1) == (radius > 1.5 or spike > 0)  # each side is the farther one somewhere
    diag = S.bbox_diagonal
    for chunk in (5, 1 << 15):
        assert abs(hausdorff_distance(S, V, q, chunk=chunk) - exact) <= 1e-12 * diag
    assert abs(_hausdorff_before(S, V, q) - exact) <= 1e-12 * diag
    assert hausdorff_distance(S, V, q[:0]) == np.inf


def test_smoothing_that_pulls_the_grid_off_a_tip_is_told_where():
    """The boundary of a coarse cube-sphere on a finely tessellated ellipsoid
    (semi-axes 1.5, 1, 0.7), its grid lines beside the +x tip pushed a cell
    away along the surface, as smoothing evened out the cells there:
    surface_left finds the tip's samples off the new boundary (exactly,
    as the exhaustive measure does), and surface_lost marks the boundary
    vertices around that tip only (the -x tip and the rest kept); with the
    grid as extracted, or moved where the boundary stays as close, nothing
    is marked."""
    from testkit.hexnet import boundary_surface, cube_sphere

    axes = np.array([1.5, 1.0, 0.7])
    Vf, Hf = cube_sphere(10, axes=axes)
    Vs, Fs, _ = boundary_surface(Vf, Hf)
    S = TriSurface(Vs, Fs)
    V0, H = cube_sphere(6, axes=axes)
    q, _ = boundary_quads(H)
    onb = np.unique(q)
    # beside the +x tip, the grid spread away from it, back onto the ellipsoid
    W = V0.copy()
    near = onb[(V0[onb, 0] > 1.35) & (np.linalg.norm(V0[onb, 1:], axis=1) > 1e-6)]  # the tip's two rings
    W[near, 1:] *= 1.6
    W[near, 0] = axes[0] * np.sqrt(np.maximum(0.0, 1.0 - np.sum((W[near, 1:] / axes[1:]) ** 2, axis=1)))
    tol = 1.05 * hausdorff_distance(S, V0, q)  # the extracted grid's own chords are within it
    X, d, quad = surface_left(S, W, q, tol)
    assert len(X) and np.all(X[:, 0] > 1.2) and np.all(d > tol)  # about the +x tip
    tri = np.vstack([q[:, [0, 1, 2]], q[:, [0, 2, 3]]])
    exact = _distances_brute(np.vstack([Vs, Vs[Fs].mean(axis=1)]), W, tri)  # every sample, every triangle
    assert np.sum(exact > tol) == len(X) and abs(d.max() - exact.max()) <= 1e-12 * S.bbox_diagonal
    lost = surface_lost(V0, W, q, S, tol)
    assert lost.any() and np.all(V0[lost, 0] > 0.9) and not lost[~np.isin(np.arange(len(V0)), onb)].any()
    assert not surface_lost(V0, V0, q, S, tol).any()
    # a small move along the surface that keeps the boundary as close
    Wk = V0.copy()
    Wk[near, 1:] *= 1.02
    assert not surface_lost(V0, Wk, q, S, tol).any()



# ------------------------------------------------------------------ rounding


def test_greedy_round_matches_the_integer_optimum_of_a_small_coupled_quadratic():
    rng = np.random.default_rng(3)
    for _ in range(20):
        A = rng.standard_normal((3, 3))
        S = A @ A.T + 3 * np.eye(3)
        c = rng.uniform(-5, 5, 3)
        w, shift = greedy_round(S, c)
        assert np.all(w == np.rint(w))
        best = min((0.5 * np.array(k) @ S @ np.array(k) - c @ np.array(k), k)
                   for k in itertools.product(range(-8, 9), repeat=3))
        e = 0.5 * w @ S @ w - c @ w
        # greedy is not exact in general; on well-conditioned problems it is within one step
        assert e <= best[0] + 0.5 * np.max(np.diag(S)) + 1e-9
        assert shift <= 0.5 + 1e-9


def test_integer_space_keeps_unit_pivots_integer():
    isp = IntegerSpace(4)
    isp.add(np.array([1.0, 1.0, -1.0, 0.0]))  # t0 + t1 = t2
    isp.add(np.array([0.0, 1.0, 0.0, -2.0]))  # t1 = 2 t3
    N = isp.N
    assert N.shape == (4, 2)
    assert np.allclose(N, np.rint(N)) and isp.nonunimodular == 0
    k = np.array([3.0, -2.0])
    t = N @ k
    assert t[0] + t[1] == t[2] and t[1] == 2 * t[3]


def test_affine_union_find_fixes_a_quarter_turn_cycle_and_collects_tau_rows():
    uf = AffineUnionFind(3, 2)
    # (I - R) x = e tau for a quarter turn about z: x0 + x1 = tau0, -x0 + x1 = tau1
    uf.add([(0, 1.0), (1, 1.0)], np.array([-1.0, 0.0]))
    uf.add([(0, -1.0), (1, 1.0)], np.array([0.0, -1.0]))
    r0, s0, o0 = uf.find(0)
    r1, s1, o1 = uf.find(1)
    assert r0 == r1 and r0 in uf.fixed
    tau = np.array([3.0, 1.0])
    x_root = uf.fixed[r0] @ tau
    x0, x1 = s0 * x_root + o0 @ tau, s1 * x_root + o1 @ tau
    assert x0 + x1 == pytest.approx(3.0) and -x0 + x1 == pytest.approx(1.0)
    uf.add([(2, 1.0), (2, -1.0)], np.array([1.0, 1.0]))  # 0 = tau0 + tau1
    assert len(uf.tau_rows) == 1


def test_foldover_free_gradient_matches_finite_differences():
    rng = np.random.default_rng(1)
    J = np.eye(3) + 0.3 * rng.standard_normal((5, 3, 3))
    J[0, 2] *= -1  # one inverted
    f, g = foldover_free(J, 0.05)
    d = 1e-6
    for i, j in [(0, 0), (1, 2), (2, 1)]:
        Jp = J.copy()
        Jp[:, i, j] += d
        fp, _ = foldover_free(Jp, 0.05)
        assert np.allclose((fp - f) / d, g[:, i, j], rtol=1e-4, atol=1e-5)


def test_the_corner_energy_in_blocks_is_the_sum_over_corners_with_its_gradient(monkeypatch):
    """CornerEnergy (blocks of CHUNK corners, one scatter per coordinate)
    against (f / F_CUBE)^POWER summed corner by corner, with a size field,
    blocks that do not divide the corners, and a vertex no hex uses; its
    gradient against finite differences, at the power smoothing uses and at
    1 (the plain sum of f); and a Morton renumbering changes nothing."""
    V, H = _hex_block(4, 0.3, seed=3)
    V = np.vstack([V, [[5.0, 5.0, 5.0]]])  # used by no hex: zero gradient
    V[H[0, 0]] += 0.6  # a few corners inverted
    cell = np.random.default_rng(4).uniform(0.4, 0.6, len(H))
    monkeypatch.setattr(smooth, "CHUNK", 100)  # 512 corners: five blocks, the last partial
    eps = 0.05
    P = V[H]
    J = (P[:, HEX_CORNER_NEIGHBOURS] - P[:, :, None, :]) / cell[:, None, None, None]  # rows: the corner's edges
    f, _ = foldover_free(J.reshape(-1, 3, 3), eps)
    assert smooth.POWER > 1.0
    for power in (1.0, smooth.POWER):
        e, g = CornerEnergy(H, cell, len(V), power)(V, eps)
        assert e == pytest.approx(float(np.sum((f / smooth.F_CUBE) ** power if power != 1.0 else f)), rel=1e-12)
        assert np.all(g[-1] == 0.0)
        d = 1e-6
        for v, k in [(int(H[0, 0]), 0), (int(H[10, 3]), 2), (int(H[-1, 6]), 1)]:
            Vp = V.copy()
            Vp[v, k] += d
            ep, _ = CornerEnergy(H, cell, len(V), power)(Vp, eps, with_grad=False)
            Vm = V.copy()
            Vm[v, k] -= d
            em, _ = CornerEnergy(H, cell, len(V), power)(Vm, eps, with_grad=False)
            assert (ep - em) / (2 * d) == pytest.approx(g[v, k], rel=1e-4, abs=1e-7 * abs(g).max())
    e, g = CornerEnergy(H, cell, len(V))(V, eps)  # the default: the plain sum of f
    order = local_order(V)
    assert sorted(order) == list(range(len(V)))
    rank = np.empty_like(order)
    rank[order] = np.arange(len(V))
    e2, g2 = CornerEnergy(rank[H], cell, len(V))(V[order], eps)
    assert e2 == pytest.approx(e, rel=1e-12) and np.allclose(g2, g[order], rtol=1e-10, atol=1e-12)


def test_smoothing_moves_the_poor_cells_and_two_rings_and_holds_the_grid():
    V, H = _hex_block(10, 0.0)
    centre = int(np.argmin(np.linalg.norm(V, axis=1)))
    V[centre] += 0.15  # a corner pushed 0.75 of a cell off the grid: its 8 cells poor
    sj = scaled_jacobian(V, H)
    assert sj.min() < 0.5 and np.sum(sj < 0.9) == 8
    free = active_vertices(len(V), H, sj)
    # the 8 cells' 27 vertices, then one ring (5^3) and two (7^3)
    assert free.sum() == 7**3
    q, _ = boundary_quads(H)
    assert not free[np.unique(q)].any()
    cells = free[H].any(axis=1)
    motion = BoundaryMotion(V, q, np.zeros((0, 2), int), None, (np.zeros((0, 3)), np.zeros((0, 3))),
                            np.zeros(len(V), bool)).held(free)
    W = optimise(V, H[cells], 0.2, motion)
    assert np.array_equal(W[~free], V[~free])
    assert scaled_jacobian(W, H).min() > 0.95


def test_the_power_mean_raises_the_least_cell_the_plain_sum_leaves():
    """One vertex of an interior line of a 6^3 block pushed sideways by 0.7
    of a cell and held, with the line and the boundary (as a singular
    curve's vertices are held near their place): the cells round it cannot
    all be cubes, and the sum of the corner energies trades its few worst
    corners against the many beside them; the power mean (POWER) weighs
    them more, and the least cell rises (0.722 -> 0.733) for a mean lower
    by less than 0.001."""
    n = 6
    V, H = _hex_block(n, 0.0)
    q, _ = boundary_quads(H)
    fixed = np.zeros(len(V), bool)
    fixed[np.unique(q)] = True
    line = np.nonzero((np.abs(V[:, 0]) < 1e-9) & (np.abs(V[:, 1]) < 1e-9) & (np.abs(V[:, 2]) < 1 - 1e-9))[0]
    V[line[len(line) // 2], 0] += 0.7 * 2.0 / n
    fixed[line] = True
    motion = BoundaryMotion(V, q, np.zeros((0, 2), int), None, (np.zeros((0, 3)), np.zeros((0, 3))),
                            fixed).held(~fixed)
    sum_, power = (scaled_jacobian(optimise(V, H, 2.0 / n, motion, power=p), H) for p in (1.0, smooth.POWER))
    assert scaled_jacobian(V, H).min() < sum_.min() < power.min() - 0.005, (sum_.min(), power.min())
    assert power.mean() >= sum_.mean() - 0.001


def test_a_chain_is_not_routed_through_a_vertex_of_a_face_another_curve_pierces():
    """A chain passing within VERTEX_ROUTE of a vertex goes through it, and
    the tets around that vertex lose its frame.  Where the vertex also holds
    a face another curve pierces (two curves a cell apart: curve A 0.07 from
    the grid's vertex column x = y = 2, curve B piercing the faces round that
    column), B's split tets would keep the frames of only two of the face's
    three vertices, their transitions could not wind around B, and the hex
    stage refused the field ("transitions do not close", a generated blob).
    A is not routed there: every split tet of B keeps each of its old
    vertices as a frame source."""
    from solver.hexmesh.curve_edges import curves_on_edges
    from solver.mesh.embed import TetLocator, trace_curve

    mesh = grid_tets(4, 4, 4)
    loc = TetLocator(mesh)
    traces = []
    for x, y in [(2.06, 2.03), (1.8, 2.5)]:  # A, B
        P = np.array([[x, y, z] for z in np.r_[np.linspace(0.0, 3.5, 8), 4.001]])
        t0 = int(loc.locate(P[:1] + [0.0, 0.0, 1e-3])[0])
        bottom = [f for f in mesh.tet_faces[t0]
                  if mesh.face_tets[f].min() < 0 and np.all(mesh.vertices[mesh.faces[f], 2] == 0.0)]
        traces.append(trace_curve(mesh, loc, P, t0, int(bottom[0]), True, "c", 1e-9, strict=False))
    emb = SimpleNamespace(traces=traces, node_region=[], node_tets=[])
    net = SimpleNamespace(curves=[SimpleNamespace(sigma=0.25, name="")] * 2, source=[0, 1],
                          start_kind=["boundary"] * 2, end_kind=["boundary"] * 2, nodes=[])
    column = {int(i) for i in np.nonzero(np.all(mesh.vertices[:, :2] == 2.0, axis=1))[0]}
    pierced_b = set(mesh.faces[traces[1].faces].reshape(-1).tolist())
    assert column & pierced_b  # the set-up: B pierces faces round A's column

    cem = curves_on_edges(mesh, emb, net)
    routed = set(cem.source_vertex[np.concatenate([c.vertices for c in cem.chains])].tolist()) - {-1}
    assert not routed & pierced_b
    b_tets = np.isin(cem.parent, traces[1].tets)
    old = np.where(cem.mesh.tets < 0, -1, cem.source_vertex[cem.mesh.tets])
    assert np.array_equal(np.sort(cem.frame_sources[b_tets], axis=1), np.sort(old[b_tets], axis=1))


# ------------------------------------------------------------- node balls


def test_prism_split_is_positive_and_neighbouring_prisms_agree():
    rng = np.random.default_rng(0)
    skin = rng.standard_normal((6, 3))
    skin /= np.linalg.norm(skin, axis=1, keepdims=True)
    P = np.vstack([skin * 0.5, skin])  # shell 1 (ids 0-5) and the skin (ids 6-11)
    tris = [(0, 1, 2), (0, 2, 3)]  # two skin triangles sharing the edge 0-2
    faces = []
    for tri in tris:
        tets = _prism_tets(list(tri), [v + 6 for v in tri])
        for t in tets:
            X = P[list(t)]
            vol = np.linalg.det(X[1:] - X[0])
            assert abs(vol) > 1e-9
            faces += [tuple(sorted(f)) for f in itertools.combinations(t, 3)]
    # the shared quad (0, 2, 8, 6) is cut by the same diagonal from both sides
    shared = [f for f in set(faces) if set(f) <= {0, 2, 6, 8}]
    assert len(shared) == 2 and all(faces.count(f) == 2 for f in shared)


# ------------------------------------------------------------- extraction


def test_extraction_of_the_identity_map_is_the_grid():
    mesh = grid_tets(4, 2, 2, h=0.5)
    cell = 0.25
    U = mesh.vertices[mesh.tets] / cell
    faces = np.nonzero(~mesh.is_boundary_face)[0]
    ab = mesh.face_tets[faces]
    raw = extract_hexes(mesh, SimpleNamespace(faces=faces, tets=ab, transition=np.zeros(len(faces), np.int64)), U,
                        cell)
    assert len(raw.hexes) == 8 * 4 * 4 and raw.lost_corners == 0
    assert np.allclose(scaled_jacobian(raw.vertices, raw.hexes), 1.0)
    assert np.allclose(raw.vertices / cell, np.rint(raw.vertices / cell))


def test_extraction_follows_a_rotated_chart_across_a_cut():
    mesh = grid_tets(4, 2, 2, h=0.5)
    cell = 0.25
    X = mesh.vertices[mesh.tets]
    U = X / cell
    # tets right of x = 1 use a chart turned a quarter about z and shifted
    g = 1 + int(np.argmax([np.allclose(G, [[0, -1, 0], [1, 0, 0], [0, 0, 1]]) for G in CUBE_GROUP[1:]]))
    R, tau = CUBE_GROUP[g], np.array([3.0, -5.0, 2.0])
    right = X.mean(axis=1)[:, 0] > 1.0
    U[right] = np.einsum("ij,tcj->tci", R, U[right]) + tau
    faces = np.nonzero(~mesh.is_boundary_face)[0]
    ab = mesh.face_tets[faces]
    M = np.zeros(len(faces), np.int64)
    M[~right[ab[:, 0]] & right[ab[:, 1]]] = g
    inv = int(np.argmax(np.isclose(np.einsum("kij,ij->k", CUBE_GROUP, R.T), 3.0)))  # R^T
    M[right[ab[:, 0]] & ~right[ab[:, 1]]] = inv
    raw = extract_hexes(mesh, SimpleNamespace(faces=faces, tets=ab, transition=M), U, cell)
    assert len(raw.hexes) == 8 * 4 * 4 and raw.lost_corners == 0 and raw.duplicate_cells == 0
    assert np.allclose(scaled_jacobian(raw.vertices, raw.hexes), 1.0)


def test_a_singular_edge_turns_about_the_curve_even_where_the_frames_lag_its_tangent():
    """The holonomy around a singular chain edge must be a turn about the
    curve: about the frame axis nearest its tangent, or one within
    AXIS_SLACK of it (where a curve's end bends faster than its tets
    resolve, the frames lag: a tet-edge ellipsoid's tip had the turn's axis
    50 degrees off the tangent and another axis 46).  A turn about an axis
    across the curve, or none, is still refused."""
    import importlib

    tr = importlib.import_module("solver.hexmesh.transitions")
    quarter_about = {}
    for g in range(len(CUBE_GROUP)):
        axis, q = tr.rotation_axis_angle(np.array([g]))
        if q[0] == 1:
            quarter_about[int(axis[0])] = g
    frame = np.eye(3)

    def tangent(deg_from_x, toward):  # a unit vector deg_from_x off x, towards axis `toward`
        t = np.zeros(3)
        t[0], t[toward] = np.cos(np.radians(deg_from_x)), np.sin(np.radians(deg_from_x))
        return t

    assert tr.turns_about_curve(quarter_about[0], frame, tangent(10.0, 2))
    # the lagging tip: 50 degrees off x, so z is nearer, but within the slack
    assert tr.turns_about_curve(quarter_about[0], frame, tangent(50.0, 2))
    assert not tr.turns_about_curve(quarter_about[0], frame, tangent(tr.AXIS_SLACK + 5.0, 2))
    # a turn about an axis across an aligned curve, and no turn at all
    assert not tr.turns_about_curve(quarter_about[1], frame, tangent(0.0, 2))
    assert not tr.turns_about_curve(0, frame, tangent(0.0, 2))
