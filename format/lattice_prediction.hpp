// The lattice predictors' one rule (spec/container.md §7.2, ids 2 and 3): with all three of the
// left, upper and upper-left neighbours, `combine` of their codes (the gradient L + U − UL, or
// LOCO-I's median); else the left one's code; else the upper one's; else `otherwise()`. The raster
// order's predictors (spatial_predictor.cpp) and the levels predictor's coarse lattice
// (level_predictor.cpp, the gradient on every 8th row and column) both predict by it.
#pragma once

#include <cstddef>
#include <cstdint>

namespace facemorph::format {

// `l`, `u`, `ul`: the neighbours' elements, −1 where absent; `code(e)` reads element e, decoded already.
template <typename Code, typename Combine, typename Otherwise>
int64_t lattice_prediction(int32_t l, int32_t u, int32_t ul, Code code, Combine combine, Otherwise otherwise) {
  if (l >= 0 && u >= 0 && ul >= 0) return combine(code(static_cast<size_t>(l)), code(static_cast<size_t>(u)), code(static_cast<size_t>(ul)));
  if (l >= 0) return code(static_cast<size_t>(l));
  if (u >= 0) return code(static_cast<size_t>(u));
  return otherwise();
}

}  // namespace facemorph::format
