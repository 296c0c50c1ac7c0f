# Shared by the command-line test scripts (sourced after they set `work`, a scratch folder):
# `fail` counts a failure; `expect_error "what" "message fragment" command...` expects a non-zero
# exit with the fragment on stderr.
failures=0
fail() { echo "FAIL: $*" >&2; failures=$((failures + 1)); }
expect_error() {
  local what=$1 fragment=$2
  shift 2
  if "$@" >"$work/out" 2>"$work/err"; then
    fail "$what: succeeded"
  elif ! grep -q -- "$fragment" "$work/err"; then
    fail "$what: stderr lacks '$fragment': $(cat "$work/err")"
  fi
}
