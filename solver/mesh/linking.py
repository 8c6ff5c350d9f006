"""Curves that leave a smooth part of the boundary and come back to it.

Where no singular curve passes, the frames lift to three smooth unit
vector fields e1, e2, e3.  A curve of the network (singular or feature)
has its tangent as a frame axis, so along it the tangent is s e_k with a
fixed k and a sign s that cannot change.  On a smooth part of the
boundary (no sharp edge) the frames are adapted to the normal (§4.2), and
the normal is the same e_k there, with the same sign, everywhere: around
the end of another curve the frames turn about the normal (its index),
which keeps e_k.  A curve that enters the solid through such a part
(tangent -n) and leaves through the same part (tangent +n) would need
s = -1 at one end and +1 at the other.  So the loop made of the curve and
a surface path back to its start must link singular curves that turn the
frames over; if it bounds a chain in the solid that no singular curve
crosses, no field exists (the monodromy around that chain would be a
half turn, Eq. 17 asks for none).  Examples: a straight curve across the
tube of a smooth solid torus (a +-1/4 pair of them ended LM at a penalty
of 1e4), a U-shaped curve under one face, a chord of a ball that no other
curve links.  With sharp edges between the two ends the normal moves to
another axis across them, as on the cylinder's caps.

The test is exact on the mesh: the loop is a path through the tets the
curve crosses and a path over the boundary avoiding sharp vertices; it
bounds a chain clear of the singular curves when d1^T c = loop has a
solution among the faces no singular curve (nor a node region) touches.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg as spla

from .embed import Embedding
from .tetmesh import TetMesh, edge_graph, shortest_path

# the largest angle between a carried axis and the next frame's nearest axis
# that _carry takes as a match (a refusal rests on every step of the carry):
# on a smooth part, and at a step to or from a vertex on a sharp edge
CARRY_MATCH_DEG = 40.0
CARRY_MATCH_SHARP_DEG = 20.0


def _edge_chain(mesh: TetMesh, path: np.ndarray) -> np.ndarray:
    """The 1-chain of a vertex path: +-1 on each mesh edge it walks."""
    u, v = path[:-1], path[1:]
    eta = np.zeros(mesh.n_edges)
    np.add.at(eta, mesh.edge_index(u, v), np.where(u < v, 1.0, -1.0))
    return eta


def _carry(E0: np.ndarray, path: np.ndarray, w: np.ndarray, on_sharp: np.ndarray | None = None,
           sharp_match_deg: float = CARRY_MATCH_SHARP_DEG) -> np.ndarray | None:
    """The signed axis w (body coordinates of E0[path[0]]) carried along the
    surface path: at each step the axis of the next frame nearest to it.
    Only that axis is matched, so the frames may turn fast about it (about
    the normal next to a curve's end).  None where no axis of the next
    frame lies within CARRY_MATCH_DEG, or CARRY_MATCH_SHARP_DEG at a step
    to or from a vertex of a sharp edge (on_sharp: a mask of the boundary
    vertices): the match would be a guess, and a refusal must not rest on
    a guess.

    Issue 41c: across a sharp edge the boundary field's frames on the two
    faces need not share an axis along the edge (next to the end of a
    singular curve on one of the faces they are 20-35 degrees apart on the
    genus-2 family), so the nearest axis of the next frame can be the wrong
    one.  With 40 degrees allowed, a tangent axis carried over the top of
    an arm of the genus-2 block, from an outer wall to a hole wall, was
    matched at 33 degrees to an in-plane axis of the hole wall: it
    "arrived across the curve" and refused 4 of 10 inputs of the family
    (sound networks: they converge when the mesh happens to carry it
    right).  A smooth surface, where a real refusal lives (a curve across
    the tube of a torus), matches the carried normal within a few degrees
    at every step (40 degrees stay allowed there: next to a curve's end
    the frames turn fast about the carried normal)."""
    smooth, sharp = np.cos(np.radians(CARRY_MATCH_DEG)), np.cos(np.radians(sharp_match_deg))
    for u, v in zip(path[:-1], path[1:]):
        c = E0[v].T @ (E0[u] @ w)
        j = int(np.argmax(np.abs(c)))
        at_sharp = on_sharp is not None and (on_sharp[u] or on_sharp[v])
        if abs(c[j]) < (sharp if at_sharp else smooth):
            return None
        w = np.sign(c[j]) * np.eye(3)[j]
    return w


def misaligned_curves(mesh: TetMesh, emb: Embedding, sigma: list[float], E0: np.ndarray,
                      sharp: np.ndarray, sharp_match_deg: float = CARRY_MATCH_SHARP_DEG) -> list[tuple]:
    """Curves with both ends on the boundary whose tangent axis the frames
    on the surface do not carry from one end to the other, around a loop
    that bounds a chain no singular curve crosses.

    mesh  : the tet mesh; emb : its embedding of the prepared curves
    sigma : index of each prepared curve (0 for feature curves)
    E0    : (#boundary vertices, 3, 3) the boundary field's frames
    sharp : (#boundary edges,) sharp mask over mesh.boundary.edges
    sharp_match_deg : the match _carry takes at steps by sharp-edge vertices
                      (CARRY_MATCH_SHARP_DEG; meshed_boundary.py also asks
                      at CARRY_MATCH_DEG, to find a boundary field that
                      turns across a sharp edge next to a curve's end)
    Returns [(curve, start vertex, end vertex, cosine)]: global vertex ids,
    and the cosine between the carried axis and the curve's tangent at its
    end (-1: reversed, 0: across); empty for every sound network.
    """
    B = mesh.boundary
    bv = mesh.boundary_vertices
    local = np.full(mesh.n_vertices, -1)
    local[bv] = np.arange(len(bv))
    cone = np.zeros(len(B.V), bool)  # vertices at the ends of curves
    for tr in emb.traces:
        for f in (tr.start_face, tr.end_face):
            if f >= 0:
                cone[local[mesh.faces[f]]] = True
    bw = np.linalg.norm(B.V[B.edges[:, 0]] - B.V[B.edges[:, 1]], axis=1)
    on_sharp = np.zeros(len(B.V), bool)
    on_sharp[B.edges[sharp].reshape(-1)] = True
    candidates = []
    for i, tr in enumerate(emb.traces):
        if tr.start_face < 0 or tr.end_face < 0:
            continue
        ends = [local[mesh.faces[f]] for f in (tr.start_face, tr.end_face)]
        ends = [e[~on_sharp[e]] if np.any(~on_sharp[e]) else e for e in ends]
        a, b = int(ends[0][0]), int(ends[1][0])
        free = ~cone
        free[[a, b]] = True
        keep = free[B.edges].all(axis=1)
        outer = shortest_path(edge_graph(len(B.V), B.edges[keep], bw[keep]), a, b)
        if outer is None:
            continue
        P = tr.polyline
        t0, t1 = P[1] - P[0], P[-1] - P[-2]
        t0, t1 = t0 / np.linalg.norm(t0), t1 / np.linalg.norm(t1)
        body = E0[a].T @ t0
        k = int(np.argmax(np.abs(body)))
        if abs(body[k]) < np.cos(np.radians(30)):
            continue  # the frame at the end is not along the curve: nothing to read
        w = _carry(E0, outer, np.sign(body[k]) * np.eye(3)[k], on_sharp, sharp_match_deg)
        if w is None:
            continue
        cos = float((E0[b] @ w) @ t1)
        if cos < 0.5:
            candidates.append((i, a, b, outer, cos))
    if not candidates:
        return []
    # faces a chain may use: none a singular curve or a node region touches
    allowed = np.ones(mesh.n_faces, bool)
    for tr, s in zip(emb.traces, sigma):
        if s != 0:
            allowed[tr.faces] = False
    nr = emb.node_region_tets
    if len(nr):
        allowed[mesh.tet_faces[nr].reshape(-1)] = False
    d1t = mesh.d1.T.tocsc()[:, np.nonzero(allowed)[0]]
    out = []
    for i, a, b, outer, cos in candidates:
        tr = emb.traces[i]
        tube = np.unique(mesh.tet_edges[tr.tets].reshape(-1))
        inner = shortest_path(edge_graph(mesh.n_vertices, mesh.edges[tube], mesh.edge_lengths[tube]), int(bv[b]),
                              int(bv[a]))
        if inner is None:
            continue
        eta = _edge_chain(mesh, bv[outer]) + _edge_chain(mesh, inner)
        chain = spla.lsqr(d1t, eta, atol=0.0, btol=1e-12, iter_lim=50000)[0]
        if np.linalg.norm(d1t @ chain - eta) <= 1e-6 * np.linalg.norm(eta):
            out.append((i, int(bv[a]), int(bv[b]), cos))
    return out
