"""The boundary surface: triangle-surface topology and checks
(trisurface.py), OBJ polygons into triangles (polygons.py), and its sharp
features, Poincaré–Hopf (§3.3, features.py) and the quantisation of sharp
corners (corners.py)."""
