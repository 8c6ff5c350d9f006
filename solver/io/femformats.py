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
``write_hex_nastran``  Nastran bulk data: ``GRID*``, ``CHEXA`` in a
                   ``PSOLID``, per patch its boundary ``CQUAD4`` in a
                   ``PSHELL`` of its own (no stiffness), the irregular
                   edges as ``PLOTEL``
``write_hex_med``  MED (HDF5, written with h5py): ``HE8`` cells in the
                   group ``volume``, per patch its boundary ``QU4`` in a
                   family and group named as the patch, the irregular
                   edges as ``SE2`` in a group per valence

Corner order: Gmsh's 8-node hexahedron, Exodus' HEX8, Abaqus' C3D8 and Nastran's
CHEXA all number the corners as VTK does (one face, then the opposite one,
counter-clockwise seen from outside the first), so cells are written as
SymFrames holds them; MED's HEXA8 runs the other way round both faces
(``MED_HEXA8``).  Every file is written whole or not at all (atomic.py).
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


def _nastran_reals(x: np.ndarray, path: str) -> np.ndarray:
    """Coordinates as Nastran large-field reals: 16 characters, 10
    significant digits ('%.9E'); a value below 1e-99 in size is 0 and one of
    1e100 or more is refused (it would not fit)."""
    from ..errors import OutputError

    x = np.where(np.abs(x) < 1e-99, 0.0, x)
    if np.any(np.abs(x) >= 1e100):
        raise OutputError(f"{path}: a coordinate of {np.abs(x).max():.3g} does not fit a Nastran field of 16 "
                          "characters; scale the mesh")
    return x


NASTRAN_SOLID_PID = 1
"""The PSOLID of the hexahedra."""
NASTRAN_PATCH_PID = 100
"""Patch k's boundary quads have the PSHELL ``NASTRAN_PATCH_PID + k``."""


def write_hex_nastran(path: str, vertices: np.ndarray, hexes: np.ndarray, patches=None, irregular_edges=None,
                      irregular_valence=None, title: str = "SymFrames hex mesh") -> None:
    """Nastran bulk data (``.bdf``, ``.nas``) between ``BEGIN BULK`` and
    ``ENDDATA``: the nodes as large-field ``GRID*`` (16 columns, 10
    significant digits), the hexahedra as ``CHEXA`` (small fields, one
    continuation; VTK's corner order, which CHEXA shares) with ``PSOLID``
    ``NASTRAN_SOLID_PID`` and a placeholder ``MAT1`` 1 (E = 1, nu = 0.3:
    set the material), and per patch k its boundary quads as ``CQUAD4``
    (outward) with their own ``PSHELL`` ``NASTRAN_PATCH_PID + k`` (T = 1)
    and no material: MID1 and MID2 blank give no membrane and no bending
    stiffness (a comment names each patch);
    Gmsh reads each property id as an entity, meshio as ``nastran:ref``.
    The irregular edges are ``PLOTEL`` (plot elements, no stiffness), a
    comment naming the element ids of each valence.  Element ids: hexahedra
    1..m, then the quads, then the edges.  Ids past 99,999,999 (8
    columns) are refused."""
    from ..errors import OutputError

    V = _nastran_reals(np.asarray(vertices, float), path)
    H = np.asarray(hexes, np.int64)
    quads, names, edges = _groups(patches, irregular_edges, irregular_valence)
    n_el = len(H) + sum(len(q) for q in quads.values()) + sum(len(e) for e in edges.values())
    if max(len(V), n_el) > 99_999_999:
        raise OutputError(f"{path}: {max(len(V), n_el):,} nodes or elements: Nastran's 8-column ids stop at "
                          "99,999,999; write .msh or .exo")
    head = [f"$ {title.replace(chr(10), ' ')[:70]}\n", f"$ {len(V):,} GRID*, {len(H):,} CHEXA"
            + (f", {sum(len(q) for q in quads.values()):,} boundary CQUAD4" if quads else "") + "\n",
            "$ Nastran bulk data: add the executive and case control decks\n",
            f"$ PSOLID {NASTRAN_SOLID_PID}: the hexahedra; MAT1 1: a placeholder (set E, nu)\n",
            "$ PSHELL: the boundary quads of a patch (outward; no material, no stiffness)\n"]
    head += [f"$ PSHELL {NASTRAN_PATCH_PID + i}: {n[:60]}\n" for i, n in names.items()]
    out = head + ["BEGIN BULK\n", f"MAT1    {1:>8d}{'1.0':>8s}{'':8s}{'0.3':>8s}\n",
                  f"PSOLID  {NASTRAN_SOLID_PID:>8d}{1:>8d}\n"]
    out += [f"PSHELL  {NASTRAN_PATCH_PID + i:>8d}{'':8s}{'1.0':>8s}\n" for i in names]  # MID1, MID2 blank
    ids = np.arange(1, len(V) + 1)
    out.append(("GRID*   %16d%16s%16.9E%16.9E\n*       %16.9E\n" * len(V))
               % tuple(x for row in zip(ids.tolist(), [""] * len(V), *V.T.tolist()) for x in row))
    eid = 1
    out.append(("CHEXA   " + "%8d" * 8 + "+\n+       %8d%8d\n") * len(H)
               % tuple(np.c_[np.arange(eid, eid + len(H)), np.full(len(H), NASTRAN_SOLID_PID), H + 1]
                       .reshape(-1).tolist()))
    eid += len(H)
    for i, q in quads.items():
        out.append(("CQUAD4  " + "%8d" * 6 + "\n") * len(q)
                   % tuple(np.c_[np.arange(eid, eid + len(q)), np.full(len(q), NASTRAN_PATCH_PID + i), q + 1]
                           .reshape(-1).tolist()))
        eid += len(q)
    for v, e in edges.items():
        out.append(f"$ irregular edges of valence {v}: PLOTEL {eid} to {eid + len(e) - 1}\n")
        out.append(("PLOTEL  %8d%8d%8d\n" * len(e)) % tuple(np.c_[np.arange(eid, eid + len(e)), e + 1]
                                                           .reshape(-1).tolist()))
        eid += len(e)
    out.append("ENDDATA\n")
    write_text(path, "".join(out))


MED_HEXA8 = np.array([0, 3, 2, 1, 4, 7, 6, 5])
"""MED's HEXA8 corners as VTK corners: MED corner k is VTK corner
``MED_HEXA8[k]`` (and back: the map is its own inverse).  MED numbers the
first face 1-2-3-4 with its normal out of the cell, VTK the other way
(Gmsh's GModelIO_MED.cpp, ``med2mshNodeIndex``; Gmsh numbers hexahedra as
VTK does).  QUAD4 and SEG2 corners are the same in both."""


def write_hex_med(path: str, vertices: np.ndarray, hexes: np.ndarray, patches=None, irregular_edges=None,
                  irregular_valence=None, mesh_name: str = "symframes") -> None:
    """MED (``.med``, HDF5: Salome, Code_Aster), MED 3.0 layout: one
    unstructured 3D mesh of ``HE8`` cells (MED's corner order,
    ``MED_HEXA8``) in family -1 with the group ``volume``, per patch k its
    boundary quads as ``QU4`` (outward) in family -(k + 1) with a group
    named as the patch (``patch_1``, ...), and the irregular edges as
    ``SE2`` in a family and group per valence (``irregular_valence_3``,
    ...), as Gmsh's .msh has them.  Written with h5py (HDF5 1.8 file format,
    which older MED libraries read); raises OutputError when h5py is not
    installed."""
    from ..errors import OutputError

    try:
        import h5py
    except ImportError:
        raise OutputError(f"{path}: MED files are HDF5, written with h5py, which is not installed (pip install "
                          "h5py); write .msh or .exo instead, or convert one with Gmsh") from None
    V = np.asarray(vertices, float)
    H = np.asarray(hexes, np.int64)
    quads, names, edges = _groups(patches, irregular_edges, irregular_valence)
    families = [(-1, "volume", "HE8", H[:, MED_HEXA8])]
    families += [(-1 - i, names[i], "QU4", q) for i, q in quads.items()]
    families += [(-1 - len(names) - k, f"irregular_valence_{v}", "SE2", e)
                 for k, (v, e) in enumerate(edges.items(), start=1)]

    def name80(s: str, size: int) -> np.ndarray:
        b = s.encode()[:size]
        return np.frombuffer(b + b"\0" * (size - len(b)), np.int8)

    def write(out):
        fh = io.BytesIO()
        with h5py.File(fh, "w", libver=("earliest", "v108")) as f:
            info = f.create_group("INFOS_GENERALES")
            for k, v in (("MAJ", 3), ("MIN", 0), ("REL", 0)):
                info.attrs.create(k, v, dtype=np.int32)
            mesh = f.create_group("ENS_MAA").create_group(mesh_name)
            for k, v in (("DIM", 3), ("ESP", 3), ("REP", 0), ("SRT", 1), ("TYP", 0)):
                mesh.attrs.create(k, v, dtype=np.int32)
            mesh.attrs.create("UNT", np.bytes_(""))
            mesh.attrs.create("UNI", np.bytes_(""))
            mesh.attrs.create("NOM", np.bytes_("".join(f"{c:<16}" for c in "XYZ")))
            mesh.attrs.create("DES", np.bytes_("SymFrames hex mesh"))
            step = mesh.create_group("-0000000000000000001-0000000000000000001")  # no time step, no iteration
            for k, v in (("CGT", 1), ("NDT", -1), ("NOR", -1)):
                step.attrs.create(k, v, dtype=np.int32)
            step.attrs.create("PDT", -1.0)

            def entity(group, data, fam, key):
                group.attrs.create("CGT", 1, dtype=np.int32)
                group.attrs.create("CGS", 1, dtype=np.int32)
                group.attrs.create("PFL", np.bytes_("MED_NO_PROFILE_INTERNAL"))
                for name, a in ((key, data), ("FAM", fam)):
                    d = group.create_dataset(name, data=a)
                    d.attrs.create("CGT", 1, dtype=np.int32)
                    d.attrs.create("NBR", len(fam), dtype=np.int32)

            # MED stores component by component (no interlace)
            entity(step.create_group("NOE"), V.reshape(-1, order="F"), np.zeros(len(V), np.int32), "COO")
            cells = step.create_group("MAI")
            cells.attrs.create("CGT", 1, dtype=np.int32)
            by_type: dict = {}
            for num, _, typ, conn in families:
                by_type.setdefault(typ, []).append((num, conn))
            for typ, blocks in by_type.items():
                conn = np.concatenate([c for _, c in blocks])
                fam = np.concatenate([np.full(len(c), num, np.int32) for num, c in blocks])
                entity(cells.create_group(typ), (conn + 1).astype(np.int32).reshape(-1, order="F"), fam, "NOD")
            fas = f.create_group("FAS").create_group(mesh_name)
            fas.create_group("FAMILLE_ZERO").attrs.create("NUM", 0, dtype=np.int32)
            eleme = fas.create_group("ELEME")
            for num, group, _, _ in families:
                fam = eleme.create_group(f"FAM_{num}_{group}"[:64])
                fam.attrs.create("NUM", num, dtype=np.int32)
                gro = fam.create_group("GRO")
                gro.attrs.create("NBR", 1, dtype=np.int32)
                nom = gro.create_dataset("NOM", (1,), dtype="80int8")  # an array of 80 characters per group
                nom[0] = name80(group, 80)
        out.write(fh.getvalue())

    write_files({path: write})
