"""Offline route check: SymFrames field export -> CubeCover -> integer-grid map -> HexHex.

Runs a locally built CubeCover command-line tool `integergrid` (Nieser,
Reitebuch, Polthier, "CubeCover - Parameterization of 3D Volumes", SGP 2011;
github.com/evouga/CubeCover, built with CoMISo for the mixed-integer
rounding) on SymFrames' hex-mesher export (.mesh tets + .fra one frame per
tet + .perm face matchings), then runs a locally built HexHex
(github.com/cgg-bern/libHexHex) on the integer-grid map that CubeCover writes
in HexEx's .hexex format.

    .venv/bin/python bench/crosscheck_cubecover.py \\
        --cubecover /path/to/integergrid --hexhex /path/to/HexHex \\
        out/cylinder_edges.mesh out/cylinder_field.mesh [...]
    CUBECOVER_BIN=... HEXHEX_BIN=... .venv/bin/python bench/crosscheck_cubecover.py a.mesh

Each X.mesh needs X.fra and X.perm beside it. Per input the script prints:
  - the field as CubeCover reads it (same conventions as its
    ReadFrameField.cpp / FrameField.cpp / AssignmentGroup.cpp): frames that
    are left-handed, face matchings that do not carry the frame onto its
    neighbour's (worst |cos|), singular edges = interior tet edges whose
    holonomy (product of the face matchings around the edge) is not the
    identity, their chains (connected pieces between nodes), and how far each
    singular edge is from the frame axis its holonomy fixes ("axis dev.":
    CubeCover's integer-grid mode forces the two other coordinates to be
    equal and integer at both ends of every singular edge, so an edge that is
    not along that axis must be squashed in the map);
  - CubeCover's run: exit code, seam faces, integer DOFs, the transition jumps
    it printed that are not integers (its integer-grid mode makes only the
    boundary and singular-curve DOFs integer, so a period around a hole can
    stay fractional), and whether its MIP solve failed (it then writes an
    all-zero map and still exits 0);
  - the map it wrote: flipped tets (parameter-space determinant < 0) and
    degenerate ones (= 0, sign decided exactly on the doubles in the file),
    and face transitions that are not a matching + integer translation;
  - HexHex's verdict (its "IGM is valid" check, and the reason it gives when it
    refuses), its hex count and the interior edges of valence != 4.

Scale. `integergrid` has no scale argument (CubeCoverOptions::scale stays
1.0): it fits the gradient of the map to scale * frame, with unit frames
that is one cell per unit length. The script writes a copy of the .fra with
every frame vector multiplied by the scale and gives CubeCover that copy,
which is the same problem (the frames enter the integer-grid solve only as
the right-hand side scale * frame and, for boundary alignment, through their
directions; the .perm matchings are used as given). By default the scale is
chosen per input so that the parameter volume (sum of tet volume * det of
scaled frame) is about --target-hexes; --scale fixes it for all inputs.

Nothing here downloads or builds anything, and no CubeCover, CoMISo or HexHex
code is part of SymFrames: both binaries are external tools the user builds.
Exit status: 0 when every input gives a map without flipped or degenerate
tets or bad transitions that HexHex accepts as it is and extracts, 1
otherwise, 2 on usage errors.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter, defaultdict
from fractions import Fraction

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
try:  # the HexHex side (runner, .ovmb reader, valences) is shared with crosscheck_hexhex.py
    from crosscheck_hexhex import figures, oriented_scaled_jacobians, ovmb_hexes, read_ovmb, run_hexhex
except ImportError as exc:  # pragma: no cover
    print(f"error: bench/crosscheck_hexhex.py is needed beside this script ({exc})",
          file=sys.stderr)
    sys.exit(2)


# --------------------------------------------------------------------------
# Readers: MEDIT .mesh, .fra, .perm, .hexex
# --------------------------------------------------------------------------

def read_medit(path: str):
    """(V (n,3), T (m,4) zero-based, tet refs (m,)) of a MEDIT .mesh file."""
    with open(path) as f:
        toks = f.read().split()
    V = T = None
    ref = None
    i = 0
    while i < len(toks):
        w = toks[i]
        if w == "Vertices":
            n = int(toks[i + 1])
            a = np.array(toks[i + 2:i + 2 + 4 * n], dtype=float).reshape(n, 4)
            V = a[:, :3]
            i += 2 + 4 * n
        elif w == "Triangles":
            i += 2 + 4 * int(toks[i + 1])
        elif w == "Edges":
            i += 2 + 3 * int(toks[i + 1])
        elif w == "Tetrahedra":
            n = int(toks[i + 1])
            a = np.array(toks[i + 2:i + 2 + 5 * n], dtype=np.int64).reshape(n, 5)
            T = a[:, :4] - 1
            ref = a[:, 4]
            i += 2 + 5 * n
        else:
            i += 1
    if V is None or T is None:
        raise ValueError(f"{path}: no Vertices or no Tetrahedra section")
    return V, T, ref


def read_fra(path: str, ntets: int) -> np.ndarray:
    toks = open(path).read().split()
    if toks[:2] != ["FRA", "1"]:
        raise ValueError(f"{path}: not a FRA 1 file")
    n, vpt = int(toks[2]), int(toks[3])
    if n != ntets or vpt != 3:
        raise ValueError(f"{path}: {n} frames x {vpt} vectors, expected {ntets} x 3")
    return np.array(toks[5:5 + 9 * n], dtype=float).reshape(n, 3, 3)


def read_perm(path: str, ntets: int) -> np.ndarray:
    toks = open(path).read().split()
    if toks[:2] != ["PERM", "1"]:
        raise ValueError(f"{path}: not a PERM 1 file")
    n, nf, nv = int(toks[2]), int(toks[3]), int(toks[4])
    if n != ntets or nv != 3:
        raise ValueError(f"{path}: header {n} {nf} {nv}, expected {ntets} tets and 3 vectors")
    return np.array(toks[5:5 + 5 * nf], dtype=np.int64).reshape(nf, 5)


def read_hexex(path: str):
    """(V, T, U (m,4,3) parameter of each tet corner) of a HexEx .hexex file."""
    toks = open(path).read().split()
    nv = int(toks[0])
    V = np.array(toks[1:1 + 3 * nv], dtype=float).reshape(nv, 3)
    k = 1 + 3 * nv
    nt = int(toks[k])
    a = np.array(toks[k + 1:k + 1 + 16 * nt], dtype=float).reshape(nt, 16)
    return V, a[:, :4].astype(np.int64), a[:, 4:].reshape(nt, 4, 3)


def write_fra(path: str, frames: np.ndarray) -> None:
    with open(path, "w") as f:
        f.write(f"FRA 1\n{len(frames)} 3 1\n")
        np.savetxt(f, frames.reshape(-1, 3), fmt="%.17g")


# --------------------------------------------------------------------------
# Tet mesh connectivity and the field as CubeCover reads it
# --------------------------------------------------------------------------

_TET_FACES = ((1, 2, 3), (0, 2, 3), (0, 1, 3), (0, 1, 2))


def matching_matrix(p) -> np.ndarray:
    """CubeCover's parseFromPerm: vector i of t0 times sign(p_i) matches vector
    |p_i|-1 of t1, and its Integration.cpp unions parameter i of t0 with
    sign(p_i) * parameter |p_i|-1 of t1. As a matrix acting on t0's
    coordinates (or frame rows): G[|p_i|-1, i] = sign(p_i)."""
    G = np.zeros((3, 3), dtype=np.int64)
    for i, pi in enumerate(p):
        G[abs(int(pi)) - 1, i] = 1 if pi > 0 else -1
    return G


class Field:
    def __init__(self, V, T, frames, perm):
        self.V, self.T, self.frames = V, T, frames
        m = len(T)
        # faces: sorted vertex triple -> [(tet, local face)]
        fk = np.sort(T[:, _TET_FACES], axis=2).reshape(-1, 3)
        order = np.lexsort(fk.T[::-1])
        fs = fk[order]
        new = np.ones(len(fs), dtype=bool)
        new[1:] = (fs[1:] != fs[:-1]).any(axis=1)
        gid = np.cumsum(new) - 1
        self.nfaces = int(gid[-1]) + 1
        face_of = np.empty(4 * m, dtype=np.int64)
        face_of[order] = gid
        self.face_of = face_of.reshape(m, 4)
        cnt = np.bincount(gid, minlength=self.nfaces)
        if cnt.max() > 2:
            raise ValueError("non-manifold tet mesh: a face with more than 2 tets")
        self.face_tets = np.full((self.nfaces, 2), -1, dtype=np.int64)
        for k, g in zip(order, gid):
            slot = 0 if self.face_tets[g, 0] < 0 else 1
            self.face_tets[g, slot] = k // 4
        self.face_verts = np.empty((self.nfaces, 3), dtype=np.int64)
        self.face_verts[gid] = fs
        self.boundary_face = self.face_tets[:, 1] < 0
        self.nbr = {}
        for f in np.flatnonzero(~self.boundary_face):
            a, b = (int(x) for x in self.face_tets[f])
            self.nbr[(a, b)] = self.nbr[(b, a)] = int(f)
        # matchings, keyed by ordered tet pair
        self.G = {}
        self.bad_perm_rows = []
        for row in perm:
            t0, t1 = int(row[0]), int(row[1])
            if (t0, t1) not in self.nbr:
                self.bad_perm_rows.append(f"no face between tets {t0} and {t1}")
                continue
            p = row[2:]
            if sorted(abs(int(x)) for x in p) != [1, 2, 3]:
                self.bad_perm_rows.append(f"invalid assignment {list(p)} for {t0} {t1}")
                continue
            G = matching_matrix(p)
            self.G[(t0, t1)] = G
            self.G[(t1, t0)] = G.T
        # edges -> tets
        et = defaultdict(list)
        for t, tet in enumerate(T):
            for a in range(4):
                for b in range(a + 1, 4):
                    u, v = int(tet[a]), int(tet[b])
                    et[(min(u, v), max(u, v))].append(t)
        self.edge_tets = et
        bv = set(self.face_verts[self.boundary_face].ravel().tolist())
        bedges = set()
        for fv in self.face_verts[self.boundary_face]:
            a, b, c = (int(x) for x in fv)
            bedges.update({(min(a, b), max(a, b)), (min(b, c), max(b, c)), (min(a, c), max(a, c))})
        self.boundary_edges = bedges
        self.boundary_verts = bv

    def match(self, t0: int, t1: int) -> np.ndarray:
        return self.G.get((t0, t1), np.eye(3, dtype=np.int64))

    def tets_around(self, e):
        """Tets around interior edge e in cyclic order (walk across the faces
        that contain the edge)."""
        a, b = e
        tets = self.edge_tets[e]
        start = tets[0]
        ring = [start]
        prev, cur = -1, start
        while True:
            nxt = None
            for lf in range(4):
                fv = set(self.T[cur][list(_TET_FACES[lf])].tolist())
                if a in fv and b in fv:
                    f = self.face_of[cur, lf]
                    t0, t1 = (int(x) for x in self.face_tets[f])
                    o = t1 if t0 == cur else t0
                    if o >= 0 and o != prev:
                        nxt = o
                        break
            if nxt is None or nxt == start:
                break
            ring.append(nxt)
            prev, cur = cur, nxt
            if len(ring) > len(tets):
                raise ValueError(f"edge {e}: tet ring does not close")
        return ring

    def analyse(self) -> dict:
        T, V, F = self.T, self.V, self.frames
        gdet = np.linalg.det(V[T[:, 1:]] - V[T[:, :1]])
        fdet = np.linalg.det(F)
        # matching quality: cos between s * frame_t0[i] and frame_t1[j] for every interior face
        worst = 1.0
        nbad = 0
        for f in np.flatnonzero(~self.boundary_face):
            t0, t1 = (int(x) for x in self.face_tets[f])
            G = self.match(t0, t1)
            A = G @ F[t0]  # t0's frame rows carried into t1's slots
            B = F[t1]
            c = np.einsum("ij,ij->i", A, B) / (np.linalg.norm(A, axis=1) * np.linalg.norm(B, axis=1))
            worst = min(worst, float(c.min()))
            nbad += int((c < 0.5).any())
        sing = []
        kinds = Counter()
        dev = []
        for e in self.edge_tets:
            if e in self.boundary_edges:
                continue
            ring = self.tets_around(e)
            H = np.eye(3, dtype=np.int64)
            for k in range(len(ring)):
                H = self.match(ring[k], ring[(k + 1) % len(ring)]) @ H
            if (H == np.eye(3, dtype=np.int64)).all():
                continue
            sing.append(e)
            fixed = [a for a in range(3) if H[a, a] == 1]
            det = int(round(np.linalg.det(H)))
            tr = int(np.trace(H))
            if det == 1 and len(fixed) == 1:
                kinds[{1: "90", -1: "180"}.get(tr, "?")] += 1
                ax = fixed[0]
                d = V[e[1]] - V[e[0]]
                d /= np.linalg.norm(d)
                fa = F[ring[0]][ax]
                dev.append(float(np.degrees(np.arccos(min(1.0, abs(d @ fa) / np.linalg.norm(fa))))))
            else:
                kinds["det-1" if det == -1 else "other"] += 1
        # chains: connected components of the singular-edge graph, cut at nodes
        deg = Counter()
        for a, b in sing:
            deg[a] += 1
            deg[b] += 1
        nodes = {v for v, d in deg.items() if d != 2}
        parent = {}

        def find(x):
            while parent.setdefault(x, x) != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x
        for i, (a, b) in enumerate(sing):  # union edges sharing a non-node vertex
            for v in (a, b):
                if v not in nodes:
                    ra, rb = find(("e", i)), find(("v", v))
                    parent[ra] = rb
            find(("e", i))
        chains = len({find(("e", i)) for i in range(len(sing))})
        dev = np.array(dev) if dev else np.zeros(0)
        return {
            "tets": len(T), "verts": len(V), "curve_tets": None,
            "geo_neg_tets": int((gdet <= 0).sum()),
            "left_handed_frames": int((fdet < 0).sum()),
            "perm_rows": len(self.G) // 2, "perm_errors": self.bad_perm_rows[:5],
            "match_worst_cos": worst, "match_bad_faces": nbad,
            "singular_edges": len(sing), "singular_kinds": dict(kinds),
            "chains": chains, "nodes": len(nodes),
            "axis_dev_max": float(dev.max()) if len(dev) else 0.0,
            "axis_dev_median": float(np.median(dev)) if len(dev) else 0.0,
            "axis_dev_over_20": int((dev > 20).sum()),
            "param_volume_unit": float((np.abs(gdet) / 6 * fdet).sum()),
        }


# --------------------------------------------------------------------------
# The map CubeCover wrote
# --------------------------------------------------------------------------

def _exact_det_sign(P) -> int:
    a = [[Fraction(float(P[i + 1][k])) - Fraction(float(P[0][k])) for k in range(3)]
         for i in range(3)]
    d = (a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
         - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
         + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]))
    return (d > 0) - (d < 0)


def map_figures(hexex: str, field: Field) -> dict:
    V, T, U = read_hexex(hexex)
    if len(T) != len(field.T) or (T != field.T).any():
        raise ValueError(f"{hexex}: tets differ from the input .mesh")
    J = U[:, 1:] - U[:, :1]
    det = np.linalg.det(J)
    scale = np.prod(np.linalg.norm(J, axis=2), axis=1)
    sign = np.sign(det).astype(np.int64)
    near = np.flatnonzero(np.abs(det) <= 1e-9 * np.maximum(scale, 1e-300))
    for t in near:
        sign[t] = _exact_det_sign(U[t])
    all_zero = bool(np.all(U == 0))
    # transitions: param in t1 = G (param in t0) + integer translation, at the 3 shared vertices
    bad_tr = 0
    worst = 0.0
    for f in np.flatnonzero(~field.boundary_face):
        t0, t1 = (int(x) for x in field.face_tets[f])
        G = field.match(t0, t1)
        fv = field.face_verts[f]
        i0 = [int(np.flatnonzero(T[t0] == v)[0]) for v in fv]
        i1 = [int(np.flatnonzero(T[t1] == v)[0]) for v in fv]
        tr = U[t1, i1] - U[t0, i0] @ G.T
        r = max(float(np.abs(tr - tr[0]).max()), float(np.abs(tr[0] - np.round(tr[0])).max()))
        worst = max(worst, r)
        bad_tr += r > 1e-3
    pv = float(det.sum() / 6)
    return {"flipped": int((sign < 0).sum()), "degenerate": int((sign == 0).sum()),
            "proper": int((sign > 0).sum()), "all_zero": all_zero,
            "param_volume": pv, "bad_transitions": int(bad_tr),
            "transition_residual": worst,
            "param_range": [float(U.min()), float(U.max())]}


# --------------------------------------------------------------------------
# Runs
# --------------------------------------------------------------------------

_CC_PATTERNS = {
    "seam_faces": r"found (\d+) seam faces",
    "mip_vars": r"MIP problem has (\d+) parameter variables",
    "jumps": r"and (\d+) transition jumps",
    "int_dofs": r"(\d+) parameter DOFs are integer",
    "residual": r"Problem residual: (\S+)",
    "constraint_norm": r"^C: (\S+)",
}
_CC_PROBLEMS = ("Problem with MIP", "not manifold", "non-manifold", "nonmanifold",
                "not face-connected", "Invalid assignment", "No face between", "Duplicate entry",
                "could not", "Mismatch", "Error", "GUROBI not available")


def run_cubecover(binary, mesh, fra, perm, out, timeout) -> dict:
    cmd = [binary, mesh, fra, perm, out]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        rc, text = proc.returncode, proc.stdout + "\n" + proc.stderr
    except subprocess.TimeoutExpired as exc:
        rc = "timeout"
        text = (exc.stdout or b"").decode(errors="replace") if isinstance(exc.stdout, bytes) \
            else (exc.stdout or "")
    wall = time.perf_counter() - t0
    res = {"cmd": cmd, "returncode": rc, "wall_s": wall, "log": text.splitlines()}
    for k, pat in _CC_PATTERNS.items():
        m = re.search(pat, text, re.M)
        res[k] = (float(m.group(1)) if "." in m.group(1) or "e" in m.group(1) else int(m.group(1))) \
            if m else None
    res["problems"] = [ln for ln in res["log"] if any(p in ln for p in _CC_PROBLEMS)]
    res["mip_failed"] = any("Problem with MIP" in ln for ln in res["log"])
    # the jump values it prints ("Integer variables: ..."); in integer-grid mode CubeCover makes
    # only boundary and singular-curve DOFs integer, so a jump (a period) can stay fractional
    m = re.search(r"^Integer variables:(.*)$", text, re.M)
    jumps = [float(x) for x in m.group(1).split()] if m else []
    res["fractional_jumps"] = [x for x in jumps if abs(x - round(x)) > 1e-6]
    return res


def hexhex_verdict(run: dict) -> tuple[str, list, int]:
    """('valid' | 'valid after large fix' | 'refused', reason lines, number of parameter
    updates its sanitization made). A 'Large Sanitization Fix' means HexHex itself moved
    parameters by more than its sanitization epsilon to make the map an integer-grid map."""
    log = run["log"]
    updates = sum(1 for ln in log if "Update igm" in ln)
    large = any("Large Sanitization Fix" in ln for ln in log)
    reasons = [ln.strip() for ln in log if re.search(
        r"Found \d+ (unaligned|inconsistent)|Detected \d+ Proper|Error|Invalid|rror loading|"
        r"failed|Failure", ln) and "Large Sanitization" not in ln]
    first_updates = [ln.strip() for ln in log if "Update igm" in ln][:2]
    if updates:
        reasons = first_updates + [f"({updates} 'Update igm' lines in all"
                                   + (", with 'Warning: Potentially Invalid Input - Large "
                                      "Sanitization Fix!')" if large else ")")] + reasons
    if run["igm_valid"]:
        return ("valid after large fix" if large else "valid"), reasons, updates
    return "refused", reasons, updates


def check_one(mesh: str, a, workdir: str) -> dict:
    base = os.path.splitext(mesh)[0]
    name = os.path.basename(base)
    fra, perm = base + ".fra", base + ".perm"
    V, T, ref = read_medit(mesh)
    frames = read_fra(fra, len(T))
    P = read_perm(perm, len(T))
    field = Field(V, T, frames, P)
    inp = field.analyse()
    inp["curve_tets"] = int((ref > 0).sum())
    if a.scale:
        s = a.scale
    else:
        s = (a.target_hexes / max(inp["param_volume_unit"], 1e-300)) ** (1 / 3)
        s = float(f"{s:.2g}")
    row = {"case": name, "mesh": mesh, "input": inp, "scale": s}
    sfra = os.path.join(workdir, f"{name}_s{s:g}.fra")
    write_fra(sfra, frames * s)
    out = os.path.join(workdir, f"{name}.hexex")
    if os.path.exists(out):
        os.remove(out)
    cc = run_cubecover(a.cubecover, mesh, sfra, perm, out, a.timeout)
    row["cubecover"] = {k: v for k, v in cc.items() if k != "log"}
    row["cubecover_log_tail"] = cc["log"][-15:]
    row["map"] = None
    row["hexhex"] = None
    if cc["returncode"] != 0 or not os.path.exists(out):
        row["verdict"] = f"CubeCover failed (exit {cc['returncode']})"
        return row
    row["map"] = map_figures(out, field)
    run = run_hexhex(a.hexhex, out, workdir, a.threads, not a.no_sanitize)
    verdict, reasons, updates = hexhex_verdict(run)
    row["hexhex_verdict"] = verdict
    row["hexhex_igm_updates"] = updates
    row["hexhex_reasons"] = reasons[:12]
    row["hexhex_log_tail"] = run["log"][-12:]
    row["hexhex_wall_s"] = round(run["wall_s"], 2)
    row["hexhex_returncode"] = run["returncode"]
    m = re.search(r"(\d+)/\d+ Edges are Singular", "\n".join(run["log"]))
    row["hexhex_singular_edges"] = int(m.group(1)) if m else None
    if run["ovmb"]:
        hp, hv, he = ovmb_hexes(read_ovmb(run["ovmb"]))
        if hv:
            row["hexhex"] = figures(hp, hv, he)
            sj = oriented_scaled_jacobians(hp, hv, he)  # HexHex's cells as extracted: no smoothing
            row["hexhex"].update(sj_min=float(sj.min()), sj_mean=float(sj.mean()), inverted=int((sj <= 0).sum()))
    return row


def fmt_val(d: dict) -> str:
    return " ".join(f"{k}:{v}" for k, v in sorted(d.items())) or "-"


def print_table(rows) -> None:
    hdr = ("case", "tets", "sing.edges/chains", "axis dev. med/max",
           "scale", "CC exit,s", "frac. jumps", "flipped", "degen.", "bad trans.", "HexHex",
           "hexes", "SJ min/mean", "irregular interior edges")
    lines = []
    for r in rows:
        i = r["input"]
        cc = r["cubecover"]
        mp = r["map"]
        hh = r["hexhex"]
        if hh:
            irr = {k: v for k, v in hh["interior_valence"].items() if k != 4}
            irr_s = fmt_val(irr)
        else:
            irr_s = "-"
        verdict = r.get("hexhex_verdict", r.get("verdict", "-"))
        if mp and mp["all_zero"]:
            verdict += " (map all zero: MIP failed)"
        lines.append((
            r["case"], str(i["tets"]), f"{i['singular_edges']}/{i['chains']}",
            f"{i['axis_dev_median']:.1f}/{i['axis_dev_max']:.1f}",
            f"{r['scale']:g}", f"{cc['returncode']},{cc['wall_s']:.1f}",
            str(len(cc["fractional_jumps"])),
            str(mp["flipped"]) if mp else "-", str(mp["degenerate"]) if mp else "-",
            str(mp["bad_transitions"]) if mp else "-",
            verdict, str(hh["hexes"]) if hh else "0" if mp else "-",
            f"{hh['sj_min']:.3f}/{hh['sj_mean']:.3f}" if hh else "-", irr_s))
    widths = [max(len(h), *(len(line[k]) for line in lines)) for k, h in enumerate(hdr)]
    print(" | ".join(h.ljust(w) for h, w in zip(hdr, widths)))
    print("-+-".join("-" * w for w in widths))
    for line in lines:
        print(" | ".join(c.ljust(w) for c, w in zip(line, widths)))
    print("sing.edges/chains: interior tet edges whose face-matching holonomy is not the identity "
          "(as CubeCover computes them from the .perm), and their chains between nodes. axis dev.: "
          "angle (deg) between a singular edge and the frame axis its holonomy fixes. frac. jumps: "
          "transition jumps CubeCover printed that are not integers. flipped / "
          "degen.: tets of CubeCover's map with parameter det < 0 / = 0 (exact). bad trans.: "
          "interior faces whose two sides differ by more than matching + integer shift (1e-3). "
          "HexHex: its own IGM validity check, after its sanitization ('valid after large fix': it "
          "had to move parameters by more than its epsilon first). SJ min/mean: the scaled Jacobian of "
          "HexHex's cells as extracted (no smoothing). irregular interior edges: valence:count of "
          "interior hex edges of valence != 4.")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cubecover", default=os.environ.get("CUBECOVER_BIN"),
                    help="path to CubeCover's integergrid binary (default: $CUBECOVER_BIN)")
    ap.add_argument("--hexhex", default=os.environ.get("HEXHEX_BIN"),
                    help="path to the HexHex binary (default: $HEXHEX_BIN)")
    ap.add_argument("--scale", type=float, default=None,
                    help="frame scale for every input (cells per unit length); default: chosen "
                         "per input from --target-hexes")
    ap.add_argument("--target-hexes", type=float, default=1000,
                    help="parameter volume aimed at when --scale is not given (default 1000)")
    ap.add_argument("--threads", type=int, default=1, help="HexHex --nthreads (default 1)")
    ap.add_argument("--timeout", type=float, default=1800, help="CubeCover time limit, s")
    ap.add_argument("--no-sanitize", action="store_true",
                    help="run HexHex with sanitize_igm off (judge the map exactly as written)")
    ap.add_argument("--keep", metavar="DIR", help="keep the scaled .fra, .hexex and HexHex outputs here")
    ap.add_argument("--json", metavar="FILE", help="also write all figures as JSON")
    ap.add_argument("meshes", nargs="+", metavar="X.mesh")
    a = ap.parse_args(argv)

    for opt, env, what in (("cubecover", "CUBECOVER_BIN", "CubeCover's integergrid"),
                           ("hexhex", "HEXHEX_BIN", "HexHex")):
        val = getattr(a, opt)
        if not val:
            print(f"error: no {what} binary given: pass --{opt} /path/to/binary or set {env} "
                  "(build it yourself; this script never downloads or builds it)", file=sys.stderr)
            return 2
        b = val if os.sep in val else shutil.which(val)
        if not b or not os.path.isfile(b) or not os.access(b, os.X_OK):
            print(f"error: {what} binary not found or not executable: {val}", file=sys.stderr)
            return 2
        setattr(a, opt, os.path.abspath(b))
    for m in a.meshes:
        base = os.path.splitext(m)[0]
        for p in (m, base + ".fra", base + ".perm"):
            if not os.path.isfile(p):
                print(f"error: no such file: {p}", file=sys.stderr)
                return 2

    workdir = a.keep or tempfile.mkdtemp(prefix="cubecover_xcheck_")
    os.makedirs(workdir, exist_ok=True)
    try:
        rows = []
        for m in a.meshes:
            rows.append(check_one(m, a, workdir))
            r = rows[-1]
            print(f"[{r['case']}] done: CubeCover {r['cubecover']['wall_s']:.1f} s, "
                  f"{r.get('hexhex_verdict', r.get('verdict'))}", file=sys.stderr, flush=True)
    finally:
        if not a.keep:
            shutil.rmtree(workdir, ignore_errors=True)

    print(f"CubeCover: {a.cubecover}\nHexHex: {a.hexhex}"
          + ("  (sanitize_igm off)" if a.no_sanitize else ""))
    print_table(rows)
    ok = True
    for r in rows:
        i, cc, mp = r["input"], r["cubecover"], r["map"]
        print(f"\n{r['case']}: {i['tets']} tets, {i['curve_tets']} tagged on curves; singular "
              f"edges by holonomy {fmt_val(i['singular_kinds'])}, {i['nodes']} nodes; "
              f"{i['axis_dev_over_20']} singular edges > 20 deg off their axis; "
              f"matchings: {i['perm_rows']} listed, worst cos {i['match_worst_cos']:.3f}; "
              f"left-handed frames {i['left_handed_frames']}, inverted tets {i['geo_neg_tets']}")
        if i["perm_errors"]:
            print("  .perm problems: " + "; ".join(i["perm_errors"]))
        print(f"  CubeCover: exit {cc['returncode']}, {cc['wall_s']:.1f} s, seam faces "
              f"{cc['seam_faces']}, {cc['int_dofs']} integer DOFs, {cc['jumps']} jumps"
              + (f", {len(cc['fractional_jumps'])} of them fractional "
                 f"({' '.join(f'{x:g}' for x in cc['fractional_jumps'][:4])})"
                 if cc["fractional_jumps"] else "")
              + (", MIP FAILED" if cc["mip_failed"] else ""))
        for ln in cc["problems"][:5]:
            print(f"    > {ln}")
        if mp:
            print(f"  map: {mp['proper']} proper, {mp['flipped']} flipped, {mp['degenerate']} "
                  f"degenerate tets; parameter volume {mp['param_volume']:.1f}; "
                  f"{mp['bad_transitions']} bad transitions (worst {mp['transition_residual']:.2g})")
            hh = r["hexhex"]
            print(f"  HexHex: {r['hexhex_verdict']}; singular edges it sees "
                  f"{r['hexhex_singular_edges']}; "
                  + (f"{hh['hexes']} hexes, interior valences {fmt_val(hh['interior_valence'])}"
                     if hh else "no hexes"))
            for ln in r["hexhex_reasons"][:8]:
                print(f"    > {ln}")
        good = bool(mp and not mp["all_zero"] and mp["flipped"] == 0 and mp["degenerate"] == 0
                    and mp["bad_transitions"] == 0 and r.get("hexhex_verdict") == "valid"
                    and r["hexhex"])
        ok &= good
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1, default=str)
    print("\nall inputs give a valid integer-grid map and a hex mesh" if ok
          else "\nFAILURES found")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
