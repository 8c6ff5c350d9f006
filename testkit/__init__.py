"""Tools for the tests and the benchmarks, never shipped in the extension:
inputs made the way other tools make them (tetedge.py).  They import the
solver; the solver never imports them."""
