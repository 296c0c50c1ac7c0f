#!/usr/bin/env bash
# Web.PlayerPageInChromium: builds the WebAssembly decoder (web/build.sh, incremental), then runs
# web/test/browser.mjs: the player page in headless Chromium driven by puppeteer-core, on FILE,
# against FMDEC's previews. Exits 77 (skipped) without emcc, node, chromium or puppeteer-core,
# naming which.
#   tests/web/browser.sh FMDEC FILE.fmv WORK_DIR
set -euo pipefail
fmdec=$1 file=$2 work=$3
root=$(cd "$(dirname "$0")/../.." && pwd)
for tool in emcc node; do
  command -v "$tool" >/dev/null || { echo "SKIPPED: $tool not found (tools/install-deps.sh installs it)"; exit 77; }
done
mkdir -p "$work"
"$root/web/build.sh" "${FACEMORPH_WEB_BUILD:-$root/build-web}" > "$work/build.log" 2>&1 || { tail -30 "$work/build.log"; exit 1; }
node "$root/web/test/browser.mjs" --fmdec "$fmdec" --file "$file" --out "$work"
