"""A stored result's field read back (``--from-result``), checked like
every other reader.

``load_field(path)`` opens the ``.npz`` as a zip archive and reads the
field's arrays (``SolvedField.to_arrays``), each member's header (dtype,
shape) before its data, so an unused member, however large, is never read;
the arrays are checked by field/arrays.py.  Whatever is wrong -- an empty, truncated or
foreign file, a damaged member, a missing or inconsistent array -- is a
``ReadError`` naming the file and what is wrong.
"""

from __future__ import annotations

import os
import zipfile
import zlib

import numpy as np

from ..errors import ReadError
from ..field.arrays import ArraySource, read_field
from ..field.solved import SolvedField


class _Archive(ArraySource):
    """The members of an open .npz, read one at a time, header first."""

    def __init__(self, path: str, zf: zipfile.ZipFile):
        super().__init__(path, "this file cannot be meshed again: solve the network again to write a new result "
                               "(python -m solver NETWORK.json -o FILE.npz)")
        self.zf = zf
        self.names = {n[:-4]: n for n in zf.namelist() if n.endswith(".npy")}

    def _read(self, key: str, data: bool):
        try:
            with self.zf.open(self.names[key]) as fh:
                if data:
                    return np.lib.format.read_array(fh, allow_pickle=False)
                version = np.lib.format.read_magic(fh)
                read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
                    np.lib.format.read_array_header_2_0
                return read_header(fh)
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError) as e:
            raise self.fail(f"the array '{key}' is damaged ({type(e).__name__}: {str(e)[:100]})") from None

    def _header(self, key: str):
        if key not in self.names:
            return None
        shape, _, dtype = self._read(key, False)
        return shape, dtype, self.zf.getinfo(self.names[key]).file_size

    def _data(self, key: str) -> np.ndarray:
        return self._read(key, True)


def open_archive(path) -> zipfile.ZipFile:
    """The zip archive at path, or a ReadError saying what the file is."""
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise ReadError(f"result file {path!r}: must be a file path (a non-empty string)")
    path = os.fspath(path)
    if not os.path.exists(path):
        raise ReadError(f"{path}: no such file; give a result .npz written by a solve (-o FILE.npz)")
    if os.path.isdir(path):
        raise ReadError(f"{path}: is a folder; give a result .npz written by a solve (-o FILE.npz)")
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as fh:
            head = fh.read(4)
        if size == 0:
            raise ReadError(f"{path}: the file is empty (0 bytes); give a result .npz written by a solve")
        if head != b"PK\x03\x04":
            kind = "a single NumPy array (.npy)" if head[:4] == b"\x93NUM" else f"a file starting with {head!r}"
            raise ReadError(f"{path}: not a NumPy .npz archive (it is {kind}); give a result .npz written by a solve")
        return zipfile.ZipFile(path)
    except zipfile.BadZipFile as e:
        raise ReadError(f"{path}: a damaged or truncated .npz archive ({e}: its zip directory, written last, is "
                        f"missing or broken; {size:,} bytes); solve the network again to write a new result") from None
    except OSError as e:
        raise ReadError(f"{path}: cannot be read ({e.strerror or e})") from None


def load_field(path):
    """The solved field of a saved result, to mesh or export it again
    without solving (``python -m solver --from-result``), read and checked
    (module docs).

    Parameters
    ----------
    path : str
        a result ``.npz`` written by ``save_result``

    Returns
    -------
    field.solved.SolvedField
        its ``status`` 'converged' or 'not converged' (the stricter of the
        field's and the solve report's)

    Raises
    ------
    ReadError
        naming the file, the array and what is wrong with it
    """
    with open_archive(path) as zf:
        return SolvedField(**read_field(_Archive(os.fspath(path), zf)))


load_hex_input = load_field
"""The earlier name of ``load_field``, removed in the next release."""
