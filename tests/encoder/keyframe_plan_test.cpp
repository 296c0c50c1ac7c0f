// The encoder's plan once every frame is sampled: the keyframes by predicted error (with and without
// residual frames), the grid's size and the representation the keyframes store.
#include "codec/core/reconstruct/reconstructor.hpp"
#include "codec/decoder/container/sequence_file.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/encode/texture_quality.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/encoder/synth/synth.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "codec/meshkit/mesh/mesh_io.hpp"
#include "codec/meshkit/mesh/topology.hpp"
#include "codec/writer/container/sequence_file_writer.hpp"

#include "codec/decoder/sequence/sequence_decoder.hpp"
#include "tests/encoder/encoder_stages.hpp"
#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <random>

namespace facemorph {
namespace {

// The representation left to the encoder (spec/method.md §7.14): measured only where most frames
// share no interior landmarks with the reference and none are tracked; then xyz where the blended
// fields miss the frames between keyframes by more than kFieldsBlendMargin times the blended
// positions. One given is kept.
TEST(SequenceEncoder, TheRepresentationFollowsHowTheKeyframesBlend) {
  testing::TempDir dir;
  Capture given = testing::small_remeshed_capture(dir, 0);
  given.frames.resize(6);
  given.landmarks.resize(6);
  auto without_interior = [&](std::initializer_list<size_t> frames) {  // rim markers and the nose kept
    Capture capture = given;
    for (size_t i : frames) {
      for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
        const std::string& name = capture.landmark_names[l];
        if (name.rfind("rim_", 0) != 0 && name != "nose_tip" && name != "nose_bridge" && name != "between_eyes") {
          capture.landmarks[i][l] = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
        }
      }
    }
    return capture;
  };
  EncodeOptions options;
  options.texture = false;
  options.tracking.spacing = 0.1;
  KeyframeSelection chosen;
  chosen.keyframes = {0, 2, 5};
  // The encoder after choose_representation, kept for the measured case's build.
  auto choose = [&](const Capture& capture, const EncodeOptions& o, int expected_without) {
    auto encoder = std::make_unique<SequenceEncoder>(capture, o);
    testing::run_to_selection(*encoder);
    EXPECT_EQ(encoder->report().frames_without_interior_landmarks, expected_without);
    adopt_chosen_representation(*encoder, chosen, 33);
    EXPECT_EQ(encoder->report().representation, encoder->representation());
    return encoder;
  };
  // Landmarks shared by most frames: nothing measured, hl+t.
  EXPECT_EQ(choose(given, options, 0)->report().blend.trials, 0);
  EXPECT_EQ(choose(without_interior({5}), options, 1)->report().blend.trials, 0);
  EXPECT_EQ(choose(without_interior({4, 5}), options, 2)->report().blend.trials, 0);  // two of five: not most
  EXPECT_EQ(choose(without_interior({3, 4, 5}), options, 3)->report().blend.trials, 2);
  {
    // Frames dropped in the registration (the nose alone: two landmarks shared) count neither way:
    // the three kept share their interior landmarks.
    Capture capture = given;
    for (size_t i : {3, 4, 5}) {
      for (size_t l = 0; l < capture.landmark_names.size(); ++l) {
        if (capture.landmark_names[l] != "nose_tip" && capture.landmark_names[l] != "nose_bridge") {
          capture.landmarks[i][l] = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
        }
      }
    }
    SequenceEncoder encoder(capture, options);
    map_frames(encoder);
    register_frames(encoder);
    EXPECT_EQ(encoder.report().dropped.size(), 3u);
    EXPECT_EQ(encoder.report().frames_without_interior_landmarks, 0);
  }
  EncodeOptions tracked = options;
  tracked.track_landmarks = true;  // tracked points are interior landmarks
  const Capture bare = without_interior({0, 1, 2, 3, 4, 5});
  EXPECT_EQ(choose(bare, tracked, 0)->report().blend.trials, 0);
  EncodeOptions hl = options;
  hl.representation = Representation::kHL;
  EXPECT_EQ(choose(bare, hl, 5)->report().blend.trials, 0);
  // Without them: both blends measured at the frames midway (1 and 3), and the rule applied.
  const std::unique_ptr<SequenceEncoder> encoder = choose(bare, options, 5);
  const BlendComparison& measured = encoder->report().blend;
  EXPECT_EQ(measured.trials, 2);
  EXPECT_GT(measured.positions_error, 0);
  EXPECT_LT(measured.positions_error, 0.01);
  EXPECT_GT(measured.fields_error, 0);
  const Representation expected = representation_for(measured);
  EXPECT_EQ(encoder->representation(), expected);
  EXPECT_EQ(build_sequence(*encoder, {0, 5}, 33).representation, expected);  // what build stores is that choice
}

// The rule once measured, and where it measures (kBlendTrials pairs at most, spread over the capture).
TEST(RepresentationChoice, XyzOnlyWhereTheFieldsBlendFartherByTheMargin) {
  auto blend = [](double fields, double positions) {
    BlendComparison b;
    b.fields_error = fields;
    b.positions_error = positions;
    b.trials = 3;
    return b;
  };
  EXPECT_EQ(representation_for(blend(1.0, 1.0)), Representation::kHLT);
  EXPECT_EQ(representation_for(blend(1.05, 1.0)), Representation::kHLT);  // within the margin
  EXPECT_EQ(representation_for(blend(1.2, 1.0)), Representation::kXYZ);
  EXPECT_EQ(representation_for(blend(0.5, 1.0)), Representation::kHLT);
  EXPECT_EQ(representation_for(blend(std::numeric_limits<double>::infinity(), 1.0)), Representation::kXYZ);  // a blend that diverged
  BlendComparison none = blend(2.0, 1.0);
  none.trials = 0;
  EXPECT_EQ(representation_for(none), Representation::kHLT);  // nothing measured

  EXPECT_EQ(blend_trial_pairs({0, 1, 2}), std::vector<size_t>{});  // keyframes on consecutive frames: nothing between
  EXPECT_EQ(blend_trial_pairs({0, 1, 3, 4, 9}), (std::vector<size_t>{1, 3}));
  std::vector<int> many;
  for (int k = 0; k <= 30; ++k) many.push_back(3 * k);  // 30 pairs
  const std::vector<size_t> spread = blend_trial_pairs(many);
  ASSERT_EQ(spread.size(), static_cast<size_t>(kBlendTrials));
  EXPECT_EQ(spread.front(), 0u);
  EXPECT_EQ(spread.back(), 29u);
  for (size_t t = 1; t < spread.size(); ++t) {
    EXPECT_GT(spread[t], spread[t - 1]);
    EXPECT_LE(spread[t] - spread[t - 1], 3u);  // evenly: 29 / 11 apart, rounded down
  }
}

// compare_blends against what it must find: a keyframe halfway between two others is matched by
// both blends at its own time (the linear spline: its blend is the two surfaces' mean, and the
// surfaces here are one bump at three heights, the middle one their mean); a frame that is no
// blend of the keyframes is missed by both.
TEST(RepresentationChoice, BothBlendsMatchAFrameThatIsTheirMean) {
  const auto geometry = std::make_shared<const GridGeometry>(make_disk_grid(33));
  auto bump = [&](double height) {
    std::vector<Vec3> surface;
    for (const Vec2& w : geometry->grid().nodes) surface.push_back({w.x(), w.y(), height * (1 - w.squaredNorm())});
    return surface;
  };
  const std::vector<std::vector<Vec3>> keys = {bump(0.2), bump(0.4)};
  const BlendComparison mean = compare_blends(geometry, {0, 1}, SplineKind::kLinear, keys, {BlendTrial{0.5, bump(0.3)}}, 1);
  EXPECT_EQ(mean.trials, 1);
  EXPECT_EQ(mean.not_converged, 0);
  EXPECT_LT(mean.positions_error, 1e-12);
  EXPECT_LT(mean.fields_error, 2e-3);  // the decode's own floor at N = 33
  const BlendComparison other = compare_blends(geometry, {0, 1}, SplineKind::kLinear, keys, {BlendTrial{0.5, bump(0.6)}}, 1);
  EXPECT_GT(other.positions_error, 0.05);
  EXPECT_GT(other.fields_error, 0.05);
  testing::expect_error(ErrorCode::kInvalidArgument, "needs keyframe 1", [&] {
    compare_blends(geometry, {0, 1}, SplineKind::kLinear, {keys[0], {}}, {BlendTrial{0.5, bump(0.3)}}, 1);
  });
}

// --grid auto: the resampling floor need not resolve a capture's per-frame noise (spec/method.md
// §7.6). The same face with 2 mm of noise (~0.6% of its diagonal) reads as noisy and gets a coarser
// grid than without; the clean one is held to the fixed 0.02% floor.
TEST(SequenceEncoder, AutomaticGridFollowsTheFloorButNotTheNoise) {
  auto grid_of = [](double noise, double* median_noise) {
    testing::TempDir dir;
    const Capture capture = testing::small_remeshed_capture(dir, 0, noise);
    EncodeOptions options;
    options.texture = false;
    SequenceEncoder encoder(capture, options);
    testing::run_to_selection(encoder);
    const int n = choose_grid(plan_settings(encoder.options()), plan_frames(encoder), encoder.report());
    *median_noise = encoder.report().median_noise;
    const auto& floors = encoder.report().grid_floors;
    EXPECT_FALSE(floors.empty());
    EXPECT_EQ(floors.back().first, n);
    // Every coarser candidate tried missed the target the chosen one met: the RMS target or, past
    // it, the floor's worst region (GridChoice.*).
    const double target = encoder.report().grid_target;
    EXPECT_DOUBLE_EQ(target, std::max(2e-4, *median_noise));  // no keyframes given: the floor and the noise
    const auto& p99s = encoder.report().grid_floor_p99s;
    const double worst = encoder.report().grid_worst_target;
    for (size_t i = 0; i + 1 < floors.size(); ++i) EXPECT_TRUE(floors[i].second > target || p99s[i].second > worst) << floors[i].first;
    if (n < encoder.report().grid_density_cap) {
      EXPECT_LE(floors.back().second, target);
    }
    EXPECT_LE(p99s.back().second, worst);
    std::printf("noise %.4f%%: N = %d (%s)\n", 100 * *median_noise, n, encoder.report().grid_term.c_str());
    return n;
  };
  double clean_noise = 0, noisy_noise = 0;
  const int clean = grid_of(0, &clean_noise), noisy = grid_of(0.002, &noisy_noise);
  EXPECT_GT(noisy_noise, 10 * clean_noise);
  EXPECT_LT(noisy, clean);
}

// Synthetic selection frames on a 9 x 9 patch: frame k's surface is a bump of height
// amplitude(k) (fraction of the unit diagonal), identity pose, normals along z.
std::vector<SelectionFrame> bump_frames(const std::vector<double>& amplitudes) {
  const int side = 9;
  std::vector<SelectionFrame> frames(amplitudes.size());
  for (size_t k = 0; k < amplitudes.size(); ++k) {
    SelectionFrame& f = frames[k];
    f.time = static_cast<double>(k) / 30.0;
    for (int j = 0; j < side; ++j) {
      for (int i = 0; i < side; ++i) {
        const double x = i / (side - 1.0) - 0.5, y = j / (side - 1.0) - 0.5;
        f.local.emplace_back(x, y, amplitudes[k] * std::exp(-8 * (x * x + y * y)) * std::sqrt(2.0));
        f.normal.emplace_back(0, 0, 1);
      }
    }
  }
  return frames;
}

double held_out_mean(const std::vector<double>& errors, const std::vector<int>& keys) {
  double sum = 0;
  int held = 0;
  for (size_t j = 0; j < errors.size(); ++j) {
    if (std::binary_search(keys.begin(), keys.end(), static_cast<int>(j))) continue;
    sum += errors[j];
    ++held;
  }
  return held == 0 ? 0.0 : sum / held;
}

// Frames sparser than SelectionOptions::sparse_interval are all keyframes; the same motion at 30
// frames a second keeps its budget (the rule looks at the frames' spacing, not at the motion).
TEST(KeyframeSelection, ASparseCaptureKeepsEveryFrame) {
  std::vector<double> amplitudes;
  for (int k = 0; k < 20; ++k) amplitudes.push_back(0.02 * std::sin(k * 0.9));
  std::vector<SelectionFrame> frames = bump_frames(amplitudes);
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  SelectionOptions options;
  options.fraction = 0.2;
  options.sparse_interval = 0.25;
  const KeyframeSelection dense = select_keyframes(frames, weights, options);
  EXPECT_FALSE(dense.sparse);
  EXPECT_NEAR(dense.median_interval, 1 / 30.0, 1e-12);
  EXPECT_EQ(dense.keyframes.size(), 4u);
  for (size_t k = 0; k < frames.size(); ++k) frames[k].time = 0.3 * static_cast<double>(k);  // 3.3 frames a second
  const KeyframeSelection sparse = select_keyframes(frames, weights, options);
  EXPECT_TRUE(sparse.sparse);
  EXPECT_EQ(sparse.keyframes.size(), frames.size());
  EXPECT_EQ(sparse.budget, 4);
  for (double e : sparse.predicted_error) EXPECT_EQ(e, 0);
  options.sparse_interval = 0;  // off: the budget
  EXPECT_EQ(select_keyframes(frames, weights, options).keyframes.size(), 4u);
}

// --max-error: every frame within the tolerance, with fewer keyframes than frames.
TEST(KeyframeSelection, AToleranceHoldsForEveryFrame) {
  std::vector<double> amplitudes;
  for (int k = 0; k < 60; ++k) amplitudes.push_back(0.02 * std::sin(k * 0.35));
  const std::vector<SelectionFrame> frames = bump_frames(amplitudes);
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  for (double tolerance : {0.002, 0.0005}) {
    SelectionOptions options;
    options.max_error = tolerance;
    const KeyframeSelection chosen = select_keyframes(frames, weights, options);
    EXPECT_LT(chosen.keyframes.size(), frames.size());
    EXPECT_GT(chosen.keyframes.size(), 2u);
    for (double e : chosen.predicted_error) EXPECT_LE(e, tolerance);
  }
}

// A budget's keyframes move to where the frames need them: motion only in the second half of the
// capture, so evenly spaced keyframes waste those in the still first half.
TEST(KeyframeSelection, TheBudgetsKeyframesMoveToTheMotion) {
  std::vector<double> amplitudes;
  for (int k = 0; k < 60; ++k) amplitudes.push_back(k < 30 ? 0.0 : 0.02 * std::sin((k - 30) * 0.5));
  const std::vector<SelectionFrame> frames = bump_frames(amplitudes);
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  SelectionOptions options;
  options.fraction = 0.15;
  const KeyframeSelection chosen = select_keyframes(frames, weights, options);
  std::vector<int> even;
  for (int k = 0; k < 9; ++k) even.push_back(static_cast<int>(std::lround(59.0 * k / 8)));
  const std::vector<double> even_errors = prediction_errors(frames, weights, even, options.spline, Vec3::Zero());
  ASSERT_EQ(chosen.keyframes.size(), even.size());
  EXPECT_LT(held_out_mean(chosen.predicted_error, chosen.keyframes), 0.7 * held_out_mean(even_errors, even));
  // Even spacing puts 4 keyframes past frame 30; the moves put more there.
  EXPECT_GE(std::count_if(chosen.keyframes.begin(), chosen.keyframes.end(), [](int k) { return k > 30; }), 5);
}

// The moves weigh each trial on the RMS of the frames the moved keyframe reaches (affected()),
// and measure the 99th percentiles once at the keyframes they reach: so every frame's errors are
// those of the keyframes chosen, as if measured afresh, with each local spline. A window narrower
// than the keyframe's reach leaves RMS values of keyframes since moved; a percentile not measured
// at the end reads 0.
TEST(KeyframeSelection, TheMovesLeaveTheErrorsOfTheKeyframesTheyReach) {
  std::vector<double> amplitudes;
  for (int k = 0; k < 60; ++k) amplitudes.push_back(k < 30 ? 0.0 : 0.02 * std::sin((k - 30) * 0.5));
  const std::vector<SelectionFrame> frames = bump_frames(amplitudes);
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  for (SplineKind kind : {SplineKind::kCatmullRom, SplineKind::kLinear, SplineKind::kLocalCubic}) {
    SelectionOptions options;
    options.fraction = 0.15;
    options.spline = kind;
    const KeyframeSelection chosen = select_keyframes(frames, weights, options);
    std::vector<int> even;
    for (int k = 0; k < 9; ++k) even.push_back(static_cast<int>(std::lround(59.0 * k / 8)));
    ASSERT_NE(chosen.keyframes, even) << "the moves must move keyframes for this to test them";
    const std::vector<double> fresh = prediction_errors(frames, weights, chosen.keyframes, kind, Vec3::Zero());
    ASSERT_EQ(chosen.predicted_p99.size(), frames.size());
    for (size_t j = 0; j < frames.size(); ++j) {
      EXPECT_EQ(chosen.predicted_error[j], fresh[j]) << "frame " << j;
      // Equal weights on 81 nodes: the 99th percentile is the largest offset, at least the RMS.
      if (fresh[j] > 0) {
        EXPECT_GE(chosen.predicted_p99[j], fresh[j]) << "frame " << j;
      }
    }
  }
}

// 40 frames of one bump at amplitudes drawn at random, up to 3% of the diagonal: motion far faster
// than a spline through a few keyframes follows.
std::vector<SelectionFrame> fast_bump_frames() {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> amplitude(-0.03, 0.03);
  std::vector<double> amplitudes;
  for (int k = 0; k < 40; ++k) amplitudes.push_back(amplitude(rng));
  return bump_frames(amplitudes);
}

// Frames far apart or fast: the frames' surfaces move by amounts the spline cannot follow (an
// independent bump of up to 3% of the diagonal per frame), so the 10% budget spread thin leaves the
// mean predicted error far above the default bound. The selection adds keyframes until the mean is
// within the bound and the worst within 3 times it; a bound of 0 keeps the budget exactly.
TEST(KeyframeSelection, FramesFarApartGetKeyframesNotABudgetSpreadThin) {
  const std::vector<SelectionFrame> frames = fast_bump_frames();
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  SelectionOptions options;
  options.error_bound = 0.005;
  const KeyframeSelection bounded = select_keyframes(frames, weights, options);
  EXPECT_EQ(bounded.budget, 4);
  ASSERT_GT(bounded.budget_mean_error, 0.005) << "the frames do not move enough to test the bound";
  EXPECT_GT(bounded.keyframes.size(), 4u);
  double sum = 0, worst = 0;
  int held = 0;
  for (size_t j = 0; j < bounded.predicted_error.size(); ++j) {
    if (std::binary_search(bounded.keyframes.begin(), bounded.keyframes.end(), static_cast<int>(j))) continue;
    sum += bounded.predicted_error[j];
    worst = std::max(worst, bounded.predicted_error[j]);
    ++held;
  }
  EXPECT_LE(held == 0 ? 0.0 : sum / held, 0.005 + 1e-12);
  EXPECT_LE(worst, 0.015 + 1e-12);
  options.error_bound = 0;
  EXPECT_EQ(select_keyframes(frames, weights, options).keyframes.size(), 4u);
}

// 40 frames of a narrow bump (σ = 0.06 of a 41 x 41 patch: a lip, an eyelid) at amplitudes drawn
// at random up to 3% of the diagonal, identity pose, normals along z: the RMS over the patch stays
// a tenth of the bump's height while its 99th-percentile point is two thirds of it.
std::vector<SelectionFrame> narrow_bump_frames() {
  const int side = 41;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> amplitude(-0.03, 0.03);
  std::vector<SelectionFrame> frames(40);
  for (size_t k = 0; k < frames.size(); ++k) {
    SelectionFrame& f = frames[k];
    f.time = static_cast<double>(k) / 30.0;
    const double a = amplitude(rng);
    for (int j = 0; j < side; ++j) {
      for (int i = 0; i < side; ++i) {
        const double x = i / (side - 1.0) - 0.5, y = j / (side - 1.0) - 0.5;
        f.local.emplace_back(x, y, a * std::exp(-(x * x + y * y) / (2 * 0.06 * 0.06)));
        f.normal.emplace_back(0, 0, 1);
      }
    }
  }
  return frames;
}

// The worst region (issue 44: every decoded frame's 99th-percentile point error within 1% of the
// diagonal): a narrow bump moving faster than the spline follows leaves the RMS bounds met by the
// budget (mean within B, worst within 3B) while the bump's own points sit far above the
// 99th-percentile bound, so only the p99 rule adds keyframes, until every held-out frame's predicted
// 99th percentile is within it. The percentile itself is checked against its closed form: one bump
// shape, so every frame's p99 over its RMS is the shape's 17th-largest height of 1681 (1% of the
// equal weights) over its RMS height.
TEST(KeyframeSelection, TheWorstRegionGetsKeyframesWhereTheRmsBoundsHold) {
  const std::vector<SelectionFrame> frames = narrow_bump_frames();
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  std::vector<double> shape;
  for (const Eigen::Vector3f& p : frames.front().local) shape.push_back(std::abs(p.z()));
  std::sort(shape.begin(), shape.end(), std::greater<double>());
  double squares = 0;
  for (double h : shape) squares += h * h;
  const double ratio = shape[16] / std::sqrt(squares / static_cast<double>(shape.size()));
  SelectionOptions options;
  options.error_bound = 0.005;
  const KeyframeSelection budget = select_keyframes(frames, weights, options);  // no p99 bound
  ASSERT_EQ(budget.keyframes.size(), 4u) << "the RMS bounds alone must hold at the budget";
  ASSERT_EQ(budget.predicted_p99.size(), frames.size());
  double worst_p99 = 0;
  for (size_t j = 0; j < frames.size(); ++j) {
    worst_p99 = std::max(worst_p99, budget.predicted_p99[j]);
    if (budget.predicted_error[j] > 1e-6) {
      EXPECT_NEAR(budget.predicted_p99[j] / budget.predicted_error[j], ratio, 1e-3 * ratio) << j;
    }
  }
  ASSERT_GT(worst_p99, 0.0075) << "the bump must sit above the bound at the budget";
  EXPECT_DOUBLE_EQ(budget.budget_worst_p99, worst_p99);
  options.p99_bound = 0.0075;
  const KeyframeSelection bounded = select_keyframes(frames, weights, options);
  EXPECT_GT(bounded.keyframes.size(), budget.keyframes.size());
  EXPECT_LT(bounded.keyframes.size(), frames.size());
  for (size_t j = 0; j < frames.size(); ++j) EXPECT_LE(bounded.predicted_p99[j], 0.0075 + 1e-12) << j;
  options.error_bound = 0;  // the budget exactly: no bound of either kind
  EXPECT_EQ(select_keyframes(frames, weights, options).keyframes.size(), 4u);
}

// The refinement measures a keyframe's trial positions on SelectionOptions::threads threads and weighs
// them in order: the keyframes, their predicted errors (bit for bit) and the residuals are the same
// for any count, with the moves weighed on the RMS alone (a budget), against a p99 bound (the worst
// region's keyframes), against a tolerance, and with residual frames.
TEST(KeyframeSelection, TheKeyframesDoNotDependOnTheThreads) {
  std::vector<double> amplitudes;
  for (int k = 0; k < 60; ++k) amplitudes.push_back(k < 30 ? 0.0 : 0.02 * std::sin((k - 30) * 0.5));
  const std::vector<SelectionFrame> moving = bump_frames(amplitudes);
  const std::vector<SelectionFrame> narrow = narrow_bump_frames();
  const std::vector<SelectionFrame> fast = fast_bump_frames();
  struct Case {
    const std::vector<SelectionFrame>* frames;
    SelectionOptions options;
  };
  std::vector<Case> cases(5);
  cases[0] = {&moving, {}};
  cases[0].options.fraction = 0.15;
  cases[1] = {&moving, cases[0].options};
  cases[1].options.spline = SplineKind::kLinear;
  cases[2] = {&narrow, {}};
  cases[2].options.error_bound = 0.005;
  cases[2].options.p99_bound = 0.0075;
  cases[3] = {&moving, {}};
  cases[3].options.max_error = 0.002;
  cases[4] = {&fast, {}};
  cases[4].options.error_bound = 0.005;
  cases[4].options.residuals = true;
  for (size_t c = 0; c < cases.size(); ++c) {
    const std::vector<SelectionFrame>& frames = *cases[c].frames;
    const std::vector<double> weights(frames.front().local.size(), 1.0);
    SelectionOptions options = cases[c].options;
    const KeyframeSelection one = select_keyframes(frames, weights, options);
    for (int threads : {2, 3}) {
      options.threads = threads;
      const KeyframeSelection more = select_keyframes(frames, weights, options);
      EXPECT_EQ(more.keyframes, one.keyframes) << "case " << c << ", " << threads << " threads";
      EXPECT_EQ(more.predicted_error, one.predicted_error) << "case " << c << ", " << threads << " threads";
      EXPECT_EQ(more.predicted_p99, one.predicted_p99) << "case " << c << ", " << threads << " threads";
      EXPECT_EQ(more.residual_frames, one.residual_frames) << "case " << c << ", " << threads << " threads";
      ASSERT_EQ(more.residuals.size(), one.residuals.size()) << "case " << c;
      for (size_t r = 0; r < one.residuals.size(); ++r) EXPECT_EQ(more.residuals[r].delta, one.residuals[r].delta) << "case " << c;
    }
    if (c == 2) {
      EXPECT_GT(one.keyframes.size(), 4u) << "the p99 bound must add keyframes for its refinement to run";
    }
    if (c == 4) {
      EXPECT_FALSE(one.residuals.empty()) << "the fast motion must take residual frames";
    }
  }
}

// Fast motion a spline cannot follow, but every frame another blend of its keyframes (one bump
// shape at amplitudes drawn at random): with residual frames (format 2.3) each frame between
// keyframes is served by a correction of the blend, so the selection meets the bound with far
// fewer keyframes than without; each residual is at a held-out frame's time, in steps of 2^-7
// summing to exactly 0, never raises that frame's predicted error, and most lower it by a tenth.
TEST(KeyframeSelection, FastMotionGetsResidualFramesInsteadOfKeyframes) {
  const std::vector<SelectionFrame> frames = fast_bump_frames();
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  SelectionOptions options;
  options.error_bound = 0.005;
  const KeyframeSelection without = select_keyframes(frames, weights, options);
  EXPECT_TRUE(without.residuals.empty());
  options.residuals = true;
  const KeyframeSelection with = select_keyframes(frames, weights, options);
  EXPECT_LT(2 * with.keyframes.size(), without.keyframes.size())
      << with.keyframes.size() << " keyframes with residuals, " << without.keyframes.size() << " without";
  ASSERT_GT(with.residuals.size(), 10u);
  ASSERT_EQ(with.residual_frames.size(), with.residuals.size());
  const std::vector<double> spline_only = prediction_errors(frames, weights, with.keyframes, options.spline, Vec3::Zero());
  size_t lowered = 0;
  for (size_t r = 0; r < with.residuals.size(); ++r) {
    const int j = with.residual_frames[r];
    EXPECT_FALSE(std::binary_search(with.keyframes.begin(), with.keyframes.end(), j));
    EXPECT_EQ(with.residuals[r].time, frames[static_cast<size_t>(j)].time);
    double sum = 0;
    for (double d : with.residuals[r].delta) {
      EXPECT_EQ(d * 128, std::round(d * 128));
      sum += d;
    }
    EXPECT_EQ(sum, 0.0);
    EXPECT_LE(with.predicted_error[static_cast<size_t>(j)], spline_only[static_cast<size_t>(j)] + 1e-12);
    lowered += with.predicted_error[static_cast<size_t>(j)] <= 0.9 * spline_only[static_cast<size_t>(j)];
  }
  EXPECT_GT(lowered, with.residuals.size() / 2);
  EXPECT_NO_THROW(validate_residuals(
      [&] {
        std::vector<double> times;
        for (int k : with.keyframes) times.push_back(frames[static_cast<size_t>(k)].time);
        return times;
      }(),
      with.residuals));
  options.residual_step = 0;
  testing::expect_error(ErrorCode::kInvalidArgument, "residual step", [&] { select_keyframes(frames, weights, options); });
}

// A budget the error bound leaves as it is (here kept exactly) on the same fast motion: with residual
// frames the selection takes fewer keyframes, as many as keep every frame, with its residual, within
// what the budget's keyframes left without (spec/method.md §7.18); their predicted errors stay the
// spline's alone (they set N and the field rounding), and the residuals are added to them.
TEST(KeyframeSelection, WithinItsBudgetResidualsTakeThePlaceOfKeyframes) {
  const std::vector<SelectionFrame> frames = fast_bump_frames();
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  SelectionOptions options;
  options.fraction = 0.25;
  const KeyframeSelection plain = select_keyframes(frames, weights, options);
  ASSERT_EQ(plain.keyframes.size(), 10u);
  options.residuals = true;
  const KeyframeSelection with = select_keyframes(frames, weights, options);
  EXPECT_LT(with.keyframes.size(), plain.keyframes.size());
  EXPECT_GE(with.keyframes.size(), 2u);
  EXPECT_EQ(with.keyframes.front(), 0);
  EXPECT_EQ(with.keyframes.back(), 39);
  EXPECT_EQ(with.predicted_error, prediction_errors(frames, weights, with.keyframes, options.spline, Vec3::Zero()));
  EXPECT_GT(with.residuals.size(), 20u);
}

// The keep rule (residuals_pay, spec/method.md §7.18): residuals pay for their bytes only where the
// selection takes fewer keyframes for them. On the same fast motion a budget of 10 keyframes that
// residuals cut pays; a budget of 2, which nothing can cut, does not, though residuals would lower
// its frames' predicted errors there (bytes added to the same keyframes): it carries none.
TEST(KeyframeSelection, ResidualsPayOnlyWhereTheyTakeKeyframesPlaces) {
  const std::vector<SelectionFrame> frames = fast_bump_frames();
  const std::vector<double> weights(frames.front().local.size(), 1.0);
  SelectionOptions options;
  options.fraction = 0.25;
  const KeyframeSelection plain = select_keyframes(frames, weights, options);
  EXPECT_EQ(plain.spline_keyframes, 10);
  EXPECT_FALSE(residuals_pay(plain));
  options.residuals = true;
  const KeyframeSelection traded = select_keyframes(frames, weights, options);
  EXPECT_EQ(traded.spline_keyframes, 10);
  EXPECT_LT(traded.keyframes.size(), 10u);
  EXPECT_TRUE(residuals_pay(traded));
  options.fraction = 2.0 / static_cast<double>(frames.size());
  const KeyframeSelection two = select_keyframes(frames, weights, options);
  ASSERT_EQ(two.keyframes.size(), 2u);
  EXPECT_EQ(two.spline_keyframes, 2);
  EXPECT_FALSE(residuals_pay(two));
  EXPECT_TRUE(two.residuals.empty());
  EXPECT_EQ(two.predicted_error, prediction_errors(frames, weights, two.keyframes, options.spline, Vec3::Zero()));
}

// Given the keyframes, --grid auto also stops at half the error the spline makes between them:
// with few keyframes for a changing expression that error is large, and a grid finer than half of
// it buys less error per byte than keyframes would (spec/method.md §7.6).
TEST(SequenceEncoder, AutomaticGridStopsAtAShareOfThePredictedError) {
  testing::TempDir dir;
  // 2 s of smoothly changing expressions: little frame noise, and two keyframes far apart.
  write_synthetic_capture(dir.path(), {.frames = 60, .vertices = 2000, .remesh = true, .noise = 0, .texture_size = 64});
  const Capture capture = read_capture(dir.path());
  EncodeOptions options;
  options.texture = false;
  options.keyframe_fraction = 0.02;
  options.keyframe_error_bound = 0;  // the budget exactly: two keyframes
  SequenceEncoder encoder(capture, options);
  testing::run_to_selection(encoder);
  const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
  EXPECT_EQ(chosen.keyframes.size(), 2u);
  const int alone = choose_grid(plan_settings(encoder.options()), plan_frames(encoder), encoder.report());
  const double alone_target = encoder.report().grid_target;
  const int with_keys = choose_grid(plan_settings(encoder.options()), plan_frames(encoder), encoder.report(), &chosen);
  double sum = 0;
  int count = 0;
  for (double e : chosen.predicted_error) {
    if (e > 0) sum += e, ++count;
  }
  ASSERT_GT(count, 0);
  const double target = encoder.report().grid_target;
  EXPECT_DOUBLE_EQ(target, std::max(alone_target, 0.5 * sum / count));
  const auto& floors = encoder.report().grid_floors;
  ASSERT_FALSE(floors.empty());
  EXPECT_EQ(floors.back().first, with_keys);
  for (size_t i = 0; i + 1 < floors.size(); ++i) EXPECT_GT(floors[i].second, target);
  EXPECT_LE(floors.back().second, target);
  EXPECT_LT(with_keys, alone) << "floors tried: " << floors.size() << ", target " << target << " against " << alone_target;
}

}  // namespace
}  // namespace facemorph
