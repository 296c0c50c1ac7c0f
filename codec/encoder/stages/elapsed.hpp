// The encoder's timings (EncodeReport::seconds_*, the maps' and geodesic frames' reports): the wall-clock
// seconds since a step began. One definition for the encoder library (the tools, which include no
// encoder-private header, have theirs in tools/tool_support.hpp).
#pragma once

#include <chrono>

namespace facemorph {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace facemorph
