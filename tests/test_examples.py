"""End-to-end solves of the built-in domains (issue 2's acceptance checks).

Each domain is meshed and solved once per session (tests/conftest.py:
``solved`` shares the result, ``meshed`` gives a test a problem of its own
on the same mesh to solve again); the tests then judge the field:
alignment, singular structure, adaptation, integrability and its
refinement, independence of the initial guess and of the development root.
fTetWild's meshes vary slightly from run to run, so the checks are about
properties every mesh of the given resolution must have.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from solver import FieldProblem, Options
from solver.analysis.measures import (
    loglog_slope,
    matched_singular_faces,
    monodromy_angles,
    normal_adaptation,
    omega_frame_mismatch,
    omega_singular_faces,
    subdomain_faces,
    tangent_adaptation,
    vertices_near_polylines,
)
from solver.examples import load_example
from solver.linalg.rotations import cross_distance, exp_so3

# every test here runs tet meshing (fTetWild/TetGen), itself or through the session fixtures
pytestmark = pytest.mark.mesher

# None: the default edge length, whose solve the hex, storage and diagnosis
# tests share (the cylinder's fTetWild run is its costliest part: 10-15 s)
H = {"cube": 0.3, "cylinder": None, "ball": 0.18, "torus": 0.15}


@pytest.fixture(scope="module")
def at(solved):
    """at(name, h=None): the session's solve of an example at edge length h
    (default: H; where that is None, the default options')."""

    def solve_at(name, h=None):
        h = h or H[name]
        return solved(name) if h is None else solved(name, edge_length=h)

    return solve_at


# ------------------------------------------------------------------ helpers
def network_neighbourhood(result) -> np.ndarray:
    """Faces belonging to the network's discretisation: those it passes
    through (pierced faces, node regions, curve-end triangles), the faces
    around node regions and around the tets a singular curve crosses, and
    faces with a vertex closer to a curve than the tube radius allows for a
    tube vertex (where fTetWild moved one).  Around a crossed tet the field
    turns fast, and an edge there can turn by more than 45 degrees (49 seen
    on a refined cylinder, 0.35 h from a curve's end on the boundary), which
    closest-rotation matching reads as a jump."""
    mesh, emb = result.mesh, result.embedding
    out = np.zeros(mesh.n_faces, bool)
    out[emb.network_faces(mesh)] = True
    near = np.zeros(mesh.n_vertices, bool)
    if len(emb.node_region_tets):
        near[mesh.tets[emb.node_region_tets].ravel()] = True
    for c, tr in zip(result.problem.network.curves, emb.traces):
        if c.sigma != 0:
            near[mesh.tets[tr.tets].ravel()] = True
    curves = [c.points for c in result.problem.network.curves]
    if curves:
        h = result.problem.edge_length
        near |= vertices_near_polylines(mesh.vertices, curves, 0.3 * h)
    out |= near[mesh.faces].any(axis=1)
    return out


def face_neighbours(mesh) -> sp.csr_matrix:
    """Faces sharing an edge."""
    fe = mesh.face_edges
    A = sp.csr_matrix((np.ones(fe.size), (np.repeat(np.arange(mesh.n_faces), 3), fe.ravel())),
                      shape=(mesh.n_faces, mesh.n_edges))
    return (A @ A.T).tocsr()


def check_singular_structure(result):
    """Singular faces of the matched frames lie on the network; every face a
    curve pierces is singular, or its singularity sits in an adjacent face
    (matching cannot tell which when an edge turns by ~45 degrees)."""
    mesh, emb = result.mesh, result.embedding
    sing, _ = matched_singular_faces(mesh, result.frames)
    hood = network_neighbourhood(result)
    spurious = np.nonzero(sing & ~hood)[0]
    assert len(spurious) == 0, f"{len(spurious)} singular faces away from the network, e.g. at " \
                               f"{mesh.vertices[mesh.faces[spurious[0]]].mean(0)}"
    pierced = (emb.pierce_count > 0) & ~emb.face_excluded
    missing = np.nonzero(pierced & ~sing)[0]
    nb = face_neighbours(mesh)
    displaced = (nb[missing] @ (sing & ~pierced).astype(float)) > 0
    assert np.all(displaced), f"{int((~displaced).sum())} pierced faces without any singularity nearby"
    assert sing[pierced].mean() > 0.85, f"only {sing[pierced].mean():.0%} of the pierced faces are singular"
    return sing


def check_omega_singular_set(result):
    """omega-matched singular faces: every pierced face, and nothing outside
    the network's faces (pierced, node regions, curve ends)."""
    mesh, emb = result.mesh, result.embedding
    sing = omega_singular_faces(mesh, result.omega, result.frames)
    net = np.zeros(mesh.n_faces, bool)
    net[emb.network_faces(mesh)] = True
    assert not np.any(sing & ~net), int((sing & ~net).sum())
    pierced = (emb.pierce_count > 0) & ~emb.face_excluded
    assert pierced.sum() > 0 and np.all(sing[pierced]), int((pierced & ~sing).sum())


def regular_monodromy_deg(result) -> np.ndarray:
    mesh = result.mesh
    net = np.zeros(mesh.n_faces, bool)
    net[result.embedding.network_faces(mesh)] = True
    regular = np.nonzero(~net & ~mesh.is_boundary_face)[0]
    return np.degrees(monodromy_angles(mesh, result.omega, regular))


def check_axis_aligned(result):
    """The cube's field is the identity cross.  Snapping (snapping.py) puts
    the tet mesh's boundary on the cube's planes, and the field is then
    exact; where a move had to be undone a face keeps fTetWild's tilt (up to
    1.6 degrees seen at edge length 0.15 without snapping), and the frames
    may turn as much as the boundary they are adapted to, and no more."""
    mesh = result.mesh
    dev = np.degrees(cross_distance(result.frames, np.broadcast_to(np.eye(3), result.frames.shape)))
    n = mesh.face_normals[mesh.boundary_faces]
    tilt = np.degrees(np.arccos(np.clip(np.abs(n).max(axis=1), 0.0, 1.0))).max()
    assert dev.max() <= tilt + 1e-6, (dev.max(), tilt)
    assert np.median(dev) <= 1e-3, np.median(dev)


# -------------------------------------------------------------------- cube
def test_cube_frames_are_axis_aligned(at):
    r = at("cube")
    check_axis_aligned(r)
    sing, _ = matched_singular_faces(r.mesh, r.frames)
    assert not sing.any()
    assert r.report.lm.converged


@pytest.mark.slow
def test_lm_converges_on_a_field_without_turning(meshed):
    """The cube's field does not turn (omega = 0): steps measured relative
    to omega alone stay at a fixed fraction of round-off there, and LM ran
    into its iteration cap from the linear start."""
    p = meshed("cube", edge_length=H["cube"])
    for init in ("zero", "linear", "random"):
        r = p.solve(init=init)
        lm = r.report.lm
        assert lm.converged and lm.n_iterations <= 12, (init, lm.n_iterations, lm.reason)
        # 1e-8 rad (6e-7 degrees): the random start stops on the gradient
        # test, at 1e-13 of its large first gradient, and its omega ended at
        # 7e-11 to 1.0e-9 on 70 fresh meshes (one above 1e-9), the zero start's
        # at 3e-14 to 2e-10
        assert np.abs(r.omega).max() <= 1e-8, (init, np.abs(r.omega).max())


# ------------------------------------------------------------------- torus
@pytest.mark.slow
def test_torus_has_no_singularity_and_is_adapted(at):
    """A smooth solid torus: the frames must twist once around each meridian
    (SO(3) loop parity), and then need no singularity.  The twist turns the
    frames by ~3 rad per unit length, 20-55 degrees per edge at this
    resolution, so closest-rotation matching misreads some edges as quarter
    turns; the omega-aware matching must find no singular face.  Every face
    the closest-rotation matching flags must have an edge where the two
    matchings can differ: |omega| plus the edge's omega/frame mismatch
    (the monodromy off the development tree, a few degrees) reaches 45
    degrees.  (|omega| alone is not enough: an edge with |omega| = 44.99
    degrees, frames 45.04 apart, was flagged on 1 of 40 fresh meshes.)"""
    r = at("torus")
    mesh = r.mesh
    assert not omega_singular_faces(mesh, r.omega, r.frames).any()
    mismatch = omega_frame_mismatch(mesh, r.omega, r.frames)
    # (8 fresh meshes: median 0.12-0.13 degrees, largest 1.9-2.9)
    assert np.degrees(np.median(mismatch)) < 0.5 and np.degrees(mismatch.max()) < 6.0
    sing, _ = matched_singular_faces(mesh, r.frames)
    reach = np.linalg.norm(r.omega, axis=1) + mismatch
    fast = reach[mesh.face_edges].max(axis=1) >= np.pi / 4
    assert sing.any() and not np.any(sing & ~fast), int((sing & ~fast).sum())
    # mean normal adaptation, 40 fresh meshes: 0.63-0.95 degrees (mean
    # 0.79, sd 0.08); 1.0 was 2.5 sd away
    na = np.degrees(normal_adaptation(mesh, r.frames))
    assert na.mean() <= 1.2, na.mean()


# --------------------------------------------------- cylinder and the ball
@pytest.mark.slow
@pytest.mark.parametrize("name", ["cylinder", "ball"])
def test_singular_structure_matches_the_network(at, name):
    check_singular_structure(at(name))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cylinder", "ball"])
def test_omega_matched_singular_faces_are_exactly_the_network(at, name):
    """Matched against the frame omega carries across each edge (not fooled
    by edges turning ~45 degrees), the singular faces are the network's:
    every pierced face, and nothing outside the network's faces (pierced,
    node regions, curve ends)."""
    check_omega_singular_set(at(name))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cylinder", "ball"])
def test_frames_are_adapted_to_curves_and_boundary(at, name):
    r = at(name)
    _, ta = tangent_adaptation(r)
    assert len(ta) > 0
    assert np.degrees(ta).mean() <= 2.0, np.degrees(ta).mean()
    fixed = r.problem.boundary.is_feature_vertex
    na = np.degrees(normal_adaptation(r.mesh, r.frames))[~fixed]
    assert na.mean() <= 1.7, na.mean()


@pytest.mark.slow
def test_frames_do_not_depend_on_the_turn_of_the_2d_field(at, meshed):
    """The 2D field is defined up to one turn about the normals (§3.4) and a
    common shift of the alphas of Eq. 20 leaves omega unchanged; the 3D field
    must not turn with it: the quarter turns around the interior curves fix
    that turn (§4.2.3).  (The turned field is solved on a copy of the solved
    problem: the same mesh, embedding and boundary field.)"""
    r = at("ball")
    p = meshed("ball", edge_length=H["ball"])
    bf = p.boundary
    bf.E0 = exp_so3(0.5 * bf.normals) @ bf.E0
    turned = p.solve()
    assert np.degrees(cross_distance(r.frames, turned.frames)).max() <= 0.01
    _, ta = tangent_adaptation(turned)
    assert np.degrees(ta).mean() <= 2.0


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cylinder", "ball"])
def test_monodromy_is_small(at, name):
    ang = regular_monodromy_deg(at(name))
    assert ang.mean() <= 0.1, ang.mean()


@pytest.mark.slow
def test_monodromy_falls_under_refinement(at):
    """Eq. 9 on a fixed subdomain a quarter unit away from the curves and the
    boundary (the paper's Fig. 15 measures away from the singular curves)."""
    # the session's solves at 0.3 (the independence tests') and at the default (0.18): slopes
    # 2.42-2.62 over four fresh pairs at 0.3 and 0.2; with 0.16 too, 2.4 (2.1 with 0.14); at 0.4 the
    # subdomain keeps 40-249 faces, and the mean is not yet falling (0.00061-0.00074 degrees against
    # 0.00061-0.00064 at 0.3)
    hs = [0.3, None]
    means, lengths = [], []
    for h in hs:
        r = at("cylinder", h)
        faces = subdomain_faces(r, 0.25)
        d, _, _ = r.problem.checked.surface.closest_points(r.mesh.vertices)
        faces = faces[(d[r.mesh.faces[faces]] >= 0.25).all(axis=1)]
        assert len(faces) > 100
        means.append(np.degrees(monodromy_angles(r.mesh, r.omega, faces)).mean())
        lengths.append(r.mesh.mean_edge_length)
    slope = loglog_slope(lengths, means)
    assert slope >= 1.5, (means, slope)


# ---------------------------------------------------------- independence
@pytest.fixture
def cylinder_problem(meshed):
    return meshed("cylinder", edge_length=0.3)


@pytest.mark.slow
def test_initialisations_reach_the_same_field(cylinder_problem):
    p = cylinder_problem
    res = {init: p.solve(init=init) for init in ("zero", "constant", "random", "linear")}
    ref = res["zero"]
    for init, r in res.items():
        rel = np.linalg.norm(r.omega - ref.omega) / np.linalg.norm(ref.omega)
        assert rel <= 1e-6, (init, rel)
        assert np.degrees(cross_distance(r.frames, ref.frames)).max() <= 0.01, init


@pytest.mark.slow
def test_lm_stops_within_its_tolerance_of_the_minimiser(cylinder_problem):
    """Wherever LM says it converged, the exact Newton step from there is
    below its step tolerance (1e-6 of omega), and started at that point it
    stops at once, although a step that small no longer changes the energy
    beyond round-off."""
    import scipy.sparse.linalg as spla

    vp = cylinder_problem.volume
    x, rep = vp.solve(np.zeros(cylinder_problem.constraints.n_unknowns))
    assert rep.converged, rep.reason
    assert rep.n_iterations <= 10

    def newton_step(x):
        g, Hgn, blocks = vp.linearise(x)
        # the damping only removes the null mode of the boundary angles,
        # which omega does not see
        H = vp.lm_matrix(Hgn + vp.second_order(x), 1e-12, vp.damping_diagonal(blocks))
        dx = spla.spsolve(H.tocsc(), -g)
        return np.linalg.norm(vp.P @ dx) / np.linalg.norm(vp.omega(x))

    assert newton_step(np.zeros_like(x)) > 0.5
    # within the step tolerance LM promises (1e-6 of omega; 3.1e-7 measured
    # on one of fTetWild's meshes, far less on most)
    assert newton_step(x) <= 1e-6
    x2, rep2 = vp.solve(x)
    assert rep2.converged and rep2.n_iterations <= 2, rep2.reason
    # the restart's own step is below the tolerance too (5e-9 of omega
    # measured; the last Newton system is solved to 1e-3, not to the end)
    np.testing.assert_allclose(vp.omega(x2), vp.omega(x), atol=1e-7 * np.abs(vp.omega(x)).max())


@pytest.mark.slow
@pytest.mark.parametrize("scale", [1e-3, 1e3])
def test_the_field_does_not_depend_on_the_model_units(solved, scale):
    """The same solid, network and tet mesh in other units (millimetres
    drawn as metres, say): the same field.  The smoothness weights of Eq. 16
    scale like a length and the structure residuals of Eq. 19 do not, so
    the solver measures lengths in the solid's own size."""
    from dataclasses import replace

    from solver.mesh.tetmesh import TetMesh

    ref = solved("cylinder", edge_length=0.3)
    V, F, net = load_example("cylinder")
    net = replace(net, curves=[replace(c, points=scale * c.points) for c in net.curves])
    mesh = TetMesh(scale * ref.mesh.vertices, ref.mesh.tets.copy())
    q = FieldProblem(scale * V, F, net, Options(edge_length=0.3 * scale), mesh=mesh)
    r = q.solve()
    assert r.report.lm.converged
    assert abs(len(r.report.lm.iterations) - len(ref.report.lm.iterations)) <= 1
    rel = np.linalg.norm(r.omega - ref.omega) / np.linalg.norm(ref.omega)
    assert rel <= 1e-6, rel
    assert np.degrees(cross_distance(r.frames, ref.frames)).max() <= 1e-3


@pytest.mark.slow
def test_development_root_does_not_matter(at):
    r = at("cylinder")
    mesh = r.mesh
    rng = np.random.default_rng(0)
    interior = np.nonzero(~mesh.is_boundary_vertex)[0]
    boundary = mesh.boundary_vertices
    for root in (int(rng.choice(interior)), int(rng.choice(interior)), int(rng.choice(boundary))):
        F2 = r.develop(root)
        dev = np.degrees(cross_distance(r.frames, F2))
        assert dev.max() <= 1.0, (root, dev.max())


@pytest.mark.slow
def test_lm_counts_the_cg_steps_of_a_newton_attempt_that_falls_back(meshed, monkeypatch):
    """Far from the minimum the full Hessian is indefinite: PCG stops on
    negative curvature and LM re-solves with Gauss-Newton.  Both solves'
    steps belong in the report."""
    import solver.field.volume3d as v3

    p = meshed("ball", edge_length=H["ball"])
    calls = []
    real_pcg = v3.pcg

    def counting_pcg(*args, **kw):
        res = real_pcg(*args, **kw)
        calls.append(res)
        return res

    monkeypatch.setattr(v3, "pcg", counting_pcg)
    # Newton from the first step on, where the Hessian is most often indefinite
    x, rep = p.volume.solve(np.zeros(p.constraints.n_unknowns), newton_step=10.0, max_iterations=6)
    assert any(c.negative_curvature for c in calls), "no Newton attempt fell back; the test needs one"
    assert sum(it.cg_iterations for it in rep.iterations) == sum(c.iterations for c in calls)
    assert rep.final.energy < rep.iterations[0].energy


@pytest.mark.slow
def test_a_direction_of_negative_curvature_lowers_the_energy_past_gauss_newton(meshed):
    """From omega = c the full Hessian of Eq. 23 is indefinite, and PCG on
    it stops on a direction of negative curvature.  Moving on from the
    Gauss-Newton trial point to the energy's minimum along that direction
    must lower the energy further, and report the energy of the point it
    returns."""
    from solver.linalg.pcg import pcg

    vp = meshed("ball", edge_length=H["ball"]).volume
    x = np.zeros(vp.P.shape[1])
    g, Hgn, blocks = vp.linearise(x)
    full = vp.assembly.matrix(Hgn + vp.second_order(x))
    pc = vp.make_preconditioner(blocks, 0.0, Hgn, vp.omega(x))
    res = pcg(full.__matmul__, -g, pc, rtol=1e-8)
    assert res.negative_curvature
    p = res.direction
    assert p @ (full @ p) < 0
    dx = pcg(vp.assembly.matrix(Hgn).__matmul__, -g, pc, rtol=1e-3).x
    es, ep = vp.energy_terms(x + dx)
    dx2, xn, es2, ep2, F2 = vp._curvature_move(x, dx, (es, ep), p, 4.0)
    assert F2 < (es + ep) * (1.0 - 1e-9)
    assert np.allclose(xn, x + dx2) and np.isclose(F2, vp.energy(xn), rtol=1e-12)
    # the move is along p: dx2 - dx is a multiple of p
    move = dx2 - dx
    assert np.linalg.norm(move - (move @ p) / (p @ p) * p) <= 1e-9 * np.linalg.norm(move)


@pytest.mark.slow
def test_lm_converges_on_a_coarse_torus(solved):
    """At h = 0.3 the torus's full Hessian stays indefinite over a dozen LM
    iterations near the minimum: Newton's attempts stopped on negative
    curvature and the Gauss-Newton steps taken instead crawled, and Newton
    steps that overshot were rejected, each a full solve wasted (10 fresh
    meshes: 9 had 2-9 rejected steps; 6 stopped at the 30-iteration cap).
    With the line minimum of an overshooting step and the move along the
    direction of negative curvature no step is rejected, and LM converged
    in 17-29 iterations on 26 fresh meshes.  That spread has a tail: one
    fresh fTetWild mesh in a later suite run stopped at the 40-iteration cap,
    so the test meshes with TetGen (the torus has no curves, so TetGen may
    mesh it, and its mesh is the same on every run: 7,606 tets, converged in
    14 iterations, one line-minimum step) and checks the same properties."""
    lm = solved("torus", edge_length=0.3, max_iterations=40, mesher="TetGen").report.lm
    assert lm.converged, lm.reason
    assert lm.n_iterations <= 32, lm.n_iterations
    # only the last step may be rejected, at round-off
    assert all(it.accepted for it in lm.iterations[:-1]), [it.iteration for it in lm.iterations if not it.accepted]


@pytest.mark.slow
def test_a_spurious_quarter_turn_in_the_lifted_boundary_field_is_refused(at):
    """Folded boundary triangles made the lift of the boundary field pick a
    wrong cross representative: a quarter turn no volume field can undo.
    The pipeline refuses such data with a MeshingError naming where."""
    import dataclasses

    from solver.errors import MeshingError
    from solver.field.boundary2d import lift_mismatch
    from solver.field.meshed_boundary import check_lift

    p = at("ball").problem
    B, bf = p.mesh.boundary, p.boundary
    assert lift_mismatch(B, bf).max() < 0.2
    # an extra quarter turn about the normal on one edge of an ordinary triangle
    e = int(B.face_edges[np.nonzero(~bf.is_feature_vertex[B.F].any(axis=1))[0][0], 0])
    omega0 = bf.omega0.copy()
    omega0[e] += 0.5 * np.pi * B.vertex_normals[B.edges[e, 0]]
    bad = dataclasses.replace(bf, omega0=omega0)
    d = lift_mismatch(B, bad)
    assert set(np.nonzero(d > np.pi / 4)[0]) == set(np.nonzero((B.face_edges == e).any(axis=1))[0])
    with pytest.raises(MeshingError, match=r"could not be lifted to 3D on 2 boundary triangle\(s\) near"):
        check_lift(p.mesh, bad, p.edge_length)
    check_lift(p.mesh, bf, p.edge_length)
