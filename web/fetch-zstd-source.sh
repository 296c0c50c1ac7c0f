#!/usr/bin/env bash
# Fetches Debian's source of the zstd the native build links (the version of the installed
# libzstd-dev), for the WebAssembly build to compile: web/build.sh calls it. Debian ships no zstd
# built for wasm32, and emscripten's ports would download one at build time, which this project does
# not do. `apt-get source` with a private list of deb-src lines and a private state folder, so the
# machine's apt configuration is not touched. Idempotent: an unpacked tree is kept.
#   web/fetch-zstd-source.sh DIR     unpacks into DIR/zstd (prints the path)
# A mirror can carry a stable update's binaries before (or without) its source. Then this fails,
# naming the version, unless FACEMORPH_ZSTD_OLDER_SOURCE_FOR_TESTS=1: with it, the newest other
# Debian revision of the same upstream release is taken, said on stderr, for a module that only the
# tests load (tests/web/web_module.sh sets it). Never for a player that is shipped: the revision it
# lacks may be a security fix of the decompressor, which reads untrusted files (bookworm's
# 1.5.4+dfsg2-5+deb12u1 is: "information disclosure when decompressing crafted input").
set -euo pipefail
dir=${1:?usage: web/fetch-zstd-source.sh DIR}
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)  # apt reads relative paths from its own folders
version=$(dpkg-query -W -f='${Version}' libzstd-dev 2>/dev/null || true)
[[ -n "$version" ]] || { echo "fetch-zstd-source: libzstd-dev is not installed (tools/install-deps.sh)" >&2; exit 1; }
out="$dir/zstd"
allow_older=${FACEMORPH_ZSTD_OLDER_SOURCE_FOR_TESTS:-0}
# The stamp names the installed version and the source unpacked for it; an older source is reused
# only where it is allowed.
if [[ -f "$out/.facemorph-version" ]]; then
  read -r stamped_for stamped_source < "$out/.facemorph-version" || true
  if [[ "$stamped_for" == "$version" && ( "${stamped_source:-$version}" == "$version" || "$allow_older" == 1 ) ]]; then
    echo "$out"
    exit 0
  fi
fi
mkdir -p "$dir/apt/sources.list.d" "$dir/apt/lists/partial" "$dir/apt/cache/archives/partial" "$dir/download"
. /etc/os-release
cat > "$dir/apt/sources.list" <<SOURCES
deb-src http://deb.debian.org/debian ${VERSION_CODENAME} main
deb-src http://deb.debian.org/debian ${VERSION_CODENAME}-updates main
deb-src http://deb.debian.org/debian-security ${VERSION_CODENAME}-security main
SOURCES
apt_options=(-o "Dir::Etc::SourceList=$dir/apt/sources.list" -o "Dir::Etc::SourceParts=$dir/apt/sources.list.d" -o "Dir::State::Lists=$dir/apt/lists"
             -o "Dir::Cache=$dir/apt/cache" -o "APT::Sandbox::User=root")
apt-get "${apt_options[@]}" update -qq >&2
# The installed version's source; where allowed (above), then the other Debian revisions of the
# same upstream release, newest first.
upstream=${version%-*}
candidates=("$version")
if [[ "$allow_older" == 1 ]]; then
  while read -r other; do
    [[ "$other" != "$version" && "${other%-*}" == "$upstream" ]] && candidates+=("$other")
  done < <(apt-cache "${apt_options[@]}" showsrc libzstd 2>/dev/null | sed -n 's/^Version: //p' | sort -r -V)
fi
fetched=
for candidate in "${candidates[@]}"; do
  rm -rf "$dir/download" && mkdir -p "$dir/download"
  if (cd "$dir/download" && apt-get "${apt_options[@]}" source --download-only "libzstd=$candidate" >&2); then
    fetched=$candidate
    break
  fi
  echo "fetch-zstd-source: Debian's source of libzstd $candidate could not be fetched" >&2
done
if [[ -z "$fetched" ]]; then
  if [[ "$allow_older" == 1 ]]; then
    echo "fetch-zstd-source: no source of zstd $upstream could be fetched (tried ${candidates[*]})" >&2
  else
    echo "fetch-zstd-source: the source of the installed libzstd $version cannot be fetched from the mirror; a player is not built from another revision (it may lack a fix of the decompressor); only the tests may, with FACEMORPH_ZSTD_OLDER_SOURCE_FOR_TESTS=1" >&2
  fi
  exit 1
fi
[[ "$fetched" == "$version" ]] || echo "fetch-zstd-source: FOR TESTS ONLY: the source of $fetched for the installed $version (the same upstream release; the module built from it must not be shipped)" >&2
rm -rf "$out"
dpkg-source -x "$dir/download"/libzstd_*.dsc "$out" >&2
echo "$version $fetched" > "$out/.facemorph-version"
echo "$out"
