"""Dense-surface benchmark (issue 41e): the ball's network on icospheres of
1,280 (the example), 81,920, 327,680 and 1,310,720 triangles, and the
cylinder example's network on the sculpt-like cylinder of testkit/sculpt.py
(bumped wall, two sharp creases) of as many triangles, default options,
each run in a fresh process.

    ./dev.sh python bench/bench_dense.py                      # one line per input
    ./dev.sh python bench/bench_dense.py --subdivisions 3 6 7 --sculpt  # chosen sizes

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


def run_one(sub: int, sculpt: bool) -> dict:
    from solver import solve
    from solver.examples import ball_example
    from testkit.sculpt import sculpted_cylinder

    # the sculpt-like cylinder of about as many triangles as the icosphere
    V, F, net = sculpted_cylinder(20 * 4**sub) if sculpt else ball_example(subdivisions=sub)
    t = time.perf_counter()
    r = solve(V, F, net)
    total = time.perf_counter() - t
    rep, m = r.report, r.report.metrics
    st = rep.stage_seconds
    return dict(input="sculpt" if sculpt else "sphere", triangles=int(len(F)),
                mesher_triangles=int(rep.sizes.get("mesher_surface_triangles", len(F))),
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
    ap.add_argument("--subdivisions", type=int, nargs="+", help="icosphere subdivisions (default 3 6 7 8; "
                    "the sculpt-like cylinder: 20 x 4^n triangles)")
    ap.add_argument("--sculpt", action="store_true", help="only the sculpt-like cylinder")
    ap.add_argument("--sphere", action="store_true", help="only the spheres")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one is not None:
        print(json.dumps(run_one(int(a.one[0]), a.one[1] == "sculpt")))
        return
    runs = []
    if not a.sculpt:
        runs += [(sub, "sphere") for sub in (a.subdivisions or [3, 6, 7, 8])]
    if not a.sphere:
        runs += [(sub, "sculpt") for sub in (a.subdivisions or [3, 6, 7, 8])]
    for sub, kind in runs:
        p = subprocess.run([sys.executable, __file__, "--one", str(sub), kind], capture_output=True, text=True,
                           cwd=ROOT)
        if p.returncode:
            print(json.dumps(dict(input=kind, subdivisions=sub,
                                  error=(p.stderr.strip().splitlines() or ["?"])[-1])), flush=True)
        else:
            print(p.stdout.strip().splitlines()[-1], flush=True)


if __name__ == "__main__":
    main()
