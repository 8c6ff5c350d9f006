"""Tests of solver/io/interchange.py (export of a solved field: VTU, MEDIT +
.fra + .perm, OVM, .qtn; the writers and readers of vtu.py, medit.py,
cubecover.py, ovm.py and qtn.py) and solver/io/tetnetwork.py (a network read
from a tet mesh with tagged edges).

One cylinder (four axial curves, sigma = 1/4) is solved once per session
(tests/conftest.py).
fTetWild is not deterministic, so the assertions are properties of whatever
mesh it made, not counts.
"""

from __future__ import annotations

import meshio
import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from solver import NetworkError, OutputError, solve
from solver.analysis.measures import tet_frames as karcher_tet_frames
from solver.field.matchings import face_matchings, omega_matchings, omega_tet_frames
from solver.io.cubecover import permutation_matrix, read_fra, read_perm, signed_permutation
from solver.io.interchange import export_field, field_export, vtu_field_data
from solver.io.medit import boundary_triangles, write_medit
from solver.io.ovm import read_ovm, write_ovm
from solver.io.qtn import quaternion_frames, read_qtn
from solver.io.tetnetwork import (
    chain_edges,
    read_tet_network,
    tag_sigma,
)
from solver.io.vtu import write_vtu
from solver.linalg.rotations import (
    CUBE_GROUP,
    GROUP_INVERSE,
    GROUP_PRODUCT,
    closest_symmetry,
    cross_distance,
    exp_so3,
    rotation_angle,
    symmetry_index,
)
from solver.mesh.tetmesh import TetMesh
from tests.meshes import box_mesh

H = 0.4


@pytest.fixture(scope="module")
def cylinder(solved):
    return solved("cylinder", edge_length=H, refine=0)


@pytest.fixture(scope="module")
def fe(cylinder):
    return field_export(cylinder)


@pytest.fixture(scope="module")
def files(cylinder, tmp_path_factory):
    d = tmp_path_factory.mktemp("interchange")
    out = {}
    data = field_export(cylinder)
    for ext in ("vtu", "mesh", "ovm", "qtn"):
        for p in export_field(cylinder, str(d / f"cyl.{ext}"), data=data):
            out[p.rsplit(".", 1)[1]] = p
    return out


def crossed_tets(result) -> np.ndarray:
    n = len(result.embedding.traces)
    return np.unique(np.concatenate([result.curve_tets(i) for i in range(n)]))


def away_tets(result) -> np.ndarray:
    """(#T,) bool: tets none of whose vertices belongs to a tet a curve crosses."""
    mesh = result.mesh
    near = np.zeros(mesh.n_vertices, bool)
    near[mesh.tets[crossed_tets(result)].reshape(-1)] = True
    return ~near[mesh.tets].any(axis=1)


def pierced_faces(result) -> np.ndarray:
    n = len(result.embedding.traces)
    return np.unique(np.concatenate([result.curve_faces(i) for i in range(n)]))


# ------------------------------------------------------------ group encoding
def test_group_tables_and_cubecover_encoding():
    G = CUBE_GROUP
    a, b = np.meshgrid(np.arange(24), np.arange(24), indexing="ij")
    assert np.allclose(G[GROUP_PRODUCT[a, b]], G[a] @ G[b])
    assert np.allclose(G[GROUP_INVERSE] @ G, np.eye(3))
    p = signed_permutation(np.arange(24))
    assert np.all(np.sort(np.abs(p), axis=1) == [1, 2, 3])
    assert np.array_equal(symmetry_index(permutation_matrix(p)), np.arange(24))
    assert np.array_equal(p[0], [1, 2, 3])  # identity
    # a reflection is no rotation of the cube
    assert symmetry_index(permutation_matrix([[-1, 2, 3]]))[0] == -1
    # CubeCover's AssignmentGroup: to.row(|p_i| - 1) = sign(p_i) from.row(i) when
    # the frames (rows = axes) satisfy F_from = F_to G[g]
    rng = np.random.default_rng(1)
    F_to = exp_so3(rng.normal(size=(24, 3)))
    F_from = F_to @ G
    rows_from, rows_to = np.transpose(F_from, (0, 2, 1)), np.transpose(F_to, (0, 2, 1))
    k = np.arange(24)[:, None]
    assert np.allclose(rows_to[k, np.abs(p) - 1], np.sign(p)[..., None] * rows_from)


# ------------------------------------------------------------ frames per tet
@pytest.mark.slow
@pytest.mark.mesher
def test_tet_frames_are_the_documented_average(cylinder, fe):
    mesh, omega, E = cylinder.mesh, cylinder.omega, cylinder.frames
    T = mesh.tets
    # the matchings: omega carries the first vertex's frame to each other vertex
    for k in range(1, 4):
        g = omega_matchings(mesh, omega, E, np.c_[T[:, 0], T[:, k]])
        assert np.array_equal(fe.tet.matching[:, k], g)
    assert np.all(fe.tet.matching[:, 0] == 0)
    # the chordal mean projected to SO(3): F = M (M^T M)^(-1/2) for the sum M
    M = np.einsum("tkij,tkjl->til", E[T], CUBE_GROUP[fe.tet.matching])
    w, U = np.linalg.eigh(np.einsum("tji,tjk->tik", M, M))
    inv_sqrt = np.einsum("tij,tj,tkj->tik", U, 1.0 / np.sqrt(w), U)
    assert np.all(np.linalg.det(M) > 0)
    assert np.allclose(fe.tet.frames, M @ inv_sqrt, atol=1e-9)
    F = fe.tet.frames
    assert np.allclose(np.einsum("tji,tjk->tik", F, F), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(F), 1.0)
    # the same cross as the Karcher mean of closest-rotation matched frames
    # (analysis.tet_frames) away from the curves; next to them an edge may turn
    # by more than 45 degrees and closest-rotation matching picks another
    # representative than omega does
    away = away_tets(cylinder)
    assert away.sum() > 0.3 * mesh.n_tets
    d = np.degrees(cross_distance(F[away], karcher_tet_frames(mesh, E)[away]))
    assert d.max() < 1.0
    assert np.degrees(fe.tet.spread[away]).max() < 30.0


def test_face_matchings_on_a_synthetic_field():
    """A smooth field with random representatives at the vertices: every face
    matching is the symmetry relating the representatives, and the tet frames
    agree across faces once matched."""
    mesh = box_mesh(3, jitter=0.1)
    X = mesh.vertices
    E = exp_so3(0.3 * np.c_[X[:, 0], X[:, 1] ** 2, X[:, 2]])
    from solver.analysis.measures import darboux_derivative

    omega = darboux_derivative(mesh, E)
    rng = np.random.default_rng(3)
    g = rng.integers(0, 24, mesh.n_vertices)
    tf = omega_tet_frames(mesh, omega, E @ CUBE_GROUP[g])
    fm = face_matchings(mesh, tf)
    assert fm.agree.all()
    assert np.array_equal(fm.symmetry, fm.closest)
    A, B = fm.tets.T
    assert rotation_angle(np.einsum("kji,kjl->kil", tf.frames[A], tf.frames[B] @ CUBE_GROUP[fm.symmetry])).max() < 0.2
    # the tet frame is the representative of the first vertex's cross
    d = rotation_angle(np.einsum("kji,kjl->kil", tf.frames, (E @ CUBE_GROUP[g])[mesh.tets[:, 0]]))
    assert d.max() < np.radians(30)


# ---------------------------------------------------------------------- VTU
@pytest.mark.slow
@pytest.mark.mesher
def test_vtu_round_trip_through_meshio(cylinder, fe, files, tmp_path):
    mesh = cylinder.mesh
    crossed = np.zeros(mesh.n_tets, bool)
    crossed[crossed_tets(cylinder)] = True
    pd, cd = vtu_field_data(fe)
    ascii_path = str(tmp_path / "ascii.vtu")
    write_vtu(ascii_path, mesh.vertices, mesh.tets, pd, cd, binary=False)
    for path in (files["vtu"], ascii_path):
        m = meshio.read(path)
        assert np.allclose(m.points, mesh.vertices, atol=1e-12)
        assert [c.type for c in m.cells] == ["tetra"]
        assert np.array_equal(m.cells[0].data, mesh.tets)
        for k in range(3):
            assert np.allclose(m.point_data[f"axis{k}"], cylinder.frames[:, :, k], atol=1e-6)
            assert np.allclose(m.cell_data[f"tet_axis{k}"][0], fe.tet.frames[:, :, k], atol=1e-6)
        assert np.array_equal(m.cell_data["singular"][0].astype(bool), crossed)
        cur = m.cell_data["curve"][0]
        for i in range(len(cylinder.embedding.traces)):
            assert np.all(cur[cylinder.curve_tets(i)] >= 0)
        assert np.all(cur[~crossed] == -1)
        # the crossed tets are where omega-matched faces fail to close
        osing = m.cell_data["omega_singular"][0]
        assert np.all(osing[~crossed] == 0)
        assert np.all(m.cell_data["monodromy_deg"][0][~crossed] < 1.0)


# -------------------------------------------------------------------- MEDIT
@pytest.mark.slow
@pytest.mark.mesher
def test_medit_round_trip_through_meshio(cylinder, fe, files):
    mesh = cylinder.mesh
    m = meshio.read(files["mesh"])
    assert np.allclose(m.points, mesh.vertices, atol=1e-12)
    cells = {c.type: (c.data, ref) for c, ref in zip(m.cells, m.cell_data["medit:ref"])}
    tets, tref = cells["tetra"]
    assert np.array_equal(tets, mesh.tets)
    assert np.array_equal(tref, fe.curve + 1)
    tri, _ = cells["triangle"]
    assert np.array_equal(tri, boundary_triangles(mesh))
    assert np.array_equal(np.sort(np.sort(tri, axis=1), axis=0), np.sort(mesh.faces[mesh.boundary_faces], axis=0))
    # boundary triangles outward: the enclosed volume is positive
    P = mesh.vertices[tri]
    vol = np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6.0
    assert vol > 0 and np.isclose(vol, np.abs(mesh.tet_volumes).sum())
    # the .fra holds the tet frames, axis per line
    assert np.allclose(read_fra(files["fra"]), fe.tet.frames, atol=1e-12)


def face_symmetries_from_perm(mesh, path):
    """CUBE_GROUP index g per face (g: F_A = F_B G[g], A = face_tets[:, 0]),
    identity where the .perm lists nothing."""
    nt, pairs, perms = read_perm(path)
    assert nt == mesh.n_tets
    g = symmetry_index(permutation_matrix(perms))
    assert np.all(g >= 0)
    ft = mesh.face_tets
    lo = np.minimum(ft[:, 0], ft[:, 1])
    key = {(int(a), int(b)): f for f, (a, b) in enumerate(ft) if lo[f] >= 0}
    out = np.zeros(mesh.n_faces, np.int64)
    for (a, b), gi in zip(pairs, g):
        f = key.get((int(a), int(b)))
        if f is None:  # listed the other way round: CubeCover inverts
            f = key[(int(b), int(a))]
            gi = GROUP_INVERSE[gi]
        out[f] = gi
    return out


@pytest.mark.slow
@pytest.mark.mesher
def test_perm_matchings_follow_omega(cylinder, files):
    mesh, omega, E = cylinder.mesh, cylinder.omega, cylinder.frames
    g = face_symmetries_from_perm(mesh, files["perm"])
    interior = np.nonzero(~mesh.is_boundary_face)[0]
    A, B = mesh.face_tets[interior].T
    # independently: through each face vertex p, match p to both tets' first vertex along omega
    votes = []
    for j in range(3):
        p = mesh.faces[interior, j]
        hA = omega_matchings(mesh, omega, E, np.c_[mesh.tets[A, 0], p])
        hB = omega_matchings(mesh, omega, E, np.c_[mesh.tets[B, 0], p])
        hA[mesh.tets[A, 0] == p] = 0
        hB[mesh.tets[B, 0] == p] = 0
        votes.append(GROUP_PRODUCT[GROUP_INVERSE[hB], hA])
    votes = np.stack(votes, axis=1)
    crossed = np.zeros(mesh.n_tets, bool)
    crossed[crossed_tets(cylinder)] = True
    gi = g[interior]
    # faces the network does not pierce: the written matching is a majority of the omega votes
    not_pierced = ~np.isin(interior, pierced_faces(cylinder))
    majority = (votes == gi[:, None]).sum(axis=1) >= 2
    assert np.all(majority[not_pierced])
    # faces between two tets no curve crosses: all three votes agree with it
    clear = ~crossed[A] & ~crossed[B]
    assert np.all(votes[clear] == gi[clear, None])
    # away from the curves (no vertex of either tet on a crossed tet): the
    # closest rotation between the written tet frames gives the same symmetry
    F = read_fra(files["fra"])
    away = away_tets(cylinder)[A] & away_tets(cylinder)[B]
    assert away.sum() > 0.3 * len(interior)
    closest = closest_symmetry(np.einsum("kji,kjl->kil", F[A], F[B]))  # F_A^T F_B g ~ I
    assert np.array_equal(closest[away], gi[away])
    assert np.allclose(np.einsum("kji,kjl->kil", F[A[away]], F[B[away]] @ CUBE_GROUP[gi[away]]),
                       np.eye(3), atol=np.sin(np.radians(30)))


@pytest.mark.slow
@pytest.mark.mesher
def test_perm_singular_edges_are_on_the_curves(cylinder, files):
    """What CubeCover derives from the .perm (FrameField::setSingularEdges):
    composing the matchings around an interior edge gives the identity except
    on edges of tets a curve crosses, and every curve leaves such edges."""
    mesh = cylinder.mesh
    g = face_symmetries_from_perm(mesh, files["perm"])
    ft = mesh.face_tets
    crossed = np.zeros(mesh.n_tets, bool)
    crossed[crossed_tets(cylinder)] = True
    # faces around each interior edge
    fe = mesh.face_edges.reshape(-1)
    fid = np.repeat(np.arange(mesh.n_faces), 3)
    order = np.argsort(fe, kind="stable")
    fe, fid = fe[order], fid[order]
    start = np.searchsorted(fe, np.arange(mesh.n_edges + 1))
    singular = []
    for e in np.nonzero(~mesh.is_boundary_edge)[0]:
        faces = fid[start[e]:start[e + 1]]
        # walk the ring of tets around the edge, h_{k+1} = G[g] h_k from A to B
        t0 = ft[faces[0], 0]
        t, h, used = t0, 0, set()
        while True:
            f = next(f for f in faces if f not in used and t in ft[f])
            used.add(f)
            if ft[f, 0] == t:
                h, t = GROUP_PRODUCT[g[f], h], ft[f, 1]
            else:
                h, t = GROUP_PRODUCT[GROUP_INVERSE[g[f]], h], ft[f, 0]
            if t == t0:
                break
        assert len(used) == len(faces)
        if h != 0:
            singular.append(e)
    singular = np.array(singular, dtype=np.int64)
    edge_in_crossed = np.zeros(mesh.n_edges, bool)
    edge_in_crossed[mesh.tet_edges[crossed].reshape(-1)] = True
    assert len(singular) and np.all(edge_in_crossed[singular])
    for i in range(len(cylinder.embedding.traces)):
        assert np.isin(mesh.tet_edges[cylinder.curve_tets(i)].reshape(-1), singular).any()


# ---------------------------------------------------------------- QTN / OVM
@pytest.mark.slow
@pytest.mark.mesher
def test_qtn_and_ovm_round_trip(cylinder, fe, files):
    mesh = cylinder.mesh
    q = read_qtn(files["qtn"])
    assert q.shape == (mesh.n_tets, 4)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0)
    assert np.allclose(quaternion_frames(q), fe.tet.frames, atol=1e-9)
    d = read_ovm(files["ovm"])
    assert np.allclose(d.vertices, mesh.vertices, atol=1e-12)
    assert np.array_equal(d.edges, mesh.edges)
    assert np.array_equal(np.sort(d.tets, axis=1), np.sort(mesh.tets, axis=1))
    assert np.all(TetMesh._signed_volumes(d.vertices, d.tets) > 0)
    assert np.allclose(quaternion_frames(d.props["vertex"]["vertex_frame_wxyz"]), cylinder.frames, atol=1e-6)
    assert np.allclose(quaternion_frames(d.props["cell"]["cell_frame_wxyz"]), fe.tet.frames, atol=1e-6)
    for k in range(3):
        assert np.allclose(d.props["cell"][f"cell_axis{k}"], fe.tet.frames[:, :, k], atol=1e-9)
    assert np.array_equal(d.props["cell"]["curve"], fe.curve)
    g = d.props["face"]["matching"]
    assert np.array_equal(g[fe.matchings.faces], fe.matchings.symmetry)
    check_ovm_topology(d)


def check_ovm_topology(d):
    """What OpenVolumeMesh checks when it adds faces and cells, and its
    orientation convention: face halfedges form a loop, each cell's halffaces
    a closed 2-manifold (every halfedge used once, with its opposite), each
    halfface in at most one cell, and halfface normals point into the cell."""
    E, he, hf, V = d.edges, d.face_halfedges, d.cell_halffaces, d.vertices
    frm = E.reshape(-1)  # from-vertex of halfedge h
    to = E[:, ::-1].reshape(-1)
    assert np.array_equal(to[he], frm[np.roll(he, -1, axis=1)])
    # halfedges of a cell's halffaces: those of halfface 2f + 1 are reversed and opposite
    hedges = he[hf // 2]  # (#C, 4, 3)
    hedges = np.where((hf % 2 == 1)[:, :, None], hedges[:, :, ::-1] ^ 1, hedges)
    flat = np.sort(hedges.reshape(len(hf), 12), axis=1)
    assert np.all(np.diff(flat, axis=1) > 0)  # each halfedge once per cell
    assert np.array_equal(np.sort(flat ^ 1, axis=1), flat)  # with its opposite
    u, c = np.unique(hf, return_counts=True)
    assert c.max() == 1
    # the halfface normal (right-hand rule on its loop) points to the cell's centroid
    loop = frm[hedges]  # (#C, 4, 3) vertices in loop order
    P = V[loop]
    n = np.cross(P[:, :, 1] - P[:, :, 0], P[:, :, 2] - P[:, :, 0])
    cen = V[d.tets].mean(axis=1)
    assert np.all(np.einsum("cfk,cfk->cf", n, cen[:, None, :] - P[:, :, 0]) > 0)


@pytest.mark.slow
@pytest.mark.mesher
def test_export_rejects_unknown_format(cylinder, tmp_path):
    with pytest.raises(OutputError, match=r"unknown format '\.stl'; the file name must end in \.vtu or"):
        export_field(cylinder, str(tmp_path / "x.stl"))
    with pytest.raises(OutputError, match="unknown format 'stl'"):
        export_field(cylinder, str(tmp_path / "x.vtu"), fmt="stl")


# ----------------------------------------------------------- tagged networks
def test_chain_edges_breaks_at_nodes_boundary_and_sigma():
    stop = np.zeros(20, bool)
    stop[[0, 9]] = True
    # 0-1-2-3 | a Y at 3: 3-4-5, 3-6-7 | loop 10-11-12-10 | 8-9 with 9 on the boundary and 1-8 sigma change
    edges = np.array([[0, 1], [1, 2], [2, 3], [3, 4], [4, 5], [3, 6], [6, 7], [10, 11], [11, 12], [12, 10],
                      [13, 14], [14, 15]])
    sigma = np.array([.25] * 10 + [.25, -.25])
    chains, sig = chain_edges(edges, sigma, stop)
    got = sorted((tuple(c) if c[0] <= c[-1] else tuple(c[::-1])) for c in chains)
    loops = [c for c in chains if c[0] == c[-1]]
    assert len(loops) == 1 and sorted(loops[0][:-1]) == [10, 11, 12]
    opens = sorted(g for g in got if g[0] != g[-1])
    assert opens == [(0, 1, 2, 3), (3, 4, 5), (3, 6, 7), (13, 14), (14, 15)]
    assert sorted(sig) == [-.25] + [.25] * 5


def test_tag_conventions():
    t = np.array([1, -1, 2, 0])
    assert np.allclose(tag_sigma(t, 1), [.25, -.25, .5, 0])
    assert np.allclose(tag_sigma(t, -1), [-.25, .25, -.5, 0])
    assert np.allclose(tag_sigma(np.array([3, 5, 4, 0, 2]), "valence"), [.25, -.25, 0, 0, .5])
    with pytest.raises(ValueError):
        tag_sigma(t, 2)


def test_import_loop_and_node_from_a_grid(tmp_path):
    """A closed loop and a degree-3 node on a structured grid, through OVM and
    MEDIT: the loop comes back closed, the three arms meet in one node.  The
    arms' ends sum to 0 under either sign, so the sign must be given."""
    from solver.network.network import prepare_network

    mesh = box_mesh(4)

    def edges_along(*pts):
        ids = [int(np.argmin(np.linalg.norm(mesh.vertices - 0.25 * np.asarray(p), axis=1))) for p in pts]
        e = mesh.edge_index(np.array(ids[:-1]), np.array(ids[1:]))
        assert np.all(e >= 0)
        return e

    tags = np.zeros(mesh.n_edges, np.int64)
    tags[edges_along((1, 1, 2), (2, 1, 2), (3, 1, 2), (3, 2, 2), (3, 3, 2), (2, 3, 2), (1, 3, 2), (1, 2, 2),
                     (1, 1, 2))] = 1
    # the arms end on the bottom face, their indices summing to 0 as its sharp edges ask
    tags[np.r_[edges_along((2, 2, 1), (2, 2, 0)), edges_along((2, 2, 1), (1, 2, 1), (1, 2, 0))]] = -1
    tags[edges_along((2, 2, 1), (3, 2, 1), (3, 2, 0))] = 2
    write_ovm(str(tmp_path / "grid.ovm"), mesh, edge_props={"tag": tags})
    on = np.nonzero(tags)[0]
    write_medit(str(tmp_path / "grid.mesh"), mesh.vertices, mesh.tets, boundary_triangles(mesh),
                edges=mesh.edges[on], edge_refs=tags[on])
    for name in ("grid.ovm", "grid.mesh"):
        with pytest.raises(NetworkError, match=r"fit more than one tag convention \('index' .*'negated'"):
            read_tet_network(str(tmp_path / name), sharp_angle=30)
        V, F, net = read_tet_network(str(tmp_path / name), "index", sharp_angle=30)
        assert sorted(c.sigma for c in net.curves) == [-0.25, -0.25, 0.25, 0.5]
        assert net.sharp_edges is None
        pn = prepare_network(net, 1.7)
        kinds = sorted(zip(pn.start_kind, pn.end_kind))
        assert kinds.count(("loop", "loop")) == 1
        assert len(pn.nodes) == 1 and len(pn.nodes[0].ends) == 3
        assert np.allclose(pn.nodes[0].position, [0.5, 0.5, 0.25])


def shortest_interior_path(mesh, a, b):
    """Vertex path a -> b through interior edges, touching the boundary only at a and b."""
    E, bnd = mesh.edges, mesh.is_boundary_vertex.copy()
    bnd[[a, b]] = False
    ok = ~mesh.is_boundary_edge & ~bnd[E[:, 0]] & ~bnd[E[:, 1]]
    n = mesh.n_vertices
    W = sp.coo_matrix((mesh.edge_lengths[ok], (E[ok, 0], E[ok, 1])), shape=(n, n))
    _, pred = dijkstra(W, directed=False, indices=a, return_predecessors=True)
    path = [b]
    while path[-1] != a:
        path.append(int(pred[path[-1]]))
    return np.array(path[::-1])


@pytest.mark.slow
@pytest.mark.mesher
def test_import_tagged_tet_mesh_and_solve(cylinder, tmp_path):
    mesh = cylinder.mesh
    curves = cylinder.problem.network.curves
    bnd = mesh.is_boundary_vertex
    index = np.zeros(mesh.n_edges, np.int64)
    ends = []
    for c in curves:
        a, b = (int(np.argmin(np.where(bnd, np.linalg.norm(mesh.vertices - x, axis=1), np.inf)))
                for x in (c.points[0], c.points[-1]))
        path = shortest_interior_path(mesh, a, b)
        index[mesh.edge_index(path[:-1], path[1:])] = round(4 * c.sigma)
        ends.append({a, b})
    # the cylinder's rims, tagged as sharp boundary edges
    B = mesh.boundary
    rim = B.dihedral_angles > np.radians(30)
    bv = mesh.boundary_vertices
    rim_edges = mesh.edge_index(bv[B.edges[rim, 0]], bv[B.edges[rim, 1]])
    index[rim_edges] = 1
    path_ovm = str(tmp_path / "tagged.ovm")
    write_ovm(path_ovm, mesh, edge_props={"other": np.zeros(mesh.n_edges, np.int64), "singular_index": index})
    # the same network through the valence convention, the opposite sign and MEDIT's edge refs
    valence = np.where(index != 0, 4 - index, 0)
    write_ovm(str(tmp_path / "valence.ovm"), mesh, edge_props={"valence": valence})
    write_ovm(str(tmp_path / "negated.ovm"), mesh, edge_props={"index": -index})
    tagged = np.nonzero(index)[0]
    write_medit(str(tmp_path / "tagged.mesh"), mesh.vertices, mesh.tets, edges=mesh.edges[tagged],
                edge_refs=index[tagged])
    V, F, net = read_tet_network(path_ovm, edge_property="singular_index")
    variants = [read_tet_network(path_ovm),  # picks the integer edge property with nonzero values
                read_tet_network(str(tmp_path / "valence.ovm"), sign="valence"),
                read_tet_network(str(tmp_path / "negated.ovm"), sign=-1),
                read_tet_network(str(tmp_path / "tagged.mesh"))]
    # the surface: the tet mesh's boundary, outward, compacted
    assert len(V) == len(bv) and np.allclose(V, mesh.vertices[bv])
    P = V[F]
    assert np.isclose(np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum() / 6.0,
                      np.abs(mesh.tet_volumes).sum())
    # curves: as many, same sigma, ends at the chosen vertices, near the original ends
    assert len(net.curves) == len(curves)
    assert sorted(c.sigma for c in net.curves) == sorted(c.sigma for c in curves)
    h = mesh.mean_edge_length
    for c in net.curves:
        a = int(np.argmin(np.linalg.norm(mesh.vertices - c.points[0], axis=1)))
        b = int(np.argmin(np.linalg.norm(mesh.vertices - c.points[-1], axis=1)))
        assert {a, b} in ends
        orig = [o for o in curves if min(np.linalg.norm(o.points[[0, -1]] - c.points[0], axis=1)) < 1.5 * h]
        assert len(orig) == 1
        d = np.linalg.norm(np.sort(orig[0].points[[0, -1]], axis=0) - np.sort(c.points[[0, -1]], axis=0), axis=1)
        assert d.max() < 1.5 * h
        # the chain runs along tet-mesh edges
        ids = np.array([int(np.argmin(np.linalg.norm(mesh.vertices - x, axis=1))) for x in c.points])
        assert np.all(mesh.edge_index(ids[:-1], ids[1:]) >= 0)
    # sharp edges: the rims, in surface vertex ids
    se = np.sort(np.asarray(net.sharp_edges), axis=1)
    assert np.array_equal(np.unique(se, axis=0), np.unique(np.sort(B.edges[rim], axis=1), axis=0))
    for V2, F2, net2 in variants:
        assert np.array_equal(F2, F) and np.array_equal(V2, V)
        assert sorted(c.sigma for c in net2.curves) == sorted(c.sigma for c in net.curves)
        assert len(net2.sharp_edges) == len(net.sharp_edges)
    # the chains as read (zig-zag along tet edges, ends where the mesh had them)
    # solve through the curve intake, and the field winds around them as the
    # original network's did: omega-matched singular faces exactly on the curves
    # (a mesh of its own: the surface is the read tet mesh's boundary)
    res = solve(V, F, net, edge_length=H)
    m, lm = res.report.metrics, res.report.lm
    print(f"\nimported network: {len(net.curves)} curves, {res.mesh.n_tets} tets; LM {lm.n_iterations} iterations, "
          f"{lm.reason}; converged {lm.converged}; moved up to "
          f"{max(r.max_displacement_h for r in res.report.repairs):.2f} h")
    assert lm.converged
    assert len(res.report.repairs) == len(curves)
    assert m["omega_spurious_singular_faces"] == 0 and m["omega_missing_singular_faces"] == 0
    assert m["normal_adaptation_mean_deg"] < 0.5 and m["tangent_adaptation_mean_deg"] < 1.0


@pytest.mark.mesher
def test_cli_exports_every_format_and_refuses_a_bad_one_before_solving(tmp_path, capsys):
    """``python -m solver --export``: each format written after the solve, an
    unknown extension or a missing folder refused before any work.  The cube's
    field is constant, so its .perm lists no face: that writes too."""
    from solver.__main__ import main

    out = [str(tmp_path / f"cube.{ext}") for ext in ("vtu", "mesh", "ovm", "qtn")]
    args = ["--example", "cube", "--edge-length", "0.5", "-q", "-o", str(tmp_path / "cube.npz")]
    assert main(args + [a for p in out for a in ("--export", p)]) == 0
    m = meshio.read(out[0])
    assert len(m.cells_dict["tetra"]) == len(read_qtn(out[3]))
    n_tets, pairs, _ = read_perm(str(tmp_path / "cube.perm"))
    assert n_tets == len(m.cells_dict["tetra"]) and len(pairs) == 0
    assert read_ovm(out[2]).tets.shape == (n_tets, 4)
    capsys.readouterr()
    assert main(["--example", "cube", "--export", str(tmp_path / "cube.stl")]) == 1
    assert "unknown format '.stl'" in capsys.readouterr().err
    assert main(["--example", "cube", "--export", str(tmp_path / "no" / "such" / "cube.vtu")]) == 1
    assert "does not exist" in capsys.readouterr().err


def test_cli_reads_a_tagged_tet_mesh(tmp_path, capsys):
    """``python -m solver --tet-network``: the domain and network of a tagged
    tet mesh, with the tag convention switch and sharp edges by angle (here
    validated only)."""
    from solver.__main__ import main

    mesh = box_mesh(4)
    tags = np.full(mesh.n_edges, 4, np.int64)  # valence 4: regular
    for x, valence in ((1, 3), (3, 5)):  # two straight axes, sigma +1/4 and -1/4: Poincare-Hopf holds
        ids = [int(np.argmin(np.linalg.norm(mesh.vertices - 0.25 * np.array([x, 2, z]), axis=1))) for z in range(5)]
        tags[mesh.edge_index(np.array(ids[:-1]), np.array(ids[1:]))] = valence
    path = str(tmp_path / "axis.ovm")
    write_ovm(path, mesh, edge_props={"valence": tags})
    assert main(["--tet-network", path, "--tag-convention", "valence", "--sharp-angle", "30",
                 "--check"]) == 0
    assert "2 interior curves" in capsys.readouterr().out


# ------------------------------------------------ tag conventions, detected
def tet_edge_tags(V, F, net, mesh):
    """The interior curves of net as tagged edges of mesh (testkit's tet-edge
    routing, without its tiny segments): (edge ids, sigma per edge)."""
    from testkit.tetedge import tet_edge_network

    tn, _ = tet_edge_network(V, F, net, 0.0, tiny=False, mesh=mesh)
    ids, sig = [], []
    for c in tn.curves:
        if c.role.value == "sharp":
            continue
        v = np.array([int(np.argmin(np.linalg.norm(mesh.vertices - x, axis=1))) for x in c.points])
        e = mesh.edge_index(v[:-1], v[1:])
        assert np.all(e >= 0)
        ids.append(e)
        sig.append(np.full(len(e), c.sigma))
    return np.concatenate(ids), np.concatenate(sig)


CONVENTION_TAGS = {"index": lambda s: np.rint(4 * s), "negated": lambda s: -np.rint(4 * s),
                   "valence": lambda s: 4 - np.rint(4 * s)}


@pytest.mark.slow
@pytest.mark.mesher
@pytest.mark.parametrize("example", ["cylinder", "ball"])
def test_the_tag_convention_is_detected_and_a_wrong_one_refused(example, example_input, tet_mesh, tmp_path, capsys):
    """An example's curves routed along the edges of its session tet mesh
    (testkit.tetedge), written with each convention as .ovm and MEDIT .mesh:
    with no convention the one written is detected (the others break
    Poincare-Hopf), and each wrong explicit one is refused naming it."""
    from solver.__main__ import main
    from solver.io.tetnetwork import import_tet_network

    V, F, net = example_input(example)
    # meshes the session has already: test_examples' ball, this module's cylinder
    mesh = tet_mesh(example, **({"edge_length": 0.18} if example == "ball" else {"edge_length": H, "refine": 0}))
    interior = sorted(net.curves[i].sigma for i in net.interior_curves)
    edges, sigma = tet_edge_tags(V, F, net, mesh)
    for name, tag in CONVENTION_TAGS.items():
        t = tag(sigma).astype(np.int64)
        paths = [str(tmp_path / f"{example}-{name}.ovm"), str(tmp_path / f"{example}-{name}.mesh")]
        full = np.zeros(mesh.n_edges, np.int64)
        full[edges] = t
        write_ovm(paths[0], mesh, edge_props={"tag": full})
        write_medit(paths[1], mesh.vertices, mesh.tets, edges=mesh.edges[edges], edge_refs=t)
        for path in paths:
            imp = import_tet_network(path)
            assert imp.convention == name and imp.detected
            assert sorted(c.sigma for c in imp.network.curves) == interior
            assert f"'{name}' convention" in imp.describe() and "detected" in imp.describe()
            for wrong in CONVENTION_TAGS:
                if wrong != name:
                    with pytest.raises(NetworkError, match=f"read by the '{wrong}' tag convention .* the "
                                                           f"'{name}' convention"):
                        import_tet_network(path, wrong)
        assert main(["--tet-network", paths[1], "--check"]) == 0
        assert f"tags read by the '{name}' convention" in capsys.readouterr().out


def test_no_convention_fits_names_all_three(tmp_path):
    """Tags that fit no convention (one valence-3 axis alone through a box:
    its ends sum to 1/2, not the box's 2) are refused with each reading's
    result."""
    mesh = box_mesh(4)
    ids = [int(np.argmin(np.linalg.norm(mesh.vertices - 0.25 * np.array([2, 2, z]), axis=1))) for z in range(5)]
    tags = np.zeros(mesh.n_edges, np.int64)
    tags[mesh.edge_index(np.array(ids[:-1]), np.array(ids[1:]))] = 1
    path = str(tmp_path / "one.ovm")
    write_ovm(path, mesh, edge_props={"tag": tags})
    with pytest.raises(NetworkError, match=r"fit no tag convention.*'index'.*'negated'.*'valence'"):
        read_tet_network(path, sharp_angle=30)
