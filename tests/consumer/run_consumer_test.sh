#!/usr/bin/env bash
# The consumer test (model: zstd's build/cmake/tests/consumer): install facemorph from BUILD_DIR into
# a fresh prefix (one install holds both kinds of library), then build a C program (consumer.c, C99)
# and a C++ one (consumer.cpp, as C++17 and as C++20) against the installed package, each against
# the shared and the static library, through CMake (find_package(facemorph) -> facemorph::decoder,
# facemorph::decoder_static: one configure for all six) and through pkg-config (facemorph.pc,
# facemorph-static.pc), and run all twelve on FILE.fmv at t = 0.2: each must print the vertex count.
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
# The player's two headers and nothing else: no internal header, no encoder header.
headers=$(cd "$prefix/include" && find . -type f | sort | tr '\n' ' ')
if [[ "$headers" != "./facemorph.h ./facemorph/decoder.hpp " ]]; then
  echo "installed headers: $headers; expected ./facemorph.h ./facemorph/decoder.hpp" >&2
  exit 1
fi
libdir=$(dirname "$(find "$prefix" -name libfacemorph_decoder.a -print -quit)")
kinds=static
if [[ -e $libdir/libfacemorph_decoder.so.1 ]]; then kinds="shared static"; fi

check() {  # check NAME KIND PROGRAM
  local output
  if ! output=$(LD_LIBRARY_PATH=$libdir${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH} "$3" "$file" 0.2); then
    echo "$1: $3 failed" >&2
    exit 1
  fi
  echo "   $1: $output"
  if ! grep -q "t = 0.200 s: $expected vertices" <<<"$output"; then
    echo "$1: expected \"t = 0.200 s: $expected vertices\"" >&2
    exit 1
  fi
  # The shared programs load libfacemorph_decoder.so.1; the static ones hold the decoder.
  if readelf -d "$3" | grep -q 'NEEDED.*libfacemorph_decoder\.so\.1'; then
    [[ $2 == shared ]] || { echo "$1: a static program needs libfacemorph_decoder.so.1" >&2; exit 1; }
  else
    [[ $2 == static ]] || { echo "$1: a shared program does not load libfacemorph_decoder.so.1" >&2; exit 1; }
  fi
}

echo "== CMake: find_package(facemorph) -> facemorph::decoder (shared), facemorph::decoder_static"
cmake -S "$here" -B "$work/cmake-build" ${generator:+-G "$generator"} -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$prefix" >"$work/configure.log" || { cat "$work/configure.log"; exit 1; }
cmake --build "$work/cmake-build" -j 2 >"$work/build.log" || { cat "$work/build.log"; exit 1; }
for kind in $kinds; do
  for program in c cxx17 cxx20; do check "cmake $program $kind" "$kind" "$work/cmake-build/consumer_${program}_$kind"; done
done

echo "== pkg-config: cc consumer.c \$(pkg-config --cflags --libs facemorph), facemorph-static"
export PKG_CONFIG_PATH=$libdir/pkgconfig
for kind in $kinds; do
  package=facemorph
  [[ $kind == static ]] && package=facemorph-static
  flags=$(pkg-config --cflags --libs "$package")
  echo "   $package: $flags"
  # shellcheck disable=SC2086  # the flags are words
  "${CC:-cc}" -std=c99 -Wall -Wextra -pedantic -Werror "$here/consumer.c" $flags -lm -o "$work/pc_c_$kind" &
  c=$!
  # shellcheck disable=SC2086
  "${CXX:-c++}" -std=c++17 -Wall -Wextra -pedantic -Werror "$here/consumer.cpp" $flags -o "$work/pc_cxx17_$kind"
  # shellcheck disable=SC2086
  "${CXX:-c++}" -std=c++20 -Wall -Wextra -pedantic -Werror "$here/consumer.cpp" $flags -o "$work/pc_cxx20_$kind"
  wait $c
  for program in c cxx17 cxx20; do check "pkg-config $program $kind" "$kind" "$work/pc_${program}_$kind"; done
done
echo "consumer test passed ($kinds)"
