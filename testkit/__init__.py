"""Tools for the tests and the benchmarks, never shipped in the extension:
inputs made the way other tools make them (tetedge.py), real-like
networks taken from hex meshes (hexnet.py), the genus-2 family (genus2.py),
sculpted solids (sculpt.py), solids of revolution (revolve.py) and solved fields changed for a test
(fields.py), and a hex-meshing run as the command line makes it (runs.py).  They import the
solver; the solver never imports them."""
