// Residual frames: corrections of the spline's blend weights between keyframes (spec/method.md §7.18).
#include "codec/core/sequence/residual_weights.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <limits>
#include <string>

namespace facemorph {

KeyWindow residual_window(int interval, int key_count) {
  const int first = std::max(interval - 1, 0), last = std::min(interval + 2, key_count - 1);
  return {first, std::max(last - first + 1, 0)};
}

int residual_interval(const std::vector<double>& times, double t) {
  if (times.size() < 2 || !(t > times.front() && t < times.back())) return -1;
  const auto after = std::upper_bound(times.begin(), times.end(), t);  // first time > t
  const int i = static_cast<int>(after - times.begin()) - 1;
  return times[static_cast<size_t>(i)] == t ? -1 : i;
}

int checked_frame_interval(const std::vector<double>& key_times, double time, const double* previous,
                           const std::function<void(const std::string&)>& fail) {
  if (!std::isfinite(time)) fail("its time is not finite");
  if (previous && !(time > *previous)) fail("times must increase");
  const int i = residual_interval(key_times, time);
  if (i < 0) fail("its time " + std::to_string(time) + " s is not strictly between two keyframes");
  return i;
}

void validate_residuals(const std::vector<double>& key_times, const std::vector<ResidualFrame>& residuals) {
  const int count = static_cast<int>(key_times.size());
  for (size_t r = 0; r < residuals.size(); ++r) {
    const ResidualFrame& f = residuals[r];
    const auto fail = [&](const std::string& what) {
      throw Error(ErrorCode::kInvalidArgument, "residual frame " + std::to_string(r) + ": " + what);
    };
    const int i = checked_frame_interval(key_times, f.time, r > 0 ? &residuals[r - 1].time : nullptr, fail);
    const KeyWindow window = residual_window(i, count);
    if (f.delta.size() != static_cast<size_t>(window.count)) {
      fail(std::to_string(f.delta.size()) + " corrections where its keyframe interval has " + std::to_string(window.count) + " keys");
    }
    double sum = 0;
    for (double d : f.delta) {
      if (!std::isfinite(d) || std::abs(d) > kMaxResidualDelta)
        fail("a correction is not finite or beyond ±" + std::to_string(kMaxResidualDelta));
      sum += d;
    }
    if (std::abs(sum) > kResidualSumTolerance) fail("its corrections sum to " + std::to_string(sum) + ", not 0");
  }
}

SplineWeights residual_weights(const KeyframeSpline& spline, const std::vector<ResidualFrame>& residuals, double t) {
  SplineWeights w = spline.weights(t);
  const std::vector<double>& times = spline.times();
  const int i = residuals.empty() ? -1 : residual_interval(times, t);
  if (i < 0) return w;
  // The nodes either side of t within its interval: a residual there, or the interval's keyframe.
  const auto after = std::upper_bound(residuals.begin(), residuals.end(), t, [](double x, const ResidualFrame& f) { return x < f.time; });
  const ResidualFrame* left =
      after != residuals.begin() && std::prev(after)->time > times[static_cast<size_t>(i)] ? &*std::prev(after) : nullptr;
  const ResidualFrame* right = after != residuals.end() && after->time < times[static_cast<size_t>(i) + 1] ? &*after : nullptr;
  if (!left && !right) return w;
  const double t0 = left ? left->time : times[static_cast<size_t>(i)], t1 = right ? right->time : times[static_cast<size_t>(i) + 1];
  const double u = (t - t0) / (t1 - t0);
  const KeyWindow window = residual_window(i, spline.key_count());
  SplineWeights out;
  size_t s = 0;  // next spline key not yet merged
  auto take_spline_until = [&](int32_t key) {
    for (; s < w.keys.size() && w.keys[s] < key; ++s) {
      out.keys.push_back(w.keys[s]);
      out.weights.push_back(w.weights[s]);
    }
  };
  for (int32_t j = 0; j < window.count; ++j) {
    const int32_t key = window.first + j;
    take_spline_until(key);
    double value = 0;
    if (s < w.keys.size() && w.keys[s] == key) value = w.weights[s++];
    // (1 − u) δ_left + u δ_right: at a residual's own time exactly its correction.
    if (left) value += (1 - u) * left->delta[static_cast<size_t>(j)];
    if (right) value += u * right->delta[static_cast<size_t>(j)];
    if (value != 0) {
      out.keys.push_back(key);
      out.weights.push_back(value);
    }
  }
  take_spline_until(std::numeric_limits<int32_t>::max());
  return out;
}

double residual_time(int64_t q, double first_time, double fps) { return first_time + static_cast<double>(q) / (kResidualTimeSteps * fps); }

int64_t residual_time_code(double time, double first_time, double fps) {
  return std::llround((time - first_time) * kResidualTimeSteps * fps);
}

std::vector<ResidualFrame> residuals_on_file_times(std::vector<ResidualFrame> residuals, const std::vector<double>& key_times,
                                                   double first_time, double fps) {
  std::vector<ResidualFrame> out;
  for (ResidualFrame& f : residuals) {
    const int before = residual_interval(key_times, f.time);
    f.time = residual_time(residual_time_code(f.time, first_time, fps), first_time, fps);
    if (before < 0 || residual_interval(key_times, f.time) != before || (!out.empty() && !(f.time > out.back().time))) continue;
    out.push_back(std::move(f));
  }
  return out;
}

int residual_max_keys(const KeyframeSpline& spline, const std::vector<ResidualFrame>& residuals) {
  if (residuals.empty()) return spline.max_keys();
  // A window is the 4 keys a Catmull-Rom segment blends, within the local cubic's 6; a linear
  // segment blends 2 of them; not-a-knot's window is wide but need not hold them all.
  const int window = std::min(4, spline.key_count());
  const int keys = spline.kind() == SplineKind::kNotAKnot ? spline.max_keys() + window : std::max(spline.max_keys(), window);
  return std::min(keys, spline.key_count());
}

}  // namespace facemorph
