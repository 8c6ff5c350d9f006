"""The boundary surface: the triangle surface with its topology, geometry,
winding numbers and closest points (trisurface.py), whether it bounds one
solid (validation.py), which of its triangles cross or touch (intersect.py),
OBJ polygons into triangles (polygons.py), whether an edge length can mesh
the solid (thickness.py), and its sharp features, Poincaré–Hopf (§3.3,
features.py) and the quantisation of sharp corners (corners.py)."""
