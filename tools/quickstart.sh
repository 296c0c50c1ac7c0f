#!/usr/bin/env bash
# The README's two commands.
#   tools/quickstart.sh sample   install what is missing, build, and run the main job on a built-in
#                                synthetic capture: fmsynth -> fmenc -> fmdec --t 1.45 (out/sample/)
#   tools/quickstart.sh test     install what is missing, build, and run every test; build and test
#                                the decoder alone (no encoder, no OpenCV); then every test again
#                                under AddressSanitizer + UndefinedBehaviorSanitizer (clang), with
#                                the fuzz targets run for a bounded time
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)

# Compiles go through ccache where it is installed (install-deps.sh installs it): the decoder-only
# build below compiles the same sources with the same flags as the full build, and would otherwise
# take 3-5 of CI's minutes to make the same objects again. The cache is the build's own (build-ccache/,
# unless CCACHE_DIR says otherwise); paths are taken relative to the checkout so that the build
# folders share it; the precompiled headers need the sloppiness (ccache's manual, "Precompiled headers").
launcher=()
if command -v ccache >/dev/null; then
  export CCACHE_DIR=${CCACHE_DIR:-$PWD/build-ccache}
  export CCACHE_BASEDIR=$PWD
  export CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi

build() {  # build DIR TARGET [cmake options...]   (TARGET "all" builds everything)
  local dir=$1 target=$2
  shift 2
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@" >/dev/null
  cmake --build "$dir" -j "$jobs" --target "$target"
}

case "${1:-}" in
  sample)
    tools/install-deps.sh
    build build all
    out=out/sample
    rm -rf "$out"
    mkdir -p "$out"
    echo "== fmsynth: a 2-second synthetic capture (60 frames, 20k vertices, textured, scanner noise)"
    build/tools/fmsynth -o "$out/capture" --frames 60 --fps 30 --expression mixed
    echo "== fmenc: encode it (10% keyframes, grid size from the capture)"
    build/tools/fmenc "$out/capture" -o "$out/sample.fmv"
    echo "== fminfo: what the file holds"
    build/tools/fminfo "$out/sample.fmv"
    echo "== fmdec: the face at t = 1.45 s, as a mesh with its texture and a picture"
    build/tools/fmdec "$out/sample.fmv" --t 1.45 -o "$out/frame_1.45.obj" --preview "$out/frame_1.45_view.png"
    echo "sample done:"
    echo "  capture  $out/capture/ (60 OBJ frames with textures)"
    echo "  file     $out/sample.fmv"
    echo "  mesh     $out/frame_1.45.obj (+ frame_1.45.mtl, texture frame_1.45.png)"
    echo "  picture  $out/frame_1.45_view.png"
    ;;
  test)
    tools/install-deps.sh
    build build all
    ctest --test-dir build --output-on-failure -j "$jobs"
    echo "== the decoder side alone, as a player builds it: encoder off, OpenCV not even looked for"
    # Neither this pass nor the sanitizer one builds the Python modules: their tests ran above, on
    # the same library (under the sanitizers they skip: Python cannot load an ASan library).
    build build-decoder all -DFACEMORPH_BUILD_ENCODER=OFF -DCMAKE_DISABLE_FIND_PACKAGE_OpenCV=ON -DFACEMORPH_PYTHON=OFF
    ctest --test-dir build-decoder --output-on-failure -j "$jobs"
    echo "== again under AddressSanitizer + UndefinedBehaviorSanitizer (clang: float-cast-overflow too), but the"
    echo "   whole-capture encodes of tests/sanitizer_long_tests.txt, and the libFuzzer targets (container"
    echo "   reader, OBJ/PLY parsers: 45 s each; the decode path: 40 s)"
    # Only what ctest runs, at -O1 -g1: the sanitizers need line tables, not full debug info.
    CC=clang CXX=clang++ build build-asan all -DFACEMORPH_SANITIZE=ON -DFACEMORPH_FUZZ=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" -DFACEMORPH_BUILD_TOOLS=OFF -DFACEMORPH_PYTHON=OFF
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      ctest --test-dir build-asan --output-on-failure -j "$jobs"
    ;;
  *)
    echo "usage: tools/quickstart.sh sample | test" >&2
    exit 2
    ;;
esac
