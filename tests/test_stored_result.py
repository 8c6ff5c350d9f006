"""Issue 52: no output replaces an input or another output; a stored result
(--from-result) is read like every other reader -- damaged, foreign or
inconsistent files are refused naming the file and what is wrong, the
field's status is kept (exit 3), and -o / --export / --check are honoured
or refused; the hex settings are checked before any work."""

import io as pyio
import json
import os
import zipfile

import numpy as np
import pytest

from solver import ReadError, io
from solver.__main__ import EXIT_NO_HEX_MESH, EXIT_NOT_CONVERGED, main
from solver.examples import load_example


@pytest.fixture(scope="module")
def stored(stored_field):
    """A small solved field's result file, and its arrays (conftest)."""
    return stored_field[:2]


@pytest.fixture(scope="module")
def tagged(tmp_path_factory):
    """A tagged tet mesh (.mesh and .ovm): inputs for --tet-network."""
    from solver.io.medit import write_medit
    from solver.io.ovm import write_ovm
    from tests.meshes import box_mesh

    d = tmp_path_factory.mktemp("tagged")
    mesh = box_mesh(3)
    tags = np.full(mesh.n_edges, 4, np.int64)
    write_ovm(str(d / "t.ovm"), mesh, edge_props={"valence": tags})
    write_medit(str(d / "t.mesh"), mesh.vertices, mesh.tets, edges=mesh.edges[:0], edge_refs=tags[:0])
    return d


def _refused(capsys, argv, *words, code=1):
    capsys.readouterr()
    assert main(argv + ["-q"]) == code
    err = capsys.readouterr().err
    for w in words:
        assert w in err, err
    assert "Traceback" not in err
    return err


# ------------------------------------------------------------ outputs vs inputs


@pytest.mark.parametrize("name, flag", [("t.mesh", "--hex"), ("t.mesh", "--export"), ("t.ovm", "--export")])
def test_an_output_naming_the_tet_network_input_is_refused_and_the_input_kept(tagged, tmp_path, capsys, name, flag):
    src = tagged / name
    path = tmp_path / name
    path.write_bytes(src.read_bytes())
    before = path.read_bytes()
    _refused(capsys, ["--tet-network", str(path), flag, str(path)], f"{flag} {path}", "--tet-network input",
             "replace the input")
    assert path.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == [name]


def test_an_output_linked_to_an_input_is_refused(tmp_path, capsys):
    """A symbolic link (to the surface) and a hard link (to the tagged mesh):
    the same file under another name."""
    assert main(["--export-example", "cube", str(tmp_path)]) == 0
    obj = tmp_path / "cube.obj"
    before = obj.read_bytes()
    link = tmp_path / "out.vtu"
    os.symlink(obj, link)
    _refused(capsys, [str(tmp_path / "cube.json"), "--hex", str(link)], f"--hex {link}", "surface input",
             str(obj))
    _refused(capsys, [str(tmp_path / "cube.json"), "--export", str(link)], "--export", "surface input")
    assert obj.read_bytes() == before and os.path.islink(link)
    assert not (tmp_path / "cube.npz").exists()


def test_a_hard_link_to_the_tet_network_is_refused(tagged, tmp_path, capsys):
    src = tmp_path / "t.mesh"
    src.write_bytes((tagged / "t.mesh").read_bytes())
    os.link(src, tmp_path / "h.mesh")
    _refused(capsys, ["--tet-network", str(src), "--hex", str(tmp_path / "h.mesh")], "--tet-network input")
    assert src.read_bytes() == (tagged / "t.mesh").read_bytes()


@pytest.mark.parametrize("second", [["--hex", "X.vtu"], ["--export", "X.vtu"], ["-o", "X.npz", "--hex", "X.npz"]])
def test_two_outputs_naming_one_file_are_refused(tmp_path, capsys, second):
    argv = ["--example", "cube", "--export", str(tmp_path / "X.vtu")] + [
        str(tmp_path / a) if a.startswith("X") else a for a in second]
    err = _refused(capsys, argv, str(tmp_path / "X."))
    assert "name the same file" in err or "unknown format" in err
    assert not list(tmp_path.iterdir())


def test_a_medit_export_s_side_files_count_as_outputs(tmp_path, capsys):
    _refused(capsys, ["--example", "cube", "--export", str(tmp_path / "a.mesh"), "--hex", str(tmp_path / "a.mesh")],
             "name the same file")
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------ damaged result files


def _write(path, arrays):
    buf = pyio.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())
    return str(path)


def _damaged(arrays):
    """(label, arrays changed, words the refusal says)."""
    a = arrays
    T = a["tets"]
    yield "omega NaN", {"omega": np.full_like(a["omega"], np.nan)}, ["'omega'", "nan", "finite"]
    yield "omega zero", {"omega": np.zeros_like(a["omega"])}, ["omega does not carry the frames"]
    yield "omega row short", {"omega": a["omega"][:-1]}, ["'omega'", "shape"]
    yield "frames x2", {"frames": 2 * a["frames"]}, ["not rotations", "det 8"]
    yield "frames zero", {"frames": np.zeros_like(a["frames"])}, ["not rotations"]
    yield "frames reflected", {"frames": -a["frames"]}, ["not rotations"]
    yield "fractional tets", {"tets": T + 0.5}, ["'tets'", "whole numbers"]
    yield "tets out of range", {"tets": np.where(T == T.max(), len(a["vertices"]) + 5, T)}, ["'tets'", "run from 0"]
    yield "trace tets out of range", {"curve_tets": a["curve_tets"] + len(T)}, ["'curve_tets'", "tet ids run from 0"]
    yield "offsets", {"curve_faces_offsets": a["curve_faces_offsets"][::-1]}, ["'curve_faces_offsets'"]
    yield "no meta", {"meta": None}, ["'meta' is missing"]
    yield "meta not JSON", {"meta": np.array("{curves")}, ["'meta' is not JSON"]
    meta = json.loads(str(a["meta"]))
    meta["curves"][0]["sigma"] = "x"
    yield "meta sigma", {"meta": np.array(json.dumps(meta))}, ["curve 0", "sigma"]
    yield "vertices as text", {"vertices": a["vertices"].astype(str)}, ["'vertices'", "not floats"]
    yield "sharp short", {"surface_sharp": a["surface_sharp"][:-2]}, ["'surface_sharp'", "shape"]
    yield "root out of range", {"root": np.int64(len(a["vertices"]) + 3)}, ["'root'", "vertex id"]
    yield "Omega faces out of range", {"omega_faces": a["omega_faces"] + 10**7}, ["'omega_faces'", "face ids"]
    yield "Omega values short", {"omega_values": a["omega_values"][:-1]}, ["'omega_values'", "shape"]
    yield "feature vertices short", {"feature_vertices": a["feature_vertices"][:-1]}, ["'feature_vertices'"]
    yield "tube curve past the curves", {"tube_curve": a["tube_curve"] + 99}, ["'tube_curve'", "curve ids"]
    walk = a["curve_tets"].copy()
    walk[[1, 2]] = walk[[2, 1]]
    yield "a walk out of order", {"curve_tets": walk}, ["curve 0", "does not lie between the tets"]
    yield "an earlier layout", {"meta": None, "hex_meta": a["meta"]}, ["earlier SymFrames"]


@pytest.mark.slow
@pytest.mark.mesher
def test_damaged_result_files_are_refused_naming_file_and_fault(stored, tmp_path, capsys):
    _, arrays = stored
    out = tmp_path / "h.vtu"
    for k, (label, change, words) in enumerate(_damaged(arrays)):
        bad = {**arrays, **change}
        path = _write(tmp_path / f"bad{k}.npz", {n: v for n, v in bad.items() if v is not None})
        with pytest.raises(ReadError) as e:
            io.load_field(path)
        for w in [path] + words:
            assert w in str(e.value), (label, str(e.value))
        _refused(capsys, ["--from-result", path, "--hex", str(out)], path)
        assert not out.exists(), label


@pytest.mark.slow
@pytest.mark.mesher
def test_truncated_empty_and_foreign_files_are_refused(stored, tmp_path, capsys):
    path, _ = stored
    data = open(path, "rb").read()
    cases = {"truncated.npz": (data[: len(data) // 2], "damaged or truncated"),
             "empty.npz": (b"", "empty (0 bytes)"),
             "text.npz": (b"vertices 1 2 3\n", "not a NumPy .npz archive"),
             "array.npz": (None, "single NumPy array (.npy)")}
    for name, (content, words) in cases.items():
        p = tmp_path / name
        if content is None:
            np.save(open(p, "wb"), np.zeros(3))
        else:
            p.write_bytes(content)
        err = _refused(capsys, ["--from-result", str(p), "--hex", str(tmp_path / "h.vtu")], str(p), words)
        assert "Traceback" not in err
    # bytes damaged inside a member: its CRC or its compression fails
    raw = bytearray(data)
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo("omega.npy")
    mid = info.header_offset + 30 + len(info.filename) + info.compress_size // 2
    raw[mid:mid + 64] = bytes(64)
    p = tmp_path / "crc.npz"
    p.write_bytes(bytes(raw))
    _refused(capsys, ["--from-result", str(p), "--hex", str(tmp_path / "h.vtu")], str(p), "'omega' is damaged")
    _refused(capsys, ["--from-result", str(tmp_path / "none.npz"), "--hex", str(tmp_path / "h.vtu")], "no such file")
    assert not (tmp_path / "h.vtu").exists()


@pytest.mark.slow
@pytest.mark.mesher
def test_an_unused_member_is_never_read(stored, tmp_path):
    """A result with an extra member whose data are garbage (as an unused
    huge one would be expensive): only the arrays hex meshing needs are read."""
    path, arrays = stored
    p = tmp_path / "extra.npz"
    p.write_bytes(open(path, "rb").read())
    with zipfile.ZipFile(p, "a") as zf:
        zf.writestr("huge.npy", b"\x93NUMPY\x01\x00v\x00{'descr': '<f8', 'fortran_order': False, 'shape': "
                                b"(400000000000,), }" + b" " * 60 + b"\n" + b"garbage")
    inp = io.load_field(str(p))
    assert inp.mesh.n_tets == len(arrays["tets"]) and inp.status == "converged"


# ------------------------------------------------------------ status and flags


@pytest.mark.slow
@pytest.mark.mesher
def test_a_stored_field_that_did_not_converge_exits_3(stored, tmp_path, capsys):
    """The status the solve's report gives wins over hex data that say
    converged: exit 3 and no hex file, as --hex after the solve does."""
    _, arrays = stored
    report = json.loads(str(arrays["report"]))
    report.update(status="not converged", converged=False)
    path = _write(tmp_path / "nc.npz", {**arrays, "report": np.array(json.dumps(report))})
    out = tmp_path / "h.vtu"
    assert io.load_field(path).status == "not converged"
    _refused(capsys, ["--from-result", path, "--hex", str(out)], "not converged", "--mesh-unconverged",
             code=EXIT_NOT_CONVERGED)
    assert not out.exists()
    _refused(capsys, ["--from-result", path, "--check", "--hex", str(out)], "not converged", code=EXIT_NOT_CONVERGED)
    # asked explicitly: meshed and written, the exit status still 3, the report says so
    capsys.readouterr()
    argv = ["--from-result", path, "--hex", str(out), "--mesh-unconverged", "--no-smooth", "--cell-size", "0.3", "-q"]
    assert main(argv) == EXIT_NOT_CONVERGED
    text = capsys.readouterr()
    assert out.exists() and "meshed as asked" in text.out and "not converged" in text.err


@pytest.mark.slow
@pytest.mark.mesher
def test_from_result_honours_export_and_check_and_refuses_o(stored, solved, tmp_path, capsys):
    path, _ = stored
    capsys.readouterr()
    q = tmp_path / "s.qtn"
    assert main(["--from-result", path, "--export", str(q), "--export", str(tmp_path / "s.vtu"), "-q"]) == 0
    q2 = tmp_path / "r.qtn"
    io.export_field(solved("cylinder"), str(q2))
    assert q.read_bytes() == q2.read_bytes()  # the stored field's export is the solve's
    assert (tmp_path / "s.vtu").stat().st_size > 0
    assert main(["--from-result", path, "--check", "--hex", str(tmp_path / "h.vtu"), "--cell-size", "0.3"]) == 0
    assert "arrays are complete and consistent" in capsys.readouterr().out
    _refused(capsys, ["--from-result", path, "-o", str(tmp_path / "x.npz"), "--hex", str(tmp_path / "h.vtu")],
             "-o", "does not solve")
    _refused(capsys, ["--from-result", path, "--edge-length", "0.1", "--hex", str(tmp_path / "h.vtu")],
             "--edge-length", "does not solve")
    _refused(capsys, ["--from-result", path], "--hex FILE", "--export FILE", "--check")
    assert not (tmp_path / "h.vtu").exists() and not (tmp_path / "x.npz").exists()


# ------------------------------------------------------------ hex settings first


@pytest.mark.slow
@pytest.mark.mesher
@pytest.mark.parametrize("size", ["10", "1e-4", "1e-300"])
def test_a_cell_size_that_cannot_fit_is_refused_before_the_solve(tmp_path, capsys, size, stored):
    err = _refused(capsys, ["--example", "cube", "--hex", str(tmp_path / "h.vtu"), "--cell-size", size],
                   f"--cell-size {float(size):g}")
    assert "two cells thick" in err or "hexahedra (the limit is" in err
    assert not list(tmp_path.iterdir())  # no solve, no result
    _refused(capsys, ["--example", "cube", "--check", "--hex", str(tmp_path / "h.vtu"), "--cell-size", size],
             f"--cell-size {float(size):g}")
    _refused(capsys, ["--from-result", stored[0], "--hex", str(tmp_path / "h.vtu"), "--cell-size", size],
             f"--cell-size {float(size):g}")


def test_a_network_no_hex_mesh_can_have_is_refused_before_the_solve(tmp_path, capsys):
    from solver import Network

    V, F, net = load_example("cylinder")
    # two +1/2 axes instead of four +1/4: Poincare-Hopf holds, no hex mesh does
    curves = [type(c)(c.points, 0.5, name=f"half{k}") for k, c in enumerate(net.curves[:2])]
    io.write_obj(str(tmp_path / "c.obj"), V, F)
    io.write_network(str(tmp_path / "c.json"), Network(curves=curves, sharp_angle=net.sharp_angle), surface="c.obj")
    for extra in ([], ["--check"]):
        _refused(capsys, [str(tmp_path / "c.json"), "--hex", str(tmp_path / "h.vtu")] + extra,
                 "the network admits none", "curve 0 'half0' has index +0.5", "valence 2", code=EXIT_NO_HEX_MESH)
    assert sorted(os.listdir(tmp_path)) == ["c.json", "c.obj"]


def test_check_hex_says_the_hex_settings_fit(tmp_path, capsys):
    capsys.readouterr()
    assert main(["--example", "cube", "--check", "--hex", str(tmp_path / "h.vtu"), "--cell-size", "0.3"]) == 0
    out = capsys.readouterr().out
    assert "hex settings: cell size 0.3 fits the solid; no curve's index rules a hex mesh out" in out
    assert not list(tmp_path.iterdir())


@pytest.mark.mesher
def test_a_field_stopped_after_one_iteration_from_a_random_start_is_read_not_refused(solved, tmp_path, capsys):
    """Its omega is far from integrable, but the frames are developed from it
    along a spanning tree: the file is whole, its field not converged (exit 3,
    not a damaged file)."""
    res = solved("cube", edge_length=0.4, max_iterations=1, init="random")
    assert not res.report.converged
    path = str(tmp_path / "r.npz")
    io.save_result(path, res)
    assert io.load_field(path).status == "not converged"
    _refused(capsys, ["--from-result", path, "--hex", str(tmp_path / "h.vtu")], "not converged",
             code=EXIT_NOT_CONVERGED)
