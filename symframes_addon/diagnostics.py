"""Diagnostics of a stored field: its singular faces as a mesh object.

A tet-mesh face is singular where the matchings of its three vertex frames
fail to close (§5.2); singular faces off the network are spurious, which a
good field does not have.  Which faces are singular and which spurious is
the solver's rule (solver.singular_faces: each edge matched as the solver's
omega carries the frame across it, the matchings the exports write).  The
mesh object has one triangle per singular face, material 0 (orange) for
network faces and 1 (red) for spurious ones, and a boolean face attribute
``spurious``.  The counts also say on how many faces closest-rotation
matching, which a tool reading only the frames would use, reads the field
otherwise.
"""

from __future__ import annotations

import bpy
import numpy as np

from ..solver import singular_faces
from . import storage

MATERIALS = (("SymFrames Network Singularity", (0.95, 0.55, 0.05)),
             ("SymFrames Spurious Singularity", (0.90, 0.05, 0.05)))
SPURIOUS_ATTRIBUTE = "spurious"
COUNTS_KEY = "symframes_counts"


def _material(name, colour):
    mat = bpy.data.materials.get(name)
    if mat is None:
        mat = bpy.data.materials.new(name)
        mat.diffuse_color = (*colour, 1.0)
        if mat.node_tree is None:  # Blender < 5.0 creates materials without nodes
            mat.use_nodes = True
        bsdf = mat.node_tree.nodes.get("Principled BSDF")
        if bsdf is not None:
            bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    return mat


def new_triangle_mesh(name: str, vertices: np.ndarray, tris: np.ndarray, finish):
    """A new mesh of the triangles tris (k, 3) into vertices (n, 3), only the
    used vertices kept; finish(me) then adds materials and attributes.
    Nothing is left in the file if any step fails."""
    used, local = np.unique(np.asarray(tris, np.int64).ravel(), return_inverse=True)
    k = len(tris)
    me = bpy.data.meshes.new(name)
    try:
        me.vertices.add(len(used))
        if len(used):  # an empty mesh has no position attribute
            me.attributes["position"].data.foreach_set("vector", np.asarray(vertices[used], np.float32).ravel())
        me.loops.add(3 * k)
        me.polygons.add(k)
        me.polygons.foreach_set("loop_start", np.arange(0, 3 * k, 3, dtype=np.int32))
        me.loops.foreach_set("vertex_index", local.astype(np.int32))
        me.update(calc_edges=True)
        finish(me)
    except Exception:
        bpy.data.meshes.remove(me)
        raise
    return me


def new_singular_mesh(vertices: np.ndarray, tris: np.ndarray, spurious: np.ndarray,
                      name: str = "SymFrames Singular Faces"):
    """A mesh of the triangles tris (k, 3) into vertices (n, 3), only the
    used vertices kept; spurious (k,) sets the material and the attribute."""

    def finish(me):
        for name_, colour in MATERIALS:
            me.materials.append(_material(name_, colour))
        me.polygons.foreach_set("material_index", np.asarray(spurious, np.int32))
        me.attributes.new(SPURIOUS_ATTRIBUTE, "BOOLEAN", "FACE")
        me.attributes[SPURIOUS_ATTRIBUTE].data.foreach_set("value", np.asarray(spurious, bool))

    return new_triangle_mesh(name, vertices, tris, finish)


def write_singular_faces(scene) -> dict:
    """Replace the scene's singular-faces object from the stored field;
    returns the counts {'singular': k, 'spurious': s, 'closest_differs': d}."""
    field = storage.frame_field(scene)
    if field is None:
        raise ValueError("no field computed yet: press Compute Field first")
    mesh = field.mesh
    sf = singular_faces(mesh, storage.field_omega(scene), field.frames,
                        storage.network_face_ids(scene))
    f = np.nonzero(sf.singular)[0]
    spurious = sf.spurious[f]
    counts = {"singular": int(len(f)), "spurious": int(spurious.sum()), "closest_differs": sf.disagreements}
    me = new_singular_mesh(mesh.vertices, mesh.faces[f], spurious)
    obj = storage.replace_output(scene, "singular_faces", "SymFrames Singular Faces", me)
    obj[COUNTS_KEY] = counts
    return counts


def remove_unused_materials() -> None:
    for name, _ in MATERIALS:
        mat = bpy.data.materials.get(name)
        if mat is not None and mat.users == 0:
            bpy.data.materials.remove(mat)
