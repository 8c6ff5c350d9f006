"""A Poisson problem on the ball's hex meshes against a hand-built cube-sphere
of the same layout, at about equal cell counts (issue 51: "at equal cell
count the ball's L2 error is <= 1.1x the error on a hand-built cube-sphere
of the same layout").

    ./dev.sh python bench/bench_fem_ball.py [--runs 2]

-lap u = f in the unit ball, u = sin(x) cos(1.3 y) exp(z / 2) on its
boundary, trilinear hexahedra (scikit-fem); the L2 error of SymFrames' hex
mesh of the ball example (solved with defaults, meshed at the default cell
size and at two finer ones) against testkit.hexnet.cube_sphere(n, m, inner),
the 7-block mesh with n^3 + 6 n^2 m cells (equiangular outer blocks, their
radial lines normal to the sphere), built with the example's own inner cube
(half-size 1 / (2 + sqrt 3): the same layout) and, for reference, with a
larger one (0.45).  The ratio column divides SymFrames' error by the
same-layout meshes' error at the same cell count (interpolated in log-log
between the two nearest counts).  Also the spread of the cell sizes (the
cube root of the cell volumes: 5th and 95th percentile over the median).
Prints a markdown table.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def exact(x):
    return np.sin(x[0]) * np.cos(1.3 * x[1]) * np.exp(0.5 * x[2])


def l2_error(V: np.ndarray, H: np.ndarray) -> float:
    import meshio
    from skfem import Basis, BilinearForm, ElementHex1, Functional, LinearForm, condense
    from skfem import solve as fem_solve
    from skfem.helpers import dot, grad
    from skfem.io.meshio import from_meshio

    @BilinearForm
    def laplace(u, v, w):
        return dot(grad(u), grad(v))

    @LinearForm
    def load(v, w):
        return (1.0 + 1.69 - 0.25) * exact(w.x) * v

    @Functional
    def error2(w):
        return (w["uh"] - exact(w.x)) ** 2

    mesh = from_meshio(meshio.Mesh(V, [("hexahedron", H)]))
    basis = Basis(mesh, ElementHex1())
    dofs = basis.get_dofs()
    u = np.zeros(basis.N)
    u[dofs] = exact(mesh.p[:, dofs])
    uh = fem_solve(*condense(laplace.assemble(basis), load.assemble(basis), x=u, D=dofs))
    return float(np.sqrt(error2.assemble(basis, uh=basis.interpolate(uh))))


def spread(V: np.ndarray, H: np.ndarray) -> tuple[float, float]:
    """5th and 95th percentile of the cells' size (cube root of the volume
    of the hex's 5-tet split) over its median."""
    P = V[H]
    tets = [(0, 1, 3, 4), (1, 2, 3, 6), (1, 4, 5, 6), (3, 4, 6, 7), (1, 3, 4, 6)]
    vol = sum(np.abs(np.einsum("ij,ij->i", P[:, b] - P[:, a], np.cross(P[:, c] - P[:, a], P[:, d] - P[:, a])))
              for a, b, c, d in tets) / 6.0
    s = np.cbrt(vol)
    med = np.median(s)
    return float(np.percentile(s, 5) / med), float(np.percentile(s, 95) / med)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1, help="fresh solves of the ball (fTetWild is not deterministic)")
    a = ap.parse_args()
    from solver import hexmesh, solve
    from solver.examples import ball_example
    from testkit.hexnet import cube_sphere

    inner = 1.0 / (2.0 + np.sqrt(3.0))  # ball_example's
    rows, same = [], []
    for n in (6, 8, 11):
        V, H = cube_sphere(n, inner=inner)
        err = l2_error(V, H)
        same.append((len(H), err))
        rows.append((f"hand-built, inner {inner:.3f}", f"n={n}", len(H), err, *spread(V, H), None))
    for n, m in ((8, 5), (12, 7), (16, 10)):
        V, H = cube_sphere(n, m)
        rows.append(("hand-built, inner 0.45", f"n={n}, m={m}", len(H), l2_error(V, H), *spread(V, H), None))
    V, F, net = ball_example()
    for run in range(a.runs):
        t = time.perf_counter()
        res = solve(V, F, net)
        for cell in (None, 0.09, 0.065):
            hm = hexmesh(res, cell)
            err = l2_error(hm.vertices, hm.hexes)
            rows.append((f"SymFrames (run {run + 1})", f"cell {hm.report.cell_size:.3g}", len(hm.hexes), err,
                         *spread(hm.vertices, hm.hexes), err / at_count(same, len(hm.hexes))))
        print(f"run {run + 1}: {time.perf_counter() - t:.0f} s", file=sys.stderr)
    print("| mesh | size | cells | L2 error | / same layout | cell size p5 / p95 over the median |")
    print("|---|---|---:|---:|---:|---|")
    for name, size, cells, err, lo, hi, ratio in rows:
        r = "" if ratio is None else f"{ratio:.2f}"
        print(f"| {name} | {size} | {cells:,} | {err:.3e} | {r} | {lo:.2f} / {hi:.2f} |")


def at_count(pairs: list, cells: int) -> float:
    """The error of (cells, error) pairs at ``cells``: log-log interpolation
    between the two nearest counts (extrapolated beyond them)."""
    c, e = np.log([p[0] for p in pairs]), np.log([p[1] for p in pairs])
    i = int(np.clip(np.searchsorted(c, np.log(cells)), 1, len(c) - 1))
    t = (np.log(cells) - c[i - 1]) / (c[i] - c[i - 1])
    return float(np.exp(e[i - 1] + t * (e[i] - e[i - 1])))


if __name__ == "__main__":
    main()
