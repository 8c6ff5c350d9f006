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
solver/network.py); ``role`` is ``singular``, ``feature`` or ``sharp``;
``torsion`` is ``free`` (Eq. 21) or ``fixed`` (Eq. 22).

Result NPZ: ``vertices`` (#V,3), ``tets`` (#T,4), ``edges`` (#E,2),
``omega`` (#E,3), ``frames`` (#V,3,3; columns are the cross axes),
``quaternions`` (#V,4; w,x,y,z), ``root``, per prepared curve the pierced faces
and crossed tets as flat arrays with offsets (``curve_faces`` /
``curve_faces_offsets``, ``curve_tets`` / ``curve_tets_offsets``),
``faces`` (#faces,3) and ``report`` (a JSON string).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, fields

import numpy as np

from .errors import NetworkError, SurfaceError
from .network import Curve, Network


def read_obj(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OBJ file; polygons are fanned."""
    V, F = [], []
    try:
        fh = open(path, encoding="utf-8", errors="replace")
    except OSError as e:
        raise SurfaceError(f"cannot read surface file {path!r}: {e.strerror}") from None
    with fh:
        for k, line in enumerate(fh, 1):
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                try:
                    V.append([float(x) for x in parts[1:4]])
                except ValueError:
                    raise SurfaceError(f"{path}:{k}: bad vertex line {line.strip()!r}") from None
            elif parts[0] == "f":
                try:
                    idx = [int(p.split("/")[0]) for p in parts[1:]]
                except ValueError:
                    raise SurfaceError(f"{path}:{k}: bad face line {line.strip()!r}") from None
                idx = [i - 1 if i > 0 else len(V) + i for i in idx]
                if len(idx) < 3:
                    raise SurfaceError(f"{path}:{k}: a face needs at least 3 vertices")
                F.extend([idx[0], idx[j], idx[j + 1]] for j in range(1, len(idx) - 1))
    if not V or not F:
        raise SurfaceError(f"{path}: no vertices or faces found; is it a triangle/polygon OBJ?")
    return np.asarray(V, float), np.asarray(F, np.int64)


def write_obj(path: str, V: np.ndarray, F: np.ndarray) -> None:
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V))
        fh.write("".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F))


_NETWORK_KEYS = {"surface", "sharp_angle", "sharp_edges", "node_tolerance", "boundary_tolerance", "curves",
                 "options", "corner_turns"}
_CURVE_KEYS = {"name", "points", "sigma", "role", "torsion", "closed"}


def network_from_dict(d: dict) -> tuple[Network, dict]:
    """(Network, options dict) from the JSON structure above."""
    if not isinstance(d, dict):
        raise NetworkError("the network file must hold a JSON object with a 'curves' list")
    unknown = set(d) - _NETWORK_KEYS
    if unknown:
        raise NetworkError(f"unknown key(s) {sorted(unknown)} in the network file; allowed: {sorted(_NETWORK_KEYS)}")
    curves = []
    for k, c in enumerate(d.get("curves", [])):
        if not isinstance(c, dict) or "points" not in c:
            raise NetworkError(f"curve {k}: must be an object with at least 'points'")
        bad = set(c) - _CURVE_KEYS
        if bad:
            raise NetworkError(f"curve {k}: unknown key(s) {sorted(bad)}; allowed: {sorted(_CURVE_KEYS)}")
        try:
            curves.append(Curve(points=np.asarray(c["points"], float), sigma=c.get("sigma", 0.25),
                                role=c.get("role", "singular"), torsion=c.get("torsion", "free"),
                                name=str(c.get("name", f"curve{k}")), closed=bool(c.get("closed", False))))
        except (TypeError, ValueError) as e:
            raise NetworkError(f"curve {k} ({c.get('name', '')}): {e}") from None
    sharp_edges = d.get("sharp_edges")
    net = Network(curves=curves,
                  sharp_edges=None if sharp_edges is None else np.asarray(sharp_edges, np.int64).reshape(-1, 2),
                  sharp_angle=d.get("sharp_angle"), node_tolerance=d.get("node_tolerance"),
                  boundary_tolerance=d.get("boundary_tolerance"),
                  corner_turns=_corner_turns(d.get("corner_turns")))
    return net, dict(d.get("options", {}))


def _corner_turns(items) -> dict | None:
    """{vertex or (x, y, z): turns} from [{"vertex": i | "position": [x, y, z], "turns": q}, ...]."""
    if items is None:
        return None
    out = {}
    for k, it in enumerate(items if isinstance(items, list) else [items]):
        if not isinstance(it, dict) or "turns" not in it or ("vertex" in it) == ("position" in it):
            raise NetworkError(f"corner_turns[{k}]: must be an object with 'turns' and either 'vertex' or 'position'")
        key = int(it["vertex"]) if "vertex" in it else tuple(float(x) for x in it["position"])
        out[key] = it["turns"]
    return out


def network_to_dict(net: Network, options: dict | None = None) -> dict:
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
    """(Network, options dict, surface path or None) from a JSON file."""
    try:
        with open(path, encoding="utf-8") as fh:
            d = json.load(fh)
    except OSError as e:
        raise NetworkError(f"cannot read network file {path!r}: {e.strerror}") from None
    except json.JSONDecodeError as e:
        raise NetworkError(f"{path}: not valid JSON ({e.msg} at line {e.lineno}, column {e.colno})") from None
    net, opts = network_from_dict(d)
    surface = d.get("surface")
    if surface is not None:
        surface = os.path.join(os.path.dirname(os.path.abspath(path)), surface)
    return net, opts, surface


def write_network(path: str, net: Network, surface: str | None = None, options: dict | None = None) -> None:
    d = network_to_dict(net, options)
    if surface is not None:
        d = {"surface": surface, **d}
    with open(path, "w", encoding="utf-8") as fh:
        json.dump(d, fh, indent=1)


def options_from_dict(d: dict):
    from .pipeline import Options

    allowed = {f.name for f in fields(Options)}
    bad = set(d) - allowed
    if bad:
        raise ValueError(f"unknown solver option(s) {sorted(bad)}; allowed: {sorted(allowed)}")
    return Options(**d)


def _flat(parts: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    offsets = np.cumsum([0] + [len(p) for p in parts]).astype(np.int64)
    flat = np.concatenate(parts).astype(np.int64) if parts else np.zeros(0, np.int64)
    return flat, offsets


def save_result(path: str, result) -> None:
    """Write a Result to an .npz file (see the module docstring)."""
    mesh = result.mesh
    n = len(result.embedding.traces)
    cf, cfo = _flat([result.curve_faces(i) for i in range(n)])
    ct, cto = _flat([result.curve_tets(i) for i in range(n)])
    report = result.report.as_dict()
    report["options"] = asdict(result.problem.options)
    np.savez_compressed(
        path, vertices=mesh.vertices, tets=mesh.tets, edges=mesh.edges, faces=mesh.faces, omega=result.omega,
        frames=result.frames, quaternions=result.quaternions(), root=np.int64(result.root),
        curve_faces=cf, curve_faces_offsets=cfo, curve_tets=ct, curve_tets_offsets=cto,
        report=np.array(json.dumps(report, default=float)),
    )


def load_result(path: str) -> dict:
    """The arrays of a saved result; ``report`` parsed back to a dict."""
    with np.load(path) as z:
        out = {k: z[k] for k in z.files}
    out["report"] = json.loads(str(out["report"]))
    return out
