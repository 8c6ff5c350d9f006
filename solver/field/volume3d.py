"""The volume problem (§4.3, Eq. 23): Levenberg-Marquardt on omega.

    minimise  sum_ij w_ij |omega_ij|^2 + a sum_f |r_f(omega)|^2
    over      omega = c + P x       (the constraints of Eq. 20-22)

Each LM step solves the damped Gauss-Newton system

    (H + lambda diag H) dx = -g,   H = 2 P^T (W + a J^T J) P,  g = 2 P^T (W omega + a J^T r)

by PCG (linalg/pcg.py).  H is assembled per LM iteration in a sparsity
pattern fixed once per problem (hessian.py: one 9x9 block per face), so a
CG step costs one sparse product, run on all cores (parallel.py).

The iteration (``VolumeProblem.solve``: start, ``_lm_step``, ``_lm_update``,
the stopping rule ``_lm_stop``), and why each part is there:

* Newton phase.  The residual of Eq. 19 does not vanish at the minimiser,
  so Gauss-Newton alone converges only linearly there: once the steps are
  small H also gets the second-order term 2 a P^T (sum_f r_f . d^2 r_f) P.
  Where that Hessian is not positive definite, the step falls back to
  Gauss-Newton.
* Damping.  Marquardt's lambda diag(H) falls by up to 10x per good step
  and by 100x more per good Newton step: damping comparable to H's
  smallest eigenvalues (modes around the node regions) slows LM to a
  linear rate.
* Early stop of CG.  Near the minimum CG stops as soon as its iterate is
  known to be below the step tolerance (pcg.pcg's ``small``), so
  confirming convergence costs a few dozen CG steps, not a solve.
* Deflation.  Once the steps are small, approximate eigenvectors of the
  smallest eigenvalues, found while solving one system (eigCG,
  pcg.RitzRecorder), deflate the next.
* Line minima.  Along any line the energy is exactly a quartic (Eq. 19 is
  quadratic in omega), so a step that would raise the energy, or a
  Gauss-Newton step that stops far short of the minimum along its line,
  is replaced by that minimum instead of being rejected and solved again
  (energy_along, line_minimum).
* Negative curvature.  Where the full Hessian is indefinite (twisted
  fields, e.g. a torus), Newton's CG stops on a direction of negative
  curvature; LM then takes the Gauss-Newton step and moves on from it to
  the energy's minimum along that direction.

The measurements behind each choice and each default of ``LMSettings`` are
in docs/performance.md ("The LM solver's settings").
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..errors import Cancelled
from ..linalg.amg import AMG, block_diag_matrix, inv_blocks
from ..linalg.parallel import parallel, ranges, run
from ..linalg.pcg import PCGResult, RitzRecorder, pcg
from ..mesh.tetmesh import TetMesh
from .constraints import AffineOmega
from .hessian import FaceAssembly, gauss_newton_blocks
from .structure import StructureEquation, _cross_mat


@dataclass
class LMIteration:
    iteration: int
    energy: float
    smoothness: float
    penalty: float
    gradient_norm: float
    damping: float
    cg_iterations: int
    accepted: bool
    seconds: float
    step: float = 0.0  # |d omega| / |omega| of the step tried (as taken: scaled by line_step)
    newton: bool = False  # the step used the full Hessian (not Gauss-Newton)
    line_step: float = 1.0  # the multiple of the LM step taken (the line search's t)
    curvature_move: bool = False  # the step also moved along a direction of negative curvature


@dataclass
class LMReport:
    init: str
    iterations: list = field(default_factory=list)
    converged: bool = False
    capped: bool = False  # stopped by max_iterations
    reason: str = ""
    seconds: float = 0.0
    setup_seconds: float = 0.0
    preconditioner_builds: int = 0

    @property
    def n_iterations(self) -> int:
        return sum(1 for it in self.iterations if it.iteration > 0)

    @property
    def cg_iterations(self) -> int:
        return sum(it.cg_iterations for it in self.iterations)

    @property
    def final(self) -> LMIteration:
        return self.iterations[-1]


@dataclass(frozen=True)
class LMSettings:
    """The tuning of ``VolumeProblem.solve``.  Each default is measured: the
    runs behind them are in docs/performance.md ("The LM solver's settings").

    Parameters
    ----------
    cg_rtol : float
        CG tolerance of Newton systems, and the cap of the Gauss-Newton
        systems' Eisenstat-Walker forcing.
    cg_rtol_floor : float
        The forcing's floor.
    step_tol : float
        LM has converged once the distance left to the minimiser is below
        this fraction of |omega| (the stopping rule, ``_lm_stop``).
    reuse_step : float
        The preconditioner is rebuilt once omega has moved by this fraction
        of |omega| since it was built (or the damping changed 100-fold).
    direct : bool
        Solve each step by sparse LU instead of PCG (the baseline of
        bench/lu_baseline.py); no Newton or deflation phase.
    newton_step : float
        The Newton phase starts after an accepted step below this fraction
        of |omega|.
    deflate : int
        Ritz vectors kept for deflation (fewer than 2: none).
    deflate_step : float
        Ritz vectors are recorded after an accepted step below this
        fraction of |omega|.
    shrink : float
        The smallest factor of the damping after a good step.
    newton_shrink : float
        A further factor of the damping after a good Newton step.
    line_search : float
        The longest multiple of a step its line minimum may take; 0: no
        line search and no move along negative curvature.
    extrapolate : float
        A step that lowers the energy is replaced by its line minimum only
        when that lies at least this many steps out.
    """

    cg_rtol: float = 1e-3
    cg_rtol_floor: float = 1e-6
    step_tol: float = 1e-6
    reuse_step: float = 0.05
    direct: bool = False
    newton_step: float = 0.01
    deflate: int = 8
    deflate_step: float = 0.1
    shrink: float = 0.1
    newton_shrink: float = 0.01
    line_search: float = 4.0
    extrapolate: float = 1.5


@dataclass
class _LMState:
    """What one LM iteration hands the next (VolumeProblem.solve)."""

    x: np.ndarray
    es: float  # smoothness and penalty energy at x
    ep: float
    g: np.ndarray  # gradient at x
    Hgn: np.ndarray  # Gauss-Newton Hessian values at x (the assembly's pattern)
    blocks: tuple  # its diagonal blocks (linearise)
    g0: float  # |g| at the start
    g_prev: float  # |g| where the last accepted step started
    om_floor: float  # the smallest |omega| steps are measured against
    Mbuf: np.ndarray  # the damped matrix's values
    lam: float = 1e-4  # Marquardt's damping
    nu: float = 2.0  # its growth after a rejection
    newton: bool = False  # in the Newton phase
    K: np.ndarray | None = None  # the Newton term at x (Newton phase)
    Kbuf: np.ndarray | None = None
    Hsum: np.ndarray | None = None  # Hgn + K
    pc: object = None  # the preconditioner, built at damping pc_lam
    pc_lam: float = 1e-4
    moved: float = 0.0  # how far omega moved since, relative to |omega|
    pc_builds: int = 0
    U: np.ndarray | None = None  # deflation vectors
    recording: bool = False  # recording Ritz vectors
    rejected: int = 0  # steps rejected in a row
    prev_step: float | None = None  # the sizes of the last two accepted steps
    last_step: float | None = None

    @property
    def F(self) -> float:
        return self.es + self.ep


@dataclass
class _Step:
    """An LM iteration's trial: the step, where it leads, how it was found."""

    res: PCGResult
    cg_steps: int
    newton: bool  # solved with the full Hessian
    dx: np.ndarray
    x: np.ndarray  # x + dx
    es: float
    ep: float
    rho: float  # actual over predicted decrease of the full step
    line_step: float  # the multiple of the solved step taken
    curvature_move: bool  # moved on along a direction of negative curvature
    size: float  # |d omega| / |omega|

    @property
    def F(self) -> float:
        return self.es + self.ep


class VolumeProblem:
    """Eq. 23 on a mesh, with its constraints; keeps the preconditioner setup
    (the vertex Laplacian's AMG), which does not depend on omega."""

    def __init__(self, mesh: TetMesh, cons: AffineOmega, Omega: np.ndarray, excluded: np.ndarray,
                 penalty: float = 1000.0, boundary_normals: np.ndarray | None = None,
                 length_unit: float = 1.0):
        self.mesh = mesh
        self.boundary_normals = mesh.boundary.vertex_normals if boundary_normals is None else boundary_normals
        self.cons = cons
        self.a = float(penalty)
        active = np.nonzero(~excluded)[0]
        self.faces = active
        self.se = StructureEquation(mesh.face_edges[active], mesh.corner_weights[active], Omega[active],
                                    mesh.n_edges)
        # w_ij of Eq. 16 scales like a length while the structure residuals
        # of Eq. 19 are angles: measured in ``length_unit`` (pipeline.py: a
        # fixed fraction of the solid's size), the balance that the penalty
        # a sets does not depend on the model's units
        self.w = mesh.dirichlet_weights / float(length_unit)
        self.W3 = np.repeat(self.w, 3)
        P = cons.P
        self.P = P
        self.PT = P.T.tocsr()
        # smoothness part of H in x space: 2 P^T W P (constant)
        self.HW = (self.PT @ sp.diags(2.0 * self.W3) @ P).tocsr()
        t = time.perf_counter()
        # the LM matrices are assembled in a pattern fixed here (hessian.py)
        # (with the free edges' whole 3x3 diagonal blocks, which block
        # Jacobi reads back)
        nfree = len(cons.free_edges)
        blk = 3 * np.arange(nfree)[:, None, None] + np.zeros((1, 3, 3), np.int64)
        bi, bj = (blk + np.arange(3)[:, None]).reshape(-1), (blk + np.arange(3)[None, :]).reshape(-1)
        n = P.shape[1]
        self.assembly = FaceAssembly(self.se.face_edges, P, self.HW,
                                     pattern=sp.csr_matrix((np.ones(len(bi)), (bi, bj)), shape=(n, n)))
        self._block_pos = self.assembly.positions(bi, bj).reshape(nfree, 3, 3)
        self._setup_gradient_space()
        self._blocks_scratch = None
        self._amg = None
        self.setup_seconds = time.perf_counter() - t

    # ------------------------------------------------------------------ energy
    def omega(self, x):
        return self.cons.omega(x)

    def energy_terms(self, x, linear=False):
        om = self.omega(x)
        r = self.se.residual(om, linear)
        es = float(np.sum(self.w[:, None] * om**2))
        ep = float(self.a * np.sum(r**2))
        return es, ep

    def energy(self, x, linear=False):
        es, ep = self.energy_terms(x, linear)
        return es + ep

    def energy_along(self, x, dx) -> np.ndarray:
        """Coefficients e_0..e_4 of E(x + t dx) = sum_k e_k t^k.  E of
        Eq. 23 is exactly a quartic in t: omega is affine in x and the
        structure residual r of Eq. 19 quadratic in omega, so along the
        line r = r_0 + t b + t^2 c, where c = -wedge(d) is the wedge term
        of Eq. 19 on the step d = omega(x + dx) - omega(x) alone."""
        om = self.omega(x)
        d = (self.P @ dx).reshape(om.shape)
        r0 = self.se.residual(om)
        c = -self.se.wedge(d)
        b = self.se.residual(om + d) - r0 - c
        w, a = self.w[:, None], self.a

        def dot(u, v):
            return float(np.einsum("ij,ij->", u, v))

        return np.array([dot(w * om, om) + a * dot(r0, r0),
                         2.0 * dot(w * om, d) + 2.0 * a * dot(r0, b),
                         dot(w * d, d) + a * (dot(b, b) + 2.0 * dot(r0, c)),
                         2.0 * a * dot(b, c),
                         a * dot(c, c)])

    @staticmethod
    def line_minimum(coef, t_max: float) -> float:
        """The t in (0, t_max] where the quartic sum_k coef_k t^k is
        smallest (1.0 among ties, so an exact step is left alone)."""
        crit = np.roots(np.arange(4, 0, -1) * np.asarray(coef)[:0:-1])  # E'(t), highest power first
        cand = [min(1.0, t_max), t_max] + [float(t.real) for t in crit
                                             if abs(t.imag) <= 1e-9 * max(1.0, abs(t)) and 0.0 < t.real < t_max]
        vals = np.array([np.polyval(np.asarray(coef)[::-1], t) for t in cand])
        best = int(np.argmin(vals))
        # the full step unless another is lower by more than round-off
        return cand[best] if vals[best] < vals[0] - 1e-12 * np.abs(vals).max() else cand[0]

    # ------------------------------------------------------------ linearisation
    def linearise(self, x, linear=False, out=None):
        """Gradient, the values of the Gauss-Newton Hessian in x space
        (FaceAssembly's pattern; written into ``out`` if given) and its
        diagonal blocks."""
        om = self.omega(x)
        r = self.se.residual(om, linear)
        Jb = self.se.jacobian_blocks(om, linear)
        JTr = self.se.jacobian_transpose_product(Jb, r)
        g = 2.0 * (self.PT @ (self.W3 * om.reshape(-1) + self.a * JTr.reshape(-1)))
        data = self.assembly.data(gauss_newton_blocks(Jb, 2.0 * self.a, out=self._face_blocks()), out=out)
        data += self.assembly.extra_data
        B = data[self._block_pos]
        d = data[self.assembly.diagonal_positions[3 * len(self.cons.free_edges):]]
        return g, data, (B, d)

    def second_order(self, x, linear=False, out=None):
        """Values of 2 a P^T (sum_f r_f . d^2 r_f) P: what Gauss-Newton
        leaves out of the Hessian of Eq. 23 (written into ``out`` if
        given).  None for the linear problem."""
        if linear:
            return None
        Q = self.se.residual_hessian_blocks(self.se.residual(self.omega(x)), out=self._face_blocks())
        Q *= 2.0 * self.a
        return self.assembly.data(Q, out=out)

    def _face_blocks(self) -> np.ndarray:
        """Scratch space for the (m, 9, 9) face blocks, kept between LM
        iterations: a fresh array this size (over 100 MB at 100k tets)
        costs more to fault in than to fill (docs/performance.md)."""
        if self._blocks_scratch is None:
            self._blocks_scratch = np.empty((len(self.faces), 9, 9))
        return self._blocks_scratch

    def lm_matrix(self, data, damping=0.0, diagH=None, out=None):
        """The assembled matrix with these values plus damping * diag(diagH)
        (the damped values written into ``out`` if given, else a copy)."""
        if damping:
            if out is None:
                data = data.copy()
            else:
                np.copyto(out, data)
                data = out
            data[self.assembly.diagonal_positions] += damping * diagH
        return self.assembly.matrix(data)

    def _setup_gradient_space(self):
        """Static parts of the auxiliary-space map (see covariant_gradient)."""
        mesh, cons = self.mesh, self.cons
        nE, nV = mesh.n_edges, mesh.n_vertices
        fe = cons.free_edges
        nfree = len(fe)
        # x rows fed by omega-space rows: free edges (identity) and tube edges
        # with free torsion (projection on T_e, in the order of the beta block)
        self._Sf = sp.csr_matrix((np.ones(3 * nfree), (np.arange(3 * nfree), (3 * fe[:, None] + np.arange(3)).ravel())),
                                 shape=(3 * nfree, 3 * nE))
        te = cons.beta_edges
        self._St = sp.csr_matrix((cons.tube_tangent[te].ravel(), (np.repeat(np.arange(len(te)), 3),
                                  (3 * te[:, None] + np.arange(3)).ravel())), shape=(len(te), 3 * nE))
        # alpha of a group = Phi_rep . N_rep
        av = cons.alpha_vertices
        bn = np.zeros((nV, 3))
        bn[mesh.boundary_vertices] = self.boundary_normals
        N = bn[av]
        cols = (3 * av[:, None] + np.arange(3)).ravel()
        self._Sa = sp.csr_matrix((N.ravel(), (np.repeat(np.arange(len(av)), 3), cols)), shape=(len(av), 3 * nV))
        # vertices whose frame may rotate (sharp-feature frames are fixed)
        keep = np.ones(nV, bool)
        keep[cons.fixed_frame_vertices] = False
        kv = np.nonzero(keep)[0]
        self._aux_cols = (3 * kv[:, None] + np.arange(3)).ravel()
        self.grad_vertices = kv

    def covariant_gradient(self, omega):
        """The map Phi (a rotation vector per vertex) -> x giving the first-order
        change of omega when every frame is rotated by exp(Phi_i):

            d omega_ij = Phi_j - Phi_i + (Phi_i + Phi_j) x omega_ij / 2.

        These are the near-null modes of H (the structure equation is
        invariant under them) that Jacobi cannot resolve; plain gradients
        (omega = 0) miss them near singular curves and curved boundaries.
        """
        E = self.mesh.edges
        nE, nV = self.mesh.n_edges, self.mesh.n_vertices
        I = np.eye(3)
        Wx = _cross_mat(omega)
        r_ = np.broadcast_to(3 * np.arange(nE)[:, None, None] + np.arange(3)[None, :, None], (nE, 3, 3)).ravel()
        Gw = None
        for blk, end in ((-(I + 0.5 * Wx), 0), (I - 0.5 * Wx, 1)):
            c_ = np.broadcast_to(3 * E[:, end][:, None, None] + np.arange(3)[None, None, :], (nE, 3, 3)).ravel()
            part = sp.csr_matrix((blk.ravel(), (r_, c_)), shape=(3 * nE, 3 * nV))
            Gw = part if Gw is None else Gw + part
        G = sp.vstack([self._Sf @ Gw, self._Sa, self._St @ Gw,
                       sp.csr_matrix((self.cons.n_gamma, 3 * nV))]).tocsr()
        return G[:, self._aux_cols].tocsr()

    @staticmethod
    def _deflated(pc, U, matvec):
        """pc plus the coarse correction U (U^T A U)^-1 U^T on the recorded
        vectors (additive, so it stays symmetric positive definite).  U is
        applied in single precision: it is only a preconditioner, and the
        products with it are memory-bound."""
        if U is None:
            return pc
        E = U.T @ np.column_stack([matvec(U[:, i]) for i in range(U.shape[1])])
        w, S = np.linalg.eigh(0.5 * (E + E.T))
        keep = w > 1e-12 * max(w.max(), 1e-300)
        Einv = ((S[:, keep] / w[keep]) @ S[:, keep].T).astype(np.float32)
        U32T = np.ascontiguousarray(U.T, dtype=np.float32)  # a vector per row
        parts = ranges(U32T.shape[1])

        def apply(r):
            # einsum, not BLAS (see pcg.pcg), by index ranges on all
            # cores; both products read the vectors row by row (U y on
            # U's rows, "i,ij->j", takes half the time of "ij,j->i" on its
            # columns)
            y = Einv @ sum(run(lambda i, j: np.einsum("ij,j->i", U32T[:, i:j], r[i:j].astype(np.float32)), parts))
            out = pc(r)

            def add(i, j):
                out[i:j] += np.einsum("i,ij->j", y, U32T[:, i:j])

            run(add, parts)
            return out

        return apply

    @staticmethod
    def damping_diagonal(blocks):
        """diag H, which Marquardt's damping lambda diag(H) scales."""
        B, d = blocks
        return np.r_[np.einsum("nii->ni", B).reshape(-1), d]

    def make_preconditioner(self, blocks, damping, Hdata, omega, scratch=None):
        """Block Jacobi plus the covariant auxiliary-space correction
        G (G^T H G)^-1 G^T, whose coarse operator is inverted by one V-cycle
        of a nodal AMG.  Hdata: the Gauss-Newton Hessian's values; scratch:
        space for the damped values (see lm_matrix)."""
        B, d = blocks
        diagH = self.damping_diagonal(blocks)
        B = B + damping * np.einsum("nii->ni", B)[:, :, None] * np.eye(3)
        d = d * (1.0 + damping)
        # block Jacobi as one sparse matrix: 3x3 inverses on free edges, the
        # diagonal on the adaptation parameters
        Dinv = parallel(sp.block_diag([block_diag_matrix(inv_blocks(B)), sp.diags(1.0 / d)], format="csr"))
        G = self.covariant_gradient(omega)
        GT = G.T.tocsr()
        # both products CSR times CSR: with G.T (CSC) SciPy converts M G
        # (millions of nonzeros) to CSC and the product back to CSR
        Ac = GT @ (self.lm_matrix(Hdata, damping, diagH, out=scratch) @ G)
        # the coarse operator's pattern is the same in every build: the
        # aggregates' roots of the last build are reused (amg.py)
        amg = self._amg = AMG.build(Ac, block=3, like=self._amg)
        G, GT = parallel(G), parallel(GT)

        def apply(r):
            return Dinv @ r + G @ amg.vcycle(GT @ r)

        return apply

    def _direct_step(self, g, H):
        """The damped Gauss-Newton step by SciPy's sparse LU of the assembled
        normal equations: the straightforward baseline of bench/lu_baseline.py
        (its fill-in grows far faster than the mesh; see linalg/pcg.py)."""
        import scipy.sparse.linalg as spla

        H = H.tocsc()
        dx = spla.splu(H).solve(-g)
        rel = float(np.linalg.norm(H @ dx + g) / max(np.linalg.norm(g), 1e-300))
        return PCGResult(dx, 0, True, rel)

    def _curvature_move(self, x, dx, terms, p, t_max):
        """From the trial point x + dx (whose energy_terms are ``terms``),
        the exact minimum of E along a direction p of negative curvature
        (scaled to the step's size, oriented downhill, at most t_max steps
        long), if it lowers E.  Returns (dx, x + dx, smoothness, penalty,
        E) of the move (those of the trial point if none lowers E).

        Where the full Hessian is indefinite (a twisted field's saddle
        region; the torus at h = 0.3), Newton's attempts stop on negative
        curvature within a few CG steps, and the Gauss-Newton steps taken
        instead crawl: its model is convex and sees no descent along p.  E
        along p is a quartic (energy_along) and falls first like its
        negative curvature, so its minimum there is a cheap and large
        decrease (as Newton-CG methods use negative curvature; what it
        saved on the torus: docs/performance.md)."""
        xn = x + dx
        es, ep = terms
        Fn = es + ep
        size, psize = np.linalg.norm(self.P @ dx), np.linalg.norm(self.P @ p)
        if not (psize > 0 and size > 0):
            return dx, xn, es, ep, Fn
        p = p * (size / psize)
        coef = self.energy_along(xn, p)
        if coef[1] > 0:
            p = -p
            coef = coef * np.array([1.0, -1.0, 1.0, -1.0, 1.0])
        t = self.line_minimum(coef, t_max)
        es_t, ep_t = self.energy_terms(xn + t * p)
        if es_t + ep_t < Fn:
            dx = dx + t * p
            return dx, x + dx, es_t, ep_t, es_t + ep_t
        return dx, xn, es, ep, Fn

    # --------------------------------------------------------------------- LM
    def solve(self, x0: np.ndarray, max_iterations: int = 50, tol: float = 1e-10, init: str = "",
              linear: bool = False, progress=None, cancel=None, **tuning) -> tuple[np.ndarray, LMReport]:
        """Minimise Eq. 23 from x0 by Levenberg-Marquardt (module docs).

        Each iteration is one ``_lm_step`` (solve the damped system, try
        the step), one ``_lm_update`` (accept or reject it, adjust the
        damping, enter the Newton and deflation phases) and the stopping
        rule ``_lm_stop``.

        Parameters
        ----------
        x0 : (n,) float array
            The start, n = cons.n_unknowns.
        max_iterations : int
            LM iterations at most (the report says ``capped`` when reached).
        tol : float
            Relative energy decrease that stops LM together with a small step.
        init : str
            The start's name, kept in the report.
        linear : bool
            Solve the linearised structure equation (Eq. 19 without the
            wedge term): the 'linear' initialisation.
        progress : callable(iteration, energy) or None
        cancel : callable() -> bool, or None
            Asked before every iteration; True raises Cancelled.
        **tuning
            Fields of ``LMSettings``.

        Returns
        -------
        x : (n,) float array
            The minimiser found.
        report : LMReport
        """
        s = LMSettings(**tuning)
        rep = LMReport(init=init, setup_seconds=self.setup_seconds)
        t0 = time.perf_counter()
        st = self._lm_start(x0, linear)
        rep.iterations.append(LMIteration(0, st.F, st.es, st.ep, st.g0, st.lam, 0, True, 0.0))
        for it in range(1, max_iterations + 1):
            if cancel is not None and cancel():
                raise Cancelled()
            ti = time.perf_counter()
            step = self._lm_step(st, it, s, linear)
            accepted = step.F < st.F
            dF = self._lm_update(st, step, accepted, s, linear)
            rep.iterations.append(
                LMIteration(it, st.F, st.es, st.ep, float(np.linalg.norm(st.g)), st.lam, step.cg_steps, accepted,
                            time.perf_counter() - ti, step.size, newton=step.newton, line_step=step.line_step,
                            curvature_move=step.curvature_move)
            )
            if progress is not None:
                progress(it, st.F)
            stop = self._lm_stop(st, step, accepted, dF, s, tol, linear)
            if stop is not None:
                rep.converged, rep.reason = stop
                break
        else:
            rep.capped = True
            rep.reason = f"stopped after {max_iterations} iterations"
        rep.preconditioner_builds = st.pc_builds
        rep.seconds = time.perf_counter() - t0
        return st.x, rep

    def _lm_start(self, x0: np.ndarray, linear: bool) -> _LMState:
        """The state at x0: energy, gradient and Gauss-Newton values."""
        x = x0.copy()
        es, ep = self.energy_terms(x, linear)
        g, Hgn, blocks = self.linearise(x, linear)
        g0 = np.linalg.norm(g)
        # the matrices' values (~100 per tet) go into arrays kept for
        # the whole solve (fresh arrays this size are new pages each time,
        # see hessian.FaceAssembly.data); steps are measured relative to
        # |omega| but not below an rms of 1e-6 rad per edge: a field without
        # turning (a cube's, omega = 0) would otherwise never meet the step
        # test (its steps stay at round-off, a fixed fraction of an omega
        # that is round-off too)
        return _LMState(x=x, es=es, ep=ep, g=g, Hgn=Hgn, blocks=blocks, g0=g0, g_prev=g0,
                        om_floor=1e-6 * np.sqrt(self.mesh.n_edges), Mbuf=np.empty_like(Hgn))

    def _lm_step(self, st: _LMState, it: int, s: LMSettings, linear: bool) -> _Step:
        """Iteration ``it``'s trial step from st: the CG tolerance, the
        preconditioner (rebuilt when stale), the damped system's solution
        (_lm_direction) and where it leads (_lm_trial)."""
        gn = np.linalg.norm(st.g)
        # Eisenstat-Walker forcing, capped at cg_rtol: tighten as the
        # gradient falls (superlinear overall; looser early solves cost as
        # much in the end, through more LM iterations).  Not in the Newton
        # phase: there the steps shrink quadratically and set the accuracy
        # (see the stopping rule), and a Newton step solved to cg_rtol is
        # within a few percent of the exact one (docs/performance.md)
        rtol = s.cg_rtol
        if it > 1 and not st.newton:
            rtol = max(s.cg_rtol_floor, min(s.cg_rtol, 0.9 * (gn / st.g_prev) ** 2))
        # the preconditioner (block Jacobi + AMG on the covariant gradients)
        # changes slowly with omega and lambda: rebuilt only once omega has
        # moved or the damping changed by a large factor, however small
        # lambda is (a floor on lambda in this test saved builds but cost
        # more CG steps: docs/performance.md)
        diagH = self.damping_diagonal(st.blocks)
        if not s.direct and (st.pc is None or st.moved > s.reuse_step or not 0.01 <= st.lam / st.pc_lam <= 100.0):
            st.pc = self.make_preconditioner(st.blocks, st.lam, st.Hgn, self.omega(st.x), st.Mbuf)
            st.pc_lam, st.moved = st.lam, 0.0
            st.pc_builds += 1
        res, cg_steps, Hdata, curved = self._lm_direction(st, s, rtol, diagH)
        return self._lm_trial(st, s, linear, res, cg_steps, Hdata, curved)

    def _lm_direction(self, st: _LMState, s: LMSettings, rtol: float, diagH: np.ndarray):
        """The damped system's solution: (PCGResult, CG steps, the Hessian
        values used, a direction of negative curvature or None).  In the
        Newton phase the full Hessian; where it is not positive definite,
        Gauss-Newton instead (the Newton phase ends: st.newton is cleared)."""
        # one assembled matrix per system (hessian.py), its products run by
        # row blocks on all cores (parallel.py)
        if st.newton:
            st.Hsum = Hdata = np.add(st.Hgn, st.K, out=st.Hsum)
        else:
            Hdata = st.Hgn
        M = self.lm_matrix(Hdata, st.lam, diagH, out=st.Mbuf)
        A = parallel(M)
        if s.direct:
            return self._direct_step(st.g, M), 0, Hdata, None
        pcd = self._deflated(st.pc, st.U, A.__matmul__)
        rec = RitzRecorder(len(st.g), nev=s.deflate // 2) if st.recording and s.deflate >= 2 else None
        # near the minimum a Newton step may be known to be below the
        # tolerance long before it is solved for (pcg.pcg's ``small``); the
        # bound keeps a 2x margin for stalled CG iterates (the partial step
        # is still taken)
        small = None
        if st.newton:
            om_norm = max(float(np.linalg.norm(self.omega(st.x))), st.om_floor)
            small = (lambda v: np.linalg.norm(self.P @ v) / om_norm, 0.5 * s.step_tol, 50)
        res = pcg(A.__matmul__, -st.g, pcd, rtol=rtol, maxiter=5000, recorder=rec, small=small)
        cg_steps = res.iterations
        curved = None
        if res.negative_curvature and st.newton:
            # the full Hessian is not positive definite here: take the
            # Gauss-Newton step instead (the steps spent on the Newton
            # attempt still count in the report), and keep the direction of
            # negative curvature that CG found
            st.newton, Hdata, rec, curved = False, st.Hgn, None, res.direction
            A = parallel(self.lm_matrix(Hdata, st.lam, diagH, out=st.Mbuf))
            pcd = self._deflated(st.pc, st.U, A.__matmul__)
            res = pcg(A.__matmul__, -st.g, pcd, rtol=rtol, maxiter=5000)
            cg_steps += res.iterations
        if rec is not None and not rec.failed and res.converged and res.iterations > rec.m:
            st.U = _merge_vectors(rec.vectors()[1], st.U, s.deflate)
        return res, cg_steps, Hdata, curved

    def _lm_trial(self, st: _LMState, s: LMSettings, linear: bool, res: PCGResult, cg_steps: int,
                  Hdata: np.ndarray, curved: np.ndarray | None) -> _Step:
        """Where the solved step leads: its energy and the ratio rho of the
        actual to the predicted decrease, moved to the energy's minimum
        along the step or along a direction of negative curvature where
        that is lower."""
        used_newton = st.newton
        x, F = st.x, st.F
        dx = res.x
        xn = x + dx
        esn, epn = self.energy_terms(xn, linear)
        Fn = esn + epn
        # predicted reduction of the quadratic model
        Hdx = self.assembly.matrix(Hdata) @ dx
        pred = -(st.g @ dx) - 0.5 * (dx @ Hdx)
        rho = (F - Fn) / pred if pred > 0 else -1.0
        t_line = 1.0
        if s.line_search and not linear and (not used_newton or Fn >= F):
            # E along the step is a quartic (energy_along), so its exact
            # minimum there costs a few residual evaluations.  Far from the
            # minimiser the full step can overshoot (the wedge term bends
            # the energy) or fall far short (the damping holds it back).
            # Taken then: when the full step would raise the energy (instead
            # of rejecting it and solving again, for a Newton step too) and
            # when the minimum lies at >= extrapolate times the step;
            # otherwise the full step, as plain LM, since taking every line
            # minimum cost more CG steps (docs/performance.md).  rho stays
            # that of the full step, so the damping follows plain LM
            # (raising it after a replaced overshoot, as after a rejection,
            # cost iterations)
            t_line = self.line_minimum(self.energy_along(x, dx), s.line_search)
            if Fn < F and t_line < s.extrapolate:
                t_line = 1.0
            if t_line != 1.0:
                es_t, ep_t = self.energy_terms(x + t_line * dx)
                if es_t + ep_t < Fn:
                    dx = t_line * dx
                    xn, esn, epn, Fn = x + dx, es_t, ep_t, es_t + ep_t
                else:
                    t_line = 1.0
        moved_along = False
        if curved is not None and s.line_search and not linear:
            # Newton found the Hessian indefinite: the Gauss-Newton step,
            # then the minimum along the direction of negative curvature
            Fgn = Fn
            dx, xn, esn, epn, Fn = self._curvature_move(x, dx, (esn, epn), curved, s.line_search)
            moved_along = Fn < Fgn
        # the step measured on omega, not on x: x also holds the boundary
        # angles alpha, whose common shift per boundary component is a null
        # mode of Eq. 23 that omega does not see
        size = float(np.linalg.norm(self.P @ dx) / max(np.linalg.norm(self.omega(xn)), st.om_floor))
        return _Step(res, cg_steps, used_newton, dx, xn, esn, epn, rho, t_line, moved_along, size)

    def _lm_update(self, st: _LMState, step: _Step, accepted: bool, s: LMSettings, linear: bool) -> float:
        """Take an accepted step (relinearise, lower the damping, enter the
        Newton and deflation phases once the steps are small) or reject it
        (raise the damping, leave the Newton phase).  Returns the energy
        decrease (0 for a rejected step)."""
        if accepted:
            st.g_prev = np.linalg.norm(st.g)
            st.prev_step, st.last_step = st.last_step, step.size
            st.x = step.x
            st.moved += step.size
            dF = st.F - step.F
            st.es, st.ep = step.es, step.ep
            # Nielsen's update, but down by up to 1 / shrink (10x, not 3x)
            # after a good step: lambda diag(H) soon exceeds H's smallest
            # eigenvalues (modes near the node regions), and the steps then
            # crawl along them
            st.lam *= max(s.shrink, 1.0 - (2.0 * step.rho - 1.0) ** 3) if step.rho > 0 else 1.0
            st.nu = 2.0
            st.g, st.Hgn, st.blocks = self.linearise(st.x, linear, out=st.Hgn)
            # Newton near the minimum: Gauss-Newton converges only linearly
            # there (the residual of Eq. 19 does not vanish at the
            # minimiser), so once the steps are small the Hessian gets its
            # second-order term
            st.newton = st.newton or (not linear and not s.direct and step.size < s.newton_step)
            if step.newton and step.rho > 0.75:
                # Newton converges quadratically only without damping: any
                # lambda left still slows it to a linear rate
                st.lam *= s.newton_shrink
            # deflation (pcg.RitzRecorder): once the steps are small the
            # systems change little from one iteration to the next and keep
            # the same few very small eigenvalues (modes around node regions
            # and curves that the preconditioner misses); eigenvectors found
            # while solving one system are a coarse space for the next
            st.recording = st.recording or (not s.direct and step.size < s.deflate_step)
            st.K = st.Kbuf = self.second_order(st.x, out=st.Kbuf) if st.newton else None
        else:
            st.lam *= st.nu
            st.nu *= 2.0
            dF = 0.0
            st.newton, st.K = False, None
        st.rejected = 0 if accepted else st.rejected + 1
        return dF

    def _lm_stop(self, st: _LMState, step: _Step, accepted: bool, dF: float, s: LMSettings, tol: float,
                 linear: bool) -> tuple[bool, str] | None:
        """The stopping rule: (converged, reason) once LM may stop, else None."""
        # converged once the distance left to the minimiser is below
        # step_tol.  An accepted step this small leaves a distance far
        # smaller still.  In the Newton phase the steps contract
        # (quadratically once the damping is gone), and the distance left
        # after a step of s that followed one of s_prev is at most about
        # s * (s / s_prev), the last contraction once more
        size = step.size
        contracted = (step.newton and st.prev_step is not None and size <= 0.1 * st.prev_step
                      and size * size / st.prev_step <= s.step_tol)
        if accepted and (size <= s.step_tol or contracted or (dF <= tol * st.F and size <= 100 * s.step_tol)):
            return True, "converged: step below tolerance"
        res = step.res
        if res.small_solution or (not accepted and st.rejected == 1 and res.converged and size <= s.step_tol):
            # the next step is below the tolerance (taken if it lowered the
            # energy: a step this small changes it at round-off)
            return True, "converged: next step below tolerance"
        gnorm = np.linalg.norm(st.g)
        if gnorm <= 1e-13 * max(st.g0, 1.0):
            return True, "converged: gradient vanished"
        if st.rejected >= 6 or st.lam > 1e12:
            # no step of any size decreases the energy: a minimum to working
            # precision
            converged = bool(gnorm <= 1e-6 * max(st.g0, 1e-300))
            return converged, "stopped: no further decrease possible" + (" (converged)" if converged else "")
        if linear and accepted and res.converged and res.relative_residual <= 1e-9:
            return True, "converged: linear problem solved"
        return None


def _merge_vectors(new: np.ndarray, old: np.ndarray | None, cap: int) -> np.ndarray:
    """An orthonormal basis of the newly recorded vectors and as many of the
    earlier ones as fit in cap columns (the new ones first)."""
    M = new if old is None else np.hstack([new, old])
    Q, R = np.linalg.qr(M[:, :cap])
    d = np.abs(np.diag(R))
    return Q[:, d > 1e-8 * max(d.max(), 1e-300)]
