"""Making the object for a .fmv file: mesh, material, scene range, and (optionally) shape keys."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import bpy

from . import player, shape_keys, texture

# The capture's units to Blender's metres (spec/capture.md: m, cm or mm).
METRES_PER_UNIT = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass
class ImportOptions:
    geometry: str = "HANDLER"      # settings.GEOMETRY_MODES
    texture: str = "FRAME"         # settings.TEXTURE_MODES
    keep_holes_filled: bool = False
    frame_offset: int = 0          # the scene frame shown at t = 0 s
    set_scene: bool = True         # the scene's fps and frame range from the file
    scale_to_metres: bool = True
    bake_start: int = 0            # shape keys: the scene frames baked (bake_end < bake_start: the file's frames)
    bake_end: int = -1
    bake_step: int = 1


def scene_frames(info, fps: float, frame_offset: int):
    """The scene frames that show the capture's first and last frames."""
    return (frame_offset + round(info["first_time"] * fps), frame_offset + round(info["last_time"] * fps))


def set_scene_rate(scene, fps: float) -> None:
    # Blender's rate is an integer over a base: 29.97 is 30 / 1.001.
    whole = max(1, round(fps))
    scene.render.fps = whole
    scene.render.fps_base = whole / fps


def import_file(context, path: str, options: ImportOptions):
    """Opens the file, makes and links the object, sets the scene; returns the object. Raises
    facemorph.Error (and subclasses) for a file that does not open or decode."""
    path = os.path.abspath(bpy.path.abspath(path))
    opened = player.open_file(path)
    info = opened.info
    scene = context.scene
    if options.set_scene:
        set_scene_rate(scene, info["fps"])
        scene.frame_start, scene.frame_end = scene_frames(info, info["fps"], options.frame_offset)
        if not scene.frame_start <= scene.frame_current <= scene.frame_end:
            scene.frame_current = scene.frame_start
    name = os.path.splitext(os.path.basename(path))[0]
    mesh = bpy.data.meshes.new(name)
    obj = bpy.data.objects.new(name, mesh)
    settings = obj.facemorph
    settings.filepath = path
    settings.geometry = options.geometry
    settings.texture = options.texture if info["texture_size"] > 0 else "NONE"
    settings.keep_holes_filled = options.keep_holes_filled or options.geometry == "SHAPE_KEYS"
    settings.frame_offset = options.frame_offset

    # The capture is y up, facing +z (OBJ's convention); Blender is z up, its front view looking
    # along +y: a quarter turn about x, in the object's transform so the mesh keeps the decoded
    # coordinates exactly.
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    if options.scale_to_metres:
        obj.scale = (METRES_PER_UNIT.get(info["units"], 1.0),) * 3

    if settings.texture != "NONE":
        settings.image = texture.new_image(f"{name} texture", info["texture_size"])
        if settings.texture == "STILL":
            # The capture's first frame, kept in the .blend: plays without the module or the file.
            frame = opened.decode(info["first_time"], clamp=True, outputs=["texture"])
            texture.set_image_pixels(settings.image, frame.texture)
            settings.image.pack()
    mesh.materials.append(texture.make_material(name, settings.image))

    if options.geometry == "SHAPE_KEYS":
        start, end = options.bake_start, options.bake_end
        if end < start:
            start, end = scene_frames(info, scene.render.fps / scene.render.fps_base, options.frame_offset)
        shape_keys.bake(obj, opened, scene, start, end, max(1, options.bake_step))
    context.collection.objects.link(obj)
    for other in context.view_layer.objects:
        other.select_set(False)
    obj.select_set(True)
    context.view_layer.objects.active = obj
    # What the handler shows at the scene's frame: the mesh (following time), the texture.
    player.forget(obj)
    player.show_time(obj, player.scene_time(scene, settings.frame_offset))
    return obj
