"""The tetrahedral mesh K with the network embedded (§2.1, §5.1): the mesh
stage of the pipeline -- which mesher, at what edge length, how many
refinements (meshing.py) -- with how fine the mesh is where and whether the
machine can hold it (resolution.py); the mesh data structure (tetmesh.py),
a dense input surface simplified to the mesh scale (decimate.py), curve
tubes handed to the mesher (tubes.py), curve ends kept off the mesher's
surface vertices (clearance.py), the meshers fTetWild (tetwild.py) and
TetGen (cdt.py), flat-tet repair (slivers.py), red refinement (refine.py),
grading by longest-edge bisection (bisection.py), snapping onto sharp
features (snapping.py), tracing the curves through the tets (embed.py), and
the curves that leave a smooth part of the boundary and come back to it
(linking.py)."""
