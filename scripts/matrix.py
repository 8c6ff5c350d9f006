"""The version matrix: install the built extension into each supported
Blender release (the bpy module from PyPI standing in for it) and run it.

For every row: a cached venv under .matrix/venvs with the Python of that
Blender (3.11 for 4.2-5.0, 3.13 for 5.1 and later), its bpy module and the
numpy that Blender ships; the zip of the row's variant built by
scripts/build_extension.py for linux-x64; then scripts/extension_smoke.py
(install from disk into a temporary BLENDER_USER_RESOURCES, enable,
compute the cylinder, whose field needs LM iterations, glyphs,
streamlines, diagnostics, Export Field, save and reload, hex mesh, clear,
Import Network; a crash on exit fails the row).  Prints a table; --write puts it into docs/platforms.md between the
matrix markers.

    ./dev.sh matrix                       # every row of ROWS
    ./dev.sh matrix --bpy 4.2.23 --bpy 5.1.2 --mesher wildmeshing
    ./dev.sh matrix --write               # and update docs/platforms.md

Downloads (each bpy wheel 335-500 MB) land once in .matrix/wheels; rows run
one after the other.  Runs on linux-x64 only: the other platforms' zips are
built and validated by build_extension.py but not run here.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

try:
    import fcntl
except ImportError:  # Windows: no lock (one process at a time there)
    fcntl = None

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import build_extension  # noqa: E402
import extension_smoke  # noqa: E402

CACHE = os.path.join(ROOT, ".matrix")
WHEELS = os.path.join(CACHE, "wheels")

# the numpy each Blender range ships (Blender's own, never bundled); 5.1+:
# the bpy module requires numpy >= 2.2, < 3 and 2.3.5 stands in for Blender's
NUMPY = {"4.2": "1.24.3", "4.5": "1.26.4", "5.1": "2.3.5"}

# the other Blender line the test suite installs its zip into (tests/test_extension.py)
OTHER_BLENDER = "4.2.23"

# (bpy version, mesher forced into the zip or None for the platform's own)
ROWS = [
    ("4.2.0", None), ("4.2.23", None), ("4.3.0", None), ("4.4.0", None), ("4.5.15", None), ("5.0.1", None),
    ("5.1.2", None), ("5.2.3", None), ("5.3.0", None),
    ("4.2.23", "wildmeshing"), ("5.0.1", "wildmeshing"), ("5.3.0", "wildmeshing"),
]
# the smoke's steps, then "exit": the smoke's process ended with code 0 (not a crash on exit)
STEPS = extension_smoke.STEPS + ("exit",)
MARK_BEGIN, MARK_END = "<!-- matrix -->", "<!-- /matrix -->"


def python_for(version: str) -> str:
    """A working interpreter of Python major.minor: on PATH or under pyenv
    (a pyenv shim of a version that is not selected fails, hence the check)."""
    candidates = [shutil.which(f"python{version}")]
    candidates += sorted(glob.glob(os.path.expanduser(f"~/.pyenv/versions/{version}.*/bin/python{version}")))[::-1]
    for exe in filter(None, candidates):
        proc = subprocess.run([exe, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"],
                              capture_output=True, text=True)
        if proc.returncode == 0 and proc.stdout.strip() == version:
            return exe
    sys.exit(f"no Python {version} found (python{version} on PATH or pyenv)")


def run(cmd, **kw):
    proc = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed:\n{proc.stdout[-2000:]}{proc.stderr[-2000:]}")
    return proc


def bpy_venv(bpy_version: str, log=print) -> str:
    """The python of a cached venv with bpy==bpy_version and its Blender's
    numpy (created on first use: the bpy wheel is downloaded once).  Safe to
    call from several processes at once: one creates the venv while the
    others wait for it (tests/conftest.py starts the 4.2 venv beside the
    suite)."""
    os.makedirs(CACHE, exist_ok=True)
    with open(os.path.join(CACHE, f"bpy-{bpy_version}.lock"), "w") as lock:
        if fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
        return _bpy_venv(bpy_version, log)


def _bpy_venv(bpy_version: str, log) -> str:
    variant = build_extension.variant_for(bpy_version)
    numpy = NUMPY[variant.name]
    venv = os.path.join(CACHE, "venvs", f"bpy-{bpy_version}")
    py = os.path.join(venv, "bin", "python")
    stamp = os.path.join(venv, ".symframes-matrix")
    want = f"bpy=={bpy_version} numpy=={numpy}\n"
    if os.path.exists(stamp) and open(stamp).read() == want:
        return py
    base = python_for(variant.python)
    os.makedirs(WHEELS, exist_ok=True)
    t0 = time.perf_counter()
    if not glob.glob(os.path.join(WHEELS, f"bpy-{bpy_version}-*.whl")):
        log(f"[matrix] downloading bpy {bpy_version} (Python {variant.python}) into {WHEELS}")
        run([base, "-m", "pip", "download", "--quiet", "--no-deps", "-d", WHEELS, f"bpy=={bpy_version}"])
    wheel = glob.glob(os.path.join(WHEELS, f"bpy-{bpy_version}-*.whl"))[0]
    for attempt in (1, 2):  # a second try after a failed download or install, from scratch
        log(f"[matrix] creating {venv} (Python {variant.python}, bpy {bpy_version}, numpy {numpy})")
        shutil.rmtree(venv, ignore_errors=True)
        try:
            run([base, "-m", "venv", venv])
            run([py, "-m", "pip", "install", "--quiet", "--no-compile", wheel, f"numpy=={numpy}"])
            break
        except RuntimeError as ex:
            if attempt == 2:
                raise
            log(f"[matrix] venv setup failed, trying once more: {str(ex)[-500:]}")
    with open(stamp, "w") as fh:
        fh.write(want)
    log(f"[matrix] venv ready in {time.perf_counter() - t0:.0f} s")
    return py


def extension_zip(variant: str, mesher: str | None = None, log=print) -> str:
    """The linux-x64 zip of a variant (and forced mesher), built once per
    run of the sources into .matrix/dist."""
    out = os.path.join(CACHE, "dist", f"{variant}-{mesher or 'default'}")
    shutil.rmtree(out, ignore_errors=True)
    cmd = [sys.executable, os.path.join(HERE, "build_extension.py"), "--blender", variant, "--platform", "linux-x64",
           "--output-dir", out]
    if mesher:
        cmd += ["--mesher", mesher]
    log(f"[matrix] building the {variant} zip{' with ' + mesher if mesher else ''}")
    run(cmd, cwd=ROOT, timeout=900)
    zips = glob.glob(os.path.join(out, "*.zip"))
    if len(zips) != 1:
        raise RuntimeError(f"expected one zip in {out}, found {zips}")
    return zips[0]


def clean_env() -> dict:
    """This process's environment without what would point another Python
    at this venv's packages."""
    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}


# Without SymFrames: a property with an update callback, registered and
# unregistered.  The bpy 4.2 module segfaults at interpreter exit after this
# (5.0.1 does not); a row whose smoke crashes on exit runs it to tell the
# bpy module's own crash from one SymFrames causes.
EXIT_CONTROL = """
import bpy
class P(bpy.types.PropertyGroup):
    x: bpy.props.FloatProperty(update=lambda self, context: None)
bpy.utils.register_class(P)
bpy.utils.unregister_class(P)
"""
BPY_EXIT_CRASH = "crash on exit: the bpy module's own"


def exit_control_crashes(python: str) -> bool:
    """Whether this bpy module crashes on exit without SymFrames (EXIT_CONTROL)."""
    with tempfile.TemporaryDirectory(prefix="symframes-control-") as tmp:
        proc = subprocess.run([python, "-c", EXIT_CONTROL], cwd=tmp, env=clean_env(), capture_output=True,
                              timeout=300)
    return proc.returncode != 0


def exit_result(returncode: int, stderr: str, python: str) -> str:
    """The 'exit' step: ok, the bpy module's own crash (the control crashes
    too), or the exit code and the last line of stderr."""
    if returncode == 0:
        return "ok"
    if returncode < 0 and exit_control_crashes(python):
        return f"{BPY_EXIT_CRASH} (signal {-returncode}; the 6-line control without SymFrames crashes too)"
    return f"exit code {returncode}: " + (stderr.strip().splitlines() or ["(no message)"])[-1][:200]


def row_passed(r: dict) -> bool:
    """Every step ok; a crash on exit that the control reproduces is the bpy
    module's (shown in the table, not counted against SymFrames)."""
    got = r.get("steps", {})
    return all(got.get(s) == "ok" or (s == "exit" and str(got.get(s, "")).startswith(BPY_EXIT_CRASH))
               for s in STEPS)


def smoke(python: str, zip_path: str, example: str = "cube", timeout: float = 1200) -> dict:
    """scripts/extension_smoke.py in python, with a fresh temporary Blender
    user folder; its RESULT dict (plus 'error' when it gave none)."""
    with tempfile.TemporaryDirectory(prefix="symframes-matrix-") as tmp:
        res = os.path.join(tmp, "blender-user")
        os.makedirs(res)
        env = {**clean_env(), "BLENDER_USER_RESOURCES": res}
        t0 = time.perf_counter()
        proc = subprocess.run([python, os.path.join(HERE, "extension_smoke.py"), zip_path, example], cwd=tmp,
                              env=env, capture_output=True, text=True, timeout=timeout)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        out = json.loads(lines[-1][len("RESULT "):]) if lines else {"steps": {}}
        out["wall_seconds"] = round(time.perf_counter() - t0, 1)
        out["returncode"] = proc.returncode
        if lines:
            out["steps"]["exit"] = exit_result(proc.returncode, proc.stderr, python)
        if not lines:
            out["error"] = (proc.stdout[-1500:] + proc.stderr[-1500:]).strip()
        out["zip"] = os.path.basename(zip_path)
        return out


def row_table(results: list[dict]) -> str:
    """Markdown: one row per run; 'steps' is 'all ok' or the steps that
    failed or did not run, with the first error."""
    head = ["Blender (bpy)", "Python", "numpy", "zip", "scipy", "mesher", "steps", "tets", "LM iterations", "s"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in results:
        cells = [r.get("bpy", ""), r.get("python", ""), r.get("numpy", ""), r.get("variant", ""), r.get("scipy", "-"),
                 r.get("mesher") or "-"]
        got = r.get("steps", {})
        bad = [f"{s}: {got[s][:80]}" if got.get(s) else f"{s}: not run" for s in STEPS if got.get(s) != "ok"]
        if not bad:
            cells.append(f"all {len(STEPS)} ok")
        elif row_passed(r):
            cells.append(f"{len(STEPS) - 1} ok; **{BPY_EXIT_CRASH}**")
        else:
            cells.append("**" + "; ".join(bad[:2]) + "**")
        cells += [f"{r['tets']:,}" if "tets" in r else "-", str(r.get("lm_iterations", "-")),
                  str(r.get("wall_seconds", "-"))]
        lines.append("| " + " | ".join(str(c).replace("|", "/") for c in cells) + " |")
    return "\n".join(lines)


def write_readme(table: str, note: str) -> None:
    path = os.path.join(ROOT, "docs", "platforms.md")
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    if MARK_BEGIN not in text or MARK_END not in text:
        sys.exit(f"docs/platforms.md has no {MARK_BEGIN} ... {MARK_END} markers")
    a, b = text.index(MARK_BEGIN) + len(MARK_BEGIN), text.index(MARK_END)
    text = text[:a] + "\n" + note + "\n\n" + table + "\n" + text[b:]
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)


def run_row(bpy_version: str, mesher: str | None = None, example: str = "cylinder", zips: dict | None = None,
            log=print) -> dict:
    variant = build_extension.variant_for(bpy_version).name
    zips = {} if zips is None else zips
    try:
        py = bpy_venv(bpy_version, log)
        if (variant, mesher) not in zips:
            zips[variant, mesher] = extension_zip(variant, mesher, log)
        r = smoke(py, zips[variant, mesher], example)
    except Exception as ex:  # a row that could not be set up is a failed row
        r = {"steps": {}, "error": str(ex)[-1500:]}
    r.update(bpy=bpy_version, variant=variant)
    return r


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--bpy", action="append", help="bpy version to run (repeatable); default: every row of ROWS")
    p.add_argument("--mesher", choices=build_extension.MESHERS, help="with --bpy: force this mesher into the zip")
    p.add_argument("--example", default="cylinder", choices=["cube", "cylinder"],
                   help="the example solved (default: the cylinder, whose field needs LM iterations)")
    p.add_argument("--write", action="store_true", help="write the table into docs/platforms.md")
    p.add_argument("--json", help="also write the results to this JSON file")
    args = p.parse_args(argv)
    rows = [(v, args.mesher) for v in args.bpy] if args.bpy else ROWS
    results, zips = [], {}
    for bpy_version, mesher in rows:
        r = run_row(bpy_version, mesher, args.example, zips)
        results.append(r)
        steps = " ".join(f"{s}={r['steps'].get(s, '-')}" for s in STEPS)
        print(f"[matrix] bpy {bpy_version} {mesher or ''}: {steps} ({r.get('wall_seconds', '-')} s)", flush=True)
        if "error" in r:
            print("[matrix]   " + r["error"].replace("\n", "\n[matrix]   "), flush=True)
    table = row_table(results)
    print(table)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=1)
    if args.write:
        note = (f"`./dev.sh matrix --write` (linux-x64, the {args.example} example): each release's bpy module "
                "with the numpy it ships (5.1+: 2.3.5 standing in), the zip of its range installed from disk; "
                f"steps: {', '.join(STEPS)} (the process ended with code 0); 'LM iterations' those the field "
                "took; wildmeshing rows bundle the macOS mesher.")
        write_readme(table, note)
        print("[matrix] docs/platforms.md updated")
    failed = [r for r in results if not row_passed(r)]
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
