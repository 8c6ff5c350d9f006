"""What hex meshing refuses before any work: what is not a solved field, or
a field no hex mesh can follow (``hex_input``), a field that did not converge
(``check_converged``) and a network no hex mesh can have
(``check_indices``)."""

from __future__ import annotations

from ..errors import HexMeshError
from ..field.solved import SolvedField, as_field, field_fault


def check_indices(curves, sources=None, error=None) -> None:
    """Refuse a network no hex mesh can have, from the network alone: a
    curve of index sigma becomes hex edges of valence 4 - 4 sigma, and
    valence 2 or less means cells meeting flat, which no valid hex mesh has
    (kind 'network').  Also a curve of index -1, -2, ... (valence 8, 12,
    ...), which SymFrames' map cannot make (kind 'map': the frames turn by
    whole turns about it, which the cube group cannot tell from none; an
    8-gon O-grid cylinder's index -1 axis, its field converged, gave a
    mesh with no edge of valence 8 and the wrong boundary).

    Parameters
    ----------
    curves : list of network.Curve
        the network's curves (a Network's or a PreparedNetwork's)
    sources : list of int, optional
        the number of each curve as the user gave it (default: its position)
    error : callable(message, kind) -> exception, optional
        default: a HexMeshError of that kind

    Raises
    ------
    HexMeshError (or what ``error`` makes)
        naming the first curve of index +1/2 or more, or -1, -2, ...
    """
    fail = error or (lambda msg, kind="network": HexMeshError(msg, kind=kind))
    for i, c in enumerate(curves):
        name = f" '{c.name}'" if c.name else ""
        if float(c.sigma) >= 0.5:
            raise fail(f"curve {i if sources is None else sources[i]}{name} has index {float(c.sigma):+g}: its hex "
                       f"edges would have valence {int(round(4 - 4 * float(c.sigma)))}, cells meeting flat, which "
                       "no valid hex mesh has; use curves of index +1/4 (valence 3) or negative indices (valence 5, "
                       "6, ...)")
        if float(c.sigma) < 0 and round(4 * float(c.sigma)) % 4 == 0:
            raise fail(f"curve {i if sources is None else sources[i]}{name} has index {float(c.sigma):+g} (hex edges "
                       f"of valence {int(round(4 - 4 * float(c.sigma)))}): the frames turn by whole turns around it, "
                       "which SymFrames' map cannot tell from no turn at all, so it cannot make those edges (a limit "
                       "of SymFrames, not of the network: such hex meshes exist; indices -1/4, -1/2 and -3/4 are "
                       "meshed). The field itself solves; split the curve's turn between nearby curves of smaller "
                       "index to hex mesh it", kind="map")


def hex_input(field, what: str) -> SolvedField:
    """The SolvedField of a field argument (a SolvedField, or a Result: its
    ``.field``), checked as one a hex mesh can follow.

    Parameters
    ----------
    field : SolvedField, or a solver Result
    what : str
        the function asking, opening a refusal's message

    Returns
    -------
    SolvedField

    Raises
    ------
    OptionsError
        not a solved field (a path: read it first, io.load_field)
    HexMeshError
        a field a hex mesh cannot follow (frames that are not rotations, an
        omega that does not carry them): kind 'field'
    """
    inp = as_field(field, what)
    fault = field_fault(inp.mesh, inp.frames, inp.omega)
    if fault:
        raise HexMeshError(f"the field is not one a hex mesh can follow: {fault}", kind="field")
    return inp


def check_converged(inp: SolvedField, allow_unconverged: bool) -> str | None:
    """Refuse a field that did not converge, unless allowed.

    Returns
    -------
    str or None
        the report's note where an unconverged field is meshed as asked

    Raises
    ------
    HexMeshError
        kind 'field', for a field that did not converge and is not allowed
    """
    status = getattr(inp, "status", "converged")
    if status == "converged":
        return None
    if not allow_unconverged:
        raise HexMeshError(
            f"the field is {status}: a field that did not converge is not one a hex mesh can follow (its "
            "transitions need not close around the curves); solve it again (a finer edge length, or the "
            "advice of the solve's report) and mesh the converged field", kind="field")
    return f"the field is {status}; meshed as asked (allow_unconverged)"


def unconverged(inp: SolvedField) -> str:
    """A message's aside where the field did not converge ('' otherwise)."""
    status = getattr(inp, "status", "")
    return f" (the field itself is {status})" if status and status != "converged" else ""
