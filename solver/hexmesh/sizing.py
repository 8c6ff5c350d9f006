"""A size field for the hex mesh: smaller cells near chosen boundary patches
or network curves (``FinerNear``), growing back to the cell size away from
them.

The cell size s(x) is ``ratio * cell`` on the chosen patches and curves and
grows linearly with the distance d from them, back to ``cell`` at
``reach`` cells:

    s(x) = cell * (ratio + (1 - ratio) * min(1, d(x) / (reach * cell)))

The seamless map fits each tet's gradient to its frame over s at its
centroid (seamless.py, the frame-fitting energy), smoothing keeps each cell
near s at its centre (smooth.py), and the report measures each cell against
s there (``HexReport.size_within``).  A pure hex mesh has as many cells along
a grid line on one side of the solid as on the other, so only sizes along
the direction away from a patch follow s freely (layers that thin towards
it, as for a boundary layer); sizes across it are a least-squares
compromise between the fine layers and the coarse ones.

Patches are numbered as the hex mesh's (``patches.surface_patches``: the
regions of the input surface between sharp edges, from 1); curves by their
index in the network as given, or by name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from .. import checks
from ..errors import OptionsError
from ..surface.trisurface import TriSurface
from .patches import surface_patches
from .quality import polyline_distance

FINER_RATIO = 0.5
"""The default cell size near the chosen patches and curves, as a fraction
of the cell size."""
FINER_REACH = 4.0
"""The default distance, in cells, over which the size grows back."""


@dataclass(frozen=True)
class FinerNear:
    """Smaller cells near chosen boundary patches and network curves (module
    docs); checked when made (``OptionsError`` names the setting and the fix).

    Parameters
    ----------
    patches : tuple of int
        patch ids of the input surface (1-based, as the hex mesh's patches:
        ``hm.patches``, the ``patch`` attribute in Blender)
    curves : tuple of int or str
        curves of the network as given: their index (0-based) or name
    ratio : float
        the cell size on them, as a fraction of the cell size (0 < ratio <= 1)
    reach : float
        the distance, in cells, over which the size grows back (> 0)
    """

    patches: tuple = ()
    curves: tuple = ()
    ratio: float = FINER_RATIO
    reach: float = FINER_REACH

    def __post_init__(self):
        E = OptionsError
        for name in ("patches", "curves"):
            value = getattr(self, name)
            if isinstance(value, (str, int, np.integer)):
                value = (value,)
            if not isinstance(value, (tuple, list)):
                raise E(f"finer_near.{name} = {checks.describe(value)}: give a tuple of "
                        + ("patch ids (1, 2, ...)" if name == "patches" else "curve indices or names"))
            object.__setattr__(self, name, tuple(value))
        for p in self.patches:
            checks.integer("finer_near.patches", p, E, low=1, fix="a patch id, 1-based, as the hex mesh's patches")
        for c in self.curves:
            if not isinstance(c, str):
                checks.integer("finer_near.curves", c, E, low=0, fix="a curve's index (0-based) or its name")
        if not self.patches and not self.curves:
            raise E("finer_near names no patch and no curve: give patches=(...) or curves=(...)")
        ratio = checks.positive_float("finer_near.ratio", self.ratio, E,
                                      fix="the cell size near them as a fraction of the cell size, in (0, 1]")
        if ratio > 1.0:
            raise E(f"finer_near.ratio = {ratio:g} would make the cells larger there; give a fraction in (0, 1]")
        if ratio < 0.05:
            raise E(f"finer_near.ratio = {ratio:g} asks for cells 20 times smaller and more; give at least 0.05, "
                    "or a smaller cell size")
        reach = checks.positive_float("finer_near.reach", self.reach, E,
                                      fix="the distance in cells over which the size grows back, e.g. 4")
        object.__setattr__(self, "ratio", ratio)
        object.__setattr__(self, "reach", reach)
        object.__setattr__(self, "patches", tuple(int(p) for p in self.patches))
        object.__setattr__(self, "curves", tuple(c if isinstance(c, str) else int(c) for c in self.curves))

    @classmethod
    def parse(cls, text: str, ratio: float = FINER_RATIO, reach: float = FINER_REACH) -> FinerNear:
        """From words such as ``"patch 3, patch 5, curve 2, curve 'radial 0'"``
        (the command line's --finer-near, the add-on's field).

        Raises
        ------
        OptionsError
            an item that is not ``patch N`` or ``curve N`` / ``curve 'name'``
        """
        if not isinstance(text, str):
            raise OptionsError(f"finer_near = {checks.describe(text)}: give words such as 'patch 3, curve 2'")
        patches, curves = [], []
        for item in filter(None, (s.strip() for s in text.split(","))):
            m = re.fullmatch(r"(patch|curve)[\s:]*(?:(\d+)|'([^']*)'|\"([^\"]*)\")", item, flags=re.IGNORECASE)
            if m is None or (m.group(1).lower() == "patch" and m.group(2) is None):
                raise OptionsError(f"finer_near: cannot read {item!r}; write items such as 'patch 3', 'curve 2' or "
                                   "\"curve 'radial 0'\", separated by commas")
            kind, number, name = m.group(1).lower(), m.group(2), m.group(3) or m.group(4)
            (patches if kind == "patch" else curves).append(int(number) if number is not None else name)
        return cls(tuple(patches), tuple(curves), ratio, reach)

    @staticmethod
    def patches_at(field, points) -> list:
        """The patch ids (sorted, each once) of the surface triangles nearest
        ``points`` (k, 3) on a solved field's surface: the patches a user
        picked by pointing at them (the add-on's Finer Near from selected
        faces)."""
        P = checks.points3("points", points, OptionsError, min_points=1)
        tri_patch = surface_patches(field.surface, field.sharp)
        _, f, _ = field.surface.closest_points(P)
        return sorted({int(p) for p in tri_patch[f]})

    def check(self, field) -> None:
        """Refuse patches and curves that a solved field does not have
        (``OptionsError``, said with what it has), before any hex work."""
        size_field(field, self)

    def describe(self) -> str:
        """In words, for the report."""
        items = [f"patch {p}" for p in self.patches] + [
            f"curve {c}" if not isinstance(c, str) else f"curve '{c}'" for c in self.curves]
        return f"{', '.join(items)} (cells {self.ratio:g} of the cell size there, back to it over {self.reach:g} cells)"


class SizeField:
    """The relative cell size s(x) / cell of a run (module docs): 1 where no
    FinerNear applies."""

    def __init__(self, finer: FinerNear | None = None, targets=()):
        self.finer = finer
        self.targets = list(targets)  # callables: points (n, 3) -> distances (n,)

    @property
    def uniform(self) -> bool:
        return self.finer is None

    def relative(self, X: np.ndarray, cell: float) -> np.ndarray | None:
        """(n,) s / cell at the points X, or None for a uniform size."""
        if self.uniform:
            return None
        X = np.asarray(X, float).reshape(-1, 3)
        d = np.min([t(X) for t in self.targets], axis=0)
        r = self.finer.ratio
        return r + (1.0 - r) * np.clip(d / (self.finer.reach * cell), 0.0, 1.0)

    def cells(self, mesh, cell: float) -> float:
        """About how many cells of this field fill the tet mesh."""
        rel = self.relative(mesh.vertices[mesh.tets].mean(axis=1), cell)
        vol = mesh.tet_volumes
        return float(np.sum(vol if rel is None else vol / rel**3)) / cell**3


def size_field(inp, finer: FinerNear | None) -> SizeField:
    """The size field of ``finer`` on a solved field (its surface, sharp
    edges and network).

    Raises
    ------
    OptionsError
        a patch id the surface does not have, a curve the network does not
        have (said with what there is)
    """
    if finer is None:
        return SizeField()
    S = inp.surface
    targets = []
    if finer.patches:
        tri_patch = surface_patches(S, inp.sharp)
        n = int(tri_patch.max())
        bad = [p for p in finer.patches if p > n]
        if bad:
            raise OptionsError(f"finer_near: the surface has {n} patch{'es' if n > 1 else ''} (regions between sharp "
                               f"edges, numbered 1 to {n} as the hex mesh's patches), not patch "
                               f"{', '.join(map(str, bad))}; mesh once and look at the hex mesh's patches (the "
                               "'patch' attribute in Blender, the physical groups of a .msh)")
        part = TriSurface(S.V, S.F[np.isin(tri_patch, finer.patches)])
        targets.append(lambda X, part=part: part.closest_points(X)[0])
    net = inp.network
    for i in chosen_curves(finer, net.curves, net.source):
        P = net.curves[i].points
        targets.append(lambda X, P=P: polyline_distance(P, X))
    return SizeField(finer, targets)


def chosen_curves(finer: FinerNear, curves, source=None) -> list:
    """The indices into ``curves`` (a network's, ``source[i]`` the index
    as given of curve i) of the curves ``finer`` names.

    Raises
    ------
    OptionsError
        a name or index the network does not have (said with what it has)
    """
    source = list(range(len(curves)) if source is None else source)
    out = []
    for c in finer.curves:
        if isinstance(c, str):
            found = [i for i, cv in enumerate(curves) if cv.name == c]
            what = f"no curve named {c!r}"
        else:
            found = [i for i, s in enumerate(source) if s == c]
            what = f"no curve {c} (curves are numbered from 0 as given)"
        if not found:
            names = list(dict.fromkeys(cv.name for cv in curves if cv.name))
            raise OptionsError(f"finer_near: the network has {what}; it has {len(set(source))} curves"
                               + (f" named {', '.join(repr(n) for n in names[:8])}{', ...' if len(names) > 8 else ''}"
                                  if names else ""))
        out += found
    return out
