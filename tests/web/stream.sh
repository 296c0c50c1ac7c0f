#!/usr/bin/env bash
# Web.StreamedFramesEqualTheWholeFile: builds the WebAssembly decoder (web/build.sh, incremental),
# then web/test/stream.mjs: FILE read by range requests into a borrowed open decodes every frame as
# the whole file does. Exits 77 (skipped) without emcc or node, naming which.
#   tests/web/stream.sh FILE.fmv WORK_DIR
set -euo pipefail
file=$1 work=$2
root=$(cd "$(dirname "$0")/../.." && pwd)
for tool in emcc node; do
  command -v "$tool" >/dev/null || { echo "SKIPPED: $tool not found (tools/install-deps.sh installs it)"; exit 77; }
done
mkdir -p "$work"
"$root/web/build.sh" "${FACEMORPH_WEB_BUILD:-$root/build-web}" > "$work/build.log" 2>&1 || { tail -30 "$work/build.log"; exit 1; }
node "$root/web/test/stream.mjs" "$file" 16
