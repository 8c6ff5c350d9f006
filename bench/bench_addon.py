"""Benchmark of the add-on's scene writing: 100k cross glyphs and 2,000
streamlines (target: under 2 s each).  Prints a markdown table; writes nothing.

    ./dev.sh python bench/bench_addon.py                      # cube, h = 0.3
    ./dev.sh python bench/bench_addon.py --example ball --edge-length 0.2

The field is solved once; glyph samples and streamlines are computed once
by solver.analysis.streamlines (timed separately, as "sampling"), then written into
the scene --repeat times (best time kept).  "write" is the add-on's bpy
work alone: building the datablocks and linking them into the scene.
"evaluate" is Blender building the 100k instances or the bevelled curves
(depsgraph evaluation), which the viewport pays on the next redraw.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load_addon():
    spec = importlib.util.spec_from_file_location("symframes", os.path.join(ROOT, "__init__.py"),
                                                  submodule_search_locations=[ROOT])
    mod = importlib.util.module_from_spec(spec)
    sys.modules["symframes"] = mod
    spec.loader.exec_module(mod)
    return mod


def best_of(repeat, fn):
    """(best time, worst time, last result) of repeat calls."""
    times, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), max(times), out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--example", default="cube")
    ap.add_argument("--edge-length", type=float, default=0.3)
    ap.add_argument("--glyphs", type=int, default=100_000)
    ap.add_argument("--streamlines", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()

    import bpy

    addon = load_addon()
    addon.register()
    from symframes.solver import sample_glyphs, seed_points, trace_streamlines
    from symframes.symframes_addon import glyphs, storage, streamline_curves

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.symframes.add_example(example=args.example)
    scene = bpy.context.scene
    s = scene.symframes
    s.edge_length = args.edge_length
    t = time.perf_counter()
    bpy.ops.symframes.compute(glyphs=False)
    t_solve = time.perf_counter() - t
    field = storage.frame_field(scene)

    t_gs, _, (P, Q) = best_of(1, lambda: sample_glyphs(field, count=args.glyphs, seed=0))
    seeds = seed_points(field, args.streamlines, seed=0)
    t_ls, _, lines = best_of(1, lambda: trace_streamlines(field, seeds, family=0))
    fams = [0] * len(lines)
    n_pts = sum(len(p) for p in lines)

    dg = bpy.context.evaluated_depsgraph_get

    def write_glyphs():
        return glyphs.write_glyphs(scene, P, Q)

    def eval_glyphs():
        obj = storage.output_object(scene, "glyphs")
        obj.update_tag()
        geo = obj.evaluated_get(dg()).evaluated_geometry()
        return len(geo.instances_pointcloud().points)

    def write_lines():
        return streamline_curves.write_streamlines(scene, lines, fams, 0.004)

    def eval_lines():
        obj = storage.output_object(scene, "streamlines")
        obj.update_tag()
        return len(obj.evaluated_get(dg()).to_mesh().vertices)

    t_gw, w_gw, _ = best_of(args.repeat, write_glyphs)
    t_ge, w_ge, n_inst = best_of(args.repeat, eval_glyphs)
    t_lw, w_lw, _ = best_of(args.repeat, write_lines)
    t_le, w_le, n_tube = best_of(args.repeat, eval_lines)
    assert n_inst == len(P), (n_inst, len(P))

    rep = storage.stored_report(scene)
    print(f"\n{args.example}, edge length {args.edge_length}: {rep.sizes['tets']:,} tets, solved in "
          f"{t_solve:.1f} s; best (worst) of {args.repeat}; Blender {bpy.app.version_string}, "
          f"{os.cpu_count()} CPUs\n")
    print("| what | count | sampling (solver) | write (add-on) | evaluate (Blender) |")
    print("|---|---:|---:|---:|---:|")
    print(f"| cross glyphs | {len(P):,} instances | {t_gs:.2f} s | {t_gw:.3f} ({w_gw:.3f}) s | "
          f"{t_ge:.3f} ({w_ge:.3f}) s |")
    print(f"| streamlines | {len(lines):,} lines, {n_pts:,} points | {t_ls:.2f} s | {t_lw:.3f} ({w_lw:.3f}) s | "
          f"{t_le:.3f} ({w_le:.3f}) s, {n_tube:,} tube vertices |")
    ok = w_gw < 2.0 and w_lw < 2.0
    print(f"\nwrite target < 2 s each: {'met' if ok else 'NOT met'}")
    addon.unregister()


if __name__ == "__main__":
    main()
