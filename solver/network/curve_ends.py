"""Curve ends: onto the surface along the normal, and onto the nodes and
the surface they were drawn to meet.

*Bending.*  A tet-edge chain ends wherever its mesh had a boundary vertex, up to
half an edge from where the curve meant to end, so the slide of its ends
while it is faired (fairing.py, step 6) is mostly what its oblique ends
need.  Where the end still meets the surface off the
normal (by more than ``BEND_MIN`` degrees: a long stretch really
oblique), its last stretch of length ``Lb = min(BEND_LENGTH * h,
f L)`` is replaced by a cubic Hermite arc
(tangent-continuous with the curve) followed by a straight piece along
the inward normal of length Lb / 4, so that the curve meets the
surface along the normal, as the frame there must be adapted to both
(§4.2.3, Eq. 20-21).  f is ``BEND_FRACTION`` = 1/2 where both ends
of the curve are bent, else ``BEND_FRACTION_ONE_END`` = 0.8: the
structure penalty grows with the square of the curvature, and the
cube-sphere network stretched into a 2 x 1 x 0.6 ellipsoid, whose
radial curves reach the surface 50 degrees off the normal and are
~3.7 h long, scored 520-580 bent over half of them and 160-166 over
0.8 (the whole curve, bending away from the node too, 219), with the
tube faces' curvature corrected (field/constraints.tube_curvature).
A bend that would leave the solid is retried
shorter; if none stays inside the input is refused with the numbers.
(Bending alone, without the slide, left the tet-edge ball's radial
curves turning 5-6 degrees per h/2 near the sphere and LM with a
penalty of 20-135, against 0.35-0.40 with it; the clean ball scores
0.18.)

*Loose node ends* and *end gaps* (before everything else).  Curves
drawn by hand meet at a node only roughly: an end farther than
boundary_tolerance from the surface and within node_tolerance of no
other end (so validation would refuse it as dangling) joins the ends
within ``NODE_GAP * h`` of it, if together they make a node of 3-4
curves (each once), or two loose ends of curves with the same index,
role and torsion (strokes of one curve, then joined into one by
network.prepare_network); all move to the node the others already
form, or to their mean.  And a hand-drawn curve rarely ends
exactly on the surface.  A chain whose last stretch runs along the surface (up to
``END_GAP * h``) is cut where it first reached it (``cut_surface_run``).
A boundary end up to ``END_GAP * h`` outside
the solid is cut back to where the curve crosses the surface; one up to
``END_GAP * h`` inside is extended along its last chord (of length h) to
the surface.  Farther ends are left for validation to refuse, with the
distance (a curve meant to end at a node, or drawn for another object).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import NetworkError
from ..surface.trisurface import TriSurface
from .network import Curve, Network, _fmt, cluster_points
from .polyline import arclength, at_arclength, resample

BEND_MIN = 2.0  # degrees: ends closer than this to the normal are left alone
BEND_LENGTH = 3.0  # bent stretch, in units of h ...
BEND_FRACTION = 0.5  # ... and at most this fraction of the curve's length where both its ends are bent,
BEND_FRACTION_ONE_END = 0.8  # ... or this fraction where only one end is (its other end a node)
END_GAP = 2.0  # boundary ends at most this many h outside or inside the surface are cut back or extended onto it
ON_SURFACE = 1e-3  # a stretch within this much of the bounding box diagonal runs along the surface
NODE_GAP = 1.0  # loose curve ends within this many h of (the centre of) others join them at a node


@dataclass
class EndBend:
    """A curve end moved onto the surface (end gaps) or bent onto its normal."""

    end: str  # 'start' or 'end'
    angle_deg: float  # angle between the faired curve's end chord (length h) and the normal
    length_h: float  # length of the bent stretch, in units of h
    position: tuple = ()
    input_angle_deg: float = 0.0  # the same for the curve as given (its last edge's angle can be larger)
    slid_h: float = 0.0  # how far the end moved along the surface while faired, in units of h
    gap: str = ""  # 'cut back' (the end was outside the solid), 'extended' (inside) or 'cut back along the surface'
    gap_h: float = 0.0  # how far the given end was from the surface (along it: the stretch cut), in units of h

    def text(self) -> str:
        along = self.gap == "cut back along the surface"
        how = [f"{self.gap} {self.gap_h:.2f} h" + ("" if along else " to the surface")] if self.gap else []
        if self.slid_h > 1e-3:
            how.append(f"slid {self.slid_h:.2f} h along the surface")
        if self.length_h > 0:
            how.append(f"bent over {self.length_h:.2f} h ({self.angle_deg:.0f} deg after fairing)")
        if self.length_h == 0.0 and self.slid_h <= 1e-3:  # only brought onto the surface
            return f"{self.end} {how[0]}"
        return f"{self.end} turned onto the normal (given {self.input_angle_deg:.0f} deg off): {', then '.join(how)}"


def surface_normal_at(S: TriSurface, f: int, q: np.ndarray) -> np.ndarray:
    """Angle-weighted pseudo-normal at q on face f: the face normal inside a
    face, the mean of the faces around an edge or a vertex q lies on."""
    tri = S.V[S.F[f]]
    e = np.linalg.norm(tri - q, axis=1)
    scale = np.linalg.norm(tri[1] - tri[0]) + 1e-300
    near_v = np.nonzero(e < 1e-6 * scale)[0]
    if len(near_v):
        v = S.F[f, near_v[0]]
        faces, corner = np.nonzero(S.F == v)
        w = S.corner_angles[faces, corner]
        n = (w[:, None] * S.face_normals[faces]).sum(axis=0)
        return n / np.linalg.norm(n)
    for k in range(3):
        a, b = tri[k], tri[(k + 1) % 3]
        t = np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
        if np.linalg.norm(a + t * (b - a) - q) < 1e-6 * scale:
            i, j = S.F[f, k], S.F[f, (k + 1) % 3]
            faces = np.nonzero(np.isin(S.F, [i, j]).sum(axis=1) == 2)[0]
            n = S.face_normals[faces].sum(axis=0)
            return n / np.linalg.norm(n)
    return S.face_normals[f]


def end_chord_angle(S: TriSurface, P: np.ndarray, h: float) -> float:
    """Angle (degrees) between the chord over the last min(h, L/2) of P and
    the surface normal where P ends."""
    _, f, q = S.closest_points(P[-1:])
    n = surface_normal_at(S, int(f[0]), q[0])
    cum = arclength(P)
    L = cum[-1]
    chord = P[-1] - at_arclength(P, np.array([max(L - min(h, 0.5 * L), 0.0)]), cum)[0]
    chord /= np.linalg.norm(chord)
    return float(np.degrees(np.arccos(np.clip(chord @ n, -1.0, 1.0))))


def _hermite(p0, t0, p1, t1, n):
    u = np.linspace(0.0, 1.0, n + 1)[:, None]
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
    return h00 * p0 + h10 * t0 + h01 * p1 + h11 * t1


def bend_end(S: TriSurface, P: np.ndarray, h: float, label: str, end_name: str,
             fraction: float = BEND_FRACTION):
    """Bend the last stretch of P (which ends on the surface at P[-1]) so that
    it reaches the surface along the normal, over at most ``fraction`` of
    its length.  Returns (new points, EndBend or None)."""
    d, f, q = S.closest_points(P[-1:])
    q = q[0]
    P = P.copy()
    P[-1] = q
    n = surface_normal_at(S, int(f[0]), q)  # outward
    cum = arclength(P)
    L = cum[-1]
    chord = q - at_arclength(P, np.array([max(L - min(h, 0.5 * L), 0.0)]), cum)[0]
    chord /= np.linalg.norm(chord)
    angle = float(np.degrees(np.arccos(np.clip(chord @ n, -1.0, 1.0))))
    if angle <= BEND_MIN:
        return P, None
    Lb0 = min(BEND_LENGTH * h, fraction * L)
    for Lb in (Lb0, 0.6 * Lb0, 0.35 * Lb0):
        s0 = L - Lb
        p0 = at_arclength(P, np.array([s0]), cum)[0]
        # tangent of the curve at p0, over a chord of l/2 behind it
        back = at_arclength(P, np.array([max(s0 - 0.5 * h, 0.0)]), cum)[0]
        t0 = p0 - back
        if np.linalg.norm(t0) < 1e-12 * L:
            t0 = chord
        t0 /= np.linalg.norm(t0)
        Ls = Lb / 4.0
        p1 = q - Ls * n
        m = np.linalg.norm(p1 - p0)
        k = max(4, int(np.ceil((Lb - Ls) / (0.25 * h))))
        arc = _hermite(p0, m * t0, p1, m * n, k)
        ks = max(2, int(np.ceil(Ls / (0.25 * h))))
        straight = p1 + np.linspace(0.0, Ls, ks + 1)[1:, None] * n
        keep = cum < s0 - 1e-9 * L
        newP = np.vstack([P[keep], arc, straight])
        newP[-1] = q
        # inside: every point strictly inside the solid except the end
        test = resample(newP[np.sum(keep):], 0.2 * h)[:-1]
        dd, _, _ = S.closest_points(test)
        inside = S.winding_number(test) > 0.5
        if np.all(inside) and np.all(dd[1:] > 1e-6 * h):
            return newP, EndBend(end_name, angle, Lb / h, tuple(np.round(q, 6)))
    raise NetworkError(
        f"{label} reaches the surface at {_fmt(q)} at {angle:.0f} degrees from the normal, and bending its last "
        f"{Lb0:.3g} ({Lb0 / h:.2f} h) onto the normal would leave the solid; move that end to where the curve can "
        "meet the surface at right angles, or lengthen the curve's last straight stretch"
    )


def join_loose_ends(S: TriSurface, net: Network, h: float, node_tol: float, boundary_tol: float):
    """Move loose curve ends onto the node they were drawn to meet (step 0 of
    the module docstring).  Returns (network, {input curve index: [('start'
    or 'end', distance moved in h)]}); the network itself when no end moved.
    """
    ends = [(k, s) for k in net.interior_curves for s in (0, -1)
            if not net.curves[k].closed and len(net.curves[k].points) > 1
            and np.linalg.norm(net.curves[k].points[0] - net.curves[k].points[-1]) > node_tol]
    if len(ends) < 2:
        return net, {}
    X = np.array([net.curves[k].points[s] for k, s in ends])
    exact = cluster_points(X, node_tol)
    size = np.bincount(exact)[exact]
    d, _, _ = S.closest_points(X)
    loose = (size == 1) & (d > boundary_tol)
    if not loose.any():
        return net, {}
    # greedy centroid linkage: the closest pair of clusters, one of them a
    # loose end, merges while it stays within NODE_GAP h and could still be
    # a node (at most 4 ends, each curve once); ends alone on the surface
    # (boundary ends) and the nodes already formed keep to themselves
    clusters = [list(np.nonzero(exact == c)[0]) for c in np.unique(exact)]
    clusters = [m for m in clusters if len(m) > 1 or loose[m[0]]]
    while True:
        C = np.array([X[m].mean(axis=0) for m in clusters])
        D = np.linalg.norm(C[:, None] - C[None], axis=2)
        free = np.array([loose[m].all() for m in clusters])
        ok = (free[:, None] | free[None]) & (D <= NODE_GAP * h)
        np.fill_diagonal(ok, False)
        best = None
        for i, j in zip(*np.nonzero(np.triu(ok))):
            merged = clusters[i] + clusters[j]
            if len(merged) <= 4 and len({ends[m][0] for m in merged}) == len(merged) and \
                    (best is None or D[i, j] < D[best]):
                best = (i, j)
        if best is None:
            break
        i, j = best
        clusters[i] = clusters[i] + clusters[j]
        del clusters[j]
    points = {k: net.curves[k].points.copy() for k, _ in ends}
    moved: dict = {}
    for members in map(np.array, clusters):
        if not loose[members].any():
            continue
        if len(members) == 2:
            # two strokes of one curve, drawn with a gap: joined if they can be one curve
            a, b = (net.curves[ends[m][0]] for m in members)
            if (a.sigma, a.role, a.torsion) != (b.sigma, b.role, b.torsion) or not loose[members].all():
                continue
        elif len(members) < 3:
            continue  # not a node (validation says why)
        fixed = members[~loose[members]]
        pos = X[fixed].mean(axis=0) if len(fixed) else X[members].mean(axis=0)
        for m in members[loose[members]]:
            k, s = ends[m]
            points[k][s] = pos
            moved.setdefault(k, []).append(("start" if s == 0 else "end", float(np.linalg.norm(pos - X[m])) / h))
    if not moved:
        return net, {}
    curves = list(net.curves)
    for k in moved:
        c = curves[k]
        curves[k] = Curve(points[k], c.sigma, c.role, c.torsion, c.name, c.closed)
    return replace(net, curves=curves), moved


def _surface_crossing(S: TriSurface, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Where the segment from a (inside the solid) to b (outside) crosses the
    surface: bisection on the winding number."""
    for _ in range(40):
        m = 0.5 * (a + b)
        if S.winding_number(m[None])[0] > 0.5:
            a = m
        else:
            b = m
    return 0.5 * (a + b)


def cut_surface_run(S: TriSurface, P: np.ndarray, limit: float):
    """P without a last stretch that runs along the surface (step 0 of the
    module docstring): a chain of tet edges routed to a boundary vertex can
    reach the surface one vertex early and follow a boundary edge to its
    end (the cube-sphere stretched into an ellipsoid, its radial curves
    36-50 degrees off the normal, routed through an independent mesh: its
    last edge on the surface, 78 degrees off the normal, and partly
    outside, refused).  A singular curve carries no meaning along the
    boundary, and the chain's end is where it first reached it.  Returns
    (points, 'cut back along the surface' or '', the stretch's length): cut
    where the points and the segments' middles all lie within
    ``ON_SURFACE`` of the bounding box diagonal of the surface (fTetWild's
    envelope: a mesh's boundary vertices lie within it), from the end back,
    when that stretch is no longer than limit."""
    if len(P) < 3:
        return P, "", 0.0
    tol = ON_SURFACE * S.bbox_diagonal
    # only the points within limit of the end (and the one before them) can
    # start a stretch short enough: a curve of 1e5 points is not measured whole
    back = np.r_[np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1)[::-1])[::-1], 0.0]
    lo = max(1, int(np.argmax(back <= limit)) - 1)
    d = np.full(len(P), np.inf)
    m = np.full(len(P) - 1, np.inf)
    d[lo - 1:] = S.closest_points(P[lo - 1:])[0]
    m[lo - 1:] = S.closest_points(0.5 * (P[lo:] + P[lo - 1:-1]))[0]
    k = len(P) - 1
    while k > 1 and d[k - 1] <= tol and m[k - 1] <= tol:
        k -= 1
    run = float(back[k])
    if k == len(P) - 1 or run <= tol or run > limit:
        return P, "", 0.0
    return P[: k + 1], "cut back along the surface", run


def close_end_gap(S: TriSurface, P: np.ndarray, h: float, tol: float, limit: float):
    """Bring the last point of P onto the surface when it is within limit of
    it (step 0 of the module docstring).  Returns (points, 'cut back' or
    'extended' or '', distance of the given end from the surface).

    Outside the solid the curve is cut where it last enters the outside
    (found by bisection on the winding number), provided everything from
    there on is outside and no longer than limit; inside, it is continued
    along its last chord of length h to where that ray leaves the solid,
    provided that is within limit."""
    d, _, _ = S.closest_points(P[-1:])
    d = float(d[0])
    if d <= tol or d > limit:
        return P, "", d
    inside = S.winding_number(P) > 0.5
    if not inside[-1]:
        k = len(P) - 1
        while k > 0 and not inside[k - 1]:
            k -= 1
        if k == 0:
            return P, "", d  # all outside: nothing to cut back to
        if float(np.linalg.norm(np.diff(P[k - 1:], axis=0), axis=1).sum()) > limit + tol:
            return P, "", d
        return np.vstack([P[:k], _surface_crossing(S, P[k - 1], P[k])]), "cut back", d
    L = arclength(P)[-1]
    back = at_arclength(P, np.array([max(L - h, 0.0)]))[0]
    t = P[-1] - back
    if np.linalg.norm(t) < 1e-12 * max(L, h):
        return P, "", d
    t /= np.linalg.norm(t)
    u = np.linspace(0.0, limit, int(np.ceil(limit / (0.05 * h))) + 1)[1:]
    out = np.nonzero(S.winding_number(P[-1] + u[:, None] * t) < 0.5)[0]
    if not len(out):
        return P, "", d
    x = _surface_crossing(S, P[-1] + (u[out[0] - 1] if out[0] else 0.0) * t, P[-1] + u[out[0]] * t)
    n = max(1, int(np.ceil(np.linalg.norm(x - P[-1]) / (0.5 * h))))
    return np.vstack([P, P[-1] + np.linspace(0.0, 1.0, n + 1)[1:, None] * (x - P[-1])]), "extended", d
