// A sequence in memory as a KeyframeSource (facemorph/keyframe_source.hpp): its keyframes handed
// out as they are, shared with the sequence.
#include "facemorph/keyframe_source.hpp"

#include "facemorph/disk_grid.hpp"
#include "facemorph/error.hpp"
#include "facemorph/grid_geometry.hpp"
#include "facemorph/sequence.hpp"

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
  return o;
}

std::shared_ptr<const GridGeometry> KeyframeSource::grid_geometry() const {
  // A throw (no memory) leaves the flag unset: the next call tries again.
  std::call_once(grid_built_, [this] { grid_ = std::make_shared<const GridGeometry>(make_disk_grid(outline().grid_n)); });
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
