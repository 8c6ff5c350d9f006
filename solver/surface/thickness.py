"""How thick a solid is, and whether a given tet edge length can mesh it.

An edge length near or past the solid's size does not give a coarse mesh:
fTetWild keeps refining towards the envelope (minutes, gigabytes) or runs out
of memory.  ``check_edge_length`` refuses it before any meshing, with a range
that works.  The thickness is ``6 V / A`` (volume V, area A): the side of a
cube, the diameter of a ball, about three times a thin plate's thickness --
an overestimate for plates, so the refusal errs on the side of letting a
solve run.
"""

from __future__ import annotations

import numpy as np

from ..errors import OptionsError
from .trisurface import TriSurface

# at least this many edge lengths across the thickness; fewer is refused
MIN_EDGES_ACROSS = 2.0
# the finest edge length suggested, as a fraction of the thickness
FINEST_SUGGESTED = 1e-2


def thickness(S: TriSurface) -> float:
    """6 x volume / area of a closed surface (module docs)."""
    vol = float(np.sum(np.abs(S.signed_volumes())))
    area = float(S.face_areas.sum())
    return 6.0 * vol / area if area > 0 else 0.0


def check_edge_length(S: TriSurface, h: float, automatic: float | None = None) -> None:
    """Refuse (OptionsError) an edge length h with fewer than
    MIN_EDGES_ACROSS edges across the solid, naming the value, the solid's
    thickness and a range to choose from (``automatic``: the edge length a
    solve without one would use)."""
    t = thickness(S)
    if not t > 0 or h * MIN_EDGES_ACROSS <= t:
        return
    auto = f"; without an edge length the solve picks about {automatic:.3g}" if automatic else ""
    raise OptionsError(
        f"option 'edge_length' = {h:.6g}: too coarse for this solid, which is about {t:.3g} thick (6 x volume / "
        f"area): fewer than {MIN_EDGES_ACROSS:g} tet edges would span it, and the mesher would refine towards the "
        f"surface for minutes or run out of memory. Use an edge length from {FINEST_SUGGESTED * t:.3g} to "
        f"{t / MIN_EDGES_ACROSS:.3g} (in the units of the surface){auto}")
