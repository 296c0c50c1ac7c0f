#!/usr/bin/env bash
# The consumer test (model: zstd's build/cmake/tests/consumer): install facemorph from BUILD_DIR into
# a fresh prefix, build tests/consumer/consumer.c against the installed package twice — through
# CMake (find_package(facemorph) -> facemorph::decoder) and through pkg-config (facemorph.pc) — and
# run both on FILE.fmv at t = 0.2, which must print the vertex count.
#   run_consumer_test.sh BUILD_DIR WORK_DIR FILE.fmv EXPECTED_VERTICES [CMAKE_GENERATOR]
set -euo pipefail
build=${1:?usage: run_consumer_test.sh BUILD_DIR WORK_DIR FILE.fmv EXPECTED_VERTICES [GENERATOR]}
work=${2:?} file=${3:?} expected=${4:?} generator=${5:-}
here=$(cd "$(dirname "$0")" && pwd)
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix

echo "== cmake --install $build --prefix $prefix"
cmake --install "$build" --prefix "$prefix" >"$work/install.log"
# Only the decoder's headers: never an encoder header, never the format room's.
test -f "$prefix/include/facemorph.h" && test -f "$prefix/include/facemorph/decoder.hpp"
if find "$prefix/include" -path '*encoder*' | grep -q .; then echo "an encoder header was installed" >&2; exit 1; fi

check() {  # check NAME OUTPUT
  echo "$2"
  if ! grep -q "t = 0.200 s: $expected vertices" <<<"$2"; then
    echo "$1: expected \"t = 0.200 s: $expected vertices\"" >&2
    exit 1
  fi
}

echo "== CMake: find_package(facemorph) -> facemorph::decoder"
cmake -S "$here" -B "$work/cmake-build" ${generator:+-G "$generator"} -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$prefix" >"$work/configure.log" || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/cmake-build" >"$work/build.log" || { cat "$work/build.log"; exit 1; }
check cmake "$("$work/cmake-build/consumer" "$file" 0.2)"

echo "== pkg-config: cc consumer.c \$(pkg-config --cflags --libs facemorph)"
pcdir=$(dirname "$(find "$prefix" -name facemorph.pc -print -quit)")
flags=$(PKG_CONFIG_PATH=$pcdir pkg-config --cflags --libs facemorph)
echo "   flags: $flags"
# shellcheck disable=SC2086  # the flags are words
"${CC:-cc}" -std=c99 -Wall -Wextra -pedantic -Werror "$here/consumer.c" $flags -o "$work/consumer-pc"
# A shared decoder is found next to the install, as a system install finds it in its library path.
check pkg-config "$(LD_LIBRARY_PATH=$pcdir/..${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH} "$work/consumer-pc" "$file" 0.2)"
echo "consumer test passed"
