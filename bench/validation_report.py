"""The validation report (paper §5.2, §5.4; docs/how-it-works.md, *Analysis*).

Runs every example domain, measures each solution with solver/analysis/measures.py,
and runs a refinement study; prints everything and writes it as markdown
(bench/VALIDATION.md) with a log-log plot of the study.

    python bench/validation_report.py                 # full run, ~20 min on 2 cores
    python bench/validation_report.py --quick         # smoke run, a few minutes; writes nothing
    python bench/validation_report.py --examples cylinder:0.2 ball:0.15 \\
        --refine cylinder:0.4,0.3,0.22,0.16 --out /tmp/v.md

What each column means is written into the report itself (COLUMN_NOTES);
the pass/fail thresholds against the paper's figures are TARGETS.
"""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time

import numpy as np
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from solver.analysis import measures as an  # noqa: E402
from solver.errors import MeshingError  # noqa: E402
from solver.examples import load_example  # noqa: E402
from solver.field.constraints import TUBE  # noqa: E402
from solver.field.develop import develop  # noqa: E402
from solver.linalg.rotations import cross_distance  # noqa: E402
from solver.pipeline import INITS, FieldProblem, Options  # noqa: E402
from testkit.tetedge import tet_edge_network  # noqa: E402

DEFAULT_EXAMPLES = [("cube", 0.2), ("cylinder", 0.2), ("torus", 0.15), ("ball", 0.15), ("plate", 0.1),
                    ("cylinder/tet-edge", 0.2), ("ball/tet-edge", 0.15), ("plate/tet-edge", 0.1)]
TET_EDGE_SOURCE = 1.5
"""An example named ``NAME/tet-edge`` is NAME's network routed along the
edges of an independent fTetWild mesh at TET_EDGE_SOURCE times the row's
edge length (``testkit/tetedge.py``: zig-zags, 1e-6 segments, oblique ends),
repaired by the curve intake and solved like the clean one."""
DEFAULT_REFINE = [("cylinder", [0.3, 0.22, 0.16, 0.12]), ("ball", [0.2, 0.15, 0.12, 0.1])]
"""Target edge lengths whose fTetWild meshes have clearly different mean edge
lengths (cylinder: 0.24 .. 0.12; ball: 0.17 .. 0.10).  Coarser targets give
almost the same mesh (the curve tubes and sharp features set the size), and
the ball fails to embed its network at 0.22-0.25 (see the report)."""
QUICK_EXAMPLES = [("cube", 0.4), ("cylinder", 0.35), ("torus", 0.3), ("ball", 0.25), ("plate", 0.2)]
QUICK_REFINE = [("cylinder", [0.3, 0.22, 0.18])]
QUICK_INITS = ("zero", "random")

AWAY = 0.25
"""Refinement subdomain: faces whose vertices are all this far (in the
examples' units: the cylinder and ball have radius 1) from every curve."""

SMOOTHING_ITERATIONS = 20

# (metric key, comparison, threshold, what the paper says)
TARGETS = [
    ("mono_max", "<=", 0.1, "monodromy a small fraction of a degree on the coarsest mesh (Fig. 15)"),
    ("root_max", "<=", 1.0, "root independence: no cross moves by more than about 1 degree (Fig. 16)"),
    ("init_cross", "<=", 0.01, "identical minimiser from every initialisation (Fig. 17; floating point in the "
                               "paper, the LM tolerance here)"),
    ("normal_mean", "<=", 1.72, "adaptation mean error 0.014-1.72 degrees (§5.2)"),
    ("tangent_mean", "<=", 1.72, "adaptation mean error 0.014-1.72 degrees (§5.2)"),
    ("omega_missing", "<=", 0, "singular faces are exactly the network (docs/how-it-works.md, *Analysis*)"),
    ("omega_spurious", "<=", 0, "no spurious singular faces"),
    ("smooth_max", "<=", 1.0, "local smoothing moves no cross by more than about 1 degree (Fig. 18)"),
]
SLOPE_TARGET = 1.5  # "near 2" (Fig. 14, 15): flagged below this

COLUMNS = [
    # header, key, format
    ("example", "example", "{}"),
    ("h", "h", "{:.3g}"),
    ("tets", "tets", "{:,}"),
    ("time s", "time", "{:.0f}"),
    ("LM it", "lm_iterations", "{}"),
    ("penalty", "penalty", "{:.3g}"),
    ("mono mean°", "mono_mean", "{:.2e}"),
    ("mono max°", "mono_max", "{:.2e}"),
    ("resid mean", "res_mean", "{:.2e}"),
    ("resid max", "res_max", "{:.2e}"),
    ("root max°", "root_max", "{:.3g}"),
    ("root max° w/ nodes", "root_max_all", "{:.3g}"),
    ("init Δω°", "init_omega", "{:.2e}"),
    ("init Δcross°", "init_cross", "{:.2e}"),
    ("normal mean°", "normal_mean", "{:.3g}"),
    ("normal max°", "normal_max", "{:.3g}"),
    ("tangent mean°", "tangent_mean", "{:.3g}"),
    ("tangent max°", "tangent_max", "{:.3g}"),
    ("sing faces", "singular", "{}"),
    ("missing", "missing", "{}"),
    ("spurious", "spurious", "{}"),
    ("missing ω-matched", "omega_missing", "{}"),
    ("spurious ω-matched", "omega_spurious", "{}"),
    ("φ_θ", "phi_theta", "{:.4g}"),
    ("φ_H", "phi_H", "{:.4g}"),
    ("smooth max°", "smooth_max", "{:.3g}"),
    ("smooth mean°", "smooth_mean", "{:.2e}"),
    ("smooth max° bnd fixed", "smooth_max_bnd_fixed", "{:.3g}"),
    ("φ_θ drop %", "smooth_drop", "{:.3g}"),
]

COLUMN_NOTES = """\
* **h**: target edge length; **tets**, **time** (meshing + all stages of the zero-start solve, wall clock),
  **LM it**: Levenberg–Marquardt iterations of the zero start; **penalty**: its structure term a·R(ω) (Eq. 23),
  which `solver/report.py` calls converged at ≤ 1 + 0.25 × smoothness.
  **NAME/tet-edge**: NAME's curves routed along the edges of an independent fTetWild mesh at 1.5 h
  (`testkit/tetedge.py`) and repaired by the curve intake; tangent adaptation is to the repaired curves.
* **mono mean/max°**: per-face monodromy angle (Eq. 9) over the *regular* faces: interior, not pierced by a curve,
  not in a node region or curve end.
* **resid mean/max**: |dω − ω∧ω − Ω| per face (Eq. 17, the BCH-consistent form of `solver/field/structure.py`), over all
  faces that carry the structure equation (pierced faces included, with their Ω).
* **root max°**: largest cross distance between the solved frames and the frames developed from 3 other boundary
  roots and 3 interior roots (farthest-point samples; interior roots off the curve tubes and node regions),
  each started from the solved frame at that root (§4.3, Fig. 16), over the vertices outside node regions;
  **w/ nodes**: over all vertices.  Node regions (balls of radius ~1.5 h around the nodes, `solver/mesh/embed.py`) carry
  no structure equation, so ω is not integrable inside them by design.
* **init Δω°**: largest |ω_init − ω_zero| over edges for the other initialisations (Fig. 17);
  **init Δcross°**: largest cross distance between the frames each solve returns (each developed from the default
  root with its own solution's boundary angle α there).
* **normal mean/max°**: angle between the boundary vertex normal and the nearest frame axis, boundary vertices off
  sharp features; **tangent mean/max°**: same for the curve tangent at the nearest curve point, at every vertex
  carrying a curve constraint (§5.2).
* **sing faces / missing / spurious**: faces whose closest-rotation matchings (24 cube symmetries) fail to close;
  missing: faces the network pierces (with an index ≠ 0) that are not singular; spurious: singular faces outside
  the pierced faces, node regions and curve-end boundary faces.  **missing / spurious ω-matched**: the same with
  each edge matched against the frame ω carries across it (`analysis.omega_singular_faces`): the field's own
  matchings, which the exports write and the targets judge.  Closest-rotation matching misreads them wherever an
  edge turns by ~45° or more: the twisted field of the coarse torus, and faces next to a curve that passes close
  to an edge.
* **φ_θ, φ_H**: §5.4 over interior faces, frames per tet = Karcher mean of its vertex frames, weights face area over
  the distance between the two tets' centroids (circumcentres are degenerate on these meshes).
* **smooth max/mean°, φ_θ drop %**: {n} Jacobi sweeps of Karcher-mean smoothing (§5.2, Fig. 18) with the Eq. 16
  weights: interior vertices free, boundary vertices rotate about their normal only, sharp-feature, curve-tube
  and node-region vertices fixed; how far the crosses move and how much φ_θ drops.  **bnd fixed**: the same
  with every boundary vertex fixed (separates the interior from the boundary angles α).
"""


# ============================================================== measurement


def _fixed_and_axes(problem):
    """Smoothing constraints: see COLUMN_NOTES."""
    mesh, cons = problem.mesh, problem.constraints
    fixed = np.zeros(mesh.n_vertices, bool)
    fixed[cons.fixed_frame_vertices] = True
    tube = cons.kind == TUBE
    fixed[mesh.edges[tube].reshape(-1)] = True
    nr = problem.embedding.node_region_tets
    if len(nr):
        fixed[mesh.tets[nr].reshape(-1)] = True
    axes = np.zeros((mesh.n_vertices, 3))
    axes[mesh.boundary_vertices] = mesh.boundary.vertex_normals
    return fixed, axes


def network_vertex_mask(problem) -> np.ndarray:
    """Vertices of curve tubes and node regions."""
    mesh, cons = problem.mesh, problem.constraints
    m = np.zeros(mesh.n_vertices, bool)
    m[mesh.edges[cons.kind == TUBE].reshape(-1)] = True
    nr = problem.embedding.node_region_tets
    if len(nr):
        m[mesh.tets[nr].reshape(-1)] = True
    return m


def measure(result, others: dict | None = None, smoothing_iterations: int = SMOOTHING_ITERATIONS,
            n_roots: tuple[int, int] = (3, 3)) -> dict:
    """Every measurement of one solved field.  ``others``: {init: Result} of
    the same problem from other initialisations."""
    mesh, prob, emb = result.mesh, result.problem, result.embedding
    row: dict = {"tets": mesh.n_tets, "h_mean": mesh.mean_edge_length}
    lm = result.report.lm
    row["lm_iterations"] = lm.n_iterations
    row["lm_converged"] = lm.converged
    row["penalty"] = lm.final.penalty
    row["time"] = result.report.total_seconds
    row["lm_seconds"] = lm.seconds
    # integrability
    reg = an.regular_faces(result)
    mono = np.degrees(an.monodromy_angles(mesh, result.omega, reg))
    row["mono_mean"], row["mono_max"] = float(mono.mean()), float(mono.max())
    row["regular_faces"] = len(reg)
    active = np.nonzero(~emb.face_excluded)[0]
    res = an.structure_residual(mesh, result.omega, result.structure_omega, active)
    row["res_mean"], row["res_max"] = float(res.mean()), float(res.max())
    # singular structure
    ss = an.network_singular_structure(result)
    row["singular"] = len(ss.faces)
    row["expected"] = len(ss.expected)
    row["missing"] = len(ss.missing)
    row["spurious"] = len(ss.spurious)
    # omega-aware matching: not fooled by edges turning more than 45 degrees
    sf = an.singular_faces(mesh, result.omega, result.frames, emb.network_faces(mesh))
    row["omega_spurious"] = int(sf.spurious.sum())
    row["omega_missing"] = int((emb.prescribed_singular() & ~sf.singular).sum())
    row["wrong_index"] = len(ss.wrong_index)
    row["axis_error_max"] = float(np.degrees(ss.axis_error.max())) if len(ss.axis_error) else 0.0
    row["singular_curves"] = len(ss.curves)
    # like for like: the network's faces (pierced, node regions, curve ends) grouped the same way
    row["expected_curves"] = len(an.group_singular_faces(mesh, emb.network_faces(mesh)))
    if len(ss.expected):
        pm = np.degrees(an.monodromy_angles(mesh, result.omega, ss.expected, emb.face_omega))
        row["pierced_mono_max"] = float(pm.max())
    if len(ss.spurious):
        row["spurious_curves"] = len(an.group_singular_faces(mesh, ss.spurious))
        row["spurious_angles"] = sorted({int(round(a)) for a in np.degrees(ss.angle[np.isin(ss.faces, ss.spurious)])})
    # root independence
    avoid = prob.avoid_edges
    roots = an.pick_roots(mesh, n_roots[0], n_roots[1], exclude=network_vertex_mask(prob), start=result.root)[1:]
    ri = an.root_independence(mesh, result.omega, result.frames, roots, avoid)
    in_node = np.zeros(mesh.n_vertices, bool)
    nr = emb.node_region_tets
    if len(nr):
        in_node[mesh.tets[nr].reshape(-1)] = True
    row["root_max_all"] = ri.max_deg
    row["root_max"] = float(np.degrees(ri.change[~in_node].max()))
    row["root_median"] = float(np.degrees(np.median(ri.change[~in_node])))
    row["root_per_root"] = [float(x) for x in np.degrees(ri.max_change)]
    row["root_kinds"] = ["boundary" if mesh.is_boundary_vertex[r] else "interior" for r in roots]
    # initialisation independence
    if others:
        omegas = {"zero": result.omega, **{k: r.omega for k, r in others.items()}}
        frames = {"zero": result.frames, **{k: r.frames for k, r in others.items()}}
        ii = an.init_independence(omegas, frames, "zero")
        row["init"] = ii
        row["init_omega"] = max(v["omega_max_deg"] for v in ii.values())
        row["init_cross"] = max(v["cross_max_deg"] for v in ii.values())
        # the same omegas developed from one root and frame: separates omega
        # from the choice of the root frame
        same = []
        for r in others.values():
            E = develop(mesh, r.omega, result.root, result.frames[result.root], avoid)
            same.append(float(np.degrees(cross_distance(result.frames, E).max())))
        row["init_cross_same_root"] = max(same)
        row["init_lm_iterations"] = {k: r.report.lm.n_iterations for k, r in others.items()}
    # adaptation
    feat = prob.boundary.is_feature_vertex
    na = np.degrees(an.normal_adaptation(mesh, result.frames))[~feat]
    row["normal_mean"] = float(na.mean()) if len(na) else 0.0
    row["normal_max"] = float(na.max()) if len(na) else 0.0
    _, ta = an.tangent_adaptation(result)
    if len(ta):
        row["tangent_mean"], row["tangent_max"] = float(np.degrees(ta).mean()), float(np.degrees(ta).max())
    # smoothness and local smoothing
    fixed, axes = _fixed_and_axes(prob)
    chk = an.smoothing_check(mesh, result.frames, smoothing_iterations, fixed, axes)
    row["phi_theta"], row["phi_H"] = chk["phi_theta_before"], chk["phi_H_before"]
    row["smooth_max"] = chk["max_change_deg"]
    row["smooth_mean"] = chk["mean_change_deg"]
    row["smooth_p99"] = chk["p99_change_deg"]
    row["smooth_last_sweep"] = chk["last_sweep_deg"]
    row["smooth_drop"] = chk["phi_theta_drop_pct"]
    d = np.degrees(cross_distance(result.frames, chk["frames"]))
    row["smooth_worst_near_network"] = bool(_near_network(result, int(np.argmax(d))))
    row["smooth_worst_on_boundary"] = bool(mesh.is_boundary_vertex[int(np.argmax(d))])
    S, _ = an.karcher_smoothing(mesh, result.frames, smoothing_iterations, fixed | mesh.is_boundary_vertex)
    row["smooth_max_bnd_fixed"] = float(np.degrees(cross_distance(result.frames, S).max()))
    return row


def _near_network(result, v: int) -> bool:
    """Vertex v within two edge lengths of a network curve."""
    curves = [c.points for c in result.field.network.curves]
    if not curves:
        return False
    return bool(an.vertices_near_polylines(result.mesh.vertices[[v]], curves, 2 * result.mesh.mean_edge_length)[0])


MESH_ATTEMPTS = 3


def make_problem(name: str, h: float, log=print) -> FieldProblem:
    """FieldProblem of an example; fTetWild is not deterministic, so a
    meshing/embedding failure is retried (and logged) up to MESH_ATTEMPTS."""
    base, _, variant = name.partition("/")
    V, F, net = load_example(base)
    if variant == "tet-edge":
        net, _ = tet_edge_network(V, F, net, TET_EDGE_SOURCE * h, seed=0)
    elif variant:
        raise ValueError(f"unknown variant {variant!r} of {base!r} (known: tet-edge)")
    for attempt in range(1, MESH_ATTEMPTS + 1):
        try:
            return FieldProblem(V, F, net, Options(edge_length=h))
        except MeshingError as e:
            log(f"  {name} h={h}: meshing attempt {attempt} failed: {e}")
            if attempt == MESH_ATTEMPTS:
                raise
    raise AssertionError("unreachable")


def run_example(name: str, h: float, inits=INITS, log=print, **kw) -> dict:
    """Mesh and solve one example from every initialisation; measure."""
    t0 = time.perf_counter()
    prob = make_problem(name, h, log)
    log(f"  {name} h={h}: {prob.mesh.n_tets:,} tets, meshed in {time.perf_counter() - t0:.1f} s")
    res = {}
    for init in ["zero", *[i for i in inits if i != "zero"]]:
        t = time.perf_counter()
        res[init] = prob.solve(init=init)
        lm = res[init].report.lm
        log(f"    {init:<8s} {time.perf_counter() - t:6.1f} s, {lm.n_iterations} LM iterations, {lm.reason}")
    main = res.pop("zero")
    # frames as returned by each solve; the reference's own frames are kept
    t = time.perf_counter()
    row = measure(main, res, **kw)
    row["example"], row["h"] = name, h
    row["analysis_seconds"] = time.perf_counter() - t
    log(f"    measured in {row['analysis_seconds']:.1f} s")
    return row


def refinement_point(name: str, h: float, away: float = AWAY, log=print) -> dict:
    """One resolution of a refinement study: monodromy and residual on the
    subdomain away from the curves (and, for comparison, also away from the
    boundary, and on all regular faces)."""
    t = time.perf_counter()
    prob = make_problem(name, h, log)
    r = prob.solve()
    mesh = r.mesh
    out = {"example": name, "h": h, "h_mean": mesh.mean_edge_length, "tets": mesh.n_tets,
           "lm_iterations": r.report.lm.n_iterations, "seconds": time.perf_counter() - t}
    sub = an.subdomain_faces(r, away)
    bd = cKDTree(mesh.vertices[mesh.boundary_vertices]).query(mesh.vertices)[0]
    inner = sub[(bd[mesh.faces[sub]] >= away).all(axis=1)]
    for tag, f in (("sub", sub), ("inner", inner), ("all", an.regular_faces(r))):
        if len(f) == 0:
            continue
        mono = np.degrees(an.monodromy_angles(mesh, r.omega, f))
        res = an.structure_residual(mesh, r.omega, r.structure_omega, f)
        out[f"{tag}_faces"] = len(f)
        out[f"{tag}_mono_mean"], out[f"{tag}_mono_max"] = float(mono.mean()), float(mono.max())
        out[f"{tag}_res_mean"], out[f"{tag}_res_max"] = float(res.mean()), float(res.max())
    nan = float("nan")
    log(f"  {name} h={h}: {mesh.n_tets:,} tets, {out['seconds']:.1f} s, subdomain {len(sub)} faces, "
        f"mono mean {out.get('sub_mono_mean', nan):.3e}°, resid mean {out.get('sub_res_mean', nan):.3e}")
    return out


def refinement_study(name: str, hs, away: float = AWAY, log=print) -> dict:
    pts = [refinement_point(name, h, away, log) for h in hs]
    hm = [p["h_mean"] for p in pts]
    slopes = {}
    for tag in ("sub", "inner", "all"):
        for q in ("mono_mean", "res_mean", "mono_max", "res_max"):
            k = f"{tag}_{q}"
            slopes[k] = an.loglog_slope(hm, [p.get(k, np.nan) for p in pts])
    return {"example": name, "away": away, "points": pts, "slopes": slopes}


# ================================================================ output


def _fmt(v, f):
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "–"
    try:
        return f.format(v)
    except (ValueError, TypeError):
        return str(v)


def format_table(rows) -> str:
    head = "| " + " | ".join(c[0] for c in COLUMNS) + " |"
    sep = "|" + "|".join("---" for _ in COLUMNS) + "|"
    lines = [head, sep]
    for r in rows:
        lines.append("| " + " | ".join(_fmt(r.get(k), f) for _, k, f in COLUMNS) + " |")
    return "\n".join(lines)


def format_details(rows) -> str:
    out = []
    for r in rows:
        s = [f"* **{r['example']}** (h={r['h']}, mean edge {r['h_mean']:.3g}): LM converged: {r['lm_converged']}, "
             f"LM {r['lm_seconds']:.1f} s; regular faces {r['regular_faces']:,}; singular faces {r['singular']} "
             f"(expected {r['expected']}) in {r['singular_curves']} groups (expected {r['expected_curves']}); "
             f"wrong index {r['wrong_index']}; max axis error vs tangent {r['axis_error_max']:.3g}°"]
        if "pierced_mono_max" in r:
            s.append(f"; pierced faces: max |monodromy vs exp(Ω)| {r['pierced_mono_max']:.3g}°")
        if r.get("spurious"):
            s.append(f"; spurious faces form {r['spurious_curves']} groups, turn angles {r['spurious_angles']}°")
        s.append(f"; root max per root, all vertices ({', '.join(r['root_kinds'])}): "
                 + ", ".join(f"{x:.3g}°" for x in r["root_per_root"])
                 + f"; median change off node regions {r['root_median']:.3g}°")
        if "init" in r:
            s.append("; init: " + ", ".join(
                f"{k} Δω {v['omega_max_deg']:.2e}° Δcross {v['cross_max_deg']:.2e}° ({r['init_lm_iterations'][k]} it)"
                for k, v in r["init"].items()))
            s.append(f"; init Δcross developed from the same root frame {r['init_cross_same_root']:.2e}°")
        s.append(f"; smoothing: p99 change {r['smooth_p99']:.3g}°, last sweep {r['smooth_last_sweep']:.2e}°, "
                 f"worst vertex {'near' if r['smooth_worst_near_network'] else 'away from'} the network, "
                 f"{'on' if r['smooth_worst_on_boundary'] else 'off'} the boundary")
        out.append("".join(s))
    return "\n".join(out)


def format_refinement(studies) -> str:
    lines = []
    for st in studies:
        lines.append(f"**{st['example']}** (subdomain: faces ≥ {st['away']} from every curve; 'inner' also ≥ "
                     f"{st['away']} from the boundary; 'all': every regular face)\n")
        lines.append("| h | mean edge | tets | LM it | sub faces | sub mono mean° | sub mono max° | sub resid mean "
                     "| sub resid max | inner faces | inner mono mean° | inner resid mean | all mono mean° "
                     "| all resid mean |")
        lines.append("|" + "---|" * 14)
        for p in st["points"]:
            lines.append("| " + " | ".join([
                f"{p['h']}", f"{p['h_mean']:.4f}", f"{p['tets']:,}", f"{p['lm_iterations']}",
                f"{p.get('sub_faces', 0):,}", _fmt(p.get("sub_mono_mean"), "{:.3e}"),
                _fmt(p.get("sub_mono_max"), "{:.3e}"), _fmt(p.get("sub_res_mean"), "{:.3e}"),
                _fmt(p.get("sub_res_max"), "{:.3e}"), f"{p.get('inner_faces', 0):,}",
                _fmt(p.get("inner_mono_mean"), "{:.3e}"), _fmt(p.get("inner_res_mean"), "{:.3e}"),
                _fmt(p.get("all_mono_mean"), "{:.3e}"), _fmt(p.get("all_res_mean"), "{:.3e}")]) + " |")
        s = st["slopes"]
        lines.append("")
        lines.append(f"log-log slopes against the mean edge length — subdomain: monodromy mean "
                     f"**{s['sub_mono_mean']:.2f}**, residual mean **{s['sub_res_mean']:.2f}** (max: "
                     f"{s['sub_mono_max']:.2f}, {s['sub_res_max']:.2f}); inner: {s['inner_mono_mean']:.2f}, "
                     f"{s['inner_res_mean']:.2f}; all regular faces: {s['all_mono_mean']:.2f}, "
                     f"{s['all_res_mean']:.2f}\n")
    return "\n".join(lines)


def check_targets(rows, studies) -> list[str]:
    """Every measured figure that misses the paper's target."""
    miss = []
    for r in rows:
        for key, _op, thr, why in TARGETS:
            v = r.get(key)
            if v is None:
                continue
            if not v <= thr:
                miss.append(f"{r['example']}: {key} = {_fmt(v, '{:.3g}')} > {thr} — {why}")
    for st in studies:
        for key in ("sub_mono_mean", "sub_res_mean"):
            v = st["slopes"][key]
            if not v >= SLOPE_TARGET:
                miss.append(f"{st['example']}: refinement slope {key} = {v:.2f} < {SLOPE_TARGET} — second order "
                            f"in the paper (Fig. 14, 15)")
    return miss


def _git_label() -> str:
    """The commit the report was made from, marked when the tree has changes."""
    import subprocess

    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        rev = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=root, capture_output=True, text=True,
                             timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        rev = ""
    return f"commit {rev}" if rev else "working tree"


def markdown(rows, studies, label: str, plot_name: str | None, command: str, seconds: float) -> str:
    parts = [
        "# Validation report",
        "",
        f"Solver state: **{label}**. Generated by `{command}` in {seconds / 60:.1f} min "
        f"(wall clock, {os.cpu_count()} cores, shared machine: times are indicative). Regenerate after solver changes.",
        "",
        "Measurements: `solver/analysis/measures.py` (tested on fields with known answers in "
        "`tests/test_analysis.py`); "
        "runner: `bench/validation_report.py`. Angles in degrees.",
        "",
        "## Examples",
        "",
        format_table(rows),
        "",
        COLUMN_NOTES.format(n=SMOOTHING_ITERATIONS),
        "### Details",
        "",
        format_details(rows),
        "",
        "## Refinement study",
        "",
        "Zero-start solves at each resolution (fresh meshes). The paper measures on a fixed subdomain away from the "
        "singular curves and finds second order (Fig. 14, 15).",
        "",
        format_refinement(studies),
    ]
    if plot_name:
        parts += [f"![refinement]({plot_name})", ""]
    miss = check_targets(rows, studies)
    parts += ["## Against the paper's targets", ""]
    parts += [f"* {m}" for m in miss] if miss else ["Every figure meets its target."]
    parts += ["", "Targets: " + "; ".join(f"{k} {op} {t}" for k, op, t, _ in TARGETS)
              + f"; refinement slopes >= {SLOPE_TARGET}.", ""]
    return "\n".join(parts)


# ------------------------------------------------------------------ plot


def write_plot(studies, path_base: str) -> str | None:
    """PNG with matplotlib if it is installed, else SVG; returns the path."""
    if not studies:
        return None
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        path = path_base + ".svg"
        with open(path, "w") as f:
            f.write(refinement_svg(studies))
        return path
    path = path_base + ".png"
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    for ax, (q, title) in zip(axs, (("mono_mean", "monodromy angle (deg), mean"), ("res_mean", "residual, mean"))):
        for st in studies:
            h = [p["h_mean"] for p in st["points"]]
            v = [p.get(f"sub_{q}", np.nan) for p in st["points"]]
            ax.loglog(h, v, "o-", label=f"{st['example']} (slope {st['slopes'][f'sub_{q}']:.2f})")
        h = np.array([p["h_mean"] for st in studies for p in st["points"]])
        hh = np.array([h.min(), h.max()])
        v0 = np.nanmax([p.get(f"sub_{q}", np.nan) for st in studies for p in st["points"]])
        ax.loglog(hh, v0 * (hh / hh.max()) ** 2, "k--", lw=0.8, label="slope 2")
        ax.set_xlabel("mean edge length h")
        ax.set_title(title)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def refinement_svg(studies) -> str:
    """Two log-log panels (monodromy, residual on the subdomain) as SVG."""
    W, H, pad = 460, 340, 60
    colors = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"]
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{2 * W}" height="{H}" font-family="sans-serif" '
           f'font-size="12"><rect width="100%" height="100%" fill="white"/>']
    for panel, (q, title) in enumerate((("mono_mean", "monodromy angle (deg), mean over subdomain"),
                                        ("res_mean", "structure residual, mean over subdomain"))):
        x0 = panel * W
        series = []
        for st in studies:
            pts = [(p["h_mean"], p.get(f"sub_{q}", np.nan)) for p in st["points"]]
            pts = [(a, b) for a, b in pts if b > 0 and np.isfinite(b)]
            series.append((st, pts))
        allh = [a for _, p in series for a, _ in p]
        allv = [b for _, p in series for _, b in p]
        if not allh:
            continue
        lx0, lx1 = np.log10(min(allh)) - 0.05, np.log10(max(allh)) + 0.05
        ly0, ly1 = np.floor(np.log10(min(allv)) - 0.1), np.ceil(np.log10(max(allv)) + 0.1)

        def X(h, lx0=lx0, lx1=lx1, x0=x0):
            return x0 + pad + (np.log10(h) - lx0) / (lx1 - lx0) * (W - 1.5 * pad)

        def Y(v, ly0=ly0, ly1=ly1):
            return H - pad + (np.log10(v) - ly0) / (ly1 - ly0) * -(H - 1.6 * pad)

        out.append(f'<rect x="{x0 + pad}" y="{0.6 * pad}" width="{W - 1.5 * pad}" height="{H - 1.6 * pad}" '
                   f'fill="none" stroke="black"/>')
        out.append(f'<text x="{x0 + W / 2}" y="{0.4 * pad}" text-anchor="middle">{title}</text>')
        out.append(f'<text x="{x0 + pad + (W - 1.5 * pad) / 2}" y="{H - 0.25 * pad}" text-anchor="middle">'
                   f'mean edge length h (log)</text>')
        for e in range(int(ly0), int(ly1) + 1):
            y = Y(10.0**e)
            out.append(f'<line x1="{x0 + pad}" x2="{x0 + W - 0.5 * pad}" y1="{y:.1f}" y2="{y:.1f}" stroke="#ddd"/>')
            out.append(f'<text x="{x0 + pad - 4}" y="{y + 4:.1f}" text-anchor="end">1e{e}</text>')
        for hv in sorted({round(a, 3) for a in allh}):
            x = X(hv)
            out.append(f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{H - pad}" y2="{H - pad + 5}" stroke="black"/>')
            out.append(f'<text x="{x:.1f}" y="{H - pad + 17}" text-anchor="middle" font-size="10">{hv:g}</text>')
        # slope-2 reference through the top-right point
        hmax, vmax = max(allh), max(allv)
        hmin = min(allh)
        out.append(f'<line x1="{X(hmin):.1f}" y1="{Y(vmax * (hmin / hmax) ** 2):.1f}" x2="{X(hmax):.1f}" '
                   f'y2="{Y(vmax):.1f}" stroke="black" stroke-dasharray="5,4"/>')
        ly = 0.6 * pad + 16
        for i, (st, pts) in enumerate(series):
            c = colors[i % len(colors)]
            path = " ".join(f"{X(a):.1f},{Y(b):.1f}" for a, b in pts)
            out.append(f'<polyline points="{path}" fill="none" stroke="{c}" stroke-width="1.5"/>')
            for a, b in pts:
                out.append(f'<circle cx="{X(a):.1f}" cy="{Y(b):.1f}" r="3.5" fill="{c}"/>')
            out.append(f'<text x="{x0 + pad + 8}" y="{ly}" fill="{c}">{st["example"]}: slope '
                       f'{st["slopes"][f"sub_{q}"]:.2f}</text>')
            ly += 15
        out.append(f'<text x="{x0 + pad + 8}" y="{ly}">- - slope 2</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


# ------------------------------------------------------------------- CLI


def _parse_examples(items):
    out = []
    for it in items:
        name, _, h = it.partition(":")
        out.append((name, float(h) if h else None))
    return out


def _parse_refine(items):
    out = []
    for it in items:
        name, _, hs = it.partition(":")
        out.append((name, [float(x) for x in hs.split(",") if x]))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="validation_report", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="coarse smoke run; writes nothing unless --out is given")
    ap.add_argument("--examples", nargs="*", metavar="NAME:H", help="examples and edge lengths for the table")
    ap.add_argument("--refine", nargs="*", metavar="NAME:H1,H2,...", help="refinement studies (>= 4 resolutions)")
    ap.add_argument("--inits", default=None, help="comma-separated initialisations (zero is always the reference)")
    ap.add_argument("--away", type=float, default=AWAY, help="refinement subdomain distance from the curves")
    ap.add_argument("--smoothing-iterations", type=int, default=SMOOTHING_ITERATIONS)
    ap.add_argument("--out", default=None, help="markdown file to write (default bench/VALIDATION.md for a full run)")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--label", default=None, help="solver version named in the report (default: the git commit)")
    args = ap.parse_args(argv)
    if args.label is None:
        args.label = _git_label()

    examples = _parse_examples(args.examples) if args.examples is not None else (
        QUICK_EXAMPLES if args.quick else DEFAULT_EXAMPLES)
    refine = _parse_refine(args.refine) if args.refine is not None else (QUICK_REFINE if args.quick else DEFAULT_REFINE)
    inits = tuple(args.inits.split(",")) if args.inits else (QUICK_INITS if args.quick else INITS)
    for name, hs in refine:
        if len(hs) < 2:
            ap.error(f"refinement study {name} needs at least two resolutions")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    out = args.out
    if out is None and not args.quick and not args.no_write:
        out = os.path.join(root, "bench", "VALIDATION.md")
    if args.no_write:
        out = None

    t0 = time.perf_counter()
    rows, studies = [], []
    print(f"examples: {', '.join(f'{n}:{h}' for n, h in examples)}; inits: {', '.join(inits)}", flush=True)
    for name, h in examples:
        rows.append(run_example(name, h, inits, log=lambda s: print(s, flush=True),
                                smoothing_iterations=args.smoothing_iterations))
    print("\n" + format_table(rows) + "\n", flush=True)
    for name, hs in refine:
        print(f"refinement study: {name} at h = {hs}", flush=True)
        studies.append(refinement_study(name, hs, args.away, log=lambda s: print(s, flush=True)))
    seconds = time.perf_counter() - t0
    print()
    print(format_details(rows))
    print()
    print(format_refinement(studies))
    miss = check_targets(rows, studies)
    print("Against the paper's targets:" + ("".join(f"\n  * {m}" for m in miss) if miss else " all met"))
    print(f"\ntotal {seconds / 60:.1f} min")
    if out:
        plot = write_plot(studies, os.path.join(os.path.dirname(os.path.abspath(out)), "validation_refinement"))
        cmd = shlex.join(["python", "bench/validation_report.py", *(sys.argv[1:] if argv is None else argv)])
        with open(out, "w") as f:
            f.write(markdown(rows, studies, args.label, os.path.basename(plot) if plot else None, cmd.strip(),
                             seconds))
        print(f"wrote {out}" + (f" and {plot}" if plot else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
