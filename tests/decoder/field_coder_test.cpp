#include "format/field_coder.hpp"
#include "format/residual_coder.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <zstd.h>

namespace facemorph {
namespace {

TEST(FieldCoder, CodePlanesRoundTripAndDamageIsNamed) {
  std::vector<format::Quantized16> arrays;
  for (int k = 0; k < 3; ++k) {
    std::vector<double> values;
    for (int i = 0; i < 1000 + 17 * k; ++i) values.push_back(std::sin(0.01 * i * (k + 1)) + 1e-3 * ((i * 7919) % 13));
    arrays.push_back(format::quantize16(values));
  }
  arrays.push_back(format::quantize16(std::vector<double>{}));  // an array a representation does not use
  const std::vector<uint8_t> bytes = format::encode_code_planes(arrays);
  std::vector<size_t> lengths;
  for (const auto& a : arrays) lengths.push_back(a.codes.size());
  const auto back = format::decode_code_planes(bytes, lengths, "k.fields");
  ASSERT_EQ(back.size(), arrays.size());
  for (size_t k = 0; k < arrays.size(); ++k) EXPECT_EQ(back[k], arrays[k].codes);
  EXPECT_LT(bytes.size(), 2 * (lengths[0] + lengths[1] + lengths[2]));  // smooth fields compress
  lengths[1] += 1;
  testing::expect_error(ErrorCode::kCorrupt, "k.fields: field payload holds", [&] { format::decode_code_planes(bytes, lengths, "k.fields"); });
  lengths[1] -= 1;
  for (size_t cut : {size_t{0}, size_t{3}, bytes.size() / 2, bytes.size() - 1}) {
    testing::expect_error(ErrorCode::kCorrupt, "k.fields", [&] { format::decode_code_planes(std::span(bytes).first(cut), lengths, "k.fields"); });
  }
}


TEST(ResidualCoder, EveryPredictorRoundTripsExactlyAndPlanesLeaveSmallResiduals) {
  const int w = 40;
  const format::LatticeNeighbours lattice = testing::square_lattice(w);
  std::vector<int32_t> plane, rough;
  for (int j = 0; j < w; ++j) {
    for (int i = 0; i < w; ++i) {
      plane.push_back(3 * i - 7 * j + 11);                     // a plane: the gradient predicts it exactly
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
      const std::vector<std::vector<int64_t>> arrays = {residuals, {}, {1, -1}};
      const std::vector<uint8_t> bytes = format::encode_residual_stream(arrays);
      const std::vector<size_t> lengths = {residuals.size(), 0, 2};
      EXPECT_EQ(format::decode_residual_stream(bytes, lengths, "t"), arrays) << int(p);
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
  testing::expect_error(ErrorCode::kInvalidArgument, "neighbour table", [&] { format::spatial_residuals(plane, format::SpatialPredictor::kGradient, nullptr); });
  format::LatticeNeighbours backwards = lattice;
  backwards.left[3] = 10;
  testing::expect_error(ErrorCode::kInvalidArgument, "comes after", [&] { format::spatial_residuals(plane, format::SpatialPredictor::kMedian, &backwards); });
}

std::vector<uint8_t> zstd_frame(const std::vector<uint8_t>& raw) {
  std::vector<uint8_t> out(ZSTD_compressBound(raw.size()));
  out.resize(ZSTD_compress(out.data(), out.size(), raw.data(), raw.size(), 3));
  return out;
}

TEST(ResidualCoder, DamagedStreamsAreNamed) {
  const std::vector<size_t> three = {3};
  // Well-formed frames whose varints are wrong: too few, too many, an endless varint, a code
  // pushed out of 32 bits by its residual.
  testing::expect_error(ErrorCode::kCorrupt, "announces", [&] { format::decode_residual_stream(zstd_frame({1, 2}), three, "r.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "after the last residual", [&] { format::decode_residual_stream(zstd_frame({1, 2, 3, 4}), three, "r.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "end early", [&] { format::decode_residual_stream(zstd_frame({1, 2, 0x80}), three, "r.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "longer than 5 bytes",
                        [&] { format::decode_residual_stream(zstd_frame({0x80, 0x80, 0x80, 0x80, 0x80, 0x01}), std::vector<size_t>{2}, "r.fmv"); });
  testing::expect_error(ErrorCode::kCorrupt, "not a zstd frame", [&] { format::decode_residual_stream(std::vector<uint8_t>{1, 2, 3, 4, 5}, three, "r.fmv"); });
  const std::vector<int64_t> beyond = {std::numeric_limits<int32_t>::max(), 1};
  testing::expect_error(ErrorCode::kCorrupt, "outside 32 bits",
                        [&] { format::codes_from_residuals(beyond, format::SpatialPredictor::kPrevious, nullptr, "r.fmv"); });
  // A frame announcing more than 5 bytes per residual is refused before anything is allocated.
  testing::expect_error(ErrorCode::kCorrupt, "announces", [&] { format::decode_residual_stream(zstd_frame(std::vector<uint8_t>(16, 0)), three, "r.fmv"); });
}

}  // namespace
}  // namespace facemorph
