// Image files through OpenCV's imgcodecs, which the encoder loads on first use
// (codec/encoder/imageio/opencv_codecs.hpp) rather than at every start.
#include "codec/encoder/imageio/image_io.hpp"

#include "format/error.hpp"

#include <gtest/gtest.h>

#include <dlfcn.h>

#include <cmath>
#include <cstdint>

namespace facemorph {
namespace {

bool imgcodecs_loaded() {
  void* handle = dlopen(FACEMORPH_OPENCV_IMGCODECS_SONAME, RTLD_LAZY | RTLD_NOLOAD);
  if (handle) dlclose(handle);  // NOLOAD took a reference
  return handle != nullptr;
}

Image gradient(int width, int height) {
  Image image(width, height, 3);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      uint8_t* p = image.at(x, y);
      p[0] = static_cast<uint8_t>(x * 3);  // smooth, and no two channels alike (a swap shows)
      p[1] = static_cast<uint8_t>(y * 4);
      p[2] = static_cast<uint8_t>(255 - x * 2);
    }
  }
  return image;
}

TEST(ImageIo, OpenCvImageCodecsAreLoadedOnFirstUse) {
  // Nothing of the encoder linked into this test loads the library at start.
  EXPECT_FALSE(imgcodecs_loaded());
  const Image image = gradient(37, 23);
  const std::vector<uint8_t> png = encode_image(image, ".png");
  EXPECT_TRUE(imgcodecs_loaded());
  const Image back = decode_image(png, "gradient.png");
  ASSERT_EQ(back.width, image.width);
  ASSERT_EQ(back.height, image.height);
  ASSERT_EQ(back.channels, 3);
  EXPECT_EQ(back.pixels, image.pixels);  // PNG is lossless: the RGB order survives both conversions
}

TEST(ImageIo, LossyFormatsRoundTripCloselyAndBadBytesAreNamed) {
  const Image image = gradient(64, 48);
  for (const char* extension : {".jpg", ".webp"}) {
    const Image back = decode_image(encode_image(image, extension, 95), extension);
    ASSERT_EQ(back.width, image.width) << extension;
    ASSERT_EQ(back.height, image.height) << extension;
    double error = 0;
    for (size_t i = 0; i < image.pixels.size(); ++i) error += std::abs(double(back.pixels[i]) - image.pixels[i]);
    EXPECT_LT(error / double(image.pixels.size()), 4) << extension;  // red and blue swapped: 73 on average
  }
  const std::vector<uint8_t> junk = {'n', 'o', 't', ' ', 'a', 'n', ' ', 'i', 'm', 'a', 'g', 'e'};
  try {
    decode_image(junk, "junk.png");
    FAIL() << "junk decoded";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kMissingTexture);
    EXPECT_NE(std::string(e.what()).find("junk.png"), std::string::npos);
  }
}

}  // namespace
}  // namespace facemorph
