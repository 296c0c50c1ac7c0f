// Resampling a mapped frame onto the shared disk grid (spec/method.md §4): positions at the nodes
// of G, texture on an M x M image of the disk's bounding square.
#pragma once

#include "facemorph/encoder/conformal.hpp"
#include "facemorph/disk_grid.hpp"
#include "facemorph/image.hpp"

#include <functional>
#include <span>
#include <vector>

namespace facemorph {

// The surface point at every node of `grid`. Throws kNumerical if a node cannot be located.
std::vector<Vec3> resample_positions(const InverseDiskMap& inverse, const DiskGrid& grid);
// The surface point at each disk point (points beyond the circle are taken on it, radially).
// Throws kNumerical if a point cannot be located.
std::vector<Vec3> resample_positions(const InverseDiskMap& inverse, std::span<const Vec2> points);

// A map of the disk onto itself: where a point of the reference disk lies on a frame's disk.
using DiskWarp = std::function<Vec2(const Vec2&)>;

// The frame's texture as seen on the disk: texel (x, y) of the size x size result covers the
// disk point w = (2 (x + 0.5) / size - 1, 1 - 2 (y + 0.5) / size) (row 0 at the top, so the image
// is addressed by UV = (w + 1) / 2 like every facemorph output). Texels outside the disk repeat
// the rim value on their ray, so bilinear lookups at the rim stay clean. Needs surface UVs.
Image resample_texture(const DiskMap& map, const InverseDiskMap& inverse, const Image& texture, int size);
// The same, registered: texel x of the result shows the frame's texture at warp(x) (the disk point
// of the frame that corresponds to the reference disk's x). The warp is evaluated on every 4th
// texel and interpolated bilinearly in between (it is smooth: measured below 1e-5 disk units off).
Image resample_texture(const InverseDiskMap& inverse, const Image& texture, int size, const DiskWarp& warp);

}  // namespace facemorph
