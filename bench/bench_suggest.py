"""Suggested networks (issue 49): closed solids with no network, suggest ->
solve -> hex mesh with default options, each run in a fresh process.

    ./dev.sh python bench/bench_suggest.py                    # every solid: a line per run
    ./dev.sh python bench/bench_suggest.py --solids sphere box_2x1x1
    ./dev.sh python bench/bench_suggest.py --write            # also bench/suggest.json
    ./dev.sh python bench/bench_suggest.py --solids torus --write   # re-run some: their rows replaced
    ./dev.sh python bench/bench_suggest.py --known --write    # the hand-made networks of the same solids

The solids are generated here (no data): spheres and ellipsoids, smooth
random radial blobs, rounded boxes, boxes and voxel L-, T- and U-parts,
twisted and bent bars, cylinders, tori, the built-in examples' surfaces,
and a dense noisy sphere; several are turned by a random rotation so that
nothing lines up with the axes.  A run is judged by issue 49's bars:
converged field; 100 % hexes, 0 inverted, min scaled Jacobian >= 0.3,
mean >= 0.90.  Recorded per run: the suggestion (curves by index, nodes,
charts, depth), the field (tets, status), the hex mesh (cells, quality,
status) and the seconds per stage, or the refusal's kind and message.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def _rotation(seed: int) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.random(random_state=seed).as_matrix()


def _radial(V, F, fn):
    d = V / np.linalg.norm(V, axis=1, keepdims=True)
    return d * fn(d)[:, None], F


def _blob(seed: int, sub: int = 4, amp: float = 0.25):
    from solver.examples import icosphere

    rng = np.random.default_rng(seed)
    V, F = icosphere(sub)
    k = rng.normal(size=(4, 3)) * 1.5
    ph = rng.uniform(0, 2 * np.pi, 4)
    a = rng.uniform(0.3, 1.0, 4) * amp / 2

    def fn(d):
        return 1.0 + sum(a[i] * np.sin(d @ k[i] + ph[i]) for i in range(4))

    return _radial(V, F, fn)


def _superquadric(p: float, scale=(1.0, 1.0, 1.0)):
    from solver.examples import icosphere

    V, F = icosphere(4)
    d = V / np.linalg.norm(V, axis=1, keepdims=True)
    r = (np.abs(d) ** p).sum(axis=1) ** (-1.0 / p)
    return d * r[:, None] * np.asarray(scale), F


def _twisted(turn_deg: float, bend: float = 0.0):
    from solver.examples import box

    V, F = box((-0.4, -0.4, -1.5), (0.4, 0.4, 1.5), n=8)
    t = np.radians(turn_deg) * (V[:, 2] + 1.5) / 3.0
    c, s = np.cos(t), np.sin(t)
    V = np.c_[c * V[:, 0] - s * V[:, 1], s * V[:, 0] + c * V[:, 1], V[:, 2]]
    if bend:
        R = 3.0 / bend  # bend the bar's axis into an arc of angle `bend` radians
        th = V[:, 2] / R
        x = R - (R - V[:, 0]) * np.cos(th)
        z = (R - V[:, 0]) * np.sin(th)
        V = np.c_[x, V[:, 1], z]
    return V, F


def _top_fillets(r: float = 0.4):
    """A cube whose four top edges (and corners) are rounded with radius r,
    the vertical and bottom edges sharp."""
    from solver.examples import box

    V, F = box(n=20)  # grid lines at the fillets' tangent lines (r a multiple of 0.1)
    c = 1.0 - r
    q = np.c_[np.clip(V[:, 0], -c, c), np.clip(V[:, 1], -c, c), np.full(len(V), c)]
    d = V - q
    n = np.linalg.norm(d, axis=1)
    m = (V[:, 2] > c) & (n > 1e-12)
    V = V.copy()
    V[m] = q[m] + r * d[m] / n[m, None]
    return V, F


def _voxels(shape: str):
    from solver.examples import voxel_surface

    occ = {"L": np.array([[[1], [0]], [[1], [1]]], bool),
           "T": np.array([[[1], [0]], [[1], [1]], [[1], [0]]], bool),
           "U": np.array([[[1], [1]], [[1], [0]], [[1], [1]]], bool)}[shape]
    occ = np.repeat(np.repeat(occ, 2, axis=0), 2, axis=1)
    return voxel_surface(occ, 0.5)


def _ring(kind: str):
    """Solids of revolution (testkit/revolve.py): a washer with sharp rims,
    a ring with rounded rims, a long pipe; a cylinder with a boss, a shaft
    with a collar whose outer rims are rounded."""
    from testkit.revolve import collared_shaft, rounded_ring, stepped_shaft, washer

    if kind == "washer":
        return washer()
    if kind == "rounded":
        return rounded_ring()
    if kind == "stepped":
        return stepped_shaft()
    if kind == "collared":
        return collared_shaft()
    return washer(0.4, 0.6, 2.0, 0.1, 48)


def solids() -> dict:
    """name -> a function making (V, F)."""
    from solver.examples import box, cylinder_surface, icosphere, load_example, plate_with_hole_surface, torus_surface

    def rot(make, seed):
        def f():
            V, F = make()
            return V @ _rotation(seed).T, F
        return f

    def noisy_dense():
        V, F = icosphere(5)
        rng = np.random.default_rng(7)
        return V * (1 + 0.003 * rng.normal(size=(len(V), 1))), F

    S = {
        "sphere": lambda: icosphere(3),
        "sphere_fine": lambda: icosphere(4),
        "ball_example": lambda: load_example("ball")[:2],
        "ellipsoid_3x2x1.5": lambda: (icosphere(4)[0] * [1.5, 1.0, 0.75], icosphere(4)[1]),
        "ellipsoid_2x1x1": lambda: (icosphere(4)[0] * [2.0, 1.0, 1.0], icosphere(4)[1]),
        "ellipsoid_rot": rot(lambda: (icosphere(4)[0] * [1.4, 1.0, 0.8], icosphere(4)[1]), 1),
        "ellipsoid_flat": lambda: (icosphere(4)[0] * [1.5, 1.5, 0.5], icosphere(4)[1]),
        "rounded_box": lambda: _superquadric(4.0),
        "rounded_box_2x1x1": lambda: _superquadric(4.0, (2.0, 1.0, 1.0)),
        "rounded_box_rot": rot(lambda: _superquadric(3.0), 2),
        "dense_noisy_sphere": noisy_dense,
        "box": lambda: box(n=2),
        "box_2x1x1": lambda: box((-1, -0.5, -0.5), (1, 0.5, 0.5), n=4),
        "box_rot": rot(lambda: box((-1, -0.6, -0.4), (1, 0.6, 0.4), n=4), 3),
        "box_top_fillets": _top_fillets,
        "L_part": lambda: _voxels("L"),
        "T_part": lambda: _voxels("T"),
        "U_part": lambda: _voxels("U"),
        "twisted_bar": lambda: _twisted(60.0),
        "twisted_bar_120": lambda: _twisted(120.0),
        "bent_bar": lambda: _twisted(0.0, 1.2),
        "cylinder": lambda: cylinder_surface(1.0, 2.0),
        "cylinder_long": lambda: cylinder_surface(0.5, 3.0, n=48),
        "cylinder_rot": rot(lambda: cylinder_surface(1.0, 1.0), 4),
        "prism_example": lambda: load_example("prism")[:2],
        "cube_example": lambda: load_example("cube")[:2],
        "plate_example": lambda: plate_with_hole_surface(),
        "genus2_example": lambda: load_example("genus2")[:2],
        "torus": lambda: torus_surface(),
        "torus_fat": lambda: torus_surface(1.0, 0.6, 48, 24),
        "torus_rot": rot(lambda: torus_surface(1.5, 0.35, 72, 20), 5),
        "washer": lambda: _ring("washer"),
        "rounded_ring": lambda: _ring("rounded"),
        "pipe_rot": rot(lambda: _ring("pipe"), 6),
        "stepped_shaft": lambda: _ring("stepped"),
        "collared_shaft_rot": rot(lambda: _ring("collared"), 7),
    }
    for s in range(6):
        S[f"blob_{s}"] = (lambda s=s: _blob(s))
    return S


def bars(row: dict) -> list:
    """The bars of issue 49 a run missed (empty: met them all)."""
    if "error" in row:
        return [row["error_kind"] + ": " + row["error"][:100]]
    miss = []
    if row["status"] != "converged":
        miss.append("not converged")
    if row.get("hex_error"):
        return miss + [f"no hex ({row['hex_kind']})"]
    if row["inverted"] or row["other_cells"]:
        miss.append("inverted/other cells")
    if row["sj_min"] < 0.3:
        miss.append("min SJ < 0.3")
    if row["sj_mean"] < 0.90:
        miss.append("mean SJ < 0.90")
    if row["hex_status"] != "valid":
        miss.append("hex " + row["hex_status"])
    if row["total_s"] > 180:
        miss.append("over 180 s")
    return miss


KNOWN = {"ball_example": "ball", "cylinder": "cylinder", "plate_example": "plate"}


def _hand(name: str):
    """The hand-made network of a solid that has one (the examples'), as
    (network, a report-like object)."""
    from types import SimpleNamespace

    from solver.examples import load_example

    net = load_example(KNOWN[name])[2]
    curves = [SimpleNamespace(sigma=c.sigma, kind="hand") for c in net.curves]
    return net, SimpleNamespace(curves=curves, nodes=-1, charts=0, sharp_boundaries=0, chart_boundaries=0,
                                depth=0.0, feature_size=0.0, target_tets=None)


def run_one(name: str, hand: bool = False) -> dict:
    from solver import HexMeshError, SymFramesError, solve
    from solver.suggest import suggest_network
    from testkit.runs import hexmesh_as_cli

    V, F = solids()[name]()
    row = dict(solid=name + (" (hand-made network)" if hand else ""), triangles=int(len(F)))
    t0 = time.perf_counter()
    try:
        net, rep = _hand(name) if hand else suggest_network(V, F)
    except SymFramesError as e:
        row.update(error=str(e), error_kind=type(e).__name__, stage="suggest",
                   total_s=round(time.perf_counter() - t0, 1))
        return row
    t_s = time.perf_counter() - t0
    row.update(curves=len(net.curves), plus=sum(c.sigma > 0 for c in rep.curves),
               minus=sum(c.sigma < 0 for c in rep.curves), nodes=rep.nodes, charts=rep.charts,
               sharp_boundaries=rep.sharp_boundaries, boundaries=rep.chart_boundaries,
               depth=round(rep.depth, 4), feature=round(rep.feature_size, 4), target_tets=rep.target_tets,
               suggest_s=round(t_s, 1))
    try:
        # as `python -m solver SURFACE.obj --hex` does: the budget the network asks for
        r = solve(V, F, net, **({"target_tets": rep.target_tets} if rep.target_tets else {}))
    except SymFramesError as e:
        row.update(error=str(e), error_kind=type(e).__name__, stage="solve",
                   total_s=round(time.perf_counter() - t0, 1))
        return row
    t_f = time.perf_counter() - t0 - t_s
    rep = r.report
    row.update(status=rep.status, tets=int(rep.sizes.get("tets", 0)), field_s=round(t_f, 1))
    t1 = time.perf_counter()
    try:
        hm, finer = hexmesh_as_cli(r)  # the field solved again finer where the map failed on it, as the CLI does
        row.update(finer)
    except HexMeshError as e:
        row.update(getattr(e, "retry", {}))
        row.update(hex_error=str(e)[:300], hex_kind=e.kind, hex_s=round(time.perf_counter() - t1, 1),
                   total_s=round(time.perf_counter() - t0, 1))
        return row
    h = hm.report
    row.update(hexes=h.hexes, other_cells=h.non_hex_cells, inverted=h.inverted, sj_min=round(h.sj_min, 3),
               sj_mean=round(h.sj_mean, 3), hex_status=h.status, reason=h.reason,
               irregular={str(k): v for k, v in h.irregular.items()},
               hex_s=round(time.perf_counter() - t1, 1), total_s=round(time.perf_counter() - t0, 1))
    return row


def table(rows: list) -> str:
    """The rows as a markdown table for bench/RESULTS.md."""
    out = ["| solid | tris | curves (+1/4 / -1/4) | nodes | charts (sharp boundaries) | budget | field | tets | hexes "
           "| SJ min / mean | s: suggest / field / hex / total | verdict |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "curves" not in r:
            out.append(f"| {r['solid']} | | {r['error_kind']}: {r['error'][:150]} | | | | | | | | {r['total_s']} | "
                       f"{r['error_kind']} |")
            continue
        r["missed"] = bars(r) if "error" not in r or r.get("stage") != "suggest" else r["missed"]
        if r.get("stage") == "suggest":
            out.append(f"| {r['solid']} | {r['triangles']} | refused: {r['error'][:150]} | | | | | | | | "
                       f"{r['total_s']} | refused |")
            continue
        curves = f"{r['curves']} ({r['plus']} / {r['minus']})"
        field = r.get("status", r.get("error_kind", ""))
        q = f"{r['sj_min']} / {r['sj_mean']}" if "sj_min" in r else ""
        secs = f"{r.get('suggest_s', '')} / {r.get('field_s', '')} / {r.get('hex_s', '')} / {r.get('total_s', '')}"
        verdict = "met" if not r["missed"] else "; ".join(m[:90] for m in r["missed"])
        nodes = r["nodes"] if r["nodes"] >= 0 else ""
        charts = f"{r['charts']} ({r['sharp_boundaries']}/{r['boundaries']})" if r["charts"] else ""
        out.append(f"| {r['solid']} | {r['triangles']} | {curves} | {nodes} | {charts} | {r.get('target_tets') or ''} "
                   f"| {field} | {r.get('tets', '')} | {r.get('hexes', '')} | {q} | {secs} | {verdict} |")
    return "\n".join(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--solids", nargs="+", default=None)
    ap.add_argument("--write", action="store_true", help="write the rows to bench/suggest.json")
    ap.add_argument("--known", action="store_true", help="the solids with a hand-made network (ball, cylinder, "
                    "plate), solved and meshed with it, for comparison (bench/suggest_known.json with --write)")
    ap.add_argument("--table", action="store_true", help="print bench/suggest.json and suggest_known.json as "
                    "markdown tables and exit")
    ap.add_argument("--timeout", type=float, default=None, help="stop a run after this many seconds and record it "
                    "as stopped")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--hand", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.one:
        print(json.dumps(run_one(a.one, a.hand)))
        return
    if a.table:
        for name in ("suggest.json", "suggest_known.json"):
            with open(os.path.join(ROOT, "bench", name)) as fh:
                print(table(json.load(fh)) + "\n")
        return
    rows = []
    for name in a.solids or (list(KNOWN) if a.known else list(solids())):
        t = time.perf_counter()
        try:
            p = subprocess.run([sys.executable, __file__, "--one", name] + (["--hand"] if a.known else []),
                               capture_output=True, text=True, cwd=ROOT, timeout=a.timeout)
        except subprocess.TimeoutExpired:
            row = dict(solid=name, error=f"stopped after {a.timeout:g} s (--timeout), before the run ended",
                       error_kind="stopped", total_s=round(time.perf_counter() - t, 1))
            row["missed"] = bars(row)
            rows.append(row)
            print(json.dumps(row), flush=True)
            continue
        if p.returncode:
            lines = p.stderr.strip().splitlines() or ["?"]
            row = dict(solid=name, error=lines[-1], error_kind="crash", total_s=round(time.perf_counter() - t, 1))
        else:
            row = json.loads(p.stdout.strip().splitlines()[-1])
        row["missed"] = bars(row)
        rows.append(row)
        print(json.dumps(row), flush=True)
    met = sum(1 for r in rows if not r["missed"])
    refused = sum(1 for r in rows if r.get("stage") == "suggest")
    print(f"met every bar: {met} of {len(rows)}; refused with a reason at the suggestion: {refused}")
    if a.write:
        path = os.path.join(ROOT, "bench", "suggest_known.json" if a.known else "suggest.json")
        if a.solids and os.path.exists(path):  # the solids named replace their rows, the others stay
            with open(path) as fh:
                old = json.load(fh)
            new = {r["solid"]: r for r in rows}
            rows = [new.pop(r["solid"], r) for r in old] + list(new.values())
        with open(path, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
