"""The hex stages 'transitions' and 'map system' timed on their own, on the
fields of five inputs.

    ./dev.sh python bench/bench_map_system.py            # print the table
    ./dev.sh python bench/bench_map_system.py --write    # (re)write bench/RESULTS.md's block

Each input (the built-in cylinder, plate and ball; the bench family's
genus-2 0 and hollow 0, testkit/hexnet.py) is solved with the default
options and meshed once with ``hexmesh``, which hands the two stages their
inputs (the split mesh, the field, the transitions); each stage is then run
again on those, best of 3, with one BLAS thread.  Both stages work on every
tet of the split mesh whatever the cell size (docs/performance.md, "The hex
map system").
"""

from __future__ import annotations

import argparse
import importlib
import os
import platform
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

INPUTS = (("cylinder", None), ("plate", None), ("ball", None), ("genus2", 0), ("hollow", 0))


def _input(name: str, seed):
    from solver.examples import load_example
    from testkit.hexnet import hexnet_input

    if seed is None:
        return load_example(name)
    d = hexnet_input(name, seed)
    return d["V"], d["F"], d["network"]


def captured(name: str, seed) -> dict:
    """The arguments ``hexmesh`` gave the two stages' builders (the first
    call of each) on a default solve of the input."""
    from solver import hexmesh, solve

    stages = {"build_transitions": importlib.import_module("solver.hexmesh.transitions"),
              "build_map_system": importlib.import_module("solver.hexmesh.seamless")}
    calls = {}
    originals = {k: getattr(m, k) for k, m in stages.items()}

    def recording(key):
        def run(*args, **kwargs):
            calls.setdefault(key, (args, kwargs))
            return originals[key](*args, **kwargs)
        return run

    for key, module in stages.items():
        setattr(module, key, recording(key))
    try:
        hexmesh(solve(*_input(name, seed)))
    finally:
        for key, module in stages.items():
            setattr(module, key, originals[key])
    return calls


def best_of(fn, args, kwargs, runs: int = 3) -> float:
    best = float("inf")
    for _ in range(runs):
        t = time.perf_counter()
        fn(*args, **kwargs)
        best = min(best, time.perf_counter() - t)
    return best


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--write", action="store_true", help="write the table into bench/RESULTS.md")
    args = p.parse_args(argv)
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    lines = ["| input | split tets | transitions (s) | map system (s) |", "|---|---:|---:|---:|"]
    for name, seed in INPUTS:
        calls = captured(name, seed)
        tr_args, tr_kw = calls["build_transitions"]
        ms_args, ms_kw = calls["build_map_system"]
        t_tr = best_of(importlib.import_module("solver.hexmesh.transitions").build_transitions, tr_args, tr_kw)
        t_ms = best_of(importlib.import_module("solver.hexmesh.seamless").build_map_system, ms_args, ms_kw)
        label = name if seed is None else f"{name} {seed}"
        lines.append(f"| {label} | {ms_args[0].mesh.n_tets:,} | {t_tr:.3f} | {t_ms:.3f} |")
        print(lines[-1], flush=True)
    from run_bench import machine, write_results_block

    text = "\n".join(lines) + f"\n\nBest of 3 per stage. Machine: {machine()}, Python {platform.python_version()}."
    if args.write:
        write_results_block("map-bench", "`./dev.sh python bench/bench_map_system.py --write`:\n\n" + text,
                            "Hex map system")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
