"""Resolution: the tet-count / memory guard, the tet budget with a graded
mesh, and the honest convergence status (issues 27d-e, 28)."""

from __future__ import annotations

import numpy as np
import pytest

from solver import Curve, FieldProblem, Network, Options, OptionsError
from solver.__main__ import EXIT_NOT_CONVERGED
from solver.__main__ import main as cli_main
from solver.analysis.measures import normal_adaptation, omega_singular_faces, tangent_adaptation
from solver.examples import ball_example, box, cube_example
from solver.mesh.bisection import bisect
from solver.mesh.resolution import ResolutionError, refusal, tet_limit
from solver.network.validation import check_input
from solver.pipeline import resolution_plan, solve_resolved


@pytest.fixture(scope="module")
def cube():
    return cube_example()


def wall_network():
    """A feature curve 0.05 from a wall of the 2-unit cube: a third of that
    everywhere meant ~2.6e7 tets."""
    V, F = box(n=2)
    c = Curve(np.linspace([-1, -0.95, 0], [1, -0.95, 0], 9), sigma=0, role="feature", name="near wall")
    return V, F, Network(curves=[c], sharp_angle=30)


# ------------------------------------------------------------------- guard
@pytest.mark.parametrize("kw", [dict(edge_length=1e-6), dict(edge_length=0.01), dict(edge_length=1e-4),
                                dict(target_tets=1_000_000_000)])
def test_guard_refuses_before_meshing(cube, kw):
    V, F, net = cube
    with pytest.raises(ResolutionError, match=r"tets .* memory.*max_tets") as info:
        FieldProblem(V, F, net, Options(**kw))
    msg = str(info.value)
    assert "--max-tets" in msg and "GB" in msg


@pytest.mark.parametrize("args", [["--edge-length", "1e-6"], ["--edge-length", "0.01"],
                                  ["--target-tets", "1000000000"], ["--edge-length", "0.01", "--check"]])
def test_guard_cli(args, capsys, tmp_path):
    rc = cli_main(["--example", "cube", "-q", "-o", str(tmp_path / "x.npz"), *args])
    assert rc == 1
    err = capsys.readouterr().err
    assert "tets" in err and "--max-tets" in err
    assert not (tmp_path / "x.npz").exists()


def test_override_lifts_the_refusal(cube):
    V, F, net = cube
    assert refusal(1.2e8, None, "test") is not None
    assert refusal(1.2e8, 200_000_000, "test") is None
    assert refusal(5e5, None, "test") is None
    assert tet_limit(None)[0] <= 1_000_000
    checked = check_input(V, F, net)
    # the decision alone: with the override the plan is made (no meshing)
    plan = resolution_plan(checked, Options(edge_length=0.01, max_tets=200_000_000))
    assert 1e8 < plan.tets < 2e8
    with pytest.raises(ResolutionError):
        resolution_plan(checked, Options(edge_length=0.01))


def test_automatic_resolution_keeps_the_budget():
    """A curve 0.05 from the wall asked for h = 0.0167 everywhere (~2.6e7
    tets); a budget given holds and the report names what was given up; by
    default the network may spend up to the ceiling (4x the default
    budget), and the estimate says what it held back past it."""
    V, F, net = wall_network()
    checked = check_input(V, F, net)
    plan = resolution_plan(checked, Options(target_tets=15_000))
    assert plan.graded and plan.tets <= 1.5 * 15_000
    assert plan.finest < plan.edge_length
    assert plan.floor > 0 and "keep the budget" in plan.describe()
    default = resolution_plan(checked, Options())
    assert Options().budget == 15_000 and Options().ceiling == 60_000
    # the bulk keeps the budget's edge length, the network gets what it asks
    assert 15_000 < default.tets <= 60_000 and default.edge_length == pytest.approx(0.2, rel=0.01)
    assert default.floor == 0 and default.finest == pytest.approx(0.05 / 3, rel=0.05)
    assert "spent" in default.describe()
    # a ceiling that binds: the finest sizes floored, what was held back said
    held = resolution_plan(checked, Options(tets_ceiling=30_000))
    assert held.tets <= 1.05 * 30_000 and 0 < held.floor < plan.floor and held.grading == 0.5
    assert "ceiling of 30,000 tets" in held.describe() and "held back" in held.describe()
    # a budget that affords the network resolves it
    big = resolution_plan(checked, Options(target_tets=80_000))
    assert big.floor == 0 and big.finest == pytest.approx(0.05 / 3, rel=0.05)


# ----------------------------------------------------------------- grading
def test_a_gentler_grading_spreads_the_fine_sizes_farther():
    """Options.grading is the growth of the sizing field per unit distance:
    with a budget that affords the network, the finest size is the same, the
    field grows from it at that rate, and the graded region costs more
    tets (~(0.5 / g)^3 times, the estimate's integral)."""
    V, F, net = wall_network()
    checked = check_input(V, F, net)
    plans = {g: resolution_plan(checked, Options(target_tets=200_000, grading=g)) for g in (0.5, 0.25)}
    for g, plan in plans.items():
        assert plan.floor == 0 and plan.grading == g
        assert plan.finest == pytest.approx(0.05 / 3, rel=0.05)
        src = plan.sources[np.argmin(plan.sizes)]
        X = src + np.array([[0.0, 0.0, 0.2], [0.0, 0.0, 0.4]])  # along the curve's wall, inside the box
        assert np.allclose(plan.sizing(X), np.minimum(plan.edge_length, plan.finest + g * np.array([0.2, 0.4])),
                           rtol=0.05)
        assert plan.tets <= 1.5 * 200_000
    assert plans[0.25].graded_tets > 3.0 * plans[0.5].graded_tets


@pytest.mark.parametrize("g", [0.0, 0.05, 1.5, "0.3", float("nan")])
def test_grading_out_of_range_is_refused(g):
    with pytest.raises(OptionsError, match="option 'grading'"):
        Options(grading=g)


def test_grading_reaches_the_plan_from_the_command_line(capsys, tmp_path):
    from solver.io.formats import write_network, write_obj

    V, F, net = wall_network()
    write_obj(str(tmp_path / "box.obj"), V, F)
    write_network(str(tmp_path / "wall.json"), net, surface="box.obj")
    expected = {}
    for g in (0.5, 0.25):
        assert cli_main([str(tmp_path / "wall.json"), "--check", "--target-tets", "200000", "--grading", str(g)]) == 0
        line = next(s for s in capsys.readouterr().out.splitlines() if s.startswith("resolution:"))
        plan = resolution_plan(check_input(V, F, net, True, None, True, 200_000),
                               Options(target_tets=200_000, grading=g))
        expected[g] = line
        assert f"expected ~{plan.tets:,.0f} tets" in line, (line, plan.describe())
    assert expected[0.5] != expected[0.25]


def test_bisection_is_conforming():
    from solver.mesh.tetmesh import TetMesh

    # a structured cube mesh (Kuhn subdivision of 3^3 cells)
    g = np.linspace(0, 1, 4)
    P = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange(64).reshape(4, 4, 4)
    T = []
    for i in range(3):
        for j in range(3):
            for k in range(3):
                c = [idx[i + a, j + b, k + d] for a in (0, 1) for b in (0, 1) for d in (0, 1)]
                for path in ((0, 4, 6, 7), (0, 4, 5, 7), (0, 1, 5, 7), (0, 1, 3, 7), (0, 2, 3, 7), (0, 2, 6, 7)):
                    T.append([c[p] for p in path])
    mesh = TetMesh(P, np.array(T))
    vol = mesh.tet_volumes.sum()
    for _ in range(4):
        mark = np.linalg.norm(mesh.vertices[mesh.tets].mean(axis=1), axis=1) < 0.4
        mesh = bisect(mesh, mark)
    assert mesh.n_tets > 6 * 27
    assert mesh.tet_volumes.min() > 0 and mesh.tet_volumes.sum() == pytest.approx(vol)
    # conforming: every interior face has two tets, the boundary is the cube's
    B = mesh.boundary
    assert B.n_components == 1 and int(np.sum(B.euler_characteristics())) == 2
    assert np.sum(mesh.face_areas[mesh.boundary_faces]) == pytest.approx(6.0)


@pytest.mark.slow
@pytest.mark.mesher
def test_short_curves_mesh_and_solve_within_budget(monkeypatch):
    """The cube-sphere network with an inner cube 0.1 across: node-to-node
    curves 0.1 long, shorter than the bulk edge length the budget allows
    (0.27 for 6,000 tets).  A uniform mesh fine enough for them would hold
    ~1.7M tets; the mesh is graded and stays within 1.5x the budget, and
    the solve, with default options, resolves the network -- converged at
    the discretisation level, the omega-matched singular faces exactly the
    network's, the frames adapted to the surface and the curves.  Measured
    here: 7.6k-8.7k tets (edges down to 0.047), 17-19 LM iterations,
    penalty 3.9-4.6; at 8,000 tets 8.7k-10.5k tets, 16-31 iterations,
    penalty 2.3-3.9 in twice the time (the penalty falls with the tet
    count, not with the grading: docs/limitations.md, "Graded meshes
    around very short curves").  A
    radial curve grazing a mesh face once flipped that face's quarter turn
    (penalty 4.5e3, 1 run in 3; test_embed).

    Tangent adaptation: mean 0.15-0.30 deg, 95th percentile <= 0.55 deg, max
    0.50-0.78 deg on most meshes; on about 1 in 8, a cube edge keeps a single
    tube edge between its node regions (each 0.04 across, plus the ring of
    tets around it), with its vertices one edge length (0.034-0.051) from
    the curve, where the field is off by 3-6 deg (4 of ~200 vertices);
    once, 36 deg at two such vertices."""
    import solver.mesh.meshing as meshing

    made, meshed_at = [], []  # the tet count of each mesh fTetWild made, and its edge length

    def counting(*args, **kwargs):
        m = mesh_at(*args, **kwargs)
        if m.mesher == "fTetWild":
            made.append(m.mesh.n_tets * 8.0**m.k)
            meshed_at.append(m.H)
        return m

    mesh_at = meshing._mesh_at
    monkeypatch.setattr(meshing, "_mesh_at", counting)
    V, F, net = ball_example(inner=0.05)  # meshed here: its own network, and the budget retries are the point
    budget = 6000
    problem = FieldProblem(V, F, net, Options(target_tets=budget))
    monkeypatch.setattr(meshing, "_mesh_at", mesh_at)
    _check_graded_within_budget(problem, budget, made, meshed_at)
    r = solve_resolved(problem)
    sizes = r.report.sizes
    assert sizes["tets"] <= 1.5 * budget and sizes.get("graded_tets", 0) > 0, sizes
    assert r.problem.plan.finest < 0.1 < r.problem.edge_length, (r.problem.plan.finest, r.problem.edge_length)
    assert r.report.converged, r.report.status_reason
    _check_short_curves_resolved(r)


def _check_graded_within_budget(problem, budget, made, meshed_at):
    """The graded mesh of test_short_curves_mesh_and_solve_within_budget:
    within 1.5x the budget, the budget retries as the meshes fTetWild made
    call for, the resolution floor said, finer near the network."""
    sizes = problem.report.sizes
    assert sizes["tets"] <= 1.5 * budget
    # fTetWild refines around the tubes of the short curves: at the planned
    # bulk edge length it may make more than the budget leaves the grading;
    # then the bulk is meshed again coarser until the planned grading fits,
    # and the report says so, but not a third time where the second mesh
    # did not lower the count by half of what a coarser bulk alone would
    # have (the tubes hold it: 8.7k tets at h, 1.03 h and 1.06 h, before).
    # fTetWild's count varies from run to run, so which case this run meets
    # is read off the meshes it made.
    room = problem.plan.graded_tets if problem.plan.graded else 0.0
    if made[0] > 1.5 * budget - room:
        assert sizes.get("budget_retries", 0) >= 1 and "with a coarser bulk" in problem.report.summary(), sizes
    else:
        assert len(made) == 1 and not sizes.get("budget_retries"), (made, sizes)
    if len(made) == 3:
        fell, bulk_alone = made[0] - made[1], made[0] * (1.0 - (meshed_at[0] / meshed_at[1]) ** 3)
        assert fell >= 0.5 * bulk_alone, (made, meshed_at)
    assert sizes.get("graded_tets", 0) > 0
    # the short curves need more than the budget allows: said, not hidden
    assert sizes["resolution_floor"] > sizes["edge_length_needed"]
    assert "raise target_tets" in problem.report.summary()
    # finer near the network than in the bulk
    h = problem.mesh.edge_lengths
    mid = problem.mesh.vertices[problem.mesh.edges].mean(axis=1)
    near = np.linalg.norm(mid, axis=1) < 0.1
    assert np.median(h[near]) < 0.5 * np.median(h[~near])


def _check_short_curves_resolved(r):
    """The solve of test_short_curves_mesh_and_solve_within_budget resolves
    its network (the docstring's figures)."""
    m = r.report.metrics
    # node regions carry no structure equation, so the frames developed
    # through them can meet the omega of an edge at their skin ~45 degrees
    # apart, where even the omega-aware matching is ambiguous: 1 spurious
    # face once in ~26 runs (converged, monodromy max 0.54 deg), and 2
    # faces of a curve read as regular once in ~30 (converged, monodromy max
    # 0.35 deg: a converged field holds Eq. 17 on every pierced face, so
    # only a matching of edges that turn by tens of degrees can miss one).
    # Any other spurious or missing face fails
    mesh, emb = r.mesh, r.embedding
    singular = omega_singular_faces(mesh, r.omega, r.frames)
    spurious = singular.copy()
    spurious[emb.network_faces(mesh)] = False
    missing = emb.prescribed_singular() & ~singular
    skin = np.zeros(mesh.n_vertices, bool)
    skin[mesh.tets[emb.node_region_tets]] = True
    for odd in (spurious, missing):
        turns = np.degrees(np.linalg.norm(r.omega[mesh.face_edges[odd]], axis=2)).round(1)
        assert odd.sum() <= 2 and skin[mesh.faces[odd]].any(axis=1).all(), (m, turns)
    na = np.degrees(normal_adaptation(r.mesh, r.frames))
    _, ta = tangent_adaptation(r)
    assert na.mean() <= 0.5, na.mean()
    ta = np.degrees(ta)
    # the single-tube-edge case of the docstring: 3-6 degrees at its vertices
    # on most such meshes, 36 at two vertices once (one run of ~200);
    # everywhere else the frames follow the curves
    assert ta.mean() <= 1.0 and np.percentile(ta, 95) <= 1.5, np.sort(ta)[-12:]
    assert np.sum(ta > 10.0) <= 2, np.sort(ta)[-12:]


# ------------------------------------------------------------------ status
@pytest.mark.mesher
def test_not_converged_status_and_exit_code(solved, tmp_path, capsys):
    res = solved("cube", edge_length=0.4, max_iterations=1, init="random")
    assert res.report.status == "not converged" and not res.report.converged
    assert "Levenberg-Marquardt" in res.report.status_reason
    assert res.report.to_dict()["converged"] is False
    out = tmp_path / "cube.npz"
    rc = cli_main(["--example", "cube", "--edge-length", "0.4", "--iterations", "1", "--init", "random", "-q",
                   "-o", str(out)])
    assert rc == EXIT_NOT_CONVERGED == 3
    assert out.exists()  # the result is still written
    assert "not converged" in capsys.readouterr().err


def _lm(penalty: float, smoothness: float, converged: bool = True):
    from solver.field.volume3d import LMIteration, LMReport

    it = LMIteration(iteration=9, energy=penalty + smoothness, smoothness=smoothness, penalty=penalty,
                     gradient_norm=0.0, damping=0.0, cg_iterations=0, accepted=True, seconds=0.0)
    return LMReport(init="zero", iterations=[it], converged=converged, reason="converged: step below tolerance")


def test_an_excess_held_by_a_few_faces_is_a_local_error():
    """A penalty over the discretisation level (1 + 0.25 x smoothness) is a
    local error of the discretisation, and the field a solution, only where
    the omega-matched structure is exact and at most one face per singular
    curve, each closing within LOCAL_DEG, holds the excess."""
    from solver.report import LOCAL_DEG, local_excess

    rng = np.random.default_rng(0)
    share = rng.uniform(0.0, 0.004, 2000)  # 4.0 spread over 2,000 faces
    share[17] = 3.4  # one face near a curve's end
    deg = np.degrees(np.sqrt(share / 1000.0))  # penalty 1000 |r|^2
    at = rng.normal(size=(2000, 3))
    exact = {"omega_spurious_singular_faces": 0, "omega_missing_singular_faces": 0}
    lm = _lm(share.sum(), smoothness=24.0)  # level 7, penalty 7.4
    why = local_excess(lm, share, deg, at, exact, n_singular=20)
    assert why and "only through one face" in why and f"{at[17, 0]:.4g}" in why and "3.3 degrees" in why, why
    # the same excess spread over the faces: the network is not resolved
    spread = share.copy()
    spread[17] = 0.0
    spread += 3.4 / len(spread)
    assert local_excess(lm, spread, np.degrees(np.sqrt(spread / 1000.0)), at, exact, 20) is None
    # a face turned by more than LOCAL_DEG, a matching not exact, an LM run
    # that did not converge, or fewer singular curves than faces needed: not local
    wide = deg.copy()
    wide[17] = LOCAL_DEG + 1.0
    assert local_excess(lm, share, wide, at, exact, 20) is None
    assert local_excess(lm, share, deg, at, {**exact, "omega_missing_singular_faces": 2}, 20) is None
    assert local_excess(_lm(share.sum(), 24.0, converged=False), share, deg, at, exact, 20) is None
    two = share.copy()
    two[18] = 3.4
    assert local_excess(_lm(two.sum(), 24.0), two, np.degrees(np.sqrt(two / 1000.0)), at, exact, 1) is None
    assert "2 faces" in local_excess(_lm(two.sum(), 24.0), two, np.degrees(np.sqrt(two / 1000.0)), at, exact, 2)
    # at or under the level there is nothing to excuse
    assert local_excess(_lm(6.0, 24.0), share, deg, at, exact, 20) is None


@pytest.mark.mesher
def test_a_solve_over_the_level_in_one_face_is_converged_and_says_so(solved, monkeypatch):
    """A solve's status, as FieldProblem.solve makes it after LM (the stop
    rule's status, then pipeline._local_status on the problem and omega),
    on the shared ball solve: with the level set (by its constants) between
    the ball's penalty and that penalty less half its worst face, converged,
    naming the face; with the level at a millionth of the penalty (every
    face would have to go), not converged."""
    import solver.report as report
    from solver.pipeline import _local_status

    first = solved("ball")
    vp = first.problem.volume
    share = vp.a * np.sum(vp.se.residual(first.omega) ** 2, axis=1)
    penalty = first.report.lm.final.penalty

    def status() -> tuple[str, str]:
        rep = report.Report(lm=first.report.lm, metrics=dict(first.report.metrics))
        rep.status, rep.status_reason = report.solution_status(rep.lm)
        return _local_status(first.problem, rep, first.omega)

    monkeypatch.setattr(report, "PENALTY_REL", 0.0)
    monkeypatch.setattr(report, "PENALTY_ABS", penalty - 0.5 * share.max())
    state, why = status()
    assert state == "converged" and "only through one face" in why, why
    monkeypatch.setattr(report, "PENALTY_ABS", 1e-6 * penalty)
    state, why = status()
    assert state == "not converged" and "above the discretisation level" in why, why


@pytest.mark.slow
@pytest.mark.mesher
def test_the_iteration_cap_says_how_close_it_came(solved):
    """Stopped by the cap with the penalty already at the discretisation
    level: the status names the energy's last change and the option to
    raise (the cylinder from a random start needs 8 iterations).  (refine=0
    is what the automatic choice gives at this edge length: the mesh of
    tests/test_interchange.py.)"""
    res = solved("cylinder", edge_length=0.4, refine=0, max_iterations=6, init="random")
    assert res.report.status == "not converged"
    why = res.report.status_reason
    assert "stopped after 6 iterations" in why and "discretisation level" in why, why
    assert "energy fell" in why and "Raise max_iterations" in why, why
    assert "close to a minimum" not in why  # it was still falling fast


@pytest.mark.mesher
def test_converged_status(solved):
    res = solved("cube", edge_length=0.4)
    assert res.report.converged, res.report.summary()
    assert "status: converged" in res.report.summary()


# ------------------------------------------------ issue 41b: the default follows the network
@pytest.mark.slow
@pytest.mark.mesher
def test_the_default_spends_what_the_network_asks_and_converges(monkeypatch):
    """A genus-2 block with three +-1/4 pairs across its arms (testkit/genus2.py)
    asks for about twice a budget of 10,000 tets: by default the mesh spends
    it (the bulk at the budget's edge length), the estimate printed before
    meshing gives tets, memory and time, and is within 1.5x of the count
    meshed; the field converges with the omega-matched singular structure
    exact and the adaptation within the issue's bars (issue 41c: 1 mesh in
    5 ended LM at its cap, penalty 4.2e3, before the handle turns were
    read only where whole).  A budget given explicitly is held."""
    import solver.pipeline as pipeline
    from testkit.genus2 import genus2_family

    monkeypatch.setattr(pipeline, "DEFAULT_TARGET_TETS", 10_000)
    V, F, net = genus2_family(0, pairs=3)
    said = []
    p = FieldProblem(V, F, net, progress=lambda stage, frac, msg: said.append(msg))
    plan = p.plan
    # every need met, up to the automatic grading's floor slack (resolution.GRADING_FLOOR_SLACK)
    from solver.mesh.resolution import GRADING_FLOOR_SLACK

    assert p.options.budget == 10_000 and plan.tets > 1.5 * 10_000
    assert plan.floor == 0 or plan.floor <= GRADING_FLOOR_SLACK * plan.need_min, (plan.floor, plan.need_min)
    estimate = next(m for m in said if m.startswith("tetmesh: edge length"))
    assert "tets" in estimate and "MB" in estimate and " s end to end" in estimate and "spent" in estimate
    assert plan.tets / 1.5 <= p.mesh.n_tets <= 1.5 * plan.tets, (plan.tets, p.mesh.n_tets)
    # as solve() and the command line do: where the graded mesh leaves the
    # oblique ends unresolved (their ends slide at most half an edge, the
    # rest bent: penalty 5.1 against 3.2 allowed), a uniform one resolves
    # them (2.1 at 19k tets), and the notes say so
    r = solve_resolved(p)
    assert r.report.converged, r.report.status_reason
    assert r.problem is p or "solved again on a uniform mesh" in r.report.notes[-1]
    assert r.report.metrics["omega_spurious_singular_faces"] == 0
    assert r.report.metrics["omega_missing_singular_faces"] == 0
    # issue 41c: on a genus-2 solid with oblique curves (ends 15-40 degrees off)
    assert r.report.metrics["tangent_adaptation_mean_deg"] <= 1.0
    assert r.report.metrics["normal_adaptation_mean_deg"] <= 0.5
    held = resolution_plan(p.checked, Options(target_tets=10_000))
    assert held.tets <= 1.5 * 10_000


def test_a_finer_solve_grades_round_a_curve_a_uniform_mesh_would_not_follow(monkeypatch):
    """SymFrames' own solves at an edge length of its choosing (the ladder,
    solve_finer for the hex stage) mesh uniformly at it; where a curve's end
    bend needs a finer local scale than that (validation.LocalScaleError,
    a refusal only where the user gave the edge length: a tet-edge
    ellipsoid's finer field was refused as if its network were at fault),
    the mesh is graded for as many tets instead, and the words say so.  A
    finer solve that the intake refuses otherwise leaves the first field
    standing, said, never a refusal.  The meshings are stand-ins."""
    import types

    import solver.pipeline as pl
    from solver.errors import NetworkError
    from solver.mesh.resolution import solid_volume, uniform_tets
    from solver.network.validation import LocalScaleError

    V, F, _ = cube_example()
    from solver.surface.trisurface import TriSurface

    S = TriSurface(V, F)
    made = []

    class Fake:
        def __init__(self, V, F, net, opts, progress=None, cancel=None):
            made.append(opts)
            if opts.edge_length is not None:
                raise LocalScaleError("curve 3 'tip' is too short to bend its oblique end(s) onto the normal")
            self.edge_length = 0.21

    monkeypatch.setattr(pl, "FieldProblem", Fake)
    problem = types.SimpleNamespace(checked=types.SimpleNamespace(surface=S), options=Options(), given=Network())
    said = []
    again, how = pl._meshed_again(problem, 0.1, uniform_tets(solid_volume(S), 0.1),
                                  lambda stage, frac, msg: said.append(msg), None)
    assert isinstance(again, Fake) and made[0].edge_length == 0.1 and made[1].edge_length is None
    assert made[1].target_tets == int(uniform_tets(solid_volume(S), 0.1))
    assert how.startswith("a mesh graded for") and "0.21" in how and "would not follow" in how
    assert any("too short to bend" in m for m in said)

    def refused(*a, **kw):
        raise NetworkError("curve 0 kinks at the finer scale")

    monkeypatch.setattr(pl, "_meshed_again", refused)
    first = types.SimpleNamespace(edge_length=0.15, options=Options(), checked=problem.checked)
    monkeypatch.setattr(pl.checks, "instance", lambda *a, **kw: None)
    none, why = pl.solve_finer(first)  # the problem solved first (a FieldProblem, as the add-on passes it)
    assert none is None and why.startswith("not solved again finer at edge length") and "kinks" in why


def test_a_stalled_lm_is_solved_again_on_a_fresh_mesh(monkeypatch):
    """LM that ran to its cap far from a solution on an fTetWild mesh (the
    O-grid torus, 2 of 29 meshes; a holed block with a singular pair, once)
    is solved again on a fresh mesh of the same plan, the better field kept
    and the notes saying so; not with TetGen (the same mesh again) nor with
    max_iterations given.  The solves are stand-ins: the rule is tested."""
    import types

    import solver.pipeline as pl

    made = []

    def result(ok, tets):
        final = types.SimpleNamespace(penalty=0.4 if ok else 874.0, smoothness=1.0)
        lm = types.SimpleNamespace(final=final, converged=ok, capped=not ok)
        rep = types.SimpleNamespace(converged=ok, lm=lm, notes=[], status_reason="ok" if ok else "capped",
                                    metrics={})
        return types.SimpleNamespace(report=rep)

    class Fake:
        def __init__(self, V, F, net, opts, progress=None, cancel=None):
            self.edge_length, self.options = 0.2, opts
            self.mesh = types.SimpleNamespace(n_tets=1000 + len(made))
            made.append(opts.edge_length)

        def solve(self, root=None, progress=None, cancel=None):
            return result(len(made) > 1, self.mesh.n_tets)

    monkeypatch.setattr(pl, "FieldProblem", Fake)
    for mesher, opts, retried in (("fTetWild", Options(), True), ("TetGen", Options(), False),
                                  ("fTetWild", Options(max_iterations=20), False)):
        made.clear()
        first = Fake(None, None, None, opts)
        first.given = None
        first.checked = types.SimpleNamespace(surface=types.SimpleNamespace(V=None, F=None))
        first.meshed = types.SimpleNamespace(stats=types.SimpleNamespace(mesher=mesher, graded_tets=0))
        res = pl.solve_resolved(first)
        assert made == ([None, None] if retried else [None]) and res.report.converged == retried
        if retried:
            note = res.report.notes[-1]
            assert "penalty of 874, far from a solution" in note and "fresh mesh (1,001 tets): penalty 0.4 (kept)" \
                in note, note


@pytest.mark.parametrize("failure", ["penalty", "adaptation", "capped"])
def test_unresolved_graded_solve_tries_uniform_then_finer(monkeypatch, failure):
    """solve_resolved's ladder: a graded automatic mesh whose LM stopped
    above the discretisation level gives way first to a uniform mesh at
    its own bulk edge length (a generated ellipsoid: penalty 31 graded at
    28.5k tets, 0.14 uniform at 9.2k), then to one FINER times as fine;
    the first that converges is kept and the notes say what was done.  So
    does one whose LM stopped at the level but with the frames off the
    curves (a generated cube with a small cavity: penalty 8.4, the level
    passed, frames 13 degrees off the curves; it went to the hex stage
    unsolved), and one whose LM ran to its default cap above the level but
    not far from a solution (a generated ellipsoid: penalty 17.4 after 50
    iterations; other meshes of it converged in 10-19); not where the user
    set the cap.  Where no mesh of the ladder resolved it, a fresh mesh of
    the first plan is solved once (fTetWild's meshes differ; a cube with a
    cavity converged on 3 of 7), the better field kept and every step said.
    The solves are stand-ins: the ladder is what is tested."""
    import types

    import solver.pipeline as pl
    from solver.report import adaptation_status

    made = []

    class Fake:
        def __init__(self, V, F, net, opts, progress=None, cancel=None):
            self.edge_length, self.options = opts.edge_length, opts
            self.mesh = types.SimpleNamespace(n_tets=1000)
            made.append(self.edge_length)

        def solve(self, root=None, progress=None, cancel=None):
            ok = len(made) == want_converged_at
            capped = failure == "capped" and not ok
            lm = types.SimpleNamespace(final=types.SimpleNamespace(penalty=0.5 if ok else 9.0 - len(made),
                                                                   smoothness=4.0),
                                       converged=not capped, capped=capped, n_iterations=50 if capped else 9)
            if ok:
                why, metrics = "ok", {}
            elif failure == "penalty":
                why, metrics = "the structure penalty is above the discretisation level", {}
            elif failure == "capped":
                why, metrics = "Levenberg-Marquardt reached max_iterations", {}
            else:
                metrics = {"tangent_adaptation_mean_deg": 13.1, "normal_adaptation_mean_deg": 1.5}
                why = adaptation_status(metrics)
            rep = types.SimpleNamespace(converged=ok, lm=lm, notes=[], status_reason=why, metrics=metrics)
            return types.SimpleNamespace(report=rep)

    monkeypatch.setattr(pl, "FieldProblem", Fake)
    first = Fake(None, None, None, Options())
    first.edge_length = 0.2
    first.given = None
    first.checked = types.SimpleNamespace(surface=types.SimpleNamespace(V=None, F=None))
    first.meshed = types.SimpleNamespace(stats=types.SimpleNamespace(mesher="fTetWild", graded_tets=500))
    long_curve = types.SimpleNamespace(points=np.array([[0.0, 0, 0], [1.0, 0, 0]]), closed=False)
    first.network = types.SimpleNamespace(curves=[long_curve])
    monkeypatch.setattr(pl, "solid_volume", lambda S: 1.0)
    # none resolved: a fresh mesh of the first plan (None), once
    for want_converged_at, lengths in ((2, [0.2]), (3, [0.2, pl.FINER * 0.2]), (4, [0.2, pl.FINER * 0.2, None]),
                                       (9, [0.2, pl.FINER * 0.2, None])):
        made.clear()
        made.append(None)  # the first problem
        res = pl.solve_resolved(first)
        assert made[1:3] == pytest.approx(lengths[:2]) and made[3:] == lengths[2:]
        note = res.report.notes[0 if want_converged_at >= 4 else -1]
        assert "uniform mesh at edge length 0.2" in note and "graded" in note
        assert {"penalty": "above the discretisation level", "capped": "ran to its cap of 50 iterations",
                "adaptation": "13.1 degrees off the curves' tangents"}[failure] in note, note
        assert res.report.converged == (want_converged_at <= 4)
        if want_converged_at >= 4:
            fresh = res.report.notes[-1]
            assert "no mesh of the ladder resolved the network" in fresh and "fresh mesh (1,000 tets)" in fresh, fresh
            assert fresh.endswith("(kept)"), fresh  # converged, or a lower penalty (the stand-ins' falls)
    # a curve shorter than SHORT_UNIFORM edges, a uniform first mesh, or
    # one the grading made less than GRADED_SHARE of: straight to the finer one
    for short, graded in ((True, 500), (False, 0), (False, 50)):
        first.meshed.stats.graded_tets = graded
        first.network.curves = [types.SimpleNamespace(points=long_curve.points * (0.49 if short else 1.0),
                                                      closed=False)]
        made.clear()
        made.append(None)
        want_converged_at = 2
        pl.solve_resolved(first)
        assert made[1:] == pytest.approx([pl.FINER * 0.2])
    if failure == "capped":  # a cap the user set: the report says how close it came, no solve again
        first.options = Options(max_iterations=40)
        made.clear()
        made.append(None)
        pl.solve_resolved(first)
        assert made == [None]
