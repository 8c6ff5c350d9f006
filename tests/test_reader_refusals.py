"""Issue 52: the interchange readers (.hexex, .fra, .perm, .qtn) refuse
out-of-range ids, non-finite values and wrong counts with a ReadError naming
the file, the line and the value; an .ovm with several integer edge
properties that could hold the tags is refused, naming them, not read by a
silent choice."""

import numpy as np
import pytest

from solver import NetworkError, ReadError, io
from solver.io.cubecover import read_fra, read_perm
from solver.io.qtn import read_qtn

FRAME = "1 0 0\n0 1 0\n0 0 1\n"
TET = "0 1 2 3 " + "0 " * 12 + "\n"
VERTS = "4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"

CASES = [
    (".hexex", VERTS + "1\n0 1 2 7 " + "0 " * 12 + "\n", io.read_hexex, ":7:",
     "vertex ids 0 1 2 7: they must be whole numbers from 0 to 3"),
    (".hexex", VERTS + "1\n0 1 2.5 3 " + "0 " * 12 + "\n", io.read_hexex, ":7:", "2.5"),
    (".hexex", VERTS + "1\n0 1 -1 3 " + "0 " * 12 + "\n", io.read_hexex, ":7:", "-1"),
    (".hexex", VERTS.replace("0 0 1", "0 0 nan") + "1\n" + TET, io.read_hexex, ":5:", "'nan'"),
    (".hexex", VERTS + "1\n0 1 2 3 nan" + " 0" * 11 + "\n", io.read_hexex, ":7:", "'nan'"),
    (".hexex", VERTS + "1\n0 1 1 3 " + "0 " * 12 + "\n", io.read_hexex, ":7:", "repeats a vertex"),
    (".hexex", VERTS + "2\n" + TET, io.read_hexex, ":6:", "2 tets announced"),
    (".hexex", VERTS + "1\n" + TET + "9\n", io.read_hexex, ":8:", "after the last tet"),
    (".fra", "FRA 1\n1 3 1\n" + FRAME.replace("0 0 1", "0 0 inf"), read_fra, ":5:", "'inf'"),
    (".fra", "FRA 1\n2 3 1\n" + FRAME, read_fra, ":2:", "2 frames announced"),
    (".fra", "FRA 1\n1 2 1\n" + FRAME, read_fra, ":2:", "2 vectors per frame"),
    (".fra", "FRA 1\n1 3 1\n" + FRAME + "1 2 3\n", read_fra, ":6:", "after the last frame"),
    (".fra", "FRA x\n", read_fra, ":1:", "not a version-1 .fra"),
    (".perm", "PERM 1\n2 1 3\n0 2 1 2 3\n", read_perm, ":3:", "names a tet outside 0..1"),
    (".perm", "PERM 1\n2 1 3\n0 1 1 2 4\n", read_perm, ":3:", "not a signed permutation"),
    (".perm", "PERM 1\n2 1 3\n1 1 1 2 3\n", read_perm, ":3:", "matches a tet with itself"),
    (".perm", "PERM 1\n2 1 3\n0 1 1 nan 3\n", read_perm, ":3:", "'nan'"),
    (".qtn", "1 0 0 0\n0 0 0 0\n", read_qtn, ":2:", "zero length"),
    (".qtn", "1 0 0 nan\n", read_qtn, ":1:", "'nan'"),
    (".qtn", "1 0 0 0\n1 0\n", read_qtn, "", "6 numbers is not four per cell"),
]


@pytest.mark.parametrize("k", range(len(CASES)))
def test_interchange_readers_refuse_naming_file_line_and_value(tmp_path, k):
    ext, text, read, line, words = CASES[k]
    p = tmp_path / f"f{ext}"
    p.write_text(text)
    with pytest.raises(ReadError) as e:
        read(str(p))
    msg = str(e.value)
    assert msg.startswith(f"{p}{line}") and words in msg, msg


def test_the_readers_read_what_the_writers_write(tmp_path):
    from solver.io.cubecover import write_fra, write_perm
    from solver.io.hexformats import write_hexex
    from solver.io.qtn import write_qtn

    rng = np.random.default_rng(0)
    V, T, U = rng.normal(size=(5, 3)), np.array([[0, 1, 2, 3], [1, 2, 3, 4]]), rng.normal(size=(2, 4, 3))
    write_hexex(str(tmp_path / "m.hexex"), V, T, U)
    V2, T2, U2 = io.read_hexex(str(tmp_path / "m.hexex"))
    assert np.array_equal(V, V2) and np.array_equal(T, T2) and np.array_equal(U, U2)
    R = np.linalg.qr(rng.normal(size=(3, 3, 3)))[0]
    write_fra(str(tmp_path / "f.fra"), R)
    assert np.array_equal(read_fra(str(tmp_path / "f.fra")), R)
    write_perm(str(tmp_path / "f.perm"), 3, np.array([[0, 1], [1, 2]]), np.array([[2, -1, 3], [1, 2, 3]]), True)
    nt, pairs, perms = read_perm(str(tmp_path / "f.perm"))
    assert nt == 3 and pairs.tolist() == [[0, 1], [1, 2]] and perms.tolist() == [[2, -1, 3], [1, 2, 3]]
    q = np.array([[1.0, 0, 0, 0], [0.5, 0.5, 0.5, 0.5]])
    write_qtn(str(tmp_path / "f.qtn"), q)
    assert np.array_equal(read_qtn(str(tmp_path / "f.qtn")), q)


def test_an_ovm_with_two_tag_properties_is_refused_naming_both(tmp_path):
    from solver.io.ovm import write_ovm
    from solver.io.tetnetwork import import_tet_network
    from tests.meshes import box_mesh

    mesh = box_mesh(2)
    a = np.zeros(mesh.n_edges, np.int64)
    a[:3] = 1
    b = np.zeros(mesh.n_edges, np.int64)
    b[5] = 3
    path = str(tmp_path / "two.ovm")
    write_ovm(path, mesh, edge_props={"index": a, "valence": b})
    with pytest.raises(NetworkError, match=r"2 integer edge properties could hold the tags: 'index' \(3 nonzero "
                       r"edges\), 'valence' \(1 nonzero edges\).*--tag-property NAME"):
        import_tet_network(path)
