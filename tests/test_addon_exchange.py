"""Files in and out of the add-on (symframes_addon/exchange.py): Export Field,
the tet mesh as an object, Import Network, and their File menu entries.

A cylinder is solved once through the add-on (coarse: seconds) and saved;
each export test reopens it, so an export works from a field read back from
a .blend, not only from the solve in memory.
"""

from __future__ import annotations

import os

import bpy
import meshio
import numpy as np
import pytest

# the add-on is loaded as the package 'symframes' by tests.test_addon, so it comes first
# isort: off
from tests import addon_package
from tests.meshes import box_mesh
from tests.test_addon import add_example, open_blend

from symframes.solver import Curve, Network  # noqa: E402
from symframes.solver.io import write_network, write_obj  # noqa: E402
from symframes.solver.io.cubecover import read_perm  # noqa: E402
from symframes.solver.io.ovm import read_ovm, write_ovm  # noqa: E402
from symframes.solver.io.qtn import read_qtn  # noqa: E402
from symframes.solver.mesh.tetmesh import TetMesh  # noqa: E402
from symframes.symframes_addon import menus, storage  # noqa: E402

# isort: on

registered = addon_package.registered  # fixtures shared by the add-on tests
empty_scene = addon_package.empty_scene


@pytest.fixture(scope="module")
def cylinder(registered, tmp_path_factory):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    add_example("cylinder", 0.4)
    assert bpy.ops.symframes.compute() == {"FINISHED"}
    path = tmp_path_factory.mktemp("cylinder") / "cylinder.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return path


def scene_objects():
    return sorted(o.name for o in bpy.data.objects)


def test_file_menus_hold_the_operators():
    assert ("symframes.export_field" in [e[0] for e in menus.EXPORT_ENTRIES]
            and menus.operator_registered("symframes.export_field"))
    assert ("symframes.import_network" in [e[0] for e in menus.IMPORT_ENTRIES]
            and menus.operator_registered("symframes.import_network"))
    assert menus.draw_export_menu in bpy.types.TOPBAR_MT_file_export._dyn_ui_initialize()
    assert menus.draw_import_menu in bpy.types.TOPBAR_MT_file_import._dyn_ui_initialize()
    assert "symframes.tet_mesh_object" in [e[0] for e in menus.OBJECT_ENTRIES if e]


def test_export_without_a_field_is_refused():
    assert not bpy.ops.symframes.export_field.poll()


@pytest.mark.slow
@pytest.mark.mesher
def test_export_every_format_from_a_saved_field(cylinder, tmp_path):
    open_blend(cylinder)
    f = storage.solved_field(bpy.context.scene)
    V, T = f.mesh.vertices, f.mesh.tets
    assert (f.curve >= 0).any() and np.abs(f.embedding.face_omega).max() > 1.0
    for fmt, ext in (("VTU", "vtu"), ("MEDIT", "mesh"), ("OVM", "ovm"), ("QTN", "qtn")):
        path = str(tmp_path / f"field.{ext}")
        assert bpy.ops.symframes.export_field(filepath=path, file_format=fmt) == {"FINISHED"}
        assert os.path.exists(path)
    # VTU: the field as solved, on its own tet mesh
    m = meshio.read(str(tmp_path / "field.vtu"))
    assert np.allclose(m.points, V, atol=1e-12) and np.array_equal(m.cells_dict["tetra"], T)
    for k in range(3):
        assert np.allclose(m.point_data[f"axis{k}"], f.frames[:, :, k], atol=1e-12)
    curve = m.cell_data["curve"][0]
    assert set(np.unique(curve[curve >= 0])) == {0, 1, 2, 3}
    assert np.array_equal(curve, f.curve)
    # the hex meshers' formats: the tet mesh split so that the curves run along its edges, tets in one order
    n = len(meshio.read(str(tmp_path / "field.mesh")).cells_dict["tetra"])
    assert n > len(T)
    assert len(read_qtn(str(tmp_path / "field.qtn"))) == n
    assert read_ovm(str(tmp_path / "field.ovm")).tets.shape == (n, 4)
    n_tets, pairs, perms = read_perm(str(tmp_path / "field.perm"))
    assert n_tets == n and len(pairs) > 0  # the field turns around the curves


@pytest.mark.slow
@pytest.mark.mesher
def test_export_field_writes_what_the_command_line_writes(cylinder, tmp_path):
    """Export Field and ``python -m solver --from-result R.npz --export``
    write the same files, byte for byte: the curves on tet edges for the hex
    meshers' formats."""
    from symframes.solver.__main__ import main
    from symframes.solver.io import save_field

    open_blend(cylinder)
    npz = str(tmp_path / "field.npz")
    save_field(npz, storage.solved_field(bpy.context.scene))
    for fmt, ext, side in (("MEDIT", "mesh", (".fra", ".perm")), ("OVM", "ovm", ()), ("VTU", "vtu", ())):
        ours, cli = tmp_path / f"addon.{ext}", tmp_path / f"cli.{ext}"
        assert bpy.ops.symframes.export_field(filepath=str(ours), file_format=fmt) == {"FINISHED"}
        assert main(["--from-result", npz, "--export", str(cli), "--quiet"]) == 0
        for suffix in (f".{ext}", *side):
            a, b = ours.with_suffix(suffix).read_bytes(), cli.with_suffix(suffix).read_bytes()
            assert a == b, f"{fmt} {suffix}: the add-on's export differs from the command line's"


@pytest.mark.slow
@pytest.mark.mesher
def test_export_into_a_missing_folder_is_refused(cylinder, tmp_path):
    open_blend(cylinder)
    with pytest.raises(RuntimeError, match="does not exist"):
        bpy.ops.symframes.export_field(filepath=str(tmp_path / "no" / "field.vtu"), file_format="VTU")


@pytest.mark.slow
@pytest.mark.mesher
def test_tet_mesh_as_object(cylinder):
    open_blend(cylinder)
    f = storage.solved_field(bpy.context.scene)
    mesh = TetMesh(f.mesh.vertices, f.mesh.tets)
    before = scene_objects()
    assert bpy.ops.symframes.tet_mesh_object() == {"FINISHED"}
    (name,) = set(scene_objects()) - set(before)
    me = bpy.data.objects[name].data
    assert len(me.polygons) == mesh.n_faces and len(me.vertices) == mesh.n_vertices
    assert storage.FRAME_ATTRIBUTE in me.attributes and "curve" in me.attributes


def test_import_a_json_network(tmp_path):
    from symframes.solver.examples import load_example

    V, F, net = load_example("cylinder")
    write_obj(str(tmp_path / "part.obj"), V, F)
    write_network(str(tmp_path / "part.json"), net, surface="part.obj")
    assert bpy.ops.symframes.import_network(filepath=str(tmp_path / "part.json")) == {"FINISHED"}
    s = bpy.context.scene.symframes
    assert s.domain is not None and s.domain.name == "part"
    curves = [o for o in s.network.all_objects if o.type == "CURVE"]
    assert len(curves) == len(net.curves) and {o.symframes.index for o in curves} == {1}
    assert bpy.ops.symframes.check_network() == {"FINISHED"}


def _tagged_axes(tmp_path) -> str:
    """A structured box tet mesh with a valence-3 and a valence-5 axis tagged
    on its edges (OVM, the valence convention); its path."""
    mesh = box_mesh(4)
    tags = np.full(mesh.n_edges, 4, np.int64)
    for x, valence in ((1, 3), (3, 5)):
        ids = np.array([np.argmin(np.linalg.norm(mesh.vertices - 0.25 * np.array([x, 2, z]), axis=1))
                        for z in range(5)])
        tags[mesh.edge_index(ids[:-1], ids[1:])] = valence
    path = str(tmp_path / "axes.ovm")
    write_ovm(path, mesh, edge_props={"valence": tags})
    return path


def test_import_a_tagged_tet_mesh(tmp_path):
    """Two straight valence-3 and valence-5 axes through a box, tagged on the
    edges of a structured tet mesh: two curves of index +1 and -1 quarter
    turns with the valence convention, the box's edges sharp by angle."""
    path = _tagged_axes(tmp_path)
    assert bpy.ops.symframes.import_network(filepath=path, tag_convention="VALENCE") == {"FINISHED"}
    s = bpy.context.scene.symframes
    curves = [o for o in s.network.all_objects if o.type == "CURVE"]
    assert sorted(o.symframes.index for o in curves) == [-1, 1]
    assert bpy.ops.symframes.check_network() == {"FINISHED"}


def test_import_detects_the_convention_and_refuses_a_wrong_one(tmp_path):
    """The same axes tagged by valence: Detect finds 'valence' and says so;
    an explicit wrong convention is refused before anything is added, naming
    the detected one (the check the command line runs, issue 43)."""
    path = _tagged_axes(tmp_path)
    before = scene_objects()
    with pytest.raises(RuntimeError, match="'index' tag convention.*the 'valence' convention"):
        bpy.ops.symframes.import_network(filepath=path, tag_convention="INDEX")
    assert scene_objects() == before
    assert bpy.ops.symframes.import_network(filepath=path) == {"FINISHED"}
    curves = [o for o in bpy.context.scene.symframes.network.all_objects if o.type == "CURVE"]
    assert sorted(o.symframes.index for o in curves) == [-1, 1]


def test_a_failed_import_leaves_the_scene_unchanged(tmp_path):
    add_example("cube", 0.4)
    before = scene_objects()
    bad = tmp_path / "broken.ovm"
    bad.write_text("OVM ASCII\nVertices\n2\n0 0 0\n")
    with pytest.raises(RuntimeError, match="cannot import broken.ovm"):
        bpy.ops.symframes.import_network(filepath=str(bad))
    lonely = tmp_path / "lonely.json"
    write_network(str(lonely), Network(curves=[Curve(np.array([[0.0, 0, 0], [0, 0, 1]]), sigma=0.25)]))
    with pytest.raises(RuntimeError, match="names no surface"):
        bpy.ops.symframes.import_network(filepath=str(lonely))
    assert scene_objects() == before
