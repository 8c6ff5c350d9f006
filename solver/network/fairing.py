"""Fairing: a chain of mesh edges made a smooth curve at the scale of the mesh.

A chain of mesh edges zig-zags and holds tiny segments (intake.py); at the
scale h of the tet mesh it is a smooth curve.  ``fair_curve`` cleans and
fairs it at a length tied to the mesh, never to the bounding box:

1. *merge*: consecutive points closer than ``MERGE * h`` are dropped;
2. *fairing length*: ``l = max(h, median segment length)`` -- a chain of
   mesh edges carries no shape below its own edge length;
3. *corners*: where the curve turns by more than ``MAX_KINK``
   between chords of length ``CORNER_WINDOW * l`` on either side and
   between chords twice as long (both fitting on the curve), but there by
   less than 1.5 times as much, and so between chords four times as long
   where they fit (a corner, not an arc or a bump), the
   input vertex nearest the largest turn is kept as a knot (a real
   corner survives and validation reports it as it would have);
4. *resample* between ends and corners by arc length at spacing ``l / 2``;
5. *fair*: ``SMOOTH_ITERATIONS`` = 72 steps of Laplacian smoothing
   ``P_i += 1/2 (P_(i-1) + P_(i+1) - 2 P_i) / 2`` with ends, nodes and corners
   fixed -- a Gaussian of width 3 l along the curve: the zig-zag of mesh
   edges goes, and so does a bend shorter than a few l between fixed points
   (a chain of 3-4 mesh edges carries no shape of its own), and an arc of
   radius R moves inwards by about 4.5 l^2 / R (a loop of radius 6.7 h by
   0.5 h; reported).  A closed loop then gets the smoothed residual back
   (Tukey's twicing: a smooth loop ``TWICINGS`` times, a chain once): the shrinking goes (to 0.01 h) and the
   zig-zag stays gone.  A curve whose faired points would leave the solid
   keeps its resampled points;
5b. *least bending*: the Gaussian keeps the long bow of a chain that
   strays to one side along its whole length, and the field pays for
   every bend of a singular curve (the structure penalty grows with the
   square of the curvature: the straight clean cylinder network scores
   0.0018, its curves bowed to turn 2.3 degrees over h 0.0099, 7 degrees
   0.090, with fairing alone, which kept those bows).  So an open curve
   is then bent as little as it can be while every point stays within
   the input's own uncertainty of it (``_least_bending``): ``ROUGH``
   times the input's roughness there (``roughness``), between
   ``SMOOTH_BAND * h`` and ``BAND * l`` -- about an edge for a chain of
   mesh edges, a fifth of h for a smooth curve -- and near a boundary end
   as far as the end may slide: the least sum of
   |P_(i-1) - 2 P_i + P_(i+1)|^2 (a discrete cubic spline) with nodes and corners held, boundary ends
   free to move in their tangent plane (by at most ``SLIDE_MAX`` h from the
   input end for a smooth curve, ``SLIDE_MAX`` l for a chain of mesh
   edges) and the curve meeting the surface along the normal
   (each end's neighbour against its mirror image in that plane); points
   beyond the band are pulled back to its edge by a penalty that grows
   from faint round by round.  A shape smaller than an edge of the chain
   goes (the tet-edge cylinder's curves come out straight), a larger one
   is kept to within l;
6. *sliding ends*: a boundary end slides along the surface while the curve is
   faired: it is smoothed against the mirror image of its neighbour in the
   tangent plane (the curve continued by reflection, which crosses the
   surface at right angles), so it moves towards the foot of the curve
   and the last stretch turns onto the normal smoothly, over the fairing
   width (by at most ``SLIDE_MAX`` times what the input leaves uncertain
   there: half an edge of a chain's mesh, h/2 for a smooth curve, however
   long its segments; the hex cells of the default size are 0.8-0.9 h, and
   ends slid a whole h left the given radial curves of ellipsoids 50-85 %
   within a cell of the hex mesh's irregular edges, 100 % at half; the
   plane follows the surface).  What the slide leaves of the end's angle is bent within the
   curve.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.linalg import solve_banded
from scipy.spatial import cKDTree

from .curves import CurveGeometry
from .polyline import arclength, merge_close, resample, turning

MAX_KINK = 45.0  # degrees a singular curve may turn over a length h (chords of h/2 each side)
MERGE = 0.05  # points closer than MERGE * h are merged
CORNER_WINDOW = 2.0  # chords of CORNER_WINDOW * l on each side detect real corners ...
ARM_STRAIGHT = 0.25  # ... between arms within this many l of their chords
TWICINGS = 3  # a smooth loop gets the smoothed residual back this many times (a chain once: Tukey's twicing)
SMOOTH_ITERATIONS = 72  # Laplacian steps of 1/2 at spacing l / 2: a Gaussian of width 3 l
BAND = 1.0  # least bending keeps every point within BAND * l of the input, at most ...
ROUGH = 3.0  # ... and within ROUGH times the input's own roughness (roughness())
SMOOTH_BAND = 0.2  # ... but never closer than SMOOTH_BAND * h: a smooth input is kept to a fifth of an edge
END_REACH = 4.0  # ... and near a boundary end within its slide, over END_REACH * l
SLIDE_MAX = 0.5  # a boundary end slides along the surface by at most this many h (a smooth curve) or l ...
FREE_SLIDE_MAX = 1.0  # ... this many where no slide limit is given (an end far off the normal)
SMOOTH_ROUGH = 0.05  # a polyline straying less than this much of a segment at its median vertex is smooth,
SMOOTH_THIRD = 0.25  # ... or whose median third difference is below this much of a segment


def _corner_knots(P: np.ndarray, ell: float, closed: bool) -> np.ndarray:
    """Indices of input vertices where the curve really turns: the turn
    between chords of CORNER_WINDOW * ell exceeds MAX_KINK, at its largest."""

    if len(P) < 3:
        return np.zeros(0, int)
    cum = arclength(P)
    fine = resample(P, ell / 4.0)
    sf = arclength(fine)
    w = CORNER_WINDOW * ell
    ang = turning(fine, w, closed)
    # A corner has straight arms: the turn is over MAX_KINK between chords
    # of w and still between chords of 2 w, but there less than 1.5 times
    # as much.  An arc's turn doubles with the chords; a bump's -- a
    # tet-edge chain straying by an edge to one side and back -- averages
    # out.  Both chords of 2 w must fit on the curve: nearer an end (or on
    # a curve shorter than four windows) a corner cannot be told from a
    # bump of the chain's own edges.  (With chords of w alone, bumps on
    # the tet-edge cylinder turning 45-50 degrees between chords of 2 l
    # were kept as corners in about 1 chain in 10; the faired curves then
    # kinked by 16-32 degrees over h, and LM ended with a penalty of 3-31
    # or at its cap.)
    wide = turning(fine, 2.0 * w, closed)
    big = (ang > MAX_KINK) & (wide > MAX_KINK) & (wide < 1.5 * ang)
    if not closed:
        big &= (sf >= 2.0 * w) & (sf <= sf[-1] - 2.0 * w)
    # ... and again between chords of 4 w, where they fit: a tight arc turns
    # about twice as much again, a corner with straight arms no more.  (A
    # tet-edge chain round a loop of radius 4 l zig-zags by 20-30 degrees
    # between chords of w, so its arc's 28 read as 45-60 and 55-62 between
    # chords of 2 w: a corner, and the loop was refused as turning by 55-81
    # degrees over h, 3 routings of the hexnet torus in 6.)  A loop shorter
    # than eight windows has no corner that can be told from its own turn.
    L = sf[-1]
    if closed and L <= 8.0 * w:
        return np.zeros(0, int)
    fits = np.ones(len(sf), bool) if closed else (sf >= 4.0 * w) & (sf <= L - 4.0 * w)
    if np.any(big & fits):
        big &= ~fits | (turning(fine, 4.0 * w, closed) < 1.5 * ang)
    # ... and its arms are straight: a tet-edge chain that detours by an
    # edge on a tight arc turns like a corner at both chords (a loop of
    # radius 5 l: 66-78 degrees between chords of w, 67-87 between chords
    # of 2 w), but its arms are as rough as the chain, where a corner the
    # user drew has straight ones
    if np.any(big):
        big &= _straight_arms(fine, sf, w, ell, closed, big)
    knots = []
    i = 0
    while i < len(ang):
        if not big[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(ang) and big[j + 1]:
            j += 1
        m = i + int(np.argmax(ang[i : j + 1]))
        v = int(np.argmin(np.abs(cum - sf[m])))
        if 0 < v < len(P) - 1:
            knots.append(v)
        i = j + 1
    return np.unique(np.array(knots, int))


def _straight_arms(fine: np.ndarray, sf: np.ndarray, w: float, ell: float, closed: bool,
                   where: np.ndarray) -> np.ndarray:
    """At each sample of ``where``: whether the curve's stretches from w / 4
    to 2 w on either side each lie within ``ARM_STRAIGHT * ell`` of their
    chord (elsewhere True)."""
    out = np.ones(len(fine), bool)
    n, L = len(fine), sf[-1]
    step = L / max(n - 1, 1)
    for m in np.nonzero(where)[0]:
        for lo, hi in ((-2.0 * w, -0.25 * w), (0.25 * w, 2.0 * w)):
            k = np.arange(int(np.floor(lo / step)), int(np.ceil(hi / step)) + 1) + m
            k = np.mod(k, n - 1) if closed else k[(k >= 0) & (k < n)]
            if len(k) < 3:
                continue
            A = fine[k]
            c = A[-1] - A[0]
            c = c / max(np.linalg.norm(c), 1e-300)
            r = A - A[0]
            dev = np.linalg.norm(r - (r @ c)[:, None] * c, axis=1).max()
            if dev > ARM_STRAIGHT * ell:
                out[m] = False
    return out


def roughness(P: np.ndarray, reach: int = 2) -> np.ndarray:
    """How far the polyline P strays from smooth near each vertex: at
    vertex i, |P_(i-1) - 2 P_i + P_(i+1)| / 2 (its distance from the
    midpoint of its neighbours), the largest within ``reach`` vertices.
    A chain of tet edges zig-zags by a large part of an edge (0.3-0.5 of
    it) and strays in bumps of an edge or more; a curve read off a hex mesh
    or drawn smooth strays only by its curvature (s^2 / 2R at spacing s on
    a radius R), a few thousandths of an edge."""
    r = np.zeros(len(P))
    if len(P) < 3:
        return r
    r[1:-1] = np.linalg.norm(P[:-2] - 2.0 * P[1:-1] + P[2:], axis=1) / 2.0
    pad = np.r_[np.zeros(reach), r, np.zeros(reach)]
    return np.max(np.lib.stride_tricks.sliding_window_view(pad, 2 * reach + 1), axis=1)


def _smooth(P: np.ndarray, closed: bool = False) -> bool:
    """Whether the polyline P is a smooth curve rather than a chain of mesh
    edges: at least five points, and at its median vertex it strays from
    the middle of its neighbours (``roughness``) by less than
    ``SMOOTH_ROUGH`` of its median segment s, or its third difference
    |P_(i-1) - 3 P_i + 3 P_(i+1) - P_(i+2)| is less than ``SMOOTH_THIRD`` s.
    A chain of tet edges zig-zags by 0.3-0.5 of an edge at most of its
    vertices, 1-2 s in third differences; a curve drawn smooth strays by a
    few thousandths and more only at its real corners, and a coarse one
    read off a hex mesh turns the same way from vertex to vertex: a ring of
    22 edges strays by 0.14 s, (s / R)^2 s = 0.08 s in third differences.
    (A chain of one to three edges reads as a chain.)"""
    if len(P) < 5:
        return False
    Q = np.vstack([P[:-1], P[:3]]) if closed and np.allclose(P[0], P[-1]) else P
    seg = float(np.median(np.linalg.norm(np.diff(Q, axis=0), axis=1)))
    third = np.linalg.norm(Q[:-3] - 3.0 * Q[1:-2] + 3.0 * Q[2:-1] - Q[3:], axis=1)
    return (float(np.median(roughness(Q, reach=0)[1:-1])) < SMOOTH_ROUGH * seg
            or float(np.median(third)) < SMOOTH_THIRD * seg)


def _laplacian_fair(P: np.ndarray, fixed: np.ndarray, closed: bool, iterations: int,
                    slide: dict | None = None, slide_max: dict | None = None, project=None) -> np.ndarray:
    """Explicit Laplacian smoothing (step 1/2) with the fixed vertices held.
    k steps at spacing s act like a Gaussian of width s sqrt(k / 2) along the
    curve.  (Taubin's lambda|mu filter, tried first, keeps bends longer than
    ~6 l: on tet-edge chains of 3-4 edges that is the zig-zag itself, and the
    ball's LM then ended at its cap with a penalty of 956.)

    slide : {0 or -1: outward unit normal} -- open ends lying on the surface.
    Such an end is smoothed against the mirror image of its neighbour in the
    tangent plane (the curve continued by reflection, which meets the plane
    at right angles): it slides in the plane towards the foot of its
    neighbour, by at most slide_max[end] in all, and the curve's last stretch
    turns towards the normal smoothly, over the filter's width.  project(x)
    -> (closest surface point, its outward normal): every 8 steps the end
    is put back on the surface and the plane follows it."""
    Q = P.copy()
    n = len(Q) - 1 if closed else len(Q)
    core = Q[:n]
    free = ~fixed[:n].copy()
    if not closed:
        free[[0, -1]] = False
    ends = [] if closed or not slide else [[i % n, (1 if i == 0 else n - 2), np.asarray(v, float)]
                                           for i, v in slide.items() if n > 2]
    start = {e[0]: core[e[0]].copy() for e in ends}
    limits = {k % n: float(slide_max[k]) for k in (slide or {})} if n > 2 else {}
    for step in range(iterations):
        if project is not None and step and step % 8 == 0:
            for e in ends:
                core[e[0]], e[2] = project(core[e[0]])
        if closed:
            lap = 0.5 * (np.roll(core, 1, axis=0) + np.roll(core, -1, axis=0)) - core
        else:
            lap = np.zeros_like(core)
            lap[1:-1] = 0.5 * (core[:-2] + core[2:]) - core[1:-1]
        for i, j, nrm in ends:
            d = core[j] - core[i]
            lap[i] = d - (d @ nrm) * nrm
        core[free] += 0.5 * lap[free]
        for i, _, _ in ends:
            x = core[i] + 0.5 * lap[i]
            off = x - start[i]
            r = np.linalg.norm(off)
            lim = limits[i]
            core[i] = x if r <= lim else start[i] + off * (lim / max(r, 1e-300))
    Q[:n] = core
    if closed:
        Q[-1] = Q[0]
    return Q


def fair_curve(P: np.ndarray, h: float, closed: bool, slide: dict | None = None, project=None,
               slide_limit: dict | None = None):
    """Steps 1-5 of the module docstring.  slide: {0 or -1: outward normal}
    of boundary ends that may slide along the surface (``_laplacian_fair``;
    by at most ``SLIDE_MAX`` h for a smooth curve (``_smooth``), l for a
    chain, or by slide_limit[end] (a length) where given and smaller; with
    no slide_limit, by ``FREE_SLIDE_MAX`` h or l, every
    point within ``BAND * l``; project: its surface projection).
    Returns (points, merged count, fairing length l, corner count, fixed
    mask)."""
    Pm = merge_close(P, MERGE * h, closed)
    merged = len(P) - len(Pm)
    seg = np.linalg.norm(np.diff(Pm, axis=0), axis=1)
    ell = max(h, float(np.median(seg)))
    L = float(seg.sum())
    knots = _corner_knots(Pm, ell, closed)
    cuts = np.r_[0, knots, len(Pm) - 1]
    pieces, fixed = [], []
    for a, b in zip(cuts[:-1], cuts[1:]):
        R = resample(Pm[a : b + 1], 0.5 * min(ell, max(L / 4.0, 1e-300)))
        pieces.append(R if not pieces else R[1:])
        f = np.zeros(len(pieces[-1]), bool)
        f[-1] = True
        if len(fixed) == 0:
            f[0] = True
        fixed.append(f)
    Q = np.vstack(pieces)
    fx = np.concatenate(fixed)
    if closed and not len(knots):
        fx[[0, -1]] = False  # a loop's seam is no end
    # Tukey's twicing, adding back the smoothed residual, keeps a loop of
    # radius 6.7 h round (0.5 h of shrinking -> 0.01 h), so loops get it; it
    # also keeps the bow of tet-edge chains near their ends, so open curves
    # do not (on the tet-edge cylinder they moved by up to 1.1 h, turned 19
    # degrees over h, and LM took 19 iterations to a penalty of 157, against
    # 0.8 h, 9 degrees, 7-9 and 67 without; least bending straightens them)
    # the input's own uncertainty: a chain of mesh edges is known to about
    # an edge (l), a smooth curve to its roughness, and is moved no further
    # (a smooth bent bar's curves, read off a hex mesh, were straightened by
    # a whole l towards least bending, 0.15 on average: 20 % of them then
    # lay within a cell of the hex mesh's irregular edges)
    if slide_limit is None and slide:
        # an end far off the normal (intake.FREE_SLIDE): the curve moves as
        # the chain's own uncertainty allows, a whole edge (a radial curve
        # bowed by 0.45 of its length, 69 degrees off, held to its roughness
        # and half an edge, kinked by 66 degrees at every local scale)
        # (a smooth curve's end by as many h: its points are where they were put)
        band_at = np.full(len(Pm), BAND * ell)
        lim = {e: FREE_SLIDE_MAX * (h if _smooth(Pm) else ell) for e in slide}
    else:
        band_at = np.clip(ROUGH * roughness(Pm), SMOOTH_BAND * h, BAND * ell)
        # an end slides by at most SLIDE_MAX times what the input leaves
        # uncertain: an edge of a chain of mesh edges, h for a smooth curve,
        # whose points are where the user put them however long its
        # segments (a straight curve of 3.2 h segments reaching a cap 45
        # degrees off the normal slid 1.6 h, half a segment; now h/2, the
        # rest bent: tests/test_intake.py)
        unc = h if _smooth(Pm) else ell
        lim = {e: min(SLIDE_MAX * unc, float((slide_limit or {}).get(e, np.inf))) for e in (slide or {})}
    # near a boundary end the curve turns onto the normal: there it may
    # move as far as the end may slide, less and less over END_REACH l (a
    # bow reaching the caps 32 degrees off, held to its roughness, turned
    # 20 degrees over h at its ends; spread over this reach, 3)
    cum = arclength(Pm)
    for e in lim:
        along = cum if e == 0 else cum[-1] - cum
        band_at = np.maximum(band_at, lim[e] * np.clip(1.0 - along / (END_REACH * ell), 0.0, 1.0))
    Q0 = Q
    Q = _laplacian_fair(Q, fx, closed, SMOOTH_ITERATIONS, slide, lim, project)
    if closed and len(Q) > 3:
        # (a smooth loop three times: a coarse one, its fairing length an edge of 1.9 h,
        # shrank by 31 % under the Gaussian and still by 10 % after one
        # twicing -- the residual goes as (1 - a)^(k+1) for a mode the
        # Gaussian keeps a of -- a collared shaft's ring, read off a hex
        # mesh, moved 0.7 h inwards, 1.4 cells off the hex mesh's irregular
        # edges; 1.3 % and 0.09 h after three.  A chain of tet edges once:
        # its routed bumps came back with more, and the tet-edge torus's
        # penalty went from 1.3 to 3.2 on one network)
        for _ in range(TWICINGS if _smooth(Pm, closed) else 1):
            Q = Q + _laplacian_fair(Q0 - Q, fx, closed, SMOOTH_ITERATIONS)
    if not closed and len(Q) > 2:
        ends = []
        for e in slide or {}:
            i = e % len(Q)
            nrm = project(Q[i])[1] if project is not None else np.asarray(slide[e], float)
            ends.append((i, 1 if i == 0 else len(Q) - 2, nrm))
        held = {i: lim[e] for e, (i, _, _) in zip(slide, ends)}
        Q = _least_bending(Q, fx, ends, Pm, band_at[cKDTree(Pm).query(Q)[1]], held)
        if project is not None:
            for i, _, _ in ends:
                Q[i] = project(Q[i])[0]
    return Q, merged, ell, len(knots), fx


def _least_bending(Q: np.ndarray, fixed: np.ndarray, ends: list, guide: np.ndarray, band: np.ndarray,
                   slide_max: dict, rounds: int = 80) -> np.ndarray:
    """Step 5b of the module docstring: the open polyline Q bent as little
    as it can be -- the least sum of |P_(i-1) - 2 P_i + P_(i+1)|^2 over the
    points not centred on a fixed one -- with the fixed points held and
    each point within its band (an array, one per point) of the polyline
    guide.  (Not for loops: with
    nothing held the sum shrinks a loop.)

    ends : (end index, its neighbour, unit outward normal) of boundary ends.
           Such an end moves in its tangent plane only (a stiff term
           PLANE (n . (P - P_end))^2); the term |2 (I - n n^T)(P_neighbour -
           P_end)|^2 (the neighbour against its mirror image in the plane)
           makes the curve meet the surface along the normal; it stays
           within slide_max[end index] of the guide's end.  The other end points
           stay where they are.
    Points beyond the band (ends: beyond slide_max) are pulled to its edge
    with a weight mu that starts faint (1e-4, against bending terms of
    order 1) and doubles each round up to PLANE, until none is 1 % past
    it: the pull follows the least-bending curve as the band closes in.
    (Starting stiff froze the first round's points at the band's edge:
    where no straight line fits, the bend gathered into a bump of 12
    degrees over h at the input's apex instead of spreading over the curve
    at 2.)
    """
    n = len(Q)
    PLANE = 1e6
    free = ~fixed
    free[[0, -1]] = False
    c = np.arange(1, n - 1)
    c = c[free[c]]
    D = sp.csr_matrix((np.tile([1.0, -2.0, 1.0], len(c)),
                       (np.repeat(np.arange(len(c)), 3), np.stack([c - 1, c, c + 1], 1).ravel())),
                      shape=(len(c), n))
    blocks = [sp.kron(D, sp.identity(3), format="csr")]
    stiff = sp.lil_matrix((3 * n, 3 * n))
    plane_rhs = np.zeros(3 * n)
    r, k = np.repeat(np.arange(3), 3), np.tile(np.arange(3), 3)
    for i, j, nrm in ends:
        T = 2.0 * (np.eye(3) - np.outer(nrm, nrm))
        blocks.append(sp.csr_matrix((np.r_[T.ravel(), -T.ravel()], (np.r_[r, r], np.r_[3 * j + k, 3 * i + k])),
                                    shape=(3, 3 * n)))
        N = PLANE * np.outer(nrm, nrm)
        stiff[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = N
        plane_rhs[3 * i : 3 * i + 3] = N @ Q[i]
        free[i] = True
    if not free.any():
        return Q
    G = sp.vstack(blocks).tocsr()
    H = (G.T @ G + stiff.tocsr()).tocsr()
    f3 = np.repeat(free, 3)
    x = Q.ravel().copy()
    target = x.copy()
    w = np.full(3 * n, 1e-8)  # the faintest pull: to the faired curve, then to the last round's
    geo = CurveGeometry(guide)
    mu = 1e-4
    # each round solves (H + diag w) x = w target + plane_rhs for the free
    # coordinates, the others held: only the diagonal changes, and H
    # couples each point only with those up to two places along the curve,
    # so the free block is banded (LAPACK's banded LU, not a sparse LU each
    # round)
    Hff = H[f3][:, f3].tocoo()
    held = H[f3][:, ~f3] @ x[~f3]
    lower, upper, ab = _band_storage(Hff)
    main = ab[upper].copy()
    for _ in range(rounds):
        ab[upper] = main + w[f3]
        x[f3] = solve_banded((lower, upper), ab, (w * target + plane_rhs)[f3] - held,
                             overwrite_b=True, check_finite=False)
        X = x.reshape(n, 3)
        s, t, d = geo.closest(X)
        foot = geo.point(s, t)
        lim = np.array(band, float)
        for i, _, _ in ends:
            foot[i] = guide[0] if i == 0 else guide[-1]
            d[i] = np.linalg.norm(X[i] - foot[i])
            lim[i] = slide_max[i]
        out = free & (d > lim)
        if not np.any(free & (d > 1.01 * lim)):
            break
        target = x.copy()
        tg = target.reshape(n, 3)
        tg[out] = foot[out] + (lim[out] / d[out])[:, None] * (X[out] - foot[out])
        w = np.full(3 * n, 1e-8)
        w.reshape(n, 3)[out] = mu
        mu = min(2.0 * mu, PLANE)
    return x.reshape(n, 3)


def _band_storage(M: sp.coo_matrix) -> tuple[int, int, np.ndarray]:
    """(lower bandwidth, upper bandwidth, M in the band storage of
    scipy.linalg.solve_banded: ab[upper + i - j, j] = M[i, j])."""
    off = M.row - M.col
    lower, upper = max(int(off.max(initial=0)), 0), max(int(-off.min(initial=0)), 0)
    ab = np.zeros((lower + upper + 1, M.shape[1]))
    np.add.at(ab, (upper + off, M.col), M.data)
    return lower, upper, ab
