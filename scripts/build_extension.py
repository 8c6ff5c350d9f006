"""Build the SymFrames extension zip (Install from Disk in Blender).

1. Collect the scipy and pytetwild wheels (Python 3.11, the Python of
   Blender 4.2-5.0) for every Blender platform that has both on the package
   index, into ./wheels.  numpy is Blender's own and is never bundled.
2. Keep ``platforms`` and ``wheels`` of blender_manifest.toml honest: a full
   build rewrites them to the platforms found.
3. Validate and build with the tool shipped in the bpy wheel
   (bl_pkg/cli/blender_ext.py), which needs no Blender binary.

The extension is built from a staging copy of the repository holding only
the wheels of the chosen platforms, so ``--platform linux-x64`` gives a
small single-platform zip (used by tests/test_extension.py) without
touching the repository's manifest.

Usage::

    ./dev.sh python scripts/build_extension.py [--output-dir dist] [--offline]
        [--platform linux-x64 ...] [--split-platforms]

--offline uses the wheels already in ./wheels instead of downloading.
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

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MANIFEST = "blender_manifest.toml"
WHEELS = os.path.join(ROOT, "wheels")
PYTHON_VERSION = "3.11"
BUNDLED = ("pytetwild", "scipy")  # numpy is Blender's own


def pinned_requirements() -> tuple[str, ...]:
    """The pins of the bundled packages in requirements.txt, e.g. 'scipy==1.17.1'."""
    pins = {}
    with open(os.path.join(ROOT, "requirements.txt"), encoding="utf-8") as fh:
        for line in fh:
            m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*==\s*([^\s#;]+)", line)
            if m:
                pins[m.group(1).lower()] = m.group(2)
    missing = [p for p in BUNDLED if p not in pins]
    if missing:
        sys.exit(f"requirements.txt pins no version of {', '.join(missing)}")
    return tuple(f"{p}=={pins[p]}" for p in BUNDLED)


REQUIREMENTS = pinned_requirements()

# Blender platform -> pip platform tags accepted (newest glibc / macOS first)
PLATFORMS = {
    "linux-x64": ["manylinux_2_28_x86_64", "manylinux_2_27_x86_64", "manylinux_2_17_x86_64", "manylinux2014_x86_64"],
    "linux-arm64": ["manylinux_2_28_aarch64", "manylinux_2_17_aarch64", "manylinux2014_aarch64"],
    "windows-x64": ["win_amd64"],
    "windows-arm64": ["win_arm64"],
    "macos-arm64": ["macosx_14_0_arm64", "macosx_12_0_arm64", "macosx_11_0_arm64"],
    "macos-x64": ["macosx_10_15_x86_64", "macosx_10_14_x86_64", "macosx_10_9_x86_64"],
}

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


def wheel_fits(filename: str, pkg: str, version: str, platform: str) -> bool:
    if not filename.startswith(f"{pkg}-{version}-") or not filename.endswith(".whl"):
        return False
    tags = filename[:-4].split("-")[-1].split(".")
    return any(t in tags for t in PLATFORMS[platform])


def download(requirement: str, platform: str) -> None:
    """Ask the package index for one binary wheel of requirement for a Blender
    platform (nothing happens when it has none)."""
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
           "--python-version", PYTHON_VERSION, "--implementation", "cp", "-d", WHEELS, requirement]
    for tag in PLATFORMS[platform]:
        cmd += ["--platform", tag]
    subprocess.run(cmd, capture_output=True, text=True)


def collect_wheels(platforms, offline: bool) -> dict[str, list[str]]:
    """Blender platform -> wheel file names, for the platforms that have a
    wheel of every requirement."""
    os.makedirs(WHEELS, exist_ok=True)
    found: dict[str, list[str]] = {}
    for platform in platforms:
        names = []
        for req in REQUIREMENTS:
            pkg, version = req.split("==")
            have = [f for f in os.listdir(WHEELS) if wheel_fits(f, pkg, version, platform)]
            if not have and not offline:
                download(req, platform)
                have = [f for f in os.listdir(WHEELS) if wheel_fits(f, pkg, version, platform)]
            name = sorted(have)[0] if have else None
            print(f"  {platform:<14s} {req:<18s} {name or '-- no wheel --'}")
            names.append(name)
        if all(names):
            found[platform] = names
    return found


def manifest_with(text: str, found: dict[str, list[str]]) -> str:
    """The manifest text with platforms and wheels set to found."""
    platforms = "platforms = [" + ", ".join(f'"{p}"' for p in found) + "]"
    wheels = sorted({w for names in found.values() for w in names})
    wheel_list = "wheels = [\n" + "".join(f'  "./wheels/{w}",\n' for w in wheels) + "]"
    for key, value in (("platforms", platforms), ("wheels", wheel_list)):
        text, n = re.subn(rf"^{key} = \[[^\]]*\]", lambda _m, v=value: v, text, flags=re.M)
        if n != 1:
            sys.exit(f"{MANIFEST}: expected one '{key} = [...]' entry")
    return text


def stage(dest: str, found: dict[str, list[str]]) -> None:
    """A copy of the extension sources with only the chosen wheels."""
    shutil.copytree(ROOT, dest, ignore=STAGE_IGNORE)
    os.makedirs(os.path.join(dest, "wheels"))
    for w in sorted({w for names in found.values() for w in names}):
        shutil.copy2(os.path.join(WHEELS, w), os.path.join(dest, "wheels", w))
    with open(os.path.join(ROOT, MANIFEST), encoding="utf-8") as fh:
        text = manifest_with(fh.read(), found)
    with open(os.path.join(dest, MANIFEST), "w", encoding="utf-8") as fh:
        fh.write(text)


def build(found: dict[str, list[str]], output_dir: str, split: bool = False) -> list[str]:
    """Validate and build from a staging copy; returns the zip paths."""
    tool, tags = blender_ext(), valid_tags_file()
    os.makedirs(output_dir, exist_ok=True)
    before = set(glob.glob(os.path.join(output_dir, "*.zip")))
    with tempfile.TemporaryDirectory(prefix="symframes-build-") as tmp:
        src = os.path.join(tmp, "symframes")
        stage(src, found)
        cmd = [sys.executable, tool, "build", "--source-dir", src, "--output-dir", output_dir, f"--valid-tags={tags}"]
        if split:
            cmd.append("--split-platforms")
        for step in ([sys.executable, tool, "validate", f"--valid-tags={tags}", src], cmd):
            if subprocess.run(step).returncode != 0:
                sys.exit(f"blender_ext.py {step[2]} failed (see above)")
    after = set(glob.glob(os.path.join(output_dir, "*.zip")))
    made = sorted(after - before) or sorted(after)
    return made


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--output-dir", default=os.path.join(ROOT, "dist"))
    p.add_argument("--offline", action="store_true", help="use the wheels already in ./wheels")
    p.add_argument("--platform", action="append", choices=sorted(PLATFORMS),
                   help="build for this platform only (repeatable); the repository manifest is left alone")
    p.add_argument("--split-platforms", action="store_true", help="one zip per platform")
    args = p.parse_args(argv)

    print(f"wheels for Python {PYTHON_VERSION}:")
    found = collect_wheels(args.platform or list(PLATFORMS), args.offline)
    if not found:
        sys.exit("no requested platform has wheels for all of " + ", ".join(REQUIREMENTS))
    if not args.platform:
        path = os.path.join(ROOT, MANIFEST)
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
        new = manifest_with(text, found)
        if new != text:
            with open(path, "w", encoding="utf-8") as fh:
                fh.write(new)
            print(f"updated {MANIFEST}: platforms {', '.join(found)}")
    # a platform-restricted build names its zip after the platform
    split = args.split_platforms or bool(args.platform)
    for z in build(found, os.path.abspath(args.output_dir), split):
        print(f"built {z} ({os.path.getsize(z) / 1e6:.1f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
