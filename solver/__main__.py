"""Command line: ``python -m solver NETWORK.json [SURFACE.obj] [options]``.

Reads a closed triangle surface (OBJ) and a curve network (JSON, format in
solver/io/formats.py), solves, prints the report and writes the result (.npz).

    python -m solver part.json -o part.npz
    python -m solver --example ball --edge-length 0.1 --profile
    python -m solver --export-example ball out/   # write ball.obj + ball.json
    python -m solver part.json --export part.vtu --export part.mesh   # ParaView, CubeCover
    python -m solver --tet-network field.ovm --tag-convention valence  # a tagged tet mesh's network
    python -m solver part.json --hex part.vtu --cell-size 0.1   # solve, then a hex mesh (docs/hexmesh.md)
    python -m solver --from-result part.npz --hex part.mesh     # a hex mesh of a stored field, no solve
    python -m solver part.obj --suggest-network part.json      # a network for a bare surface (docs/suggest.md)
    python -m solver part.obj --hex part.vtu                    # no network: suggest one, solve, mesh

Exit status: 0 solved and converged (and with --hex: a valid hex mesh
written); 1 bad input or settings (nothing written; this includes a mesh
past the tet / memory limit, see --max-tets); 2 usage; 3 solved but not
converged (the result is written and the report says why: LM stopped at
its cap or the structure penalty is above the discretisation level), or a
hex mesh written that the quality report calls defective, or (with
--mesh-unconverged) one of a field that did not converge; 4 no hex mesh
(the field's result is written, the reason printed; a network no hex mesh
can have is said before the solve, and nothing is written); 130 cancelled.
No output may name an input or another output (refused before any work).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from . import checks, io
from .errors import Cancelled, OptionsError, OutputError, SymFramesError
from .examples import EXAMPLES, load_example
from .io.atomic import check_distinct, check_output_path
from .pipeline import INITS, FieldProblem, solve_resolved
from .precheck import check

TAG_CONVENTIONS = ("index", "negated", "valence")


EXIT_NOT_CONVERGED = 3
EXIT_NO_HEX_MESH = 4


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m solver", description="Symmetric Moving Frames: a 3D cross field "
                                "from a closed surface and a curve network.")
    p.add_argument("network", nargs="?", help="network JSON file (may name its surface)")
    p.add_argument("surface", nargs="?", help="surface OBJ file (default: the one the JSON names)")
    p.add_argument("--example", choices=sorted(EXAMPLES), help="solve a built-in example instead")
    p.add_argument("--suggest-network", metavar="FILE.json", help="with a bare SURFACE.obj (no network): write the "
                   "suggested network there (docs/suggest.md) and exit unless --hex or --export asks for more; a "
                   "bare SURFACE.obj without it has its network suggested and solved")
    p.add_argument("--export-example", nargs=2, metavar=("NAME", "DIR"),
                   help="write a built-in example as NAME.obj + NAME.json into DIR and exit")
    p.add_argument("--tet-network", metavar="FILE", help="read the domain and network from a tet mesh whose edges "
                   "carry an integer singularity tag (.ovm edge property or MEDIT .mesh Edges) instead of JSON")
    p.add_argument("--tag-convention", choices=TAG_CONVENTIONS, default=None,
                   help="with --tet-network: 'index' = tag in quarter turns, +1 the valence-3 edge (SymFrames' "
                   "sign); 'negated' = the opposite sign; 'valence' = hexahedra around the edge (3 -> +1/4). "
                   "Default: detected (the one convention under which the network satisfies Poincare-Hopf)")
    p.add_argument("--tag-property", metavar="NAME", help="with --tet-network .ovm: the edge property holding "
                   "the tags (default: the only integer edge property)")
    p.add_argument("--sharp-angle", type=float, metavar="DEG", help="with --tet-network: boundary edges whose "
                   "dihedral angle turns by more than DEG degrees are sharp too (besides the tagged boundary edges)")
    p.add_argument("-o", "--output", help="result .npz (default: next to the network file, or NAME.npz)")
    p.add_argument("--export", action="append", default=[], metavar="FILE",
                   help="also write the field as FILE: .vtu (ParaView), .mesh (MEDIT + .fra + .perm, CubeCover), "
                   ".ovm (OpenVolumeMesh) or .qtn (AlgoHex); may be repeated")
    p.add_argument("--hex", action="append", default=[], metavar="FILE",
                   help="also make a hex mesh and write it as FILE: .vtu, .vtk, .mesh (MEDIT), .msh (Gmsh), .inp "
                   "(Abaqus/CalculiX), .exo (Exodus II), .bdf/.nas (Nastran), .med (MED), .ovm (OpenVolumeMesh) or "
                   ".hexex (the integer-grid map, for HexEx / HexHex); may be repeated")
    p.add_argument("--cell-size", type=float, metavar="LENGTH", help="with --hex: the hex edge length (default: "
                   "about --hex-cells cells, finer where the network needs it)")
    p.add_argument("--hex-cells", type=int, metavar="N", help="with --hex and no --cell-size: the number of "
                   "cells aimed at (default 3000)")
    p.add_argument("--finer-near", metavar="WHERE", help="with --hex: smaller cells near these boundary patches and "
                   "curves, e.g. \"patch 3, curve 2\" (patches numbered from 1 as the hex mesh's boundary groups, "
                   "curves from 0 as given, or \"curve 'name'\"); docs/hexmesh.md")
    p.add_argument("--finer-ratio", type=float, metavar="R", help="with --finer-near: the cell size there as a "
                   "fraction of the cell size (default 0.5)")
    p.add_argument("--finer-reach", type=float, metavar="CELLS", help="with --finer-near: the distance, in cells, "
                   "over which the size grows back (default 4)")
    p.add_argument("--no-smooth", action="store_true", help="with --hex: keep the vertices where the integer-grid "
                   "map puts them (no optimisation of the cells' shape)")
    p.add_argument("--from-result", metavar="FILE.npz", help="with --hex: mesh the field stored in a result file "
                   "instead of solving (with --export: write that field too; with --check: only check the file and "
                   "the hex settings)")
    p.add_argument("--mesh-unconverged", action="store_true", help="with --hex: mesh a field that did not converge "
                   "anyway (default: refused, exit 3); the exit status stays 3")
    p.add_argument("--edge-length", type=float, help="target tet edge length (default: automatic)")
    p.add_argument("--target-tets", type=int, help="tet count aimed at when the edge length is automatic (default "
                   "15,000, which the network may exceed up to --tets-ceiling; a count given here is held)")
    p.add_argument("--tets-ceiling", type=int, help="with the automatic edge length: the most tets spent where the "
                   "network asks for more than the budget (default 4x the default budget, within --max-tets)")
    p.add_argument("--grading", type=float, help="with the automatic edge length: growth of the edge length per "
                   "unit distance from the network where it needs a finer mesh (0.1-1, default 0.5; lower it, with "
                   "a larger --target-tets, around node-to-node curves shorter than an edge)")
    p.add_argument("--max-tets", type=int, help="refuse meshes estimated past this many tets (default 1,000,000, "
                   "or what fits in 3/4 of the memory); raise it to solve larger meshes on a big machine")
    p.add_argument("--refine", type=int, help="red-refinement levels after fTetWild (default: automatic, 0-2)")
    p.add_argument("--no-snap", action="store_true", help="keep fTetWild's boundary as it is (default: moved "
                   "back onto the input's sharp edges and patches)")
    p.add_argument("--mesher", choices=("auto", "TetGen", "fTetWild"),
                   help="tet mesher (default auto: TetGen where the tetgen package is installed and the surface "
                        "is no denser than the mesh, else fTetWild; fTetWild meshes where TetGen fails)")
    p.add_argument("--penalty", type=float, help="penalty a of Eq. 23 (default 1000)")
    p.add_argument("--iterations", type=int, help="maximum Levenberg-Marquardt iterations (default 50)")
    p.add_argument("--init", choices=INITS, help="initial guess (default zero)")
    p.add_argument("--root", type=int, help="tet-mesh vertex to develop the frames from (default: a boundary vertex)")
    p.add_argument("--check", action="store_true", help="only validate the input, then exit")
    p.add_argument("--profile", action="store_true", help="print the per-stage and per-iteration breakdown "
                   "and the hottest functions")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress messages")
    return p


def _options(args, file_options: dict):
    d = dict(file_options)
    for key, val in (("edge_length", args.edge_length), ("target_tets", args.target_tets),
                     ("tets_ceiling", args.tets_ceiling), ("grading", args.grading),
                     ("penalty", args.penalty), ("max_iterations", args.iterations), ("init", args.init),
                     ("refine", args.refine), ("max_tets", args.max_tets), ("mesher", args.mesher)):
        if val is not None:
            d[key] = val
    if args.no_snap:
        d["snap_features"] = False
    return io.options_from_dict(d)


def _check_exports(paths: list[str]) -> None:
    """Refuse an export the solve could not write, before the solve."""
    from .io.interchange import FORMATS, MEDIT_SIDE_FILES

    for path in paths:
        side = MEDIT_SIDE_FILES if os.path.splitext(path)[1].lower() == ".mesh" else ()
        check_output_path(path, "--export", FORMATS, suffix_files=side)


def _check_hex_outputs(args) -> None:
    """Refuse hex-mesh settings and outputs the run could not use, before
    any work."""
    from .hexmesh import DEFAULT_HEXES, MAX_HEXES
    from .io.hexformats import check_hex_path

    for path in args.hex:
        check_hex_path(path, "--hex")
    hexing = args.cell_size is not None or args.hex_cells is not None or args.no_smooth or args.mesh_unconverged
    if (hexing or args.finer_near is not None) and not args.hex:
        raise OptionsError("--cell-size, --hex-cells, --finer-near, --no-smooth and --mesh-unconverged go with --hex "
                           "FILE (the hex mesh to write)")
    if (args.finer_ratio is not None or args.finer_reach is not None) and args.finer_near is None:
        raise OptionsError("--finer-ratio and --finer-reach go with --finer-near (where the cells are to be smaller)")
    args.finer = None
    if args.finer_near is not None:
        from .hexmesh.sizing import FINER_RATIO, FINER_REACH, FinerNear

        args.finer = FinerNear.parse(args.finer_near, FINER_RATIO if args.finer_ratio is None else args.finer_ratio,
                                     FINER_REACH if args.finer_reach is None else args.finer_reach)
    if args.from_result and not (args.hex or args.export or args.check):
        raise OptionsError("--from-result reads a stored field for --hex FILE (a hex mesh), --export FILE (the "
                           "field for another tool) or --check (check the file); give one of them")
    args.cell_size = checks.positive_float("--cell-size", args.cell_size, OptionsError, allow_none=True,
                                           fix="a length in the units of the surface")
    args.hex_cells = checks.integer("--hex-cells", args.hex_cells, OptionsError, low=1, high=MAX_HEXES,
                                    allow_none=True, fix=f"a number of cells, the default is {DEFAULT_HEXES}")


def _outputs(args, out: str | None) -> list:
    """Every file the run writes, as (how it was named, path)."""
    from .io.interchange import MEDIT_SIDE_FILES

    outs = [] if out is None else [("-o", out)]
    for path in args.export:
        outs.append(("--export", path))
        if os.path.splitext(path)[1].lower() == ".mesh":
            outs += [(f"--export {path} writes", os.path.splitext(path)[0] + s) for s in MEDIT_SIDE_FILES]
    outs += [("--suggest-network", args.suggest_network)] if args.suggest_network else []
    return outs + [("--hex", p) for p in args.hex]


def _check_overwrites(args, out: str | None, inputs) -> None:
    """Refuse, before any work, an output that names an input or another
    output (atomic.check_distinct)."""
    check_distinct(_outputs(args, out), inputs)


def _hex_refusal(args, size: tuple[float, float] | None, curves, sources=None) -> int:
    """The hex settings against the solid and the network, before any work
    (hexmesh.cellsize.check_cell_size / hexmesh.intake.check_indices); returns 0 when they
    fit.  A cell size the user gave that does not fit raises an
    OptionsError naming --cell-size (exit 1); a network no hex mesh can have
    is said as the hex stage says it, and returns EXIT_NO_HEX_MESH.  size:
    (the solid's smallest extent, its volume), None where unknown."""
    from .errors import HexMeshError
    from .hexmesh.cellsize import check_cell_size
    from .hexmesh.intake import check_indices

    if args.cell_size is not None and size is not None:
        check_cell_size(args.cell_size, *size, subject=f"--cell-size {args.cell_size:g}", error=OptionsError)
    if getattr(args, "finer", None) is not None:
        from .hexmesh.sizing import chosen_curves

        chosen_curves(args.finer, curves, sources)  # OptionsError (exit 1): a curve the network lacks
    try:
        check_indices(curves, sources)
    except HexMeshError as e:
        print(f"error: no hex mesh: {_HEX_KIND[e.kind]}{e}; nothing was solved or written (checked before any "
              "work)", file=sys.stderr)
        return EXIT_NO_HEX_MESH
    return 0


_HEX_KIND = {"network": "the network admits none: ", "settings": "not at this cell size: ",
             "field": "the field cannot be followed: ",
             "map": "SymFrames' map failed (a limit of SymFrames, not a fault of the network): "}
"""How a HexMeshError's kind opens its line (errors.HexMeshError)."""


def _hex(args, inp, progress, finer=None) -> int:
    """Make and write the hex mesh; returns the exit status it implies.
    finer: where the map fails (a limit of SymFrames, such as two nodes
    closer than the field's mesh resolves), a callable giving the field
    solved again finer (a SolvedField, or None), which is meshed instead."""
    from .errors import HexMeshError
    from .hexmesh import DEFAULT_HEXES, HexOptions, hexmesh
    from .io.hexformats import export_hexmesh

    converged = getattr(inp, "status", "converged") == "converged"
    if not converged and not args.mesh_unconverged:
        # said before any hex work: the field's own status, not a hex failure
        print(f"error: no hex mesh: the field is {inp.status}, and a hex mesh needs a converged field; no hex file "
              "written (solve it again: a finer edge length, or the advice above; --mesh-unconverged meshes it "
              "anyway)", file=sys.stderr)
        return EXIT_NOT_CONVERGED
    try:
        options = HexOptions(cell_size=args.cell_size, target_hexes=args.hex_cells or DEFAULT_HEXES,
                             smooth=not args.no_smooth, finer_near=getattr(args, "finer", None))
        hm = hexmesh(inp, options=options, progress=progress, allow_unconverged=args.mesh_unconverged)
    except HexMeshError as e:
        again = finer(e) if finer is not None and e.kind == "map" and e.finer else None
        if again is not None:
            return _hex(args, again, progress)
        print(f"error: no hex mesh: {_HEX_KIND.get(e.kind, '')}{e}", file=sys.stderr)
        return EXIT_NO_HEX_MESH
    print(hm.report.summary())
    for path in args.hex:
        print("wrote " + ", ".join(export_hexmesh(hm, path)))
    if not hm.report.valid:
        print(f"warning: the hex mesh is defective: {hm.report.reason}", file=sys.stderr)
    elif hm.report.warnings:
        print(f"warning: the hex mesh is valid with warnings: {'; '.join(hm.report.warnings)}", file=sys.stderr)
    if not converged:
        print(f"warning: the hex mesh is of a field that is {inp.status} (--mesh-unconverged)", file=sys.stderr)
    return 0 if hm.report.valid and converged else EXIT_NOT_CONVERGED


def _solve_finer(args, result, out: str, error, progress):
    """For a hex map that failed on this field: the field solved again
    finer (pipeline.solve_finer), written over ``out`` and the --export
    files, as a SolvedField; None (said why) where it is not solved again or
    does not converge."""
    from .pipeline import solve_finer

    print(f"note: no hex mesh on this field ({error}); solving the field again finer", file=sys.stderr)
    again, what = solve_finer(result, progress=progress)
    print(f"note: {what}", file=sys.stderr)
    if again is None or not again.report.converged:
        return None
    print(again.report.summary())
    _save_result(out, again)
    print(f"wrote {out}")
    for path in args.export:
        print("wrote " + ", ".join(io.export_field(again, path)))
    return again.field


def _from_result(args) -> int:
    """--from-result: check the stored field (io.load_field) and the hex
    settings against it, then mesh it (--hex) and write the field (--export),
    or stop after the checks (--check).  -o is refused: no solve, no result."""
    from .hexmesh.cellsize import solid_size

    if args.example or args.network or args.tet_network:
        raise OptionsError("--from-result meshes a stored field: give no network, --example or --tet-network with "
                           "it")
    if args.output:
        raise OptionsError(f"-o {args.output} with --from-result: -o writes the result of a solve, and --from-result "
                           f"does not solve (the field stays in {args.from_result}); drop -o, or copy the file")
    given = [f"--{k.replace('_', '-')}" for k in _SOLVE_FLAGS if getattr(args, k) not in (None, False)]
    if given:
        raise OptionsError(f"{', '.join(given)} with --from-result: a setting of the solve, and --from-result does "
                           "not solve; drop it")
    _check_overwrites(args, None, [("--from-result", args.from_result)])
    _check_exports(args.export)
    inp = io.load_field(args.from_result)
    refused = _hex_refusal(args, solid_size(inp), inp.network.curves, inp.network.source) if args.hex else 0
    if refused:
        return refused
    if args.check:
        print(f"{args.from_result}: a stored field of {inp.mesh.n_tets:,} tets, {len(inp.network.curves)} curves, "
              f"{inp.status}; its arrays are complete and consistent")
        if inp.status != "converged" and args.hex and not args.mesh_unconverged:
            print(f"error: no hex mesh: the field is {inp.status} (--mesh-unconverged meshes it anyway)",
                  file=sys.stderr)
            return EXIT_NOT_CONVERGED
        return 0
    status = 0
    for path in args.export:
        print("wrote " + ", ".join(io.export_field(inp, path)))
    if inp.status != "converged" and not args.hex:
        print(f"warning: the stored field is {inp.status}", file=sys.stderr)
        status = EXIT_NOT_CONVERGED
    if args.hex:
        status = max(status, _hex(args, inp, _progress(args.quiet)))
    return status


_SOLVE_FLAGS = ("edge_length", "target_tets", "tets_ceiling", "grading", "max_tets", "refine", "mesher", "penalty",
                "iterations", "init", "root", "no_snap", "profile", "tag_convention", "tag_property", "sharp_angle")
"""Command-line settings of a solve (and of its input), which --from-result has no use for."""


def _suggested(args):
    """A bare surface: its suggested network (solver/suggest), written with
    --suggest-network, and the options it asks for; (V, F, None, {}) when
    writing it is all that was asked."""
    from .suggest import suggest_network

    if args.suggest_network:
        check_output_path(args.suggest_network, "--suggest-network", (".json",))
    V, F = io.read_obj(args.network)
    net, rep = suggest_network(V, F)
    print(rep.summary())
    opts = {"target_tets": rep.target_tets} if rep.target_tets else {}
    if args.suggest_network:
        rel = os.path.relpath(os.path.abspath(args.network), os.path.dirname(os.path.abspath(args.suggest_network)))
        io.write_network(args.suggest_network, net, surface=rel, options=opts or None)
        print(f"wrote {args.suggest_network}")
        if not args.hex and not args.export:
            return V, F, None, {}
    # the budget the network asks for, unless the resolution is given
    return V, F, net, opts if args.target_tets is None and args.edge_length is None else {}


def _progress(quiet: bool):
    if quiet:
        return None
    t0 = time.perf_counter()

    def show(stage, fraction, message):
        print(f"[{time.perf_counter() - t0:7.1f} s] {100 * fraction:3.0f}%  {message}", file=sys.stderr, flush=True)

    return show


def _print_profile(result) -> None:
    lm = result.report.lm
    print("\nLevenberg-Marquardt iterations:")
    print(f"  {'it':>3} {'energy':>12} {'smooth':>12} {'penalty':>10} {'|grad|':>10} {'damping':>9} {'CG':>5} "
          f"{'ok':>3} {'s':>7} {'step':>9}  kind")
    for it in lm.iterations:
        print(f"  {it.iteration:3d} {it.energy:12.6g} {it.smoothness:12.6g} {it.penalty:10.3g} "
              f"{it.gradient_norm:10.3g} {it.damping:9.2g} {it.cg_iterations:5d} {'y' if it.accepted else 'n':>3} "
              f"{it.seconds:7.2f} {it.step:9.2e}  {'' if it.iteration == 0 else 'Newton' if it.newton else 'GN'}")
    print(f"  setup {lm.setup_seconds:.2f} s, total {lm.seconds:.2f} s")


def _save_result(out: str, result) -> None:
    """Write the result; when its folder refuses the write after the solve
    (checked before it, but a disk can fill up or a permission change
    meanwhile), keep the solve: write it to the temporary folder instead and
    say where, then fail with the reason."""
    import tempfile

    try:
        io.save_result(out, result)
    except OutputError as e:
        fd, spare = tempfile.mkstemp(prefix=os.path.splitext(os.path.basename(out))[0] + "-", suffix=".npz")
        os.close(fd)
        try:
            io.save_result(spare, result)
        except OutputError:
            os.remove(spare)
            raise e from None
        raise OutputError(f"{e}; the result was saved to {spare} instead") from None


def _exit_on_signals() -> None:
    """SIGTERM (kill, a job scheduler) and SIGHUP (terminal closed) end the
    command like Ctrl-C does: by an exception, so that every finally block
    runs -- the fTetWild child is killed and its temporary folder removed
    (mesh.tetwild.run_tetwild) -- instead of Python dying on the spot."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return

    def stop(signum, frame):
        raise SystemExit(128 + signum)

    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), stop)


def _stem(args) -> str | None:
    """The default result's path without .npz."""
    if args.example:
        return args.example
    src = args.tet_network or args.network
    return None if src is None else os.path.splitext(src)[0]


def _load(args):
    """(V, F, network, the network file's options, the result path) of the
    input the arguments name, or None when they name none.  Outputs naming
    an input are refused before the input is read (beyond the network
    file, which names the surface)."""
    stem = _stem(args)
    if stem is None:
        return None
    out = None if args.check else args.output or f"{stem}.npz"
    if args.example:
        _check_overwrites(args, out, [])
        V, F, net = load_example(args.example)
        return V, F, net, {}, out
    if args.tet_network:
        from .io.tetnetwork import import_tet_network

        _check_overwrites(args, out, [("--tet-network", args.tet_network)])
        imp = import_tet_network(args.tet_network, args.tag_convention, args.tag_property, args.sharp_angle)
        print(f"{args.tet_network}: {imp.describe()}")
        return imp.V, imp.F, imp.network, {}, out
    if args.network.lower().endswith(".obj") and args.surface is None:
        # a bare surface: its network is suggested (None: only written)
        _check_overwrites(args, out, [("surface", args.network)])
        V, F, net, file_opts = _suggested(args)
        return V, F, net, file_opts, out
    if args.suggest_network:
        raise OptionsError("--suggest-network takes a bare SURFACE.obj, with no network file")
    net, file_opts, surface = io.read_network(args.network)
    surface = args.surface or surface
    if surface is None:
        raise SymFramesError("no surface: give SURFACE.obj or a 'surface' key in the network file")
    _check_overwrites(args, out, [("network", args.network), ("surface", surface)])
    V, F = io.read_obj(surface)
    return V, F, net, file_opts, args.output or f"{stem}.npz"


def _surface_size(V, F) -> tuple[float, float] | None:
    """(smallest axis extent, enclosed volume) of a closed surface; None for
    one that cannot be measured (the solve's checks then say what is wrong)."""
    import numpy as np

    V, F = np.asarray(V, float), np.asarray(F, np.int64)
    if V.ndim != 2 or V.shape[1:] != (3,) or F.ndim != 2 or F.shape[1:] != (3,) or not len(F) or \
            F.min() < 0 or F.max() >= len(V) or not np.isfinite(V).all():
        return None
    ext = np.ptp(V[np.unique(F)], axis=0)
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    # an open or folded surface (refused later, by the solve's checks) bounds no
    # volume of its own: the box's stands in
    vol = abs(float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum()) / 6.0)
    return float(ext.min()), min(vol, float(np.prod(ext)))


def _check_only(args, V, F, net, opts) -> int:
    """--check: validate the input (and the hex settings), print what was found."""
    found = check(V, F, net, options=opts)
    for rep in (found.repairs_text(), found.corners_text()):
        if rep:
            print(rep)
    print(f"input is valid: {found.interior_curves} interior curves, {found.nodes} nodes, "
          f"{found.boundary_components} boundary component(s)")
    print(f"resolution: {found.plan.describe()}")
    if args.hex:
        refused = _hex_refusal(args, _surface_size(V, F), net.curves)
        if refused:
            return refused
        size = f"cell size {args.cell_size:g} fits the solid" if args.cell_size is not None else \
            "the cell size is chosen after the solve"
        print(f"hex settings: {size}; no curve's index rules a hex mesh out")
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if argv is None:  # run as a command, not called from Python (tests)
        _exit_on_signals()
    try:
        if args.export_example:
            name, folder = args.export_example
            if name not in EXAMPLES:
                raise OptionsError(f"--export-example {name}: no such example; the examples are "
                                   f"{', '.join(sorted(EXAMPLES))}")
            V, F, net = load_example(name)
            try:
                os.makedirs(folder, exist_ok=True)
            except OSError as e:
                raise OutputError(f"--export-example: cannot make the folder {folder}: {e.strerror}") from None
            io.write_obj(os.path.join(folder, f"{name}.obj"), V, F)
            io.write_network(os.path.join(folder, f"{name}.json"), net, surface=f"{name}.obj")
            print(f"wrote {os.path.join(folder, name)}.obj and .json")
            return 0
        _check_hex_outputs(args)
        if args.from_result:
            return _from_result(args)
        loaded = _load(args)
        if loaded is None:
            _parser().print_usage(sys.stderr)
            print("error: give a network file or --example NAME", file=sys.stderr)
            return 2
        V, F, net, file_opts, out = loaded
        if net is None:  # --suggest-network alone: written
            return 0
        opts = _options(args, file_opts)
        # what can only fail at the end is checked before any work
        if args.root is not None and args.root < 0:
            raise OptionsError(f"--root {args.root}: must be a tet-mesh vertex index >= 0 (omit it for a boundary "
                               "vertex)")
        if not args.check:
            # the result is always NumPy .npz, written at exactly this path
            check_output_path(out, "-o", (".npz",))
        _check_exports(args.export)
        if args.check:
            return _check_only(args, V, F, net, opts)
        refused = _hex_refusal(args, _surface_size(V, F), net.curves) if args.hex else 0
        if refused:
            return refused
        progress = _progress(args.quiet)
        profiler = None
        if args.profile:
            import cProfile

            profiler = cProfile.Profile()
            profiler.enable()
        problem = FieldProblem(V, F, net, opts, progress=progress)
        result = solve_resolved(problem, root=args.root, progress=progress)
        if profiler is not None:
            profiler.disable()
        print(result.report.summary())
        if args.profile:
            _print_profile(result)
            import pstats

            print("\nHottest functions (cumulative time):")
            pstats.Stats(profiler, stream=sys.stdout).sort_stats("tottime").print_stats(15)
        _save_result(out, result)
        print(f"wrote {out}")
        for path in args.export:
            print("wrote " + ", ".join(io.export_field(result, path)))
        status = 0
        if not result.report.converged:
            print(f"warning: not converged: {result.report.status_reason}", file=sys.stderr)
            status = EXIT_NOT_CONVERGED
        if args.hex:
            def finer(error):
                return _solve_finer(args, result, out, error, progress)

            hex_status = _hex(args, result.field, progress, finer=finer)
            status = max(status, hex_status)
            if hex_status and (args.network or "").lower().endswith(".obj") and args.surface is None:
                print("the network was suggested (docs/suggest.md): write it with --suggest-network FILE.json, edit "
                      "the curves or nodes named above (move them inward, lengthen short ones, or remove a radial "
                      "pair) and solve that file", file=sys.stderr)
        return status
    except (SymFramesError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except Cancelled:
        print("cancelled", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
