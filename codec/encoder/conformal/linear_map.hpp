// The linear disk map: harmonic, with the rim on the circle at arc length (QIEM's start and fallback).
#pragma once

#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/mesh.hpp"

#include <vector>

namespace facemorph {

// The intrinsic Delaunay triangulation of a mesh: its faces and edge lengths (the Laplacian built
// from them has non-negative weights everywhere but on boundary edges, which are never flipped).
struct IntrinsicMesh {
  std::vector<Face> faces;
  std::vector<CornerValues> lengths;
  int flips = 0;
};
IntrinsicMesh intrinsic_delaunay(const TriangleMesh& mesh);

// Harmonic map onto the disk with the rim on the unit circle at arc-length angles. With the
// intrinsic Delaunay weights (all interior weights >= 0) this is a convex-combination map.
// Throws kNumerical when the system cannot be factored or solved.
std::vector<Vec2> linear_disk_map(const TriangleMesh& mesh, const IntrinsicMesh& intrinsic, const std::vector<int>& rim);

// The last resort: Tutte's map with positive weights that ignore the geometry (one per edge), the
// rim at arc length. Needs nothing of the triangles' shapes, so it maps a disk whose preconditioning
// or intrinsic weights failed; an embedding by Tutte's theorem (Floater: any positive weights), far
// from conformal. Throws kNumerical only if the solver fails.
std::vector<Vec2> tutte_disk_map(const TriangleMesh& mesh, const std::vector<int>& rim);

}  // namespace facemorph
