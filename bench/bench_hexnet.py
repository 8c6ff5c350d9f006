"""Hex meshes of networks known to be meshable (issue 48f): the
testkit/hexnet.py family, default options, each run in a fresh process.

    ./dev.sh python bench/bench_hexnet.py                       # every kind, seeds 0-2: a line per run
    ./dev.sh python bench/bench_hexnet.py --kinds ball plate --seeds 0 1 --tet-edge
    ./dev.sh python bench/bench_hexnet.py --write               # also bench/hexnet.json
    ./dev.sh python bench/bench_hexnet.py --kinds ball cylinder plate genus2 torus --seeds 0 1 --tet-edge \
        --write --json hexnet_tetedge.json                      # the tet-edge variants too
    ./dev.sh python bench/bench_hexnet.py --seeds 13 --transform turn --scale 1000   # turned, moved, scaled
    ./dev.sh python bench/bench_hexnet.py --table               # bench/RESULTS.md's table of bench/hexnet.json
    ./dev.sh python bench/bench_hexnet.py --replay bench/output/stalls/torus-0-clean-....pickle  # a kept LM stall

Each input is the boundary and the irregular edges of a hex mesh deformed by
a smooth random map (an O-grid, a cube-sphere, plates with holes, a torus,
a genus-2 part, a cube with a spherical cavity, triangular and hexagonal prisms, an L-shaped part), so a
valid hex mesh with exactly these curves exists.  A
run solves the field and meshes it with the defaults, as
``python -m solver NET.json --hex out.vtu`` does (where the map fails, the
field solved again finer and that one meshed), and is judged by the bars
of issue 48: converged; 100 % hexes, 0 inverted, min scaled Jacobian >= 0.5,
mean >= 0.93; irregular edges within one cell of the curves as given, with
valence 4 - 4 sigma, none elsewhere; Hausdorff <= 1 % of the diagonal.
Recorded per run: the field (tets, LM iterations, penalty, status), the hex
mesh (cells, quality, irregular edges against the given curves), the
seconds per stage and end to end, or the error's kind and message.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def bars(row: dict) -> list:
    """The bars a run missed (issue 48's list), empty when it met them all."""
    if "error" in row:
        return [row["error_kind"] + ": " + row["error"][:80]]
    miss = []
    if row["status"] != "converged":
        miss.append("not converged")
    if row.get("hex_error"):
        return miss + [f"no hex ({row['hex_kind']})"]
    if row["inverted"] or row["other_cells"]:
        miss.append("inverted/other cells")
    if row["sj_min"] < 0.5:
        miss.append("min SJ < 0.5")
    if row["sj_mean"] < 0.93:
        miss.append("mean SJ < 0.93")
    if row["given_extra"] or row["given_covered"] < 1.0 or not row["structure_exact"]:
        miss.append("structure")
    if row["hausdorff_pct"] > 1.0:
        miss.append("Hausdorff")
    return miss


TRANSFORMS = ("none", "turn", "mirror", "stretch")
"""--transform: the input as made; turned (a random rotation of the seed) and
moved, times --scale; mirrored in x (the triangles turned over, so still
outward); stretched by 1.6 x 1 x 0.8."""


def transformed(d: dict, how: str, scale: float, seed: int) -> dict:
    """The input d (hexnet_input's) under one of TRANSFORMS: its surface and
    its curves alike (the source hex mesh is dropped)."""
    import numpy as np
    from scipy.spatial.transform import Rotation

    from solver import Curve, Network

    if how == "none" and scale == 1.0:
        return d
    M, F = np.eye(3), d["F"]
    if how == "turn":
        M = Rotation.random(random_state=seed).as_matrix()
    elif how == "mirror":
        M, F = np.diag([-1.0, 1.0, 1.0]), F[:, ::-1].copy()
    elif how == "stretch":
        M = np.diag([1.6, 1.0, 0.8])
    shift = np.array([3.0, -2.0, 5.0]) * scale if how == "turn" else np.zeros(3)

    def X(P):
        return (np.asarray(P, float) @ M.T) * scale + shift

    net = d["network"]
    curves = [Curve(X(c.points), c.sigma, c.role, c.torsion, c.name) for c in net.curves]
    return {**d, "V": X(d["V"]), "F": F, "network": Network(curves, sharp_angle=net.sharp_angle)}


def run_one(kind: str, seed: int, tet_edge: bool, how: str = "none", scale: float = 1.0) -> dict:
    from solver import HexMeshError, SymFramesError, solve
    from testkit.hexnet import hexnet_input
    from testkit.runs import hexmesh_as_cli

    d = transformed(hexnet_input(kind, seed), how, scale, seed)
    V, F, net = d["V"], d["F"], d["network"]
    if tet_edge:
        from testkit.tetedge import tet_edge_network

        diag = float((V.max(axis=0) - V.min(axis=0)) @ (V.max(axis=0) - V.min(axis=0))) ** 0.5
        net, _ = tet_edge_network(V, F, net, 0.05 * diag, seed=seed)
    row = dict(kind=kind, seed=seed, variant="tet-edge" if tet_edge else "clean", curves=len(net.curves),
               **({"transform": how, "scale": scale} if how != "none" or scale != 1.0 else {}),
               source_irregular={str(k): int(v) for k, v in d["meta"].get("irregular_edges", {}).items()})
    _keep_stalls(row, V, F, net)
    t0 = time.perf_counter()
    try:
        r = solve(V, F, net)
    except SymFramesError as e:
        row.update(error=str(e), error_kind=type(e).__name__, total_s=round(time.perf_counter() - t0, 1))
        return row
    t_field = time.perf_counter() - t0
    rep = r.report
    row.update(status=rep.status, status_reason=rep.status_reason, penalty=round(float(rep.lm.final.penalty), 3),
               iterations=int(rep.lm.n_iterations), tets=int(rep.sizes.get("tets", 0)),
               field_s=round(t_field, 1), field_stages={k: round(v, 1) for k, v in rep.stage_seconds.items()},
               field_notes=list(rep.notes))
    t1 = time.perf_counter()
    try:
        hm, finer = hexmesh_as_cli(r)  # where the map fails, the field solved again finer, as the CLI does
        row.update({k: v for k, v in finer.items() if k != "tets"})
    except HexMeshError as e:
        row.update({k: v for k, v in getattr(e, "retry", {}).items() if k != "tets"})
        row.update(hex_error=str(e), hex_kind=e.kind, total_s=round(time.perf_counter() - t0, 1))
        return row
    h = hm.report
    row.update(hexes=h.hexes, other_cells=h.non_hex_cells, inverted=h.inverted, sj_min=round(h.sj_min, 3),
               sj_mean=round(h.sj_mean, 3), sj_min_raw=round(h.sj_min_raw, 3), hex_status=h.status,
               reason=h.reason, irregular={str(k): v for k, v in h.irregular.items()},
               structure_exact=bool(h.structure_exact), given_extra=int(h.given_extra),
               given_distance_cells=round(h.given_distance / h.cell_size, 2),
               given_covered=round(h.given_covered, 3), given_moved_cells=round(h.given_moved / h.cell_size, 2),
               hausdorff_pct=round(100 * h.hausdorff_relative, 2), cell=round(h.cell_size, 4), notes=h.notes,
               size_within=round(h.size_within, 3), size_p5=round(h.size_p5, 2), size_p95=round(h.size_p95, 2),
               hex_s=round(time.perf_counter() - t1, 1),
               hex_stages={k: round(v, 1) for k, v in h.stage_seconds.items()},
               total_s=round(time.perf_counter() - t0, 1))
    if tet_edge:
        # also against the source's curves, which the zigzag was routed for
        # (information, not a bar: a zigzag strays from them by up to 1-3
        # cells, zigzag_cells, and a chain of one tet edge keeps no trace of
        # where its source was)
        import numpy as np

        from solver.hexmesh.quality import polyline_distance
        from solver.hexmesh.report import curve_matches

        clean = [(np.asarray(c.points, float), float(c.sigma), i, c.name)
                 for i, c in enumerate(d["network"].curves) if c.sigma != 0]
        extra, matches = curve_matches(clean, hm.vertices, hm.irregular_edges, hm.irregular_valence, h.cell_size)
        # how far the zigzag strays: each of its points from the nearest source curve
        zigzag = max((float(np.min([polyline_distance(P, np.asarray(t.points, float)) for P, *_ in clean],
                                   axis=0).max()) for t in net.curves if t.sigma != 0), default=0.0)
        row.update(source_extra=int(extra), source_covered=round(min((m.covered for m in matches), default=1.0), 3),
                   zigzag_cells=round(zigzag / h.cell_size, 2))
    return row


STALLS = os.path.join(ROOT, "bench", "output", "stalls")


def _keep_stalls(row: dict, V, F, net) -> None:
    """Where LM stalls (runs to its cap far from a solution) and the
    pipeline meshes again (pipeline._fresh_mesh), keep the input and the
    stalled tet mesh in bench/output/stalls/ (git-ignored), named in the
    row, so that ``--replay`` can solve on that very mesh: the stall comes
    on about 1 fTetWild mesh in 15 of some solids with handles, and its
    cause is not found."""
    import pickle

    import solver.pipeline as pl

    real = pl._fresh_mesh

    def keep(problem, res, *a, **kw):
        os.makedirs(STALLS, exist_ok=True)
        path = os.path.join(STALLS, f"{row['kind'].replace(' ', '-')}-{row['seed']}-{row['variant']}-"
                                    f"{time.strftime('%Y%m%d%H%M%S')}.pickle")
        with open(path, "wb") as fh:
            pickle.dump(dict(V=V, F=F, network=net, vertices=problem.mesh.vertices, tets=problem.mesh.tets,
                             penalty=float(res.report.lm.final.penalty)), fh)
        row["stall_mesh"] = os.path.relpath(path, ROOT)
        return real(problem, res, *a, **kw)

    pl._fresh_mesh = keep


def replay(path: str) -> dict:
    """Solve a kept stall (``_keep_stalls``) again on its own tet mesh."""
    import pickle

    from solver import FieldProblem
    from solver.mesh.tetmesh import TetMesh

    with open(path, "rb") as fh:
        d = pickle.load(fh)
    t0 = time.perf_counter()
    r = FieldProblem(d["V"], d["F"], d["network"], mesh=TetMesh(d["vertices"], d["tets"])).solve()
    return dict(stall=path, tets=len(d["tets"]), penalty_then=d["penalty"], status=r.report.status,
                penalty=float(r.report.lm.final.penalty), iterations=int(r.report.lm.n_iterations),
                seconds=round(time.perf_counter() - t0, 1))


HEADER = ("| input | curves | tets | LM its | penalty | field | cells | min / mean SJ | raw min | irregular edges vs "
          "given curves: far / max distance (cells) / least covered | cells within 20 % of the cell size | Hausdorff | "
          "s field + hex | bars missed |\n|---|---:|---:|---:|---:|---|---:|---|---:|---|---:|---:|---|---|")


def table(rows: list) -> str:
    """The Markdown table of bench/RESULTS.md ("Networks read off hex
    meshes") from the rows run_one wrote."""
    out = [HEADER]
    for r in rows:
        name = f"{r['kind']} {r['seed']}" + (" tet-edge" if r.get("variant") == "tet-edge" else "")
        missed = ", ".join(r.get("missed") or []) or "—"
        if "error" in r or "status" not in r:
            out.append(f"| {name} | {r.get('curves', '')} | | | | {r.get('error_kind', '')} | | | | | | | "
                       f"{r.get('total_s', '')} | {missed} |")
            continue
        again = any("solved again" in n for n in r.get("field_notes", []))
        local = "only through" in r.get("status_reason", "")  # report.local_excess
        field = r["status"] + (" (solved again)" if again else "") + (" (a local excess)" if local else "")
        if r.get("hex_error"):
            out.append(f"| {name} | {r['curves']} | {r['tets']:,} | {r['iterations']} | {r['penalty']} | {field} | "
                       f"| | | | | | {r['field_s']} + – | {missed} |")
            continue
        out.append(
            f"| {name} | {r['curves']} | {r['tets']:,} | {r['iterations']} | {r['penalty']} | {field} | "
            f"{r['hexes']:,} | {r['sj_min']:.3f} / {r['sj_mean']:.3f} | {r['sj_min_raw']:.2f} | "
            f"{r['given_extra']} / {r['given_distance_cells']:.2f} / {100 * r['given_covered']:.0f}% | "
            f"{100 * r['size_within']:.0f}% | {r['hausdorff_pct']:.2f}% | {r['field_s']} + {r['hex_s']} | {missed} |")
    return "\n".join(out)


def main() -> None:
    from testkit.hexnet import KINDS

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=list(KINDS))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--tet-edge", action="store_true", help="also each input's tet-edge variant")
    ap.add_argument("--write", action="store_true", help="write the rows to bench/hexnet.json (or --json)")
    ap.add_argument("--json", default="hexnet.json", help="with --write: the file's name in bench/")
    ap.add_argument("--transform", choices=TRANSFORMS, default="none", help="each input turned and moved, mirrored "
                    "or stretched (TRANSFORMS)")
    ap.add_argument("--scale", type=float, default=1.0, help="each input scaled by this (with --transform turn: "
                    "after the turn)")
    ap.add_argument("--table", action="store_true", help="print the Markdown table of bench/hexnet.json (or --json) "
                    "and stop")
    ap.add_argument("--replay", metavar="STALL", help="solve a stall kept in bench/output/stalls/ on its own mesh")
    ap.add_argument("--one", nargs=3, metavar=("KIND", "SEED", "VARIANT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.table:
        with open(os.path.join(ROOT, "bench", a.json)) as fh:
            print(table(json.load(fh)))
        return
    if a.replay:
        print(json.dumps(replay(a.replay)))
        return
    if a.one:
        print(json.dumps(run_one(a.one[0], int(a.one[1]), a.one[2] == "tet-edge", a.transform, a.scale)))
        return
    rows = []
    for kind in a.kinds:
        for seed in a.seeds:
            for variant in (["clean", "tet-edge"] if a.tet_edge else ["clean"]):
                t = time.perf_counter()
                p = subprocess.run([sys.executable, __file__, "--one", kind, str(seed), variant, "--transform",
                                    a.transform, "--scale", str(a.scale)], capture_output=True, text=True, cwd=ROOT)
                if p.returncode:
                    lines = p.stderr.strip().splitlines() or ["?"]
                    row = dict(kind=kind, seed=seed, variant=variant, error=lines[-1], error_kind="crash",
                               total_s=round(time.perf_counter() - t, 1))
                else:
                    row = json.loads(p.stdout.strip().splitlines()[-1])
                row["missed"] = bars(row)
                rows.append(row)
                print(json.dumps(row), flush=True)
    met = sum(1 for r in rows if not r["missed"])
    print(f"met every bar: {met} of {len(rows)}")
    if a.write:
        with open(os.path.join(ROOT, "bench", a.json), "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
