#!/usr/bin/env bash
# Runs a libFuzzer target for a bounded time from the project's seed corpus; new inputs go to a
# temporary folder, never into the source tree. A crash leaves its input in the build folder.
#   run_fuzzer.sh FUZZER SECONDS SEED_DIR...
set -euo pipefail
fuzzer=$1 seconds=$2
shift 2
corpus=$(mktemp -d)
trap 'rm -rf "$corpus"' EXIT
exec "$fuzzer" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -max_len=262144 -print_final_stats=1 \
  -artifact_prefix="$(dirname "$fuzzer")/" "$corpus" "$@"
