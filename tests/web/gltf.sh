#!/usr/bin/env bash
# Web.CompactGltfClipMatchesFloats: fmdec's glTF clip of FILE as the web gets it (quantised,
# meshopt-compressed) against the same clip in floats (--glb-float), by web/test/gltf_check.mjs.
# Exits 77 (skipped) without node or the npm packages (web/install-npm.sh), naming which.
#   tests/web/gltf.sh FMDEC FILE.fmv WORK_DIR
set -euo pipefail
fmdec=$1 file=$2 work=$3
root=$(cd "$(dirname "$0")/../.." && pwd)
command -v node >/dev/null || { echo "SKIPPED: node not found (tools/install-deps.sh installs it)"; exit 77; }
mkdir -p "$work"
"$fmdec" "$file" --fps 30 -o "$work/compact.glb" --quiet
"$fmdec" "$file" --fps 30 -o "$work/float.glb" --glb-float --quiet
node "$root/web/test/gltf_check.mjs" "$work/compact.glb" "$work/float.glb"
