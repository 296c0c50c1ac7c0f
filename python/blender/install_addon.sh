#!/bin/sh
# Installs the add-on into your Blender, enabled, its module folder set, the preferences saved:
#   python/blender/install_addon.sh [MODULE_FOLDER]
# MODULE_FOLDER holds the facemorph package (default: the checkout's build/python, which cmake's
# target facemorph_python makes); give "" to rely on $FACEMORPH_PYTHONPATH or Blender's sys.path
# (a pip install into Debian's Python). BLENDER (default blender) names the program.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
module_folder=${1-"$here/../../build/python"}
if [ -n "$module_folder" ]; then
  module_folder=$(cd "$module_folder" && pwd)
fi
zip=$(mktemp -d)/facemorph_blender.zip
python3 "$here/make_addon_zip.py" "$zip" >/dev/null
"${BLENDER:-blender}" -b --factory-startup --python-exit-code 1 --python-expr "
import bpy
bpy.ops.preferences.addon_install(filepath='$zip', overwrite=True)
bpy.ops.preferences.addon_enable(module='facemorph_blender')
bpy.context.preferences.addons['facemorph_blender'].preferences.module_folder = '$module_folder'
bpy.ops.wm.save_userpref()
print('facemorph_blender: installed and enabled; module folder: ' + ('$module_folder' or 'FACEMORPH_PYTHONPATH, then sys.path'))
" | grep '^facemorph_blender:'
rm -rf "$(dirname "$zip")"
