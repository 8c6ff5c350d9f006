"""fTetWild's simplification of its input, on and off, for surfaces with sharp
features, where it was on for surfaces over 3x as dense as their mesh and is
now off (solver/mesh/tetwild.py: wants_simplify).

    ./dev.sh python bench/bench_simplify.py            # print the table
    ./dev.sh python bench/bench_simplify.py --write    # also bench/RESULTS.md

Each input is meshed and solved twice with default options but the budget
(FieldProblem, then solve): once with fTetWild simplifying the surface and
the curve tubes, once not.  Reported: the meshing stage's seconds (retries
included), its tets, the LM iterations, whether it converged, and the
omega-matched spurious and missing singular faces.  fTetWild is not
deterministic: these are single runs.  Inputs: the cylinder example at its
default resolution and at a 2,500-tet budget, and the sharp kinds of
testkit/hexnet.py at that budget: 2.5-14x the triangles of an h-mesh.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from run_bench import machine, write_results_block  # noqa: E402  (bench/ is the script's directory, on sys.path)

import solver.mesh.tetwild as tetwild  # noqa: E402
from solver import FieldProblem, Options  # noqa: E402
from solver.examples import load_example  # noqa: E402
from testkit.hexnet import hexnet_input  # noqa: E402

BUDGET = 2500
KINDS = ("plate", "genus2", "hollow", "prism", "L-part", "polygon cylinder")


def inputs():
    """(name, V, F, network, options) of each input."""
    V, F, net = load_example("cylinder")
    yield "cylinder example, default", V, F, net, {}
    yield f"cylinder example, {BUDGET:,} tets", V, F, net, {"target_tets": BUDGET}
    for kind in KINDS:
        d = hexnet_input(kind, 0)
        yield f"hexnet {kind}, {BUDGET:,} tets", d["V"], d["F"], d["network"], {"target_tets": BUDGET}


def run(V, F, net, options: dict, simplify: bool) -> dict:
    """Mesh and solve with fTetWild's simplification forced on or off for
    sharp surfaces (smooth ones keep the rule's answer, always on)."""
    rule = tetwild.wants_simplify
    tetwild.wants_simplify = lambda sharp: simplify if sharp else rule(sharp)
    try:
        t = time.perf_counter()
        problem = FieldProblem(V, F, net, Options(**options))
        mesh_s = time.perf_counter() - t
    finally:
        tetwild.wants_simplify = rule
    r = problem.solve()
    m = r.report.metrics
    return {"mesh_s": mesh_s, "tets": problem.mesh.n_tets, "its": len(r.report.lm.iterations),
            "converged": r.report.lm.converged, "spurious": m.get("omega_spurious_singular_faces"),
            "missing": m.get("omega_missing_singular_faces")}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--write", action="store_true", help="write the table into bench/RESULTS.md")
    args = ap.parse_args()
    rows = ["| input | simplified: mesh s, tets, LM its | not: mesh s, tets, LM its | faster | tets |",
            "|---|---:|---:|---:|---:|"]
    for name, V, F, net, options in inputs():
        on, off = run(V, F, net, options, True), run(V, F, net, options, False)

        def cell(x):
            ok = "" if x["converged"] and not x["spurious"] and not x["missing"] else \
                f" (converged {x['converged']}, {x['spurious']} spurious, {x['missing']} missing)"
            return f"{x['mesh_s']:.1f}, {x['tets']:,}, {x['its']}{ok}"

        rows.append(f"| {name} | {cell(on)} | {cell(off)} | {on['mesh_s'] / off['mesh_s']:.1f}x "
                    f"| {100.0 * (off['tets'] / on['tets'] - 1.0):+.0f} % |")
        print(rows[-1], flush=True)
    text = f"{machine()}; single runs.\n\n" + "\n".join(rows)
    print(text)
    if args.write:
        write_results_block("simplify-bench", text, "fTetWild's simplification of sharp surfaces")
    return 0


if __name__ == "__main__":
    sys.exit(main())
