"""A solve run off the main thread (no bpy here).

``SolveJob`` takes plain arrays (scene_io.Inputs and a DisplaySettings
snapshot), runs FieldProblem + solve + glyph/streamline sampling, and keeps
the latest progress message, the outcome and the error.  The compute
operator starts it in a thread and polls it from a modal timer; all writing
to the scene happens afterwards on the main thread, and only on success.
``run()`` is the same work in the calling thread (background mode, tests).

The tet mesh of the last solve is kept in memory with the fingerprint of
what it depends on, so re-solving after changing only solver settings
(penalty, iterations, start, indices) does not remesh.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from ..solver import Cancelled, FieldProblem, FrameField, Report, vertex_normal_adaptation
from ..solver.io import FieldData, field_data
from . import display

_MESH_CACHE: dict = {}


def cached_mesh(key: str):
    return _MESH_CACHE.get("mesh") if _MESH_CACHE.get("key") == key else None


@dataclass
class Outcome:
    """What the main thread writes after a successful solve."""

    field: FieldData  # tet mesh, frames, omega, per-tet markers, prescribed Omega
    quaternions: np.ndarray  # (#V, 4) w x y z
    adaptation: np.ndarray  # (#V,) solver.vertex_normal_adaptation: radians, -1 where not measured
    network_faces: np.ndarray  # (k,) ids of the faces the network passes through
    report: Report
    remeshed: bool = True
    glyphs: tuple | None = None  # (points, quaternions, errors or None, error attribute name)
    streamlines: tuple | None = None  # (lines, families)


@dataclass
class SolveJob:
    inputs: object  # scene_io.Inputs
    display: display.DisplaySettings
    want_glyphs: bool = True
    want_streamlines: bool = False
    reuse_mesh: bool = True
    echo: bool = False  # print each stage (background mode)
    stage: str = ""
    fraction: float = 0.0
    message: str = "starting"
    outcome: Outcome | None = None
    error: BaseException | None = None
    cancelled: bool = False
    _cancel: threading.Event = field(default_factory=threading.Event)
    _thread: threading.Thread | None = None

    # --------------------------------------------------------------- control
    def start(self) -> None:
        self._thread = threading.Thread(target=self.run, name="SymFrames solve", daemon=True)
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
        """Solve and sample; sets outcome, or error, or cancelled.  Never raises."""
        try:
            self.outcome = self._work()
        except Cancelled:
            self.cancelled = True
        except BaseException as e:  # noqa: BLE001 -- handed to the main thread
            self.error = e

    def _work(self) -> Outcome:
        inp = self.inputs
        key = inp.mesh_key()
        mesh = cached_mesh(key) if self.reuse_mesh else None
        problem = FieldProblem(inp.V, inp.F, inp.network, inp.options, progress=self._progress,
                               cancel=self._is_cancelled, mesh=mesh)
        result = problem.solve(progress=self._progress, cancel=self._is_cancelled)
        _MESH_CACHE.update(key=key, mesh=problem.meshed)  # with its edge length and how it was made
        adaptation = vertex_normal_adaptation(result)
        network_faces = result.embedding.network_faces(result.mesh)
        out = Outcome(field_data(result), result.quaternions(), adaptation, network_faces, result.report,
                      remeshed=mesh is None)
        if self.want_glyphs or self.want_streamlines:
            self._progress("display", 0.97, "sampling glyphs and streamlines")
            f = FrameField.from_result(result)
            if self.want_glyphs:
                mono = None
                if self.display.colour == "MONODROMY":
                    mono = display.vertex_monodromy(result.mesh, result.omega, network_faces)
                attr = display.ERROR_ATTRIBUTES.get(self.display.colour, display.ERROR_ATTRIBUTES["ADAPTATION"])
                out.glyphs = (*display.glyph_samples(f, self.display, adaptation, mono), attr)
            if self._is_cancelled():
                raise Cancelled()
            if self.want_streamlines:
                out.streamlines = display.streamlines(f, self.display, self._is_cancelled)
        if self._is_cancelled():
            raise Cancelled()
        return out

