"""A stored result read back for hex meshing (``--from-result``), checked
like every other reader.

``load_hex_input(path)`` opens the ``.npz`` as a zip archive and reads only
the arrays hex meshing needs (an unused member, however large, is never
read).  Each array's header (dtype and shape) is checked before its data
are read, then its values: finite coordinates, whole-number indices within
their mesh, offsets that split their array, frames that are rotations and
an omega per tet edge.  Whatever is wrong is a ``ReadError`` naming the
file, the array and the value; nothing reaches the hex stages unchecked.
"""

from __future__ import annotations

import json
import os
import zipfile
import zlib

import numpy as np

from ..errors import NetworkError, ReadError

_PER_CURVE = ("tets", "faces", "points", "tangents", "polyline", "curve_points")


def _split(flat, off) -> list:
    return [flat[a:b] for a, b in zip(off[:-1], off[1:])]


class _Archive:
    """The members of an open .npz, read one at a time, header first."""

    def __init__(self, path: str, zf: zipfile.ZipFile):
        self.path, self.zf = path, zf
        self.names = {n[:-4]: n for n in zf.namelist() if n.endswith(".npy")}

    def fail(self, what: str) -> ReadError:
        return ReadError(f"{self.path}: {what}; this file cannot be meshed again: solve the network again to write "
                         "a new result (python -m solver NETWORK.json -o FILE.npz)")

    def array(self, key: str, kinds: str, shape: tuple, optional: bool = False):
        """Member ``key`` as an array whose dtype kind is one of ``kinds``
        ('f' float, 'i'/'u' integer, 'b' boolean, 'U' text) and whose shape
        matches ``shape`` (None: any length there); None when optional and
        absent."""
        if key not in self.names:
            if optional:
                return None
            raise self.fail(f"the array '{key}' is missing (not a SymFrames result, or one written before hex "
                            "meshing could read it back)")
        name = self.names[key]
        try:
            with self.zf.open(name) as fh:
                version = np.lib.format.read_magic(fh)
                read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else \
                    np.lib.format.read_array_header_2_0
                got, _, dtype = read_header(fh)
                self._check_header(key, got, dtype, kinds, shape)
                size = self.zf.getinfo(name).file_size
                if int(np.prod(got, dtype=np.float64)) * dtype.itemsize > size:
                    raise self.fail(f"the array '{key}' claims {got} values of {dtype}, more than its "
                                    f"{size:,} bytes hold (a damaged file)")
            with self.zf.open(name) as fh:
                a = np.lib.format.read_array(fh, allow_pickle=False)
        except ReadError:
            raise
        except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError) as e:
            raise self.fail(f"the array '{key}' is damaged ({type(e).__name__}: {str(e)[:100]})") from None
        except MemoryError:
            raise self.fail(f"the array '{key}' does not fit in memory") from None
        if a.dtype.kind == "f" and not np.isfinite(a).all():
            bad = np.argwhere(~np.isfinite(a))[0]
            raise self.fail(f"the array '{key}' holds {a[tuple(bad)]} at {tuple(int(x) for x in bad)}: every value "
                            "must be a finite number")
        return a

    def _check_header(self, key, got, dtype, kinds, shape) -> None:
        names = {"f": "floats", "i": "integers", "u": "integers", "b": "booleans", "U": "text"}
        if dtype.kind not in kinds:
            want = " or ".join(dict.fromkeys(names[k] for k in kinds))
            raise self.fail(f"the array '{key}' holds {dtype} values, not {want}")
        if len(got) != len(shape) or any(s is not None and s != g for s, g in zip(shape, got)):
            want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
            raise self.fail(f"the array '{key}' has shape {got}, not {want}")

    def indices(self, key: str, n: int, what: str, shape: tuple, low: int = 0):
        """An integer array (floats allowed only when whole) with values in
        [low, n)."""
        a = self.array(key, "iuf", shape)
        if a.dtype.kind == "f":
            whole = (a == np.round(a)).reshape(len(a), int(np.prod(a.shape[1:])))
            frac = np.nonzero(~whole.all(axis=1))[0]
            if len(frac):
                raise self.fail(f"the array '{key}' holds {a[frac[0]].tolist()} at row {frac[0]}: {what} must be whole "
                                "numbers")
        a = a.astype(np.int64)
        out = (a < low) | (a >= n)
        bad = np.nonzero(out.reshape(len(a), int(np.prod(a.shape[1:]))).any(axis=1))[0]
        if len(bad):
            raise self.fail(f"the array '{key}' holds {a[bad[0]].tolist()} at row {bad[0]}: {what} run from {low} "
                            f"to {n - 1}")
        return a

    def parts(self, key: str, count: int, kinds: str, tail: tuple, n: int | None = None, what: str = ""):
        """A flat array and its offsets, split into ``count`` parts."""
        flat = self.indices(f"hex_{key}", n, what, (None, *tail)) if n is not None else \
            self.array(f"hex_{key}", kinds, (None, *tail))
        off = self.indices(f"hex_{key}_offsets", len(flat) + 1, "offsets", (count + 1,))
        if off[0] != 0 or off[-1] != len(flat) or np.any(np.diff(off) < 0):
            raise self.fail(f"the array 'hex_{key}_offsets' = {off.tolist()[:8]} does not split 'hex_{key}' "
                            f"({len(flat)} rows): offsets must rise from 0 to {len(flat)}")
        return flat, off


def _open(path) -> zipfile.ZipFile:
    """The zip archive at path, or a ReadError saying what the file is."""
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        raise ReadError(f"result file {path!r}: must be a file path (a non-empty string)")
    path = os.fspath(path)
    if not os.path.exists(path):
        raise ReadError(f"{path}: no such file; give a result .npz written by a solve (-o FILE.npz)")
    if os.path.isdir(path):
        raise ReadError(f"{path}: is a folder; give a result .npz written by a solve (-o FILE.npz)")
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as fh:
            head = fh.read(4)
        if size == 0:
            raise ReadError(f"{path}: the file is empty (0 bytes); give a result .npz written by a solve")
        if head != b"PK\x03\x04":
            kind = "a single NumPy array (.npy)" if head[:4] == b"\x93NUM" else f"a file starting with {head!r}"
            raise ReadError(f"{path}: not a NumPy .npz archive (it is {kind}); give a result .npz written by a solve")
        return zipfile.ZipFile(path)
    except zipfile.BadZipFile as e:
        raise ReadError(f"{path}: a damaged or truncated .npz archive ({e}: its zip directory, written last, is "
                        f"missing or broken; {size:,} bytes); solve the network again to write a new result") from None
    except OSError as e:
        raise ReadError(f"{path}: cannot be read ({e.strerror or e})") from None


def load_hex_input(path):
    """The field of a saved result, to mesh it again without solving
    (``python -m solver --from-result``), read and checked (module docs).

    Parameters
    ----------
    path : str
        a result ``.npz`` written by ``save_result``

    Returns
    -------
    hexmesh.HexInput
        its ``status`` 'converged' or 'not converged' (the stricter of the
        hex data's and the solve report's)

    Raises
    ------
    ReadError
        naming the file, the array and what is wrong with it
    """
    with _open(path) as zf:
        return _read(_Archive(os.fspath(path), zf))


def _read(z: _Archive):
    from ..hexmesh import HexInput
    from ..hexmesh.source import field_fault
    from ..mesh.tetmesh import TetMesh
    from ..surface.trisurface import TriSurface

    V = z.array("vertices", "f", (None, 3))
    T = z.indices("tets", len(V), "vertex ids", (None, 4))
    rep = np.nonzero((np.sort(T, axis=1)[:, 1:] == np.sort(T, axis=1)[:, :-1]).any(axis=1))[0]
    if len(rep):
        raise z.fail(f"tet {rep[0]} of 'tets' is {T[rep[0]].tolist()}: a tet has four different vertices")
    if len(T) == 0:
        raise z.fail("the array 'tets' is empty: a field needs a tet mesh")
    mesh = TetMesh(V, T)
    stored_edges = z.array("edges", "iuf", (None, 2), optional=True)
    if stored_edges is not None and (stored_edges.shape != mesh.edges.shape or np.any(stored_edges != mesh.edges)):
        raise z.fail(f"the array 'edges' ({len(stored_edges)} rows) is not the edge list of 'tets' "
                     f"({mesh.n_edges} edges): omega would be read on the wrong edges")
    frames = z.array("frames", "f", (len(V), 3, 3))
    omega = z.array("omega", "f", (mesh.n_edges, 3))
    fault = field_fault(mesh, frames, omega)
    if fault:
        raise z.fail(f"the stored field is damaged: {fault}")
    meta = _meta(z)
    net, emb = _network(z, mesh, meta)
    SV = z.array("hex_surface_vertices", "f", (None, 3))
    SF = z.indices("hex_surface_faces", len(SV), "surface vertex ids", (None, 3))
    S = TriSurface(SV, SF)
    sharp = z.array("hex_surface_sharp", "b", (len(S.edges),))
    given = _given(z, meta)
    return HexInput(mesh, omega, frames, emb, net, S, sharp, _status(z, meta), given)


def _meta(z: _Archive) -> dict:
    m = z.array("hex_meta", "U", ())
    try:
        meta = json.loads(str(m))
    except ValueError as e:
        raise z.fail(f"the array 'hex_meta' is not JSON ({e})") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("curves"), list) or \
            not isinstance(meta.get("nodes"), list):
        raise z.fail("the array 'hex_meta' lacks its 'curves' and 'nodes' lists")
    return meta


def _entry(z: _Archive, what: str, d, keys: dict):
    """Fields of one meta entry, each checked against its type."""
    if not isinstance(d, dict):
        raise z.fail(f"'hex_meta' {what} is {str(d)[:60]!r}, not an object")
    out = []
    for key, types in keys.items():
        v = d.get(key)
        if not isinstance(v, types) or isinstance(v, bool) and bool not in types:
            kind = {float: "a number", int: "a whole number", str: "text", bool: "true or false", list: "a list"}
            raise z.fail(f"'hex_meta' {what}: '{key}' = {str(v)[:60]!r} is not {kind[types[0]]}")
        out.append(v)
    return out


def _network(z: _Archive, mesh, meta: dict):
    from ..mesh.embed import CurveTrace, Embedding
    from ..network.network import Curve, Node, PreparedNetwork
    nc = len(meta["curves"])
    parts = {}
    for key in _PER_CURVE:
        n, what = {"tets": (mesh.n_tets, "tet ids"), "faces": (mesh.n_faces, "face ids")}.get(key, (None, ""))
        flat, off = z.parts(key, nc, "f", () if n is not None else (3,), n, what)
        parts[key] = _split(flat, off)
    ends = z.indices("hex_ends", mesh.n_faces, "boundary face ids (or -1)", (nc, 2), low=-1)
    curves, traces, kinds = [], [], ("boundary", "node", "loop")
    for i, c in enumerate(meta["curves"]):
        sigma, role, name, source, k0, k1, closed = _entry(z, f"curve {i}", c, {
            "sigma": (float, int), "role": (str,), "name": (str, type(None)), "source": (int,), "start": (str,),
            "end": (str,), "closed": (bool,)})
        if k0 not in kinds or k1 not in kinds:
            raise z.fail(f"'hex_meta' curve {i}: its ends are {k0!r}, {k1!r}, not of {kinds}")
        if len(parts["tangents"][i]) != len(parts["points"][i]):
            raise z.fail(f"curve {i}: {len(parts['points'][i])} pierce points but {len(parts['tangents'][i])} "
                         "tangents in 'hex_points' / 'hex_tangents'")
        try:
            curves.append(Curve(parts["curve_points"][i], sigma, role, name=name, closed=closed))
        except NetworkError as e:
            raise z.fail(f"'hex_meta' curve {i}: {e}") from None
        traces.append(CurveTrace(parts["tets"][i], parts["faces"][i], parts["tangents"][i], parts["points"][i],
                                 int(ends[i, 0]), int(ends[i, 1]), parts["polyline"][i]))
    nodes = []
    for j, nd in enumerate(meta["nodes"]):
        pos, e = _entry(z, f"node {j}", nd, {"position": (list,), "ends": (list,)})
        P, E = np.asarray(pos, dtype=object), np.asarray(e, dtype=object)
        if P.shape != (3,) or not all(isinstance(x, (int, float)) and np.isfinite(x) for x in pos) or \
                E.ndim != 2 or E.shape[1:] != (2,) or not all(isinstance(x, int) for x in E.ravel()) or \
                np.any(E[:, 0].astype(np.int64) >= nc) or np.any(E.astype(np.int64) < 0) or \
                np.any(E[:, 1].astype(np.int64) > 1):
            raise z.fail(f"'hex_meta' node {j} is {str(nd)[:80]}: a node has a position [x, y, z] and ends "
                         f"[[curve 0..{nc - 1}, 0 or 1], ...]")
        nodes.append(Node(np.asarray(pos, float), [(int(a), int(b)) for a, b in e]))
    nn = len(nodes)
    region, roff = z.parts("node_region", nn, "iuf", (), mesh.n_tets, "tet ids")
    node_tets = z.indices("hex_node_tets", mesh.n_tets, "tet ids", (nn,))
    net = PreparedNetwork(curves, [c["source"] for c in meta["curves"]], [c["start"] for c in meta["curves"]],
                          [c["end"] for c in meta["curves"]], nodes)
    emb = Embedding(traces, node_tets, _split(region, roff), np.zeros((mesh.n_faces, 3)),
                    np.zeros(mesh.n_faces, bool), np.zeros(mesh.n_faces, np.int64))
    return net, emb


def _given(z: _Archive, meta: dict):
    if "given" not in meta:
        return None
    g = meta["given"]
    if not isinstance(g, list):
        raise z.fail("'hex_meta' given is not a list")
    flat, off = z.parts("given_points", len(g), "f", (3,))
    out = []
    for k, (P, d) in enumerate(zip(_split(flat, off), g)):
        sigma, curve, name = _entry(z, f"given curve {k}", d, {"sigma": (float, int), "curve": (int,),
                                                               "name": (str, type(None))})
        out.append((P, float(sigma), curve, name))
    return out


def _status(z: _Archive, meta: dict) -> str:
    """The field's status: 'not converged' if the hex data or the solve's
    report says so."""
    status = meta.get("status", "converged")
    if status not in ("converged", "not converged"):
        raise z.fail(f"'hex_meta' status is {str(status)[:40]!r}, not 'converged' or 'not converged'")
    rep = z.array("report", "U", (), optional=True)
    if rep is not None:
        try:
            d = json.loads(str(rep))
        except ValueError as e:
            raise z.fail(f"the array 'report' is not JSON ({e})") from None
        if isinstance(d, dict) and (d.get("converged") is False or d.get("status") == "not converged"):
            status = "not converged"
    return status
