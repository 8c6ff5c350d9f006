"""From a polycube chart graph to SymFrames curves (the padding network).

A chart boundary on sharp creases stays a sharp edge (no curve).  A chart
boundary across a smooth region becomes a singular curve under the surface:
the polycube shrunk by a depth ``delta`` (each face moved in by delta along
its label) puts the boundary between charts of directions d_a, d_b at
``p - delta (d_a + d_b)``, index +1/4 under a convex polycube edge and -1/4
under a concave one.  A corner where three smooth boundaries meet becomes a
node at ``p - delta (d_a + d_b + d_c)`` with a radial curve out to the
surface corner p: index +1/4 where the three charts turn the same way
(all convex or all concave: a 90-degree angle in each chart), -1/4 where
one chart has a 270-degree angle.  A smooth boundary ending at a corner
whose two other boundaries are sharp runs on, along its own direction, to
the third chart's surface (the cylinder's O-grid).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import NetworkError
from ..network.network import Curve
from ..surface.trisurface import TriSurface
from ..surface.validation import _fmt
from .charts import ChartGraph, label_direction
from .labels import LABEL_NAMES


@dataclass
class SuggestedCurve:
    """What one suggested curve stands for."""

    name: str
    sigma: float
    kind: str  # 'padding' (under a chart boundary), 'radial' (node to a surface corner)
    charts: str  # the labels it lies between, e.g. '+X|+Y'
    length: float


def ray_hit(S: TriSurface, origin: np.ndarray, direction: np.ndarray) -> np.ndarray | None:
    """The first point where the ray origin + t direction (t > 0) meets the
    surface (Moller-Trumbore over all triangles), or None."""
    T = S.V[S.F]
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - T[:, 0]
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ direction) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9) & (t > 1e-12)
    if not np.any(hit):
        return None
    return origin + float(t[hit].min()) * direction


def _resample(P: np.ndarray, n: int) -> np.ndarray:
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    if s[-1] <= 0:
        return np.repeat(P[:1], n, axis=0)
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, P[:, k]) for k in range(3)], axis=1)


def _smooth(P: np.ndarray, iterations: int) -> np.ndarray:
    """Laplacian smoothing with both ends held."""
    P = P.copy()
    for _ in range(iterations):
        P[1:-1] = 0.5 * P[1:-1] + 0.25 * (P[:-2] + P[2:])
    return P


def _blend_ends(P: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Move P's ends to a and b, spreading the moves linearly along it."""
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    s = s / s[-1] if s[-1] > 0 else np.linspace(0, 1, len(P))
    return P + (1 - s)[:, None] * (a - P[0]) + s[:, None] * (b - P[-1])


def _leave_angle(P: np.ndarray, out_a: np.ndarray, out_b: np.ndarray) -> float:
    """The smallest angle (degrees) between the directions in which P leaves
    its ends (to the points within its first and last fifth) and the
    directions out_a, out_b from those ends to their surface corners."""
    m = max(2, len(P) // 5)
    worst = 180.0
    for Q, out in ((P[1:m + 1] - P[0], out_a), (P[-m - 1:-1] - P[-1], out_b)):
        n = np.maximum(np.linalg.norm(Q, axis=1) * np.linalg.norm(out), 1e-300)
        worst = min(worst, float(np.degrees(np.arccos(np.clip(Q @ out / n, -1, 1))).min()))
    return worst


def _unbow(P: np.ndarray, out_a: np.ndarray, out_b: np.ndarray, min_angle: float = 60.0) -> np.ndarray:
    """A curve between two nodes that leaves a node towards that node's
    surface corner (less than min_angle off its radial curve: the chain
    along a flat solid's rounded rim bows out with the rim, and left its
    node along the radial), with its bow off the chord scaled down until
    it does not (a polycube edge leaves its corner at 125 degrees from the
    diagonal).  A curve that follows a convex arc leaves at about 90
    degrees less the tilt of its ends (70 to 95 on a sphere or a torus)
    and is left as it is; the flat ellipsoid's rim curves left at 29."""
    if len(P) < 3 or _leave_angle(P, out_a, out_b) >= min_angle:
        return P
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    s = s / s[-1] if s[-1] > 0 else np.linspace(0, 1, len(P))
    line = P[0] + s[:, None] * (P[-1] - P[0])
    lo, hi = 0.0, 1.0
    for _ in range(20):
        mid = 0.5 * (lo + hi)
        if _leave_angle(line + mid * (P - line), out_a, out_b) >= min_angle:
            lo = mid
        else:
            hi = mid
    return line + lo * (P - line)


@dataclass
class _Plan:
    smooth_at: dict  # corner vertex -> number of smooth chains there
    third: dict  # (chain id, corner vertex) -> label of the corner's chart off the chain


def _plan(S: TriSurface, G: ChartGraph) -> _Plan:
    """Pad the smooth chains; count them at each corner; refuse a corner
    where two smooth chains meet a sharp one.  (Padding both faces of the
    sharp one leaves a regular edge under it, valence 4 with the block
    between the two pads; the node under the corner would then join two
    +1/4 curves, that regular edge and a radial of valence 2, which no hex
    mesh has.)"""
    for ch in G.chains:
        ch.padded = not ch.sharp
    smooth_at, third = {}, {}
    for cn in G.corners:
        if len(cn.chains) != 3:
            raise NetworkError(
                f"no network suggested: the polycube corner at {_fmt(S.V[cn.vertex])} joins {len(cn.chains)} chart "
                "boundaries, not 3; draw the network near it by hand (docs/suggest.md)"
            )
        smooth_at[cn.vertex] = sum(G.chains[k].padded for k in cn.chains)
        if smooth_at[cn.vertex] == 2:
            raise NetworkError(
                f"no network suggested: at the surface point {_fmt(S.V[cn.vertex])} two smooth chart boundaries meet "
                "a sharp crease (a crease running out into a fillet), a corner the padded polycube does not handle "
                "(its node would need an edge of valence 2); draw the network near it by hand (docs/suggest.md)"
            )
        for k in cn.chains:
            off = [c for c in cn.charts if c not in G.chains[k].charts]
            third[(k, cn.vertex)] = int(G.chart_label[off[0]]) if off else -1
    return _Plan(smooth_at, third)


def _inward(R, G: ChartGraph, charts, dc: np.ndarray) -> np.ndarray:
    """The shrunk polycube's move of a point on the given charts: each chart
    c moved in by its depth dc[c] along its label."""
    return -sum(dc[c] * label_direction(R, int(G.chart_label[c])) for c in charts)


def chart_depths(S: TriSurface, R: np.ndarray, G: ChartGraph, plan, delta: float,
                 core: float = 0.0) -> np.ndarray:
    """A padding depth per chart: delta, lowered so that every smooth chart
    boundary between two nodes keeps at least half its length once the
    charts at its ends are moved in (a thin polycube gets thin padding),
    and (core > 0) so that any two nodes stay at least ``core`` times the padding that
    parts them apart (the deepest chart of one node and not the other: the
    core between them is then no thinner than that padding; the inner and
    outer nodes of a ring's thin tube share no chain)."""
    dc = np.full(G.n_charts, float(delta))
    cons = []
    for _k, ch in enumerate(G.chains):
        a, b = int(ch.vertices[0]), int(ch.vertices[-1])
        if not ch.padded or plan.smooth_at.get(a) != 3 or plan.smooth_at.get(b) != 3:
            continue
        ends = []
        for v in (a, b):
            cn = next(c for c in G.corners if c.vertex == v)
            ends += [c for c in cn.charts if c not in ch.charts]
        cons.append((ends, 0.5 * float(np.linalg.norm(S.V[a] - S.V[b]))))
    nodes = [cn for cn in G.corners if plan.smooth_at.get(cn.vertex) == 3]
    dirs = np.array([label_direction(R, int(lab)) for lab in G.chart_label]).reshape(-1, 3)
    pairs = []
    for i in range(len(nodes) if core > 0 else 0):
        for j in range(i + 1, len(nodes)):
            apart = sorted(set(nodes[i].charts) ^ set(nodes[j].charts))
            if apart:
                pairs.append((S.V[nodes[i].vertex] - S.V[nodes[j].vertex], list(nodes[i].charts),
                              list(nodes[j].charts), apart))
    for _ in range(60 if pairs else 20):
        changed = False
        for ends, room in cons:
            tot = dc[ends].sum()
            if tot > room * (1 + 1e-9):
                dc[ends] *= room / tot
                changed = True
        for gap, ci, cj, apart in pairs:
            # the nodes p - sum dc d over their charts, and their distance
            d = gap - dc[ci] @ dirs[ci] + dc[cj] @ dirs[cj]
            pad = dc[apart].max()
            if np.linalg.norm(d) < core * pad * (1 - 1e-6):
                dc[apart] *= 0.95
                changed = True
        if not changed:
            break
    return dc


def _offsets_ok(S: TriSurface, G: ChartGraph, polys: list, nodes: dict, dc: np.ndarray) -> bool:
    """Every padding point inside the solid, at least 0.7 delta from the
    surface (but near an end that runs on to the surface) and from the
    other padding curves (but near a shared node)."""
    keep, owner, own_depth = [], [], []
    delta = float(dc.min())
    for i, (k, P) in enumerate(polys):
        ch = G.chains[k]
        own_depth.append(float(dc[list(ch.charts)].min()))
        m = np.ones(len(P), bool)
        for v in (int(ch.vertices[0]), int(ch.vertices[-1])):
            if v not in nodes:
                m &= np.linalg.norm(P - S.V[v], axis=1) > 2.0 * delta
        keep.append(P[m])
        owner.append(np.full(int(m.sum()), i))
    X = np.vstack(keep + [np.array(list(nodes.values())).reshape(-1, 3)])
    if len(X):
        d, _, _ = S.closest_points(X)
        if not (np.all(d >= 0.7 * delta) and np.all(S.winding_number(X) > 0.5)):
            return False
    own = np.concatenate(owner) if owner else np.zeros(0, int)
    Y = np.vstack(keep) if keep else np.zeros((0, 3))
    if len(Y) < 2:
        return True
    depth = np.array(own_depth)[own]
    i, j = cKDTree(Y).query_pairs(0.7 * float(depth.max()), output_type="ndarray").T
    # two curves closer than 0.7 times the shallower one's depth
    other = (own[i] != own[j]) & (np.linalg.norm(Y[i] - Y[j], axis=1) < 0.7 * np.minimum(depth[i], depth[j]))
    if nodes and np.any(other):
        N = np.array(list(nodes.values()))
        near = cKDTree(N).query(Y[i[other]])[0] < 1.5 * delta
        return bool(np.all(near))
    return not np.any(other)


def _geometry(S, R, G, plan, dc, proportioned=False):
    """The padding curves' points at the chart depths dc: (chain id, points),
    nodes."""
    nodes = {}
    for cn in G.corners:
        if plan.smooth_at[cn.vertex] == 3:
            nodes[cn.vertex] = S.V[cn.vertex] + _inward(R, G, cn.charts, dc)
    polys = []
    for k, ch in enumerate(G.chains):
        if not ch.padded:
            continue
        P = S.V[ch.vertices] + _inward(R, G, ch.charts, dc)
        delta = float(dc[list(ch.charts)].min())
        L = float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())
        P = _smooth(_resample(_resample(P, 96), 96), 200)
        # enough points between two nodes that no vertex turns much: a chain
        # along a rounded rim (a flat solid's) bows, and 8 points made a kink
        t = np.diff(P, axis=0)
        t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
        turn = float(np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", t[:-1], t[1:]), -1, 1))).sum())
        n = int(np.clip(np.ceil(3 * L / delta), 8, 48))
        if proportioned and int(ch.vertices[0]) in nodes and int(ch.vertices[-1]) in nodes:
            n = int(max(n, min(96, np.ceil(turn / 6.0) + 2)))
        P = _resample(P, n)
        ends = []
        for v, Q in ((ch.vertices[0], P[0]), (ch.vertices[-1], P[-1])):
            ends.append(nodes[int(v)] if int(v) in nodes else Q)
        P = _blend_ends(P, ends[0], ends[1])
        a, b = int(ch.vertices[0]), int(ch.vertices[-1])
        if proportioned and a in nodes and b in nodes:
            P = _unbow(P, S.V[a] - nodes[a], S.V[b] - nodes[b])
        polys.append((k, P))
    return nodes, polys


def _extend(S, R, G, plan, k, P):
    """Run a padding curve whose corner is not a node on to the surface,
    along the direction of the corner's third chart (or against it, where
    that points back along the curve)."""
    ch = G.chains[k]
    for end in (0, -1):
        v = int(ch.vertices[end])
        if v in plan.smooth_at and plan.smooth_at[v] == 3:
            continue
        lab = plan.third[(k, v)]
        d = label_direction(R, lab)
        q = P[end]
        # on, away from the curve: under a concave corner (a boss's foot) the
        # third chart faces back along the curve
        if len(P) > 1 and np.dot(q - P[1 if end == 0 else -2], d) < 0:
            d = -d
        hit = ray_hit(S, q - 0.5 * np.linalg.norm(q - S.V[v]) * d, d)
        if hit is None:
            raise NetworkError(f"no network suggested: the padding curve under the {_charts(G, ch)} boundary finds "
                               f"no surface beyond {_fmt(q)}; draw the network there by hand (docs/suggest.md)")
        seg = np.linalg.norm(hit - q)
        inner = P[1:] if end == 0 else P[:-1]
        step = np.linalg.norm(np.diff(P, axis=0), axis=1).mean()
        if seg > 0.5 * step:
            m = int(np.ceil(seg / step))
            extra = q + np.linspace(0, 1, m + 1)[1:, None] * (hit - q)
            P = np.vstack([extra[::-1], P]) if end == 0 else np.vstack([P, extra])
        else:
            P = np.vstack([hit, inner]) if end == 0 else np.vstack([inner, hit])
    return P


def _charts(G: ChartGraph, ch) -> str:
    return "|".join(LABEL_NAMES[int(G.chart_label[c])] for c in ch.charts)


def padding_network(S: TriSurface, R: np.ndarray, G: ChartGraph, depth: float | None = None,
                    proportioned: bool = False):
    """The padding curves of the chart graph: (curves, descriptions, depth,
    notes).  depth: the padding depth (None: a third of the median distance
    between the ends of the smooth chart boundaries, lowered until every
    curve point is at least 0.7 depth from the surface).  proportioned:
    also keep any two nodes at least the padding that parts them apart,
    and straighten a curve that leaves a node towards its surface corner
    (docs/suggest.md)."""
    plan = _plan(S, G)
    smooth = [ch for ch in G.chains if ch.padded]
    notes = []
    if not smooth:
        return [], [], 0.0, ["every chart boundary lies on a sharp crease: no padding curve"]
    chords = [np.linalg.norm(S.V[ch.vertices[0]] - S.V[ch.vertices[-1]]) for ch in smooth]
    delta = float(depth) if depth is not None else 0.35 * float(np.median(chords))
    for _ in range(12):
        dc = chart_depths(S, R, G, plan, delta, core=1.0 if proportioned else 0.0)
        nodes, polys = _geometry(S, R, G, plan, dc, proportioned)
        if depth is not None or _offsets_ok(S, G, polys, nodes, dc):
            break
        delta *= 0.8
        notes.append(f"padding depth lowered to {delta:.3g}: a curve came within 0.7 depth of the surface or of "
                     "another curve")
    else:
        raise NetworkError("no network suggested: no padding depth keeps the curves inside the solid and away from "
                           "its surface (the solid is too thin for its chart layout); draw the network by hand "
                           "(docs/suggest.md)")
    curves, info = [], []
    for k, P in polys:
        ch = G.chains[k]
        P = _extend(S, R, G, plan, k, P)
        sigma = 0.25 if ch.convex else -0.25
        name = f"pad {_charts(G, ch)} #{k}"
        curves.append(Curve(P, sigma=sigma, name=name))
        info.append(SuggestedCurve(name, sigma, "padding", _charts(G, ch),
                                   float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum())))
    for cn in G.corners:
        if cn.vertex not in nodes:
            continue
        conv = [G.chains[k].convex for k in cn.chains]
        sigma = 0.25 if all(conv) or not any(conv) else -0.25
        a, b = nodes[cn.vertex], S.V[cn.vertex]
        n = max(4, int(np.ceil(3 * np.linalg.norm(b - a) / dc[list(cn.charts)].min())))
        P = a + np.linspace(0, 1, n + 1)[:, None] * (b - a)
        labs = "|".join(LABEL_NAMES[int(G.chart_label[c])] for c in cn.charts)
        name = f"radial {labs} @{cn.vertex}"
        curves.append(Curve(P, sigma=sigma, name=name))
        info.append(SuggestedCurve(name, sigma, "radial", labs, float(np.linalg.norm(b - a))))
    if dc.min() < delta * (1 - 1e-9):
        notes.append(f"padding depth {dc.min():.3g} to {dc.max():.3g} by chart: lowered where a chart boundary "
                     "between two nodes is short")
    return curves, info, float(dc.min()), notes
