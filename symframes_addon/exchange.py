"""Files in and out: Export Field and Export Hex Mesh (File > Export),
Import Network (File > Import) and the tet mesh as a Blender object (so
Blender's own exporters reach it).

The formats are the solver's (solver.io; docs/usage.md); this module only
moves arrays between them and the scene.  A failed import or export leaves
the scene as it was.
"""

from __future__ import annotations

import os

import bpy
import numpy as np
from bpy.props import EnumProperty, FloatProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from ..solver import SymFramesError
from ..solver.io import HEX_FORMATS, export_field, export_hexmesh, import_tet_network, read_network, read_obj
from . import examples, hex_mesh, storage

FORMATS = (
    ("VTU", "VTU (ParaView)", "VTK XML unstructured grid: vertex and per-tet frames, curve markers, error measures",
     ".vtu"),
    ("MEDIT", "MEDIT + .fra + .perm (CubeCover)", "MEDIT .mesh with per-tet frames (.fra) and face matchings (.perm)",
     ".mesh"),
    ("OVM", "OpenVolumeMesh (.ovm)", "OpenVolumeMesh ASCII with per-vertex and per-cell frame properties", ".ovm"),
    ("QTN", "Quaternions (.qtn, AlgoHex)", "One w x y z line per tet, in the tet order of the other formats", ".qtn"),
)
EXTENSION = {key: ext for key, _, _, ext in FORMATS}
HEX_FILE_FORMATS = tuple((ext[1:].upper(), f"{name} ({ext})", f"The hex mesh as {name} ({ext})", ext)
                         for ext, name in HEX_FORMATS.items())
HEX_EXTENSION = {key: ext for key, _, _, ext in HEX_FILE_FORMATS}
TAG_CONVENTIONS = (
    ("AUTO", "Detect", "Try each convention and keep the one under which the network satisfies Poincare-Hopf "
     "(refused, with each result, when none or several do)"),
    ("INDEX", "Index", "Tag in quarter turns, +1 the valence-3 edge (SymFrames' sign)"),
    ("NEGATED", "Negated Index", "Tag in quarter turns counted the other way: -1 the valence-3 edge"),
    ("VALENCE", "Valence", "Tag = hexahedra around the edge: 3 -> +1/4, 5 -> -1/4 (0 and 4: untagged)"),
)
TAG_SIGN = {"AUTO": None, "INDEX": "index", "NEGATED": "negated", "VALENCE": "valence"}
TET_MESH_ROLE = "tet_mesh"


def _field_or_report(op, context):
    me = storage.stored_field(context.scene)
    if me is None:
        op.report({"ERROR"}, "SymFrames: no field computed yet; run Compute Field first")
    return me


class SYMFRAMES_OT_export_field(bpy.types.Operator, ExportHelper):
    """Write the computed field for ParaView or a hex mesher."""

    bl_description = ("Write the computed field for ParaView or a hex mesher (VTU, MEDIT + .fra + .perm, "
                      "OpenVolumeMesh, AlgoHex .qtn)")

    bl_idname = "symframes.export_field"
    bl_label = "Export SymFrames Field"
    bl_options = {"PRESET"}

    filename_ext = ".vtu"
    filter_glob: StringProperty(default="*.vtu;*.mesh;*.ovm;*.qtn", options={"HIDDEN"})
    file_format: EnumProperty(name="Format", items=[f[:3] for f in FORMATS], default="VTU")

    @classmethod
    def poll(cls, context):
        return storage.stored_field(context.scene) is not None

    def check(self, context):
        # keep the file name's extension in step with the chosen format
        ext = EXTENSION[self.file_format]
        stem, old = os.path.splitext(self.filepath)
        if old.lower() != ext:
            self.filepath = (stem if old.lower() in EXTENSION.values() else self.filepath) + ext
            return True
        return False

    def invoke(self, context, event):
        self.filename_ext = EXTENSION[self.file_format]
        return ExportHelper.invoke(self, context, event)

    def execute(self, context):
        me = _field_or_report(self, context)
        if me is None:
            return {"CANCELLED"}
        path = self.filepath
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            self.report({"ERROR"}, f"SymFrames: the folder {folder} does not exist")
            return {"CANCELLED"}
        try:
            written = export_field(storage.solved_field(context.scene), path, self.file_format.lower())
        except (SymFramesError, ValueError, OSError) as e:
            self.report({"ERROR"}, f"SymFrames: export failed: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, "SymFrames: wrote " + ", ".join(os.path.basename(p) for p in written))
        return {"FINISHED"}


def _with_extension(path: str, ext: str, known) -> str:
    """path ending in ext: a known extension replaced, any other kept and ext added."""
    stem, old = os.path.splitext(path)
    if old.lower() == ext:
        return path
    return (stem if old.lower() in known else path) + ext


class SYMFRAMES_OT_export_hex_mesh(bpy.types.Operator, ExportHelper):
    """Write the hex mesh for ParaView, a finite-element code or HexEx."""

    bl_description = ("Write the last hex mesh: VTU or legacy VTK (with the scaled Jacobian per cell), MEDIT .mesh, "
                      "Gmsh .msh or Abaqus/CalculiX .inp (with the boundary patches as groups), "
                      "or the integer-grid map it came from (.hexex, for HexEx and libHexHex)")

    bl_idname = "symframes.export_hex_mesh"
    bl_label = "Export SymFrames Hex Mesh"
    bl_options = {"PRESET"}

    filename_ext = ".vtu"
    filter_glob: StringProperty(default=";".join(f"*{ext}" for ext in HEX_FORMATS), options={"HIDDEN"})
    file_format: EnumProperty(name="Format", items=[f[:3] for f in HEX_FILE_FORMATS], default="VTU")

    @classmethod
    def poll(cls, context):
        if context.scene is None or hex_mesh.hex_object(context.scene) is None:
            cls.poll_message_set("no hex mesh yet: press Hex Mesh first")
            return False
        return True

    def check(self, context):
        # keep the file name's extension in step with the chosen format
        path = _with_extension(self.filepath, HEX_EXTENSION[self.file_format], HEX_FORMATS)
        changed = path != self.filepath
        self.filepath = path
        return changed

    def invoke(self, context, event):
        self.filename_ext = HEX_EXTENSION[self.file_format]
        return ExportHelper.invoke(self, context, event)

    def execute(self, context):
        path = _with_extension(self.filepath, HEX_EXTENSION[self.file_format], HEX_FORMATS)
        folder = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(folder):
            self.report({"ERROR"}, f"SymFrames: the folder {folder} does not exist")
            return {"CANCELLED"}
        try:
            hm, made_here = hex_mesh.hex_mesh_to_export(context.scene)
            if self.file_format == "HEXEX" and not made_here:
                # the map is not kept in the .blend: only a hex mesh made in this session has it
                raise ValueError("this hex mesh was read back from the .blend, which does not keep the integer-grid "
                                 "map; make the hex mesh again to write its integer-grid map")
            M = np.array(hex_mesh.hex_object(context.scene).matrix_world, float)
            moved = not np.allclose(M, np.eye(4), rtol=0.0, atol=1e-9)
            if moved:  # the object was moved, turned, scaled or mirrored since it was made: write it where it is
                if self.file_format == "HEXEX" and np.linalg.det(M[:3, :3]) < 0:
                    raise ValueError("the hex object is mirrored (a negative scale), and an integer-grid map "
                                     "cannot be mirrored; undo the mirror, or export another format")
                hm = hm.transformed(M)
            written = export_hexmesh(hm, path)
        except (SymFramesError, ValueError, OSError) as e:
            self.report({"ERROR"}, f"SymFrames: export failed: {e}")
            return {"CANCELLED"}
        self.report({"INFO"}, "SymFrames: wrote " + ", ".join(os.path.basename(p) for p in written)
                    + (" with the hex object's transform applied (it was moved, turned or scaled since it was "
                       "made)" if moved else ""))
        return {"FINISHED"}


class SYMFRAMES_OT_tet_mesh_object(bpy.types.Operator):
    """The computed field's tet mesh as a mesh object."""

    bl_description = ("Add the computed field's tet mesh as a mesh object (its triangles, the frames as a quaternion "
                      "attribute, the curve marker per face), so Blender's exporters reach it")

    bl_idname = "symframes.tet_mesh_object"
    bl_label = "Tet Mesh as Object"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return storage.stored_field(context.scene) is not None

    def execute(self, context):
        me_field = _field_or_report(self, context)
        if me_field is None:
            return {"CANCELLED"}
        try:
            fd = storage.solved_field(context.scene)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, f"SymFrames: {e}")
            return {"CANCELLED"}
        mesh = fd.mesh
        me = bpy.data.meshes.new("SymFrames Tet Mesh")
        try:
            me.from_pydata(mesh.vertices.tolist(), [], mesh.faces.tolist())
            q = fd.quaternions()
            me.attributes.new(storage.FRAME_ATTRIBUTE, "QUATERNION", "POINT")
            me.attributes[storage.FRAME_ATTRIBUTE].data.foreach_set("value", q.astype(np.float32).ravel())
            # a face of the tet mesh is on a curve's tube when a crossed tet holds it
            ft = mesh.face_tets
            on_curve = np.where(ft >= 0, fd.curve[np.maximum(ft, 0)], -1).max(axis=1)
            me.attributes.new("curve", "INT", "FACE")
            me.attributes["curve"].data.foreach_set("value", on_curve.astype(np.int32))
            me.update()
            obj = bpy.data.objects.new("SymFrames Tet Mesh", me)
        except Exception:
            bpy.data.meshes.remove(me)
            raise
        obj[storage.ROLE_KEY] = TET_MESH_ROLE
        obj.display_type = "WIRE"
        context.scene.collection.objects.link(obj)
        self.report({"INFO"}, f"SymFrames: tet mesh with {mesh.n_tets:,} tets, {mesh.n_faces:,} triangles")
        return {"FINISHED"}


class SYMFRAMES_OT_import_network(bpy.types.Operator, ImportHelper):
    """A domain and its network from a file."""

    bl_description = ("Add a domain and its network from a file: SymFrames JSON (+ OBJ), or a tet mesh whose edges "
                      "carry a singularity tag (OpenVolumeMesh .ovm, MEDIT .mesh)")

    bl_idname = "symframes.import_network"
    bl_label = "Import SymFrames Network"
    bl_options = {"REGISTER", "UNDO"}

    filter_glob: StringProperty(default="*.json;*.ovm;*.mesh", options={"HIDDEN"})
    tag_convention: EnumProperty(name="Tags", items=TAG_CONVENTIONS, default="AUTO",
                                 description="What an edge's integer tag means (tet-mesh files); Detect tries "
                                             "each and checks Poincare-Hopf before the import succeeds")
    tag_property: StringProperty(name="Edge Property", default="",
                                 description="OpenVolumeMesh: the edge property holding the tags (empty: the only "
                                             "integer edge property)")
    sharp_angle: FloatProperty(name="Sharp Angle", default=0.5235987755982988, min=0.0, max=3.141592653589793,
                               subtype="ANGLE", description="Tet-mesh files: boundary edges turning by more than "
                               "this are sharp too (0: only the tagged boundary edges)")

    def execute(self, context):
        path = self.filepath
        name = os.path.splitext(os.path.basename(path))[0] or "Imported"
        how = ""
        try:
            if path.lower().endswith(".json"):
                net, _opts, surface = read_network(path)
                if surface is None:
                    raise SymFramesError(f"{path}: the network file names no surface ('surface' key with an OBJ)")
                if not os.path.isabs(surface):
                    surface = os.path.join(os.path.dirname(path), surface)
                V, F = read_obj(surface)
            else:
                angle = np.degrees(self.sharp_angle) if self.sharp_angle > 0 else None
                # the same check as the command line: the network must satisfy Poincare-Hopf under the
                # convention (detected or given) before the import reports success
                imp = import_tet_network(path, TAG_SIGN[self.tag_convention], self.tag_property or None, angle)
                V, F, net, how = imp.V, imp.F, imp.network, f"; {imp.describe()}"
        except (SymFramesError, ValueError, OSError) as e:
            self.report({"ERROR"}, f"SymFrames: cannot import {os.path.basename(path)}: {e}")
            return {"CANCELLED"}
        examples.add_domain_and_network(context.scene, name, V, F, net)
        self.report({"INFO"}, f"SymFrames: imported '{name}' with {len(net.curves)} curve(s); set the resolution "
                              f"and Compute Field{how}")
        return {"FINISHED"}


CLASSES = (SYMFRAMES_OT_export_field, SYMFRAMES_OT_export_hex_mesh, SYMFRAMES_OT_tet_mesh_object,
           SYMFRAMES_OT_import_network)

