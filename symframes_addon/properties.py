"""Settings stored in the .blend: one group per scene, one per curve object.

The scene group holds the inputs (domain object, network collection), the
solver settings, the display settings and a pointer to the stored result
(see storage.py).  The object group holds a network curve's index, role and
torsion; it is edited in the panel and read by scene_io.read_network.
"""

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from ..solver import DEFAULT_HEXES

ROLES = (
    ("singular", "Singular", "Interior curve around which the field turns by the index"),
    ("feature", "Feature", "Interior curve the field is tangent to (index 0)"),
    ("sharp", "Sharp boundary", "Sharp feature curve lying on the domain surface (index 0)"),
)
TORSIONS = (
    ("free", "Free", "Free torsion per edge (Eq. 21)"),
    ("fixed", "Fixed", "Total torsion of the least-twist reference frame (Eq. 22)"),
)
FAMILIES = (
    ("0", "X", "Streamlines along the first frame axis (red glyph bars)"),
    ("1", "Y", "Streamlines along the second frame axis (green glyph bars)"),
    ("2", "Z", "Streamlines along the third frame axis (blue glyph bars)"),
    ("ALL", "All", "Streamlines along all three axes from every seed"),
)
AXES = (("X", "X", "Plane normal to X"), ("Y", "Y", "Plane normal to Y"), ("Z", "Z", "Plane normal to Z"))
HEX_AXES = AXES + (("NEG_X", "-X", "Plane normal to X, the cells on its negative side go first"),
                   ("NEG_Y", "-Y", "Plane normal to Y, the cells on its negative side go first"),
                   ("NEG_Z", "-Z", "Plane normal to Z, the cells on its negative side go first"))
GLYPH_REGIONS = (
    ("VOLUME", "Volume", "Glyphs throughout the solid"),
    ("CUTAWAY", "Cutaway", "Glyphs on one side of the slice plane only, to see inside"),
    ("SLICE", "Slice", "Glyphs on the slice plane only"),
)
GLYPH_COLORS = (
    ("AXES", "Axes", "Bars colored by frame axis (red, green, blue)"),
    ("ADAPTATION", "Adaptation Error",
     "Glyphs at the boundary vertices, colored by the angle between the surface normal and the nearest frame "
     "axis (blue: 0 degrees, red: the Adaptation Scale and above)"),
    ("MONODROMY", "Monodromy",
     "Glyphs at tet-mesh vertices (all, the cutaway's or the slice faces'), colored by the mean monodromy angle "
     "of the faces around the vertex, off the network (blue: 0, red: the Monodromy Scale and above)"),
)
OMEGA_REGIONS = (
    ("VOLUME", "Volume", "Arrows on edges throughout the solid"),
    ("CUTAWAY", "Cutaway", "Arrows on the edges on one side of the slice plane only"),
    ("SLICE", "Slice", "Arrows on the edges of the tet faces along the slice plane"),
)
SLICE_QUANTITIES = (
    ("MONODROMY", "Monodromy",
     "Tet faces along the slice plane, colored by how far omega fails to close around each (Eq. 9); "
     "faces the network passes through are grey"),
    ("ADAPTATION", "Adaptation Error",
     "The domain surface on the kept side of the slice plane, colored by the normal adaptation error"),
)
# Quality presets (the Apply Preset operator): Auto resolution aiming at a tet
# count, and the largest number of LM iterations.  Standard is the defaults.
# Each follows the network as the solver's default does (issue 41b): where
# the network asks for more tets than the preset's count, up to 4x as many.
PRESETS = {
    "DRAFT": {"auto_resolution": True, "target_tets": 4000, "follow_network": True, "max_iterations": 15},
    "STANDARD": {"auto_resolution": True, "target_tets": 15000, "follow_network": True, "max_iterations": 50},
    "FINE": {"auto_resolution": True, "target_tets": 50000, "follow_network": True, "max_iterations": 60},
}
PRESET_ITEMS = (
    ("DRAFT", "Draft", "Auto resolution aiming at about 4,000 tets (up to 4x where the network asks for more), at "
     "most 15 iterations: the quickest, to try a network"),
    ("STANDARD", "Standard", "Auto resolution aiming at about 15,000 tets (up to 4x where the network asks for "
     "more), at most 50 iterations (the defaults)"),
    ("FINE", "Fine", "Auto resolution aiming at about 50,000 tets (up to 4x where the network asks for more), at "
     "most 60 iterations: a finer field, slower"),
)
# Hex Cells presets (the Apply Hex Preset operator): about how many hexahedra
# the automatic cell size aims at.  Medium is the default, as the solver's.
HEX_PRESETS = {"COARSE": 800, "MEDIUM": DEFAULT_HEXES, "FINE": 12000}
HEX_PRESET_ITEMS = (
    ("COARSE", "Coarse", "Automatic cell size for about 800 hexahedra: the quickest"),
    ("MEDIUM", "Medium", f"Automatic cell size for about {DEFAULT_HEXES:,} hexahedra (the default)"),
    ("FINE", "Fine", "Automatic cell size for about 12,000 hexahedra"),
)
INITS = (
    ("zero", "Zero", "Start Levenberg-Marquardt from omega = 0"),
    ("linear", "Linear", "Start from the solution of the linearised problem"),
    ("constant", "Constant", "Start from a constant omega"),
    ("random", "Random", "Start from a random omega"),
)


def _is_mesh(_self, obj):
    return obj.type == "MESH"


def _select_network_curve(self, context):
    # picking a curve in the list makes it the active, selected object, as the
    # Outliner does, so that it can be found in the viewport
    net = self.network
    if net is None or not 0 <= self.curve_index < len(net.all_objects):
        return
    obj = net.all_objects[self.curve_index]
    view_layer = context.view_layer
    if view_layer is None or view_layer.objects.get(obj.name) is None:
        return
    for other in view_layer.objects.selected:
        other.select_set(False)
    obj.select_set(True)
    view_layer.objects.active = obj


def _update_glyph_inputs(self, context):
    # the glyph size and error scale are live inputs of the Geometry Nodes modifier
    from . import glyphs

    glyphs.sync_modifier(context.scene)


def _update_error_scales(self, context):
    from . import error_slice, glyphs

    glyphs.sync_modifier(context.scene)
    error_slice.recolour(context.scene)


def _update_omega_scale(self, context):
    from . import omega_arrows

    omega_arrows.sync_modifier(context.scene)


def _update_hex_only(self, context):
    from . import hex_mesh

    hex_mesh.show_hex_only(context.scene, bool(self.hex_only))


def _update_hex_view(self, context):
    # Explode, Fall Away and Axis are live inputs of the hex mesh's Geometry Nodes modifier
    from . import hex_mesh

    hex_mesh.sync_modifier(context.scene)


def _update_streamline_radius(self, context):
    from . import storage

    obj = storage.output_object(context.scene, "streamlines")
    if obj is not None and obj.type == "CURVE":
        obj.data.bevel_depth = self.streamline_radius


class SymFramesCurveSettings(bpy.types.PropertyGroup):
    """Per curve object: how it enters the network."""

    index: IntProperty(
        name="Index",
        description="Index in quarter turns: the field turns by index/4 full turns around the curve "
        "(+1: valence-3 hex edge, -1: valence-5). Use 0 for feature and sharp curves",
        default=1,
        min=-8,
        max=8,
    )
    role: EnumProperty(name="Role", items=ROLES, default="singular")
    torsion: EnumProperty(name="Torsion", items=TORSIONS, default="free")


class SymFramesSettings(bpy.types.PropertyGroup):
    """Per scene: inputs, solver and display settings, and the stored result."""

    # ---------------------------------------------------------------- inputs
    domain: PointerProperty(
        name="Domain", type=bpy.types.Object, poll=_is_mesh,
        description="Closed mesh object bounding the solid (read in world space with modifiers applied)",
    )
    network: PointerProperty(
        name="Network", type=bpy.types.Collection,
        description="Collection whose curve objects form the singularity and feature network",
    )
    curve_index: IntProperty(
        name="Network Curve", default=0, min=0, update=_select_network_curve,
        description="The network curve whose settings the Network Curves panel edits",
    )
    node_tolerance: FloatProperty(
        name="Node Tolerance", default=0.0, min=0.0, soft_max=1.0, subtype="DISTANCE", precision=4,
        description="Curve endpoints closer than this meet at a node (0: a thousandth of the domain's size)",
    )
    use_sharp_marks: BoolProperty(
        name="Marked Sharp Edges", default=True,
        description="Use the domain mesh's edges marked sharp as sharp boundary features",
    )
    use_sharp_angle: BoolProperty(
        name="Sharp Angle", default=True,
        description="Treat surface edges whose faces meet at more than this angle as sharp features",
    )
    sharp_angle: FloatProperty(
        name="Angle", default=0.5235987755982988, min=0.0, max=3.141592653589793, subtype="ANGLE",
        description="Dihedral angle above which an edge is sharp",
    )
    # ---------------------------------------------------------------- solver
    auto_resolution: BoolProperty(
        name="Auto", default=True,
        description="Pick the tet edge length from the volume and the network's smallest features",
    )
    edge_length: FloatProperty(
        name="Edge Length", default=0.2, min=1e-4, soft_max=10.0, subtype="DISTANCE", precision=3,
        description="Target tetrahedron edge length (smaller: finer mesh, slower)",
    )
    target_tets: IntProperty(
        name="Target Tets", default=15000, min=500, soft_max=200000, step=1000,
        description="With Auto resolution: about how many tetrahedra to mesh the solid with (the edge length is "
        "then also kept small enough to resolve the network's smallest features)",
    )
    follow_network: BoolProperty(
        name="Follow Network", default=True,
        description="With Auto resolution: where the network asks for more tetrahedra than Target Tets (short or "
        "close curves), spend up to 4x as many (within the memory limit) and choose the grading automatically, "
        "as the solver's default does; off: Target Tets and Grading hold as set",
    )
    grading: FloatProperty(
        name="Grading", default=0.5, min=0.1, max=1.0, precision=2,
        description="With Auto resolution: how fast the edge length grows away from the parts of the network "
        "that need a finer mesh (per unit distance). Lower it, with more Target Tets, around curves shorter "
        "than an edge",
    )
    penalty: FloatProperty(
        name="Penalty", default=1000.0, min=1e-3, soft_max=1e5,
        description="Weight a of the structure-equation penalty (Eq. 23)",
    )
    max_iterations: IntProperty(name="Iterations", default=50, min=1, soft_max=200,
                                description="Largest number of Levenberg-Marquardt iterations")
    init: EnumProperty(name="Start", items=INITS, default="zero",
                       description="Initial guess of Levenberg-Marquardt (the result should not depend on it)")
    solve_seed: IntProperty(
        name="Solve Seed", default=0, min=0,
        description="Seed of the solver's random numbers (the Random start); the same seed and inputs repeat "
        "the same solve, except for the tet mesh, which fTetWild does not make repeatable",
    )
    # --------------------------------------------------------------- display
    glyph_count: IntProperty(name="Glyphs", default=2000, min=0, soft_max=50000,
                             description="Number of cross glyphs (their density): about this many are sampled")
    glyph_size: FloatProperty(name="Glyph Size", default=0.08, min=0.0, soft_max=1.0, subtype="DISTANCE",
                              description="Length of a glyph's bars", update=_update_glyph_inputs)
    glyph_region: EnumProperty(name="Region", items=GLYPH_REGIONS, default="VOLUME",
                               description="Where glyphs are sampled")
    glyph_colour: EnumProperty(name="Color", items=GLYPH_COLORS, default="AXES",
                               description="What the glyphs' colors show")
    error_scale: FloatProperty(
        name="Adaptation Scale", default=0.08726646259971647, min=1e-4, max=1.5707963267948966, subtype="ANGLE",
        description="Adaptation error shown in full red (glyphs and error slice)", update=_update_error_scales,
    )
    monodromy_scale: FloatProperty(
        name="Monodromy Scale", default=0.0017453292519943296, min=1e-7, max=3.141592653589793, subtype="ANGLE",
        precision=4, description="Monodromy angle shown in full red (glyphs and error slice); the paper's fields "
        "stay below a small fraction of a degree", update=_update_error_scales,
    )
    omega_region: EnumProperty(name="Region", items=OMEGA_REGIONS, default="SLICE",
                               description="Which edges get an omega arrow")
    omega_count: IntProperty(name="Arrows", default=20000, min=1, soft_max=200000,
                             description="Largest number of omega arrows (a random subset of the edges beyond it)")
    omega_scale: FloatProperty(
        name="Arrow Scale", default=2.0, min=0.0, soft_max=20.0,
        description="Arrow length per radian of rotation, in mean tet edge lengths (live)",
        update=_update_omega_scale,
    )
    slice_quantity: EnumProperty(name="Quantity", items=SLICE_QUANTITIES, default="MONODROMY",
                                 description="What the error slice shows")
    slice_axis: EnumProperty(name="Slice Axis", items=AXES, default="Y")
    slice_offset: FloatProperty(
        name="Slice Position", default=0.5, min=0.0, max=1.0, subtype="FACTOR",
        description="Position of the slice plane across the solid's bounding box",
    )
    flip_clip: BoolProperty(name="Flip", default=False, description="Keep the other side of the slice plane "
                                                                     "(cutaway)")
    streamline_family: EnumProperty(name="Family", items=FAMILIES, default="ALL")
    streamline_seeds: IntProperty(name="Seeds", default=150, min=1, soft_max=5000,
                                  description="Number of seed points (each gives one line per family)")
    streamline_on_plane: BoolProperty(name="Seed on Slice Plane", default=False,
                                      description="Seed on the slice plane instead of throughout the solid")
    streamline_radius: FloatProperty(name="Radius", default=0.008, min=0.0, soft_max=0.1, subtype="DISTANCE",
                                     description="Tube radius of the streamlines",
                                     update=_update_streamline_radius)
    seed: IntProperty(name="Random Seed", default=0, min=0,
                      description="Seed of the display's random choices: glyph and streamline seed points, and "
                      "which omega arrows are drawn beyond the Arrows limit (not the solve: see Solve Seed)")
    # -------------------------------------------------------------- hex mesh
    hex_cell_size: FloatProperty(
        name="Cell Size", default=0.0, min=0.0, soft_max=10.0, subtype="DISTANCE", precision=3,
        description="Edge length of the hexahedra (0: automatic, about Hex Cells cells, finer where the "
        "network's short curves need it)",
    )
    hex_cells: IntProperty(
        name="Hex Cells", default=HEX_PRESETS["MEDIUM"], min=10, soft_max=100000, step=100,
        description="With Cell Size 0: about how many hexahedra the automatic cell size aims at",
    )
    hex_smooth: BoolProperty(
        name="Smooth", default=True,
        description="Optimise the hex vertices after extraction (it never lowers the minimum scaled Jacobian)",
    )
    hex_finer_near: StringProperty(
        name="Finer Near", default="",
        description="Smaller cells near these boundary patches and curves, e.g. \"patch 3, curve 2\" or "
        "\"curve 'radial 0'\": patches numbered as the hex mesh's 'patch' attribute, curves from 0 in the "
        "network's order or by name (empty: one cell size everywhere)",
    )
    hex_finer_ratio: FloatProperty(
        name="Ratio", default=0.5, min=0.05, max=1.0, subtype="FACTOR",
        description="With Finer Near: the cell size there, as a fraction of the cell size",
    )
    hex_finer_reach: FloatProperty(
        name="Reach", default=4.0, min=0.1, soft_max=20.0,
        description="With Finer Near: the distance, in cells, over which the size grows back to the cell size",
    )
    hex_explode: FloatProperty(
        name="Explode", default=0.0, min=0.0, max=0.9, subtype="FACTOR", update=_update_hex_view,
        description="Shrink every hex cell about its centre, to see the cells inside (live)",
    )
    hex_fall_away: FloatProperty(
        name="Fall Away", default=0.0, min=0.0, max=1.0, subtype="FACTOR", update=_update_hex_view,
        description="Hide the hex cells beyond a plane sweeping along the axis: 0 hides none, 1 all (live)",
    )
    hex_only: BoolProperty(
        name="Hex Only", default=False, update=_update_hex_only,
        description="Hide the domain, the network curves and the field's objects (glyphs, streamlines, "
                    "diagnostics) while the hex mesh is shown; off shows again what it hid. Hex Mesh turns it on",
    )
    hex_show_below: FloatProperty(
        name="Show Below", default=1.0, min=0.0, max=1.0, subtype="FACTOR", update=_update_hex_view,
        description="Show only the hex cells whose scaled Jacobian is at most this: 1 shows all (live)",
    )
    hex_axis: EnumProperty(
        name="Axis", items=HEX_AXES, default="Z", update=_update_hex_view,
        description="The axis along which Fall Away sweeps (cells on its positive side go first; -X, -Y, -Z: "
                    "on its negative side)",
    )
    # ---------------------------------------------------------------- result
    field: PointerProperty(
        name="Field", type=bpy.types.Mesh,
        description="Stored result: tet mesh vertices with a 'frame' quaternion attribute, tets as faces "
        "(see storage.py)",
    )


CLASSES = (SymFramesCurveSettings, SymFramesSettings)


def register_properties():
    bpy.types.Scene.symframes = PointerProperty(type=SymFramesSettings)
    bpy.types.Object.symframes = PointerProperty(type=SymFramesCurveSettings)


def unregister_properties():
    del bpy.types.Object.symframes
    del bpy.types.Scene.symframes
