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

// Format 2.5's predictor along a sequence: 2 d(i−1) − d(i−2), the first code from 0 and the second
// from the first, as previous. It needs no lattice, leaves a parabola a constant second difference,
// and round-trips the extremes of 32 bits (residuals up to 4 × 2^31 there).
TEST(SpatialPredictor, LinearExtrapolatesTheTwoCodesBeforeAlongTheArray) {
  std::vector<int32_t> parabola;
  for (int i = 0; i < 50; ++i) parabola.push_back(3 * i * i - 5 * i + 7);
  const std::vector<int64_t> r = format::spatial_residuals(parabola, format::SpatialPredictor::kLinear, nullptr);
  EXPECT_EQ(r[0], 7);
  EXPECT_EQ(r[1], 5 - 7);
  for (size_t i = 2; i < r.size(); ++i) ASSERT_EQ(r[i], 6) << i;
  std::vector<int32_t> rough = parabola;
  rough[10] = std::numeric_limits<int32_t>::max();
  rough[11] = std::numeric_limits<int32_t>::min();
  rough[12] = std::numeric_limits<int32_t>::max();
  const std::vector<int64_t> wide = format::spatial_residuals(rough, format::SpatialPredictor::kLinear, nullptr);
  EXPECT_EQ(wide[12], int64_t{std::numeric_limits<int32_t>::max()} - 2 * int64_t{std::numeric_limits<int32_t>::min()} +
                          int64_t{std::numeric_limits<int32_t>::max()});
  EXPECT_EQ(format::codes_from_residuals(wide, format::SpatialPredictor::kLinear, nullptr, "t"), rough);
  // A residual that leads past 32 bits is the file's fault, named.
  std::vector<int64_t> past = r;
  past[3] += int64_t{1} << 32;
  testing::expect_error(ErrorCode::kCorrupt, "seq: a field code outside 32 bits",
                        [&] { format::codes_from_residuals(past, format::SpatialPredictor::kLinear, nullptr, "seq"); });
}

}  // namespace
}  // namespace facemorph
