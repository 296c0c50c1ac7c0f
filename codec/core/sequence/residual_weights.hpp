// Residual frames (spec/method.md §7.18, format 2.3): between two keyframes a captured frame may
// carry a correction of the spline's blend weights, so that a frame the spline misses (fast speech:
// the mouth opens and shuts between keyframes) is shown as another blend of the same keyframes. The
// correction is linear in t between a keyframe interval's residual frames and zero at its keyframes,
// so the blend stays continuous in t, a keyframe's own time shows the keyframe, and outside the
// keyframes' span (extrapolation) nothing changes.
#pragma once

#include "codec/core/sequence/spline.hpp"

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace facemorph {

struct ResidualFrame {
  double time = 0;            // strictly inside a keyframe interval (t_i, t_{i+1}), seconds
  std::vector<double> delta;  // one per key of residual_window(i, K), in order; they sum to 0
};

// The keys a residual of keyframe interval i (between keyframes i and i + 1) corrects: i − 1 … i + 2,
// those of 0 … K − 1 (the four a Catmull-Rom segment blends; 2 to 4 of them).
struct KeyWindow {
  int32_t first = 0;
  int32_t count = 0;
};
KeyWindow residual_window(int interval, int key_count);
// The keyframe interval i with t_i < t < t_{i+1} of `key_times` (strictly increasing), or -1 where t
// is outside their span, at a keyframe, or not finite.
int residual_interval(const std::vector<double>& key_times, double t);
// The keyframe interval of a frame that a list of frames between keyframes holds (residual frames,
// frame patches), after the checks both lists share: its time finite, after `previous` (the list's
// frame before it; null for the first), strictly inside a keyframe interval. `fail` throws, naming
// the frame and the defect.
int checked_frame_interval(const std::vector<double>& key_times, double time, const double* previous,
                           const std::function<void(const std::string&)>& fail);

// The most a correction may add to one key's weight: far beyond what a fit asks for (a frame is a
// blend of its neighbours), small enough that a blend stays a bounded combination of keyframes.
inline constexpr double kMaxResidualDelta = 4.0;
// How far from 0 a residual's corrections may sum (rounding of stored corrections is exact: the
// format stores all but the last, which is minus their sum).
inline constexpr double kResidualSumTolerance = 1e-9;

// Checks what residual_weights relies on, against the keyframes' times (strictly increasing): each
// residual's time finite and strictly inside a keyframe interval, the times strictly increasing, one
// correction per key of its window, each finite with |δ| ≤ kMaxResidualDelta, summing to 0 within
// kResidualSumTolerance. Throws kInvalidArgument naming the residual and the defect.
void validate_residuals(const std::vector<double>& key_times, const std::vector<ResidualFrame>& residuals);

// The weights a frame at t blends: the spline's, plus the correction of t's keyframe interval
// interpolated linearly between the neighbouring nodes (its residuals, and its two keyframes with a
// correction of 0). Keys stay increasing; a key whose weight sums to exactly 0 is left out. Where no
// residual applies (outside the span, at a keyframe, an interval without residuals) it is
// spline.weights(t) itself. `residuals` must pass validate_residuals for the spline's times.
SplineWeights residual_weights(const KeyframeSpline& spline, const std::vector<ResidualFrame>& residuals, double t);

// A residual's time as a file stores it (spec/container.md §7.4): first_time + q / (kResidualTimeSteps
// fps), q a whole number of 64ths of the capture's frame period from its first frame.
inline constexpr double kResidualTimeSteps = 64;
double residual_time(int64_t q, double first_time, double fps);
// The q whose residual_time is nearest `time`.
int64_t residual_time_code(double time, double first_time, double fps);

// `residuals` (times and corrections as a fit gave them) as a file can hold them: each time moved to
// its nearest residual_time, and a residual whose moved time is not strictly inside its keyframe
// interval or not after the previous one's dropped (frames closer than a 64th of a frame period).
std::vector<ResidualFrame> residuals_on_file_times(std::vector<ResidualFrame> residuals, const std::vector<double>& key_times,
                                                   double first_time, double fps);

// The most keys residual_weights returns for these residuals: the spline's max_keys(), or more where
// a residual's window reaches keys the spline does not blend there (a linear spline: 2 → 4).
int residual_max_keys(const KeyframeSpline& spline, const std::vector<ResidualFrame>& residuals);

}  // namespace facemorph
