"""A dense sculpt-like solid with sharp creases, and a network on it
(issue 41e).

Blender users' sculpted or subdivided objects have 1e5-1e6 triangles, are
not exact primitives and often keep creases where a part was trimmed flat.
``sculpted_cylinder(triangles, seed)`` makes such an input from the
cylinder example (solver.examples.cylinder_example: its four axial curves
of index +1/4 end on the flat caps, along their normals): the solid as a
dense mesh of about that many triangles, its wall pushed in and out by
smooth random bumps, meeting the caps at two circular 90-degree creases.

(A sphere trimmed flat does not take the ball's network: the crease loop
splits it into two disks that each need singular ends of total index 1,
and the ball's radial curves reach a flat bottom 55 degrees off its normal.)
"""

from __future__ import annotations

import numpy as np


def _stitch(inner: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """Triangles between two closed rings of vertex ids, each running
    counter-clockwise from angle 0 (seen from +z), advancing along
    whichever ring's next vertex comes first by angle."""
    ni, no = len(inner), len(outer)
    nxt = np.r_[np.arange(1, ni + 1) / ni, np.arange(1, no + 1) / no]
    moves = np.argsort(nxt, kind="stable") >= ni  # True: the outer ring advances
    i = np.r_[0, np.cumsum(~moves)[:-1]]
    j = np.r_[0, np.cumsum(moves)[:-1]]
    a, b = inner[i % ni], outer[j % no]
    third = np.where(moves, outer[(j + 1) % no], inner[(i + 1) % ni])
    return np.stack([a, b, third], 1)


def sculpted_cylinder(triangles: int = 320_000, seed: int = 0, amplitude: float = 0.06):
    """(V, F, network): the cylinder example's solid (radius 1, z in
    [-1, 1]) as a dense mesh of about ``triangles`` triangles (walls of
    quads split in two; caps of rings whose vertex counts grow with the
    radius, as a subdivided cylinder has them), its wall pushed in and out
    by smooth random bumps (up to ``amplitude``) that fade out 0.25 before
    the caps, so the two caps meet it at circular 90-degree creases; and the
    cylinder example's network (four axial curves of index +1/4)."""
    from solver.examples import cylinder_example

    ds = np.sqrt(12.0 * np.pi / triangles)
    S = max(12, int(round(2 * np.pi / ds)))
    R = max(2, int(round(2.0 / ds)))
    K = max(2, int(round(1.0 / ds)))
    phi = 2 * np.pi * np.arange(S) / S
    z = np.linspace(-1.0, 1.0, R + 1)
    rng = np.random.default_rng(seed)
    C = np.stack([rng.uniform(0, 2 * np.pi, 6), rng.uniform(-0.6, 0.6, 6)], 1)
    width, sign = rng.uniform(0.25, 0.5, 6), rng.choice([-1.0, 1.0], 6)
    ph, zz = np.meshgrid(phi, z, indexing="ij")  # (S, R + 1)
    dphi = np.angle(np.exp(1j * (ph[..., None] - C[:, 0])))
    bump = (sign * np.exp(-(dphi**2 + (zz[..., None] - C[:, 1]) ** 2) / width**2)).sum(-1) / 3.0
    r = 1.0 + amplitude * np.clip((1.0 - np.abs(zz)) / 0.25, 0.0, 1.0) * bump
    wall = np.stack([r * np.cos(ph), r * np.sin(ph), zz], -1).transpose(1, 0, 2).reshape(-1, 3)
    ids = np.arange(len(wall)).reshape(R + 1, S)
    nx = np.roll(ids, -1, axis=1)
    a, b, c, d = ids[:-1], nx[:-1], ids[1:], nx[1:]  # row k below row k + 1
    F = [np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)]
    V = [wall]
    nv = len(wall)
    for cap_z, rim in ((1.0, ids[-1]), (-1.0, ids[0])):
        rings = [rim]
        for k in range(K - 1, 0, -1):
            n = max(6, int(round(S * k / K)))
            t = 2 * np.pi * np.arange(n) / n
            V.append(np.stack([k / K * np.cos(t), k / K * np.sin(t), np.full(n, cap_z)], 1))
            rings.append(nv + np.arange(n))
            nv += n
        V.append(np.array([[0.0, 0.0, cap_z]]))
        centre = nv
        nv += 1
        tris = [_stitch(rings[q + 1], rings[q]) for q in range(len(rings) - 1)]
        inner = rings[-1]
        tris.append(np.stack([np.full(len(inner), centre), inner, np.roll(inner, -1)], 1))
        T = np.concatenate(tris)
        F.append(T if cap_z > 0 else T[:, ::-1])
    _, _, net = cylinder_example()
    return np.vstack(V), np.concatenate(F), net
