#!/usr/bin/env bash
# Builds the decoder as WebAssembly with Debian's emscripten (apt: emscripten), from the same
# sources and the same C API as the native library (spec/web.md):
#   web/build.sh [BUILD_DIR]      (default build-web) -> web/dist/facemorph_wasm.{mjs,wasm}
# The decoder library is configured by emcmake with the image codecs off (the browser decodes the
# textures) and zstd compiled from Debian's source of the installed libzstd (web/fetch-zstd-source.sh);
# Eigen is header-only. Nothing is downloaded at build time but that source package, once.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-web}
jobs=${FACEMORPH_JOBS:-2}
command -v emcc >/dev/null || { echo "web/build.sh: emcc not found (apt-get install emscripten)" >&2; exit 77; }
# Debian's emscripten runs its JS tools with the machine's node and requires Debian's node modules
# (acorn, ...), which a node from elsewhere does not look for.
export NODE_PATH=${NODE_PATH:+$NODE_PATH:}/usr/share/nodejs
zstd_dir=$(web/fetch-zstd-source.sh "$build/deps")
# C++ exceptions carry the decoder's errors to the C API's boundary: emscripten turns catching off
# unless asked. -O3 for the reconstruction's loops; no SIMD flag (WebAssembly SIMD is not in every
# browser the page aims at, and the exactness test compares scalar code with native).
flags="-fexceptions -O3"
emcmake cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_C_FLAGS="-O3" \
  -DFACEMORPH_BUILD_TOOLS=OFF -DFACEMORPH_BUILD_TESTS=OFF -DFACEMORPH_BUILD_ENCODER=OFF \
  -DFACEMORPH_SHARED=OFF -DFACEMORPH_INSTALL=OFF -DFACEMORPH_IMAGE_CODECS=OFF \
  -DFACEMORPH_ZSTD_SOURCE_DIR="$zstd_dir" \
  -DEigen3_DIR=/usr/share/eigen3/cmake -DCMAKE_FIND_ROOT_PATH_MODE_PACKAGE=BOTH >/dev/null
cmake --build "$build" -j "$jobs" --target facemorph_decoder facemorph_core facemorph_zstd
mkdir -p web/dist
# The C API's functions and nothing else (as the shared library's version script), plus malloc and
# free for the buffers JS hands in. One ES module, instantiated by facemorph.js with the .wasm's
# bytes it fetched itself (web page, worker or node alike).
exports=$(grep -o 'FM_API [^(]*(' codec/decoder/include/facemorph.h | sed -E 's/.*[ *](fm_[a-z0-9_]+)\($/_\1/' | grep '^_fm_' | sort -u | paste -sd, -)
emcc $flags "$build/codec/decoder/libfacemorph_decoder.a" "$build/codec/core/libfacemorph_core.a" "$build/format/libfacemorph_format.a" "$build/libfacemorph_zstd.a" \
  -o web/dist/facemorph_wasm.mjs \
  -sMODULARIZE=1 -sEXPORT_ES6=1 -sEXPORT_NAME=createFacemorphModule -sENVIRONMENT=web,worker \
  -sALLOW_MEMORY_GROWTH=1 -sINITIAL_MEMORY=33554432 -sMAXIMUM_MEMORY=2147483648 -sFILESYSTEM=0 \
  -sEXPORTED_FUNCTIONS="$exports,_malloc,_free" -sEXPORTED_RUNTIME_METHODS=UTF8ToString \
  -sINCOMING_MODULE_JS_API=wasmBinary,print,printErr
# three.js for the pages, from the npm folder web/install-npm.sh manages: served beside the module,
# so a page needs nothing from the network. dist/three.min.js, what the pages' import maps name, is
# three.module.js and three.core.js bundled into one module and minified by esbuild (0.75 MB, 0.19 MB
# gzipped, against 2.13 MB and 0.42 MB: spec/web.md §6); without esbuild it re-exports the two files
# as they are, so the pages work either way.
npm_dir=${FACEMORPH_NPM_DIR:-build-web/npm}
three=$npm_dir/node_modules/three/build
if [[ -f "$three/three.module.js" ]]; then
  rm -f web/dist/three.module.js web/dist/three.core.js
  if [[ -x "$npm_dir/node_modules/.bin/esbuild" ]]; then
    "$npm_dir/node_modules/.bin/esbuild" "$three/three.module.js" --bundle --minify --format=esm --log-level=warning --outfile=web/dist/three.min.js
  else
    echo "web/build.sh: no esbuild in $npm_dir (web/install-npm.sh): three.js served unminified" >&2
    cp "$three/three.module.js" "$three/three.core.js" web/dist/
    echo "export * from './three.module.js';" > web/dist/three.min.js
  fi
else
  echo "web/build.sh: no three.js in $npm_dir (web/install-npm.sh): the pages will not find it" >&2
fi
ls -l web/dist/
