"""facemorph for Blender: File > Import > facemorph (.fmv).

The imported mesh follows the scene's time (each frame decoded at (frame - offset) / fps by a
frame-change handler through the `facemorph` Python module), or is baked to shape keys; its
material shows the decoded texture. See spec/blender.md for the choices and their limits.
"""

bl_info = {
    "name": "facemorph (.fmv)",
    "author": "facemorph",
    "version": (0, 8, 0),
    "blender": (3, 4, 0),
    "location": "File > Import > facemorph (.fmv)",
    "description": "Plays compressed 3D facial video (.fmv) at any time t, or bakes it to shape keys",
    "category": "Import-Export",
}

import bpy

from . import operators, player, settings


class FacemorphPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    module_folder: bpy.props.StringProperty(
        name="Module folder",
        subtype="DIR_PATH",
        description="The folder that holds the facemorph Python package (facemorph/), e.g. the build's "
                    "build/python or a venv's site-packages. Empty: $FACEMORPH_PYTHONPATH, then Blender's sys.path")

    def draw(self, context):
        self.layout.prop(self, "module_folder")


classes = (FacemorphPreferences,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    settings.register()
    operators.register()
    player.register()


def unregister():
    player.unregister()
    operators.unregister()
    settings.unregister()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
