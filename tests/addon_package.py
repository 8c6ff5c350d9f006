"""The repository's add-on, imported as the package ``symframes`` (as Blender
imports an installed extension: its modules use relative imports), and the
fixtures every add-on test module uses: import them by name."""

import importlib.util
import os
import sys

import bpy
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = "symframes"


def load_addon():
    """The add-on package, imported once."""
    if PACKAGE not in sys.modules:
        spec = importlib.util.spec_from_file_location(PACKAGE, os.path.join(ROOT, "__init__.py"),
                                                      submodule_search_locations=[ROOT])
        mod = importlib.util.module_from_spec(spec)
        sys.modules[PACKAGE] = mod
        spec.loader.exec_module(mod)
    return sys.modules[PACKAGE]


@pytest.fixture(scope="module", autouse=True)
def registered(share_mesher_runs):
    """The add-on registered for the test module that imports this fixture;
    its copy of the solver shares the session's fTetWild runs
    (tests/conftest.py)."""
    addon = load_addon()
    share_mesher_runs(importlib.import_module(f"{PACKAGE}.solver.mesh.tetwild"))
    addon.register()
    yield
    addon.unregister()


@pytest.fixture(autouse=True)
def empty_scene(registered):
    """Every test starts from an empty factory scene."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield
