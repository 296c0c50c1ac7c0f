#!/usr/bin/env bash
# The README's two commands, and the developers' third.
#   tools/quickstart.sh sample    install what is missing, build what the main job runs, and run it on a
#                                 built-in synthetic capture: fmsynth -> fmenc -> fminfo -> fmdec --t 1.45
#                                 (out/sample/)
#   tools/quickstart.sh test      install what is missing, build everything (reusing sample's build), run
#                                 every test; then build the decoder side alone (no encoder, no OpenCV), as
#                                 a player builds it, under AddressSanitizer + UndefinedBehaviorSanitizer
#                                 (clang) and run its tests and the fuzz targets for a bounded time (20 s each)
#   tools/quickstart.sh sanitize  every library and test under the sanitizers, the encoder included
#                                 (build-asan/): what `test` ran until CI's time asked for less (README)
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)

# Compiles go through ccache where it is installed: the build folders then share objects made with
# the same flags, and a rebuild after a small change is quick. Chosen only after install-deps.sh has
# run (it installs ccache): choosing before meant a fresh machine's `sample` built without the launcher
# and `test` then compiled every object again under it. The cache is the checkout's own (build-ccache/,
# unless CCACHE_DIR says otherwise), with paths taken relative to the checkout.
launcher=()
choose_launcher() {
  if command -v ccache >/dev/null; then
    export CCACHE_DIR=${CCACHE_DIR:-$PWD/build-ccache}
    export CCACHE_BASEDIR=$PWD
    export CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  fi
}

build() {  # build DIR "TARGET..." [cmake options...]   (TARGET "all" builds everything)
  local dir=$1 targets=$2
  shift 2
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" "$@" >/dev/null
  # shellcheck disable=SC2086  # the targets are words
  cmake --build "$dir" -j "$jobs" --target $targets
}

sanitized_tests() {  # sanitized_tests DIR
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    ctest --test-dir "$1" --output-on-failure -j "$jobs"
}

# The sanitizer builds: clang (float-cast-overflow too) at -O1; FACEMORPH_SANITIZE adds the line
# tables the reports print (-g1). The Python modules are not built: Python cannot load an ASan library.
sanitizer_options=(-DFACEMORPH_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo
                   -DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -DFACEMORPH_PYTHON=OFF)

case "${1:-}" in
  sample)
    tools/install-deps.sh
    choose_launcher
    build build "fmsynth fmenc fminfo fmdec"
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
    choose_launcher
    build build all
    ctest --test-dir build --output-on-failure -j "$jobs"
    echo "== the decoder side alone, as a player builds it (encoder off, OpenCV not even looked for), under"
    echo "   AddressSanitizer + UndefinedBehaviorSanitizer: every reader of a file a player is given (container,"
    echo "   decode path, player API, OBJ/PLY parsers), the hostile set, and the libFuzzer targets (20 s each)"
    # It reads the hostile set the plain build's tests just wrote (the same sources write the same files).
    CC=clang CXX=clang++ build build-decoder-asan all -DFACEMORPH_BUILD_ENCODER=OFF -DCMAKE_DISABLE_FIND_PACKAGE_OpenCV=ON \
      -DFACEMORPH_FUZZ=ON -DFACEMORPH_BUILD_TOOLS=OFF -DFACEMORPH_HOSTILE_FILES="$PWD/build/tests/hostile-files" "${sanitizer_options[@]}"
    sanitized_tests build-decoder-asan
    ;;
  sanitize)
    tools/install-deps.sh
    choose_launcher
    echo "== every library and test under AddressSanitizer + UndefinedBehaviorSanitizer (clang), the encoder's"
    echo "   included, but the whole-capture encodes of tests/sanitizer_long_tests.txt"
    CC=clang CXX=clang++ build build-asan all -DFACEMORPH_FUZZ=ON -DFACEMORPH_BUILD_TOOLS=OFF "${sanitizer_options[@]}" "${@:2}"
    sanitized_tests build-asan
    ;;
  *)
    echo "usage: tools/quickstart.sh sample | test | sanitize [cmake options]" >&2
    exit 2
    ;;
esac
