"""The rules a network's indices alone decide, without the intake.

``check_topology`` runs what ``validation.check_input`` checks of the
indices -- the node rules (``validation.check_nodes``) and Poincaré–Hopf on
each boundary component and sharp-edge patch, after the turns of the sharp
corners are chosen -- on the curves as given: no repair, no geometry checks.
An import that must tell how to read a file's integer tags
(io/tetnetwork.py) asks it of each reading: read the wrong way, the same tags
give indices whose ends no longer sum to the Euler characteristic.
"""

from __future__ import annotations

import numpy as np

from ..errors import TopologyError
from ..surface.corners import explain_failure, resolve_corners
from ..surface.features import check_poincare_hopf
from ..surface.trisurface import TriSurface
from .network import Network, prepare_network
from .validation import _label, check_nodes, sharp_feature_graph


def check_topology(S: TriSurface, net: Network) -> None:
    """Node rules and Poincaré–Hopf of net on the closed surface S (module
    docs).  Curve ends within the network's boundary tolerance of S count on
    the triangle closest to them; others are left for check_input.  Raises
    NetworkError or TopologyError (as check_input words them)."""
    diag = S.bbox_diagonal
    pn = prepare_network(net, diag)
    check_nodes(pn, lambda ci: _label(net.curves, pn.source[ci]))
    btol = net.boundary_tolerance if net.boundary_tolerance is not None else 1e-2 * diag
    face_sigma = np.zeros(len(S.F))
    ends = [(ci, c.points[0 if end == 0 else -1]) for ci, c in enumerate(pn.curves)
            for end, kind in ((0, pn.start_kind[ci]), (1, pn.end_kind[ci])) if kind == "boundary"]
    if ends:
        d, f, _ = S.closest_points(np.array([x for _, x in ends]))
        near = d <= btol
        np.add.at(face_sigma, f[near], [pn.curves[ci].sigma for (ci, _), ok in zip(ends, near) if ok])
    G, corners = resolve_corners(S, sharp_feature_graph(S, net), face_sigma, net.corner_turns)
    try:
        check_poincare_hopf(S, G, face_sigma, "the boundary")
        G.check_patches(face_sigma)
    except TopologyError as e:
        explain_failure(S, G, corners, e, face_sigma)
