"""Hex meshing, stage by stage: from a solved field to a pure hex mesh.

    curves onto edges -> transitions -> map system -> seamless map
        -> integer-grid map -> extraction -> smoothing -> quality

``hexmesh(field, cell_size)`` runs it on a solved field (a ``SolvedField``:
a Result's ``.field``, or one read back from a file, so a stored field is
meshed without solving again).  This module keeps only the order of the stages and the
ladder of cell sizes tried; each stage is its own module's (the package's
docs).
"""

from __future__ import annotations

import numpy as np

from .. import checks
from ..errors import Cancelled, HexMeshError, OptionsError
from ..field.solved import SolvedField
from ..stages import Stages
from .cellsize import (
    cell_choice,
    check_cell,
    hex_estimate,
    too_many,
)
from .curve_edges import CurveEdgeError, CurveEdgeMesh, curves_on_edges
from .extract import ExtractionError, extract_hexes, snap
from .hexes import HexMesh
from .intake import check_converged, check_indices, hex_input
from .options import (
    DEFAULT_HEXES,
    HexOptions,
    hex_options,
)
from .patches import boundary_patches
from .quality import irregular_edges, scaled_jacobian
from .report import HAUSDORFF_BAR, HexReport, assess, where
from .seamless import (
    MapError,
    integer_grid_map,
    map_system,
    optimise_map,
    seamless_map,
    split_flat,
    widen_rings,
)
from .sizing import SizeField, size_field
from .smooth import smooth_hexes
from .transitions import checked_transitions

STAGE_WEIGHTS = {"curves onto edges": 0.03, "transitions": 0.07, "map system": 0.08, "seamless map": 0.15,
                 "integer-grid map": 0.1, "extraction": 0.07, "smoothing": 0.4, "quality": 0.1}
"""Share of a typical hex-meshing run each stage takes (the progress bar),
in the order the stages run."""
MAP_ROUNDS = 6
"""The most times the transitions and the map system are built, the tets
flat in every map split in between (seamless.freeing_edges)."""
AUTO_STEPS = (1.0, 0.85, 0.7)
"""Cell sizes tried, as fractions of the automatic one, when the map fails
or the mesh is defective at it (greedy rounding can collapse curves, nodes
or thin parts that are about a cell apart; a smaller cell keeps them apart).
A cell size the caller gives is tried alone."""


class _Retry(HexMeshError):
    """A failure of the map at this cell size that a smaller cell may undo."""


def hexmesh(field, cell_size: float | None = None, *, smooth: bool = True, progress=None, cancel=None,
            target_hexes: int = DEFAULT_HEXES, allow_unconverged: bool = False,
            options: HexOptions | None = None, finer_near=None) -> HexMesh:
    """A pure hexahedral mesh of a solved field whose irregular edges are the
    prescribed curves.

    Parameters
    ----------
    field : SolvedField, or a solver Result
        the solved field (``solve(...).field``, ``io.load_field(path)``);
        it must have converged
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
    options : HexOptions, optional
        cell_size, target_hexes, smooth and finer_near as one value; a
        keyword left at its default defers to it, one that disagrees with it
        is refused
    finer_near : FinerNear or str, optional
        smaller cells near chosen boundary patches or network curves
        (``sizing.FinerNear``, or words such as ``"patch 3, curve 2"``: half
        the cell size there, back to it over 4 cells); the cell size is the
        one away from them

    Returns
    -------
    HexMesh
        with ``report.status`` 'valid', or 'defective' and the reason

    Raises
    ------
    OptionsError
        a setting of the wrong type or range (checked before the field is
        read), or a keyword that disagrees with ``options``
    HexMeshError
        when no valid hex mesh can be made; its ``kind`` says whose limit it
        is: 'network' (the network admits none), 'settings' (the cell size
        does not fit the solid), 'field' (the field did not converge, or its
        transitions do not close as the network prescribes) or 'map'
        (SymFrames' map failed: a limit of SymFrames); the message says how
        many tets and where
    """
    opts = hex_options(options, cell_size=cell_size, target_hexes=target_hexes, smooth=smooth, finer_near=finer_near)
    allow_unconverged = checks.boolean("allow_unconverged", allow_unconverged, OptionsError)
    for name, fn in (("progress", progress), ("cancel", cancel)):
        if fn is not None and not callable(fn):
            raise OptionsError(f"{name} = {checks.describe(fn)}: must be a function or None")
    inp = hex_input(field, "hexmesh")
    note = check_converged(inp, allow_unconverged)
    report = HexReport()
    if note:
        report.notes.append(note)
    clock = Stages(STAGE_WEIGHTS, report.stage_seconds, progress, cancel)
    auto = opts.cell_size is None
    cell, why = (opts.cell_size, "given") if not auto else cell_choice(inp, opts.target_hexes)
    sizes = size_field(inp, opts.finer_near)
    check_cell(inp, cell, why, sizes)
    check_indices(inp.network.curves, inp.network.source)
    report.cell_reason = why
    if sizes.finer is not None:
        report.finer_near = sizes.finer.describe()
    return _ladder(inp, cell, AUTO_STEPS if auto else (1.0,), opts.smooth, clock, report, sizes)


def _ladder(inp: SolvedField, cell: float, steps: tuple, smooth: bool, clock: Stages, report: HexReport,
            sizes: SizeField) -> HexMesh:
    """The stages at each cell size of ``steps`` (fractions of ``cell``)
    until one gives a valid mesh whose boundary is within HAUSDORFF_BAR of
    the surface (other warnings, poor cells, a smaller cell would not fix);
    else the valid one whose boundary lies closest to the surface (a smaller cell
    need not be closer: the ellipsoid of bench/hexnet.json was 1.58%, 1.94%
    and 1.13% off at 1, 0.85 and 0.7 of its cell), or the first defective
    one; a map that fails at every size is refused.  A mesh kept from an
    earlier size carries the notes of every size tried (``_kept``)."""
    first_defective, warned, failure = None, None, ""
    for k, f in enumerate(steps):
        c = cell * f
        stop = too_many(inp, c, sizes) if k else None
        if stop and (first_defective is not None or warned is not None):
            report.notes.append(f"cell size {c:.4g} is not tried: {stop}")
            break
        if stop:  # the last size's map failed, and the next one may not be tried
            raise HexMeshError(f"{failure}; the next cell size, {c:.4g}, is not tried: {stop}; try a finer field (a "
                               "smaller edge length)", report, kind="map")
        n, mb = hex_estimate(inp, c, sizes)
        clock.say("curves onto edges", f"hex: cell size {c:.4g}: expected ~{n:,.0f} cells and ~{mb:,.0f} MB of "
                                       "memory for the hex stages")
        try:
            hm = _mesh_at(inp, c, smooth, clock, report, sizes)
        except _Retry as e:
            failure = str(e)
            if k + 1 < len(steps):
                report.notes.append(f"at cell size {c:.4g} the map failed ({failure}); trying "
                                    f"{cell * steps[k + 1]:.4g}")
                clock.say("integer-grid map", f"hex: {report.notes[-1]}")
                continue
            if warned is not None or first_defective is not None:
                report.notes.append(f"at cell size {c:.4g} the map failed ({failure})")
                return _kept(warned or first_defective, report)
            tried = ", ".join(f"{cell * x:.4g}" for x in steps[:k + 1])
            raise HexMeshError((f"{failure} (cell sizes tried: {tried}, {_whose(report)})" if len(steps) > 1
                                else f"{failure} ({_whose(report)})")
                               + f"; {_smaller(report)}, or a finer field (a smaller edge length)", report,
                               kind="map") from None
        if hm.report.valid and hm.report.hausdorff_relative <= HAUSDORFF_BAR:
            return hm  # a warning a smaller cell would not fix (poor cells) ends the ladder too
        if hm.report.valid:
            if warned is None or hm.report.hausdorff_relative < warned.report.hausdorff_relative:
                warned = hm
        else:
            first_defective = first_defective or hm
        what = (f"valid with warnings ({'; '.join(hm.report.warnings)})" if hm.report.valid
                else f"defective ({hm.report.reason})")
        if k + 1 == len(steps):
            return _kept(warned or first_defective, hm.report, f"at cell size {c:.4g} the mesh was {what}")
        report = _fresh_report(report, f"at cell size {c:.4g} the mesh was {what}; trying {cell * steps[k + 1]:.4g}")
        clock.seconds = report.stage_seconds
        clock.say("quality", f"hex: {report.notes[-1]}")
    return _kept(warned or first_defective, report)


def _kept(hm: HexMesh, last: HexReport, outcome: str = "") -> HexMesh:
    """``hm``, whose report now carries the notes of every cell size tried
    (``last``: the report of the last attempt; ``outcome``: what that
    attempt gave), their seconds, and which size was kept."""
    rep = hm.report
    if last is rep:
        return hm
    # a later attempt's report starts from this one's notes (_fresh_report)
    what = (f"valid with warnings, {100 * rep.hausdorff_relative:.2f}% off the surface" if rep.valid
            else "defective")
    rep.notes = list(last.notes) + ([outcome] if outcome else []) + [
        f"kept the mesh at cell size {rep.cell_size:.4g} ({what}): of the sizes tried, the "
        + ("closest to the surface" if rep.valid else "first one meshed")]
    rep.stage_seconds = dict(last.stage_seconds)
    return hm


def _whose(report: HexReport) -> str:
    """Whose cell size it is, for a message."""
    why = report.cell_reason
    return "the cell size given" if why == "given" else f"the automatic cell size, for {why}"


def _smaller(report: HexReport) -> str:
    """What to change, for a message that asks for smaller cells."""
    if report.cell_reason == "given":
        return "choose a smaller cell size"
    return "give a smaller cell size (cell_size, --cell-size) or aim at more cells (target_hexes, --hex-cells)"


def _fresh_report(old: HexReport, note: str) -> HexReport:
    """A new report for the next attempt, keeping the notes and the seconds
    spent so far."""
    rep = HexReport()
    rep.notes, rep.cell_reason, rep.finer_near = old.notes + [note], old.cell_reason, old.finer_near
    rep.stage_seconds = dict(old.stage_seconds)
    return rep


def _stage(clock: Stages, name: str, fn, *args, retry: bool = False, again: bool = False, **kw):
    """clock.run, with any failure that is not a diagnosis (a numpy or scipy
    error, an internal inconsistency) turned into a HexMeshError that says it
    is SymFrames' limit, never the network's.  ``again``: a later part of a
    stage already run (timed under its name, its weight not counted twice)."""
    try:
        if not again:
            return clock.run(name, fn, *args, **kw)
        if clock.cancel is not None and clock.cancel():
            raise Cancelled()
        with clock.timed(name):
            return fn(*args, **kw)
    except (HexMeshError, Cancelled):
        raise
    except (CurveEdgeError, MapError, ExtractionError, ArithmeticError, ValueError, IndexError, RuntimeError,
            np.linalg.LinAlgError) as e:
        cls = _Retry if retry else HexMeshError
        raise cls(f"SymFrames' hex stage '{name}' failed on this field ({type(e).__name__}: {e}); this is a limit "
                  "of SymFrames, not a fault of the network: try another cell size or a finer field (a smaller "
                  "edge length), and please report this input", kind="map") from None


def _ticker(clock: Stages, stage: str, what: str):
    """An L-BFGS callback: cancel when asked, a progress line every 25
    iterations."""

    def tick(it, energy):
        if clock.cancel is not None and clock.cancel():
            raise Cancelled()
        if it % 25 == 0:
            clock.say(stage, f"hex: {what}, iteration {it}, energy {energy:.6g}")

    return tick


def _mesh_at(inp: SolvedField, cell: float, smooth: bool, clock: Stages, report: HexReport,
             sizes: SizeField | None = None) -> HexMesh:
    """The stages at one cell size (module docs); raises _Retry where a
    smaller cell may succeed."""
    report.cell_size = cell
    cem = _curves_on_edges(inp, clock, report)
    # the rings of tets around the singular chain edges widened where they are
    # too few for the edge's valence (seamless.ring_edges)
    cem = _stage(clock, "curves onto edges", widen_rings, cem, again=True)
    cem, tr, ms = _map_system(cem, inp, cell, clock, report, sizes)
    sm, red = _stage(clock, "seamless map", seamless_map, ms)
    report.seamless_inverted = sm.inverted
    gm = _stage(clock, "integer-grid map", integer_grid_map, ms, red, retry=True)
    if gm.folded():
        gm = _stage(clock, "integer-grid map", optimise_map, ms, gm, retry=True,
                    callback=_ticker(clock, "integer-grid map", "untangling"))
    report.map_inverted, report.rounding_shift, report.stiffening = gm.folded(), gm.max_shift, gm.stiffening
    if report.map_inverted:
        _refuse_folded(inp, cem, sm, gm, cell, report)
    raw = _stage(clock, "extraction", extract_hexes, cem.mesh, tr, gm.corners, cell, retry=True)
    report.lost_corners = raw.lost_corners
    if raw.fractional:
        raise _Retry(f"the map is not an integer-grid map ({raw.fractional} cut faces with a translation that is "
                     "not whole): a fault of SymFrames' rounding; please report this input", report, kind="map")
    if not len(raw.hexes):
        raise HexMeshError(f"the map holds no whole cell at cell size {cell:.4g} ({_whose(report)}); "
                           f"{_smaller(report)}", report, kind="settings")
    V, H = raw.vertices, raw.hexes
    rel = None if sizes is None else sizes.relative(V[H].mean(axis=1), cell)  # per cell, where a size field asks
    sj0 = scaled_jacobian(V, H)
    report.sj_min_raw, report.sj_mean_raw = float(sj0.min()), float(sj0.mean())
    if smooth:
        V = _stage(clock, "smoothing", smooth_hexes, V, H, cell, inp, cem, _ticker(clock, "smoothing", "smoothing"),
                   rel)
    _stage(clock, "quality", assess, report, inp, V, H, cell, rel)
    e, val = irregular_edges(H)
    return HexMesh(V, H, scaled_jacobian(V, H), report, e, val,
                   (cem.mesh.vertices, cem.mesh.tets, snap(gm.corners)),
                   boundary_patches(inp.surface, inp.sharp, V, H))


def _curves_on_edges(inp: SolvedField, clock: Stages, report: HexReport) -> CurveEdgeMesh:
    """The first stage: the network onto the tet mesh's edges."""
    try:
        return clock.run("curves onto edges", curves_on_edges, inp.mesh, inp.embedding, inp.network)
    except CurveEdgeError as e:
        raise HexMeshError(f"the network cannot be put onto the tet mesh's edges: {e}; this is a limit of the "
                           "field's tet mesh, not of the network", report,
                           kind="map") from None
    except (ArithmeticError, ValueError, IndexError, KeyError, TypeError, RuntimeError) as e:
        raise HexMeshError(f"SymFrames' hex stage 'curves onto edges' failed on this field ({type(e).__name__}: "
                           f"{e}); this is a limit of SymFrames, not a fault of the network: try a finer field (a "
                           "smaller edge length), and please report this input", report, kind="map") from None


def _map_system(cem: CurveEdgeMesh, inp: SolvedField, cell: float, clock: Stages, report: HexReport,
                sizes: SizeField | None = None):
    """The stages 'transitions' and 'map system', again on the mesh split
    where tets are flat whatever the map (seamless.split_flat), at most
    MAP_ROUNDS times; tets still flat are refused."""
    for k in range(MAP_ROUNDS):
        tr = _stage(clock, "transitions", checked_transitions, cem, inp, report, again=k > 0)
        ms, flat = _stage(clock, "map system", map_system, cem, tr, cell, report, sizes, again=k > 0)
        split = _stage(clock, "map system", split_flat, cem, flat, again=True) if len(flat) else None
        if split is None:
            break
        cem = split
    report.sizes.update(cem.stats)
    report.sizes.update(ms.stats)
    if len(flat):
        raise HexMeshError(f"{len(flat)} tets near {where(cem.mesh.vertices[cem.mesh.tets[flat]].reshape(-1, 3))} "
                           "are flat in every map the constraints allow, and splitting them did not free them; "
                           "this is a limit of SymFrames' map on this tet mesh: solve the field finer", report,
                           kind="map")
    return cem, tr, ms


def _refuse_folded(inp: SolvedField, cem: CurveEdgeMesh, sm, gm, cell: float, report: HexReport) -> None:
    """The refusal of a map that stays folded after rounding, stiffening and
    untangling: a _Retry (a smaller cell may do: the next size of the
    ladder), saying whether the seamless map already folded before
    rounding; only a smooth handle without singular curves, where the
    seamless map folds in half its tets at any size, is a HexMeshError at
    once.  (The genus-2 plates of testkit/hexnet.py: their seamless maps
    fold around every singular curve, 80-200 tets of 9-15k, ~1 %, on each
    of 27 meshes looked at (23 fTetWild, 4 TetGen), with three tets around
    each valence-5 chain edge; rounding and untangling left 1-18 of them
    folded on 14 of 81 (mesh, cell size) pairs, two meshes at every size.
    With those rings widened (seamless.ring_edges) 33-164 fold before
    rounding, and after it one tet on one pair.)"""
    bad = np.nonzero(gm.det <= 0)[0]
    if not len(bad):
        bad = np.argsort(gm.det)[:1]
    at = where(cem.mesh.vertices[cem.mesh.tets[bad]].reshape(-1, 3))
    if sm.inverted > 0.01 * len(sm.det):
        if not any(c.sigma != 0 for c in inp.network.curves) and not inp.sharp.any() and \
                min(inp.surface.euler_characteristics()) <= 0:
            raise HexMeshError(
                f"SymFrames' seamless map folds: already before rounding, {sm.inverted:,} of {len(sm.det):,} "
                f"tets fold (around {at}); this is a limit of SymFrames' map (its cut, transitions and "
                "constraints), not a proof that the network admits no hex mesh; here the solid has a smooth handle "
                "and no singular curve, and a grid needs corners on a boundary: a smooth solid torus, for example, "
                "needs curves around its tube (add them, or sharp edges)", report, kind="map", finer=False)
        raise _Retry(
            f"SymFrames' seamless map folds: already before rounding, {sm.inverted:,} of {len(sm.det):,} tets "
            f"fold, and {report.map_inverted} stay folded after rounding, stiffening and untangling at cell size "
            f"{cell:.4g} (around {at}); this is a limit of SymFrames' map (its cut, transitions and "
            "constraints), not a proof that the network admits no hex mesh; please report the input if a finer "
            "field folds too", report, kind="map")
    before = int(np.sum(sm.det[bad] <= 0))
    why = (f"{before} of them fold already in the seamless map, before rounding: a limit of SymFrames' map (its "
           "constraints on this tet mesh) there, not of its rounding" if before else
           "greedy rounding could not keep the curves, the surface or its thin parts apart there: a limit of "
           "SymFrames' rounding")
    raise _Retry(
        f"no valid integer-grid map at cell size {cell:.4g}: {report.map_inverted} of {len(gm.det):,} tets stay "
        f"inverted or flat after rounding, stiffening and untangling, around {at} ({why})", report,
        kind="map")
