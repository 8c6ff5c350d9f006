"""The map of the genus-2 plate (issue 48b): a network read off a hex mesh
(testkit/hexnet.py, 5 x 3 cells with two holes, eight curves of index -1/4
through the thickness), so a hex mesh with exactly these curves exists.

A curve crossing a tet becomes a chain edge by the tet's split in five,
which leaves three tets around the edge.  A piecewise-linear map images
them with dihedral angles below 180 degrees that sum to 450 at a valence-5
edge: 150 on average, and the frame-fitting map pushed one of the three
past 180 in most rings (and at a curve's end, one of its three boundary
triangles past 180 in the boundary plane), where rounding and untangling
could leave it folded at every cell size.  The rings are widened first
(seamless.ring_edges).  TetGen meshes the plate the same way each run; on
its mesh of seed 4 the map stayed folded at every size of the ladder (18,
14 and 14 tets after untangling) before the rings were widened.
"""

import numpy as np
import pytest

from solver import solve
from solver.hexmesh import hexmesh
from solver.hexmesh.curve_edges import curves_on_edges
from solver.hexmesh.intake import hex_input
from solver.hexmesh.mesher import AUTO_STEPS, MAP_ROUNDS
from solver.hexmesh.seamless import integer_grid_map, map_system, optimise_map, seamless_map, split_flat, widen_rings
from solver.hexmesh.transitions import checked_transitions
from testkit.hexnet import hexnet_input

# solves and hex meshes an input of its own (TetGen: the same mesh each run): slow and mesher (CONTRIBUTING.md)
pytestmark = [pytest.mark.slow, pytest.mark.mesher]


@pytest.fixture(scope="module")
def genus2():
    d = hexnet_input("genus2", 4)
    res = solve(d["V"], d["F"], d["network"], mesher="TetGen")
    assert res.report.converged, res.report.status_reason
    return res


def _ring_counts(cem):
    """(tets around each interior singular chain edge, its valence)."""
    mesh = cem.mesh
    count = np.bincount(mesh.tet_edges.ravel(), minlength=mesh.n_edges)
    out = []
    for ch in cem.chains:
        if ch.sigma == 0:
            continue
        e = mesh.edge_index(ch.vertices[:-1], ch.vertices[1:])
        e = e[(e >= 0) & ~mesh.is_boundary_edge[e]]
        out.append(np.c_[count[e], np.full(len(e), round(4 - 4 * ch.sigma))])
    return np.vstack(out)


def test_rings_around_valence_5_edges_hold_at_least_five_tets(genus2):
    inp = hex_input(genus2, "test")
    cem = curves_on_edges(inp.mesh, inp.embedding, inp.network)
    before = _ring_counts(cem)
    assert np.all(before[:, 1] == 5)  # every curve of the plate is -1/4
    # the split in five leaves three tets around most chain edges
    assert np.mean(before[:, 0] < 5) > 0.5, np.bincount(before[:, 0])
    wide = widen_rings(cem)
    after = _ring_counts(wide)
    assert np.all(after[:, 0] >= after[:, 1]), np.bincount(after[:, 0])
    # the mesh changed only by splitting: same chains, every tet positive
    assert [len(c.vertices) for c in wide.chains] == [len(c.vertices) for c in cem.chains]
    assert np.all(wide.mesh.tet_volumes > 0)


def test_the_integer_grid_map_unfolds_at_every_cell_size_of_the_ladder(genus2):
    inp = hex_input(genus2, "test")
    hm = hexmesh(genus2)
    r = hm.report
    assert r.status == "valid", r.summary()
    # kept at the first (automatic) cell size: no size of the ladder failed
    assert not r.notes, r.notes
    assert r.map_inverted == 0 and r.inverted == 0
    assert r.sj_min >= 0.5 and r.sj_mean >= 0.93, r.summary()
    # the smaller sizes the ladder would try: rounding, stiffening and
    # untangling (as the mesher runs them) leave no tet folded there either
    cem = widen_rings(curves_on_edges(inp.mesh, inp.embedding, inp.network))
    for f in AUTO_STEPS[1:]:
        c = cem
        for _ in range(MAP_ROUNDS):
            tr = checked_transitions(c, inp)
            ms, flat = map_system(c, tr, r.cell_size * f)
            split = split_flat(c, flat) if len(flat) else None
            if split is None:
                break
            c = split
        assert not len(flat)
        sm, red = seamless_map(ms)
        gm = integer_grid_map(ms, red)
        if gm.folded():
            gm = optimise_map(ms, gm)
        assert gm.folded() == 0, f"cell size {r.cell_size * f:.4g}: {gm.folded()} tets fold"
