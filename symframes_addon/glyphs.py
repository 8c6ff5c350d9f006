"""Cross glyphs: one instanced cross per sampled point, via Geometry Nodes.

The glyph object is a mesh of loose points with a QUATERNION point attribute
``frame``; its Geometry Nodes modifier instances a cross of three orthogonal
bars (red, green, blue for the frame's first, second and third axis) on
every point, rotated by Named Attribute(frame) -> Instance on Points.Rotation.
Writing 100k points is two foreach_set calls.

In the error colourings the points also carry a FLOAT attribute (radians):
``adaptation`` (normal adaptation error) or ``monodromy`` (mean monodromy
of the faces around the vertex); the modifier's Error Attribute names it.
The node group then picks one of ERROR_STEPS crosses, each with its own
material, by the step of error / Error Scale (clamped to [0, 1]), and
stores that factor on the instances as ``symframes_error``.  The materials'
viewport display colors are the steps' colors, which the Solid view shows
as it is (Color: Material); Material Preview and renders show a smooth ramp,
as the materials read the factor with an Attribute node (Instancer).
"""

from __future__ import annotations

import bpy
import numpy as np

from . import display, storage

NODE_GROUP = "SymFrames Cross Glyph"
NODE_GROUP_VERSION = 4
MODIFIER = "SymFrames Glyphs"
AXIS_COLOURS = ((0.85, 0.12, 0.10), (0.15, 0.65, 0.15), (0.12, 0.30, 0.90))
AXIS_MATERIALS = tuple(f"SymFrames Axis {a}" for a in "XYZ")
ERROR_MATERIAL = "SymFrames Glyph Error"  # + " 1" .. " ERROR_STEPS"
ERROR_STEPS = 8  # error colors the Solid view shows (it shows a material's viewport color)
ERROR_RAMP = np.array([(0.10, 0.25, 0.90), (0.95, 0.85, 0.15), (0.90, 0.08, 0.05)])  # at 0, 1/2, 1
ERROR_ATTRIBUTE = display.ERROR_ATTRIBUTES["ADAPTATION"]
MONODROMY_ATTRIBUTE = display.ERROR_ATTRIBUTES["MONODROMY"]
ERROR_FACTOR = "symframes_error"
BAR_THICKNESS = 0.14  # relative to the bar length
# modifier inputs: name -> (socket type, default)
INPUTS = {
    "Size": ("NodeSocketFloat", 0.1),
    "Color by Error": ("NodeSocketBool", False),
    "Error Scale": ("NodeSocketFloat", 0.0872665),
    "Error Attribute": ("NodeSocketString", ERROR_ATTRIBUTE),
}


# --------------------------------------------------------------- materials
def _principled(mat, colour):
    # the viewport display color: what the Solid view shows by default (Color: Material)
    mat.diffuse_color = (*colour, 1.0)
    if mat.node_tree is None:  # Blender < 5.0 creates materials without nodes
        mat.use_nodes = True
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    if bsdf is not None:
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Roughness"].default_value = 0.45
    return bsdf


def axis_material(axis: int):
    """Material of frame axis 0, 1 or 2 (shared by glyph bars and streamlines)."""
    mat = bpy.data.materials.get(AXIS_MATERIALS[axis])
    if mat is None:
        mat = bpy.data.materials.new(AXIS_MATERIALS[axis])
        _principled(mat, AXIS_COLOURS[axis])
    return mat


def error_step_colours(steps: int | None = None) -> np.ndarray:
    """(steps, 3) RGB of ERROR_RAMP at the middle of each step of [0, 1]."""
    steps = ERROR_STEPS if steps is None else steps
    t = (np.arange(steps) + 0.5) / steps
    x = np.linspace(0.0, 1.0, len(ERROR_RAMP))
    return np.stack([np.interp(t, x, ERROR_RAMP[:, c]) for c in range(3)], axis=1)


def error_materials():
    """One material per error step: in Material Preview and renders a smooth
    ramp from the instance attribute (blue, yellow, red at Error Scale); in
    the Solid view, whose default color is the material's viewport display
    color, the step's color."""
    mats = []
    for k, colour in enumerate(error_step_colours()):
        name = f"{ERROR_MATERIAL} {k + 1}"
        mat = bpy.data.materials.get(name)
        if mat is None:
            mat = bpy.data.materials.new(name)
            bsdf = _principled(mat, tuple(colour))
            if bsdf is not None:
                nodes, links = mat.node_tree.nodes, mat.node_tree.links
                attr = nodes.new("ShaderNodeAttribute")
                attr.attribute_type = "INSTANCER"
                attr.attribute_name = ERROR_FACTOR
                attr.location = (-700, 200)
                ramp = nodes.new("ShaderNodeValToRGB")
                ramp.location = (-450, 200)
                els = ramp.color_ramp.elements
                els[0].color = (*ERROR_RAMP[0], 1.0)
                els[1].color = (*ERROR_RAMP[-1], 1.0)
                mid = els.new(0.5)
                mid.color = (*ERROR_RAMP[1], 1.0)
                links.new(attr.outputs["Fac"], ramp.inputs["Fac"])
                links.new(ramp.outputs["Color"], bsdf.inputs["Base Color"])
        mats.append(mat)
    return mats


# -------------------------------------------------------------- node group
def current_node_group(name: str, version: int):
    """The node group of that name if it is of this version, else None."""
    ng = bpy.data.node_groups.get(name)
    return ng if ng is not None and ng.get("symframes_version") == version else None


def new_node_group(name: str, version: int, inputs: dict):
    """A new Geometry Nodes group: Geometry in, the given inputs
    {name: (socket type, default)} (floats clamped at 0), Geometry out.  An
    outdated group of that name is renamed out of the way."""
    old = bpy.data.node_groups.get(name)
    if old is not None:
        old.name = name + " (old)"
    ng = bpy.data.node_groups.new(name, "GeometryNodeTree")
    ng["symframes_version"] = version
    iface = ng.interface
    iface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    for socket, (kind, default) in inputs.items():
        sock = iface.new_socket(socket, in_out="INPUT", socket_type=kind)
        sock.default_value = default
        if kind == "NodeSocketFloat":
            sock.min_value = 0.0
    iface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    return ng


def node_group():
    """The glyph node group, built once per file (rebuilt if outdated)."""
    ng = current_node_group(NODE_GROUP, NODE_GROUP_VERSION)
    if ng is not None:
        return ng
    ng = new_node_group(NODE_GROUP, NODE_GROUP_VERSION, INPUTS)

    nodes, links = ng.nodes, ng.links
    gin = nodes.new("NodeGroupInput")
    gin.location = (-900, 0)
    gout = nodes.new("NodeGroupOutput")
    gout.location = (700, 0)
    # the cross: three bars, in the axis colors, and once more per error step
    join = nodes.new("GeometryNodeJoinGeometry")
    join.location = (-150, -300)
    plain = nodes.new("GeometryNodeJoinGeometry")
    plain.location = (-150, -900)
    t = BAR_THICKNESS
    for axis in range(3):
        y = -250 - 200 * axis
        cube = nodes.new("GeometryNodeMeshCube")
        cube.location = (-650, y)
        dims = [t, t, t]
        dims[axis] = 1.0
        cube.inputs["Size"].default_value = dims
        setmat = nodes.new("GeometryNodeSetMaterial")
        setmat.location = (-400, y)
        setmat.inputs["Material"].default_value = axis_material(axis)
        links.new(cube.outputs["Mesh"], setmat.inputs["Geometry"])
        links.new(setmat.outputs["Geometry"], join.inputs["Geometry"])
        links.new(cube.outputs["Mesh"], plain.inputs["Geometry"])
    # one instance per error step, picked by the step of error / Error Scale
    steps = nodes.new("GeometryNodeGeometryToInstance")
    steps.location = (150, -900)
    # a multi-input socket lists its links last-linked first: link the last step first
    for k, mat in reversed(list(enumerate(error_materials()))):
        setmat = nodes.new("GeometryNodeSetMaterial")
        setmat.location = (-100, -900 - 120 * k)
        setmat.inputs["Material"].default_value = mat
        links.new(plain.outputs["Geometry"], setmat.inputs["Geometry"])
        links.new(setmat.outputs["Geometry"], steps.inputs["Geometry"])
    which = nodes.new("GeometryNodeSwitch")
    which.input_type = "GEOMETRY"
    which.location = (300, -400)
    links.new(gin.outputs["Color by Error"], which.inputs["Switch"])
    links.new(join.outputs["Geometry"], which.inputs["False"])
    links.new(steps.outputs["Instances"], which.inputs["True"])
    frame = nodes.new("GeometryNodeInputNamedAttribute")
    frame.location = (-400, 200)
    frame.data_type = "QUATERNION"
    frame.inputs["Name"].default_value = storage.FRAME_ATTRIBUTE
    # error / scale in [0, 1], and its step min(floor(factor * STEPS), STEPS - 1)
    err = nodes.new("GeometryNodeInputNamedAttribute")
    err.location = (0, -250)
    err.data_type = "FLOAT"
    links.new(gin.outputs["Error Attribute"], err.inputs["Name"])
    div = nodes.new("ShaderNodeMath")
    div.location = (200, -250)
    div.operation = "DIVIDE"
    div.use_clamp = True
    links.new(err.outputs["Attribute"], div.inputs[0])
    links.new(gin.outputs["Error Scale"], div.inputs[1])
    step = div
    for op, value in (("MULTIPLY", ERROR_STEPS), ("FLOOR", None), ("MINIMUM", ERROR_STEPS - 1)):
        node = nodes.new("ShaderNodeMath")
        node.location = (step.location[0] + 150, -450)
        node.operation = op
        links.new(step.outputs["Value"], node.inputs[0])
        if value is not None:
            node.inputs[1].default_value = value
        step = node
    inst = nodes.new("GeometryNodeInstanceOnPoints")
    inst.location = (0, 0)
    links.new(gin.outputs["Geometry"], inst.inputs["Points"])
    links.new(which.outputs["Output"], inst.inputs["Instance"])
    links.new(gin.outputs["Color by Error"], inst.inputs["Pick Instance"])
    links.new(step.outputs["Value"], inst.inputs["Instance Index"])
    links.new(frame.outputs["Attribute"], inst.inputs["Rotation"])
    links.new(gin.outputs["Size"], inst.inputs["Scale"])
    # the factor on the instances, for the error materials' smooth ramp
    store = nodes.new("GeometryNodeStoreNamedAttribute")
    store.location = (400, 0)
    store.data_type = "FLOAT"
    store.domain = "INSTANCE"
    store.inputs["Name"].default_value = ERROR_FACTOR
    links.new(inst.outputs["Instances"], store.inputs["Geometry"])
    links.new(div.outputs["Value"], store.inputs["Value"])
    links.new(store.outputs["Geometry"], gout.inputs["Geometry"])
    return ng


def remove_unused(node_group_prefix: str, material_names) -> None:
    """Drop the node groups named with that prefix (old versions included)
    and the named materials once nothing uses them."""
    for ng in [g for g in bpy.data.node_groups if g.name.startswith(node_group_prefix)]:
        if ng.users == 0:
            bpy.data.node_groups.remove(ng)
    for name in material_names:
        mat = bpy.data.materials.get(name)
        if mat is not None and mat.users == 0:
            bpy.data.materials.remove(mat)


def remove_unused_helpers() -> None:
    """Drop the node group and the materials once nothing uses them."""
    remove_unused(NODE_GROUP, (*AXIS_MATERIALS, *(f"{ERROR_MATERIAL} {k + 1}" for k in range(ERROR_STEPS))))


# ------------------------------------------------------------------- write
_ATTRIBUTE_KEYS = {"FLOAT": ("value", np.float32), "INT": ("value", np.int32),
                   "QUATERNION": ("value", np.float32), "FLOAT_VECTOR": ("vector", np.float32)}


def new_point_mesh(name: str, points: np.ndarray, attributes: dict):
    """A new mesh of loose points (k, 3) with the point attributes
    {name: (type, values)}; nothing is left in the file if a step fails."""
    me = bpy.data.meshes.new(name)
    try:
        me.vertices.add(len(points))
        if len(points):  # an empty mesh has no position attribute
            me.attributes["position"].data.foreach_set("vector", np.asarray(points, np.float32).ravel())
        for attr, (kind, values) in attributes.items():
            key, dtype = _ATTRIBUTE_KEYS[kind]
            me.attributes.new(attr, kind, "POINT")
            # fetch by name: a reference taken before another attributes.new() goes stale
            me.attributes[attr].data.foreach_set(key, np.asarray(values, dtype).ravel())
        me.update()
    except Exception:
        bpy.data.meshes.remove(me)
        raise
    return me


def new_glyph_mesh(points: np.ndarray, quaternions: np.ndarray, error: np.ndarray | None = None,
                   error_attribute: str = ERROR_ATTRIBUTE, name: str = "SymFrames Glyph Points"):
    """A new mesh of loose points with the ``frame`` quaternion attribute
    (w, x, y, z) and, if error is given, the error attribute of that name
    (``adaptation`` or ``monodromy``)."""
    attributes = {storage.FRAME_ATTRIBUTE: ("QUATERNION", quaternions)}
    if error is not None:
        if error_attribute not in (ERROR_ATTRIBUTE, MONODROMY_ATTRIBUTE):
            raise ValueError(f"unknown glyph error attribute {error_attribute!r}")
        attributes[error_attribute] = ("FLOAT", error)
    return new_point_mesh(name, points, attributes)


def install_glyph_mesh(scene, me):
    """Make me the glyph object's points (creating the object and its
    Geometry Nodes modifier if needed); returns the glyph object."""
    obj = storage.replace_output(scene, "glyphs", "SymFrames Glyphs", me)
    mod = obj.modifiers.get(MODIFIER)
    if mod is None:
        mod = obj.modifiers.new(MODIFIER, "NODES")
    ng = node_group()
    if mod.node_group != ng:
        mod.node_group = ng
    sync_modifier(scene)
    return obj


def write_glyphs(scene, points: np.ndarray, quaternions: np.ndarray, error: np.ndarray | None = None,
                 error_attribute: str = ERROR_ATTRIBUTE):
    """Replace the scene's glyph points; returns the glyph object."""
    return install_glyph_mesh(scene, new_glyph_mesh(points, quaternions, error, error_attribute))


def error_attribute(obj) -> str | None:
    """The error attribute a glyph object's points carry, or None."""
    if obj.type != "MESH":
        return None
    return next((a for a in (ERROR_ATTRIBUTE, MONODROMY_ATTRIBUTE) if a in obj.data.attributes), None)


def sync_modifier(scene) -> None:
    """Copy the scene's glyph size and error scale into the modifier (live,
    no resampling); colour by error when the points carry an error."""
    obj = storage.output_object(scene, "glyphs")
    if obj is None:
        return
    mod = obj.modifiers.get(MODIFIER)
    if mod is None or mod.node_group is None:
        return
    s = scene.symframes
    attr = error_attribute(obj)
    values = {
        "Size": float(s.glyph_size),
        "Color by Error": attr is not None,
        "Error Scale": float(s.monodromy_scale if attr == MONODROMY_ATTRIBUTE else s.error_scale),
        "Error Attribute": attr or ERROR_ATTRIBUTE,
    }
    for item in mod.node_group.interface.items_tree:
        if getattr(item, "in_out", None) == "INPUT" and item.name in values:
            storage.set_modifier_input(mod, item.identifier, values[item.name])
    obj.update_tag()


def glyph_points(obj) -> tuple[np.ndarray, np.ndarray]:
    """(points (k, 3), quaternions (k, 4)) held by a glyph object."""
    me = obj.data
    n = len(me.vertices)
    P = np.empty(3 * n, np.float32)
    me.attributes["position"].data.foreach_get("vector", P)
    q = np.empty(4 * n, np.float32)
    me.attributes[storage.FRAME_ATTRIBUTE].data.foreach_get("value", q)
    return P.reshape(-1, 3), q.reshape(-1, 4)
