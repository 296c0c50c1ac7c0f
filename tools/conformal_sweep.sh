#!/usr/bin/env bash
# The conformal map's robustness sweep (issue 26): every frame of the Medusa capture, of the whole
# 67 s ICT capture, and of fmsynth captures over seeds, expressions, remeshing, noise and scanner
# defects (--defects all: repaired before the map), through
# the encoder's map (fmbench conformal --sweep: counts of QIEM, linear and Tutte maps, failures,
# preconditioning left-overs, time). A benchmark, not a test: it takes tens of minutes.
# Captures are made once into CACHE and reused.
#
#   tools/conformal_sweep.sh [BUILD_DIR=build] [DATA=../shared/data] [CACHE=out/sweep]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build} data=${2:-../shared/data} cache=${3:-out/sweep}
mkdir -p "$cache"
inputs=()

# fmsynth: seeds, every expression, remeshed (each frame its own triangulation) or not, and noise
# up to the size of the edges (the regime that once collapsed QIEM's disk).
settings=(
  "--seed 1 --expression mixed"
  "--seed 2 --expression talk --remesh"
  "--seed 3 --expression smile --remesh --noise 0.001"
  "--seed 4 --expression blink --noise 0.0005"
  "--seed 5 --expression mouth --remesh --noise 0.0003"
  "--seed 6 --expression talk --noise 0.002"
  "--seed 7 --expression talk --noise 0.001"
  "--seed 8 --expression mixed --remesh --vertices 40000"
  "--seed 9 --expression mouth --vertices 3000 --noise 0.001"
  "--seed 10 --expression smile --remesh --vertices 5000"
  # What scanners write (issue 47): every defect the encoder repairs, in every frame.
  "--seed 11 --expression mixed --defects all"
  "--seed 12 --expression talk --remesh --noise 0.001 --defects all"
  # Whole heads whose rim is the neck, eyes, mouth and nostrils open (issue 47 part 2).
  "--seed 13 --expression mixed --head --holes --vertices 6000"
  "--seed 14 --expression talk --head --holes --noise 0.001 --vertices 6000"
)
for s in "${settings[@]}"; do
  name=synth_$(echo "$s" | tr -c 'a-z0-9' '_' | tr -s '_')
  if [[ ! -f "$cache/$name/capture.json" ]]; then
    [[ "$s" == *--vertices* ]] || s="$s --vertices 20000"
    # shellcheck disable=SC2086
    "$build/tools/fmsynth" -o "$cache/$name" --frames 20 --fps 30 $s --quiet
  fi
  inputs+=("$cache/$name")
done

if [[ -d "$data/medusa-mediapipe-4d/capture" ]]; then
  inputs+=("$data/medusa-mediapipe-4d/capture")
else
  echo "conformal_sweep: skipping Medusa ($data/medusa-mediapipe-4d/capture not found)" >&2
fi
if [[ -f "$data/ict-facekit/tools/make_capture.py" ]]; then
  if [[ ! -f "$cache/ict_all/capture.json" ]]; then
    python3 "$data/ict-facekit/tools/make_capture.py" "$cache/ict_all" --start-seconds 0 --seconds 67
  fi
  inputs+=("$cache/ict_all")
  # ICT's whole head to the neck, eyes and mouth open (issue 47 part 2; its separate eyeballs, teeth,
  # gums and lashes, tools/ict_whole_head.py --pieces, are what fmenc --largest-component drops).
  if [[ ! -f "$cache/ict_whole_head/capture.json" ]]; then
    python3 tools/ict_whole_head.py "$cache/ict_whole_head" --frames 20 --data "$data"
  fi
  inputs+=("$cache/ict_whole_head")
else
  echo "conformal_sweep: skipping ICT ($data/ict-facekit not found)" >&2
fi

exec "$build/tools/fmbench" conformal --sweep "${inputs[@]}" --json "$cache/sweep.json"
