"""Example scenes built from solver.examples: a domain mesh object, a network
collection of curve objects carrying their SymFrames settings, and the
scene settings that solve them: Auto resolution, as the solver's default
(at the hand-set edge lengths of ``EDGE_LENGTHS``, shown when Auto is turned
off, the torus's field does not converge and the ball's nodes are too close
for its hex map), and glyph sizes that suit each solid."""

from __future__ import annotations

import bpy
import numpy as np

from ..solver.examples import load_example

DESCRIPTIONS = {
    "cube": "Unit cube with sharp edges, no interior curves",
    "cylinder": "Cylinder with sharp rims and 4 axial singular curves (index +1/4): the O-grid layout",
    "torus": "Smooth solid torus (genus 1), no curves",
    "ball": "Ball with the cube-sphere network: 20 curves of index +1/4 meeting at 8 nodes",
    "plate": "CAD-like plate with a hole: sharp edges and 4 curves of index -1/4 around the hole",
}

# the Edge Length shown when Auto is turned off: coarse meshes that solve in
# seconds (the torus's does not converge at it; the ball's hex map needs finer)
EDGE_LENGTHS = {"cube": 0.3, "cylinder": 0.3, "torus": 0.25, "ball": 0.2, "plate": 0.15}
GLYPH_SIZES = {"cube": 0.14, "cylinder": 0.12, "torus": 0.06, "ball": 0.08, "plate": 0.06}
CURVE_COLOUR = (0.95, 0.75, 0.1)
DOMAIN_COLOUR = (0.6, 0.65, 0.75)


def mesh_from_arrays(name: str, V: np.ndarray, F: np.ndarray):
    me = bpy.data.meshes.new(name)
    me.from_pydata(np.asarray(V, float).tolist(), [], np.asarray(F, int).tolist())
    me.update()
    return me


def curve_from_points(name: str, P: np.ndarray, closed: bool = False, bevel: float = 0.0):
    cu = bpy.data.curves.new(name, "CURVE")
    cu.dimensions = "3D"
    cu.bevel_depth = bevel
    sp = cu.splines.new("POLY")
    if closed and np.linalg.norm(P[0] - P[-1]) < 1e-12:
        P = P[:-1]
    sp.points.add(len(P) - 1)
    co = np.ones((len(P), 4))
    co[:, :3] = P
    sp.points.foreach_set("co", co.ravel())
    sp.use_cyclic_u = bool(closed)
    return cu


def _material(name: str, colour, alpha: float = 1.0):
    mat = bpy.data.materials.get(name)
    if mat is None:
        mat = bpy.data.materials.new(name)
        if mat.node_tree is None:  # Blender < 5.0 creates materials without nodes
            mat.use_nodes = True
    mat.diffuse_color = (*colour, alpha)
    bsdf = mat.node_tree.nodes.get("Principled BSDF")
    if bsdf is not None:
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
        bsdf.inputs["Alpha"].default_value = alpha
        bsdf.inputs["Roughness"].default_value = 0.3
    return mat


def add_network_curves(network, net, diag: float) -> None:
    """The network's curves as curve objects in the collection, with their
    index, role and torsion (editable as any drawn curve)."""
    curve_mat = _material("SymFrames Network Curve", CURVE_COLOUR) if net.curves else None
    for k, c in enumerate(net.curves):
        cname = c.name or f"curve {k}"
        cu = curve_from_points(cname, c.points, c.closed, bevel=0.006 * diag)
        cu.materials.append(curve_mat)
        obj = bpy.data.objects.new(cname, cu)
        obj.symframes.index = int(round(4 * c.sigma))
        obj.symframes.role = c.role.value
        obj.symframes.torsion = c.torsion.value
        network.objects.link(obj)


def add_domain_and_network(scene, title: str, V: np.ndarray, F: np.ndarray, net, group: str | None = None) -> tuple:
    """A domain mesh object ``title`` and a network collection of curve
    objects (with their index, role and torsion) in a new collection
    ``group`` (default: ``title``); sharp edges
    of the network are marked sharp on the domain.  Points the SymFrames
    settings at them.  Returns (domain object, network collection)."""
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    root = bpy.data.collections.new(group or title)
    scene.collection.children.link(root)
    domain = bpy.data.objects.new(title, mesh_from_arrays(title, V, F))
    domain.data.materials.append(_material("SymFrames Domain", DOMAIN_COLOUR, 0.12))
    domain.display_type = "WIRE"  # the glyphs inside stay visible
    root.objects.link(domain)
    if net.sharp_edges is not None and len(net.sharp_edges):
        _mark_sharp(domain.data, np.asarray(net.sharp_edges, np.int64))
    network = bpy.data.collections.new(f"{title} Network")
    root.children.link(network)
    add_network_curves(network, net, diag)
    s = scene.symframes
    s.domain = domain
    s.network = network
    s.use_sharp_marks = True
    s.use_sharp_angle = net.sharp_angle is not None
    if net.sharp_angle is not None:
        s.sharp_angle = np.radians(net.sharp_angle)
    s.glyph_size = 0.03 * diag
    s.streamline_radius = 0.0035 * diag
    return domain, network


def _mark_sharp(me, pairs: np.ndarray) -> None:
    """Mark the mesh edges joining the vertex pairs (k, 2) sharp."""
    E = np.empty(2 * len(me.edges), np.int32)
    me.edges.foreach_get("vertices", E)
    E = np.sort(E.reshape(-1, 2).astype(np.int64), axis=1)
    n = len(me.vertices)
    keys = E[:, 0] * n + E[:, 1]
    p = np.sort(pairs, axis=1)
    sharp = np.isin(keys, p[:, 0] * n + p[:, 1])
    if "sharp_edge" not in me.attributes:
        me.attributes.new("sharp_edge", "BOOLEAN", "EDGE")
    me.attributes["sharp_edge"].data.foreach_set("value", sharp)


def build_example(scene, name: str) -> tuple:
    """Add example ``name`` to the scene and point the SymFrames settings at it.

    Returns (domain object, network collection).
    """
    V, F, net = load_example(name)
    title = name.capitalize()
    domain, network = add_domain_and_network(scene, title, V, F, net, group=f"{title} Example")
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    s = scene.symframes
    s.auto_resolution = True  # the solver's default: it solves again finer where the hex map needs it
    s.edge_length = EDGE_LENGTHS.get(name, 0.05 * diag)
    s.glyph_size = GLYPH_SIZES.get(name, 0.03 * diag)
    return domain, network
