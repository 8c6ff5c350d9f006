"""Outputs checked before any work and written whole or not at all
(solver/io/atomic.py, issue 43): the command line refuses an output it
could not write before meshing, a write that fails half-way (a full disk)
leaves the old file or none and says so, -o writes exactly the path given."""

from __future__ import annotations

import errno
import os
import re

import numpy as np
import pytest

from solver import OutputError
from solver.io.atomic import check_output_path, write_files, write_text


@pytest.fixture
def no_meshing(monkeypatch):
    """Any meshing fails the test: a refusal must come before it."""
    import solver.pipeline

    def boom(*a, **k):
        raise AssertionError("meshing started")

    monkeypatch.setattr(solver.pipeline, "mesh_domain", boom)


def _cli(args, capsys):
    from solver.__main__ import main

    code = main(args)
    return code, capsys.readouterr().err


@pytest.mark.parametrize("kind", ["device", "folder", "missing folder", "folder is a file", "extension", "export",
                                  "export folder", "medit side file", "hex"])
def test_unwritable_outputs_are_refused_before_meshing(kind, tmp_path, capsys, no_meshing):
    (tmp_path / "afile").write_text("x")
    (tmp_path / "d.vtu").mkdir()
    (tmp_path / "m.fra").mkdir()
    out = ["-o", str(tmp_path / "r.npz")]
    args, match = {
        "device": (["-o", "/dev/full"], "/dev/full is a device"),
        "folder": (["-o", str(tmp_path)], "is a folder; give a file name inside it"),
        "missing folder": (["-o", str(tmp_path / "no" / "r.npz")], "does not exist; create it first"),
        "folder is a file": (["-o", str(tmp_path / "afile" / "r.npz")], "is a file, not a folder"),
        "extension": (["-o", str(tmp_path / "out.dat")], r"unknown format '\.dat'; the file name must end in \.npz"),
        "export": (out + ["--export", str(tmp_path / "x.stl")], r"unknown format '\.stl'"),
        "export folder": (out + ["--export", str(tmp_path / "d.vtu")], "d.vtu is a folder"),
        "medit side file": (out + ["--export", str(tmp_path / "m.mesh")], "m.fra is a folder"),
        "hex": (out + ["--hex", "/dev/full"], "/dev/full is a device"),
    }[kind]
    code, err = _cli(["--example", "cube", "-q"] + args, capsys)
    assert code == 1
    assert "Traceback" not in err
    assert re.search(match, err), err
    assert not os.path.exists("/dev/full.npz")
    assert sorted(os.listdir(tmp_path)) == ["afile", "d.vtu", "m.fra"]  # nothing written, no temporary left


def _full_disk(monkeypatch, after_bytes=0):
    """Writes fail with ENOSPC (when flushed to the disk)."""
    real = os.fsync

    def fsync(fd):
        if os.fstat(fd).st_size > after_bytes:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(fd)

    monkeypatch.setattr(os, "fsync", fsync)


def test_a_full_disk_leaves_the_old_file_and_no_partial_one(tmp_path, monkeypatch):
    path = tmp_path / "r.vtu"
    path.write_text("old")
    _full_disk(monkeypatch)
    with pytest.raises(OutputError, match=r"cannot write .*r\.vtu: the disk holding .* is full; free some space.*"
                                          "the old file is kept"):
        write_text(str(path), "new" * 1000)
    assert path.read_text() == "old"
    assert os.listdir(tmp_path) == ["r.vtu"]
    with pytest.raises(OutputError, match="no file was made"):
        write_text(str(tmp_path / "n.vtu"), "new" * 1000)
    assert os.listdir(tmp_path) == ["r.vtu"]


def test_files_that_go_together_are_written_all_or_none(tmp_path, monkeypatch):
    """MEDIT's .mesh + .fra + .perm: the third failing leaves none of them."""
    _full_disk(monkeypatch, after_bytes=100)
    files = {str(tmp_path / "a.mesh"): "m", str(tmp_path / "a.fra"): "f", str(tmp_path / "a.perm"): "p" * 1000}
    with pytest.raises(OutputError, match=r"a\.perm"):
        write_files(files)
    assert os.listdir(tmp_path) == []


@pytest.mark.slow
@pytest.mark.mesher
def test_a_full_disk_during_the_result_write_is_a_message(tmp_path, monkeypatch, cylinder_result):
    """The solve's last step: a disk that fills up while the .npz is written
    gives an OutputError (the command line prints it, exit 1), no partial file."""
    from solver import io

    _full_disk(monkeypatch)
    with pytest.raises(OutputError, match="is full"):
        io.save_result(str(tmp_path / "r.npz"), cylinder_result)
    assert os.listdir(tmp_path) == []


@pytest.fixture(scope="module")
def cylinder_result(solved):
    return solved("cylinder", edge_length=0.4, refine=0)


@pytest.mark.slow
@pytest.mark.mesher
def test_the_result_is_written_at_exactly_the_path_given(tmp_path, cylinder_result):
    from solver import io

    path = tmp_path / "result.npz"
    io.save_result(str(path), cylinder_result)
    assert os.listdir(tmp_path) == ["result.npz"]
    with np.load(path) as d:
        assert d["tets"].shape == cylinder_result.mesh.tets.shape


def test_check_output_path_names_the_format(tmp_path):
    with pytest.raises(OutputError, match=r"-o .*x\.dat: unknown format '\.dat'; the file name must end in \.npz, "
                                          r"e\.g\. x\.npz"):
        check_output_path(str(tmp_path / "x.dat"), "-o", (".npz",))
    with pytest.raises(OutputError, match="must be a file path"):
        check_output_path(None, "-o")
    assert check_output_path(str(tmp_path / "x.npz"), "-o", (".npz",)) == str(tmp_path / "x.npz")
    assert os.listdir(tmp_path) == []  # the probe file is gone


@pytest.mark.slow
@pytest.mark.mesher
def test_a_result_the_folder_refuses_after_the_solve_is_kept_elsewhere(tmp_path, monkeypatch, cylinder_result):
    """The folder passed the check but refuses the write when the solve is
    done: the result goes to the temporary folder, and the message says where."""
    import solver.__main__ as cli
    from solver import io

    real = io.save_result
    target = str(tmp_path / "r.npz")

    def refuse(path, result):
        if path == target:
            raise OutputError(f"cannot write {path}: permission denied")
        real(path, result)

    monkeypatch.setattr(io, "save_result", refuse)
    with pytest.raises(OutputError, match=r"permission denied; the result was saved to (\S+\.npz) instead") as e:
        cli._save_result(target, cylinder_result)
    spare = re.search(r"saved to (\S+\.npz) instead", str(e.value)).group(1)
    try:
        with np.load(spare) as d:
            assert d["tets"].shape == cylinder_result.mesh.tets.shape
    finally:
        os.remove(spare)
    assert os.listdir(tmp_path) == []
