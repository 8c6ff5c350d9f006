"""Dense-surface benchmark (issue 41e): the ball's network on icospheres of
1,280 (the example), 20,480, 81,920 and 327,680 triangles, default options,
each run in a fresh process.

    ./dev.sh python bench/bench_dense.py                      # one line per size
    ./dev.sh python bench/bench_dense.py --subdivisions 3 6 7  # chosen sizes

Recorded: the triangles the mesher got (mesh/decimate.py), seconds per
stage and end to end, the meshing share, status, penalty, LM iterations
and the field's measures (omega-matched spurious/missing singular faces,
normal and tangent adaptation).
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


def run_one(sub: int) -> dict:
    from solver import solve
    from solver.examples import ball_example

    V, F, net = ball_example(subdivisions=sub)
    t = time.perf_counter()
    r = solve(V, F, net)
    total = time.perf_counter() - t
    rep, m = r.report, r.report.metrics
    st = rep.stage_seconds
    return dict(triangles=int(len(F)), mesher_triangles=int(rep.sizes.get("mesher_surface_triangles", len(F))),
                tets=int(rep.sizes.get("tets", 0)), status=rep.status,
                penalty=round(float(rep.lm.final.penalty), 3), iterations=int(rep.lm.n_iterations),
                validate_s=round(st.get("validate", 0.0), 1), tetmesh_s=round(st.get("tetmesh", 0.0), 1),
                volume3d_s=round(st.get("volume3d", 0.0), 1), seconds=round(total, 1),
                mesh_share=round(st.get("tetmesh", 0.0) / total, 2),
                omega_spurious=int(m.get("omega_spurious_singular_faces", -1)),
                omega_missing=int(m.get("omega_missing_singular_faces", -1)),
                normal_mean_deg=round(float(m["normal_adaptation_mean_deg"]), 3),
                tangent_mean_deg=round(float(m["tangent_adaptation_mean_deg"]), 3))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subdivisions", type=int, nargs="+", default=[3, 5, 6, 7])
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one is not None:
        print(json.dumps(run_one(a.one)))
        return
    for sub in a.subdivisions:
        p = subprocess.run([sys.executable, __file__, "--one", str(sub)], capture_output=True, text=True, cwd=ROOT)
        if p.returncode:
            print(json.dumps(dict(subdivisions=sub, error=(p.stderr.strip().splitlines() or ["?"])[-1])), flush=True)
        else:
            print(p.stdout.strip().splitlines()[-1], flush=True)


if __name__ == "__main__":
    main()
