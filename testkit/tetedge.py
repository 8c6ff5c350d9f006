"""Tet-edge networks: a network as other field tools export it (docs/limitations.md, *Repaired networks*).

Tools such as libSCOF and AlgoHex output a singular curve as a chain of
edges of *their* tet mesh.  ``tet_edge_network`` makes such an input from
any network: it meshes the solid independently with fTetWild at an edge
length ``h_src``, moves every node to the nearest mesh vertex and every
boundary end to the nearest boundary vertex, and replaces each curve by the
shortest path through the mesh's edges between them
(``scipy.sparse.csgraph.dijkstra``) that passes through no vertex an earlier
curve's path or another node holds.  The result zig-zags, reaches the
surface along whatever edge the mesh had, and -- with ``tiny`` -- holds
segments ~1e-6 of the model size next to normal ones, like the exports.
Used by the tests (tests/test_intake.py) and the validation report
(bench/validation_report.py); hex-meshing tests and benchmarks can take it too.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from solver.mesh.tetmesh import TetMesh, edge_graph, shortest_path
from solver.mesh.tetwild import tetrahedralize
from solver.network.network import Curve, Network, prepare_network
from solver.surface.trisurface import TriSurface


def tet_edge_network(V, F, net: Network, h_src: float, tiny: bool = True, mesh: TetMesh | None = None,
                     seed: int = 0) -> tuple[Network, TetMesh]:
    """The interior curves of net routed along the edges of an independent
    tet mesh of the solid (V, F) at edge length h_src.

    tiny : split every third interior edge of each path ~1e-6 of the bounding
           box diagonal from one of its ends (the exports' tiny segments)
    mesh : a tet mesh to route through instead of meshing anew
    Returns (network with the same sharp settings, the tet mesh used).
    """
    S = TriSurface(np.asarray(V, float), np.asarray(F, np.int64))
    diag = S.bbox_diagonal
    if mesh is None:
        mesh = tetrahedralize(S, h_src)
    G = edge_graph(mesh.n_vertices, mesh.edges, mesh.edge_lengths)
    X = mesh.vertices
    interior = ~mesh.is_boundary_vertex
    tree_in = cKDTree(X[interior])
    id_in = np.nonzero(interior)[0]
    tree_b = cKDTree(X[~interior])
    id_b = np.nonzero(~interior)[0]
    pn = prepare_network(net, diag)
    node_vertex = {}
    for k, nd in enumerate(pn.nodes):
        node_vertex[k] = int(id_in[tree_in.query(nd.position)[1]])
    end_node = {e: k for k, nd in enumerate(pn.nodes) for e in nd.ends}
    rng = np.random.default_rng(seed)
    used: set[int] = set()
    curves = []
    def route(a: int, b: int, free: list, inside: bool = False) -> np.ndarray:
        """The shortest path a -> b through no vertex another curve holds
        (a path's inner vertices, the nodes), but for those in free: two
        routes through one vertex would cross there, which no export has
        (and the check refuses); inside: through interior vertices only."""
        blocked = ~interior if inside else np.zeros(mesh.n_vertices, bool)
        blocked[list(used)] = True
        blocked[list(node_vertex.values())] = True
        blocked[free] = False
        path = shortest_path(_without(G, blocked), a, b) if blocked.any() else None
        if path is None:
            path = shortest_path(G, a, b)
        if path is None:
            raise ValueError(f"no path between mesh vertices {a} and {b}")
        used.update(int(v) for v in path[1:-1])
        return path

    for ci, c in enumerate(pn.curves):
        if c.closed:
            # a loop: through three of its points, leg by leg
            n = len(c.points) - 1
            way = [int(id_in[tree_in.query(c.points[k])[1]]) for k in (0, n // 3, (2 * n) // 3)]
            legs = [route(way[k], way[(k + 1) % 3], [way[k], way[(k + 1) % 3]], inside=True) for k in range(3)]
            used.update(way)
            path = np.concatenate([legs[0], legs[1][1:], legs[2][1:]])
            curves.append(Curve(X[path], c.sigma, c.role, c.torsion, c.name, True))
            continue
        ids = []
        for s, kind in ((0, pn.start_kind[ci]), (1, pn.end_kind[ci])):
            x = c.points[0 if s == 0 else -1]
            if kind == "node":
                ids.append(node_vertex[end_node[(ci, s)]])
            else:
                ids.append(int(id_b[tree_b.query(x)[1]]))
        P = X[route(ids[0], ids[1], ids)]
        if tiny and len(P) > 2:
            out = [P[0]]
            for k in range(1, len(P)):
                if k % 3 == 1 and k < len(P) - 1:
                    d = P[k] - P[k - 1]
                    out.append(P[k] - (1e-6 * diag * (1 + rng.random())) * d / np.linalg.norm(d))
                out.append(P[k])
            P = np.array(out)
        curves.append(Curve(P, c.sigma, c.role, c.torsion, c.name, False))
    sharp = [c for c in net.curves if c.role.value == "sharp"]
    out = Network(curves=curves + sharp, sharp_edges=net.sharp_edges, sharp_angle=net.sharp_angle,
                  node_tolerance=net.node_tolerance, boundary_tolerance=net.boundary_tolerance)
    return out, mesh


def _without(G, blocked: np.ndarray):
    """The edge graph G without the edges at the blocked vertices."""
    keep = sp.diags((~blocked).astype(float))
    H = (keep @ G @ keep).tocsr()
    H.eliminate_zeros()
    return H


def end_angles(S: TriSurface, net: Network) -> np.ndarray:
    """Angle (degrees) between the last segment of each curve end lying on
    the surface and the normal of the nearest surface triangle."""
    out = []
    tol = 1e-2 * S.bbox_diagonal
    for c in net.curves:
        for a, b in ((c.points[0], c.points[1]), (c.points[-1], c.points[-2])):
            d, f, _ = S.closest_points(a[None])
            if d[0] > tol:
                continue
            t = (a - b) / np.linalg.norm(a - b)
            out.append(np.degrees(np.arccos(min(1.0, abs(float(t @ S.face_normals[f[0]]))))))
    return np.array(out)
