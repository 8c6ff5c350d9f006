"""Install a SymFrames extension zip as a user does and run the add-on.

Run with the Python of a venv holding the bpy module of the Blender release
to test, with BLENDER_USER_RESOURCES set to an empty temporary folder::

    BLENDER_USER_RESOURCES=/tmp/res python scripts/extension_smoke.py dist/symframes-....zip [cube|cylinder]

The zip is installed with bpy.ops.extensions.package_install_files (what
Install from Disk calls) and enabled; Blender unpacks the wheels the zip
bundles for this platform and Python into the user resources'
extensions/.local site-packages, which comes first on sys.path as in
Blender.  Then: an example's compute (the cylinder's needs Levenberg-Marquardt
iterations, and the step fails if it took none; their count is recorded),
glyphs, streamlines, the diagnostics (singular faces, error slice), Export
Field (MEDIT + .fra + .perm), save the .blend and reload it, glyphs again
from the reloaded file, a hex mesh of the reloaded field (its Hex View
modifier evaluated exploded and fallen away, exported as .vtu), clear, and
Import Network (a JSON network and its OBJ written by the bundled solver,
imported and checked with Check Network).  Each step runs only if the
previous ones passed; the last stdout line is ``RESULT {json}`` with a
result per step (``ok`` or the error) and the versions that ran; the exit
code is 0 (scripts/matrix.py counts any other, a crash on exit, as a
failure).  Used by tests/test_extension.py and scripts/matrix.py.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import os
import sys
import time
import traceback

STEPS = ("install", "enable", "compute", "glyphs", "streamlines", "diagnostics", "export_field", "save_reload", "hex",
         "clear", "import_network")
ADDON = "bl_ext.user_default.symframes"


class _Stop(Exception):
    pass


def main(argv: list[str]) -> int:
    zip_path = os.path.abspath(argv[0])
    example = argv[1] if len(argv) > 1 else "cube"
    res = os.environ["BLENDER_USER_RESOURCES"]
    py = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    site = os.path.join(res, "extensions", ".local", "lib", py, "site-packages")
    os.makedirs(site, exist_ok=True)
    sys.path.insert(0, site)  # as in Blender: the bundled wheels, not the venv's copies
    import bpy
    import numpy

    out: dict = {"blender": bpy.app.version_string, "python": ".".join(map(str, sys.version_info[:3])),
                 "numpy": numpy.__version__, "example": example, "steps": {}, "seconds": {}}

    def step(name, fn):
        t0 = time.perf_counter()
        try:
            value = fn()
        except Exception as ex:  # the step's failure is the result
            msg = f"{type(ex).__name__}: {ex}".strip().splitlines()
            out["steps"][name] = msg[-1][:300] if msg else type(ex).__name__
            out["traceback"] = traceback.format_exc()[-3000:]
            raise _Stop() from None
        out["seconds"][name] = round(time.perf_counter() - t0, 2)
        out["steps"][name] = "ok"
        return value

    def finished(result, what):
        if set(result) != {"FINISHED"}:
            raise RuntimeError(f"{what} returned {sorted(result)}")

    def install():
        finished(bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                          enable_on_install=True), "package_install_files")

    def enable():
        if ADDON not in sys.modules:
            importlib.import_module(ADDON)  # raises the error enabling met (e.g. scipy vs numpy)
            raise RuntimeError("installed but not enabled")
        mod = sys.modules[ADDON]
        import scipy

        tetwild = importlib.import_module(ADDON + ".solver.mesh.tetwild")
        mesher = tetwild.mesher_name()
        spec = importlib.util.find_spec(mesher) if mesher else None  # found, not imported (the worker does)
        out["files"] = {"addon": mod.__file__, "scipy": scipy.__file__, "mesher": spec.origin if spec else ""}
        out["scipy"], out["mesher"] = scipy.__version__, mesher
        if not mesher:
            raise RuntimeError("no fTetWild bindings (pytetwild or wildmeshing) were installed")
        ops = ("compute", "check_network", "show_glyphs", "trace_streamlines", "show_singular_faces",
               "show_slice", "hex_mesh", "export_hex_mesh", "clear")
        missing = [n for n in ops if not hasattr(bpy.ops.symframes, n)]
        if missing:
            raise RuntimeError(f"operators missing: {missing}")

    scene = bpy.context.scene

    def roles():
        return {o.get("symframes_role"): o for o in bpy.context.scene.objects if o.get("symframes_role")}

    def compute():
        bpy.ops.symframes.add_example(example=example)
        s = scene.symframes
        s.glyph_count, s.streamline_seeds = 300, 10
        s.auto_resolution = False  # coarse and quick: the smoke test checks the install, not the resolution
        s.edge_length = 0.4 if example == "cube" else 0.3
        finished(bpy.ops.symframes.check_network(), "check_network")
        finished(bpy.ops.symframes.compute(streamlines=False), "compute")
        report = json.loads(s.field["symframes_report"])
        out["tets"] = report["sizes"]["tets"]
        out["lm_iterations"] = sum(1 for it in report.get("lm", {}).get("iterations", []) if it["iteration"] > 0)
        out["status"] = report.get("status", "")
        if example == "cylinder" and not out["lm_iterations"]:
            raise RuntimeError("the cylinder's field took no Levenberg-Marquardt iteration")
        if out["status"] != "converged":
            raise RuntimeError(f"the field did not converge: {report.get('status_reason', '')}")

    def glyphs():
        finished(bpy.ops.symframes.show_glyphs(), "show_glyphs")
        out["glyphs"] = len(roles()["glyphs"].data.vertices)

    def streamlines():
        finished(bpy.ops.symframes.trace_streamlines(), "trace_streamlines")
        out["streamlines"] = len(roles()["streamlines"].data.splines)

    def diagnostics():
        finished(bpy.ops.symframes.show_singular_faces(), "show_singular_faces")
        finished(bpy.ops.symframes.show_slice(), "show_slice")
        out["roles"] = sorted(roles())

    def export_field():
        path = os.path.join(os.getcwd(), "smoke_field.mesh")
        finished(bpy.ops.symframes.export_field(filepath=path, file_format="MEDIT"), "export_field")
        for ext in (".mesh", ".fra", ".perm"):
            if not os.path.getsize(path[:-5] + ext):
                raise RuntimeError(f"the field export's {ext} is empty")

    def save_reload():
        path = os.path.join(os.getcwd(), "smoke.blend")
        finished(bpy.ops.wm.save_as_mainfile(filepath=path), "save_as_mainfile")
        finished(bpy.ops.wm.open_mainfile(filepath=path), "open_mainfile")
        if sorted(roles()) != out["roles"]:
            raise RuntimeError(f"after reload: {sorted(roles())} != {out['roles']}")
        finished(bpy.ops.symframes.show_glyphs(), "show_glyphs after reload")
        if len(roles()["glyphs"].data.vertices) != out["glyphs"]:
            raise RuntimeError("glyphs differ after reload")

    def hex():
        # the reloaded file's field, with the network its solve traced (kept in the file)
        s = bpy.context.scene.symframes  # the scene of the reloaded file
        s.hex_cells = 300
        finished(bpy.ops.symframes.hex_mesh(), "hex_mesh")
        obj = roles()["hex_mesh"]
        report = json.loads(obj.data["symframes_hex_report"])
        out["hexes"], out["hex_status"] = report["hexes"], report["status"]
        if len(obj.data.polygons) != 6 * report["hexes"]:
            raise RuntimeError(f"{len(obj.data.polygons)} faces for {report['hexes']} hexahedra")
        # the Hex View modifier's nodes exist in this Blender: shrink the cells, hide half of them
        s.hex_explode, s.hex_fall_away = 0.5, 0.5
        dg = bpy.context.evaluated_depsgraph_get()
        dg.update()
        ev = obj.evaluated_get(dg)
        me = ev.to_mesh()
        shown = len(me.polygons)
        ev.to_mesh_clear()
        if not 0 < shown < len(obj.data.polygons):
            raise RuntimeError(f"Hex View shows {shown} of {len(obj.data.polygons)} faces at Fall Away 0.5")
        path = os.path.join(os.getcwd(), "smoke_hex.vtu")
        finished(bpy.ops.symframes.export_hex_mesh(filepath=path, file_format="VTU"), "export_hex_mesh")
        if not os.path.getsize(path):
            raise RuntimeError("the hex mesh export is empty")

    def clear():
        finished(bpy.ops.symframes.clear(), "clear")
        out["left"] = sorted(roles())
        if out["left"]:
            raise RuntimeError(f"left behind: {out['left']}")

    def import_network():
        # a network file as another session of the bundled solver writes it
        io = importlib.import_module(ADDON + ".solver.io")
        V, F, net = importlib.import_module(ADDON + ".solver.examples").load_example("cube")
        io.write_obj(os.path.join(os.getcwd(), "part.obj"), V, F)
        path = os.path.join(os.getcwd(), "part.json")
        io.write_network(path, net, surface="part.obj")
        before = set(bpy.data.objects.keys())
        finished(bpy.ops.symframes.import_network(filepath=path), "import_network")
        added = set(bpy.data.objects.keys()) - before
        if len(added) != 1 + len(net.curves):
            raise RuntimeError(f"import added {sorted(added)}, expected the domain and {len(net.curves)} curve(s)")
        finished(bpy.ops.symframes.check_network(), "check_network after import")

    try:
        for name in STEPS:
            step(name, locals()[name])
    except _Stop:
        pass
    print("RESULT " + json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
