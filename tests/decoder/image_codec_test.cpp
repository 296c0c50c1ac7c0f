#include "codec/decoder/image/image_decode.hpp"
#include "codec/writer/image/image_encode.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace facemorph {
namespace {

// A smooth picture with an edge, like a face texture: gradients and one sharp boundary.
Image test_picture(int width, int height, int channels) {
  Image image(width, height, channels);
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> noise(-6, 6);  // skin-like grain: what makes lossless costly
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      uint8_t* p = image.at(x, y);
      const int grain = noise(rng);
      p[0] = static_cast<uint8_t>(128 + 100 * std::sin(x * 0.05) + grain);
      p[1] = static_cast<uint8_t>(y * 255 / (height - 1));
      p[2] = static_cast<uint8_t>((x - width / 2) * (x - width / 2) + (y - height / 2) * (y - height / 2) < width * width / 9 ? 220 : 40);
      if (channels == 4) p[3] = static_cast<uint8_t>(x % 256);
    }
  }
  return image;
}

using testing::psnr;

TEST(ImageCodec, PngAndLosslessWebpRoundTripExactly) {
  for (int channels : {3, 4}) {
    const Image image = test_picture(97, 64, channels);
    const Image png = decode_png(encode_png(image), "t.png");
    EXPECT_EQ(png.channels, channels);
    EXPECT_EQ(png.pixels, image.pixels);
    const Image webp = decode_webp(encode_webp(image, 101), "t.webp", channels);
    EXPECT_EQ(webp.pixels, image.pixels);
  }
}

TEST(ImageCodec, LossyWebpIsSmallerAndClose) {
  const Image image = test_picture(256, 256, 3);
  const std::vector<uint8_t> lossy = encode_webp(image, 90), lossless = encode_webp(image, 101);
  EXPECT_LT(lossy.size(), lossless.size());
  const Image back = decode_webp(lossy, "t.webp");
  ASSERT_EQ(back.width, 256);
  EXPECT_GT(psnr(image, back), 30.0);
}

TEST(ImageCodec, DamagedBytesAreNamedErrors) {
  const Image image = test_picture(64, 64, 3);
  const std::vector<uint8_t> png = encode_png(image), webp = encode_webp(image, 80);
  testing::expect_error(ErrorCode::kCorrupt, "t.png", [&] { decode_png(std::span(png).first(png.size() / 2), "t.png"); });
  testing::expect_error(ErrorCode::kCorrupt, "t.webp", [&] { decode_webp(std::span(webp).first(webp.size() / 2), "t.webp"); });
  testing::expect_error(ErrorCode::kCorrupt, "x.webp", [&] { decode_webp(png, "x.webp"); });
  testing::expect_error(ErrorCode::kInvalidArgument, "too large", [&] { decode_png(png, "t.png", 100); });
  testing::expect_error(ErrorCode::kInvalidArgument, "cannot encode", [] { encode_webp(Image(), 90); });
  // Every truncation of a small WebP is an error or a full image, never a crash.
  for (size_t n = 0; n < webp.size(); n += 7) {
    try {
      const Image back = decode_webp(std::span(webp).first(n), "t.webp");
      EXPECT_EQ(back.width, 64);
    } catch (const Error& e) {
      EXPECT_EQ(e.code(), ErrorCode::kCorrupt);
    }
  }
}

TEST(ImageCodec, AvifIsCloseAtHighQualityAndSmallerThanWebpAtEqualError) {
  const Image image = test_picture(256, 256, 3);
  const std::vector<uint8_t> fine = encode_avif(image, 90), coarse = encode_avif(image, 40);
  EXPECT_LT(coarse.size(), fine.size());
  const Image back = decode_avif(fine, "t.avif");
  ASSERT_EQ(back.width, 256);
  ASSERT_EQ(back.height, 256);
  EXPECT_GT(psnr(image, back), 38.0);
  const double coarse_psnr = psnr(image, decode_avif(coarse, "t.avif"));
  EXPECT_LT(coarse_psnr, psnr(image, back));
  // The lowest WebP quality at least as close as AVIF at 40 takes more bytes: why AVIF is the default.
  int webp_quality = 0;
  while (webp_quality < 100 && psnr(image, decode_webp(encode_webp(image, webp_quality), "t.webp")) < coarse_psnr) ++webp_quality;
  EXPECT_GT(encode_webp(image, webp_quality).size(), coarse.size()) << "WebP q" << webp_quality;
  // A file must be the same bytes on every run.
  EXPECT_EQ(encode_avif(image, 40), coarse);
  // RGBA in: the alpha is dropped; RGBA out: opaque.
  const Image rgba = decode_avif(encode_avif(test_picture(64, 48, 4), 90), "t.avif", 4);
  ASSERT_EQ(rgba.channels, 4);
  for (size_t i = 3; i < rgba.pixels.size(); i += 4) ASSERT_EQ(rgba.pixels[i], 255);
}

// texture_quality_for takes AVIF's error floor from the colour conversion alone: that must be what
// quality 100 decodes to, texel for texel (a noisy picture too, where a lossy step would show).
TEST(ImageCodec, AvifAtQuality100DecodesAsItsColourRoundTrip) {
  Image noisy = test_picture(96, 80, 3);
  uint32_t state = 12345;
  for (uint8_t& p : noisy.pixels) {
    state = state * 1664525u + 1013904223u;
    p = static_cast<uint8_t>(std::clamp(static_cast<int>(p) + static_cast<int>(state >> 28) - 8, 0, 255));
  }
  for (const Image& image : {test_picture(128, 128, 3), noisy}) {
    const Image round_trip = avif_colour_round_trip(image);
    EXPECT_EQ(decode_avif(encode_avif(image, 100), "t.avif").pixels, round_trip.pixels);
    EXPECT_NE(round_trip.pixels, image.pixels);  // the conversion does round: a floor above 0
    EXPECT_NE(decode_avif(encode_avif(image, 99), "t.avif").pixels, round_trip.pixels);
  }
}

TEST(ImageCodec, TextureCodecsDispatchAndLosslessIsWebp) {
  const Image image = test_picture(64, 64, 3);
  EXPECT_EQ(encode_texture(TextureCodec::kAvif, image, 70), encode_avif(image, 70));
  EXPECT_EQ(encode_texture(TextureCodec::kWebp, image, 70), encode_webp(image, 70));
  const std::vector<uint8_t> lossless = encode_texture(TextureCodec::kAvif, image, 101);
  EXPECT_EQ(stored_texture_codec(TextureCodec::kAvif, 101), TextureCodec::kWebp);
  EXPECT_EQ(stored_texture_codec(TextureCodec::kAvif, 100), TextureCodec::kAvif);
  EXPECT_EQ(decode_texture(TextureCodec::kWebp, lossless, "t").pixels, image.pixels);
  EXPECT_EQ(parse_texture_codec(texture_codec_name(TextureCodec::kAvif)), TextureCodec::kAvif);
  EXPECT_EQ(parse_texture_codec(texture_codec_name(TextureCodec::kWebp)), TextureCodec::kWebp);
  testing::expect_error(ErrorCode::kInvalidArgument, "'jpeg'", [] { parse_texture_codec("jpeg"); });
}

TEST(ImageCodec, AStillCodedAtManyQualitiesGivesEachCodingsOwnBytes) {
  // One conversion to YUV serves every quality: the bytes are encode_avif's and encode_webp's own
  // (as stored_texture_codec picks), the floor is what quality 100 decodes to, whatever order the
  // qualities come in, an RGBA image and WebP's qualities (and lossless) too. (encode_texture and
  // avif_colour_round_trip are stills themselves: compared with the codecs' own functions.)
  for (const Image& image : {test_picture(96, 64, 3), test_picture(64, 48, 4)}) {
    for (const TextureCodec codec : {TextureCodec::kAvif, TextureCodec::kWebp}) {
      const TextureStill still(codec, image);
      for (const int quality : {40, 5, 90, 40, 101}) {
        const bool avif = stored_texture_codec(codec, quality) == TextureCodec::kAvif;
        EXPECT_EQ(still.encode(quality), avif ? encode_avif(image, quality) : encode_webp(image, quality)) << quality;
      }
      EXPECT_EQ(still.colour_round_trip().pixels, decode_avif(encode_avif(image, 100), "t.avif").pixels);
    }
  }
  testing::expect_error(ErrorCode::kInvalidArgument, "cannot encode", [] {
    const Image empty;
    TextureStill(TextureCodec::kAvif, empty).encode(50);
  });
}

TEST(ImageCodec, DamagedAvifBytesAreNamedErrors) {
  const Image image = test_picture(64, 64, 3);
  const std::vector<uint8_t> avif = encode_avif(image, 60), png = encode_png(image);
  testing::expect_error(ErrorCode::kCorrupt, "x.avif", [&] { decode_avif(png, "x.avif"); });
  testing::expect_error(ErrorCode::kInvalidArgument, "too large", [&] { decode_avif(avif, "t.avif", 3, 100); });
  testing::expect_error(ErrorCode::kInvalidArgument, "cannot encode", [] { encode_avif(Image(), 90); });
  // A header (ispe) that claims a smaller image than the AV1 frame holds: refused, before the frame's
  // size is trusted for an allocation.
  std::vector<uint8_t> small_header = avif;
  const std::string ispe = "ispe";
  const auto at = std::search(small_header.begin(), small_header.end(), ispe.begin(), ispe.end());
  ASSERT_NE(at, small_header.end());
  const auto size_at = static_cast<size_t>(at - small_header.begin()) + 8;         // after the box's version and flags
  for (size_t i = 0; i < 8; ++i) small_header[size_at + i] = i % 4 == 3 ? 16 : 0;  // 16 x 16, big-endian
  testing::expect_error(ErrorCode::kCorrupt, "t.avif", [&] { decode_avif(small_header, "t.avif", 3, 16 * 16); });
  // Every truncation, and a byte changed at every 5th place, is an error or a full image, never a crash.
  for (size_t n = 0; n < avif.size(); n += 5) {
    for (bool truncate : {true, false}) {
      std::vector<uint8_t> bad = avif;
      if (truncate) {
        bad.resize(n);
      } else {
        bad[n] ^= 0x5a;
      }
      try {
        const Image back = decode_avif(bad, "t.avif");
        EXPECT_EQ(back.width, 64);
        EXPECT_EQ(back.pixels.size(), size_t{64} * 64 * 3);
      } catch (const Error& e) {
        EXPECT_EQ(e.code(), ErrorCode::kCorrupt) << e.what();
        EXPECT_NE(std::string(e.what()).find("t.avif"), std::string::npos);
      }
    }
  }
}

}  // namespace
}  // namespace facemorph
