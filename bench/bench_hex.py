"""Hex-meshing benchmark: seconds per hex stage, quality and peak memory on
the ball's field at ~50k tets, each run in a fresh process.

    ./dev.sh python bench/bench_hex.py                 # one run
    ./dev.sh python bench/bench_hex.py --runs 2 --write   # (re)write bench/RESULTS.md's hex table

Each run solves the ball example at an edge length that gives ~50k tets,
then meshes the field at the default cell size (about 3,000 cells) and at
one for about 12,000 (--cells: others, e.g. 100000). Target: the hex stages
within 60 s at 50k tets on the 2-core bench machine (issue 40).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

EDGE_LENGTH = 0.088  # the ball at this edge length: ~50k tets (about 10 tets per h^3 of volume)
CELLS = (3000, 12000)


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_one(cells_aimed=CELLS) -> dict:
    from solver import default_cell_size, hexmesh, solve
    from solver.examples import load_example

    V, F, net = load_example("ball")
    t0 = time.perf_counter()
    res = solve(V, F, net, edge_length=EDGE_LENGTH)
    field_s = time.perf_counter() - t0
    field_mb = _rss_mb()
    inp = res.field
    rows = []
    for cells in cells_aimed:
        cell = default_cell_size(inp, cells)
        t = time.perf_counter()
        hm = hexmesh(inp, cell)
        r = hm.report
        rows.append({"target": cells, "cell": cell, "seconds": time.perf_counter() - t, "stages": r.stage_seconds,
                     "hexes": r.hexes, "status": r.status, "sj_min": r.sj_min, "sj_mean": r.sj_mean,
                     "sj_min_raw": r.sj_min_raw, "sj_mean_raw": r.sj_mean_raw, "sj_irregular": r.sj_mean_irregular,
                     "irregular": r.irregular, "exact": r.structure_exact, "hausdorff": r.hausdorff_relative,
                     "size_within": r.size_within, "size_p5": r.size_p5, "size_p95": r.size_p95,
                     "split_tets": r.sizes.get("tets", 0), "peak_mb": _rss_mb()})
    return {"tets": res.mesh.n_tets, "field_s": field_s, "field_status": res.report.status, "field_mb": field_mb,
            "rows": rows}


def _stages() -> tuple:
    """The hex stages' names in the order they run (hexmesh.STAGE_WEIGHTS)."""
    from solver.hexmesh.mesher import STAGE_WEIGHTS

    return tuple(STAGE_WEIGHTS)


STAGES = _stages()


def table(runs: list[dict]) -> str:
    head = ("| field tets | cells | " + " | ".join(STAGES) + " | hex s | hexes | min / mean SJ (raw) | "
            "at irregular | structure | Hausdorff | peak MB |")
    lines = [head, "|" + "---:|" * (len(STAGES) + 9)]
    for run in runs:
        for r in run["rows"]:
            st = " | ".join(f"{r['stages'].get(s, 0.0):.1f}" for s in STAGES)
            irr = ", ".join(f"{n}×v{v}" for v, n in sorted(r["irregular"].items(), key=lambda x: int(x[0])))
            lines.append(f"| {run['tets']:,} | ~{r['target']:,} | {st} | {r['seconds']:.1f} | {r['hexes']:,} | "
                         f"{r['sj_min']:.2f} / {r['sj_mean']:.3f} ({r['sj_min_raw']:.2f} / {r['sj_mean_raw']:.3f}) | "
                         f"{r['sj_irregular']:.3f} | {'exact' if r['exact'] else 'NOT exact'} ({irr}) | "
                         f"{100 * r['hausdorff']:.2f}% | {r['peak_mb']:.0f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=1, help="fresh field meshes (fTetWild is not deterministic)")
    p.add_argument("--write", action="store_true", help="write the table into bench/RESULTS.md")
    p.add_argument("--cells", type=int, nargs="+", default=list(CELLS),
                   help="cell counts aimed at (default: %(default)s)")
    p.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # internal: one run, print JSON
    args = p.parse_args(argv)
    if args.one:
        print("RESULT " + json.dumps(run_one(tuple(args.cells)), default=float))
        return 0
    runs = []
    for k in range(args.runs):
        print(f"[bench_hex] run {k + 1} of {args.runs}: ball at edge length {EDGE_LENGTH} ...", file=sys.stderr,
              flush=True)
        out = subprocess.run([sys.executable, os.path.abspath(__file__), "--one", "--cells", *map(str, args.cells)],
                             capture_output=True, text=True)
        line = [x for x in out.stdout.splitlines() if x.startswith("RESULT ")]
        if out.returncode != 0 or not line:
            print(out.stderr[-3000:], file=sys.stderr)
            return 1
        runs.append(json.loads(line[0][7:]))
    from run_bench import machine, write_results_block

    text = table(runs)
    text += ("\n\nSeconds per hex stage (wall clock) after the field solve; 'raw' is before smoothing; 'at "
             "irregular' the mean scaled Jacobian of the cells touching an irregular edge; peak MB the process's "
             "resident peak (the field solve included; it reached "
             + ", ".join(f"{r['field_mb']:.0f}" for r in runs) + " MB before hex meshing).")
    text += f"\n\nMachine: {machine()}, Python {platform.python_version()}."
    print(text)
    if args.write:
        cells = "" if tuple(args.cells) == CELLS else " --cells " + " ".join(map(str, args.cells))
        write_results_block("hex-bench", "Ball at ~50k tets (`./dev.sh python bench/bench_hex.py --runs "
                            f"{args.runs}{cells} --write`):\n\n{text}", "Hex meshing")
    return 0


if __name__ == "__main__":
    sys.exit(main())
