"""Built-in example domains: a surface (V, F) and a curve network each.

All are built procedurally (no downloaded data):

* ``cube``        -- unit cube, its 12 sharp edges, no interior curves
* ``cylinder``    -- solid cylinder, sharp rims, 4 axial curves of index +1/4
                     (the O-grid layout)
* ``torus``       -- smooth solid torus, no curves (genus 1 boundary)
* ``ball``        -- ball with the cube-sphere network: the 12 edges of an
                     inner cube and 8 radial segments to the sphere, index
                     +1/4 each, meeting at 8 degree-4 nodes
* ``plate``       -- CAD-like part: a square plate with a round hole, sharp
                     edges everywhere, and the 4 index -1/4 curves around the
                     hole that a hex mesh aligned with all edges needs
* ``prism``       -- CAD-like: an extruded pentagon whose outline turns by 47
                     and 52 degrees at two corners (ambiguous, corners.py),
                     no interior curves
* ``genus2``      -- a block with two square through-holes and two feature
                     curves reaching the faces 25 degrees off the normal
"""

from __future__ import annotations

import itertools

import numpy as np

from .network.network import Curve, Network


def icosphere(subdivisions: int = 3, radius: float = 1.0):
    t = (1 + 5**0.5) / 2
    V = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]],
        float,
    )
    F = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
         [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11],
         [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    )
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    for _ in range(subdivisions):
        E = np.sort(np.vstack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
        ue, inv = np.unique(E, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        m = V[ue].mean(axis=1)
        m /= np.linalg.norm(m, axis=1, keepdims=True)
        nv = len(V)
        V = np.vstack([V, m])
        k = len(F)
        a, b, c = inv[:k] + nv, inv[k : 2 * k] + nv, inv[2 * k :] + nv
        F = np.vstack([np.c_[F[:, 0], a, c], np.c_[F[:, 1], b, a], np.c_[F[:, 2], c, b], np.c_[a, b, c]])
    return V * radius, F


def box(lo=(-1, -1, -1), hi=(1, 1, 1), n: int = 1):
    """Axis-aligned box, each face split into an n x n grid of quads (2 tris each)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    V, F = [], []
    for axis in range(3):
        for side in (0, 1):
            u, v = [a for a in range(3) if a != axis]
            g = np.linspace(0, 1, n + 1)
            uu, vv = np.meshgrid(g, g, indexing="ij")
            P = np.zeros((n + 1, n + 1, 3))
            P[..., axis] = hi[axis] if side else lo[axis]
            P[..., u] = lo[u] + uu * (hi[u] - lo[u])
            P[..., v] = lo[v] + vv * (hi[v] - lo[v])
            base = sum(len(x) for x in V)
            V.append(P.reshape(-1, 3))
            idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1) + base
            a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
            tris = np.vstack([np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]])
            # outward orientation: normal of (u, v) order is +axis when (axis,u,v) is cyclic
            cyclic = (u - axis) % 3 == 1
            if cyclic != bool(side):
                tris = tris[:, [0, 2, 1]]
            F.append(tris)
    V = np.vstack(V)
    F = np.vstack(F)
    return merge_vertices(V, F)


def merge_vertices(V, F, tol=1e-9):
    key = np.round(V / tol).astype(np.int64)
    _, idx, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    return V[idx], inv.reshape(-1)[F]


def cylinder_surface(radius=1.0, height=2.0, n=64, rings=8):
    """Closed cylinder along z, centred at the origin; caps are triangle fans
    refined in `rings` concentric rings."""
    th = np.linspace(0, 2 * np.pi, n, endpoint=False)
    circle = np.c_[np.cos(th), np.sin(th)]
    V = []
    F = []
    zs = np.linspace(-height / 2, height / 2, max(2, int(round(height / (2 * np.pi * radius / n))) + 1))
    # side
    for z in zs:
        V.append(np.c_[radius * circle, np.full(n, z)])
    side = np.vstack(V)
    for r in range(len(zs) - 1):
        i = np.arange(n)
        j = (i + 1) % n
        a, b, c, d = r * n + i, r * n + j, (r + 1) * n + j, (r + 1) * n + i
        F.append(np.c_[a, b, c])
        F.append(np.c_[a, c, d])
    V = [side]
    nv = len(side)
    # caps: concentric rings from the rim inwards, with a centre vertex
    for top in (False, True):
        z = height / 2 if top else -height / 2
        rim = (len(zs) - 1) * n if top else 0
        prev = rim + np.arange(n)
        for k in range(1, rings):
            rr = radius * (1 - k / rings)
            ring = np.c_[rr * circle, np.full(n, z)]
            ids = nv + np.arange(n)
            V.append(ring)
            nv += n
            i = np.arange(n)
            j = (i + 1) % n
            t1 = np.c_[prev[i], prev[j], ids[j]]
            t2 = np.c_[prev[i], ids[j], ids[i]]
            tt = np.vstack([t1, t2])
            F.append(tt if top else tt[:, [0, 2, 1]])
            prev = ids
        V.append(np.array([[0, 0, z]]))
        c = nv
        nv += 1
        i = np.arange(n)
        j = (i + 1) % n
        tt = np.c_[prev[i], prev[j], np.full(n, c)]
        F.append(tt if top else tt[:, [0, 2, 1]])
    return np.vstack(V), np.vstack(F)


def torus_surface(R=1.0, r=0.4, n_major=64, n_minor=24):
    u = np.linspace(0, 2 * np.pi, n_major, endpoint=False)
    v = np.linspace(0, 2 * np.pi, n_minor, endpoint=False)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    X = (R + r * np.cos(vv)) * np.cos(uu)
    Y = (R + r * np.cos(vv)) * np.sin(uu)
    Z = r * np.sin(vv)
    V = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    i, j = np.meshgrid(np.arange(n_major), np.arange(n_minor), indexing="ij")
    a = i * n_minor + j
    b = ((i + 1) % n_major) * n_minor + j
    c = ((i + 1) % n_major) * n_minor + (j + 1) % n_minor
    d = i * n_minor + (j + 1) % n_minor
    F = np.vstack([np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), d.ravel()]])
    # outward: check with the signed volume
    P = V[F]
    vol = np.einsum("ij,ij->i", P[:, 0], np.cross(P[:, 1], P[:, 2])).sum()
    if vol < 0:
        F = F[:, [0, 2, 1]]
    return V, F


def plate_with_hole_surface(size=2.0, thickness=0.5, hole=0.45, n=48):
    """Square plate [-s/2, s/2]^2 x [-t/2, t/2] with a round through hole.

    Each cap is triangulated as a ring between the square outline (n points,
    including the 4 corners) and the hole circle (n points).
    """
    s = size / 2
    # square outline with n points, equally spaced in angle-ish via perimeter
    per = np.linspace(0, 8 * s, n, endpoint=False)
    pts = []
    start = -s  # start at (s, -s) going ccw
    for p in per:
        side, d = divmod(p, 2 * s)
        if side == 0:
            pts.append((s, -s + d))
        elif side == 1:
            pts.append((s - d, s))
        elif side == 2:
            pts.append((-s, s - d))
        else:
            pts.append((-s + d, -s))
    del start
    sq = np.array(pts)
    ang = np.arctan2(sq[:, 1], sq[:, 0])
    circ = hole * np.c_[np.cos(ang), np.sin(ang)]
    z0, z1 = -thickness / 2, thickness / 2
    nz = max(2, int(round(thickness / (2 * np.pi * hole / n))) + 1)
    zs = np.linspace(z0, z1, nz)
    V = []
    F = []
    # outer wall rings and inner wall rings
    outer = [np.c_[sq, np.full(n, z)] for z in zs]
    inner = [np.c_[circ, np.full(n, z)] for z in zs]
    V = outer + inner
    o = lambda k: k * n + np.arange(n)  # noqa: E731
    ib = nz * n
    ii = lambda k: ib + k * n + np.arange(n)  # noqa: E731
    i = np.arange(n)
    j = (i + 1) % n
    for k in range(nz - 1):
        a, b = o(k), o(k + 1)
        F += [np.c_[a[i], a[j], b[j]], np.c_[a[i], b[j], b[i]]]
        a, b = ii(k), ii(k + 1)
        F += [np.c_[a[i], b[j], a[j]], np.c_[a[i], b[i], b[j]]]
    # caps: rings between the square and the circle
    rings = 4
    for top in (False, True):
        k = nz - 1 if top else 0
        z = zs[k]
        prev = o(k)
        nv = sum(len(x) for x in V)
        for r in range(1, rings):
            t = r / rings
            ring = np.c_[(1 - t) * sq + t * circ, np.full(n, z)]
            ids = nv + np.arange(n)
            V.append(ring)
            nv += n
            tt = np.vstack([np.c_[prev[i], prev[j], ids[j]], np.c_[prev[i], ids[j], ids[i]]])
            F.append(tt if top else tt[:, [0, 2, 1]])
            prev = ids
        last = ii(k)
        tt = np.vstack([np.c_[prev[i], prev[j], last[j]], np.c_[prev[i], last[j], last[i]]])
        F.append(tt if top else tt[:, [0, 2, 1]])
    return np.vstack(V), np.vstack(F)


def _segment(a, b, n=8):
    t = np.linspace(0, 1, n + 1)[:, None]
    return a + t * (np.asarray(b) - np.asarray(a))


def cube_example():
    V, F = box(n=2)
    return V, F, Network(curves=[], sharp_angle=30.0)


def cylinder_example(offset: float = 0.35):
    V, F = cylinder_surface(1.0, 2.0)
    curves = []
    for k, (x, y) in enumerate(itertools.product((-offset, offset), repeat=2)):
        curves.append(Curve(_segment((x, y, -1.0), (x, y, 1.0)), sigma=0.25, name=f"axial {k}"))
    return V, F, Network(curves=curves, sharp_angle=30.0)


def torus_example():
    V, F = torus_surface()
    return V, F, Network(curves=[])


def ball_example(inner: float = 1.0 / (2.0 + np.sqrt(3.0)), subdivisions: int = 3):
    """The cube-sphere network: 12 + 8 curves, 8 degree-4 nodes.

    The inner cube's half-size makes cube edges and radial segments equally
    long (2c = 1 - sqrt(3) c), which maximises the shortest curve for a given
    ball and so the coarsest mesh that resolves the network.
    """
    V, F = icosphere(subdivisions)
    c = inner
    corners = np.array(list(itertools.product((-c, c), repeat=3)))
    curves = []
    for a, b in itertools.combinations(range(8), 2):
        if np.sum(corners[a] != corners[b]) == 1:
            curves.append(Curve(_segment(corners[a], corners[b]), sigma=0.25, name=f"cube edge {a}-{b}"))
    for a in range(8):
        d = corners[a] / np.linalg.norm(corners[a])
        curves.append(Curve(_segment(corners[a], d * 1.0), sigma=0.25, name=f"radial {a}"))
    return V, F, Network(curves=curves)


def plate_example():
    V, F = plate_with_hole_surface()
    curves = []
    r = 0.72
    for k in range(4):
        a = np.pi / 4 + k * np.pi / 2
        x, y = r * np.cos(a), r * np.sin(a)
        curves.append(Curve(_segment((x, y, -0.25), (x, y, 0.25), 2), sigma=-0.25, name=f"hole {k}"))
    return V, F, Network(curves=curves, sharp_angle=30.0)


def prism_surface(outline, height: float, n: int = 4):
    """A convex planar outline (k, 2), counter-clockwise, extruded along z
    over [0, height]: caps fanned from the centroid in n rings, walls split
    into n x n quads (2 triangles each)."""
    O = np.asarray(outline, float)
    k = len(O)
    c = O.mean(axis=0)
    V, F = [], []
    nv = 0
    # walls
    for i in range(k):
        a, b = O[i], O[(i + 1) % k]
        t = np.linspace(0.0, 1.0, n + 1)
        z = np.linspace(0.0, height, n + 1)
        tt, zz = np.meshgrid(t, z, indexing="ij")
        P = np.c_[(a[0] + tt * (b[0] - a[0])).ravel(), (a[1] + tt * (b[1] - a[1])).ravel(), zz.ravel()]
        idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1) + nv
        q0, q1, q2, q3 = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
        F.append(np.vstack([np.c_[q0.ravel(), q1.ravel(), q2.ravel()], np.c_[q0.ravel(), q2.ravel(), q3.ravel()]]))
        V.append(P)
        nv += len(P)
    # caps: rings from the outline (subdivided n per side) to the centroid
    rim = np.vstack([O[i] + np.linspace(0, 1, n, endpoint=False)[:, None] * (O[(i + 1) % k] - O[i])
                     for i in range(k)])
    m = len(rim)
    j = np.arange(m)
    for top in (False, True):
        z = height if top else 0.0
        prev = None
        for r in range(n):
            ring = c + (1 - r / n) * (rim - c)
            ids = nv + j
            V.append(np.c_[ring, np.full(m, z)])
            nv += m
            if prev is not None:
                tt = np.vstack([np.c_[prev[j], prev[(j + 1) % m], ids[(j + 1) % m]],
                                np.c_[prev[j], ids[(j + 1) % m], ids[j]]])
                F.append(tt if top else tt[:, [0, 2, 1]])
            prev = ids
        V.append(np.array([[c[0], c[1], z]]))
        tt = np.c_[prev[j], prev[(j + 1) % m], np.full(m, nv)]
        nv += 1
        F.append(tt if top else tt[:, [0, 2, 1]])
    return merge_vertices(np.vstack(V), np.vstack(F), tol=1e-9)


def house_outline(left: float = 38.0, right: float = 43.0, width: float = 2.0, wall: float = 1.0):
    """A pentagon: a 2 x 1 rectangle under a roof rising at `left` and `right`
    degrees, so the outline turns by 180 - 90 - angle (52 and 47 degrees by
    default) at the tops of the walls: corners of 128 and 133 degrees, which
    rounding makes 90 and a CAD user may mean as smooth; 99 at the ridge."""
    tl, tr = np.tan(np.radians(left)), np.tan(np.radians(right))
    x = width * tr / (tl + tr)
    return np.array([[0.0, 0.0], [width, 0.0], [width, wall], [x, wall + tl * x], [0.0, wall]])


def prism_example():
    """CAD-like: the house pentagon extruded, no interior curves.  Edges
    sharper than 50 degrees are sharp: the caps' outlines, the right-angled
    vertical edges, the ridge (81 degrees) and the 52-degree wall-top edge;
    the walls bend smoothly by 47 degrees at the other wall top.  The caps'
    outline corners of 128 and 133 degrees are ambiguous; rounded, each cap
    has five convex corners and Poincare-Hopf fails by 1/4 per cap;
    corners.py makes the 133-degree one smooth: the smaller rounding, and
    the one a field without singular curves can follow (two sharp edges
    there; see corners.py).  With sharp_angle 30 (the 47-degree edge sharp
    too) the smooth corner would end that crease, which is then treated as
    smooth as well (corners.py); with 60 the 128-degree corner would be a
    corner between smooth walls, which no field follows without a singular
    curve ending there: refused before meshing (LM used to end at its cap
    with a penalty of 5.0e3)."""
    V, F = prism_surface(house_outline(), 0.8)
    return V, F, Network(curves=[], sharp_angle=50.0)


def voxel_surface(occupied, cell: float = 1.0, n: int = 2):
    """Boundary of a union of voxels (occupied: 3D bool array; voxel (i, j, k)
    is [i, i+1] x [j, j+1] x [k, k+1] times cell), each voxel face split into
    n x n quads of 2 triangles, outward oriented.  The union must be a
    manifold solid (no voxels touching along an edge or a corner only)."""
    occ = np.pad(np.asarray(occupied, bool), 1)
    V, F = [], []
    nv = 0
    g = np.linspace(0.0, 1.0, n + 1)
    for axis in range(3):
        u, v = [a for a in range(3) if a != axis]
        d = np.diff(occ.astype(np.int8), axis=axis)  # +1: empty -> full (face normal -axis)
        for sign in (1, -1):
            for idx in np.argwhere(d == sign):
                base = idx - 1  # voxel coordinates of the lower cell (padding removed)
                corner = base.astype(float)
                corner[axis] += 1.0
                uu, vv = np.meshgrid(g, g, indexing="ij")
                P = np.zeros((n + 1, n + 1, 3))
                P[..., axis] = corner[axis]
                P[..., u] = corner[u] + uu
                P[..., v] = corner[v] + vv
                ids = np.arange((n + 1) ** 2).reshape(n + 1, n + 1) + nv
                a, b, c, e = ids[:-1, :-1], ids[1:, :-1], ids[1:, 1:], ids[:-1, 1:]
                tris = np.vstack([np.c_[a.ravel(), b.ravel(), c.ravel()], np.c_[a.ravel(), c.ravel(), e.ravel()]])
                # (u, v) order has normal +axis when (axis, u, v) is cyclic;
                # the outward normal is -axis where the full cell is above
                outward_plus = sign == -1
                if (((u - axis) % 3 == 1) != outward_plus):
                    tris = tris[:, [0, 2, 1]]
                V.append(P.reshape(-1, 3) * cell)
                F.append(tris)
                nv += (n + 1) ** 2
    return merge_vertices(np.vstack(V), np.vstack(F), tol=1e-9 * cell)


def genus2_example(slant: float = 25.0):
    """A 2.5 x 1.5 x 0.5 block with two square through-holes (genus 2, sharp
    edges everywhere) and two straight feature curves (sigma = 0) from the
    bottom to the top, slanted by `slant` degrees off the normal: the
    intake bends both ends of each onto the normals, and the field follows
    their tangent.  A +1/4, -1/4 pair of singular curves there instead
    solves too (tests/test_handles.py)."""
    occ = np.ones((5, 3, 1), bool)
    occ[1, 1, 0] = occ[3, 1, 0] = False
    V, F = voxel_surface(occ, 0.5)
    t = 0.5 * np.tan(np.radians(slant))
    curves = []
    for k, x in enumerate((0.25, 2.25)):
        a = np.array([x, 0.75 - t / 2, 0.0])
        b = np.array([x, 0.75 + t / 2, 0.5])
        curves.append(Curve(_segment(a, b, 6), sigma=0.0, role="feature", name=f"slanted {k}"))
    return V, F, Network(curves=curves, sharp_angle=30.0)


def extruded_cells_surface(cells, height: float = 0.5, n: int = 4):
    """Closed surface of a prism over a union of unit squares (cells: (i, j)
    pairs), extruded along z from 0 to height; every unit of the outline is
    split into n, the height into ceil(n * height) (quads split into two
    triangles, outward)."""
    cells = {tuple(c) for c in cells}
    nz = max(1, int(np.ceil(n * height)))
    quads = []
    for i, j in cells:
        for u in range(n):
            for v in range(n):
                x0, y0 = i + u / n, j + v / n
                x1, y1 = x0 + 1 / n, y0 + 1 / n
                quads.append([(x0, y0, 0), (x0, y1, 0), (x1, y1, 0), (x1, y0, 0)])  # bottom, normal -z
                quads.append([(x0, y0, height), (x1, y0, height), (x1, y1, height), (x0, y1, height)])
        for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            if (i + di, j + dj) in cells:
                continue
            for u in range(n):
                for w in range(nz):
                    t0, t1 = u / n, (u + 1) / n
                    z0, z1 = w * height / nz, (w + 1) * height / nz
                    if di:
                        x = i + (1 if di > 0 else 0)
                        a, b = (x, j + t0), (x, j + t1)
                        if di < 0:
                            a, b = b, a
                    else:
                        y = j + (1 if dj > 0 else 0)
                        a, b = (i + t1, y), (i + t0, y)
                        if dj < 0:
                            a, b = b, a
                    quads.append([(*a, z0), (*b, z0), (*b, z1), (*a, z1)])
    Q = np.array(quads, float)
    V = Q.reshape(-1, 3)
    idx = np.arange(len(V)).reshape(-1, 4)
    F = np.vstack([idx[:, [0, 1, 2]], idx[:, [0, 2, 3]]])
    return merge_vertices(V, F)


def l_prism_example(height: float = 0.5):
    """CAD-like part: an L-shaped prism (three unit squares) with sharp edges
    everywhere and one feature curve across its thickness in the corner
    square (bench/run_bench.py's real-shape row)."""
    V, F = extruded_cells_surface([(0, 0), (1, 0), (0, 1)], height)
    curve = Curve(_segment((0.5, 0.5, 0.0), (0.5, 0.5, height), 4), sigma=0.0, role="feature", name="corner post")
    return V, F, Network(curves=[curve], sharp_angle=30.0)


EXAMPLES = {
    "cube": cube_example,
    "cylinder": cylinder_example,
    "torus": torus_example,
    "ball": ball_example,
    "plate": plate_example,
    "prism": prism_example,
    "genus2": genus2_example,
}


def load_example(name: str):
    """(V, F, Network) of a built-in example."""
    try:
        return EXAMPLES[name]()
    except KeyError:
        raise ValueError(f"unknown example {name!r}; choose one of {', '.join(EXAMPLES)}") from None
