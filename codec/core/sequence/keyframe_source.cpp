// A sequence in memory as a KeyframeSource (codec/core/sequence/keyframe_source.hpp): its keyframes handed
// out as they are, shared with the sequence.
#include "codec/core/sequence/keyframe_source.hpp"

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/reconstruct/grid_geometry.hpp"
#include "codec/core/sequence/sequence.hpp"
#include "format/error.hpp"

#include <cmath>
#include <string>

namespace facemorph {

SequenceOutline outline_of(const Sequence& sequence) {
  SequenceOutline o;
  o.grid_n = sequence.grid_n;
  o.representation = sequence.representation;
  o.spline = sequence.spline;
  o.fps = sequence.fps;
  o.first_time = sequence.first_time;
  o.last_time = sequence.last_time;
  o.units = sequence.units;
  o.pose_centre = sequence.pose_centre;
  for (const Keyframe& key : sequence.keyframes) {
    o.times.push_back(key.time);
    o.poses.push_back(key.pose);
  }
  o.fixed_node_count = sequence.keyframes.empty() ? 0 : sequence.keyframes.front().fields.fixed_nodes.size();
  o.has_holes = sequence.has_holes();
  o.texture_size = sequence.has_texture() ? sequence.keyframes.front().texture.width : 0;
  o.residuals = sequence.residuals;
  o.patches = sequence.patches;
  return o;
}

void validate_outline(const SequenceOutline& o) {
  const auto fail = [](const std::string& what) { throw Error(ErrorCode::kInvalidArgument, "sequence: " + what); };
  if (o.times.empty()) fail("no keyframes");
  if (o.poses.size() != o.times.size()) fail("a pose for every keyframe");
  if (!(o.fps > 0) || !std::isfinite(o.fps)) fail("frame rate must be finite and positive");
  if (!std::isfinite(o.first_time) || !std::isfinite(o.last_time) || o.last_time < o.first_time)
    fail("the capture's time span is not a finite interval");
  for (size_t k = 0; k < o.times.size(); ++k) {
    if (!std::isfinite(o.times[k])) fail("keyframe " + std::to_string(k) + ": time is not finite");
    if (k > 0 && !(o.times[k] > o.times[k - 1])) fail("keyframe " + std::to_string(k) + ": time does not increase");
  }
  if (o.texture_size < 0) fail("a negative texture size");
  try {
    validate_residuals(o.times, o.residuals);
    validate_patches(o.times, o.patches);
  } catch (const Error& e) {
    fail(e.what());
  }
}

void validate_keyframe(const SequenceOutline& outline, const std::vector<int32_t>& fixed_nodes, size_t k, const Keyframe& key) {
  const auto fail = [&](const std::string& what) {
    throw Error(ErrorCode::kInvalidArgument, "sequence: keyframe " + std::to_string(k) + ": " + what);
  };
  if (!(key.time == outline.times.at(k))) fail("its time is not the outline's");
  try {
    validate_fields(key.fields);
  } catch (const Error& e) {
    fail(e.what());
  }
  if (key.fields.grid_n != outline.grid_n || key.fields.representation != outline.representation)
    fail("fields of another grid or representation");
  if (key.fields.fixed_nodes != fixed_nodes) fail("fixed-frame nodes differ from keyframe 0's");
  if (!key.pose.is_proper()) fail("the pose is not a finite proper rotation and translation");
  if (key.hole_level.empty() == outline.has_holes) {
    fail(std::string("hole levels present in some keyframes only (") +
         (outline.has_holes ? "none here, where keyframe 0 has them" : "here, where keyframe 0 has none") + ")");
  }
  if (!key.hole_level.empty()) {
    const DiskGridShape shape = disk_grid_shape(outline.grid_n);
    const auto nodes = static_cast<size_t>(shape.interior_count + shape.rim_count);
    if (key.hole_level.size() != nodes)
      fail(std::to_string(key.hole_level.size()) + " hole levels for " + std::to_string(nodes) + " nodes");
    for (double v : key.hole_level) {
      if (!std::isfinite(v)) fail("a hole level is not finite");
    }
  }
}

std::shared_ptr<const GridGeometry> KeyframeSource::grid_geometry() const {
  // A throw (no memory) leaves the flag unset: the next call tries again.
  std::call_once(grid_built_, [this] { grid_ = shared_grid_geometry(outline().grid_n); });
  return grid_;
}

namespace {

class MemorySource final : public KeyframeSource {
 public:
  explicit MemorySource(std::shared_ptr<const Sequence> sequence) : sequence_(std::move(sequence)), outline_(outline_of(*sequence_)) {}
  const SequenceOutline& outline() const override { return outline_; }
  // Aliasing pointers: they keep the whole sequence alive and copy nothing.
  std::shared_ptr<const Keyframe> keyframe(size_t k) const override { return {sequence_, &sequence_->keyframes.at(k)}; }
  std::shared_ptr<const Image> texture(size_t k) const override { return {sequence_, &sequence_->keyframes.at(k).texture}; }
  // The sequence is all in memory already; its surfaces may be too (as before sources existed).
  size_t surfaces_kept() const override { return sequence_->keyframes.size(); }
  uint64_t bytes_held() const override { return 0; }

 private:
  std::shared_ptr<const Sequence> sequence_;
  SequenceOutline outline_;
};

}  // namespace

std::shared_ptr<const KeyframeSource> memory_source(std::shared_ptr<const Sequence> sequence) {
  if (!sequence) throw Error(ErrorCode::kInvalidArgument, "sequence: null");
  validate_sequence(*sequence);
  return std::make_shared<MemorySource>(std::move(sequence));
}

}  // namespace facemorph
