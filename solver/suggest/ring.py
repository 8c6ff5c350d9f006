"""The ring route: a network for a solid of revolution around an axis outside it.

A torus, a washer, a pipe, an O-ring or a tyre is a ring: its boundary is a
surface of revolution and its axis does not pass through the solid (the
solid is genus 1).  A polycube in the world frame cuts a ring into a square
ring of 10 charts and 16 corners, each a node under the surface, with 40
curves (docs/suggest.md); on `torus_surface()` two of those nodes lie 0.107
apart and the field's mesh cannot resolve them within its budget.  In the
frame that turns with the ring, (e_r, e_theta, e_z), the boundary's normals
have no e_theta part, so the polycube of a ring has only the labels +-r and
+-z: its charts are bands around the axis, their boundaries are circles, and
there is no corner.  Padding it (each band moved in by the depth along its
label, as build.py does in a fixed frame) gives closed singular loops and no
node: +1/4 under a convex boundary of the profile, -1/4 under a concave one.
The swept O-grid of a torus (4 loops of +1/4) is this network; a washer or a
pipe with sharp rims needs no curve at all.

Steps (``ring_network``):

1. **Axis.** A surface of revolution's normal lines all meet its axis
   (Pottmann and Wallner, *Computational Line Geometry*, 2001, §7.2): with
   the normal line of face f as the Pluecker pair (n_f, p_f x n_f) and the
   axis as (a, c x a), each face asks a . (p_f x n_f) + n_f . (c x a) = 0,
   linear in (a, c x a).  The least squares over the faces (area-weighted),
   with |a| = 1, is the smallest eigenvector of a 3 x 3 Schur complement.
   The surface is a ring when its Euler characteristic is 0 and the normals'
   e_theta parts are small (``TILT_RMS``, ``TILT_MAX``).
2. **Profile.** The surface cut by one half-plane through the axis: a closed
   polygon in (r, z), oriented with the solid on its left.
3. **Charts.** Each profile segment takes the label of its outward normal
   (+r, -r, +z, -z); runs of one label shorter than ``MIN_RUN`` of the
   profile join a neighbour.  A label change on a sharp crease is kept sharp
   (no curve); a smooth one becomes a loop at p - delta (d_a + d_b).
4. **Depth.** ``DEPTH`` times the median chord of the bands next to smooth
   boundaries (the O-grid of a disk of radius rho puts its inner square's
   corners at 0.45 rho: depth 0.26 rho, 0.18 of a quarter's chord), lowered
   (x 0.8) until each loop is at least ``CLEARANCE`` depth inside the
   profile and from the other loops.

A solid that is not a ring, or whose profile's labels make no valid
rectilinear polygon (two opposite labels next to each other), is left to the
padded polycube (``ring_network`` returns None).

``axial_network`` takes a solid of revolution the axis passes through (a
cylinder with a boss, a stepped shaft; genus 0), where the padded polycube
failed: its profile runs from the axis to the axis, the caps there flat and
bounded by sharp rims; four +1/4 curves along the axis at ``AXIAL`` times
the narrowest radius between the caps (the O-grid of every cross-section)
run from cap to cap, and each smooth turn of the profile gets a loop as on
a ring.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..network.network import Curve
from ..surface.trisurface import TriSurface

TILT_RMS = 0.08  # area-weighted RMS of the normals' e_theta parts for a surface of revolution ...
TILT_MAX = 0.3  # ... and their largest
MIN_RUN = 0.02  # a profile run of one label shorter than this share of the profile joins a neighbour
DEPTH = 0.18  # the depth as a share of the median chord of the bands next to smooth boundaries
CLEARANCE = 0.7  # each loop stays this many depths inside the profile and from the other loops
AXIAL = 0.45  # the axial curves of a solid the axis passes through, at this share of its narrowest radius
# labels in the ring's frame: +r, -r, +z, -z (the report writes them as +X, -X, +Z, -Z of frame rows u, v, a)
RING_LABELS = ("+r", "-r", "+z", "-z")
_DIRS = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
_AS_POLYCUBE = np.array([0, 1, 4, 5])


def fit_axis(S: TriSurface) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The axis (point c, unit direction a) whose lines the faces' normal
    lines meet best, and each face's e_theta part of its normal."""
    N, A = S.face_normals, S.face_areas / S.face_areas.sum()
    P = S.V[S.F].mean(axis=1)
    c0 = A @ P
    P = P - c0  # about the centroid: better conditioned
    M = np.cross(P, N)
    X = np.c_[M, N] * np.sqrt(A)[:, None]
    G = X.T @ X
    Gaa, Gam, Gmm = G[:3, :3], G[:3, 3:], G[3:, 3:]
    # min over m of [a; m]^T G [a; m]: m = -Gmm^-1 Gam^T a, leaving the Schur complement in a
    K = np.linalg.solve(Gmm, Gam.T)
    _, vec = np.linalg.eigh(Gaa - Gam @ K)
    a = vec[:, 0]
    m = -K @ a  # = c x a
    c = c0 + np.cross(a, m)
    return c, a, tilts(S, c, a)


def tilts(S: TriSurface, c: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Each face's normal's component along e_theta about the axis (c, a)."""
    P = S.V[S.F].mean(axis=1) - c
    t = np.cross(a, P)
    n = np.linalg.norm(t, axis=1)
    return np.einsum("ij,ij->i", S.face_normals, t) / np.maximum(n, 1e-300)


def profile(S: TriSurface, c: np.ndarray, a: np.ndarray, sharp: np.ndarray):
    """The surface cut by a half-plane through the axis: ((k, 2) points in
    (r, z), (k,) sharp flags, u, closed) with the solid on the polygon's
    left, u the half-plane's direction.  A ring's cut is one closed loop; a
    solid the axis passes through is cut in one chain from the axis to the
    axis, returned closed through it (its first and last points on the
    axis, ``closed`` False).  None where the cut is neither."""
    u0 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    u0 /= np.linalg.norm(u0)
    v0 = np.cross(a, u0)
    D = S.V - c
    scale = S.bbox_diagonal
    off_axis = np.linalg.norm(np.cross(D, a), axis=1) > 1e-9 * scale  # a pole lies in every half-plane's plane
    for phi in np.linspace(0.0, np.pi, 7)[:-1] + 0.1234:
        u = np.cos(phi) * u0 + np.sin(phi) * v0
        w = np.cross(a, u)
        s = np.where(off_axis, D @ w, 0.0)  # an edge from a pole does not cross
        if np.min(np.abs(s[off_axis])) < 1e-9 * scale:
            continue
        E = S.edges
        s0, s1 = s[E[:, 0]], s[E[:, 1]]
        cross = s0 * s1 < 0
        t = s0 / np.where(cross, s0 - s1, 1.0)
        X = D[E[:, 0]] + t[:, None] * (D[E[:, 1]] - D[E[:, 0]])
        keep = cross & (X @ u > 0)
        # each face crossed by the plane joins its two crossing edges
        fe = S.face_edges
        k = keep[fe]
        faces = np.nonzero(k.sum(axis=1) == 2)[0]
        if len(faces) == 0:
            return None
        pair = np.sort(np.where(k[faces], fe[faces], -1), axis=1)[:, 1:]
        n = len(E)
        Adj = sp.coo_matrix((np.ones(len(pair)), (pair[:, 0], pair[:, 1])), shape=(n, n)).tocsr()
        Adj = Adj + Adj.T
        deg = np.asarray(Adj.getnnz(axis=1)).ravel()
        idx = np.nonzero(keep)[0]
        ends = idx[deg[idx] == 1]
        if np.any(deg[idx] > 2) or np.any(deg[idx] == 0) or len(ends) not in (0, 2):
            continue
        ncomp, _ = connected_components(Adj[idx][:, idx], directed=False)
        if ncomp != 1:
            return None
        order = [ends[0] if len(ends) else idx[0]]
        prev = -1
        while True:
            nb = Adj.indices[Adj.indptr[order[-1]]:Adj.indptr[order[-1] + 1]]
            nb = nb[nb != prev]
            if len(nb) == 0 or nb[0] == order[0]:
                break
            prev = order[-1]
            order.append(nb[0])
        order = np.array(order)
        Q = np.c_[X[order] @ u, X[order] @ a]
        flags = sharp[order]
        closed = len(ends) == 0
        if not closed:
            # an open chain runs from the axis to the axis: closed through it
            Q = np.vstack([[0.0, Q[0, 1]], Q, [0.0, Q[-1, 1]]])
            flags = np.r_[False, flags, False]
        area = 0.5 * np.sum(Q[:, 0] * np.roll(Q[:, 1], -1) - np.roll(Q[:, 0], -1) * Q[:, 1])
        if area < 0:
            Q, flags = Q[::-1], flags[::-1]
        return Q, flags, u, closed
    return None


def _runs(labels: np.ndarray) -> list[tuple[int, int, int]]:
    """Cyclic runs of equal labels: (start, end exclusive mod k, label),
    starting at a label change (a single run when all are equal)."""
    k = len(labels)
    change = np.nonzero(labels != np.roll(labels, 1))[0]
    if len(change) == 0:
        return [(0, k, int(labels[0]))]
    runs = []
    for i, s in enumerate(change):
        e = change[(i + 1) % len(change)]
        runs.append((int(s), int(e), int(labels[s])))
    return runs


def profile_charts(Q: np.ndarray):
    """Labels of the profile's segments (segment i from Q[i] to Q[i+1]),
    small runs merged; None where two opposite labels meet."""
    T = np.roll(Q, -1, axis=0) - Q
    L = np.linalg.norm(T, axis=1)
    Nout = np.c_[T[:, 1], -T[:, 0]] / np.maximum(L, 1e-300)[:, None]  # solid on the left: outward is the right
    lab = np.argmax(Nout @ _DIRS.T, axis=1)
    total = L.sum()
    for _ in range(len(lab)):
        runs = _runs(lab)
        if len(runs) <= 1:
            break
        length = [L[np.arange(s, e if e > s else e + len(lab)) % len(lab)].sum() for s, e, _ in runs]
        i = int(np.argmin(length))
        if length[i] >= MIN_RUN * total:
            break
        s, e, _ = runs[i]
        prev_lab, next_lab = runs[i - 1][2], runs[(i + 1) % len(runs)][2]
        seg = np.arange(s, e if e > s else e + len(lab)) % len(lab)
        # the neighbour whose direction is nearer the run's mean normal
        mean = Nout[seg].T @ L[seg]
        lab[seg] = prev_lab if _DIRS[prev_lab] @ mean >= _DIRS[next_lab] @ mean else next_lab
    runs = _runs(lab)
    for i, (_, _, la) in enumerate(runs):
        nb = runs[(i + 1) % len(runs)][2]
        if len(runs) > 1 and nb == (la ^ 1):
            return None
    return lab, runs, L


def _inside_distance(Q: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Signed distance of points X (m, 2) inside the closed polygon Q
    (positive inside)."""
    A, B = Q, np.roll(Q, -1, axis=0)
    AB = B - A
    t = np.clip(np.einsum("mkj,kj->mk", X[:, None] - A[None], AB) / np.maximum(np.sum(AB * AB, axis=1), 1e-300),
                0.0, 1.0)
    d = np.linalg.norm(X[:, None] - (A[None] + t[..., None] * AB[None]), axis=2).min(axis=1)
    # crossing number for inside
    y = X[:, 1][:, None]
    c1 = (A[None, :, 1] > y) != (B[None, :, 1] > y)
    xint = A[None, :, 0] + (y - A[None, :, 1]) * AB[None, :, 0] / np.where(AB[None, :, 1] == 0, 1.0, AB[None, :, 1])
    inside = (np.sum(c1 & (X[:, 0][:, None] < xint), axis=1) % 2) == 1
    return np.where(inside, d, -d)


def ring_loops(Q: np.ndarray, flags: np.ndarray, depth: float | None = None):
    """The loops of a ring's profile: a list of ((r, z), sigma, 'a|b'), the
    depth and (bands, sharp band boundaries); no loop where every label
    change is sharp; None where the profile's labels make no rectilinear
    polygon or no depth fits."""
    charts = profile_charts(Q)
    if charts is None:
        return None
    lab, runs, L = charts
    k = len(Q)
    if len(runs) < 4:
        return None
    corners = []
    at_change = np.zeros(k, bool)
    for _, e, _ in runs:
        at_change[[(e - 1) % k, e % k, (e + 1) % k]] = True
    if np.any(flags & ~at_change):
        # a crease inside a band: the padded polycube leaves such creases
        # smooth with the sharp angle that keeps the others (docs/suggest.md)
        return None
    for i, (_, e, la) in enumerate(runs):
        nxt = runs[(i + 1) % len(runs)]
        p = Q[e % k]  # the profile point where run i ends and the next begins
        # sharp when the crease is at the change or within a segment of it
        near = [(e - 1) % k, e % k, (e + 1) % k]
        sharp = bool(np.any(flags[near]))
        da, db = _DIRS[la], _DIRS[nxt[2]]
        convex = da[0] * db[1] - da[1] * db[0] > 0
        corners.append((p, la, nxt[2], sharp, convex))
    # a rectilinear polygon turns by one full turn: 4 more convex corners than concave
    turn = sum(1 if cv else -1 for *_, cv in corners)
    if turn != 4:
        return None
    smooth = [cn for cn in corners if not cn[3]]
    counts = (len(runs), len(corners) - len(smooth))
    if not smooth:
        return [], 0.0, counts
    chords = [np.linalg.norm(Q[e % k] - Q[start]) for i, (start, e, _) in enumerate(runs)
              if not (corners[i - 1][3] and corners[i][3])]
    placed = _place_loops(Q, smooth, depth, chords, lambda pts: pts[:, 0])  # off the axis
    return None if placed is None else placed + (counts,)


def _place_loops(Q: np.ndarray, smooth: list, depth: float | None, chords: list, away):
    """(loops, depth) for the smooth label changes of the profile Q: each at
    p - depth (d_a + d_b), the depth DEPTH times the median of ``chords``
    (or as given) lowered x 0.8 until every loop is CLEARANCE depths inside
    Q, from the others and by ``away(points)`` from what else they must
    keep off; None where no depth does."""
    if depth is None:
        depth, tries = DEPTH * float(np.median(chords)), 40
    else:
        tries = 1
    for _ in range(tries):
        pts = np.array([p - depth * (_DIRS[a] + _DIRS[b]) for p, a, b, *_ in smooth])
        ok = np.all(_inside_distance(Q, pts) >= CLEARANCE * depth) and np.all(away(pts) >= CLEARANCE * depth)
        if ok and len(pts) > 1:
            gap = np.linalg.norm(pts[:, None] - pts[None], axis=2)
            ok = gap[np.triu_indices(len(pts), 1)].min() >= CLEARANCE * depth
        if ok:
            loops = [(q, 0.25 if cv else -0.25, f"{RING_LABELS[a]}|{RING_LABELS[b]}")
                     for q, (p, a, b, sh, cv) in zip(pts, smooth)]
            return loops, float(depth)
        depth *= 0.8
    return None


def ring_frame(S: TriSurface, c: np.ndarray, a: np.ndarray, u: np.ndarray):
    """Each face's label in the ring's frame, as a polycube label (+r as +X,
    -r as -X, +z as +Z, -z as -Z) and the frame's rows (u, a x u, a)."""
    P = S.V[S.F].mean(axis=1) - c
    er = P - np.outer(P @ a, a)
    er /= np.maximum(np.linalg.norm(er, axis=1), 1e-300)[:, None]
    nr, nz = np.einsum("ij,ij->i", S.face_normals, er), S.face_normals @ a
    lab = np.argmax(np.c_[nr, -nr, nz, -nz], axis=1)
    return _AS_POLYCUBE[lab], np.array([u, np.cross(a, u), a])


def circle(c: np.ndarray, a: np.ndarray, u: np.ndarray, r: float, z: float, spacing: float) -> np.ndarray:
    """A closed polyline: the circle of radius r about the axis at height z,
    its first point repeated."""
    n = max(24, int(np.ceil(2 * np.pi * r / spacing)))
    phi = np.linspace(0.0, 2 * np.pi, n + 1)
    v = np.cross(a, u)
    P = c + z * a + r * (np.outer(np.cos(phi), u) + np.outer(np.sin(phi), v))
    P[-1] = P[0]
    return P


def _of_revolution(S: TriSurface, sharp: np.ndarray, euler: int):
    """(c, a, RMS tilt, profile(...)) where S is one surface of Euler
    characteristic ``euler`` whose normals lie in the meridian planes of
    an axis (within TILT_RMS and TILT_MAX), else None."""
    if len(S.V) - len(S.edges) + len(S.F) != euler:
        return None
    c, a, tilt = fit_axis(S)
    A = S.face_areas / S.face_areas.sum()
    rms = float(np.sqrt(A @ tilt**2))
    if rms > TILT_RMS or np.max(np.abs(tilt)) > TILT_MAX:
        return None
    cut = profile(S, c, a, sharp)
    return None if cut is None else (c, a, rms, cut)


def _loop_curves(loops, c, a, u, spacing: float) -> tuple[list, list]:
    """Closed Curves (and their info rows) for the loops ((r, z), sigma,
    charts) about the axis (c, a)."""
    curves, info = [], []
    for i, (q, sigma, charts) in enumerate(loops):
        P = circle(c, a, u, float(q[0]), float(q[1]), spacing)
        name = f"ring_{i}"
        curves.append(Curve(P, sigma=sigma, name=name, closed=True))
        info.append((name, sigma, charts, float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())))
    return curves, info


def ring_network(S: TriSurface, sharp: np.ndarray, depth: float | None = None):
    """The ring route's curves (docs/suggest.md, *Rings*): (curves, info,
    frame, labels, depth, notes, (bands, sharp band boundaries)) where
    (V, F) bound a ring, else None.  ``info`` holds (name, sigma, charts,
    length) per curve."""
    found = _of_revolution(S, sharp, 0)
    if found is None:
        return None
    c, a, rms, (Q, flags, u, closed) = found
    # the profile must keep off the axis: a ring, not a solid the axis passes through
    if not closed or Q[:, 0].min() <= 0:
        return None
    found = ring_loops(Q, flags, depth)
    if found is None:
        return None
    loops, delta, counts = found
    spacing = 0.25 * (delta if delta > 0 else 0.05 * S.bbox_diagonal)
    curves, info = _loop_curves(loops, c, a, u, spacing)
    labels, frame = ring_frame(S, c, a, u)
    notes = [f"a solid of revolution about the axis through ({', '.join(f'{x:.4g}' for x in c)}) along "
             f"({', '.join(f'{x:.3g}' for x in a)}) (normals off the meridian planes by {rms:.3g} RMS): its polycube "
             f"is taken in the frame that turns with it, bands with no corner; {len(loops)} loops, no node"]
    return curves, info, frame, labels, delta, notes, counts


def _on_run(Q: np.ndarray, run: tuple[int, int, int], r: float) -> float | None:
    """The height where the profile's run (its segments start..end-1) passes
    the radius r, or None."""
    s, e, _ = run
    for i in range(s, e):
        (r0, z0), (r1, z1) = Q[i], Q[i + 1]
        if min(r0, r1) <= r <= max(r0, r1) and r0 != r1:
            return float(z0 + (r - r0) / (r1 - r0) * (z1 - z0))
    return None


def axial_curves(Q: np.ndarray, flags: np.ndarray, depth: float | None = None):
    """The network of a solid the axis passes through, from its profile Q
    (closed through the axis: Q[0] and Q[-1] on it, the solid on the left):
    (loops as ring_loops gives them, (rho, z_bottom, z_top) of the four
    axial curves, depth, (bands, sharp band boundaries)), or None.  The flat caps the axis crosses must be
    bounded by sharp rims (a smooth pole is left to the padded polycube,
    whose cube-sphere suits it)."""
    k = len(Q)
    T = Q[1:] - Q[:-1]
    L = np.linalg.norm(T, axis=1)
    Nout = np.c_[T[:, 1], -T[:, 0]] / np.maximum(L, 1e-300)[:, None]
    lab = np.argmax(Nout @ _DIRS.T, axis=1)
    change = np.nonzero(lab[1:] != lab[:-1])[0] + 1
    runs = [(int(s), int(e), int(lab[s])) for s, e in zip(np.r_[0, change], np.r_[change, k - 1])]
    if len(runs) < 3 or runs[0][2] != 3 or runs[-1][2] != 2:  # from the bottom cap (-z) to the top one (+z)
        return None
    if any(b[2] == (a_[2] ^ 1) for a_, b in zip(runs[:-1], runs[1:])):
        return None
    at_change = np.zeros(k, bool)
    corners = []
    for (_, e, la), (_, _, lb) in zip(runs[:-1], runs[1:]):
        near = [max(e - 1, 0), e, min(e + 1, k - 1)]
        at_change[near] = True
        da, db = _DIRS[la], _DIRS[lb]
        corners.append((Q[e], la, lb, bool(np.any(flags[near])), da[0] * db[1] - da[1] * db[0] > 0))
    if np.any(flags & ~at_change):
        return None  # a crease inside a band
    # half a turn from cap to cap (the axis closes the other half)
    if sum(1 if cv else -1 for *_, cv in corners) != 2 or not (corners[0][3] and corners[-1][3]):
        return None
    r_neck = float(Q[runs[0][1]:runs[-1][0] + 1, 0].min())
    rho = AXIAL * r_neck
    z0, z1 = _on_run(Q, runs[0], rho), _on_run(Q, runs[-1], rho)
    if z0 is None or z1 is None or not z0 < z1:
        return None
    zs = np.linspace(z0, z1, 64)[1:-1]
    if np.any(_inside_distance(Q, np.c_[np.full_like(zs, rho), zs]) <= 0):
        return None
    smooth = [cn for cn in corners if not cn[3]]
    counts = (len(runs), len(corners) - len(smooth))
    if not smooth:
        return [], (rho, z0, z1), 0.0, counts
    chords = [np.linalg.norm(Q[e] - Q[s]) for i, (s, e, _) in enumerate(runs)
              if (i > 0 and not corners[i - 1][3]) or (i < len(corners) and not corners[i][3])]
    placed = _place_loops(Q, smooth, depth, chords, lambda pts: np.abs(pts[:, 0] - rho))  # off the axial curves
    return None if placed is None else (placed[0], (rho, z0, z1), placed[1], counts)


def axial_network(S: TriSurface, sharp: np.ndarray, depth: float | None = None):
    """The route for a solid of revolution the axis passes through, with
    flat caps there (a stepped shaft, a cylinder with a boss or a flange):
    four straight +1/4 curves along the axis at AXIAL times the narrowest
    radius between the caps (the O-grid of every cross-section) and the
    ring route's loops under the profile's smooth turns.  (curves, info,
    frame, labels, depth, notes) as ring_network, or None."""
    found = _of_revolution(S, sharp, 2)
    if found is None or found[3][3]:
        return None
    c, a, _, (Q, flags, u, _) = found
    found = axial_curves(Q, flags, depth)
    if found is None:
        return None
    loops, (rho, z0, z1), delta, counts = found
    spacing = 0.25 * (delta if delta > 0 else rho)
    v = np.cross(a, u)
    curves, info = [], []
    n = max(8, int(np.ceil((z1 - z0) / spacing)))
    t = np.linspace(z0, z1, n + 1)[:, None]
    for i in range(4):
        phi = np.pi / 4 + i * np.pi / 2
        P = c + rho * (np.cos(phi) * u + np.sin(phi) * v) + t * a
        name = f"axial_{i}"
        curves.append(Curve(P, sigma=0.25, name=name))
        info.append((name, 0.25, "axis", float(z1 - z0)))
    more, more_info = _loop_curves(loops, c, a, u, spacing)
    curves, info = curves + more, info + more_info
    labels, frame = ring_frame(S, c, a, u)
    notes = [f"a solid of revolution through its axis ({', '.join(f'{x:.4g}' for x in c)}) along "
             f"({', '.join(f'{x:.3g}' for x in a)}), flat caps where the axis crosses it: four curves along the "
             f"axis at {rho:.4g} from it (an O-grid in every cross-section), {len(loops)} loops, no node"]
    return curves, info, frame, labels, delta, notes, counts
