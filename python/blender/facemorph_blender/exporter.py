"""Exporting a Blender animation of one mesh to .fmv through facemorph.encode (fmenc's encoder).

Each scene frame start..end (every step-th) is evaluated as it renders (modifiers, shape keys, a
facemorph handler) and triangulated; its vertices go from Blender's z-up world in metres to the
capture's convention (y up, facing +z: (X, Y, Z) -> (X, Z, -Y)), the inverse of the importer's
transform, so an imported face exports where it came from. The topology must be one for every
frame (the encoder itself accepts any, but a Blender animation of one mesh has one). UVs are per
corner; the texture is the material's first image, one array for every frame (the encoder stores
it once) unless it is a facemorph object's image updated every frame, which is copied per frame.
The face is expected in Blender's front view (facing -Y, up +Z), as the importer poses it: the
nose tip and bridge passed as landmarks come from that pose (view_landmarks).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np

# Blender world (X, Y, Z) -> capture (x, y, z) = (X, Z, -Y).
WORLD_TO_CAPTURE = np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]], dtype=np.float64)


class ExportError(Exception):
    """Why the animation cannot be exported (a message for the report)."""


@dataclass
class ExportOptions:
    frame_start: int
    frame_end: int
    frame_step: int = 1
    texture: bool = True
    keyframes: Optional[str] = None   # fmenc's --keyframes ("10%"); None: its default


def material_image(obj):
    """The first image of the object's first material's image texture nodes, or None."""
    for slot in obj.material_slots:
        material = slot.material
        if material is None or not material.use_nodes:
            continue
        for node in material.node_tree.nodes:
            if node.type == "TEX_IMAGE" and node.image is not None and node.image.size[0] > 0:
                return node.image
    return None


def image_rgb(image) -> np.ndarray:
    """An image's pixels as uint8 (H, W, 3) RGB, row 0 at the top (the encoder's order)."""
    width, height = image.size
    pixels = np.empty(width * height * image.channels, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    rgb = pixels.reshape(height, width, image.channels)[::-1, :, :3]
    return np.ascontiguousarray(np.clip(np.rint(rgb * 255.0), 0, 255).astype(np.uint8))


def evaluated_frame(obj, depsgraph):
    """(vertices in capture coordinates, triangles, per-corner uv or None) of obj as evaluated now."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        mesh.calc_loop_triangles()
        count = len(mesh.vertices)
        local = np.empty(3 * count, dtype=np.float32)
        mesh.vertices.foreach_get("co", local)
        matrix = np.array(evaluated.matrix_world, dtype=np.float64)
        world = local.reshape(-1, 3).astype(np.float64) @ matrix[:3, :3].T + matrix[:3, 3]
        triangles = np.empty(3 * len(mesh.loop_triangles), dtype=np.int32)
        mesh.loop_triangles.foreach_get("vertices", triangles)
        uv = None
        if mesh.uv_layers.active is not None:
            corners = np.empty(3 * len(mesh.loop_triangles), dtype=np.int32)
            mesh.loop_triangles.foreach_get("loops", corners)
            loop_uv = np.empty(2 * len(mesh.loops), dtype=np.float32)
            mesh.uv_layers.active.data.foreach_get("uv", loop_uv)
            uv = loop_uv.reshape(-1, 2)[corners]
        return world @ WORLD_TO_CAPTURE.T, triangles.reshape(-1, 3), uv
    finally:
        evaluated.to_mesh_clear()


def view_landmarks(vertices: np.ndarray) -> dict:
    """nose_tip and nose_bridge of a face posed as Blender's front view shows it (the importer's
    pose: y up, facing +z in capture coordinates): the tip is the vertex farthest along +z; the
    bridge the farthest along +z of those a tenth to a fifth of the face's height above it, near
    its midline. They tell the encoder which way is up where the geometry alone may not (a smooth
    decoded face: fmenc's --landmarks auto found no orientation on the decoded sample)."""
    low, high = vertices.min(0), vertices.max(0)
    width, height = high[0] - low[0], high[1] - low[1]
    tip = vertices[np.argmax(vertices[:, 2])]
    above = vertices[(vertices[:, 1] > tip[1] + 0.1 * height) & (vertices[:, 1] < tip[1] + 0.2 * height)
                     & (np.abs(vertices[:, 0] - tip[0]) < 0.05 * width)]
    if len(above) == 0:
        return {}
    return {"nose_tip": tip, "nose_bridge": above[np.argmax(above[:, 2])]}


def collect_frames(context, obj, options: ExportOptions) -> tuple:
    """The frames as facemorph.encode takes them, and their times (seconds)."""
    scene = context.scene
    fps = scene.render.fps / scene.render.fps_base
    numbers = list(range(options.frame_start, options.frame_end + 1, max(1, options.frame_step)))
    if len(numbers) < 2:
        raise ExportError(f"frames {options.frame_start}..{options.frame_end}: at least two frames are needed")
    image = material_image(obj) if options.texture else None
    per_frame_texture = image is not None and obj.facemorph.filepath and obj.facemorph.texture == "FRAME" \
        and image == obj.facemorph.image
    shared_texture = image_rgb(image) if image is not None and not per_frame_texture else None
    frames, times, topology = [], [], None
    current = scene.frame_current
    try:
        for number in numbers:
            scene.frame_set(number)
            vertices, triangles, uv = evaluated_frame(obj, context.evaluated_depsgraph_get())
            if topology is None:
                topology = triangles
            elif not np.array_equal(topology, triangles):
                raise ExportError(f"frame {number}: the mesh's topology changed ({len(vertices)} vertices, "
                                  f"{len(triangles)} triangles); export needs one topology for every frame")
            frame = {"vertices": vertices, "faces": triangles, "landmarks": view_landmarks(vertices)}
            if uv is not None and image is not None:
                frame["uv"] = uv
                frame["uv_faces"] = np.arange(3 * len(triangles), dtype=np.int32).reshape(-1, 3)
                frame["texture"] = image_rgb(image) if per_frame_texture else shared_texture
            frames.append(frame)
            times.append((number - numbers[0]) / fps)
    finally:
        scene.frame_set(current)
    return frames, times


def export(context, obj, path: str, options: ExportOptions, progress: Optional[Callable[[str, int, int], None]] = None):
    """Encodes obj's animation into path; returns facemorph.encode's report."""
    from . import player
    facemorph = player.facemorph_module()
    frames, times = collect_frames(context, obj, options)
    has_texture = "texture" in frames[0]
    keywords = {"times": times, "units": "m", "texture": has_texture, "progress": progress}
    if options.keyframes:
        keywords["keyframes"] = options.keyframes
    return facemorph.encode(frames, path, **keywords)
