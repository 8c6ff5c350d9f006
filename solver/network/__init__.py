"""The singularity network (§1.2): curves with an index, a role and a
torsion mode (network.py), their geometry along the curve (curves.py), the
repair of real-world curves at the mesh scale (intake.py: polylines in
polyline.py, fairing in fairing.py, their ends in curve_ends.py), the checks of
a network against the solid before any heavy work (validation.py), and the
rules its indices alone decide, without the intake (topology.py)."""

from .network import Curve, Network, PreparedNetwork, Role, Torsion

__all__ = ["Curve", "Network", "PreparedNetwork", "Role", "Torsion"]
