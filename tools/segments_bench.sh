#!/usr/bin/env bash
# Segments against the one-process assemble stage (spec/method.md §7.17): the same parts assembled
# both ways on this machine, each segment's stages one after the other, timed; then how far the
# joined file decodes from the one-process file and from the capture (fmbench --geometry-only
# --against). A benchmark, not a test: minutes on a long capture. The parts are sampled into OUT
# once (one part of every frame) unless PARTS names a folder of them.
#
#   tools/segments_bench.sh CAPTURE N OUT [PARTS] [-- fmenc options]
#   e.g. tools/segments_bench.sh /tmp/ict2000 4 out/seg-ict
#        tools/segments_bench.sh ../shared/data/medusa-mediapipe-4d/capture 3 out/seg-medusa "" -- --intra-period 4
set -euo pipefail
capture=${1:?usage: segments_bench.sh CAPTURE N OUT [PARTS] [-- fmenc options]} n=${2:?} out=${3:?} parts=${4:-}
shift $(( $# < 4 ? $# : 4 ))
[[ ${1:-} == -- ]] && shift
options=("$@")
bin=$(cd "$(dirname "$0")/.." && pwd)/build/tools
mkdir -p "$out"
out=$(cd "$out" && pwd)
timed() {  # timed LABEL COMMAND...: one line "LABEL SECONDS s PEAK kB" in times
  /usr/bin/time -f "$1 %e s %M kB" -a -o "$out/times" "${@:2}"
}
: >"$out/times"
if [[ -z $parts ]]; then
  parts=$out/parts
  mkdir -p "$parts"
  [[ -s $parts/all.fms ]] || timed "sample" "$bin/fmenc" "$capture" --stage sample --frames 0:1000000 -o "$parts/all.fms" -q --threads 2 "${options[@]}"
fi
timed "one-process assemble" "$bin/fmenc" --stage assemble "$parts"/*.fms -o "$out/one.fmv" -q --threads 2 "${options[@]}"
measures=""
for ((s = 0; s < n; s++)); do
  timed "measure $s/$n" "$bin/fmenc" --stage measure "$parts"/*.fms --segment "$s/$n" -o "$out/measure_$s.json" --threads 2 "${options[@]}" >>"$out/stages.out"
  measures+="$out/measure_$s.json,"
done
for ((s = 0; s < n; s++)); do
  timed "segment $s/$n" "$bin/fmenc" --stage assemble "$parts"/*.fms --segment "$s/$n" --measures "${measures%,}" -o "$out/segment_$s.fmv" \
    --threads 2 "${options[@]}" >>"$out/stages.out"
done
timed "fmcat" "$bin/fmcat" "$out"/segment_*.fmv -o "$out/joined.fmv" -q
"$bin/fmbench" --capture "$capture" --fmv "$out/joined.fmv" --geometry-only --quiet --against "$out/one.fmv" >>"$out/times"
"$bin/fmbench" --capture "$capture" --fmv "$out/one.fmv" --geometry-only --quiet >>"$out/times"
cat "$out/times"
grep -h "reading the parts" "$out/stages.out"
