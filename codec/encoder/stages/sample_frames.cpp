// The encoder's third and fourth stages: every registered frame sampled on the coarse selection
// grid with its rigid head pose (into the encoder's SelectionSamples, which also estimates each
// frame's noise from them), and the keyframes chosen from those samples by the spline's predicted error.
#include "codec/encoder/encode/sequence_encoder.hpp"

#include "codec/core/util/elapsed.hpp"

#include "codec/core/geometry/elementary.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/util/parallel.hpp"
#include "codec/encoder/encode/plan_keyframes.hpp"
#include "codec/encoder/keyframes/keyframes.hpp"
#include "codec/meshkit/geometry/distance.hpp"
#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

namespace facemorph {

void sample_frames(SequenceEncoder& encoder) {
  const auto start = std::chrono::steady_clock::now();
  const EncodeOptions& options = encoder.options();
  const int count = encoder.frame_count();
  const auto reference = static_cast<size_t>(options.reference_frame);
  SelectionSamples& selection = encoder.selection();
  const GridGeometry geometry = selection.start(static_cast<size_t>(count), options.spill_frames ? SpillMode::kSpill : SpillMode::kMemory);
  const std::vector<double>& node_weights = selection.weights();
  const size_t nodes = node_weights.size();
  const std::vector<CaptureFrame>& frames = encoder.capture().frames;
  // A frame's registered surface on the nodes, in the capture frame, and its normals.
  auto sample = [&](size_t index, std::vector<Eigen::Vector3f>& normal) {
    SelectionFrame& s = selection.outline(index);
    s.time = frames[index].time;
    const std::shared_ptr<const MappedFrame> frame = encoder.frame(static_cast<int>(index));
    s.diagonal = bounding_box_diagonal(frame->map.surface.positions);
    std::vector<Vec3> all = encoder.frame_sampler().sample_surface(*frame, static_cast<int>(index), geometry.grid().nodes);
    std::vector<Vec3> tu, tv, normals;
    geometry.frames(all, tu, tv, normals);
    normal.resize(normals.size());
    for (size_t v = 0; v < normals.size(); ++v) normal[v] = normals[v].cast<float>();
    all.resize(nodes);
    return all;
  };
  std::vector<Eigen::Vector3f> reference_normal;
  const std::vector<Vec3> reference_world = sample(reference, reference_normal);
  parallel_for(count, options.threads, [&](int i) {
    const auto index = static_cast<size_t>(i);
    std::vector<Eigen::Vector3f> normal;
    const std::vector<Vec3> world = index == reference ? reference_world : sample(index, normal);
    if (index == reference) normal = reference_normal;
    // The head pose: the rigid motion taking the reference's registered surface onto this frame's,
    // fitted over every node (weighted by area). The reference's frame is the face frame.
    SelectionFrame& s = selection.outline(index);
    s.pose = index == reference ? RigidPose{} : fit_rigid_pose(reference_world, world, node_weights);
    const RigidPose to_face = s.pose.inverse();
    std::vector<Eigen::Vector3f> local(nodes);
    for (size_t v = 0; v < nodes; ++v) local[v] = to_face.apply(world[v]).cast<float>();
    // The reference's local vectors stay in its outline too: pose_centre reads them after the
    // samples are released.
    if (index == reference) s.local = local;
    selection.put(index, std::move(local), std::move(normal));
  });
  encoder.report().peak_selection_samples_in_memory = 0;
  encoder.report().seconds_selection = seconds_since(start);
}

KeyframeSelection select_keyframes(const PlanSettings& settings, const SelectionSamples& selection) {
  SelectionOptions options = settings.selection;
  options.pose_centre = selection.centre(settings.reference_frame);
  options.threads = settings.threads;
  return select_keyframes(selection.samples(), selection.weights(), options);
}

}  // namespace facemorph
