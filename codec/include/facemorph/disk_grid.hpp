// The shared disk grid G: the one mesh of the unit disk every keyframe is stored on and every
// decoded frame is reconstructed on (spec/method.md §4).
//
//   * interior nodes: the points (-1 + i h, -1 + j h), h = 2 / (N - 1), at least h/2 inside the
//     circle (|w| <= 1 - h/2): Cartesian, so the decoder's finite-difference stencils apply;
//   * rim nodes: B points evenly spaced on the unit circle (default round(2π / h): spacing ≈ h),
//     at angles 2π k / B;
//   * faces: the Delaunay triangulation of all nodes. Keeping interior nodes h/2 off the circle is
//     what keeps slivers out of the rim band.
#pragma once

#include "facemorph/mesh.hpp"

#include <vector>

namespace facemorph {

struct DiskGrid {
  int n = 0;          // N: grid points per side of [-1, 1]²
  double h = 0;       // grid spacing
  std::vector<Vec2> nodes;                    // interior nodes first, then rim nodes
  std::vector<std::array<int32_t, 2>> cell;   // (i, j) of each interior node
  std::vector<int32_t> node_at;               // N*N: node index of grid point (i, j) (j * N + i), or -1
  int interior_count = 0;
  int rim_count = 0;
  std::vector<Face> faces;                    // counter-clockwise

  int node_count() const { return static_cast<int>(nodes.size()); }
  bool is_rim(int node) const { return node >= interior_count; }
  // Node index of grid point (i, j), or -1 where (i, j) is off the square or outside the disk.
  int32_t node(int i, int j) const {
    return (i < 0 || j < 0 || i >= n || j >= n) ? -1 : node_at[static_cast<size_t>(j) * static_cast<size_t>(n) + static_cast<size_t>(i)];
  }
  double rim_angle(int k) const;              // angle of rim node k (node interior_count + k)
};

// Builds G. Throws kInvalidArgument unless 5 <= N <= 8193 and rim_samples is 0 (automatic) or >= 8.
DiskGrid make_disk_grid(int n, int rim_samples = 0);

}  // namespace facemorph
