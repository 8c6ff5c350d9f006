"""Work run off the main thread (no bpy here): a solve, or a hex mesh.

A ``Job`` takes plain arrays, runs in a worker thread and keeps the latest
progress message, the outcome and the error; the operators start it and
poll it from a modal timer.  All writing to the scene happens afterwards on
the main thread, and only on success.  ``run()`` is the same work in the
calling thread (background mode, tests).

* ``SolveJob``: FieldProblem + solve + glyph/streamline sampling.
* ``HexJob``: solver.hexmesh of a solved field (solver.SolvedField: the
  scene's stored field, read back whole from the .blend).  Where the map
  fails on it (a limit of SymFrames, such as two nodes closer than the
  field's mesh resolves) and the resolution is Auto, the field is solved
  again finer (solver.solve_finer, as ``python -m solver --hex`` does) and
  that field is meshed and then stored in place of the first.
* ``SuggestJob``: solver.suggest_network of the domain's surface.

Kept in memory beside the scene, each with what it depends on:

* the tet mesh of the last solve, with the fingerprint of its inputs, so
  re-solving after changing only solver settings (penalty, iterations,
  start, indices) does not remesh;
* the last HexMesh, under the id written on its object, so that the export
  writes it in full precision with its integer-grid map.
"""

from __future__ import annotations

import threading
import uuid
from dataclasses import dataclass, field

import numpy as np

from ..solver import (
    Cancelled,
    FieldProblem,
    FrameField,
    HexMesh,
    HexMeshError,
    HexOptions,
    Report,
    SolvedField,
    SymFramesError,
    hexmesh,
    solve_finer,
    solve_resolved,
    suggest_network,
    vertex_normal_adaptation,
)
from . import display

_MESH_CACHE: dict = {}
_HEX_CACHE: dict = {}


def cached_mesh(key: str):
    return _MESH_CACHE.get("mesh") if _MESH_CACHE.get("key") == key else None


def new_id() -> str:
    """An id for a result kept in memory and written on its datablock."""
    return uuid.uuid4().hex


def forget_results() -> None:
    """Drop the kept HexMesh (Clear Results: it is large); the tet mesh
    stays, as re-solving the same inputs reuses it."""
    _HEX_CACHE.clear()


def remember_hex(hex_id: str, hex_mesh: HexMesh) -> None:
    _HEX_CACHE.clear()
    _HEX_CACHE.update(id=hex_id, hex=hex_mesh)


def cached_hex(hex_id: str | None) -> HexMesh | None:
    """The HexMesh written under hex_id, if it is the one kept, else None."""
    return _HEX_CACHE.get("hex") if hex_id and _HEX_CACHE.get("id") == hex_id else None


@dataclass(kw_only=True)
class Job:
    """Work for a worker thread, cancellable; subclasses define _work()."""

    echo: bool = False  # print each stage (background mode)
    stage: str = ""
    fraction: float = 0.0
    message: str = "starting"
    outcome: object = None
    error: BaseException | None = None
    cancelled: bool = False
    _cancel: threading.Event = field(default_factory=threading.Event)
    _thread: threading.Thread | None = None

    # --------------------------------------------------------------- control
    def start(self) -> None:
        self._thread = threading.Thread(target=self.run, name=f"SymFrames {type(self).__name__}", daemon=True)
        self._thread.start()

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def done(self) -> bool:
        return self._thread is not None and not self._thread.is_alive()

    def join(self, timeout: float | None = None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    # ------------------------------------------------------------------ work
    def _progress(self, stage: str, fraction: float, message: str) -> None:
        # single attribute assignments: atomic under the GIL, read by the timer
        if self.echo and stage != self.stage:
            print(f"SymFrames: {stage} ({100 * fraction:.0f}%)", flush=True)
        self.stage, self.fraction, self.message = stage, float(fraction), message

    def _is_cancelled(self) -> bool:
        return self._cancel.is_set()

    def run(self) -> None:
        """Do the work; sets outcome, or error, or cancelled.  Never raises."""
        try:
            self.outcome = self._work()
        except Cancelled:
            self.cancelled = True
        except BaseException as e:  # noqa: BLE001 -- handed to the main thread
            self.error = e

    def _work(self):
        raise NotImplementedError


@dataclass
class Outcome:
    """What the main thread writes after a successful solve."""

    field: SolvedField  # the solved field, kept whole in the .blend
    adaptation: np.ndarray  # (#V,) solver.vertex_normal_adaptation: radians, -1 where not measured
    report: Report
    remeshed: bool = True
    glyphs: tuple | None = None  # (points, quaternions, errors or None, error attribute name)
    streamlines: tuple | None = None  # (lines, families)
    inputs_key: str = ""  # scene_io.Inputs.field_key() of the inputs solved
    inputs_parts: str = ""  # scene_io.Inputs.field_parts() of the same (what Hex Mesh names when they change)


@dataclass
class SolveJob(Job):
    inputs: object  # scene_io.Inputs
    display: display.DisplaySettings
    want_glyphs: bool = True
    want_streamlines: bool = False
    reuse_mesh: bool = True

    def _work(self) -> Outcome:
        inp = self.inputs
        key = inp.mesh_key()
        mesh = cached_mesh(key) if self.reuse_mesh else None
        problem = FieldProblem(inp.V, inp.F, inp.network, inp.options, progress=self._progress,
                               cancel=self._is_cancelled, mesh=mesh)
        result = solve_resolved(problem, progress=self._progress, cancel=self._is_cancelled)
        _MESH_CACHE.update(key=key, mesh=problem.meshed)  # with its edge length and how it was made
        return field_outcome(self, result, inp, self.display, self.want_glyphs, self.want_streamlines,
                             remeshed=mesh is None)


def field_outcome(j: Job, result, inp, ds: display.DisplaySettings, want_glyphs: bool, want_streamlines: bool,
                  remeshed: bool) -> Outcome:
    """The Outcome of a solved ``result`` (a solver.Result) of the inputs
    ``inp``, with glyphs and streamlines sampled as ``ds`` says, in job j's
    thread (its progress and cancel)."""
    solved = result.field
    adaptation = vertex_normal_adaptation(solved)
    out = Outcome(solved, adaptation, result.report, remeshed=remeshed, inputs_key=inp.field_key(),
                  inputs_parts=inp.field_parts())
    if want_glyphs or want_streamlines:
        j._progress("display", 0.97, "sampling glyphs and streamlines")
        f = FrameField.from_field(solved)
        if want_glyphs:
            mono = None
            if ds.colour == "MONODROMY":
                mono = display.vertex_monodromy(solved.mesh, solved.omega, solved.embedding.network_faces(solved.mesh))
            attr = display.ERROR_ATTRIBUTES.get(ds.colour, display.ERROR_ATTRIBUTES["ADAPTATION"])
            out.glyphs = (*display.glyph_samples(f, ds, adaptation, mono), attr)
        if j._is_cancelled():
            raise Cancelled()
        if want_streamlines:
            out.streamlines = display.streamlines(f, ds, j._is_cancelled)
    if j._is_cancelled():
        raise Cancelled()
    return out


@dataclass
class HexOutcome:
    """What the main thread writes after a hex-meshing run."""

    hex_mesh: HexMesh
    hex_id: str
    resolved: Outcome | None = None  # the field solved again finer, meshed instead of the stored one
    note: str = ""  # why and how it was solved again


@dataclass
class HexJob(Job):
    source: SolvedField  # the scene's stored field (storage.solved_field)
    options: HexOptions = field(default_factory=HexOptions)  # cell size (None: about target_hexes cells), smoothing
    # the inputs the field was solved for, with the solve's display settings
    # and outputs: where the map fails and the resolution is Auto, the field
    # is solved again finer (solver.solve_finer) and meshed instead
    inputs: object = None  # scene_io.Inputs
    display: display.DisplaySettings | None = None
    want_glyphs: bool = False
    want_streamlines: bool = False

    def _work(self) -> HexOutcome:
        try:
            hm = hexmesh(self.source, options=self.options, progress=self._progress, cancel=self._is_cancelled)
        except HexMeshError as e:
            if e.kind != "map" or not e.finer or self.inputs is None:
                raise
            return self._finer(e)
        return HexOutcome(hm, new_id())

    def _finer(self, error: HexMeshError) -> HexOutcome:
        """The field solved again finer and meshed, for a map that failed
        with ``error`` on the stored field; ``error`` again, with why not,
        where it is not solved again, does not converge or fails too."""
        inp = self.inputs
        if inp.options.edge_length is not None:
            h = inp.options.edge_length
            raise HexMeshError(f"{error}. The Edge Length {h:.4g} is set by hand, so SymFrames does not solve "
                               f"finer by itself: set a smaller one (e.g. {0.7 * h:.3g}, the step solve_finer "
                               "takes) or turn Auto on, and Compute Field again", error.report, error.kind) from error
        self._progress("validate", 0.0, f"no hex mesh on this field ({error}); solving the field again finer")
        # the problem on the stored field's own tet mesh (the kept one when it
        # is that mesh: it knows the edge length it was made for)
        kept = cached_mesh(inp.mesh_key())
        same = kept is not None and np.array_equal(kept.mesh.tets, self.source.mesh.tets) and np.array_equal(
            kept.mesh.vertices, self.source.mesh.vertices)
        try:
            problem = FieldProblem(inp.V, inp.F, inp.network, inp.options, progress=self._progress,
                                   cancel=self._is_cancelled, mesh=kept if same else self.source.mesh)
            again, what = solve_finer(problem, progress=self._progress, cancel=self._is_cancelled)
        except (SymFramesError, ValueError) as e:  # Cancelled is not one: it ends the job as cancelled
            raise HexMeshError(f"{error}; not solved again finer: {e}", error.report, error.kind) from e
        if again is None or not again.report.converged:
            raise HexMeshError(f"{error}; {what}", error.report, error.kind) from error
        try:
            hm = hexmesh(again.field, options=self.options, progress=self._progress, cancel=self._is_cancelled)
        except HexMeshError as e:
            raise HexMeshError(f"{e} (on the field {what}, after the map failed on the stored one; the scene is "
                               "unchanged)", e.report, e.kind) from e
        resolved = field_outcome(self, again, inp, self.display or display.DisplaySettings(), self.want_glyphs,
                                 self.want_streamlines, remeshed=True)
        return HexOutcome(hm, new_id(), resolved=resolved,
                          note=f"the map failed on the stored field ({error}), so the field was {what}")


@dataclass
class SuggestJob(Job):
    """solver.suggest_network of the surface (V, F); outcome (network,
    report).  The suggestion takes seconds and reports no progress of its
    own: a cancel during it discards its result."""

    V: np.ndarray = None
    F: np.ndarray = None
    sharp_angle: float = 30.0

    def _work(self):
        self._progress("suggest", 0.05, "labelling the boundary as a polycube and padding it")
        out = suggest_network(self.V, self.F, sharp_angle=self.sharp_angle)
        if self._is_cancelled():
            raise Cancelled()
        self._progress("suggest", 1.0, "suggested")
        return out
