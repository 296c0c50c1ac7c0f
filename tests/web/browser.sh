#!/usr/bin/env bash
# Web.PlayerPageInChromium: builds the WebAssembly decoder (web/build.sh, incremental), then runs
# web/test/browser.mjs: the player page in headless Chromium driven by puppeteer-core, on FILE,
# against FMDEC's previews, with files FMDEC refuses (named errors, controls disabled), and the
# shipped web/examples/minimal.html in a second tab of the same browser. Exits 77 (skipped) without emcc, node, chromium or puppeteer-core,
# naming which.
#   tests/web/browser.sh FMDEC FILE.fmv WORK_DIR
set -euo pipefail
fmdec=$1 file=$2 work=$3
root=$(cd "$(dirname "$0")/../.." && pwd)
source "$root/tests/web/web_module.sh"
web_module "$work"
node "$root/web/test/browser.mjs" --fmdec "$fmdec" --file "$file" --out "$work"
