// A frame's registered surface and colour, read through the map and register stages' state units.
#include "codec/encoder/encode/frame_sampler.hpp"

#include "codec/encoder/conformal/resample.hpp"
#include "format/error.hpp"

#include <optional>

namespace facemorph {

std::vector<Vec3> FrameSampler::sample_surface(int i, std::span<const Vec2> nodes) const {
  return sample_surface(*maps_.frame(i), i, nodes);
}

std::vector<Vec3> FrameSampler::sample_surface(const MappedFrame& frame, int i, std::span<const Vec2> nodes, int threads) const {
  return resample_positions(InverseDiskMap(frame.map), registrations_.sample_points(i, nodes, threads));
}

Image FrameSampler::frame_texture(int i, int size) const { return frame_texture(*maps_.frame(i), i, size); }

Image FrameSampler::frame_texture(const MappedFrame& f, int i, int size) const {
  Image image;
  const std::optional<TextureSource> source = frame_texture_source(f.map, maps_.textures[static_cast<size_t>(i)], image);
  if (!source) throw Error(ErrorCode::kMissingTexture, f.name + ": the frame has neither a texture image with UVs nor vertex colours");
  return resample_texture(InverseDiskMap(f.map), *source, size, sampler(i));
}

}  // namespace facemorph
