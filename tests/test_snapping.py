"""solver/mesh/snapping.py: the tet mesh's boundary moved back onto the input's
sharp edges, corners and patches."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from solver import FieldProblem, Options
from solver.examples import box
from solver.linalg.rotations import cross_distance
from solver.mesh.snapping import closest_on_features, snap_to_features
from solver.mesh.tetmesh import TetMesh
from solver.network.network import Network
from solver.surface.features import FeatureGraph, sharp_edges_by_angle, transfer_features
from solver.surface.trisurface import TriSurface
from tests.meshes import box_mesh, l_prism_surface
from tests.test_examples import check_axis_aligned


def cube_features():
    V, F = box(n=2)
    S = TriSurface(V, F)
    return FeatureGraph(S, sharp_edges_by_angle(S, 30.0))


def shaken_box(seed=0, amount=0.04):
    """A 6^3 grid of [-1, 1]^3 whose boundary vertices are moved off the
    cube by up to ``amount`` of a cell in every direction."""
    mesh = box_mesh(6, (-1, -1, -1), (1, 1, 1))
    rng = np.random.default_rng(seed)
    P = mesh.vertices.copy()
    bv = mesh.boundary_vertices
    P[bv] += rng.uniform(-amount, amount, (len(bv), 3)) * (2.0 / 6)
    return mesh, TetMesh(P, mesh.tets.copy())


def test_closest_points_on_the_sharp_edges():
    G = cube_features()
    X = np.array([[0.3, -1.2, -0.9], [2.0, 2.0, 2.0], [0.1, 0.0, 1.05], [-0.5, 1.1, 0.2]])
    np.testing.assert_allclose(closest_on_features(X, G),
                               [[0.3, -1, -1], [1, 1, 1], [1, 0, 1], [-1, 1, 0.2]], atol=1e-12)


def test_a_shaken_box_is_put_back_on_its_faces_edges_and_corners():
    exact, shaken = shaken_box()
    G = cube_features()
    out, stats = snap_to_features(shaken, G)
    assert stats.reverted == 0 and stats.too_far == 0
    assert stats.moved == len(shaken.boundary_vertices)
    bv = out.boundary_vertices
    # every boundary vertex is back on the cube (moved along the normal, not
    # within the face), the grid's edge vertices on the cube's edges and its
    # corners at the corners
    on_side = np.abs(np.abs(out.vertices[bv]) - 1.0) < 1e-12
    np.testing.assert_array_equal(on_side, np.abs(np.abs(exact.vertices[bv]) - 1.0) < 1e-12)
    np.testing.assert_allclose(out.vertices[bv][on_side], exact.vertices[bv][on_side], atol=1e-12)
    np.testing.assert_array_equal(out.vertices[~out.is_boundary_vertex], shaken.vertices[~out.is_boundary_vertex])
    assert out.tet_volumes.min() > 0
    assert np.isclose(out.tet_volumes.sum(), 8.0)
    # the mapped sharp edges of the snapped mesh are the cube's 12 edges
    sharp = transfer_features(G, out.boundary)
    assert np.isclose(out.boundary.dihedral_angles[sharp], np.pi / 2).all()
    assert sharp.sum() == 12 * 6


def test_a_move_that_would_flatten_a_tet_is_undone(monkeypatch):
    import solver.mesh.snapping as snapping

    _, shaken = shaken_box(seed=1)
    G = cube_features()
    real = snapping.boundary_targets
    corner = int(np.argmin(np.linalg.norm(shaken.vertices - [-1, -1, -1], axis=1)))
    local = int(np.searchsorted(shaken.boundary_vertices, corner))

    def through_the_corner_cell(B, sharp, src):
        T = real(B, sharp, src)
        T[local] = [-1 + 0.5, -1 + 0.5, -1 + 0.5]  # deep into the corner cell
        return T

    monkeypatch.setattr(snapping, "boundary_targets", through_the_corner_cell)
    out, stats = snap_to_features(shaken, G, max_move=10.0)
    assert stats.reverted >= 1
    np.testing.assert_array_equal(out.vertices[corner], shaken.vertices[corner])
    assert np.all(out.tet_volumes >= 0.1 * shaken.tet_volumes - 1e-15)
    # the other vertices were still moved
    assert stats.moved >= len(shaken.boundary_vertices) - 8


def test_without_sharp_edges_nothing_moves():
    _, shaken = shaken_box()
    S = TriSurface(*box(n=2))
    out, stats = snap_to_features(shaken, FeatureGraph(S, np.zeros(len(S.edges), bool)))
    assert out is shaken and stats.moved == 0


@pytest.mark.slow
@pytest.mark.mesher
def test_l_prism_field_is_the_identity():
    """An L-shaped prism (a concave sharp edge, nothing singular): the exact
    field is constant.  Without snapping fTetWild's thin triangles along the
    creases turned it by 5-18 degrees next to the edges; snapped, the
    boundary is the prism's and the field the identity."""
    V, F = l_prism_surface()
    p = FieldProblem(V, F, Network([], sharp_angle=30.0), Options(edge_length=0.2))
    stats = p.meshed.stats.snap
    assert stats.moved > 0
    assert p.report.sizes["snapped_vertices"] == stats.moved
    assert "boundary snapped" in p.report.summary()
    r = p.solve()
    assert r.report.lm.converged
    check_axis_aligned(r)
    mesh = r.mesh
    assert len(stats.kept) == stats.reverted + stats.too_far
    d, _, _ = p.checked.surface.closest_points(mesh.vertices[mesh.boundary_vertices])
    assert np.sum(d > 1e-9) <= len(stats.kept), (np.sum(d > 1e-9), stats)
    # exact wherever the boundary within two edges was put back in place
    # (everywhere, unless a move had to be undone)
    dev = np.degrees(cross_distance(r.frames, np.broadcast_to(np.eye(3), r.frames.shape)))
    far = np.ones(mesh.n_vertices, bool)
    if len(stats.kept):
        far = cKDTree(mesh.vertices[stats.kept]).query(mesh.vertices)[0] > 2 * p.edge_length
    assert far.mean() > 0.5
    assert dev[far].max() <= 1e-4, dev[far].max()


def test_features_that_cannot_be_mapped_leave_the_mesh_alone(monkeypatch):
    """The boundary stage reports unmappable features with its hint; the
    snapping step must not fail first or move anything."""
    import solver.mesh.snapping as snapping
    from solver.errors import TopologyError

    def fail(src, dst):
        raise TopologyError("a sharp feature curve does not lie on the surface")

    monkeypatch.setattr(snapping, "transfer_features", fail)
    _, shaken = shaken_box()
    out, stats = snap_to_features(shaken, cube_features())
    assert out is shaken and stats.moved == 0
