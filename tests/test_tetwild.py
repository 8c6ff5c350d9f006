"""fTetWild through both bindings (solver/mesh/tetwild.py): pytetwild, the
default, and wildmeshing, which the macOS zips bundle.  SYMFRAMES_MESHER
forces one; both must give the unfiltered mesh that the inside filter
of tetwild.py trims to the solid."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from solver.examples import icosphere
from solver.mesh import tetwild
from solver.surface.trisurface import TriSurface

# every test here runs fTetWild on the ball: slow and mesher (CONTRIBUTING.md, Testing)
pytestmark = [pytest.mark.slow, pytest.mark.mesher]


@pytest.mark.parametrize("mesher", tetwild.MESHERS)
def test_each_mesher_fills_the_ball(mesher, monkeypatch):
    if importlib.util.find_spec(mesher) is None:
        pytest.skip(f"{mesher} is not installed")
    monkeypatch.setenv("SYMFRAMES_MESHER", mesher)
    assert tetwild.mesher_name() == mesher
    V, F = icosphere(3)
    S = TriSurface(V, F)
    mesh = tetwild.tetrahedralize(S, 0.45)
    assert mesh.n_tets > 100 and mesh.tet_volumes.min() > 0
    assert np.isclose(mesh.tet_volumes.sum(), 4.0 / 3.0 * np.pi, rtol=0.05)
    # the unfiltered background mesh was trimmed: nothing outside the ball
    assert np.linalg.norm(mesh.vertices, axis=1).max() < 1.0 + 1e-2



def test_a_first_mesh_whose_surface_folds_is_made_again(monkeypatch):
    """fTetWild folds the surface of a few of its meshes where a curve's
    tube or a feature comes close to it (a cube with a cavity, 1 test run in
    7), and the boundary field cannot be lifted there (check_lift).  Another
    run of the same input lifts: the problem meshes once more and says so in
    its report and its solve's; a second fold is refused, saying both
    meshes folded; a mesh the caller gave is not replaced."""
    import solver.field.meshed_boundary as mb
    from solver import FieldProblem, Options
    from solver.examples import load_example
    from solver.field.meshed_boundary import FoldedLiftError

    lift, made = mb.check_lift, []

    def folds(first_only):
        def check(mesh, bf, edge_length):
            made.append(mesh)
            if len(made) == 1 or not first_only:
                raise FoldedLiftError("the boundary cross field could not be lifted to 3D (stand-in)")
            return lift(mesh, bf, edge_length)
        return check

    V, F, net = load_example("cube")
    monkeypatch.setattr(mb, "check_lift", folds(first_only=True))
    p = FieldProblem(V, F, net, Options(edge_length=0.5))
    assert len(made) == 2 and p.mesh is made[1] and made[0] is not made[1]
    assert any("was made again" in n and "(stand-in)" in n for n in p.report.notes), p.report.notes
    r = p.solve()
    assert r.report.converged and p.report.notes[0] in r.report.notes
    made.clear()
    monkeypatch.setattr(mb, "check_lift", folds(first_only=False))
    with pytest.raises(FoldedLiftError, match="a second mesh of the same input folded too"):
        FieldProblem(V, F, net, Options(edge_length=0.5))
    assert len(made) == 2
    made.clear()
    with pytest.raises(FoldedLiftError, match=r"\(stand-in\)$"):
        FieldProblem(V, F, net, Options(edge_length=0.5), mesh=p.mesh)
    assert len(made) == 1
