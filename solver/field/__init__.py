"""The cross field, in the order of the paper: the 2D boundary field (§3,
boundary2d.py), the linear constraints on ω (§4.2, constraints.py), the
structure equation (Eq. 17, structure.py), the Levenberg–Marquardt
matrices (hessian.py) and solve (Eq. 23, volume3d.py), and the development
of ω into frames (§4.3, develop.py)."""
