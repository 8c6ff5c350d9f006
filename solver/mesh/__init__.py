"""The tetrahedral mesh K with the network embedded (§2.1, §5.1): the mesh
data structure (tetmesh.py), curve tubes handed to the mesher (tubes.py),
curve ends kept off the mesher's surface vertices (clearance.py), fTetWild
(tetwild.py), flat-tet repair (slivers.py), red refinement
(refine.py), snapping onto sharp features (snapping.py) and tracing the
curves through the tets (embed.py)."""
