"""Stages 3-5 of hex meshing: the map system, the seamless map and the
integer-grid map.

The map u gives each tet corner a point of R^3 (parameter units: cells).
It minimises the frame-fitting energy (AlgoHex's FrameFittingElement3D,
CubeCover's least squares, paper §5 "Meshing")

    E(u) = sum_t V_t || cell_t * grad(u_t) F_t - I ||_F^2

(cell_t: the cell size, or a size field's at tet t, sizing.py) subject to
linear constraints:

* across a face off the cut the charts agree (corners are merged: one
  unknown per *wedge*, the corners of a vertex joined through non-cut faces);
* across a cut face of patch P, ``u_to = G[M_P] u_from + tau_P`` (one
  translation per manifold cut patch, AlgoHex's trick);
* a boundary face keeps the coordinate along its normal axis constant, a
  curve edge (singular or feature) the two coordinates across its axis.

Every constraint relates at most two scalar unknowns up to translations, so
they are eliminated exactly by an affine union-find over the scalars (with
offsets that are combinations of the tau): classes of scalars that must be
equal up to sign and a translation, classes fixed by a cycle (the two
coordinates of a singular edge's vertex, fixed by its quarter-turn
holonomy), and linear relations among the translations alone (at cut
junctions).  Those relations, and the parity of the singular lines, are
eliminated over the integers with unimodular pivots (``IntegerSpace``), so
that integer values of the remaining variables give integer translations,
boundary planes and curve lines: the integer-grid map is then a rounding of
plain coordinates of the reduced vector z.  Building this system is the
stage "map system" (``map_system``: where some tets are flat in every map
it allows, their interior edges between two constrained vertices are split
(``freeing_edges``) and the transitions and the system are built again).

The seamless map and the integer-grid map (stages "seamless map" and
"integer-grid map").  The integer unknowns of the reduced system are plain
coordinates of z: the translations across the cut, the boundary planes and
the curve lines.  Their energy, with every other unknown at its optimum,
is a small dense quadratic: with z split into continuous y and integer w,

    y(w) = Q_yy^-1 (b_y - Q_yw w),
    E(w) = 1/2 w' S w - c' w,   S = Q_ww - Q_wy Q_yy^-1 Q_yw,

one solve of Q_yy per integer unknown (and one for y0) gives S
(``_Reduced``: a sparse factorisation on small systems, conjugate gradients
with an algebraic multigrid preconditioner on large ones, whose fill would
grow faster than the mesh).  Its minimum over real w is the seamless map
(``seamless_map``); greedy rounding of w (quantize.py) gives the
integer-grid map (``integer_grid_map``), with no re-solve of the large
system between roundings.  Inverted tets left by the rounding are then
stiffened (MIQ; AlgoHex's ``update_cell_weights``): their weight grows and
the continuous unknowns are solved again (conjugate gradients
preconditioned by the first solve's factorisation or multigrid), keeping
the best map; a map still folded is untangled with its integers fixed
(``optimise_map``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

from ..errors import HexMeshError
from ..linalg.amg import AMG
from ..linalg.lbfgs import lbfgs
from ..linalg.multipcg import pcg_columns
from ..linalg.parallel import parallel
from ..linalg.rotations import CUBE_GROUP
from ..mesh.tetmesh import TET_EDGE_OPPOSITE, TET_FACES, TetMesh
from .curve_edges import CurveEdgeError, CurveEdgeMesh, split_edges
from .extract import snap
from .quality import det3
from .quantize import greedy_round
from .smooth import SHARP_DIHEDRAL, foldover_free
from .transitions import GROUP_INVERSE, GROUP_PRODUCT, Transitions, edge_rings

G = CUBE_GROUP


class MapError(CurveEdgeError):
    """The constraints of the map cannot be met (an inconsistent field)."""


# ============================================================== cut patches


def cut_patches(mesh: TetMesh, tr: Transitions):
    """Group the cut faces into patches joined across interior non-singular
    edges that hold exactly two cut faces, with an orientation per face.

    Returns (patch (k,) per interior face, -1 off the cut; orient (k,) +-1,
    +1 where the face maps A -> B as the patch does; patch_M (P,) index).
    """
    k = len(tr.faces)
    cutpos = np.nonzero(tr.cut)[0]
    face_pos = np.full(mesh.n_faces, -1, dtype=np.int64)
    face_pos[tr.faces] = np.arange(k)
    fe = mesh.face_edges[tr.faces[cutpos]]  # (c, 3)
    e, cnt = np.unique(fe, return_counts=True)
    sing = np.zeros(mesh.n_edges, bool)
    sing[tr.singular_edges] = True
    join = e[(cnt == 2) & ~sing[e] & ~mesh.is_boundary_edge[e]]
    rings = edge_rings(mesh, join, face_pos)
    ab = tr.tets
    links = {}  # cut position -> list of (other position, relative sign)
    for edge in join.tolist():
        order, crossed = rings[edge]
        idx = [i for i, p in enumerate(crossed) if tr.cut[p]]
        if len(idx) != 2:
            raise MapError("internal: a cut edge's ring holds another count of cut faces")
        i, j = idx
        pi, pj = crossed[i], crossed[j]
        bi_in_x = ab[pi, 1] == order[i + 1]  # arc X runs from face i to face j
        bj_in_x = ab[pj, 1] == order[j]
        s = 1 if bi_in_x == bj_in_x else -1
        links.setdefault(pi, []).append((pj, s))
        links.setdefault(pj, []).append((pi, s))
    patch = np.full(k, -1, dtype=np.int64)
    orient = np.zeros(k, dtype=np.int64)
    patch_M = []
    M = tr.transition
    for p0 in cutpos.tolist():
        if patch[p0] >= 0:
            continue
        pid = len(patch_M)
        patch_M.append(int(M[p0]))
        patch[p0], orient[p0] = pid, 1
        stack = [p0]
        while stack:
            p = stack.pop()
            for q, s in links.get(p, ()):
                o = orient[p] * s
                if patch[q] < 0:
                    patch[q], orient[q] = pid, o
                    stack.append(q)
                elif orient[q] != o:
                    raise MapError("a cut patch is not orientable (the field's transitions are inconsistent)")
    patch_M = np.array(patch_M, dtype=np.int64)
    # every face of a patch carries its transition (holonomy is the identity
    # around the edges that join them)
    on = patch >= 0
    want = np.where(orient[on] > 0, patch_M[patch[on]], GROUP_INVERSE[patch_M[patch[on]]])
    if np.any(want != M[on]):
        raise MapError(f"{int(np.sum(want != M[on]))} cut faces disagree with their patch's transition")
    return patch, orient, patch_M


# ==================================================================== wedges


def corner_wedges(mesh: TetMesh, tr: Transitions):
    """Wedge id per tet corner (#T, 4) (corners of one vertex joined through
    non-cut faces) and the vertex of each wedge."""
    T = mesh.tets
    nT = len(T)
    keep = ~tr.cut
    A, B = tr.tets[keep, 0], tr.tets[keep, 1]
    Fv = mesh.faces[tr.faces[keep]]
    rows, cols = [], []
    for k in range(3):
        x = Fv[:, k]
        la = np.argmax(T[A] == x[:, None], axis=1)
        lb = np.argmax(T[B] == x[:, None], axis=1)
        rows.append(4 * A + la)
        cols.append(4 * B + lb)
    r, c = np.concatenate(rows), np.concatenate(cols)
    g = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(4 * nT, 4 * nT))
    n, lab = connected_components(g, directed=False)
    wedge = lab.reshape(nT, 4)
    wv = np.empty(n, dtype=np.int64)
    wv[wedge.reshape(-1)] = T.reshape(-1)
    return wedge, wv


# ============================================================ affine union-find


class AffineUnionFind:
    """Scalars x_s related by rows ``a x_s + b x_r + e.tau = 0`` (a, b in
    {0, +-1}): each scalar is ``sign * x_root + off . tau``; a root may be
    fixed to ``val . tau``; rows among the tau alone are collected."""

    def __init__(self, n: int, ntau: int):
        self.parent = np.arange(n)
        self.sign = np.ones(n)
        self.off: dict[int, np.ndarray] = {}
        self.fixed: dict[int, np.ndarray] = {}
        self.ntau = ntau
        self.tau_rows: list[np.ndarray] = []

    def _zero(self):
        return np.zeros(self.ntau)

    def find(self, s: int):
        path = []
        while self.parent[s] != s:
            path.append(s)
            s = self.parent[s]
        root = s
        # compress: re-express every scalar on the path directly on the root
        sg, off = 1.0, self._zero()
        for v in reversed(path):
            o = self.off.get(v)
            # x_v = sign_v x_p + off_v ; x_p = sg x_root + off (accumulated)
            sg, off = self.sign[v] * sg, self.sign[v] * off + (o if o is not None else 0.0)
            self.parent[v], self.sign[v] = root, sg
            if np.any(off):
                self.off[v] = off.copy()
            else:
                self.off.pop(v, None)
        if not path:
            return root, 1.0, self._zero()
        s0 = path[0]
        return root, float(self.sign[s0]), self.off.get(s0, self._zero()).copy()

    def flatten(self):
        """(root, sign, offsets as a sparse (n, ntau) matrix) of every scalar:
        x_s = sign_s x_root(s) + offsets[s] . tau, by pointer jumping."""
        n = len(self.parent)
        parent, sign = self.parent.copy(), self.sign.copy()
        if self.off:
            keys = np.array(sorted(self.off), dtype=np.int64)
            dense = np.array([self.off[int(k)] for k in keys]).reshape(-1, self.ntau)
            P = sp.csr_matrix((np.ones(len(keys)), (keys, np.arange(len(keys)))), shape=(n, len(keys)))
            O = (P @ sp.csr_matrix(dense)).tocsr()
        else:
            O = sp.csr_matrix((n, self.ntau))
        while True:
            pp = parent[parent]
            if np.array_equal(pp, parent):
                break
            # x_s = sign_s (sign_p x_pp + O_p) + O_s
            O = (O + sp.diags(sign) @ O[parent]).tocsr()
            sign = sign * sign[parent]
            parent = pp
        return parent, sign, O

    def add(self, terms, e: np.ndarray | None):
        """Add the row sum(c * x_s for s, c in terms) + e . tau = 0."""
        e = self._zero() if e is None else np.asarray(e, float).copy()
        coef: dict[int, float] = {}
        for s, c in terms:
            if c == 0:
                continue
            r, sg, off = self.find(int(s))
            coef[r] = coef.get(r, 0.0) + c * sg
            e += c * off
        for r in [r for r, c in coef.items() if c == 0.0]:
            del coef[r]
        for r in [r for r in coef if r in self.fixed]:
            e += coef.pop(r) * self.fixed[r]
        if not coef:
            if np.any(np.abs(e) > 1e-12):
                self.tau_rows.append(e)
            return
        if len(coef) == 1:
            (r, c), = coef.items()
            self.fixed[r] = -e / c
            return
        (r1, c1), (r2, c2) = coef.items()
        if abs(c2) != 1.0 and abs(c1) == 1.0:
            r1, c1, r2, c2 = r2, c2, r1, c1
        if abs(c2) != 1.0:
            raise MapError("internal: a constraint with coefficients other than +-1")
        # x_r2 = -(c1 / c2) x_r1 - e / c2
        self.parent[r2] = r1
        self.sign[r2] = -c1 / c2
        off = -e / c2
        if np.any(off):
            self.off[r2] = off
        else:
            self.off.pop(r2, None)


# ============================================================ integer space


class IntegerSpace:
    """Unknowns q = [tau; lines] with linear relations among them, reduced
    to free integer variables k with q = N k, N integer: every integer k
    gives integer q, and every integer q meeting the relations comes from an
    integer k.

    A relation r.q = 0 (rational, from the map's cycles: halves at most) is
    scaled to integers and reduced by Euclid's algorithm on its coefficients
    in k -- unimodular column operations on N -- until one coefficient g is
    left; g k_p = 0 then removes k_p.  (A pivot on a coefficient other than
    +-1 without this would leave N with fractions: a boundary plane at 16/3
    on a tet-edge ball.)"""

    def __init__(self, n: int):
        self.N = np.eye(n)
        self.cols = np.arange(n)  # the original unknown each k stands for (before column operations)
        self.nonunimodular = 0  # relations whose coefficients were not dyadic (reduced in floating point)

    def add(self, row: np.ndarray) -> None:
        r = row @ self.N
        r[np.abs(r) < 1e-9] = 0.0
        if not np.any(r):
            return
        scale = 1.0
        while scale <= 4096 and not np.allclose(r * scale, np.rint(r * scale), rtol=0, atol=1e-7):
            scale *= 2.0
        if scale > 4096:
            # not a relation the map makes: eliminate in floating point
            self.nonunimodular += 1
            p = int(np.argmax(np.abs(r)))
            self._eliminate(p, -r / r[p])
            return
        ri = np.rint(r * scale).astype(np.int64)
        nz = np.nonzero(ri)[0]
        while len(nz) > 1:
            # the smallest coefficient reduces the others (Euclid), one column
            # operation each: col_i -= q col_j, r_i -= q r_j
            j = nz[np.argmin(np.abs(ri[nz]))]
            for i in nz:
                if i == j:
                    continue
                q = ri[i] // ri[j]
                if q:
                    ri[i] -= q * ri[j]
                    self.N[:, i] -= q * self.N[:, j]
            nz = np.nonzero(ri)[0]
        # g k_p = 0: k_p is gone
        p = int(nz[0])
        self.N = np.delete(self.N, p, axis=1)
        self.cols = np.delete(self.cols, p)

    def _eliminate(self, p: int, coeff: np.ndarray) -> None:
        """k_p = coeff . k (coeff[p] ignored), substituted into q = N k."""
        c = np.delete(coeff, p)
        self.N = np.delete(self.N, p, axis=1) + np.outer(self.N[:, p], c)
        self.cols = np.delete(self.cols, p)


# ================================================================== the system


@dataclass
class MapSystem:
    """The reduced system of the seamless map (module docs).

    mesh, frames : the split mesh and its combed tet frames
    cell         : the target cell size (model units)
    wedge        : (#T, 4) wedge id per corner; wedge_vertex (#W,)
    X            : (12 #T, nz) sparse: corner coordinates from z, row
                   12 t + 3 c + a (tet t, corner c, coordinate a)
    x0           : (12 #T,) the constant part (pinned vertex), usually 0
    Q, b         : the energy 1/2 z'Qz - b'z (+ const) of z
    integer      : (nz,) bool, z entries that must be integers in an
                   integer-grid map
    boundary_axis: (#bF,) normal axis per boundary face of the split mesh,
                   boundary_angle its angle to the normal (degrees)
    stats        : sizes and counts
    """

    mesh: TetMesh
    frames: np.ndarray
    cell: float
    wedge: np.ndarray
    wedge_vertex: np.ndarray
    X: sp.csr_matrix
    Q: sp.csr_matrix
    b: np.ndarray
    integer: np.ndarray
    tet_weight: np.ndarray
    grad: np.ndarray
    boundary_angle: np.ndarray
    LX: sp.csr_matrix
    stats: dict = field(default_factory=dict)

    def least_squares(self):
        """(LX, w): the residuals cell * grad(u) F - I of every tet, 9 rows
        per tet, are LX z - vec(I), weighted by w (the tet volumes)."""
        return self.LX, np.repeat(self.tet_weight, 9)

    def corners(self, z: np.ndarray) -> np.ndarray:
        """(#T, 4, 3) parameter points of the tet corners."""
        return (self.X @ z).reshape(-1, 4, 3)

    def energy(self, z: np.ndarray) -> float:
        J = np.einsum("tca,tcj->taj", self.corners(z), self.grad)  # cell * grad(u) F
        return float(np.sum(self.tet_weight[:, None, None] * (J - np.eye(3)) ** 2))


_PERM = np.argmax(np.abs(G), axis=2)  # (24, 3): row a of G[m] reads coordinate _PERM[m, a] ...
_SIGN = np.take_along_axis(G, _PERM[..., None], axis=2)[..., 0]  # ... times _SIGN[m, a]


def _cut_relations(mesh, tr, wedge, patch, orient, patch_M):
    """The relations between the wedges on either side of each cut face, at
    each of its vertices, forward and backward in turn: (from, to, group
    element, patch, direction) arrays with u_to = G[m] u_from + (tau_P
    forward, -G[m] tau_P backward)."""
    T = mesh.tets
    cutpos = np.nonzero(tr.cut)[0]
    ab = tr.tets[cutpos]
    fwd = orient[cutpos] > 0
    src, dst = np.where(fwd, ab[:, 0], ab[:, 1]), np.where(fwd, ab[:, 1], ab[:, 0])
    Fv = mesh.faces[tr.faces[cutpos]]
    ws = np.take_along_axis(wedge[src], np.argmax(T[src][:, None, :] == Fv[:, :, None], axis=2), axis=1).ravel()
    wd = np.take_along_axis(wedge[dst], np.argmax(T[dst][:, None, :] == Fv[:, :, None], axis=2), axis=1).ravel()
    pid = np.repeat(patch[cutpos].astype(np.int64), 3)
    m = patch_M[pid].astype(np.int64)
    return (np.c_[ws, wd].ravel(), np.c_[wd, ws].ravel(), np.c_[m, GROUP_INVERSE[m]].ravel(),
            np.repeat(pid, 2), np.tile([1, -1], len(ws)))


def _translations(frm, rel, Bs, mm, pp, dd, ntau):
    """(3 k, ntau) sparse: G[m] B_from + (tau_P forward, -G[m] tau_P
    backward) across the k relations ``rel``, B_w the rows 3 w + a of
    ``Bs``."""
    k = len(rel)
    m = mm[rel]
    rows = np.arange(3 * k)
    cols = (3 * frm[rel][:, None] + _PERM[m]).ravel()
    S = sp.csr_matrix((_SIGN[m].ravel(), (rows, cols)), shape=(3 * k, Bs.shape[0]))
    fw = dd[rel] > 0
    # forward: the block of tau_P as it is; backward: -G[m] on it
    tcol = np.where(fw[:, None], np.arange(3)[None, :], _PERM[m]) + 3 * pp[rel][:, None]
    tval = np.where(fw[:, None], 1.0, -_SIGN[m])
    return S @ Bs + sp.csr_matrix((tval.ravel(), (rows, tcol.ravel())), shape=(3 * k, ntau))


def _wedge_expressions(mesh, tr, wedge, wv, patch, orient, patch_M, ntau):
    """Per wedge: A (group index) and B (3, ntau) with u_w = G[A] r_v + B tau,
    by a depth-first search over each vertex's wedges through the cut; cycle
    rows (scalar terms, tau row) for the union-find, and (k, ntau) the
    cycles' rows among the tau alone."""
    nW = len(wv)
    frm, to, mm, pp, dd = _cut_relations(mesh, tr, wedge, patch, orient, patch_M)
    A = np.zeros(nW, dtype=np.int64)
    # the search (group indices only): the relation each wedge is reached by,
    # its depth, and the relations that close a cycle, in the order met
    order = np.argsort(frm, kind="stable")
    ptr = np.searchsorted(frm[order], np.arange(nW + 1)).tolist()
    first = np.unique(frm, return_index=True)[1]
    seen = [False] * nW
    by = np.full(nW, -1, dtype=np.int64)
    depth = np.zeros(nW, dtype=np.int64)
    cycles = []
    to_l, mm_l, order_l, P = to.tolist(), mm.tolist(), order.tolist(), GROUP_PRODUCT.tolist()
    Al, dl, byl = A.tolist(), depth.tolist(), by.tolist()
    for w0 in frm[np.sort(first)].tolist():
        if seen[w0]:
            continue
        seen[w0] = True
        stack = [w0]
        while stack:
            w = stack.pop()
            for j in order_l[ptr[w]:ptr[w + 1]]:
                w2 = to_l[j]
                if seen[w2]:
                    cycles.append(j)
                    continue
                seen[w2] = True
                Al[w2], dl[w2], byl[w2] = P[mm_l[j]][Al[w]], dl[w] + 1, j
                stack.append(w2)
    A, depth, by = np.array(Al, dtype=np.int64), np.array(dl), np.array(byl, dtype=np.int64)
    # B along the search's tree, a depth at a time (parents first)
    Bs = sp.csr_matrix((3 * nW, ntau))
    for d in range(1, int(depth.max(initial=0)) + 1):
        ws = np.nonzero(depth == d)[0]
        new = _translations(frm, by[ws], Bs, mm, pp, dd, ntau).tocoo()
        place = sp.csr_matrix((new.data, ((3 * ws)[new.row // 3] + new.row % 3, new.col)), shape=Bs.shape)
        Bs = (Bs + place).tocsr()
    Bs.eliminate_zeros()
    nzw = np.unique(Bs.nonzero()[0] // 3)
    dense = Bs[(3 * nzw[:, None] + np.arange(3)).ravel()].toarray().reshape(len(nzw), 3, ntau)
    Bd = dict(zip(nzw.tolist(), dense))
    # a cycle: G[A_w2] r + B_w2 tau = G[A_new] r + B_new tau
    cyc = np.array(cycles, dtype=np.int64)
    w, w2 = frm[cyc], to[cyc]
    D = G[A[w2]] - G[GROUP_PRODUCT[mm[cyc], A[w]]]
    sel = sp.csr_matrix((np.ones(3 * len(cyc)), (np.arange(3 * len(cyc)), (3 * w2[:, None] + np.arange(3)).ravel())),
                        shape=(3 * len(cyc), 3 * nW))
    # row 3 i + a: coordinate a of cycle i, kept sparse (dense, the ball's
    # 25k cycles at 306 translations were 188 MB and 2.5 s of the stage)
    E = (sel @ Bs - _translations(frm, cyc, Bs, mm, pp, dd, ntau)).tocsr()
    v = wv[w]
    terms = (D != 0).any(axis=2).reshape(-1)
    big = np.abs(E.data) > 1e-12
    tau_only = ~terms & (np.bincount(np.repeat(np.arange(E.shape[0]), np.diff(E.indptr))[big],
                                     minlength=E.shape[0]) > 0)
    with_terms = np.nonzero(terms)[0]
    Et = E[with_terms].toarray()
    rows = [([(3 * int(v[r // 3]) + j, D[r // 3, r % 3, j]) for j in range(3) if D[r // 3, r % 3, j] != 0], Et[k])
            for k, r in enumerate(with_terms.tolist())]
    return A, Bd, rows, E[np.nonzero(tau_only)[0]].toarray()


def build_map_system(cem: CurveEdgeMesh, tr: Transitions, cell: float, rel: np.ndarray | None = None) -> MapSystem:
    """Assemble the reduced seamless-map system (module docs).

    Parameters
    ----------
    cem : CurveEdgeMesh
    tr : Transitions
        combed frames, transitions and cut of cem.mesh
    cell : float
        the target hex edge length, in model units
    rel : (#T,) float array, optional
        a size field: tet t fits its gradient to cells of ``cell * rel[t]``
        (sizing.py); None: ``cell`` everywhere

    Returns
    -------
    MapSystem
    """
    mesh = cem.mesh
    nV = mesh.n_vertices
    patch, orient, patch_M = cut_patches(mesh, tr)
    ntau = 3 * len(patch_M)
    wedge, wv = corner_wedges(mesh, tr)
    A, Bd, cycle_rows, tau_rows = _wedge_expressions(mesh, tr, wedge, wv, patch, orient, patch_M, ntau)
    coords = _CornerCoordinates(mesh.tets, wedge, A, Bd, ntau)
    rows, angle = _equal_coordinates(cem, tr, coords)
    uf, integer_scalar = _union_find(nV, ntau, rows, cycle_rows, tau_rows, coords)
    # the gauge (a global translation): the coordinates of one vertex that
    # lies on the integer grid anyway (a node, a curve's end, a corner) are
    # 0 -- the vertex's own coordinates, which differ from their class's
    # root by a sign and a translation
    pin = _pin_vertex(cem, integer_scalar)
    for j in range(3):
        uf.add([(3 * pin + j, 1.0)], None)
    roots, sgn, Off = uf.flatten()
    root_int = np.zeros(3 * nV, bool)
    np.logical_or.at(root_int, roots, integer_scalar)
    isp, fixed_int = _integer_space(uf, root_int, ntau)
    N = isp.N
    Ntau, Nline = N[:ntau], N[ntau:]
    nk = N.shape[1]
    is_root = roots == np.arange(3 * nV)
    free = is_root & ~np.isin(np.arange(3 * nV), list(uf.fixed))
    col = np.full(3 * nV, -1, dtype=np.int64)
    col[free] = np.arange(int(free.sum()))
    nr = int(free.sum())
    # a fixed root's value: its line's integer unknown, or its translations
    fixed_val = {r: Nline[i] for i, r in enumerate(fixed_int)}
    for r, val in uf.fixed.items():
        fixed_val.setdefault(r, val @ Ntau)
    Xm = _corner_matrix(coords, roots, sgn, Off, col, fixed_val, Ntau, nr, nk)
    LX, Q, bvec, coef, vol = _fitting_energy(mesh, tr.frames, cell if rel is None else cell * rel, Xm)
    integer = np.zeros(nr + nk, bool)
    integer[col[free & root_int]] = True
    integer[nr:] = True
    stats = {"patches": len(patch_M), "cut_faces": int(tr.cut.sum()), "wedges": len(wv), "unknowns": nr + nk,
             "integer_unknowns": int(integer.sum()), "translations": nk, "tau_relations": len(uf.tau_rows),
             "fixed_scalars": len(uf.fixed), "nonunimodular_pivots": isp.nonunimodular,
             "boundary_angle_max": float(angle.max()) if len(angle) else 0.0}
    return MapSystem(mesh, tr.frames, cell, wedge, wv, Xm, Q, bvec, integer, vol, coef, angle, LX, stats)


class _CornerCoordinates:
    """Which scalar unknown (vertex v, component j), with which sign and which
    translation row, coordinate a of a tet corner reads: u_w = G[A_w] r_v +
    B_w tau for the corner's wedge w."""

    def __init__(self, T, wedge, A, Bd, ntau):
        Ga = G[A]  # (nW, 3, 3)
        self.T, self.wedge = T, wedge
        self.jmax = np.argmax(np.abs(Ga), axis=2)  # (nW, 3)
        self.gsign = np.take_along_axis(Ga, self.jmax[..., None], axis=2)[..., 0]
        bw = np.array(sorted(Bd), dtype=np.int64)
        self.B = np.array([Bd[int(w)] for w in bw]) if len(bw) else np.zeros((0, 3, ntau))
        self.brow = np.full(len(A), -1, dtype=np.int64)
        self.brow[bw] = np.arange(len(bw))

    def __call__(self, t, c, a):
        """(scalar, sign, row into self.B or -1) of coordinate a of corner c
        of tets t (arrays)."""
        w = self.wedge[t, c]
        return 3 * self.T[t, c] + self.jmax[w, a], self.gsign[w, a], self.brow[w]


def _equal_coordinates(cem: CurveEdgeMesh, tr: Transitions, coords: _CornerCoordinates):
    """The coordinate equalities: on a boundary face the coordinate along its
    normal's axis, along a curve edge the two across the curve's axis.
    Returns ((S0, G0, B0, S1, G1, B1, AX) arrays of the row pairs, the
    boundary faces' angles to their axis in degrees)."""
    mesh = cem.mesh
    T, X, F = mesh.tets, mesh.vertices, tr.frames
    rows0, rows1 = [], []  # (tets, corners, coordinate) that must be equal
    bf = mesh.boundary_faces
    bt = mesh.face_tets[bf, 0]
    on_face = (T[bt][:, :, None] == mesh.faces[bf][:, None, :]).any(axis=2)
    loc = np.argmax(~on_face, axis=1)  # the vertex off the face
    P3 = X[T[bt][np.arange(len(bt))[:, None], TET_FACES[loc]]]
    n = np.cross(P3[:, 1] - P3[:, 0], P3[:, 2] - P3[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    proj = np.abs(np.einsum("tji,tj->ti", F[bt], n))  # |F^T n|
    axis = np.argmax(proj, axis=1)
    angle = np.degrees(np.arccos(np.clip(proj.max(axis=1), -1.0, 1.0)))
    cs = TET_FACES[loc]  # (b, 3) corners on the face
    for m in (1, 2):
        rows0.append((bt, cs[:, 0], axis))
        rows1.append((bt, cs[:, m], axis))
    te = mesh.tet_edges
    for ch in cem.chains:
        e = mesh.edge_index(ch.vertices[:-1], ch.vertices[1:])
        r, c = np.nonzero(np.isin(te, e))
        first = {}
        for t, k in zip(r.tolist(), c.tolist()):
            first.setdefault(int(te[t, k]), t)
        tt = np.array([first[int(x)] for x in e], dtype=np.int64)  # one tet per chain edge
        cx = np.argmax(T[tt] == ch.vertices[:-1, None], axis=1)
        cy = np.argmax(T[tt] == ch.vertices[1:, None], axis=1)
        k = np.argmax(np.abs(np.einsum("tji,tj->ti", F[tt], ch.tangents(X))), axis=1)
        for d in (1, 2):
            rows0.append((tt, cx, (k + d) % 3))
            rows1.append((tt, cy, (k + d) % 3))
    S0, G0, B0 = (np.concatenate(x) for x in zip(*[coords(*r) for r in rows0]))
    S1, G1, B1 = (np.concatenate(x) for x in zip(*[coords(*r) for r in rows1]))
    AX = np.concatenate([r[2] for r in rows0])
    return (S0, G0, B0, S1, G1, B1, AX), angle


def _union_find(nV: int, ntau: int, rows, cycle_rows, tau_rows, coords: _CornerCoordinates):
    """The affine union-find of every constraint (module docs), and which
    scalars must be integers."""
    S0, G0, B0, S1, G1, B1, AX = rows
    integer_scalar = np.zeros(3 * nV, bool)
    integer_scalar[S0] = integer_scalar[S1] = True
    uf = AffineUnionFind(3 * nV, ntau)
    # equal scalars with no translation between them: merged at once
    plain = (B0 < 0) & (B1 < 0) & (G0 == G1)
    if plain.any():
        g = sp.coo_matrix((np.ones(int(plain.sum())), (S0[plain], S1[plain])), shape=(3 * nV, 3 * nV))
        _, lab = connected_components(g, directed=False)
        rep = np.full(lab.max() + 1, 3 * nV)
        np.minimum.at(rep, lab, np.arange(3 * nV))
        uf.parent = rep[lab]
    uf.tau_rows.extend(tau_rows)  # (deduplicated and sorted by _integer_space)
    for terms, e in cycle_rows:
        uf.add(terms, e)
    zero = np.zeros(ntau)
    for i in np.nonzero(~plain)[0].tolist():
        e0 = coords.B[B0[i], AX[i]] if B0[i] >= 0 else zero
        e1 = coords.B[B1[i], AX[i]] if B1[i] >= 0 else zero
        uf.add([(int(S0[i]), float(G0[i])), (int(S1[i]), -float(G1[i]))], e0 - e1)
    return uf, integer_scalar


def _integer_space(uf: AffineUnionFind, root_int: np.ndarray, ntau: int):
    """The integer unknowns: the translations and one line value per fixed
    root that must be an integer, reduced by their relations (IntegerSpace).
    Returns (IntegerSpace, the fixed integer roots in line order)."""
    fixed_int = [r for r in uf.fixed if root_int[r]]
    q = ntau + len(fixed_int)
    isp = IntegerSpace(q)
    if uf.tau_rows:
        # the same relation comes from many cycles: each distinct one once
        # (equal bytes first, -0 made 0: the numeric sort of np.unique's
        # axis=0 is slow on thousands of rows)
        R = np.round(np.array(uf.tau_rows), 9) + 0.0
        _, once = np.unique(R.view(np.dtype((np.void, R.itemsize * R.shape[1]))), return_index=True)
        R = np.unique(R[once], axis=0)
        for row in R:
            isp.add(np.r_[row, np.zeros(len(fixed_int))])
    for i, r in enumerate(fixed_int):
        row = np.r_[2.0 * uf.fixed[r], np.zeros(len(fixed_int))]
        row[ntau + i] = -2.0
        rk = row @ isp.N
        if np.all(np.isclose(np.rint(rk) % 2, 0)) and np.allclose(rk, np.rint(rk)):
            row = 0.5 * row  # integer already: the line value follows from the tau
        isp.add(row)
    return isp, fixed_int


def _corner_matrix(coords, roots, sgn, Off, col, fixed_val, Ntau, nr, nk) -> sp.csr_matrix:
    """X (12 #T, nz): corner coordinates from z = [free roots; integer k].
    Scalar s = sgn_s x_root + Off[s] . tau, x_root free (a column), fixed
    (fixed_val, in k) or pinned (0); tau = Ntau k.  ``coords``
    (_CornerCoordinates) gives each corner's scalar, sign and wedge B."""
    nT = len(coords.T)
    rows_i, cols_i, vals = [], [], []
    dense_rows, dense_vals = [], []
    Tf, Wf = coords.T.reshape(-1), coords.wedge.reshape(-1)
    # the translation parts in k: each wedge's B (coords.brow), each scalar's
    # offset (``Off``), each fixed root's value (its row of ``frow``)
    brow = coords.brow
    BN = np.einsum("bit,tk->bik", coords.B, Ntau)
    Off = Off.tocsr(copy=True)
    Off.eliminate_zeros()
    has_off = np.diff(Off.indptr) > 0
    frow = np.full(len(roots), -1, dtype=np.int64)
    fkeys = np.array(list(fixed_val), dtype=np.int64)
    frow[fkeys] = np.arange(len(fkeys))
    FV = np.array([fixed_val[int(r)] for r in fkeys]) if len(fkeys) else np.zeros((0, nk))
    for a in range(3):
        g = coords.gsign[Wf, a]
        s = 3 * Tf + coords.jmax[Wf, a]
        r = roots[s]
        rid = 12 * np.repeat(np.arange(nT), 4) + 3 * np.tile(np.arange(4), nT) + a
        ok = col[r] >= 0
        rows_i.append(rid[ok])
        cols_i.append(col[r[ok]])
        vals.append((g * sgn[s])[ok])
        # translation parts: the wedge's B, the scalar's offset, a fixed root's value
        need = np.nonzero((brow[Wf] >= 0) | has_off[s] | (frow[r] >= 0))[0]
        vec = np.zeros((len(need), nk))
        b = brow[Wf[need]]
        vec[b >= 0] += BN[b[b >= 0], a]
        o = has_off[s[need]]
        vec[o] += g[need[o], None] * (Off[s[need[o]]] @ Ntau)
        f = frow[r[need]]
        vec[f >= 0] += (g * sgn[s])[need[f >= 0], None] * FV[f[f >= 0]]
        keep = np.any(vec != 0, axis=1)
        dense_rows.append(rid[need[keep]])
        dense_vals.append(vec[keep])
    D = np.concatenate(dense_vals)
    if len(D):
        nzr, nzc = np.nonzero(np.abs(D) > 1e-12)
        rows_i.append(np.concatenate(dense_rows)[nzr])
        cols_i.append(nr + nzc)
        vals.append(D[nzr, nzc])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows_i), np.concatenate(cols_i))),
                         shape=(12 * nT, nr + nk))


def _fitting_energy(mesh: TetMesh, F: np.ndarray, cell, Xm: sp.csr_matrix):
    """The frame-fitting energy (module docs) in z: (LX, Q, b, coef, volumes)
    with residuals LX z - vec(I) per tet, weights the volumes, and coef the
    (#T, 4, 3) coefficients of cell * grad(u) F in the corners (cell: one
    size, or one per tet for a size field)."""
    T, X = mesh.tets, mesh.vertices
    nT = len(T)
    Xt = X[T]
    Mb = Xt[:, 1:] - Xt[:, :1]  # (nT, 3, 3) rows: edge vectors
    gl = np.zeros((nT, 4, 3))
    gl[:, 1:] = np.linalg.inv(np.transpose(Mb, (0, 2, 1)))  # rows: grad lambda_1..3
    gl[:, 0] = -gl[:, 1:].sum(axis=1)
    # (nT, 4, 3): corner c, frame axis j; cell: one size, or one per tet
    coef = np.asarray(cell, float)[..., None, None] * np.einsum("tck,tkj->tcj", gl, F)
    vol = mesh.tet_volumes
    # residual (t, a, j) = sum_c u[t, c, a] coef[t, c, j] - delta_aj
    rr, cc, vv = [], [], []
    for a in range(3):
        for j in range(3):
            for c in range(4):
                rr.append(9 * np.arange(nT) + 3 * a + j)
                cc.append(12 * np.arange(nT) + 3 * c + a)
                vv.append(coef[:, c, j])
    L = sp.csr_matrix((np.concatenate(vv), (np.concatenate(rr), np.concatenate(cc))), shape=(9 * nT, 12 * nT))
    LX = (L @ Xm).tocsr()
    w = np.repeat(vol, 9)
    Q = (LX.T @ sp.diags(w) @ LX).tocsr()
    b = np.asarray(LX.T @ (w * np.tile(np.eye(3).reshape(-1), nT))).ravel()
    return LX, Q, b, coef, vol


def _pin_vertex(cem: CurveEdgeMesh, integer_scalar: np.ndarray) -> int:
    """The vertex pinned at the origin: one whose three coordinates are
    integers in any integer-grid map (a node, a curve's end on the surface, a
    corner of the boundary), a node first; else the one with the most."""
    count = integer_scalar.reshape(-1, 3).sum(axis=1)
    if len(cem.node_vertices):
        return int(cem.node_vertices[0])
    return int(np.argmax(count))


def degenerate_tets(ms: MapSystem, seed: int = 0) -> np.ndarray:
    """Tets whose image is flat whatever the unknowns: their constraints
    put four corners in one plane or three on one line (a tet with all its
    vertices on one boundary chart, three on one sharp edge).  Found by
    evaluating the map at random unknowns, twice."""
    rng = np.random.default_rng(seed)
    flat = np.ones(len(ms.tet_weight), bool)
    for _ in range(2):
        U = ms.corners(rng.standard_normal(ms.X.shape[1]))
        E = U[:, 1:] - U[:, :1]
        scale = np.linalg.norm(E, axis=2).max(axis=1) ** 3
        flat &= np.abs(det3(E)) <= 1e-9 * np.maximum(scale, 1e-300)
    return np.nonzero(flat)[0]


def _kept_edges(cem: CurveEdgeMesh) -> np.ndarray:
    """(#E,) bool: the edges never split, the chain edges of every curve
    (singular or feature: its chain would lose the edge) and the sharp
    boundary edges."""
    mesh = cem.mesh
    kept = np.zeros(mesh.n_edges, bool)
    for ch in cem.chains:
        e = mesh.edge_index(ch.vertices[:-1], ch.vertices[1:])
        kept[e[e >= 0]] = True
    B = mesh.boundary
    sharp_local = B.edges[np.degrees(B.dihedral_angles) > SHARP_DIHEDRAL]
    if len(sharp_local):
        sv = mesh.boundary_vertices[sharp_local]
        e = mesh.edge_index(sv[:, 0], sv[:, 1])
        kept[e[e >= 0]] = True
    return kept


def ring_edges(cem: CurveEdgeMesh) -> np.ndarray:
    """The edges whose midpoints widen the rings of tets around the
    singular chain edges that hold fewer tets than the edge's valence (k, 2).

    A piecewise-linear map images each tet of the ring around an interior
    edge with a dihedral angle at the edge below 180 degrees; around a
    chain edge of index sigma those angles sum to (1 - sigma) 360 degrees,
    90 per hex of its valence 4 - 4 sigma.  A curve crossing a tet is made a
    chain edge by the tet's split in five (curve_edges._split_crossed),
    which leaves three tets around it: at a valence-5 edge their angles
    average 150 degrees, and the frame-fitting map, whose unit frames cannot
    be integrable next to the curve (they turn by sigma per radian around
    it), pushes one of the three past 180 in most rings: the genus-2 plates
    of testkit/hexnet.py folded in 80-200 of 9-15k tets, every one with a
    singular vertex, 85 % of the valence-5 rings, whether or not the
    boundary planes and the curves' lines are imposed; at a curve's end on
    the surface the same three tets hold the three boundary triangles
    around the end, 150 degrees each in its plane, and there (and next to
    the end) rounding and untangling left 1-18 tets folded on 14 of 81
    (mesh, cell size) pairs, two meshes at every size; one tet on one pair
    once the rings are widened.  Splitting
    the edge opposite the chain edge in each tet of such a ring (the ring's
    link) doubles the ring, so the angles average 75 degrees; the link edges
    of a curve's end ring lie in the surface, their midpoints on it.  Chain
    edges of any curve and sharp boundary edges are never split.
    """
    mesh = cem.mesh
    valence = np.zeros(mesh.n_edges)  # 0: not a singular chain edge
    for ch in cem.chains:
        if ch.sigma != 0:
            e = mesh.edge_index(ch.vertices[:-1], ch.vertices[1:])
            valence[e[e >= 0]] = 4.0 - 4.0 * ch.sigma
    valence[mesh.is_boundary_edge] = 0.0  # an open fan, not a ring
    te = mesh.tet_edges
    count = np.bincount(te.ravel(), minlength=mesh.n_edges)
    t, k = np.nonzero(count[te] < valence[te])
    if not len(t):
        return np.zeros((0, 2), dtype=np.int64)
    link = mesh.tets[t[:, None], TET_EDGE_OPPOSITE[k]]
    a, b = link.min(axis=1), link.max(axis=1)
    e = mesh.edge_index(a, b)
    ok = (e >= 0) & ~_kept_edges(cem)[e]
    return np.unique(np.c_[a[ok], b[ok]], axis=0).astype(np.int64).reshape(-1, 2)


def widen_rings(cem: CurveEdgeMesh) -> CurveEdgeMesh:
    """cem with the rings around its singular chain edges widened
    (``ring_edges``: their link edges split at their midpoints, every tet
    around them in two; the children keep their parent's frame sources)."""
    edges = ring_edges(cem)
    return split_edges(cem, edges) if len(edges) else cem


def freeing_edges(cem: CurveEdgeMesh, tets: np.ndarray) -> np.ndarray:
    """The edges whose midpoints free the structurally flat tets (k, 2).

    Of each flat tet, every interior edge (not on the boundary, not a curve
    edge) between two constrained vertices (boundary or curve) is split, as
    Expansion Cones (Nigolian, Campen, Bommes, SIGGRAPH 2023; its
    ``TetMeshBoundarySplitter``) splits the interior edges that join two
    boundary vertices so that any feature can be mapped to a plane.  Then a
    child holds three vertices of one boundary plane only where they are a
    boundary face (or an interior face whose three edges all lie on the
    boundary, which Expansion Cones also splits and this does not), and its
    sign says only that its new vertex is inside.
    One split per tet is not enough where the tet has fewer than two
    boundary faces: a child keeps three vertices of the plane that are not a
    boundary face, and its new vertex, the midpoint of an edge between two
    boundary vertices, lies within the surface's sagitta of them, on the
    outer side of their plane where the surface bends; the child is then
    inverted in every map that keeps the new vertex inside (on a bar
    twisted 60 degrees: 3 of 22,577 tets, at every cell size).  A flat tet
    with no such edge (flat on a curve) has one edge split: between two
    constrained vertices first, then interior, then the longest, never a
    curve edge nor a sharp boundary edge.
    """
    mesh = cem.mesh
    X = mesh.vertices
    tets = np.asarray(tets, dtype=np.int64)
    if not len(tets):
        return np.zeros((0, 2), dtype=np.int64)
    constrained = mesh.is_boundary_vertex.copy()
    for ch in cem.chains:
        constrained[ch.vertices] = True
    kept = _kept_edges(cem)
    loc = np.array([(i, j) for i in range(4) for j in range(i + 1, 4)])
    T = mesh.tets[tets]
    a, b = T[:, loc[:, 0]], T[:, loc[:, 1]]  # (k, 6)
    a, b = np.minimum(a, b), np.maximum(a, b)
    e = mesh.edge_index(a.ravel(), b.ravel()).reshape(a.shape)
    both = constrained[a] & constrained[b]
    onb = mesh.is_boundary_edge[e]
    ok = ~kept[e]
    every = ok & both & ~onb
    pick = every.copy()
    rest = ~every.any(axis=1)
    if rest.any():
        # (not both, on the boundary, -length) lexicographically: the least wins
        length = np.linalg.norm(X[a[rest]] - X[b[rest]], axis=2)
        key = np.where(ok[rest], (~both[rest]) * 4.0 + onb[rest] * 2.0 + (1.0 - length / (length.max() + 1e-300)),
                       np.inf)
        best = np.argmin(key, axis=1)
        has = np.isfinite(key[np.arange(len(best)), best])
        pick[np.nonzero(rest)[0][has], best[has]] = True
    out = np.unique(np.c_[a[pick], b[pick]], axis=0)
    return out.astype(np.int64).reshape(-1, 2)


def map_system(cem: CurveEdgeMesh, tr: Transitions, cell: float, report=None,
               sizes=None) -> tuple[MapSystem, np.ndarray]:
    """The map system of the split mesh and its transitions, and the tets
    flat in every map it allows (``degenerate_tets``).

    Parameters
    ----------
    cem : CurveEdgeMesh
    tr : Transitions
        the transitions of cem (transitions.checked_transitions)
    cell : float
        the cell size
    report : HexReport, optional
        carried by a refusal
    sizes : sizing.SizeField, optional
        smaller cells where it asks (None: ``cell`` everywhere)

    Returns
    -------
    (MapSystem, (k,) int array)

    Raises
    ------
    HexMeshError
        kind 'map', where the constraints cannot be met
    """
    mesh = cem.mesh
    rel = None if sizes is None else sizes.relative(mesh.vertices[mesh.tets].mean(axis=1), cell)
    try:
        ms = build_map_system(cem, tr, cell, rel)
    except MapError as e:
        raise HexMeshError(f"the map's constraints cannot be met: {e}", report, kind="map") from None
    return ms, degenerate_tets(ms)


def split_flat(cem: CurveEdgeMesh, flat: np.ndarray) -> CurveEdgeMesh | None:
    """cem with the freeing edges of the flat tets split at their midpoints
    (``freeing_edges``), or None where no edge would free one."""
    edges = freeing_edges(cem, flat)
    return split_edges(cem, edges) if len(edges) else None


# ============================================================ the maps


@dataclass
class GridMap:
    """An integer-grid map (or its relaxed seamless version).

    z        : (nz,) the reduced unknowns; z[system.integer] are integers
    corners  : (#T, 4, 3) parameter points of the tet corners (cells)
    det      : (#T,) det of cell * grad(u) F per tet (> 0: not inverted)
    energy   : the frame-fitting energy
    rounded  : how many integer unknowns were rounded
    max_shift: largest move of an integer unknown off its relaxed value
    stiffening : stiffening iterations used
    """

    z: np.ndarray
    corners: np.ndarray
    det: np.ndarray
    energy: float
    rounded: int = 0
    max_shift: float = 0.0
    stiffening: int = 0

    @property
    def inverted(self) -> int:
        """How many tets the map inverts or flattens (det <= 0)."""
        return int(np.sum(self.det <= 0))

    def folded(self) -> int:
        """Tets the map inverts or flattens, measured also on the snapped
        corners the extraction reads (a tet whose tiny positive volume
        snapping erases cannot be traced through)."""
        U = snap(self.corners)
        d = det3(np.transpose(U[:, 1:] - U[:, :1], (0, 2, 1)))
        return int(np.sum((self.det <= 0) | (np.sign(self.det) * d <= 1e-12)))


def _jacobian_det(ms: MapSystem, z: np.ndarray):
    U = ms.corners(z)
    J = np.einsum("tca,tcj->taj", U, ms.grad)
    return U, det3(J)


def _grid_map(ms: MapSystem, z: np.ndarray, **kw) -> GridMap:
    U, det = _jacobian_det(ms, z)
    return GridMap(z, U, det, ms.energy(z), **kw)


# Continuous unknowns up to which Q_yy is factorised (SuperLU); above, PCG
# with an AMG V-cycle.  SPD solves with 1 + 4 right-hand sides (2 cores, PCG
# to a relative residual of 1e-12, its hierarchy included): the small
# examples' 6.4-7.3k unknowns 0.05-0.27 s factorised against 0.14-0.39 s;
# leading blocks of the 171k-tet ball's system 0.1 s either way at 5k
# unknowns, 0.5 against 0.3 s at 10k, 8.2 against 1.3 s at 40k; the 53k-tet
# ball's 29,909 unknowns 3.6-5.3 s (54x fill) against 1.3-2.1 s; the
# 171k-tet ball's 89,910 unknowns 179 s (132x fill; the process peaked at
# 6.2 GB) against 5 s.  Up to the threshold the maps are those of the
# factorisation, bit for bit.
DIRECT_MAX = 8_000
# PCG stops at this relative residual per column.  On the 171k-tet ball the
# maps (seamless and integer-grid) then differ from the factorisation's by
# 3.8e-11 and 3.0e-11 cells, and no corner coordinate snaps (extract.snap,
# 2^-20) elsewhere: the hex mesh is the same, in 104 steps for the first
# solve.  At 1e-12 (99 steps) they differed by 4.5e-10 and 2.0e-10, 24 of
# the 2.1 M snapped coordinates moved by 2^-20, the hexes by up to 1.8e-7
# after smoothing and the least scaled Jacobian by 1.5e-5.
PCG_RTOL = 1e-13
PCG_MAXITER = 1000
# A stiffened solve that took more PCG steps than this (a factorisation's) or
# than this many times the first solve's (AMG's) builds the preconditioner
# anew on its matrix for the next stiffening, whose weights grow on the same
# tets.  Measured: the examples' stiffenings took 9-19 steps with the first
# factorisation (a new one costs 30-60 steps at 7k unknowns); the 171k-tet
# ball's two 131 and 148 with the first hierarchy, 104 for the first solve
# (a step takes 6 ms there, a hierarchy 0.5 s with the first one's
# aggregates' roots); a synthetic map folded on a fifth of its tets
# (tests/test_map_solve.py) took 28, 54, 80, 144, 247 and 407 steps over
# six stiffenings with the first factorisation and 59 to 623 with the first
# hierarchy (36 for the first solve), 38-50 with each matrix's own
# hierarchy; 28-59 and 59-107 steps with these refreshes.
LU_REFRESH_STEPS = 30
AMG_REFRESH_RATIO = 2.0


def _factorise(A: sp.spmatrix):
    """SuperLU of the SPD matrix A: symmetric mode with a symmetric ordering
    is several times faster than SuperLU's default (COLAMD, partial
    pivoting)."""
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


class _Reduced:
    """The energy as a function of the integer unknowns (module docs).

    Q_yy is factorised (SuperLU) up to ``direct_max`` continuous unknowns;
    above, its solves are PCG preconditioned by one V-cycle of a
    smoothed-aggregation AMG (amg.py), every right-hand side at once
    (``pcg_columns``), to a relative residual of ``PCG_RTOL``: a sparse LU
    of these 3D meshes fills superlinearly (``DIRECT_MAX``).  PCG that does
    not converge falls back to the factorisation.  The factorisation or
    hierarchy is kept to precondition the stiffened systems (``stiffened``).

    Parameters
    ----------
    Q : (nz, nz) sparse SPD, b : (nz,)
        the energy 1/2 z'Qz - b'z
    integer : (nz,) bool
        the integer unknowns w (the rest are the continuous y)
    direct_max : int
        factorise Q_yy up to this many continuous unknowns

    Attributes
    ----------
    y0, Z : y(w) = y0 - Z w
    S, c : the reduced energy 1/2 w'Sw - c'w
    method : 'lu' or 'amg-pcg'
    iterations : list of the PCG steps of each solve (empty if none)
    """

    def __init__(self, Q: sp.csr_matrix, b: np.ndarray, integer: np.ndarray, direct_max: int = DIRECT_MAX):
        self.iw = np.nonzero(integer)[0]
        self.iy = np.nonzero(~integer)[0]
        self.n = len(b)
        Q = Q.tocsc()
        Qy = Q[self.iy]
        Qyy = Qy[:, self.iy]
        Qyw = Qy[:, self.iw].toarray()
        Qww = Q[self.iw][:, self.iw].toarray()
        self.Qyy, self.Qyw, self.by = Qyy.tocsr(), Qyw, b[self.iy]
        self.lu = self.amg = None
        self.iterations: list[int] = []
        if len(self.iy) <= direct_max:
            self.method = "lu"
            self.lu = _factorise(Qyy)
            self.y0 = self.lu.solve(self.by)
            self.Z = self.lu.solve(Qyw) if len(self.iw) else np.zeros((len(self.iy), 0))
        else:
            self.method = "amg-pcg"
            self.amg = AMG.build(self.Qyy, block=1)
            Y = self._solve(self.Qyy, np.column_stack([self.by, Qyw]))
            self.y0, self.Z = Y[:, 0].copy(), Y[:, 1:].copy()
        self.S = Qww - Qyw.T @ self.Z
        self.c = b[self.iw] - Qyw.T @ self.y0

    def _precondition(self, R: np.ndarray) -> np.ndarray:
        return self.lu.solve(R) if self.lu is not None else self.amg.vcycle(R)

    def _solve(self, A: sp.csr_matrix, B: np.ndarray, X0: np.ndarray | None = None) -> np.ndarray:
        """A^-1 B by PCG (this system's preconditioner), from X0; by a
        factorisation of A where PCG does not converge."""
        Ap = parallel(A)
        res = pcg_columns(lambda X: Ap @ X, B, self._precondition, X0=X0, rtol=PCG_RTOL, maxiter=PCG_MAXITER)
        self.iterations.append(res.iterations)
        if res.converged:
            return res.X
        return _factorise(A).solve(B)

    def z(self, w: np.ndarray) -> np.ndarray:
        out = np.empty(self.n)
        out[self.iw] = w
        out[self.iy] = self.y0 - self.Z @ w
        return out

    def relaxed(self) -> np.ndarray:
        if not len(self.iw):
            return np.zeros(0)
        return np.linalg.solve(self.S + 1e-12 * np.eye(len(self.S)) * np.trace(self.S), self.c)

    def stiffened(self, dQ: sp.spmatrix, db: np.ndarray, w: np.ndarray, y: np.ndarray) -> np.ndarray:
        """z minimising 1/2 z'(Q + dQ)z - (b + db)'z with the integer
        unknowns held at w: the continuous ones solve

            (Q_yy + dQ_yy) y = b_y + db_y - (Q_yw + dQ_yw) w

        by PCG from y (the last map's), preconditioned by Q_yy's
        factorisation or AMG hierarchy, not a new one.  dQ (a stiffening:
        a few tets' weights raised) changes few rows, so the preconditioned
        matrix is the identity plus a low-rank term (factorisation: 9-19
        steps on the examples' stiffenings, against a new factorisation)
        or stays close to Q_yy's (AMG: 131 and 148 steps on the 171k-tet
        ball's two, 104 for the first solve).  Where the solve took many steps
        (``LU_REFRESH_STEPS``, ``AMG_REFRESH_RATIO``) the preconditioner is
        built again on this matrix for the next call.

        Parameters
        ----------
        dQ : (nz, nz) sparse, db : (nz,)
            the change of the energy
        w : (m,) the integer unknowns
        y : (ny,) the starting continuous unknowns

        Returns
        -------
        (nz,) z
        """
        dQy = sp.csr_matrix(dQ)[self.iy]
        A = (self.Qyy + dQy[:, self.iy]).tocsr()
        rhs = self.by + db[self.iy] - self.Qyw @ w - dQy[:, self.iw] @ w
        out = np.empty(self.n)
        out[self.iw] = w
        out[self.iy] = self._solve(A, rhs, y)
        steps = self.iterations[-1]
        if self.lu is not None and steps > LU_REFRESH_STEPS:
            self.lu = _factorise(A)
        elif self.amg is not None and steps > AMG_REFRESH_RATIO * self.iterations[0]:
            self.amg = AMG.build(A, block=1, like=self.amg)
        return out


def seamless_map(ms: MapSystem) -> tuple[GridMap, _Reduced]:
    """The relaxed (real-valued) seamless map and its reduced energy."""
    red = _Reduced(ms.Q, ms.b, ms.integer)
    z = red.z(red.relaxed())
    return _grid_map(ms, z), red


def integer_grid_map(ms: MapSystem, red: _Reduced | None = None, stiffen_iters: int = 6,
                     stiffen_factor: float = 5.0) -> GridMap:
    """Round the integer unknowns greedily and stiffen inverted tets.

    Parameters
    ----------
    ms : MapSystem
    red : the reduced energy of ms (seamless_map's), computed if None
    stiffen_iters : at most this many re-solves with inverted tets' weights
        multiplied by stiffen_factor

    Returns
    -------
    GridMap  (the least inverted of the maps tried)
    """
    red = red or _Reduced(ms.Q, ms.b, ms.integer)
    w, shift = greedy_round(red.S, red.c)
    best = _grid_map(ms, red.z(w), rounded=len(w), max_shift=shift)
    if best.inverted == 0 or stiffen_iters == 0:
        return best
    # stiffening: the integer unknowns stay, the continuous ones move.  The
    # energy's weights change only on the tets stiffened so far: Q + dQ with
    # dQ = LX' diag(wts - weight) LX over their rows, solved by PCG with the
    # first solve's factorisation or hierarchy (_Reduced.stiffened).  A new
    # factorisation per iteration took 329 s for two iterations on the
    # 171k-tet ball (89,910 unknowns).
    LX, weight = ms.least_squares()
    wts = weight.copy()
    nT = len(ms.tet_weight)
    target = np.tile(np.eye(3).reshape(-1), nT)
    cur = best
    for it in range(1, stiffen_iters + 1):
        bad = cur.det <= 0
        if not bad.any():
            break
        scale = np.ones(nT)
        scale[bad] = stiffen_factor
        wts = wts * np.repeat(scale, 9)
        rows = np.nonzero(wts != weight)[0]
        dw = wts[rows] - weight[rows]
        L = LX[rows]
        dQ = L.T @ sp.diags(dw) @ L
        db = np.asarray(L.T @ (dw * target[rows])).ravel()
        z = red.stiffened(dQ, db, w, cur.z[red.iy])
        cur = _grid_map(ms, z, rounded=len(w), max_shift=shift, stiffening=it)
        if cur.inverted < best.inverted or (cur.inverted == best.inverted and cur.det.min() > best.det.min()):
            best = cur
    return best


def optimise_map(ms: MapSystem, gm: GridMap, mu: float = 10.0, lam: float = 0.0, iters: int = 300,
                 rounds: int = 4, callback=None) -> GridMap:
    """Lower the map's distortion with its integers fixed, untangling
    inverted tets on the way: minimise, over the continuous unknowns,

        sum_t V_t ( ||J_t - I||^2 + mu f(J_t) ),   J_t = cell grad(u_t) F_t,

    f the foldover-free energy of smooth.py (mean-ratio shape plus volume,
    finite while eps > 0 so an inverted start is allowed, a barrier as eps
    -> 0).  The first term keeps the map aligned with the field (f alone is
    blind to rotation).  AlgoHex likewise follows its linear solve with a
    locally injective optimisation under the same constraints.
    """
    iy = np.nonzero(~ms.integer)[0]
    z = gm.z.copy()
    w = ms.tet_weight / ms.tet_weight.sum()
    X = ms.X
    Xy = X[:, iy].tocsc()
    base = X @ z - Xy @ z[iy]  # the integer part of the corners, fixed
    coef = ms.grad
    eye = np.eye(3)
    best = gm
    for _ in range(rounds):
        U = ms.corners(z)
        J = np.einsum("tca,tcj->taj", U, coef)
        Dmin = float(det3(J).min())
        eps = 1e-3 if Dmin > 1e-2 else float(np.sqrt(1e-6 + 0.04 * Dmin * Dmin))

        def fun(y):
            U = (base + Xy @ y).reshape(-1, 4, 3)
            J = np.matmul(U.transpose(0, 2, 1), coef)  # J_taj = sum_c U_tca coef_tcj
            f, dJ = foldover_free(J, eps, lam)
            R = J - eye
            e = float(np.sum(w * (np.sum(R * R, axis=(1, 2)) + mu * f)))
            dJ = w[:, None, None] * (2.0 * R + mu * dJ)
            dU = np.matmul(coef, dJ.transpose(0, 2, 1))  # dU_tca = sum_j dJ_taj coef_tcj
            return e, Xy.T @ dU.reshape(-1)

        res = lbfgs(fun, z[iy], max_iterations=iters, callback=callback)
        z[iy] = res.x
        cur = _grid_map(ms, z.copy(), rounded=gm.rounded, max_shift=gm.max_shift, stiffening=gm.stiffening)
        if cur.inverted <= best.inverted:
            best = cur
        if cur.inverted == 0 and Dmin > 1e-2:
            break
    return best
