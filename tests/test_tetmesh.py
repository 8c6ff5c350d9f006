"""fTetWild's output as the pipeline takes it (solver/tetmesh.py)."""

from __future__ import annotations

import numpy as np
import pytest

import solver.tetmesh as tm
from solver.errors import MeshingError
from solver.examples import icosphere
from solver.trisurface import TriSurface


def _flatten_first_tet(P, T):
    """Move the fourth corner of the tet nearest the centre (fTetWild's
    unfiltered output also holds tets outside the solid) into the plane of
    the other three."""
    P = np.array(P, dtype=float)
    t = T[np.argmin(np.linalg.norm(P[T].mean(axis=1), axis=1))]
    a, b, c, d = (P[i] for i in t)
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    P[t[3]] = d - np.dot(d - a, n) * n
    return P, T


@pytest.fixture
def sphere():
    V, F = icosphere(2)
    return TriSurface(V, F)


def test_a_flat_tet_from_ftetwild_is_meshed_again(sphere, monkeypatch):
    """A flat tet would break point location and the cotan weights: the
    mesh is made again at a slightly different edge length."""
    real = tm.run_tetwild
    lengths = []

    def flaky(V, F, h, eps, cancel=None):
        lengths.append(h)
        P, T = real(V, F, h, eps, cancel=cancel)
        return _flatten_first_tet(P, T) if len(lengths) == 1 else (P, T)

    monkeypatch.setattr(tm, "run_tetwild", flaky)
    mesh = tm.tetrahedralize(sphere, 0.5)
    assert len(lengths) == 2 and lengths[1] != lengths[0]
    assert mesh.info["tetwild_retries"] == 1
    assert not tm.flat_tets(mesh).any()
    assert mesh.tet_volumes.min() > 0


def test_flat_tets_on_every_attempt_are_a_clear_error(sphere, monkeypatch):
    real = tm.run_tetwild
    monkeypatch.setattr(tm, "run_tetwild", lambda *a, **k: _flatten_first_tet(*real(*a, **k)))
    with pytest.raises(MeshingError, match="flat tetrahedra.*try another edge length"):
        tm.tetrahedralize(sphere, 0.5)
