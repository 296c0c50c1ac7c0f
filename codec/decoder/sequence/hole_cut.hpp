// Cutting holes (open eyes, an open mouth) back out of a decoded surface (spec/method.md §7.4).
//
// The encoder fills every hole of a captured frame so the frame is a disk, and stores per keyframe
// a level-set function on G that is negative inside the filled holes and positive outside. The
// decoder blends those functions like every other field and keeps the part of the decoded grid
// surface where the blend is positive, clipping the triangles that cross its zero level, so a mouth
// that opens between two keyframes opens smoothly.
#pragma once

#include "codec/core/geometry/mesh.hpp"
#include "codec/core/grid/disk_grid.hpp"

#include <vector>

namespace facemorph {

// The part of G's triangulation where `level` (one value per node of G, interior then rim) is
// >= 0, with the surface `positions` (one per node). Triangles that cross the zero level are
// clipped along it, with new vertices on their edges interpolated linearly (positions and the
// disk coordinates); an edge's crossing is shared by both its triangles, so the result is a
// manifold mesh whose new boundary loops follow the zero level. UVs are (w + 1) / 2 of the disk
// point, as for every decoded mesh. Throws kInvalidArgument when the sizes do not match G or a
// value is not finite.
TriangleMesh cut_holes(const DiskGrid& grid, const std::vector<Vec3>& positions, const std::vector<double>& level);

}  // namespace facemorph
