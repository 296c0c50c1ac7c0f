// The operators on the shared disk grid G that encoder and decoder share (spec/method.md §5.1):
// the P1 finite-element Laplacian Δ_h S = −M⁻¹ K S (on G's Cartesian interior exactly the 5-point
// stencil), the conformal factor, and the frames the reconstruction iterates on.
#pragma once

#include "facemorph/disk_grid.hpp"
#include "facemorph/geometry.hpp"
#include "facemorph/mesh.hpp"

#include <Eigen/Core>
#include <Eigen/Sparse>

#include <array>
#include <vector>

namespace facemorph {

// The operators on G that encoder and decoder share.
class GridGeometry {
 public:
  explicit GridGeometry(DiskGrid grid);

  const DiskGrid& grid() const { return grid_; }
  int interior_count() const { return grid_.interior_count; }
  // The rim band: interior nodes with |w| > 1 - 2h; hl+t stores their Laplacian in boundary frames.
  const std::vector<int32_t>& band_nodes() const { return band_nodes_; }
  int band_count() const { return static_cast<int>(band_nodes_.size()); }

  // Δ_h S = -M⁻¹ K S at the interior nodes (S given at every node of G).
  std::vector<Vec3> laplacian(const std::vector<Vec3>& positions) const;
  // λ² per interior node: surface area over disk area of the faces around it.
  std::vector<double> conformal_factor_squared(const std::vector<Vec3>& positions) const;
  // Orthonormal frame (t_u, t_v, n) per interior node: n = S_u × S_v / |S_u × S_v|, t_u along S_u,
  // t_v = n × t_u. Central differences where the four neighbours are interior nodes (every node
  // outside the rim band), else the area-weighted Jacobian of the surrounding faces.
  void frames(const std::vector<Vec3>& positions, std::vector<Vec3>& tu, std::vector<Vec3>& tv, std::vector<Vec3>& n) const;

  // Orthonormal frame for each of `nodes` from the boundary curve alone (`rim`: positions at the
  // rim nodes): the rim's tangent at the node's angle, the direction towards the rim's centroid
  // orthogonal to it, and their cross product. It rotates with the boundary and, the boundary
  // being data, does not change while the decoder iterates.
  std::vector<std::array<Vec3, 3>> boundary_frames(const std::vector<Vec3>& rim, const std::vector<int32_t>& nodes) const;

  const SparseMatrix& stiffness() const { return K_; }        // over all nodes, SPD on the interior block
  const Eigen::VectorXd& mass() const { return mass_; }       // lumped, per node

 private:
  DiskGrid grid_;
  SparseMatrix K_;
  Eigen::VectorXd mass_;
  std::vector<int32_t> band_nodes_;
  std::vector<std::array<int32_t, 4>> neighbours_;  // interior node: E, W, N, S interior indices or -1
  std::vector<std::vector<int32_t>> faces_of_;      // faces around each node
  // Interior nodes without four interior neighbours: S_u = Σ cu S[node], S_v = Σ cv S[node] over
  // stencil_[stencil_start_[v] .. stencil_start_[v + 1]) (empty for the others).
  struct StencilEntry {
    int32_t node;
    double cu, cv;
  };
  std::vector<int32_t> stencil_start_;
  std::vector<StencilEntry> stencil_;
  void build_jacobian_stencils();
};

}  // namespace facemorph
