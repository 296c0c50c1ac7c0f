"""Baking a file's frames to shape keys: plays without the facemorph module, at the baked frames.

Absolute shape keys (Key.use_relative off): one key per baked frame, and the key's evaluation time
keyframed so that each baked scene frame shows exactly its own key (the decoded float32 positions),
with linear blending between two neighbours when the step is above 1. One fcurve with one point a
baked frame, instead of a relative key's weight curve per key. The topology must be one for every
key, so holes are kept filled (the decoder's grid).
"""

from __future__ import annotations

import numpy as np

from . import mesh_data


def bake(obj, opened, scene, start: int, end: int, step: int) -> int:
    """Keys for the scene frames start..end (every step-th); returns how many were made."""
    fps = scene.render.fps / scene.render.fps_base
    offset = obj.facemorph.frame_offset
    frames = list(range(start, end + 1, step))
    if frames[-1] != end:
        frames.append(end)  # the range's last frame is always baked
    mesh = obj.data
    first = opened.decode((frames[0] - offset) / fps, clamp=True, keep_holes_filled=True,
                          outputs=["positions", "faces", "uv"])
    mesh_data.build_topology(mesh, first.positions, first.faces, first.uv)
    blocks = []
    for index, frame_number in enumerate(frames):
        block = obj.shape_key_add(name=f"frame {frame_number}", from_mix=False)
        block.interpolation = "KEY_LINEAR"
        positions = first.positions if index == 0 else opened.decode(
            (frame_number - offset) / fps, clamp=True, keep_holes_filled=True, outputs=["positions"]).positions
        block.data.foreach_set("co", np.ascontiguousarray(positions, dtype=np.float32).ravel())
        blocks.append(block)
    key = mesh.shape_keys
    key.use_relative = False
    for frame_number, block in zip(frames, blocks):
        key.eval_time = block.frame
        key.keyframe_insert("eval_time", frame=frame_number)
    for fcurve in key.animation_data.action.fcurves:
        for point in fcurve.keyframe_points:
            point.interpolation = "LINEAR"
    return len(frames)
