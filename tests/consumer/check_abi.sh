#!/usr/bin/env bash
# The ABI of the freshly built shared library against the API 1.0 baseline (abidw's XML of
# libfacemorph_decoder.so.1 as 1.0 shipped it, tests/consumer/api-1.0/libfacemorph_decoder.abi):
# abidiff (libabigail) must find no change, beyond functions added (the only change a 1.x may make
# besides appending enum values and struct fields past struct_size, which abidiff reports — so a
# 1.x that appends regenerates the baseline with --update after its own review: spec/api.md §5).
# The baseline holds only the API's own types (api-1.0/public.supp). Exits 77 (skipped) when abidiff is
# not installed.
# --strict compares without growth.supp: for the newest minor's baseline, since which nothing may
# have grown (growth.supp would let any change to a struct it names pass, a retyped field too).
#   check_abi.sh LIB BASELINE [--update | --strict]
set -euo pipefail
lib=${1:?usage: check_abi.sh LIB BASELINE [--update | --strict]} baseline=${2:?} update=${3:-}
suppressions=$(dirname "$baseline")/public.supp
if ! command -v abidiff >/dev/null || ! command -v abidw >/dev/null; then
  echo "abidiff not found (Debian: abigail-tools): ABI check skipped"
  exit 77
fi
if [[ $update == --update ]]; then
  abidw --no-corpus-path --no-comp-dir-path --suppressions "$suppressions" --out-file "$baseline" "$lib"
  echo "wrote $baseline"
  exit 0
fi
status=0
# growth.supp: the appending of fields that the struct_size rule allows (spec/api.md §8).
growth=(--suppressions "$(dirname "$0")/growth.supp")
[[ $update == --strict ]] && growth=()
abidiff --no-added-syms "${growth[@]}" "$baseline" "$lib" || status=$?
# abidiff's status is a bit field: 1 error, 2 usage, 4 an ABI change, 8 an incompatible one.
if ((status != 0)); then
  echo "abidiff: status $status: the ABI of $lib is not API 1.0's (${baseline})" >&2
  exit 1
fi
echo "ABI unchanged from the baseline"
