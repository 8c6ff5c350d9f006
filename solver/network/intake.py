"""Curve intake: repair the polylines users bring instead of refusing them.

Networks exported by other field tools are chains of tet-mesh edges (design
notes §5): they zig-zag (consecutive edges 20-70 degrees apart), hold
segments of 1e-6 next to normal ones and reach the surface along whatever
edge the mesh had.  Measured at the scale of one polyline vertex such a
chain "kinks" and "touches itself"; measured at the scale h of the tet mesh
that will carry the field it is a smooth curve.  So every interior curve is
cleaned and faired at a length tied to the mesh, never to the bounding box:

0. *loose node ends* and *end gaps*: ends drawn to meet at a node join it,
   ends near the surface are cut back or extended onto it, a last stretch
   running along the surface is cut (curve_ends.join_loose_ends,
   close_end_gap, cut_surface_run);
1-5. merge close points, find real corners, resample, fair and bend as
   little as the chain's own uncertainty allows, the boundary ends
   sliding along the surface (fairing.fair_curve);
6. ends still off the normal are bent onto it over a short stretch
   (curve_ends.bend_end).

Every change is reported per curve (``CurveRepair``); displacements are in
units of h.  Real crossings and self-intersections are not repaired:
validation still refuses them, now at tolerances relative to h.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..surface.intersect import segments_distance
from ..surface.trisurface import TriSurface
from .curve_ends import (
    BEND_FRACTION,
    BEND_FRACTION_ONE_END,
    END_GAP,
    EndBend,
    bend_end,
    close_end_gap,
    cut_surface_run,
    end_chord_angle,
    surface_normal_at,
)
from .fairing import fair_curve
from .network import Curve, PreparedNetwork
from .polyline import hausdorff, merge_close, resample, turning

TETS_PER_H3 = 15.0  # as mesh/resolution.py's (network/ sits below mesh/)
SLIDE_PER_TAN = 6.0  # an end slides at most this many h times the tangent of its angle to the normal ...
SHARP_CLEAR = 0.1  # ... and stays this many h off the sharp edges
FREE_SLIDE = 30.0  # ... unless fairing turns it more than this many degrees off the normal (then as a chain: an edge)
LOCAL_LEVELS = 3  # an end repair that kinks at h is redone at h / 2, h / 4, h / 8 (the mesh is refined there)
# the repair's own bar: under the kink check's MAX_KINK (45 degrees over h),
# with a margin for the mesh's sampling of the curve
REPAIR_KINK = 40.0


def solid_scale(S: TriSurface, target_tets: int = 15000) -> float:
    """The budget edge length ``(15 * volume / target_tets)^(1/3)``: the
    scale h the intake and validation use when no edge length is given (the
    pipeline's default h may be smaller where the network needs it, but it
    is computed from the network, so the network is repaired at this one)."""
    vol = float(np.sum(np.abs(S.signed_volumes())))
    return float(max((TETS_PER_H3 * vol / target_tets) ** (1.0 / 3.0), 1e-3 * S.bbox_diagonal))


@dataclass
class CurveRepair:
    """What the intake changed on one interior curve.

    curve : index in Network.curves;  points_in / points_out : sizes
    merged : points dropped as closer than MERGE * h to their neighbour
    max_displacement_h : largest distance between input and repaired curve
    turn_in_deg / turn_out_deg : largest turning over a window of h
    corners : input vertices kept as corners;  ends : EndBend list
    """

    curve: int
    name: str
    points_in: int
    points_out: int
    merged: int
    faired: bool
    max_displacement_h: float
    turn_in_deg: float
    turn_out_deg: float
    corners: int = 0
    ends: list = field(default_factory=list)
    note: str = ""
    joined: list = field(default_factory=list)  # ('start' or 'end', distance in h) of ends moved to join a node
    pieces: list = field(default_factory=list)  # input curves joined end to end into this one (more than one)
    scale_h: float = 1.0  # the local scale the curve was repaired at, in h (< 1: the mesh is finer around it)

    @property
    def changed(self) -> bool:
        return (self.max_displacement_h > 1e-6 or bool(self.ends) or self.merged > 0 or bool(self.joined)
                or len(self.pieces) > 1)

    def text(self) -> str:
        label = f"curve {self.curve}" + (f" '{self.name}'" if self.name else "")
        s = (f"{label}"
             + (f" (joined end to end from curves {', '.join(map(str, self.pieces))})" if len(self.pieces) > 1 else "")
             + f": {self.points_in} -> {self.points_out} points"
             + (f", {self.merged} merged" if self.merged else "")
             + (", faired" if self.faired else "")
             + f", moved at most {self.max_displacement_h:.2f} h, turning over h {self.turn_in_deg:.0f} -> "
               f"{self.turn_out_deg:.0f} deg")
        if self.corners:
            s += f", {self.corners} corner(s) kept"
        for end, d in self.joined:
            s += f"; {end} moved {d:.2f} h to join a node"
        for b in self.ends:
            s += "; " + b.text()
        if self.note:
            s += f"; {self.note}"
        return s


def repairs_text(repairs: list[CurveRepair], h: float) -> str:
    """Lines for the CLI and the add-on; empty when nothing changed."""
    changed = [r for r in repairs if r.changed]
    if not changed:
        return ""
    lines = [f"curve intake at h = {h:.4g}: {len(changed)} of {len(repairs)} interior curve(s) repaired"]
    lines += ["  " + r.text() for r in changed]
    return "\n".join(lines)


def _repair_without_kinks(repair_at, h: float, c: Curve):
    """The repair of curve c at scale h, or at a finer local scale where the
    repair turns faster than the kink check allows: (the scale, repair_at's
    result at it).

    A repair must never make what the kink check refuses (issue 41a): the
    check judges a singular curve over the mesh scale, and an end bent onto
    the normal on a curve a few h long can turn faster than that (a curve
    3.4 h long with its start 30 degrees off turned by 79 degrees over h).
    The kink check judges the curve as given and the repair apart: a turn at
    a corner the fairing held is the user's (validation refuses it, naming
    the corner); one the repair made is repaired again at a local scale
    h / 2, h / 4, ..., and the mesh is made that fine around the curve
    (CheckedInput.curve_scales, resolution.py); only a turn no scale down to
    h / 2**LOCAL_LEVELS removes is left to validation, which says it is the
    repair's.
    """
    hc = h
    out = repair_at(hc)
    Q, corners = out[0], out[6]
    if c.sigma == 0 or len(Q) <= 2:
        return hc, out
    for _ in range(LOCAL_LEVELS):
        k, turn = _worst_turn(Q, hc, c.closed)
        if turn <= REPAIR_KINK or _near(Q[k], corners, 0.5 * hc):
            break
        finer = repair_at(0.5 * hc)
        _, turn2 = _worst_turn(finer[0], 0.5 * hc, c.closed)
        hc *= 0.5
        out = finer
        Q, corners = out[0], out[6]
        if turn2 <= REPAIR_KINK:
            break
    if hc < h:
        Q, merged, faired, note, ends, ncorner, corners = out
        note = (note + "; " if note else "") + (
            f"repaired at a local scale {hc:.3g} = {hc / h:.2g} h (its end bend turns too fast for h; the "
            "mesh is made that fine around it)")
        out = (Q, merged, faired, note, ends, ncorner, corners)
    return hc, out


def slide_limit(S: TriSurface, P: np.ndarray, h: float) -> float:
    """How far the boundary end P[-1] may slide along the surface while its
    curve is faired: ``SLIDE_PER_TAN * h * tan`` of its chord's angle to the
    normal (an end 4 degrees off slides at most 0.42 h), within
    fairing.SLIDE_MAX times the input's uncertainty there (h/2 for a smooth
    curve, half an edge for a chain of mesh edges).  Sliding costs the field far less than
    bending (on the cube-sphere networks of testkit/hexnet.py, whose short
    radial curves reach the sphere 1-4 degrees off, ends held to 3 h tan
    were bent over most of their length and left penalties of 3-6; at
    6-10 h tan 0.3-4), but it moves the curve: before, fairing slid ends a
    few degrees off the normal by up to a whole h (issue 48)."""
    ang = np.radians(end_chord_angle(S, merge_close(P, 1e-9 * h, False), h)) if len(P) > 1 else 0.0
    return max(SLIDE_PER_TAN * h * float(np.tan(min(ang, 1.4))), 0.0)


class EndProjection:
    """Where a boundary end goes while its curve is faired: the closest
    point of the surface (``project``), or, for an end sliding from a given
    point, of that point's own patch between sharp edges, kept
    ``SHARP_CLEAR * h`` off the sharp edges (``for_ends``): an end inside a
    face stays inside it and never crosses an edge onto the next face.

    sharp : (A, B) the sharp edges' end points; patch_of : (#F,) the patch
    of each face."""

    def __init__(self, S: TriSurface, h: float, sharp: tuple | None, patch_of: np.ndarray | None):
        self.S, self.h = S, h
        self.sharp = sharp if sharp is not None and len(sharp[0]) and patch_of is not None else None
        self.patch_of = patch_of
        self._patches = {}

    def project(self, x):
        """(closest surface point, its normal)."""
        _, f, q = self.S.closest_points(x[None])
        return q[0], surface_normal_at(self.S, int(f[0]), q[0])

    def for_ends(self, starts: list):
        """A projection for the ends sliding from the points ``starts``: each
        point goes with the start it is nearest."""
        if self.sharp is None or not starts:
            return self.project
        procs = [self._on_patch(x) for x in starts]

        def proj(x):
            k = int(np.argmin([np.linalg.norm(x - s) for s in starts]))
            return self._kept_off(procs[k], x)

        return proj

    def _on_patch(self, x) -> TriSurface:
        _, f, _ = self.S.closest_points(x[None])
        p = int(self.patch_of[int(f[0])])
        if p not in self._patches:
            self._patches[p] = TriSurface(self.S.V, self.S.F[self.patch_of == p])
        return self._patches[p]

    def _kept_off(self, P: TriSurface, x):
        A, B = self.sharp
        clear = SHARP_CLEAR * self.h
        _, f, q = P.closest_points(x[None])
        q = q[0]
        y = np.repeat(q[None], len(A), axis=0)
        d, mid = segments_distance(y, y, A, B)
        k = int(np.argmin(d))
        if d[k] < clear:
            # back into the patch, square to the edge (from on the edge:
            # towards the middle of the face the end was put on)
            foot = 2.0 * mid[k] - q
            w = q - foot if d[k] > 1e-9 * self.h else P.V[P.F[int(f[0])]].mean(axis=0) - foot
            t = B[k] - A[k]
            w = w - (w @ t) / max(t @ t, 1e-300) * t
            n = float(np.linalg.norm(w))
            if n > 1e-300:
                _, f, q2 = P.closest_points((foot + (clear / n) * w)[None])
                q = q2[0]
        return q, surface_normal_at(P, int(f[0]), q)


def repair_network(S: TriSurface, pn: PreparedNetwork, h: float, names: list,
                   boundary_tolerance: float, joined: dict | None = None,
                   sharp: tuple | None = None, patch_of: np.ndarray | None = None
                   ) -> tuple[PreparedNetwork, list[CurveRepair]]:
    """Repair every prepared interior curve at scale h (module docstring).

    names[ci] : label of prepared curve ci for messages;  boundary ends
    farther than boundary_tolerance from the surface are left as they are
    (validation refuses them).  joined : join_loose_ends' moves, reported
    with the curves.  sharp : (A, B) the sharp edges' end points, and
    patch_of : (#F,) the patch of each face between them: a sliding end
    stays on its patch, ``SHARP_CLEAR * h`` off its edges (EndProjection).
    Returns the repaired network, one CurveRepair per curve and the
    IntakeScales (each curve's local scale, the input's corners held).
    """
    joined = joined or {}

    def moves(src):  # the ends moved to join a node, of the curve or of the pieces joined into it
        return [m for k in pn.pieces.get(src, [src]) for m in joined.get(k, [])]

    curves, repairs, scales, held = [], [], [], []

    onto = EndProjection(S, h, sharp, patch_of)
    project = onto.project

    for ci, c in enumerate(pn.curves):
        P0 = c.points
        kinds = (pn.start_kind[ci], pn.end_kind[ci])
        gaps = {}
        if not c.closed and len(P0) > 1:
            for end, kind in ((1, kinds[1]), (0, kinds[0])):
                if kind == "boundary":
                    R, how, d = close_end_gap(S, P0 if end == 1 else P0[::-1], h, boundary_tolerance,
                                              END_GAP * h)
                    if not how:
                        R, how, run = cut_surface_run(S, R, END_GAP * h)
                        d = run
                    if how:
                        P0 = R if end == 1 else R[::-1]
                        gaps[end] = (how, d / h)
        if len(P0) > 2 and np.any(S.winding_number(P0[1:-1]) < 0.5):
            # a curve that leaves the solid is refused as given (validation
            # names where), not pulled back in by the fairing
            repairs.append(CurveRepair(pn.source[ci], c.name, len(P0), len(P0), 0, False, 0.0, 0.0, 0.0,
                                       note="not repaired: passes outside the solid",
                                       joined=moves(pn.source[ci]),
                                       pieces=pn.pieces.get(pn.source[ci], [])))
            curves.append(c)
            scales.append(h)
            held.append(np.zeros((0, 3)))
            continue

        # the ends on the surface slide while the curve is faired, at every scale alike
        slide, limit = {}, {}
        if not c.closed and len(P0) > 1:
            for end, kind in ((0, kinds[0]), (-1, kinds[1])):
                if kind == "boundary":
                    q, nrm = project(P0[end])
                    if np.linalg.norm(q - P0[end]) <= boundary_tolerance:
                        slide[end] = nrm
                        limit[end] = slide_limit(S, P0 if end == -1 else P0[::-1], h)
        project_end = onto.for_ends([P0[e] for e in slide])

        def repair_at(hc):
            """Fair and bend the curve at the scale hc (steps 1-6)."""
            Q, merged, ell, ncorner, fixed = fair_curve(P0, hc, c.closed, slide, project_end, limit)
            if limit and max(end_chord_angle(S, Q if e == -1 else Q[::-1], hc) for e in limit) > FREE_SLIDE:
                # the fairing itself turns the end far off the normal (a
                # shape smaller than the fairing width): the end slides
                # as the curve needs, as far as fair_curve allows
                Q, merged, ell, ncorner, fixed = fair_curve(P0, hc, c.closed, slide, project_end)
            faired, note = True, ""
            # the faired curve must stay inside the solid (a curve hugging a
            # concave part of the surface could be pulled out of it)
            inner = Q[1:-1]
            if len(inner) and np.any(S.winding_number(inner) < 0.5):
                Q = np.vstack([resample(P0, 0.5 * ell)])
                faired, fixed = False, np.zeros(len(Q), bool)
                note = "not faired (fairing would leave the solid)"
            ends = []
            if not c.closed:
                for end, kind in ((1, kinds[1]), (0, kinds[0])):
                    if kind != "boundary":
                        continue
                    x = Q[-1] if end == 1 else Q[0]
                    d, _, _ = S.closest_points(x[None])
                    if d[0] > boundary_tolerance:
                        continue
                    R = Q if end == 1 else Q[::-1]
                    both = kinds[0] == "boundary" and kinds[1] == "boundary"
                    R, bend = bend_end(S, R, hc, names[ci], "end" if end == 1 else "start",
                                       BEND_FRACTION if both else BEND_FRACTION_ONE_END)
                    Q = R if end == 1 else R[::-1]
                    slid = float(np.linalg.norm(R[-1] - (P0[-1] if end == 1 else P0[0]))) / h
                    if bend is None and (slid > 1e-3 or end in gaps):
                        bend = EndBend("end" if end == 1 else "start", 0.0, 0.0, tuple(np.round(R[-1], 6)))
                    if bend is not None:
                        if end in gaps:
                            bend.gap, bend.gap_h = gaps[end]
                        P_in = merge_close(P0 if end == 1 else P0[::-1], 1e-9 * h, False)
                        bend.input_angle_deg = end_chord_angle(S, P_in, h)
                        bend.slid_h = slid
                        bend.length_h *= hc / h
                        ends.append(bend)
            return Q, merged, faired, note, ends, ncorner, _corner_points(Q, fixed, c.closed)

        hc, (Q, merged, faired, note, ends, ncorner, corners) = _repair_without_kinks(repair_at, h, c)
        scales.append(hc)
        turn_in = float(turning(merge_close(P0, 1e-9 * h, c.closed), 0.5 * h, c.closed).max()) if len(P0) > 2 else 0.0
        turn_out = float(turning(Q, 0.5 * h, c.closed).max()) if len(Q) > 2 else 0.0
        disp = hausdorff(P0, Q, 0.05 * h) / h
        curves.append(Curve(Q, c.sigma, c.role, c.torsion, c.name, c.closed))
        repairs.append(CurveRepair(pn.source[ci], c.name, len(P0), len(Q), merged, faired, disp, turn_in, turn_out,
                                   ncorner, ends[::-1], note, moves(pn.source[ci]),
                                   pn.pieces.get(pn.source[ci], []), hc / h))
        held.append(corners)
    out = PreparedNetwork(curves, list(pn.source), list(pn.start_kind), list(pn.end_kind), pn.nodes, pn.pieces)
    return out, repairs, IntakeScales(np.array(scales, float), held)


@dataclass
class IntakeScales:
    """Per prepared curve: the scale it was repaired and is checked at
    (the intake's h, or finer where an end bend needed it), and the input's
    corners the fairing held ((k, 3) each), which the kink check names as
    the user's."""

    scales: np.ndarray
    corners: list


def _worst_turn(Q: np.ndarray, hc: float, closed: bool) -> tuple[int, float]:
    """Where and by how much (degrees) Q turns most over hc (the kink check's
    measure: chords of hc / 2 on either side)."""
    ang = turning(Q, 0.5 * hc, closed)
    k = int(np.argmax(ang))
    return k, float(ang[k])


def _corner_points(Q: np.ndarray, fixed: np.ndarray, closed: bool) -> np.ndarray:
    """(k, 3) the corners the fairing held (fixed points but the ends)."""
    f = np.asarray(fixed, bool).copy()
    if len(f) != len(Q):
        return np.zeros((0, 3))
    if not closed:
        f[[0, -1]] = False
    return Q[f]


def _near(x: np.ndarray, P: np.ndarray, r: float) -> bool:
    return bool(len(P)) and float(np.min(np.linalg.norm(P - x, axis=1))) <= r
