#!/usr/bin/env bash
# The README's two commands.
#   tools/quickstart.sh sample   install what is missing, build, and run the main job on a built-in
#                                synthetic capture (out/sample/)
#   tools/quickstart.sh test     install what is missing, build, and run every test, then again
#                                under AddressSanitizer + UndefinedBehaviorSanitizer
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc 2>/dev/null || echo 2)

build() {  # build DIR [cmake options...]
  local dir=$1
  shift
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
  cmake --build "$dir" -j "$jobs"
}

case "${1:-}" in
  sample)
    tools/install-deps.sh
    build build
    out=out/sample
    rm -rf "$out"
    mkdir -p "$out"
    echo "== fmsynth: a 2-second synthetic capture (60 frames, 20k vertices, textured)"
    build/tools/fmsynth -o "$out/capture" --frames 60 --fps 30 --expression mixed
    echo "== fminfo: validate every frame as the encoder will"
    build/tools/fminfo "$out/capture" --quiet
    echo "== fmview: a picture of frame 44 (t = 1.4667 s)"
    build/tools/fmview "$out/capture/frame_0044.obj" -o "$out/frame_0044_view.png" --yaw 20
    echo "sample done: capture in $out/capture, picture $out/frame_0044_view.png"
    ;;
  test)
    tools/install-deps.sh
    build build
    ctest --test-dir build --output-on-failure -j "$jobs"
    echo "== again under AddressSanitizer + UndefinedBehaviorSanitizer"
    build build-asan -DFACEMORPH_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo
    ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
      ctest --test-dir build-asan --output-on-failure -j "$jobs"
    ;;
  *)
    echo "usage: tools/quickstart.sh sample | test" >&2
    exit 2
    ;;
esac
