"""Checks of the network against the solid, run before any heavy work.

Every failure is a ``ValueError`` subclass naming the curve or point and
saying how to fix it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from .. import checks
from ..errors import NetworkError, TopologyError
from ..surface.corners import check_realisable, explain_failure, resolve_corners
from ..surface.features import (
    FeatureGraph,
    check_poincare_hopf,
    polyline_to_edges,
    sharp_edges_by_angle,
    sharp_edges_from_pairs,
)
from ..surface.intersect import segment_crosses_triangle, segments_distance
from ..surface.thickness import check_edge_length
from ..surface.trisurface import TriSurface
from ..surface.validation import validate_surface
from .curve_ends import END_GAP, join_loose_ends
from .fairing import MAX_KINK
from .intake import IntakeScales, repair_network, solid_scale
from .network import Network, PreparedNetwork, _fmt, check_curve_basics, check_tolerances, prepare_network
from .polyline import turning

MAX_END_ANGLE = 30.0  # degrees between a curve's end tangent and the surface normal
CROSSING_TOLERANCE = 0.01  # curves closer than this times h touch


@dataclass
class CheckedInput:
    """Everything the pipeline needs from a validated input."""

    surface: TriSurface
    network: PreparedNetwork
    features: FeatureGraph
    face_sigma: np.ndarray  # (#F,) index of curve ends per input triangle
    feature_size: float  # smallest distance the mesh must resolve
    repairs: list = field(default_factory=list)  # intake.CurveRepair per interior curve
    scale: float = 0.0  # the length h the curves were repaired and checked at
    corners: list = field(default_factory=list)  # corners.CornerChoice per reported sharp corner
    # (#curves,) the scale each prepared curve was repaired and checked at:
    # `scale`, or finer where an end bend needed it (intake.py); the
    # automatic resolution meshes that fine around it (mesh/resolution.py)
    curve_scales: np.ndarray | None = None
    # (#surface edges,) bool: sharp edges the corner quantisation made smooth
    # bends (corners.py), which the hex boundary still follows; None: none
    bends: np.ndarray | None = None


def _label(net_curves, k):
    c = net_curves[k]
    return f"curve {k} '{c.name}'" if c.name else f"curve {k}"


def sharp_feature_graph(S: TriSurface, net: Network) -> FeatureGraph:
    """Sharp edges from the mesh marks, the angle threshold and 'sharp' curves."""
    sharp = np.zeros(len(S.edges), bool)
    if net.sharp_edges is not None and len(net.sharp_edges):
        sharp |= sharp_edges_from_pairs(S, net.sharp_edges)
    if net.sharp_angle is not None:
        sharp |= sharp_edges_by_angle(S, net.sharp_angle)
    tol = 1e-2 * S.bbox_diagonal
    for k in net.sharp_curves:
        c = net.curves[k]
        d, _, _ = S.closest_points(c.points)
        if np.max(d) > tol:
            i = int(np.argmax(d))
            raise NetworkError(
                f"{_label(net.curves, k)} is a sharp boundary feature but its point {_fmt(c.points[i])} lies "
                f"{d[i]:.3g} away from the surface; snap it onto the surface or make it an interior curve"
            )
        closed = c.closed or np.linalg.norm(c.points[0] - c.points[-1]) < 1e-9 * S.bbox_diagonal
        sharp |= polyline_to_edges(S, c.points, closed)
    return FeatureGraph(S, sharp)


def check_input(V, F, net: Network, check_intersections: bool = True, scale: float | None = None,
                repair: bool = True, target_tets: int = 15000) -> CheckedInput:
    """Validate the surface and the network; raise with an actionable message.

    scale  : the length h at which curves are repaired and measured (kinks
             over h, crossings closer than CROSSING_TOLERANCE * h); None:
             intake.solid_scale(surface, target_tets), the budget edge length
    repair : run the curve intake (intake.py) on the interior curves first
    """

    if not isinstance(net, Network):
        raise NetworkError(f"network = {checks.describe(net)}: must be a solver.Network (e.g. Network(curves=[...]), "
                           "or Network() for none)")
    S = validate_surface(V, F, check_intersections=check_intersections)
    diag = S.bbox_diagonal
    if scale is not None:  # a given edge length: refused before meshing when past the solid's size
        check_edge_length(S, float(scale), solid_scale(S, target_tets))
    h = float(scale) if scale is not None else solid_scale(S, target_tets)
    btol = net.boundary_tolerance if net.boundary_tolerance is not None else 1e-2 * diag
    joined = {}
    if repair:
        # as prepare_network does first: the points and tolerances are sound
        check_curve_basics(net, diag)
        check_tolerances(net, diag)
        ntol = net.node_tolerance if net.node_tolerance is not None else 1e-3 * diag
        net, joined = join_loose_ends(S, net, h, ntol, btol)
    pn = prepare_network(net, diag)
    check_nodes(pn, lambda ci: _label(net.curves, pn.source[ci]))

    def label(ci):
        return _label(net.curves, pn.source[ci])

    G = sharp_feature_graph(S, net)
    repairs = []
    intake = IntakeScales(np.full(len(pn.curves), h), [np.zeros((0, 3))] * len(pn.curves))
    if repair and pn.curves:
        # a real crossing is refused before fairing could pull it apart
        _check_crossings(pn, label, CROSSING_TOLERANCE * h)
        E = S.edges[G.sharp]
        pn, repairs, intake = repair_network(S, pn, h, [label(ci) for ci in range(len(pn.curves))], btol, joined,
                                             (S.V[E[:, 0]], S.V[E[:, 1]]), G.patches[1] if len(E) else None)
        if scale is not None:
            _check_local_scales(intake.scales, h, repairs, label)

    face_sigma = np.zeros(len(S.F))
    end_points = []  # (curve, point) of each end on the boundary
    # ------------------------------------------------------- ends and insides
    for ci, c in enumerate(pn.curves):
        for end, kind in ((0, pn.start_kind[ci]), (1, pn.end_kind[ci])):
            if kind == "boundary":
                f, q = _boundary_end(S, c.points, end, label(ci), btol, h)
                face_sigma[f] += c.sigma
                end_points.append((ci, q))
        _check_inside(S, pn, ci, label(ci), float(intake.scales[ci]), intake.corners[ci],
                      repairs[ci] if repairs else None)
    # ------------------------------------------------------------- crossings
    _check_crossings(pn, label, CROSSING_TOLERANCE * h)
    _check_end_points(S, G, end_points, label)
    # -------------------------------------------------------- Poincare-Hopf
    sharp_given = G.sharp
    G, corners = resolve_corners(S, G, face_sigma, net.corner_turns)
    bends = sharp_given & ~G.sharp
    try:
        check_poincare_hopf(S, G, face_sigma, "the boundary")
        G.check_patches(face_sigma)
    except TopologyError as e:
        explain_failure(S, G, corners, e, face_sigma)
    check_realisable(G, np.array([q for _, q in end_points]).reshape(-1, 3), h, corners)
    size = network_feature_size(S, pn)
    return CheckedInput(S, pn, G, face_sigma, size, repairs, h, corners, intake.scales,
                        bends if bends.any() else None)


def _boundary_end(S: TriSurface, P: np.ndarray, end: int, label: str, btol: float, h: float):
    """The boundary triangle and point where the curve through P ends (end
    0: its start, 1: its end), refused when it is off the surface or meets
    it at more than MAX_END_ANGLE from the normal."""
    x = P[0] if end == 0 else P[-1]
    d, f, q = S.closest_points(x[None])
    if d[0] > btol:
        where = "starts" if end == 0 else "ends"
        far = d[0] > END_GAP * h
        gap = f"distance to the surface {d[0]:.3g} = {d[0] / h:.2f} h; "
        if S.winding_number(x[None])[0] < 0.5:
            gap += (f"ends up to {END_GAP:g} h outside are cut back onto it" if far else
                    f"the curve does not cross the surface within {END_GAP:g} h of that end, to be cut "
                    "back there")
            raise NetworkError(
                f"{label} {where} at {_fmt(x)}, outside the solid ({gap}); move that end onto the "
                "surface, or inside the solid at a node"
            )
        gap += (f"ends up to {END_GAP:g} h short of it are extended onto it" if far else
                f"its last chord, extended by {END_GAP:g} h, does not reach it")
        raise NetworkError(
            f"{label} {where} at {_fmt(x)}, inside the solid but not at a node or on the boundary "
            f"({gap}); extend it to the surface, or connect 3-4 curve ends at a node"
        )
    t = (P[1] - P[0]) if end == 0 else (P[-1] - P[-2])
    t = t / np.linalg.norm(t)
    n = S.face_normals[f[0]]
    ang = np.degrees(np.arccos(min(1.0, abs(float(t @ n)))))
    if ang > MAX_END_ANGLE:
        raise NetworkError(
            f"{label} meets the boundary at {_fmt(q[0])} at {ang:.0f} degrees from the surface normal; "
            "a curve must reach the surface at right angles (its tangent along the normal), since the "
            "frame there is adapted to both"
        )
    return f[0], q[0]


def _check_inside(S: TriSurface, pn: PreparedNetwork, ci: int, label: str, h: float,
                  corners: np.ndarray | None = None, repaired=None) -> None:
    """Refuse a curve whose points or segments leave the solid, or a
    singular curve with a kink (over h, its own scale; corners: the input's
    corners the intake held; repaired: the intake's CurveRepair of it)."""
    c = pn.curves[ci]
    P = c.points
    inner = P[1:-1] if not c.closed else P[:-1]
    ends_inside = [P[0]] if pn.start_kind[ci] == "node" else []
    ends_inside += [P[-1]] if pn.end_kind[ci] == "node" else []
    X = np.vstack([inner] + ([np.array(ends_inside)] if ends_inside else [])) if len(inner) or ends_inside \
        else np.zeros((0, 3))
    if len(X):
        w = S.winding_number(X)
        bad = np.nonzero(w < 0.5)[0]
        if len(bad):
            raise NetworkError(
                f"{label} passes outside the solid at {_fmt(X[bad[0]])}; keep interior curves inside the "
                "domain mesh"
            )
    _check_segments_inside(S, P, label, pn, ci)
    if c.sigma != 0:
        _check_kinks(P, c.closed, label, h, corners, repaired)


def _check_end_points(S: TriSurface, G: FeatureGraph, end_points: list, label) -> None:
    """Ends on the boundary must be distinct and away from sharp features."""
    diag = S.bbox_diagonal
    if len(end_points) > 1:
        Q = np.array([q for _, q in end_points])
        pairs = cKDTree(Q).query_pairs(1e-3 * diag)
        for a, b in pairs:
            raise NetworkError(
                f"{label(end_points[a][0])} and {label(end_points[b][0])} end at the same boundary point "
                f"{_fmt(Q[a])}; boundary ends must be distinct"
            )
    if np.any(G.sharp) and end_points:
        E = S.edges[G.sharp]
        mids = 0.5 * (S.V[E[:, 0]] + S.V[E[:, 1]])
        seg_len = np.linalg.norm(S.V[E[:, 1]] - S.V[E[:, 0]], axis=1).max()
        tree = cKDTree(mids)
        for ci, q in end_points:
            d, j = tree.query(q)
            a, b = S.V[E[j]]
            t = np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
            if np.linalg.norm(a + t * (b - a) - q) < 1e-3 * diag or d < 1e-6 * seg_len:
                raise NetworkError(
                    f"{label(ci)} ends on a sharp edge at {_fmt(q)}; end it inside a face, away from sharp edges"
                )


def check_nodes(pn: PreparedNetwork, label) -> None:
    """Refuse node configurations that no hex mesh vertex has (and, for the
    first rule, that no cross field has), naming the node and the rule.

    Let a node join k curve ends of indices sigma_1..sigma_k.

    1. Parity.  Going around a curve of index sigma the field turns by
       2 pi sigma, an element of the cube's rotation group O, which acts on
       the four body diagonals as S4: a quarter or three-quarter turn is a
       4-cycle (odd), a half or full turn even.  The loops around all curve
       ends at a node compose to a loop on a small sphere around it that
       bounds a disk there, so the product of their turns is the identity.
       Hence the number of ends whose index is an odd multiple of 1/4 must be
       even: three +1/4 curves cannot meet, nor three +1/4 and one feature.

    2. Room for the curves.  The field is meant for hex meshing (Liu et al.
       2018, "Singularity-constrained octahedral fields for hexahedral
       meshing", list the locally meshable node types).  The link of a hex
       mesh vertex is a triangulated sphere: its vertices are the mesh edges
       at the node, its triangles the hexes, and an edge of valence v (v
       hexes around it, v = 4 - 4 sigma: 3 for +1/4, 5 for -1/4, 4 for a
       regular edge or a feature curve) is a link vertex of degree v.
       Euler's formula with 3 T = 2 E gives sum (6 - v) = 12 over the link
       vertices, so the node has 6 - 2 sum(sigma) edges and 8 - 4 sum(sigma)
       hexes.  Each curve end is one of those edges, so
       6 - 2 sum(sigma) >= k: sum(sigma) <= 3/2 at a degree-3 node and <= 1
       at a degree-4 node (the ball's cube-sphere nodes, four +1/4 curves,
       are exactly at the bound: 4 hexes).  Four half-turn curves (sum 2)
       leave room for no hex at all; LM then ended at a penalty of 91.
    """
    for n, nd in enumerate(pn.nodes):
        sig = np.array([pn.curves[i].sigma for i, _ in nd.ends])
        q = np.rint(4 * sig).astype(int)
        k = len(sig)
        names = ", ".join(f"{label(i)} ({s:+g})" for (i, _), s in zip(nd.ends, sig))
        where = f"node {n} at {_fmt(nd.position)} joining {names}"
        odd = int(np.sum(q % 2 != 0))
        if odd % 2:
            raise NetworkError(
                f"{where}: {odd} of its curves have an index that is an odd multiple of 1/4; no cross field has such "
                "a node (the turns around the curves at a node must compose to no turn, and an odd number of "
                "quarter turns cannot). Change one index by 1/4 (e.g. make a curve a feature or give it "
                "+-1/2), or add or remove a curve at the node"
            )
        total = float(sig.sum())
        edges = 6 - 2 * total
        if edges < k:
            raise NetworkError(
                f"{where}: the indices sum to {total:g}, but a hex-mesh vertex with edges of these indices has "
                f"6 - 2 x {total:g} = {edges:g} edges and {8 - 4 * total:g} hexes around it, fewer than its {k} "
                f"curves need (the sum must be at most {(6 - k) / 2:g} at a node of {k} curves). Lower some "
                "indices (e.g. +1/4 instead of +1/2)"
            )


def _check_segments_inside(S: TriSurface, P, label, pn, ci):
    """No segment of an interior curve may cross the surface (except the end
    segments touching it)."""
    a, b = P[:-1], P[1:]
    mid = 0.5 * (a + b)
    half = 0.5 * np.linalg.norm(b - a, axis=1)
    T, cent, rad, tree = S.face_tree
    tol = 1e-9 * S.bbox_diagonal
    near = tree.query_ball_point(mid, half + rad.max())
    for k in range(len(a)):
        cand = near[k]
        if not cand:
            continue
        cand = np.asarray(cand)
        hit = segment_crosses_triangle(np.repeat(a[k][None], len(cand), 0), np.repeat(b[k][None], len(cand), 0),
                                       T[cand], tol)
        if not np.any(hit):
            continue
        # crossings at the very ends of boundary-ending curves are their ends
        f = cand[hit]
        x = _segment_triangle_point(a[k], b[k], T[f])
        da = np.linalg.norm(x - P[0], axis=1)
        db = np.linalg.norm(x - P[-1], axis=1)
        endtol = 1e-2 * S.bbox_diagonal
        ok = ((pn.start_kind[ci] == "boundary") & (da < endtol)) | ((pn.end_kind[ci] == "boundary") & (db < endtol))
        if not np.all(ok):
            raise NetworkError(
                f"{label} crosses the boundary surface at {_fmt(x[~ok][0])}; keep interior curves inside the "
                "solid between their ends"
            )


def _segment_triangle_point(a, b, T):
    n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    t = np.einsum("ij,ij->i", n, T[:, 0] - a) / np.einsum("ij,j->i", n, b - a)
    return a + t[:, None] * (b - a)


def _check_kinks(P, closed, label, h, corners=None, repaired=None):
    """The turn between chords of h/2 on either side of each vertex: a
    segment far shorter than h carries no direction of its own.

    The message says whose the turn is (issue 41a): at a corner of the
    curve as given that the intake held (``corners``), the user's; anywhere
    else on a repaired curve, the repair's -- the intake bends ends within
    this bar and refines locally where a curve is too short for h, so such
    a turn is a fault of the repair, reported as one with what the repair
    did (``repaired``: its intake.CurveRepair)."""

    ang = turning(P, 0.5 * h, closed)
    bad = np.nonzero(ang > MAX_KINK)[0]
    if not len(bad):
        return
    k = bad[np.argmax(ang[bad])]
    at = f"{label} turns by {ang[k]:.0f} degrees over a length {h:.3g} (the mesh scale h) at {_fmt(P[k])}"
    held = corners is not None and len(corners) and np.min(np.linalg.norm(corners - P[k], axis=1)) <= 0.5 * h
    if held or repaired is None or not repaired.changed:
        raise NetworkError(
            f"{at}, a corner of the curve as given; a singular curve must be smooth (its axis of rotation is its "
            "tangent), so round the corner or split the curve at a node"
        )
    local = f", even at the local scale {h:.3g} = {repaired.scale_h:.2g} h" if repaired.scale_h < 1.0 else ""
    raise NetworkError(
        f"{at}, a turn made by the curve intake's repair, not by the curve as given (it has no corner there): a "
        f"fault of the repair, which could not bend the curve smoothly{local} ({repaired.text()}). Move that end "
        "to where the curve meets the surface nearer the normal and away from sharp edges, or split the curve at "
        "a node"
    )


class LocalScaleError(NetworkError):
    """A NetworkError: a curve's end repair needs a finer local scale than
    the edge length given (``_check_local_scales``).  SymFrames' own solves
    at an edge length of its choosing (pipeline.solve_resolved's ladder,
    solve_finer) grade the mesh around that curve instead."""


def _check_local_scales(scales: np.ndarray, h: float, repairs: list, label) -> None:
    """With the edge length given, a curve whose end repair needs a finer
    local scale than h (intake.py) is refused with that scale: the mesh is
    uniform at h and would not follow the bend (the automatic resolution
    refines around it instead)."""
    bad = np.nonzero(scales < (1.0 - 1e-9) * h)[0]
    if len(bad):
        ci = int(bad[np.argmin(scales[bad])])
        ends = "; ".join(b.text() for b in repairs[ci].ends) if ci < len(repairs) else ""
        raise LocalScaleError(
            f"{label(ci)} is too short to bend its oblique end(s) onto the normal at the edge length {h:.4g}: the "
            f"bend turns by more than {MAX_KINK:.0f} degrees over h, and stays within it at {scales[ci]:.3g} "
            f"({scales[ci] / h:.2g} h)" + (f" ({ends})" if ends else "") + f". Use an edge length of at most "
            f"{scales[ci]:.3g}, or leave it automatic (the mesh is then refined around the curve alone)"
        )


def _check_crossings(pn: PreparedNetwork, label, tol):
    """Curves must not intersect themselves or each other (except at nodes).

    tol : distance below which two segments touch.  Segments of one curve
    closer along the curve than 4 tol apart are neighbours, not a
    self-intersection (a segment shorter than tol made segments i and i + 2
    touch).  Near-linear in the number of points (``_near_segments``);
    points closer along the curve than tol / 8 are thinned out first (the
    polyline moves by less than tol / 16), so that a curve sampled far
    finer than tol does not pair every segment with hundreds of its
    neighbours."""
    segs, owner, index = [], [], []
    curve_points = [_thinned(c.points, tol / 8) for c in pn.curves]
    for ci, P in enumerate(curve_points):
        segs.append(np.stack([P[:-1], P[1:]], axis=1))
        owner.append(np.full(len(P) - 1, ci))
        index.append(np.arange(len(P) - 1))
    if not segs:
        return
    S = np.concatenate(segs)
    own = np.concatenate(owner)
    idx = np.concatenate(index)
    nseg = np.array([len(P) - 1 for P in curve_points])
    seg_len = np.linalg.norm(S[:, 1] - S[:, 0], axis=1)
    # arc length along its curve of each segment's ends
    s_end = np.concatenate([np.cumsum(seg_len[own == o]) for o in range(len(pn.curves))])
    s_start = s_end - seg_len
    closed = np.array([c.closed for c in pn.curves])
    node_pts = np.array([nd.position for nd in pn.nodes]) if pn.nodes else np.zeros((0, 3))
    node_tree = cKDTree(node_pts) if len(node_pts) else None
    i, j = _near_segments(S, seg_len, tol)
    same = own[i] == own[j]
    first, second = np.where(idx[i] < idx[j], i, j), np.where(idx[i] < idx[j], j, i)
    gap = np.where(same, s_start[second] - s_end[first], np.inf)
    adjacent = same & ((np.abs(idx[i] - idx[j]) == 1) | (gap < 4 * tol))
    wrap = same & closed[own[i]] & (np.abs(idx[i] - idx[j]) == nseg[own[i]] - 1)
    keep = np.nonzero(~adjacent & ~wrap)[0]
    i, j = i[keep], j[keep]
    for a in range(0, len(i), 1 << 20):  # bounded memory whatever the number of candidates
        ii, jj = i[a:a + (1 << 20)], j[a:a + (1 << 20)]
        d, pt = _segment_distance(S[ii], S[jj])
        bad = np.nonzero(d < tol)[0]
        if len(bad) and node_tree is not None:
            # segments meeting at a shared node are allowed to touch there
            dn, _ = node_tree.query(pt[bad])
            bad = bad[dn >= 10 * tol]
        if len(bad):
            k = bad[0]
            a_, b_ = own[ii[k]], own[jj[k]]
            what = f"{label(a_)} intersects itself" if a_ == b_ else f"{label(a_)} and {label(b_)} cross"
            raise NetworkError(f"{what} near {_fmt(pt[k])} ({d[k]:.3g} apart, closer than {tol:.3g}); curves may "
                               "only meet at their ends, at nodes")


def _thinned(P: np.ndarray, step: float) -> np.ndarray:
    """P without the points that fall in the same arc-length bin of width
    step as the point kept before them (both ends kept)."""
    if len(P) <= 2 or step <= 0:
        return P
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    b = np.floor(s / step)
    keep = np.r_[True, b[1:] != b[:-1]]
    keep[-1] = True
    return P[keep]


def _near_segments(S: np.ndarray, length: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Candidate pairs (i, j), i < j, of segments S ((n, 2, 3)) that may come
    closer than tol: a superset of them, found among pieces of the segments.

    Every segment is cut into pieces no longer than L, and two pieces closer
    than tol have midpoints closer than L + tol.  The search radius so
    follows the local segment length, not the longest one: L is the median
    length (or the mean over 4, so that at most 5 n pieces are made, or
    tol), and a long segment among short ones adds pieces, not a radius
    that pairs every short segment with all its neighbours."""
    n = len(S)
    L = max(float(np.median(length)), float(length.sum()) / (4 * n), tol, 1e-300)
    k = np.maximum(1, np.ceil(length / L)).astype(np.int64)
    seg = np.repeat(np.arange(n), k)
    t = (np.arange(len(seg)) - np.repeat(np.cumsum(k) - k, k) + 0.5) / k[seg]
    mid = S[seg, 0] + t[:, None] * (S[seg, 1] - S[seg, 0])
    pairs = cKDTree(mid).query_pairs(L + tol + 1e-12 * L, output_type="ndarray")
    i, j = seg[pairs[:, 0]], seg[pairs[:, 1]]
    keep = i != j
    code = np.unique(np.minimum(i[keep], j[keep]) * n + np.maximum(i[keep], j[keep]))
    return code // n, code % n


def _segment_distance(A, B):
    """Closest distance between segments A[k] and B[k] ((k, 2, 3) each), and
    the midpoint of the closest pair."""
    return segments_distance(A[:, 0], A[:, 1], B[:, 0], B[:, 1])


def network_feature_size(S: TriSurface, pn: PreparedNetwork) -> float:
    """The smallest length the mesh must resolve: distances between curves
    away from shared nodes, from curves to the boundary away from their ends,
    and the length of curves between nodes (inf for no curve)."""
    _, need = network_needs(S, pn)
    return float(need.min()) if len(need) else float("inf")


def network_needs(S: TriSurface, pn: PreparedNetwork) -> tuple[np.ndarray, np.ndarray]:
    """Points along the network and the local feature size at each (inf
    where nothing is close): network_feature_size is their
    smallest, and mesh/resolution.py grades the mesh by them.  The edge length wanted there is a
    third of it (as the uniform default had for the smallest)."""
    diag = S.bbox_diagonal
    dense = []
    for ci, c in enumerate(pn.curves):
        P = c.points
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        L = float(seg.sum())
        n = max(8, int(np.ceil(L / (0.005 * diag))) + 1)
        s = np.linspace(0.0, 1.0, n)
        cum = np.r_[0.0, np.cumsum(seg)] / L
        X = np.stack([np.interp(s, cum, P[:, k]) for k in range(3)], axis=1)
        need = np.full(n, np.inf)
        if "node" in (pn.start_kind[ci], pn.end_kind[ci]):
            need[:] = L if pn.start_kind[ci] == pn.end_kind[ci] else 2.0 * L
        dense.append([ci, X, s * L, L, need])
    for ci, X, s, L, need in dense:
        to_end = np.full(len(X), np.inf)
        if pn.start_kind[ci] == "boundary":
            to_end = np.minimum(to_end, s)
        if pn.end_kind[ci] == "boundary":
            to_end = np.minimum(to_end, L - s)
        keep = to_end > 0.1 * L
        if np.any(keep):
            # only distances below both bounds count: the query may stop there
            d, _, _ = S.closest_points(X[keep], within=float(np.max(np.minimum(0.5 * to_end[keep], need[keep]))))
            close = d < 0.5 * to_end[keep]
            idx = np.nonzero(keep)[0][close]
            need[idx] = np.minimum(need[idx], d[close])
    node_pts = np.array([nd.position for nd in pn.nodes]).reshape(-1, 3)
    for a in range(len(dense)):
        for b in range(a + 1, len(dense)):
            Xa, Xb = dense[a][1], dense[b][1]
            for (A, B, needA) in ((Xa, Xb, dense[a][4]), (Xb, Xa, dense[b][4])):
                d, _ = cKDTree(B).query(A)
                ok = np.ones(len(A), bool)
                for p in node_pts:
                    ok &= d < 0.5 * np.linalg.norm(A - p, axis=1)
                needA[ok] = np.minimum(needA[ok], d[ok])
    if not dense:
        return np.zeros((0, 3)), np.zeros(0)
    return np.vstack([x[1] for x in dense]), np.concatenate([x[4] for x in dense])
