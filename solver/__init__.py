"""SymFrames solver: Symmetric Moving Frames (Corman & Crane 2019) in numpy/scipy.

No bpy anywhere in this package.  Typical use::

    from solver import Network, Curve, solve
    result = solve(V, F, Network(curves=[...], sharp_angle=30), edge_length=0.1)
    result.frames        # (#V, 3, 3) one rotation per tet-mesh vertex
    result.quaternions() # (#V, 4) w, x, y, z
    print(result.report.summary())

See README.md for the sign convention of the index sigma and the file formats.
"""

from .errors import Cancelled, MeshingError, NetworkError, OptionsError, SurfaceError, SymFramesError, TopologyError
from .network.network import Curve, Network, Role, Torsion
from .pipeline import FieldProblem, Options, Result, solve
from .report import Report

__all__ = [
    "Cancelled",
    "Curve",
    "FieldProblem",
    "MeshingError",
    "Network",
    "NetworkError",
    "Options",
    "OptionsError",
    "Report",
    "Result",
    "Role",
    "SurfaceError",
    "SymFramesError",
    "TopologyError",
    "Torsion",
    "solve",
]
