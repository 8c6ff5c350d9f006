"""Genus-2 benchmark (issue 41c): the testkit/genus2.py family, default
options, each run in a fresh process.

    ./dev.sh python bench/bench_genus2.py --seeds 0 1 2 3 4          # print one line per run
    ./dev.sh python bench/bench_genus2.py --seeds 0 1 2 3 4 --tet-edge --write   # also bench/genus2.json

A run is the block with 2-3 pairs of +-1/4 curves from an outer wall to the
hole wall facing it, ends 15-40 degrees off the normal; with --tet-edge
also its tet-edge variant (testkit/tetedge.py: the curves routed along an
independent fTetWild mesh at h = 0.12).  Recorded: status, penalty and its
bound, LM iterations, tets, omega-matched spurious/missing singular faces,
tangent and normal adaptation, seconds end to end and the meshing share.
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
TET_EDGE_H = 0.12


def run_one(seed: int, tet_edge: bool) -> dict:
    from solver import solve
    from testkit.genus2 import end_angles, genus2_family

    V, F, net = genus2_family(seed)
    if tet_edge:
        from testkit.tetedge import tet_edge_network

        net, _ = tet_edge_network(V, F, net, TET_EDGE_H, seed=seed)
    ang = end_angles(V, F, net)
    t = time.perf_counter()
    r = solve(V, F, net)
    total = time.perf_counter() - t
    rep, m = r.report, r.report.metrics
    return dict(seed=seed, variant="tet-edge" if tet_edge else "clean", curves=len(net.curves),
                end_deg=[round(float(ang.min()), 1), round(float(ang.max()), 1)],
                status=rep.status, penalty=round(float(rep.lm.final.penalty), 3),
                bound=round(1.0 + 0.25 * float(rep.lm.final.smoothness), 2),
                iterations=int(rep.lm.n_iterations), tets=int(rep.sizes.get("tets", 0)),
                omega_spurious=int(m.get("omega_spurious_singular_faces", -1)),
                omega_missing=int(m.get("omega_missing_singular_faces", -1)),
                tangent_mean_deg=round(float(m["tangent_adaptation_mean_deg"]), 3),
                normal_mean_deg=round(float(m["normal_adaptation_mean_deg"]), 3),
                seconds=round(total, 1), tetmesh_s=round(float(rep.stage_seconds.get("tetmesh", 0.0)), 1),
                mesh_share=round(float(rep.stage_seconds.get("tetmesh", 0.0)) / total, 2))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    ap.add_argument("--tet-edge", action="store_true", help="also the tet-edge variant of each seed")
    ap.add_argument("--write", action="store_true", help="write bench/genus2.json")
    ap.add_argument("--one", nargs=2, metavar=("SEED", "VARIANT"), help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        print(json.dumps(run_one(int(a.one[0]), a.one[1] == "tet-edge")))
        return
    rows = []
    for seed in a.seeds:
        for variant in (["clean", "tet-edge"] if a.tet_edge else ["clean"]):
            p = subprocess.run([sys.executable, __file__, "--one", str(seed), variant], capture_output=True,
                               text=True, cwd=ROOT)
            if p.returncode:
                row = dict(seed=seed, variant=variant, error=(p.stderr.strip().splitlines() or ["?"])[-1])
            else:
                row = json.loads(p.stdout.strip().splitlines()[-1])
            rows.append(row)
            print(json.dumps(row), flush=True)
    if a.write:
        with open(os.path.join(ROOT, "bench", "genus2.json"), "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
