#include "format/spatial_predictor.hpp"

#include "format/error.hpp"
#include "format/lattice_prediction.hpp"

#include <algorithm>
#include <limits>

namespace facemorph::format {

namespace {

const LatticeNeighbours& checked_lattice(const LatticeNeighbours* lattice, size_t size) {
  if (lattice == nullptr || lattice->size() != size || lattice->up.size() != size || lattice->up_left.size() != size) {
    throw Error(ErrorCode::kInvalidArgument, "a lattice predictor needs the array's neighbour table");
  }
  return *lattice;
}

// The prediction of element i from the codes before it; `code(j)` reads an earlier element.
template <typename Code>
int64_t predict(size_t i, SpatialPredictor predictor, const LatticeNeighbours* lattice, Code code) {
  const auto previous = [&] { return i == 0 ? int64_t{0} : code(i - 1); };
  switch (predictor) {
    case SpatialPredictor::kNone: return 0;
    case SpatialPredictor::kPrevious: return previous();
    // A smooth curve sampled finely (the rim round the disk) has a second difference far smaller
    // than its first: extrapolating the two codes before leaves 36–45% fewer bits of an intra
    // keyframe's rim than kPrevious (spec/method.md §7.20.1).
    case SpatialPredictor::kLinear: return i < 2 ? previous() : 2 * code(i - 1) - code(i - 2);
    case SpatialPredictor::kGradient:
    case SpatialPredictor::kMedian: {
      const auto combine = [&](int64_t a, int64_t b, int64_t c) -> int64_t {
        if (predictor == SpatialPredictor::kGradient) return a + b - c;
        // LOCO-I: an edge above or to the left picks the other neighbour; else the plane.
        if (c >= std::max(a, b)) return std::min(a, b);
        if (c <= std::min(a, b)) return std::max(a, b);
        return a + b - c;
      };
      return lattice_prediction(lattice->left[i], lattice->up[i], lattice->up_left[i], code, combine, previous);
    }
    case SpatialPredictor::kLevels: break;  // another order of the elements: level_predictor.hpp
  }
  throw Error(ErrorCode::kInvalidArgument, "unknown spatial predictor");
}

void check_order(const LatticeNeighbours& lattice) {
  for (size_t i = 0; i < lattice.size(); ++i) {
    for (int32_t n : {lattice.left[i], lattice.up[i], lattice.up_left[i]}) {
      if (n >= static_cast<int64_t>(i)) throw Error(ErrorCode::kInvalidArgument, "a lattice neighbour that comes after its element");
    }
  }
}

}  // namespace

std::vector<int64_t> spatial_residuals(std::span<const int32_t> codes, SpatialPredictor predictor, const LatticeNeighbours* lattice) {
  if (uses_lattice(predictor)) check_order(checked_lattice(lattice, codes.size()));
  std::vector<int64_t> out(codes.size());
  for (size_t i = 0; i < codes.size(); ++i) {
    out[i] = codes[i] - predict(i, predictor, lattice, [&](size_t j) { return int64_t{codes[j]}; });
  }
  return out;
}

std::vector<int32_t> codes_from_residuals(std::span<const int64_t> residuals, SpatialPredictor predictor, const LatticeNeighbours* lattice,
                                          const std::string& source) {
  if (uses_lattice(predictor)) check_order(checked_lattice(lattice, residuals.size()));
  std::vector<int32_t> codes(residuals.size());
  for (size_t i = 0; i < residuals.size(); ++i) {
    // Residuals are below 2^35 and predictions of int32 codes below 2^33 (3 × 2^31 for kLinear): no
    // overflow in 64 bits.
    const int64_t code = predict(i, predictor, lattice, [&](size_t j) { return int64_t{codes[j]}; }) + residuals[i];
    if (code < std::numeric_limits<int32_t>::min() || code > std::numeric_limits<int32_t>::max()) {
      throw Error(ErrorCode::kCorrupt, source + ": a field code outside 32 bits");
    }
    codes[i] = static_cast<int32_t>(code);
  }
  return codes;
}

}  // namespace facemorph::format
