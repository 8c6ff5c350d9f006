"""The singularity network: curves with an index, a role and a torsion mode.

Sign convention for the index sigma (used everywhere in SymFrames)
------------------------------------------------------------------
Orient a small loop around a curve counter-clockwise when seen from the tip of
the curve's tangent T (right-hand rule around T).  Going once around that loop
the cross field turns by ``2*pi*sigma`` about T in the same (right-handed)
sense.  Reversing the curve reverses both T and the loop, so sigma does not
depend on the curve's direction.  Where a curve meets the boundary, the 2D
field on the boundary has a singularity of the same index sigma, counted with
the outward normal; so sigma = +1/4 is the valence-3 edge of a hex mesh (the
cube's own edges), sigma = -1/4 the valence-5 edge.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .. import checks
from ..errors import NetworkError
from .polyline import spaced


class Role(str, Enum):
    """What a curve of the network is to the field.

    Attributes
    ----------
    SINGULAR : str
        ``'singular'``: an interior curve with index sigma != 0; the field
        turns by sigma about it (Eq. 17).
    FEATURE : str
        ``'feature'``: an interior curve with sigma = 0; the field is
        adapted to its tangent but regular around it.
    SHARP : str
        ``'sharp'``: a sharp feature curve on the boundary surface.
    """

    SINGULAR = "singular"  # interior curve with sigma != 0
    FEATURE = "feature"  # interior curve with sigma == 0: the field is tangent, not singular
    SHARP = "sharp"  # sharp feature curve lying on the boundary surface


class Torsion(str, Enum):
    """How the torsion of the field along a curve is treated (§4.2).

    Attributes
    ----------
    FREE : str
        ``'free'`` (the default): a free torsion per curve edge (Eq. 21).
    FIXED : str
        ``'fixed'``: the total torsion of the least-twist reference frame
        (Eq. 22).
    """

    FREE = "free"  # Eq. 21: free torsion per edge
    FIXED = "fixed"  # Eq. 22: total torsion of the least-twist reference frame


_UNSET = object()


class _Checked:
    """A dataclass whose fields, set after construction, are checked again
    as at construction (``_check``): a value refused there is refused here,
    with the same NetworkError, and the old value is kept."""

    def __setattr__(self, name, value):
        d = self.__dict__
        if not d.get("_ready") or d.get("_checking") or name.startswith("_"):
            object.__setattr__(self, name, value)
            return
        old = d.get(name, _UNSET)
        object.__setattr__(self, name, value)
        object.__setattr__(self, "_checking", True)
        try:
            self._check()
        except BaseException:
            if old is _UNSET:
                object.__delattr__(self, name)
            else:
                object.__setattr__(self, name, old)
            raise
        finally:
            object.__setattr__(self, "_checking", False)


@dataclass
class Curve(_Checked):
    """A polyline of the network.

    The fields are checked when the curve is made and again when one is set
    later (``NetworkError`` names the field and the fix; a refused value
    leaves the old one).

    Parameters
    ----------
    points : (n, 3) float array
        n >= 2 points; a closed loop repeats its first point at the end (or
        sets ``closed``).
    sigma : float
        The index in turns, a multiple of 1/4: +0.25 for a valence-3 edge
        of a hex mesh, -0.25 for valence 5, 0 for a feature curve.
    role : Role or str
        ``'singular'`` (default), ``'feature'`` or ``'sharp'``.
    torsion : Torsion or str
        ``'free'`` (Eq. 21, default) or ``'fixed'`` (Eq. 22).
    name : str
        Named in every message about the curve.
    closed : bool
        The polyline is a loop.

    Raises
    ------
    NetworkError
        A field of the wrong type or out of range.
    """

    points: np.ndarray
    sigma: float = 0.25
    role: Role = Role.SINGULAR
    torsion: Torsion = Torsion.FREE
    name: str = ""
    closed: bool = False

    def __post_init__(self):
        self._check()
        object.__setattr__(self, "_ready", True)

    def _check(self):
        # types and ranges in one place (checks.py); geometry is checked
        # against the solid in validation.py
        E = NetworkError
        self.name = "" if self.name is None else checks.text("curve name", self.name, E)
        where = f"curve {self.label}"
        self.points = checks.points3(f"{where}: points", self.points, E)
        self.sigma = checks.real(f"{where}: sigma", self.sigma, E,
                                 fix="the index in turns, a multiple of 1/4 such as 0.25 or -0.25 (0 for a feature)")
        self.role = Role(checks.choice(f"{where}: role", self.role, [r.value for r in Role], E))
        self.torsion = Torsion(checks.choice(f"{where}: torsion", self.torsion, [t.value for t in Torsion], E))
        self.closed = checks.boolean(f"{where}: closed", self.closed, E)

    @property
    def label(self) -> str:
        return f"'{self.name}'" if self.name else "(unnamed)"


def _corner_turns(turns) -> dict:
    """corner_turns checked: {vertex index (int >= 0) or (x, y, z): -2..2 quarter turns}."""
    E = NetworkError
    out = {}
    for key, q in checks.mapping("corner_turns", turns, E).items():
        if isinstance(key, tuple):
            key = tuple(checks.points3(f"corner_turns key {key!r}", [key], E, min_points=1)[0].tolist())
        else:
            key = checks.integer(f"corner_turns key {key!r}", key, E, low=0,
                                 fix="a surface vertex index, or an (x, y, z) position")
        out[key] = checks.integer(f"corner_turns[{key!r}]", q, E, low=-2, high=2,
                                  fix="quarter turns: 0 smooth, 1 convex corner, -1 concave")
    return out


@dataclass
class Network(_Checked):
    """The curve network and the sharp-feature settings of a domain.

    Parameters
    ----------
    curves : list of Curve
    sharp_edges : (k, 2) int array, optional
        Surface vertex pairs marked sharp.
    sharp_angle : float, optional
        Dihedral threshold in degrees: surface edges whose normals differ by
        more than this are sharp.
    node_tolerance : float, optional
        Curve ends closer than this form a node (default: 1e-3 of the
        surface's bounding-box diagonal).
    boundary_tolerance : float, optional
        Curve ends closer than this to the surface end on the boundary
        (default: 1e-2 of the diagonal).
    corner_turns : dict, optional
        ``{surface vertex index or (x, y, z): quarter turns}`` fixing the
        turn of sharp corners (surface/corners.py): 0 smooth, 1 a convex
        corner (index +1/4), -1 a concave one.

    Raises
    ------
    NetworkError
        A field of the wrong type or out of range; ``validate()`` checks
        again after fields were changed.
    """

    curves: list[Curve] = field(default_factory=list)
    sharp_edges: np.ndarray | None = None
    sharp_angle: float | None = None
    node_tolerance: float | None = None
    boundary_tolerance: float | None = None
    corner_turns: dict | None = None

    def __post_init__(self):
        self.validate()
        object.__setattr__(self, "_ready", True)

    def _check(self):
        self.validate()

    def validate(self) -> None:
        """Types and ranges of the fields (checks.py); raises NetworkError.
        Tolerances are checked against the surface's size in prepare_network."""
        E = NetworkError
        if not isinstance(self.curves, (list, tuple)):
            raise E(f"the network's curves must be a list of Curve, got {checks.describe(self.curves)}")
        self.curves = list(self.curves)
        for k, c in enumerate(self.curves):
            if not isinstance(c, Curve):
                raise E(f"curves[{k}] is {checks.describe(c)}, not a Curve; wrap each polyline, e.g. "
                        "Curve(points, sigma=0.25, name='axis')")
        if self.sharp_edges is not None:
            self.sharp_edges = checks.index_pairs("sharp_edges", self.sharp_edges, E)
        self.sharp_angle = checks.real("sharp_angle", self.sharp_angle, E, low=0.0, high=180.0, high_open=True,
                                       allow_none=True,
                                       fix="a dihedral angle in degrees, e.g. 30 (None: no sharp edges by angle)")
        for key in ("node_tolerance", "boundary_tolerance"):
            setattr(self, key, checks.positive_float(key, getattr(self, key), E, allow_none=True,
                                                     fix="a distance in the units of the surface (None: the "
                                                         "default, a fraction of the bounding-box diagonal)"))
        if self.node_tolerance is not None and self.curves:
            # against the surface in check_tolerances; here against the curves
            # themselves, whose ends it would all merge
            X = np.vstack([c.points for c in self.curves])
            size = float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))
            if size > 0 and self.node_tolerance > 0.5 * size:
                raise E(f"node_tolerance = {self.node_tolerance:g} is more than half the size of the whole network "
                        f"({size:.4g}); it would join every curve end into one node. Give it in the units of the "
                        "curves, e.g. a thousandth of the model's size, or leave it unset")
        if self.corner_turns is not None:
            self.corner_turns = _corner_turns(self.corner_turns)

    @property
    def interior_curves(self) -> list[int]:
        return [i for i, c in enumerate(self.curves) if c.role != Role.SHARP]

    @property
    def sharp_curves(self) -> list[int]:
        return [i for i, c in enumerate(self.curves) if c.role == Role.SHARP]


@dataclass
class Node:
    """An interior point where 3 or 4 curve ends meet.

    ends : list of (curve index, 0 for the start / 1 for the end)
    """

    position: np.ndarray
    ends: list


@dataclass
class PreparedNetwork:
    """Interior curves after cleaning, joining and classifying their ends.

    curves : list of Curve, points cleaned; closed loops end at their start
    start_kind, end_kind : per curve 'boundary', 'node' or 'loop'
    nodes : list of Node
    """

    curves: list[Curve]
    source: list[int]  # index of each prepared curve in Network.curves
    start_kind: list[str]
    end_kind: list[str]
    nodes: list[Node]
    pieces: dict = field(default_factory=dict)  # source index -> input curves joined into it (_join_chains)


def clean_polyline(points: np.ndarray, tol: float) -> np.ndarray:
    """Drop consecutive points closer than tol."""
    return points[spaced(points, tol)]


def check_curve_basics(net: Network, diag: float) -> None:
    """Per-curve checks that need no geometry: shapes, indices, roles."""
    if not isinstance(net.curves, (list, tuple)):
        raise NetworkError("the network's curves must be a list")
    for k, c in enumerate(net.curves):
        where = f"curve {k} {c.label}"
        P = c.points
        if P.ndim != 2 or P.shape[1] != 3:
            raise NetworkError(f"{where}: points must be an (n, 3) array, got shape {P.shape}")
        if not np.all(np.isfinite(P)):
            raise NetworkError(f"{where}: has a non-finite point coordinate")
        q = 4.0 * c.sigma
        if abs(q - round(q)) > 1e-9:
            raise NetworkError(
                f"{where}: index sigma = {c.sigma:g} is not a multiple of 1/4; "
                f"use quarter turns, e.g. {round(q) / 4:g}"
            )
        if c.role == Role.FEATURE and round(q) != 0:
            raise NetworkError(f"{where}: a feature curve must have sigma = 0 (got {c.sigma:g}); make it 'singular'")
        if c.role == Role.SINGULAR and round(q) == 0:
            raise NetworkError(
                f"{where}: a singular curve needs a nonzero index; use sigma = 0 only with role 'feature'"
            )
        if c.role == Role.SHARP and round(q) != 0:
            raise NetworkError(f"{where}: sharp boundary features carry no index; set sigma = 0")
        if len(clean_polyline(P, 1e-9 * diag)) < 2:
            raise NetworkError(f"{where}: needs at least two distinct points")


MAX_TOLERANCE = 0.1  # of the bounding-box diagonal, for node_tolerance and boundary_tolerance


def check_tolerances(net: Network, diag: float) -> None:
    """Refuse tolerances so large that they join unrelated curve ends into a
    node or call a point deep inside the solid "on the boundary"."""
    net.validate()  # fields may have been changed since construction
    for key, default in (("node_tolerance", 1e-3), ("boundary_tolerance", 1e-2)):
        v = getattr(net, key)
        if v is not None and v > MAX_TOLERANCE * diag:
            raise NetworkError(
                f"{key} = {v:g} is more than {MAX_TOLERANCE:g} of the surface's bounding-box diagonal ({diag:.4g}); "
                f"it would merge unrelated points. Give it in the units of the surface (the default is "
                f"{default:g} of the diagonal, {default * diag:.3g} here) or leave it unset")


def prepare_network(net: Network, diag: float) -> PreparedNetwork:
    """Clean interior curves, find nodes, join degree-2 chains and loops.

    Endpoints are classified as 'node' (3-4 ends within node_tolerance),
    'loop' (the curve closes on itself) or, provisionally, 'boundary'; the
    boundary claim is checked against the surface later.
    """
    check_curve_basics(net, diag)
    check_tolerances(net, diag)
    tol = net.node_tolerance if net.node_tolerance is not None else 1e-3 * diag
    idx = net.interior_curves
    curves = []
    for k in idx:
        c = net.curves[k]
        P = clean_polyline(c.points, 1e-9 * diag)
        closed = c.closed or (len(P) > 2 and np.linalg.norm(P[0] - P[-1]) <= tol)
        if closed and np.linalg.norm(P[0] - P[-1]) > 1e-12:
            P = np.vstack([P, P[:1]])
        elif closed:
            P[-1] = P[0]
        if closed and len(P) < 4:
            raise NetworkError(f"curve {k} {c.label}: a closed loop needs at least three distinct points")
        curves.append(Curve(P, c.sigma, c.role, c.torsion, c.name, closed))
    curves, idx, pieces = _join_chains(curves, idx, tol)
    # cluster the open ends
    ends = [(i, s) for i, c in enumerate(curves) if not c.closed for s in (0, 1)]
    nodes: list[Node] = []
    kinds = {}
    if ends:
        X = np.array([curves[i].points[0 if s == 0 else -1] for i, s in ends])
        lab = cluster_points(X, tol)
        for cl in range(lab.max() + 1):
            members = np.nonzero(lab == cl)[0]
            m_ends = [ends[m] for m in members]
            if len(members) == 1:
                kinds[m_ends[0]] = "boundary"
                continue
            names = ", ".join(f"{net.curves[idx[i]].label}" for i, _ in m_ends)
            pos = X[members].mean(axis=0)
            if len({i for i, _ in m_ends}) == 1 and len(members) == 2:
                raise NetworkError(
                    f"curve {idx[m_ends[0][0]]} {net.curves[idx[m_ends[0][0]]].label}: its two ends meet at "
                    f"{_fmt(pos)} but the curve is not closed; close it or move an end"
                )
            if len(members) == 2:
                a, b = (curves[i] for i, _ in m_ends)
                gap = float(np.linalg.norm(X[members[0]] - X[members[1]]))
                if (a.sigma, a.role, a.torsion) == (b.sigma, b.role, b.torsion):
                    # not joined by _join_chains: they turn back on each other
                    raise NetworkError(
                        f"curves {names} have ends {gap:.3g} apart at {_fmt(pos)}, closer than node_tolerance "
                        f"({tol:.3g}), but they do not continue each other (they turn back there): ends this "
                        "close are one point, and curves are joined only where one continues the other. Move "
                        "the ends apart (more than node_tolerance), make them one curve, or end them at a node "
                        "of 3-4 curves")
                raise NetworkError(
                    f"curves {names} meet end to end at {_fmt(pos)} (ends {gap:.3g} apart, within "
                    f"node_tolerance {tol:.3g}; a node of degree 2) with different "
                    f"indices, roles or torsions (sigma {a.sigma:+g} / {b.sigma:+g}, {a.role.value} / "
                    f"{b.role.value}, torsion {a.torsion.value} / {b.torsion.value}); one curve needs one of "
                    "each: make them equal, or end them at a node of 3-4 curves"
                )
            if len(members) > 4:
                raise NetworkError(
                    f"{len(members)} curve ends meet at {_fmt(pos)} ({names}); nodes of degree 3 and 4 are "
                    "supported, split the node into several"
                )
            for e in m_ends:
                kinds[e] = "node"
            nodes.append(Node(pos, m_ends))
    start_kind = ["loop" if c.closed else kinds[(i, 0)] for i, c in enumerate(curves)]
    end_kind = ["loop" if c.closed else kinds[(i, 1)] for i, c in enumerate(curves)]
    # snap node ends exactly onto the node
    for node in nodes:
        for i, s in node.ends:
            curves[i].points[0 if s == 0 else -1] = node.position
    return PreparedNetwork(curves, idx, start_kind, end_kind, nodes, pieces)


def cluster_points(X: np.ndarray, tol: float) -> np.ndarray:
    """Cluster label per point: points chained by distances <= tol share one
    (labels 0..k-1)."""
    n = len(X)
    pairs = cKDTree(X).query_pairs(tol, output_type="ndarray")
    if not len(pairs):
        return np.arange(n)
    return connected_components(coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)),
                                directed=False)[1]


def _end_direction(P: np.ndarray, end: int) -> np.ndarray:
    """Unit direction in which an open polyline leaves through its end (0:
    the start, 1: the end): the chord from the point a quarter of its length
    in, which a hand-drawn wiggle at the end does not turn."""
    Q = P if end == 1 else P[::-1]
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))]
    k = min(int(np.searchsorted(s, 0.75 * s[-1])), len(Q) - 2)
    d = Q[-1] - Q[k]
    n = np.linalg.norm(d)
    return d / n if n > 0 else d


def _join_chains(curves: list, idx: list, tol: float) -> tuple[list, list, dict]:
    """Curves that meet end to end, two ends alone within tol with the same
    index, role and torsion (a curve drawn in several strokes), become one
    curve (closed if the chain closes).  sigma does not depend on a curve's
    direction, so a piece is reversed where needed.  Returns the curves,
    their input indices (a joined curve: its first piece's) and {input index
    of a joined curve: input indices of its pieces}; pieces with different
    indices are left apart, for the degree-2 node refusal."""
    ends = [(i, s) for i, c in enumerate(curves) if not c.closed for s in (0, 1)]
    if len(ends) < 2:
        return curves, idx, {}
    lab = cluster_points(np.array([curves[i].points[0 if s == 0 else -1] for i, s in ends]), tol)
    link = {}  # (curve, end) -> (other curve, its end)
    for cl in np.unique(lab):
        m = np.nonzero(lab == cl)[0]
        if len(m) != 2:
            continue
        (i, si), (j, sj) = ends[m[0]], ends[m[1]]
        a, b = curves[i], curves[j]
        if i == j or (a.sigma, a.role, a.torsion) != (b.sigma, b.role, b.torsion):
            continue
        if _end_direction(a.points, si) @ _end_direction(b.points, sj) >= 0:
            # the pieces turn back on each other (two curves side by side, not one drawn in strokes): left
            # apart, for the refusal that names both and their distance
            continue
        link[(i, si)], link[(j, sj)] = (j, sj), (i, si)
    if not link:
        return curves, idx, {}
    done = set()
    out, out_idx, pieces_of = [], [], {}
    # chains first from a piece with a free end, then the closed ones
    starts = [i for i in range(len(curves)) if not curves[i].closed and ((i, 0) in link) != ((i, 1) in link)]
    starts += [i for i in range(len(curves)) if (i, 0) in link and (i, 1) in link]
    for i in range(len(curves)):
        if i in done:
            continue
        if (i, 0) not in link and (i, 1) not in link:
            out.append(curves[i])
            out_idx.append(idx[i])
            done.add(i)
    for i0 in starts:
        if i0 in done:
            continue
        # walk from i0's free end (or its start, for a closed chain)
        s_in = 0 if (i0, 0) not in link or (i0, 1) in link else 1
        pieces, i, s = [], i0, s_in
        members = []
        while i not in done:
            done.add(i)
            members.append(idx[i])
            P = curves[i].points if s == 0 else curves[i].points[::-1]
            pieces.append(P if not pieces else P[1:])
            nxt = link.get((i, 1 - s))
            if nxt is None:
                break
            i, s = nxt
        P = np.vstack(pieces)
        c0 = curves[i0]
        closed = np.linalg.norm(P[0] - P[-1]) <= tol and len(pieces) > 1 and (i0, 0) in link and (i0, 1) in link
        if closed:
            P[-1] = P[0]
        out.append(Curve(P, c0.sigma, c0.role, c0.torsion, c0.name, closed))
        out_idx.append(idx[i0])
        pieces_of[idx[i0]] = sorted(members)
    order = np.argsort(out_idx, kind="stable")
    return [out[k] for k in order], [out_idx[k] for k in order], pieces_of


def _fmt(p) -> str:
    return "(" + ", ".join(f"{x:.4g}" for x in p) + ")"


def polyline_tangents(P: np.ndarray, closed: bool) -> np.ndarray:
    """Unit tangents at polyline vertices: the normalised sum of the adjacent
    unit segment directions."""
    seg = np.diff(P, axis=0)
    seg = seg / np.maximum(np.linalg.norm(seg, axis=1, keepdims=True), 1e-300)  # a repeated point adds nothing
    T = np.zeros_like(P)
    T[:-1] += seg
    T[1:] += seg
    if closed:
        T[0] += seg[-1]
        T[-1] = T[0]
    # a hairpin (opposite segments) would give zero; fall back to a segment
    bad = np.linalg.norm(T, axis=1) < 1e-9
    T[bad] = np.vstack([seg, seg[-1:]])[bad]
    return T / np.linalg.norm(T, axis=1, keepdims=True)
