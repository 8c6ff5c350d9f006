"""The arrays a stored field keeps for hex meshing (``hex_source_arrays``)
read back and checked, whatever holds them: a result ``.npz``
(io.load_hex_input), the add-on's .blend, a caller's dict
(``input_from_arrays``).

Each array's dtype and shape are checked before its data are used (a
``.npz`` member's header before its data are read, so an unused member is
never read), then its values: finite coordinates, whole-number indices
within their mesh, offsets that split their array, frames that are
rotations, an omega per tet edge that carries them (``field_fault``).
Whatever is wrong is a ``ReadError`` naming the source, the array and the
value; nothing reaches the hex stages unchecked.
"""

from __future__ import annotations

import json

import numpy as np

from ..errors import NetworkError, OptionsError, ReadError


def _split(flat, off) -> list:
    return [flat[a:b] for a, b in zip(off[:-1], off[1:])]


class ArraySource:
    """Named arrays, each checked as it is taken (module docs).  Subclasses
    give ``_header(key)`` -> (shape, dtype, size in bytes or None), or None
    when absent, and ``_data(key)`` -> the array."""

    def __init__(self, label: str, fix: str):
        self.label, self.fix = label, fix

    def fail(self, what: str) -> ReadError:
        return ReadError(f"{self.label}: {what}; {self.fix}")

    def _header(self, key: str):
        raise NotImplementedError

    def _data(self, key: str) -> np.ndarray:
        raise NotImplementedError

    def array(self, key: str, kinds: str, shape: tuple, optional: bool = False):
        """Array ``key`` whose dtype kind is one of ``kinds`` ('f' float,
        'i'/'u' integer, 'b' boolean, 'U' text) and whose shape matches
        ``shape`` (None: any length there), its floats finite; None when
        optional and absent."""
        head = self._header(key)
        if head is None:
            if optional:
                return None
            raise self.fail(f"the array '{key}' is missing (not a SymFrames result, or one written before hex "
                            "meshing could read it back)")
        got, dtype, size = head
        empty = int(np.prod(got)) == 0 and len(shape) > 0 and shape[0] in (None, 0) and \
            all(s is not None for s in shape[1:])
        if empty and tuple(got) != (0, *shape[1:]):
            # an empty array may come back flat from a store (the add-on's .blend): no values, any shape
            return np.zeros((0, *shape[1:]), {"f": float, "b": bool}.get(kinds[0], np.int64))
        self._check_header(key, got, dtype, kinds, shape)
        if size is not None and int(np.prod(got, dtype=np.float64)) * dtype.itemsize > size:
            raise self.fail(f"the array '{key}' claims {got} values of {dtype}, more than its {size:,} bytes hold "
                            "(a damaged file)")
        try:
            a = self._data(key)
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



_PER_CURVE = ("tets", "faces", "points", "tangents", "polyline", "curve_points")


class DictSource(ArraySource):
    """Arrays given as a mapping (``input_from_arrays``, the add-on's .blend)."""

    def __init__(self, label: str, arrays, fix: str = "give the arrays hex_source_arrays(HexInput) returned for "
                 "this field"):
        super().__init__(label, fix)
        if not hasattr(arrays, "keys") or not hasattr(arrays, "__getitem__"):
            from ..checks import describe

            raise self.fail(f"arrays = {describe(arrays)}: must be a dict of named arrays")
        self.arrays = arrays

    def _header(self, key: str):
        if key not in self.arrays or self.arrays[key] is None:
            return None
        try:
            a = np.asarray(self.arrays[key])
        except (ValueError, TypeError) as e:
            raise self.fail(f"the array '{key}' is not an array ({e})") from None
        return a.shape, a.dtype, None

    def _data(self, key: str) -> np.ndarray:
        return np.asarray(self.arrays[key])


def read_hex_input(z: ArraySource):
    """The HexInput of a source's arrays, every one checked (module docs)."""
    from ..mesh.tetmesh import TetMesh
    from ..surface.trisurface import TriSurface
    from .source import HexInput, field_fault

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


def _meta(z: ArraySource) -> dict:
    m = z.array("hex_meta", "U", ())
    try:
        meta = json.loads(str(m))
    except ValueError as e:
        raise z.fail(f"the array 'hex_meta' is not JSON ({e})") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("curves"), list) or \
            not isinstance(meta.get("nodes"), list):
        raise z.fail("the array 'hex_meta' lacks its 'curves' and 'nodes' lists")
    return meta


def _entry(z: ArraySource, what: str, d, keys: dict):
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


def _network(z: ArraySource, mesh, meta: dict):
    """The prepared network and its embedding, checked against the mesh and
    each other."""
    from ..mesh.embed import Embedding
    from ..network.network import PreparedNetwork

    curves, traces, ends = _curves(z, mesh, meta)
    nodes = _nodes(z, meta, ends)
    nn = len(nodes)
    region, roff = z.parts("node_region", nn, "iuf", (), mesh.n_tets, "tet ids")
    node_tets = z.indices("hex_node_tets", mesh.n_tets, "tet ids", (nn,))
    net = PreparedNetwork(curves, [c["source"] for c in meta["curves"]], [c["start"] for c in meta["curves"]],
                          [c["end"] for c in meta["curves"]], nodes)
    emb = Embedding(traces, node_tets, _split(region, roff), np.zeros((mesh.n_faces, 3)),
                    np.zeros(mesh.n_faces, bool), np.zeros(mesh.n_faces, np.int64))
    return net, emb


_KINDS = ("boundary", "node", "loop")


def _curves(z: ArraySource, mesh, meta: dict):
    """(curves, traces, the kind of each curve end) of the hex data."""
    from ..mesh.embed import CurveTrace
    from ..network.network import Curve

    nc = len(meta["curves"])
    parts = {}
    for key in _PER_CURVE:
        n, what = {"tets": (mesh.n_tets, "tet ids"), "faces": (mesh.n_faces, "face ids")}.get(key, (None, ""))
        flat, off = z.parts(key, nc, "f", () if n is not None else (3,), n, what)
        parts[key] = _split(flat, off)
    ends = z.indices("hex_ends", mesh.n_faces, "boundary face ids (or -1)", (nc, 2), low=-1)
    curves, traces, kinds = [], [], []
    for i, c in enumerate(meta["curves"]):
        sigma, role, name, _, k0, k1, closed = _entry(z, f"curve {i}", c, {
            "sigma": (float, int), "role": (str,), "name": (str, type(None)), "source": (int,), "start": (str,),
            "end": (str,), "closed": (bool,)})
        if k0 not in _KINDS or k1 not in _KINDS:
            raise z.fail(f"'hex_meta' curve {i}: its ends are {k0!r}, {k1!r}, not of {_KINDS}")
        for end, kind in ((0, k0), (1, k1)):
            if (kind == "boundary") != (ends[i, end] >= 0):
                raise z.fail(f"curve {i}: its {('start', 'end')[end]} is a {kind} end, but 'hex_ends' gives it the "
                             f"boundary face {ends[i, end]} (-1: none)")
        n_faces = len(parts["faces"][i])
        if len(parts["tangents"][i]) != n_faces or len(parts["points"][i]) != n_faces:
            raise z.fail(f"curve {i}: {n_faces} pierced faces but {len(parts['points'][i])} pierce points and "
                         f"{len(parts['tangents'][i])} tangents in 'hex_faces' / 'hex_points' / 'hex_tangents'")
        try:
            curves.append(Curve(parts["curve_points"][i], sigma, role, name=name, closed=closed))
        except NetworkError as e:
            raise z.fail(f"'hex_meta' curve {i}: {e}") from None
        traces.append(CurveTrace(parts["tets"][i], parts["faces"][i], parts["tangents"][i], parts["points"][i],
                                 int(ends[i, 0]), int(ends[i, 1]), parts["polyline"][i]))
        kinds.append((k0, k1))
    return curves, traces, kinds


def _nodes(z: ArraySource, meta: dict, kinds: list) -> list:
    """The nodes of the hex data; every curve end of kind 'node' at exactly
    one node, and no other end."""
    from ..network.network import Node

    nc, nodes, seen = len(kinds), [], {}
    for j, nd in enumerate(meta["nodes"]):
        pos, e = _entry(z, f"node {j}", nd, {"position": (list,), "ends": (list,)})
        P, E = np.asarray(pos, dtype=object), np.asarray(e, dtype=object)
        if P.shape != (3,) or not all(isinstance(x, (int, float)) and np.isfinite(x) for x in pos) or \
                E.ndim != 2 or E.shape[1:] != (2,) or not all(isinstance(x, int) for x in E.ravel()) or \
                np.any(E[:, 0].astype(np.int64) >= nc) or np.any(E.astype(np.int64) < 0) or \
                np.any(E[:, 1].astype(np.int64) > 1):
            raise z.fail(f"'hex_meta' node {j} is {str(nd)[:80]}: a node has a position [x, y, z] and ends "
                         f"[[curve 0..{nc - 1}, 0 or 1], ...]")
        for a, b in e:
            if kinds[a][b] != "node" or (a, b) in seen:
                why = f"also at node {seen[(a, b)]}" if (a, b) in seen else f"a {kinds[a][b]} end"
                raise z.fail(f"'hex_meta' node {j} holds the {('start', 'end')[b]} of curve {a}, which is {why}")
            seen[(a, b)] = j
        nodes.append(Node(np.asarray(pos, float), [(int(a), int(b)) for a, b in e]))
    loose = [(a, b) for a in range(nc) for b in (0, 1) if kinds[a][b] == "node" and (a, b) not in seen]
    if loose:
        a, b = loose[0]
        raise z.fail(f"'hex_meta' curve {a}: its {('start', 'end')[b]} is a node end, but no node holds it")
    return nodes


def _given(z: ArraySource, meta: dict):
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


def _status(z: ArraySource, meta: dict) -> str:
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


def _shown(x) -> str:
    from ..checks import describe

    return describe(x) if not hasattr(x, "__dict__") else f"a {type(x).__name__}"


def input_from_arrays(mesh, frames: np.ndarray, omega: np.ndarray, arrays: dict):
    """The HexInput of a stored field, every array checked (arrays.py).

    Parameters
    ----------
    mesh : TetMesh
        the field's tet mesh, with the solve's exact vertex positions
    frames : (#V, 3, 3) float array
    omega : (#E, 3) float array
    arrays : dict
        what ``hex_source_arrays`` returned for this field

    Returns
    -------
    HexInput

    Raises
    ------
    ReadError
        an array missing, of the wrong type, shape or range, frames that are
        not rotations or an omega that does not carry them (named)
    """
    from ..mesh.tetmesh import TetMesh

    if not isinstance(mesh, TetMesh):
        raise OptionsError(f"input_from_arrays: mesh = {_shown(mesh)}: must be a TetMesh (the field's tet mesh)")
    src = DictSource("input_from_arrays", arrays)
    src.arrays = {**arrays, "vertices": mesh.vertices, "tets": mesh.tets, "frames": frames, "omega": omega}
    return read_hex_input(src)
