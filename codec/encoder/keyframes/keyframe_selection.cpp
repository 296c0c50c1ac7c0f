// Keyframe selection by predicted error: an even start (or greedy, for a tolerance), then local
// moves of each keyframe within the gap to its neighbours while the objective improves.
#include "codec/encoder/keyframes/keyframes.hpp"

#include "codec/core/util/parallel.hpp"
#include "codec/encoder/keyframes/blend_correction.hpp"
#include "codec/encoder/keyframes/normal_offsets.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace facemorph {

namespace {

void check_frames(const SelectionFrames& frames, const std::vector<double>& node_weights) {
  if (frames.size() == 0) throw Error(ErrorCode::kInvalidArgument, "keyframe selection: no frames");
  for (size_t i = 0; i < frames.size(); ++i) {
    const std::shared_ptr<const SelectionFrame> f = frames.sampled(i);
    if (f->local.size() != node_weights.size() || f->normal.size() != node_weights.size()) {
      throw Error(ErrorCode::kInvalidArgument, "keyframe selection: frame " + std::to_string(i) + " has arrays of another size");
    }
    if (i > 0 && !(frames.outline(i).time > frames.outline(i - 1).time))
      throw Error(ErrorCode::kInvalidArgument, "keyframe selection: times must increase");
  }
}

// Every frame's predicted errors (0 at keyframes): the RMS the selection weighs, and the
// 99th-percentile point the worst region shows (SelectionOptions::p99_bound).
struct FrameErrors {
  std::vector<double> rms, p99;
  void resize(size_t frames) {
    rms.resize(frames, 0.0);
    p99.resize(frames, 0.0);
  }
  void set(size_t j, double rms_error, double p99_error) {
    rms[j] = rms_error;
    p99[j] = p99_error;
  }
};

// The area-weighted 99th percentile of |offsets|: the smallest |o| with at least 99% of the weight
// at or below it. Only the top few percent by count are sorted (nth_element): G's lumped masses
// differ by a few times at most, so the top 1% of the weight lies among them; the whole is sorted
// where it does not.
double weighted_p99(const std::vector<double>& offsets, const std::vector<double>& weights, double total_weight) {
  if (offsets.empty() || !(total_weight > 0)) return 0.0;
  std::vector<std::pair<double, double>> points(offsets.size());  // (|offset|, weight)
  for (size_t v = 0; v < offsets.size(); ++v) points[v] = {std::abs(offsets[v]), weights[v]};
  const auto larger = [](const auto& a, const auto& b) { return a.first > b.first; };
  const double tail = 0.01 * total_weight;
  for (size_t top : {std::max<size_t>(points.size() / 20, 1), points.size()}) {
    if (top < points.size()) {
      std::nth_element(points.begin(), points.begin() + static_cast<std::ptrdiff_t>(top), points.end(), larger);
    }
    std::sort(points.begin(), points.begin() + static_cast<std::ptrdiff_t>(top), larger);
    double above = 0;  // the weight strictly above the candidate
    for (size_t i = 0; i < top; ++i) {
      if (above + points[i].second >= tail) return points[i].first;
      above += points[i].second;
    }
  }
  return points.back().first;
}

// A frame's capture-frame positions, every node's (SelectionFrame::world_at).
std::vector<Vec3> capture_frame_positions(const SelectionFrame& frame) {
  std::vector<Vec3> world(frame.local.size());
  for (size_t v = 0; v < world.size(); ++v) world[v] = frame.world_at(v);
  return world;
}

// Some frames' capture-frame positions, frame `first` onwards (Predictor::worlds).
struct FrameWorlds {
  int first = 0;
  std::vector<std::vector<Vec3>> frames;
  const Vec3* at(int j) const {
    const int f = j - first;
    return f >= 0 && f < static_cast<int>(frames.size()) ? frames[static_cast<size_t>(f)].data() : nullptr;
  }
};

// Predicts frames from a set of keyframes as the decoder would, and measures the error.
class Predictor {
 public:
  // residual_step > 0: each frame between keyframes predicted with its best residual (SelectionOptions::residuals).
  Predictor(const SelectionFrames& frames, const std::vector<double>& node_weights, SplineKind kind, const Vec3& centre,
            double residual_step = 0)
      : frames_(frames), weights_(node_weights), kind_(kind), centre_(centre), residual_step_(residual_step) {
    for (double w : node_weights) total_weight_ += w;
  }

  // Errors of the frames [first, last] (clamped to the capture) given `keys` (frame indices,
  // increasing); 0 at keyframes.
  // `residuals` (with residual_step): the residual frames kept, at the frames in `at`.
  void errors(const std::vector<int>& keys, int first, int last, FrameErrors& out, std::vector<ResidualFrame>* residuals = nullptr,
              std::vector<int>* at = nullptr) const {
    measure(keys, first, last, out, residuals, at, true);
  }

  // The RMS errors alone, each frame's 99th percentile set to 0: for a search that weighs only the
  // RMS (refine without a p99 limit). The percentile's partial sort costs about half as much as
  // the prediction itself (profiled on Medusa), and the RMS is the same either way.
  void rms_errors(const std::vector<int>& keys, int first, int last, FrameErrors& out, const FrameWorlds* worlds = nullptr) const {
    measure(keys, first, last, out, nullptr, nullptr, false, worlds);
  }

  // As errors() without residuals, each frame's capture-frame positions read from `worlds`.
  void errors_with(const std::vector<int>& keys, int first, int last, FrameErrors& out, const FrameWorlds& worlds) const {
    measure(keys, first, last, out, nullptr, nullptr, true, &worlds);
  }

  // Frames [first, last]'s capture-frame positions (SelectionFrame::world_at, each node's), which
  // every trial position of one keyframe predicts again (refine).
  FrameWorlds worlds(int first, int last, int threads) const {
    FrameWorlds held;
    held.first = std::max(first, 0);
    const int hi = std::min(last, static_cast<int>(frames_.size()) - 1);
    held.frames.resize(static_cast<size_t>(std::max(hi - held.first + 1, 0)));
    parallel_for(static_cast<int>(held.frames.size()), threads, [&](int f) {
      held.frames[static_cast<size_t>(f)] = capture_frame_positions(*frames_.sampled(static_cast<size_t>(held.first + f)));
    });
    return held;
  }

  // Whether affected() is exact: every frame outside it predicted the same whatever keyframe i's
  // position (not so for the not-a-knot spline, global, whose window is an approximation).
  bool local() const { return kind_ != SplineKind::kNotAKnot; }

  // The frames whose prediction can change when keyframe i of `keys` moves between its
  // neighbours: those of the segments that use it (a few keys either side; a window of the global
  // spline, whose weights decay at least 2x per key). A Catmull-Rom segment k blends keys k - 1 …
  // k + 2 (at the ends the one-sided tangents stay within them), so key i reaches the frames from
  // key i - 2 to key i + 2; a linear one keys i - 1 to i + 1. The local cubic's end tangents reach
  // a key further (4 points), and the window is one key wider where that was not worked out.
  std::pair<int, int> affected(const std::vector<int>& keys, size_t i) const {
    const int reach = kind_ == SplineKind::kLinear ? 1 : kind_ == SplineKind::kCatmullRom ? 2 : kind_ == SplineKind::kLocalCubic ? 4 : 13;
    const int lo = static_cast<int>(i) - reach, hi = static_cast<int>(i) + reach;
    return {keys[static_cast<size_t>(std::max(lo, 0))], keys[static_cast<size_t>(std::min(hi, static_cast<int>(keys.size()) - 1))]};
  }

 private:
  void measure(const std::vector<int>& keys, int first, int last, FrameErrors& out, std::vector<ResidualFrame>* residuals,
               std::vector<int>* at, bool with_p99, const FrameWorlds* worlds = nullptr) const {
    std::vector<double> times;
    std::vector<RigidPose> poses;
    for (int k : keys) {
      times.push_back(frames_.outline(static_cast<size_t>(k)).time);
      poses.push_back(frames_.outline(static_cast<size_t>(k)).pose);
    }
    const KeyframeSpline spline(times, kind_);
    const std::vector<Vec3> rotations = unwrap_rotations(poses);
    out.resize(frames_.size());
    const int lo = std::max(first, 0), hi = std::min(last, static_cast<int>(frames_.size()) - 1);
    std::vector<Prediction> predicted(static_cast<size_t>(std::max(hi - lo + 1, 0)));
    for (int j = lo; j <= hi; ++j) {
      if (std::binary_search(keys.begin(), keys.end(), j)) {
        out.set(static_cast<size_t>(j), 0.0, 0.0);
        continue;
      }
      Prediction& p = predicted[static_cast<size_t>(j - lo)];
      p = predict(j, keys, spline, poses, rotations, with_p99, worlds ? worlds->at(j) : nullptr);
      out.set(static_cast<size_t>(j), p.kept() ? p.fitted : p.spline, p.kept() ? p.fitted_p99 : p.spline_p99);
    }
    if (!residuals) return;
    // The decoder interpolates the corrections between an interval's residual frames (0 at its
    // keyframes), so a frame left without one between two would take theirs, which need not fit it
    // (measured on Medusa: with residuals only where they were kept, 101 of 209 held-out frames came
    // out worse). So an interval with a residual kept has one at each of its frames: the frame's own
    // fit where that is no worse than the spline, else a correction of 0.
    for (size_t i = 0; i + 1 < keys.size(); ++i) {
      const int from = std::max(keys[i] + 1, lo), to = std::min(keys[i + 1] - 1, hi);
      bool any = false;
      for (int j = from; j <= to; ++j) any = any || predicted[static_cast<size_t>(j - lo)].kept();
      if (!any) continue;
      const KeyWindow window = residual_window(static_cast<int>(i), static_cast<int>(keys.size()));
      for (int j = from; j <= to; ++j) {
        Prediction& p = predicted[static_cast<size_t>(j - lo)];
        const bool own = !p.delta.empty() && p.fitted <= p.spline;
        residuals->push_back({frames_.outline(static_cast<size_t>(j)).time,
                              own ? std::move(p.delta) : std::vector<double>(static_cast<size_t>(window.count), 0.0)});
        at->push_back(j);
        out.set(static_cast<size_t>(j), own ? p.fitted : p.spline, own ? p.fitted_p99 : p.spline_p99);
      }
    }
  }

  // A frame's predicted error with the spline alone, and with residuals its best residual and the
  // error with it (fitted < 0: none fitted, the spline's error being below kResidualFloor).
  struct Prediction {
    double spline = 0, fitted = -1;
    double spline_p99 = 0, fitted_p99 = 0;  // the 99th-percentile |offset| / diagonal of each
    std::vector<double> delta;
    // Worth its bytes: a tenth or more of the frame's error (kResidualMinGain).
    bool kept() const { return fitted >= 0 && fitted <= (1 - kResidualMinGain) * spline; }
  };

  Prediction predict(int j, const std::vector<int>& keys, const KeyframeSpline& spline, const std::vector<RigidPose>& poses,
                     const std::vector<Vec3>& rotations, bool with_p99, const Vec3* world) const {
    const std::shared_ptr<const SelectionFrame> held = frames_.sampled(static_cast<size_t>(j));
    const SelectionFrame& frame = *held;
    const SplineWeights w = spline.weights(frame.time);
    const RigidPose pose = blend_poses(poses, rotations, w, centre_);
    std::vector<std::shared_ptr<const SelectionFrame>> blended;  // the keyframes the spline blends at t_j
    for (int32_t key : w.keys) blended.push_back(frames_.sampled(static_cast<size_t>(keys[static_cast<size_t>(key)])));
    // The blended keys' arrays read through plain pointers, and the frame's capture-frame positions
    // from `world` where given: the same arithmetic, without reloading each key's vector every node.
    std::vector<const Eigen::Vector3f*> key_local;
    for (const auto& key : blended) key_local.push_back(key->local.data());
    const size_t key_count = key_local.size();
    const double* key_weight = w.weights.data();
    std::vector<Vec3> own_world;
    if (!world) {
      own_world = capture_frame_positions(frame);
      world = own_world.data();
    }
    std::vector<double> offsets(weights_.size());
    predicted_normal_offsets({key_local.data(), key_count}, {key_weight, key_count}, pose, world, frame.normal.data(), offsets.size(),
                             offsets.data());
    double sum = 0;
    for (size_t v = 0; v < weights_.size(); ++v) sum += weights_[v] * offsets[v] * offsets[v];
    Prediction p;
    p.spline = std::sqrt(sum / std::max(total_weight_, 1e-300)) / frame.diagonal;
    if (with_p99) p.spline_p99 = weighted_p99(offsets, weights_, total_weight_) / frame.diagonal;
    if (residual_step_ > 0 && p.spline > kResidualFloor) {
      p.fitted = fit_residual(frame, keys, spline, pose, offsets, p.delta, with_p99 ? &p.fitted_p99 : nullptr);
    }
    return p;
  }

  // The residual of `frame` (residual_weights.hpp) that best cancels its normal offsets under the
  // spline: the pose stays the spline's, so each key's correction moves the prediction along the
  // normals by its rotated samples (fit_blend_correction, rounded to residual_step_). Returns the
  // error with it, and its 99th percentile in `p99` where that is given.
  double fit_residual(const SelectionFrame& frame, const std::vector<int>& keys, const KeyframeSpline& spline, const RigidPose& pose,
                      const std::vector<double>& offsets, std::vector<double>& delta, double* p99) const {
    const std::vector<double>& times = spline.times();
    const int interval = static_cast<int>(std::upper_bound(times.begin(), times.end(), frame.time) - times.begin()) - 1;
    const KeyWindow window = residual_window(interval, spline.key_count());
    const int n = window.count;
    if (n < 2) return 1e300;
    std::vector<std::shared_ptr<const SelectionFrame>> keyed;
    for (int m = 0; m < n; ++m) keyed.push_back(frames_.sampled(static_cast<size_t>(keys[static_cast<size_t>(window.first + m)])));
    const Eigen::Matrix3d& rotation = pose.rotation;
    // a[m][v]: how far key m's unit weight moves node v along its normal.
    std::vector<std::vector<double>> a(static_cast<size_t>(n), std::vector<double>(weights_.size()));
    for (int m = 0; m < n; ++m) {
      for (size_t v = 0; v < weights_.size(); ++v)
        a[static_cast<size_t>(m)][v] = (rotation * keyed[static_cast<size_t>(m)]->local_at(v)).dot(frame.normal_at(v));
    }
    const double sum = fit_blend_correction(offsets, a, weights_, residual_step_, delta);
    if (delta.empty()) return 1e300;
    if (p99) {
      std::vector<double> corrected = offsets;
      for (int m = 0; m < n; ++m) {
        for (size_t v = 0; v < corrected.size(); ++v) corrected[v] += delta[static_cast<size_t>(m)] * a[static_cast<size_t>(m)][v];
      }
      *p99 = weighted_p99(corrected, weights_, total_weight_) / frame.diagonal;
    }
    return std::sqrt(sum / std::max(total_weight_, 1e-300)) / frame.diagonal;
  }

  const SelectionFrames& frames_;
  const std::vector<double>& weights_;
  SplineKind kind_;
  Vec3 centre_;
  double residual_step_ = 0;
  double total_weight_ = 0;
};

struct Objective {
  double mean = 0, worst = 0;
  double worst_p99 = 0;  // the worst held-out frame's 99th percentile (a bound, not weighed)
  // Mean and worst both count: the mean is what a viewer sees most of the time, the worst what
  // they notice. A quarter of the worst, measured on Medusa, lowered both against either alone
  // (spec/method.md §7.5).
  double value() const { return mean + 0.25 * worst; }
};

Objective objective(const FrameErrors& errors, const std::vector<int>& keys) {
  Objective o;
  int held = 0;
  for (size_t j = 0; j < errors.rms.size(); ++j) {
    if (std::binary_search(keys.begin(), keys.end(), static_cast<int>(j))) continue;
    o.mean += errors.rms[j];
    o.worst = std::max(o.worst, errors.rms[j]);
    o.worst_p99 = std::max(o.worst_p99, errors.p99[j]);
    ++held;
  }
  o.mean /= std::max(held, 1);
  return o;
}

// Moves each inner keyframe to the position within the gap to its neighbours that lowers the
// objective most, sweeping until nothing moves. `limit` > 0: no move may lift the worst above it;
// `p99_limit` > 0: nor the worst frame's 99th percentile above that. A keyframe's trial positions are
// measured on up to `threads` threads (each against the errors before the move) and then weighed in
// order, as one thread weighs them: the keys chosen do not depend on `threads`.
void refine(const Predictor& predictor, std::vector<int>& keys, FrameErrors& errors, double limit, double p99_limit = 0,
            int threads = 1) {
  Objective current = objective(errors, keys);
  const std::vector<int> initial = keys;
  // Each move is weighed on the RMS alone where no p99 limit applies: measuring the percentile of
  // every trial took a third of Medusa's selection (spec/method.md §7.18). Only with a spline whose
  // reach affected() covers exactly (a local one), so that one measure at the end equals what the
  // moves measured.
  const bool rms_only = p99_limit <= 0 && predictor.local();
  for (int sweep = 0; sweep < 6; ++sweep) {
    bool moved = false;
    for (size_t i = 1; i + 1 < keys.size(); ++i) {
      const int original = keys[i];
      int best = original;
      FrameErrors best_errors;
      // Every position in the gap but the original (each a prediction of the frames it affects, the
      // selection's cost: 10% of Medusa's encode on one thread), measured first.
      std::vector<int> positions;
      for (int position = keys[i - 1] + 1; position < keys[i + 1]; ++position) {
        if (position != original) positions.push_back(position);
      }
      std::vector<FrameErrors> trial_errors(positions.size(), errors);
      std::vector<Objective> trial_objectives(positions.size());
      const auto [window_first, window_last] = predictor.affected(keys, i);  // the neighbours' keys bound it, not key i
      const FrameWorlds worlds = predictor.worlds(window_first, window_last, threads);
      parallel_for(static_cast<int>(positions.size()), threads, [&](int t) {
        std::vector<int> trial = keys;
        trial[i] = positions[static_cast<size_t>(t)];
        const auto [first, last] = predictor.affected(trial, i);
        FrameErrors& e = trial_errors[static_cast<size_t>(t)];
        if (rms_only) {
          predictor.rms_errors(trial, first, last, e, &worlds);
        } else {
          predictor.errors_with(trial, first, last, e, worlds);
        }
        trial_objectives[static_cast<size_t>(t)] = objective(e, trial);
      });
      for (size_t t = 0; t < positions.size(); ++t) {
        const Objective& o = trial_objectives[t];
        if (o.value() < current.value() - 1e-12 && (limit <= 0 || o.worst <= limit) && (p99_limit <= 0 || o.worst_p99 <= p99_limit)) {
          current = o;
          best = positions[t];
          best_errors = std::move(trial_errors[t]);
        }
      }
      if (best != original) {
        keys[i] = best;
        errors = std::move(best_errors);
        moved = true;
      }
    }
    if (!moved) break;
  }
  // Without a p99 limit the moves were weighed on the RMS alone; the percentiles at the keyframes
  // they reached are measured once (the RMS kept as the moves left it, bit for bit).
  if (rms_only && keys != initial) {
    FrameErrors measured;
    predictor.errors(keys, 0, static_cast<int>(errors.rms.size()) - 1, measured);
    errors.p99 = std::move(measured.p99);
  }
}

}  // namespace

std::vector<double> prediction_errors(const std::vector<SelectionFrame>& frames, const std::vector<double>& node_weights,
                                      const std::vector<int>& keyframes, SplineKind kind, const Vec3& pose_centre) {
  return prediction_errors(SelectionFramesInMemory(frames), node_weights, keyframes, kind, pose_centre);
}

KeyframeSelection select_keyframes(const std::vector<SelectionFrame>& frames, const std::vector<double>& node_weights,
                                   const SelectionOptions& options) {
  return select_keyframes(SelectionFramesInMemory(frames), node_weights, options);
}

std::vector<double> prediction_errors(const SelectionFrames& frames, const std::vector<double>& node_weights,
                                      const std::vector<int>& keyframes, SplineKind kind, const Vec3& pose_centre) {
  check_frames(frames, node_weights);
  for (size_t i = 0; i < keyframes.size(); ++i) {
    if (keyframes[i] < 0 || static_cast<size_t>(keyframes[i]) >= frames.size() || (i > 0 && keyframes[i] <= keyframes[i - 1])) {
      throw Error(ErrorCode::kInvalidArgument, "keyframe selection: keyframes must be increasing frame indices");
    }
  }
  FrameErrors errors;
  Predictor(frames, node_weights, kind, pose_centre).errors(keyframes, 0, static_cast<int>(frames.size()) - 1, errors);
  return errors.rms;
}

namespace {

// The largest value of `values`; 0 for none.
double largest(const std::vector<double>& values) { return values.empty() ? 0.0 : *std::max_element(values.begin(), values.end()); }

// The selection with every frame predicted as `predictor` predicts it (with or without residuals);
// with residuals, the residual frames of the keyframes chosen are recorded at every return.
KeyframeSelection select_with(const SelectionFrames& frames, const Predictor& predictor, const SelectionOptions& options, bool residuals) {
  const int count = static_cast<int>(frames.size());
  KeyframeSelection selection;
  FrameErrors errors;
  const auto finish = [&] {
    if (residuals) predictor.errors(selection.keyframes, 0, count - 1, errors, &selection.residuals, &selection.residual_frames);
    selection.predicted_error = std::move(errors.rms);
    selection.predicted_p99 = std::move(errors.p99);
    return selection;
  };
  std::vector<int>& keys = selection.keyframes;
  if (count <= 2) {
    for (int i = 0; i < count; ++i) keys.push_back(i);
    predictor.errors(keys, 0, count - 1, errors);
    selection.history.emplace_back(count, 0.0);
    return finish();
  }
  if (options.max_error > 0) {
    // A tolerance: greedily add the worst-predicted frame until every frame is within it.
    keys = {0, count - 1};
    for (;;) {
      predictor.errors(keys, 0, count - 1, errors);
      const auto worst = std::max_element(errors.rms.begin(), errors.rms.end());
      selection.history.emplace_back(static_cast<int>(keys.size()), *worst);
      if (*worst <= options.max_error || static_cast<int>(keys.size()) >= count) break;
      const int add = static_cast<int>(worst - errors.rms.begin());
      keys.insert(std::upper_bound(keys.begin(), keys.end(), add), add);
    }
    refine(predictor, keys, errors, options.max_error, 0, options.threads);
  } else {
    // A budget: evenly spaced in time, then moved to where the frames need them. Measured on
    // Medusa (232 frames, 23 keyframes, linear): even 0.42% mean / 1.93% worst, greedy by the
    // worst 0.40% / 0.78%, even then moved 0.30% / 0.78% (spec/method.md §7.5).
    const int budget = std::clamp(static_cast<int>(std::lround(options.fraction * count)), 2, count);
    const double first = frames.outline(0).time, span = frames.outline(frames.size() - 1).time - first;
    std::vector<double> times(frames.size());
    for (size_t j = 0; j < frames.size(); ++j) times[j] = frames.outline(j).time;
    for (int k = 0; k < budget; ++k) {
      const double target = first + span * k / (budget - 1);
      int index = static_cast<int>(std::lower_bound(times.begin(), times.end(), target) - times.begin());
      index = std::clamp(index, keys.empty() ? 0 : keys.back() + 1, count - (budget - k));
      keys.push_back(index);
    }
    predictor.errors(keys, 0, count - 1, errors);
    selection.history.emplace_back(static_cast<int>(keys.size()), largest(errors.rms));
    refine(predictor, keys, errors, 0, 0, options.threads);
    selection.budget = budget;
    std::vector<double> intervals;
    for (size_t j = 1; j < frames.size(); ++j) intervals.push_back(times[j] - times[j - 1]);
    if (!intervals.empty()) {
      std::nth_element(intervals.begin(), intervals.begin() + static_cast<std::ptrdiff_t>(intervals.size() / 2), intervals.end());
      selection.median_interval = intervals[intervals.size() / 2];
    }
    const Objective spread = objective(errors, keys);
    selection.budget_mean_error = spread.mean;
    selection.budget_worst_error = spread.worst;
    selection.budget_worst_p99 = spread.worst_p99;
    // Frames far apart or fast: the budget spread thin leaves errors no budget was meant to allow;
    // add the worst-predicted frame until the mean and the worst are within the bound (spec/method.md
    // §7.5), and the worst region within its own (the frame whose 99th percentile is furthest above
    // it first), then let refinement move them without lifting either worst past its bound.
    const double bound = options.error_bound, worst_bound = 3 * options.error_bound;
    const double p99_bound = bound > 0 ? options.p99_bound : 0.0;
    const auto add_worst = [&](const std::vector<double>& by) {
      const int add = static_cast<int>(std::max_element(by.begin(), by.end()) - by.begin());
      keys.insert(std::upper_bound(keys.begin(), keys.end(), add), add);
      predictor.errors(keys, 0, count - 1, errors);
      selection.history.emplace_back(static_cast<int>(keys.size()), largest(errors.rms));
    };
    if (options.sparse_interval > 0 && selection.median_interval > options.sparse_interval) {
      // A sparse capture: every frame a keyframe (SelectionOptions::sparse_interval).
      selection.sparse = true;
      keys.resize(static_cast<size_t>(count));
      std::iota(keys.begin(), keys.end(), 0);
      predictor.errors(keys, 0, count - 1, errors);
    } else if (bound > 0) {
      if (spread.mean > bound || spread.worst > worst_bound) {
        for (Objective o = spread; (o.mean > bound || o.worst > worst_bound) && static_cast<int>(keys.size()) < count;
             o = objective(errors, keys)) {
          add_worst(errors.rms);
        }
        refine(predictor, keys, errors, worst_bound, 0, options.threads);
      }
      // Then the worst region: the frame whose 99th percentile is furthest above its bound first.
      // The keyframes it adds are for the worst region alone: the grid's and the rounding's RMS
      // targets stay those of the keyframes the RMS bounds chose (rate_mean_error), which on ICT
      // decimated to 2k otherwise rounded the fields twice as finely: 14% more bytes for the same decoded error.
      const Objective rms_chosen = objective(errors, keys);
      if (p99_bound > 0 && rms_chosen.worst_p99 > p99_bound) {
        selection.rate_mean_error = rms_chosen.mean;
        for (Objective o = rms_chosen; o.worst_p99 > p99_bound && static_cast<int>(keys.size()) < count; o = objective(errors, keys)) {
          add_worst(errors.p99);
        }
        refine(predictor, keys, errors, worst_bound, p99_bound, options.threads);
      }
    }
  }
  selection.history.emplace_back(static_cast<int>(keys.size()), largest(errors.rms));
  return finish();
}

// A budget the error bound left as it was: the fewest keyframes whose frames, each with its residual,
// are predicted within what the budget's keyframes leave without them, mean and worst (on Medusa
// the objective mean + ¼ worst alone traded 23 keyframes for 22 whose worst frame decoded at 0.90%
// against 0.79%, p99 2.43% against 1.73%), and the worst region within SelectionOptions::p99_bound, so that
// residuals take the place of keyframes there too. Each smaller count is chosen as the budget is
// (spline_only: even, then moved), and its residuals added; the search stops at the first count
// that misses. The keyframes' predicted errors stay the spline's (they set N and the field
// rounding, spec/method.md §7.18); `plain` (with its residuals) where no smaller count holds.
KeyframeSelection fewer_keyframes_with_residuals(const SelectionFrames& frames, const Predictor& spline_only,
                                                 const Predictor& with_residuals, const SelectionOptions& options,
                                                 KeyframeSelection plain) {
  const int count = static_cast<int>(frames.size());
  FrameErrors plain_errors;
  plain_errors.rms = plain.predicted_error;
  plain_errors.p99 = plain.predicted_p99;
  const Objective bar = objective(plain_errors, plain.keyframes);
  const double p99_bound = options.error_bound > 0 ? options.p99_bound : 0.0;
  SelectionOptions fewer = options;
  fewer.error_bound = 0;
  KeyframeSelection best = std::move(plain);
  for (int budget = static_cast<int>(best.keyframes.size()) - 1; budget >= 2; --budget) {
    fewer.fraction = static_cast<double>(budget) / count;
    KeyframeSelection trial = select_with(frames, spline_only, fewer, false);
    if (static_cast<int>(trial.keyframes.size()) != budget) break;
    FrameErrors with;
    with_residuals.errors(trial.keyframes, 0, count - 1, with, &trial.residuals, &trial.residual_frames);
    const Objective o = objective(with, trial.keyframes);
    if (!(o.mean <= bar.mean && o.worst <= bar.worst && (p99_bound <= 0 || o.worst_p99 <= p99_bound))) break;
    trial.spline_keyframes = best.spline_keyframes;
    best = std::move(trial);
  }
  return best;
}

}  // namespace

KeyframeSelection select_keyframes(const SelectionFrames& frames, const std::vector<double>& node_weights,
                                   const SelectionOptions& options) {
  check_frames(frames, node_weights);
  if (options.residuals && !(options.residual_step > 0 && options.residual_step <= 1)) {
    throw Error(ErrorCode::kInvalidArgument, "keyframe selection: the residual step must lie in (0, 1]");
  }
  const Predictor spline_only(frames, node_weights, options.spline, options.pose_centre);
  KeyframeSelection plain = select_with(frames, spline_only, options, false);
  plain.spline_keyframes = static_cast<int>(plain.keyframes.size());
  if (!options.residuals) return plain;
  const Predictor with_residuals(frames, node_weights, options.spline, options.pose_centre, options.residual_step);
  // Residual frames take the place of keyframes only where the error bound (or a tolerance) added
  // keyframes past the budget: there a residual is bytes against a keyframe's hundreds. Elsewhere
  // the keyframes stay the spline's own, and so do the predicted errors that set N and the field
  // precision: the residuals are added to what the encode would have been (measured on Medusa, 23
  // keyframes at the budget: letting them move the keyframes and N cost 24% more bytes for a worse
  // decoded error; spec/method.md §7.18).
  const bool grown =
      options.max_error > 0 || (!plain.sparse && plain.budget > 0 && static_cast<int>(plain.keyframes.size()) > plain.budget);
  if (grown) {
    KeyframeSelection traded = select_with(frames, with_residuals, options, true);
    traded.spline_keyframes = plain.spline_keyframes;
    if (traded.keyframes.size() < plain.keyframes.size()) return traded;
  }
  // The spline's own keyframes carry no residuals: on them residuals would be bytes added
  // (residuals_pay), so none is predicted for them either.
  if (grown || plain.sparse || plain.budget <= 2) return plain;
  return fewer_keyframes_with_residuals(frames, spline_only, with_residuals, options, std::move(plain));
}

bool residuals_pay(const KeyframeSelection& chosen) { return static_cast<int>(chosen.keyframes.size()) < chosen.spline_keyframes; }

double mean_predicted_error(const KeyframeSelection& chosen) {
  if (chosen.rate_mean_error > 0) return chosen.rate_mean_error;
  double sum = 0;
  int count = 0;
  for (double e : chosen.predicted_error) {
    if (e > 0) {
      sum += e;
      ++count;
    }
  }
  return count == 0 ? 0.0 : sum / count;
}

double unpredicted_error_bound(const SelectionOptions& options) {
  if (options.max_error > 0) return options.max_error;
  return options.error_bound > 0 ? options.error_bound : kDefaultKeyframeErrorBound;
}

double held_error(const KeyframeSelection& chosen, const SelectionOptions& options) {
  const double mean = mean_predicted_error(chosen);
  return mean > 0 ? mean : unpredicted_error_bound(options);
}

}  // namespace facemorph
