"""``check``: what a solve verifies before any meshing, run on its own.

The surface is validated, the network checked against it after the curve
intake has repaired it at the mesh scale, and the resolution planned (and
refused past the tet / memory limit).  The command line's ``--check`` and
the add-on's Check Network both run this; ``FieldProblem`` runs the same
steps before it meshes.
"""

from __future__ import annotations

from dataclasses import dataclass

from .mesh.resolution import Plan
from .network.intake import repairs_text
from .network.network import Network
from .network.validation import CheckedInput, check_input
from .pipeline import Options, as_options, resolution_plan
from .surface.corners import corners_text


@dataclass
class CheckResult:
    """What ``check`` found: the input as a solve would take it.

    Attributes
    ----------
    checked : CheckedInput
        The validated surface, the prepared (repaired) network, the sharp
        features, the curve repairs and the corner choices.
    plan : Plan
        The resolution a solve would mesh at: the bulk edge length, the
        grading towards the network and the expected tet count
        (``plan.describe()`` says it in a line).
    """

    checked: CheckedInput
    plan: Plan

    @property
    def interior_curves(self) -> int:
        """Interior curves after the intake (pieces joined, sharp curves left out)."""
        return len(self.checked.network.curves)

    @property
    def nodes(self) -> int:
        """Nodes where 3-4 interior curves meet."""
        return len(self.checked.network.nodes)

    @property
    def sharp_edges(self) -> int:
        """Sharp edges of the surface (marked, by angle and by sharp curves)."""
        return int(self.checked.features.sharp.sum())

    @property
    def boundary_components(self) -> int:
        """Connected components of the surface."""
        return int(self.checked.surface.n_components)

    @property
    def repairs(self) -> list:
        """One ``CurveRepair`` per interior curve: what the intake changed."""
        return self.checked.repairs

    def repairs_text(self) -> str:
        """Lines on the repaired curves (the first counts them); empty when none changed."""
        return repairs_text(self.checked.repairs, self.checked.scale)

    def corners_text(self) -> str:
        """Lines on the sharp corners whose turn was ambiguous or chosen; empty when none."""
        return corners_text(self.checked.corners)


def check(V, F, network: Network, *, options: Options | None = None) -> CheckResult:
    """Validate a domain and its network, repair the curves and plan the
    resolution, as a solve does before meshing -- without meshing.

    Parameters
    ----------
    V : (n, 3) float array
        Vertices of the closed surface.
    F : (m, 3) int array
        Its triangles.
    network : Network
        The curves and sharp features.
    options : Options, optional
        The solve's settings; check reads ``edge_length`` (the scale the
        curves are repaired at, and the resolution; None: from
        ``target_tets`` and ``grading``), ``max_tets``, ``refine`` and
        ``check_intersections``.  Default ``Options()``.

    Returns
    -------
    CheckResult

    Raises
    ------
    SurfaceError
        The surface is not closed, manifold, oriented and non-degenerate.
    NetworkError
        A curve does not fit the solid (the message names it and the fix).
    TopologyError
        The indices violate Poincare-Hopf, or features and curves disagree.
    MeshingError
        The resolution asks for more tets or memory than allowed
        (``mesh.resolution.ResolutionError``).
    OptionsError
        options is not an Options.
    """
    opts = as_options(options)
    checked = check_input(V, F, network, check_intersections=opts.check_intersections, scale=opts.edge_length,
                          repair=True, target_tets=opts.budget)
    return CheckResult(checked=checked, plan=resolution_plan(checked, opts))
