"""The Blender add-on, driven through its operators with the bpy module.

The repository root is the extension's package, so the add-on is imported
from root __init__.py as the package ``symframes`` (its modules use
relative imports, as an installed extension does) and registered once per
module.  Every test starts from an empty factory scene.  Two solves are
shared (module fixtures, saved as .blend files and reopened per test): the
cube (sharp features only) and the plate (sharp features and four singular
curves, one of them a Bezier spline).  Coarse meshes keep them to seconds.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

from tests import addon_package
from tests.addon_package import load_addon

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

GLYPHS = 600
SEEDS = 25
HANG = 600  # seconds: a deadline that catches a hung solve, never a slow machine
CUBE_EDGE = 0.4
PLATE_EDGE = 0.2


addon = load_addon()
from symframes.solver import FieldProblem, check, regular_face_mask  # noqa: E402
from symframes.solver.analysis.measures import (  # noqa: E402
    matched_singular_faces,
    monodromy_angles,
    normal_adaptation,
    omega_singular_faces,
)
from symframes.solver.analysis.streamlines import FrameField  # noqa: E402
from symframes.solver.io import quaternion_frames  # noqa: E402
from symframes.symframes_addon import (  # noqa: E402
    diagnostics,
    display,
    error_slice,
    glyphs,
    job,
    omega_arrows,
    operators,
    scene_io,
    storage,
    streamline_curves,
)

registered = addon_package.registered  # fixtures shared by the add-on tests
empty_scene = addon_package.empty_scene


# ------------------------------------------------------------------ helpers
def scene():
    return bpy.context.scene


def add_example(name: str, edge_length: float | None = None):
    """The example at a hand-set edge length (its own coarse one by
    default, examples.EDGE_LENGTHS): quick solves, not the example's Auto."""
    bpy.ops.symframes.add_example(example=name)
    s = scene().symframes
    s.auto_resolution = False
    if edge_length is not None:
        s.edge_length = edge_length
    s.glyph_count = GLYPHS
    s.streamline_seeds = SEEDS
    s.streamline_family = "ALL"
    return s


def scene_state() -> dict:
    """Names of everything a result could add, change or leave behind."""
    s = scene().symframes
    return {
        "objects": sorted((o.name, o.type, o.data.name if o.data else "") for o in bpy.data.objects),
        "meshes": sorted(m.name for m in bpy.data.meshes),
        "curves": sorted(c.name for c in bpy.data.curves),
        "collections": sorted(c.name for c in bpy.data.collections),
        "node_groups": sorted(g.name for g in bpy.data.node_groups),
        "materials": sorted(m.name for m in bpy.data.materials),
        "field": s.field.name if s.field else None,
    }


def input_fingerprint() -> str:
    """Hash of the domain's and the network curves' geometry, transforms and settings."""
    bpy.context.view_layer.update()  # matrix_world of moved objects
    s = scene().symframes
    h = hashlib.sha1()
    objs = [s.domain] + (sorted(s.network.all_objects, key=lambda o: o.name) if s.network else [])
    for obj in objs:
        h.update(obj.name.encode())
        h.update(np.array(obj.matrix_world).tobytes())
        if obj.type == "MESH":
            co = np.empty(3 * len(obj.data.vertices))
            obj.data.vertices.foreach_get("co", co)
            h.update(co.tobytes())
            h.update(str(len(obj.data.polygons)).encode())
        else:
            for sp in obj.data.splines:
                pts = sp.points if sp.type == "POLY" else sp.bezier_points
                co = np.empty((4 if sp.type == "POLY" else 3) * len(pts))
                pts.foreach_get("co", co)
                h.update(co.tobytes())
            h.update(repr((obj.symframes.index, obj.symframes.role, obj.symframes.torsion)).encode())
    return h.hexdigest()


def singular_mask(mesh, frames) -> np.ndarray:
    """solver.analysis.measures.matched_singular_faces' mask (it may also return the failures)."""
    found = matched_singular_faces(mesh, frames)
    return np.asarray(found[0] if isinstance(found, tuple) else found, bool)


def output(role):
    return storage.output_object(scene(), role)


def polylines(obj):
    return streamline_curves.streamline_polylines(obj)


def open_blend(path):
    bpy.ops.wm.open_mainfile(filepath=str(path))


def solve_example(name, edge_length, tmp_path_factory, prepare=None):
    """Solve an example with glyphs and streamlines, save it; returns what
    the tests compare against."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    s = add_example(name, edge_length)
    if prepare is not None:
        prepare(s)
    before = input_fingerprint()
    assert bpy.ops.symframes.compute(streamlines=True) == {"FINISHED"}
    inputs = scene_io.read_inputs(bpy.context)
    meshed = job.cached_mesh(inputs.mesh_key())
    assert meshed is not None, "the tet mesh of the last solve is kept for re-solves"
    mesh = meshed.mesh
    P, Q = glyphs.glyph_points(output("glyphs"))
    ns = SimpleNamespace(
        inputs_before=before, inputs_after=input_fingerprint(), inputs=inputs, mesh=mesh,
        glyph_points=P.copy(), glyph_quats=Q.copy(), lines=[p.copy() for p in polylines(output("streamlines"))],
        report=storage.stored_report(scene()),
    )
    ns.path = tmp_path_factory.mktemp(name) / f"{name}.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(ns.path))
    return ns


@pytest.fixture(scope="module")
def cube(registered, tmp_path_factory):
    return solve_example("cube", CUBE_EDGE, tmp_path_factory)


def _bezier_hole_curve(s):
    """Replace the plate's curve 'hole 0' by a Bezier spline along the same
    segment (vector handles: straight), to solve through the Bezier path."""
    obj = bpy.data.objects["hole 0"]
    P = scene_io.spline_points(obj.data.splines[0], obj.matrix_world)
    cu = obj.data
    cu.splines.clear()
    sp = cu.splines.new("BEZIER")
    sp.bezier_points.add(1)
    for bp, x in zip(sp.bezier_points, (P[0], P[-1])):
        bp.co = x
        bp.handle_left_type = bp.handle_right_type = "VECTOR"
    cu.splines[0].resolution_u = 4


@pytest.fixture(scope="module")
def plate(registered, tmp_path_factory):
    return solve_example("plate", PLATE_EDGE, tmp_path_factory, prepare=_bezier_hole_curve)


# ------------------------------------------------------------- registration
def test_register_unregister_repeatedly():
    names = [c.__name__ for c in operators.CLASSES]
    for _ in range(3):
        addon.unregister()
        assert not hasattr(bpy.types.Scene, "symframes")
        assert not hasattr(bpy.types.Object, "symframes")
        assert not any(hasattr(bpy.types, n) for n in names)
        addon.register()
        assert hasattr(bpy.types.Scene, "symframes") and hasattr(bpy.types.Object, "symframes")
        assert all(hasattr(bpy.types, n) for n in names)
    # still fully usable
    add_example("cube")
    assert bpy.ops.symframes.check_network() == {"FINISHED"}


def test_operators_are_searchable_and_undoable():
    for cls in operators.CLASSES:
        op = getattr(bpy.ops.symframes, cls.bl_idname.split(".")[1])
        rna = op.get_rna_type()
        assert rna.name and rna.description, cls.__name__  # shown in F3 search and tooltips
        if cls is not operators.SYMFRAMES_OT_check_network:  # the one that changes no data
            assert "UNDO" in cls.bl_options, cls.__name__


def test_panel_lives_in_sidebar_tab():
    from symframes.symframes_addon import panel

    for cls in panel.CLASSES:
        if issubclass(cls, bpy.types.Panel):  # not the curve list
            assert (cls.bl_space_type, cls.bl_region_type, cls.bl_category) == ("VIEW_3D", "UI", "SymFrames")


# --------------------------------------------------------------------- inputs
def test_read_network_curves_settings_and_nodes():
    s = add_example("ball")
    inp = scene_io.read_inputs(bpy.context)
    assert len(inp.network.curves) == 20
    assert all(c.sigma == 0.25 and c.role.value == "singular" for c in inp.network.curves)
    assert "20 curve(s)" in inp.network_note
    assert check(inp.V, inp.F, inp.network).nodes == 8
    # per-curve settings: role feature -> sigma 0 whatever the index; torsion passed on
    obj = bpy.data.objects["radial 0"]
    obj.symframes.role = "feature"
    obj.symframes.torsion = "fixed"
    c = next(c for c in scene_io.read_inputs(bpy.context).network.curves if c.name == "radial 0")
    assert (c.sigma, c.role.value, c.torsion.value) == (0.0, "feature", "fixed")
    s.node_tolerance = 0.05
    assert scene_io.read_inputs(bpy.context).network.node_tolerance == pytest.approx(0.05)


def test_bezier_spline_is_resampled_along_the_curve():
    cu = bpy.data.curves.new("bez", "CURVE")
    cu.dimensions = "3D"
    sp = cu.splines.new("BEZIER")
    sp.resolution_u = 12
    sp.bezier_points.add(1)
    a, b = sp.bezier_points
    a.co, a.handle_right = (0, 0, 0), (1, 0, 0)
    b.co, b.handle_left = (1, 1, 0), (1, 0.5, 0)
    obj = bpy.data.objects.new("bez", cu)
    obj.location = (0, 0, 2)
    bpy.context.scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    P = scene_io.spline_points(sp, obj.matrix_world)
    assert len(P) == 13
    t = np.linspace(0, 1, 13)[:, None]
    c0, c1, c2, c3 = (np.array(x, float) for x in ((0, 0, 0), (1, 0, 0), (1, 0.5, 0), (1, 1, 0)))
    exact = (1 - t) ** 3 * c0 + 3 * (1 - t) ** 2 * t * c1 + 3 * (1 - t) * t**2 * c2 + t**3 * c3
    np.testing.assert_allclose(P, exact + [0, 0, 2], atol=1e-6)
    R = scene_io.resample(P, 0.01)
    assert np.linalg.norm(np.diff(R, axis=0), axis=1).max() <= 0.01 + 1e-12


def test_marked_sharp_edges_are_read():
    s = add_example("cube")
    s.use_sharp_angle = False
    me = s.domain.data
    me.attributes.new("sharp_edge", "BOOLEAN", "EDGE")
    V = np.array([v.co for v in me.vertices])
    E = np.array([e.vertices[:] for e in me.edges])
    # the cube's 12 edges: both ends on a box edge (two coordinates at +-1)
    on_edge = (np.abs(np.abs(V) - 1) < 1e-9).sum(axis=1) >= 2
    mark = on_edge[E].all(axis=1) & (np.abs(V[E[:, 0]] - V[E[:, 1]]) > 1e-9).sum(axis=1) == 1
    me.attributes["sharp_edge"].data.foreach_set("value", mark)
    inp = scene_io.read_inputs(bpy.context)
    assert inp.network.sharp_angle is None
    assert len(inp.network.sharp_edges) == mark.sum() == 24
    assert bpy.ops.symframes.check_network() == {"FINISHED"}


def test_a_curve_drawn_past_the_surface_in_two_strokes_is_repaired(capsys):
    """Hand-drawn: the cylinder's curve 'axial 0' as two splines of its
    object meeting end to end, the upper one running past the top cap.
    Check Network accepts it and says what the intake did: the strokes
    joined into one curve, the end cut back to the cap."""
    add_example("cylinder")
    cu = bpy.data.objects["axial 0"].data
    co = np.empty(4 * len(cu.splines[0].points))
    cu.splines[0].points.foreach_get("co", co)
    P = co.reshape(-1, 4)[:, :3]  # the object's own coordinates
    top = P[-1] + 0.1 * (P[-1] - P[-2]) / np.linalg.norm(P[-1] - P[-2])  # 0.1 past the cap: about 0.5 h
    mid = len(P) // 2
    cu.splines.clear()
    for part in (P[:mid + 1], np.vstack([P[mid:], top])):
        sp = cu.splines.new("POLY")
        sp.points.add(len(part) - 1)
        sp.points.foreach_set("co", np.c_[part, np.ones(len(part))].ravel())
    inp = scene_io.read_inputs(bpy.context)
    assert len(inp.network.curves) == 5
    assert bpy.ops.symframes.check_network() == {"FINISHED"}
    out = capsys.readouterr().out
    assert "(joined end to end from curves" in out and "end cut back" in out, out


# ---------------------------------------------------------------- bad input
def _fails(match, op=None):
    """op (default: compute) raises with a message matching match; nothing changes."""
    before, inputs = scene_state(), input_fingerprint() if scene().symframes.domain else None
    with pytest.raises(RuntimeError, match=match):
        (op or bpy.ops.symframes.compute)()
    assert scene_state() == before
    if inputs is not None:
        assert input_fingerprint() == inputs


def test_error_no_domain():
    s = add_example("cube")
    s.domain = None
    _fails("no domain: pick a closed mesh object as Domain")
    _fails("no domain", bpy.ops.symframes.check_network)


def test_error_domain_not_closed():
    import bmesh  # only importable once bpy is

    s = add_example("cube")
    bm = bmesh.new()
    bm.from_mesh(s.domain.data)
    bm.faces.ensure_lookup_table()
    bm.faces.remove(bm.faces[0])
    bm.to_mesh(s.domain.data)
    bm.free()
    _fails("not closed and manifold.*open boundary")


def test_error_domain_open_plane():
    """An open plane as the domain: named as an open sheet, not as quads to triangulate (issue 43)."""
    s = add_example("cube")
    bpy.ops.mesh.primitive_plane_add(size=2)
    s.domain = bpy.context.active_object
    _fails("has 2 triangle\\(s\\), an open sheet such as a plane: it must be a closed surface")


def test_error_curve_outside_domain():
    add_example("cylinder")
    bpy.data.objects["axial 0"].location.x += 3.0
    _fails("'axial 0'")


def test_error_resolution_past_the_limit():
    """The Edge Length slider's minimum on the cube asks for ~1e11 tets: refused
    before meshing, naming the estimate and the override, the scene unchanged."""
    s = add_example("cube", 1e-4)
    s.auto_resolution = False
    _fails(r"would have ~.* tets .*larger edge length")


def test_error_curve_object_without_splines():
    add_example("cylinder")
    cu = bpy.data.curves.new("empty", "CURVE")
    scene().symframes.network.objects.link(bpy.data.objects.new("empty curve", cu))
    _fails("'empty curve' in the network has no spline", bpy.ops.symframes.check_network)


def test_error_curve_leaves_domain():
    add_example("cylinder")
    obj = bpy.data.objects["axial 0"]
    sp = obj.data.splines[0]
    co = np.empty(4 * len(sp.points))
    sp.points.foreach_get("co", co)
    co = co.reshape(-1, 4)
    xy = co[len(co) // 2, :2]
    co[len(co) // 2, :2] = 2.0 * xy / np.linalg.norm(xy)  # a bulge straight out through the cylinder wall
    sp.points.foreach_set("co", co.ravel())
    _fails("'axial 0' passes outside the solid")


def test_error_poincare_hopf():
    add_example("cylinder")
    bpy.data.objects["axial 0"].symframes.index = 2
    _fails("Poincare-Hopf is violated")


def test_error_empty_network():
    s = add_example("ball")
    for obj in list(s.network.objects):
        s.network.objects.unlink(obj)
    _fails("Poincare-Hopf.*The network is empty: the network collection 'Ball Network' holds no curve objects")
    s.network = None
    _fails("The network is empty: no network collection is chosen")


def test_error_display_without_field():
    add_example("cube")
    for op in (bpy.ops.symframes.show_glyphs, bpy.ops.symframes.trace_streamlines,
               bpy.ops.symframes.show_singular_faces, bpy.ops.symframes.show_omega, bpy.ops.symframes.show_slice):
        _fails("no field computed yet", op)


def test_cancelled_solve_writes_nothing():
    s = add_example("cube", CUBE_EDGE)
    before = scene_state()
    j = job.SolveJob(scene_io.read_inputs(bpy.context), display.DisplaySettings.from_scene(scene()),
                     reuse_mesh=False)
    j.start()
    j.cancel()
    j.join(HANG)
    assert j.done and j.cancelled and j.outcome is None
    assert operators.finish_job(scene(), j)[0] == "WARNING"
    assert scene_state() == before and s.field is None


@pytest.mark.slow
@pytest.mark.mesher
def test_threaded_solve_then_finish():
    """The compute operator's modal path: the solve (meshing included) in a
    worker thread, the scene written on the main thread afterwards."""
    add_example("cube", CUBE_EDGE)
    j = job.SolveJob(scene_io.read_inputs(bpy.context), display.DisplaySettings.from_scene(scene()),
                     reuse_mesh=False)
    seen = []
    progress = j._progress
    j._progress = lambda *a: (seen.append(a[0]), progress(*a))
    j.start()
    j.join(HANG)
    assert j.done and j.error is None and not j.cancelled
    assert {"tetmesh", "volume3d", "integrate", "display"} <= set(seen)
    level, msg = operators.finish_job(scene(), j)
    assert level == "INFO" and "tets" in msg
    assert len(output("glyphs").data.vertices) == GLYPHS
    assert storage.stored_remeshed(scene()) is True
    # a solve that stopped without converging is written, but reported as a warning
    assert j.outcome.report.converged is True
    j.outcome.report.status = "not converged"
    j.outcome.report.status_reason = "Levenberg-Marquardt stopped after 30 iterations"
    level, msg = operators.finish_job(scene(), j)
    assert level == "WARNING" and "not converged (Levenberg-Marquardt stopped after 30 iterations)" in msg
    assert "Check Network" in msg and "Edge Length" in msg  # what to try


# ------------------------------------------------------------------ results
@pytest.mark.mesher
def test_compute_writes_field_glyphs_and_streamlines(cube):
    open_blend(cube.path)
    s = scene().symframes
    assert cube.inputs_after == cube.inputs_before, "compute must not modify its inputs"
    assert s.field is not None and s.field.users >= 1
    g, st = output("glyphs"), output("streamlines")
    assert g is not None and st is not None
    assert len(g.data.vertices) == GLYPHS
    # all three families from every seed; a line is dropped only if it cannot leave its seed
    n = len(st.data.splines)
    assert 0.9 * 3 * SEEDS <= n <= 3 * SEEDS
    assert sorted({sp.material_index for sp in st.data.splines}) == [0, 1, 2]
    assert st.data.bevel_depth == pytest.approx(s.streamline_radius)
    assert g.users_collection[0] == st.users_collection[0]
    assert g.users_collection[0].get(storage.ROLE_KEY) == "results"
    r = cube.report
    assert r.sizes["tets"] > 100 and r.lm.n_iterations >= 1 and r.total_seconds > 0
    assert r.metrics["spurious_singular_faces"] == 0
    assert r.metrics["monodromy_mean_deg"] < 1e-3


@pytest.mark.mesher
def test_field_attribute_equals_solver_frames(cube):
    """The stored 'frame' attribute is the solver's result on the same tet
    mesh, and every glyph's quaternion is the solver's interpolated frame."""
    open_blend(cube.path)
    inp = cube.inputs
    result = FieldProblem(inp.V, inp.F, inp.network, inp.options, mesh=cube.mesh).solve()
    sf = storage.solved_field(scene())
    np.testing.assert_array_equal(sf.mesh.vertices, cube.mesh.vertices)
    assert np.array_equal(sf.mesh.tets, cube.mesh.tets)
    np.testing.assert_allclose(sf.frames, result.frames, atol=1e-9)
    P, Q = glyphs.glyph_points(output("glyphs"))
    expect = FrameField.from_field(result).quaternions_at(P.astype(float))
    assert np.all(np.isfinite(expect[:, 0]))
    assert np.abs(np.einsum("ij,ij->i", Q, expect)).min() > 1 - 1e-5  # q and -q are one rotation


@pytest.mark.mesher
def test_glyph_instances_follow_the_quaternion_attribute(cube):
    open_blend(cube.path)
    s = scene().symframes
    s.glyph_size = 0.05  # live: no resampling
    g = output("glyphs")
    P, Q = glyphs.glyph_points(g)
    geo = g.evaluated_get(bpy.context.evaluated_depsgraph_get()).evaluated_geometry()
    inst = geo.instances_pointcloud()
    assert len(inst.points) == GLYPHS
    M = np.array([np.array(d.value) for d in inst.attributes["instance_transform"].data])
    np.testing.assert_allclose(M[:, :3, 3], P, atol=1e-6)
    np.testing.assert_allclose(M[:, :3, :3], 0.05 * quaternion_frames(Q.astype(float)), atol=1e-6)
    # one cross: three bars, each long along its own axis
    refs = geo.instance_references()  # keep the geometry sets alive while reading their mesh
    assert len(refs) == 1
    mesh = refs[0].mesh
    X = np.array([v.co for v in mesh.vertices])
    assert np.allclose(X.max(axis=0) - X.min(axis=0), 1.0)
    assert len(mesh.polygons) == 18
    for p in mesh.polygons:  # each bar has the colour of the axis it lies along
        extent = np.ptp(X[list(p.vertices)], axis=0)
        if extent.max() > 0.5:  # a long side of a bar
            assert mesh.materials[p.material_index].name == glyphs.AXIS_MATERIALS[int(np.argmax(extent))]


@pytest.mark.mesher
def test_save_and_reload_keep_the_result(cube):
    open_blend(cube.path)
    assert storage.stored_report(scene()) == cube.report
    P, Q = glyphs.glyph_points(output("glyphs"))
    np.testing.assert_array_equal(P, cube.glyph_points)
    np.testing.assert_array_equal(Q, cube.glyph_quats)
    lines = polylines(output("streamlines"))
    assert len(cube.lines) > 0
    assert len(lines) == len(cube.lines) and all(np.array_equal(a, b) for a, b in zip(lines, cube.lines))
    # the stored field alone drives the display operators: no solve needed
    assert bpy.ops.symframes.show_glyphs() == {"FINISHED"}
    assert len(output("glyphs").data.vertices) == GLYPHS


@pytest.mark.mesher
def test_recompute_replaces_the_result_cleanly(cube):
    open_blend(cube.path)
    s = scene().symframes
    before = scene_state()
    old_field = s.field.session_uid
    s.penalty = 500.0  # a solver setting only: the tet mesh is reused
    assert bpy.ops.symframes.compute() == {"FINISHED"}
    after = scene_state()
    assert after == before  # same datablocks by name: nothing left over, nothing duplicated
    assert s.field.session_uid != old_field
    assert len(bpy.data.meshes) == len(before["meshes"])
    assert storage.stored_remeshed(scene()) is False
    for role in ("glyphs", "streamlines"):
        assert sum(o.get(storage.ROLE_KEY) == role for o in bpy.data.objects) == 1
    # the streamlines were there, so they were traced again for the new field
    assert len(output("streamlines").data.splines) >= 0.9 * 3 * SEEDS


def test_undo_after_compute_restores_the_scene(cube):
    # Undo works in the bpy module (it has a window).  Operators called from
    # Python push an undo step only when asked (undo=True), and then only if
    # they have the UNDO option, as a click in the UI does.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    add_example("cube", CUBE_EDGE)
    bpy.ops.ed.undo_push(message="example added")
    before = scene_state()
    assert bpy.ops.symframes.compute("EXEC_DEFAULT", True) == {"FINISHED"}
    assert scene_state() != before
    bpy.ops.ed.undo()
    assert scene_state() == before
    assert scene().symframes.field is None and output("glyphs") is None
    bpy.ops.ed.redo()
    assert scene().symframes.field is not None and output("glyphs") is not None


@pytest.mark.mesher
def test_clear_removes_everything_it_added(cube):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    add_example("cube")
    clean = scene_state()
    open_blend(cube.path)
    s = scene().symframes
    assert bpy.ops.symframes.show_singular_faces() == {"FINISHED"}
    assert bpy.ops.symframes.show_omega() == {"FINISHED"}
    for quantity in ("MONODROMY", "ADAPTATION"):  # one object, replaced
        s.slice_quantity = quantity
        assert bpy.ops.symframes.show_slice() == {"FINISHED"}
    s.glyph_colour = "MONODROMY"
    assert bpy.ops.symframes.show_glyphs() == {"FINISHED"}
    s.hex_cells = 300
    assert bpy.ops.symframes.hex_mesh() == {"FINISHED"}
    roles = [o.get(storage.ROLE_KEY) for o in bpy.data.objects]
    # the cube's hex mesh is a grid: no irregular edge, so no irregular-edges object
    assert sorted(r for r in roles if r) == sorted(set(storage.OUTPUT_ROLES) - {"irregular_edges"})
    assert bpy.ops.symframes.clear() == {"FINISHED"}
    after = scene_state()
    assert after == clean
    assert bpy.ops.symframes.clear() == {"CANCELLED"}  # nothing left to clear


# ------------------------------------------------------------------ display
@pytest.mark.mesher
def test_glyph_regions(cube):
    open_blend(cube.path)
    s = scene().symframes
    f = storage.frame_field(scene())
    s.slice_axis, s.slice_offset = "Z", 0.3
    origin, normal = display.DisplaySettings.from_scene(scene()).plane(*f.bounds)
    s.glyph_region = "CUTAWAY"
    assert bpy.ops.symframes.show_glyphs() == {"FINISHED"}
    P, _ = glyphs.glyph_points(output("glyphs"))
    assert len(P) == GLYPHS and np.all((P - origin) @ normal <= 1e-6)
    s.glyph_region = "SLICE"
    assert bpy.ops.symframes.show_glyphs() == {"FINISHED"}
    P, Q = glyphs.glyph_points(output("glyphs"))
    assert 0.9 * GLYPHS <= len(P) <= GLYPHS
    np.testing.assert_allclose((P - origin) @ normal, 0.0, atol=1e-6)
    expect = f.quaternions_at(P.astype(float))
    assert np.abs(np.einsum("ij,ij->i", Q, expect)).min() > 1 - 1e-5


@pytest.mark.mesher
def test_trace_streamlines_on_slice_plane(cube):
    open_blend(cube.path)
    s = scene().symframes
    s.streamline_family, s.streamline_seeds, s.streamline_on_plane = "1", 30, True
    s.slice_axis, s.slice_offset = "X", 0.5
    s.streamline_radius = 0.004
    assert bpy.ops.symframes.trace_streamlines() == {"FINISHED"}
    st = output("streamlines")
    ds = display.DisplaySettings.from_scene(scene())
    f = storage.frame_field(scene())
    expect, _ = display.streamlines(f, ds)
    assert len(st.data.splines) == len(expect) >= 27
    assert all(sp.material_index == 1 for sp in st.data.splines)
    assert st.data.bevel_depth == pytest.approx(0.004)
    origin, normal = ds.plane(*f.bounds)
    for P, E in zip(polylines(st), expect):
        np.testing.assert_allclose(P, E, atol=1e-6)
        assert np.abs((P - origin) @ normal).min() < 1e-6  # each line passes through its seed


# -------------------------------------------------------- network + diagnostics
@pytest.mark.slow
@pytest.mark.mesher
def test_plate_with_curves_solves_without_spurious_singularities(plate):
    open_blend(plate.path)
    assert plate.inputs_after == plate.inputs_before
    assert bpy.data.objects["hole 0"].data.splines[0].type == "BEZIER"
    assert len(plate.inputs.network.curves) == 4
    m = plate.report.metrics
    # the field's own (omega-aware) matchings: exactly the network's singular faces
    assert m["omega_spurious_singular_faces"] == 0 and m["omega_missing_singular_faces"] == 0
    assert m["omega_singular_faces"] > 0 and m["tangent_adaptation_mean_deg"] < 1.0
    # closest-rotation matching may read a face next to a curve instead of the
    # pierced one (an edge the curve passes close to turns by ~45 degrees), on
    # some meshes fTetWild makes: never a face away from the network
    f = storage.frame_field(scene())
    omega = storage.field_omega(scene())
    mesh = f.mesh
    differ = singular_mask(mesh, f.frames) != omega_singular_faces(mesh, omega, f.frames)
    assert differ.sum() == m["matching_disagreements"]
    net = np.zeros(mesh.n_vertices, bool)
    net[mesh.faces[storage.network_face_ids(scene())]] = True
    assert net[mesh.faces[differ]].any(axis=1).all()


@pytest.mark.slow
@pytest.mark.mesher
def test_singular_faces_match_the_solver(plate):
    open_blend(plate.path)
    assert bpy.ops.symframes.show_singular_faces() == {"FINISHED"}
    obj = output("singular_faces")
    me = obj.data
    counts = obj[diagnostics.COUNTS_KEY].to_dict()
    m = plate.report.metrics
    assert counts == {"singular": len(me.polygons), "spurious": 0, "closest_differs": m["matching_disagreements"]}
    assert counts["singular"] == m["omega_singular_faces"]
    sp = np.empty(len(me.polygons), bool)
    me.attributes["spurious"].data.foreach_get("value", sp)
    mat = np.empty(len(me.polygons), np.int32)
    me.polygons.foreach_get("material_index", mat)
    assert not sp.any() and not mat.any()


@pytest.mark.mesher
def test_spurious_singular_faces_are_highlighted(cube):
    """Overwrite the stored field with one that turns by a quarter turn
    around the z axis (the frame at angle theta is rotated by theta/4 about
    z, omega the turn along each edge up to a quarter turn): the faces the
    axis pierces are singular, and since the cube's network is empty they
    are all spurious."""
    open_blend(cube.path)
    me = scene().symframes.field
    f0 = storage.solved_field(scene())
    V, E = f0.mesh.vertices, f0.mesh.edges
    phi = np.arctan2(V[:, 1], V[:, 0]) / 4
    R = np.zeros((len(V), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = np.cos(phi), -np.sin(phi), np.sin(phi), np.cos(phi), 1
    turn = phi[E[:, 1]] - phi[E[:, 0]]
    turn -= np.round(turn / (np.pi / 2)) * (np.pi / 2)
    group = me[storage.FIELD_KEY]
    group["frames"] = R.ravel().tolist()
    group["omega"] = np.c_[np.zeros((len(E), 2)), turn].ravel().tolist()
    storage._FIELD_CACHE.clear()  # the field was edited behind the add-on's back
    assert bpy.ops.symframes.show_singular_faces() == {"FINISHED"}
    obj = output("singular_faces")
    counts = obj[diagnostics.COUNTS_KEY].to_dict()
    f = storage.frame_field(scene())
    omega = storage.field_omega(scene())
    sing = omega_singular_faces(f.mesh, omega, f.frames)
    differs = int((sing != singular_mask(f.mesh, f.frames)).sum())
    assert counts == {"singular": int(sing.sum()), "spurious": int(sing.sum()), "closest_differs": differs}
    assert counts["singular"] >= 5 and len(obj.data.polygons) == counts["singular"]
    # they lie along the z axis, from the bottom to the top of the cube
    X = np.array([v.co for v in obj.data.vertices])
    assert np.linalg.norm(X[:, :2], axis=1).min() < 0.5 * CUBE_EDGE
    C = f.mesh.vertices[f.mesh.faces[sing]].mean(axis=1)
    assert np.linalg.norm(C[:, :2], axis=1).max() < 1.5 * CUBE_EDGE
    assert C[:, 2].max() - C[:, 2].min() > 1.0
    mat = np.empty(len(obj.data.polygons), np.int32)
    obj.data.polygons.foreach_get("material_index", mat)
    assert mat.all()  # all red


@pytest.mark.slow
@pytest.mark.mesher
def test_glyphs_coloured_by_adaptation_error(plate):
    open_blend(plate.path)
    s = scene().symframes
    s.glyph_colour = "ADAPTATION"
    s.glyph_count = 100_000  # all measured boundary vertices
    assert bpy.ops.symframes.show_glyphs() == {"FINISHED"}
    g = output("glyphs")
    P, Q = glyphs.glyph_points(g)
    err = np.empty(len(P), np.float32)
    g.data.attributes[glyphs.ERROR_ATTRIBUTE].data.foreach_get("value", err)
    f = storage.frame_field(scene())
    # the glyphs sit on boundary vertices; their error is the solver's normal adaptation there
    from scipy.spatial import cKDTree

    d, vid = cKDTree(f.mesh.vertices).query(P.astype(float))
    assert d.max() < 1e-6
    bv = f.mesh.boundary_vertices
    assert np.isin(vid, bv).all()
    expect = normal_adaptation(f.mesh, f.frames)[np.searchsorted(bv, vid)]
    np.testing.assert_allclose(err, expect, atol=1e-4)
    # the same vertices as the solver's metric: all boundary vertices but the
    # sharp feature ones, whose frames are fixed
    assert 0 < len(P) < len(bv)
    mean = float(np.degrees(err.astype(float)).mean())
    assert mean == pytest.approx(plate.report.metrics["normal_adaptation_mean_deg"], rel=1e-3)
    mod = g.modifiers[glyphs.MODIFIER]
    by_error = next(i for i in mod.node_group.interface.items_tree if getattr(i, "name", "") == "Color by Error")
    assert bool(storage.modifier_input(mod, by_error.identifier)) is True
    geo = g.evaluated_get(bpy.context.evaluated_depsgraph_get()).evaluated_geometry()
    inst = geo.instances_pointcloud()  # valid while geo lives
    fac = np.array([d.value for d in inst.attributes[glyphs.ERROR_FACTOR].data])
    np.testing.assert_allclose(fac, np.clip(err / s.error_scale, 0, 1), atol=1e-5)


# ------------------------------------------------------------ omega, slices
def _instance_transforms(obj) -> np.ndarray:
    """(k, 4, 4) transforms of the instances an object's modifier makes."""
    geo = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).evaluated_geometry()
    inst = geo.instances_pointcloud()  # valid while geo lives
    return np.array([np.array(d.value) for d in inst.attributes["instance_transform"].data])


def _face_attribute(me, name, dtype=np.float32) -> np.ndarray:
    out = np.empty(len(me.polygons), dtype)
    me.attributes[name].data.foreach_get("value", out)
    return out


def _face_colours(me) -> np.ndarray:
    c = np.empty(4 * len(me.loops), np.float32)
    me.color_attributes[error_slice.COLOUR_ATTRIBUTE].data.foreach_get("color", c)
    return c.reshape(-1, 3, 4)[:, 0]  # every corner of a face has its colour


@pytest.mark.slow
@pytest.mark.mesher
def test_field_stores_the_solvers_omega(plate):
    """The field mesh holds exactly the tet-mesh edges with the solver's
    omega on them (same tet mesh, so the same solve)."""
    open_blend(plate.path)
    inp = plate.inputs
    result = FieldProblem(inp.V, inp.F, inp.network, inp.options, mesh=plate.mesh).solve()
    me = scene().symframes.field
    assert len(me.edges) == plate.mesh.n_edges
    assert me.validate() is False  # a valid mesh: nothing to fix
    omega = storage.field_omega(scene())
    f = storage.frame_field(scene())
    assert np.array_equal(f.mesh.edges, result.mesh.edges)
    assert np.linalg.norm(result.omega, axis=1).max() > 0.3  # a field that turns: the test can fail
    np.testing.assert_allclose(omega, result.omega, atol=1e-6)
    # its monodromy off the network is the report's (float32 storage costs < 1e-4 degrees)
    regular = np.nonzero(regular_face_mask(f.mesh, storage.network_face_ids(scene())))[0]
    mono = np.degrees(monodromy_angles(f.mesh, omega, regular))
    assert mono.mean() == pytest.approx(plate.report.metrics["monodromy_mean_deg"], abs=1e-4)


def test_an_arrow_along_minus_z_points_down():
    """Align Rotation to Vector left +z in place for omega within ~1e-19 of
    -z (a round-off component: 3 arrows of 5,690 on one plate mesh pointed
    up); exactly opposite, nearly opposite and ordinary vectors all turn."""
    omega = np.array([[2.4e-26, 0.0, -0.18], [3e-27, 0.0, -0.15], [0.0, 0.0, -0.2], [1e-14, 1e-14, -0.5],
                      [0.0, 1e-30, 0.3], [0.1, -0.2, 0.05]])
    points = np.arange(len(omega) * 3, dtype=float).reshape(-1, 3)
    obj = omega_arrows.write_arrows(scene(), points, omega, np.arange(len(omega)), 0.5)
    M = _instance_transforms(obj)
    length = scene().symframes.omega_scale * 0.5
    np.testing.assert_allclose(M[:, :3, 2], length * omega, atol=1e-6)


@pytest.mark.slow
@pytest.mark.mesher
def test_omega_arrows_match_the_stored_omega(plate):
    open_blend(plate.path)
    s = scene().symframes
    f = storage.frame_field(scene())
    omega = storage.field_omega(scene())
    h = f.mesh.mean_edge_length
    s.omega_region, s.omega_count = "VOLUME", 10**6
    assert bpy.ops.symframes.show_omega() == {"FINISHED"}
    obj = output("omega_arrows")
    P, W, e = omega_arrows.arrow_points(obj)
    assert np.array_equal(e, np.arange(f.mesh.n_edges))  # every edge, once
    np.testing.assert_allclose(P, f.mesh.vertices[f.mesh.edges].mean(axis=1), atol=1e-6)
    np.testing.assert_allclose(W, omega, atol=1e-7)
    # the instanced arrows: from the midpoint along the axis, length |omega| * scale * h, width 5% of h
    M = _instance_transforms(obj)
    assert len(M) == f.mesh.n_edges
    some = np.argsort(-np.linalg.norm(omega, axis=1))[:50]  # the longest arrows, and a few short ones
    some = np.r_[some, np.arange(0, f.mesh.n_edges, 97)]
    np.testing.assert_allclose(M[some, :3, 3], P[some], atol=1e-6)
    np.testing.assert_allclose(M[some, :3, 2], s.omega_scale * h * omega[some], atol=1e-6)
    np.testing.assert_allclose(np.einsum("kij,ki->kj", M[some, :3, :2], omega[some]), 0.0, atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(M[some, :3, :2], axis=1), omega_arrows.WIDTH * h, rtol=1e-4)
    # the scale is live
    s.omega_scale = 0.5
    np.testing.assert_allclose(_instance_transforms(obj)[some, :3, 2], 0.5 * h * omega[some], atol=1e-6)
    # the slice region: the edges of the slice faces; a cap picks a subset; re-running replaces the object
    s.omega_region, s.omega_count = "SLICE", 10**6
    assert bpy.ops.symframes.show_omega() == {"FINISHED"}
    _, W, e = omega_arrows.arrow_points(output("omega_arrows"))
    sf, _ = display.slice_faces(f, display.DisplaySettings.from_scene(scene()))
    assert len(sf) > 0 and np.array_equal(e, np.unique(f.mesh.face_edges[sf]))
    np.testing.assert_allclose(W, omega[e], atol=1e-7)
    s.omega_count = 10
    assert bpy.ops.symframes.show_omega() == {"FINISHED"}
    _, W, e2 = omega_arrows.arrow_points(output("omega_arrows"))
    assert len(e2) == 10 and np.isin(e2, e).all()
    assert sum(o.get(storage.ROLE_KEY) == "omega_arrows" for o in bpy.data.objects) == 1


@pytest.mark.slow
@pytest.mark.mesher
def test_monodromy_slice_matches_the_solver(plate):
    open_blend(plate.path)
    s = scene().symframes
    s.slice_axis, s.slice_offset = "Z", 0.5  # across the plate: the four curves pierce it
    s.slice_quantity = "MONODROMY"
    assert bpy.ops.symframes.show_slice() == {"FINISHED"}
    obj = output("error_slice")
    me = obj.data
    f = storage.frame_field(scene())
    omega = storage.field_omega(scene())
    faces = _face_attribute(me, "face", np.int32)
    expect_faces, tris = display.slice_faces(f, display.DisplaySettings.from_scene(scene()))
    assert np.array_equal(faces, expect_faces)
    # the triangles are those faces (only the used vertices kept)
    X = np.array([v.co for v in me.vertices])
    T = np.array([p.vertices[:] for p in me.polygons])
    np.testing.assert_allclose(X[T], f.mesh.vertices[tris], atol=1e-6)
    # the slice lies along the plane, between a kept and a cut-away tet
    origin, normal = display.DisplaySettings.from_scene(scene()).plane(*f.bounds)
    assert np.abs((X - origin) @ normal).max() < 2 * f.mesh.edge_lengths.max()
    value = _face_attribute(me, "monodromy")
    np.testing.assert_allclose(value, monodromy_angles(f.mesh, omega, faces), atol=1e-6)
    # the network's faces are flagged and grey; they turn by a quarter turn (index -1/4)
    net = _face_attribute(me, "network", bool)
    ids = storage.network_face_ids(scene())
    assert np.array_equal(net, np.isin(faces, ids))
    assert net.sum() >= 4
    np.testing.assert_allclose(np.degrees(value[net]).max(), 90.0, atol=0.5)
    # elsewhere a fraction of a degree, within the report's largest monodromy
    st = obj[error_slice.STATS_KEY].to_dict()
    assert st["faces"] == len(faces) and st["grey"] == net.sum()
    assert st["max_deg"] == pytest.approx(np.degrees(value[~net]).max(), rel=1e-5)
    assert st["max_deg"] <= plate.report.metrics["monodromy_max_deg"] + 1e-4
    # colours: the ramp at the Monodromy Scale, live
    for scale in (s.monodromy_scale, 1e-5):
        s.monodromy_scale = scale
        C = _face_colours(me)
        assert np.abs(C[net, :3] - error_slice.GREY).max() < 1e-6
        np.testing.assert_allclose(C[~net], error_slice.ramp_colours(value[~net], scale), atol=1e-6)
    assert not np.allclose(C[~net], error_slice.ramp_colours(value[~net], 1.0))


@pytest.mark.slow
@pytest.mark.mesher
def test_adaptation_slice_is_the_cut_surface(plate):
    open_blend(plate.path)
    s = scene().symframes
    s.slice_axis, s.slice_offset, s.slice_quantity = "X", 0.6, "ADAPTATION"
    assert bpy.ops.symframes.show_slice() == {"FINISHED"}
    me = output("error_slice").data
    f = storage.frame_field(scene())
    mesh = f.mesh
    faces = _face_attribute(me, "face", np.int32)
    assert mesh.is_boundary_face[faces].all()
    origin, normal = display.DisplaySettings.from_scene(scene()).plane(*f.bounds)
    C = mesh.vertices[mesh.tets[mesh.face_tets[faces, 0]]].mean(axis=1)
    assert np.all((C - origin) @ normal <= 0)
    # every boundary face of a kept tet
    Cb = mesh.vertices[mesh.tets[mesh.face_tets[mesh.boundary_faces, 0]]].mean(axis=1)
    assert len(faces) == np.sum((Cb - origin) @ normal <= 0)
    # each face: the mean of its vertices' normal adaptation errors (the sharp-feature ones not measured)
    err = normal_adaptation(mesh, f.frames)
    na = np.full(mesh.n_vertices, np.nan)
    stored = storage.read_adaptation(s.field)
    na[stored >= 0] = err[np.searchsorted(mesh.boundary_vertices, np.nonzero(stored >= 0)[0])]
    A = na[mesh.faces[faces]]
    n = np.isfinite(A).sum(axis=1)
    expect = np.where(n > 0, np.nansum(A, axis=1) / np.maximum(n, 1), np.nan)
    value = _face_attribute(me, "adaptation")
    ok = np.isfinite(expect)
    assert ok.sum() > 0.9 * len(faces)
    np.testing.assert_allclose(value[ok], expect[ok], atol=1e-5)
    assert np.all(value[~ok] == -1)
    assert np.abs(_face_colours(me)[~ok, :3] - error_slice.GREY).max() < 1e-6


@pytest.mark.slow
@pytest.mark.mesher
def test_glyphs_coloured_by_monodromy(plate):
    open_blend(plate.path)
    s = scene().symframes
    s.glyph_colour, s.glyph_region, s.glyph_count = "MONODROMY", "VOLUME", 100_000
    s.monodromy_scale = 1e-4
    assert bpy.ops.symframes.show_glyphs() == {"FINISHED"}
    g = output("glyphs")
    P, _ = glyphs.glyph_points(g)
    f = storage.frame_field(scene())
    mesh = f.mesh
    assert len(P) == mesh.n_vertices  # one per vertex, in order
    np.testing.assert_allclose(P, mesh.vertices, atol=1e-6)
    err = np.empty(len(P), np.float32)
    g.data.attributes[glyphs.MONODROMY_ATTRIBUTE].data.foreach_get("value", err)
    # mean over the interior faces around the vertex that the network does not pass through
    omega = storage.field_omega(scene())
    net = np.zeros(mesh.n_faces, bool)
    net[storage.network_face_ids(scene())] = True
    regular = np.nonzero(~net & ~mesh.is_boundary_face)[0]
    import scipy.sparse as sparse

    rows, cols = mesh.faces[regular].ravel(), np.repeat(np.arange(len(regular)), 3)
    A = sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(mesh.n_vertices, len(regular)))
    n = np.asarray(A.sum(axis=1)).ravel()
    expect = (A @ monodromy_angles(mesh, omega, regular)) / np.maximum(n, 1)
    np.testing.assert_allclose(err, expect, atol=1e-7)
    assert err.max() > 0
    mod = g.modifiers[glyphs.MODIFIER]
    values = {i.name: storage.modifier_input(mod, i.identifier) for i in mod.node_group.interface.items_tree
              if getattr(i, "in_out", None) == "INPUT" and i.name != "Geometry"}
    assert values["Color by Error"] and values["Error Attribute"] == glyphs.MONODROMY_ATTRIBUTE
    assert values["Error Scale"] == pytest.approx(1e-4)
    geo = g.evaluated_get(bpy.context.evaluated_depsgraph_get()).evaluated_geometry()
    inst = geo.instances_pointcloud()
    fac = np.array([d.value for d in inst.attributes[glyphs.ERROR_FACTOR].data])
    np.testing.assert_allclose(fac, np.clip(err / 1e-4, 0, 1), atol=1e-5)
    # the slice region: the vertices of the slice faces
    s.glyph_region = "SLICE"
    assert bpy.ops.symframes.show_glyphs() == {"FINISHED"}
    P, _ = glyphs.glyph_points(output("glyphs"))
    sf, _ = display.slice_faces(f, display.DisplaySettings.from_scene(scene()))
    np.testing.assert_allclose(P, mesh.vertices[np.unique(mesh.faces[sf])], atol=1e-6)


@pytest.mark.slow
@pytest.mark.mesher
def test_diagnostics_survive_save_and_reload(plate, tmp_path):
    open_blend(plate.path)
    s = scene().symframes
    s.slice_axis = "Z"
    assert bpy.ops.symframes.show_omega() == {"FINISHED"}
    assert bpy.ops.symframes.show_slice() == {"FINISHED"}
    M = _instance_transforms(output("omega_arrows"))
    value = _face_attribute(output("error_slice").data, "monodromy")
    path = tmp_path / "diagnostics.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    open_blend(path)
    s = scene().symframes
    assert storage.field_omega(scene()) is not None
    np.testing.assert_allclose(_instance_transforms(output("omega_arrows")), M, atol=1e-7)
    np.testing.assert_array_equal(_face_attribute(output("error_slice").data, "monodromy"), value)
    s.omega_scale *= 2  # still live
    np.testing.assert_allclose(_instance_transforms(output("omega_arrows"))[:, :3, 2], 2 * M[:, :3, 2], atol=1e-6)
    # and the operators run again from the reopened file, replacing their objects
    before = scene_state()
    assert bpy.ops.symframes.show_omega() == {"FINISHED"}
    assert bpy.ops.symframes.show_slice() == {"FINISHED"}
    assert scene_state() == before
    np.testing.assert_array_equal(_face_attribute(output("error_slice").data, "monodromy"), value)


@pytest.mark.slow
@pytest.mark.mesher
def test_a_field_without_its_omega_is_refused(plate):
    """A stored field missing what the solve stores (here its omega) is
    refused with what to do, and the scene is unchanged."""
    open_blend(plate.path)
    s = scene().symframes
    s.glyph_colour, s.slice_quantity = "MONODROMY", "MONODROMY"
    group = s.field[storage.FIELD_KEY]
    layout = json.loads(group[storage.ARRAYS_LAYOUT])
    del layout["omega"], group["omega"]
    group[storage.ARRAYS_LAYOUT] = json.dumps(layout)
    storage._FIELD_CACHE.clear()  # the field was edited behind the add-on's back
    for op in (bpy.ops.symframes.show_omega, bpy.ops.symframes.show_slice, bpy.ops.symframes.show_glyphs,
               bpy.ops.symframes.show_singular_faces):
        _fails("'omega' is missing.*compute the field again", op)
    with pytest.raises(RuntimeError, match="'omega' is missing"):
        bpy.ops.symframes.export_field(filepath=str(plate.path.with_suffix(".vtu")), file_format="VTU")
    assert not plate.path.with_suffix(".vtu").exists()


@pytest.mark.mesher
def test_diagnostics_bad_plane_undo_and_recompute(cube):
    open_blend(cube.path)
    s = scene().symframes
    s.slice_offset = 0.0  # at the edge of the solid: nothing on the plane
    s.omega_region = "SLICE"
    _fails("move the slice plane into the solid", bpy.ops.symframes.show_slice)
    _fails("move the slice plane into the solid", bpy.ops.symframes.show_omega)
    s.slice_quantity = "ADAPTATION"  # the cutaway keeps nothing
    _fails("move the slice plane into the solid", bpy.ops.symframes.show_slice)
    s.slice_offset = 0.5
    bpy.ops.ed.undo_push(message="before the diagnostics")
    before = scene_state()
    assert bpy.ops.symframes.show_omega("EXEC_DEFAULT", True) == {"FINISHED"}
    assert bpy.ops.symframes.show_slice("EXEC_DEFAULT", True) == {"FINISHED"}
    assert scene_state() != before
    bpy.ops.ed.undo()
    bpy.ops.ed.undo()
    assert scene_state() == before and output("omega_arrows") is None
    bpy.ops.ed.redo()
    bpy.ops.ed.redo()
    assert output("omega_arrows") is not None and output("error_slice") is not None
    # computing again removes them: they showed the old field; the glyphs are coloured in the solve
    s = scene().symframes  # undo reloads the scene: references from before it are stale
    s.glyph_colour = "MONODROMY"
    assert bpy.ops.symframes.compute() == {"FINISHED"}
    assert output("omega_arrows") is None and output("error_slice") is None
    g = output("glyphs")
    # monodromy glyphs sit on vertices: as many as asked for, or every vertex
    # of a small mesh (fTetWild's vertex count varies from run to run)
    n_vertices = storage.solved_field(scene()).mesh.n_vertices
    assert len(g.data.vertices) == min(GLYPHS, n_vertices)
    assert glyphs.error_attribute(g) == glyphs.MONODROMY_ATTRIBUTE


@pytest.mark.slow
@pytest.mark.mesher
def test_panels_draw_the_diagnostics(plate):
    """Every panel draws (with a stand-in layout that checks each property
    exists) and the Diagnostics panel reports the error slice."""
    from symframes.symframes_addon import panel

    class Layout:
        def __init__(self, labels):
            self.labels = labels

        def __getattr__(self, name):
            def call(*args, **kw):
                if name == "prop":
                    getattr(args[0], args[1])
                elif name == "label":
                    self.labels.append(kw.get("text", ""))
                return self
            return call

    open_blend(plate.path)
    s = scene().symframes
    s.slice_axis, s.slice_quantity = "Z", "MONODROMY"
    assert bpy.ops.symframes.show_slice() == {"FINISHED"}
    bpy.data.objects["hole 0"].select_set(True)
    bpy.context.view_layer.objects.active = bpy.data.objects["hole 0"]
    labels = {}
    for cls in (c for c in panel.CLASSES if issubclass(c, bpy.types.Panel)):
        labels[cls.__name__] = []
        cls.draw(SimpleNamespace(layout=Layout(labels[cls.__name__])), bpy.context)
    st = output("error_slice")[error_slice.STATS_KEY]
    assert any(f"{st['faces']:,} faces" in t and "network" in t for t in labels["SYMFRAMES_PT_diagnostics"])
    assert any("tangents" in t for t in labels["SYMFRAMES_PT_result"])
    # singular faces as the field's own matchings read them; where closest-rotation
    # matching reads some otherwise, the panel says so
    m = plate.report.metrics
    assert f"Singular faces {m['omega_singular_faces']}" in labels["SYMFRAMES_PT_result"]
    me = scene().symframes.field
    r = json.loads(me[storage.REPORT_KEY])
    r["metrics"]["matching_disagreements"] = 3
    me[storage.REPORT_KEY] = json.dumps(r)
    drawn = []
    panel.SYMFRAMES_PT_result.draw(SimpleNamespace(layout=Layout(drawn)), bpy.context)
    assert "   closest-rotation reads 3 otherwise" in drawn


# ------------------------------------------------------------------ headless
@pytest.mark.slow
@pytest.mark.mesher
def test_headless_script_builds_solves_saves_and_renders(tmp_path):
    cmd = [sys.executable, os.path.join(ROOT, "scripts", "symframes_run.py"), "--example", "cube",
           "--edge-length", str(CUBE_EDGE), "--glyphs", "200", "--streamlines", "10", "--out-dir", str(tmp_path),
           "--resolution", "80x60", "--samples", "1"]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=HANG, cwd=ROOT)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert (tmp_path / "cube.png").stat().st_size > 0
    open_blend(tmp_path / "cube.blend")
    assert scene().symframes.field is not None
    assert len(output("glyphs").data.vertices) == 200
    assert len(output("streamlines").data.splines) > 0
    assert scene().camera is not None and scene().render.engine == "CYCLES"
