"""The whole method, stage by stage (design notes §2).

    validate -> tubes + tet mesh -> embed network -> 2D boundary field
             -> constraints -> Levenberg-Marquardt on omega -> development

Two levels of API, as in potpourri3d: ``solve()`` for one call, and
``FieldProblem`` which keeps the tet mesh, the embedding and the boundary
field so that changing only solver settings does not remesh.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from . import checks
from .errors import Cancelled, MeshingError, OptionsError, TopologyError
from .field.boundary2d import BoundaryField, lift_mismatch, solve_boundary_field
from .field.constraints import TUBE, AffineOmega, build_constraints, tube_curvature
from .field.develop import develop, symmetric_turn
from .field.handles import settle_handle_turns
from .field.volume3d import VolumeProblem
from .linalg.rotations import exp_so3
from .mesh.embed import Embedding, embed_network
from .mesh.linking import misaligned_curves
from .mesh.refine import red_refine
from .mesh.resolution import GRADING, TETS_PER_H3, Plan, check_resolution, plan_resolution, uniform_tets
from .mesh.snapping import snap_to_features
from .mesh.tetmesh import TetMesh
from .mesh.tetwild import tetrahedralize
from .mesh.tubes import build_tubes
from .network.network import Network, PreparedNetwork
from .network.validation import CheckedInput, check_input
from .report import Report, adaptation_status, solution_status
from .surface.corners import transfer_quarters
from .surface.features import FeatureGraph, check_poincare_hopf, transfer_features

INITS = ("zero", "constant", "random", "linear")


MESHER_CHOICES = ("auto", "TetGen", "fTetWild")


@dataclass
class Options:
    """Settings of a solve.

    edge_length    : target tet edge length (units of the surface); None picks
                     one from the solid's volume and the network's feature size
    penalty        : a in Eq. 23 (affects convergence, not the minimiser)
    max_iterations : Levenberg-Marquardt iterations
    tolerance      : relative energy decrease at which LM stops
    init           : 'zero', 'constant', 'random' or 'linear' (§5.2)
    seed           : random initialisation seed
    tube_radius    : cross-section size of the curve tubes, relative to
                     edge_length
    node_radius    : radius of node regions, relative to edge_length
    epsilon        : fTetWild envelope, relative to the bounding-box diagonal
    target_tets    : tet budget when edge_length is None: the mesh is graded
                     (fine only where the network needs it, resolution.py)
                     and stays within 1.5x of it whatever the network
    grading        : growth of that graded mesh's edge length per unit
                     distance from the network (0.1-1; default 0.5).  Lower
                     it together with a larger target_tets to resolve
                     node-to-node curves shorter than an edge better
    max_tets       : refuse a solve whose estimated tet count exceeds this;
                     None: 1,000,000 tets, or fewer if their estimated
                     memory exceeds 3/4 of this machine's (resolution.py)
    refine         : red refinement levels (refine.py): fTetWild meshes at
                     edge_length * 2**refine and each level splits every tet
                     into eight; None picks 0-2 so that fTetWild's mesh keeps
                     >= ~6k tets and >= 3 edges along the shortest curve
                     (as the default edge length does)
    snap_features  : move the tet mesh's boundary onto the input's sharp
                     edges and patches (snapping.py); fTetWild leaves thin
                     tilted triangles along creases that twist the field
    mesher         : 'auto' (the default), 'TetGen' or 'fTetWild'.  TetGen
                     (mesh/cdt.py) keeps a clean surface exactly and meshes
                     3-10x faster; it needs the AGPL ``tetgen`` package, which
                     the extension does not bundle.  fTetWild remeshes any
                     triangle soup and meshes the curve tubes.  'auto'
                     takes TetGen where it is installed, the network has no
                     singular curves and the surface is no denser than an
                     h-mesh of it (cdt.wants_tetgen), else fTetWild; where
                     TetGen fails, fTetWild meshes and the report says why
    """

    edge_length: float | None = None
    penalty: float = 1000.0
    max_iterations: int = 50
    tolerance: float = 1e-10
    init: str = "zero"
    seed: int = 0
    tube_radius: float = 0.35
    node_radius: float = 1.5
    epsilon: float = 1e-3
    target_tets: int = 15000
    grading: float = GRADING
    check_intersections: bool = True
    refine: int | None = None
    snap_features: bool = True
    max_tets: int | None = None
    mesher: str = "auto"

    def __post_init__(self):
        # types and ranges in one place (checks.py): a bad value is refused
        # here, not minutes later inside fTetWild or LM
        E = OptionsError
        self.edge_length = checks.positive_float("option 'edge_length'", self.edge_length, E, allow_none=True,
                                                 fix="a length in the units of the surface")
        self.penalty = checks.positive_float("option 'penalty'", self.penalty, E, fix="the default is 1000")
        self.max_iterations = checks.integer("option 'max_iterations'", self.max_iterations, E, low=1,
                                             fix="the default is 50")
        self.tolerance = checks.nonnegative_float("option 'tolerance'", self.tolerance, E, fix="the default is 1e-10")
        self.init = checks.choice("option 'init'", self.init, INITS, E)
        self.seed = checks.integer("option 'seed'", self.seed, E, low=0, fix="a whole number such as 0")
        self.tube_radius = checks.positive_float("option 'tube_radius'", self.tube_radius, E, high=1.0,
                                                 fix="a fraction of the edge length, the default is 0.35")
        self.node_radius = checks.positive_float("option 'node_radius'", self.node_radius, E, high=10.0,
                                                 fix="a multiple of the edge length, the default is 1.5")
        self.epsilon = checks.positive_float("option 'epsilon'", self.epsilon, E, high=0.1,
                                             fix="fTetWild's envelope as a fraction of the bounding-box diagonal, "
                                                 "the default is 1e-3")
        self.target_tets = checks.integer("option 'target_tets'", self.target_tets, E, low=1,
                                          fix="the default is 15000")
        self.grading = checks.real("option 'grading'", self.grading, E, low=0.1, high=1.0,
                                     fix=f"a growth of the edge length per unit distance, the default is {GRADING:g}")
        self.check_intersections = checks.boolean("option 'check_intersections'", self.check_intersections, E)
        self.refine = checks.integer("option 'refine'", self.refine, E, low=0, high=3, allow_none=True,
                                     fix="0-3 red-refinement levels, or null/None for automatic")
        self.snap_features = checks.boolean("option 'snap_features'", self.snap_features, E)
        self.max_tets = checks.integer("option 'max_tets'", self.max_tets, E, low=1, allow_none=True,
                                       fix="a tet count, or null/None for the default limit (mesh/resolution.py)")
        self.mesher = checks.choice("option 'mesher'", self.mesher, MESHER_CHOICES, E)


class _Stages:
    """Times stages, reports progress and checks for cancellation."""

    WEIGHTS = {"validate": 0.03, "tetmesh": 0.3, "embed": 0.04, "boundary2d": 0.05, "constraints": 0.03,
               "volume3d": 0.5, "integrate": 0.05}

    def __init__(self, report: Report, progress, cancel):
        self.report = report
        self.progress = progress
        self.cancel = cancel
        self.done = 0.0

    def run(self, name, fn, *args, **kw):
        if self.cancel is not None and self.cancel():
            raise Cancelled()
        if self.progress is not None:
            self.progress(name, self.done, f"{name}...")
        t = time.perf_counter()
        out = fn(*args, **kw)
        self.report.stage_seconds[name] = self.report.stage_seconds.get(name, 0.0) + time.perf_counter() - t
        self.done = min(1.0, self.done + self.WEIGHTS.get(name, 0.0))
        if self.progress is not None:
            self.progress(name, self.done, f"{name} done")
        return out




def _volume(checked: CheckedInput) -> float:
    return float(np.sum(np.abs(checked.surface.signed_volumes())))


def length_unit(checked: CheckedInput) -> float:
    """The radius of the ball with the solid's volume: the unit in which the
    smoothness weights of Eq. 16 are measured, so that the penalty a of
    Eq. 23 strikes the same balance whatever the model's units (and its
    orientation).  The built-in ball has unit 1."""
    return float((3.0 * _volume(checked) / (4.0 * np.pi)) ** (1.0 / 3.0))


def resolution_plan(checked: CheckedInput, opts: Options) -> Plan:
    """The resolution of a solve (resolution.py): a uniform edge length if
    one is given, else a graded mesh for the tet budget.  Raises
    resolution.ResolutionError, before any meshing, when it is past the
    tet / memory limit (Options.max_tets)."""
    vol = _volume(checked)
    if opts.edge_length:
        h = float(opts.edge_length)
        plan = Plan(edge_length=h, tets=uniform_tets(vol, h))
        what = f"edge length {h:.4g} over a volume of {vol:.4g}"
    else:
        target = int(opts.target_tets)
        check_resolution(target, opts.max_tets, f"target_tets = {target:,}")
        plan = plan_resolution(vol, checked.surface, checked.network, target, grading=opts.grading)
        what = f"target_tets = {target:,}"
    k = 0 if opts.refine is None else int(opts.refine)
    check_resolution(plan.tets, opts.max_tets, what, mesher_tets=plan.tets / 8.0**k, volume=vol)
    return plan


class FieldProblem:
    """A domain and network meshed and prepared for repeated solves.

    V : (n, 3) float array, F : (m, 3) int array -- the closed surface
    network : Network
    options : Options (mesh-related fields are used here)
    """

    def __init__(self, V, F, network: Network, options: Options | None = None, progress=None, cancel=None,
                 mesh: TetMesh | None = None):
        self.options = options or Options()
        self.report = Report()
        st = _Stages(self.report, progress, cancel)
        # the curve intake (intake.py) repairs the network at the scale of
        # the mesh: the edge length when given, else the budget edge length
        # of the solid alone (the default h below depends on the network)
        self.checked: CheckedInput = st.run("validate", check_input, V, F, network,
                                            self.options.check_intersections, self.options.edge_length,
                                            True, self.options.target_tets)
        self.report.repairs = self.checked.repairs
        self.report.repair_scale = self.checked.scale
        self.report.corners = self.checked.corners
        self.plan = self._plan()
        h = self.plan.edge_length
        self.edge_length = h
        self.report.edge_length = h
        self.network: PreparedNetwork = self.checked.network
        self.hierarchy = []  # refine.Refinement per level, coarse to fine
        self._tetgen_off = ""  # why TetGen, asked for, did not mesh (then fTetWild did)
        if mesh is None:
            if progress is not None:
                progress("tetmesh", st.done, f"tetmesh: {self.plan.describe()}")
            mesh = st.run("tetmesh", self._mesh, h, cancel)
            h = self.edge_length  # raised if fTetWild's mesh came out past the tet budget
        self.mesh = mesh
        node_r = self._node_radius(self._node_h(h))
        self.embedding: Embedding = st.run("embed", embed_network, mesh, self.network, node_r)
        self.boundary: BoundaryField = st.run("boundary2d", self._boundary)
        self.constraints: AffineOmega = st.run("constraints", build_constraints, mesh, self.network,
                                               self.embedding, self.boundary)
        self.embedding.structure_omega = tube_curvature(mesh, self.constraints, self.embedding,
                                                       self.network)
        self.report.sizes = {"tets": mesh.n_tets, "vertices": mesh.n_vertices, "edges": mesh.n_edges,
                             "faces": mesh.n_faces, "unknowns": self.constraints.n_unknowns,
                             "curves": len(self.network.curves), "nodes": len(self.network.nodes),
                             # kept in mesh.info, so a reused mesh still says how it was made
                             "refine_levels": int(mesh.info.get("refine_levels", 0)),
                             "mesher_tets": int(mesh.info.get("mesher_tets", mesh.n_tets)),
                             "estimated_tets": int(round(self.plan.tets))}
        if mesh.info.get("budget_retries"):
            # fTetWild's mesh came out past 1.5x the budget (or left no room for
            # the grading) and was made again coarser
            self.report.sizes["budget_retries"] = int(mesh.info["budget_retries"])
        if mesh.info.get("graded_tets"):
            self.report.sizes["graded_tets"] = int(mesh.info["graded_tets"])
            self.report.sizes["edge_length_min"] = float(self.plan.finest)
        if self.plan.floor > 0:
            self.report.sizes["resolution_floor"] = self.plan.floor
            self.report.sizes["edge_length_needed"] = self.plan.need_min
            self.report.sizes["needed_tets"] = int(round(self.plan.needed_tets))
        flat = mesh.info.get("flat_tets")
        if flat is not None and flat["flat_tets"]:
            self.report.sizes["flat_tets"] = flat["flat_tets"]
            self.report.sizes["flat_tets_left"] = flat["flat_tets_left"]
            self.report.sizes["flat_moved_vertices"] = flat["moved_vertices"]
        snap = mesh.info.get("snap")
        if snap is not None:
            self.report.sizes["snapped_vertices"] = snap.moved
            self.report.sizes["snap_kept_vertices"] = int(len(snap.kept))
        self._volume = None

    # --------------------------------------------------------------- stages
    def _plan(self) -> Plan:
        return resolution_plan(self.checked, self.options)

    def _node_h(self, h):
        """The edge length around the nodes (finer than h on a graded mesh)."""
        if not self.plan.graded or not self.network.nodes:
            return h
        return float(min(h, self.plan.sizing(np.array([nd.position for nd in self.network.nodes])).min()))

    def _grade(self, mesh: TetMesh) -> TetMesh:
        """Bisect the tets longer than 1.5x the sizing field at their
        centroid (fTetWild's longest edges are ~1.2 h), pass after pass,
        keeping within 1.5x the tet budget."""
        from .mesh.bisection import bisect

        cap = int(1.5 * self.options.target_tets)
        n0 = mesh.n_tets
        for _ in range(60):
            X = mesh.vertices[mesh.tets]
            longest = np.max(np.linalg.norm(X[:, [0, 0, 0, 1, 1, 2]] - X[:, [1, 2, 3, 2, 3, 3]], axis=2), axis=1)
            ratio = longest / (1.5 * self.plan.sizing(X.mean(axis=1)))
            mark = ratio > 1.0
            if not np.any(mark):
                break
            room = (cap - mesh.n_tets) // 3  # a cut tet and its closure: ~3 more tets
            finer = None
            while room > 0:
                if mark.sum() > room:
                    mark = np.zeros(len(mark), bool)
                    mark[np.argsort(-ratio)[:room]] = True
                finer = bisect(mesh, mark, self.checked.surface)
                if finer.n_tets <= cap:
                    break
                # the closure cut more than ~3 per tet: fewer tets, or none
                finer, room = None, room // 2
            if finer is None:
                break
            mesh = finer
        mesh.info["graded_tets"] = mesh.n_tets - n0
        return mesh

    def _node_radius(self, h):
        r = self.options.node_radius * h
        nodes = [nd.position for nd in self.network.nodes]
        if len(nodes) > 1:
            P = np.array(nodes)
            d = np.linalg.norm(P[:, None] - P[None], axis=2) + np.eye(len(P)) * 1e300
            r = min(r, 0.4 * d.min())
        return r

    def refine_levels(self, h) -> int:
        """Red-refinement levels for a final edge length h (Options.refine)."""
        if self.options.refine is not None:
            return int(self.options.refine)
        est = TETS_PER_H3 * _volume(self.checked) / h**3
        k = 0
        while (k < 2 and est / 8.0 ** (k + 1) >= 6000.0
               and h * 2.0 ** (k + 1) <= self.checked.feature_size / 3.0):
            k += 1
        return k

    def _mesh(self, h, cancel=None):
        """fTetWild at h * 2**k, then k red refinements (refine.py).  A coarse
        mesh that changed the boundary's topology (a pinch or a handle where
        curve tubes pass close to the surface) is retried one level finer
        when the levels were chosen automatically."""
        # the budget holds for the mesh fTetWild makes, not only for the
        # estimate: curve tubes make it refine locally beyond 15 tets/h^3
        # (the ball with an inner cube 0.03 across: 8.9k-9.4k tets where
        # the plan expected 3,000 for the bulk of a 6,000 budget).  An
        # automatic mesh past 1.5x the budget, or one that leaves no room
        # under it for the grading the plan expects, is made again coarser
        cap = None if self.options.edge_length else 1.5 * self.options.target_tets
        room = self.plan.graded_tets if self.plan.graded else 0.0
        made = []  # (tets, h, mesh, k, H) of each mesh kept as a candidate
        retries = 0
        for _attempt in range(3):
            mesh, k, H, problem = self._mesh_at(h, cancel)
            n = mesh.n_tets * 8.0**k
            if problem is not None:
                break
            if cap is not None and self.report.mesher == "TetGen" and n > cap:
                # TetGen keeps the input's triangles and refines around the
                # small or thin ones whatever h is (a box with 1,728 thin
                # triangles: 3.4k tets at 1.8 h after the overshoot at h,
                # where fTetWild made 9.1k at h), so fTetWild meshes instead
                self._tetgen_off = (f"TetGen made {int(n):,} tets, past 1.5x the budget, around the surface's "
                                    "small or thin triangles")
                continue
            made.append((n, h, mesh, k, H))
            # TetGen has no tubes: a coarser h would not make room
            if cap is None or n <= cap - room or self.report.mesher == "TetGen" or _attempt == 2:
                break
            # past the cap: aim at the budget; else just make room
            aim = self.options.target_tets if n > cap else cap - room
            h *= (n / aim) ** (1.0 / 3.0)
            retries += 1
        if retries and (problem is not None or made[-1][0] > cap - room):
            # fTetWild's count around the tubes varies from run to run (the
            # ball with an inner cube 0.03 across: 6.2k tets, then 9.0k at a
            # coarser h), and a coarser mesh may lose the boundary's topology:
            # keep the best mesh made
            problem = None
            made = [min(made, key=lambda m: m[0])]
        if made:
            _, h, mesh, k, H = made[-1]
        self.edge_length = self.report.edge_length = h
        if problem is not None:
            hint = (f"Try a smaller edge length (now {h:.4g})" if k == 0 else
                    f"fTetWild meshed at {H:.4g} before {k} refinement level(s): try refine={k - 1}")
            raise MeshingError(f"the tet mesh's boundary {problem}; a thin part was lost, a cavity appeared or "
                               f"curve tubes too close to the surface merged with it. {hint}")
        if self.options.snap_features:
            mesh, _ = snap_to_features(mesh, self.checked.features)
        mesh.info["budget_retries"] = retries
        self.hierarchy = []
        for _ in range(k):
            ref = red_refine(mesh, self.checked.surface)
            self.hierarchy.append(ref)
            mesh = ref.fine
        if self.plan.graded:
            mesh = self._grade(mesh)
        return mesh

    def _mesh_at(self, h, cancel=None):
        """fTetWild's mesh for a final edge length h: (mesh, refinement
        levels k, the edge length H = h 2**k meshed at, topology problem or
        None).  With mesher 'TetGen' the surface alone is meshed at h (no
        tubes: embed.py traces the curves through any mesh); where TetGen
        fails, fTetWild meshes it and the report says why."""
        from .mesh.cdt import tetrahedralize_cdt, wants_tetgen

        mesher = self.options.mesher
        if mesher == "auto":
            singular = any(c.sigma != 0 for c in self.network.curves)
            mesher = "TetGen" if wants_tetgen(self.checked.surface, h, singular) else "fTetWild"
        if mesher == "TetGen" and not self._tetgen_off:
            # no automatic red refinement: TetGen's time grows with its output
            # no faster than refinement's (refine_levels is for fTetWild)
            k = int(self.options.refine or 0)
            try:
                mesh = tetrahedralize_cdt(self.checked.surface, h * 2.0**k, cancel)
            except MeshingError as e:
                self._tetgen_off = f"TetGen failed: {e}"
            else:
                self.report.mesher = "TetGen"
                return mesh, k, h * 2.0**k, self._topology_change(mesh)
        self.report.mesher = "fTetWild" + (f" ({self._tetgen_off})" if self._tetgen_off else "")
        k = self.refine_levels(h)
        while True:
            H = h * 2.0**k
            r = self.options.tube_radius * H
            # caps stay on the surface only where it is flat: well inside
            # fTetWild's envelope (tubes.py)
            flat = 0.01 * self.options.epsilon * self.checked.surface.bbox_diagonal
            tubes = build_tubes(self.network, self.checked.surface, r, r * np.sqrt(3.0), self._node_radius(H), flat)
            mesh = tetrahedralize(self.checked.surface, H, (tubes.V, tubes.F), self.options.epsilon, cancel,
                                  sharp=bool(np.any(self.checked.features.sharp)))
            problem = self._topology_change(mesh)
            if problem is None or k == 0 or self.options.refine is not None:
                return mesh, k, H, problem
            k -= 1

    def _topology_change(self, mesh: TetMesh) -> str | None:
        """How the boundary of mesh differs topologically from the input
        surface, or None."""
        S, B = self.checked.surface, mesh.boundary
        if B.n_components != S.n_components:
            return f"has {B.n_components} components but the surface has {S.n_components}"
        _, _, cnt = B._edge_data
        if np.any(cnt != 2):
            return f"is not manifold ({int(np.sum(cnt != 2))} edges with more than two faces)"
        chi_in, chi_out = int(np.sum(S.euler_characteristics())), int(np.sum(B.euler_characteristics()))
        if chi_in != chi_out:
            return f"has Euler characteristic {chi_out} but the surface has {chi_in}"
        return None

    def _boundary(self) -> BoundaryField:
        mesh = self.mesh
        B = mesh.boundary
        if np.any(self.checked.features.sharp):
            sharp = transfer_features(self.checked.features, B)
        else:
            sharp = np.zeros(len(B.edges), bool)
        # the corner quantisation chosen on the input (corners.py), not a
        # new rounding of the remeshed boundary's angles
        G = transfer_quarters(self.checked.features, FeatureGraph(B, sharp))
        fs = np.zeros(len(B.F))
        ends = self.embedding.boundary_end_faces
        if ends:
            loc = np.searchsorted(mesh.boundary_faces, [f for f, _ in ends])
            np.add.at(fs, loc, [s for _, s in ends])
        try:
            check_poincare_hopf(B, G, fs, "the meshed boundary")
            G.check_patches(fs)
        except TopologyError as e:
            raise MeshingError(f"the mesh did not preserve the sharp features or curve ends ({e}); try a smaller "
                               f"edge length (now {self.edge_length:.4g})") from None
        # at a curve's end the frame is adapted to the curve tangent: the
        # monodromy of the boundary data around the end triangle is then a
        # quarter turn about the same axis as in the tube just inside (with
        # the vertex normals it would differ by ~ tube radius / curvature
        # radius, like a kink of the singular curve at the surface)
        override = {}
        for tr in self.embedding.traces:
            P = tr.polyline
            for f, t in ((tr.start_face, P[0] - P[1]), (tr.end_face, P[-1] - P[-2])):
                if f < 0:
                    continue
                t = t / np.linalg.norm(t)
                for v in B.F[np.searchsorted(mesh.boundary_faces, f)]:
                    override[int(v)] = t
        bf = solve_boundary_field(B, G, fs, normal_override=override)
        # loops that bound in the solid: their turns must be what the
        # singular curves through the spanning chain prescribe (field/handles.py)
        bf = settle_handle_turns(mesh, self.embedding, bf, lambda turns: solve_boundary_field(
            B, G, fs, generator_turns=turns, normal_override=override))
        self._check_carried(bf)
        self._check_lift(bf)
        return bf

    def _check_carried(self, bf: BoundaryField) -> None:
        """Refuse a curve whose tangent axis the frames on the surface cannot
        carry from one end to the other, with no singular curve between it
        and the surface (mesh/linking.py): no cross field is adapted to it
        (LM ended at its cap with a penalty of 1e4 on a smooth torus)."""
        bad = misaligned_curves(self.mesh, self.embedding, [c.sigma for c in self.network.curves], bf.E0,
                                bf.features.sharp)
        if not bad:
            return

        def label(j):
            c = self.network.curves[j]
            return f"curve {self.network.source[j]}" + (f" '{c.name}'" if c.name else "")

        i, a, b, cos = bad[0]
        pa, pb = (", ".join(f"{x:.4g}" for x in self.mesh.vertices[v]) for v in (a, b))
        how = "reversed" if cos < -0.5 else "across the curve"
        raise TopologyError(
            f"{label(i)} meets the surface at ({pa}) and ({pb}), and the frame axis along it, carried over the "
            f"surface from one end to the other, arrives {how}: the frames have the curve's tangent as an axis "
            f"and are adapted to the surface, so no cross field follows this curve unless a singular curve "
            f"passes between it and the surface (on one smooth part of the surface the normal stays one axis: "
            f"a curve across the tube of a smooth torus, or U-shaped under one face, cannot be followed). Mark "
            f"sharp edges between its ends (sharp_angle or 'sharp' curves), end it elsewhere, or add the "
            f"singular curves that let the field turn (curves refused: {', '.join(label(j) for j, *_ in bad)})")

    def _check_lift(self, bf: BoundaryField) -> None:
        """Refuse boundary data the volume solve cannot satisfy: triangles
        where the 3D lift of the boundary field turns by a spurious quarter
        turn (folded boundary triangles made them; LM then ends at its cap
        with a penalty of 1e4 or more)."""
        B = self.mesh.boundary
        d = lift_mismatch(B, bf)
        bad = np.nonzero(d > np.pi / 4)[0]
        if len(bad):
            c = B.V[B.F[bad[np.argmax(d[bad])]]].mean(axis=0)
            raise MeshingError(
                f"the boundary cross field could not be lifted to 3D on {len(bad)} boundary triangle(s) near "
                f"({c[0]:.4g}, {c[1]:.4g}, {c[2]:.4g}): the tet mesh's surface is probably folded there (a "
                f"curve tube or feature close to the surface). Try another edge length (now {self.edge_length:.4g})")

    # ----------------------------------------------------------------- solve
    @property
    def volume(self) -> VolumeProblem:
        if self._volume is None:
            self._volume = VolumeProblem(self.mesh, self.constraints, self.embedding.equation_omega,
                                         self.embedding.face_excluded, self.options.penalty,
                                         self.boundary.normals, length_unit(self.checked))
        return self._volume

    def initial_guess(self, init: str, seed: int = 0) -> np.ndarray:
        n = self.constraints.n_unknowns
        if init == "zero":
            return np.zeros(n)
        if init == "constant":
            om = np.tile([0.3, -0.2, 0.1], (self.mesh.n_edges, 1))
            return self.constraints.x_from_omega(om)
        if init == "random":
            rng = np.random.default_rng(seed)
            return rng.uniform(-0.5, 0.5, n)
        if init == "linear":
            x, _ = self.volume.solve(np.zeros(n), max_iterations=3, linear=True, init="linear")
            return x
        raise ValueError(f"unknown init {init!r}")

    def solve(self, init: str | None = None, penalty: float | None = None, max_iterations: int | None = None,
              root: int | None = None, progress=None, cancel=None) -> Result:
        """Optimise omega (Eq. 23) and develop the frames (§4.3)."""
        opts = self.options
        init = init or opts.init
        if init not in INITS:
            raise OptionsError(f"init must be one of {', '.join(INITS)}, got {init!r}")
        # checked before LM, so a bad root does not lose the solve
        max_iterations = checks.integer("max_iterations", max_iterations, OptionsError, low=1, allow_none=True)
        root = checks.integer("root", root, OptionsError, low=0, high=self.mesh.n_vertices - 1, allow_none=True,
                              fix=f"a vertex of the tet mesh, which has {self.mesh.n_vertices} vertices "
                                  "(None: a boundary vertex)")
        if penalty is not None and penalty != self.volume.a:
            self._volume = None
            self.options = Options(**{**asdict(opts), "penalty": penalty})
        report = Report(stage_seconds=dict(self.report.stage_seconds), sizes=dict(self.report.sizes),
                        edge_length=self.edge_length, repairs=self.report.repairs,
                        repair_scale=self.report.repair_scale, corners=self.report.corners,
                        mesher=self.report.mesher)
        st = _Stages(report, progress, cancel)
        st.done = 0.45
        # the volume problem's setup (assembly pattern, preconditioner
        # statics) and the initial guess count as part of the volume3d stage
        t_setup = time.perf_counter()
        if progress is not None and self._volume is None:
            progress("volume3d", st.done, "volume3d: assembling the LM matrix pattern...")
        vp = self.volume
        x0 = self.initial_guess(init, opts.seed)
        t_setup = time.perf_counter() - t_setup

        def lm_progress(it, energy):
            if progress is not None:
                progress("volume3d", min(0.95, 0.45 + 0.45 * it / (max_iterations or opts.max_iterations)),
                         f"LM iteration {it}, energy {energy:.6g}")

        x, lm = st.run("volume3d", vp.solve, x0, max_iterations or opts.max_iterations, opts.tolerance, init,
                       False, lm_progress, cancel)
        report.stage_seconds["volume3d"] += t_setup
        report.lm = lm
        report.status, report.status_reason = solution_status(lm)
        omega = self.constraints.omega(x)
        self._last_x, self._root_frame = x, None
        root, E_root = self.default_root(x) if root is None else (root, None)
        frames = st.run("integrate", self.develop, omega, root, E_root)
        res = Result(problem=self, omega=omega, x=x, frames=frames, root=root, report=report)
        report.metrics.update(res.quick_metrics())
        why = adaptation_status(report.metrics) if report.status == "converged" else None
        if why:
            report.status, report.status_reason = "not converged", why
        return res

    # ------------------------------------------------------------ development
    @property
    def avoid_edges(self) -> np.ndarray:
        """Edges of node-region tets.  Their faces carry no structure equation,
        so a tree path through them (or around them) would not be
        integrable; the development reaches those vertices last."""
        mesh = self.mesh
        out = np.zeros(mesh.n_edges, bool)
        nr = self.embedding.node_region_tets
        if len(nr):
            out[mesh.tet_edges[nr].reshape(-1)] = True
        return out

    def default_root(self, x: np.ndarray | None = None):
        """A boundary vertex and its frame: a sharp-feature vertex (frame
        fixed) if any, else a boundary vertex rotated by its solved alpha
        about its normal (Eq. 20) and, for the solved x, by the turn that
        makes the developed field consistent (develop.symmetric_turn)."""
        mesh, cons, bf = self.mesh, self.constraints, self.boundary
        bv = mesh.boundary_vertices
        if len(cons.fixed_frame_vertices):
            r = int(cons.fixed_frame_vertices[0])
            return r, bf.E0[np.searchsorted(bv, r)]
        if x is not None and x is getattr(self, "_last_x", None):
            if getattr(self, "_root_frame", None) is None:
                self._root_frame = self._symmetric_root(x)
            return self._root_frame
        return self._normal_root(x)

    def _symmetric_root(self, x):
        """The root frame turned about its normal so that the field is a
        consistent cross field (develop.symmetric_turn)."""
        r, E = self._normal_root(x)
        omega = self.constraints.omega(x)
        frames = develop(self.mesh, omega, r, E, self.avoid_edges)
        bv = self.mesh.boundary_vertices
        n = self.boundary.normals[np.searchsorted(bv, r)]
        axis = int(np.argmax(np.abs(E.T @ n)))
        theta = symmetric_turn(self.mesh, omega, frames, axis, self.avoid_edges)
        return r, E @ exp_so3(theta * np.eye(3)[axis])

    def _normal_root(self, x):
        mesh, cons, bf = self.mesh, self.constraints, self.boundary
        bv = mesh.boundary_vertices
        loc = int(np.argmax(cons.alpha_column >= 0)) if np.any(cons.alpha_column >= 0) else 0
        r = int(bv[loc])
        E = bf.E0[loc]
        col = cons.alpha_column[loc]
        if x is not None and col >= 0:
            # adding one constant to every alpha of a boundary component
            # leaves omega unchanged (Eq. 20 only sees alpha differences), so
            # measure the root's alpha from the component's mean: the frames
            # then do not depend on where the solve started
            B = self.mesh.boundary
            n = len(B.V)
            adj = sp.coo_matrix((np.ones(len(B.edges)), (B.edges[:, 0], B.edges[:, 1])), shape=(n, n))
            _, comp = connected_components(adj, directed=False)
            same = (comp == comp[loc]) & (cons.alpha_column >= 0)
            alpha = x[col] - float(np.mean(x[cons.alpha_column[same]]))
            E = exp_so3(alpha * bf.normals[loc]) @ E
        return r, E

    def develop(self, omega, root, E_root=None):
        """Frames from omega, starting at root.  E_root defaults to the frame
        the root gets when developed from the default root."""
        if E_root is None:
            r0, E0 = self.default_root(getattr(self, "_last_x", None))
            E_root = develop(self.mesh, omega, r0, E0, self.avoid_edges)[root]
        return develop(self.mesh, omega, root, E_root, self.avoid_edges)


@dataclass
class Result:
    """A solved field.

    omega  : (#E, 3) Darboux derivative per edge of problem.mesh
    frames : (#V, 3, 3) rotation per vertex; columns are the cross axes
    root   : vertex the frames were developed from
    """

    problem: FieldProblem
    omega: np.ndarray
    x: np.ndarray
    frames: np.ndarray
    root: int
    report: Report

    @property
    def mesh(self) -> TetMesh:
        return self.problem.mesh

    @property
    def embedding(self) -> Embedding:
        return self.problem.embedding

    def quaternions(self) -> np.ndarray:
        """(#V, 4) unit quaternions (w, x, y, z) of the frames."""
        from scipy.spatial.transform import Rotation

        q = Rotation.from_matrix(self.frames).as_quat()  # x y z w
        return np.c_[q[:, 3], q[:, :3]]

    def curve_tets(self, i: int) -> np.ndarray:
        """Tets crossed by prepared curve i."""
        return self.embedding.traces[i].tets

    def curve_faces(self, i: int) -> np.ndarray:
        """Faces pierced by prepared curve i."""
        return self.embedding.traces[i].faces

    def curve_vertices(self, i: int) -> np.ndarray:
        """Vertices whose edges carry curve i's adaptation constraints."""
        cons = self.problem.constraints
        e = np.nonzero((cons.kind == TUBE) & (cons.tube_curve == i))[0]
        return np.unique(self.mesh.edges[e])

    def quick_metrics(self) -> dict:
        from .analysis.measures import quick_metrics

        return quick_metrics(self)


def solve(V, F, network: Network, options: Options | None = None, progress=None, cancel=None, **kw) -> Result:
    """Compute the field in one call: ``solve(V, F, network, edge_length=0.1)``.

    Keyword arguments override fields of ``options``.
    """
    opts = options or Options()
    if kw:
        opts = Options(**{**asdict(opts), **kw})
    problem = FieldProblem(V, F, network, opts, progress=progress, cancel=cancel)
    return problem.solve(progress=progress, cancel=cancel)
