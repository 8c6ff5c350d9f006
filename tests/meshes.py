"""Small structured tet meshes shared by the tests."""

from __future__ import annotations

import itertools

import numpy as np

from solver.mesh.tetmesh import TetMesh


def box_grid(n, lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0), jitter: float = 0.0, seed: int = 0):
    """(V, T) of a box of n[0] x n[1] x n[2] cubes, each split into the 6 tets
    around its main diagonal (Freudenthal), conforming.  ``jitter`` moves
    interior vertices randomly by up to that fraction of a cell."""
    n = np.broadcast_to(np.asarray(n), (3,))
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    g = [np.linspace(lo[i], hi[i], n[i] + 1) for i in range(3)]
    V = np.stack(np.meshgrid(*g, indexing="ij"), axis=-1).reshape(-1, 3)
    if jitter:
        rng = np.random.default_rng(seed)
        eps = 1e-9 * np.max(hi - lo)
        inner = np.all((V > lo + eps) & (V < hi - eps), axis=1)
        V[inner] += rng.uniform(-jitter, jitter, (inner.sum(), 3)) * (hi - lo) / n
    vid = np.arange(len(V)).reshape(tuple(n + 1))
    cells = np.indices(tuple(n)).reshape(3, -1).T
    T = []
    for perm in itertools.permutations(range(3)):
        c = cells.copy()
        tet = [vid[tuple(c.T)]]
        for ax in perm:
            c = c.copy()
            c[:, ax] += 1
            tet.append(vid[tuple(c.T)])
        T.append(np.stack(tet, axis=1))
    return V, np.vstack(T)


def box_mesh(n, lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0), jitter: float = 0.0, seed: int = 0) -> TetMesh:
    return TetMesh(*box_grid(n, lo, hi, jitter, seed))


def l_prism_surface():
    """(V, F) of an L-shaped prism: unit cells (0, 0), (1, 0) and (0, 1) of
    the xy grid extruded to z in [0, 1], outward triangles.  Its edge along
    x = y = 1 is concave."""
    cells = {(0, 0), (1, 0), (0, 1)}
    quads = []
    for i, j in sorted(cells):
        # the side walls not shared with a neighbour, then bottom and top
        if (i + 1, j) not in cells:
            quads.append([(i + 1, j, 0), (i + 1, j + 1, 0), (i + 1, j + 1, 1), (i + 1, j, 1)])
        if (i - 1, j) not in cells:
            quads.append([(i, j, 0), (i, j, 1), (i, j + 1, 1), (i, j + 1, 0)])
        if (i, j + 1) not in cells:
            quads.append([(i, j + 1, 0), (i, j + 1, 1), (i + 1, j + 1, 1), (i + 1, j + 1, 0)])
        if (i, j - 1) not in cells:
            quads.append([(i, j, 0), (i + 1, j, 0), (i + 1, j, 1), (i, j, 1)])
        quads.append([(i, j, 0), (i, j + 1, 0), (i + 1, j + 1, 0), (i + 1, j, 0)])
        quads.append([(i, j, 1), (i + 1, j, 1), (i + 1, j + 1, 1), (i, j + 1, 1)])
    ids = {}
    for q in quads:
        for v in q:
            ids.setdefault(v, len(ids))
    V = np.array(list(ids), float)
    F = [[ids[q[0]], ids[q[k]], ids[q[k + 1]]] for q in quads for k in (1, 2)]
    return V, np.array(F)
