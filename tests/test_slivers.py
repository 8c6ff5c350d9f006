"""Repair of flat tets in the mesher's output (solver/mesh/slivers.py)."""

from __future__ import annotations

import numpy as np
import pytest

from solver.mesh.refine import red_refine
from solver.mesh.slivers import FLAT_QUALITY, FlatRepair, repair_flat_tets, tet_quality
from solver.mesh.tetmesh import TetMesh
from tests.meshes import box_grid


def flattened_box(flip: bool, seed: int = 5):
    """A jittered box mesh in which one interior vertex has been moved onto
    the plane of the opposite face of one of its tets (the rest stay
    positive), as fTetWild's rounding leaves them.  flip: that tet's
    vertices in the other order, as a volume of round-off sign sorts it."""
    V, T = box_grid(4, jitter=0.2, seed=seed)
    M = TetMesh(V, T)
    inner = np.flatnonzero(~M.is_boundary_vertex)
    for v in inner:
        for t in np.flatnonzero((M.tets == v).any(axis=1)):
            face = M.tets[t][M.tets[t] != v]
            a, b, c = M.vertices[face]
            n = np.cross(b - a, c - a)
            n /= np.linalg.norm(n)
            P = M.vertices.copy()
            P[v] -= np.dot(P[v] - a, n) * n
            q = tet_quality(P, M.tets)
            others = np.delete(q, t)
            if others.min() > 0.05 and abs(q[t]) < 1e-12:
                Tn = M.tets.copy()
                if flip:
                    Tn[t] = Tn[t][[1, 0, 2, 3]]
                return M, P, Tn, t, v
    raise AssertionError("no vertex could be flattened without inverting a neighbour")


@pytest.mark.parametrize("flip", [False, True])
def test_flat_tet_is_lifted_off_its_plane_without_moving_the_boundary(flip):
    M, P, T, t, v = flattened_box(flip)
    P2, T2, info = repair_flat_tets(P, T, M.is_boundary_vertex, M.face_tets, M.tet_faces)
    assert info == FlatRepair(flat_tets=1, moved_vertices=1, flat_tets_left=0)
    q = tet_quality(P2, T2)
    # every tet positive in one consistent orientation: the signed volumes
    # then add up to the box's, whatever the interior vertices do
    assert q.min() >= FLAT_QUALITY
    assert np.isclose(TetMesh._signed_volumes(P2, T2).sum(), 1.0, rtol=1e-12)
    assert np.array_equal(P2[M.is_boundary_vertex], P[M.is_boundary_vertex])
    # only the flat tet's vertices may have moved
    moved = np.flatnonzero(np.any(P2 != P, axis=1))
    assert set(moved) <= set(T[t])
    # refined, the repaired mesh has no degenerate tet or edge
    fine = red_refine(TetMesh(P2, T2)).fine
    assert fine.tet_volumes.min() > 0
    assert tet_quality(fine.vertices, fine.tets).min() >= FLAT_QUALITY / 4
    assert fine.edge_lengths.min() > 1e-3 * fine.mean_edge_length


def test_a_mesh_without_flat_tets_is_returned_unchanged():
    M = TetMesh(*box_grid(3, jitter=0.2, seed=1))
    P, T, info = repair_flat_tets(M.vertices, M.tets, M.is_boundary_vertex, M.face_tets, M.tet_faces)
    assert info == FlatRepair(flat_tets=0, moved_vertices=0, flat_tets_left=0)
    assert P is M.vertices and T is M.tets


def test_a_flat_tet_with_only_boundary_vertices_is_reported_not_moved():
    # a single cube cell: every vertex is on the boundary, so nothing may
    # move; flatten one tet by squashing the box and check that it is left
    # as it is and counted
    V, T = box_grid(1)
    M = TetMesh(V, T)
    P = M.vertices.copy()
    t = 0
    a, b, c, d = P[M.tets[t]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    P[M.tets[t][3]] -= np.dot(d - a, n) * n
    P2, T2, info = repair_flat_tets(P, M.tets, np.ones(len(P), bool), M.face_tets, M.tet_faces)
    assert info.flat_tets >= 1 and info.moved_vertices == 0
    assert info.flat_tets_left == info.flat_tets
    assert np.array_equal(P2, P)


def test_the_report_says_how_many_flat_tets_were_repaired():
    from solver.report import Report

    r = Report(sizes={"tets": 10, "flat_tets": 3, "flat_tets_left": 1, "flat_moved_vertices": 2})
    assert "fTetWild left 3 flat tet(s): 2 vertices moved off their plane, 1 still flat" in r.summary()
    assert "flat" not in Report(sizes={"tets": 10}).summary()
