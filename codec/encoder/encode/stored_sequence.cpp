#include "codec/encoder/encode/stored_sequence.hpp"

#include "format/error.hpp"

namespace facemorph {

StoredSequence::StoredSequence(Sequence shape, SpillMode mode)
    : shape_(std::move(shape)), fields_(mode, count_), holes_(mode, count_), textures_(mode, count_) {
  for (Keyframe& key : shape_.keyframes) {
    key.fields = {};
    key.hole_level = {};
    key.texture = {};
  }
  fields_.reset(size());
  holes_.reset(size());
  textures_.reset(size());
  outline_ = outline_of(shape_);  // its array sizes follow keyframe 0's puts
}

std::unique_ptr<StoredSequence> StoredSequence::of(Sequence&& sequence, SpillMode mode) {
  validate_sequence(sequence);
  std::vector<Keyframe> keyframes = std::move(sequence.keyframes);
  sequence.keyframes.clear();
  Sequence shape = std::move(sequence);
  for (const Keyframe& key : keyframes) {
    Keyframe& outline = shape.keyframes.emplace_back();
    outline.time = key.time;
    outline.pose = key.pose;
  }
  auto stored = std::make_unique<StoredSequence>(std::move(shape), mode);
  for (size_t k = 0; k < keyframes.size(); ++k) {
    stored->put_fields(k, std::move(keyframes[k].fields));
    stored->put_hole_level(k, std::move(keyframes[k].hole_level));
    stored->put_texture(k, std::move(keyframes[k].texture));
    keyframes[k] = {};  // released as it goes
  }
  return stored;
}

Sequence StoredSequence::to_sequence() const {
  Sequence sequence = shape_;
  for (size_t k = 0; k < size(); ++k) {
    Keyframe& key = sequence.keyframes[k];
    key.fields = *fields_.get(k);
    key.hole_level = *holes_.get(k);
    key.texture = *textures_.get(k);
  }
  validate_sequence(sequence);
  return sequence;
}

void StoredSequence::put_fields(size_t k, GridFields&& fields) {
  if (k == 0) outline_.fixed_node_count = fields.fixed_nodes.size();
  fields_.put(k, std::move(fields));
}

void StoredSequence::put_hole_level(size_t k, std::vector<double>&& level) {
  if (k == 0) outline_.has_holes = !level.empty();
  holes_.put(k, std::move(level));
}

void StoredSequence::put_texture(size_t k, Image&& texture) {
  if (k == 0) outline_.texture_size = texture.empty() ? 0 : texture.width;
  textures_.put(k, std::move(texture));
}

void StoredSequence::set_pose(size_t k, const RigidPose& pose) {
  if (k >= size()) throw Error(ErrorCode::kInternal, "stored sequence: keyframe " + std::to_string(k) + " is past its size");
  shape_.keyframes[k].pose = pose;
  outline_.poses[k] = pose;
}

void StoredSequence::set_patches(std::vector<FramePatch> patches) {
  validate_patches(outline_.times, patches);
  shape_.patches = patches;
  outline_.patches = std::move(patches);
}

void StoredSequence::set_residuals(std::vector<ResidualFrame> residuals) {
  validate_residuals(outline_.times, residuals);
  shape_.residuals = residuals;
  outline_.residuals = std::move(residuals);
}

std::shared_ptr<const Keyframe> StoredSequence::keyframe(size_t k) const {
  auto key = std::make_shared<Keyframe>();
  key->time = shape_.keyframes.at(k).time;
  key->pose = shape_.keyframes[k].pose;
  key->fields = *fields_.get(k);
  key->hole_level = *holes_.get(k);
  return key;
}

}  // namespace facemorph
