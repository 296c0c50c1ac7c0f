#!/usr/bin/env bash
# Web.StreamedFramesEqualTheWholeFile: builds the WebAssembly decoder (web/build.sh, incremental),
# then web/test/stream.mjs: FILE read by range requests into a borrowed open decodes every frame as
# the whole file does. Exits 77 (skipped) without emcc or node, naming which.
#   tests/web/stream.sh FILE.fmv WORK_DIR
set -euo pipefail
file=$1 work=$2
root=$(cd "$(dirname "$0")/../.." && pwd)
source "$root/tests/web/web_module.sh"
web_module "$work"
node "$root/web/test/stream.mjs" "$file" 16
