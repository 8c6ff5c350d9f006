"""Every hex failure is a diagnosis (issue 48a): the exit code, the kind
(the network admits no hex mesh / the cell size / the field / SymFrames' map)
and a message naming the cause and the place; no numpy or scipy message
reaches the user, and a field that did not converge is never meshed."""

import json
import os

import numpy as np
import pytest

from solver import io
from solver.__main__ import EXIT_NO_HEX_MESH, EXIT_NOT_CONVERGED, main
from solver.hexmesh import HexMeshError, hexmesh, mesher, smooth
from testkit.fields import with_curve

# every test here runs tet meshing (fTetWild/TetGen), itself or through the session fixtures
pytestmark = pytest.mark.mesher


@pytest.mark.slow
def test_kinds_name_whose_limit_it_is(solved):
    res = solved("cylinder")
    with pytest.raises(HexMeshError, match="larger than half the solid") as e:
        hexmesh(res, 10.0)
    assert e.value.kind == "settings"
    inp = with_curve(res.field, 0, sigma=0.5)
    with pytest.raises(HexMeshError, match="valence 2") as e:
        hexmesh(inp)
    assert e.value.kind == "network"
    # index -1 (valence 8): whole turns, a limit of SymFrames' map, said before any hex work
    inp = with_curve(res.field, 0, sigma=-1.0)
    with pytest.raises(HexMeshError, match="valence 8.*whole turns.*a limit of SymFrames") as e:
        hexmesh(inp)
    assert e.value.kind == "map" and e.value.report is None


def test_a_whole_turn_curve_is_refused_before_the_solve(tmp_path, capsys):
    """The command line checks the indices before any work: a curve of index
    -1 with --hex is exit 4, said as a limit of SymFrames, nothing solved."""
    from solver import Curve, Network
    from solver.examples import load_example

    V, F, net = load_example("cylinder")
    curves = [Curve(c.points, -1.0 if i == 0 else c.sigma, c.role, c.torsion, c.name)
              for i, c in enumerate(net.curves)]
    net_path = str(tmp_path / "net.json")
    io.write_obj(str(tmp_path / "c.obj"), V, F)
    io.write_network(net_path, Network(curves, sharp_angle=net.sharp_angle), surface="c.obj")
    out = str(tmp_path / "c.vtu")
    assert main([net_path, "--hex", out, "-q"]) == EXIT_NO_HEX_MESH
    err = capsys.readouterr().err
    assert "limit of SymFrames" in err and "valence 8" in err and "nothing was solved" in err
    assert not os.path.exists(out)


@pytest.mark.slow
def test_a_field_that_did_not_converge_is_not_meshed(solved, tmp_path, capsys):
    res = solved("cylinder", max_iterations=1)
    assert not res.report.converged, res.report.summary()
    with pytest.raises(HexMeshError, match="did not converge") as e:
        hexmesh(res)
    assert e.value.kind == "field" and res.report.status in str(e.value)
    # the command line: exit 3 (the field's status), before any hex work, no hex file
    npz, out = str(tmp_path / "c.npz"), str(tmp_path / "c.vtu")
    io.save_result(npz, res)
    capsys.readouterr()
    assert main(["--from-result", npz, "--hex", out, "-q"]) == EXIT_NOT_CONVERGED
    err = capsys.readouterr().err
    assert "not converged" in err and "no hex file written" in err
    assert not os.path.exists(out)


@pytest.mark.slow
def test_an_internal_failure_is_said_as_a_limit_of_symframes(solved, monkeypatch, tmp_path, capsys):
    """A numpy error inside a stage (here the extraction's, as a singular
    matrix) becomes a HexMeshError of kind 'map' naming the stage; at the
    automatic cell size smaller cells are tried first, and said."""
    res = solved("cylinder")
    calls = []

    def broken(*a, **k):
        calls.append(a[-1])
        raise np.linalg.LinAlgError("Singular matrix")

    monkeypatch.setattr(mesher, "extract_hexes", broken)
    with pytest.raises(HexMeshError) as e:
        hexmesh(res, smooth=False)
    msg = str(e.value)
    assert e.value.kind == "map" and "'extraction'" in msg and "limit of SymFrames" in msg
    assert "not a fault of the network" in msg and "cell sizes tried" in msg
    # each size tried reaches the extraction unless its map fails first
    assert 1 <= len(calls) <= len(mesher.AUTO_STEPS) and calls == sorted(calls, reverse=True)
    # a cell size the user gave is tried alone
    calls.clear()
    with pytest.raises(HexMeshError, match="extraction"):
        hexmesh(res, 0.3, smooth=False)
    assert calls == [0.3]
    # the command line: exit 4, the kind first, no traceback
    npz, out = str(tmp_path / "c.npz"), str(tmp_path / "c.vtu")
    io.save_result(npz, res)
    capsys.readouterr()
    assert main(["--from-result", npz, "--hex", out, "--no-smooth", "-q"]) == EXIT_NO_HEX_MESH
    err = capsys.readouterr().err
    assert "SymFrames' map failed (a limit of SymFrames, not a fault of the network)" in err
    assert "Traceback" not in err and not os.path.exists(out)


@pytest.mark.slow
def test_a_map_failure_at_the_automatic_size_steps_the_cell_down(solved, monkeypatch):
    """The first automatic cell size fails (as a stalled untangling would);
    the next one meshes, and the report says what happened."""
    res = solved("cylinder")
    real = mesher.extract_hexes
    seen = []

    def first_fails(*a, **k):
        seen.append(a[-1])
        if len(seen) == 1:
            raise np.linalg.LinAlgError("Singular matrix")
        return real(*a, **k)

    monkeypatch.setattr(mesher, "extract_hexes", first_fails)
    hm = hexmesh(res, smooth=False)
    assert len(seen) >= 2 and np.isclose(seen[1], mesher.AUTO_STEPS[1] * seen[0])
    assert any(np.isclose(hm.report.cell_size, c) for c in seen[1:])
    assert hm.report.notes and "the map failed" in hm.report.notes[0] and "note:" in hm.report.summary()


@pytest.mark.slow
def test_a_smooth_torus_without_curves_is_a_map_limit_with_the_reason(solved):
    """The seamless map of the smooth solid torus folds; the message says it
    is SymFrames' map that failed, and why such a solid needs curves, without
    calling that a proof about the user's network."""
    res = solved("torus", edge_length=0.3, max_iterations=40, mesher="TetGen")  # test_examples' solve
    assert res.report.converged, res.report.summary()
    with pytest.raises(HexMeshError) as e:
        hexmesh(res)
    assert e.value.kind == "map", str(e.value)
    assert not e.value.finer  # it folds so at any resolution: --hex and the add-on do not solve again finer
    assert "before rounding" in str(e.value) and "torus" in str(e.value)
    assert "not a proof" in str(e.value) and "add them" in str(e.value)


@pytest.mark.slow
def test_the_automatic_cell_size_says_why_and_keeps_close_curves_apart(solved):
    """Issue 48d: the default cell size resolves the network and says why:
    the cylinder's 4 axial curves are 0.7 apart, so the target's cells rule;
    with one curve moved to 0.12 from another, 1.5 cells fit between them."""
    from solver.hexmesh.cellsize import cell_choice

    res = solved("cylinder")
    inp = res.field
    cell, why = cell_choice(inp)
    assert why.startswith("about 3,000 cells"), why
    P0 = inp.network.curves[0].points
    moved = P0 + np.array([0.12, 0.0, 0.0])
    inp = with_curve(inp, 1, points=moved)
    close, why = cell_choice(inp)
    assert np.isclose(close, 0.12 / 1.5, rtol=0.05) and close < cell, (close, why)
    assert "between curve" in why and "0.12 apart" in why, why


@pytest.mark.slow
def test_a_smoothing_run_that_diverges_keeps_the_maps_own_places(solved, monkeypatch):
    """A smoothing run whose positions go non-finite (seen once on a
    generated genus-2 part: scipy's "'x' must be finite") is dropped; with
    every run dropped the cells stay where the map put them."""
    res = solved("cylinder")

    def diverges(V, *a, **k):
        raise ValueError("'x' must be finite, check for nan or inf values")

    monkeypatch.setattr(smooth, "optimise", diverges)
    hm = hexmesh(res)
    assert hm.report.sj_min == pytest.approx(hm.report.sj_min_raw)
    assert np.isfinite(hm.vertices).all()


def test_a_radial_curve_inside_its_node_ball_is_put_onto_edges():
    """The cube-sphere network with an inner cube 0.45 of the radius: radial
    curves 0.22 long, inside their nodes' balls of tets at edge length 0.25
    (TetGen: the same mesh each run).  Refused before ("lies inside its
    nodes' balls of tets"; a generated ellipsoid's field, converged, was
    refused so); now the boundary face it ends on is split and the node's
    cone reaches it: every curve is a chain of the new mesh's edges, each
    radial one from its node to the surface."""
    from solver import FieldProblem, Options
    from solver.examples import ball_example
    from solver.hexmesh.curve_edges import curves_on_edges

    V, F, net = ball_example(inner=0.45)
    p = FieldProblem(V, F, net, Options(mesher="TetGen", edge_length=0.25))  # meshed here: its short curves
    cem = curves_on_edges(p.mesh, p.embedding, p.network)
    M = cem.mesh
    edges = set(map(tuple, np.sort(M.edges, axis=1).tolist()))
    on_surface = np.zeros(M.n_vertices, bool)
    on_surface[M.faces[M.boundary_faces].ravel()] = True
    radial = 0
    for c in cem.chains:
        assert all(tuple(sorted(e)) in edges for e in zip(c.vertices[:-1].tolist(), c.vertices[1:].tolist()))
        if p.network.curves[c.curve].name.startswith("radial"):
            radial += 1
            assert c.vertices[0] in set(cem.node_vertices.tolist()) and on_surface[c.vertices[-1]]
    assert radial == 8


@pytest.mark.slow
def test_a_map_that_needs_a_finer_field_solves_it_again_finer(monkeypatch, tmp_path, capsys):
    """The command line: where SymFrames' map fails on the field (here its
    first step, as when two nodes are closer than the field's mesh
    resolves) and the edge length was automatic, the field is solved again
    on a uniform mesh 0.7 times as fine, written over the result, and that
    field is meshed; with an edge length given it says to give a smaller
    one instead (exit 4)."""
    from solver.hexmesh.curve_edges import CurveEdgeError

    real, calls = mesher.curves_on_edges, []

    def first_fails(mesh, *a):
        calls.append(mesh.n_tets)
        if len(calls) == 1:
            raise CurveEdgeError("nodes 0 and 1 are too close for the field's mesh (their balls of tets overlap)")
        return real(mesh, *a)

    monkeypatch.setattr(mesher, "curves_on_edges", first_fails)
    npz, out = str(tmp_path / "c.npz"), str(tmp_path / "c.vtu")
    # a small budget: the edge length is still the automatic one, and the finer field 4x cheaper
    assert main(["--example", "cube", "--target-tets", "4000", "-o", npz, "--hex", out, "-q"]) == 0
    err = capsys.readouterr().err
    assert "solving the field again finer" in err and "solved again on a uniform mesh at edge length" in err
    assert len(calls) == 2 and calls[1] > 2 * calls[0]  # 0.7 times the edge length: ~2.9 times the tets
    assert os.path.exists(out) and io.load_field(npz).mesh.n_tets == calls[1]
    with np.load(npz) as z:  # the result file's report keeps the note of why and how
        notes = json.loads(str(z["report"]))["notes"]
    assert any("solved again on a uniform mesh" in n and "for the hex mesh" in n for n in notes), notes
    calls.clear()
    assert main(["--example", "cube", "--edge-length", "0.3", "-o", npz, "--hex", out + ".vtu", "-q"]) == \
        EXIT_NO_HEX_MESH
    err = capsys.readouterr().err
    assert "the edge length 0.3 was given; give a smaller one" in err and "too close" in err
    assert len(calls) == 1 and not os.path.exists(out + ".vtu")


def test_poor_cells_are_a_warning_that_names_them_and_ends_the_ladder(solved, monkeypatch):
    """Cells below a scaled Jacobian of 0.3: valid with a warning that says
    how many, the least and where, and, for cells much finer than the
    field's tets, that a larger cell size gives better ones; a smaller cell
    would not help, so the automatic ladder stops there."""
    from solver.hexmesh.report import HexReport, verdict

    r = HexReport(euler=[2], euler_expected=[2], structure_exact=True, sj_min=0.21, sj_poor=3,
                  sj_worst_at=[0.5, -0.25, 1.0], cell_size=0.01, tet_edge=0.1)
    verdict(r)
    assert r.valid and len(r.warnings) == 1, r.warnings
    assert "3 cells have a scaled Jacobian below 0.3 (the least 0.21, at (0.5, -0.25, 1))" in r.warnings[0]
    assert "a larger cell size gives better ones" in r.warnings[0]
    r.cell_size = 0.1  # as large as the tets: no such hint
    verdict(r)
    assert r.warnings and "larger cell size" not in r.warnings[0]
    r.sj_poor = 0
    verdict(r)
    assert r.valid and not r.warnings
    res = solved("cylinder")
    real, sizes = mesher.assess, []

    def poor(report, inp, V, H, cell, rel=None):
        real(report, inp, V, H, cell, rel)
        sizes.append(cell)
        report.sj_poor = 2
        verdict(report)

    monkeypatch.setattr(mesher, "assess", poor)
    hm = hexmesh(res, target_hexes=1000)
    assert len(sizes) == 1 and hm.report.valid and "below 0.3" in hm.report.warnings[0]


@pytest.mark.slow
def test_the_verdict_has_a_level_for_a_boundary_slightly_off(solved, monkeypatch):
    """valid; valid with warnings (the boundary 1-2% of the diagonal off the
    surface, said with the figure); defective past 2%.  At the automatic cell
    size a mesh with warnings gives way to a smaller size's clean one, and is
    kept where no size is clean."""
    from solver.hexmesh.report import HexReport, verdict

    r = HexReport(euler=[2], euler_expected=[2], structure_exact=True, hausdorff_relative=0.015)
    verdict(r)
    assert r.valid and len(r.warnings) == 1 and "1.50% of the diagonal" in r.warnings[0]
    assert "valid, with warnings: the boundary is 1.50%" in r.summary()
    r.hausdorff_relative = 0.025
    verdict(r)
    assert not r.valid and "2.50% of the diagonal" in r.reason and not r.warnings
    r.hausdorff_relative = 0.005
    verdict(r)
    assert r.valid and not r.warnings
    res = solved("cylinder")
    real, sizes = mesher.assess, []

    def off(report, inp, V, H, cell, rel=None):  # the first size's boundary 1.5% off, the others on it
        real(report, inp, V, H, cell, rel)
        sizes.append(cell)
        report.hausdorff_relative = 0.015 if len(sizes) == 1 else 0.001
        verdict(report)

    monkeypatch.setattr(mesher, "assess", off)
    hm = hexmesh(res, target_hexes=1000)  # the ladder and the verdict do not depend on the count: few cells
    assert len(sizes) >= 2 and "valid with warnings" in hm.report.notes[0]
    # the first clean size's mesh; the warned one only where no smaller size gave a valid mesh
    assert hm.report.valid and (not hm.report.warnings or hm.report.cell_size == sizes[0])
    sizes.clear()
    hm = hexmesh(res, 0.3)  # a size given: tried alone, kept with its warning
    assert sizes == [0.3] and hm.report.valid and hm.report.warnings

    def warned(report, inp, V, H, cell, rel=None):  # every size off, the second closest
        real(report, inp, V, H, cell, rel)
        sizes.append(cell)
        report.hausdorff_relative = (0.015, 0.012, 0.018)[min(len(sizes), 3) - 1]
        verdict(report)

    monkeypatch.setattr(mesher, "assess", warned)
    sizes.clear()
    hm = hexmesh(res, target_hexes=1000)
    assert len(sizes) == len(mesher.AUTO_STEPS) == 3
    # the closest of the sizes tried is kept, and its notes tell every size
    assert hm.report.valid and hm.report.cell_size == sizes[1] and "1.20%" in hm.report.warnings[0]
    notes = " | ".join(hm.report.notes)
    assert "1.50%" in notes and "1.80%" in notes and "kept the mesh at cell size" in hm.report.notes[-1], notes
