#!/usr/bin/env bash
# Writes a golden container for the current format version, and what it decodes to, with the
# project's own tools. Run it only when the format version changes, naming the new version: never
# replace an old golden file (later versions must keep decoding every earlier file identically).
#   tests/data/make_golden.sh BUILD_DIR VERSION [FMSYNTH OPTIONS...]   e.g. VERSION = 2_0
# The fmsynth options give the capture what the version adds (2.2: --shared-texture, one texture
# image for every frame, which the keyframes share; 2.3: --speech-rate 3, a mouth faster than the
# spline of the keyframes follows, which residual frames serve, with FMENC_OPTIONS=--residual-frames).
#   FMENC_OPTIONS="--residual-frames" tests/data/make_golden.sh build 2_3 --speech-rate 3
# 2.4: the same capture with fmenc's defaults but a patch bound of 0.4% (at 1% its 12 frames need no
# frame patch, the PTCH chunk the version adds):
#   FMENC_OPTIONS="--patch-bound 0.4%" tests/data/make_golden.sh build 2_4 --speech-rate 3
# 2.5: the same as 2.4 (its header against the dictionary, its patches range-coded, its rim linear):
#   FMENC_OPTIONS="--patch-bound 0.4%" tests/data/make_golden.sh build 2_5 --speech-rate 3
# 2.6: the same at N = 129 (GOLDEN_GRID, 33 unless set), where the writer chooses the levels
# predictor (KGLV chunks) for some group (at N = 33 it does not):
#   GOLDEN_GRID=129 FMENC_OPTIONS="--patch-bound 0.4%" tests/data/make_golden.sh build 2_6 --speech-rate 3
set -euo pipefail
build=${1:?usage: make_golden.sh BUILD_DIR VERSION}
version=${2:?usage: make_golden.sh BUILD_DIR VERSION (e.g. 2_0)}
shift 2
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$build/tools/fmsynth" -o "$work/capture" --frames 12 --fps 30 --expression mixed --vertices 3000 --remesh --noise 0 \
  --texture-size 128 --head-motion 10 --quiet "$@"
# Intra period 2: two groups of keyframes, one coded from the other within it.
"$build/tools/fmenc" "$work/capture" -o "$here/golden_v$version.fmv" --keyframes 25% --grid "${GOLDEN_GRID:-33}" --texture 64 --quality 80 --intra-period 2 --quiet ${FMENC_OPTIONS:---no-residual-frames}
FACEMORPH_WRITE_GOLDEN="$here/golden_v$version.csv" "$build/tests/facemorph_decoder_tests" --gtest_filter="GoldenFile.Version${version}*"
