"""The SymFrames tab of the 3D viewport sidebar (N panel)."""

import fnmatch

import bpy

from ..solver import HexReport
from . import diagnostics, error_slice, hex_mesh, job, operators, storage


class SymFramesPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "SymFrames"


def _split(layout):
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


class SYMFRAMES_PT_main(SymFramesPanel, bpy.types.Panel):
    bl_label = "Symmetric Moving Frames"

    def draw(self, context):
        s = context.scene.symframes
        layout = _split(self.layout)
        col = layout.column()
        col.prop(s, "domain")
        col.prop(s, "network")
        col = layout.column(heading="Sharp Edges")
        col.prop(s, "use_sharp_marks", text="Marked")
        row = col.row(align=True)
        row.prop(s, "use_sharp_angle", text="Angle")
        sub = row.row()
        sub.active = s.use_sharp_angle
        sub.prop(s, "sharp_angle", text="")
        col = layout.column(heading="Resolution")
        row = col.row(align=True)
        row.prop(s, "auto_resolution", text="Auto")
        if s.auto_resolution:
            row.prop(s, "target_tets", text="Tets")
        else:
            row.prop(s, "edge_length", text="")
        row = layout.row(align=True)
        row.use_property_split = False
        row.operator_enum("symframes.apply_preset", "preset")
        layout.operator("symframes.check_network", icon="CHECKMARK")
        j = operators.running_job()
        if isinstance(j, job.SolveJob):
            layout.progress(factor=j.fraction, text=f"{j.message} (Esc to cancel)")
        else:
            layout.operator("symframes.compute", icon="PLAY")
        layout.operator_menu_enum("symframes.add_example", "example", text="Add Example", icon="ADD")


class SYMFRAMES_PT_advanced(SymFramesPanel, bpy.types.Panel):
    bl_label = "Advanced Solver Settings"
    bl_parent_id = "SYMFRAMES_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        s = context.scene.symframes
        layout = _split(self.layout)
        col = layout.column()
        sub = col.row()
        sub.active = s.auto_resolution
        sub.prop(s, "follow_network")
        sub = col.row()
        sub.active = s.auto_resolution and not s.follow_network
        sub.prop(s, "grading")
        col.prop(s, "penalty")
        col.prop(s, "max_iterations")
        col.prop(s, "init")
        col.prop(s, "solve_seed")
        col.prop(s, "node_tolerance")
        layout.label(text="Guide: docs/addon.md, “Advanced solver settings”", icon="HELP")


class SYMFRAMES_UL_curves(bpy.types.UIList):
    """The curve objects of the network collection: name, index, role, torsion."""

    bl_idname = "SYMFRAMES_UL_curves"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0, flt_flag=0):
        cs = item.symframes
        row = layout.row(align=True)
        row.label(text=item.name, icon="CURVE_DATA")
        sub = row.row(align=True)
        sub.active = cs.role == "singular"
        sub.label(text=f"{cs.index:+d}" if cs.role == "singular" else "0")
        row.label(text=_enum_name(cs, "role"))
        row.label(text=_enum_name(cs, "torsion"))

    def filter_items(self, context, data, propname):
        # only the curves, by name: as scene_io reads them and messages number them
        objects = list(getattr(data, propname))
        pattern = f"*{self.filter_name}*" if self.filter_name else "*"
        shown = [obj.type == "CURVE" and fnmatch.fnmatch(obj.name.lower(), pattern.lower()) for obj in objects]
        if self.use_filter_invert:
            shown = [not x for x in shown]
        by_name = sorted(range(len(objects)), key=lambda i: objects[i].name)
        order = [0] * len(objects)
        for position, i in enumerate(by_name):
            order[i] = position  # the new position of item i
        return [self.bitflag_filter_item if x else 0 for x in shown], order


def _enum_name(data, prop: str) -> str:
    value = getattr(data, prop)
    return next(item.name for item in data.bl_rna.properties[prop].enum_items if item.identifier == value)


def active_network_curve(scene):
    """The curve picked in the Network Curves list, or None."""
    s = scene.symframes
    net = s.network
    if net is None or not 0 <= s.curve_index < len(net.all_objects):
        return None
    obj = net.all_objects[s.curve_index]
    return obj if obj.type == "CURVE" else None


class SYMFRAMES_PT_curve(SymFramesPanel, bpy.types.Panel):
    bl_label = "Network Curves"
    bl_parent_id = "SYMFRAMES_PT_main"

    def draw(self, context):
        s = context.scene.symframes
        layout = self.layout
        net = s.network
        if net is None:
            layout.label(text="Pick a Network collection above", icon="INFO")
            return
        row = layout.row()
        row.label(text="Curve")
        row.label(text="Index")
        row.label(text="Role")
        row.label(text="Torsion")
        layout.template_list("SYMFRAMES_UL_curves", "", net, "all_objects", s, "curve_index", rows=4)
        obj = active_network_curve(context.scene)
        active = context.active_object
        if obj is None and active is not None and active.type == "CURVE":
            obj = active  # a curve selected in the viewport that is not in the list
            layout.label(text=f"'{obj.name}' is not in the network collection", icon="INFO")
        if obj is None:
            layout.label(text="Pick a curve in the list to edit its settings")
            return
        cs = obj.symframes
        layout = _split(layout)
        layout.label(text=obj.name, icon="CURVE_DATA")
        layout.prop(cs, "role")
        row = layout.row()
        row.active = cs.role == "singular"
        row.prop(cs, "index", text="Index (quarter turns)")
        layout.prop(cs, "torsion")


class SYMFRAMES_PT_display(SymFramesPanel, bpy.types.Panel):
    bl_label = "Display"
    bl_parent_id = "SYMFRAMES_PT_main"

    def draw(self, context):
        s = context.scene.symframes
        layout = _split(self.layout)
        col = layout.column()
        col.prop(s, "glyph_count")
        col.prop(s, "glyph_size")
        col.prop(s, "glyph_region")
        col = layout.column(heading="Slice Plane")
        col.prop(s, "slice_axis")
        col.prop(s, "slice_offset")
        col.prop(s, "flip_clip")
        layout.operator("symframes.show_glyphs", icon="EMPTY_AXIS")
        col = layout.column()
        col.prop(s, "streamline_family")
        col.prop(s, "streamline_seeds")
        col.prop(s, "streamline_on_plane")
        col.prop(s, "streamline_radius")
        col.prop(s, "seed")
        layout.operator("symframes.trace_streamlines", icon="FORCE_MAGNETIC")
        layout.operator("symframes.clear", icon="TRASH")


class SYMFRAMES_PT_result(SymFramesPanel, bpy.types.Panel):
    bl_label = "Result"
    bl_parent_id = "SYMFRAMES_PT_main"

    def draw(self, context):
        layout = self.layout
        r = storage.stored_report(context.scene)
        if r is None:
            layout.label(text="No field computed yet")
            return
        sizes, m = r.sizes, r.metrics
        col = layout.column(align=True)
        col.label(text=f"Tets {sizes.get('tets', 0):,}   vertices {sizes.get('vertices', 0):,}")
        col.label(text=f"Edge length {r.edge_length:.3g}" + ("" if storage.stored_remeshed(context.scene)
                                                             else "  (mesh reused)"))
        col.label(text=f"Iterations {r.lm.n_iterations if r.lm else 0}   time {r.total_seconds:.1f} s")
        if not r.converged:
            col.label(text="Not converged: see the status bar's advice", icon="ERROR")
        # 'changed': joined pieces and ends brought onto the surface or a node count too
        moved = [c for c in r.repairs if c.changed]
        if moved:
            worst = max(moved, key=lambda c: c.max_displacement_h)
            col.label(text=f"{len(moved)} curve(s) repaired, up to {worst.max_displacement_h:.2f} h "
                           f"('{worst.name}')", icon="INFO")
        col = layout.column(align=True)
        col.label(text="Integrability (monodromy)")
        col.label(text=f"   mean {m.get('monodromy_mean_deg', 0):.3g}°   max {m.get('monodromy_max_deg', 0):.3g}°")
        col.label(text="Adaptation (mean, max)")
        col.label(text=f"   normals {m.get('normal_adaptation_mean_deg', 0):.3g}°, "
                       f"{m.get('normal_adaptation_max_deg', 0):.3g}°")
        if "tangent_adaptation_mean_deg" in m:
            col.label(text=f"   tangents {m['tangent_adaptation_mean_deg']:.3g}°, "
                           f"{m.get('tangent_adaptation_max_deg', 0):.3g}°")
        col = layout.column(align=True)
        c = r.singular_face_counts()
        col.label(text=f"Singular faces {c['singular']}",
                  icon="CHECKMARK" if c["spurious"] == 0 and c["missing"] == 0 else "ERROR")
        col.label(text=f"   spurious {c['spurious']}   missing {c['missing']}")
        if c["closest_differs"]:
            col.label(text=f"   closest-rotation reads {c['closest_differs']} otherwise", icon="INFO")
        row = layout.row(align=True)
        row.operator("symframes.export_field", text="Export Field…", icon="EXPORT")
        row.operator("symframes.tet_mesh_object", text="Tet Mesh", icon="MESH_ICOSPHERE")


class SYMFRAMES_PT_hex(SymFramesPanel, bpy.types.Panel):
    bl_label = "Hex Mesh"
    bl_parent_id = "SYMFRAMES_PT_main"

    def draw(self, context):
        scene = context.scene
        s = scene.symframes
        layout = _split(self.layout)
        col = layout.column()
        col.prop(s, "hex_cell_size")
        sub = col.row()
        sub.active = s.hex_cell_size == 0  # the cell count only picks the automatic size
        sub.prop(s, "hex_cells")
        row = layout.row(align=True)
        row.use_property_split = False
        row.operator_enum("symframes.apply_hex_preset", "preset")
        row = layout.row(align=True)
        row.prop(s, "hex_finer_near")
        row.operator("symframes.finer_near_selected", text="", icon="RESTRICT_SELECT_OFF")
        sub = layout.column(align=True)
        sub.active = bool(s.hex_finer_near.strip())
        sub.prop(s, "hex_finer_ratio")
        sub.prop(s, "hex_finer_reach")
        layout.prop(s, "hex_smooth")
        j = operators.running_job()
        if isinstance(j, job.HexJob):
            layout.progress(factor=j.fraction, text=f"{j.message} (Esc to cancel)")
        else:
            layout.operator("symframes.hex_mesh", icon="MESH_CUBE")
        r = hex_mesh.stored_report(scene)
        if r is None:
            if storage.stored_field(scene) is None:
                layout.label(text="Compute a field first")
            return
        draw_hex_report(layout.column(align=True), r)
        obj = hex_mesh.hex_object(scene)
        if obj is not None:
            draw_hex_histogram(layout.column(align=True), obj.data)
        col = layout.column(heading="View")
        col.prop(s, "hex_only")
        col.prop(s, "hex_explode")
        col.prop(s, "hex_fall_away")
        col.prop(s, "hex_axis")
        col.prop(s, "hex_show_below")
        layout.label(text="Quality colors: Solid view, Color: Material or Attribute", icon="INFO")
        layout.operator("symframes.export_hex_mesh", text="Export Hex Mesh…", icon="EXPORT")


def _number(x) -> float:
    """A figure of a report read back from JSON (where NaN is null)."""
    return float("nan") if x is None else float(x)


def draw_hex_histogram(col, me) -> None:
    """The scaled Jacobian's histogram (cells per tenth, a bar each) and the
    colour ramp's legend, from what the hex mesh datablock keeps."""
    counts = list(me.get(hex_mesh.HISTOGRAM_KEY, []))
    if counts:
        top = max(max(counts), 1)
        edges = hex_mesh.HISTOGRAM_EDGES
        col.label(text="Scaled Jacobian per cell")
        for k, n in enumerate(counts):
            if not n and k == 0:
                continue  # no inverted cell: no row for them
            what = "below 0" if k == 0 else f"{edges[k]:.1f}-{edges[k + 1]:.1f}"
            bar = "|" * int(round(24 * n / top))
            col.label(text=f"   {what:>9}  {bar} {n:,}")
    low = me.get(hex_mesh.LOW_KEY)
    if low is not None:
        col.label(text=f"Colors: red {low:.2f} (this mesh's least), yellow {0.5 * (low + 1):.2f}, green 1.00")


def draw_hex_report(col, r: HexReport) -> None:
    """The verdict and figures of a stored HexReport."""
    col.label(text="Valid hex mesh" if r.valid else "Defective hex mesh", icon="CHECKMARK" if r.valid else "ERROR")
    if not r.valid and r.reason:
        for part in str(r.reason).split("; "):
            col.label(text=f"   {part}")
    for w in (getattr(r, "warnings", None) or []) if r.valid else []:
        col.label(text=f"   warning: {w}", icon="INFO")
    col.label(text=f"Hexahedra {r.hexes:,}   vertices {r.vertices:,}")
    col.label(text=f"Cell size {_number(r.cell_size):.3g}")
    if r.size_p95:  # 0 in reports stored before the sizes were measured
        col.label(text=f"   {100 * _number(r.size_within):.0f}% of cells within 20% of it; 5-95%: "
                       f"{_number(r.size_p5):.2f}-{_number(r.size_p95):.2f} of it")
    col.label(text=f"Scaled Jacobian min {_number(r.sj_min):.3f}   mean {_number(r.sj_mean):.3f}")
    col.label(text=f"   before smoothing min {_number(r.sj_min_raw):.3f}")
    col.label(text="   Verdict's, least of the 8 corners (Gmsh's minSJ differs)")
    by_valence = ", ".join(f"{n} of valence {v}" for v, n in sorted(r.irregular.items()))
    col.label(text=f"Irregular edges: {by_valence or 'none'}")
    exact = bool(r.structure_exact)
    col.label(text="   exactly the prescribed curves" if exact else "   not the prescribed curves",
              icon="CHECKMARK" if exact else "ERROR")
    col.label(text=f"Hausdorff distance {100 * _number(r.hausdorff_relative):.2f}% of the diagonal")


class SYMFRAMES_PT_diagnostics(SymFramesPanel, bpy.types.Panel):
    bl_label = "Diagnostics"
    bl_parent_id = "SYMFRAMES_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        scene = context.scene
        s = scene.symframes
        layout = _split(self.layout)
        layout.operator("symframes.show_singular_faces", icon="MOD_TRIANGULATE")
        obj = storage.output_object(scene, "singular_faces")
        if obj is not None and diagnostics.COUNTS_KEY in obj:
            c = obj[diagnostics.COUNTS_KEY]
            layout.label(text=f"{c['singular']:,} singular faces, {c['spurious']:,} spurious (red)",
                         icon="CHECKMARK" if c["spurious"] == 0 else "ERROR")
            if c.get("closest_differs"):
                layout.label(text=f"closest-rotation reads {c['closest_differs']} otherwise", icon="INFO")
        # omega arrows
        col = layout.column()
        col.prop(s, "omega_region")
        col.prop(s, "omega_count")
        col.prop(s, "omega_scale")
        layout.operator("symframes.show_omega", icon="ORIENTATION_GIMBAL")
        # error slice and glyph colours; both use the Display panel's slice plane
        col = layout.column()
        col.prop(s, "slice_quantity")
        col.prop(s, "monodromy_scale")
        col.prop(s, "error_scale")
        layout.operator("symframes.show_slice", icon="MOD_BOOLEAN")
        obj = storage.output_object(scene, error_slice.ROLE)
        if obj is not None and error_slice.STATS_KEY in obj:
            st = obj[error_slice.STATS_KEY]
            what = "monodromy" if st["quantity"] == "MONODROMY" else "adaptation"
            grey = "network" if st["quantity"] == "MONODROMY" else "not measured"
            col = layout.column(align=True)
            col.label(text=f"{st['faces']:,} faces ({st['grey']:,} {grey}, grey)")
            col.label(text=f"   {what} mean {st['mean_deg']:.3g}°   max {st['max_deg']:.3g}°")
        layout.prop(s, "glyph_colour")
        layout.operator("symframes.show_glyphs", icon="EMPTY_AXIS")
        layout.label(text="Error colors in full: Material Preview (Solid view: in steps)", icon="INFO")


CLASSES = (SYMFRAMES_UL_curves, SYMFRAMES_PT_main, SYMFRAMES_PT_curve, SYMFRAMES_PT_advanced, SYMFRAMES_PT_display,
           SYMFRAMES_PT_result, SYMFRAMES_PT_hex, SYMFRAMES_PT_diagnostics)
