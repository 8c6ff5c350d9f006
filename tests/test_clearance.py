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


# ---------------------------------------------------------------------------
# inside the solid: the tet mesh's vertices and edges off the curves


def _box_mesh(n: int = 6):
    """A structured tet mesh of the unit cube (6 tets per cell), deterministic."""
    from solver.mesh.tetmesh import TetMesh

    g = np.linspace(0.0, 1.0, n + 1)
    X = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange((n + 1) ** 3).reshape(n + 1, n + 1, n + 1)
    c = np.stack([idx[:-1, :-1, :-1], idx[1:, :-1, :-1], idx[1:, 1:, :-1], idx[:-1, 1:, :-1],
                  idx[:-1, :-1, 1:], idx[1:, :-1, 1:], idx[1:, 1:, 1:], idx[:-1, 1:, 1:]], -1).reshape(-1, 8)
    kuhn = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]
    T = np.vstack([c[:, list(k)] for k in kuhn])
    vol = np.einsum("ij,ij->i", np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]), X[T[:, 3]] - X[T[:, 0]])
    T[vol < 0] = T[vol < 0][:, [0, 2, 1, 3]]
    return TetMesh(X, T)


def _segment_distances(P, Q, curve):
    from solver.mesh.clearance import _segments_distance

    return _segments_distance(P, Q, curve[:-1], curve[1:]).min(axis=1)


def test_interior_vertices_and_edges_move_off_a_curve():
    """A curve through interior mesh vertices and along a tet edge (the
    configuration where a quarter turn is packed into slivers and LM ends
    above the discretisation level): afterwards no interior vertex lies
    within INNER_CLEAR local edges of it and no edge between vertices clear
    of it within INNER_EDGE_CLEAR (an edge from a boundary vertex on the
    curve, at its ends, cannot be), every tet keeps its orientation, the boundary
    stays where it was, and the input mesh is not touched."""
    from solver.mesh.clearance import INNER_CLEAR, INNER_EDGE_CLEAR, clear_curves

    mesh = _box_mesh(6)
    X0 = mesh.vertices.copy()
    # through the grid vertices at x = y = 1/2 (along the cells' edges), then
    # across the cube diagonally through more vertices
    curve = np.vstack([np.linspace([0.5, 0.5, 0.0], [0.5, 0.5, 0.5], 4),
                       np.linspace([0.5, 0.5, 0.5], [1.0, 1.0, 1.0], 4)[1:]])
    out, moved = clear_curves(mesh, [curve])
    assert moved > 0 and out is not mesh
    assert np.array_equal(mesh.vertices, X0)
    b = mesh.is_boundary_vertex
    assert np.array_equal(out.vertices[b], X0[b])
    assert out.tet_volumes.min() > 0
    E, L = mesh.edges, mesh.edge_lengths  # the local edge lengths as the clearing measures them
    h_loc = np.bincount(E.reshape(-1), np.repeat(L, 2), len(X0)) / np.bincount(E.reshape(-1))
    inner = ~b
    dv = _segment_distances(out.vertices[inner], out.vertices[inner], curve)
    assert np.all(dv >= 0.99 * INNER_CLEAR * h_loc[inner]), dv.min()
    dall = _segment_distances(out.vertices, out.vertices, curve)
    clear = dall >= INNER_CLEAR * h_loc
    movable = (inner[E[:, 0]] | inner[E[:, 1]]) & clear[E[:, 0]] & clear[E[:, 1]]
    assert movable.sum() > 0.9 * (inner[E[:, 0]] | inner[E[:, 1]]).sum()
    de = _segment_distances(out.vertices[E[movable, 0]], out.vertices[E[movable, 1]], curve)
    he = 0.5 * (h_loc[E[movable, 0]] + h_loc[E[movable, 1]])
    assert np.all(de >= 0.99 * INNER_EDGE_CLEAR * he), (de / he).min()
    # before: vertices and edges on the curve
    assert _segment_distances(X0[inner], X0[inner], curve).min() < 1e-12


def test_a_mesh_clear_of_the_curves_and_the_skipped_balls_stay_as_they_are():
    """Nothing near a curve: the mesh itself comes back; a vertex within a
    skipped ball (a node region) never moves."""
    from solver.mesh.clearance import clear_curves

    mesh = _box_mesh(4)
    # inside the cells, off their diagonal planes
    clear = np.linspace([0.4, 0.3, 0.1], [0.4, 0.3, 0.9], 5)
    out, moved = clear_curves(mesh, [clear])
    assert out is mesh and moved == 0
    through = np.linspace([0.5, 0.5, 0.0], [0.5, 0.5, 1.0], 5)
    out, moved = clear_curves(mesh, [through], skip=[(np.array([0.5, 0.5, 0.5]), 0.1)])
    assert moved > 0
    near = np.linalg.norm(mesh.vertices - 0.5, axis=1) <= 0.1
    assert np.array_equal(out.vertices[near], mesh.vertices[near])


def test_a_clustered_surface_that_is_not_manifold_is_cleared_too():
    """A dense surface clustered for the mesher (decimate.py) need not be
    manifold where a thin part collapsed (a collared shaft: 2 edges of 4
    triangles); the sharp vertices were found with the dihedral angles of a
    manifold surface, and an IndexError reached the user.  Two spheres
    glued along one edge (the second the first mirrored in a plane through
    that edge): a curve end on a vertex is cleared, and the glued edge's
    vertices (on an edge of 4 triangles) stay where they are."""
    V1, F1 = icosphere(2)
    a, b = TriSurface(V1, F1).edges[0]
    n = (V1[a] + V1[b]) / np.linalg.norm(V1[a] + V1[b])
    V2 = V1 - 2.0 * np.outer((V1 - V1[a]) @ n, n)  # mirrored: a and b stay
    F2 = np.where(np.isin(F1, [a, b]), F1, F1 + len(V1))[:, ::-1]  # turned over, a and b shared
    S = TriSurface(np.vstack([V1, V2]), np.vstack([F1, F2]))
    assert np.bincount(S.face_edges.reshape(-1)).max() == 4
    far = int(np.argmin(V1 @ n))  # the vertex opposite the glued edge
    out, moved = clear_curve_ends(S, V1[[far]], 0.3)
    assert moved == 1 and not np.allclose(out.V[far], V1[far])
    assert np.array_equal(out.V[[a, b]], V1[[a, b]])
