"""The result does not depend on the model's units (issue 28, item 5)."""

from __future__ import annotations

import numpy as np
import pytest

from solver import Curve, Network, Options, solve
from solver.examples import cylinder_example, cylinder_surface

# every test here solves, meshes or hex meshes an example: slow and mesher (CONTRIBUTING.md, Testing)
pytestmark = [pytest.mark.slow, pytest.mark.mesher]


def test_cylinder_at_micrometre_scale_solves():
    """The cylinder scaled by 1e-6 failed after meshing with 'no tetrahedra
    lie inside the surface' (fTetWild's absolute tolerances); it is now
    meshed centred and scaled to a unit diagonal, and solves like the
    unscaled one.  (The example's network in a 32-gon of the same solid,
    as tests/test_refine.py meshes it: the 64-gon's 4,480 triangles cost
    fTetWild twice the time and test nothing more here.)"""
    s = 1e-6
    _, _, net = cylinder_example()
    V, F = cylinder_surface(1.0, 2.0, n=32, rings=4)
    net = Network([Curve(c.points * s, c.sigma, c.role, c.torsion, c.name) for c in net.curves],
                  sharp_angle=net.sharp_angle)
    r = solve(V * s, F, net, edge_length=0.4 * s)  # meshed here: fTetWild at this scale is the point
    X = r.mesh.vertices
    # the boundary within the mesher's envelope of the surface (epsilon of
    # its diagonal): the 1,088-triangle surface, 4x denser than a 0.4-mesh
    # of it, goes to fTetWild as it is (sharp rims: mesh/tetwild.py,
    # wants_simplify), and its mesh keeps the polygon's extreme vertices
    env = Options().epsilon * np.linalg.norm(np.ptp(V, axis=0)) * s
    assert np.allclose(X.min(axis=0), V.min(axis=0) * s, atol=env)
    assert np.allclose(X.max(axis=0), V.max(axis=0) * s, atol=env)
    assert np.isclose(np.sum(r.mesh.tet_volumes), np.pi * 2.0 * s**3, rtol=0.03)
    m = r.report.metrics
    assert r.report.lm.converged, r.report.lm.reason
    assert m["omega_spurious_singular_faces"] == 0 and m["omega_missing_singular_faces"] == 0, m
    assert m["normal_adaptation_mean_deg"] < 1.0 and m["tangent_adaptation_mean_deg"] < 2.0, m
