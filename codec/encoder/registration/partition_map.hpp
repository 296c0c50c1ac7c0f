// Φ, the piecewise-affine registration on the partition mesh (paper §5, method-notes §6): its tables
// and the step register_disks takes from f̄ to Φ.
#pragma once

#include "codec/encoder/registration/registration.hpp"

#include <cmath>
#include <memory>
#include <numbers>
#include <vector>

namespace facemorph {

// The polar angle of p in [0, 2π).
inline double circle_angle(const Vec2& p) {
  const double a = std::atan2(p.y(), p.x());
  return a < 0 ? a + 2 * std::numbers::pi : a;
}

// Φ's tables, shared by every copy of a DiskRegistration: the partition, the image of every vertex
// and the constant Jacobian of every triangle.
struct PiecewiseAffineMap {
  std::shared_ptr<const PartitionMesh> partition;
  std::vector<Vec2> images;                // Φ(V) per partition vertex (frame disk)
  std::vector<Eigen::Matrix2d> jacobians;  // per partition triangle

  // Φ(w): barycentric inside the partition (notes §6, with the division by the triangle's area); in
  // the gap between a boundary chord and the circle, radially onto the gap beyond the image chord.
  // Any finite w; with `jacobian`, DΦ(w) too.
  Vec2 evaluate(const Vec2& w, Eigen::Matrix2d* jacobian) const;
};

// register_through_partition without E_D: `base` with Φ on `images` (the energy left as base's).
DiskRegistration partition_registration(const GeodesicFrame& frame, const DiskRegistration& base, std::vector<Vec2> images,
                                        bool allow_fallback);

}  // namespace facemorph
