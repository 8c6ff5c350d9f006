"""What to draw from a field: glyph samples, streamlines and the
diagnostics' selections -- omega arrows, slice faces (no bpy).

A snapshot of the scene's display settings (``DisplaySettings``) is taken on
the main thread; sampling and tracing then run anywhere -- in the solve
thread right after a solve, or directly when refreshing from the stored
field.  The numerics are the solver's (solver.FrameField, sample_glyphs,
seed_points, trace_streamlines, monodromy_angles, regular_face_mask).

The slice plane cuts the tet mesh along tet faces: the tets whose centroid
lies on the kept side (the cutaway's) against the others.  The faces
between the two sets are the *slice faces*; the diagnostics draw on them
(colours), on their edges (omega arrows) and on their vertices (glyphs), so
that the three overlay.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..solver import monodromy_angles, regular_face_mask, sample_glyphs, seed_points, trace_streamlines

ERROR_ATTRIBUTES = {"ADAPTATION": "adaptation", "MONODROMY": "monodromy"}
"""Glyph colouring -> name of the glyph points' error attribute (radians)."""


@dataclass
class DisplaySettings:
    glyph_count: int = 2000
    region: str = "VOLUME"  # 'VOLUME', 'CUTAWAY' or 'SLICE'
    colour: str = "AXES"  # 'AXES', 'ADAPTATION' or 'MONODROMY'
    slice_axis: str = "Y"
    slice_offset: float = 0.5
    flip_clip: bool = False
    family: str = "ALL"  # '0', '1', '2' or 'ALL'
    seeds: int = 150
    seed_on_plane: bool = False
    seed: int = 0
    omega_region: str = "SLICE"  # 'VOLUME', 'CUTAWAY' or 'SLICE'
    omega_count: int = 20000

    @classmethod
    def from_scene(cls, scene) -> DisplaySettings:
        s = scene.symframes
        return cls(s.glyph_count, s.glyph_region, s.glyph_colour, s.slice_axis, s.slice_offset, s.flip_clip,
                   s.streamline_family, s.streamline_seeds, s.streamline_on_plane, s.seed, s.omega_region,
                   s.omega_count)

    def plane(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(origin, normal) of the slice plane within the box [lo, hi]; the
        cutaway keeps the side the normal points away from."""
        axis = "XYZ".index(self.slice_axis)
        origin = 0.5 * (np.asarray(lo, float) + np.asarray(hi, float))
        origin[axis] = lo[axis] + self.slice_offset * (hi[axis] - lo[axis])
        normal = np.zeros(3)
        normal[axis] = -1.0 if self.flip_clip else 1.0
        return origin, normal

    @property
    def families(self) -> list[int]:
        return [0, 1, 2] if self.family == "ALL" else [int(self.family)]


def _canonical(q: np.ndarray) -> np.ndarray:
    return np.where(q[:, :1] < 0, -q, q)


def _subset(ids: np.ndarray, n: int, seed: int) -> np.ndarray:
    """At most n of ids, picked at random (reproducibly), in order."""
    if len(ids) > n:
        ids = np.sort(np.random.default_rng(seed).choice(ids, n, replace=False))
    return ids


def glyph_samples(field, ds: DisplaySettings, adaptation: np.ndarray | None = None,
                  monodromy: np.ndarray | None = None):
    """Glyph points, their frames and (in the error colourings) errors.

    field : solver.FrameField
    adaptation : (#V,) float array, the normal adaptation error (radians) of
        each field vertex, negative where not measured (interior and sharp
        feature vertices); needed for ds.colour == 'ADAPTATION'.
    monodromy : (#V,) float array, vertex_monodromy of the field; needed for
        ds.colour == 'MONODROMY'.

    Returns (points (k, 3), quaternions (k, 4) w x y z, errors (k,) or None).
    'VOLUME' and 'CUTAWAY' give about ds.glyph_count glyphs, 'SLICE' at most
    that many; the error colourings put the glyphs on (at most
    ds.glyph_count) vertices: the adaptation error on measured boundary
    vertices, cut away like the others, the monodromy on all vertices, the
    kept side's or the slice faces' ones.
    """
    n = int(ds.glyph_count)
    empty = (np.zeros((0, 3)), np.zeros((0, 4)), None if ds.colour == "AXES" else np.zeros(0))
    if n <= 0:
        return empty
    lo, hi = field.bounds
    origin, normal = ds.plane(lo, hi)
    if ds.colour in ERROR_ATTRIBUTES:
        if ds.colour == "ADAPTATION":
            err = adaptation
            if err is None or len(err) != len(field.frames):
                raise ValueError("this result stores no adaptation errors; compute the field again")
            v = np.nonzero(err >= 0)[0]
        else:
            err = monodromy
            if err is None or len(err) != len(field.frames):
                raise ValueError("glyphs coloured by monodromy need the monodromy of every vertex")
            v = np.arange(len(err)) if ds.region != "SLICE" else np.unique(slice_faces(field, ds)[1])
        if ds.region == "CUTAWAY":
            v = v[(field.mesh.vertices[v] - origin) @ normal <= 0]
        v = _subset(v, n, ds.seed)
        return field.mesh.vertices[v], _canonical(field.quaternions[v]), err[v]
    if ds.region == "SLICE":
        P = seed_points(field, n, mode="plane", plane_origin=origin, plane_normal=normal, seed=ds.seed)
        Q = field.quaternions_at(P)
        ok = np.isfinite(Q[:, 0])
        return P[ok], Q[ok], None
    kw = {"clip_origin": origin, "clip_normal": normal} if ds.region == "CUTAWAY" else {}
    P, Q = sample_glyphs(field, count=n, seed=ds.seed, **kw)
    return P, Q, None


def streamline_seeds(field, ds: DisplaySettings) -> np.ndarray:
    """(k, 3) seed points: ds.seeds in the volume or on the slice plane."""
    if ds.seed_on_plane:
        origin, normal = ds.plane(*field.bounds)
        return seed_points(field, ds.seeds, mode="plane", plane_origin=origin, plane_normal=normal, seed=ds.seed)
    return seed_points(field, ds.seeds, mode="volume", seed=ds.seed)


def streamlines(field, ds: DisplaySettings, cancel=None) -> tuple[list, list]:
    """(polylines, frame axis of each): one trace per seed and family."""
    seeds = streamline_seeds(field, ds)
    lines, fams = [], []
    for fam in ds.families:
        if cancel is not None and cancel():
            break
        got = trace_streamlines(field, seeds, family=fam)
        lines += got
        fams += [fam] * len(got)
    return lines, fams


# ------------------------------------------------------------- diagnostics
def kept_tets(field, ds: DisplaySettings) -> np.ndarray:
    """(#T,) bool: the tets whose centroid lies on the cutaway's kept side
    of the slice plane (the side its normal points away from)."""
    mesh = field.mesh
    origin, normal = ds.plane(*field.bounds)
    C = mesh.vertices[mesh.tets].mean(axis=1)
    return (C - origin) @ normal <= 0


def _oriented(mesh, faces: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """(k, 3) vertex triples of faces, ordered so that their normals point
    away from the tets inner (k,)."""
    P = mesh.vertices
    F = mesh.faces[faces].copy()
    n = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
    C = P[mesh.tets[inner]].mean(axis=1)
    flip = np.einsum("ij,ij->i", n, P[F[:, 0]] - C) < 0
    F[flip] = F[flip][:, [0, 2, 1]]
    return F


def slice_faces(field, ds: DisplaySettings) -> tuple[np.ndarray, np.ndarray]:
    """(face ids (k,), vertex triples (k, 3)) of the slice faces: the
    interior faces between a kept and a cut-away tet, facing the cut-away
    side (towards the viewer of the cutaway)."""
    mesh = field.mesh
    keep = kept_tets(field, ds)
    ft = mesh.face_tets
    interior = ft[:, 1] >= 0
    f = np.nonzero(interior & (keep[ft[:, 0]] != keep[np.maximum(ft[:, 1], 0)]))[0]
    inner = np.where(keep[ft[f, 0]], ft[f, 0], ft[f, 1])
    return f, _oriented(mesh, f, inner)


def kept_boundary_faces(field, ds: DisplaySettings) -> tuple[np.ndarray, np.ndarray]:
    """(face ids (k,), vertex triples (k, 3) facing out) of the domain
    boundary faces of the kept tets: the surface left by the cutaway."""
    mesh = field.mesh
    keep = kept_tets(field, ds)
    f = mesh.boundary_faces
    f = f[keep[mesh.face_tets[f, 0]]]
    return f, _oriented(mesh, f, mesh.face_tets[f, 0])


def vertex_monodromy(mesh, omega: np.ndarray, network_faces: np.ndarray) -> np.ndarray:
    """(#V,) mean monodromy angle (radians, Eq. 9) of the regular faces
    (solver.regular_face_mask) around each vertex; 0 where there is none.
    network_faces : (k,) ids of the faces the network passes through."""
    f = np.nonzero(regular_face_mask(mesh, network_faces))[0]
    ang = monodromy_angles(mesh, omega, f)
    F = mesh.faces[f].ravel()
    total = np.bincount(F, np.repeat(ang, 3), mesh.n_vertices)
    count = np.bincount(F, minlength=mesh.n_vertices)
    return total / np.maximum(count, 1)


def omega_arrows(field, omega: np.ndarray, ds: DisplaySettings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (k, 3), rotation vectors (k, 3), edge ids (k,)) of the omega
    arrows: one per edge at its midpoint, for every edge ('VOLUME'), the
    edges with their midpoint on the kept side ('CUTAWAY') or the edges of
    the slice faces ('SLICE'); at most ds.omega_count, picked at random."""
    mesh = field.mesh
    if ds.omega_region == "SLICE":
        e = np.unique(mesh.face_edges[slice_faces(field, ds)[0]])
    else:
        e = np.arange(mesh.n_edges)
    M = mesh.vertices[mesh.edges[e]].mean(axis=1)
    if ds.omega_region == "CUTAWAY":
        origin, normal = ds.plane(*field.bounds)
        keep = (M - origin) @ normal <= 0
        e, M = e[keep], M[keep]
    pick = _subset(np.arange(len(e)), max(int(ds.omega_count), 0), ds.seed)
    return M[pick], np.asarray(omega, float)[e[pick]], e[pick]
