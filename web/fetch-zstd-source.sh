#!/usr/bin/env bash
# Fetches Debian's source of the zstd the native build links (the version of the installed
# libzstd-dev), for the WebAssembly build to compile: web/build.sh calls it. Debian ships no zstd
# built for wasm32 (where the mirror lacks the installed revision's source: the same upstream release's
# other revision, below), and emscripten's ports would download one at build time, which this project does
# not do. `apt-get source` with a private list of deb-src lines and a private state folder, so the
# machine's apt configuration is not touched. Idempotent: an unpacked tree is kept.
#   web/fetch-zstd-source.sh DIR     unpacks into DIR/zstd (prints the path)
set -euo pipefail
dir=${1:?usage: web/fetch-zstd-source.sh DIR}
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)  # apt reads relative paths from its own folders
version=$(dpkg-query -W -f='${Version}' libzstd-dev 2>/dev/null || true)
[[ -n "$version" ]] || { echo "fetch-zstd-source: libzstd-dev is not installed (tools/install-deps.sh)" >&2; exit 1; }
out="$dir/zstd"
if [[ -f "$out/.facemorph-version" && "$(cat "$out/.facemorph-version")" == "$version" ]]; then
  echo "$out"
  exit 0
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
# The installed version's source first. A mirror can carry a stable update's binaries before (or
# without) its source: then the newest other Debian revision of the same upstream release, whose
# library reads and writes the same frames (a Debian revision patches packaging and security fixes,
# not the format), said on stderr.
upstream=${version%-*}
candidates=("$version")
while read -r other; do
  [[ "$other" != "$version" && "${other%-*}" == "$upstream" ]] && candidates+=("$other")
done < <(apt-cache "${apt_options[@]}" showsrc libzstd 2>/dev/null | sed -n 's/^Version: //p' | sort -r -V)
fetched=
for candidate in "${candidates[@]}"; do
  rm -rf "$dir/download" && mkdir -p "$dir/download"
  if (cd "$dir/download" && apt-get "${apt_options[@]}" source --download-only "libzstd=$candidate" >&2); then
    fetched=$candidate
    break
  fi
  echo "fetch-zstd-source: Debian's source of libzstd $candidate could not be fetched" >&2
done
[[ -n "$fetched" ]] || { echo "fetch-zstd-source: no source of zstd $upstream could be fetched (tried ${candidates[*]})" >&2; exit 1; }
[[ "$fetched" == "$version" ]] || echo "fetch-zstd-source: using the source of $fetched for the installed $version (the same upstream release)" >&2
rm -rf "$out"
dpkg-source -x "$dir/download"/libzstd_*.dsc "$out" >&2
echo "$version" > "$out/.facemorph-version"
echo "$out"
