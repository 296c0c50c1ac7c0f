// The shared disk grid G: the one mesh of the unit disk every keyframe is stored on and every
// decoded frame is reconstructed on. Its nodes and faces are defined exactly, by integer
// arithmetic, in spec/method.md §4 (rule version kDiskGridRule), so that a file decodes to the
// same surface on every platform; `hash` identifies the result and the container records it.
//
//   * interior nodes: the grid points (i, j), w = ((2i − M)/M, (2j − M)/M) with M = N − 1, at
//     least half a cell inside the circle: (2i − M)² + (2j − M)² <= (M − 1)²;
//   * rim nodes: B = round(π M) points on the unit circle at angles 2π k / B (spacing ≈ h),
//     rounded to the lattice of spacing 1 / (Q M), Q = floor(2^30 / M);
//   * faces: every grid square with four interior corners split along its diagonal from (i, j) to
//     (i + 1, j + 1); the band between those squares and the rim by the Delaunay triangulation of
//     the nodes with exact predicates, ties broken by a fixed symbolic perturbation. The whole is
//     the Delaunay triangulation of all nodes under that perturbation.
#pragma once

#include "codec/core/geometry/mesh.hpp"

#include <cstdint>
#include <vector>

namespace facemorph {

// The version of the rule that builds G; a container records it with the grid's hash.
inline constexpr int kDiskGridRule = 1;

struct DiskGrid {
  int n = 0;                                 // N: grid points per side of [-1, 1]²
  double h = 0;                              // grid spacing, 2 / (N - 1)
  std::vector<Vec2> nodes;                   // interior nodes (row by row, j then i), then rim nodes
  std::vector<std::array<int32_t, 2>> cell;  // (i, j) of each interior node
  std::vector<int32_t> node_at;              // N*N: node index of grid point (i, j) (j * N + i), or -1
  int interior_count = 0;
  int rim_count = 0;
  std::vector<Face> faces;  // counter-clockwise, in the canonical order of spec/method.md §4
  // FNV-1a 64 of the nodes' lattice coordinates and the faces (spec/method.md §4): equal hashes,
  // equal grids.
  uint64_t hash = 0;

  int node_count() const { return static_cast<int>(nodes.size()); }
  bool is_rim(int node) const { return node >= interior_count; }
  // Node index of grid point (i, j), or -1 where (i, j) is off the square or outside the disk.
  int32_t node(int i, int j) const {
    return (i < 0 || j < 0 || i >= n || j >= n) ? -1 : node_at[static_cast<size_t>(j) * static_cast<size_t>(n) + static_cast<size_t>(i)];
  }
  double rim_angle(int k) const;  // nominal angle 2π k / B of rim node k (node interior_count + k)
};

inline constexpr int kMinGridSize = 5;
inline constexpr int kMaxGridSize = 4097;

// Builds G. Throws kInvalidArgument unless kMinGridSize <= N <= kMaxGridSize.
DiskGrid make_disk_grid(int n);

// G's hash for N up to kKnownGridHashes without building G (a table, checked against
// make_disk_grid by the tests): checking a file's header costs no grid. 0 for other N.
inline constexpr int kKnownGridHashes = 1025;
uint64_t known_disk_grid_hash(int n);

// The node counts of G for N without building it (cheap): what validating fields needs.
struct DiskGridShape {
  int interior_count = 0;
  int rim_count = 0;
};
DiskGridShape disk_grid_shape(int n);

}  // namespace facemorph
