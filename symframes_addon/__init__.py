"""The Blender side of SymFrames: everything that imports bpy.

It only converts between Blender data and arrays: every rule that decides
what a field is (regular and spurious faces, where adaptation is measured,
the report's form) is the solver's, and the add-on imports nothing from it
but the names of solver/__init__.py, solver.io and solver.examples
(tests/test_addon_imports.py).

Modules, in the order data flows through them:

* properties        -- scene settings and per-curve settings (saved in the .blend)
* scene_io          -- domain mesh + network curves -> solver arrays
* job               -- the solve and hex meshing, off the main thread, cancellable
* display           -- glyph samples, streamlines and the diagnostics' slice
                       faces and edges from a field (solver.FrameField and its sampling)
* storage           -- the solved field (frames, omega) in the .blend; the output objects
* glyphs            -- instanced cross glyphs via Geometry Nodes
* streamline_curves -- streamlines as a bevelled curve object
* diagnostics       -- singular faces of a stored field as a mesh object
* omega_arrows      -- the Darboux derivative omega as instanced arrows
* error_slice       -- tet faces coloured by monodromy or adaptation error
* hex_mesh          -- the hex mesh as cells (quality colors, the Hex View
                       modifier: explode, fall away) and its irregular edges
* exchange          -- Export Field, Export Hex Mesh, Import Network, the tet
                       mesh as an object
* operators, panel, menus -- the user interface (sidebar tab; Object, Add and
                       File menus, which F3 search finds)
* examples, presentation -- example scenes; camera, lights, render settings
"""

import bpy

from . import exchange, menus, operators, panel, properties

_register_classes, _unregister_classes = bpy.utils.register_classes_factory(
    properties.CLASSES + operators.CLASSES + exchange.CLASSES + panel.CLASSES + menus.CLASSES
)


def register():
    _register_classes()
    properties.register_properties()
    menus.register_menus()


def unregister():
    job = operators.running_job()
    if job is not None:
        job.cancel()
    menus.unregister_menus()
    properties.unregister_properties()
    _unregister_classes()  # in reverse order
