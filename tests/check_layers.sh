#!/bin/sh
# The libraries' floors and the one include style (codec/CMakeLists.txt), checked from the sources:
#   format -> codec/core -> codec/decoder -> codec/writer -> codec/meshkit -> codec/encoder -> tools, python
# A library includes its own headers and those of the floors below it, never one above or beside
# it; OpenCV only in the encoder and the tools. Every quoted include is a path from the repository
# root to a file that exists, except the two installed headers, which keep their installed names.
# Prints each include that breaks a rule and fails; run from the repository root.
set -u
status=0
# folder | what it may include besides system headers
rules='format|format/
codec/core|format/ codec/core/
codec/decoder|format/ codec/core/ codec/decoder/ facemorph.h facemorph/decoder.hpp
codec/writer|format/ codec/core/ codec/decoder/ codec/writer/
codec/meshkit|format/ codec/core/ codec/writer/ codec/meshkit/
codec/encoder|format/ codec/core/ codec/decoder/ codec/writer/ codec/meshkit/ codec/encoder/ facemorph.h facemorph/decoder.hpp'

for source in $(find format codec tools python tests -name '*.cpp' -o -name '*.hpp' -o -name '*.h' -o -name '*.c' -o -name '*.inc' | sort); do
  case $source in tests/consumer/*) continue ;; esac  # programs built against the installed package
  allowed=''
  for rule in $(echo "$rules" | tr ' ' '#'); do
    folder=${rule%%|*}
    case $source in "$folder"/*) allowed=$(echo "${rule#*|}" | tr '#' ' ') ;; esac
  done
  grep -n '^[[:space:]]*#[[:space:]]*include' "$source" | while IFS= read -r line; do
    include=$(echo "$line" | sed -n 's/.*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p')
    if [ -z "$include" ]; then
      case $source in codec/encoder/* | tools/* | python/* | tests/*) ;;
        *) echo "$line" | grep -q 'opencv' && echo "$source:$line: OpenCV below the encoder" ;;
      esac
      continue
    fi
    case $include in
      facemorph.h | facemorph/decoder.hpp) ;;
      *) [ -f "$include" ] || echo "$source:$line: not a path from the repository root" ;;
    esac
    [ -z "$allowed" ] && continue
    ok=no
    for prefix in $allowed; do
      case $include in "$prefix"*) ok=yes ;; esac
    done
    [ $ok = yes ] || echo "$source:$line: runs back up or sideways (allowed: $allowed)"
  done
done > /tmp/check_layers.$$ 2>&1
if [ -s /tmp/check_layers.$$ ]; then
  cat /tmp/check_layers.$$
  status=1
fi
rm -f /tmp/check_layers.$$
exit $status
