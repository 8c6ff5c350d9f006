"""The solver's LM against a straightforward LM that factorises every
normal-equation system with SciPy's sparse LU (issue 5), on the same mesh.

    ./dev.sh python bench/lu_baseline.py                    # ball at ~10k, 20k, 40k tets
    ./dev.sh python bench/lu_baseline.py --tets 10000 20000 --write

Both runs use the same LM loop (solver/field/volume3d.py: acceptance, damping,
stopping) and differ in the step: the solver's (preconditioned CG with the
block-Jacobi + auxiliary-space AMG preconditioner, Newton steps and eigCG
deflation near the minimum), or ``splu`` of the assembled damped
Gauss-Newton matrix.  The LU run happens in a forked child
that is stopped after --limit seconds (default 600); sizes grow until the
baseline no longer finishes.  Reported: the LM time of each, the speed-up,
the relative energy difference, and the LU child's peak memory.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import platform
import resource
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from run_bench import machine, write_results_block  # noqa: E402  (bench/ is the script's directory, on sys.path)


def _lu_child(vp, x0, conn):
    t = time.perf_counter()
    x, rep = vp.solve(x0, direct=True)
    conn.send({"seconds": time.perf_counter() - t, "energy": rep.final.energy, "iterations": rep.n_iterations,
               "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, "reason": rep.reason})
    conn.close()


def compare(example: str, tets: int, limit: float) -> dict:
    import numpy as np

    from solver import FieldProblem, Options
    from solver.examples import load_example

    V, F, net = load_example(example)
    p = FieldProblem(V, F, net, Options(target_tets=tets))
    vp = p.volume
    x0 = np.zeros(p.constraints.n_unknowns)
    t = time.perf_counter()
    _, rep = vp.solve(x0)
    row = {"tets": p.mesh.n_tets, "edges": p.mesh.n_edges, "unknowns": len(x0),
           "cg": {"seconds": time.perf_counter() - t, "energy": rep.final.energy, "iterations": rep.n_iterations,
                  "reason": rep.reason}}
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_lu_child, args=(vp, x0, send))
    child.start()
    send.close()
    lu = recv.recv() if recv.poll(limit) else None
    if child.is_alive():
        child.kill()
    child.join()
    row["lu"] = lu
    return row


def table(rows: list[dict], limit: float) -> str:
    lines = ["| tets | edges | unknowns | CG LM s (its) | LU LM s (its) | speed-up | energy rel. diff | LU peak MB |",
             "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        cg, lu = r["cg"], r["lu"]
        if lu is None:
            lu_cells = f"> {limit:.0f} (stopped) | > {limit / cg['seconds']:.0f}x | - | -"
        else:
            diff = abs(lu["energy"] - cg["energy"]) / abs(lu["energy"])
            lu_cells = (f"{lu['seconds']:.1f} ({lu['iterations']}) | {lu['seconds'] / cg['seconds']:.1f}x | "
                        f"{diff:.1e} | {lu['peak_mb']:.0f}")
        lines.append(f"| {r['tets']:,} | {r['edges']:,} | {r['unknowns']:,} | "
                     f"{cg['seconds']:.1f} ({cg['iterations']}) | " + lu_cells + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--example", default="ball")
    p.add_argument("--tets", type=int, nargs="+", default=[10000, 20000, 40000])
    p.add_argument("--limit", type=float, default=600.0, help="seconds before the LU run is stopped")
    p.add_argument("--write", action="store_true", help="write the table into bench/RESULTS.md")
    args = p.parse_args(argv)
    rows = []
    for n in args.tets:
        print(f"[lu-baseline] {args.example} ~{n:,} tets ...", file=sys.stderr, flush=True)
        r = compare(args.example, n, args.limit)
        rows.append(r)
        lu = r["lu"]
        print(f"[lu-baseline]   {r['tets']:,} tets: CG {r['cg']['seconds']:.1f} s, "
              + ("LU stopped" if lu is None else f"LU {lu['seconds']:.1f} s"), file=sys.stderr, flush=True)
        if lu is None:
            break
    text = table(rows, args.limit)
    text += (f"\n\nLM time only (same mesh, same LM loop; meshing excluded). Machine: {machine()}, "
             f"Python {platform.python_version()}.")
    print(text)
    if args.write:
        write_results_block("lu-baseline", f"{args.example} (`./dev.sh python bench/lu_baseline.py --write`):"
                                           f"\n\n{text}", "Against a sparse-LU LM")
    return 0


if __name__ == "__main__":
    sys.exit(main())
