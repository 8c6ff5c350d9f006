"""Offline cross-check of SymFrames' hex ``.ovm`` against OpenVolumeMesh itself.

Builds OpenVolumeMesh (github.com/OpenVolumeMesh/OpenVolumeMesh, LGPL) from a
source tree the user supplies, with a 60-line reader this script writes out
(cmake and a C++17 compiler; a few minutes on one core, once per --build),
and reads hex meshes written by ``write_hex_ovm`` (``export_hexmesh(hm,
X.ovm)``) into OpenVolumeMesh's ``GeometricHexahedralMeshV3d`` with its
topology check, as HexHex, AlgoHex and the OVM tools read them:

    .venv/bin/python bench/crosscheck_ovm.py --ovm-src /path/to/OpenVolumeMesh \\
        [--build /tmp/ovm-build] [--example plate --example ball] [X.ovm ...]

--ovm-src is a checkout or a bare git directory (its HEAD is exported with
``git archive``). With --example NAME the example is solved and hex meshed
at its default settings and written to a temporary .ovm first (tens of
seconds each). Per file, OpenVolumeMesh's counts against SymFrames' (vertices,
edges, faces, cells), then what OpenVolumeMesh makes of the cells:

- kept as written: the cells read with the topology check hold the
  halffaces the file lists, in its order (HexahedralMeshTopologyKernel
  reorders halffaces it finds out of its XF, XB, YF, YB, ZF, ZB order, and
  drops a cell that does not close);
- inward: halffaces whose normal (Newell's, over OpenVolumeMesh's own
  halfface vertex loop) points to the cell's centroid; OpenVolumeMesh's
  convention is into the cell, so all of them;
- same hexes: each cell's eight corners in OpenVolumeMesh's order
  (``hex_vertices``: its figure's 0..7), turned to VTK's (0, 3, 2, 1, 4, 5, 6,
  7), are SymFrames' hexahedron up to its symmetries of orientation (the
  same oriented faces), and their minimum scaled Jacobian is SymFrames';
- properties: the edge property ``valence`` equals the cells OpenVolumeMesh
  finds around each edge, and the face property ``patch`` is non-zero on
  exactly the faces OpenVolumeMesh calls boundary.

Nothing here is downloaded, and no OpenVolumeMesh code is part of
SymFrames. Exit status: 0 when every file agrees, 1 otherwise, 2 on usage
errors.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

READER = r"""
#include <OpenVolumeMesh/FileManager/FileManager.hh>
#include <OpenVolumeMesh/Mesh/HexahedralMesh.hh>
#include <cstdio>
using namespace OpenVolumeMesh;

int main(int argc, char **argv) {
  if (argc != 3) return 2;
  GeometricHexahedralMeshV3d checked, as_is;
  IO::FileManager fm;
  bool ok = fm.readFile(argv[1], checked, true, true);
  bool ok2 = fm.readFile(argv[1], as_is, false, true);
  if (!ok || !ok2) { std::printf("{\"read\": false}\n"); return 1; }
  size_t kept = 0, inward = 0, outward = 0;
  FILE *out = std::fopen(argv[2], "w");
  for (auto ch : checked.cells()) {
    if (ch.idx() < (int)as_is.n_cells() && checked.cell(ch).halffaces() == as_is.cell(ch).halffaces()) ++kept;
    Vec3d c(0, 0, 0);
    for (auto vh : checked.hex_vertices(ch)) { c += checked.vertex(vh); std::fprintf(out, "%d ", vh.idx()); }
    std::fprintf(out, "\n");
    c /= 8.0;
    for (auto hf : checked.cell(ch).halffaces()) {
      std::vector<Vec3d> p;
      for (auto vh : checked.halfface_vertices(hf)) p.push_back(checked.vertex(vh));
      Vec3d n(0, 0, 0), m(0, 0, 0);
      for (size_t i = 0; i < p.size(); ++i) {
        const Vec3d &a = p[i], &b = p[(i + 1) % p.size()];
        n += Vec3d((a[1] - b[1]) * (a[2] + b[2]), (a[2] - b[2]) * (a[0] + b[0]), (a[0] - b[0]) * (a[1] + b[1]));
        m += a;
      }
      m /= double(p.size());
      if ((n | (c - m)) > 0) ++inward; else ++outward;
    }
  }
  std::fclose(out);
  auto valence = checked.request_edge_property<int>("valence");
  auto patch = checked.request_face_property<int>("patch");
  size_t valence_wrong = 0, boundary = 0, patch_on_boundary = 0, patch_inside = 0;
  for (auto eh : checked.edges()) {
    int n = 0;
    for (auto c : checked.edge_cells(eh)) { (void)c; ++n; }
    if (n != valence[eh]) ++valence_wrong;
  }
  for (auto fh : checked.faces()) {
    if (checked.is_boundary(fh)) { ++boundary; if (patch[fh] > 0) ++patch_on_boundary; }
    else if (patch[fh] != 0) ++patch_inside;
  }
  std::printf("{\"read\": true, \"vertices\": %zu, \"edges\": %zu, \"faces\": %zu, \"cells\": %zu, "
              "\"cells_unchecked\": %zu, \"kept\": %zu, \"inward\": %zu, \"outward\": %zu, "
              "\"valence_wrong\": %zu, \"boundary_faces\": %zu, \"patch_on_boundary\": %zu, \"patch_inside\": %zu}\n",
              checked.n_vertices(), checked.n_edges(), checked.n_faces(), checked.n_cells(), as_is.n_cells(), kept,
              inward, outward, valence_wrong, boundary, patch_on_boundary, patch_inside);
  return 0;
}
"""

CMAKE = """cmake_minimum_required(VERSION 3.12)
project(ovm_crosscheck CXX)
set(CMAKE_CXX_STANDARD 17)
set(OVM_ENABLE_APPLICATIONS OFF CACHE BOOL "" FORCE)
set(OVM_ENABLE_UNITTESTS OFF CACHE BOOL "" FORCE)
set(OVM_ENABLE_EXAMPLES OFF CACHE BOOL "" FORCE)
set(OVM_BUILD_DOCUMENTATION OFF CACHE BOOL "" FORCE)
add_subdirectory("{src}" ovm)
add_executable(ovm_check reader.cc)
target_link_libraries(ovm_check OpenVolumeMesh::OpenVolumeMesh)
"""

OVM_TO_VTK = np.array([0, 3, 2, 1, 4, 5, 6, 7])


def source_tree(src: str, build: str) -> str:
    """A source tree: src itself, or its HEAD exported when it is a git directory."""
    if os.path.exists(os.path.join(src, "CMakeLists.txt")):
        return os.path.abspath(src)
    tree = os.path.join(build, "src")
    if not os.path.exists(os.path.join(tree, "CMakeLists.txt")):
        os.makedirs(tree, exist_ok=True)
        archive = subprocess.run(["git", "--git-dir", src, "archive", "HEAD"], capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", tree], input=archive.stdout, check=True)
    return tree


def build_reader(src: str, build: str, jobs: int) -> str:
    tree = source_tree(src, build)
    proj = os.path.join(build, "reader")
    os.makedirs(proj, exist_ok=True)
    with open(os.path.join(proj, "reader.cc"), "w") as f:
        f.write(READER)
    with open(os.path.join(proj, "CMakeLists.txt"), "w") as f:
        f.write(CMAKE.replace("{src}", tree))
    out = os.path.join(build, "out")
    subprocess.run(["cmake", "-S", proj, "-B", out, "-DCMAKE_BUILD_TYPE=Release"], check=True,
                   stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", out, "-j", str(jobs), "--target", "ovm_check"], check=True,
                   stdout=subprocess.DEVNULL)
    return os.path.join(out, "ovm_check")


def oriented_faces(H: np.ndarray) -> list:
    from solver.hexmesh.quality import HEX_FACES

    F = H[:, HEX_FACES]
    r = np.argmin(F, axis=2)[..., None]
    F = np.take_along_axis(F, (r + np.arange(4)) % 4, axis=2)
    return [frozenset(map(tuple, f)) for f in F.tolist()]


def check(exe: str, path: str) -> dict:
    from solver.hexmesh.quality import scaled_jacobian
    from solver.io.ovm import read_hex_ovm

    ours = read_hex_ovm(path)
    with tempfile.TemporaryDirectory() as tmp:
        cells = os.path.join(tmp, "cells.txt")
        run = subprocess.run([exe, path, cells], capture_output=True, text=True)
        if run.returncode != 0:
            return {"file": path, "read": False, "log": run.stdout + run.stderr}
        got = json.loads(run.stdout.strip().splitlines()[-1])
        hv = np.loadtxt(cells, dtype=np.int64, ndmin=2)
    H = hv[:, OVM_TO_VTK]
    same = oriented_faces(H) == oriented_faces(ours.hexes)
    sj_ovm = float(scaled_jacobian(ours.vertices, H).min()) if len(H) else float("nan")
    sj_ours = float(scaled_jacobian(ours.vertices, ours.hexes).min()) if len(H) else float("nan")
    got.update(file=os.path.basename(path), ours={"vertices": len(ours.vertices), "edges": len(ours.edges),
                                                 "faces": len(ours.face_halfedges), "cells": len(ours.hexes)},
               same_hexes=bool(same), min_sj_ovm=sj_ovm, min_sj_ours=sj_ours)
    m = len(ours.hexes)
    got["agrees"] = bool(got["read"] and got["cells"] == got["cells_unchecked"] == got["kept"] == m
                         and all(got[k] == got["ours"][k] for k in ("vertices", "edges", "faces"))
                         and got["outward"] == 0 and got["inward"] == 6 * m and same
                         and got["valence_wrong"] == 0 and got["patch_inside"] == 0
                         and got["patch_on_boundary"] == got["boundary_faces"])
    return got


def example_ovm(name: str, folder: str) -> str:
    """The example solved and hex meshed at its defaults, as X.ovm (the command line)."""
    path = os.path.join(folder, f"{name}.ovm")
    run = subprocess.run([sys.executable, "-m", "solver", "--example", name, "-o", os.path.join(folder, f"{name}.npz"),
                          "--hex", path], cwd=ROOT, capture_output=True, text=True)
    if run.returncode != 0:
        raise SystemExit(f"--example {name}: the solve or hex mesh failed:\n{run.stderr[-2000:]}")
    return path


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="*", help="hex .ovm files written by SymFrames")
    p.add_argument("--ovm-src", default=os.environ.get("OVM_SRC"), help="OpenVolumeMesh source tree or git directory")
    p.add_argument("--build", default=os.path.join(tempfile.gettempdir(), "symframes-ovm-build"))
    p.add_argument("--example", action="append", default=[], help="solve and hex mesh an example first")
    p.add_argument("--jobs", type=int, default=1)
    a = p.parse_args(argv)
    if not a.ovm_src or not (a.files or a.example):
        p.print_usage(sys.stderr)
        return 2
    if not shutil.which("cmake"):
        print("cmake is not installed", file=sys.stderr)
        return 2
    exe = build_reader(a.ovm_src, a.build, a.jobs)
    files = list(a.files)
    with tempfile.TemporaryDirectory() as tmp:
        files += [example_ovm(name, tmp) for name in a.example]
        results = [check(exe, f) for f in files]
    print("| file | vertices | edges | faces | cells (checked / as is / kept) | halffaces inward | same hexes "
          "| min SJ OVM / ours | valence prop | patch prop on boundary faces |")
    print("|---|---:|---:|---:|---|---|---|---|---|---|")
    for r in results:
        if not r["read"]:
            print(f"| {r['file']} | not read: {r.get('log', '')[:200]} |")
            continue
        o = r["ours"]
        print(f"| {r['file']} | {r['vertices']:,} / {o['vertices']:,} | {r['edges']:,} / {o['edges']:,} "
              f"| {r['faces']:,} / {o['faces']:,} | {r['cells']:,} / {r['cells_unchecked']:,} / {r['kept']:,} "
              f"| {r['inward']:,} of {6 * o['cells']:,} | {'yes' if r['same_hexes'] else 'no'} "
              f"| {r['min_sj_ovm']:.3f} / {r['min_sj_ours']:.3f} | {r['valence_wrong']} wrong "
              f"| {r['patch_on_boundary']:,} of {r['boundary_faces']:,}, {r['patch_inside']} inside |")
    return 0 if all(r.get("agrees") for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
