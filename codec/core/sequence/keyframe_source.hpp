// What a decoder reads a sequence through: its outline (everything but the keyframes' fields, hole
// levels and textures) at once, and each keyframe's content when first asked for. A Sequence in
// memory hands out its own keyframes; an opened file (open_sequence_source, sequence_file.hpp)
// decodes them on demand into a cache bounded by the caller's memory budget (spec/container.md
// §10.1), so memory follows what is played, not the length of the file.
#pragma once

#include "codec/core/image/image.hpp"
#include "codec/core/limits/decoder_limits.hpp"
#include "codec/core/reconstruct/fields.hpp"
#include "codec/core/sequence/frame_patch.hpp"
#include "codec/core/sequence/pose.hpp"
#include "codec/core/sequence/residual_weights.hpp"
#include "codec/core/sequence/spline.hpp"

#include <cstddef>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace facemorph {

struct Keyframe;
struct Sequence;
class GridGeometry;

struct SequenceOutline {
  int grid_n = 0;
  Representation representation = Representation::kHLT;
  SplineKind spline = SplineKind::kCatmullRom;
  double fps = 0, first_time = 0, last_time = 0;  // as Sequence's
  std::string units = "m";
  Vec3 pose_centre = Vec3::Zero();
  std::vector<double> times;     // every keyframe's, strictly increasing
  std::vector<RigidPose> poses;  // every keyframe's
  size_t fixed_node_count = 0;   // nodes in the boundary frames (GridFields::fixed_nodes)
  bool has_holes = false;
  int texture_size = 0;                  // M; 0: no texture
  std::vector<ResidualFrame> residuals;  // as Sequence's (format 2.3)
  std::vector<FramePatch> patches;       // as Sequence's (format 2.4)
  bool has_texture() const { return texture_size > 0; }
  size_t keyframe_count() const { return times.size(); }
};

// The outline of a sequence validate_sequence accepts.
SequenceOutline outline_of(const Sequence& sequence);

// validate_sequence's checks split for keyframes met one at a time (a writer reading a source):
// of the outline, at least one keyframe, a finite positive frame rate and time span, finite
// strictly increasing times, a texture size not negative; of keyframe k, its time the outline's,
// fields valid on the outline's grid and representation with `fixed_nodes` (keyframe 0's), a
// finite proper pose, and one finite hole level per node where the outline has holes (none where it
// has none). Each throws kInvalidArgument naming the defect, and the keyframe where one is at
// fault; the texture is not checked (validate_sequence and the writer check it as each holds it).
void validate_outline(const SequenceOutline& outline);
void validate_keyframe(const SequenceOutline& outline, const std::vector<int32_t>& fixed_nodes, size_t k, const Keyframe& key);

// Thread-safe: decoders on several threads may share one source.
class KeyframeSource {
 public:
  virtual ~KeyframeSource() = default;
  virtual const SequenceOutline& outline() const = 0;
  // Keyframe k's time, pose, fields and hole level (its texture may be left empty: texture(k)).
  // An opened file throws kCorrupt (or kLimit) where keyframe k's chunk is, naming it.
  virtual std::shared_ptr<const Keyframe> keyframe(size_t k) const = 0;
  // Keyframe k's texture, M × M RGB (outline().has_texture()).
  virtual std::shared_ptr<const Image> texture(size_t k) const = 0;
  // The same, charging what is decoded to `work` (a decode call's meter; spec/container.md §10.3):
  // kLimit where it would pass the call's limit, after which the next call goes on. A sequence in
  // memory decodes nothing and charges nothing.
  virtual std::shared_ptr<const Keyframe> keyframe(size_t k, WorkMeter&) const { return keyframe(k); }
  virtual std::shared_ptr<const Image> texture(size_t k, WorkMeter&) const { return texture(k); }
  // What one decode call on this source may do (DecoderLimits::max_work of an opened file; 0, no
  // bound, for a sequence in memory), and what errors name it by.
  virtual uint64_t work_limit() const { return 0; }
  virtual std::string name() const { return "sequence"; }
  // The keyframe whose stored texture keyframe k shows: k, or in a file of shared textures (format
  // 2.2) the first keyframe naming the same TEXR chunk (texture(k) is that keyframe's image).
  virtual size_t texture_owner(size_t k) const { return k; }
  // How many keyframes' reconstructed surfaces one decoder on this source may keep: its share of
  // the memory budget (every keyframe for a sequence in memory).
  virtual size_t surfaces_kept() const = 0;
  // What the source's cache of decoded keyframes and textures holds now, in bytes as §10.1 counts
  // them (0 for a sequence in memory: it shares the sequence and decodes nothing).
  virtual uint64_t bytes_held() const = 0;
  // G for the outline's N and its geometry, built on the first call and shared by every decoder on
  // this source (immutable; one per source, so opening a file builds at most one G).
  std::shared_ptr<const GridGeometry> grid_geometry() const;

 private:
  mutable std::once_flag grid_built_;
  mutable std::shared_ptr<const GridGeometry> grid_;
};

// A source over a sequence in memory, which it shares. Validates the sequence (kInvalidArgument).
std::shared_ptr<const KeyframeSource> memory_source(std::shared_ptr<const Sequence> sequence);

}  // namespace facemorph
