#!/usr/bin/env bash
# Web.HostileFilesHoldTheirLimits (issue 46): our own hostile set (hostile_corpus) through the
# WebAssembly decoder under node at its default limits (web/test/hostile.mjs: open, info, keyframe
# times, a decoder, one decode call at one of the manifest's times, a process a time). Every file must decode to
# finite positions or be refused by a FacemorphError (its status name and the library's message,
# saying what the manifest says for a file every run must refuse); never a trap, an abort or a hang;
# each node process within 3 s of CPU time (node --single-threaded: no compiler or collector thread
# of its own adds to it; wall time measured the load, 5.9 s for 2.6 s of CPU beside a build) and 320 MiB of peak resident memory (the default budget of 256 MiB and node's own
# ~60 MiB), as the tools are held (tests/tools/hostile_files_test.sh). Builds the module first (web/build.sh,
# incremental). Exits 77 (skipped) without emcc, node, /usr/bin/time or timeout, naming which.
#   tests/web/hostile.sh HOSTILE_FILES WORK_DIR   (HOSTILE_FILES: hostile_corpus's output, written
#   once per test run by the fixture Hostile.FilesAreWritten)
# HOSTILE_MAX_SECONDS and HOSTILE_MAX_MB override the bounds.
set -uo pipefail
files=${1:?usage: hostile.sh HOSTILE_FILES WORK_DIR} work=${2:?}
max_seconds=${HOSTILE_MAX_SECONDS:-3} max_mb=${HOSTILE_MAX_MB:-320}
root=$(cd "$(dirname "$0")/../.." && pwd)
for tool in /usr/bin/time timeout; do
  command -v "$tool" >/dev/null || { echo "SKIPPED: $tool not found"; exit 77; }
done
source "$root/tests/web/web_module.sh"
web_module "$work"
source "$root/tests/tools/expect.sh"
source "$root/tests/tools/bounded_run.sh"

[[ -f $files/manifest.tsv ]] || { echo "FAIL: $files/manifest.tsv: no hostile set there (hostile_corpus writes it)"; exit 1; }

while IFS=$'\t' read -r name times what refused; do
  file=$files/$name
  [[ -f $file ]] || { fail "$name: listed in the manifest, not written"; continue; }
  # One process a time, as the tools run (tests/tools/hostile_files_test.sh): the module's memory
  # never shrinks, so each call's peak is its own.
  for t in ${times//,/ }; do
    bounded_run "$file" "wasm --t $t" node --single-threaded "$root/web/test/hostile.mjs" "$file" "$t"
    status=$?
    ((status == 2)) && fail "$name: t = $t s: the module crashed: $(grep -m1 CRASH "$work/err" | cut -c1-300)"
    if [[ -n $refused ]] && { ((status == 0)) || ! grep -qF -- "$refused" "$work/err"; }; then
      fail "$name: t = $t s: not refused with '$refused': $(head -c 300 "$work/err")"
    fi
    if [[ $name == control_* ]] && ((status != 0)); then fail "$name: a valid file failed: $(head -c 300 "$work/err")"; fi
  done
done <"$files/manifest.tsv"

report_runs wasm
((failures == 0)) || { echo "$failures failures"; exit 1; }
echo "every file within $max_seconds s and $max_mb MB in the WebAssembly decoder, refused by name or finite"
