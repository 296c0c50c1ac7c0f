#include "format/field_coder.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cmath>

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

}  // namespace
}  // namespace facemorph
