"""The solved field kept in the .blend, and the add-on's output objects.

The field is a mesh datablock that no object uses, held by the scene
setting ``symframes.field`` (a pointer counts as a user, so it is saved):

* ``["symframes_field"]`` = the solved field itself, in full precision and
  complete: a group of ID properties holding solver.SolvedField.to_arrays()
  (the tet mesh, frames, omega, the network as the solve traced it, the
  input surface with its sharp edges ...), from which
  solver.SolvedField.from_arrays reads it back, checked.  Every reader
  (frame_field, field_omega, solved_field: glyphs, diagnostics, exports,
  Hex Mesh on a reopened file) takes it from there.  Each array is kept
  flat, float64 (``d``) or int32 (``i``; booleans as 0/1), a string as a
  string property; ``["layout"]`` (JSON) gives each key's kind and shape.
* for looking at the field in Blender (spreadsheet, modifiers), nothing
  reads them back: vertices = tet-mesh vertices, faces = one 4-corner face
  per tetrahedron, edges = the tet-mesh edges; ``frame`` = QUATERNION point
  attribute (w, x, y, z); ``omega`` = FLOAT_VECTOR edge attribute (the
  rotation vector from the frame at the edge's first vertex to the one at
  its second, Eq. 8, E_j = exp(omega_ij) E_i)
* ``adaptation`` = FLOAT point attribute, solver.vertex_normal_adaptation:
  radians at boundary vertices, -1 inside and at sharp feature vertices
  (whose frames are fixed); the glyphs' colour reads it
* ``["symframes_report"]`` = JSON, solver.Report.to_dict() of the solve;
  ``["symframes_remeshed"]`` = whether the solve made its tet mesh (else it
  reused the previous one)
* ``["symframes_inputs_key"]`` = scene_io.Inputs.field_key() of the inputs
  solved (Hex Mesh, in the session that solved it or on a reopened file,
  refuses if the scene's inputs changed since: the field is not theirs);
  ``["symframes_inputs_parts"]`` = scene_io.Inputs.field_parts() (JSON), for
  the refusal to say what changed

Output objects (glyphs, streamlines, the diagnostics, the hex mesh and its
irregular edges: see OUTPUT_ROLES) are found by the custom property
``symframes_role`` on objects of the scene, so that renaming them is
harmless.
"""

from __future__ import annotations

import json

import bpy
import numpy as np

from ..solver import FrameField, Report, SolvedField

FIELD_NAME = "SymFrames Field"
FRAME_ATTRIBUTE = "frame"
ADAPTATION_ATTRIBUTE = "adaptation"
OMEGA_ATTRIBUTE = "omega"
REPORT_KEY = "symframes_report"
REMESHED_KEY = "symframes_remeshed"
INPUTS_KEY = "symframes_inputs_key"
INPUTS_PARTS_KEY = "symframes_inputs_parts"
FIELD_KEY = "symframes_field"
ARRAYS_LAYOUT = "layout"
ROLE_KEY = "symframes_role"
RESULTS_COLLECTION = "SymFrames Results"
OUTPUT_ROLES = ("glyphs", "streamlines", "singular_faces", "omega_arrows", "error_slice", "hex_mesh",
                "irregular_edges")


# ------------------------------------------------------------------- field
def new_field_mesh(field: SolvedField, adaptation: np.ndarray, report: Report, remeshed: bool):
    """A new (unlinked) mesh datablock holding a solved field (module docs).

    field : the solve's SolvedField (Result.field)
    adaptation : (#V,) solver.vertex_normal_adaptation of the solve
    report : the solve's Report;  remeshed : whether the solve made its tet mesh
    """
    mesh = field.mesh
    n, m = mesh.n_vertices, mesh.n_tets
    me = bpy.data.meshes.new(FIELD_NAME)
    try:
        me.vertices.add(n)
        me.attributes["position"].data.foreach_set("vector", np.asarray(mesh.vertices, np.float32).ravel())
        me.loops.add(4 * m)
        me.polygons.add(m)
        me.polygons.foreach_set("loop_start", np.arange(0, 4 * m, 4, dtype=np.int32))
        me.loops.foreach_set("vertex_index", np.asarray(mesh.tets, np.int32).ravel())
        _set_edges(me, n, np.asarray(mesh.tets, np.int64), np.asarray(mesh.edges, np.int64))
        me.attributes.new(OMEGA_ATTRIBUTE, "FLOAT_VECTOR", "EDGE")
        me.attributes[OMEGA_ATTRIBUTE].data.foreach_set("vector", np.asarray(field.omega, np.float32).ravel())
        me.attributes.new(FRAME_ATTRIBUTE, "QUATERNION", "POINT")
        # fetch by name: a reference taken before another attributes.new() goes stale
        me.attributes[FRAME_ATTRIBUTE].data.foreach_set("value",
                                                        np.asarray(field.quaternions(), np.float32).ravel())
        me.attributes.new(ADAPTATION_ATTRIBUTE, "FLOAT", "POINT")
        me.attributes[ADAPTATION_ATTRIBUTE].data.foreach_set("value", np.asarray(adaptation, np.float32))
        me[REPORT_KEY] = json.dumps(report.to_dict())
        me[REMESHED_KEY] = bool(remeshed)
        me[FIELD_KEY] = encode_arrays(field.to_arrays())
    except Exception:
        bpy.data.meshes.remove(me)
        raise
    return me


def _edge_keys(edges: np.ndarray, n: int) -> np.ndarray:
    e = np.sort(np.asarray(edges, np.int64), axis=1)
    return e[:, 0] * n + e[:, 1]


def _set_edges(me, n: int, tets: np.ndarray, edges: np.ndarray) -> None:
    """Give the field mesh exactly the tet-mesh edges, in the given order,
    and point each face corner at the edge to the next corner (the two
    diagonals of a tet's 4-corner face are edges of no face corner)."""
    keys = _edge_keys(edges, n)
    order = np.argsort(keys)
    a = tets.ravel()
    b = np.roll(tets, -1, axis=1).ravel()
    want = _edge_keys(np.c_[a, b], n)
    pos = np.clip(np.searchsorted(keys, want, sorter=order), 0, len(keys) - 1)
    loop_edge = order[pos]
    if not np.array_equal(keys[loop_edge], want):
        raise ValueError("the edges do not contain every edge of the tets")
    me.edges.add(len(edges))
    me.edges.foreach_set("vertices", edges.astype(np.int32).ravel())
    me.loops.foreach_set("edge_index", loop_edge.astype(np.int32))
    me.update()


_INT32 = np.iinfo(np.int32)


def encode_arrays(arrays: dict) -> dict:
    """Arrays as values an ID property group holds (see the module
    docstring): flat float64 or int32 arrays and strings, with their layout."""
    group, layout = {}, {}
    for key, value in arrays.items():
        a = np.asarray(value)
        if a.dtype.kind in "US":
            if a.ndim:
                raise ValueError(f"'{key}': only a single string can be kept")
            group[key], layout[key] = str(a), ["str", []]
        elif a.dtype.kind in "biu":
            if a.size and (a.min() < _INT32.min or a.max() > _INT32.max):
                raise ValueError(f"'{key}': values beyond 32-bit integers cannot be kept")
            kind = "bool" if a.dtype.kind == "b" else "int"
            group[key], layout[key] = a.astype(np.int32).ravel(), [kind, list(a.shape)]
        elif a.dtype.kind == "f":
            group[key], layout[key] = a.astype(np.float64).ravel(), ["float", list(a.shape)]
        else:
            raise ValueError(f"'{key}': cannot keep an array of {a.dtype}")
    group[ARRAYS_LAYOUT] = json.dumps(layout)
    return group


def decode_arrays(group) -> dict:
    """encode_arrays' arrays back from an ID property group (int64 for
    integers); ValueError if the group is not as encode_arrays wrote it."""
    key = ARRAYS_LAYOUT
    try:
        layout = json.loads(group[key])
        out = {}
        for key, (kind, shape) in layout.items():
            value = group[key]
            if kind == "str":
                if not isinstance(value, str):
                    raise TypeError("not a string")
                out[key] = np.array(value)
                continue
            dtype = {"float": np.float64, "int": np.int64, "bool": bool}[kind]
            out[key] = np.asarray(value).astype(dtype).reshape(shape)
        return out
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError(f"this field's stored arrays are not as Compute Field wrote them ('{key}': "
                         f"{type(e).__name__}); compute the field again") from None


def read_adaptation(me) -> np.ndarray | None:
    """(n,) stored normal adaptation errors in radians (-1: not measured), or None."""
    attr = me.attributes.get(ADAPTATION_ATTRIBUTE)
    if attr is None:
        return None
    a = np.empty(len(me.vertices), np.float32)
    attr.data.foreach_get("value", a)
    return a.astype(float)


def stored_field(scene):
    """The scene's field mesh, or None."""
    me = scene.symframes.field
    if me is None or FRAME_ATTRIBUTE not in me.attributes:
        return None
    return me


def stored_report(scene) -> Report | None:
    """The solver's Report of the stored field, or None."""
    me = stored_field(scene)
    if me is None or REPORT_KEY not in me:
        return None
    try:
        return Report.from_dict(json.loads(me[REPORT_KEY]))
    except (TypeError, ValueError, KeyError):
        return None


def stored_remeshed(scene) -> bool | None:
    """Whether the stored field's solve made its tet mesh (False: it reused
    the previous solve's); None if there is no result."""
    me = stored_field(scene)
    return None if me is None else bool(me.get(REMESHED_KEY, True))


_FIELD_CACHE: dict = {}


def solved_field(scene) -> SolvedField | None:
    """The scene's stored field as a solver.SolvedField (read once per field
    datablock and content, then kept), or None if there is no result;
    ValueError if it is stored without its arrays, ReadError if they are
    damaged."""
    me = stored_field(scene)
    if me is None:
        return None
    key = (me.session_uid, me.get(REPORT_KEY, ""), len(me.vertices), len(me.polygons))
    if _FIELD_CACHE.get("key") != key:
        group = me.get(FIELD_KEY)
        if group is None:
            raise ValueError("this field was stored by an earlier SymFrames, without the arrays the field is read "
                             "back from: compute the field again")
        f = SolvedField.from_arrays(decode_arrays(group), "the stored field", "compute the field again")
        _FIELD_CACHE.clear()
        _FIELD_CACHE.update(solved=f, key=key)
    return _FIELD_CACHE["solved"]


def frame_field(scene) -> FrameField | None:
    """solver.FrameField of the stored field (kept with it), or None if
    there is no result."""
    f = solved_field(scene)
    if f is None:
        return None
    if "frames" not in _FIELD_CACHE:
        _FIELD_CACHE["frames"] = FrameField.from_field(f)
    return _FIELD_CACHE["frames"]


def field_omega(scene) -> np.ndarray | None:
    """(#E, 3) the solver's omega on frame_field(scene).mesh.edges, or None
    if there is no result."""
    f = solved_field(scene)
    return None if f is None else f.omega


def network_face_ids(scene) -> np.ndarray:
    """(k,) ids in the stored field's tet mesh of the faces its network
    passes through (empty if there is no result)."""
    f = solved_field(scene)
    return np.zeros(0, np.int64) if f is None else f.embedding.network_faces(f.mesh)


def set_field(scene, me) -> None:
    """Make me the scene's field, removing the previous one."""
    old = scene.symframes.field
    scene.symframes.field = me
    if old is not None and old != me and old.users == 0:
        bpy.data.meshes.remove(old)
        me.name = FIELD_NAME  # the name is free again: no '.001'
    _FIELD_CACHE.clear()


# ----------------------------------------------------------------- outputs
def results_collection(scene):
    """The collection holding the output objects, created and linked on demand."""
    for c in scene.collection.children_recursive:
        if c.get(ROLE_KEY) == "results":
            return c
    c = bpy.data.collections.new(RESULTS_COLLECTION)
    c[ROLE_KEY] = "results"
    scene.collection.children.link(c)
    return c


def output_object(scene, role: str):
    """The scene's output object with the given role (see OUTPUT_ROLES), or None."""
    for obj in scene.objects:
        if obj.get(ROLE_KEY) == role:
            return obj
    return None


def replace_output(scene, role: str, name: str, data):
    """Put data into the output object of this role (creating it in the
    results collection), removing the data it held before."""
    obj = output_object(scene, role)
    if obj is None:
        obj = bpy.data.objects.new(name, data)
        obj[ROLE_KEY] = role
        results_collection(scene).objects.link(obj)
        return obj
    old, old_name = obj.data, obj.data.name
    obj.data = data
    if _remove_data(old):
        data.name = old_name  # the name is free again: no '.001'
    return obj


def remove_output(scene, role: str) -> bool:
    obj = output_object(scene, role)
    if obj is None:
        return False
    data = obj.data
    bpy.data.objects.remove(obj)
    _remove_data(data)
    return True


def _remove_data(data) -> bool:
    """Remove an output's old datablock unless something else uses it."""
    if data is None or data.users > 0:
        return False
    if isinstance(data, bpy.types.Mesh):
        bpy.data.meshes.remove(data)
    elif isinstance(data, bpy.types.Curve):
        bpy.data.curves.remove(data)
    else:
        return False
    return True


def clear_results(scene) -> bool:
    """Remove the stored field and the output objects of the scene.

    Returns whether anything was removed.  The shared helpers of the display
    modules (node groups, materials) are theirs to remove (operators.py).
    """
    removed = False
    for role in OUTPUT_ROLES:
        removed |= remove_output(scene, role)
    me = scene.symframes.field
    if me is not None:
        scene.symframes.field = None
        if me.users == 0:
            bpy.data.meshes.remove(me)
        removed = True
    _FIELD_CACHE.clear()
    for c in list(scene.collection.children):
        if c.get(ROLE_KEY) == "results" and not c.all_objects:
            bpy.data.collections.remove(c)
    return removed



def modifier_input(mod, identifier: str):
    """A Geometry Nodes modifier's input value (see set_modifier_input)."""
    inputs = _modifier_inputs(mod)
    return getattr(inputs, identifier).value if inputs is not None else mod[identifier]


def set_modifier_input(mod, identifier: str, value) -> None:
    """Set a Geometry Nodes modifier's input: an ID property of the modifier
    up to Blender 5.1, the ``value`` of ``mod.properties.inputs.<identifier>``
    from 5.2 on (where ``mod[identifier] = value`` raises TypeError)."""
    inputs = _modifier_inputs(mod)
    if inputs is not None:
        getattr(inputs, identifier).value = value
    else:
        mod[identifier] = value


def _modifier_inputs(mod):
    props = getattr(mod, "properties", None)
    return getattr(props, "inputs", None)
