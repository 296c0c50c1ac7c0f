# Shared by the hostile-file scripts (tests/tools/hostile_files_test.sh, tests/web/hostile.sh),
# sourced after expect.sh and after they set `work` (a scratch folder), `max_seconds` and `max_mb`:
#   bounded_run FILE TOOL COMMAND...   runs COMMAND under timeout and /usr/bin/time and adds a row
#     (file, tool, status, seconds, MB, first line of stderr) to $runs. `fail`s where the run was
#     killed (a signal, or a timeout: a hang), failed without naming FILE on stderr, succeeded with
#     "nan" or "inf" in its output, or took more than max_seconds or max_mb (MiB) of peak resident
#     memory. Seconds are the process's CPU time (user + system; the tools decode on one thread):
#     the tests run beside others on 2 cores, where wall time measured the load (CI's 3.96 s for a
#     2.6 s decode), not the file (node's too: 5.9 s of wall time for 2.6 s of CPU beside a build).
#     A hang still shows: timeout kills on wall time. Node runs with --single-threaded
#     (tests/web/hostile.sh), so that no compiler or collector thread of its own adds to it.
#     Returns the command's status. Its stdout and stderr stay in $work/out and $work/err.
#   report_runs TOOL...                prints every row, then the worst time and memory of each
#     TOOL (its rows: those of that tool, or of it with --t T and more).
runs=$work/runs.tsv
: >"$runs"
bounded_run() {
  local file=$1 tool=$2
  shift 2
  local name status seconds kb mb message
  name=$(basename "$file")
  # fminfo --verify decodes every keyframe of the file (spec/container.md §10.5): its time may grow
  # with the file's bytes, at max_seconds_per_mb (0.5 s a MB: the 11 MB, 400-keyframe N = 257 file
  # took 5 s on 2 loaded cores), never with what a small file only states. fminfo --field-bytes
  # decodes them as --verify does and codes each as the writer would, trying its four predictors from
  # nothing and from the keyframe before: seven times --verify's rate (that file: 21.4 s against
  # 3.2 s of CPU). Every decode, and plain fminfo (checksums only), is bounded alone.
  local bound=$max_seconds rate=0
  if [[ $tool == "fminfo --verify"* ]]; then
    rate=${max_seconds_per_mb:-0.5}
  elif [[ $tool == "fminfo --field-bytes"* ]]; then
    rate=$(awk -v r="${max_seconds_per_mb:-0.5}" 'BEGIN { print 7 * r }')
  fi
  bound=$(awk -v s="$max_seconds" -v b="$(stat -c %s "$file")" -v r="$rate" 'BEGIN { printf "%.2f", s + r * b / 1048576 }')
  # Killed well past the bound, so that a hang shows as a timeout, not as a stuck test.
  /usr/bin/time -f "%e %U %S %M" -o "$work/time" timeout -k 2 "$(awk -v b="$bound" 'BEGIN { printf "%d", 4 * b + 5 }')" "$@" >"$work/out" 2>"$work/err"
  status=$?
  local user system
  read -r _ user system kb < <(tail -1 "$work/time")
  seconds=$(awk -v u="${user:-0}" -v s="${system:-0}" 'BEGIN { printf "%.2f", u + s }')
  mb=$(awk -v kb="${kb:-0}" 'BEGIN { printf "%.1f", kb / 1024 }')
  message=$(grep -v '^$' "$work/err" | head -1)
  printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$name" "$tool" "$status" "$seconds" "$mb" "$message" >>"$runs"
  if ((status == 124 || status >= 128)); then
    fail "$name: $tool: killed (status $status, $( ((status == 124)) && echo "a timeout" || echo "signal $((status - 128))")): $(head -c 600 "$work/err")"
  elif ((status != 0)); then
    grep -qF -- "$name" "$work/err" || fail "$name: $tool: exit $status without naming the file: $(head -c 600 "$work/err")"
  elif grep -qiwE 'nan|-?inf(inity)?' "$work/out"; then
    fail "$name: $tool: succeeded with a number that is not finite: $(grep -iwE -m1 'nan|-?inf(inity)?' "$work/out" | cut -c1-200)"
  fi
  if awk -v s="${seconds:-0}" -v max="$bound" 'BEGIN { exit !(s > max) }'; then fail "$name: $tool: $seconds s, over $bound s"; fi
  if awk -v m="$mb" -v max="$max_mb" 'BEGIN { exit !(m > max) }'; then fail "$name: $tool: $mb MB, over $max_mb MB"; fi
  return "$status"
}

report_runs() {
  {
    printf 'file\ttool\tstatus\tseconds\tMB\tmessage\n'
    cat "$runs"
  } | column -t -s $'\t' | cut -c1-250
  echo
  echo "worst per tool, of $(wc -l <"$runs") runs (bounds $max_seconds s of CPU time, $max_mb MB):"
  local tool
  for tool in "$@"; do
    awk -F'\t' -v tool="$tool" '
      $2 == tool || index($2, tool " --t ") == 1 {
        if ($4 + 0 >= s) { s = $4 + 0; sf = $1 }
        if ($5 + 0 >= m) { m = $5 + 0; mf = $1 }
      }
      END { printf "  %-14s %6.2f s (%s)   %7.1f MB (%s)\n", tool, s, sf, m, mf }' "$runs"
  done
}
