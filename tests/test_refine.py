"""Red refinement (solver/mesh/refine.py) and solves on refined meshes."""

from __future__ import annotations

import numpy as np
import pytest

from solver import FieldProblem, Options
from solver.analysis.measures import matched_singular_faces
from solver.examples import cylinder_surface, icosphere, load_example
from solver.mesh.refine import red_refine
from solver.mesh.slivers import tet_quality
from solver.mesh.tetwild import tetrahedralize
from solver.surface.trisurface import TriSurface
from tests.meshes import box_mesh
from tests.test_examples import check_axis_aligned


@pytest.fixture(scope="module")
def box_refinement():
    coarse = box_mesh(3, jitter=0.25, seed=3)
    return coarse, red_refine(coarse)


def test_red_refinement_is_conforming_and_keeps_volume_and_shape(box_refinement):
    coarse, ref = box_refinement
    fine = ref.fine
    assert fine.n_tets == 8 * coarse.n_tets
    assert fine.n_vertices == coarse.n_vertices + coarse.n_edges
    assert fine.tet_volumes.min() > 0
    assert np.isclose(fine.tet_volumes.sum(), coarse.tet_volumes.sum(), rtol=1e-12)
    # conforming: every face has two tets except the boundary, which is split 4:1
    assert len(fine.boundary_faces) == 4 * len(coarse.boundary_faces)
    assert fine.boundary.n_components == 1
    assert int(fine.boundary.euler_characteristics()[0]) == 2
    # Bey's shortest-diagonal rule keeps the shapes of the coarse tets
    assert tet_quality(fine.vertices, fine.tets).min() >= 0.5 * tet_quality(coarse.vertices, coarse.tets).min()


def test_whitney_prolongation_is_exact_for_constant_forms(box_refinement):
    coarse, ref = box_refinement
    fine = ref.fine
    rng = np.random.default_rng(0)
    for _ in range(3):
        c = rng.normal(size=3)
        wc = (coarse.vertices[coarse.edges[:, 1]] - coarse.vertices[coarse.edges[:, 0]]) @ c
        wf = (fine.vertices[fine.edges[:, 1]] - fine.vertices[fine.edges[:, 0]]) @ c
        assert np.abs(ref.whitney @ wc - wf).max() < 1e-12
    half = ref.edge_parent >= 0
    assert half.sum() == 2 * coarse.n_edges
    # a half edge runs from a coarse vertex to a midpoint: along its parent
    # where that vertex is the parent's first end
    par = ref.edge_parent[half]
    sign = np.where(fine.edges[half, 0] == coarse.edges[par, 0], 1.0, -1.0)
    wc = rng.normal(size=coarse.n_edges)
    assert np.allclose((ref.whitney @ wc)[half], 0.5 * sign * wc[par])


@pytest.mark.slow
@pytest.mark.mesher
def test_refined_boundary_lies_on_the_input_surface():
    V, F = icosphere(3)
    S = TriSurface(V, F)
    coarse = tetrahedralize(S, 0.45)
    ref = red_refine(coarse, S)
    fine = ref.fine
    assert fine.tet_volumes.min() > 0
    mids = fine.boundary_vertices[fine.boundary_vertices >= coarse.n_vertices]
    d_mid, _, _ = S.closest_points(fine.vertices[mids])
    d_coarse, _, _ = S.closest_points(coarse.vertices[coarse.boundary_vertices])
    # midpoints of smooth boundary edges were moved onto the surface; a chord
    # midpoint would sag by ~ l^2 / 8 (about 0.02 here)
    assert np.mean(d_mid < 1e-9) > 0.95, np.mean(d_mid < 1e-9)
    assert d_mid.max() <= max(d_coarse.max(), 1e-9) + 0.03
    assert np.isclose(fine.tet_volumes.sum(), 4.0 / 3.0 * np.pi, rtol=0.03)


@pytest.mark.slow
@pytest.mark.mesher
def test_cube_on_a_refined_mesh_keeps_its_sharp_edges():
    V, F, net = load_example("cube")
    problem = FieldProblem(V, F, net, Options(edge_length=0.2, refine=1))  # meshed here: refinement is the point
    # one level: every coarse tet split into eight
    assert problem.report.sizes["refine_levels"] == 1
    assert problem.mesh.n_tets == 8 * problem.report.sizes["mesher_tets"]
    # a reused mesh stage still reports how its mesh was made
    again = FieldProblem(V, F, net, Options(edge_length=0.2), mesh=problem.meshed)
    assert again.report.sizes["refine_levels"] == 1 and again.mesh is problem.mesh
    r = problem.solve()
    check_axis_aligned(r)
    sing, _ = matched_singular_faces(r.mesh, r.frames)
    assert not sing.any()
    assert r.report.lm.converged


def test_refine_option_is_checked():
    with pytest.raises(ValueError, match="refine"):
        Options(refine=7)


@pytest.mark.slow
@pytest.mark.mesher
def test_cylinder_on_a_refined_mesh_has_the_network_as_its_singular_set():
    """The O-grid cylinder solved on a refined mesh (fTetWild at 0.4, one
    level of red refinement): the same singular-structure and adaptation
    checks as on a direct mesh."""
    from solver.analysis.measures import tangent_adaptation
    from tests.test_examples import check_omega_singular_set, check_singular_structure

    # the example's network in the 32-gon of its solid: fTetWild meshes it in
    # a third of the 64-gon's time (tests/conftest.py)
    V, F = cylinder_surface(1.0, 2.0, n=32, rings=4)
    problem = FieldProblem(V, F, load_example("cylinder")[2], Options(edge_length=0.2, refine=1))  # meshed here
    r = problem.solve()
    assert r.report.lm.converged
    check_singular_structure(r)
    check_omega_singular_set(r)
    _, ta = tangent_adaptation(r)
    assert np.degrees(ta).mean() <= 2.0
