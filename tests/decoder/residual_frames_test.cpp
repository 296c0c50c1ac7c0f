// Residual frames (format 2.3, spec/container.md §7.4, spec/method.md §7.18): the corrected blend
// weights, analytically; continuity in t, past the ends too; the RSDW chunk's round trip to the bit
// and what a decoder shows with it; and every check of its reader.
#include "codec/core/sequence/residual_weights.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "tests/decoder/crafted_files.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstring>
#include <functional>
#include <map>

namespace facemorph {
namespace {

using crafted::rebuild;
using crafted::small_metadata;
using crafted::small_sequence;

std::map<int32_t, double> as_map(const SplineWeights& w) {
  std::map<int32_t, double> m;
  for (size_t i = 0; i < w.keys.size(); ++i) m[w.keys[i]] = w.weights[i];
  return m;
}

// Key k's weight at t (0 where the blend leaves it out).
double weight(const SplineWeights& w, int32_t k) {
  const auto m = as_map(w);
  const auto it = m.find(k);
  return it == m.end() ? 0.0 : it->second;
}

// Four keyframes 0.5 s apart; interval 0 (keys 0..2 in its window) has residuals at 0.2 and 0.3,
// interval 1 (keys 0..3) one at 0.8, interval 2 none.
struct Fixture {
  KeyframeSpline spline{{0.0, 0.5, 1.0, 1.5}, SplineKind::kCatmullRom};
  std::vector<ResidualFrame> residuals = {{0.2, {0.25, -0.5, 0.25}}, {0.3, {-0.125, 0.0, 0.125}}, {0.8, {0.5, -0.25, -0.125, -0.125}}};
};

TEST(ResidualFrames, TheWeightsAreTheSplinesPlusTheCorrectionInterpolatedBetweenNodes) {
  const Fixture f;
  ASSERT_NO_THROW(validate_residuals(f.spline.times(), f.residuals));
  EXPECT_EQ(residual_window(0, 4).first, 0);
  EXPECT_EQ(residual_window(0, 4).count, 3);
  EXPECT_EQ(residual_window(1, 4).count, 4);
  EXPECT_EQ(residual_window(2, 4).first, 1);
  EXPECT_EQ(residual_window(2, 4).count, 3);
  // (t, the correction expected there, per key 0..3): at a residual its own; between two the mean
  // at the midpoint; between a keyframe (0) and a residual, the line from 0.
  const std::vector<std::pair<double, std::array<double, 4>>> expected = {
      {0.2, {0.25, -0.5, 0.25, 0}},
      {0.25, {0.0625, -0.25, 0.1875, 0}},
      {0.3, {-0.125, 0, 0.125, 0}},
      {0.1, {0.125, -0.25, 0.125, 0}},           // u = 1/2 from keyframe 0 to the residual at 0.2
      {0.4, {-0.0625, 0, 0.0625, 0}},            // u = 1/2 from 0.3 to keyframe 1
      {0.65, {0.25, -0.125, -0.0625, -0.0625}},  // from keyframe 1 (0.5) to 0.8: u = 1/2
      {0.9, {0.25, -0.125, -0.0625, -0.0625}},   // from 0.8 to keyframe 2 (1.0): u = 1/2
  };
  for (const auto& [t, delta] : expected) {
    SCOPED_TRACE(t);
    const SplineWeights spline = f.spline.weights(t), with = residual_weights(f.spline, f.residuals, t);
    double sum = 0;
    for (int32_t k = 0; k < 4; ++k) {
      EXPECT_NEAR(weight(with, k), weight(spline, k) + delta[static_cast<size_t>(k)], 1e-15) << k;
      sum += weight(with, k);
    }
    EXPECT_NEAR(sum, 1.0, 1e-14);
    EXPECT_TRUE(std::is_sorted(with.keys.begin(), with.keys.end()));
  }
  // At a keyframe, in an interval without residuals and past either end: the spline's, to the bit.
  for (double t : {0.0, 0.5, 1.0, 1.2, 1.5, -0.3, 1.9}) {
    SCOPED_TRACE(t);
    const SplineWeights spline = f.spline.weights(t), with = residual_weights(f.spline, f.residuals, t);
    EXPECT_EQ(with.keys, spline.keys);
    EXPECT_EQ(with.weights, spline.weights);
  }
  EXPECT_EQ(residual_max_keys(f.spline, f.residuals), 4);
  // A linear spline blends 2 keys; a residual's window 4.
  const KeyframeSpline linear({0.0, 0.5, 1.0, 1.5}, SplineKind::kLinear);
  EXPECT_EQ(residual_max_keys(linear, {}), 2);
  EXPECT_EQ(residual_max_keys(linear, f.residuals), 4);
  EXPECT_EQ(residual_weights(linear, f.residuals, 0.8).keys.size(), 4u);
}

// Every key's weight moves by at most (a bound on its slope) x the step, everywhere from a second
// before the first keyframe to a second after the last: no jump where a residual's correction
// starts or ends (a correction not back to 0 at a keyframe would jump there by up to 0.5).
TEST(ResidualFrames, TheBlendIsContinuousInTimeAndExtrapolationIsTheSplines) {
  const Fixture f;
  const double h = 1e-4;
  double worst = 0;
  SplineWeights before = residual_weights(f.spline, f.residuals, -1.0);
  for (double t = -1.0 + h; t <= 2.5; t += h) {
    const SplineWeights now = residual_weights(f.spline, f.residuals, t);
    for (int32_t k = 0; k < 4; ++k) worst = std::max(worst, std::abs(weight(now, k) - weight(before, k)));
    before = now;
  }
  // Slopes: the spline's (a few per second) plus |δ| / Δτ (0.5 / 0.1 s = 5 per second, 0.625 / 0.1 s).
  EXPECT_LT(worst, 12 * h);
  // Extrapolated, the weights are the spline's (ResidualFrames.TheWeightsAre... checks -0.3, 1.9).
}

TEST(ResidualFrames, ValidationRefusesWhatTheBlendCannotUse) {
  const std::vector<double> times = {0.0, 0.5, 1.0, 1.5};
  const auto refused = [&](std::vector<ResidualFrame> r, const std::string& fragment) {
    testing::expect_error(ErrorCode::kInvalidArgument, fragment, [&] { validate_residuals(times, r); });
  };
  refused({{0.5, {0.25, -0.25, 0, 0}}}, "not strictly between two keyframes");  // at a keyframe
  refused({{-0.1, {0.25, -0.25, 0}}}, "not strictly between two keyframes");    // before the first
  refused({{1.6, {0.25, -0.25, 0}}}, "not strictly between two keyframes");     // after the last
  refused({{0.2, {0.25, -0.25}}}, "2 corrections where its keyframe interval has 3 keys");
  refused({{0.2, {0.25, -0.25, 0}}, {0.1, {0.25, -0.25, 0}}}, "times must increase");
  refused({{0.2, {0.25, -0.25, 0.1}}}, "sum to");
  refused({{0.2, {5.0, -5.0, 0}}}, "beyond");
  refused({{0.2, {std::nan(""), 0, 0}}}, "not finite");
  refused({{std::nan(""), {0.25, -0.25, 0}}}, "not finite");
  EXPECT_NO_THROW(validate_residuals(times, {}));
}

// small_sequence's keyframes at 0, 0.5 and 1 s (30 fps) with two residual frames on the file's
// lattice (64ths of a frame period: 0.25 s is 480 of them, 0.75 s 1440).
Sequence with_residuals() {
  Sequence s = small_sequence(9, 8);
  s.residuals = {{0.25, {0.25, -0.125, -0.125}}, {0.75, {-0.0625, -0.0625, 0.125}}};
  return s;
}

std::vector<uint8_t> residual_file() { return encode_sequence_file(with_residuals(), small_metadata()); }

using testing::chunk_count;

TEST(ResidualFrames, AFileHoldsThemToTheBitAndADecoderShowsThem) {
  const Sequence s = with_residuals();
  SequenceFileInfo info;
  // The file's keyframes are its fields rounded: the decoders below compare on those.
  const Sequence back = decode_sequence_file(residual_file(), "residuals.fmv", &info);
  ASSERT_EQ(back.residuals.size(), s.residuals.size());
  for (size_t r = 0; r < s.residuals.size(); ++r) {
    EXPECT_EQ(back.residuals[r].time, s.residuals[r].time);
    EXPECT_EQ(back.residuals[r].delta, s.residuals[r].delta);
  }
  EXPECT_EQ(info.minor_version, format::kMinorVersion);  // stamped with the writer's version
  EXPECT_EQ(info.residual_frames, 2u);
  EXPECT_EQ(chunk_count(info, "RSDW"), 1);
  // The file's frame at a residual's time is the sequence's, and not the spline's alone.
  const auto from_file = open_sequence_source(residual_file(), "residuals.fmv");
  ASSERT_EQ(from_file->outline().residuals.size(), 2u);
  SequenceDecoder file_decoder(from_file), memory_decoder(std::make_shared<const Sequence>(back));
  Sequence plain = back;
  plain.residuals.clear();
  SequenceDecoder plain_decoder(std::make_shared<const Sequence>(plain));
  DecodeOptions o;
  o.continue_correction = false;
  for (double t : {0.25, 0.6, 0.75}) {
    SCOPED_TRACE(t);
    const DecodedFrame a = file_decoder.decode(t, o), b = memory_decoder.decode(t, o), c = plain_decoder.decode(t, o);
    EXPECT_EQ(a.grid_positions, b.grid_positions);
    EXPECT_EQ(a.texture.pixels, b.texture.pixels);
    EXPECT_EQ(a.hole_level, b.hole_level);
    double apart = 0;
    for (size_t n = 0; n < a.grid_positions.size(); ++n) apart = std::max(apart, (a.grid_positions[n] - c.grid_positions[n]).norm());
    // The keyframes' shapes are one quadric at amplitudes 0.2, 0.3, 0.4: the corrections change the
    // blend's amplitude by -0.0375 at 0.25 s and +0.01875 at 0.75 s (0.6 s: from both).
    EXPECT_GT(apart, 5e-3);
    // The texture blends with the corrected weights, as the fields (spec/container.md §7.4; on
    // fast speech this measured 0.9 dB closer than the spline's weights, spec/method.md §7.18).
    EXPECT_EQ(a.texture.pixels, blend_textures(back, a.weights).pixels);
    EXPECT_NE(a.texture.pixels, c.texture.pixels);
    // The head pose keeps the spline's weights.
    EXPECT_TRUE(a.pose.rotation.isApprox(c.pose.rotation, 1e-15));
    EXPECT_TRUE(a.pose.translation.isApprox(c.pose.translation, 1e-15));
  }
  // Without residual frames no RSDW is written.
  SequenceFileInfo plain_info;
  decode_sequence_file(encode_sequence_file(plain, small_metadata()), "plain.fmv", &plain_info);
  EXPECT_EQ(chunk_count(plain_info, "RSDW"), 0);
  EXPECT_EQ(plain_info.residual_frames, 0u);
}

TEST(ResidualFrames, TheWriterRefusesWhatTheFileCannotHoldExactly) {
  Sequence s = with_residuals();
  s.residuals[0].time = 0.25 + 1e-9;  // off the 64th-of-a-frame lattice
  testing::expect_error(ErrorCode::kInvalidArgument, "64th of a frame period", [&] { encode_sequence_file(s, small_metadata()); });
  s = with_residuals();
  s.residuals[0].delta = {1e-12, -1e-12, 0};  // not a multiple of 2^-30
  testing::expect_error(ErrorCode::kInvalidArgument, "not multiples of 2^-30", [&] { encode_sequence_file(s, small_metadata()); });
  // The encoder's helper moves times to the lattice and drops one that would leave its interval.
  const std::vector<ResidualFrame> moved =
      residuals_on_file_times({{0.25 + 1e-9, {0.25, -0.125, -0.125}}, {0.5 - 1e-6, {0.25, -0.125, -0.125}}}, {0.0, 0.5, 1.0}, 0.0, 30.0);
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_EQ(moved[0].time, 0.25);
}

// The RSDW payload of residual_file(), edited by `change`.
std::vector<uint8_t> with_payload(const std::function<void(std::vector<uint8_t>&)>& change) {
  return crafted::with_chunk_payload(residual_file(), "RSDW", change);
}

// Its payload: u32 count 2, u8 e = 4 (corrections in 16ths), then 480 (zigzag 960: 0xC0 0x07), codes
// 4 and -2 (zigzag 8, 3); 960 (0x80 0x0F), codes -1 and -1 (zigzag 1, 1).
TEST(ResidualFrames, EveryCheckOfTheChunkRefusesABadOneByName) {
  const std::vector<uint8_t> good = residual_file();
  ASSERT_EQ(crafted::chunk_payload(good, "RSDW"), (std::vector<uint8_t>{2, 0, 0, 0, 4, 0xC0, 0x07, 8, 3, 0x80, 0x0F, 1, 1}));
  const auto corrupt = [](const std::vector<uint8_t>& bytes, const std::string& fragment) {
    testing::expect_error(ErrorCode::kCorrupt, fragment, [&] { open_sequence_source(bytes, "crafted.fmv"); });
    testing::expect_error(ErrorCode::kCorrupt, fragment, [&] { decode_sequence_file(bytes, "crafted.fmv"); });
  };
  corrupt(with_payload([](auto& p) { p[0] = 0; }), "states 0 residual frames");
  corrupt(with_payload([](auto& p) { p[0] = 7; }), "states 7 residual frames");  // its 9 bytes hold 4
  corrupt(with_payload([](auto& p) { p[3] = 0x10; }), "residual frames");        // 2^28 + 2
  corrupt(with_payload([](auto& p) { p[4] = 31; }), "step exponent 31");
  corrupt(with_payload([](auto& p) {
            p[9] = 0;
            p[10] = 0;
          }),
          "residual frame 1: its time does not come after");  // a change of 0
  corrupt(with_payload([](auto& p) {
            p[9] = 0x80;
            p[10] = 0x2F;
          }),
          "residual frame 1: its time");  // q = 3488: 1.82 s, past the last keyframe
  corrupt(with_payload([](auto& p) {
            p[7] = 0x80;
            p[8] = 0x02;
          }),
          "a correction beyond");  // code 128 > 4 x 16
  corrupt(with_payload([](auto& p) {
            p[11] = 0x7E;
            p[12] = 0x7E;
          }),
          "last correction");  // 63 + 63: their sum is beyond
  corrupt(with_payload([](auto& p) { p.push_back(0); }), "1 bytes after its last field");
  testing::expect_error(ErrorCode::kTruncated, "a residual correction",
                        [&] { open_sequence_source(with_payload([](auto& p) { p.resize(11); }), "crafted.fmv"); });
  // Two RSDW chunks in a 2.3 file: the extra chunk rebuild adds, renamed.
  const std::vector<uint8_t> two = rebuild(rebuild(
                                               good, [](const std::string&, std::vector<uint8_t>&) {}, true),
                                           [&](std::string& type, std::vector<uint8_t>& payload) {
                                             if (type == "ZZZ1") {
                                               type = "RSDW";
                                               payload = {2, 0, 0, 0, 4, 0xC0, 0x07, 8, 3, 0x80, 0x0F, 1, 1};
                                             }
                                           });
  corrupt(two, "two RSDW chunks");
}

// A file stamped 2.2 with an RSDW chunk: skipped, as a 2.2 decoder skips a chunk it does not know,
// so the frames are the spline's alone.
TEST(ResidualFrames, InAFileOfAnEarlierMinorVersionTheChunkIsSkipped) {
  const std::vector<uint8_t> bytes = crafted::with_minor_version(residual_file(), 2);
  const auto source = open_sequence_source(bytes, "v2_2.fmv");
  EXPECT_TRUE(source->outline().residuals.empty());
  EXPECT_TRUE(decode_sequence_file(bytes, "v2_2.fmv").residuals.empty());
}

}  // namespace
}  // namespace facemorph
