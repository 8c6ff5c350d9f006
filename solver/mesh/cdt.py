"""TetGen: a constrained Delaunay tet mesh of a clean closed surface.

fTetWild (tetwild.py) remeshes any triangle soup inside an envelope, which
makes it robust and slow: ~2 s for the 11k-tet L prism, 8-13 s for the ball
and cylinder at the default budget, most of end to end.  TetGen (the mesher
the paper used, §5.1) takes a surface that does not intersect itself and
keeps it exactly (its triangles split, never moved): 0.1-0.6 s for the same
surfaces.  The network needs no tubes in the mesh: embed.py traces every
curve through whatever tets it crosses (dual paths: docs/how-it-works.md, *Embedding the network*), and
the solves with and without tubes agree (ball: 0 omega-matched spurious or
missing faces, tangent adaptation 0.05 degrees, penalty 0.14).

TetGen is AGPL-3.0.  GPL-3.0-or-later code may be combined with it (GPLv3
section 13), but the extension would then ship a second licence with a
network clause, so the extension does not bundle it: the solver uses it
where the ``tetgen`` package is installed (requirements.txt installs it for
the command line, the API and the tests) and ``Options.mesher`` allows it
('auto', the default, takes it for networks without singular curves on
surfaces no denser than the mesh: ``wants_tetgen``).  fTetWild meshes everything else, and wherever TetGen
fails or its mesh's boundary differs from the surface (meshing.py).  TetGen carves only what lies
outside the outer surface: the tets it puts in a cavity are dropped here (``_carve_cavities``).
Like fTetWild it runs in a child process (tetwild.run_tetwild): TetGen aborts the process on some inputs (seen:
overlapping facets), which must not take the host application down.
"""

from __future__ import annotations

import importlib.util

import numpy as np

from ..errors import MeshingError
from ..surface.trisurface import TriSurface
from .resolution import TETS_PER_H3
from .tetmesh import TetMesh
from .tetwild import _normalisation, run_tetwild

# the budget's density, which a volume bound of 2 h^3 / 15 gives (mean volume ~ half the bound)
VOLUME_BOUND = 2.0 / TETS_PER_H3
# 'auto' takes TetGen only for a surface with at most this many times the
# triangles of an h-mesh of it (wants_tetgen)
TETGEN_DENSITY = 3.0


def tetgen_available() -> bool:
    return importlib.util.find_spec("tetgen") is not None


def tetrahedralize_cdt(surface: TriSurface, edge_length: float, cancel=None) -> TetMesh:
    """TetGen's quality mesh of the solid bounded by ``surface`` at a target
    edge length (volume bound VOLUME_BOUND * h^3), in normalised
    coordinates like fTetWild.  Raises MeshingError when TetGen is missing
    or fails."""
    if not tetgen_available():
        raise MeshingError("TetGen is not installed (pip install tetgen); use the default mesher, fTetWild")
    used = np.unique(surface.F)
    remap = np.full(len(surface.V), -1, np.int64)
    remap[used] = np.arange(len(used))
    V, F = surface.V[used], remap[surface.F]
    centre, unit = _normalisation(surface)
    h = edge_length / unit
    P, T = run_tetwild((V - centre) / unit, F, h, 0.0, cancel=cancel, tetgen_volume=VOLUME_BOUND * h**3)
    if len(T) == 0:
        raise MeshingError("TetGen produced no tetrahedra")
    P, T = np.asarray(P, float) * unit + centre, np.asarray(T, np.int64)
    if surface.n_components > 1:
        P, T = _carve_cavities(surface, P, T)
    if len(T) == 0:
        raise MeshingError("TetGen produced no tetrahedra inside the solid")
    mesh = TetMesh(P, T)
    vol = mesh.tet_volumes
    if np.any(vol <= 0):
        raise MeshingError(f"TetGen produced {int(np.sum(vol <= 0))} inverted or flat tetrahedra")
    return mesh


def _carve_cavities(surface: TriSurface, P: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """TetGen carves only what lies outside the outer surface: the tets it
    puts inside a cavity (an inner component oriented into it) are dropped
    here, by the winding number of their centroids (1 in the solid, 0 in a
    cavity; TetGen keeps the surface's triangles, so no tet straddles one),
    and the vertices only they used."""
    inside = surface.winding_number(P[T].mean(axis=1)) > 0.5
    T = T[inside]
    used = np.unique(T)
    remap = np.full(len(P), -1, np.int64)
    remap[used] = np.arange(len(used))
    return P[used], remap[T]


def wants_tetgen(surface: TriSurface, edge_length: float, singular_curves: bool = False) -> bool:
    """Whether Options.mesher 'auto' takes TetGen: it is installed, the
    network has no singular curves, and the surface has no more than
    TETGEN_DENSITY times the triangles of an h-mesh of it.

    * Singular curves: fTetWild meshes the curve tubes (tubes.py) into rings
      of vertices around each curve, across whose edges the field turns by
      < 45 degrees; a TetGen mesh has no tubes, edges pass close to the
      curves, and closest-rotation matching (what a tool reading only the
      frames computes) puts the singularity in a neighbouring face: on the
      ball 79% of the pierced faces were singular, against > 85% required
      by tests/test_examples.py (omega-matched: all of them, 0 spurious).
    * Density: TetGen keeps every input vertex, so a dense scan would mesh
      far past the tet budget; fTetWild's mesh need not keep them."""
    if singular_curves or not tetgen_available():
        return False
    per_h_mesh = float(surface.face_areas.sum()) / (np.sqrt(3.0) / 4.0 * edge_length**2)
    return len(surface.F) <= TETGEN_DENSITY * max(per_h_mesh, 1.0)
