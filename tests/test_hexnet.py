"""testkit/hexnet.py: networks read off block-structured hex meshes (the
singular graph of a hex mesh, hex-meshable by construction).  Fast: no
solve and no tet meshing; ``check`` runs the solver's input validation on
each kind."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from solver import check
from solver.hexmesh.quality import scaled_jacobian
from testkit.hexnet import (
    KINDS,
    cube_sphere,
    hexnet_family,
    hexnet_input,
    irregular_edges,
    network_from_hexmesh,
    o_grid_cylinder,
    o_grid_torus,
    plate_with_holes,
    smooth_deformation,
)


def _sigmas(net) -> list[float]:
    return sorted(c.sigma for c in net.curves)


def _closed_outward(V, F) -> float:
    """Asserts (V, F) is a closed, consistently oriented manifold; returns its signed volume."""
    D = np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    keys, cnt = np.unique(D, axis=0, return_counts=True)
    assert cnt.max() == 1, "a directed edge appears twice: not consistently oriented or not manifold"
    rev = {tuple(e) for e in keys}
    assert all((b, a) in rev for a, b in keys), "an edge has one triangle: the surface is open"
    assert len(np.unique(F)) == len(V), "surface vertices not compacted"
    P = V[F]
    return float(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6)


def _euler(V, F) -> int:
    E = np.unique(np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    return len(V) - len(E) + len(F)


def _assert_chains(V, H, net):
    """Every curve is a chain of irregular interior edges of the hex mesh, of
    one valence 4 - 4 sigma, and the curves hold each irregular edge once."""
    E, val, _ = irregular_edges(H)
    n = len(V)
    valence = dict(zip((E[:, 0] * n + E[:, 1]).tolist(), val.tolist()))
    tree = cKDTree(V)
    used = []
    for c in net.curves:
        d, ids = tree.query(c.points)
        assert d.max() == 0.0, f"{c.name}: a point is not a hex vertex"
        a, b = np.minimum(ids[:-1], ids[1:]), np.maximum(ids[:-1], ids[1:])
        keys = (a * n + b).tolist()
        assert all(k in valence for k in keys), f"{c.name}: a segment is not an irregular interior edge"
        assert {valence[k] for k in keys} == {round(4 - 4 * c.sigma)}, c.name
        used += keys
    assert sorted(used) == sorted(valence), "irregular edges missed or held twice"


def test_cube_sphere_is_the_cube_sphere_network():
    n, m = 4, 3
    V, H = cube_sphere(n, m)
    assert len(H) == n**3 + 6 * n * n * m and scaled_jacobian(V, H).min() > 0
    E, val, _ = irregular_edges(H)
    assert val.tolist() == [3] * (12 * n + 8 * m)
    Vs, Fs, net = network_from_hexmesh(V, H)
    assert len(net.curves) == 20 and _sigmas(net) == [0.25] * 20 and net.sharp_angle == 30.0
    assert sorted(len(c.points) for c in net.curves) == [m + 1] * 8 + [n + 1] * 12
    assert not any(c.closed for c in net.curves)
    # the 8 radial curves end on the unit sphere; every other end is an inner corner
    ends = np.array([c.points[k] for c in net.curves for k in (0, -1)])
    r = np.linalg.norm(ends, axis=1)
    assert np.sum(np.isclose(r, 1.0)) == 8 and np.allclose(r[~np.isclose(r, 1.0)], 0.45 * np.sqrt(3))
    _assert_chains(V, H, net)
    vol = _closed_outward(Vs, Fs)
    assert 0.9 * 4 / 3 * np.pi < vol < 4 / 3 * np.pi and _euler(Vs, Fs) == 2
    # an ellipsoid's shell turns onto the normal: the last of 6 layers ends
    # 10.5 degrees off it, straight lines 31 degrees off
    axes = np.array([1.5, 1.0, 0.75])
    for orthogonal, lo, hi in ((True, 10.0, 11.0), (False, 30.0, 32.0)):
        V, H = cube_sphere(n, 6, axes=axes, orthogonal=orthogonal)
        assert scaled_jacobian(V, H).min() > 0.2
        _, _, net = network_from_hexmesh(V, H)
        radial = [c for c in net.curves if len(c.points) == 7]
        assert len(radial) == 8
        for c in radial:
            P = c.points if np.sum((c.points[-1] / axes) ** 2) > 0.99 else c.points[::-1]
            normal, t = P[-1] / axes**2, P[-1] - P[-2]
            angle = np.degrees(np.arccos(t @ normal / np.linalg.norm(t) / np.linalg.norm(normal)))
            assert lo < angle < hi


def test_o_grid_cylinder_has_four_axial_curves():
    V, H = o_grid_cylinder(4, layers=6)
    assert scaled_jacobian(V, H).min() > 0
    Vs, Fs, net = network_from_hexmesh(V, H)
    assert _sigmas(net) == [0.25] * 4
    for c in net.curves:
        assert len(c.points) == 7 and np.allclose(c.points[:, :2], c.points[0, :2])
        assert sorted([c.points[0, 2], c.points[-1, 2]]) == [-1.0, 1.0]  # from cap to cap
    _assert_chains(V, H, net)
    assert _closed_outward(Vs, Fs) > 0 and _euler(Vs, Fs) == 2


def test_o_grid_torus_has_four_closed_curves():
    V, H = o_grid_torus(3, segments=16)
    assert scaled_jacobian(V, H).min() > 0
    Vs, Fs, net = network_from_hexmesh(V, H)
    assert _sigmas(net) == [0.25] * 4 and all(c.closed for c in net.curves)
    assert all(np.array_equal(c.points[0], c.points[-1]) and len(c.points) == 17 for c in net.curves)
    _assert_chains(V, H, net)
    assert _closed_outward(Vs, Fs) > 0 and _euler(Vs, Fs) == 0


def test_plate_with_one_hole_is_the_plate_network():
    V, H = plate_with_holes(3, 3, ((1, 1),), n=4, thickness=0.5, layers=2)
    assert scaled_jacobian(V, H).min() > 0
    Vs, Fs, net = network_from_hexmesh(V, H)
    assert _sigmas(net) == [-0.25] * 4
    corners = np.array([[1, 1], [2, 1], [1, 2], [2, 2]], float)
    for c in net.curves:
        assert len(c.points) == 3 and np.allclose(c.points[:, :2], c.points[0, :2])
        assert np.min(np.linalg.norm(corners - c.points[0, :2], axis=1)) < 1e-12  # at a corner of the hole's cell
    _assert_chains(V, H, net)
    vol = _closed_outward(Vs, Fs)
    assert abs(vol - 0.5 * (9 - np.pi * 0.3**2)) < 0.01 and _euler(Vs, Fs) == 0


def test_plate_with_two_holes_is_genus_2_and_adjacent_holes_make_valence_6():
    V, H = plate_with_holes(5, 3, ((1, 1), (3, 1)), n=4)
    Vs, Fs, net = network_from_hexmesh(V, H)
    assert scaled_jacobian(V, H).min() > 0 and _sigmas(net) == [-0.25] * 8
    assert _euler(Vs, Fs) == -2
    _assert_chains(V, H, net)
    V, H = plate_with_holes(4, 3, ((1, 1), (2, 1)), n=4)
    _, _, net = network_from_hexmesh(V, H)
    assert _sigmas(net) == [-0.5] * 2 + [-0.25] * 4
    _assert_chains(V, H, net)


def test_smooth_deformation_keeps_the_hexes_positive():
    V, H = o_grid_cylinder(4, layers=12, radius=0.5, height=4.0)
    W = smooth_deformation(V, np.random.default_rng(1), 0.1, bend=np.pi / 2, twist=np.pi / 2, H=H)
    assert scaled_jacobian(W, H).min() > 0 and np.abs(W - V).max() > 0.3
    assert np.array_equal(W, smooth_deformation(V, np.random.default_rng(1), 0.1, np.pi / 2, np.pi / 2, H=H))
    # far too large: halved until no hex is inverted
    W = smooth_deformation(V, np.random.default_rng(2), 3.0, H=H, cycles=3.0)
    assert scaled_jacobian(W, H).min() > 0


# per kind at seed 0: curves, their sigma, and the sharp edges check finds
# by angle (n: the seed's resolution, layers: its layers)
def _expected(kind, p):
    """({sigma: curves}, sharp edges) of a kind's seed-0 input."""
    n = p["n"]
    if kind in ("ball", "ellipsoid", "blob"):
        return {0.25: 20}, 0
    if kind in ("cylinder", "bent bar"):
        return {0.25: 4}, 2 * 4 * n
    if kind == "torus":
        return {0.25: 4}, 0
    if kind == "hollow":  # the middle cube's edges and its radial edges; the outer cube's 12 edges are sharp
        return {-0.25: 12, 0.25: 8}, 12 * (n + 2 * p["frame"])
    if kind == "prism":  # the triangle's outline on both faces (two half sides of n each), its 3 corners
        return {0.25: 1}, 2 * 6 * n + 3 * p["layers"]
    if kind == "hex prism":  # the hexagon's outline on both faces, 3 of its 6 corners: the creases of the 3
        return {0.25: 1}, 2 * 6 * n + 3 * p["layers"]  # corners chosen flat are smooth (corners.py)
    if kind == "polygon cylinder":  # the axis of valence k in a ring of k +1/4 curves; the two rims (2 n k each)
        return {(4 - p["k"]) / 4: 1, 0.25: p["k"]}, 2 * 2 * n * p["k"]
    # the outline on both faces, each hole's ring on both, the vertical corners (5 convex and
    # 1 concave for the L)
    nx, ny, holes, corners = {"plate": (3, 3, 1, 4), "genus2": (5, 3, 2, 4), "L-part": (5, 5, 2, 6)}[kind]
    return {-0.25: 4 * holes}, 2 * (2 * (nx + ny) * n + holes * 4 * n) + corners * p["layers"]


@pytest.mark.parametrize("kind", KINDS)
def test_each_kind_passes_check(kind):
    e = hexnet_input(kind, 0)
    m = e["meta"]
    assert e["name"] == f"{kind} seed 0" and m["kind"] == kind and m["seed"] == 0
    assert scaled_jacobian(m["V"], m["H"]).min() > 0 and m["min_jacobian"] > 0
    assert 1000 <= len(m["H"]) <= 5000 and len(e["F"]) <= 4000
    by_sigma, sharp = _expected(kind, m["params"])
    curves = sum(by_sigma.values())
    net = e["network"]
    assert {s: sum(c.sigma == s for c in net.curves) for s in by_sigma} == by_sigma and len(net.curves) == curves
    assert m["curves"] == {round(4 - 4 * s): k for s, k in by_sigma.items()}
    _assert_chains(m["V"], m["H"], net)
    assert _closed_outward(e["V"], e["F"]) > 0
    found = check(e["V"], e["F"], net)
    assert found.interior_curves == curves and found.nodes == (8 if curves == 20 else 0)
    assert found.sharp_edges == sharp
    # deterministic for a seed; another seed another input
    again = hexnet_input(kind, 0)
    assert np.array_equal(again["V"], e["V"]) and np.array_equal(again["F"], e["F"])
    assert not np.array_equal(hexnet_input(kind, 1)["meta"]["V"][:10], m["V"][:10])


def test_family_and_unknown_kind():
    assert [e["meta"]["kind"] for e in hexnet_family(0, kinds=("plate", "torus"))] == ["plate", "torus"]
    with pytest.raises(ValueError, match="unknown kind"):
        hexnet_input("sphere", 0)
