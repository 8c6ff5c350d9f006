"""File formats: a surface as OBJ, a network as JSON, a result as NPZ.

Network JSON (all keys but ``curves`` optional)::

    {
      "surface": "part.obj",            # path relative to the JSON file
      "sharp_angle": 30,                # dihedral threshold in degrees
      "sharp_edges": [[0, 1], [1, 5]],  # surface vertex pairs marked sharp
      "node_tolerance": 0.001,
      "boundary_tolerance": 0.01,
      "corner_turns": [{"vertex": 12, "turns": 0},        # fix sharp corners' turns in
                       {"position": [1, 0, 0], "turns": 1}], # quarter turns (corners.py)
      "curves": [
        {"name": "axis", "points": [[0, 0, -1], [0, 0, 1]],
         "sigma": 0.25, "role": "singular", "torsion": "free", "closed": false}
      ],
      "options": {"edge_length": 0.1, "penalty": 1000}   # any solver Options field
    }

``sigma`` is in turns (a multiple of 1/4; see the sign convention in
solver/network/network.py); ``role`` is ``singular``, ``feature`` or ``sharp``;
``torsion`` is ``free`` (Eq. 21) or ``fixed`` (Eq. 22).

Result NPZ: the solved field in its one layout, ``SolvedField.to_arrays()``
(solver/field/solved.py lists the arrays: ``vertices`` (#V,3), ``tets``
(#T,4), ``frames`` (#V,3,3; columns are the cross axes), ``omega`` (#E,3 on
``TetMesh(vertices, tets).edges``), ``root``, per prepared curve the crossed
tets and pierced faces as flat arrays with offsets (``curve_tets`` /
``curve_tets_offsets``, ``curve_faces`` / ``curve_faces_offsets``), the
network, the input surface and what else the stages after the solve need),
and ``report`` (a JSON string: ``Report.to_dict()`` with the solve's
``options`` added; ``Report.from_dict`` reads it back).  ``io.load_field``
reads the field back, checked.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, fields
from io import BytesIO

import numpy as np

from .. import checks
from ..errors import NetworkError, OptionsError, SurfaceError
from ..network.network import Curve, Network
from ..surface.polygons import triangulate_polygons
from ..surface.validation import MAX_COORDINATE
from .atomic import write_files, write_text
from .text import read_text


def read_obj(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OBJ file.

    Polygons are triangulated by ear clipping in their plane (polygons.py).
    Face indices are OBJ's: 1-based, negative counts back from the last
    vertex read so far; any other index (0, or beyond the vertices) is
    refused with the file, the line and the valid range.

    Parameters
    ----------
    path : str

    Returns
    -------
    V : (n, 3) float array
    F : (m, 3) int array
        0-based triangles.

    Raises
    ------
    SurfaceError
        An unreadable file, a bad line, an index out of range or a
        degenerate polygon, with the file and line.
    """
    V, polys, lines = [], [], []
    # UTF-8, or UTF-16/32 as some Windows tools save it (text.py)
    text = read_text(path, SurfaceError, "surface file")
    for k, line in enumerate(text.splitlines(), 1):
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            try:
                xyz = [float(x) for x in parts[1:4]]
            except ValueError:
                xyz = []
            if len(xyz) != 3 or not all(np.isfinite(xyz)):
                raise SurfaceError(f"{path}:{k}: bad vertex line {line.strip()[:80]!r}; a vertex is 'v x y z' "
                                   "with three finite numbers")
            if max(map(abs, xyz)) > MAX_COORDINATE:
                raise SurfaceError(f"{path}:{k}: vertex {len(V) + 1} at {xyz} is beyond +-{MAX_COORDINATE:g}; a "
                                   "stray vertex (delete it) or a model in the wrong units (scale it)")
            V.append(xyz)
        elif parts[0] == "f":
            try:
                idx = [int(p.split("/")[0]) for p in parts[1:]]
            except ValueError:
                raise SurfaceError(f"{path}:{k}: bad face line {line.strip()[:80]!r}; a face is 'f i j k ...' "
                                   "with 1-based vertex indices") from None
            if len(idx) < 3:
                raise SurfaceError(f"{path}:{k}: a face needs at least 3 vertices, got {len(idx)}")
            for i in idx:
                # 0 is no OBJ index; negative ones count back from the vertices read so far
                if i == 0 or i < -len(V):
                    raise SurfaceError(_obj_index_message(path, k, i, len(V), relative=i < 0))
            polys.append([i - 1 if i > 0 else len(V) + i for i in idx])
            lines.append(k)
    if not V or not polys:
        raise SurfaceError(f"{path}: no vertices or faces found; is it a triangle/polygon OBJ?")
    for p, k in zip(polys, lines):  # positive indices may refer to vertices listed later
        if max(p) >= len(V):
            raise SurfaceError(_obj_index_message(path, k, max(p) + 1, len(V), relative=False))
    V = np.asarray(V, float)
    F, src, failed = triangulate_polygons(V, polys)
    if failed:
        k = lines[failed[0]]
        raise SurfaceError(f"{path}:{k}: polygon with {len(polys[failed[0]])} vertices has zero area (all its "
                           f"vertices on one line) or crosses itself; {len(failed)} such polygon(s). Dissolve or "
                           "fix it (Blender: Mesh > Clean Up > Degenerate Dissolve)")
    return V, F


def _obj_index_message(path, line, index, n, relative):
    where = "counting back from the last vertex" if relative else "1-based"
    rng = f"1..{n} or -1..-{n}" if n else "none yet: no vertex is listed before this face"
    return (f"{path}:{line}: face refers to vertex {index} ({where}), but the file has {n} vertices"
            f"{' so far' if relative else ''}; OBJ vertex indices run {rng} (0 is not an OBJ index)")


def write_obj(path: str, V: np.ndarray, F: np.ndarray) -> None:
    """Write a triangle surface as OBJ (whole or not at all, atomic.py).

    Parameters
    ----------
    path : str
    V : (n, 3) float array
    F : (m, 3) int array
        0-based (written 1-based).

    Raises
    ------
    SurfaceError
        V not (n, 3) finite numbers, F not (m, 3) vertex indices of V
    OutputError
        a path that cannot be written
    """
    V = checks.array("write_obj: V", V, SurfaceError, shape=(None, 3))
    F = checks.array("write_obj: F", F, SurfaceError, shape=(None, 3), kind="i")
    if len(F) and (F.min() < 0 or F.max() >= len(V)):
        raise SurfaceError(f"write_obj: F holds vertex index {int(F.min() if F.min() < 0 else F.max())}, outside "
                           f"0..{len(V) - 1}")
    write_text(path, "".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
               + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F))


_NETWORK_KEYS = {"surface", "sharp_angle", "sharp_edges", "node_tolerance", "boundary_tolerance", "curves",
                 "options", "corner_turns"}
_CURVE_KEYS = {"name", "points", "sigma", "role", "torsion", "closed"}


def network_from_dict(d: dict) -> tuple[Network, dict]:
    """A network and its solver options from the JSON structure above.

    Types are checked here and in Curve/Network (checks.py); every message
    names the key and the curve.

    Parameters
    ----------
    d : dict
        The parsed JSON (``{"curves": [...], "sharp_angle": ..., ...}``).

    Returns
    -------
    network : Network
    options : dict
        The file's ``"options"`` (``options_from_dict`` makes them Options).

    Raises
    ------
    NetworkError
        An unknown key, a value of the wrong type or out of range.
    """
    E = NetworkError
    if not isinstance(d, dict):
        raise E(f"the network file must hold a JSON object with a 'curves' list, got {checks.describe(d)}")
    unknown = set(d) - _NETWORK_KEYS
    if unknown:
        raise E(f"unknown key(s) {sorted(unknown)} in the network file; allowed: {sorted(_NETWORK_KEYS)}")
    curves = []
    for k, c in enumerate(checks.sequence("curves", d.get("curves", []), E)):
        if not isinstance(c, dict) or "points" not in c:
            raise E(f"curve {k}: must be an object with at least 'points', got {checks.describe(c)}")
        bad = set(c) - _CURVE_KEYS
        if bad:
            raise E(f"curve {k}: unknown key(s) {sorted(bad)}; allowed: {sorted(_CURVE_KEYS)}")
        name = c.get("name", f"curve{k}")
        name = name if isinstance(name, str) else checks.text(f"curve {k}: name", name, E)
        try:
            curves.append(Curve(points=c["points"], sigma=c.get("sigma", 0.25), role=c.get("role", "singular"),
                                torsion=c.get("torsion", "free"), name=name, closed=c.get("closed", False)))
        except NetworkError as e:
            # Curve names itself by name only; add its place in the file
            msg = str(e)
            label = f"curve '{name}'"
            raise E(f"curve {k} '{name}'{msg[len(label):]}" if msg.startswith(label) else f"curve {k}: {msg}") \
                from None
    net = Network(curves=curves, sharp_edges=d.get("sharp_edges"), sharp_angle=d.get("sharp_angle"),
                  node_tolerance=d.get("node_tolerance"), boundary_tolerance=d.get("boundary_tolerance"),
                  corner_turns=_corner_turns(d.get("corner_turns")))
    return net, dict(checks.mapping("options", d.get("options", {}), OptionsError))


def _corner_turns(items) -> dict | None:
    """{vertex or (x, y, z): turns} from [{"vertex": i | "position": [x, y, z], "turns": q}, ...]."""
    if items is None:
        return None
    out = {}
    for k, it in enumerate(items if isinstance(items, list) else [items]):
        if not isinstance(it, dict) or "turns" not in it or ("vertex" in it) == ("position" in it):
            raise NetworkError(f"corner_turns[{k}]: must be an object with 'turns' and either 'vertex' or 'position'")
        if "vertex" in it:
            key = checks.integer(f"corner_turns[{k}].vertex", it["vertex"], NetworkError, low=0)
        else:
            key = tuple(checks.points3(f"corner_turns[{k}].position", [it["position"]], NetworkError,
                                       min_points=1)[0].tolist())
        out[key] = it["turns"]
    return out


def network_to_dict(net: Network, options: dict | None = None) -> dict:
    """The JSON structure of a network (the inverse of ``network_from_dict``).

    Parameters
    ----------
    net : Network
    options : dict, optional
        Solver options stored beside the curves.

    Returns
    -------
    dict
        Plain lists and numbers, ready for ``json.dump``.

    Raises
    ------
    NetworkError, OptionsError
        net not a Network, options not a dict or None
    """
    checks.instance("network", net, Network, NetworkError, "e.g. Network(curves=[...])")
    if options is not None:
        checks.mapping("options", options, OptionsError)
    d: dict = {"curves": [{"name": c.name, "points": np.asarray(c.points).tolist(), "sigma": c.sigma,
                           "role": c.role.value, "torsion": c.torsion.value, "closed": bool(c.closed)}
                          for c in net.curves]}
    if net.sharp_angle is not None:
        d["sharp_angle"] = net.sharp_angle
    if net.sharp_edges is not None:
        d["sharp_edges"] = np.asarray(net.sharp_edges).tolist()
    for key in ("node_tolerance", "boundary_tolerance"):
        if getattr(net, key) is not None:
            d[key] = getattr(net, key)
    if net.corner_turns:
        d["corner_turns"] = [{"vertex": int(k)} | {"turns": int(q)} if np.ndim(k) == 0 else
                             {"position": [float(x) for x in k], "turns": int(q)} for k, q in net.corner_turns.items()]
    if options:
        d["options"] = options
    return d


def read_network(path: str) -> tuple[Network, dict, str | None]:
    """A network file (JSON, the format above).

    Parameters
    ----------
    path : str

    Returns
    -------
    network : Network
    options : dict
        The file's solver options.
    surface : str or None
        The surface OBJ the file names, as a path relative to the file's
        folder made absolute.

    Raises
    ------
    NetworkError
        An unreadable file, invalid JSON, or what ``network_from_dict``
        refuses.
    """
    text = read_text(path, NetworkError, "network file", "JSON text")
    try:
        d = json.loads(text)
    except RecursionError:
        raise NetworkError(f"{path}: the JSON is nested too deeply to be a network file (lists within lists "
                           "thousands deep); see docs/usage.md for its layout") from None
    except json.JSONDecodeError as e:
        raise NetworkError(f"{path}: not valid JSON ({e.msg} at line {e.lineno}, column {e.colno})") from None
    except (UnicodeDecodeError, ValueError) as e:
        raise NetworkError(f"{path}: not a JSON text file ({e.__class__.__name__}: {str(e)[:80]}); the network "
                           "file is JSON (see solver/io.py), the surface an OBJ") from None
    net, opts = network_from_dict(d)
    surface = d.get("surface")
    if surface is not None:
        surface = checks.text("surface", surface, NetworkError)
        surface = os.path.join(os.path.dirname(os.path.abspath(path)), surface)
    return net, opts, surface


def write_network(path: str, net: Network, surface: str | None = None, options: dict | None = None) -> None:
    """Write a network file (JSON).

    Parameters
    ----------
    path : str
    net : Network
    surface : str, optional
        The surface OBJ to name in the file (relative to its folder).
    options : dict, optional
        Solver options to store beside the curves.
    """
    d = network_to_dict(net, options)
    if surface is not None:
        surface = checks.text("surface", surface, NetworkError)
        d = {"surface": surface, **d}
    write_text(path, json.dumps(d, indent=1))


def options_from_dict(d: dict):
    """Solver options from a dict (a network file's ``"options"``).

    Parameters
    ----------
    d : dict
        Fields of ``solver.Options``.

    Returns
    -------
    Options

    Raises
    ------
    OptionsError
        An unknown key or a value of the wrong type or out of range.
    """
    from ..pipeline import Options

    d = checks.mapping("options", d, OptionsError)
    allowed = {f.name for f in fields(Options)}
    bad = set(d) - allowed
    if bad:
        raise OptionsError(f"unknown solver option(s) {sorted(bad)}; allowed: {sorted(allowed)}")
    return Options(**d)


def save_result(path: str, result) -> None:
    """Write a solved field to an ``.npz`` file (its one layout, module
    docs) with the solve's report, at exactly ``path`` (numpy would add
    '.npz' to a name without it) and whole or not at all (atomic.py).

    Parameters
    ----------
    path : str
    result : Result

    Raises
    ------
    OptionsError
        result not a solver Result
    OutputError
        a path that cannot be written
    """
    from ..pipeline import Result

    checks.instance("save_result: result", result, Result, OptionsError, "the Result of solve(...)")
    report = result.report.to_dict()
    report["options"] = asdict(result.options)
    save_field(path, result.field, report)


def save_field(path: str, field, report: dict | None = None) -> None:
    """Write a solved field to an ``.npz`` file in its one layout, exactly
    at ``path`` and whole or not at all (atomic.py); ``io.load_field``
    reads it back.

    Parameters
    ----------
    path : str
    field : SolvedField
        a Result's ``.field``, or one read back
    report : dict, optional
        ``Report.to_dict()`` of its solve, stored as ``report``

    Raises
    ------
    OptionsError
        field not a SolvedField, report not a dict
    OutputError
        a path that cannot be written
    """
    from ..field.solved import SolvedField

    checks.instance("save_field: field", field, SolvedField, OptionsError, "a SolvedField (Result.field)")
    arrays = field.to_arrays()
    if report is not None:
        checks.instance("save_field: report", report, dict, OptionsError, "Report.to_dict() or None")
        arrays["report"] = np.array(json.dumps(report, default=float))
    # compressed in memory: numpy leaves its zip file open when a write
    # fails, and it would complain again when collected
    buf = BytesIO()
    np.savez_compressed(buf, **arrays)
    write_files({path: buf.getbuffer()})


def load_result(path: str) -> dict:
    """The arrays of a saved result.

    Parameters
    ----------
    path : str
        An ``.npz`` written by ``save_result``.

    Returns
    -------
    dict
        Array name -> array; ``"report"`` parsed back to a dict
        (``solver.Report.from_dict(out["report"])`` makes it a Report).

    Raises
    ------
    ReadError
        a file that is missing, empty, truncated, not an ``.npz`` or damaged,
        or has no report
    """
    import zipfile
    import zlib

    from ..errors import ReadError
    from .stored import open_archive

    open_archive(path).close()  # an empty, truncated or foreign file is refused, naming it
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {k: z[k] for k in z.files}
        out["report"] = json.loads(str(out["report"]))
    except KeyError:
        raise ReadError(f"{path}: the array 'report' is missing: not a SymFrames result") from None
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError) as e:
        raise ReadError(f"{path}: a damaged result file ({type(e).__name__}: {str(e)[:100]})") from None
    return out
