"""Tracing curves through the tet mesh (embed.py) where they meet mesh edges."""

from __future__ import annotations

import numpy as np
import pytest

from solver.mesh.embed import TetLocator, _Degenerate, trace_curve
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


def test_a_loop_starting_on_a_face_returns_to_its_start_tet():
    """A closed curve whose start lies on a face between two tets: the walk
    round it comes back to that point from the other tet, which the start
    was not located in.  The embedding jitters it and retries (as for a
    curve through an edge), where it used to stop with 'did not return to
    its start tet' (a suggested loop on a turned shaft, 1 fTetWild mesh in
    2)."""
    from solver.mesh.embed import embed_network
    from solver.network.network import Curve, PreparedNetwork

    mesh = box_mesh(4)
    phi = np.linspace(0.0, 2 * np.pi, 41)
    # from (0.5, 0.4375, 0.3125) (exact in binary), on the grid plane x = 0.5
    # between two cubes' tets, round a circle in the plane z = 0.3125
    P0 = np.array([0.5, 0.4375, 0.3125])
    P = P0 + 0.125 * np.c_[np.cos(phi) - 1.0, np.sin(phi), np.zeros_like(phi)]
    P[0] = P[-1] = P0
    loc = TetLocator(mesh)
    t0 = int(loc.locate(P[:1])[0])
    tr = trace_curve(mesh, loc, P, t0, -1, False, "loop", 1e-9 * mesh.mean_edge_length, closed=True)
    assert tr.tets[-1] != tr.tets[0]  # the case: back on the face, in the neighbour
    net = PreparedNetwork(curves=[Curve(P, sigma=0.25, closed=True)], source=[0], start_kind=["loop"],
                          end_kind=["loop"], nodes=[])
    emb = embed_network(mesh, net, node_radius=0.1)
    assert len(emb.network_faces(mesh)) >= 4


def _tubes(name, h):
    from solver.examples import load_example
    from solver.mesh.tubes import build_tubes
    from solver.network.validation import check_input

    V, F, net = load_example(name)
    ch = check_input(V, F, net, False)
    r = 0.35 * h
    tubes = build_tubes(ch.network, ch.surface, r, r * np.sqrt(3.0), 0.4 * ch.feature_size,
                        1e-5 * ch.surface.bbox_diagonal)
    assert len(tubes.F) and tubes.F.max() < len(tubes.V)
    d = ch.surface.closest_points(tubes.V)[0]
    on = d < 1e-9
    caps = tubes.F[on[tubes.F].all(axis=1)]
    # a cap lies on the surface: its centroid and edge midpoints too
    Q = tubes.V[caps]
    probe = np.concatenate([Q.mean(axis=1), 0.5 * (Q + np.roll(Q, 1, axis=1)).reshape(-1, 3)])
    cap_off = ch.surface.closest_points(probe)[0].max() if len(caps) else 0.0
    return d, on, len(caps), cap_off, r * np.sqrt(3.0)


@pytest.mark.parametrize("h, caps", [(0.22, 4), (0.1, 8)])
def test_tube_caps_lie_flat_on_the_surface_or_tubes_keep_off_it(h, caps):
    """A cap triangle on a curved surface lies inside fTetWild's envelope
    without lying on it: the boundary came out folded there and the ball
    failed at h = 0.21-0.25.  A cap is kept only where it lies on the
    surface (here: within one facet of the icosphere); otherwise the tube
    stops a spacing short of the surface."""
    d, on, n_caps, cap_off, spacing = _tubes("ball", h)
    assert cap_off < 1e-12
    assert on.sum() == 3 * n_caps  # every vertex on the surface is a cap's
    assert d[~on].min() > 0.5 * spacing
    # of the 8 radial curves' caps, 4 straddle facets at h = 0.22 and are left out
    assert n_caps == caps


def test_tubes_on_a_flat_surface_end_in_caps():
    # plate: 4 curves through the thickness, a cap on both faces
    d, on, n_caps, cap_off, spacing = _tubes("plate", 0.1)
    assert n_caps == 8 and cap_off < 1e-12


def test_point_location_survives_a_tet_flat_to_round_off():
    """fTetWild once returned a tet of volume 2.5e-34; its barycentric map
    has no inverse, and locating points must not fail on it."""
    from solver.mesh.embed import TetLocator
    from tests.meshes import box_mesh

    mesh = box_mesh(2)
    X = mesh.vertices.copy()
    t = mesh.tets[0]
    # the fourth corner on the first edge's midpoint: the tet is flat
    # (numpy's inverse raises on it)
    X[t[3]] = 0.5 * (X[t[0]] + X[t[1]])
    flat = type(mesh)(X, mesh.tets)
    loc = TetLocator(flat)
    P = flat.vertices[flat.tets].mean(axis=1)
    found = loc.locate(P)
    assert (found[1:] >= 0).all()
    # a point of the flat tet is given to a neighbour that holds it
    assert found[0] not in (-1, 0)
    assert loc.barycentric(found[0], P[0]).min() > -1e-9


def test_the_pierce_tangent_is_the_smooth_tangent_of_a_sampled_arc():
    """Omega_f's axis (Eq. 19, §4.2.2) is the curve's smooth tangent at the
    pierce point, not its segment's direction: on an arc of radius 1
    sampled every 0.1 (5.7 degrees per segment) the segment directions are
    up to 2.9 degrees off the arc's tangent, which costs 4.5 degrees of
    residual on a quarter-turn face; interpolated vertex tangents are off
    by less than 0.3 degrees."""
    mesh = box_mesh(5)
    loc = TetLocator(mesh)
    a = np.linspace(-0.45, 0.45, 10)  # radius 1 about (0.5, 0.5, -0.6): 5.7 degrees per segment
    P = np.c_[0.5 + np.sin(a), np.full_like(a, 0.47), -0.6 + np.cos(a)]
    t0 = int(loc.locate(P[:1])[0])
    tr = trace_curve(mesh, loc, P, t0, -1, False, "arc", 1e-9 * mesh.mean_edge_length, strict=False)
    assert len(tr.faces) >= 5
    x = tr.points
    ang = np.arctan2(x[:, 0] - 0.5, x[:, 2] + 0.6)
    exact = np.c_[np.cos(ang), np.zeros_like(ang), -np.sin(ang)]
    err = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", tr.tangents, exact), -1, 1)))
    seg = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", _segment_directions(P, ang, a), exact), -1, 1)))
    # the end segments have one-sided vertex tangents (the segment's own)
    inner = (ang > a[1]) & (ang < a[-2])
    assert inner.sum() >= 3 and err[inner].max() < 0.3 and seg[inner].max() > 1.0, (err, seg)


def _segment_directions(P, ang, a):
    k = np.clip(np.searchsorted(a, ang) - 1, 0, len(P) - 2)
    d = P[k + 1] - P[k]
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_a_curve_grazing_a_face_turns_the_way_it_crosses():
    """Omega_f's orientation is the walk's: from the tet the curve leaves
    into the one it enters.  Here a curve crosses the mesh plane x = y at
    a grazing angle (segment 0.8 degrees off the plane) and then bends
    back, so its smooth tangent at the crossing (interpolated between
    vertex tangents) lies on the far side of the plane: signing Omega_f
    by n . T reversed that face's quarter turn (penalty 4.5e3 on a ball
    mesh whose face a radial curve grazed)."""
    from solver import Curve
    from solver.mesh.embed import embed_network
    from solver.network.network import PreparedNetwork

    mesh = box_mesh(4, lo=(-1, -1, -1), hi=(1, 1, 1))
    d = 0.01  # x = 0.1: the cell [0, 0.5]'s diagonal plane x = y is crossed at z = -0.5
    P = np.array([[0.1, 0.1 - d, -1.0], [0.1, 0.1 + d, 0.0], [0.1, 0.1 - 9 * d, 1.0]])
    pn = PreparedNetwork(curves=[Curve(P, sigma=0.25, name="grazing")], source=[0], start_kind=["boundary"],
                         end_kind=["boundary"], nodes=[])
    emb = embed_network(mesh, pn, node_radius=0.1)
    tr = emb.traces[0]
    n = mesh.face_normals[tr.faces]
    grazing = np.abs(np.einsum("ij,ij->i", n, tr.tangents)) < 0.02
    assert grazing.any()  # the case this test is about
    cen = mesh.vertices[mesh.tets].mean(axis=1)
    way = np.sign(np.einsum("ij,ij->i", n, cen[tr.tets[1:]] - cen[tr.tets[:-1]]))
    want = 2 * np.pi * 0.25 * way[:, None] * tr.tangents
    assert np.allclose(emb.face_omega[tr.faces], want, atol=1e-12)
    # every face a quarter-turn curve pierces is one where the field must be singular
    assert emb.prescribed_singular()[tr.faces].all()
    assert emb.prescribed_singular().sum() == len(np.unique(tr.faces))


def _all_tube_faces(problem):
    from solver.field.constraints import TUBE

    emb, mesh = problem.embedding, problem.mesh
    return np.nonzero((problem.constraints.kind == TUBE)[mesh.face_edges].all(axis=1) & ~emb.face_excluded)[0]


@pytest.mark.slow
@pytest.mark.mesher
def test_straight_tubes_keep_the_prescribed_curvature(solved):
    """On straight curves the tube's reference field is a rotation about one
    axis, so tube_curvature leaves Omega_f = 2 pi sigma T (or 0) as the
    embedding prescribed it: the walk's orientation and the polar angle's
    winding agree on every pierced face.  (The session's default solve of
    the cylinder; any resolution will do.)"""
    p = solved("cylinder").problem
    faces = _all_tube_faces(p)
    pierced = faces[p.embedding.pierce_count[faces] > 0]
    assert len(faces) > 50 and len(pierced) > 10
    assert np.abs(p.structure_omega - p.embedding.face_omega).max() < 1e-9


@pytest.mark.slow
@pytest.mark.mesher
def test_bent_tubes_carry_no_structure_error():
    """Around a bent singular curve the adapted rotations omega0 + beta T_e
    do not commute, and with Omega_f = 2 pi sigma T (or 0) the second-order
    equation missed on every tube face and the faces around: the
    cube-sphere ball with its radial curves bowed by 0.45 had a penalty of
    9.9 on its all-tube faces (13.4 in all, not converged).  With the
    reference field's curvature they carry almost none (0.03; 1.6 in all,
    converged)."""
    from solver import Curve, Network, solve
    from solver.examples import ball_example

    V, F, net = ball_example()
    curves = []
    for c in net.curves:
        P = c.points
        if c.name.startswith("radial"):
            p0, q = P[0], P[-1]
            u = np.cross(q - p0, [0.3, 0.5, 0.8])
            t = np.linspace(0.0, 1.0, 33)[:, None]
            P = p0 + t * (q - p0) + 0.45 * np.sin(np.pi * t) * u / np.linalg.norm(u)
        curves.append(Curve(P, sigma=c.sigma, name=c.name))
    r = solve(V, F, Network(curves=curves))
    assert max(rp.turn_out_deg for rp in r.report.repairs) > 5.0  # the curves stay bent
    vp = r.problem.volume
    res = np.zeros((r.mesh.n_faces, 3))
    res[vp.faces] = vp.se.residual(r.omega)
    faces = _all_tube_faces(r.problem)
    changed = np.linalg.norm(r.structure_omega - r.embedding.face_omega, axis=1)[faces]
    assert len(faces) > 30 and changed.max() > 1e-3  # (the tubes' ends on the sphere are free: END_FREE)
    assert vp.a * np.sum(res[faces] ** 2) < 1.0
    assert r.report.converged, r.report.status_reason


@pytest.mark.slow
@pytest.mark.mesher
def test_tube_reference_winds_as_the_curve_pierces(monkeypatch):
    """The tube edges' reference winding theta is measured per vertex, in
    the frame of each vertex's nearest curve point; where a bent curve
    crosses an oblique face close to an edge, those points lie apart and
    the face wound 0 times where the curve pierces it -- rare on default
    meshes, common on meshes graded towards bends (the cube-sphere network
    stretched into a 2 x 1 x 0.6 ellipsoid, its ends bent onto the normal:
    50 of 851 tube faces, penalty 275).  Settled against the winding seen
    from the curve (constraints._settle_windings): 6."""
    import solver.field.constraints as constraints
    import solver.mesh.meshing as meshing
    import solver.mesh.resolution as resolution
    from solver import Options

    needs = resolution.network_needs

    def needs_and_bends(S, pn):  # a sizing field also a third of the radius of curvature
        P, need = needs(S, pn)
        for c in pn.curves:
            d = np.diff(c.points, axis=0)
            ln = np.linalg.norm(d, axis=1)
            u = d / ln[:, None]
            turn = np.arccos(np.clip(np.einsum("ij,ij->i", u[:-1], u[1:]), -1.0, 1.0)) + 1e-12
            P, need = np.vstack([P, c.points[1:-1]]), np.concatenate([need, 0.5 * (ln[:-1] + ln[1:]) / turn])
        return P, need

    monkeypatch.setattr(resolution, "network_needs", needs_and_bends)
    # as the meshes this was seen on: the tube edges at the curves' ends
    # constrained (now left free: constraints.END_FREE) and the vertices near
    # the curves where the mesher put them (now moved off: clearance.py, which
    # leaves the per-vertex measure nothing to get wrong here)
    monkeypatch.setattr(constraints, "END_FREE", 0.0)
    monkeypatch.setattr(meshing, "clear_curves", lambda mesh, curves, skip=None: (mesh, 0))
    # the budget held and graded at 0.5, as the meshes this was seen on (the
    # default now spends more tets on this network and grades more gently,
    # which leaves only a few faces for the per-vertex measure to get wrong).
    # TetGen's graded meshes: the same every run on one machine, but which
    # faces the per-vertex measure gets wrong turns on the last bits of the
    # input (x86_64 machines of two makes: 8 and 0 on the first mesh here,
    # 0-17 over these).  So meshes are made until 6 faces have been wrong.
    # On fTetWild's meshes the per-vertex measure gets 4-16 faces wrong and
    # the settling leaves 0-4 (13 runs), but on one mesh of a CI run it left
    # all 12 of 12: TetGen's meshes are the ones this measures
    variants = (((2.0, 1.0, 0.6), 15000, 0.5), ((2.0, 1.0, 0.6), 20000, 0.5), ((2.0, 1.1, 0.6), 15000, 0.5),
                ((2.0, 1.0, 0.6), 15000, 0.4), ((2.2, 1.0, 0.5), 15000, 0.5))
    before = after = 0
    for scale, target, grading in variants:
        b, a = _tube_windings_per_vertex_and_settled(np.array(scale), Options(target_tets=target, grading=grading,
                                                                               mesher="TetGen"))
        print(f"{scale} {target} tets graded {grading}: wrong per vertex {b}, settled {a}")
        assert a <= b, (scale, b, a)
        before, after = before + b, after + a
        if before >= 6:
            break
    # the settling must cut the faces the per-vertex measure gets wrong (8 -> 3, 17 -> 6, 14 -> 0 here)
    assert before >= 6 and after <= 0.5 * before, (before, after)


def _tube_windings_per_vertex_and_settled(S, options) -> tuple[int, int]:
    """The tube faces the per-vertex winding gets wrong, and the settled one,
    on the cube-sphere network stretched by S (test above)."""
    from solver import Curve, FieldProblem, Network
    from solver.examples import ball_example
    from solver.field.constraints import FREE, TUBE, _tube_edges
    from solver.field.structure import StructureEquation

    V, F, net = ball_example()
    net = Network(curves=[Curve(c.points * S, sigma=c.sigma, name=c.name) for c in net.curves])
    p = FieldProblem(V * S, F, net, options)
    assert p.report.sizes.get("graded_tets", 0) > 0
    mesh, emb, cons = p.mesh, p.embedding, p.constraints
    faces = _all_tube_faces(p)
    assert len(faces) > 300
    se = StructureEquation(mesh.face_edges[faces], mesh.corner_weights[faces], emb.face_omega[faces], mesh.n_edges)

    def wrong(ref):
        return int(np.sum(np.linalg.norm(se.residual(ref), axis=1) > np.pi / 4))

    kind = np.where(cons.kind == TUBE, FREE, cons.kind)  # the edges' kinds before the tubes
    curve, T, omega0, theta, _ = _tube_edges(mesh, p.network, emb, kind, p.boundary.normals)
    assert np.array_equal(curve >= 0, cons.kind == TUBE)
    tube = curve >= 0
    sigma = np.array([c.sigma for c in p.network.curves])[curve[tube]]
    per_vertex = np.zeros((mesh.n_edges, 3))
    per_vertex[tube] = omega0[tube] + (sigma * theta[tube])[:, None] * T[tube]
    return wrong(per_vertex), wrong(cons.tube_reference)


@pytest.mark.slow
@pytest.mark.mesher
def test_node_regions_of_a_graded_mesh_reach_where_the_tubes_start():
    """The curves' tubes stop node_radius(bulk edge length) from a node,
    and the node regions must reach as far: sized by the graded mesh's
    finer edge length at the nodes, they left a stretch of each curve
    constrained to turn about itself alone next to the node, where the
    node's other curves still turn the field (a generated cube with a
    cavity: penalty 46.7 against 10.8, the frames 17-35 degrees off the
    curves; 1.5 with the regions this large).  A budget of 6,000 tets
    grades this input: bulk edge length 0.34, 0.17 at the nodes."""
    from solver import FieldProblem, Options
    from solver.mesh.meshing import node_radius
    from testkit.hexnet import hexnet_input

    d = hexnet_input("hollow", 17)  # meshed here: its own input, the only graded one with nodes
    p = FieldProblem(d["V"], d["F"], d["network"], Options(target_tets=6000))
    assert p.plan.graded and p.plan.finest < 0.75 * p.edge_length
    r = node_radius(p.network, p.edge_length, p.options.node_radius)
    m = p.mesh
    for region, node in zip(p.embedding.node_region, p.network.nodes):
        reach = np.linalg.norm(m.vertices[m.tets[region]].mean(axis=1) - np.asarray(node.position), axis=1).max()
        assert reach >= 0.8 * r > 1.5 * p.plan.finest, (reach, r, p.plan.finest)
