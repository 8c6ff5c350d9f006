"""The Darboux derivative omega drawn as one arrow per tet edge (Fig. 17, 19).

omega_ij is the rotation taking the frame at vertex i to the frame at j
(Eq. 8): its direction is the rotation axis, its length the angle.  The
arrow object is a mesh of loose points, one at the midpoint of each drawn
edge, with a FLOAT_VECTOR point attribute ``omega`` (radians, world
coordinates) and an INT attribute ``edge`` (the solver's edge id); its
Geometry Nodes modifier instances an arrow along +z on every point, turned
onto omega (Align Rotation to Vector) and scaled to

    length = |omega| * Length per Radian,   width = Width.

Length per Radian is the scene's Arrow Scale times the mean edge length of
the tet mesh (kept on the object as ``symframes_mean_edge``), so changing
the scale is live.  Long arrows mark where the field turns fast: near the
singular curves and sharp corners.
"""

from __future__ import annotations

import bpy
import numpy as np

from . import glyphs, storage

ROLE = "omega_arrows"
OBJECT_NAME = "SymFrames Omega"
NODE_GROUP = "SymFrames Omega Arrow"
NODE_GROUP_VERSION = 1
MODIFIER = "SymFrames Omega Arrows"
MATERIAL = ("SymFrames Omega", (0.03, 0.10, 0.45))  # dark blue, as in the paper
OMEGA_ATTRIBUTE = "omega"
EDGE_ATTRIBUTE = "edge"
MEAN_EDGE_KEY = "symframes_mean_edge"
WIDTH = 0.05  # arrow width, relative to the mean edge length
SHAFT = 0.75  # shaft length of the unit arrow; the head takes the rest
INPUTS = {"Length per Radian": ("NodeSocketFloat", 0.1), "Width": ("NodeSocketFloat", 0.01)}


def material():
    mat = bpy.data.materials.get(MATERIAL[0])
    if mat is None:
        mat = bpy.data.materials.new(MATERIAL[0])
        glyphs._principled(mat, MATERIAL[1])
    return mat


def node_group():
    """The arrow node group, built once per file (rebuilt if outdated)."""
    ng = glyphs.current_node_group(NODE_GROUP, NODE_GROUP_VERSION)
    if ng is not None:
        return ng
    ng = glyphs.new_node_group(NODE_GROUP, NODE_GROUP_VERSION, INPUTS)

    nodes, links = ng.nodes, ng.links
    gin = nodes.new("NodeGroupInput")
    gin.location = (-900, 0)
    gout = nodes.new("NodeGroupOutput")
    gout.location = (500, 0)
    # the unit arrow along +z from the origin: shaft of diameter 1, head of diameter 2
    shaft = nodes.new("GeometryNodeMeshCylinder")
    shaft.location = (-700, -300)
    shaft.inputs["Vertices"].default_value = 8
    shaft.inputs["Radius"].default_value = 0.5
    shaft.inputs["Depth"].default_value = SHAFT
    head = nodes.new("GeometryNodeMeshCone")
    head.location = (-700, -550)
    head.inputs["Vertices"].default_value = 8
    head.inputs["Radius Bottom"].default_value = 1.0
    head.inputs["Depth"].default_value = 1.0 - SHAFT
    join = nodes.new("GeometryNodeJoinGeometry")
    join.location = (-250, -400)
    for k, (node, z) in enumerate(((shaft, SHAFT / 2), (head, (1.0 + SHAFT) / 2))):
        move = nodes.new("GeometryNodeTransform")
        move.location = (-480, -300 - 250 * k)
        move.inputs["Translation"].default_value = (0.0, 0.0, z)
        links.new(node.outputs["Mesh"], move.inputs["Geometry"])
        links.new(move.outputs["Geometry"], join.inputs["Geometry"])
    setmat = nodes.new("GeometryNodeSetMaterial")
    setmat.location = (-100, -400)
    setmat.inputs["Material"].default_value = material()
    links.new(join.outputs["Geometry"], setmat.inputs["Geometry"])
    # rotation: +z onto omega; scale: (width, width, |omega| * length per radian)
    omega = nodes.new("GeometryNodeInputNamedAttribute")
    omega.location = (-700, 250)
    omega.data_type = "FLOAT_VECTOR"
    omega.inputs["Name"].default_value = OMEGA_ATTRIBUTE
    align = nodes.new("FunctionNodeAlignRotationToVector")
    align.location = (-450, 300)
    align.axis = "Z"
    links.new(omega.outputs["Attribute"], align.inputs["Vector"])
    length = nodes.new("ShaderNodeVectorMath")
    length.location = (-450, 100)
    length.operation = "LENGTH"
    links.new(omega.outputs["Attribute"], length.inputs[0])
    mul = nodes.new("ShaderNodeMath")
    mul.location = (-250, 100)
    mul.operation = "MULTIPLY"
    links.new(length.outputs["Value"], mul.inputs[0])
    links.new(gin.outputs["Length per Radian"], mul.inputs[1])
    scale = nodes.new("ShaderNodeCombineXYZ")
    scale.location = (-80, 100)
    links.new(gin.outputs["Width"], scale.inputs["X"])
    links.new(gin.outputs["Width"], scale.inputs["Y"])
    links.new(mul.outputs["Value"], scale.inputs["Z"])
    inst = nodes.new("GeometryNodeInstanceOnPoints")
    inst.location = (200, 0)
    links.new(gin.outputs["Geometry"], inst.inputs["Points"])
    links.new(setmat.outputs["Geometry"], inst.inputs["Instance"])
    links.new(align.outputs["Rotation"], inst.inputs["Rotation"])
    links.new(scale.outputs["Vector"], inst.inputs["Scale"])
    links.new(inst.outputs["Instances"], gout.inputs["Geometry"])
    return ng


def remove_unused_helpers() -> None:
    glyphs.remove_unused(NODE_GROUP, (MATERIAL[0],))


def alignable(omega: np.ndarray) -> np.ndarray:
    """omega (k, 3) with the components below 1e-9 of its length set to 0.

    Align Rotation to Vector turns +z onto a vector within ~1e-19 of -z by
    nothing: their cross product, the rotation axis, is not zero but does not
    normalise in single precision (exactly opposite vectors it handles).  Such
    arrows pointed up instead of down: 3 of 5,690 on a plate mesh, omega
    (2e-26, 0, -0.18), a component the solver leaves as round-off."""
    w = np.array(omega, dtype=float, copy=True).reshape(-1, 3)
    w[np.abs(w) < 1e-9 * np.linalg.norm(w, axis=1, keepdims=True)] = 0.0
    return w


def new_arrow_mesh(points: np.ndarray, omega: np.ndarray, edges: np.ndarray, name: str = "SymFrames Omega Points"):
    """A mesh of loose points (k, 3) with the ``omega`` (k, 3) and ``edge``
    (k,) point attributes."""
    return glyphs.new_point_mesh(name, points, {OMEGA_ATTRIBUTE: ("FLOAT_VECTOR", alignable(omega)),
                                                EDGE_ATTRIBUTE: ("INT", edges)})


def write_arrows(scene, points: np.ndarray, omega: np.ndarray, edges: np.ndarray, mean_edge: float):
    """Replace the scene's omega arrows; returns the arrow object."""
    me = new_arrow_mesh(points, omega, edges)
    obj = storage.replace_output(scene, ROLE, OBJECT_NAME, me)
    obj[MEAN_EDGE_KEY] = float(mean_edge)
    mod = obj.modifiers.get(MODIFIER)
    if mod is None:
        mod = obj.modifiers.new(MODIFIER, "NODES")
    ng = node_group()
    if mod.node_group != ng:
        mod.node_group = ng
    sync_modifier(scene)
    return obj


def sync_modifier(scene) -> None:
    """Copy the scene's Arrow Scale into the modifier (live)."""
    obj = storage.output_object(scene, ROLE)
    if obj is None:
        return
    mod = obj.modifiers.get(MODIFIER)
    if mod is None or mod.node_group is None:
        return
    h = float(obj.get(MEAN_EDGE_KEY, 1.0))
    values = {"Length per Radian": float(scene.symframes.omega_scale) * h, "Width": WIDTH * h}
    for item in mod.node_group.interface.items_tree:
        if getattr(item, "in_out", None) == "INPUT" and item.name in values:
            storage.set_modifier_input(mod, item.identifier, values[item.name])
    obj.update_tag()


def arrow_points(obj) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (k, 3), omega (k, 3), edge ids (k,)) held by an arrow object."""
    me = obj.data
    n = len(me.vertices)
    P = np.empty(3 * n, np.float32)
    me.attributes["position"].data.foreach_get("vector", P)
    w = np.empty(3 * n, np.float32)
    me.attributes[OMEGA_ATTRIBUTE].data.foreach_get("vector", w)
    e = np.empty(n, np.int32)
    me.attributes[EDGE_ATTRIBUTE].data.foreach_get("value", e)
    return P.reshape(-1, 3), w.reshape(-1, 3), e
