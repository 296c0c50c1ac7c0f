// Each stage's time in the report (EncodeReport::seconds_*): the wall-clock seconds since it began.
#pragma once

#include <chrono>

namespace facemorph {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace facemorph
