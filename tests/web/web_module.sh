# Sourced by the web tests (exactness.sh, stream.sh, browser.sh): the tools they need and the
# WebAssembly module they test, built by web/build.sh (incremental after the first time).
#   web_module WORK_DIR    exits 77 (skipped) without emcc or node, saying which; 1 if the build fails
web_module() {
  local work=$1 root
  root=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
  local tool
  for tool in emcc node; do
    command -v "$tool" >/dev/null || { echo "SKIPPED: $tool not found (tools/install-deps.sh installs it)"; exit 77; }
  done
  mkdir -p "$work"
  # The module is the tests' own: where the mirror lacks the installed zstd's source, an older
  # revision of the same release will do for them (web/fetch-zstd-source.sh; never for a player).
  FACEMORPH_ZSTD_OLDER_SOURCE_FOR_TESTS=1 "$root/web/build.sh" "${FACEMORPH_WEB_BUILD:-$root/build-web}" > "$work/build.log" 2>&1 || { tail -30 "$work/build.log"; exit 1; }
}
