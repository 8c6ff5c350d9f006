"""suggest_network: a network for a solid that has none (solver/suggest)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from solver import Network, NetworkError, hexmesh, solve, suggest_network
from solver.__main__ import main
from solver.examples import ball_example, box, cylinder_surface, icosphere, prism_example, torus_surface, voxel_surface
from solver.io import read_network, write_obj
from solver.network.validation import check_input


@pytest.fixture(scope="module")
def sphere():
    V, F = icosphere(3)
    net, rep = suggest_network(V, F)
    return V, F, net, rep


def _nodes(V, F, net):
    ci = check_input(V, F, net)
    return ci, [sorted(ci.network.curves[i].sigma for i, _ in nd.ends) for nd in ci.network.nodes]


def test_sphere_gets_the_cube_sphere_network(sphere):
    """12 curves under the chart boundaries, 8 radial ones, all +1/4, and 8
    nodes of degree 4 (three padding curves and a radial each): the ball
    example's structure."""
    V, F, net, rep = sphere
    kinds = [c.kind for c in rep.curves]
    assert kinds.count("padding") == 12 and kinds.count("radial") == 8
    assert all(c.sigma == 0.25 for c in net.curves)
    assert rep.charts == 6 and rep.corners == 8 and rep.nodes == 8
    ci, nodes = _nodes(V, F, net)
    assert len(nodes) == 8 and all(s == [0.25] * 4 for s in nodes)
    ref = check_input(*ball_example())
    assert len(ref.network.curves) == len(ci.network.curves) and len(ref.network.nodes) == len(nodes)
    # the radial curves end on the sphere, the nodes lie well inside it
    ends = np.array([c.points[-1] for c, k in zip(net.curves, kinds) if k == "radial"])
    assert np.allclose(np.linalg.norm(ends, axis=1), 1.0, atol=0.02)
    pos = np.array([nd.position for nd in ci.network.nodes])
    assert np.all(np.linalg.norm(pos, axis=1) < 0.8)
    assert "20 curves" in rep.summary()


@pytest.mark.slow
@pytest.mark.mesher
def test_sphere_suggestion_solves_and_meshes(sphere):
    """As `python -m solver SURFACE.obj --hex` does: solved at the budget the
    suggestion asks for (at the default 15,000 the penalty ended at 7.69
    against 7.2 on one mesh), then a valid hex mesh whose irregular edges are
    the suggested curves."""
    V, F, net, rep = sphere
    r = solve(V, F, net, target_tets=rep.target_tets)
    assert r.report.converged, r.report.status_reason
    hm = hexmesh(r)
    assert hm.report.valid and hm.report.structure_exact, hm.report.summary()
    assert set(hm.report.irregular) == {3} and all(c.covered == 1.0 for c in hm.report.curves)


def test_box_and_L_part_need_no_singular_curve():
    """Every chart boundary of a box or an L-part lies on a sharp crease:
    they stay sharp edges and no curve is suggested."""
    occ = np.array([[[1], [0]], [[1], [1]]], bool)
    for V, F in (box(n=2), voxel_surface(occ, 0.5)):
        net, rep = suggest_network(V, F)
        assert net.curves == [] and net.sharp_angle == 30.0
        assert rep.sharp_boundaries == rep.chart_boundaries > 0
        check_input(V, F, net)


def test_a_bar_twisted_past_a_quarter_turn_needs_only_its_creases():
    """A box (0.8 x 0.8 x 3) twisted by 120 degrees: each side face's normal
    turns through a third of a turn, so no one polycube label fits a side
    and the padded polycube fails (four charts at a point).  Its creases
    alone bound six disks whose corners satisfy Poincare-Hopf: the network
    with no curve, which check_input accepts (bench/RESULTS.md: it hex
    meshes).  A smooth solid, or one whose creases leave a patch that is
    not a disk, keeps the polycube route or its refusal."""
    V, F = box((-0.4, -0.4, -1.5), (0.4, 0.4, 1.5), n=8)
    t = np.radians(120.0) * (V[:, 2] + 1.5) / 3.0
    V = np.c_[np.cos(t) * V[:, 0] - np.sin(t) * V[:, 1], np.sin(t) * V[:, 0] + np.cos(t) * V[:, 1], V[:, 2]]
    net, rep = suggest_network(V, F)
    assert net.curves == [] and net.sharp_angle == 30.0
    assert rep.charts == 6 and rep.chart_boundaries == rep.sharp_boundaries == 12 and rep.corners == 8
    assert any("padded polycube failed" in n and "needs no curve" in n for n in rep.notes), rep.notes
    check_input(V, F, net)
    # not taken where a patch is not a disk: the cylinder's wall (an annulus) needs its O-grid
    net, rep = suggest_network(*cylinder_surface(1.0, 2.0, n=32, rings=4))
    assert len(net.curves) == 4 and not any("needs no curve" in n for n in rep.notes)


@pytest.mark.slow
@pytest.mark.mesher
def test_a_crease_inside_a_chart_is_left_smooth():
    """The prism example's walls bend by 47 degrees at one wall top: at the
    default sharp angle that is a crease, but both walls take one label, and
    a field adapted to two normals 47 degrees apart does not exist (the
    solve did not converge with it sharp).  The suggestion leaves it smooth,
    says so, and keeps every other crease; the field converges."""
    V, F, _ = prism_example()
    net, rep = suggest_network(V, F)
    # the 47-degree edges are the bluntest creases: a sharp angle between them
    # and the next (52 degrees) keeps the other 56 edges past 30 degrees
    assert 47 < net.sharp_angle < 52 and net.sharp_edges is None
    assert any("4 crease edges inside one chart (47-47 degrees) left smooth" in n for n in rep.notes)
    r = solve(V, F, net)
    assert r.report.converged, r.report.status_reason


def test_cylinder_gets_the_o_grid():
    """Four +1/4 curves along the axis under the smooth side's chart
    boundaries, each running from cap to cap (the cylinder example's
    O-grid); the rims stay sharp."""
    V, F = cylinder_surface(1.0, 2.0)
    net, rep = suggest_network(V, F)
    assert len(net.curves) == 4 and rep.nodes == 0 and rep.sharp_boundaries == 8
    for c in net.curves:
        assert c.sigma == 0.25
        z = sorted([c.points[0, 2], c.points[-1, 2]])
        assert np.allclose(z, [-1.0, 1.0], atol=0.02)
        r = np.linalg.norm(c.points[:, :2], axis=1)
        assert np.all((r > 0.1) & (r < 0.9))
    check_input(V, F, net)


def _elliptic_torus():
    """A torus stretched 1.25 x along x: genus 1, not a solid of revolution
    (its normals leave the meridian planes by 0.11 RMS), so the padded
    polycube takes it."""
    V, F = torus_surface(1.0, 0.45, 40, 14)
    return V * [1.25, 1.0, 1.0], F


def test_a_ring_that_is_not_of_revolution_gets_a_square_ring():
    """A torus-like solid that is not of revolution is labelled as a square
    ring: 10 charts (the top and bottom ones annuli), 16 corners, each a
    node with a radial curve: +1/4 at the 8 outer corners, -1/4 at the 8
    inner ones (one chart turns by 270 degrees there), so that the ends add
    up to the torus' Euler characteristic 0; the hole's 4 vertical
    boundaries are concave."""
    V, F = _elliptic_torus()
    net, rep = suggest_network(V, F)
    assert rep.route == "padded polycube"
    assert rep.charts == 10 and rep.corners == 16 and rep.nodes == 16
    radial = [c for c in rep.curves if c.kind == "radial"]
    assert sorted(c.sigma for c in radial) == [-0.25] * 8 + [0.25] * 8
    assert sum(c.sigma for c in radial) == 0
    minus = [c for c in rep.curves if c.kind == "padding" and c.sigma < 0]
    assert len(minus) == 4
    for c in net.curves:
        if c.name in {m.name for m in minus}:
            # under the hole's wall, running up and down the axis
            assert np.ptp(c.points[:, 2]) > 3 * np.ptp(np.linalg.norm(c.points[:, :2], axis=1))


@pytest.mark.parametrize("seed", [1])
def test_a_torus_gets_four_loops_about_its_own_axis(seed):
    """A torus, turned and moved anywhere (ring.py): its axis is found from
    the normals, and its network is the swept O-grid: 4 closed loops of
    +1/4 about that axis, no node, at 0.45 of the tube's radius from the
    tube's centre along both diagonals (the O-grid's inner square), and
    check_input accepts it."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(seed)
    V, F = torus_surface(1.0, 0.4, 48, 16)
    Rm = Rotation.random(random_state=seed).as_matrix()
    shift = rng.uniform(-3, 3, 3)
    W = V @ Rm.T + shift
    net, rep = suggest_network(W, F)
    assert rep.route == "ring" and rep.nodes == 0 and rep.charts == 4
    assert len(net.curves) == 4 and all(c.closed and c.sigma == 0.25 for c in net.curves)
    for c in net.curves:
        P = (c.points - shift) @ Rm  # back in the torus's own frame
        r = np.linalg.norm(P[:, :2], axis=1)
        assert np.ptp(r) < 1e-2 and np.ptp(P[:, 2]) < 1e-2  # a circle about the axis
        off = np.array([r.mean() - 1.0, P[:, 2].mean()])
        assert np.allclose(np.abs(off), 0.45 * 0.4, rtol=0.25), off
    check_input(W, F, net)


@pytest.mark.slow
def test_a_ring_with_sharp_rims_needs_no_curve_and_a_rounded_one_gets_loops():
    """A washer (rectangular profile, sharp rims) is four bands between
    sharp creases: no curve at all, the hex mesh a sweep.  The same ring
    with rounded rims gets a +1/4 loop under each fillet.  A profile with a
    groove gets -1/4 loops under its concave turns."""
    from solver.suggest import sharp_creases
    from solver.suggest.ring import ring_network
    from solver.surface.validation import validate_surface
    from testkit.revolve import polyline, revolved_surface, rounded_ring, washer

    net, rep = suggest_network(*washer())
    assert rep.route == "ring" and net.curves == [] and rep.sharp_boundaries == 4
    S = validate_surface(*rounded_ring())
    curves = ring_network(S, sharp_creases(S, 30.0)[0])[0]  # (the route alone: the groove below is checked)
    assert sorted(c.sigma for c in curves) == [0.25] * 4 and all(c.closed for c in curves)
    r = [np.linalg.norm(c.points[:, :2], axis=1).mean() for c in curves]
    assert all(0.5 < x < 1.0 for x in r)
    # a groove round the outside: a U-shaped profile, its two concave corners -1/4 loops
    groove = [(0.5, -0.3), (1.0, -0.3), (1.0, -0.1), (0.8, -0.1), (0.8, 0.1), (1.0, 0.1), (1.0, 0.3), (0.5, 0.3)]
    V, F = revolved_surface(polyline(groove, 0.05), 72)
    net, rep = suggest_network(V, F, sharp_angle=100.0)  # no crease: every boundary smooth
    assert rep.route == "ring"
    assert sorted(c.sigma for c in net.curves) == [-0.25] * 2 + [0.25] * 6
    # chamfered outer rims: a 45-degree crease inside a band, which the ring
    # route leaves to the padded polycube (it knows such creases)
    chamfer = [(0.5, -0.25), (0.9, -0.25), (1.0, -0.15), (1.0, 0.15), (0.9, 0.25), (0.5, 0.25)]
    S = validate_surface(*revolved_surface(polyline(chamfer, 0.05), 72))
    assert ring_network(S, sharp_creases(S, 30.0)[0]) is None


@pytest.mark.slow
def test_a_shaft_with_a_boss_gets_the_o_grid_of_its_cross_sections():
    """A solid of revolution the axis passes through, where the padded
    polycube fails (a cylinder with a boss on its top face: the body's and
    the boss's O-grid curves would both end on the bottom disk,
    Poincare-Hopf 4 != 2), gets four +1/4 curves along the axis at 0.45 of
    the boss's radius, from cap to cap (ring.py's axial route); with the
    collar's outer rims rounded, a +1/4 loop under each fillet too."""
    from testkit.revolve import collared_shaft, stepped_shaft

    net, rep = suggest_network(*stepped_shaft())
    assert rep.route == "axial" and rep.nodes == 0 and "Poincare-Hopf" in rep.notes[0]
    assert len(net.curves) == 4 and all(c.sigma == 0.25 and not c.closed for c in net.curves)
    for c in net.curves:
        r = np.linalg.norm(c.points[:, :2], axis=1)
        assert np.allclose(r, 0.45 * 0.5, atol=2e-3)  # the cut crosses the 64-gon between its corners
        assert np.isclose(c.points[:, 2].min(), -0.5, atol=1e-6) and np.isclose(c.points[:, 2].max(), 1.1, atol=1e-6)
    # the collar (its padded polycube fails as the boss's does: bench/RESULTS.md)
    from solver.suggest import sharp_creases
    from solver.suggest.ring import axial_network
    from solver.surface.validation import validate_surface

    S = validate_surface(*collared_shaft())
    curves = axial_network(S, sharp_creases(S, 30.0)[0])[0]
    loops = [c for c in curves if c.closed]
    assert len(curves) == 6 and len(loops) == 2 and all(c.sigma == 0.25 for c in curves)
    z = sorted(float(np.mean(c.points[:, 2])) for c in loops)
    assert z[0] < 0 < z[1]  # under the lower and the upper fillet ...
    assert all(np.linalg.norm(c.points[:, :2], axis=1).min() > 0.7 for c in loops)  # ... near the collar's rim


def _nodes_and_depths(net, rep):
    """Each node's position, labels and depth per frame axis, from its
    radial curve (node to surface corner: the sum of its charts' depths
    along their labels), as suggested (before the intake)."""
    out = []
    for c, info in zip(net.curves, rep.curves):
        if info.kind == "radial":
            labs = info.charts.split("|")
            d = rep.frame @ (c.points[-1] - c.points[0])
            out.append((c.points[0], {lab[1]: lab for lab in labs}, np.abs(d)))
    return out


@pytest.mark.slow
def test_proportioned_keeps_a_core_as_thick_as_the_padding():
    """The experimental ``proportioned`` suggestion (docs/suggest.md,
    *Proportions*): on a flat ellipsoid (1.5 x 1.5 x 0.5) the corners sit
    where a box projection puts them (|z| about 0.27, not at 0.15 where the
    normals turn), and on a torus the inner and outer nodes at one azimuth,
    which share no chain, stay at least as far apart as the padding that
    parts them (0.107 apart under 0.2 of padding by default)."""
    V0, F0 = icosphere(3)
    V0 = V0 * [1.5, 1.5, 0.5]
    net, rep = suggest_network(V0, F0, proportioned=True)
    corners = np.array([c.points[-1] for c, i in zip(net.curves, rep.curves) if i.kind == "radial"])
    assert len(corners) == 8 and np.all(np.abs(corners[:, 2]) > 0.22)
    assert rep.feature_size > 0.2  # 0.10 with the normals' corners
    for V, F in ((V0, F0), _elliptic_torus()):
        net, rep = suggest_network(V, F, proportioned=True)
        nodes = _nodes_and_depths(net, rep)
        assert len(nodes) in (8, 16)
        for i, (p, li, di) in enumerate(nodes):
            for q, lj, dj in nodes[i + 1:]:
                apart = [a for a, axis in enumerate("XYZ") if li[axis] != lj[axis]]
                pad = max([di[a] for a in apart] + [dj[a] for a in apart] + [0.0])
                assert np.linalg.norm(p - q) >= 0.99 * pad


def _top_fillets(r=0.4):
    V, F = box(n=20)
    c = 1.0 - r
    q = np.c_[np.clip(V[:, 0], -c, c), np.clip(V[:, 1], -c, c), np.full(len(V), c)]
    d = V - q
    n = np.linalg.norm(d, axis=1)
    m = (V[:, 2] > c) & (n > 1e-12)
    V[m] = q[m] + r * d[m] / n[m, None]
    return V, F


def test_refusals_name_the_reason_and_the_place():
    V, F = _top_fillets()  # the vertical creases run out into the top fillets
    with pytest.raises(NetworkError, match=r"at the surface point \(.*\) two smooth chart boundaries meet a sharp"):
        suggest_network(V, F)
    V1, F1 = icosphere(1)
    V2 = np.vstack([V1, 0.3 * V1])  # a ball with a cavity inside
    F2 = np.vstack([F1, F1[:, ::-1] + len(V1)])
    with pytest.raises(NetworkError, match="2 connected components"):
        suggest_network(V2, F2)


def test_cli_writes_the_suggestion_and_refuses_it_with_a_network(tmp_path, capsys):
    V, F = icosphere(2)
    obj = os.path.join(tmp_path, "s.obj")
    out = os.path.join(tmp_path, "net", "s.json")
    os.makedirs(os.path.dirname(out))
    write_obj(obj, V, F)
    assert main([obj, "--suggest-network", out, "-q"]) == 0
    net, _, surface = read_network(out)
    assert isinstance(net, Network) and len(net.curves) == 20
    assert os.path.samefile(surface, obj)
    assert "suggested network" in capsys.readouterr().out
    assert main([out, "--suggest-network", os.path.join(tmp_path, "x.json")]) == 1
    assert "bare SURFACE.obj" in capsys.readouterr().err
    with open(out) as fh:
        assert json.load(fh)["surface"] == os.path.join("..", "s.obj")


@pytest.mark.slow
@pytest.mark.mesher
def test_cli_meshes_a_bare_surface(tmp_path, capsys):
    """`python -m solver SURFACE.obj --hex out.vtu` with no network: the
    suggestion (the cylinder's O-grid) is solved and meshed.  (The 32-gon of
    the example's solid: fTetWild meshes it in a third of the 64-gon's time.)"""
    V, F = cylinder_surface(1.0, 2.0, n=32, rings=4)
    obj = os.path.join(tmp_path, "c.obj")
    write_obj(obj, V, F)
    vtu = os.path.join(tmp_path, "c.vtu")
    assert main([obj, "--hex", vtu, "-q"]) == 0
    out = capsys.readouterr().out
    assert "suggested network (padded polycube): 4 curves" in out and "hex mesh: valid" in out
    assert os.path.getsize(vtu) > 0 and os.path.exists(os.path.join(tmp_path, "c.npz"))
