// The linear disk map: intrinsic Delaunay weights, the rim at arc-length angles, one SPD solve.
#include "codec/encoder/conformal/linear_map.hpp"

#include "codec/meshkit/geometry/surface_measures.hpp"
#include "format/error.hpp"

#include "codec/encoder/conformal/double_cover.hpp"
#include "codec/encoder/conformal/spd_solver.hpp"

#include <cmath>
#include <numbers>
#include <string>

namespace facemorph {

IntrinsicMesh intrinsic_delaunay(const TriangleMesh& mesh) {
  IntrinsicMesh out{mesh.faces, face_edge_lengths(mesh), 0};
  out.flips = flip_to_intrinsic_delaunay(out.faces, out.lengths);
  return out;
}

namespace {

// The map solving K's interior rows with the rim fixed on the circle at arc-length angles: a
// convex-combination map when K's off-diagonal weights are all non-positive.
std::vector<Vec2> disk_map_with_laplacian(const TriangleMesh& mesh, const SparseMatrix& K, const std::vector<int>& rim, const char* what) {
  const int n = mesh.vertex_count();
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
    if (!solver.factorize(A)) throw Error(ErrorCode::kNumerical, std::string(what) + ": the Laplacian could not be factored");
    const Eigen::MatrixXd x = solver.solve(rhs);
    if (!x.allFinite()) throw Error(ErrorCode::kNumerical, std::string(what) + ": non-finite solution");
    for (int v = 0; v < n; ++v) {
      if (unknown[static_cast<size_t>(v)] >= 0) w[static_cast<size_t>(v)] = x.row(unknown[static_cast<size_t>(v)]).transpose();
    }
  }
  return w;
}

}  // namespace

std::vector<Vec2> linear_disk_map(const TriangleMesh& mesh, const IntrinsicMesh& intrinsic, const std::vector<int>& rim) {
  const SparseMatrix K = laplacian_from_cotangents(intrinsic.faces, corner_cotangents_from_lengths(intrinsic.lengths), mesh.vertex_count());
  return disk_map_with_laplacian(mesh, K, rim, "linear disk map");
}

std::vector<Vec2> tutte_disk_map(const TriangleMesh& mesh, const std::vector<int>& rim) {
  // Half a unit per face an edge borders: 1 inside, 1/2 on the rim. Only the interior rows are
  // solved, so the rim's weights do not matter; what matters is that every weight is positive.
  const int n = mesh.vertex_count();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(12 * mesh.faces.size());
  for (const Face& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      const int32_t i = f[k], j = f[(k + 1) % 3];
      triplets.emplace_back(i, j, -0.5);
      triplets.emplace_back(j, i, -0.5);
      triplets.emplace_back(i, i, 0.5);
      triplets.emplace_back(j, j, 0.5);
    }
  }
  SparseMatrix K(n, n);
  K.setFromTriplets(triplets.begin(), triplets.end());
  return disk_map_with_laplacian(mesh, K, rim, "Tutte disk map");
}

}  // namespace facemorph
