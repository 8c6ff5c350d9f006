"""Exceptions raised for bad input.

Every error is a ``ValueError`` subclass whose message names the offending
element (curve, vertex, triangle) and says how to fix it, so the Blender
add-on can show it verbatim.
"""


class SymFramesError(ValueError):
    """Base class of all input errors."""


class SurfaceError(SymFramesError):
    """The boundary surface is not a closed, oriented, manifold, non-degenerate
    triangle mesh."""


class NetworkError(SymFramesError):
    """The curve network is malformed or does not fit the solid."""


class TopologyError(SymFramesError):
    """Indices violate Poincare-Hopf, or sharp features and singularities are
    inconsistent."""


class MeshingError(SymFramesError):
    """Tetrahedral meshing failed or produced a mesh that cannot be used."""


class OptionsError(SymFramesError):
    """A solver option (an Options field, a command-line flag or the network
    file's "options") has the wrong type or a value no solve can use; also
    an argument of a public function of the wrong type, shape or range."""


class OutputError(SymFramesError):
    """An output file cannot be written: its folder is missing or refuses
    the write, the path is a folder or a device, its extension is not a
    format SymFrames writes, or the disk filled up while writing (then the
    old file, or none, is left: never a partial one)."""


class ReadError(SymFramesError):
    """A file SymFrames reads back is not what its format says: a stored
    result (``--from-result``, ``io.load_field``) that is empty,
    truncated, not a NumPy archive, or lacks an array or holds one of the
    wrong type, shape or range (frames that are not rotations, a non-finite
    omega, an index past its mesh); an interchange file (``.hexex``,
    ``.fra``, ``.perm``, ``.qtn``) with a wrong count, a non-finite value or
    an id out of range.  The message names the file, the array or line, and
    the value."""


class Cancelled(Exception):
    """Raised inside a solve when the caller's cancel callback returns True."""


class HexMeshError(SymFramesError):
    """No valid hex mesh at these settings.  The message says why, where and
    what to change; ``kind`` says whose the limit is:

    * ``'network'``: the network admits no hex mesh, with the proof (an index
      whose edges would have valence 2 or less);
    * ``'settings'``: the cell size does not fit the solid;
    * ``'field'``: the field is not one a hex mesh can follow (it did not
      converge, or its transitions do not close as the network prescribes);
    * ``'map'``: SymFrames' map failed (a fold it could not undo, a rounding
      it could not keep apart): a limit of SymFrames, not a fault of the
      network.

    ``report`` (a hexmesh.HexReport, or None) holds the figures gathered
    before the stop.  ``finer`` says whether a field solved on a finer mesh
    may mesh (``python -m solver --hex`` and the add-on then solve again
    finer, where the resolution was automatic): False where the map fails
    so at any resolution (a smooth handle without singular curves)."""

    KINDS = ("network", "settings", "field", "map")

    def __init__(self, message: str, report=None, kind: str = "map", finer: bool = True):
        super().__init__(message)
        self.report = report
        self.kind = kind if kind in self.KINDS else "map"
        self.finer = bool(finer)
