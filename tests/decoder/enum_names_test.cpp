// The enumerations' name tables (codec/core/util/enum_names.hpp): every name is what files and
// settings have always stored, each enumerator's name parses back to it, and a name outside the
// table is a named error listing the table.
#include "codec/core/util/enum_names.hpp"
#include "codec/core/container/file_metadata.hpp"
#include "codec/core/image/texture_codec.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/sequence/spline.hpp"
#include "format/error.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <string>
#include <utility>

namespace facemorph {
namespace {

enum class EnumNamesTestColour { kRed, kGreen, kBlue };
constexpr EnumName<EnumNamesTestColour> kEnumNamesTestColours[] = {
    {EnumNamesTestColour::kRed, "red"}, {EnumNamesTestColour::kGreen, "green"}, {EnumNamesTestColour::kBlue, "blue"}};

TEST(EnumNames, NameAndParseAreInverse) {
  for (const auto& entry : kEnumNamesTestColours) {
    EXPECT_STREQ(name_of(kEnumNamesTestColours, entry.value), entry.name);
    EXPECT_EQ(parse_name(kEnumNamesTestColours, entry.name, "colour"), entry.value);
  }
  EXPECT_STREQ(name_of(kEnumNamesTestColours, static_cast<EnumNamesTestColour>(7)), "unknown");
}

TEST(EnumNames, AnUnknownNameListsTheTable) {
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown colour 'mauve' (red, green, blue)",
                        [] { parse_name(kEnumNamesTestColours, "mauve", "colour"); });
  // A prefix of a name is not the name.
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown colour 're'", [] { parse_name(kEnumNamesTestColours, "re", "colour"); });
}

// The names files and settings store (golden files hold them): never renamed.
TEST(EnumNames, TheStoredNamesStay) {
  const std::pair<SplineKind, const char*> splines[] = {{SplineKind::kLocalCubic, "local"},
                                                        {SplineKind::kCatmullRom, "catmull-rom"},
                                                        {SplineKind::kNotAKnot, "not-a-knot"},
                                                        {SplineKind::kLinear, "linear"}};
  for (const auto& [kind, name] : splines) {
    EXPECT_STREQ(spline_kind_name(kind), name);
    EXPECT_EQ(parse_spline_kind(name), kind);
  }
  const std::pair<Representation, const char*> representations[] = {
      {Representation::kHL, "hl"}, {Representation::kHLT, "hl+t"}, {Representation::kXYZ, "xyz"}};
  for (const auto& [representation, name] : representations) {
    EXPECT_STREQ(representation_name(representation), name);
    EXPECT_EQ(parse_representation(name), representation);
  }
  EXPECT_STREQ(texture_codec_name(TextureCodec::kAvif), "avif");
  EXPECT_STREQ(texture_codec_name(TextureCodec::kWebp), "webp");
  EXPECT_EQ(parse_texture_codec("webp"), TextureCodec::kWebp);
  EXPECT_STREQ(texture_coding_name(TextureCoding::kSequence), "sequence");
  EXPECT_STREQ(texture_coding_name(TextureCoding::kStills), "stills");
  EXPECT_EQ(parse_texture_coding("stills"), TextureCoding::kStills);
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown spline 'cubic' (local, catmull-rom, not-a-knot, linear)",
                        [] { parse_spline_kind("cubic"); });
  testing::expect_error(ErrorCode::kInvalidArgument, "unknown texture codec 'jpeg' (avif, webp)", [] { parse_texture_codec("jpeg"); });
}

// The numbers files store for the coded enumerations (spec/container.md §5, §8): fixed forever,
// whatever the order of the C++ enumerators. Each table's two maps are inverse.
TEST(EnumNames, TheStoredCodesStay) {
  const std::pair<SplineKind, uint8_t> splines[] = {
      {SplineKind::kLocalCubic, 0}, {SplineKind::kCatmullRom, 1}, {SplineKind::kNotAKnot, 2}, {SplineKind::kLinear, 3}};
  for (const auto& [kind, code] : splines) {
    EXPECT_EQ(code_of(kSplineKinds, kind), code);
    EXPECT_EQ(enum_of(kSplineKinds, code, "spline"), kind);
  }
  const std::pair<Representation, uint8_t> representations[] = {
      {Representation::kHL, 0}, {Representation::kHLT, 1}, {Representation::kXYZ, 2}};
  for (const auto& [representation, code] : representations) {
    EXPECT_EQ(code_of(kRepresentations, representation), code);
    EXPECT_EQ(enum_of(kRepresentations, code, "representation"), representation);
  }
  EXPECT_EQ(code_of(kTextureCodecs, TextureCodec::kWebp), 1u);
  EXPECT_EQ(code_of(kTextureCodecs, TextureCodec::kAvif), 2u);
  EXPECT_EQ(entry_of_code(kTextureCodecs, uint32_t{3}), nullptr);  // TGOP's sequence, not a still's codec
  testing::expect_error(ErrorCode::kUnsupported, "spline kind 4 is not one this decoder knows",
                        [] { enum_of(kSplineKinds, uint8_t{4}, "spline kind"); });
  testing::expect_error(ErrorCode::kInvalidArgument, "no file code", [] { code_of(kRepresentations, static_cast<Representation>(7)); });
}

TEST(EnumNames, OneToOneSeesARepeatedCodeOrName) {
  enum class EnumNamesTestShape { kSquare, kCircle };
  constexpr CodedEnumName<EnumNamesTestShape, uint8_t> fine[] = {{EnumNamesTestShape::kSquare, "square", 0},
                                                                 {EnumNamesTestShape::kCircle, "circle", 1}};
  constexpr CodedEnumName<EnumNamesTestShape, uint8_t> same_code[] = {{EnumNamesTestShape::kSquare, "square", 1},
                                                                      {EnumNamesTestShape::kCircle, "circle", 1}};
  constexpr CodedEnumName<EnumNamesTestShape, uint8_t> same_name[] = {{EnumNamesTestShape::kSquare, "square", 0},
                                                                      {EnumNamesTestShape::kCircle, "square", 1}};
  static_assert(is_one_to_one(fine));
  static_assert(!is_one_to_one(same_code));
  static_assert(!is_one_to_one(same_name));
  EXPECT_STREQ(name_of(fine, EnumNamesTestShape::kCircle), "circle");
  EXPECT_EQ(parse_name(fine, "square", "shape"), EnumNamesTestShape::kSquare);
}

}  // namespace
}  // namespace facemorph
