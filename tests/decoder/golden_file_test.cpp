// Files written by earlier versions must keep decoding to the same surfaces. tests/data holds a small
// container per format version since the format was frozen (2.0 by facemorph 0.8.0), written with
// tests/data/make_golden.sh, and a sample of what it decoded to then: grid positions at keyframe
// times, between keyframes and past the ends. Format 1.x (facemorph 0.2-0.7) was experimental and
// is refused by name (experimental_v1_5.fmv, the last of them).
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "format/file_io.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#ifndef FACEMORPH_TEST_DATA
#error "FACEMORPH_TEST_DATA must name tests/data"
#endif

namespace facemorph {
namespace {

constexpr int kNodeStride = 7;  // every 7th node of G is compared (2.6's file, at N = 129, every 61st)

std::vector<double> sample_times(const Sequence& s) {
  std::vector<double> times;
  for (const Keyframe& key : s.keyframes) times.push_back(key.time);
  for (size_t k = 0; k + 1 < s.keyframes.size(); ++k) times.push_back(0.5 * (s.keyframes[k].time + s.keyframes[k + 1].time));
  const double step = 1 / s.fps;
  times.push_back(s.keyframes.front().time - step);  // extrapolated, a frame before and after
  times.push_back(s.keyframes.back().time + step);
  // Format 2.4's patches show fully only at their own times (between them they are interpolated):
  // sample those too. Files without patches keep the sample their CSV was written with.
  for (const FramePatch& patch : s.patches) times.push_back(patch.time);
  return times;
}

// Decodes tests/data/golden_v<version>.fmv at its sample times and compares with the positions it
// decoded to when it was written (golden_v<version>.csv). Every later decoder must keep decoding
// every earlier file identically.
void expect_golden(const std::string& version, uint16_t major_version, uint16_t minor_version, const std::string& encoder,
                   size_t node_stride = kNodeStride) {
  const std::filesystem::path data = FACEMORPH_TEST_DATA;
  SequenceFileInfo info;
  const auto sequence = std::make_shared<const Sequence>(read_sequence_file(data / ("golden_v" + version + ".fmv"), &info));
  EXPECT_EQ(info.major_version, major_version);
  EXPECT_EQ(info.minor_version, minor_version);
  EXPECT_EQ(info.metadata.encoder, encoder);
  SequenceDecoder decoder(sequence);
  DecodeOptions options;
  options.reconstruct.tolerance = 1e-10;  // tight, so the comparison measures the format, not the solver's stopping point
  std::ostringstream fresh;
  fresh.precision(17);
  std::vector<std::vector<double>> rows;
  for (double t : sample_times(*sequence)) {
    const DecodedFrame frame = decoder.decode(t, options);
    EXPECT_TRUE(frame.converged) << "t = " << t;
    for (size_t n = 0; n < frame.grid_positions.size(); n += node_stride) {
      const Vec3& p = frame.grid_positions[n];
      fresh << t << "," << n << "," << p.x() << "," << p.y() << "," << p.z() << "\n";
      rows.push_back({t, static_cast<double>(n), p.x(), p.y(), p.z()});
    }
  }
  if (const char* out = std::getenv("FACEMORPH_WRITE_GOLDEN")) {
    format::write_file_atomically(out, std::string_view(fresh.str()));
    GTEST_SKIP() << "wrote " << out;
  }
  std::ifstream in(data / ("golden_v" + version + ".csv"));
  ASSERT_TRUE(in) << "tests/data/golden_v" << version << ".csv is missing";
  std::string line;
  size_t row = 0;
  double worst = 0;
  while (std::getline(in, line)) {
    ASSERT_LT(row, rows.size()) << "the golden sample has more rows than this decoder produces";
    std::istringstream fields(line);
    std::vector<double> v;
    for (std::string cell; std::getline(fields, cell, ',');) v.push_back(std::stod(cell));
    ASSERT_EQ(v.size(), 5u);
    EXPECT_EQ(v[0], rows[row][0]);
    EXPECT_EQ(v[1], rows[row][1]);
    for (int c = 2; c < 5; ++c) worst = std::max(worst, std::abs(v[static_cast<size_t>(c)] - rows[row][static_cast<size_t>(c)]));
    ++row;
  }
  EXPECT_EQ(row, rows.size());
  // The face is ~0.2 m across: 1 µm. The solver stops at 1e-10 relative; platforms' rounding and
  // summation order move the result far less than this, a change of format or method far more.
  EXPECT_LT(worst, 1e-6);
}

// A golden file of format 2.y decodes as it did, and reads as written: AVIF textures of 64² in the
// given coding, groups of two keyframes (make_golden.sh). Returns the file's description.
SequenceFileInfo expect_golden_2(const std::string& version, uint16_t minor_version, TextureCoding coding,
                                 size_t node_stride = kNodeStride) {
  expect_golden(version, 2, minor_version, "facemorph 0.8.0", node_stride);
  SequenceFileInfo info;
  const Sequence s = read_sequence_file(std::filesystem::path(FACEMORPH_TEST_DATA) / ("golden_v" + version + ".fmv"), &info);
  EXPECT_EQ(info.metadata.texture_codec, TextureCodec::kAvif);
  EXPECT_EQ(info.metadata.texture_coding, coding);
  EXPECT_EQ(info.metadata.field_coding.intra_period, 2);
  EXPECT_TRUE(s.has_texture());
  EXPECT_EQ(s.keyframes.front().texture.width, 64);
  return info;
}

using testing::chunk_count;

// Format 2.0: the header, the index with every keyframe's time and pose, one KGOP chunk per group
// of keyframes, a TEXR chunk per keyframe.
TEST(GoldenFile, Version2_0DecodesAsItDidWhenWritten) {
  const SequenceFileInfo info = expect_golden_2("2_0", 0, TextureCoding::kStills);
  EXPECT_EQ(chunk_count(info, "TEXR"), static_cast<int>(info.keyframes.size()));
  EXPECT_EQ(chunk_count(info, "TGOP"), 0);
}

// Format 2.1: 2.0 with the keyframe textures as one AV1 image sequence per group of keyframes
// (TGOP; make_golden.sh's --quality 80 takes the writer's default, the sequence coding).
TEST(GoldenFile, Version2_1DecodesAsItDidWhenWritten) {
  const SequenceFileInfo info = expect_golden_2("2_1", 1, TextureCoding::kSequence);
  EXPECT_EQ(chunk_count(info, "TGOP"), static_cast<int>((info.keyframes.size() + 1) / 2));
  EXPECT_EQ(chunk_count(info, "TEXR"), 0);
}

// Format 2.2: 2.1 with keyframe textures painted from one captured image stored once, each
// keyframe's index entry naming the one TEXR (make_golden.sh's capture with --shared-texture; the
// writer takes the stills, fewer bytes than a sequence per group).
TEST(GoldenFile, Version2_2DecodesAsItDidWhenWritten) {
  const SequenceFileInfo info = expect_golden_2("2_2", 2, TextureCoding::kStills);
  EXPECT_EQ(chunk_count(info, "TEXR"), 1);
  EXPECT_EQ(info.distinct_textures, 1u);
  EXPECT_GT(info.keyframes.size(), 1u);
}

// Format 2.3: 2.2 with residual frames (RSDW), corrections of the blend between keyframes
// (make_golden.sh's capture with --speech-rate 3): the golden sample's times between keyframes
// decode with them.
TEST(GoldenFile, Version2_3DecodesAsItDidWhenWritten) {
  const SequenceFileInfo info = expect_golden_2("2_3", 3, TextureCoding::kSequence);
  EXPECT_EQ(chunk_count(info, "RSDW"), 1);
  EXPECT_GT(info.residual_frames, 0u);
}

// Format 2.4: 2.3 with frame patches (PTCH), lattice displacements of the decoded surface between
// keyframes (make_golden.sh's capture with --speech-rate 3, fmenc's defaults): the golden sample
// holds every patch's own time, where the decoder adds that patch whole.
TEST(GoldenFile, Version2_4DecodesAsItDidWhenWritten) {
  const SequenceFileInfo info = expect_golden_2("2_4", 4, TextureCoding::kSequence);
  EXPECT_EQ(chunk_count(info, "PTCH"), 1);
  const Sequence s = read_sequence_file(std::filesystem::path(FACEMORPH_TEST_DATA) / "golden_v2_4.fmv");
  ASSERT_FALSE(s.patches.empty());
  size_t moving_nodes = 0;
  for (const FramePatch& patch : s.patches) moving_nodes += patch.nodes.size();
  EXPECT_GT(moving_nodes, 0u) << "every patch is a pin: the golden file would not test the displacement";
}

// Format 2.5: 2.4 with three codings (make_golden.sh's 2.4 capture and options): the header
// compressed against the frozen header dictionary, the frame patches range-coded, and the rim's
// linear predictor where the writer finds it cheapest; the golden sample's times between keyframes
// decode with the patches.
TEST(GoldenFile, Version2_5DecodesAsItDidWhenWritten) {
  const SequenceFileInfo info = expect_golden_2("2_5", 5, TextureCoding::kSequence);
  EXPECT_EQ(chunk_count(info, "PTCH"), 1);
  ASSERT_FALSE(info.chunks.empty());
  EXPECT_EQ(info.chunks.front().type, "HEAD");
  EXPECT_GT(info.chunks.front().against_dictionary, 0) << "the header is not compressed against the dictionary";
  const Sequence s = read_sequence_file(std::filesystem::path(FACEMORPH_TEST_DATA) / "golden_v2_5.fmv");
  size_t moving_nodes = 0;
  for (const FramePatch& patch : s.patches) moving_nodes += patch.nodes.size();
  EXPECT_GT(moving_nodes, 0u) << "every patch is a pin: the golden file would not test the range-coded displacement";
}

// Format 2.6: 2.5 with the levels predictor on G's lattice in KGLV chunks (make_golden.sh's 2.5
// capture and options at N = 129, where the writer finds it cheapest for some array; every 61st node
// sampled, about as many as 2.5's every 7th at N = 33).
TEST(GoldenFile, Version2_6DecodesAsItDidWhenWritten) {
  const SequenceFileInfo info = expect_golden_2("2_6", 6, TextureCoding::kSequence, 61);
  EXPECT_GT(chunk_count(info, "KGLV"), 0) << "no group uses the levels predictor: the golden file would not test it";
  EXPECT_EQ(info.chunks.front().type, "HEAD");
}

// Format 1.x is refused by name, with what to do about it, from its preamble alone.
TEST(GoldenFile, AnExperimentalVersion1FileIsRefusedByName) {
  const std::filesystem::path file = std::filesystem::path(FACEMORPH_TEST_DATA) / "experimental_v1_5.fmv";
  testing::expect_error(ErrorCode::kUnsupported,
                        "format version 1.5 is an experimental version this decoder does not read; encode the capture again",
                        [&] { read_sequence_file(file); });
  testing::expect_error(ErrorCode::kUnsupported, "experimental version", [&] { open_sequence_source(file); });
}

}  // namespace
}  // namespace facemorph
