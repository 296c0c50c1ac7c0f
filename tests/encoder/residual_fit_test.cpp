// Residual frames fitted to the stored keyframes (codec/encoder/encode/residual_fit.hpp, spec/method.md
// §7.18): the least-squares correction itself, and on an encoded fast-speech capture that the
// residuals lower what a decoder shows against the captured frames, never make a frame worse, reach
// the file to the bit, and leave keyframes and extrapolation as the spline has them.
#include "codec/encoder/encode/residual_fit.hpp"
#include "codec/encoder/keyframes/blend_correction.hpp"

#include "codec/decoder/container/sequence_file.hpp"
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/encode/encode_settings.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/encode/stored_sequence.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"
#include "tests/encoder/encoder_stages.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

namespace facemorph {
namespace {

// Offsets made by a known correction (multiples of the step, summing to 0) of four random columns:
// the fit finds that correction exactly and leaves nothing; past ±1 it clamps; below two keys none.
TEST(ResidualFit, TheCorrectionCancelsOffsetsMadeByAKnownBlend) {
  std::mt19937 random(3);
  std::normal_distribution<double> normal;
  const size_t nodes = 200;
  std::vector<std::vector<double>> columns(4, std::vector<double>(nodes));
  std::vector<double> weights(nodes);
  for (auto& c : columns) {
    for (double& a : c) a = normal(random);
  }
  for (double& w : weights) w = 0.5 + std::abs(normal(random));
  const std::vector<double> known = {0.25, -0.375, 0.0625, 0.0625};
  std::vector<double> offsets(nodes, 0.0);
  for (size_t v = 0; v < nodes; ++v) {
    for (size_t m = 0; m < 4; ++m) offsets[v] -= known[m] * columns[m][v];
  }
  std::vector<double> delta;
  const double left = fit_blend_correction(offsets, columns, weights, 1.0 / 128, delta);
  ASSERT_EQ(delta.size(), 4u);
  for (size_t m = 0; m < 4; ++m) EXPECT_NEAR(delta[m], known[m], 1e-12) << m;
  EXPECT_NEAR(left, 0.0, 1e-18);
  // Twice as far along a blend that sums to 0: clamped to ±1, the last still minus the others' sum.
  for (double& o : offsets) o *= 8;
  fit_blend_correction(offsets, columns, weights, 1.0 / 128, delta);
  EXPECT_EQ(delta[1], -1.0);
  EXPECT_EQ(delta[0] + delta[1] + delta[2] + delta[3], 0.0);
  std::vector<std::vector<double>> one = {columns[0]};
  EXPECT_TRUE(std::isinf(fit_blend_correction(offsets, one, weights, 1.0 / 128, delta)));
  EXPECT_TRUE(delta.empty());
}

constexpr int kResidualTestGrid = 33;

// A fast-speech capture at a few thousand vertices (fmsynth --expression talk --speech-rate 3):
// the mouth opens and shuts between keyframes a 10% budget spreads over it.
struct FastSpeech {
  testing::TempDir dir;
  Capture capture;
  std::unique_ptr<SequenceEncoder> encoder;
  std::vector<int> keyframes;
  explicit FastSpeech(bool select = true) {
    SynthOptions synth = testing::fast_speech_options(24);
    synth.remesh = true;
    synth.texture_size = 64;
    write_synthetic_capture(dir.path(), synth);
    capture = read_capture(dir.path());
    if (!select) return;
    EncodeOptions options;
    options.grid = kResidualTestGrid;
    options.texture = false;
    encoder = std::make_unique<SequenceEncoder>(capture, options);
    testing::run_to_selection(*encoder);
    keyframes = select_keyframes(plan_settings(encoder->options()), encoder->selection()).keyframes;
  }
};

// Point-to-surface RMS of the decoded frame against the captured one, over its diagonal (as
// fmbench --capture measures): not the measure the fit uses (offsets on G along the normals).
double decoded_error(SequenceDecoder& decoder, const Capture& capture, size_t i) {
  const SurfaceDistance d = surface_distance(read_mesh(capture.mesh_path(i)), decoder.decode(capture.frames[i].time).mesh);
  return d.rms / d.diagonal;
}

TEST(ResidualFit, FittedToTheStoredKeyframesTheyLowerTheDecodedErrorAndReachTheFile) {
  FastSpeech fast;
  ASSERT_GE(fast.keyframes.size(), 2u);
  ASSERT_LT(fast.keyframes.size(), 6u) << "the budget should leave the mouth's motion to the spline";
  std::unique_ptr<StoredSequence> stored = fast.encoder->build(build_settings(fast.encoder->options()), fast.keyframes, kResidualTestGrid);
  ResidualFitReport report;
  const std::vector<ResidualFrame> residuals =
      fit_decoded_residuals(registered_frames(*fast.encoder), *stored, fast.keyframes, 1.0 / 128, &report);
  EXPECT_TRUE(stored->shape().residuals.empty());  // left as it was
  ASSERT_GT(residuals.size(), 5u);
  // On two threads, one decoder each: the same residuals to the bit.
  const std::vector<ResidualFrame> on_two =
      fit_decoded_residuals(registered_frames(*fast.encoder), *stored, fast.keyframes, 1.0 / 128, nullptr, 2);
  ASSERT_EQ(on_two.size(), residuals.size());
  for (size_t r = 0; r < residuals.size(); ++r) {
    EXPECT_EQ(on_two[r].time, residuals[r].time);
    EXPECT_EQ(on_two[r].delta, residuals[r].delta);
  }
  EXPECT_EQ(report.residuals, static_cast<int>(residuals.size()));
  EXPECT_GT(report.frames_improved, 0);
  EXPECT_LT(report.mean_after, report.mean_before);
  EXPECT_LE(report.worst_after, report.worst_before);
  for (const ResidualFrame& r : residuals) {
    double sum = 0;
    for (double d : r.delta) {
      EXPECT_EQ(d * 128, std::round(d * 128));
      EXPECT_LE(std::abs(d), 1.0);
      sum += d;
    }
    EXPECT_EQ(sum, 0.0);
  }
  const std::shared_ptr<const Sequence> plain = std::make_shared<const Sequence>(stored->to_sequence());
  stored->set_residuals(residuals);
  // Through a file: the residuals come back to the bit, and the frames decode as from memory.
  const std::vector<uint8_t> bytes = encode_sequence_file(stored->to_sequence(), {});
  const std::shared_ptr<const Sequence> with = std::make_shared<const Sequence>(decode_sequence_file(bytes, "fast.fmv"));
  ASSERT_EQ(with->residuals.size(), residuals.size());
  for (size_t r = 0; r < residuals.size(); ++r) {
    EXPECT_EQ(with->residuals[r].time, residuals[r].time);
    EXPECT_EQ(with->residuals[r].delta, residuals[r].delta);
  }
  const std::shared_ptr<const Sequence> plain_file =
      std::make_shared<const Sequence>(decode_sequence_file(encode_sequence_file(*plain, {}), "plain.fmv"));
  SequenceDecoder a(with), b(plain_file);
  // Against the captured frames: the held-out mean falls, and no frame is worse beyond the
  // reconstruction's tolerance.
  double sum_with = 0, sum_without = 0;
  int held = 0;
  for (size_t i = 0; i < fast.capture.frames.size(); ++i) {
    if (std::binary_search(fast.keyframes.begin(), fast.keyframes.end(), static_cast<int>(i))) continue;
    const double e_with = decoded_error(a, fast.capture, i), e_without = decoded_error(b, fast.capture, i);
    EXPECT_LE(e_with, e_without * 1.02 + 1e-6) << "frame " << i;
    sum_with += e_with;
    sum_without += e_without;
    ++held;
  }
  ASSERT_GT(held, 0);
  EXPECT_LT(sum_with, 0.97 * sum_without) << "held-out mean " << sum_with / held << " with residuals, " << sum_without / held << " without";
  // At a keyframe and past either end (extrapolation) the frame is the spline's, to the bit; near
  // the ends it moves continuously into them.
  DecodeOptions past;
  past.ignore_sane_range = true;
  past.continue_correction = false;
  const double first = with->keyframes.front().time, last = with->keyframes.back().time;
  for (double t : {first, with->keyframes[1].time, last, first - 0.02, last + 0.02}) {
    SCOPED_TRACE(t);
    EXPECT_EQ(a.decode(t, past).grid_positions, b.decode(t, past).grid_positions);
  }
  const double h = 1e-5;
  for (double t : {first, last, residuals.front().time, residuals.back().time}) {
    SCOPED_TRACE(t);
    const DecodedFrame before = a.decode(t - h, past), after = a.decode(t + h, past);
    double apart = 0;
    for (size_t n = 0; n < before.grid_positions.size(); ++n)
      apart = std::max(apart, (before.grid_positions[n] - after.grid_positions[n]).norm());
    EXPECT_LT(apart, 1e-4 * fast.encoder->selection().frames().front().diagonal);
  }
}

// EncodeOptions::residual_frames end to end, with the keep rule (residuals_pay): at the default budget
// (2 keyframes of 24, which no residual can cut) the encoder keeps none, and the file and its
// settings are those of the encode without them, byte for byte; at a budget the residuals cut the
// sequence carries what the fit kept, and the report says so.
TEST(ResidualFit, TheEncoderKeepsResidualsOnlyWhereTheyTakeKeyframesPlaces) {
  const FastSpeech fast(false);
  EncodeOptions options;
  options.grid = kResidualTestGrid;
  options.texture = false;
  ASSERT_TRUE(options.residual_frames) << "on by default";
  const auto file_of = [&](EncodeReport& report) {
    const std::unique_ptr<StoredSequence> stored = encode_capture_stored(fast.capture, options, &report);
    SequenceFileMetadata metadata;
    metadata.settings = encode_settings_json(options, report);
    return encode_sequence_file(stored->to_sequence(), metadata);
  };
  EncodeReport with_report, without_report;
  const std::vector<uint8_t> with = file_of(with_report);
  EXPECT_EQ(with_report.keyframes.size(), 2u);
  EXPECT_EQ(with_report.residual_fit.keyframes_saved, 0);
  EXPECT_EQ(with_report.residual_fit.residuals, 0);
  options.residual_frames = false;
  EXPECT_TRUE(with == file_of(without_report)) << "no residual kept: the file without them, byte for byte";
  options.residual_frames = true;
  options.keyframe_fraction = 0.25;
  EncodeReport traded;
  const std::unique_ptr<StoredSequence> stored = encode_capture_stored(fast.capture, options, &traded);
  EXPECT_GT(traded.residual_fit.keyframes_saved, 0);
  EXPECT_EQ(traded.residual_fit.residuals, static_cast<int>(stored->shape().residuals.size()));
  EXPECT_GT(stored->shape().residuals.size(), 5u);
  EXPECT_LT(traded.residual_fit.mean_after, traded.residual_fit.mean_before);
  options.residual_frames = false;
  EXPECT_TRUE(encode_capture_stored(fast.capture, options).get()->shape().residuals.empty());
}

}  // namespace
}  // namespace facemorph
