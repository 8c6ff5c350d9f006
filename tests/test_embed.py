"""Tracing curves through the tet mesh (embed.py) where they meet mesh edges."""

from __future__ import annotations

import numpy as np
import pytest

from solver.embed import TetLocator, _Degenerate, trace_curve
from tests.meshes import box_mesh


def test_a_curve_through_a_mesh_edge_is_retried_or_walked_face_to_face():
    mesh = box_mesh(3)
    loc = TetLocator(mesh)
    c = 1.0 / 3.0
    # crosses the vertical mesh edge x = y = 1/3 at mid height
    P = np.array([[c - 0.1, c - 0.05, 0.5], [c + 0.1, c + 0.05, 0.5]])
    t0 = int(loc.locate(P[:1])[0])
    tol = 1e-9 * mesh.mean_edge_length
    with pytest.raises(_Degenerate):
        trace_curve(mesh, loc, P, t0, -1, False, "test", tol)
    tr = trace_curve(mesh, loc, P, t0, -1, False, "test", tol, strict=False)
    assert len(tr.faces) >= 1 and len(tr.tets) == len(tr.faces) + 1
    for k, f in enumerate(tr.faces):  # a chain of face-adjacent tets
        assert set(mesh.face_tets[f]) == {tr.tets[k], tr.tets[k + 1]}
    assert loc.barycentric(tr.tets[-1], P[-1]).min() > -1e-9  # ends where the curve ends
