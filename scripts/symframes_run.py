"""Compute a SymFrames field headless and save a .blend (and a PNG).

Works with the Blender binary and with the bpy module::

    blender --background --python scripts/symframes_run.py -- [ARGS]
    python scripts/symframes_run.py [ARGS]          # ./dev.sh demo [ARGS]

Without arguments: build the default example (cylinder), compute it, add
glyphs below a horizontal slice plane and streamlines seeded on it, and
write out/cylinder.blend and out/cylinder.png (Cycles, CPU).  With
--blend FILE the domain, network and settings stored in FILE's SymFrames
panel are used instead.

Under the Blender binary the solver needs scipy and pytetwild: install the
SymFrames extension in that Blender (its wheels provide them), or keep this
checkout's .venv, whose site-packages is then used as a fallback.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "symframes"


def script_args(argv: list[str]) -> list[str]:
    """The script's own arguments: after '--' when run by Blender (none
    without it: the rest are Blender's)."""
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    import bpy

    return [] if bpy.app.binary_path else argv[1:]


def ensure_solver_dependencies() -> None:
    """scipy and pytetwild importable, or exit with what to do."""
    missing = [m for m in ("scipy", "pytetwild") if importlib.util.find_spec(m) is None]
    if not missing:
        return
    venv = os.path.join(ROOT, ".venv", "lib", f"python{sys.version_info[0]}.{sys.version_info[1]}", "site-packages")
    if os.path.isdir(venv):
        sys.path.append(venv)  # after Blender's own modules: its numpy stays first
        missing = [m for m in missing if importlib.util.find_spec(m) is None]
    if missing:
        sys.exit(f"symframes_run.py: {', '.join(missing)} not found; install the SymFrames extension in this "
                 "Blender (Edit > Preferences > Get Extensions > Install from Disk), or run ./dev.sh demo")


def parse_args(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="symframes_run.py", description=__doc__.split("\n\n")[0])
    src = p.add_mutually_exclusive_group()
    src.add_argument("--example", default=None,
                     help="build a built-in example: cube, cylinder, torus, ball, plate (default: cylinder)")
    src.add_argument("--blend", default=None, help="open this .blend and solve its SymFrames settings")
    p.add_argument("--out-dir", default=os.path.join(ROOT, "out"), help="output folder (default: out/)")
    p.add_argument("--name", default=None, help="output file stem (default: the example or .blend name)")
    p.add_argument("--edge-length", type=float, default=None, help="target tet edge length (default: the scene's)")
    p.add_argument("--auto-resolution", action="store_true", help="let the solver pick the edge length")
    p.add_argument("--iterations", type=int, default=None, help="Levenberg-Marquardt iterations")
    p.add_argument("--glyphs", type=int, default=None, help="number of cross glyphs (example default 900)")
    p.add_argument("--glyph-size", type=float, default=None, help="glyph bar length (default: the scene's)")
    p.add_argument("--no-cutaway", action="store_true", help="show glyphs in the whole solid")
    p.add_argument("--streamlines", type=int, default=None,
                   help="streamline seeds (0: none; example default 25 on a horizontal slice plane)")
    p.add_argument("--seed-volume", action="store_true",
                   help="seed streamlines throughout the solid instead of on the slice plane")
    p.add_argument("--family", default=None, choices=["X", "Y", "Z", "ALL"], help="streamline axis family")
    p.add_argument("--hex", action="store_true", help="also make the hex mesh and show it (cells coloured by "
                   "scaled Jacobian, the front ones falling away) instead of glyphs and streamlines")
    p.add_argument("--hex-cells", type=int, default=None, help="with --hex: cells aimed at (default: the scene's)")
    p.add_argument("--hex-finer-near", default=None, metavar="WHERE", help="with --hex: Finer Near, smaller cells "
                   "near these patches and curves (e.g. \"patch 5\"; docs/hexmesh.md)")
    p.add_argument("--fall-away", type=float, default=0.5, help="with --hex: the Hex View's Fall Away (0-1)")
    p.add_argument("--explode", type=float, default=0.15, help="with --hex: the Hex View's Explode (0-0.9)")
    p.add_argument("--no-render", action="store_true", help="skip the PNG")
    p.add_argument("--resolution", default="800x600", help="PNG size WxH (default 800x600)")
    p.add_argument("--samples", type=int, default=16, help="Cycles samples, denoised (default 16)")
    p.add_argument("--posterize", type=int, default=0, metavar="LEVELS",
                   help="round the PNG's channels to LEVELS values (e.g. 24) for a much smaller file")
    return p.parse_args(argv)


def load_addon():
    """The add-on package of this checkout, registered unless an installed
    copy already registered the same classes."""
    import bpy

    if PACKAGE in sys.modules:
        mod = sys.modules[PACKAGE]
    else:
        spec = importlib.util.spec_from_file_location(PACKAGE, os.path.join(ROOT, "__init__.py"),
                                                      submodule_search_locations=[ROOT])
        mod = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = mod
        spec.loader.exec_module(mod)
    if not hasattr(bpy.types.Scene, "symframes"):
        mod.register()
    return mod


def main(argv: list[str]) -> int:
    args = parse_args(script_args(argv))
    import bpy

    ensure_solver_dependencies()
    addon = load_addon()
    from importlib import import_module

    examples = import_module(f"{PACKAGE}.symframes_addon.examples")
    presentation = import_module(f"{PACKAGE}.symframes_addon.presentation")
    storage = import_module(f"{PACKAGE}.symframes_addon.storage")
    del addon

    if args.blend:
        bpy.ops.wm.open_mainfile(filepath=os.path.abspath(args.blend))
        name = args.name or os.path.splitext(os.path.basename(args.blend))[0]
    else:
        bpy.ops.wm.read_factory_settings(use_empty=True)
        example = args.example or "cylinder"
        examples.build_example(bpy.context.scene, example)
        name = args.name or example
    scene = bpy.context.scene
    s = scene.symframes
    if args.edge_length is not None:
        s.auto_resolution, s.edge_length = False, args.edge_length
    if args.auto_resolution:
        s.auto_resolution = True
    if args.iterations is not None:
        s.max_iterations = args.iterations
    if args.glyph_size is not None:
        s.glyph_size = args.glyph_size
    if not args.blend:
        # the demo view: a horizontal slice half way up, glyphs below it,
        # streamlines seeded on it; a .blend keeps its own display settings
        s.slice_axis, s.slice_offset, s.flip_clip = "Z", 0.5, False
        s.glyph_count, s.glyph_region = 900, "CUTAWAY"
        s.streamline_seeds, s.streamline_on_plane, s.streamline_family = 25, True, "ALL"
    if args.glyphs is not None:
        s.glyph_count = args.glyphs
    if args.no_cutaway:
        s.glyph_region = "VOLUME"
    if args.streamlines:
        s.streamline_seeds = args.streamlines
    if args.seed_volume:
        s.streamline_on_plane = False
    if args.family is not None:
        s.streamline_family = {"X": "0", "Y": "1", "Z": "2"}.get(args.family, "ALL")
    with_lines = args.streamlines != 0 and (not args.blend or args.streamlines is not None)

    t = time.perf_counter()
    try:
        bpy.ops.symframes.compute(streamlines=with_lines)
    except RuntimeError as e:  # the operator's error report
        print(f"symframes_run.py: {e}", file=sys.stderr)
        return 1
    print(f"SymFrames: solved in {time.perf_counter() - t:.1f} s")
    print(storage.stored_report(scene).summary())
    if args.hex:
        if args.hex_cells is not None:
            s.hex_cell_size, s.hex_cells = 0.0, args.hex_cells
        if args.hex_finer_near is not None:
            s.hex_finer_near = args.hex_finer_near
        t = time.perf_counter()
        try:
            bpy.ops.symframes.hex_mesh()
        except RuntimeError as e:
            print(f"symframes_run.py: {e}", file=sys.stderr)
            return 1
        print(f"SymFrames: hex mesh in {time.perf_counter() - t:.1f} s")
        hex_mesh = import_module(f"{PACKAGE}.symframes_addon.hex_mesh")
        print(hex_mesh.stored_report(scene).summary())
        s.hex_fall_away, s.hex_explode = args.fall_away, args.explode
        # the cells only: the solid, glyphs and streamlines stay out of the picture
        hexes = hex_mesh.hex_object(scene)
        for o in scene.objects:
            if o is not hexes and not (o.type == "CURVE" and "Irregular" in o.name):
                o.hide_render = True

    os.makedirs(args.out_dir, exist_ok=True)
    if not args.no_render:
        w, h = (int(x) for x in args.resolution.lower().split("x"))
        if scene.camera is None:
            shown = [o for o in scene.objects if o.type in {"MESH", "CURVE"} and not o.hide_render]
            frame = [s.domain] if s.domain else shown
            if args.hex:
                frame = [o for o in shown if not o.hide_render] or frame
            presentation.setup_presentation(scene, frame, w, h, args.samples)
        else:  # a .blend with its own camera and lights
            presentation.setup_cycles(scene, w, h, args.samples)
    blend = os.path.join(os.path.abspath(args.out_dir), f"{name}.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    print(f"SymFrames: wrote {blend}")
    if not args.no_render:
        png = os.path.join(os.path.abspath(args.out_dir), f"{name}.png")
        t = time.perf_counter()
        presentation.render_png(scene, png)
        if args.posterize:
            presentation.posterize_png(png, args.posterize)
        print(f"SymFrames: rendered {png} in {time.perf_counter() - t:.1f} s")
    return 0


if __name__ == "__main__":
    code = main(sys.argv)
    if code:
        sys.exit(code)
