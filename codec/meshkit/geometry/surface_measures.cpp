#include "codec/meshkit/geometry/surface_measures.hpp"

#include <algorithm>
#include <cmath>
#include "codec/core/geometry/elementary.hpp"

namespace facemorph {
namespace {

const Vec3& at(std::span<const Vec3> positions, int32_t i) { return positions[static_cast<size_t>(i)]; }

}  // namespace

std::vector<CornerValues> corner_angles(std::span<const Vec3> positions, std::span<const Face> faces) {
  std::vector<CornerValues> angles(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const Vec3& p = at(positions, faces[f][k]);
      const Vec3 a = at(positions, faces[f][(k + 1) % 3]) - p;
      const Vec3 b = at(positions, faces[f][(k + 2) % 3]) - p;
      angles[f][k] = angle_between(a, b);
    }
  }
  return angles;
}

std::vector<CornerValues> corner_cotangents_from_lengths(std::span<const CornerValues> lengths) {
  std::vector<CornerValues> cot(lengths.size());
  for (size_t f = 0; f < lengths.size(); ++f) {
    const double a = lengths[f][0], b = lengths[f][1], c = lengths[f][2];
    // Heron's formula in the numerically stable ordering (Kahan).
    std::array<double, 3> s = {a, b, c};
    std::sort(s.begin(), s.end(), std::greater<>());
    const double product = (s[0] + (s[1] + s[2])) * (s[2] - (s[0] - s[1])) * (s[2] + (s[0] - s[1])) * (s[0] + (s[1] - s[2]));
    const double area = 0.25 * std::sqrt(std::max(product, 0.0));
    const double floor = 1e-12 * std::max({a * b, b * c, c * a});
    const double twice_area2 = 4.0 * std::max(area, 0.5 * floor);  // cot = (b²+c²-a²)/(4 area)
    for (int k = 0; k < 3; ++k) {
      const double opposite = lengths[f][k];
      const double left = lengths[f][(k + 1) % 3];
      const double right = lengths[f][(k + 2) % 3];
      cot[f][k] = (left * left + right * right - opposite * opposite) / twice_area2;
    }
  }
  return cot;
}

std::vector<double> face_areas(std::span<const Vec3> positions, std::span<const Face> faces) {
  std::vector<double> areas(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    areas[f] = triangle_area(at(positions, faces[f][0]), at(positions, faces[f][1]), at(positions, faces[f][2]));
  }
  return areas;
}

double total_area(std::span<const Vec3> positions, std::span<const Face> faces) {
  double sum = 0;
  for (double a : face_areas(positions, faces)) sum += a;
  return sum;
}

double signed_volume(std::span<const Vec3> positions, std::span<const Face> faces) {
  double six_volume = 0;
  for (const Face& f : faces) six_volume += at(positions, f[0]).dot(at(positions, f[1]).cross(at(positions, f[2])));
  return six_volume / 6.0;
}

Eigen::VectorXd barycentric_areas(std::span<const Vec3> positions, std::span<const Face> faces) {
  Eigen::VectorXd area = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(positions.size()));
  for (const Face& f : faces) {
    const double third = triangle_area(at(positions, f[0]), at(positions, f[1]), at(positions, f[2])) / 3.0;
    for (int32_t v : f) area[v] += third;
  }
  return area;
}

std::vector<Vec3> face_normals(std::span<const Vec3> positions, std::span<const Face> faces) {
  std::vector<Vec3> normals(faces.size());
  for (size_t f = 0; f < faces.size(); ++f) {
    const Vec3 n = (at(positions, faces[f][1]) - at(positions, faces[f][0])).cross(at(positions, faces[f][2]) - at(positions, faces[f][0]));
    const double length = n.norm();
    normals[f] = length > 0 ? Vec3(n / length) : Vec3::Zero();
  }
  return normals;
}

std::vector<Vec3> vertex_normals(std::span<const Vec3> positions, std::span<const Face> faces) {
  std::vector<Vec3> normals(positions.size(), Vec3::Zero());
  const auto fn = face_normals(positions, faces);
  const auto angles = corner_angles(positions, faces);
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) normals[static_cast<size_t>(faces[f][k])] += angles[f][k] * fn[f];
  }
  for (Vec3& n : normals) {
    const double length = n.norm();
    if (length > 0) n /= length;
  }
  return normals;
}

std::vector<Vec3> laplace_beltrami_of_positions(std::span<const Vec3> positions, std::span<const Face> faces) {
  const auto cot = corner_cotangents(positions, faces);
  const Eigen::VectorXd area = mixed_voronoi_areas(positions, faces);
  std::vector<Vec3> laplacian(positions.size(), Vec3::Zero());
  for (size_t f = 0; f < faces.size(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const auto i = static_cast<size_t>(faces[f][(k + 1) % 3]);
      const auto j = static_cast<size_t>(faces[f][(k + 2) % 3]);
      const Vec3 d = 0.5 * cot[f][k] * (positions[j] - positions[i]);
      laplacian[i] += d;  // sum_j w_ij (x_j - x_i) = -(K x)_i
      laplacian[j] -= d;
    }
  }
  for (size_t i = 0; i < laplacian.size(); ++i) {
    if (area[static_cast<Eigen::Index>(i)] > 0) laplacian[i] /= area[static_cast<Eigen::Index>(i)];
  }
  return laplacian;
}

Eigen::VectorXd mean_curvature(std::span<const Vec3> positions, std::span<const Face> faces, const std::vector<bool>& is_boundary) {
  const auto laplacian = laplace_beltrami_of_positions(positions, faces);
  const auto normals = vertex_normals(positions, faces);
  const auto n = static_cast<Eigen::Index>(positions.size());
  Eigen::VectorXd H(n);
  for (Eigen::Index i = 0; i < n; ++i) H[i] = 0.5 * laplacian[static_cast<size_t>(i)].dot(normals[static_cast<size_t>(i)]);

  // Boundary vertices: mean over interior neighbours. A boundary vertex whose faces touch no
  // interior vertex (an "ear") then takes the mean of its neighbours resolved in the first pass.
  auto neighbour_mean = [&](const std::vector<uint8_t>& usable) {
    Eigen::VectorXd sum = Eigen::VectorXd::Zero(n);
    Eigen::VectorXi count = Eigen::VectorXi::Zero(n);
    for (const Face& f : faces) {
      for (int k = 0; k < 3; ++k) {
        const int32_t i = f[k];
        if (!is_boundary[static_cast<size_t>(i)]) continue;
        for (int m = 1; m < 3; ++m) {
          const int32_t j = f[(k + m) % 3];
          if (!usable[static_cast<size_t>(j)]) continue;
          sum[i] += H[j];  // counted once per incident face: weighted by incidence
          count[i] += 1;
        }
      }
    }
    return std::make_pair(sum, count);
  };
  std::vector<uint8_t> resolved(static_cast<size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) resolved[static_cast<size_t>(i)] = !is_boundary[static_cast<size_t>(i)];
  const auto [interior_sum, interior_count] = neighbour_mean(resolved);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!is_boundary[static_cast<size_t>(i)]) continue;
    H[i] = interior_count[i] > 0 ? interior_sum[i] / interior_count[i] : 0.0;
    resolved[static_cast<size_t>(i)] = interior_count[i] > 0;
  }
  const auto [ear_sum, ear_count] = neighbour_mean(resolved);
  for (Eigen::Index i = 0; i < n; ++i) {
    if (is_boundary[static_cast<size_t>(i)] && interior_count[i] == 0 && ear_count[i] > 0) H[i] = ear_sum[i] / ear_count[i];
  }
  return H;
}

}  // namespace facemorph
