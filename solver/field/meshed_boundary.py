"""The boundary field of the tet mesh (§3): the pipeline's boundary stage.

The input's sharp features and corner turns are carried onto the boundary
of the tet mesh, the curves' ends give the singular boundary triangles,
the 2D field is solved there (boundary2d.py) and the turns around the
solid's handles settled (handles.py).  Two refusals follow, before the
volume solve would spend its iterations on data no field satisfies:

* a curve whose tangent axis the surface frames cannot carry from one end
  to the other (``check_carried``, mesh/linking.py);
* boundary triangles where the 3D lift of the 2D field turns by a spurious
  quarter turn (``check_lift``; folded boundary triangles made them).
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshingError, TopologyError
from ..mesh.embed import Embedding
from ..mesh.linking import misaligned_curves
from ..mesh.tetmesh import TetMesh
from ..network.network import PreparedNetwork
from ..surface.corners import transfer_quarters
from ..surface.features import FeatureGraph, check_poincare_hopf, transfer_features
from .boundary2d import BoundaryField, lift_mismatch, solve_boundary_field
from .handles import settle_handle_turns


def meshed_boundary_field(mesh: TetMesh, embedding: Embedding, network: PreparedNetwork, features: FeatureGraph,
                          edge_length: float) -> BoundaryField:
    """The 2D cross field on the tet mesh's boundary and its lift (§3).

    Parameters
    ----------
    mesh : TetMesh
        The tet mesh; its boundary carries the field.
    embedding : mesh.embed.Embedding
        The network traced through the mesh (curve ends on the boundary).
    network : network.network.PreparedNetwork
        The curves, for their indices and the messages.
    features : surface.features.FeatureGraph
        The input surface's sharp edges and corner quarters.
    edge_length : float
        The mesh's edge length, quoted in the messages.

    Returns
    -------
    BoundaryField
        On ``mesh.boundary`` (its #bV vertices and #bF triangles).

    Raises
    ------
    MeshingError
        The mesh lost a sharp feature or a curve end, or its boundary
        is folded where the field is lifted to 3D.
    TopologyError
        A curve the surface frames cannot follow (``check_carried``).
    """
    B = mesh.boundary
    if np.any(features.sharp):
        sharp = transfer_features(features, B)
    else:
        sharp = np.zeros(len(B.edges), bool)
    # the corner quantisation chosen on the input (corners.py), not a
    # new rounding of the remeshed boundary's angles
    G = transfer_quarters(features, FeatureGraph(B, sharp))
    fs = np.zeros(len(B.F))
    ends = embedding.boundary_end_faces
    if ends:
        loc = np.searchsorted(mesh.boundary_faces, [f for f, _ in ends])
        np.add.at(fs, loc, [s for _, s in ends])
    try:
        check_poincare_hopf(B, G, fs, "the meshed boundary")
        G.check_patches(fs)
    except TopologyError as e:
        raise MeshingError(f"the mesh did not preserve the sharp features or curve ends ({e}); try a smaller "
                           f"edge length (now {edge_length:.4g})") from None
    override = _end_tangents(mesh, embedding)
    bf = solve_boundary_field(B, G, fs, normal_override=override)
    # loops that bound in the solid: their turns must be what the
    # singular curves through the spanning chain prescribe (field/handles.py)
    bf = settle_handle_turns(mesh, embedding, bf, lambda turns: solve_boundary_field(
        B, G, fs, generator_turns=turns, normal_override=override))
    check_carried(mesh, embedding, network, bf)
    check_lift(mesh, bf, edge_length)
    return bf


def _end_tangents(mesh: TetMesh, embedding: Embedding) -> dict[int, np.ndarray]:
    """Boundary vertex -> the unit tangent of the curve ending on a triangle
    of it.  At a curve's end the frame is adapted to the curve tangent: the
    monodromy of the boundary data around the end triangle is then a
    quarter turn about the same axis as in the tube just inside (with the
    vertex normals it would differ by ~ tube radius / curvature radius, like
    a kink of the singular curve at the surface)."""
    B = mesh.boundary
    override = {}
    for tr in embedding.traces:
        P = tr.polyline
        for f, t in ((tr.start_face, P[0] - P[1]), (tr.end_face, P[-1] - P[-2])):
            if f < 0:
                continue
            t = t / np.linalg.norm(t)
            for v in B.F[np.searchsorted(mesh.boundary_faces, f)]:
                override[int(v)] = t
    return override


def check_carried(mesh: TetMesh, embedding: Embedding, network: PreparedNetwork, bf: BoundaryField) -> None:
    """Refuse a curve whose tangent axis the frames on the surface cannot
    carry from one end to the other, with no singular curve between it and
    the surface (mesh/linking.py): no cross field is adapted to it (LM
    ended at its cap with a penalty of 1e4 on a smooth torus).

    Raises
    ------
    TopologyError
        Naming the first such curve, where it meets the surface, and the
        others refused.
    """
    bad = misaligned_curves(mesh, embedding, [c.sigma for c in network.curves], bf.E0, bf.features.sharp)
    if not bad:
        return

    def label(j):
        c = network.curves[j]
        return f"curve {network.source[j]}" + (f" '{c.name}'" if c.name else "")

    i, a, b, cos = bad[0]
    pa, pb = (", ".join(f"{x:.4g}" for x in mesh.vertices[v]) for v in (a, b))
    how = "reversed" if cos < -0.5 else "across the curve"
    raise TopologyError(
        f"{label(i)} meets the surface at ({pa}) and ({pb}), and the frame axis along it, carried over the "
        f"surface from one end to the other, arrives {how}: the frames have the curve's tangent as an axis "
        f"and are adapted to the surface, so no cross field follows this curve unless a singular curve "
        f"passes between it and the surface (on one smooth part of the surface the normal stays one axis: "
        f"a curve across the tube of a smooth torus, or U-shaped under one face, cannot be followed). Mark "
        f"sharp edges between its ends (sharp_angle or 'sharp' curves), end it elsewhere, or add the "
        f"singular curves that let the field turn (curves refused: {', '.join(label(j) for j, *_ in bad)})")


class FoldedLiftError(MeshingError):
    """The boundary field does not lift to 3D on some boundary triangles of
    the tet mesh (check_lift): its surface is folded there."""


def check_lift(mesh: TetMesh, bf: BoundaryField, edge_length: float) -> None:
    """Refuse boundary data the volume solve cannot satisfy: triangles where
    the 3D lift of the boundary field turns by a spurious quarter turn
    (folded boundary triangles made them; LM then ends at its cap with a
    penalty of 1e4 or more).

    Raises
    ------
    FoldedLiftError
        With the number of such triangles and where the worst one is.
    """
    B = mesh.boundary
    d = lift_mismatch(B, bf)
    bad = np.nonzero(d > np.pi / 4)[0]
    if len(bad):
        c = B.V[B.F[bad[np.argmax(d[bad])]]].mean(axis=0)
        raise FoldedLiftError(
            f"the boundary cross field could not be lifted to 3D on {len(bad)} boundary triangle(s) near "
            f"({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g}): the tet mesh's surface is probably folded there (a "
            f"curve tube or feature close to the surface). Try another edge length (now {edge_length:.4g})")
