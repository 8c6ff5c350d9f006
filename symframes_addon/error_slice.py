"""Tet faces coloured by an error of the stored field, as a mesh object.

Two quantities (the scene's Slice Quantity):

* ``MONODROMY`` -- the slice faces (display.slice_faces: the tet faces
  separating the two sides of the slice plane), with the monodromy angle of
  each face (Eq. 9, solver.monodromy_angles on the stored omega):
  how far omega fails to be integrable around it.  The faces that are not
  regular (solver.regular_face_mask: the network's, which turn by their
  prescribed quarter turns) are flagged (``network``) and drawn grey;
  elsewhere a good field has a small fraction of a degree.
* ``ADAPTATION`` -- the domain boundary faces the cutaway keeps
  (display.kept_boundary_faces), with the mean normal adaptation error of
  their measured vertices (-1, grey, where none is measured: on sharp
  features, whose frames are fixed).

The mesh has one triangle per face, the value as a FLOAT face attribute
named after the quantity (radians), the tet-mesh face id (``face``), and a
color attribute ``symframes_colour`` (face corners; blue 0, yellow, red at
the quantity's scale and above) that the materials and the Solid view's
Attribute coloring show.  The Solid view's default coloring (Material)
shows the materials' viewport display colors instead, so each face also
gets the material of its step (glyphs.ERROR_STEPS of them, grey first).
Changing the scale recolours it (recolour).
"""

from __future__ import annotations

import bpy
import numpy as np

from ..solver import monodromy_angles, regular_face_mask
from . import diagnostics, display, glyphs, storage

ROLE = "error_slice"
OBJECT_NAME = "SymFrames Error Slice"
QUANTITY_ATTRIBUTES = {"MONODROMY": "monodromy", "ADAPTATION": "adaptation"}
FACE_ATTRIBUTE = "face"
NETWORK_ATTRIBUTE = "network"
COLOUR_ATTRIBUTE = "symframes_colour"
STATS_KEY = "symframes_slice"
MATERIALS = ("SymFrames Error Slice Grey",
             *(f"SymFrames Error Slice {k + 1}" for k in range(glyphs.ERROR_STEPS)))
RAMP = glyphs.ERROR_RAMP  # at 0, 1/2, 1
GREY = (0.35, 0.35, 0.35)


def ramp_colours(values: np.ndarray, scale: float, grey: np.ndarray | None = None) -> np.ndarray:
    """(k, 4) RGBA of values / scale clamped to [0, 1] through RAMP; grey
    where the mask grey (k,) is set."""
    t = np.clip(np.asarray(values, float) / max(float(scale), 1e-300), 0.0, 1.0)
    x = np.linspace(0.0, 1.0, len(RAMP))
    rgb = np.stack([np.interp(t, x, RAMP[:, c]) for c in range(3)], axis=1)
    if grey is not None:
        rgb[np.asarray(grey, bool)] = GREY
    return np.c_[rgb, np.ones(len(rgb))]


def slice_values(field, omega: np.ndarray | None, adaptation: np.ndarray | None, network_faces: np.ndarray,
                 ds: display.DisplaySettings, quantity: str):
    """(face ids (k,), triangles (k, 3), values (k,) radians, grey (k,) bool).
    network_faces : (j,) ids of the faces the network passes through."""
    mesh = field.mesh
    if quantity == "MONODROMY":
        f, tris = display.slice_faces(field, ds)
        return f, tris, monodromy_angles(mesh, omega, f), ~regular_face_mask(mesh, network_faces)[f]
    if quantity == "ADAPTATION":
        if adaptation is None or len(adaptation) != mesh.n_vertices:
            raise ValueError("this result stores no adaptation errors; compute the field again")
        f, tris = display.kept_boundary_faces(field, ds)
        a = adaptation[mesh.faces[f]]
        measured = a >= 0
        n = measured.sum(axis=1)
        val = np.where(n > 0, np.where(measured, a, 0.0).sum(axis=1) / np.maximum(n, 1), -1.0)
        return f, tris, val, n == 0
    raise ValueError(f"unknown slice quantity {quantity!r}")


def materials():
    """Material 0 for grey faces, then one per error step: the viewport
    display color is the step's color (what the Solid view shows by
    default); the shading reads the color attribute (smooth)."""
    colours = [GREY, *map(tuple, glyphs.error_step_colours())]
    mats = []
    for name, colour in zip(MATERIALS, colours):
        mat = bpy.data.materials.get(name)
        if mat is None:
            mat = bpy.data.materials.new(name)
            bsdf = glyphs._principled(mat, colour)
            if bsdf is not None:
                col = mat.node_tree.nodes.new("ShaderNodeVertexColor")
                col.layer_name = COLOUR_ATTRIBUTE
                col.location = (-400, 200)
                mat.node_tree.links.new(col.outputs["Color"], bsdf.inputs["Base Color"])
        mats.append(mat)
    return mats


def material_steps(values: np.ndarray, scale: float, grey: np.ndarray) -> np.ndarray:
    """(k,) material index: 0 where grey, else 1 + the step of values / scale."""
    t = np.clip(np.asarray(values, float) / max(float(scale), 1e-300), 0.0, 1.0)
    step = 1 + np.minimum((t * glyphs.ERROR_STEPS).astype(np.int32), glyphs.ERROR_STEPS - 1)
    return np.where(np.asarray(grey, bool), 0, step).astype(np.int32)


def new_slice_mesh(vertices: np.ndarray, tris: np.ndarray, faces: np.ndarray, values: np.ndarray,
                   grey: np.ndarray, quantity: str, scale: float, name: str = "SymFrames Error Slice"):
    """A mesh of the triangles tris (k, 3) into vertices (n, 3), only the
    used vertices kept, with the attributes of the module docstring."""

    def finish(me):
        for mat in materials():
            me.materials.append(mat)
        attr = QUANTITY_ATTRIBUTES[quantity]
        me.attributes.new(attr, "FLOAT", "FACE")
        me.attributes[attr].data.foreach_set("value", np.asarray(values, np.float32))
        me.attributes.new(FACE_ATTRIBUTE, "INT", "FACE")
        me.attributes[FACE_ATTRIBUTE].data.foreach_set("value", np.asarray(faces, np.int32))
        if quantity == "MONODROMY":
            me.attributes.new(NETWORK_ATTRIBUTE, "BOOLEAN", "FACE")
            me.attributes[NETWORK_ATTRIBUTE].data.foreach_set("value", np.asarray(grey, bool))
        me.color_attributes.new(COLOUR_ATTRIBUTE, "FLOAT_COLOR", "CORNER")
        me.color_attributes.active_color = me.color_attributes[COLOUR_ATTRIBUTE]
        me.color_attributes.render_color_index = me.color_attributes.active_color_index
        _set_colours(me, values, scale, grey)

    return diagnostics.new_triangle_mesh(name, vertices, tris, finish)


def _set_colours(me, values: np.ndarray, scale: float, grey: np.ndarray) -> None:
    corners = np.repeat(ramp_colours(values, scale, grey), 3, axis=0)  # triangles: three corners per face
    me.color_attributes[COLOUR_ATTRIBUTE].data.foreach_set("color", corners.astype(np.float32).ravel())
    me.polygons.foreach_set("material_index", material_steps(values, scale, grey))


def quantity_scale(scene, quantity: str) -> float:
    s = scene.symframes
    return float(s.monodromy_scale if quantity == "MONODROMY" else s.error_scale)


def write_slice(scene, quantity: str) -> dict:
    """Replace the scene's error slice from the stored field; returns its
    statistics {'quantity', 'faces', 'grey', 'mean_deg', 'max_deg'} (mean
    and max over the faces not grey)."""
    field = storage.frame_field(scene)
    if field is None:
        raise ValueError("no field computed yet: press Compute Field first")
    me_field = scene.symframes.field
    omega = storage.field_omega(scene) if quantity == "MONODROMY" else None
    ds = display.DisplaySettings.from_scene(scene)
    f, tris, val, grey = slice_values(field, omega, storage.read_adaptation(me_field),
                                      storage.network_face_ids(scene), ds, quantity)
    if len(f) == 0:
        where = "on the slice plane" if quantity == "MONODROMY" else "on the kept side of the slice plane"
        raise ValueError(f"no tet face {where}: move the slice plane into the solid (Slice Position)")
    shown = val[~grey]
    stats = {"quantity": quantity, "faces": int(len(f)), "grey": int(grey.sum()),
             "mean_deg": float(np.degrees(shown.mean())) if len(shown) else 0.0,
             "max_deg": float(np.degrees(shown.max())) if len(shown) else 0.0}
    me = new_slice_mesh(field.mesh.vertices, tris, f, val, grey, quantity, quantity_scale(scene, quantity))
    obj = storage.replace_output(scene, ROLE, OBJECT_NAME, me)
    obj[STATS_KEY] = stats
    return stats


def recolour(scene) -> None:
    """Recolour the error slice with the scene's current scale (live)."""
    obj = storage.output_object(scene, ROLE)
    if obj is None or obj.type != "MESH" or STATS_KEY not in obj:
        return
    quantity = obj[STATS_KEY].get("quantity")
    me = obj.data
    attr = me.attributes.get(QUANTITY_ATTRIBUTES.get(quantity, ""))
    if attr is None or COLOUR_ATTRIBUTE not in me.color_attributes:
        return
    k = len(me.polygons)
    val = np.empty(k, np.float32)
    attr.data.foreach_get("value", val)
    grey = val < 0
    if NETWORK_ATTRIBUTE in me.attributes:
        net = np.empty(k, bool)
        me.attributes[NETWORK_ATTRIBUTE].data.foreach_get("value", net)
        grey |= net
    _set_colours(me, val, quantity_scale(scene, quantity), grey)
    me.update()


def remove_unused_material() -> None:
    for name in MATERIALS:
        mat = bpy.data.materials.get(name)
        if mat is not None and mat.users == 0:
            bpy.data.materials.remove(mat)
