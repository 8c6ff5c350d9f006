"""Interpolated cross fields, their integral curves and glyph samples (§5.5).

§5.5 visualises a field by "integral curves through an interpolated field
given by the barycentric weighted Karcher mean on SO(3)".  Inside a tet with
barycentric weights w, the four vertex frames are first matched (closest
cube symmetry) to the frame of the vertex with the largest weight, then
averaged: the weighted Karcher mean R minimises sum_k w_k d(R, E_k)^2 and is
the fixed point of R <- R exp(sum_k w_k log(R^T E_k)).

Frames are handled as unit quaternions (w, x, y, z) internally: matching
against the 24 cube symmetries is then one 4 x 24 matrix product, and the
Karcher iteration a few elementwise operations, vectorised over all points.

An integral curve of a cross field follows, at every point, the frame axis
closest to its current direction, with the sign that keeps it going forward.
All streamlines advance together, one Runge-Kutta step per loop iteration;
every stage re-selects the axis nearest the step's first direction.  Each
stage point is reached by walking the straight segment from the current point
through the mesh, so leaving the solid is detected exactly (also in
non-convex solids): a step that would leave is redone to end just short of
the boundary, and the last one is clipped at the boundary face it crosses.

Typical use::

    field = FrameField.from_field(result.field)     # or FrameField(V, T, E)
    lines = trace_streamlines(field, seed_points(field, 500), family="all")
    points, quats = sample_glyphs(field, spacing=0.1, clip_normal=(0, 0, 1))
"""

from __future__ import annotations

from functools import cached_property

import numpy as np
from scipy.spatial.transform import Rotation

from .. import checks
from ..errors import OptionsError
from ..field.solved import as_field
from ..linalg.rotations import CUBE_GROUP
from ..mesh.embed import TetLocator
from ..mesh.tetmesh import TetMesh

_INSIDE_TOL = 1e-10
"""A point is inside a tet when no barycentric coordinate is below -tol."""

_KARCHER_ITERATIONS = 4
_KARCHER_TOL = 1e-9
"""Radians: the Karcher iteration stops at each point once its update is
smaller than this.  The error left is a small fraction of the last update
(the iteration contracts by O(spread^2)); from the chordal mean, one or two
updates suffice even where the four frames spread by 0.75 rad."""

_KARCHER_TOL_TRACE = 1e-4
"""The same for streamline directions: on a solved field, stopping at this
update size left every direction within 4e-6 rad of the Karcher mean (200k
points in a solved ball), far below the integration error, and saves a
second update at most points."""

_MAX_TURN = np.radians(30.0)
"""A streamline stops where its direction would turn by more than this within
one step: the field is not resolved there (a singular curve or a sharp
corner), and the nearest-axis rule would pick an arbitrary axis."""

_TABLEAUX = {
    # (stage offsets a_ij, weights b_i) of explicit Runge-Kutta methods
    "rk2": ([[], [0.5]], [0.0, 1.0]),
    "rk4": ([[], [0.5], [0.0, 0.5], [0.0, 0.0, 1.0]], [1 / 6, 1 / 3, 1 / 3, 1 / 6]),
}


# ------------------------------------------------------------------ quaternions
def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (..., 4), scalar first (broadcasting)."""
    # explicit components: several times faster than np.cross + concatenate
    a0, a1, a2, a3 = np.moveaxis(a, -1, 0)
    b0, b1, b2, b3 = np.moveaxis(b, -1, 0)
    return np.stack(
        [
            a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
            a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
            a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
            a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
        ],
        axis=-1,
    )


def _qconj(q: np.ndarray) -> np.ndarray:
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _qlog(q: np.ndarray) -> np.ndarray:
    """Rotation vector (..., 3) of unit quaternions (..., 4): log_so3 of the
    rotation, angle in [0, pi]."""
    w = np.abs(q[..., 0])
    v = np.where(q[..., :1] < 0, -q[..., 1:], q[..., 1:])
    n = np.sqrt(np.einsum("...i,...i->...", v, v))
    # angle / n, which tends to 2 / w as n -> 0
    scale = np.where(n > 1e-12, 2.0 * np.arctan2(n, w) / np.maximum(n, 1e-300), 2.0 / np.maximum(w, 1e-300))
    return v * scale[..., None]


def _qexp(v: np.ndarray) -> np.ndarray:
    """Unit quaternions (..., 4) of rotation vectors (..., 3): exp_so3."""
    theta = np.sqrt(np.einsum("...i,...i->...", v, v))[..., None]
    # sin(theta/2) / theta, with np.sinc(x) = sin(pi x) / (pi x)
    return np.concatenate([np.cos(0.5 * theta), 0.5 * np.sinc(theta / (2 * np.pi)) * v], axis=-1)


def _qmatrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of unit quaternions (..., 4)."""
    w, x, y, z = np.moveaxis(q, -1, 0)
    R = np.empty(q.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def _to_quaternions(frames: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations -> (..., 4) unit quaternions (w, x, y, z)."""
    shape = frames.shape[:-2]
    q = Rotation.from_matrix(frames.reshape(-1, 3, 3)).as_quat(scalar_first=True)
    return q.reshape(shape + (4,))


def _canonical(q: np.ndarray) -> np.ndarray:
    """The sign of each quaternion with w >= 0 (q and -q are one rotation)."""
    return np.where(q[..., :1] < 0, -q, q)


_CUBE_Q = _to_quaternions(CUBE_GROUP)
"""(24, 4) quaternions of rotations.CUBE_GROUP, same order (identity first)."""


# ------------------------------------------------------------- interpolation
def _match_q(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Signed index of the closest symmetry of each cross to a reference.

    q : (..., j, 4) unit quaternions; ref : (..., 4)
    Returns (..., j) int8 ``s * (g + 1)``: q_j @ CUBE_GROUP[g] is the
    representative of q_j's cross closest to ref (as closest_symmetry), and
    s = +-1 puts its quaternion in ref's hemisphere.
    """
    # the g maximising |<ref, q_j g>| = |<conj(q_j) ref, g>|
    rel = _qmul(_qconj(q), ref[..., None, :])
    score = rel @ _CUBE_Q.T
    g = np.argmax(np.abs(score), axis=-1)
    sign = np.where(np.take_along_axis(score, g[..., None], axis=-1)[..., 0] < 0, -1, 1)
    return (sign * (g + 1)).astype(np.int8)


def _apply_match(q: np.ndarray, code: np.ndarray) -> np.ndarray:
    """The representatives q_j g (..., j, 4) chosen by _match_q."""
    g = np.abs(code).astype(np.int64) - 1
    return _qmul(q, _CUBE_Q[g]) * np.sign(code)[..., None]


def _karcher_q(m: np.ndarray, w: np.ndarray, iterations: int = _KARCHER_ITERATIONS, tol: float = _KARCHER_TOL
               ) -> np.ndarray:
    """Weighted Karcher mean on SO(3) of matched quaternions (§5.5).

    m : (k, j, 4) unit quaternions in one hemisphere (one cross, matched)
    w : (k, j) nonnegative weights, rows summing to one
    tol : stop at a point once its update is below tol (radians)
    Returns (k, 4) unit quaternions.
    """
    # the chordal mean is within O(spread^3) of the Karcher mean: a good start
    R = np.einsum("kj,kjc->kc", w, m)
    R /= np.linalg.norm(R, axis=1, keepdims=True)
    act = np.arange(len(R))
    for _ in range(iterations):
        # R <- R exp(sum_j w_j log(R^T E_j)), on the points not yet converged
        Ra = R[act]
        s = np.einsum("kj,kjc->kc", w[act], _qlog(_qmul(_qconj(Ra)[:, None, :], m[act])))
        R[act] = _qmul(Ra, _qexp(s))
        act = act[np.abs(s).max(axis=1, initial=0.0) >= tol]
        if len(act) == 0:
            break
    return R / np.linalg.norm(R, axis=1, keepdims=True)


def barycentric_karcher_mean(frames: np.ndarray, weights: np.ndarray, iterations: int = _KARCHER_ITERATIONS
                             ) -> np.ndarray:
    """The interpolated cross of §5.5: barycentric weighted Karcher mean on SO(3).

    Parameters
    ----------
    frames : (k, j, 3, 3) float array
        j rotation matrices per point (columns are the cross axes), e.g. the
        frames at the four vertices of the tet containing the point.
    weights : (k, j) float array
        Nonnegative weights (barycentric coordinates); normalised here.
    iterations : int
        Karcher fixed-point iterations after the chordal (quaternion) mean.

    Returns
    -------
    (k, 3, 3) float array
        Each frame is matched to the frame with the largest weight by the
        closest cube symmetry, then averaged; the result is the representative
        of the mean cross near that frame.  With all the weight on one frame
        the result is that frame.
    """
    E = np.asarray(frames, dtype=float)
    w = np.asarray(weights, dtype=float)
    if E.ndim != 4 or E.shape[2:] != (3, 3) or w.shape != E.shape[:2]:
        raise OptionsError(
            f"frames must be (k, j, 3, 3) and weights (k, j); got {E.shape} and {w.shape}"
        )
    w = np.clip(w, 0.0, None)
    total = w.sum(axis=1, keepdims=True)
    if np.any(total <= 0):
        raise OptionsError("every row of weights needs a positive entry")
    w = w / total
    q = _to_quaternions(E)
    ref = q[np.arange(len(q)), np.argmax(w, axis=1)]
    return _qmatrix(_karcher_q(_apply_match(q, _match_q(q, ref)), w, iterations))


# ------------------------------------------------------------------ the field
class FrameField:
    """A cross field on a tet mesh, interpolated inside tets (§5.5).

    Parameters
    ----------
    vertices : (n, 3) float array
    tets : (m, 4) int array
    frames : (n, 3, 3) float array
        One rotation per vertex; its columns are the cross axes.
    mesh : TetMesh, optional
        An existing mesh on the same vertices and tets, to reuse its
        precomputed connectivity (``FrameField.from_field`` passes it).

    Precomputes point location (KD-tree on tet centroids, then a straight
    walk through the mesh) and the vertex frames as quaternions.
    """

    def __init__(self, vertices, tets, frames, mesh: TetMesh | None = None):
        try:
            V = np.asarray(vertices, dtype=float)
            T = np.asarray(tets)
            E = np.asarray(frames, dtype=float)
        except (TypeError, ValueError, OverflowError) as e:
            raise OptionsError(f"FrameField: vertices, tets and frames must be arrays of numbers ({e})") from None
        if T.dtype.kind not in "iu" and not (T.dtype.kind == "f" and np.isfinite(T).all() and np.all(T == np.round(T))):
            raise OptionsError(f"FrameField: tets must be whole-number vertex ids; got {T.dtype}")
        T = T.astype(np.int64) if T.size else T.reshape(-1, 4).astype(np.int64)
        if mesh is not None and not isinstance(mesh, TetMesh):
            raise OptionsError(f"FrameField: mesh must be a TetMesh or None; got a {type(mesh).__name__}")
        if V.ndim != 2 or V.shape[1] != 3:
            raise OptionsError(f"vertices must be an (n, 3) array; got shape {V.shape}")
        if T.ndim != 2 or T.shape[1] != 4 or len(T) == 0:
            raise OptionsError(f"tets must be a non-empty (m, 4) int array; got shape {T.shape}")
        if T.min() < 0 or T.max() >= len(V):
            raise OptionsError(f"tets index vertices 0..{len(V) - 1}; found indices {T.min()}..{T.max()}")
        if E.shape != (len(V), 3, 3):
            raise OptionsError(f"frames must be (n, 3, 3) with n = {len(V)} vertices; got shape {E.shape}")
        if not np.all(np.isfinite(E)):
            raise OptionsError("frames contain NaN or inf; solve the field again")
        err = np.abs(np.einsum("nji,njk->nik", E, E) - np.eye(3)).max()
        if err > 1e-6 or np.any(np.linalg.det(E) < 0):
            raise OptionsError(
                f"frames must be rotation matrices (orthonormal, det +1); max |E^T E - I| = {err:.2g}. "
                "Re-orthonormalise them, e.g. with scipy's Rotation.from_matrix(E).as_matrix()"
            )
        self.mesh = mesh if mesh is not None else TetMesh(V, T)
        if self.mesh.n_vertices != len(V) or self.mesh.n_tets != len(T):
            raise OptionsError("mesh does not match vertices and tets")
        flat = np.abs(self.mesh.tet_volumes) <= 1e-12 * self.mesh.mean_edge_length**3
        if np.any(flat):
            raise OptionsError(
                f"{int(flat.sum())} tets have (almost) zero volume, e.g. tet {int(np.argmax(flat))}; "
                "points cannot be located in them: remove them or remesh"
            )
        self.frames = E
        self.quaternions = _to_quaternions(E)
        self.locator = TetLocator(self.mesh)
        X = self.mesh.vertices[self.mesh.tets]
        # no point of a tet is farther than this from its centroid, so a point
        # farther than this from every centroid lies outside the mesh
        self._reach = float(np.linalg.norm(X - self.locator.centroids[:, None], axis=2).max()) * (1 + 1e-9)
        # barycentric coordinates as one affine map per tet, lambda = B @ (p, 1):
        # a single gather per query, twice as fast as TetLocator.barycentric
        Ainv, o = self.locator.Ainv, self.locator.origin
        B = np.empty((len(Ainv), 4, 4))
        B[:, 1:, :3] = Ainv
        B[:, 1:, 3] = -np.einsum("kij,kj->ki", Ainv, o)
        B[:, 0, :3] = -Ainv.sum(axis=1)
        B[:, 0, 3] = 1.0 - B[:, 1:, 3].sum(axis=1)
        self._bary = B

    @classmethod
    def from_field(cls, field) -> FrameField:
        """The frames of a solved field (a ``SolvedField``, or a
        ``solver.Result``), interpolated on its own tet mesh."""
        f = as_field(field, "FrameField.from_field")
        return cls(f.mesh.vertices, f.mesh.tets, f.frames, mesh=f.mesh)

    from_result = from_field  # the earlier name, removed in the next release

    @property
    def mean_edge_length(self) -> float:
        return self.mesh.mean_edge_length

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) corners of the bounding box, (3,) each."""
        return self.mesh.vertices.min(axis=0), self.mesh.vertices.max(axis=0)

    # ------------------------------------------------------------ location
    def barycentric(self, tets: np.ndarray, points: np.ndarray) -> np.ndarray:
        """(k, 4) barycentric coordinates of points (k, 3) in tets (k,)."""
        Bt = self._bary[tets]
        return np.einsum("kij,kj->ki", Bt[..., :3], points) + Bt[..., 3]

    def locate(self, points: np.ndarray) -> np.ndarray:
        """Tet containing each point, or -1 outside the mesh.

        points : (k, 3) float array  ->  (k,) int array
        """
        P = _as_points(points, "points")
        out = np.full(len(P), -1, dtype=np.int64)
        if len(P) == 0:
            return out
        d, near = self.locator.tree.query(P, distance_upper_bound=self._reach)
        cand = np.nonzero(np.isfinite(d))[0]
        lam = self.barycentric(near[cand], P[cand])
        hit = lam.min(axis=1) >= -_INSIDE_TOL
        out[cand[hit]] = near[cand[hit]]
        rest = cand[~hit]
        if len(rest):
            # walk the segment from the nearest centroid (inside its tet)
            t, _, status, _ = self._walk(near[rest], self.locator.centroids[near[rest]], P[rest])
            out[rest] = np.where(status == _REACHED, t, -1)
            failed = rest[status == _FAILED]
            if len(failed):  # degenerate walks (through an edge): rare
                out[failed] = self.locator.locate(P[failed])
        return out

    def _walk(self, t0: np.ndarray, a: np.ndarray, b: np.ndarray, max_iterations: int = 10000):
        """Follow the segments a -> b (k, 3) through the mesh from the tets t0
        (k,) that contain a.  Vectorised over segments.

        Returns (tet containing b, its barycentric coordinates (k, 4), status,
        s): status is _REACHED, _LEFT (the segment leaves the mesh at
        a + s (b - a)) or _FAILED (degenerate).
        """
        n = len(t0)
        t = np.array(t0, dtype=np.int64)
        lam = self.barycentric(t, b)
        status = np.full(n, _FAILED, dtype=np.int8)
        s_out = np.ones(n)
        done = lam.min(axis=1) >= -_INSIDE_TOL
        status[done] = _REACHED
        act = np.nonzero(~done)[0]
        l1 = lam[act]
        entry = np.full(n, -1, dtype=np.int64)
        tet_faces, face_tets = self.mesh.tet_faces, self.mesh.face_tets
        for _ in range(max_iterations):
            if len(act) == 0:
                break
            ta = t[act]
            l0 = self.barycentric(ta, a[act])
            faces = tet_faces[ta]
            # leave through the face whose coordinate reaches zero first,
            # never back through the face we came in by
            exiting = (l1 < -_INSIDE_TOL) & (l0 > l1) & (faces != entry[act, None])
            s = np.where(exiting, np.maximum(l0, 0.0) / np.where(exiting, l0 - l1, 1.0), np.inf)
            k = np.argmin(s, axis=1)
            rows = np.arange(len(act))
            sk, f = s[rows, k], faces[rows, k]
            ft = face_tets[f]
            nb = np.where(ft[:, 0] == ta, ft[:, 1], ft[:, 0])
            stuck = np.isinf(sk)
            left = ~stuck & (nb < 0)
            status[act[left]] = _LEFT
            s_out[act[left]] = np.clip(sk[left], 0.0, 1.0)
            go = ~stuck & ~left
            act = act[go]
            t[act], entry[act] = nb[go], f[go]
            l1 = self.barycentric(t[act], b[act])
            done = l1.min(axis=1) >= -_INSIDE_TOL
            status[act[done]] = _REACHED
            lam[act[done]] = l1[done]
            act, l1 = act[~done], l1[~done]
        return t, lam, status, s_out

    # -------------------------------------------------------- interpolation
    def _frames_in(self, tets: np.ndarray, points: np.ndarray | None = None, weights: np.ndarray | None = None,
                   tol: float = _KARCHER_TOL, chunk: int = 65536) -> np.ndarray:
        """(k, 4) interpolated quaternions at points (k, 3) inside tets (k,),
        or at given barycentric coordinates weights (k, 4) in those tets."""
        out = np.empty((len(tets), 4))
        for i in range(0, len(tets), chunk):
            t = tets[i : i + chunk]
            w = self.barycentric(t, points[i : i + chunk]) if weights is None else weights[i : i + chunk]
            w = np.clip(w, 0.0, None)
            w /= w.sum(axis=1, keepdims=True)
            # reference: the vertex with the largest weight
            code = self._tet_matching[t, np.argmax(w, axis=1)]
            m = _apply_match(self._tet_quaternions[t], code)
            out[i : i + chunk] = _karcher_q(m, w, tol=tol)
        return out

    @cached_property
    def _tet_quaternions(self) -> np.ndarray:
        """(m, 4, 4) the quaternions of the four vertex frames of each tet."""
        return self.quaternions[self.mesh.tets]

    @cached_property
    def _tet_matching(self) -> np.ndarray:
        """(m, 4, 4) int8: [t, r, j] matches vertex j of tet t to vertex r
        (see _match_q).  16 bytes per tet; saves the 24-way search per query."""
        Q = self._tet_quaternions
        out = np.empty((len(Q), 4, 4), dtype=np.int8)
        for r in range(4):
            out[:, r] = _match_q(Q, Q[:, r])
        return out

    def quaternions_at(self, points: np.ndarray) -> np.ndarray:
        """Interpolated frames (§5.5) as unit quaternions (w, x, y, z), w >= 0.

        points : (k, 3) float array  ->  (k, 4) float array, NaN outside the mesh.
        The order (w, x, y, z) is Blender's ``Quaternion`` order.
        """
        P = _as_points(points, "points")
        t = self.locate(P)
        out = np.full((len(P), 4), np.nan)
        inside = t >= 0
        out[inside] = _canonical(self._frames_in(t[inside], P[inside]))
        return out

    def frames_at(self, points: np.ndarray) -> np.ndarray:
        """Interpolated frames (§5.5): barycentric weighted Karcher mean.

        points : (k, 3) float array  ->  (k, 3, 3) float array, columns the
        cross axes; NaN outside the mesh.
        """
        q = self.quaternions_at(points)
        out = np.full((len(q), 3, 3), np.nan)
        inside = np.isfinite(q[:, 0])
        out[inside] = _qmatrix(q[inside])
        return out


_REACHED, _LEFT, _FAILED = 0, 1, 2


def _as_points(points, name: str) -> np.ndarray:
    try:
        P = np.asarray(points, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise OptionsError(f"{name} must be a (k, 3) array of positions; got {checks.describe(points)}") from None
    if P.ndim == 1 and P.shape == (3,):
        P = P[None]
    if P.ndim != 2 or P.shape[1] != 3:
        raise OptionsError(f"{name} must be a (k, 3) array of positions; got shape {P.shape}")
    return P


def _as_field(field) -> FrameField:
    if isinstance(field, FrameField):
        return field
    return FrameField.from_field(field)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _plane_basis(normal) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = np.asarray(normal, dtype=float).reshape(3)
    if not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0:
        raise OptionsError(f"a plane normal must be a nonzero 3-vector; got {normal!r}")
    n = n / np.linalg.norm(n)
    u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    return n, u, np.cross(n, u)


# ----------------------------------------------------------------- sampling
def seed_points(field, count: int, mode: str = "volume", plane_origin=None, plane_normal=None,
                seed: int = 0) -> np.ndarray:
    """Seed points for streamlines, inside the mesh.

    Parameters
    ----------
    field : FrameField or solver.Result
    count : int
        Number of seeds.  ``plane`` may return fewer when the section is
        small compared with the grid spacing this count implies.
    mode : {'volume', 'plane'}
        ``volume``: uniform random points in the solid (tets chosen with
        probability proportional to volume).  ``plane``: a jittered grid on
        the plane through plane_origin (default: bounding-box centre) with
        normal plane_normal (default +z), restricted to the solid.
    plane_origin, plane_normal : (3,) float arrays, optional
        The plane of ``mode='plane'``.
    seed : int
        Random seed.

    Returns
    -------
    (k, 3) float array
    """
    f = _as_field(field)
    count = int(count)
    if count < 0:
        raise OptionsError(f"count must be nonnegative; got {count}")
    rng = np.random.default_rng(seed)
    mesh = f.mesh
    if mode == "volume":
        vol = np.abs(mesh.tet_volumes)
        t = rng.choice(mesh.n_tets, size=count, p=vol / vol.sum())
        # normalised exponentials are uniform on the simplex (Dirichlet(1,1,1,1))
        w = rng.exponential(size=(count, 4))
        w /= w.sum(axis=1, keepdims=True)
        return np.einsum("ki,kij->kj", w, mesh.vertices[mesh.tets[t]])
    if mode != "plane":
        raise OptionsError(f"mode must be 'volume' or 'plane'; got {mode!r}")
    lo, hi = f.bounds
    o = 0.5 * (lo + hi) if plane_origin is None else np.asarray(plane_origin, dtype=float).reshape(3)
    n, u, v = _plane_basis((0.0, 0.0, 1.0) if plane_normal is None else plane_normal)
    # the section lies in the projection of the mesh onto the plane
    UV = (mesh.vertices - o) @ np.c_[u, v]
    uv_lo, uv_hi = UV.min(axis=0), UV.max(axis=0)
    area = float(np.prod(uv_hi - uv_lo))
    if count == 0:
        return np.zeros((0, 3))

    def on_plane(spacing):
        uv = _jittered_grid(uv_lo, uv_hi, spacing, 0.5, rng)
        P = o + uv @ np.stack([u, v])
        return P[f.locate(P) >= 0], len(P)

    # the section's area, from the share of a coarse grid that lands inside
    probe, total = on_plane(np.sqrt(area) / 64)
    if len(probe) == 0:
        raise OptionsError(
            f"the plane through {np.round(o, 4).tolist()} with normal {np.round(n, 4).tolist()} does not cut "
            "the solid; move plane_origin inside it"
        )
    spacing = 0.98 * np.sqrt(area * len(probe) / total / count)
    P, _ = on_plane(spacing)
    if len(P) < count:
        P, _ = on_plane(spacing * np.sqrt(len(P) / count))
    if len(P) > count:
        P = P[np.sort(rng.choice(len(P), count, replace=False))]
    return P


def _jittered_grid(lo: np.ndarray, hi: np.ndarray, spacing: float, jitter: float, rng,
                   max_points: int = 50_000_000) -> np.ndarray:
    """Centres of the cells of a grid with the given spacing over the box
    [lo, hi] (d,), each moved by up to +-jitter/2 spacings along each axis.
    Returns (k, d)."""
    shape = np.maximum(np.ceil((hi - lo) / spacing).astype(np.int64), 1)
    if np.prod(shape) > max_points:
        raise OptionsError(f"spacing {spacing:.3g} gives {np.prod(shape):,} grid points; use a larger spacing")
    idx = np.indices(shape).reshape(len(shape), -1).T
    return lo + (idx + 0.5 + jitter * rng.uniform(-0.5, 0.5, idx.shape)) * spacing


def sample_glyphs(field, count: int | None = None, spacing: float | None = None, clip_origin=None,
                  clip_normal=None, seed: int = 0, jitter: float = 0.5):
    """Roughly uniform points in the solid and the interpolated frame at each (§5.5).

    Parameters
    ----------
    field : FrameField or solver.Result
    count : int, optional
        Number of glyphs wanted (after clipping); the result has count
        points, fewer only when the grid is coarse compared with the solid's
        features.  Default 2000 if spacing is not given either.
    spacing : float, optional
        Grid spacing instead of a count.
    clip_origin, clip_normal : (3,) float arrays, optional
        Keep only points p with (p - clip_origin) . clip_normal <= 0, so that
        the inside of the solid can be seen.  clip_origin defaults to the
        bounding-box centre when clip_normal is given.
    seed : int
        Random seed of the jitter.
    jitter : float
        Each grid point moves by up to +-jitter/2 spacings along each axis
        (0: a regular grid; 1: one uniform point per cell).  Below 1,
        neighbouring glyphs stay at least (1 - jitter) spacings apart.

    Returns
    -------
    points : (k, 3) float array
    quaternions : (k, 4) float array
        Unit quaternions (w, x, y, z), w >= 0, of the interpolated frames.
    """
    f = _as_field(field)
    if count is not None and spacing is not None:
        raise OptionsError("give either count or spacing, not both")
    if clip_origin is not None and clip_normal is None:
        raise OptionsError("clip_origin needs clip_normal: the side p . normal <= origin . normal is kept")
    if not 0.0 <= jitter <= 1.0:
        raise OptionsError(f"jitter must lie in [0, 1]; got {jitter}")
    rng = np.random.default_rng(seed)
    mesh = f.mesh
    lo, hi = f.bounds
    clip = None
    if clip_normal is not None:
        n, _, _ = _plane_basis(clip_normal)
        o = 0.5 * (lo + hi) if clip_origin is None else np.asarray(clip_origin, dtype=float).reshape(3)
        clip = (o, n)
    if spacing is None:
        count = 2000 if count is None else int(count)
        if count <= 0:
            return np.zeros((0, 3)), np.zeros((0, 4))
        vol = np.abs(mesh.tet_volumes)
        if clip is not None:
            cen = f.locator.centroids
            vol = vol[(cen - clip[0]) @ clip[1] <= 0]
        if vol.sum() <= 0:
            return np.zeros((0, 3)), np.zeros((0, 4))
        # ~6% more grid points than wanted, then a random few are dropped:
        # the count is then met despite the randomness of the jitter
        spacing = 0.98 * (vol.sum() / count) ** (1.0 / 3.0)
    spacing = float(spacing)
    if not spacing > 0:
        raise OptionsError(f"spacing must be positive; got {spacing}")
    P = _jittered_grid(lo, hi, spacing, jitter, rng)
    if clip is not None:
        P = P[(P - clip[0]) @ clip[1] <= 0]
    t = f.locate(P)
    P, t = P[t >= 0], t[t >= 0]
    if count is not None and len(P) > count:
        keep = np.sort(rng.choice(len(P), count, replace=False))
        P, t = P[keep], t[keep]
    return P, _canonical(f._frames_in(t, P))


# -------------------------------------------------------------- streamlines
def _nearest_axis(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """The signed axis of each frame (quaternions (k, 4)) closest to the
    directions ref (k, 3): the cross direction continuing ref."""
    E = _qmatrix(q)
    proj = np.einsum("kij,ki->kj", E, ref)  # E^T ref
    a = np.argmax(np.abs(proj), axis=1)
    rows = np.arange(len(q))
    return E[rows, :, a] * np.sign(proj[rows, a])[:, None]


def trace_streamlines(field, seeds, family=0, step: float | None = None, max_length: float | None = None,
                      max_steps: int = 10000, both_directions: bool = True, method: str = "rk2"
                      ) -> list[np.ndarray]:
    """Integral curves of the interpolated cross field (§5.5).

    Parameters
    ----------
    field : FrameField or solver.Result
    seeds : (k, 3) float array
        Start points; seeds outside the mesh give no streamline.
    family : {0, 1, 2, 'all'}
        Which axis of the seed's interpolated frame to start along; 'all'
        traces the three families from every seed.
    step : float, optional
        Integration step; default a quarter of the mean edge length.
    max_length : float, optional
        Largest length traced in each direction from a seed; default the
        bounding-box diagonal.
    max_steps : int
        Largest number of steps in each direction.
    both_directions : bool
        Trace backwards as well and join the two halves at the seed.
    method : {'rk2', 'rk4'}
        Runge-Kutta scheme (midpoint or classical); every stage follows the
        axis closest to the step's first direction.  The interpolated field
        is only continuous across tet faces, so RK4 is not much more
        accurate on a solved field, and it costs twice as much.

    Returns
    -------
    list of (n_i, 3) float arrays
        One polyline per seed and family (seed-major, families in order),
        leaving out those with fewer than 2 points.  A line stops where it
        leaves the mesh (its last point is then on the boundary), at
        max_length or max_steps, or where the field turns by more than 30
        degrees within a step (a singular curve or sharp corner).
    """
    f = _as_field(field)
    S = _as_points(seeds, "seeds")
    if isinstance(family, str):
        if family != "all":
            raise OptionsError(f"family must be 0, 1, 2 or 'all'; got {family!r}")
        families = np.arange(3)
    else:
        if family not in (0, 1, 2):
            raise OptionsError(f"family must be 0, 1, 2 or 'all'; got {family!r}")
        families = np.array([int(family)])
    if method not in _TABLEAUX:
        raise OptionsError(f"method must be one of {', '.join(_TABLEAUX)}; got {method!r}")
    lo, hi = f.bounds
    step = 0.25 * f.mean_edge_length if step is None else float(step)
    max_length = float(np.linalg.norm(hi - lo)) if max_length is None else float(max_length)
    if not step > 0 or not max_length > 0:
        raise OptionsError(f"step and max_length must be positive; got {step} and {max_length}")

    t0 = f.locate(S)
    inside = np.nonzero(t0 >= 0)[0]
    q0 = f._frames_in(t0[inside], S[inside])
    axes = _qmatrix(q0)[:, :, families]  # (k, 3, nf): the starting axes
    signs = np.array([1.0, -1.0]) if both_directions else np.array([1.0])
    # half-lines in the order (seed, family, sign)
    nk, nf, ns = len(inside), len(families), len(signs)
    d0 = (np.moveaxis(axes, 1, 2)[:, :, None, :] * signs[None, None, :, None]).reshape(-1, 3)
    x0 = np.repeat(S[inside], nf * ns, axis=0)
    tt0 = np.repeat(t0[inside], nf * ns)
    ids, steps, pts = _integrate(f, x0, tt0, d0, step, max_length, int(max_steps), method)

    # join halves: backward points in reverse order, then the forward ones;
    # the seed is stored once (step 0 of the forward half)
    half_sign = signs[ids % ns]
    line = ids // ns
    keep = (half_sign > 0) | (steps > 0)
    line, pos, pts = line[keep], (steps * half_sign)[keep], pts[keep]
    order = np.lexsort((pos, line))
    line, pts = line[order], pts[order]
    counts = np.bincount(line, minlength=nk * nf)
    lines = np.split(pts, np.cumsum(counts)[:-1])
    return [p for p in lines if len(p) >= 2]


def _rk_step(f: FrameField, A, b, x, t, lam, d, h):
    """One Runge-Kutta step of the cross field's integral curves.

    x, t, lam, d : (k, 3) points, (k,) their tets, (k, 4) barycentric
    coordinates, (k, 3) current directions; h : (k, 1) step lengths.
    Returns (increment direction (k, 3), first stage k1, ok, out): ok is False
    where the field turns by more than _MAX_TURN, out True where a stage
    point lies outside the mesh (the increment is then meaningless).
    """
    cos_turn = np.cos(_MAX_TURN)
    k1 = _nearest_axis(f._frames_in(t, weights=lam, tol=_KARCHER_TOL_TRACE), d)
    ok = np.sum(k1 * d, axis=1) >= cos_turn
    out = np.zeros(len(x), bool)
    K = [k1]
    for a in A[1:]:
        y = x + h * sum(c * kj for c, kj in zip(a, K))
        ty, wy, status, _ = f._walk(t, x, y)
        reached = status == _REACHED
        k = k1.copy()
        if np.any(reached):
            q = f._frames_in(ty[reached], weights=wy[reached], tol=_KARCHER_TOL_TRACE)
            # every stage follows the axis nearest k1
            k[reached] = _nearest_axis(q, k1[reached])
        out |= ~reached
        # a large turn within a step: the field is not resolved here
        ok &= np.sum(k * k1, axis=1) >= cos_turn
        K.append(k)
    return sum(c * kj for c, kj in zip(b, K)), k1, ok, out


def _integrate(f: FrameField, x: np.ndarray, t: np.ndarray, d: np.ndarray, step: float, max_length: float,
               max_steps: int, method: str):
    """Advance all half-lines together, one Runge-Kutta step per iteration.

    x, t, d : (L, 3) start points, (L,) their tets, (L, 3) start directions.
    Returns (line ids, step numbers, points) of every recorded point.
    """
    A, b = _TABLEAUX[method]
    L = len(x)
    x, t, d = x.copy(), t.copy(), d.copy()
    lam = f.barycentric(t, x)
    length = np.zeros(L)
    alive = np.arange(L)
    rec_ids, rec_steps, rec_pts = [alive.copy()], [np.zeros(L, dtype=np.int64)], [x.copy()]
    for it in range(1, max_steps + 1):
        if len(alive) == 0:
            break
        xa, ta, la, da = x[alive], t[alive], lam[alive], d[alive]
        h = np.minimum(step, max_length - length[alive])[:, None]

        def attempt(sel):
            incr, k1, ok, out = _rk_step(f, A, b, xa[sel], ta[sel], la[sel], da[sel], h[sel])
            incr[out] = k1[out]  # a stage point outside the mesh: Euler step
            xn = xa[sel] + h[sel] * incr
            return (incr, ok, out, xn) + f._walk(ta[sel], xa[sel], xn)

        incr, ok, out, xn, tn, wn, status, s = attempt(slice(None))
        # Leaving the solid: redo the step so that it ends just before the
        # boundary, keeping the last segments accurate.  Within 5% of a step
        # of the boundary, the straight step clipped at the boundary is
        # accurate enough (its error is (0.05 step)^2 times the curvature).
        frac = np.where(status == _LEFT, s, 0.5)
        r = np.nonzero((out | (status == _LEFT)) & (frac * h[:, 0] >= 0.05 * step))[0]
        if len(r):
            h[r] *= 0.97 * frac[r, None]
            incr[r], ok[r], out[r], xn[r], tn[r], wn[r], status[r], s[r] = attempt(r)
        left = status == _LEFT
        xn[left] = xa[left] + s[left, None] * (xn[left] - xa[left])  # clip at the boundary
        seg = np.linalg.norm(xn - xa, axis=1)
        moved = ok & (status != _FAILED) & (seg > 1e-9 * step)
        ids = alive[moved]
        x[ids], t[ids], lam[ids] = xn[moved], tn[moved], wn[moved]
        d[ids] = _unit(incr[moved])
        length[ids] += seg[moved]
        rec_ids.append(ids)
        rec_steps.append(np.full(len(ids), it, dtype=np.int64))
        rec_pts.append(xn[moved])
        alive = alive[moved & ~left & (length[alive] < max_length * (1 - 1e-12))]
    return np.concatenate(rec_ids), np.concatenate(rec_steps), np.concatenate(rec_pts)
