"""What to draw from a field: glyph samples and streamlines (no bpy).

A snapshot of the scene's display settings (``DisplaySettings``) is taken on
the main thread; sampling and tracing then run anywhere -- in the solve
thread right after a solve, or directly when refreshing from the stored
field.  The numerics are solver.streamlines'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..solver.streamlines import sample_glyphs, seed_points, trace_streamlines


@dataclass
class DisplaySettings:
    glyph_count: int = 2000
    region: str = "VOLUME"  # 'VOLUME', 'CUTAWAY' or 'SLICE'
    colour: str = "AXES"  # 'AXES' or 'ADAPTATION'
    slice_axis: str = "Y"
    slice_offset: float = 0.5
    flip_clip: bool = False
    family: str = "ALL"  # '0', '1', '2' or 'ALL'
    seeds: int = 150
    seed_on_plane: bool = False
    seed: int = 0

    @classmethod
    def from_scene(cls, scene) -> DisplaySettings:
        s = scene.symframes
        return cls(s.glyph_count, s.glyph_region, s.glyph_colour, s.slice_axis, s.slice_offset, s.flip_clip,
                   s.streamline_family, s.streamline_seeds, s.streamline_on_plane, s.seed)

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


def glyph_samples(field, ds: DisplaySettings, adaptation: np.ndarray | None = None):
    """Glyph points, their frames and (in the adaptation colouring) errors.

    field : solver.streamlines.FrameField
    adaptation : (#V,) float array, the normal adaptation error (radians) of
        each field vertex, negative where not measured (interior and sharp
        feature vertices); needed for ds.colour == 'ADAPTATION'.

    Returns (points (k, 3), quaternions (k, 4) w x y z, errors (k,) or None).
    'VOLUME' and 'CUTAWAY' give about ds.glyph_count glyphs, 'SLICE' at most
    that many; the adaptation colouring puts the glyphs on (at most
    ds.glyph_count) measured boundary vertices, cut away like the others.
    """
    n = int(ds.glyph_count)
    empty = (np.zeros((0, 3)), np.zeros((0, 4)), None if ds.colour == "AXES" else np.zeros(0))
    if n <= 0:
        return empty
    lo, hi = field.bounds
    origin, normal = ds.plane(lo, hi)
    if ds.colour == "ADAPTATION":
        if adaptation is None or len(adaptation) != len(field.frames):
            raise ValueError("this result stores no adaptation errors; compute the field again")
        v = np.nonzero(adaptation >= 0)[0]
        if ds.region == "CUTAWAY":
            v = v[(field.mesh.vertices[v] - origin) @ normal <= 0]
        if len(v) > n:
            v = np.sort(np.random.default_rng(ds.seed).choice(v, n, replace=False))
        return field.mesh.vertices[v], _canonical(field.quaternions[v]), adaptation[v]
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
