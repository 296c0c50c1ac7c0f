#!/bin/sh
# The libraries' floors and the one include style (codec/CMakeLists.txt), checked from the sources:
#   format -> codec/core -> {codec/decoder, codec/writer} -> codec/meshkit -> codec/encoder -> tools, python
# (the decoder and the writer side by side: a writer includes no reader, a player no writer)
# A library includes its own headers and those of the floors below it, never one above or beside
# it; OpenCV only in the encoder and the tools. Every quoted include is a path from the repository
# root to a file that exists, except the two installed headers, which keep their installed names.
# Prints each include that breaks a rule and fails; run from the repository root.
set -u
find format codec tools python tests \( -name '*.cpp' -o -name '*.hpp' -o -name '*.h' -o -name '*.c' -o -name '*.inc' \) \
     ! -path 'tests/consumer/*' | sort > /tmp/check_layers_sources.$$
# Every file an include may name (a path from the root).
find format codec tools python tests -type f | sort > /tmp/check_layers_files.$$
xargs grep -Hn '^[[:space:]]*#[[:space:]]*include' < /tmp/check_layers_sources.$$ |
awk -v files=/tmp/check_layers_files.$$ '
  BEGIN {
    while ((getline f < files) > 0) exists[f] = 1
    # folder | what it may include besides system headers
    rule["format"] = "format/"
    rule["codec/core"] = "format/ codec/core/"
    rule["codec/decoder"] = "format/ codec/core/ codec/decoder/ facemorph.h facemorph/decoder.hpp"
    rule["codec/writer"] = "format/ codec/core/ codec/writer/"
    rule["codec/meshkit"] = "format/ codec/core/ codec/writer/ codec/meshkit/"
    rule["codec/encoder"] = "format/ codec/core/ codec/decoder/ codec/writer/ codec/meshkit/ codec/encoder/ facemorph.h facemorph/decoder.hpp"
    bad = 0
  }
  {
    source = $0; sub(/:.*/, "", source)
    at = $0; sub(/^[^:]*:/, "", at); sub(/:.*/, "", at)
    line = $0; sub(/^[^:]*:[0-9]+:/, "", line)
    folder = ""
    for (f in rule) if (index(source, f "/") == 1 && length(f) > length(folder)) folder = f
    if (match(line, /"[^"]*"/)) {
      include = substr(line, RSTART + 1, RLENGTH - 2)
      if (include != "facemorph.h" && include != "facemorph/decoder.hpp" && !(include in exists)) {
        print source ":" at ": " line ": not a path from the repository root"; bad = 1
      }
      if (folder != "") {
        n = split(rule[folder], allowed, " "); ok = 0
        for (i = 1; i <= n; i++) if (index(include, allowed[i]) == 1) ok = 1
        if (!ok) { print source ":" at ": " line ": runs back up or sideways (allowed: " rule[folder] ")"; bad = 1 }
      }
    } else if (line ~ /opencv/ && source !~ /^(codec\/encoder|tools|python|tests)\//) {
      print source ":" at ": " line ": OpenCV below the encoder"; bad = 1
    }
  }
  END { exit bad }'
status=$?
rm -f /tmp/check_layers_sources.$$ /tmp/check_layers_files.$$
exit $status
