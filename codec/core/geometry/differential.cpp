#include "codec/core/geometry/differential.hpp"

#include "format/error.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace facemorph {
namespace {

const Vec3& at(std::span<const Vec3> positions, int32_t i) { return positions[static_cast<size_t>(i)]; }

}  // namespace

double cotangent(const Vec3& a, const Vec3& b) {
  const double cross = a.cross(b).norm();
  const double floor = 1e-12 * a.norm() * b.norm();
  const double denominator = std::max(cross, floor);
  return denominator > 0 ? a.dot(b) / denominator : 0.0;
}

std::vector<CornerValues> corner_cotangents(std::span<const Vec3> positions, std::span<const Face> faces) {
  std::vector<CornerValues> cot(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Vec3& p = at(positions, faces[f][k]);
      cot[f][k] = cotangent(at(positions, faces[f][(k + 1) % 3]) - p, at(positions, faces[f][(k + 2) % 3]) - p);
    }
  }
  return cot;
}

SparseMatrix laplacian_from_cotangents(std::span<const Face> faces, std::span<const CornerValues> cotangents, int vertex_count) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(faces.size() * 12);
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int i = faces[f][(k + 1) % 3];
      const int j = faces[f][(k + 2) % 3];
      const double w = 0.5 * cotangents[f][k];
      triplets.emplace_back(i, j, -w);
      triplets.emplace_back(j, i, -w);
      triplets.emplace_back(i, i, w);
      triplets.emplace_back(j, j, w);
    }
  }
  SparseMatrix K(vertex_count, vertex_count);
  K.setFromTriplets(triplets.begin(), triplets.end());
  return K;
}

SparseMatrix cotangent_laplacian(std::span<const Vec3> positions, std::span<const Face> faces) {
  return laplacian_from_cotangents(faces, corner_cotangents(positions, faces), static_cast<int>(positions.size()));
}

double triangle_area(const Vec3& a, const Vec3& b, const Vec3& c) { return 0.5 * (b - a).cross(c - a).norm(); }

Eigen::VectorXd mixed_voronoi_areas(std::span<const Vec3> positions, std::span<const Face> faces) {
  Eigen::VectorXd area = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(positions.size()));
  for (const Face& f : faces) {
    const Vec3 p[3] = {at(positions, f[0]), at(positions, f[1]), at(positions, f[2])};
    const double face_area = triangle_area(p[0], p[1], p[2]);
    int obtuse = -1;
    for (int k = 0; k < 3; ++k) {
      if ((p[(k + 1) % 3] - p[k]).dot(p[(k + 2) % 3] - p[k]) < 0) obtuse = k;
    }
    for (int k = 0; k < 3; ++k) {
      double share;
      if (obtuse < 0) {
        // Voronoi region: (|x_i - x_j|² cot(angle opposite ij)) / 8 over the two edges at corner k.
        const Vec3& pi = p[k];
        const Vec3& pj = p[(k + 1) % 3];
        const Vec3& pl = p[(k + 2) % 3];
        const double cot_l = cotangent(pi - pl, pj - pl);  // angle at l, opposite edge ij
        const double cot_j = cotangent(pi - pj, pl - pj);  // angle at j, opposite edge il
        share = ((pi - pj).squaredNorm() * cot_l + (pi - pl).squaredNorm() * cot_j) / 8.0;
      } else {
        share = obtuse == k ? face_area / 2.0 : face_area / 4.0;
      }
      area[f[static_cast<size_t>(k)]] += share;
    }
  }
  return area;
}

void area_weighted_normals(std::span<const Vec3> positions, std::span<const Face> faces, std::span<float> out) {
  if (out.size() != 3 * positions.size()) {
    throw Error(ErrorCode::kInvalidArgument,
                "normals: " + std::to_string(out.size()) + " floats for " + std::to_string(positions.size()) + " vertices");
  }
  std::vector<Vec3> sum(positions.size(), Vec3::Zero());
  const auto count = static_cast<int64_t>(positions.size());
  for (const Face& f : faces) {
    for (int32_t v : f) {
      if (v < 0 || v >= count) throw Error(ErrorCode::kInvalidArgument, "normals: face index " + std::to_string(v) + " out of range");
    }
    const Vec3& a = positions[static_cast<size_t>(f[0])];
    // |(b − a) × (c − a)| is twice the triangle's area: the sum weights each face by its area.
    const Vec3 n = (positions[static_cast<size_t>(f[1])] - a).cross(positions[static_cast<size_t>(f[2])] - a);
    for (int32_t v : f) sum[static_cast<size_t>(v)] += n;
  }
  for (size_t v = 0; v < sum.size(); ++v) {
    const double length = sum[v].norm();
    const Vec3 n = length > 0 && std::isfinite(length) ? Vec3(sum[v] / length) : Vec3::Zero();
    for (int k = 0; k < 3; ++k) out[3 * v + static_cast<size_t>(k)] = static_cast<float>(n[k]);
  }
}

}  // namespace facemorph
