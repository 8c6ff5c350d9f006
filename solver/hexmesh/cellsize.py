"""The cell size of a hex-meshing run: the automatic one and why
(``cell_choice``), and the refusal of one that does not fit the solid or
this machine's memory (``check_cell``), before any hex work."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .. import checks
from ..errors import HexMeshError, OptionsError
from ..field.solved import SolvedField
from ..mesh.resolution import RAM_FRACTION, physical_memory_mb
from .intake import hex_input
from .options import DEFAULT_HEXES, MAX_HEXES

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
CELL_FLOOR = 8.0
"""The network's needs make at most this many times the target's cells."""


def _curve_lengths(net) -> np.ndarray:
    return np.array([float(np.sum(np.linalg.norm(np.diff(c.points, axis=0), axis=1))) for c in net.curves])


def default_cell_size(inp: SolvedField, target_hexes: int = DEFAULT_HEXES) -> float:
    """The automatic cell size.

    Parameters
    ----------
    inp : SolvedField
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
    inp = hex_input(inp, "default_cell_size")
    target_hexes = checks.integer("target_hexes", target_hexes, OptionsError, low=1, high=MAX_HEXES,
                                  fix=f"the number of cells aimed at (default {DEFAULT_HEXES})")
    return cell_choice(inp, target_hexes)[0]


def cell_choice(inp: SolvedField, target_hexes: int = DEFAULT_HEXES) -> tuple[float, str]:
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


def cell_count(inp: SolvedField, cell: float, sizes=None) -> float:
    """About how many cells of this size the solid holds (with a size
    field's smaller cells, ``sizing.SizeField``)."""
    if sizes is not None and not sizes.uniform:
        return sizes.cells(inp.mesh, cell)
    return _cells(float(np.sum(inp.mesh.tet_volumes)), cell)[0]


def solid_size(inp: SolvedField) -> tuple[float, float]:
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


def check_cell(inp: SolvedField, cell: float, why: str = "given", sizes=None) -> None:
    """Refuse a cell size (given, or the automatic one for ``why``) that
    does not fit the solid (``check_cell_size``) or this machine's memory
    (``memory_refusal``).

    Raises
    ------
    HexMeshError
        kind 'settings'
    """
    if why == "given":
        check_cell_size(cell, *solid_size(inp))
    else:
        check_cell_size(cell, *solid_size(inp), subject=f"the automatic cell size {cell:.4g} (for {why})",
                        fix="; give a cell size (cell_size, --cell-size) instead")
    n = cell_count(inp, cell, sizes) if sizes is not None and not sizes.uniform else 0.0
    if n > MAX_HEXES:
        raise HexMeshError(f"cell size {cell:.4g} with smaller cells near {sizes.finer.describe()} would make about "
                           f"{n:,.0f} hexahedra (the limit is {MAX_HEXES:,}); choose a larger cell size or a larger "
                           "finer_near ratio", kind="settings")
    refusal = memory_refusal(inp, cell, sizes)
    if refusal:
        raise HexMeshError(refusal, kind="settings")


def too_many(inp: SolvedField, cell: float, sizes=None) -> str | None:
    """Why a cell size the automatic steps reach may not be tried (the cell
    limit, the memory estimate), or None."""
    n = cell_count(inp, cell, sizes)
    if n > MAX_HEXES:
        return f"it would make about {n:,.0f} hexahedra (the limit is {MAX_HEXES:,})"
    return memory_refusal(inp, cell, sizes)


def hex_memory_mb(cells: float, tets: int) -> float:
    """Estimated memory (MB) the hex stages need above the field's, for
    about ``cells`` cells on a field of ``tets`` tets (``HEX_KB_PER_CELL``)."""
    return HEX_BASE_MB + (HEX_KB_PER_CELL * cells + HEX_KB_PER_TET * tets) / 1024.0


def hex_estimate(inp: SolvedField, cell: float, sizes=None) -> tuple[float, float]:
    """(about how many cells, estimated MB of the hex stages) at a cell size."""
    n = cell_count(inp, cell, sizes)
    return n, hex_memory_mb(n, inp.mesh.n_tets)


def _gb(mb: float) -> str:
    return f"{mb / 1024:.1f} GB" if mb < 10240 else f"{mb / 1024:,.0f} GB"


def memory_refusal(inp: SolvedField, cell: float, sizes=None) -> str | None:
    """The message refusing a hex run at this cell size for its memory
    estimate, or None when it fits in ``RAM_FRACTION`` of this machine's
    memory."""
    n, mb = hex_estimate(inp, cell, sizes)
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
