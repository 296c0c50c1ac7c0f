"""File > Import > facemorph (.fmv), and the object panel that says what an object plays."""

import bpy
from bpy.props import BoolProperty, EnumProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ExportHelper, ImportHelper

from . import exporter, importer, module_locator, player, settings


def _module_or_report(operator):
    """The facemorph module, or None after saying in Blender's report why it was not found."""
    try:
        return player.facemorph_module()
    except module_locator.ModuleNotFound as error:
        operator.report({"ERROR"}, str(error))
        return None


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
        facemorph = _module_or_report(self)
        if facemorph is None:
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


class EXPORT_SCENE_OT_facemorph(bpy.types.Operator, ExportHelper):
    """Export the active mesh's animation (one topology) to a facemorph file (.fmv)"""

    bl_idname = "export_scene.facemorph"
    bl_label = "Export facemorph"

    filename_ext = ".fmv"
    filter_glob: StringProperty(default="*.fmv", options={"HIDDEN"})
    frame_start: IntProperty(name="From frame", default=0)
    frame_end: IntProperty(name="To frame", default=-1, description="Below 'From frame': the scene's range")
    frame_step: IntProperty(name="Every", default=1, min=1, description="Export every n-th frame")
    texture: BoolProperty(name="Texture", default=True, description="The material's first image, through the UVs")
    keyframes: StringProperty(name="Keyframes", default="",
                              description="The share of frames kept as keyframes (fmenc's --keyframes, e.g. 10%); empty: the encoder's default")

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def execute(self, context):
        facemorph = _module_or_report(self)
        if facemorph is None:
            return {"CANCELLED"}
        scene = context.scene
        start, end = self.frame_start, self.frame_end
        if end < start:
            start, end = scene.frame_start, scene.frame_end
        options = exporter.ExportOptions(start, end, self.frame_step, self.texture, self.keyframes or None)
        window_manager = context.window_manager
        window_manager.progress_begin(0, 100)
        stages = {"writing": 0, "mapping": 1, "registering": 2, "keyframes": 3}

        def progress(stage, done, total):
            window_manager.progress_update(25 * stages.get(stage, 3) + (25 * done // max(1, total)))

        try:
            report = exporter.export(context, context.active_object, self.filepath, options, progress)
        except (exporter.ExportError, facemorph.Error) as error:
            self.report({"ERROR"}, f"facemorph export: {type(error).__name__}: {error}")
            return {"CANCELLED"}
        except Exception as error:  # noqa: BLE001 - a report, never a traceback
            self.report({"ERROR"}, f"facemorph export: {type(error).__name__}: {error}")
            return {"CANCELLED"}
        finally:
            window_manager.progress_end()
        dropped = f", {len(report['dropped'])} frames dropped" if report["dropped"] else ""
        self.report({"INFO"}, f"facemorph: {report['output']}: {report['frames']} frames, "
                              f"{len(report['keyframe_times'])} keyframes, {report['bytes']} bytes{dropped}")
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


def menu_export(self, context):
    self.layout.operator(EXPORT_SCENE_OT_facemorph.bl_idname, text="facemorph (.fmv)")


classes = (IMPORT_SCENE_OT_facemorph, EXPORT_SCENE_OT_facemorph, OBJECT_PT_facemorph)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
