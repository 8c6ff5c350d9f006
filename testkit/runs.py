"""A hex-meshing run as the command line makes it, for the benchmarks."""

from __future__ import annotations


def hexmesh_as_cli(result):
    """``hexmesh(result)``, and where SymFrames' map fails on the field, the
    field solved again finer (pipeline.solve_finer) and that one meshed, as
    ``python -m solver ... --hex`` does.

    Returns
    -------
    (HexMesh, dict)
        the hex mesh, and what the retry did (``finer``, ``first_hex_error``,
        ``tets`` of the finer field), empty where none was needed

    Raises
    ------
    HexMeshError
        the first failure where it is not the map's, or the finer field is
        not solved or does not converge; else the finer field's.  Its
        ``retry`` (where set) is what the retry did, as returned
    """
    from solver import HexMeshError, hexmesh
    from solver.pipeline import solve_finer

    try:
        return hexmesh(result), {}
    except HexMeshError as e:
        if e.kind != "map":
            raise
        again, what = solve_finer(result)
        info = dict(finer=what, first_hex_error=str(e)[:300])
        if again is None or not again.report.converged:
            e.retry = info
            raise
        info["tets"] = int(again.report.sizes.get("tets", 0))
        try:
            return hexmesh(again), info
        except HexMeshError as e2:
            e2.retry = info
            raise
