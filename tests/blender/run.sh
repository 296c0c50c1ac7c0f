#!/bin/sh
# Runs the Blender add-on's test: run.sh PYTHON PACKAGE_DIR FMDEC DATA_DIR WORK_DIR. Skips (exit 77,
# ctest's SKIP_RETURN_CODE) naming what is missing: blender, python3 or its numpy, the facemorph
# modules, or numpy inside Blender (test_addon.py says so and exits 77 itself: one Blender start
# less). Makes the add-on's zip from python/blender as a user would, and installs it into a scripts
# folder of the test's own (BLENDER_USER_SCRIPTS), never the user's.
python=$1 package=$2 fmdec=$3 data=$4 work=$5
here=$(cd "$(dirname "$0")" && pwd)
if ! command -v blender >/dev/null 2>&1; then
  echo "SKIP: no blender on PATH (Debian: blender; tools/install-deps.sh installs it)"
  exit 77
fi
. "$here/../python/skip_without_package.sh"
rm -rf "$work" && mkdir -p "$work/scripts" || exit 1
"$python" "$here/../../python/blender/make_addon_zip.py" "$work/facemorph_blender.zip" >/dev/null || exit 1
# Cycles prints a line per render step; the checks' lines ("ok", "FAIL") are what to read.
BLENDER_USER_SCRIPTS="$work/scripts" exec blender -b --factory-startup --python-exit-code 1 \
  --python "$here/test_addon.py" -- "$work/facemorph_blender.zip" "$package" "$fmdec" "$data" "$work"
