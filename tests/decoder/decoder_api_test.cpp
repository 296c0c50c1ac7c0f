// The C++ player API (facemorph/decoder.hpp, header-only over the C API) as a player uses it: built
// as C++17, linked to libfacemorph_decoder.so.1 alone, no internal header in sight.
#include <facemorph/decoder.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <type_traits>
#include <vector>

namespace {

const std::string kGolden = std::string(FACEMORPH_TEST_DATA) + "/golden_v2_0.fmv";

static_assert(!std::is_copy_constructible_v<fm::File> && std::is_nothrow_move_constructible_v<fm::File>);
static_assert(!std::is_copy_constructible_v<fm::Decoder> && std::is_nothrow_move_constructible_v<fm::Decoder>);

TEST(DecoderApi, OpensAndDecodesEveryOutputIntoReusedArrays) {
  const fm::File file = fm::File::open(kGolden);
  const fm_info info = file.info();
  EXPECT_EQ(info.struct_size, sizeof(fm_info));
  EXPECT_EQ(info.grid_n, 33u);
  EXPECT_EQ(file.keyframe_times().size(), info.keyframe_count);
  fm::Decoder decoder(file);
  fm::Frame frame;
  decoder.decode(0.2, frame);
  EXPECT_EQ(frame.vertex_count, 850u);
  EXPECT_DOUBLE_EQ(frame.time, 0.2);
  ASSERT_EQ(frame.positions.size(), 3u * frame.vertex_count);
  ASSERT_EQ(frame.normals.size(), 3u * frame.vertex_count);
  ASSERT_EQ(frame.uvs.size(), 2u * frame.vertex_count);
  ASSERT_EQ(frame.indices.size(), 3u * frame.triangle_count);
  ASSERT_EQ(frame.texture.size(), 4u * frame.texture_size * frame.texture_size);
  for (float x : frame.positions) ASSERT_TRUE(std::isfinite(x));
  for (uint32_t v : frame.indices) ASSERT_LT(v, frame.vertex_count);
  // Another time into the same arrays: same topology, no new allocation.
  const float* positions = frame.positions.data();
  const std::vector<float> first = frame.positions;
  decoder.decode(0.3, frame);
  EXPECT_EQ(frame.positions.data(), positions);
  EXPECT_NE(frame.positions, first);
  // Only what is asked for.
  decoder.decode(0.3, frame, fm::kPositions);
  EXPECT_EQ(frame.positions.size(), 3u * frame.vertex_count);
  EXPECT_TRUE(frame.normals.empty() && frame.uvs.empty() && frame.indices.empty() && frame.texture.empty());
}

TEST(DecoderApi, StatusesAreExceptionsThatNameThem) {
  try {
    fm::File::open("/nonexistent/face.fmv");
    FAIL() << "a missing file opened";
  } catch (const fm::Error& e) {
    EXPECT_EQ(e.status(), FM_ERROR_IO);
    EXPECT_EQ(std::string(e.what()).rfind("io: fm_file_open_with_options: ", 0), 0u) << e.what();
  }
  fm_decoder_options options = fm::default_options();
  options.max_grid_n = 17;  // the golden file's grid is 33
  try {
    fm::File::open(kGolden, options);
    FAIL() << "opened over the limit";
  } catch (const fm::Error& e) {
    EXPECT_EQ(e.status(), FM_ERROR_LIMIT);
  }
  const fm::File file = fm::File::open(kGolden);
  fm::Decoder decoder(file);
  fm::Frame frame;
  try {
    decoder.decode(1000, frame);
    FAIL() << "decoded outside the range";
  } catch (const fm::Error& e) {
    EXPECT_EQ(e.status(), FM_ERROR_OUT_OF_RANGE);
  }
  decoder.decode(1000, frame, fm::kPositions, fm::kClamp);
  EXPECT_DOUBLE_EQ(frame.time, file.info().range_end);
}

TEST(DecoderApi, DecodeIntoTheCallersBuffersSaysWhatIsNeeded) {
  const fm::File file = fm::File::open(kGolden);
  fm::Decoder decoder(file);
  std::vector<float> positions(3);
  fm_frame frame;
  fm_frame_init(&frame);
  frame.positions = positions.data();
  frame.positions_bytes = sizeof(float) * positions.size();
  try {
    decoder.decode_into(0.2, frame);
    FAIL() << "three floats held 850 vertices";
  } catch (const fm::Error& e) {
    EXPECT_EQ(e.status(), FM_ERROR_BUFFER_TOO_SMALL);
  }
  EXPECT_EQ(frame.vertex_count, 850u);
  positions.resize(3 * frame.vertex_count);
  frame.positions = positions.data();
  frame.positions_bytes = sizeof(float) * positions.size();
  decoder.decode_into(0.2, frame);
  EXPECT_TRUE(std::isfinite(positions.back()));
}

TEST(DecoderApi, DecodersOutliveTheirFileAndDecodeOnThreads) {
  std::ifstream in(kGolden, std::ios::binary);
  const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  std::vector<fm::Decoder> decoders;
  {
    fm::File file = fm::File::open_memory(bytes.data(), bytes.size());
    fm::File moved = std::move(file);  // the moved-from File closes nothing
    decoders.emplace_back(moved);
    decoders.emplace_back(moved);
  }
  std::vector<uint32_t> counts(2);
  std::vector<std::thread> threads;
  for (size_t i = 0; i < decoders.size(); ++i) {
    threads.emplace_back([&, i] {
      fm::Frame frame;
      decoders[i].decode(0.1 + 0.1 * static_cast<double>(i), frame, fm::kPositions);
      counts[i] = frame.vertex_count;
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(counts, (std::vector<uint32_t>{850, 850}));
}

// API 1.1 through the wrapper: a File on borrowed bytes decodes as one on the path, bit for bit; the
// texture weights, blended as facemorph.h documents over the keyframes' own textures, are the
// decoded texture byte for byte.
TEST(DecoderApi, BorrowedBytesAndTextureWeightsAsTheCApi) {
  std::ifstream in(kGolden, std::ios::binary);
  const std::vector<char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const fm::File borrowed = fm::File::open_memory_borrowed(bytes.data(), bytes.size());
  const fm::File opened = fm::File::open(kGolden);
  fm::Decoder on_bytes(borrowed), on_path(opened);
  fm::Frame a, b;
  on_bytes.decode(0.25, a);
  on_path.decode(0.25, b);
  EXPECT_EQ(a.positions, b.positions);
  EXPECT_EQ(a.texture, b.texture);

  const std::vector<double> times = opened.keyframe_times();
  ASSERT_GE(times.size(), 2u);
  ASSERT_GT(b.texture_size, 0u);
  std::vector<std::vector<uint8_t>> keyframe_textures;
  for (size_t k = 0; k < times.size(); ++k) {
    const fm::Decoder::TextureWeights alone = on_path.texture_weights(times[k]);
    ASSERT_EQ(alone.keyframes, std::vector<uint32_t>{static_cast<uint32_t>(k)});
    EXPECT_EQ(alone.weights, std::vector<double>{1.0});
    fm::Frame frame;
    on_path.decode(times[k], frame, fm::kTexture);
    keyframe_textures.push_back(frame.texture);
  }
  const double t = times.front() + 0.4 * (times.back() - times.front());
  const fm::Decoder::TextureWeights blend = on_path.texture_weights(t);
  ASSERT_GE(blend.keyframes.size(), 2u);
  ASSERT_EQ(blend.weights.size(), blend.keyframes.size());
  fm::Frame frame;
  on_path.decode(t, frame, fm::kTexture);
  for (size_t i = 0; i < frame.texture.size(); ++i) {
    float texel = 0;
    for (size_t j = 0; j < blend.keyframes.size(); ++j) {
      texel += static_cast<float>(blend.weights[j]) * static_cast<float>(keyframe_textures.at(blend.keyframes[j])[i]);
    }
    const float rounded = std::min(255.0f, std::max(0.0f, texel + 0.5f));
    ASSERT_EQ(frame.texture[i], static_cast<uint8_t>(rounded)) << "texel byte " << i;
  }
  // Past the file without kClamp: the wrapper throws the C API's status.
  try {
    on_bytes.texture_weights(1e9);
    FAIL() << "t = 1e9 s gave texture weights";
  } catch (const fm::Error& e) {
    EXPECT_EQ(e.status(), FM_ERROR_OUT_OF_RANGE);
  }
}

// API 1.3 through the wrapper and the shared library: the double arrays round to the float ones,
// a file without holes has no hole levels, the default tolerance is FM_DEFAULT_TOLERANCE (a decoder
// set to it decodes the same bits), a coarser one takes fewer iterations, and a bad one is refused.
TEST(DecoderApi, DoubleArraysAndToleranceOfApi1_3) {
  const fm::File file = fm::File::open(kGolden);
  fm::Decoder decoder(file), coarse(file), set_to_default(file);
  set_to_default.set_tolerance(FM_DEFAULT_TOLERANCE);
  coarse.set_tolerance(1e-3);
  fm::Frame frame, again, rough;
  uint32_t iterations = 0, coarse_iterations = 0;
  for (double t : {0.1, 0.2, 0.3}) {
    decoder.decode(t, frame, fm::kPositions | fm::kUvs | fm::kPositionsF64 | fm::kUvsF64 | fm::kHoleLevels);
    ASSERT_EQ(frame.positions_f64.size(), 3u * frame.vertex_count);
    ASSERT_EQ(frame.uvs_f64.size(), 2u * frame.vertex_count);
    for (size_t i = 0; i < frame.positions.size(); ++i) ASSERT_EQ(frame.positions[i], static_cast<float>(frame.positions_f64[i]));
    for (size_t i = 0; i < frame.uvs.size(); ++i) ASSERT_EQ(frame.uvs[i], static_cast<float>(frame.uvs_f64[i]));
    EXPECT_EQ(frame.hole_level_count, 0u);
    EXPECT_TRUE(frame.hole_levels.empty());
    set_to_default.decode(t, again, fm::kPositionsF64);
    EXPECT_EQ(again.positions_f64, frame.positions_f64);
    coarse.decode(t, rough, fm::kPositionsF64);
    EXPECT_NE(rough.positions_f64, frame.positions_f64);
    iterations += frame.iterations;
    coarse_iterations += rough.iterations;
  }
  EXPECT_LT(coarse_iterations, iterations);
  for (double bad : {0.0, 0.5, std::nan("")}) {
    try {
      decoder.set_tolerance(bad);
      FAIL() << "tolerance " << bad << " accepted";
    } catch (const fm::Error& e) {
      EXPECT_EQ(e.status(), FM_ERROR_INVALID_ARGUMENT);
      EXPECT_NE(std::string(e.what()).find("fm_decoder_set_tolerance: "), std::string::npos) << e.what();
    }
  }
}

}  // namespace
