"""The add-on's user interface with the bpy module, without solving: menus
(what F3 search finds), quality presets, the solve seed, the list of network
curves, labels and spelling, and colors that the Solid view shows.

Menus and panels are drawn with a stand-in layout that records what they
would show; the bpy module has no window to draw into.
"""

from __future__ import annotations

from types import SimpleNamespace

import bpy
import numpy as np
import pytest

from tests import addon_package
from tests.addon_package import load_addon

addon = load_addon()
from symframes.solver import Options  # noqa: E402
from symframes.solver.examples import EXAMPLES  # noqa: E402
from symframes.symframes_addon import (  # noqa: E402
    diagnostics,
    error_slice,
    exchange,
    glyphs,
    hex_mesh,
    menus,
    omega_arrows,
    operators,
    panel,
    properties,
    scene_io,
    storage,
)

registered = addon_package.registered  # fixtures shared by the add-on tests
empty_scene = addon_package.empty_scene

DEFAULT_DIFFUSE = tuple(bpy.types.Material.bl_rna.properties["diffuse_color"].default_array)
BLENDER_MENUS = ("VIEW3D_MT_object", "VIEW3D_MT_add", "TOPBAR_MT_file_import", "TOPBAR_MT_file_export")


def scene():
    return bpy.context.scene


class Layout:
    """Records what a draw function would show: operators (with their
    properties), menus, labels and texts, and the properties drawn."""

    def __init__(self):
        self.operators, self.menus, self.texts, self.props = [], [], [], []

    def _record(self, name, args, kw):
        if "text" in kw:
            self.texts.append(kw["text"])
        if name == "operator":
            self.operators.append(args[0])
            return SimpleNamespace()  # the operator's properties, set by the caller
        if name in ("operator_menu_enum", "operator_enum"):
            self.operators.append(args[0])
        elif name == "menu":
            self.menus.append(args[0])
        elif name == "prop":
            getattr(args[0], args[1])  # the property exists
            self.props.append(args[1])
            if "text" not in kw:
                self.texts.append(args[0].bl_rna.properties[args[1]].name)
        elif name == "template_list":
            getattr(args[2], args[3])
            getattr(args[4], args[5])
        return self

    def __getattr__(self, name):
        return lambda *args, **kw: self._record(name, args, kw)


def draw(func, cls=None) -> Layout:
    layout = Layout()
    func(SimpleNamespace(layout=layout, bl_idname=getattr(cls, "bl_idname", "")), bpy.context)
    return layout


def appended(menu: str) -> list:
    """The draw functions of one of Blender's menus (its own and appended ones)."""
    return list(getattr(bpy.types, menu)._dyn_ui_initialize())


def addon_operators() -> list:
    return [cls.bl_idname for cls in operators.CLASSES + exchange.CLASSES]


# ---------------------------------------------------------------------- menus
def test_menus_are_appended_and_reach_every_operator():
    for menu, func in menus.MENU_FUNCTIONS:
        assert func in appended(menu), menu
    assert draw(menus.draw_object_menu).menus == ["SYMFRAMES_MT_object"]
    assert draw(menus.draw_add_menu).menus == ["SYMFRAMES_MT_add_example"]
    in_object = draw(menus.SYMFRAMES_MT_object.draw).operators
    examples = draw(menus.SYMFRAMES_MT_add_example.draw)
    assert examples.operators == ["symframes.add_example"] * len(EXAMPLES)
    assert examples.texts == [name.capitalize() for name in EXAMPLES]
    for idname in ("symframes.check_network", "symframes.compute", "symframes.show_glyphs",
                   "symframes.trace_streamlines", "symframes.show_singular_faces", "symframes.show_omega",
                   "symframes.show_slice", "symframes.hex_mesh", "symframes.apply_hex_preset", "symframes.clear",
                   "symframes.apply_preset", "symframes.finer_near_selected"):
        assert idname in in_object, idname
    # every operator of the add-on is in a menu, hence in F3 search
    in_file = draw(menus.draw_import_menu).operators + draw(menus.draw_export_menu).operators
    assert set(addon_operators()) <= set(in_object) | set(examples.operators) | set(in_file)


def test_file_menus_draw_the_entries_of_registered_operators(monkeypatch):
    assert draw(menus.draw_import_menu).operators == ["symframes.import_network"]
    assert draw(menus.draw_export_menu).operators == ["symframes.export_field", "symframes.export_hex_mesh"]
    # an entry shows only once its operator is registered
    monkeypatch.setattr(menus, "IMPORT_ENTRIES", [("symframes.no_such_importer", "Nothing (.xyz)", "NONE")])
    monkeypatch.setattr(menus, "EXPORT_ENTRIES", [("symframes.check_network", "Stand-in (.npz)", "NONE")])
    assert draw(menus.draw_import_menu).operators == []  # not registered
    exported = draw(menus.draw_export_menu)
    assert exported.operators == ["symframes.check_network"] and exported.texts == ["Stand-in (.npz)"]


def test_menu_entries_grey_out_with_the_operators_poll():
    # the menus draw the operators themselves, so their poll() decides
    assert not bpy.ops.symframes.show_glyphs.poll()  # no field yet
    assert not bpy.ops.symframes.show_omega.poll()
    assert bpy.ops.symframes.compute.poll() and bpy.ops.symframes.check_network.poll()


def test_unregister_removes_the_menu_entries():
    try:
        addon.unregister()
        for menu, func in menus.MENU_FUNCTIONS:
            assert func not in appended(menu), menu
            assert getattr(bpy.types, menu) is not None  # Blender's own menu stays
        assert not hasattr(bpy.types, "SYMFRAMES_MT_object")
        assert not hasattr(bpy.types, "SYMFRAMES_MT_add_example")
        assert not hasattr(bpy.types, "SYMFRAMES_UL_curves")
    finally:
        addon.register()
    for menu, func in menus.MENU_FUNCTIONS:
        assert appended(menu).count(func) == 1, menu  # once, not once per registration


# ----------------------------------------------------------- presets, seed
def test_presets_set_the_documented_values():
    s = scene().symframes
    documented = {"DRAFT": (4000, 15), "STANDARD": (15000, 50), "FINE": (50000, 60)}  # docs/addon.md
    assert set(properties.PRESETS) == set(documented)
    for preset, (tets, iterations) in documented.items():
        s.auto_resolution, s.target_tets, s.max_iterations = False, 777, 3
        assert bpy.ops.symframes.apply_preset(preset=preset) == {"FINISHED"}
        assert (s.auto_resolution, s.target_tets, s.max_iterations) == (True, tets, iterations)
    # Standard is the defaults, of the panel and of the solver alike
    rna = s.bl_rna.properties
    for key, value in properties.PRESETS["STANDARD"].items():
        assert rna[key].default == value, key
    assert (Options().budget, Options().max_iterations) == (15000, 50)
    # the solver's default follows the network (issue 41b), as the panel's does
    assert rna["follow_network"].default is True and Options().target_tets is None
    assert bpy.ops.symframes.apply_preset(preset="STANDARD") == {"FINISHED"}
    inp = scene_io.solver_options(s)
    assert (inp.grading, inp.ceiling) == (None, 4 * 15000) and Options().ceiling == 4 * 15000
    from symframes.solver.mesh.resolution import GRADING

    assert rna["grading"].default == pytest.approx(GRADING)  # the grading held when Follow Network is off


def test_solve_seed_and_target_tets_reach_the_solver():
    bpy.ops.symframes.add_example(example="cube")
    s = scene().symframes
    s.solve_seed, s.seed = 7, 3
    s.auto_resolution, s.target_tets = True, 4000
    inp = scene_io.read_inputs(bpy.context)
    assert (inp.options.seed, inp.options.target_tets, inp.options.edge_length) == (7, 4000, None)
    # with Auto, the target tet count decides the mesh: another one is not reused
    key = inp.mesh_key()
    s.target_tets = 8000
    assert scene_io.read_inputs(bpy.context).mesh_key() != key
    key = scene_io.read_inputs(bpy.context).mesh_key()
    s.solve_seed = 8  # the seed does not change the mesh
    assert scene_io.read_inputs(bpy.context).options.seed == 8
    assert scene_io.read_inputs(bpy.context).mesh_key() == key
    # nor does anything but the resolution: the grading does (Follow Network off)
    s.follow_network = False
    key = scene_io.read_inputs(bpy.context).mesh_key()
    s.grading = 0.3
    inp = scene_io.read_inputs(bpy.context)
    assert inp.options.grading == pytest.approx(0.3) and inp.mesh_key() != key
    s.grading, s.follow_network = 0.5, True
    # a fixed edge length decides it alone
    s.auto_resolution = False
    key = scene_io.read_inputs(bpy.context).mesh_key()
    s.target_tets = 4000
    assert scene_io.read_inputs(bpy.context).mesh_key() == key


# ------------------------------------------------------------- curve list
def test_curve_list_shows_the_network_curves_and_edits_the_picked_one():
    bpy.ops.symframes.add_example(example="plate")
    s = scene().symframes
    net = s.network
    stray = bpy.data.objects.new("not a curve", None)  # an empty in the collection: not listed
    net.objects.link(stray)
    ul = bpy.types.SYMFRAMES_UL_curves
    assert issubclass(ul, bpy.types.UIList)
    fake = SimpleNamespace(filter_name="", use_filter_invert=False, bitflag_filter_item=1 << 30)
    flags, order = ul.filter_items(fake, bpy.context, net, "all_objects")
    shown = [obj.name for obj, f in zip(net.all_objects, flags) if f]
    assert sorted(shown) == sorted(o.name for o in net.all_objects if o.type == "CURVE") and len(shown) == 4
    # by name, as scene_io numbers the curves in its messages
    listed = [None] * len(order)
    for obj, position in zip(net.all_objects, order):
        listed[position] = obj.name
    curves, _ = scene_io.network_objects(net)
    assert [n for n in listed if n in shown] == [o.name for o in curves]
    fake.filter_name = "hole 1"
    flags, _ = ul.filter_items(fake, bpy.context, net, "all_objects")
    assert [obj.name for obj, f in zip(net.all_objects, flags) if f] == ["hole 1"]
    # a row: name, index in quarter turns, role, torsion
    obj = bpy.data.objects["hole 1"]
    row = Layout()
    ul.draw_item(fake, bpy.context, row, net, obj, 0, s, "curve_index", 0)
    assert row.texts == ["hole 1", f"{obj.symframes.index:+d}", "Singular", "Free"]
    obj.symframes.role = "feature"
    row = Layout()
    ul.draw_item(fake, bpy.context, row, net, obj, 0, s, "curve_index", 0)
    assert row.texts[1:] == ["0", "Feature", "Free"]
    # picking a row makes the curve active; the panel edits its settings
    s.curve_index = list(net.all_objects).index(obj)
    assert bpy.context.view_layer.objects.active == obj and obj.select_get()
    assert panel.active_network_curve(scene()) == obj
    drawn = draw(panel.SYMFRAMES_PT_curve.draw)
    assert "hole 1" in drawn.texts and {"role", "index", "torsion"} <= set(drawn.props)
    s.curve_index = list(net.all_objects).index(stray)
    assert panel.active_network_curve(scene()) is None


# --------------------------------------------------------- labels, spelling
def test_operator_labels_are_unique():
    labels = [cls.bl_label for cls in operators.CLASSES + exchange.CLASSES]
    assert len(set(labels)) == len(labels), labels
    menu_labels = [cls.bl_label for cls in menus.CLASSES]
    assert len(set(menu_labels)) == len(menu_labels)


def _rna_strings(rna) -> list:
    out = []
    for prop in rna.properties:
        out += [prop.name, prop.description]
        if prop.type == "ENUM":
            for item in prop.enum_items:
                out += [item.name, item.description]
    return out


def test_no_user_visible_string_says_colour():
    strings = []
    for cls in operators.CLASSES + exchange.CLASSES + menus.CLASSES + panel.CLASSES + properties.CLASSES:
        strings += [getattr(cls, "bl_label", ""), cls.__doc__ or ""]  # F3, tooltips
        strings += _rna_strings(cls.bl_rna)
    for cls in operators.CLASSES + exchange.CLASSES:  # the operators' own properties (redo panel)
        strings += _rna_strings(getattr(bpy.ops.symframes, cls.bl_idname.split(".")[1]).get_rna_type())
    bpy.ops.symframes.add_example(example="plate")
    bpy.context.view_layer.objects.active = bpy.data.objects["hole 0"]
    for cls in panel.CLASSES:
        if issubclass(cls, bpy.types.Panel):
            strings += draw(cls.draw).texts
    for group in (glyphs.node_group(), omega_arrows.node_group(), hex_mesh.node_group()):  # modifier inputs
        strings += [item.name for item in group.interface.items_tree]
    assert len(strings) > 200
    said = [t for t in strings if "colour" in t.lower()]
    assert said == []


# ------------------------------------------------------------------ colors
def test_solid_view_shows_material_colors_by_default():
    # the premise of the colors below: Solid shading colors by material
    assert bpy.types.View3DShading.bl_rna.properties["color_type"].default == "MATERIAL"


def _diffuse(mat) -> tuple:
    return tuple(round(float(c), 4) for c in mat.diffuse_color)


def test_glyph_materials_have_viewport_colors():
    sc = scene()
    P = np.random.default_rng(0).random((40, 3))
    Q = np.tile([1.0, 0.0, 0.0, 0.0], (40, 1))
    err = np.linspace(0.0, 2.0, 40) * sc.symframes.error_scale
    g = glyphs.write_glyphs(sc, P, Q, err, glyphs.ERROR_ATTRIBUTE)
    used = [n.inputs["Material"].default_value for n in g.modifiers[glyphs.MODIFIER].node_group.nodes
            if n.bl_idname == "GeometryNodeSetMaterial"]
    assert len(used) == 3 + glyphs.ERROR_STEPS
    colours = [_diffuse(m) for m in used]
    assert all(c != DEFAULT_DIFFUSE for c in colours)
    assert len(set(colours)) == len(colours)  # every axis and every error step its own
    for axis in range(3):
        assert _diffuse(glyphs.axis_material(axis))[:3] == pytest.approx(glyphs.AXIS_COLOURS[axis], abs=1e-3)
    # error coloring: each glyph is the cross of its error step (what the Solid view shows)
    geo = g.evaluated_get(bpy.context.evaluated_depsgraph_get()).evaluated_geometry()
    inst = geo.instances_pointcloud()
    ref = np.array([d.value for d in inst.attributes[".reference_index"].data])
    step = np.minimum((np.clip(err / sc.symframes.error_scale, 0, 1) * glyphs.ERROR_STEPS).astype(int),
                      glyphs.ERROR_STEPS - 1)
    np.testing.assert_array_equal(ref, step)
    refs = geo.instance_references()
    names = [[m.name for m in r.mesh.materials if m is not None] for r in refs]
    assert names == [[f"{glyphs.ERROR_MATERIAL} {k + 1}"] for k in range(glyphs.ERROR_STEPS)]
    steps = glyphs.error_step_colours()
    assert steps[0][2] > steps[0][0] and steps[-1][0] > steps[-1][2]  # blue to red


def test_error_slice_faces_get_the_material_of_their_step():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]], float)
    tris = np.array([[0, 1, 2], [1, 3, 2], [1, 4, 3], [4, 5, 3]])
    scale = 0.01
    values = np.array([0.0, 0.45 * scale, 5 * scale, 0.5 * scale])
    grey = np.array([False, False, False, True])
    me = error_slice.new_slice_mesh(V, tris, np.arange(4), values, grey, "MONODROMY", scale)
    assert [m.name for m in me.materials] == list(error_slice.MATERIALS)
    assert all(_diffuse(m) != DEFAULT_DIFFUSE for m in me.materials)
    assert _diffuse(me.materials[0])[:3] == pytest.approx(error_slice.GREY, abs=1e-3)
    idx = np.empty(4, np.int32)
    me.polygons.foreach_get("material_index", idx)
    assert idx.tolist() == [1, 1 + int(0.45 * glyphs.ERROR_STEPS), glyphs.ERROR_STEPS, 0]
    # the scale recolors live: the steps follow
    obj = storage.replace_output(scene(), error_slice.ROLE, error_slice.OBJECT_NAME, me)
    obj[error_slice.STATS_KEY] = {"quantity": "MONODROMY"}
    scene().symframes.monodromy_scale = 100 * scale  # calls recolour
    obj.data.polygons.foreach_get("material_index", idx)
    assert idx.tolist() == [1, 1, 1, 0]


def test_other_outputs_and_the_network_have_viewport_colors():
    bpy.ops.symframes.add_example(example="cylinder")
    curve = next(o for o in scene().symframes.network.all_objects if o.type == "CURVE")
    mats = [curve.data.materials[0], omega_arrows.material()]
    mats += [diagnostics._material(name, colour) for name, colour in diagnostics.MATERIALS]
    mats += hex_mesh.quality_materials() + hex_mesh.valence_materials()
    for mat in mats:
        assert _diffuse(mat) != DEFAULT_DIFFUSE, mat.name
