"""Seeded fuzzing of everything that reads user input (issue 28).

Random option values, mutated network files (JSON), mutated surfaces (OBJ)
and random networks in the examples' solids go through the reading and
validation path (io + check_input, what ``--check`` runs; no meshing), and
eight tiny solves with random valid options run on a structured tet mesh.  The
bar: nothing but the documented errors (SymFramesError subclasses) comes
out, every tiny solve gives rotations, and no case hangs (CASE_SECONDS, a
deadline far past any case's time even on a loaded machine).  Each case is
derived from its own seed, printed on failure so that it can be replayed.
"""

from __future__ import annotations

import contextlib
import json
import signal
import sys
import zlib

import numpy as np
import pytest

from solver import Curve, Network, SymFramesError, io
from solver.examples import box, cylinder_example, cylinder_surface, icosphere
from solver.network.validation import check_input

# wall clock: catches a hang, not slowness (a case takes well under a second;
# issue 43's bar for any input is 60 s)
CASE_SECONDS = 60


@contextlib.contextmanager
def bounded(seconds=CASE_SECONDS):
    """Fail a case that runs longer than ``seconds`` (POSIX alarm)."""
    if not hasattr(signal, "SIGALRM"):
        yield
        return

    def hang(signum, frame):
        raise TimeoutError(f"case ran longer than {seconds} s")

    old = signal.signal(signal.SIGALRM, hang)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def run_case(label, fn, seconds=CASE_SECONDS):
    """Run fn; return 'ok' or the error class; fail on anything else."""
    try:
        with bounded(seconds):
            fn()
        return "ok"
    except SymFramesError as e:
        assert str(e), label
        return type(e).__name__
    except Exception as e:  # noqa: BLE001 - this is what the test looks for
        pytest.fail(f"{label}: {type(e).__name__}: {e}")


# ------------------------------------------------------------------ values
WEIRD = [None, True, False, 0, -1, 1, 2.5, -0.0, 1e308, -1e-300, float("nan"), float("inf"), -float("inf"), "",
         "0.3", "abc", "1e3", [], [1], [1, 2, 3], {}, {"a": 1}, 10**30, -(10**30), 3.0, 0.001]


def weird(rng):
    return WEIRD[int(rng.integers(len(WEIRD)))]


OPTION_KEYS = ["edge_length", "penalty", "max_iterations", "tolerance", "init", "seed", "tube_radius", "node_radius",
               "epsilon", "target_tets", "check_intersections", "refine", "snap_features", "bogus"]


@pytest.mark.parametrize("seed", range(60))
def test_fuzz_options(seed):
    rng = np.random.default_rng(seed)
    d = {OPTION_KEYS[int(k)]: weird(rng) for k in rng.integers(0, len(OPTION_KEYS), int(rng.integers(1, 4)))}
    run_case(f"options seed {seed}: {d!r}", lambda: io.options_from_dict(d))


# ------------------------------------------------------- network files
def _small_cylinder():
    """The cylinder example on a coarser surface (validation in ~0.1 s)."""
    _, _, net = cylinder_example()
    V, F = cylinder_surface(1.0, 2.0, n=24, rings=3)
    return V, F, net


@pytest.fixture(scope="module")
def cylinder_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz")
    V, F, net = _small_cylinder()
    io.write_obj(str(d / "c.obj"), V, F)
    io.write_network(str(d / "c.json"), net, surface="c.obj")
    assert run_case("the unmutated file", lambda: check_input(*io.read_obj(str(d / "c.obj")),
                                                              io.read_network(str(d / "c.json"))[0])) == "ok"
    return d, json.loads((d / "c.json").read_text()), (d / "c.obj").read_text()


def mutate_json(rng, obj, depth=0):
    """Replace, delete or add one value somewhere in a JSON structure."""
    if isinstance(obj, dict) and obj and rng.random() < 0.8:
        key = list(obj)[int(rng.integers(len(obj)))]
        r = rng.random()
        if r < 0.15:
            del obj[key]
        elif r < 0.5 or depth > 3:
            obj[key] = weird(rng)
        else:
            obj[key] = mutate_json(rng, obj[key], depth + 1)
        return obj
    if isinstance(obj, list) and obj and rng.random() < 0.8:
        i = int(rng.integers(len(obj)))
        r = rng.random()
        if r < 0.15:
            del obj[i]
        elif r < 0.25:
            obj.append(obj[i] if rng.random() < 0.5 else weird(rng))
        elif r < 0.5 or depth > 3:
            obj[i] = weird(rng)
        else:
            obj[i] = mutate_json(rng, obj[i], depth + 1)
        return obj
    if isinstance(obj, (int, float)) and not isinstance(obj, bool) and rng.random() < 0.6:
        return obj * float(rng.choice([-1.0, 0.0, 0.5, 2.0, 1e6, 1e-6])) + float(rng.normal())
    return weird(rng)


def gentle_network(rng, d):
    """Valid-looking changes: jittered points, other quarter-turn indices,
    roles, torsions, closed flags, tolerances, sharp edges and options."""
    for c in d["curves"]:
        P = np.asarray(c["points"], float)
        c["points"] = (P + rng.normal(scale=float(rng.choice([0.0, 1e-4, 0.01, 0.1])), size=P.shape)).tolist()
        if rng.random() < 0.3:
            c["sigma"] = float(rng.choice([-0.5, -0.25, 0.0, 0.25, 0.5]))
            c["role"] = "singular" if c["sigma"] else str(rng.choice(["feature", "sharp"]))
        if rng.random() < 0.2:
            c["torsion"] = "fixed"
        if rng.random() < 0.1:
            c["closed"] = True
    if rng.random() < 0.3:
        d["curves"] = d["curves"][: int(rng.integers(0, len(d["curves"]) + 1))]
    if rng.random() < 0.3:
        d["sharp_angle"] = float(rng.uniform(0, 179))
    if rng.random() < 0.2:
        d["sharp_edges"] = rng.integers(0, 200, (int(rng.integers(1, 5)), 2)).tolist()
    for key in ("node_tolerance", "boundary_tolerance"):
        if rng.random() < 0.2:
            d[key] = float(rng.choice([1e-9, 1e-3, 0.05, 0.2, 1.0]))
    if rng.random() < 0.3:
        d["options"] = {"edge_length": float(rng.choice([0.05, 0.3, 1.0])), "refine": int(rng.integers(0, 4)),
                        "init": str(rng.choice(["zero", "random", "linear"]))}
    return d


@pytest.mark.parametrize("seed", range(70))
def test_fuzz_network_file(cylinder_files, seed):
    folder, base, _ = cylinder_files
    rng = np.random.default_rng(1000 + seed)
    d = json.loads(json.dumps(base))
    if seed % 2:
        d = gentle_network(rng, d)  # plausible values: reach the geometric checks
    for _ in range(int(rng.integers(0 if seed % 2 else 1, 3))):
        d = mutate_json(rng, d)
    path = folder / f"m{seed}.json"
    if rng.random() < 0.15:  # corrupt the text itself
        text = bytearray(json.dumps(d).encode())
        for _ in range(int(rng.integers(1, 5))):
            text[int(rng.integers(len(text)))] = int(rng.integers(256))
        path.write_bytes(bytes(text[: int(rng.integers(1, len(text) + 1))]))
    else:
        path.write_text(json.dumps(d))

    def go():
        net, opts, surface = io.read_network(str(path))
        io.options_from_dict(opts)
        V, F = io.read_obj(str(folder / "c.obj"))
        check_input(V, F, net)

    run_case(f"network file seed {1000 + seed}: {path.read_bytes()[:300]!r}", go)


# ---------------------------------------------------------------- OBJ files
def mutate_obj(rng, text):
    lines = text.splitlines()
    for _ in range(int(rng.integers(1, 4))):
        i = int(rng.integers(len(lines)))
        r = rng.random()
        parts = lines[i].split()
        if r < 0.15:
            del lines[i]
        elif r < 0.25:
            lines.insert(i, lines[i])
        elif r < 0.45 and parts and parts[0] == "f":  # an index out of range, 0, negative or garbage
            j = int(rng.integers(1, len(parts)))
            parts[j] = str(rng.choice(["0", "-1", "-999", "999", "x", "1/2/3", "2//1", "1.5"]))
            lines[i] = " ".join(parts)
        elif r < 0.6 and parts and parts[0] == "v":
            j = int(rng.integers(1, len(parts)))
            parts[j] = str(rng.choice(["nan", "inf", "1e400", "abc", "", "0"]))
            lines[i] = " ".join(parts)
        elif r < 0.7 and parts and parts[0] == "f":  # reverse or merge into a polygon
            lines[i] = " ".join(["f"] + parts[:0:-1])
        elif r < 0.8:
            f = [str(int(x)) for x in rng.integers(-20, 60, int(rng.integers(1, 7)))]
            lines.insert(i, "f " + " ".join(f))
        elif r < 0.9:
            lines.insert(i, f"v {rng.normal():.3f} {rng.normal():.3f}")
        else:
            lines = lines[: i + 1]
    return "\n".join(lines) + "\n"


def gentle_obj(rng, V, F):
    """The box as an OBJ with its coplanar triangle pairs merged into quads
    or larger polygons (vertices rotated, some collinear), vt/vn/comment
    records, slash indices, negative indices, jitter."""
    V = V + rng.normal(scale=float(rng.choice([0.0, 1e-9, 1e-4])), size=V.shape)
    polys = [list(f) for f in F]
    # merge triangle pairs sharing an edge in the same plane into quads
    if rng.random() < 0.7:
        merged, used = [], set()
        for i in range(0, len(F) - 1, 2):
            a, b = F[i], F[i + 1]
            shared = set(a) & set(b)
            if len(shared) == 2:
                (x,) = set(b) - shared
                # insert b's free vertex between a's shared pair
                j = next(j for j in range(3) if a[j] in shared and a[(j + 1) % 3] in shared)
                merged.append([a[j], x, a[(j + 1) % 3], a[(j + 2) % 3]])
                used |= {i, i + 1}
        polys = merged + [list(F[i]) for i in range(len(F)) if i not in used]
    polys = [list(np.roll(p, int(rng.integers(len(p))))) for p in polys]
    lines = ["# fuzz", "o box"] + [f"v {x:.12g} {y:.12g} {z:.12g}" for x, y, z in V] + ["vt 0 0", "vn 0 0 1"]
    n = len(V)
    late = rng.random() < 0.2  # faces before the vertices they use (then no negative indices)
    for p in polys:
        style = rng.random()
        if late and 0.3 <= style < 0.4:
            style = 0.5
        if style < 0.2:
            idx = [f"{i + 1}/1/1" for i in p]
        elif style < 0.3:
            idx = [f"{i + 1}//1" for i in p]
        elif style < 0.4:
            idx = [str(i - n) for i in p]
        else:
            idx = [str(i + 1) for i in p]
        lines.append("f " + " ".join(idx))
    if late:
        k = 2 + n
        lines = lines[:2] + lines[k + 2:] + lines[2:k + 2]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("seed", range(50))
def test_fuzz_obj_file(tmp_path, seed):
    rng = np.random.default_rng(2000 + seed)
    V, F = box(n=2)
    text = "".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V) + "".join(f"f {a + 1} {b + 1} {c + 1}\n"
                                                                            for a, b, c in F)
    path = tmp_path / "m.obj"
    valid = False
    if seed % 2:  # valid-looking: polygons, other OBJ records, faces before vertices, jitter
        text = gentle_obj(rng, V, F)
        valid = rng.random() >= 0.3
        if not valid:
            text = mutate_obj(rng, text)
        path.write_text(text)
    elif rng.random() < 0.1:
        path.write_bytes(bytes(rng.integers(0, 256, 400, dtype=np.uint8)))
    else:
        path.write_text(mutate_obj(rng, text))

    def go():
        W, G = io.read_obj(str(path))
        check_input(W, G, Network(sharp_angle=30))

    outcome = run_case(f"OBJ seed {2000 + seed}: {path.read_bytes()[:400]!r}", go)
    if valid:  # a closed box, however its polygons are written, is accepted
        assert outcome == "ok", (seed, outcome)


# ------------------------------------------------------ random networks
@pytest.fixture(scope="module")
def solids():
    Vb, Fb = icosphere(2)
    Vc, Fc = box(n=3)
    return {"ball": (Vb, Fb, None), "cube": (Vc, Fc, 30.0)}


def random_network(rng, sharp_angle, surface=None):
    """Random polylines between random points of [-1.2, 1.2]^3 (some outside,
    some ending on the surface), some sharing a node; random indices, roles,
    torsions and tolerances."""
    kind = rng.random()
    if kind < 0.35:
        return _radial_network(rng, sharp_angle, surface)
    if kind < 0.6:
        return _axis_network(rng, sharp_angle)
    curves = []
    hub = rng.uniform(-0.5, 0.5, 3)
    for k in range(int(rng.integers(0, 6))):
        a = hub if rng.random() < 0.4 else rng.uniform(-1.2, 1.2, 3)
        b = rng.normal(size=3)
        b = b / np.linalg.norm(b) * (1.0 if rng.random() < 0.5 else rng.uniform(0.2, 1.3))
        n = int(rng.integers(2, 9))
        P = np.linspace(a, b, n) + rng.normal(scale=0.02 * rng.random(), size=(n, 3))
        if rng.random() < 0.1:
            P = np.vstack([P, P[:1]])
        role = str(rng.choice(["singular", "feature", "sharp"]))
        sigma = 0.0 if role != "singular" else float(rng.choice([-0.5, -0.25, 0.25, 0.5, 0.75, 0.3]))
        curves.append(Curve(P, sigma, role, str(rng.choice(["free", "fixed"])), name=f"r{k}",
                            closed=bool(rng.random() < 0.05)))
    kw = {}
    if rng.random() < 0.2:
        kw["node_tolerance"] = float(rng.choice([1e-6, 1e-3, 0.05, 0.5]))
    if rng.random() < 0.2:
        kw["boundary_tolerance"] = float(rng.choice([1e-6, 1e-2, 0.1, 0.5]))
    if rng.random() < 0.2:
        kw["sharp_edges"] = rng.integers(0, 40, (int(rng.integers(1, 4)), 2))
    return Network(curves, sharp_angle=sharp_angle if rng.random() < 0.8 else float(rng.uniform(0, 179)), **kw)


SIGMAS = [-0.5, -0.25, 0.0, 0.25, 0.5]


def _sigma_role(rng):
    s = float(rng.choice(SIGMAS))
    return s, ("singular" if s else "feature")


def _radial_network(rng, sharp_angle, surface):
    """2-5 arms from a node at the centre to their closest surface points
    (on the ball along the normal, on the cube mostly not)."""
    k = int(rng.integers(2, 6))
    dirs = rng.normal(size=(k, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    if surface is not None:
        dirs = surface.closest_points(dirs)[2]
    curves = []
    for j, d in enumerate(dirs):
        s, role = _sigma_role(rng)
        curves.append(Curve(np.linspace(np.zeros(3), d, 6), s, role, name=f"arm{j}"))
    return Network(curves, sharp_angle=sharp_angle)


def _axis_network(rng, sharp_angle):
    """Straight curves parallel to an axis through the solid (face to face in
    the cube, perpendicular at both ends), some crossing each other."""
    curves = []
    for j in range(int(rng.integers(1, 5))):
        ax = int(rng.integers(3))
        a = rng.uniform(-0.8, 0.8, 3)
        b = a.copy()
        a[ax], b[ax] = -1.0, 1.0
        s, role = _sigma_role(rng)
        curves.append(Curve(np.linspace(a, b, 7), s, role, name=f"line{j}"))
    return Network(curves, sharp_angle=sharp_angle)


@pytest.mark.parametrize("seed", range(60))
def test_fuzz_random_networks(solids, seed):
    rng = np.random.default_rng(3000 + seed)
    name = "ball" if seed % 2 else "cube"
    V, F, angle = solids[name]
    from solver.surface.trisurface import TriSurface

    net = random_network(rng, angle, TriSurface(V, F))
    run_case(f"random network seed {3000 + seed} in the {name}", lambda: check_input(V, F, net))


# ------------------------------------------- tagged tet meshes (.mesh, .ovm)
@pytest.fixture(scope="module")
def tagged_files(tmp_path_factory):
    """Two valence-3/5 axes through a structured box, as OVM and MEDIT text."""
    from solver.io.medit import write_medit
    from solver.io.ovm import write_ovm
    from tests.meshes import box_mesh

    d = tmp_path_factory.mktemp("tagged")
    mesh = box_mesh(3)
    tags = np.full(mesh.n_edges, 4, np.int64)
    for x, valence in ((1, 3), (2, 5)):
        ids = np.array([int(np.argmin(np.linalg.norm(mesh.vertices - np.array([x, 1.5, z]) / 3, axis=1)))
                        for z in range(4)])
        tags[mesh.edge_index(ids[:-1], ids[1:])] = valence
    write_ovm(str(d / "t.ovm"), mesh, edge_props={"valence": tags})
    on = np.nonzero(tags != 4)[0]
    write_medit(str(d / "t.mesh"), mesh.vertices, mesh.tets, edges=mesh.edges[on], edge_refs=tags[on])
    return d, (d / "t.ovm").read_text(), (d / "t.mesh").read_text()


TAG_WORDS = ["0", "-1", "1.5", "2**70", "1180591620717411303424", "1e30", "nan", "x", "-7", "9", "99999999", "",
             "3.0", "End"]


def mutate_tet_text(rng, text):
    """Truncate, drop or repeat lines, change a count, an index or a tag."""
    lines = text.splitlines()
    for _ in range(int(rng.integers(1, 4))):
        i = int(rng.integers(len(lines)))
        parts = lines[i].split()
        r = rng.random()
        if r < 0.12:
            lines = lines[:i]  # truncated
        elif r < 0.22:
            del lines[i]
        elif r < 0.3:
            lines.insert(i, lines[i])  # a repeated entry (tet, edge, vertex)
        elif r < 0.45 and len(parts) == 1 and parts[0].lstrip("-").isdigit():  # a count
            lines[i] = str(int(parts[0]) + int(rng.choice([-2, -1, 1, 5, 10**6])))
        elif r < 0.8 and parts and parts[0][:1].isdigit() or parts[:1] and parts[0][:1] == "-":
            j = int(rng.integers(len(parts)))
            parts[j] = str(rng.choice(TAG_WORDS)) if rng.random() < 0.6 else str(int(rng.integers(-3, 80)))
            lines[i] = " ".join(parts)
        elif r < 0.9:
            lines.insert(i, str(rng.choice(["Tetrahedra", "Edges", "Vertices", "Dimension 2", "Triangles", "End",
                                            "bogus", "EProp int \"t\"", "# comment"])))
        else:
            lines[i] = lines[i][: int(rng.integers(len(lines[i]) + 1))]
    return "\n".join(lines) + ("\n" if rng.random() < 0.8 else "")


@pytest.mark.parametrize("seed", range(70))
def test_fuzz_tagged_tet_mesh(tagged_files, seed):
    from solver.io.tetnetwork import import_tet_network

    rng = np.random.default_rng(5000 + seed)
    folder, ovm, medit = tagged_files
    ext, text = (".ovm", ovm) if seed % 2 else (".mesh", medit)
    path = folder / f"m{seed}{ext}"
    if rng.random() < 0.05:
        path.write_bytes(bytes(rng.integers(0, 256, 300, dtype=np.uint8)))
    elif rng.random() < 0.05:
        path = folder / f"missing{seed}{ext}"
    else:
        path.write_text(mutate_tet_text(rng, text))
    convention = [None, "index", "negated", "valence", 1, -1, 7, "bogus"][int(rng.integers(8))]
    label = f"tagged tet mesh seed {5000 + seed} ({convention!r}): " + (
        repr(path.read_bytes()[:300]) if path.exists() else "missing file")
    run_case(label, lambda: import_tet_network(str(path), convention, sharp_angle=30))


def test_fuzz_tagged_tet_mesh_refusals_name_the_line(tagged_files, tmp_path):
    """The silent misreadings of issue 43: 0-based MEDIT indices, a fractional
    or huge tag, a repeated tet, a truncated section; each refused naming
    the file and the line."""
    from solver import NetworkError
    from solver.io.tetnetwork import import_tet_network

    _, ovm, medit = tagged_files
    lines = medit.splitlines()
    t = lines.index("Tetrahedra") + 2
    e = lines.index("Edges") + 2

    def refused(text, match, ext=".mesh"):
        path = tmp_path / f"x{ext}"
        path.write_text(text)
        with pytest.raises(NetworkError, match=match):
            import_tet_network(str(path))

    zero = lines.copy()
    zero[t] = " ".join(["0"] + zero[t].split()[1:])
    refused("\n".join(zero), rf"x\.mesh:{t + 1}: Tetrahedra entry 1 refers to vertex 0.*0-based")
    frac = lines.copy()
    frac[e] = " ".join(frac[e].split()[:2] + ["1.5"])
    refused("\n".join(frac), rf"x\.mesh:{e + 1}: 1\.5 in the Edges section: must be a whole number")
    big = lines.copy()
    big[e] = " ".join(big[e].split()[:2] + [str(2**70)])
    refused("\n".join(big), rf"x\.mesh:{e + 1}: .*out of range")
    rep = lines[:t + 1] + lines[t:]
    rep[t - 1] = str(int(rep[t - 1]) + 1)
    refused("\n".join(rep), rf"x\.mesh:{t + 2}: tet 1 .* repeats tet 0 \(.*x\.mesh:{t + 1}\)")
    refused("\n".join(lines[:t + 3]), r"x\.mesh:\d+: .*(truncated|ends inside)")
    refused(ovm.replace("\nEProp", "\nEProp")[: len(ovm) // 2], r"x\.ovm:\d+: ", ".ovm")


# ------------------------------------------------------ the API's arguments
API_VALUES = [None, 0, 1.5, "abc", [], {}, {"edge_length": 0.5}, [[0, 0, 0]], np.zeros((4, 3), complex),
              np.full((4, 3), np.nan), np.zeros((0, 3)), np.zeros((5, 2)), object(), 10**400]


@pytest.fixture
def stop_before_meshing(monkeypatch):
    """Arguments that get as far as meshing are accepted: stop there."""
    import solver.pipeline

    class Reached(Exception):
        pass

    def stop(*a, **k):
        raise Reached

    monkeypatch.setattr(solver.pipeline, "mesh_domain", stop)
    return Reached


@pytest.mark.parametrize("seed", range(40))
def test_fuzz_api_arguments(seed, stop_before_meshing):
    """solve, FieldProblem and check with wrong types in each place: the
    same SymFramesError classes as the command line, options given as a
    dict or another type included."""
    from solver import FieldProblem, Options, check, solve

    rng = np.random.default_rng(6000 + seed)
    V, F, net = _small_cylinder()
    args = [V, F, net]
    for k in rng.choice(3, int(rng.integers(1, 3)), replace=False):
        args[k] = API_VALUES[int(rng.integers(len(API_VALUES)))]
    if rng.random() < 0.3 and len(net.curves):
        c = net.curves[0]
        field_, value = [("sigma", "x"), ("points", None), ("role", 3), ("closed", "yes"), ("sigma", 10**400),
                         ("points", np.ones((3, 3), complex))][int(rng.integers(6))]
        try:
            setattr(c, field_, value)
            pytest.fail(f"curve field {field_} = {value!r} accepted after construction")
        except SymFramesError:
            pass
    opt = API_VALUES[int(rng.integers(len(API_VALUES)))] if rng.random() < 0.5 else None
    if rng.random() < 0.3:
        opt = {"edge_length": 0.3}  # options as a dict, as read from a JSON file
    fn = [lambda: solve(*args), lambda: FieldProblem(*args), lambda: check(*args, options=opt),
          lambda: solve(*args, edge_length=opt), lambda: Options(edge_length=opt, target_tets=opt),
          lambda: solve(*args, options=opt), lambda: FieldProblem(*args, options=opt)][seed % 7]
    try:
        run_case(f"API seed {6000 + seed}: {[type(a).__name__ for a in args]}, {opt!r}"[:300], fn)
    except stop_before_meshing:
        pass


# ------------------------------------------------ dense curves, edge lengths
@pytest.mark.slow
@pytest.mark.parametrize("n", [10_000, 30_000, 100_000])
def test_fuzz_dense_curve(n):
    """One curve of 1e4-1e5 points (a Blender curve at a high resolution),
    wiggling and noisy: checked in near-linear time and memory (issue 43)."""
    rng = np.random.default_rng(n)
    V, F, net = _small_cylinder()
    z = np.linspace(-1.0, 1.0, n)
    P = np.c_[-0.35 + 0.03 * np.sin(float(rng.uniform(5, 40)) * z), np.full(n, -0.35), z]
    P[1:-1] += rng.normal(scale=1e-5, size=(n - 2, 3))
    curves = [Curve(P, 0.25, name="dense")] + net.curves[1:]
    run_case(f"dense curve of {n} points", lambda: check_input(V, F, Network(curves, sharp_angle=30)))


@pytest.mark.parametrize("factor", [1e-3, 1e-2, 0.1, 0.3, 0.4, 1.0, 3.0, 10.0, 1e3])
def test_fuzz_edge_length_against_the_solid(factor):
    """Edge lengths from 1e-3 to 1e3 times the solid's size: a plan or a
    refusal before meshing (too fine: the tet budget; too coarse: fewer than
    2 edges across), never a mesher run away."""
    from solver import Options, check

    V, F, net = _small_cylinder()
    outcome = run_case(f"edge length {factor} x 2", lambda: check(V, F, net, options=Options(edge_length=2 * factor)))
    # ResolutionError: a MeshingError, the tet budget's
    expected = {1e-3: "ResolutionError", 1e-2: "ResolutionError", 1.0: "OptionsError", 3.0: "OptionsError",
                10.0: "OptionsError", 1e3: "OptionsError"}.get(factor, "ok")
    assert outcome == expected, (factor, outcome)


def test_fuzz_covers_enough_cases():
    """The issue's bar: >= 200 cases."""
    mod = sys.modules[__name__]
    n = sum(len(getattr(mod, f).pytestmark[0].args[1]) for f in dir(mod)
            if f.startswith("test_fuzz_") and hasattr(getattr(mod, f), "pytestmark"))
    assert n >= 200, n


# ------------------------------------------------ a handful of tiny solves
@pytest.mark.parametrize("seed", range(8))
def test_fuzz_tiny_solves(seed):
    """Random valid options through the whole solve, on a structured tet mesh
    of the cube (no fTetWild): valid input, so every seed solves (converged
    or not), no error at all, and rotations out."""
    from solver import FieldProblem, Options
    from tests.meshes import box_mesh

    rng = np.random.default_rng(4000 + seed)
    V, F = box(n=2)
    opts = Options(edge_length=0.7, penalty=float(10 ** rng.uniform(-3, 6)), max_iterations=int(rng.integers(1, 5)),
                   tolerance=float(rng.choice([0.0, 1e-12, 1e-3])), init=str(rng.choice(["zero", "constant", "random",
                                                                                          "linear"])),
                   seed=int(rng.integers(0, 2**31)), node_radius=float(rng.uniform(0.5, 3.0)))
    mesh = box_mesh(int(rng.integers(2, 4)), lo=(-1, -1, -1), hi=(1, 1, 1), jitter=float(rng.uniform(0, 0.3)),
                    seed=seed)
    out = {}

    def go():
        p = FieldProblem(V, F, Network(sharp_angle=30), opts, mesh=mesh)
        root = None if rng.random() < 0.5 else int(rng.integers(0, p.mesh.n_vertices))
        out["r"] = p.solve(root=root)

    outcome = run_case(f"tiny solve seed {4000 + seed}: {opts}", go, seconds=2 * CASE_SECONDS)
    assert outcome == "ok", (seed, outcome)
    E = out["r"].frames
    assert E.shape == (out["r"].mesh.n_vertices, 3, 3)
    assert np.all(np.isfinite(E))
    assert np.allclose(np.einsum("vji,vjk->vik", E, E), np.eye(3), atol=1e-6)


# ------------------------------------------------ hex names, stored results, interchange readers (issue 52)


@pytest.fixture
def stop_before_hex_stages(monkeypatch):
    """Arguments that get as far as the hex stages are accepted: stop there."""
    from solver.hexmesh import mesher

    class Reached(BaseException):  # past run_case's net: a pass, not a failure
        pass

    def stop(*a, **k):
        raise Reached

    monkeypatch.setattr(mesher, "_mesh_at", stop)
    return Reached


HEX_VALUES = WEIRD + ["result.npz", np.zeros((3, 3)), object()]


def _hex_call(rng, seed, path, arrays, res, tmp):
    """One call of a public hex name with some arguments replaced."""
    from solver import SolvedField, default_cell_size, hex_source_arrays, hexmesh
    from solver.hexmesh import field_on_edges

    def pick(good, p=0.5):
        return HEX_VALUES[int(rng.integers(len(HEX_VALUES)))] if rng.random() < p else good

    inp = res.field
    hex_arrays = {k: v for k, v in arrays.items() if k != "report"}
    if rng.random() < 0.5:
        k = str(rng.choice(sorted(hex_arrays)))
        if rng.random() < 0.5:
            del hex_arrays[k]
        else:
            hex_arrays[k] = pick(None, 1.0)
    if rng.random() < 0.3:  # a SolvedField made by hand, one field wrong: refused as it is made
        import dataclasses

        name = str(rng.choice([f.name for f in dataclasses.fields(SolvedField)]))
        return lambda: dataclasses.replace(inp, **{name: pick(None, 1.0)})
    k = seed % 8
    if k == 0:
        return lambda: hexmesh(pick(inp, 0.4), pick(None), smooth=pick(True, 0.2), target_hexes=pick(3000, 0.3),
                               progress=pick(None, 0.2), allow_unconverged=pick(False, 0.2))
    if k == 1:
        return lambda: default_cell_size(pick(inp), pick(3000))
    if k == 2:
        return lambda: SolvedField.from_arrays(pick(hex_arrays, 0.2))
    if k == 3:
        return lambda: hex_source_arrays(pick(inp, 0.8))
    if k == 4:
        return lambda: io.export_hexmesh(pick(None, 1.0), pick(str(tmp / "h.vtu"), 0.5))
    if k == 5:
        return lambda: SolvedField.from_result(pick(res, 0.8))
    if k == 6:
        return lambda: field_on_edges(pick(inp, 0.8))
    return lambda: io.load_field(pick(path, 0.8))


@pytest.mark.slow
@pytest.mark.mesher
@pytest.mark.parametrize("seed", range(64))
def test_fuzz_hex_api(stored_field, stop_before_hex_stages, tmp_path, seed):
    """The public hex names with wrong types in each place: SymFrames errors
    only (hexmesh("result.npz"), hexmesh(None), target_hexes=0,
    SolvedField.from_arrays({}), export_hexmesh(None, ...))."""
    path, arrays, res = stored_field
    rng = np.random.default_rng(9000 + seed)
    fn = _hex_call(rng, seed, path, arrays, res, tmp_path)
    try:
        run_case(f"hex API seed {9000 + seed}", fn)
    except stop_before_hex_stages:
        pass


def _mutate_arrays(rng, arrays):
    a = dict(arrays)
    for _ in range(int(rng.integers(1, 3))):
        k = str(rng.choice(sorted(a)))
        v = np.asarray(a[k])
        r = rng.random()
        if r < 0.15:
            del a[k]
        elif r < 0.3 and v.size and v.dtype.kind != "U":
            w = v.astype(float).copy()
            w.flat[int(rng.integers(v.size))] = rng.choice([np.nan, np.inf, -1, 1e9, 0.5])
            a[k] = w
        elif r < 0.45 and v.ndim:
            a[k] = v[: int(rng.integers(len(v) + 1))]
        elif r < 0.55 and v.dtype.kind in "fi":
            a[k] = v * rng.choice([0, -1, 2, 1e-3])
        elif r < 0.65 and v.dtype.kind in "fiu" and v.size:
            a[k] = v + rng.choice([1, -1, 10**6])
        elif r < 0.75 and v.dtype.kind != "U":
            a[k] = v.astype(rng.choice(["float32", "int32", "U8", "bool", "complex128"]))
        elif r < 0.85 and v.ndim == 2:
            a[k] = v.T
        else:
            a[k] = np.asarray(weird(rng)) if not isinstance(weird(rng), dict) else np.zeros(0)
    return a


@pytest.mark.slow
@pytest.mark.mesher
@pytest.mark.parametrize("seed", range(64))
def test_fuzz_result_file(stored_field, tmp_path, seed):
    """Damaged result files (arrays dropped, cut, scaled, shifted, retyped;
    the file's bytes cut or overwritten): read back, or a ReadError naming
    the file, never a traceback."""
    path, arrays, _ = stored_field
    rng = np.random.default_rng(9500 + seed)
    p = tmp_path / "r.npz"
    if seed % 4 == 3:
        raw = bytearray(open(path, "rb").read())
        if rng.random() < 0.5:
            raw = raw[: int(rng.integers(len(raw)))]
        else:
            i = int(rng.integers(len(raw) - 64))
            raw[i:i + int(rng.integers(1, 64))] = rng.bytes(64)[: len(raw[i:i + 64])][: 64]
        p.write_bytes(bytes(raw))
    else:
        np.savez(p, **_mutate_arrays(rng, arrays))
    outcome = run_case(f"result file seed {9500 + seed}", lambda: io.load_field(str(p)))
    assert outcome in ("ok", "ReadError"), outcome


@pytest.fixture(scope="module")
def interchange_texts():
    """Valid .hexex, .fra, .perm and .qtn texts of a small field."""
    from solver.io.cubecover import fra_text, perm_text
    from tests.meshes import box_mesh

    rng = np.random.default_rng(1)
    mesh = box_mesh(2)
    U = rng.normal(size=(mesh.n_tets, 4, 3))
    hexex = f"{mesh.n_vertices}\n" + "\n".join(" ".join(f"{x:.17g}" for x in r) for r in mesh.vertices) + \
        f"\n{mesh.n_tets}\n" + "\n".join(" ".join(str(x) for x in t) + " " + " ".join(f"{u:.6g}" for u in p.ravel())
                                         for t, p in zip(mesh.tets, U)) + "\n"
    R = np.linalg.qr(rng.normal(size=(mesh.n_tets, 3, 3)))[0]
    pairs = mesh.face_tets[~mesh.is_boundary_face][:20]
    perms = np.tile([1, 2, 3], (len(pairs), 1)) * rng.choice([-1, 1], size=(len(pairs), 3))
    q = rng.normal(size=(mesh.n_tets, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return {".hexex": hexex, ".fra": fra_text(R), ".perm": perm_text(mesh.n_tets, pairs, perms, keep_identity=True),
            ".qtn": "\n".join(" ".join(f"{x:.17g}" for x in r) for r in q) + "\n"}


@pytest.mark.parametrize("seed", range(64))
def test_fuzz_interchange_readers(interchange_texts, tmp_path, seed):
    """Mutated .hexex / .fra / .perm / .qtn files: read, or a ReadError naming
    the file (and the line), never a plain ValueError or a traceback."""
    from solver.io.cubecover import read_fra, read_perm
    from solver.io.qtn import read_qtn

    ext = [".hexex", ".fra", ".perm", ".qtn"][seed % 4]
    rng = np.random.default_rng(9800 + seed)
    p = tmp_path / f"f{ext}"
    p.write_text(mutate_tet_text(rng, interchange_texts[ext]))
    fn = {".hexex": io.read_hexex, ".fra": read_fra, ".perm": read_perm, ".qtn": read_qtn}[ext]
    outcome = run_case(f"{ext} seed {9800 + seed}", lambda: fn(str(p)))
    assert outcome in ("ok", "ReadError"), outcome


def test_fuzz_interchange_readers_read_their_own_files(interchange_texts, tmp_path):
    """Not vacuous: the unmutated files read back."""
    from solver.io.cubecover import read_fra, read_perm
    from solver.io.qtn import read_qtn

    for ext, fn in {".hexex": io.read_hexex, ".fra": read_fra, ".perm": read_perm, ".qtn": read_qtn}.items():
        p = tmp_path / f"f{ext}"
        p.write_text(interchange_texts[ext])
        fn(str(p))


def _public_names():
    import inspect

    import solver
    import solver.io

    out = []
    for mod in (solver, solver.io):
        for name in mod.__all__:
            f = getattr(mod, name)
            if callable(f) and name not in ("Role", "Torsion") and not (
                    inspect.isclass(f) and issubclass(f, BaseException)):
                out.append(f"{mod.__name__}.{name}")
    return out


@pytest.mark.slow
@pytest.mark.mesher
@pytest.mark.parametrize("name", _public_names())
def test_fuzz_every_public_name(name, stored_field, stop_before_meshing, stop_before_hex_stages, tmp_path,
                                monkeypatch):
    """Every public callable of solver and solver.io, called with wrong values
    in each place (an int where a path goes would open a file descriptor;
    None, strings, NaN, dicts, arrays of the wrong shape): SymFrames errors
    only, 12 calls each."""
    import importlib
    import inspect

    module, _, attr = name.rpartition(".")
    f = getattr(importlib.import_module(module), attr)
    monkeypatch.chdir(tmp_path)
    values = HEX_VALUES + [0, 1, stored_field[0], np.zeros((4, 3)), np.zeros(0)]
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    for _ in range(12):
        args = [values[int(rng.integers(len(values)))] for _ in range(int(rng.integers(0, 5)))]
        try:
            inspect.signature(f).bind(*args)
        except TypeError:
            continue  # a call Python itself refuses (arity)
        except ValueError:
            pass  # no signature to check against
        try:
            run_case(f"{name}{tuple(type(a).__name__ for a in args)}", lambda: f(*args))
        except (stop_before_meshing, stop_before_hex_stages):
            pass


@pytest.mark.slow
@pytest.mark.mesher
@pytest.mark.parametrize("method", ["develop", "curve_tets", "curve_faces", "curve_vertices"])
def test_fuzz_result_methods(stored_field, method):
    """A Result's methods with wrong indices (issue 52: Result.develop):
    SymFrames errors only; a valid index still works."""
    res = stored_field[2]
    f = getattr(res, method)
    for v in HEX_VALUES + [res.mesh.n_vertices, 10**30, -5, len(res.embedding.traces), np.int64(1)]:
        run_case(f"Result.{method}({v!r:.40})", lambda: f(v))
    assert len(f(0))
