"""Draw an exported field (.vtu) as another tool reads it: a picture for the docs.

Reads the file with meshio, as ParaView or a hex mesher would, and draws the
tets that a horizontal plane cuts: each tet's frame (the cell arrays
``tet_axis0..2``) as a cross seen from above, tets that a curve crosses
(``curve`` >= 0) filled.  Writes an SVG; no plotting library is needed.

    ./dev.sh python -m solver --example cylinder --export out/cylinder.vtu
    ./dev.sh python scripts/render_export.py out/cylinder.vtu docs/images/export_vtu.svg [--z 0.0]
"""

from __future__ import annotations

import argparse
import sys

import meshio
import numpy as np

AXIS_COLORS = ("#d62728", "#2ca02c", "#1f77b4")  # as the add-on's glyphs: x red, y green, z blue


def render(path: str, out: str, z: float | None = None, size: int = 640) -> int:
    m = meshio.read(path)
    P = m.points
    T = m.cells_dict["tetra"]
    cd = {k: v[0] for k, v in m.cell_data.items()}
    zs = P[T, 2]
    if z is None:
        z = float(np.median(P[:, 2]))
    cut = (zs.min(axis=1) <= z) & (zs.max(axis=1) >= z)
    # one tet per cell of a grid about two edge lengths wide: a readable picture, a small file
    cen = P[T].mean(axis=1)
    edge = float(np.cbrt(np.abs(np.linalg.det(P[T[cut, 1:]] - P[T[cut, :1]])) / 6.0).mean()) * 2.0
    key = np.floor(cen[:, :2] / (1.5 * edge)).astype(np.int64)
    order = np.nonzero(cut)[0]
    _, first = np.unique(key[order], axis=0, return_index=True)
    keep = np.zeros(len(T), bool)
    keep[order[first]] = True
    crossing = cd.get("curve", np.full(len(T), -1)) >= 0
    cut = keep | (cut & crossing)
    C = P[T[cut]].mean(axis=1)
    lo, hi = P[:, :2].min(axis=0), P[:, :2].max(axis=0)
    scale = (size - 40) / float(np.max(hi - lo))

    def xy(p):
        q = (p[..., :2] - lo) * scale + 20
        return q[..., 0], size - q[..., 1]

    h = 0.5 * edge * scale
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}">',
             f'<rect width="{size}" height="{size}" fill="white"/>']
    crossed = cd.get("curve", np.full(len(T), -1))[cut] >= 0
    cx, cy = xy(C)
    for x, y in zip(cx[crossed], cy[crossed]):
        parts.append(f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{1.2 * h:.1f}" fill="#f2c200" fill-opacity="0.6"/>')
    for k in range(3):
        a = cd[f"tet_axis{k}"][cut]
        a = a[:, :2] * h  # seen from above: the axis' horizontal part
        for (x, y), (u, v) in zip(np.c_[cx, cy], a):
            parts.append(f'<line x1="{x - u:.1f}" y1="{y + v:.1f}" x2="{x + u:.1f}" y2="{y - v:.1f}" '
                         f'stroke="{AXIS_COLORS[k]}" stroke-width="1.2"/>')
    parts.append(f'<text x="20" y="{size - 6}" font-family="sans-serif" font-size="12">{path.split("/")[-1]}: '
                 f'frames of tets cut by z = {z:.3g} (a sample, of {len(T):,} tets); yellow: crossed by a curve</text>')
    parts.append("</svg>")
    with open(out, "w") as fh:
        fh.write("\n".join(parts))
    return int(cut.sum())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("vtu")
    ap.add_argument("svg")
    ap.add_argument("--z", type=float, help="height of the cutting plane (default: the median vertex height)")
    args = ap.parse_args(argv)
    n = render(args.vtu, args.svg, args.z)
    print(f"wrote {args.svg}: {n} tets")
    return 0


if __name__ == "__main__":
    sys.exit(main())
