"""Settings of a hex-meshing run: ``HexOptions``, checked when made, and the
defaults (``DEFAULT_HEXES``, ``MAX_HEXES``) the command line and the add-on
share."""

from __future__ import annotations

from dataclasses import dataclass, fields

from .. import checks
from ..errors import OptionsError
from .sizing import FinerNear

DEFAULT_HEXES = 3000
"""The number of cells the automatic cell size aims at."""
MAX_HEXES = 2_000_000
"""The most cells a hex mesh may have (a cell size past it is refused)."""


@dataclass(frozen=True)
class HexOptions:
    """Settings of ``hexmesh``; every value is checked when the options are
    made (``OptionsError`` names the setting and the fix).

    Parameters
    ----------
    cell_size : float, optional
        Hex edge length in the units of the surface; None (the default):
        automatic, about ``target_hexes`` cells and finer where the network
        needs it (``default_cell_size``).
    target_hexes : int
        The number of cells the automatic cell size aims at (1 to
        ``MAX_HEXES``; ignored when ``cell_size`` is given).
    smooth : bool
        Optimise the vertex positions after the extraction (never lowering
        the minimum scaled Jacobian).
    finer_near : FinerNear, optional
        Smaller cells near chosen boundary patches or network curves
        (``sizing.FinerNear``: which, how much smaller, over how many
        cells); None (the default): one cell size everywhere.

    Raises
    ------
    OptionsError
        a cell size that is not a finite number > 0, a target that is not a
        whole number in [1, MAX_HEXES], a smooth that is not a boolean, a
        finer_near that is not a FinerNear (or words FinerNear.parse reads)
    """

    cell_size: float | None = None
    target_hexes: int = DEFAULT_HEXES
    smooth: bool = True
    finer_near: FinerNear | None = None

    def __post_init__(self):
        # types and ranges in one place (checks.py), before any hex work
        E = OptionsError
        checked = {
            "cell_size": checks.positive_float("cell_size", self.cell_size, E, allow_none=True,
                                               fix="the hex edge length in the units of the surface (None: "
                                                   "automatic)"),
            "target_hexes": checks.integer("target_hexes", self.target_hexes, E, low=1, high=MAX_HEXES,
                                           fix="the number of cells the automatic cell size aims at (default "
                                               f"{DEFAULT_HEXES})"),
            "smooth": checks.boolean("smooth", self.smooth, E),
            "finer_near": (FinerNear.parse(self.finer_near) if isinstance(self.finer_near, str) else
                           checks.instance("finer_near", self.finer_near, (FinerNear, type(None)), E,
                                           fix="solver.hexmesh.FinerNear(patches=(...), curves=(...), ratio=0.5), "
                                               "words such as 'patch 3, curve 2', or None")),
        }
        for name, value in checked.items():
            object.__setattr__(self, name, value)  # frozen: the checked, normalised value


def hex_options(options: HexOptions | None = None, **keywords) -> HexOptions:
    """The settings of a run given as keywords (``hexmesh(cell_size=...)``),
    as ``options``, or both.

    Parameters
    ----------
    options : HexOptions, optional
    **keywords
        fields of HexOptions; one left at its default defers to ``options``

    Returns
    -------
    HexOptions

    Raises
    ------
    OptionsError
        a keyword of the wrong type or range, ``options`` that is not a
        HexOptions, or a keyword that disagrees with ``options``
    """
    given = HexOptions(**keywords)
    if options is None:
        return given
    checks.instance("options", options, HexOptions, OptionsError,
                    fix="solver.hexmesh.HexOptions(cell_size=..., target_hexes=..., smooth=..., finer_near=...), "
                                        "or None")
    default = HexOptions()
    for f in fields(HexOptions):
        mine, theirs = getattr(given, f.name), getattr(options, f.name)
        if mine != getattr(default, f.name) and mine != theirs:
            raise OptionsError(f"{f.name} = {checks.describe(mine)} disagrees with options.{f.name} = "
                               f"{checks.describe(theirs)}; give it once, as a keyword or in options")
    return options
