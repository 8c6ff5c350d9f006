"""AlgoHex's ``.qtn`` frames: one quaternion per tet, in cell order.

A ``.qtn`` export (interchange.py) writes the tet frames as unit
quaternions ``w x y z``, one line per cell in the tet order of the
``.ovm``/``.mesh``/``.vtu`` written with it (AlgoHex
``--cell-quaternion-in-path``).  ``read_qtn`` reads them back, checking
every value; ``quaternion_frames`` turns quaternions (a ``.qtn``'s, or the
add-on's stored ones) into frames.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import ReadError
from .atomic import write_text
from .text import Tokens, format_rows


def write_qtn(path: str, quaternions: np.ndarray) -> None:
    """Write AlgoHex's ``.qtn``: one unit quaternion ``w x y z`` per cell, in
    cell order, no header (AlgoHex reads whitespace-separated numbers, four per
    cell: cgg-bern/AlgoHex demo/HexMeshing/HexMeshing.cc load_cell_quaternions
    and src/AlgoHex/SingularGraphExtractionT_impl.hh).  AlgoHex's frame axis i
    is ``q * e_i``, the i-th column of the rotation matrix, as here.  The cell
    order is the tet order of the ``.ovm``/``.mesh``/``.vtu`` written with it."""
    write_text(path, format_rows(np.asarray(quaternions, float), "%.17g"))


def read_qtn(path: str) -> np.ndarray:
    """(n, 4) quaternions w, x, y, z of a ``.qtn`` file.

    Raises
    ------
    ReadError
        a value that is not a finite number, a count that is not four per
        cell, or a quaternion of zero length; naming the file, line and value
    """
    tok = Tokens.of_file(path, ReadError, ".qtn (AlgoHex quaternions)")
    if len(tok) % 4:
        raise ReadError(f"{tok.path}: {len(tok)} numbers is not four per cell (w x y z); the file is truncated or "
                        f"has extra data (line {tok.line(len(tok) - 1)})")
    q = tok.block(len(tok) // 4, 4, "quaternions")
    norm = np.linalg.norm(q, axis=1)
    bad = np.nonzero(norm < 1e-9)[0]
    if len(bad):
        raise ReadError(f"{tok.path}:{tok.lines[4 * bad[0]]}: quaternion {bad[0]} is {q[bad[0]].tolist()}: of zero "
                        "length, no rotation")
    return q


def quaternion_frames(q: np.ndarray) -> np.ndarray:
    """Frames of quaternions, as ``.qtn`` files and the add-on store them.

    Parameters
    ----------
    q : (n, 4) float array
        Quaternions w, x, y, z; normalised here, so any nonzero length will do.

    Returns
    -------
    (n, 3, 3) float array
        Rotation matrices, columns the cross axes.

    Raises
    ------
    OptionsError
        q not (n, 4) finite numbers, or a quaternion of zero length
    """
    from .. import checks
    from ..errors import OptionsError

    q = checks.array("quaternions", q, OptionsError, shape=(None, 4))
    zero = np.nonzero(np.linalg.norm(q, axis=1) < 1e-12)[0]
    if len(zero):
        raise OptionsError(f"quaternion {zero[0]} is {q[zero[0]].tolist()}: of zero length, no rotation")
    return Rotation.from_quat(np.asarray(q, float), scalar_first=True).as_matrix()

