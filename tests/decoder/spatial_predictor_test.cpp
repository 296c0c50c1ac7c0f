#include "format/spatial_predictor.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <limits>

namespace facemorph {
namespace {

TEST(SpatialPredictor, EveryPredictorRoundTripsExactlyAndPlanesLeaveSmallResiduals) {
  const int w = 40;
  const format::LatticeNeighbours lattice = testing::square_lattice(w);
  std::vector<int32_t> plane, rough;
  for (int j = 0; j < w; ++j) {
    for (int i = 0; i < w; ++i) {
      plane.push_back(3 * i - 7 * j + 11);  // a plane: the gradient predicts it exactly
      rough.push_back(static_cast<int32_t>((i * 7919 + j * 104729) % 2001) - 1000);
    }
  }
  // The extremes of 32 bits survive every predictor (residuals reach 2^33 there).
  rough[5] = std::numeric_limits<int32_t>::max();
  rough[6] = std::numeric_limits<int32_t>::min();
  rough[w + 6] = std::numeric_limits<int32_t>::max();
  for (uint8_t p = 0; p < format::kSpatialPredictorCount; ++p) {
    const auto predictor = static_cast<format::SpatialPredictor>(p);
    for (const std::vector<int32_t>& codes : {plane, rough}) {
      const std::vector<int64_t> residuals = format::spatial_residuals(codes, predictor, &lattice);
      EXPECT_EQ(format::codes_from_residuals(residuals, predictor, &lattice, "t"), codes) << int(p);
    }
  }
  const std::vector<int64_t> gradient = format::spatial_residuals(plane, format::SpatialPredictor::kGradient, &lattice);
  const std::vector<int64_t> median = format::spatial_residuals(plane, format::SpatialPredictor::kMedian, &lattice);
  for (size_t i = 0; i < plane.size(); ++i) {
    if (lattice.left[i] >= 0 && lattice.up[i] >= 0) {
      ASSERT_EQ(gradient[i], 0) << i;
      ASSERT_EQ(median[i], 0) << i;  // a plane has no edge: the median detector takes the plane too
    }
  }
  // A lattice predictor without the table, or with a neighbour that comes later, is refused.
  testing::expect_error(ErrorCode::kInvalidArgument, "neighbour table",
                        [&] { format::spatial_residuals(plane, format::SpatialPredictor::kGradient, nullptr); });
  format::LatticeNeighbours backwards = lattice;
  backwards.left[3] = 10;
  testing::expect_error(ErrorCode::kInvalidArgument, "comes after",
                        [&] { format::spatial_residuals(plane, format::SpatialPredictor::kMedian, &backwards); });
}

}  // namespace
}  // namespace facemorph
