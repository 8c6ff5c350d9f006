"""Suggest Network in the add-on: a bare domain gets editable curves, the
solver's suggestion, which Compute Field and Hex Mesh then use as any drawn
network."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

# the add-on is loaded as the package 'symframes' by tests.test_addon, so it comes first
# isort: off
from tests import addon_package
from tests.test_addon import scene, scene_state

from symframes.solver import check, suggest_network  # noqa: E402
from symframes.solver.examples import icosphere  # noqa: E402
from symframes.symframes_addon import examples, scene_io  # noqa: E402

# isort: on

registered = addon_package.registered
empty_scene = addon_package.empty_scene


def _bare_ball_arrays():
    return icosphere(3)


def _bare_ball():
    V, F = _bare_ball_arrays()
    obj = bpy.data.objects.new("Ball", examples.mesh_from_arrays("Ball", V, F))
    scene().collection.objects.link(obj)
    scene().symframes.domain = obj
    return obj


def test_suggest_network_writes_editable_curves_that_solve_and_mesh():
    """The curves written are editable curve objects, and read back they are
    the solver's suggestion itself: the network test_suggest solves and hex
    meshes (test_sphere_suggestion_solves_and_meshes), so Compute Field and
    Hex Mesh take them as that test does."""
    V, F = _bare_ball_arrays()
    _bare_ball()
    assert bpy.ops.symframes.suggest_network() == {"FINISHED"}
    s = scene().symframes
    objs = list(s.network.objects)
    assert len(objs) == 20 and all(o.type == "CURVE" and o.symframes.index == 1 for o in objs)
    assert sum(o.name.startswith("radial") for o in objs) == 8
    inp = scene_io.read_inputs(bpy.context)
    assert check(inp.V, inp.F, inp.network).nodes == 8
    want, _ = suggest_network(V, F)
    got = sorted(inp.network.curves, key=lambda c: c.name)
    assert [c.name for c in got] == sorted(c.name for c in want.curves)
    for c, w in zip(got, sorted(want.curves, key=lambda c: c.name)):
        # the same polyline, read back with points between its own (Blender keeps them in float32)
        assert c.sigma == w.sigma and c.role == w.role
        np.testing.assert_allclose(c.points[[0, -1]], w.points[[0, -1]], atol=1e-6)
        assert _off_polyline(c.points, w.points).max() < 1e-6 and _off_polyline(w.points, c.points).max() < 1e-6


def _off_polyline(P, Q):
    """Distance of each point of P from the polyline Q."""
    A, B = Q[:-1], Q[1:]
    AB = B - A
    t = np.clip(np.einsum("pkj,kj->pk", P[:, None] - A, AB) / np.einsum("kj,kj->k", AB, AB), 0.0, 1.0)
    return np.linalg.norm(P[:, None] - (A + t[..., None] * AB), axis=2).min(axis=1)


def test_suggest_network_is_undone_and_a_refusal_changes_nothing():
    _bare_ball()
    bpy.ops.ed.undo_push(message="domain added")
    before = scene_state()
    assert bpy.ops.symframes.suggest_network("EXEC_DEFAULT", True) == {"FINISHED"}
    assert scene_state() != before
    bpy.ops.ed.undo()
    assert scene_state() == before
    # a ball with a cavity: refused, nothing written
    V, F = icosphere(1)
    me = examples.mesh_from_arrays("Hollow", np.vstack([V, 0.3 * V]), np.vstack([F, F[:, ::-1] + len(V)]))
    hollow = bpy.data.objects.new("Hollow", me)
    scene().collection.objects.link(hollow)
    scene().symframes.domain = hollow
    state = scene_state()
    with pytest.raises(RuntimeError, match="connected components"):
        bpy.ops.symframes.suggest_network()
    assert scene_state() == state


def test_suggest_network_sets_the_angle_that_keeps_its_creases():
    """The prism's 47-degree wall bend lies inside a chart and is left smooth
    (docs/suggest.md): the operator sets the Angle to the one that marks
    exactly the creases kept, 49.5 degrees."""
    from symframes.solver.examples import prism_example

    V, F, _ = prism_example()
    obj = bpy.data.objects.new("Prism", examples.mesh_from_arrays("Prism", V, F))
    scene().collection.objects.link(obj)
    s = scene().symframes
    s.domain = obj
    assert np.isclose(np.degrees(s.sharp_angle), 30.0)
    assert bpy.ops.symframes.suggest_network() == {"FINISHED"}
    assert 47.0 < np.degrees(s.sharp_angle) < 52.0 and s.use_sharp_angle
    assert len(s.network.objects) == 0  # every chart boundary is a crease: no curve


def test_a_torus_gets_closed_loops_read_back_closed():
    """A torus's suggestion is four closed loops of +1/4 (the ring route,
    solver/suggest/ring.py): written as cyclic splines, they read back as
    closed curves of the same index, so the user edits loops, not arcs."""
    from symframes.solver.examples import torus_surface

    V, F = torus_surface(1.0, 0.4, 48, 16)
    obj = bpy.data.objects.new("Torus", examples.mesh_from_arrays("Torus", V, F))
    scene().collection.objects.link(obj)
    scene().symframes.domain = obj
    assert bpy.ops.symframes.suggest_network() == {"FINISHED"}
    objs = list(scene().symframes.network.objects)
    assert len(objs) == 4 and all(o.data.splines[0].use_cyclic_u for o in objs)
    inp = scene_io.read_inputs(bpy.context)
    assert len(inp.network.curves) == 4
    assert all(c.closed and c.sigma == 0.25 for c in inp.network.curves)


def test_a_cancelled_suggestion_gives_nothing_to_write():
    """The suggestion runs as a job (a worker thread from the UI); Esc during
    it discards its result, and the operator then writes nothing."""
    from symframes.symframes_addon import job

    V, F = icosphere(2)
    j = job.SuggestJob(V=V, F=F)
    j.cancel()
    j.run()
    assert j.cancelled and j.outcome is None and j.error is None
    done = job.SuggestJob(V=V, F=F)
    done.run()
    net, rep = done.outcome
    assert len(net.curves) == 20 and rep.nodes == 8 and done.fraction == 1.0
