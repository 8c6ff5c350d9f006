"""Diagnostics of a stored field: its singular faces as a mesh object.

A tet-mesh face is singular where the matchings of its three vertex frames
fail to close (§5.2).  Each edge is matched against the frame the solver's
omega carries across it (solver.analysis.measures.omega_singular_faces):
the field's own matchings, the ones the exports write.  Singular faces the
network passes through are expected; the others are spurious
singularities, which a good field does not have.  The mesh object has one
triangle per singular face, material 0 (orange) for network faces and 1
(red) for spurious ones, and a boolean face attribute ``spurious``.

Closest-rotation matching (matched_singular_faces), which a tool reading
only the frames would use, is ambiguous where an edge turns by ~45 degrees:
next to a curve that passes close to an edge it can flag a neighbouring
face instead of the pierced one.  The counts say on how many faces the two
readings differ.
"""

from __future__ import annotations

import bpy
import numpy as np

from ..solver.analysis.measures import matched_singular_faces, omega_singular_faces
from . import storage

MATERIALS = (("SymFrames Network Singularity", (0.95, 0.55, 0.05)),
             ("SymFrames Spurious Singularity", (0.90, 0.05, 0.05)))
SPURIOUS_ATTRIBUTE = "spurious"
COUNTS_KEY = "symframes_counts"


def singular_faces(field, omega: np.ndarray, network_faces: np.ndarray | None
                   ) -> tuple[np.ndarray, np.ndarray, int]:
    """(vertex triples (k, 3) of the singular faces, spurious (k,) bool,
    faces where closest-rotation matching reads the field differently).

    field : solver.analysis.streamlines.FrameField of the stored result
    omega : (#E, 3) its Darboux derivative on field.mesh.edges
    network_faces : (j, 3) vertex triples of the faces the network passes through
    """
    if network_faces is None:
        raise ValueError("this result does not store its network faces; compute the field again")
    mesh = field.mesh
    sing = omega_singular_faces(mesh, omega, field.frames)
    closest, _ = matched_singular_faces(mesh, field.frames)
    on_network = np.zeros(mesh.n_faces, bool)
    ids = mesh.face_index(network_faces) if len(network_faces) else np.zeros(0, np.int64)
    on_network[ids[ids >= 0]] = True
    f = np.nonzero(sing)[0]
    return mesh.faces[f], ~on_network[f], int((sing != closest).sum())


def singular_counts(metrics: dict) -> dict:
    """{'singular', 'spurious', 'missing', 'closest_differs'} of a solve's
    report metrics, from the omega-aware matchings (reports written before
    they were counted: the closest-rotation ones, and no difference)."""
    if "omega_singular_faces" not in metrics:
        return {"singular": metrics.get("singular_faces", 0), "spurious": metrics.get("spurious_singular_faces", 0),
                "missing": metrics.get("missing_singular_faces", 0), "closest_differs": 0}
    return {"singular": metrics["omega_singular_faces"], "spurious": metrics["omega_spurious_singular_faces"],
            "missing": metrics["omega_missing_singular_faces"],
            "closest_differs": metrics.get("matching_disagreements", 0)}


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
    omega, _ = storage.field_omega(scene)
    tris, spurious, differs = singular_faces(field, omega, storage.read_network_faces(scene.symframes.field))
    counts = {"singular": int(len(tris)), "spurious": int(spurious.sum()), "closest_differs": differs}
    me = new_singular_mesh(field.mesh.vertices, tris, spurious)
    obj = storage.replace_output(scene, "singular_faces", "SymFrames Singular Faces", me)
    obj[COUNTS_KEY] = counts
    return counts


def remove_unused_materials() -> None:
    for name, _ in MATERIALS:
        mat = bpy.data.materials.get(name)
        if mat is not None and mat.users == 0:
            bpy.data.materials.remove(mat)
