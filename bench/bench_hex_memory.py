"""Hex-stage memory on dense surfaces (issue 52): the solve's peak against
the hex stages' peak, per stage, each input in a fresh process.

    ./dev.sh python bench/bench_hex_memory.py                      # the 1.3M-triangle ball and a 500k sculpt
    ./dev.sh python bench/bench_hex_memory.py --input sphere:7      # one input (icosphere subdivisions)
    ./dev.sh python bench/bench_hex_memory.py --input sculpt:500000 # the sculpt-like cylinder of ~500k triangles
    ./dev.sh python bench/bench_hex_memory.py --cells cube:20000 cube:100000   # memory per cell

Each run solves with default options (``solve``), then meshes the field at
the default cell size (``hexmesh``), as ``python -m solver ... --hex`` does.
A thread samples the resident set (/proc/self/statm) every 20 ms and files
each sample under the stage running then (the progress callback), so each
row says which stage set the peak. Target: the hex stages' peak at most
0.5 GB above the solve's own peak.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

INPUTS = ("sphere:8", "sculpt:500000")


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


class Sampler:
    """The resident set's peak per named phase, sampled in a thread."""

    def __init__(self, period: float = 0.02):
        self.phase, self.peaks, self.period = "start", {}, period
        self._stop = threading.Event()
        self._t = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        while not self._stop.is_set():
            self.note()
            time.sleep(self.period)

    def note(self):
        """Take one sample now."""
        r = _rss_mb()
        self.peaks[self.phase] = max(self.peaks.get(self.phase, 0.0), r)

    def set(self, phase: str):
        """Samples from now on belong to ``phase``."""
        self.note()
        self.phase = phase
        self.note()

    def __enter__(self):
        self._t.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._t.join()
        self.note()


def _input(spec: str):
    kind, n = spec.split(":")
    if kind == "sphere":
        from solver.examples import ball_example

        return ball_example(subdivisions=int(n))
    from testkit.sculpt import sculpted_cylinder

    return sculpted_cylinder(int(n))


def run_one(spec: str) -> dict:
    from solver import hexmesh, solve

    V, F, net = _input(spec)
    with Sampler() as s:
        s.set("solve")
        t = time.perf_counter()
        res = solve(V, F, net)
        solve_s = time.perf_counter() - t
        s.set("hex")
        t = time.perf_counter()
        hm = hexmesh(res, progress=lambda stage, frac, msg: s.set("hex " + stage))
        hex_s = time.perf_counter() - t
    solve_peak = s.peaks["solve"]
    hex_peaks = {k[4:]: round(v) for k, v in s.peaks.items() if k.startswith("hex ")}
    hex_peak = max(hex_peaks.values())
    return dict(input=spec, triangles=int(len(F)), tets=int(res.mesh.n_tets), solve_s=round(solve_s, 1),
                hex_s=round(hex_s, 1), hexes=int(hm.report.hexes), status=hm.report.status,
                hausdorff_pct=round(100 * hm.report.hausdorff_relative, 3), solve_peak_mb=round(solve_peak),
                hex_peak_mb=round(hex_peak), over_solve_mb=round(hex_peak - solve_peak),
                peak_stage=max(hex_peaks, key=hex_peaks.get), stage_peaks_mb=hex_peaks,
                quality_s=round(hm.report.stage_seconds.get("quality", 0.0), 1))


def run_cells(spec: str) -> dict:
    """example:cells[:edge length] -- the example solved (at defaults, or
    at that edge length), then meshed at the
    cell size for about that many cells: the hex stages' peak above the
    resident set the solve left (what the per-cell estimate is fitted to)."""
    from solver import default_cell_size, hexmesh, solve
    from solver.examples import load_example

    name, cells, *h = spec.split(":")
    V, F, net = load_example(name)
    res = solve(V, F, net, edge_length=float(h[0]) if h else None)
    inp = res.field
    cell = default_cell_size(inp, int(cells))
    with Sampler() as s:
        s.set("before")
        t = time.perf_counter()
        hm = hexmesh(inp, cell, progress=lambda stage, frac, msg: s.set("hex " + stage))
        hex_s = time.perf_counter() - t
    base = s.peaks["before"]
    hex_peaks = {k[4:]: round(v - base) for k, v in s.peaks.items() if k.startswith("hex ")}
    return dict(input=spec, tets=int(res.mesh.n_tets), split_tets=int(hm.report.sizes.get("tets", 0)),
                cell=round(cell, 4), hexes=int(hm.report.hexes), status=hm.report.status, hex_s=round(hex_s, 1),
                base_mb=round(base), over_base_mb=max(hex_peaks.values()),
                peak_stage=max(hex_peaks, key=hex_peaks.get), stage_peaks_mb=hex_peaks)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--input", nargs="+", default=list(INPUTS), help="sphere:SUBDIVISIONS or sculpt:TRIANGLES")
    ap.add_argument("--cells", nargs="+", help="EXAMPLE:CELLS[:EDGE_LENGTH], e.g. cube:100000: the hex stages' "
                    "peak above the solve's resident set at that many cells (the per-cell memory figure)")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--one-cells", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        print(json.dumps(run_one(a.one)))
        return
    if a.one_cells:
        print(json.dumps(run_cells(a.one_cells)))
        return
    jobs = [("--one-cells", c) for c in a.cells] if a.cells else [("--one", i) for i in a.input]
    for flag, spec in jobs:
        p = subprocess.run([sys.executable, __file__, flag, spec], capture_output=True, text=True, cwd=ROOT)
        if p.returncode:
            print(json.dumps(dict(input=spec, error=(p.stderr.strip().splitlines() or ["?"])[-1])), flush=True)
        else:
            print(p.stdout.strip().splitlines()[-1], flush=True)


if __name__ == "__main__":
    main()
