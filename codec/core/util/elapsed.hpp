// Wall-clock timings (the encoder's EncodeReport::seconds_*, the maps' and geodesic frames'
// reports): the seconds since a step began. Here, below every encoder folder, so that the stages,
// the driver, the conformal map and the registration take it from one place without an include
// running back up (the tools take it through tools/tool_support.hpp).
#pragma once

#include <chrono>

namespace facemorph {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace facemorph
