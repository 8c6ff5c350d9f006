"""Suggest a singularity network for a solid that has none (docs/suggest.md).

``suggest_network(V, F)`` labels the boundary as a polycube (+-X, +-Y, +-Z
per triangle in a frame aligned to the solid), keeps the chart boundaries
on sharp creases as sharp edges and pads the ones across smooth regions:
singular curves of index +-1/4 under them, nodes under the corners where
three of them meet, radial curves from there out to the surface.  It
returns the network, which ``check_input`` accepts, and a report of what it
chose; where no network can be suggested it raises ``NetworkError`` saying
why and where.

The steps: the frame and the per-triangle labels (labels.py), the charts,
their boundaries and corners (charts.py), and the curves and nodes built
from them (build.py).  A solid of revolution about an axis outside it (a
torus, a washer, a pipe) takes the polycube in the frame that turns with
it instead: bands around the axis, closed loops and no node (ring.py).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import NetworkError, TopologyError
from ..network.network import Network
from ..surface.features import sharp_edges_by_angle
from ..surface.validation import validate_surface
from .build import SuggestedCurve, padding_network
from .charts import chart_graph
from .labels import LABEL_NAMES, align_frame, face_adjacency, label_faces, label_scores, merge_small_charts
from .ring import axial_network, ring_network

__all__ = ["SuggestReport", "SuggestedCurve", "suggest_network"]


@dataclass
class SuggestReport:
    """What ``suggest_network`` chose and why.

    Attributes
    ----------
    frame : (3, 3) array
        Rows: the polycube's X, Y, Z axes in world coordinates.
    labels : (#F,) int array
        The polycube label of each input triangle, 0..5 for +X, -X, +Y,
        -Y, +Z, -Z.
    charts : int
        Number of charts (connected regions of one label).
    chart_boundaries : int
        Chart boundaries between corners; ``sharp_boundaries`` of them on
        the input's sharp creases (no curve), the others padded.
    sharp_boundaries : int
    corners : int
        Polycube corners (surface points where three charts meet);
        ``nodes`` of them have three smooth boundaries and became nodes.
    nodes : int
    depth : float
        The padding depth: how far under the surface the padding curves run.
    curves : list of SuggestedCurve
        One per curve of the network, in its order.
    notes : list of str
        What was simplified or adjusted (small charts merged, depth lowered).
    feature_size : float
        The smallest length the suggested network asks the mesh to
        resolve (check_input's; 0 when not checked).
    target_tets : int or None
        A tet budget whose edge length resolves that length (a third of it
        or finer, within the default ceiling of 60,000), for the network's
        solve; None when the default budget does (or not checked).  The
        command line uses it for a bare surface unless --target-tets or
        --edge-length is given.
    seconds : float
    route : str
        How the network was made: ``'padded polycube'``, ``'ring'`` (a
        solid of revolution about an axis outside it: the polycube in the
        frame that turns with it), ``'creases'`` (the sharp creases alone)
        or ``'axial'`` (a solid of revolution the axis passes through, where
        the padded polycube failed: the O-grid of its cross-sections).
    """

    frame: np.ndarray
    labels: np.ndarray
    charts: int = 0
    chart_boundaries: int = 0
    sharp_boundaries: int = 0
    corners: int = 0
    nodes: int = 0
    depth: float = 0.0
    curves: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    feature_size: float = 0.0
    target_tets: int | None = None
    seconds: float = 0.0
    route: str = "padded polycube"

    def summary(self) -> str:
        """A few lines for a person: charts, curves by kind and index, notes."""
        n_pos = sum(1 for c in self.curves if c.sigma > 0)
        n_neg = sum(1 for c in self.curves if c.sigma < 0)
        kinds = {}
        for c in self.curves:
            kinds[c.kind] = kinds.get(c.kind, 0) + 1
        lines = [
            f"suggested network ({self.route}): {len(self.curves)} curves "
            f"({', '.join(f'{v} {k}' for k, v in sorted(kinds.items())) or 'none'}; {n_pos} of index +1/4, "
            f"{n_neg} of -1/4), {self.nodes} nodes",
            f"  polycube: {self.charts} charts, {self.chart_boundaries} chart boundaries ({self.sharp_boundaries} on "
            f"sharp creases, kept as sharp edges), {self.corners} corners; padding depth {self.depth:.4g}",
        ]
        if self.target_tets:
            lines.append(f"  its shortest feature, {self.feature_size:.3g}, asks for a tet budget of "
                         f"{self.target_tets:,}")
        lines += [f"  note: {n}" for n in self.notes]
        lines.append(f"  {self.seconds:.2f} s")
        return "\n".join(lines)


def suggest_network(V, F, sharp_angle: float = 30.0, depth: float | None = None, smoothing: float | None = None,
                    check: bool = True, target_tets: int = 15000,
                    position: float | None = None, proportioned: bool = False) -> tuple[Network, SuggestReport]:
    """Suggest a singularity network for the closed surface (V, F).

    Parameters
    ----------
    V, F : (n, 3) float, (m, 3) int arrays
        A closed, oriented triangle surface (as ``solve`` takes).
    sharp_angle : float
        Edges whose faces' normals differ by more than this many degrees
        are sharp creases; the network carries it as its ``sharp_angle``.
    depth : float or None
        How far under the surface the padding curves run (None: about a
        third of the typical chart boundary's length, lowered where the
        solid is thin).
    smoothing : float or None
        Length over which the labels are made compact (None: 1/10 of the
        bounding box diagonal).
    position : float
        Weight of the box projection against the normals in the labels
        (``label_faces``): 0 labels by the normals alone (None: 0.4, added
        to the normals' scores; 1.0, blended, with ``proportioned``).
    proportioned : bool
        Experimental (docs/suggest.md, *Proportions*): blend the box
        projection into the labels of smooth patches (corners where a box's
        would be), keep any two nodes at least as far apart as the padding
        that parts them, and straighten a curve that leaves a node towards
        its surface corner.  It makes the flat ellipsoid's and the torus's
        networks better proportioned, but in the bench it meshed worse, so
        it is off by default.
    check : bool
        Run ``check_input`` on the suggestion, so that a network it would
        refuse is refused here, as the suggestion's failure (after up to
        two shallower paddings), and fill in the report's feature size and
        tet budget.
    target_tets : int
        The tet budget the check measures the curves at (the solve's
        default).

    Returns
    -------
    (Network, SuggestReport)

    Raises
    ------
    NetworkError
        No network can be suggested: the message says why and where.
    SurfaceError
        The surface is not a closed manifold (as ``solve`` would say).
    """
    t0 = time.perf_counter()
    S = validate_surface(V, F)
    if S.n_components != 1:
        raise NetworkError(f"no network suggested: the surface has {S.n_components} connected components (a "
                           "solid with cavities), and the polycube route takes one; draw the network by hand "
                           "(docs/suggest.md)")
    notes = []
    sharp, dropped = sharp_creases(S, sharp_angle)
    if dropped:
        notes.append(f"{dropped} sharp edges in short isolated groups (noise, not creases) left smooth")
    found = _revolved(ring_network, "ring", V, F, S, sharp, dropped, notes, sharp_angle, depth, check, target_tets)
    if found is not None:
        found[1].seconds = time.perf_counter() - t0
        return found
    R = align_frame(S)
    try:
        net, rep = _padded_polycube(V, F, S, R, sharp, dropped, notes, sharp_angle, depth, smoothing, check,
                                    target_tets, position, proportioned)
    except NetworkError as refusal:
        # the polycube route failed; where the creases alone make a valid
        # network (a bar twisted by 90 degrees or more: its side faces' normals
        # turn through a quarter turn, so no one label fits a side), take it
        found = _crease_network(V, F, S, R, sharp, dropped, sharp_angle, target_tets) if check else None
        if found is not None:
            net, rep = found
            rep.route = "creases"
            rep.notes = notes + [f"the padded polycube failed ({str(refusal)[:200]}); every patch between the "
                                 "sharp creases is a disk and the creases' corners satisfy Poincare-Hopf, so the "
                                 "network needs no curve"] + rep.notes
        else:
            # a solid of revolution the axis passes through (a stepped shaft):
            # the O-grid of its cross-sections along the axis
            found = _revolved(axial_network, "axial", V, F, S, sharp, dropped, notes, sharp_angle, depth, check,
                              target_tets)
            if found is None:
                raise
            net, rep = found
            rep.notes = [f"the padded polycube failed ({str(refusal)[:200]})"] + rep.notes
    rep.seconds = time.perf_counter() - t0
    return net, rep


def _padded_polycube(V, F, S, R, sharp, dropped, notes, sharp_angle, depth, smoothing, check, target_tets,
                     position, proportioned) -> tuple[Network, SuggestReport]:
    """The padded polycube network of suggest_network (docs/suggest.md, steps
    2-6), or NetworkError."""
    notes = list(notes)
    diag = S.bbox_diagonal
    if position is None:
        position = 1.0 if proportioned else 0.4
    lab = label_faces(S, R, sharp, 0.1 * diag if smoothing is None else float(smoothing), position,
                      blend=proportioned)
    merged = merge_small_charts(S, lab, 2e-3 * S.face_areas.sum())
    if np.any(merged != lab):
        notes.append(f"{int(np.sum(merged != lab))} triangles of small or misplaced charts relabelled")
    inner = in_chart_creases(S, merged, sharp)
    if np.any(inner):
        f0, f1 = S.edge_faces[inner].T
        turn = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", S.face_normals[f0], S.face_normals[f1]), -1, 1)))
        notes.append(f"{int(inner.sum())} crease edges inside one chart ({turn.min():.0f}-{turn.max():.0f} degrees) "
                     "left smooth: the polycube does not turn there, and no cross field is adapted to two normals "
                     "so far from a multiple of 90 degrees apart; the hex cells will cut the crease")
        sharp = sharp & ~inner
    G = chart_graph(S, merged, sharp, R)
    kw = dict(sharp_angle=sharp_angle)
    if dropped or np.any(inner):
        kw = dict(sharp_edges=S.edges[sharp])
        angle = separating_angle(S, sharp)
        if angle is not None:
            kw = dict(sharp_angle=angle)
            notes.append(f"sharp angle {angle:.4g} degrees (not {sharp_angle:.4g}): it keeps exactly the creases "
                         "kept")
    tries = 3 if depth is None and check else 1
    for attempt in range(tries):
        curves, info, delta, more = padding_network(S, R, G, depth, proportioned)
        net = Network(curves=curves, **kw)
        rep = SuggestReport(R, merged, G.n_charts, len(G.chains), sum(ch.sharp for ch in G.chains),
                            len(G.corners), sum(1 for c in info if c.kind == "radial"), delta, info, notes + more)
        if not check:
            break
        from ..network.validation import check_input

        try:
            ci = check_input(V, F, net, target_tets=target_tets)
            rep.feature_size = float(ci.feature_size) if np.isfinite(ci.feature_size) else 0.0
            rep.target_tets = resolving_budget(S, ci.feature_size, target_tets)
            break
        except (NetworkError, TopologyError) as e:
            if attempt + 1 < tries and curves:
                notes.append(f"padding at depth {delta:.3g} refused by the input check ({str(e)[:160]}...); "
                             "tried shallower")
                depth = 0.7 * delta
                continue
            raise NetworkError(f"the suggested network is not valid ({e}); this is a limit of the suggestion, not "
                               "of the input: draw the network by hand (docs/suggest.md)") from None
    return net, rep


def _revolved(route, name, V, F, S, sharp, dropped, notes, sharp_angle, depth, check, target_tets):
    """A route of ring.py (``ring_network``: a solid of revolution about an
    axis outside it; ``axial_network``: one the axis passes through) where it
    applies and check_input accepts its curves (tried at up to three depths,
    each 0.7 x shallower), else None."""
    from ..network.validation import check_input

    for _ in range(3 if depth is None and check else 1):
        found = route(S, sharp, depth)
        if found is None:
            return None
        curves, info, frame, labels, delta, more, (bands, sharp_bands) = found
        kw = dict(sharp_edges=S.edges[sharp]) if dropped else dict(sharp_angle=sharp_angle)
        net = Network(curves=curves, **kw)
        # bands around the axis, their boundaries circles (a ring's as many as its bands)
        boundaries = bands if name == "ring" else bands - 1
        rep = SuggestReport(frame, labels, bands, boundaries, sharp_bands, 0, 0, delta,
                            [SuggestedCurve(name_, sigma, "axial" if charts == "axis" else "padding", charts, length)
                             for name_, sigma, charts, length in info], list(notes) + more, route=name)
        if not check:
            return net, rep
        try:
            ci = check_input(V, F, net, target_tets=target_tets)
        except (NetworkError, TopologyError):
            if not curves or delta <= 0:
                return None
            depth = 0.7 * delta
            continue
        rep.feature_size = float(ci.feature_size) if np.isfinite(ci.feature_size) else 0.0
        rep.target_tets = resolving_budget(S, ci.feature_size, target_tets)
        return net, rep
    return None


def _crease_network(V, F, S, R, sharp, dropped, sharp_angle, target_tets) -> tuple[Network, SuggestReport] | None:
    """The network with no curve, where the sharp creases bound every patch
    as a disk (Euler characteristic 1: one boundary loop, no handle) and
    ``check_input`` accepts it (Poincare-Hopf with the creases' corners on
    every patch): each patch then maps to one face of a grid, as a box's
    faces do.  None where they do not.  A smooth patch that is not a disk
    (a sphere, a torus, a cylinder's wall) needs curves: a cross field with
    no singularity exists on a smooth torus, but its boundary has no corner
    for an integer-grid map's planes."""
    from ..network.validation import check_input

    if not np.any(sharp):
        return None
    n, comp = connected_components(face_adjacency(S, ~sharp), directed=False)
    f0, f1 = S.edge_faces.T
    c0, c1 = comp[f0], comp[f1]
    edges = np.bincount(c0, minlength=n) + np.bincount(c1[c1 != c0], minlength=n)
    pv = np.unique(np.c_[np.repeat(comp, 3), S.F.ravel()], axis=0)
    euler = np.bincount(pv[:, 0], minlength=n) - edges + np.bincount(comp, minlength=n)
    if np.any(euler != 1):
        return None
    net = Network(curves=[], **(dict(sharp_edges=S.edges[sharp]) if dropped else dict(sharp_angle=sharp_angle)))
    try:
        ci = check_input(V, F, net, target_tets=target_tets)
    except (NetworkError, TopologyError):
        return None
    # one label per patch, the one its area-weighted normal scores best (for the report and pictures)
    D = S.face_normals @ R.T
    score = np.zeros((n, 6))
    np.add.at(score, comp, label_scores(D) * S.face_areas[:, None])
    labels = np.argmax(score, axis=1)[comp]
    pairs = len(np.unique(np.sort(np.c_[c0, c1][c0 != c1], axis=1), axis=0))
    deg = np.bincount(S.edges[sharp].ravel(), minlength=len(S.V))
    rep = SuggestReport(R, labels, n, pairs, pairs, int(np.sum(deg >= 3)), 0, 0.0, [], [])
    rep.feature_size = float(ci.feature_size) if np.isfinite(ci.feature_size) else 0.0
    return net, rep


def resolving_budget(S, feature_size: float, target_tets: int = 15000, per_feature: float = 3.2,
                     ceiling: int = 60000) -> int | None:
    """The tet budget at which the solid's edge length (intake.solid_scale)
    is feature_size / per_feature, within [target_tets, ceiling]; None when
    target_tets already gets there.  Edge length goes as budget^(-1/3)."""
    from ..network.intake import solid_scale

    if not np.isfinite(feature_size) or feature_size <= 0:
        return None
    h = solid_scale(S, target_tets)
    need = target_tets * (per_feature * h / feature_size) ** 3
    if need <= target_tets:
        return None
    return int(min(ceiling, np.ceil(need / 1000.0) * 1000))


def sharp_creases(S, sharp_angle: float, min_length: float = 0.05) -> tuple[np.ndarray, int]:
    """The edges sharper than sharp_angle, less those in connected groups
    shorter in all than min_length times the bounding box diagonal (noise
    on a sculpted surface, not creases): (mask, number dropped)."""
    sharp = sharp_edges_by_angle(S, sharp_angle)
    if not np.any(sharp):
        return sharp, 0
    E = S.edges[sharp]
    n = len(S.V)
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
    _, comp = connected_components(A, directed=False)
    length = np.linalg.norm(S.V[E[:, 1]] - S.V[E[:, 0]], axis=1)
    total = np.bincount(comp[E[:, 0]], length, comp.max() + 1)
    short = total[comp[E[:, 0]]] < min_length * S.bbox_diagonal
    idx = np.nonzero(sharp)[0]
    sharp = sharp.copy()
    sharp[idx[short]] = False
    return sharp, int(short.sum())


def in_chart_creases(S, labels, sharp, tolerance: float = 20.0) -> np.ndarray:
    """The sharp edges between two faces of one label whose normals turn by
    more than ``tolerance`` degrees (a crease inside a chart: the 47-degree
    bend of the prism example's wall).  A cross field adapted to the
    boundary aligns an axis with the normal on each side of a sharp edge,
    which two normals that far from parallel (and under 90 degrees apart,
    as one label implies) do not allow."""
    f0, f1 = S.edge_faces.T
    c = np.einsum("ij,ij->i", S.face_normals[f0], S.face_normals[f1])
    return sharp & (labels[f0] == labels[f1]) & (c < np.cos(np.radians(tolerance)))


def separating_angle(S, sharp) -> float | None:
    """A sharp angle (degrees) that marks exactly the edges of ``sharp``:
    halfway between the sharpest edge left out and the bluntest one kept,
    or None when no angle does (an edge left out is sharper than one kept)
    or none is kept."""
    turn = np.degrees(S.dihedral_angles)
    if not np.any(sharp) or np.all(sharp):
        return None
    lo, hi = turn[~sharp].max(), turn[sharp].min()
    if not lo < hi:
        return None
    angle = float(0.5 * (lo + hi))
    return angle if np.array_equal(sharp_edges_by_angle(S, angle), sharp) else None


def label_name(label: int) -> str:
    """'+X', '-X', ... for a label 0..5."""
    return LABEL_NAMES[int(label)]
