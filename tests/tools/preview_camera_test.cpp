// The tools show a face from one camera (meshkit's kPreviewYawDegrees): fmdec --preview of a decoded
// frame and fmview of the same frame written as OBJ are the same picture, so a decoded frame and a
// captured one can be set side by side. fmview turned the mesh 0 degrees and fmdec 20, and the
// decoded face looked turned next to the captured one.
#include "codec/decoder/image/image_decode.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>

#ifndef FACEMORPH_FMDEC
#error "FACEMORPH_FMDEC and FACEMORPH_FMVIEW must name the programs"
#endif

namespace {

using facemorph::testing::TempDir;

facemorph::Image read_picture(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  return facemorph::decode_png(bytes, path.string());
}

bool background(const facemorph::Image& picture, int x, int y) {
  const uint8_t* p = picture.at(x, y);
  return p[0] == 255 && p[1] == 255 && p[2] == 255;
}

TEST(PreviewCamera, FmviewOfADecodedFrameIsFmdecsPreview) {
  const TempDir dir;
  const std::string golden = std::string(FACEMORPH_TEST_DATA) + "/golden_v2_1.fmv";
  const std::string decode = std::string(FACEMORPH_FMDEC) + " " + golden + " --t 0.2 -o " + (dir / "f.obj").string() + " --preview " +
                             (dir / "preview.png").string() + " --preview-size 400 --quiet";
  ASSERT_EQ(std::system(decode.c_str()), 0) << decode;
  const std::string view =
      std::string(FACEMORPH_FMVIEW) + " " + (dir / "f.obj").string() + " -o " + (dir / "view.png").string() + " --size 400";
  ASSERT_EQ(std::system(view.c_str()), 0) << view;

  const facemorph::Image preview = read_picture(dir / "preview.png");
  const facemorph::Image viewed = read_picture(dir / "view.png");
  ASSERT_EQ(preview.width, viewed.width);
  ASSERT_EQ(preview.height, viewed.height);
  // The silhouettes agree pixel for pixel but at the rim (the OBJ's positions are rounded to print),
  // and the colours inside within a few levels. A camera 20 degrees apart moves the silhouette by
  // several per cent of the face's pixels.
  int face = 0, both = 0;
  double colour_difference = 0;
  for (int y = 0; y < preview.height; ++y) {
    for (int x = 0; x < preview.width; ++x) {
      const bool in_preview = !background(preview, x, y), in_view = !background(viewed, x, y);
      face += in_preview || in_view;
      if (!(in_preview && in_view)) continue;
      ++both;
      for (int c = 0; c < 3; ++c) colour_difference += std::abs(preview.at(x, y)[c] - viewed.at(x, y)[c]);
    }
  }
  ASSERT_GT(face, preview.width * preview.height / 10);
  EXPECT_GT(static_cast<double>(both) / face, 0.995);
  EXPECT_LT(colour_difference / (3.0 * both), 1.0);
}

}  // namespace
