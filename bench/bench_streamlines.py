"""Benchmark of solver/analysis/streamlines.py on a solved example: glyph sampling and
streamline tracing.  Prints a table; writes nothing.

    ./dev.sh python bench/bench_streamlines.py                  # ball, h = 0.12
    ./dev.sh python bench/bench_streamlines.py --example cylinder --edge-length 0.1

Times are the best of --repeat runs (wall clock and CPU of this process).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from solver import solve  # noqa: E402
from solver.analysis.streamlines import FrameField, sample_glyphs, seed_points, trace_streamlines  # noqa: E402
from solver.examples import load_example  # noqa: E402


def best_of(repeat, fn):
    wall, cpu, out = [], [], None
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu), out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--example", default="ball")
    ap.add_argument("--edge-length", type=float, default=0.12)
    ap.add_argument("--glyphs", type=int, default=100_000)
    ap.add_argument("--seeds", type=int, default=2_000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    t0 = time.perf_counter()
    V, F, net = load_example(args.example)
    result = solve(V, F, net, edge_length=args.edge_length)
    solve_s = time.perf_counter() - t0
    mesh = result.mesh
    print(f"{args.example}, edge_length {args.edge_length}: {mesh.n_tets:,} tets, {mesh.n_vertices:,} vertices, "
          f"mean edge {mesh.mean_edge_length:.4f}; solved in {solve_s:.1f} s; {os.cpu_count()} cores")

    rows = []

    def build():
        f = FrameField.from_field(result.field)
        f.frames_at(mesh.vertices[:1])  # builds the per-tet matching table
        return f

    wall, cpu, field = best_of(args.repeat, build)
    rows.append(("FrameField.from_field + matching table", "", wall, cpu))

    wall, cpu, (P, _) = best_of(args.repeat, lambda: sample_glyphs(field, count=args.glyphs))
    rows.append((f"sample_glyphs(count={args.glyphs:,})", f"{len(P):,} glyphs", wall, cpu))

    wall, cpu, (P, _) = best_of(args.repeat, lambda: sample_glyphs(field, count=args.glyphs, clip_normal=(1, 0, 0)))
    rows.append((f"sample_glyphs(count={args.glyphs:,}, clipped)", f"{len(P):,} glyphs", wall, cpu))

    seeds = seed_points(field, args.seeds, seed=0)
    for family, method in ((0, "rk2"), (0, "rk4"), ("all", "rk2")):
        wall, cpu, lines = best_of(
            args.repeat, lambda fam=family, m=method: trace_streamlines(field, seeds, family=fam, method=m)
        )
        npts = sum(len(p) for p in lines)
        length = sum(float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in lines)
        rows.append((
            f"trace_streamlines({args.seeds:,} seeds, family={family!r}, {method})",
            f"{len(lines):,} lines, {npts:,} pts, mean length {length / max(len(lines), 1):.2f}",
            wall,
            cpu,
        ))

    w = max(len(r[0]) for r in rows)
    o = max(len(r[1]) for r in rows)
    print(f"{'operation':<{w}}  {'output':<{o}}  {'wall s':>7}  {'cpu s':>7}")
    for name, out, wall, cpu in rows:
        print(f"{name:<{w}}  {out:<{o}}  {wall:7.3f}  {cpu:7.3f}")


if __name__ == "__main__":
    main()
