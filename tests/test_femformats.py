"""Hex meshes for simulation codes (issue 51): boundary patches, Gmsh MSH 4.1,
Abaqus/CalculiX .inp, Exodus II, Nastran bulk data, MED and hex .ovm, each
read back by its consumer: Gmsh (the gmsh package, built with MED) for .msh,
Nastran and MED, CalculiX (Debian's calculix-ccx, which ./dev.sh installs)
for .inp, VTK's Exodus reader, meshio's Nastran reader, and SymFrames' own
OpenVolumeMesh reader (OpenVolumeMesh itself: bench/crosscheck_ovm.py)."""

import os
import re
import shutil
import subprocess

import numpy as np
import pytest

from solver import hexmesh
from solver.io import export_hexmesh
from solver.io.femformats import write_hex_msh

# every test here solves, meshes or hex meshes an example: slow and mesher (CONTRIBUTING.md, Testing)
pytestmark = [pytest.mark.slow, pytest.mark.mesher]


def _with_patches(hm):
    """A hex mesh and its patches' outward normals and areas (per patch id)."""
    P, V = hm.patches, hm.vertices
    Q = V[P.quads]
    vec = 0.5 * np.cross(Q[:, 2] - Q[:, 0], Q[:, 3] - Q[:, 1])  # a bilinear quad's vector area
    normal = {i: vec[P.patch == i].sum(axis=0) for i in range(1, len(P.names) + 1)}
    area = {i: np.linalg.norm(vec[P.patch == i], axis=1).sum() for i in normal}
    return hm, normal, area


@pytest.fixture(scope="module")
def plate(solved):
    """The plate example's hex mesh, with its patches' normals and areas."""
    return _with_patches(hexmesh(solved("plate")))


@pytest.fixture(scope="module")
def l_prism_hole(solved):
    """An L-prism with a hole (testkit.hexnet.l_prism_with_hole: its network
    read off a block hex mesh), with its patches' normals and areas."""
    return _with_patches(hexmesh(solved("l_prism_hole")))


@pytest.fixture(scope="module", params=["plate", "l_prism_hole"])
def part(request):
    """Each part a format is proven on."""
    return request.getfixturevalue(request.param)


def test_patches_are_the_surfaces_faces(plate):
    """Seven patches: the four sides, the hole, the top and the bottom; every
    boundary quad in one, each patch's quads on one side of the plate."""
    hm, normal, area = plate
    P = hm.patches
    assert len(P.names) == 7 and set(np.unique(P.patch)) == set(range(1, 8))
    assert len(P.quads) == len(hm.boundary_quads())
    sides = sorted(i for i in normal if np.linalg.norm(normal[i]) > 0.99 * area[i])  # flat patches
    assert len(sides) == 6
    hole = [i for i in normal if i not in sides]
    assert len(hole) == 1 and np.linalg.norm(normal[hole[0]]) < 0.02 * area[hole[0]]  # a closed wall
    assert np.isclose(sum(area[i] for i in sides if abs(normal[i][2]) > 0.9), 2 * (4 - np.pi * 0.45**2), rtol=0.02)


def test_the_l_prism_with_a_hole_meshes_with_its_nine_patches(l_prism_hole):
    """The L-prism with a hole: a valid hex mesh whose irregular edges are
    its four curves, and nine patches: six flat sides, the top, the bottom
    and the hole's wall."""
    hm, normal, area = l_prism_hole
    r = hm.report
    assert r.valid and r.structure_exact and set(r.irregular) == {5}, r.summary()
    assert len(hm.patches.names) == 9 and len(hm.patches.quads) == len(hm.boundary_quads())
    flat = [i for i in normal if np.linalg.norm(normal[i]) > 0.99 * area[i]]
    assert len(flat) == 8
    caps = [i for i in flat if abs(normal[i][2]) > 0.99 * area[i]]
    assert len(caps) == 2 and np.isclose(area[caps[0]], 3.0 - np.pi * 0.1**2, rtol=0.02)
    wall = [i for i in normal if i not in flat]
    assert len(wall) == 1 and np.isclose(area[wall[0]], 2 * np.pi * 0.1 * 0.5, rtol=0.03)


@pytest.mark.parametrize("binary", [False, True])
def test_gmsh_reads_the_msh_with_its_groups(part, tmp_path, binary):
    import gmsh
    hm, _, _ = part
    path = str(tmp_path / "plate.msh")
    if binary:
        write_hex_msh(path, hm.vertices, hm.hexes, hm.patches, hm.irregular_edges, hm.irregular_valence, binary=True)
    else:
        assert export_hexmesh(hm, path) == [path]
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(path)
        names = {gmsh.model.getPhysicalName(d, t): (d, t) for d, t in gmsh.model.getPhysicalGroups()}
        npatch = len(hm.patches.names)
        assert set(names) == {"volume", "irregular_valence_5"} | {f"patch_{i}" for i in range(1, npatch + 1)}
        counts = {}
        for name, (d, t) in names.items():
            n = 0
            for e in gmsh.model.getEntitiesForPhysicalGroup(d, t):
                n += sum(len(x) for x in gmsh.model.mesh.getElements(d, e)[1])
            counts[name] = n
        assert counts["volume"] == len(hm.hexes)
        assert counts["irregular_valence_5"] == int(np.sum(hm.irregular_valence == 5)) > 0
        assert [counts[f"patch_{i}"] for i in range(1, npatch + 1)] == np.bincount(hm.patches.patch)[1:].tolist()
        _, tags, _ = gmsh.model.mesh.getElements(3)
        q = gmsh.model.mesh.getElementQualities(tags[0], "minSJ")  # Gmsh's own measure: every cell positive
        assert len(q) == len(hm.hexes) and q.min() > 0.3
    finally:
        gmsh.finalize()


def test_medit_carries_the_boundary_quads_with_their_patch(part, tmp_path):
    hm, _, _ = part
    path = str(tmp_path / "plate.mesh")
    export_hexmesh(hm, path)
    text = open(path).read()
    k = len(hm.patches.quads)
    block = text.split("Quadrilaterals\n", 1)[1].split("\n", k + 1)
    assert int(block[0]) == k
    rows = np.array([r.split() for r in block[1:k + 1]], np.int64)
    assert np.array_equal(rows[:, :4] - 1, hm.patches.quads) and np.array_equal(rows[:, 4], hm.patches.patch)


def _ccx():
    exe = shutil.which("ccx")
    assert exe, "CalculiX (ccx) is not installed: ./dev.sh test installs Debian's calculix-ccx"
    return exe


def test_calculix_runs_a_static_case_on_the_patches(part, tmp_path):
    """The plate held at its -y side (the node set of that patch), a pressure
    of 1 on its +y side (the element-face surface S_PATCH_k, *DSLOAD) and a
    force of 1 per node in x on the hole (its node set, *CLOAD): CalculiX
    solves it and the reaction at the held side balances the loads within
    1 %."""
    hm, normal, area = part
    held = min(normal, key=lambda i: normal[i][1] / area[i])
    pushed = max(normal, key=lambda i: normal[i][1] / area[i])
    hole = min(normal, key=lambda i: np.linalg.norm(normal[i]) / area[i])
    assert len({held, pushed, hole}) == 3
    export_hexmesh(hm, str(tmp_path / "plate.inp"))
    n_hole = len(np.unique(hm.patches.quads[hm.patches.patch == hole]))
    deck = ("*INCLUDE, INPUT=plate.inp\n*MATERIAL, NAME=STEEL\n*ELASTIC\n210000., 0.3\n"
            "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n"
            f"*BOUNDARY\nPATCH_{held}, 1, 3\n*STEP\n*STATIC\n"
            f"*DSLOAD\nS_PATCH_{pushed}, P, 1.0\n*CLOAD\nPATCH_{hole}, 1, 1.0\n"
            f"*NODE PRINT, NSET=PATCH_{held}, TOTALS=ONLY\nRF\n*END STEP\n")
    (tmp_path / "case.inp").write_text(deck)
    run = subprocess.run([_ccx(), "-i", "case"], cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0 and "*ERROR" not in run.stdout, run.stdout[-2000:]
    dat = (tmp_path / "case.dat").read_text()
    rf = np.array([float(x) for x in re.search(r"total force.*?\n\s*\n\s*(\S+)\s+(\S+)\s+(\S+)", dat).groups()])
    # a pressure pushes against the outward normal: the held side pulls back along it
    assert abs(rf[0] + n_hole) <= 0.01 * n_hole, (rf, n_hole)
    assert abs(rf[1] - normal[pushed][1]) <= 0.01 * abs(normal[pushed][1]), (rf, normal[pushed])
    assert abs(rf[2]) <= 0.01 * abs(normal[pushed][1])
    assert os.path.exists(tmp_path / "case.frd")


def test_poisson_converges_at_second_order_on_the_ball(solved):
    """A Poisson problem with a manufactured solution, -lap u = f in the ball
    with u given on its boundary, solved with trilinear hexahedra
    (scikit-fem) on SymFrames' hex meshes of one field at three cell sizes:
    the L2 error falls at order >= 1.8 in the mean cell size (volume /
    cells)^(1/3), the least-squares slope (measured at the sizes 0.2, 0.14,
    0.1 on five fields: 1.91-1.92 in it, 1.95-1.96 in the asked size).  In
    the asked size one CI run read 1.74, its error at 0.2 0.0105 against
    0.0122 on those five (the other two sizes alike): the cells were not
    the size asked, so the asked size is no h to measure an order by."""
    import meshio
    from skfem import Basis, BilinearForm, ElementHex1, Functional, LinearForm, condense
    from skfem import solve as fem_solve
    from skfem.helpers import dot, grad
    from skfem.io.meshio import from_meshio

    def exact(x):
        return np.sin(x[0]) * np.cos(1.3 * x[1]) * np.exp(0.5 * x[2])

    @BilinearForm
    def laplace(u, v, w):
        return dot(grad(u), grad(v))

    @LinearForm
    def load(v, w):
        return (1.0 + 1.69 - 0.25) * exact(w.x) * v  # -lap u for the u above

    @Functional
    def error2(w):
        return (w["uh"] - exact(w.x)) ** 2

    @Functional
    def volume(w):
        return 1.0 + 0.0 * w.x[0]

    res = solved("ball")
    h, err = [], []
    for cell in (0.2, 0.14, 0.1):
        hm = hexmesh(res, cell)
        mesh = from_meshio(meshio.Mesh(hm.vertices, [("hexahedron", hm.hexes)]))  # VTK's corner order to skfem's
        basis = Basis(mesh, ElementHex1())
        dofs = basis.get_dofs()
        u = np.zeros(basis.N)
        u[dofs] = exact(mesh.p[:, dofs])
        uh = fem_solve(*condense(laplace.assemble(basis), load.assemble(basis), x=u, D=dofs))
        err.append(np.sqrt(error2.assemble(basis, uh=basis.interpolate(uh))))
        h.append((volume.assemble(basis) / len(hm.hexes)) ** (1.0 / 3.0))
    order = np.polyfit(np.log(h), np.log(err), 1)[0]
    assert order >= 1.8, (h, err, order)



def test_vtk_reads_the_exodus_side_sets(part, tmp_path):
    """VTK's Exodus II reader (ParaView's) sees the hexahedra and one side set
    per patch, each with exactly the patch's boundary quads."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOExodus import vtkExodusIIReader

    hm, _, _ = part
    path = str(tmp_path / "plate.exo")
    assert export_hexmesh(hm, path) == [path]
    r = vtkExodusIIReader()
    r.SetFileName(path)
    r.UpdateInformation()
    n = r.GetNumberOfObjects(vtkExodusIIReader.SIDE_SET)
    assert n == len(hm.patches.names) and r.GetNumberOfObjects(vtkExodusIIReader.NODE_SET) == 1
    for i in range(n):
        r.SetObjectStatus(vtkExodusIIReader.SIDE_SET, i, 1)
    r.GenerateGlobalNodeIdArrayOn()
    r.Update()
    out = r.GetOutput()
    it = out.NewTreeIterator()
    it.InitTraversal()
    got = {}
    while not it.IsDoneWithTraversal():
        ds = it.GetCurrentDataObject()
        ids = vtk_to_numpy(ds.GetPointData().GetArray("GlobalNodeId")) - 1
        cells = vtk_to_numpy(ds.GetCells().GetConnectivityArray()).reshape(ds.GetNumberOfCells(), -1)
        got[it.GetCurrentMetaData().Get(out.NAME())] = ids[cells]
        it.GoToNextItem()
    assert np.array_equal(got["hexahedra"], hm.hexes)  # Exodus' HEX8 corner order is VTK's
    for i, name in enumerate(hm.patches.names, start=1):
        want = {tuple(sorted(q)) for q in hm.patches.quads[hm.patches.patch == i].tolist()}
        assert {tuple(sorted(q)) for q in got[name].tolist()} == want, name


def _gmsh_counts(path):
    """What Gmsh reads from path: {(dim, entity tag): elements}, {physical
    name: elements}, its minSJ per hexahedron, node tags and coordinates."""
    import gmsh

    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.open(path)
        entities = {(d, t): sum(len(x) for x in gmsh.model.mesh.getElements(d, t)[1])
                    for d, t in gmsh.model.getEntities() if d > 0}
        groups = {gmsh.model.getPhysicalName(d, t): sum(entities[(d, e)] for e in
                                                        gmsh.model.getEntitiesForPhysicalGroup(d, t))
                  for d, t in gmsh.model.getPhysicalGroups()}
        _, tags, _ = gmsh.model.mesh.getElements(3)
        q = gmsh.model.mesh.getElementQualities(tags[0], "minSJ")
        nodes, xyz, _ = gmsh.model.mesh.getNodes()
        return entities, groups, q, nodes, xyz.reshape(-1, 3)
    finally:
        gmsh.finalize()


def test_gmsh_and_meshio_read_the_nastran_bulk_data(part, tmp_path):
    """Gmsh reads the .bdf with every hexahedron positive (its own minSJ), in
    the volume of PSOLID 1, and each patch's boundary quads in the surface of
    its PSHELL (100 + k; Gmsh's Nastran reader makes entities of property
    ids, not physical groups); meshio reads the same cells back in the same
    corner order, and the coordinates keep 10 significant digits."""
    import meshio

    from solver.io.femformats import NASTRAN_PATCH_PID, NASTRAN_SOLID_PID

    hm, _, _ = part
    P = hm.patches
    path = str(tmp_path / "plate.bdf")
    assert export_hexmesh(hm, path) == [path]
    entities, groups, q, nodes, xyz = _gmsh_counts(path)
    per_patch = np.bincount(P.patch)[1:].tolist()
    assert entities == {(3, NASTRAN_SOLID_PID): len(hm.hexes),
                        **{(2, NASTRAN_PATCH_PID + i): n for i, n in enumerate(per_patch, start=1)}}
    assert len(q) == len(hm.hexes) and q.min() > 0.3
    scale = np.abs(hm.vertices).max()
    assert len(nodes) == len(hm.vertices)
    assert np.abs(xyz[np.argsort(nodes)] - hm.vertices).max() <= 1e-9 * scale
    m = meshio.read(path)
    blocks = {c.type: (c.data, ref) for c, ref in zip(m.cells, m.cell_data["nastran:ref"])}
    assert set(blocks) == {"hexahedron", "quad"} and len(m.cells) == 2  # each kind written in one run
    assert np.array_equal(blocks["hexahedron"][0], hm.hexes) and set(blocks["hexahedron"][1]) == {1}
    quads, refs = blocks["quad"]
    order = np.argsort(P.patch, kind="stable")
    assert np.array_equal(quads, P.quads[order]) and np.array_equal(refs, NASTRAN_PATCH_PID + P.patch[order])
    assert np.abs(m.points - hm.vertices).max() <= 1e-9 * scale
    text = open(path).read()
    assert text.count("PLOTEL") == len(hm.irregular_edges) + len(np.unique(hm.irregular_valence))  # and comments
    assert max(len(line) for line in text.splitlines()) <= 80


def test_gmsh_reads_the_med_with_its_groups(part, tmp_path):
    """Gmsh (built with MED) reads the .med with every hexahedron positive
    (MED's corner order is not VTK's: meshio's MED writer gets this wrong,
    and Gmsh reads its cells inverted), the patches and the irregular edges
    as named groups of the right sizes, and the coordinates exactly."""
    import gmsh

    gmsh.initialize()
    assert "Med" in gmsh.option.getString("General.BuildOptions").split()
    gmsh.finalize()
    hm, _, _ = part
    path = str(tmp_path / "plate.med")
    assert export_hexmesh(hm, path) == [path]
    _, groups, q, nodes, xyz = _gmsh_counts(path)
    assert groups == {"volume": len(hm.hexes), "irregular_valence_5": int(np.sum(hm.irregular_valence == 5)),
                      **{f"patch_{i}": n for i, n in enumerate(np.bincount(hm.patches.patch)[1:].tolist(), start=1)}}
    assert len(q) == len(hm.hexes) and q.min() > 0.3
    assert np.array_equal(xyz[np.argsort(nodes)], hm.vertices)


def test_med_without_h5py_is_refused_before_any_work(monkeypatch, tmp_path):
    import sys

    from solver.errors import OutputError
    from solver.io.hexformats import check_hex_path

    monkeypatch.setitem(sys.modules, "h5py", None)  # import h5py raises ImportError
    with pytest.raises(OutputError, match="h5py"):
        check_hex_path(str(tmp_path / "x.med"), "--hex")
    assert check_hex_path(str(tmp_path / "x.bdf")) == str(tmp_path / "x.bdf")


def _oriented_faces(H):
    """Per hexahedron, the set of its faces as loops out of it, each from its smallest corner."""
    from solver.hexmesh.quality import HEX_FACES

    F = H[:, HEX_FACES]
    r = np.argmin(F, axis=2)[..., None]
    F = np.take_along_axis(F, (r + np.arange(4)) % 4, axis=2)
    return [frozenset(map(tuple, f)) for f in F.tolist()]


def test_hex_ovm_reads_back_with_its_properties(part, tmp_path):
    """The hex .ovm read back (read_hex_ovm, which checks that each cell's six
    halffaces are one hexahedron's faces, all into the cell): the same
    vertices, the same hexahedra with the same orientation, the patch of every
    boundary face, the hexahedra around each edge (valence 5 exactly at the
    irregular edges inside), the scaled Jacobian; a flipped halfface and a tet
    file are refused."""
    from solver.errors import ReadError
    from solver.hexmesh.quality import HEX_EDGES
    from solver.io import read_hex_ovm
    from solver.io.ovm import OVM_HEX_FACES, read_ovm

    hm, _, _ = part
    P = hm.patches
    path = str(tmp_path / "plate.ovm")
    assert export_hexmesh(hm, path) == [path]
    d = read_hex_ovm(path)
    assert np.array_equal(d.vertices, hm.vertices) and d.tets.shape == (0, 4)
    assert _oriented_faces(d.hexes) == _oriented_faces(hm.hexes)
    patch = d.props["face"]["patch"]
    assert np.array_equal(np.bincount(patch, minlength=len(P.names) + 1)[1:], np.bincount(P.patch)[1:])
    assert np.sum(patch > 0) == len(P.quads)
    E = np.sort(hm.hexes[:, HEX_EDGES].reshape(-1, 2), axis=1)
    e, n = np.unique(E, axis=0, return_counts=True)
    assert np.array_equal(d.edges, e) and np.array_equal(d.props["edge"]["valence"], n)
    irregular = {tuple(x) for x in np.sort(hm.irregular_edges[hm.irregular_valence == 5], axis=1).tolist()}
    assert {tuple(x) for x in e[n == 5].tolist()} == irregular
    assert np.allclose(d.props["cell"]["scaled_jacobian"], hm.scaled_jacobian, rtol=0, atol=1e-15)
    assert OVM_HEX_FACES.tolist() == [0, 1, 4, 2, 5, 3]
    lines = open(path).read().split("\n")
    first = lines.index("Polyhedra") + 2
    cell = lines[first].split()
    cell[1] = str(int(cell[1]) ^ 1)  # the cell's first halfface turned out of it
    lines[first] = " ".join(cell)
    bad = str(tmp_path / "flipped.ovm")
    open(bad, "w").write("\n".join(lines))
    with pytest.raises(ReadError, match=rf"flipped.ovm:{first + 1}: cell 0: .* not the six faces of one hexahedron"):
        read_hex_ovm(bad)
    with pytest.raises(ReadError, match="face 0 has 4 halfedges; only tetrahedral meshes are supported"):
        read_ovm(path, ReadError)

