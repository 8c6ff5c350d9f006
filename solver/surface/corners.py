"""Quantising sharp corners (§3.3, Fig. 11): rounding, ambiguity, user choice.

features.FeatureGraph reads the sharp edges as the skeleton of an
axis-aligned surface: every sector between consecutive sharp edges at a
vertex gets k quarter turns (k >= 1, its angle rounded to a multiple of 90
degrees) and the vertex gets the index ``1 - sum(k) / 4``.  We call
``turn = 4 - sum(k)`` the corner's *turn in quarter turns*: 0 for a smooth
vertex (an outline going straight on, or a 130-degree corner meant as
smooth), 1 for a cube-like convex corner (index +1/4), -1 for a concave one.

A CAD outline's 130-degree corner is ambiguous (docs/limitations.md, *Sharp
corners that are not multiples of 90°*): rounding
takes it to 90 degrees (a corner), another tool to 180 (smooth).  Here

* a sector is *ambiguous* when its angle is more than ``AMBIGUOUS`` (22.5
  degrees) from every multiple of 90: it could be rounded either way;
* the user fixes a vertex's turn with ``Network.corner_turns`` ({surface
  vertex index or (x, y, z) position: quarter turns}, or the JSON key
  ``corner_turns``); its sectors then get the k closest to their angles
  that sum to ``4 - turn``;
* when Poincare-Hopf fails on a patch bounded by sharp edges (per patch,
  features.FeatureGraph.check_patches; the per-component check follows),
  the ambiguous sectors of that patch not fixed by the user are rounded the
  other way, cheapest first, the cost of a sector being the growth of its
  rounding error |angle - k 90|, until the patch's sum matches: the choice
  with the smallest total rounding (per patch the sectors are independent,
  so taking the cheapest is optimal).  Before rounding comes realisability:
  a vertex with two sharp edges must be flat (sum k = 4) and one with three
  a cube corner (3 or 5), or the field needs a singular curve ending there
  that the network does not have (the house prism of examples.py with its
  128-degree corner rounded to 90 between smooth walls: residual quarter
  turns and a penalty of 5e3), so a change that makes a vertex realisable
  goes first and one that makes it unrealisable last;
* a flat corner that still ends a crease (Poincare-Hopf left no other
  choice: a hexagonal prism's 120-degree corners, three of which must be
  flat) makes that crease, where its own dihedral angle is ambiguous, a
  smooth bend of the wall: its edges are no longer sharp and the corners
  are quantised again (``_creases_to_smooth``; a hex mesh puts two cells
  round such a crease);
* what was chosen is reported per corner (``CornerChoice``), and a failure
  names the corners and the amount missing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from ..errors import NetworkError, TopologyError
from .features import FeatureGraph
from .trisurface import TriSurface

AMBIGUOUS = 22.5  # degrees from the nearest multiple of 90


@dataclass
class CornerChoice:
    """One sharp-feature vertex whose quantisation is reported.

    vertex : surface vertex index;  position : (3,)
    sector_deg : angles of its sectors (degrees);  quarters : their k
    turn : 4 - sum(k) (quarter turns);  rounded_turn : the same by plain rounding
    how : 'rounded', 'chosen' (ambiguous, rounded the other way to satisfy
    Poincare-Hopf) or 'fixed' (Network.corner_turns)
    """

    vertex: int
    position: tuple
    sector_deg: tuple
    quarters: tuple
    turn: int
    rounded_turn: int
    how: str
    ambiguous: bool
    smoothed_crease: int = 0  # sharp edges of the crease it ended, treated as smooth (``_creases_to_smooth``)

    def text(self) -> str:
        secs = ", ".join(f"{a:.1f}" for a in self.sector_deg)
        pos = ", ".join(f"{x:.4g}" for x in self.position)
        s = f"vertex {self.vertex} at ({pos}): sectors {secs} deg -> {'/'.join(map(str, self.quarters))} quarter(s), " \
            f"turn {self.turn:+d}/4"
        if self.how == "chosen":
            s += f" (rounding gave {self.rounded_turn:+d}/4; chosen for Poincare-Hopf)"
        elif self.how == "fixed":
            s += " (fixed by corner_turns)"
        elif self.ambiguous:
            s += " (ambiguous)"
        if self.smoothed_crease:
            s += (f"; the crease it ended ({self.smoothed_crease} sharp edges) is treated as smooth, as a flat "
                  "corner needs")
        return s


def corners_text(choices: list[CornerChoice]) -> str:
    shown = [c for c in choices if c.ambiguous or c.how != "rounded"]
    if not shown:
        return ""
    return "\n".join(["sharp corners (ambiguous or chosen):"] + ["  " + c.text() for c in shown])


def _realisable(degree, ksum):
    """Whether a vertex with `degree` sharp edges and sector sum `ksum` is a
    vertex of an axis-aligned (polycube) surface, i.e. needs no singular
    curve inside the solid: two sharp edges bound a flat vertex (sum 4),
    three a convex or concave cube corner (3 or 5); more are left alone."""
    degree, ksum = np.asarray(degree), np.asarray(ksum)
    return ((degree == 2) & (ksum == 4)) | ((degree == 3) & ((ksum == 3) | (ksum == 5))) | (degree >= 4)


def _rounding_cost(theta, k):
    return np.abs(theta - k * (np.pi / 2))


def _nearest_quarters(G: FeatureGraph):
    """Per sector of G: its vertex, angle, nearest quarter count k0 >= 1,
    whether its vertex is on a sharp feature, and the rounding error in
    degrees."""
    sv, theta = G.sector_vertex, G.sector_angle
    q = np.round(theta / (np.pi / 2))
    return sv, theta, np.maximum(1, q).astype(int), G.degree[sv] > 0, np.degrees(np.abs(theta - q * (np.pi / 2)))


def _distribute(theta: np.ndarray, k: np.ndarray, total: int) -> np.ndarray:
    """k (>= 1) closest to the angles theta (in rounding error) summing to total."""
    k = k.copy()
    while k.sum() < total:
        c = _rounding_cost(theta, k + 1) - _rounding_cost(theta, k)
        k[np.argmin(c)] += 1
    while k.sum() > total:
        c = np.where(k > 1, _rounding_cost(theta, k - 1) - _rounding_cost(theta, k), np.inf)
        k[np.argmin(c)] -= 1
    return k


def user_corner_vertices(S: TriSurface, G: FeatureGraph, corner_turns) -> dict:
    """{vertex: turn} from Network.corner_turns (keys: vertex index or a
    position, matched to the nearest sharp-feature vertex)."""
    out = {}
    if not corner_turns:
        return out
    feat = np.nonzero(G.degree > 0)[0]
    tree = cKDTree(S.V[feat]) if len(feat) else None
    for key, q in dict(corner_turns).items():
        if np.ndim(key) == 0:
            v = int(key)
            if not 0 <= v < len(S.V) or G.degree[v] == 0:
                raise NetworkError(f"corner_turns: vertex {v} is not a vertex of a sharp edge of the surface")
        else:
            x = np.asarray(key, float).reshape(3)
            if tree is None:
                raise NetworkError("corner_turns given but the surface has no sharp edges")
            d, j = tree.query(x)
            if d > 1e-2 * S.bbox_diagonal:
                raise NetworkError(f"corner_turns: no sharp-feature vertex near ({x[0]:.4g}, {x[1]:.4g}, "
                                   f"{x[2]:.4g}) (the nearest is {d:.3g} away)")
            v = int(feat[j])
        if float(q) != int(round(float(q))):
            raise NetworkError(f"corner_turns: vertex {v}: the turn must be a whole number of quarter turns, got {q}")
        out[v] = int(round(float(q)))
    return out


def resolve_corners(S: TriSurface, G: FeatureGraph, face_sigma: np.ndarray, corner_turns=None):
    """Quantise every sharp sector (module docstring).  Returns (FeatureGraph
    with the chosen ``quarters``, list of CornerChoice).  Raises
    TopologyError naming the corners when no choice satisfies Poincare-Hopf.

    Where the choice leaves flat corners that end a crease (three sharp
    edges, sectors summing to four quarters: unrealisable), the ambiguous
    crease each ends is treated as smooth (``_creases_to_smooth``) and the
    corners are quantised again without it; kept where that leaves fewer
    unrealisable vertices."""
    G2, choices = _resolve(S, G, face_sigma, corner_turns)
    drop = _creases_to_smooth(G2)
    if drop is None:
        return G2, choices
    G3, again = _resolve(S, FeatureGraph(S, G.sharp & ~drop), face_sigma, corner_turns)
    if _unrealisable(G3) >= _unrealisable(G2):
        return G2, choices
    E = S.edges[drop]
    ends = np.nonzero(np.bincount(E.reshape(-1), minlength=len(S.V)) == 1)[0]  # each crease's two ends
    count = _crease_sizes(E, len(S.V))
    for c in again:
        if c.vertex in ends:
            c.smoothed_crease = int(count.get(c.vertex, 0))
    return G3, again


def check_realisable(G: FeatureGraph, ends: np.ndarray, radius: float, choices: list[CornerChoice]) -> None:
    """Refuse, before any meshing, a sharp corner no field can follow without
    a singular curve ending there that the network does not have
    (``_realisable``): two sharp edges meeting with a turn (a corner between
    smoothly joined walls), or three with none (a flat corner ending a
    crease that is not ambiguous).  LM would end at its iteration cap (the
    house prism with sharp_angle 55-80: 50 iterations, penalty 5e3).  A
    curve end (``ends``, (k, 3) points on the surface) within ``radius`` of
    the vertex exempts it; so do crease ends (one sharp edge) and vertices
    of four or more.
    The message names each corner, the bend of the smooth edges there, and
    the three fixes."""
    S = G.S
    ksum = np.bincount(G.sector_vertex, weights=G.sector_quarters, minlength=len(S.V)).astype(int)
    bad = (G.degree >= 2) & (G.degree <= 3) & ~_realisable(G.degree, ksum)
    if not bad.any():
        return
    if len(ends):  # a curve ending near the corner may carry its index
        cand = np.nonzero(bad)[0]
        d, _ = cKDTree(np.asarray(ends, float)).query(S.V[cand])
        bad[cand[d <= radius]] = False
    verts = np.nonzero(bad)[0]
    if not len(verts):
        return
    ef, N = S.edge_faces, S.face_normals
    bend = np.degrees(np.arccos(np.clip(np.sum(N[ef[:, 0]] * N[ef[:, 1]], axis=1), -1.0, 1.0)))
    # the largest bend of a smooth edge at each vertex
    smooth_bend = np.zeros(len(S.V))
    soft = ~G.sharp
    for k in range(2):
        np.maximum.at(smooth_bend, S.edges[soft, k], bend[soft])
    by_vertex = {c.vertex: c for c in choices}
    lines = []
    for v in verts[:6]:
        b = float(smooth_bend[v])
        pos = ", ".join(f"{x:.4g}" for x in S.V[v])
        turn = 4 - int(ksum[v])
        c = by_vertex.get(int(v))
        how = " (fixed by corner_turns)" if c is not None and c.how == "fixed" else ""
        if G.degree[v] == 2:
            what = (f"two sharp edges meet at a turn of {turn:+d}/4{how}, and the walls beside them join smoothly "
                    f"(bending by up to {b:.0f} degrees at an edge from there)")
        else:
            what = f"three sharp edges meet with no turn{how} (a flat corner at the end of a crease)"
        lines.append(f"vertex {int(v)} at ({pos}): {what}")
    more = f"; and {len(verts) - 6} more" if len(verts) > 6 else ""
    least = float(smooth_bend[verts].min())
    hint = f"a sharp_angle below {least:.0f} degrees (making the bend a crease), " if least > 1.0 else ""
    raise TopologyError(
        "no field can follow these sharp corners without a singular curve ending at each, which the network does "
        f"not have: {'; '.join(lines)}{more}. Fix with {hint}a singular curve ending at the corner, or, where "
        "Poincare-Hopf allows another choice, corner_turns={vertex: quarter turns} (0 = smooth, 1 = convex)")


def _unrealisable(G: FeatureGraph) -> int:
    """Feature vertices no axis-aligned surface has (``_realisable``)."""
    ksum = np.bincount(G.sector_vertex, weights=G.sector_quarters, minlength=len(G.S.V)).astype(int)
    feat = G.degree > 0
    return int(np.sum(feat & ~_realisable(G.degree, ksum)))


def _crease_sizes(E: np.ndarray, nv: int) -> dict:
    """{end vertex: number of edges} of the chains (paths) of the edges E."""
    A = sp.coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(nv, nv))
    _, lab = csgraph.connected_components(A, directed=False)
    size = np.bincount(lab[E[:, 0]], minlength=lab.max() + 1)
    deg = np.bincount(E.reshape(-1), minlength=nv)
    return {int(v): int(size[lab[v]]) for v in np.nonzero(deg == 1)[0]}


def _creases_to_smooth(G: FeatureGraph) -> np.ndarray | None:
    """Sharp edges to treat as smooth, or None: at each flat corner that ends
    a crease (three sharp edges, sectors summing to 4 quarters: a vertex no
    axis-aligned surface has, which the field could only follow with a
    singular curve ending there), the crease whose two sectors there merge
    into a sector of their summed quarters with the least rounding error
    (within ``AMBIGUOUS``), followed through its flat vertices to its other
    end, where its dihedral angle is ambiguous too (its faces' normals more
    than ``AMBIGUOUS`` from a right angle: a crease a hex mesh may round
    either way).  A triangular prism whose caps' 120-degree corners are
    alternately a corner and flat (a triangle split into three quads,
    meshed so) has such corners: its flat corners' vertical creases are
    then bends of the wall, one cell column round each (issue 48)."""
    S = G.S
    ns, lab = G.sectors
    sv, theta, k = G.sector_vertex, G.sector_angle, G.sector_quarters
    ksum = np.bincount(sv, weights=k, minlength=len(S.V)).astype(int)
    bad = np.nonzero((G.degree == 3) & (ksum == 4))[0]
    if not len(bad):
        return None
    E, ef = S.edges, S.edge_faces
    ids = np.nonzero(G.sharp)[0]
    inc: dict[int, list] = {}
    for e in ids:
        for v in E[e]:
            inc.setdefault(int(v), []).append(int(e))
    N = S.face_normals
    bend = np.degrees(np.arccos(np.clip(np.sum(N[ef[:, 0]] * N[ef[:, 1]], axis=1), -1.0, 1.0)))

    def corner(f, v):
        return 3 * int(f) + int(np.nonzero(S.F[f] == v)[0][0])

    def chain(v, e):
        out, u = [e], int(E[e, 0] if E[e, 1] == v else E[e, 1])
        while G.degree[u] == 2 and u != v:
            nxt = [x for x in inc[u] if x != out[-1]]
            if not nxt or nxt[0] in out:
                break
            out.append(nxt[0])
            u = int(E[nxt[0], 0] if E[nxt[0], 1] == u else E[nxt[0], 1])
        return out, u

    bad_set = set(bad.tolist())
    drop = np.zeros(len(E), bool)
    for v in bad:
        best, best_err = None, np.radians(AMBIGUOUS)
        for e in inc[int(v)]:
            s1, s2 = lab[corner(ef[e, 0], v)], lab[corner(ef[e, 1], v)]
            if s1 == s2 or drop[e]:
                continue
            err = abs(theta[s1] + theta[s2] - (k[s1] + k[s2]) * np.pi / 2)
            c, w = chain(int(v), e)
            # its other end must stay a vertex a field can follow without it
            # (the sectors there merge: same sum, one sharp edge fewer)
            keeps = w in bad_set or w == v or bool(_realisable(G.degree[w] - 1, ksum[w])) or G.degree[w] == 1
            if keeps and err <= best_err and abs(np.mean(bend[c]) - 90.0) > AMBIGUOUS:
                best, best_err = c, err
        if best is not None:
            drop[best] = True
    return drop if drop.any() else None


def _resolve(S: TriSurface, G: FeatureGraph, face_sigma: np.ndarray, corner_turns=None):
    """resolve_corners' quantisation of the sharp sectors of G, as given."""
    if not np.any(G.sharp):
        return G, []
    ns, slab = G.sectors
    sv, theta, k0, feat_sec, err = _nearest_quarters(G)
    ambiguous = feat_sec & (err > AMBIGUOUS)
    k = k0.copy()
    fixed = np.zeros(ns, bool)
    for v, q in user_corner_vertices(S, G, corner_turns).items():
        secs = np.nonzero(sv == v)[0]
        total = 4 - q
        if total < len(secs):
            raise NetworkError(f"corner_turns: vertex {v} has {len(secs)} sectors between sharp edges, so its turn "
                               f"is at most {4 - len(secs)} quarter turn(s); got {q}")
        k[secs] = _distribute(theta[secs], k0[secs], total)
        fixed[secs] = True
    # per patch: the amount missing, in quarter turns
    npch, plab = G.patches
    sec_patch = np.empty(ns, dtype=np.int64)
    sec_patch[slab] = np.repeat(plab, 3)
    chi = _patch_chi(G, npch, plab, sec_patch)
    sing = np.bincount(plab, weights=face_sigma, minlength=npch)
    chosen = np.zeros(ns, bool)
    for p in range(npch):
        in_p = feat_sec & (sec_patch == p)
        missing = chi[p] - sing[p] - np.sum((2 - k[in_p]) / 4.0)  # index the corners must still add
        steps = int(round(4 * missing))
        if steps == 0 or abs(4 * missing - steps) > 1e-6:
            continue
        # raising the turn of the patch's corners by 1/4 = lowering one k by 1
        delta = -1 if steps > 0 else 1
        cand = np.nonzero(in_p & ambiguous & ~fixed & ((k + delta) >= 1))[0]
        cand = cand[np.sign(theta[cand] / (np.pi / 2) - k[cand]) == delta]  # the other rounding only
        if len(cand) < abs(steps):
            continue  # reported below by the checks
        cost = _rounding_cost(theta[cand], k[cand] + delta) - _rounding_cost(theta[cand], k[cand])
        # prefer making vertices realisable (REALISABLE) over rounding: a
        # change that makes one unrealisable costs more than any rounding
        ksum = np.bincount(sv, weights=k, minlength=len(S.V)).astype(int)
        deg = G.degree[sv[cand]]
        before = _realisable(deg, ksum[sv[cand]])
        after = _realisable(deg, ksum[sv[cand]] + delta)
        cost = cost + 2 * np.pi * (before & ~after) - 2 * np.pi * (~before & after)
        pick = cand[np.argsort(cost, kind="stable")[: abs(steps)]]
        k[pick] += delta
        chosen[pick] = True
    G2 = FeatureGraph(G.S, G.sharp, quarters=k)
    choices = []
    show = np.unique(sv[feat_sec & (ambiguous | fixed | chosen)])
    show = np.union1d(show, G2.corners)
    for v in show:
        secs = np.nonzero(sv == v)[0]
        how = "fixed" if fixed[secs].any() else "chosen" if chosen[secs].any() else "rounded"
        choices.append(CornerChoice(int(v), tuple(float(x) for x in S.V[v]), tuple(np.degrees(theta[secs])),
                                    tuple(int(x) for x in k[secs]), int(4 - k[secs].sum()),
                                    int(4 - k0[secs].sum()), how, bool(ambiguous[secs].any())))
    return G2, choices


def _patch_chi(G: FeatureGraph, npch, plab, sec_patch):
    """Euler characteristic of each patch cut open along the sharp edges (as
    in FeatureGraph.check_patches)."""
    S = G.S
    F_P = np.bincount(plab, minlength=npch)
    V_P = np.bincount(sec_patch, minlength=npch)
    ef = S.edge_faces
    E_P = np.bincount(plab[ef[:, 0]], minlength=npch) + np.bincount(plab[ef[G.sharp, 1]], minlength=npch)
    return V_P - E_P + F_P


def explain_failure(S: TriSurface, G: FeatureGraph, choices: list[CornerChoice], err: TopologyError,
                    face_sigma: np.ndarray):
    """Re-raise a Poincare-Hopf failure naming the ambiguous corners, if any,
    and the index missing per boundary component."""
    amb = [c for c in choices if c.ambiguous]
    if not amb:
        raise err
    ncomp, lab = S.face_components
    chi = S.euler_characteristics()
    vcomp = np.full(len(S.V), -1)
    vcomp[S.F.reshape(-1)] = np.repeat(lab, 3)
    have = np.bincount(lab, weights=face_sigma, minlength=ncomp) + np.bincount(
        vcomp[G.corners], weights=G.vertex_index[G.corners], minlength=ncomp)
    miss = chi - have
    missing = ", ".join(f"component {c}: {m * 4:+.0f}/4" for c, m in enumerate(miss) if abs(m) > 1e-6)
    names = "; ".join(c.text() for c in amb[:6]) + (f"; and {len(amb) - 6} more" if len(amb) > 6 else "")
    raise TopologyError(f"{err}. Index missing ({missing or 'per patch only'}; a smooth corner adds -1/4 "
                        f"against a convex one). Ambiguous sharp corners (more than {AMBIGUOUS:g} degrees from a "
                        "multiple of 90): "
                        f"{names}. Fix their turns with corner_turns={{vertex: quarter turns}} (0 = smooth, "
                        "1 = convex corner)") from None


def sector_directions(G: FeatureGraph) -> np.ndarray:
    """(#sectors, 3) unit direction into each sector from its vertex: the
    corner-angle weighted sum of the directions to the face centroids."""
    S = G.S
    ns, slab = G.sectors
    P = S.V[S.F]
    d = P.mean(axis=1)[:, None, :] - P
    d /= np.maximum(np.linalg.norm(d, axis=2, keepdims=True), 1e-300)
    w = S.corner_angles[..., None] * d
    out = np.zeros((ns, 3))
    np.add.at(out, slab, w.reshape(-1, 3))
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)


def transfer_quarters(src: FeatureGraph, dst: FeatureGraph) -> FeatureGraph:
    """The quantisation chosen on the input surface carried onto a remeshed
    boundary (the tet mesh's): at every input vertex whose sectors were
    ambiguous, chosen or fixed, the nearest sharp vertex of dst takes the k
    of the input sector pointing the same way."""
    if src.quarters is None or not np.any(dst.sharp):
        return dst
    ns, _ = src.sectors
    sv, theta, k0, feat_sec, err = _nearest_quarters(src)
    special = np.unique(sv[feat_sec & ((src.quarters != k0) | (err > AMBIGUOUS))])
    if not len(special):
        return dst
    dfeat = np.nonzero(dst.degree > 0)[0]
    _, j = cKDTree(dst.S.V[dfeat]).query(src.S.V[special])
    k = dst.sector_quarters.copy()
    dsv = dst.sector_vertex
    sdir, ddir = sector_directions(src), sector_directions(dst)
    for v, w in zip(special, dfeat[j]):
        a = np.nonzero(sv == v)[0]
        b = np.nonzero(dsv == w)[0]
        if len(a) != len(b):
            continue
        match = np.argmax(ddir[b] @ sdir[a].T, axis=1)
        k[b] = src.quarters[a[match]]
    return FeatureGraph(dst.S, dst.sharp, quarters=k)
