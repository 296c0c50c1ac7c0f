#!/usr/bin/env bash
# Web.WasmDecodesAsNative: builds the WebAssembly decoder (web/build.sh, incremental after the first
# time), decodes FILE at 20 times natively (NATIVE_FRAMES, tests/c_frames.c --web) and with the
# module under node (web/test/exactness.mjs), and fails if a vertex differs by more than 1e-6 of the
# bounding-box diagonal. Exits 77 (skipped) without emcc or node, saying which.
# Each FILE in turn.
#   tests/web/exactness.sh NATIVE_FRAMES WORK_DIR FILE.fmv...
set -euo pipefail
native_frames=$1 work=$2
shift 2
root=$(cd "$(dirname "$0")/../.." && pwd)
source "$root/tests/web/web_module.sh"
web_module "$work"
for file in "$@"; do
  "$native_frames" --web "$file" 20 "$work/native.bin"
  node "$root/web/test/exactness.mjs" "$file" "$work/native.bin" 20 1e-6
done
