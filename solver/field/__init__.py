"""The cross field, in the order of the paper: the 2D boundary field (§3,
boundary2d.py), the linear constraints on ω (§4.2, constraints.py), the
structure equation (Eq. 17, structure.py), the Levenberg–Marquardt
matrices (hessian.py) and solve (Eq. 23, volume3d.py), the development
of ω into frames (§4.3, develop.py) from its root (root.py); beside them the
boundary stage (meshed_boundary.py), the turns around the solid's handles
(handles.py), per-tet frames and face matchings (§5.5, matchings.py), and
the solved field as one value (solved.py) with its stored arrays read back
and checked (arrays.py)."""
