"""fTetWild, the tet mesher (§5.1; design notes §3): the solid bounded by a
triangle surface, with internal constraint triangles (the curve tubes of
tubes.py), as a TetMesh.

fTetWild runs in a child process (cancellable, and a crash cannot take the
host application down); its unfiltered output is filtered here by the
winding number of the domain surface alone, and flat tets left by its final
rounding are repaired (slivers.py).
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import MeshingError
from ..surface.trisurface import TriSurface
from .slivers import repair_flat_tets
from .tetmesh import TetMesh


def tetrahedralize(
    surface: TriSurface,
    edge_length: float,
    internal: tuple[np.ndarray, np.ndarray] | None = None,
    epsilon: float = 1e-3,
    cancel=None,
) -> TetMesh:
    """Tetrahedralise the solid bounded by ``surface`` with fTetWild (§5.1).

    edge_length : target edge length in the units of the surface.
    internal    : optional (V, F) triangles to embed inside the solid (the
                  curve tubes of tubes.py); they never decide inside/outside.
    epsilon     : envelope size relative to the bounding-box diagonal.

    fTetWild's own inside/outside filter uses the winding number of all input
    triangles, so crossing internal surfaces can carve spurious cavities.  We
    ask for the unfiltered mesh instead and keep the connected regions (cut
    along faces lying on the domain surface) whose winding number with
    respect to the domain surface alone is one.
    """
    t0 = time.perf_counter()
    V, F = surface.V, surface.F
    if internal is not None and len(internal[1]):
        Vi, Fi = internal
        V = np.vstack([V, Vi])
        F = np.vstack([F, Fi + len(surface.V)])
    P, T = run_tetwild(V, F, edge_length, epsilon, cancel=cancel)
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
    if flat["moved_vertices"]:
        mesh = TetMesh(P, T)
    mesh.info["flat_tets"] = flat
    mesh.info["tetwild_seconds"] = time.perf_counter() - t0
    return mesh


# fTetWild's optimisation passes (its default is 80).  Where a mesh reaches
# fTetWild's quality target it does so within a few passes; where it does not
# (inputs with curve tubes, the smooth torus) every further pass refined
# more: the ball at h = 0.1076 gave 63k-141k tets in 125-267 s with 80
# passes against 35k in 21 s with 10 (same LM iterations, minimum dihedral
# angles no worse), the torus at h = 0.1 33k tets in 141 s against 31k in 21 s.
TETWILD_PASSES = 10

# The fTetWild bindings the worker runs: pytetwild (wheels for Linux x64 and
# Windows x64; from 0.4.2 also Linux arm64) or, where it has no wheel,
# wildmeshing (macOS arm64 and x64).
# Both are fTetWild and get the same parameters; SYMFRAMES_MESHER=pytetwild
# or =wildmeshing forces one (tests run both).
MESHERS = ("pytetwild", "wildmeshing")

_TETWILD_WORKER = r"""
import os, sys, numpy as np
z = np.load(sys.argv[1])
V, F = z["V"], z["F"].astype(np.int32)
h, eps, passes = float(z["h"]), float(z["eps"]), int(z["passes"])
forced = os.environ.get("SYMFRAMES_MESHER", "")
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
    # the same fTetWild run: relative edge length, envelope, passes, no
    # coarsening, and all tets kept (all_mesh: the unfiltered background mesh)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    t = wildmeshing.Tetrahedralizer(stop_quality=10.0, max_its=passes, epsilon=eps, edge_length_r=h / diag,
                                    coarsen=False)
    t.set_log_level(6)
    t.set_mesh(V, F)
    t.tetrahedralize()
    P, T = t.get_tet_mesh(all_mesh=True)[:2]
else:
    P, T = pytetwild.tetrahedralize(V, F, edge_length_abs=h, epsilon=eps, optimize=True, disable_filtering=True,
                                    quiet=True, num_opt_iter=passes)
np.savez(sys.argv[2], P=np.asarray(P), T=np.asarray(T))
"""


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


def run_tetwild(V, F, edge_length, epsilon, cancel=None):
    """fTetWild's unfiltered tet mesh of the triangle soup (V, F).

    Runs in a child process whose working directory is a temporary folder:
    fTetWild writes a debug file (_tracked_surface.stl) into the current
    directory, and a child can be stopped when the caller cancels and cannot
    take the host application (Blender) down if the mesher crashes.
    """
    import os
    import subprocess
    import sys
    import tempfile

    from ..errors import Cancelled

    with tempfile.TemporaryDirectory(prefix="symframes_tetwild_") as tmp:
        src = os.path.join(tmp, "in.npz")
        dst = os.path.join(tmp, "out.npz")
        np.savez(src, V=np.asarray(V, np.float64), F=np.asarray(F, np.int64), h=float(edge_length),
                 eps=float(epsilon), passes=TETWILD_PASSES)
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)
        proc = subprocess.Popen([sys.executable, "-c", _TETWILD_WORKER, src, dst], cwd=tmp, env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        while True:
            try:
                _, err = proc.communicate(timeout=0.2)
                break
            except subprocess.TimeoutExpired:
                if cancel is not None and cancel():
                    proc.kill()
                    proc.communicate()
                    raise Cancelled() from None
        if proc.returncode != 0 or not os.path.exists(dst):
            msg = err.decode(errors="replace").strip().splitlines()[-3:] if err else []
            raise MeshingError(f"fTetWild failed (exit code {proc.returncode}): {' | '.join(msg)}")
        z = np.load(dst)
        return z["P"], z["T"]


def _inside_tets(mesh: TetMesh, surface: TriSurface, eps: float) -> np.ndarray:
    """Tets inside the closed surface: flood regions bounded by mesh faces
    that lie on the surface, then classify each region by the winding number
    of a few of its largest tets' centroids."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    d, _, _ = surface.closest_points(mesh.vertices)
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
