"""Hex Mesh in the add-on, with the bpy module: the operator (in the calling
thread as in background mode, and as a thread job), the cell-soup object and
its attributes, the irregular edges, the Hex View modifier, the panel, the
export, and a refused or cancelled run leaving the scene as it was.

One solve of the cylinder (4 curves of index +1/4) at a coarse resolution and
one hex mesh of it at the Coarse preset are shared (a module fixture, saved
as a .blend and reopened per test); the figures are the solver's report.
The ball (20 curves meeting at 8 nodes) is solved and hex meshed the same
way, for the hex mesh of a reopened file: the network its solve traced is
kept in the .blend, so the same cells and irregular edges come back.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import bpy
import meshio
import numpy as np
import pytest

from tests import addon_package
from tests.addon_package import load_addon

addon = load_addon()
from symframes.solver import HexOptions, HexReport, SolvedField  # noqa: E402
from symframes.solver import io as sio  # noqa: E402
from symframes.symframes_addon import (  # noqa: E402
    exchange,
    hex_mesh,
    job,
    menus,
    operators,
    panel,
    properties,
    storage,
)

registered = addon_package.registered  # fixtures shared by the add-on tests
empty_scene = addon_package.empty_scene

EDGE_LENGTH = 0.4  # the cylinder's field: about 3,500 tets
BALL_EDGE_LENGTH = 0.25  # the ball's field: about 4,300 tets; coarser meshes put neighbouring nodes' balls together
HEX_PRESET = "COARSE"  # about 800 hexahedra


def scene():
    return bpy.context.scene


def output(role):
    return storage.output_object(scene(), role)


def scene_state() -> dict:
    """Everything a hex run could add, change or leave behind."""
    hex_obj = output(hex_mesh.ROLE)
    return {
        "objects": sorted((o.name, o.type, o.data.name if o.data else "") for o in bpy.data.objects),
        "meshes": sorted((m.name, len(m.vertices), len(m.polygons)) for m in bpy.data.meshes),
        "curves": sorted((c.name, len(c.splines)) for c in bpy.data.curves),
        "collections": sorted(c.name for c in bpy.data.collections),
        "node_groups": sorted(g.name for g in bpy.data.node_groups),
        "materials": sorted(m.name for m in bpy.data.materials),
        "hex": None if hex_obj is None else (hex_obj.data.get(hex_mesh.HEX_ID_KEY),
                                             hex_obj.data.get(hex_mesh.REPORT_KEY)),
    }


def attribute(me, name, count, dtype=np.float32, width=1):
    a = np.empty(count * width, dtype)
    attr = me.attributes[name]
    attr.data.foreach_get("vector" if width == 3 and attr.data_type == "FLOAT_VECTOR" else "value", a)
    return a.reshape(-1, width) if width > 1 else a


def evaluated_counts(obj) -> tuple[int, int, np.ndarray]:
    """(vertices, faces, positions) of the object after its modifiers."""
    obj.update_tag()
    dg = bpy.context.evaluated_depsgraph_get()
    dg.update()
    ev = obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        co = np.empty(3 * len(me.vertices))
        me.vertices.foreach_get("co", co)
        return len(me.vertices), len(me.polygons), co.reshape(-1, 3)
    finally:
        ev.to_mesh_clear()


class Layout:
    """Records the texts a panel's draw function would show."""

    def __init__(self):
        self.texts, self.operators, self.props = [], [], []

    def _record(self, name, args, kw):
        if "text" in kw:
            self.texts.append(kw["text"])
        if name in ("operator", "operator_enum"):
            self.operators.append(args[0])
            return SimpleNamespace()
        if name == "prop":
            getattr(args[0], args[1])
            self.props.append(args[1])
        return self

    def __getattr__(self, name):
        return lambda *args, **kw: self._record(name, args, kw)


def draw_hex_panel() -> Layout:
    layout = Layout()
    panel.SYMFRAMES_PT_hex.draw(SimpleNamespace(layout=layout), bpy.context)
    return layout


def solve_and_hex(example: str, edge_length: float, path):
    """An example solved and hex meshed at the Coarse preset (in background
    mode's execute), saved to path; what the tests compare against.

    Solved by Compute Field, not taken from conftest's session cache of
    solves: what is tested is the add-on's own solve and what it stores, and
    the add-on runs the solver as the package ``symframes.solver``, whose
    classes (Role, TetMesh, SolvedField) are not those of the ``solver``
    package that the cache's Results are made of.  (fTetWild's output for
    the same input is shared, as everywhere: tests/conftest.py.)"""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.symframes.add_example(example=example)
    s = scene().symframes
    s.auto_resolution, s.edge_length, s.glyph_count = False, edge_length, 200
    assert bpy.ops.symframes.compute() == {"FINISHED"}
    assert bpy.ops.symframes.apply_hex_preset(preset=HEX_PRESET) == {"FINISHED"}
    assert (s.hex_cells, s.hex_cell_size) == (properties.HEX_PRESETS[HEX_PRESET], 0.0)
    assert bpy.ops.symframes.hex_mesh() == {"FINISHED"}
    obj = output(hex_mesh.ROLE)
    hm = job.cached_hex(obj.data[hex_mesh.HEX_ID_KEY])
    assert hm is not None, "the hex mesh written is kept in memory for the export"
    field = storage.solved_field(scene())
    assert isinstance(field, SolvedField), "the solved field is kept whole in the .blend"
    ns = SimpleNamespace(hm=hm, report=hm.report, stored=hex_mesh.stored_report(scene()),
                         memory=(obj.data[hex_mesh.HEX_ID_KEY], hm), field=field, source=field.to_arrays(),
                         path=path)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return ns


@pytest.fixture(scope="module")
def cyl(registered, tmp_path_factory):
    """The cylinder solved and hex meshed, saved."""
    return solve_and_hex("cylinder", EDGE_LENGTH, tmp_path_factory.mktemp("hex") / "cylinder_hex.blend")


@pytest.fixture(scope="module")
def ball(registered, tmp_path_factory):
    """The ball (curves meeting at nodes) solved and hex meshed, saved."""
    return solve_and_hex("ball", BALL_EDGE_LENGTH, tmp_path_factory.mktemp("hex") / "ball_hex.blend")


def reopen(cyl, new_session: bool = False):
    """Open the fixture's file with what the session that wrote it kept in
    memory (its HexMesh), or, as a new session, with nothing."""
    bpy.ops.wm.open_mainfile(filepath=str(cyl.path))
    job.forget_results()
    if not new_session:
        hex_id, hm = cyl.memory
        job.remember_hex(hex_id, hm)


# ------------------------------------------------------------------ the run
@pytest.mark.slow
@pytest.mark.mesher
def test_the_hex_run_is_valid_and_reported(cyl):
    reopen(cyl)
    r = cyl.report
    assert r.status == "valid", r.summary()
    assert r.structure_exact and r.irregular == {3: r.irregular[3]} and r.irregular[3] > 0
    # the object keeps the report (HexReport.to_dict as JSON), read back by HexReport.from_dict
    stored = hex_mesh.stored_report(scene())
    assert isinstance(stored, HexReport) and stored.to_dict() == r.to_dict() == cyl.stored.to_dict()
    assert stored.hexes == r.hexes == len(cyl.hm.hexes)
    assert stored.status == "valid" and stored.irregular == r.irregular and stored.curves == r.curves
    assert json.loads(output(hex_mesh.ROLE).data[hex_mesh.REPORT_KEY])["irregular"] == {"3": r.irregular[3]}


@pytest.mark.slow
@pytest.mark.mesher
def test_hex_object_is_a_cell_soup_with_the_reports_figures(cyl):
    reopen(cyl)
    obj = output(hex_mesh.ROLE)
    assert obj is not None and obj.name == hex_mesh.OBJECT_NAME and obj.type == "MESH"
    assert obj.users_collection[0].get(storage.ROLE_KEY) == "results"
    assert obj.show_wire  # the cells' outlines
    me, hm = obj.data, cyl.hm
    m = cyl.report.hexes
    # 8 vertices and 6 quads per cell, 12 edges: every cell an island
    assert (len(me.vertices), len(me.polygons), len(me.edges)) == (8 * m, 6 * m, 12 * m)
    sizes = np.empty(6 * m, np.int32)
    me.polygons.foreach_get("loop_total", sizes)
    assert np.all(sizes == 4)
    cell = attribute(me, hex_mesh.CELL_ATTRIBUTE, 6 * m, np.int32)
    np.testing.assert_array_equal(cell, np.repeat(np.arange(m), 6))
    # the corners in VTK order, copies of the hex mesh's vertices
    ids = attribute(me, hex_mesh.VERTEX_ATTRIBUTE, 8 * m, np.int32).reshape(m, 8)
    np.testing.assert_array_equal(ids, hm.hexes)
    P = attribute(me, "position", 8 * m, width=3)
    np.testing.assert_allclose(P, hm.vertices[hm.hexes].reshape(-1, 3), atol=1e-6)
    # the scaled Jacobian: the report's figures
    sj = attribute(me, hex_mesh.SJ_ATTRIBUTE, 6 * m)
    assert sj.min() == pytest.approx(cyl.report.sj_min, abs=1e-6)
    assert sj[::6].mean() == pytest.approx(cyl.report.sj_mean, abs=1e-6)
    np.testing.assert_allclose(sj[::6], hm.scaled_jacobian, atol=1e-6)
    centre = attribute(me, hex_mesh.CENTER_ATTRIBUTE, 6 * m, width=3)
    np.testing.assert_allclose(centre[::6], hm.vertices[hm.hexes].mean(axis=1), atol=1e-6)
    # every face outward: each cell's faces enclose its volume with a positive sign
    corners = np.empty(24 * m, np.int32)
    me.loops.foreach_get("vertex_index", corners)
    Q = P[corners.reshape(-1, 4)]
    tri = np.concatenate([Q[:, [0, 1, 2]], Q[:, [0, 2, 3]]], axis=0)
    signed = np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6
    per_cell = (signed[: 6 * m] + signed[6 * m:]).reshape(m, 6).sum(axis=1)
    assert np.all(per_cell > 0)


@pytest.mark.slow
@pytest.mark.mesher
def test_quality_colors(cyl):
    reopen(cyl)
    me = output(hex_mesh.ROLE).data
    m = cyl.report.hexes
    assert me.color_attributes.active_color_name == hex_mesh.COLOR_ATTRIBUTE
    col = np.empty(24 * m * 4, np.float32)
    me.color_attributes[hex_mesh.COLOR_ATTRIBUTE].data.foreach_get("color", col)
    col = col.reshape(m, 24, 4)
    assert np.all(col == col[:, :1])  # one color per cell
    # the ramp fitted to this mesh: red at its least scaled Jacobian, green at 1
    low = hex_mesh.ramp_low(cyl.hm.scaled_jacobian)
    assert np.isclose(low, cyl.hm.scaled_jacobian.min()) and np.isclose(me[hex_mesh.LOW_KEY], low)
    np.testing.assert_allclose(col[:, 0], hex_mesh.sj_colors(cyl.hm.scaled_jacobian, low), atol=1e-6)
    # by default red at and below 0.3, green at 1, yellow between
    red, yellow, green = hex_mesh.sj_colors(np.array([0.1, hex_mesh.SJ_RED + 0.35, 1.0]))[:, :3]
    assert red[0] > 0.8 > red[1] and green[1] > 0.6 > green[0] and yellow[0] > 0.9 and yellow[1] > 0.8
    # the Solid view's default (Color: Material): each face the material of its step
    idx = np.empty(6 * m, np.int32)
    me.polygons.foreach_get("material_index", idx)
    np.testing.assert_array_equal(idx, np.repeat(hex_mesh.sj_steps(cyl.hm.scaled_jacobian, low), 6))
    assert len(set(idx.tolist())) > 2  # a good mesh is not one green: its spread shows
    # the panel's histogram: cells per tenth of the scaled Jacobian
    counts = list(me[hex_mesh.HISTOGRAM_KEY])
    assert sum(counts) == m and counts == hex_mesh.histogram(cyl.hm.scaled_jacobian)
    viewport = [tuple(round(c, 4) for c in mat.diffuse_color) for mat in me.materials]
    assert len(viewport) == hex_mesh.SJ_STEPS and len(set(viewport)) == hex_mesh.SJ_STEPS


@pytest.mark.slow
@pytest.mark.mesher
def test_irregular_edges_are_a_curve_per_edge_with_its_valence(cyl):
    reopen(cyl)
    obj = output(hex_mesh.EDGES_ROLE)
    assert obj is not None and obj.type == "CURVE" and obj.name == hex_mesh.EDGES_NAME
    hm = cyl.hm
    splines = obj.data.splines
    assert len(splines) == sum(cyl.report.irregular.values()) == len(hm.irregular_edges)
    valence = list(obj.data[hex_mesh.VALENCE_KEY])
    assert valence == hm.irregular_valence.tolist()
    assert valence.count(3) == cyl.report.irregular[3]
    mats = [sp.material_index for sp in splines]
    assert mats == [hex_mesh.VALENCE_INDEX.get(v, 2) for v in valence]
    co = np.array([[tuple(p.co)[:3] for p in sp.points] for sp in splines])
    np.testing.assert_allclose(co, hm.vertices[hm.irregular_edges], atol=1e-6)
    # valence 3 and 5 look different in the Solid view
    v3, v5 = obj.data.materials[0], obj.data.materials[1]
    assert tuple(v3.diffuse_color) != tuple(v5.diffuse_color)
    assert obj.data.bevel_depth > 0


@pytest.mark.slow
@pytest.mark.mesher
def test_view_modifier_explodes_and_falls_away(cyl):
    reopen(cyl)
    obj = output(hex_mesh.ROLE)
    s = scene().symframes
    mod = obj.modifiers[hex_mesh.MODIFIER]
    assert mod.node_group.name == hex_mesh.NODE_GROUP
    inputs = [i.name for i in mod.node_group.interface.items_tree if getattr(i, "in_out", None) == "INPUT"]
    assert inputs == ["Geometry", "Explode", "Fall Away", "Axis", "Show Below"]
    m = cyl.report.hexes
    n, f, P = evaluated_counts(obj)
    assert (n, f) == (8 * m, 6 * m)  # 0, 0: the cells as written, a closed surface outside
    # Explode: every cell shrunk about its centre
    s.hex_explode = 0.5
    n, f, P = evaluated_counts(obj)
    assert (n, f) == (8 * m, 6 * m)
    C = cyl.hm.vertices[cyl.hm.hexes]
    np.testing.assert_allclose(P.reshape(m, 8, 3), C.mean(axis=1, keepdims=True) + 0.5 * (C - C.mean(axis=1,
                               keepdims=True)), atol=1e-5)
    s.hex_explode = 0.0
    # Fall Away: the cells whose centre lies beyond the plane sweeping along the axis are hidden
    centres = C.mean(axis=1)
    for fall, axis in ((0.5, "Z"), (0.25, "X"), (0.5, "NEG_Z")):  # NEG_: the negative side goes first
        s.hex_axis, s.hex_fall_away = axis, fall
        sign = -1.0 if axis.startswith("NEG_") else 1.0
        d = sign * centres[:, "XYZ".index(axis[-1])]
        plane = d.min() + (1 - fall) * (d.max() - d.min())
        n, f, P = evaluated_counts(obj)
        shown = sign * P.reshape(-1, 8, 3).mean(axis=1)[:, "XYZ".index(axis[-1])]
        eps = 1e-5  # Geometry Nodes compares in single precision: a cell on the plane may go either way
        assert np.sum(d < plane - eps) <= len(shown) <= np.sum(d < plane + eps) and 0 < len(shown) < m
        assert (n, f) == (8 * len(shown), 6 * len(shown)) and shown.max() < plane + eps
    s.hex_fall_away = 1.0
    assert evaluated_counts(obj)[:2] == (0, 0)
    s.hex_fall_away = 0.0
    assert evaluated_counts(obj)[:2] == (8 * m, 6 * m)
    # the irregular edges follow: an edge whose midpoint lies beyond the plane gets radius 0
    cu = output(hex_mesh.EDGES_ROLE).data

    def radii():
        r = np.empty(2 * len(cu.splines), np.float32)
        for k, sp in enumerate(cu.splines):
            sp.points.foreach_get("radius", r[2 * k: 2 * k + 2])
        return r.reshape(-1, 2)[:, 0]

    assert np.all(radii() == 1.0)
    s.hex_axis, s.hex_fall_away = "Z", 0.5
    mids = np.array([0.5 * (np.array(sp.points[0].co[:3]) + np.array(sp.points[1].co[:3])) for sp in cu.splines])
    plane = centres[:, 2].min() + 0.5 * (centres[:, 2].max() - centres[:, 2].min())
    hidden = radii() == 0.0
    assert 0 < hidden.sum() < len(hidden)
    assert np.all(mids[hidden, 2] >= plane - 1e-5) and np.all(mids[~hidden, 2] < plane + 1e-5)
    s.hex_fall_away = 0.0
    assert np.all(radii() == 1.0)
    # Show Below: only the cells whose scaled Jacobian is at most the value
    sj = cyl.hm.scaled_jacobian
    below = float(np.quantile(sj, 0.3))
    s.hex_show_below = below
    n, f, P = evaluated_counts(obj)
    eps = 1e-6  # single precision in Geometry Nodes
    assert np.sum(sj <= below - eps) <= n // 8 <= np.sum(sj <= below + eps) and 0 < n // 8 < m
    s.hex_show_below = 1.0
    assert evaluated_counts(obj)[:2] == (8 * m, 6 * m)


@pytest.mark.slow
@pytest.mark.mesher
def test_panel_shows_the_verdict_and_figures(cyl):
    reopen(cyl)
    drawn = draw_hex_panel()
    r = cyl.report
    assert "symframes.hex_mesh" in drawn.operators and "symframes.export_hex_mesh" in drawn.operators
    assert "symframes.apply_hex_preset" in drawn.operators
    assert {"hex_cell_size", "hex_cells", "hex_smooth", "hex_explode", "hex_fall_away", "hex_axis",
            "hex_show_below"} <= set(drawn.props)
    assert "Scaled Jacobian per cell" in drawn.texts and any(t.startswith("Colors: red ") for t in drawn.texts)
    assert "Valid hex mesh" in drawn.texts
    assert f"Hexahedra {r.hexes:,}   vertices {r.vertices:,}" in drawn.texts
    assert f"Scaled Jacobian min {r.sj_min:.3f}   mean {r.sj_mean:.3f}" in drawn.texts
    assert f"Irregular edges: {r.irregular[3]} of valence 3" in drawn.texts
    assert "   exactly the prescribed curves" in drawn.texts
    assert f"Hausdorff distance {100 * r.hausdorff_relative:.2f}% of the diagonal" in drawn.texts
    assert (f"   {100 * r.size_within:.0f}% of cells within 20% of it; 5-95%: {r.size_p5:.2f}-{r.size_p95:.2f} of it"
            in drawn.texts)


def test_panel_before_a_field_and_the_operators_polls():
    drawn = draw_hex_panel()
    assert "Compute a field first" in drawn.texts and "Valid hex mesh" not in drawn.texts
    assert not bpy.ops.symframes.hex_mesh.poll()
    assert not bpy.ops.symframes.export_hex_mesh.poll()
    for preset, cells in properties.HEX_PRESETS.items():
        scene().symframes.hex_cell_size = 0.5
        assert bpy.ops.symframes.apply_hex_preset(preset=preset) == {"FINISHED"}
        assert (scene().symframes.hex_cells, scene().symframes.hex_cell_size) == (cells, 0.0)
    assert properties.HEX_PRESETS["MEDIUM"] == scene().symframes.bl_rna.properties["hex_cells"].default == 3000


def test_menus_reach_the_hex_operators():
    exports = [e[0] for e in menus.EXPORT_ENTRIES]
    assert "symframes.export_hex_mesh" in exports
    assert ("symframes.hex_mesh", "MESH_CUBE") in menus.OBJECT_ENTRIES
    layout = Layout()
    menus.SYMFRAMES_MT_object.draw(SimpleNamespace(layout=layout), bpy.context)
    assert {"symframes.hex_mesh"} <= set(layout.operators)


# ------------------------------------------------------ failure and cancel
def _refused(op, pattern, **kw):
    with pytest.raises(RuntimeError, match=pattern):
        op(**kw)


@pytest.mark.slow
@pytest.mark.mesher
def test_a_refused_run_leaves_the_scene_unchanged(cyl):
    reopen(cyl)
    before = scene_state()
    scene().symframes.hex_cell_size = 10.0  # larger than the solid
    _refused(bpy.ops.symframes.hex_mesh, "cell size 10 \\(the one given\\) is larger than half the solid's smallest")
    assert scene_state() == before
    # also on the stored field (a reopened file): the same refusal, nothing written
    job.forget_results()
    _refused(bpy.ops.symframes.hex_mesh, "cell size 10 \\(the one given\\) is larger than half")
    assert scene_state() == before


@pytest.mark.slow
@pytest.mark.mesher
def test_finer_near_a_patch_from_the_panel(cyl):
    """Finer Near: a patch the field lacks is refused before the job, the
    scene unchanged; a patch it has (the cylinder's bottom cap, 2) gives
    more, thinner cells there, and the stored report says where."""
    reopen(cyl)
    before = scene_state()
    s = scene().symframes
    s.hex_finer_near = "patch 9"
    _refused(bpy.ops.symframes.hex_mesh, "the surface has 3 patches .* not patch 9")
    assert scene_state() == before
    s.hex_finer_near, s.hex_finer_ratio = "patch 2", 0.5
    assert bpy.ops.symframes.hex_mesh() == {"FINISHED"}
    rep = hex_mesh.stored_report(scene())
    assert rep.status == "valid" and rep.hexes > cyl.report.hexes, rep.summary()
    assert "patch 2 (cells 0.5 of the cell size there" in rep.finer_near


@pytest.mark.slow
@pytest.mark.mesher
def test_finer_near_from_the_selected_faces(cyl):
    """Finer Near Selected Faces: the patches of the domain's selected faces
    (the cylinder's bottom cap and its side: 2 and 1), the curves already
    named kept; with nothing selected it says what to do and changes
    nothing."""
    reopen(cyl)
    s = scene().symframes
    dom = s.domain
    for p in dom.data.polygons:
        p.select = False
    s.hex_finer_near = "curve 1"
    _refused(bpy.ops.symframes.finer_near_selected, "no face of .* is selected: select faces of the solid in Edit "
                                                    "Mode")
    assert s.hex_finer_near == "curve 1"
    M = dom.matrix_world
    for p in dom.data.polygons:
        n = (M.to_3x3() @ p.normal).normalized()
        p.select = n.z < -0.9 or abs(n.z) < 0.1 and p.index % 7 == 0  # the bottom cap and a few side faces
    assert bpy.ops.symframes.finer_near_selected() == {"FINISHED"}
    assert s.hex_finer_near == "patch 1, patch 2, curve 1"
@pytest.mark.slow
@pytest.mark.mesher
def test_cancel_leaves_the_scene_unchanged(cyl):
    reopen(cyl)
    before = scene_state()
    scene().symframes.hex_cell_size = 0.0
    j = job.HexJob(source=operators.hex_source(bpy.context), options=HexOptions(target_hexes=cyl.report.hexes))
    progress, seen = j._progress, []

    def cancel_at_the_map(stage, fraction, message):
        seen.append(stage)
        progress(stage, fraction, message)
        if stage == "seamless map":
            j.cancel()  # cancelled while hexmesh runs: it stops at the next check

    j._progress = cancel_at_the_map
    j.start()
    j.join(120)
    assert j.done and j.cancelled and j.outcome is None and j.error is None
    assert "seamless map" in seen and "extraction" not in seen
    assert operators.finish_hex_job(scene(), j)[0] == "WARNING"
    assert scene_state() == before


@pytest.mark.slow
@pytest.mark.mesher
def test_a_changed_network_is_refused_on_a_stored_field(cyl):
    reopen(cyl, new_session=True)
    before = scene_state()
    curve = next(o for o in scene().symframes.network.all_objects if o.type == "CURVE")
    curve.symframes.index = -1
    _refused(bpy.ops.symframes.hex_mesh, "changed since the field was computed")
    assert scene_state() == before


def _scale_domain():
    scene().symframes.domain.scale = (1.2, 1.2, 1.2)
    bpy.context.view_layer.update()


def _network_curve():
    return next(o for o in scene().symframes.network.all_objects if o.type == "CURVE")


def _change_index():
    _network_curve().symframes.index = -1


def _delete_curve():
    bpy.data.objects.remove(_network_curve())


@pytest.mark.slow
@pytest.mark.mesher
@pytest.mark.parametrize("edit, what", [
    (_scale_domain, r"the domain '[^']+' was moved, scaled or edited"),
    (_change_index, r"curve '[^']+' has index -1/4, was \+1/4"),
    (_delete_curve, r"curve '[^']+' was removed or renamed"),
])
def test_a_stale_field_is_refused_within_the_session(cyl, edit, what):
    """The session still holds the solve's Result, yet after scaling the
    domain, changing a curve's index or deleting a curve Hex Mesh refuses
    with what changed (the inputs key of a reopened file), and the scene is
    unchanged; the inputs as solved give the session's Result."""
    reopen(cyl)
    assert operators.hex_source(bpy.context) == cyl.field  # nothing changed: the solve's field
    edit()
    before = scene_state()
    _refused(bpy.ops.symframes.hex_mesh, "changed since the field was computed .*" + what)
    assert scene_state() == before


# ------------------------------------------------------------ the stored field
@pytest.mark.slow
@pytest.mark.mesher
def test_hex_mesh_of_the_stored_field_in_a_thread(cyl):
    """A reopened file: the field is read back whole from the .blend, the
    network as its solve traced it included, and gives the same hex mesh."""
    reopen(cyl, new_session=True)
    source = operators.hex_source(bpy.context)
    assert source == cyl.field
    j = job.HexJob(source=source, options=HexOptions(target_hexes=scene().symframes.hex_cells))
    j.start()
    j.join(300)
    assert j.done and j.error is None, j.error
    r = j.outcome.hex_mesh.report
    assert r.status == "valid" and r.hexes == cyl.report.hexes and r.irregular == cyl.report.irregular
    assert r.sj_min == pytest.approx(cyl.report.sj_min, abs=1e-9)  # the field kept in full precision
    output(hex_mesh.ROLE).show_wire = False  # the user's choice, kept when the mesh is replaced
    level, msg = operators.finish_hex_job(scene(), j)
    assert level == "INFO" and f"{r.hexes:,} hexahedra" in msg and "exactly the prescribed curves" in msg
    obj = output(hex_mesh.ROLE)
    assert not obj.show_wire
    assert obj.data[hex_mesh.HEX_ID_KEY] == j.outcome.hex_id and obj.data.name == hex_mesh.OBJECT_NAME
    assert len([o for o in bpy.data.objects if o.get(storage.ROLE_KEY) == hex_mesh.ROLE]) == 1  # replaced
    # a defective mesh is written all the same, and said to be
    r.status, r.reason = "defective", "the irregular edges are not exactly the prescribed curves"
    level, msg = operators.finish_hex_job(scene(), j)
    assert level == "WARNING" and msg.endswith("defective: the irregular edges are not exactly the prescribed curves")
    assert "Defective hex mesh" in draw_hex_panel().texts


def _map_fails_on(monkeypatch, fields: list, finer: bool = True) -> list:
    """job.hexmesh raising the map's HexMeshError (a limit of SymFrames,
    as two nodes closer than the field's mesh resolves; ``finer``: whether
    a finer field may mesh) on the fields in ``fields``, and meshing any
    other; returns the fields it was given."""
    from symframes.solver import HexMeshError

    seen, real = [], job.hexmesh

    def hexmesh(field, **kw):
        seen.append(field)
        if any(field == f for f in fields):
            raise HexMeshError("nodes 1 and 5 are too close for the field's mesh: solve the field on a finer mesh",
                               kind="map", finer=finer)
        return real(field, **kw)

    monkeypatch.setattr(job, "hexmesh", hexmesh)
    return seen


@pytest.mark.slow
@pytest.mark.mesher
def test_a_map_failure_on_a_set_edge_length_says_what_to_change(cyl, monkeypatch):
    """The Edge Length set by hand: SymFrames does not solve finer by
    itself; the error says so, with a smaller edge length to set, and the
    scene is unchanged."""
    reopen(cyl)
    before = scene_state()
    s = scene().symframes
    assert not s.auto_resolution and s.edge_length == pytest.approx(EDGE_LENGTH)
    seen = _map_fails_on(monkeypatch, [operators.hex_source(bpy.context)])
    _refused(bpy.ops.symframes.hex_mesh, r"too close for the field's mesh.*The Edge Length 0.4 is set by hand, "
                                         r"so SymFrames does not solve finer by itself: set a smaller one \(e.g. "
                                         r"0.28, the step solve_finer takes\) or turn Auto on")
    assert len(seen) == 1 and scene_state() == before


@pytest.mark.slow
@pytest.mark.mesher
def test_a_map_failure_with_auto_resolution_solves_the_field_again_finer(registered, monkeypatch):
    """Auto resolution: where the map fails on the stored field, Hex Mesh
    solves the field again finer (solver.solve_finer, as the command line's
    --hex does), meshes that field and stores it in place of the first, with
    the glyphs sampled again; the message says so."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.symframes.add_example(example="cube")
    s = scene().symframes
    s.auto_resolution, s.target_tets, s.glyph_count = True, 2000, 200
    assert bpy.ops.symframes.compute() == {"FINISHED"}
    first = storage.solved_field(scene())
    first_report = storage.stored_report(scene())
    assert bpy.ops.symframes.apply_hex_preset(preset=HEX_PRESET) == {"FINISHED"}
    # where a finer field cannot help (a smooth handle without curves): refused at once, the scene unchanged
    before = scene_state()
    seen = _map_fails_on(monkeypatch, [operators.hex_source(bpy.context)], finer=False)
    _refused(bpy.ops.symframes.hex_mesh, "too close for the field's mesh: solve the field on a finer mesh$")
    assert len(seen) == 1 and scene_state() == before
    seen = _map_fails_on(monkeypatch, [operators.hex_source(bpy.context)])
    assert bpy.ops.symframes.hex_mesh() == {"FINISHED"}
    assert len(seen) == 2 and seen[1] != seen[0]
    again = storage.solved_field(scene())
    report = storage.stored_report(scene())
    assert again != first and again.mesh.n_tets > first.mesh.n_tets
    assert report.converged and report.edge_length == pytest.approx(0.7 * first_report.edge_length)
    assert any("solved again on a uniform mesh" in n and "for the hex mesh" in n for n in report.notes)
    assert operators.hex_source(bpy.context) == again  # the field of the scene's inputs: Hex Mesh meshes it next
    assert output("glyphs") is not None and not output("glyphs").visible_get()  # sampled again, hidden under the hex
    hm = job.cached_hex(output(hex_mesh.ROLE).data[hex_mesh.HEX_ID_KEY])
    assert hm.report.status == "valid" and len(hm.hexes) == hex_mesh.stored_report(scene()).hexes


@pytest.mark.slow
@pytest.mark.mesher
def test_the_field_keeps_its_solve_exactly(ball, tmp_path):
    """The arrays of SolvedField.to_arrays come back from the .blend as the
    solve made them (dtypes aside: integers as int64), and the field read
    back from the .blend equals the one read back from a result file."""
    reopen(ball, new_session=True)
    kept = storage.decode_arrays(scene().symframes.field[storage.FIELD_KEY])
    assert sorted(kept) == sorted(ball.source)
    for key, a in ball.source.items():
        a = np.asarray(a)
        assert kept[key].shape == a.shape, key
        if a.dtype.kind in "US":
            assert str(kept[key]) == str(a)
        else:
            np.testing.assert_array_equal(kept[key], a, err_msg=key)
    assert json.loads(str(kept["meta"]))["nodes"]  # the ball's nodes, as the solve prepared them
    f = storage.solved_field(scene())
    assert f == ball.field
    path = str(tmp_path / "ball.npz")
    sio.save_field(path, f)
    g = sio.load_field(path)
    assert g == f
    a, b = hexmesh_of(f), hexmesh_of(g)
    np.testing.assert_array_equal(a.hexes, b.hexes)
    np.testing.assert_array_equal(a.vertices, b.vertices)


@pytest.mark.slow
@pytest.mark.mesher
def test_ball_from_a_reopened_file_gives_the_sessions_hex_mesh(ball):
    """Curves meeting at nodes: the solve's node regions come from the file,
    nothing is traced again, and the hex mesh is the session's."""
    r0 = ball.report
    assert r0.status == "valid" and r0.structure_exact and r0.irregular.get(3, 0) > 0, r0.summary()
    reopen(ball, new_session=True)
    assert operators.hex_source(bpy.context) == ball.field
    assert bpy.ops.symframes.hex_mesh() == {"FINISHED"}
    obj = output(hex_mesh.ROLE)
    hm = job.cached_hex(obj.data[hex_mesh.HEX_ID_KEY])
    r = hm.report
    assert r.status == "valid", r.summary()
    assert (r.hexes, r.vertices, r.irregular, r.structure_exact) == (r0.hexes, r0.vertices, r0.irregular, True)
    np.testing.assert_array_equal(hm.hexes, ball.hm.hexes)
    np.testing.assert_array_equal(hm.irregular_edges, ball.hm.irregular_edges)
    np.testing.assert_array_equal(hm.irregular_valence, ball.hm.irregular_valence)
    # the field is kept in full precision: the same map, the same smoothed vertices
    np.testing.assert_allclose(hm.vertices, ball.hm.vertices, atol=1e-9 * r0.cell_size)
    assert r.sj_min == pytest.approx(r0.sj_min, abs=1e-9)
    assert list(output(hex_mesh.EDGES_ROLE).data[hex_mesh.VALENCE_KEY]) == ball.hm.irregular_valence.tolist()


@pytest.mark.slow
@pytest.mark.mesher
def test_a_field_without_its_arrays_is_refused(cyl):
    """A field whose stored arrays are damaged, or that keeps none (stored by
    an earlier SymFrames): compute it again; nothing is traced, nothing
    written."""
    reopen(cyl, new_session=True)
    field = scene().symframes.field
    before = scene_state()
    group = field[storage.FIELD_KEY]
    group["curve_tets"] = np.zeros(3, np.int32)  # Blender writes the first 3 values: a walk that is not one
    storage._FIELD_CACHE.clear()  # the field was edited behind the add-on's back
    _refused(bpy.ops.symframes.hex_mesh, "curve 0: its face .* does not lie between the tets.*compute the field again")
    del group["curve_tets"]  # an array of the layout missing
    storage._FIELD_CACHE.clear()
    _refused(bpy.ops.symframes.hex_mesh, "not as Compute Field wrote them .*'curve_tets'.*compute the field again")
    del field[storage.FIELD_KEY]
    storage._FIELD_CACHE.clear()
    _refused(bpy.ops.symframes.hex_mesh, "stored by an earlier SymFrames.*compute the field again")
    assert scene_state() == before


def hexmesh_of(field):
    from symframes.solver import hexmesh

    return hexmesh(field, target_hexes=properties.HEX_PRESETS[HEX_PRESET])


def test_arrays_kept_as_id_properties_round_trip():
    """storage.encode_arrays / decode_arrays through a datablock's ID
    properties: floats in double precision, integers, booleans, empty arrays
    and shapes, one string; what cannot be kept is refused."""
    arrays = {"f": np.random.default_rng(1).random((4, 3)), "i": np.arange(-3, 5, dtype=np.int64).reshape(2, 4),
              "b": np.array([True, False, True]), "e": np.zeros((0, 3)), "ei": np.zeros(0, np.int64),
              "s": np.array(json.dumps({"x": [1, 2]}))}
    me = bpy.data.meshes.new("kept")
    me["group"] = storage.encode_arrays(arrays)
    back = storage.decode_arrays(me["group"])
    assert sorted(back) == sorted(arrays)
    for key, a in arrays.items():
        assert back[key].shape == a.shape and back[key].dtype.kind == a.dtype.kind, key
        np.testing.assert_array_equal(back[key], a)
    with pytest.raises(ValueError, match="beyond 32-bit"):
        storage.encode_arrays({"big": np.array([2**40])})
    with pytest.raises(ValueError, match="compute the field again"):
        storage.decode_arrays({"layout": "{not json"})


# ------------------------------------------------------------------ export
@pytest.mark.slow
@pytest.mark.mesher
def test_export_writes_what_meshio_reads(cyl, tmp_path):
    reopen(cyl)
    hm = cyl.hm
    path = tmp_path / "cyl.vtu"
    assert bpy.ops.symframes.export_hex_mesh(filepath=str(path), file_format="VTU") == {"FINISHED"}
    m = meshio.read(str(path))
    assert m.cells_dict["hexahedron"].shape == (cyl.report.hexes, 8)
    np.testing.assert_array_equal(m.cells_dict["hexahedron"], hm.hexes)
    np.testing.assert_allclose(m.points, hm.vertices)
    # the extension follows the format; in this session the integer-grid map is there
    assert bpy.ops.symframes.export_hex_mesh(filepath=str(tmp_path / "cyl.vtu"), file_format="HEXEX") == {"FINISHED"}
    assert (tmp_path / "cyl.hexex").exists()
    # the simulation formats, with the boundary patches of the hex mesh made in this session
    # (the cylinder: its side and two caps)
    assert bpy.ops.symframes.export_hex_mesh(filepath=str(tmp_path / "cyl.inp"), file_format="INP") == {"FINISHED"}
    inp = (tmp_path / "cyl.inp").read_text()
    assert inp.count("*ELEMENT, TYPE=C3D8") == 1 and inp.count("*SURFACE, NAME=S_PATCH_") == 3
    assert bpy.ops.symframes.export_hex_mesh(filepath=str(tmp_path / "cyl.msh"), file_format="MSH") == {"FINISHED"}
    assert '2 3 "patch_3"' in (tmp_path / "cyl.msh").read_text()


@pytest.mark.slow
@pytest.mark.mesher
def test_a_moved_hex_object_is_exported_where_it_is(cyl, tmp_path):
    """The hex object moved, scaled and mirrored after it was made: the
    export writes it where it stands (the object's transform applied, said in
    the message), with no cell inside out; the .hexex map is refused for a
    mirror."""
    reopen(cyl)
    hm = cyl.hm
    obj = output(hex_mesh.ROLE)
    obj.location = (1.0, 2.0, 3.0)
    obj.scale = (2.0, -1.0, 1.0)
    bpy.context.view_layer.update()
    path = tmp_path / "moved.vtu"
    assert bpy.ops.symframes.export_hex_mesh(filepath=str(path), file_format="VTU") == {"FINISHED"}
    m = meshio.read(str(path))
    want = hm.vertices * [2.0, -1.0, 1.0] + [1.0, 2.0, 3.0]
    np.testing.assert_allclose(m.points, want, atol=1e-5)
    sj = m.cell_data["scaled_jacobian"][0]
    assert sj.min() > 0 and len(sj) == len(hm.hexes)  # the corners reordered: not inside out
    _refused(bpy.ops.symframes.export_hex_mesh, "mirrored", filepath=str(tmp_path / "moved.hexex"),
             file_format="HEXEX")
    obj.location, obj.scale = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)
    bpy.context.view_layer.update()


@pytest.mark.slow
@pytest.mark.mesher
def test_reopened_file_exports_vtu_and_refuses_hexex(cyl, tmp_path):
    reopen(cyl, new_session=True)
    hm = cyl.hm
    # the boundary patches are kept in the .blend (a face attribute and their names, which the user may
    # edit): the simulation formats carry them after reopening too, with the names as edited
    me = output(hex_mesh.ROLE).data
    assert list(me[hex_mesh.PATCH_NAMES_KEY]) == hm.patches.names
    me[hex_mesh.PATCH_NAMES_KEY] = ["side", "bottom", "top"][: len(hm.patches.names)]
    assert bpy.ops.symframes.export_hex_mesh(filepath=str(tmp_path / "again.inp"), file_format="INP") == {"FINISHED"}
    inp = (tmp_path / "again.inp").read_text()
    assert inp.count("*SURFACE, NAME=S_") == len(hm.patches.names) and "*NSET, NSET=BOTTOM" in inp
    me[hex_mesh.PATCH_NAMES_KEY] = hm.patches.names
    for fmt, ext, cell in (("VTU", ".vtu", "hexahedron"), ("MESH", ".mesh", "hexahedron")):
        path = tmp_path / f"again{ext}"
        assert bpy.ops.symframes.export_hex_mesh(filepath=str(path), file_format=fmt) == {"FINISHED"}
        m = meshio.read(str(path))
        np.testing.assert_array_equal(m.cells_dict[cell], hm.hexes)
        np.testing.assert_allclose(m.points, hm.vertices, atol=1e-6)  # as Blender keeps them: single precision
    sj = meshio.read(str(tmp_path / "again.vtu")).cell_data["scaled_jacobian"][0]
    np.testing.assert_allclose(sj, hm.scaled_jacobian, atol=1e-6)
    _refused(bpy.ops.symframes.export_hex_mesh, "make the hex mesh again to write its integer-grid map",
             filepath=str(tmp_path / "map.hexex"), file_format="HEXEX")
    assert not (tmp_path / "map.hexex").exists()


@pytest.mark.slow
@pytest.mark.mesher
def test_an_edited_hex_object_is_refused_for_export(cyl, tmp_path):
    reopen(cyl, new_session=True)
    me = output(hex_mesh.ROLE).data
    me.attributes.remove(me.attributes[hex_mesh.VERTEX_ATTRIBUTE])
    _refused(bpy.ops.symframes.export_hex_mesh, "make the hex mesh again", filepath=str(tmp_path / "x.vtu"),
             file_format="VTU")
    assert not (tmp_path / "x.vtu").exists()


def test_export_formats_are_the_solvers():
    from symframes.solver.io import HEX_FORMATS

    assert sorted(exchange.HEX_EXTENSION.values()) == sorted(HEX_FORMATS)


@pytest.mark.slow
@pytest.mark.mesher
def test_hex_only_hides_the_field_objects_and_shows_them_again(cyl):
    """Hex Mesh turns Hex Only on: the domain, the network curves and the
    field's outputs are hidden while the hex mesh is shown; off shows again
    exactly what it hid (an object the user had hidden stays hidden)."""
    reopen(cyl)
    s = scene().symframes
    field = hex_mesh.field_objects(scene())
    assert s.domain in field and len(field) > 1
    s.hex_only = False
    assert all(o.visible_get() for o in field)
    s.network.all_objects[0].hide_set(True)  # the user's own choice
    s.hex_only = True
    assert not any(o.visible_get() for o in field)
    assert output(hex_mesh.ROLE).visible_get() and output(hex_mesh.EDGES_ROLE).visible_get()
    s.hex_only = False
    assert not s.network.all_objects[0].visible_get()
    assert all(o.visible_get() for o in field if o != s.network.all_objects[0])
    s.network.all_objects[0].hide_set(False)


# ------------------------------------------------------------------- clear
@pytest.mark.slow
@pytest.mark.mesher
def test_clear_removes_the_hex_mesh_and_its_helpers(cyl):
    reopen(cyl)
    assert output(hex_mesh.ROLE) is not None and output(hex_mesh.EDGES_ROLE) is not None
    assert bpy.ops.symframes.clear() == {"FINISHED"}
    assert output(hex_mesh.ROLE) is None and output(hex_mesh.EDGES_ROLE) is None
    assert hex_mesh.NODE_GROUP not in bpy.data.node_groups
    left = [m.name for m in bpy.data.materials if m.name.startswith((hex_mesh.SJ_MATERIAL, "SymFrames Valence"))]
    assert left == []
    assert scene_state()["hex"] is None
