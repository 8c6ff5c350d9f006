"""What a solve reports: sizes, timings, the curve and corner repairs, the
LM history, and whether it converged (solution_status, local_excess,
adaptation_status)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields

import numpy as np

from .field.volume3d import LMIteration, LMReport
from .network.curve_ends import EndBend
from .network.intake import CurveRepair, repairs_text
from .surface.corners import CornerChoice, corners_text


@dataclass
class Report:
    """Sizes, timings (seconds per stage) and the solver history of a solve.

    Attributes
    ----------
    stage_seconds : dict
        Seconds per stage (``'validate'``, ``'tetmesh'``, ... ``'integrate'``).
    sizes : dict
        Counts: ``tets``, ``vertices``, ``edges`` and the meshing details.
    lm : LMReport or None
        The Levenberg-Marquardt history (§5.1).
    metrics : dict
        Measures of the field (analysis/measures.py): spurious singular
        faces, adaptation angles, ...
    edge_length : float
        The tet mesh's edge length h.
    repairs : list
        One ``CurveRepair`` per interior curve: what the intake changed.
    repair_scale : float
        The h the curves were repaired at.
    mesher : str
        The mesher that made the tet mesh, and why if not the one asked for.
    corners : list
        One ``CornerChoice`` per reported sharp corner.
    status : str
        ``'converged'`` or ``'not converged'``.
    status_reason : str
        Why (solution_status).
    notes : list of str
        What the solve changed on its way (a finer mesh where the automatic
        one left the network unresolved, and why).
    """

    stage_seconds: dict = field(default_factory=dict)
    sizes: dict = field(default_factory=dict)
    lm: LMReport | None = None
    metrics: dict = field(default_factory=dict)
    edge_length: float = 0.0
    repairs: list = field(default_factory=list)  # intake.CurveRepair per interior curve
    repair_scale: float = 0.0  # the h the curves were repaired at
    mesher: str = ""  # the mesher that made the tet mesh, and why if not the one asked for
    corners: list = field(default_factory=list)  # corners.CornerChoice per reported sharp corner
    status: str = ""  # 'converged' or 'not converged' (solution_status)
    status_reason: str = ""
    notes: list = field(default_factory=list)

    @property
    def converged(self) -> bool:
        return self.status == "converged"

    @property
    def total_seconds(self) -> float:
        return float(sum(self.stage_seconds.values()))

    def summary(self) -> str:
        lines = [f"tets {self.sizes.get('tets', 0):,}  vertices {self.sizes.get('vertices', 0):,}  "
                 f"edges {self.sizes.get('edges', 0):,}  (edge length {self.edge_length:.4g})"]
        if self.status:
            lines.insert(0, f"status: {self.status} ({self.status_reason})")
        lines += [f"  note: {n}" for n in self.notes]
        if self.mesher and self.mesher != "fTetWild":
            lines.append(f"  meshed by {self.mesher}")
        if self.sizes.get("graded_tets"):
            lines.append(f"  graded towards the network: {self.sizes['graded_tets']:,} tets added by bisection, "
                         f"edges down to {self.sizes['edge_length_min']:.4g}")
        if self.sizes.get("budget_retries"):
            lines.append(f"  fTetWild's mesh came out past 1.5x the tet budget or left no room under it for the "
                         f"grading: meshed {self.sizes['budget_retries']} more time(s) with a coarser bulk, the "
                         f"smallest mesh kept")
        if self.sizes.get("resolution_floor"):
            lines.append(f"  the network asked for edges down to {self.sizes['edge_length_needed']:.3g} "
                         f"(~{self.sizes['needed_tets']:,} tets): held at {self.sizes['resolution_floor']:.3g} to keep "
                         f"the tet budget or its ceiling; raise target_tets or tets_ceiling to resolve it")
        if self.sizes.get("refine_levels"):
            who = "TetGen" if self.mesher == "TetGen" else "fTetWild"
            lines.append(f"  {who} meshed {self.sizes['mesher_tets']:,} tets, refined "
                         f"{self.sizes['refine_levels']}x (each tet into 8)")
        if self.sizes.get("flat_tets"):
            left = self.sizes.get("flat_tets_left", 0)
            lines.append(f"  fTetWild left {self.sizes['flat_tets']} flat tet(s): "
                         f"{self.sizes.get('flat_moved_vertices', 0)} vertices moved off their plane"
                         + (f", {left} still flat (no move of an interior vertex improved them)" if left else ""))
        if self.sizes.get("mesher_surface_triangles"):
            lines.append(f"  the surface simplified for the mesher: {self.sizes['surface_triangles']:,} -> "
                         f"{self.sizes['mesher_surface_triangles']:,} triangles (dense input, mesh/decimate.py)")
        if self.sizes.get("snapped_vertices") is not None:
            kept = self.sizes.get("snap_kept_vertices", 0)
            lines.append(f"  boundary snapped onto the input's sharp features: {self.sizes['snapped_vertices']:,} "
                         f"vertices moved" + (f", {kept:,} left where fTetWild put them (the move was too "
                                              f"long or would have flattened a tet)" if kept else ""))
        if self.sizes.get("cleared_vertices"):
            lines.append(f"  {self.sizes['cleared_vertices']:,} interior vertices moved off the curves (no tet "
                         "vertex or edge on a curve, mesh/clearance.py)")
        rep = repairs_text(self.repairs, self.repair_scale)
        if rep:
            lines.append(rep)
        rep = corners_text(self.corners)
        if rep:
            lines.append(rep)
        for k, v in self.stage_seconds.items():
            lines.append(f"  {k:<12s} {v:8.2f} s")
        lines.append(f"  {'total':<12s} {self.total_seconds:8.2f} s")
        if self.lm is not None:
            f = self.lm.final
            lines.append(f"LM ({self.lm.init} start): {self.lm.n_iterations} iterations, {self.lm.cg_iterations} CG "
                         f"steps, energy {f.energy:.6g} (smoothness {f.smoothness:.6g}, penalty {f.penalty:.3g}); "
                         f"{self.lm.reason}")
        for k, v in self.metrics.items():
            lines.append(f"  {k}: {v:.4g}" if isinstance(v, float) else f"  {k}: {v}")
        return "\n".join(lines)

    def singular_face_counts(self) -> dict:
        """The singular faces a solve headlines: those of the field's own
        (omega-aware) matchings, which the exports write.

        Returns
        -------
        dict
            ``singular``, ``spurious`` (off the network), ``missing``
            (prescribed faces that are not singular) and ``closest_differs``
            (faces closest-rotation matching reads otherwise), all int; 0
            where the metrics hold no count.
        """
        m = self.metrics
        return {"singular": int(m.get("omega_singular_faces", 0)),
                "spurious": int(m.get("omega_spurious_singular_faces", 0)),
                "missing": int(m.get("omega_missing_singular_faces", 0)),
                "closest_differs": int(m.get("matching_disagreements", 0))}

    def to_dict(self) -> dict:
        """The report as JSON types, the form a result file and the add-on keep.

        Returns
        -------
        dict
            Every field, the notes included (``lm`` left out when there was
            no LM run; the curve repairs, corners and LM iterations as dicts
            of their fields), plus ``converged`` for readers of the file.
            ``Report.from_dict`` reads it back.
        """
        d = {"stage_seconds": self.stage_seconds, "sizes": self.sizes, "metrics": self.metrics,
             "edge_length": self.edge_length, "repairs": [asdict(r) for r in self.repairs],
             "repair_scale": self.repair_scale, "mesher": self.mesher,
             "corners": [asdict(c) for c in self.corners], "status": self.status, "converged": self.converged,
             "status_reason": self.status_reason, "notes": list(self.notes)}
        if self.lm is not None:
            d["lm"] = asdict(self.lm)
        return _plain(d)

    @classmethod
    def from_dict(cls, d: dict) -> Report:
        """The Report that ``to_dict`` (possibly through JSON) wrote.

        Parameters
        ----------
        d : dict
            ``Report.to_dict()``'s output; keys it does not write (a result
            file's ``options``) and the derived ``converged`` are ignored.

        Returns
        -------
        Report
        """
        lm = d.get("lm")
        if lm is not None:
            lm = LMReport(**{**lm, "iterations": [LMIteration(**it) for it in lm.get("iterations", [])]})
        repairs = [CurveRepair(**{**r, "ends": [EndBend(**{**b, "position": tuple(b.get("position", ()))})
                                                for b in r.get("ends", [])],
                                  "joined": [tuple(j) for j in r.get("joined", [])]})
                   for r in d.get("repairs", [])]
        corners = [CornerChoice(**{**c, **{k: tuple(c[k]) for k in ("position", "sector_deg", "quarters")}})
                   for c in d.get("corners", [])]
        known = {f.name for f in fields(cls)} - {"lm", "repairs", "corners"}
        return cls(lm=lm, repairs=repairs, corners=corners, **{k: v for k, v in d.items() if k in known})


def _plain(x):
    """x with numpy scalars and arrays as Python numbers and lists, tuples
    as lists: what JSON writes and reads back."""
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple, np.ndarray)):
        return [_plain(v) for v in x]
    if isinstance(x, np.generic):
        return x.item()
    return x


# A solve is "converged" when LM met its stopping rule and the structure
# penalty of Eq. 23 sits at the discretisation level: at most
# PENALTY_ABS + PENALTY_REL * smoothness.  Calibration (default meshes of
# the built-in examples): cube 3e-26, cylinder 0.002, ball 0.16, plate
# ~0.1, against smoothness 0-120; the torus, whose twist the second-order
# structure equation cannot represent exactly, 13.8 at smoothness 117.6
# (an exactly integrable twisted field scores 37-65 there, README).  Runs
# that failed to embed the network (curves without tubes, folded
# boundaries) ended at 24-2180.
PENALTY_ABS = 1.0
PENALTY_REL = 0.25


def solution_status(lm: LMReport) -> tuple[str, str]:
    """('converged' | 'not converged', why) of a Levenberg-Marquardt run."""
    f = lm.final
    allowed = PENALTY_ABS + PENALTY_REL * f.smoothness
    if not lm.converged:
        why = f"Levenberg-Marquardt {lm.reason}"
        E = [it.energy for it in lm.iterations if it.accepted]
        if lm.capped and len(E) > 5 and f.penalty <= allowed:
            # the iteration cap, not a failure to resolve the network: say how
            # close it came (graded meshes around short curves end in a flat
            # valley of the energy, falling by ~1e-5 of it per iteration;
            # 16-31 iterations at 8,000 tets)
            change = (E[-6] - E[-1]) / max(abs(E[-1]), 1e-300)
            fell = f"{1.0 + change:.3g}-fold" if change > 1.0 else f"by {100.0 * change:.2g}%"
            near = ", close to a minimum but not at it" if change < 1e-3 else ""
            why += (f" with the penalty at the discretisation level ({f.penalty:.3g} <= {allowed:.3g}); the "
                    f"energy fell {fell} over the last 5 iterations{near}. Raise max_iterations (command "
                    f"line: --iterations) to finish")
        return "not converged", why
    if f.penalty > allowed:
        return "not converged", (f"the structure penalty {f.penalty:.3g} is above the discretisation level "
                                 f"({PENALTY_ABS:g} + {PENALTY_REL:g} x smoothness {f.smoothness:.3g} = "
                                 f"{allowed:.3g}): the network is not resolved or the field cannot wind as "
                                 f"prescribed; try a finer mesh")
    return "converged", f"{lm.reason}; penalty {f.penalty:.3g} <= {allowed:.3g}"


LOCAL_DEG = 10.0
"""A structure penalty above the discretisation level counts as a local
error of the discretisation, not a network left unresolved
(``local_excess``), when removing at most one face per singular curve brings
it under the level and each of those faces closes within this angle: a
quarter of the 45 degrees at which a face's matching would change.  Solved
fields' worst faces closed within 0.0-1.34 degrees (14 default solves: six
built-in examples and eight of testkit/hexnet.py's family); a cube with a spherical cavity
whose LM converged at a penalty of 9.3 against a level of 7.7 had a third of
it in one face pierced by a curve 0.2 h from its end on the cavity, closing
within 3.3 degrees, and its hex mesh met every bar (bench/RESULTS.md); a
flipped quarter turn leaves 90."""


def local_excess(lm: LMReport, face_penalty: np.ndarray, face_deg: np.ndarray, face_at: np.ndarray,
                 metrics: dict, n_singular: int) -> str | None:
    """Why a field whose LM converged with the structure penalty above the
    discretisation level (``solution_status``) is a solution all the same,
    or None: the omega-matched singular faces are exactly the network's, and
    the excess is held by at most one face per singular curve
    (``n_singular``), each closing within ``LOCAL_DEG``.

    Parameters
    ----------
    lm : LMReport
    face_penalty : (m,) float array
        each face's share of the penalty (Eq. 23)
    face_deg : (m,) float array
        each face's residual of Eq. 17 as an angle, in degrees
    face_at : (m, 3) float array
        the faces' centres, for the message
    metrics : dict
        the field's measures (quick_metrics)
    n_singular : int
        the singular curves of the network
    """
    f = lm.final
    allowed = PENALTY_ABS + PENALTY_REL * f.smoothness
    if not lm.converged or f.penalty <= allowed or not len(face_penalty):
        return None
    if metrics.get("omega_spurious_singular_faces", 1) or metrics.get("omega_missing_singular_faces", 1):
        return None
    order = np.argsort(-face_penalty)
    left = face_penalty.sum() - np.cumsum(face_penalty[order])
    k = int(np.argmax(left <= allowed)) + 1 if left[-1] <= allowed else len(order) + 1
    if k > max(n_singular, 1) or face_deg[order[:k]].max() > LOCAL_DEG:
        return None
    c = face_at[order[0]]
    faces = "one face" if k == 1 else f"{k} faces"
    return (f"{lm.reason}; penalty {f.penalty:.3g}, above the discretisation level {allowed:.3g} only through "
            f"{faces} (the worst near ({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g}), closing within "
            f"{face_deg[order[:k]].max():.2g} degrees; the rest {left[k - 1]:.3g}): a local error of the "
            f"discretisation, the omega-matched singular faces exactly the network's")


# mean adaptation a converged field stays within (degrees): solved networks
# score <= 0.6 (tangent: bent and short curves included) and <= 0.3 (normal); a
# field that cannot follow a curve (one the surface frames do not carry,
# before mesh/linking.py refused them) scored 43 with a penalty of 3e-5
ADAPTATION_DEG = 5.0


def adaptation_status(metrics: dict) -> str | None:
    """Why a field whose structure penalty passed is still not a solution:
    frames off the curves' tangents or the surface normals on average by
    more than ADAPTATION_DEG; None when they follow both."""
    for key, what in (("tangent_adaptation", "the curves' tangents"), ("normal_adaptation", "the surface normals")):
        mean = metrics.get(f"{key}_mean_deg", 0.0)
        if mean > ADAPTATION_DEG:
            return (f"the frames are {mean:.3g} degrees off {what} on average (worst "
                    f"{metrics.get(f'{key}_max_deg', mean):.3g}; a solved field stays within {ADAPTATION_DEG:g}): "
                    f"check that the network is valid (every curve meets the surface along the normal, the "
                    f"singular curves a sharp corner or a bent curve needs are there) and refine near the curves")
    return None
