"""Smaller cells near chosen patches and curves (hexmesh/sizing.py,
``HexOptions.finer_near``): the settings checked before any hex work, the
cells near a chosen patch thinner as asked, the rest of the mesh as before,
and the command line's flags."""

import numpy as np
import pytest

from solver import FinerNear, HexOptions, OptionsError, hexmesh
from solver.__main__ import main as cli_main
from solver.hexmesh.patches import surface_patches
from solver.hexmesh.quality import HEX_EDGES, det3, polyline_distance


# ------------------------------------------------------------------ the settings
def test_words_are_read_into_patches_and_curves():
    f = FinerNear.parse("patch 3, Patch:5 ,curve 2, curve 'radial 0', curve \"hole 1\"", ratio=0.4, reach=2)
    assert f.patches == (3, 5) and f.curves == (2, "radial 0", "hole 1")
    assert (f.ratio, f.reach) == (0.4, 2.0)
    assert HexOptions(finer_near="patch 3").finer_near == FinerNear(patches=(3,))
    assert "patch 3, curve 2" in FinerNear((3,), (2,)).describe()


@pytest.mark.parametrize("words, match", [
    ("hole", "cannot read 'hole'"),
    ("patch x", "cannot read"),
    ("patch 'top'", "cannot read"),  # patches go by number
    ("", "names no patch and no curve"),
    ("patch 0", r"finer_near.patches = 0: must be a whole number >= 1"),
])
def test_words_it_cannot_read_are_refused(words, match):
    with pytest.raises(OptionsError, match=match):
        FinerNear.parse(words)


@pytest.mark.parametrize("kw, match", [
    (dict(ratio=1.5), "larger there"),
    (dict(ratio=0.0), "finer_near.ratio = 0"),
    (dict(ratio=0.01), "at least 0.05"),
    (dict(reach=-1.0), "finer_near.reach = -1"),
    (dict(patches=(1.5,)), "finer_near.patches = 1.5"),
    (dict(patches="3"), "finer_near.patches = '3'"),
])
def test_values_out_of_range_are_refused(kw, match):
    kw = {"patches": (1,), **kw}
    with pytest.raises(OptionsError, match=match):
        FinerNear(**kw)


def test_hex_options_take_a_finer_near_or_words_only():
    with pytest.raises(OptionsError, match="finer_near = 3: must be a FinerNear"):
        HexOptions(finer_near=3)


# ------------------------------------------------------------------ on a field
@pytest.fixture(scope="module")
def plate(solved):
    """The plate's field, its hole's patch id and its mesh at one cell
    size, as a hex run without a size field makes it."""
    r = solved("plate")
    f = r.field
    tp = surface_patches(f.surface, f.sharp)
    radius = [np.linalg.norm(f.surface.V[f.surface.F[tp == p]].mean(axis=1)[:, :2], axis=1).mean()
              for p in range(1, tp.max() + 1)]
    hole = 1 + int(np.argmin(radius))
    plain = hexmesh(f)
    return f, hole, plain


def _thickness(hm, patch: int) -> float:
    """The median thickness of the cells on a boundary patch (their volume
    over their boundary quad's area), over the cell size."""
    pq = hm.patches
    sel = pq.patch == patch
    Q = hm.vertices[pq.quads[sel]]
    area = 0.5 * np.linalg.norm(np.cross(Q[:, 2] - Q[:, 0], Q[:, 3] - Q[:, 1]), axis=1)
    P = hm.vertices[hm.hexes[pq.cells[sel]]]
    vol = np.abs(det3(np.stack([P[:, 1] - P[:, 0], P[:, 3] - P[:, 0], P[:, 4] - P[:, 0]], axis=1)))
    return float(np.median(vol / area)) / hm.report.cell_size


def test_cells_on_a_chosen_patch_are_thinner_and_the_rest_as_before(plate):
    """Half the cell size asked for at the hole's wall: the layers of cells
    around the hole thin to 0.5-0.8 of the cell size (measured 0.56-0.76
    over fTetWild's meshes; 1.0-1.23 without), the solid's other sides keep
    theirs (0.94-1.05), with the same
    singular structure and cells as good.  Sizes across the wall cannot
    follow (a grid line around the hole has as many cells as the ring it
    closes), so the cells there are thin, not small: sizing.py."""
    f, hole, plain = plate
    hm = hexmesh(f, finer_near=f"patch {hole}")
    rep = hm.report
    assert rep.valid and rep.structure_exact and rep.inverted == 0, rep.summary()
    assert rep.sj_min >= 0.5 and rep.sj_mean >= 0.95, rep.summary()
    assert rep.cell_size == plain.report.cell_size  # the cell size is the one away from the patch
    assert rep.hexes > plain.report.hexes
    assert f"finer near patch {hole}" in rep.summary()
    assert _thickness(plain, hole) >= 0.9
    assert 0.5 <= _thickness(hm, hole) <= 0.8, _thickness(hm, hole)
    sides = [p for p in np.unique(hm.patches.patch) if p != hole]
    for p in sides:
        assert 0.8 <= _thickness(hm, p) <= 1.25, (p, _thickness(hm, p))


def test_cells_near_a_chosen_curve_are_smaller(plate):
    """Near one of the plate's four curves (by name) the cells are smaller
    across the curve than at the same curve without a size field (measured
    0.75x), and smaller than at the other three (by 1.32-1.34x); the irregular edges stay
    the curves.  (Along the curve, through the plate's thickness, the
    layers are the whole plate's.)"""
    f, _, plain = plate
    name = f.network.curves[0].name
    hm = hexmesh(f, finer_near=f"curve '{name}'")
    assert hm.report.valid and hm.report.structure_exact, hm.report.summary()

    def near(m, i):
        """The mean length of the cell edges across the plate (in its
        plane) of the 24 cells nearest curve i (it has five around it per
        layer)."""
        E = m.vertices[m.hexes[:, HEX_EDGES]]  # (cells, 12, 2, 3)
        d = E[:, :, 1] - E[:, :, 0]
        L = np.linalg.norm(d, axis=2)
        across = np.abs(d[:, :, 2]) < 0.5 * L
        size = (L * across).sum(axis=1) / np.maximum(across.sum(axis=1), 1)
        C = m.vertices[m.hexes].mean(axis=1)
        dist = polyline_distance(f.network.curves[i].points, C)
        return float(size[np.argsort(dist)[:24]].mean())

    assert near(hm, 0) <= 0.9 * near(plain, 0), (near(hm, 0), near(plain, 0))
    assert all(near(hm, 0) < 0.9 * near(hm, i) for i in (1, 2, 3))


def test_patches_and_curves_the_field_lacks_are_refused_before_any_hex_work(plate):
    f, _, _ = plate
    said = []
    with pytest.raises(OptionsError, match=r"has 7 patches .* not patch 9"):
        hexmesh(f, finer_near="patch 9", progress=lambda *a: said.append(a))
    with pytest.raises(OptionsError, match=r"no curve named 'nope'; it has 4 curves named 'hole 0'"):
        hexmesh(f, finer_near="curve 'nope'", progress=lambda *a: said.append(a))
    with pytest.raises(OptionsError, match=r"no curve 4 \(curves are numbered from 0 as given\)"):
        FinerNear(curves=(4,)).check(f)
    assert not said  # no stage began


def test_the_command_line_refuses_a_missing_curve_before_the_solve(tmp_path, capsys):
    out = tmp_path / "p.npz"
    rc = cli_main(["--example", "plate", "--hex", str(tmp_path / "p.vtu"), "--finer-near", "curve 7", "-q",
                   "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 1 and "no curve 7" in err and not out.exists(), err
    rc = cli_main(["--example", "plate", "--hex", str(tmp_path / "p.vtu"), "--finer-ratio", "0.3", "-q"])
    assert rc == 1 and "--finer-ratio and --finer-reach go with --finer-near" in capsys.readouterr().err
    rc = cli_main(["--example", "plate", "--finer-near", "patch 1", "-q"])
    assert rc == 1 and "go with --hex" in capsys.readouterr().err
    rc = cli_main(["--example", "plate", "--hex", str(tmp_path / "p.vtu"), "--finer-near", "patch 1",
                   "--finer-ratio", "2", "-q"])
    assert rc == 1 and "larger there" in capsys.readouterr().err


def test_a_mesh_with_nothing_to_smooth_takes_a_size_field_quietly(solved):
    """The L-prism's cells are all good (nothing for smoothing to move); with
    a size field the optimisation over no cell warned 'Mean of empty slice'."""
    import warnings

    f = solved("l_prism").field
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        hm = hexmesh(f, finer_near="patch 1")
    assert hm.report.valid and hm.report.sj_min >= 0.9, hm.report.summary()
