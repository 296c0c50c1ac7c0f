#!/usr/bin/env bash
# Web.StreamedFramesEqualTheWholeFile: builds the WebAssembly decoder (web/build.sh, incremental),
# then web/test/stream.mjs: each FILE read by range requests into a borrowed open decodes every frame
# as the whole file does (2.1, 2.3 with residual frames and 2.4 with frame patches: a chunk the open
# reads must be fetched whole). Exits 77 (skipped) without emcc or node, naming which.
#   tests/web/stream.sh WORK_DIR FILE.fmv...
set -euo pipefail
work=$1
shift
root=$(cd "$(dirname "$0")/../.." && pwd)
source "$root/tests/web/web_module.sh"
web_module "$work"
for file in "$@"; do
  node "$root/web/test/stream.mjs" "$file" 16
  # And with a first request of one byte: every chunk the open reads must be fetched for itself.
  node "$root/web/test/stream.mjs" "$file" 8 1
done
