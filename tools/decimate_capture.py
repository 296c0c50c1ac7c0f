# Decimates every OBJ frame of a capture with Blender's Decimate modifier (collapse), each frame on
# its own, so that a capture of ~10k vertices becomes a sparser one with the same motion: a
# low-resolution capture for the benchmarks (tools/encode_time_bench.sh's ict2k24). The frames keep
# their positions and faces only (no materials, UVs or normals); capture.json is copied beside them.
#
#   blender -b -P tools/decimate_capture.py -- SOURCE_CAPTURE DESTINATION RATIO
import glob
import os
import shutil
import sys

import bpy

source, destination, ratio = sys.argv[sys.argv.index("--") + 1:][:3]
os.makedirs(destination, exist_ok=True)
for frame in sorted(glob.glob(os.path.join(source, "*.obj"))):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=frame)
    mesh = bpy.context.selected_objects[0]
    bpy.context.view_layer.objects.active = mesh
    decimate = mesh.modifiers.new("decimate", "DECIMATE")
    decimate.ratio = float(ratio)
    bpy.ops.object.modifier_apply(modifier=decimate.name)
    bpy.ops.wm.obj_export(filepath=os.path.join(destination, os.path.basename(frame)), export_selected_objects=False,
                          export_materials=False, export_uv=False, export_normals=False)
if os.path.exists(os.path.join(source, "capture.json")):
    shutil.copy(os.path.join(source, "capture.json"), destination)
