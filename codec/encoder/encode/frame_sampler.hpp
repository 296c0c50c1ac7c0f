// Where every stage after registration reads a frame: its registered surface at disk points of G
// (or of the selection grid), and its own colour on the disk texture. Over the map stage's and the
// register stage's state units only, so that a stage samples frames without the whole encoder.
#pragma once

#include "codec/core/image/image.hpp"
#include "codec/encoder/encode/frame_maps.hpp"
#include "codec/encoder/encode/frame_registrations.hpp"

#include <memory>
#include <span>
#include <vector>

namespace facemorph {

// Where frame i is sampled for disk points of G (or of the disk texture): the reference's
// reparametrisation, then the frame's registration. Holds the registration it read back.
class RegistrationSampler {
 public:
  RegistrationSampler(const DiskReparametrisation& reparametrisation, std::shared_ptr<const DiskRegistration> registration)
      : reparametrisation_(reparametrisation), registration_(std::move(registration)) {}
  Vec2 operator()(const Vec2& node) const { return (*registration_)(reparametrisation_(node)); }
  // Every node in place, the registration's kernels vectorised over them (a DiskWarp).
  void operator()(std::span<Vec2> nodes) const {
    for (Vec2& w : nodes) w = reparametrisation_(w);
    registration_->map_points(nodes, nullptr);
  }

 private:
  const DiskReparametrisation& reparametrisation_;
  std::shared_ptr<const DiskRegistration> registration_;
};

// Samples the frames of `maps` through `registrations` (after register_frames); holds references to both.
class FrameSampler {
 public:
  FrameSampler(const FrameMaps& maps, const FrameRegistrations& registrations) : maps_(maps), registrations_(registrations) {}
  RegistrationSampler sampler(int i) const {
    return RegistrationSampler(registrations_.reparametrisation(), registrations_.registration(i));
  }
  // Frame i's surface at the disk points `nodes` (capture frame): what G, the selection grid and the
  // fit sample; the second from frame i's map as the caller loaded it (once, for several uses).
  // `threads`: as FrameRegistrations::sample_points's.
  std::vector<Vec3> sample_surface(int i, std::span<const Vec2> nodes) const;
  std::vector<Vec3> sample_surface(const MappedFrame& frame, int i, std::span<const Vec2> nodes, int threads = 1) const;
  // Frame i's own colour on the size x size disk texture, sampled through its registration as a
  // keyframe's is: the image resampled, or the vertex colours painted. What texture PSNR is
  // measured against. Throws kMissingTexture when the frame has no colour. The second from frame
  // i's map as the caller loaded it.
  Image frame_texture(int i, int size) const;
  Image frame_texture(const MappedFrame& frame, int i, int size) const;

 private:
  const FrameMaps& maps_;
  const FrameRegistrations& registrations_;
};

}  // namespace facemorph
