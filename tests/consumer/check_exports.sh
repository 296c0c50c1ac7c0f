#!/usr/bin/env bash
# The shared library exports the C API and nothing else: its dynamic symbols are exactly the
# functions facemorph.h declares with FM_API (every one fm_*), and its soname is the API's major
# version, not the project's.
#   check_exports.sh LIBFACEMORPH_DECODER.SO FACEMORPH.H
set -euo pipefail
lib=${1:?usage: check_exports.sh LIB HEADER} header=${2:?}
exported=$(nm -D --defined-only "$lib" | awk '{print $NF}' | sort)
declared=$(grep -oE '^FM_API [^(]*fm_[a-z0-9_]+\(' "$header" | sed -E 's/.*[ *](fm_[a-z0-9_]+)\($/\1/' | sort)
echo "exported: $(wc -l <<<"$exported") symbols"
if grep -v '^fm_' <<<"$exported"; then
  echo "^ exported symbols that are not the C API's (fm_*)" >&2
  exit 1
fi
if [[ "$exported" != "$declared" ]]; then
  diff <(echo "$declared") <(echo "$exported") >&2 || true
  echo "the exported symbols (>) differ from the header's FM_API functions (<)" >&2
  exit 1
fi
soname=$(readelf -d "$lib" | sed -n 's/.*Library soname: \[\(.*\)\]/\1/p')
major=$(sed -n 's/^#define FACEMORPH_API_VERSION_MAJOR \([0-9]*\)$/\1/p' "$header")
if [[ "$soname" != "libfacemorph_decoder.so.$major" ]]; then
  echo "soname $soname; API major version $major: expected libfacemorph_decoder.so.$major" >&2
  exit 1
fi
echo "exports only the C API; soname $soname"
