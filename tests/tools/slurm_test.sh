#!/usr/bin/env bash
# The cluster encode on a real Slurm cluster of one node (slurm_cluster.sh): tools/slurm/fmenc-slurm
# encodes a small fmsynth capture as an array of sample tasks and an assemble job, one task is
# killed while it runs and must be named and retried, a rerun after a part was lost and another
# damaged submits those two only, and a library of two captures is one array. Every file must be the
# one-process encode's bytes; assembled as segments (--segments 3), the file must be the segmented
# encode's run here. Skips (77) by name where Slurm is not installed.
#   slurm_test.sh TOOLS_DIR
set -uo pipefail
tools=${1:?usage: slurm_test.sh TOOLS_DIR}
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
slurm=$here/../../tools/slurm/fmenc-slurm
source "$here/slurm_cluster.sh"
if ! slurm_cluster_available; then
  echo "SKIPPED: Slurm.ClusterEncode needs slurmctld, slurmd, sbatch (slurm-wlm) and munged (munge), run as root; tools/install-deps.sh installs them"
  exit 77
fi
work=$(mktemp -d)
source "$here/expect.sh"
cleanup() {
  slurm_cluster_stop
  rm -rf "$work"
}
trap cleanup EXIT
slurm_cluster_start "$work/cluster" 2 || { echo "FAIL: the cluster did not start"; tail -20 "$work/cluster/log/"*.log; exit 1; }

options=(--grid 33 --texture 64 --keyframes 25%)
"$tools/fmsynth" -o "$work/lib/talk" --frames 30 --fps 30 --vertices 2500 --remesh --texture-size 64 --expression talk --seed 5 --quiet || fail "fmsynth talk"
"$tools/fmsynth" -o "$work/lib/smile" --frames 14 --fps 30 --vertices 2500 --remesh --texture-size 64 --expression mixed --seed 9 --quiet || fail "fmsynth smile"
for c in talk smile; do
  "$tools/fmenc" "$work/lib/$c" -o "$work/$c.one.fmv" "${options[@]}" --quiet || fail "fmenc $c"
done

# Waits (at most $2 seconds) until file $1 exists.
wait_for() {
  local i
  for ((i = 0; i < $2 * 5; i++)); do
    [[ -s $1 ]] && return 0
    sleep 0.2
  done
  return 1
}

# 1. A capture in 6 tasks; the first task seen running is killed (scancel) and must be retried.
"$slurm" "$work/lib/talk" -o "$work/talk.fmv" --frames-per-task 5 --fmenc "$tools/fmenc" --quiet -- "${options[@]}" || fail "fmenc-slurm submitted nothing"
killed=""
for ((i = 0; i < 300; i++)); do
  killed=$(squeue -h -t RUNNING -n fmenc-sample -o '%i' | head -1)
  [[ -n $killed ]] && break
  sleep 0.1
done
[[ -n $killed ]] && scancel "$killed" || fail "no sample task was seen running to kill"
wait_for "$work/talk.fmv" 300 || fail "the capture was not encoded after a task was killed: $("$slurm" --status "$work/talk.fmv.slurm")"
cmp -s "$work/talk.fmv" "$work/talk.one.fmv" || fail "the cluster encode differs from the one-process encode"
grep -q "round 1: task .*no valid part" "$work/talk.fmv.slurm/failures.log" 2>/dev/null || fail "the killed task was not named: $(cat "$work/talk.fmv.slurm/failures.log" 2>/dev/null)"
grep -q "^2 sample" "$work/talk.fmv.slurm/jobs" || fail "the killed task was not retried in a second round"
status=$("$slurm" --status "$work/talk.fmv.slurm")
grep -q "parts: 6 of 6 written (30 of 30 frames); files: 1 of 1 assembled" <<<"$status" || fail "--status: $status"

# 2. Resume: a part lost, another damaged, the file gone: the rerun submits those two tasks only.
parts=("$work"/talk.fmv.slurm/parts/talk/*.fms)
rm "${parts[2]}"
printf 'damaged' | dd of="${parts[5]}" bs=1 seek=3000 conv=notrunc status=none
rm "$work/talk.fmv"
"$slurm" "$work/lib/talk" -o "$work/talk.fmv" --frames-per-task 5 --fmenc "$tools/fmenc" -- "${options[@]}" >"$work/resume" || fail "the rerun failed"
grep -q "round [0-9]*: 2 sample tasks, 1 assemble jobs" "$work/resume" || fail "the rerun did not submit the two missing parts only: $(cat "$work/resume")"
wait_for "$work/talk.fmv" 300 || fail "the rerun did not encode the capture"
cmp -s "$work/talk.fmv" "$work/talk.one.fmv" || fail "the resumed encode differs from the one-process encode"

# 3. A library of two captures: one array over both, an assemble job each.
"$slurm" "$work/lib" -o "$work/libout" --frames-per-task 6 --fmenc "$tools/fmenc" --wait --quiet -- "${options[@]}" || fail "the library encode failed"
for c in talk smile; do
  cmp -s "$work/libout/$c.fmv" "$work/$c.one.fmv" || fail "the library's $c differs from its one-process encode"
done
[[ $(grep -c "sample" "$work/libout/.slurm/jobs") -eq 1 ]] || fail "the library was not one array: $(cat "$work/libout/.slurm/jobs")"

# 4. Segments: the capture assembled as 3 segments (a measure array, a segment array, the join),
# which must be what the same stages make on this machine, byte for byte.
segmented=("${options[@]}" --intra-period 2)
"$tools/fmenc" "$work/lib/talk" --stage sample --frames 0:30 -o "$work/talk.fms" "${segmented[@]}" --quiet || fail "local sample stage"
for s in 0 1 2; do
  "$tools/fmenc" --stage measure "$work/talk.fms" --segment "$s/3" -o "$work/measure_$s.json" "${segmented[@]}" --quiet || fail "local measure $s"
done
for s in 0 1 2; do
  "$tools/fmenc" --stage assemble "$work/talk.fms" --segment "$s/3" --measures "$work/measure_0.json,$work/measure_1.json,$work/measure_2.json" \
    -o "$work/segment_$s.fmv" "${segmented[@]}" --quiet || fail "local segment $s"
done
"$tools/fmcat" "$work"/segment_*.fmv -o "$work/talk.segmented.fmv" --quiet || fail "local fmcat"
"$slurm" "$work/lib/talk" -o "$work/talk3.fmv" --frames-per-task 10 --segments 3 --fmenc "$tools/fmenc" --wait --quiet -- "${segmented[@]}" ||
  fail "the segmented cluster encode failed: $(tail -3 "$work"/talk3.fmv.slurm/logs/*.log)"
cmp -s "$work/talk3.fmv" "$work/talk.segmented.fmv" || fail "the cluster's segmented encode differs from the same stages run here"
for stage in measure segment join; do
  grep -q "^1 $stage " "$work/talk3.fmv.slurm/jobs" || fail "no $stage job: $(cat "$work/talk3.fmv.slurm/jobs")"
done
[[ $(ls "$work"/talk3.fmv.slurm/segments/0/segment_*.fmv | wc -l) -eq 3 ]] || fail "not 3 segment files"

# 5. A task that always fails: retried --retries times, then named and given up, exit 1.
cat >"$work/failing-fmenc" <<SCRIPT
#!/usr/bin/env bash
[[ " \$* " == *" --stage sample "* && " \$* " == *" 0:5 "* ]] && { echo "no disk left (simulated)"; exit 3; }
exec "$tools/fmenc" "\$@"
SCRIPT
chmod +x "$work/failing-fmenc"
"$slurm" "$work/lib/smile" -o "$work/fails.fmv" --frames-per-task 5 --retries 1 --fmenc "$work/failing-fmenc" --wait --quiet -- "${options[@]}" 2>"$work/fails.err"
[[ $? -eq 1 ]] || fail "a task that always fails did not end fmenc-slurm with exit 1"
[[ $(grep -c "frames 0:5 .*last said: no disk left (simulated)" "$work/fails.fmv.slurm/failures.log") -eq 2 ]] ||
  fail "the failing task was not named once per round (2 rounds with --retries 1): $(cat "$work/fails.fmv.slurm/failures.log")"
grep -q "gave up" "$work/fails.err" || fail "fmenc-slurm --wait did not say it gave up: $(cat "$work/fails.err")"
[[ ! -e $work/fails.fmv ]] || fail "a file was written though a part is missing"

# 6. What fmenc-slurm refuses before submitting anything.
expect_error "a missing capture" "not a folder" "$slurm" "$work/none" -o "$work/x.fmv"
expect_error "a bad task size" "--frames-per-task" "$slurm" "$work/lib/talk" -o "$work/x.fmv" --frames-per-task 0
expect_error "threads among the fmenc options" "--threads is set per task" "$slurm" "$work/lib/talk" -o "$work/x.fmv" -- --threads 2
expect_error "a segment among the fmenc options" "fmenc-slurm's to set" "$slurm" "$work/lib/talk" -o "$work/x.fmv" -- --segment 0/2
expect_error "a bad segment count" "--segments" "$slurm" "$work/lib/talk" -o "$work/x.fmv" --segments 0
expect_error "tracking" "track" "$tools/fmenc" "$work/lib/talk" --stage sample --frames 0:4 -o "$work/x.fms" --track-landmarks
[[ ! -e $work/x.fms ]] || fail "a refused sample stage left a part"

((failures == 0)) && echo "slurm_test: all passed"
exit $((failures > 0))
