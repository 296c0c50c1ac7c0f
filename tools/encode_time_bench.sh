#!/usr/bin/env bash
# Encode time against an earlier commit (issue 44: "the encode is no slower than today"), with each
# file's bytes and errors beside it. A benchmark, not a test: each round encodes every capture once
# with the baseline's fmenc and once per variant of this tree's, interleaved capture by capture, so
# that a machine that slows down in the middle slows both; the ratios are of the same round. Each
# encode runs with --threads 2 (the CI machine's cores, as issue 44's figures were read).
# Then every file of the last round is measured by this tree's `fmbench --geometry-only`.
#
#   tools/encode_time_bench.sh [BASELINE=3a7ec5d] [ROUNDS=2] [BUILD=build] [DATA=../shared/data]
#                              [CACHE=out/encode-time]
#
# CAPTURES (environment): the captures to run, of fast24 ict2k24 medusa ict24 sample ict60 (all by
# default; those made from DATA are skipped without it, ict2k24 also without Blender), and ict10 and
# ict10_2k: a second of ICT nearly still from 10.0 s and it decimated (stop 80's rate check,
# spec/method.md §7.14 "An error the tolerance does not ask for"), on request.
# VARIANTS (environment): this tree's fmenc flags to time, one variant a line; the default times
# the defaults and `--representation xyz` (no choice by bytes at equal error).
# Captures and the baseline's build are made once into CACHE and reused.
set -euo pipefail
cd "$(dirname "$0")/.."
baseline=${1:-3a7ec5d} rounds=${2:-2} build=${3:-build} data=${4:-../shared/data} cache=${5:-out/encode-time}
captures=${CAPTURES:-fast24 ict2k24 medusa ict24 sample ict60}
variants=${VARIANTS:-$'\n--representation xyz'}
for tool in fmenc fmsynth fmbench; do
  [[ -x "$build/tools/$tool" ]] || { echo "encode_time_bench: $build/tools/$tool is missing (build it first)" >&2; exit 1; }
done
command -v /usr/bin/time > /dev/null || { echo "encode_time_bench: needs /usr/bin/time (Debian's time package)" >&2; exit 1; }
mkdir -p "$cache"
cache=$(cd "$cache" && pwd)

# The captures of spec/method.md §7.10: fast speech at 2k vertices, the quick start's sample, and
# from the shared data ICT's speech (24 frames from 59.0 s; 60 from 58.0 s), the same 24 frames
# decimated to about 2k vertices by Blender's collapse, and the Medusa capture.
make_capture() {
  local name=$1 dir="$cache/$1"
  [[ -f "$dir/capture.json" ]] && return 0
  case $name in
    fast24) "$build/tools/fmsynth" -o "$dir" --frames 25 --fps 24 --expression talk --vertices 2000 --speech-rate 3 --remesh \
              --texture-size 256 --quiet ;;
    sample) "$build/tools/fmsynth" -o "$dir" --frames 60 --fps 30 --expression mixed --quiet ;;
    ict24) python3 "$data/ict-facekit/tools/make_capture.py" "$dir" --start-seconds 59.0 --seconds 0.8 --fps 30 > /dev/null ;;
    ict60) python3 "$data/ict-facekit/tools/make_capture.py" "$dir" --start-seconds 58.0 --seconds 2.0 --fps 30 > /dev/null ;;
    ict10) python3 "$data/ict-facekit/tools/make_capture.py" "$dir" --start-seconds 10.0 --seconds 1.0 --fps 30 > /dev/null ;;
    ict2k24 | ict10_2k)
      local full=ict24  # the capture decimated
      [[ $name == ict10_2k ]] && full=ict10
      make_capture "$full"
      blender -b -P tools/decimate_capture.py -- "$cache/$full" "$dir" 0.221 > "$cache/decimate.log" 2>&1
      cp "$cache/$full/landmarks.csv" "$dir/" ;;
  esac
}
capture_path() {
  if [[ $1 == medusa ]]; then echo "$data/medusa-mediapipe-4d/capture"; else echo "$cache/$1"; fi
}
runnable=()
for c in $captures; do
  case $c in
    fast24 | sample) ;;
    medusa | ict24 | ict60 | ict2k24 | ict10 | ict10_2k)
      if [[ ! -d "$data" ]]; then echo "encode_time_bench: $c skipped: no $data" >&2; continue; fi
      if [[ $c == *2k* ]] && ! command -v blender > /dev/null; then echo "encode_time_bench: $c skipped: no blender" >&2; continue; fi ;;
    *) echo "encode_time_bench: unknown capture $c" >&2; exit 1 ;;
  esac
  make_capture "$c"
  runnable+=("$c")
done

# The baseline's fmenc, built once in a worktree of its own.
base_tree="$cache/baseline-$baseline"
if [[ ! -x "$base_tree/build/tools/fmenc" ]]; then
  [[ -d "$base_tree" ]] || git worktree add --detach "$base_tree" "$baseline" > /dev/null
  cmake -S "$base_tree" -B "$base_tree/build" -G Ninja -DCMAKE_BUILD_TYPE=Release > "$cache/baseline-cmake.log"
  echo "encode_time_bench: building $baseline's fmenc (minutes)" >&2
  cmake --build "$base_tree/build" -j "$(nproc)" --target fmenc > "$cache/baseline-build.log"
fi

# Rows: round capture encoder user sys wall peak-kB bytes file.
results="$cache/times.tsv"
: > "$results"
time_one() {  # round capture label fmenc flags...
  local round=$1 c=$2 label=$3 fmenc=$4
  shift 4
  local out
  out="$cache/files/$c.$(echo "$label" | tr -c 'a-z0-9' '_').fmv"
  mkdir -p "$cache/files"
  /usr/bin/time -o "$cache/time.txt" -f '%U %S %e %M' "$fmenc" "$(capture_path "$c")" -o "$out" --threads 2 --quiet "$@" > /dev/null 2> "$cache/fmenc.err" ||
    { echo "encode_time_bench: $label on $c failed:" >&2; cat "$cache/fmenc.err" >&2; exit 1; }
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$round" "$c" "$label" "$(tr ' ' '\t' < "$cache/time.txt")" "$(stat -c %s "$out")" "$out" >> "$results"
}
for round in $(seq "$rounds"); do
  for c in "${runnable[@]}"; do
    echo "encode_time_bench: round $round, $c" >&2
    time_one "$round" "$c" "$baseline" "$base_tree/build/tools/fmenc"
    while IFS= read -r flags; do
      # shellcheck disable=SC2086  # the flags are words
      time_one "$round" "$c" "today ${flags:-(defaults)}" "$build/tools/fmenc" $flags
    done <<< "$variants"
  done
done

# Each file of the last round: held-out RMS (mean, worst) and the worst frame's 99th percentile.
errors="$cache/errors.tsv"
: > "$errors"
while IFS=$'\t' read -r round c label _ _ _ _ bytes file; do
  [[ $round == "$rounds" ]] || continue
  line=$("$build/tools/fmbench" --capture "$(capture_path "$c")" --fmv "$file" --geometry-only --quiet | grep 'held-out') ||
    { echo "encode_time_bench: fmbench could not measure $file" >&2; exit 1; }
  printf '%s\t%s\t%s\t%s\n' "$c" "$label" "$bytes" "$line" >> "$errors"
done < "$results"

python3 - "$results" "$errors" "$baseline" << 'EOF'
import collections, re, sys
results, errors, baseline = sys.argv[1:4]
runs = collections.defaultdict(dict)  # (round, capture) -> label -> (cpu, wall, peak MB)
for line in open(results):
    r, c, label, user, sys_, wall, peak, _, _ = line.rstrip("\n").split("\t")
    runs[(r, c)][label] = (float(user) + float(sys_), float(wall), int(peak) // 1024)
measured = {}
for line in open(errors):
    c, label, size, text = line.rstrip("\n").split("\t")
    m = re.search(r"held-out RMS ([\d.]+)% mean, ([\d.]+)% worst.*99th percentile ([\d.]+)% worst frame", text)
    measured[(c, label)] = (int(size),) + (tuple(float(x) for x in m.groups()) if m else (float("nan"),) * 3)
print("| capture | encoder | CPU s (each round) | CPU ratio | wall ratio | peak MB | bytes | held-out RMS mean / worst % | worst p99 % |")
print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
captures = list(dict.fromkeys(c for _, c in runs))
for c in captures:
    rounds = sorted((r for r, cc in runs if cc == c), key=int)  # round 10 after round 9
    labels = list(runs[(rounds[0], c)])
    for label in labels:
        cpu = [runs[(r, c)][label][0] for r in rounds]
        cpu_ratio = [runs[(r, c)][label][0] / runs[(r, c)][baseline][0] for r in rounds]
        wall_ratio = [runs[(r, c)][label][1] / runs[(r, c)][baseline][1] for r in rounds]
        peak = max(runs[(r, c)][label][2] for r in rounds)
        size, mean, worst, p99 = measured.get((c, label), (0, float("nan"), float("nan"), float("nan")))
        span = lambda v: f"{min(v):.2f}" if f"{min(v):.2f}" == f"{max(v):.2f}" else f"{min(v):.2f}-{max(v):.2f}"
        print(f"| {c} | {label} | {', '.join(f'{x:.2f}' for x in cpu)} | {span(cpu_ratio)} | {span(wall_ratio)} | {peak} | "
              f"{size:,} | {mean:.4f} / {worst:.4f} | {p99:.4f} |")
EOF
