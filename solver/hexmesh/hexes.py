"""What hex meshing hands back: ``HexMesh``, the cells with their report,
the integer-grid map they came from and their boundary patches, and the
mesh moved by an affine matrix (``HexMesh.transformed``)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .. import checks
from ..errors import OptionsError
from .patches import BoundaryPatches
from .quality import HEX_FACES, boundary_quads, scaled_jacobian
from .report import HexReport


@dataclass
class HexMesh:
    """A hexahedral mesh.

    Attributes
    ----------
    vertices : (n, 3) float array
    hexes : (m, 8) int array
        VTK_HEXAHEDRON corner order: corners (0,0,0), (1,0,0), (1,1,0),
        (0,1,0) of the cell's parameter cube, then the same at z = 1
    scaled_jacobian : (m,) float array
        Verdict's scaled Jacobian per cell (the minimum over its corners)
    report : HexReport
    irregular_edges : (k, 2) int array
        vertex pairs of the interior edges whose valence is not 4
    irregular_valence : (k,) int array
        their valences
    grid_map : tuple or None
        (tet vertices (n, 3), tets (t, 4), parameters (t, 4, 3)): the
        integer-grid map the hexes were extracted from (written as .hexex)
    patches : patches.BoundaryPatches or None
        the boundary quads, each with its cell, local face and the input
        surface's patch (its regions between sharp edges), which the
        simulation formats write as groups (.msh physical groups, .inp
        surfaces and sets, MEDIT refs); None where the surface is unknown
    """

    vertices: np.ndarray
    hexes: np.ndarray
    scaled_jacobian: np.ndarray
    report: HexReport
    irregular_edges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    irregular_valence: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    grid_map: tuple | None = None
    patches: BoundaryPatches | None = None

    def boundary_quads(self) -> np.ndarray:
        """The boundary faces.

        Returns
        -------
        (k, 4) int array
            faces held by one cell, oriented outward
        """
        return boundary_quads(self.hexes)[0]

    def transformed(self, matrix) -> HexMesh:
        """The mesh moved by a 4 x 4 affine matrix (a Blender object's
        ``matrix_world``): its vertices (and its map's tet vertices) mapped,
        the scaled Jacobian measured again (a non-uniform scale changes it).
        A mirror (negative determinant) reorders each cell's corners so that
        none is inside out; its integer-grid map is then dropped (a map
        cannot be mirrored with its parameters kept).

        Parameters
        ----------
        matrix : (4, 4) array-like

        Returns
        -------
        HexMesh

        Raises
        ------
        OptionsError
            a matrix that is not 4 x 4 and finite, or whose 3 x 3 part is
            singular
        """
        M = checks.array("matrix", matrix, OptionsError, shape=(4, 4))
        A, t = M[:3, :3], M[:3, 3]
        det = float(np.linalg.det(A))
        if not abs(det) > 1e-12 * max(float(np.abs(A).max()) ** 3, 1e-300):
            raise OptionsError(f"matrix: its 3 x 3 part is singular (determinant {det:.3g}): it would flatten the "
                               "hex mesh")
        V = self.vertices @ A.T + t
        H, P, gm = self.hexes, self.patches, self.grid_map
        if det < 0:
            H = H[:, MIRROR_CORNERS]
            gm = None
            if P is not None:
                P = replace(P, quads=P.quads[:, ::-1], faces=MIRROR_FACES[P.faces])
        elif gm is not None:
            gm = (gm[0] @ A.T + t, gm[1], gm[2])
        return replace(self, vertices=V, hexes=H, scaled_jacobian=scaled_jacobian(V, H), grid_map=gm, patches=P)


MIRROR_CORNERS = np.array([0, 3, 2, 1, 4, 7, 6, 5])
"""A VTK hexahedron's corners with its first two parameter axes swapped:
the cell the right way out again after a mirror."""
MIRROR_FACES = np.array([[j for j in range(6) if set(HEX_FACES[j]) == set(MIRROR_CORNERS[HEX_FACES[k]])][0]
                         for k in range(6)])
"""The local face (of quality.HEX_FACES) of a mirrored cell that each face
of the original lands on."""
