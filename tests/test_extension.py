"""The extension package: manifest, build, and install as a user does.

The zip is built by scripts/build_extension.py for linux-x64 only (the
wheels of the other platforms would only make it bigger), then installed
with bpy.ops.extensions.package_install_files -- what Install from Disk
calls -- in a separate Python process whose Blender user resources
(BLENDER_USER_RESOURCES) are a temporary folder: the extension and the
wheels it unpacks land there, never in the home folder or the venv.  In
that process the extensions' site-packages comes first on sys.path, so the
installed add-on runs on the bundled scipy and pytetwild (numpy is the
venv's, standing in for Blender's own).
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

INSTALL_AND_RUN = r'''
import json, os, sys
res = os.environ["BLENDER_USER_RESOURCES"]
site = os.path.join(res, "extensions", ".local", "lib", "python3.11", "site-packages")
os.makedirs(site, exist_ok=True)
sys.path.insert(0, site)  # as in Blender: the bundled wheels, not the venv's copies
import bpy

out = {}
out["install"] = sorted(bpy.ops.extensions.package_install_files(
    filepath=sys.argv[1], repo="user_default", enable_on_install=True))
mod = sys.modules["bl_ext.user_default.symframes"]
import scipy, pytetwild
out["files"] = {"addon": mod.__file__, "scipy": scipy.__file__, "pytetwild": pytetwild.__file__}
out["ops"] = [hasattr(bpy.ops.symframes, n) for n in ("compute", "check_network", "show_glyphs",
                                                      "trace_streamlines", "show_singular_faces", "clear")]
scene = bpy.context.scene
bpy.ops.symframes.add_example(example="cube")
s = scene.symframes
s.edge_length, s.glyph_count, s.streamline_seeds = 0.4, 300, 10
out["check"] = sorted(bpy.ops.symframes.check_network())
out["compute"] = sorted(bpy.ops.symframes.compute(streamlines=True))
out["glyphs_op"] = sorted(bpy.ops.symframes.show_glyphs())
out["trace_op"] = sorted(bpy.ops.symframes.trace_streamlines())
out["singular_op"] = sorted(bpy.ops.symframes.show_singular_faces())
roles = {o.get("symframes_role"): o for o in scene.objects if o.get("symframes_role")}
out["roles"] = sorted(roles)
out["glyphs"] = len(roles["glyphs"].data.vertices)
out["streamlines"] = len(roles["streamlines"].data.splines)
out["tets"] = json.loads(s.field["symframes_report"])["sizes"]["tets"]
out["clear"] = sorted(bpy.ops.symframes.clear())
out["left"] = sorted(o.name for o in scene.objects if o.get("symframes_role"))
print("RESULT " + json.dumps(out))
'''


def venv_site_packages() -> list[str]:
    import numpy

    site = os.path.dirname(os.path.dirname(numpy.__file__))
    return sorted(os.listdir(site))


def test_manifest_is_honest():
    with open(os.path.join(ROOT, "blender_manifest.toml"), "rb") as fh:
        m = tomllib.load(fh)
    assert m["schema_version"] == "1.0.0" and m["type"] == "add-on" and m["id"] == "symframes"
    assert tuple(int(x) for x in m["blender_version_min"].split(".")) >= (4, 5, 0)  # 4.2-4.4: numpy 1.24 (README)
    assert all(lic.startswith("SPDX:") for lic in m["license"])
    assert set(m["permissions"]) == {"files"}  # Export Field / Import Network, nothing else
    assert len(m["tagline"]) <= 64
    wheels = [os.path.basename(w) for w in m["wheels"]]
    assert not any(w.startswith("numpy") for w in wheels)  # Blender's own
    # every platform has both wheels, and there is no wheel for an unlisted platform
    tags = {"linux-x64": "x86_64", "windows-x64": "win_amd64", "linux-arm64": "aarch64",
            "windows-arm64": "win_arm64", "macos-arm64": "macosx", "macos-x64": "macosx"}
    for platform in m["platforms"]:
        for pkg in ("scipy", "pytetwild"):
            assert any(w.startswith(pkg + "-") and tags[platform] in w for w in wheels), (platform, pkg)
    for w in wheels:
        assert any(tags[p] in w for p in m["platforms"]), w


@pytest.fixture(scope="module")
def linux_zip(tmp_path_factory):
    out = tmp_path_factory.mktemp("dist")
    # downloads the two linux wheels into ./wheels if they are not there yet
    proc = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "build_extension.py"),
                           "--platform", "linux-x64", "--output-dir", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    zips = sorted(out.glob("*.zip"))
    assert [z.name for z in zips] == ["symframes-0.1.0-linux_x64.zip"]
    return zips[0]


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


def test_install_from_disk_and_run_the_installed_operators(linux_zip, tmp_path):
    res = tmp_path / "blender-user"
    res.mkdir()
    script = tmp_path / "install_and_run.py"
    script.write_text(INSTALL_AND_RUN)
    env = {**os.environ, "BLENDER_USER_RESOURCES": str(res)}
    before = venv_site_packages()
    proc = subprocess.run([sys.executable, str(script), str(linux_zip)], capture_output=True, text=True,
                          timeout=600, env=env, cwd=str(tmp_path))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    assert line, proc.stdout[-3000:] + proc.stderr[-3000:]
    out = json.loads(line[-1][len("RESULT "):])
    assert out["install"] == ["FINISHED"]
    installed = res / "extensions" / "user_default" / "symframes"
    site = res / "extensions" / ".local" / "lib" / "python3.11" / "site-packages"
    assert out["files"]["addon"] == str(installed / "__init__.py")
    # the add-on ran on the wheels the zip bundles
    assert out["files"]["scipy"].startswith(str(site)) and out["files"]["pytetwild"].startswith(str(site))
    assert all(out["ops"])
    for key in ("check", "compute", "glyphs_op", "trace_op", "singular_op", "clear"):
        assert out[key] == ["FINISHED"], key
    assert out["roles"] == ["glyphs", "singular_faces", "streamlines"]
    assert out["glyphs"] == 300 and 27 <= out["streamlines"] <= 30 and out["tets"] > 100
    assert out["left"] == []
    assert venv_site_packages() == before  # nothing was installed into the venv
