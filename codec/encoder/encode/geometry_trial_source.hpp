// A trial's keyframes without textures: what the encoder's trials (the field precision's steps, the
// representation's bytes, spec/method.md §5.3, §7.14) hand the file writer and the decoders to
// measure the geometry alone. A trial says how its keyframes are made (keyframe(k)); the rest is here.
#pragma once

#include "codec/core/sequence/keyframe_source.hpp"
#include "format/error.hpp"

#include <string>
#include <utility>

namespace facemorph {

class GeometryTrialSource : public KeyframeSource {
 public:
  // `outline`: the stored sequence's, its texture left out; `trial` names the trial in the error a
  // texture request raises (nothing asks for one: the outline says there is none).
  GeometryTrialSource(const SequenceOutline& outline, std::string trial) : outline_(outline), trial_(std::move(trial)) {
    outline_.texture_size = 0;
  }
  const SequenceOutline& outline() const final { return outline_; }
  std::shared_ptr<const Image> texture(size_t) const final {
    throw Error(ErrorCode::kInternal, trial_ + ": a trial of the geometry has no textures");
  }
  size_t surfaces_kept() const final { return 1; }
  uint64_t bytes_held() const final { return 0; }

 private:
  SequenceOutline outline_;
  std::string trial_;
};

}  // namespace facemorph
