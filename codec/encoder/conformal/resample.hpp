// Resampling a mapped frame onto the shared disk grid (spec/method.md §4): positions at the nodes
// of G, texture on an M x M image of the disk's bounding square.
#pragma once

#include "codec/core/grid/disk_grid.hpp"
#include "codec/core/image/image.hpp"
#include "codec/encoder/conformal/conformal.hpp"

#include <array>
#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <vector>

namespace facemorph {

// The surface point at every node of `grid`. Throws kNumerical if a node cannot be located.
std::vector<Vec3> resample_positions(const InverseDiskMap& inverse, const DiskGrid& grid);
// The surface point at each disk point (points beyond the circle are taken on it, radially).
// Throws kNumerical if a point cannot be located.
std::vector<Vec3> resample_positions(const InverseDiskMap& inverse, std::span<const Vec2> points);

// Where a frame's colour comes from: its texture image sampled at the surface point's UV, or its
// vertex colours interpolated barycentrically across the surface triangle (a capture without an
// image, spec/capture.md). Both give 8-bit sRGB-coded values, as the image holds them.
class TextureSource {
 public:
  // The image is kept by reference: it must outlive the source. Needs surface UVs.
  static TextureSource image(const Image& texture) { return TextureSource(&texture); }
  // Needs surface colours (TriangleMesh::colours).
  static TextureSource vertex_colours() { return TextureSource(nullptr); }
  // Of `map`'s surface (kMissingTexture naming what it lacks otherwise).
  void check(const DiskMap& map) const;
  // The colour at surface point `p`, per channel in [0, 255].
  std::array<double, 3> sample(const InverseDiskMap& inverse, const SurfacePoint& p) const;

 private:
  explicit TextureSource(const Image* image) : image_(image) {}
  const Image* image_;
};

// The texture source a mapped frame offers: its image when it has one and UVs (read into `image`,
// which must outlive the result), else its vertex colours; nullopt when it has neither.
std::optional<TextureSource> frame_texture_source(const DiskMap& map, const std::filesystem::path& texture, Image& image);

// A map of the disk onto itself, applied to points in place: where each point of the reference
// disk lies on a frame's disk. Many points a call, so that a registration evaluates them together
// (DiskRegistration::map_points).
using DiskWarp = std::function<void(std::span<Vec2>)>;

// The frame's texture as seen on the disk: texel (x, y) of the size x size result covers the
// disk point w = (2 (x + 0.5) / size - 1, 1 - 2 (y + 0.5) / size) (row 0 at the top, so the image
// is addressed by UV = (w + 1) / 2 like every facemorph output). Texels outside the disk repeat
// the rim value on their ray, so bilinear lookups at the rim stay clean. Needs surface UVs.
Image resample_texture(const DiskMap& map, const InverseDiskMap& inverse, const Image& texture, int size);
// The same, registered: texel x of the result shows the frame's texture at warp(x) (the disk point
// of the frame that corresponds to the reference disk's x). The warp is evaluated on every 4th
// texel and interpolated bilinearly in between (it is smooth: measured below 1e-5 disk units off).
Image resample_texture(const InverseDiskMap& inverse, const Image& texture, int size, const DiskWarp& warp);
// The same from either source: a vertex-coloured frame's disk texture is its triangles painted with
// their corners' colours, sampled through the same registration as an image would be.
Image resample_texture(const InverseDiskMap& inverse, const TextureSource& source, int size, const DiskWarp& warp);

}  // namespace facemorph
