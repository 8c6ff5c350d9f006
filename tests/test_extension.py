"""The extension package: manifest, build, and install as a user does.

The zip is built by scripts/build_extension.py for linux-x64 only (the
wheels of the other platforms would only make it bigger), then installed
with bpy.ops.extensions.package_install_files -- what Install from Disk
calls -- by scripts/extension_smoke.py in a separate Python process whose
Blender user resources (BLENDER_USER_RESOURCES) are a temporary folder: the
extension and the wheels it unpacks land there, never in the home folder or
the venv.  In that process the extensions' site-packages comes first on
sys.path, so the installed add-on runs on the bundled scipy and mesher
(numpy is the venv's, standing in for Blender's own).

The venv's bpy 5.0.1 gets the 4.5 variant (Blender 4.5-5.0).  One other
release runs too: Blender 4.2 LTS (bpy 4.2.23 with numpy 1.24.3, in a venv
cached under .matrix/ that scripts/matrix.py creates from PyPI on first
use) with the 4.2 variant; ``./dev.sh matrix`` runs every release.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
import zipfile

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import build_extension  # noqa: E402
import matrix  # noqa: E402

# the Blender release run besides the venv's (CI budget: docs/platforms.md, Supported versions)
OTHER_BLENDER = matrix.OTHER_BLENDER


def venv_site_packages() -> list[str]:
    import numpy

    site = os.path.dirname(os.path.dirname(numpy.__file__))
    return sorted(os.listdir(site))


def test_manifest_is_honest():
    with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as fh:
        m = tomllib.load(fh)
    assert m["schema_version"] == "1.0.0" and m["type"] == "add-on" and m["id"] == "symframes"
    # the union of the variants; each zip gets its own range (build_extension.VARIANTS)
    assert m["blender_version_min"] == min(v.blender_min for v in build_extension.VARIANTS.values())
    assert m["blender_version_max"] == max(v.blender_max for v in build_extension.VARIANTS.values())
    assert all(lic.startswith("SPDX:") for lic in m["license"])
    assert set(m["permissions"]) == {"files"}  # Export Field / Hex Mesh, Import Network, nothing else
    # the user's guide says the same
    with open(os.path.join(ROOT, "docs", "addon.md"), encoding="utf-8") as fh:
        guide = fh.read()
    assert "asks for one permission, `files`" in guide and "no permissions" not in guide
    assert len(m["tagline"]) <= 64
    wheels = [os.path.basename(w) for w in m["wheels"]]
    assert not any(w.startswith("numpy") for w in wheels)  # Blender's own
    # every variant has a scipy and a mesher wheel for every listed platform,
    # and no wheel serves an unlisted platform
    for platform in m["platforms"]:
        for v in build_extension.VARIANTS.values():
            assert any(build_extension.wheel_fits(w, "scipy", v.scipy, platform, v.python) for w in wheels), \
                (v.name, platform)
            assert any(build_extension.wheel_fits(w, pkg, version, platform, v.python)
                       for w in wheels for pkg, version in build_extension.MESHER_WHEELS), (v.name, platform)
    for w in wheels:
        assert any(build_extension.wheel_fits(w, w.split("-")[0], w.split("-")[1], p, v.python)
                   for p in m["platforms"] for v in build_extension.VARIANTS.values()), w


def test_variants_cover_the_supported_releases_without_gaps():
    vs = sorted(build_extension.VARIANTS.values(), key=lambda v: v.blender_min)
    # the newest range ends after the newest release measured (the matrix's last row)
    assert vs[0].blender_min == "4.2.0" and vs[-1].blender_max == "5.4.0"
    newest = max(tuple(map(int, v.split("."))) for v, _ in matrix.ROWS)
    assert newest < (5, 4, 0)
    assert all(a.blender_max == b.blender_min for a, b in zip(vs, vs[1:]))
    assert build_extension.variant_for("4.4.0").name == "4.2" and build_extension.variant_for("5.0.1").name == "4.5"
    assert build_extension.variant_for("5.3.0").python == "3.13"


@pytest.fixture(scope="module")
def linux_build(tmp_path_factory):
    """(the built zip, what the build printed)."""
    out = tmp_path_factory.mktemp("dist")
    # downloads the two linux wheels into ./wheels if they are not there yet
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "build_extension.py"),
                           "--blender", "4.5", "--platform", "linux-x64", "--output-dir", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    zips = sorted(out.glob("*.zip"))
    assert [z.name for z in zips] == ["symframes-0.1.0-blender4.5-linux_x64.zip"]
    return zips[0], proc.stdout


@pytest.fixture(scope="module")
def linux_zip(linux_build):
    return linux_build[0]


def test_zip_holds_the_addon_the_solver_and_the_linux_wheels(linux_zip):
    with zipfile.ZipFile(linux_zip) as z:
        names = z.namelist()
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
    assert "__init__.py" in names
    assert "symframes_addon/operators.py" in names and "solver/pipeline.py" in names
    assert not [n for n in names if n.split("/")[0] in ("tests", "scripts", "bench", "docs", "out", ".venv")]
    assert not [n for n in names if "__pycache__" in n or n.endswith((".blend", ".png"))]
    wheels = sorted(n for n in names if n.endswith(".whl"))
    assert [w.split("/")[1].split("-")[0] for w in wheels] == ["pytetwild", "scipy"]
    assert all("x86_64" in w for w in wheels)
    assert manifest["platforms"] == ["linux-x64"]
    assert (manifest["blender_version_min"], manifest["blender_version_max"]) == ("4.5.0", "5.1.0")


# test and bench tools: outside solver/ (testkit/, bench/), and left out of the zip
TEST_TOOLS = ("tests/", "testkit/", "bench/", "scripts/")


def test_zip_ships_no_test_or_bench_module_and_the_build_says_what_it_left_out(linux_build):
    path, printed = linux_build
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
    modules = [n for n in names if n.endswith(".py")]
    assert not [n for n in modules if n.startswith(TEST_TOOLS)]
    # every shipped module is the extension's: the add-on, the solver, the entry point
    assert all(n == "__init__.py" or n.startswith(("symframes_addon/", "solver/")) for n in modules), modules
    assert not [n for n in modules if n.rsplit("/", 1)[-1] in ("tetedge.py", "validation_report.py")]
    line = [ln for ln in printed.splitlines() if ln.startswith(f"left out of {path.name}: ")]
    assert len(line) == 1, printed
    left = line[0].split(": ", 1)[1].split(", ")
    assert set(TEST_TOOLS) | {"docs/", "dev.sh"} <= set(left), left
    assert not [n for n in left if n.startswith(("solver/", "symframes_addon/"))], left


def test_left_out_names_whole_folders_and_single_modules(tmp_path):
    for rel in ("solver/a.py", "solver/b.py", "tests/test_a.py", "README.md", "dev.sh"):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("")
    shipped = ["solver/", "solver/a.py", "README.md"]
    assert build_extension.left_out(str(tmp_path), shipped) == ["dev.sh", "solver/b.py", "tests/"]


def _check_smoke(out: dict, res_dir=None):
    assert set(out["steps"]) == set(matrix.STEPS) and matrix.row_passed(out), \
        out.get("traceback") or out.get("error") or out["steps"]
    if res_dir is not None:
        installed = res_dir / "extensions" / "user_default" / "symframes"
        py = "python{}.{}".format(*sys.version_info[:2])
        site = res_dir / "extensions" / ".local" / "lib" / py / "site-packages"
        assert out["files"]["addon"] == str(installed / "__init__.py")
        # the add-on ran on the wheels the zip bundles
        assert out["files"]["scipy"].startswith(str(site)) and out["files"]["mesher"].startswith(str(site))
    assert out["mesher"] == "pytetwild"
    assert out["roles"] == ["error_slice", "glyphs", "singular_faces", "streamlines"]
    assert out["glyphs"] == 300 and 27 <= out["streamlines"] <= 30 and out["tets"] > 100
    assert out["hex_status"] == "valid" and out["hexes"] > 100  # the cube: a grid of cells
    assert out["left"] == []


@pytest.mark.slow
@pytest.mark.mesher
def test_install_from_disk_and_run_the_installed_operators(linux_zip, tmp_path):
    res = tmp_path / "blender-user"
    res.mkdir()
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(res)}
    before = venv_site_packages()
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "extension_smoke.py"), str(linux_zip)],
                          capture_output=True, text=True, timeout=600, env=env, cwd=str(tmp_path))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert line, proc.stdout[-3000:] + proc.stderr[-3000:]
    out = json.loads(line[-1][len("RESULT "):])
    out["steps"]["exit"] = "ok"  # returncode 0, checked above (matrix.smoke does the same)
    _check_smoke(out, res)
    assert out["scipy"] == build_extension.PINS["scipy"]
    assert venv_site_packages() == before  # nothing was installed into the venv


@pytest.mark.slow
@pytest.mark.mesher
def test_blender_4_2_lts_installs_and_runs_its_zip():
    """Blender 4.2 LTS (numpy 1.24.3) with the 4.2 variant's scipy 1.15.3;
    the first run downloads bpy 4.2.23 (335 MB) into .matrix/."""
    out = matrix.run_row(OTHER_BLENDER, example="cube")
    assert "error" not in out, out["error"]  # a row that could not be set up says why
    assert out["blender"].startswith("4.2.") and out["numpy"] == "1.24.3" and out["python"].startswith("3.11.")
    _check_smoke(out)
    assert out["scipy"] == build_extension.VARIANTS["4.2"].scipy
