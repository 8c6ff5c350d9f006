"""Blender objects -> solver arrays.  Reads only; the inputs are never modified.

The domain is the evaluated mesh (modifiers applied) in world space, its
loop triangles as F; sharp boundary edges come from its boolean edge
attribute ``sharp_edge`` and/or the scene's angle threshold.  The network is
every curve object in the chosen collection (and its children), one solver
``Curve`` per spline, with the object's SymFrames settings.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
from mathutils.geometry import interpolate_bezier

from ..solver import Curve, Network, Options, SymFramesError


class InputError(SymFramesError):
    """The Blender inputs cannot be turned into solver arrays."""


@dataclass
class Inputs:
    """Everything a solve needs, as plain arrays (safe to hand to a thread).

    V : (n, 3) float array, F : (m, 3) int array -- world-space surface
    network : solver Network
    options : solver Options
    ignored : names of objects in the network collection that are not curves
    network_note : where the curves came from, for messages
    """

    V: np.ndarray
    F: np.ndarray
    network: Network
    options: Options
    ignored: list
    network_note: str = ""
    domain_name: str = ""
    curve_shapes: dict = field(default_factory=dict)  # curve name -> fingerprint of its spline as drawn

    def mesh_key(self) -> str:
        """Fingerprint of what the tet mesh depends on (surface, curve
        geometry and roles, node tolerance, edge length or, with Auto, the
        target tet count and the grading); equal keys allow reusing the tet mesh."""
        h = hashlib.sha1()
        for a in (self.V, self.F):
            h.update(np.ascontiguousarray(a).tobytes())
        for c in self.network.curves:
            h.update(c.role.value.encode())
            h.update(np.ascontiguousarray(c.points).tobytes())
        auto = ((self.options.target_tets, self.options.tets_ceiling, self.options.grading)
                if self.options.edge_length is None else None)
        h.update(repr((self.options.edge_length, auto, self.network.node_tolerance)).encode())
        return h.hexdigest()

    def field_key(self) -> str:
        """Fingerprint of what a field's network depends on beyond its tet
        mesh (mesh_key, the curves' indices, the sharp features): equal keys
        mean that tracing these inputs through a stored field finds the
        network it was solved with (Hex Mesh on a reopened file)."""
        h = hashlib.sha1(self.mesh_key().encode())
        h.update(repr([c.sigma for c in self.network.curves]).encode())
        h.update(repr(self.network.sharp_angle).encode())
        if self.network.sharp_edges is not None:
            h.update(np.ascontiguousarray(self.network.sharp_edges, np.int64).tobytes())
        return h.hexdigest()

    def field_parts(self) -> str:
        """What field_key fingerprints, part by part (JSON): the domain's
        surface, the resolution settings, the sharp features and each curve's
        index, role and shape as drawn, so that ``changes`` can say what
        differs."""
        o = self.options
        auto = (o.target_tets, o.tets_ceiling, o.grading) if o.edge_length is None else None
        sharp = hashlib.sha1(repr(self.network.sharp_angle).encode())
        if self.network.sharp_edges is not None:
            sharp.update(np.ascontiguousarray(self.network.sharp_edges, np.int64).tobytes())
        return json.dumps({
            "domain": [self.domain_name, _digest(self.V, self.F)],
            "resolution": repr((o.edge_length, auto, self.network.node_tolerance)),
            "sharp": sharp.hexdigest()[:16],
            "curves": {c.name: [float(c.sigma), c.role.value, self.curve_shapes.get(c.name) or _digest(c.points)]
                       for c in self.network.curves}})


def _digest(*arrays) -> str:
    h = hashlib.sha1()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def _index(sigma: float) -> str:
    """A curve index as the panel speaks of it: +1/4, -1/2, -1, 0."""
    f = Fraction(sigma).limit_denominator(64)
    return "0" if f == 0 else f"{'+' if f > 0 else '-'}{abs(f)}"


def changes(solved_parts: str | None, now: Inputs) -> list[str]:
    """What differs between the inputs a field was solved with (their
    ``field_parts``) and ``now``, in words; [] if nothing that can be named
    (a field stored without its parts)."""
    try:
        was = json.loads(solved_parts) if solved_parts else None
    except ValueError:
        was = None
    if not isinstance(was, dict):
        return []
    cur = json.loads(now.field_parts())
    out = []
    if was.get("domain") != cur["domain"]:
        old_name, new_name = (was.get("domain") or ["", ""])[0], cur["domain"][0]
        out.append(f"the domain is now '{new_name}', was '{old_name}'" if old_name != new_name else
                   f"the domain '{new_name}' was moved, scaled or edited")
    if was.get("resolution") != cur["resolution"]:
        out.append("the resolution settings (edge length, Auto's tet count or grading, node tolerance) changed")
    if was.get("sharp") != cur["sharp"]:
        out.append("the sharp edges (the angle or the marked edges) changed")
    old_curves, new_curves = was.get("curves") or {}, cur["curves"]
    for name, (sigma, role, shape) in new_curves.items():
        if name not in old_curves:
            out.append(f"curve '{name}' was added")
            continue
        o_sigma, o_role, o_shape = old_curves[name]
        if o_role != role:
            out.append(f"curve '{name}' is now a {role} curve, was {o_role}")
        elif o_sigma != sigma:
            out.append(f"curve '{name}' has index {_index(sigma)}, was {_index(o_sigma)}")
        if o_shape != shape:
            out.append(f"curve '{name}' was moved or reshaped")
    out += [f"curve '{name}' was removed or renamed" for name in old_curves if name not in new_curves]
    return out


def read_domain(obj, depsgraph) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World-space triangles of a mesh object with modifiers applied.

    Returns V (n, 3) float, F (m, 3) int (outward if the input is), and the
    (k, 2) vertex pairs of edges marked sharp (indices into V).  Vertices
    used by no face are dropped.
    """
    if obj is None:
        raise InputError("no domain: pick a closed mesh object as Domain in the SymFrames panel")
    if obj.type != "MESH":
        raise InputError(f"domain '{obj.name}' is a {obj.type.lower()} object; pick a closed mesh object")
    ev = obj.evaluated_get(depsgraph)
    me = ev.to_mesh()
    try:
        n = len(me.vertices)
        co = np.empty(3 * n, np.float32)
        me.vertices.foreach_get("co", co)
        tris = me.loop_triangles
        F = np.empty(3 * len(tris), np.int32)
        tris.foreach_get("vertices", F)
        E = np.empty(2 * len(me.edges), np.int32)
        me.edges.foreach_get("vertices", E)
        sharp = np.zeros(len(me.edges), bool)
        attr = me.attributes.get("sharp_edge")
        if attr is not None and attr.domain == "EDGE" and attr.data_type == "BOOLEAN":
            attr.data.foreach_get("value", sharp)
    finally:
        ev.to_mesh_clear()
    F = F.reshape(-1, 3).astype(np.int64)
    if len(F) == 0:
        raise InputError(f"domain '{obj.name}' has no faces; it must be a closed surface bounding a solid")
    if len(F) < 4:  # a plane or a single polygon: open, whatever its polygons
        raise InputError(f"domain '{obj.name}' has {len(F)} triangle(s), an open sheet such as a plane: it must be a "
                         "closed surface bounding a solid (at least 4 triangles); pick or model a closed mesh")
    M = np.array(obj.matrix_world, dtype=float)
    V = co.reshape(-1, 3).astype(float) @ M[:3, :3].T + M[:3, 3]
    if np.linalg.det(M[:3, :3]) < 0:  # a mirroring transform turns the surface inside out
        F = F[:, ::-1]
    used = np.zeros(n, bool)
    used[F.ravel()] = True
    remap = np.cumsum(used) - 1
    sharp_pairs = E.reshape(-1, 2)[sharp]
    sharp_pairs = sharp_pairs[used[sharp_pairs].all(axis=1)]
    return V[used], remap[F], remap[sharp_pairs]


def spline_points(spline, matrix) -> np.ndarray:
    """(n, 3) world-space points of a poly or Bézier spline; a cyclic spline
    repeats its first point at the end."""
    M = np.array(matrix, dtype=float)
    if spline.type == "POLY":
        co = np.empty(4 * len(spline.points), np.float32)
        spline.points.foreach_get("co", co)
        P = co.reshape(-1, 4)[:, :3].astype(float)
        if spline.use_cyclic_u and len(P) > 2:
            P = np.vstack([P, P[:1]])
    elif spline.type == "BEZIER":
        bp = list(spline.bezier_points)
        pairs = list(zip(bp[:-1], bp[1:]))
        if spline.use_cyclic_u and len(bp) > 2:
            pairs.append((bp[-1], bp[0]))
        res = max(int(spline.resolution_u), 1) + 1
        pts = [np.array(bp[0].co)]
        for a, b in pairs:
            seg = interpolate_bezier(a.co, a.handle_right, b.handle_left, b.co, res)
            pts.extend(np.array(v) for v in seg[1:])
        P = np.array(pts, dtype=float)
    else:
        raise InputError(
            f"{spline.type.lower()} splines are not supported; set the spline type to Poly or Bézier "
            "(Edit Mode > Curve > Set Spline Type)"
        )
    return P @ M[:3, :3].T + M[:3, 3]


def resample(P: np.ndarray, max_segment: float) -> np.ndarray:
    """Split every segment longer than max_segment evenly; keeps all input
    points (so corners stay corners)."""
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    k = np.maximum(np.ceil(seg / max_segment).astype(int), 1)
    if np.all(k == 1):
        return P
    out = [P[:1]]
    for i in range(len(seg)):
        t = np.arange(1, k[i] + 1)[:, None] / k[i]
        out.append(P[i] + t * (P[i + 1] - P[i]))
    return np.vstack(out)


def network_objects(collection) -> tuple[list, list]:
    """(curve objects, names of other objects) of a collection and its children, by name."""
    if collection is None:
        return [], []
    objs = sorted(collection.all_objects, key=lambda o: o.name)
    return [o for o in objs if o.type == "CURVE"], [o.name for o in objs if o.type != "CURVE"]


def curve_sigma(settings) -> float:
    """Index in turns; feature and sharp curves carry none whatever the stored number."""
    return settings.index / 4.0 if settings.role == "singular" else 0.0


def read_network(collection, settings, max_segment: float) -> tuple[Network, list]:
    """The solver Network of a collection's curve objects and the scene's
    sharp-edge settings (the marked sharp edges are added by read_inputs)."""
    curves = []
    objs, ignored = network_objects(collection)
    for obj in objs:
        cs = obj.symframes
        splines = list(obj.data.splines)
        if not splines:
            raise InputError(f"curve object '{obj.name}' in the network has no spline (no points): draw the "
                             "curve, or move the object out of the network collection")
        for k, sp in enumerate(splines):
            name = obj.name if len(splines) == 1 else f"{obj.name}[{k}]"
            try:
                P = spline_points(sp, obj.matrix_world)
            except InputError as e:
                raise InputError(f"curve object '{obj.name}': {e}") from None
            curves.append(Curve(points=resample(P, max_segment), sigma=curve_sigma(cs), role=cs.role,
                                torsion=cs.torsion, name=name, closed=bool(sp.use_cyclic_u and len(P) > 3)))
    angle = math.degrees(settings.sharp_angle) if settings.use_sharp_angle else None
    tol = float(settings.node_tolerance) if settings.node_tolerance > 0 else None
    return Network(curves=curves, sharp_angle=angle, node_tolerance=tol), ignored


def network_note(collection, n_curves: int) -> str:
    """Where the network's curves come from, in words."""
    if collection is None:
        return "no network collection is chosen in the SymFrames panel"
    if n_curves == 0:
        return f"the network collection '{collection.name}' holds no curve objects"
    return f"{n_curves} curve(s) from the collection '{collection.name}'"


def solver_options(settings) -> Options:
    follow = bool(settings.follow_network)
    return Options(
        edge_length=None if settings.auto_resolution else float(settings.edge_length),
        penalty=float(settings.penalty),
        max_iterations=int(settings.max_iterations),
        init=settings.init,
        seed=int(settings.solve_seed),
        target_tets=int(settings.target_tets),
        # Follow Network: the solver's default rule (issue 41b) for this count
        tets_ceiling=Options.following_ceiling(settings.target_tets) if follow else None,
        grading=None if follow else float(settings.grading),
    )


def read_inputs(context) -> Inputs:
    """Read the scene's domain and network into arrays; raise InputError
    with a message for the user when they are missing or unusable."""
    scene = context.scene
    s = scene.symframes
    depsgraph = context.evaluated_depsgraph_get()
    V, F, sharp_pairs = read_domain(s.domain, depsgraph)
    opts = solver_options(s)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    # curves need no more points than the mesh resolves; long straight
    # segments are split so that tangents and kinks are measured locally
    max_seg = 0.5 * opts.edge_length if opts.edge_length else diag / 50.0
    net, ignored = read_network(s.network, s, max_seg)
    if s.use_sharp_marks and len(sharp_pairs):
        net.sharp_edges = sharp_pairs
    return Inputs(V=V, F=F, network=net, options=opts, ignored=ignored,
                  network_note=network_note(s.network, len(net.curves)), domain_name=s.domain.name,
                  curve_shapes=curve_shapes(s.network))


def curve_shapes(collection) -> dict:
    """Fingerprint of each network curve's spline as drawn (world space,
    before resampling), under the name read_network gives it."""
    out = {}
    objs, _ = network_objects(collection)
    for obj in objs:
        splines = list(obj.data.splines)
        for k, sp in enumerate(splines):
            name = obj.name if len(splines) == 1 else f"{obj.name}[{k}]"
            out[name] = _digest(spline_points(sp, obj.matrix_world))
    return out

