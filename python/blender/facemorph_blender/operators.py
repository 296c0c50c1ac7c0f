"""File > Import > facemorph (.fmv), and the object panel that says what an object plays."""

from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import importer, module_locator, player, settings


class IMPORT_SCENE_OT_facemorph(bpy.types.Operator, ImportHelper):
    """Import a facemorph file (.fmv): a face mesh that follows the scene's time"""

    bl_idname = "import_scene.facemorph"
    bl_label = "Import facemorph"
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".fmv"
    filter_glob: StringProperty(default="*.fmv", options={"HIDDEN"})
    geometry: EnumProperty(name="Geometry", items=settings.GEOMETRY_MODES, default="HANDLER")
    texture: EnumProperty(name="Texture", items=settings.TEXTURE_MODES, default="FRAME")
    keep_holes_filled: BoolProperty(name="Keep holes filled", default=False,
                                    description="Eyes and mouth stay filled: one topology for every frame")
    frame_offset: IntProperty(name="Frame offset", default=0, description="The scene frame shown at t = 0 s")
    set_scene: BoolProperty(name="Set the scene's fps and frame range", default=True)
    scale_to_metres: BoolProperty(name="Scale to metres", default=True,
                                  description="The object's scale turns the file's units (m, cm, mm) into metres")
    bake_start: IntProperty(name="Bake from frame", default=0)
    bake_end: IntProperty(name="Bake to frame", default=-1,
                          description="Below 'Bake from frame': every frame of the file")
    bake_step: IntProperty(name="Bake every", default=1, min=1, description="Bake every n-th frame")

    def draw(self, context):
        layout = self.layout
        for name in ("geometry", "texture", "keep_holes_filled", "frame_offset", "set_scene", "scale_to_metres"):
            layout.prop(self, name)
        if self.geometry == "SHAPE_KEYS":
            column = layout.column(align=True)
            for name in ("bake_start", "bake_end", "bake_step"):
                column.prop(self, name)

    def execute(self, context):
        try:
            facemorph = player.facemorph_module()
        except module_locator.ModuleNotFound as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        options = importer.ImportOptions(
            geometry=self.geometry, texture=self.texture, keep_holes_filled=self.keep_holes_filled,
            frame_offset=self.frame_offset, set_scene=self.set_scene, scale_to_metres=self.scale_to_metres,
            bake_start=self.bake_start, bake_end=self.bake_end, bake_step=self.bake_step)
        try:
            obj = importer.import_file(context, self.filepath, options)
        except facemorph.Error as error:
            # The library's message names the file and what is wrong with it (truncated, damaged, ...).
            self.report({"ERROR"}, f"facemorph: {type(error).__name__}: {error}")
            return {"CANCELLED"}
        except Exception as error:  # noqa: BLE001 - a report, never a traceback, for anything else
            self.report({"ERROR"}, f"facemorph: could not import {self.filepath}: {type(error).__name__}: {error}")
            return {"CANCELLED"}
        self.report({"INFO"}, f"facemorph: {obj.name}, frames {context.scene.frame_start}-{context.scene.frame_end}")
        return {"FINISHED"}


class OBJECT_PT_facemorph(bpy.types.Panel):
    """What a facemorph object plays (Properties > Object)"""

    bl_label = "facemorph"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.object is not None and context.object.type == "MESH" and context.object.facemorph.filepath

    def draw(self, context):
        settings_ = context.object.facemorph
        layout = self.layout
        # What was chosen at import is shown, not offered: changing it needs a new import.
        layout.label(text=settings_.filepath, icon="FILE")
        geometry = dict((key, label) for key, label, _ in settings.GEOMETRY_MODES)[settings_.geometry]
        texture = dict((key, label) for key, label, _ in settings.TEXTURE_MODES)[settings_.texture]
        layout.label(text=f"Geometry: {geometry}; texture: {texture}")
        layout.prop(settings_, "frame_offset")
        if settings_.last_error:
            layout.label(text=settings_.last_error, icon="ERROR")


def menu_import(self, context):
    self.layout.operator(IMPORT_SCENE_OT_facemorph.bl_idname, text="facemorph (.fmv)")


classes = (IMPORT_SCENE_OT_facemorph, OBJECT_PT_facemorph)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
