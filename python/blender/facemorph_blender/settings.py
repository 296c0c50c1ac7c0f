"""What an imported object remembers (Object.facemorph, saved in the .blend)."""

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, PointerProperty, StringProperty

GEOMETRY_MODES = [
    ("HANDLER", "Follow the scene's time",
     "Decode the frame at (frame - offset) / fps whenever the frame changes (needs the facemorph module while playing; any time t)"),
    ("SHAPE_KEYS", "Bake to shape keys",
     "Decode the chosen frames once into shape keys (plays without the module; only those frames, linear between them)"),
]

TEXTURE_MODES = [
    ("FRAME", "Every frame", "The texture decoded at each frame shown (needs the module while playing)"),
    ("STILL", "First frame only", "The texture at the first frame, packed into the .blend (plays without the module)"),
    ("NONE", "None", "Geometry only, a grey material"),
]


class FacemorphObjectSettings(bpy.types.PropertyGroup):
    filepath: StringProperty(name="File", subtype="FILE_PATH", description="The .fmv file this object plays")
    geometry: EnumProperty(name="Geometry", items=GEOMETRY_MODES, default="HANDLER")
    texture: EnumProperty(name="Texture", items=TEXTURE_MODES, default="FRAME")
    keep_holes_filled: BoolProperty(
        name="Keep holes filled",
        description="Eyes and mouth stay filled: one topology for every frame (shape keys always do this)")
    frame_offset: IntProperty(name="Frame offset", description="The scene frame shown at t = 0 s", default=0)
    image: PointerProperty(name="Texture image", type=bpy.types.Image)
    last_error: StringProperty(name="Last error", description="Why the last frame could not be decoded")


def register() -> None:
    bpy.utils.register_class(FacemorphObjectSettings)
    bpy.types.Object.facemorph = PointerProperty(type=FacemorphObjectSettings)


def unregister() -> None:
    del bpy.types.Object.facemorph
    bpy.utils.unregister_class(FacemorphObjectSettings)
