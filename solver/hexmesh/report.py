"""What a hex-meshing run reports (``HexReport``), and when its mesh counts
as valid: the measures of quality.py filled in (``assess``), the irregular
edges matched against the prescribed curves (``curve_matches``) and the
verdict (``verdict``)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from .quality import (
    boundary_quads,
    cell_sizes,
    edge_valences,
    euler_per_component,
    hausdorff_distance,
    polyline_distance,
    scaled_jacobian,
    segments_distance,
)

VALID = "valid"
DEFECTIVE = "defective"
HAUSDORFF_BAR = 0.01
"""A valid mesh's boundary lies within this share of the bounding-box
diagonal of the input surface."""
HAUSDORFF_WARNED = 0.02
"""Past HAUSDORFF_BAR and up to this, the mesh is valid with a warning
(a secondary measure slightly over its bar); past it, defective."""
SJ_WARNED = 0.3
"""A valid mesh with cells whose scaled Jacobian is below this is valid with
a warning: poor elements for a simulation (and the bar of suggested
networks' meshes, docs/suggest.md)."""
SIZE_SPREAD = 0.2
"""A cell counts as even (HexReport.size_within) when its size is within
this fraction of the cell size."""


@dataclass
class CurveMatch:
    """How the hex mesh follows one prescribed singular curve.

    valence   : the valence the curve asks for (4 - 4 sigma)
    edges     : irregular interior hex edges matched to it
    covered   : fraction of the curve within one cell of those edges
    distance  : largest distance (model units) of those edges from the curve
    """

    curve: int
    name: str
    sigma: float
    valence: int
    edges: int
    covered: float
    distance: float


def _plain(x):
    """numpy scalars and arrays, and dict keys, as plain JSON types."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if hasattr(x, "tolist"):
        return _plain(x.tolist())
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else (1e308 if x > 0 else -1e308)
    return x


@dataclass
class HexReport:
    """Figures of a hex mesh and the verdict on it.

    Attributes
    ----------
    status : str
        'valid' (pure hex, manifold, no inverted cell, the irregular edges
        exactly the prescribed curves, the boundary's topology and position
        right) or 'defective'; ``reason`` says which check failed
    sj_min, sj_mean : float
        Verdict's scaled Jacobian (corner definition) after smoothing;
        ``sj_min_raw`` / ``sj_mean_raw`` before it, ``sj_mean_irregular`` over
        the cells touching an irregular edge
    irregular : dict of int to int
        {valence: count} of the interior edges whose valence is not 4
    curves : list of CurveMatch
        how each prescribed singular curve is followed
    hausdorff : float
        two-sided (sampled) distance between the hex mesh's boundary and the
        input surface; ``hausdorff_relative`` divides it by the bounding-box
        diagonal
    stage_seconds : dict of str to float
        seconds per stage
    sizes : dict
        sizes of the intermediate meshes and systems
    given_moved : float
        the largest distance (model units) from a singular curve as given
        to what the intake made of it (fairing, ends turned onto the
        normal); ``given_least`` names the least covered curve as given
    given_extra, given_distance, given_covered : int, float, float
        the irregular edges against the singular curves as the user gave
        them, before the intake repaired them: how many lie more than a
        cell from every given curve of their valence, the largest distance
        of a matched one, and the least fraction of a given curve within a
        cell of its edges
    size_within : float
        the share of cells whose size (the mean length of their 12 edges)
        is within ``SIZE_SPREAD`` (20 %) of ``cell_size``; ``size_p5`` and
        ``size_p95``: the 5th and 95th percentiles of the cells' sizes, as
        fractions of ``cell_size``.  Under a size field (``finer_near``)
        each cell is measured against the size asked for at its centre.  The
        network's layout may force grading (a cube-sphere's shell cells grow
        outward by the ratio of the surface to the inner cube), so this is
        reported, not a verdict
    finer_near : str
        the size field asked for, in words ('' for one cell size)
    cell_reason : str
        why the cell size is what it is ('given', or what the automatic
        size resolves: the target's cells, the shortest singular curve, two
        close curves)
    notes : list of str
        what the run changed on its way (a smaller automatic cell size where
        the map failed at the first one, and why)
    warnings : list of str
        a valid mesh's secondary measures over their bars, with the figures
        (the boundary 1-2% of the diagonal off the surface; cells with a
        scaled Jacobian below SJ_WARNED): the verdict's middle level, *valid
        with warnings*
    sj_poor, sj_worst_at : int, list of 3 floats
        how many cells have a scaled Jacobian below SJ_WARNED, and the
        centre of the least one
    tet_edge : float
        the mean edge length of the field's tets (cells much finer than
        them lose quality next to the singular curves)
    """

    status: str = DEFECTIVE
    reason: str = ""
    cell_size: float = 0.0
    hexes: int = 0
    vertices: int = 0
    non_hex_cells: int = 0
    inverted: int = 0
    sj_min: float = 0.0
    sj_mean: float = 0.0
    sj_min_raw: float = 0.0
    sj_mean_raw: float = 0.0
    sj_mean_irregular: float = 0.0
    faces_over_two: int = 0
    lost_corners: int = 0
    euler: list = field(default_factory=list)
    euler_expected: list = field(default_factory=list)
    irregular: dict = field(default_factory=dict)
    extra_irregular: int = 0
    curves: list = field(default_factory=list)
    structure_exact: bool = False
    hausdorff: float = 0.0
    hausdorff_relative: float = 0.0
    holonomy_bad_edges: int = 0
    seamless_inverted: int = 0
    map_inverted: int = 0
    rounding_shift: float = 0.0
    stiffening: int = 0
    stage_seconds: dict = field(default_factory=dict)
    sizes: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    cell_reason: str = ""
    sj_poor: int = 0
    sj_worst_at: list = field(default_factory=list)
    tet_edge: float = 0.0
    given_extra: int = 0
    given_distance: float = 0.0
    given_covered: float = 1.0
    given_moved: float = 0.0
    given_least: str = ""
    size_within: float = 0.0
    size_p5: float = 0.0
    size_p95: float = 0.0
    finer_near: str = ""

    @property
    def valid(self) -> bool:
        return self.status == VALID

    def to_dict(self) -> dict:
        """The report as JSON types (numbers, strings, lists, dicts)."""
        return _plain(asdict(self))

    as_dict = to_dict

    @classmethod
    def from_dict(cls, d: dict) -> HexReport:
        """A HexReport from to_dict's output."""
        d = dict(d)
        d["irregular"] = {int(k): int(v) for k, v in d.get("irregular", {}).items()}
        d["curves"] = [CurveMatch(**c) for c in d.get("curves", [])]
        known = set(cls.__dataclass_fields__)
        return cls(**{k: v for k, v in d.items() if k in known})

    def summary(self) -> str:
        lines = [f"hex mesh: {self.status}" + (f" ({self.reason})" if self.reason else "")
                 + (f", with warnings: {'; '.join(self.warnings)}" if self.valid and self.warnings else ""),
                 f"  {self.hexes:,} hexahedra ({self.non_hex_cells} other cells), {self.vertices:,} vertices, "
                 f"cell size {self.cell_size:.4g}" + (f" ({self.cell_reason})" if self.cell_reason else ""),
                 f"  scaled Jacobian (Verdict's, least of the 8 corners): min {self.sj_min:.3f}, mean "
                 f"{self.sj_mean:.3f} (before smoothing "
                 f"{self.sj_min_raw:.3f} / {self.sj_mean_raw:.3f}); cells at irregular edges: mean "
                 f"{self.sj_mean_irregular:.3f}; inverted {self.inverted}",
                 "  irregular interior edges: " + (", ".join(f"{n} of valence {v}" for v, n in
                                                            sorted(self.irregular.items())) or "none")
                 + f"; {'exactly the prescribed curves' if self.structure_exact else 'NOT the prescribed curves'}"
                 + (f" ({self.extra_irregular} elsewhere)" if self.extra_irregular else ""),
                 f"  cell sizes (mean edge length): {100 * self.size_within:.0f}% of the cells within "
                 f"{100 * SIZE_SPREAD:.0f}% of the {'size asked for there' if self.finer_near else 'cell size'}; "
                 f"5-95th percentile {self.size_p5:.2f}-{self.size_p95:.2f} of it"
                 + (f"; finer near {self.finer_near}" if self.finer_near else ""),
                 f"  boundary: Euler characteristic {self.euler} (surface {self.euler_expected}); faces in more "
                 f"than two cells {self.faces_over_two}; Hausdorff distance {self.hausdorff:.3g} "
                 f"({100 * self.hausdorff_relative:.2f}% of the diagonal)",
                 f"  map: holonomy wrong on {self.holonomy_bad_edges} edges; inverted tets seamless "
                 f"{self.seamless_inverted}, integer-grid {self.map_inverted}; rounding moved up to "
                 f"{self.rounding_shift:.2f} cells; stiffening {self.stiffening}",
                 "  seconds: " + ", ".join(f"{k} {v:.2f}" for k, v in self.stage_seconds.items())]
        if self.curves:
            cells = max(self.cell_size, 1e-300)
            lines.insert(4, f"  against the curves as given: {self.given_extra} irregular edges more than a cell away, "
                            f"the others within {self.given_distance:.3g} "
                            f"({self.given_distance / cells:.2f} cells), covering "
                            f"{100 * self.given_covered:.0f}% of each curve or more"
                            + (f" ({self.given_least} least); the intake moved the curves up to "
                               f"{self.given_moved:.3g} ({self.given_moved / cells:.2f} cells) from where they were "
                               "given, to repair them (a chain that zig-zags is faired, not followed)"
                               if self.given_covered < 1.0 else ""))
        lines += [f"  note: {n}" for n in self.notes]
        for c in self.curves:
            if c.covered < 1.0 or c.distance > self.cell_size:
                lines.append(f"  curve {c.curve} {c.name!r}: {c.edges} edges of valence {c.valence}, covers "
                             f"{100 * c.covered:.0f}%, up to {c.distance:.3g} away")
        return "\n".join(lines)


def where(points: np.ndarray) -> str:
    """The centre of some points (k, 3), for a message: '(x, y, z)'."""
    c = points.mean(axis=0)
    return f"({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g})"


def assess(report: HexReport, inp, V: np.ndarray, H: np.ndarray, cell: float, rel: np.ndarray | None = None) -> None:
    """Fill in the report's measures of the hex mesh (V, H) and its verdict.

    Parameters
    ----------
    report : HexReport
        filled in place
    inp : SolvedField
        the field meshed (its surface and network are measured against)
    V, H : (n, 3) float array, (m, 8) int array
        the mesh's vertices and cells
    cell : float
        the cell size: the tolerance of the curves' match
    rel : (m,) float array, optional
        a size field's size per cell over the cell size (sizing.py): each
        cell's size is measured against its own
    """
    sj = scaled_jacobian(V, H)
    report.hexes, report.vertices = len(H), len(V)
    report.inverted = int(np.sum(sj <= 0))
    report.sj_min, report.sj_mean = float(sj.min()), float(sj.mean())
    report.sj_poor = int(np.sum(sj < SJ_WARNED))
    report.sj_worst_at = [float(x) for x in V[H[int(np.argmin(sj))]].mean(axis=0)]
    report.tet_edge = float(inp.mesh.mean_edge_length)
    q, over = boundary_quads(H)
    report.faces_over_two = over
    report.euler = euler_per_component(q)
    report.euler_expected = sorted(int(x) for x in inp.surface.euler_characteristics())
    e, val, onb = edge_valences(H, q)
    irr = (~onb) & (val != 4)
    report.irregular = {int(v): int(n) for v, n in zip(*np.unique(val[irr], return_counts=True))}
    # cells touching an irregular edge
    if irr.any():
        touch = np.isin(H, np.unique(e[irr])).sum(axis=1) >= 2
        report.sj_mean_irregular = float(sj[touch].mean()) if touch.any() else 1.0
    else:
        report.sj_mean_irregular = 1.0
    match_curves(report, inp, V, e[irr], val[irr], cell)
    size = cell_sizes(V, H) / (cell if rel is None else cell * np.asarray(rel, float))
    report.size_within = float(np.mean(np.abs(size - 1.0) <= SIZE_SPREAD))
    report.size_p5, report.size_p95 = (float(x) for x in np.percentile(size, [5, 95]))
    report.hausdorff = hausdorff_distance(inp.surface, V, q)
    report.hausdorff_relative = report.hausdorff / inp.surface.bbox_diagonal
    verdict(report)


def match_curves(report: HexReport, inp, V, E, val, cell: float) -> None:
    """Each irregular interior edge near a singular curve of the right index,
    and every singular curve covered by such edges (within one cell): against
    the curves the field followed (the verdict), and against the curves as
    the user gave them (reported: the intake may have moved them)."""
    net = inp.network
    sing = [(c.points, float(c.sigma), int(net.source[i]), c.name) for i, c in enumerate(net.curves) if c.sigma != 0]
    report.extra_irregular, report.curves = curve_matches(sing, V, E, val, cell)
    report.structure_exact = bool(report.extra_irregular == 0 and all(c.covered >= 1.0 for c in report.curves))
    given = inp.given if inp.given is not None else sing
    extra, matches = curve_matches([g for g in given if g[1] != 0], V, E, val, cell)
    report.given_extra = extra
    report.given_distance = max([c.distance for c in matches if c.edges] + [0.0])
    report.given_covered = min([c.covered for c in matches] + [1.0])
    if matches and report.given_covered < 1.0:
        least = min(matches, key=lambda c: c.covered)
        report.given_least = f"curve {least.curve}" + (f" '{least.name}'" if least.name else "")
    report.given_moved = _moved(given, sing)


def _moved(given: list, prepared: list) -> float:
    """The largest distance from a singular curve as given to the curves
    the intake made of it (the same index as given), sampled at its points
    and segment midpoints; 0 where the network was not repaired."""
    out = 0.0
    for P, sigma, cid, _ in given:
        mine = [Q for Q, _s, c, _ in prepared if c == cid]
        if sigma == 0 or not mine or len(P) < 2:
            continue
        X = np.vstack([P, 0.5 * (P[1:] + P[:-1])])
        out = max(out, float(np.min([polyline_distance(Q, X) for Q in mine], axis=0).max()))
    return out


def curve_matches(curves: list, V, E, val, cell: float) -> tuple[int, list]:
    """Irregular edges E (k, 2) with valences val against singular curves
    [(points, sigma, id, name)]: how many lie more than a cell from every
    curve of their valence, and a CurveMatch per curve."""
    mid = 0.5 * (V[E[:, 0]] + V[E[:, 1]]) if len(E) else np.zeros((0, 3))
    if not curves:
        return len(E), []
    D = np.stack([polyline_distance(P, mid) for P, *_ in curves], axis=1) if len(E) else \
        np.zeros((0, len(curves)))
    want = np.array([int(round(4 - 4 * sigma)) for _, sigma, *_ in curves])
    # the nearest curve of the edge's own valence
    D = np.where(val[:, None] == want[None, :], D, np.inf) if len(E) else D
    near = np.argmin(D, axis=1) if len(E) else np.zeros(0, dtype=np.int64)
    dist = D[np.arange(len(E)), near] if len(E) else np.zeros(0)
    ok = dist <= cell
    out = []
    for j, (P, sigma, cid, name) in enumerate(curves):
        mine = ok & (near == j)
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        n = np.maximum(1, np.ceil(seg / (0.25 * cell)).astype(int))
        S = np.vstack([P[k] + np.linspace(0, 1, n[k], endpoint=False)[:, None] * (P[k + 1] - P[k])
                       for k in range(len(seg))] + [P[-1:]])
        if mine.any():
            # covered by the edges of its valence within a cell of it, also those nearer
            # another curve (at a node, where curves meet, an edge is near all of them)
            Em = E[D[:, j] <= cell]
            d = segments_distance(S, V[Em[:, 0]], V[Em[:, 1]])
            covered, far = float(np.mean(d <= cell)), float(dist[mine].max())
        else:
            covered, far = 0.0, float("inf")
        out.append(CurveMatch(cid, name, sigma, int(want[j]), int(mine.sum()), covered, far))
    return int(np.sum(~ok)), out


def verdict(report: HexReport) -> None:
    """Set the report's status (VALID or DEFECTIVE), its reason and its
    warnings from its figures: a valid mesh is pure hex, has no inverted
    cell, no lost corner and no face in more than two cells, has the
    surface's Euler characteristics, irregular edges exactly on the
    prescribed curves and a boundary within HAUSDORFF_WARNED of the surface
    (past HAUSDORFF_BAR with a warning); cells with a scaled Jacobian below
    SJ_WARNED are a warning."""
    why = []
    if report.non_hex_cells:
        why.append(f"{report.non_hex_cells} cells are not hexahedra")
    if report.inverted:
        why.append(f"{report.inverted} cells are inverted")
    if report.lost_corners:
        why.append(f"{report.lost_corners} cell corners could not be traced (their cells are missing)")
    if report.faces_over_two:
        why.append(f"{report.faces_over_two} faces are shared by more than two cells")
    if report.euler != report.euler_expected:
        why.append(f"the boundary's Euler characteristic is {report.euler}, the surface's {report.euler_expected}")
    if not report.structure_exact:
        why.append("the irregular edges are not exactly the prescribed curves")
    warn = []
    off = f"the boundary is {100 * report.hausdorff_relative:.2f}% of the diagonal off the surface"
    if report.hausdorff_relative > HAUSDORFF_WARNED:
        why.append(off)
    elif report.hausdorff_relative > HAUSDORFF_BAR:
        warn.append(f"{off} (the bar is {100 * HAUSDORFF_BAR:g}%; up to {100 * HAUSDORFF_WARNED:g}% is a warning)")
    if report.sj_poor and not report.inverted:
        x, y, z = report.sj_worst_at
        poor = (f"{report.sj_poor} cells have a scaled Jacobian below {SJ_WARNED:g} (the least {report.sj_min:.2f}, "
                f"at ({x:.4g}, {y:.4g}, {z:.4g}))")
        if report.cell_size < 0.75 * report.tet_edge:
            # the ball's field on 53k tets (bench/RESULTS.md): least cell 0.73
            # at ~3,000 cells, 0.52 at ~100,000, 0.29-0.41 at ~900,000
            poor += (f"; cells much finer than the field's tets (cell {report.cell_size:.3g}, tet edges "
                     f"{report.tet_edge:.3g} on average) lose quality next to the singular curves: a larger cell "
                     "size gives better ones")
        warn.append(poor)
    report.status = DEFECTIVE if why else VALID
    report.reason = "; ".join(why)
    report.warnings = warn
