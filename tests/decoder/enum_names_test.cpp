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

}  // namespace
}  // namespace facemorph
