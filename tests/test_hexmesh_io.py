"""Hex meshes and hex-mesher exports through files: the command line, the
writers read back by their consumers' readers (meshio; the HexEx format by
its definition), and the field export with the curves on tet edges."""

import os

import meshio
import numpy as np
import pytest

from solver import SolvedField, io
from solver.__main__ import main
from solver.hexmesh import hexmesh
from solver.hexmesh.transitions import edge_rings
from solver.io.cubecover import permutation_matrix, read_fra, read_perm
from solver.mesh.tetmesh import TetMesh

# every test here solves, meshes or hex meshes an example: slow and mesher (CONTRIBUTING.md, Testing)
pytestmark = [pytest.mark.slow, pytest.mark.mesher]


@pytest.fixture(scope="module")
def cylinder_npz(solved, tmp_path_factory):
    res = solved("cylinder")
    path = tmp_path_factory.mktemp("hexio") / "cylinder.npz"
    io.save_result(str(path), res)
    return res, str(path)


def test_a_stored_field_is_meshed_again_from_its_result_file(cylinder_npz, tmp_path):
    res, npz = cylinder_npz
    out = [str(tmp_path / f"c.{ext}") for ext in ("vtu", "vtk", "mesh", "hexex")]
    args = ["--from-result", npz, "--cell-size", "0.2", "-q"]
    for p in out:
        args += ["--hex", p]
    assert main(args) == 0
    direct = hexmesh(res, 0.2)
    for p in out[:3]:
        m = meshio.read(p)
        H = m.cells_dict["hexahedron"]
        assert len(H) == direct.report.hexes
        assert np.abs(m.points[H].mean(axis=1).mean(axis=0) - direct.vertices[direct.hexes].mean(axis=1).mean(
            axis=0)).max() < 1e-9
    V, T, U = io.read_hexex(out[3])
    # the map's own tets, positively oriented, with their parameter points
    X = V[T]
    assert np.all(np.linalg.det(X[:, 1:] - X[:, :1]) > 0)
    assert np.all(np.linalg.det(U[:, 1:] - U[:, :1]) > 0)  # locally injective


def test_a_cell_size_that_does_not_fit_exits_1_before_any_work_and_writes_nothing(cylinder_npz, tmp_path):
    _, npz = cylinder_npz
    out = tmp_path / "big.vtu"
    assert main(["--from-result", npz, "--hex", str(out), "--cell-size", "5", "-q"]) == 1
    assert not out.exists()
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".symframes-")]


def test_hex_options_are_checked_before_any_work(tmp_path):
    assert main(["--example", "cube", "--cell-size", "0.1", "-q"]) == 1  # no --hex to write
    assert main(["--example", "cube", "--hex", str(tmp_path / "x.stl"), "-q"]) == 1
    assert main(["--example", "cube", "--hex", str(tmp_path / "nofolder" / "x.vtu"), "-q"]) == 1
    assert main(["--example", "cube", "--hex", str(tmp_path / "x.vtu"), "--cell-size", "-1", "-q"]) == 1
    assert main(["--example", "cube", "--hex", str(tmp_path / "x.vtu"), "--hex-cells", "0", "-q"]) == 1
    assert not list(tmp_path.iterdir())


def _singular_edges_from_files(stem):
    """Interior edges whose face matchings, read back from .mesh + .perm,
    do not compose to the identity around them."""
    m = meshio.read(stem + ".mesh")
    mesh = TetMesh(m.points, m.cells_dict["tetra"])
    nt, pairs, perms = read_perm(stem + ".perm")
    assert nt == mesh.n_tets and len(read_fra(stem + ".fra")) == mesh.n_tets
    G = permutation_matrix(perms)
    M = {}
    for (a, b), g in zip(pairs.tolist(), G):
        M[(a, b)], M[(b, a)] = g, g.T
    face_pos = np.full(mesh.n_faces, -1)
    inner = np.nonzero(~mesh.is_boundary_face)[0]
    face_pos[inner] = np.arange(len(inner))
    touched = set()
    for a, b in pairs.tolist():
        f = mesh.face_index(np.intersect1d(mesh.tets[a], mesh.tets[b])[None])[0]
        touched.update(mesh.face_edges[f].tolist())
    edges = np.array(sorted(e for e in touched if not mesh.is_boundary_edge[e]))
    rings = edge_rings(mesh, edges, face_pos)
    singular = []
    for e in edges.tolist():
        order = rings[e][0]
        H = np.eye(3)
        for i in range(len(order)):
            H = M.get((order[i], order[(i + 1) % len(order)]), np.eye(3)) @ H
        if not np.allclose(H, np.eye(3)):
            singular.append(e)
    return mesh, np.array(singular)


def test_the_hex_mesher_export_has_its_singular_edges_on_the_curves(solved, tmp_path):
    """Written for CubeCover (.mesh + .fra + .perm): the per-tet field's
    singular edges are the curves' chains, not staircases around them."""
    res = solved("cylinder")
    stem = str(tmp_path / "field")
    io.export_field(res, stem + ".mesh")
    mesh, sing = _singular_edges_from_files(stem)
    assert len(sing) > 0
    # every singular edge lies on a prescribed curve (the cylinder's are straight)
    mid = mesh.vertices[mesh.edges[sing]].mean(axis=1)
    ends = mesh.vertices[mesh.edges[sing]]
    axes = [(c.points[0], c.points[-1]) for c in res.problem.network.curves]

    def dist(P, a, b):
        d = (b - a) / np.linalg.norm(b - a)
        r = P - a
        return np.linalg.norm(r - np.outer(r @ d, d), axis=1)

    D = np.min([dist(mid, a, b) for a, b in axes], axis=0) / res.mesh.mean_edge_length
    # on them up to round-off, but curve_edges.py may move a chain off its
    # curve by a fraction of an edge (a pierce point clamped to LAMBDA_MIN
    # from its face's edges, a vertex within VERTEX_ROUTE taken into it):
    # 1.4e-3 of the mean edge length on one mesh of about ten; a staircase
    # around a curve would be about half an edge length off
    assert np.mean(D < 1e-9) >= 0.9 and D.max() < 0.05, (np.mean(D < 1e-9), D.max())
    # and along them: each edge is parallel to its curve
    d = ends[:, 1] - ends[:, 0]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    assert np.abs(d[:, 2]).min() > 0.999


def test_a_hex_input_round_trips_through_its_arrays(solved, tmp_path):
    res = solved("ball")
    path = str(tmp_path / "ball.npz")
    io.save_result(path, res)
    a, b = hexmesh(res, 0.2), hexmesh(io.load_field(path), 0.2)
    assert a.report.hexes == b.report.hexes and a.report.irregular == b.report.irregular
    assert np.allclose(a.vertices, b.vertices)
    assert isinstance(io.load_field(path), SolvedField)
