#!/usr/bin/env bash
# Hostile.ToolsHoldTheirLimitsOnEveryFile (issue 46): our own hostile set (hostile_corpus: one file
# per row of the outside review's table and more, every checksum valid) through the tools at their
# default limits: `fminfo FILE` (header, index and checksums), `fminfo --verify --json FILE` (every
# keyframe decoded), `fminfo --field-bytes --json FILE` (every keyframe decoded and coded as the
# writer would) and fmdec at each of the manifest's times (the first written to a mesh, the
# others to --null; the last near the end of the range). Every run must exit 0 with finite output
# (JSON that parses, a mesh without nan or inf), or non-zero with an error on stderr naming the file
# (and, for a file the manifest says is refused, saying what it says in every run that decodes:
# plain fminfo decodes nothing, so it may describe a file whose keyframes are at fault); never by a
# signal or a timeout; within MAX_SECONDS of CPU time (3; fminfo --verify, which decodes every
# keyframe, 3 s and 0.5 s a MB of the file; --field-bytes 3 s and 3.5 s a MB) and a tool's MAX_MB of
# peak resident memory (/usr/bin/time's "Maximum resident set size", MiB): the decode budget a file
# may fill (DecoderLimits' default max_memory_bytes, 256 MiB, spec/container.md §10), plus what the
# tool holds whatever the file (its own allowance: its peak on the 3.9 KB tests/data/golden_v2_5.fmv
# in the runs below, the worst of six, rounded up: fminfo 62.8 MiB, nearly all of it the 178
# libraries it maps, OpenCV and GDAL among them, as --help alone peaks at 60.6 MiB; fmdec 12.3 MiB),
# plus 4 MiB for what differs from run to run (at most 0.4 MiB over the six). So fminfo 323 MiB,
# fmdec 273 MiB; the old 256 MiB a process left fmdec 2.3 MiB on f_n400_rough_fields.fmv (253.7 MiB)
# and left fminfo, its own 62.8 MiB taken, 193 MiB: less than the budget a file may fill. Prints a
# table of every run and the worst time and memory per tool. Exits 77 (skipped) without
# /usr/bin/time, timeout or python3, naming which.
#   hostile_files_test.sh HOSTILE_FILES FMINFO FMDEC WORK_DIR   (HOSTILE_FILES: hostile_corpus's output,
#   written once per test run by the fixture Hostile.FilesAreWritten)
# HOSTILE_MAX_SECONDS and HOSTILE_MAX_MB override the bounds (to measure on a slower machine; the
# memory one for both tools).
set -uo pipefail
files=${1:?usage: hostile_files_test.sh HOSTILE_FILES FMINFO FMDEC WORK_DIR} fminfo=${2:?} fmdec=${3:?} work=${4:?}
budget_mb=256                             # DecoderLimits' default max_memory_bytes
fminfo_own_mb=63 fmdec_own_mb=13 margin_mb=4  # measured as said above
fminfo_max_mb=${HOSTILE_MAX_MB:-$((budget_mb + fminfo_own_mb + margin_mb))}
fmdec_max_mb=${HOSTILE_MAX_MB:-$((budget_mb + fmdec_own_mb + margin_mb))}
max_seconds=${HOSTILE_MAX_SECONDS:-3} max_mb=$fminfo_max_mb  # bounded_run's bound: set per tool below
for tool in /usr/bin/time timeout python3; do
  command -v "$tool" >/dev/null || { echo "SKIPPED: $tool not found"; exit 77; }
done
rm -rf "$work"
mkdir -p "$work"
source "$(dirname "${BASH_SOURCE[0]}")/expect.sh"
source "$(dirname "${BASH_SOURCE[0]}")/bounded_run.sh"

[[ -f $files/manifest.tsv ]] || { echo "FAIL: $files/manifest.tsv: no hostile set there (hostile_corpus writes it)"; exit 1; }

while IFS=$'\t' read -r name times what refused; do
  file=$files/$name
  [[ -f $file ]] || { fail "$name: listed in the manifest, not written"; continue; }
  max_mb=$fminfo_max_mb
  bounded_run "$file" fminfo "$fminfo" "$file"
  for run in --verify --field-bytes; do
    if bounded_run "$file" "fminfo $run --json" "$fminfo" $run --json "$file"; then
      python3 -c 'import json, sys
def finite(text): raise ValueError(text + " in the JSON")
json.load(open(sys.argv[1]), parse_constant=finite)' "$work/out" 2>"$work/json_err" || fail "$name: fminfo $run --json: not JSON: $(tail -1 "$work/json_err")"
    fi
  done
  first=1
  max_mb=$fmdec_max_mb
  for t in ${times//,/ }; do
    if ((first)); then
      rm -f "$work/frame.obj"
      bounded_run "$file" "fmdec --t $t -o" "$fmdec" "$file" --t "$t" -o "$work/frame.obj" --no-texture
      first=0
    else
      bounded_run "$file" "fmdec --t $t --null" "$fmdec" "$file" --fps 30 --from "$t" --to "$t" --null
    fi
    # The mesh's numbers (the run's output checked its own stdout): finite where it was written.
    if [[ -f $work/frame.obj ]] && grep -qiwE 'nan|-?inf(inity)?' "$work/frame.obj"; then
      fail "$name: fmdec --t $t wrote a mesh with a number that is not finite"
    fi
    rm -f "$work/frame.obj"
  done
  # A file refused for what it is (the manifest's fourth column) is refused so by every run that
  # decodes; plain fminfo, if it refuses, says why too.
  if [[ -n $refused ]]; then
    grep -P "^\Q$name\E\t" "$runs" | awk -F'\t' -v what="$refused" '($2 != "fminfo" && $3 == 0) || ($3 != 0 && index($6, what) == 0) { print $2 ": " ($3 == 0 ? "succeeded" : $6) }' >"$work/unrefused"
    [[ -s $work/unrefused ]] && fail "$name: not refused with '$refused': $(head -1 "$work/unrefused")"
  fi
  # Every control decodes.
  if [[ $name == control_* ]] && grep -P "^\Q$name\E\t" "$runs" | cut -f3 | grep -qv '^0$'; then
    fail "$name: a valid file failed: $(grep -P "^\Q$name\E\t" "$runs" | grep -vP '\t0\t' | head -1 | cut -f2,6)"
  fi
done <"$files/manifest.tsv"

max_mb="$fminfo_max_mb (fminfo), $fmdec_max_mb (fmdec)"  # for the report's text only
report_runs "fminfo" "fminfo --verify --json" "fminfo --field-bytes --json" "fmdec"
((failures == 0)) || { echo "$failures failures"; exit 1; }
echo "every run within $max_seconds s and $max_mb MB, refused by name or finite"
