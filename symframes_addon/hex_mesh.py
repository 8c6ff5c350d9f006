"""The hex mesh of a field as Blender objects, and back.

Blender has no volume cells, so the hex mesh object is a *cell soup*: every
hexahedron has its own 8 vertices, in VTK_HEXAHEDRON order, and its own 6
quad faces, oriented outward, so that each cell is an island the view
modifier can shrink or hide on its own.  A face shared by two cells is there
twice, back to back, hidden inside; seen from outside, the cells show the
boundary quads as a closed surface.  Its mesh holds:

* ``vertex``          INT point: the hex-mesh vertex each corner is a copy of
                      (the conforming mesh is rebuilt from it for export)
* ``cell``            INT face: the hexahedron of the face
* ``scaled_jacobian`` FLOAT face: the cell's scaled Jacobian (Verdict's,
                      the minimum over its corners)
* ``cell_center``     FLOAT_VECTOR face: the mean of the cell's corners
* ``sj_color``        FLOAT_COLOR face corner: red at SJ_RED and below,
                      yellow, green at 1 -- what the Solid view shows with
                      Color: Attribute (Blender keeps color attributes on
                      points or corners, not faces) and the materials render
* material index      the step of that ramp: one of SJ_STEPS materials whose
                      viewport display color is the step's, so the Solid view
                      as it opens (Color: Material) shows quality too
* ``["symframes_hex_report"]`` JSON: the solver's HexReport.to_dict()
                      (read back by HexReport.from_dict)
* ``["symframes_hex_id"]``: the id under which job.py keeps the HexMesh in
                      memory (exports write that one while it is kept: full
                      precision, with its integer-grid map)

The object's Geometry Nodes modifier *SymFrames Hex View* has two live
inputs besides the axis: **Explode** (0-0.9) scales each cell by 1 - Explode
about its centre (Scale Elements, per island); **Fall Away** (0-1) hides the
cells whose centre lies beyond a plane that sweeps along **Axis** from the
far end (Delete Geometry; the plane's position comes from the range of
cell_center . Axis over the faces, Attribute Statistic): 0 hides none, 1 all.
The scene's Explode, Fall Away and Axis settings drive them (sync_modifier).

The irregular edges are a curve object: one bevelled poly spline per
irregular interior edge of the hex mesh, coloured by valence through its
material (VALENCE_MATERIALS: 3, 5, any other); legacy curves carry no
attributes, so the valences are also kept per spline as
``["symframes_valence"]``.
"""

from __future__ import annotations

import json
from dataclasses import replace

import bpy
import numpy as np

from ..solver import BoundaryPatches, HexMesh, HexReport
from . import glyphs, job, storage

ROLE = "hex_mesh"
OBJECT_NAME = "SymFrames Hex Mesh"
EDGES_ROLE = "irregular_edges"
EDGES_NAME = "SymFrames Irregular Edges"
VERTEX_ATTRIBUTE = "vertex"
CELL_ATTRIBUTE = "cell"
SJ_ATTRIBUTE = "scaled_jacobian"
CENTER_ATTRIBUTE = "cell_center"
COLOR_ATTRIBUTE = "sj_color"
PATCH_ATTRIBUTE = "patch"  # FACE INT: the boundary patch of a cell's face, 0 inside
PATCH_NAMES_KEY = "symframes_patch_names"  # the patches' names, in id order; the exports write them
REPORT_KEY = "symframes_hex_report"
HEX_ID_KEY = "symframes_hex_id"
VALENCE_KEY = "symframes_valence"

# VTK_HEXAHEDRON's faces, each counter-clockwise seen from outside the cell
# (corners 0-3 the bottom, counter-clockwise seen from above, 4-7 the top)
HEX_FACES = np.array([(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)])

SJ_RED = 0.3  # the floor before smoothing; at and below it a cell is red
SJ_RAMP = np.array([(0.85, 0.08, 0.05), (0.95, 0.85, 0.15), (0.10, 0.70, 0.20)])  # at SJ_RED, halfway, 1
SJ_STEPS = 8
SJ_MATERIAL = "SymFrames Hex Quality"  # + " 1" .. " SJ_STEPS"
VALENCE_MATERIALS = (("SymFrames Valence 3", (0.85, 0.10, 0.75)),
                     ("SymFrames Valence 5", (0.10, 0.45, 0.95)),
                     ("SymFrames Valence Other", (0.08, 0.08, 0.08)))
VALENCE_INDEX = {3: 0, 5: 1}  # material index of a valence; any other: 2
EDGE_RADIUS = 0.06  # bevel radius of the irregular edges, in cells

NODE_GROUP = "SymFrames Hex View"
NODE_GROUP_VERSION = 2  # 2: Show Below
MODIFIER = "SymFrames Hex View"
# modifier inputs: name -> (socket type, default, min, max)
INPUTS = {
    "Explode": ("NodeSocketFloat", 0.0, 0.0, 0.9),
    "Fall Away": ("NodeSocketFloat", 0.0, 0.0, 1.0),
    "Axis": ("NodeSocketVector", (0.0, 0.0, 1.0), None, None),
    "Show Below": ("NodeSocketFloat", 1.0, 0.0, 1.0),
}
LOW_KEY = "symframes_sj_low"  # the red end of this mesh's colour ramp
HISTOGRAM_KEY = "symframes_sj_histogram"  # cells per bin of HISTOGRAM_EDGES
HISTOGRAM_EDGES = np.r_[-np.inf, np.linspace(0.0, 1.0, 11)]
"""Bins of the panel's histogram: below 0 (inverted), then tenths of 0-1."""
AXIS_VECTORS = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0),
                "NEG_X": (-1.0, 0.0, 0.0), "NEG_Y": (0.0, -1.0, 0.0), "NEG_Z": (0.0, 0.0, -1.0)}


# ------------------------------------------------------------------ colors
def ramp_low(sj: np.ndarray) -> float:
    """The red end of a mesh's colour ramp: its least scaled Jacobian (so
    that a good mesh shows its spread instead of a uniform green), at most
    0.95; SJ_RED for no cells."""
    sj = np.asarray(sj, float)
    return float(min(sj.min(), 0.95)) if len(sj) else SJ_RED


def histogram(sj: np.ndarray) -> list:
    """Cells per bin of HISTOGRAM_EDGES (the last bin holds 1.0)."""
    sj = np.asarray(sj, float)
    k = np.clip(np.searchsorted(HISTOGRAM_EDGES, sj, side="right") - 1, 0, len(HISTOGRAM_EDGES) - 2)
    return np.bincount(k, minlength=len(HISTOGRAM_EDGES) - 1).tolist()


def quality_factor(sj: np.ndarray, low: float = SJ_RED) -> np.ndarray:
    """(m,) where each scaled Jacobian lies on the ramp: 0 at low and below, 1 at 1."""
    return np.clip((np.asarray(sj, float) - low) / (1.0 - low), 0.0, 1.0)


def _ramp(t: np.ndarray) -> np.ndarray:
    x = np.linspace(0.0, 1.0, len(SJ_RAMP))
    return np.stack([np.interp(t, x, SJ_RAMP[:, c]) for c in range(3)], axis=1)


def sj_colors(sj: np.ndarray, low: float = SJ_RED) -> np.ndarray:
    """(m, 4) RGBA of each scaled Jacobian: red (<= low), yellow, green (1)."""
    rgb = _ramp(quality_factor(sj, low))
    return np.c_[rgb, np.ones(len(rgb))]


def sj_steps(sj: np.ndarray, low: float = SJ_RED) -> np.ndarray:
    """(m,) material index: the step of the ramp each scaled Jacobian falls in."""
    return np.minimum((quality_factor(sj, low) * SJ_STEPS).astype(np.int32), SJ_STEPS - 1)


def quality_materials():
    """One material per step of the ramp: viewport display color the step's
    (the Solid view's default), shading from the ``sj_color`` attribute."""
    mats = []
    for k, colour in enumerate(_ramp((np.arange(SJ_STEPS) + 0.5) / SJ_STEPS)):
        name = f"{SJ_MATERIAL} {k + 1}"
        mat = bpy.data.materials.get(name)
        if mat is None:
            mat = bpy.data.materials.new(name)
            bsdf = glyphs._principled(mat, tuple(colour))
            if bsdf is not None:
                col = mat.node_tree.nodes.new("ShaderNodeVertexColor")
                col.layer_name = COLOR_ATTRIBUTE
                col.location = (-400, 200)
                mat.node_tree.links.new(col.outputs["Color"], bsdf.inputs["Base Color"])
        mats.append(mat)
    return mats


def valence_materials():
    mats = []
    for name, colour in VALENCE_MATERIALS:
        mat = bpy.data.materials.get(name)
        if mat is None:
            mat = bpy.data.materials.new(name)
            glyphs._principled(mat, colour)
        mats.append(mat)
    return mats


# ---------------------------------------------------------------- the mesh
def _set(me, name: str, kind: str, domain: str, values) -> None:
    key, dtype = ("vector", np.float32) if kind == "FLOAT_VECTOR" else \
        ("value", np.int32 if kind == "INT" else np.float32)
    me.attributes.new(name, kind, domain)
    # fetch by name: a reference taken before another attributes.new() goes stale
    me.attributes[name].data.foreach_set(key, np.asarray(values, dtype).ravel())


def new_hex_mesh_data(hm: HexMesh, hex_id: str, name: str = OBJECT_NAME):
    """A new (unlinked) mesh datablock: the cell soup of hm with the
    attributes of the module docstring; nothing is left if a step fails."""
    H = np.asarray(hm.hexes, np.int64)
    V = np.asarray(hm.vertices, float)
    m = len(H)
    sj = np.asarray(hm.scaled_jacobian, float)
    me = bpy.data.meshes.new(name)
    try:
        me.vertices.add(8 * m)
        if m:  # an empty mesh has no position attribute
            me.attributes["position"].data.foreach_set("vector", V[H].astype(np.float32).ravel())
        me.loops.add(24 * m)
        me.polygons.add(6 * m)
        me.polygons.foreach_set("loop_start", np.arange(0, 24 * m, 4, dtype=np.int32))
        corners = HEX_FACES[None] + 8 * np.arange(m)[:, None, None]
        me.loops.foreach_set("vertex_index", corners.astype(np.int32).ravel())
        me.update(calc_edges=True)
        _set(me, VERTEX_ATTRIBUTE, "INT", "POINT", H.ravel())
        cell = np.repeat(np.arange(m), 6)
        _set(me, CELL_ATTRIBUTE, "INT", "FACE", cell)
        _set(me, SJ_ATTRIBUTE, "FLOAT", "FACE", sj[cell])
        _set(me, CENTER_ATTRIBUTE, "FLOAT_VECTOR", "FACE", V[H].mean(axis=1)[cell])
        if hm.patches is not None:  # the boundary faces' patch ids (0: inside), and the patches' names
            patch = np.zeros(6 * m, np.int64)
            patch[6 * hm.patches.cells + hm.patches.faces] = hm.patches.patch
            _set(me, PATCH_ATTRIBUTE, "INT", "FACE", patch)
            me[PATCH_NAMES_KEY] = list(hm.patches.names)
        for mat in quality_materials():
            me.materials.append(mat)
        low = ramp_low(sj)
        me.polygons.foreach_set("material_index", sj_steps(sj, low)[cell])
        me.color_attributes.new(COLOR_ATTRIBUTE, "FLOAT_COLOR", "CORNER")
        me.color_attributes.active_color = me.color_attributes[COLOR_ATTRIBUTE]
        me.color_attributes.render_color_index = me.color_attributes.active_color_index
        me.color_attributes[COLOR_ATTRIBUTE].data.foreach_set(
            "color", np.repeat(sj_colors(sj, low), 24, axis=0).astype(np.float32).ravel())
        me[LOW_KEY] = low
        me[HISTOGRAM_KEY] = histogram(sj)
        me[REPORT_KEY] = json.dumps(hm.report.to_dict())
        me[HEX_ID_KEY] = hex_id
    except Exception:
        bpy.data.meshes.remove(me)
        raise
    return me


def new_edges_curve(hm: HexMesh, radius: float, name: str = EDGES_NAME):
    """A new curve datablock, one poly spline per irregular edge of hm, the
    material of its valence; None if hm has no irregular edge."""
    E = np.asarray(hm.irregular_edges, np.int64).reshape(-1, 2)
    val = np.asarray(hm.irregular_valence, np.int64)
    if not len(E):
        return None
    V = np.asarray(hm.vertices, float)
    cu = bpy.data.curves.new(name, "CURVE")
    try:
        cu.dimensions = "3D"
        cu.bevel_depth = radius
        cu.bevel_resolution = 2
        cu.use_fill_caps = True
        for mat in valence_materials():
            cu.materials.append(mat)
        co = np.ones((len(E), 2, 4), np.float32)
        co[:, :, :3] = V[E]
        for c, v in zip(co, val.tolist()):
            sp = cu.splines.new("POLY")
            sp.points.add(1)
            sp.points.foreach_set("co", c.ravel())
            sp.material_index = VALENCE_INDEX.get(v, len(VALENCE_MATERIALS) - 1)
        cu[VALENCE_KEY] = val.tolist()
    except Exception:
        bpy.data.curves.remove(cu)
        raise
    return cu


def write_hex_mesh(scene, hm: HexMesh, hex_id: str):
    """Replace the scene's hex mesh and irregular edges with hm's, all or
    nothing: both datablocks are built before either output is replaced.
    Returns the hex mesh object."""
    me = new_hex_mesh_data(hm, hex_id)
    cu = None
    try:
        cu = new_edges_curve(hm, EDGE_RADIUS * float(hm.report.cell_size or 1.0))
        ng = node_group()
    except Exception:
        bpy.data.meshes.remove(me)
        if cu is not None:
            bpy.data.curves.remove(cu)
        raise
    first = hex_object(scene) is None
    obj = storage.replace_output(scene, ROLE, OBJECT_NAME, me)
    if first:  # the cells' outlines (neighbours of equal quality share a color); the user may turn it off
        obj.show_wire = True
    mod = obj.modifiers.get(MODIFIER)
    if mod is None:
        mod = obj.modifiers.new(MODIFIER, "NODES")
    if mod.node_group != ng:
        mod.node_group = ng
    if cu is not None:
        storage.replace_output(scene, EDGES_ROLE, EDGES_NAME, cu)
    else:
        storage.remove_output(scene, EDGES_ROLE)
    sync_modifier(scene)
    return obj


def hex_object(scene):
    """The scene's hex mesh object, or None."""
    obj = storage.output_object(scene, ROLE)
    return obj if obj is not None and obj.type == "MESH" else None


def stored_report(scene) -> HexReport | None:
    """The HexReport of the scene's hex mesh, or None."""
    obj = hex_object(scene)
    return None if obj is None else _read_report(obj.data)


def _read_report(me) -> HexReport | None:
    if REPORT_KEY not in me:
        return None
    try:
        return HexReport.from_dict(json.loads(me[REPORT_KEY]))
    except (TypeError, ValueError, KeyError, AttributeError):
        return None


def read_hex_mesh(obj) -> HexMesh:
    """The conforming hex mesh of a hex mesh object (its ``vertex`` ids),
    in the single precision Blender keeps, with its stored report (an empty
    one if it has none); no integer-grid map."""
    me = obj.data
    n, k = len(me.vertices), len(me.polygons)
    attr = me.attributes.get(VERTEX_ATTRIBUTE)
    sj_attr = me.attributes.get(SJ_ATTRIBUTE)
    if attr is None or attr.domain != "POINT" or sj_attr is None or n % 8 or k != 6 * (n // 8):
        raise ValueError(f"'{obj.name}' is not a SymFrames hex mesh as written (8 corners and 6 faces per cell); "
                         "make the hex mesh again")
    ids = np.empty(n, np.int32)
    attr.data.foreach_get("value", ids)
    P = np.empty(3 * n, np.float32)
    me.attributes["position"].data.foreach_get("vector", P)
    nv = int(ids.max()) + 1 if n else 0
    if n and not np.array_equal(np.unique(ids), np.arange(nv)):
        raise ValueError(f"'{obj.name}' has lost some of its cells; make the hex mesh again")
    V = np.zeros((nv, 3))
    V[ids] = P.reshape(-1, 3)
    sj = np.empty(k, np.float32)
    sj_attr.data.foreach_get("value", sj)
    H = ids.reshape(-1, 8).astype(np.int64)
    return HexMesh(V, H, sj[::6].astype(float), _read_report(me) or HexReport(), patches=read_patches(me, H))


def read_patches(me, H: np.ndarray) -> BoundaryPatches | None:
    """The boundary patches a hex mesh datablock keeps (its ``patch`` face
    attribute and the names in PATCH_NAMES_KEY, which the user may edit), or
    None where it keeps none."""
    attr = me.attributes.get(PATCH_ATTRIBUTE)
    if attr is None or attr.domain != "FACE" or len(attr.data) != 6 * len(H):
        return None
    patch = np.empty(len(attr.data), np.int32)
    attr.data.foreach_get("value", patch)
    names = [str(n) for n in me.get(PATCH_NAMES_KEY, [])]
    if not len(patch) or patch.min() < 0 or patch.max() > len(names):
        return None
    f = np.nonzero(patch > 0)[0]
    cells, faces = f // 6, f % 6
    return BoundaryPatches(H[cells[:, None], HEX_FACES[faces]], cells, faces, patch[f].astype(np.int64), names)


def _named_patches(hm: HexMesh, me) -> HexMesh:
    """hm with its patches' names as the datablock has them now (the user
    may have renamed them in its custom properties)."""
    names = me.get(PATCH_NAMES_KEY)
    if hm.patches is None or names is None or len(names) != len(hm.patches.names):
        return hm
    return replace(hm, patches=replace(hm.patches, names=[str(n) for n in names]))


def hex_mesh_to_export(scene) -> tuple[HexMesh, bool]:
    """(the scene's hex mesh, whether it is the one solver.hexmesh made):
    the HexMesh kept in memory while the object is the one written from it,
    else the mesh rebuilt from the object (single precision, no integer-grid
    map); ValueError if there is none."""
    obj = hex_object(scene)
    if obj is None:
        raise ValueError("no hex mesh yet: press Hex Mesh first")
    hm = job.cached_hex(obj.data.get(HEX_ID_KEY))
    if hm is not None:
        return _named_patches(hm, obj.data), True
    return read_hex_mesh(obj), False


# -------------------------------------------------------------- node group
def node_group():
    """The view node group, built once per file (rebuilt if outdated)."""
    ng = glyphs.current_node_group(NODE_GROUP, NODE_GROUP_VERSION)
    if ng is not None:
        return ng
    old = bpy.data.node_groups.get(NODE_GROUP)
    if old is not None:
        old.name = NODE_GROUP + " (old)"
    ng = bpy.data.node_groups.new(NODE_GROUP, "GeometryNodeTree")
    ng["symframes_version"] = NODE_GROUP_VERSION
    iface = ng.interface
    iface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    for name, (kind, default, low, high) in INPUTS.items():
        sock = iface.new_socket(name, in_out="INPUT", socket_type=kind)
        sock.default_value = default
        if low is not None:
            sock.min_value, sock.max_value = low, high
            sock.subtype = "FACTOR"  # a slider
    iface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")

    nodes, links = ng.nodes, ng.links

    def node(kind, x, y, **props):
        n = nodes.new(kind)
        n.location = (x, y)
        for key, value in props.items():
            setattr(n, key, value)
        return n

    def math(op, a, b, x, y):
        n = node("ShaderNodeMath", x, y, operation=op)
        for sock, v in zip(n.inputs, (a, b)):
            if isinstance(v, (int, float)):
                sock.default_value = v
            else:
                links.new(v, sock)
        return n.outputs["Value"]

    gin = node("NodeGroupInput", -1000, 0)
    gout = node("NodeGroupOutput", 900, 0)
    centre = node("GeometryNodeInputNamedAttribute", -800, -300, data_type="FLOAT_VECTOR")
    centre.inputs["Name"].default_value = CENTER_ATTRIBUTE
    # how far along the axis each cell's centre lies, and the range of it over the cells
    along = node("ShaderNodeVectorMath", -600, -300, operation="DOT_PRODUCT")
    links.new(centre.outputs["Attribute"], along.inputs[0])
    links.new(gin.outputs["Axis"], along.inputs[1])
    stats = node("GeometryNodeAttributeStatistic", -400, -100, domain="FACE", data_type="FLOAT")
    links.new(gin.outputs["Geometry"], stats.inputs["Geometry"])
    links.new(along.outputs["Value"], stats.inputs["Attribute"])
    # hidden: (d - min) >= (1 - Fall Away) * range, once Fall Away > 0 (so that
    # 0 hides nothing and 1 everything)
    beyond = node("FunctionNodeCompare", -100, -300, data_type="FLOAT", operation="GREATER_EQUAL")
    links.new(math("SUBTRACT", along.outputs["Value"], stats.outputs["Min"], -250, -350), beyond.inputs["A"])
    kept = math("SUBTRACT", 1.0, gin.outputs["Fall Away"], -400, -500)
    links.new(math("MULTIPLY", kept, stats.outputs["Range"], -250, -500), beyond.inputs["B"])
    on = node("FunctionNodeCompare", -100, -550, data_type="FLOAT", operation="GREATER_THAN")
    links.new(gin.outputs["Fall Away"], on.inputs["A"])
    on.inputs["B"].default_value = 0.0
    hide = node("FunctionNodeBooleanMath", 100, -350, operation="AND")
    links.new(beyond.outputs["Result"], hide.inputs[0])
    links.new(on.outputs["Result"], hide.inputs[1])
    # Show Below: only the cells whose scaled Jacobian is at most this (1: all)
    sj = node("GeometryNodeInputNamedAttribute", -400, -700, data_type="FLOAT")
    sj.inputs["Name"].default_value = SJ_ATTRIBUTE
    above = node("FunctionNodeCompare", -100, -750, data_type="FLOAT", operation="GREATER_THAN")
    links.new(sj.outputs["Attribute"], above.inputs["A"])
    links.new(gin.outputs["Show Below"], above.inputs["B"])
    either = node("FunctionNodeBooleanMath", 200, -500, operation="OR")
    links.new(hide.outputs["Boolean"], either.inputs[0])
    links.new(above.outputs["Result"], either.inputs[1])
    delete = node("GeometryNodeDeleteGeometry", 300, 0, domain="FACE", mode="ALL")
    links.new(gin.outputs["Geometry"], delete.inputs["Geometry"])
    links.new(either.outputs["Boolean"], delete.inputs["Selection"])
    # each cell (an island of 6 faces) shrunk about its centre
    scale = node("GeometryNodeScaleElements", 600, 0, domain="FACE")
    if hasattr(scale, "scale_mode"):  # a property up to Blender 4.x, a menu input (default Uniform) from 5.0
        scale.scale_mode = "UNIFORM"
    links.new(delete.outputs["Geometry"], scale.inputs["Geometry"])
    links.new(math("SUBTRACT", 1.0, gin.outputs["Explode"], 400, -200), scale.inputs["Scale"])
    links.new(centre.outputs["Attribute"], scale.inputs["Center"])
    links.new(scale.outputs["Geometry"], gout.inputs["Geometry"])
    return ng


def sync_modifier(scene) -> None:
    """Copy the scene's Explode, Fall Away and Axis into the view modifier (live)."""
    obj = hex_object(scene)
    if obj is None:
        return
    mod = obj.modifiers.get(MODIFIER)
    if mod is None or mod.node_group is None:
        return
    s = scene.symframes
    values = {"Explode": float(s.hex_explode), "Fall Away": float(s.hex_fall_away),
              "Axis": AXIS_VECTORS[s.hex_axis], "Show Below": float(s.hex_show_below)}
    for item in mod.node_group.interface.items_tree:
        if getattr(item, "in_out", None) == "INPUT" and item.name in values:
            storage.set_modifier_input(mod, item.identifier, values[item.name])
    obj.update_tag()
    edges = storage.output_object(scene, EDGES_ROLE)
    if edges is not None and edges.type == "CURVE":
        fall_away_edges(obj, edges.data, float(s.hex_fall_away), AXIS_VECTORS[s.hex_axis])
        edges.update_tag()


HIDDEN_KEY = "symframes_hidden_for_hex"  # on the scene: the objects Hex Only hid, to show them again


def field_objects(scene) -> list:
    """The objects Hex Only hides: the domain, the network's curves and every
    SymFrames output but the hex mesh and its irregular edges."""
    s = scene.symframes
    objs = [s.domain] if s.domain is not None else []
    if s.network is not None:
        objs += list(s.network.all_objects)
    for role in storage.OUTPUT_ROLES:
        if role not in (ROLE, EDGES_ROLE):
            obj = storage.output_object(scene, role)
            if obj is not None:
                objs.append(obj)
    return [o for o in objs if o.name in scene.objects]


def show_hex_only(scene, on: bool) -> int:
    """Hide the field's objects (field_objects) that are visible, and
    remember them; or show again those it hid.  Returns how many changed."""
    if on:
        hidden = [o.name for o in field_objects(scene) if o.visible_get()]
        for name in hidden:
            scene.objects[name].hide_set(True)
        scene[HIDDEN_KEY] = sorted(set(hidden) | set(scene.get(HIDDEN_KEY, [])))
        return len(hidden)
    names = list(scene.get(HIDDEN_KEY, []))
    for name in names:
        obj = scene.objects.get(name)
        if obj is not None:
            obj.hide_set(False)
    if HIDDEN_KEY in scene:
        del scene[HIDDEN_KEY]
    return len(names)


def fall_away_edges(obj, cu, fall: float, axis) -> int:
    """Hide the irregular edges (radius 0) whose midpoint lies beyond the
    Fall Away plane of the cells (the view modifier's rule, from the hex
    object's cell centres), show the others; returns how many are hidden."""
    attr = obj.data.attributes.get(CENTER_ATTRIBUTE)
    if attr is None or not len(cu.splines):
        return 0
    C = np.empty(3 * len(attr.data), np.float32)
    attr.data.foreach_get("vector", C)
    a = np.asarray(axis, float)
    d = C.reshape(-1, 3) @ a
    lo, span = (float(d.min()), float(d.max() - d.min())) if len(d) else (0.0, 0.0)
    hidden = 0
    p = np.empty(8, np.float32)
    for sp in cu.splines:
        sp.points.foreach_get("co", p)
        beyond = fall > 0.0 and float(0.5 * (p[:3] + p[4:7]) @ a) - lo >= (1.0 - fall) * span
        hidden += beyond
        sp.points.foreach_set("radius", [0.0, 0.0] if beyond else [1.0, 1.0])
    return int(hidden)


def remove_unused_helpers() -> None:
    """Drop the node group and the materials once nothing uses them."""
    glyphs.remove_unused(NODE_GROUP, (*(f"{SJ_MATERIAL} {k + 1}" for k in range(SJ_STEPS)),
                                      *(name for name, _ in VALENCE_MATERIALS)))
