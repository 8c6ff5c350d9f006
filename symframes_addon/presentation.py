"""Camera, lights, world and Cycles settings for a picture of a result.

Used by scripts/symframes_run.py (``./dev.sh demo``); Cycles on the CPU
renders headless (EEVEE needs a GPU context and is very slow without one).
"""

from __future__ import annotations

import bpy
import numpy as np
from mathutils import Vector

VIEW_DIRECTION = (0.45, -0.9, 1.4)  # from the target towards the camera: above, front right


def scene_bounds(objects) -> tuple[np.ndarray, np.ndarray]:
    """World-space bounding box (lo, hi) of objects' bound boxes."""
    pts = []
    for obj in objects:
        M = np.array(obj.matrix_world)
        B = np.array([list(c) for c in obj.bound_box])
        pts.append(B @ M[:3, :3].T + M[:3, 3])
    P = np.vstack(pts)
    return P.min(axis=0), P.max(axis=0)


def setup_camera(scene, lo, hi, direction=VIEW_DIRECTION, lens: float = 50.0, margin: float = 1.05):
    """A camera looking at the box [lo, hi] from ``direction``, framing it
    (the box's corners projected onto the view plane fit in the frame)."""
    cam_data = bpy.data.cameras.new("SymFrames Camera")
    cam_data.lens = lens
    cam = bpy.data.objects.new("SymFrames Camera", cam_data)
    scene.collection.objects.link(cam)
    centre = Vector(((lo + hi) / 2).tolist())
    d = Vector(direction).normalized()
    rot = (-d).to_track_quat("-Z", "Y")
    # extent of the box across the view (camera x and y axes) and along it
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    axes = np.array(rot.to_matrix())  # columns: camera x, y, -view
    local = (corners - np.array(centre)) @ axes
    aspect = scene.render.resolution_x / scene.render.resolution_y
    tan_w = np.tan(0.5 * cam_data.angle) if aspect >= 1 else np.tan(0.5 * cam_data.angle) * aspect
    tan_h = tan_w / aspect
    # each corner must lie inside the view frustum: distance >= its depth
    # towards the camera + its lateral offset over the half-angle's tangent
    x, y, z = np.abs(local[:, 0]), np.abs(local[:, 1]), local[:, 2]
    dist = float(np.max(z + margin * np.maximum(x / tan_w, y / tan_h)))
    cam.location = centre + d * dist
    cam.rotation_euler = rot.to_euler()
    cam_data.clip_end = max(100.0, 4 * dist)
    scene.camera = cam
    return cam


def setup_lights(scene, lo, hi):
    """A key sun, a soft fill area light and a light grey world."""
    size = float(np.linalg.norm(hi - lo))
    centre = Vector(((lo + hi) / 2).tolist())
    sun = bpy.data.objects.new("SymFrames Key Light", bpy.data.lights.new("SymFrames Key Light", "SUN"))
    sun.data.energy = 3.0
    sun.data.angle = 0.2
    sun.rotation_euler = Vector((-0.6, -0.4, 1.0)).to_track_quat("Z", "Y").to_euler()
    fill = bpy.data.objects.new("SymFrames Fill Light", bpy.data.lights.new("SymFrames Fill Light", "AREA"))
    fill.data.energy = 40.0 * size * size
    fill.data.size = size
    fill.location = centre + Vector((-1.0, -0.6, 0.8)) * size
    fill.rotation_euler = (centre - fill.location).to_track_quat("-Z", "Y").to_euler()
    for obj in (sun, fill):
        scene.collection.objects.link(obj)
    world = scene.world or bpy.data.worlds.new("SymFrames World")
    scene.world = world
    if world.node_tree is None:  # Blender < 5.0 creates worlds without nodes
        world.use_nodes = True
    bg = world.node_tree.nodes.get("Background")
    if bg is not None:
        bg.inputs["Color"].default_value = (0.92, 0.93, 0.95, 1.0)
        bg.inputs["Strength"].default_value = 0.7
    return sun, fill


def setup_cycles(scene, width: int = 960, height: int = 720, samples: int = 32) -> None:
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = True
    scene.cycles.use_denoising = True
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"  # opaque background: no alpha, smaller files
    scene.render.image_settings.color_depth = "8"
    scene.render.image_settings.compression = 100
    scene.view_settings.view_transform = "Standard"
    if hasattr(scene, "cycles_curves"):
        scene.cycles_curves.shape = "THICK"


def setup_presentation(scene, objects, width: int = 960, height: int = 720, samples: int = 32):
    """Render settings, lights and a camera framing ``objects``."""
    setup_cycles(scene, width, height, samples)
    lo, hi = scene_bounds(objects)
    setup_lights(scene, lo, hi)
    return setup_camera(scene, lo, hi)


def render_png(scene, filepath: str) -> None:
    scene.render.filepath = filepath
    with bpy.context.temp_override(scene=scene):
        bpy.ops.render.render(write_still=True)


def posterize_png(filepath: str, levels: int) -> None:
    """Round every channel of a PNG to ``levels`` values, in place: a
    rendered picture then compresses several times better (for documents)."""
    img = bpy.data.images.load(filepath, check_existing=False)
    try:
        px = np.empty(len(img.pixels), np.float32)
        img.pixels.foreach_get(px)
        img.pixels.foreach_set(np.round(px * (levels - 1)) / (levels - 1))
        img.filepath_raw = filepath
        img.file_format = "PNG"
        img.save()
    finally:
        bpy.data.images.remove(img)
