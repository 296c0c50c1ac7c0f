// API 1.1 (facemorph.h, spec/api.md): fm_file_open_memory_borrowed and
// fm_decoder_get_texture_weights, what the browser player (spec/web.md) is built on: bytes filled in
// after opening, and the texture blended by the player from the keyframes' images.
#include "facemorph.h"

#include "tests/decoder/c_api_opened.hpp"
#include "tests/test_util.hpp"

#include "format/container.hpp"
#include "format/file_io.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#ifndef FACEMORPH_TEST_DATA
#error "FACEMORPH_TEST_DATA must name tests/data"
#endif

namespace {

// 2.1: textures as one AV1 sequence per group, the default the browser meets.
using facemorph::testing::CApiOpened;
using facemorph::testing::kGoldenV2_1;

struct Decoded {
  std::vector<float> positions;
  std::vector<uint8_t> texture;
  fm_status status = FM_OK;
};

Decoded decode(fm_decoder* decoder, const fm_info& info, double t, bool texture) {
  Decoded out;
  out.positions.assign(3 * size_t{info.max_vertex_count}, 0.0f);
  fm_frame frame;
  fm_frame_init(&frame);
  frame.positions = out.positions.data();
  frame.positions_bytes = out.positions.size() * sizeof(float);
  if (texture) {
    out.texture.assign(4 * size_t{info.texture_size} * info.texture_size, 0);
    frame.texture = out.texture.data();
    frame.texture_bytes = out.texture.size();
  }
  out.status = fm_decoder_decode(decoder, t, 0, &frame);
  out.positions.resize(3 * size_t{frame.vertex_count});
  return out;
}

std::vector<double> keyframe_times(fm_file* file) {
  size_t count = 0;
  EXPECT_EQ(fm_file_get_keyframe_times(file, nullptr, 0, &count), FM_OK);
  std::vector<double> times(count);
  EXPECT_EQ(fm_file_get_keyframe_times(file, times.data(), times.size(), &count), FM_OK);
  return times;
}

// The file as a streaming player holds it right after opening: the preamble, the header and index
// chunks, and every other chunk's header and checksum; its payloads still zero.
std::vector<uint8_t> skeleton_of(const std::vector<uint8_t>& bytes) {
  const facemorph::format::ContainerReader reader(bytes, "golden");
  std::vector<uint8_t> skeleton(bytes.size(), 0);
  std::copy_n(bytes.begin(), facemorph::format::kPreambleBytes, skeleton.begin());
  for (const facemorph::format::ChunkView& chunk : reader.chunks()) {
    const bool whole = chunk.type == "HEAD" || chunk.type == "KIDX";
    const size_t begin = chunk.offset, payload = begin + facemorph::format::kChunkHeaderBytes, end = begin + chunk.total_size();
    std::copy(bytes.begin() + begin, bytes.begin() + (whole ? end : payload), skeleton.begin() + begin);
    std::copy(bytes.begin() + (end - facemorph::format::kChunkTrailerBytes), bytes.begin() + end,
              skeleton.begin() + (end - facemorph::format::kChunkTrailerBytes));
  }
  // The end chunk, which the reader does not list.
  const size_t last = reader.chunks().back().offset + reader.chunks().back().total_size();
  std::copy(bytes.begin() + last, bytes.end(), skeleton.begin() + last);
  return skeleton;
}

// `owner(k)`: the keyframe whose TEXR keyframe k shows (itself but in a file of shared textures).
void expect_weights_rebuild_the_texture(const std::filesystem::path& path, const std::function<uint32_t(size_t)>& owner) {
  const std::vector<uint8_t> bytes = facemorph::format::read_file(path);
  CApiOpened o(bytes, false);
  ASSERT_EQ(o.status, FM_OK) << fm_last_error_message();
  ASSERT_GT(o.info.texture_size, 0u);
  const std::vector<double> times = keyframe_times(o.file);
  // Each keyframe's own texture: at its time the blend is that keyframe alone, weight exactly 1.
  std::vector<std::vector<uint8_t>> keyframe_textures;
  for (size_t k = 0; k < times.size(); ++k) {
    size_t count = 0;
    ASSERT_EQ(fm_decoder_get_texture_weights(o.decoder, times[k], 0, nullptr, nullptr, 0, &count), FM_OK);
    ASSERT_EQ(count, 1u);
    uint32_t key = 99;
    double weight = 0;
    ASSERT_EQ(fm_decoder_get_texture_weights(o.decoder, times[k], 0, &key, &weight, 1, &count), FM_OK);
    EXPECT_EQ(key, owner(k));
    EXPECT_EQ(weight, 1.0);
    Decoded d = decode(o.decoder, o.info, times[k], true);
    ASSERT_EQ(d.status, FM_OK) << fm_last_error_message();
    keyframe_textures.push_back(std::move(d.texture));
  }
  // Between keyframes (and past the last, extrapolating), the documented blend of those images is
  // the decoder's texture, byte for byte.
  const double span = times.back() - times.front();
  for (double t : {times.front() + 0.13 * span, times.front() + 0.5 * span, times.front() + 0.77 * span, o.info.range_end}) {
    size_t count = 0;
    ASSERT_EQ(fm_decoder_get_texture_weights(o.decoder, t, 0, nullptr, nullptr, 0, &count), FM_OK);
    ASSERT_GE(count, 2u);
    std::vector<uint32_t> keys(count);
    std::vector<double> weights(count);
    EXPECT_EQ(fm_decoder_get_texture_weights(o.decoder, t, 0, keys.data(), weights.data(), count - 1, &count), FM_ERROR_BUFFER_TOO_SMALL);
    ASSERT_EQ(fm_decoder_get_texture_weights(o.decoder, t, 0, keys.data(), weights.data(), count, &count), FM_OK);
    double sum = 0;
    for (double w : weights) sum += w;
    EXPECT_NEAR(sum, 1.0, 1e-12);
    const Decoded d = decode(o.decoder, o.info, t, true);
    ASSERT_EQ(d.status, FM_OK) << fm_last_error_message();
    size_t differing = 0;
    for (size_t p = 0; p < d.texture.size(); ++p) {
      float blended = 0.0f;
      for (size_t i = 0; i < count; ++i) blended += static_cast<float>(weights[i]) * static_cast<float>(keyframe_textures[keys[i]][p]);
      const auto byte = static_cast<uint8_t>(std::min(std::max(blended + 0.5f, 0.0f), 255.0f));
      differing += byte != d.texture[p];
    }
    EXPECT_EQ(differing, 0u) << "t = " << t;
  }
  size_t count = 0;
  EXPECT_EQ(fm_decoder_get_texture_weights(o.decoder, 0.5, 0, nullptr, nullptr, 0, nullptr), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_decoder_get_texture_weights(o.decoder, 0.5, 0, nullptr, nullptr, 4, &count), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_decoder_get_texture_weights(o.decoder, 1e9, 0, nullptr, nullptr, 0, &count), FM_ERROR_OUT_OF_RANGE);
  EXPECT_EQ(fm_decoder_get_texture_weights(o.decoder, 1e9, FM_DECODE_CLAMP, nullptr, nullptr, 0, &count), FM_OK);
  EXPECT_EQ(fm_decoder_get_texture_weights(nullptr, 0.5, 0, nullptr, nullptr, 0, &count), FM_ERROR_INVALID_ARGUMENT);
}

TEST(CApi11, TextureWeightsRebuildTheDecodersTexture) {
  expect_weights_rebuild_the_texture(kGoldenV2_1, [](size_t k) { return static_cast<uint32_t>(k); });
}

// Format 2.2: the golden file's three keyframes show one TEXR, keyframe 0's; each is named by it.
TEST(CApi11, TextureWeightsNameTheKeyframeWhoseSharedTextureTheyShow) {
  expect_weights_rebuild_the_texture(std::filesystem::path(FACEMORPH_TEST_DATA) / "golden_v2_2.fmv", [](size_t) { return 0u; });
}

// Format 2.3: between keyframes the weights are the spline's corrected by the residual frames, and
// still rebuild the decoder's texture (a player blending the images itself shows what it shows).
TEST(CApi11, TextureWeightsIncludeTheResidualFramesCorrection) {
  expect_weights_rebuild_the_texture(std::filesystem::path(FACEMORPH_TEST_DATA) / "golden_v2_3.fmv",
                                     [](size_t k) { return static_cast<uint32_t>(k); });
}

TEST(CApi11, BorrowedBytesFilledInAfterOpeningDecodeAsACopy) {
  const std::vector<uint8_t> bytes = facemorph::format::read_file(kGoldenV2_1);
  CApiOpened copied(bytes, false);
  ASSERT_EQ(copied.status, FM_OK) << fm_last_error_message();
  std::vector<uint8_t> streamed = skeleton_of(bytes);
  CApiOpened borrowed(streamed, true);
  ASSERT_EQ(borrowed.status, FM_OK) << fm_last_error_message();
  EXPECT_EQ(borrowed.info.keyframe_count, copied.info.keyframe_count);
  EXPECT_EQ(keyframe_times(borrowed.file), keyframe_times(copied.file));
  // The rest arrives; the decoder reads it where it lies.
  std::copy(bytes.begin(), bytes.end(), streamed.begin());
  const std::vector<double> times = keyframe_times(copied.file);
  for (double t : {times.front(), 0.5 * (times.front() + times.back()), times.back()}) {
    const Decoded a = decode(copied.decoder, copied.info, t, false), b = decode(borrowed.decoder, borrowed.info, t, false);
    ASSERT_EQ(b.status, FM_OK) << fm_last_error_message();
    EXPECT_EQ(a.positions, b.positions);
  }
}

TEST(CApi11, ABorrowedGroupReadBeforeItsBytesArriveIsCorrupt) {
  const std::vector<uint8_t> bytes = facemorph::format::read_file(kGoldenV2_1);
  std::vector<uint8_t> streamed = skeleton_of(bytes);
  CApiOpened borrowed(streamed, true);
  ASSERT_EQ(borrowed.status, FM_OK) << fm_last_error_message();
  EXPECT_EQ(decode(borrowed.decoder, borrowed.info, keyframe_times(borrowed.file).front(), false).status, FM_ERROR_CORRUPT);
  EXPECT_NE(std::string(fm_last_error_message()).find("checksum"), std::string::npos) << fm_last_error_message();
  fm_file* file = nullptr;
  EXPECT_EQ(fm_file_open_memory_borrowed(nullptr, 10, nullptr, &file), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_file_open_memory_borrowed(bytes.data(), bytes.size(), nullptr, nullptr), FM_ERROR_INVALID_ARGUMENT);
  EXPECT_EQ(fm_file_open_memory_borrowed(bytes.data(), 100, nullptr, &file), FM_ERROR_TRUNCATED);
  EXPECT_EQ(file, nullptr);
}

}  // namespace
