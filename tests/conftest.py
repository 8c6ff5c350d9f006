"""Meshed and solved examples shared by the whole test session.

fTetWild takes most of a solve's time (the cylinder at h = 0.3: ~15 of ~19
CPU seconds), and many modules need the same solids.  Each example is
meshed once, and solved once, per session and set of options; the factory
fixtures hand out deep copies, so a test may change what it gets (solve it
again, turn its boundary field, edit its arrays) without touching the next
test's:

    solved(example, **options)   -> Result: the session's solve
    meshed(example, **options)   -> FieldProblem: tet mesh, embedding,
                                    boundary field and constraints, not solved
    tet_mesh(example, **options) -> TetMesh
    example_input(example)       -> (V, F, Network)

``options`` are fields of solver.Options (validated and normalised by it).
The mesh is keyed by the example and every field but the solver's own
(SOLVER_FIELDS: penalty, max_iterations, tolerance, init, seed): a
meshed() problem carries the options asked for, and solved() solves such a
problem.  A result is keyed by the example and every field.  ``example`` is
a name of solver.examples.EXAMPLES, ``l_prism``
(solver.examples.l_prism_example), ``l_prism_hole``
(testkit.hexnet.l_prism_with_hole), or one followed by ``:tet-edge``: its
interior curves routed along the edges of an independent fTetWild mesh, as
other tools export networks (testkit/tetedge.py; drawn once per session).

./dev.sh test runs the suite on two pytest-xdist workers; they share the
cache through files in the run's common temporary folder (one worker makes
an entry, the other waits for it and reads it), so an example is meshed
once per run on either.

fTetWild is not deterministic: a shared mesh is one of the meshes it may
make, and what a test checks on it must hold on any of them.  A test that
needs a mesh made afresh (meshing is what it checks, or its input is its
own) builds one itself and says why.
"""

from __future__ import annotations

import copy
import hashlib
import os
import pickle
import shutil
from dataclasses import asdict

import pytest

try:
    import fcntl
except ImportError:  # Windows: each pytest-xdist worker makes its own
    fcntl = None

SOLVER_FIELDS = ("penalty", "max_iterations", "tolerance", "init", "seed")
TET_EDGE = ":tet-edge"
# edge length of the independent mesh a tet-edge network is routed through
# (the solve's own default h is 0.15-0.16 for these examples)
TET_EDGE_H = {"cylinder": 0.25, "ball": 0.2}
TET_EDGE_H_DEFAULT = 0.2


# ------------------------------------------------------------------ inputs
def _load(example: str):
    """(V, F, Network) of an example (names as in the module docstring)."""
    from solver.examples import l_prism_example, load_example

    base, _, variant = example.partition(":")
    if base == "l_prism_hole":
        from testkit.hexnet import l_prism_with_hole

        V, F, net = l_prism_with_hole()
    else:
        V, F, net = l_prism_example() if base == "l_prism" else load_example(base)
    if not variant:
        return V, F, net
    if ":" + variant != TET_EDGE:
        raise ValueError(f"unknown variant {variant!r} of {base!r}; the one there is: {TET_EDGE}")
    from solver.examples import cylinder_surface
    from solver.mesh.tetwild import tetrahedralize
    from solver.surface.trisurface import TriSurface
    from testkit.tetedge import tet_edge_network

    h_src = TET_EDGE_H.get(base, TET_EDGE_H_DEFAULT)
    mesh = None
    if base == "cylinder":
        # fTetWild takes 3x longer on the example's 64-gon with its thin
        # wall triangles; a 32-gon of the same solid routes as well
        mesh = tetrahedralize(TriSurface(*cylinder_surface(1.0, 2.0, n=32, rings=4)), h_src)
    tn, _ = tet_edge_network(V, F, net, h_src, mesh=mesh, seed=1)
    return V, F, tn


def _keys(options: dict):
    """(Options, mesh key, solve key) of keyword options."""
    from solver import Options

    opts = Options(**options)
    fields = asdict(opts)
    mesh_key = tuple((k, v) for k, v in fields.items() if k not in SOLVER_FIELDS)
    return opts, mesh_key, tuple(fields.items())


class _Session:
    """The cache.  Nothing in it is handed out: every call returns a deep
    copy.  With pytest-xdist the workers share it through files (shared):
    one worker makes an entry, the others wait for it and read it."""

    def __init__(self):
        self.made = {}  # (kind, key) -> input (V, F, Network), FieldProblem or Result
        self.shared = None  # a folder every worker of this run sees, or None

    def _get(self, kind, key, make):
        if (kind, key) not in self.made:
            self.made[kind, key] = self._made_once(kind, key, make)
        return self.made[kind, key]

    def _made_once(self, kind, key, make):
        if self.shared is None or fcntl is None:
            return make()
        path = self.shared / f"{kind}-{hashlib.sha1(repr(key).encode()).hexdigest()}.pickle"
        with open(path.with_suffix(".lock"), "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
            if path.exists():
                with open(path, "rb") as fh:
                    return pickle.load(fh)
            obj = make()
            tmp = path.with_suffix(".part")
            with open(tmp, "wb") as fh:
                pickle.dump(obj, fh, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, path)
            return obj

    def input(self, example):
        return self._get("input", example, lambda: _load(example))

    def problem(self, example, options):
        from solver import FieldProblem

        opts, mesh_key, _ = _keys(options)
        p = self._get("problem", (example, mesh_key), lambda: FieldProblem(*self.input(example), opts))
        return p, opts

    def meshed(self, example, options):
        p, opts = self.problem(example, options)
        out = copy.deepcopy(p)
        out.options = opts  # differs at most in the solver's own fields
        return out

    def _solve(self, example, options):
        r = self.meshed(example, options).solve()
        # the LM matrices (~50 MB for the ball at 6.5k tets): made again,
        # the same, by a copy that asks for problem.volume
        r.problem._volume = None
        return r

    def solved(self, example, options):
        _, _, key = _keys(options)
        return copy.deepcopy(self._get("result", (example, key), lambda: self._solve(example, options)))


_SESSION = _Session()


CACHE_FOLDER = "symframes-cache"


@pytest.fixture(scope="session", autouse=True)
def _shared_cache(tmp_path_factory):
    """Under pytest-xdist: a folder of this run that every worker sees
    (the parent of the workers' own temporary folders)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        _SESSION.shared = tmp_path_factory.getbasetemp().parent / CACHE_FOLDER
        _SESSION.shared.mkdir(exist_ok=True)
    yield


def pytest_sessionfinish(session):
    """The controller of a pytest-xdist run removes the workers' shared
    cache (a few hundred MB of pickles) once they are done."""
    factory = getattr(session.config, "_tmp_path_factory", None)
    if os.environ.get("PYTEST_XDIST_WORKER") or factory is None or not session.config.getoption("numprocesses", None):
        return
    shutil.rmtree(factory.getbasetemp() / CACHE_FOLDER, ignore_errors=True)


def _runs_the_blender_4_2_test(config) -> bool:
    """Whether this run includes test_extension's Blender 4.2 test: the
    whole tests folder (or that file) named, no -k, and slow tests kept."""
    if config.getoption("keyword", "") or "slow" in (config.getoption("markexpr", "") or ""):
        return False
    here = os.path.dirname(os.path.abspath(__file__))
    named = [os.path.abspath(str(a).split("::")[0]) for a in (config.args or ["."])]
    return any(here.startswith(p) or p == os.path.join(here, "test_extension.py") for p in named)


def pytest_sessionstart(session):
    """The controller (the one process of a run without workers) starts the
    Blender 4.2 venv of test_extension (a 335 MB bpy wheel downloaded and
    installed, 30-40 s on a fresh clone, spent mostly waiting on the
    network) in a thread, beside the tests; scripts/matrix.py's lock makes
    the test wait for it, or make it itself should this fail."""
    if os.environ.get("PYTEST_XDIST_WORKER") or not _runs_the_blender_4_2_test(session.config):
        return
    import sys
    import threading

    scripts = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "scripts")
    sys.path.insert(0, scripts)
    try:
        import matrix
    finally:
        sys.path.remove(scripts)

    def prefetch():
        try:
            matrix.bpy_venv(matrix.OTHER_BLENDER, log=lambda msg: None)
        except Exception:  # the test makes it itself and reports what failed
            pass

    threading.Thread(target=prefetch, name="bpy-4.2-venv", daemon=True).start()


SUITE_TIMES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench", "SUITE.md")


def _file_seconds() -> dict:
    """Each test file's seconds of work as bench/SUITE.md records them
    (``| `tests/x.py` | 12.3 | ...`` rows); empty where it cannot be read."""
    import re

    try:
        with open(SUITE_TIMES, encoding="utf-8") as fh:
            text = fh.read()
    except OSError:
        return {}
    return {m[1]: float(m[2]) for m in re.finditer(r"^\| `(tests/[^`]+\.py)` \| ([\d.]+) \|", text, re.M)}


def pytest_collection_modifyitems(config, items):
    """The heaviest test files first, by their recorded seconds (files not
    recorded last): ./dev.sh test deals files whole to two workers in
    collection order (--dist loadfile --no-loadscope-reorder), and a heavy
    file dealt last keeps one worker busy while the other has nothing left.
    The sort is stable, so each file's tests keep their order."""
    seconds = _file_seconds()
    if seconds:
        items.sort(key=lambda item: -seconds.get(item.nodeid.split("::")[0], 0.0))


def _tetwild_key(V, F, edge_length, epsilon, simplify, tetgen_volume):
    """The memo key of one mesher run: its input rounded far below any
    tolerance of the mesher (the same solid built at another scale or place
    comes normalised to the same unit box up to round-off), the options and
    the bindings that would run it."""
    import numpy as np

    from solver.mesh.tetwild import mesher_name

    digest = hashlib.sha1(np.round(np.asarray(V, float), 9).tobytes())
    digest.update(np.asarray(F, np.int64).tobytes())
    return (digest.hexdigest(), round(float(edge_length), 12), float(epsilon), bool(simplify),
            None if tetgen_volume is None else round(float(tetgen_volume), 15), mesher_name())


FRESH_RUNS = ("_fresh_mesh", "_remesh")  # solver.pipeline's functions that ask for a new mesh of the same input


def _share_mesher_runs(tetwild) -> None:
    """Each distinct fTetWild run once per test run: tests that mesh the
    same solid with the same curve tubes (the cylinder at the metre and at
    the micrometre: fTetWild gets both in a unit box) share its output, as
    they share a solve above.  ``tetwild`` is solver.mesh.tetwild, or the
    add-on's copy of it (tests/addon_package.py: the add-on runs the solver
    as the package ``symframes.solver``); a miss runs that module's own
    run_tetwild, so its errors are its own classes.  A run that can be
    cancelled is made afresh (cancelling is what such a caller checks),
    and so is the fresh mesh SymFrames asks for itself where a mesh left LM
    short of a solution (pipeline._fresh_mesh: the shared run would hand
    back the mesh it replaces, and FieldProblem's second mesh where its first
    one's surface folded: FRESH_RUNS); TetGen runs (mesh/cdt.py, which holds
    run_tetwild by its own name) are not shared."""
    import inspect

    run = tetwild.run_tetwild
    if getattr(run, "unshared", None) is not None:
        return

    def shared(V, F, edge_length, epsilon, cancel=None, simplify=True, tetgen_volume=None):
        if cancel is not None or any(f.function in FRESH_RUNS for f in inspect.stack(0)):
            return run(V, F, edge_length, epsilon, cancel=cancel, simplify=simplify, tetgen_volume=tetgen_volume)
        key = _tetwild_key(V, F, edge_length, epsilon, simplify, tetgen_volume)
        P, T = _SESSION._get("mesher", key, lambda: run(V, F, edge_length, epsilon, simplify=simplify,
                                                         tetgen_volume=tetgen_volume))
        return P.copy(), T.copy()

    shared.unshared = run
    tetwild.run_tetwild = shared


@pytest.fixture(scope="session", autouse=True)
def _shared_mesher_runs():
    """solver.mesh.tetwild's runs shared for the session (_share_mesher_runs)."""
    import solver.mesh.tetwild as tetwild

    _share_mesher_runs(tetwild)
    yield
    tetwild.run_tetwild = tetwild.run_tetwild.unshared


@pytest.fixture(scope="session")
def share_mesher_runs():
    """share_mesher_runs(tetwild module): another copy of solver.mesh.tetwild
    (the add-on's) shares the session's fTetWild runs too."""
    return _share_mesher_runs


@pytest.fixture(scope="session")
def example_input():
    """example_input(example) -> (V, F, Network) of an example, a copy of the
    session's (a tet-edge network is drawn once per session)."""
    return lambda example: copy.deepcopy(_SESSION.input(example))


@pytest.fixture(scope="session")
def tet_mesh():
    """tet_mesh(example, **options) -> a copy of the session's TetMesh of an example."""
    return lambda example, **options: copy.deepcopy(_SESSION.problem(example, options)[0].mesh)


@pytest.fixture(scope="session")
def meshed():
    """meshed(example, **options) -> a FieldProblem of the caller's own on the
    session's mesh of the example (the options that only the solve reads
    are set on it)."""
    return lambda example, **options: _SESSION.meshed(example, options)


@pytest.fixture(scope="session")
def solved():
    """solved(example, **options) -> a copy of the session's Result for the
    example and options."""
    return lambda example, **options: _SESSION.solved(example, options)


@pytest.fixture(scope="module")
def stored_field(solved, tmp_path_factory):
    """A solved cylinder's result file (io.save_result), its arrays and its
    Result: what the stored-result readers are tested on."""
    import numpy as np

    from solver import io

    res = solved("cylinder")
    path = tmp_path_factory.mktemp("stored") / "c.npz"
    io.save_result(str(path), res)
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    return str(path), arrays, res
