// fmbench tracking: landmark tracking (landmark_tracking.hpp) measured on a capture with interior
// landmarks: how close the tracked points come to where the capture's landmarks are, frame by frame;
// or, with --variants, the keyframe selection's predicted error for tracking variants with the
// landmarks withheld. Measurements that used to live in the test binary behind environment
// variables.
#include "tools/bench_tracking.hpp"

#include "codec/encoder/capture/capture.hpp"
#include "codec/encoder/encode/frame_pipeline.hpp"
#include "codec/encoder/encode/sequence_encoder.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/encoder/landmarks/landmark_tracking.hpp"
#include "codec/meshkit/geometry/distance.hpp"

#include "tools/tool_support.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace facemorph::tools {

namespace {

Vec2 on_disk(const MappedFrame& f, const Vec3& p) { return disk_point(f.map, PointToMesh(f.map.surface).closest(p)); }

// The tracked accuracy on every frame, against the capture's interior landmarks (disk RMS).
void measure_accuracy(const TrackingBenchOptions& o) {
  Capture capture = read_capture(o.capture);
  const int stride = std::max(1, o.stride);
  EncodeOptions options;
  options.texture = false;
  options.largest_component = true;
  SequenceEncoder encoder(capture, options);
  map_frames(encoder);
  const Capture& kept = encoder.capture();
  std::vector<size_t> interior;
  for (size_t l = 0; l < kept.landmark_names.size(); ++l) {
    const std::string& n = kept.landmark_names[l];
    if (n.rfind("rim_", 0) != 0 && n != "nose_tip" && n != "nose_bridge" && n != "between_eyes") interior.push_back(l);
  }
  TrackingOptions tracking;
  if (o.image_size > 0) tracking.image_size = o.image_size;
  if (o.window > 0) tracking.window = o.window;
  if (o.blur >= 0) tracking.blur = o.blur;
  if (o.factor_weight >= 0) tracking.log_factor_weight = o.factor_weight;
  if (o.levels > 0) tracking.pyramid_levels = o.levels;
  if (o.round_trip >= 0) tracking.max_round_trip = o.round_trip;
  auto points_of = [&](size_t i) {
    std::vector<Vec2> p;
    for (size_t l : interior) p.push_back(on_disk(*encoder.frame(static_cast<int>(i)), encoder.landmarks(static_cast<int>(i))[l]));
    return p;
  };
  const bool holes = !o.no_holes;
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
    if (o.chain) {
      // Frame to frame: from where the previous frame put each point.
      const DiskFeatures previous = draw(i - stride);
      t = track_points(previous, other, last, {}, tracking);
      if (o.chain_direct) {
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
  if (o.per_landmark) {
    for (size_t l = 0; l < interior.size(); ++l) {
      std::printf("  %s at (%.3f, %.3f): kept %d, RMS %.4f tracked, %.4f untracked\n", kept.landmark_names[interior[l]].c_str(),
                  from[l].x(), from[l].y(), per_kept[l], std::sqrt(per_tracked[l] / (encoder.frame_count() - 1) * stride),
                  std::sqrt(per_untracked[l] / (encoder.frame_count() - 1) * stride));
    }
  }
  std::printf("all: %d of %d kept; RMS %.4f tracked (lost points untracked), %.4f untracked\n", kept_points, tried,
              std::sqrt(sum_tracked / std::max(tried, 1)), std::sqrt(sum_untracked / std::max(tried, 1)));
}

// The keyframe selection's predicted error between keyframes (what held-out frames will show) for
// tracking variants on one mapping of the capture, its landmarks withheld.
void measure_selection(const TrackingBenchOptions& o) {
  Capture capture = read_capture(o.capture);
  if (!o.given_landmarks) {
    capture.landmark_names.clear();
    capture.landmarks.assign(capture.frames.size(), {});
  }
  EncodeOptions options;
  options.texture = false;
  options.residual_frames = false;  // keyframes selected for sequences built without residuals
  SequenceEncoder encoder(capture, options);
  map_frames(encoder);
  const std::string& text = o.variants;
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
    register_frames(encoder);
    sample_frames(encoder);
    const KeyframeSelection chosen = select_keyframes(plan_settings(encoder.options()), encoder.selection());
    double sum = 0;
    int n = 0;
    for (double e : chosen.predicted_error) {
      if (e > 0) sum += e, ++n;
    }
    int fallbacks = 0;
    for (int i = 0; i < encoder.frame_count(); ++i) fallbacks += encoder.registration(i)->fallback != RegistrationFallback::kNone;
    std::printf(
        "gain %.2f spacing %.3f window %.0f round trip %.3f smoothing %.3g: %zu keyframes, predicted mean %.4f%% (budget mean %.4f%%), "
        "%d fallbacks, %.1f points, %.2f s tracking, %.2f s registration\n",
        gain, spacing, window, round_trip, smoothing, chosen.keyframes.size(), 100 * sum / std::max(n, 1), 100 * chosen.budget_mean_error,
        fallbacks, encoder.report().tracked_points_mean, encoder.report().seconds_tracking, encoder.report().seconds_registration);
  }
}

}  // namespace

void add_tracking_command(CLI::App& app, TrackingBenchOptions& options) {
  CLI::App* cmd = app.add_subcommand("tracking",
                                     "Landmark tracking on a capture with interior landmarks: tracked against given, frame by frame; or, "
                                     "with --variants, the keyframe selection per tracking variant, landmarks withheld");
  cmd->add_option("capture", options.capture, "A capture folder with interior landmarks")->required();
  cmd->add_option("--stride", options.stride, "Every stride-th frame")->capture_default_str();
  cmd->add_option("--image-size", options.image_size, "Disk image texels per side (0: the default)");
  cmd->add_option("--window", options.window, "Lucas-Kanade window (0: the default)");
  cmd->add_option("--blur", options.blur, "Image blur (negative: the default)");
  cmd->add_option("--factor-weight", options.factor_weight, "Weight of log λ against H in the images (negative: the default)");
  cmd->add_option("--levels", options.levels, "Pyramid levels (0: the default)");
  cmd->add_option("--round-trip", options.round_trip, "Largest forward-backward distance kept (negative: the default)");
  cmd->add_flag("--no-holes", options.no_holes, "Images without the filled holes' outlines");
  cmd->add_flag("--chain", options.chain, "Track frame to frame instead of from the reference");
  cmd->add_flag("--chain-direct", options.chain_direct,
                "With --chain: track from the reference again, started where the chain put each point");
  cmd->add_flag("--per-landmark", options.per_landmark, "Also each landmark's RMS");
  cmd->add_option("--variants", options.variants, "\"spacing,window,round_trip,smoothing[,gain];...\": the selection per variant instead");
  cmd->add_flag("--given-landmarks", options.given_landmarks, "With --variants: keep the capture's landmarks");
}

int run_tracking_bench(const TrackingBenchOptions& options) {
  if (options.variants.empty()) {
    measure_accuracy(options);
  } else {
    measure_selection(options);
  }
  return 0;
}

}  // namespace facemorph::tools
