"""The polycube structure of a labelled surface: charts, the chart boundaries
between corners (chains) and the corners where three charts meet."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..errors import NetworkError
from ..surface.trisurface import TriSurface
from ..surface.validation import _fmt
from .labels import DIRECTIONS, LABEL_NAMES, charts_of


@dataclass
class Chain:
    """A chart boundary between two corners: surface vertices in order."""

    charts: tuple  # (chart a, chart b)
    vertices: np.ndarray  # surface vertex ids, first and last are corners
    sharp: bool = False  # lies on the input's sharp creases
    convex: bool = True  # the polycube edge is convex (the solid turns away)
    padded: bool = False  # a padding curve runs under it (build.py)


@dataclass
class Corner:
    """A surface vertex where three charts meet."""

    vertex: int
    charts: tuple
    chains: list = field(default_factory=list)  # chain ids


@dataclass
class ChartGraph:
    """Charts (face -> chart, chart -> label), chains and corners."""

    chart: np.ndarray
    chart_label: np.ndarray
    chains: list
    corners: list

    @property
    def n_charts(self) -> int:
        return len(self.chart_label)


def _where(S: TriSurface, faces) -> str:
    """A point of the faces: the centroid of the one nearest their mean."""
    C = S.V[S.F[np.asarray(faces)]].mean(axis=1)
    return _fmt(C[np.argmin(np.linalg.norm(C - C.mean(axis=0), axis=1))])


def chart_graph(S: TriSurface, labels: np.ndarray, sharp: np.ndarray, R: np.ndarray) -> ChartGraph:
    """Charts, chains and corners of the labelling, refused (NetworkError,
    naming where) when it is no polycube: a vertex where four or more
    charts meet, opposite labels side by side, a
    chart boundary with no corner."""
    n, chart = charts_of(S, labels)
    chart_label = np.zeros(n, int)
    chart_label[chart] = labels
    # a chart need not be a disk: the top of a square ring is an annulus; the
    # network is judged by check_input (Poincare-Hopf per patch) instead
    ef = S.edge_faces
    ca, cb = chart[ef[:, 0]], chart[ef[:, 1]]
    bnd = np.nonzero(ca != cb)[0]
    opp = bnd[(chart_label[ca[bnd]] ^ 1) == chart_label[cb[bnd]]]
    if len(opp):
        e = S.edges[opp[0]]
        raise NetworkError(
            f"no network suggested: charts of opposite labels {LABEL_NAMES[chart_label[ca[opp[0]]]]} and "
            f"{LABEL_NAMES[chart_label[cb[opp[0]]]]} touch at {_fmt(S.V[e].mean(axis=0))}, which no polycube has "
            "(the part is too thin there for its turn); draw the network by hand (docs/suggest.md)"
        )
    # charts around each vertex
    vc = np.unique(np.c_[S.F.reshape(-1), np.repeat(chart, 3)], axis=0)
    count = np.bincount(vc[:, 0], minlength=len(S.V))
    many = np.nonzero(count > 3)[0]
    if len(many):
        v = int(many[0])
        raise NetworkError(
            f"no network suggested: {count[v]} charts meet at the surface point {_fmt(S.V[v])}, where a polycube "
            "corner joins three; draw the network by hand there (docs/suggest.md)"
        )
    corner_v = np.nonzero(count == 3)[0]
    corners = {int(v): Corner(int(v), tuple(vc[vc[:, 0] == v, 1])) for v in corner_v}
    chains = _walk_chains(S, bnd, ca, cb, corners)
    for k, ch in enumerate(chains):
        for end in (ch.vertices[0], ch.vertices[-1]):
            corners[int(end)].chains.append(k)
        m = S.edge_index(ch.vertices[:-1], ch.vertices[1:])
        ch.sharp = bool(np.mean(sharp[m]) > 0.5)
        ch.convex = _convex(S, ch, chart, chart_label, R)
    return ChartGraph(chart, chart_label, chains, list(corners.values()))


def _walk_chains(S: TriSurface, bnd, ca, cb, corners: dict) -> list:
    """Split the chart boundary edges into chains between corners."""
    E = S.edges
    big = int(max(ca.max(), cb.max())) + 1
    key = np.minimum(ca[bnd], cb[bnd]) * big + np.maximum(ca[bnd], cb[bnd])
    nbr = defaultdict(list)  # (vertex, key) -> [(other vertex, edge)]
    for e, k in zip(bnd, key):
        a, b = E[e]
        nbr[(int(a), int(k))].append((int(b), int(e)))
        nbr[(int(b), int(k))].append((int(a), int(e)))
    used = set()
    chains = []
    for (v, k), lst in list(nbr.items()):
        if v not in corners:
            continue
        for w, e in lst:
            if e in used:
                continue
            path = [v, w]
            used.add(e)
            while path[-1] not in corners:
                nxt = [(x, f) for x, f in nbr[(path[-1], k)] if f not in used]
                if not nxt:
                    break
                x, f = nxt[0]
                used.add(f)
                path.append(x)
            if path[-1] not in corners:
                continue
            pair = (int(ca[e]), int(cb[e]))
            chains.append(Chain(tuple(sorted(pair)), np.array(path)))
    left = [e for e in bnd if int(e) not in used]
    if left:
        e = left[0]
        raise NetworkError(
            f"no network suggested: the chart boundary through {_fmt(S.V[E[e]].mean(axis=0))} has no corner (one "
            "chart surrounds another), which no polycube has; draw the network by hand (docs/suggest.md)"
        )
    return chains


def _convex(S: TriSurface, ch: Chain, chart: np.ndarray, chart_label: np.ndarray, R: np.ndarray) -> bool:
    """Whether the polycube edge of the chain is convex: the faces of each
    chart within a third of the chain's chord of it lie below the plane of
    the other chart's label through their nearest chain point (robust to
    noise: a sum over a neighbourhood, not the dihedral angles)."""
    P = S.V[ch.vertices]
    r = max(float(np.linalg.norm(P[0] - P[-1])) / 3.0, 1e-12)
    C = S.V[S.F].mean(axis=1)
    tree = cKDTree(P)
    total = 0.0
    for this, other in ((ch.charts[0], ch.charts[1]), (ch.charts[1], ch.charts[0])):
        f = np.nonzero(chart == this)[0]
        d, i = tree.query(C[f], distance_upper_bound=r)
        ok = np.isfinite(d)
        if not np.any(ok):
            continue
        n = label_direction(R, int(chart_label[other]))
        total += float(np.mean((C[f[ok]] - P[i[ok]]) @ n))
    return total <= 0


def label_direction(R: np.ndarray, label: int) -> np.ndarray:
    """The outward direction of a label in world coordinates."""
    return R.T @ DIRECTIONS[label]
