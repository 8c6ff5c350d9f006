"""Build the SymFrames extension zips (Install from Disk in Blender).

One zip per Blender range ("variant"), because Blender's installer cannot
tell two wheels of one package for the same Python apart by the numpy they
need: it keeps the wheels that match the running platform and Python
version, then only the newest version of each package (bl_pkg
``_extensions_wheel_filter_for_this_system``, ``_bpy_internal.extensions.
wheel_manager.wheel_list_deduplicate_as_skip_set``).

=======  ================  =======  =====================================
variant  Blender           Python   bundled
=======  ================  =======  =====================================
4.2      4.2 LTS - 4.4     3.11     scipy 1.15.3 (their numpy is 1.24.3)
4.5      4.5 LTS - 5.0     3.11     scipy as pinned in requirements.txt
5.1      5.1 and later     3.13     scipy as pinned in requirements.txt
=======  ================  =======  =====================================

plus, per platform, the fTetWild bindings: pytetwild 0.2.3 where it has a
wheel (Linux x64, Windows x64), else wildmeshing (macOS arm64 and x64), else
pytetwild 0.4.2 (Linux arm64).  numpy
is Blender's own and never bundled.  Each zip's manifest gets its
``blender_version_min``/``blender_version_max``, ``platforms`` and
``wheels``; a platform without a scipy and a mesher wheel is left out.

1. Collect the wheels into ./wheels.
2. A build of every variant and platform rewrites blender_manifest.toml's
   ``platforms`` and ``wheels`` to the union of all variants (the
   repository's manifest states everything that is supported; only the
   zips are installable: see its comments).
3. Validate and build with the tool shipped in the bpy wheel
   (bl_pkg/cli/blender_ext.py), which needs no Blender binary, from a
   staging copy holding only the variant's wheels; the zip is named
   ``symframes-<version>-blender<variant>[-<platform>].zip``.
4. List what the zip left out of the staging copy (the manifest's
   ``[build] paths_exclude_pattern``: tests, test and bench tools,
   benchmarks, scripts, documents): only what runs in Blender ships.

Usage::

    ./dev.sh python scripts/build_extension.py [--blender 4.2|4.5|5.1 ...] [--platform linux-x64 ...]
        [--split-platforms] [--mesher pytetwild|wildmeshing] [--output-dir dist] [--offline]

Without --blender every variant is built (--all-variants says so
explicitly).  --offline uses the wheels already in ./wheels.  --mesher
bundles one mesher wherever it has a wheel (wildmeshing on linux-x64
tests the macOS back-end on Linux).
"""

from __future__ import annotations

import argparse
import glob
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MANIFEST = "blender_manifest.toml"
WHEELS = os.path.join(ROOT, "wheels")
MESHERS = ("pytetwild", "wildmeshing")  # fTetWild bindings, in order of preference
# what a mesher imports besides numpy (wildmeshing's package imports its SVG
# helpers, which import svgwrite, a pure-Python wheel)
MESHER_DEPENDENCIES = {"pytetwild": (), "wildmeshing": ("svgwrite",)}


def pinned_requirements() -> dict[str, str]:
    """The pins of requirements.txt, e.g. {'scipy': '1.17.1'}."""
    pins = {}
    with open(os.path.join(ROOT, "requirements.txt"), encoding="utf-8") as fh:
        for line in fh:
            m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*==\s*([^\s#;]+)", line)
            if m:
                pins[m.group(1).lower()] = m.group(2)
    missing = [p for p in ("scipy", *MESHERS, *sum(MESHER_DEPENDENCIES.values(), ())) if p not in pins]
    if missing:
        sys.exit(f"requirements.txt pins no version of {', '.join(missing)}")
    return pins


PINS = pinned_requirements()
# the mesher wheels to look for, in order of preference: the pinned pytetwild
# (linux-x64, windows-x64), wildmeshing (macOS), and pytetwild 0.4.2, the
# first with linux-arm64 wheels (it imports pyvista at package import:
# solver/mesh/tetwild.py's worker gives it a stand-in)
MESHER_WHEELS = (("pytetwild", PINS["pytetwild"]), ("wildmeshing", PINS["wildmeshing"]), ("pytetwild", "0.4.2"))


@dataclass(frozen=True)
class Variant:
    name: str
    blender_min: str
    blender_max: str | None  # exclusive, as Blender reads it
    python: str
    scipy: str
    why: str


VARIANTS = {
    v.name: v for v in (
        Variant("4.2", "4.2.0", "4.5.0", "3.11", "1.15.3",
                "Blender 4.2-4.4 ship numpy 1.24.3; scipy 1.17 fails to import there, 1.15.3 does"),
        Variant("4.5", "4.5.0", "5.1.0", "3.11", PINS["scipy"], "Blender 4.5-5.0: Python 3.11, numpy 1.26.4"),
        # the newest release the matrix runs is 5.3: a later Blender (a new Python, a new numpy) must be
        # measured before a zip claims it
        Variant("5.1", "5.1.0", "5.4.0", "3.13", PINS["scipy"], "Blender 5.1-5.3: Python 3.13, numpy 2"),
    )
}


def variant_for(blender_version: str) -> Variant:
    """The variant whose Blender range holds blender_version ('4.2.23')."""
    v = tuple(int(x) for x in blender_version.split(".")[:3])
    for var in VARIANTS.values():
        lo = tuple(int(x) for x in var.blender_min.split("."))
        hi = tuple(int(x) for x in var.blender_max.split(".")) if var.blender_max else (1000,)
        if lo <= v < hi:
            return var
    sys.exit(f"no variant supports Blender {blender_version}")


# Blender platform -> pip platform tags accepted (newest glibc / macOS first)
PLATFORMS = {
    "linux-x64": ["manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64"],
    "linux-arm64": ["manylinux_2_28_aarch64", "manylinux_2_17_aarch64", "manylinux2014_aarch64"],
    "windows-x64": ["win_amd64"],
    "windows-arm64": ["win_arm64"],
    "macos-arm64": ["macosx_14_0_arm64", "macosx_12_0_arm64", "macosx_11_0_arm64"],
    "macos-x64": ["macosx_13_0_x86_64", "macosx_10_15_x86_64", "macosx_10_14_x86_64", "macosx_10_13_x86_64",
                  "macosx_10_9_x86_64"],
}
# the architecture part of the platform tag, matched as Blender does (it ignores
# the glibc and macOS versions)
ARCH = {"linux-x64": ("manylinux", "_x86_64"), "linux-arm64": ("manylinux", "_aarch64"),
        "windows-x64": ("win_amd64", ""), "windows-arm64": ("win_arm64", ""),
        "macos-arm64": ("macosx_", "_arm64"), "macos-x64": ("macosx_", "_x86_64")}

# copied into the staging folder; the manifest's [build] exclusions then apply
STAGE_IGNORE = shutil.ignore_patterns(".*", "__pycache__", "wheels", "out", "dist", "build", "*.blend", "*.blend1",
                                      "*.zip")


def bpy_root() -> str:
    """The bpy wheel's folder (site-packages/bpy), found without importing bpy."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        sys.exit("the bpy module is not installed; run this with the project's venv (./dev.sh python ...)")
    return list(spec.submodule_search_locations)[0]


def blender_ext() -> str:
    hits = glob.glob(os.path.join(bpy_root(), "*", "scripts", "addons_core", "bl_pkg", "cli", "blender_ext.py"))
    if not hits:
        sys.exit(f"blender_ext.py not found in {bpy_root()}")
    return hits[0]


def valid_tags_file() -> str:
    """Blender's list of extension tags (a .py file the tool reads directly)."""
    hits = glob.glob(os.path.join(bpy_root(), "*", "scripts", "modules", "_bpy_internal", "extensions", "tags.py"))
    return hits[0] if hits else ""  # "" disables tag validation


def wheel_fits(filename: str, pkg: str, version: str, platform: str, python: str) -> bool:
    """Whether a wheel file is pkg==version for a Blender platform and
    Python version, judged as Blender's installer does."""
    if not filename.startswith(f"{pkg}-{version}-") or not filename.endswith(".whl"):
        return False
    py_tag, abi_tag, plat_tags = filename[:-4].split("-")[-3:]
    start, end = ARCH[platform]
    if plat_tags != "any" and not any(t.startswith(start) and t.endswith(end) for t in plat_tags.split(".")):
        return False
    major, minor = (int(x) for x in python.split("."))
    for tag in py_tag.split("."):
        if tag == f"py{major}":
            return True
        m = re.fullmatch(r"cp(\d)(\d+)", tag)
        if m and int(m.group(1)) == major:
            if int(m.group(2)) == minor or (abi_tag == "abi3" and int(m.group(2)) <= minor):
                return True
    return False


def download(requirement: str, platform: str, python: str) -> None:
    """Ask the package index for one binary wheel of requirement for a Blender
    platform and Python version (nothing happens when it has none)."""
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
           "--python-version", python, "--implementation", "cp", "-d", WHEELS, requirement]
    for tag in PLATFORMS[platform]:
        cmd += ["--platform", tag]
    subprocess.run(cmd, capture_output=True, text=True)


def find_wheel(pkg: str, version: str, platform: str, python: str, offline: bool) -> str | None:
    have = [f for f in os.listdir(WHEELS) if wheel_fits(f, pkg, version, platform, python)]
    if not have and not offline:
        download(f"{pkg}=={version}", platform, python)
        have = [f for f in os.listdir(WHEELS) if wheel_fits(f, pkg, version, platform, python)]
    return sorted(have)[0] if have else None


def collect_wheels(variant: Variant, platforms, offline: bool, meshers=MESHERS) -> dict[str, list[str]]:
    """Blender platform -> [scipy wheel, mesher wheel, its dependencies] of a
    variant, for the platforms that have them all; the first mesher with a
    wheel is taken."""
    os.makedirs(WHEELS, exist_ok=True)
    found: dict[str, list[str]] = {}
    for platform in platforms:
        scipy = find_wheel("scipy", variant.scipy, platform, variant.python, offline)
        mesher, deps = None, []
        for pkg, version in MESHER_WHEELS:
            if pkg not in meshers:
                continue
            mesher = find_wheel(pkg, version, platform, variant.python, offline)
            if mesher:
                deps = [find_wheel(d, PINS[d], platform, variant.python, offline) for d in MESHER_DEPENDENCIES[pkg]]
                break
        print(f"  {variant.name:<4s} {platform:<14s} {scipy or '-- no scipy wheel --'}  "
              f"{mesher or '-- no mesher wheel --'}  {' '.join(d or '-- missing --' for d in deps)}")
        if scipy and mesher and all(deps):
            found[platform] = [scipy, mesher, *deps]
    return found


def _set_key(text: str, key: str, value: str | None) -> str:
    """Set (or, for None, remove) a top-level 'key = "..."' line of the manifest."""
    line = f'{key} = "{value}"\n' if value is not None else ""
    text, n = re.subn(rf'^{key} = "[^"]*"\n', lambda _m: line, text, flags=re.M)
    if n == 0 and value is not None:
        text, n = re.subn(r'^(blender_version_min = "[^"]*"\n)', lambda m: m.group(1) + line, text, flags=re.M)
    if n > 1:
        sys.exit(f"{MANIFEST}: more than one '{key}' entry")
    return text


def manifest_with(text: str, found: dict[str, list[str]], variant: Variant | None = None) -> str:
    """The manifest text with platforms and wheels set to found, and, for a
    variant, its Blender range."""
    platforms = "platforms = [" + ", ".join(f'"{p}"' for p in found) + "]"
    wheels = sorted({w for names in found.values() for w in names})
    wheel_list = "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]"
    for key, value in (("platforms", platforms), ("wheels", wheel_list)):
        text, n = re.subn(rf"^{key} = \[[^\]]*\]", lambda _m, v=value: v, text, flags=re.M)
        if n != 1:
            sys.exit(f"{MANIFEST}: expected one '{key} = [...]' entry")
    if variant is not None:
        text = _set_key(text, "blender_version_min", variant.blender_min)
        text = _set_key(text, "blender_version_max", variant.blender_max)
    return text


def stage(dest: str, found: dict[str, list[str]], variant: Variant) -> None:
    """A copy of the extension sources with only the variant's wheels."""
    shutil.copytree(ROOT, dest, ignore=STAGE_IGNORE)
    os.makedirs(os.path.join(dest, "wheels"))
    for w in sorted({w for names in found.values() for w in names}):
        shutil.copy2(os.path.join(WHEELS, w), os.path.join(dest, "wheels", w))
    with open(os.path.join(ROOT, MANIFEST), encoding="utf-8") as fh:
        text = manifest_with(fh.read(), found, variant)
    with open(os.path.join(dest, MANIFEST), "w", encoding="utf-8") as fh:
        fh.write(text)


def left_out(src: str, names: list[str]) -> list[str]:
    """What of the staged sources ``src`` a zip holding ``names`` does not
    ship: top-level files and folders left out whole ('tests/'), and Python
    modules left out of a folder that ships ('solver/x.py')."""
    shipped = {n.rstrip("/") for n in names}
    tops = {n.split("/")[0] for n in shipped}
    out = []
    for entry in sorted(os.listdir(src)):
        path = os.path.join(src, entry)
        if entry not in tops:
            out.append(entry + "/" if os.path.isdir(path) else entry)
        elif os.path.isdir(path):
            for dirpath, _dirs, files in os.walk(path):
                for f in files:
                    rel = os.path.relpath(os.path.join(dirpath, f), src).replace(os.sep, "/")
                    if f.endswith(".py") and rel not in shipped:
                        out.append(rel)
    return sorted(out)


def build(found: dict[str, list[str]], variant: Variant, output_dir: str, split: bool = False) -> list[str]:
    """Validate and build a variant from a staging copy; returns the zip
    paths, named symframes-<version>-blender<variant>[-<platform>].zip."""
    tool, tags = blender_ext(), valid_tags_file()
    os.makedirs(output_dir, exist_ok=True)
    made = []
    with tempfile.TemporaryDirectory(prefix="symframes-build-") as tmp:
        src, out = os.path.join(tmp, "symframes"), os.path.join(tmp, "out")
        stage(src, found, variant)
        os.makedirs(out)
        cmd = [sys.executable, tool, "build", "--source-dir", src, "--output-dir", out, f"--valid-tags={tags}"]
        if split:
            cmd.append("--split-platforms")
        for step in ([sys.executable, tool, "validate", f"--valid-tags={tags}", src], cmd):
            if subprocess.run(step).returncode != 0:
                sys.exit(f"blender_ext.py {step[2]} failed (see above)")
        for z in sorted(glob.glob(os.path.join(out, "*.zip"))):
            name = os.path.basename(z)  # symframes-0.1.0[-linux_x64].zip
            m = re.fullmatch(r"(symframes-[^-]+)(-.*)?\.zip", name)
            dest = os.path.join(output_dir, f"{m.group(1)}-blender{variant.name}{m.group(2) or ''}.zip")
            with zipfile.ZipFile(z) as zf:
                print(f"left out of {os.path.basename(dest)}: {', '.join(left_out(src, zf.namelist()))}")
            shutil.move(z, dest)
            made.append(dest)
    return made


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--output-dir", default=os.path.join(ROOT, "dist"))
    p.add_argument("--offline", action="store_true", help="use the wheels already in ./wheels")
    p.add_argument("--blender", action="append", choices=sorted(VARIANTS),
                   help="build this variant (a Blender range, see above; repeatable); default: all")
    p.add_argument("--all-variants", action="store_true", help="build every variant (the default)")
    p.add_argument("--platform", action="append", choices=sorted(PLATFORMS),
                   help="build for this platform only (repeatable); the repository manifest is left alone")
    p.add_argument("--split-platforms", action="store_true", help="one zip per platform")
    p.add_argument("--mesher", choices=MESHERS, help="bundle only this mesher (where it has a wheel)")
    args = p.parse_args(argv)

    variants = [VARIANTS[v] for v in (sorted(VARIANTS) if args.all_variants or not args.blender
                                      else args.blender)]
    meshers = (args.mesher,) if args.mesher else MESHERS
    union: dict[str, list[str]] = {}
    builds = []
    for variant in variants:
        print(f"wheels for Blender {variant.blender_min} - {variant.blender_max or '...'} (Python {variant.python}):")
        found = collect_wheels(variant, args.platform or list(PLATFORMS), args.offline, meshers)
        if not found:
            sys.exit(f"no requested platform has a scipy and a mesher wheel for variant {variant.name}")
        for platform, names in found.items():
            union.setdefault(platform, []).extend(names)
        builds.append((variant, found))
    if not args.platform and len(variants) == len(VARIANTS) and not args.mesher:
        path = os.path.join(ROOT, MANIFEST)
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
        new = manifest_with(text, union)
        if new != text:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(new)
            print(f"updated {MANIFEST}: platforms {', '.join(union)}")
    # a platform-restricted build names its zip after the platform
    split = args.split_platforms or bool(args.platform)
    for variant, found in builds:
        for z in build(found, variant, os.path.abspath(args.output_dir), split):
            print(f"built {z} ({os.path.getsize(z) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
