"""fTetWild, the tet mesher (§5.1; docs/how-it-works.md, *Tubes and tet mesh*): the solid bounded by a
triangle surface, with internal constraint triangles (the curve tubes of
tubes.py), as a TetMesh.

fTetWild runs in a child process (cancellable, and a crash cannot take the
host application down); its unfiltered output is filtered here by the
winding number of the domain surface alone, and flat tets left by its final
rounding are repaired (slivers.py).
"""

from __future__ import annotations

import numpy as np

from ..errors import MeshingError
from ..surface.trisurface import TriSurface
from .slivers import FlatRepair, repair_flat_tets
from .tetmesh import TetMesh


def tetrahedralize(*args, **kw) -> TetMesh:
    """The tet mesh of ``tetrahedralize_repaired`` (same parameters), without
    the account of its flat-tet repair."""
    return tetrahedralize_repaired(*args, **kw)[0]


def tetrahedralize_repaired(
    surface: TriSurface,
    edge_length: float,
    internal: tuple[np.ndarray, np.ndarray] | None = None,
    epsilon: float = 1e-3,
    cancel=None,
    sharp: bool = False,
) -> tuple[TetMesh, FlatRepair]:
    """Tetrahedralise the solid bounded by ``surface`` with fTetWild (§5.1),
    and repair the flat tets its rounding left (slivers.py).

    edge_length : target edge length in the units of the surface.
    internal    : optional (V, F) triangles to embed inside the solid (the
                  curve tubes of tubes.py); they never decide inside/outside.
    epsilon     : envelope size relative to the bounding-box diagonal.
    sharp       : the surface has sharp features (see wants_simplify).

    Returns (the TetMesh, the slivers.FlatRepair of its flat tets).

    fTetWild's own inside/outside filter uses the winding number of all input
    triangles, so crossing internal surfaces can carve spurious cavities.  We
    ask for the unfiltered mesh instead and keep the connected regions (cut
    along faces lying on the domain surface) whose winding number with
    respect to the domain surface alone is one.
    """
    V, F = surface.V, surface.F
    if internal is not None and len(internal[1]):
        Vi, Fi = internal
        V = np.vstack([V, Vi])
        F = np.vstack([F, Fi + len(surface.V)])
    # fTetWild works in the model's units with absolute tolerances: the
    # cylinder scaled by 1e-6 came back with no tet inside the surface.  It
    # meshes the model centred and scaled to a unit bounding-box diagonal
    # instead, so the result does not depend on the units.
    centre, unit = _normalisation(surface)
    P, T = run_tetwild((V - centre) / unit, F, edge_length / unit, epsilon, cancel=cancel,
                       simplify=wants_simplify(sharp))
    P = np.asarray(P, float) * unit + centre
    if len(T) == 0:
        raise MeshingError("fTetWild produced no tetrahedra; check that the surface encloses a volume")
    full = TetMesh(np.asarray(P), np.asarray(T))
    keep = _inside_tets(full, surface, epsilon * surface.bbox_diagonal)
    if not np.any(keep):
        raise MeshingError(
            "no tetrahedra lie inside the surface; check that it is closed and its normals point outward"
        )
    used, Tn = np.unique(full.tets[keep], return_inverse=True)
    mesh = TetMesh(full.vertices[used], Tn.reshape(-1, 4))
    # tets that fTetWild's rounding left flat: moved off their plane
    P, T, flat = repair_flat_tets(mesh.vertices, mesh.tets, mesh.is_boundary_vertex, mesh.face_tets,
                                  mesh.tet_faces)
    if flat.moved_vertices:
        mesh = TetMesh(P, T)
    return mesh, flat


def _normalisation(surface: TriSurface) -> tuple[np.ndarray, float]:
    """Centre and size (bounding-box diagonal) of the surface's vertices."""
    used = surface.V[np.unique(surface.F)]
    lo, hi = used.min(axis=0), used.max(axis=0)
    return 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))


# fTetWild's optimisation passes (its default is 80).  Where a mesh reaches
# fTetWild's quality target it does so within a few passes; where it does not
# (inputs with curve tubes, the smooth torus) every further pass refined
# more (docs/performance.md, *fTetWild's optimisation passes*).
TETWILD_PASSES = 10

# fTetWild first simplifies its input inside the envelope.  A smooth surface
# needs it: the smooth torus meshed unsimplified left LM at its cap on 2 of 3
# meshes, and the ball's 1,280 triangles at h = 0.27 made 17 % more tets.  A
# surface with sharp features (CAD parts, where meshing dominates) does not:
# unsimplified, fTetWild meshed the cylinder example and six sharp hex-mesh
# boundaries 1.4-4.5x faster, with between 18 % fewer and 20 % more tets, and
# every solve converged, also where the surface had up to 14x the triangles of
# an h-mesh (bench/bench_simplify.py; docs/performance.md, *Meshing*: fTetWild's
# input simplification).  A surface far denser than its mesh is clustered
# first (decimate.py).
def wants_simplify(sharp: bool) -> bool:
    """Whether fTetWild simplifies its input before meshing: only where the
    surface has no sharp features (the comment above)."""
    return not sharp


# The fTetWild bindings the worker runs: pytetwild (wheels for Linux x64 and
# Windows x64; from 0.4.2 also Linux arm64) or, where it has no wheel,
# wildmeshing (macOS arm64 and x64).
# Both are fTetWild and get the same parameters; SYMFRAMES_MESHER=pytetwild
# or =wildmeshing forces one (tests run both).
MESHERS = ("pytetwild", "wildmeshing")

_TETWILD_WORKER = r"""
import os, sys
parent = int(sys.argv[3])
if sys.platform.startswith("linux"):
    # die with the parent, even when it is SIGKILLed (Blender killed)
    import ctypes, signal
    ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL))  # PR_SET_PDEATHSIG
if os.getppid() != parent:
    sys.exit(3)  # the parent died before prctl took effect
if not sys.platform.startswith("linux"):
    import threading, time
    def watch():
        while True:
            time.sleep(1.0)
            try:
                os.kill(parent, 0)
            except OSError:
                os._exit(3)
    threading.Thread(target=watch, daemon=True).start()
import numpy as np
z = np.load(sys.argv[1])
V, F = z["V"], z["F"].astype(np.int32)
h, eps, passes, simplify = float(z["h"]), float(z["eps"]), int(z["passes"]), bool(z["simplify"])
threads = int(z["threads"]) if "threads" in z.files else 0  # 0: every core
forced = os.environ.get("SYMFRAMES_MESHER", "")
if "tetgen_volume" in z.files:
    # TetGen (cdt.py): a constrained Delaunay mesh of the closed surface,
    # quality-refined (radius-edge 1.5) under a volume bound; interior only
    import tetgen
    out = tetgen.TetGen(V, F).tetrahedralize(switches="pq1.5a%.17gQ" % float(z["tetgen_volume"]))
    np.savez(sys.argv[2], P=np.asarray(out[0]), T=np.asarray(out[1]))
    sys.exit(0)
try:
    if forced == "wildmeshing":
        raise ImportError("SYMFRAMES_MESHER=wildmeshing")
    import importlib.util, types
    if importlib.util.find_spec("pyvista") is None:
        # pytetwild >= 0.3 (0.4.2: the linux-arm64 wheels) imports pyvista at
        # package import, only to register an accessor that it skips when
        # pyvista lacks register_dataset_accessor: an empty stand-in will do
        sys.modules["pyvista"] = types.ModuleType("pyvista")
    import pytetwild
except ImportError:
    if forced == "pytetwild":
        raise
    import wildmeshing
    # the same fTetWild run: relative edge length, envelope, passes,
    # simplification, threads, no coarsening, and all tets kept (all_mesh:
    # the unfiltered background mesh)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    t = wildmeshing.Tetrahedralizer(stop_quality=10.0, max_its=passes, epsilon=eps, edge_length_r=h / diag,
                                    coarsen=False, skip_simplify=not simplify, max_threads=threads)
    t.set_log_level(6)
    t.set_mesh(V, F)
    t.tetrahedralize()
    P, T = t.get_tet_mesh(all_mesh=True)[:2]
else:
    kw = dict(edge_length_abs=h, epsilon=eps, optimize=True, disable_filtering=True, quiet=True,
              num_opt_iter=passes, num_threads=threads)
    try:
        P, T = pytetwild.tetrahedralize(V, F, simplify=simplify, **kw)
    except TypeError:  # a pytetwild without the simplify or threads switches
        kw.pop("num_threads")
        P, T = pytetwild.tetrahedralize(V, F, **kw)
np.savez(sys.argv[2], P=np.asarray(P), T=np.asarray(T))
"""

TEMP_PREFIX = "symframes_tetwild_"
_OWNER_FILE = "owner"
_LIVE_CHILDREN: set = set()  # fTetWild processes running now, killed at exit


def _process_start(pid: int) -> str | None:
    """The start time of a process (Linux /proc), to tell a reused pid from
    the owner; None where unknown."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return None


def _pid_alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process
    except OSError:
        return True  # unknown (Windows): keep the folder
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"  # a zombie is dead
    except (OSError, IndexError):
        return True


def remove_stale_folders(folder: str | None = None) -> list[str]:
    """Remove the temporary folders of fTetWild runs whose owner process is
    dead (killed before it could clean up: SIGKILL, a crash, Blender killed).

    Only folders named TEMP_PREFIX + '<pid>_...' that hold our owner file,
    belong to this user and whose pid is not running (or now belongs to a
    process started at another time) are removed.  Returns their paths.
    """
    import os
    import shutil
    import tempfile

    folder = folder or tempfile.gettempdir()
    removed = []
    try:
        names = [n for n in os.listdir(folder) if n.startswith(TEMP_PREFIX)]
    except OSError:
        return removed
    for name in names:
        path = os.path.join(folder, name)
        try:
            st = os.lstat(path)
            if not os.path.isdir(path) or os.path.islink(path) or (hasattr(os, "getuid") and st.st_uid != os.getuid()):
                continue
            with open(os.path.join(path, _OWNER_FILE)) as fh:
                pid_text, start = (fh.read().split() + [""])[:2]
            pid = int(pid_text)
        except (OSError, ValueError):
            continue  # not ours, or the owner is still writing it
        if pid == os.getpid():
            continue
        if _pid_alive(pid) and (not start or _process_start(pid) in (None, start)):
            continue
        shutil.rmtree(path, ignore_errors=True)
        if not os.path.exists(path):
            removed.append(path)
    return removed


def _kill_live_children() -> None:
    for proc in list(_LIVE_CHILDREN):
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        _LIVE_CHILDREN.discard(proc)


def mesher_name() -> str:
    """The fTetWild bindings the worker will use here ('pytetwild' or
    'wildmeshing'), honouring SYMFRAMES_MESHER; '' when neither imports."""
    import importlib.util
    import os

    forced = os.environ.get("SYMFRAMES_MESHER", "")
    for name in ([forced] if forced in MESHERS else MESHERS):
        if importlib.util.find_spec(name) is not None:
            return name
    return ""


def _mesher_threads() -> int:
    """fTetWild's threads: SymFrames' own count where one is set
    (SYMFRAMES_THREADS, linalg.parallel.set_threads), else 0 (fTetWild's
    default: every core).  With one thread the child takes 20 % less CPU time
    for 10 % more wall time (the cylinder at h = 0.4: 11.8-12.1 CPU seconds
    against 14.3-15.1, 2 cores), which is what a machine kept busy by other
    work (the test suite's two workers) wants."""
    from ..linalg import parallel

    return parallel.threads() if parallel.threads_set() else 0


def run_tetwild(V, F, edge_length, epsilon, cancel=None, simplify=True, tetgen_volume=None):
    """fTetWild's unfiltered tet mesh of the triangle soup (V, F).

    Runs in a child process whose working directory is a temporary folder:
    fTetWild writes a debug file (_tracked_surface.stl) into the current
    directory, and a child can be stopped when the caller cancels and cannot
    take the host application (Blender) down if the mesher crashes.

    The child never outlives the solve: it is killed when the wait for it
    ends in any way (cancel, an exception such as KeyboardInterrupt or the
    command line's SIGTERM handler, interpreter exit via atexit), and on
    Linux it asks the kernel to kill it when its parent dies (PR_SET_PDEATHSIG),
    so a SIGKILLed parent does not orphan it either.  The folder is named
    after the owner's pid; folders of owners that died without cleaning up
    are removed by the next run (remove_stale_folders).

    tetgen_volume : run TetGen instead, with this bound on the tet volume
                    (cdt.py), in the same kind of child.
    """
    import atexit
    import os
    import subprocess
    import sys
    import tempfile

    from ..errors import Cancelled

    remove_stale_folders()
    if not getattr(run_tetwild, "_atexit", False):
        atexit.register(_kill_live_children)
        run_tetwild._atexit = True
    with tempfile.TemporaryDirectory(prefix=f"{TEMP_PREFIX}{os.getpid()}_") as tmp:
        with open(os.path.join(tmp, _OWNER_FILE), "w") as fh:
            fh.write(f"{os.getpid()} {_process_start(os.getpid()) or ''}\n")
        src = os.path.join(tmp, "in.npz")
        dst = os.path.join(tmp, "out.npz")
        extra = {} if tetgen_volume is None else {"tetgen_volume": float(tetgen_volume)}
        np.savez(src, V=np.asarray(V, np.float64), F=np.asarray(F, np.int64), h=float(edge_length),
                 eps=float(epsilon), passes=TETWILD_PASSES, simplify=bool(simplify), threads=_mesher_threads(),
                 **extra)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
        proc = subprocess.Popen([sys.executable, "-c", _TETWILD_WORKER, src, dst, str(os.getpid())], cwd=tmp,
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _LIVE_CHILDREN.add(proc)
        try:
            while True:
                try:
                    _, err = proc.communicate(timeout=0.2)
                    break
                except subprocess.TimeoutExpired:
                    if cancel is not None and cancel():
                        raise Cancelled() from None
        finally:
            # cancelled, interrupted or terminated: the child goes first, then
            # the folder it works in
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            _LIVE_CHILDREN.discard(proc)
        if proc.returncode != 0 or not os.path.exists(dst):
            msg = err.decode(errors="replace").strip().splitlines()[-3:] if err else []
            who = "TetGen" if tetgen_volume is not None else "fTetWild"
            raise MeshingError(f"{who} failed (exit code {proc.returncode}): {' | '.join(msg)}")
        z = np.load(dst)
        return z["P"], z["T"]


def _inside_tets(mesh: TetMesh, surface: TriSurface, eps: float) -> np.ndarray:
    """Tets inside the closed surface: flood regions bounded by mesh faces
    that lie on the surface, then classify each region by the winding number
    of a few of its largest tets' centroids."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    d, _, _ = surface.closest_points(mesh.vertices, within=4.0 * eps)
    near = d <= 4.0 * eps
    blocking = near[mesh.faces].all(axis=1)
    ft = mesh.face_tets
    link = (ft[:, 1] >= 0) & ~blocking
    n = mesh.n_tets
    A = coo_matrix((np.ones(link.sum()), (ft[link, 0], ft[link, 1])), shape=(n, n))
    ncomp, lab = connected_components(A, directed=False)
    vol = np.abs(mesh.tet_volumes)
    cen = mesh.vertices[mesh.tets].mean(axis=1)
    # up to five largest tets per region
    order = np.lexsort((-vol, lab))
    first = np.r_[0, np.nonzero(np.diff(lab[order]))[0] + 1]
    rank = np.arange(n) - np.repeat(first, np.diff(np.r_[first, n]))
    sample = order[rank < 5]
    w = surface.winding_number(cen[sample])
    inside_votes = np.bincount(lab[sample], weights=(w > 0.5).astype(float), minlength=ncomp)
    total = np.bincount(lab[sample], minlength=ncomp)
    inside = inside_votes > 0.5 * total
    return inside[lab]
