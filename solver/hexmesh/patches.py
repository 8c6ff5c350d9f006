"""Boundary patches of a hex mesh: its boundary quads grouped by the input
surface's patches, for the boundary conditions of a simulation.

A *patch* of the surface is a connected region of its triangles bounded by
sharp edges (a face of a CAD part); a smooth closed component with no sharp
edge is one patch.  Each boundary quad of the hex mesh takes the patch of the
surface triangle nearest its centre (a valid hex mesh keeps the sharp edges,
so no quad straddles two patches).  Patches are numbered from 1 in the order
of the surface's triangles, and named ``patch_1``, ``patch_2``, ...

The quads also carry the cell that holds them and that cell's local face, for
formats that name a boundary face by (element, face): Abaqus/CalculiX ``S1``
to ``S6`` (``ABAQUS_FACE``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..surface.trisurface import TriSurface
from .quality import HEX_FACES, boundary_faces

ABAQUS_FACE = np.array([1, 2, 3, 4, 5, 6])
"""The Abaqus/CalculiX C3D8 face number (S1..S6) of each of quality.HEX_FACES:
S1 = nodes 1-2-3-4, S2 = 5-8-7-6, S3 = 1-5-6-2, S4 = 2-6-7-3, S5 = 3-7-8-4,
S6 = 4-8-5-1 (1-based, VTK's corner order, which C3D8 shares)."""


@dataclass
class BoundaryPatches:
    """The boundary quads of a hex mesh and their patches.

    Attributes
    ----------
    quads : (k, 4) int array
        boundary faces, oriented outward (vertex ids of the hex mesh)
    cells : (k,) int array
        the hexahedron holding each quad
    faces : (k,) int array
        its local face, 0..5 in the order of ``quality.HEX_FACES``
    patch : (k,) int array
        the patch id of each quad, 1..len(names)
    names : list of str
        the patches' names, ``names[i - 1]`` for id i
    """

    quads: np.ndarray
    cells: np.ndarray
    faces: np.ndarray
    patch: np.ndarray
    names: list


def surface_patches(S: TriSurface, sharp: np.ndarray) -> np.ndarray:
    """(#F,) patch id per surface triangle, 1-based: the connected regions of
    triangles across edges that are not sharp, numbered in the order of
    their first triangle."""
    ef = S.edge_faces[~np.asarray(sharp, bool)]
    n = len(S.F)
    A = sp.coo_matrix((np.ones(len(ef)), (ef[:, 0], ef[:, 1])), shape=(n, n))
    _, comp = connected_components(A, directed=False)
    _, first = np.unique(comp, return_index=True)
    order = np.argsort(np.argsort(first))  # component -> rank of its first triangle
    return order[comp] + 1


def boundary_patches(S: TriSurface, sharp: np.ndarray, V: np.ndarray, H: np.ndarray) -> BoundaryPatches:
    """The boundary quads of the hex mesh (V, H) with their cells, local
    faces and surface patches (module docs)."""
    H = np.asarray(H, np.int64)
    one, _ = boundary_faces(H)
    cells, faces = one // 6, one % 6
    quads = H[cells[:, None], HEX_FACES[faces]]
    tri_patch = surface_patches(S, sharp)
    n = int(tri_patch.max()) if len(tri_patch) else 0
    if len(quads):
        _, f, _ = S.closest_points(np.asarray(V, float)[quads].mean(axis=1))
        patch = tri_patch[f]
    else:
        patch = np.zeros(0, np.int64)
    return BoundaryPatches(quads, cells, faces, patch, [f"patch_{i}" for i in range(1, n + 1)])
