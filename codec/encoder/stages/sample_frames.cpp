// The encoder's third and fourth stages: every registered frame sampled on the coarse selection
// grid with its rigid head pose, and the keyframes chosen from those samples by the spline's
// predicted error; each frame's noise estimate, which the grid's choice and the keyframe fit read.
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/encode/selection_store.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

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

GridGeometry SequenceEncoder::set_selection_weights() {
  GridGeometry geometry(make_disk_grid(kSelectionGrid));
  const auto nodes = static_cast<size_t>(geometry.interior_count());
  node_weights_.resize(nodes);
  for (size_t v = 0; v < nodes; ++v) node_weights_[v] = geometry.mass()[static_cast<Eigen::Index>(v)];
  return geometry;
}

void SequenceEncoder::sample_frames() {
  const auto start = std::chrono::steady_clock::now();
  const int count = frame_count();
  const auto reference = static_cast<size_t>(options_.reference_frame);
  const GridGeometry geometry = set_selection_weights();
  const size_t nodes = node_weights_.size();
  selection_.assign(static_cast<size_t>(count), {});
  samples_.reset();  // the samples of the frames as sampled before, if any
  samples_ =
      std::make_unique<SelectionStore>(selection_, options_.spill_frames ? SpillMode::kSpill : SpillMode::kMemory, kSelectionCacheBytes);
  samples_released_ = false;
  released_noise_.clear();
  // A frame's registered surface on the nodes, in the capture frame, and its normals.
  auto sample = [&](size_t index, std::vector<Eigen::Vector3f>& normal) {
    SelectionFrame& s = selection_[index];
    s.time = capture_.frames[index].time;
    const std::shared_ptr<const MappedFrame> frame = this->frame(static_cast<int>(index));
    s.diagonal = bounding_box_diagonal(frame->map.surface.positions);
    std::vector<Vec3> all = sample_surface(*frame, static_cast<int>(index), geometry.grid().nodes);
    std::vector<Vec3> tu, tv, normals;
    geometry.frames(all, tu, tv, normals);
    normal.resize(normals.size());
    for (size_t v = 0; v < normals.size(); ++v) normal[v] = normals[v].cast<float>();
    all.resize(nodes);
    return all;
  };
  std::vector<Eigen::Vector3f> reference_normal;
  const std::vector<Vec3> reference_world = sample(reference, reference_normal);
  parallel_for(count, options_.threads, [&](int i) {
    const auto index = static_cast<size_t>(i);
    std::vector<Eigen::Vector3f> normal;
    const std::vector<Vec3> world = index == reference ? reference_world : sample(index, normal);
    if (index == reference) normal = reference_normal;
    // The head pose: the rigid motion taking the reference's registered surface onto this frame's,
    // fitted over every node (weighted by area). The reference's frame is the face frame.
    SelectionFrame& s = selection_[index];
    s.pose = index == reference ? RigidPose{} : fit_rigid_pose(reference_world, world, node_weights_);
    const RigidPose to_face = s.pose.inverse();
    std::vector<Eigen::Vector3f> local(nodes);
    for (size_t v = 0; v < nodes; ++v) local[v] = to_face.apply(world[v]).cast<float>();
    // The reference's local vectors stay in its outline too: pose_centre reads them after the
    // samples are released.
    if (index == reference) s.local = local;
    samples_->put(index, std::move(local), std::move(normal));
  });
  report_.peak_selection_samples_in_memory = 0;
  report_.seconds_selection = seconds_since(start);
}

Vec3 SequenceEncoder::pose_centre() const {
  const SelectionFrame& reference = selection_[static_cast<size_t>(options_.reference_frame)];
  Vec3 sum = Vec3::Zero();
  double total = 0;
  for (size_t v = 0; v < node_weights_.size(); ++v) {
    sum += node_weights_[v] * reference.local_at(v);
    total += node_weights_[v];
  }
  return sum / total;
}

void SequenceEncoder::release_selection_samples(const std::vector<int>& keyframes) {
  for (int k : keyframes) released_noise_[k] = noise_at(k);
  note_selection_samples();
  samples_.reset();
  samples_released_ = true;
}

void SequenceEncoder::note_selection_samples() {
  if (!samples_) return;
  report_.peak_selection_samples_in_memory = std::max(report_.peak_selection_samples_in_memory, samples_->peak_held());
  report_.selection_spilled_bytes = samples_->spilled_bytes();
}

std::shared_ptr<const SelectionFrame> SequenceEncoder::selection_frame(int i) const {
  if (!samples_) throw Error(ErrorCode::kInternal, "the selection's samples were released (sample_frames again)");
  return samples_->sampled(static_cast<size_t>(i));
}

double SequenceEncoder::noise_at(int k) const {
  if (!samples_released_) return frame_noise(*samples_, node_weights_, k);
  const auto it = released_noise_.find(k);
  if (it == released_noise_.end())
    throw Error(ErrorCode::kInternal, "frame " + std::to_string(k) + " is no keyframe the selection's samples were released for");
  return it->second;
}

const SelectionFrames& SequenceEncoder::selection_samples() const {
  if (!samples_) throw Error(ErrorCode::kInternal, "the selection's samples were released or never made (sample_frames first)");
  return *samples_;
}

KeyframeSelection select_keyframes(const SequenceEncoder& encoder) {
  const SelectionFrames& samples = encoder.selection_samples();
  const EncodeOptions& options = encoder.options();
  SelectionOptions selection;
  selection.fraction = options.keyframe_fraction;
  selection.max_error = options.max_error;
  selection.error_bound = options.keyframe_error_bound;
  selection.p99_bound = options.keyframe_p99_bound;
  selection.sparse_interval = options.sparse_frame_interval;
  selection.spline = options.spline;
  selection.pose_centre = encoder.pose_centre();
  selection.residuals = options.residual_frames;
  return select_keyframes(samples, encoder.selection_weights(), selection);
}

}  // namespace facemorph
