"""Curve ends off the mesher's vertices and edges (solver/mesh/clearance.py,
issue 48): networks exported by other tools end exactly at vertices of the
surface that comes with them."""

import numpy as np

from solver.examples import icosphere
from solver.mesh.clearance import CLEAR, EDGE_CLEAR, MAX_MOVE, clear_curve_ends
from solver.surface.trisurface import TriSurface


def _edges_distance(S: TriSurface, x: np.ndarray) -> float:
    A, B = S.V[S.edges[:, 0]], S.V[S.edges[:, 1]]
    ab = B - A
    t = np.clip(np.einsum("ij,ij->i", x - A, ab) / np.einsum("ij,ij->i", ab, ab), 0, 1)
    return float(np.linalg.norm(A + t[:, None] * ab - x, axis=1).min())


def test_ends_on_vertices_and_edges_come_to_lie_inside_triangles():
    V, F = icosphere(2)
    S = TriSurface(V, F)
    h = 0.3
    on_vertex = V[5]
    on_edge = 0.5 * (V[S.edges[40, 0]] + V[S.edges[40, 1]])
    on_edge /= np.linalg.norm(on_edge)  # (on the sphere: a hair outside the edge's chord)
    ends = np.array([on_vertex, on_edge])
    out, moved = clear_curve_ends(S, ends, h)
    assert moved >= 3 and out is not S
    assert np.array_equal(S.V, V)  # the input is not touched
    shortest = float(np.linalg.norm(V[S.edges[:, 0]] - V[S.edges[:, 1]], axis=1).min())
    for x in ends:
        d = np.linalg.norm(out.V - x, axis=1).min()
        assert d >= 0.9 * min(CLEAR * h, MAX_MOVE * shortest), d  # (back on the sphere: a little shorter)
        assert _edges_distance(out, x) > 0.1 * EDGE_CLEAR * CLEAR * h
    # still a sphere: every vertex on the input surface, triangles hardly turned
    dist, _, _ = S.closest_points(out.V)
    assert dist.max() < 1e-9
    cos = np.einsum("ij,ij->i", out.face_normals, S.face_normals)
    assert cos.min() > np.cos(np.radians(10))


def test_ends_inside_triangles_leave_the_surface_as_it_is():
    V, F = icosphere(2)
    S = TriSurface(V, F)
    x = V[F[7]].mean(axis=0)
    out, moved = clear_curve_ends(S, x[None], 0.05)
    assert moved == 0 and out is S


def test_sharp_vertices_never_move():
    from solver.examples import box

    V, F = box(n=2)
    S = TriSurface(V, F)
    corner = np.array([1.0, 1.0, 1.0])
    mid_face = np.array([0.0, 0.0, 1.0])  # a vertex of box(n=2), on a flat face
    out, moved = clear_curve_ends(S, np.array([corner, mid_face]), 0.5)
    k = np.argmin(np.linalg.norm(V - corner, axis=1))
    assert np.allclose(out.V[k], corner)
    assert np.linalg.norm(out.V - mid_face, axis=1).min() > 0.05 and moved >= 1
