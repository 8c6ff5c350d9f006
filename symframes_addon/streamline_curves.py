"""Streamlines as a curve object: one poly spline per line, bevelled so
that it renders, coloured by axis family (material index = family, with the
glyphs' axis materials)."""

from __future__ import annotations

import bpy
import numpy as np

from . import glyphs, storage


def new_streamline_curve(lines: list, families: list, radius: float, name: str = "SymFrames Streamlines"):
    """A new curve datablock with one poly spline per (n_i, 3) polyline.

    families : per line, 0, 1 or 2 (the frame axis it follows)
    """
    cu = bpy.data.curves.new(name, "CURVE")
    try:
        cu.dimensions = "3D"
        cu.bevel_depth = radius
        cu.bevel_resolution = 2
        cu.use_fill_caps = True
        for axis in range(3):
            cu.materials.append(glyphs.axis_material(axis))
        for P, fam in zip(lines, families):
            sp = cu.splines.new("POLY")
            sp.points.add(len(P) - 1)
            co = np.ones((len(P), 4), np.float32)
            co[:, :3] = P
            sp.points.foreach_set("co", co.ravel())
            sp.material_index = int(fam)
    except Exception:
        bpy.data.curves.remove(cu)
        raise
    return cu


def write_streamlines(scene, lines: list, families: list, radius: float):
    """Replace the scene's streamlines; returns the curve object."""
    cu = new_streamline_curve(lines, families, radius)
    return storage.replace_output(scene, "streamlines", "SymFrames Streamlines", cu)


def streamline_polylines(obj) -> list:
    """The (n_i, 3) point arrays of a streamline object's splines."""
    out = []
    for sp in obj.data.splines:
        co = np.empty(4 * len(sp.points), np.float32)
        sp.points.foreach_get("co", co)
        out.append(co.reshape(-1, 4)[:, :3])
    return out
