"""A family of genus-2 solids with oblique singular curves (issue 41c).

Real genus-2 parts come with networks whose singular curves run between the
outer wall and the walls of the holes and reach the surface well off the
normal (3-36 degrees on the two solids of issue 41).  ``genus2_family(seed)``
makes such an input: the block 2.5 x 1.5 x 0.5 with two square through
holes (solver.examples.genus2_example's solid, sharp edges everywhere), and
2-3 pairs of straight or slightly bowed singular curves of index +1/4 and
-1/4 across an arm of the block, from an outer wall to the hole wall facing
it, each end 15-40 degrees off the normal.

Curves come in +-1/4 pairs on one outer wall and one hole wall: a curve end
is a singularity of the 2D boundary field, and each patch bounded by sharp
edges keeps its own Poincare-Hopf sum (a wall is a rectangle whose four
corners already make it), so the ends on every patch must cancel.  The seed
varies the number of pairs, their arms, their ends and angles, the bow and
the surface's triangulation (2-4 quads per 0.5 along an edge).
"""

from __future__ import annotations

import numpy as np

from solver.examples import voxel_surface
from solver.network.network import Curve, Network

SIZE = (2.5, 1.5, 0.5)
# the holes' squares (x0, x1) x (y0, y1), and the flat walls a curve may end
# on: (a point of the wall, its outward normal, the ranges of the two other
# coordinates, kept 0.09 off the sharp edges, so that a tet-edge variant does not move an end onto one)
HOLE_X = ((0.5, 1.0), (1.5, 2.0))
HOLE_Y = (0.5, 1.0)
MARGIN = 0.09


def block_with_holes(n: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The closed surface of the genus-2 block (module docstring), outward,
    each 0.5 x 0.5 face of its voxels split into n x n quads."""
    occ = np.ones((5, 3, 1), bool)
    occ[1, 1, 0] = occ[3, 1, 0] = False
    return voxel_surface(occ, 0.5, n)


def _walls(h: int):
    """(outer wall, hole wall) pairs facing each other across an arm of the
    block around hole h: (axis, outer coordinate, hole coordinate, range of
    the other horizontal coordinate)."""
    x0, x1 = HOLE_X[h]
    y0, y1 = HOLE_Y
    out = [(1, 0.0, y0, (x0, x1)), (1, SIZE[1], y1, (x0, x1))]
    if h == 0:
        out.append((0, 0.0, x0, (y0, y1)))
    else:
        out.append((0, SIZE[0], x1, (y0, y1)))
    return out


def _curve(a, b, bow, rng, n=12):
    t = np.linspace(0, 1, n + 1)[:, None]
    P = a + t * (b - a)
    if bow:
        side = np.cross(b - a, rng.normal(size=3))
        side /= np.linalg.norm(side)
        P += bow * np.linalg.norm(b - a) * (4 * t * (1 - t)) * side
    return P


def genus2_family(seed: int = 0, pairs: int | None = None, angles=(15.0, 40.0)):
    """(V, F, Network): the genus-2 block and 2-3 pairs of +-1/4 curves from
    an outer wall to the hole wall facing it across an arm, each end within
    ``angles`` degrees off the normal (module docstring).  Curves are at
    least 0.15 apart (0.3 edge lengths of the default mesh)."""
    rng = np.random.default_rng(seed)
    V, F = block_with_holes(int(rng.integers(2, 5)))
    n_pairs = pairs if pairs is not None else int(rng.integers(2, 4))
    slots = [(h, k) for h in range(2) for k in range(3)]
    chosen = [slots[i] for i in rng.permutation(len(slots))[:n_pairs]]
    curves = []
    placed: list[np.ndarray] = []
    for p, (h, k) in enumerate(chosen):
        axis, outer, inner, (lo, hi) = _walls(h)[k]
        other = 1 - axis
        for s, sigma in enumerate((0.25, -0.25)):
            for _ in range(5000):
                a, b = np.zeros(3), np.zeros(3)
                a[axis], b[axis] = outer, inner
                a[other] = rng.uniform(lo + MARGIN, hi - MARGIN)
                b[other] = rng.uniform(lo + MARGIN, hi - MARGIN)
                a[2], b[2] = rng.uniform(MARGIN, SIZE[2] - MARGIN, 2)
                bow = float(rng.choice([0.0, 0.04]))
                P = _curve(a, b, bow, rng)
                angs = _end_angles(P, axis)
                if not (angles[0] <= angs.min() and angs.max() <= angles[1]):
                    continue
                if placed and min(_distance(P, Q) for Q in placed) < 0.15:
                    continue
                break
            else:
                raise RuntimeError(f"seed {seed}: no curve found for pair {p}")
            placed.append(P)
            curves.append(Curve(P, sigma=sigma, name=f"pair {p}{'+-'[s]} hole {h}"))
    return V, F, Network(curves=curves, sharp_angle=30.0)


def _end_angles(P: np.ndarray, axis: int) -> np.ndarray:
    """Angles (degrees) off the walls' normal (the axis) of both end chords."""
    out = []
    for t in (P[1] - P[0], P[-1] - P[-2]):
        out.append(np.degrees(np.arccos(min(1.0, abs(t[axis]) / np.linalg.norm(t)))))
    return np.array(out)


def _distance(P: np.ndarray, Q: np.ndarray) -> float:
    from solver.surface.intersect import segments_distance

    A0, A1 = np.repeat(P[:-1], len(Q) - 1, 0), np.repeat(P[1:], len(Q) - 1, 0)
    B0, B1 = np.tile(Q[:-1], (len(P) - 1, 1)), np.tile(Q[1:], (len(P) - 1, 1))
    return float(segments_distance(A0, A1, B0, B1)[0].min())


def end_angles(V, F, net: Network) -> np.ndarray:
    """Angles (degrees) off the normal at every boundary end of net's curves."""
    from solver.surface.trisurface import TriSurface
    from testkit.tetedge import end_angles as ea

    return ea(TriSurface(np.asarray(V, float), np.asarray(F)), net)
