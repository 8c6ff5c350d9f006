"""SymFrames: 3D cross fields from Symmetric Moving Frames (Corman & Crane 2019).

The extension's entry point: registration only.  The add-on lives in
symframes_addon/, the bpy-free solver in solver/.
"""


def register():
    from . import symframes_addon

    symframes_addon.register()


def unregister():
    from . import symframes_addon

    symframes_addon.unregister()
