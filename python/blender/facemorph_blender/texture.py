"""The decoded texture as a Blender image and the material that shows it.

Choice: one image datablock per object, its pixels replaced by the decoded texture of each frame
shown (facemorph.File.decode's M×M×3 RGB). This is exactly the texture the decoder blends from the
keyframes' textures at t (the same bytes as fmdec's), whatever the blend's weights (Catmull-Rom:
up to four keyframes, weights may be negative): blending keyframe images in a node tree would need
one image node per keyframe and could not reproduce the decoder's rounding. Cost: the pixels'
copy into the image (about 40 ms for 1024²: spec/blender.md §4), done only when the texture can
change (a file whose keyframes share one texture sets it once).
"""

from __future__ import annotations

import bpy
import numpy as np


def texture_pixels(texture: np.ndarray) -> np.ndarray:
    """Blender's float RGBA pixels, bottom row first, for an M×M×3 uint8 RGB texture (top row first)."""
    # RGBA bytes first, then one contiguous conversion: 1.7x faster than converting into the
    # strided RGB part of a float array (19 against 33 ms for 1024², spec/blender.md).
    rgba = np.full(texture.shape[:2] + (4,), 255, dtype=np.uint8)
    rgba[..., :3] = texture[::-1]
    pixels = np.multiply(rgba, np.float32(1.0 / 255.0), dtype=np.float32)
    return pixels.ravel()


def new_image(name: str, size: int):
    """A new 8-bit sRGB image for one object (Blender makes the name unique: two imports of a file
    never share, and overwrite, one image)."""
    return bpy.data.images.new(name, size, size, alpha=False)


def set_image_pixels(image, texture: np.ndarray) -> None:
    image.pixels.foreach_set(texture_pixels(texture))
    image.update()


def make_material(name: str, image):
    """A Principled BSDF whose base colour is `image` through the mesh's UVs; rough, not shiny,
    as skin under a scanner's even light. Without an image, a plain grey."""
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    nodes = material.node_tree.nodes
    bsdf = nodes.get("Principled BSDF")
    bsdf.inputs["Roughness"].default_value = 0.6
    bsdf.inputs["Specular"].default_value = 0.2
    if image is None:
        bsdf.inputs["Base Color"].default_value = (0.6, 0.6, 0.6, 1.0)
        return material
    node = nodes.new("ShaderNodeTexImage")
    node.name = "facemorph texture"
    node.image = image
    node.interpolation = "Linear"
    node.extension = "EXTEND"  # the disk's rim samples its own border, never the opposite side
    node.location = (-400, 250)
    material.node_tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    return material
