// Resampling a mapped frame onto the shared disk grid (spec/method.md §4): positions at the nodes
// of G, texture on an M x M image of the disk's bounding square.
#pragma once

#include "facemorph/encoder/conformal.hpp"
#include "facemorph/disk_grid.hpp"
#include "facemorph/image.hpp"

#include <vector>

namespace facemorph {

// The surface point at every node of `grid`. Throws kNumerical if a node cannot be located.
std::vector<Vec3> resample_positions(const InverseDiskMap& inverse, const DiskGrid& grid);

// The frame's texture as seen on the disk: texel (x, y) of the size x size result covers the
// disk point w = (2 (x + 0.5) / size - 1, 1 - 2 (y + 0.5) / size) (row 0 at the top, so the image
// is addressed by UV = (w + 1) / 2 like every facemorph output). Texels outside the disk repeat
// the rim value on their ray, so bilinear lookups at the rim stay clean. Needs surface UVs.
Image resample_texture(const DiskMap& map, const InverseDiskMap& inverse, const Image& texture, int size);

}  // namespace facemorph
