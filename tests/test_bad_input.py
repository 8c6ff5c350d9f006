"""Every kind of bad input is refused before any heavy work, with an error of
the documented class whose message names the culprit and says what to do."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from solver import (
    Curve,
    Network,
    NetworkError,
    Options,
    OptionsError,
    SurfaceError,
    SymFramesError,
    TopologyError,
    io,
    solve,
)
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
    if degree == 2:  # two pieces of one curve are joined (intake): only pieces that cannot be one curve are refused
        curves[1] = Curve(seg([0.0, 0.0, 0.0], dirs[1]), 0.25, name="arm1")
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


# ------------------------------------------------ types and ranges (checks.py)
@pytest.mark.parametrize("kw, match", [
    (dict(edge_length="0.3"), r"option 'edge_length' = '0\.3' \(a string\).*without quotes"),
    (dict(penalty=None), r"option 'penalty' = null/None"),
    (dict(target_tets=0), r"option 'target_tets' = 0: must be a whole number >= 1"),
    (dict(target_tets=-5), r"'target_tets' = -5"),
    (dict(tube_radius=0), r"'tube_radius' = 0: must be a finite number > 0"),
    (dict(node_radius=-1), r"'node_radius' = -1"),
    (dict(epsilon=-1e-3), r"'epsilon' = -0\.001"),
    (dict(tolerance=-1.0), r"'tolerance' = -1\.0: must be a finite number >= 0"),
    (dict(edge_length=float("inf")), r"'edge_length' = inf"),
    (dict(edge_length=float("nan")), r"'edge_length' = nan"),
    (dict(penalty=float("inf")), r"'penalty' = inf"),
    (dict(max_iterations=2.7), r"'max_iterations' = 2\.7: must be a whole number"),
    (dict(refine=1.5), r"'refine' = 1\.5"),
    (dict(seed="abc"), r"'seed' = 'abc' \(a string\)"),
    (dict(init="ones"), r"'init' = 'ones'.*'zero'"),
    (dict(snap_features="no"), r"'snap_features' = 'no'.*true or false"),
])
def test_options_refused_at_construction(kw, match):
    with pytest.raises(OptionsError, match=match) as info:
        Options(**kw)
    assert isinstance(info.value, ValueError)


def test_options_accept_plain_and_numpy_numbers():
    o = Options(edge_length=np.float32(0.25), max_iterations=np.int64(5), refine=2.0, seed=np.uint8(3))
    assert (o.edge_length, o.max_iterations, o.refine, o.seed) == (0.25, 5, 2, 3)
    assert type(o.max_iterations) is int and type(o.edge_length) is float


@pytest.mark.parametrize("make, match", [
    (lambda P: Curve(P, sigma=None, name="axis"), r"curve 'axis': sigma = null/None"),
    (lambda P: Curve(P, role="singularity"), r"role = 'singularity'.*'singular', 'feature', 'sharp'"),
    (lambda P: Curve(P, torsion="loose"), r"torsion = 'loose'.*'free', 'fixed'"),
    (lambda P: Curve(P, closed="false"), r"closed = 'false' \(a string\): must be true or false"),
    (lambda P: Curve([[0, 0, 0], [1, 0]], name="ragged"), r"curve 'ragged': points: point 1 is \[1, 0\]"),
    (lambda P: Curve(P[:, :2]), r"points = .*\(n, 3\)"),
    (lambda P: Network([P]), r"curves\[0\] is .* not a Curve; wrap each polyline"),
    (lambda P: Network(Curve(P)), r"curves must be a list"),
    (lambda P: Network(sharp_angle="30"), r"sharp_angle = '30' \(a string\).*without quotes, e.g. 30"),
    (lambda P: Network(sharp_angle=-10), r"sharp_angle = -10"),
    (lambda P: Network(sharp_angle=float("nan")), r"sharp_angle = nan"),
    (lambda P: Network(sharp_angle=180), r"sharp_angle = 180: .*< 180"),
    (lambda P: Network(node_tolerance=-1e-3), r"node_tolerance = -0\.001"),
    (lambda P: Network(boundary_tolerance="0.01"), r"boundary_tolerance = '0\.01'"),
    (lambda P: Network(sharp_edges=[["a", "b"]]), r"sharp_edges: entry 0 is \['a', 'b'\]"),
    (lambda P: Network(sharp_edges=[[0, -1]]), r"sharp_edges: entry 0 .* negative"),
])
def test_network_and_curve_refused_at_construction(make, match):
    with pytest.raises(NetworkError, match=match):
        make(seg([0.0, 0.0, -1.0], [0.0, 0.0, 1.0]))


def test_huge_node_tolerance_refused(cube):
    V, F = cube
    c = Curve(seg([0.1, 0.1, -1.0], [0.1, 0.1, 1.0]), 0.25)
    with pytest.raises(NetworkError, match=r"node_tolerance = 1e\+06 is more than half the size of the whole network"):
        Network([c], node_tolerance=1e6)  # refused at construction, against the curves
    net = Network([c], node_tolerance=0.5)  # fine for the curves, too large for the cube
    expect(NetworkError, r"node_tolerance = 0\.5 is more than 0\.1 of the surface's bounding-box diagonal", V, F, net)


def _write_cylinder(tmp_path):
    V, F, net = cylinder_example()
    io.write_obj(str(tmp_path / "c.obj"), V, F)
    io.write_network(str(tmp_path / "c.json"), net, surface="c.obj")
    return json.loads((tmp_path / "c.json").read_text())


def _cli_error(tmp_path, capsys, d, *extra):
    (tmp_path / "m.json").write_text(json.dumps(d))
    rc = cli_main([str(tmp_path / "m.json"), "-q", *extra])
    err = capsys.readouterr().err
    assert rc == 1 and err.startswith("error: ") and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("change, match", [
    (dict(sharp_angle="30"), "sharp_angle = '30'"),
    (dict(boundary_tolerance="0.01"), "boundary_tolerance = '0.01'"),
    (dict(options={"edge_length": "0.3"}), "option 'edge_length' = '0.3'"),
    (dict(options={"penalty": None}), "option 'penalty' = null/None"),
    (dict(options=[1]), r"options = \[1\] \(a list\): must be an object"),
    (dict(options={"max_iterations": 2.5}), "option 'max_iterations' = 2.5"),
    (dict(options={"seed": "abc"}), "option 'seed' = 'abc'"),
    (dict(options={"tube_radius": 0}), "option 'tube_radius' = 0"),
    (dict(options={"edge_lenght": 0.3}), r"unknown solver option\(s\) \['edge_lenght'\]"),
    (dict(curves={"a": 1}), r"curves = .*: must be a list"),
    (dict(sharp_edges=[["a", "b"]]), r"sharp_edges: entry 0 is \['a', 'b'\]"),
    (dict(surface=5), "surface = 5: must be a string"),
])
def test_network_file_wrong_types(tmp_path, capsys, change, match):
    """Wrong JSON types: an error naming the key, never a traceback, and
    refused with --check too (before any meshing)."""
    d = _write_cylinder(tmp_path)
    d.update(change)
    import re

    assert re.search(match, _cli_error(tmp_path, capsys, d, "--check"))


@pytest.mark.parametrize("key, value, match", [
    ("sigma", None, r"curve 0 'axial 0': sigma = null/None"),
    ("points", [[0, 0, 0], [1, 0]], r"curve 0 'axial 0': points: point 1 is \[1, 0\]"),
    ("points", "abc", r"curve 0 'axial 0': points = 'abc'"),
    ("role", "bogus", r"curve 0 'axial 0': role = 'bogus'.*'singular', 'feature', 'sharp'"),
    ("torsion", "bogus", r"curve 0 'axial 0': torsion = 'bogus'.*'free', 'fixed'"),
    ("closed", "false", r"curve 0 'axial 0': closed = 'false' \(a string\)"),
    ("name", 7, r"curve 0: name = 7: must be a string"),
])
def test_network_file_curve_types(tmp_path, capsys, key, value, match):
    import re

    d = _write_cylinder(tmp_path)
    d["curves"][0][key] = value
    assert re.search(match, _cli_error(tmp_path, capsys, d, "--check"))


def test_binary_network_file(tmp_path):
    p = tmp_path / "net.json"
    p.write_bytes(bytes(range(256)))
    with pytest.raises(NetworkError, match=r"net\.json: not a JSON text file"):
        io.read_network(str(p))


def test_command_line_refuses_before_work(tmp_path, capsys):
    """--target-tets <= 0, a negative --root and an unwritable -o are refused
    up front, not after the solve."""
    _write_cylinder(tmp_path)
    net = str(tmp_path / "c.json")
    for extra, match in ((["--target-tets", "0"], "'target_tets' = 0"), (["--target-tets", "-4"], "= -4"),
                         (["--root", "-1"], r"--root -1: must be a tet-mesh vertex index >= 0"),
                         (["-o", str(tmp_path / "no/such/dir/out.npz")], "does not exist; create it first"),
                         (["-o", str(tmp_path)], "is a folder"),
                         (["--edge-length", "nan"], "'edge_length' = nan")):
        assert cli_main([net, "-q", *extra]) == 1
        err = capsys.readouterr().err
        assert match in err, (extra, err)


def test_root_out_of_range_refused_before_lm(monkeypatch):
    """A root beyond the mesh is refused once the mesh exists, before LM."""
    from solver import FieldProblem
    from solver.field.volume3d import VolumeProblem
    from tests.meshes import box_mesh

    V, F = box(n=2)
    mesh = box_mesh(3, lo=(-1, -1, -1), hi=(1, 1, 1))  # a structured mesh: no fTetWild
    problem = FieldProblem(V, F, Network(sharp_angle=30), Options(edge_length=0.7), mesh=mesh)

    def boom(*a, **k):
        raise AssertionError("LM started")

    monkeypatch.setattr(VolumeProblem, "solve", boom)
    for root in (problem.mesh.n_vertices, 99999999):
        with pytest.raises(OptionsError, match=rf"root = {root}: .* <= {problem.mesh.n_vertices - 1}"):
            problem.solve(root=root)


# ---------------------------------------------------------------- OBJ files
TET_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"


@pytest.mark.parametrize("faces, match", [
    ("f 1 3 0\n", r"t\.obj:5: face refers to vertex 0 .* 1\.\.4 or -1\.\.-4 \(0 is not an OBJ index\)"),
    ("f 1 3 99\n", r"t\.obj:5: face refers to vertex 99 \(1-based\), but the file has 4 vertices"),
    ("f 1 3 -99\n", r"t\.obj:5: face refers to vertex -99 \(counting back"),
    ("f 1 3\n", r"t\.obj:5: a face needs at least 3 vertices"),
    ("f 1 3 x\n", r"t\.obj:5: bad face line"),
])
def test_obj_bad_face_index(tmp_path, faces, match):
    p = tmp_path / "t.obj"
    p.write_text(TET_OBJ + faces + "f 1 2 4\nf 1 4 3\nf 2 3 4\n")
    with pytest.raises(SurfaceError, match=match):
        io.read_obj(str(p))


def test_obj_bad_vertex_line(tmp_path):
    p = tmp_path / "t.obj"
    p.write_text("v 0 0 0\nv 1 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    with pytest.raises(SurfaceError, match=r"t\.obj:2: bad vertex line 'v 1 0'"):
        io.read_obj(str(p))


def test_obj_negative_indices_read(tmp_path):
    p = tmp_path / "t.obj"
    p.write_text(TET_OBJ + "f -4 -2 -3\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    V, F = io.read_obj(str(p))
    assert F[0].tolist() == [0, 2, 1]
    from solver.surface.validation import validate_surface

    validate_surface(V, F)


def test_triangle_soup(cube):
    V, F = cube
    W = V[F].reshape(-1, 3)
    msg = expect(SurfaceError, r"triangle soup", W, np.arange(len(W)).reshape(-1, 3), Network())
    assert "Merge by Distance" in msg


def test_obj_polygon_with_collinear_vertices(tmp_path):
    """A cube whose top face is one octagon through its edge midpoints (three
    collinear vertices per side): a fan gave zero-area triangles and the
    advice to merge duplicate vertices; ear clipping tiles it."""
    V, F = box(n=2)
    top = np.all(np.isclose(V[F][:, :, 2], 1.0), axis=1)
    ring = [(-1, -1), (0, -1), (1, -1), (1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0)]
    ids = [int(np.nonzero(np.all(np.isclose(V, [x, y, 1.0]), axis=1))[0][0]) + 1 for x, y in ring]
    text = "".join(f"v {x} {y} {z}\n" for x, y, z in V) + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F[~top])
    p = tmp_path / "octagon.obj"
    p.write_text(text + "f " + " ".join(map(str, ids)) + "\n")
    W, G = io.read_obj(str(p))
    assert len(G) == int(np.sum(~top)) + 6
    checked = check_input(W, G, Network(sharp_angle=30))
    assert checked.surface.face_areas.min() > 0.1
    assert np.isclose(np.sum(checked.surface.signed_volumes()), 8.0)


def test_ear_clipping_non_convex_polygons():
    """Random star-shaped polygons with collinear points: the triangles keep
    the polygon's orientation, have positive area and tile it exactly."""
    from solver.surface.polygons import ear_clip

    rng = np.random.default_rng(1)
    for _ in range(40):
        n = int(rng.integers(5, 14))
        ang = np.sort(rng.uniform(0, 2 * np.pi, n))
        r = rng.uniform(0.3, 1.0, n)
        P2 = np.c_[r * np.cos(ang), r * np.sin(ang)]
        P2 = np.insert(P2, 1, 0.5 * (P2[0] + P2[1]), axis=0)  # a collinear point
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        P = np.c_[P2, np.zeros(len(P2))] @ R.T + rng.normal(size=3)
        T = ear_clip(P)
        assert T is not None and len(T) == len(P) - 2
        x, y = P2[:, 0], P2[:, 1]
        area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        A = P2[T]
        tri = 0.5 * ((A[:, 1, 0] - A[:, 0, 0]) * (A[:, 2, 1] - A[:, 0, 1])
                     - (A[:, 1, 1] - A[:, 0, 1]) * (A[:, 2, 0] - A[:, 0, 0]))
        assert np.all(tri > 0) and np.isclose(tri.sum(), area)


# ------------------------------------------------------- several solids
def _two_boxes(lo, hi, n=2):
    V1, F1 = box(n=n)
    V2, F2 = box(lo=lo, hi=hi, n=n)
    return np.vstack([V1, V2]), np.vstack([F1, F2 + len(V1)])


def test_disjoint_solids_refused():
    V, F = _two_boxes((2, -1, -1), (4, 1, 1))
    msg = expect(SurfaceError, r"bounds 2 separate solids", V, F, Network(sharp_angle=30))
    assert "near (3, 0, 0)" in msg and "Solve each solid separately" in msg


def test_solid_inside_a_cavity_refused():
    V, F = box(lo=(-2, -2, -2), hi=(2, 2, 2), n=2)
    Vc, Fc = box(n=2)
    Vs, Fs = box(lo=(-0.5,) * 3, hi=(0.5,) * 3, n=2)
    W = np.vstack([V, Vc, Vs])
    G = np.vstack([F, Fc[:, ::-1] + len(V), Fs + len(V) + len(Vc)])
    expect(SurfaceError, r"component 2 .* is a solid inside a cavity", W, G, Network(sharp_angle=30))


@pytest.mark.parametrize("lo, hi", [((1, -1, -1), (3, 1, 1)),          # face to face, same grid
                                    ((1, -0.5, -0.3), (2, 0.5, 0.7)),  # face to face, offset
                                    ((0, -1, -1), (2, 1, 1)),          # overlapping, coincident faces
                                    ((1, 1, -1), (2, 2, 1))])          # along an edge
def test_touching_or_overlapping_solids_refused(lo, hi):
    """These passed validation and failed after meshing ('not connected') or
    were called a wrongly oriented cavity."""
    V, F = _two_boxes(lo, hi)
    msg = expect(SurfaceError, r"surface components \d and \d touch or overlap: triangles \d+ and \d+ meet at \(",
                 V, F, Network(sharp_angle=30))
    assert "solve each solid separately" in msg


def test_cavity_still_allowed():
    V, F = box(n=2)
    Vc, Fc = box(lo=(-0.5,) * 3, hi=(0.5,) * 3, n=2)
    from solver.surface.validation import validate_surface

    S = validate_surface(np.vstack([V, Vc]), np.vstack([F, Fc[:, ::-1] + len(V)]))
    assert S.n_components == 2


def test_self_intersection_broad_phase_per_triangle():
    """A few long triangles among many small ones: each triangle searches
    its own neighbourhood (one global radius made this quadratic: a 13,102-
    face version took 49 s, the 25k one ran out of memory)."""
    from solver.surface.intersect import candidate_pairs
    from solver.surface.polygons import ear_clip
    from solver.surface.validation import validate_surface

    V, F = box(n=20)
    top = np.all(np.isclose(V[F][:, :, 2], 1.0), axis=1)
    rim = np.nonzero(np.isclose(V[:, 2], 1.0) & (np.isclose(np.abs(V[:, 0]), 1) | np.isclose(np.abs(V[:, 1]), 1)))[0]
    ring = rim[np.argsort(np.arctan2(V[rim, 1], V[rim, 0]))]
    F = np.vstack([F[~top], ring[ear_clip(V[ring])]])
    S = validate_surface(V, F)  # unused centre vertices are allowed
    n_pairs = sum(len(f) for f, _ in candidate_pairs(S))
    assert n_pairs < 30 * len(F), n_pairs  # 4,078 faces: 34,659 candidate pairs, not ~n^2 / 2


# ------------------------------------------------------ node configurations
def test_four_half_turn_curves_at_a_node_refused():
    """Accepted before, and LM ended at a penalty of 91: four sigma = 1/2
    curves at an interior node of the ball leave room for no hex."""
    from solver.examples import icosphere

    V, F = icosphere(3)
    dirs = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)]
    net = Network([Curve(seg([0.0, 0.0, 0.0], d, 9), 0.5, name=f"arm{k}") for k, d in enumerate(dirs)])
    msg = expect(NetworkError, r"node 0 at \(0, 0, 0\) joining curve 0 'arm0' \(\+0\.5\).*sum to 2.*at most 1", V, F,
                 net)
    assert "0 hexes" in msg


DIRS3 = [(1, 0, 0), (-0.5, 0.866, 0), (-0.5, -0.866, 0)]
DIRS4 = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0)]


@pytest.mark.parametrize("sigmas, match", [
    ((0.25, 0.25, 0.25), "3 of its curves have an index that is an odd multiple of 1/4"),
    ((0.25, 0.25, 0.25, 0.0), "3 of its curves"),
    ((-0.25, 0.0, 0.0), "1 of its curves"),
    ((0.5, 0.5, 0.25, 0.25), r"sum to 1\.5.*at most 1 at a node of 4"),
    ((0.5, 0.5, 0.5, 0.5), "sum to 2"),
    ((0.75, 0.75, 0.5), r"sum to 2.*at most 1\.5 at a node of 3"),
    ((0.25, 0.25, 0.0), None), ((-0.25, -0.25, 0.0), None), ((0.5, 0.5, 0.5), None),
    ((0.25, 0.25, 0.25, 0.25), None), ((-0.25,) * 4, None), ((0.25, 0.25, -0.25, -0.25), None),
    ((0.5, 0.0, 0.0, 0.5), None), ((0.0, 0.0, 0.0), None),
])
def test_node_rules(sigmas, match):
    """Parity of quarter turns (any cross field) and 6 - 2 sum(sigma) >= k
    (a hex-mesh vertex); the ball's nodes (four +1/4) are accepted."""
    from solver.network.network import prepare_network
    from solver.network.validation import check_nodes

    dirs = DIRS3 if len(sigmas) == 3 else DIRS4
    curves = [Curve(seg([0.0, 0.0, 0.0], d), s, "singular" if s else "feature", name=f"c{k}")
              for k, (d, s) in enumerate(zip(dirs, sigmas))]
    pn = prepare_network(Network(curves), 4.0)
    if match is None:
        check_nodes(pn, str)
    else:
        with pytest.raises(NetworkError, match=match):
            check_nodes(pn, str)


@pytest.mark.parametrize("V, F", [([[0, 0, "a"]] * 4, [[0, 1, 2]] * 4), ([[0, 0, 0], [1, 0]], [[0, 1, 2]]),
                                  ([[0, 0, 0]] * 4, [[0, 1], [2]])])
def test_surface_arrays_of_the_wrong_kind(V, F):
    expect(SurfaceError, r"surface vertices must be an \(n, 3\) array of numbers", V, F, Network())


def test_sharp_edges_arrays():
    """What the add-on passes (integer or integral float pairs, or none) is
    accepted; fractional indices are not."""
    assert Network(sharp_edges=np.zeros((0, 2))).sharp_edges.shape == (0, 2)
    assert Network(sharp_edges=np.array([[1.0, 2.0]])).sharp_edges.tolist() == [[1, 2]]
    with pytest.raises(NetworkError, match=r"sharp_edges = \[\[1\.5, 2\.0\]\]"):
        Network(sharp_edges=np.array([[1.5, 2.0]]))


# ------------------------------------------------------------ issue 43
def test_utf16_obj_and_far_vertex_and_deep_json(tmp_path):
    """A UTF-16 OBJ (Windows tools) reads as the UTF-8 one; a vertex at
    1e200 is refused naming its line; JSON nested thousands deep is a
    NetworkError, not a RecursionError."""
    V, F = box(n=2)
    text = "".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V) + "".join(f"f {a + 1} {b + 1} {c + 1}\n"
                                                                            for a, b, c in F)
    for enc in ("utf-16", "utf-16-le", "utf-32"):
        (tmp_path / "u.obj").write_bytes(text.encode(enc))
        W, G = io.read_obj(str(tmp_path / "u.obj"))
        assert np.allclose(W, V) and np.array_equal(G, F)
    (tmp_path / "far.obj").write_text(text + "v 1e200 0 0\n")
    with pytest.raises(SurfaceError, match=rf"far\.obj:{len(V) + len(F) + 1}: vertex {len(V) + 1} at \[1e\+200"):
        io.read_obj(str(tmp_path / "far.obj"))
    (tmp_path / "deep.json").write_text("[" * 100000 + "]" * 100000)
    with pytest.raises(NetworkError, match="nested too deeply"):
        io.read_network(str(tmp_path / "deep.json"))


def test_api_arguments_of_the_wrong_kind():
    """solve(V, F, None), complex or None vertices, 10**30 indices and
    10**400 numbers, and curve fields set after construction: the CLI's
    error classes, not AttributeError, TypeError or OverflowError."""
    V, F = box(n=2)
    with pytest.raises(NetworkError, match="network = null/None: must be a solver.Network"):
        solve(V, F, None)
    with pytest.raises(SurfaceError, match="complex numbers"):
        check_input(V + 1j, F, Network())
    with pytest.raises(SurfaceError, match="surface vertices = None"):
        check_input(None, F, Network())
    with pytest.raises(OptionsError, match=r"'edge_length' = ~10\*\*400"):
        Options(edge_length=10**400)
    with pytest.raises(NetworkError, match=r"vertex index ~10\*\*30"):
        Network(sharp_edges=[[10**30, 1]])
    c = Curve(np.array([[0.0, 0, -1], [0, 0, 1]]), 0.25, name="axis")
    for field, value in (("sigma", "x"), ("points", None), ("role", "bogus"), ("closed", 2)):
        with pytest.raises(NetworkError, match=f"curve 'axis': {field}"):
            setattr(c, field, value)
    assert c.sigma == 0.25 and c.points.shape == (2, 3)  # the old values are kept
    net = Network(curves=[c])
    with pytest.raises(NetworkError, match="curves\\[1\\] is"):
        net.curves = [c, "not a curve"]
    assert len(net.curves) == 1


@pytest.mark.slow
def test_the_plane_side_early_out_never_hides_a_crossing():
    """_crossing drops pairs whose unshared corners lie strictly on one side
    of the other's plane before its six edge tests; on 3,000 random pairs
    (a third sharing a corner, many nearly coplanar) it finds a crossing
    exactly where the six edge tests alone do."""
    from solver.surface.intersect import _crossing, segment_crosses_triangle
    from solver.surface.trisurface import TriSurface

    rng = np.random.default_rng(7)
    n = 3000
    A = rng.normal(size=(n, 3, 3))
    B = A.mean(axis=1)[:, None] + rng.normal(size=(n, 3, 3)) * rng.choice([1.0, 0.3, 1e-3], size=(n, 1, 1))
    B[rng.random(n) < 0.3, 2] *= 1e-9  # some nearly flat against the first's neighbourhood
    share = rng.random(n) < 0.33
    B[share, 0] = A[share, 0]
    V = np.concatenate([A.reshape(-1, 3), B.reshape(-1, 3)])
    F = np.arange(6 * n).reshape(2 * n, 3)
    F[n:][share, 0] = F[:n][share, 0]
    S = TriSurface(V, F)
    f, g = np.arange(n), np.arange(n, 2 * n)
    tol = 1e-9 * S.bbox_diagonal
    P = V[F]
    want = np.zeros(n, bool)
    for X, Y in ((f, g), (g, f)):
        for k in range(3):
            a, b = F[X, k], F[X, (k + 1) % 3]
            touches = (a[:, None] == F[Y]).any(1) | (b[:, None] == F[Y]).any(1)
            want |= segment_crosses_triangle(V[a], V[b], P[Y], tol) & ~touches
    got = np.array([_crossing(S, f[i : i + 1], g[i : i + 1]) is not None for i in range(n)])
    assert 100 < want.sum() < n - 100
    assert np.array_equal(got, want)


@pytest.mark.parametrize("scale, words", [
    ((1e-200,) * 3, "only 2e-200 across (its largest extent), too small for SymFrames' double-precision geometry"),
    ((0.0,) * 3, "the surface has no size: all its"),
    ((1, 1, 0), "the surface is flat: 2 across but 0 along z"),
    ((1, 1e-300, 1), "along y"),
])
def test_a_surface_of_no_size_or_flat_is_refused_saying_so(scale, words):
    """Issue 52: a surface scaled by 1e-200 or flattened (an add-on domain
    with scale (1, 1, 0)) says what it is, not "zero size" or "degenerate
    triangles"; 1e-40 of the cube still checks."""
    from solver import check

    V, F = box(n=2)
    with pytest.raises(SurfaceError, match=re.escape(words)):
        check(V * np.array(scale, float), F, Network(sharp_angle=30))
    check(V * 1e-40, F, Network(sharp_angle=30))
