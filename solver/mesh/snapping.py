"""Put the tet mesh's boundary back onto the input's sharp features.

fTetWild keeps its surface within an envelope of the input but does not keep
sharp edges as mesh edges: along a crease it often leaves thin triangles
whose corners lie on the two sides of the edge (chamfers), tilted by tens of
degrees.  The frames are adapted to those normals (§4.2.2), so a chamfer
twists the field next to the edge (an L-shaped prism: 5-18 degrees off the
axes, where the exact field is constant).

After the sharp edges have been mapped to the mesh (features.transfer_features),
each boundary vertex is moved to its place on the input:

- a corner of the mapped feature graph to the nearest input corner,
- another vertex of a mapped sharp edge to the nearest point of an input
  sharp edge,
- any other boundary vertex to the nearest point of the input patch (the
  faces bounded by sharp edges) its mesh patch lies on,

unless the move is long (a quarter of the mean boundary edge) or shrinks a
tet below a tenth of its volume; such moves are undone, the latter
repeatedly until every tet keeps its volume.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..errors import TopologyError
from ..network.curves import CurveGeometry
from ..surface.features import FeatureGraph, feature_polylines, transfer_features
from ..surface.trisurface import TriSurface
from .tetmesh import TetMesh


@dataclass
class SnapStats:
    moved: int = 0            # boundary vertices moved
    reverted: int = 0         # moves undone to keep tets' volumes
    too_far: int = 0          # moves not made: longer than the limit
    max_move: float = 0.0     # longest move made
    kept: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # vertices left off their place


def closest_on_features(X: np.ndarray, src: FeatureGraph) -> np.ndarray:
    """Closest point of each of X (k, 3) on the sharp edges of src, chain by
    chain (curves.CurveGeometry)."""
    best_d = np.full(len(X), np.inf)
    best_p = X.copy()
    for verts, closed in feature_polylines(src):
        P = src.S.V[np.r_[verts, verts[:1]] if closed else verts]
        g = CurveGeometry(P, closed)
        seg, t, d = g.closest(X)
        better = d < best_d
        best_d[better], best_p[better] = d[better], g.point(seg[better], t[better])
    return best_p


def _chain_ends(G: FeatureGraph) -> np.ndarray:
    """Feature vertices where chains of sharp edges end or turn a corner."""
    end = (G.degree > 0) & (G.degree != 2)
    end[G.corners] = True
    return np.nonzero(end)[0]


def boundary_targets(B: TriSurface, sharp: np.ndarray, src: FeatureGraph) -> np.ndarray:
    """Where each vertex of the mesh boundary B belongs on the input surface
    src.S, given B's mapped sharp edges (see the module docstring)."""
    S = src.S
    target = B.V.copy()
    dst = FeatureGraph(B, sharp)
    # non-feature vertices: onto the input patch their mesh patch lies on
    npd, pd = dst.patches
    nps, ps = src.patches
    _, fid, _ = S.closest_points(B.V[B.F].mean(axis=1))
    votes = np.zeros((npd, nps))
    np.add.at(votes, (pd, ps[fid]), B.face_areas)
    match = votes.argmax(axis=1)
    vpatch = np.full(len(B.V), -1)
    vpatch[B.F.reshape(-1)] = np.repeat(pd, 3)
    plain = dst.degree == 0
    for p in range(npd):
        verts = np.nonzero(plain & (vpatch == p))[0]
        if len(verts) == 0:
            continue
        patch = TriSurface(S.V, S.F[ps == match[p]])
        _, _, target[verts] = patch.closest_points(B.V[verts])
    # feature vertices: corners to corners, the others onto the sharp edges
    feat = np.nonzero(dst.degree > 0)[0]
    if len(feat):
        target[feat] = closest_on_features(B.V[feat], src)
        ends_src, ends_dst = _chain_ends(src), _chain_ends(dst)
        if len(ends_src) and len(ends_dst):
            _, j = cKDTree(S.V[ends_src]).query(B.V[ends_dst])
            target[ends_dst] = S.V[ends_src[j]]
    return target


def snap_to_features(mesh: TetMesh, src: FeatureGraph, max_move: float = 0.25,
                     min_volume_ratio: float = 0.1) -> tuple[TetMesh, SnapStats]:
    """The mesh with its boundary moved onto the input surface and its sharp
    features (module docstring).  ``max_move`` is relative to the mean
    boundary edge length.  Returns the mesh unchanged when the input has no
    sharp edges."""
    stats = SnapStats()
    if not np.any(src.sharp):
        return mesh, stats
    B = mesh.boundary
    try:
        sharp = transfer_features(src, B)
    except TopologyError:
        # the features could not be mapped: leave the mesh as it is, the
        # boundary stage reports this with its hint
        return mesh, stats
    target = boundary_targets(B, sharp, src)
    move = target - B.V
    length = np.linalg.norm(move, axis=1)
    limit = max_move * np.linalg.norm(B.V[B.edges[:, 1]] - B.V[B.edges[:, 0]], axis=1).mean()
    far = length > limit
    stats.too_far = int(far.sum())
    move[far] = 0.0
    bv = mesh.boundary_vertices
    wanted = np.zeros(mesh.n_vertices, bool)
    wanted[bv] = (length > 0) & ~far
    P0 = mesh.vertices
    vol0 = TetMesh._signed_volumes(P0, mesh.tets)
    active = wanted.copy()
    delta = np.zeros_like(P0)
    delta[bv] = move
    while True:
        P = P0 + np.where(active[:, None], delta, 0.0)
        vol = TetMesh._signed_volumes(P, mesh.tets)
        bad = vol < min_volume_ratio * vol0
        undo = np.unique(mesh.tets[bad])
        undo = undo[active[undo]]
        if len(undo) == 0:
            break
        active[undo] = False
        stats.reverted += len(undo)
    stats.moved = int(active.sum())
    stats.kept = np.r_[bv[far], np.nonzero(wanted & ~active)[0]]
    stats.max_move = float(np.linalg.norm(delta[active], axis=1).max()) if stats.moved else 0.0
    return TetMesh(P, mesh.tets.copy()), stats
