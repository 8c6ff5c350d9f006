"""solver.check: a solve's validation, curve intake and resolution plan on
their own, as the command line's --check and the add-on's Check Network run
them (solver/precheck.py)."""

from __future__ import annotations

import numpy as np
import pytest

from solver import CheckResult, Curve, NetworkError, Options, OptionsError, check
from solver.examples import load_example
from solver.mesh.resolution import ResolutionError


@pytest.fixture(scope="module")
def cylinder():
    return load_example("cylinder")


def test_check_reports_the_input_as_a_solve_takes_it(cylinder):
    V, F, net = cylinder
    found = check(V, F, net, options=Options(target_tets=8000))
    assert isinstance(found, CheckResult)
    assert found.interior_curves == 4 and found.nodes == 0 and found.boundary_components == 1
    assert found.sharp_edges > 0  # the rims
    assert len(found.repairs) == 4 and found.repairs_text() == ""  # clean curves: nothing to repair
    assert 0.5 * 8000 < found.plan.tets < 1.5 * 8000 and "expected ~" in found.plan.describe()
    # the default options and an explicit edge length
    assert check(V, F, net).plan.tets > check(V, F, net, options=Options(edge_length=0.5)).plan.tets


def test_check_says_what_the_intake_repaired():
    V, F, net = load_example("cylinder")
    c = net.curves[0]
    top = c.points[-1] + 0.05 * (c.points[-1] - c.points[-2]) / np.linalg.norm(c.points[-1] - c.points[-2])
    net.curves[0] = Curve(np.vstack([c.points, top]), sigma=c.sigma, name=c.name)  # past the cap
    found = check(V, F, net, options=Options(edge_length=0.3))
    assert found.repairs[0].changed and "end cut back" in found.repairs_text()


def test_check_refuses_as_a_solve_would(cylinder):
    V, F, net = cylinder
    with pytest.raises(ResolutionError, match="max_tets"):
        check(V, F, net, options=Options(edge_length=1e-4))
    with pytest.raises(NetworkError, match="outside"):
        check(V, F, type(net)(curves=[Curve(c.points + [3.0, 0, 0], sigma=c.sigma) for c in net.curves],
                              sharp_angle=net.sharp_angle))
    with pytest.raises(OptionsError, match="must be a solver.Options"):
        check(V, F, net, options={"edge_length": 0.3})
    with pytest.raises(TypeError):
        check(V, F, net, Options())  # options by keyword only
