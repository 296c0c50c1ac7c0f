// The operators on the shared disk grid G that encoder and decoder share (spec/method.md §5.1):
// the P1 finite-element Laplacian Δ_h S = −M⁻¹ K S (on G's Cartesian interior exactly the 5-point
// stencil), the conformal factor, and the frames the reconstruction iterates on.
#pragma once

#include "codec/core/geometry/differential.hpp"
#include "codec/core/geometry/mesh.hpp"
#include "codec/core/grid/disk_grid.hpp"

#include <Eigen/Core>
#include <Eigen/Sparse>

#include <array>
#include <cmath>
#include <memory>
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
  // The frame of interior node v alone, as frames() computes it: for a caller that uses it at once
  // (the decoder's iteration, which then never stores three arrays it reads once).
  [[gnu::always_inline]] inline void frame(size_t v, const Vec3* positions, Vec3& tu, Vec3& tv, Vec3& n) const;

  // Orthonormal frame for each of `nodes` from the boundary curve alone (`rim`: positions at the
  // rim nodes): the rim's tangent at the node's angle, the direction towards the rim's centroid
  // orthogonal to it, and their cross product. It rotates with the boundary and, the boundary
  // being data, does not change while the decoder iterates.
  std::vector<std::array<Vec3, 3>> boundary_frames(const std::vector<Vec3>& rim, const std::vector<int32_t>& nodes) const;

  const SparseMatrix& stiffness() const { return K_; }   // over all nodes, SPD on the interior block
  const Eigen::VectorXd& mass() const { return mass_; }  // lumped, per node

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

// G's geometry at N (make_disk_grid(n)), the one still held somewhere for that N if there is one,
// else made anew. A GridGeometry is a function of N alone and never changes once made, so a shared
// one reads to the bit as a new one would; the encoder's candidates at one N (the choice by bytes,
// spec/method.md §7.14: the field precision's reconstructors, the held-out decoders, the fields of
// another representation) each made their own, 3.7% of ict24's encode. Only weak references are
// kept: nothing outlives its last holder. Thread-safe.
std::shared_ptr<const GridGeometry> shared_grid_geometry(int n);

[[gnu::always_inline]] inline void GridGeometry::frame(size_t v, const Vec3* S, Vec3& tu, Vec3& tv, Vec3& n) const {
  Vec3 su, sv;
  if (stencil_start_[v] == stencil_start_[v + 1]) {
    const auto& nb = neighbours_[v];
    const double inv2h = 0.5 / grid_.h;
    su = (S[nb[0]] - S[nb[1]]) * inv2h;
    sv = (S[nb[2]] - S[nb[3]]) * inv2h;
  } else {
    // Near the rim: the disk-area-weighted Jacobian of the faces around the node.
    su = sv = Vec3::Zero();
    for (int32_t k = stencil_start_[v]; k < stencil_start_[v + 1]; ++k) {
      const StencilEntry& e = stencil_[static_cast<size_t>(k)];
      const Vec3& p = S[e.node];
      su += e.cu * p;
      sv += e.cv * p;
    }
  }
  // n ⟂ S_u by construction, so t_u is S_u's direction with no projection. The two square roots
  // are independent and nothing branches on them: their latency was most of this function's time.
  const Vec3 c = su.cross(sv);
  const double c2 = c.squaredNorm(), su2 = su.squaredNorm();
  if (c2 > 0 && su2 > 0) {  // (|S_u|² may underflow where |S_u × S_v|² does not)
    const double inverse_c = 1 / std::sqrt(c2), inverse_u = 1 / std::sqrt(su2);
    n = c * inverse_c;
    tu = su * inverse_u;
    tv = n.cross(tu);
    return;
  }
  // Degenerate (S_u ∥ S_v, or vanishing): n = +z, t_u along S_u's part orthogonal to it.
  n = Vec3::UnitZ();
  const Vec3 along(su.x(), su.y(), 0.0);
  const double ul = along.norm();
  tu = ul > 0 ? Vec3(along * (1 / ul)) : Vec3(n.unitOrthogonal());
  tv = n.cross(tu);
}

}  // namespace facemorph
