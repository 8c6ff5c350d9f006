"""How fine the tet mesh is, where, and whether this machine can hold it
(issues 27d and 28).

Three things, all decided before any heavy work:

* **The estimate.**  fTetWild meshes hold about ``TETS_PER_H3`` = 15 tets per
  h^3 of volume; a graded mesh adds the integral of 15 (h(x)^-3 - H^-3)
  over the region where the sizing field h(x) is finer than the bulk edge
  length H.  Peak memory is the larger of the solver's and fTetWild's:
  ``SOLVER_KB_PER_TET`` = 18.5 KB per tet plus 100 MB (a linear fit of the
  benchmark's peaks, bench/RESULTS.md: 383 MB at 18.6k tets, 1,689 MB at
  97k, 3,557 MB at 195k), and ``MESHER_KB_PER_TET`` = 8.5 KB per tet of
  fTetWild's own mesh (the 1.5M-tet run of issue 27 peaked at 12.4 GB;
  fTetWild on a bare cube needs far less, 220 MB for 411k tets).
* **The guard.**  A solve is refused when the estimate exceeds
  ``DEFAULT_MAX_TETS`` = 1,000,000 tets or its memory exceeds
  ``RAM_FRACTION`` = 3/4 of the machine's physical memory (on a 24 GB,
  2-core machine the two coincide: 1M tets need ~18 GB and take the LM
  ten minutes or more).  ``Options.max_tets`` (CLI ``--max-tets``) replaces
  both limits with an explicit tet count.
* **The budget and the grading.**  With the edge length automatic, the
  mesh aims at ``Options.target_tets`` tets whatever the network: the bulk
  gets the edge length H that the budget leaves once the network's needs
  are paid for, and the sizing field
  h(x) = min(H, min_i (h_i + g |x - p_i|)) is fine only near
  network sample points p_i that need it: h_i = (local feature size) / 3,
  where the local feature size is the length of a curve between nodes,
  the distance of a curve to another or to the surface (as in
  network.validation.network_needs).  When the network's
  needs alone exceed the budget, h_i are floored (the report says so and
  by how much the budget would have to grow).  bisection.py refines the
  bulk mesh to this field after meshing.  The growth rate g is
  ``Options.grading`` (default ``GRADING`` = 0.5): around a small part of
  the network (node-to-node curves shorter than an edge) the field turns
  like 1/r, so an edge turns it by about g and the structure residual of
  every octave of distance is about the same, set by g; a gentler grading
  costs ~(0.5 / g)^3 times the graded tets (docs/limitations.md).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..errors import MeshingError
from ..network.network import PreparedNetwork
from ..network.validation import network_needs
from ..surface.trisurface import TriSurface

TETS_PER_H3 = 15.0
SOLVER_KB_PER_TET = 18.5
SOLVER_BASE_MB = 100.0
MESHER_KB_PER_TET = 8.5
DEFAULT_MAX_TETS = 1_000_000
DEFAULT_TARGET_TETS = 15_000  # the budget when Options.target_tets is None
CEILING_FACTOR = 4.0  # ... which the network may exceed up to this many times (Options.tets_ceiling)
# expected seconds end to end ~ SECONDS_PER_TET_POW * tets^0.85 on the bench
# machine (2 cores): a fit of bench/RESULTS.md's ball (15 s at 18.6k tets,
# 46 s at 97k, 125 s at 195k) and the genus-2 family (10-24 s at ~12k);
# the network and the machine's load move it by up to ~2x either way
SECONDS_PER_TET_POW = 3.4e-3
TIME_EXPONENT = 0.85
RAM_FRACTION = 0.75
GRADING = 0.5  # growth of the sizing field per unit distance with a budget held as given (Options.grading)
# the growth the network asks for where the plan may spend beyond the budget:
# around node-to-node curves shorter than an edge the structure penalty is
# set by the growth (docs/limitations.md: 2.73 at 0.5, 0.92 at 0.2), so the
# automatic grading is the gentlest of GRADING_STEPS within the ceiling,
# the finest sizes floored by up to GRADING_FLOOR_SLACK if need be: on
# the short-curve ball (curves 0.1 long) 0.2 fitted whole and gave 29k tets
# and penalty 1.06-1.07 (bar: 1), 0.15 with its finest size floored from
# 0.0333 to 0.0353 gave 41.7k tets and 0.735, converged in 13 LM iterations
# against 15-16, in about the same time (76 s against 70-80 s)
GRADING_GENTLEST = 0.15
GRADING_STEPS = (0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.5)
GRADING_FLOOR_SLACK = 1.1
BULK_SHARE_MIN = 0.5  # the bulk keeps at least half of the budget's tets
# bisected tets are less regular than fTetWild's: grading a ball's mesh
# from 0.2 down to a point of 0.02 (bisection.py, longest edges <= 1.5 h)
# added 1,925 tets where the integral of 15 (h^-3 - H^-3) says 1,160
GRADED_FACTOR = 1.7
# the final estimate tests its samples for inside the solid (winding
# numbers: samples x faces) on surfaces up to this many faces
INSIDE_TEST_MAX_FACES = 20_000
INSIDE_SAMPLES = 500


class ResolutionError(MeshingError):
    """The requested resolution would need more tets or memory than allowed."""


def physical_memory_mb() -> float:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**20
    except (ValueError, OSError, AttributeError):
        return 16384.0


def memory_mb(tets: float, mesher_tets: float | None = None) -> float:
    """Estimated peak memory (MB) of a solve with this many tets, fTetWild
    having meshed mesher_tets of them (default: all)."""
    mesher = tets if mesher_tets is None else mesher_tets
    return max(SOLVER_BASE_MB + SOLVER_KB_PER_TET * tets / 1024.0, SOLVER_BASE_MB + MESHER_KB_PER_TET * mesher / 1024.0)


def solid_volume(surface: TriSurface) -> float:
    """The volume the closed surface bounds (all its components)."""
    return float(np.sum(np.abs(surface.signed_volumes())))


def uniform_tets(volume: float, h: float) -> float:
    return TETS_PER_H3 * volume / h**3


@dataclass
class Plan:
    """The resolution of a solve, decided before meshing.

    edge_length : bulk edge length H
    tets        : estimated tet count (bulk + graded)
    graded_tets : the part of it due to the grading
    sources     : (n, 3) network points where the mesh is finer, sizes (n,)
                  their edge lengths (after the floor); empty when uniform
    floor       : edge length below which the network's needs were not
                  met to keep the budget (0: all met)
    needed_tets : the estimate had every need been met (== tets if floor 0)
    grading     : growth of the edge length per unit distance from the sources
    """

    edge_length: float
    tets: float
    graded_tets: float = 0.0
    sources: np.ndarray | None = None
    sizes: np.ndarray | None = None
    floor: float = 0.0
    needed_tets: float = 0.0
    finest: float = 0.0
    need_min: float = 0.0
    grading: float = GRADING
    budget: float = 0.0  # the tet budget asked for (target_tets); 0: none (edge length given)
    ceiling: float = 0.0  # what the plan may spend where the network asks for more than the budget

    @property
    def graded(self) -> bool:
        return self.sizes is not None and len(self.sizes) > 0

    def sizing(self, X: np.ndarray) -> np.ndarray:
        """Edge length h(x) wanted at points X (n, 3)."""
        return sizing_field(X, self.sources, self.sizes, self.edge_length, self.grading)

    @property
    def mesh_budget(self) -> int | None:
        """The tet count the mesh stage keeps within 1.5x of: the budget, or
        what the network asked beyond it up to the ceiling; None when the
        edge length was given."""
        if not self.budget:
            return None
        return int(round(max(self.budget, min(self.tets, self.ceiling or self.budget))))

    def describe(self) -> str:
        """The estimate printed before meshing: edge lengths, tets, memory,
        expected time, and what was spent beyond the budget or held back."""
        s = f"edge length {self.edge_length:.4g}"
        if self.graded:
            s += f" in the bulk, down to {self.finest:.4g} near the network (grading {self.grading:g})"
        s += (f"; expected ~{self.tets:,.0f} tets, ~{memory_mb(self.tets):,.0f} MB, "
              f"~{expected_seconds(self.tets):.0f} s end to end")
        if self.budget and self.tets > 1.05 * self.budget and self.floor == 0:
            s += f" (the network asks for more than the budget of {self.budget:,.0f} tets: spent)"
        if self.floor > 0:
            why = (f"the ceiling of {self.ceiling:,.0f} tets" if self.ceiling > self.budget else "the budget")
            s += (f" (the network asks for edges down to {self.need_min:.3g}, ~{self.needed_tets:,.0f} "
                  f"tets: held at {self.floor:.3g} to keep {why}; held back ~{self.needed_tets - self.tets:,.0f} "
                  "tets)")
        return s


def expected_seconds(tets: float) -> float:
    """Expected seconds end to end of a solve of this many tets on the
    bench machine (SECONDS_PER_TET_POW)."""
    return float(SECONDS_PER_TET_POW * max(tets, 1.0) ** TIME_EXPONENT)


def sizing_field(X, sources, sizes, H, grading: float = GRADING, k: int = 24) -> np.ndarray:
    X = np.asarray(X, float)
    out = np.full(len(X), float(H))
    if sources is None or len(sources) == 0:
        return out
    tree = cKDTree(sources)
    d, j = tree.query(X, k=min(k, len(sources)))
    if d.ndim == 1:
        d, j = d[:, None], j[:, None]
    return np.minimum(out, np.min(sizes[j] + grading * d, axis=1))


# ------------------------------------------------------------------ budget
_UNIT_BALL = None


def _unit_ball(n: int = 4000) -> np.ndarray:
    global _UNIT_BALL
    if _UNIT_BALL is None or len(_UNIT_BALL) != n:
        rng = np.random.default_rng(12345)
        u = rng.normal(size=(n, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        _UNIT_BALL = (u * rng.uniform(0, 1, n)[:, None] ** (1.0 / 3.0), rng.uniform(0, 1, n))
    return _UNIT_BALL


def graded_extra_tets(sources: np.ndarray, sizes: np.ndarray, H: float, grading: float = GRADING,
                      winding=None) -> float:
    """Monte Carlo estimate of the tets the sizing field adds to a uniform
    mesh at H: the integral of 15 (h^-3 - H^-3) over the union of the balls
    where h < H (each sample weighted by 1 / the number of balls holding it,
    so overlaps count once).  winding: None, or a function of points (k, 3)
    returning the winding number (> 0.5 inside the solid); without it the
    part of the balls outside the solid is counted too and the estimate errs
    high -- by 1.7x on the genus-2 family at grading 0.2, where the balls
    reach through a block 0.5 thick (issue 41b), so the printed estimate
    counts inside only."""
    sel = sizes < H
    if not np.any(sel):
        return 0.0
    P, h = sources[sel], sizes[sel]
    R = (H - h) / grading
    vol = 4.0 / 3.0 * np.pi * R**3
    U, w = _unit_ball()
    cdf = np.cumsum(vol) / vol.sum()
    pick = np.minimum(np.searchsorted(cdf, w), len(P) - 1)
    X = P[pick] + R[pick, None] * U
    pairs = cKDTree(X).sparse_distance_matrix(cKDTree(P), R.max(), output_type="coo_matrix")
    row, flat, d = pairs.row, pairs.col, pairs.data
    inside = d < R[flat]
    c = np.bincount(row[inside], minlength=len(X)).astype(float)
    hx = np.full(len(X), H)
    np.minimum.at(hx, row[inside], h[flat[inside]] + grading * d[inside])
    f = TETS_PER_H3 * (hx**-3 - H**-3)
    if winding is not None:
        # an unbiased subsample (winding numbers cost samples x faces)
        sub = np.arange(0, len(X), max(1, len(X) // INSIDE_SAMPLES))
        keep = np.zeros(len(X))
        keep[sub] = (np.asarray(winding(X[sub])) > 0.5) * (len(X) / len(sub))
        f = f * keep
    return float(GRADED_FACTOR * vol.sum() / len(X) * np.sum(f / np.maximum(c, 1.0)))


def plan_resolution(volume: float, S: TriSurface, pn: PreparedNetwork, target_tets: int,
                    graded: bool = True, grading: float | None = GRADING, ceiling: float | None = None,
                    curve_scales: np.ndarray | None = None) -> Plan:
    """The automatic resolution: a bulk edge length and a sizing field for
    the tet budget target_tets (module docstring).

    ceiling      : where the network's needs cost more than the budget, the
                   plan keeps the bulk at the budget's edge length and
                   spends what the network asks, up to this many tets; past
                   it the needs are floored.  None (or <= target_tets): the
                   budget holds, the bulk coarsening to make room first.
    grading      : growth of the sizing field; None: automatic, the
                   gentlest of GRADING_STEPS whose plan fits the ceiling
                   with the finest sizes floored by up to
                   GRADING_FLOOR_SLACK (GRADING when the budget is held).
    curve_scales : (#curves,) the local scale each curve was repaired at
                   (network.intake): a curve repaired finer than the bulk
                   needs that edge length along it."""
    H0 = (TETS_PER_H3 * volume / target_tets) ** (1.0 / 3.0)
    pts, need = network_needs(S, pn) if graded else (np.zeros((0, 3)), np.zeros(0))
    h = need / 3.0
    if graded and curve_scales is not None:
        lp, lh = _local_scale_sources(pn, curve_scales)
        pts, h = np.vstack([pts, lp]), np.r_[h, lh]
    sel = h < H0
    ceiling = float(ceiling) if ceiling is not None else float(target_tets)
    if not np.any(sel):
        return Plan(edge_length=H0, tets=uniform_tets(volume, H0), budget=target_tets, ceiling=ceiling,
                    grading=GRADING if grading is None else float(grading))
    pts, h = pts[sel], h[sel]
    need_min = float(h.min())
    if grading is None:
        grading = GRADING
        if ceiling > target_tets:
            slack = np.maximum(h, GRADING_FLOOR_SLACK * need_min)
            for g in GRADING_STEPS:
                if uniform_tets(volume, H0) + graded_extra_tets(pts, slack, H0, g) <= ceiling:
                    grading = g
                    break
    total = lambda H, hh: uniform_tets(volume, H) + graded_extra_tets(pts, hh, H, grading)  # noqa: E731
    H_max = H0 / BULK_SHARE_MIN ** (1.0 / 3.0)
    needed = total(H0, h)
    floor = 0.0
    if needed > target_tets and ceiling > target_tets:
        # issue 41b: the default spends what the network asks, up to the
        # ceiling, with the bulk at the budget's edge length; past the
        # ceiling the finest needs are floored
        H = H0
        if needed > ceiling:
            lo, hi = need_min, H
            for _ in range(14):
                mid = np.sqrt(lo * hi)
                lo, hi = (mid, hi) if total(H, np.maximum(h, mid)) > ceiling else (lo, mid)
            floor = hi
    elif total(H_max, h) <= target_tets:
        lo, hi = H0, H_max
        for _ in range(8):
            mid = np.sqrt(lo * hi)
            lo, hi = (mid, hi) if total(mid, h) > target_tets else (lo, mid)
        H = hi
    else:
        # the network's needs alone exceed what the budget leaves: floor them
        H = H_max
        lo, hi = need_min, H
        for _ in range(14):
            mid = np.sqrt(lo * hi)
            lo, hi = (mid, hi) if total(H, np.maximum(h, mid)) > target_tets else (lo, mid)
        floor = hi
    hh = np.maximum(h, floor)
    # the estimate printed and kept by the mesh stage: inside the solid only
    # (the bisections above err high, so spend at most the ceiling)
    inside = S.winding_number if len(S.F) <= INSIDE_TEST_MAX_FACES else None
    extra = graded_extra_tets(pts, hh, H, grading, inside)
    return Plan(edge_length=float(H), tets=uniform_tets(volume, H) + extra, graded_tets=extra, sources=pts,
                sizes=hh, floor=float(floor), needed_tets=float(needed), finest=float(hh.min()), need_min=need_min,
                grading=float(grading), budget=target_tets, ceiling=ceiling)


def _local_scale_sources(pn: PreparedNetwork, scales: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points along the curves repaired at a finer local scale than the rest
    (network.intake: an end bend too tight for h), at half that spacing,
    with that scale as their edge length."""
    base = float(np.max(scales)) if len(scales) else 0.0
    P, hs = [np.zeros((0, 3))], [np.zeros(0)]
    for c, sc in zip(pn.curves, scales):
        if sc >= (1.0 - 1e-9) * base:
            continue
        cum = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(c.points, axis=0), axis=1))]
        s = np.linspace(0.0, cum[-1], max(2, int(np.ceil(cum[-1] / (0.5 * sc))) + 1))
        P.append(np.stack([np.interp(s, cum, c.points[:, k]) for k in range(3)], axis=1))
        hs.append(np.full(len(s), float(sc)))
    return np.vstack(P), np.concatenate(hs)


# ------------------------------------------------------------------- guard
def tet_limit(max_tets: int | None) -> tuple[int, str]:
    """The tet count past which a solve is refused, and why that number."""
    if max_tets is not None:
        return int(max_tets), f"max_tets = {int(max_tets):,}"
    ram = physical_memory_mb()
    fits = int((RAM_FRACTION * ram - SOLVER_BASE_MB) * 1024.0 / SOLVER_KB_PER_TET)
    if fits < DEFAULT_MAX_TETS:
        return fits, (f"{fits:,} tets, what fits in {RAM_FRACTION:.0%} of this machine's {ram / 1024:.0f} GB of "
                      f"memory")
    return DEFAULT_MAX_TETS, f"the default limit of {DEFAULT_MAX_TETS:,} tets"


def refusal(tets: float, max_tets: int | None, what: str, mesher_tets: float | None = None,
            volume: float | None = None) -> str | None:
    """The message refusing a solve of ~tets tets, or None if it is allowed.

    what   : how the size came about (the edge length, the budget)
    volume : the solid's, to suggest the smallest edge length allowed"""
    limit, why = tet_limit(max_tets)
    hint = f" (at least {(TETS_PER_H3 * volume / limit) ** (1 / 3):.3g})" if volume else ""
    if not np.isfinite(tets) or tets > limit:
        gb = memory_mb(tets, mesher_tets) / 1024.0
        mem_s = (f"{gb:.1f} GB" if gb < 10 else f"{gb:,.0f} GB" if gb < 1e6 else f"{gb:.2g} GB") if np.isfinite(gb) \
            else "unbounded memory"
        return (f"the tet mesh would have ~{tets:,.3g} tets ({what}) and need ~{mem_s} of memory, past {why}. "
                f"Use a larger edge length{hint} or a smaller target_tets, or, on a machine that can hold it, "
                f"raise the limit: Options(max_tets=N) (command line: --max-tets N).")
    return None


def check_resolution(tets: float, max_tets: int | None, what: str, mesher_tets: float | None = None,
                     volume: float | None = None) -> None:
    msg = refusal(tets, max_tets, what, mesher_tets, volume)
    if msg is not None:
        raise ResolutionError(msg)
