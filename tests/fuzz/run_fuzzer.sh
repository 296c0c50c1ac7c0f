#!/usr/bin/env bash
# Runs a libFuzzer target for a bounded time from the project's seed corpus; new inputs go to a
# temporary folder, never into the source tree. A crash leaves its input in the build folder.
#   run_fuzzer.sh FUZZER SECONDS SEED_DIR...
# FUZZ_RSS_LIMIT_MB and FUZZ_TIMEOUT (seconds per input) override the defaults, 2048 and 10: a target
# whose inputs run under the decoder's limits sets them to match those limits.
set -euo pipefail
fuzzer=$1 seconds=$2
shift 2
corpus=$(mktemp -d)
trap 'rm -rf "$corpus"' EXIT
exec "$fuzzer" -max_total_time="$seconds" -timeout="${FUZZ_TIMEOUT:-10}" -rss_limit_mb="${FUZZ_RSS_LIMIT_MB:-2048}" -max_len=262144 -print_final_stats=1 \
  -artifact_prefix="$(dirname "$fuzzer")/" "$corpus" "$@"
