"""Pictures of suggested networks for docs/suggest.md (SVG, numpy only).

    ./dev.sh python scripts/suggest_pictures.py      # -> docs/images/suggest-*.svg

Each picture shows the surface see-through (faces shaded by the light,
coloured by their polycube label), its sharp creases in black and the
suggested curves: index +1/4 in red, -1/4 in blue.
"""

from __future__ import annotations

import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

LABEL_COLOURS = ("#e8c39e", "#e8c39e", "#a9c8e8", "#a9c8e8", "#b8dcb0", "#b8dcb0")


def _view(yaw: float = 35.0, pitch: float = 25.0) -> np.ndarray:
    a, b = np.radians(yaw), np.radians(pitch)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    # screen x right, y up, z towards the viewer; the world's z is up
    M = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], float)
    return Rx @ M @ Rz


def render(V, F, net, labels, path: str, size: int = 360) -> None:
    """Write an SVG of the surface, its sharp edges and the network's curves."""
    from solver.surface.features import sharp_edges_by_angle
    from solver.surface.validation import validate_surface

    S = validate_surface(V, F)
    R = _view()
    P = V @ R.T
    lo, hi = P[:, :2].min(axis=0), P[:, :2].max(axis=0)
    scale = 0.9 * size / float((hi - lo).max())
    mid = 0.5 * (lo + hi)

    def xy(X):
        Q = (X @ R.T)[:, :2] - mid
        return np.c_[size / 2 + scale * Q[:, 0], size / 2 - scale * Q[:, 1]]

    N = S.face_normals @ R.T
    depth = P[F].mean(axis=1)[:, 2]
    light = np.clip(0.35 + 0.65 * N @ np.array([0.3, 0.5, 0.8]) / np.linalg.norm([0.3, 0.5, 0.8]), 0.2, 1.0)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" viewBox="0 0 {size} {size}">',
           f'<rect width="{size}" height="{size}" fill="white"/>']
    for f in np.argsort(depth):
        if N[f, 2] <= 0:
            continue
        pts = " ".join(f"{x:.1f},{y:.1f}" for x, y in xy(V[F[f]]))
        c = LABEL_COLOURS[int(labels[f])]
        out.append(f'<polygon points="{pts}" fill="{c}" fill-opacity="{0.75 * light[f]:.2f}" stroke="none"/>')
    sharp = sharp_edges_by_angle(S, net.sharp_angle or 30.0) if net.sharp_edges is None else None
    if sharp is not None and np.any(sharp):
        for a, b in xy(V[S.edges[sharp].reshape(-1)]).reshape(-1, 2, 2):
            out.append(f'<line x1="{a[0]:.1f}" y1="{a[1]:.1f}" x2="{b[0]:.1f}" y2="{b[1]:.1f}" stroke="black" '
                       'stroke-width="0.8"/>')
    for c in net.curves:
        pts = " ".join(f"{x:.1f},{y:.1f}" for x, y in xy(np.asarray(c.points)))
        col = "#d62728" if c.sigma > 0 else "#1f4fd6"
        out.append(f'<polyline points="{pts}" fill="none" stroke="{col}" stroke-width="2.2"/>')
    out.append("</svg>")
    with open(path, "w") as fh:
        fh.write("\n".join(out))


def main() -> None:
    from solver import suggest_network
    from solver.examples import cylinder_surface, icosphere, plate_with_hole_surface, torus_surface

    shapes = {
        "ellipsoid": (icosphere(3)[0] * [1.5, 1.0, 0.75], icosphere(3)[1]),
        "cylinder": cylinder_surface(1.0, 2.0, n=48),
        "plate": plate_with_hole_surface(),
        "torus": torus_surface(1.0, 0.45, 48, 16),
    }
    for name, (V, F) in shapes.items():
        net, rep = suggest_network(V, F)
        path = os.path.join(ROOT, "docs", "images", f"suggest-{name}.svg")
        render(V, F, net, rep.labels, path)
        print(f"wrote {path}: {len(net.curves)} curves, {rep.nodes} nodes")


if __name__ == "__main__":
    main()
