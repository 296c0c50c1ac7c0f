// The linear disk map: intrinsic Delaunay weights, the rim at arc-length angles, one SPD solve.
#include "codec/conformal/linear_map.hpp"

#include "facemorph/error.hpp"

#include "codec/conformal/double_cover.hpp"
#include "codec/conformal/spd_solver.hpp"

#include <cmath>
#include <numbers>

namespace facemorph {

IntrinsicMesh intrinsic_delaunay(const TriangleMesh& mesh) {
  IntrinsicMesh out{mesh.faces, face_edge_lengths(mesh), 0};
  out.flips = flip_to_intrinsic_delaunay(out.faces, out.lengths);
  return out;
}

std::vector<Vec2> linear_disk_map(const TriangleMesh& mesh, const IntrinsicMesh& intrinsic, const std::vector<int>& rim) {
  const int n = mesh.vertex_count();
  const SparseMatrix K = laplacian_from_cotangents(intrinsic.faces, corner_cotangents_from_lengths(intrinsic.lengths), n);
  std::vector<Vec2> w(static_cast<size_t>(n), Vec2::Zero());
  std::vector<int> unknown(static_cast<size_t>(n), 0);
  double perimeter = 0;
  std::vector<double> arc = {0.0};
  for (size_t i = 0; i < rim.size(); ++i) {
    perimeter += (mesh.positions[static_cast<size_t>(rim[i])] - mesh.positions[static_cast<size_t>(rim[(i + 1) % rim.size()])]).norm();
    arc.push_back(perimeter);
  }
  std::vector<uint8_t> fixed(static_cast<size_t>(n), 0);
  for (size_t i = 0; i < rim.size(); ++i) {
    const double theta = 2 * std::numbers::pi * arc[i] / perimeter;
    w[static_cast<size_t>(rim[i])] = Vec2(std::cos(theta), std::sin(theta));
    fixed[static_cast<size_t>(rim[i])] = 1;
  }
  int m = 0;
  for (int v = 0; v < n; ++v) unknown[static_cast<size_t>(v)] = fixed[static_cast<size_t>(v)] ? -1 : m++;
  std::vector<Eigen::Triplet<double>> triplets;
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(m, 2);
  for (int k = 0; k < K.outerSize(); ++k) {
    for (SparseMatrix::InnerIterator it(K, k); it; ++it) {
      const int i = static_cast<int>(it.row()), j = static_cast<int>(it.col());
      if (unknown[static_cast<size_t>(i)] < 0) continue;
      if (unknown[static_cast<size_t>(j)] >= 0) {
        triplets.emplace_back(unknown[static_cast<size_t>(i)], unknown[static_cast<size_t>(j)], it.value());
      } else {
        rhs.row(unknown[static_cast<size_t>(i)]) -= it.value() * w[static_cast<size_t>(j)].transpose();
      }
    }
  }
  if (m > 0) {
    SparseMatrix A(m, m);
    A.setFromTriplets(triplets.begin(), triplets.end());
    SpdSolver solver;
    solver.analyze(A);
    if (!solver.factorize(A)) throw Error(ErrorCode::kNumerical, "linear disk map: the Laplacian could not be factored");
    const Eigen::MatrixXd x = solver.solve(rhs);
    if (!x.allFinite()) throw Error(ErrorCode::kNumerical, "linear disk map: non-finite solution");
    for (int v = 0; v < n; ++v) {
      if (unknown[static_cast<size_t>(v)] >= 0) w[static_cast<size_t>(v)] = x.row(unknown[static_cast<size_t>(v)]).transpose();
    }
  }
  return w;
}

}  // namespace facemorph
