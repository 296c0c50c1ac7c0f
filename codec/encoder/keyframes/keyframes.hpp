// Keyframe selection by error (spec/method.md §7.5): keep the frames where the spline of the kept
// ones predicts the others worst, within a budget (--keyframes 10%) or until every frame is
// predicted within a tolerance (--max-error).
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/residual_weights.hpp"
#include "codec/core/sequence/spline.hpp"

#include <memory>
#include <vector>

namespace facemorph {

// One captured frame as the selection sees it: its registered surface sampled on a coarse copy of
// G, in the face's own frame, with the normals, the head pose and the size. Every frame's samples
// are held until the keyframes are chosen, so they are single precision and the capture frame's
// positions are not stored but placed by the pose: 24 B a node instead of 72 (ICT: 79 instead of
// 238 kB a frame). Single precision moves a node by ~1e-7 of the face's size, a thousandth of the
// smallest error the selection weighs.
struct SelectionFrame {
  double time = 0;
  std::vector<Eigen::Vector3f> local;   // face frame (the pose taken out)
  std::vector<Eigen::Vector3f> normal;  // unit normals in the capture frame
  RigidPose pose;
  double diagonal = 1;  // bounding-box diagonal of the captured frame

  Vec3 local_at(size_t v) const { return local[v].cast<double>(); }
  Vec3 world_at(size_t v) const { return pose.apply(local_at(v)); }  // capture frame
  Vec3 normal_at(size_t v) const { return normal[v].cast<double>(); }
};

// The frames the selection reads: every frame's time, pose and diagonal, and a frame's samples (its
// local and normal vectors) when asked, which a store may keep outside memory (the encoder keeps
// them in its temporary file: 79 kB a frame, and a long capture has thousands).
class SelectionFrames {
 public:
  virtual ~SelectionFrames() = default;
  virtual size_t size() const = 0;
  // Frame i's time, pose and diagonal (its vectors may be empty here).
  virtual const SelectionFrame& outline(size_t i) const = 0;
  // Frame i with its vectors, held while the pointer is. Thread-safe.
  virtual std::shared_ptr<const SelectionFrame> sampled(size_t i) const = 0;
};

// Frames in memory, as they are (the vector outlives the view).
class SelectionFramesInMemory final : public SelectionFrames {
 public:
  explicit SelectionFramesInMemory(const std::vector<SelectionFrame>& frames) : frames_(frames) {}
  size_t size() const override { return frames_.size(); }
  const SelectionFrame& outline(size_t i) const override { return frames_.at(i); }
  std::shared_ptr<const SelectionFrame> sampled(size_t i) const override {
    return {std::shared_ptr<const SelectionFrame>(), &frames_.at(i)};
  }

 private:
  const std::vector<SelectionFrame>& frames_;
};

struct SelectionOptions {
  double fraction = 0.10;  // budget: keyframes = max(2, round(fraction * frames))
  // With the budget, > 0: more keyframes than the budget where it leaves the mean predicted error
  // between keyframes above this, or the worst above 3 times this (frames far apart, fast motion):
  // the worst-predicted frame is added until both hold. 0: the budget exactly.
  double error_bound = 0;
  // With the budget, > 0: a capture whose frames lie on median further apart than this (seconds)
  // keeps every frame as a keyframe. Frames that sparse (scans at a few a second or fewer) give the
  // spline nothing between them to be checked against, and are few: each is stored, not predicted,
  // the grid's RMS target max(0.02%, the noise, half the error bound) (half the bound withdrawn twice,
  // the rule again since the rounding's p99 is held to what the decoded floor leaves of 1%), the
  // fields rounded to two fifths of the error bound (spec/method.md §5.3, §7.5, §7.6).
  double sparse_interval = 0;
  // With the error bound (> 0), > 0: the budget also grows until every held-out frame's predicted
  // 99th-percentile point error (the area-weighted 99th percentile of the prediction's offsets along
  // the frame's normals, over its diagonal) is within this: the worst region (lips, eyelids), which
  // the RMS bounds leave far above the RMS (spec/method.md §7.5).
  double p99_bound = 0;
  double max_error = 0;  // > 0: instead of the budget, add keyframes until every frame's predicted error <= this
  SplineKind spline = SplineKind::kCatmullRom;
  Vec3 pose_centre = Vec3::Zero();  // the point whose path the pose blend follows (Sequence::pose_centre)
  // Residual frames (residual_weights.hpp): each frame between keyframes is predicted with the
  // correction of its blend weights that fits it best (least squares on the same normal offsets,
  // rounded to residual_step, within ±1), where that lowers its error by kResidualMinGain or more.
  // Where the error bound grows the budget, the selection weighs those errors, so a frame a residual
  // serves needs no keyframe (KeyframeSelection::residuals); where it does not, the selection takes
  // the fewest keyframes whose frames with residuals are predicted within what the budget's leave
  // without (mean and worst).
  bool residuals = false;
  double residual_step = 1.0 / 128;  // the corrections' quantum (spec/container.md §7.4)
  // Threads the refinement measures a keyframe's trial positions on (0: one per hardware thread);
  // the keyframes chosen are the same for any count.
  int threads = 1;
};

// A residual is kept only where it lowers its frame's predicted error by this fraction (a residual
// costs a few bytes; one that buys less than a tenth of its frame's error is not worth them), and
// only on frames predicted worse than kResidualFloor of the diagonal (below it nothing shows).
inline constexpr double kResidualMinGain = 0.1;
inline constexpr double kResidualFloor = 5e-5;

struct KeyframeSelection {
  std::vector<int> keyframes;           // frame indices, increasing; always the first and the last frame
  std::vector<double> predicted_error;  // per frame: RMS of the prediction's normal offset / diagonal (0 at keyframes)
  std::vector<double> predicted_p99;    // per frame: its area-weighted 99th percentile / diagonal (0 at keyframes)
  // After each addition: how many keyframes, and the worst predicted error then.
  std::vector<std::pair<int, double>> history;
  int budget = 0;                                        // keyframes the budget gave (0 with max_error)
  double budget_mean_error = 0, budget_worst_error = 0;  // what the budget alone left (held-out frames)
  double budget_worst_p99 = 0;                           // and the worst held-out frame's predicted 99th percentile
  // > 0 where SelectionOptions::p99_bound added keyframes: the held-out mean predicted error of the
  // keyframes chosen before them, which mean_predicted_error then returns (the grid's and the
  // field rounding's targets follow the RMS, not the keyframes the worst region added).
  double rate_mean_error = 0;
  double median_interval = 0;  // between consecutive frames, seconds
  bool sparse = false;         // every frame kept: median_interval above SelectionOptions::sparse_interval
  // With SelectionOptions::residuals, where they took keyframes' places (residuals_pay; empty
  // where the selection keeps the spline's own keyframes): the residual frames at the frames they
  // serve (times the frames' own; ResidualFrame::delta multiples of residual_step), increasing.
  // Where the error bound grew the budget, or under a tolerance, predicted_error is each frame's
  // error with its residual; within the budget (fewer keyframes than it, the residuals keeping the
  // frames within what it left) predicted_error is the spline's alone, to which the residuals are added.
  std::vector<ResidualFrame> residuals;
  std::vector<int> residual_frames;  // the frame index of each
  // The keyframes the same selection takes without residuals (with SelectionOptions::residuals;
  // otherwise keyframes.size()): residuals_pay compares the two.
  int spline_keyframes = 0;
};

// Whether the residuals pay for their bytes (spec/method.md §7.18, "Which residuals are kept"): only
// where the selection took fewer keyframes for them. With the spline's own keyframes every residual
// is bytes added to the file it would be without them (4–6 B a frame, +0.2% to +2.2% measured), so
// there the encoder fits none and writes that file byte for byte; a keyframe it saves costs
// hundreds of bytes, more than the residuals of the frames around it.
bool residuals_pay(const KeyframeSelection& chosen);

// The mean of `chosen`'s predicted errors between keyframes (fraction of the diagonal); 0 when
// none was predicted (every frame a keyframe): what the grid's and the field precision's targets scale with.
// Where the worst-region bound added keyframes, the mean before them (KeyframeSelection::rate_mean_error).
double mean_predicted_error(const KeyframeSelection& chosen);

// The default bound on the mean predicted error between keyframes (EncodeOptions::keyframe_error_bound).
inline constexpr double kDefaultKeyframeErrorBound = 0.005;

// The error a frame is held to where the selection predicts none (one frame; every frame a
// keyframe): the tolerance (max_error), else the bound on the mean (error_bound), else, where a
// budget given holds the selection to none (fmenc --keyframes P), the default bound. A frame of a
// sequence at these options may be left that far from its capture, so the fields of a frame nothing
// is predicted for are rounded to two fifths of it (spec/method.md §5.3). The grid reads it too: its
// RMS target there is half of it (choose_grid.cpp; §7.6, "A single frame"), withdrawn twice while the
// coarse N left the worst region no room for that rounding, the rule again since the rounding's p99
// is held to what the decoded floor leaves of 1% (round_fields.cpp).
double unpredicted_error_bound(const SelectionOptions& options);

// What the field rounding's target scales with (auto_target_error): the mean predicted error between
// keyframes (mean_predicted_error), or where the selection predicts none, unpredicted_error_bound.
double held_error(const KeyframeSelection& chosen, const SelectionOptions& options);

// Greedy: start from the first and the last frame, then repeatedly add the frame predicted worst.
// A frame's prediction is the spline (`options.spline`) of the keyframes' face-frame surfaces
// placed by the spline of their poses, exactly as the decoder blends; its error is the RMS over the
// nodes (weighted by `node_weights`, e.g. G's lumped mass) of the prediction's offset along the
// frame's normal — the point-to-surface distance to first order, blind to sliding along the
// surface, which costs nothing — divided by the frame's diagonal. Throws kInvalidArgument for
// fewer than one frame, frames of unequal sizes or times not increasing.
KeyframeSelection select_keyframes(const SelectionFrames& frames, const std::vector<double>& node_weights, const SelectionOptions& options);
KeyframeSelection select_keyframes(const std::vector<SelectionFrame>& frames, const std::vector<double>& node_weights,
                                   const SelectionOptions& options);

// The predicted error of every frame given the keyframes (frame indices, increasing).
std::vector<double> prediction_errors(const SelectionFrames& frames, const std::vector<double>& node_weights,
                                      const std::vector<int>& keyframes, SplineKind spline, const Vec3& pose_centre);
std::vector<double> prediction_errors(const std::vector<SelectionFrame>& frames, const std::vector<double>& node_weights,
                                      const std::vector<int>& keyframes, SplineKind spline, const Vec3& pose_centre);

}  // namespace facemorph
