"""Does a triangle surface bound one solid?  ``validate_surface`` checks, in
order: array shapes and finiteness, index range, size, degenerate triangles,
closed and manifold edges, consistent orientation, manifold vertices,
self-intersections and contacts (intersect.py), and the nesting and
orientation of its components (one solid, cavities inward); the first
problem found is refused with a ``SurfaceError`` that says where it is and
how to fix it.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from ..errors import SurfaceError
from .intersect import find_crossing_or_contact
from .trisurface import TriSurface


def _fmt(p) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in p) + ")"


def validate_surface(V: np.ndarray, F: np.ndarray, check_intersections: bool = True) -> TriSurface:
    """Check that (V, F) bounds a solid; raise SurfaceError saying what to fix.

    Checks, in order: array shapes and finiteness, index range, degenerate
    triangles, every edge shared by exactly two triangles, consistent
    orientation, manifold vertices, self-intersections and outward
    orientation (cavities inward).

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    check_intersections : bool
        Look for triangles that cross or touch (the slowest check).

    Returns
    -------
    TriSurface

    Raises
    ------
    SurfaceError
        Naming the first problem found, where it is and how to fix it.
    """
    V, F = _surface_arrays(V, F)
    _check_size(V, F)
    S = TriSurface(V, F)
    _check_degenerate(S)
    _check_closed(S)
    _check_orientation(S)
    _check_manifold_vertices(S)
    # intersections first: nesting below is only meaningful without them
    if check_intersections:
        _check_intersections(S)
    _check_nesting(S)
    return S


def _is_complex(V) -> bool:
    """Complex vertex coordinates (an array, or lists holding complex numbers)."""
    if isinstance(V, np.ndarray):
        return np.iscomplexobj(V)
    if isinstance(V, (list, tuple)):
        return any(isinstance(x, (complex, np.complexfloating)) for row in V if isinstance(row, (list, tuple))
                   for x in row)
    return False


# coordinates beyond this overflow squared distances and volumes (1e200**2 = inf)
MAX_COORDINATE = 1e100


MIN_EXTENT = 1e-50
"""A surface smaller than this across underflows the geometry: a small
triangle's area (a product of two lengths) or a tet's volume (of three)
rounds to 0 long before the double range ends (1e-308)."""


FLAT_RATIO = 1e-9
"""A surface thinner than this fraction of its size along an axis is flat:
no tet mesh or field fits in it."""


def _check_size(V: np.ndarray, F: np.ndarray) -> None:
    """Refuse a surface of no size or too small for floating-point geometry,
    saying its size and the scale that would fix it."""
    P = V[np.unique(F)]
    ext = float(np.ptp(P, axis=0).max())
    if ext == 0:
        raise SurfaceError(f"the surface has no size: all its {len(P)} vertices are at {P[0].tolist()}; give the "
                           "surface of a solid")
    ptp = np.ptp(P, axis=0)
    flat = np.nonzero(ptp <= FLAT_RATIO * ext)[0]
    if len(flat):
        axes = " and ".join("xyz"[i] for i in flat)
        raise SurfaceError(f"the surface is flat: {ext:.4g} across but {float(ptp[flat[0]]):.3g} along {axes}, so it "
                           "bounds (almost) no volume (an object scaled to 0 along an axis, e.g. Blender scale "
                           "(1, 1, 0)?); give the surface of a solid: a non-zero scale on every axis")
    if ext < MIN_EXTENT:
        k = int(np.ceil(-np.log10(ext)))
        raise SurfaceError(f"the surface is only {ext:.3g} across (its largest extent), too small for SymFrames' "
                           f"double-precision geometry (below {MIN_EXTENT:g} across, areas and volumes round to 0); "
                           f"a model in the wrong units: scale it up (e.g. by 1e{k}, to about 1 across)")


def _surface_arrays(V, F) -> tuple[np.ndarray, np.ndarray]:
    """(V, F) as float and int64 arrays of the right shapes, finite, with
    indices in range."""
    if V is None or F is None:
        raise SurfaceError(f"surface {'vertices' if V is None else 'faces'} = None: give the vertices as an (n, 3) "
                           "array of numbers and the faces as an (m, 3) array of vertex indices")
    if _is_complex(V):
        raise SurfaceError("surface vertices are complex numbers; give real coordinates (an (n, 3) float array; "
                           "the imaginary part is not dropped silently)")
    try:
        V = np.asarray(V, dtype=float)
        F = np.asarray(F)
    except (TypeError, ValueError, OverflowError) as e:
        raise SurfaceError(f"surface vertices must be an (n, 3) array of numbers and faces an (m, 3) array of "
                           f"vertex indices ({e})") from None
    if V.ndim != 2 or V.shape[1] != 3 or len(V) < 4:
        raise SurfaceError(f"surface vertices must be an (n, 3) array with n >= 4, got shape {V.shape}")
    if F.ndim == 2 and F.shape[1] == 3 and len(F) < 4:
        raise SurfaceError(f"the surface has {len(F)} triangle(s): a closed surface bounding a solid has at least 4 "
                           "(an open plane or sheet bounds no volume); give the closed surface of the solid")
    if F.ndim != 2 or F.shape[1] != 3:
        raise SurfaceError(
            f"surface faces must be an (m, 3) array of triangles with m >= 4, got shape {F.shape}; "
            "triangulate quads and n-gons first"
        )
    if not np.all(np.isfinite(V)):
        bad = np.nonzero(~np.all(np.isfinite(V), axis=1))[0][0]
        raise SurfaceError(f"surface vertex {bad} has a non-finite coordinate")
    far = np.nonzero(np.any(np.abs(V) > MAX_COORDINATE, axis=1))[0]
    if len(far):
        raise SurfaceError(f"surface vertex {far[0]} at {V[far[0]].tolist()} is beyond +-{MAX_COORDINATE:g}: "
                           f"{len(far)} such vertex/vertices; a stray vertex (delete it) or a model in the wrong "
                           "units (scale it)")
    if not np.issubdtype(F.dtype, np.integer):
        raise SurfaceError("surface faces must hold integer vertex indices")
    F = F.astype(np.int64)
    if F.min() < 0 or F.max() >= len(V):
        raise SurfaceError(f"surface face indices must lie in [0, {len(V) - 1}], found {F.min()}..{F.max()}")
    return V, F


def _check_degenerate(S: TriSurface) -> None:
    """Refuse triangles with repeated vertices or (near) zero area."""
    V, F, diag = S.V, S.F, S.bbox_diagonal
    rep = (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])
    P = V[F]
    longest = np.max(np.linalg.norm(P - np.roll(P, 1, axis=1), axis=2), axis=1)
    thin = S.face_areas <= 1e-10 * np.maximum(longest, 1e-300) ** 2
    bad = np.nonzero(rep | thin | (longest < 1e-12 * diag))[0]
    if len(bad):
        f = bad[0]
        raise SurfaceError(
            f"{len(bad)} degenerate triangle(s) (zero area), e.g. triangle {f} at {_fmt(P[f].mean(0))}; "
            "merge duplicate vertices and dissolve degenerate faces (Blender: Mesh > Clean Up > Merge by "
            "Distance, Degenerate Dissolve)"
        )


def _check_closed(S: TriSurface) -> None:
    """Refuse edges not shared by exactly two triangles (and say so when the
    triangles are an unmerged soup)."""
    V = S.V
    _, _, cnt = S._edge_data
    if np.any(cnt == 1):
        soup = _unmerged_vertices(S, np.unique(S.edges[cnt == 1]))
        if soup is not None:
            n_open, n_twin, (i, j) = soup
            raise SurfaceError(
                f"surface triangles are not connected: {n_open} open edges, and {n_twin} of their vertices sit at the "
                f"same position as another vertex (e.g. vertices {i} and {j} at {_fmt(V[i])}) -- a triangle soup "
                "as STL files store it. Merge vertices by distance (Blender: Mesh > Clean Up > Merge by Distance; "
                "trimesh: merge_vertices())"
            )
    if np.any(cnt != 2):
        e = np.nonzero(cnt != 2)[0][0]
        i, j = S.edges[e]
        kind = "an open boundary (hole)" if cnt[e] == 1 else f"a non-manifold edge shared by {cnt[e]} faces"
        raise SurfaceError(
            f"surface is not closed and manifold: edge ({i}, {j}) at {_fmt(V[[i, j]].mean(0))} is {kind}; "
            f"{int(np.sum(cnt == 1))} open and {int(np.sum(cnt > 2))} non-manifold edges in total. "
            "Fill holes and separate touching parts (Blender: Select > All by Trait > Non Manifold)"
        )


def _check_orientation(S: TriSurface) -> None:
    """Refuse neighbouring triangles that list their shared edge in the same
    direction: each directed edge is used once."""
    V, F = S.V, S.F
    a = F.reshape(-1)
    b = np.roll(F, -1, axis=1).reshape(-1)
    dkeys = a.astype(np.int64) * len(V) + b
    ud, dc = np.unique(dkeys, return_counts=True)
    if np.any(dc > 1):
        k = ud[np.nonzero(dc > 1)[0][0]]
        i, j = k // len(V), k % len(V)
        raise SurfaceError(
            f"surface orientation is inconsistent at edge ({i}, {j}) near {_fmt(V[[i, j]].mean(0))}: two "
            "neighbouring triangles list it in the same direction. Recalculate normals "
            "(Blender: Mesh > Normals > Recalculate Outside)"
        )


def _check_manifold_vertices(S: TriSurface) -> None:
    """Refuse vertices where two parts of the surface touch: the corners
    around each vertex form a single fan."""
    V, F = S.V, S.F
    nF = len(F)
    corner = np.arange(3 * nF).reshape(nF, 3)
    # corner (f,k) at vertex F[f,k]; its outgoing edge (F[f,k] -> F[f,k+1]) is
    # the incoming edge of the neighbouring corner around the same vertex
    in_keys = np.roll(F, 1, axis=1).astype(np.int64) * len(V) + F  # prev -> vertex
    # neighbour of corner (f,k) around vertex v: the corner whose incoming edge is
    # the reverse of (v -> next)
    rev = np.roll(F, -1, axis=1).astype(np.int64) * len(V) + F
    order = np.argsort(in_keys.reshape(-1))
    pos = np.searchsorted(in_keys.reshape(-1)[order], rev.reshape(-1))
    nb = order[np.clip(pos, 0, len(order) - 1)]
    A = sp.coo_matrix((np.ones(3 * nF), (corner.reshape(-1), nb)), shape=(3 * nF, 3 * nF))
    ncc, lab = csgraph.connected_components(A, directed=False)
    used = np.unique(F)
    if ncc != len(used):
        per_vertex = np.zeros(len(V), int)
        first = np.full(ncc, -1)
        verts = F.reshape(-1)
        first[lab] = verts
        np.add.at(per_vertex, first, 1)
        v = np.nonzero(per_vertex > 1)[0][0]
        raise SurfaceError(
            f"surface vertex {v} at {_fmt(V[v])} is non-manifold (two parts of the surface touch only there); "
            "split it or move the parts apart"
        )


def _check_intersections(S: TriSurface) -> None:
    """Refuse triangles that cross, or that touch without sharing vertices."""
    P = S.V[S.F]
    hit = find_crossing_or_contact(S)
    if hit is not None and hit[0] == "cross":
        f, g = hit[1:3]
        raise SurfaceError(
            f"surface intersects itself: triangles {f} and {g} cross near {_fmt(P[f].mean(0))}; "
            "remove the intersection (Blender: 3D-Print Toolbox > Intersections, or a Boolean union)"
        )
    if hit is not None:
        f, g, x = hit[1:]
        cf, cg = S.component_of_faces()[[f, g]]
        what = (f"surface components {cf} and {cg} touch or overlap" if cf != cg else
                f"surface component {cf} touches itself")
        raise SurfaceError(
            f"{what}: triangles {f} and {g} meet at {_fmt(x)} without sharing vertices -- solids touching face "
            "to face or along an edge, overlapping with coincident faces, or a surface folded onto itself. "
            "Move the parts apart and solve each solid separately, or join them into one solid (a Boolean "
            "union)"
        )


def _check_nesting(S: TriSurface) -> None:
    """One solid, its outer surface outward and its cavities inward."""
    V, F = S.V, S.F
    vols = S.signed_volumes()
    ncomp, lab = S.face_components
    if ncomp > 1:
        comp_vertex = np.array([F[np.nonzero(lab == c)[0][0], 0] for c in range(ncomp)])
        depth = np.zeros(ncomp, int)
        for c in range(ncomp):
            others = [d for d in range(ncomp) if d != c]
            for d in others:
                sub = TriSurface(V, F[lab == d])
                if abs(sub.winding_number(V[comp_vertex[c]][None])[0]) > 0.5:
                    depth[c] += 1
    else:
        depth = np.zeros(1, int)
    _check_one_solid(S, depth)
    for c in range(ncomp):
        want_positive = depth[c] % 2 == 0
        if (vols[c] > 0) != want_positive:
            what = "an outer surface" if want_positive else "a cavity"
            fix = "outward" if want_positive else "into the cavity (towards the solid's outside)"
            raise SurfaceError(
                f"surface component {c} ({int(np.sum(lab == c))} triangles, {what}) is oriented the wrong "
                f"way; its normals must point {fix} (Blender: Mesh > Normals > Recalculate Outside)"
            )


def _check_one_solid(S: TriSurface, depth: np.ndarray) -> None:
    """One solid per solve: exactly one outer component (depth 0, inside no
    other); every other component is a cavity directly inside it (depth 1).
    A second outer component is a separate solid (the tet mesh would not be
    connected); a component inside a cavity is a solid floating in it."""
    ncomp, lab = S.face_components
    outer = np.nonzero(depth == 0)[0]
    sizes = np.bincount(lab, minlength=ncomp)
    if len(outer) > 1:
        where = ", ".join(f"component {c} ({sizes[c]} triangles) near {_fmt(S.V[S.F[lab == c]].mean(axis=(0, 1)))}"
                          for c in outer[:4])
        raise SurfaceError(
            f"the surface bounds {len(outer)} separate solids ({where}{', ...' if len(outer) > 4 else ''}); a solve "
            "takes one solid, possibly with cavities inside it. Solve each solid separately (Blender: Mesh > "
            "Separate > By Loose Parts), or join them into one (a Boolean union)"
        )
    inner = np.nonzero(depth >= 2)[0]
    if len(inner):
        c = inner[0]
        raise SurfaceError(
            f"surface component {c} ({sizes[c]} triangles) near {_fmt(S.V[S.F[lab == c]].mean(axis=(0, 1)))} is a "
            "solid inside a cavity of another; a solve takes one solid. Solve it separately (Blender: Mesh > "
            "Separate > By Loose Parts)"
        )


def _unmerged_vertices(S: TriSurface, open_vertices: np.ndarray):
    """(open edge count, vertices of open edges with a geometric twin, one
    such pair) when most open-edge vertices coincide with another vertex --
    the surface is an unmerged triangle soup -- else None."""
    tree = cKDTree(S.V)
    d, j = tree.query(S.V[open_vertices], k=2)
    twin = d[:, 1] <= 1e-9 * S.bbox_diagonal
    if twin.sum() < max(3, 0.5 * len(open_vertices)):
        return None
    k = int(np.argmax(twin))
    n_open = int(np.sum(S._edge_data[2] == 1))
    v = int(open_vertices[k])
    return n_open, int(twin.sum()), (v, int(j[k, 1] if j[k, 0] == v else j[k, 0]))
