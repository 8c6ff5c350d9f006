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
import time
from dataclasses import dataclass, field

import numpy as np

from ..solver import Cancelled, FieldProblem
from ..solver.analysis.measures import normal_adaptation
from ..solver.analysis.streamlines import FrameField
from ..solver.io.interchange import field_data
from . import display

_MESH_CACHE: dict = {}


def cached_mesh(key: str):
    return _MESH_CACHE.get("mesh") if _MESH_CACHE.get("key") == key else None


def forget_mesh() -> None:
    _MESH_CACHE.clear()


@dataclass
class Outcome:
    """What the main thread writes after a successful solve."""

    vertices: np.ndarray  # (n, 3)
    tets: np.ndarray  # (m, 4)
    quaternions: np.ndarray  # (n, 4) w x y z
    report: dict
    adaptation: np.ndarray | None = None  # (n,) radians, -1 where not measured
    network_faces: np.ndarray | None = None  # (k, 3) vertex triples
    edges: np.ndarray | None = None  # (e, 2) tet-mesh edges i -> j
    omega: np.ndarray | None = None  # (e, 3) the solver's Darboux derivative on them
    tet_curve: np.ndarray | None = None  # (m,) the curve crossing each tet, -1 elsewhere
    tet_node: np.ndarray | None = None  # (m,) tets of node regions
    network_omega: np.ndarray | None = None  # (k, 3) the prescribed Omega of the network faces
    glyphs: tuple | None = None  # (points, quaternions, errors or None, error attribute name)
    streamlines: tuple | None = None  # (lines, families)
    remeshed: bool = True


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
        t0 = time.perf_counter()
        key = inp.mesh_key()
        mesh = cached_mesh(key) if self.reuse_mesh else None
        problem = FieldProblem(inp.V, inp.F, inp.network, inp.options, progress=self._progress,
                               cancel=self._is_cancelled, mesh=mesh)
        result = problem.solve(progress=self._progress, cancel=self._is_cancelled)
        _MESH_CACHE.update(key=key, mesh=problem.mesh)
        rep = result.report
        report = {
            "summary": rep.summary(),
            "sizes": dict(rep.sizes),
            "metrics": dict(rep.metrics),
            "iterations": int(rep.lm.n_iterations) if rep.lm is not None else 0,
            "converged": bool(rep.converged) if rep.lm is not None else True,
            "status_reason": rep.status_reason,
            "repairs": [{"name": r.name, "max_displacement_h": float(r.max_displacement_h), "changed": r.changed,
                         "text": r.text()} for r in rep.repairs],
            "lm_reason": rep.lm.reason if rep.lm is not None else "",
            "seconds": float(rep.total_seconds),
            "wall_seconds": float(time.perf_counter() - t0),
            "edge_length": float(rep.edge_length),
            "remeshed": mesh is None,
        }
        adaptation, network_faces = diagnostic_data(result)
        fd = field_data(result)
        out = Outcome(result.mesh.vertices, result.mesh.tets, result.quaternions(), report, adaptation,
                      network_faces, result.mesh.edges, result.omega, fd.curve, fd.node_region,
                      fd.face_omega[result.embedding.network_faces(result.mesh)], remeshed=mesh is None)
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


def diagnostic_data(result) -> tuple[np.ndarray, np.ndarray]:
    """What the Diagnostics panel needs beyond the frames, which only the
    solve knows: the normal adaptation error per vertex (radians; -1 inside
    and at sharp feature vertices, whose frames are fixed, as in
    solver.analysis.measures.quick_metrics) and the network's faces as (k, 3) vertex
    triples."""
    mesh = result.mesh
    adaptation = np.full(mesh.n_vertices, -1.0)
    measured = ~np.asarray(result.problem.boundary.is_feature_vertex, bool)
    adaptation[mesh.boundary_vertices[measured]] = normal_adaptation(mesh, result.frames)[measured]
    return adaptation, mesh.faces[result.embedding.network_faces(mesh)]
