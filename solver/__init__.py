"""SymFrames solver: Symmetric Moving Frames (Corman & Crane 2019) in numpy/scipy.

No bpy anywhere in this package.  Typical use::

    from solver import Network, Curve, solve
    result = solve(V, F, Network(curves=[...], sharp_angle=30), edge_length=0.1)
    result.frames        # (#V, 3, 3) one rotation per tet-mesh vertex
    result.quaternions() # (#V, 4) w, x, y, z
    print(result.report.summary())

The public API is what this module exports, plus ``solver.io`` (file
formats) and ``solver.examples`` (the built-in example solids and networks,
``load_example`` and ``EXAMPLES``); the Blender add-on imports nothing else.

* Solving: ``solve``, ``FieldProblem`` (mesh once, solve repeatedly;
  ``solve_resolved`` solves it, and once more finer where the automatic
  mesh left the network unresolved; ``solve_finer`` solves a field again
  finer for a hex map that needs it),
  ``Options``, ``Result``, ``Report``; ``SolvedField`` is a solved field
  as one value (``Result.field``; ``SolvedField.to_arrays`` /
  ``SolvedField.from_arrays`` store it, ``io.load_field`` reads a result
  file's), what hex meshing, the exports and the measures take; ``check`` runs a solve's validation,
  curve repair and resolution plan without meshing (``CheckResult``).
* Input: ``Curve``, ``Network``, ``Role``, ``Torsion``.
* Measuring a field (§5.2): ``monodromy_angles``, ``regular_face_mask``,
  ``singular_faces`` (``SingularFaces``), ``vertex_normal_adaptation``.
* Showing a field (§5.5): ``FrameField`` (frames interpolated inside tets),
  ``sample_glyphs``, ``seed_points``, ``trace_streamlines``.
* Hex meshing (docs/hexmesh.md): ``hexmesh`` makes a pure hex mesh of a
  solved field (``HexMesh``, its ``HexReport`` and its ``BoundaryPatches``)
  with ``HexOptions`` (cell size, ``DEFAULT_HEXES`` cells by default, up to
  ``MAX_HEXES``; smoothing; ``FinerNear``: smaller cells near chosen patches
  and curves); ``default_cell_size``.  ``HexInput``, ``hex_source_arrays`` and
  ``input_from_arrays`` are the earlier names of ``SolvedField`` and its
  arrays, kept for one release.
* No network yet (docs/suggest.md): ``suggest_network`` suggests one for a
  closed surface (a padded polycube), with its ``SuggestReport``.
* Errors: ``SymFramesError`` and its subclasses (``HexMeshError`` when no
  valid hex mesh exists at the settings, ``OutputError`` when a file
  cannot be written, ``ReadError`` when a stored result or interchange file
  is damaged); ``Cancelled``.

See README.md for the sign convention of the index sigma and docs/usage.md for the file formats.
"""

from .analysis.measures import (
    SingularFaces,
    monodromy_angles,
    regular_face_mask,
    singular_faces,
    vertex_normal_adaptation,
)
from .analysis.streamlines import FrameField, sample_glyphs, seed_points, trace_streamlines
from .errors import (
    Cancelled,
    HexMeshError,
    MeshingError,
    NetworkError,
    OptionsError,
    OutputError,
    ReadError,
    SurfaceError,
    SymFramesError,
    TopologyError,
)
from .field.solved import SolvedField
from .hexmesh import (
    DEFAULT_HEXES,
    MAX_HEXES,
    BoundaryPatches,
    FinerNear,
    HexInput,
    HexMesh,
    HexOptions,
    HexReport,
    default_cell_size,
    hex_source_arrays,
    hexmesh,
    input_from_arrays,
)
from .network.network import Curve, Network, Role, Torsion
from .pipeline import FieldProblem, Options, Result, solve, solve_finer, solve_resolved
from .precheck import CheckResult, check
from .report import Report
from .suggest import SuggestReport, suggest_network

__all__ = [
    "DEFAULT_HEXES",
    "MAX_HEXES",
    "Cancelled",
    "CheckResult",
    "Curve",
    "FieldProblem",
    "FinerNear",
    "FrameField",
    "HexInput",
    "BoundaryPatches",
    "HexMesh",
    "HexMeshError",
    "HexOptions",
    "HexReport",
    "MeshingError",
    "Network",
    "NetworkError",
    "Options",
    "OptionsError",
    "OutputError",
    "ReadError",
    "Report",
    "Result",
    "SolvedField",
    "SuggestReport",
    "Role",
    "SingularFaces",
    "SurfaceError",
    "SymFramesError",
    "TopologyError",
    "Torsion",
    "check",
    "default_cell_size",
    "hex_source_arrays",
    "hexmesh",
    "input_from_arrays",
    "monodromy_angles",
    "regular_face_mask",
    "sample_glyphs",
    "seed_points",
    "singular_faces",
    "solve",
    "solve_finer",
    "solve_resolved",
    "suggest_network",
    "trace_streamlines",
    "vertex_normal_adaptation",
]
