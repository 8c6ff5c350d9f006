"""Hex meshes for simulation codes, with their boundary groups.

``write_hex_msh``  Gmsh MSH 4.1, ASCII or binary: hexahedra (type 5) in
                   the physical volume ``volume``, the boundary quads
                   (type 3) in one surface entity and physical group per
                   patch (``patch_1``, ...), the irregular edges (type 1)
                   in a curve entity and physical group per valence
                   (``irregular_valence_3``, ``irregular_valence_5``)
``write_hex_inp``  Abaqus / CalculiX input: ``*NODE``, ``*ELEMENT,
                   TYPE=C3D8`` (set ``EALL``), and per patch a node set
                   and an element set ``PATCH_k`` (its nodes, the cells
                   holding its quads) and an element-face surface
                   ``S_PATCH_k`` (``S1``..``S6``; CalculiX 2.20's
                   ``*DSLOAD`` loads nothing on a surface named as a set);
                   the irregular edges' nodes as the node set
                   ``IRREGULAR_EDGES``.  Numbers are written in at most 19
                   characters and lines stay under 132, as CalculiX reads
                   them.

``write_hex_exodus``  Exodus II (netCDF classic, written with scipy): one
                   element block of ``HEX8``, a side set per patch
                   (``patch_1``, ...; Exodus' side numbers) and the
                   irregular edges' nodes as the node set
                   ``irregular_edges``

Corner order: Gmsh's 8-node hexahedron, Exodus' HEX8 and Abaqus' C3D8 all number the
corners as VTK does (one face, then the opposite one, counter-clockwise
seen from outside the first), so cells are written as SymFrames holds them.
Both files are written whole or not at all (atomic.py).
"""

from __future__ import annotations

import io
import re

import numpy as np

from .atomic import write_files, write_text
from .text import format_rows

_GMSH_LINE, _GMSH_QUAD, _GMSH_HEX = 1, 3, 5


def _groups(patches, irregular_edges, irregular_valence):
    """(quads by patch id, names by patch id, edges by valence)."""
    quads, names = {}, {}
    if patches is not None:
        for i, name in enumerate(patches.names, start=1):
            m = patches.patch == i
            if np.any(m):
                quads[i], names[i] = patches.quads[m], name
    edges = {}
    E = np.asarray(irregular_edges if irregular_edges is not None else np.zeros((0, 2)), np.int64).reshape(-1, 2)
    val = np.asarray(irregular_valence if irregular_valence is not None else np.zeros(0), np.int64).reshape(-1)
    for v in np.unique(val):
        edges[int(v)] = E[val == v]
    return quads, names, edges


def write_hex_msh(path: str, vertices: np.ndarray, hexes: np.ndarray, patches=None, irregular_edges=None,
                  irregular_valence=None, binary: bool = False) -> None:
    """Gmsh MSH 4.1 (module docs); patches: a hexmesh.patches.BoundaryPatches
    or None (the hexahedra alone)."""
    V = np.asarray(vertices, float)
    H = np.asarray(hexes, np.int64)
    quads, names, edges = _groups(patches, irregular_edges, irregular_valence)
    lo, hi = V.min(axis=0), V.max(axis=0)

    def box(ids):
        P = V[np.unique(ids)] if np.size(ids) else np.zeros((1, 3))
        return np.r_[P.min(axis=0), P.max(axis=0)]

    physical = [(3, 1, "volume")] + [(2, i, n) for i, n in names.items()] + \
               [(1, v, f"irregular_valence_{v}") for v in edges]
    # entities: curves (tag = valence), surfaces (tag = patch id), volume 1
    curves = [(v, box(e), v) for v, e in edges.items()]
    surfaces = [(i, box(q), i) for i, q in quads.items()]
    blocks = [(1, v, _GMSH_LINE, e) for v, e in edges.items()] + \
             [(2, i, _GMSH_QUAD, q) for i, q in quads.items()] + [(3, 1, _GMSH_HEX, H)]
    n_el = sum(len(b[3]) for b in blocks)
    head = f"$MeshFormat\n4.1 {int(binary)} 8\n".encode()
    if binary:
        head += np.array([1], np.int32).tobytes() + b"\n"
    head += b"$EndMeshFormat\n$PhysicalNames\n" + f"{len(physical)}\n".encode()
    head += "".join(f'{d} {t} "{str(n).replace(chr(34), chr(39))}"\n' for d, t, n in physical).encode()
    head += b"$EndPhysicalNames\n"
    if binary:
        body = _msh_binary(V, H, lo, hi, curves, surfaces, blocks, n_el)
    else:
        body = _msh_ascii(V, H, lo, hi, curves, surfaces, blocks, n_el)
    write_files({path: head + body})


def _reals(a) -> str:
    return " ".join(f"{float(x):.17g}" for x in a)


def _msh_ascii(V, H, lo, hi, curves, surfaces, blocks, n_el) -> bytes:
    out = ["$Entities\n", f"0 {len(curves)} {len(surfaces)} 1\n"]
    out += [f"{t} {_reals(b)} 1 {p} 0\n" for t, b, p in curves + surfaces]
    out.append(f"1 {_reals(np.r_[lo, hi])} 1 1 {len(surfaces)}" + "".join(f" {t}" for t, _, _ in surfaces) + "\n")
    out += ["$EndEntities\n", "$Nodes\n", f"1 {len(V)} 1 {len(V)}\n", f"3 1 0 {len(V)}\n",
            format_rows(np.arange(1, len(V) + 1), "%d"), format_rows(V, "%.17g"), "$EndNodes\n",
            "$Elements\n", f"{len(blocks)} {n_el} 1 {n_el}\n"]
    tag = 1
    for dim, ent, kind, cells in blocks:
        out.append(f"{dim} {ent} {kind} {len(cells)}\n")
        out.append(format_rows(np.c_[np.arange(tag, tag + len(cells)), np.asarray(cells) + 1], "%d"))
        tag += len(cells)
    out.append("$EndElements\n")
    return "".join(out).encode()


def _msh_binary(V, H, lo, hi, curves, surfaces, blocks, n_el) -> bytes:
    i32, u64, f64 = (lambda *a: np.array(a, np.int32).tobytes()), (lambda *a: np.array(a, np.uint64).tobytes()), \
        (lambda a: np.asarray(a, np.float64).tobytes())
    out = [b"$Entities\n", u64(0, len(curves), len(surfaces), 1)]
    for t, b, p in curves + surfaces:
        out += [i32(t), f64(b), u64(1), i32(p), u64(0)]
    out += [i32(1), f64(np.r_[lo, hi]), u64(1), i32(1), u64(len(surfaces)), i32(*[t for t, _, _ in surfaces])
            if surfaces else b""]
    out += [b"\n$EndEntities\n$Nodes\n", u64(1, len(V), 1, len(V)), i32(3, 1, 0), u64(len(V)),
            np.arange(1, len(V) + 1, dtype=np.uint64).tobytes(), f64(V), b"\n$EndNodes\n$Elements\n",
            u64(len(blocks), n_el, 1, n_el)]
    tag = 1
    for dim, ent, kind, cells in blocks:
        cells = np.asarray(cells, np.int64)
        out += [i32(dim, ent, kind), u64(len(cells)),
                np.c_[np.arange(tag, tag + len(cells)), cells + 1].astype(np.uint64).tobytes()]
        tag += len(cells)
    out.append(b"\n$EndElements\n")
    return b"".join(out)


def _id_lines(ids: np.ndarray, per_line: int = 10) -> str:
    """1-based ids, comma separated, per_line to a line (CalculiX reads at
    most 132 characters a line)."""
    ids = np.asarray(ids, np.int64)
    lines = []
    for s in range(0, len(ids), per_line):
        lines.append(", ".join(str(int(i)) for i in ids[s:s + per_line]) + "\n")
    return "".join(lines)


def write_hex_inp(path: str, vertices: np.ndarray, hexes: np.ndarray, patches=None, irregular_edges=None,
                  heading: str = "SymFrames hex mesh") -> None:
    """Abaqus / CalculiX input (module docs); patches: a
    hexmesh.patches.BoundaryPatches or None (nodes and elements alone)."""
    from ..hexmesh.patches import ABAQUS_FACE

    V = np.asarray(vertices, float)
    H = np.asarray(hexes, np.int64)
    out = ["*HEADING\n", heading.replace("\n", " ")[:120] + "\n", "*NODE, NSET=NALL\n",
           ("%d, %.12g, %.12g, %.12g\n" * len(V)) % tuple(np.c_[np.arange(1, len(V) + 1), V].reshape(-1).tolist()),
           "*ELEMENT, TYPE=C3D8, ELSET=EALL\n", format_rows(np.c_[np.arange(1, len(H) + 1), H + 1], "%d")
           .replace(" ", ", ")]
    if patches is not None:
        for i, name in enumerate(patches.names, start=1):
            m = patches.patch == i
            if not np.any(m):
                continue
            up = re.sub(r"[^A-Za-z0-9_]", "_", str(name)).upper()[:70]  # CalculiX names: letters, digits, _
            cells = patches.cells[m] + 1
            out += [f"*NSET, NSET={up}\n", _id_lines(np.unique(patches.quads[m]) + 1),
                    f"*ELSET, ELSET={up}\n", _id_lines(np.unique(cells)),
                    f"*SURFACE, NAME=S_{up}, TYPE=ELEMENT\n",
                    "".join(f"{c}, S{s}\n" for c, s in zip(cells.tolist(), ABAQUS_FACE[patches.faces[m]].tolist()))]
    if irregular_edges is not None and len(irregular_edges):
        out += ["*NSET, NSET=IRREGULAR_EDGES\n", _id_lines(np.unique(irregular_edges) + 1)]
    write_text(path, "".join(out))


EXODUS_SIDE = np.array([5, 6, 1, 2, 3, 4])
"""The Exodus II HEX8 side number of each of quality.HEX_FACES: side 1 =
nodes 1-2-6-5, 2 = 2-3-7-6, 3 = 3-4-8-7, 4 = 1-5-8-4, 5 = 1-4-3-2,
6 = 5-6-7-8 (1-based)."""


def write_hex_exodus(path: str, vertices: np.ndarray, hexes: np.ndarray, patches=None,
                     irregular_edges=None, title: str = "SymFrames hex mesh") -> None:
    """Exodus II (module docs); patches: a hexmesh.patches.BoundaryPatches
    or None (the hexahedra alone)."""
    from scipy.io import netcdf_file

    V = np.asarray(vertices, float)
    H = np.asarray(hexes, np.int64)
    sides = []
    if patches is not None:
        for i, name in enumerate(patches.names, start=1):
            m = patches.patch == i
            if np.any(m):
                sides.append((i, name, patches.cells[m] + 1, EXODUS_SIDE[patches.faces[m]]))
    nodes = [] if irregular_edges is None or not len(irregular_edges) else [np.unique(irregular_edges) + 1]

    def chars(names, width=33):
        a = np.zeros((len(names), width), "S1")
        for k, n in enumerate(names):
            b = n.encode()[: width - 1]
            a[k, : len(b)] = np.frombuffer(b, "S1")
        return a

    def write(out):
        fh = io.BytesIO()  # netcdf_file closes the file it wrote
        nc = netcdf_file(fh, "w", version=2)  # 64-bit offsets: Exodus' "large model" layout
        nc.api_version, nc.version = np.float32(8.03), np.float32(8.03)
        nc.floating_point_word_size, nc.file_size, nc.maximum_name_length = np.int32(8), np.int32(1), np.int32(32)
        nc.int64_status, nc.title = np.int32(0), title
        dims = {"time_step": None, "len_string": 33, "len_line": 81, "four": 4, "len_name": 33, "num_dim": 3,
                "num_nodes": len(V), "num_elem": len(H), "num_el_blk": 1, "num_el_in_blk1": len(H),
                "num_nod_per_el1": 8}
        if sides:
            dims["num_side_sets"] = len(sides)
            dims.update({f"num_side_ss{k}": len(c) for k, (_, _, c, _) in enumerate(sides, start=1)})
        if nodes:
            dims.update({"num_node_sets": 1, "num_nod_ns1": len(nodes[0])})
        for d, n in dims.items():
            nc.createDimension(d, n)

        def var(key, dtype, shape, data, **attrs):
            v = nc.createVariable(key, dtype, shape)
            v[:] = data
            for a, x in attrs.items():
                setattr(v, a, x)

        var("time_whole", "d", ("time_step",), np.zeros(0))
        var("coor_names", "c", ("num_dim", "len_name"), chars(["x", "y", "z"]))
        for k, axis in enumerate("xyz"):
            var(f"coord{axis}", "d", ("num_nodes",), V[:, k])
        var("eb_names", "c", ("num_el_blk", "len_name"), chars(["hexahedra"]))
        var("eb_status", "i", ("num_el_blk",), np.ones(1, np.int32))
        var("eb_prop1", "i", ("num_el_blk",), np.ones(1, np.int32), name="ID")
        var("connect1", "i", ("num_el_in_blk1", "num_nod_per_el1"), (H + 1).astype(np.int32), elem_type="HEX8")
        if sides:
            var("ss_names", "c", ("num_side_sets", "len_name"), chars([n for _, n, _, _ in sides]))
            var("ss_status", "i", ("num_side_sets",), np.ones(len(sides), np.int32))
            var("ss_prop1", "i", ("num_side_sets",), np.array([i for i, _, _, _ in sides], np.int32), name="ID")
            for k, (_, _, c, f) in enumerate(sides, start=1):
                var(f"elem_ss{k}", "i", (f"num_side_ss{k}",), c.astype(np.int32))
                var(f"side_ss{k}", "i", (f"num_side_ss{k}",), f.astype(np.int32))
        if nodes:
            var("ns_names", "c", ("num_node_sets", "len_name"), chars(["irregular_edges"]))
            var("ns_status", "i", ("num_node_sets",), np.ones(1, np.int32))
            var("ns_prop1", "i", ("num_node_sets",), np.ones(1, np.int32), name="ID")
            var("node_ns1", "i", ("num_nod_ns1",), nodes[0].astype(np.int32))
        nc.flush()
        out.write(fh.getvalue())
        nc.close()

    write_files({path: write})
