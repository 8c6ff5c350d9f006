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

