"""Curve intake: repair the polylines users bring instead of refusing them.

Networks exported by other field tools are chains of tet-mesh edges (design
notes §5): they zig-zag (consecutive edges 20-70 degrees apart), hold
segments of 1e-6 next to normal ones and reach the surface along whatever
edge the mesh had.  Measured at the scale of one polyline vertex such a
chain "kinks" and "touches itself"; measured at the scale h of the tet mesh
that will carry the field it is a smooth curve.  So every interior curve is
cleaned and faired at a length tied to the mesh, never to the bounding box:

1. *merge*: consecutive points closer than ``MERGE * h`` are dropped;
2. *fairing length*: ``l = max(h, median segment length)`` -- a chain of
   mesh edges carries no shape below its own edge length;
3. *corners*: where the curve turns by more than ``MAX_KINK``
   between chords of length ``CORNER_WINDOW * l`` on either side and
   between chords twice as long (both fitting on the curve), but there by
   less than 1.5 times as much (a corner, not an arc or a bump), the
   input vertex nearest the largest turn is kept as a knot (a real
   corner survives and validation reports it as it would have);
4. *resample* between ends and corners by arc length at spacing ``l / 2``;
5. *fair*: ``SMOOTH_ITERATIONS`` = 72 steps of Laplacian smoothing
   ``P_i += 1/2 (P_(i-1) + P_(i+1) - 2 P_i) / 2`` with ends, nodes and corners
   fixed -- a Gaussian of width 3 l along the curve: the zig-zag of mesh
   edges goes, and so does a bend shorter than a few l between fixed points
   (a chain of 3-4 mesh edges carries no shape of its own), and an arc of
   radius R moves inwards by about 4.5 l^2 / R (a loop of radius 6.7 h by
   0.5 h; reported).  A curve whose faired points would leave the solid
   keeps its resampled points;
5b. *least bending*: the Gaussian keeps the long bow of a chain that
   strays to one side along its whole length, and the field pays for
   every bend of a singular curve (the structure penalty grows with the
   square of the curvature: the straight clean cylinder network scores
   0.0018, its curves bowed to turn 2.3 degrees over h 0.0099, 7 degrees
   0.090, with fairing alone, which kept those bows).  So an open curve
   is then bent as little as it can be while every point stays within
   ``BAND * l`` of the input -- again the chain's own uncertainty
   (``_least_bending``): the least sum of |P_(i-1) - 2 P_i + P_(i+1)|^2
   (a discrete cubic spline) with nodes and corners held, boundary ends
   free to move in their tangent plane (by at most ``SLIDE_MAX * l`` from
   the input end) and the curve meeting the surface along the normal
   (each end's neighbour against its mirror image in that plane); points
   beyond the band are pulled back to its edge by a penalty that grows
   from faint round by round.  A shape smaller than an edge of the chain
   goes (the tet-edge cylinder's curves come out straight), a larger one
   is kept to within l;
6. *ends*: a boundary end slides along the surface while the curve is
   faired: it is smoothed against the mirror image of its neighbour in the
   tangent plane (the curve continued by reflection, which crosses the
   surface at right angles), so it moves towards the foot of the curve
   and the last stretch turns onto the normal smoothly, over the fairing
   width (by at most ``SLIDE_MAX * l``: the chain's own uncertainty,
   about an edge of its mesh; the plane follows the surface).
   A tet-edge chain ends wherever its mesh had a boundary vertex, up to
   half an edge from where the curve meant to end, so this is mostly what
   its oblique ends need.  Where the end still meets the surface off the
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

0. *loose node ends* and *end gaps* (before everything else).  Curves
   drawn by hand meet at a node only roughly: an end farther than
   boundary_tolerance from the surface and within node_tolerance of no
   other end (so validation would refuse it as dangling) joins the ends
   within ``NODE_GAP * h`` of it, if together they make a node of 3-4
   curves (each once), or two loose ends of curves with the same index,
   role and torsion (strokes of one curve, then joined into one by
   network.prepare_network); all move to the node the others already
   form, or to their mean.  And a hand-drawn curve rarely ends
   exactly on the surface.  A boundary end up to ``END_GAP * h`` outside
   the solid is cut back to where the curve crosses the surface; one up to
   ``END_GAP * h`` inside is extended along its last chord (of length h) to
   the surface.  Farther ends are left for validation to refuse, with the
   distance (a curve meant to end at a node, or drawn for another object).

Every change is reported per curve (``CurveRepair``); displacements are in
units of h.  Real crossings and self-intersections are not repaired:
validation still refuses them, now at tolerances relative to h.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree

from ..errors import NetworkError
from ..surface.trisurface import TriSurface
from .curves import CurveGeometry
from .network import Curve, Network, PreparedNetwork, _fmt, cluster_points

MAX_KINK = 45.0  # degrees a singular curve may turn over a length h (chords of h/2 each side)
MERGE = 0.05  # points closer than MERGE * h are merged
CORNER_WINDOW = 2.0  # chords of CORNER_WINDOW * l on each side detect real corners
SMOOTH_ITERATIONS = 72  # Laplacian steps of 1/2 at spacing l / 2: a Gaussian of width 3 l
BAND = 1.0  # least bending keeps every point within BAND * l of the input
SLIDE_MAX = 1.0  # a boundary end slides along the surface by at most this many l while faired
BEND_MIN = 2.0  # degrees: ends closer than this to the normal are left alone
BEND_LENGTH = 3.0  # bent stretch, in units of h ...
BEND_FRACTION = 0.5  # ... and at most this fraction of the curve's length where both its ends are bent,
BEND_FRACTION_ONE_END = 0.8  # ... or this fraction where only one end is (its other end a node)
END_GAP = 2.0  # boundary ends at most this many h outside or inside the surface are cut back or extended onto it
NODE_GAP = 1.0  # loose curve ends within this many h of (the centre of) others join them at a node
TETS_PER_H3 = 15.0  # as mesh/resolution.py's (network/ sits below mesh/)


def solid_scale(S: TriSurface, target_tets: int = 15000) -> float:
    """The budget edge length ``(15 * volume / target_tets)^(1/3)``: the
    scale h the intake and validation use when no edge length is given (the
    pipeline's default h may be smaller where the network needs it, but it
    is computed from the network, so the network is repaired at this one)."""
    vol = float(np.sum(np.abs(S.signed_volumes())))
    return float(max((TETS_PER_H3 * vol / target_tets) ** (1.0 / 3.0), 1e-3 * S.bbox_diagonal))


@dataclass
class EndBend:
    """A curve end moved onto the surface (end gaps) or bent onto its normal."""

    end: str  # 'start' or 'end'
    angle_deg: float  # angle between the faired curve's end chord (length h) and the normal
    length_h: float  # length of the bent stretch, in units of h
    position: tuple = ()
    input_angle_deg: float = 0.0  # the same for the curve as given (its last edge's angle can be larger)
    slid_h: float = 0.0  # how far the end moved along the surface while faired, in units of h
    gap: str = ""  # 'cut back' (the end was outside the solid) or 'extended' (inside), else ''
    gap_h: float = 0.0  # how far the given end was from the surface, in units of h

    def text(self) -> str:
        how = [f"{self.gap} {self.gap_h:.2f} h to the surface"] if self.gap else []
        if self.slid_h > 1e-3:
            how.append(f"slid {self.slid_h:.2f} h along the surface")
        if self.length_h > 0:
            how.append(f"bent over {self.length_h:.2f} h ({self.angle_deg:.0f} deg after fairing)")
        if self.length_h == 0.0 and self.slid_h <= 1e-3:  # only brought onto the surface
            return f"{self.end} {how[0]}"
        return f"{self.end} turned onto the normal (given {self.input_angle_deg:.0f} deg off): {', then '.join(how)}"


@dataclass
class CurveRepair:
    """What the intake changed on one interior curve.

    curve : index in Network.curves;  points_in / points_out : sizes
    merged : points dropped as closer than MERGE * h to their neighbour
    max_displacement_h : largest distance between input and repaired curve
    turn_in_deg / turn_out_deg : largest turning over a window of h
    corners : input vertices kept as corners;  ends : EndBend list
    """

    curve: int
    name: str
    points_in: int
    points_out: int
    merged: int
    faired: bool
    max_displacement_h: float
    turn_in_deg: float
    turn_out_deg: float
    corners: int = 0
    ends: list = field(default_factory=list)
    note: str = ""
    joined: list = field(default_factory=list)  # ('start' or 'end', distance in h) of ends moved to join a node
    pieces: list = field(default_factory=list)  # input curves joined end to end into this one (more than one)

    @property
    def changed(self) -> bool:
        return (self.max_displacement_h > 1e-6 or bool(self.ends) or self.merged > 0 or bool(self.joined)
                or len(self.pieces) > 1)

    def text(self) -> str:
        label = f"curve {self.curve}" + (f" '{self.name}'" if self.name else "")
        s = (f"{label}"
             + (f" (joined end to end from curves {', '.join(map(str, self.pieces))})" if len(self.pieces) > 1 else "")
             + f": {self.points_in} -> {self.points_out} points"
             + (f", {self.merged} merged" if self.merged else "")
             + (", faired" if self.faired else "")
             + f", moved at most {self.max_displacement_h:.2f} h, turning over h {self.turn_in_deg:.0f} -> "
               f"{self.turn_out_deg:.0f} deg")
        if self.corners:
            s += f", {self.corners} corner(s) kept"
        for end, d in self.joined:
            s += f"; {end} moved {d:.2f} h to join a node"
        for b in self.ends:
            s += "; " + b.text()
        if self.note:
            s += f"; {self.note}"
        return s


def repairs_text(repairs: list[CurveRepair], h: float) -> str:
    """Lines for the CLI and the add-on; empty when nothing changed."""
    changed = [r for r in repairs if r.changed]
    if not changed:
        return ""
    lines = [f"curve intake at h = {h:.4g}: {len(changed)} of {len(repairs)} interior curve(s) repaired"]
    lines += ["  " + r.text() for r in changed]
    return "\n".join(lines)


# ------------------------------------------------------------------ geometry
def arclength(P: np.ndarray) -> np.ndarray:
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]


def at_arclength(P: np.ndarray, s: np.ndarray, cum: np.ndarray | None = None) -> np.ndarray:
    """Points of the polyline P at arc lengths s (clamped to the ends)."""
    cum = arclength(P) if cum is None else cum
    return np.stack([np.interp(s, cum, P[:, k]) for k in range(3)], axis=1)


def turning(P: np.ndarray, window: float, closed: bool = False) -> np.ndarray:
    """Angle (degrees) at each vertex between the chords to the points at arc
    length ``window`` behind and ahead of it (clamped at open ends): the turn
    of the curve over a length comparable to window, not across one segment."""
    cum = arclength(P)
    L = cum[-1]
    s = cum
    if closed:
        back = at_arclength(P, np.mod(s - window, L), cum)
        ahead = at_arclength(P, np.mod(s + window, L), cum)
    else:
        back = at_arclength(P, np.maximum(s - window, 0.0), cum)
        ahead = at_arclength(P, np.minimum(s + window, L), cum)
    u, v = P - back, ahead - P
    nu, nv = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
    ok = (nu > 1e-12 * max(L, 1e-300)) & (nv > 1e-12 * max(L, 1e-300))
    c = np.einsum("ij,ij->i", u, v) / np.where(ok, nu * nv, 1.0)
    out = np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))
    out[~ok] = 0.0
    return out


def merge_close(P: np.ndarray, tol: float, closed: bool) -> np.ndarray:
    """Drop points closer than tol to the last kept one (ends are kept)."""
    keep = [0]
    for i in range(1, len(P) - 1):
        if np.linalg.norm(P[i] - P[keep[-1]]) > tol:
            keep.append(i)
    last = len(P) - 1
    if len(keep) > 1 and np.linalg.norm(P[last] - P[keep[-1]]) <= tol:
        keep[-1] = last
    else:
        keep.append(last)
    return P[keep]


def resample(P: np.ndarray, spacing: float) -> np.ndarray:
    """Uniform resampling by arc length (ends kept)."""
    cum = arclength(P)
    n = max(1, int(np.ceil(cum[-1] / spacing - 1e-9)))
    return at_arclength(P, np.linspace(0.0, cum[-1], n + 1), cum)


def hausdorff(A: np.ndarray, B: np.ndarray, step: float) -> float:
    """Symmetric Hausdorff distance between two polylines, sampled at step."""
    a = resample(A, step) if len(A) > 1 else A
    b = resample(B, step) if len(B) > 1 else B
    return float(max(cKDTree(b).query(a)[0].max(), cKDTree(a).query(b)[0].max()))


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


# ------------------------------------------------------------------- fairing
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


def _laplacian_fair(P: np.ndarray, fixed: np.ndarray, closed: bool, iterations: int,
                    slide: dict | None = None, slide_max: float = 0.0, project=None) -> np.ndarray:
    """Explicit Laplacian smoothing (step 1/2) with the fixed vertices held.
    k steps at spacing s act like a Gaussian of width s sqrt(k / 2) along the
    curve.  (Taubin's lambda|mu filter, tried first, keeps bends longer than
    ~6 l: on tet-edge chains of 3-4 edges that is the zig-zag itself, and the
    ball's LM then ended at its cap with a penalty of 956.)

    slide : {0 or -1: outward unit normal} -- open ends lying on the surface.
    Such an end is smoothed against the mirror image of its neighbour in the
    tangent plane (the curve continued by reflection, which meets the plane
    at right angles): it slides in the plane towards the foot of its
    neighbour, by at most slide_max in all, and the curve's last stretch
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
            core[i] = x if r <= slide_max else start[i] + off * (slide_max / r)
    Q[:n] = core
    if closed:
        Q[-1] = Q[0]
    return Q


def fair_curve(P: np.ndarray, h: float, closed: bool, slide: dict | None = None, project=None):
    """Steps 1-5 of the module docstring.  slide: {0 or -1: outward normal}
    of boundary ends that may slide along the surface (``_laplacian_fair``;
    by at most ``SLIDE_MAX * l``; project: its surface projection).
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
    # (Tukey's twicing, adding back the smoothed residual, kept a loop of
    # radius 6.7 h round (0.5 h of shrinking -> 0.01 h) but also the bow of
    # tet-edge chains near their ends: on the tet-edge cylinder curves moved
    # by up to 1.1 h, turned 19 degrees over h, and LM took 19 iterations to
    # a penalty of 157, against 0.8 h, 9 degrees, 7-9 and 67 without)
    Q = _laplacian_fair(Q, fx, closed, SMOOTH_ITERATIONS, slide, SLIDE_MAX * ell, project)
    if not closed and len(Q) > 2:
        ends = []
        for e in slide or {}:
            i = e % len(Q)
            nrm = project(Q[i])[1] if project is not None else np.asarray(slide[e], float)
            ends.append((i, 1 if i == 0 else len(Q) - 2, nrm))
        Q = _least_bending(Q, fx, ends, Pm, BAND * ell, SLIDE_MAX * ell)
        if project is not None:
            for i, _, _ in ends:
                Q[i] = project(Q[i])[0]
    return Q, merged, ell, len(knots), fx


def _least_bending(Q: np.ndarray, fixed: np.ndarray, ends: list, guide: np.ndarray, band: float,
                   slide_max: float, rounds: int = 80) -> np.ndarray:
    """Step 5b of the module docstring: the open polyline Q bent as little
    as it can be -- the least sum of |P_(i-1) - 2 P_i + P_(i+1)|^2 over the
    points not centred on a fixed one -- with the fixed points held and
    every point within band of the polyline guide.  (Not for loops: with
    nothing held the sum shrinks a loop.)

    ends : (end index, its neighbour, unit outward normal) of boundary ends.
           Such an end moves in its tangent plane only (a stiff term
           PLANE (n . (P - P_end))^2); the term |2 (I - n n^T)(P_neighbour -
           P_end)|^2 (the neighbour against its mirror image in the plane)
           makes the curve meet the surface along the normal; it stays
           within slide_max of the guide's end.  The other end points
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
    for _ in range(rounds):
        A = (H + sp.diags(w)).tocsr()
        x[f3] = spsolve(A[f3][:, f3].tocsc(), (w * target + plane_rhs)[f3] - A[f3][:, ~f3] @ x[~f3])
        X = x.reshape(n, 3)
        s, t, d = geo.closest(X)
        foot = geo.point(s, t)
        lim = np.full(n, band)
        for i, _, _ in ends:
            foot[i] = guide[0] if i == 0 else guide[-1]
            d[i] = np.linalg.norm(X[i] - foot[i])
            lim[i] = slide_max
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


# ------------------------------------------------------------------ end bend
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


# ------------------------------------------------------------------- driver
def repair_network(S: TriSurface, pn: PreparedNetwork, h: float, names: list,
                   boundary_tolerance: float, joined: dict | None = None) -> tuple[PreparedNetwork, list[CurveRepair]]:
    """Repair every prepared interior curve at scale h (module docstring).

    names[ci] : label of prepared curve ci for messages;  boundary ends
    farther than boundary_tolerance from the surface are left as they are
    (validation refuses them).  joined : join_loose_ends' moves, reported
    with the curves.  Returns the repaired network and one CurveRepair per
    curve.
    """
    joined = joined or {}

    def moves(src):  # the ends moved to join a node, of the curve or of the pieces joined into it
        return [m for k in pn.pieces.get(src, [src]) for m in joined.get(k, [])]

    curves, repairs = [], []

    def project(x):
        _, f, q = S.closest_points(x[None])
        return q[0], surface_normal_at(S, int(f[0]), q[0])

    for ci, c in enumerate(pn.curves):
        P0 = c.points
        kinds = (pn.start_kind[ci], pn.end_kind[ci])
        gaps = {}
        if not c.closed and len(P0) > 1:
            for end, kind in ((1, kinds[1]), (0, kinds[0])):
                if kind == "boundary":
                    R, how, d = close_end_gap(S, P0 if end == 1 else P0[::-1], h, boundary_tolerance,
                                              END_GAP * h)
                    if how:
                        P0 = R if end == 1 else R[::-1]
                        gaps[end] = (how, d / h)
        if len(P0) > 2 and np.any(S.winding_number(P0[1:-1]) < 0.5):
            # a curve that leaves the solid is refused as given (validation
            # names where), not pulled back in by the fairing
            repairs.append(CurveRepair(pn.source[ci], c.name, len(P0), len(P0), 0, False, 0.0, 0.0, 0.0,
                                       note="not repaired: passes outside the solid",
                                       joined=moves(pn.source[ci]),
                                       pieces=pn.pieces.get(pn.source[ci], [])))
            curves.append(c)
            continue
        slide = {}
        if not c.closed and len(P0) > 1:
            for end, kind in ((0, kinds[0]), (-1, kinds[1])):
                if kind == "boundary":
                    q, nrm = project(P0[end])
                    if np.linalg.norm(q - P0[end]) <= boundary_tolerance:
                        slide[end] = nrm
        Q, merged, ell, ncorner, fixed = fair_curve(P0, h, c.closed, slide, project)
        faired = True
        note = ""
        # the faired curve must stay inside the solid (a curve hugging a
        # concave part of the surface could be pulled out of it)
        inner = Q[1:-1]
        if len(inner) and np.any(S.winding_number(inner) < 0.5):
            Q = np.vstack([resample(P0, 0.5 * ell)])
            faired = False
            note = "not faired (fairing would leave the solid)"
        ends = []
        if not c.closed:
            for end, kind in ((1, kinds[1]), (0, kinds[0])):
                if kind != "boundary":
                    continue
                x = Q[-1] if end == 1 else Q[0]
                d, _, _ = S.closest_points(x[None])
                if d[0] > boundary_tolerance:
                    continue
                R = Q if end == 1 else Q[::-1]
                both = kinds[0] == "boundary" and kinds[1] == "boundary"
                R, bend = bend_end(S, R, h, names[ci], "end" if end == 1 else "start",
                                   BEND_FRACTION if both else BEND_FRACTION_ONE_END)
                Q = R if end == 1 else R[::-1]
                slid = float(np.linalg.norm(R[-1] - (P0[-1] if end == 1 else P0[0]))) / h
                if bend is None and (slid > 1e-3 or end in gaps):
                    bend = EndBend("end" if end == 1 else "start", 0.0, 0.0, tuple(np.round(R[-1], 6)))
                if bend is not None:
                    if end in gaps:
                        bend.gap, bend.gap_h = gaps[end]
                    P_in = merge_close(P0 if end == 1 else P0[::-1], 1e-9 * h, False)
                    bend.input_angle_deg = end_chord_angle(S, P_in, h)
                    bend.slid_h = slid
                    ends.append(bend)
        turn_in = float(turning(merge_close(P0, 1e-9 * h, c.closed), 0.5 * h, c.closed).max()) if len(P0) > 2 else 0.0
        turn_out = float(turning(Q, 0.5 * h, c.closed).max()) if len(Q) > 2 else 0.0
        disp = hausdorff(P0, Q, 0.05 * h) / h
        curves.append(Curve(Q, c.sigma, c.role, c.torsion, c.name, c.closed))
        repairs.append(CurveRepair(pn.source[ci], c.name, len(P0), len(Q), merged, faired, disp, turn_in, turn_out,
                                   ncorner, ends[::-1], note, moves(pn.source[ci]),
                                   pn.pieces.get(pn.source[ci], [])))
    out = PreparedNetwork(curves, list(pn.source), list(pn.start_kind), list(pn.end_kind), pn.nodes, pn.pieces)
    return out, repairs
