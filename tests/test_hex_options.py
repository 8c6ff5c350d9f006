"""The settings of a hex-meshing run (hexmesh/options.py): checked when
made, before the field is read, and the same whether given as keywords or
as one HexOptions; the stage names a run reports."""

import dataclasses
import importlib
import math

import pytest

from solver import OptionsError
from solver.errors import Cancelled
from solver.hexmesh import DEFAULT_HEXES, MAX_HEXES, STAGE_WEIGHTS, HexOptions, hexmesh


class Touched(Exception):
    """Raised by a fake field as soon as anything reads it."""


class Untouchable:
    """A stand-in for a field that no refusal of the settings may read."""

    def __getattr__(self, name):
        raise Touched(name)


def test_the_defaults_are_public():
    hexmesh_pkg = importlib.import_module("solver.hexmesh")  # (solver.hexmesh is also the function)
    assert DEFAULT_HEXES == 3000 and MAX_HEXES == 2_000_000
    assert {"DEFAULT_HEXES", "MAX_HEXES", "HexOptions"} <= set(hexmesh_pkg.__all__)
    assert HexOptions() == HexOptions(cell_size=None, target_hexes=DEFAULT_HEXES, smooth=True)


@pytest.mark.parametrize("cell", [-1.0, 0, 0.0, math.nan, math.inf, -math.inf, "0.1", True, [0.1]])
def test_a_cell_size_that_is_not_a_positive_number_is_refused(cell):
    with pytest.raises(OptionsError, match=r"^cell_size = .*: must be a finite number > 0") as e:
        HexOptions(cell_size=cell)
    assert "hex edge length" in str(e.value)  # the fix


@pytest.mark.parametrize("target", [0, -5, 2.5, "3000", None, True, MAX_HEXES + 1, math.nan])
def test_a_target_that_is_not_a_count_in_range_is_refused(target):
    with pytest.raises(OptionsError, match=rf"^target_hexes = .*: must be a whole number >= 1 and <= {MAX_HEXES}"):
        HexOptions(target_hexes=target)


@pytest.mark.parametrize("smooth", ["false", 0, 1, None])
def test_smooth_must_be_a_boolean(smooth):
    with pytest.raises(OptionsError, match=r"^smooth = .*: must be true or false"):
        HexOptions(smooth=smooth)


def test_the_values_are_normalised_and_frozen():
    o = HexOptions(cell_size=1, target_hexes=4000.0)
    assert o.cell_size == 1.0 and isinstance(o.cell_size, float)
    assert o.target_hexes == 4000 and isinstance(o.target_hexes, int)
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.cell_size = 2.0


@pytest.mark.parametrize("kw", [{"cell_size": -1}, {"cell_size": 0.0}, {"cell_size": math.nan},
                                {"target_hexes": 0}, {"smooth": "yes"}])
def test_hexmesh_refuses_bad_settings_before_reading_the_field(kw):
    """The settings are checked first: the field (any object here) is not
    read, and a bad cell size is an OptionsError, not a HexMeshError."""
    name = next(iter(kw))
    with pytest.raises(OptionsError, match=rf"^{name} = "):
        hexmesh(Untouchable(), **kw)
    with pytest.raises(OptionsError, match=rf"^{name} = "):
        hexmesh("result.npz", **kw)  # a path is refused only after the settings


def test_options_and_keywords():
    """options= is read like the keywords; a keyword left at its default
    defers to it, one that agrees passes, one that disagrees is refused."""
    with pytest.raises(Touched):  # good settings: on to reading the field
        hexmesh(Untouchable(), options=HexOptions(cell_size=0.2, smooth=False))
    with pytest.raises(Touched):
        hexmesh(Untouchable(), 0.2, smooth=False, options=HexOptions(cell_size=0.2, smooth=False))
    with pytest.raises(OptionsError, match=r"^cell_size = 0.3 disagrees with options.cell_size = 0.2"):
        hexmesh(Untouchable(), 0.3, options=HexOptions(cell_size=0.2))
    with pytest.raises(OptionsError, match=r"^target_hexes = 500 disagrees with options.target_hexes = 4000"):
        hexmesh(Untouchable(), target_hexes=500, options=HexOptions(target_hexes=4000))
    with pytest.raises(OptionsError, match=r"^options = .*: must be a HexOptions"):
        hexmesh(Untouchable(), options={"cell_size": 0.2})


def test_the_map_system_is_a_stage_of_its_own():
    """STAGE_WEIGHTS lists the stages in the order they run, the map
    system between the transitions and the seamless map; the weights are
    shares of a run."""
    stages = list(STAGE_WEIGHTS)
    assert stages == ["curves onto edges", "transitions", "map system", "seamless map", "integer-grid map",
                      "extraction", "smoothing", "quality"]
    assert sum(STAGE_WEIGHTS.values()) == pytest.approx(1.0)


@pytest.mark.slow
@pytest.mark.mesher
def test_a_run_reports_the_map_system_apart(solved):
    """A run cancelled before the seamless map has announced, timed and
    finished 'transitions' and 'map system' as two stages."""
    seen = []

    def progress(stage, fraction, message):
        seen.append((stage, fraction, message))

    with pytest.raises(Cancelled):
        hexmesh(solved("cube"), progress=progress, cancel=lambda: any(s == "map system" and m.endswith("done")
                                                                        for s, _, m in seen))
    done = [s for s, _, m in seen if m.endswith(" done")]
    assert done == ["curves onto edges", "transitions", "map system"]
    fractions = [f for _, f, _ in seen]
    assert fractions == sorted(fractions)
    assert fractions[-1] == pytest.approx(sum(STAGE_WEIGHTS[s] for s in done))
