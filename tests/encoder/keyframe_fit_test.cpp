// The keyframe fit (spec/method.md §7.5, EncodeOptions::keyframe_fit): each keyframe stores the
// values whose spline best matches every frame of the capture, not its own frame. On a noisy
// capture that averages each frame's noise away with its neighbours'; on a clean one it barely
// moves the keyframes.
#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "tests/encoder/encoder_stages.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>

namespace facemorph {
namespace {

constexpr int kFrames = 24;
constexpr int kGrid = 65;

Capture synthetic_capture(const testing::TempDir& dir, double noise) {
  SynthOptions options;
  options.frames = kFrames;
  options.vertices = 3000;
  options.remesh = true;
  options.noise = noise;
  options.texture_size = 64;
  write_synthetic_capture(dir.path(), options);
  return read_capture(dir.path());
}

struct BothFits {
  std::vector<int> keyframes;
  std::shared_ptr<const Sequence> fitted, interpolating;
};

// One mapping, registration and selection; the keyframes built with and without the fit.
BothFits encode_both(const Capture& capture) {
  EncodeOptions options;
  options.keyframe_fraction = 0.25;
  options.grid = kGrid;
  options.texture = false;
  options.residual_frames = false;  // the spline's own keyframes: built here without residuals
  SequenceEncoder encoder(capture, options);
  testing::run_to_selection(encoder);
  BothFits e;
  e.keyframes = select_keyframes(plan_settings(encoder.options()), encoder.selection()).keyframes;
  encoder.options().keyframe_fit = true;
  e.fitted = std::make_shared<const Sequence>(build_sequence(encoder, e.keyframes, kGrid));
  encoder.options().keyframe_fit = false;
  e.interpolating = std::make_shared<const Sequence>(build_sequence(encoder, e.keyframes, kGrid));
  return e;
}

bool is_key(const BothFits& e, size_t i) { return std::binary_search(e.keyframes.begin(), e.keyframes.end(), static_cast<int>(i)); }

double relative_rms(const TriangleMesh& reference, const TriangleMesh& test) {
  const SurfaceDistance d = surface_distance(reference, test);
  return d.rms / d.diagonal;
}

// Frames = smooth motion + zero-mean noise along the normal, independent per frame: the fitted
// keyframes decode every frame closer to the true (noise-free) surface than the interpolating ones,
// held-out frames and keyframes alike, and a keyframe stays within the noise of its own frame.
TEST(KeyframeFit, AveragesPerFrameNoiseAwayAndBeatsInterpolatingTheKeyframes) {
  testing::TempDir dir;
  const Capture capture = synthetic_capture(dir, 0.001);  // 1 mm: ~0.4% of the face's diagonal
  const BothFits e = encode_both(capture);
  ASSERT_EQ(e.keyframes.size(), 6u);
  const SyntheticFace face(Expression::kMixed, 1);
  SequenceDecoder fitted(e.fitted), interpolating(e.interpolating);
  double fitted_held = 0, interpolating_held = 0, fitted_key = 0, interpolating_key = 0, worst_key_to_capture = 0;
  for (size_t i = 0; i < capture.frames.size(); ++i) {
    const double t = capture.frames[i].time;
    const TriangleMesh truth = face.truth_mesh(t, 20000);
    const DecodedFrame a = fitted.decode(t), b = interpolating.decode(t);
    EXPECT_TRUE(a.converged && b.converged) << "frame " << i;
    const double ea = relative_rms(truth, a.mesh), eb = relative_rms(truth, b.mesh);
    if (is_key(e, i)) {
      fitted_key += ea;
      interpolating_key += eb;
      worst_key_to_capture =
          std::max(worst_key_to_capture, relative_rms(read_mesh(capture.mesh_path(i), {.allow_missing_texture = true}), a.mesh));
    } else {
      fitted_held += ea;
      interpolating_held += eb;
    }
  }
  const double keys = static_cast<double>(e.keyframes.size()), held = kFrames - keys;
  fitted_held /= held, interpolating_held /= held, fitted_key /= keys, interpolating_key /= keys;
  RecordProperty("fitted_held", std::to_string(fitted_held));
  RecordProperty("interpolating_held", std::to_string(interpolating_held));
  std::printf(
      "to the truth, mean: held-out %.4f%% fitted, %.4f%% interpolating; keyframes %.4f%% / %.4f%%; keyframe to its capture, worst "
      "%.4f%%\n",
      100 * fitted_held, 100 * interpolating_held, 100 * fitted_key, 100 * interpolating_key, 100 * worst_key_to_capture);
  EXPECT_LT(fitted_held, 0.9 * interpolating_held);
  EXPECT_LT(fitted_key, 0.9 * interpolating_key);
  EXPECT_LT(worst_key_to_capture, 0.008);  // the capture's own noise (~0.4%) and the fit's share of it
}

// Noise-free frames: the spline through the keyframes' own frames is already close to every frame,
// so the fit moves each keyframe's decoded surface by a small fraction of the held-out error.
TEST(KeyframeFit, BarelyMovesTheKeyframesOfACleanCapture) {
  testing::TempDir dir;
  const Capture capture = synthetic_capture(dir, 0);
  const BothFits e = encode_both(capture);
  SequenceDecoder fitted(e.fitted), interpolating(e.interpolating);
  double worst_moved = 0;
  for (int k : e.keyframes) {
    const double t = capture.frames[static_cast<size_t>(k)].time;
    worst_moved = std::max(worst_moved, relative_rms(interpolating.decode(t).mesh, fitted.decode(t).mesh));
  }
  std::printf("clean capture: the fit moves a keyframe by at most %.4f%% RMS of the diagonal\n", 100 * worst_moved);
  EXPECT_LT(worst_moved, 0.0005);
}

// The bound κ·noise is what keeps a clean capture's keyframes its own frames: with two keyframes for
// 24 frames of a smoothly changing expression, the unbounded fit would move them towards the frames
// between them (the spline's systematic error); the default κ = 3 leaves them within 3 times their
// noise, which smooth motion keeps tiny. κ far larger lets the fit move them.
TEST(KeyframeFit, TheNoiseBoundKeepsACleanCapturesKeyframesWhereTheyAre) {
  testing::TempDir dir;
  write_synthetic_capture(dir.path(), {.frames = kFrames, .vertices = 3000, .remesh = true, .noise = 0, .texture_size = 64});
  const Capture capture = read_capture(dir.path());
  EncodeOptions options;
  options.keyframe_fraction = 2.0 / kFrames;
  options.keyframe_error_bound = 0;
  options.grid = kGrid;
  options.texture = false;
  SequenceEncoder encoder(capture, options);
  testing::run_to_selection(encoder);
  const std::vector<int> keys = select_keyframes(plan_settings(encoder.options()), encoder.selection()).keyframes;
  ASSERT_EQ(keys.size(), 2u);
  auto moved = [&](double kappa) {
    encoder.options().keyframe_fit = true;
    encoder.options().keyframe_fit_noise = kappa;
    const auto fitted = std::make_shared<const Sequence>(build_sequence(encoder, keys, kGrid));
    encoder.options().keyframe_fit = false;
    const auto own = std::make_shared<const Sequence>(build_sequence(encoder, keys, kGrid));
    SequenceDecoder a(fitted), b(own);
    double worst = 0;
    for (int k : keys) {
      const double t = capture.frames[static_cast<size_t>(k)].time;
      worst = std::max(worst, relative_rms(b.decode(t).mesh, a.decode(t).mesh));
    }
    return worst;
  };
  const double bounded = moved(EncodeOptions{}.keyframe_fit_noise), free = moved(1e6);
  std::printf("clean capture, two keyframes: keyframes moved %.4f%% with the bound, %.4f%% without\n", 100 * bounded, 100 * free);
  EXPECT_LT(bounded, 0.0005);
  EXPECT_GT(free, 3 * bounded);
  EXPECT_GT(free - bounded, 0.001);
}

// The fit streams the held frames in chunks of 32 and solves each keyframe once no later frame
// reaches it: keyframes every other frame make every held frame the last to reach one of them, so
// chunk boundaries fall on such frames. The fitted keyframes differ from their frames (the fit ran
// on every frame) by no more than the noise allows.
TEST(KeyframeFit, AKeyframeIsSolvedOnlyOnceItsLastFrameIsIn) {
  testing::TempDir dir;
  SynthOptions synth;
  synth.frames = 69;
  synth.vertices = 800;
  synth.noise = 0.0005;
  synth.texture_size = 16;
  write_synthetic_capture(dir.path(), synth);
  EncodeOptions options;
  options.grid = 33;
  options.texture = false;
  options.threads = 2;
  SequenceEncoder encoder(read_capture(dir.path()), options);
  testing::run_to_selection(encoder);
  std::vector<int> keyframes;
  for (int k = 0; k < 69; k += 2) keyframes.push_back(k);  // 35 keyframes, 34 held frames
  encoder.options().keyframe_fit = true;
  const Sequence fitted = build_sequence(encoder, keyframes, 33);
  encoder.options().keyframe_fit = false;
  const Sequence own = build_sequence(encoder, keyframes, 33);
  ASSERT_EQ(fitted.keyframes.size(), 35u);
  int moved = 0;
  for (size_t k = 0; k < fitted.keyframes.size(); ++k) {
    const std::vector<double>& a = fitted.keyframes[k].fields.mean_curvature;
    const std::vector<double>& b = own.keyframes[k].fields.mean_curvature;
    moved += a != b;
  }
  EXPECT_GE(moved, 30) << "the fit left most keyframes as their frames";
}

}  // namespace
}  // namespace facemorph
