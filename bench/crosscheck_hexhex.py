"""Offline cross-check of SymFrames' hex extraction against libHexHex.

Runs a locally built HexHex command-line tool (Kohler, Heistermann, Bommes,
"HexHex: Highspeed Extraction of Hexahedral Meshes", SIGGRAPH 2025;
github.com/cgg-bern/libHexHex, GPL) on integer-grid maps in HexEx format and
compares its hex mesh with the one SymFrames extracted from the same map.

    .venv/bin/python bench/crosscheck_hexhex.py --hexhex /path/to/HexHex \\
        cube.hexex cube.vtu  ball.hexex ball.vtu  [...]
    HEXHEX_BIN=/path/to/HexHex .venv/bin/python bench/crosscheck_hexhex.py a.hexex a.vtu

Arguments come in pairs: a .hexex map and the .vtu (VTK_HEXAHEDRON cells)
SymFrames extracted from it. Per pair, ours / HexHex: hex count, vertex count,
boundary quad count, the multiset of interior-edge valences (interior edge =
edge on no boundary quad; valence = hexes around it), whether the two meshes
are the same up to vertex renumbering, and HexHex's own verdict on the map.

"Same mesh" is decided twice. Strict: every HexHex vertex lies within --tol
times the bounding-box diagonal of one of ours (KD-tree), one to one, and the
sorted hex vertex tuples and the edge sets agree under that map. Topology: the
same with each HexHex vertex mapped to its nearest vertex of ours, if that is
one to one. SymFrames smooths the vertex positions after extraction by
default while HexHex places every vertex where the map puts it, so a
smoothed .vtu agrees in topology only; the "moved" column says how far
(largest distance, as a fraction of the diagonal) and the SJ column gives the
minimum scaled Jacobian of our positions and of HexHex's on the same hexes.

Nothing here downloads or builds anything, and no HexHex code is part of
SymFrames: the binary is an external tool the user builds. Its output is read
as .ovmb (OpenVolumeMesh binary, full double precision; the tool's ASCII
outputs keep only 6 significant digits). Exit status: 0 when every pair agrees
in counts and topology and HexHex finds the map valid, 1 otherwise, 2 on
usage errors.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import time
from collections import Counter

import numpy as np

# --------------------------------------------------------------------------
# OpenVolumeMesh binary (.ovmb) reader: header, VERT and TOPO chunks only.
# Little-endian. File header (48 bytes): magic "OVMB\n\r\n\xff", file_version
# u8, header_version u8, vertex_dim u8, topo_type u8, 4 reserved, then
# n_verts, n_edges, n_faces, n_cells as u64. Each chunk: fourcc, version u8,
# padding u8, compression u8, flags u8, length u64 (payload + padding).
# VERT payload: first u64, count u32, encoding u8 (1 float, 2 double), 3
# reserved, coordinates. TOPO payload: first u64, count u32, entity u8 (1 edge,
# 2 face, 3 cell), valence u8 (0: variable), valence encoding u8, handle
# encoding u8 (bytes per int), handle offset u64, [valences], handles: vertex
# ids per edge, halfedge ids per face (edge = he >> 1), halfface ids per cell
# (face = hf >> 1).
# --------------------------------------------------------------------------

OVMB_MAGIC = b"OVMB\n\r\n\xff"
_INT_DTYPES = {1: "<u1", 2: "<u2", 4: "<u4"}


def read_ovmb(path: str) -> dict:
    """{'points': (n,3), 'edges': (ne,2) vertex ids, 'faces': halfedge-id
    arrays, 'cells': halfface-id arrays} of an .ovmb file."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 48 or data[:8] != OVMB_MAGIC:
        raise ValueError(f"{path}: not an OpenVolumeMesh binary file")
    _fv, hv, vdim, _topo = struct.unpack_from("<BBBB", data, 8)
    if hv != 1:
        raise ValueError(f"{path}: unsupported ovmb header version {hv}")
    nv, ne, nf, nc = struct.unpack_from("<QQQQ", data, 16)
    points = np.full((nv, vdim), np.nan)
    edges = np.full((ne, 2), -1, dtype=np.int64)
    faces: list = [None] * nf
    cells: list = [None] * nc
    pos = 48
    while pos + 16 <= len(data):
        fourcc = data[pos:pos + 4]
        _ver, pad, compression, _flags = struct.unpack_from("<BBBB", data, pos + 4)
        (length,) = struct.unpack_from("<Q", data, pos + 8)
        pos += 16
        payload = memoryview(data)[pos:pos + length - pad]
        pos += length
        if fourcc == b"EOF ":
            break
        if compression:
            raise ValueError(f"{path}: compressed ovmb chunks are not supported")
        if fourcc == b"VERT":
            first, count, enc = struct.unpack_from("<QIB", payload, 0)
            dt = {1: "<f4", 2: "<f8"}[enc]
            arr = np.frombuffer(payload, dtype=dt, count=count * vdim, offset=16)
            points[first:first + count] = arr.reshape(count, vdim)
        elif fourcc == b"TOPO":
            first, count, entity, valence, venc, henc, hoff = struct.unpack_from(
                "<QIBBBBQ", payload, 0)
            off = 24
            if valence:
                vals = np.full(count, valence, dtype=np.int64)
            else:
                vals = np.frombuffer(payload, dtype=_INT_DTYPES[venc], count=count,
                                     offset=off).astype(np.int64)
                off += count * venc
            handles = np.frombuffer(payload, dtype=_INT_DTYPES[henc],
                                    count=int(vals.sum()), offset=off).astype(np.int64) + hoff
            if entity == 1:
                edges[first:first + count] = handles.reshape(count, 2)
            else:
                target = faces if entity == 2 else cells
                target[first:first + count] = np.split(handles, np.cumsum(vals)[:-1])
        # DIRP / PROP chunks (properties) are not needed here.
    if vdim != 3 or np.isnan(points).any() or (edges < 0).any() \
            or any(x is None for x in faces) or any(x is None for x in cells):
        raise ValueError(f"{path}: incomplete ovmb file")
    return {"points": points, "edges": edges, "faces": faces, "cells": cells}


def ovmb_hexes(mesh: dict):
    """(points, per-cell vertex sets, per-cell edge sets as vertex-pair
    frozensets), from the cell -> halfface -> halfedge -> edge topology."""
    edges = mesh["edges"]
    face_edges = [frozenset(int(h) >> 1 for h in hes) for hes in mesh["faces"]]
    vsets, esets = [], []
    for hfs in mesh["cells"]:
        eids = set()
        for hf in hfs:
            eids |= face_edges[int(hf) >> 1]
        eset = frozenset(frozenset((int(edges[e, 0]), int(edges[e, 1]))) for e in eids)
        vsets.append(frozenset(v for e in eset for v in e))
        esets.append(eset)
    return mesh["points"], vsets, esets


# --------------------------------------------------------------------------
# VTK hexahedra (ours)
# --------------------------------------------------------------------------

_VTK_HEX_EDGES = ((0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                  (0, 4), (1, 5), (2, 6), (3, 7))
# the three corners joined to each corner, ordered so that a positively
# oriented VTK hex has positive corner determinants
_VTK_CORNER_NBRS = np.array([[1, 3, 4], [2, 0, 5], [3, 1, 6], [0, 2, 7],
                             [7, 5, 0], [4, 6, 1], [5, 7, 2], [6, 4, 3]])


def vtu_hexes(path: str):
    """(points, hexes (m,8) in VTK order, vertex sets, edge sets)."""
    import meshio

    m = meshio.read(path)
    others = sorted({c.type for c in m.cells if c.type != "hexahedron"})
    if others:
        raise ValueError(f"{path}: non-hex cells present: {others}")
    blocks = [np.asarray(c.data, dtype=np.int64) for c in m.cells]
    hexes = np.concatenate(blocks) if blocks else np.zeros((0, 8), dtype=np.int64)
    vsets = [frozenset(int(v) for v in h) for h in hexes]
    esets = [frozenset(frozenset((int(h[a]), int(h[b]))) for a, b in _VTK_HEX_EDGES)
             for h in hexes]
    return np.asarray(m.points, dtype=float)[:, :3], hexes, vsets, esets


def vtk_order(vset, eset) -> list[int]:
    """A cell's 8 vertices in VTK_HEXAHEDRON order from its vertex and edge
    sets (orientation not yet chosen: see oriented_scaled_jacobians)."""
    nb = {v: set() for v in vset}
    for e in eset:
        a, b = tuple(e)
        nb[a].add(b)
        nb[b].add(a)
    v0 = min(vset)
    n1, n3, n4 = sorted(nb[v0])

    def common(a, b):
        return next(x for x in nb[a] & nb[b] if x != v0)

    v2, v5, v7 = common(n1, n3), common(n1, n4), common(n3, n4)
    v6 = next(iter(set(vset) - {v0, n1, v2, n3, n4, v5, v7}))
    return [v0, n1, v2, n3, n4, v5, v6, v7]


def oriented_scaled_jacobians(points: np.ndarray, vsets, esets) -> np.ndarray:
    """Per cell the smallest corner scaled Jacobian of a mesh given as vertex
    and edge sets (an .ovmb): each cell in VTK order, in the orientation
    whose corner determinants sum higher (the mirror order negates them all)."""
    H = np.array([vtk_order(v, e) for v, e in zip(vsets, esets)], dtype=np.int64).reshape(-1, 8)
    a, b = corner_scaled_jacobians(points, H), corner_scaled_jacobians(points, H[:, [0, 3, 2, 1, 4, 7, 6, 5]])
    return np.where(b.sum(axis=1) > a.sum(axis=1), b.min(axis=1), a.min(axis=1))


def corner_scaled_jacobians(points: np.ndarray, hexes: np.ndarray) -> np.ndarray:
    """(m, 8): per corner the det of the 3 unit edges there (VTK order)."""
    P = points[hexes]
    E = P[:, _VTK_CORNER_NBRS] - P[:, :, None, :]
    E /= np.maximum(np.linalg.norm(E, axis=3, keepdims=True), 1e-300)
    return np.einsum("...i,...i->...", E[..., 0, :], np.cross(E[..., 1, :], E[..., 2, :]))


def min_scaled_jacobian(points: np.ndarray, hexes: np.ndarray) -> float:
    """Smallest corner scaled Jacobian (det of the 3 unit edges at a corner)."""
    if not len(hexes):
        return float("nan")
    return float(corner_scaled_jacobians(points, hexes).min())


# --------------------------------------------------------------------------
# Figures and comparison
# --------------------------------------------------------------------------

def figures(points, vsets, esets) -> dict:
    """Counts and interior-edge valences. The quads of a hex are the 4-cycles
    of its edge graph (a cube's graph has exactly its 6 faces as 4-cycles)."""
    face_count: Counter = Counter()
    for vs, es in zip(vsets, esets):
        adj = {v: set() for v in vs}
        for e in es:
            a, b = tuple(e)
            adj[a].add(b)
            adj[b].add(a)
        quads = set()
        for a in vs:
            for b in adj[a]:
                for c in adj[b] - {a}:
                    for d in adj[c] - {a, b}:
                        if a in adj[d]:
                            quads.add(frozenset((a, b, c, d)))
        face_count.update(quads)
    boundary = [q for q, n in face_count.items() if n == 1]
    edge_val: Counter = Counter()
    for es in esets:
        edge_val.update(es)
    bnd_edges = set()
    for q in boundary:
        ql = tuple(q)
        for i in range(4):
            for j in range(i + 1, 4):
                e = frozenset((ql[i], ql[j]))
                if e in edge_val:  # a quad's sides are hex edges, its diagonals are not
                    bnd_edges.add(e)
    interior = Counter(n for e, n in edge_val.items() if e not in bnd_edges)
    used = set().union(*vsets) if vsets else set()
    return {
        "hexes": len(vsets),
        "vertices": len(points),
        "unused_vertices": len(points) - len(used),
        "boundary_quads": len(boundary),
        "quads": len(face_count),
        "nonmanifold_quads": sum(1 for n in face_count.values() if n > 2),
        "edges": len(edge_val),
        "interior_valence": dict(sorted(interior.items())),
        "boundary_edge_valence": dict(sorted(Counter(edge_val[e] for e in bnd_edges).items())),
    }


def _compare_under(m: list, va, ea, vb, eb) -> dict:
    ha = Counter(tuple(sorted(s)) for s in va)
    hb = Counter(tuple(sorted(m[v] for v in s)) for s in vb)
    sa = set().union(*ea) if ea else set()
    sb = {frozenset(m[v] for v in e) for es in eb for e in es}
    out = {"hexes_only_ours": sum((ha - hb).values()),
           "hexes_only_hexhex": sum((hb - ha).values()),
           "edges_only_ours": len(sa - sb), "edges_only_hexhex": len(sb - sa)}
    out["same"] = not any(out.values())
    return out


def same_mesh(pa, va, ea, pb, vb, eb, tol_rel: float) -> dict:
    """Map B's vertices (HexHex) to A's (ours) by position, strictly within
    tol_rel * bbox diagonal and by plain nearest neighbour; compare hexes and
    edges under each map."""
    from scipy.spatial import cKDTree

    lo = np.minimum(pa.min(axis=0), pb.min(axis=0))
    hi = np.maximum(pa.max(axis=0), pb.max(axis=0))
    diag = float(np.linalg.norm(hi - lo))
    dist, idx = cKDTree(pa).query(pb, k=1)
    m = idx.tolist()
    bijective = len(pa) == len(pb) and len(set(m)) == len(m)
    ok = dist <= tol_rel * diag
    out = {"diag": diag, "tol": tol_rel * diag,
           "moved_vertices": int((~ok).sum()),
           "max_moved_rel": float(dist.max()) / diag if len(dist) else 0.0,
           "nearest_is_bijective": bijective}
    topo = _compare_under(m, va, ea, vb, eb) if bijective else {"same": False}
    out["topology"] = topo
    out["same_topology"] = topo["same"]
    out["same_strict"] = bool(topo["same"] and ok.all())
    out["map"] = m if bijective else None
    return out


# HexHex's Config fields (its --config loader needs every one of them); the
# values are HexHex's defaults except sanitize_igm, which --no-sanitize turns
# off so that its validity check sees the map exactly as written.
HEXHEX_CONFIG = {
    "extract_piecewise_linear_edges": False, "extract_piecewise_linear_faces": False,
    "verbose": True, "hf_transition_prop_name": "HalffaceTransiton",
    "e_valence_prop_name": "edge_valance", "sanitize_igm": True, "num_threads": 1,
    "igm_scaling_factor": 1, "sanitization_epsilon": 1e-2,
    "assert_igm_validity": True, "rasterization_epsilon": 1e-6,
}

# Log lines of HexHex that flag a defect in the input map or a failure.
_PROBLEM_MARKERS = ("Update igm", "Inconsistent Parameters", "HexHex: Found",
                    "Flipped", "Failure", "Invalid", "failed", "Error", "rror loading")


def run_hexhex(binary: str, hexex: str, workdir: str, threads: int,
               sanitize: bool = True) -> dict:
    out = os.path.join(workdir, os.path.splitext(os.path.basename(hexex))[0] + ".ovmb")
    rep = out[:-5] + ".report.json"
    for p in (out, rep):
        if os.path.exists(p):
            os.remove(p)
    cmd = [binary, "--in", hexex, "--out-hex", out, "--report", rep,
           "--nthreads", str(threads)]
    if not sanitize:
        cfg = os.path.join(workdir, "config_nosanitize.json")
        with open(cfg, "w") as f:
            json.dump(dict(HEXHEX_CONFIG, sanitize_igm=False, num_threads=threads), f)
        cmd += ["--config", cfg]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    log = (proc.stdout + "\n" + proc.stderr).splitlines()
    res = {"cmd": cmd, "returncode": proc.returncode, "wall_s": wall,
           "log": log, "ovmb": None, "report": None,
           "igm_valid": any("IGM is valid" in line for line in log),
           "problems": [line for line in log if any(k in line for k in _PROBLEM_MARKERS)]}
    if os.path.exists(rep):
        try:
            with open(rep) as f:
                res["report"] = json.load(f)
        except ValueError:
            pass
    if proc.returncode == 0 and os.path.exists(out) and os.path.getsize(out) > 0:
        res["ovmb"] = out
    return res


def fmt_val(d: dict) -> str:
    return " ".join(f"{k}:{v}" for k, v in sorted(d.items())) or "-"


def compare_pair(binary, hexex, vtu, workdir, args) -> dict:
    name = os.path.splitext(os.path.basename(hexex))[0]
    op, oh, ov, oe = vtu_hexes(vtu)
    ours = figures(op, ov, oe)
    ours["sj_min"] = min_scaled_jacobian(op, oh)
    run = run_hexhex(binary, hexex, workdir, args.threads, not args.no_sanitize)
    row = {"case": name, "hexex": hexex, "vtu": vtu, "ours": ours, "hexhex": None,
           "hexhex_wall_s": round(run["wall_s"], 3), "hexhex_returncode": run["returncode"],
           "hexhex_igm_valid": run["igm_valid"], "hexhex_problems": run["problems"],
           "hexhex_report": run["report"], "agree": False}
    if run["ovmb"] is None:
        row["refused"] = run["log"][-12:]
        return row
    hp, hv, he = ovmb_hexes(read_ovmb(run["ovmb"]))
    if not hv:  # HexHex writes an empty mesh when its extraction fails
        row["refused"] = run["log"][-12:]
        return row
    theirs = figures(hp, hv, he)
    iso = same_mesh(op, ov, oe, hp, hv, he, args.tol)
    m = iso.pop("map")
    if m is not None and iso["same_topology"]:
        # HexHex's positions on our connectivity: inv[ours] = hexhex vertex
        inv = np.empty(len(m), dtype=np.int64)
        inv[np.asarray(m)] = np.arange(len(m))
        theirs["sj_min"] = min_scaled_jacobian(hp[inv], oh)
    else:
        theirs["sj_min"] = float("nan")
    keys = ("hexes", "vertices", "boundary_quads", "interior_valence")
    row.update(hexhex=theirs, same_mesh=iso,
               agree=bool(all(ours[k] == theirs[k] for k in keys) and iso["same_topology"]
                          and run["igm_valid"] and not run["problems"]))
    return row


def print_table(rows) -> None:
    hdr = ("case", "hexes ours/HH", "verts ours/HH", "bnd quads ours/HH",
           "interior valences ours | HH", "same mesh", "moved", "SJ min ours/HH",
           "IGM valid", "HH s")
    lines = []
    for r in rows:
        o, t = r["ours"], r["hexhex"]
        valid = "yes" if r["hexhex_igm_valid"] else "no"
        if t is None:
            lines.append((r["case"], f"{o['hexes']}/-", f"{o['vertices']}/-",
                          f"{o['boundary_quads']}/-",
                          f"{fmt_val(o['interior_valence'])} | REFUSED", "-", "-",
                          f"{o['sj_min']:.3f}/-", valid, f"{r['hexhex_wall_s']:.2f}"))
            continue
        iso = r["same_mesh"]
        if iso["same_strict"]:
            same = "yes"
        elif iso["same_topology"]:
            same = "topology"
        elif not iso["nearest_is_bijective"]:
            same = "no (no vertex bijection)"
        else:
            tp = iso["topology"]
            same = (f"no ({tp['hexes_only_ours']}/{tp['hexes_only_hexhex']} hexes, "
                    f"{tp['edges_only_ours']}/{tp['edges_only_hexhex']} edges differ)")
        moved = (f"{iso['moved_vertices']} ({iso['max_moved_rel']:.1e})"
                 if iso["moved_vertices"] else "0")
        vo, vh = fmt_val(o["interior_valence"]), fmt_val(t["interior_valence"])
        lines.append((r["case"], f"{o['hexes']}/{t['hexes']}",
                      f"{o['vertices']}/{t['vertices']}",
                      f"{o['boundary_quads']}/{t['boundary_quads']}",
                      vo if vo == vh else f"{vo} | {vh}", same, moved,
                      f"{o['sj_min']:.3f}/{t['sj_min']:.3f}", valid,
                      f"{r['hexhex_wall_s']:.2f}"))
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(hdr)]
    print(" | ".join(h.ljust(w) for h, w in zip(hdr, widths)))
    print("-+-".join("-" * w for w in widths))
    for line in lines:
        print(" | ".join(c.ljust(w) for c, w in zip(line, widths)))
    print("interior valences: valence:count (one entry when both agree). same mesh: 'yes' = same "
          "hexes and edges with vertices matched within --tol of the bbox diagonal; 'topology' = "
          "same hexes and edges under nearest-vertex matching, positions differ. moved: vertices "
          "farther than --tol from HexHex's (largest distance / diagonal). SJ min: smallest "
          "corner scaled Jacobian, HexHex's positions on the same hexes. IGM valid: HexHex's own "
          "check (after its sanitization unless --no-sanitize).")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--hexhex", default=os.environ.get("HEXHEX_BIN"),
                    help="path to the HexHex binary (default: $HEXHEX_BIN)")
    ap.add_argument("--tol", type=float, default=1e-6,
                    help="vertex match tolerance, relative to the bbox diagonal (default 1e-6)")
    ap.add_argument("--threads", type=int, default=1, help="HexHex --nthreads (default 1)")
    ap.add_argument("--no-sanitize", action="store_true",
                    help="run HexHex with sanitize_igm off: its validity check (exact "
                         "transitions, singular edges and boundary faces on the integer "
                         "grid, no flipped tets) then judges the map as written")
    ap.add_argument("--keep", metavar="DIR", help="keep HexHex's outputs (.ovmb, report) here")
    ap.add_argument("--json", metavar="FILE", help="also write all figures as JSON")
    ap.add_argument("pairs", nargs="+", metavar="FILE.hexex OURS.vtu")
    a = ap.parse_args(argv)

    if not a.hexhex:
        print("error: no HexHex binary given: pass --hexhex /path/to/HexHex or set HEXHEX_BIN "
              "(build libHexHex yourself; this script never downloads or builds it)",
              file=sys.stderr)
        return 2
    binary = a.hexhex if os.sep in a.hexhex else shutil.which(a.hexhex)
    if not binary or not os.path.isfile(binary) or not os.access(binary, os.X_OK):
        print(f"error: HexHex binary not found or not executable: {a.hexhex}", file=sys.stderr)
        return 2
    if len(a.pairs) % 2:
        print("error: arguments must come in pairs FILE.hexex OURS.vtu", file=sys.stderr)
        return 2
    pairs = list(zip(a.pairs[0::2], a.pairs[1::2]))
    for hx, vt in pairs:
        for p in (hx, vt):
            if not os.path.isfile(p):
                print(f"error: no such file: {p}", file=sys.stderr)
                return 2

    workdir = a.keep or tempfile.mkdtemp(prefix="hexhex_xcheck_")
    os.makedirs(workdir, exist_ok=True)
    try:
        rows = [compare_pair(binary, hx, vt, workdir, a) for hx, vt in pairs]
    finally:
        if not a.keep:
            shutil.rmtree(workdir, ignore_errors=True)

    print(f"HexHex: {binary}" + ("  (sanitize_igm off)" if a.no_sanitize else ""))
    print_table(rows)
    for r in rows:
        probs = r["hexhex_problems"]
        if probs:
            shown = probs if len(probs) <= 10 else probs[:4] + ["..."] + probs[-6:]
            print(f"\n{r['case']}: HexHex flagged {len(probs)} log line(s):\n  "
                  + "\n  ".join(shown))
        if r["hexhex"] is None:
            print(f"\n{r['case']}: HexHex produced no hex mesh (exit "
                  f"{r['hexhex_returncode']}); its last output:\n  " + "\n  ".join(r["refused"]))
            continue
        for side in ("ours", "hexhex"):
            f = r[side]
            if f["unused_vertices"] or f["nonmanifold_quads"]:
                print(f"{r['case']} ({side}): {f['unused_vertices']} unused vertices, "
                      f"{f['nonmanifold_quads']} quads in more than 2 hexes")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1, default=str)
    ok = all(r["agree"] for r in rows)
    print("\nall agree" if ok else "\nDISCREPANCIES found")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
