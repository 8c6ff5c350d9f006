"""What hex meshing needs of a solved field, and how it is kept.

A field is meshed from a ``HexInput``: the tet mesh with its frames and
omega, the network as the solve traced it through that mesh (the embedding
and the prepared curves), and the input surface with its sharp edges.
A solver Result gives all of it; a stored field gives it back through
``hex_source_arrays`` / ``input_from_arrays`` (the .npz result file and the
add-on's .blend keep those arrays beside the field).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import OptionsError
from ..linalg.rotations import CUBE_GROUP, closest_symmetry, exp_so3, rotation_angle
from ..mesh.embed import Embedding
from ..mesh.tetmesh import TetMesh
from ..network.network import PreparedNetwork
from ..surface.trisurface import TriSurface


@dataclass
class HexInput:
    """What hex meshing needs of a solved field.

    Attributes
    ----------
    mesh : TetMesh
        the field's tet mesh
    omega : (#E, 3) float array
        the Darboux derivative on mesh.edges (Eq. 8)
    frames : (#V, 3, 3) float array
        the vertex frames, columns the cross axes
    embedding : mesh.embed.Embedding
        the curves traced through the mesh (pierced faces, node regions)
    network : network.network.PreparedNetwork
        the curves and nodes the embedding traced
    surface : TriSurface
        the input surface, for the boundary's position and the Hausdorff
        distance
    sharp : (#surface edges,) bool array
        the surface's sharp edges
    status : str
        the field's status, 'converged' or 'not converged'
    given : list or None
        the singular curves as the user gave them, before the intake
        repaired them: (points (n, 3), sigma, curve id, name) each; None
        where unknown (the repaired curves are then taken)
    """

    mesh: TetMesh
    omega: np.ndarray
    frames: np.ndarray
    embedding: Embedding
    network: PreparedNetwork
    surface: TriSurface
    sharp: np.ndarray
    status: str = "converged"
    given: list | None = None

    @classmethod
    def from_result(cls, result) -> HexInput:
        """The HexInput of a solver Result.

        Parameters
        ----------
        result : solver.Result

        Returns
        -------
        HexInput
        """
        if not all(hasattr(result, a) for a in ("problem", "mesh", "omega", "frames", "embedding", "report")):
            raise OptionsError(f"HexInput.from_result: result = {_describe(result)}: must be a solver Result "
                               "(solve(...)); a stored result file is read by solver.io.load_hex_input(path)")
        checked = result.problem.checked
        given = getattr(result.problem, "given", None)
        if given is not None:
            given = [(np.asarray(c.points, float), float(c.sigma), i, c.name) for i, c in enumerate(given.curves)
                     if c.sigma != 0]
        return cls(result.mesh, np.asarray(result.omega), np.asarray(result.frames), result.embedding,
                   result.problem.network, checked.surface, np.asarray(checked.features.sharp, bool),
                   result.report.status, given)


def _describe(x) -> str:
    from ..checks import describe

    return describe(x) if not hasattr(x, "__dict__") else f"a {type(x).__name__}"


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


def field_fault(mesh: TetMesh, frames, omega) -> str:
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


def _flat(parts):
    parts = [np.asarray(p) for p in parts]
    off = np.cumsum([0] + [len(p) for p in parts]).astype(np.int64)
    shape = parts[0].shape[1:] if parts else ()
    flat = np.concatenate(parts) if parts else np.zeros((0, *shape))
    return flat, off


def _split(flat, off):
    return [flat[a:b] for a, b in zip(off[:-1], off[1:])]


def hex_source_arrays(inp: HexInput) -> dict:
    """What a stored field needs, besides its mesh, frames and omega, to be
    hex meshed again.

    Parameters
    ----------
    inp : HexInput

    Returns
    -------
    dict of str to numpy array
        arrays prefixed ``hex_`` (the traces, node regions, the prepared
        curves and nodes as JSON in ``hex_meta``, the input surface and its
        sharp edges), for ``numpy.savez`` or any array store;
        ``input_from_arrays`` rebuilds the HexInput from them
    """
    if not isinstance(inp, HexInput):
        raise OptionsError(f"hex_source_arrays: inp = {_describe(inp)}: must be a HexInput "
                           "(HexInput.from_result(result))")
    emb, net = inp.embedding, inp.network
    tr = emb.traces
    out = {}
    for name, parts in (("tets", [t.tets for t in tr]), ("faces", [t.faces for t in tr]),
                        ("points", [np.asarray(t.points).reshape(-1, 3) for t in tr]),
                        ("tangents", [np.asarray(t.tangents).reshape(-1, 3) for t in tr]),
                        ("polyline", [t.polyline for t in tr]), ("curve_points", [c.points for c in net.curves]),
                        ("node_region", [np.asarray(r, np.int64) for r in emb.node_region])):
        flat, off = _flat(parts)
        out[f"hex_{name}"], out[f"hex_{name}_offsets"] = flat, off
    out["hex_ends"] = np.array([[t.start_face, t.end_face] for t in tr], np.int64).reshape(-1, 2)
    out["hex_node_tets"] = np.asarray(emb.node_tets, np.int64)
    meta = {"curves": [{"sigma": float(c.sigma), "name": c.name, "role": c.role.value, "source": int(s),
                        "start": k0, "end": k1, "closed": bool(c.closed)}
                       for c, s, k0, k1 in zip(net.curves, net.source, net.start_kind, net.end_kind)],
            "nodes": [{"position": [float(x) for x in nd.position], "ends": [[int(a), int(b)] for a, b in nd.ends]}
                      for nd in net.nodes],
            "status": inp.status}
    if inp.given is not None:
        meta["given"] = [{"sigma": g[1], "curve": int(g[2]), "name": g[3]} for g in inp.given]
        out["hex_given_points"], out["hex_given_points_offsets"] = _flat([g[0] for g in inp.given])
    out["hex_meta"] = np.array(json.dumps(meta))
    out["hex_surface_vertices"] = inp.surface.V
    out["hex_surface_faces"] = inp.surface.F
    out["hex_surface_sharp"] = inp.sharp
    return out
