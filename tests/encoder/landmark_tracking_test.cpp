// Landmark correspondence by optical flow on the disk images (landmark_tracking.hpp): fmsynth's
// faces, whose every material point is known at every time, tracked from a reference frame.
#include "facemorph/meshkit/distance.hpp"
#include "facemorph/encoder/capture.hpp"
#include "facemorph/encoder/frame_pipeline.hpp"
#include "facemorph/encoder/landmark_tracking.hpp"
#include "facemorph/encoder/sequence_encoder.hpp"
#include "facemorph/encoder/synth.hpp"
#include "facemorph/meshkit/mesh_io.hpp"
#include "facemorph/sequence.hpp"
#include "facemorph/sequence_file.hpp"

#include "tests/test_util.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

namespace facemorph {
namespace {

struct Truth {
  std::vector<MappedFrame> frames;
  std::vector<std::vector<Vec2>> landmarks;  // per frame, the interior landmarks' disk points
};

Vec2 on_disk(const MappedFrame& f, const Vec3& p) { return disk_point(f.map, PointToMesh(f.map.surface).closest(p)); }

// Frames of a synthetic face at `times`, each mapped and normalised by its own nose landmarks, with
// where its interior landmarks lie on its disk.
Truth synthetic_frames(Expression expression, uint64_t seed, const std::vector<double>& times, int vertices) {
  const SyntheticFace face(expression, seed);
  Truth t;
  for (double time : times) {
    const TriangleMesh mesh = face.truth_mesh(time, vertices);
    FrameLandmarks given;
    std::vector<Vec3> interior;
    for (const NamedPoint& p : face.landmarks()) {
      const Vec3 x = face.position(p.material, time);
      if (p.name == "nose_tip") given.centre = x;
      else if (p.name == "nose_bridge") given.up = x;
      else if (p.name.rfind("rim_", 0) == 0) given.rim_markers.push_back(x);
      else if (p.name != "between_eyes") interior.push_back(x);
    }
    t.frames.push_back(map_frame(mesh, "synth", given));
    std::vector<Vec2> points;
    for (const Vec3& x : interior) points.push_back(on_disk(t.frames.back(), x));
    t.landmarks.push_back(points);
  }
  return t;
}

struct Accuracy {
  double tracked = 0, untracked = 0;  // RMS disk distance to the truth: tracked, and left where the reference has it
  int kept = 0, tried = 0;
};

Accuracy measure(const Truth& t, size_t frame, const TrackingOptions& options) {
  const DiskFeatures reference = disk_features(t.frames[0].map, options.image_size);
  const DiskFeatures other = disk_features(t.frames[frame].map, options.image_size);
  const TrackedPoints tracked = track_points(reference, other, t.landmarks[0], {}, options);
  Accuracy a;
  a.tried = tracked.tried;
  a.kept = static_cast<int>(tracked.index.size());
  for (size_t k = 0; k < tracked.index.size(); ++k) {
    const auto l = static_cast<size_t>(tracked.index[k]);
    a.tracked += (tracked.frame[k] - t.landmarks[frame][l]).squaredNorm();
    a.untracked += (t.landmarks[0][l] - t.landmarks[frame][l]).squaredNorm();
  }
  a.tracked = std::sqrt(a.tracked / std::max(a.kept, 1));
  a.untracked = std::sqrt(a.untracked / std::max(a.kept, 1));
  return a;
}

// A talking face's landmarks (eyes, brows, lips, mouth corners) from the neutral frame onto frames
// with the mouth open: the tracked points land far nearer the truth than the normalised maps put
// them, and most are kept.
TEST(LandmarkTracking, FollowsASyntheticFacesLandmarks) {
  const Truth t = synthetic_frames(Expression::kTalk, 4, {0.0, 0.4, 0.9}, 6000);
  for (size_t i = 1; i < t.frames.size(); ++i) {
    const Accuracy a = measure(t, i, {});
    std::printf("frame %zu: %d of %d kept; RMS %.4f tracked, %.4f untracked (disk units)\n", i, a.kept, a.tried, a.tracked, a.untracked);
    EXPECT_GE(a.kept, a.tried * 2 / 3);
    EXPECT_LT(a.tracked, 0.7 * a.untracked);
    EXPECT_LT(a.tracked, 0.008);
  }
}

// A frame whose disk is the reference's turned by 60°: no window matches where the flow can reach,
// so the round-trip, neighbour and gain checks drop nearly every point; without them a fifth of
// the grid, all wrong, would be kept.
TEST(LandmarkTracking, DropsPointsItCannotFollow) {
  const Truth t = synthetic_frames(Expression::kTalk, 4, {0.0}, 6000);
  MappedFrame turned = t.frames[0];
  const double c = std::cos(1.047), s = std::sin(1.047);
  for (Vec2& w : turned.map.disk) w = Vec2(c * w.x() - s * w.y(), s * w.x() + c * w.y());
  TrackingOptions options;
  const DiskFeatures reference = disk_features(t.frames[0].map, options.image_size), other = disk_features(turned.map, options.image_size);
  const std::vector<Vec2> grid = tracking_grid(options);
  const TrackedPoints checked = track_points(reference, other, grid, {}, options);
  options.check_round_trip = false;
  const TrackedPoints unchecked = track_points(reference, other, grid, {}, options);
  std::printf("%zu of %d kept with the checks, %zu without\n", checked.index.size(), checked.tried, unchecked.index.size());
  EXPECT_LT(checked.index.size(), grid.size() / 20);
  EXPECT_GT(unchecked.index.size(), grid.size() / 6);
}

// On real captures, when FACEMORPH_TRACKING_CAPTURE names one with interior landmarks: the tracked
// accuracy on every frame, printed (a measurement, not a check).
TEST(LandmarkTracking, MeasureOnACapture) {
  const char* path = std::getenv("FACEMORPH_TRACKING_CAPTURE");
  if (!path) GTEST_SKIP() << "FACEMORPH_TRACKING_CAPTURE not set";
  Capture capture = read_capture(path);
  const int stride = std::getenv("FACEMORPH_TRACKING_STRIDE") ? std::atoi(std::getenv("FACEMORPH_TRACKING_STRIDE")) : 1;
  EncodeOptions options;
  options.texture = false;
  options.largest_component = true;
  SequenceEncoder encoder(capture, options);
  encoder.map_frames();
  const Capture& kept = encoder.capture();
  std::vector<size_t> interior;
  for (size_t l = 0; l < kept.landmark_names.size(); ++l) {
    const std::string& n = kept.landmark_names[l];
    if (n.rfind("rim_", 0) != 0 && n != "nose_tip" && n != "nose_bridge" && n != "between_eyes") interior.push_back(l);
  }
  TrackingOptions tracking;
  if (std::getenv("FACEMORPH_TRACKING_SIZE")) tracking.image_size = std::atoi(std::getenv("FACEMORPH_TRACKING_SIZE"));
  if (std::getenv("FACEMORPH_TRACKING_WINDOW")) tracking.window = std::atoi(std::getenv("FACEMORPH_TRACKING_WINDOW"));
  if (std::getenv("FACEMORPH_TRACKING_BLUR")) tracking.blur = std::atof(std::getenv("FACEMORPH_TRACKING_BLUR"));
  if (std::getenv("FACEMORPH_TRACKING_FACTOR")) tracking.log_factor_weight = std::atof(std::getenv("FACEMORPH_TRACKING_FACTOR"));
  if (std::getenv("FACEMORPH_TRACKING_LEVELS")) tracking.pyramid_levels = std::atoi(std::getenv("FACEMORPH_TRACKING_LEVELS"));
  if (std::getenv("FACEMORPH_TRACKING_ROUND_TRIP")) tracking.max_round_trip = std::atof(std::getenv("FACEMORPH_TRACKING_ROUND_TRIP"));
  auto points_of = [&](size_t i) {
    std::vector<Vec2> p;
    for (size_t l : interior) p.push_back(on_disk(*encoder.frame(static_cast<int>(i)), kept.landmarks[i][l]));
    return p;
  };
  const bool holes = !std::getenv("FACEMORPH_TRACKING_NO_HOLES");
  auto draw = [&](int i) {
    const std::shared_ptr<const MappedFrame> f = encoder.frame(i);  // held: it may be read back from the store
    return disk_features(f->map, tracking.image_size, holes ? f->prepared.report.holes : std::vector<FilledHole>{});
  };
  const DiskFeatures reference = draw(0);
  const std::vector<Vec2> from = points_of(0);
  std::vector<Vec2> last = from;
  double sum_tracked = 0, sum_untracked = 0;
  int kept_points = 0, tried = 0;
  std::vector<double> per_tracked(interior.size()), per_untracked(interior.size());
  std::vector<int> per_kept(interior.size());
  for (int i = 1; i < encoder.frame_count(); i += stride) {
    const DiskFeatures other = draw(i);
    TrackedPoints t;
    if (std::getenv("FACEMORPH_TRACKING_CHAIN")) {
      // Frame to frame: from where the previous frame put each point.
      const DiskFeatures previous = draw(i - stride);
      t = track_points(previous, other, last, {}, tracking);
      if (std::getenv("FACEMORPH_TRACKING_CHAIN_DIRECT")) {
        std::vector<Vec2> start = last;
        for (size_t k = 0; k < t.index.size(); ++k) start[static_cast<size_t>(t.index[k])] = t.frame[k];
        t = track_points(reference, other, from, start, tracking);
      } else {
        for (size_t k = 0; k < t.index.size(); ++k) t.reference[k] = from[static_cast<size_t>(t.index[k])];
      }
    } else {
      t = track_points(reference, other, from, last, tracking);
    }
    const std::vector<Vec2> truth = points_of(static_cast<size_t>(i));
    double e = 0, u = 0;
    std::vector<Vec2> estimate = from;  // a point lost stays where the reference has it
    for (size_t k = 0; k < t.index.size(); ++k) {
      estimate[static_cast<size_t>(t.index[k])] = t.frame[k];
      last[static_cast<size_t>(t.index[k])] = t.frame[k];
    }
    for (size_t l = 0; l < from.size(); ++l) {
      e += (estimate[l] - truth[l]).squaredNorm();
      u += (from[l] - truth[l]).squaredNorm();
      per_tracked[l] += (estimate[l] - truth[l]).squaredNorm();
      per_untracked[l] += (from[l] - truth[l]).squaredNorm();
    }
    for (int k : t.index) ++per_kept[static_cast<size_t>(k)];
    sum_tracked += e, sum_untracked += u, kept_points += static_cast<int>(t.index.size()), tried += t.tried;
    std::printf("frame %d: %zu of %d kept (%d outliers); RMS %.4f tracked, %.4f untracked\n", i, t.index.size(), t.tried, t.outliers,
                std::sqrt(e / static_cast<double>(from.size())), std::sqrt(u / static_cast<double>(from.size())));
  }
  if (std::getenv("FACEMORPH_TRACKING_PER_LANDMARK")) {
    for (size_t l = 0; l < interior.size(); ++l) {
      std::printf("  %s at (%.3f, %.3f): kept %d, RMS %.4f tracked, %.4f untracked\n", kept.landmark_names[interior[l]].c_str(), from[l].x(), from[l].y(),
                  per_kept[l], std::sqrt(per_tracked[l] / (encoder.frame_count() - 1) * stride), std::sqrt(per_untracked[l] / (encoder.frame_count() - 1) * stride));
    }
  }
  std::printf("all: %d of %d kept; RMS %.4f tracked (lost points untracked), %.4f untracked\n", kept_points, tried, std::sqrt(sum_tracked / std::max(tried, 1)),
              std::sqrt(sum_untracked / std::max(tried, 1)));
}

}  // namespace
}  // namespace facemorph

namespace facemorph {
namespace {

// A file's held-out error against its capture (FACEMORPH_MEASURE_CAPTURE, FACEMORPH_MEASURE_FMV),
// as fmbench --capture C --fmv X.fmv measures its main row (a measurement, not a check).
TEST(LandmarkTracking, MeasureAFile) {
  const char* capture_path = std::getenv("FACEMORPH_MEASURE_CAPTURE");
  const char* file = std::getenv("FACEMORPH_MEASURE_FMV");
  if (!capture_path || !file) GTEST_SKIP() << "FACEMORPH_MEASURE_CAPTURE and FACEMORPH_MEASURE_FMV not set";
  const Capture capture = read_capture(capture_path);
  SequenceFileInfo info;
  const auto sequence = std::make_shared<const Sequence>(read_sequence_file(file, &info));
  SequenceDecoder decoder(sequence);
  DecodeOptions options;
  options.ignore_sane_range = true;
  options.reconstruct.throw_on_failure = false;
  std::vector<size_t> keys;
  for (const Keyframe& key : sequence->keyframes) {
    size_t nearest = 0;
    for (size_t i = 1; i < capture.frames.size(); ++i) {
      if (std::abs(capture.frames[i].time - key.time) < std::abs(capture.frames[nearest].time - key.time)) nearest = i;
    }
    keys.push_back(nearest);
  }
  double sum = 0, worst = 0;
  int held = 0;
  for (size_t i = 0; i < capture.frames.size(); ++i) {
    if (std::find(keys.begin(), keys.end(), i) != keys.end()) continue;
    const DecodedFrame decoded = decoder.decode(capture.frames[i].time, options);
    const SurfaceDistance d = surface_distance(read_mesh(capture.mesh_path(i), {.allow_missing_texture = true}), decoded.mesh);
    sum += d.rms / d.diagonal;
    worst = std::max(worst, d.rms / d.diagonal);
    ++held;
  }
  std::printf("%s: %llu bytes, %zu keyframes, N = %d; held-out RMS %.4f%% mean, %.4f%% worst\n", file, static_cast<unsigned long long>(info.file_bytes),
              keys.size(), sequence->grid_n, 100 * sum / std::max(held, 1), 100 * worst);
}

}  // namespace
}  // namespace facemorph

namespace facemorph {
namespace {

// The keyframe selection's predicted error between keyframes (what held-out frames will show) for
// tracking variants on one mapping of FACEMORPH_MEASURE_CAPTURE, its landmarks withheld (a
// measurement, not a check). FACEMORPH_MEASURE_VARIANTS: "spacing,window,max_round_trip,smoothing;...".
TEST(LandmarkTracking, MeasureSelection) {
  const char* capture_path = std::getenv("FACEMORPH_MEASURE_CAPTURE");
  const char* variants = std::getenv("FACEMORPH_MEASURE_VARIANTS");
  if (!capture_path || !variants) GTEST_SKIP() << "FACEMORPH_MEASURE_CAPTURE and FACEMORPH_MEASURE_VARIANTS not set";
  Capture capture = read_capture(capture_path);
  if (!std::getenv("FACEMORPH_MEASURE_GIVEN")) {
    capture.landmark_names.clear();
    capture.landmarks.assign(capture.frames.size(), {});
  }
  EncodeOptions options;
  options.texture = false;
  SequenceEncoder encoder(capture, options);
  encoder.map_frames();
  std::string text = variants;
  for (size_t begin = 0; begin < text.size();) {
    size_t end = text.find(';', begin);
    if (end == std::string::npos) end = text.size();
    double spacing = 0, window = 0, round_trip = 0, smoothing = 0, gain = 0.7;
    std::sscanf(text.substr(begin, end - begin).c_str(), "%lf,%lf,%lf,%lf,%lf", &spacing, &window, &round_trip, &smoothing, &gain);
    encoder.options().tracking.min_gain = gain;
    begin = end + 1;
    encoder.options().track_landmarks = spacing > 0;
    if (spacing > 0) encoder.options().tracking.spacing = spacing;
    if (window > 0) encoder.options().tracking.window = static_cast<int>(window);
    if (round_trip > 0) encoder.options().tracking.max_round_trip = round_trip;
    encoder.options().registration.smoothing = smoothing;
    encoder.register_frames();
    encoder.sample_frames();
    const KeyframeSelection chosen = encoder.select_keyframes();
    double sum = 0;
    int n = 0;
    for (double e : chosen.predicted_error) {
      if (e > 0) sum += e, ++n;
    }
    int fallbacks = 0;
    for (int i = 0; i < encoder.frame_count(); ++i) fallbacks += encoder.registration(i).fallback != RegistrationFallback::kNone;
    std::printf("gain %.2f spacing %.3f window %.0f round trip %.3f smoothing %.3g: %zu keyframes, predicted mean %.4f%% (budget mean %.4f%%), "
                "%d fallbacks, %.1f points, %.2f s tracking, %.2f s registration\n",
                gain, spacing, window, round_trip, smoothing, chosen.keyframes.size(), 100 * sum / std::max(n, 1), 100 * chosen.budget_mean_error, fallbacks,
                encoder.report().tracked_points_mean, encoder.report().seconds_tracking, encoder.report().seconds_registration);
  }
}

}  // namespace
}  // namespace facemorph
