"""A solved field as one value: ``SolvedField``.

Everything downstream of the solve -- hex meshing, the exports, the
measures of a field, streamlines, the add-on's stored field -- takes a
``SolvedField``: the tet mesh with its vertex frames and omega, the network
as the solve traced it through that mesh (the complete embedding and the
prepared curves and nodes), the input surface with its sharp edges, the
boundary's sharp-feature vertices, the curve-tube edges that carry the
tangent constraints, the root of the development and the status.

One layout stores it, in full precision: ``to_arrays()`` gives named numpy
arrays (a result ``.npz`` writes them as they are, the add-on's ``.blend``
keeps them in an ID-property group) and ``SolvedField.from_arrays`` reads
them back, every array checked (field/arrays.py), so
``SolvedField.from_arrays(f.to_arrays()) == f``.

The arrays (flat per-curve data come with ``<name>_offsets``):

=========================  ==================================================
``vertices``, ``tets``     the tet mesh
``frames``, ``omega``      (#V, 3, 3) vertex frames, (#E, 3) omega on
                           ``TetMesh.edges`` (Eq. 8)
``root``                   the vertex the frames were developed from (§4.3)
``curve_tets``             per prepared curve, the tets it crosses ...
``curve_faces``            ... the faces it pierces, with ``curve_points``
                           and ``curve_tangents`` at each pierce
``curve_polyline``         the polyline traced
``curve_ends``             (#curves, 2) boundary face of each end, -1 if none
``network_points``         the prepared curves' points
``node_tets``              (#nodes,) tet holding each node
``node_region``            per node, the tets without a structure equation
``omega_faces``            faces with a prescribed Omega_f (Eq. 17) and ...
``omega_values``           ... its value there (zero elsewhere)
``excluded_faces``         faces left out of R(omega) (Eq. 19)
``pierced_faces``          faces curves cross, and ``pierce_counts`` how often
``end_faces``              (k,) boundary faces where curves end, and
                           ``end_sigma`` their index
``tube_edges``             edges carrying a curve's tangent constraint, and
                           ``tube_curve`` which curve's
``feature_vertices``       (#V,) bool: boundary vertices on sharp features
``surface_vertices``,      the input surface, and ``surface_sharp`` its
``surface_faces``          sharp edges
``surface_bends``          creases of the input surface made smooth bends
                           (corners.py; optional, none where absent)
``given_points``           the singular curves as the user gave them
``meta``                   JSON: the curves' sigma, role, name, ends; the
                           nodes; the status; the given curves' ids
=========================  ==================================================
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np

from ..errors import OptionsError
from ..mesh.embed import Embedding
from ..mesh.tetmesh import TetMesh
from ..network.network import PreparedNetwork
from ..surface.trisurface import TriSurface
from .arrays import DictSource, field_fault, read_field

__all__ = ["SolvedField", "as_field", "field_fault", "flat_parts"]

STATUSES = ("converged", "not converged")


@dataclass(frozen=True, eq=False)
class SolvedField:
    """A solved cross field and what it was solved for (module docs).

    Attributes
    ----------
    mesh : TetMesh
        the field's tet mesh
    frames : (#V, 3, 3) float array
        the vertex frames, columns the cross axes
    omega : (#E, 3) float array
        the Darboux derivative on ``mesh.edges`` (Eq. 8)
    embedding : mesh.embed.Embedding
        the curves traced through the mesh: pierced faces, node regions,
        the prescribed Omega_f and the faces left out of R(omega)
    network : network.network.PreparedNetwork
        the curves and nodes the embedding traced
    surface : TriSurface
        the input surface (the boundary's position, the Hausdorff distance)
    sharp : (#surface edges,) bool array
        the surface's sharp edges
    feature_vertices : (#V,) bool array
        boundary vertices on sharp features (their frames are fixed there)
    tube_edges : (k,) int array
        edges carrying a curve's tangent constraint (§4.2) ...
    tube_curve : (k,) int array
        ... and the prepared curve each belongs to
    root : int
        the vertex the frames were developed from (§4.3)
    status : str
        'converged' or 'not converged'
    given : list or None
        the singular curves as the user gave them, before the intake
        repaired them: (points (n, 3), sigma, curve id, name) each; None
        where unknown (the repaired curves are then taken)
    bends : (#surface edges,) bool array or None
        creases of the input surface the corner quantisation made smooth
        bends (surface/corners.py), which the hex boundary still follows;
        None: none
    """

    mesh: TetMesh
    frames: np.ndarray
    omega: np.ndarray
    embedding: Embedding
    network: PreparedNetwork
    surface: TriSurface
    sharp: np.ndarray
    feature_vertices: np.ndarray
    tube_edges: np.ndarray
    tube_curve: np.ndarray
    root: int = 0
    status: str = "converged"
    given: list | None = None
    bends: np.ndarray | None = None

    def __post_init__(self):
        """Each part of the type and size the others say (cheap checks: the
        frames and omega themselves are checked by ``field_fault``)."""
        for name, cls in (("mesh", TetMesh), ("embedding", Embedding), ("network", PreparedNetwork),
                          ("surface", TriSurface)):
            if not isinstance(getattr(self, name), cls):
                raise OptionsError(f"SolvedField: its {name} is {_shown(getattr(self, name))}, not a "
                                   f"{cls.__name__} (Result.field or io.load_field(path) make a whole one)")
        nv, ne = self.mesh.n_vertices, self.mesh.n_edges
        for name, shape, kinds in (("frames", (nv, 3, 3), "fi"), ("omega", (ne, 3), "fi"),
                                   ("sharp", (len(self.surface.edges),), "b"), ("feature_vertices", (nv,), "b"),
                                   ("tube_edges", None, "iu"), ("tube_curve", None, "iu")):
            a = getattr(self, name)
            if not isinstance(a, np.ndarray) or a.dtype.kind not in kinds or \
                    (a.shape != shape if shape else a.ndim != 1):
                want = f"shape {shape}" if shape else "one dimension"
                raise OptionsError(f"SolvedField: its {name} is {_shown(a)}, not an array of {want} "
                                   f"({'booleans' if kinds == 'b' else 'numbers'})")
        if self.tube_curve.shape != self.tube_edges.shape:
            raise OptionsError(f"SolvedField: {len(self.tube_edges)} tube edges but {len(self.tube_curve)} curve ids")
        if len(self.embedding.traces) != len(self.network.curves):
            raise OptionsError(f"SolvedField: its embedding traces {len(self.embedding.traces)} curves, its network "
                               f"has {len(self.network.curves)}")
        if isinstance(self.root, bool) or not isinstance(self.root, (int, np.integer)) or \
                not 0 <= self.root < nv:
            raise OptionsError(f"SolvedField: its root is {_shown(self.root)}, not a vertex id from 0 to {nv - 1}")
        if self.status not in STATUSES:
            raise OptionsError(f"SolvedField: its status is {_shown(self.status)}, not 'converged' or "
                               "'not converged'")
        b = self.bends
        if b is not None and (not isinstance(b, np.ndarray) or b.dtype.kind != "b" or
                              b.shape != (len(self.surface.edges),)):
            raise OptionsError(f"SolvedField: its bends is {_shown(b)}, not None or an array of shape "
                               f"({len(self.surface.edges)},) (booleans)")
        if self.given is not None and not _given_ok(self.given):
            raise OptionsError(f"SolvedField: its given = {_shown(self.given)}: must be None or a list of "
                               "(points (n, 3), sigma, curve id, name) per singular curve as the user gave it")

    # ------------------------------------------------------------ per tet
    @property
    def curve(self) -> np.ndarray:
        """(#T,) the prepared curve crossing each tet, -1 elsewhere."""
        out = np.full(self.mesh.n_tets, -1, dtype=np.int64)
        for i, tr in enumerate(self.embedding.traces):
            out[tr.tets] = i
        return out

    @property
    def node_region(self) -> np.ndarray:
        """(#T,) bool: the tets of node regions (no structure equation)."""
        out = np.zeros(self.mesh.n_tets, bool)
        out[self.embedding.node_region_tets] = True
        return out

    def curve_vertices(self, i: int) -> np.ndarray:
        """Vertices of the edges carrying curve i's tangent constraints."""
        return np.unique(self.mesh.edges[self.tube_edges[self.tube_curve == i]])

    def quaternions(self) -> np.ndarray:
        """(#V, 4) unit quaternions (w, x, y, z) of the frames."""
        from scipy.spatial.transform import Rotation

        q = Rotation.from_matrix(self.frames).as_quat()  # x y z w
        return np.c_[q[:, 3], q[:, :3]]

    # ------------------------------------------------------------ storage
    def to_arrays(self) -> dict:
        """The field as named numpy arrays, in full precision (module docs);
        ``SolvedField.from_arrays`` reads them back."""
        emb, net, mesh = self.embedding, self.network, self.mesh
        tr = emb.traces
        out = {"vertices": np.asarray(mesh.vertices, float), "tets": np.asarray(mesh.tets, np.int64),
               "frames": np.asarray(self.frames, float), "omega": np.asarray(self.omega, float),
               "root": np.int64(self.root)}
        for name, parts in (("curve_tets", [t.tets for t in tr]), ("curve_faces", [t.faces for t in tr]),
                            ("curve_points", [np.asarray(t.points, float).reshape(-1, 3) for t in tr]),
                            ("curve_tangents", [np.asarray(t.tangents, float).reshape(-1, 3) for t in tr]),
                            ("curve_polyline", [np.asarray(t.polyline, float).reshape(-1, 3) for t in tr]),
                            ("network_points", [np.asarray(c.points, float).reshape(-1, 3) for c in net.curves]),
                            ("node_region", [np.asarray(r, np.int64) for r in emb.node_region])):
            out[name], out[f"{name}_offsets"] = flat_parts(parts, 3 if name.endswith(
                ("points", "tangents", "polyline")) else None)
        out["curve_ends"] = np.array([[t.start_face, t.end_face] for t in tr], np.int64).reshape(-1, 2)
        out["node_tets"] = np.asarray(emb.node_tets, np.int64).reshape(-1)
        fo = np.asarray(emb.face_omega, float)
        nz = np.nonzero(np.any(fo != 0, axis=1))[0]
        out["omega_faces"], out["omega_values"] = nz.astype(np.int64), fo[nz]
        out["excluded_faces"] = np.nonzero(np.asarray(emb.face_excluded, bool))[0].astype(np.int64)
        pc = np.asarray(emb.pierce_count, np.int64)
        out["pierced_faces"] = np.nonzero(pc)[0].astype(np.int64)
        out["pierce_counts"] = pc[out["pierced_faces"]]
        out["end_faces"] = np.array([int(f) for f, _ in emb.boundary_end_faces], np.int64)
        out["end_sigma"] = np.array([float(s) for _, s in emb.boundary_end_faces], float)
        out["tube_edges"] = np.asarray(self.tube_edges, np.int64).reshape(-1)
        out["tube_curve"] = np.asarray(self.tube_curve, np.int64).reshape(-1)
        out["feature_vertices"] = np.asarray(self.feature_vertices, bool)
        out["surface_vertices"] = np.asarray(self.surface.V, float)
        out["surface_faces"] = np.asarray(self.surface.F, np.int64)
        out["surface_sharp"] = np.asarray(self.sharp, bool)
        out["surface_bends"] = (np.zeros(len(self.surface.edges), bool) if self.bends is None
                                else np.asarray(self.bends, bool))
        meta = {"curves": [{"sigma": float(c.sigma), "name": c.name, "role": c.role.value, "source": int(s),
                            "start": k0, "end": k1, "closed": bool(c.closed)}
                           for c, s, k0, k1 in zip(net.curves, net.source, net.start_kind, net.end_kind)],
                "nodes": [{"position": [float(x) for x in nd.position], "ends": [[int(a), int(b)] for a, b in nd.ends]}
                          for nd in net.nodes],
                "pieces": {str(k): [int(x) for x in v] for k, v in net.pieces.items()},
                "status": self.status}
        if self.given is not None:
            meta["given"] = [{"sigma": float(g[1]), "curve": int(g[2]), "name": g[3]} for g in self.given]
            out["given_points"], out["given_points_offsets"] = flat_parts([g[0] for g in self.given], 3)
        out["meta"] = np.array(json.dumps(meta))
        return out

    @classmethod
    def from_arrays(cls, arrays, label: str = "from_arrays", fix: str | None = None) -> SolvedField:
        """The field of ``to_arrays()``'s arrays, every one checked.

        Parameters
        ----------
        arrays : mapping of str to array
            what ``to_arrays`` returned (a loaded ``.npz``, the add-on's
            stored group, a dict)
        label : str
            how an error names the source
        fix : str, optional
            what an error tells the user to do

        Raises
        ------
        ReadError
            an array missing, of the wrong type, shape or range, frames that
            are not rotations or an omega that does not carry them (named)
        """
        return cls(**read_field(DictSource(label, arrays) if fix is None else DictSource(label, arrays, fix)))

    @classmethod
    def from_result(cls, result) -> SolvedField:
        """``result.field`` (the earlier ``HexInput.from_result``; removed in
        the next release)."""
        return as_field(result, "SolvedField.from_result")

    def __eq__(self, other) -> bool:
        if not isinstance(other, SolvedField):
            return NotImplemented
        a, b = self.to_arrays(), other.to_arrays()
        return a.keys() == b.keys() and all(np.asarray(a[k]).shape == np.asarray(b[k]).shape and
                                            np.array_equal(a[k], b[k]) for k in a)

    __hash__ = None


def _shown(x) -> str:
    from ..checks import describe

    return describe(x) if not hasattr(x, "__dict__") or isinstance(x, np.ndarray) else f"a {type(x).__name__}"


def _given_ok(given) -> bool:
    from ..checks import _is_real

    if not isinstance(given, list):
        return False
    for g in given:
        if not isinstance(g, tuple) or len(g) != 4:
            return False
        P = np.asarray(g[0]) if isinstance(g[0], np.ndarray) else None
        if P is None or P.ndim != 2 or P.shape[1:] != (3,) or len(P) < 2 or P.dtype.kind not in "fi" or \
                not np.isfinite(P).all() or not _is_real(g[1]) or not np.isfinite(float(g[1])):
            return False
    return True


def flat_parts(parts, width: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Arrays concatenated, and the offsets that split them again."""
    parts = [np.asarray(p) for p in parts]
    off = np.cumsum([0] + [len(p) for p in parts]).astype(np.int64)
    if parts:
        flat = np.concatenate(parts)
    else:
        flat = np.zeros((0, width) if width else 0, float if width else np.int64)
    return (flat.astype(np.int64) if width is None else flat.astype(float)), off


def as_field(value, what: str) -> SolvedField:
    """The SolvedField of a value: a SolvedField, or anything holding one as
    ``.field`` (a solver Result); else an OptionsError naming ``what``."""
    field = value if isinstance(value, SolvedField) else getattr(value, "field", None)
    if isinstance(field, SolvedField):
        return field
    from ..checks import describe

    if isinstance(value, (str, bytes)) or hasattr(value, "__fspath__"):
        path = os.fsdecode(value)
        raise OptionsError(f"{what}: {path!r} is a path, not a solved field: a stored result file is read first, "
                           f"{what}(solver.io.load_field({path!r}))")
    shown = describe(value) if not hasattr(value, "__dict__") else f"a {type(value).__name__}"
    raise OptionsError(f"{what}: {shown} is not a solved field: give the Result of solve(...) or its .field, or a "
                       "stored one (solver.io.load_field(path))")
