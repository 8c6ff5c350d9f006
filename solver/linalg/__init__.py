"""Numerical building blocks with no knowledge of meshes or networks:
rotations and the cube group (rotations.py), sparse products on several
cores (parallel.py), preconditioned conjugate gradients (pcg.py; on several
right-hand sides in lockstep, multipcg.py), smoothed-aggregation algebraic
multigrid (amg.py) and limited-memory BFGS without BLAS threads (lbfgs.py)."""
