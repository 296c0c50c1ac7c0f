"""Playing a facemorph object: the frame-change handler that decodes the scene's time.

Each object with Object.facemorph.filepath set shows the frame at t = (frame - frame_offset) / fps,
fps being the scene's (render.fps / render.fps_base), the subframe included, t clamped into the
file's range (so scrubbing past the end holds the last pose instead of failing). Files are opened
once and kept here (not in the .blend): after a .blend is loaded, the first frame change opens them
again, which is why the handler is persistent.
"""

from __future__ import annotations

import os
from typing import Dict, Optional, Tuple

import bpy
from bpy.app.handlers import persistent

from . import mesh_data, module_locator, texture

# path -> facemorph.File; object name -> (path, t) of the frame the object shows now.
_open_files: Dict[str, object] = {}
_shown: Dict[str, Tuple[str, float]] = {}


def preference_folder() -> Optional[str]:
    addon = bpy.context.preferences.addons.get(__package__)
    return addon.preferences.module_folder if addon is not None else None


def facemorph_module():
    return module_locator.import_facemorph(preference_folder())


def open_file(path: str):
    """The opened facemorph.File for an absolute path (opened once)."""
    path = os.path.abspath(bpy.path.abspath(path))
    opened = _open_files.get(path)
    if opened is None or opened.closed:
        opened = facemorph_module().open(path)
        _open_files[path] = opened
    return opened


def close_files() -> None:
    for opened in _open_files.values():
        opened.close()
    _open_files.clear()
    _shown.clear()


def scene_time(scene, frame_offset: int) -> float:
    fps = scene.render.fps / scene.render.fps_base
    return (scene.frame_current + scene.frame_subframe - frame_offset) / fps


def texture_changes(opened) -> bool:
    """False where every keyframe shows one stored texture (format 2.2's shared atlas): set once."""
    return opened.info["distinct_textures"] > 1


def show_time(obj, t: float) -> None:
    """Decodes obj's file at t and puts the frame into obj's mesh (and its image)."""
    settings = obj.facemorph
    path = settings.filepath
    shown = _shown.get(obj.name)
    if shown == (path, t) and len(obj.data.vertices) > 0:
        return  # the same frame again (a render after the frame change, a redraw): nothing to do
    opened = open_file(path)
    info = opened.info
    follow_geometry = settings.geometry == "HANDLER"
    want_texture = (settings.texture == "FRAME" and settings.image is not None and info["texture_size"] > 0
                    and (texture_changes(opened) or shown is None or shown[0] != path))
    outputs = []
    cut_holes = info["has_holes"] and not settings.keep_holes_filled
    if follow_geometry:
        # Without holes (or with them kept filled) every frame has the grid's topology and only the
        # positions move; cut holes change the counts each frame, so the mesh is rebuilt.
        rebuild = cut_holes or len(obj.data.vertices) != info["grid_vertex_count"]
        outputs += ["positions", "faces", "uv"] if rebuild else ["positions"]
    if want_texture:
        outputs.append("texture")
    if outputs:
        frame = opened.decode(t, clamp=True, keep_holes_filled=not cut_holes, outputs=outputs)
        if follow_geometry:
            if rebuild:
                mesh_data.build_topology(obj.data, frame.positions, frame.faces, frame.uv)
            else:
                mesh_data.set_positions(obj.data, frame.positions)
        if want_texture:
            texture.set_image_pixels(settings.image, frame.texture)
    if settings.last_error:
        settings.last_error = ""
    _shown[obj.name] = (path, t)


def update_objects(scene) -> None:
    for obj in scene.objects:
        if obj.type != "MESH" or not obj.facemorph.filepath:
            continue
        try:
            show_time(obj, scene_time(scene, obj.facemorph.frame_offset))
        except Exception as error:  # noqa: BLE001 - a handler must never raise into Blender
            message = f"facemorph: {obj.name}: {error}"
            if obj.facemorph.last_error != message:
                print(message)  # once per distinct error, not once per frame
                obj.facemorph.last_error = message


@persistent
def on_frame_change(scene, depsgraph=None) -> None:
    update_objects(scene)


def forget(obj) -> None:
    """obj shows nothing yet (a new object may take a deleted one's name)."""
    _shown.pop(obj.name, None)


@persistent
def on_load(_dummy=None) -> None:
    # Objects of the loaded .blend show what their files say at the scene's frame.
    close_files()
    update_objects(bpy.context.scene)


@persistent
def on_undo(_dummy=None) -> None:
    # Undo restores meshes and images as they were at that step, whatever frame they showed: show
    # the scene's frame again.
    _shown.clear()
    update_objects(bpy.context.scene)


HANDLERS = ((bpy.app.handlers.frame_change_post, on_frame_change), (bpy.app.handlers.load_post, on_load),
            (bpy.app.handlers.undo_post, on_undo), (bpy.app.handlers.redo_post, on_undo))


def register() -> None:
    for handlers, function in HANDLERS:
        handlers.append(function)


def unregister() -> None:
    for handlers, function in HANDLERS:
        while function in handlers:
            handlers.remove(function)
    close_files()
