// The encoder's keyframes from the step that makes them to the file writer (spec/method.md §7.15).
//
// A keyframe's arrays are its fields (~1.7 MB at N = 257), its hole level (0.5 MB) and its texture
// (3 MB at 1024²), and a long capture has hundreds of keyframes. Held as a Sequence, they made the
// encoder's memory grow with the capture's length. Here each array goes to the encoder's temporary
// file as soon as a step makes it (KeyframeStore) and is read back when a step, or the file writer,
// asks for that keyframe: memory holds every keyframe's time and pose and the few arrays in use.
#pragma once

#include "codec/core/sequence/keyframe_source.hpp"
#include "codec/core/sequence/sequence.hpp"
#include "codec/encoder/encode/keyframe_store.hpp"
#include "codec/writer/container/texture_group_cache.hpp"

#include <memory>
#include <type_traits>

namespace facemorph {

class StoredSequence final : public KeyframeSource {
 public:
  // `shape`: the sequence's grid, representation, spline, times and units, and each keyframe's
  // time and pose (any arrays it holds are dropped); the arrays are put later.
  StoredSequence(Sequence shape, SpillMode mode);
  // Every keyframe of `sequence` moved in (validate_sequence first: kInvalidArgument).
  static std::unique_ptr<StoredSequence> of(Sequence&& sequence, SpillMode mode);
  // Every keyframe read back, validated: the Sequence a caller of the in-memory API gets.
  Sequence to_sequence() const;
  // step(stored) on `sequence` moved into a store (`mode`), and the sequence moved back, as the
  // step left it, also when the step throws: the Sequence overloads of the encoder's steps.
  template <typename Step>
  static auto around(Sequence& sequence, SpillMode mode, const Step& step) {
    const std::unique_ptr<StoredSequence> stored = of(std::move(sequence), mode);
    try {
      if constexpr (std::is_void_v<decltype(step(*stored))>) {
        step(*stored);
        sequence = stored->to_sequence();
      } else {
        auto result = step(*stored);
        sequence = stored->to_sequence();
        return result;
      }
    } catch (...) {
      sequence = stored->to_sequence();
      throw;
    }
  }

  // The sequence without its arrays: every keyframe's time and pose.
  const Sequence& shape() const { return shape_; }
  size_t size() const { return shape_.keyframes.size(); }

  // Keyframe k's arrays, put from any thread (each k by one; keyframe 0's sets the outline's array
  // sizes). A put replaces what was there; a pose set is the shape's and the outline's.
  void put_fields(size_t k, GridFields&& fields);
  void put_hole_level(size_t k, std::vector<double>&& level);  // an empty one: the sequence keeps no holes
  void put_texture(size_t k, Image&& texture);                 // an empty one: none
  void set_pose(size_t k, const RigidPose& pose);
  // The residual frames (validate_residuals against the keyframes' times: kInvalidArgument), the
  // shape's and the outline's.
  void set_residuals(std::vector<ResidualFrame> residuals);
  // The texture groups a measure of this sequence's file coded (sequence_file_size's `coded`), for
  // the file's write to take (write_sequence_file's): keyed by the textures' pixels, so a texture
  // put since is coded anew.
  TextureGroupCache& coded_texture_groups() const { return *coded_texture_groups_; }
  // The frame patches (validate_patches against the keyframes' times: kInvalidArgument), the
  // shape's and the outline's.
  void set_patches(std::vector<FramePatch> patches);
  // Keyframe k's arrays as put (kInternal for one never put).
  std::shared_ptr<const GridFields> fields(size_t k) const { return fields_.get(k); }
  std::shared_ptr<const std::vector<double>> hole_level(size_t k) const { return holes_.get(k); }

  // KeyframeSource, for the steps' result (read it once every array is put): keyframe(k) holds its
  // time, pose, fields and hole level (not its texture: texture(k)).
  const SequenceOutline& outline() const override { return outline_; }
  std::shared_ptr<const Keyframe> keyframe(size_t k) const override;
  std::shared_ptr<const Image> texture(size_t k) const override { return textures_.get(k); }
  // A decoder on it may keep every keyframe's surface, as on a sequence in memory (fmenc only
  // writes from it).
  size_t surfaces_kept() const override { return size(); }
  uint64_t bytes_held() const override { return 0; }

  // The most arrays read back and in memory at once, and the bytes written to the temporary file.
  int peak_held() const { return count_->peak.load(); }
  uint64_t spilled_bytes() const { return fields_.spilled_bytes() + holes_.spilled_bytes() + textures_.spilled_bytes(); }

 private:
  Sequence shape_;
  std::shared_ptr<ResidentCount> count_ = std::make_shared<ResidentCount>();
  FieldsStore fields_;
  HoleLevelStore holes_;
  TextureStore textures_;
  SequenceOutline outline_;
  std::unique_ptr<TextureGroupCache> coded_texture_groups_ = std::make_unique<TextureGroupCache>();
};

}  // namespace facemorph
