// The spherical conformal map of the double cover by the quasi-implicit Euler method (QIEM).
#pragma once

#include "codec/core/geometry/differential.hpp"
#include "codec/encoder/conformal/conformal.hpp"

#include "codec/encoder/conformal/double_cover.hpp"

#include <Eigen/Core>

#include <vector>

namespace facemorph {

// The converged spherical map and what it took.
struct FlowResult {
  Eigen::MatrixXd phi;  // one unit vector per double-cover vertex
  int iterations = 0;
  int factorizations = 0;  // of the two symmetric systems together (LaggedCholesky)
  double energy = 0;
};

// Inverse stereographic projection of a disk map onto the southern hemisphere, mirrored on copy 2.
Eigen::MatrixXd initial_sphere_map(const std::vector<Vec2>& w, const DoubleCover& cover);

// QIEM on the double cover (method-notes §2.4): [I + δt (K - D)] φ⁺ = φ, projection to the sphere,
// centring by a disk Möbius map. Symmetric throughout (see SymmetricSystems in qiem.cpp). K is the
// cover's cotangent Laplacian, `areas` its vertex areas, `phi` the start (initial_sphere_map).
// Throws kNumerical when the map degenerates or no step lowers the energy, kNotConverged when the
// energy has not settled after options.max_iterations steps.
FlowResult spherical_flow(const SparseMatrix& K, const Eigen::VectorXd& areas, const DoubleCover& cover, Eigen::MatrixXd phi,
                          const ConformalOptions& options);

}  // namespace facemorph
