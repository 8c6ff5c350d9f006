"""The volume problem (§4.3, Eq. 23): Levenberg-Marquardt on omega.

    minimise  sum_ij w_ij |omega_ij|^2 + a sum_f |r_f(omega)|^2
    over      omega = c + P x       (the constraints of Eq. 20-22)

Each LM step solves the damped Gauss-Newton system

    (H + lambda diag H) dx = -g,   H = 2 P^T (W + a J^T J) P,  g = 2 P^T (W omega + a J^T r)

by PCG (linalg/pcg.py).  H is assembled per LM iteration in a sparsity
pattern fixed once per problem (hessian.py: one 9x9 block per face), so a
CG step costs one sparse product, run on all cores (parallel.py).  Once
the steps are small (< 1% of omega) H also gets the second-order term
2 a P^T (sum_f r_f . d^2 r_f) P: the residual of Eq. 19 does not vanish at
the minimiser, so Gauss-Newton alone converges only linearly there (ball,
78k tets: 11 iterations; with the Newton term, 10 and a 100x smaller final
gradient).  Where that Hessian is not positive definite, the step falls
back to Gauss-Newton.  Marquardt's damping lambda diag(H) falls by up to
10x per good step and by 100x more per good Newton step: damping comparable
to H's smallest eigenvalues (modes around the node regions) slows LM to a
linear rate.  On a 98k-tet ball lambda = 1.5e-8 still left Newton a rate
of ~0.03, so those eigenvalues are near 5e-7 of the diagonal; with the
faster decrease LM took 7 iterations and 1,638 CG steps there, not 10 and
2,975.  Near the minimum CG stops as soon as its iterate is known to be
below the step tolerance (pcg.pcg's ``small``), so confirming
convergence costs ~50 CG steps, not a solve.  Once the steps are below 10%
of omega, approximate eigenvectors of the smallest eigenvalues, found while
solving one system (eigCG, pcg.RitzRecorder), deflate the next (ball,
78k tets: 4,320 -> 2,700 CG steps).  Along any line the energy is
exactly a quartic (Eq. 19 is quadratic in omega), so a step that would
raise the energy, or a Gauss-Newton step that stops far short of the
minimum along its line, is replaced by that minimum instead of being
rejected and solved again (energy_along, line_minimum).  Where the full
Hessian is indefinite (twisted fields, e.g. a torus), Newton's CG stops on
a direction of negative curvature; LM then takes the Gauss-Newton step and
moves on from it to the energy's minimum along that direction.
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
        iterations: a fresh array this size (123 MB at 98k tets) costs
        more to fault in than to fill (gauss_newton_blocks 0.07 s into a
        kept array, 0.08-0.24 s into a new one)."""
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
            # cores; both products read the vectors row by row (U y as
            # "ij,j->i" on U's columns took 1.1 ms per CG step at 78k tets,
            # as "i,ij->j" on its rows 0.5 ms)
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
        # (7.1 M nonzeros at 98k tets) to CSC and the product back to CSR
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
        decrease (as Newton-CG methods use negative curvature).  Torus,
        h = 0.3: a mesh whose Gauss-Newton steps crawled for 15 iterations
        and stopped at the 30-iteration cap converged in 21 with it."""
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
    def solve(
        self,
        x0: np.ndarray,
        max_iterations: int = 50,
        tol: float = 1e-10,
        init: str = "",
        linear: bool = False,
        progress=None,
        cancel=None,
        cg_rtol: float = 1e-3,
        cg_rtol_floor: float = 1e-6,
        step_tol: float = 1e-6,
        reuse_step: float = 0.05,
        direct: bool = False,
        newton_step: float = 0.01,
        deflate: int = 8,
        deflate_step: float = 0.1,
        shrink: float = 0.1,
        newton_shrink: float = 0.01,
        line_search: float = 4.0,
        extrapolate: float = 1.5,
    ):
        rep = LMReport(init=init, setup_seconds=self.setup_seconds)
        t0 = time.perf_counter()
        x = x0.copy()
        es, ep = self.energy_terms(x, linear)
        F = es + ep
        lam = 1e-4
        nu = 2.0
        g, Hgn, blocks = self.linearise(x, linear)
        # the matrices' values (~10 M at 98k tets) go into arrays kept for
        # the whole solve: the damped matrix, the Newton term and the
        # Hessian's sum; the Gauss-Newton values of an accepted step
        # overwrite those of the last (fresh arrays this size are new pages
        # each time, see hessian.FaceAssembly.data)
        Mbuf, Kbuf, Hsum = np.empty_like(Hgn), None, None
        g0 = np.linalg.norm(g)
        rep.iterations.append(LMIteration(0, F, es, ep, g0, lam, 0, True, 0.0))
        pc, pc_lam, moved = None, lam, 0.0
        # Newton near the minimum: Gauss-Newton converges only linearly here
        # (the residual r of Eq. 19 does not vanish at the minimiser), so
        # once the steps are small the Hessian gets its second-order term
        newton, K = False, None
        # deflation (pcg.RitzRecorder): once the steps are small, the
        # systems change little from one iteration to the next and keep the
        # same few very small eigenvalues (modes around node regions and
        # curves that the preconditioner misses); eigenvectors found while
        # solving one system are added as a coarse space to the next
        U, recording = None, False
        rejected = 0
        g_prev = g0
        prev_step = last_step = None  # the steps of the last two accepted iterations
        # steps are measured relative to |omega|, but not below an rms of
        # 1e-6 rad per edge: a field without turning (a cube's, omega = 0)
        # would otherwise never meet the step test (its steps stay at
        # round-off, a fixed fraction of an omega that is round-off too)
        om_floor = 1e-6 * np.sqrt(self.mesh.n_edges)
        for it in range(1, max_iterations + 1):
            if cancel is not None and cancel():
                raise Cancelled()
            ti = time.perf_counter()
            gn = np.linalg.norm(g)
            # Eisenstat-Walker forcing, capped at cg_rtol: tighten as the
            # gradient falls (superlinear overall).  Loose early solves
            # (cap 0.1) cost as much in the end, through 40% more LM
            # iterations (ball, 11k and 26k tets: 14 -> 10 iterations).
            # Not in the Newton phase: there the steps shrink
            # quadratically and set the accuracy (see the step test
            # below), and a step solved to 1e-3 is within a few percent of
            # the exact one (ball, 98k tets: 0.3-4%).  Tightening the last
            # Newton system (to 3.5e-5 there) cost a third of all CG steps
            # and moved the result by 5e-8 of omega (bench/RESULTS.md)
            rtol = cg_rtol
            if it > 1 and not newton:
                rtol = max(cg_rtol_floor, min(cg_rtol, 0.9 * (gn / g_prev) ** 2))
            # the preconditioner (block Jacobi + AMG on the covariant
            # gradients) changes slowly with omega and lambda: rebuild it only
            # once omega has moved or the damping changed by a large factor,
            # however small lambda is (ignoring changes below 1e-8 saved
            # builds but cost 18% more CG steps on a 36k-tet ball;
            # bench/RESULTS.md)
            diagH = self.damping_diagonal(blocks)
            if not direct and (pc is None or moved > reuse_step or not 0.01 <= lam / pc_lam <= 100.0):
                pc, pc_lam, moved = self.make_preconditioner(blocks, lam, Hgn, self.omega(x), Mbuf), lam, 0.0
                rep.preconditioner_builds += 1
            # one assembled matrix per system (hessian.py), its products run
            # by row blocks on all cores (parallel.py)
            if newton:
                Hsum = Hdata = np.add(Hgn, K, out=Hsum)
            else:
                Hdata = Hgn
            M = self.lm_matrix(Hdata, lam, diagH, out=Mbuf)
            A = parallel(M)
            curved = None  # a direction of negative curvature of the full Hessian
            if direct:
                res = self._direct_step(g, M)
                cg_steps = 0
            else:
                pcd = self._deflated(pc, U, A.__matmul__)
                rec = RitzRecorder(len(g), nev=deflate // 2) if recording and deflate >= 2 else None
                # near the minimum a Newton step may be known to be below
                # the tolerance long before it is solved for (pcg.pcg)
                # (stalled CG iterates have been seen at 0.66 and 0.96-0.99
                # of the solution's size, ball 78k and 98k tets, so the bound
                # keeps a 2x margin; the partial step is still taken below)
                small = None
                if newton:
                    om_norm = max(float(np.linalg.norm(self.omega(x))), om_floor)
                    small = (lambda v: np.linalg.norm(self.P @ v) / om_norm, 0.5 * step_tol, 50)
                res = pcg(A.__matmul__, -g, pcd, rtol=rtol, maxiter=5000, recorder=rec, small=small)
                cg_steps = res.iterations
                if res.negative_curvature and newton:
                    # the full Hessian is not positive definite here: take
                    # the Gauss-Newton step instead (the steps spent on the
                    # Newton attempt still count in the report), and keep
                    # the direction of negative curvature that CG found
                    newton, Hdata, rec, curved = False, Hgn, None, res.direction
                    A = parallel(self.lm_matrix(Hdata, lam, diagH, out=Mbuf))
                    pcd = self._deflated(pc, U, A.__matmul__)
                    res = pcg(A.__matmul__, -g, pcd, rtol=rtol, maxiter=5000)
                    cg_steps += res.iterations
                if rec is not None and not rec.failed and res.converged and res.iterations > rec.m:
                    U = _merge_vectors(rec.vectors()[1], U, deflate)
            used_newton = newton
            dx = res.x
            xn = x + dx
            esn, epn = self.energy_terms(xn, linear)
            Fn = esn + epn
            # predicted reduction of the quadratic model
            Hdx = self.assembly.matrix(Hdata) @ dx
            pred = -(g @ dx) - 0.5 * (dx @ Hdx)
            rho = (F - Fn) / pred if pred > 0 else -1.0
            t_line = 1.0
            if line_search and not linear and (not used_newton or Fn >= F):
                # E along the Gauss-Newton step is a quartic (energy_along),
                # so its exact minimum there costs a few residual evaluations.
                # (Along a Newton step too: one that would raise the energy
                # is replaced by that minimum rather than rejected.  Torus,
                # 10 fresh meshes at h = 0.3: 9 had 2-9 rejected Newton
                # steps, each a full solve, and 6 stopped at the 30-iteration
                # cap; with this and _curvature_move none did.)
                # Far from the minimiser the full step can overshoot (the
                # wedge term bends the energy) or fall far short (the
                # damping holds it back).  Taken then: when the full step
                # would raise the energy (instead of rejecting it and
                # solving again) and when the minimum lies at >= 1.5 times
                # the step.  Otherwise the full step, as plain LM: taking
                # every line minimum (t = 0.8-1.15 on the ball) cost 13-18%
                # more CG steps on 4 of 4 balls of ~99k tets.  Torus
                # example, 52.6k tets: 24 -> 18 LM iterations.  rho stays
                # that of the full step, so the damping follows plain LM
                # (raising it after a replaced overshoot, as after a
                # rejection, cost 2-3 more iterations on the torus).
                t_line = self.line_minimum(self.energy_along(x, dx), line_search)
                if Fn < F and t_line < extrapolate:
                    t_line = 1.0
                if t_line != 1.0:
                    es_t, ep_t = self.energy_terms(x + t_line * dx)
                    if es_t + ep_t < Fn:
                        dx = t_line * dx
                        xn, esn, epn, Fn = x + dx, es_t, ep_t, es_t + ep_t
                    else:
                        t_line = 1.0
            moved_along = False
            if curved is not None and line_search and not linear:
                # Newton found the Hessian indefinite: the Gauss-Newton step,
                # then the minimum along the direction of negative curvature
                Fgn = Fn
                dx, xn, esn, epn, Fn = self._curvature_move(x, dx, (esn, epn), curved, line_search)
                moved_along = Fn < Fgn
            accepted = Fn < F
            # the step measured on omega, not on x: x also holds the
            # boundary angles alpha, whose common shift per boundary
            # component is a null mode of Eq. 23 that omega does not see
            step = float(np.linalg.norm(self.P @ dx) / max(np.linalg.norm(self.omega(xn)), om_floor))
            if accepted:
                g_prev = gn
                prev_step, last_step = last_step, step
                x = xn
                moved += step
                dF = F - Fn
                F, es, ep = Fn, esn, epn
                # Nielsen's update, but down by up to 10x (not 3x) after a
                # good step: lambda diag(H) soon exceeds H's smallest
                # eigenvalues (modes near the node regions, near 5e-7 of
                # the diagonal), and the steps then crawl along them (114k-tet
                # ball: steps of 5, 5, 3, 3, 3, 2, 1% of omega and 12 LM
                # iterations with 3x; 9 iterations with 10x)
                lam *= max(shrink, 1.0 - (2.0 * rho - 1.0) ** 3) if rho > 0 else 1.0
                nu = 2.0
                g, Hgn, blocks = self.linearise(x, linear, out=Hgn)
                newton = newton or (not linear and not direct and step < newton_step)
                if used_newton and rho > 0.75:
                    # Newton converges quadratically only without damping:
                    # lambda = 1e-8 still left a linear rate (ball, 98k
                    # tets: steps of 5e-4, 4e-5, 2e-6 of omega; with
                    # lambda 100x smaller per good Newton step, 5e-4 and
                    # 6e-6 to 9e-6, after which omega was within 3e-9 of
                    # the minimiser)
                    lam *= newton_shrink
                recording = recording or (not direct and step < deflate_step)
                K = Kbuf = self.second_order(x, out=Kbuf) if newton else None
            else:
                lam *= nu
                nu *= 2.0
                dF = 0.0
                newton, K = False, None
            rep.iterations.append(
                LMIteration(it, F, es, ep, float(np.linalg.norm(g)), lam, cg_steps, accepted,
                            time.perf_counter() - ti, step, newton=used_newton, line_step=t_line,
                            curvature_move=moved_along)
            )
            if progress is not None:
                progress(it, F)
            # converged once the distance left to the minimiser is below
            # step_tol.  An accepted step this small leaves a distance far
            # smaller still.  In the Newton phase the steps contract
            # (quadratically once the damping is gone: ball, 98k tets,
            # 5.4e-3, 5.2e-4, 1.0e-5 of omega), and the distance left
            # after a step of s that followed one of s_prev is at most
            # about s * (s / s_prev), the last contraction once more.  On
            # ball meshes of 15k-98k tets LM stopped 1.4e-8 to 5.4e-8 of
            # omega from the minimiser this way (estimates 8e-9 to 2e-7;
            # the rest is the last step's CG error)
            contracted = (used_newton and prev_step is not None and step <= 0.1 * prev_step
                          and step * step / prev_step <= step_tol)
            if accepted and (step <= step_tol or contracted or (dF <= tol * F and step <= 100 * step_tol)):
                rep.converged = True
                rep.reason = "converged: step below tolerance"
                break
            if res.small_solution or (not accepted and rejected == 0 and res.converged and step <= step_tol):
                # the next step is below the tolerance (taken if it lowered
                # the energy: a step this small changes it at round-off)
                rep.converged = True
                rep.reason = "converged: next step below tolerance"
                break
            if np.linalg.norm(g) <= 1e-13 * max(g0, 1.0):
                rep.converged = True
                rep.reason = "converged: gradient vanished"
                break
            rejected = 0 if accepted else rejected + 1
            if rejected >= 6 or lam > 1e12:
                # no step of any size decreases the energy: a minimum to
                # working precision
                rep.converged = bool(np.linalg.norm(g) <= 1e-6 * max(g0, 1e-300))
                rep.reason = "stopped: no further decrease possible" + (" (converged)" if rep.converged else "")
                break
            if linear and accepted and res.converged and res.relative_residual <= 1e-9:
                rep.converged = True
                rep.reason = "converged: linear problem solved"
                break
        else:
            rep.capped = True
            rep.reason = f"stopped after {max_iterations} iterations"
        rep.seconds = time.perf_counter() - t0
        return x, rep


def _merge_vectors(new: np.ndarray, old: np.ndarray | None, cap: int) -> np.ndarray:
    """An orthonormal basis of the newly recorded vectors and as many of the
    earlier ones as fit in cap columns (the new ones first)."""
    M = new if old is None else np.hstack([new, old])
    Q, R = np.linalg.qr(M[:, :cap])
    d = np.abs(np.diag(R))
    return Q[:, d > 1e-8 * max(d.max(), 1e-300)]
