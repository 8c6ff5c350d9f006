"""Every kind of bad input is refused before any heavy work, with an error of
the documented class whose message names the culprit and says what to do."""

from __future__ import annotations

import json

import numpy as np
import pytest

from solver import Curve, Network, NetworkError, SurfaceError, SymFramesError, TopologyError, io, solve
from solver.__main__ import main as cli_main
from solver.examples import box, cylinder_example, merge_vertices
from solver.network.validation import check_input


@pytest.fixture(scope="module")
def cube():
    V, F = box(n=4)
    return V, F


def seg(a, b, n=6):
    return np.linspace(a, b, n)


def expect(exc, match, V, F, net):
    with pytest.raises(exc, match=match) as info:
        check_input(V, F, net)
    assert isinstance(info.value, ValueError)  # callers may catch ValueError
    return str(info.value)


# ------------------------------------------------------------------ surface
def test_open_surface(cube):
    V, F = cube
    expect(SurfaceError, "(?i)closed|boundary|hole", V, F[1:], Network())


def test_non_manifold_surface(cube):
    V, F = cube
    # a second cube glued onto the face x = 1 of the first: those faces
    # appear twice, so their edges have four faces
    W = np.vstack([V, V + np.array([2.0, 0.0, 0.0])])
    FF = np.vstack([F, F + len(V)])
    W, FF = merge_vertices(W, FF)  # shares the face x = 1: faces there appear twice
    expect(SurfaceError, "(?i)manifold|twice|duplicate|more than two", W, FF, Network())


def test_inconsistently_oriented_surface(cube):
    V, F = cube
    F = F.copy()
    F[3] = F[3, ::-1]
    expect(SurfaceError, "(?i)orient", V, F, Network())


def test_inside_out_surface(cube):
    V, F = cube
    expect(SurfaceError, "(?i)inside out|orient|negative", V, F[:, ::-1], Network())


def test_degenerate_triangle(cube):
    V, F = cube
    V = V.copy()
    # collapse one triangle by moving a vertex onto its neighbour's position
    a, b = F[0, 0], F[0, 1]
    V = np.vstack([V, V[a]])
    F = F.copy()
    F[F == b] = len(V) - 1  # vertex b's faces now use a copy of vertex a
    msg = expect(SurfaceError, "(?i)degenerate|zero area|duplicate|manifold", V, F, Network())
    assert "triangle" in msg or "vertex" in msg or "face" in msg


def test_self_intersecting_surface(cube):
    V, F = cube
    V2, F2 = box(lo=(0.3, 0.37, 0.41), hi=(1.6, 1.55, 1.45), n=4)
    expect(SurfaceError, "(?i)intersect", np.vstack([V, V2]), np.vstack([F, F2 + len(V)]), Network())


def test_non_finite_vertex(cube):
    V, F = cube
    V = V.copy()
    V[5, 1] = np.nan
    expect(SurfaceError, "vertex 5", V, F, Network())


# ------------------------------------------------------------------ network
def test_curve_outside_the_solid(cube):
    V, F = cube
    c = Curve(seg([0.0, 0.0, -1.0], [0.0, 0.0, 1.0]) + [0.0, 1.5, 0.0], 0.25, name="outside")
    msg = expect(NetworkError, "'outside'", V, F, Network([c]))
    assert "outside the solid" in msg and "but not at a node" not in msg, msg


def test_curve_leaving_and_reentering(cube):
    V, F = cube
    P = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -0.5], [0.0, 1.5, 0.0], [0.0, 0.0, 0.5], [0.0, 0.0, 1.0]])
    expect(NetworkError, "'detour'", V, F, Network([Curve(P, 0.25, name="detour")]))


def test_dangling_endpoint(cube):
    V, F = cube
    c = Curve(seg([0.1, 0.1, -1.0], [0.1, 0.1, 0.2]), 0.25, name="stub")
    msg = expect(NetworkError, "'stub'", V, F, Network([c]))
    assert "node" in msg and "boundary" in msg


def test_self_intersecting_curve(cube):
    V, F = cube
    t = np.linspace(0, 1, 40)
    # a figure-of-eight loop inside the cube, crossing itself at the origin
    P = np.c_[0.5 * np.sin(2 * np.pi * t), 0.5 * np.sin(4 * np.pi * t), 0 * t]
    expect(NetworkError, "(?i)intersects itself|cross", V, F,
           Network([Curve(P, 0.0, "feature", name="eight", closed=True)]))


def test_crossing_curves(cube):
    V, F = cube
    a = Curve(seg([-1.0, 0.2, 0.0], [1.0, 0.2, 0.0]), 0.0, "feature", name="a")
    b = Curve(seg([0.2, -1.0, 0.0], [0.2, 1.0, 0.0]), 0.0, "feature", name="b")
    msg = expect(NetworkError, "cross", V, F, Network([a, b]))
    assert "'a'" in msg and "'b'" in msg


@pytest.mark.parametrize("degree", [2, 5])
def test_unsupported_node_degree(cube, degree):
    V, F = cube
    dirs = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]][:degree]
    curves = [Curve(seg([0.0, 0.0, 0.0], d), 0.0, "feature", name=f"arm{k}") for k, d in enumerate(dirs)]
    msg = expect(NetworkError, "(?i)node|degree|join", V, F, Network(curves))
    assert "arm0" in msg


def test_index_not_a_quarter_turn(cube):
    V, F = cube
    c = Curve(seg([0.1, 0.1, -1.0], [0.1, 0.1, 1.0]), 0.3, name="odd")
    msg = expect(NetworkError, "1/4", V, F, Network([c]))
    assert "'odd'" in msg and "0.25" in msg


def test_poincare_hopf_violated(cube):
    """A single +1/4 curve through the cube: its two ends add +1/2 on a face
    patch of the cube that needs 0 -- per patch and per component checks."""
    V, F = cube
    c = Curve(seg([0.1, 0.1, -1.0], [0.1, 0.1, 1.0]), 0.25, name="axis")
    msg = expect(TopologyError, "(?i)poincar|index|patch", V, F, Network([c], sharp_angle=30))
    assert "1/4" in msg or "0.25" in msg or "sum" in msg or "index" in msg


def test_poincare_hopf_per_component():
    """A smooth ball with a cavity: a curve from the outer sphere to the inner
    one is fine for neither component (each needs total index 2)."""
    from solver.examples import icosphere

    Vo, Fo = icosphere(2, 1.0)
    Vi, Fi = icosphere(2, 0.4)
    V = np.vstack([Vo, Vi])
    F = np.vstack([Fo, Fi[:, ::-1] + len(Vo)])  # the cavity's faces point into it
    c = Curve(seg([0.0, 0.0, 0.42], [0.0, 0.0, 0.98]), 0.25, name="spoke")
    msg = expect(TopologyError, "(?i)component|poincar|index", V, F, Network([c]))
    assert "2" in msg


def test_solve_refuses_before_meshing(cube):
    """The public entry point raises the same errors, fast."""
    V, F = cube
    with pytest.raises(SymFramesError, match="1/4"):
        solve(V, F, Network([Curve(seg([0.1, 0.1, -1.0], [0.1, 0.1, 1.0]), 0.1)]))


# --------------------------------------------------------------- file input
def test_network_file_errors(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{ not json")
    with pytest.raises(NetworkError, match="not valid JSON"):
        io.read_network(str(bad))
    bad.write_text(json.dumps({"curves": [{"points": [[0, 0, 0], [1, 0, 0]], "sigmaa": 0.25}]}))
    with pytest.raises(NetworkError, match="sigmaa"):
        io.read_network(str(bad))
    with pytest.raises(SurfaceError, match="cannot read"):
        io.read_obj(str(tmp_path / "missing.obj"))


def test_network_file_round_trip(tmp_path):
    V, F, net = cylinder_example()
    io.write_obj(str(tmp_path / "c.obj"), V, F)
    io.write_network(str(tmp_path / "c.json"), net, surface="c.obj", options={"edge_length": 0.3})
    net2, opts, surface = io.read_network(str(tmp_path / "c.json"))
    V2, F2 = io.read_obj(surface)
    assert np.allclose(V2, V) and np.array_equal(F2, F)
    assert opts == {"edge_length": 0.3}
    assert len(net2.curves) == len(net.curves)
    for a, b in zip(net.curves, net2.curves):
        assert np.allclose(a.points, b.points) and a.sigma == b.sigma and a.role == b.role
    assert net2.sharp_angle == net.sharp_angle


def test_command_line_reports_errors(tmp_path, capsys):
    V, F = box(n=2)
    io.write_obj(str(tmp_path / "box.obj"), V, F)
    net = Network([Curve(seg([0.1, 0.1, -1.0], [0.1, 0.1, 1.0]), 0.3, name="odd")])
    io.write_network(str(tmp_path / "box.json"), net, surface="box.obj")
    assert cli_main([str(tmp_path / "box.json")]) == 1
    err = capsys.readouterr().err
    assert "error:" in err and "'odd'" in err and "1/4" in err
