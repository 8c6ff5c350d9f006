"""The tet mesh of a solve (§5.1): which mesher, at what edge length, how
many refinements, and what the mesh must keep.

``mesh_domain`` is the mesh stage of the pipeline.  Its policy, in order:

* **Mesher.**  TetGen (cdt.py) where it is asked for, or where 'auto' finds
  it installed, the network without singular curves and the surface no
  denser than an h-mesh of it (cdt.wants_tetgen); fTetWild (tetwild.py)
  otherwise, with the curve tubes (tubes.py).  Where TetGen fails, or
  overshoots the tet budget around the surface's small triangles,
  fTetWild meshes instead and ``MeshStats.mesher`` says why.
* **Refinement.**  fTetWild meshes at H = h 2**k and k red refinements
  (refine.py) bring it to h; k is ``MeshSettings.refine`` or chosen
  (``refine_levels``) so that fTetWild's mesh keeps >= ~6k tets and >= 3
  edges along the shortest curve.
* **Topology.**  A mesh whose boundary differs topologically from the
  input (a pinch or a handle where tubes pass close to the surface) is
  made one level finer when k was chosen automatically, else refused.
* **Budget.**  With the edge length automatic, a mesh past 1.5x the tet
  budget, or one that leaves no room under it for the grading, is made
  again with a coarser bulk (at most twice); the smallest mesh made is
  kept.
* **Features and grading.**  The boundary is snapped back onto the input's
  sharp features (snapping.py), then refined, then graded towards the
  network by bisection (bisection.py) as the resolution plan asks.

The outcome is a ``MeshOutcome``: the mesh, the edge length it was made for
and how it was made (``MeshStats``), which the report quotes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import MeshingError
from ..network.network import PreparedNetwork
from ..network.validation import CheckedInput
from ..surface.trisurface import TriSurface
from . import cdt
from .bisection import bisect
from .clearance import clear_curve_ends, clear_curves
from .decimate import Simplified, simplify_for_meshing
from .refine import red_refine
from .resolution import TETS_PER_H3, Plan, solid_volume
from .slivers import FlatRepair
from .snapping import SnapStats, snap_to_features
from .tetmesh import TetMesh
from .tetwild import tetrahedralize_repaired
from .tubes import build_tubes


@dataclass(frozen=True)
class MeshSettings:
    """What the mesh stage takes from the solve's options (pipeline.Options).

    Parameters
    ----------
    mesher : str
        'auto', 'TetGen' or 'fTetWild'.
    refine : int or None
        Red-refinement levels; None chooses them (``refine_levels``).
    budget : int or None
        The tet budget the mesh keeps within 1.5x of; None when the edge
        length was given (no budget, no grading).
    tube_radius : float
        Curve tube radius, relative to the edge length fTetWild meshes at.
    node_radius : float
        Node region radius, relative to the edge length.
    epsilon : float
        fTetWild's envelope, relative to the bounding-box diagonal.
    snap_features : bool
        Move the boundary back onto the input's sharp features.
    """

    mesher: str = "auto"
    refine: int | None = None
    budget: int | None = None
    tube_radius: float = 0.35
    node_radius: float = 1.5
    epsilon: float = 1e-3
    snap_features: bool = True


@dataclass(frozen=True)
class MeshStats:
    """How a tet mesh was made, as the report quotes it.

    Parameters
    ----------
    mesher : str
        'TetGen', 'fTetWild', or 'fTetWild (why TetGen did not mesh)'; ''
        for a mesh made elsewhere.
    mesher_tets : int or None
        Tets the mesher made before red refinement; None when the mesh was
        not refined (then: as many as the mesh has).
    refine_levels : int
        Red refinements after meshing (each tet into 8).
    budget_retries : int
        Times fTetWild meshed again with a coarser bulk to keep the budget.
    graded_tets : int
        Tets added by bisection towards the network.
    flat : slivers.FlatRepair or None
        fTetWild's flat tets and their repair (None for TetGen).
    snap : snapping.SnapStats or None
        The snap onto the sharp features (None where it was not asked for).
    simplified : tuple of int or None
        (input triangles, triangles the mesher got) where a dense surface
        was simplified first (decimate.py), else None.
    cleared : int
        Surface vertices moved off the curve ends for the mesher
        (clearance.py).
    cleared_inside : int
        Interior vertices moved off the curves after meshing
        (clearance.clear_curves).
    """

    mesher: str = ""
    mesher_tets: int | None = None
    refine_levels: int = 0
    budget_retries: int = 0
    graded_tets: int = 0
    cleared: int = 0
    cleared_inside: int = 0
    flat: FlatRepair | None = None
    snap: SnapStats | None = field(default=None, compare=False)
    simplified: tuple | None = None


@dataclass(frozen=True)
class MeshOutcome:
    """The mesh stage's result.

    Parameters
    ----------
    mesh : TetMesh
        The tet mesh, #V vertices and #T tets.
    h : float
        The bulk edge length it was made for (coarser than planned when the
        budget asked for it).
    stats : MeshStats
        How it was made.
    """

    mesh: TetMesh
    h: float
    stats: MeshStats = MeshStats()

    def sizes(self, plan: Plan) -> dict:
        """The report's mesh entries (Report.sizes): refinement, the
        estimate, grading, budget retries, the resolution floor, flat tets
        and the snap, each where it applies.

        Parameters
        ----------
        plan : resolution.Plan
            The plan the mesh was made for (the estimate, the floor).

        Returns
        -------
        dict of str to int or float
        """
        st, mesh = self.stats, self.mesh
        out = {"refine_levels": st.refine_levels,
               "mesher_tets": st.mesher_tets if st.mesher_tets is not None else mesh.n_tets,
               "estimated_tets": int(round(plan.tets))}
        if st.budget_retries:
            out["budget_retries"] = st.budget_retries
        if st.graded_tets:
            out["graded_tets"] = st.graded_tets
            out["edge_length_min"] = float(plan.finest)
        if plan.floor > 0:
            out["resolution_floor"] = plan.floor
            out["edge_length_needed"] = plan.need_min
            out["needed_tets"] = int(round(plan.needed_tets))
        if st.flat is not None and st.flat.flat_tets:
            out["flat_tets"] = st.flat.flat_tets
            out["flat_tets_left"] = st.flat.flat_tets_left
            out["flat_moved_vertices"] = st.flat.moved_vertices
        if st.simplified is not None:
            out["surface_triangles"], out["mesher_surface_triangles"] = st.simplified
        if st.snap is not None:
            out["snapped_vertices"] = st.snap.moved
            out["snap_kept_vertices"] = int(len(st.snap.kept))
        if st.cleared_inside:
            out["cleared_vertices"] = st.cleared_inside
        return out


@dataclass
class _Made:
    """One mesh made at an edge length: what the retries compare."""

    mesh: TetMesh
    h: float
    k: int  # refinement levels still to apply
    H: float  # the edge length meshed at, h 2**k
    problem: str | None  # how its boundary's topology differs, or None
    mesher: str
    flat: FlatRepair | None
    tetgen_off: str  # why TetGen did not mesh (then it is not asked again)


def mesh_domain(checked: CheckedInput, plan: Plan, settings: MeshSettings, cancel=None, say=None) -> MeshOutcome:
    """The tet mesh of a checked input for a resolution plan (module docs).

    Parameters
    ----------
    checked : network.validation.CheckedInput
        The surface, its sharp features and the prepared network.
    plan : resolution.Plan
        The bulk edge length and, on a graded mesh, the sizing field.
    settings : MeshSettings
    cancel : callable() -> bool, or None
        Passed to the mesher's child process.
    say : callable(str), or None
        Progress messages (the surface simplified for the mesher, issue 41e).

    Returns
    -------
    MeshOutcome

    Raises
    ------
    MeshingError
        When the mesh's boundary lost the surface's topology and no finer
        level is left to try, or when no mesher could mesh the surface.
    """
    h = plan.edge_length
    # the budget holds for the mesh fTetWild makes, not only for the
    # estimate: curve tubes make it refine locally beyond 15 tets/h^3
    # (the ball with an inner cube 0.03 across: 8.9k-9.4k tets where the
    # plan expected 3,000 for the bulk of a 6,000 budget)
    cap = None if settings.budget is None else 1.5 * settings.budget
    room = plan.graded_tets if plan.graded else 0.0
    made: list[tuple[float, _Made]] = []  # (tets once refined, mesh) of each mesh kept as a candidate
    tetgen_off = ""  # why TetGen, asked for, did not mesh (then fTetWild did)
    retries = 0
    # a surface far denser than the mesh is brought down to it first
    # (decimate.py): fTetWild's time grows with its input's triangles
    simplified = simplify_for_meshing(checked.surface, h, say, checked.features,
                                      settings.epsilon * checked.surface.bbox_diagonal)
    domain, cleared = _cleared_domain(checked, simplified, h)
    if cleared and say is not None:
        say(f"tetmesh: {cleared} surface vertices moved off the curve ends for the mesher (clearance.py)")
    for attempt in range(3):
        m = _mesh_at(checked, settings, h, tetgen_off, cancel, simplified, domain)
        tetgen_off = m.tetgen_off
        n = m.mesh.n_tets * 8.0**m.k
        if m.problem is not None:
            break
        if cap is not None and m.mesher == "TetGen" and n > cap:
            # TetGen keeps the input's triangles and refines around the
            # small or thin ones whatever h is (a box with 1,728 thin
            # triangles: 3.4k tets at 1.8 h after the overshoot at h,
            # where fTetWild made 9.1k at h), so fTetWild meshes instead
            tetgen_off = (f"TetGen made {int(n):,} tets, past 1.5x the budget, around the surface's small or "
                          "thin triangles")
            continue
        made.append((n, m))
        # TetGen has no tubes: a coarser h would not make room
        if cap is None or n <= cap - room or m.mesher == "TetGen" or attempt == 2:
            break
        if len(made) > 1 and _held_by_tubes(made[-2], made[-1]):
            break
        # past the cap: aim at the budget; else just make room
        aim = settings.budget if n > cap else cap - room
        h *= (n / aim) ** (1.0 / 3.0)
        retries += 1
    if retries and (m.problem is not None or made[-1][0] > cap - room):
        # fTetWild's count around the tubes varies from run to run (the
        # ball with an inner cube 0.03 across: 6.2k tets, then 9.0k at a
        # coarser h), and a coarser mesh may lose the boundary's topology:
        # keep the best mesh made
        m = min(made, key=lambda c: c[0])[1]
    elif made:
        m = made[-1][1]
    if m.problem is not None:
        hint = (f"Try a smaller edge length (now {m.h:.4g})" if m.k == 0 else
                f"fTetWild meshed at {m.H:.4g} before {m.k} refinement level(s): try refine={m.k - 1}")
        raise MeshingError(f"the tet mesh's boundary {m.problem}; a thin part was lost, a cavity appeared or "
                           f"curve tubes too close to the surface merged with it. {hint}")
    return _finish(checked, plan, settings, m, retries, simplified, cleared)


def _held_by_tubes(before: tuple[float, _Made], after: tuple[float, _Made]) -> bool:
    """Whether a coarser bulk lowered the tet count by less than half of
    what it would have lowered a mesh of bulk alone (n h^3 constant): then
    the count is held by fTetWild's refinement around the curve tubes, and a
    coarser bulk again would not make room either.  (The ball with an inner
    cube 0.1 across at a 6,000 budget: 8.7k tets at h, then as many at 1.03 h
    and at 1.06 h, 7 s of fTetWild each.)"""
    (n0, m0), (n1, m1) = before, after
    expected = n0 * (1.0 - (m0.H / m1.H) ** 3)
    return n0 - n1 < 0.5 * expected


def _cleared_domain(checked: CheckedInput, simplified: Simplified | None, h: float) -> tuple[TriSurface, int]:
    """The surface the mesher meshes: the input or its simplification, with
    the curve ends off its vertices and edges (clearance.py)."""
    net = checked.network
    ends = [c.points[k] for i, c in enumerate(net.curves) if not c.closed
            for k, kind in ((0, net.start_kind[i]), (-1, net.end_kind[i])) if kind == "boundary"]
    if simplified is not None:
        return clear_curve_ends(simplified.surface, np.array(ends), h)
    fixed = checked.features.degree > 0 if np.any(checked.features.sharp) else None
    return clear_curve_ends(checked.surface, np.array(ends), h, fixed)


def _finish(checked: CheckedInput, plan: Plan, settings: MeshSettings, m: _Made, retries: int,
            simplified: Simplified | None = None, cleared: int = 0) -> MeshOutcome:
    """Snap, refine and grade the mesh kept."""
    mesh, snap = m.mesh, None
    if settings.snap_features:
        snapped, stats = snap_to_features(mesh, checked.features)
        # a snap is reported where one was made: the input has sharp edges
        # and they could be mapped onto the mesh (else the mesh comes back)
        mesh, snap = snapped, (stats if snapped is not mesh else None)
    mesher_tets = mesh.n_tets if m.k else None
    for _ in range(m.k):
        mesh = red_refine(mesh, checked.surface).fine
    graded = 0
    if plan.graded:
        mesh, graded = grade(mesh, plan, settings.budget, checked.surface)
    # no tet vertex or edge on a curve: the last step, on the final vertices
    net = checked.network
    r_node = node_radius(net, m.h, settings.node_radius)
    mesh, inside = clear_curves(mesh, [c.points for c in net.curves],
                                [(nd.position, 0.5 * r_node) for nd in net.nodes])
    stats = MeshStats(mesher=m.mesher, mesher_tets=mesher_tets, refine_levels=m.k, budget_retries=retries,
                      graded_tets=graded, flat=m.flat, snap=snap,
                      simplified=None if simplified is None else (simplified.faces_in, simplified.faces_out),
                      cleared=cleared, cleared_inside=inside)
    return MeshOutcome(mesh, m.h, stats)


def _mesh_at(checked: CheckedInput, settings: MeshSettings, h: float, tetgen_off: str, cancel,
             simplified: Simplified | None = None, domain: TriSurface | None = None) -> _Made:
    """A mesh for a final edge length h.  With mesher 'TetGen' the surface
    alone is meshed at h (no tubes: embed.py traces the curves through any
    mesh); where TetGen fails (or ``tetgen_off`` says why it may not),
    fTetWild meshes, coarser by the refinement levels, one level finer
    each time the boundary's topology comes out wrong.  simplified: the
    dense input brought down to the mesh scale (decimate.py), which the
    mesher gets instead of the input surface; domain: the surface the
    mesher gets, where given (the curve ends cleared, clearance.py)."""
    if domain is None:
        domain = simplified.surface if simplified is not None else checked.surface
    mesher = settings.mesher
    if mesher == "auto":
        singular = any(c.sigma != 0 for c in checked.network.curves)
        mesher = "TetGen" if cdt.wants_tetgen(checked.surface, h, singular) else "fTetWild"
    if mesher == "TetGen" and not tetgen_off:
        # no automatic red refinement: TetGen's time grows with its output
        # no faster than refinement's (refine_levels is for fTetWild)
        k = int(settings.refine or 0)
        try:
            mesh = cdt.tetrahedralize_cdt(domain, h * 2.0**k, cancel)
        except MeshingError as e:
            tetgen_off = f"TetGen failed: {e}"
        else:
            problem = topology_change(checked.surface, mesh)
            if problem is None:
                return _Made(mesh, h, k, h * 2.0**k, None, "TetGen", None, "")
            # (a cavity TetGen filled, a thin part it lost): fTetWild meshes the solid instead
            tetgen_off = f"TetGen's mesh boundary {problem}"
    name = "fTetWild" + (f" ({tetgen_off})" if tetgen_off else "")
    k = refine_levels(checked, settings.refine, h)
    while True:
        H = h * 2.0**k
        r = settings.tube_radius * H
        # caps stay on the surface only where it is flat: well inside
        # fTetWild's envelope (tubes.py)
        flat = 0.01 * settings.epsilon * checked.surface.bbox_diagonal
        tubes = build_tubes(checked.network, checked.surface, r, r * np.sqrt(3.0),
                            node_radius(checked.network, H, settings.node_radius), flat)
        mesh, repair = tetrahedralize_repaired(domain, H, (tubes.V, tubes.F), settings.epsilon, cancel,
                                               sharp=bool(np.any(checked.features.sharp)))
        problem = topology_change(checked.surface, mesh)
        if problem is None or k == 0 or settings.refine is not None:
            return _Made(mesh, h, k, H, problem, name, repair, tetgen_off)
        k -= 1


def refine_levels(checked: CheckedInput, refine: int | None, h: float) -> int:
    """Red-refinement levels for a final edge length h: ``refine`` when
    given, else 0-2, as many as keep fTetWild's mesh at >= ~6k tets and
    its edge within a third of the network's feature size.

    Parameters
    ----------
    checked : network.validation.CheckedInput
        The solid (its volume) and the network's feature size.
    refine : int or None
        MeshSettings.refine.
    h : float
        The final edge length.

    Returns
    -------
    int
    """
    if refine is not None:
        return int(refine)
    est = TETS_PER_H3 * solid_volume(checked.surface) / h**3
    k = 0
    while (k < 2 and est / 8.0 ** (k + 1) >= 6000.0
           and h * 2.0 ** (k + 1) <= checked.feature_size / 3.0):
        k += 1
    return k


def grade(mesh: TetMesh, plan: Plan, budget: int, surface: TriSurface) -> tuple[TetMesh, int]:
    """Bisect the tets longer than 1.5x the plan's sizing field at their
    centroid (fTetWild's longest edges are ~1.2 h), pass after pass,
    keeping within 1.5x the tet budget.

    Returns
    -------
    mesh : TetMesh
        The graded mesh.
    added : int
        Tets the grading added.
    """
    cap = int(1.5 * budget)
    n0 = mesh.n_tets
    for _ in range(60):
        X = mesh.vertices[mesh.tets]
        longest = np.max(np.linalg.norm(X[:, [0, 0, 0, 1, 1, 2]] - X[:, [1, 2, 3, 2, 3, 3]], axis=2), axis=1)
        ratio = longest / (1.5 * plan.sizing(X.mean(axis=1)))
        mark = ratio > 1.0
        if not np.any(mark):
            break
        room = (cap - mesh.n_tets) // 3  # a cut tet and its closure: ~3 more tets
        finer = None
        while room > 0:
            if mark.sum() > room:
                mark = np.zeros(len(mark), bool)
                mark[np.argsort(-ratio)[:room]] = True
            finer = bisect(mesh, mark, surface)
            if finer.n_tets <= cap:
                break
            # the closure cut more than ~3 per tet: fewer tets, or none
            finer, room = None, room // 2
        if finer is None:
            break
        mesh = finer
    return mesh, mesh.n_tets - n0


def topology_change(surface: TriSurface, mesh: TetMesh) -> str | None:
    """How the boundary of mesh differs topologically from the surface.

    Parameters
    ----------
    surface : TriSurface
        The input surface.
    mesh : TetMesh

    Returns
    -------
    str or None
        What differs (components, manifoldness, Euler characteristic), as
        the end of a sentence about the mesh's boundary; None if nothing.
    """
    B = mesh.boundary
    if B.n_components != surface.n_components:
        return f"has {B.n_components} components but the surface has {surface.n_components}"
    _, _, cnt = B._edge_data
    if np.any(cnt != 2):
        return f"is not manifold ({int(np.sum(cnt != 2))} edges with more than two faces)"
    chi_in, chi_out = int(np.sum(surface.euler_characteristics())), int(np.sum(B.euler_characteristics()))
    if chi_in != chi_out:
        return f"has Euler characteristic {chi_out} but the surface has {chi_in}"
    return None


def node_radius(network: PreparedNetwork, h: float, factor: float) -> float:
    """The radius of the node regions at edge length h: the bulk edge
    length, also where a graded mesh is finer around the nodes.  The curves'
    tubes stop there (``build_tubes``), and so must the tube constraints: a
    region sized by the finer edge length left a stretch of curve between
    it and the tube whose tets were constrained to turn about the curve
    alone, where the node's other curves still turn the field (on a
    generated cube with a cavity: penalty 46.7 against a level of 10.8 at 21k graded
    tets, the frames along the curves 17-35 degrees off them; with the
    regions at the bulk edge length, 1.58 and 1.50 on two fresh meshes, the
    frames 0.8 and 0.7 degrees off).

    Parameters
    ----------
    network : PreparedNetwork
    h : float
        The edge length around the nodes.
    factor : float
        Options.node_radius.

    Returns
    -------
    float
        ``factor`` h, but at most 0.4 times the distance between two nodes.
    """
    r = factor * h
    nodes = [nd.position for nd in network.nodes]
    if len(nodes) > 1:
        P = np.array(nodes)
        d = np.linalg.norm(P[:, None] - P[None], axis=2) + np.eye(len(P)) * 1e300
        r = min(r, 0.4 * d.min())
    return r
