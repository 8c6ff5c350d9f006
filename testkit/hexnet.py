"""Hex-mesh networks: real-like inputs known to be hex-meshable.

Real singularity networks come from hex meshes: the singular graph of an
existing hex mesh is a network that some hex mesh realises, so the solver
must be able to solve it and the hex mesher to mesh it.  This module builds
such inputs the way they arise:

1. a block-structured hex mesh of a known topology (``cube_sphere``: the
   7-block ball; ``o_grid_cylinder``: a 5-block disk extruded; ``o_grid_torus``:
   the same disk swept around a circle; ``plate_with_holes``: a grid of
   squares, some with a round hole in an O-grid ring of 4 blocks, extruded;
   ``hollow_cube``: a cube with a spherical cavity, 26 blocks round a middle
   cube and 6 from its faces to the sphere; ``triangle_prism``: a triangle
   split into 3 quads at its centroid, extruded; ``hexagon_prism``: a
   hexagon split into 3 quads at its centre, extruded; ``plate_with_holes`` with
   ``missing`` cells: an L-shaped part);
2. deformed by a smooth random map (``smooth_deformation``: a few
   low-frequency Fourier modes kept well inside the diffeomorphisms, an
   optional twist and bend; ``radial_blob``: a random radius on the ball's
   shell), checked to invert no hex;
3. read back (``network_from_hexmesh``): the triangulated boundary of the
   hex mesh is the surface (V, F), and every chain of interior hex edges of
   valence != 4 is a curve of index sigma = (4 - valence) / 4 (valence 3:
   +1/4, valence 5: -1/4, valence 6: -1/2; the sign convention of
   solver/network/network.py).

``hexnet_input(kind, seed)`` makes one input of each kind of ``KINDS``
(deterministic for a seed, which varies the resolution, proportions and
deformation); ``hexnet_family(seed)`` all of them.  The source hex mesh
(about 1,000-5,000 cells) comes along in the entry's ``meta``.
"""

from __future__ import annotations

import numpy as np

from solver.hexmesh.quality import boundary_quads, edge_valences, scaled_jacobian
from solver.network.network import Curve, Network, cluster_points

KINDS = ("ball", "ellipsoid", "blob", "cylinder", "bent bar", "torus", "plate", "genus2", "hollow", "prism",
         "hex prism", "L-part", "polygon cylinder")
"""The kinds ``hexnet_input`` makes."""

MIRROR = np.array([0, 3, 2, 1, 4, 7, 6, 5])  # a VTK hex's corners with x and y swapped: the orientation flipped


# ---------------------------------------------------------------------------
# reading a hex mesh back as (surface, network)


def boundary_surface(V: np.ndarray, H: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The boundary of a hex mesh as a triangle surface.

    Parameters
    ----------
    V : (n, 3) float array
        Hex mesh vertices.
    H : (m, 8) int array
        Hexes in VTK_HEXAHEDRON corner order.

    Returns
    -------
    V_s : (k, 3) float array
        The boundary vertices (compacted).
    F_s : (2 q, 3) int array
        Each boundary quad split into two triangles along its shorter
        diagonal, oriented outward.
    ids : (k,) int array
        The hex mesh vertex of each surface vertex.

    Raises
    ------
    ValueError
        A face is held by more than two hexes.
    """
    V = np.asarray(V, float)
    quads, over = boundary_quads(np.asarray(H, np.int64))
    if over:
        raise ValueError(f"{over} faces of the hex mesh are held by more than two hexes")
    d02 = np.linalg.norm(V[quads[:, 0]] - V[quads[:, 2]], axis=1)
    d13 = np.linalg.norm(V[quads[:, 1]] - V[quads[:, 3]], axis=1)
    split = np.where((d02 <= d13)[:, None, None], np.array([[0, 1, 2], [0, 2, 3]]),
                     np.array([[0, 1, 3], [1, 2, 3]]))  # (q, 2, 3) corners of the two triangles
    T = np.take_along_axis(quads[:, None, :], split.reshape(len(quads), 6)[:, None, :], axis=2)
    T = T.reshape(-1, 3)
    ids, F_s = np.unique(T, return_inverse=True)
    return V[ids], F_s.reshape(-1, 3), ids


def irregular_edges(H: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The interior edges of a hex mesh whose valence (hexes around) is not 4.

    Returns
    -------
    edges : (k, 2) int array
        Vertex pairs, sorted per row.
    valence : (k,) int array
        Hexes around each.
    boundary_vertices : (b,) int array
        The vertices of the boundary quads.
    """
    H = np.asarray(H, np.int64)
    quads, _ = boundary_quads(H)
    e, cnt, onb = edge_valences(H, quads)
    irr = ~onb & (cnt != 4)
    return e[irr], cnt[irr], np.unique(quads)


def _chains(E: np.ndarray, val: np.ndarray, boundary: np.ndarray, nv: int) -> list[tuple[np.ndarray, bool]]:
    """Vertex chains of the edges E (valence val): broken at the nodes (see
    ``network_from_hexmesh``); closed loops end at their start.  Returns
    [(vertices in order, closed)]."""
    if not len(E):
        return []
    deg = np.bincount(E.ravel(), minlength=nv)
    lo = np.full(nv, np.iinfo(np.int64).max)
    hi = np.full(nv, -1)
    np.minimum.at(lo, E.ravel(), np.repeat(val, 2))
    np.maximum.at(hi, E.ravel(), np.repeat(val, 2))
    node = (deg != 2) | (lo != hi)
    node[boundary] = True
    node &= deg > 0
    # the two edges at each vertex of degree 2: incidences sorted by vertex
    inc_v = E.ravel()
    inc_e = np.repeat(np.arange(len(E)), 2)
    order = np.argsort(inc_v, kind="stable")
    inc_v, inc_e = inc_v[order], inc_e[order]
    start = np.searchsorted(inc_v, np.arange(nv))
    other = {}  # (vertex of degree 2, edge) -> its other edge there
    for v in np.nonzero((deg == 2) & ~node)[0]:
        a, b = inc_e[start[v]], inc_e[start[v] + 1]
        other[(v, a)], other[(v, b)] = b, a
    seen = np.zeros(len(E), bool)

    def walk(e0: int, v0: int) -> list[int]:
        verts, e, v = [v0], e0, v0
        while True:
            seen[e] = True
            a, b = E[e]
            w = int(b if a == v else a)
            verts.append(w)
            if node[w]:
                return verts
            e = other[(w, e)]
            if e == e0:
                return verts
            v = w

    out = []
    for v0 in np.nonzero(node)[0]:
        for e0 in inc_e[start[v0]:start[v0] + deg[v0]]:
            if not seen[e0]:
                out.append((np.array(walk(int(e0), int(v0))), False))
    for e0 in np.nonzero(~seen)[0]:
        if not seen[e0]:
            out.append((np.array(walk(int(e0), int(E[e0, 0]))), True))
    return out


def network_from_hexmesh(V, H, sharp_angle: float = 30.0, name: str = "") -> tuple[np.ndarray, np.ndarray, Network]:
    """The solver input a hex mesh realises: its boundary and its singular graph.

    Parameters
    ----------
    V : (n, 3) float array
        Hex mesh vertices.
    H : (m, 8) int array
        Hexes in VTK_HEXAHEDRON corner order, positively oriented.
    sharp_angle : float
        The Network's dihedral threshold (degrees) for the solver's sharp
        edges; the solver finds them on the surface itself.
    name : str
        Prefix of the curve names.

    Returns
    -------
    V_s : (k, 3) float array
        Vertices of the boundary surface.
    F_s : (f, 3) int array
        Its triangles: each boundary quad split in two, outward (a closed
        manifold surface for a hex mesh of a solid).
    network : Network
        One Curve per chain of interior edges of valence v != 4, with
        sigma = (4 - v) / 4, its points the hex vertices along the chain in
        order, named "valence v #k".  A chain breaks at nodes: vertices with
        a number of incident irregular interior edges other than 2, where
        the valence changes, and boundary vertices (a chain ends where it
        reaches the surface).  A loop without nodes is a closed curve.
    """
    V = np.asarray(V, float)
    H = np.asarray(H, np.int64)
    V_s, F_s, _ = boundary_surface(V, H)
    E, val, bnd = irregular_edges(H)
    curves = []
    count: dict[int, int] = {}
    for verts, closed in _chains(E, val, bnd, len(V)):
        a, b = np.sort(verts[:2])
        v = int(val[np.nonzero((E[:, 0] == a) & (E[:, 1] == b))[0][0]])
        k = count.get(v, 0)
        count[v] = k + 1
        label = f"{name} valence {v} #{k}".strip()
        curves.append(Curve(V[verts], sigma=(4 - v) / 4, name=label, closed=closed))
    return V_s, F_s, Network(curves=curves, sharp_angle=sharp_angle)


# ---------------------------------------------------------------------------
# block-structured hex meshes


def _grid_cells(shape: tuple[int, ...]) -> np.ndarray:
    """Cells of a structured grid of points of the given shape (C order):
    (cells, 4) quads for a 2D grid, (cells, 8) VTK hexes for a 3D one."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    if len(shape) == 2:
        c = [idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]]
    else:
        lo, up = idx[:, :, :-1], idx[:, :, 1:]
        c = [g[a, b] for g in (lo, up) for a, b in ((np.s_[:-1], np.s_[:-1]), (np.s_[1:], np.s_[:-1]),
                                                     (np.s_[1:], np.s_[1:]), (np.s_[:-1], np.s_[1:]))]
    return np.stack([x.ravel() for x in c], axis=1)


def _assemble(blocks: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """One mesh of structured blocks (point grids (a, b, 2) or (a, b, c, 3)):
    cells of every block, coincident vertices merged (1e-7 of the size),
    each cell oriented positively (quads counter-clockwise, hexes with a
    positive scaled Jacobian)."""
    pts, cells, nv = [], [], 0
    for P in blocks:
        pts.append(P.reshape(-1, P.shape[-1]))
        cells.append(_grid_cells(P.shape[:-1]) + nv)
        nv += len(pts[-1])
    X, C = np.vstack(pts), np.vstack(cells)
    size = float(np.linalg.norm(X.max(axis=0) - X.min(axis=0)))
    lab = cluster_points(X, 1e-7 * size)
    Y = np.empty((lab.max() + 1, X.shape[1]))
    Y[lab] = X
    C = lab[C]
    if X.shape[1] == 2:
        P = Y[C]
        area = np.sum(P[:, :, 0] * np.roll(P[:, :, 1], -1, axis=1) - np.roll(P[:, :, 0], -1, axis=1) * P[:, :, 1],
                      axis=1)
        C[area < 0] = C[area < 0][:, [0, 3, 2, 1]]
    else:
        C = _orient(Y, C)
    return Y, C


def _orient(V: np.ndarray, H: np.ndarray) -> np.ndarray:
    """H with every negatively oriented hex mirrored; raises if one is degenerate."""
    flip = scaled_jacobian(V, H) < 0
    H = H.copy()
    H[flip] = H[flip][:, MIRROR]
    q = scaled_jacobian(V, H)
    if q.min() <= 0:
        raise ValueError(f"{int(np.sum(q <= 0))} hexes are degenerate (scaled Jacobian {q.min():.3g})")
    return H


def extrude(V2: np.ndarray, Q: np.ndarray, zs) -> tuple[np.ndarray, np.ndarray]:
    """Counter-clockwise quads (V2, Q) extruded through the levels zs (increasing): (V, H)."""
    zs = np.asarray(zs, float)
    nv = len(V2)
    V = np.vstack([np.c_[V2, np.full(nv, z)] for z in zs])
    H = np.vstack([np.c_[Q + k * nv, Q + (k + 1) * nv] for k in range(len(zs) - 1)])
    return V, H


def cube_sphere(n: int = 6, m: int | None = None, inner: float = 0.45, axes=(1.0, 1.0, 1.0),
                orthogonal: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The 7-block hex mesh of the unit ball (or of an ellipsoid).

    Parameters
    ----------
    n : int
        Cells along an edge of the central cube [-inner, inner]^3 (n^3
        cells) and along each side of the 6 outer blocks.
    m : int, optional
        Radial layers of the outer blocks; default: the radial cell length
        about the cube's cell length, round((1 - inner) n / (2 inner)).
    inner : float
        Half-size of the central cube.
    axes : (3,) floats
        The whole mesh scaled by these: the semi-axes of an ellipsoid.
    orthogonal : bool
        The outer blocks' radial lines reach the surface along its normal,
        as a hex mesher's boundary layer does: cubic arcs leaving the cube's
        face along the chord c and reaching the surface along (c . n) n
        (n the surface normal; on the sphere the chords are nearly normal
        already, on the ellipsoid (1.5, 1, 0.75) up to 31 degrees off);
        False: straight lines.

    Returns
    -------
    V : (k, 3) float array
    H : (n^3 + 6 n^2 m, 8) int array
        VTK hexes, positively oriented.  The outer blocks blend from the
        cube's face to the surface (equiangular on the sphere).  The
        irregular edges: the 12 cube edges and the 8 radial edges from its
        corners, all of valence 3.
    """
    if m is None:
        m = max(1, int(round((1 - inner) * n / (2 * inner))))
    axes = np.asarray(axes, float)
    g = np.linspace(-1.0, 1.0, n + 1)
    blocks = [inner * np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1) * axes]
    t, faces = _cube_to_sphere(n, m, inner)
    for P_in, D in faces:
        P_in, P_out = P_in * axes, D * axes
        if orthogonal:
            N = D / axes  # the ellipsoid's normal at D * axes
            N /= np.linalg.norm(N, axis=-1, keepdims=True)
            T = P_out - P_in
            K = np.sum(T * N, axis=-1, keepdims=True) * N - T  # the chord's part across the normal, negated
            blocks.append((1 - t) * P_in + t * P_out + (t**3 - t**2) * K)
        else:
            blocks.append((1 - t) * P_in + t * P_out)
    return _assemble(blocks)


def hollow_cube(n: int = 4, inner: float = 0.55, cavity: float = 0.3, k: int | None = None,
                m: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The hex mesh of the cube [-1, 1]^3 with a spherical cavity of radius
    ``cavity`` at its centre: the 26 blocks of a 3 x 3 x 3 grid round a
    middle cube [-inner, inner]^3, and in that cube 6 blocks from its faces
    to the sphere (equiangular on it, as ``cube_sphere``'s outer blocks).

    Parameters
    ----------
    n : int
        Cells along the middle cube's edge (and each shell block's sides).
    inner : float
        Half-size of the middle cube; cavity < inner < 1.
    k : int, optional
        Cells across the frame [inner, 1]; default about the middle cube's
        cell length, round((1 - inner) n / (2 inner)), at least 1.
    m : int, optional
        Radial layers of the shell; default round((inner - cavity) n /
        (2 inner)), at least 2.

    Returns
    -------
    V : (k, 3) float array
    H : (m, 8) int array
        VTK hexes, positively oriented.  Irregular: the middle cube's 12
        edges (three frame blocks and two shell blocks round each: valence
        5, -1/4) and the 8 radial edges from its corners to the sphere
        (valence 3, +1/4), which meet in 8 nodes; two boundary components,
        the outer one with 12 sharp edges.
    """
    if not 0 < cavity < inner < 1:
        raise ValueError(f"need 0 < cavity < inner < 1, got cavity {cavity}, inner {inner}")
    cell = 2 * inner / n
    if k is None:
        k = max(1, int(round((1 - inner) / cell)))
    if m is None:
        m = max(2, int(round((inner - cavity) / cell)))
    spans = [np.linspace(-1.0, -inner, k + 1), np.linspace(-inner, inner, n + 1), np.linspace(inner, 1.0, k + 1)]
    blocks = [np.stack(np.meshgrid(spans[i], spans[j], spans[l], indexing="ij"), axis=-1)
              for i in range(3) for j in range(3) for l in range(3) if (i, j, l) != (1, 1, 1)]
    t, faces = _cube_to_sphere(n, m, inner)
    blocks += [(1 - t) * cavity * D + t * P_out for P_out, D in faces]
    return _assemble(blocks)


def _cube_to_sphere(n: int, m: int, inner: float):
    """The 6 blocks between the faces of the cube [-inner, inner]^3 and the
    unit sphere: t (n+1, n+1, m+1, 1), the blend parameter from the face
    (0) to the sphere (1) or back, and per face (P, D), its uniform
    (n+1, n+1, 3) grid of points on the cube and the matching equiangular
    grid of unit directions (the points on the unit sphere)."""
    g = np.linspace(-1.0, 1.0, n + 1)
    uu, vv, tt = np.meshgrid(g, g, np.linspace(0.0, 1.0, m + 1), indexing="ij")
    faces = []
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        for side in (-1.0, 1.0):
            P = np.zeros(uu.shape + (3,))
            P[..., axis], P[..., u], P[..., v] = side * inner, inner * uu, inner * vv
            D = np.zeros_like(P)
            D[..., axis], D[..., u], D[..., v] = side, np.tan(uu * np.pi / 4), np.tan(vv * np.pi / 4)
            faces.append((P, D / np.linalg.norm(D, axis=-1, keepdims=True)))
    return tt[..., None], faces


def o_grid_disk(n: int = 6, m: int | None = None, radius: float = 1.0,
                inner: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """The 5-block quad mesh of a disk: a central square [-inner r, inner r]^2
    of n x n quads and 4 blocks of n x m quads from its sides to the circle
    (uniform in angle).  Default m: round((1 - inner) n / (2 inner)).
    Returns (V2 (k, 2), Q (q, 4) counter-clockwise)."""
    if m is None:
        m = max(1, int(round((1 - inner) * n / (2 * inner))))
    g = np.linspace(-1.0, 1.0, n + 1)
    c = inner * radius
    blocks = [c * np.stack(np.meshgrid(g, g, indexing="ij"), axis=-1)]
    ss, tt = np.meshgrid(g, np.linspace(0.0, 1.0, m + 1), indexing="ij")
    for k in range(4):
        co, si = np.cos(k * np.pi / 2), np.sin(k * np.pi / 2)
        rot = np.array([[co, -si], [si, co]])
        side = np.stack([np.full_like(ss, c), c * ss], axis=-1) @ rot.T
        th = ss * np.pi / 4 + k * np.pi / 2
        arc = radius * np.stack([np.cos(th), np.sin(th)], axis=-1)
        blocks.append((1 - tt[..., None]) * side + tt[..., None] * arc)
    return _assemble(blocks)


def polygon_disk(k: int, n: int = 4, m: int = 4, radius: float = 1.0,
                 inner: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """The quad mesh of a disk around a regular k-gon of circumradius
    ``inner * radius``: the k-gon split into k quads at its centre (n x n
    each: centre, edge middle, corner, edge middle) and k blocks of 2n x m
    quads from its sides to the circle.  The centre has valence k (index
    (4 - k) / 4: -1/4, -1/2, -3/4 for k = 5, 6, 7), the k-gon's corners
    valence 3 (+1/4); the indices sum to 1, the disk's.
    Returns (V2 (p, 2), Q (q, 4) counter-clockwise)."""
    th = np.pi / 2 + 2 * np.pi * np.arange(k) / k
    C = inner * radius * np.c_[np.cos(th), np.sin(th)]
    g = np.linspace(0.0, 1.0, n + 1)
    s, t = (a[..., None] for a in np.meshgrid(g, g, indexing="ij"))
    blocks = []
    for j in range(k):
        a, nxt, prev = C[j], C[(j + 1) % k], C[j - 1]
        p1, p3 = 0.5 * (a + prev), 0.5 * (a + nxt)
        blocks.append(s * (1 - t) * p1 + s * t * a + (1 - s) * t * p3)  # the centre is the origin
    ss, tt = np.meshgrid(np.linspace(0.0, 1.0, 2 * n + 1), np.linspace(0.0, 1.0, m + 1), indexing="ij")
    for j in range(k):
        a, b = C[j], C[(j + 1) % k]
        side = a + (b - a) * ss[..., None]  # the k-gon's side, its middle a grid line (n segments each half)
        ang = th[j] + ss * (2 * np.pi / k)
        arc = radius * np.stack([np.cos(ang), np.sin(ang)], axis=-1)
        blocks.append((1 - tt[..., None]) * side + tt[..., None] * arc)
    return _assemble(blocks)


def o_grid_cylinder(n: int = 6, m: int | None = None, layers: int = 12, radius: float = 1.0, height: float = 2.0,
                    inner: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """The 5-block disk (``o_grid_disk``) extruded along z over
    [-height/2, height/2] in ``layers`` layers.

    Returns
    -------
    V : (k, 3) float array
    H : ((n^2 + 4 n m) layers, 8) int array
        VTK hexes, positively oriented.  Irregular: the 4 axial edges
        through the central square's corners (valence 3, +1/4), ending on
        the flat caps, whose rims are sharp.
    """
    V2, Q = o_grid_disk(n, m, radius, inner)
    V, H = extrude(V2, Q, np.linspace(-height / 2, height / 2, layers + 1))
    return V, _orient(V, H)


def o_grid_torus(n: int = 4, m: int | None = None, segments: int = 32, major: float = 1.0, minor: float = 0.4,
                 inner: float = 0.45) -> tuple[np.ndarray, np.ndarray]:
    """The 5-block disk of radius ``minor`` (``o_grid_disk``) swept around the
    z axis at distance ``major`` in ``segments`` steps: a solid torus.

    Returns
    -------
    V : (k, 3) float array
    H : ((n^2 + 4 n m) segments, 8) int array
        VTK hexes, positively oriented.  Irregular: 4 closed loops of
        valence 3 (+1/4) through the central square's corners.
    """
    V2, Q = o_grid_disk(n, m, minor, inner)
    phi = np.linspace(0.0, 2 * np.pi, segments + 1)
    nv = len(V2)
    r = major + V2[:, 0]
    V = np.vstack([np.c_[r * np.cos(p), r * np.sin(p), V2[:, 1]] for p in phi])
    H = np.vstack([np.c_[Q + k * nv, Q + (k + 1) * nv] for k in range(segments)])
    lab = cluster_points(V, 1e-7 * major)  # the last ring is the first
    W = np.empty((lab.max() + 1, 3))
    W[lab] = V
    return W, _orient(W, lab[H])


def plate_with_holes(nx: int = 3, ny: int = 3, holes=((1, 1),), n: int = 4, thickness: float = 0.5, layers: int = 2,
                     hole_radius: float = 0.3, ring: int | None = None, missing=()) -> tuple[np.ndarray, np.ndarray]:
    """A plate of nx x ny unit squares, some with a round hole, extruded.

    Parameters
    ----------
    nx, ny : int
        The plate is [0, nx] x [0, ny] x [-thickness/2, thickness/2].
    holes : sequence of (i, j)
        Cells [i, i+1] x [j, j+1] with a round hole of radius hole_radius
        at their centre, the cell between the circle and its square filled
        by an O-grid ring of 4 blocks (n along a side, ``ring`` radially;
        default max(2, round((0.6 - hole_radius) n))).  The other cells are
        n x n grids, so the quads of neighbouring cells match.
    n : int
        Quads along every cell side.
    layers : int
        Hex layers through the thickness.
    missing : sequence of (i, j)
        Cells left out: an L-shaped plate is a square one without a corner
        block of cells.

    Returns
    -------
    V : (k, 3) float array
    H : (m, 8) int array
        VTK hexes, positively oriented.  Each corner of a hole cell inside
        the plate has valence 3 + 2 = 5 (three grid cells and two ring
        blocks meet there; 6 where two hole cells do): a -1/4 (-1/2) curve
        through the thickness, ending on the flat faces.
    """
    holes = {tuple(int(x) for x in h) for h in holes}
    missing = {tuple(int(x) for x in h) for h in missing}
    if holes & missing:
        raise ValueError(f"cells both with a hole and missing: {sorted(holes & missing)}")
    if ring is None:
        ring = max(2, int(round((0.6 - hole_radius) * n)))
    g = np.linspace(0.0, 1.0, n + 1)
    blocks = []
    ss, tt = np.meshgrid(g, np.linspace(0.0, 1.0, ring + 1), indexing="ij")
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    for i in range(nx):
        for j in range(ny):
            if (i, j) in missing:
                continue
            if (i, j) not in holes:
                blocks.append(np.stack(np.meshgrid(i + g, j + g, indexing="ij"), axis=-1))
                continue
            centre = np.array([i + 0.5, j + 0.5])
            for k in range(4):
                a, b = corners[k] + (i, j), corners[(k + 1) % 4] + (i, j)
                side = a + ss[..., None] * (b - a)
                th = (1.25 + 0.5 * k + 0.5 * ss) * np.pi  # from corner a's angle (225 degrees for k = 0) to b's
                arc = centre + hole_radius * np.stack([np.cos(th), np.sin(th)], axis=-1)
                blocks.append((1 - tt[..., None]) * arc + tt[..., None] * side)
    V2, Q = _assemble(blocks)
    V, H = extrude(V2, Q, np.linspace(-thickness / 2, thickness / 2, layers + 1))
    return V, _orient(V, H)


def triangle_prism(corners, n: int = 4, thickness: float = 1.0, layers: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """A triangular prism: the triangle ``corners`` (3, 2) split into 3
    quads (each corner, the midpoints of its two sides and the centroid;
    n x n cells each), extruded over [-thickness/2, thickness/2] in
    ``layers`` layers.  The centroid has valence 3: one +1/4 curve through
    the thickness, ending on the two flat faces; each corner is one cell
    corner, its sharp edge as acute as the triangle's angle there.

    Returns
    -------
    V : (k, 3) float array
    H : (m, 8) int array
        VTK hexes, positively oriented.
    """
    C = np.asarray(corners, float)
    O = C.mean(axis=0)
    g = np.linspace(0.0, 1.0, n + 1)
    s, t = np.meshgrid(g, g, indexing="ij")
    s, t = s[..., None], t[..., None]
    blocks = []
    for k in range(3):
        a, prev, nxt = C[k], C[k - 1], C[(k + 1) % 3]
        p0, p1, p2, p3 = a, 0.5 * (a + nxt), O, 0.5 * (a + prev)  # the quad, bilinear
        blocks.append((1 - s) * (1 - t) * p0 + s * (1 - t) * p1 + s * t * p2 + (1 - s) * t * p3)
    V2, Q = _assemble(blocks)
    V, H = extrude(V2, Q, np.linspace(-thickness / 2, thickness / 2, layers + 1))
    return V, _orient(V, H)


def hexagon_prism(corners, n: int = 8, thickness: float = 0.8, layers: int = 6) -> tuple[np.ndarray, np.ndarray]:
    """A hexagonal prism: the hexagon ``corners`` (6, 2), counter-clockwise
    round the origin, split into 3 quads (the origin and corners 2k, 2k+1,
    2k+2; n x n cells each), extruded over [-thickness/2, thickness/2] in
    ``layers`` layers.  The centre has valence 3: one +1/4 curve through
    the thickness.  Its corners of about 120 degrees are alternately a cell
    corner (odd corners) and flat (even ones, two cells): the ambiguous
    corners of a CAD outline, rounded one way or the other by the mesh.
    """
    C = np.asarray(corners, float)
    O = np.zeros(2)
    g = np.linspace(0.0, 1.0, n + 1)
    s, t = np.meshgrid(g, g, indexing="ij")
    s, t = s[..., None], t[..., None]
    blocks = []
    for k in range(3):
        p0, p1, p2, p3 = O, C[2 * k], C[2 * k + 1], C[(2 * k + 2) % 6]
        blocks.append((1 - s) * (1 - t) * p0 + s * (1 - t) * p1 + s * t * p2 + (1 - s) * t * p3)
    V2, Q = _assemble(blocks)
    V, H = extrude(V2, Q, np.linspace(-thickness / 2, thickness / 2, layers + 1))
    return V, _orient(V, H)


def l_prism_with_hole(n: int = 4) -> tuple[np.ndarray, np.ndarray, Network]:
    """An L-shaped prism with a round hole through it (issue 51's second
    part to simulate on): 2 x 2 with a 1 x 1 corner block cut out, 0.5
    thick, the hole (radius 0.1) in an O-grid ring whose four corners are
    curves of -1/4 through the thickness.  Read off its block hex mesh
    (``plate_with_holes`` on 6 x 6 cells of 1/3 without the 3 x 3 corner,
    ``network_from_hexmesh``): the closed surface (V, F) and the network;
    the 16-gon hole keeps its wall one patch at the 30 degree sharp angle.
    """
    missing = [(i, j) for i in range(3, 6) for j in range(3, 6)]
    V, H = plate_with_holes(6, 6, ((1, 1),), n=n, thickness=1.5, layers=max(2, n - 1), hole_radius=0.3,
                            missing=missing)
    return network_from_hexmesh(V / 3.0, H, name="L-prism with a hole")


# ---------------------------------------------------------------------------
# smooth deformations


def min_jacobian(V: np.ndarray, H: np.ndarray) -> float:
    """The smallest scaled Jacobian of the hexes (<= 0: one is inverted)."""
    return float(scaled_jacobian(np.asarray(V, float), np.asarray(H, np.int64)).min())


def smooth_deformation(V, rng: np.random.Generator, amplitude: float = 0.1, bend: float = 0.0, twist: float = 0.0,
                       H=None, modes: int = 4, cycles: float = 1.0, axis: int | None = None,
                       min_quality: float = 0.0) -> np.ndarray:
    """Points moved by a smooth random map.

    The map is x + A D sum_k w_k a_k sin(omega_k . (x - c) / D + phi_k)
    (c the bounding box's centre, D its diagonal, a_k random unit vectors,
    weights w_k >= 0 summing to 1, |omega_k| <= omega_max), then a twist
    about the box's longest axis and a bend of that axis in the plane of
    the next one.  The gradient of the random part is at most A omega_max,
    kept <= 1/2 (omega_max = min(2 pi cycles, 0.5 / A)), so the map is a
    diffeomorphism that turns directions by at most ~30 degrees.

    Parameters
    ----------
    V : (n, 3) float array
    rng : numpy.random.Generator
        Draws the modes (once; a retry scales the same modes).
    amplitude : float
        A: the largest displacement, as a fraction of D.
    bend : float
        Angle (radians) the axis turns through from one end to the other
        (a circular arc of radius length / bend; it must exceed the bar's
        half-width).
    twist : float
        Angle (radians) the cross-sections turn through from one end to
        the other, about the axis.
    H : (m, 8) int array, optional
        Hexes on V: if given, the deformed mesh must keep every scaled
        Jacobian > min_quality; if it does not, the amplitude is halved
        and the map tried again (up to 8 times, then twist and bend are
        halved with it).
    modes : int
        Fourier modes.
    cycles : float
        Largest frequency, in cycles per diagonal.
    axis : int, optional
        The twist and bend axis (default: the box's longest).
    min_quality : float
        See H.

    Returns
    -------
    (n, 3) float array
        The new positions.

    Raises
    ------
    ValueError
        Every retry inverted a hex.
    """
    V = np.asarray(V, float)
    lo, hi = V.min(axis=0), V.max(axis=0)
    c, D = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    ax = int(np.argmax(hi - lo)) if axis is None else int(axis)
    across = (ax + 1) % 3
    dirs = rng.normal(size=(modes, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    mag = rng.uniform(0.5, 1.0, modes)
    disp = rng.normal(size=(modes, 3))
    disp /= np.linalg.norm(disp, axis=1, keepdims=True)
    w = rng.uniform(0.5, 1.0, modes)
    w /= w.sum()
    phase = rng.uniform(0.0, 2 * np.pi, modes)
    for attempt in range(12):
        A = amplitude / 2**attempt
        s = 0.5 ** max(0, attempt - 8)
        om = min(2 * np.pi * cycles, 0.5 / A) if A > 0 else 0.0
        omega = dirs * (mag * om)[:, None]
        X = V + A * D * np.sin((V - c) @ omega.T / D + phase) @ (w[:, None] * disp)
        X = _twist_bend(X, c, hi[ax] - lo[ax], ax, across, s * bend, s * twist)
        if H is None or min_jacobian(X, H) > min_quality:
            return X
    raise ValueError("every deformation tried inverted a hex")


def _twist_bend(X: np.ndarray, c: np.ndarray, length: float, ax: int, across: int, bend: float,
                twist: float) -> np.ndarray:
    """X twisted by ``twist`` about the line through c along ``ax`` (linear
    along it, zero at c) and bent by ``bend`` in the (ax, across) plane."""
    X = X.copy()
    s = X[:, ax] - c[ax]
    if twist:
        o = [a for a in range(3) if a != ax]
        phi = twist * s / length
        p, q = X[:, o[0]] - c[o[0]], X[:, o[1]] - c[o[1]]
        X[:, o[0]] = c[o[0]] + np.cos(phi) * p - np.sin(phi) * q
        X[:, o[1]] = c[o[1]] + np.sin(phi) * p + np.cos(phi) * q
    if bend:
        R = length / bend
        q = X[:, across] - c[across]
        th = s / R
        X[:, ax] = c[ax] + (R - q) * np.sin(th)
        X[:, across] = c[across] + R - (R - q) * np.cos(th)
    return X


def radial_blob(V, rng: np.random.Generator, amplitude: float = 0.2, modes: int = 4) -> np.ndarray:
    """A ball's points p moved to p (1 + g(p / |p|) |p|^2): the unit sphere
    goes to the radius 1 + g, g a random smooth function of the direction
    (``modes`` cosines of frequency 1-2 per radian, |g| <= amplitude), and
    the centre stays (the factor |p|^2 makes the map smooth there).
    Returns the new positions."""
    V = np.asarray(V, float)
    dirs = rng.normal(size=(modes, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    omega = dirs * rng.uniform(1.0, 2.0, modes)[:, None]
    w = rng.uniform(0.5, 1.0, modes)
    w *= amplitude / w.sum()
    phase = rng.uniform(0.0, 2 * np.pi, modes)
    r2 = np.sum(V**2, axis=1)
    d = V / np.sqrt(np.maximum(r2, 1e-300))[:, None]
    g = np.cos(d @ omega.T + phase) @ w
    return V * (1 + g * r2)[:, None]


# ---------------------------------------------------------------------------
# the family


def _cycle(seed: int, options: tuple):
    """The resolution of a seed: seeds 0, 1, ... go through the options in turn."""
    return options[int(seed) % len(options)]


def hexnet_input(kind: str, seed: int = 0) -> dict:
    """One input of a kind (``KINDS``), deterministic for the seed.

    Parameters
    ----------
    kind : str
        ``'ball'`` (cube_sphere, slightly deformed), ``'ellipsoid'``
        (cube_sphere scaled by about (1.5, 1.0, 0.75), deformed),
        ``'blob'`` (cube_sphere with a random radius, ``radial_blob``),
        ``'cylinder'`` (o_grid_cylinder), ``'bent bar'`` (a long
        o_grid_cylinder, bent by 60-120 and twisted by 0-90 degrees),
        ``'torus'`` (o_grid_torus: 4 closed curves), ``'plate'``
        (plate_with_holes, 3 x 3 with one hole: 4 curves of -1/4),
        ``'genus2'`` (5 x 3 with two holes: 8 curves of -1/4), ``'hollow'``
        (hollow_cube: a cube with a spherical cavity, 12 curves of -1/4 and
        8 of +1/4 meeting in 8 nodes, the radial ones ending on the cavity),
        ``'prism'`` (triangle_prism of a random triangle, angles 30-80
        degrees: one +1/4 curve, sharp edges of those angles), ``'hex
        prism'`` (hexagon_prism of a hexagon with corners of about 120
        degrees: one +1/4 curve; three of its corners flat), ``'L-part'``
        (plate_with_holes on 5 x 5 cells without the 2 x 2 corner block: a
        concave sharp edge, two holes, 8 curves of -1/4), ``'polygon
        cylinder'`` (polygon_disk extruded: an axis of valence 5, 6 or 7 --
        index -1/4, -1/2, -3/4 -- in a ring of k curves of +1/4).
    seed : int
        Varies the resolution n, proportions and deformation.

    Returns
    -------
    dict
        ``name`` ("kind seed s"), ``V``, ``F`` (the closed outward boundary
        surface), ``network``, and ``meta``: ``kind``, ``seed``, ``V`` and
        ``H`` (the deformed source hex mesh), ``params`` (what the seed
        chose), ``irregular_edges`` and ``curves`` ({valence: count}),
        ``min_jacobian`` (of the source mesh), ``end_angles`` (degrees off
        the surface's normal of each curve end's last segment).
    """
    if kind not in KINDS:
        raise ValueError(f"unknown kind {kind!r}; choose one of {', '.join(KINDS)}")
    rng = np.random.default_rng([int(seed), KINDS.index(kind)])
    p: dict = {}
    if kind in ("ball", "ellipsoid", "blob"):
        p["n"] = _cycle(seed, (7, 8) if kind == "ellipsoid" else (6, 7, 8))
        p["inner"] = float(rng.uniform(0.3, 0.45))
        p["m"] = max(1, int(round((1 - p["inner"]) * p["n"] / (2 * p["inner"]))))
        axes = (1.0, 1.0, 1.0)
        if kind == "ellipsoid":
            axes = p["axes"] = [round(float(x), 3) for x in np.array([1.5, 1.0, 0.75]) * rng.uniform(0.9, 1.1, 3)]
        V, H = cube_sphere(p["n"], p["m"], inner=p["inner"], axes=axes)
        if kind == "blob":
            p["blob"] = float(rng.uniform(0.15, 0.25))
            V = radial_blob(V, rng, p["blob"])
        p["amplitude"] = float(rng.uniform(0.02, 0.06))
        V = smooth_deformation(V, rng, p["amplitude"], H=H)
    elif kind in ("cylinder", "bent bar"):
        bar = kind == "bent bar"
        p["n"] = _cycle(seed, (4, 5) if bar else (6, 7, 8))
        p["inner"] = float(rng.uniform(0.3, 0.4)) if bar else float(rng.uniform(0.35, 0.45))
        p["radius"] = 0.6 if bar else 1.0
        p["height"] = float(rng.uniform(3.5, 4.5)) if bar else float(rng.uniform(1.5, 2.5))
        h = 2 * p["inner"] * p["radius"] / p["n"]  # the central square's cell
        p["layers"] = max(4, int(round(p["height"] / (1.5 * h))))
        V, H = o_grid_cylinder(p["n"], layers=p["layers"], radius=p["radius"], height=p["height"], inner=p["inner"])
        if bar:
            p["bend"] = float(np.radians(rng.uniform(60.0, 120.0)))
            p["twist"] = float(np.radians(rng.uniform(0.0, 90.0)))
        p["amplitude"] = float(rng.uniform(0.01, 0.03)) if bar else float(rng.uniform(0.02, 0.05))
        V = smooth_deformation(V, rng, p["amplitude"], bend=p.get("bend", 0.0), twist=p.get("twist", 0.0), H=H,
                               axis=2)
    elif kind == "polygon cylinder":
        p["k"] = _cycle(seed, (5, 6, 7))
        p["n"] = _cycle(seed // 3, (3, 4))
        p["inner"] = float(rng.uniform(0.4, 0.5))
        p["height"] = float(rng.uniform(1.5, 2.5))
        p["layers"] = max(4, int(round(p["height"] / (1.2 * p["inner"] / p["n"]))))
        V2, Q = polygon_disk(p["k"], p["n"], p["n"], 1.0, p["inner"])
        V, H = extrude(V2, Q, np.linspace(-p["height"] / 2, p["height"] / 2, p["layers"] + 1))
        H = _orient(V, H)
        p["amplitude"] = float(rng.uniform(0.02, 0.05))
        V = smooth_deformation(V, rng, p["amplitude"], H=H, axis=2)
    elif kind == "torus":
        p["n"] = _cycle(seed, (4, 5))
        p["minor"] = float(rng.uniform(0.35, 0.45))
        h = 0.9 * p["minor"] / p["n"]
        p["segments"] = int(round(2 * np.pi / (2 * h)))
        V, H = o_grid_torus(p["n"], segments=p["segments"], minor=p["minor"])
        p["amplitude"] = float(rng.uniform(0.02, 0.05))
        V = smooth_deformation(V, rng, p["amplitude"], H=H)
    elif kind == "hollow":
        p["n"] = _cycle(seed, (6, 7, 8))
        p["inner"] = float(rng.uniform(0.5, 0.65))
        p["cavity"] = round(p["inner"] * float(rng.uniform(0.4, 0.6)), 4)
        p["frame"] = max(1, int(round((1 - p["inner"]) * p["n"] / (2 * p["inner"]))))
        V, H = hollow_cube(p["n"], p["inner"], p["cavity"], k=p["frame"])
        p["amplitude"] = float(rng.uniform(0.02, 0.05))
        V = smooth_deformation(V, rng, p["amplitude"], H=H)
    elif kind == "prism":
        p["n"] = _cycle(seed, (8, 9, 10))
        while True:  # a triangle whose angles are 30-80 degrees
            ang = rng.uniform(30.0, 80.0, 2)
            if 30.0 <= 180.0 - ang.sum() <= 80.0:
                break
        p["angles"] = [round(float(a), 2) for a in (*ang, 180.0 - ang.sum())]
        a, b = np.radians(ang)
        # corners (0, 0), (2, 0) and the third by the angles at the first two
        x = 2.0 * np.tan(b) / (np.tan(a) + np.tan(b))
        corners = np.array([[0.0, 0.0], [2.0, 0.0], [x, x * np.tan(a)]])
        p["thickness"] = float(rng.uniform(0.8, 1.3))
        p["layers"] = max(2, int(round(p["thickness"] * p["n"])))
        V, H = triangle_prism(corners, p["n"], p["thickness"], p["layers"])
        p["amplitude"] = float(rng.uniform(0.02, 0.05))
        V = smooth_deformation(V, rng, p["amplitude"], H=H)
    elif kind == "hex prism":
        p["n"] = _cycle(seed, (8, 9, 10))
        ang = np.radians(np.arange(6) * 60.0 + rng.uniform(-6.0, 6.0, 6))
        rad = rng.uniform(0.9, 1.1, 6)
        p["corners"] = np.round(np.c_[rad * np.cos(ang), rad * np.sin(ang)], 4).tolist()
        p["thickness"] = float(rng.uniform(0.6, 1.0))
        p["layers"] = max(2, int(round(p["thickness"] * p["n"])))
        V, H = hexagon_prism(p["corners"], p["n"], p["thickness"], p["layers"])
        p["amplitude"] = float(rng.uniform(0.01, 0.03))
        V = smooth_deformation(V, rng, p["amplitude"], H=H)
    else:
        holes = {"plate": ((1, 1),), "genus2": ((1, 1), (3, 1))}.get(kind)
        nx, ny = {"plate": (3, 3), "genus2": (5, 3)}.get(kind, (5, 5))
        missing = ()
        if kind == "L-part":
            holes = ((1, 1), ((1, 3), (3, 1))[int(rng.integers(2))])
            missing = ((3, 3), (3, 4), (4, 3), (4, 4))
        p["n"] = _cycle(seed, (6, 7) if kind == "plate" else (4, 5) if kind == "L-part" else (5, 6))
        p["thickness"] = float(rng.uniform(0.4, 0.6))
        p["hole_radius"] = float(rng.uniform(0.25, 0.35))
        p["layers"] = max(3 if kind == "L-part" else 2, int(np.ceil(p["thickness"] * p["n"])))
        V, H = plate_with_holes(nx, ny, holes, p["n"], p["thickness"], p["layers"], p["hole_radius"], missing=missing)
        p["amplitude"] = float(rng.uniform(0.02, 0.05))
        V = smooth_deformation(V, rng, p["amplitude"], H=H)
    Vs, Fs, net = network_from_hexmesh(V, H, name=kind)
    _, val, _ = irregular_edges(H)
    meta = {
        "kind": kind,
        "seed": int(seed),
        "V": V,
        "H": H,
        "params": p,
        "irregular_edges": {int(v): int(c) for v, c in zip(*np.unique(val, return_counts=True))},
        "curves": {int(v): sum(1 for c in net.curves if round(4 - 4 * c.sigma) == v)
                   for v in np.unique(val).tolist()},
        "min_jacobian": min_jacobian(V, H),
        "end_angles": end_angles(Vs, Fs, net),
    }
    return {"name": f"{kind} seed {seed}", "V": Vs, "F": Fs, "network": net, "meta": meta}


def end_angles(V, F, net: Network) -> np.ndarray:
    """Angles (degrees) between the last segment of each curve end on the
    surface (V, F) and the normal of the nearest triangle."""
    from solver.surface.trisurface import TriSurface
    from testkit.tetedge import end_angles as angles

    return angles(TriSurface(np.asarray(V, float), np.asarray(F, np.int64)), net)


def hexnet_family(seed: int = 0, kinds=KINDS) -> list[dict]:
    """``hexnet_input(kind, seed)`` for every kind."""
    return [hexnet_input(k, seed) for k in kinds]
