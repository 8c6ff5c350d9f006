"""Diagnostics of a stored field: its singular faces as a mesh object.

A tet-mesh face is singular where the closest-rotation matchings of its
three vertex frames fail to close (solver.analysis.measures.matched_singular_faces,
§5.2).  Singular faces the network passes through are expected; the others
are spurious singularities, which a good field does not have.  The mesh
object has one triangle per singular face, material 0 (orange) for network
faces and 1 (red) for spurious ones, and a boolean face attribute
``spurious``.
"""

from __future__ import annotations

import bpy
import numpy as np

from ..solver.analysis.measures import matched_singular_faces
from . import storage

MATERIALS = (("SymFrames Network Singularity", (0.95, 0.55, 0.05)),
             ("SymFrames Spurious Singularity", (0.90, 0.05, 0.05)))
SPURIOUS_ATTRIBUTE = "spurious"
COUNTS_KEY = "symframes_counts"


def singular_faces(field, network_faces: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(vertex triples (k, 3) of the singular faces, spurious (k,) bool).

    field : solver.analysis.streamlines.FrameField of the stored result
    network_faces : (j, 3) vertex triples of the faces the network passes through
    """
    if network_faces is None:
        raise ValueError("this result does not store its network faces; compute the field again")
    mesh = field.mesh
    found = matched_singular_faces(mesh, field.frames)
    sing = np.asarray(found[0] if isinstance(found, tuple) else found, bool)
    on_network = np.zeros(mesh.n_faces, bool)
    ids = mesh.face_index(network_faces) if len(network_faces) else np.zeros(0, np.int64)
    on_network[ids[ids >= 0]] = True
    f = np.nonzero(sing)[0]
    return mesh.faces[f], ~on_network[f]


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
    returns the counts {'singular': k, 'spurious': s}."""
    field = storage.frame_field(scene)
    if field is None:
        raise ValueError("no field computed yet: press Compute Field first")
    tris, spurious = singular_faces(field, storage.read_network_faces(scene.symframes.field))
    counts = {"singular": int(len(tris)), "spurious": int(spurious.sum())}
    me = new_singular_mesh(field.mesh.vertices, tris, spurious)
    obj = storage.replace_output(scene, "singular_faces", "SymFrames Singular Faces", me)
    obj[COUNTS_KEY] = counts
    return counts


def remove_unused_materials() -> None:
    for name, _ in MATERIALS:
        mat = bpy.data.materials.get(name)
        if mat is not None and mat.users == 0:
            bpy.data.materials.remove(mat)
