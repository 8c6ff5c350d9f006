"""Menu entries, so that every operator is in F3 search (which searches menus).

* Object -> SymFrames: the operators of the panel, in its order.
* Add -> SymFrames Example: one entry per built-in example.
* File -> Import / Export: the entries of IMPORT_ENTRIES and EXPORT_ENTRIES
  (exchange.py's operators), shown once their operator is registered.

register_menus() appends the draw functions to Blender's menus and
unregister_menus() removes them; the menu classes are registered with the
other classes (CLASSES).  Operators keep their poll(), so menu entries grey
out as the panel's buttons do.
"""

import bpy

from ..solver.examples import EXAMPLES

# (operator bl_idname, icon), in menu order, shown under their bl_label; None: a separator
OBJECT_ENTRIES = (
    ("symframes.suggest_network", "CURVE_DATA"),
    ("symframes.check_network", "CHECKMARK"),
    ("symframes.compute", "PLAY"),
    None,
    ("symframes.show_glyphs", "EMPTY_AXIS"),
    ("symframes.trace_streamlines", "FORCE_MAGNETIC"),
    None,
    ("symframes.show_singular_faces", "MOD_TRIANGULATE"),
    ("symframes.show_omega", "ORIENTATION_GIMBAL"),
    ("symframes.show_slice", "MOD_BOOLEAN"),
    None,
    ("symframes.hex_mesh", "MESH_CUBE"),
    None,
    ("symframes.tet_mesh_object", "MESH_ICOSPHERE"),
    ("symframes.clear", "TRASH"),
)
# (operator bl_idname, menu text, icon), named as Blender names its importers and exporters
IMPORT_ENTRIES = [("symframes.import_network", "SymFrames Network (.json, .ovm, .mesh)", "NONE")]
EXPORT_ENTRIES = [("symframes.export_field", "SymFrames Field (.vtu, .mesh, .ovm, .qtn)", "NONE"),
                  ("symframes.export_hex_mesh", "SymFrames Hex Mesh (.vtu, .vtk, .mesh, .hexex)", "NONE")]


def operator_registered(idname: str) -> bool:
    """Whether the operator 'module.name' is registered."""
    module, name = idname.split(".")
    return bpy.types.Operator.bl_rna_get_subclass_py(f"{module.upper()}_OT_{name}") is not None


def draw_entries(layout, entries) -> None:
    """Draw (idname, icon) or (idname, text, icon) entries whose operator is
    registered; None draws a separator."""
    for entry in entries:
        if entry is None:
            layout.separator()
        elif operator_registered(entry[0]):
            if len(entry) == 2:
                layout.operator(entry[0], icon=entry[1])
            else:
                layout.operator(entry[0], text=entry[1], icon=entry[2])


class SYMFRAMES_MT_object(bpy.types.Menu):
    """SymFrames: check the network, compute the field, show results and diagnostics"""

    bl_idname = "SYMFRAMES_MT_object"
    bl_label = "SymFrames"

    def draw(self, context):
        layout = self.layout
        draw_entries(layout, OBJECT_ENTRIES[:2])
        layout.operator_menu_enum("symframes.apply_preset", "preset", icon="PRESET")
        hexing = OBJECT_ENTRIES.index(("symframes.hex_mesh", "MESH_CUBE"))
        draw_entries(layout, OBJECT_ENTRIES[2:hexing + 1])
        layout.operator_menu_enum("symframes.apply_hex_preset", "preset", icon="PRESET")
        layout.operator("symframes.finer_near_selected", icon="RESTRICT_SELECT_OFF")
        draw_entries(layout, OBJECT_ENTRIES[hexing + 1:])


class SYMFRAMES_MT_add_example(bpy.types.Menu):
    """Built-in example solids with their networks and settings"""

    bl_idname = "SYMFRAMES_MT_add_example"
    bl_label = "SymFrames Example"

    def draw(self, context):
        layout = self.layout
        for name in EXAMPLES:
            layout.operator("symframes.add_example", text=name.capitalize()).example = name


def draw_object_menu(self, context):
    self.layout.separator()
    self.layout.menu(SYMFRAMES_MT_object.bl_idname)


def draw_add_menu(self, context):
    self.layout.separator()
    self.layout.menu(SYMFRAMES_MT_add_example.bl_idname, icon="ORIENTATION_GIMBAL")


def draw_import_menu(self, context):
    draw_entries(self.layout, IMPORT_ENTRIES)


def draw_export_menu(self, context):
    draw_entries(self.layout, EXPORT_ENTRIES)


# Blender's menu -> the draw function appended to it
MENU_FUNCTIONS = (
    ("VIEW3D_MT_object", draw_object_menu),
    ("VIEW3D_MT_add", draw_add_menu),
    ("TOPBAR_MT_file_import", draw_import_menu),
    ("TOPBAR_MT_file_export", draw_export_menu),
)

CLASSES = (SYMFRAMES_MT_object, SYMFRAMES_MT_add_example)


def register_menus():
    for menu, func in MENU_FUNCTIONS:
        getattr(bpy.types, menu).append(func)


def unregister_menus():
    for menu, func in reversed(MENU_FUNCTIONS):
        getattr(bpy.types, menu).remove(func)
