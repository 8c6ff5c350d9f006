"""Operators (all in F3 search, through the menus of menus.py).

Every failure is reported with self.report({'ERROR'}, message) and leaves
the scene as it was: inputs are read into arrays first, numerics run on
arrays, and the scene is written only after everything succeeded.
"""

import traceback

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty

from ..solver import FinerNear, HexOptions, SymFramesError, TopologyError, check
from ..solver.examples import EXAMPLES
from . import (
    diagnostics,
    display,
    error_slice,
    examples,
    glyphs,
    hex_mesh,
    job,
    omega_arrows,
    properties,
    scene_io,
    storage,
    streamline_curves,
)

_RUNNING: dict = {}  # the one job (solve or hex mesh) running in the background, if any


def running_job():
    return _RUNNING.get("job")


def error_text(e: BaseException, inputs=None) -> str:
    """A message for the user: input errors verbatim, others with their type."""
    if isinstance(e, (SymFramesError, ValueError)):
        msg = str(e)
        if isinstance(e, TopologyError) and inputs is not None and not inputs.network.curves:
            msg += f". The network is empty: {inputs.network_note}"
        return msg
    return f"SymFrames failed ({type(e).__name__}: {e}); see the system console for details"


def write_outcome(scene, out: job.Outcome) -> None:
    """Replace the scene's result with a solved outcome, all or nothing:
    every new datablock is built before any old one is replaced.  Output
    objects that were not recomputed are removed: they showed the old field."""
    created = []
    try:
        field_me = storage.new_field_mesh(out.field, out.adaptation, out.report, out.remeshed)
        created.append((bpy.data.meshes, field_me))
        field_me[storage.INPUTS_KEY] = out.inputs_key
        field_me[storage.INPUTS_PARTS_KEY] = out.inputs_parts
        glyph_me = curve = None
        if out.glyphs is not None:
            glyph_me = glyphs.new_glyph_mesh(*out.glyphs)
            created.append((bpy.data.meshes, glyph_me))
        if out.streamlines is not None:
            curve = streamline_curves.new_streamline_curve(*out.streamlines, scene.symframes.streamline_radius)
            created.append((bpy.data.curves, curve))
    except Exception:
        for coll, data in created:
            coll.remove(data)
        raise
    storage.set_field(scene, field_me)
    if glyph_me is not None:
        glyphs.install_glyph_mesh(scene, glyph_me)
    else:
        storage.remove_output(scene, "glyphs")
    if curve is not None:
        storage.replace_output(scene, "streamlines", "SymFrames Streamlines", curve)
    else:
        storage.remove_output(scene, "streamlines")
    for role in ("singular_faces", omega_arrows.ROLE, error_slice.ROLE, hex_mesh.ROLE, hex_mesh.EDGES_ROLE):
        storage.remove_output(scene, role)


def finish_job(scene, j: job.SolveJob) -> tuple[str, str]:
    """Write a finished job into the scene (only if it succeeded).

    Returns (report level, message): ('INFO', summary), ('WARNING', ...) when
    cancelled, ('ERROR', ...) on failure -- the scene is then unchanged.
    """
    if j.cancelled:
        return "WARNING", "SymFrames: cancelled; the scene is unchanged"
    if j.error is not None:
        if not isinstance(j.error, (SymFramesError, ValueError)):
            traceback.print_exception(j.error)
        return "ERROR", error_text(j.error, j.inputs)
    if scene is None:
        return "ERROR", "SymFrames: the scene was deleted during the solve; nothing was written"
    try:
        write_outcome(scene, j.outcome)
    except Exception as e:
        traceback.print_exc()
        return "ERROR", error_text(e)
    r = j.outcome.report
    c = r.singular_face_counts()
    msg = (f"SymFrames: {r.sizes.get('tets', 0):,} tets, {r.lm.n_iterations if r.lm else 0} iterations, "
           f"{r.total_seconds:.1f} s; monodromy {r.metrics.get('monodromy_mean_deg', 0):.3g} deg mean, "
           f"{c['spurious']} spurious and {c['missing']} missing singular faces")
    warnings = []
    if not r.converged:
        # written all the same (it may help to see where it fails), but said
        # plainly: an unconverged field can be far from the minimiser
        warnings.append(f"not converged ({r.status_reason}), so the field may be "
                        "wrong: check the network's validity (Check Network), then try a finer resolution near "
                        "its short curves (a smaller Edge Length or more Tets) or more iterations")
    if j.outcome.streamlines is not None and not j.outcome.streamlines[0]:
        warnings.append("no streamline could be traced")
    return ("WARNING", "; ".join([msg] + warnings)) if warnings else ("INFO", msg)


def _tag_redraw(context) -> None:
    screen = context.screen
    if screen is None:
        return
    for area in screen.areas:
        if area.type == "VIEW_3D":
            area.tag_redraw()


class SYMFRAMES_OT_check_network(bpy.types.Operator):
    """Validate the domain and the curve network without solving"""

    bl_idname = "symframes.check_network"
    bl_label = "Check Network"
    bl_options = {"REGISTER"}

    def execute(self, context):
        inp = None
        try:
            inp = scene_io.read_inputs(context)
            found = check(inp.V, inp.F, inp.network, options=inp.options)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e, inp))
            return {"CANCELLED"}
        msg = (f"Network OK: {len(inp.network.curves)} curve(s) ({found.interior_curves} interior, "
               f"{found.nodes} node(s)), {found.sharp_edges} sharp surface edge(s), {len(inp.F):,} triangles; "
               f"about {found.plan.tets:,.0f} tets")
        if inp.ignored:
            msg += f"; ignored non-curve object(s): {', '.join(inp.ignored)}"
        repaired = found.repairs_text()
        if repaired:
            # the first line counts the repaired curves; the rest goes to the console
            msg += "; " + repaired.splitlines()[0]
            print(repaired)
        print(f"SymFrames resolution: {found.plan.describe()}")
        self.report({"INFO"}, msg)
        return {"FINISHED"}


class _Threaded:
    """An operator whose work is a job.Job: in a worker thread polled by a
    modal timer when invoked from the UI (progress in the status bar and the
    panel, Esc cancels), in the calling thread by execute() (background
    mode, scripts, tests).  Subclasses define _prepare(context, echo) -> Job
    or None (reading the scene; None after reporting why) and
    _finish(scene, job) -> (level, message) (writing it, on the main thread)."""

    @classmethod
    def poll(cls, context):
        if running_job() is not None:
            cls.poll_message_set("a SymFrames job is already running")
            return False
        return context.scene is not None

    def _done(self, scene, j) -> set:
        level, msg = self._finish(scene, j)
        self.report({level}, msg)
        return {"FINISHED"} if level != "ERROR" and not j.cancelled else {"CANCELLED"}

    def execute(self, context):
        j = self._prepare(context, echo=bpy.app.background)
        if j is None:
            return {"CANCELLED"}
        j.run()
        return self._done(context.scene, j)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        j = self._prepare(context)
        if j is None:
            return {"CANCELLED"}
        wm = context.window_manager
        _RUNNING["job"] = j
        self._scene_name = context.scene.name
        j.start()
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        wm.progress_begin(0, 100)
        self._show_status(context, j)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        j = running_job()
        if j is None:
            return {"CANCELLED"}
        if event.type == "ESC" and event.value == "PRESS":
            j.cancel()
            j.message = "cancelling..."
            return {"RUNNING_MODAL"}
        if event.type == "TIMER":
            self._show_status(context, j)
            if j.done:
                self._cleanup(context)
                return self._done(bpy.data.scenes.get(self._scene_name), j)
        return {"PASS_THROUGH"}

    def cancel(self, context):
        # Blender ends the modal (e.g. a file is loaded): stop the thread, write nothing
        j = running_job()
        if j is not None:
            j.cancel()
            j.join(5.0)
        self._cleanup(context)

    def _show_status(self, context, j) -> None:
        context.window_manager.progress_update(int(100 * j.fraction))
        if context.workspace is not None:
            context.workspace.status_text_set(f"SymFrames: {j.message} ({100 * j.fraction:.0f}%)   Esc: cancel")
        _tag_redraw(context)

    def _cleanup(self, context) -> None:
        wm = context.window_manager
        if getattr(self, "_timer", None) is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        _RUNNING.clear()
        _tag_redraw(context)


class SYMFRAMES_OT_suggest_network(_Threaded, bpy.types.Operator):
    """Suggest a singularity network for the domain (a padded polycube, docs/suggest.md), written as editable
    curves into a new network collection (Esc cancels)"""

    bl_idname = "symframes.suggest_network"
    bl_label = "Suggest Network"
    bl_options = {"REGISTER", "UNDO"}

    def _prepare(self, context, echo: bool = False):
        s = context.scene.symframes
        try:
            V, F, _ = scene_io.read_domain(s.domain, context.evaluated_depsgraph_get())
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, f"SymFrames: no network suggested; the scene is unchanged: {error_text(e)}")
            return None
        return job.SuggestJob(V=V, F=F, sharp_angle=float(np.degrees(s.sharp_angle)), echo=echo)

    def _finish(self, scene, j):
        if j.cancelled:
            return "WARNING", "SymFrames: Suggest Network cancelled; the scene is unchanged"
        if j.error is not None:
            return "ERROR", f"SymFrames: no network suggested; the scene is unchanged: {error_text(j.error)}"
        net, rep = j.outcome
        print(rep.summary())
        s = scene.symframes
        level = "INFO"
        if net.sharp_edges is not None:  # no angle keeps just those: marks would have to be written on the domain
            level = "WARNING"
        V = j.V
        network = bpy.data.collections.new(f"{s.domain.name} Suggested Network")
        scene.collection.children.link(network)
        examples.add_network_curves(network, net, float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))))
        s.network = network
        s.use_sharp_angle = True
        if net.sharp_angle is not None and not np.isclose(np.degrees(s.sharp_angle), net.sharp_angle):
            s.sharp_angle = float(np.radians(net.sharp_angle))  # the creases the suggestion keeps, and only those
        if rep.target_tets:
            s.target_tets = max(int(s.target_tets), int(rep.target_tets))
        msg = (f"SymFrames: suggested {len(net.curves)} curve(s), {rep.nodes} node(s) in '{network.name}'; edit "
               "them, then Compute Field")
        if level == "WARNING":
            msg += (" (the suggestion chose the sharp creases edge by edge: noise or creases inside a chart left "
                    "smooth, see the console; the network is solved with the Sharp Angle instead)")
        return level, msg


class SYMFRAMES_OT_compute(_Threaded, bpy.types.Operator):
    """Compute the cross field of the domain and network (Esc cancels)"""

    bl_idname = "symframes.compute"
    bl_label = "Compute Field"
    bl_options = {"REGISTER", "UNDO"}

    glyphs: BoolProperty(name="Glyphs", default=True, description="Also sample cross glyphs")
    streamlines: BoolProperty(
        name="Streamlines", default=False,
        description="Also trace streamlines (they are always refreshed if the scene already has them)",
    )

    def _prepare(self, context, echo: bool = False):
        try:
            inp = scene_io.read_inputs(context)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return None
        scene = context.scene
        want_lines = self.streamlines or storage.output_object(scene, "streamlines") is not None
        return job.SolveJob(inp, display.DisplaySettings.from_scene(scene), want_glyphs=self.glyphs,
                            want_streamlines=want_lines, echo=echo)

    def _finish(self, scene, j):
        return finish_job(scene, j)


def hex_source(context):
    """What Hex Mesh meshes: the scene's stored field (``hex_inputs``)."""
    return hex_inputs(context)[0]


def hex_inputs(context):
    """(field, inputs): the scene's stored field (storage.solved_field),
    only as long as the scene's inputs (scene_io.Inputs, returned beside it)
    are the ones it was solved with (the same inputs key in the session and
    in a reopened file).  ValueError (or a SymFramesError) says why there is
    none, and what changed."""
    scene = context.scene
    me = storage.stored_field(scene)
    if me is None:
        raise ValueError("no field computed yet: press Compute Field first")
    solved = me.get(storage.INPUTS_KEY)
    if solved is None:
        raise ValueError("this field was stored without the inputs it was solved for, which Hex Mesh checks: "
                         "compute the field again")
    now = scene_io.read_inputs(context)
    if solved != now.field_key():
        what = scene_io.changes(me.get(storage.INPUTS_PARTS_KEY), now)
        what = f" ({'; '.join(what)})" if what else ""
        raise ValueError(f"the domain, the network or their settings changed since the field was computed"
                         f"{what}, so the field is not theirs: press Compute Field again (or undo the change)")
    return storage.solved_field(scene), now


def finish_hex_job(scene, j: job.HexJob) -> tuple[str, str]:
    """Write a finished hex job into the scene (only if it succeeded);
    returns (report level, message) as finish_job does."""
    if j.cancelled:
        return "WARNING", "SymFrames: hex meshing cancelled; the scene is unchanged"
    if j.error is not None:
        if not isinstance(j.error, (SymFramesError, ValueError)):
            traceback.print_exception(j.error)
        return "ERROR", error_text(j.error)
    if scene is None:
        return "ERROR", "SymFrames: the scene was deleted during hex meshing; nothing was written"
    out = j.outcome
    try:
        if out.resolved is not None:
            # the field the hex mesh is of: solved again finer (job.HexJob)
            print(f"SymFrames: {out.note}")
            write_outcome(scene, out.resolved)
        hex_mesh.write_hex_mesh(scene, out.hex_mesh, out.hex_id)
    except Exception as e:
        traceback.print_exc()
        return "ERROR", error_text(e)
    job.remember_hex(out.hex_id, out.hex_mesh)
    if scene.symframes.hex_only:
        hex_mesh.show_hex_only(scene, True)  # objects made since it was turned on
    else:
        scene.symframes.hex_only = True  # hides the field's objects while the hex mesh is shown
    r = out.hex_mesh.report
    irregular = ", ".join(f"{n} of valence {v}" for v, n in sorted(r.irregular.items())) or "none"
    msg = (f"SymFrames: {r.hexes:,} hexahedra, scaled Jacobian min {r.sj_min:.3f} mean {r.sj_mean:.3f}; "
           f"irregular edges {irregular}, "
           f"{'exactly the prescribed curves' if r.structure_exact else 'not the prescribed curves'}")
    if out.resolved is not None:
        rr = out.resolved.report
        msg += (f"; on the field solved again finer ({rr.sizes.get('tets', 0):,} tets, edge length "
                f"{rr.edge_length:.4g}): the map failed on the first, see the system console")
    if r.status != "valid":
        # written all the same, so that the defect can be seen, but said plainly
        return "WARNING", f"{msg}; the hex mesh is defective: {r.reason}"
    if r.warnings:
        return "WARNING", f"{msg}; valid with warnings: {'; '.join(r.warnings)}"
    return "INFO", msg


class SYMFRAMES_OT_hex_mesh(_Threaded, bpy.types.Operator):
    """Make a pure hexahedral mesh of the computed field, its irregular edges the network's curves (Esc cancels)"""

    bl_idname = "symframes.hex_mesh"
    bl_label = "Hex Mesh"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if not super().poll(context):
            return False
        if storage.stored_field(context.scene) is None:
            cls.poll_message_set("no field computed yet: press Compute Field first")
            return False
        return True

    def _prepare(self, context, echo: bool = False):
        s = context.scene.symframes
        try:
            finer = (FinerNear.parse(s.hex_finer_near, float(s.hex_finer_ratio), float(s.hex_finer_reach))
                     if s.hex_finer_near.strip() else None)
            options = HexOptions(cell_size=float(s.hex_cell_size) if s.hex_cell_size > 0 else None,
                                 target_hexes=int(s.hex_cells), smooth=bool(s.hex_smooth), finer_near=finer)
            source, inputs = hex_inputs(context)  # the inputs: the field is solved again if the map fails
            if finer is not None:
                finer.check(source)  # patches and curves the field has, before the job starts
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return None
        scene = context.scene
        return job.HexJob(source=source, options=options, echo=echo, inputs=inputs,
                          display=display.DisplaySettings.from_scene(scene),
                          want_glyphs=storage.output_object(scene, "glyphs") is not None,
                          want_streamlines=storage.output_object(scene, "streamlines") is not None)

    def _finish(self, scene, j):
        return finish_hex_job(scene, j)


def _stored_field(op, context):
    f = storage.frame_field(context.scene)
    if f is None:
        op.report({"ERROR"}, "no field computed yet: press Compute Field first")
    return f


class _FieldOperator:
    """Operators that only read the stored field: available once there is one."""

    @classmethod
    def poll(cls, context):
        if context.scene is None or storage.stored_field(context.scene) is None:
            cls.poll_message_set("no field computed yet: press Compute Field first")
            return False
        return True


class SYMFRAMES_OT_show_glyphs(_FieldOperator, bpy.types.Operator):
    """Sample cross glyphs from the stored field again (no re-solve)"""

    bl_idname = "symframes.show_glyphs"
    bl_label = "Show Cross Glyphs"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        try:
            f = _stored_field(self, context)
            if f is None:
                return {"CANCELLED"}
            ds = display.DisplaySettings.from_scene(scene)
            mono = None
            if ds.colour == "MONODROMY":
                mono = display.vertex_monodromy(f.mesh, storage.field_omega(scene),
                                                storage.network_face_ids(scene))
            P, Q, err = display.glyph_samples(f, ds, storage.read_adaptation(scene.symframes.field), mono)
            if len(P) == 0:
                self.report({"ERROR"}, "no glyph to show: raise Glyphs, or move the slice plane into the solid")
                return {"CANCELLED"}
            glyphs.write_glyphs(scene, P, Q, err, display.ERROR_ATTRIBUTES.get(ds.colour, glyphs.ERROR_ATTRIBUTE))
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"SymFrames: {len(P):,} glyphs")
        return {"FINISHED"}


class SYMFRAMES_OT_trace_streamlines(_FieldOperator, bpy.types.Operator):
    """Trace streamlines of the stored field (no re-solve)"""

    bl_idname = "symframes.trace_streamlines"
    bl_label = "Trace Streamlines"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        wm = context.window_manager
        try:
            f = _stored_field(self, context)
            if f is None:
                return {"CANCELLED"}
            wm.progress_begin(0, 1)
            try:
                lines, fams = display.streamlines(f, display.DisplaySettings.from_scene(scene))
            finally:
                wm.progress_end()
            if not lines:
                self.report({"ERROR"}, "no streamline could be traced; use more seeds or move the slice plane")
                return {"CANCELLED"}
            streamline_curves.write_streamlines(scene, lines, fams, scene.symframes.streamline_radius)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"SymFrames: {len(lines):,} streamlines")
        return {"FINISHED"}


class SYMFRAMES_OT_show_singular_faces(_FieldOperator, bpy.types.Operator):
    """Show the faces where the field is singular; spurious ones (off the network) in red"""

    bl_idname = "symframes.show_singular_faces"
    bl_label = "Show Singular Faces"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            counts = diagnostics.write_singular_faces(context.scene)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return {"CANCELLED"}
        msg = f"SymFrames: {counts['singular']:,} singular faces, {counts['spurious']:,} spurious"
        if counts["closest_differs"]:
            msg += (f"; closest-rotation matching reads {counts['closest_differs']} face(s) differently (edges "
                    "turning by ~45 degrees; exports carry the field's own matchings)")
        self.report({"INFO"}, msg)
        return {"FINISHED"}


class SYMFRAMES_OT_show_omega(_FieldOperator, bpy.types.Operator):
    """Draw the Darboux derivative omega as an arrow per tet edge: rotation axis, length by angle"""

    bl_idname = "symframes.show_omega"
    bl_label = "Show Omega Arrows"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        try:
            f = _stored_field(self, context)
            if f is None:
                return {"CANCELLED"}
            omega = storage.field_omega(scene)
            P, W, e = display.omega_arrows(f, omega, display.DisplaySettings.from_scene(scene))
            if len(P) == 0:
                self.report({"ERROR"}, "no edge to draw: move the slice plane into the solid (Slice Position), "
                                       "or pick the Volume region")
                return {"CANCELLED"}
            omega_arrows.write_arrows(scene, P, W, e, f.mesh.mean_edge_length)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return {"CANCELLED"}
        self.report({"INFO"}, f"SymFrames: {len(P):,} omega arrows, largest rotation "
                              f"{np.degrees(np.linalg.norm(W, axis=1).max()):.3g} deg")
        return {"FINISHED"}


class SYMFRAMES_OT_show_slice(_FieldOperator, bpy.types.Operator):
    """Show tet faces colored by monodromy (along the slice plane) or adaptation error (surface, cut away)"""

    bl_idname = "symframes.show_slice"
    bl_label = "Show Error Slice"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        scene = context.scene
        try:
            if _stored_field(self, context) is None:
                return {"CANCELLED"}
            st = error_slice.write_slice(scene, scene.symframes.slice_quantity)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return {"CANCELLED"}
        what = "monodromy" if st["quantity"] == "MONODROMY" else "adaptation error"
        self.report({"INFO"}, f"SymFrames: {st['faces']:,} faces, {what} mean {st['mean_deg']:.3g} deg, "
                              f"max {st['max_deg']:.3g} deg")
        return {"FINISHED"}


class SYMFRAMES_OT_clear(bpy.types.Operator):
    """Remove the stored field and every SymFrames output object (glyphs, streamlines, diagnostics)"""

    bl_idname = "symframes.clear"
    bl_label = "Clear Results"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        if context.scene.symframes.hex_only:
            context.scene.symframes.hex_only = False  # shows again what it hid
        removed = storage.clear_results(context.scene)
        job.forget_results()
        # shared helpers (the glyph node groups, the materials), once nothing uses them
        glyphs.remove_unused_helpers()
        omega_arrows.remove_unused_helpers()
        diagnostics.remove_unused_materials()
        error_slice.remove_unused_material()
        hex_mesh.remove_unused_helpers()
        if not removed:
            self.report({"INFO"}, "SymFrames: nothing to clear")
            return {"CANCELLED"}
        self.report({"INFO"}, "SymFrames: results cleared")
        return {"FINISHED"}


class SYMFRAMES_OT_add_example(bpy.types.Operator):
    """Add a built-in example: domain mesh, network curves, and the panel settings to solve it"""

    bl_idname = "symframes.add_example"
    bl_label = "Add SymFrames Example"
    bl_options = {"REGISTER", "UNDO"}

    example: EnumProperty(
        name="Example",
        items=[(k, k.capitalize(), examples.DESCRIPTIONS.get(k, "")) for k in EXAMPLES],
        default="cylinder",
    )

    def execute(self, context):
        try:
            examples.build_example(context.scene, self.example)
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return {"CANCELLED"}
        return {"FINISHED"}


class SYMFRAMES_OT_apply_preset(bpy.types.Operator):
    """Set the resolution and iterations for a quality: Draft, Standard (the defaults) or Fine"""

    bl_idname = "symframes.apply_preset"
    bl_label = "Apply Quality Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Preset", items=properties.PRESET_ITEMS, default="STANDARD")

    def execute(self, context):
        s = context.scene.symframes
        values = properties.PRESETS[self.preset]
        for key, value in values.items():
            setattr(s, key, value)
        self.report({"INFO"}, f"SymFrames: {self.preset.capitalize()} preset, about {values['target_tets']:,} "
                              f"tets, at most {values['max_iterations']} iterations")
        return {"FINISHED"}


class SYMFRAMES_OT_apply_hex_preset(bpy.types.Operator):
    """Set the automatic hex cell size for a number of cells: Coarse, Medium (the default) or Fine"""

    bl_idname = "symframes.apply_hex_preset"
    bl_label = "Apply Hex Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Preset", items=properties.HEX_PRESET_ITEMS, default="MEDIUM")

    def execute(self, context):
        s = context.scene.symframes
        s.hex_cells = properties.HEX_PRESETS[self.preset]
        s.hex_cell_size = 0.0  # the preset is a cell count: the automatic size
        self.report({"INFO"}, f"SymFrames: {self.preset.capitalize()} hex mesh, about {s.hex_cells:,} cells")
        return {"FINISHED"}


class SYMFRAMES_OT_finer_near_selected(bpy.types.Operator):
    """Set Finer Near to the boundary patches (regions between sharp edges) of the domain's selected faces, keeping
    the curves it names"""

    bl_idname = "symframes.finer_near_selected"
    bl_label = "Finer Near Selected Faces"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        s = context.scene.symframes
        if s.domain is None or s.domain.type != "MESH":
            cls.poll_message_set("no domain mesh: choose the solid first")
            return False
        if storage.stored_field(context.scene) is None:
            cls.poll_message_set("no field computed yet: press Compute Field first")
            return False
        return True

    def execute(self, context):
        s = context.scene.symframes
        obj = s.domain
        if obj.mode == "EDIT":
            obj.update_from_editmode()  # the selection as the user sees it
        polys = [p for p in obj.data.polygons if p.select]
        if not polys:
            self.report({"ERROR"}, f"SymFrames: no face of '{obj.name}' is selected: select faces of the solid in "
                                   "Edit Mode (face select), then press Finer Near Selected Faces")
            return {"CANCELLED"}
        try:
            field = hex_source(context)
            M = obj.matrix_world
            ids = FinerNear.patches_at(field, [tuple(M @ p.center) for p in polys])
            kept = FinerNear.parse(s.hex_finer_near).curves if s.hex_finer_near.strip() else ()
        except (SymFramesError, ValueError) as e:
            self.report({"ERROR"}, error_text(e))
            return {"CANCELLED"}
        items = [f"patch {p}" for p in ids] + [f"curve '{c}'" if isinstance(c, str) else f"curve {c}" for c in kept]
        s.hex_finer_near = ", ".join(items)
        self.report({"INFO"}, f"SymFrames: Finer Near {s.hex_finer_near} ({len(polys)} selected faces)")
        return {"FINISHED"}


CLASSES = (
    SYMFRAMES_OT_check_network,
    SYMFRAMES_OT_suggest_network,
    SYMFRAMES_OT_compute,
    SYMFRAMES_OT_hex_mesh,
    SYMFRAMES_OT_show_glyphs,
    SYMFRAMES_OT_trace_streamlines,
    SYMFRAMES_OT_show_singular_faces,
    SYMFRAMES_OT_show_omega,
    SYMFRAMES_OT_show_slice,
    SYMFRAMES_OT_clear,
    SYMFRAMES_OT_add_example,
    SYMFRAMES_OT_apply_preset,
    SYMFRAMES_OT_apply_hex_preset,
    SYMFRAMES_OT_finer_near_selected,
)
