"""TetGen as the mesher of clean surfaces (solver/mesh/cdt.py) and the
choice between it and fTetWild (Options.mesher)."""

from __future__ import annotations

import numpy as np
import pytest

from solver import FieldProblem, MeshingError, Network, Options, OptionsError
from solver.examples import box, l_prism_example, load_example
from solver.mesh.cdt import tetrahedralize_cdt, wants_tetgen
from solver.surface.trisurface import TriSurface


@pytest.mark.mesher
def test_tetgen_keeps_the_surface_exactly():
    """Every boundary vertex of the mesh lies on the input surface and the
    volumes agree to round-off; no tet is flat; the count is near the
    budget's 15 tets per h^3."""
    V, F, _ = l_prism_example()
    S = TriSurface(V, F)
    h = 0.12
    mesh = tetrahedralize_cdt(S, h)
    assert mesh.tet_volumes.min() > 0
    assert mesh.tet_volumes.sum() == pytest.approx(abs(S.signed_volumes().sum()), rel=1e-9)
    d, _, _ = S.closest_points(mesh.vertices[mesh.boundary_vertices])
    assert d.max() < 1e-9
    expected = 15.0 * abs(S.signed_volumes().sum()) / h**3
    assert 0.5 * expected < mesh.n_tets < 1.5 * expected


@pytest.mark.mesher
def test_tetgen_failure_is_an_error_not_a_crash():
    """Two overlapping boxes (a surface that intersects itself, which
    validation would refuse): TetGen refuses it in its child process; the
    caller gets a MeshingError and keeps running."""
    V, F = box(n=2)
    S = TriSurface(np.vstack([V, V + 0.5]), np.vstack([F, F + len(V)]))
    with pytest.raises(MeshingError, match="TetGen failed"):
        tetrahedralize_cdt(S, 0.3)


@pytest.mark.slow
@pytest.mark.mesher
def test_auto_takes_tetgen_for_a_clean_part_and_it_solves(solved):
    r = solved("prism")
    assert r.report.mesher == "TetGen" and "meshed by TetGen" in r.report.summary()
    assert r.report.converged, r.report.status_reason
    assert r.report.metrics["normal_adaptation_mean_deg"] < 0.5


@pytest.mark.mesher
def test_where_tetgen_fails_ftetwild_meshes(monkeypatch):
    import solver.mesh.cdt as cdt

    def fail(*a, **k):
        raise MeshingError("TetGen failed (exit code 1): test")

    monkeypatch.setattr(cdt, "tetrahedralize_cdt", fail)
    V, F, net = load_example("cube")
    p = FieldProblem(V, F, net, Options(mesher="TetGen", edge_length=0.3))  # meshed here: the fallback is the point
    assert p.report.mesher.startswith("fTetWild (TetGen failed") and p.mesh.n_tets > 0
    assert "meshed by fTetWild (TetGen failed" in p.report.summary()


def test_dense_surfaces_and_singular_curves_go_to_ftetwild():
    """TetGen keeps every input vertex: a surface with many more triangles
    than an h-mesh of it would mesh far past the budget."""
    V, F, _ = load_example("cylinder")  # 4,480 triangles, 3.5x an h-mesh at h = 0.18
    S = TriSurface(V, F)
    assert not wants_tetgen(S, 0.18) and wants_tetgen(S, 0.09) and not wants_tetgen(S, 0.09, singular_curves=True)
    with pytest.raises(OptionsError, match="mesher"):
        Options(mesher="gmsh")


@pytest.mark.slow
@pytest.mark.mesher
def test_a_surface_of_thin_triangles_that_tetgen_overrefines_goes_to_ftetwild():
    """A box whose 1,728 triangles are squeezed towards x = 0 (up to 100:1):
    no denser than the mesh, but TetGen refines around the thin triangles
    whatever the edge length, far past 1.5x the budget; fTetWild meshes it
    at the same edge length instead of a coarser TetGen mesh."""
    V, F = box(n=12)
    V = V.copy()
    V[:, 0] = np.sign(V[:, 0]) * np.abs(V[:, 0]) ** 4
    budget = 6000
    p = FieldProblem(V, F, Network(curves=[], sharp_angle=30.0), Options(target_tets=budget))
    assert p.report.mesher.startswith("fTetWild (TetGen made"), p.report.mesher
    assert p.mesh.n_tets <= 1.5 * budget
    assert p.edge_length == pytest.approx(p.plan.edge_length)


def _box_with_cavity():
    """The box [-1, 1]^3 with a cubic cavity [-0.4, 0.4]^3 (its faces into it)."""
    V, F = box(n=2)
    Vc, Fc = box(lo=(-0.4,) * 3, hi=(0.4,) * 3, n=2)
    return np.vstack([V, Vc]), np.vstack([F, Fc[:, ::-1] + len(V)])


@pytest.mark.slow
@pytest.mark.mesher
def test_a_solid_with_a_cavity_solves_with_defaults():
    """TetGen fills cavities (it carves only outside the outer surface); the
    tets it puts in one are dropped: the mesh's boundary has the surface's
    two components and the solid's volume, and the field converges."""
    from solver import solve

    V, F = _box_with_cavity()
    r = solve(V, F, Network(sharp_angle=30.0))
    assert r.report.mesher == "TetGen", r.report.mesher
    assert r.mesh.boundary.n_components == 2
    assert r.mesh.tet_volumes.sum() == pytest.approx(8.0 - 0.8**3, rel=1e-9)
    assert not np.any(np.all(np.abs(r.mesh.vertices[r.mesh.tets].mean(axis=1)) < 0.4, axis=1))
    assert r.report.converged, r.report.status_reason


@pytest.mark.slow
@pytest.mark.mesher
def test_where_tetgen_fills_a_cavity_ftetwild_meshes(monkeypatch):
    """Should TetGen's mesh still miss a component of the surface, fTetWild
    meshes instead and the report says why."""
    import solver.mesh.cdt as cdt

    monkeypatch.setattr(cdt, "_carve_cavities", lambda S, P, T: (P, T))  # TetGen's mesh as it comes
    V, F = _box_with_cavity()
    p = FieldProblem(V, F, Network(sharp_angle=30.0), Options(edge_length=0.3))
    assert p.report.mesher == "fTetWild (TetGen's mesh boundary has 1 components but the surface has 2)", \
        p.report.mesher
    assert p.mesh.boundary.n_components == 2
