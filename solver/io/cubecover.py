"""CubeCover's frame-field files: ``.fra`` tet frames and ``.perm`` face matchings.

A ``.mesh`` export (interchange.py) writes the MEDIT tet mesh (medit.py)
with a ``.fra`` and a ``.perm`` beside it: the three files CubeCover
(Nieser et al. 2011) reads.  The tet frames and face matchings they carry
are the field's (field/matchings.py, paper §5.5); CubeCover encodes a
matching, a cube symmetry, as a signed permutation of the axes
(``signed_permutation``, inverse ``permutation_matrix``).  Written by hand
with numpy; each writer's docstring states the format and the CubeCover
source it was checked against.  ``read_fra`` and ``read_perm`` read them
back, checking every value.
"""

from __future__ import annotations

import numpy as np

from ..errors import ReadError
from ..linalg.rotations import CUBE_GROUP
from .atomic import write_text
from .text import Tokens, format_rows


def signed_permutation(g: np.ndarray) -> np.ndarray:
    """CubeCover's encoding of cube symmetries: (n,) CUBE_GROUP indices ->
    (n, 3) int, entry i = s * (j + 1) when axis i of the first frame maps to
    s times axis j of the second (the column i of G[g] has s in row j)."""
    M = CUBE_GROUP[np.asarray(g)]
    j = np.argmax(np.abs(M), axis=1)  # (n, 3): row of the nonzero per column
    s = np.take_along_axis(M, j[:, None, :], axis=1)[:, 0, :]
    return (s * (j + 1)).astype(np.int64)


def permutation_matrix(p: np.ndarray) -> np.ndarray:
    """Inverse of ``signed_permutation``: (n, 3) entries +-(1..3) -> (n, 3, 3)."""
    p = np.asarray(p, dtype=np.int64).reshape(-1, 3)
    if np.any((np.abs(p) < 1) | (np.abs(p) > 3)) or np.any(np.sort(np.abs(p), axis=1) != [1, 2, 3]):
        raise ValueError("a permutation row must hold +-1, +-2, +-3, each magnitude once")
    M = np.zeros((len(p), 3, 3))
    n = np.arange(len(p))[:, None]
    M[n, np.abs(p) - 1, np.arange(3)[None, :]] = np.sign(p)
    return M


def write_fra(path: str, frames: np.ndarray) -> None:
    """Write per-tet frames as ``fra_text`` makes them."""
    write_text(path, fra_text(frames))


def fra_text(frames: np.ndarray) -> str:
    """Per-tet frames in CubeCover's ``.fra`` format::

        FRA 1
        ntets 3 1
        a0x a0y a0z          (3 lines per tet, in tet order: the frame's
        a1x a1y a1z           three axes, i.e. the columns of E)
        a2x a2y a2z

    The header line after ``FRA 1`` is ``#frames vectors-per-frame type``;
    CubeCover reads the type and ignores it, and its own writer puts 1.
    Checked against evouga/CubeCover src/ReadFrameField.cpp and
    src/WriteFrameFIeld.cpp.

    frames : (#T, 3, 3) float array, columns are the cross axes
    """
    F = np.asarray(frames, float)
    rows = np.transpose(F, (0, 2, 1)).reshape(-1, 3)  # axis k of tet t on row 3t + k
    return f"FRA 1\n{len(F)} 3 1\n" + format_rows(rows, "%.17g")


def read_fra(path: str) -> np.ndarray:
    """Per-tet frames of a ``.fra`` file with 3 vectors per tet -> (#T, 3, 3),
    the vectors as columns.

    Raises
    ------
    ReadError
        not a version-1 ``.fra``, a count that the file does not hold, a
        value that is not a finite number, or data after the last frame;
        naming the file, the line and the value
    """
    tok = Tokens.of_file(path, ReadError, ".fra (CubeCover frames)")
    if tok.next("'FRA'") != "FRA" or tok.next("the version") != "1":
        tok.fail("not a version-1 .fra file (it must start with 'FRA 1')", 0)
    n = tok.count("frames", 9)
    vpt = tok.count("vectors per frame", 0)
    if vpt != 3:
        tok.fail(f"{vpt} vectors per frame; only frames of 3 vectors are read", tok.pos - 1)
    tok.next("the frame type")
    vals = tok.block(3 * n, 3, "frame vectors")
    tok.end("the last frame")
    return np.transpose(vals.reshape(n, 3, 3), (0, 2, 1))


def write_perm(path: str, n_tets: int, tets: np.ndarray, perms: np.ndarray, keep_identity: bool = False) -> None:
    """Write face matchings as ``perm_text`` makes them."""
    write_text(path, perm_text(n_tets, tets, perms, keep_identity))


def perm_text(n_tets: int, tets: np.ndarray, perms: np.ndarray, keep_identity: bool = False) -> str:
    """Face matchings in CubeCover's ``.perm`` format::

        PERM 1
        ntets nfaces 3
        t0 t1 p0 p1 p2       (one line per listed interior face)

    t0, t1 are 0-based tets sharing the face; p_i = s * (j + 1) says that
    axis i of t0's frame corresponds to s times axis j of t1's frame
    (CubeCover's AssignmentGroup: ``to.row(j) ~ s * from.row(i)``).  Faces not
    listed have the identity matching; like CubeCover's own writer only
    non-identity faces are written unless ``keep_identity``.  CubeCover inverts
    the permutation itself when t0, t1 come in the other order than in its face
    table.  Checked against evouga/CubeCover src/ReadFrameField.cpp,
    src/FrameField.cpp (fromFramesAndAssignments), src/AssignmentGroup.cpp
    (parseFromPerm, operator*) and src/WriteFrameFIeld.cpp.

    tets : (k, 2) int, perms : (k, 3) int (``signed_permutation``)
    """
    tets = np.asarray(tets, np.int64).reshape(-1, 2)
    perms = np.asarray(perms, np.int64).reshape(-1, 3)
    if not keep_identity:
        keep = np.any(perms != [1, 2, 3], axis=1)
        tets, perms = tets[keep], perms[keep]
    return f"PERM 1\n{int(n_tets)} {len(tets)} 3\n" + format_rows(np.c_[tets, perms], "%d")


def read_perm(path: str) -> tuple[int, np.ndarray, np.ndarray]:
    """(#tets, (k, 2) tet pairs, (k, 3) signed permutations) of a ``.perm`` file.

    Raises
    ------
    ReadError
        not a version-1 ``.perm``, a count the file does not hold, a tet id
        outside 0..#tets-1, a face of a tet with itself, or a permutation
        that is not a signed permutation of 1, 2, 3; naming the file, the line
        and the value
    """
    tok = Tokens.of_file(path, ReadError, ".perm (CubeCover face matchings)")
    if tok.next("'PERM'") != "PERM" or tok.next("the version") != "1":
        tok.fail("not a version-1 .perm file (it must start with 'PERM 1')", 0)
    nt = tok.count("tets", 0)
    nf = tok.count("face lines", 5)
    nv = tok.count("assignments per face", 0)
    if nv != 3:
        tok.fail(f"{nv} assignments per face; only 3 are read", tok.pos - 1)
    first = tok.pos
    vals = tok.block(nf, 5, "face lines", "int")
    tok.end("the last face line")
    T, P = vals[:, :2], vals[:, 2:]
    line = tok.lines[first::5] if nf else tok.lines[:0]
    bad = np.nonzero(((T < 0) | (T >= nt)).any(axis=1))[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{line[bad[0]]}: face line {T[bad[0]].tolist()} names a tet outside 0..{nt - 1} "
                        f"(the header says {nt} tets; ids are 0-based)")
    bad = np.nonzero(T[:, 0] == T[:, 1])[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{line[bad[0]]}: face line {T[bad[0]].tolist()} matches a tet with itself")
    bad = np.nonzero(np.any(np.sort(np.abs(P), axis=1) != [1, 2, 3], axis=1))[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{line[bad[0]]}: the permutation {P[bad[0]].tolist()} is not a signed "
                        "permutation of 1, 2, 3 (each of +-1, +-2, +-3 once)")
    return nt, T, P

