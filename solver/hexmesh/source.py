"""Names of the hex stage's input kept for one release: a solved field is
one value now, ``field.solved.SolvedField`` (``Result.field``), and these
are that value under their earlier names.

- ``HexInput`` is ``SolvedField``;
- ``hex_source_arrays(f)`` is ``f.to_arrays()``;
- ``input_from_arrays(mesh, frames, omega, arrays)`` is
  ``SolvedField.from_arrays`` of those arrays with the mesh, frames and
  omega put in.
"""

from __future__ import annotations

import numpy as np

from ..errors import OptionsError
from ..field.solved import SolvedField, field_fault
from ..mesh.tetmesh import TetMesh

HexInput = SolvedField

__all__ = ["HexInput", "field_fault", "hex_source_arrays", "input_from_arrays"]


def hex_source_arrays(field: SolvedField) -> dict:
    """``field.to_arrays()`` (the earlier name; removed in the next release).

    Parameters
    ----------
    field : SolvedField

    Returns
    -------
    dict of str to numpy array
        the field's one layout (field/solved.py)
    """
    if not isinstance(field, SolvedField):
        raise OptionsError(f"hex_source_arrays: {type(field).__name__} is not a SolvedField (Result.field)")
    return field.to_arrays()


def input_from_arrays(mesh: TetMesh, frames: np.ndarray, omega: np.ndarray, arrays: dict) -> SolvedField:
    """``SolvedField.from_arrays`` of ``arrays`` with the mesh, frames and
    omega put in (the earlier name; removed in the next release).

    Parameters
    ----------
    mesh : TetMesh
        the field's tet mesh
    frames : (#V, 3, 3) float array
    omega : (#E, 3) float array
    arrays : dict
        the rest of ``SolvedField.to_arrays()``

    Returns
    -------
    SolvedField

    Raises
    ------
    ReadError
        an array missing, of the wrong type, shape or range (named)
    """
    if not isinstance(mesh, TetMesh):
        raise OptionsError(f"input_from_arrays: mesh is a {type(mesh).__name__}, not a TetMesh (the field's tet mesh)")
    return SolvedField.from_arrays({**arrays, "vertices": mesh.vertices, "tets": mesh.tets, "frames": frames,
                                    "omega": omega}, "input_from_arrays")
