"""Stage 7 of hex meshing: vertex optimisation that never lowers quality.

The extracted hexes have the right structure; near nodes and where the map
is strained their shape can be poor, even inverted (a cell's corners are the
preimages of a unit cube's, but nothing asks the eight of them to form a
good hexahedron).  Their positions are optimised here, with the topology
fixed, as an untangling problem over the 8 corner tetrahedra of every hex:
for each corner, J = [e1 e2 e3] / cell (its three edges), and

    f(J) = tr(J'J) / chi(det J)^(2/3) + lam (det(J)^2 + 1) / chi(det J),
    chi(D) = (D + sqrt(eps^2 + D^2)) / 2,

the regularised energy of Garanzha et al., "Foldover-free maps in 50 lines
of code" (SIGGRAPH 2021): finite for inverted corners while eps > 0, so an
inverted mesh can be untangled, and with eps -> 0 a barrier that keeps the
corners positive.  Its first term is the mean-ratio shape measure (3 at a
cube corner), the second keeps volumes near the cell's.  What is minimised
is the sum of f over the corners, then, from where that left the mesh, the
sum of (f / F_CUBE)^POWER (F_CUBE: f at a cube's corner), a power mean as
in Mesquite's objectives (Brewer et al., "The Mesquite Mesh Quality
Improvement Toolkit", IMR 2003), which weighs the worst corners more.

Only the poor cells and a margin around them move (``active_vertices``);
the regular grid elsewhere is held.  Boundary vertices move in the tangent
plane of the input surface and are projected back onto it (sharp-feature
vertices along their feature, corners not at all); vertices of irregular
edges (the network) are held near their place by a spring.  A pass is
kept only if the minimum scaled Jacobian does not decrease; the report
says what smoothing gained.  ``smooth_hexes`` is that policy (which vertex
moves how, the spring's weight, what is kept); ``optimise`` the
optimisation itself.
"""

from __future__ import annotations

import copy

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from ..linalg.lbfgs import lbfgs
from ..surface.trisurface import unique_rows
from .quality import (
    HEX_CORNER_NEIGHBOURS,
    HEX_EDGES,
    boundary_quads,
    det3,
    polyline_distance,
    quad_surface,
    scaled_jacobian,
    segments_distance,
    surface_left,
)
from .report import HAUSDORFF_BAR

LAMBDA = 0.5
F_CUBE = 3.0 + 2.0 * LAMBDA
"""f at a cube's corner (J the identity, eps -> 0): the corner energies are
taken over it, so that a perfect corner counts 1."""
POWER = 3.0
"""The power of each corner's energy (f / F_CUBE) in the sum the last run
of smoothing minimises (``_polished``; the runs before it, which untangle
and find the spring, minimise the plain sum).  Under the plain sum alone
the ball's field (9.8k tets) meshed at 86,528 cells kept a least scaled
Jacobian of 0.458-0.459 (two fields): the cell inside the cube at each cube
edge (a valence-3 curve) opened to 152 degrees there and the two shell
cells closed to 104, because the sum trades those few corners against the
many beside them.  Minimised from the start with power 2 the least cell was
0.557-0.558, with 3 0.620-0.621, with 4 0.678, at 21, 41 and 58 s of
smoothing against 24 (single runs); at ~1M cells, though, no spring then
kept the curves within 0.9 of a cell, and the mesh stayed as extracted.
As a last run after the plain sum's, power 3 gives 0.621 and 0.638 at
86,528 and 90,584 cells (mean 0.974-0.980)."""
SHARP_DIHEDRAL = 30.0
"""A boundary edge whose two faces meet at more than this many degrees is a
crease: of the hex boundary, smoothed along the input's sharp edges it
follows; of the tet mesh, never split to free a flat tet (seamless.py)."""
ACTIVE_BELOW = 0.9
"""Smoothing moves the vertices of the cells whose scaled Jacobian is below
this and ACTIVE_RINGS rings of cells around them; the rest of the mesh, a
regular grid already, is held.  On the ball's field meshed at 90k cells the
whole-mesh optimisation (of the plain sum) stalled at its iteration cap
(min 0.43 after 64 s), while its 40k cells near the curves alone reach a
min of 0.51 in 20 s: the
line search of one optimisation over every vertex is held back by its worst
corners, and the held grid costs an evaluation's time for nothing."""
ACTIVE_RINGS = 2
KEEP_SURFACE = 0.9
"""Smoothing may leave the input surface by this share of the Hausdorff bar
(report.HAUSDORFF_BAR, of the diagonal) where the extracted mesh did not:
farther, the boundary vertices there keep their extracted places.  At an
ellipsoid's tips (semi-axes 1.53, 1.0, 0.70; the hexnet family's) the
layout's cells are tall and wide, and evening them out moved the grid
lines beside a tip 0.15 (1.3 cells) away from it: a cap 1.6% of the
diagonal off the surface, 0.84% before smoothing, so that the ladder
stepped the cells down twice and the curves' ends slid over a cell.
Holding the 77 of 434 boundary vertices there keeps 0.84% (mean scaled
Jacobian 0.927 against 0.936; 0.930 once the ring around the 33 nearest
is let go again); at half the bar 155 were held (0.924)."""
SURFACE_ROUNDS = 2
"""Runs of the smoothing made again, each holding the vertices near the
stretches of surface the last left (``surface_lost``)."""
POLISH_MEAN = 0.005
"""The most the power mean's run may lower the mean scaled Jacobian to be
kept (``_polished``): it trades a little of the mean for the least cell
(the ball's field at 86,528 cells: mean 0.9758 -> 0.9737, least 0.459 ->
0.621)."""
SPRING = 0.1
"""Weight of the spring holding singular-curve vertices during smoothing
(per cell of displacement, against the mean corner energy): under the
plain sum, at 1.0 the ball's cells at its nodes kept a minimum scaled
Jacobian of 0.54, at 0.1 0.72, with the irregular edges still within a
cell of their curves."""


def foldover_free(J: np.ndarray, eps: float, lam: float = LAMBDA):
    """f(J) of the module docs per (n, 3, 3) matrix, and df/dJ (n, 3, 3)."""
    rows = np.ascontiguousarray(J.transpose(1, 2, 0))
    f, G = _foldover_rows(rows, eps, lam)
    return f, G.transpose(2, 0, 1)


def _foldover_rows(R: np.ndarray, eps: float, lam: float = LAMBDA, work: np.ndarray | None = None):
    """``foldover_free`` on the nine components of J as contiguous vectors:
    R (3, 3, n), R[i, k] the k-th coordinate of J's row i; returns f (n,)
    and df/dJ in the same layout.  The rows' cross products (the cofactors,
    dD/dJ) are written out: on the 725k corners of a 90k-cell mesh several
    times faster than np.cross on (n, 3, 3) arrays.  A line search's trial
    step far out (J huge, chi near 0) overflows to inf or nan: the step is
    then rejected (lbfgs takes only finite energies), so numpy is not let
    to warn about it.

    work : (WORK_ROWS, >= n) float array, optional
        scratch every step writes into, f and df/dJ included (views of it,
        valid until the next call): a call then allocates nothing.  Freeing
        and allocating some thirty arrays per block of corners made the
        allocator hand the memory back to the system and fault it in again,
        page by page: on blocks of 8192 corners, 219 ns per corner against
        84-99 with scratch."""
    n = R.shape[2]
    w = np.empty((WORK_ROWS, n)) if work is None else work[:, :n]
    C, P = w[:9].reshape(3, 3, n), w[9:18].reshape(3, 3, n)
    D, DD, tr, root, chi, dchi, c23, f, u, t = w[18:28]
    mul, sub = np.multiply, np.subtract
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        (a0, a1, a2), (b0, b1, b2), (c0, c1, c2) = R
        # cofactor rows, dD/dJ: b x c, c x a, a x b
        for (x, y, z, v), out in zip([(b1, c2, b2, c1), (b2, c0, b0, c2), (b0, c1, b1, c0),
                                      (c1, a2, c2, a1), (c2, a0, c0, a2), (c0, a1, c1, a0),
                                      (a1, b2, a2, b1), (a2, b0, a0, b2), (a0, b1, a1, b0)], C.reshape(9, n)):
            mul(x, y, out=out)
            mul(z, v, out=t)
            sub(out, t, out=out)
        mul(a0, C[0, 0], out=D)
        for x, y in ((a1, C[0, 1]), (a2, C[0, 2])):
            mul(x, y, out=t)
            D += t
        np.einsum("ijn,ijn->n", R, R, out=tr)
        mul(D, D, out=DD)
        np.add(DD, eps * eps, out=root)
        np.sqrt(root, out=root)
        np.add(D, root, out=chi)
        chi *= 0.5  # chi(D) of the module docs
        np.divide(D, root, out=dchi)
        dchi += 1.0
        dchi *= 0.5  # its derivative
        np.power(chi, -2.0 / 3.0, out=c23)
        # f = tr c23 + lam (D^2 + 1) / chi
        mul(tr, c23, out=u)
        np.add(DD, 1.0, out=t)
        t /= chi
        t *= lam
        np.add(u, t, out=f)
        # df/dD = -2/3 tr c23 / chi dchi + lam (2 D chi - (D^2 + 1) dchi) / chi^2
        u /= chi
        u *= dchi
        u *= -2.0 / 3.0
        np.add(DD, 1.0, out=root)  # root is not needed any more
        root *= dchi
        mul(D, chi, out=t)
        t *= 2.0
        t -= root
        t /= chi
        t /= chi
        t *= lam
        u += t
        # df/dJ = df/dD dD/dJ + 2 c23 J
        C *= u
        c23 *= 2.0
        mul(R, c23, out=P)
        C += P
        return f, C


WORK_ROWS = 28
"""Rows of ``_foldover_rows``' scratch."""

CHUNK = 16384
"""Corners per block of an energy evaluation (``CornerEnergy``): a block's
scratch stays in the processor's cache, and no block allocates.  On a
227k-cell grid (1.8M corners), its vertices and hexes shuffled as an
extraction leaves them, one evaluation took 1.0 s on whole arrays, 0.27-0.34 s
in blocks of 16384 corners after ``local_order`` (8192 to 65536 alike, 2048
0.44; bench/RESULTS.md)."""


class CornerEnergy:
    """Sum of (f / F_CUBE)^power over every hex corner of H (m, 8) on n
    vertices (J's rows: the corner's three edges over the cell size: one, or
    one per hex of a size field), and its gradient (n, 3): ``energy(V, eps)``.

    The corners' vertex ids are gathered once; an evaluation runs over
    blocks of CHUNK corners (``_foldover_rows`` on each coordinate as a
    contiguous vector) and scatters the gradient in one ``bincount`` per
    coordinate over the four vertices each corner touches."""

    def __init__(self, H: np.ndarray, cell, n: int, power: float = 1.0):
        self.power = float(power)
        corner = H.reshape(-1)
        nb = H[:, HEX_CORNER_NEIGHBOURS]  # (m, 8, 3): the corner's three neighbours
        self.ids = np.empty((4, len(corner)), dtype=np.int64)  # the three neighbours, then the corner
        for j in range(3):
            self.ids[j] = nb[:, :, j].reshape(-1)
        self.ids[3] = corner
        self.cell = cell if np.ndim(cell) == 0 else np.repeat(np.asarray(cell, float), 8)  # per corner
        self.n = n
        self._scratch = None

    def __call__(self, V: np.ndarray, eps: float, with_grad: bool = True):
        X = np.ascontiguousarray(V.T)  # (3, n)
        ids, N = self.ids, self.ids.shape[1]
        per_corner = np.ndim(self.cell) != 0
        if self._scratch is None:  # kept between evaluations: fresh memory is faulted in anew each time
            k = min(CHUNK, N)
            self._scratch = np.empty((3, 3, k)), np.empty((3, k)), np.empty((WORK_ROWS, k)), np.empty((3, 4, N))
        # a block's scratch: a block allocates nothing (_foldover_rows); dE:
        # d energy / d vertex, per coordinate and corner vertex
        R, base, work, dE = self._scratch
        total = 0.0
        for a in range(0, N, CHUNK):
            b = min(N, a + CHUNK)
            r, o = R[:, :, :b - a], base[:, :b - a]
            np.take(X, ids[3, a:b], axis=1, out=o, mode="clip")  # (unbuffered)
            for j in range(3):
                np.take(X, ids[j, a:b], axis=1, out=r[j], mode="clip")
                r[j] -= o
            c = self.cell[a:b] if per_corner else self.cell
            r /= c
            f, G = _foldover_rows(r, eps, work=work)
            if self.power != 1.0:
                # (f / F_CUBE)^p and its derivative p (f / F_CUBE)^(p-1) / F_CUBE,
                # in place: f is scratch of this block, and so is the last
                # row of `work` (_foldover_rows' own last step is done)
                f /= F_CUBE
                with np.errstate(over="ignore", invalid="ignore"):  # a trial step far out: rejected by lbfgs
                    slope = work[WORK_ROWS - 1, :b - a]
                    if self.power == 3.0:  # products: np.power with a float exponent costs 3x the kernel
                        np.multiply(f, f, out=slope)
                        f *= slope
                    else:
                        np.power(f, self.power - 1.0, out=slope)
                        f *= slope
                    if with_grad:
                        slope *= self.power / F_CUBE
                        G *= slope
            total += float(f.sum())
            if with_grad:
                G /= c
                dE[:, :3, a:b] = G.transpose(1, 0, 2)
                np.sum(G, axis=0, out=dE[:, 3, a:b])
                np.negative(dE[:, 3, a:b], out=dE[:, 3, a:b])
        if not with_grad:
            return total, None
        flat = ids.reshape(-1)
        g = np.empty((self.n, 3))
        for k in range(3):
            g[:, k] = np.bincount(flat, dE[k].reshape(-1), self.n)
        return total, g


def local_order(P: np.ndarray, bits: int = 10) -> np.ndarray:
    """A permutation of the points P (n, 3) along a Morton (Z-order) curve
    of their bounding box: points near in space come near in the order, so
    an evaluation's gathers and scatters touch memory close together."""
    span = float(np.ptp(P, axis=0).max()) if len(P) else 0.0
    q = ((P - P.min(axis=0)) * (((1 << bits) - 1) / max(span, 1e-300))).astype(np.int64)
    code = np.zeros(len(P), dtype=np.int64)
    for bit in range(bits):
        for k in range(3):
            code |= ((q[:, k] >> bit) & 1) << (3 * bit + k)
    return np.argsort(code, kind="stable")


def _closest_on_segments(X: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Closest point to each X (k, 3) on the segment set A -> B (s, 3)."""
    if not len(A):
        return X.copy()
    mid = 0.5 * (A + B)
    k = min(8, len(A))
    _, idx = cKDTree(mid).query(X, k=k)
    idx = idx.reshape(len(X), k)
    a, d = A[idx], (B - A)[idx]  # (k_pts, k, 3)
    t = np.clip(np.einsum("nki,nki->nk", X[:, None] - a, d) / np.maximum(np.einsum("nki,nki->nk", d, d), 1e-300),
                0.0, 1.0)
    C = a + t[..., None] * d
    best = np.argmin(np.linalg.norm(C - X[:, None], axis=2), axis=1)
    return C[np.arange(len(X)), best]


class BoundaryMotion:
    """How each vertex may move: interior vertices freely; boundary vertices
    in the tangent plane of the surface (then projected onto it); vertices on
    lines -- sharp edges of the boundary, feature and singular curves inside
    -- along the line (then projected onto line_segments, the input's sharp
    edges and curves); where lines meet or end, and the vertices in `fixed`,
    not at all.

    feature_edges : (k, 2) hex edges along those lines
    line_segments : (A, B) the segments (s, 3) the line vertices return to
    """

    def __init__(self, V, quads, feature_edges, surface, line_segments, fixed):
        n = len(V)
        self.surface, self.sharp = surface, line_segments
        bnd = np.zeros(n, bool)
        bnd[np.unique(quads)] = True
        fdeg = np.bincount(feature_edges.reshape(-1), minlength=n) if len(feature_edges) else np.zeros(n, int)
        self.corner = (fdeg > 2) | (fdeg == 1) | fixed
        self.feature = (fdeg == 2) & ~self.corner
        self.smooth = bnd & ~self.feature & ~self.corner
        self.interior = ~bnd & ~self.feature & ~self.corner
        self.feature_edges = feature_edges
        self.quads = quads

    def held(self, free: np.ndarray) -> BoundaryMotion:
        """A copy in which the vertices outside `free` (n,) bool do not move."""
        m = copy.copy(self)
        m.corner = self.corner | ~free
        m.feature, m.smooth, m.interior = self.feature & free, self.smooth & free, self.interior & free
        return m

    def bases(self, V):
        """(vertex ids, (k, 3, d) bases) per group with d = 3, 2, 1."""
        n = len(V)
        # vertex normals of the quad boundary
        P = V[self.quads]
        qn = np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 1])
        N = np.zeros((n, 3))
        for k in range(4):
            np.add.at(N, self.quads[:, k], qn)
        N /= np.maximum(np.linalg.norm(N, axis=1, keepdims=True), 1e-300)
        out = []
        iv = np.nonzero(self.interior)[0]
        out.append((iv, np.broadcast_to(np.eye(3), (len(iv), 3, 3))))
        sv = np.nonzero(self.smooth)[0]
        if len(sv):
            a = np.where(np.abs(N[sv, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
            t1 = np.cross(N[sv], a)
            # a vertex whose quads' normals cancel has no tangent plane: zero
            # directions, so it stays where it is (was NaN on a genus-2 part)
            t1 /= np.maximum(np.linalg.norm(t1, axis=1, keepdims=True), 1e-300)
            t2 = np.cross(N[sv], t1)
            out.append((sv, np.stack([t1, t2], axis=2)))
        fv = np.nonzero(self.feature)[0]
        if len(fv):
            E = self.feature_edges
            both = np.r_[E, E[:, ::-1]]
            both = both[np.argsort(both[:, 0], kind="stable")]
            start = np.searchsorted(both[:, 0], fv)
            n1, n2 = both[start, 1], both[start + 1, 1]  # a feature vertex has two feature neighbours
            u1 = V[n1] - V[fv]
            u2 = V[n2] - V[fv]
            t = u1 / np.linalg.norm(u1, axis=1, keepdims=True) - u2 / np.linalg.norm(u2, axis=1, keepdims=True)
            t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
            out.append((fv, t[:, :, None]))
        return out

    def project(self, V):
        V = V.copy()
        sv = np.nonzero(self.smooth)[0]
        if len(sv):
            _, _, q = self.surface.closest_points(V[sv])
            V[sv] = q
        fv = np.nonzero(self.feature)[0]
        if len(fv) and len(self.sharp[0]):
            V[fv] = _closest_on_segments(V[fv], *self.sharp)
        return V


def optimise(V: np.ndarray, H: np.ndarray, cell, motion: BoundaryMotion, anchor: np.ndarray | None = None,
             anchor_weight: float = 1.0, iters: int = 150, rounds: int = 2, callback=None,
             start: np.ndarray | None = None, power: float = 1.0) -> np.ndarray:
    """Minimise the corner energy over the vertex motions `motion` allows,
    projecting the boundary back after each round; cell: the cell size, or
    one per hex of H (a size field); anchor: (n,) bool, vertices pulled
    towards their places in V by a spring (per cell of displacement: the
    median cell); start: where the vertices start (V by default; a run with
    a weaker spring); callback(iteration, energy) after each L-BFGS
    iteration (it may raise to cancel); power: of each corner's energy
    (CornerEnergy), in the rounds that start with no corner inverted.
    Returns the new positions."""
    V0 = V.copy()
    V = (V if start is None else start).copy()
    a_idx = np.nonzero(anchor)[0] if anchor is not None else np.zeros(0, dtype=np.int64)
    n_corner = 8 * len(H)
    per_hex = np.asarray(cell, float)[..., None, None, None]  # broadcasts over (m, 8, 3, 3)
    unit = float(np.median(cell)) if np.size(cell) else 1.0  # (no cell to move: nothing is optimised)
    for _ in range(rounds):
        groups = motion.bases(V)
        if not sum(len(ids) for ids, _ in groups):
            break
        # the vertices of H (and any that move or are pulled), numbered
        # compactly: an evaluation touches them alone, not the whole mesh
        # (H is the active cells: 218k of the ball's 890k at ~1M cells)
        verts, Hc = np.unique(np.concatenate([H.reshape(-1), a_idx, *(ids for ids, _ in groups)]),
                              return_inverse=True)
        # in Morton order, the hexes by their first vertex: an evaluation's
        # gathers and scatters stay near each other (CHUNK)
        order = local_order(V[verts])
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        verts, Hc = verts[order], rank[Hc[:H.size].reshape(H.shape)]
        by_first = np.argsort(Hc.min(axis=1), kind="stable")
        Hc = Hc[by_first]
        P = V[H]
        E = (P[:, HEX_CORNER_NEIGHBOURS] - P[:, :, None, :]) / per_hex
        Dmin = float(det3(E.reshape(-1, 3, 3)).min())
        # eps from the worst corner: large while inverted, small once untangled
        eps = 1e-3 if Dmin > 0.05 else max(1e-3, float(np.sqrt(1e-6 + 0.01 * Dmin * Dmin)))
        # a power mean only once no corner is inverted: while one is, the
        # plain sum untangles (POWER)
        energy = CornerEnergy(Hc, cell if np.ndim(cell) == 0 else np.asarray(cell, float)[by_first], len(verts),
                              power if Dmin > 0 else 1.0)
        loc = np.full(len(V), -1, dtype=np.int64)
        loc[verts] = np.arange(len(verts))
        lids = [loc[ids] for ids, _ in groups]
        a_loc = loc[a_idx]
        Vs = V[verts]
        sizes = [ids.size * B.shape[2] for ids, B in groups]
        offs = np.r_[0, np.cumsum(sizes)]

        def positions(x):
            W = Vs.copy()
            for (ids, B), li, o0, o1 in zip(groups, lids, offs[:-1], offs[1:]):
                if len(ids):
                    W[li] += np.einsum("kij,kj->ki", B, x[o0:o1].reshape(len(ids), -1))
            return W

        def fun(x):
            W = positions(x)
            e, g = energy(W, eps)
            e /= n_corner
            g /= n_corner
            if len(a_idx):
                d = (W[a_loc] - V0[a_idx]) / unit
                e += anchor_weight * float(np.sum(d * d)) / len(a_idx)
                g[a_loc] += 2.0 * anchor_weight * d / unit / len(a_idx)
            gx = np.concatenate([np.einsum("kij,ki->kj", B, g[li]).reshape(-1) for (_, B), li in zip(groups, lids)])
            return e, gx

        res = lbfgs(fun, np.zeros(offs[-1]), max_iterations=iters, callback=callback)
        V[verts] = positions(res.x)
        V = motion.project(V)
    return V


# ------------------------------------------------------------ the policy


def curve_vertices(V: np.ndarray, cem, cell: float) -> list:
    """Per chain of the CurveEdgeMesh: the hex vertices lying on it (the map
    puts them there)."""
    X = cem.mesh.vertices
    tol = 1e-6 * cell
    out = []
    for ch in cem.chains:
        A, B = X[ch.vertices[:-1]], X[ch.vertices[1:]]
        # only the vertices in the chain's box are measured (at ~1M cells
        # every vertex against every segment took seconds per chain)
        P = X[ch.vertices]
        near = np.nonzero(np.all((V >= P.min(axis=0) - tol) & (V <= P.max(axis=0) + tol), axis=1))[0]
        out.append(near[segments_distance(V[near], A, B) <= tol])
    return out


def smooth_hexes(V: np.ndarray, H: np.ndarray, cell: float, inp, cem, callback=None,
                 rel: np.ndarray | None = None) -> np.ndarray:
    """Untangle and improve the vertex positions (``optimise``): interior
    vertices freely, boundary vertices along the input surface, vertices of
    sharp edges and of the network's feature curves along them (and the
    line of vertices nearest each of the field's bends, ``bend_edges``,
    first put onto it, its ends held), vertices of
    singular curves held by a spring (the weakest of SPRING, 3, 10 and 100
    times it that keeps them within 0.9 of a cell of their curves); kept
    only if the minimum scaled Jacobian does not drop.

    Parameters
    ----------
    V, H : (n, 3) float array, (m, 8) int array
        the extracted mesh
    cell : float
        the cell size
    inp : SolvedField
        the field meshed: its surface, sharp edges and network
    cem : curve_edges.CurveEdgeMesh
        the split tet mesh the map lives on (its chains are the curves)
    callback : callable(iteration, energy), optional
        after each L-BFGS iteration (it may raise to cancel)
    rel : (m,) float array, optional
        a size field: each cell's size over the cell size (sizing.py); the
        optimisation keeps each cell near its own size, and the curves'
        vertices within 0.9 of their cells

    Where the run took the boundary away from a stretch of the input surface
    (a surface sample farther than KEEP_SURFACE of the Hausdorff bar from
    it, and farther than the extracted mesh had it), the boundary vertices
    there are held at their extracted places and the run is made again
    (``surface_lost``); then the ring of them around the vertices nearest
    those samples is let go again, kept where the surface stays as close.

    Returns
    -------
    (n, 3) float array
        the new positions (V itself where no run kept the minimum)
    """
    held = np.zeros(len(V), bool)
    q, _ = boundary_quads(H)
    on_curve = curve_vertices(V, cem, cell)
    W = _smoothed(V, H, q, on_curve, cell, inp, callback, rel, held)
    tol = KEEP_SURFACE * HAUSDORFF_BAR * inp.surface.bbox_diagonal
    core = np.zeros(len(V), bool)
    for _ in range(SURFACE_ROUNDS):
        nearest = surface_lost(V, W, q, inp.surface, tol, rings=0)
        lost = _grown(q, nearest)
        if not np.any(lost & ~held):
            break
        core |= nearest
        held |= lost
        W = _smoothed(V, H, q, on_curve, cell, inp, callback, rel, held)
    if held.any():
        # hold no more than keeps the surface: the ring released, from
        # where the held run left it, and kept if the surface stays as close
        W2 = _smoothed(V, H, q, on_curve, cell, inp, callback, rel, core, start=W)
        if W2 is not W and not surface_lost(V, W2, q, inp.surface, tol, rings=0).any() \
                and _farthest(inp.surface, W2, q, tol) <= _farthest(inp.surface, W, q, tol):
            W = W2
    return W


def _farthest(S, W: np.ndarray, q: np.ndarray, tol: float) -> float:
    """The farthest sample of S from the quad boundary q of W, or tol if none
    is farther."""
    d = surface_left(S, W, q, tol)[1]
    return float(d.max()) if len(d) else tol


def _smoothed(V: np.ndarray, H: np.ndarray, q: np.ndarray, on_curve: list, cell: float, inp, callback, rel,
              held: np.ndarray, start: np.ndarray | None = None) -> np.ndarray:
    """One run of ``smooth_hexes``, the vertices in `held` (n,) bool not
    moving; from `start` (the positions of a run before) where given, the
    curves' vertices (`on_curve`, ``curve_vertices`` of V) those of V; q:
    the boundary quads of H."""
    if start is not None:
        V = start
    S = inp.surface
    fe, sa, sb = sharp_lines(V, q, S, inp.sharp, cell)
    segs_a, segs_b, lines = [sa], [sb], [fe]
    V0 = V
    V, be, bend_ends = snap_to_bends(V, q, inp, cell)
    if len(be):
        B = S.edges[inp.bends]
        lines.append(be)
        segs_a.append(S.V[B[:, 0]])
        segs_b.append(S.V[B[:, 1]])
    # hex edges along each feature curve, and the curve itself
    E = None
    fixed = held.copy()
    fixed[bend_ends] = True  # where a bend meets an outline: the corner it ends at
    onb = np.zeros(len(V), bool)
    onb[np.unique(q)] = True
    anchor = np.zeros(len(V), bool)
    for verts, c in zip(on_curve, inp.network.curves):
        if not len(verts):
            continue
        if c.sigma != 0:
            # singular curves, their ends on the surface too: held near the
            # map's place by a spring (the cells around nodes and ends need
            # room); the report checks that they stay within a cell
            anchor[verts] = True
            continue
        fixed[verts[onb[verts]]] = True  # where a feature curve meets the surface
        mark = np.zeros(len(V), bool)
        mark[verts] = True
        if E is None:  # the hex edges once (the first feature curve)
            E = H[:, HEX_EDGES].reshape(-1, 2)
        along = E[mark[E[:, 0]] & mark[E[:, 1]]]
        lines.append(unique_rows(np.sort(along, axis=1))[0] if len(along) else along)
        segs_a.append(c.points[:-1])
        segs_b.append(c.points[1:])
    sj = scaled_jacobian(V, H)
    best_min = float((sj if V is V0 else scaled_jacobian(V0, H)).min())  # the extracted mesh's
    free = active_vertices(len(V), H, sj, ACTIVE_BELOW, ACTIVE_RINGS)
    cells = free[H].any(axis=1)  # the cells whose energy changes
    motion = BoundaryMotion(V, q, np.vstack(lines), S, (np.vstack(segs_a), np.vstack(segs_b)), fixed).held(free)
    spring = anchor & ~fixed & free

    sing_curves = [c.points for c in inp.network.curves if c.sigma != 0]
    sv = np.nonzero(spring)[0]
    hex_cell, sv_cell = None, 1.0
    if rel is not None:  # moved() measures in cells of the size field: a vertex's smallest cell
        hex_cell = cell * np.asarray(rel, float)
        vertex_cell = np.full(len(V), np.inf)
        np.minimum.at(vertex_cell, H.reshape(-1), np.repeat(hex_cell, 8))
        sv_cell = vertex_cell[sv] / cell

    def moved(W):
        """Largest distance of a singular curve's vertex from the curves
        (in units of the cell size, over the size field's)."""
        if not len(sv):
            return 0.0
        return float((np.min([polyline_distance(P, W[sv]) for P in sing_curves], axis=0) / sv_cell).max())

    # the weakest spring that keeps the curves' vertices within 0.9 of a
    # cell of the curves, then the largest step towards the stiffest optimum
    # that keeps the minimum; each stiffer spring starts where the weaker
    # left the mesh: away from the curves it is at its optimum already (on
    # the ball at 233k cells the second spring then took 243 evaluations of
    # the energy, not 342, least and mean scaled Jacobian 0.415 / 0.980 as
    # before; bench/RESULTS.md)
    def run(weight, start, power=1.0):
        """optimise with this spring from `start` (None: V), or None where
        it diverged (non-finite positions)."""
        try:
            W = optimise(V, H[cells], cell if rel is None else hex_cell[cells], motion, anchor=spring,
                         anchor_weight=weight, callback=callback, start=start, power=power)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError):
            return None
        return W if np.all(np.isfinite(W)) else None

    def kept(W):
        return moved(W) <= 0.9 * cell and float(scaled_jacobian(W, H).min()) >= best_min

    W = V
    springs = (SPRING, 3 * SPRING, 10 * SPRING, 100 * SPRING)
    for k, weight in enumerate(springs):
        Wk = run(weight, None if W is V else W)
        if Wk is None:
            continue  # the next spring, or the map's own places
        W = Wk
        if kept(W):
            return _polished(W, H, lambda: run(springs[min(k + 1, len(springs) - 1)], W, POWER), kept)
    for a in (0.5, 0.25, 0.125):
        Wa = V + a * (W - V)
        if kept(Wa):
            return Wa
    if V is not V0 and kept(V):
        return V  # the bends' vertices snapped, nothing else moved
    return V0


def _polished(W: np.ndarray, H: np.ndarray, run, kept) -> np.ndarray:
    """W, or the run of the power mean from it (``run()``, POWER) where that
    keeps the curves within 0.9 of a cell (``kept``), raises the least
    scaled Jacobian and lowers the mean by at most POLISH_MEAN.  The caller
    runs it with a spring one step stiffer than the one W kept: the power
    pushes the curves' vertices harder than the sum does (the ball's stored
    field at 90,584 cells: with W's spring, 0.1, they went past 0.9 of a
    cell; with 0.3 they stayed, least cell 0.51 -> 0.64).  One run, so that
    its cost is bounded: at ~1M cells one run takes about as long as the
    sum's own (140 s), and there the curves moved too far with 0.3 as well."""
    if POWER == 1.0:
        return W
    Wp = run()
    if Wp is None or not kept(Wp):
        return W
    sj, sjp = scaled_jacobian(W, H), scaled_jacobian(Wp, H)
    return Wp if sjp.min() > sj.min() and sjp.mean() >= sj.mean() - POLISH_MEAN else W


def surface_lost(V0: np.ndarray, W: np.ndarray, q: np.ndarray, S, tol: float, rings: int = 1) -> np.ndarray:
    """(n,) bool: the boundary vertices near the stretches of the surface S
    that the smoothed positions W leave: its samples farther than tol from
    the quad boundary q of W and farther (by 5 %) than from that of the
    extracted positions V0 (a cap of a tip cut off when the cells around it
    were evened out).  Marked: the vertices of the quads nearest those
    samples and of `rings` rings of quads around them."""
    out = np.zeros(len(W), bool)
    X, d, near = surface_left(S, W, q, tol)
    if not len(X):
        return out
    d0 = quad_surface(V0, q).closest_points(X)[0]
    out[q[near[d > 1.05 * d0]]] = True
    for _ in range(rings):
        out = _grown(q, out)
    return out


def _grown(q: np.ndarray, mark: np.ndarray) -> np.ndarray:
    """`mark` (n,) bool and the vertices of every quad of q touching it."""
    out = mark.copy()
    out[q[mark[q].any(axis=1)]] = True
    return out


def active_vertices(n: int, H: np.ndarray, sj: np.ndarray, below: float = ACTIVE_BELOW,
                    rings: int = ACTIVE_RINGS) -> np.ndarray:
    """(n,) bool over the n vertices: those of the cells whose scaled
    Jacobian `sj` is below `below`, and of `rings` rings of cells around
    them."""
    free = np.zeros(n, bool)
    free[H[sj < below]] = True
    for _ in range(rings):
        free[H[free[H].any(axis=1)]] = True
    return free


def sharp_lines(V: np.ndarray, quads: np.ndarray, S, sharp: np.ndarray, cell: float):
    """The creases of the hex boundary that follow the input's sharp edges
    (a crease the cells make on a smooth bend is smoothed like the surface):
    ((k, 2) their edges, and the sharp edges' segments A, B)."""
    E = S.edges[sharp]
    A, B = S.V[E[:, 0]], S.V[E[:, 1]]
    fe = feature_edges(quads, V)
    if len(fe) and len(E):
        fe = fe[segments_distance(0.5 * (V[fe[:, 0]] + V[fe[:, 1]]), A, B) <= 0.25 * cell]
    return (fe if len(E) else fe[:0]), A, B


def snap_to_bends(V: np.ndarray, quads: np.ndarray, inp, cell: float):
    """The creases the corner quantisation made smooth bends of the wall
    (``inp.bends``, corners.py): the line of boundary vertices that runs
    along each (``bend_edges``) put onto it.  Returns (positions, (k, 2)
    those lines' edges, the vertices where they end: at the corners)."""
    none = np.zeros((0, 2), np.int64)
    if inp.bends is None or not np.any(inp.bends):
        return V, none, none[:, 0]
    S = inp.surface
    B = S.edges[np.asarray(inp.bends, bool)]
    ba, bb = S.V[B[:, 0]], S.V[B[:, 1]]
    be = bend_edges(quads, V, ba, bb, cell)
    if not len(be):
        return V, none, none[:, 0]
    V = V.copy()
    vb = np.unique(be)
    V[vb] = _closest_on_segments(V[vb], ba, bb)
    return V, be, np.nonzero(np.bincount(be.reshape(-1), minlength=len(V)) == 1)[0]


def bend_edges(quads: np.ndarray, V: np.ndarray, A: np.ndarray, B: np.ndarray, cell: float) -> np.ndarray:
    """(k, 2) edges of the quad boundary that run along the segments (A, B)
    (creases of the surface the cells would cut): per crease (a connected
    chain of segments), the chain of boundary edges nearest it whose ends
    lie within a cell of it and whose projection onto it keeps at
    least 0.7 of their length (an edge across it projects to about a
    point); one chain per crease, so that two grid lines never both go
    onto it."""
    E = unique_rows(np.sort(np.stack([quads, np.roll(quads, -1, axis=1)], axis=2).reshape(-1, 2), axis=1))[0]
    dist = segments_distance(V, A, B)
    E = E[(dist[E[:, 0]] <= cell) & (dist[E[:, 1]] <= cell)]
    if not len(E):
        return E
    P0, P1 = _closest_on_segments(V[E[:, 0]], A, B), _closest_on_segments(V[E[:, 1]], A, B)
    E = E[np.linalg.norm(P1 - P0, axis=1) >= 0.7 * np.linalg.norm(V[E[:, 1]] - V[E[:, 0]], axis=1)]
    if not len(E):
        return E
    # the creases: chains of segments sharing end points
    X = np.vstack([A, B])
    _, key = np.unique(np.round(X / (1e-9 + 1e-6 * cell)).astype(np.int64), axis=0, return_inverse=True)
    ns = len(A)
    G = sp.coo_matrix((np.ones(ns), (key[:ns], key[ns:])), shape=(key.max() + 1,) * 2)
    _, crease_of_point = csgraph.connected_components(G, directed=False)
    crease = crease_of_point[key[:ns]]
    # the chains of hex edges, each on the crease nearest its middle
    nv = len(V)
    C = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(nv, nv))
    _, chain_of = csgraph.connected_components(C, directed=False)
    chain = chain_of[E[:, 0]]
    mid = 0.5 * (V[E[:, 0]] + V[E[:, 1]])
    _, seg = cKDTree(0.5 * (A + B)).query(mid)  # the segment with the nearest middle: its crease
    on = crease[seg]
    keep = np.zeros(len(E), bool)
    for c in np.unique(on):
        mine = on == c
        chains = np.unique(chain[mine])
        mean = [float(np.mean(dist[E[mine & (chain == k)]])) for k in chains]
        keep |= mine & (chain == chains[int(np.argmin(mean))])
    return E[keep]


def feature_edges(quads: np.ndarray, V: np.ndarray) -> np.ndarray:
    """(k, 2) edges of the quad boundary whose two quads meet at more than
    SHARP_DIHEDRAL degrees."""
    Q = quads
    P = V[Q]
    n = np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 1])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    E = np.stack([Q, np.roll(Q, -1, axis=1)], axis=2).reshape(-1, 2)
    key = np.sort(E, axis=1)
    f = np.repeat(np.arange(len(Q)), 4)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, f = key[order], f[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    i = np.nonzero(same)[0]
    cosang = np.einsum("ij,ij->i", n[f[i]], n[f[i + 1]])
    return key[i[cosang < np.cos(np.radians(SHARP_DIHEDRAL))]]
