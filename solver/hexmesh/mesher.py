"""Hex meshing, stage by stage: from a solved field to a pure hex mesh.

    curves onto tet edges -> transitions from omega -> seamless map
        -> integer-grid map -> extraction -> smoothing -> quality

``hexmesh(result, cell_size)`` runs it on a solver Result; ``HexInput``
holds what it needs of the field (so a stored field can be meshed without
solving again).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from .. import checks
from ..errors import Cancelled, HexMeshError, OptionsError
from ..mesh.embed import Embedding
from ..mesh.resolution import RAM_FRACTION, physical_memory_mb
from ..mesh.tetmesh import TetMesh
from ..network.network import PreparedNetwork
from ..stages import Stages
from ..surface.trisurface import TriSurface
from .curve_edges import CurveEdgeError, CurveEdgeMesh, curves_on_edges, split_edges
from .extract import ExtractionError, extract_hexes, snap
from .patches import BoundaryPatches, boundary_patches
from .quality import (
    HEX_EDGES,
    HEX_FACES,
    boundary_quads,
    det3,
    edge_valences,
    euler_characteristic,
    hausdorff_distance,
    scaled_jacobian,
)
from .quantize import integer_grid_map, optimise_map, seamless_map
from .report import DEFECTIVE, VALID, CurveMatch, HexReport
from .seamless import MapError, build_map_system, degenerate_tets
from .smooth import BoundaryMotion, optimise
from .source import HexInput, field_fault
from .transitions import build_transitions

SHARP_DIHEDRAL = 30.0
SPRING = 0.1
"""Weight of the spring holding singular-curve vertices during smoothing
(per cell of displacement, against the mean corner energy): at 1.0 the
ball's cells at its nodes kept a minimum scaled Jacobian of 0.54, at 0.1
0.72, with the irregular edges still within a cell of their curves."""
DEFAULT_HEXES = 3000
MAX_HEXES = 2_000_000
HEX_BASE_MB = 50.0
HEX_KB_PER_CELL = 4.1
HEX_KB_PER_TET = 5.0
"""The hex stages' memory above the field's: ``HEX_KB_PER_CELL`` per cell
(extraction and smoothing; bench/bench_hex_memory.py on the cube's field:
83 MB at 19.7k cells, 396 MB at 97k, 1,202 MB at 301k) plus
``HEX_KB_PER_TET`` per tet of the field (the seamless map; the ball's field
of 51.8k tets, split to 55.7k: 251 MB at 2,432 cells), plus ``HEX_BASE_MB``.
A cell size whose estimate passes ``RAM_FRACTION`` of the machine's memory
is refused before any hex work."""


@dataclass
class HexMesh:
    """A hexahedral mesh.

    Attributes
    ----------
    vertices : (n, 3) float array
    hexes : (m, 8) int array
        VTK_HEXAHEDRON corner order: corners (0,0,0), (1,0,0), (1,1,0),
        (0,1,0) of the cell's parameter cube, then the same at z = 1
    scaled_jacobian : (m,) float array
        Verdict's scaled Jacobian per cell (the minimum over its corners)
    report : HexReport
    irregular_edges : (k, 2) int array
        vertex pairs of the interior edges whose valence is not 4
    irregular_valence : (k,) int array
        their valences
    grid_map : tuple or None
        (tet vertices (n, 3), tets (t, 4), parameters (t, 4, 3)): the
        integer-grid map the hexes were extracted from (written as .hexex)
    patches : patches.BoundaryPatches or None
        the boundary quads, each with its cell, local face and the input
        surface's patch (its regions between sharp edges), which the
        simulation formats write as groups (.msh physical groups, .inp
        surfaces and sets, MEDIT refs); None where the surface is unknown
    """

    vertices: np.ndarray
    hexes: np.ndarray
    scaled_jacobian: np.ndarray
    report: HexReport
    irregular_edges: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    irregular_valence: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    grid_map: tuple | None = None
    patches: BoundaryPatches | None = None

    def boundary_quads(self) -> np.ndarray:
        """The boundary faces.

        Returns
        -------
        (k, 4) int array
            faces held by one cell, oriented outward
        """
        return boundary_quads(self.hexes)[0]

    def transformed(self, matrix) -> HexMesh:
        """The mesh moved by a 4 x 4 affine matrix (a Blender object's
        ``matrix_world``): its vertices (and its map's tet vertices) mapped,
        the scaled Jacobian measured again (a non-uniform scale changes it).
        A mirror (negative determinant) reorders each cell's corners so that
        none is inside out; its integer-grid map is then dropped (a map
        cannot be mirrored with its parameters kept).

        Parameters
        ----------
        matrix : (4, 4) array-like

        Returns
        -------
        HexMesh

        Raises
        ------
        OptionsError
            a matrix that is not 4 x 4 and finite, or whose 3 x 3 part is
            singular
        """
        M = checks.array("matrix", matrix, OptionsError, shape=(4, 4))
        A, t = M[:3, :3], M[:3, 3]
        det = float(np.linalg.det(A))
        if not abs(det) > 1e-12 * max(float(np.abs(A).max()) ** 3, 1e-300):
            raise OptionsError(f"matrix: its 3 x 3 part is singular (determinant {det:.3g}): it would flatten the "
                               "hex mesh")
        V = self.vertices @ A.T + t
        H, P, gm = self.hexes, self.patches, self.grid_map
        if det < 0:
            H = H[:, MIRROR_CORNERS]
            gm = None
            if P is not None:
                P = replace(P, quads=P.quads[:, ::-1], faces=MIRROR_FACES[P.faces])
        elif gm is not None:
            gm = (gm[0] @ A.T + t, gm[1], gm[2])
        return replace(self, vertices=V, hexes=H, scaled_jacobian=scaled_jacobian(V, H), grid_map=gm, patches=P)


MIRROR_CORNERS = np.array([0, 3, 2, 1, 4, 7, 6, 5])
"""A VTK hexahedron's corners with its first two parameter axes swapped:
the cell the right way out again after a mirror."""
MIRROR_FACES = np.array([[j for j in range(6) if set(HEX_FACES[j]) == set(MIRROR_CORNERS[HEX_FACES[k]])][0]
                         for k in range(6)])
"""The local face (of quality.HEX_FACES) of a mirrored cell that each face
of the original lands on."""

STAGE_WEIGHTS = {"curves onto edges": 0.03, "transitions": 0.15, "seamless map": 0.15, "integer-grid map": 0.1,
                 "extraction": 0.07, "smoothing": 0.4, "quality": 0.1}
"""Share of a typical hex-meshing run each stage takes (the progress bar)."""


# ------------------------------------------------------------ cell size


def _curve_lengths(net) -> np.ndarray:
    return np.array([float(np.sum(np.linalg.norm(np.diff(c.points, axis=0), axis=1))) for c in net.curves])


def default_cell_size(inp: HexInput, target_hexes: int = DEFAULT_HEXES) -> float:
    """The automatic cell size.

    Parameters
    ----------
    inp : HexInput
    target_hexes : int
        the number of cells aimed at

    Returns
    -------
    float
        a cell size for about target_hexes hexahedra, finer where the
        network needs it (``cell_choice``): at least 1.5 cells along its
        shortest singular curve and between two singular curves that share
        no node (so that the rounding keeps them one cell long, and apart)
    """
    inp = _hex_input(inp, "default_cell_size")
    target_hexes = checks.integer("target_hexes", target_hexes, OptionsError, low=1, high=MAX_HEXES,
                                  fix=f"the number of cells aimed at (default {DEFAULT_HEXES})")
    return cell_choice(inp, target_hexes)[0]


CELL_FLOOR = 8.0
"""The network's needs make at most this many times the target's cells."""


def cell_choice(inp: HexInput, target_hexes: int = DEFAULT_HEXES) -> tuple[float, str]:
    """``default_cell_size`` and why: (cell size, the reason in words)."""
    vol = float(np.sum(inp.mesh.tet_volumes))
    cell = (vol / target_hexes) ** (1.0 / 3.0)
    why = f"about {target_hexes:,} cells"
    net = inp.network
    sing = [i for i, c in enumerate(net.curves) if c.sigma != 0]
    if not sing:
        return cell, why
    L = _curve_lengths(net)
    k = min(sing, key=lambda i: L[i])
    if L[k] / 1.5 < cell:
        cell, why = float(L[k]) / 1.5, f"1.5 cells along the shortest singular curve, {_name(net, k)} ({L[k]:.3g} long)"
    gap, pair = _closest_apart(net, sing, cell)
    if gap / 1.5 < cell:
        cell, why = gap / 1.5, (f"1.5 cells between {_name(net, pair[0])} and {_name(net, pair[1])}, "
                                f"{gap:.3g} apart")
    floor = (vol / (CELL_FLOOR * target_hexes)) ** (1.0 / 3.0)
    if cell < floor:
        cell, why = floor, why + f"; held at {CELL_FLOOR:g}x the {target_hexes:,} cells aimed at"
    return cell, why


def _name(net, i: int) -> str:
    c = net.curves[i]
    return f"curve {net.source[i]}" + (f" '{c.name}'" if c.name else "")


def _closest_apart(net, sing: list, cell: float) -> tuple[float, tuple]:
    """The least distance between two singular curves that share no node
    (sampled at a quarter cell), and the pair."""
    nodes = {}
    for n, nd in enumerate(net.nodes):
        for ci, _ in nd.ends:
            nodes.setdefault(ci, set()).add(n)
    samples = []
    for i in sing:
        P = net.curves[i].points
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
        m = np.maximum(1, np.ceil(seg / (0.25 * cell)).astype(int))
        t = np.concatenate([np.arange(q) / q for q in m] + [[1.0]])
        j = np.r_[np.repeat(np.arange(len(seg)), m), len(seg) - 1]
        samples.append(P[j] + t[:, None] * np.diff(P, axis=0)[j])
    best, pair = np.inf, (-1, -1)
    trees = [cKDTree(X) for X in samples]
    for a in range(len(sing)):
        for b in range(a + 1, len(sing)):
            if nodes.get(sing[a], set()) & nodes.get(sing[b], set()):
                continue
            d, _ = trees[b].query(samples[a], distance_upper_bound=min(best, 1.5 * cell))
            if np.isfinite(d).any() and d.min() < best:
                best, pair = float(d.min()), (sing[a], sing[b])
    return best, pair


def _cells(volume: float, cell: float) -> tuple[float, str]:
    """About how many cells of this size the volume holds, and that in words
    (in powers of ten past 10^12, where cell**3 may underflow)."""
    log = np.log10(volume) - 3 * np.log10(cell)
    return (10.0**log if log < 300 else np.inf), (f"{10.0**log:,.0f}" if log < 12 else f"10^{log:.0f}")


def solid_size(inp: HexInput) -> tuple[float, float]:
    """(the solid's smallest axis extent, its volume) from the field's tet mesh."""
    return float(np.ptp(inp.mesh.vertices, axis=0).min()), float(np.sum(inp.mesh.tet_volumes))


def check_cell_size(cell: float, extent: float, volume: float, subject: str | None = None,
                    fix: str = "", error=None) -> None:
    """Refuse a cell size that does not fit the solid.

    Parameters
    ----------
    cell : float
        a positive cell size
    extent, volume : float
        the solid's smallest axis extent and its volume (``solid_size``, or
        the surface's before any tet mesh exists)
    subject : str, optional
        the cell size and whose it is, opening the message (default
        "cell size 0.1 (the one given)"; "--cell-size 0.1" on the command
        line, the automatic one with its reason)
    fix : str
        what else to change, ending the message
    error : callable(message) -> exception, optional
        default: a HexMeshError of kind 'settings'

    Raises
    ------
    HexMeshError (or what ``error`` makes)
        a cell of at least half the smallest extent (less than two cells
        across), or more than MAX_HEXES cells
    """
    fail = error or (lambda msg: HexMeshError(msg, kind="settings"))
    subject = subject or f"cell size {cell:.4g} (the one given)"
    if cell >= 0.5 * extent:
        raise fail(f"{subject} is larger than half the solid's smallest extent ({extent:.4g}): "
                   f"the solid would be less than two cells thick; choose a cell size below {0.25 * extent:.4g}{fix}")
    n, words = _cells(volume, cell)
    if n > MAX_HEXES:
        raise fail(f"{subject} would make about {words} hexahedra (the limit is {MAX_HEXES:,}); "
                   f"choose a cell size of at least {(volume / MAX_HEXES) ** (1 / 3):.4g}{fix}")


def _check_cell(inp: HexInput, cell: float, why: str = "given") -> None:
    if why == "given":
        check_cell_size(cell, *solid_size(inp))
    else:
        check_cell_size(cell, *solid_size(inp), subject=f"the automatic cell size {cell:.4g} (for {why})",
                        fix="; give a cell size (cell_size, --cell-size) instead")
    refusal = memory_refusal(inp, cell)
    if refusal:
        raise HexMeshError(refusal, kind="settings")


def hex_memory_mb(cells: float, tets: int) -> float:
    """Estimated memory (MB) the hex stages need above the field's, for
    about ``cells`` cells on a field of ``tets`` tets (``HEX_KB_PER_CELL``)."""
    return HEX_BASE_MB + (HEX_KB_PER_CELL * cells + HEX_KB_PER_TET * tets) / 1024.0


def hex_estimate(inp: HexInput, cell: float) -> tuple[float, float]:
    """(about how many cells, estimated MB of the hex stages) at a cell size."""
    n = _cell_count(inp, cell)
    return n, hex_memory_mb(n, inp.mesh.n_tets)


def _gb(mb: float) -> str:
    return f"{mb / 1024:.1f} GB" if mb < 10240 else f"{mb / 1024:,.0f} GB"


def memory_refusal(inp: HexInput, cell: float) -> str | None:
    """The message refusing a hex run at this cell size for its memory
    estimate, or None when it fits in ``RAM_FRACTION`` of this machine's
    memory."""
    n, mb = hex_estimate(inp, cell)
    ram = physical_memory_mb()
    if np.isfinite(mb) and mb <= RAM_FRACTION * ram:
        return None
    fits = (RAM_FRACTION * ram - hex_memory_mb(0, inp.mesh.n_tets)) * 1024.0 / HEX_KB_PER_CELL
    vol = float(np.sum(inp.mesh.tet_volumes))
    head = (f"cell size {cell:.4g} would make about {n:,.0f} hexahedra, and the hex stages would need ~{_gb(mb)} of "
            f"memory ({HEX_KB_PER_CELL:g} KB per cell, {HEX_KB_PER_TET:g} KB per tet of the field's "
            f"{inp.mesh.n_tets:,}), past {RAM_FRACTION:.0%} of this machine's {_gb(ram)}")
    if fits < 1000:
        return (f"{head}; the field's tets alone take most of it: mesh a coarser field (a larger edge length), or "
                "on a machine with more memory")
    return (f"{head}; choose a cell size of at least {(vol / fits) ** (1 / 3):.4g} (about {fits:,.0f} cells), or "
            "mesh on a machine with more memory")


def check_indices(curves, sources=None, error=None) -> None:
    """Refuse a network no hex mesh can have, from the network alone: a
    curve of index sigma becomes hex edges of valence 4 - 4 sigma, and
    valence 2 or less means cells meeting flat, which no valid hex mesh has.

    Parameters
    ----------
    curves : list of network.Curve
        the network's curves (a Network's or a PreparedNetwork's)
    sources : list of int, optional
        the number of each curve as the user gave it (default: its position)
    error : callable(message) -> exception, optional
        default: a HexMeshError of kind 'network'

    Raises
    ------
    HexMeshError (or what ``error`` makes)
        naming the first curve of index +1/2 or more
    """
    fail = error or (lambda msg: HexMeshError(msg, kind="network"))
    for i, c in enumerate(curves):
        if float(c.sigma) >= 0.5:
            name = f" '{c.name}'" if c.name else ""
            raise fail(f"curve {i if sources is None else sources[i]}{name} has index {float(c.sigma):+g}: its hex "
                       f"edges would have valence {int(round(4 - 4 * float(c.sigma)))}, cells meeting flat, which "
                       "no valid hex mesh has; use curves of index +1/4 (valence 3) or negative indices (valence 5, "
                       "6, ...)")


def _check_indices(inp: HexInput) -> None:
    check_indices(inp.network.curves, inp.network.source)


# ------------------------------------------------------------ the stages


def _split_choice(cem: CurveEdgeMesh, tets: np.ndarray) -> np.ndarray:
    """One edge per structurally flat tet whose midpoint frees it: between two
    constrained vertices (boundary or curve), not a curve edge nor a sharp
    boundary edge; interior edges first, then the longest."""
    mesh = cem.mesh
    X = mesh.vertices
    constrained = mesh.is_boundary_vertex.copy()
    chain_keys = set()
    for ch in cem.chains:
        constrained[ch.vertices] = True
        for a, b in ch.edges.tolist():
            chain_keys.add((min(a, b), max(a, b)))
    B = mesh.boundary
    sharp_local = B.edges[np.degrees(B.dihedral_angles) > SHARP_DIHEDRAL]
    sharp = {tuple(sorted(e)) for e in mesh.boundary_vertices[sharp_local].tolist()}
    onb = mesh.is_boundary_edge
    out = set()
    for t in tets.tolist():
        T = mesh.tets[t]
        cands = []
        for i in range(4):
            for j in range(i + 1, 4):
                a, b = sorted((int(T[i]), int(T[j])))
                if (a, b) in chain_keys or (a, b) in sharp:
                    continue
                e = int(mesh.edge_index(np.array([a]), np.array([b]))[0])
                both = constrained[a] and constrained[b]
                cands.append((not both, bool(onb[e]), -float(np.linalg.norm(X[a] - X[b])), (a, b)))
        if cands:
            out.add(min(cands)[3])
    return np.array(sorted(out), dtype=np.int64).reshape(-1, 2)


def _map_system(cem: CurveEdgeMesh, inp: HexInput, cell: float, report: HexReport, max_rounds: int = 6):
    """Transitions and the map system, splitting edges until no tet is flat
    whatever the map (degenerate_tets); refuses transitions that do not
    close as the network prescribes."""
    for _ in range(max_rounds):
        tr = build_transitions(cem, inp.mesh, inp.omega, inp.frames)
        report.holonomy_bad_edges = len(tr.bad_edges)
        if tr.bad_edges or len(tr.ambiguous_faces):
            P = cem.mesh.vertices[np.r_[cem.mesh.edges[tr.bad_edges].reshape(-1),
                                        cem.mesh.faces[tr.ambiguous_faces].reshape(-1)].astype(np.int64)]
            raise HexMeshError(
                f"the field's transitions do not close as the network prescribes around {len(tr.bad_edges)} tet "
                f"edges ({len(tr.ambiguous_faces)} faces ambiguous) near {_where(P)}: the field has singularities "
                "the network does not ask for there" + _unconverged(inp) + "; a field that is not hex-meshable as "
                "solved cannot give a hex mesh (solve it on a finer mesh, or check the network there)", report,
                kind="field")
        try:
            ms = build_map_system(cem, tr, cell)
        except MapError as e:
            raise HexMeshError(f"the map's constraints cannot be met: {e}", report, kind="map") from None
        flat = degenerate_tets(ms)
        if not len(flat):
            break
        edges = _split_choice(cem, flat)
        if not len(edges):
            break
        cem = split_edges(cem, edges)
    return cem, tr, ms, flat


def _unconverged(inp: HexInput) -> str:
    status = getattr(inp, "status", "")
    return f" (the field itself is {status})" if status and status != "converged" else ""


def _where(points: np.ndarray) -> str:
    c = points.mean(axis=0)
    return f"({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g})"


AUTO_STEPS = (1.0, 0.85, 0.7)
"""Cell sizes tried, as fractions of the automatic one, when the map fails
or the mesh is defective at it (greedy rounding can collapse curves, nodes
or thin parts that are about a cell apart; a smaller cell keeps them apart).
A cell size the caller gives is tried alone."""


def _given_ok(given) -> bool:
    if not isinstance(given, list):
        return False
    for g in given:
        if not isinstance(g, tuple) or len(g) != 4:
            return False
        P = np.asarray(g[0]) if isinstance(g[0], np.ndarray) else None
        if P is None or P.ndim != 2 or P.shape[1:] != (3,) or len(P) < 2 or P.dtype.kind not in "fi" or \
                not np.isfinite(P).all() or not checks._is_real(g[1]) or not np.isfinite(float(g[1])):
            return False
    return True


def _hex_input(result, what: str) -> HexInput:
    """The HexInput of a Result or HexInput argument, its field checked."""
    if not isinstance(result, HexInput):
        if isinstance(result, (str, bytes)) or hasattr(result, "__fspath__"):
            raise OptionsError(f"{what}: result = {result!r} is a path; a stored result file is read first: "
                               f"{what}(solver.io.load_hex_input({str(result)!r}))")
        inp = HexInput.from_result(result)
    else:
        inp = result
    for name, cls in (("mesh", TetMesh), ("embedding", Embedding), ("network", PreparedNetwork),
                      ("surface", TriSurface)):
        if not isinstance(getattr(inp, name), cls):
            raise OptionsError(f"{what}: the HexInput's {name} is {type(getattr(inp, name)).__name__}, not a "
                               f"{cls.__name__} (HexInput.from_result(result) or io.load_hex_input(path) make one)")
    sharp = np.asarray(inp.sharp)
    if sharp.shape != (len(inp.surface.edges),) or sharp.dtype.kind != "b":
        raise OptionsError(f"{what}: the HexInput's sharp is {sharp.shape} {sharp.dtype}, not one boolean per "
                           f"surface edge ({len(inp.surface.edges)})")
    if len(inp.embedding.traces) != len(inp.network.curves):
        raise OptionsError(f"{what}: the HexInput's embedding traces {len(inp.embedding.traces)} curves, its network "
                           f"has {len(inp.network.curves)}")
    if inp.given is not None and not _given_ok(inp.given):
        raise OptionsError(f"{what}: the HexInput's given = {checks.describe(inp.given)}: must be None or a list of "
                           "(points (n, 3), sigma, curve id, name) per singular curve as the user gave it")
    if inp.status not in ("converged", "not converged"):
        raise OptionsError(f"{what}: the HexInput's status = {checks.describe(inp.status)}: must be 'converged' or "
                           "'not converged'")
    fault = field_fault(inp.mesh, inp.frames, inp.omega)
    if fault:
        raise HexMeshError(f"the field is not one a hex mesh can follow: {fault}", kind="field")
    return inp


class _Retry(HexMeshError):
    """A failure of the map at this cell size that a smaller cell may undo."""


def hexmesh(result, cell_size: float | None = None, *, smooth: bool = True, progress=None, cancel=None,
            target_hexes: int = DEFAULT_HEXES, allow_unconverged: bool = False) -> HexMesh:
    """A pure hexahedral mesh of a solved field whose irregular edges are the
    prescribed curves.

    Parameters
    ----------
    result : solver Result, or HexInput
        the solved field (``solve(...)``); it must have converged
    cell_size : float, optional
        hex edge length in the units of the surface; default
        (``default_cell_size``): about target_hexes cells, at least 1.5
        along the shortest singular curve; where the map fails or the mesh
        is defective at the automatic size, 0.85 and 0.7 of it are tried
        (``report.notes`` says so)
    smooth : bool
        optimise the vertex positions afterwards (never lowering the
        minimum scaled Jacobian)
    progress : callable(stage, fraction, message), optional
    cancel : callable() -> bool, optional
        polled between stages; raises Cancelled when it returns True
    target_hexes : int
        the number of cells the default cell size aims at (ignored when
        cell_size is given)
    allow_unconverged : bool
        mesh a field that did not converge anyway (``report.notes`` says
        so); by default such a field is refused

    Returns
    -------
    HexMesh
        with ``report.status`` 'valid', or 'defective' and the reason

    Raises
    ------
    HexMeshError
        when no valid hex mesh can be made; its ``kind`` says whose limit it
        is: 'network' (the network admits none), 'settings' (the cell size
        does not fit the solid), 'field' (the field did not converge, or its
        transitions do not close as the network prescribes) or 'map'
        (SymFrames' map failed: a limit of SymFrames); the message says how
        many tets and where
    """
    inp = _hex_input(result, "hexmesh")
    cell_size = checks.positive_float("cell_size", cell_size, OptionsError, allow_none=True,
                                      fix="the hex edge length in the units of the surface (None: automatic)")
    target_hexes = checks.integer("target_hexes", target_hexes, OptionsError, low=1, high=MAX_HEXES,
                                  fix=f"the number of cells the automatic cell size aims at (default {DEFAULT_HEXES})")
    smooth = checks.boolean("smooth", smooth, OptionsError)
    allow_unconverged = checks.boolean("allow_unconverged", allow_unconverged, OptionsError)
    for name, fn in (("progress", progress), ("cancel", cancel)):
        if fn is not None and not callable(fn):
            raise OptionsError(f"{name} = {checks.describe(fn)}: must be a function or None")
    status = getattr(inp, "status", "converged")
    if status != "converged" and not allow_unconverged:
        raise HexMeshError(
            f"the field is {status}: a field that did not converge is not one a hex mesh can follow (its "
            "transitions need not close around the curves); solve it again (a finer edge length, or the "
            "advice of the solve's report) and mesh the converged field", kind="field")
    report = HexReport()
    if status != "converged":
        report.notes.append(f"the field is {status}; meshed as asked (allow_unconverged)")
    clock = Stages(STAGE_WEIGHTS, report.stage_seconds, progress, cancel)
    auto = cell_size is None
    cell, why = (float(cell_size), "given") if not auto else cell_choice(inp, target_hexes)
    _check_cell(inp, cell, why)
    _check_indices(inp)
    steps = AUTO_STEPS if auto else (1.0,)
    first_defective, warned, failure = None, None, ""
    report.cell_reason = why
    for k, f in enumerate(steps):
        c = cell * f
        stop = _too_many(inp, c) if k else None
        if stop and (first_defective is not None or warned is not None):
            break
        if stop:  # the last size's map failed, and the next one may not be tried
            raise HexMeshError(f"{failure}; the next cell size, {c:.4g}, is not tried: {stop}; try a finer field (a "
                               "smaller edge length)", report, kind="map")
        n, mb = hex_estimate(inp, c)
        clock.say("curves onto edges", f"hex: cell size {c:.4g}: expected ~{n:,.0f} cells and ~{mb:,.0f} MB of "
                                       "memory for the hex stages")
        try:
            hm = _mesh_at(inp, c, smooth, clock, report)
        except _Retry as e:
            failure = str(e)
            if k + 1 < len(steps):
                report.notes.append(f"at cell size {c:.4g} the map failed ({failure}); trying "
                                    f"{cell * steps[k + 1]:.4g}")
                clock.say("integer-grid map", f"hex: {report.notes[-1]}")
                continue
            if warned is not None or first_defective is not None:
                return warned or first_defective
            tried = ", ".join(f"{cell * x:.4g}" for x in steps[:k + 1])
            raise HexMeshError((f"{failure} (cell sizes tried: {tried}, {_whose(report)})" if len(steps) > 1
                                else f"{failure} ({_whose(report)})")
                               + f"; {_smaller(report)}, or a finer field (a smaller edge length)", report,
                               kind="map") from None
        if hm.report.valid and not hm.report.warnings:
            return hm
        if hm.report.valid:
            warned = warned or hm
        else:
            first_defective = first_defective or hm
        if k + 1 == len(steps):
            return warned or first_defective
        what = (f"valid with warnings ({'; '.join(hm.report.warnings)})" if hm.report.valid
                else f"defective ({hm.report.reason})")
        report = _fresh_report(report, f"at cell size {c:.4g} the mesh was {what}; trying {cell * steps[k + 1]:.4g}")
        clock.seconds = report.stage_seconds
        clock.say("quality", f"hex: {report.notes[-1]}")
    return warned or first_defective


def _too_many(inp: HexInput, cell: float) -> str | None:
    """Why a cell size the automatic steps reach may not be tried (the cell
    limit, the memory estimate), or None."""
    n = _cell_count(inp, cell)
    if n > MAX_HEXES:
        return f"it would make about {n:,.0f} hexahedra (the limit is {MAX_HEXES:,})"
    return memory_refusal(inp, cell)


def _whose(report: HexReport) -> str:
    """Whose cell size it is, for a message."""
    why = report.cell_reason
    return "the cell size given" if why == "given" else f"the automatic cell size, for {why}"


def _smaller(report: HexReport) -> str:
    """What to change, for a message that asks for smaller cells."""
    if report.cell_reason == "given":
        return "choose a smaller cell size"
    return "give a smaller cell size (cell_size, --cell-size) or aim at more cells (target_hexes, --hex-cells)"


def _cell_count(inp: HexInput, cell: float) -> float:
    """About how many cells of this size the solid holds."""
    return _cells(float(np.sum(inp.mesh.tet_volumes)), cell)[0]


def _fresh_report(old: HexReport, note: str) -> HexReport:
    """A new report for the next attempt, keeping the notes and the seconds
    spent so far."""
    rep = HexReport()
    rep.notes, rep.cell_reason = old.notes + [note], old.cell_reason
    rep.stage_seconds = dict(old.stage_seconds)
    return rep


def _stage(clock: Stages, name: str, fn, *args, retry: bool = False, **kw):
    """clock.run, with any failure that is not a diagnosis (a numpy or scipy
    error, an internal inconsistency) turned into a HexMeshError that says it
    is SymFrames' limit, never the network's."""
    try:
        return clock.run(name, fn, *args, **kw)
    except (HexMeshError, Cancelled):
        raise
    except (CurveEdgeError, MapError, ExtractionError, ArithmeticError, ValueError, IndexError, RuntimeError,
            np.linalg.LinAlgError) as e:
        cls = _Retry if retry else HexMeshError
        raise cls(f"SymFrames' hex stage '{name}' failed on this field ({type(e).__name__}: {e}); this is a limit "
                  "of SymFrames, not a fault of the network: try another cell size or a finer field (a smaller "
                  "edge length), and please report this input", kind="map") from None


def _mesh_at(inp: HexInput, cell: float, smooth: bool, clock: Stages, report: HexReport) -> HexMesh:
    """The stages at one cell size (module docs); raises _Retry where a
    smaller cell may succeed."""
    report.cell_size = cell
    try:
        cem = clock.run("curves onto edges", curves_on_edges, inp.mesh, inp.embedding, inp.network)
    except CurveEdgeError as e:
        raise HexMeshError(f"the network cannot be put onto the tet mesh's edges: {e}; this is a limit of the "
                           "field's tet mesh, not of the network", report,
                           kind="map") from None
    except (ArithmeticError, ValueError, IndexError, KeyError, TypeError, RuntimeError) as e:
        raise HexMeshError(f"SymFrames' hex stage 'curves onto edges' failed on this field ({type(e).__name__}: "
                           f"{e}); this is a limit of SymFrames, not a fault of the network: try a finer field (a "
                           "smaller edge length), and please report this input", report, kind="map") from None
    cem, tr, ms, flat = _stage(clock, "transitions", _map_system, cem, inp, cell, report)
    report.sizes.update(cem.stats)
    report.sizes.update(ms.stats)
    if len(flat):
        raise HexMeshError(f"{len(flat)} tets near {_where(cem.mesh.vertices[cem.mesh.tets[flat]].reshape(-1, 3))} "
                           "are flat in every map the constraints allow, and splitting them did not free them; "
                           "this is a limit of SymFrames' map on this tet mesh: solve the field finer", report,
                           kind="map")
    sm, red = _stage(clock, "seamless map", seamless_map, ms)
    report.seamless_inverted = sm.inverted
    gm = _stage(clock, "integer-grid map", integer_grid_map, ms, red, retry=True)
    if _folded(gm):
        gm = _stage(clock, "integer-grid map", optimise_map, ms, gm, retry=True,
                    callback=_ticker(clock, "integer-grid map", "untangling"))
    report.map_inverted, report.rounding_shift, report.stiffening = _folded(gm), gm.max_shift, gm.stiffening
    if report.map_inverted:
        _refuse_folded(inp, cem, sm, gm, cell, report)
    raw = _stage(clock, "extraction", extract_hexes, cem.mesh, tr.faces, tr.tets, tr.transition, gm.corners, cell,
                 retry=True)
    report.lost_corners = raw.lost_corners
    if raw.fractional:
        raise _Retry(f"the map is not an integer-grid map ({raw.fractional} cut faces with a translation that is "
                     "not whole): a fault of SymFrames' rounding; please report this input", report, kind="map")
    if not len(raw.hexes):
        raise HexMeshError(f"the map holds no whole cell at cell size {cell:.4g} ({_whose(report)}); "
                           f"{_smaller(report)}", report, kind="settings")
    V, H = raw.vertices, raw.hexes
    sj0 = scaled_jacobian(V, H)
    report.sj_min_raw, report.sj_mean_raw = float(sj0.min()), float(sj0.mean())
    if smooth:
        V = _stage(clock, "smoothing", _smooth, V, H, cell, inp, _curve_vertices(V, cem, cell),
                   _ticker(clock, "smoothing", "smoothing"))
    _stage(clock, "quality", _assess, report, inp, V, H, cell)
    e, val = _irregular(H)
    return HexMesh(V, H, scaled_jacobian(V, H), report, e, val,
                   (cem.mesh.vertices, cem.mesh.tets, snap(gm.corners)),
                   boundary_patches(inp.surface, inp.sharp, V, H))


def _folded(gm) -> int:
    """Tets the map inverts or flattens, measured on the snapped corners the
    extraction reads (a tet whose tiny positive volume snapping erases
    cannot be traced through)."""
    U = snap(gm.corners)
    d = det3(np.transpose(U[:, 1:] - U[:, :1], (0, 2, 1)))
    return int(np.sum((gm.det <= 0) | (np.sign(gm.det) * d <= 1e-12)))


def _refuse_folded(inp: HexInput, cem, sm, gm, cell: float, report: HexReport) -> None:
    """The message for a map that stays folded: before rounding, the
    seamless map's own fold (no cell size helps); after it, the rounding's
    (a smaller cell may)."""
    bad = np.nonzero(gm.det <= 0)[0]
    if not len(bad):
        bad = np.argsort(gm.det)[:1]
    where = _where(cem.mesh.vertices[cem.mesh.tets[bad]].reshape(-1, 3))
    if sm.inverted > 0.01 * len(sm.det):
        hint = ("; try a finer field (a smaller edge length), and please report the input if it folds there "
                "too")
        if not any(c.sigma != 0 for c in inp.network.curves) and not inp.sharp.any() and \
                min(inp.surface.euler_characteristics()) <= 0:
            hint = ("; here the solid has a smooth handle and no singular curve, and a grid needs corners on a "
                    "boundary: a smooth solid torus, for example, needs curves around its tube (add them, or "
                    "sharp edges)")
        raise HexMeshError(
            f"SymFrames' seamless map folds: already before rounding, {sm.inverted:,} of {len(sm.det):,} tets "
            f"fold (around {where}); this is a limit of SymFrames' map (its cut, transitions and constraints), "
            f"not a proof that the network admits no hex mesh{hint}", report, kind="map")
    raise _Retry(
        f"no valid integer-grid map at cell size {cell:.4g}: {report.map_inverted} of {len(gm.det):,} tets stay "
        f"inverted or flat after rounding, stiffening and untangling, around {where} (greedy rounding could not "
        "keep the curves, the surface or its thin parts apart there: a limit of SymFrames' rounding)", report,
        kind="map")


def _ticker(clock: Stages, stage: str, what: str):
    """An L-BFGS callback: cancel when asked, a progress line every 25
    iterations."""

    def tick(it, energy):
        if clock.cancel is not None and clock.cancel():
            raise Cancelled()
        if it % 25 == 0:
            clock.say(stage, f"hex: {what}, iteration {it}, energy {energy:.6g}")

    return tick


def _irregular(H: np.ndarray):
    q, _ = boundary_quads(H)
    e, val, onb = edge_valences(H, q)
    irr = (~onb) & (val != 4)
    return e[irr], val[irr]


# ------------------------------------------------------------ smoothing


def _curve_vertices(V: np.ndarray, cem: CurveEdgeMesh, cell: float) -> list:
    """Per chain: the hex vertices lying on it (the map puts them there)."""
    X = cem.mesh.vertices
    out = []
    for ch in cem.chains:
        A, B = X[ch.vertices[:-1]], X[ch.vertices[1:]]
        d = _segments_distance(V, A, B)
        out.append(np.nonzero(d <= 1e-6 * cell)[0])
    return out


def _smooth(V: np.ndarray, H: np.ndarray, cell: float, inp: HexInput, on_curve: list, callback=None) -> np.ndarray:
    """Untangle and improve the vertex positions (smooth.optimise): interior
    vertices freely, boundary vertices along the input surface, vertices of
    sharp edges and of the network's curves along them; kept only if the
    minimum scaled Jacobian does not drop."""
    q, _ = boundary_quads(H)
    S = inp.surface
    sharp = S.edges[inp.sharp]
    segs_a, segs_b = [S.V[sharp[:, 0]]], [S.V[sharp[:, 1]]]
    # creases of the hex boundary that follow the input's sharp edges (a
    # crease the cells make on a smooth bend is smoothed like the surface)
    fe = _feature_edges(q, V)
    if len(fe) and len(sharp):
        d = _segments_distance(0.5 * (V[fe[:, 0]] + V[fe[:, 1]]), segs_a[0], segs_b[0])
        fe = fe[d <= 0.25 * cell]
    else:
        fe = fe[:0]
    lines = [fe]
    # hex edges along each curve (singular or feature), and the curve itself
    E = np.sort(H[:, HEX_EDGES].reshape(-1, 2), axis=1)
    E = np.unique(E, axis=0)
    fixed = np.zeros(len(V), bool)
    onb = np.zeros(len(V), bool)
    onb[np.unique(q)] = True
    anchor = np.zeros(len(V), bool)
    for verts, c in zip(on_curve, inp.network.curves):
        if not len(verts):
            continue
        if c.sigma != 0:
            # singular curves, their ends on the surface too: held near the
            # map's place by a spring (the cells around nodes and ends need
            # room); the report checks that they stay within a cell
            anchor[verts] = True
            continue
        fixed[verts[onb[verts]]] = True  # where a feature curve meets the surface
        mark = np.zeros(len(V), bool)
        mark[verts] = True
        lines.append(E[mark[E[:, 0]] & mark[E[:, 1]]])
        segs_a.append(c.points[:-1])
        segs_b.append(c.points[1:])
    motion = BoundaryMotion(V, q, np.vstack(lines), S, (np.vstack(segs_a), np.vstack(segs_b)), fixed)
    best_min = float(scaled_jacobian(V, H).min())
    spring = anchor & ~fixed

    sing_curves = [c.points for c in inp.network.curves if c.sigma != 0]
    sv = np.nonzero(spring)[0]

    def moved(W):
        """Largest distance of a singular curve's vertex from the curves."""
        if not len(sv):
            return 0.0
        return float(np.min([_polyline_distance(P, W[sv]) for P in sing_curves], axis=0).max())

    # the weakest spring that keeps the curves' vertices within 0.9 of a
    # cell of the curves, then the largest step towards the stiffest optimum
    # that keeps the minimum
    W = V
    for weight in (SPRING, 3 * SPRING, 10 * SPRING, 100 * SPRING):
        try:
            Wk = optimise(V, H, cell, motion, anchor=spring, anchor_weight=weight, callback=callback)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError):
            continue  # a run that diverged (non-finite positions): the next spring, or the map's own places
        if not np.all(np.isfinite(Wk)):
            continue
        W = Wk
        if moved(W) <= 0.9 * cell and float(scaled_jacobian(W, H).min()) >= best_min:
            return W
    for a in (0.5, 0.25, 0.125):
        Wa = V + a * (W - V)
        if moved(Wa) <= 0.9 * cell and float(scaled_jacobian(Wa, H).min()) >= best_min:
            return Wa
    return V


def _feature_edges(quads, V) -> np.ndarray:
    """(k, 2) edges of the quad boundary whose two quads meet at more than
    SHARP_DIHEDRAL degrees."""
    Q = quads
    P = V[Q]
    n = np.cross(P[:, 2] - P[:, 0], P[:, 3] - P[:, 1])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    E = np.stack([Q, np.roll(Q, -1, axis=1)], axis=2).reshape(-1, 2)
    key = np.sort(E, axis=1)
    f = np.repeat(np.arange(len(Q)), 4)
    order = np.lexsort((key[:, 1], key[:, 0]))
    key, f = key[order], f[order]
    same = np.all(key[1:] == key[:-1], axis=1)
    i = np.nonzero(same)[0]
    cosang = np.einsum("ij,ij->i", n[f[i]], n[f[i + 1]])
    return key[i[cosang < np.cos(np.radians(SHARP_DIHEDRAL))]]


# ------------------------------------------------------------ quality


def _assess(report: HexReport, inp: HexInput, V: np.ndarray, H: np.ndarray, cell: float) -> None:
    sj = scaled_jacobian(V, H)
    report.hexes, report.vertices = len(H), len(V)
    report.inverted = int(np.sum(sj <= 0))
    report.sj_min, report.sj_mean = float(sj.min()), float(sj.mean())
    q, over = boundary_quads(H)
    report.faces_over_two = over
    report.euler = _euler_per_component(q)
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
    _match_curves(report, inp, V, e[irr], val[irr], cell)
    report.hausdorff = hausdorff_distance(inp.surface, V, q)
    report.hausdorff_relative = report.hausdorff / inp.surface.bbox_diagonal
    _verdict(report)


def _euler_per_component(q: np.ndarray) -> list:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if not len(q):
        return []
    n = int(q.max()) + 1
    a = np.r_[q[:, 0], q[:, 1], q[:, 2]]
    b = np.r_[q[:, 1], q[:, 2], q[:, 3]]
    _, lab = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)), directed=False)
    comp = lab[q[:, 0]]
    return sorted(euler_characteristic(q[comp == c]) for c in np.unique(comp))


def _polyline_distance(P: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Distance from points X (k, 3) to the polyline P (n, 3)."""
    a, d = P[:-1], P[1:] - P[:-1]
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    out = np.full(len(X), np.inf)
    for s in range(0, len(X), 4096):
        Y = X[s:s + 4096]
        t = np.clip(np.einsum("kij,ij->ki", Y[:, None] - a[None], d) / dd, 0.0, 1.0)
        out[s:s + 4096] = np.linalg.norm(Y[:, None] - (a[None] + t[..., None] * d[None]), axis=2).min(axis=1)
    return out


def _match_curves(report: HexReport, inp: HexInput, V, E, val, cell: float) -> None:
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


def curve_matches(curves: list, V, E, val, cell: float) -> tuple[int, list]:
    """Irregular edges E (k, 2) with valences val against singular curves
    [(points, sigma, id, name)]: how many lie more than a cell from every
    curve of their valence, and a CurveMatch per curve."""
    mid = 0.5 * (V[E[:, 0]] + V[E[:, 1]]) if len(E) else np.zeros((0, 3))
    if not curves:
        return len(E), []
    D = np.stack([_polyline_distance(P, mid) for P, *_ in curves], axis=1) if len(E) else \
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
            d = _segments_distance(S, V[Em[:, 0]], V[Em[:, 1]])
            covered, far = float(np.mean(d <= cell)), float(dist[mine].max())
        else:
            covered, far = 0.0, float("inf")
        out.append(CurveMatch(cid, name, sigma, int(want[j]), int(mine.sum()), covered, far))
    return int(np.sum(~ok)), out


def _segments_distance(X, A, B):
    out = np.full(len(X), np.inf)
    d = B - A
    dd = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
    for s in range(0, len(A), 2048):
        a, dv, ddv = A[s:s + 2048], d[s:s + 2048], dd[s:s + 2048]
        t = np.clip(np.einsum("kij,ij->ki", X[:, None] - a[None], dv) / ddv, 0.0, 1.0)
        out = np.minimum(out, np.linalg.norm(X[:, None] - (a[None] + t[..., None] * dv[None]), axis=2).min(axis=1))
    return out


def _verdict(report: HexReport) -> None:
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
    report.status = DEFECTIVE if why else VALID
    report.reason = "; ".join(why)
    report.warnings = warn


HAUSDORFF_BAR = 0.01
"""A valid mesh's boundary lies within this share of the bounding-box
diagonal of the input surface."""
HAUSDORFF_WARNED = 0.02
"""Past HAUSDORFF_BAR and up to this, the mesh is valid with a warning
(a secondary measure slightly over its bar); past it, defective."""


@dataclass
class EdgeField:
    """A solved field on its tet mesh split so that the network runs along
    tet edges (curve_edges.py), one frame per tet, ready for a hex mesher
    that wants singular edges on mesh edges (CubeCover, AlgoHex).

    mesh         : TetMesh, the split mesh
    tet_frames   : (#T, 3, 3) combed per-tet frames, columns the cross axes
    faces, tets  : (k,) interior faces and (k, 2) their tets (A, B)
    transition   : (k,) CUBE_GROUP index g with F_A ~ F_B G[g]
    curve        : (#T,) the prepared curve whose chain runs along an edge of
                   the tet, -1 elsewhere
    vertex_frames: (#V, 3, 3) the field's frame at its own vertices; at the
                   inserted ones (on the curves) that of a tet around them
    chains       : the curve_edges.Chain of every prepared curve
    """

    mesh: object
    tet_frames: np.ndarray
    faces: np.ndarray
    tets: np.ndarray
    transition: np.ndarray
    curve: np.ndarray
    vertex_frames: np.ndarray
    chains: list


def field_on_edges(result) -> EdgeField:
    """The field of a Result (or HexInput) with its curves on tet edges.

    Raises
    ------
    HexMeshError
        where the network cannot be put onto tet edges or the field's
        transitions do not close as the network prescribes (then no hex
        mesher can use it either)
    """
    inp = _hex_input(result, "field_on_edges")
    try:
        cem = curves_on_edges(inp.mesh, inp.embedding, inp.network)
    except CurveEdgeError as e:
        raise HexMeshError(f"the network cannot be put onto the tet mesh's edges: {e}", kind="map") from None
    tr = build_transitions(cem, inp.mesh, inp.omega, inp.frames)
    if tr.bad_edges or len(tr.ambiguous_faces):
        raise HexMeshError(f"the field's transitions do not close as the network prescribes around "
                           f"{len(tr.bad_edges)} tet edges" + _unconverged(inp), kind="field")
    mesh = cem.mesh
    curve = np.full(mesh.n_tets, -1, dtype=np.int64)
    for ch in cem.chains:
        e = mesh.edge_index(ch.vertices[:-1], ch.vertices[1:])
        curve[np.nonzero(np.isin(mesh.tet_edges, e).any(axis=1))[0]] = ch.curve
    VF = np.zeros((mesh.n_vertices, 3, 3))
    src = cem.source_vertex
    VF[src >= 0] = inp.frames[src[src >= 0]]
    new = np.nonzero(src < 0)[0]
    if len(new):
        # the first tet around each inserted vertex
        t_of = np.full(mesh.n_vertices, -1, dtype=np.int64)
        t_of[mesh.tets.reshape(-1)[::-1]] = np.repeat(np.arange(mesh.n_tets), 4)[::-1]
        VF[new] = tr.frames[t_of[new]]
    return EdgeField(mesh, tr.frames, tr.faces, tr.tets, tr.transition, curve, VF, cem.chains)
