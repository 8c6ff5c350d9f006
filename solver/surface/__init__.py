"""The boundary surface: triangle-surface topology and checks
(trisurface.py) and its sharp features, corners and Poincaré–Hopf (§3.3,
features.py)."""
