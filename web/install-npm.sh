#!/usr/bin/env bash
# Installs the browser side's npm packages, pinned, into a folder this script manages (never
# committed): three (the player page's renderer, copied next to the module by web/build.sh) and
# puppeteer-core (the headless-Chromium test, tests/web/browser.sh; it drives Debian's chromium and
# downloads no browser), gltf-validator (the clips' tests) and esbuild (web/build.sh bundles three.js
# into one minified module with it; its binary comes in its npm package @esbuild/linux-x64). Idempotent: a folder that holds these versions is left as it is, without
# touching the network. tools/install-deps.sh runs it.
#   web/install-npm.sh [DIR]     (default: $FACEMORPH_NPM_DIR or build-web/npm)
# Each npm install is bounded ($FACEMORPH_NPM_TIMEOUT seconds, default 300) and tried 3 times: a
# registry that stalls a connection once left an install hanging with no output and no end.
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-${FACEMORPH_NPM_DIR:-build-web/npm}}
packages=(three@0.187.0 puppeteer-core@25.16.0 gltf-validator@2.0.0-dev.3.10 esbuild@0.28.2)
command -v npm >/dev/null || { echo "install-npm: npm not found (tools/install-deps.sh installs it)" >&2; exit 1; }
have() {  # have NAME@VERSION: installed at that version
  local name=${1%@*} version=${1##*@}
  [[ -f "$dir/node_modules/$name/package.json" ]] && grep -q "\"version\": \"$version\"" "$dir/node_modules/$name/package.json"
}
missing=()
for package in "${packages[@]}"; do have "$package" || missing+=("$package"); done
((${#missing[@]} == 0)) && exit 0
mkdir -p "$dir"
[[ -f "$dir/package.json" ]] || echo '{"name": "facemorph-web-deps", "private": true}' > "$dir/package.json"
timeout_s=${FACEMORPH_NPM_TIMEOUT:-300}
for attempt in 1 2 3; do
  echo "install-npm: installing ${missing[*]} into $dir (attempt $attempt of 3, at most ${timeout_s} s)" >&2
  if timeout --kill-after=10 "$timeout_s" npm install --prefix "$dir" --no-audit --no-fund --ignore-scripts "${missing[@]}" >&2; then
    exit 0
  fi
  echo "install-npm: npm install failed or took over ${timeout_s} s" >&2
done
echo "install-npm: npm install did not finish in 3 attempts; the registry may be unreachable" >&2
exit 1
