"""A stored field's arrays (``SolvedField.to_arrays``, field/solved.py)
read back and checked, whatever holds them: a result ``.npz``
(io.load_field), the add-on's .blend, a caller's dict
(``SolvedField.from_arrays``).

Each array's dtype and shape are checked before its data are used (a
``.npz`` member's header before its data are read, so an unused member is
never read), then its values: finite coordinates, whole-number indices
within their mesh, offsets that split their array, frames that are
rotations, an omega per tet edge that carries them (``field_fault``).
Whatever is wrong is a ``ReadError`` naming the source, the array and the
value; nothing reaches the stages after the solve unchecked.
"""

from __future__ import annotations

import json

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import NetworkError, ReadError
from ..linalg.rotations import CUBE_GROUP, closest_symmetry, exp_so3, rotation_angle


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
            raise self.fail(f"the array '{key}' is missing (not a SymFrames result)")
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
        flat = self.indices(key, n, what, (None, *tail)) if n is not None else \
            self.array(key, kinds, (None, *tail))
        off = self.indices(f"{key}_offsets", len(flat) + 1, "offsets", (count + 1,))
        if off[0] != 0 or off[-1] != len(flat) or np.any(np.diff(off) < 0):
            raise self.fail(f"the array '{key}_offsets' = {off.tolist()[:8]} does not split '{key}' "
                            f"({len(flat)} rows): offsets must rise from 0 to {len(flat)}")
        return flat, off



_PER_CURVE = ("curve_tets", "curve_faces", "curve_points", "curve_tangents", "curve_polyline", "network_points")


class DictSource(ArraySource):
    """Arrays given as a mapping (``SolvedField.from_arrays``, the add-on's .blend)."""

    def __init__(self, label: str, arrays, fix: str = "give the arrays SolvedField.to_arrays() returned for "
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


def read_field(z: ArraySource) -> dict:
    """The parts of the SolvedField of a source's arrays (its keyword
    arguments), every one checked (module docs)."""
    from ..mesh.tetmesh import TetMesh
    from ..surface.trisurface import TriSurface

    legacy = z._header("hex_meta") is not None and z._header("meta") is None
    if legacy:
        raise z.fail("it was written by an earlier SymFrames, which kept the field in another layout")
    V = z.array("vertices", "f", (None, 3))
    T = z.indices("tets", len(V), "vertex ids", (None, 4))
    rep = np.nonzero((np.sort(T, axis=1)[:, 1:] == np.sort(T, axis=1)[:, :-1]).any(axis=1))[0]
    if len(rep):
        raise z.fail(f"tet {rep[0]} of 'tets' is {T[rep[0]].tolist()}: a tet has four different vertices")
    if len(T) == 0:
        raise z.fail("the array 'tets' is empty: a field needs a tet mesh")
    mesh = TetMesh(V, T)
    frames = z.array("frames", "f", (len(V), 3, 3))
    omega = z.array("omega", "f", (mesh.n_edges, 3))
    fault = field_fault(mesh, frames, omega)
    if fault:
        raise z.fail(f"the stored field is damaged: {fault}")
    root = z.array("root", "iuf", ())
    if root != np.round(root) or not 0 <= root < len(V):
        raise z.fail(f"the array 'root' is {root}: the root is a vertex id from 0 to {len(V) - 1}")
    root = int(root)
    meta = _meta(z)
    net, emb = _network(z, mesh, meta)
    SV = z.array("surface_vertices", "f", (None, 3))
    SF = z.indices("surface_faces", len(SV), "surface vertex ids", (None, 3))
    S = TriSurface(SV, SF)
    sharp = z.array("surface_sharp", "b", (len(S.edges),))
    # (fields stored before bends were kept have none)
    bends = z.array("surface_bends", "b", (len(S.edges),)) if z._header("surface_bends") is not None else None
    feature = z.array("feature_vertices", "b", (len(V),))
    tube_edges = z.indices("tube_edges", mesh.n_edges, "edge ids", (None,))
    tube_curve = z.indices("tube_curve", max(len(net.curves), 1), "curve ids", (len(tube_edges),))
    given = _given(z, meta)
    return dict(mesh=mesh, frames=frames, omega=omega, embedding=emb, network=net, surface=S, sharp=sharp,
                feature_vertices=feature, tube_edges=tube_edges, tube_curve=tube_curve, root=root,
                status=_status(z, meta), given=given, bends=bends)


def _meta(z: ArraySource) -> dict:
    m = z.array("meta", "U", ())
    try:
        meta = json.loads(str(m))
    except ValueError as e:
        raise z.fail(f"the array 'meta' is not JSON ({e})") from None
    if not isinstance(meta, dict) or not isinstance(meta.get("curves"), list) or \
            not isinstance(meta.get("nodes"), list):
        raise z.fail("the array 'meta' lacks its 'curves' and 'nodes' lists")
    return meta


def _entry(z: ArraySource, what: str, d, keys: dict):
    """Fields of one meta entry, each checked against its type."""
    if not isinstance(d, dict):
        raise z.fail(f"'meta' {what} is {str(d)[:60]!r}, not an object")
    out = []
    for key, types in keys.items():
        v = d.get(key)
        if not isinstance(v, types) or isinstance(v, bool) and bool not in types:
            kind = {float: "a number", int: "a whole number", str: "text", bool: "true or false", list: "a list"}
            raise z.fail(f"'meta' {what}: '{key}' = {str(v)[:60]!r} is not {kind[types[0]]}")
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
    node_tets = z.indices("node_tets", mesh.n_tets, "tet ids", (nn,))
    net = PreparedNetwork(curves, [c["source"] for c in meta["curves"]], [c["start"] for c in meta["curves"]],
                          [c["end"] for c in meta["curves"]], nodes, _pieces(z, meta))
    nf = mesh.n_faces
    face_omega = np.zeros((nf, 3))
    faces = z.indices("omega_faces", nf, "face ids", (None,))
    face_omega[faces] = z.array("omega_values", "f", (len(faces), 3))
    excluded = np.zeros(nf, bool)
    excluded[z.indices("excluded_faces", nf, "face ids", (None,))] = True
    pierce = np.zeros(nf, np.int64)
    pierced = z.indices("pierced_faces", nf, "face ids", (None,))
    pierce[pierced] = z.indices("pierce_counts", 2**62, "pierce counts", (len(pierced),))
    end_faces = z.indices("end_faces", nf, "face ids", (None,))
    end_sigma = z.array("end_sigma", "fi", (len(end_faces),))
    emb = Embedding(traces, node_tets, _split(region, roff), face_omega, excluded, pierce,
                    [(int(f), float(s)) for f, s in zip(end_faces, end_sigma)])
    return net, emb


def _pieces(z: ArraySource, meta: dict) -> dict:
    p = meta.get("pieces", {})
    if not isinstance(p, dict) or not all(isinstance(v, list) and all(isinstance(x, int) for x in v)
                                          for v in p.values()) or not all(k.isdigit() for k in p):
        raise z.fail("'meta' pieces is not a map of curve ids to lists of curve ids")
    return {int(k): v for k, v in p.items()}


_KINDS = ("boundary", "node", "loop")


def _curves(z: ArraySource, mesh, meta: dict):
    """(curves, traces, the kind of each curve end) of the stored field."""
    from ..mesh.embed import CurveTrace
    from ..network.network import Curve

    nc = len(meta["curves"])
    parts = {}
    for key in _PER_CURVE:
        n, what = {"curve_tets": (mesh.n_tets, "tet ids"),
                   "curve_faces": (mesh.n_faces, "face ids")}.get(key, (None, ""))
        flat, off = z.parts(key, nc, "f", () if n is not None else (3,), n, what)
        parts[key] = _split(flat, off)
    ends = z.indices("curve_ends", mesh.n_faces, "boundary face ids (or -1)", (nc, 2), low=-1)
    curves, traces, kinds = [], [], []
    for i, c in enumerate(meta["curves"]):
        sigma, role, name, _, k0, k1, closed = _entry(z, f"curve {i}", c, {
            "sigma": (float, int), "role": (str,), "name": (str, type(None)), "source": (int,), "start": (str,),
            "end": (str,), "closed": (bool,)})
        if k0 not in _KINDS or k1 not in _KINDS:
            raise z.fail(f"'meta' curve {i}: its ends are {k0!r}, {k1!r}, not of {_KINDS}")
        for end, kind in ((0, k0), (1, k1)):
            if (kind == "boundary") != (ends[i, end] >= 0):
                raise z.fail(f"curve {i}: its {('start', 'end')[end]} is a {kind} end, but 'curve_ends' gives it the "
                             f"boundary face {ends[i, end]} (-1: none)")
        n_faces = len(parts["curve_faces"][i])
        if len(parts["curve_tangents"][i]) != n_faces or len(parts["curve_points"][i]) != n_faces:
            raise z.fail(f"curve {i}: {n_faces} pierced faces but {len(parts['curve_points'][i])} pierce points and "
                         f"{len(parts['curve_tangents'][i])} tangents in 'curve_faces' / 'curve_points' / "
                         "'curve_tangents'")
        try:
            curves.append(Curve(parts["network_points"][i], sigma, role, name=name, closed=closed))
        except NetworkError as e:
            raise z.fail(f"'meta' curve {i}: {e}") from None
        traces.append(CurveTrace(parts["curve_tets"][i], parts["curve_faces"][i], parts["curve_tangents"][i],
                                 parts["curve_points"][i], int(ends[i, 0]), int(ends[i, 1]),
                                 parts["curve_polyline"][i]))
        kinds.append((k0, k1))
    _check_walks(z, mesh, traces)
    return curves, traces, kinds


def _check_walks(z: ArraySource, mesh, traces) -> None:
    """Each trace a walk through the mesh: its k-th pierced face lies
    between its k-th and (k+1)-th tets, and a boundary end's face is a
    boundary face of the tet at that end."""
    ft = mesh.face_tets
    for i, t in enumerate(traces):
        T, Fc = np.asarray(t.tets), np.asarray(t.faces)
        n = len(T) - 1
        if len(T) == 0 or len(Fc) < n:
            raise z.fail(f"curve {i} crosses {len(T)} tets but pierces {len(Fc)} faces in 'curve_tets' / "
                         "'curve_faces': a curve's walk pierces a face between each two tets it crosses")
        pair = np.sort(np.c_[T[:-1], T[1:]], axis=1)
        bad = np.nonzero(np.any(np.sort(ft[Fc[:n]], axis=1) != pair, axis=1))[0]
        if len(bad):
            k = bad[0]
            raise z.fail(f"curve {i}: its face {Fc[k]} (step {k} of 'curve_faces') does not lie between the tets "
                         f"{T[k]} and {T[k + 1]} it crosses there: the stored walk is not one through this mesh")
        for end, f, tet in (("start", t.start_face, T[0]), ("end", t.end_face, T[-1])):
            if f >= 0 and not (tet in ft[f] and -1 in ft[f]):
                raise z.fail(f"curve {i}: its {end} face {f} ('curve_ends') is not a boundary face of its {end} "
                             f"tet {tet}")


def _nodes(z: ArraySource, meta: dict, kinds: list) -> list:
    """The nodes of the stored field; every curve end of kind 'node' at exactly
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
            raise z.fail(f"'meta' node {j} is {str(nd)[:80]}: a node has a position [x, y, z] and ends "
                         f"[[curve 0..{nc - 1}, 0 or 1], ...]")
        for a, b in e:
            if kinds[a][b] != "node" or (a, b) in seen:
                why = f"also at node {seen[(a, b)]}" if (a, b) in seen else f"a {kinds[a][b]} end"
                raise z.fail(f"'meta' node {j} holds the {('start', 'end')[b]} of curve {a}, which is {why}")
            seen[(a, b)] = j
        nodes.append(Node(np.asarray(pos, float), [(int(a), int(b)) for a, b in e]))
    loose = [(a, b) for a in range(nc) for b in (0, 1) if kinds[a][b] == "node" and (a, b) not in seen]
    if loose:
        a, b = loose[0]
        raise z.fail(f"'meta' curve {a}: its {('start', 'end')[b]} is a node end, but no node holds it")
    return nodes


def _given(z: ArraySource, meta: dict):
    if "given" not in meta:
        return None
    g = meta["given"]
    if not isinstance(g, list):
        raise z.fail("'meta' given is not a list")
    flat, off = z.parts("given_points", len(g), "f", (3,))
    out = []
    for k, (P, d) in enumerate(zip(_split(flat, off), g)):
        sigma, curve, name = _entry(z, f"given curve {k}", d, {"sigma": (float, int), "curve": (int,),
                                                               "name": (str, type(None))})
        out.append((P, float(sigma), curve, name))
    return out


def _status(z: ArraySource, meta: dict) -> str:
    """The field's status: 'not converged' if the field's meta or the
    solve's report says so."""
    status = meta.get("status", "converged")
    if status not in ("converged", "not converged"):
        raise z.fail(f"'meta' status is {str(status)[:40]!r}, not 'converged' or 'not converged'")
    rep = z.array("report", "U", (), optional=True)
    if rep is not None:
        try:
            d = json.loads(str(rep))
        except ValueError as e:
            raise z.fail(f"the array 'report' is not JSON ({e})") from None
        if isinstance(d, dict) and (d.get("converged") is False or d.get("status") == "not converged"):
            status = "not converged"
    return status


ROTATION_TOL = 1e-6
"""Largest |R^T R - I| entry and |det R - 1| of a field's frame (a solve
gives rotations to about 1e-12)."""
EXACT_DEG = 1e-4
"""A solve develops its frames from omega along a spanning tree of edges
(Eq. 8, §4.3), where omega carries the frame at one end to the other's
exactly (to about 1e-12 degrees; 1e-4 leaves room for float32 storage).
So the edges omega carries within EXACT_DEG connect every vertex, converged
or not, whatever the rest of the field does; a zeroed, scaled or shuffled
omega leaves the mesh in pieces (2,373 of the cylinder's 2,375 vertices
alone, zeroed)."""


def field_fault(mesh, frames, omega) -> str:
    """What is wrong with a field's frames and omega on its mesh, or ''.

    Checks the shapes ((#V, 3, 3) and (#E, 3)), that every value is
    finite, that the frames are rotations (orthonormal, determinant +1,
    within ROTATION_TOL) and that omega carries them exactly along edges
    that connect every vertex (EXACT_DEG)."""
    R, w = np.asarray(frames), np.asarray(omega)
    if R.shape != (mesh.n_vertices, 3, 3) or R.dtype.kind not in "fi":
        return f"frames have shape {R.shape} ({R.dtype}), not ({mesh.n_vertices}, 3, 3) floats: one per vertex"
    if w.shape != (mesh.n_edges, 3) or w.dtype.kind not in "fi":
        return f"omega has shape {w.shape} ({w.dtype}), not ({mesh.n_edges}, 3) floats: one per tet edge"
    for name, a in (("frames", R), ("omega", w)):
        bad = np.argwhere(~np.isfinite(a))
        if len(bad):
            return f"{name} hold {a[tuple(bad[0])]} at {tuple(int(x) for x in bad[0])}: values must be finite"
    off = np.abs(np.einsum("nki,nkj->nij", R, R) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(R)
    bad = np.nonzero((off > ROTATION_TOL) | (np.abs(det - 1) > ROTATION_TOL))[0]
    if len(bad):
        k = bad[0]
        return (f"{len(bad):,} of the {len(R):,} frames are not rotations, e.g. frame {k} (|R^T R - I| = "
                f"{off[k]:.3g}, det {det[k]:.4g}); a frame has orthonormal columns and determinant +1")
    E = mesh.edges
    miss = np.empty(len(E))
    for a in range(0, len(E), 100_000):  # in chunks: closest_symmetry holds 24 traces per edge
        e = E[a:a + 100_000]
        carried = exp_so3(w[a:a + 100_000]) @ R[e[:, 0]]
        M = np.einsum("nji,njk->nik", carried, R[e[:, 1]])
        miss[a:a + len(e)] = np.degrees(rotation_angle(M @ CUBE_GROUP[closest_symmetry(M)]))
    exact = miss < EXACT_DEG
    graph = sp.coo_matrix((np.ones(int(exact.sum())), (E[exact, 0], E[exact, 1])), shape=(len(R), len(R)))
    pieces = connected_components(graph, directed=False)[0]
    if pieces > 1:
        return (f"omega does not carry the frames across their edges: a solve develops the frames from omega along "
                f"a spanning tree, where omega carries them exactly, but here the edges it carries (within "
                f"{EXACT_DEG:g} degrees) leave the mesh in {pieces:,} pieces (median miss {np.median(miss):.3g} "
                "degrees); omega and the frames are not one field (Eq. 8)")
    return ""
