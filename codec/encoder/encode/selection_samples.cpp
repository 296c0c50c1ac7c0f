// The sample stage's state: the selection grid's weights, every frame's outline and samples, and
// each frame's noise estimate from them.
#include "codec/encoder/encode/selection_samples.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace facemorph {

namespace {

// What of frame k its neighbours' motion does not explain: its surface (selection grid, face frame)
// against the cubic through the four nearest other frames in time (k−2, k−1, k+1, k+2; one-sided
// at the ends), RMS by area, over the stencil's noise gain √(1 + Σ w²). For independent noise of
// RMS σ per frame this is σ; smooth motion leaks in only through its fourth derivative (1.7% of a
// sinusoid of 11 frames a period). Infinity with fewer than 5 frames.
double frame_noise(const SelectionFrames& frames, const std::vector<double>& node_weights, int k) {
  const int count = static_cast<int>(frames.size());
  if (count < 5) return std::numeric_limits<double>::infinity();
  const int first = std::clamp(k - 2, 0, count - 5);
  std::vector<int> others;
  for (int j = first; j < first + 5; ++j) {
    if (j != k) others.push_back(j);
  }
  const auto time = [&](int j) { return frames.outline(static_cast<size_t>(j)).time; };
  const double t = time(k);
  std::vector<double> w;
  double gain = 1;
  std::vector<std::shared_ptr<const SelectionFrame>> neighbours;  // their samples, held while used
  for (int a : others) {
    double l = 1;
    for (int b : others) {
      if (b != a) l *= (t - time(b)) / (time(a) - time(b));
    }
    w.push_back(l);
    gain += l * l;
    neighbours.push_back(frames.sampled(static_cast<size_t>(a)));
  }
  const std::shared_ptr<const SelectionFrame> frame = frames.sampled(static_cast<size_t>(k));
  double sum = 0, total = 0;
  for (size_t v = 0; v < node_weights.size(); ++v) {
    Vec3 r = frame->local_at(v);
    for (size_t i = 0; i < others.size(); ++i) r -= w[i] * neighbours[i]->local_at(v);
    sum += node_weights[v] * r.squaredNorm();
    total += node_weights[v];
  }
  return std::sqrt(sum / std::max(total, 1e-300) / gain);
}

}  // namespace

GridGeometry SelectionSamples::start(size_t count, SpillMode mode) {
  GridGeometry geometry(make_disk_grid(kGrid));
  const auto nodes = static_cast<size_t>(geometry.interior_count());
  weights_.resize(nodes);
  for (size_t v = 0; v < nodes; ++v) weights_[v] = geometry.mass()[static_cast<Eigen::Index>(v)];
  outlines_.assign(count, {});
  samples_.reset();  // the samples of the frames as sampled before, if any
  samples_ = std::make_unique<SelectionStore>(outlines_, mode, kCacheBytes);
  released_ = false;
  released_noise_.clear();
  return geometry;
}

void SelectionSamples::put(size_t i, std::vector<Eigen::Vector3f>&& local, std::vector<Eigen::Vector3f>&& normal) {
  if (!samples_) throw Error(ErrorCode::kInternal, "the selection's samples were released or never made (sample_frames first)");
  samples_->put(i, std::move(local), std::move(normal));
}

const SelectionFrames& SelectionSamples::samples() const {
  if (!samples_) throw Error(ErrorCode::kInternal, "the selection's samples were released or never made (sample_frames first)");
  return *samples_;
}

std::shared_ptr<const SelectionFrame> SelectionSamples::frame(int i) const {
  if (!samples_) throw Error(ErrorCode::kInternal, "the selection's samples were released (sample_frames again)");
  return samples_->sampled(static_cast<size_t>(i));
}

double SelectionSamples::noise_at(int k) const {
  if (!released_) return frame_noise(samples(), weights_, k);
  const auto it = released_noise_.find(k);
  if (it == released_noise_.end())
    throw Error(ErrorCode::kInternal, "frame " + std::to_string(k) + " is no keyframe the selection's samples were released for");
  return it->second;
}

Vec3 SelectionSamples::centre(int reference) const {
  const SelectionFrame& frame = outlines_[static_cast<size_t>(reference)];
  Vec3 sum = Vec3::Zero();
  double total = 0;
  for (size_t v = 0; v < weights_.size(); ++v) {
    sum += weights_[v] * frame.local_at(v);
    total += weights_[v];
  }
  return sum / total;
}

std::optional<SelectionSamples::StoreFigures> SelectionSamples::release(const std::vector<int>& keyframes) {
  for (int k : keyframes) released_noise_[k] = noise_at(k);
  std::optional<StoreFigures> figures;
  if (samples_) figures = StoreFigures{samples_->peak_held(), samples_->spilled_bytes()};
  samples_.reset();
  released_ = true;
  return figures;
}

}  // namespace facemorph
