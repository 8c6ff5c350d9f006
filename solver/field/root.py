"""Where the development starts (§4.3): a root vertex and its frame.

omega fixes the frames only up to one rotation, which the root's frame
sets.  The root is a boundary vertex, whose frame the boundary field gives:

* a sharp-feature vertex, whose frame is fixed (Eq. 20 leaves it no turn);
* else the first boundary vertex with an adaptation angle alpha, turned
  about its normal by its solved alpha (``normal_root``) and, for a solved
  x, by the turn that makes the developed field a consistent cross field
  (``symmetric_root``, develop.symmetric_turn).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..linalg.rotations import exp_so3
from ..mesh.embed import Embedding
from ..mesh.tetmesh import TetMesh
from .boundary2d import BoundaryField
from .constraints import AffineOmega
from .develop import develop, symmetric_turn


def node_region_edges(mesh: TetMesh, embedding: Embedding) -> np.ndarray:
    """The edges of node-region tets.  Their faces carry no structure
    equation, so a tree path through them (or around them) would not be
    integrable; the development reaches those vertices last.

    Parameters
    ----------
    mesh : TetMesh
    embedding : mesh.embed.Embedding

    Returns
    -------
    (#E,) bool array
    """
    out = np.zeros(mesh.n_edges, bool)
    nr = embedding.node_region_tets
    if len(nr):
        out[mesh.tet_edges[nr].reshape(-1)] = True
    return out


def default_root(mesh: TetMesh, constraints: AffineOmega, boundary: BoundaryField, x: np.ndarray | None = None,
                 avoid_edges: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """The root of the development of a solution x (module docs).

    Parameters
    ----------
    mesh : TetMesh
    constraints : constraints.AffineOmega
        omega = c + P x, and which boundary vertex holds which alpha.
    boundary : boundary2d.BoundaryField
        E0 and the normals of the #bV boundary vertices.
    x : (n,) float array or None
        The solved unknowns; None for the frame before any solve (E0 of
        the root).
    avoid_edges : (#E,) bool array or None
        Edges the development takes last (``node_region_edges``).

    Returns
    -------
    root : int
        A boundary vertex of the mesh.
    E_root : (3, 3) float array
        Its frame, columns the cross axes.
    """
    fixed = constraints.fixed_frame_vertices
    if len(fixed):
        r = int(fixed[0])
        return r, boundary.E0[np.searchsorted(mesh.boundary_vertices, r)]
    if x is None:
        return normal_root(mesh, constraints, boundary, None)
    return symmetric_root(mesh, constraints, boundary, x, avoid_edges)


def symmetric_root(mesh: TetMesh, constraints: AffineOmega, boundary: BoundaryField, x: np.ndarray,
                   avoid_edges: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """``normal_root`` turned about the root's normal so that the developed
    field is a consistent cross field (develop.symmetric_turn).  Parameters
    and returns as ``default_root``."""
    r, E = normal_root(mesh, constraints, boundary, x)
    omega = constraints.omega(x)
    frames = develop(mesh, omega, r, E, avoid_edges)
    n = boundary.normals[np.searchsorted(mesh.boundary_vertices, r)]
    axis = int(np.argmax(np.abs(E.T @ n)))
    theta = symmetric_turn(mesh, omega, frames, axis, avoid_edges)
    return r, E @ exp_so3(theta * np.eye(3)[axis])


def normal_root(mesh: TetMesh, constraints: AffineOmega, boundary: BoundaryField,
                x: np.ndarray | None = None) -> tuple[int, np.ndarray]:
    """The first boundary vertex with an alpha (Eq. 20), its frame E0 turned
    about its normal by its alpha in x (not turned for x None).  Parameters
    and returns as ``default_root``."""
    cons = constraints
    bv = mesh.boundary_vertices
    loc = int(np.argmax(cons.alpha_column >= 0)) if np.any(cons.alpha_column >= 0) else 0
    r = int(bv[loc])
    E = boundary.E0[loc]
    col = cons.alpha_column[loc]
    if x is not None and col >= 0:
        # adding one constant to every alpha of a boundary component
        # leaves omega unchanged (Eq. 20 only sees alpha differences), so
        # measure the root's alpha from the component's mean: the frames
        # then do not depend on where the solve started
        B = mesh.boundary
        n = len(B.V)
        adj = sp.coo_matrix((np.ones(len(B.edges)), (B.edges[:, 0], B.edges[:, 1])), shape=(n, n))
        _, comp = connected_components(adj, directed=False)
        same = (comp == comp[loc]) & (cons.alpha_column >= 0)
        alpha = x[col] - float(np.mean(x[cons.alpha_column[same]]))
        E = exp_so3(alpha * boundary.normals[loc]) @ E
    return r, E
